//! BehaviorTree.CPP v4 XML import: twins of the bundled YAML trees, SubTree
//! expansion, the short form, and every refusal with its location.

use std::path::Path;

use btrel::compile::{analyze, Options};
use btrel::tree::xml::{is_unsupported, parse_xml_file, parse_xml_str, parse_xml_str_with};
use btrel::tree::{parse_file, Decorator, NodeKind, Tree, TreeError, TreeErrorKind};

fn xml(src: &str, params: &str) -> Result<Tree, TreeError> {
    parse_xml_str(src, "t.xml", params, "t.params.yaml")
}

fn ok(src: &str, params: &str) -> Tree {
    xml(src, params).unwrap_or_else(|e| panic!("{e}"))
}

fn err(src: &str, params: &str) -> TreeError {
    match xml(src, params) {
        Ok(t) => panic!("expected an error, got {t:?}"),
        Err(e) => e,
    }
}

fn wrap(body: &str) -> String {
    format!(
        "<root BTCPP_format=\"4\">\n<BehaviorTree ID=\"Main\">\n{body}\n</BehaviorTree>\n</root>\n"
    )
}

fn names(t: &Tree) -> Vec<&str> {
    t.nodes().iter().map(|n| n.name.as_str()).collect()
}

fn close(a: f64, b: f64) -> bool {
    (a - b).abs() <= 1e-12 * a.abs().max(b.abs()).max(1e-300)
}

fn same_figures(name: &str) {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("trees");
    let y = parse_file(&dir.join(format!("{name}.yaml"))).unwrap();
    let x = parse_xml_file(
        &dir.join(format!("{name}.xml")),
        &dir.join(format!("{name}.params.yaml")),
    )
    .unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(x.nodes().len(), y.nodes().len());
    let ay = analyze(&y, &Options::default()).unwrap();
    let ax = analyze(&x, &Options::default()).unwrap();
    for (i, n) in y.nodes().iter().enumerate() {
        let j = x
            .find(&n.name)
            .unwrap_or_else(|| panic!("{} missing", n.name));
        assert_eq!(x.nodes()[j].path, n.path, "{}", n.name);
        assert_eq!(x.nodes()[j].kind.keyword(), n.kind.keyword(), "{}", n.name);
        let (fy, fx) = (ay.nodes[i], ax.nodes[j]);
        assert!(close(fx.ps, fy.ps) && close(fx.pf, fy.pf), "{}", n.name);
        for (a, b) in [(fx.mtts, fy.mtts), (fx.mttf, fy.mttf)] {
            match (a, b) {
                (Some(a), Some(b)) => assert!(close(a, b), "{}: {a} vs {b}", n.name),
                (a, b) => assert_eq!(a, b, "{}", n.name),
            }
        }
    }
}

#[test]
fn twins_give_the_same_figures() {
    same_figures("search-and-grasp");
    same_figures("two-arm-parallel");
}

#[test]
fn control_nodes_and_decorators_map() {
    let t = ok(
        &wrap(
            // (a ReactiveSequence with actions in several children is refused:
            // tests/btcpp_referee.rs)
            r#"<Sequence>
  <SequenceWithMemory><A/></SequenceWithMemory>
  <ReactiveFallback><A/><AlwaysFailure/></ReactiveFallback>
  <Inverter><ForceSuccess><ForceFailure><A name="x &amp; &#x79;"/></ForceFailure></ForceSuccess></Inverter>
  <RetryUntilSuccessful num_attempts="3"><Repeat num_cycles='2'><AlwaysSuccess/></Repeat></RetryUntilSuccessful>
</Sequence>
<!-- trailing comment -->"#,
        )
        .replace("</root>", "<TreeNodesModel><Action ID=\"A\"/></TreeNodesModel></root>"),
        "A: {ps: 0.5, mu: 1, nu: 2}",
    );
    assert_eq!(
        names(&t),
        [
            "Sequence",
            "SequenceWithMemory",
            "A",
            "ReactiveFallback",
            "A#2",
            "AlwaysFailure",
            "Inverter",
            "ForceSuccess",
            "ForceFailure",
            "x & y",
            "RetryUntilSuccessful",
            "Repeat",
            "AlwaysSuccess"
        ]
    );
    assert_eq!(t.nodes()[0].kind.keyword(), "sequence");
    assert_eq!(t.nodes()[1].kind.keyword(), "sequence");
    assert_eq!(t.nodes()[3].kind.keyword(), "fallback");
    assert_eq!(t.nodes()[5].kind, NodeKind::Condition { ps: 0.0 });
    assert_eq!(t.nodes()[12].kind, NodeKind::Condition { ps: 1.0 });
    assert!(matches!(
        t.nodes()[10].kind,
        NodeKind::Decorator {
            decorator: Decorator::Retry { attempts: 3 },
            child: 11
        }
    ));
    assert!(matches!(
        t.nodes()[11].kind,
        NodeKind::Decorator {
            decorator: Decorator::Repeat { times: 2 },
            ..
        }
    ));
    assert_eq!(t.nodes()[9].path, "0.2.0.0.0");
    assert_eq!(t.nodes()[9].depth, 4);
    assert_eq!(t.nodes()[9].parent, Some(8));
    assert_eq!(t.nodes()[2].location, Some((4, 23)));
    assert_eq!(t.title(), Some("Main"));
    analyze(&t, &Options::default()).unwrap();
}

#[test]
fn parallel_counts() {
    let leaves = "<A/><A/><A/><A/>";
    let model = "<TreeNodesModel><Condition ID=\"A\"/></TreeNodesModel></root>";
    let par = |attrs: &str| {
        let src = wrap(&format!("<Parallel {attrs}>{leaves}</Parallel>")).replace("</root>", model);
        match &ok(&src, "A: {ps: 0.5}").nodes()[0].kind {
            NodeKind::Parallel {
                success_threshold,
                failure_threshold,
                children,
            } => (*success_threshold, *failure_threshold, children.len()),
            k => panic!("{k:?}"),
        }
    };
    assert_eq!(par(""), (4, 1, 4)); // BT.CPP v4 defaults -1, 1
    assert_eq!(par("success_count=\"2\" failure_count=\"2\""), (2, 2, 4)); // F != N-M+1 = 3
    assert_eq!(par("success_count=\"1\" failure_count=\"-1\""), (1, 4, 4));
    assert_eq!(par("success_count=\"-2\""), (3, 1, 4));
    for bad in [
        "success_count=\"5\"",
        "failure_count=\"0\"",
        "success_count=\"-5\"",
        "success_count=\"{m}\"",
        "failure_count=\"1.5\"",
    ] {
        let src = wrap(&format!("<Parallel {bad}>{leaves}</Parallel>")).replace("</root>", model);
        let e = err(&src, "A: {ps: 0.5}");
        assert_eq!((e.line, e.column), (3, 11), "{bad}: {e}");
    }
}

#[test]
fn subtrees_expand_with_prefixed_names() {
    let src = r#"<root BTCPP_format="4" main_tree_to_execute="Main">
  <BehaviorTree ID="Grasp">
    <Fallback><Action ID="Hand" name="one"/><SubTree ID="Two"/></Fallback>
  </BehaviorTree>
  <BehaviorTree ID="Two">
    <Action ID="Hand" name="two"/>
  </BehaviorTree>
  <BehaviorTree ID="Main">
    <Sequence>
      <SubTree ID="Grasp" name="left" target="{left}" _autoremap="true"/>
      <SubTree ID="Grasp"/>
      <Action ID="Hand" name="one"/>
    </Sequence>
  </BehaviorTree>
</root>"#;
    let t = ok(
        src,
        "Hand: {ps: 0.5, mu: 1, nu: 2}\nleft/one: {ps: 0.25, mu: 1, nu: 2}",
    );
    assert_eq!(
        names(&t),
        [
            "Sequence",
            "left/Fallback",
            "left/one",
            "left/Two/two",
            "Grasp/Fallback",
            "Grasp/one",
            "Grasp/Two/two",
            "one"
        ]
    );
    assert_eq!(t.nodes()[3].path, "0.0.1");
    assert_eq!(t.nodes()[3].depth, 2);
    assert_eq!(t.nodes()[3].location, Some((6, 5)));
    // lookup: full name first, then name attribute, then ID
    let ps = |i: usize| match t.nodes()[i].kind {
        NodeKind::Action(a) => a.ps,
        _ => panic!(),
    };
    assert_eq!((ps(2), ps(5), ps(7)), (0.25, 0.5, 0.5));
    assert_eq!(t.title(), Some("Main"));
    // without main_tree_to_execute: the first tree
    let first = src.replace(" main_tree_to_execute=\"Main\"", "");
    let t = ok(&first, "Hand: {ps: 0.5, mu: 1, nu: 2}");
    assert_eq!(names(&t), ["Fallback", "one", "Two/two"]);
}

#[test]
fn subtree_recursion_is_named() {
    let src = r#"<root BTCPP_format="4" main_tree_to_execute="Main">
  <BehaviorTree ID="Main"><Sequence><SubTree ID="A"/></Sequence></BehaviorTree>
  <BehaviorTree ID="A"><Fallback><SubTree ID="B"/></Fallback></BehaviorTree>
  <BehaviorTree ID="B"><Inverter><SubTree ID="A"/></Inverter></BehaviorTree>
</root>"#;
    let e = err(src, "");
    assert!(e.message.contains("recursive SubTree: A -> B -> A"), "{e}");
    assert_eq!((e.line, e.column), (4, 34));
    let selfref = wrap("<SubTree ID=\"Main\"/>");
    let e = err(&selfref, "");
    assert!(e.message.contains("Main -> Main"), "{e}");
    let e = err(&wrap("<SubTree ID=\"Mainn\"/>"), "");
    assert!(e.message.contains("did you mean `Main`"), "{e}");
}

#[test]
fn short_form_leaves_are_inferred_or_taken_from_the_model() {
    // no model: a leaf's params entry decides (ps only: condition)
    let t = ok(
        &wrap("<Sequence>\n  <Grasp/>\n  <Ready/>\n</Sequence>"),
        "Grasp: {ps: 1, mu: 1}\nReady: {ps: 0.5}",
    );
    assert!(matches!(t.nodes()[1].kind, NodeKind::Action(a) if a.ps == 1.0));
    assert_eq!(t.nodes()[2].kind, NodeKind::Condition { ps: 0.5 });
    // a typo of a control node with children is an unknown node
    let e = err(&wrap("<Sequense><AlwaysSuccess/></Sequense>"), "");
    assert!(e.message.contains("did you mean <Sequence>"), "{e}");
    assert!(!is_unsupported(&e));
    // the model wins over the inference
    let with_model = wrap("<Sequence><Grasp/><Ready/></Sequence>").replace(
        "</root>",
        "<TreeNodesModel><Action ID=\"Grasp\"><input_port name=\"x\">text is fine here</input_port></Action><Condition ID=\"Ready\"/></TreeNodesModel></root>",
    );
    let t = ok(&with_model, "Grasp: {ps: 1, mu: 1}\nReady: {ps: 0.5}");
    assert!(matches!(t.nodes()[1].kind, NodeKind::Action(a) if a.ps == 1.0));
    assert_eq!(t.nodes()[2].kind, NodeKind::Condition { ps: 0.5 });
    let e = err(&with_model, "Grasp: {ps: 1}\nReady: {ps: 0.5}");
    assert!(e.message.contains("no success time"), "{e}");
    let custom = wrap("<MyDeco><AlwaysSuccess/></MyDeco>").replace(
        "</root>",
        "<TreeNodesModel><Decorator ID=\"MyDeco\"/></TreeNodesModel></root>",
    );
    let e = err(&custom, "");
    assert!(e.message.contains("<MyDeco>: a custom decorator"), "{e}");
    assert!(is_unsupported(&e));
}

#[test]
fn refusals_have_locations() {
    let cases: &[(&str, (usize, usize), &str)] = &[
        ("<BlackboardCheckInt value_A=\"{x}\" value_B=\"1\" return_on_mismatch=\"FAILURE\"><AlwaysSuccess/></BlackboardCheckInt>", (3, 1), "<BlackboardCheckInt>: its outcome is computed from blackboard values"),
        ("<Sequence>\n <Switch2 variable=\"{v}\"><AlwaysSuccess/></Switch2></Sequence>", (4, 2), "<Switch2>"),
        ("<RunOnce><AlwaysSuccess/></RunOnce>", (3, 1), "<RunOnce>"),
        ("<Delay delay_msec=\"{d}\"><AlwaysSuccess/></Delay>", (3, 8), "blackboard"),
        ("<Sleep msec=\"{t}\"/>", (3, 8), "blackboard"),
        ("<Timeout msec=\"{t}\"><AlwaysSuccess/></Timeout>", (3, 10), "blackboard"),
        ("<Sequence _skipIf=\"x\"><AlwaysSuccess/></Sequence>", (3, 11), "`_skipIf`"),
        ("<Action ID=\"A\" _while=\"x\"/>", (3, 16), "`_while`"),
        ("<Sequence port=\"{x}\"><AlwaysSuccess/></Sequence>", (3, 11), "unknown attribute `port`"),
        ("<RetryUntilSuccessful><AlwaysSuccess/></RetryUntilSuccessful>", (3, 1), "needs `num_attempts`"),
        ("<Repeat num_cycles=\"{n}\"><AlwaysSuccess/></Repeat>", (3, 9), "blackboard"),
        ("<Repeat num_cycles=\"0\"><AlwaysSuccess/></Repeat>", (3, 9), "not a valid count"),
        ("<Inverter><AlwaysSuccess/><AlwaysSuccess/></Inverter>", (3, 1), "exactly one child"),
        ("<Sequence/>", (3, 1), "no children"),
        ("<Action ID=\"A\"><AlwaysSuccess/></Action>", (3, 16), "takes no children"),
        ("<Action/>", (3, 1), "needs an ID"),
        ("<Action ID=\"A\" name=\"\"/>", (3, 16), "must not be empty"),
        ("<Foo><AlwaysSuccess/></Foo>", (3, 1), "unknown node <Foo> with children"),
        ("<Fooo/>", (3, 1), "leaf `Fooo` (ID `Fooo`): no entry"),
        ("<SubTree ID=\"Nope\"/>", (3, 1), "no <BehaviorTree ID=\"Nope\">"),
        ("<Control ID=\"MySelector\"><AlwaysSuccess/></Control>", (3, 1), "<MySelector>: a custom control node"),
        ("<Parallel success_threshold=\"1\"><AlwaysSuccess/></Parallel>", (3, 11), "unknown attribute `success_threshold`"),
    ];
    for (body, at, what) in cases {
        let e = err(&wrap(body), "A: {ps: 0.5, mu: 1, nu: 1}");
        assert_eq!((e.line, e.column), *at, "{body}: {e}");
        assert!(e.message.contains(what), "{body}: {e}");
        assert!(e.help.is_some(), "{body}: {e}");
        assert_eq!(e.file, "t.xml");
        let shown = e.to_string();
        assert!(
            shown.starts_with(&format!("t.xml:{}:{}: ", at.0, at.1)),
            "{shown}"
        );
    }
    // document level
    let docs: &[(&str, (usize, usize), &str)] = &[
        ("<root BTCPP_format=\"5\"><BehaviorTree ID=\"M\"><AlwaysSuccess/></BehaviorTree></root>", (1, 7), "BTCPP_format"),
        ("<root main_tree_to_execute=\"X\"><BehaviorTree ID=\"M\"><AlwaysSuccess/></BehaviorTree></root>", (1, 7), "no <BehaviorTree ID=\"X\">"),
        ("<root><BehaviorTree ID=\"M\"><AlwaysSuccess/></BehaviorTree><BehaviorTree ID=\"M\"><AlwaysSuccess/></BehaviorTree></root>", (1, 59), "duplicate BehaviorTree"),
        ("<root><BehaviorTree ID=\"M\"/></root>", (1, 7), "exactly one node"),
        ("<root></root>", (1, 1), "no <BehaviorTree>"),
        ("<tree/>", (1, 1), "not <root>"),
        ("<root><include path=\"x.xml\"/></root>", (1, 7), "<include> cannot be resolved"),
        ("<root><BehaviorTree><AlwaysSuccess/></BehaviorTree><BehaviorTree ID=\"B\"><AlwaysSuccess/></BehaviorTree></root>", (1, 7), "needs an ID"),
        ("<root>\n<BehaviorTree ID=\"M\"><![CDATA[x]]></BehaviorTree></root>", (2, 22), "CDATA"),
        ("<!DOCTYPE root><root/>", (1, 1), "DOCTYPE"),
        ("<root><BehaviorTree ID=\"M\"><AlwaysSuccess/></Behaviortree></root>", (1, 44), "does not close"),
        ("<root>\n  <BehaviorTree ID=\"M\">", (2, 3), "never closed"),
        ("<root a=\"1\" a=\"2\"/>", (1, 13), "duplicate attribute"),
        ("<root a=1/>", (1, 9), "quoted"),
        ("<root/><root/>", (1, 8), "after the root"),
        ("<root a=\"1\"b=\"2\"/>", (1, 12), "white space"),
        ("<!-- never closed <root/>", (1, 1), "unterminated comment"),
        ("", (1, 1), "no root element"),
        ("hello", (1, 1), "no root element"),
    ];
    for (src, at, what) in docs {
        let e = err(src, "");
        assert_eq!((e.line, e.column), *at, "{src}: {e}");
        assert!(e.message.contains(what), "{src}: {e}");
    }
}

#[test]
fn missing_parameters_are_listed_together() {
    let src = wrap(
        "<Sequence>\n  <Action ID=\"A\"/>\n  <Condition ID=\"C\"/>\n  <Action ID=\"B\" name=\"bee\"/>\n  <Action ID=\"D\"/>\n</Sequence>",
    );
    let e = err(&src, "A: {ps: 0.5, mu: 1}\nD: {pf: 0.5}\n");
    assert_eq!(e.file, "t.xml");
    assert_eq!((e.line, e.column), (4, 3));
    assert!(
        e.message
            .starts_with("missing parameters for 4 nodes in t.params.yaml:"),
        "{e}"
    );
    let lines: Vec<&str> = e.message.lines().skip(1).collect();
    assert_eq!(lines.len(), 4, "{e}");
    assert!(lines[0].contains("t.xml:4:3: action `A`") && lines[0].contains("no failure time"));
    assert!(lines[1].contains("t.xml:5:3: condition `C`") && lines[1].contains("no entry"));
    assert!(
        lines[2].contains("t.xml:6:3: action `bee` (ID `B`)")
            && lines[2].contains("keys tried: bee, B")
    );
    assert!(lines[3].contains("t.xml:7:3: action `D`") && lines[3].contains("missing `ps`"));
}

/// A RecoveryNode's retries copy its main branch: a leaf without an entry
/// is listed once, with its number of copies (one entry covers them all).
#[test]
fn missing_parameters_of_copies_are_listed_once() {
    let src = wrap(
        "<RecoveryNode number_of_retries=\"2\">\n  <Sequence><Action ID=\"A\"/><Action ID=\"B\"/></Sequence>\n  <Action ID=\"R\"/>\n</RecoveryNode>",
    );
    let e = err(&src, "R: {ps: 0.5, mu: 1, nu: 1}\n");
    assert!(
        e.message
            .starts_with("missing parameters for 2 nodes in t.params.yaml:"),
        "{e}"
    );
    let lines: Vec<&str> = e.message.lines().skip(1).collect();
    assert_eq!(lines.len(), 2, "{e}");
    for (line, id) in lines.iter().zip(["A", "B"]) {
        assert!(line.contains(&format!("(ID `{id}`)")), "{e}");
        assert!(line.contains("[3 copies of this element"), "{e}");
    }
}

#[test]
fn params_are_validated_in_the_params_file() {
    let src = wrap("<Sequence><Action ID=\"A\"/><Condition ID=\"C\"/></Sequence>");
    let cases: &[(&str, (usize, usize), &str)] = &[
        (
            "A: {ps: 1.5, mu: 1}\nC: {ps: 1}",
            (1, 9),
            "not a probability",
        ),
        (
            "A: {ps: 0.5, pf: 0.4, mu: 1, nu: 1}\nC: {ps: 1}",
            (1, 18),
            "ps + pf",
        ),
        (
            "A: {ps: 0.5, mu: 1, tau_s: 1, nu: 1}\nC: {ps: 1}",
            (1, 28),
            "both `mu` and `tau_s`",
        ),
        (
            "A: {ps: 0.5, mu: 0, nu: 1}\nC: {ps: 1}",
            (1, 18),
            "not a valid rate",
        ),
        (
            "A: {ps: 0.5, mu: 1, tau_f: -1}\nC: {ps: 1}",
            (1, 28),
            "not a valid time",
        ),
        (
            "A: {ps: 0.5, mu: 1, nu: 1}\nC: {ps: 1, mu: 2}",
            (2, 16),
            "only `ps`",
        ),
        (
            "A: {ps: 0.5, mu: 1, nu: 1}\nC: {ps: 1}\nCC: {ps: 1}",
            (3, 5),
            "params key `CC`",
        ),
        ("A: {ps: 0.5, mux: 1, nu: 1}\nC: {ps: 1}", (1, 14), "mux"),
    ];
    for (params, at, what) in cases {
        let e = err(&src, params);
        assert_eq!(e.file, "t.params.yaml", "{params}: {e}");
        assert_eq!((e.line, e.column), *at, "{params}: {e}");
        assert!(e.message.contains(what), "{params}: {e}");
    }
    // hybrids are accepted, as in the YAML format
    let t = ok(&src, "A: {ps: 0.5, tau_s: 2, nu: 1}\nC: {ps: 1}");
    assert!(matches!(t.nodes()[1].kind, NodeKind::Action(a) if !a.is_markovian()));
}

#[test]
fn garbage_is_rejected_without_panic() {
    let inputs: Vec<String> = vec![
        "\u{0}\u{1}\u{2}binary".into(),
        String::from_utf8_lossy(&(0u8..=255).collect::<Vec<_>>()).into_owned(),
        "<".into(),
        "<root".into(),
        "<root a".into(),
        "<root a=".into(),
        "<root a=\"".into(),
        "<root>&".into(),
        "<root>&#xFFFFFFFFF;</root>".into(),
        "<root a=\"&#0;\"/>".into(),
        "</root>".into(),
        "<?xml".into(),
        "<root><!--".into(),
        "<<<<>>>>".into(),
        "<root><BehaviorTree ID=\"M\"><Parallel success_count=\"99999999999999999999\"><AlwaysSuccess/></Parallel></BehaviorTree></root>".into(),
        "<rööt/>".into(),
        "<root>\u{feff}</root>".into(),
    ];
    for s in &inputs {
        assert!(xml(s, "").is_err(), "{s:?}");
    }
    // all prefixes of a valid file
    let good = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("trees/search-and-grasp.xml"),
    )
    .unwrap();
    for (i, _) in good.char_indices() {
        let _ = xml(&good[..i], "");
    }
    let params = "{{{{{{{{{{{{{{{{{{{{{{{{{{{{{{{{{{{{{{{{";
    assert!(xml(&wrap("<AlwaysSuccess/>"), params).is_err());
}

#[test]
fn deep_nesting_is_rejected() {
    let deep = |n: usize| {
        format!(
            "{}<AlwaysSuccess/>{}",
            "<Inverter>".repeat(n),
            "</Inverter>".repeat(n)
        )
    };
    let e = err(&wrap(&deep(500)), "");
    assert_eq!(e.kind, TreeErrorKind::Budget, "{e}");
    assert!(e.message.contains("nested too deeply"), "{e}");
    let e = err(&wrap(&deep(200)), "");
    assert_eq!(e.kind, TreeErrorKind::Budget, "{e}");
    assert!(e.message.contains("nested too deeply"), "{e}");
    let t = ok(&wrap(&deep(199)), "");
    assert_eq!(t.nodes().len(), 200);
    // a chain of SubTrees, each adding levels, is bounded too
    let mut src = String::from("<root BTCPP_format=\"4\" main_tree_to_execute=\"T0\">");
    for i in 0..300 {
        src.push_str(&format!(
            "<BehaviorTree ID=\"T{i}\"><Inverter><SubTree ID=\"T{}\"/></Inverter></BehaviorTree>",
            i + 1
        ));
    }
    src.push_str("<BehaviorTree ID=\"T300\"><AlwaysSuccess/></BehaviorTree></root>");
    let e = err(&src, "");
    assert_eq!(e.kind, TreeErrorKind::Budget, "{e}");
    assert!(e.message.contains("too deeply"), "{e}");
    // 100 000 unclosed elements: bounded, no stack overflow
    let e = err(&"<a>".repeat(100_000), "");
    assert_eq!(e.kind, TreeErrorKind::Budget, "{e}");
    assert!(e.message.contains("nested too deeply"), "{e}");
}

#[test]
fn subtree_blowup_is_bounded() {
    // 2^30 nodes if expanded
    let mut src = String::from("<root main_tree_to_execute=\"T0\">");
    for i in 0..30 {
        src.push_str(&format!(
            "<BehaviorTree ID=\"T{i}\"><Sequence><SubTree ID=\"T{0}\"/><SubTree ID=\"T{0}\"/></Sequence></BehaviorTree>",
            i + 1
        ));
    }
    src.push_str("<BehaviorTree ID=\"T30\"><AlwaysSuccess/></BehaviorTree></root>");
    let e = err(&src, "");
    assert_eq!(e.kind, TreeErrorKind::Budget, "{e}");
    assert!(e.message.contains("too many nodes"), "{e}");
}

// ---------------------------------------------------------------------------
// Published trees: what BT.CPP accepts, v3, forms, metadata, includes
// ---------------------------------------------------------------------------

fn kinds(t: &Tree) -> Vec<&str> {
    t.nodes().iter().map(|n| n.kind.keyword()).collect()
}

#[test]
fn all_leaves_without_parameters_are_listed_at_once() {
    // like a Nav2 tree: many custom leaves, no model, params incomplete
    let src = wrap(
        "<Sequence>\n  <ComputePath/>\n  <FollowPath/>\n  <IsStuck/>\n  <Spin/>\n  <AlwaysSucess/>\n</Sequence>",
    );
    let e = err(
        &src,
        "FollowPath: {ps: 0.9, mu: 1, nu: 1}\nIsStuck: {ps: 0.1}\n",
    );
    let lines: Vec<&str> = e.message.lines().skip(1).collect();
    assert_eq!(e.kind, TreeErrorKind::MissingParameter, "{e}");
    assert!(
        e.message.starts_with("missing parameters for 3 nodes"),
        "{e}"
    );
    assert!(
        lines[0].starts_with("  t.xml:4:3: leaf `ComputePath`"),
        "{e}"
    );
    assert!(lines[1].starts_with("  t.xml:7:3: leaf `Spin`"), "{e}");
    assert!(
        lines[2].starts_with("  t.xml:8:3: leaf `AlwaysSucess`"),
        "{e}"
    );
    assert!(lines[2].contains("did you mean <AlwaysSuccess>"), "{e}");
    assert_eq!((e.line, e.column), (4, 3));
}

#[test]
fn node_types_without_a_meaning_are_listed_at_once() {
    let src = r#"<root BTCPP_format="4" main_tree_to_execute="Main">
  <BehaviorTree ID="Main">
    <PersistentSequence>
      <ParallelAll max_failures="1"><A/></ParallelAll>
      <Sequence _skipIf="x > 1"><A/></Sequence>
      <SubTree ID="Sub"/>
    </PersistentSequence>
  </BehaviorTree>
  <BehaviorTree ID="Sub"><RunOnce><A/></RunOnce></BehaviorTree>
</root>"#;
    let e = err(src, "A: {ps: 0.5, mu: 1, nu: 1}");
    assert!(is_unsupported(&e), "{e}");
    assert!(
        e.message
            .starts_with("btrel has no stochastic meaning yet for 4 nodes of this tree:"),
        "{e}"
    );
    let lines: Vec<&str> = e.message.lines().skip(1).collect();
    assert_eq!(lines.len(), 4, "{e}");
    assert!(lines[0].starts_with("  t.xml:3:5: <PersistentSequence>: Nav2 control node"));
    assert!(lines[1].starts_with("  t.xml:4:7: <ParallelAll>: it runs every child"));
    assert!(lines[2].starts_with("  t.xml:5:17: `_skipIf` attribute on <Sequence>"));
    assert!(lines[3].starts_with("  t.xml:9:26: <RunOnce>"));
    assert_eq!((e.line, e.column), (3, 5));
    // an unknown node with children is a front-end problem, listed first,
    // and the semantic ones follow
    let src = wrap("<Sequence>\n<Fallbak><A/></Fallbak>\n<RunOnce><A/></RunOnce>\n<Sequense><A/></Sequense>\n</Sequence>");
    let e = err(&src, "A: {ps: 0.5, mu: 1, nu: 1}");
    assert_eq!(e.kind, TreeErrorKind::UnknownNode, "{e}");
    assert!(e.message.starts_with("2 nodes cannot be read:"), "{e}");
    assert!(
        e.message
            .contains("t.xml:4:1: unknown node <Fallbak> with children (did you mean <Fallback>?)"),
        "{e}"
    );
    assert!(
        e.message.contains(
            "t.xml:6:1: unknown node <Sequense> with children (did you mean <Sequence>?)"
        ),
        "{e}"
    );
    assert!(
        e.message.contains(
            "and btrel has no stochastic meaning yet for 1 node:\n  t.xml:5:1: <RunOnce>"
        ),
        "{e}"
    );
}

#[test]
fn explicit_forms_are_the_short_forms() {
    let short = wrap(
        r#"<Sequence name="top">
  <Inverter><Grasp/></Inverter>
  <RetryUntilSuccessful num_attempts="2"><Ready/></RetryUntilSuccessful>
  <Parallel success_count="1"><Grasp/><Grasp/></Parallel>
  <AlwaysSuccess/>
</Sequence>"#,
    );
    let explicit = wrap(
        r#"<Control ID="Sequence" name="top">
  <Decorator ID="Inverter"><Action ID="Grasp"/></Decorator>
  <Decorator ID="RetryUntilSuccessful" num_attempts="2"><Condition ID="Ready"/></Decorator>
  <Control ID="Parallel" success_count="1"><Action ID="Grasp"/><Action ID="Grasp"/></Control>
  <Action ID="AlwaysSuccess"/>
</Control>"#,
    );
    let params = "Grasp: {ps: 0.5, mu: 1, nu: 2}\nReady: {ps: 0.25}";
    let (a, b) = (ok(&short, params), ok(&explicit, params));
    assert_eq!(names(&a), names(&b));
    assert_eq!(
        a.nodes().iter().map(|n| &n.kind).collect::<Vec<_>>(),
        b.nodes().iter().map(|n| &n.kind).collect::<Vec<_>>()
    );
    assert_eq!(kinds(&a)[0], "sequence");
    // the form decides a leaf's kind: a ps-only entry for an <Action> lacks times
    let e = err(&wrap("<Action ID=\"Ready\"/>"), "Ready: {ps: 0.25}");
    assert!(e.message.contains("no success time"), "{e}");
}

#[test]
fn metadata_attributes_are_ignored_and_no_op_preconditions_read() {
    let src = r#"<?xml version="1.0" encoding="UTF-8" ?>
<root BTCPP_format="4" main_tree_to_execute="Pick">
  <BehaviorTree ID="Pick" _description="Example" _favorite="false" target="x">
    <Control ID="Sequence" name="Top" _collapsed="false" _skipIf="false">
      <Action ID="Move" _uid="7" _hardcoded="true" _while="true" _failureIf=" false "/>
      <Action ID="Grab" _onSuccess="done:=true" _post="n:=n+1"/>
    </Control>
  </BehaviorTree>
  <TreeNodesModel>
    <SubTree ID="Pick"><MetadataFields><Metadata runnable="true"/></MetadataFields></SubTree>
  </TreeNodesModel>
</root>"#;
    let t = ok(
        src,
        "Move: {ps: 0.9, mu: 1, nu: 1}\nGrab: {ps: 0.8, mu: 2, nu: 1}",
    );
    assert_eq!(names(&t), ["Top", "Move", "Grab"]);
    let e = err(
        &src.replace("_skipIf=\"false\"", "_skipIf=\"busy\""),
        "Move: {ps: 0.9, mu: 1, nu: 1}\nGrab: {ps: 0.8, mu: 2, nu: 1}",
    );
    assert!(
        is_unsupported(&e) && e.message.contains("`_skipIf` attribute on <Control>"),
        "{e}"
    );
    assert_eq!((e.line, e.column), (4, 58));
}

#[test]
fn what_the_bt_cpp_parser_accepts_is_read() {
    let src = "// clang-format off\n <root BTCPP_format=\"4\">\n<!------ a comment -- with dashes ---->\n  <BehaviorTree>\n    <Sequence>\n      <Say msg=\"a && b &nbsp; &lt;\"/>;\n      <Say name=\"x && y\"/>;\n    </Sequence>\n  </BehaviorTree>\n </root>\ntrailing text\n";
    let t = ok(src, "Say: {ps: 1, mu: 1}");
    assert_eq!(names(&t), ["Sequence", "Say", "x && y"]);
    // a lone BehaviorTree without an ID has no title
    assert_eq!(t.title(), None);
}

#[test]
fn bt_cpp_v3_files_are_read() {
    let v3 = |attrs: &str, body: &str| {
        format!("<root{attrs}>\n<BehaviorTree ID=\"M\">\n{body}\n</BehaviorTree>\n</root>")
    };
    let body = r#"<SequenceStar>
  <RetryUntilSuccesful num_attempts="3"><A/></RetryUntilSuccesful>
  <Parallel success_threshold="-1" failure_threshold="2"><A/><A/><A/></Parallel>
  <SetBlackboard output_key="k" value="v"/>
  <SubTreePlus ID="S" __autoremap="true"/>
</SequenceStar>"#;
    let params = "A: {ps: 0.5, mu: 1, nu: 1}";
    for attrs in ["", " BTCPP_format=\"3\""] {
        let src = v3(attrs, body).replace(
            "</root>",
            "<BehaviorTree ID=\"S\"><AlwaysFailure/></BehaviorTree></root>",
        );
        let t = ok(&src, params);
        assert_eq!(
            kinds(&t),
            [
                "sequence",
                "retry",
                "action",
                "parallel",
                "action",
                "action",
                "action",
                "condition",
                "condition"
            ]
        );
        assert!(matches!(
            t.nodes()[1].kind,
            NodeKind::Decorator {
                decorator: Decorator::Retry { attempts: 3 },
                ..
            }
        ));
        assert!(matches!(
            t.nodes()[3].kind,
            NodeKind::Parallel {
                success_threshold: 3,
                failure_threshold: 2,
                ..
            }
        ));
        assert_eq!(t.nodes()[7].kind, NodeKind::Condition { ps: 1.0 });
        assert_eq!(t.nodes()[8].kind, NodeKind::Condition { ps: 0.0 });
        assert_eq!(t.nodes()[8].name, "S/AlwaysFailure");
    }
    // v3 has no default success_threshold; v4 names are unknown in a v3 file
    let e = err(
        &v3(" BTCPP_format=\"3\"", "<Parallel><A/></Parallel>"),
        params,
    );
    assert!(e.message.contains("needs `success_threshold`"), "{e}");
    let e = err(
        &v3(
            " BTCPP_format=\"3\"",
            "<Parallel success_count=\"1\"><A/></Parallel>",
        ),
        params,
    );
    assert!(
        e.message.contains("unknown attribute `success_count`"),
        "{e}"
    );
    // without BTCPP_format and without attributes: v4 defaults (all must succeed)
    let t = ok(&v3("", "<Parallel><A/><A/></Parallel>"), params);
    assert!(matches!(
        t.nodes()[0].kind,
        NodeKind::Parallel {
            success_threshold: 2,
            failure_threshold: 1,
            ..
        }
    ));
}

#[test]
fn zero_time_nodes_are_immediate_successes_unless_given_parameters() {
    let src = wrap(
        "<Sequence><Script code=\"a:=1\"/><SetBlackboard output_key=\"k\" value=\"1\"/><UnsetBlackboard key=\"k\"/><Action ID=\"Script\" code=\"b:=2\"/></Sequence>",
    );
    let t = ok(&src, "");
    assert_eq!(
        t.nodes()[1..].iter().map(|n| &n.kind).collect::<Vec<_>>(),
        [&NodeKind::Condition { ps: 1.0 }; 4]
    );
    // a params entry models them (e.g. their run time)
    let t = ok(&src, "Script: {ps: 1, mu: 1000}");
    assert!(matches!(t.nodes()[1].kind, NodeKind::Action(a) if a.ps == 1.0));
    assert!(matches!(t.nodes()[4].kind, NodeKind::Action(a) if a.ps == 1.0));
    assert_eq!(t.nodes()[2].kind, NodeKind::Condition { ps: 1.0 });
}

/// RecoveryNode(m, r, n) by Nav2's algorithm (recovery_node.cpp): success
/// after k recoveries has probability (fm sr)^k sm; failure when r fails
/// after k recoveries (k < n) or when m fails the (n+1)-th time. Returns
/// (ps, MTTS, MTTF) for exponential actions m = (sm, mu_m, nu_m), r = (sr,
/// mu_r, nu_r).
fn recovery_closed_form(m: (f64, f64, f64), r: (f64, f64, f64), n: i32) -> (f64, f64, f64) {
    let (sm, mum, num) = m;
    let (sr, mur, nur) = r;
    let (fm, fr) = (1.0 - sm, 1.0 - sr);
    let round = 1.0 / num + 1.0 / mur; // m fails, r succeeds
    let (mut ps, mut ts, mut pf, mut tf) = (0.0, 0.0, 0.0, 0.0);
    for k in 0..=n {
        let w = (fm * sr).powi(k);
        ps += w * sm;
        ts += w * sm * (k as f64 * round + 1.0 / mum);
        if k < n {
            pf += w * fm * fr;
            tf += w * fm * fr * (k as f64 * round + 1.0 / num + 1.0 / nur);
        } else {
            pf += w * fm;
            tf += w * fm * (k as f64 * round + 1.0 / num);
        }
    }
    assert!((ps + pf - 1.0).abs() < 1e-12);
    (ps, ts / ps, tf / pf)
}

#[test]
fn recovery_node_is_nav2s_retry_loop() {
    let params = "M: {ps: 0.6, mu: 2, nu: 0.5}\nR: {ps: 0.7, mu: 1, nu: 3}";
    for n in [0, 1, 2, 6] {
        let src = wrap(&format!(
            "<RecoveryNode number_of_retries=\"{n}\" name=\"Rec\"><M/><R/></RecoveryNode>"
        ));
        // with no retry the recovery branch never runs: its entry is unused
        let params = if n == 0 { &params[..28] } else { params };
        let t = ok(&src, params);
        assert_eq!(t.nodes().len(), (2 * n + (n + 1) + n) as usize);
        let a = analyze(&t, &Options::default()).unwrap();
        let (ps, mtts, mttf) = recovery_closed_form((0.6, 2.0, 0.5), (0.7, 1.0, 3.0), n);
        let root = a.nodes[0];
        assert!((root.ps - ps).abs() < 1e-12, "n = {n}: {} vs {ps}", root.ps);
        assert!((root.mtts.unwrap() - mtts).abs() < 1e-9 * mtts, "n = {n}");
        assert!((root.mttf.unwrap() - mttf).abs() < 1e-9 * mttf, "n = {n}");
    }
    // default: one retry; the copies are named by attempt
    let t = ok(
        &wrap("<RecoveryNode name=\"Rec\"><M/><R/></RecoveryNode>"),
        params,
    );
    assert_eq!(
        names(&t),
        [
            "Rec",
            "M",
            "Rec/recovery 1",
            "Rec/recovery 1/R",
            "Rec/attempt 2/M"
        ]
    );
    assert_eq!(
        kinds(&t),
        ["fallback", "action", "sequence", "action", "action"]
    );
    assert_eq!(t.nodes()[4].path, "0.1.1");
    // memory in the main branch resumes instead of starting afresh: read
    // as a SequenceWithMemory whose copies share one index (a flow in the
    // analysis, `tests/sequence_memory.rs`)
    let t = ok(
        &wrap("<RecoveryNode><SequenceWithMemory><M/><M/></SequenceWithMemory><R/></RecoveryNode>"),
        params,
    );
    let slots: Vec<usize> = t
        .nodes()
        .iter()
        .filter_map(|n| match n.kind {
            btrel::tree::NodeKind::SequenceWithMemory { slot, .. } => Some(slot),
            _ => None,
        })
        .collect();
    assert!(slots.len() == 2 && slots[0] == slots[1], "{slots:?}");
    // ... a Sequence in the recovery branch (ticked again only after a
    // success) and below a single attempt
    ok(
        &wrap("<RecoveryNode><M/><SequenceWithMemory><R/><R/></SequenceWithMemory></RecoveryNode>"),
        params,
    );
    ok(
        &wrap("<RetryUntilSuccessful num_attempts=\"1\"><SequenceStar><M/><R/></SequenceStar></RetryUntilSuccessful>"),
        params,
    );
    let e = err(&wrap("<RecoveryNode><M/></RecoveryNode>"), params);
    assert!(e.message.contains("exactly two children"), "{e}");
    let e = err(
        &wrap("<RecoveryNode number_of_retries=\"-2\"><M/><R/></RecoveryNode>"),
        params,
    );
    assert!(e.message.contains("not a valid count"), "{e}");
    let e = err(
        &wrap("<RecoveryNode number_of_retries=\"{n}\"><M/><R/></RecoveryNode>"),
        params,
    );
    assert!(
        e.kind == TreeErrorKind::MissingParameter
            && e.message.starts_with("missing parameters for 1 node")
            && e.message.contains("number_of_retries = \"{n}\""),
        "{e}"
    );
    // nested retries multiply; the size is checked before building
    let mut body = "<M/>".to_string();
    for _ in 0..4 {
        body = format!("<RecoveryNode number_of_retries=\"1000\">{body}<R/></RecoveryNode>");
    }
    let e = err(&wrap(&body), params);
    assert_eq!(e.kind, TreeErrorKind::Budget, "{e}");
    assert!(e.message.contains("too many nodes"), "{e}");
}

#[test]
fn included_texts_provide_subtrees_and_models() {
    let main = r#"<root BTCPP_format="4" main_tree_to_execute="Main">
  <BehaviorTree ID="Main"><Sequence><SubTree ID="Grasp"/><Ready/><SubTree ID="Elsewhere"/></Sequence></BehaviorTree>
</root>"#;
    let sub = r#"<root BTCPP_format="4"><BehaviorTree ID="Grasp"><Fallback><Hand/><Hand/></Fallback></BehaviorTree></root>"#;
    let model = r#"<root><TreeNodesModel><Condition ID="Ready"/><Action ID="Hand"/></TreeNodesModel></root>"#;
    let params =
        "Hand: {ps: 0.5, mu: 1, nu: 2}\nReady: {ps: 0.9}\nElsewhere: {ps: 0.5, mu: 1, nu: 1}";
    let t = parse_xml_str_with(
        main,
        "main.xml",
        &[("sub.xml", sub), ("model.xml", model)],
        params,
        "p.yaml",
    )
    .unwrap_or_else(|e| panic!("{e}"));
    // a SubTree defined nowhere but with a params entry is one leaf
    assert_eq!(
        names(&t),
        [
            "Sequence",
            "Grasp/Fallback",
            "Grasp/Hand",
            "Grasp/Hand#2",
            "Ready",
            "Elsewhere"
        ]
    );
    assert_eq!(kinds(&t)[5], "action");
    // without the file: the SubTree is reported, with the trees read
    let e = parse_xml_str_with(main, "main.xml", &[("model.xml", model)], params, "p.yaml")
        .unwrap_err();
    assert!(
        e.message
            .contains("main.xml:2:37: no <BehaviorTree ID=\"Grasp\"> for this SubTree"),
        "{e}"
    );
    // an error in an included file names that file
    let e = parse_xml_str_with(
        main,
        "main.xml",
        &[(
            "sub.xml",
            "<root><BehaviorTree ID=\"Grasp\"><Hand x=/></BehaviorTree></root>",
        )],
        params,
        "p.yaml",
    )
    .unwrap_err();
    assert_eq!(
        (e.file.as_str(), e.line, e.column),
        ("sub.xml", 1, 40),
        "{e}"
    );
    // the main file's definition wins; two included definitions clash
    let twice = parse_xml_str_with(
        main,
        "main.xml",
        &[("a.xml", sub), ("b.xml", sub)],
        params,
        "p.yaml",
    )
    .unwrap_err();
    assert!(
        twice.message.contains("defined in several included files"),
        "{twice}"
    );
    assert!(twice.help.unwrap().contains("a.xml:1:24, b.xml:1:24"));
}

#[test]
fn include_elements_and_folders_are_read_from_disk() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path();
    std::fs::create_dir(p.join("lib")).unwrap();
    std::fs::write(
        p.join("main.xml"),
        r#"<root BTCPP_format="4" main_tree_to_execute="Main">
  <include path="lib/grasp.xml"/>
  <BehaviorTree ID="Main"><Sequence><SubTree ID="Grasp"/><SubTree ID="Place"/></Sequence></BehaviorTree>
</root>"#,
    )
    .unwrap();
    // an include relative to the including file; a cycle is read once
    std::fs::write(
        p.join("lib/grasp.xml"),
        r#"<root><include path="../main.xml"/><include path="place.xml"/><BehaviorTree ID="Grasp"><Hand/></BehaviorTree></root>"#,
    )
    .unwrap();
    std::fs::write(
        p.join("lib/place.xml"),
        r#"<root><BehaviorTree ID="Place"><Put/></BehaviorTree></root>"#,
    )
    .unwrap();
    std::fs::write(
        p.join("main.params.yaml"),
        "Hand: {ps: 0.5, mu: 1, nu: 2}\nPut: {ps: 0.9}",
    )
    .unwrap();
    let t =
        btrel::tree::xml::parse_xml_files(&p.join("main.xml"), &p.join("main.params.yaml"), &[])
            .unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(names(&t), ["Sequence", "Grasp/Hand", "Place/Put"]);
    // the same from the command line: --include a folder
    std::fs::write(
        p.join("plain.xml"),
        r#"<root main_tree_to_execute="Main"><BehaviorTree ID="Main"><Sequence><SubTree ID="Place"/><SubTree ID="Place"/></Sequence></BehaviorTree></root>"#,
    )
    .unwrap();
    std::fs::write(p.join("plain.params.yaml"), "Put: {ps: 0.5}").unwrap();
    // without the include: only SubTrees are missing
    let e =
        btrel::tree::xml::parse_xml_files(&p.join("plain.xml"), &p.join("plain.params.yaml"), &[])
            .unwrap_err();
    assert_eq!(e.kind, TreeErrorKind::UndefinedSubTree, "{e}");
    let out = assert_cmd::Command::cargo_bin("btrel")
        .unwrap()
        .current_dir(p)
        .args([
            "report",
            "plain.xml",
            "--include",
            "lib",
            "--format",
            "json",
        ])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    // two independent conditions with ps 0.5 in a Sequence
    assert!(
        (json["nodes"][0]["ps"].as_f64().unwrap() - 0.25).abs() < 1e-12,
        "{json}"
    );
    // without it: exit 2 and the flag in the advice
    let out = assert_cmd::Command::cargo_bin("btrel")
        .unwrap()
        .current_dir(p)
        .args(["check", "plain.xml"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("plain.xml:1:69: 2 nodes cannot be read"),
        "{stderr}"
    );
    assert!(stderr.contains("--include FILE"), "{stderr}");
    // a tree refused for node semantics only exits with 1
    std::fs::write(
        p.join("nav.xml"),
        r#"<root><BehaviorTree ID="M"><PersistentSequence><Put/></PersistentSequence></BehaviorTree></root>"#,
    )
    .unwrap();
    std::fs::write(p.join("nav.params.yaml"), "Put: {ps: 0.5}").unwrap();
    let out = assert_cmd::Command::cargo_bin("btrel")
        .unwrap()
        .current_dir(p)
        .args(["report", "nav.xml"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    assert!(out.stdout.is_empty());
    // --include is refused for a YAML tree and must exist
    let out = assert_cmd::Command::cargo_bin("btrel")
        .unwrap()
        .current_dir(p)
        .args(["check", "plain.xml", "--include", "nope.xml"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("--include nope.xml does not exist"));
}

#[test]
fn blackboard_counts_and_durations_read_the_params_file() {
    let body = r#"<Sequence>
        <Repeat num_cycles="{n}"><Step/></Repeat>
        <Sleep msec="{pause}"/>
        <RetryUntilSuccessful num_attempts="{tries}"><Grab/></RetryUntilSuccessful>
      </Sequence>"#;
    let params = "Step: {ps: 0.9, mu: 2, nu: 1}\nGrab: {ps: 0.5, mu: 1, nu: 4}\n\
                  \"{n}\": {value: 3}\n\"{pause}\": {value: 1500}\n\"{tries}\": {value: 2}\n";
    let t = ok(&wrap(body), params);
    let f = btrel::analyze(&t, &Default::default())
        .expect("analysed")
        .nodes[0];
    // Repeat 3 × Step, a 1.5 s Sleep, Retry 2 × Grab:
    // P(S) = 0.9³ · (1 − 0.5²); every successful run takes 3 Step successes
    // (3 × 1/2 s), the 1.5 s pause, and Grab's success after at most one
    // failure: E = 0.5/0.75 · 1 + 0.25/0.75 · (1/4 + 1)
    let ps = 0.9f64.powi(3) * 0.75;
    let grab = (0.5 * 1.0 + 0.25 * (0.25 + 1.0)) / 0.75;
    assert!(close(f.ps, ps), "{} vs {ps}", f.ps);
    assert!(close(f.mtts.unwrap(), 1.5 + 1.5 + grab), "{:?}", f.mtts);

    // without the values: missing parameters (not a refusal), all of them
    // at once and each located, with a leaf's missing entry in the same list
    let e = err(&wrap(body), "Step: {ps: 0.9, mu: 2, nu: 1}\n");
    assert_eq!(e.kind, TreeErrorKind::MissingParameter, "{e}");
    assert!(
        e.message.starts_with("missing parameters for 4 nodes"),
        "{e}"
    );
    for (line, col, what) in [
        (6, 54, "leaf `Grab`"),
        (4, 17, "num_cycles = \"{n}\""),
        (5, 16, "msec = \"{pause}\""),
        (6, 31, "num_attempts = \"{tries}\""),
    ] {
        let at = format!("t.xml:{line}:{col}: ");
        let entry = e.message.lines().find(|l| l.contains(&at));
        assert!(entry.is_some_and(|l| l.contains(what)), "{at} {what}: {e}");
    }
    assert!(e.to_string().contains(r#""{n}": {value: N}"#), "{e}");
    assert!(
        e.help
            .as_deref()
            .is_some_and(|h| h.contains("blackboard value")),
        "{e}"
    );

    // mistakes in the params file are located there
    let with = |extra: &str| {
        format!("Step: {{ps: 0.9, mu: 2, nu: 1}}\nGrab: {{ps: 0.5, mu: 1, nu: 4}}\n\"{{n}}\": {{value: 3}}\n\"{{pause}}\": {{value: 1500}}\n\"{{tries}}\": {{value: 2}}\n{extra}")
    };
    for (extra, says) in [
        (
            "\"{other}\": {value: 1}\n",
            "`{other}` matches no blackboard reference",
        ),
        (
            "\"{x}\": {ps: 0.5}\n",
            "blackboard entry `{x}` needs a `value`",
        ),
        (
            "\"{x}\": {value: 1, ps: 0.5}\n",
            "blackboard entry `{x}` takes only `value`",
        ),
        (
            "Other: {ps: 0.5, value: 2}\n",
            "`value` in the entry of `Other`",
        ),
    ] {
        let e = err(&wrap(body), &with(extra));
        assert!(e.to_string().contains(says), "{extra}: {e}");
        assert!(e.to_string().contains("t.params.yaml:6:"), "{extra}: {e}");
    }
    let e = err(
        &wrap(body),
        &with("").replace("\"{n}\": {value: 3}", "\"{n}\": {value: 2.5}"),
    );
    assert!(
        e.to_string()
            .contains("reads 2.5 from the params file, not a whole number"),
        "{e}"
    );
}

/// Blackboard values the params file lacks are missing parameters (the fix
/// is a params entry), listed at once with their locations, also when the
/// tree has nodes without a stochastic meaning (those follow the list).
#[test]
fn missing_blackboard_values_are_missing_parameters() {
    let body = "<Sequence>\n<LoopPose queue=\"{waypoints}\"><Go/></LoopPose>\n\
                <Timeout msec=\"{relaxation_time_ms}\"><Go/></Timeout>\n\
                <RunOnce><Go/></RunOnce>\n</Sequence>";
    let e = err(&wrap(body), "Go: {ps: 0.5, mu: 1, nu: 1}\n");
    assert_eq!(e.kind, TreeErrorKind::MissingParameter, "{e}");
    assert!(!is_unsupported(&e), "{e}");
    // the body starts on line 3: LoopPose at 4:1, its queue at 4:11,
    // Timeout's msec at 5:10, RunOnce at 6:1
    assert_eq!(
        e.message,
        "missing parameters for 2 nodes in t.params.yaml:\n  \
         t.xml:4:11: <LoopPose> queue = \"{waypoints}\": a blackboard value known only at run \
         time; give its length: `\"{waypoints}\": {value: N}`\n  \
         t.xml:5:10: <Timeout> msec = \"{relaxation_time_ms}\": a blackboard value known only \
         at run time; give it in milliseconds: `\"{relaxation_time_ms}\": {value: N}`\n\
         and btrel has no stochastic meaning yet for 1 node of this tree:\n  \
         t.xml:6:1: <RunOnce>: it runs its child at most once, keeping its status across \
         executions"
    );
    assert_eq!((e.line, e.column), (4, 11));
    assert!(e
        .help
        .as_deref()
        .unwrap()
        .contains("`\"{waypoints}\": {value: 5}`"));
    // with the values given, only the refusal is left
    let e = err(
        &wrap(body),
        "Go: {ps: 0.5, mu: 1, nu: 1}\n\"{waypoints}\": {value: 2}\n\"{relaxation_time_ms}\": {value: 500}\n",
    );
    assert_eq!(e.kind, TreeErrorKind::NoMeaning, "{e}");
    assert!(is_unsupported(&e), "{e}");
}
