//! BT.CPP nodes whose outcome comes from a predicate over the blackboard
//! (`Precondition`'s `if`) or from a queue (`LoopInt`, `LoopDouble`, ...).
//!
//! A predicate is a zero-time condition leaf named `<node>/<port>` (e.g.
//! `Precondition/if`): its `ps`, the probability that the predicate holds,
//! comes from the params file, keyed by the full name `<node>/<port>`, then
//! `<name attribute>/<port>`, then `<ID>/<port>`. Under the SBT assumption
//! the predicate keeps its value during the parent's run, so BT.CPP reading
//! it once (Precondition reads `if` only before the child starts) is exact.

use super::{
    canonical, Builder, Elem, Flow, FlowNext, FlowState, Kind, Leaf, LeafKind, NodeKind, Queue,
    TreeError, PRECONDITIONS,
};

/// The parent element of each element (`None` for the roots).
pub(super) fn parents(elems: &[Elem]) -> Vec<Option<usize>> {
    let mut parent = vec![None; elems.len()];
    for (i, e) in elems.iter().enumerate() {
        for &c in &e.children {
            if let Some(p) = parent.get_mut(c) {
                *p = Some(i);
            }
        }
    }
    parent
}

/// The node type of an element: its ID in the explicit forms and for a
/// SubTree, else its tag.
fn type_of(e: &Elem) -> &str {
    match e.name.as_str() {
        "Action" | "Condition" | "Control" | "Decorator" | "SubTree" | "SubTreePlus" => {
            e.attr("ID").map_or(e.name.as_str(), |a| a.value.as_str())
        }
        t => t,
    }
}

/// The pre-conditions of `e` that are not the no-op constant, in the order
/// BT.CPP checks them (`PreCond`: failure, success, skip, while).
fn active_preconditions(e: &Elem) -> Vec<&'static str> {
    PRECONDITIONS
        .iter()
        .filter(|(p, noop)| e.attr(p).is_some_and(|a| a.value.trim() != *noop))
        .map(|&(p, _)| p)
        .collect()
}

/// Whether a pre-condition of `e` may skip it.
fn may_skip(e: &Elem) -> bool {
    active_preconditions(e)
        .iter()
        .any(|p| matches!(*p, "_skipIf" | "_while"))
}

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
        self.predicate_leaf(e, ty, port, parent, depth, path, prefix, true)
    }

    /// [`Builder::predicate`]; `constants`: whether `true` / `false` are
    /// read as constant predicates (not for a Switch's case values).
    #[allow(clippy::too_many_arguments)]
    pub(super) fn predicate_leaf(
        &mut self,
        e: &Elem,
        ty: &str,
        port: &str,
        parent: usize,
        depth: usize,
        path: &str,
        prefix: &str,
        constants: bool,
    ) -> Result<usize, TreeError> {
        let name_attr = self.name_attr(e)?;
        let base = format!(
            "{}/{port}",
            name_attr.clone().unwrap_or_else(|| ty.to_string())
        );
        let constant = e
            .attr(port)
            .filter(|_| constants)
            .and_then(|a| match a.value.trim() {
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
                    .err(
                        Kind::InvalidValue,
                        a.loc,
                        format!("<{ty}> has an empty `if`"),
                    )
                    .with_help(
                        "write the predicate as a BT.CPP script, e.g. if=\"battery > 20\"",
                    ));
            }
            Some(_) => {}
            None => {
                return Err(self
                    .err(Kind::Structure, e.loc, format!("<{ty}> needs `if`"))
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
                        .err(
                            Kind::InvalidValue,
                            a.loc,
                            format!("else = \"{v}\" is not a node status"),
                        )
                        .with_help(
                            "`else` is SUCCESS, FAILURE (the default), RUNNING or SKIPPED",
                        ));
                }
            },
        };
        self.guarded_child(
            e,
            ty,
            "if",
            &base,
            otherwise_success,
            parent,
            depth,
            path,
            prefix,
            retry,
        )
    }

    /// A predicate `<node>/<port>` guarding the one child of `e` (node name
    /// `base`): the predicate at `{path}.0`, the child at `{path}.1`. A true
    /// predicate runs the child and returns its status; a false one returns
    /// Success when `otherwise_success` (the flow port → (S: child,
    /// F: Success)), else Failure (Sequence(port, child)). Precondition and
    /// Nav2's PathLongerOnApproach share it.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn guarded_child(
        &mut self,
        e: &'a Elem,
        ty: &str,
        port: &str,
        base: &str,
        otherwise_success: bool,
        parent: Option<usize>,
        depth: usize,
        path: &str,
        prefix: &str,
        retry: Option<&'static str>,
    ) -> Result<usize, TreeError> {
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
        let id = self.push(e, base, prefix, parent, depth, path, kind)?;
        let cond = self.predicate(e, ty, port, id, depth + 1, &format!("{path}.0"), prefix)?;
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
                Flow::new(vec![cond, child], states).expect("a guarded child's flow is valid"),
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
    ///
    /// `ConsumeQueue` (BT.CPP `consume_queue.h`) and MoveIt Pro's `ForEach`
    /// read the same way, from a blackboard reference only (`queue`,
    /// `vector_in`: BT.CPP reads a queue object there, not a literal) and
    /// without `if_empty`: an empty queue is Success for ConsumeQueue and
    /// refused for ForEach (MoveIt Pro does not document that case).
    #[allow(clippy::too_many_arguments)]
    pub(super) fn loop_queue(
        &mut self,
        e: &'a Elem,
        ty: &str,
        form: Queue,
        parent: Option<usize>,
        depth: usize,
        path: &str,
        prefix: &str,
        retry: Option<&'static str>,
    ) -> Result<usize, TreeError> {
        self.one_child(e, ty)?;
        let base = self.name_attr(e)?.unwrap_or_else(|| ty.to_string());
        let port = if form == Queue::ForEach {
            "vector_in"
        } else {
            "queue"
        };
        let Some(q) = e.attr(port) else {
            let literal = if form == Queue::Loop {
                format!("<{ty} queue=\"a;b;c\">, or ")
            } else {
                String::new()
            };
            return Err(self
                .err(Kind::Structure, e.loc, format!("<{ty}> needs `{port}`"))
                .with_help(format!(
                    "write {literal}a blackboard reference whose length the params file gives: \
                     <{ty} {port}=\"{{items}}\"> with `\"{{items}}\": {{value: N}}`"
                )));
        };
        if form != Queue::Loop && !q.value.trim().starts_with('{') {
            self.problem(
                e.doc,
                q.loc,
                format!(
                    "<{ty}> with {port} = \"{}\", not a blackboard reference: it reads a \
                     container from the blackboard, which a literal does not give",
                    q.value.trim()
                ),
                true,
            );
            return self.placeholder(e, &base, parent, depth, path, prefix, retry);
        }
        let n = if q.value.trim().starts_with('{') {
            if self.unresolved(&q.value) {
                self.missing_value(e, q.loc, ty, port, "give its length", "N");
                return self.placeholder(e, &base, parent, depth, path, prefix, retry);
            }
            let Some((n, at)) = self.int_attr(e, port)? else {
                return Err(self.err(Kind::Structure, q.loc, format!("<{ty}> needs `{port}`")));
            };
            if !(0..=MAX_QUEUE as i64).contains(&n) {
                return Err(self
                    .err(
                        Kind::InvalidValue,
                        at,
                        format!("queue length {n} is not valid"),
                    )
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
                    .err(
                        Kind::Budget,
                        q.loc,
                        format!("the queue has {pieces} elements"),
                    )
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
                        .err(
                            Kind::InvalidValue,
                            a.loc,
                            format!("if_empty = \"{v}\" is not a valid status"),
                        )
                        .with_help("`if_empty` is SUCCESS (the default), FAILURE or SKIPPED"));
                }
            },
        };
        if n == 0 && form == Queue::ForEach {
            self.problem(
                e.doc,
                q.loc,
                format!(
                    "<{ty}> over an empty vector ({} has length 0 in the params file): MoveIt \
                     Pro does not document what ForEach returns then",
                    q.value.trim()
                ),
                true,
            );
            return self.placeholder(e, &base, parent, depth, path, prefix, retry);
        }
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

    /// Whether element `ei` carries a pre-condition that is not a no-op.
    pub(super) fn has_preconditions(&self, ei: usize) -> bool {
        !active_preconditions(self.elem(ei)).is_empty()
    }

    /// What a skipped element `ei` means to its parent: `Ok(true)` Success
    /// (a Sequence passes over it), `Ok(false)` Failure (a Fallback), or why
    /// it has no meaning.
    fn skip_means_success(&self, ei: usize) -> Result<bool, String> {
        let Some(pe) = self
            .elem_parent
            .get(ei)
            .copied()
            .flatten()
            .map(|p| self.elem(p))
        else {
            return Err("the tree's root is skipped: BT.CPP returns SKIPPED to the caller".into());
        };
        let pty = canonical(type_of(pe));
        let success = match pty {
            "Sequence" | "SequenceWithMemory" | "ReactiveSequence" => true,
            "Fallback" | "ReactiveFallback" => false,
            "BehaviorTree" => {
                return Err(
                    "it is a BehaviorTree's root: a skipped tree is SKIPPED for the \
                            SubTree's parent"
                        .into(),
                )
            }
            other => {
                return Err(format!(
                    "its parent <{other}> is not a Sequence or Fallback (which pass over a \
                     skipped child as a Success / Failure)"
                ))
            }
        };
        if pe.children.iter().all(|&c| may_skip(self.elem(c))) {
            return Err(format!(
                "every child of its parent <{pty}> may be skipped, and BT.CPP returns SKIPPED \
                 when all are"
            ));
        }
        Ok(success)
    }

    /// Element `ei` with BT.CPP v4 pre-conditions (`TreeNode::checkPreConditions`,
    /// checked before the node starts, in this order): `_failureIf` true →
    /// Failure, `_successIf` true → Success, `_skipIf` true or `_while` false
    /// → SKIPPED, else the node runs (`_while` is checked again while it
    /// runs, which changes nothing while the predicate keeps its value).
    /// One flow `<node>/guard` over the predicates `<node>/<attribute>`
    /// (conditions from the params file, *Predicates*) and the node; a skip
    /// is the parent's: Success below a Sequence, Failure below a Fallback
    /// (exact while some child cannot be skipped), refused elsewhere.
    pub(super) fn guarded(
        &mut self,
        ei: usize,
        parent: Option<usize>,
        depth: usize,
        path: String,
        prefix: &str,
        retry: Option<&'static str>,
    ) -> Result<usize, TreeError> {
        let e = self.elem(ei);
        self.pre_handled.insert((e.doc, e.loc));
        let pres = active_preconditions(e);
        let skip = if pres.iter().any(|p| matches!(*p, "_skipIf" | "_while")) {
            match self.skip_means_success(ei) {
                Ok(s) => Some(s),
                Err(why) => {
                    let p = pres
                        .iter()
                        .find(|p| matches!(**p, "_skipIf" | "_while"))
                        .and_then(|p| e.attr(p));
                    let at = p.map_or(e.loc, |a| a.loc);
                    let name = p.map_or("_skipIf", |a| a.name.as_str());
                    self.problem(
                        e.doc,
                        at,
                        format!("`{name}` attribute on <{}>: {why}", e.name),
                        true,
                    );
                    return self.node_here(ei, parent, depth, path, prefix, retry);
                }
            }
        } else {
            None
        };
        if let Some(a) = pres
            .iter()
            .filter_map(|p| e.attr(p))
            .find(|a| a.value.trim().starts_with('{'))
        {
            self.problem(
                e.doc,
                a.loc,
                format!(
                    "`{}` attribute on <{}> = \"{}\": a pre-condition is a script, not a \
                     blackboard reference",
                    a.name,
                    e.name,
                    a.value.trim()
                ),
                true,
            );
            return self.node_here(ei, parent, depth, path, prefix, retry);
        }
        let ty = type_of(e).to_string();
        let base = match self.name_attr(e)? {
            Some(n) => n,
            None => ty.clone(),
        };
        let kind = NodeKind::Flow(Flow {
            children: Vec::new(),
            states: Vec::new(),
        });
        let id = self.push(
            e,
            &format!("{base}/guard"),
            prefix,
            parent,
            depth,
            &path,
            kind,
        )?;
        let mut children = Vec::with_capacity(pres.len() + 1);
        let mut states = Vec::with_capacity(pres.len() + 1);
        let skipped = if skip == Some(true) {
            FlowNext::Success
        } else {
            FlowNext::Failure
        };
        for (k, p) in pres.iter().enumerate() {
            let c = self.predicate(e, &ty, p, id, depth + 1, &format!("{path}.{k}"), prefix)?;
            children.push(c);
            let next = FlowNext::State(k + 1);
            let (on_success, on_failure) = match *p {
                "_failureIf" => (FlowNext::Failure, next),
                "_successIf" => (FlowNext::Success, next),
                "_skipIf" => (skipped, next),
                _ => (next, skipped),
            };
            states.push(FlowState {
                child: k,
                on_success,
                on_failure,
            });
        }
        let k = pres.len();
        let x = self.node_here(
            ei,
            Some(id),
            depth + 1,
            format!("{path}.{k}"),
            prefix,
            retry,
        )?;
        children.push(x);
        states.push(FlowState {
            child: k,
            on_success: FlowNext::Success,
            on_failure: FlowNext::Failure,
        });
        self.nodes[id].kind = NodeKind::Flow(
            Flow::new(children, states).expect("the flow of a node's pre-conditions is valid"),
        );
        Ok(id)
    }

    /// BT.CPP v4 `SwitchN` (`switch_node.h`): N cases and N + 1 children;
    /// it runs the child of the first `case_k` equal to `variable` (the last
    /// child if none) and returns its status. Under the SBT assumption the
    /// variable keeps its value while the chosen child runs (BT.CPP would
    /// halt it and switch otherwise). Case k is a predicate `<node>/case_k`
    /// whose `ps` is the probability that it matches given that no earlier
    /// case did; a missing `case_k` never matches (ps 0). One flow over the
    /// predicates and the children: predicate k → (S: child k, F: predicate
    /// k + 1, or the default child after the last).
    #[allow(clippy::too_many_arguments)]
    pub(super) fn switch(
        &mut self,
        e: &'a Elem,
        ty: &str,
        cases: usize,
        parent: Option<usize>,
        depth: usize,
        path: &str,
        prefix: &str,
        retry: Option<&'static str>,
    ) -> Result<usize, TreeError> {
        if e.children.len() != cases + 1 {
            return Err(self
                .err(
                    Kind::Structure,
                    e.loc,
                    format!("<{ty}> has {} children", e.children.len()),
                )
                .with_help(format!(
                    "<{ty}> takes {} children: one per case_1..case_{cases}, then the default",
                    cases + 1
                )));
        }
        if e.attr("variable").is_none() {
            return Err(self
                .err(Kind::Structure, e.loc, format!("<{ty}> needs `variable`"))
                .with_help(format!("write <{ty} variable=\"{{name}}\" case_1=\"...\">")));
        }
        let base = self.name_attr(e)?.unwrap_or_else(|| ty.to_string());
        let kind = NodeKind::Flow(Flow {
            children: Vec::new(),
            states: Vec::new(),
        });
        let id = self.push(e, &base, prefix, parent, depth, path, kind)?;
        let mut ids = Vec::with_capacity(2 * cases + 1);
        for k in 1..=cases {
            let port = format!("case_{k}");
            let at = format!("{path}.{}", k - 1);
            let c = if e.attr(&port).is_some() {
                self.predicate_leaf(e, ty, &port, id, depth + 1, &at, prefix, false)?
            } else {
                let name = format!("{base}/{port}");
                let kind = NodeKind::Condition { ps: 0.0 };
                self.push(e, &name, prefix, Some(id), depth + 1, &at, kind)?
            };
            ids.push(c);
        }
        for (i, &c) in e.children.iter().enumerate() {
            let at = format!("{path}.{}", cases + i);
            ids.push(self.node(c, Some(id), depth + 1, at, prefix, retry)?);
        }
        let mut states = Vec::with_capacity(2 * cases + 1);
        for k in 0..cases {
            states.push(FlowState {
                child: k,
                on_success: FlowNext::State(cases + k),
                on_failure: FlowNext::State(if k + 1 < cases { k + 1 } else { 2 * cases }),
            });
        }
        for k in 0..=cases {
            states.push(FlowState {
                child: cases + k,
                on_success: FlowNext::Success,
                on_failure: FlowNext::Failure,
            });
        }
        self.nodes[id].kind =
            NodeKind::Flow(Flow::new(ids, states).expect("a Switch's flow is valid"));
        Ok(id)
    }
}
