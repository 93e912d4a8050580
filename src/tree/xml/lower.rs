//! Lowering one XML element to tree nodes: the dispatch over node types
//! (`node`, `node_here`).

use super::*;

/// The element being lowered and where its node goes: what each per-type
/// step of [`Builder::node_here`] reads.
pub(super) struct Here<'a, 'p> {
    pub(super) ei: usize,
    pub(super) e: &'a Elem,
    /// The node type as written (`SequenceStar`, or the ID of an explicit
    /// form), and as read (`SequenceWithMemory`).
    pub(super) ty: &'a str,
    pub(super) canon: &'a str,
    /// The explicit form (`Action`, `Condition`, `Control`, `Decorator`).
    pub(super) form: Option<&'a str>,
    pub(super) parent: Option<usize>,
    pub(super) depth: usize,
    pub(super) path: String,
    pub(super) prefix: &'p str,
    pub(super) retry: Option<&'static str>,
}

/// The attributes a node accepts: `extra`, `name`, and `ID` in an explicit
/// form.
pub(super) fn allowed_attrs(form: Option<&str>, extra: &[&'static str]) -> Vec<&'static str> {
    let with_id: &[&'static str] = if form.is_some() {
        &["name", "ID"]
    } else {
        &["name"]
    };
    with_id.iter().chain(extra).copied().collect()
}

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
        // the arms that take more than a few lines are named steps
        let here = |path: String| Here {
            ei,
            e,
            ty,
            canon,
            form,
            parent,
            depth,
            path,
            prefix,
            retry,
        };
        match canon {
            "PipelineSequence" | "RoundRobin" => self.lower_pipeline(here(path)),
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
            | "ReactiveFallback" | "Parallel" => self.lower_control(here(path)),
            "IfThenElse" | "WhileDoElse" => self.lower_if_then_else(here(path)),
            "Inverter"
            | "ForceSuccess"
            | "ForceFailure"
            | "RetryUntilSuccessful"
            | "Repeat"
            | "KeepRunningUntilFailure" => self.lower_decorator(here(path)),
            "RecoveryNode" => {
                self.check_attrs(e, &attrs(&["number_of_retries"]), false)?;
                self.recovery(e, ty, parent, depth, path, prefix, retry)
            }
            // BT.CPP Sleep: Success after `msec`; Delay: waits `delay_msec`,
            // then runs its child and returns what it returns
            "Sleep" | "Delay" => self.lower_sleep_delay(here(path)),
            // BT.CPP Timeout: a timer started with the child halts it at
            // `msec` if it is still running, and the next tick returns
            // Failure (no timer for msec 0): the child raced by a deadline,
            // Parallel{M = 1, F = 1}(deadline, child), the deadline first so
            // that it wins a tie (the timer fires before the tick that would
            // see the child's return at the same instant)
            "Timeout" => self.lower_timeout(here(path)),
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
            _ => self.lower_other(here(path)),
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
