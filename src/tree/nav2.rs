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
//!
//! Size: one concern, Nav2's nodes as btrel primitives: the re-tick rules,
//! the lowering and the memory-index flows it uses (about 240 lines are
//! comments).

use std::collections::HashMap;

use super::{Decorator, Flow, FlowNext, FlowState, NodeId, NodeKind, Tree};

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
        NodeKind::Sequence { .. } | NodeKind::SequenceWithMemory { .. } => (all(s), any(f)),
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
pub(crate) fn zero_time(tree: &Tree, id: NodeId) -> bool {
    tree.subtree(id).all(|n| match &tree.nodes[n].kind {
        NodeKind::Action(a) => [a.success, a.failure]
            .iter()
            .flatten()
            .all(|d| matches!(d, super::Duration::Fixed { time } if *time == 0.0)),
        _ => true,
    })
}

/// What a re-tick of `id` does (see the module documentation).
pub(crate) fn retick(tree: &Tree, id: NodeId) -> Retick {
    match &tree.nodes[id].kind {
        NodeKind::Action(_) | NodeKind::Condition { .. } => Retick::Inert,
        NodeKind::Decorator {
            decorator: Decorator::SingleTrigger,
            ..
        } => Retick::Fail,
        _ if zero_time(tree, id) || !outcomes(tree, id).1 => Retick::Inert,
        NodeKind::Decorator {
            decorator: Decorator::Rate { period, .. },
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

/// A tree with its Nav2 nodes lowered to primitives ([`primitive_view`]).
#[derive(Debug, Clone, PartialEq)]
pub struct View {
    /// The lowered tree (pre-order, like every tree).
    pub tree: Tree,
    /// `image[id]`: the node of [`View::tree`] that stands for node `id` of
    /// the original tree (its first run, for a node the lowering copies).
    pub image: Vec<NodeId>,
    /// `copied[id]`: node `id` of the original tree also has re-run copies
    /// in the lowered tree (it lies below a pipeline child that re-runs).
    pub copied: Vec<bool>,
}

/// The tree with every Nav2 node replaced by primitives that are exactly
/// equivalent (`None` when the tree has no Nav2 node).
///
/// * A PipelineSequence `(c_0, …, c_{n−1})` whose earlier children are
///   [`Retick::Inert`] is a Sequence (re-ticks change nothing and the later
///   children are not delayed by them).
/// * An earlier child `c_k` that re-runs ([`Retick::Rate`] or
///   [`Retick::Restart`]) starts, at the instant its first run succeeds, a
///   re-run process that never succeeds and fails when a re-run fails:
///   `until_failure(Sequence(wait T, c_k′))` for a RateController of period
///   `T` (`wait`: an action with ps 1 and tau_s `T`; `c_k′` a fresh copy of
///   the RateController's child; a SpeedController whose first wait `T₀`
///   differs runs one cycle of its own first:
///   `Sequence(wait T₀, c_k′, until_failure(Sequence(wait T, c_k′)))`, the
///   copies fresh), `until_failure(c_k′)` for a control node
///   or decorator re-run back to back (`c_k′` a fresh copy of `c_k`). The
///   process lives until the pipeline ends, so it races the whole rest of
///   the pipeline, not each later phase on its own (it is memoryless only at
///   its own renewals): the pipeline is
///   `Sequence(c_0, …, c_k, Parallel{M = 1, F = 1}(process_k, rest))` with
///   `rest` the lowering of `(c_{k+1}, …, c_{n−1})`, so several re-running
///   children nest, each process raced with everything after its child.
///   The processes are independent (each re-run is a fresh execution). The
///   process comes first in the Parallel: when the rest ends at the instant
///   a re-run fails, the pipeline's next tick reaches the earlier child
///   first and fails, as BT.CPP's Parallel gives the tie to the child ticked
///   first.
/// * A RoundRobin with `wrap_around` executed at most once per run of the
///   tree starts at index 0 and is a Fallback.
/// * A RoundRobin whose index matters (without `wrap_around`, or with copies
///   sharing its index: a RecoveryNode's retries) makes the lowest common
///   ancestor of its copies one [`NodeKind::Flow`] over (place in that
///   node's run, index): see `index_roots` and `Lowering::index_flow`.
///   That ancestor is entered with the index at 0: it runs at most once per
///   run of the tree (checked), and every run of the tree starts with the
///   index at 0 — the simulator's assumption too (`sim::engine`, which resets
///   the RoundRobins at every episode).
/// * A SequenceWithMemory (read as one below a node that ticks it again
///   after a Failure) whose index may be other than 0 when it starts — a
///   child after the first can fail (the index stays there), or, in BT.CPP
///   v4, a Parallel or PipelineSequence above may halt it while such a
///   child runs — is followed like a RoundRobin's index: one flow at the
///   lowest common ancestor of its copies, or at the RetryUntilSuccessful
///   or Repeat above it; otherwise it is a Sequence.
/// * RateController and SingleTrigger outside those positions run their
///   child once (`repeat` 1, the identity).
///
/// Anything else is refused, naming the node.
pub fn primitive_view(tree: &Tree) -> Result<Option<View>, NotPrimitive> {
    let nav2 = |k: &NodeKind| {
        matches!(
            k,
            NodeKind::Pipeline { .. }
                | NodeKind::RoundRobin { .. }
                | NodeKind::SequenceWithMemory { .. }
                | NodeKind::Decorator {
                    decorator: Decorator::Rate { .. } | Decorator::SingleTrigger,
                    ..
                }
        )
    };
    if !tree.nodes.iter().any(|n| nav2(&n.kind)) {
        return Ok(None);
    }
    let roots = index_roots(tree)?;
    let mut lower = Lowering {
        tree,
        out: Vec::with_capacity(tree.nodes.len()),
        image: vec![usize::MAX; tree.nodes.len()],
        copied: vec![false; tree.nodes.len()],
        roots,
    };
    lower.node(Tree::ROOT, None, 0, None)?;
    Ok(Some(View {
        tree: Tree {
            title: tree.title.clone(),
            nodes: lower.out,
        },
        image: lower.image,
        copied: lower.copied,
    }))
}

/// The most nodes a lowered tree may have (re-run copies included).
const MAX_LOWERED_NODES: usize = 1 << 20;

struct Lowering<'a> {
    tree: &'a Tree,
    out: Vec<super::Node>,
    image: Vec<NodeId>,
    copied: Vec<bool>,
    /// The nodes that become one flow over a RoundRobin's index
    /// ([`index_roots`]), each with the RoundRobin slot.
    roots: HashMap<NodeId, usize>,
}

impl Lowering<'_> {
    /// Appends a node (children set later) and returns its id.
    fn push(
        &mut self,
        name: String,
        path: String,
        parent: Option<NodeId>,
        depth: usize,
        kind: NodeKind,
        from: NodeId,
    ) -> Result<NodeId, NotPrimitive> {
        if self.out.len() >= MAX_LOWERED_NODES {
            return Err(NotPrimitive {
                node: from,
                reason: format!(
                    "its re-run copies would make the lowered tree exceed \
                     {MAX_LOWERED_NODES} nodes"
                ),
            });
        }
        self.out.push(super::Node {
            name,
            path,
            depth,
            parent,
            kind,
            location: self.tree.nodes[from].location,
        });
        Ok(self.out.len() - 1)
    }

    fn set_children(&mut self, id: NodeId, ids: Vec<NodeId>) {
        match &mut self.out[id].kind {
            NodeKind::Sequence { children } | NodeKind::Parallel { children, .. } => {
                *children = ids
            }
            NodeKind::Fallback { children } => *children = ids,
            NodeKind::Pipeline { children }
            | NodeKind::RoundRobin { children, .. }
            | NodeKind::SequenceWithMemory { children, .. } => *children = ids,
            NodeKind::Flow(flow) => flow.children = ids,
            NodeKind::Decorator { child, .. } => *child = ids[0],
            NodeKind::Action(_) | NodeKind::Condition { .. } => {}
        }
    }

    /// Lowers the subtree of original node `id` below `parent`; `copy`:
    /// the name prefix of a re-run copy (`None`: the first run).
    fn node(
        &mut self,
        id: NodeId,
        parent: Option<NodeId>,
        depth: usize,
        copy: Option<&str>,
    ) -> Result<NodeId, NotPrimitive> {
        let tree = self.tree;
        let node = &tree.nodes[id];
        let (name, path) = match copy {
            None => (node.name.clone(), node.path.clone()),
            Some(prefix) => (
                format!("{prefix}/{}", node.name),
                format!("{prefix}/{}", node.path),
            ),
        };
        if let Some(&slot) = self.roots.get(&id) {
            return self.index_flow(id, slot, parent, depth, copy, name, path);
        }
        let kind = match &node.kind {
            NodeKind::Pipeline { children } => {
                let seq = self.push(
                    name.clone(),
                    path,
                    parent,
                    depth,
                    NodeKind::Sequence {
                        children: Vec::new(),
                    },
                    id,
                )?;
                self.note(id, seq, copy);
                let kids = self.pipeline(id, children, seq, depth + 1, &name, copy)?;
                self.set_children(seq, kids);
                return Ok(seq);
            }
            NodeKind::RoundRobin { children, slot, .. } => {
                // a RoundRobin that needs no flow: wrapping, and with one
                // child or executed once per run (index 0: a Fallback)
                if copy.is_some() && children.len() > 1 {
                    return Err(NotPrimitive {
                        node: id,
                        reason: "it lies in a PipelineSequence child that runs again while the \
                                 later children run, so it is executed several times per run \
                                 and starts each time after the child that last succeeded: its \
                                 start index depends on the earlier executions, which the \
                                 analysis cannot follow yet"
                            .into(),
                    });
                }
                if children.len() > 1 {
                    if let Some(why) = repeated(tree, id, *slot) {
                        return Err(NotPrimitive {
                            node: id,
                            reason: format!(
                                "it is executed several times per run ({why}) and starts each \
                                 time after the child that last succeeded: its start index \
                                 depends on the earlier executions, which the analysis cannot \
                                 follow yet"
                            ),
                        });
                    }
                }
                NodeKind::Fallback {
                    children: children.clone(),
                }
            }
            NodeKind::SequenceWithMemory { children, slot, .. } => {
                // one whose index needs no flow: it starts at 0 whenever it
                // runs (module docs of `index_roots`)
                if memory_matters(tree, id)
                    && (copy.is_some() || repeated(tree, id, *slot).is_some())
                {
                    return Err(NotPrimitive {
                        node: id,
                        reason: "it runs again after a Failure (or a halt) and resumes at the \
                                 child where it stopped, inside a node whose runs the flow over \
                                 its index cannot follow (a PipelineSequence child that re-runs, \
                                 or a child of another node's index flow)"
                            .into(),
                    });
                }
                NodeKind::Sequence {
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
            other => other.clone(),
        };
        let me = self.push(name, path, parent, depth, kind, id)?;
        self.note(id, me, copy);
        let kids = node
            .kind
            .children()
            .iter()
            .map(|&c| self.node(c, Some(me), depth + 1, copy))
            .collect::<Result<Vec<_>, _>>()?;
        if !kids.is_empty() {
            self.set_children(me, kids);
        }
        Ok(me)
    }

    fn note(&mut self, id: NodeId, at: NodeId, copy: Option<&str>) {
        if copy.is_some() {
            self.copied[id] = true;
        } else {
            self.image[id] = at;
        }
    }

    /// The children of the Sequence `seq` that a pipeline `(children…)`
    /// becomes (see [`primitive_view`]).
    fn pipeline(
        &mut self,
        pipe: NodeId,
        children: &[NodeId],
        seq: NodeId,
        depth: usize,
        pipe_name: &str,
        copy: Option<&str>,
    ) -> Result<Vec<NodeId>, NotPrimitive> {
        let tree = self.tree;
        let mut kids = Vec::new();
        for (k, &c) in children.iter().enumerate() {
            let first = self.node(c, Some(seq), depth, copy)?;
            kids.push(first);
            if k + 1 == children.len() {
                break;
            }
            let cname = &tree.nodes[c].name;
            // what re-runs, and after which waits (the first, the later)
            let (rerun, wait) = match retick(tree, c) {
                Retick::Inert => continue,
                Retick::Restart => (c, None),
                Retick::Rate(period) => {
                    let NodeKind::Decorator { child, decorator } = tree.nodes[c].kind else {
                        unreachable!("Rate is a decorator")
                    };
                    // a SpeedController's first wait differs
                    let first = match decorator {
                        Decorator::Rate { first, .. } => first,
                        _ => period,
                    };
                    (child, Some((first, period)))
                }
                Retick::Fail => {
                    return Err(NotPrimitive {
                        node: pipe,
                        reason: format!(
                            "its child '{cname}' (SingleTrigger) returns Failure when ticked \
                             again while a later child runs, which the analysis does not model"
                        ),
                    })
                }
            };
            // Parallel{1, 1}(process, rest)
            let race_name = format!("{pipe_name}/after {cname}");
            let race_path = format!("{}/after {cname}", self.out[seq].path);
            let race = self.push(
                race_name.clone(),
                race_path.clone(),
                Some(seq),
                depth,
                NodeKind::Parallel {
                    success_threshold: 1,
                    failure_threshold: 1,
                    children: Vec::new(),
                },
                c,
            )?;
            kids.push(race);
            let pname = match copy {
                None => format!("{cname}/re-run"),
                Some(prefix) => format!("{prefix}/{cname}/re-run"),
            };
            // a first wait of its own: Sequence(first wait, first copy, loop)
            let outer = match wait {
                Some((first, period)) if first != period => {
                    let outer = self.push(
                        pname.clone(),
                        format!("{race_path}/re-run"),
                        Some(race),
                        depth + 1,
                        NodeKind::Sequence {
                            children: Vec::new(),
                        },
                        c,
                    )?;
                    let w = self.push(
                        format!("{pname}/first wait"),
                        format!("{race_path}/re-run/first wait"),
                        Some(outer),
                        depth + 2,
                        NodeKind::Action(super::Action {
                            ps: 1.0,
                            pf: 0.0,
                            success: Some(super::Duration::Fixed { time: first }),
                            failure: None,
                        }),
                        c,
                    )?;
                    let once = format!("{pname}/first");
                    let again = self.node(rerun, Some(outer), depth + 2, Some(&once))?;
                    Some((outer, vec![w, again]))
                }
                _ => None,
            };
            // the loop (below `outer` when there is one)
            let (lname, lpath, ld) = match &outer {
                Some(_) => (
                    format!("{pname}/loop"),
                    format!("{race_path}/re-run/loop"),
                    depth + 2,
                ),
                None => (pname.clone(), format!("{race_path}/re-run"), depth + 1),
            };
            let process = self.push(
                lname,
                lpath.clone(),
                Some(outer.as_ref().map_or(race, |o| o.0)),
                ld,
                NodeKind::Decorator {
                    decorator: Decorator::UntilFailure,
                    child: usize::MAX,
                },
                c,
            )?;
            let body = match wait {
                None => self.node(rerun, Some(process), ld + 1, Some(&pname))?,
                Some((_, period)) => {
                    let cycle = self.push(
                        format!("{pname}/cycle"),
                        format!("{lpath}/cycle"),
                        Some(process),
                        ld + 1,
                        NodeKind::Sequence {
                            children: Vec::new(),
                        },
                        c,
                    )?;
                    let w = self.push(
                        format!("{pname}/wait"),
                        format!("{lpath}/wait"),
                        Some(cycle),
                        ld + 2,
                        NodeKind::Action(super::Action {
                            ps: 1.0,
                            pf: 0.0,
                            success: Some(super::Duration::Fixed { time: period }),
                            failure: None,
                        }),
                        c,
                    )?;
                    let again = self.node(rerun, Some(cycle), ld + 2, Some(&pname))?;
                    self.set_children(cycle, vec![w, again]);
                    cycle
                }
            };
            self.set_children(process, vec![body]);
            let process = match outer {
                Some((outer, mut kids)) => {
                    kids.push(process);
                    self.set_children(outer, kids);
                    outer
                }
                None => process,
            };
            let rest = self.push(
                format!("{race_name}/rest"),
                format!("{race_path}/rest"),
                Some(race),
                depth + 1,
                NodeKind::Sequence {
                    children: Vec::new(),
                },
                c,
            )?;
            self.set_children(race, vec![process, rest]);
            let rest_kids =
                self.pipeline(pipe, &children[k + 1..], rest, depth + 2, pipe_name, copy)?;
            self.set_children(rest, rest_kids);
            return Ok(kids);
        }
        Ok(kids)
    }
}

/// Most re-runs in the series of a re-run process the engine sums as a
/// series (its truncated series costs about K³: K = 100 about 1 s); a
/// longer one's race is taken from the process's levels or its composed
/// law (`crate::compile::race`, `crate::compile::plan`). Never a refusal:
/// every such race is analysed.
pub const MAX_RERUN_TERMS: usize = 100;

/// Why the RoundRobin `id` may run more than once per run of the root, if it
/// may: another node shares its index (a copy made by a RecoveryNode), or an
/// ancestor repeats its child.
fn repeated(tree: &Tree, id: NodeId, slot: usize) -> Option<String> {
    if let Some(other) = tree
        .nodes
        .iter()
        .enumerate()
        .find(|(o, n)| *o != id && slot_of(&n.kind) == Some(slot))
    {
        return Some(format!("'{}' is a copy of it", other.1.name));
    }
    repeating_ancestor(tree, id)
        .map(|a| format!("its ancestor '{}' repeats it", tree.nodes[a].name))
}

/// The index slot of a RoundRobin or SequenceWithMemory (the xml front
/// end gives the two kinds distinct slots).
fn slot_of(kind: &NodeKind) -> Option<usize> {
    match kind {
        NodeKind::RoundRobin { slot, .. } | NodeKind::SequenceWithMemory { slot, .. } => {
            Some(*slot)
        }
        _ => None,
    }
}

/// Whether the index of the SequenceWithMemory `id` may be other than 0
/// when it starts a run: a Failure of a child after the first keeps the
/// index there, and so does a halt while such a child runs in BT.CPP v4
/// (a Parallel or PipelineSequence above it may halt it; v3's halt resets
/// the index). Otherwise each run starts at 0 and it is a Sequence.
fn memory_matters(tree: &Tree, id: NodeId) -> bool {
    let NodeKind::SequenceWithMemory {
        children,
        halt_resets,
        ..
    } = &tree.nodes[id].kind
    else {
        return false;
    };
    if children.len() < 2 {
        return false;
    }
    let fails = children[1..].iter().any(|&c| outcomes(tree, c).1);
    let mut halted = false;
    let mut up = tree.nodes[id].parent;
    while let Some(a) = up {
        halted |= matches!(
            tree.nodes[a].kind,
            NodeKind::Parallel { .. } | NodeKind::Pipeline { .. }
        );
        up = tree.nodes[a].parent;
    }
    fails || (halted && !halt_resets)
}

/// The most states of the flow that follows a RoundRobin's index.
pub(crate) const MAX_INDEX_STATES: usize = 1 << 16;

/// The RoundRobins that need a flow over their index, each by the node
/// that becomes that flow: the lowest common ancestor of the copies of one
/// RoundRobin (the RecoveryNode whose retries copied it, or the RoundRobin
/// itself when it has one copy). A RoundRobin needs one when its start
/// index matters: without `wrap_around` (the last child's Success is a
/// Failure), or with several copies (they share one index) and more than
/// one child.
fn index_roots(tree: &Tree) -> Result<HashMap<NodeId, usize>, NotPrimitive> {
    // (slot, copies, needs no flow when executed once, children, index
    // matters at all)
    let mut copies: Vec<(usize, Vec<NodeId>, bool, usize, bool)> = Vec::new();
    for (id, n) in tree.nodes.iter().enumerate() {
        let (slot, once_free, m, matters) = match &n.kind {
            NodeKind::RoundRobin {
                children,
                wrap,
                slot,
            } => (*slot, *wrap, children.len(), true),
            NodeKind::SequenceWithMemory { children, slot, .. } => {
                (*slot, true, children.len(), memory_matters(tree, id))
            }
            _ => continue,
        };
        match copies.iter_mut().find(|c| c.0 == slot) {
            Some(c) => {
                c.1.push(id);
                c.4 |= matters;
            }
            None => copies.push((slot, vec![id], once_free, m, matters)),
        }
    }
    let mut roots: HashMap<NodeId, usize> = HashMap::new();
    for (slot, ids, once_free, m, matters) in copies {
        let robin = matches!(tree.nodes[ids[0]].kind, NodeKind::RoundRobin { .. });
        let mut root = ids[1..]
            .iter()
            .fold(ids[0], |a, &b| common_ancestor(tree, a, b));
        // a SequenceWithMemory's index carries over the runs of a
        // RetryUntilSuccessful or Repeat above it: the flow starts there
        while let Some(a) = repeating_ancestor(tree, root).filter(|_| !robin) {
            match tree.nodes[a].kind {
                NodeKind::Decorator {
                    decorator: Decorator::Retry { .. } | Decorator::Repeat { .. },
                    ..
                } => root = a,
                _ => break,
            }
        }
        let once = ids.len() == 1 && root == ids[0];
        if !matters || (once_free && (once || m == 1)) {
            continue;
        }
        if let Some(why) = ancestor_repeats(tree, root) {
            return Err(NotPrimitive {
                node: ids[0],
                reason: if robin {
                    format!(
                        "{why}, and the RoundRobin starts each time after the child that last \
                         succeeded: its start index depends on the earlier executions, which the \
                         analysis follows only within one execution of '{}'",
                        tree.nodes[root].name
                    )
                } else {
                    format!(
                        "{why}, and the SequenceWithMemory resumes at the child where it \
                         stopped (after a Failure, or a halt): its start index depends on the \
                         earlier executions, which the analysis follows only within one \
                         execution of '{}' (a RecoveryNode's retries, or a RetryUntilSuccessful \
                         directly above it)",
                        tree.nodes[root].name
                    )
                },
            });
        }
        if roots.insert(root, slot).is_some() {
            return Err(NotPrimitive {
                node: ids[0],
                reason: "another RoundRobin's or SequenceWithMemory's copies have the same \
                         lowest common ancestor; the analysis follows one index per node"
                    .into(),
            });
        }
    }
    // one index per flow: no flow root inside another
    for &r in roots.keys() {
        let mut up = tree.nodes[r].parent;
        while let Some(a) = up {
            if roots.contains_key(&a) {
                return Err(NotPrimitive {
                    node: r,
                    reason: format!(
                        "its RoundRobin's index and the index of a RoundRobin around it \
                         (below '{}') would both have to be followed; the analysis follows one \
                         at a time",
                        tree.nodes[a].name
                    ),
                });
            }
            up = tree.nodes[a].parent;
        }
    }
    Ok(roots)
}

/// The lowest common ancestor of `a` and `b`.
fn common_ancestor(tree: &Tree, a: NodeId, b: NodeId) -> NodeId {
    let mut seen = std::collections::HashSet::new();
    let mut x = Some(a);
    while let Some(n) = x {
        seen.insert(n);
        x = tree.nodes[n].parent;
    }
    let mut y = b;
    while !seen.contains(&y) {
        y = tree.nodes[y].parent.unwrap_or(Tree::ROOT);
    }
    y
}

/// Why node `id` may run more than once per run of the root (an ancestor
/// repeats it), if it may.
fn ancestor_repeats(tree: &Tree, id: NodeId) -> Option<String> {
    repeating_ancestor(tree, id).map(|a| {
        format!(
            "'{}' runs several times per run: its ancestor '{}' repeats it",
            tree.nodes[id].name, tree.nodes[a].name
        )
    })
}

/// The nearest ancestor of `id` that may run it more than once per run of
/// the root: a flow visiting it from several states, a Retry or Repeat of
/// more than one, a loop without a bound.
fn repeating_ancestor(tree: &Tree, id: NodeId) -> Option<NodeId> {
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
            return Some(a);
        }
        (below, up) = (a, tree.nodes[a].parent);
    }
    None
}

/// The states of a flow over a RoundRobin's index, built backwards (every
/// edge goes to a state built earlier); `child` holds the original node.
struct IndexFlow<'a> {
    tree: &'a Tree,
    /// The RoundRobin's slot.
    slot: usize,
    /// `onpath[k]`: node `root + k` holds a copy of the RoundRobin.
    onpath: Vec<bool>,
    root: NodeId,
    states: Vec<FlowState>,
    known: HashMap<StateKey, usize>,
}

/// A state by its child and its two edges (see [`edge_key`]).
type StateKey = (NodeId, (u8, usize), (u8, usize));

fn edge_key(n: FlowNext) -> (u8, usize) {
    match n {
        FlowNext::State(s) => (0, s),
        FlowNext::Success => (1, 0),
        FlowNext::Failure => (2, 0),
    }
}

impl IndexFlow<'_> {
    /// A state running original node `child` (shared with an identical one).
    fn state(
        &mut self,
        child: NodeId,
        on_success: FlowNext,
        on_failure: FlowNext,
    ) -> Result<FlowNext, NotPrimitive> {
        let key = (child, edge_key(on_success), edge_key(on_failure));
        if let Some(&s) = self.known.get(&key) {
            return Ok(FlowNext::State(s));
        }
        if self.states.len() >= MAX_INDEX_STATES {
            return Err(NotPrimitive {
                node: self.root,
                reason: format!(
                    "following its RoundRobin's index takes more than {MAX_INDEX_STATES} flow \
                     states"
                ),
            });
        }
        self.states.push(FlowState {
            child,
            on_success,
            on_failure,
        });
        self.known.insert(key, self.states.len() - 1);
        Ok(FlowNext::State(self.states.len() - 1))
    }

    /// The entry of node `id` for each start index, given where its
    /// Success (`ks[i]`) and Failure (`kf[i]`) lead with the index then `i`.
    fn entries(
        &mut self,
        id: NodeId,
        ks: &[FlowNext],
        kf: &[FlowNext],
    ) -> Result<Vec<FlowNext>, NotPrimitive> {
        let m = ks.len();
        if !self.onpath[id - self.root] {
            // the index does not change: one state per distinct continuation
            return (0..m).map(|i| self.state(id, ks[i], kf[i])).collect();
        }
        let refuse = |why: &str| NotPrimitive {
            node: id,
            reason: format!(
                "it holds a copy of a RoundRobin or SequenceWithMemory whose index the \
                 analysis follows through Sequences, Fallbacks, that node, one-run decorators, \
                 RetryUntilSuccessful and Repeat only; {why}"
            ),
        };
        match &self.tree.nodes[id].kind {
            NodeKind::Sequence { children } => {
                let mut cont = ks.to_vec();
                for &c in children.iter().rev() {
                    cont = self.entries(c, &cont, kf)?;
                }
                Ok(cont)
            }
            NodeKind::Fallback { children } => {
                let mut cont = kf.to_vec();
                for &c in children.iter().rev() {
                    cont = self.entries(c, ks, &cont)?;
                }
                Ok(cont)
            }
            NodeKind::Decorator { decorator, child } => match decorator.as_primitive() {
                Decorator::Inverter => self.entries(*child, kf, ks),
                Decorator::ForceSuccess => self.entries(*child, ks, ks),
                Decorator::ForceFailure => self.entries(*child, kf, kf),
                // BT.CPP's RetryNode and RepeatNode reset a child that
                // returned without halting it: its index carries over to
                // the next attempt
                Decorator::Retry { attempts } => {
                    let mut cont = kf.to_vec();
                    for _ in 0..attempts {
                        cont = self.entries(*child, ks, &cont)?;
                    }
                    Ok(cont)
                }
                Decorator::Repeat { times } => {
                    let mut cont = ks.to_vec();
                    for _ in 0..times {
                        cont = self.entries(*child, &cont, kf)?;
                    }
                    Ok(cont)
                }
                _ => Err(refuse("this decorator repeats it")),
            },
            NodeKind::RoundRobin {
                children,
                wrap,
                slot,
            } if *slot == self.slot => {
                // Nav2's round_robin_node.cpp: the index moves past every
                // child that returns; a Success returns Success with the
                // index after that child; all failed (and, without wrap,
                // passing the last child whatever its status) → Failure,
                // index 0
                let mut out = Vec::with_capacity(m);
                for start in 0..m {
                    let mut next = kf[0];
                    let order: Vec<usize> = if *wrap {
                        (0..m).map(|t| (start + t) % m).collect()
                    } else {
                        (start..m).collect()
                    };
                    for &j in order.iter().rev() {
                        let on_success = if j + 1 < m {
                            ks[j + 1]
                        } else if *wrap {
                            ks[0]
                        } else {
                            kf[0]
                        };
                        next = self.state(children[j], on_success, next)?;
                    }
                    out.push(next);
                }
                Ok(out)
            }
            NodeKind::SequenceWithMemory { children, slot, .. } if *slot == self.slot => {
                // BT.CPP's sequence_with_memory_node.cpp: from the kept
                // index, child j's Failure returns Failure with the index
                // left at j, its Success moves on; the last child's Success
                // returns Success with the index back at 0
                let mut out = Vec::with_capacity(m);
                let mut next = ks[0];
                let mut chain = vec![ks[0]; m];
                for j in (0..m).rev() {
                    next = self.state(children[j], next, kf[j])?;
                    chain[j] = next;
                }
                out.extend(chain);
                Ok(out)
            }
            NodeKind::RoundRobin { .. } => Err(refuse("another RoundRobin holds it")),
            NodeKind::SequenceWithMemory { .. } => {
                Err(refuse("another SequenceWithMemory holds it"))
            }
            NodeKind::Parallel { .. } => Err(refuse("a Parallel holds it")),
            NodeKind::Pipeline { .. } => Err(refuse("a PipelineSequence holds it")),
            NodeKind::Flow(_) => Err(refuse("a flow (IfThenElse, Switch, ...) holds it")),
            NodeKind::Action(_) | NodeKind::Condition { .. } => {
                unreachable!("a leaf holds no RoundRobin")
            }
        }
    }
}

impl Lowering<'_> {
    /// Node `id`, the lowest common ancestor of the copies of RoundRobin
    /// `slot`, as one flow over (place in `id`'s run, RoundRobin index):
    /// its children are the subtrees without a copy (the RecoveryNode's
    /// main-branch copies, the conditions around the RoundRobin, ...) and
    /// the RoundRobin copies' children; the nodes between them (the
    /// RecoveryNode's Fallbacks and Sequences, the RoundRobin copies) have
    /// no run of their own in the flow and stand for the flow's.
    #[allow(clippy::too_many_arguments)]
    fn index_flow(
        &mut self,
        id: NodeId,
        slot: usize,
        parent: Option<NodeId>,
        depth: usize,
        copy: Option<&str>,
        name: String,
        path: String,
    ) -> Result<NodeId, NotPrimitive> {
        let tree = self.tree;
        if copy.is_some() {
            return Err(NotPrimitive {
                node: id,
                reason: "it lies in a PipelineSequence child that runs again while the later \
                         children run, and holds a RoundRobin whose index carries over from one \
                         run to the next, which the analysis cannot follow yet"
                    .into(),
            });
        }
        let range = tree.subtree(id);
        let holds = |n: NodeId| {
            tree.subtree(n)
                .any(|k| slot_of(&tree.nodes[k].kind) == Some(slot))
        };
        let onpath: Vec<bool> = range.clone().map(holds).collect();
        let m = tree
            .subtree(id)
            .find(|&k| slot_of(&tree.nodes[k].kind) == Some(slot))
            .map(|k| tree.nodes[k].kind.children().len())
            .unwrap_or(1);
        let mut flow = IndexFlow {
            tree,
            slot,
            onpath,
            root: id,
            states: Vec::new(),
            known: HashMap::new(),
        };
        let entry = flow.entries(id, &vec![FlowNext::Success; m], &vec![FlowNext::Failure; m])?[0];
        let FlowNext::State(first) = entry else {
            unreachable!("a node runs at least one state")
        };
        // the states reachable from the entry; every edge goes to a state
        // built earlier, so the reverse of the building order is a
        // topological order
        let mut reach = vec![false; flow.states.len()];
        let mut stack = vec![first];
        while let Some(s) = stack.pop() {
            if std::mem::replace(&mut reach[s], true) {
                continue;
            }
            for next in [flow.states[s].on_success, flow.states[s].on_failure] {
                if let FlowNext::State(t) = next {
                    stack.push(t);
                }
            }
        }
        let order: Vec<usize> = (0..flow.states.len()).rev().filter(|&s| reach[s]).collect();
        let mut number = vec![usize::MAX; flow.states.len()];
        for (k, &s) in order.iter().enumerate() {
            number[s] = k;
        }
        let mut kids: Vec<NodeId> = order.iter().map(|&s| flow.states[s].child).collect();
        kids.sort_unstable();
        kids.dedup();
        // a child that several states run must keep no memory of its own
        for &c in &kids {
            if let Some(r) = tree.subtree(c).find(|&k| match &tree.nodes[k].kind {
                NodeKind::RoundRobin { children, .. } => children.len() > 1,
                NodeKind::SequenceWithMemory { .. } => memory_matters(tree, k),
                _ => false,
            }) {
                return Err(NotPrimitive {
                    node: r,
                    reason: format!(
                        "it lies in '{}', which the flow following the index of another \
                         RoundRobin (in '{}') may run several times, and its own index would \
                         carry over",
                        tree.nodes[c].name, tree.nodes[id].name
                    ),
                });
            }
        }
        let renumber = |n: FlowNext| match n {
            FlowNext::State(s) => FlowNext::State(number[s]),
            other => other,
        };
        let states: Vec<FlowState> = order
            .iter()
            .map(|&s| {
                let st = flow.states[s];
                FlowState {
                    child: kids.binary_search(&st.child).unwrap_or(usize::MAX),
                    on_success: renumber(st.on_success),
                    on_failure: renumber(st.on_failure),
                }
            })
            .collect();
        let me = self.push(
            name,
            path,
            parent,
            depth,
            NodeKind::Flow(Flow {
                children: Vec::new(),
                states: Vec::new(),
            }),
            id,
        )?;
        let mut lowered = Vec::with_capacity(kids.len());
        for &c in &kids {
            lowered.push(self.node(c, Some(me), depth + 1, None)?);
        }
        let built = Flow::new(lowered, states).map_err(|e| NotPrimitive {
            node: id,
            reason: format!("internal error: the flow over its RoundRobin's index: {e}"),
        })?;
        self.out[me].kind = NodeKind::Flow(built);
        // the nodes between the flow and its children have no run of their
        // own: they stand for the flow
        for k in range {
            if self.image[k] == usize::MAX {
                self.image[k] = me;
            }
        }
        Ok(me)
    }
}
