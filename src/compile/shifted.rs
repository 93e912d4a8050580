//! Mixed timing in Sequences, Fallbacks and decorators: outcome laws as
//! signed mixtures of **shifted phase-type** sub-distributions.
//!
//! A subtree that mixes deterministic or hybrid actions with stochastic
//! ones has neither a finite phase chain nor finitely many return instants.
//! But convolution commutes, so the time of a path through a Sequence of
//! fixed delays and exponential phases is a deterministic shift plus a
//! phase-type time. Each outcome of a node is kept as a list of components
//! `w · (δ_τ ⊛ PH)`: weight `w` (signed), shift `τ` and a phase chain in
//! *counted/lost* form — its Success exit (and `initial_success`) is the
//! outcome counted, its Failure exit (and `initial_failure`) is every other
//! way the run can end. Then `P(returned that outcome by t) = Σ w ·
//! A(t − τ)`, `A` the chain's counted absorption by then.
//!
//! * a stochastic (or any Markovian) subtree: one component per outcome,
//!   its exact phase chain, relabelled so that the outcome is counted;
//! * a fixed time τ: an empty chain (an atom) shifted by τ; a shifted
//!   (Erlang, hypoexponential or exponential) time: its stages' chain
//!   shifted by its shift;
//! * a hybrid action's random side `min(X, τ)`, X ~ Exp(λ): by memorylessness
//!   its law is `Exp(λ) − e^{−λτ}·(δ_τ ⊛ Exp(λ)) + e^{−λτ}·δ_τ` (the only
//!   negative weights; they are bounded by 1);
//! * Sequence: Success is `S₁ ⊛ S₂ ⊛ …`, Failure `F₁ + S₁ ⊛ F₂ + …`; a
//!   Fallback likewise with the outcomes exchanged. `⊛` of two components
//!   adds shifts, multiplies weights and concatenates the chains (the first
//!   one's counted exit enters the second, its lost exit stays lost);
//! * inverter: outcomes exchanged; force: both lists become one outcome;
//!   Retry N / Repeat N: a Fallback / Sequence of N copies;
//! * a Parallel is a component when its whole subtree is Markovian (its
//!   product chain) or deterministic (atoms), and when it returns with its
//!   first child (M = 1, F = 1: BT.CPP's `Timeout`) over Markovian and
//!   deterministic children ([`first_return`]: its product chain restarted
//!   at each deterministic instant, with negative weights); any other mixed
//!   Parallel has no such form and is answered where it is, by counting or
//!   as a race (`crate::compile::plan`).
//!
//! Every operation is exact; the only approximations are the transient
//! solutions of the chains (with their own bounds) and the rounding of the
//! signed sums. Atoms at the same instant (within 1e-12 relative) are merged.

use super::atoms::{self, Atom};
use super::mrg::Outcome;
use super::phase;
use super::AnalysisError;
use crate::ir::{Flow, FlowGraph, Graph, Op};
use crate::solve::chain::PhaseChain;
use crate::tree::same_instant;
use crate::tree::{Duration, FlowNext, NodeId};

/// One term `weight · (δ_shift ⊛ PH(chain))` of an outcome's law.
#[derive(Debug, Clone)]
pub(crate) struct Component {
    /// Deterministic delay before the chain starts (s).
    pub shift: f64,
    /// Signed weight.
    pub weight: f64,
    /// Phase chain in counted/lost form (module docs).
    pub chain: PhaseChain,
}

/// A node's outcome law: the components of its Success and its Failure.
#[derive(Debug, Clone, Default)]
pub(crate) struct ShiftedLaw {
    /// Components of the Success sub-distribution.
    pub success: Vec<Component>,
    /// Components of the Failure sub-distribution.
    pub failure: Vec<Component>,
}

impl ShiftedLaw {
    /// Every shift, for the instants where the law's CDFs may jump or kink.
    pub fn shifts(&self) -> impl Iterator<Item = f64> + '_ {
        self.success.iter().chain(&self.failure).map(|c| c.shift)
    }

    pub(crate) fn phases(&self) -> usize {
        self.success
            .iter()
            .chain(&self.failure)
            .map(|c| c.chain.len().max(1))
            .sum()
    }
}

/// Exchanges the exits so that Failure is counted.
fn count_failure(mut c: PhaseChain) -> PhaseChain {
    std::mem::swap(&mut c.exit_success, &mut c.exit_failure);
    std::mem::swap(&mut c.initial_success, &mut c.initial_failure);
    c
}

/// An atom: an empty chain returning the counted outcome at once.
fn atom(shift: f64, weight: f64) -> Component {
    Component {
        shift,
        weight,
        chain: PhaseChain {
            initial_success: 1.0,
            ..PhaseChain::default()
        },
    }
}

/// One exponential phase of `rate` ending in the counted outcome.
fn exponential(rate: f64) -> PhaseChain {
    let mut c = PhaseChain::default();
    let i = c.push_phase();
    c.exit_success[i] = rate;
    c.initial.push((i, 1.0));
    c
}

/// The components of an outcome of probability `p` taking `d`.
fn leaf_side(p: f64, d: Option<Duration>) -> Vec<Component> {
    if p <= 0.0 {
        return Vec::new();
    }
    match d {
        None => Vec::new(),
        Some(Duration::Fixed { time }) => vec![atom(time, p)],
        Some(Duration::Exponential { rate }) => vec![Component {
            shift: 0.0,
            weight: p,
            chain: exponential(rate),
        }],
        // Erlang, hypoexponential, shifted: the stages' chain after the shift
        Some(Duration::PhaseType { shift, stages }) => vec![Component {
            shift,
            weight: p,
            chain: stages.chain(),
        }],
        Some(Duration::TruncatedExponential { rate, cap }) => {
            let tail = (-rate * cap).exp();
            vec![
                Component {
                    shift: 0.0,
                    weight: p,
                    chain: exponential(rate),
                },
                Component {
                    shift: cap,
                    weight: -p * tail,
                    chain: exponential(rate),
                },
                atom(cap, p * tail),
            ]
        }
    }
}

/// Whether a component shifted by `shift` starts by `horizon` (the same
/// instant within [`SAME_INSTANT`](crate::tree::SAME_INSTANT)): one that starts later is zero
/// on `[0, horizon]` and is dropped.
fn starts_by(shift: f64, horizon: f64) -> bool {
    shift <= horizon || same_instant(shift, horizon)
}

/// Merges atoms at the same instant and drops zero weights.
fn tidy(mut comps: Vec<Component>) -> Vec<Component> {
    comps.retain(|c| c.weight != 0.0);
    let (mut atoms, mut rest): (Vec<Component>, Vec<Component>) =
        comps.into_iter().partition(|c| c.chain.is_empty());
    atoms.sort_by(|a, b| a.shift.total_cmp(&b.shift));
    let mut merged: Vec<Component> = Vec::with_capacity(atoms.len());
    for a in atoms {
        match merged.last_mut() {
            Some(l) if same_instant(l.shift, a.shift) => {
                l.weight += a.weight * a.chain.initial_success;
            }
            _ => {
                let w = a.weight * a.chain.initial_success;
                merged.push(atom(a.shift, w));
            }
        }
    }
    rest.extend(merged);
    rest
}

/// `a ⊛ b` for every pair, or `Err(size)` — before allocating anything —
/// when the result would hold more than `room` phases (each component
/// counted as at least one), `size` an upper bound of what it would hold.
fn convolve(
    a: &[Component],
    b: &[Component],
    room: usize,
    horizon: f64,
) -> Result<Vec<Component>, f64> {
    // the pairs that start by the horizon and their phases
    let (mut pairs, mut size) = (0usize, 0.0f64);
    for x in a {
        for y in b {
            if starts_by(x.shift + y.shift, horizon) {
                pairs += 1;
                size += 1.0 + (x.chain.len() + y.chain.len()) as f64;
            }
        }
    }
    if size > room as f64 {
        return Err(size);
    }
    let mut out = Vec::with_capacity(pairs);
    for x in a {
        for y in b {
            if !starts_by(x.shift + y.shift, horizon) {
                continue;
            }
            out.push(Component {
                shift: x.shift + y.shift,
                weight: x.weight * y.weight,
                chain: phase::concatenate(vec![x.chain.clone(), y.chain.clone()], true),
            });
        }
    }
    Ok(out)
}

/// Phases held by `parts` (each component counted as at least one).
fn held(parts: &[&[Component]]) -> usize {
    parts
        .iter()
        .flat_map(|p| p.iter())
        .map(|c| c.chain.len().max(1))
        .sum()
}

/// The shifted phase-type law of the subtree at `id`, or `None` when it
/// holds a Parallel that mixes timings (no such form). Fails when the
/// components would hold more than `max_states` phases in all.
fn budget(tree: &Graph, id: NodeId, states: f64, max_states: usize) -> AnalysisError {
    AnalysisError::StateBudget {
        node: tree.node(id).name.clone(),
        states,
        budget: max_states,
    }
}

pub fn shifted_law(
    tree: &Graph,
    id: NodeId,
    max_states: usize,
) -> Result<Option<ShiftedLaw>, AnalysisError> {
    shifted_law_within(tree, id, max_states, f64::INFINITY)
}

/// [`shifted_law`] exact on `[0, horizon]` only: components that start
/// after `horizon` are dropped as they are made (every operation only moves
/// a start later), so a loop's series stops where its repetitions start
/// beyond the horizon. For a node whose parent has returned by `horizon`
/// whatever happens (a child of a `Timeout`'s race): its law after that
/// instant is never read. Without a horizon (`f64::INFINITY`) it is
/// [`shifted_law`].
pub fn shifted_law_within(
    tree: &Graph,
    id: NodeId,
    max_states: usize,
    horizon: f64,
) -> Result<Option<ShiftedLaw>, AnalysisError> {
    let law = shifted_law_unclipped(tree, id, max_states, horizon)?;
    Ok(law.map(|l| {
        let clip = |v: Vec<Component>| -> Vec<Component> {
            v.into_iter()
                .filter(|c| starts_by(c.shift, horizon))
                .collect()
        };
        ShiftedLaw {
            success: clip(l.success),
            failure: clip(l.failure),
        }
    }))
}

fn shifted_law_unclipped(
    tree: &Graph,
    id: NodeId,
    max_states: usize,
    horizon: f64,
) -> Result<Option<ShiftedLaw>, AnalysisError> {
    let node = tree.node(id);
    // Markovian subtrees: their exact chain, one component per outcome
    if let Some(chain) = phase::markovian_chain_of(tree, id, max_states)? {
        return Ok(Some(ShiftedLaw {
            success: vec![Component {
                shift: 0.0,
                weight: 1.0,
                chain: chain.clone(),
            }],
            failure: vec![Component {
                shift: 0.0,
                weight: 1.0,
                chain: count_failure(chain),
            }],
        }));
    }
    if let Some(a) = node.kind.action() {
        return Ok(Some(ShiftedLaw {
            success: leaf_side(a.ps, a.success),
            failure: leaf_side(a.pf, a.failure),
        }));
    }
    if let Some(list) = atoms::atoms(tree, id, max_states)? {
        return Ok(Some(from_atoms(&list)));
    }
    let children = node.kind.children();
    let mut laws = Vec::with_capacity(children.len());
    for &c in children {
        match shifted_law_within(tree, c, max_states, horizon)? {
            Some(l) => laws.push(l),
            None => return Ok(None),
        }
    }
    let check = |l: ShiftedLaw| -> Result<ShiftedLaw, AnalysisError> {
        let phases = l.phases();
        if phases > max_states {
            return Err(budget(tree, id, phases as f64, max_states));
        }
        Ok(l)
    };
    let law = match &node.kind {
        Op::Flow(flow) => match flow.graph {
            FlowGraph::Chain { stop } => in_turn(
                laws,
                stop == Outcome::Failure,
                tree,
                id,
                max_states,
                horizon,
            )?,
            FlowGraph::Repeat { times, stop } => {
                let l = laws.pop().expect("a repetition has a child");
                in_turn(
                    vec![l; times],
                    stop == Outcome::Failure,
                    tree,
                    id,
                    max_states,
                    horizon,
                )?
            }
            FlowGraph::States(_) => through_flow(&laws, flow, tree, id, max_states, horizon)?,
        },
        Op::Map {
            on_success,
            on_failure,
            ..
        } => {
            let l = laws.pop().expect("a map has a child");
            let mut out = ShiftedLaw::default();
            for (to, part) in [(on_success, l.success), (on_failure, l.failure)] {
                match to {
                    Outcome::Success => out.success.extend(part),
                    Outcome::Failure => out.failure.extend(part),
                }
            }
            out
        }
        Op::Loop { until, .. } => {
            let l = laws.pop().expect("a loop has a child");
            loop_series(l, *until == Outcome::Success, tree, id, max_states, horizon)?
        }
        // a first-return race (a Timeout) over Markovian and deterministic
        // children; any other mixed Parallel is answered where it is
        Op::KOfN { .. } => match first_return(tree, id, max_states)? {
            Some(law) => law,
            None => return Ok(None),
        },
        _ => return Ok(None),
    };
    check(law).map(Some)
}

fn from_atoms(list: &[Atom]) -> ShiftedLaw {
    let mut law = ShiftedLaw::default();
    for a in list {
        let c = atom(a.time, a.prob);
        match a.outcome {
            Outcome::Success => law.success.push(c),
            Outcome::Failure => law.failure.push(c),
        }
    }
    law
}

/// Children run one after the other while they return the "continue"
/// outcome (Success for a Sequence, Failure for a Fallback).
fn in_turn(
    laws: Vec<ShiftedLaw>,
    sequence: bool,
    tree: &Graph,
    id: NodeId,
    max_states: usize,
    horizon: f64,
) -> Result<ShiftedLaw, AnalysisError> {
    // `going`: the law of having continued through the children so far
    let mut going = vec![atom(0.0, 1.0)];
    let mut stopped = Vec::new();
    for l in laws {
        let (cont, stop) = if sequence {
            (l.success, l.failure)
        } else {
            (l.failure, l.success)
        };
        let over = |size: f64, now: usize| budget(tree, id, size + now as f64, max_states);
        let now = held(&[&going, &stopped]);
        let s = convolve(&going, &stop, max_states.saturating_sub(now), horizon)
            .map_err(|size| over(size, now))?;
        stopped.extend(s);
        let now = held(&[&stopped]);
        going = tidy(
            convolve(&going, &cont, max_states.saturating_sub(now), horizon)
                .map_err(|size| over(size, now))?,
        );
        within_budget(&going, &stopped, tree, id, max_states)?;
    }
    let stopped = tidy(stopped);
    Ok(if sequence {
        ShiftedLaw {
            success: going,
            failure: stopped,
        }
    } else {
        ShiftedLaw {
            success: stopped,
            failure: going,
        }
    })
}

/// Probability that a component's run ends in its counted outcome.
fn counted_probability(c: &Component) -> f64 {
    let chain = &c.chain;
    if chain.is_empty() {
        return c.weight * chain.initial_success;
    }
    let a = crate::solve::transient::absorption_by_phase(chain);
    let from_start: f64 = chain
        .initial
        .iter()
        .map(|&(i, p)| p * a.to_success[i])
        .sum();
    c.weight * (chain.initial_success + from_start)
}

/// Refuses (a budget error) once the components of a fold, still going
/// and stopped, hold more than `max_states` phases in all.
fn within_budget(
    going: &[Component],
    stopped: &[Component],
    tree: &Graph,
    id: NodeId,
    max_states: usize,
) -> Result<(), AnalysisError> {
    let phases: usize = going
        .iter()
        .chain(stopped)
        .map(|c| c.chain.len().max(1))
        .sum();
    if phases > max_states {
        return Err(budget(tree, id, phases as f64, max_states));
    }
    Ok(())
}

/// Most repetitions a loop's series may take ([`loop_series`]).
pub const MAX_LOOP_TERMS: usize = 100_000;

/// Most phases the shifted mixture may hold on its first attempt at a
/// node's curve: past it the composed laws answer (exact too, and faster
/// there); the mixture gets the whole `--max-states` only where the laws
/// cannot hold the node.
pub(crate) const SHIFTED_FIRST: usize = 1 << 16;

/// What the shifted mixture within [`SHIFTED_FIRST`] gave a node's curve.
#[derive(Clone)]
pub(crate) enum FirstMixture {
    /// The mixture, within that budget.
    Built(std::sync::Arc<ShiftedLaw>),
    /// A form the mixture cannot hold (a Parallel below).
    CannotHold,
    /// More components than that budget.
    Over,
}

/// The first attempts at nodes' shifted mixtures, kept by a plan: each is
/// built once per node and budget, not at every curve query (a
/// quadrature's rounds ask a child's curve tens of times).
#[derive(Default)]
pub(crate) struct KeptMixtures(
    std::cell::RefCell<std::collections::HashMap<(NodeId, usize), FirstMixture>>,
);

impl KeptMixtures {
    /// Node `id`'s mixture within `budget`, built at the first call.
    pub(crate) fn first(
        &self,
        tree: &Graph,
        id: NodeId,
        budget: usize,
    ) -> Result<FirstMixture, AnalysisError> {
        if let Some(m) = self.0.borrow().get(&(id, budget)) {
            return Ok(m.clone());
        }
        let m = match shifted_law(tree, id, budget) {
            Ok(Some(law)) => FirstMixture::Built(std::sync::Arc::new(law)),
            Ok(None) => FirstMixture::CannotHold,
            Err(AnalysisError::StateBudget { .. }) => FirstMixture::Over,
            Err(e) => return Err(e),
        };
        self.0.borrow_mut().insert((id, budget), m.clone());
        Ok(m)
    }
}

/// The law of a loop without a bound over a child with mixed timing: the
/// geometric series `Σ_k again^{⊛k} ⊛ end` (`again` the child's repeating
/// outcome — Success for `until_failure` — and `end` the other), truncated
/// after K terms with `p_againᴷ ≤ LOOP_TAIL` (1e-14). Each term is a set of
/// shifted components like any Sequence's; the true law is a non-negative
/// measure, so dropping the rest changes every CDF by at most `p_againᴷ`
/// (and no probability of an outcome: the loop's P(end) is 1 by its own
/// figures). Refused with a budget error when K exceeds
/// [`MAX_LOOP_TERMS`] or the components exceed `max_states` phases.
fn loop_series(
    l: ShiftedLaw,
    until_success: bool,
    tree: &Graph,
    id: NodeId,
    max_states: usize,
    horizon: f64,
) -> Result<ShiftedLaw, AnalysisError> {
    let (mut again, mut end) = if until_success {
        (l.failure, l.success)
    } else {
        (l.success, l.failure)
    };
    let p_end: f64 = end.iter().map(counted_probability).sum();
    if p_end <= 0.0 {
        // the child never ends the loop: the loop never returns (no mass)
        return Ok(ShiftedLaw::default());
    }
    // a repetition at once (an atom of "again" at 0: a condition that
    // repeats the child) takes no time: folded into the loop's entry, the
    // rest renormalised by 1 − p₀, as for a child with a phase chain
    // (`phase::unrolled_loop`) — survey tree 6 repeated at once 86% of the
    // time and unrolled 230 rounds of it
    let instant = |c: &Component| c.chain.is_empty() && c.shift == 0.0;
    let p0: f64 = again
        .iter()
        .filter(|c| instant(c))
        .map(|c| c.weight * c.chain.initial_success)
        .sum();
    if p0 > 0.0 && p0 < 1.0 {
        again.retain(|c| !instant(c));
        let w = 1.0 / (1.0 - p0);
        for c in again.iter_mut().chain(end.iter_mut()) {
            c.weight *= w;
        }
    }
    let p_again: f64 = again.iter().map(counted_probability).sum::<f64>().max(0.0);
    let terms = if p_again <= 0.0 {
        1.0
    } else {
        (phase::LOOP_TAIL.ln() / p_again.min(1.0 - 1e-16).ln())
            .ceil()
            .max(1.0)
    };
    // within a horizon: the k-th repetition starts after k times the
    // shortest shift of a repetition, so later ones are dropped anyway
    let shortest = again.iter().map(|c| c.shift).fold(f64::INFINITY, f64::min);
    let terms = if horizon.is_finite() && shortest > 0.0 {
        terms.min((horizon / shortest).floor() + 2.0)
    } else {
        terms
    };
    let per_term: usize = again.iter().map(|c| c.chain.len().max(1)).sum();
    if terms > MAX_LOOP_TERMS as f64 {
        return Err(budget(tree, id, terms * per_term.max(1) as f64, max_states));
    }
    let mut going = vec![atom(0.0, 1.0)];
    let mut stopped = Vec::new();
    for _ in 0..terms as usize {
        let over = |size: f64, now: usize| budget(tree, id, size + now as f64, max_states);
        let now = held(&[&going, &stopped]);
        let s = convolve(&going, &end, max_states.saturating_sub(now), horizon)
            .map_err(|size| over(size, now))?;
        stopped.extend(s);
        let now = held(&[&stopped]);
        going = tidy(
            convolve(&going, &again, max_states.saturating_sub(now), horizon)
                .map_err(|size| over(size, now))?,
        );
        within_budget(&going, &stopped, tree, id, max_states)?;
        if going.is_empty() {
            break;
        }
    }
    // the mass still repeating after K rounds ends the loop there (as the
    // unrolled chain of a Markovian child does): P(end) stays 1
    stopped.extend(going);
    let stopped = tidy(stopped);
    Ok(if until_success {
        ShiftedLaw {
            success: stopped,
            failure: Vec::new(),
        }
    } else {
        ShiftedLaw {
            success: Vec::new(),
            failure: stopped,
        }
    })
}

/// A flow: the law of the time each state is entered (`δ₀` for state 0),
/// carried forward state by state — convolved with the state's child's
/// Success and Failure laws and added to the entry law of the state each
/// leads to, or to the node's outcome.
fn through_flow(
    laws: &[ShiftedLaw],
    flow: &Flow,
    tree: &Graph,
    id: NodeId,
    max_states: usize,
    horizon: f64,
) -> Result<ShiftedLaw, AnalysisError> {
    let states = flow.states();
    let mut entered: Vec<Vec<Component>> = vec![Vec::new(); states.len()];
    entered[0].push(atom(0.0, 1.0));
    let mut out = ShiftedLaw::default();
    for (i, s) in states.iter().enumerate() {
        let here = tidy(std::mem::take(&mut entered[i]));
        if here.is_empty() {
            continue;
        }
        let l = &laws[s.child];
        for (side, next) in [(&l.success, s.on_success), (&l.failure, s.on_failure)] {
            let now = held(&[&here, &out.success, &out.failure])
                + entered.iter().map(|e| held(&[e])).sum::<usize>();
            let comps = convolve(&here, side, max_states.saturating_sub(now), horizon)
                .map_err(|size| budget(tree, id, size + now as f64, max_states))?;
            match next {
                FlowNext::State(j) => entered[j].extend(comps),
                FlowNext::Success => out.success.extend(comps),
                FlowNext::Failure => out.failure.extend(comps),
            }
        }
        let phases: usize = entered
            .iter()
            .flatten()
            .chain(&out.success)
            .chain(&out.failure)
            .map(|c| c.chain.len().max(1))
            .sum();
        if phases > max_states {
            return Err(budget(tree, id, phases as f64, max_states));
        }
    }
    Ok(ShiftedLaw {
        success: tidy(out.success),
        failure: tidy(out.failure),
    })
}

/// Most phases of the product chain of a first-return race
/// ([`first_return`]): its phase distribution is taken at every instant,
/// one weight vector per phase.
const MAX_FIRST_RETURN_PHASES: usize = 2_000;

/// The law of a Parallel with thresholds M = 1, F = 1 — it returns with its
/// first child to return, e.g. BT.CPP's `Timeout` (a deadline racing its
/// child) — whose children are each Markovian (a phase chain without
/// instantaneous outcomes) or deterministic (atoms after 0), as a signed
/// shifted mixture; `None` for any other node.
///
/// The Markovian children run jointly in their product chain `P` (α, T),
/// which exits with the first of them to return. The deterministic ones
/// return only at instants `τ_1 < … < τ_K`; with `u_i` the probability that
/// none has returned before `τ_i` (`u_1 = 1`), the node's law is
///
/// * continuous part: `P`'s exits while no deterministic child has returned,
///   `u_1·PH(α) + Σ_i (u_{i+1} − u_i)·δ_{τ_i} ⊛ PH(π(τ_i))` — the chain
///   restarted at `τ_i` from its phase distribution `π(τ_i) = α e^{T τ_i}`
///   (memorylessness), with the weight the deterministic children lost at
///   `τ_i` (negative);
/// * an atom at each `τ_i`: `|π(τ_i)|`·`u_i`·P(a deterministic child returns
///   at `τ_i` | none before), its outcome the first such child's **in child
///   order** (BT.CPP's tie rule; a Markovian child never returns exactly at
///   `τ_i`).
///
/// Exact up to the transient solution of `P` at the instants (uniformization
/// with its truncation bound).
fn first_return(
    tree: &Graph,
    id: NodeId,
    max_states: usize,
) -> Result<Option<ShiftedLaw>, AnalysisError> {
    let Op::KOfN {
        success: 1,
        failure: 1,
        children,
    } = &tree.node(id).kind
    else {
        return Ok(None);
    };
    let mut chains: Vec<PhaseChain> = Vec::new();
    let mut fixed: Vec<Vec<Atom>> = Vec::new();
    for &c in children {
        if let Some(list) = atoms::atoms(tree, c, max_states)? {
            if list.iter().any(|a| a.time <= 0.0) {
                return Ok(None);
            }
            fixed.push(list);
            continue;
        }
        match phase::chain_within(tree, c, max_states)? {
            Some(ch) if ch.initial_success == 0.0 && ch.initial_failure == 0.0 => chains.push(ch),
            _ => return Ok(None),
        }
    }
    if chains.is_empty() || fixed.is_empty() {
        return Ok(None);
    }
    let size: f64 = chains.iter().map(|c| c.len() as f64).product();
    if size > MAX_FIRST_RETURN_PHASES.min(max_states) as f64 {
        return Ok(None);
    }
    let p = first_exit_product(&chains);
    // the instants, merged across children
    let mut instants: Vec<f64> = fixed.iter().flatten().map(|a| a.time).collect();
    instants.sort_by(f64::total_cmp);
    instants.dedup_by(|a, b| same_instant(*a, *b));
    // per instant: u_i and the atoms' outcome masses (given none before)
    let mut returned = vec![0.0f64; fixed.len()]; // each child's mass before τ_i
    let mut u = Vec::with_capacity(instants.len() + 1);
    let mut outcomes = Vec::with_capacity(instants.len());
    for &tau in &instants {
        let none_before: f64 = returned.iter().map(|r| (1.0 - r).max(0.0)).product();
        u.push(none_before);
        // child order: the first deterministic child returning decides
        let (mut s, mut f, mut quiet) = (0.0, 0.0, 1.0);
        for (h, list) in fixed.iter().enumerate() {
            let alive = (1.0 - returned[h]).max(0.0);
            let (mut qs, mut qf) = (0.0, 0.0);
            for a in list.iter().filter(|a| same_instant(a.time, tau)) {
                match a.outcome {
                    Outcome::Success => qs += a.prob,
                    Outcome::Failure => qf += a.prob,
                }
            }
            if alive > 0.0 {
                s += quiet * qs / alive;
                f += quiet * qf / alive;
                quiet *= (1.0 - (qs + qf) / alive).max(0.0);
            }
            returned[h] += qs + qf;
        }
        outcomes.push((s * none_before, f * none_before));
    }
    u.push(returned.iter().map(|r| (1.0 - r).max(0.0)).product());
    // π(τ_i): the product chain's phase distribution at each instant
    let n = p.len();
    let unit: Vec<Vec<f64>> = (0..n)
        .map(|j| {
            let mut e = vec![0.0; n];
            e[j] = 1.0;
            e
        })
        .collect();
    let weights: Vec<&[f64]> = unit.iter().map(Vec::as_slice).collect();
    let Some(rows) = crate::solve::transient::transient_weighted(
        &p,
        &instants,
        crate::solve::transient::DEFAULT_TOLERANCE,
        &weights,
    ) else {
        return Ok(None);
    };
    let mut law = ShiftedLaw::default();
    let restarted = |pi: &[f64]| -> (f64, PhaseChain) {
        let mass: f64 = pi.iter().sum();
        let mut c = p.clone();
        c.initial = pi
            .iter()
            .enumerate()
            .filter(|(_, &x)| x > 0.0)
            .map(|(j, &x)| (j, x / mass))
            .collect();
        (mass, c)
    };
    let push = |law: &mut ShiftedLaw, shift: f64, weight: f64, chain: &PhaseChain| {
        law.success.push(Component {
            shift,
            weight,
            chain: chain.clone(),
        });
        law.failure.push(Component {
            shift,
            weight,
            chain: count_failure(chain.clone()),
        });
    };
    push(&mut law, 0.0, u[0], &p);
    for (i, &tau) in instants.iter().enumerate() {
        let (mass, chain) = restarted(&rows[i][2..]);
        if mass > 0.0 {
            push(&mut law, tau, (u[i + 1] - u[i]) * mass, &chain);
        }
        let (s, f) = outcomes[i];
        law.success.push(atom(tau, mass * s));
        law.failure.push(atom(tau, mass * f));
    }
    law.success = tidy(law.success);
    law.failure = tidy(law.failure);
    Ok(Some(law))
}

/// The product of independent chains (no instantaneous outcomes) that exits
/// with the first of them to return, with that child's outcome.
fn first_exit_product(chains: &[PhaseChain]) -> PhaseChain {
    let dims: Vec<usize> = chains.iter().map(PhaseChain::len).collect();
    let n: usize = dims.iter().product();
    let mut p = PhaseChain::default();
    for _ in 0..n {
        p.push_phase();
    }
    // mixed radix: the last child varies fastest
    let mut stride = vec![1usize; dims.len()];
    for h in (0..dims.len().saturating_sub(1)).rev() {
        stride[h] = stride[h + 1] * dims[h + 1];
    }
    for state in 0..n {
        for (h, c) in chains.iter().enumerate() {
            let i = state / stride[h] % dims[h];
            p.exit_success[state] += c.exit_success[i];
            p.exit_failure[state] += c.exit_failure[i];
            for &(j, r) in &c.transitions[i] {
                let target = state - i * stride[h] + j * stride[h];
                p.transitions[state].push((target, r));
            }
        }
    }
    // the joint start: the product of the initial distributions
    let mut initial = vec![(0usize, 1.0f64)];
    for (c, &step) in chains.iter().zip(&stride) {
        initial = initial
            .iter()
            .flat_map(|&(s, w)| c.initial.iter().map(move |&(i, q)| (s + i * step, w * q)))
            .collect();
    }
    p.initial = initial;
    p
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `until_failure(Fallback(condition 0.8, fail at 1 s))`: the child
    /// succeeds at once with 0.8 (a repetition in no time) and otherwise
    /// fails at 1 s, so the loop fails at exactly 1 s with probability
    /// Σ 0.8ᵏ·0.2 = 1 — one atom, without a series of instant rounds.
    #[test]
    fn instant_repetitions_of_a_loop_take_no_time() {
        let tree = crate::parse_str(
            "tree:\n  until_failure:\n    child:\n      fallback:\n        children:\n          - condition: {ps: 0.8}\n          - action: {ps: 0, tau_f: 1}\n",
            "loop.yaml",
        )
        .expect("a tree");
        let graph = crate::ir::graph_of(&tree);
        let law = shifted_law(&graph, 0, 1000)
            .expect("a law")
            .expect("a mixture");
        assert!(law.success.is_empty(), "{:?}", law.success);
        assert_eq!(law.failure.len(), 1, "{:?}", law.failure);
        let c = &law.failure[0];
        assert!(c.chain.is_empty() && (c.shift - 1.0).abs() < 1e-15);
        assert!((c.weight * c.chain.initial_success - 1.0).abs() < 1e-14);
    }
}
