//! Lowering, the per-type steps of [`Builder::node_here`] that take more
//! than a few lines: control nodes, decorators, timers, and any other type
//! (leaves, custom nodes, types without a stochastic meaning).

use super::*;

impl<'a> Builder<'a> {
    /// PipelineSequence and RoundRobin (its index slot shared by copies).
    pub(super) fn lower_pipeline(&mut self, h: Here<'a, '_>) -> Result<usize, TreeError> {
        let Here {
            ei,
            e,
            ty,
            form,
            canon,
            parent,
            depth,
            path,
            prefix,
            retry,
        } = h;
        let attrs = |extra: &[&'static str]| allowed_attrs(form, extra);
        let default_name = || ty.to_string();
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

    /// Sequence, Fallback, their reactive and memory forms, and Parallel.
    pub(super) fn lower_control(&mut self, h: Here<'a, '_>) -> Result<usize, TreeError> {
        let Here {
            ei,
            e,
            ty,
            form,
            canon,
            parent,
            depth,
            path,
            prefix,
            retry,
        } = h;
        let attrs = |extra: &[&'static str]| allowed_attrs(form, extra);
        let default_name = || ty.to_string();
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
                    halt_resets: ty == "SequenceStar" || self.sources[e.doc].format == Format::V3,
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

    /// IfThenElse and WhileDoElse: a flow over the condition and branches.
    pub(super) fn lower_if_then_else(&mut self, h: Here<'a, '_>) -> Result<usize, TreeError> {
        let Here {
            e,
            ty,
            form,
            canon,
            parent,
            depth,
            path,
            prefix,
            retry,
            ..
        } = h;
        let attrs = |extra: &[&'static str]| allowed_attrs(form, extra);
        let default_name = || ty.to_string();
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

    /// Inverter, ForceSuccess, ForceFailure, RetryUntilSuccessful, Repeat and KeepRunningUntilFailure.
    pub(super) fn lower_decorator(&mut self, h: Here<'a, '_>) -> Result<usize, TreeError> {
        let Here {
            e,
            ty,
            form,
            canon,
            parent,
            depth,
            path,
            prefix,
            retry,
            ..
        } = h;
        let attrs = |extra: &[&'static str]| allowed_attrs(form, extra);
        let default_name = || ty.to_string();
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

    /// Sleep and Delay: fixed times from `msec` / `delay_msec`.
    pub(super) fn lower_sleep_delay(&mut self, h: Here<'a, '_>) -> Result<usize, TreeError> {
        let Here {
            e,
            ty,
            form,
            canon,
            parent,
            depth,
            path,
            prefix,
            retry,
            ..
        } = h;
        let attrs = |extra: &[&'static str]| allowed_attrs(form, extra);
        let default_name = || ty.to_string();
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

    /// Timeout: the child raced by a deadline.
    pub(super) fn lower_timeout(&mut self, h: Here<'a, '_>) -> Result<usize, TreeError> {
        let Here {
            e,
            ty,
            form,
            parent,
            depth,
            path,
            prefix,
            retry,
            ..
        } = h;
        let attrs = |extra: &[&'static str]| allowed_attrs(form, extra);
        let default_name = || ty.to_string();
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

    /// Any other type: a leaf (by its form, model or params entry), a custom node, or a type without a stochastic meaning.
    pub(super) fn lower_other(&mut self, h: Here<'a, '_>) -> Result<usize, TreeError> {
        let Here {
            e,
            ty,
            form,
            canon,
            parent,
            depth,
            path,
            prefix,
            retry,
            ..
        } = h;
        let attrs = |extra: &[&'static str]| allowed_attrs(form, extra);
        let default_name = || ty.to_string();
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
            Some(Decl::Action) => self.leaf(e, ty, LeafKind::Action, parent, depth, &path, prefix),
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
