//! BT.CPP nodes whose outcome comes from a predicate over the blackboard
//! (`Precondition`'s `if`) or from a queue (`LoopInt`, `LoopDouble`, ...).
//!
//! A predicate is a zero-time condition leaf named `<node>/<port>` (e.g.
//! `Precondition/if`): its `ps`, the probability that the predicate holds,
//! comes from the params file, keyed by the full name `<node>/<port>`, then
//! `<name attribute>/<port>`, then `<ID>/<port>`. Under the SBT assumption
//! the predicate keeps its value during the parent's run, so BT.CPP reading
//! it once (Precondition reads `if` only before the child starts) is exact.

use super::{Builder, Elem, Flow, FlowNext, FlowState, Leaf, LeafKind, NodeKind, TreeError};

/// Most elements of a literal loop queue (as `num_cycles`).
const MAX_QUEUE: usize = 1_000_000;

impl<'a> Builder<'a> {
    /// The condition leaf of predicate port `port` of `e` (type `ty`), below
    /// node `parent`. A literal `true` / `false` is a condition of ps 1 / 0
    /// without a params entry.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn predicate(
        &mut self,
        e: &Elem,
        ty: &str,
        port: &str,
        parent: usize,
        depth: usize,
        path: &str,
        prefix: &str,
    ) -> Result<usize, TreeError> {
        let name_attr = self.name_attr(e)?;
        let base = format!(
            "{}/{port}",
            name_attr.clone().unwrap_or_else(|| ty.to_string())
        );
        let constant = e.attr(port).and_then(|a| match a.value.trim() {
            "true" => Some(1.0),
            "false" => Some(0.0),
            _ => None,
        });
        if let Some(ps) = constant {
            let kind = NodeKind::Condition { ps };
            return self.push(e, &base, prefix, Some(parent), depth, path, kind);
        }
        let kind = NodeKind::Condition { ps: 0.0 };
        let node = self.push(e, &base, prefix, Some(parent), depth, path, kind)?;
        self.leaves.push(Leaf {
            node,
            kind: LeafKind::Condition,
            id: format!("{ty}/{port}"),
            name_attr: name_attr.map(|n| format!("{n}/{port}")),
            doc: e.doc,
        });
        Ok(node)
    }

    /// BT.CPP v4 `Precondition` (`script_precondition.h`): before its child
    /// starts it evaluates `if`; false → it returns `else` (default
    /// FAILURE) without ticking the child; true → it runs the child and
    /// returns its status. `else` = FAILURE is Sequence(if, child); SUCCESS
    /// is the flow if → (S: child, F: Success). RUNNING (returned again at
    /// every tick while the predicate keeps its value: it never finishes),
    /// SKIPPED (the parent's business) and a blackboard `else` are refused.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn precondition(
        &mut self,
        e: &'a Elem,
        ty: &str,
        parent: Option<usize>,
        depth: usize,
        path: &str,
        prefix: &str,
        retry: Option<&'static str>,
    ) -> Result<usize, TreeError> {
        self.one_child(e, ty)?;
        let base = self.name_attr(e)?.unwrap_or_else(|| ty.to_string());
        match e.attr("if") {
            Some(a) if a.value.trim().is_empty() => {
                return Err(self
                    .err(a.loc, format!("<{ty}> has an empty `if`"))
                    .with_help(
                        "write the predicate as a BT.CPP script, e.g. if=\"battery > 20\"",
                    ));
            }
            Some(_) => {}
            None => {
                return Err(self
                    .err(e.loc, format!("<{ty}> needs `if`"))
                    .with_help(format!(
                        "write <{ty} if=\"...\" else=\"FAILURE\">; the probability that `if` \
                         holds is the params entry `\"{base}/if\": {{ps: ...}}`"
                    )));
            }
        }
        let otherwise_success = match e.attr("else") {
            None => false,
            Some(a) => match a.value.trim() {
                "FAILURE" => false,
                "SUCCESS" => true,
                v @ ("RUNNING" | "SKIPPED") => {
                    let why = if v == "RUNNING" {
                        "a false `if` returns RUNNING at every tick, and the predicate keeps its \
                         value during the run: the node never finishes"
                    } else {
                        "a false `if` skips the node, which only its parent can interpret"
                    };
                    self.problem(
                        e.doc,
                        a.loc,
                        format!("<{ty}> with else=\"{v}\": {why}"),
                        true,
                    );
                    return self.placeholder(e, &base, parent, depth, path, prefix, retry);
                }
                v if v.starts_with('{') => {
                    self.problem(
                        e.doc,
                        a.loc,
                        format!(
                            "<{ty}> with else = \"{v}\", a blackboard reference: the status is \
                             only known at run time"
                        ),
                        true,
                    );
                    return self.placeholder(e, &base, parent, depth, path, prefix, retry);
                }
                v => {
                    return Err(self
                        .err(a.loc, format!("else = \"{v}\" is not a node status"))
                        .with_help(
                            "`else` is SUCCESS, FAILURE (the default), RUNNING or SKIPPED",
                        ));
                }
            },
        };
        let kind = if otherwise_success {
            NodeKind::Flow(Flow {
                children: Vec::new(),
                states: Vec::new(),
            })
        } else {
            NodeKind::Sequence {
                children: Vec::new(),
            }
        };
        let id = self.push(e, &base, prefix, parent, depth, path, kind)?;
        let cond = self.predicate(e, ty, "if", id, depth + 1, &format!("{path}.0"), prefix)?;
        let child = self.node(
            e.children[0],
            Some(id),
            depth + 1,
            format!("{path}.1"),
            prefix,
            retry,
        )?;
        if otherwise_success {
            let states = vec![
                FlowState {
                    child: 0,
                    on_success: FlowNext::State(1),
                    on_failure: FlowNext::Success,
                },
                FlowState {
                    child: 1,
                    on_success: FlowNext::Success,
                    on_failure: FlowNext::Failure,
                },
            ];
            self.nodes[id].kind = NodeKind::Flow(
                Flow::new(vec![cond, child], states).expect("a Precondition's flow is valid"),
            );
        } else {
            self.set_children(id, vec![cond, child]);
        }
        Ok(id)
    }

    /// BT.CPP v4 `LoopNode<T>` (`loop_node.h`) over a literal queue
    /// (`queue="1;2;3"`, read as BT.CPP's `splitString`: pieces between `;`,
    /// a trailing `;` adds none) or a blackboard queue whose length the
    /// params file gives (`"{name}": {value: N}`). It pops one element per
    /// child run: a child Failure is the node's Failure; when the queue is
    /// empty it returns `if_empty` (default SUCCESS). With n elements:
    /// SUCCESS → Repeat n; FAILURE → a flow running the child n times, then
    /// Failure; n = 0 → a condition of ps 1 / 0 (the child never runs, and
    /// is not built). `if_empty` = SKIPPED or from the blackboard is refused.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn loop_queue(
        &mut self,
        e: &'a Elem,
        ty: &str,
        parent: Option<usize>,
        depth: usize,
        path: &str,
        prefix: &str,
        retry: Option<&'static str>,
    ) -> Result<usize, TreeError> {
        self.one_child(e, ty)?;
        let base = self.name_attr(e)?.unwrap_or_else(|| ty.to_string());
        let Some(q) = e.attr("queue") else {
            return Err(self
                .err(e.loc, format!("<{ty}> needs `queue`"))
                .with_help(format!(
                    "write <{ty} queue=\"a;b;c\">, or a blackboard reference whose length the \
                     params file gives: `\"{{queue}}\": {{value: N}}`"
                )));
        };
        let n = if q.value.trim().starts_with('{') {
            if self.unresolved(&q.value) {
                let v = q.value.trim();
                self.problem(
                    e.doc,
                    q.loc,
                    format!(
                        "<{ty}> with queue = \"{v}\", a blackboard reference: its length is only \
                         known at run time (give it in the params file: `\"{v}\": {{value: N}}`)"
                    ),
                    true,
                );
                return self.placeholder(e, &base, parent, depth, path, prefix, retry);
            }
            let Some((n, at)) = self.int_attr(e, "queue")? else {
                return Err(self.err(q.loc, format!("<{ty}> needs `queue`")));
            };
            if !(0..=MAX_QUEUE as i64).contains(&n) {
                return Err(self
                    .err(at, format!("queue length {n} is not valid"))
                    .with_help(format!(
                        "the params value of a queue is its length, 0 to {MAX_QUEUE}"
                    )));
            }
            n as usize
        } else {
            let mut pieces = q.value.split(';').count();
            if q.value.is_empty() || q.value.ends_with(';') {
                pieces -= 1;
            }
            if pieces > MAX_QUEUE {
                return Err(self
                    .err(q.loc, format!("the queue has {pieces} elements"))
                    .with_help(format!(
                        "btrel reads queues of at most {MAX_QUEUE} elements"
                    )));
            }
            pieces
        };
        let if_empty_success = match e.attr("if_empty") {
            None => true,
            Some(a) => match a.value.trim() {
                "SUCCESS" => true,
                "FAILURE" => false,
                v if v == "SKIPPED" || v.starts_with('{') => {
                    let why = if v == "SKIPPED" {
                        "an emptied queue skips the node, which only its parent can interpret"
                    } else {
                        "a blackboard reference: the status is only known at run time"
                    };
                    self.problem(
                        e.doc,
                        a.loc,
                        format!("<{ty}> with if_empty = \"{v}\": {why}"),
                        true,
                    );
                    return self.placeholder(e, &base, parent, depth, path, prefix, retry);
                }
                v => {
                    return Err(self
                        .err(a.loc, format!("if_empty = \"{v}\" is not a valid status"))
                        .with_help("`if_empty` is SUCCESS (the default), FAILURE or SKIPPED"));
                }
            },
        };
        if n == 0 {
            let ps = if if_empty_success { 1.0 } else { 0.0 };
            return self.push(
                e,
                &base,
                prefix,
                parent,
                depth,
                path,
                NodeKind::Condition { ps },
            );
        }
        if if_empty_success {
            let kind = NodeKind::Decorator {
                decorator: super::Decorator::Repeat { times: n },
                child: 0,
            };
            let id = self.push(e, &base, prefix, parent, depth, path, kind)?;
            let ids = self.children(e, id, depth, path, prefix, retry)?;
            self.set_children(id, ids);
            return Ok(id);
        }
        let kind = NodeKind::Flow(Flow {
            children: Vec::new(),
            states: Vec::new(),
        });
        let id = self.push(e, &base, prefix, parent, depth, path, kind)?;
        let ids = self.children(e, id, depth, path, prefix, retry)?;
        let states = (0..n)
            .map(|k| FlowState {
                child: 0,
                on_success: if k + 1 < n {
                    FlowNext::State(k + 1)
                } else {
                    FlowNext::Failure
                },
                on_failure: FlowNext::Failure,
            })
            .collect();
        self.nodes[id].kind =
            NodeKind::Flow(Flow::new(ids, states).expect("a loop's flow is valid"));
        Ok(id)
    }
}
