//! Exact phase chains: every subtree whose actions are stochastic (Def. 9.7)
//! is exactly an absorbing CTMC of exponential phases.
//!
//! * An action is the two-phase mixture of Def. 9.7: with probability `ps`
//!   it enters a phase of rate `mu` that exits to Success, with probability
//!   `pf` a phase of rate `nu` that exits to Failure. An Erlang or
//!   hypoexponential outcome time is its stages in series instead of one
//!   phase, a hyperexponential or general phase-type time its own (acyclic)
//!   chain.
//! * A condition has no phase: it starts in Success with probability `ps`,
//!   in Failure otherwise.
//! * A Sequence (Fallback) concatenates its children's phases: a child's
//!   Success (Failure) exit enters the next child's initial distribution, its
//!   other exit is the node's outcome. Instantaneous outcomes of a child pass
//!   straight on to the next child.
//! * A Parallel runs its children jointly: its phases are the reachable
//!   tuples of the children's local states (a phase, or "returned Success",
//!   or "returned Failure"), and it exits as soon as ≥ M children have
//!   succeeded or > N − M have failed (the rest are halted). Tuples are
//!   numbered by the sum of the children's local ranks, which every
//!   transition increases: the chain stays acyclic and topologically ordered.

use std::collections::HashMap;

use super::mrg::{Policy, Status};
use super::AnalysisError;
use crate::ir::{FlowGraph, Graph, Leaf, Op, Outcome};
use crate::solve::chain::PhaseChain;
use crate::tree::{Duration, NodeId, Tree};

/// A distribution over "where a run goes next": transient phases, or an
/// instantaneous Success or Failure.
#[derive(Debug, Clone, Default)]
struct Entry {
    states: Vec<(usize, f64)>,
    success: f64,
    failure: f64,
}

/// Builds the exact phase chain of the subtree rooted at `id`.
///
/// Fails if a leaf's times are not exponential (deterministic and hybrid
/// actions have no finite phase representation) or if a Parallel's product
/// would exceed `max_states` phases.
pub fn phase_chain(
    tree: &Tree,
    id: NodeId,
    max_states: usize,
) -> Result<PhaseChain, AnalysisError> {
    let lowered = super::lower(tree)?;
    chain_of(&lowered.graph, lowered.node(id), max_states)
}

/// The bound [`chain_size`] puts on the length of [`phase_chain`]`(tree,
/// id, max_states)` before building it: `Some(phases)` where within
/// `max_states` (then [`phase_chain`] builds a chain of at most that many
/// phases), `None` where over it or where a leaf below is not phase-type.
pub fn phase_chain_bound(
    tree: &Tree,
    id: NodeId,
    max_states: usize,
) -> Result<Option<f64>, AnalysisError> {
    let lowered = super::lower(tree)?;
    let size = chain_size(
        &lowered.graph,
        lowered.node(id),
        max_states,
        &mut HashMap::new(),
    )?;
    Ok(match size {
        ChainSize::Within(n) => Some(n),
        ChainSize::NotMarkovian(_) | ChainSize::Over(_) => None,
    })
}

/// Whether an outcome of probability `p` with time `d` has a phase chain:
/// it cannot happen, takes no time, or has a phase-type time (exponential,
/// Erlang, hypo-, hyperexponential, phase-type). The planner's shapes and
/// [`markovian`] use this one rule, which is [`chain_of`]'s.
pub(crate) fn outcome_markovian(p: f64, d: Option<Duration>) -> bool {
    p <= 0.0
        || matches!(d, Some(Duration::Fixed { time }) if time == 0.0)
        || d.is_some_and(|d| d.is_phase_type())
}

/// Whether the subtree at `id` of a tree's IR has a phase chain (every
/// action's outcomes [`outcome_markovian`]): then [`chain_of`] can fail only
/// for its budget. Decided from the leaves, before building anything.
pub(crate) fn markovian(tree: &Graph, id: NodeId) -> bool {
    tree.subtree(id).all(|n| match &tree.node(n).kind {
        Op::Leaf(Leaf::Action(a)) => {
            outcome_markovian(a.ps, a.success) && outcome_markovian(a.pf, a.failure)
        }
        _ => true,
    })
}

/// [`chain_of`] where the subtree is [`markovian`], `None` where it is not;
/// refused where its size ([`chain_size`]) is over the budget. Nothing is
/// built unless it fits.
pub(crate) fn markovian_chain_of(
    tree: &Graph,
    id: NodeId,
    max_states: usize,
) -> Result<Option<PhaseChain>, AnalysisError> {
    if !markovian(tree, id) {
        return Ok(None);
    }
    match chain_size(tree, id, max_states, &mut HashMap::new())? {
        ChainSize::Within(_) => chain_of(tree, id, max_states).map(Some),
        ChainSize::NotMarkovian(_) => Ok(None),
        ChainSize::Over(e) => Err(e),
    }
}

/// [`chain_of`] where its size ([`chain_size`]) is within the budget,
/// `None` (nothing built) where it is over it or a leaf is not phase-type.
pub(crate) fn chain_within(
    tree: &Graph,
    id: NodeId,
    max_states: usize,
) -> Result<Option<PhaseChain>, AnalysisError> {
    match chain_size(tree, id, max_states, &mut HashMap::new())? {
        ChainSize::Within(_) => chain_of(tree, id, max_states).map(Some),
        ChainSize::NotMarkovian(_) | ChainSize::Over(_) => Ok(None),
    }
}

pub(crate) fn chain_of(
    tree: &Graph,
    id: NodeId,
    max_states: usize,
) -> Result<PhaseChain, AnalysisError> {
    let node = tree.node(id);
    match &node.kind {
        Op::Leaf(Leaf::Action(a)) => {
            let mut c = PhaseChain::default();
            for (p, d, success) in [(a.ps, a.success, true), (a.pf, a.failure, false)] {
                if p <= 0.0 {
                    continue;
                }
                // a zero-time outcome (a synchronous action) is
                // instantaneous, as a condition's
                if let Some(Duration::Fixed { time: 0.0 }) = d {
                    if success {
                        c.initial_success += p;
                    } else {
                        c.initial_failure += p;
                    }
                    continue;
                }
                // exponential: one phase; Erlang, hypoexponential: in
                // series; hyperexponential, phase-type: its (acyclic) chain
                // (a leaf's own chain is small: at most MAX_PHASES phases)
                let Some(law) = d.and_then(|d: Duration| d.phase_chain()) else {
                    return Err(AnalysisError::NotMarkovian {
                        leaf: node.name.clone(),
                    });
                };
                if c.len() + law.len() > max_states {
                    return Err(AnalysisError::StateBudget {
                        node: node.name.clone(),
                        states: (c.len() + law.len()) as f64,
                        budget: max_states,
                    });
                }
                let first = c.len();
                for i in 0..law.len() {
                    let k = c.push_phase();
                    c.transitions[k] = law.transitions[i]
                        .iter()
                        .map(|&(j, r)| (first + j, r))
                        .collect();
                    if success {
                        c.exit_success[k] = law.exit_success[i];
                    } else {
                        c.exit_failure[k] = law.exit_success[i];
                    }
                }
                c.initial
                    .extend(law.initial.iter().map(|&(i, a)| (first + i, p * a)));
            }
            Ok(c)
        }
        Op::Leaf(Leaf::Condition { ps }) => Ok(PhaseChain {
            initial_success: *ps,
            initial_failure: 1.0 - ps,
            ..PhaseChain::default()
        }),
        _ => {
            let chains = node
                .kind
                .children()
                .iter()
                .map(|&c| chain_of(tree, c, max_states))
                .collect::<Result<Vec<_>, _>>()?;
            combine(tree, id, chains, max_states)
        }
    }
}

/// What [`chain_of`] would build for a subtree, told before building it.
#[derive(Debug, Clone)]
pub(crate) enum ChainSize {
    /// At most this many phases, within the budget: [`chain_of`] builds it
    /// (it cannot fail for its budget).
    Within(f64),
    /// A leaf below has no phase chain ([`markovian`] is false).
    NotMarkovian(AnalysisError),
    /// Over the budget: the refusal, naming the node that exceeds it and
    /// its estimated number of states.
    Over(AnalysisError),
}

impl ChainSize {
    /// Whether [`chain_of`] builds the chain.
    pub(crate) fn fits(&self) -> bool {
        matches!(self, ChainSize::Within(_))
    }
}

/// An upper bound of the length of [`chain_of`]`(tree, id, max_states)`,
/// computed from the leaves' phase counts without building the chain: sums
/// along a flow, the count of a Parallel's tuples that leave it running
/// (by the numbers of children returned so far, a programme over its
/// children), and a loop's copies — the only node whose size depends on
/// its child's probabilities, so a loop builds its child's chain (within
/// the budget, by this same estimate first) to count its copies. The bound
/// errs only upwards: where it is within `max_states`, [`chain_of`]
/// succeeds. `memo` keeps the answers of nodes already estimated.
pub(crate) fn chain_size(
    tree: &Graph,
    id: NodeId,
    max_states: usize,
    memo: &mut HashMap<NodeId, ChainSize>,
) -> Result<ChainSize, AnalysisError> {
    if let Some(s) = memo.get(&id) {
        return Ok(s.clone());
    }
    let size = estimate(tree, id, max_states, memo)?;
    memo.insert(id, size.clone());
    Ok(size)
}

fn estimate(
    tree: &Graph,
    id: NodeId,
    max_states: usize,
    memo: &mut HashMap<NodeId, ChainSize>,
) -> Result<ChainSize, AnalysisError> {
    let node = tree.node(id);
    let over = |states: f64, budget: usize| {
        ChainSize::Over(AnalysisError::StateBudget {
            node: node.name.clone(),
            states,
            budget,
        })
    };
    let within = |states: f64| {
        if states > max_states as f64 {
            over(states, max_states)
        } else {
            ChainSize::Within(states)
        }
    };
    let sizes = match children_sizes(tree, node.kind.children(), max_states, memo)? {
        Ok(sizes) => sizes,
        Err(refusal) => return Ok(refusal),
    };
    Ok(match &node.kind {
        Op::Leaf(Leaf::Action(a)) => {
            let mut phases = 0.0;
            for (p, d) in [(a.ps, a.success), (a.pf, a.failure)] {
                if p <= 0.0 || matches!(d, Some(Duration::Fixed { time }) if time == 0.0) {
                    continue;
                }
                match d.and_then(|d: Duration| d.phase_chain()) {
                    Some(law) => phases += law.len() as f64,
                    None => {
                        return Ok(ChainSize::NotMarkovian(AnalysisError::NotMarkovian {
                            leaf: node.name.clone(),
                        }))
                    }
                }
            }
            within(phases)
        }
        Op::Leaf(Leaf::Condition { .. }) => ChainSize::Within(0.0),
        Op::Flow(flow) => within(match flow.graph {
            FlowGraph::Chain { .. } => sizes.iter().sum(),
            FlowGraph::Repeat { times, .. } => sizes[0] * times as f64,
            FlowGraph::States(_) => (0..flow.state_count())
                .map(|i| sizes[flow.state(i).child])
                .sum(),
        }),
        Op::Map { .. } => ChainSize::Within(sizes[0]),
        Op::Loop { until, .. } => {
            let child = chain_of(tree, node.kind.children()[0], max_states)?;
            within(loop_shape(child, *until == Outcome::Success).len())
        }
        Op::KOfN {
            success,
            failure,
            children,
        } => {
            let policy = Policy::of(&node.kind).expect("a Parallel has a policy");
            let bound: f64 = sizes.iter().map(|n| n + 2.0).product();
            let share = max_states / BOOK_PARALLEL_SHARE;
            if *failure >= children.len() + 1 - success && bound > share as f64 {
                return Ok(over(bound, share));
            }
            product_size(&node.name, &sizes, policy, max_states)
        }
    })
}

/// The chain sizes of `children`, all within the budget, or the refusal
/// of one: a leaf without a phase chain anywhere first, else the first
/// child over the budget.
pub(crate) fn children_sizes(
    tree: &Graph,
    children: &[NodeId],
    max_states: usize,
    memo: &mut HashMap<NodeId, ChainSize>,
) -> Result<Result<Vec<f64>, ChainSize>, AnalysisError> {
    let mut sizes = Vec::with_capacity(children.len());
    let mut first_over = None;
    for &c in children {
        match chain_size(tree, c, max_states, memo)? {
            ChainSize::Within(n) => sizes.push(n),
            s @ ChainSize::NotMarkovian(_) => return Ok(Err(s)),
            s @ ChainSize::Over(_) => {
                first_over.get_or_insert(s);
            }
        }
    }
    Ok(first_over.map_or(Ok(sizes), Err))
}

/// The size of the product chain ([`product`]) of a Parallel named `name`
/// with `policy` over children of at most `sizes` phases.
pub(crate) fn product_size(
    name: &str,
    sizes: &[f64],
    policy: Policy,
    max_states: usize,
) -> ChainSize {
    let over = |states: f64| {
        ChainSize::Over(AnalysisError::StateBudget {
            node: name.to_string(),
            states,
            budget: max_states,
        })
    };
    let bound: f64 = sizes.iter().map(|n| n + 2.0).product();
    if bound > 16.0 * max_states as f64 {
        return over(bound);
    }
    let (running, widest_prefix) = running_tuples(sizes, policy);
    if running > max_states as f64 || widest_prefix > 4.0 * max_states as f64 {
        return over(running.max(widest_prefix / 4.0));
    }
    ChainSize::Within(running)
}

/// The number of a Parallel's tuples of its children's local states (a
/// phase, "returned Success", "returned Failure") on which it still runs —
/// the most its product chain can reach ([`product`]) — and the most of
/// any prefix of its children (its entry, built child by child). Counted by
/// the numbers of successes and failures so far, `sizes[h]` the phases of
/// child `h`.
fn running_tuples(sizes: &[f64], policy: Policy) -> (f64, f64) {
    let n = sizes.len();
    // count[s][f]: running prefixes with s successes and f failures
    let mut count = vec![vec![0.0; n + 1]; n + 1];
    count[0][0] = 1.0;
    let mut widest: f64 = 1.0;
    let mut total = 1.0;
    for (h, &phases) in sizes.iter().enumerate() {
        let mut next = vec![vec![0.0; n + 1]; n + 1];
        for s in 0..=h {
            for f in 0..=h - s {
                let c = count[s][f];
                if c == 0.0 {
                    continue;
                }
                next[s][f] += c * phases;
                next[s + 1][f] += c;
                next[s][f + 1] += c;
            }
        }
        total = 0.0;
        for (s, row) in next.iter_mut().enumerate() {
            for (f, c) in row.iter_mut().enumerate() {
                if *c != 0.0 && policy.status(n, s, f) != Status::Running {
                    *c = 0.0;
                }
                total += *c;
            }
        }
        widest = widest.max(total);
        count = next;
    }
    (total, widest)
}

/// The phase chain of control node `id` from its children's chains (in
/// child order): concatenation for Sequence/Fallback, the decorator's
/// transformation, or the Parallel product. Lets a caller substitute a
/// child's chain (e.g. by a marker, see [`crate::compile::curve`]).
pub(crate) fn combine(
    tree: &Graph,
    id: NodeId,
    chains: Vec<PhaseChain>,
    max_states: usize,
) -> Result<PhaseChain, AnalysisError> {
    let node = tree.node(id);
    match &node.kind {
        Op::Leaf(_) => unreachable!("combine is called on control nodes"),
        Op::Flow(flow) => {
            let (copies, stop) = match flow.graph {
                FlowGraph::Chain { stop } => (None, stop),
                FlowGraph::Repeat { times, stop } => (Some(times), stop),
                FlowGraph::States(_) => {
                    let total = super::flow::glued_len(flow, &chains);
                    if total > max_states {
                        return Err(AnalysisError::StateBudget {
                            node: node.name.clone(),
                            states: total as f64,
                            budget: max_states,
                        });
                    }
                    return Ok(super::flow::glue(flow, &chains));
                }
            };
            let total = match copies {
                None => chains.iter().map(PhaseChain::len).sum::<usize>() as f64,
                Some(k) => chains[0].len() as f64 * k as f64,
            };
            if total > max_states as f64 {
                return Err(AnalysisError::StateBudget {
                    node: node.name.clone(),
                    states: total,
                    budget: max_states,
                });
            }
            let sequence = stop == Outcome::Failure;
            Ok(match copies {
                None => concatenate(chains, sequence),
                Some(k) => concatenate(vec![chains[0].clone(); k], sequence),
            })
        }
        Op::Map {
            on_success,
            on_failure,
            ..
        } => {
            let c = chains.into_iter().next().expect("a map has a child");
            Ok(map_outcomes(c, *on_success, *on_failure))
        }
        Op::Loop { until, .. } => {
            let c = chains.into_iter().next().expect("a loop has a child");
            unrolled_loop(&node.name, c, *until == Outcome::Success, max_states)
        }
        Op::KOfN {
            success: success_threshold,
            failure: failure_threshold,
            children,
        } => {
            let policy = Policy::of(&node.kind).expect("a Parallel has a policy");
            // with the book's thresholds the node is counted rather than
            // multiplied out when its product is large ([`super::counts`],
            // [`crate::compile::curve`]): refuse early instead of building it
            let bound: f64 = chains.iter().map(|c| (c.len() + 2) as f64).product();
            let limit = max_states / BOOK_PARALLEL_SHARE;
            if *failure_threshold >= children.len() + 1 - success_threshold && bound > limit as f64
            {
                return Err(AnalysisError::StateBudget {
                    node: node.name.clone(),
                    states: bound,
                    budget: limit,
                });
            }
            product(&chains, policy, max_states).ok_or_else(|| AnalysisError::StateBudget {
                node: node.name.clone(),
                states: chains.iter().map(|c| (c.len() + 2) as f64).product(),
                budget: max_states,
            })
        }
    }
}

/// A chain whose exits to Success lead to `on_success` and whose exits to
/// Failure lead to `on_failure` (an inverter swaps them, a force decorator
/// merges them).
fn map_outcomes(mut c: PhaseChain, on_success: Outcome, on_failure: Outcome) -> PhaseChain {
    let map = |s: f64, f: f64| {
        let mut out = [0.0; 2];
        out[on_success.index()] += s;
        out[on_failure.index()] += f;
        (out[0], out[1])
    };
    for i in 0..c.len() {
        (c.exit_success[i], c.exit_failure[i]) = map(c.exit_success[i], c.exit_failure[i]);
    }
    (c.initial_success, c.initial_failure) = map(c.initial_success, c.initial_failure);
    c
}

/// Mass a loop's unrolled chain may leave behind ([`unrolled_loop`]).
pub const LOOP_TAIL: f64 = 1e-14;

/// The phase chain of a loop without a bound (`until_failure`,
/// `until_success`) over a child with chain `c`, unrolled: K fresh copies of
/// the child in turn (a Sequence of copies for `until_failure`, a Fallback
/// for `until_success`), with K the least such that the probability of K
/// repetitions, `p_againᴷ`, is at most [`LOOP_TAIL`]. The loop's cyclic
/// chain (the counted exit re-entering the start) is exact but cyclic, and
/// every solver of absorbing chains here relies on a topological order; the
/// unrolled chain is acyclic, and differs from the cyclic one only after K
/// repetitions: that mass (≤ 1e-14) ends the loop at its K-th repetition
/// instead of going round again, so P(Success), P(Failure) stay exact and
/// `π(t)` is within 1e-14. Refused when K × the child's phases exceeds
/// `max_states` (a child that repeats almost surely).
pub fn unrolled_loop(
    name: &str,
    c: PhaseChain,
    until_success: bool,
    max_states: usize,
) -> Result<PhaseChain, AnalysisError> {
    Ok(match loop_shape(c, until_success) {
        LoopShape::Trap => trap(),
        LoopShape::Once(c) => finish_loop(c, until_success),
        LoopShape::Folded(c) => c,
        LoopShape::Copies(c, copies) => {
            let total = copies * c.len() as f64;
            if total > max_states as f64 {
                return Err(AnalysisError::StateBudget {
                    node: name.to_string(),
                    states: total,
                    budget: max_states,
                });
            }
            finish_loop(
                concatenate(vec![c; copies as usize], !until_success),
                until_success,
            )
        }
    })
}

/// The loop's exact cyclic chain over its child's chain `c`: the exit that
/// repeats the child ("again") re-enters the child's entry distribution,
/// an instantaneous "again" folded in by renormalising the entry (the
/// entry is `initial / (1 − p₀)`). Cyclic: only for solvers that need no
/// order of the phases (uniformization: `loop_curve`, a composed law's
/// sampled chain). `None` where the child never ends the loop (it runs
/// forever).
pub fn cyclic_loop(mut c: PhaseChain, until_success: bool) -> Option<PhaseChain> {
    // work with "again" as the Success exit, then swap back
    let swap = |c: &mut PhaseChain| {
        if until_success {
            std::mem::swap(&mut c.exit_success, &mut c.exit_failure);
            std::mem::swap(&mut c.initial_success, &mut c.initial_failure);
        }
    };
    swap(&mut c);
    let again0 = c.initial_success;
    if again0 >= 1.0 || (c.initial.is_empty() && c.initial_failure <= 0.0) {
        return None;
    }
    let scale = 1.0 / (1.0 - again0);
    let entry: Vec<(usize, f64)> = c.initial.iter().map(|&(j, p)| (j, p * scale)).collect();
    let end0 = c.initial_failure * scale;
    for i in 0..c.len() {
        let again = std::mem::take(&mut c.exit_success[i]);
        if again > 0.0 {
            c.transitions[i].extend(entry.iter().map(|&(j, p)| (j, again * p)));
            c.exit_failure[i] += again * end0;
        }
    }
    c.initial = entry;
    c.initial_success = 0.0;
    c.initial_failure = end0;
    swap(&mut c);
    Some(c)
}

/// Phases of an unrolled chain holding a loop past which the loop's cyclic
/// chain ([`cyclic_loop`]) samples its law and its ancestors take composed
/// laws (`Plan::long_unrolled`, `law::Builder::piece`): uniformization
/// steps every copy of the unrolled chain (survey tree 2786: a Repeat over
/// an `until_success` unrolled into 36,126 phases, six of its own).
pub const LONG_UNROLLED: f64 = 4096.0;

/// Whether a chain of `size` holding a loop (`looped`) is a loop unrolled
/// into more than [`LONG_UNROLLED`] phases: the one test of the planner's
/// chain rule and of a composed law's chain pieces.
pub(crate) fn long_unrolled(size: &ChainSize, looped: bool) -> bool {
    looped && matches!(size, ChainSize::Within(n) if *n > LONG_UNROLLED)
}

/// Whether the subtree of `id` holds a loop without a bound.
pub fn holds_loop(tree: &Graph, id: NodeId) -> bool {
    tree.subtree(id)
        .any(|n| matches!(tree.node(n).kind, Op::Loop { .. }))
}

/// What [`unrolled_loop`] makes of a child's chain, before it builds it.
enum LoopShape {
    /// The child never ends the loop: one trap phase.
    Trap,
    /// Its repetitions take no time: the child's chain (normalised), once.
    Once(PhaseChain),
    /// The loop folded onto the child's own phases ([`folded_loop`]).
    Folded(PhaseChain),
    /// This many copies of the (normalised) child in turn.
    Copies(PhaseChain, f64),
}

impl LoopShape {
    /// The number of phases of the loop's chain.
    fn len(&self) -> f64 {
        match self {
            LoopShape::Trap => 1.0,
            LoopShape::Once(c) | LoopShape::Folded(c) => c.len() as f64,
            LoopShape::Copies(c, copies) => copies * c.len() as f64,
        }
    }
}

fn loop_shape(mut c: PhaseChain, until_success: bool) -> LoopShape {
    let absorption = crate::solve::transient::absorption_by_phase(&c);
    let from_start = |h: &[f64]| c.initial.iter().map(|&(i, p)| p * h[i]).sum::<f64>();
    let success = c.initial_success + from_start(&absorption.to_success);
    let failure = c.initial_failure + from_start(&absorption.to_failure);
    let (mut again, end) = if until_success {
        (failure, success)
    } else {
        (success, failure)
    };
    if end <= 0.0 {
        // the child never ends the loop: it never returns, one trap phase
        // (no exits) holding all the mass
        return LoopShape::Trap;
    }
    // a repetition at once (the child's instantaneous "again", e.g. a
    // condition) takes no time: the loop enters its child as if it had not
    // happened, the entry renormalised by 1 − p₀, and only the repetitions
    // that take time are unrolled (a loop over a Fallback whose first
    // condition repeats it 80% of the time needed 145 copies, now one)
    let instant = if until_success {
        &mut c.initial_failure
    } else {
        &mut c.initial_success
    };
    let p0 = std::mem::take(instant);
    if p0 > 0.0 {
        let w = 1.0 / (1.0 - p0);
        c.initial.iter_mut().for_each(|(_, p)| *p *= w);
        if until_success {
            c.initial_success *= w;
        } else {
            c.initial_failure *= w;
        }
        again = ((again - p0) * w).max(0.0);
    }
    if c.is_empty() || again <= 0.0 {
        // instantaneous repetitions take no time; one copy otherwise
        return LoopShape::Once(c);
    }
    if let Some(folded) = folded_loop(&c, until_success) {
        return LoopShape::Folded(folded);
    }
    let copies = (LOOP_TAIL.ln() / again.min(1.0 - 1e-300).ln())
        .ceil()
        .max(1.0);
    LoopShape::Copies(c, copies)
}

/// The loop's chain `out` with the mass still repeating after its last copy
/// ending the loop too.
fn finish_loop(mut out: PhaseChain, until_success: bool) -> PhaseChain {
    for i in 0..out.len() {
        let total = out.exit_success[i] + out.exit_failure[i];
        (out.exit_success[i], out.exit_failure[i]) = if until_success {
            (total, 0.0)
        } else {
            (0.0, total)
        };
    }
    let total = out.initial_success + out.initial_failure;
    (out.initial_success, out.initial_failure) = if until_success {
        (total, 0.0)
    } else {
        (0.0, total)
    };
    out
}

/// The loop's exact chain without unrolling, when the child repeats from a
/// single phase: no instantaneous outcome, no transitions, and exactly one
/// entry phase `s` with the "again" exit (and no ending exit). A run that
/// leaves `s` to repeat enters `s` again with probability `α_s` — by
/// memorylessness no change — and phase `j` with `α_j`: so `s` moves to
/// `j` at rate `a_s·α_j`, acyclic. A single action (ps, Exp(mu) / Exp(nu)) is
/// such a child: the loop is then exact with the child's phases alone.
fn folded_loop(c: &PhaseChain, until_success: bool) -> Option<PhaseChain> {
    if c.initial_success != 0.0 || c.initial_failure != 0.0 {
        return None;
    }
    if c.transitions.iter().any(|t| !t.is_empty()) {
        return None;
    }
    let again = |i: usize| {
        if until_success {
            c.exit_failure[i]
        } else {
            c.exit_success[i]
        }
    };
    let end = |i: usize| {
        if until_success {
            c.exit_success[i]
        } else {
            c.exit_failure[i]
        }
    };
    let repeating: Vec<usize> = (0..c.len()).filter(|&i| again(i) > 0.0).collect();
    let [s] = repeating[..] else {
        return None;
    };
    if end(s) > 0.0 {
        return None;
    }
    let alpha_s: f64 = c.initial.iter().filter(|e| e.0 == s).map(|e| e.1).sum();
    if alpha_s >= 1.0 {
        return None;
    }
    // `s` first (its moves go to later phases), the others in order
    let order: Vec<usize> = std::iter::once(s)
        .chain((0..c.len()).filter(|&i| i != s))
        .collect();
    let mut at = vec![0; c.len()];
    for (k, &i) in order.iter().enumerate() {
        at[i] = k;
    }
    let mut out = PhaseChain::default();
    for &i in &order {
        let k = out.push_phase();
        let e = end(i);
        if until_success {
            out.exit_success[k] = e;
        } else {
            out.exit_failure[k] = e;
        }
    }
    out.initial = c.initial.iter().map(|&(i, p)| (at[i], p)).collect();
    let a = again(s);
    for &(j, p) in &c.initial {
        if j != s && p > 0.0 {
            out.transitions[0].push((at[j], a * p));
        }
    }
    Some(out)
}

/// The chain of a node that never returns: one phase without transitions
/// or exits (a *trap*; its total rate is 0), entered with probability 1.
pub fn trap() -> PhaseChain {
    let mut c = PhaseChain::default();
    let i = c.push_phase();
    c.initial = vec![(i, 1.0)];
    c
}

/// A Parallel with the book's thresholds gets its product chain only up to
/// `max_states / BOOK_PARALLEL_SHARE` (bound `Π (phases + 2)`); beyond, it is
/// analysed by counting its children.
pub const BOOK_PARALLEL_SHARE: usize = 16;

/// Sequence (`sequence = true`) or Fallback composition of children's chains.
pub fn concatenate(chains: Vec<PhaseChain>, sequence: bool) -> PhaseChain {
    let offsets: Vec<usize> = chains
        .iter()
        .scan(0, |acc, c| {
            let o = *acc;
            *acc += c.len();
            Some(o)
        })
        .collect();
    let mut out = PhaseChain::default();
    let total = offsets
        .last()
        .map_or(0, |&o| o + chains.last().map_or(0, |c| c.len()));
    out.transitions = vec![Vec::new(); total];
    out.exit_success = vec![0.0; total];
    out.exit_failure = vec![0.0; total];
    // where a run goes after the last child "continues"
    let mut next = Entry {
        states: Vec::new(),
        success: if sequence { 1.0 } else { 0.0 },
        failure: if sequence { 0.0 } else { 1.0 },
    };
    for (k, c) in chains.iter().enumerate().rev() {
        let off = offsets[k];
        for i in 0..c.len() {
            let gi = off + i;
            out.transitions[gi].extend(c.transitions[i].iter().map(|&(j, r)| (off + j, r)));
            let (cont, stop) = if sequence {
                (c.exit_success[i], c.exit_failure[i])
            } else {
                (c.exit_failure[i], c.exit_success[i])
            };
            if stop > 0.0 {
                if sequence {
                    out.exit_failure[gi] += stop;
                } else {
                    out.exit_success[gi] += stop;
                }
            }
            if cont > 0.0 {
                out.transitions[gi].extend(next.states.iter().map(|&(j, w)| (j, cont * w)));
                out.exit_success[gi] += cont * next.success;
                out.exit_failure[gi] += cont * next.failure;
            }
        }
        // entry of child k: its initial phases, plus its instantaneous
        // outcomes routed on
        let (cont0, stop0) = if sequence {
            (c.initial_success, c.initial_failure)
        } else {
            (c.initial_failure, c.initial_success)
        };
        let mut entry = Entry {
            states: c.initial.iter().map(|&(j, p)| (off + j, p)).collect(),
            success: 0.0,
            failure: 0.0,
        };
        if sequence {
            entry.failure += stop0;
        } else {
            entry.success += stop0;
        }
        if cont0 > 0.0 {
            entry
                .states
                .extend(next.states.iter().map(|&(j, w)| (j, cont0 * w)));
            entry.success += cont0 * next.success;
            entry.failure += cont0 * next.failure;
        }
        next = entry;
    }
    out.initial = next.states;
    out.initial_success = next.success;
    out.initial_failure = next.failure;
    out
}

/// The chain of a Parallel (named `name`) with thresholds `m` and `f` over
/// children with `chains`, refused when it would exceed `max_states`.
pub(crate) fn parallel_chain(
    name: &str,
    chains: &[PhaseChain],
    m: usize,
    f: usize,
    max_states: usize,
) -> Result<PhaseChain, AnalysisError> {
    let policy = Policy::Parallel {
        success_threshold: m,
        failure_threshold: f,
    };
    product(chains, policy, max_states).ok_or_else(|| AnalysisError::StateBudget {
        node: name.to_string(),
        states: chains.iter().map(|c| (c.len() + 2) as f64).product(),
        budget: max_states,
    })
}

const SUCCEEDED: u32 = u32::MAX - 1;
const FAILED: u32 = u32::MAX;

/// Joint chain of a Parallel node's children. Returns `None` if more than
/// `max_states` phases would be needed.
fn product(chains: &[PhaseChain], policy: Policy, max_states: usize) -> Option<PhaseChain> {
    let n = chains.len();
    // refuse before allocating when even a generous share of the upper
    // bound Π(len_h + 2) cannot fit
    let bound: f64 = chains.iter().map(|c| (c.len() + 2) as f64).product();
    if bound > 16.0 * max_states as f64 {
        return None;
    }
    let status_of = |key: &[u32]| {
        let s = key.iter().filter(|&&x| x == SUCCEEDED).count();
        let f = key.iter().filter(|&&x| x == FAILED).count();
        policy.status(n, s, f)
    };
    // topological rank of a local state: phases 1..=len, returned len + 1
    let rank = |key: &[u32]| -> u64 {
        key.iter()
            .zip(chains)
            .map(|(&x, c)| {
                if x >= SUCCEEDED {
                    c.len() as u64 + 1
                } else {
                    x as u64 + 1
                }
            })
            .sum()
    };

    let mut keys: Vec<Box<[u32]>> = Vec::new();
    let mut index: HashMap<Box<[u32]>, usize> = HashMap::new();
    let mut out = PhaseChain::default();
    // intern a tuple; None if the budget is exceeded
    let mut intern =
        |key: Box<[u32]>, keys: &mut Vec<Box<[u32]>>, out: &mut PhaseChain| -> Option<usize> {
            if let Some(&i) = index.get(&key) {
                return Some(i);
            }
            if keys.len() >= max_states {
                return None;
            }
            let i = out.push_phase();
            keys.push(key.clone());
            index.insert(key, i);
            Some(i)
        };

    // initial distribution: product of the children's entries. A tick
    // visits the children in order and the node returns at the first
    // threshold met (BehaviorTree.CPP): a prefix whose instantaneous outcomes
    // already meet a threshold is absorbed there, whatever later children do.
    let mut partial: Vec<(Vec<u32>, f64)> = vec![(Vec::with_capacity(n), 1.0)];
    for c in chains {
        let mut next = Vec::new();
        for (key, p) in &partial {
            let mut options: Vec<(u32, f64)> =
                c.initial.iter().map(|&(j, q)| (j as u32, q)).collect();
            options.push((SUCCEEDED, c.initial_success));
            options.push((FAILED, c.initial_failure));
            for (x, q) in options {
                if q > 0.0 {
                    let mut k = key.clone();
                    k.push(x);
                    match status_of(&k) {
                        Status::Success => out.initial_success += p * q,
                        Status::Failure => out.initial_failure += p * q,
                        Status::Running => next.push((k, p * q)),
                    }
                }
            }
        }
        partial = next;
        if partial.len() > max_states.saturating_mul(4) {
            return None;
        }
    }
    for (key, p) in partial {
        let i = intern(key.into_boxed_slice(), &mut keys, &mut out)?;
        out.initial.push((i, p));
    }

    // explore
    let mut next = 0;
    while next < keys.len() {
        let key = keys[next].clone();
        for (h, c) in chains.iter().enumerate() {
            let x = key[h];
            if x >= SUCCEEDED {
                continue;
            }
            let p = x as usize;
            let mut moves: Vec<(u32, f64)> = c.transitions[p]
                .iter()
                .map(|&(j, r)| (j as u32, r))
                .collect();
            moves.push((SUCCEEDED, c.exit_success[p]));
            moves.push((FAILED, c.exit_failure[p]));
            for (y, r) in moves {
                if r <= 0.0 {
                    continue;
                }
                let mut k = key.clone();
                k[h] = y;
                match status_of(&k) {
                    Status::Success => out.exit_success[next] += r,
                    Status::Failure => out.exit_failure[next] += r,
                    Status::Running => {
                        let j = intern(k, &mut keys, &mut out)?;
                        out.transitions[next].push((j, r));
                    }
                }
            }
        }
        next += 1;
    }

    // renumber in topological order (by rank)
    let mut order: Vec<usize> = (0..keys.len()).collect();
    order.sort_by_key(|&i| rank(&keys[i]));
    let mut new_index = vec![0usize; keys.len()];
    for (new, &old) in order.iter().enumerate() {
        new_index[old] = new;
    }
    let mut sorted = PhaseChain {
        initial: out
            .initial
            .iter()
            .map(|&(i, p)| (new_index[i], p))
            .collect(),
        initial_success: out.initial_success,
        initial_failure: out.initial_failure,
        ..PhaseChain::default()
    };
    for &old in &order {
        sorted.transitions.push(
            out.transitions[old]
                .iter()
                .map(|&(j, r)| (new_index[j], r))
                .collect(),
        );
        sorted.exit_success.push(out.exit_success[old]);
        sorted.exit_failure.push(out.exit_failure[old]);
    }
    Some(sorted)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `until_failure` over a child that succeeds at once with 0.8 and
    /// otherwise fails after Exp(λ): the instant successes repeat it in no
    /// time, so the loop fails after Exp(λ) with probability
    /// Σ 0.8ᵏ·0.2 = 1 — one phase, entered with 1, failing at rate λ.
    #[test]
    fn instant_repetitions_are_folded_into_the_entry() {
        let lambda = 1.7;
        let mut c = PhaseChain {
            initial_success: 0.8,
            ..PhaseChain::default()
        };
        let i = c.push_phase();
        c.exit_failure[i] = lambda;
        c.initial.push((i, 0.2));
        let l = unrolled_loop("loop", c, false, 1000).expect("a chain");
        assert_eq!(l.len(), 1);
        assert_eq!(l.initial.len(), 1);
        assert!((l.initial[0].1 - 1.0).abs() < 1e-15, "{:?}", l.initial);
        assert_eq!(l.initial_success + l.initial_failure, 0.0);
        assert!((l.exit_failure[0] - lambda).abs() < 1e-15);
        assert_eq!(l.exit_success[0], 0.0);
    }
}
