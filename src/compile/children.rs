//! What a representation asks of the subtrees below it, answered by the
//! planner: a race's children may be any subtree (a phase chain, a shifted
//! mixture, a count, another race, a composed law), and a composed law may
//! hold a race. The representations ask through [`Children`], which
//! [`super::plan::Plan`] implements, so that none of them names the planner
//! or another's builder: the planner is the one file that knows them all
//! (`docs/ARCHITECTURE.md`; `tests/module_cycles.rs` fails on a cycle).
//!
//! [`Representation`] — the planner's answer for one node — lives here too:
//! both sides speak it.

use super::phase::ChainSize;
use super::{AnalysisError, Figures};
use crate::ir::Graph;
use crate::solve::chain::PhaseChain;
use crate::tree::NodeId;

/// How the engine represents one node's outcome law (the planner's table,
/// module docs).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Representation {
    /// A leaf: its parameters and closed-form CDFs.
    Closed,
    /// The book's CTMC over the node's MRG (strategy `book`).
    Book,
    /// A loop without a bound: a cyclic chain or a truncated series.
    Loop,
    /// Finitely many return instants (deterministic subtree).
    Atoms,
    /// An exact phase chain (exponential subtree within the budget).
    Chain,
    /// A Parallel with the book's thresholds, by counting its children.
    Counted,
    /// A Parallel whose thresholds can both be met: a race of its children.
    Race,
    /// A map of its child's outcomes (an inverter, a force decorator) over
    /// a child without a phase chain or atoms: its child's law, mapped.
    Mapped,
    /// A shifted phase-type mixture (mixed timing); the composed laws
    /// where the mixture exceeds the budget or cannot hold a Parallel.
    Shifted,
    /// Composed outcome laws (interpolated densities; a wide Parallel below).
    Composed,
}

impl Representation {
    /// A short name, as in docs/METHOD.md.
    pub fn name(&self) -> &'static str {
        match self {
            Representation::Closed => "closed form",
            Representation::Book => "book CTMC",
            Representation::Loop => "loop",
            Representation::Atoms => "atoms",
            Representation::Chain => "phase chain",
            Representation::Counted => "counted",
            Representation::Race => "race",
            Representation::Mapped => "mapped child",
            Representation::Shifted => "shifted mixture",
            Representation::Composed => "composed laws",
        }
    }
}

/// The planner, as the representations see it.
pub(crate) trait Children {
    /// The (primitive) tree planned.
    fn tree(&self) -> &Graph;
    /// The largest chain (or number of atoms) the plan builds.
    fn max_states(&self) -> usize;
    /// The representation of node `id`.
    fn representation(&self, id: NodeId) -> Result<Representation, AnalysisError>;
    /// Whether `id`'s subtree has a phase chain (every leaf phase-type:
    /// its shape, known before building anything).
    fn markovian(&self, id: NodeId) -> bool;
    /// The exact phase chain of `id`.
    fn chain(&self, id: NodeId) -> Result<PhaseChain, AnalysisError>;
    /// The size of `id`'s phase chain, estimated before building it.
    fn chain_size(&self, id: NodeId) -> Result<ChainSize, AnalysisError>;
    /// The figures of `id`'s subtree computed so far (`None` for the
    /// others; `[k]` is node `id + k`).
    fn known_subtree_figures(&self, id: NodeId) -> Vec<Option<Figures>>;
    /// The figures of every node of `id`'s subtree (`[k]`: node `id + k`).
    fn subtree_figures(&self, id: NodeId) -> Result<Vec<Figures>, AnalysisError>;
    /// The composed outcome law of `id` on `[0, end]`.
    fn horizon_law(&self, id: NodeId, end: f64) -> Result<Box<dyn ReturnLaw>, AnalysisError>;
    /// `[P(S), P(F), E[T·1{S}], E[T·1{F}]]` of a deadline race over a
    /// renewal race (`None` for any other node).
    fn deadline_figures(&self, id: NodeId) -> Result<Option<[f64; 4]>, AnalysisError>;
}

/// A subtree's outcome law on `[0, end]` as a race reads it: past `end`
/// its probabilities stay at their values there and its densities are 0.
pub(crate) trait ReturnLaw {
    /// Probability of returning by `end`.
    fn mass(&self) -> f64;
    /// `[S, F, s, f]` at `t`; `left`: without a return exactly at `t`.
    fn row(&self, t: f64, left: bool) -> [f64; 4];
    /// Instants with an atom.
    fn instants(&self) -> Vec<f64>;
    /// Where its densities may jump or kink (and its end).
    fn cuts(&self) -> Vec<f64>;
}
