//! BT.CPP's ReactiveSequence / ReactiveFallback restart loop.
//!
//! When a child returns RUNNING, a reactive node halts every other child
//! (BT.CPP v4 `reactive_sequence.cpp`, `reactive_fallback.cpp`: `haltChild(i)`
//! for every `i != index`, which resets a child that has already returned to
//! IDLE) and at its next tick ticks the children from the first one again.
//! So when two children hold actions that take time, the first of them, `T1`,
//! is ticked again from IDLE while the second, `T2`, runs: `T1` starts a
//! fresh execution, returns RUNNING and halts `T2`. `T2` therefore never
//! completes: a ReactiveSequence runs fresh executions of `T1` until one
//! fails (its Failure) and never returns if `T1` cannot fail; a
//! ReactiveFallback runs them until one succeeds (its Success).
//!
//! With the children before `T1` (`P`) and between `T1` and `T2` (`Q`)
//! taking no time (conditions keep their value within the node's execution,
//! the SBT assumption), a ReactiveSequence is exactly
//! `Sequence(P…, T1, Q…, until_failure(T1′), T2, …)` (`T1′` a fresh copy of
//! `T1`; without `Q` the first run of `T1` is the loop's first run:
//! `Sequence(P…, until_failure(T1), T2, …)`) — the children after the loop
//! are never reached. A ReactiveFallback is the mirror image with
//! `until_success`. Exact when `T1` and `T2` return RUNNING at their first
//! tick with probability 1 ([`surely_timed`]); other cases are refused by
//! the caller.

use std::collections::{HashMap, HashSet};

use crate::tree::{Decorator, Duration, Node, NodeId, NodeKind, Tree};

/// How one reactive node is rewritten.
#[derive(Debug, Clone, Copy)]
pub(super) struct Restart {
    /// Position of `T1` among the node's children.
    pub first: usize,
    /// Position of `T2`.
    pub second: usize,
    /// ReactiveSequence (true) or ReactiveFallback.
    pub sequence: bool,
}

/// Whether an outcome time has no atom at 0 (the action returns RUNNING
/// at its first tick).
fn takes_time(d: &Duration) -> bool {
    match *d {
        Duration::Fixed { time } => time > 0.0,
        Duration::TruncatedExponential { cap, .. } => cap > 0.0,
        Duration::Exponential { .. } | Duration::PhaseType { .. } => true,
    }
}

/// Whether the subtree at `id` returns RUNNING at its first tick with
/// probability 1: an action whose every possible outcome takes time, or a
/// node whose first tick surely reaches such a subtree (the first child of
/// a Sequence, Fallback or flow, the child of a decorator, every child of a
/// Parallel, RoundRobin or PipelineSequence). Conservative: `false` may
/// also mean "not known".
pub(super) fn surely_timed(nodes: &[Node], id: NodeId) -> bool {
    match &nodes[id].kind {
        NodeKind::Action(a) => [(a.ps, a.success), (a.pf, a.failure)]
            .iter()
            .all(|&(p, d)| p <= 0.0 || d.is_some_and(|d| takes_time(&d))),
        NodeKind::Condition { .. } => false,
        NodeKind::Sequence { children } | NodeKind::Fallback { children } => {
            surely_timed(nodes, children[0])
        }
        NodeKind::Flow(f) => surely_timed(nodes, f.children[f.states[0].child]),
        NodeKind::Decorator { child, .. } => surely_timed(nodes, *child),
        // a SequenceWithMemory starts at its kept index: surely timed when
        // every child is
        NodeKind::Parallel { children, .. }
        | NodeKind::RoundRobin { children, .. }
        | NodeKind::SequenceWithMemory { children, .. }
        | NodeKind::Pipeline { children } => children.iter().all(|&c| surely_timed(nodes, c)),
    }
}

/// One child of a rewritten node.
enum Item {
    /// An existing subtree.
    Old(NodeId),
    /// `until_failure` / `until_success` over the subtree, or over a fresh
    /// copy of it (`true`).
    Loop(NodeId, bool),
}

struct Out<'a> {
    old: &'a Tree,
    keys: &'a [Option<String>],
    edits: &'a HashMap<NodeId, Restart>,
    nodes: Vec<Node>,
    new_keys: Vec<Option<String>>,
    names: HashSet<String>,
    max_nodes: usize,
    max_depth: usize,
}

impl Out<'_> {
    /// `name`, made unique among all names (old ones are reserved) when
    /// `fresh` (a copy or a loop node); an old node keeps its name.
    fn unique(&mut self, name: String, fresh: bool) -> String {
        if !fresh {
            return name;
        }
        let mut n = name.clone();
        let mut k = 2;
        while self.names.contains(&n) {
            n = format!("{name}#{k}");
            k += 1;
        }
        self.names.insert(n.clone());
        n
    }

    /// Appends `node` (its name made unique when `fresh`) with its params
    /// key.
    fn push(&mut self, mut node: Node, key: Option<String>, fresh: bool) -> Result<NodeId, String> {
        if self.nodes.len() >= self.max_nodes {
            return Err(format!(
                "the restart loops of its reactive nodes take more than {} nodes",
                self.max_nodes
            ));
        }
        if node.depth >= self.max_depth {
            return Err(format!(
                "the restart loops of its reactive nodes nest the tree more than {} levels deep",
                self.max_depth
            ));
        }
        node.name = self.unique(std::mem::take(&mut node.name), fresh);
        self.nodes.push(node);
        self.new_keys.push(key);
        Ok(self.nodes.len() - 1)
    }

    /// Emits the old subtree `src` (names prefixed with `prefix` for a copy)
    /// in pre-order; its new id.
    fn emit(
        &mut self,
        src: NodeId,
        prefix: &str,
        parent: Option<NodeId>,
        depth: usize,
        path: String,
    ) -> Result<NodeId, String> {
        let node = &self.old.nodes[src];
        let name = format!("{prefix}{}", node.name);
        let id = self.push(
            Node {
                name,
                path: path.clone(),
                depth,
                parent,
                kind: node.kind.clone(),
                location: node.location,
            },
            self.keys.get(src).cloned().flatten(),
            !prefix.is_empty(),
        )?;
        let children: Vec<NodeId> = node.kind.children().to_vec();
        let items: Vec<Item> = match self.edits.get(&src) {
            None => children.iter().map(|&c| Item::Old(c)).collect(),
            Some(r) => {
                let mut items = Vec::with_capacity(children.len() + 1);
                // without children between T1 and T2, T1's first run is
                // the loop's first run; otherwise the loop runs a copy
                let copy = r.second > r.first + 1;
                for (i, &c) in children.iter().enumerate() {
                    if i == r.first && !copy {
                        items.push(Item::Loop(c, false));
                        continue;
                    }
                    if i == r.second && copy {
                        items.push(Item::Loop(children[r.first], true));
                    }
                    items.push(Item::Old(c));
                }
                items
            }
        };
        let mut ids = Vec::with_capacity(items.len());
        for (k, item) in items.iter().enumerate() {
            let p = format!("{path}.{k}");
            let new = match *item {
                Item::Old(c) => self.emit(c, prefix, Some(id), depth + 1, p)?,
                Item::Loop(c, copy) => {
                    let sequence = self.edits[&src].sequence;
                    let own = self.nodes[id].name.clone();
                    let decorator = if sequence {
                        Decorator::UntilFailure
                    } else {
                        Decorator::UntilSuccess
                    };
                    let d = self.push(
                        Node {
                            name: format!("{own}/restarts"),
                            path: p.clone(),
                            depth: depth + 1,
                            parent: Some(id),
                            kind: NodeKind::Decorator {
                                decorator,
                                child: 0,
                            },
                            location: self.old.nodes[src].location,
                        },
                        None,
                        true,
                    )?;
                    let inner = if copy {
                        self.emit(c, &format!("{own}/restart/"), Some(d), depth + 2, p + ".0")?
                    } else {
                        self.emit(c, prefix, Some(d), depth + 2, p + ".0")?
                    };
                    if let NodeKind::Decorator { child, .. } = &mut self.nodes[d].kind {
                        *child = inner;
                    }
                    d
                }
            };
            ids.push(new);
        }
        match &mut self.nodes[id].kind {
            NodeKind::Sequence { children }
            | NodeKind::Fallback { children }
            | NodeKind::Pipeline { children }
            | NodeKind::RoundRobin { children, .. }
            | NodeKind::SequenceWithMemory { children, .. }
            | NodeKind::Parallel { children, .. } => *children = ids,
            NodeKind::Flow(f) => f.children = ids,
            NodeKind::Decorator { child, .. } => *child = ids[0],
            NodeKind::Action(_) | NodeKind::Condition { .. } => {}
        }
        Ok(id)
    }
}

/// The tree with every reactive node in `edits` rewritten as its restart
/// loop (module docs), and the params keys of its nodes (copies keep the
/// key of their original); or why not (too many nodes, too deep).
pub(super) fn rewrite(
    tree: &Tree,
    keys: &[Option<String>],
    edits: &HashMap<NodeId, Restart>,
    max_nodes: usize,
    max_depth: usize,
) -> Result<(Tree, Vec<Option<String>>), String> {
    let mut out = Out {
        old: tree,
        keys,
        edits,
        nodes: Vec::with_capacity(tree.nodes.len() + edits.len()),
        new_keys: Vec::with_capacity(tree.nodes.len() + edits.len()),
        // the old names are reserved for the nodes emitted under them
        names: tree.nodes.iter().map(|n| n.name.clone()).collect(),
        max_nodes,
        max_depth,
    };
    let root = out.emit_root()?;
    debug_assert_eq!(root, 0);
    Ok((
        Tree {
            title: tree.title.clone(),
            nodes: out.nodes,
        },
        out.new_keys,
    ))
}

impl Out<'_> {
    fn emit_root(&mut self) -> Result<NodeId, String> {
        self.emit(0, "", None, 0, "0".to_string())
    }
}
