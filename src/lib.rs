//! # btrel — reliability of Stochastic Behavior Trees
//!
//! btrel computes how reliable a Stochastic Behavior Tree (SBT) is, following
//! chapter 9 of *Behavior Trees in Robotics and AI* (Colledanchise & Ögren):
//! every node's probability to succeed and to fail, its Mean Time To Succeed
//! (MTTS) and Mean Time To Fail (MTTF).
//!
//! ## The library in one page
//!
//! [`parse_file`] / [`parse_str`] read a tree (YAML, BehaviorTree.CPP XML)
//! into a [`Tree`]; [`Model`] analyses it once and answers every query —
//! [`Model::figures`] (P(S), P(F), MTTS, MTTF of any node) and
//! [`Model::curve`] (`π(t)`); [`simulate`] plays the tree's tick semantics
//! by Monte Carlo. Errors are one typed [`Error`] per stage (a located
//! [`TreeError`], an [`AnalysisError`], a [`SimError`]); they state facts,
//! never command-line advice.
//!
//! ```
//! let tree = btrel::parse_str(
//!     "tree:\n  fallback:\n    children:\n      - action: {ps: 0.5, mu: 1.0, nu: 2.0}\n      - action: {ps: 0.5, mu: 1.0, nu: 2.0}\n",
//!     "example.yaml",
//! )?;
//! let model = btrel::Model::new(&tree)?;
//! let root = model.figures(btrel::Tree::ROOT)?;
//! assert!((root.ps - 0.75).abs() < 1e-12);
//! // MTTF = 1/nu + 1/nu (eq. 9.75)
//! assert!((root.mttf.unwrap() - 1.0).abs() < 1e-12);
//! # Ok::<(), btrel::Error>(())
//! ```
//!
//! ## The pipeline, one module per stage
//!
//! 1. [`tree`]: parse and validate a tree (YAML, BehaviorTree.CPP XML);
//!    [`logs`] and [`fit`] estimate leaf parameters from robots' logs;
//! 2. [`compile`]: the model — the planner (`compile::plan`, internal: one table
//!    picks each node's representation from its children's, bottom-up,
//!    memoised) and the representations (phase chains, atoms, shifted
//!    phase-type mixtures, counted Parallels, races, composed laws);
//! 3. [`solve`]: the numerics (faer linear algebra, transient analysis,
//!    quadrature, interpolation);
//! 4. queries on the model: [`report`] (per-node figures as a table, JSON
//!    or CSV), [`curve`] (π(t)), [`compare`] (Fallback orderings), [`plot`],
//!    [`sensitivity`], [`uncertainty`] (intervals from the parameters'
//!    sampling uncertainty);
//! 5. [`export`]: DOT, PRISM, Storm;
//! 6. [`gate`]: requirements on the figures (`ps >= 0.95`) decided exactly,
//!    by fitted-parameter intervals, or by sequential tests
//!    ([`sim::sequential`]: SPRT, Chow–Robbins, Okamoto's bound).
//!
//! [`sim`] (Monte Carlo) stands beside them and shares only the parsed tree.
//! Dependencies run one way: `compile` uses `solve` and `tree`; the queries
//! use `compile`; nothing below uses what is above it. The stage modules are
//! public for the command-line tool, benches and tests; the items re-exported
//! here are the library's supported surface.

pub mod compare;
pub mod compile;
pub mod curve;
pub mod export;
pub mod fit;
pub mod gate;
pub mod generate;
pub mod ir;
pub mod logs;
mod model;
pub mod number;
pub mod output;
pub mod plot;
pub mod report;
pub mod sensitivity;
pub mod sim;
pub mod solve;
pub mod tree;
pub mod uncertainty;

pub use compile::{analyze, Analysis, AnalysisError, Figures, Method, Options, Representation};
pub use curve::{CurvePoint, Timing};
pub use model::{Error, Model};
pub use sim::{simulate, SimError, SimOptions, SimResult};
pub use tree::{parse_file, parse_str, NodeId, Tree, TreeError};
