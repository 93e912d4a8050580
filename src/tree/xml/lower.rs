//! Lowering one XML element to tree nodes: the dispatch over node types
//! (`node`, `node_here`).

use super::*;

impl<'a> Builder<'a> {
    /// Builds element `ei`; `retry` names the nearest ancestor that ticks a
    /// failed child again (RetryUntilSuccessful, RecoveryNode), if any.
    pub(super) fn node(
        &mut self,
        ei: usize,
        parent: Option<usize>,
        depth: usize,
        path: String,
        prefix: &str,
        retry: Option<&'static str>,
    ) -> Result<usize, TreeError> {
        let saved = self.cur.replace(self.elem(ei).doc);
        let r = if self.has_preconditions(ei) {
            self.guarded(ei, parent, depth, path, prefix, retry)
        } else {
            self.node_here(ei, parent, depth, path, prefix, retry)
        };
        self.cur.set(saved);
        r
    }

    pub(super) fn node_here(
        &mut self,
        ei: usize,
        parent: Option<usize>,
        depth: usize,
        path: String,
        prefix: &str,
        retry: Option<&'static str>,
    ) -> Result<usize, TreeError> {
        let e = self.elem(ei);
        if depth >= MAX_DEPTH {
            return Err(self
                .err(Kind::Budget, e.loc, "the tree is nested too deeply")
                .with_help(format!("btrel accepts trees up to {MAX_DEPTH} levels deep")));
        }
        if matches!(e.name.as_str(), "SubTree" | "SubTreePlus") {
            return self.subtree(e, parent, depth, path, prefix, retry);
        }
        // the explicit form <Control ID="Sequence">: the ID is the node type
        let (ty, form) = match e.name.as_str() {
            "Action" | "Condition" | "Control" | "Decorator" => {
                (self.id_attr(e)?, Some(e.name.as_str()))
            }
            t => (t, None),
        };
        let with_id: &[&str] = if form.is_some() {
            &["name", "ID"]
        } else {
            &["name"]
        };
        let attrs = |extra: &[&'static str]| -> Vec<&str> {
            with_id
                .iter()
                .copied()
                .chain(extra.iter().copied())
                .collect()
        };
        let canon = canonical(ty);
        let default_name = || ty.to_string();
        match canon {
            "PipelineSequence" | "RoundRobin" => {
                let robin = canon == "RoundRobin";
                let keys: &[&'static str] = if robin { &["wrap_around"] } else { &[] };
                self.check_attrs(e, &attrs(keys), false)?;
                if e.children.is_empty() {
                    return Err(self
                        .err(Kind::Structure, e.loc, format!("<{ty}> has no children"))
                        .with_help("a control node needs at least one child"));
                }
                let base = self.name_attr(e)?.unwrap_or_else(default_name);
                let kind = if robin {
                    let Some(wrap) = self.wrap_around(e, ty)? else {
                        return self.placeholder(e, &base, parent, depth, &path, prefix, retry);
                    };
                    let key = format!("{ei}|{:?}", self.expanding);
                    let next = self.slots.len();
                    let slot = *self.slots.entry(key).or_insert(next);
                    NodeKind::RoundRobin {
                        children: Vec::new(),
                        wrap,
                        slot,
                    }
                } else {
                    NodeKind::Pipeline {
                        children: Vec::new(),
                    }
                };
                let id = self.push(e, &base, prefix, parent, depth, &path, kind)?;
                let ids = self.children(e, id, depth, &path, prefix, retry)?;
                self.set_children(id, ids);
                Ok(id)
            }
            // GoalUpdater copies an updated goal to the blackboard and
            // returns its child's status: the child itself
            "GoalUpdater" => {
                self.check_attrs(e, &attrs(&[]), true)?;
                self.one_child(e, ty)?;
                self.node(e.children[0], parent, depth, path, prefix, retry)
            }
            // GoalUpdatedController (`goal_updated_controller.cpp`) ticks its
            // child at its first tick and again only while it runs or when
            // the goal on the blackboard changed; it returns the child's
            // status. The goal keeps its value during the run (the SBT
            // assumption for blackboard values), so it runs its child once
            // per execution: the child itself. Ticked again after returning
            // (an earlier PipelineSequence child) it returns RUNNING without
            // ticking the child, which does not block the pipeline: checked
            // after the build (`once`)
            "GoalUpdatedController" => {
                self.check_attrs(e, &attrs(&[]), true)?;
                self.one_child(e, ty)?;
                let id = self.node(e.children[0], parent, depth, path, prefix, retry)?;
                self.once.push((id, e.doc, e.loc, "GoalUpdatedController"));
                Ok(id)
            }
            "DistanceController" | "SpeedController" => {
                let distance = canon == "DistanceController";
                let keys: &[&'static str] = if distance {
                    &["distance", "global_frame", "robot_base_frame"]
                } else {
                    &[
                        "min_rate",
                        "max_rate",
                        "min_speed",
                        "max_speed",
                        "filter_duration",
                    ]
                };
                self.check_attrs(e, &attrs(keys), false)?;
                self.motion_controller(e, ty, distance, parent, depth, &path, prefix, retry)
            }
            "PathLongerOnApproach" => {
                self.check_attrs(e, &attrs(&["path", "prox_len", "length_factor"]), false)?;
                self.path_longer(e, ty, parent, depth, &path, prefix, retry)
            }
            "ManualSelector" => {
                self.check_attrs(e, &attrs(&["repeat_last_selection"]), false)?;
                self.manual_selector(e, ty, parent, depth, &path, prefix, retry)
            }
            "RateController" | "SingleTrigger" => {
                let rate = canon == "RateController";
                self.check_attrs(e, &attrs(if rate { &["hz"] } else { &[] }), false)?;
                self.one_child(e, ty)?;
                let base = self.name_attr(e)?.unwrap_or_else(default_name);
                let decorator = if rate {
                    let Some(period) = self.period(e, ty)? else {
                        return self.placeholder(e, &base, parent, depth, &path, prefix, retry);
                    };
                    Decorator::Rate {
                        period,
                        first: period,
                    }
                } else {
                    Decorator::SingleTrigger
                };
                let kind = NodeKind::Decorator {
                    decorator,
                    child: 0,
                };
                let id = self.push(e, &base, prefix, parent, depth, &path, kind)?;
                let ids = self.children(e, id, depth, &path, prefix, retry)?;
                self.set_children(id, ids);
                Ok(id)
            }
            "Sequence" | "SequenceWithMemory" | "ReactiveSequence" | "Fallback"
            | "ReactiveFallback" | "Parallel" => {
                let parallel = canon == "Parallel";
                let version = self.parallel_version(e);
                let keys: &[&'static str] = match (parallel, version) {
                    (false, _) => &[],
                    (true, Format::V3) => &["success_threshold", "failure_threshold"],
                    (true, _) => &["success_count", "failure_count"],
                };
                self.check_attrs(e, &attrs(keys), false)?;
                if e.children.is_empty() {
                    return Err(self
                        .err(Kind::Structure, e.loc, format!("<{ty}> has no children"))
                        .with_help("a control node needs at least one child"));
                }
                let base = self.name_attr(e)?.unwrap_or_else(default_name);
                let kind = match canon {
                    "Fallback" | "ReactiveFallback" => NodeKind::Fallback {
                        children: Vec::new(),
                    },
                    "Parallel" => NodeKind::Parallel {
                        success_threshold: 0,
                        failure_threshold: 0,
                        children: Vec::new(),
                    },
                    // ticked again after a Failure, it resumes at the failed
                    // child: its index is followed (`tree::nav2`), shared by
                    // the copies a RecoveryNode makes
                    "SequenceWithMemory" if retry.is_some() => {
                        let key = format!("memory|{ei}|{:?}", self.expanding);
                        let next = self.slots.len();
                        let slot = *self.slots.entry(key).or_insert(next);
                        NodeKind::SequenceWithMemory {
                            children: Vec::new(),
                            slot,
                            // v3's SequenceStarNode::halt resets the index,
                            // v4's SequenceWithMemory::halt keeps it
                            halt_resets: ty == "SequenceStar"
                                || self.sources[e.doc].format == Format::V3,
                        }
                    }
                    _ => NodeKind::Sequence {
                        children: Vec::new(),
                    },
                };
                let id = self.push(e, &base, prefix, parent, depth, &path, kind)?;
                let ids = self.children(e, id, depth, &path, prefix, retry)?;
                if parallel {
                    let (m, f) = self.thresholds(e, ids.len(), version)?;
                    if let NodeKind::Parallel {
                        success_threshold,
                        failure_threshold,
                        ..
                    } = &mut self.nodes[id].kind
                    {
                        (*success_threshold, *failure_threshold) = (m, f);
                    }
                }
                self.set_children(id, ids);
                if matches!(canon, "ReactiveSequence" | "ReactiveFallback") {
                    self.reactive.push((id, e.doc, e.loc, ty));
                }
                Ok(id)
            }
            "IfThenElse" | "WhileDoElse" => {
                self.check_attrs(e, &attrs(&[]), false)?;
                if !(2..=3).contains(&e.children.len()) {
                    return Err(self
                        .err(
                            Kind::Structure,
                            e.loc,
                            format!("<{ty}> has {} children", e.children.len()),
                        )
                        .with_help(format!(
                            "<{ty}> takes 2 or 3 children: the condition, the branch run on its \
                             Success, and (optionally) the one run on its Failure"
                        )));
                }
                let base = self.name_attr(e)?.unwrap_or_else(default_name);
                let kind = NodeKind::Flow(Flow {
                    children: Vec::new(),
                    states: Vec::new(),
                });
                let id = self.push(e, &base, prefix, parent, depth, &path, kind)?;
                let ids = self.children(e, id, depth, &path, prefix, retry)?;
                self.nodes[id].kind =
                    NodeKind::Flow(Flow::if_then_else(ids[0], ids[1], ids.get(2).copied()));
                if canon == "WhileDoElse" {
                    self.while_do_else.push((id, e.doc, e.loc));
                }
                Ok(id)
            }
            "Inverter"
            | "ForceSuccess"
            | "ForceFailure"
            | "RetryUntilSuccessful"
            | "Repeat"
            | "KeepRunningUntilFailure" => {
                let (decorator, child_retry) = match canon {
                    "KeepRunningUntilFailure" => {
                        self.check_attrs(e, &attrs(&[]), false)?;
                        (Decorator::UntilFailure, retry)
                    }
                    "RetryUntilSuccessful" if self.forever(e, "num_attempts") => {
                        self.check_attrs(e, &attrs(&["num_attempts"]), false)?;
                        (Decorator::UntilSuccess, Some("RetryUntilSuccessful"))
                    }
                    "Repeat" if self.forever(e, "num_cycles") => {
                        self.check_attrs(e, &attrs(&["num_cycles"]), false)?;
                        (Decorator::UntilFailure, retry)
                    }
                    "Inverter" => {
                        self.check_attrs(e, &attrs(&[]), false)?;
                        (Decorator::Inverter, retry)
                    }
                    "ForceSuccess" => {
                        self.check_attrs(e, &attrs(&[]), false)?;
                        (Decorator::ForceSuccess, retry)
                    }
                    "ForceFailure" => {
                        self.check_attrs(e, &attrs(&[]), false)?;
                        (Decorator::ForceFailure, retry)
                    }
                    "RetryUntilSuccessful" => {
                        self.check_attrs(e, &attrs(&["num_attempts"]), false)?;
                        let Some(attempts) = self.count(e, "num_attempts")? else {
                            let base = self.name_attr(e)?.unwrap_or_else(default_name);
                            return self.placeholder(e, &base, parent, depth, &path, prefix, retry);
                        };
                        if attempts > 1 && retry.is_none() {
                            if let [only] = e.children[..] {
                                if canonical(&self.elem(only).name) == "SequenceWithMemory" {
                                    let base = self.name_attr(e)?.unwrap_or_else(default_name);
                                    return self.retry_with_memory(
                                        e, only, &base, attempts, parent, depth, &path, prefix,
                                    );
                                }
                            }
                        }
                        // one attempt never ticks a failed child again
                        let r = if attempts > 1 {
                            Some("RetryUntilSuccessful")
                        } else {
                            retry
                        };
                        (Decorator::Retry { attempts }, r)
                    }
                    _ => {
                        self.check_attrs(e, &attrs(&["num_cycles"]), false)?;
                        let Some(times) = self.count(e, "num_cycles")? else {
                            let base = self.name_attr(e)?.unwrap_or_else(default_name);
                            return self.placeholder(e, &base, parent, depth, &path, prefix, retry);
                        };
                        (Decorator::Repeat { times }, retry)
                    }
                };
                self.one_child(e, ty)?;
                let base = self.name_attr(e)?.unwrap_or_else(default_name);
                let kind = NodeKind::Decorator {
                    decorator,
                    child: 0,
                };
                let id = self.push(e, &base, prefix, parent, depth, &path, kind)?;
                let ids = self.children(e, id, depth, &path, prefix, child_retry)?;
                self.set_children(id, ids);
                Ok(id)
            }
            "RecoveryNode" => {
                self.check_attrs(e, &attrs(&["number_of_retries"]), false)?;
                self.recovery(e, ty, parent, depth, path, prefix, retry)
            }
            // BT.CPP Sleep: Success after `msec`; Delay: waits `delay_msec`,
            // then runs its child and returns what it returns
            "Sleep" | "Delay" => {
                let key = if canon == "Sleep" {
                    "msec"
                } else {
                    "delay_msec"
                };
                self.check_attrs(e, &attrs(&[key]), false)?;
                let Some(seconds) = self.milliseconds(e, key)? else {
                    let base = self.name_attr(e)?.unwrap_or_else(default_name);
                    return self.placeholder(e, &base, parent, depth, &path, prefix, retry);
                };
                let wait = |ps| {
                    NodeKind::Action(crate::tree::Action {
                        ps,
                        pf: 0.0,
                        success: Some(crate::tree::Duration::Fixed { time: seconds }),
                        failure: None,
                    })
                };
                let base = self.name_attr(e)?.unwrap_or_else(default_name);
                if canon == "Sleep" {
                    self.no_children(e)?;
                    return self.push(e, &base, prefix, parent, depth, &path, wait(1.0));
                }
                self.one_child(e, ty)?;
                let sq = self.push(
                    e,
                    &base,
                    prefix,
                    parent,
                    depth,
                    &path,
                    NodeKind::Sequence {
                        children: Vec::new(),
                    },
                )?;
                let w = self.push(
                    e,
                    &format!("{base}/wait"),
                    prefix,
                    Some(sq),
                    depth + 1,
                    &format!("{path}.0"),
                    wait(1.0),
                )?;
                let c = self.node(
                    e.children[0],
                    Some(sq),
                    depth + 1,
                    format!("{path}.1"),
                    prefix,
                    retry,
                )?;
                self.set_children(sq, vec![w, c]);
                Ok(sq)
            }
            // BT.CPP Timeout: a timer started with the child halts it at
            // `msec` if it is still running, and the next tick returns
            // Failure (no timer for msec 0): the child raced by a deadline,
            // Parallel{M = 1, F = 1}(deadline, child), the deadline first so
            // that it wins a tie (the timer fires before the tick that would
            // see the child's return at the same instant)
            "Timeout" => {
                self.check_attrs(e, &attrs(&["msec"]), false)?;
                let Some(seconds) = self.milliseconds(e, "msec")? else {
                    let base = self.name_attr(e)?.unwrap_or_else(default_name);
                    return self.placeholder(e, &base, parent, depth, &path, prefix, retry);
                };
                self.one_child(e, ty)?;
                let base = self.name_attr(e)?.unwrap_or_else(default_name);
                let race = self.push(
                    e,
                    &base,
                    prefix,
                    parent,
                    depth,
                    &path,
                    NodeKind::Parallel {
                        success_threshold: 1,
                        failure_threshold: 1,
                        children: Vec::new(),
                    },
                )?;
                let mut kids = Vec::new();
                if seconds > 0.0 {
                    let deadline = NodeKind::Action(crate::tree::Action {
                        ps: 0.0,
                        pf: 1.0,
                        success: None,
                        failure: Some(crate::tree::Duration::Fixed { time: seconds }),
                    });
                    kids.push(self.push(
                        e,
                        &format!("{base}/deadline"),
                        prefix,
                        Some(race),
                        depth + 1,
                        &format!("{path}.0"),
                        deadline,
                    )?);
                }
                let c = self.node(
                    e.children[0],
                    Some(race),
                    depth + 1,
                    format!("{path}.{}", kids.len()),
                    prefix,
                    retry,
                )?;
                kids.push(c);
                self.set_children(race, kids);
                Ok(race)
            }
            "AlwaysSuccess" | "AlwaysFailure" => {
                self.check_attrs(e, &attrs(&[]), false)?;
                self.no_children(e)?;
                let base = self.name_attr(e)?.unwrap_or_else(default_name);
                let ps = if canon == "AlwaysSuccess" { 1.0 } else { 0.0 };
                self.push(
                    e,
                    &base,
                    prefix,
                    parent,
                    depth,
                    &path,
                    NodeKind::Condition { ps },
                )
            }
            "Script" | "SetBlackboard" | "UnsetBlackboard" => {
                self.check_attrs(e, &attrs(&[]), true)?;
                self.leaf(e, ty, LeafKind::ZeroTime, parent, depth, &path, prefix)
            }
            // a condition whose outcome is a script over the blackboard: its
            // probability of success comes from the params file (any form,
            // `<Action ID="ScriptCondition">` included)
            "ScriptCondition" => {
                self.check_attrs(e, &attrs(&["code"]), false)?;
                self.leaf(e, ty, LeafKind::Condition, parent, depth, &path, prefix)
            }
            "Precondition" => {
                self.check_attrs(e, &attrs(&["if", "else"]), false)?;
                self.precondition(e, ty, parent, depth, &path, prefix, retry)
            }
            "Switch2" | "Switch3" | "Switch4" | "Switch5" | "Switch6" => {
                let cases = usize::from(canon.as_bytes()[6] - b'0');
                let keys: Vec<String> = (1..=cases).map(|k| format!("case_{k}")).collect();
                let mut allowed = attrs(&["variable"]);
                allowed.extend(keys.iter().map(String::as_str));
                self.check_attrs(e, &allowed, false)?;
                self.switch(e, ty, cases, parent, depth, &path, prefix, retry)
            }
            // BT.CPP's LoopNode<T>; LoopPose is LoopNode<Pose2D> as its
            // t18_waypoints example registers it
            "LoopInt" | "LoopDouble" | "LoopString" | "LoopBool" | "LoopPose" => {
                self.check_attrs(e, &attrs(&["queue", "if_empty", "value"]), false)?;
                self.loop_queue(e, ty, Queue::Loop, parent, depth, &path, prefix, retry)
            }
            // BT.CPP's ConsumeQueue<T> (v3, deprecated in v4 for LoopNode):
            // pops one item per child run from a queue object on the
            // blackboard, a child Failure is its Failure, an empty queue is
            // Success
            "ConsumeQueue" => {
                self.check_attrs(e, &attrs(&["queue", "popped_item"]), false)?;
                self.loop_queue(e, ty, Queue::Consume, parent, depth, &path, prefix, retry)
            }
            // MoveIt Pro's ForEach: ticks its child once per element of
            // `vector_in`, a child Failure ends it with Failure
            "ForEach" => {
                self.check_attrs(e, &attrs(&["vector_in", "out", "index"]), false)?;
                self.loop_queue(e, ty, Queue::ForEach, parent, depth, &path, prefix, retry)
            }
            _ => {
                self.check_attrs(e, &attrs(&[]), true)?;
                let base = self.name_attr(e)?.unwrap_or_else(default_name);
                if let Some(why) = unsupported(canon) {
                    self.problem(e.doc, e.loc, format!("<{ty}>: {why}"), true);
                    return self.placeholder(e, &base, parent, depth, &path, prefix, retry);
                }
                let decl = match form {
                    Some("Action") => Some(Decl::Action),
                    Some("Condition") => Some(Decl::Condition),
                    Some("Control") => Some(Decl::Other("control node")),
                    Some(_) => Some(Decl::Other("decorator")),
                    None => self.model.get(ty).copied(),
                };
                match decl {
                    Some(Decl::Action) => {
                        self.leaf(e, ty, LeafKind::Action, parent, depth, &path, prefix)
                    }
                    Some(Decl::Condition) => {
                        self.leaf(e, ty, LeafKind::Condition, parent, depth, &path, prefix)
                    }
                    Some(Decl::Other(what)) => {
                        self.problem(
                            e.doc,
                            e.loc,
                            format!(
                                "<{ty}>: a custom {what}; btrel models only its own control nodes \
                                 and decorators"
                            ),
                            true,
                        );
                        self.placeholder(e, &base, parent, depth, &path, prefix, retry)
                    }
                    None if e.children.is_empty() => {
                        self.leaf(e, ty, LeafKind::Inferred, parent, depth, &path, prefix)
                    }
                    None => {
                        let mut known: Vec<&str> = BUILTINS.to_vec();
                        known.extend(self.model.keys().copied());
                        let hint = match nearest(ty, &known) {
                            Some(k) => format!(" (did you mean <{k}>?)"),
                            None => String::new(),
                        };
                        self.problem(
                            e.doc,
                            e.loc,
                            format!(
                                "unknown node <{ty}> with children{hint}: a node with children must \
                                 be a control node or decorator that btrel knows, or be declared \
                                 in a <TreeNodesModel>"
                            ),
                            false,
                        );
                        self.placeholder(e, &base, parent, depth, &path, prefix, retry)
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tree(body: &str, params: &str) -> Tree {
        let xml =
            format!("<root BTCPP_format=\"4\"><BehaviorTree ID=\"M\">{body}</BehaviorTree></root>");
        parse_xml_str(&xml, "t.xml", params, "p.yaml").unwrap_or_else(|e| panic!("{e}"))
    }

    fn shape(t: &Tree) -> Vec<(&str, &str)> {
        t.nodes
            .iter()
            .map(|n| (n.name.as_str(), n.kind.keyword()))
            .collect()
    }

    #[test]
    fn control_nodes_and_decorators() {
        let t = tree(
            "<Fallback><Inverter><C/></Inverter><ReactiveSequence name=\"r\"><C/><AlwaysFailure/></ReactiveSequence></Fallback>",
            "C: {ps: 0.25}",
        );
        // names are unique in pre-order: the second C is C#2
        let names: Vec<&str> = t.nodes.iter().map(|n| n.name.as_str()).collect();
        assert_eq!(
            names,
            ["Fallback", "Inverter", "C", "r", "C#2", "AlwaysFailure"]
        );
        assert_eq!(t.nodes[2].kind, NodeKind::Condition { ps: 0.25 });
        assert_eq!(t.nodes[5].kind, NodeKind::Condition { ps: 0.0 });
        let kw = shape(&t);
        assert_eq!(kw[0].1, NodeKind::Fallback { children: vec![] }.keyword());
        assert_eq!(kw[3].1, NodeKind::Sequence { children: vec![] }.keyword());
    }

    #[test]
    fn explicit_forms_and_v3_spellings() {
        let a = tree(
            "<Control ID=\"SequenceStar\"><C/></Control>",
            "C: {ps: 0.5}",
        );
        let b = tree(
            "<SequenceWithMemory><C/></SequenceWithMemory>",
            "C: {ps: 0.5}",
        );
        assert_eq!(shape(&a)[1..], shape(&b)[1..]);
        assert_eq!(a.nodes[0].name, "SequenceStar");
    }

    #[test]
    fn script_nodes_take_no_time() {
        let t = tree(
            "<Sequence><Script code=\"x:=1\"/><C/></Sequence>",
            "C: {ps: 0.5}",
        );
        assert_eq!(t.nodes[1].kind, NodeKind::Condition { ps: 1.0 });
    }

    #[test]
    fn recovery_node_unrolls() {
        // RecoveryNode(main, recovery) with 1 retry:
        // Fallback(main, Sequence(recovery, main)): 5 nodes
        let t = tree(
            "<RecoveryNode number_of_retries=\"1\"><M/><R/></RecoveryNode>",
            "M: {ps: 0.5}\nR: {ps: 0.5}",
        );
        assert_eq!(t.nodes.len(), 5);
    }
}
