//! The core IR: the few operators the engine knows. Every node a reader
//! accepts — YAML, BehaviorTree.CPP, Nav2 — lowers to them in one place
//! ([`lower`]); the engine (`compile`) sees nothing else.
//!
//! | operator | what it does | surface nodes |
//! |---|---|---|
//! | [`Op::Leaf`] | returns an outcome after a time drawn from its law | actions, conditions |
//! | [`Op::Flow`] | a finite acyclic graph of states, each running one child afresh | Sequence, Fallback, IfThenElse, Switch, Retry, Repeat, RecoveryNode's retries, memory indexes, RoundRobin |
//! | [`Op::Map`] | returns a function of its child's outcome, at the same instant | Inverter, ForceSuccess, ForceFailure, a RateController or SingleTrigger run once |
//! | [`Op::KOfN`] | runs its children at once; Success at `success` of them, Failure at `failure` (child order breaks ties) | Parallel, Timeout, a re-planning race |
//! | [`Op::Loop`] | runs a fresh child until it returns `until` | KeepRunningUntilFailure, RetryUntilSuccessful forever, the re-runs of a PipelineSequence |
//!
//! A [`Graph`] is the same pre-order arena as a [`Tree`], node for node
//! with the tree it lowers (the primitive view's tree for a tree with Nav2
//! nodes): a node's id, name, path and location are its surface node's.

mod lower;

use crate::tree::{Action, FlowNext, FlowState, Kind, NodeId, Tree};

#[cfg(test)]
pub(crate) use lower::graph_of;
pub use lower::{lower, op, Lowered};

/// The core IR of a tree: [`Op`]s in a pre-order arena.
pub type Graph = Tree<Op>;

/// A node's outcome.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Outcome {
    /// Success.
    Success,
    /// Failure.
    Failure,
}

impl Outcome {
    /// 0 for Success, 1 for Failure (the order of `[S, F]` pairs).
    pub fn index(self) -> usize {
        usize::from(self == Outcome::Failure)
    }

    /// The other outcome.
    pub fn other(self) -> Outcome {
        match self {
            Outcome::Success => Outcome::Failure,
            Outcome::Failure => Outcome::Success,
        }
    }
}

/// A leaf: an action (a time law per outcome) or a condition (no time).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Leaf {
    /// Returns Success with probability `ps` after its success time, else
    /// Failure after its failure time.
    Action(Action),
    /// Returns at once: Success with probability `ps`.
    Condition {
        /// Probability of Success.
        ps: f64,
    },
}

/// An operator of the core IR.
#[derive(Debug, Clone, PartialEq)]
pub enum Op {
    /// A leaf.
    Leaf(Leaf),
    /// A flow over its children (see [`Flow`]).
    Flow(Flow),
    /// The child's outcome mapped: Success becomes `on_success`, Failure
    /// `on_failure`, at the instant the child returns.
    Map {
        /// The child.
        child: NodeId,
        /// What the node returns when the child succeeds.
        on_success: Outcome,
        /// What the node returns when the child fails.
        on_failure: Outcome,
    },
    /// The children run at once, independently; Success once `success` of
    /// them have succeeded, Failure once `failure` have failed or Success
    /// has become impossible (more than N − `success` failed). Children
    /// returning at one instant count in child order.
    KOfN {
        /// M, in `1..=children.len()`.
        success: usize,
        /// F, in `1..=children.len()`.
        failure: usize,
        /// The children (at least one).
        children: Vec<NodeId>,
    },
    /// A fresh run of the child after each return other than `until`; the
    /// node returns `until` when the child does (and never returns if it
    /// never does).
    Loop {
        /// The child.
        child: NodeId,
        /// The outcome that ends the loop.
        until: Outcome,
    },
}

/// A flow: a finite acyclic graph of states, each running one child (a
/// fresh, independent run at every visit), whose Success and Failure edges
/// lead to a later state or to the node's own outcome. Two graph shapes
/// that most trees are made of are kept in a compact form ([`FlowGraph`]),
/// so that the engine can use their closed forms and so that a Retry of
/// 10⁶ attempts is not 10⁶ states in memory.
#[derive(Debug, Clone, PartialEq)]
pub struct Flow {
    /// The children (distinct subtrees), in tree order.
    pub children: Vec<NodeId>,
    /// The graph of states.
    pub graph: FlowGraph,
}

/// The graph of a [`Flow`].
#[derive(Debug, Clone, PartialEq)]
pub enum FlowGraph {
    /// Each child once, in order; the first to return `stop` ends the flow
    /// with `stop`; if none does, the flow returns the other outcome.
    /// Sequence: `stop` Failure; Fallback: `stop` Success.
    Chain {
        /// The outcome that ends the chain early.
        stop: Outcome,
    },
    /// The only child, run up to `times` times; the first `stop` ends the
    /// flow with `stop`; `times` runs without it return the other outcome.
    /// Retry: `stop` Success; Repeat: `stop` Failure.
    Repeat {
        /// The most runs (≥ 1).
        times: usize,
        /// The outcome that ends the repetition early.
        stop: Outcome,
    },
    /// Any acyclic graph: the run starts in `states[0]`; every edge to a
    /// state goes to a later one (checked by [`crate::tree::Flow::new`]).
    States(Vec<FlowState>),
}

impl Flow {
    /// The number of states of the flow's graph.
    pub fn state_count(&self) -> usize {
        match &self.graph {
            FlowGraph::Chain { .. } => self.children.len(),
            FlowGraph::Repeat { times, .. } => *times,
            FlowGraph::States(states) => states.len(),
        }
    }

    /// Every state of the flow's graph, in order (generated for the
    /// compact graphs: callers bound [`Flow::state_count`] first).
    pub fn states(&self) -> std::borrow::Cow<'_, [FlowState]> {
        match &self.graph {
            FlowGraph::States(states) => std::borrow::Cow::Borrowed(states),
            _ => (0..self.state_count()).map(|i| self.state(i)).collect(),
        }
    }

    /// State `i` of the flow's graph (`i < state_count()`).
    pub fn state(&self, i: usize) -> FlowState {
        let step = |stop: Outcome, last: bool, child: usize| {
            let next = if last {
                stop.other().exit()
            } else {
                FlowNext::State(i + 1)
            };
            let (on_success, on_failure) = match stop {
                Outcome::Success => (FlowNext::Success, next),
                Outcome::Failure => (next, FlowNext::Failure),
            };
            FlowState {
                child,
                on_success,
                on_failure,
            }
        };
        match &self.graph {
            FlowGraph::Chain { stop } => step(*stop, i + 1 == self.children.len(), i),
            FlowGraph::Repeat { times, stop } => step(*stop, i + 1 == *times, 0),
            FlowGraph::States(states) => states[i],
        }
    }
}

/// Whether the subtree at `id` can return (Success, Failure), as far as
/// its structure tells (a flow's graph may send either outcome of a child
/// anywhere: any return of a child counts for both).
pub fn outcomes(graph: &Graph, id: NodeId) -> (bool, bool) {
    let op = &graph.node(id).kind;
    let kids: Vec<(bool, bool)> = op.children().iter().map(|&c| outcomes(graph, c)).collect();
    let any = |f: fn(&(bool, bool)) -> bool| kids.iter().any(f);
    let all = |f: fn(&(bool, bool)) -> bool| kids.iter().all(f);
    match op {
        Op::Leaf(Leaf::Action(a)) => (a.ps > 0.0, a.pf > 0.0),
        Op::Leaf(Leaf::Condition { ps }) => (*ps > 0.0, *ps < 1.0),
        Op::Flow(f) => match f.graph {
            FlowGraph::Chain {
                stop: Outcome::Failure,
            } => (all(|o| o.0), any(|o| o.1)),
            FlowGraph::Chain {
                stop: Outcome::Success,
            } => (any(|o| o.0), all(|o| o.1)),
            FlowGraph::Repeat { .. } => kids[0],
            FlowGraph::States(_) => {
                let r = any(|o| o.0 || o.1);
                (r, r)
            }
        },
        Op::KOfN { .. } => (any(|o| o.0), any(|o| o.1)),
        Op::Map {
            on_success,
            on_failure,
            ..
        } => {
            let (s, f) = kids[0];
            let to = |o: Outcome| (s && *on_success == o) || (f && *on_failure == o);
            (to(Outcome::Success), to(Outcome::Failure))
        }
        Op::Loop { until, .. } => match until {
            Outcome::Success => (kids[0].0, false),
            Outcome::Failure => (false, kids[0].1),
        },
    }
}

impl Outcome {
    /// The flow exit that returns this outcome.
    pub fn exit(self) -> FlowNext {
        match self {
            Outcome::Success => FlowNext::Success,
            Outcome::Failure => FlowNext::Failure,
        }
    }
}

impl Op {
    /// The node's children (empty for a leaf).
    pub fn children(&self) -> &[NodeId] {
        match self {
            Op::Leaf(_) => &[],
            Op::Flow(f) => &f.children,
            Op::KOfN { children, .. } => children,
            Op::Map { child, .. } | Op::Loop { child, .. } => std::slice::from_ref(child),
        }
    }

    /// The operator's name.
    pub fn keyword(&self) -> &'static str {
        match self {
            Op::Leaf(Leaf::Action(_)) => "action",
            Op::Leaf(Leaf::Condition { .. }) => "condition",
            Op::Flow(_) => "flow",
            Op::Map { .. } => "map",
            Op::KOfN { .. } => "k-of-n",
            Op::Loop { .. } => "loop",
        }
    }

    /// The children of a Sequence: the chain that stops at a Failure.
    pub fn sequence(&self) -> Option<&[NodeId]> {
        match self {
            Op::Flow(Flow {
                children,
                graph:
                    FlowGraph::Chain {
                        stop: Outcome::Failure,
                    },
            }) => Some(children),
            _ => None,
        }
    }

    /// A map's child and where it sends the child's Success and Failure
    /// ([`Outcome::index`]: 0 Success, 1 Failure).
    pub fn as_map(&self) -> Option<(NodeId, [usize; 2])> {
        match self {
            Op::Map {
                child,
                on_success,
                on_failure,
            } => Some((*child, [on_success.index(), on_failure.index()])),
            _ => None,
        }
    }

    /// The action of an action leaf.
    pub fn action(&self) -> Option<&Action> {
        match self {
            Op::Leaf(Leaf::Action(a)) => Some(a),
            _ => None,
        }
    }
}

impl Kind for Op {
    fn children(&self) -> &[NodeId] {
        Op::children(self)
    }

    fn children_mut(&mut self) -> &mut [NodeId] {
        match self {
            Op::Leaf(_) => &mut [],
            Op::Flow(f) => &mut f.children,
            Op::KOfN { children, .. } => children,
            Op::Map { child, .. } | Op::Loop { child, .. } => std::slice::from_mut(child),
        }
    }

    fn same_parameters(&self, other: &Self) -> bool {
        match (self, other) {
            (Op::Leaf(a), Op::Leaf(b)) => a == b,
            (Op::Flow(a), Op::Flow(b)) => a.graph == b.graph,
            (
                Op::Map {
                    on_success: s1,
                    on_failure: f1,
                    ..
                },
                Op::Map {
                    on_success: s2,
                    on_failure: f2,
                    ..
                },
            ) => (s1, f1) == (s2, f2),
            (
                Op::KOfN {
                    success: m1,
                    failure: f1,
                    ..
                },
                Op::KOfN {
                    success: m2,
                    failure: f2,
                    ..
                },
            ) => (m1, f1) == (m2, f2),
            (Op::Loop { until: a, .. }, Op::Loop { until: b, .. }) => a == b,
            _ => false,
        }
    }
}
