//! `π(t)` of nodes without a phase chain within the budget — wide Parallels
//! and every node above them — from their *outcome laws*: the probabilities
//! of an instant Success or Failure, and the sub-densities `s(t)`, `f(t)` of
//! the return time with each outcome, as piecewise Chebyshev interpolants on
//! `[0, T]` ([`crate::solve::interpolant`]), T the last requested time.
//!
//! Laws compose exactly as the tick semantics do; only the interpolation of
//! each density is approximate (an error estimate of 1e-15 in probability
//! mass per panel):
//!
//! * a subtree with a phase chain: its densities `π(t)·exit` sampled by
//!   uniformization ([`transient_weighted`]);
//! * a Parallel with the book's thresholds (`F = N − M + 1`): until it
//!   returns its children run independently and the thresholds cannot both
//!   be met, so it has succeeded by t iff at least M children have
//!   ([`super::curve`]'s count programme); its densities are the time derivatives
//!   of that count programme, computed in dual numbers from the children's
//!   probabilities and densities
//!   ([`counts::status_and_densities_by_counts`]);
//! * a Sequence runs its children one after the other, each independent of
//!   the others and started at the previous one's return: with `G_k` the
//!   law of the time at which the first k children have all succeeded
//!   (`G_0 = δ₀`), `G_k = G_{k−1} ⊛ S_k` and the Sequence fails with density
//!   `Σ_k G_{k−1} ⊛ F_k` and succeeds with `G_n` — where `⊛` convolves
//!   measures with an atom at 0 and a density, `(a δ₀ + g) ⊛ (b δ₀ + h) =
//!   ab δ₀ + a h + b g + g * h`. A Fallback is the same with the outcomes
//!   exchanged. Consecutive children with phase chains are concatenated
//!   into one chain first (exact, and fewer convolutions);
//! * Retry N and Repeat N are a Fallback and a Sequence of N copies,
//!   composed by binary powering (O(log N) convolutions, stopped once the
//!   mass still going on within `[0, T]` is negligible); inverter and force
//!   decorators exchange or merge the outcomes.
//!
//! A Parallel with independent failure threshold has no such decomposition
//! (which threshold is met first depends on the joint times) and keeps its
//! product-chain error; laws with atoms after 0 (deterministic times) are
//! refused as mixed timing.

use super::curve::CurveOptions;
use crate::compile::{counts, phase, renewal_law, AnalysisError};
use crate::solve::chain::PhaseChain;
use crate::solve::expm;
use crate::solve::interpolant::{build, BuildError, Interpolant};
use crate::solve::transient::{
    absorption_by_phase, transient_split, transient_weighted, uniformization_work, CurvePoint,
    MAX_SINGLE_PASS_STEPS,
};
use crate::tree::{Decorator, Flow, FlowNext, NodeId, NodeKind, Tree};

/// Dropped Poisson mass in each sampled density.
const SAMPLE_TOLERANCE: f64 = 1e-16;

/// Mass below which the rest of a fold is dropped.
const NEGLIGIBLE: f64 = 1e-17;

const SUCCESS: usize = 0;
const FAILURE: usize = 1;

/// A node's outcome law on `[0, T]`.
#[derive(Debug, Clone)]
struct Law {
    /// Probability of Success (index 0) and Failure (1) at time 0.
    atom: [f64; 2],
    /// Sub-densities of the return time with Success and with Failure.
    density: [Interpolant; 2],
}

impl Law {
    /// The part of the law with outcome `o`.
    fn measure(&self, o: usize) -> Measure {
        Measure {
            atom: self.atom[o],
            density: Some(self.density[o].clone()),
        }
    }

    /// P(returned outcome `o` by t).
    fn cdf(&self, o: usize, t: f64) -> f64 {
        self.atom[o] + self.density[o].integral_to(t)
    }
}

/// A child as its chain (when it has one) or its law.
enum Piece {
    Chain(PhaseChain),
    Law(Law),
}

/// `π(t)` of `id`, a node whose phase chain exceeds the budget, at `times`.
pub(super) fn curve_by_laws(
    tree: &Tree,
    id: NodeId,
    times: &[f64],
    options: &CurveOptions,
    budget_error: AnalysisError,
) -> Result<Vec<CurvePoint>, AnalysisError> {
    let end = times.iter().copied().fold(0.0, f64::max);
    let memo = LawMemo::default();
    let law = Builder {
        tree,
        end,
        max_states: options.max_states,
        memo: &memo,
    }
    .opaque(id, budget_error)?;
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

/// Accepted bound on the time the children may still run beyond the
/// horizon, relative to the node's mean time.
const MEAN_TOLERANCE: f64 = 1e-11;

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
    tree: &Tree,
    id: NodeId,
    m: usize,
    child_mean_times: &[f64],
    max_states: usize,
    memo: &LawMemo,
) -> Result<[f64; 2], AnalysisError> {
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
        .filter_map(|&c| phase::chain_of(tree, c, max_states).ok())
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
    for _ in 0..MAX_DOUBLINGS {
        let b = Builder {
            tree,
            end,
            max_states,
            memo,
        };
        // laws depend on the horizon
        let pieces = children
            .iter()
            .map(|&c| b.piece(c))
            .collect::<Result<Vec<_>, _>>()?;
        let law = b.counted_from(id, children, &pieces, m)?;
        let moments = [
            law.density[SUCCESS].first_moment(),
            law.density[FAILURE].first_moment(),
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
                    let done =
                        l.density[SUCCESS].first_moment() + l.density[FAILURE].first_moment();
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
fn stiff(tree: &Tree, id: NodeId, chain: &PhaseChain, end: f64) -> AnalysisError {
    let nnz: usize = chain.transitions.iter().map(Vec::len).sum::<usize>() + 2 * chain.len();
    AnalysisError::Stiff {
        node: tree.node(id).name.clone(),
        work: uniformization_work(chain, &[end]),
        limit: MAX_SINGLE_PASS_STEPS as f64 * nnz.max(1) as f64,
    }
}

/// `[S, F, π·h₁, ...]` at `points` by one uniformization pass, or — when that
/// would take too many steps (a stiff chain over a long horizon) and the
/// chain is small — by dense exponentials whose bound is below the sampling
/// tolerance; `None` otherwise.
pub(crate) fn sample_weighted(
    chain: &PhaseChain,
    points: &[f64],
    weights: &[&[f64]],
) -> Option<Vec<Vec<f64>>> {
    // phases that only exit (an action, a mixture of exponentials): closed
    // form, π_i(t) = p_i e^{−q_i t}
    if chain.transitions.iter().all(Vec::is_empty) {
        return Some(
            points
                .iter()
                .map(|&t| {
                    let mut row = vec![chain.initial_success, chain.initial_failure];
                    row.resize(2 + weights.len(), 0.0);
                    for &(i, p) in &chain.initial {
                        let q = chain.total_rate(i);
                        let (alive, gone) = ((-q * t).exp(), -(-q * t).exp_m1());
                        if q > 0.0 {
                            row[0] += p * chain.exit_success[i] / q * gone;
                            row[1] += p * chain.exit_failure[i] / q * gone;
                        }
                        for (k, w) in weights.iter().enumerate() {
                            row[2 + k] += p * alive * w[i];
                        }
                    }
                    row
                })
                .collect(),
        );
    }
    if let Some(rows) = transient_weighted(chain, points, SAMPLE_TOLERANCE, weights) {
        return Some(rows);
    }
    if chain.len() + 2 > expm::MAX_DENSE_STATES {
        return None;
    }
    let (rows, bound) = expm::transient_dense_weighted(chain, points, weights);
    (bound <= super::curve::DENSE_TOLERANCE).then_some(rows)
}

struct Builder<'a> {
    tree: &'a Tree,
    end: f64,
    max_states: usize,
    memo: &'a LawMemo,
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

    fn interpolate(
        &self,
        id: NodeId,
        k: usize,
        sample: impl FnMut(&[f64]) -> Result<Vec<f64>, AnalysisError>,
    ) -> Result<Vec<Interpolant>, AnalysisError> {
        build(self.end, k, sample).map_err(|e| match e {
            BuildError::Sample(e) => e,
            BuildError::NotConverged => AnalysisError::Numerical {
                node: self.name(id),
                what: "the interpolated densities of its outcome times did not converge".into(),
            },
        })
    }

    /// The child's chain if it has one within the budget, else its law.
    fn piece(&self, id: NodeId) -> Result<Piece, AnalysisError> {
        let key = (id, self.end.to_bits());
        if let Some(l) = self.memo.0.borrow().get(&key) {
            return Ok(Piece::Law(l.clone()));
        }
        let e = match phase::chain_of(self.tree, id, self.max_states) {
            Ok(chain) => return Ok(Piece::Chain(chain)),
            Err(e @ AnalysisError::StateBudget { .. }) => e,
            // a renewal race (Nav2's re-planning) below: its law from its levels
            Err(AnalysisError::NotMarkovian { leaf }) if renewal_law::holds_race(self.tree, id) => {
                AnalysisError::MixedTiming {
                    node: self.name(id),
                    leaf,
                }
            }
            Err(AnalysisError::NotMarkovian { leaf }) => {
                return Err(AnalysisError::MixedTiming {
                    node: self.name(id),
                    leaf,
                })
            }
            Err(e) => return Err(e),
        };
        // a copy's (a RecoveryNode's retries copy the subtree they retry)
        let copy = self.memo.0.borrow().iter().find_map(|(&(n, end), l)| {
            (end == key.1 && self.tree.same_subtree(n, id)).then(|| l.clone())
        });
        let law = match copy {
            Some(l) => l,
            None => match renewal_law::law(self.tree, id, self.end, self.max_states)? {
                // the race, or the Sequence that starts it
                Some((atom, density)) => Law { atom, density },
                None => self.opaque(id, e)?,
            },
        };
        self.memo.0.borrow_mut().insert(key, law.clone());
        Ok(Piece::Law(law))
    }

    /// Densities `π(t)·exit` of a chain, sampled by uniformization.
    fn chain_law(&self, id: NodeId, chain: &PhaseChain) -> Result<Law, AnalysisError> {
        let weights = [&chain.exit_success[..], &chain.exit_failure[..]];
        let mut d = self.interpolate(id, 2, |points| {
            let rows = sample_weighted(chain, points, &weights)
                .ok_or_else(|| stiff(self.tree, id, chain, self.end))?;
            Ok(rows.iter().flat_map(|r| [r[2], r[3]]).collect())
        })?;
        let failure = d.pop().expect("two densities");
        let success = d.pop().expect("two densities");
        Ok(Law {
            atom: [chain.initial_success, chain.initial_failure],
            density: [success, failure],
        })
    }

    /// The law of a node without a chain (`budget_error` is what its chain
    /// construction reported, returned where laws cannot help).
    fn opaque(&self, id: NodeId, budget_error: AnalysisError) -> Result<Law, AnalysisError> {
        let node = self.tree.node(id);
        match &node.kind {
            NodeKind::Parallel {
                success_threshold,
                failure_threshold,
                children,
            } if *failure_threshold >= children.len() + 1 - success_threshold => {
                self.counted(id, children, *success_threshold)
            }
            // Nav2 nodes as their primitive equivalents (`primitive_view`)
            NodeKind::Sequence { children }
            | NodeKind::Pipeline { children }
            | NodeKind::SequenceWithMemory { children, .. } => self.in_turn(id, children, true),
            NodeKind::Fallback { children } | NodeKind::RoundRobin { children, .. } => {
                self.in_turn(id, children, false)
            }
            NodeKind::Flow(flow) => self.flow(id, flow),
            NodeKind::Decorator { decorator, child } => {
                let law = match self.piece(*child)? {
                    Piece::Law(l) => l,
                    // the child fits, so its copies are what exceeded the budget
                    Piece::Chain(c) => self.chain_law(*child, &c)?,
                };
                match decorator.as_primitive() {
                    Decorator::Inverter => {
                        let [s, f] = law.density;
                        Ok(Law {
                            atom: [law.atom[FAILURE], law.atom[SUCCESS]],
                            density: [f, s],
                        })
                    }
                    Decorator::ForceSuccess | Decorator::ForceFailure => {
                        let both = self.add(id, &law.measure(SUCCESS), &law.measure(FAILURE))?;
                        let to = if *decorator == Decorator::ForceSuccess {
                            SUCCESS
                        } else {
                            FAILURE
                        };
                        Ok(self.law_from(to, both, Measure::zero()))
                    }
                    Decorator::Retry { attempts } => self.repeated(id, &law, attempts, false),
                    Decorator::Repeat { times } => self.repeated(id, &law, times, true),
                    Decorator::UntilFailure | Decorator::UntilSuccess => {
                        Err(AnalysisError::Unbounded {
                            node: self.name(id),
                        })
                    }
                    Decorator::Rate { .. } | Decorator::SingleTrigger => {
                        unreachable!("as_primitive maps Nav2 decorators to repeat 1")
                    }
                }
            }
            _ => Err(budget_error),
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

    /// [`Self::counted`] from the children's pieces.
    fn counted_from(
        &self,
        id: NodeId,
        children: &[NodeId],
        pieces: &[Piece],
        m: usize,
    ) -> Result<Law, AnalysisError> {
        let f_cap = children.len() + 1 - m;
        let atoms: Vec<(f64, f64)> = pieces
            .iter()
            .map(|p| match p {
                Piece::Chain(c) => (c.initial_success, c.initial_failure),
                Piece::Law(l) => (l.atom[SUCCESS], l.atom[FAILURE]),
            })
            .collect();
        let (atom_s, atom_f) = counts::status_by_counts(&atoms, m, f_cap);
        let mut d = self.interpolate(id, 2, |points| {
            // per child and point: [S, F, s, f]
            let columns = pieces
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
                                l.density[SUCCESS].eval(t),
                                l.density[FAILURE].eval(t),
                            ]
                        })
                        .collect::<Vec<[f64; 4]>>()),
                })
                .collect::<Result<Vec<_>, _>>()?;
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
        Ok(Law {
            atom: [atom_s, atom_f],
            density: [success, failure],
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
                    laws.push(l);
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
            .map(|&c| match self.piece(c)? {
                Piece::Law(l) => Ok(l),
                Piece::Chain(chain) => self.chain_law(c, &chain),
            })
            .collect::<Result<Vec<_>, AnalysisError>>()?;
        let mut entered: Vec<Option<Measure>> = vec![None; flow.states.len()];
        entered[0] = Some(Measure::unit());
        let mut ends = [Measure::zero(), Measure::zero()];
        for (i, s) in flow.states.iter().enumerate() {
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
        let [s, f] = ends;
        let zero = || Interpolant::zero(self.end);
        Ok(Law {
            atom: [s.atom, f.atom],
            density: [
                s.density.unwrap_or_else(zero),
                f.density.unwrap_or_else(zero),
            ],
        })
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
            let here = self.convolve(id, &reach, &law.measure(stop))?;
            stopped = self.add(id, &stopped, &here)?;
            reach = self.convolve(id, &reach, &law.measure(go))?;
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

    fn law_from(&self, go: usize, going: Measure, stopped: Measure) -> Law {
        let zero = || Interpolant::zero(self.end);
        let mut law = Law {
            atom: [0.0; 2],
            density: [zero(), zero()],
        };
        law.atom[go] = going.atom;
        law.atom[1 - go] = stopped.atom;
        law.density[go] = going.density.unwrap_or_else(zero);
        law.density[1 - go] = stopped.density.unwrap_or_else(zero);
        law
    }

    /// `(a δ₀ + g) ⊛ (b δ₀ + h) = ab δ₀ + a h + b g + g * h`.
    fn convolve(&self, id: NodeId, x: &Measure, y: &Measure) -> Result<Measure, AnalysisError> {
        let atom = x.atom * y.atom;
        let density = match (&x.density, &y.density) {
            (None, None) => None,
            (None, Some(h)) => Some(h.scaled(x.atom)),
            (Some(g), None) => Some(g.scaled(y.atom)),
            (Some(g), Some(h)) => Some(
                self.interpolate(id, 1, |points| {
                    let conv = g.convolve_many(h, points);
                    Ok(points
                        .iter()
                        .zip(conv)
                        .map(|(&t, c)| x.atom * h.eval(t) + y.atom * g.eval(t) + c)
                        .collect())
                })?
                .remove(0),
            ),
        };
        Ok(Measure { atom, density })
    }

    fn add(&self, id: NodeId, x: &Measure, y: &Measure) -> Result<Measure, AnalysisError> {
        let density = match (&x.density, &y.density) {
            (None, d) | (d, None) => d.clone(),
            (Some(g), Some(h)) => Some(
                self.interpolate(id, 1, |points| {
                    Ok(points.iter().map(|&t| g.eval(t) + h.eval(t)).collect())
                })?
                .remove(0),
            ),
        };
        Ok(Measure {
            atom: x.atom + y.atom,
            density,
        })
    }
}

/// `(go, stop)`: the outcome on which a Sequence (`sequence`) or Fallback
/// goes on to its next child, and the one on which it returns.
fn outcomes(sequence: bool) -> (usize, usize) {
    if sequence {
        (SUCCESS, FAILURE)
    } else {
        (FAILURE, SUCCESS)
    }
}

/// A measure on `[0, T]`: an atom at 0 and a density (`None` = 0).
#[derive(Debug, Clone)]
struct Measure {
    atom: f64,
    density: Option<Interpolant>,
}

impl Measure {
    /// `δ₀`.
    fn unit() -> Measure {
        Measure {
            atom: 1.0,
            density: None,
        }
    }

    fn zero() -> Measure {
        Measure {
            atom: 0.0,
            density: None,
        }
    }

    /// Mass within the horizon.
    fn mass(&self) -> f64 {
        self.atom.abs() + self.density.as_ref().map_or(0.0, Interpolant::total)
    }
}
