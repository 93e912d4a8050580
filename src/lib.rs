//! # btrel — reliability of Stochastic Behavior Trees
//!
//! btrel computes how reliable a Stochastic Behavior Tree (SBT) is, following
//! chapter 9 of *Behavior Trees in Robotics and AI* (Colledanchise & Ögren):
//! every node's probability to succeed and to fail, its Mean Time To Succeed
//! (MTTS) and Mean Time To Fail (MTTF).
//!
//! The pipeline, one module per stage:
//!
//! 1. [`tree`]: parse and validate a tree (YAML, BehaviorTree.CPP XML);
//! 2. [`compile`]: the model — each node's marking reachability graph and
//!    its outcome distribution, bottom-up (phase chains, atoms, shifted
//!    phase-type mixtures, counted Parallels, composed laws), with each
//!    node's figures and curve;
//! 3. [`solve`]: the numerics those use (faer linear algebra, transient
//!    analysis, quadrature, interpolation);
//! 4. queries on the model: [`report`] (per-node figures as a table, JSON
//!    or CSV), [`curve`] (π(t)), [`compare`] (Fallback orderings), [`plot`];
//! 5. [`export`]: DOT, PRISM, Storm.
//!
//! [`logs`] and [`fit`] estimate leaf parameters from robots' logs;
//! [`uncertainty`] turns their sampling uncertainty into intervals of the
//! figures.
//!
//! [`sim`] (Monte Carlo) stands beside them and shares only the parsed tree.
//! Dependencies run one way: `compile` uses `solve` and `tree`; the queries
//! use `compile`; nothing below uses what is above it.
//!
//! ```
//! let tree = btrel::tree::parse_str(
//!     "tree:\n  fallback:\n    children:\n      - action: {ps: 0.5, mu: 1.0, nu: 2.0}\n      - action: {ps: 0.5, mu: 1.0, nu: 2.0}\n",
//!     "example.yaml",
//! ).unwrap();
//! let analysis = btrel::compile::analyze(&tree, &Default::default()).unwrap();
//! let root = analysis.nodes[0];
//! assert!((root.ps - 0.75).abs() < 1e-12);
//! // MTTF = 1/nu + 1/nu (eq. 9.75)
//! assert!((root.mttf.unwrap() - 1.0).abs() < 1e-12);
//! ```

pub mod compare;
pub mod compile;
pub mod curve;
pub mod export;
pub mod fit;
pub mod generate;
pub mod logs;
pub mod output;
pub mod plot;
pub mod report;
pub mod sensitivity;
pub mod sim;
pub mod solve;
pub mod tree;
pub mod uncertainty;

pub use compile::{analyze, Analysis, AnalysisError, Figures, Method, Options};
pub use tree::{parse_file, parse_str, Tree};
