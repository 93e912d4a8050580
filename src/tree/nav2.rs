//! Nav2's node types — PipelineSequence, RoundRobin, RateController,
//! SingleTrigger — under the SBT assumptions: what ticking a child again
//! does, and when a node is exactly one of btrel's primitives.
//!
//! Facts from the sources (Nav2 `nav2_behavior_tree/plugins`, BehaviorTree.CPP
//! v4 `src/`), on which the meanings below rest:
//!
//! * `PipelineSequence::tick` ticks children `0..n` in order on every tick; a
//!   child returning RUNNING stops the loop only if it is at or beyond the
//!   furthest child reached (`last_child_ticked_`), so an earlier child that
//!   runs does not block the later ones; FAILURE of any child halts all
//!   children and fails; SUCCESS of the last child halts all and succeeds.
//!   Children that returned SUCCESS are not reset by it (a ControlNode does
//!   not reset its children), so they are ticked again *from their SUCCESS
//!   state* on every tick.
//! * What such a re-tick does depends on the child: a leaf action
//!   (`StatefulActionNode::tick` returns its previous status unless it is
//!   IDLE or RUNNING; Nav2's `BtActionNode::tick` sends a new goal only when
//!   `!isStatusActive(status())`, and SUCCESS is active) returns SUCCESS again
//!   without running; a condition is evaluated again (the SBT assumption: it
//!   keeps its value); a control node (Sequence, Fallback, RecoveryNode, …
//!   reset their children when they return) or a decorator
//!   (`DecoratorNode::executeTick` resets a child that returned) runs again
//!   from the start; `RateController::tick` ticks its child only the first
//!   time, while the child runs, or once `1/hz` seconds have passed since the
//!   child's last SUCCESS (`start_` is reset there; it returns RUNNING
//!   otherwise, which does not block the pipeline); `SingleTrigger::tick`
//!   returns FAILURE once its child has returned, until it is reset.
//! * `ControlNode::haltChild` resets a child's status to IDLE whether it was
//!   running or not (it halts it first if it was RUNNING), so after a
//!   pipeline returns every child starts afresh at its next execution
//!   (RateController's `first_time_`, SingleTrigger's `first_time_`).
//! * `RoundRobinNode::tick` starts at `current_child_idx_`, moves it past
//!   every child that returns; SUCCESS returns SUCCESS (the index stays at the
//!   next child); when all children failed it calls `halt()`, which sets the
//!   index to 0. A parent resets a RoundRobin that returned without halting
//!   it (`haltChild` halts only RUNNING children), so the index survives the
//!   RecoveryNode's retries and later executions of the tree. Without
//!   `wrap_around` (the default since Nav2 #5308, 2025) the loop breaks when
//!   the index passes the last child, before the status of that child is
//!   looked at: the last child's SUCCESS returns FAILURE.
//!
//! In continuous time a tick is instantaneous and ticks follow each other
//! without gaps, so an earlier pipeline child that is restarted "every tick"
//! runs back to back: after each Success it starts again at once, until one
//! run fails (which fails the pipeline) or the pipeline ends.

use super::{Decorator, NodeId, NodeKind, Tree};

/// What ticking a child again after it returned Success does, when its
/// parent (a PipelineSequence) does not reset it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Retick {
    /// Nothing changes: a leaf (an action returns its old status, a
    /// condition keeps its value), a subtree of zero-time leaves (its
    /// conditions keep their values), or a subtree that cannot fail.
    Inert,
    /// The child runs again from the start, back to back, until a run fails.
    Restart,
    /// RateController: the child runs again `period` seconds after each
    /// Success, until a run fails.
    Rate(f64),
    /// SingleTrigger: Failure at once.
    Fail,
}

/// Whether the subtree rooted at `id` can return (Success, Failure).
pub fn outcomes(tree: &Tree, id: NodeId) -> (bool, bool) {
    let kids: Vec<(bool, bool)> = tree.nodes[id]
        .kind
        .children()
        .iter()
        .map(|&c| outcomes(tree, c))
        .collect();
    type Pick = fn(&(bool, bool)) -> bool;
    let any = |f: Pick| kids.iter().any(f);
    let all = |f: Pick| kids.iter().all(f);
    let (s, f): (Pick, Pick) = (|o| o.0, |o| o.1);
    match &tree.nodes[id].kind {
        NodeKind::Action(a) => (a.ps > 0.0, a.pf > 0.0),
        NodeKind::Condition { ps } => (*ps > 0.0, *ps < 1.0),
        NodeKind::Sequence { .. } => (all(s), any(f)),
        NodeKind::Pipeline { children } => {
            let trigger = children[..children.len() - 1]
                .iter()
                .any(|&c| retick(tree, c) == Retick::Fail);
            (all(s), trigger || any(f))
        }
        NodeKind::Fallback { .. } => (any(s), all(f)),
        // a start index past a failing child may still reach every child
        NodeKind::RoundRobin { wrap, .. } => (any(s), !wrap || any(f)),
        NodeKind::Parallel { .. } => (any(s), any(f)),
        // a flow's edges may map either outcome of a child to either of its
        // own: any return is possible as far as this rough test knows
        NodeKind::Flow(_) => {
            let r = any(s) || any(f);
            (r, r)
        }
        NodeKind::Decorator { decorator, .. } => {
            let (s, f) = kids[0];
            match decorator {
                Decorator::Inverter => (f, s),
                Decorator::ForceSuccess => (true, false),
                Decorator::ForceFailure => (false, true),
                Decorator::UntilFailure => (false, f),
                Decorator::UntilSuccess => (s, false),
                Decorator::Retry { .. }
                | Decorator::Repeat { .. }
                | Decorator::Rate { .. }
                | Decorator::SingleTrigger => (s, f),
            }
        }
    }
}

/// Whether every run of the subtree takes zero time (all its leaves are
/// conditions or actions whose times are all fixed at 0).
pub fn zero_time(tree: &Tree, id: NodeId) -> bool {
    tree.subtree(id).all(|n| match &tree.nodes[n].kind {
        NodeKind::Action(a) => [a.success, a.failure]
            .iter()
            .flatten()
            .all(|d| matches!(d, super::Duration::Fixed { time } if *time == 0.0)),
        _ => true,
    })
}

/// What a re-tick of `id` does (see the module documentation).
pub fn retick(tree: &Tree, id: NodeId) -> Retick {
    match &tree.nodes[id].kind {
        NodeKind::Action(_) | NodeKind::Condition { .. } => Retick::Inert,
        NodeKind::Decorator {
            decorator: Decorator::SingleTrigger,
            ..
        } => Retick::Fail,
        _ if zero_time(tree, id) || !outcomes(tree, id).1 => Retick::Inert,
        NodeKind::Decorator {
            decorator: Decorator::Rate { period },
            ..
        } => Retick::Rate(*period),
        _ => Retick::Restart,
    }
}

/// Why a Nav2 node has no exact meaning in btrel's primitives (yet).
#[derive(Debug, Clone, PartialEq)]
pub struct NotPrimitive {
    /// The node.
    pub node: NodeId,
    /// What it does that the primitives cannot express.
    pub reason: String,
}

/// The tree with every Nav2 node replaced by the primitive it is exactly
/// equivalent to, node ids unchanged (`None` when the tree has no Nav2
/// node): a PipelineSequence whose earlier children are [`Retick::Inert`] is
/// a Sequence (re-ticks change nothing and the later children are not
/// delayed by them); a RoundRobin with `wrap_around` executed at most once
/// per run of the tree starts at index 0 and is a Fallback; RateController
/// and SingleTrigger outside those positions run their child once (`repeat`
/// 1, the identity). Anything else is refused, naming the node.
pub fn primitive_view(tree: &Tree) -> Result<Option<Tree>, NotPrimitive> {
    let nav2 = |k: &NodeKind| {
        matches!(
            k,
            NodeKind::Pipeline { .. }
                | NodeKind::RoundRobin { .. }
                | NodeKind::Decorator {
                    decorator: Decorator::Rate { .. } | Decorator::SingleTrigger,
                    ..
                }
        )
    };
    if !tree.nodes.iter().any(|n| nav2(&n.kind)) {
        return Ok(None);
    }
    let mut out = tree.clone();
    for (id, node) in tree.nodes.iter().enumerate() {
        let kind = match &node.kind {
            NodeKind::Pipeline { children } => {
                for &c in &children[..children.len() - 1] {
                    let name = &tree.nodes[c].name;
                    let reason = match retick(tree, c) {
                        Retick::Inert => continue,
                        Retick::Rate(p) => format!(
                            "its child '{name}' runs again {p} s after each of its successes \
                             while the later children run (Nav2's re-planning), and fails the \
                             pipeline when a re-run fails: that loop races the later children \
                             (a Parallel with M = 1, F = 1 over a loop with a fixed wait), \
                             which the analysis cannot compute yet"
                        ),
                        Retick::Restart => format!(
                            "its child '{name}' (a control node or decorator that can fail) \
                             runs again from the start after every success while the later \
                             children run, and fails the pipeline when a run fails: that loop \
                             races the later children, which the analysis cannot compute yet"
                        ),
                        Retick::Fail => format!(
                            "its child '{name}' (SingleTrigger) returns Failure when ticked \
                             again while a later child runs, which the analysis does not model"
                        ),
                    };
                    return Err(NotPrimitive { node: id, reason });
                }
                NodeKind::Sequence {
                    children: children.clone(),
                }
            }
            NodeKind::RoundRobin {
                children,
                wrap,
                slot,
            } => {
                if !wrap && children.len() > 1 {
                    return Err(NotPrimitive {
                        node: id,
                        reason: "without wrap_around=\"true\" it returns Failure when its last \
                                 child succeeds (Nav2's round_robin_node.cpp leaves its loop \
                                 before looking at that child's status), which the analysis \
                                 does not model"
                            .into(),
                    });
                }
                if let Some(why) = repeated(tree, id, *slot) {
                    return Err(NotPrimitive {
                        node: id,
                        reason: format!(
                            "it is executed several times per run ({why}) and starts each \
                             time after the child that last succeeded: its start index depends \
                             on the earlier executions, which the analysis cannot follow yet"
                        ),
                    });
                }
                NodeKind::Fallback {
                    children: children.clone(),
                }
            }
            NodeKind::Decorator {
                decorator: Decorator::Rate { .. } | Decorator::SingleTrigger,
                child,
            } => NodeKind::Decorator {
                decorator: Decorator::Repeat { times: 1 },
                child: *child,
            },
            _ => continue,
        };
        out.nodes[id].kind = kind;
    }
    Ok(Some(out))
}

/// Why the RoundRobin `id` may run more than once per run of the root, if it
/// may: another node shares its index (a copy made by a RecoveryNode), or an
/// ancestor repeats its child.
fn repeated(tree: &Tree, id: NodeId, slot: usize) -> Option<String> {
    if let Some(other) = tree.nodes.iter().enumerate().find(|(o, n)| {
        *o != id && matches!(&n.kind, NodeKind::RoundRobin { slot: s, .. } if *s == slot)
    }) {
        return Some(format!("'{}' is a copy of it", other.1.name));
    }
    let (mut below, mut up) = (id, tree.nodes[id].parent);
    while let Some(a) = up {
        let again = match &tree.nodes[a].kind {
            // a flow may visit the same child from several states
            NodeKind::Flow(flow) => {
                let at = flow.children.iter().position(|&c| c == below);
                at.is_some_and(|k| flow.states.iter().filter(|s| s.child == k).count() > 1)
            }
            NodeKind::Decorator { decorator, .. } => match decorator {
                Decorator::Retry { attempts } => *attempts > 1,
                Decorator::Repeat { times } => *times > 1,
                Decorator::UntilFailure | Decorator::UntilSuccess => true,
                _ => false,
            },
            _ => false,
        };
        if again {
            return Some(format!("its ancestor '{}' repeats it", tree.nodes[a].name));
        }
        (below, up) = (a, tree.nodes[a].parent);
    }
    None
}
