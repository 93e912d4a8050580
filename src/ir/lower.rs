//! The one place where surface nodes become the core IR's operators.
//!
//! Two steps: the stateful BehaviorTree.CPP / Nav2 nodes (PipelineSequence
//! re-runs, RoundRobin and SequenceWithMemory indexes, RateController,
//! SingleTrigger) are first replaced by exactly equivalent primitives
//! ([`crate::tree::nav2::primitive_view`]); then every node, one for one,
//! becomes its operator ([`op`]).

use super::{Flow, FlowGraph, Graph, Leaf, Op, Outcome};
use crate::tree::nav2::{primitive_view, NotPrimitive};
use crate::tree::{Decorator, NodeId, NodeKind, Tree};

/// A tree lowered to the core IR.
#[derive(Debug, Clone)]
pub struct Lowered {
    /// The IR, node for node with the tree's primitive view.
    pub graph: Graph,
    /// `image[id]`: the node of [`Lowered::graph`] standing for node `id` of
    /// the tree (its first run, for a node the lowering copies); `None`
    /// when the tree had no Nav2 node (node `id` is node `id`).
    pub image: Option<Vec<NodeId>>,
    /// `copied[id]`: node `id` of the tree also has re-run copies in the
    /// graph (it lies below a PipelineSequence child that re-runs); empty
    /// when `image` is `None`.
    pub copied: Vec<bool>,
}

impl Lowered {
    /// The node of the graph standing for node `id` of the tree.
    pub fn node(&self, id: NodeId) -> NodeId {
        self.image.as_ref().map_or(id, |image| image[id])
    }
}

/// Lowers `tree` to the core IR, or names the Nav2 node that has no exact
/// equivalent where it stands.
pub fn lower(tree: &Tree) -> Result<Lowered, NotPrimitive> {
    Ok(match primitive_view(tree)? {
        Some(view) => Lowered {
            graph: graph_of(&view.tree),
            image: Some(view.image),
            copied: view.copied,
        },
        None => Lowered {
            graph: graph_of(tree),
            image: None,
            copied: Vec::new(),
        },
    })
}

/// The IR of a tree of primitives, node for node.
pub(crate) fn graph_of(tree: &Tree) -> Graph {
    Tree {
        title: tree.title.clone(),
        nodes: tree
            .nodes
            .iter()
            .map(|n| crate::tree::Node {
                name: n.name.clone(),
                path: n.path.clone(),
                depth: n.depth,
                parent: n.parent,
                kind: op(&n.kind),
                location: n.location,
            })
            .collect(),
    }
}

/// The operator of one node.
///
/// The Nav2 kinds appear here only in their primitive reading (a tree's
/// primitive view has none left): a PipelineSequence is a Sequence, a
/// RoundRobin a Fallback, a SequenceWithMemory a Sequence, a
/// RateController or SingleTrigger the identity.
pub fn op(kind: &NodeKind) -> Op {
    let chain = |children: &Vec<NodeId>, stop| {
        Op::Flow(Flow {
            children: children.clone(),
            graph: FlowGraph::Chain { stop },
        })
    };
    let map = |child: NodeId, on_success, on_failure| Op::Map {
        child,
        on_success,
        on_failure,
    };
    let repeat = |child: NodeId, times, stop| {
        Op::Flow(Flow {
            children: vec![child],
            graph: FlowGraph::Repeat { times, stop },
        })
    };
    use Outcome::{Failure, Success};
    match kind {
        NodeKind::Action(a) => Op::Leaf(Leaf::Action(*a)),
        NodeKind::Condition { ps } => Op::Leaf(Leaf::Condition { ps: *ps }),
        NodeKind::Sequence { children }
        | NodeKind::Pipeline { children }
        | NodeKind::SequenceWithMemory { children, .. } => chain(children, Failure),
        NodeKind::Fallback { children } | NodeKind::RoundRobin { children, .. } => {
            chain(children, Success)
        }
        NodeKind::Parallel {
            success_threshold,
            failure_threshold,
            children,
        } => Op::KOfN {
            success: *success_threshold,
            failure: *failure_threshold,
            children: children.clone(),
        },
        NodeKind::Flow(f) => Op::Flow(Flow {
            children: f.children.clone(),
            graph: FlowGraph::States(f.states.clone()),
        }),
        NodeKind::Decorator { decorator, child } => {
            let child = *child;
            match *decorator {
                Decorator::Inverter => map(child, Failure, Success),
                Decorator::ForceSuccess => map(child, Success, Success),
                Decorator::ForceFailure => map(child, Failure, Failure),
                Decorator::Rate { .. } | Decorator::SingleTrigger => map(child, Success, Failure),
                Decorator::Retry { attempts } => repeat(child, attempts, Success),
                Decorator::Repeat { times } => repeat(child, times, Failure),
                Decorator::UntilFailure => Op::Loop {
                    child,
                    until: Failure,
                },
                Decorator::UntilSuccess => Op::Loop {
                    child,
                    until: Success,
                },
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tree::{FlowNext, FlowState};

    fn states(op: &Op) -> Vec<FlowState> {
        let Op::Flow(f) = op else {
            panic!("not a flow: {op:?}")
        };
        (0..f.state_count()).map(|i| f.state(i)).collect()
    }

    fn st(child: usize, on_success: FlowNext, on_failure: FlowNext) -> FlowState {
        FlowState {
            child,
            on_success,
            on_failure,
        }
    }

    #[test]
    fn a_sequence_is_the_chain_that_stops_at_a_failure() {
        let op = op(&NodeKind::Sequence {
            children: vec![1, 2, 3],
        });
        use FlowNext::*;
        assert_eq!(
            states(&op),
            [
                st(0, State(1), Failure),
                st(1, State(2), Failure),
                st(2, Success, Failure)
            ]
        );
    }

    #[test]
    fn a_fallback_is_the_chain_that_stops_at_a_success() {
        let op = op(&NodeKind::Fallback {
            children: vec![1, 2],
        });
        use FlowNext::*;
        assert_eq!(
            states(&op),
            [st(0, Success, State(1)), st(1, Success, Failure)]
        );
    }

    #[test]
    fn retry_and_repeat_are_one_child_run_again() {
        use FlowNext::*;
        let retry = op(&NodeKind::Decorator {
            decorator: Decorator::Retry { attempts: 3 },
            child: 1,
        });
        assert_eq!(
            states(&retry),
            [
                st(0, Success, State(1)),
                st(0, Success, State(2)),
                st(0, Success, Failure)
            ]
        );
        let repeat = op(&NodeKind::Decorator {
            decorator: Decorator::Repeat { times: 2 },
            child: 1,
        });
        assert_eq!(
            states(&repeat),
            [st(0, State(1), Failure), st(0, Success, Failure)]
        );
    }

    #[test]
    fn the_outcome_decorators_are_maps() {
        use Outcome::*;
        let of = |decorator| match op(&NodeKind::Decorator {
            decorator,
            child: 1,
        }) {
            Op::Map {
                on_success,
                on_failure,
                ..
            } => (on_success, on_failure),
            other => panic!("not a map: {other:?}"),
        };
        assert_eq!(of(Decorator::Inverter), (Failure, Success));
        assert_eq!(of(Decorator::ForceSuccess), (Success, Success));
        assert_eq!(of(Decorator::ForceFailure), (Failure, Failure));
        assert_eq!(of(Decorator::SingleTrigger), (Success, Failure));
    }

    #[test]
    fn the_unbounded_decorators_are_loops() {
        let until = |decorator| match op(&NodeKind::Decorator {
            decorator,
            child: 1,
        }) {
            Op::Loop { until, .. } => until,
            other => panic!("not a loop: {other:?}"),
        };
        assert_eq!(until(Decorator::UntilFailure), Outcome::Failure);
        assert_eq!(until(Decorator::UntilSuccess), Outcome::Success);
    }
}
