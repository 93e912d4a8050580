//! Marking reachability graphs (MRG) of control nodes, eqs. (9.29)–(9.35).
//!
//! A marking `m ∈ {-1, 0, 1}^N` records which children of a node with N
//! children have returned Failure (−1) or Success (1). An event lets one
//! feasible child return; the node returns when its policy says so. Markings
//! are numbered so that every event leads to a higher number (the graph is
//! acyclic, Remark 9.7): that is the topological order the solvers rely on.
//!
//! Sequence and Fallback MRGs are a path of N running markings with one
//! absorbing marking hanging off each; they are built in O(N) without storing
//! marking vectors. Parallel MRGs are enumerated breadth first and can grow
//! like 3^N: [`parallel_marking_count`] bounds them before anything is built.

pub use crate::ir::Outcome;
use crate::ir::{FlowGraph, Op};

/// The return status of a node at a marking.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Status {
    /// The node is still running (transient marking).
    Running,
    /// The node has returned Success (absorbing marking).
    Success,
    /// The node has returned Failure (absorbing marking).
    Failure,
}

/// The execution policy of a control node.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Policy {
    /// Sequence (→).
    Sequence,
    /// Fallback (?).
    Fallback,
    /// Parallel (⇒) with success threshold M and failure threshold F.
    Parallel {
        /// M: Success at ≥ M successes.
        success_threshold: usize,
        /// F: Failure at ≥ F failures (or once M successes are impossible,
        /// i.e. more than N − M failures; the book's F is N − M + 1).
        failure_threshold: usize,
    },
}

impl Policy {
    /// The policy of a chain or a k-of-n node, `None` for other operators.
    pub fn of(op: &Op) -> Option<Policy> {
        match op {
            Op::Flow(f) => match f.graph {
                FlowGraph::Chain { stop } => Some(Policy::stopping_at(stop)),
                _ => None,
            },
            Op::KOfN {
                success, failure, ..
            } => Some(Policy::Parallel {
                success_threshold: *success,
                failure_threshold: *failure,
            }),
            _ => None,
        }
    }

    /// The chain that ends at the first child returning `stop`: a Sequence
    /// stops at a Failure, a Fallback at a Success.
    pub fn stopping_at(stop: Outcome) -> Policy {
        match stop {
            Outcome::Failure => Policy::Sequence,
            Outcome::Success => Policy::Fallback,
        }
    }

    /// The node's status given how many children succeeded and failed, for a
    /// node with `n` children (valid for every marking the policy reaches).
    pub fn status(&self, n: usize, successes: usize, failures: usize) -> Status {
        match *self {
            Policy::Sequence if failures > 0 => Status::Failure,
            Policy::Sequence if successes == n => Status::Success,
            Policy::Fallback if successes > 0 => Status::Success,
            Policy::Fallback if failures == n => Status::Failure,
            Policy::Parallel {
                success_threshold, ..
            } if successes >= success_threshold => Status::Success,
            Policy::Parallel {
                success_threshold,
                failure_threshold,
            } if failures >= failure_threshold || failures > n - success_threshold => {
                Status::Failure
            }
            _ => Status::Running,
        }
    }
}

/// An event of the MRG: `child` returns `outcome` at marking `from`,
/// which moves the node to marking `to`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Event {
    /// Marking before the event.
    pub from: usize,
    /// The child (0-based position) that returns.
    pub child: usize,
    /// What it returns.
    pub outcome: Outcome,
    /// Marking after the event.
    pub to: usize,
}

/// The marking reachability graph of a control node.
#[derive(Debug, Clone)]
pub(crate) struct Mrg {
    /// The node's policy.
    pub policy: Policy,
    /// Number of children N.
    pub n_children: usize,
    /// Status of each marking, indexed by marking number. Marking 0 is the
    /// initial marking `0^N`.
    pub status: Vec<Status>,
    /// All events, grouped by `from` in increasing order.
    pub events: Vec<Event>,
    /// Marking vectors, stored only for Parallel nodes.
    markings: Option<Vec<Box<[i8]>>>,
}

impl Mrg {
    /// Builds the MRG of a node with `n` children (n ≥ 1).
    pub fn build(policy: Policy, n: usize) -> Mrg {
        match policy {
            Policy::Sequence | Policy::Fallback => Self::build_chain(policy, n),
            Policy::Parallel { .. } => Self::build_parallel(policy, n),
        }
    }

    /// Sequence/Fallback: marking k (0 ≤ k < N) is running with the first k
    /// children returned "continue" (Success for a Sequence, Failure for a
    /// Fallback); marking N is the node's "all continued" outcome; marking
    /// N + 1 + k is the node's early outcome caused by child k.
    fn build_chain(policy: Policy, n: usize) -> Mrg {
        let (cont, stop, all_cont, early) = match policy {
            Policy::Sequence => (
                Outcome::Success,
                Outcome::Failure,
                Status::Success,
                Status::Failure,
            ),
            _ => (
                Outcome::Failure,
                Outcome::Success,
                Status::Failure,
                Status::Success,
            ),
        };
        let mut status = vec![Status::Running; n];
        status.push(all_cont);
        status.extend(std::iter::repeat_n(early, n));
        let mut events = Vec::with_capacity(2 * n);
        for k in 0..n {
            events.push(Event {
                from: k,
                child: k,
                outcome: cont,
                to: k + 1,
            });
            events.push(Event {
                from: k,
                child: k,
                outcome: stop,
                to: n + 1 + k,
            });
        }
        Mrg {
            policy,
            n_children: n,
            status,
            events,
            markings: None,
        }
    }

    fn build_parallel(policy: Policy, n: usize) -> Mrg {
        use std::collections::HashMap;
        let mut markings: Vec<Box<[i8]>> = vec![vec![0i8; n].into_boxed_slice()];
        let mut index: HashMap<Box<[i8]>, usize> = HashMap::new();
        index.insert(markings[0].clone(), 0);
        let mut status = vec![Status::Running];
        let mut events = Vec::new();
        // Breadth first: each event adds one non-zero entry, so discovery
        // order is a topological order.
        let mut next = 0;
        while next < markings.len() {
            if status[next] == Status::Running {
                for child in 0..n {
                    if markings[next][child] != 0 {
                        continue;
                    }
                    for (outcome, value) in [(Outcome::Success, 1i8), (Outcome::Failure, -1i8)] {
                        let mut m = markings[next].clone();
                        m[child] = value;
                        let to = match index.get(&m) {
                            Some(&i) => i,
                            None => {
                                let s = m.iter().filter(|&&x| x == 1).count();
                                let f = m.iter().filter(|&&x| x == -1).count();
                                status.push(policy.status(n, s, f));
                                markings.push(m.clone());
                                index.insert(m, markings.len() - 1);
                                markings.len() - 1
                            }
                        };
                        events.push(Event {
                            from: next,
                            child,
                            outcome,
                            to,
                        });
                    }
                }
            }
            next += 1;
        }
        Mrg {
            policy,
            n_children: n,
            status,
            events,
            markings: Some(markings),
        }
    }

    /// Number of markings.
    pub fn len(&self) -> usize {
        self.status.len()
    }

    /// Children feasible at marking `i` (eqs. 9.33–9.35; the tests check
    /// the graph against the book's).
    #[cfg(test)]
    fn feasible(&self, i: usize) -> impl Iterator<Item = usize> + '_ {
        let start = self.events.partition_point(|e| e.from < i);
        self.events[start..]
            .iter()
            .take_while(move |e| e.from == i)
            .filter(|e| e.outcome == Outcome::Success)
            .map(|e| e.child)
    }

    /// The marking vector of marking `i` (eq. 9.29).
    pub fn marking(&self, i: usize) -> Vec<i8> {
        if let Some(m) = &self.markings {
            return m[i].to_vec();
        }
        let n = self.n_children;
        let cont: i8 = if self.policy == Policy::Sequence {
            1
        } else {
            -1
        };
        let mut m = vec![0i8; n];
        if i <= n {
            m[..i].fill(cont);
        } else {
            let k = i - n - 1;
            m[..k].fill(cont);
            m[k] = -cont;
        }
        m
    }
}

/// Number of markings of a Parallel MRG with `n` children and thresholds
/// `m`, `f`, as a float (it can exceed any integer type): the running
/// markings have fewer than M successes and at most min(F − 1, N − M)
/// failures, and each absorbing marking is reached from a running one by
/// one event.
pub fn parallel_marking_count(n: usize, m: usize, f: usize) -> f64 {
    // multinomial(n; s, f, n-s-f) computed in log space to avoid overflow
    let ln_fact = |k: usize| -> f64 { (1..=k).map(|x| (x as f64).ln()).sum() };
    let lf: Vec<f64> = (0..=n).map(ln_fact).collect();
    let mut total = 0.0;
    let max_f = (n - m).min(f.saturating_sub(1)); // failures allowed while running
    for s in 0..=m.min(n) {
        for f in 0..=(max_f + 1).min(n - s) {
            let running = s < m && f <= max_f;
            let absorbing = (s == m && f <= max_f) || (f == max_f + 1 && s < m);
            if running || absorbing {
                total += (lf[n] - lf[s] - lf[f] - lf[n - s - f]).exp();
            }
        }
    }
    total
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sequence_mrg_matches_fig_9_8() {
        let g = Mrg::build(Policy::Sequence, 3);
        // 3 running, 1 success, 3 failure markings
        assert_eq!(g.len(), 7);
        assert_eq!(g.marking(0), vec![0, 0, 0]);
        assert_eq!(g.marking(2), vec![1, 1, 0]);
        assert_eq!(g.marking(3), vec![1, 1, 1]);
        assert_eq!(g.status[3], Status::Success);
        assert_eq!(g.marking(5), vec![1, -1, 0]);
        assert_eq!(g.status[5], Status::Failure);
        assert_eq!(g.feasible(1).collect::<Vec<_>>(), vec![1]);
    }

    #[test]
    fn fallback_feasible_set_of_example_9_5() {
        let g = Mrg::build(Policy::Fallback, 2);
        // marking [-1, 0] is number 1; only child 1 may return
        assert_eq!(g.marking(1), vec![-1, 0]);
        assert_eq!(g.feasible(1).collect::<Vec<_>>(), vec![1]);
        // [1, 0] is absorbing: empty feasible set
        let success = (0..g.len()).find(|&i| g.marking(i) == vec![1, 0]).unwrap();
        assert_eq!(g.status[success], Status::Success);
        assert_eq!(g.feasible(success).count(), 0);
    }

    #[test]
    fn parallel_mrg_of_fig_9_10() {
        // two children, M = 2: markings [0,0], [1,0], [-1,0]F, [0,1], [0,-1]F, [1,1]S, [1,-1]F...
        let g = Mrg::build(
            Policy::Parallel {
                success_threshold: 2,
                failure_threshold: 1,
            },
            2,
        );
        let statuses: Vec<(Vec<i8>, Status)> =
            (0..g.len()).map(|i| (g.marking(i), g.status[i])).collect();
        // running: [0,0], [1,0], [0,1]; failure: [-1,0], [0,-1], [1,-1], [-1,1]; success: [1,1]
        let running = statuses
            .iter()
            .filter(|(_, s)| *s == Status::Running)
            .count();
        let success = statuses
            .iter()
            .filter(|(_, s)| *s == Status::Success)
            .count();
        let failure = statuses
            .iter()
            .filter(|(_, s)| *s == Status::Failure)
            .count();
        assert_eq!((running, success, failure), (3, 1, 4));
        assert_eq!(parallel_marking_count(2, 2, 1), 8.0);
        // events always go to a later marking
        assert!(g.events.iter().all(|e| e.to > e.from));
    }

    #[test]
    fn parallel_count_matches_enumeration() {
        for n in 1..=6 {
            for m in 1..=n {
                for f in 1..=n {
                    let g = Mrg::build(
                        Policy::Parallel {
                            success_threshold: m,
                            failure_threshold: f,
                        },
                        n,
                    );
                    let c = parallel_marking_count(n, m, f);
                    assert!(
                        (c - g.len() as f64).abs() < 1e-6,
                        "n={n} m={m} f={f}: {c} vs {}",
                        g.len()
                    );
                }
            }
        }
    }
}
