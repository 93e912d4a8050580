//! BehaviorTree.CPP v4 XML import: twins of the bundled YAML trees, SubTree
//! expansion, the short form, and every refusal with its location.

use std::path::Path;

use btrel::compile::{analyze, Options};
use btrel::tree::xml::{parse_xml_file, parse_xml_str};
use btrel::tree::{parse_file, Decorator, NodeKind, Tree, TreeError};

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
    t.nodes.iter().map(|n| n.name.as_str()).collect()
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
    assert_eq!(x.nodes.len(), y.nodes.len());
    let ay = analyze(&y, &Options::default()).unwrap();
    let ax = analyze(&x, &Options::default()).unwrap();
    for (i, n) in y.nodes.iter().enumerate() {
        let j = x
            .find(&n.name)
            .unwrap_or_else(|| panic!("{} missing", n.name));
        assert_eq!(x.nodes[j].path, n.path, "{}", n.name);
        assert_eq!(x.nodes[j].kind.keyword(), n.kind.keyword(), "{}", n.name);
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
            r#"<ReactiveSequence>
  <SequenceWithMemory><A/></SequenceWithMemory>
  <ReactiveFallback><A/><AlwaysFailure/></ReactiveFallback>
  <Inverter><ForceSuccess><ForceFailure><A name="x &amp; &#x79;"/></ForceFailure></ForceSuccess></Inverter>
  <RetryUntilSuccessful num_attempts="3"><Repeat num_cycles='2'><AlwaysSuccess/></Repeat></RetryUntilSuccessful>
</ReactiveSequence>
<!-- trailing comment -->"#,
        )
        .replace("</root>", "<TreeNodesModel><Action ID=\"A\"/></TreeNodesModel></root>"),
        "A: {ps: 0.5, mu: 1, nu: 2}",
    );
    assert_eq!(
        names(&t),
        [
            "ReactiveSequence",
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
    assert_eq!(t.nodes[0].kind.keyword(), "sequence");
    assert_eq!(t.nodes[1].kind.keyword(), "sequence");
    assert_eq!(t.nodes[3].kind.keyword(), "fallback");
    assert_eq!(t.nodes[5].kind, NodeKind::Condition { ps: 0.0 });
    assert_eq!(t.nodes[12].kind, NodeKind::Condition { ps: 1.0 });
    assert!(matches!(
        t.nodes[10].kind,
        NodeKind::Decorator {
            decorator: Decorator::Retry { attempts: 3 },
            child: 11
        }
    ));
    assert!(matches!(
        t.nodes[11].kind,
        NodeKind::Decorator {
            decorator: Decorator::Repeat { times: 2 },
            ..
        }
    ));
    assert_eq!(t.nodes[9].path, "0.2.0.0.0");
    assert_eq!(t.nodes[9].depth, 4);
    assert_eq!(t.nodes[9].parent, Some(8));
    assert_eq!(t.nodes[2].location, Some((4, 23)));
    assert_eq!(t.title.as_deref(), Some("Main"));
    analyze(&t, &Options::default()).unwrap();
}

#[test]
fn parallel_counts() {
    let leaves = "<A/><A/><A/><A/>";
    let model = "<TreeNodesModel><Condition ID=\"A\"/></TreeNodesModel></root>";
    let par = |attrs: &str| {
        let src = wrap(&format!("<Parallel {attrs}>{leaves}</Parallel>")).replace("</root>", model);
        match &ok(&src, "A: {ps: 0.5}").nodes[0].kind {
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
    assert_eq!(t.nodes[3].path, "0.0.1");
    assert_eq!(t.nodes[3].depth, 2);
    assert_eq!(t.nodes[3].location, Some((6, 5)));
    // lookup: full name first, then name attribute, then ID
    let ps = |i: usize| match t.nodes[i].kind {
        NodeKind::Action(a) => a.ps,
        _ => panic!(),
    };
    assert_eq!((ps(2), ps(5), ps(7)), (0.25, 0.5, 0.5));
    assert_eq!(t.title.as_deref(), Some("Main"));
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
    assert!(e.help.unwrap().contains("did you mean `Main`"));
}

#[test]
fn short_form_needs_the_model() {
    let e = err(
        &wrap("<Sequence>\n  <Grasp/>\n</Sequence>"),
        "Grasp: {ps: 1, mu: 1}",
    );
    assert_eq!((e.line, e.column), (4, 3));
    assert!(e.message.contains("unknown node <Grasp>"), "{e}");
    assert!(e.help.unwrap().contains("<TreeNodesModel>"));
    let e = err(&wrap("<Sequense><AlwaysSuccess/></Sequense>"), "");
    assert!(e.help.unwrap().contains("did you mean <Sequence>"));
    let with_model = wrap("<Sequence><Grasp/><Ready/></Sequence>").replace(
        "</root>",
        "<TreeNodesModel><Action ID=\"Grasp\"><input_port name=\"x\">text is fine here</input_port></Action><Condition ID=\"Ready\"/></TreeNodesModel></root>",
    );
    let t = ok(&with_model, "Grasp: {ps: 1, mu: 1}\nReady: {ps: 0.5}");
    assert!(matches!(t.nodes[1].kind, NodeKind::Action(a) if a.ps == 1.0));
    assert_eq!(t.nodes[2].kind, NodeKind::Condition { ps: 0.5 });
    let custom = wrap("<MyDeco><AlwaysSuccess/></MyDeco>").replace(
        "</root>",
        "<TreeNodesModel><Decorator ID=\"MyDeco\"/></TreeNodesModel></root>",
    );
    let e = err(&custom, "");
    assert!(e.message.contains("custom decorator <MyDeco>"), "{e}");
}

#[test]
fn refusals_have_locations() {
    let cases: &[(&str, (usize, usize), &str)] = &[
        ("<Script code=\"x:=1\"/>", (3, 1), "<Script> is not supported"),
        ("<Sequence>\n <Switch2 variable=\"{v}\"><AlwaysSuccess/></Switch2></Sequence>", (4, 2), "<Switch2>"),
        ("<Timeout msec=\"10\"><AlwaysSuccess/></Timeout>", (3, 1), "<Timeout>"),
        ("<Delay delay_msec=\"10\"><AlwaysSuccess/></Delay>", (3, 1), "<Delay>"),
        ("<KeepRunningUntilFailure><AlwaysSuccess/></KeepRunningUntilFailure>", (3, 1), "KeepRunningUntilFailure"),
        ("<Sequence _skipIf=\"x\"><AlwaysSuccess/></Sequence>", (3, 11), "`_skipIf`"),
        ("<Action ID=\"A\" _while=\"x\"/>", (3, 16), "`_while`"),
        ("<Sequence port=\"{x}\"><AlwaysSuccess/></Sequence>", (3, 11), "unknown attribute `port`"),
        ("<Repeat num_cycles=\"-1\"><AlwaysSuccess/></Repeat>", (3, 9), "forever"),
        ("<RetryUntilSuccessful num_attempts=\"-1\"><AlwaysSuccess/></RetryUntilSuccessful>", (3, 23), "forever"),
        ("<RetryUntilSuccessful><AlwaysSuccess/></RetryUntilSuccessful>", (3, 1), "needs `num_attempts`"),
        ("<Repeat num_cycles=\"{n}\"><AlwaysSuccess/></Repeat>", (3, 9), "blackboard"),
        ("<Repeat num_cycles=\"0\"><AlwaysSuccess/></Repeat>", (3, 9), "not a valid count"),
        ("<Inverter><AlwaysSuccess/><AlwaysSuccess/></Inverter>", (3, 1), "exactly one child"),
        ("<Sequence/>", (3, 1), "no children"),
        ("<Sequence>hello<AlwaysSuccess/></Sequence>", (3, 11), "text inside"),
        ("<Action ID=\"A\"><AlwaysSuccess/></Action>", (3, 16), "takes no children"),
        ("<Action/>", (3, 1), "needs an ID"),
        ("<Action ID=\"A\" name=\"\"/>", (3, 16), "must not be empty"),
        ("<Foo/>", (3, 1), "unknown node <Foo>"),
        ("<RetryUntilSuccessful num_attempts=\"2\"><Sequence><SequenceWithMemory><AlwaysSuccess/></SequenceWithMemory></Sequence></RetryUntilSuccessful>", (3, 50), "SequenceWithMemory below"),
        ("<SubTree ID=\"Nope\"/>", (3, 1), "no <BehaviorTree ID=\"Nope\">"),
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
        ("<root BTCPP_format=\"3\"><BehaviorTree ID=\"M\"><AlwaysSuccess/></BehaviorTree></root>", (1, 7), "BTCPP_format"),
        ("<root main_tree_to_execute=\"X\"><BehaviorTree ID=\"M\"><AlwaysSuccess/></BehaviorTree></root>", (1, 7), "no <BehaviorTree ID=\"X\">"),
        ("<root><BehaviorTree ID=\"M\"><AlwaysSuccess/></BehaviorTree><BehaviorTree ID=\"M\"><AlwaysSuccess/></BehaviorTree></root>", (1, 59), "duplicate BehaviorTree"),
        ("<root><BehaviorTree ID=\"M\"/></root>", (1, 7), "exactly one node"),
        ("<root></root>", (1, 1), "no <BehaviorTree>"),
        ("<tree/>", (1, 1), "not <root>"),
        ("<root><include path=\"x.xml\"/></root>", (1, 7), "<include>"),
        ("<root>\n<BehaviorTree ID=\"M\"><![CDATA[x]]></BehaviorTree></root>", (2, 22), "CDATA"),
        ("<!DOCTYPE root><root/>", (1, 1), "DOCTYPE"),
        ("<root><BehaviorTree ID=\"M\"><AlwaysSuccess/></Behaviortree></root>", (1, 44), "does not close"),
        ("<root>\n  <BehaviorTree ID=\"M\">", (2, 3), "never closed"),
        ("<root a=\"1\" a=\"2\"/>", (1, 13), "duplicate attribute"),
        ("<root a=1/>", (1, 9), "quoted"),
        ("<root a=\"&nbsp;\"/>", (1, 10), "entity"),
        ("<root a=\"x & y\"/>", (1, 12), "`&`"),
        ("<root/><root/>", (1, 8), "after the root"),
        ("<root a=\"1\"b=\"2\"/>", (1, 12), "white space"),
        ("<!-- never closed <root/>", (1, 1), "unterminated comment"),
        ("", (1, 1), "no root element"),
        ("hello", (1, 1), "expected `<`"),
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
    assert!(matches!(t.nodes[1].kind, NodeKind::Action(a) if !a.is_markovian()));
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
    assert!(e.message.contains("nested too deeply"), "{e}");
    let e = err(&wrap(&deep(200)), "");
    assert!(e.message.contains("nested too deeply"), "{e}");
    let t = ok(&wrap(&deep(199)), "");
    assert_eq!(t.nodes.len(), 200);
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
    assert!(e.message.contains("too deeply"), "{e}");
    // 100 000 unclosed elements: bounded, no stack overflow
    let e = err(&"<a>".repeat(100_000), "");
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
    assert!(e.message.contains("too many nodes"), "{e}");
}
