//! The episode engine: a flattened copy of the tree and one run of a subtree.
//!
//! [`Flat`] is built once per simulation. Each node becomes one small,
//! `Copy` [`Op`] in an array indexed by [`NodeId`] (the tree's own indices),
//! children live in one shared index array, and an episode is a tight
//! recursive function over those indices: no allocation, no dynamic
//! dispatch. Parallel nodes use a [`Scratch`] stack whose capacity is
//! reserved up front, so it never grows during a simulation.

use rand::Rng;
use rand_distr::{Distribution, Exp1};

use crate::tree::{Duration, NodeId, NodeKind, Tree};

/// Outcome threshold meaning "always Success" (ps = 1): no random draw.
const ALWAYS: u64 = u64::MAX;
/// Outcome threshold meaning "always Failure" (ps = 0): no random draw.
const NEVER: u64 = 0;
/// Outcomes compare the top 53 bits of a `u64` draw with `ps · 2^53`.
const ONE53: f64 = (1u64 << 53) as f64;

/// How long one outcome of a leaf takes, ready to sample.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Time {
    /// Exactly this long (also a condition's zero duration).
    Fixed(f64),
    /// `Exp1 · inv_rate`.
    Exp { inv_rate: f64 },
    /// `min(Exp1 · inv_rate, cap)`.
    Trunc { inv_rate: f64, cap: f64 },
}

impl Time {
    fn new(d: Option<Duration>) -> Time {
        match d {
            // Unreachable outcome (probability 0): never sampled.
            None => Time::Fixed(0.0),
            Some(Duration::Fixed { time }) => Time::Fixed(time),
            Some(Duration::Exponential { rate }) => Time::Exp {
                inv_rate: 1.0 / rate,
            },
            Some(Duration::TruncatedExponential { rate, cap }) => Time::Trunc {
                inv_rate: 1.0 / rate,
                cap,
            },
        }
    }

    #[inline(always)]
    fn sample<R: Rng>(self, rng: &mut R) -> f64 {
        match self {
            Time::Fixed(t) => t,
            Time::Exp { inv_rate } => {
                let e: f64 = Exp1.sample(rng);
                e * inv_rate
            }
            Time::Trunc { inv_rate, cap } => {
                let e: f64 = Exp1.sample(rng);
                (e * inv_rate).min(cap)
            }
        }
    }
}

/// One node, flattened. Children are `kids[first..end]`.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Op {
    /// An action or a condition (a condition has two zero [`Time::Fixed`]s).
    Leaf {
        /// Success iff `draw >> 11 < thr`; [`ALWAYS`] and [`NEVER`] draw nothing.
        thr: u64,
        success: Time,
        failure: Time,
    },
    Sequence { first: u32, end: u32 },
    Fallback { first: u32, end: u32 },
    Parallel { first: u32, end: u32, m: u32 },
}

/// Per-thread work space for Parallel nodes: stacks of child finishing times.
#[derive(Debug, Default)]
pub(crate) struct Scratch {
    succ: Vec<f64>,
    fail: Vec<f64>,
}

/// The tree flattened for fast episodes.
#[derive(Debug, Clone)]
pub(crate) struct Flat {
    ops: Vec<Op>,
    kids: Vec<u32>,
    /// Total number of children of Parallel nodes (bounds the scratch stacks).
    parallel_kids: usize,
    /// Deepest node depth (root 0).
    pub(crate) max_depth: usize,
}

/// Probability → outcome threshold.
fn threshold(ps: f64) -> u64 {
    let thr = (ps * ONE53).round();
    if thr >= ONE53 {
        ALWAYS
    } else if thr <= 0.0 {
        NEVER
    } else {
        thr as u64
    }
}

impl Flat {
    /// Flattens `tree`. Node ids are preserved.
    pub(crate) fn new(tree: &Tree) -> Flat {
        let mut kids = Vec::with_capacity(tree.nodes.len());
        let mut parallel_kids = 0;
        let mut span = |children: &[NodeId]| {
            let first = kids.len() as u32;
            kids.extend(children.iter().map(|&c| c as u32));
            (first, kids.len() as u32)
        };
        let ops = tree
            .nodes
            .iter()
            .map(|node| match &node.kind {
                NodeKind::Action(a) => Op::Leaf {
                    thr: threshold(a.ps),
                    success: Time::new(a.success),
                    failure: Time::new(a.failure),
                },
                NodeKind::Condition { ps } => Op::Leaf {
                    thr: threshold(*ps),
                    success: Time::Fixed(0.0),
                    failure: Time::Fixed(0.0),
                },
                NodeKind::Sequence { children } => {
                    let (first, end) = span(children);
                    Op::Sequence { first, end }
                }
                NodeKind::Fallback { children } => {
                    let (first, end) = span(children);
                    Op::Fallback { first, end }
                }
                NodeKind::Parallel {
                    success_threshold,
                    children,
                } => {
                    parallel_kids += children.len();
                    let (first, end) = span(children);
                    Op::Parallel {
                        first,
                        end,
                        m: *success_threshold as u32,
                    }
                }
            })
            .collect();
        Flat {
            ops,
            kids,
            parallel_kids,
            max_depth: tree.nodes.iter().map(|n| n.depth).max().unwrap_or(0),
        }
    }

    /// A scratch space big enough for any episode of this tree.
    pub(crate) fn scratch(&self) -> Scratch {
        Scratch {
            succ: Vec::with_capacity(self.parallel_kids),
            fail: Vec::with_capacity(self.parallel_kids),
        }
    }

    /// Runs the subtree rooted at `id` once, from time 0.
    ///
    /// Returns (`true` for Success, duration).
    #[inline]
    pub(crate) fn run<R: Rng>(&self, id: usize, rng: &mut R, scratch: &mut Scratch) -> (bool, f64) {
        match self.ops[id] {
            Op::Leaf {
                thr,
                success,
                failure,
            } => {
                let ok = match thr {
                    ALWAYS => true,
                    NEVER => false,
                    _ => (rng.next_u64() >> 11) < thr,
                };
                if ok {
                    (true, success.sample(rng))
                } else {
                    (false, failure.sample(rng))
                }
            }
            Op::Sequence { first, end } => {
                let mut t = 0.0;
                for &c in &self.kids[first as usize..end as usize] {
                    let (ok, d) = self.run(c as usize, rng, scratch);
                    t += d;
                    if !ok {
                        return (false, t);
                    }
                }
                (true, t)
            }
            Op::Fallback { first, end } => {
                let mut t = 0.0;
                for &c in &self.kids[first as usize..end as usize] {
                    let (ok, d) = self.run(c as usize, rng, scratch);
                    t += d;
                    if ok {
                        return (true, t);
                    }
                }
                (false, t)
            }
            Op::Parallel { first, end, m } => self.parallel(first, end, m, rng, scratch),
        }
    }

    /// A Parallel node. All children start at 0 and run independently. The
    /// outcome vector alone decides the result: with at least M successes the
    /// node succeeds at the M-th success time (the failure threshold N−M+1
    /// can then never be reached), otherwise it fails at the (N−M+1)-th
    /// failure time. So the halted children may as well be run to the end
    /// (their outcomes do not matter), and ties between children finishing
    /// at the same time cannot change the result.
    #[inline(never)]
    fn parallel<R: Rng>(
        &self,
        first: u32,
        end: u32,
        m: u32,
        rng: &mut R,
        scratch: &mut Scratch,
    ) -> (bool, f64) {
        let (s0, f0) = (scratch.succ.len(), scratch.fail.len());
        for &c in &self.kids[first as usize..end as usize] {
            let (ok, d) = self.run(c as usize, rng, scratch);
            if ok {
                scratch.succ.push(d);
            } else {
                scratch.fail.push(d);
            }
        }
        let n = (end - first) as usize;
        let m = m as usize;
        let result = if scratch.succ.len() - s0 >= m {
            (true, kth_smallest(&mut scratch.succ[s0..], m - 1))
        } else {
            (false, kth_smallest(&mut scratch.fail[f0..], n - m))
        };
        scratch.succ.truncate(s0);
        scratch.fail.truncate(f0);
        result
    }
}

/// The `k`-th smallest (0-based) of non-empty `xs`; reorders `xs`.
#[inline]
fn kth_smallest(xs: &mut [f64], k: usize) -> f64 {
    match xs.len() {
        1 => xs[0],
        2 => {
            let (a, b) = (xs[0], xs[1]);
            if k == 0 {
                a.min(b)
            } else {
                a.max(b)
            }
        }
        _ => *xs.select_nth_unstable_by(k, f64::total_cmp).1,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn thresholds() {
        assert_eq!(threshold(0.0), NEVER);
        assert_eq!(threshold(1.0), ALWAYS);
        assert_eq!(threshold(0.5), 1 << 52);
    }

    #[test]
    fn kth() {
        let mut v = [3.0, 1.0, 2.0, 0.5];
        assert_eq!(kth_smallest(&mut v, 1), 1.0);
        assert_eq!(kth_smallest(&mut [2.0, 1.0], 0), 1.0);
        assert_eq!(kth_smallest(&mut [2.0, 1.0], 1), 2.0);
        assert_eq!(kth_smallest(&mut [7.0], 0), 7.0);
    }
}
