//! Flows ([`Flow`]): a finite acyclic graph of states, each running one
//! child afresh, with the child's Success and Failure edges leading to a
//! later state or to the node's outcome.
//!
//! Because the states are in topological order and every visit is a fresh,
//! independent run of the state's child, each representation composes a
//! flow state by state, in O(states) compositions:
//!
//! * figures: the DTMC over the states, with the state's child's `ps`/`pf`
//!   as probabilities and its MTTS/MTTF as durations ([`figures_chain`]) —
//!   exact, as mean times add along paths;
//! * phase chains: one copy of the state's child chain per state, its exits
//!   glued to the entry of the state it leads to ([`glue`]); instantaneous
//!   outcomes pass straight on;
//! * the book's CTMC: each state summarised as one exponential phase of
//!   rate `1/SJ` (states whose child takes no time are vanishing) ([`book_chain`]);
//! * atoms, shifted phase-type mixtures and interpolated laws: the law of
//!   the time at which each state is entered, carried forward
//!   ([`super::atoms::flow_atoms`], [`super::shifted`], [`super::law`]).
//!
//! A subtree of Sequences, Fallbacks, inverters and force decorators is
//! itself a flow over its leaves ([`leaf_flow`]): each leaf a state, its
//! Success and Failure edges leading to the leaf the tick semantics run
//! next or to the subtree's outcome.

use super::Figures;
use crate::ir::{Flow, FlowGraph, Graph, Op};
use crate::solve::chain::{AbsorbingChain, Edge, PhaseChain, Target};
use crate::tree::{FlowNext, FlowState, NodeId};

/// The DTMC over a flow's states whose transitions are the children's
/// outcomes (probabilities `ps`, `pf`, durations MTTS, MTTF); `children`
/// holds the figures of `flow.children` in order.
pub fn figures_chain(flow: &Flow, children: &[Figures]) -> AbsorbingChain {
    let target = |n: FlowNext| match n {
        FlowNext::State(j) => Target::State(j),
        FlowNext::Success => Target::Success,
        FlowNext::Failure => Target::Failure,
    };
    let states = flow.states();
    let mut edges = Vec::with_capacity(2 * states.len());
    for (i, s) in states.iter().enumerate() {
        let f = &children[s.child];
        for (p, t, next) in [(f.ps, f.mtts, s.on_success), (f.pf, f.mttf, s.on_failure)] {
            if p > 0.0 {
                edges.push(Edge {
                    from: i,
                    to: target(next),
                    prob: p,
                    duration: t.unwrap_or(0.0),
                });
            }
        }
    }
    AbsorbingChain {
        n: states.len(),
        initial: vec![(0, 1.0)],
        initial_success: 0.0,
        initial_failure: 0.0,
        edges,
    }
}

/// Number of phases of the glued chain: one copy of the child's chain per state.
pub fn glued_len(flow: &Flow, chains: &[PhaseChain]) -> usize {
    (0..flow.state_count())
        .map(|i| chains[flow.state(i).child].len())
        .sum()
}

/// "Where a run goes next": phases, or an instantaneous outcome.
#[derive(Debug, Clone, Default)]
struct Entry {
    phases: Vec<(usize, f64)>,
    success: f64,
    failure: f64,
}

impl Entry {
    fn add_scaled(&mut self, other: &Entry, w: f64) {
        if w <= 0.0 {
            return;
        }
        self.phases
            .extend(other.phases.iter().map(|&(j, p)| (j, p * w)));
        self.success += other.success * w;
        self.failure += other.failure * w;
    }

    fn outcome(success: bool) -> Entry {
        Entry {
            phases: Vec::new(),
            success: f64::from(u8::from(success)),
            failure: f64::from(u8::from(!success)),
        }
    }
}

/// Entries of every state, computed from the last state back, given each
/// state's own entry builder.
fn next_entry<'a>(entries: &'a [Entry], n: FlowNext, ends: &'a [Entry; 2]) -> &'a Entry {
    match n {
        FlowNext::State(j) => &entries[j],
        FlowNext::Success => &ends[0],
        FlowNext::Failure => &ends[1],
    }
}

/// The exact phase chain of a flow from its children's chains (one per
/// child of `flow.children`): state `i` holds a copy of its child's chain,
/// placed after the copies of the states before it (so every transition
/// goes forward); a Success (Failure) exit of that copy enters the state
/// `on_success` (`on_failure`) leads to, or is the node's outcome.
/// The caller checks [`glued_len`] against its budget.
pub fn glue(flow: &Flow, chains: &[PhaseChain]) -> PhaseChain {
    let states = flow.states();
    let offsets: Vec<usize> = states
        .iter()
        .scan(0, |acc, s| {
            let o = *acc;
            *acc += chains[s.child].len();
            Some(o)
        })
        .collect();
    let total = glued_len(flow, chains);
    let mut out = PhaseChain {
        transitions: vec![Vec::new(); total],
        exit_success: vec![0.0; total],
        exit_failure: vec![0.0; total],
        ..PhaseChain::default()
    };
    let ends = [Entry::outcome(true), Entry::outcome(false)];
    let mut entries = vec![Entry::default(); states.len()];
    for (i, s) in states.iter().enumerate().rev() {
        let c = &chains[s.child];
        let off = offsets[i];
        let on_s = next_entry(&entries, s.on_success, &ends).clone();
        let on_f = next_entry(&entries, s.on_failure, &ends).clone();
        for k in 0..c.len() {
            let g = off + k;
            out.transitions[g].extend(c.transitions[k].iter().map(|&(j, r)| (off + j, r)));
            for (rate, to) in [(c.exit_success[k], &on_s), (c.exit_failure[k], &on_f)] {
                if rate > 0.0 {
                    out.transitions[g].extend(to.phases.iter().map(|&(j, w)| (j, rate * w)));
                    out.exit_success[g] += rate * to.success;
                    out.exit_failure[g] += rate * to.failure;
                }
            }
        }
        let mut entry = Entry {
            phases: c.initial.iter().map(|&(j, p)| (off + j, p)).collect(),
            ..Entry::default()
        };
        entry.add_scaled(&on_s, c.initial_success);
        entry.add_scaled(&on_f, c.initial_failure);
        entries[i] = entry;
    }
    let start = std::mem::take(&mut entries[0]);
    out.initial = start.phases;
    out.initial_success = start.success;
    out.initial_failure = start.failure;
    out
}

/// The book's CTMC of a flow (Section 9.3.3 applied state by state): a state
/// whose child has mean duration `SJ > 0` is one exponential phase of rate
/// `1/SJ`, left with Success or Failure in proportion `ps : pf`; a state
/// whose child takes no time is vanishing and routes its probability on.
pub fn book_chain(flow: &Flow, children: &[Figures]) -> PhaseChain {
    let states = flow.states();
    let sojourn = |i: usize| children[states[i].child].mean_time();
    let mut chain = PhaseChain::default();
    let mut phase_of = vec![usize::MAX; states.len()];
    for (i, p) in phase_of.iter_mut().enumerate() {
        if sojourn(i) > 0.0 {
            *p = chain.push_phase();
        }
    }
    let ends = [Entry::outcome(true), Entry::outcome(false)];
    let mut entries = vec![Entry::default(); states.len()];
    for (i, s) in states.iter().enumerate().rev() {
        let f = &children[s.child];
        let on_s = next_entry(&entries, s.on_success, &ends).clone();
        let on_f = next_entry(&entries, s.on_failure, &ends).clone();
        entries[i] = if phase_of[i] == usize::MAX {
            let mut e = Entry::default();
            e.add_scaled(&on_s, f.ps);
            e.add_scaled(&on_f, f.pf);
            e
        } else {
            let p = phase_of[i];
            let sj = sojourn(i);
            for (prob, to) in [(f.ps, &on_s), (f.pf, &on_f)] {
                if prob > 0.0 {
                    let rate = prob / sj;
                    chain.exit_success[p] += rate * to.success;
                    chain.exit_failure[p] += rate * to.failure;
                    chain.transitions[p].extend(to.phases.iter().map(|&(j, w)| (j, rate * w)));
                }
            }
            Entry {
                phases: vec![(p, 1.0)],
                ..Entry::default()
            }
        };
    }
    let start = std::mem::take(&mut entries[0]);
    chain.initial = start.phases;
    chain.initial_success = start.success;
    chain.initial_failure = start.failure;
    chain
}

/// The subtree of `id` as a flow over its leaves, when it holds only
/// chains (Sequences, Fallbacks) and maps (inverters, force decorators)
/// over conditions and actions for which `leaf` holds (`None` otherwise). The states are the
/// leaves in tree order (a topological order: the tick semantics only ever
/// go on to a later leaf); a Sequence sends each child's Success to the
/// next child's first leaf, a Fallback each child's Failure; an inverter
/// exchanges its subtree's exits, a force decorator merges them.
pub(crate) fn leaf_flow(tree: &Graph, id: NodeId, leaf: impl Fn(NodeId) -> bool) -> Option<Flow> {
    let mut children = Vec::new();
    let mut states = Vec::new();
    lay_out(tree, id, &leaf, &mut children, &mut states)?;
    let checked = crate::tree::Flow::new(children, states).ok()?;
    Some(Flow {
        children: checked.children,
        graph: FlowGraph::States(checked.states),
    })
}

/// Sends every exit of `states` that goes to `from` to `to`.
fn redirect(states: &mut [FlowState], from: FlowNext, to: FlowNext) {
    for s in states {
        for next in [&mut s.on_success, &mut s.on_failure] {
            if *next == from {
                *next = to;
            }
        }
    }
}

/// Appends the states of `id`'s subtree, its own exits left as
/// `Success`/`Failure` for its parent to redirect.
fn lay_out(
    tree: &Graph,
    id: NodeId,
    leaf: &impl Fn(NodeId) -> bool,
    children: &mut Vec<NodeId>,
    states: &mut Vec<FlowState>,
) -> Option<()> {
    let start = states.len();
    match &tree.node(id).kind {
        Op::Leaf(_) if leaf(id) => {
            states.push(FlowState {
                child: children.len(),
                on_success: FlowNext::Success,
                on_failure: FlowNext::Failure,
            });
            children.push(id);
        }
        Op::Flow(Flow {
            children: kids,
            graph: FlowGraph::Chain { stop },
        }) => {
            // a child's outcome other than `stop` goes on to the next child
            let go = stop.other().exit();
            let (last, earlier) = kids.split_last()?;
            for &c in earlier {
                let from = states.len();
                lay_out(tree, c, leaf, children, states)?;
                // the next child starts where this one's states end
                let next = FlowNext::State(states.len());
                redirect(&mut states[from..], go, next);
            }
            lay_out(tree, *last, leaf, children, states)?;
        }
        Op::Map {
            child,
            on_success,
            on_failure,
        } => {
            lay_out(tree, *child, leaf, children, states)?;
            // placeholders that no exit uses: the state count is past them all
            let (hold_s, hold_f) = (FlowNext::State(usize::MAX), FlowNext::State(usize::MAX - 1));
            let own = &mut states[start..];
            redirect(own, FlowNext::Success, hold_s);
            redirect(own, FlowNext::Failure, hold_f);
            redirect(own, hold_s, on_success.exit());
            redirect(own, hold_f, on_failure.exit());
        }
        _ => return None,
    }
    Some(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::solve::solve_absorbing;
    use crate::tree::FlowState;

    fn fig(ps: f64, mtts: f64, mttf: f64) -> Figures {
        Figures {
            ps,
            pf: 1.0 - ps,
            mtts: Some(mtts),
            mttf: Some(mttf),
        }
    }

    #[test]
    fn if_then_else_by_hand() {
        // C (0.3; 1, 2), T (0.6; 3, 4), E (0.8; 5, 6)
        let f = crate::tree::Flow::if_then_else(0, 1, Some(2));
        let flow = Flow {
            children: f.children,
            graph: FlowGraph::States(f.states),
        };
        let figs = [fig(0.3, 1.0, 2.0), fig(0.6, 3.0, 4.0), fig(0.8, 5.0, 6.0)];
        let a = solve_absorbing(&figures_chain(&flow, &figs)).unwrap();
        let ps = 0.3 * 0.6 + 0.7 * 0.8;
        assert!((a.success - ps).abs() < 1e-15);
        let ts = 0.3 * 0.6 * (1.0 + 3.0) + 0.7 * 0.8 * (2.0 + 5.0);
        assert!((a.time_success - ts).abs() < 1e-14);
        let tf = 0.3 * 0.4 * (1.0 + 4.0) + 0.7 * 0.2 * (2.0 + 6.0);
        assert!((a.time_failure - tf).abs() < 1e-14);
    }

    #[test]
    fn flow_new_refuses_backward_edges_and_unused_children() {
        let st = |child, s, f| FlowState {
            child,
            on_success: s,
            on_failure: f,
        };
        assert!(crate::tree::Flow::new(
            vec![7, 8],
            vec![st(0, FlowNext::State(0), FlowNext::Failure)]
        )
        .is_err());
        assert!(crate::tree::Flow::new(
            vec![7, 8],
            vec![st(0, FlowNext::Success, FlowNext::Failure)]
        )
        .is_err());
        assert!(
            crate::tree::Flow::new(vec![7], vec![st(1, FlowNext::Success, FlowNext::Failure)])
                .is_err()
        );
        assert!(crate::tree::Flow::new(vec![], vec![]).is_err());
    }
}
