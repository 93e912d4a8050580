//! Mapping the status changes of a Nav2 `behavior_tree_log` onto the nodes
//! of the tree given with `--tree`, and turning them into leaf episodes
//! exactly as for a `.btlog` ([`super::btlog::step`]).
//!
//! **Node numbering.** BehaviorTree.CPP gives every node of a tree a uid
//! when it instantiates it: `config.uid = output_tree.getUID()` in
//! `XMLParser::PImpl::createNodeFromXML` (`src/xml_parsing.cpp`), the counter
//! starting at 1, and `recursivelyCreateSubtree` creates a node before its
//! children, in document order, and a SubTree node before the nodes of the
//! tree it includes. So the uids are the preorder (depth-first) positions of
//! the main tree's nodes, SubTrees expanded, from 1. A node's name is its
//! `name` attribute, else its registration ID.
//!
//! **With `uid`** every change names its node; the node's name must be the
//! change's `node_name` (otherwise `--tree` is not the tree that ran).
//!
//! **Without `uid`** (bags before 2023) a change names its node only by
//! `node_name`, and names repeat (Nav2's trees name a RecoveryNode
//! `ComputePathToPose` around the action `ComputePathToPose`). The change
//! sequence is replayed against the tree: each node's status is tracked, and
//! a change goes to the node of that name whose tracked status is the
//! change's `previous_status` — or, in this order of preference, one that
//! was reset to IDLE unlogged (SUCCESS/FAILURE → IDLE), one halted unlogged
//! (RUNNING → IDLE), one never seen before (the recording began mid-run).
//! Among equals, the tree's structure decides: a node leaving RUNNING has no
//! RUNNING descendant (BT.CPP halts or finishes the children first); a node
//! starting has no equal-named ancestor that is not yet running (a child is
//! ticked by its running parent); a node reset to IDLE has no active
//! descendant; then the node with the fewest ancestors not RUNNING (BT.CPP 3
//! control nodes such as ReactiveFallback log their own RUNNING only after
//! their children's changes). Two nodes still equal are a located error
//! naming them.
//!
//! **Unlogged transitions.** Nav2 before BT.CPP 4 (Humble) logs no transition
//! to IDLE except the root's: BT.CPP 3's `resetStatus()` does not notify the
//! loggers. So when a node stops running (SUCCESS, FAILURE or IDLE), its
//! descendants still tracked RUNNING were halted at that moment (censored
//! then) and all its descendants are IDLE again. A node seen starting again
//! while still tracked RUNNING with no such event was halted unlogged: it is
//! censored at the last time it was known to be running (its start, or the
//! last logged change of one of its descendants).
//!
//! **Time.** Durations are differences of the changes' own timestamps (ns).

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use super::btlog::{step, Node, Status, BUILTIN_LEAVES, MAX_STEP_BACK_US};
use super::{Declared, End, Episode, LeafLog, Log, LogError, LogHint};
use crate::tree::xml::{scan_elements, XmlElement};

/// One status change of a `BehaviorTreeLog` message.
#[derive(Clone, Debug, PartialEq)]
pub struct Change {
    /// The change's own timestamp, ns since the epoch.
    pub t_ns: i64,
    pub name: String,
    pub uid: Option<u16>,
    pub(super) prev: Status,
    pub(super) cur: Status,
}

/// A node of the tree, with its replay state.
struct TNode {
    node: Node,
    name: String,
    id: String,
    parent: Option<usize>,
    /// One past the index of its last descendant (preorder).
    end: usize,
    /// `FILE line L column C`.
    place: String,
    /// A change of it has been seen.
    seen: bool,
    /// Its running episode's start is known (false when the recording began
    /// while it was running).
    start_known: bool,
    /// The last time (ns from the first change) it was known to be running.
    alive: u64,
}

/// The tree of `--tree`, numbered as BT.CPP numbers it.
pub(super) struct BagTree {
    nodes: Vec<TNode>,
    leaves: Vec<LeafLog>,
    by_name: HashMap<String, Vec<usize>>,
    file: String,
}

const MAX_DEPTH: usize = 256;

impl BagTree {
    /// Reads the tree file (and `includes`, which may define SubTrees).
    pub(super) fn load(tree: &Path, includes: &[PathBuf]) -> Result<BagTree, LogError> {
        let file = tree.display().to_string();
        let mut docs: Vec<(String, Vec<XmlElement>)> = Vec::new();
        for p in std::iter::once(&tree.to_path_buf()).chain(includes) {
            let f = p.display().to_string();
            let text = std::fs::read_to_string(p)
                .map_err(|e| LogError::new(&f, None, format!("cannot read the tree: {e}")))?;
            let elems = scan_elements(&text, &f).map_err(|e| {
                LogError::new(
                    &f,
                    Some(format!("line {} column {}", e.line, e.column)),
                    e.message.clone(),
                )
            })?;
            docs.push((f, elems));
        }
        // the trees by ID, and the declared kinds of IDs
        let mut trees: HashMap<String, (usize, usize)> = HashMap::new();
        let mut order: Vec<String> = Vec::new();
        let mut declared: HashMap<String, Declared> = HashMap::new();
        for (d, (_, elems)) in docs.iter().enumerate() {
            for (i, e) in elems.iter().enumerate() {
                if e.name == "BehaviorTree" {
                    let id = e.attr("ID").unwrap_or("").to_string();
                    if !trees.contains_key(&id) {
                        order.push(id.clone());
                    }
                    trees.insert(id, (d, i));
                }
                if e.name == "TreeNodesModel" {
                    for &c in &e.children {
                        let m = &elems[c];
                        if let Some(id) = m.attr("ID") {
                            match m.name.as_str() {
                                "Action" => declared.insert(id.to_string(), Declared::Action),
                                "Condition" => declared.insert(id.to_string(), Declared::Condition),
                                _ => None,
                            };
                        }
                    }
                }
            }
        }
        let root = &docs[0].1;
        let main = root
            .first()
            .and_then(|r| r.attr("main_tree_to_execute"))
            .map(str::to_string);
        let main = match main {
            Some(m) => m,
            None if order.len() == 1 => order[0].clone(),
            None => {
                return Err(LogError::new(
                    &file,
                    None,
                    format!(
                        "{} BehaviorTree elements and no main_tree_to_execute: which one ran?",
                        order.len()
                    ),
                ))
            }
        };
        let Some(&(d, i)) = trees.get(&main) else {
            return Err(LogError::new(
                &file,
                None,
                format!("there is no <BehaviorTree ID=\"{main}\">"),
            ));
        };
        let mut t = BagTree {
            nodes: Vec::new(),
            leaves: Vec::new(),
            by_name: HashMap::new(),
            file: file.clone(),
        };
        let (df, elems) = &docs[d];
        let Some(&first) = elems[i].children.first() else {
            return Err(LogError::new(
                df,
                Some(format!("line {} column {}", elems[i].line, elems[i].column)),
                format!("<BehaviorTree ID=\"{main}\"> is empty"),
            ));
        };
        let mut stack = vec![main.clone()];
        t.add(&docs, &trees, &declared, d, first, None, &mut stack)?;
        if t.nodes.len() > usize::from(u16::MAX) {
            return Err(LogError::new(
                &file,
                None,
                format!(
                    "the tree has {} nodes, more than BT.CPP's 16-bit uids number",
                    t.nodes.len()
                ),
            ));
        }
        Ok(t)
    }

    #[allow(clippy::too_many_arguments)]
    fn add(
        &mut self,
        docs: &[(String, Vec<XmlElement>)],
        trees: &HashMap<String, (usize, usize)>,
        declared: &HashMap<String, Declared>,
        d: usize,
        i: usize,
        parent: Option<usize>,
        stack: &mut Vec<String>,
    ) -> Result<(), LogError> {
        let (f, elems) = &docs[d];
        let e = &elems[i];
        let place = format!("{f} line {} column {}", e.line, e.column);
        if stack.len() > MAX_DEPTH {
            return Err(LogError::new(
                f,
                Some(format!("line {} column {}", e.line, e.column)),
                format!("the tree nests deeper than {MAX_DEPTH} levels"),
            ));
        }
        let explicit = matches!(
            e.name.as_str(),
            "Action" | "Condition" | "Control" | "Decorator"
        );
        let subtree = matches!(
            e.name.as_str(),
            "SubTree" | "SubTreePlus" | "SubTreeWrapper"
        );
        let id = if explicit || subtree {
            e.attr("ID").unwrap_or(&e.name).to_string()
        } else {
            e.name.clone()
        };
        let name = e.attr("name").unwrap_or(&id).to_string();
        let idx = self.nodes.len();
        let uid = idx + 1;
        let is_leaf = e.children.is_empty() && !subtree && !BUILTIN_LEAVES.contains(&id.as_str());
        let leaf = if is_leaf {
            let dec = match e.name.as_str() {
                "Action" => Declared::Action,
                "Condition" => Declared::Condition,
                _ => declared.get(&id).copied().unwrap_or(Declared::Unknown),
            };
            self.leaves.push(LeafLog {
                id: id.clone(),
                name: e.attr("name").map(str::to_string),
                declared: dec,
                episodes: Vec::new(),
            });
            Some(self.leaves.len() - 1)
        } else {
            None
        };
        let label = if name != id {
            format!("node {uid} (`{name}`, {id}, {place})")
        } else {
            format!("node {uid} ({id}, {place})")
        };
        self.nodes.push(TNode {
            node: Node {
                leaf,
                status: Status::Idle,
                started: 0,
                label,
            },
            name: name.clone(),
            id: id.clone(),
            parent,
            end: idx + 1,
            place,
            seen: false,
            start_known: true,
            alive: 0,
        });
        self.by_name.entry(name).or_default().push(idx);
        if subtree {
            let Some(&(sd, si)) = trees.get(&id) else {
                return Err(LogError::new(
                    f,
                    Some(format!("line {} column {}", e.line, e.column)),
                    format!(
                        "SubTree `{id}` is not defined in the tree file{}",
                        if docs.len() > 1 {
                            " nor in the included files"
                        } else {
                            ""
                        }
                    ),
                )
                .with_hint(LogHint::DefineSubTree));
            };
            if stack.contains(&id) {
                return Err(LogError::new(
                    f,
                    Some(format!("line {} column {}", e.line, e.column)),
                    format!("SubTree `{id}` includes itself"),
                ));
            }
            if let Some(&c) = docs[sd].1[si].children.first() {
                stack.push(id);
                self.add(docs, trees, declared, sd, c, Some(idx), stack)?;
                stack.pop();
            }
        } else {
            for &c in &e.children {
                self.add(docs, trees, declared, d, c, Some(idx), stack)?;
            }
        }
        self.nodes[idx].end = self.nodes.len();
        Ok(())
    }
}

/// How a chosen node's tracked status relates to the change's previous
/// status: lower is better.
fn rank(n: &TNode, prev: Status) -> Option<u8> {
    use Status::*;
    let s = n.node.status;
    if s == prev {
        Some(0)
    } else if prev == Idle && matches!(s, Success | Failure | Skipped) {
        Some(1)
    } else if prev == Idle && s == Running {
        Some(2)
    } else if !n.seen && s == Idle {
        Some(3)
    } else {
        None
    }
}

fn text(s: Status) -> &'static str {
    match s {
        Status::Idle => "IDLE",
        Status::Running => "RUNNING",
        Status::Success => "SUCCESS",
        Status::Failure => "FAILURE",
        Status::Skipped => "SKIPPED",
    }
}

/// The replay of one bag's changes.
pub(super) struct Replay {
    tree: BagTree,
    bag: String,
    first: Option<i64>,
    last: u64,
    records: usize,
    out_of_order: usize,
    max_back: u64,
    truncated: usize,
    unlogged_halts: usize,
}

impl Replay {
    pub(super) fn new(tree: BagTree, bag: &str) -> Replay {
        Replay {
            tree,
            bag: bag.to_string(),
            first: None,
            last: 0,
            records: 0,
            out_of_order: 0,
            max_back: 0,
            truncated: 0,
            unlogged_halts: 0,
        }
    }

    /// Whether every change's uid names a node of the tree by its name
    /// (changes without uid: whether every name is in the tree).
    pub(super) fn uids_fit(&self, changes: &[Change]) -> bool {
        changes.iter().all(|c| match c.uid {
            Some(u) => usize::from(u)
                .checked_sub(1)
                .and_then(|i| self.tree.nodes.get(i))
                .is_some_and(|n| n.name == c.name),
            None => self.tree.by_name.contains_key(&c.name),
        })
    }

    fn err(&self, at: &dyn Fn() -> String, m: String) -> LogError {
        LogError::new(&self.bag, Some(at()), m)
    }

    fn is_ancestor(&self, a: usize, d: usize) -> bool {
        a < d && d < self.tree.nodes[a].end
    }

    /// The node a change without uid is for.
    fn choose(&self, c: &Change, at: &dyn Fn() -> String) -> Result<usize, LogError> {
        let nodes = &self.tree.nodes;
        let Some(named) = self.tree.by_name.get(&c.name) else {
            return Err(self.err(
                at,
                format!(
                    "no node of {} is named `{}`: is it the tree bt_navigator ran?",
                    self.tree.file, c.name
                ),
            ));
        };
        let ranked: Vec<(usize, u8)> = named
            .iter()
            .filter_map(|&i| rank(&nodes[i], c.prev).map(|r| (i, r)))
            .collect();
        let Some(best) = ranked.iter().map(|&(_, r)| r).min() else {
            return Err(self
                .err(
                    at,
                    format!(
                        "`{}` goes from {} to {}, but no node of that name can: {}",
                        c.name,
                        text(c.prev),
                        text(c.cur),
                        named
                            .iter()
                            .map(|&i| format!(
                                "{} is {}",
                                nodes[i].node.label,
                                text(nodes[i].node.status)
                            ))
                            .collect::<Vec<_>>()
                            .join("; ")
                    ),
                )
                .with_hint(LogHint::WrongTree));
        };
        let mut cands: Vec<usize> = ranked
            .iter()
            .filter(|&&(_, r)| r == best)
            .map(|&(i, _)| i)
            .collect();
        let keep = |cands: &mut Vec<usize>, f: &dyn Fn(usize) -> bool| {
            let kept: Vec<usize> = cands.iter().copied().filter(|&i| f(i)).collect();
            if !kept.is_empty() {
                *cands = kept;
            }
        };
        let active = |i: usize, s: &[Status]| {
            (i + 1..nodes[i].end).any(|d| s.contains(&nodes[d].node.status))
        };
        if cands.len() > 1 {
            if c.prev == Status::Running {
                keep(&mut cands, &|i| !active(i, &[Status::Running]));
            } else if c.cur != Status::Idle {
                let all = cands.clone();
                keep(&mut cands, &|i| {
                    !all.iter()
                        .any(|&a| self.is_ancestor(a, i) && nodes[a].node.status != Status::Running)
                });
            } else {
                keep(&mut cands, &|i| {
                    !active(
                        i,
                        &[
                            Status::Running,
                            Status::Success,
                            Status::Failure,
                            Status::Skipped,
                        ],
                    )
                });
            }
        }
        if cands.len() > 1 {
            // the fewest ancestors not running (a node is ticked by running
            // ancestors; some control nodes log their own RUNNING only after
            // their children's changes)
            let idle_above = |i: usize| {
                let mut n = 0;
                let mut p = nodes[i].parent;
                while let Some(a) = p {
                    n += usize::from(nodes[a].node.status != Status::Running);
                    p = nodes[a].parent;
                }
                n
            };
            let fewest = cands.iter().map(|&i| idle_above(i)).min().unwrap_or(0);
            keep(&mut cands, &|i| idle_above(i) == fewest);
        }
        if cands.len() > 1 {
            return Err(self.err(
                at,
                format!(
                    "`{}` ({} → {}) fits {} nodes of {} equally: {}; the bag has no uid to tell \
                     them apart: give them distinct `name` attributes (and record again), or \
                     record with a Nav2 whose messages carry `uid` (2023 and later)",
                    c.name,
                    text(c.prev),
                    text(c.cur),
                    cands.len(),
                    self.tree.file,
                    cands
                        .iter()
                        .map(|&i| format!(
                            "node {} ({}, {}, {})",
                            i + 1,
                            nodes[i].id,
                            nodes[i].place,
                            text(nodes[i].node.status)
                        ))
                        .collect::<Vec<_>>()
                        .join(", ")
                ),
            ));
        }
        Ok(cands[0])
    }

    fn push(&mut self, i: usize, e: Episode) {
        let n = &self.tree.nodes[i];
        if let Some(l) = n.node.leaf {
            if !e.instant && !n.start_known {
                self.truncated += 1;
            } else {
                self.tree.leaves[l].episodes.push(e);
            }
        }
    }

    /// Applies one change.
    pub(super) fn apply(&mut self, c: &Change, at: &dyn Fn() -> String) -> Result<(), LogError> {
        let first = *self.first.get_or_insert(c.t_ns);
        let rel = u64::try_from(i128::from(c.t_ns) - i128::from(first)).unwrap_or(0);
        if rel < self.last {
            let back = self.last - rel;
            if back > MAX_STEP_BACK_US * 1000 {
                return Err(self.err(
                    at,
                    format!(
                        "the change's timestamp goes back in time by {:.3} s: changes are out of \
                         order or the bag is mixed up",
                        back as f64 * 1e-9
                    ),
                ));
            }
            self.out_of_order += 1;
            self.max_back = self.max_back.max(back);
        }
        let now = rel.max(self.last);
        let idx = match c.uid {
            Some(uid) => {
                let Some(n) = usize::from(uid)
                    .checked_sub(1)
                    .filter(|&i| i < self.tree.nodes.len())
                else {
                    return Err(self.err(
                        at,
                        format!(
                            "node uid {uid} (`{}`) is not in {} (its uids are 1..{}, numbered \
                             depth-first as BT.CPP does): is it the tree bt_navigator ran?",
                            c.name,
                            self.tree.file,
                            self.tree.nodes.len()
                        ),
                    ));
                };
                if self.tree.nodes[n].name != c.name {
                    return Err(self.err(
                        at,
                        format!(
                            "node uid {uid} is `{}` in the bag but `{}` in {} ({}): \
                             is it the tree bt_navigator ran?",
                            c.name,
                            self.tree.nodes[n].name,
                            self.tree.file,
                            self.tree.nodes[n].place
                        ),
                    ));
                }
                n
            }
            None => self.choose(c, at)?,
        };
        let r = rank(&self.tree.nodes[idx], c.prev);
        match r {
            Some(0) => {}
            Some(1) => self.tree.nodes[idx].node.status = Status::Idle,
            Some(2) => {
                // halted without a logged change
                let n = &self.tree.nodes[idx];
                let e = Episode {
                    duration: n.alive.saturating_sub(n.node.started) as f64 * 1e-9,
                    end: End::Halted,
                    instant: false,
                };
                if n.node.leaf.is_some() {
                    self.unlogged_halts += 1;
                }
                self.push(idx, e);
                self.tree.nodes[idx].node.status = Status::Idle;
            }
            Some(_) => {
                let n = &mut self.tree.nodes[idx];
                n.node.status = c.prev;
                if c.prev == Status::Running {
                    n.start_known = false;
                    n.node.started = now;
                }
            }
            None => {
                let n = &self.tree.nodes[idx];
                return Err(self
                    .err(
                        at,
                        format!(
                            "{} goes from {} to {}, but the earlier changes left it {}",
                            n.node.label,
                            text(c.prev),
                            text(c.cur),
                            text(n.node.status)
                        ),
                    )
                    .with_hint(LogHint::WrongTree));
            }
        }
        let was = self.tree.nodes[idx].node.status;
        let episode = step(&mut self.tree.nodes[idx].node, c.cur, now, |d| {
            d as f64 * 1e-9
        })
        .map_err(|m| self.err(at, m))?;
        if let Some(e) = episode {
            self.push(idx, e);
        }
        {
            let n = &mut self.tree.nodes[idx];
            n.seen = true;
            if c.cur == Status::Running && was != Status::Running {
                n.start_known = true;
                n.alive = now;
            }
        }
        // its running ancestors were running now
        let mut p = self.tree.nodes[idx].parent;
        while let Some(a) = p {
            let n = &mut self.tree.nodes[a];
            if n.node.status == Status::Running {
                n.alive = now;
            }
            p = n.parent;
        }
        // a node that stops running has halted or reset its descendants
        if c.cur != Status::Running {
            for d in idx + 1..self.tree.nodes[idx].end {
                match self.tree.nodes[d].node.status {
                    Status::Running => {
                        let n = &self.tree.nodes[d];
                        let e = Episode {
                            duration: now.saturating_sub(n.node.started) as f64 * 1e-9,
                            end: End::Halted,
                            instant: false,
                        };
                        if n.node.leaf.is_some() {
                            self.unlogged_halts += 1;
                        }
                        self.push(d, e);
                        self.tree.nodes[d].node.status = Status::Idle;
                    }
                    Status::Idle => {}
                    _ => self.tree.nodes[d].node.status = Status::Idle,
                }
            }
        }
        self.last = now;
        self.records += 1;
        Ok(())
    }

    /// The log, and notes for the user.
    pub(super) fn finish(mut self) -> (Log, Vec<String>) {
        // still running when the recording ended: censored at its last change
        for i in 0..self.tree.nodes.len() {
            let n = &self.tree.nodes[i];
            if n.node.status == Status::Running {
                let e = Episode {
                    duration: self.last.saturating_sub(n.node.started) as f64 * 1e-9,
                    end: End::Halted,
                    instant: false,
                };
                self.push(i, e);
            }
        }
        let mut notes = Vec::new();
        if self.truncated > 0 {
            notes.push(format!(
                "{} episode(s) were running when the recording began (start unknown): not used",
                self.truncated
            ));
        }
        if self.unlogged_halts > 0 {
            notes.push(format!(
                "{} halt(s) inferred from the tree's structure (the bag logs no transition to \
                 IDLE for them): censored when the parent stopped running",
                self.unlogged_halts
            ));
        }
        (
            Log {
                file: self.bag,
                xml: None,
                leaves: self.tree.leaves,
                records: self.records,
                out_of_order: self.out_of_order,
                max_step_back: self.max_back as f64 * 1e-9,
                repeated_tail: 0,
            },
            notes,
        )
    }
}
