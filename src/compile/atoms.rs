//! Deterministic timing (Def. 9.8, Prop. 9.2): outcome distributions with
//! finitely many atoms.
//!
//! When every action of a subtree has fixed times `tau_s`, `tau_f`, the
//! subtree returns at one of finitely many instants — sums of τ's along the
//! paths through its MRG — and `π(t)` is piecewise constant between them
//! (the zero-order hold of Prop. 9.2). Instead of the book's common time
//! step Δτ we keep the exact instants: each node's outcome distribution is a
//! list of atoms `(time, outcome, probability)`.
//!
//! * Sequence/Fallback: the start-time distribution of each child is the
//!   "continue" atoms of the previous ones, shifted (a discrete convolution).
//! * Parallel: every combination of the children's atoms is resolved by
//!   replaying the children's returns in time order (ties in child order, as
//!   a tick visits them) until a threshold is met.
//!
//! Instants that agree to 1e-12 (relative) are merged: they are the same sum
//! of τ's added in a different order.

use super::mrg::{Outcome, Policy, Status};
use super::{AnalysisError, Figures};
use crate::ir::{Flow, FlowGraph, Graph, Leaf, Op};
use crate::tree::same_instant;
use crate::tree::{Duration, FlowNext, NodeId};

/// One possible return of a node: at `time`, with `outcome`, with probability `prob`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Atom {
    /// When the node returns (s).
    pub time: f64,
    /// What it returns.
    pub outcome: Outcome,
    /// Probability of this return.
    pub prob: f64,
}

/// Sorts atoms by (outcome, time) and merges equal instants.
fn normalise(mut atoms: Vec<Atom>) -> Vec<Atom> {
    atoms.retain(|a| a.prob > 0.0);
    atoms.sort_by(|a, b| {
        (a.outcome == Outcome::Failure)
            .cmp(&(b.outcome == Outcome::Failure))
            .then(a.time.total_cmp(&b.time))
    });
    let mut out: Vec<Atom> = Vec::with_capacity(atoms.len());
    for a in atoms {
        match out.last_mut() {
            Some(l) if l.outcome == a.outcome && same_instant(l.time, a.time) => l.prob += a.prob,
            _ => out.push(a),
        }
    }
    out
}

/// Outcome atoms of the subtree at `id`, or `None` if some action in it is
/// not deterministic. Fails if more than `max_atoms` combinations would be
/// needed.
pub fn atoms(
    tree: &Graph,
    id: NodeId,
    max_atoms: usize,
) -> Result<Option<Vec<Atom>>, AnalysisError> {
    let node = tree.node(id);
    let budget = |n: f64| AnalysisError::StateBudget {
        node: node.name.clone(),
        states: n,
        budget: max_atoms,
    };
    match &node.kind {
        Op::Leaf(Leaf::Action(a)) => {
            let mut out = Vec::new();
            for (p, d, o) in [
                (a.ps, a.success, Outcome::Success),
                (a.pf, a.failure, Outcome::Failure),
            ] {
                if p <= 0.0 {
                    continue;
                }
                match d {
                    Some(Duration::Fixed { time }) => out.push(Atom {
                        time,
                        outcome: o,
                        prob: p,
                    }),
                    _ => return Ok(None),
                }
            }
            Ok(Some(normalise(out)))
        }
        Op::Leaf(Leaf::Condition { ps }) => Ok(Some(normalise(vec![
            Atom {
                time: 0.0,
                outcome: Outcome::Success,
                prob: *ps,
            },
            Atom {
                time: 0.0,
                outcome: Outcome::Failure,
                prob: 1.0 - ps,
            },
        ]))),
        Op::Flow(flow) => {
            let mut lists = Vec::with_capacity(flow.children.len());
            for &c in &flow.children {
                match atoms(tree, c, max_atoms)? {
                    Some(a) => lists.push(a),
                    None => return Ok(None),
                }
            }
            match flow.graph {
                // a child's outcome other than `stop` goes on
                FlowGraph::Chain { stop } => chain(lists.iter(), stop.other(), max_atoms),
                FlowGraph::Repeat { times, stop } => chain(
                    std::iter::repeat_n(&lists[0], times),
                    stop.other(),
                    max_atoms,
                ),
                FlowGraph::States(_) => flow_atoms(flow, &lists, max_atoms),
            }
            .map_err(budget)
            .map(Some)
        }
        // infinitely many return instants: a shifted law's truncated
        // series ([`super::shifted`]) instead
        Op::Loop { .. } => Ok(None),
        Op::Map {
            child,
            on_success,
            on_failure,
        } => {
            let Some(c) = atoms(tree, *child, max_atoms)? else {
                return Ok(None);
            };
            Ok(Some(normalise(
                c.iter()
                    .map(|a| Atom {
                        outcome: match a.outcome {
                            Outcome::Success => *on_success,
                            Outcome::Failure => *on_failure,
                        },
                        ..*a
                    })
                    .collect(),
            )))
        }
        Op::KOfN { children, .. } => {
            let mut per_child = Vec::with_capacity(children.len());
            for &c in children {
                match atoms(tree, c, max_atoms)? {
                    Some(a) => per_child.push(a),
                    None => return Ok(None),
                }
            }
            let combos: f64 = per_child.iter().map(|a| a.len() as f64).product();
            if combos > max_atoms as f64 {
                return Err(budget(combos));
            }
            let policy = Policy::of(&node.kind).expect("a Parallel has a policy");
            let n = children.len();
            let mut out = Vec::new();
            let mut pick = vec![0usize; n];
            let mut events: Vec<(f64, usize, Outcome)> = Vec::with_capacity(n);
            loop {
                let prob: f64 = pick
                    .iter()
                    .zip(&per_child)
                    .map(|(&i, a)| a[i].prob)
                    .product();
                events.clear();
                events.extend(
                    pick.iter()
                        .zip(&per_child)
                        .enumerate()
                        .map(|(h, (&i, a))| (a[i].time, h, a[i].outcome)),
                );
                events.sort_by(|a, b| a.0.total_cmp(&b.0));
                same_instants_in_child_order(&mut events);
                let (mut s, mut f) = (0, 0);
                for &(t, _, o) in &events {
                    match o {
                        Outcome::Success => s += 1,
                        Outcome::Failure => f += 1,
                    }
                    match policy.status(n, s, f) {
                        Status::Running => continue,
                        Status::Success => out.push(Atom {
                            time: t,
                            outcome: Outcome::Success,
                            prob,
                        }),
                        Status::Failure => out.push(Atom {
                            time: t,
                            outcome: Outcome::Failure,
                            prob,
                        }),
                    }
                    break;
                }
                // next combination (odometer)
                let mut h = 0;
                loop {
                    if h == n {
                        return Ok(Some(normalise(out)));
                    }
                    pick[h] += 1;
                    if pick[h] < per_child[h].len() {
                        break;
                    }
                    pick[h] = 0;
                    h += 1;
                }
            }
        }
    }
}

/// Within each run of events at the same instant (within
/// [`SAME_INSTANT`](crate::tree::SAME_INSTANT); `events` sorted by time), takes the run's first time
/// for all of them and puts them in child order: a tick visits the children
/// in order, so that is the order in which simultaneous returns count.
fn same_instants_in_child_order(events: &mut [(f64, usize, Outcome)]) {
    let mut start = 0;
    while start < events.len() {
        let t = events[start].0;
        let end = start
            + events[start..]
                .iter()
                .position(|e| !same_instant(e.0, t))
                .unwrap_or(events.len() - start);
        for e in &mut events[start..end] {
            e.0 = t;
        }
        events[start..end].sort_by_key(|e| e.1);
        start = end;
    }
}

/// Runs children (given by their atoms) one after the other while they
/// return `cont` (Success for a Sequence, Failure for a Fallback). Fails with
/// the number of atoms if it would exceed `max_atoms`.
fn chain<'a>(
    children: impl Iterator<Item = &'a Vec<Atom>>,
    cont: Outcome,
    max_atoms: usize,
) -> Result<Vec<Atom>, f64> {
    let mut running = vec![(0.0f64, 1.0f64)];
    let mut out = Vec::new();
    for child in children {
        let mut next = Vec::new();
        for &(t0, p0) in &running {
            for a in child {
                let atom = Atom {
                    time: t0 + a.time,
                    outcome: a.outcome,
                    prob: p0 * a.prob,
                };
                if a.outcome == cont {
                    next.push(atom);
                } else {
                    out.push(atom);
                }
            }
        }
        if next.len() + out.len() > max_atoms {
            return Err((next.len() + out.len()) as f64);
        }
        running = normalise(next).iter().map(|a| (a.time, a.prob)).collect();
        out = normalise(out);
    }
    out.extend(running.into_iter().map(|(time, prob)| Atom {
        time,
        outcome: cont,
        prob,
    }));
    Ok(normalise(out))
}

/// A flow's atoms from its children's (`children[k]` for `flow.children[k]`):
/// the instants at which each state is entered are carried forward, state
/// by state, shifted by the state's child's atoms. Fails with the number of
/// atoms if it would exceed `max_atoms`.
pub(crate) fn flow_atoms(
    flow: &Flow,
    children: &[Vec<Atom>],
    max_atoms: usize,
) -> Result<Vec<Atom>, f64> {
    // entry instants of each state, as atoms whose outcome is irrelevant
    let states = flow.states();
    let mut entered: Vec<Vec<Atom>> = vec![Vec::new(); states.len()];
    entered[0].push(Atom {
        time: 0.0,
        outcome: Outcome::Success,
        prob: 1.0,
    });
    let mut out = Vec::new();
    for (i, s) in states.iter().enumerate() {
        let here = normalise(std::mem::take(&mut entered[i]));
        for e in &here {
            for a in &children[s.child] {
                let next = match a.outcome {
                    Outcome::Success => s.on_success,
                    Outcome::Failure => s.on_failure,
                };
                let (list, outcome) = match next {
                    FlowNext::State(j) => (&mut entered[j], Outcome::Success),
                    FlowNext::Success => (&mut out, Outcome::Success),
                    FlowNext::Failure => (&mut out, Outcome::Failure),
                };
                list.push(Atom {
                    time: e.time + a.time,
                    outcome,
                    prob: e.prob * a.prob,
                });
            }
        }
        let held = out.len() + entered.iter().map(Vec::len).sum::<usize>();
        if held > max_atoms {
            return Err(held as f64);
        }
        out = normalise(out);
    }
    Ok(normalise(out))
}

/// ps, pf, MTTS and MTTF from a node's atoms.
pub fn figures(atoms: &[Atom]) -> Figures {
    let (mut ps, mut pf, mut ts, mut tf) = (0.0, 0.0, 0.0, 0.0);
    for a in atoms {
        match a.outcome {
            Outcome::Success => {
                ps += a.prob;
                ts += a.prob * a.time;
            }
            Outcome::Failure => {
                pf += a.prob;
                tf += a.prob * a.time;
            }
        }
    }
    Figures::from_moments([ps, pf, ts, tf])
}

/// P(returned Success by t) and P(returned Failure by t): right-continuous
/// step functions (an atom at `t` counts at `t`).
pub fn cumulative(atoms: &[Atom], t: f64) -> (f64, f64) {
    let (mut s, mut f) = (0.0, 0.0);
    for a in atoms {
        if a.time <= t || same_instant(a.time, t) {
            match a.outcome {
                Outcome::Success => s += a.prob,
                Outcome::Failure => f += a.prob,
            }
        }
    }
    (s, f)
}
