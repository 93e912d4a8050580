//! Checks after lowering, and the whole pipeline ([`build_keyed`]): the
//! files' roots and declarations, the main tree, the problems reported at
//! once, the leaves' parameters, unused params keys and the finished tree.

use super::*;

/// One error for every node of `problems` (none: `None`), located at the
/// first, with `help`.
pub(super) fn unsupported_nodes(
    b: &Builder,
    sources: &[Source],
    problems: &[Problem],
    help: &str,
) -> Option<TreeError> {
    let first = problems.first()?;
    let n = problems.len();
    let refs: Vec<&Problem> = problems.iter().collect();
    Some(
        b.err_in(
            Kind::NoMeaning,
            first.doc,
            first.loc,
            format!(
                "{UNSUPPORTED} {n} node{} of this tree:\n{}",
                if n == 1 { "" } else { "s" },
                problem_lines(sources, &refs)
            ),
        )
        .with_help(help.to_string()),
    )
}

/// Formats collected problems as `file:line:column: text` lines.
pub(super) fn problem_lines(sources: &[Source], ps: &[&Problem]) -> String {
    ps.iter()
        .map(|p| {
            format!(
                "  {}:{}:{}: {}",
                sources[p.doc].name, p.loc.0, p.loc.1, p.text
            )
        })
        .collect::<Vec<_>>()
        .join("\n")
}

pub(super) fn build_keyed(
    files: Files,
    params: &str,
    params_file: &str,
) -> Result<Keyed, TreeError> {
    let Files {
        sources,
        elems,
        roots,
        ..
    } = files;
    let table = parse_params(params, params_file)?;
    let mut b = Builder {
        sources: &sources,
        elems: &elems,
        table: &table,
        blackboard_used: Default::default(),
        trees: HashMap::new(),
        model: HashMap::new(),
        nodes: Vec::new(),
        used: HashSet::new(),
        name_bytes: 0,
        leaves: Vec::new(),
        reactive: Vec::new(),
        while_do_else: Vec::new(),
        missing_values: Vec::new(),
        once: Vec::new(),
        problems: Vec::new(),
        seen_problems: HashSet::new(),
        cur: std::cell::Cell::new(0),
        expanding: Vec::new(),
        sizes: HashMap::new(),
        sizing: HashSet::new(),
        slots: HashMap::new(),
        elem_parent: predicates::parents(&elems),
        pre_handled: HashSet::new(),
    };
    let (order, unnamed_main) = declarations(&mut b, &sources, &elems, &roots)?;
    let main_id = lower_main(&mut b, &sources, &elems, &roots, &order, unnamed_main)?;
    let no_meaning_after = report_problems(&b, &sources)?;
    let param_keys = resolve_leaves(&mut b, &table, params, params_file, no_meaning_after)?;
    let loops = check_restarts(&b, &sources)?;
    let mut keys = vec![None; b.nodes.len()];
    for (node, key) in param_keys {
        keys[node] = Some(key);
    }
    check_retick(&b, &sources)?;
    let tree = Tree {
        title: main_id.map(str::to_string),
        nodes: b.nodes,
    };
    if loops.is_empty() {
        return Ok(Keyed { tree, keys });
    }
    // the restart loops, once every check on the built tree is done
    let (tree, keys) =
        reactive::rewrite(&tree, &keys, &loops, MAX_NODES, MAX_DEPTH).map_err(|e| {
            let &(_, doc, loc, _) = b
                .reactive
                .iter()
                .find(|r| loops.contains_key(&r.0))
                .expect("a rewritten node is reactive");
            let s = &sources[doc];
            TreeError::at(Kind::Budget, &s.name, &s.text, loc, e)
        })?;
    Ok(Keyed { tree, keys })
}

/// Step 1: every file's `<root>`: its BehaviorTree definitions (by ID; the
/// main file's in order, with its only unnamed one) and its
/// `<TreeNodesModel>` declarations.
#[allow(clippy::type_complexity)]
fn declarations<'a>(
    b: &mut Builder<'a>,
    sources: &'a [Source],
    elems: &'a [Elem],
    roots: &[usize],
) -> Result<(Vec<(&'a str, usize)>, Option<usize>), TreeError> {
    let mut order: Vec<(&str, usize)> = Vec::new();
    let mut unnamed_main: Option<usize> = None;
    for (doc, &ri) in roots.iter().enumerate() {
        b.cur.set(doc);
        let root = &elems[ri];
        let src = &sources[doc];
        let err =
            |kind: Kind, at: Loc, msg: String| TreeError::at(kind, &src.name, &src.text, at, msg);
        if root.name != "root" {
            return Err(err(Kind::Structure, root.loc, format!("the root element is <{}>, not <root>", root.name))
                .with_help("a BT.CPP file is `<root BTCPP_format=\"4\"> <BehaviorTree ID=\"Main\"> ... </BehaviorTree> </root>`"));
        }
        b.check_attrs(root, &["BTCPP_format", "main_tree_to_execute"], false)?;
        let lone = root
            .children
            .iter()
            .filter(|&&c| elems[c].name == "BehaviorTree")
            .count()
            == 1;
        for &c in &root.children {
            let e = &elems[c];
            match e.name.as_str() {
                "BehaviorTree" => {
                    // other attributes are the SubTree's port defaults
                    b.check_attrs(e, &["ID"], true)?;
                    let id = match e.attr("ID") {
                        // BT.CPP accepts a lone BehaviorTree without an ID
                        None if lone && doc == 0 => {
                            unnamed_main = Some(c);
                            None
                        }
                        None if lone => {
                            return Err(err(Kind::Structure, e.loc, "<BehaviorTree> needs an ID attribute in an included file".into())
                                .with_help("a SubTree refers to an included tree by its ID: write <BehaviorTree ID=\"...\">"))
                        }
                        None => {
                            return Err(err(Kind::Structure, e.loc, "<BehaviorTree> needs an ID attribute".into())
                                .with_help("only a file's only BehaviorTree may omit its ID; write <BehaviorTree ID=\"...\">"))
                        }
                        Some(_) => Some(b.id_attr(e)?),
                    };
                    if e.children.len() != 1 {
                        return Err(err(
                            Kind::Structure,
                            e.loc,
                            format!(
                                "<BehaviorTree{}> must hold exactly one node, found {}",
                                id.map(|i| format!(" ID=\"{i}\"")).unwrap_or_default(),
                                e.children.len()
                            ),
                        )
                        .with_help("wrap several nodes in a <Sequence> or <Fallback>"));
                    }
                    let Some(id) = id else { continue };
                    let defs = b.trees.entry(id).or_default();
                    if let Some(&prev) = defs.iter().find(|&&p| elems[p].doc == doc) {
                        let p = elems[prev].loc;
                        return Err(err(
                            Kind::Structure,
                            e.loc,
                            format!("duplicate BehaviorTree ID `{id}`"),
                        )
                        .with_help(format!(
                            "`{id}` is already defined at line {}, column {}",
                            p.0, p.1
                        )));
                    }
                    defs.push(c);
                    if doc == 0 {
                        order.push((id, c));
                    }
                }
                "TreeNodesModel" => {
                    for &m in &e.children {
                        let d = &elems[m];
                        let decl = match d.name.as_str() {
                            "Action" => Decl::Action,
                            "Condition" => Decl::Condition,
                            "Decorator" => Decl::Other("decorator"),
                            "Control" => Decl::Other("control node"),
                            // a SubTree's model (ports, metadata) says nothing about leaves
                            "SubTree" => continue,
                            other => {
                                return Err(err(Kind::Structure, d.loc, format!("unknown <{other}> in <TreeNodesModel>"))
                                    .with_help("<TreeNodesModel> declares <Action>, <Condition>, <Decorator>, <Control> and <SubTree> entries"));
                            }
                        };
                        let id = b.id_attr(d)?;
                        if let Some(&prev) = b.model.get(id) {
                            if prev != decl {
                                return Err(err(
                                    Kind::Structure,
                                    d.loc,
                                    format!("`{id}` is declared twice with different kinds"),
                                )
                                .with_help("declare each ID once, as an Action or a Condition"));
                            }
                        }
                        b.model.insert(id, decl);
                    }
                }
                // resolved when the file was read
                "include" => {}
                other => {
                    return Err(err(
                        Kind::Structure,
                        e.loc,
                        format!("unknown <{other}> in <root>"),
                    )
                    .with_help(
                        "<root> holds <BehaviorTree>, <TreeNodesModel> and <include> elements",
                    ));
                }
            }
        }
    }
    Ok((order, unnamed_main))
}

/// Step 2: the tree to analyse (`main_tree_to_execute`, else the main
/// file's first), its size checked before it is lowered; returns its ID.
fn lower_main<'a>(
    b: &mut Builder<'a>,
    sources: &'a [Source],
    elems: &'a [Elem],
    roots: &[usize],
    order: &[(&'a str, usize)],
    unnamed_main: Option<usize>,
) -> Result<Option<&'a str>, TreeError> {
    b.cur.set(0);
    let root = &elems[roots[0]];
    let err = |kind: Kind, at: Loc, msg: String| {
        TreeError::at(kind, &sources[0].name, &sources[0].text, at, msg)
    };
    let (main_id, main): (Option<&str>, usize) = match root.attr("main_tree_to_execute") {
        Some(a) => match b.lookup_tree(&a.value, a.loc)? {
            Some(t) => (Some(a.value.as_str()), t),
            None => {
                let ids: Vec<&str> = b.trees.keys().copied().collect();
                let mut sorted = ids.clone();
                sorted.sort_unstable();
                let hint = match nearest(&a.value, &ids) {
                    Some(k) => format!("did you mean `{k}`? trees: {}", sorted.join(", ")),
                    None => format!("trees: {}", sorted.join(", ")),
                };
                return Err(err(
                    Kind::Structure,
                    a.loc,
                    format!("no <BehaviorTree ID=\"{}\">", a.value),
                )
                .with_help(hint));
            }
        },
        None => match (order.first(), unnamed_main) {
            (Some(&(id, t)), _) => (Some(id), t),
            (None, Some(t)) => (None, t),
            (None, None) => {
                return Err(err(
                    Kind::Structure,
                    root.loc,
                    "the file has no <BehaviorTree>".into(),
                )
                .with_help("add <BehaviorTree ID=\"Main\"> holding the root node"))
            }
        },
    };
    let size = match main_id {
        Some(id) => b.tree_size(id, 0),
        None => b.elem_size(elems[main].children[0], 0),
    };
    if size > MAX_NODES as u64 {
        return Err(err(
            Kind::Budget,
            elems[main].loc,
            format!("the tree has too many nodes after SubTree expansion ({size})"),
        )
        .with_help(format!("btrel accepts at most {MAX_NODES} nodes")));
    }
    if let Some(id) = main_id {
        b.expanding.push((id, elems[main].loc));
    }
    b.node(elems[main].children[0], None, 0, "0".into(), "", None)?;
    b.expanding.pop();
    Ok(main_id)
}

/// Step 3: the problems collected while lowering, all in one error: unknown
/// nodes and SubTrees defined nowhere (UnknownNode, or UndefinedSubTree
/// when only SubTrees are), else nodes without a
/// stochastic meaning (NoMeaning). While blackboard values are missing the
/// latter wait: returned as the text that follows the missing parameters.
fn report_problems(b: &Builder, sources: &[Source]) -> Result<Option<String>, TreeError> {
    // Nodes without a stochastic meaning wait while the params file lacks
    // blackboard values: the fix for those is a params entry, so they are
    // reported as missing parameters, with these nodes listed after them.
    let mut no_meaning_after: Option<String> = None;
    if !b.problems.is_empty() {
        let (semantic, front): (Vec<&Problem>, Vec<&Problem>) =
            b.problems.iter().partition(|p| p.semantic);
        if front.is_empty() && !b.missing_values.is_empty() {
            let n = semantic.len();
            no_meaning_after = Some(format!(
                "\nand {UNSUPPORTED} {n} node{} of this tree:\n{}",
                if n == 1 { "" } else { "s" },
                problem_lines(sources, &semantic)
            ));
        }
    }
    if !b.problems.is_empty() && no_meaning_after.is_none() {
        let (semantic, front): (Vec<&Problem>, Vec<&Problem>) =
            b.problems.iter().partition(|p| p.semantic);
        let (kind, first, message, help) = if front.is_empty() {
            let n = semantic.len();
            (
                Kind::NoMeaning,
                semantic[0],
                format!(
                    "{UNSUPPORTED} {n} node{} of this tree:\n{}",
                    if n == 1 { "" } else { "s" },
                    problem_lines(sources, &semantic)
                ),
                "these BT.CPP node types (or attributes) have no model as a Stochastic Behavior \
                 Tree in btrel yet; read: Sequence, SequenceWithMemory, ReactiveSequence, \
                 Fallback, ReactiveFallback, Parallel, Inverter, ForceSuccess, ForceFailure, \
                 RetryUntilSuccessful, Repeat, RecoveryNode, SubTree, AlwaysSuccess, \
                 AlwaysFailure, Script, SetBlackboard, UnsetBlackboard, ScriptCondition, \
                 Precondition, Switch2..Switch6, LoopInt/LoopDouble/LoopString/LoopBool/LoopPose, \
                 pre-conditions \
                 (_failureIf, _successIf; _skipIf, _while below a Sequence or Fallback) and \
                 custom leaves"
                    .to_string(),
            )
        } else {
            let n = front.len();
            let mut message = format!(
                "{n} node{} cannot be read:\n{}",
                if n == 1 { "" } else { "s" },
                problem_lines(sources, &front)
            );
            if !semantic.is_empty() {
                message.push_str(&format!(
                    "\nand {UNSUPPORTED} {} node{}:\n{}",
                    semantic.len(),
                    if semantic.len() == 1 { "" } else { "s" },
                    problem_lines(sources, &semantic)
                ));
            }
            let mut help = Vec::new();
            if front.iter().any(|p| p.text.starts_with("unknown node")) {
                help.push(
                    "a leaf (an element without children) needs no declaration, its params entry \
                     makes it an action or a condition; a node with children must be a known \
                     control node or decorator",
                );
            }
            if front.iter().any(|p| p.text.starts_with("no <BehaviorTree")) {
                help.push("a SubTree's BehaviorTree may be defined in an included file");
            }
            let kind = if front.iter().all(|p| p.text.starts_with("no <BehaviorTree")) {
                Kind::UndefinedSubTree
            } else {
                Kind::UnknownNode
            };
            (kind, front[0], message, help.join("; "))
        };
        return Err(b
            .err_in(kind, first.doc, first.loc, message)
            .with_help(help));
    }
    Ok(no_meaning_after)
}

/// Step 5: reactive nodes with actions in two children (their restart
/// loops, or refused) and WhileDoElse with an action in its condition.
fn check_restarts(
    b: &Builder,
    sources: &[Source],
) -> Result<HashMap<usize, reactive::Restart>, TreeError> {
    // A Reactive node halts (resets) its other children when one returns
    // RUNNING and ticks them again from IDLE on the next tick: an action in
    // an earlier child is restarted while a later child runs (and that one
    // is halted), which a Sequence / Fallback does not model. Refused when
    // two or more children hold actions that take time; conditions only
    // re-read their value, and zero-time actions (`tau_s: 0`, `tau_f: 0`:
    // synchronous, never RUNNING) return in the tick that starts them.
    let has_action = |root: usize| {
        let mut stack = vec![root];
        while let Some(n) = stack.pop() {
            match &b.nodes[n].kind {
                NodeKind::Action(a)
                    if [a.success, a.failure].iter().flatten().any(
                        |d| !matches!(d, crate::tree::Duration::Fixed { time } if *time == 0.0),
                    ) =>
                {
                    return true
                }
                NodeKind::Action(_) => {}
                k => stack.extend(k.children().iter().copied()),
            }
        }
        false
    };
    let mut restarts: Vec<Problem> = Vec::new();
    let mut loops: HashMap<usize, reactive::Restart> = HashMap::new();
    for &(id, doc, loc, ty) in &b.reactive {
        // a PathLongerOnApproach that returned Success below a
        // ReactiveSequence, ticked again (even from IDLE), finds the path it
        // stored and returns Success at once: it is never restarted, though
        // a later child that runs is halted while its own child runs
        let once = |c: usize| {
            ty == "ReactiveSequence"
                && b.once
                    .iter()
                    .any(|o| o.0 == c && o.3 == "PathLongerOnApproach")
        };
        let children = b.nodes[id].kind.children();
        let kids: Vec<usize> = (0..children.len())
            .filter(|&i| has_action(children[i]))
            .collect();
        let restarted = kids
            .split_last()
            .is_some_and(|(_, earlier)| earlier.iter().any(|&i| !once(children[i])));
        if !restarted {
            continue;
        }
        // the restart loop (reactive.rs): the first two children that take
        // time must surely return RUNNING at their first tick, and the
        // first must be restarted (not a PathLongerOnApproach)
        let (first, second) = (kids[0], kids[1]);
        let name = |i: usize| format!("'{}'", b.nodes[children[i]].name);
        let unsure: Vec<String> = [first, second]
            .into_iter()
            .filter(|&i| !reactive::surely_timed(&b.nodes, children[i]))
            .map(name)
            .collect();
        if !unsure.is_empty() || once(children[first]) {
            let why = if unsure.is_empty() {
                format!(
                    "its first child that takes time, {}, is a PathLongerOnApproach, which is \
                     not restarted while a later child is",
                    name(first)
                )
            } else {
                format!(
                    "{} may return within its first tick or take time, which decides whether \
                     the children are restarted",
                    unsure.join(" and ")
                )
            };
            restarts.push(Problem {
                doc,
                loc,
                text: format!(
                    "<{ty}> with actions that take time in {} children ({}): BT.CPP halts its \
                     other children when one returns RUNNING and ticks them again from IDLE; \
                     btrel reads this restart loop exactly when the first two such children \
                     surely return RUNNING at their first tick, but {why}",
                    kids.len(),
                    kids.iter().map(|&i| name(i)).collect::<Vec<_>>().join(", "),
                ),
                semantic: true,
            });
            continue;
        }
        loops.insert(
            id,
            reactive::Restart {
                first,
                second,
                sequence: ty == "ReactiveSequence",
            },
        );
    }
    // WhileDoElse ticks its condition child again at every tick of a
    // running branch and halts the branch if the outcome changes: with
    // conditions only (which keep their value) that is IfThenElse; an action
    // there would be ticked again after it returned, which no fresh run
    // models.
    for &(id, doc, loc) in &b.while_do_else {
        let condition = b.nodes[id].kind.children()[0];
        if has_action(condition) {
            restarts.push(Problem {
                doc,
                loc,
                text: "<WhileDoElse> whose condition child holds an action: BT.CPP ticks that \
                       child again at every tick while a branch runs (and halts the branch when \
                       its outcome changes); read as IfThenElse only when the condition child \
                       takes no time (conditions only)"
                    .to_string(),
                semantic: true,
            });
        }
    }
    if let Some(e) = unsupported_nodes(
        b,
        sources,
        &restarts,
        "ReactiveSequence and ReactiveFallback are read as Sequence and Fallback when \
                 at most one child holds actions (conditions before it are re-ticked, which \
                 changes nothing while they keep their value), and as their restart loop when \
                 two children hold actions that surely take time (docs/TREE-FORMAT.md, node table); \
                 WhileDoElse is read as IfThenElse when its condition child holds conditions \
                 only",
    ) {
        return Err(e);
    }
    Ok(loops)
}

/// Step 6: nodes whose re-tick as an earlier PipelineSequence child btrel
/// would read as a re-run.
fn check_retick(b: &Builder, sources: &[Source]) -> Result<(), TreeError> {
    // GoalUpdatedController and PathLongerOnApproach ticked again after
    // returning (an earlier PipelineSequence child) do not run their child
    // again while the goal and the path keep their values; btrel reads a
    // re-ticked subtree that takes time and can fail as re-run
    let mut again: Vec<Problem> = Vec::new();
    let view = Tree {
        title: None,
        nodes: if b.once.is_empty() {
            Vec::new()
        } else {
            b.nodes.clone()
        },
    };
    for &(id, doc, loc, ty) in &b.once {
        let tree = &view;
        let Some(p) = tree.nodes[id].parent else {
            continue;
        };
        let earlier = match &tree.nodes[p].kind {
            NodeKind::Pipeline { children } => children.last() != Some(&id),
            _ => false,
        };
        if earlier && crate::tree::nav2::retick(tree, id) != crate::tree::nav2::Retick::Inert {
            again.push(Problem {
                doc,
                loc,
                text: format!(
                    "<{ty}> as an earlier child of a PipelineSequence: ticked again while a later \
                     child runs it does not run its child again (the goal and the path keep \
                     their values), while btrel's PipelineSequence would re-run a subtree that \
                     takes time and can fail"
                ),
                semantic: true,
            });
        }
    }
    if let Some(e) = unsupported_nodes(
        b,
        sources,
        &again,
        "as an earlier PipelineSequence child, GoalUpdatedController is read exactly when \
                 its child is a leaf, takes no time or cannot fail, and PathLongerOnApproach when \
                 its child takes no time or cannot fail",
    ) {
        return Err(e);
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn keyed(body: &str, params: &str) -> Result<Keyed, TreeError> {
        let xml = format!(
            "<root BTCPP_format=\"4\">\n<BehaviorTree ID=\"M\">\n{body}\n</BehaviorTree>\n</root>"
        );
        parse_xml_str_keyed(&xml, "t.xml", params, "p.yaml")
    }

    #[test]
    fn leaves_take_their_keys() {
        let k = keyed(
            "<Sequence><A name=\"a\"/><B/></Sequence>",
            "a: {ps: 0.5, mu: 1, nu: 1}\nB: {ps: 0.9}\n",
        )
        .unwrap();
        let names: Vec<&str> = k.tree.nodes.iter().map(|n| n.name.as_str()).collect();
        assert_eq!(names, ["Sequence", "a", "B"]);
        assert_eq!(k.keys, [None, Some("a".into()), Some("B".into())]);
        assert_eq!(k.tree.nodes[2].kind, NodeKind::Condition { ps: 0.9 });
    }

    #[test]
    fn missing_parameters_are_listed_at_once() {
        // the body is line 3: <Sequence> at column 1, <A/> at 11, <B/> at 15
        let e = keyed("<Sequence><A/><B/></Sequence>", "").unwrap_err();
        assert_eq!(e.kind, Kind::MissingParameter);
        assert_eq!((e.line, e.column), (3, 11));
        let lines: Vec<&str> = e.message.lines().collect();
        assert_eq!(lines[0], "missing parameters for 2 nodes in p.yaml:");
        assert!(
            lines[1].starts_with("  t.xml:3:11: leaf `A` (ID `A`): no entry"),
            "{e}"
        );
        assert!(
            lines[2].starts_with("  t.xml:3:15: leaf `B` (ID `B`): no entry"),
            "{e}"
        );
    }

    #[test]
    fn problems_are_reported_by_kind() {
        let e = keyed("<RunOnce><A/></RunOnce>", "A: {ps: 1}").unwrap_err();
        assert_eq!((e.kind, e.line, e.column), (Kind::NoMeaning, 3, 1));
        let e = keyed("<Mystery><A/></Mystery>", "A: {ps: 1}").unwrap_err();
        assert_eq!(e.kind, Kind::UnknownNode);
        assert!(e
            .message
            .starts_with("1 node cannot be read:\n  t.xml:3:1: unknown node <Mystery>"));
    }

    #[test]
    fn unused_params_keys_are_refused() {
        let e = keyed("<A/>", "A: {ps: 1}\nZ: {ps: 1}\n").unwrap_err();
        assert_eq!(
            (e.kind, e.file.as_str(), e.line),
            (Kind::InvalidValue, "p.yaml", 2)
        );
        assert_eq!(e.message, "params key `Z` matches no action or condition");
        let e = keyed("<A/>", "A: {ps: 1}\n\"{n}\": {value: 1}\n").unwrap_err();
        assert_eq!((e.kind, e.line), (Kind::InvalidValue, 2));
    }

    #[test]
    fn problem_lines_are_located() {
        let sources = [Source {
            name: "t.xml".into(),
            text: String::new(),
            format: Format::V4,
        }];
        let p = Problem {
            doc: 0,
            loc: (2, 5),
            text: "<X>: why".into(),
            semantic: true,
        };
        assert_eq!(
            problem_lines(&sources, &[&p, &p]),
            "  t.xml:2:5: <X>: why\n  t.xml:2:5: <X>: why"
        );
    }
}
