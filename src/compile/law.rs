//! `π(t)` of nodes that no exact chain, atom list or shifted mixture holds —
//! wide Parallels, mixed timing beyond the shifted mixture's budget, and
//! every node above them — from their *outcome laws*: for each outcome a
//! measure on `[0, T]` made of **atoms** (probabilities of returning at
//! exactly τ: zero-time conditions, fixed times, a hybrid's cut-off) and a
//! **sub-density** of the return time, a piecewise Chebyshev interpolant
//! ([`crate::solve::interpolant`]) whose panels start at the instants where
//! it may jump or kink; T is the last requested time.
//!
//! Laws compose exactly as the tick semantics do; only the interpolation of
//! each density is approximate (an error estimate of 1e-15 in probability
//! mass per panel):
//!
//! * a subtree with a phase chain: its densities `π(t)·exit` sampled by
//!   uniformization ([`transient_weighted`]), its instant returns an atom at 0;
//! * a leaf without one: a fixed time τ is an atom at τ; a hybrid's random
//!   side `min(X, τ)` the density of X on `[0, τ)` plus an atom `e^{−λτ}` at
//!   τ; a shifted phase-type time its stages' density shifted by the shift;
//! * a Parallel with the book's thresholds (`F = N − M + 1`): until it
//!   returns its children run independently and the thresholds cannot both
//!   be met, so it has succeeded by t iff at least M children have
//!   ([`super::curve`]'s count programme); its densities are the time
//!   derivatives of that count programme, computed in dual numbers from the
//!   children's probabilities and densities
//!   ([`counts::status_and_densities_by_counts`]), and its atom at each
//!   instant where a child has one is the jump of the programme there (the
//!   children's probabilities just after minus just before: the order of
//!   simultaneous returns cannot matter, as the thresholds cannot both be
//!   met);
//! * a Parallel whose thresholds can both be met is composed only when its
//!   subtree is deterministic ([`super::atoms`]: ties in child order);
//! * a Sequence runs its children one after the other, each independent of
//!   the others and started at the previous one's return: with `G_k` the
//!   law of the time at which the first k children have all succeeded
//!   (`G_0 = δ₀`), `G_k = G_{k−1} ⊛ S_k` and the Sequence fails with
//!   `Σ_k G_{k−1} ⊛ F_k` and succeeds with `G_n` — where `⊛` convolves
//!   measures: `(Σ a_i δ_{τ_i} + g) ⊛ (Σ b_j δ_{σ_j} + h) = Σ a_i b_j
//!   δ_{τ_i+σ_j} + Σ a_i h(· − τ_i) + Σ b_j g(· − σ_j) + g * h`. A Fallback
//!   is the same with the outcomes exchanged. Consecutive children with
//!   phase chains are concatenated into one chain first (exact, and fewer
//!   convolutions);
//! * Retry N and Repeat N are a Fallback and a Sequence of N copies,
//!   composed by binary powering (O(log N) convolutions, stopped once the
//!   mass still going on within `[0, T]` is negligible); a loop without a
//!   bound is its renewal equation marched in time (`Builder::renewal`:
//!   about one convolution's cost, whatever the number of runs); inverter and force
//!   decorators exchange or merge the outcomes; a flow carries the law of
//!   the time each state is entered.
//!
//! **Atoms.** Instants that agree within [`SAME_INSTANT`](crate::tree::SAME_INSTANT) (1e-12
//! relative, [`same_instant`]: the deterministic analysis's and the races'
//! rule) are one instant — `0.1 + 0.2` and `0.3` are the same — and a curve
//! point at such an instant counts the atom as returned. Atoms after T are
//! dropped (they do not change `[0, T]`); atoms below [`ATOM_FLOOR`] are
//! dropped too, and their mass is added up: a law whose dropped mass
//! exceeds [`DROPPED_LIMIT`] is refused, so the curve's error is the
//! interpolation's estimate plus at most that. The pairs of a convolution
//! are counted before they are allocated: more than the state budget
//! (`--max-states`) is refused, naming the node.
//!
//! **Breaks.** A density may jump at an atom's instant plus a jump of the
//! density it shifts, and kink at the sum of two jumps; these instants (at
//! most [`MAX_BREAKS`] per density, the earliest kept; further ones are
//! resolved by halving panels) start interpolation panels
//! ([`build_with_breaks`]), so every panel's function is smooth.
//!
//! A Parallel with an independent failure threshold over mixed or wide
//! children has no such decomposition (which threshold is met first depends
//! on the joint times): it is refused here (its own curve is a race,
//! `super::race`).
//!
//! Size: one concern, the composed outcome law; most of it is one `Builder`
//! whose methods are the law of each node kind over shared panels and memo,
//! then the curves read from laws (`curve_by_laws`, a loop's `loop_curve`);
//! about 300 lines are comments.

use super::atoms as det;
use super::chain_curve::{
    curve_by_shifted, sample_weighted, sample_weighted_kept, SAMPLE_TOLERANCE,
};
use super::curve_options::CurveOptions;
use super::mrg::Outcome;
use super::shifted;
use crate::compile::children::{Children, ReturnLaw};
use crate::compile::{counts, phase, renewal_law, AnalysisError};
use crate::ir::{Flow, FlowGraph, Graph, Leaf, Op};
use crate::solve::chain::PhaseChain;
use crate::solve::exponential::{erlang_densities, ErlangConvolution, ErlangMarch, MAX_STAGES};
use crate::solve::interpolant::{
    build_marching, build_with_breaks, panel_convolution, panel_weights, BuildError, Interpolant,
    POINTS,
};
use crate::solve::transient::{
    self, absorption_by_phase, transient_split, uniformization_work, CurvePoint,
    MAX_SINGLE_PASS_STEPS,
};
use crate::tree::same_instant;
use crate::tree::stages::Stages;
use crate::tree::{Duration, FlowNext, NodeId};
use rayon::prelude::*;

/// Mass below which the rest of a fold is dropped.
const NEGLIGIBLE: f64 = 1e-17;

/// Atoms lighter than this are dropped (their mass counted).
pub const ATOM_FLOOR: f64 = 1e-22;

/// Most atom mass a law may have dropped (else it is refused).
pub const DROPPED_LIMIT: f64 = 1e-12;

/// A density's jump times the horizon below which the jump does not keep
/// a break (it changes the mass of a panel by less than this).
const JUMP_FLOOR: f64 = 1e-16;

/// Most work of one builder's convolutions of two interpolated densities,
/// in panel-piece evaluations: each costs `(P_x + P_y) · P_out` of them
/// (every point of the result's panels sums a piece per panel edge in its
/// window), counted when done, and estimated before it runs with `P_out`
/// the longer density's panels: one over the limit is refused before it
/// runs. About 2.7e6 build Nav2's fitted tree's curve (1.2 s); 1.8e7 take
/// about 10 s (survey tree 272 to t = 10).
pub const MAX_CONVOLUTION_WORK: f64 = 4e7;

/// Most instants that start interpolation panels, per density.
pub const MAX_BREAKS: usize = 4096;

const SUCCESS: usize = 0;
const FAILURE: usize = 1;

/// A node's outcome law on `[0, T]`: the measure of its return time with
/// Success (index 0) and with Failure (1).
#[derive(Debug, Clone)]
struct Law {
    parts: [Measure; 2],
}

impl Law {
    /// The part of the law with outcome `o`.
    fn measure(&self, o: usize) -> Measure {
        self.parts[o].clone()
    }

    /// P(returned outcome `o` by t).
    fn cdf(&self, o: usize, t: f64) -> f64 {
        self.parts[o].cdf(t)
    }

    /// Atom mass dropped in building the law.
    fn dropped(&self) -> f64 {
        self.parts[SUCCESS].dropped + self.parts[FAILURE].dropped
    }
}

/// A child as its chain (when it has one) or its law.
enum Piece {
    Chain(PhaseChain),
    Law(Box<Law>),
}

/// For every node, whether a leaf below (or the node) has a time that is
/// not phase-type (fixed, hybrid, shifted): its subtree has no phase chain.
fn non_markovian(tree: &Graph) -> Vec<bool> {
    let mut out = vec![false; tree.nodes.len()];
    // pre-order: reverse order is bottom-up
    for id in (0..tree.nodes.len()).rev() {
        out[id] = match &tree.node(id).kind {
            Op::Leaf(Leaf::Action(a)) => {
                [(a.ps, a.success), (a.pf, a.failure)]
                    .iter()
                    .any(|&(p, d)| {
                        p > 0.0
                            && !matches!(d, Some(Duration::Fixed { time: 0.0 }))
                            && !d.is_some_and(|d| d.is_phase_type())
                    })
            }
            kind => kind.children().iter().any(|&c| out[c]),
        };
    }
    out
}

/// The width below which a segment between two breaks of a density
/// starts as one panel ([`build_with_breaks`]): `1/λ`, `λ` the fastest rate
/// of any leaf's time in the tree (every phase of a composed law runs at
/// one of them), 0 without one.
fn narrow_segment(tree: &Graph) -> f64 {
    let fastest = tree
        .nodes
        .iter()
        .filter_map(|n| match &n.kind {
            Op::Leaf(Leaf::Action(a)) => Some([a.success, a.failure]),
            _ => None,
        })
        .flatten()
        .flatten()
        .map(|d| d.fastest_rate())
        .fold(0.0, f64::max);
    if fastest > 0.0 {
        1.0 / fastest
    } else {
        0.0
    }
}

/// A Parallel with thresholds M = 1, F = 1 over a deadline — an action that
/// fails at a fixed time `D > 0` and cannot succeed — and one other child:
/// A subtree's composed outcome law on `[0, end]`, as a child of a race
/// or a count ([`super::race`]): the universal representation, for any
/// subtree the faster ones cannot hold (mixed timing in a loop or a race,
/// a shifted mixture over its budget). Past `end` its probabilities stay
/// at their values there and its densities are 0: exact where the caller
/// picks `end` past all but a negligible mass (stated by [`Self::mass`]).
pub(crate) struct HorizonLaw {
    law: Law,
    end: f64,
    /// Per part, the running sums of its atoms' masses (`[0]` = 0): a
    /// race's quadrature asks the CDF at every point of its panels, and a
    /// loop over fixed times has an atom at every instant of its lattice
    /// (random survey tree 1735: 23,707 atoms, 853,632 points).
    prefix: [Vec<f64>; 2],
}

impl HorizonLaw {
    /// The law of `id` on `[0, end]`, its children's asked of `children`.
    pub(crate) fn build(
        children: &dyn Children,
        id: NodeId,
        end: f64,
    ) -> Result<HorizonLaw, AnalysisError> {
        let law = composed_law(children, id, end, children.max_states(), |b| b.law(id))?;
        // summed in order, as `Measure::cdf` sums them
        let prefix = |m: &Measure| {
            let mut p = Vec::with_capacity(m.atoms.len() + 1);
            let mut sum = -0.0;
            p.push(sum);
            for a in &m.atoms {
                sum += a.1;
                p.push(sum);
            }
            p
        };
        let prefix = [prefix(&law.parts[0]), prefix(&law.parts[1])];
        Ok(HorizonLaw { law, end, prefix })
    }

    /// `Measure::cdf` (`left`: `cdf_left`) of part `o` by the running sums.
    fn cdf(&self, o: usize, t: f64, left: bool) -> f64 {
        let m = &self.law.parts[o];
        let k = if left {
            m.atoms
                .partition_point(|a| a.0 < t && !same_instant(a.0, t))
        } else {
            m.atoms
                .partition_point(|a| a.0 <= t || same_instant(a.0, t))
        };
        self.prefix[o][k] + m.density.as_ref().map_or(0.0, |d| d.integral_to(t))
    }
}

impl ReturnLaw for HorizonLaw {
    fn mass(&self) -> f64 {
        self.law.cdf(SUCCESS, self.end) + self.law.cdf(FAILURE, self.end)
    }

    fn row(&self, t: f64, left: bool) -> [f64; 4] {
        if t > self.end && !same_instant(t, self.end) {
            return [
                self.law.cdf(SUCCESS, self.end),
                self.law.cdf(FAILURE, self.end),
                0.0,
                0.0,
            ];
        }
        let p = &self.law.parts;
        [
            self.cdf(SUCCESS, t, left),
            self.cdf(FAILURE, t, left),
            p[SUCCESS].density_at(t),
            p[FAILURE].density_at(t),
        ]
    }

    fn instants(&self) -> Vec<f64> {
        self.law
            .parts
            .iter()
            .flat_map(|m| m.atoms.iter().map(|a| a.0))
            .collect()
    }

    fn cuts(&self) -> Vec<f64> {
        self.law
            .parts
            .iter()
            .flat_map(|m| m.breaks.iter().copied().chain(m.atoms.iter().map(|a| a.0)))
            .chain(std::iter::once(self.end))
            .collect()
    }
}

/// BT.CPP's `Timeout` (the deadline first) or a user's race.
pub(crate) struct DeadlineRace {
    /// `D` (s).
    pub(crate) time: f64,
    /// The raced child.
    pub(crate) child: NodeId,
    /// The deadline comes first in child order (it wins a tie at `D`).
    pub(crate) deadline_first: bool,
}

/// Node `id` as a [`DeadlineRace`], if it is one.
pub(crate) fn deadline_race(tree: &Graph, id: NodeId) -> Option<DeadlineRace> {
    let Op::KOfN {
        success: 1,
        failure: 1,
        children,
    } = &tree.node(id).kind
    else {
        return None;
    };
    let [a, b] = children[..] else {
        return None;
    };
    let deadline = |c: NodeId| match &tree.node(c).kind {
        Op::Leaf(Leaf::Action(x)) if x.ps == 0.0 && x.pf == 1.0 => match x.failure {
            Some(Duration::Fixed { time }) if time > 0.0 && time.is_finite() => Some(time),
            _ => None,
        },
        _ => None,
    };
    match (deadline(a), deadline(b)) {
        (Some(time), _) => Some(DeadlineRace {
            time,
            child: b,
            deadline_first: true,
        }),
        (None, Some(time)) => Some(DeadlineRace {
            time,
            child: a,
            deadline_first: false,
        }),
        (None, None) => None,
    }
}

/// The figures `[P(S), P(F), E[T·1{S}], E[T·1{F}]]` of a deadline race
/// (`Timeout`) whose child holds a race against a renewal process below
/// (Nav2's re-planning, MoveIt Pro's `KeepRunningUntilFailure` beside an
/// action): the node has returned by its deadline `D`, so its composed law
/// on `[0, D]` is all of it (the child's law from its levels, see
/// [`renewal_law`]); `None` for any other node. Exact but for the
/// interpolation's estimate (1e-15 of mass per panel).
pub(crate) fn deadline_figures(
    children: &dyn Children,
    id: NodeId,
) -> Result<Option<[f64; 4]>, AnalysisError> {
    let (tree, max_states) = (children.tree(), children.max_states());
    let Some(race) = deadline_race(tree, id) else {
        return Ok(None);
    };
    if !renewal_law::holds_race(tree, race.child) {
        return Ok(None);
    }
    let memo = LawMemo::default();
    let mixed = non_markovian(tree);
    let b = Builder {
        tree,
        children,
        end: race.time,
        max_states,
        memo: &memo,
        mixed: &mixed,
        narrow: narrow_segment(tree),
        work: std::cell::Cell::new(0.0),
    };
    let law = b.deadline(id, &race)?;
    let [s, f] = &law.parts;
    Ok(Some([
        s.mass(),
        f.mass(),
        s.first_moment(),
        f.first_moment(),
    ]))
}

/// `π(t)` of `id` from its composed law, at `times` (any subtree: only a
/// budget stops it).
pub(super) fn curve_by_laws(
    children: &dyn Children,
    id: NodeId,
    times: &[f64],
    options: &CurveOptions,
    kept: &Kept,
) -> Result<Vec<CurvePoint>, AnalysisError> {
    let end = times.iter().copied().fold(0.0, f64::max);
    let key = (id, options.max_states);
    let known = kept
        .laws
        .borrow()
        .get(&key)
        .filter(|(until, _)| *until >= end)
        .map(|(_, law)| law.clone());
    let law = match known {
        Some(law) => law,
        None => {
            let law =
                std::sync::Arc::new(composed_law(children, id, end, options.max_states, |b| {
                    b.opaque(id)
                })?);
            kept.laws.borrow_mut().insert(key, (end, law.clone()));
            law
        }
    };
    Ok(times
        .iter()
        .map(|&t| {
            let success = law.cdf(SUCCESS, t).clamp(0.0, 1.0);
            let failure = law.cdf(FAILURE, t).clamp(0.0, 1.0);
            CurvePoint {
                t,
                success,
                failure,
                running: (1.0 - success - failure).max(0.0),
            }
        })
        .collect())
}

/// What a plan keeps across its curve queries, so that a quadrature's
/// rounds and a curve's later times do not build a node's law again: the
/// composed laws, by node and budget — the law of a node on `[0, end]`
/// answers every later query up to `end` (on a longer horizon it is the
/// same law up to `end`); a query past it builds the law on its own
/// horizon — and the nodes' shifted mixtures.
#[derive(Default)]
pub(crate) struct Kept {
    laws: std::cell::RefCell<std::collections::HashMap<(NodeId, usize), KeptLaw>>,
    /// The shifted mixtures within their first budget.
    pub(crate) mixtures: shifted::KeptMixtures,
}

/// A composed law kept with the end of its horizon.
type KeptLaw = (f64, std::sync::Arc<Law>);

/// The law of `id` that `build` makes with a fresh builder on `[0, end]`, refused where
/// it dropped more than [`DROPPED_LIMIT`] of atom mass.
fn composed_law(
    children: &dyn Children,
    id: NodeId,
    end: f64,
    max_states: usize,
    build: impl FnOnce(&Builder) -> Result<Law, AnalysisError>,
) -> Result<Law, AnalysisError> {
    let tree = children.tree();
    let memo = LawMemo::default();
    let mixed = non_markovian(tree);
    let b = Builder {
        tree,
        children,
        end,
        max_states,
        memo: &memo,
        mixed: &mixed,
        narrow: narrow_segment(tree),
        work: std::cell::Cell::new(0.0),
    };
    let law = build(&b)?;
    if law.dropped() > DROPPED_LIMIT {
        return Err(AnalysisError::Numerical {
            node: b.name(id),
            what: format!(
                "its law has {:.1e} probability in atoms below {ATOM_FLOOR:e} (more than \
                 {DROPPED_LIMIT:e})",
                law.dropped()
            ),
        });
    }
    Ok(law)
}

/// Accepted bound on the time the children may still run beyond the
/// horizon, relative to the node's mean time.
const MEAN_TOLERANCE: f64 = 1e-11;

/// Fraction of a loop's returning mass left when its renewal density is
/// taken as 0 for the rest of the horizon ([`Builder::renewal`]).
const SETTLED_MASS: f64 = 1e-15;

/// Most doublings of the horizon for [`counted_parallel_times`].
const MAX_DOUBLINGS: usize = 40;

/// `[E[T·1{S}], E[T·1{F}]]` of Parallel `id` with the book's thresholds
/// (success threshold `m`), some of whose children have no chain, given the
/// children's exact mean times `E[T_h]` (`ps·MTTS + pf·MTTF`).
///
/// The node's law is built on `[0, T]` and its first moments taken. What
/// they miss is `E[T·1{o}; T_node > T] ≤ ∫_T^∞ P(T_node > t) dt ≤ Σ_h
/// E[(T_h − T)⁺]` (the node returns by the time all its children have),
/// and each child's `E[(T_h − T)⁺]` is known: `∫_T^∞ P(running)` by
/// uniformization for a child with a chain, `E[T_h] − E[min(T_h, T)]` from
/// its law otherwise. `T` starts at 4 × the largest `E[T_h]` and doubles
/// until that remainder is below 1e-11 of the node's mean time (or at the
/// rounding floor of the children's mean times). The error of the result is
/// that remainder plus the interpolation's estimate.
pub(crate) fn counted_parallel_times(
    planner: &dyn Children,
    id: NodeId,
    m: usize,
    child_mean_times: &[f64],
    max_states: usize,
    memo: &LawMemo,
) -> Result<[f64; 2], AnalysisError> {
    let tree = planner.tree();
    let children = tree.node(id).kind.children();
    let longest = child_mean_times.iter().copied().fold(0.0, f64::max);
    if longest == 0.0 {
        return Ok([0.0, 0.0]);
    }
    let floor = 64.0 * f64::EPSILON * child_mean_times.iter().sum::<f64>();
    // a start that usually needs no doubling: the slowest phase of the
    // children with chains has decayed by e^{-30}
    let slowest = children
        .iter()
        .filter_map(|&c| phase::chain_within(tree, c, max_states).ok().flatten())
        .filter_map(|c| (0..c.len()).map(|i| c.total_rate(i)).reduce(f64::min))
        .fold(f64::INFINITY, f64::min);
    let start = (4.0 * longest).max(if slowest.is_finite() {
        30.0 / slowest
    } else {
        0.0
    });
    // a power of two, so that the ancestors of a nested Parallel meet the
    // same horizons and reuse its memoised law
    let mut end = 2f64.powi(start.log2().ceil() as i32);
    let mixed = non_markovian(tree);
    let narrow = narrow_segment(tree);
    for _ in 0..MAX_DOUBLINGS {
        let b = Builder {
            tree,
            children: planner,
            end,
            max_states,
            memo,
            mixed: &mixed,
            narrow,
            work: std::cell::Cell::new(0.0),
        };
        // laws depend on the horizon
        let pieces = children
            .iter()
            .map(|&c| b.piece(c))
            .collect::<Result<Vec<_>, _>>()?;
        let law = b.counted_from(id, children, &pieces, m)?;
        let moments = [
            law.parts[SUCCESS].first_moment(),
            law.parts[FAILURE].first_moment(),
        ];
        let mut beyond = 0.0;
        for ((piece, &mean), &c) in pieces.iter().zip(child_mean_times).zip(children) {
            beyond += match piece {
                Piece::Chain(chain) => {
                    let absorption = absorption_by_phase(chain);
                    let p = transient_split(chain, &[end], SAMPLE_TOLERANCE, &absorption)
                        .ok_or_else(|| stiff(tree, c, chain, end))?;
                    p[0].time_to_success + p[0].time_to_failure
                }
                Piece::Law(l) => {
                    let done = l.parts[SUCCESS].first_moment() + l.parts[FAILURE].first_moment();
                    let running = 1.0 - l.cdf(SUCCESS, end) - l.cdf(FAILURE, end);
                    (mean - done - end * running.max(0.0)).max(0.0)
                }
            };
        }
        if beyond <= MEAN_TOLERANCE * (moments[0] + moments[1]) || beyond <= floor {
            return Ok(moments);
        }
        end *= 2.0;
    }
    Err(AnalysisError::Numerical {
        node: tree.node(id).name.clone(),
        what: "its mean times did not converge on growing horizons".into(),
    })
}

/// Uniformization of `id`'s chain to `end` would need more steps than one
/// pass keeps, and the chain is too large for dense exponentials.
fn stiff(tree: &Graph, id: NodeId, chain: &PhaseChain, end: f64) -> AnalysisError {
    let nnz: usize = chain.transitions.iter().map(Vec::len).sum::<usize>() + 2 * chain.len();
    AnalysisError::Stiff {
        node: tree.node(id).name.clone(),
        work: uniformization_work(chain, &[end]),
        limit: MAX_SINGLE_PASS_STEPS as f64 * nnz.max(1) as f64,
    }
}

struct Builder<'a> {
    tree: &'a Graph,
    /// The planner, asked for the races below ([`Children`]).
    children: &'a dyn Children,
    end: f64,
    max_states: usize,
    memo: &'a LawMemo,
    /// [`non_markovian`] of the tree.
    mixed: &'a [bool],
    /// [`narrow_segment`] of the tree.
    narrow: f64,
    /// Work of the convolutions so far (see [`MAX_CONVOLUTION_WORK`]).
    work: std::cell::Cell<f64>,
}

/// Laws already built, by node and horizon: a node's law is built once per
/// horizon however many ancestors need it (nested wide Parallels would
/// otherwise rebuild every subtree for every ancestor: quadratic in depth).
#[derive(Default)]
pub(crate) struct LawMemo(std::cell::RefCell<std::collections::HashMap<(NodeId, u64), Law>>);

impl Builder<'_> {
    fn name(&self, id: NodeId) -> String {
        self.tree.node(id).name.clone()
    }

    /// `k` interpolants on `[0, T]` with panels starting at `breaks`.
    fn interpolate(
        &self,
        id: NodeId,
        k: usize,
        breaks: &[f64],
        sample: impl FnMut(&[f64]) -> Result<Vec<f64>, AnalysisError>,
    ) -> Result<Vec<Interpolant>, AnalysisError> {
        build_with_breaks(self.end, breaks, self.narrow, k, sample).map_err(|e| match e {
            BuildError::Sample(e) => e,
            BuildError::NotConverged => AnalysisError::Numerical {
                node: self.name(id),
                what: "the interpolated densities of its outcome times did not converge".into(),
            },
        })
    }

    /// One interpolated density with panels starting at `breaks`.
    fn density(
        &self,
        id: NodeId,
        breaks: &[f64],
        sample: impl FnMut(&[f64]) -> Result<Vec<f64>, AnalysisError>,
    ) -> Result<Interpolant, AnalysisError> {
        let d = self.interpolate(id, 1, breaks, sample)?.remove(0);
        Ok(d)
    }

    /// The child's chain if it has one within the budget, else its law.
    fn piece(&self, id: NodeId) -> Result<Piece, AnalysisError> {
        // the chain where its size, estimated before building, is within
        // the budget
        // (a loop unrolled into many copies: the loop's cyclic chain, and
        // the composed laws above it)
        if !self.mixed[id] {
            let size = phase::chain_size(self.tree, id, self.max_states, &mut Default::default())?;
            if size.fits() {
                if !phase::long_unrolled(&size, phase::holds_loop(self.tree, id)) {
                    return Ok(Piece::Chain(phase::chain_of(
                        self.tree,
                        id,
                        self.max_states,
                    )?));
                }
                if let Op::Loop { child, until } = self.tree.node(id).kind {
                    let c = phase::chain_of(self.tree, child, self.max_states)?;
                    let cyclic = phase::cyclic_loop(c, until == Outcome::Success);
                    return Ok(Piece::Chain(cyclic.unwrap_or_else(phase::trap)));
                }
            }
        }
        let key = (id, self.end.to_bits());
        if let Some(l) = self.memo.0.borrow().get(&key) {
            return Ok(Piece::Law(Box::new(l.clone())));
        }
        let law = if renewal_law::holds_race(self.tree, id) {
            // a renewal race (Nav2's re-planning) below; a copy's law (a
            // RecoveryNode's retries copy the subtree they retry) is reused
            let copy = self.memo.0.borrow().iter().find_map(|(&(n, end), l)| {
                (end == key.1 && self.tree.same_subtree(n, id)).then(|| l.clone())
            });
            match copy {
                Some(l) => l,
                None => match renewal_law::law(self.tree, id, self.end, self.max_states)? {
                    // the race, or the Sequence that starts it: its law from
                    // its levels
                    Some((atom, [success, failure])) => Law {
                        parts: [
                            self.measure(vec![(0.0, atom[0])], Some(success), Vec::new(), 0.0),
                            self.measure(vec![(0.0, atom[1])], Some(failure), Vec::new(), 0.0),
                        ],
                    },
                    None => self.opaque(id)?,
                },
            }
        } else {
            self.opaque(id)?
        };
        self.memo.0.borrow_mut().insert(key, law.clone());
        Ok(Piece::Law(Box::new(law)))
    }

    /// The child's law (a chain's sampled, once for a subtree and its
    /// copies: a RecoveryNode's retries copy the subtree they retry).
    fn law(&self, id: NodeId) -> Result<Law, AnalysisError> {
        match self.piece(id)? {
            Piece::Law(l) => Ok(*l),
            Piece::Chain(c) => {
                let end = self.end.to_bits();
                let kept = self.memo.0.borrow().iter().find_map(|(&(n, e), l)| {
                    (e == end && (n == id || self.tree.same_subtree(n, id))).then(|| l.clone())
                });
                if let Some(l) = kept {
                    return Ok(l);
                }
                let law = self.chain_law(id, &c)?;
                self.memo.0.borrow_mut().insert((id, end), law.clone());
                Ok(law)
            }
        }
    }

    /// Densities `π(t)·exit` of a chain, sampled by uniformization; its
    /// instant returns as atoms at 0.
    fn chain_law(&self, id: NodeId, chain: &PhaseChain) -> Result<Law, AnalysisError> {
        let weights = [&chain.exit_success[..], &chain.exit_failure[..]];
        let mut pass = None;
        let mut d = self.interpolate(id, 2, &[], |points| {
            let rows = sample_weighted_kept(&mut pass, chain, points, &weights)
                .ok_or_else(|| stiff(self.tree, id, chain, self.end))?;
            Ok(rows.iter().flat_map(|r| [r[2], r[3]]).collect())
        })?;
        let failure = d.pop().expect("two densities");
        let success = d.pop().expect("two densities");
        Ok(Law {
            parts: [
                self.measure(
                    vec![(0.0, chain.initial_success)],
                    Some(success),
                    Vec::new(),
                    0.0,
                ),
                self.measure(
                    vec![(0.0, chain.initial_failure)],
                    Some(failure),
                    Vec::new(),
                    0.0,
                ),
            ],
        })
    }

    /// A measure from its parts: atoms sorted, merged at the same instant,
    /// dropped after T or below [`ATOM_FLOOR`] (their mass added to
    /// `dropped`); breaks sorted, merged, inside `(0, T)`, at most
    /// [`MAX_BREAKS`].
    fn measure(
        &self,
        mut atoms: Vec<(f64, f64)>,
        density: Option<Interpolant>,
        mut breaks: Vec<f64>,
        mut dropped: f64,
    ) -> Measure {
        let end = self.end;
        atoms.retain(|&(t, p)| p != 0.0 && (t <= end || same_instant(t, end)));
        atoms.sort_by(|a, b| a.0.total_cmp(&b.0));
        let mut merged: Vec<(f64, f64)> = Vec::with_capacity(atoms.len());
        for (t, p) in atoms {
            match merged.last_mut() {
                Some(l) if same_instant(l.0, t) => l.1 += p,
                _ => merged.push((t, p)),
            }
        }
        merged.retain(|&(_, p)| {
            let keep = p.abs() >= ATOM_FLOOR;
            if !keep {
                dropped += p.abs();
            }
            keep
        });
        breaks.retain(|&b| b > 0.0 && b < end && !same_instant(b, 0.0) && !same_instant(b, end));
        breaks.sort_by(f64::total_cmp);
        breaks.dedup_by(|b, a| same_instant(*a, *b));
        breaks.truncate(MAX_BREAKS);
        // a jump too small to need its own panels is interpolated through
        // (panels that hold it are halved as any others)
        if let Some(d) = &density {
            let floor = JUMP_FLOOR / end.max(1.0);
            breaks.retain(|&b| d.jump_at(b).is_none_or(|j| j > floor));
        }
        Measure {
            atoms: merged,
            density,
            breaks,
            dropped,
            kernel: None,
        }
    }

    /// The law of a leaf without a phase chain: each outcome's time as
    /// atoms and a density.
    fn leaf_law(&self, id: NodeId) -> Result<Law, AnalysisError> {
        let Op::Leaf(Leaf::Action(a)) = &self.tree.node(id).kind else {
            unreachable!("a leaf without a chain is an action")
        };
        Ok(Law {
            parts: [
                self.leaf_measure(id, a.ps, a.success)?,
                self.leaf_measure(id, a.pf, a.failure)?,
            ],
        })
    }

    /// An outcome of probability `p` taking `d`.
    fn leaf_measure(
        &self,
        id: NodeId,
        p: f64,
        d: Option<Duration>,
    ) -> Result<Measure, AnalysisError> {
        let Some(d) = d.filter(|_| p > 0.0) else {
            return Ok(Measure::zero());
        };
        match d {
            Duration::Fixed { time } => Ok(self.measure(vec![(time, p)], None, Vec::new(), 0.0)),
            // min(X, cap): X's density before cap, the rest at cap
            Duration::TruncatedExponential { rate, cap } => {
                let density = self.density(id, &[cap], |points| {
                    Ok(points
                        .iter()
                        .map(|&t| {
                            if t < cap {
                                p * rate * (-rate * t).exp()
                            } else {
                                0.0
                            }
                        })
                        .collect())
                })?;
                let rest = p * (-rate * cap).exp();
                let mut m = self.measure(vec![(cap, rest)], Some(density), vec![cap], 0.0);
                m.kernel = Some(Kernel::leaf(rate, 0.0, 1, p, cap));
                Ok(m)
            }
            // the stages' density, shifted
            Duration::Exponential { .. } | Duration::PhaseType { .. } => {
                let shift = d.shift();
                let chain = d
                    .stages()
                    .expect("exponential and phase-type times have stages")
                    .chain();
                let weights = [&chain.exit_success[..]];
                let mut pass = None;
                let density = self.density(id, &[shift], |points| {
                    let local: Vec<f64> = points.iter().map(|&t| (t - shift).max(0.0)).collect();
                    let rows = sample_weighted_kept(&mut pass, &chain, &local, &weights)
                        .ok_or_else(|| stiff(self.tree, id, &chain, self.end))?;
                    Ok(points
                        .iter()
                        .zip(rows)
                        .map(|(&t, r)| if t >= shift { p * r[2] } else { 0.0 })
                        .collect())
                })?;
                let mut m = self.measure(Vec::new(), Some(density), vec![shift], 0.0);
                m.kernel = match d {
                    Duration::Exponential { rate } => {
                        Some(Kernel::leaf(rate, shift, 1, p, f64::INFINITY))
                    }
                    Duration::PhaseType { stages, .. } if kernel_stages(stages) => {
                        let series = stages.series();
                        let rate = series[series.len() - 1];
                        Some(if series.iter().all(|&r| r == rate) {
                            Kernel::leaf(rate, shift, series.len(), p, f64::INFINITY)
                        } else {
                            Kernel {
                                before: Some(stages),
                                ..Kernel::leaf(rate, shift, 1, p, f64::INFINITY)
                            }
                        })
                    }
                    _ => None,
                };
                Ok(m)
            }
        }
    }

    /// The composed law of any node (one without a chain within the budget,
    /// or the top of a composed curve).
    fn opaque(&self, id: NodeId) -> Result<Law, AnalysisError> {
        let node = self.tree.node(id);
        if let Some(d) = deadline_race(self.tree, id) {
            return self.deadline(id, &d);
        }
        // a renewal race whose R has no phase chain: the process's law from
        // its levels raced with R's (`race::renewal_race`)
        if super::renewal::parts(self.tree, id).is_some() {
            if let Some(race) = super::race::renewal_race(self.children, id, Some(self.end), 0.0)? {
                return self.race_law(id, &race);
            }
        }
        match &node.kind {
            Op::Leaf(Leaf::Action(_)) => self.leaf_law(id),
            Op::KOfN {
                success,
                failure,
                children,
            } if *failure >= children.len() + 1 - success => self.counted(id, children, *success),
            // thresholds that can both be met: ties in child order
            Op::KOfN { .. } => match det::atoms(self.tree, id, self.max_states)? {
                Some(atoms) => Ok(self.atoms_law(&atoms)),
                // the race of its children's laws on the horizon (`race`:
                // phase chains, shifted mixtures, or their own composed
                // laws): its atoms and interpolated densities
                None => {
                    let race = super::race::race_within(self.children, id, self.end)?;
                    self.race_law(id, &race)
                }
            },
            // a chain over simple leaves as their flow
            Op::Flow(flow) => match flow.graph {
                FlowGraph::Chain { stop } => match self.leaf_flow(id)? {
                    Some(law) => Ok(law),
                    None => self.in_turn(id, &flow.children, stop == Outcome::Failure),
                },
                FlowGraph::Repeat { times, stop } => {
                    // a child that fits: its copies are what exceeded the budget
                    let law = self.law(flow.children[0])?;
                    self.repeated(id, &law, times, stop == Outcome::Failure)
                }
                FlowGraph::States(_) => self.flow(id, flow),
            },
            Op::Map {
                child,
                on_success,
                on_failure,
            } => {
                let law = self.law(*child)?;
                if on_success != on_failure {
                    let [s, f] = law.parts;
                    return Ok(match on_success {
                        Outcome::Success => Law { parts: [s, f] },
                        Outcome::Failure => Law { parts: [f, s] },
                    });
                }
                let both = self.add(id, &law.measure(SUCCESS), &law.measure(FAILURE))?;
                let to = match on_success {
                    Outcome::Success => SUCCESS,
                    Outcome::Failure => FAILURE,
                };
                Ok(self.law_from(to, both, Measure::zero()))
            }
            Op::Loop { child, until } => {
                let law = self.law(*child)?;
                self.unbounded(id, &law, *until == Outcome::Failure)
            }
            Op::Leaf(Leaf::Condition { ps }) => Ok(Law {
                parts: [
                    self.measure(vec![(0.0, *ps)], None, Vec::new(), 0.0),
                    self.measure(vec![(0.0, 1.0 - ps)], None, Vec::new(), 0.0),
                ],
            }),
        }
    }

    /// A deadline racing one child (BT.CPP `Timeout`, [`deadline_race`]):
    /// the child's law before the deadline `D`, and Failure at `D` for
    /// what it has not returned by then; at `D` itself the deadline wins a
    /// tie when it comes first in child order (BT.CPP's `Timeout`), the
    /// child's return otherwise. Exact but for re-interpolating the
    /// child's densities cut at `D` (the usual estimate).
    fn deadline(&self, id: NodeId, race: &DeadlineRace) -> Result<Law, AnalysisError> {
        let law = self.law(race.child)?;
        let d = race.time;
        if d > self.end && !same_instant(d, self.end) {
            // the deadline is after the horizon: the child's law is the node's
            return Ok(law);
        }
        let before = |t: f64| {
            if race.deadline_first {
                t < d && !same_instant(t, d)
            } else {
                t < d || same_instant(t, d)
            }
        };
        let cut = |m: &Measure| -> Result<Measure, AnalysisError> {
            let atoms = m.atoms.iter().copied().filter(|a| before(a.0)).collect();
            let density = match &m.density {
                None => None,
                Some(den) => {
                    let mut breaks = m.breaks.clone();
                    breaks.push(d);
                    Some(self.density(id, &breaks, |points| {
                        Ok(points
                            .iter()
                            .map(|&t| if t < d { den.eval(t) } else { 0.0 })
                            .collect())
                    })?)
                }
            };
            let mut breaks = m.breaks.clone();
            breaks.push(d);
            Ok(self.measure(atoms, density, breaks, m.dropped))
        };
        let success = cut(&law.parts[SUCCESS])?;
        let failure = cut(&law.parts[FAILURE])?;
        let rest = (1.0 - success.mass() - failure.mass()).max(0.0);
        let mut atoms = failure.atoms.clone();
        atoms.push((d, rest));
        let failure = self.measure(atoms, failure.density, failure.breaks, failure.dropped);
        Ok(Law {
            parts: [success, failure],
        })
    }

    /// The law of a race (a Parallel whose thresholds can both be met,
    /// `race`): its atoms, and its Success and Failure densities — the count
    /// programme over the children's laws — interpolated on panels that
    /// start at its instants and shifts.
    fn race_law(&self, id: NodeId, race: &super::race::Race) -> Result<Law, AnalysisError> {
        let mut d = self.interpolate(id, 2, race.cuts(), |points| {
            Ok(race
                .densities(points)?
                .iter()
                .flat_map(|r| [r[0], r[1]])
                .collect())
        })?;
        let failure = d.pop().expect("two densities");
        let success = d.pop().expect("two densities");
        let side = |o: usize| race.atoms().iter().map(|a| (a.0, [a.1, a.2][o])).collect();
        Ok(Law {
            parts: [
                self.measure(side(SUCCESS), Some(success), race.cuts().to_vec(), 0.0),
                self.measure(side(FAILURE), Some(failure), race.cuts().to_vec(), 0.0),
            ],
        })
    }

    /// The law of a deterministic subtree's return instants.
    fn atoms_law(&self, atoms: &[det::Atom]) -> Law {
        let side = |o: Outcome| {
            let a = atoms
                .iter()
                .filter(|a| a.outcome == o)
                .map(|a| (a.time, a.prob))
                .collect();
            self.measure(a, None, Vec::new(), 0.0)
        };
        Law {
            parts: [side(Outcome::Success), side(Outcome::Failure)],
        }
    }

    /// A Parallel with the book's thresholds, by counting its children.
    fn counted(&self, id: NodeId, children: &[NodeId], m: usize) -> Result<Law, AnalysisError> {
        let pieces = children
            .iter()
            .map(|&c| self.piece(c))
            .collect::<Result<Vec<_>, _>>()?;
        self.counted_from(id, children, &pieces, m)
    }

    /// Per child and point: `[S, F, s, f]` (the chains sampled in one pass
    /// each).
    fn columns(
        &self,
        children: &[NodeId],
        pieces: &[Piece],
        points: &[f64],
    ) -> Result<Vec<Vec<[f64; 4]>>, AnalysisError> {
        pieces
            .iter()
            .zip(children)
            .map(|(p, &c)| match p {
                Piece::Chain(chain) => {
                    let weights = [&chain.exit_success[..], &chain.exit_failure[..]];
                    sample_weighted(chain, points, &weights)
                        .map(|rows| rows.iter().map(|r| [r[0], r[1], r[2], r[3]]).collect())
                        .ok_or_else(|| stiff(self.tree, c, chain, self.end))
                }
                Piece::Law(l) => Ok(points
                    .iter()
                    .map(|&t| {
                        [
                            l.cdf(SUCCESS, t),
                            l.cdf(FAILURE, t),
                            l.parts[SUCCESS].density_at(t),
                            l.parts[FAILURE].density_at(t),
                        ]
                    })
                    .collect()),
            })
            .collect()
    }

    /// [`Self::counted`] from the children's pieces: the atom at each
    /// instant where a child has one is the jump of the count programme
    /// there; the densities between, its derivative.
    fn counted_from(
        &self,
        id: NodeId,
        children: &[NodeId],
        pieces: &[Piece],
        m: usize,
    ) -> Result<Law, AnalysisError> {
        let f_cap = children.len() + 1 - m;
        // every child's instants, and where its densities may jump or kink
        let mut instants = vec![0.0];
        let mut breaks = Vec::new();
        for p in pieces {
            if let Piece::Law(l) = p {
                for part in &l.parts {
                    instants.extend(part.atoms.iter().map(|a| a.0));
                    breaks.extend(part.atoms.iter().map(|a| a.0));
                    breaks.extend_from_slice(&part.breaks);
                }
            }
        }
        instants.sort_by(f64::total_cmp);
        instants.dedup_by(|b, a| same_instant(*a, *b));
        // the probabilities just after each instant, and just before
        let after = self.columns(children, pieces, &instants)?;
        let mut atoms = [Vec::new(), Vec::new()];
        for (k, &t) in instants.iter().enumerate() {
            let right: Vec<(f64, f64)> = after.iter().map(|c| (c[k][0], c[k][1])).collect();
            let left: Vec<(f64, f64)> = if k == 0 && t == 0.0 {
                vec![(0.0, 0.0); children.len()]
            } else {
                pieces
                    .iter()
                    .zip(&right)
                    .map(|(p, &r)| match p {
                        // continuous after 0
                        Piece::Chain(_) => r,
                        Piece::Law(l) => {
                            (l.parts[SUCCESS].cdf_left(t), l.parts[FAILURE].cdf_left(t))
                        }
                    })
                    .collect()
            };
            let (s1, f1) = counts::status_by_counts(&right, m, f_cap);
            let (s0, f0) = counts::status_by_counts(&left, m, f_cap);
            atoms[SUCCESS].push((t, s1 - s0));
            atoms[FAILURE].push((t, f1 - f0));
        }
        let dropped: f64 = pieces
            .iter()
            .map(|p| match p {
                Piece::Chain(_) => 0.0,
                Piece::Law(l) => l.dropped(),
            })
            .sum();
        let mut d = self.interpolate(id, 2, &breaks, |points| {
            let columns = self.columns(children, pieces, points)?;
            let mut row = vec![[0.0; 4]; children.len()];
            let mut out = Vec::with_capacity(2 * points.len());
            for k in 0..points.len() {
                for (r, col) in row.iter_mut().zip(&columns) {
                    *r = col[k];
                }
                let [_, _, s, f] = counts::status_and_densities_by_counts(&row, m, f_cap);
                out.extend([s, f]);
            }
            Ok(out)
        })?;
        let failure = d.pop().expect("two densities");
        let success = d.pop().expect("two densities");
        let [atoms_s, atoms_f] = atoms;
        Ok(Law {
            parts: [
                self.measure(atoms_s, Some(success), breaks.clone(), dropped),
                self.measure(atoms_f, Some(failure), breaks, 0.0),
            ],
        })
    }

    /// A Sequence (`sequence`) or Fallback: runs of children with chains
    /// concatenated, then the laws folded in order.
    fn in_turn(
        &self,
        id: NodeId,
        children: &[NodeId],
        sequence: bool,
    ) -> Result<Law, AnalysisError> {
        let mut laws = Vec::new();
        let mut run: Vec<PhaseChain> = Vec::new();
        for &c in children {
            match self.piece(c)? {
                Piece::Chain(chain) => run.push(chain),
                Piece::Law(l) => {
                    if !run.is_empty() {
                        let chain = phase::concatenate(std::mem::take(&mut run), sequence);
                        laws.push(self.chain_law(id, &chain)?);
                    }
                    laws.push(*l);
                }
            }
        }
        if !run.is_empty() {
            laws.push(self.chain_law(id, &phase::concatenate(run, sequence))?);
        }
        self.fold(id, &laws, sequence)
    }

    /// A flow: the law of the time each state is entered (`δ₀` for state 0)
    /// carried forward, convolved with the state's child's Success and
    /// Failure laws and added to where each leads.
    fn flow(&self, id: NodeId, flow: &Flow) -> Result<Law, AnalysisError> {
        let laws = flow
            .children
            .iter()
            .map(|&c| self.law(c))
            .collect::<Result<Vec<_>, AnalysisError>>()?;
        self.flow_of(id, flow, &laws)
    }

    /// A subtree of Sequences and Fallbacks over leaves with fixed,
    /// exponential, Erlang or hypoexponential ([`KERNEL_STAGES`] stages at
    /// most), shifted or hybrid times and conditions, as
    /// the flow over its leaves ([`super::flow::leaf_flow`]): every
    /// convolution is then one with a leaf's law — a shift, or the
    /// exponential kernel's recursion — linear in the panels, where folding
    /// the children's laws convolves two densities (quadratic).
    fn leaf_flow(&self, id: NodeId) -> Result<Option<Law>, AnalysisError> {
        let simple = |d: Option<Duration>| match d {
            None | Some(Duration::Fixed { .. }) => true,
            Some(Duration::Exponential { .. } | Duration::TruncatedExponential { .. }) => true,
            Some(Duration::PhaseType { stages, .. }) => kernel_stages(stages),
        };
        let leaf = |c: NodeId| match &self.tree.node(c).kind {
            Op::Leaf(Leaf::Condition { .. }) => true,
            Op::Leaf(Leaf::Action(a)) => simple(a.success) && simple(a.failure),
            _ => false,
        };
        let Some(flow) = super::flow::leaf_flow(self.tree, id, leaf) else {
            return Ok(None);
        };
        let laws = flow
            .children
            .iter()
            .map(|&c| match self.tree.node(c).kind {
                Op::Leaf(Leaf::Condition { ps }) => Ok(Law {
                    parts: [
                        self.measure(vec![(0.0, ps)], None, Vec::new(), 0.0),
                        self.measure(vec![(0.0, 1.0 - ps)], None, Vec::new(), 0.0),
                    ],
                }),
                _ => self.leaf_law(c),
            })
            .collect::<Result<Vec<_>, AnalysisError>>()?;
        self.flow_of(id, &flow, &laws).map(Some)
    }

    /// A flow whose children's laws are `laws`.
    fn flow_of(&self, id: NodeId, flow: &Flow, laws: &[Law]) -> Result<Law, AnalysisError> {
        let states = flow.states();
        let mut entered: Vec<Option<Measure>> = vec![None; states.len()];
        entered[0] = Some(Measure::unit());
        let mut ends = [Measure::zero(), Measure::zero()];
        for (i, s) in states.iter().enumerate() {
            let Some(here) = entered[i].take() else {
                continue;
            };
            if here.mass() < NEGLIGIBLE {
                continue;
            }
            for (o, next) in [(SUCCESS, s.on_success), (FAILURE, s.on_failure)] {
                let m = self.convolve(id, &here, &laws[s.child].measure(o))?;
                let slot = match next {
                    FlowNext::State(j) => &mut entered[j],
                    FlowNext::Success => {
                        ends[SUCCESS] = self.add(id, &ends[SUCCESS], &m)?;
                        continue;
                    }
                    FlowNext::Failure => {
                        ends[FAILURE] = self.add(id, &ends[FAILURE], &m)?;
                        continue;
                    }
                };
                *slot = Some(match slot.take() {
                    Some(before) => self.add(id, &before, &m)?,
                    None => m,
                });
            }
        }
        Ok(Law { parts: ends })
    }

    /// Children's laws run in turn; a Sequence (`sequence`) goes on after a
    /// Success and stops at a Failure, a Fallback the other way round:
    /// `G_0 = δ₀`, `G_k = G_{k−1} ⊛ go_k`, stopping with `Σ_k G_{k−1} ⊛ stop_k`.
    fn fold(&self, id: NodeId, laws: &[Law], sequence: bool) -> Result<Law, AnalysisError> {
        let (go, stop) = outcomes(sequence);
        let mut reach = Measure::unit();
        let mut stopped = Measure::zero();
        for law in laws {
            if reach.mass() < NEGLIGIBLE {
                break;
            }
            let here = self.convolve(id, &reach, &law.parts[stop])?;
            stopped = self.add(id, &stopped, &here)?;
            reach = self.convolve(id, &reach, &law.parts[go])?;
        }
        Ok(self.law_from(go, reach, stopped))
    }

    /// `n` fresh runs of one law in turn (Repeat: a Sequence; Retry: a
    /// Fallback), by binary powering: with `P_k = go^{⊛k}` and `Q_k = Σ_{j<k}
    /// go^{⊛j}`, the node goes on with `P_n` and stops with `Q_n ⊛ stop`;
    /// `P_{2k} = P_k ⊛ P_k`, `Q_{2k} = Q_k + P_k ⊛ Q_k`, `P_{k+1} = P_k ⊛ go`,
    /// `Q_{k+1} = Q_k + P_k` — O(log n) convolutions. Once `P_k` carries
    /// less than 1e-17 within the horizon, later runs change nothing there.
    fn repeated(
        &self,
        id: NodeId,
        law: &Law,
        n: usize,
        sequence: bool,
    ) -> Result<Law, AnalysisError> {
        let (go, stop) = outcomes(sequence);
        let step = law.measure(go);
        let (mut p, mut q) = (Measure::unit(), Measure::zero());
        for bit in (0..usize::BITS - n.leading_zeros()).rev() {
            // the runs still to add are at most n, each within P_k's mass
            if p.mass() * (n as f64) < NEGLIGIBLE {
                break;
            }
            let pq = self.convolve(id, &p, &q)?;
            q = self.add(id, &q, &pq)?;
            p = self.convolve(id, &p, &p)?;
            if n >> bit & 1 == 1 {
                q = self.add(id, &q, &p)?;
                p = self.convolve(id, &p, &step)?;
            }
        }
        let stopped = self.convolve(id, &q, &law.measure(stop))?;
        Ok(self.law_from(go, p, stopped))
    }

    /// A loop without a bound (`until_failure`: `sequence`, on the
    /// child's Success; `until_success` on its Failure) on `[0, T]`: it
    /// returns with the child's other outcome after `n ≥ 0` runs that went
    /// on, `Σ_n G^{*n} ⊛ stop` (`G` the law of a run that goes on), the
    /// solution of a renewal equation marched in time ([`Self::renewal`]).
    /// Within `[0, T]` it never returns otherwise (the runs still going
    /// after `T`); a child that goes on at once for sure (an atom of mass 1
    /// at 0: it would loop within one instant) is refused.
    fn unbounded(&self, id: NodeId, law: &Law, sequence: bool) -> Result<Law, AnalysisError> {
        let (go, stop) = outcomes(sequence);
        if law.parts[stop].mass() == 0.0 {
            // the child cannot end the loop within the horizon: every term
            // of the series is a convolution with that zero measure
            return Ok(self.law_from(go, Measure::zero(), Measure::zero()));
        }
        let stopped = self.renewal(id, &law.parts[go], &law.parts[stop])?;
        Ok(self.law_from(go, Measure::zero(), stopped))
    }

    /// The atoms `R_a = Σ_n (p₀δ₀ + Σ pᵢδ_{aᵢ})^{*n} ⊛ start` on the
    /// horizon (`delays` the `(aᵢ, pᵢ)`, `scale = 1/(1 − p₀)`), instant by
    /// instant in increasing order: `R_a(t) = scale·(start(t) + Σ pᵢ
    /// R_a(t − aᵢ))`. Atoms below [`ATOM_FLOOR`] are dropped (their mass
    /// returned); more than the budget's is refused.
    fn renewal_atoms(
        &self,
        id: NodeId,
        delays: &[(f64, f64)],
        scale: f64,
        start: &[(f64, f64)],
    ) -> Result<(Vec<(f64, f64)>, f64), AnalysisError> {
        let end = self.end;
        // keys: the bits of non-negative instants, ordered as the instants
        let mut heap: std::collections::BTreeMap<u64, f64> = std::collections::BTreeMap::new();
        for &(at, w) in start {
            *heap.entry(at.to_bits()).or_insert(0.0) += w;
        }
        let mut atoms: Vec<(f64, f64)> = Vec::new();
        let mut dropped = 0.0;
        while let Some((k, mut w)) = heap.pop_first() {
            let at = f64::from_bits(k);
            while let Some((&k2, _)) = heap.first_key_value() {
                if !same_instant(f64::from_bits(k2), at) {
                    break;
                }
                w += heap.pop_first().map_or(0.0, |e| e.1);
            }
            let r = w * scale;
            if r.abs() < ATOM_FLOOR {
                dropped += r.abs();
                continue;
            }
            atoms.push((at, r));
            if atoms.len() > self.max_states {
                return Err(AnalysisError::StateBudget {
                    node: self.name(id),
                    states: atoms.len() as f64,
                    budget: self.max_states,
                });
            }
            for &(a, p) in delays {
                let next = at + a;
                if next <= end || same_instant(next, end) {
                    *heap.entry(next.to_bits()).or_insert(0.0) += p * r;
                }
            }
        }
        Ok((atoms, dropped))
    }

    /// `R = Σ_n G^{*n} ⊛ T` on `[0, T_end]`, the solution of the renewal
    /// equation `R = T + G ⊛ R`, marched in time instead of summed: with
    /// `G = p₀δ₀ + Σ pᵢδ_{aᵢ} + g` (`aᵢ > 0`) and `T = T_a + τ`, R's atoms
    /// are the discrete renewal `R_a(t) = (T_a(t) + Σ pᵢ R_a(t − aᵢ)) / (1 −
    /// p₀)`, taken instant by instant in increasing order, and its density
    /// solves `r(t) = (τ(t) + (g ⊛ R_a)(t) + Σ pᵢ r(t − aᵢ) + ∫₀ᵗ g(u)
    /// r(t − u) du) / (1 − p₀)`, built panel by panel from the left
    /// ([`build_marching`]): the parts before a panel are known, and on the
    /// panel the equation is linear in the panel polynomial's values at its
    /// points — collocation there, `(I − c(M + D)) v = c·(known)` with `M`
    /// the panel's convolution with `g` and `D` its own delayed values —
    /// solved directly (a panel whose system is singular is halved; the
    /// interpolation's tail test then decides the panel as for any
    /// density). Its kinks and jumps are at the sums of the delays plus T's
    /// breaks, and at R's atoms plus g's breaks, where panels start. Its
    /// cost is about one convolution's: the series by doubling it replaced
    /// took `2 log₂ K` convolutions for `K` runs (Nav2's fitted re-planning
    /// law to 857 s: 0.9 s → 0.1 s, the same figures within 2e-14).
    fn renewal(&self, id: NodeId, g: &Measure, t: &Measure) -> Result<Measure, AnalysisError> {
        let end = self.end;
        let at_zero = |a: &(f64, f64)| same_instant(a.0, 0.0);
        let p0: f64 = g.atoms.iter().filter(|a| at_zero(a)).map(|a| a.1).sum();
        if p0 >= 1.0 - 1e-12 {
            // it goes on at once for sure: it loops within one instant
            return Err(AnalysisError::Unbounded {
                node: self.name(id),
            });
        }
        let scale = 1.0 / (1.0 - p0);
        let delays: Vec<(f64, f64)> = g.atoms.iter().filter(|a| !at_zero(a)).copied().collect();
        let delay_mass: f64 = delays.iter().map(|a| a.1).sum::<f64>() * scale;
        let (atoms, mut dropped) = self.renewal_atoms(id, &delays, scale, &t.atoms)?;
        // what an atom dropped would have started (its renewals too)
        if delay_mass < 1.0 {
            dropped /= 1.0 - delay_mass;
        }
        dropped += t.dropped * scale + g.dropped * (t.mass() + t.dropped) * scale;
        let (gd, td) = (g.density.as_ref(), t.density.as_ref());
        if gd.is_none() && td.is_none() {
            return Ok(self.measure(atoms, None, Vec::new(), dropped));
        }
        // where r may jump or kink: at R's atoms plus g's jumps (g's start
        // included), and where the delays' renewals carry τ's jumps — each
        // kept where its jump is not negligible (as `measure` keeps them)
        let floor = JUMP_FLOOR / end.max(1.0);
        let limit = 4 * MAX_BREAKS;
        let mut breaks: Vec<f64> = Vec::new();
        if let Some(gd) = gd {
            let starts = gd.eval(0.0).abs();
            for &(at, r) in &atoms {
                if breaks.len() >= limit {
                    break;
                }
                if r.abs() * starts > floor {
                    breaks.push(at);
                }
                for s in &g.breaks {
                    // (a break without a panel edge is kept, as `measure` does)
                    if at + s < end && gd.jump_at(*s).is_none_or(|j| r.abs() * j > floor) {
                        breaks.push(at + s);
                    }
                }
            }
        }
        if let (Some(td), false) = (td, t.breaks.is_empty()) {
            let (renewals, _) = self.renewal_atoms(id, &delays, scale, &[(0.0, 1.0)])?;
            for &(l, w) in &renewals {
                if breaks.len() >= 2 * limit {
                    break;
                }
                for s in &t.breaks {
                    if l + s < end && td.jump_at(*s).is_none_or(|j| w.abs() * j > floor) {
                        breaks.push(l + s);
                    }
                }
            }
        }
        let breaks = self.measure(Vec::new(), None, breaks, 0.0).breaks;
        let g_support = gd.and_then(Interpolant::support);
        let g_panels = gd.map_or(0, Interpolant::panels) as f64;
        let g_gauss = gd.map_or(Vec::new(), Interpolant::gauss_values);
        let mut done_gauss: Vec<[f64; POINTS]> = Vec::new();
        // R's mass within the horizon is at most |T|/(1 − |G|) (masses
        // within it): once what it has returned by a panel's start is within
        // 1e-15 of that, the rest of its density is negligible (and counted
        // as dropped below)
        let bound = match g.mass() {
            m if m < 1.0 - 1e-9 => t.mass() / (1.0 - m),
            _ => f64::INFINITY,
        };
        // the atoms' mass up to each (they come in increasing order)
        let cumulative: Vec<f64> = std::iter::once(0.0)
            .chain(atoms.iter().scan(0.0, |acc, x| {
                *acc += x.1;
                Some(*acc)
            }))
            .collect();
        let returned = |done: &Interpolant| {
            let a = done.end();
            cumulative[atoms.partition_point(|x| x.0 <= a)] + done.total()
        };
        let cut = std::cell::Cell::new(None);
        let settled = |done: &Interpolant| {
            let rest = bound - returned(done);
            let settled = rest <= SETTLED_MASS * bound;
            if settled {
                cut.set(Some(rest.max(0.0)));
            }
            settled
        };
        // g's density in closed form (`Kernel`: shifted exponential and
        // Erlang terms of one rate): g ⊛ (R's atoms + r before the panel)
        // by the Erlang recursion, linear in the panels (`ErlangMarch`),
        // where the general convolution reads every panel within g's reach
        // at every point (random survey trees 1510, an `until_success`
        // whose run fails at a lattice instant or after a shifted
        // exponential, and 2014, whose run is a Retry of such runs)
        let mut recursion = g
            .kernel
            .as_ref()
            .filter(|k| k.before.is_none() && k.positive())
            .map(|k| {
                let rates = k.rates();
                let z_atoms: Vec<ErlangConvolution> = rates
                    .iter()
                    .map(|&(r, m)| ErlangConvolution::new(r, m, &atoms, None))
                    .collect();
                let z_done: Vec<ErlangMarch> =
                    rates.iter().map(|&(r, m)| ErlangMarch::new(r, m)).collect();
                (k, rates, z_atoms, z_done)
            });
        let density = build_marching(end, &breaks, self.narrow, settled, |done, a, b, points| {
            // on the panel the equation is linear in its values v:
            // (I − c(M + D)) v = c(known + delays from before), M the
            // panel's convolution with g, D its own delayed values
            let mut matrix = match gd {
                Some(g) => panel_convolution(g, g_support, a, b, points),
                None => [[0.0; POINTS]; POINTS],
            };
            let before = |x: f64| {
                if x < 0.0 || done.panels() == 0 {
                    0.0
                } else {
                    done.eval(x)
                }
            };
            let mut delayed = [0.0; POINTS];
            for k in 0..POINTS {
                for &(ai, pi) in &delays {
                    let y = points[k] - ai;
                    if y < a {
                        delayed[k] += pi * before(y);
                    } else {
                        let w = panel_weights(a, b, y);
                        for j in 0..POINTS {
                            matrix[k][j] += pi * w[j];
                        }
                    }
                }
            }
            // the work of the convolutions (as a convolution's: the input
            // panels each output panel reads): g's, and r's before it
            // within g's reach
            let window = match g_support {
                Some((_, reach)) => {
                    done.panels()
                        - done
                            .edges()
                            .partition_point(|&e| e < a - reach)
                            .min(done.panels())
                }
                None => 0,
            };
            let work = match recursion {
                Some(_) => self.work.get() + 1.0,
                None => self.work.get() + g_panels.max(1.0) + window as f64,
            };
            if work > MAX_CONVOLUTION_WORK {
                return Err(AnalysisError::ConvolutionWork {
                    node: self.name(id),
                    horizon: end,
                    work,
                    limit: MAX_CONVOLUTION_WORK,
                });
            }
            self.work.set(work);
            // what does not depend on r on the panel: τ, g ⊛ R_a, g ⊛ r
            // before the panel
            let (from_atoms, known): (Vec<f64>, Vec<f64>) = match &mut recursion {
                Some((k, rates, z_atoms, z_done)) => {
                    z_done.iter_mut().for_each(|z| z.catch_up(done));
                    (
                        points
                            .iter()
                            .map(|&x| k.apply(rates, x, &mut |r, y, out| z_atoms[r].at(y, out)))
                            .collect(),
                        points
                            .iter()
                            .map(|&x| {
                                k.apply(rates, x, &mut |r, y, out| z_done[r].at(done, y, out))
                            })
                            .collect(),
                    )
                }
                None => {
                    while done_gauss.len() < done.panels() {
                        done_gauss.push(done.panel_gauss(done_gauss.len()));
                    }
                    let supports = (done.support(), g_support);
                    let known = points
                        .par_iter()
                        .with_min_len(4)
                        .map(|&x| {
                            gd.map_or(0.0, |g| {
                                done.convolve_point(g, supports, (&done_gauss, &g_gauss), x)
                            })
                        })
                        .collect();
                    (shifted_many(&atoms, gd, points), known)
                }
            };
            let mut rhs = [0.0; POINTS];
            for k in 0..POINTS {
                let x = points[k];
                let own = td.map_or(0.0, |d| d.eval(x)) + from_atoms[k] + known[k];
                rhs[k] = scale * (own + delayed[k]);
            }
            for (k, row) in matrix.iter_mut().enumerate() {
                for (j, x) in row.iter_mut().enumerate() {
                    *x = f64::from(u8::from(k == j)) - scale * *x;
                }
            }
            Ok(solve_dense(matrix, rhs))
        })
        .map_err(|e| match e {
            BuildError::Sample(e) => e,
            BuildError::NotConverged => AnalysisError::Numerical {
                node: self.name(id),
                what: "its loop's renewal density did not converge".into(),
            },
        })?;
        // what a density cut where it had settled may have left out
        if let Some(rest) = cut.get() {
            dropped += rest;
        }
        Ok(self.measure(atoms, Some(density), breaks, dropped))
    }

    fn law_from(&self, go: usize, going: Measure, stopped: Measure) -> Law {
        let mut parts = [Measure::zero(), Measure::zero()];
        parts[go] = going;
        parts[1 - go] = stopped;
        Law { parts }
    }

    /// `(Σ a_i δ_{τ_i} + g) ⊛ (Σ b_j δ_{σ_j} + h) = Σ a_i b_j δ_{τ_i+σ_j} +
    /// Σ a_i h(· − τ_i) + Σ b_j g(· − σ_j) + g * h`.
    fn convolve(&self, id: NodeId, x: &Measure, y: &Measure) -> Result<Measure, AnalysisError> {
        let pairs = x.atoms.len() as f64 * y.atoms.len() as f64;
        if pairs > self.max_states as f64 {
            return Err(AnalysisError::StateBudget {
                node: self.name(id),
                states: pairs,
                budget: self.max_states,
            });
        }
        // dropped mass d_x carried by y's mass (and d_y by x's) within [0, T]
        let dropped = x.dropped * (y.mass() + y.dropped) + y.dropped * x.mass();
        // δ_0-only factors scale the other
        for (a, b) in [(x, y), (y, x)] {
            if a.density.is_none() && a.atoms.len() == 1 && a.atoms[0].0 == 0.0 {
                let c = a.atoms[0].1;
                let mut out = b.clone();
                out.atoms.iter_mut().for_each(|t| t.1 *= c);
                out.density = b.density.as_ref().map(|d| d.scaled(c));
                out.dropped = c.abs() * b.dropped + a.dropped * (b.mass() + b.dropped);
                out.kernel = b.kernel.clone().map(|k| k.scaled(c));
                return Ok(out);
            }
        }
        let end = self.end;
        let mut atoms = Vec::with_capacity(pairs as usize);
        for &(a, p) in &x.atoms {
            for &(b, q) in &y.atoms {
                if a + b <= end || same_instant(a + b, end) {
                    atoms.push((a + b, p * q));
                }
            }
        }
        if x.density.is_none() && y.density.is_none() {
            return Ok(self.measure(atoms, None, Vec::new(), dropped));
        }
        // kernels (leaves' exponential and Erlang times, and what they
        // compose into): the result's density in closed form where both
        // sides' are (or have none), else by the Erlang recursion, linear
        // in the panels
        if let Some(k) = Kernel::convolution(x, y, end).filter(|k| k.before.is_none()) {
            let breaks: Vec<f64> = k.terms.iter().map(|t| t.shift).collect();
            let breaks = self.measure(Vec::new(), None, breaks, 0.0).breaks;
            let density = self.density(id, &breaks, |points| Ok(k.eval_many(points)))?;
            let mut out = self.measure(atoms, Some(density), breaks, dropped);
            out.kernel = Some(k);
            return Ok(out);
        }
        let kernel_case = match (&x.kernel, &y.kernel) {
            (_, Some(k)) => Some((x, y, k)),
            (Some(k), None) => Some((y, x, k)),
            (None, None) => None,
        };
        if let Some((other, with, k)) = kernel_case {
            let mut out = self.convolve_kernel(id, other, with, k, atoms, dropped)?;
            out.kernel = Kernel::convolution(x, y, end);
            return Ok(out);
        }
        // a density jumps at an atom plus a jump of the density it shifts
        // (g * h is continuous: its kinks are resolved by halving panels)
        let limit = 4 * MAX_BREAKS;
        let mut breaks: Vec<f64> = Vec::new();
        for (a, b) in [(x, y), (y, x)] {
            if b.density.is_none() {
                continue;
            }
            for &(t, _) in &a.atoms {
                if breaks.len() >= limit || t > end {
                    break;
                }
                breaks.push(t);
                breaks.extend(b.breaks.iter().map(|s| t + s).take_while(|&s| s < end));
            }
        }
        let breaks = self.measure(Vec::new(), None, breaks, 0.0).breaks;
        // its work, estimated with as many panels as the longer density
        let panels = match (&x.density, &y.density) {
            (Some(g), Some(h)) => Some((g.panels() + h.panels(), g.panels().max(h.panels()))),
            _ => None,
        };
        if let Some((both, longer)) = panels {
            let work = self.work.get() + (both * longer) as f64;
            if work > MAX_CONVOLUTION_WORK {
                return Err(AnalysisError::ConvolutionWork {
                    node: self.name(id),
                    horizon: self.end,
                    work,
                    limit: MAX_CONVOLUTION_WORK,
                });
            }
        }
        // both densities' supports and panel values, once for every batch
        let convolution = match (&x.density, &y.density) {
            (Some(g), Some(h)) => Some(g.convolution(h)),
            _ => None,
        };
        let density = self.density(id, &breaks, |points| {
            let conv = match &convolution {
                Some(c) => c.many(points),
                None => vec![0.0; points.len()],
            };
            let xs = shifted_many(&x.atoms, y.density.as_ref(), points);
            let ys = shifted_many(&y.atoms, x.density.as_ref(), points);
            Ok(conv
                .iter()
                .zip(xs)
                .zip(ys)
                .map(|((c, a), b)| c + a + b)
                .collect())
        })?;
        if let Some((both, _)) = panels {
            self.work
                .set(self.work.get() + (both * density.panels()) as f64);
        }
        Ok(self.measure(atoms, Some(density), breaks, dropped))
    }

    /// [`Self::convolve`] where `y`'s density is the closed form `k`:
    /// `y = atoms + Σ w·E_m(· − s)`, so that
    /// `x ⊛ y = x ⊛ atoms + Σ w·z_m(· − s)` with `z_m = E_m ⊛ x`
    /// ([`ErlangConvolution`], after `k`'s stages of other rates, if any);
    /// `atoms` are the products of both measures' atoms.
    fn convolve_kernel(
        &self,
        id: NodeId,
        x: &Measure,
        y: &Measure,
        k: &Kernel,
        atoms: Vec<(f64, f64)>,
        dropped: f64,
    ) -> Result<Measure, AnalysisError> {
        let end = self.end;
        // the stages before the last one, one interpolated density each
        let series = k.before.map(Stages::series).unwrap_or_default();
        let mut through = std::borrow::Cow::Borrowed(x);
        for &rate in series.iter().take(series.len().saturating_sub(1)) {
            let z = ErlangConvolution::new(rate, 1, &through.atoms, through.density.as_ref());
            let jumps: Vec<f64> = through.atoms.iter().map(|a| a.0).collect();
            let density = self.density(id, &jumps, |points| {
                Ok(points
                    .iter()
                    .map(|&t| {
                        let mut out = [0.0; MAX_STAGES];
                        z.at(t, &mut out);
                        out[0]
                    })
                    .collect())
            })?;
            through = std::borrow::Cow::Owned(self.measure(Vec::new(), Some(density), jumps, 0.0));
        }
        let rates = k.rates();
        let z: Vec<ErlangConvolution> = rates
            .iter()
            .map(|&(r, m)| ErlangConvolution::new(r, m, &through.atoms, through.density.as_ref()))
            .collect();
        // z jumps at the atoms it convolves (x's; none after a first
        // stage) and only kinks at x's breaks; the terms' shifts move those
        // jumps, y's atoms x's own
        let mut breaks: Vec<f64> = Vec::new();
        let limit = 4 * MAX_BREAKS;
        let from_x: Vec<f64> = std::iter::once(0.0)
            .chain(through.atoms.iter().map(|a| a.0))
            .collect();
        let mut shifts: Vec<f64> = k.terms.iter().map(|t| t.shift).collect();
        shifts.dedup();
        for shift in shifts {
            breaks.extend(from_x.iter().map(|b| b + shift).take_while(|&b| b < end));
        }
        if x.density.is_some() {
            for &(t, _) in &y.atoms {
                if breaks.len() >= limit || t > end {
                    break;
                }
                breaks.push(t);
                breaks.extend(x.breaks.iter().map(|s| t + s).take_while(|&s| s < end));
            }
        }
        breaks.truncate(limit);
        let breaks = self.measure(Vec::new(), None, breaks, 0.0).breaks;
        let density = self.density(id, &breaks, |points| {
            let kernel = |t: f64| k.apply(&rates, t, &mut |r, u, out| z[r].at(u, out));
            let kernel: Vec<f64> = if points.len() >= 4096 {
                points.par_iter().map(|&t| kernel(t)).collect()
            } else {
                points.iter().map(|&t| kernel(t)).collect()
            };
            let ys = shifted_many(&y.atoms, x.density.as_ref(), points);
            Ok(kernel.iter().zip(ys).map(|(a, b)| a + b).collect())
        })?;
        Ok(self.measure(atoms, Some(density), breaks, dropped))
    }

    fn add(&self, id: NodeId, x: &Measure, y: &Measure) -> Result<Measure, AnalysisError> {
        let density = match (&x.density, &y.density) {
            (None, d) | (d, None) => d.clone(),
            (Some(g), Some(h)) => {
                let breaks: Vec<f64> = x.breaks.iter().chain(&y.breaks).copied().collect();
                let breaks = self.measure(Vec::new(), None, breaks, 0.0).breaks;
                Some(self.density(id, &breaks, |points| {
                    let (gv, hv) = (g.eval_many(points), h.eval_many(points));
                    Ok(gv.iter().zip(hv).map(|(a, b)| a + b).collect())
                })?)
            }
        };
        let atoms = x.atoms.iter().chain(&y.atoms).copied().collect();
        let breaks = x.breaks.iter().chain(&y.breaks).copied().collect();
        let mut out = self.measure(atoms, density, breaks, x.dropped + y.dropped);
        // the density is one side's, or the sum of two kernels: its
        // closed form too
        out.kernel = match (&x.density, &y.density) {
            (Some(_), None) => x.kernel.clone(),
            (None, Some(_)) => y.kernel.clone(),
            _ => match (&x.kernel, &y.kernel) {
                (Some(a), Some(b)) => Kernel::sum(a, b),
                _ => None,
            },
        };
        Ok(out)
    }
}

/// `Σ a_i h(t − τ_i)` over `atoms` `(τ_i, a_i)` at each of `points`, 0
/// without `h` (each atom's shift evaluated in blocks).
/// The solution of `A x = b` by Gaussian elimination with partial
/// pivoting; `None` if `A` is singular (or a result is not finite).
fn solve_dense(mut a: [[f64; POINTS]; POINTS], mut b: [f64; POINTS]) -> Option<[f64; POINTS]> {
    for col in 0..POINTS {
        let pivot = (col..POINTS).max_by(|&i, &j| a[i][col].abs().total_cmp(&a[j][col].abs()))?;
        if a[pivot][col] == 0.0 {
            return None;
        }
        a.swap(col, pivot);
        b.swap(col, pivot);
        for row in col + 1..POINTS {
            let f = a[row][col] / a[col][col];
            if f != 0.0 {
                let pivot_row = a[col];
                for (x, p) in a[row][col..].iter_mut().zip(&pivot_row[col..]) {
                    *x -= f * p;
                }
                b[row] -= f * b[col];
            }
        }
    }
    let mut x = [0.0; POINTS];
    for row in (0..POINTS).rev() {
        let mut v = b[row];
        for k in row + 1..POINTS {
            v -= a[row][k] * x[k];
        }
        x[row] = v / a[row][row];
    }
    x.iter().all(|v| v.is_finite()).then_some(x)
}

fn shifted_many(atoms: &[(f64, f64)], h: Option<&Interpolant>, points: &[f64]) -> Vec<f64> {
    let mut out = vec![0.0; points.len()];
    let Some(h) = h else { return out };
    let mut local = vec![0.0; points.len()];
    for &(tau, a) in atoms {
        for (l, &t) in local.iter_mut().zip(points) {
            *l = t - tau;
        }
        for (o, v) in out.iter_mut().zip(h.eval_many(&local)) {
            *o += a * v;
        }
    }
    out
}

/// Whether a time of these stages is a [`Kernel`]: stages in series
/// (Erlang, hypoexponential; not a general phase-type law), at most
/// [`KERNEL_STAGES`] of them.
fn kernel_stages(stages: &Stages) -> bool {
    stages.as_general().is_none() && (1..=KERNEL_STAGES).contains(&stages.phases())
}

/// `(go, stop)`: the outcome on which a Sequence (`sequence`) goes on to
/// its next child, and the one on which it returns.
fn outcomes(sequence: bool) -> (usize, usize) {
    if sequence {
        (SUCCESS, FAILURE)
    } else {
        (FAILURE, SUCCESS)
    }
}

/// A measure on `[0, T]`: atoms `(instant, mass)` (sorted, distinct
/// instants) and a density (`None` = 0) that may jump or kink at `breaks`.
#[derive(Debug, Clone, Default)]
struct Measure {
    atoms: Vec<(f64, f64)>,
    density: Option<Interpolant>,
    breaks: Vec<f64>,
    /// Mass of the atoms dropped below [`ATOM_FLOOR`].
    dropped: f64,
    /// The density's closed form when it is a leaf's exponential time
    /// (`convolve` then takes the exponential kernel's recursion).
    kernel: Option<Kernel>,
}

/// A density in closed form, `Σ w·E_m(λ; t − s)` over its terms
/// `(s, λ, m, w)`, `E_m(λ; ·)` the Erlang-`m` density of rate `λ`
/// ([`erlang_densities`]): a leaf's exponential or Erlang time, shifted;
/// the random side of a hybrid (`w·E_1(t)` cut at the cap: a term
/// `−w e^{−λc}·E_1(t − c)` cancels it after); and their sums and
/// convolutions — closed under both: two terms of one rate convolve into
/// one (shifts and stages add), two of different rates into terms of both
/// by partial fractions (while the cancellation they bring, tracked across
/// convolutions, stays within [`MAX_AMPLIFICATION`]), so that a
/// Retry's or a Sequence's law over such leaves keeps its closed form and a
/// loop over it its linear renewal march (`ErlangMarch`, one per rate).
/// With `before`, a hypoexponential leaf's time: those stages of other
/// rates in series first (all but the last of `before`'s series; then terms
/// of one stage of the last rate, one per shift).
#[derive(Debug, Clone)]
struct Kernel {
    terms: Vec<Term>,
    before: Option<&'static Stages>,
    /// How far `Σ |w|` exceeds what the same laws would have without
    /// partial fractions (1 for a leaf; products along convolutions): the
    /// cancellation its evaluation suffers, at most [`MAX_AMPLIFICATION`].
    amplification: f64,
}

/// `weight·E_stages(rate; t − shift)`.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Term {
    shift: f64,
    rate: f64,
    stages: usize,
    weight: f64,
}

/// Most stages in series that a leaf's time may have to be a kernel (each
/// is one pass of [`ErlangConvolution`] and one interpolation).
const KERNEL_STAGES: u32 = MAX_STAGES as u32;

/// Most terms a kernel keeps (a sum or convolution with more has none: its
/// density is interpolated as any other's).
const MAX_KERNEL_TERMS: usize = 64;

/// Largest [`Kernel::amplification`]: partial fractions of close rates
/// cancel, each factor of 10 costing a digit of the density's accuracy,
/// and a density evaluated with rounding noise far above its own size
/// makes its interpolation halve panels without end (a trial that took
/// hypoexponential leaves as partial fractions, checking each convolution
/// only against its factors, ran out of memory on survey tree 1531: a
/// Retry 4 over rates 1.236 and 1.218, 136 a factor).
const MAX_AMPLIFICATION: f64 = 1e3;

impl Kernel {
    /// `weight·E_stages(rate; · − shift)`, cut at `shift + cap` (`cap`
    /// infinite: not cut).
    fn leaf(rate: f64, shift: f64, stages: usize, weight: f64, cap: f64) -> Kernel {
        let mut terms = vec![Term {
            shift,
            rate,
            stages,
            weight,
        }];
        if cap.is_finite() {
            terms.push(Term {
                shift: shift + cap,
                rate,
                stages: 1,
                weight: -weight * (-rate * cap).exp(),
            });
        }
        Kernel {
            terms,
            before: None,
            amplification: 1.0,
        }
    }

    fn scaled(mut self, c: f64) -> Kernel {
        self.terms.iter_mut().for_each(|t| t.weight *= c);
        self
    }

    /// Its distinct rates, each with its largest stage count.
    fn rates(&self) -> Vec<(f64, usize)> {
        let mut out: Vec<(f64, usize)> = Vec::new();
        for t in &self.terms {
            match out.iter_mut().find(|r| r.0 == t.rate) {
                Some(r) => r.1 = r.1.max(t.stages),
                None => out.push((t.rate, t.stages)),
            }
        }
        out
    }

    /// Whether every rate is positive (the recursions need it).
    fn positive(&self) -> bool {
        self.terms.iter().all(|t| t.rate > 0.0)
    }

    /// Its terms summed where they have the same shift, rate and stages, in
    /// order of shift; `None` past [`MAX_KERNEL_TERMS`].
    fn merged(mut self) -> Option<Kernel> {
        self.terms.sort_by(|a, b| {
            a.shift
                .total_cmp(&b.shift)
                .then(a.rate.total_cmp(&b.rate))
                .then(a.stages.cmp(&b.stages))
        });
        let mut out: Vec<Term> = Vec::with_capacity(self.terms.len());
        for t in self.terms {
            match out
                .iter_mut()
                .rev()
                .take_while(|o| same_instant(o.shift, t.shift))
                .find(|o| o.rate == t.rate && o.stages == t.stages)
            {
                Some(o) => o.weight += t.weight,
                None => out.push(Term {
                    shift: out
                        .last()
                        .filter(|o| same_instant(o.shift, t.shift))
                        .map_or(t.shift, |o| o.shift),
                    ..t
                }),
            }
        }
        out.retain(|t| t.weight != 0.0);
        self.terms = out;
        (self.terms.len() <= MAX_KERNEL_TERMS).then_some(self)
    }

    /// The kernel of `x + y`'s density where both densities are kernels.
    fn sum(x: &Kernel, y: &Kernel) -> Option<Kernel> {
        if x.before.is_some() || y.before.is_some() {
            return None;
        }
        let mut k = x.clone();
        k.terms.extend_from_slice(&y.terms);
        k.amplification = x.amplification.max(y.amplification);
        k.merged()
    }

    /// `E_m(a) ⊛ E_n(b)` as terms at shift `shift`, `weight` times: one
    /// term for one rate, else by partial fractions of
    /// `aᵐbⁿ/((s + a)ᵐ(s + b)ⁿ)`: the weight of `E_k(a)` is
    /// `a^{m−k} bⁿ (−1)^{m−k} C(n + m − k − 1, m − k) / (b − a)^{n+m−k}`,
    /// and symmetrically for `b`.
    fn pair(s: &Term, t: &Term, out: &mut Vec<Term>) -> Option<()> {
        let shift = s.shift + t.shift;
        let weight = s.weight * t.weight;
        if s.rate == t.rate {
            if s.stages + t.stages > MAX_STAGES {
                return None;
            }
            out.push(Term {
                shift,
                rate: s.rate,
                stages: s.stages + t.stages,
                weight,
            });
            return Some(());
        }
        for (x, y) in [(s, t), (t, s)] {
            let (a, b, m, n) = (x.rate, y.rate, x.stages, y.stages);
            for k in 1..=m {
                let j = m - k;
                // C(n + j − 1, j)
                let binomial: f64 = (1..=j).map(|i| (n + i - 1) as f64 / i as f64).product();
                let sign = if j % 2 == 0 { 1.0 } else { -1.0 };
                let w =
                    sign * binomial * (a / (b - a)).powi(j as i32) * (b / (b - a)).powi(n as i32);
                out.push(Term {
                    shift,
                    rate: a,
                    stages: k,
                    weight: weight * w,
                });
            }
        }
        Some(())
    }

    /// The kernel of `x ⊛ y`'s density, for measures whose densities are
    /// kernels or none (at least one a kernel), within `[0, end]`: each
    /// one's atoms shift the other's terms, and two terms convolve by
    /// [`Self::pair`].
    fn convolution(x: &Measure, y: &Measure, end: f64) -> Option<Kernel> {
        let closed = |m: &Measure| m.density.is_none() || m.kernel.is_some();
        if !closed(x) || !closed(y) {
            return None;
        }
        let (kx, ky) = (x.kernel.as_ref(), y.kernel.as_ref());
        let first = kx.or(ky)?;
        if let (Some(a), Some(b)) = (kx, ky) {
            if a.before.is_some() || b.before.is_some() {
                return None;
            }
        }
        let within = |s: f64| s <= end || same_instant(s, end);
        let mut terms = Vec::new();
        let mut amplification = kx.or(ky).map_or(1.0, |k| k.amplification);
        for (m, k) in [(x, ky), (y, kx)] {
            let Some(k) = k else { continue };
            if m.atoms.len() * k.terms.len() > 4 * MAX_KERNEL_TERMS {
                return None;
            }
            for &(tau, a) in &m.atoms {
                for t in &k.terms {
                    if within(t.shift + tau) {
                        terms.push(Term {
                            shift: t.shift + tau,
                            weight: t.weight * a,
                            ..*t
                        });
                    }
                }
            }
        }
        if let (Some(a), Some(b)) = (kx, ky) {
            if a.terms.len() * b.terms.len() > 4 * MAX_KERNEL_TERMS {
                return None;
            }
            let from = terms.len();
            for s in &a.terms {
                for t in &b.terms {
                    if within(s.shift + t.shift) {
                        Self::pair(s, t, &mut terms)?;
                    }
                }
            }
            // the pairs' own cancellation: their weights against the
            // products' (both no less than 1 where partial fractions apply)
            let total = |ts: &[Term]| ts.iter().map(|t| t.weight.abs()).sum::<f64>();
            let products: f64 = a.terms.iter().map(|s| s.weight.abs()).sum::<f64>()
                * b.terms.iter().map(|t| t.weight.abs()).sum::<f64>();
            let pairs = if products > 0.0 {
                (total(&terms[from..]) / products).max(1.0)
            } else {
                1.0
            };
            amplification = amplification
                .max(kx.map_or(1.0, |k| k.amplification))
                .max(ky.map_or(1.0, |k| k.amplification))
                .max(a.amplification * b.amplification * pairs);
            if amplification > MAX_AMPLIFICATION {
                return None;
            }
        }
        Kernel {
            terms,
            before: first.before,
            amplification,
        }
        .merged()
    }

    /// Its density at each of `points` (`before` none).
    fn eval_many(&self, points: &[f64]) -> Vec<f64> {
        let mut e = [0.0; MAX_STAGES];
        points
            .iter()
            .map(|&x| {
                let mut v = 0.0;
                for t in &self.terms {
                    if t.shift > x {
                        break;
                    }
                    erlang_densities(t.rate, x - t.shift, &mut e[..t.stages]);
                    v += t.weight * e[t.stages - 1];
                }
                v
            })
            .collect()
    }

    /// `Σ w·z_m(λ; x − s)`: its convolution with what `z(r, y, out)` gives
    /// as `z_1(y), …, z_m(y)` for the `r`-th of [`Self::rates`] (one call
    /// per distinct shift and rate).
    fn apply(
        &self,
        rates: &[(f64, usize)],
        x: f64,
        z: &mut dyn FnMut(usize, f64, &mut [f64]),
    ) -> f64 {
        let mut out = [0.0; MAX_STAGES];
        let mut v = 0.0;
        let mut last = None;
        for t in &self.terms {
            if t.shift > x {
                break;
            }
            if last != Some((t.shift, t.rate)) {
                let r = rates
                    .iter()
                    .position(|r| r.0 == t.rate)
                    .expect("the kernel's own rates");
                z(r, x - t.shift, &mut out);
                last = Some((t.shift, t.rate));
            }
            v += t.weight * out[t.stages - 1];
        }
        v
    }
}

impl Measure {
    /// `δ₀`.
    fn unit() -> Measure {
        Measure {
            atoms: vec![(0.0, 1.0)],
            ..Measure::default()
        }
    }

    fn zero() -> Measure {
        Measure::default()
    }

    /// Mass within the horizon.
    fn mass(&self) -> f64 {
        self.atoms.iter().map(|a| a.1.abs()).sum::<f64>()
            + self.density.as_ref().map_or(0.0, Interpolant::total)
    }

    /// The mass in `[0, t]`: an atom at t (within [`same_instant`]) counts.
    fn cdf(&self, t: f64) -> f64 {
        let k = self
            .atoms
            .partition_point(|a| a.0 <= t || same_instant(a.0, t));
        self.atoms[..k].iter().map(|a| a.1).sum::<f64>()
            + self.density.as_ref().map_or(0.0, |d| d.integral_to(t))
    }

    /// The mass in `[0, t)`: an atom at t does not count.
    fn cdf_left(&self, t: f64) -> f64 {
        let k = self
            .atoms
            .partition_point(|a| a.0 < t && !same_instant(a.0, t));
        self.atoms[..k].iter().map(|a| a.1).sum::<f64>()
            + self.density.as_ref().map_or(0.0, |d| d.integral_to(t))
    }

    fn density_at(&self, t: f64) -> f64 {
        self.density.as_ref().map_or(0.0, |d| d.eval(t))
    }

    /// `∫ t dμ` over the horizon.
    fn first_moment(&self) -> f64 {
        self.atoms.iter().map(|a| a.0 * a.1).sum::<f64>()
            + self.density.as_ref().map_or(0.0, Interpolant::first_moment)
    }
}

/// `π(t)` of a loop without a bound over a child with a phase chain: the
/// child's chain with the exit that repeats it ("again": Success for
/// `until_failure`) routed back to its entry distribution — a cyclic chain,
/// solved by uniformization (which needs no order of the phases). An
/// instantaneous "again" at entry is folded in by renormalising the entry:
/// the entry is `initial / (1 − p₀)`, `p₀` the child's instantaneous
/// probability of "again".
pub(crate) fn loop_curve(
    children: &dyn Children,
    id: NodeId,
    child: NodeId,
    until: Outcome,
    times: &[f64],
    options: &CurveOptions,
    kept: &Kept,
) -> Result<Vec<CurvePoint>, AnalysisError> {
    let tree = children.tree();
    let node = tree.node(id);
    if !children.markovian(child) {
        // a child with mixed timing: the loop's truncated geometric series
        // as a shifted mixture where it is small (as the planner's
        // `Shifted` rule), else the loop's composed law (`law`: its renewal
        // equation marched in time, any child)
        let first = options.max_states.min(super::shifted::SHIFTED_FIRST);
        return match kept.mixtures.first(tree, id, first, options.max_states)? {
            shifted::FirstMixture::Built(law) => curve_by_shifted(&law, times, options, &node.name),
            shifted::FirstMixture::CannotHold | shifted::FirstMixture::Over => {
                curve_by_laws(children, id, times, options, kept)
            }
        };
    }
    let until_success = until == Outcome::Success;
    let c = phase::cyclic_loop(
        phase::chain_of(tree, child, options.max_states)?,
        until_success,
    );
    let Some(c) = c else {
        // the child never ends the loop: it runs forever
        return Ok(times
            .iter()
            .map(|&t| CurvePoint {
                t,
                success: 0.0,
                failure: 0.0,
                running: 1.0,
            })
            .collect());
    };
    let work = uniformization_work(&c, times);
    if work > options.max_work {
        return Err(AnalysisError::Stiff {
            node: node.name.clone(),
            work,
            limit: options.max_work,
        });
    }
    Ok(transient::transient(&c, times, options.tolerance))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::solve::interpolant::build1;

    /// A builder on `[0, end]` over a one-leaf tree (the renewal march
    /// reads only its horizon and budget).
    fn with_builder<T>(end: f64, f: impl FnOnce(&Builder) -> T) -> T {
        let tree = crate::parse_str("tree: {action: {name: a, ps: 0.5, mu: 1, nu: 1}}", "t.yaml")
            .expect("a tree");
        let tree = crate::ir::graph_of(&tree);
        let plan = crate::compile::Plan::new(&tree, crate::compile::Method::Exact, 1_000_000);
        let memo = LawMemo::default();
        let mixed = non_markovian(&tree);
        let b = Builder {
            tree: &tree,
            children: &plan,
            end,
            max_states: 1_000_000,
            memo: &memo,
            mixed: &mixed,
            narrow: narrow_segment(&tree),
            work: std::cell::Cell::new(0.0),
        };
        f(&b)
    }

    fn density(end: f64, f: impl Fn(f64) -> f64) -> Measure {
        Measure {
            density: Some(build1(end, f)),
            ..Measure::default()
        }
    }

    #[test]
    fn a_renewal_over_a_fixed_delay_is_the_geometric_lattice_sum() {
        // G = p·δ_d (a run that goes on takes exactly d), T = (1 − p)·Exp(ν):
        // R = Σ_n pⁿ(1 − p) δ_{nd} ⊛ Exp(ν), so
        // R([0, t]) = Σ_{nd ≤ t} pⁿ(1 − p)(1 − e^{−ν(t − nd)})
        let (p, d, nu, end) = (0.6, 0.5, 1.3, 20.0);
        let g = Measure {
            atoms: vec![(d, p)],
            ..Measure::default()
        };
        let t = density(end, |x| (1.0 - p) * nu * (-nu * x).exp());
        let r = with_builder(end, |b| b.renewal(0, &g, &t)).expect("a law");
        for x in [0.2, 0.5, 0.75, 1.0, 3.3, 10.0, 19.9] {
            let mut exact = 0.0;
            let mut n = 0;
            while n as f64 * d <= x {
                exact += p.powi(n) * (1.0 - p) * (1.0 - (-nu * (x - n as f64 * d)).exp());
                n += 1;
            }
            assert!(
                (r.cdf(x) - exact).abs() < 1e-12,
                "{x}: {} vs {exact}",
                r.cdf(x)
            );
        }
    }

    #[test]
    fn a_renewal_with_an_instant_repeat_and_a_density_is_exponential() {
        // G = p₀δ₀ + q·Exp(λ), T = r·Exp(λ): in Laplace R = T/(1 − G) =
        // (rλ/(1 − p₀)) / (s + λ'), λ' = λ(1 − q/(1 − p₀)): R has density
        // rλ/(1 − p₀)·e^{−λ't} (mass 1 here)
        let (p0, q, rr, lambda, end) = (0.2, 0.5, 0.3, 2.0, 30.0);
        let g = Measure {
            atoms: vec![(0.0, p0)],
            density: Some(build1(end, |x| q * lambda * (-lambda * x).exp())),
            ..Measure::default()
        };
        let t = density(end, |x| rr * lambda * (-lambda * x).exp());
        let r = with_builder(end, |b| b.renewal(0, &g, &t)).expect("a law");
        let slow = lambda * (1.0 - q / (1.0 - p0));
        let c = rr * lambda / (1.0 - p0);
        for x in [0.01, 0.3, 1.0, 2.5, 7.0, 29.0] {
            let exact = c / slow * (1.0 - (-slow * x).exp());
            assert!(
                (r.cdf(x) - exact).abs() < 1e-12,
                "{x}: {} vs {exact}",
                r.cdf(x)
            );
            let dens = c * (-slow * x).exp();
            assert!((r.density_at(x) - dens).abs() < 1e-10 * c, "{x}");
        }
        // a run that goes on at once for sure loops within one instant
        let forever = Measure {
            atoms: vec![(0.0, 1.0)],
            ..Measure::default()
        };
        let err = with_builder(end, |b| b.renewal(0, &forever, &t)).unwrap_err();
        assert!(matches!(err, AnalysisError::Unbounded { .. }), "{err}");
    }

    /// The density of one kernel term's pair product at `t`.
    fn pair_density(s: Term, t: Term, x: f64) -> f64 {
        let mut terms = Vec::new();
        Kernel::pair(&s, &t, &mut terms).expect("within the stages");
        Kernel {
            terms,
            before: None,
            amplification: 1.0,
        }
        .merged()
        .expect("few terms")
        .eval_many(&[x])[0]
    }

    fn term(rate: f64, stages: usize) -> Term {
        Term {
            shift: 0.0,
            rate,
            stages,
            weight: 1.0,
        }
    }

    /// Partial fractions of two rates against closed forms by hand:
    /// `E_1(a) ⊛ E_1(b) = ab(e^{−at} − e^{−bt})/(b − a)` and
    /// `E_2(λ) ⊛ E_1(κ) = λ²κ[e^{−κt} − e^{−λt} − (λ − κ)te^{−λt}]/(λ − κ)²`;
    /// one rate: `E_2 ⊛ E_3 = E_5`; and `E_2(a) ⊛ E_3(b)` against the
    /// convolution integral by Simpson's rule on 20,000 intervals.
    #[test]
    fn kernel_terms_convolve_by_partial_fractions() {
        let (a, b): (f64, f64) = (0.7, 2.3);
        for x in [0.01f64, 0.5, 2.0, 7.5] {
            let exact = a * b * ((-a * x).exp() - (-b * x).exp()) / (b - a);
            let got = pair_density(term(a, 1), term(b, 1), x);
            assert!((got - exact).abs() < 1e-14, "t = {x}: {got} vs {exact}");
            let (l, k) = (a, b);
            let d = l - k;
            let exact =
                l * l * k * ((-k * x).exp() - (-l * x).exp() - d * x * (-l * x).exp()) / (d * d);
            let got = pair_density(term(l, 2), term(k, 1), x);
            assert!((got - exact).abs() < 1e-14, "t = {x}: {got} vs {exact}");
            let e5 = a.powi(5) * x.powi(4) * (-a * x).exp() / 24.0;
            let got = pair_density(term(a, 2), term(a, 3), x);
            assert!((got - e5).abs() < 1e-15, "t = {x}: {got} vs {e5}");
            let erlang = |r: f64, m: i32, u: f64| {
                let fact: f64 = (1..m).map(f64::from).product();
                r * (r * u).powi(m - 1) * (-r * u).exp() / fact
            };
            let n = 20_000;
            let h = x / n as f64;
            let simpson: f64 = (0..=n)
                .map(|i| {
                    let u = i as f64 * h;
                    let c = if i == 0 || i == n {
                        1.0
                    } else if i % 2 == 1 {
                        4.0
                    } else {
                        2.0
                    };
                    c * erlang(a, 2, u) * erlang(b, 3, x - u)
                })
                .sum::<f64>()
                * h
                / 3.0;
            let got = pair_density(term(a, 2), term(b, 3), x);
            assert!((got - simpson).abs() < 1e-12, "t = {x}: {got} vs {simpson}");
        }
    }

    /// Close rates cancel in partial fractions: their convolution keeps no
    /// kernel past the amplification limit.
    #[test]
    fn close_rates_keep_no_kernel() {
        let k = |rate: f64| Measure {
            kernel: Some(Kernel::leaf(rate, 0.0, 3, 1.0, f64::INFINITY)),
            density: Some(build1(10.0, |_| 0.0)),
            ..Measure::default()
        };
        assert!(Kernel::convolution(&k(1.0), &k(1.001), 10.0).is_none());
        assert!(Kernel::convolution(&k(1.0), &k(3.0), 10.0).is_some());
        // one stage each at 1 and 1.02: weights 51 and −50, amplification
        // 101, kept; its convolution with itself would be 101² > 1e3: none
        let one = |rate: f64| Measure {
            kernel: Some(Kernel::leaf(rate, 0.0, 1, 1.0, f64::INFINITY)),
            density: Some(build1(10.0, |_| 0.0)),
            ..Measure::default()
        };
        let hypo = Kernel::convolution(&one(1.0), &one(1.02), 10.0).expect("kept");
        assert!(
            (hypo.amplification - 101.0).abs() < 1e-9,
            "{}",
            hypo.amplification
        );
        let m = Measure {
            kernel: Some(hypo),
            ..one(1.0)
        };
        assert!(Kernel::convolution(&m, &m, 10.0).is_none());
    }
}
