//! The options and points of a curve query, shared by the curve's
//! representations (a leaf module: it uses none of them).

use crate::compile::{self, Method};
use crate::solve::transient;

pub use crate::solve::transient::CurvePoint;

/// How action times are taken.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Timing {
    /// As written in the tree file.
    #[default]
    AsGiven,
    /// Every exponential time replaced by a fixed time `1/rate`.
    Deterministic,
}

/// Error bound accepted from the dense stiff solver.
pub(crate) const DENSE_TOLERANCE: f64 = 1e-10;

/// Default limit on uniformization work (vector operations × nonzeros; an
/// upper bound, since the solver skips zero entries: about a few seconds).
pub(crate) const DEFAULT_MAX_WORK: f64 = 1e11;

/// Options of a curve computation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CurveOptions {
    /// exact or book.
    pub method: Method,
    /// Times as given or made deterministic.
    pub timing: Timing,
    /// Largest chain or number of atoms.
    pub max_states: usize,
    /// Bound on the absolute error of the truncated series.
    pub tolerance: f64,
    /// Largest uniformization effort before refusing.
    pub max_work: f64,
}

impl Default for CurveOptions {
    fn default() -> Self {
        CurveOptions {
            method: Method::Exact,
            timing: Timing::AsGiven,
            max_states: compile::DEFAULT_MAX_STATES,
            tolerance: transient::DEFAULT_TOLERANCE,
            max_work: DEFAULT_MAX_WORK,
        }
    }
}
