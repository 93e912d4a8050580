//! The lowering state ([`Builder`]) and its small steps: errors and
//! collected problems, attribute readers (durations, rates, counts,
//! blackboard references), unique names, pushing nodes.

use super::*;

/// A leaf waiting for its parameters.
pub(super) struct Leaf {
    pub(super) node: usize,
    pub(super) kind: LeafKind,
    pub(super) id: String,
    pub(super) name_attr: Option<String>,
    pub(super) doc: usize,
}

/// A node that cannot be read, collected so that all of them are reported
/// at once. `semantic`: a known node type (or attribute) that btrel has no
/// stochastic meaning for; otherwise a front-end problem (an unknown node, a
/// SubTree defined nowhere).
pub(super) struct Problem {
    pub(super) doc: usize,
    pub(super) loc: Loc,
    pub(super) text: String,
    pub(super) semantic: bool,
}

pub(super) struct Builder<'a> {
    pub(super) sources: &'a [Source],
    pub(super) elems: &'a [Elem],
    pub(super) table: &'a ParamsTable,
    /// Blackboard entries of the params file read by some port.
    pub(super) blackboard_used: std::cell::RefCell<HashSet<String>>,
    /// BehaviorTree elements by ID; a definition in the main file comes
    /// first.
    pub(super) trees: HashMap<&'a str, Vec<usize>>,
    pub(super) model: HashMap<&'a str, Decl>,
    pub(super) nodes: Vec<Node>,
    pub(super) used: HashSet<String>,
    pub(super) name_bytes: usize,
    pub(super) leaves: Vec<Leaf>,
    /// ReactiveSequence / ReactiveFallback nodes (node, source, location,
    /// type), checked once the leaves are known to be actions or conditions.
    pub(super) reactive: Vec<(usize, usize, Loc, &'a str)>,
    /// WhileDoElse nodes (node, source, location), checked once the leaves
    /// are known: their condition child must take no time.
    pub(super) while_do_else: Vec<(usize, usize, Loc)>,
    /// Port values the params file lacks (source, location, message),
    /// listed with the leaves' missing parameters.
    pub(super) missing_values: Vec<(usize, Loc, String)>,
    /// Nodes whose re-tick after returning changes nothing under the SBT
    /// assumptions (node, source, location, type): refused as an earlier
    /// PipelineSequence child whose re-tick btrel would read as a re-run.
    pub(super) once: Vec<(usize, usize, Loc, &'static str)>,
    pub(super) problems: Vec<Problem>,
    pub(super) seen_problems: HashSet<(usize, Loc, String)>,
    /// The source of the element being built (for error locations).
    pub(super) cur: std::cell::Cell<usize>,
    /// SubTree IDs being expanded, outermost first, with the instance
    /// location.
    pub(super) expanding: Vec<(&'a str, Loc)>,
    /// Node counts of expanded trees (memo for [`Builder::tree_size`]).
    pub(super) sizes: HashMap<&'a str, u64>,
    pub(super) sizing: HashSet<&'a str>,
    /// RoundRobin index slots by element and SubTree instance: the copies
    /// of one element made by a RecoveryNode share their index.
    pub(super) slots: HashMap<String, usize>,
    /// The parent element of each element (for pre-conditions that skip a
    /// node: its parent decides what a skip means).
    pub(super) elem_parent: Vec<Option<usize>>,
    /// Elements whose pre-condition attributes are modelled (by
    /// [`Builder::guarded`]), by source and location.
    pub(super) pre_handled: HashSet<(usize, Loc)>,
}

impl<'a> Builder<'a> {
    pub(super) fn err_in(
        &self,
        kind: Kind,
        doc: usize,
        at: Loc,
        msg: impl Into<String>,
    ) -> TreeError {
        let s = &self.sources[doc];
        TreeError::at(kind, &s.name, &s.text, at, msg)
    }

    pub(super) fn err(&self, kind: Kind, at: Loc, msg: impl Into<String>) -> TreeError {
        self.err_in(kind, self.cur.get(), at, msg)
    }

    pub(super) fn elem(&self, i: usize) -> &'a Elem {
        &self.elems[i]
    }

    pub(super) fn problem(&mut self, doc: usize, loc: Loc, text: String, semantic: bool) {
        if self.seen_problems.insert((doc, loc, text.clone())) {
            self.problems.push(Problem {
                doc,
                loc,
                text,
                semantic,
            });
        }
    }

    /// Refuses attributes not in `allowed`; `ports` accepts data ports
    /// (attributes not starting with `_`). Attributes starting with `_`
    /// are metadata (`_description`, `_collapsed`, ...), `_autoremap`, or
    /// post-conditions (`_onSuccess`, ...), which BT.CPP runs after the node
    /// has returned and which only write the blackboard: all are ignored.
    /// Pre-conditions (`_skipIf`, `_while`, ...) are recorded as problems
    /// unless their value is the constant that makes them a no-op.
    pub(super) fn check_attrs(
        &mut self,
        e: &Elem,
        allowed: &[&str],
        ports: bool,
    ) -> Result<(), TreeError> {
        for a in &e.attrs {
            if allowed.contains(&a.name.as_str()) {
                continue;
            }
            if a.name.starts_with('_') {
                if self.pre_handled.contains(&(e.doc, e.loc)) {
                    continue;
                }
                if let Some(&(_, noop)) = PRECONDITIONS.iter().find(|(p, _)| *p == a.name) {
                    if a.value.trim() != noop {
                        self.problem(
                            e.doc,
                            a.loc,
                            format!(
                                "`{}` attribute on <{}>: a pre-condition skips the node or ends it \
                                 early depending on blackboard values (only {}=\"{noop}\", a no-op, \
                                 is read)",
                                a.name, e.name, a.name
                            ),
                            true,
                        );
                    }
                }
                continue;
            }
            if ports {
                continue;
            }
            let hint = match nearest(&a.name, allowed) {
                Some(k) => format!(
                    "did you mean `{k}`? <{}> accepts: {}",
                    e.name,
                    allowed.join(", ")
                ),
                None if allowed.is_empty() => format!(
                    "<{}> accepts no attributes here; blackboard ports have no stochastic meaning",
                    e.name
                ),
                None => format!(
                    "<{}> accepts: {}; blackboard ports have no stochastic meaning",
                    e.name,
                    allowed.join(", ")
                ),
            };
            return Err(self
                .err_in(
                    Kind::Structure,
                    e.doc,
                    a.loc,
                    format!("unknown attribute `{}` on <{}>", a.name, e.name),
                )
                .with_help(hint));
        }
        Ok(())
    }

    /// A duration in milliseconds (BT.CPP's `msec`, `delay_msec`: a whole
    /// number ≥ 0), in seconds; `None` (a problem recorded) for a blackboard
    /// reference.
    pub(super) fn milliseconds(&mut self, e: &Elem, key: &str) -> Result<Option<f64>, TreeError> {
        if let Some(a) = e.attr(key).filter(|a| self.unresolved(&a.value)) {
            let (at, ty) = (a.loc, e.name.clone());
            self.missing_value(e, at, &ty, key, "give it in milliseconds", "N");
            return Ok(None);
        }
        match self.int_attr(e, key)? {
            Some((n, _)) if n >= 0 => Ok(Some(n as f64 / 1000.0)),
            Some((n, at)) => Err(self
                .err(
                    Kind::InvalidValue,
                    at,
                    format!("{key} = {n} is not a valid duration"),
                )
                .with_help(format!("{key} is a whole number of milliseconds >= 0"))),
            None => Err(self
                .err(
                    Kind::Structure,
                    e.loc,
                    format!("<{}> needs `{key}`", e.name),
                )
                .with_help(format!("write {key}=\"N\", N in milliseconds"))),
        }
    }

    /// RateController's `hz` (default 10, as in Nav2) as a period in
    /// seconds; `None` (a problem recorded) for a blackboard reference.
    pub(super) fn period(&mut self, e: &Elem, ty: &str) -> Result<Option<f64>, TreeError> {
        let Some(a) = e.attr("hz") else {
            return Ok(Some(0.1));
        };
        let v = a.value.trim();
        let given = self.table.blackboard.get(v).map(|g| g.value);
        if given.is_some() {
            self.blackboard_used.borrow_mut().insert(v.to_string());
        } else if v.starts_with('{') {
            self.missing_value(e, a.loc, ty, "hz", "give the rate in Hz", "x");
            return Ok(None);
        }
        match given.map_or_else(|| v.parse::<f64>().ok(), Some) {
            Some(hz) if hz.is_finite() && hz > 0.0 && (1.0 / hz).is_finite() => Ok(Some(1.0 / hz)),
            _ => Err(self
                .err(
                    Kind::InvalidValue,
                    a.loc,
                    format!("hz = \"{v}\" is not a valid rate"),
                )
                .with_help("hz is a number of re-runs per second, > 0 (e.g. 1.0 or 0.5)")),
        }
    }

    /// RoundRobin's `wrap_around`; by default `false` in BehaviorTree.CPP v4
    /// files (Nav2's default since 2025) and `true` in v3 files (Nav2 Humble
    /// and Iron always wrapped). `None` (a problem recorded) for a
    /// blackboard reference.
    pub(super) fn wrap_around(&mut self, e: &Elem, ty: &str) -> Result<Option<bool>, TreeError> {
        let Some(a) = e.attr("wrap_around") else {
            return Ok(Some(self.sources[e.doc].format != Format::V4));
        };
        let v = a.value.trim();
        if v.starts_with('{') {
            self.problem(
                e.doc,
                a.loc,
                format!("<{ty}> with wrap_around = \"{v}\", a blackboard reference: known only at run time"),
                true,
            );
            return Ok(None);
        }
        match v {
            "true" | "True" | "TRUE" | "1" => Ok(Some(true)),
            "false" | "False" | "FALSE" | "0" => Ok(Some(false)),
            _ => Err(self
                .err(
                    Kind::InvalidValue,
                    a.loc,
                    format!("wrap_around = \"{v}\" is not a boolean"),
                )
                .with_help("write wrap_around=\"true\" or \"false\"")),
        }
    }

    /// Records a blackboard reference the params file lacks as a missing
    /// parameter: `<ty> key = "{v}"`, and what to give (`give`, with the
    /// entry's placeholder `n`).
    pub(super) fn missing_value(
        &mut self,
        e: &Elem,
        at: Loc,
        ty: &str,
        key: &str,
        give: &str,
        n: &str,
    ) {
        let v = e.attr(key).map_or("", |a| a.value.trim());
        self.missing_values.push((
            e.doc,
            at,
            format!(
                "<{ty}> {key} = \"{v}\": a blackboard value known only at run time; {give}: \
                 `\"{v}\": {{value: {n}}}`"
            ),
        ));
    }

    /// Whether `value` is a blackboard reference (`{name}`) without a value
    /// in the params file.
    pub(super) fn unresolved(&self, value: &str) -> bool {
        let v = value.trim();
        v.starts_with('{') && !self.table.blackboard.contains_key(v)
    }

    /// A whole-number attribute; `None` if absent. A blackboard reference
    /// (`{name}`) reads the params file's `"{name}": {value: N}`.
    pub(super) fn int_attr(&self, e: &Elem, key: &str) -> Result<Option<(i64, Loc)>, TreeError> {
        let Some(a) = e.attr(key) else {
            return Ok(None);
        };
        let v = a.value.trim();
        if let Some(given) = self.table.blackboard.get(v) {
            self.blackboard_used.borrow_mut().insert(v.to_string());
            let n = given.value;
            if n.fract() != 0.0 || !n.is_finite() || n.abs() > 1e15 {
                return Err(self
                    .err(
                        Kind::InvalidValue,
                        a.loc,
                        format!(
                            "{key} = \"{v}\" reads {n} from the params file, not a whole number"
                        ),
                    )
                    .with_help(format!("give `\"{v}\": {{value: N}}` a whole number N")));
            }
            return Ok(Some((n as i64, a.loc)));
        }
        if v.starts_with('{') {
            return Err(self
                .err(
                    Kind::MissingParameter,
                    a.loc,
                    format!("{key} = \"{v}\" is a blackboard reference"),
                )
                .with_help(format!(
                    "btrel needs a literal whole number for {key}, or the reference's value in the \
                     params file: `\"{v}\": {{value: N}}`"
                )));
        }
        let ok = !v.is_empty()
            && v.strip_prefix('-')
                .unwrap_or(v)
                .chars()
                .all(|c| c.is_ascii_digit())
            && v != "-";
        match v.parse::<i64>() {
            Ok(n) if ok => Ok(Some((n, a.loc))),
            _ => Err(self
                .err(
                    Kind::InvalidValue,
                    a.loc,
                    format!("{key} = \"{v}\" is not a whole number"),
                )
                .with_help(format!("write {key} as a whole number such as 3"))),
        }
    }

    pub(super) fn name_attr(&self, e: &Elem) -> Result<Option<String>, TreeError> {
        match e.attr("name") {
            Some(a) if a.value.trim().is_empty() => Err(self
                .err_in(
                    Kind::InvalidValue,
                    e.doc,
                    a.loc,
                    "a node name must not be empty",
                )
                .with_help("omit `name` to name the node by its ID")),
            Some(a) => Ok(Some(a.value.clone())),
            None => Ok(None),
        }
    }

    pub(super) fn id_attr(&self, e: &'a Elem) -> Result<&'a str, TreeError> {
        match e.attr("ID") {
            Some(a) if !a.value.trim().is_empty() => Ok(a.value.as_str()),
            Some(a) => Err(self.err_in(
                Kind::Structure,
                e.doc,
                a.loc,
                format!("<{}> has an empty ID", e.name),
            )),
            None => Err(self
                .err_in(
                    Kind::Structure,
                    e.doc,
                    e.loc,
                    format!("<{}> needs an ID attribute", e.name),
                )
                .with_help(format!("write <{} ID=\"...\"/>", e.name))),
        }
    }

    /// A unique name: `prefix + base`, with `#k` appended if taken.
    pub(super) fn unique(&mut self, base: String, at: Loc) -> Result<String, TreeError> {
        let mut name = base.clone();
        let mut k = 2usize;
        while self.used.contains(&name) {
            name = format!("{base}#{k}");
            k += 1;
        }
        self.name_bytes += name.len();
        if self.name_bytes > MAX_NAME_BYTES {
            return Err(self
                .err(Kind::Budget, at, "the node names after SubTree expansion are too long")
                .with_help(format!(
                    "btrel accepts at most {MAX_NAME_BYTES} bytes of node names; shorten names or nest fewer SubTrees"
                )));
        }
        self.used.insert(name.clone());
        Ok(name)
    }

    #[allow(clippy::too_many_arguments)]
    pub(super) fn push(
        &mut self,
        e: &Elem,
        base: &str,
        prefix: &str,
        parent: Option<usize>,
        depth: usize,
        path: &str,
        kind: NodeKind,
    ) -> Result<usize, TreeError> {
        if self.nodes.len() >= MAX_NODES {
            return Err(self
                .err(
                    Kind::Budget,
                    e.loc,
                    "the tree has too many nodes after SubTree expansion",
                )
                .with_help(format!("btrel accepts at most {MAX_NODES} nodes")));
        }
        if depth >= MAX_DEPTH {
            return Err(self
                .err(Kind::Budget, e.loc, "the tree is nested too deeply")
                .with_help(format!("btrel accepts trees up to {MAX_DEPTH} levels deep")));
        }
        let name = self.unique(format!("{prefix}{base}"), e.loc)?;
        self.nodes.push(Node {
            name,
            path: path.to_string(),
            depth,
            parent,
            kind,
            location: Some(e.loc),
        });
        Ok(self.nodes.len() - 1)
    }

    pub(super) fn set_children(&mut self, id: usize, ids: Vec<usize>) {
        match &mut self.nodes[id].kind {
            NodeKind::Sequence { children }
            | NodeKind::Fallback { children }
            | NodeKind::Pipeline { children }
            | NodeKind::RoundRobin { children, .. }
            | NodeKind::SequenceWithMemory { children, .. }
            | NodeKind::Parallel { children, .. } => *children = ids,
            NodeKind::Decorator { child, .. } => *child = ids[0],
            // a flow is built whole once its children are known
            NodeKind::Action(_) | NodeKind::Condition { .. } | NodeKind::Flow(_) => {}
        }
    }

    /// Builds the children of `e` below node `id`.
    pub(super) fn children(
        &mut self,
        e: &'a Elem,
        id: usize,
        depth: usize,
        path: &str,
        prefix: &str,
        retry: Option<&'static str>,
    ) -> Result<Vec<usize>, TreeError> {
        let mut ids = Vec::with_capacity(e.children.len());
        for (i, &c) in e.children.iter().enumerate() {
            ids.push(self.node(c, Some(id), depth + 1, format!("{path}.{i}"), prefix, retry)?);
        }
        Ok(ids)
    }

    /// `RetryUntilSuccessful(n ≥ 2)` over a `SequenceWithMemory` (element
    /// `swm`): BT.CPP's SequenceWithMemory keeps its index after a failure,
    /// so the next attempt resumes at the failed child. One flow over
    /// (failures so far f < n, child i): child i's Success goes to (f, i + 1)
    /// (Success after the last child), its Failure to (f + 1, i) (Failure at
    /// the n-th). The flow node carries the Retry's name; the
    /// SequenceWithMemory's children are its children. Exact as long as
    /// nothing ticks the Retry again after it failed (checked by the caller:
    /// no retrying ancestor), where the kept index would carry over.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn retry_with_memory(
        &mut self,
        e: &'a Elem,
        swm: usize,
        base: &str,
        attempts: usize,
        parent: Option<usize>,
        depth: usize,
        path: &str,
        prefix: &str,
    ) -> Result<usize, TreeError> {
        let s = self.elem(swm);
        self.check_attrs(s, &["name"], false)?;
        let k = s.children.len();
        if k == 0 {
            return Err(self
                .err(
                    Kind::Structure,
                    s.loc,
                    format!("<{}> has no children", s.name),
                )
                .with_help("a control node needs at least one child"));
        }
        if attempts.saturating_mul(k) > MAX_FLOW_STATES {
            self.problem(
                e.doc,
                e.loc,
                format!(
                    "<{}> of {attempts} attempts over a SequenceWithMemory of {k} children: \
                     {} states, more than the {MAX_FLOW_STATES} btrel builds",
                    e.name,
                    attempts.saturating_mul(k)
                ),
                true,
            );
            return self.placeholder(e, base, parent, depth, path, prefix, None);
        }
        let kind = NodeKind::Flow(Flow {
            children: Vec::new(),
            states: Vec::new(),
        });
        let id = self.push(e, base, prefix, parent, depth, path, kind)?;
        // the SequenceWithMemory's children sit directly below the flow;
        // below them, a failed child is ticked again (on the next attempt)
        let ids = self.children(s, id, depth, path, prefix, Some("RetryUntilSuccessful"))?;
        let mut states = Vec::with_capacity(attempts * k);
        for f in 0..attempts {
            for i in 0..k {
                states.push(FlowState {
                    child: i,
                    on_success: if i + 1 < k {
                        FlowNext::State(f * k + i + 1)
                    } else {
                        FlowNext::Success
                    },
                    on_failure: if f + 1 < attempts {
                        FlowNext::State((f + 1) * k + i)
                    } else {
                        FlowNext::Failure
                    },
                });
            }
        }
        self.nodes[id].kind = NodeKind::Flow(
            Flow::new(ids, states).expect("the states of a retried SequenceWithMemory are valid"),
        );
        Ok(id)
    }

    /// A stand-in for a node that is reported as a problem: its children
    /// are still built, so that every problem of the tree is found.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn placeholder(
        &mut self,
        e: &'a Elem,
        base: &str,
        parent: Option<usize>,
        depth: usize,
        path: &str,
        prefix: &str,
        retry: Option<&'static str>,
    ) -> Result<usize, TreeError> {
        if e.children.is_empty() {
            return self.push(
                e,
                base,
                prefix,
                parent,
                depth,
                path,
                NodeKind::Condition { ps: 1.0 },
            );
        }
        let kind = NodeKind::Sequence {
            children: Vec::new(),
        };
        let id = self.push(e, base, prefix, parent, depth, path, kind)?;
        let ids = self.children(e, id, depth, path, prefix, retry)?;
        self.set_children(id, ids);
        Ok(id)
    }
}
