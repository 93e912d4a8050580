//! Probabilities over time: `π(t)` of any node of a tree — the query on
//! the compiled model ([`crate::compile::curve`] documents how each node's
//! curve is computed: phase chains, atoms, shifted phase-type mixtures,
//! counted Parallels, composed outcome laws, cyclic loop chains, or the
//! book's CTMC).

pub use crate::compile::curve::{curve, deterministic_version, CurveOptions, CurvePoint, Timing};
