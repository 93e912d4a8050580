//! Absorbing Markov chains with two absorbing outcomes, in jump-chain form.
//!
//! Both the DTMCs over marking reachability graphs (with a mean duration on
//! each transition) and the exact CTMCs of phases (where a state with total
//! exit rate `q` has jump probabilities `q_ij / q` and mean sojourn `1 / q`)
//! are stored as an [`AbsorbingChain`]: transient states in topological order
//! (every edge goes to a higher-numbered state), an initial distribution, and
//! edges with a probability and a mean duration ("reward").

/// Where an edge leads.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Target {
    /// A transient state (its index is larger than the edge's source).
    State(usize),
    /// The Success outcome (absorbing).
    Success,
    /// The Failure outcome (absorbing).
    Failure,
}

/// One transition of the jump chain.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Edge {
    /// Source transient state.
    pub from: usize,
    /// Destination.
    pub to: Target,
    /// Probability that the source's sojourn ends through this edge.
    pub prob: f64,
    /// Mean time spent before taking this edge, given that it is taken.
    pub duration: f64,
}

/// An acyclic absorbing chain with Success and Failure outcomes.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct AbsorbingChain {
    /// Number of transient states.
    pub n: usize,
    /// Initial probability of each transient state (sparse).
    pub initial: Vec<(usize, f64)>,
    /// Probability of starting in Success (an instantaneous outcome).
    pub initial_success: f64,
    /// Probability of starting in Failure.
    pub initial_failure: f64,
    /// Transitions, in any order.
    pub edges: Vec<Edge>,
}

/// A continuous-time chain of exponential phases with Success and Failure
/// exits: the exact representation of a subtree whose leaves are Markovian.
///
/// States are in topological order: every transition goes to a higher index.
/// A phase without transitions or exits (total rate 0) is a *trap*: a run
/// that enters it never returns (a defective law, `P(S) + P(F) < 1`).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PhaseChain {
    /// Initial probability of each phase (sparse).
    pub initial: Vec<(usize, f64)>,
    /// Probability of an instantaneous Success (e.g. a condition).
    pub initial_success: f64,
    /// Probability of an instantaneous Failure.
    pub initial_failure: f64,
    /// Transitions between phases, per source phase: `(target, rate)`.
    pub transitions: Vec<Vec<(usize, f64)>>,
    /// Rate of leaving each phase into Success.
    pub exit_success: Vec<f64>,
    /// Rate of leaving each phase into Failure.
    pub exit_failure: Vec<f64>,
}

impl PhaseChain {
    /// Number of phases.
    pub fn len(&self) -> usize {
        self.exit_success.len()
    }

    /// Whether the chain has no phases (its outcome is instantaneous).
    pub fn is_empty(&self) -> bool {
        self.exit_success.is_empty()
    }

    /// Total rate of leaving phase `i`.
    pub fn total_rate(&self, i: usize) -> f64 {
        self.exit_success[i]
            + self.exit_failure[i]
            + self.transitions[i].iter().map(|&(_, r)| r).sum::<f64>()
    }

    /// Appends a phase with no transitions yet, returning its index.
    pub fn push_phase(&mut self) -> usize {
        self.transitions.push(Vec::new());
        self.exit_success.push(0.0);
        self.exit_failure.push(0.0);
        self.len() - 1
    }

    /// The embedded jump chain, with mean sojourn `1 / q_i` on every edge
    /// leaving phase `i`.
    pub fn jump_chain(&self) -> AbsorbingChain {
        let mut edges = Vec::new();
        for i in 0..self.len() {
            let q = self.total_rate(i);
            // a trap (no exits: the run never returns) has no jumps
            if q <= 0.0 {
                continue;
            }
            let d = 1.0 / q;
            for &(j, r) in &self.transitions[i] {
                edges.push(Edge {
                    from: i,
                    to: Target::State(j),
                    prob: r / q,
                    duration: d,
                });
            }
            for (rate, to) in [
                (self.exit_success[i], Target::Success),
                (self.exit_failure[i], Target::Failure),
            ] {
                if rate > 0.0 {
                    edges.push(Edge {
                        from: i,
                        to,
                        prob: rate / q,
                        duration: d,
                    });
                }
            }
        }
        AbsorbingChain {
            n: self.len(),
            initial: self.initial.clone(),
            initial_success: self.initial_success,
            initial_failure: self.initial_failure,
            edges,
        }
    }
}
