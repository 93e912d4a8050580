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

/// One term `weight · (δ_shift ⊛ PH(chain))` of an outcome's law; with
/// `P` = [`Size`], only the term's size and outcome probabilities.
#[derive(Debug, Clone)]
pub(crate) struct Component<P = PhaseChain> {
    /// Deterministic delay before the chain starts (s).
    pub shift: f64,
    /// Signed weight.
    pub weight: f64,
    /// Phase chain in counted/lost form (module docs).
    pub chain: P,
}

/// A node's outcome law: the components of its Success and its Failure.
#[derive(Debug, Clone)]
pub(crate) struct ShiftedLaw<P = PhaseChain> {
    /// Components of the Success sub-distribution.
    pub success: Vec<Component<P>>,
    /// Components of the Failure sub-distribution.
    pub failure: Vec<Component<P>>,
}

impl<P> Default for ShiftedLaw<P> {
    fn default() -> Self {
        ShiftedLaw {
            success: Vec::new(),
            failure: Vec::new(),
        }
    }
}

/// What the mixture's algebra needs of a component's chain: the chain
/// itself (the law), or its [`Size`] only (the estimate made before
/// building it: [`mixture_size`]).
pub(crate) trait Part: Clone {
    /// An empty chain returning the counted outcome at once.
    fn atom() -> Self;
    /// A chain.
    fn of_chain(chain: PhaseChain) -> Self;
    /// Its phases.
    fn len(&self) -> usize;
    /// Whether it has no phase (an atom).
    fn is_empty(&self) -> bool {
        self.len() == 0
    }
    /// The probability of the counted outcome at once.
    fn instant(&self) -> f64;
    /// This chain, then `next` where this one's counted exit is taken.
    fn then(&self, next: &Self) -> Self;
    /// The exits exchanged: Failure counted.
    fn swapped(self) -> Self;
    /// The probability of the counted outcome.
    fn counted(&self) -> f64;
}

impl Part for PhaseChain {
    fn atom() -> Self {
        PhaseChain {
            initial_success: 1.0,
            ..PhaseChain::default()
        }
    }
    fn of_chain(chain: PhaseChain) -> Self {
        chain
    }
    fn len(&self) -> usize {
        PhaseChain::len(self)
    }
    fn instant(&self) -> f64 {
        self.initial_success
    }
    fn then(&self, next: &Self) -> Self {
        phase::concatenate(vec![self.clone(), next.clone()], true)
    }
    fn swapped(mut self) -> Self {
        std::mem::swap(&mut self.exit_success, &mut self.exit_failure);
        std::mem::swap(&mut self.initial_success, &mut self.initial_failure);
        self
    }
    fn counted(&self) -> f64 {
        outcome_probabilities(self)[0]
    }
}

/// P(counted), P(lost) of a chain run from its start.
fn outcome_probabilities(chain: &PhaseChain) -> [f64; 2] {
    let mut out = [chain.initial_success, chain.initial_failure];
    if PhaseChain::is_empty(chain) {
        return out;
    }
    let a = crate::solve::transient::absorption_by_phase(chain);
    for &(i, p) in &chain.initial {
        out[0] += p * a.to_success[i];
        out[1] += p * a.to_failure[i];
    }
    out
}

/// A chain's size and outcome probabilities, without its phases: the
/// mixture's algebra over these sizes a mixture before building it.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Size {
    phases: usize,
    /// P(counted at once), P(lost at once).
    instant: [f64; 2],
    /// P(counted), P(lost).
    outcome: [f64; 2],
}

impl Part for Size {
    fn atom() -> Self {
        Size {
            phases: 0,
            instant: [1.0, 0.0],
            outcome: [1.0, 0.0],
        }
    }
    fn of_chain(chain: PhaseChain) -> Self {
        Size {
            phases: chain.len(),
            instant: [chain.initial_success, chain.initial_failure],
            outcome: outcome_probabilities(&chain),
        }
    }
    fn len(&self) -> usize {
        self.phases
    }
    fn instant(&self) -> f64 {
        self.instant[0]
    }
    fn then(&self, next: &Self) -> Self {
        Size {
            phases: self.phases + next.phases,
            instant: [
                self.instant[0] * next.instant[0],
                self.instant[1] + self.instant[0] * next.instant[1],
            ],
            outcome: [
                self.outcome[0] * next.outcome[0],
                self.outcome[1] + self.outcome[0] * next.outcome[1],
            ],
        }
    }
    fn swapped(self) -> Self {
        Size {
            phases: self.phases,
            instant: [self.instant[1], self.instant[0]],
            outcome: [self.outcome[1], self.outcome[0]],
        }
    }
    fn counted(&self) -> f64 {
        self.outcome[0]
    }
}

impl<P: Part> ShiftedLaw<P> {
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

/// An atom: an empty chain returning the counted outcome at once.
fn atom<P: Part>(shift: f64, weight: f64) -> Component<P> {
    Component {
        shift,
        weight,
        chain: P::atom(),
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
fn leaf_side<P: Part>(p: f64, d: Option<Duration>) -> Vec<Component<P>> {
    if p <= 0.0 {
        return Vec::new();
    }
    match d {
        None => Vec::new(),
        Some(Duration::Fixed { time }) => vec![atom(time, p)],
        Some(Duration::Exponential { rate }) => vec![Component {
            shift: 0.0,
            weight: p,
            chain: P::of_chain(exponential(rate)),
        }],
        // Erlang, hypoexponential, shifted: the stages' chain after the shift
        Some(Duration::PhaseType { shift, stages }) => vec![Component {
            shift,
            weight: p,
            chain: P::of_chain(stages.chain()),
        }],
        Some(Duration::TruncatedExponential { rate, cap }) => {
            let tail = (-rate * cap).exp();
            let chain = P::of_chain(exponential(rate));
            vec![
                Component {
                    shift: 0.0,
                    weight: p,
                    chain: chain.clone(),
                },
                Component {
                    shift: cap,
                    weight: -p * tail,
                    chain,
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
fn tidy<P: Part>(mut comps: Vec<Component<P>>) -> Vec<Component<P>> {
    comps.retain(|c| c.weight != 0.0);
    let (mut atoms, mut rest): (Vec<Component<P>>, Vec<Component<P>>) =
        comps.into_iter().partition(|c| c.chain.is_empty());
    atoms.sort_by(|a, b| a.shift.total_cmp(&b.shift));
    let mut merged: Vec<Component<P>> = Vec::with_capacity(atoms.len());
    for a in atoms {
        match merged.last_mut() {
            Some(l) if same_instant(l.shift, a.shift) => {
                l.weight += a.weight * a.chain.instant();
            }
            _ => {
                let w = a.weight * a.chain.instant();
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
fn convolve<P: Part>(
    a: &[Component<P>],
    b: &[Component<P>],
    room: usize,
    horizon: f64,
) -> Result<Vec<Component<P>>, f64> {
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
                chain: x.chain.then(&y.chain),
            });
        }
    }
    Ok(out)
}

/// Phases held by `parts` (each component counted as at least one).
fn held<P: Part>(parts: &[&[Component<P>]]) -> usize {
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
    mixture(tree, id, max_states, horizon)
}

/// How large a node's shifted mixture would be ([`mixture_size`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum MixtureSize {
    /// This many phases (each component counted as at least one), within
    /// the limit asked.
    Holds(usize),
    /// More than the limit asked.
    Over,
    /// A form the mixture cannot hold (a Parallel below that mixes
    /// timings, other than a first-return race).
    CannotHold,
}

/// The size of node `id`'s shifted mixture on `[0, horizon]`, made
/// before building it: the mixture's algebra run over the chains' sizes
/// and outcome probabilities only ([`Size`]: shifts, weights, atoms merged
/// at equal instants, a loop's number of terms — but no chain built past
/// the Markovian subtrees' own and no chain concatenated), stopped as soon
/// as it passes `limit` phases. A caller picks the mixture or another
/// representation by it, then builds the mixture it picked.
pub(crate) fn mixture_size(
    tree: &Graph,
    id: NodeId,
    limit: usize,
    horizon: f64,
) -> Result<MixtureSize, AnalysisError> {
    Ok(match sizes(tree, id, limit, horizon)? {
        Some(Some(law)) => MixtureSize::Holds(law.phases()),
        Some(None) => MixtureSize::CannotHold,
        None => MixtureSize::Over,
    })
}

/// The mixture's algebra over [`Size`]s within `limit` phases: `None`
/// past the limit — the algebra's own, met before allocating (`convolve`,
/// `within_budget`, the loop's terms, the atoms' instants) —, else
/// whether the mixture holds the node.
fn sizes(
    tree: &Graph,
    id: NodeId,
    limit: usize,
    horizon: f64,
) -> Result<Option<Option<ShiftedLaw<Size>>>, AnalysisError> {
    match mixture::<Size>(tree, id, limit, horizon) {
        Ok(law) => Ok(Some(law)),
        Err(AnalysisError::StateBudget { .. }) => Ok(None),
        Err(e) => Err(e),
    }
}

/// The shifts of node `id`'s shifted mixture — the instants where its
/// CDFs may jump or kink — where it holds within `limit` phases, from the
/// algebra over sizes ([`mixture_size`]; no chain is built): `None` past
/// the limit or where the mixture cannot hold the node.
pub(crate) fn mixture_shifts(
    tree: &Graph,
    id: NodeId,
    limit: usize,
) -> Result<Option<Vec<f64>>, AnalysisError> {
    Ok(sizes(tree, id, limit, f64::INFINITY)?
        .flatten()
        .map(|l| l.shifts().collect()))
}

/// [`shifted_law_within`] over any [`Part`]: the law, or its sizes.
fn mixture<P: Part>(
    tree: &Graph,
    id: NodeId,
    max_states: usize,
    horizon: f64,
) -> Result<Option<ShiftedLaw<P>>, AnalysisError> {
    let law = shifted_law_unclipped(tree, id, max_states, horizon)?;
    Ok(law.map(|l| {
        let clip = |v: Vec<Component<P>>| -> Vec<Component<P>> {
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

fn shifted_law_unclipped<P: Part>(
    tree: &Graph,
    id: NodeId,
    max_states: usize,
    horizon: f64,
) -> Result<Option<ShiftedLaw<P>>, AnalysisError> {
    let node = tree.node(id);
    // Markovian subtrees: their exact chain, one component per outcome
    if let Some(chain) = phase::markovian_chain_of(tree, id, max_states)? {
        return Ok(Some(ShiftedLaw {
            success: vec![Component {
                shift: 0.0,
                weight: 1.0,
                chain: P::of_chain(chain.clone()),
            }],
            failure: vec![Component {
                shift: 0.0,
                weight: 1.0,
                chain: P::of_chain(chain.swapped()),
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
        match mixture(tree, c, max_states, horizon)? {
            Some(l) => laws.push(l),
            None => return Ok(None),
        }
    }
    let check = |l: ShiftedLaw<P>| -> Result<ShiftedLaw<P>, AnalysisError> {
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
            Some(law) => ShiftedLaw {
                success: parts_of(law.success),
                failure: parts_of(law.failure),
            },
            None => return Ok(None),
        },
        _ => return Ok(None),
    };
    check(law).map(Some)
}

/// Components of chains as components of any [`Part`].
fn parts_of<P: Part>(comps: Vec<Component>) -> Vec<Component<P>> {
    comps
        .into_iter()
        .map(|c| Component {
            shift: c.shift,
            weight: c.weight,
            chain: P::of_chain(c.chain),
        })
        .collect()
}

fn from_atoms<P: Part>(list: &[Atom]) -> ShiftedLaw<P> {
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
fn in_turn<P: Part>(
    laws: Vec<ShiftedLaw<P>>,
    sequence: bool,
    tree: &Graph,
    id: NodeId,
    max_states: usize,
    horizon: f64,
) -> Result<ShiftedLaw<P>, AnalysisError> {
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
fn counted_probability<P: Part>(c: &Component<P>) -> f64 {
    c.weight * c.chain.counted()
}

/// Refuses (a budget error) once the components of a fold, still going
/// and stopped, hold more than `max_states` phases in all.
fn within_budget<P: Part>(
    going: &[Component<P>],
    stopped: &[Component<P>],
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

/// Most phases the shifted mixture may hold, by its estimated size
/// ([`mixture_size`]), to give a node's curve: past it the composed laws
/// answer (exact too, and faster there).
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

/// Nodes' shifted mixtures (or why none), kept by a plan: each is
/// estimated and built once per node and budget, not at every curve query
/// (a quadrature's rounds ask a child's curve tens of times).
#[derive(Default)]
pub(crate) struct KeptMixtures(
    std::cell::RefCell<std::collections::HashMap<(NodeId, usize), FirstMixture>>,
);

impl KeptMixtures {
    /// Node `id`'s mixture within `budget` phases ([`mixture_size`]),
    /// built at the first call (within `max_states`, which the estimate
    /// leaves room for).
    pub(crate) fn first(
        &self,
        tree: &Graph,
        id: NodeId,
        budget: usize,
        max_states: usize,
    ) -> Result<FirstMixture, AnalysisError> {
        if let Some(m) = self.0.borrow().get(&(id, budget)) {
            return Ok(m.clone());
        }
        let m = match mixture_size(tree, id, budget, f64::INFINITY)? {
            MixtureSize::Holds(_) => match shifted_law(tree, id, budget.max(max_states))? {
                Some(law) => FirstMixture::Built(std::sync::Arc::new(law)),
                None => FirstMixture::CannotHold,
            },
            MixtureSize::CannotHold => FirstMixture::CannotHold,
            MixtureSize::Over => FirstMixture::Over,
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
fn loop_series<P: Part>(
    l: ShiftedLaw<P>,
    until_success: bool,
    tree: &Graph,
    id: NodeId,
    max_states: usize,
    horizon: f64,
) -> Result<ShiftedLaw<P>, AnalysisError> {
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
    let instant = |c: &Component<P>| c.chain.is_empty() && c.shift == 0.0;
    let p0: f64 = again
        .iter()
        .filter(|c| instant(c))
        .map(|c| c.weight * c.chain.instant())
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
fn through_flow<P: Part>(
    laws: &[ShiftedLaw<P>],
    flow: &Flow,
    tree: &Graph,
    id: NodeId,
    max_states: usize,
    horizon: f64,
) -> Result<ShiftedLaw<P>, AnalysisError> {
    let states = flow.states();
    let mut entered: Vec<Vec<Component<P>>> = vec![Vec::new(); states.len()];
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
            chain: chain.clone().swapped(),
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

    fn graph(yaml: &str) -> crate::ir::Graph {
        let tree = crate::parse_str(yaml, "t.yaml").expect("a tree");
        crate::ir::graph_of(&tree)
    }

    /// The size estimate, by hand: a Sequence of `k` actions each
    /// succeeding after 1 s and failing after 2 s fails at `j − 1 + 2` for
    /// the `j`-th failure (k distinct atoms) and succeeds at `k` (one):
    /// `k + 1` components, an atom counted as one phase. With an
    /// exponential action second — a chain of two phases, one per outcome
    /// (entered with ps and pf), as Success and Failure take different
    /// rates — Success is one component (shift 1, two phases) and Failure
    /// an atom at 2 plus one (shift 1, two phases): 5.
    /// Past the limit: `Over`; a Parallel that needs both children and mixes
    /// timings: `CannotHold`. Every estimate equals the size of the mixture
    /// then built, and `Over` is what building within the limit refuses.
    #[test]
    fn mixture_sizes_are_known_before_building() {
        let fixed = "{action: {ps: 0.5, tau_s: 1, tau_f: 2}}";
        let seq = |k: usize| {
            format!(
                "tree:\n  sequence:\n    children: [{}]\n",
                vec![fixed; k].join(", ")
            )
        };
        for k in [1usize, 2, 5, 12] {
            let g = graph(&seq(k));
            assert_eq!(
                mixture_size(&g, 0, 1000, f64::INFINITY).unwrap(),
                MixtureSize::Holds(k + 1),
                "k = {k}"
            );
            let built = shifted_law(&g, 0, 1000).unwrap().expect("a mixture");
            assert_eq!(built.phases(), k + 1);
            assert_eq!(
                mixture_size(&g, 0, k, f64::INFINITY).unwrap(),
                MixtureSize::Over
            );
            assert!(matches!(
                shifted_law(&g, 0, k),
                Err(AnalysisError::StateBudget { .. })
            ));
            let shifts = mixture_shifts(&g, 0, 1000).unwrap().expect("shifts");
            let mut expected: Vec<f64> = (1..=k).map(|j| (j + 1) as f64).collect();
            expected.push(k as f64);
            let mut got = shifts.clone();
            got.sort_by(f64::total_cmp);
            expected.sort_by(f64::total_cmp);
            assert_eq!(got, expected, "k = {k}");
        }
        let g = graph(&format!(
            "tree:\n  sequence:\n    children: [{fixed}, {{action: {{ps: 0.5, mu: 2, nu: 3}}}}]\n"
        ));
        assert_eq!(
            mixture_size(&g, 0, 1000, f64::INFINITY).unwrap(),
            MixtureSize::Holds(5)
        );
        assert_eq!(shifted_law(&g, 0, 1000).unwrap().unwrap().phases(), 5);
        let g = graph(&format!(
            "tree:\n  parallel:\n    success_threshold: 2\n    children: [{fixed}, {{action: {{ps: 0.5, mu: 2, nu: 3}}}}]\n"
        ));
        assert_eq!(
            mixture_size(&g, 0, 1000, f64::INFINITY).unwrap(),
            MixtureSize::CannotHold
        );
        assert!(shifted_law(&g, 0, 1000).unwrap().is_none());
        // a loop: its terms counted from the repetition's probability as
        // the law's are (0.5ᴷ ≤ 1e-14: K = 47 atoms at 1, 2, …, 47 s)
        let g =
            graph("tree:\n  until_success:\n    child: {action: {ps: 0.5, tau_s: 1, tau_f: 1}}\n");
        assert_eq!(
            mixture_size(&g, 0, 1000, f64::INFINITY).unwrap(),
            MixtureSize::Holds(47)
        );
        assert_eq!(shifted_law(&g, 0, 1000).unwrap().unwrap().phases(), 47);
    }

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
