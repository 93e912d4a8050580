//! BehaviorTree.CPP nodes whose outcome comes from blackboard predicates or
//! queues: ScriptCondition, Precondition and LoopInt/LoopDouble/... . The
//! expected figures are hand calculations from BT.CPP v4's semantics
//! (`script_condition.h`, `script_precondition.h`, `loop_node.h`).

mod common;

use btrel::compile::{analyze, Figures, Options};
use btrel::tree::xml::{is_unsupported, parse_xml_str};
use btrel::tree::{NodeKind, Tree, TreeError, TreeErrorKind};
use common::{check_figures, close};

fn xml(body: &str, params: &str) -> Result<Tree, TreeError> {
    let src = format!(
        "<root BTCPP_format=\"4\">\n<BehaviorTree ID=\"Main\">\n{body}\n</BehaviorTree>\n{}</root>\n",
        SUB
    );
    parse_xml_str(&src, "t.xml", params, "t.params.yaml")
}

/// A SubTree the tests may refer to.
const SUB: &str = "<BehaviorTree ID=\"Sub\">\n<Precondition name=\"P\" if=\"x\"><A/></Precondition>\n</BehaviorTree>\n";

/// Action A: ps 1/2, success time Exp(1) (mean 1 s), failure time Exp(2)
/// (mean 1/2 s).
const A: &str = "A: {ps: 0.5, mu: 1, nu: 2}\n";

fn xml_root(body: &str, params: &str) -> Figures {
    let t = xml(body, params).unwrap_or_else(|e| panic!("{e}"));
    analyze(&t, &Options::default()).unwrap().nodes[0]
}

fn err(body: &str, params: &str) -> TreeError {
    match xml(body, params) {
        Ok(t) => panic!("expected an error, got {t:?}"),
        Err(e) => e,
    }
}

#[test]
fn script_condition_is_a_condition_from_the_params_file() {
    // Sequence(cond 0.7, A): ps 0.35; success takes A's success time (1);
    // failure: 0.3 at time 0, 0.35 at A's failure time 1/2
    let body = "<Sequence><ScriptCondition code=\"x == 1\"/><A/></Sequence>";
    let f = xml_root(body, &format!("{A}ScriptCondition: {{ps: 0.7}}"));
    check_figures(f, 0.35, Some(1.0), Some(0.35 * 0.5 / 0.65));
    // keyed by name; the explicit form <Action ID="ScriptCondition"> is a
    // condition all the same (a timing key is refused)
    let body = "<Action ID=\"ScriptCondition\" name=\"drained\" code=\"drained\"/>";
    let t = xml(body, "drained: {ps: 0.25}").unwrap();
    assert_eq!(t.nodes()[0].kind, NodeKind::Condition { ps: 0.25 });
    let e = err(body, "drained: {ps: 0.25, mu: 1}");
    assert!(e.message.contains("a condition takes only `ps`"), "{e}");
    // listed with the other missing parameters, with its location
    let e = err("<Sequence><ScriptCondition code=\"x\"/><B/></Sequence>", "");
    assert_eq!(e.kind, TreeErrorKind::MissingParameter, "{e}");
    assert!(
        e.message.starts_with("missing parameters for 2 nodes"),
        "{e}"
    );
    assert!(
        e.message
            .contains("t.xml:3:11: condition `ScriptCondition`"),
        "{e}"
    );
    // `code` is its only port
    let e = err("<ScriptCondition cod=\"x\"/>", "ScriptCondition: {ps: 1}");
    assert!(e.message.contains("unknown attribute `cod`"), "{e}");
}

#[test]
fn precondition_else_failure_is_a_sequence() {
    // if holds with 0.8: ps 0.8·0.5 = 0.4; failures: 0.2 at time 0, 0.4 at
    // A's failure time 1/2 → MTTF 0.2/0.6
    let body = "<Precondition if=\"A > -B\" else=\"FAILURE\"><A/></Precondition>";
    let params = format!("{A}\"Precondition/if\": {{ps: 0.8}}");
    check_figures(xml_root(body, &params), 0.4, Some(1.0), Some(0.2 / 0.6));
    // `else` defaults to FAILURE
    let body = "<Precondition if=\"ok\"><A/></Precondition>";
    check_figures(xml_root(body, &params), 0.4, Some(1.0), Some(0.2 / 0.6));
    let t = xml(body, &params).unwrap();
    assert_eq!(t.nodes()[1].name, "Precondition/if");
    assert_eq!(t.nodes()[1].kind, NodeKind::Condition { ps: 0.8 });
}

#[test]
fn precondition_else_success_skips_the_child_with_success() {
    // false `if` (0.2) → Success at 0; true → A: ps 0.2 + 0.4 = 0.6,
    // MTTS = 0.4·1/0.6, MTTF = A's 1/2
    let body = "<Precondition name=\"Check\" if=\"ok\" else=\"SUCCESS\"><A/></Precondition>";
    let params = format!("{A}\"Check/if\": {{ps: 0.8}}");
    check_figures(xml_root(body, &params), 0.6, Some(0.4 / 0.6), Some(0.5));
    // constant predicates need no entry
    let body = "<Precondition if=\"false\" else=\"SUCCESS\"><A/></Precondition>";
    check_figures(xml_root(body, A), 1.0, Some(0.0), None);
    let body = "<Precondition if=\"true\"><A/></Precondition>";
    check_figures(xml_root(body, A), 0.5, Some(1.0), Some(0.5));
}

#[test]
fn predicate_keys_follow_leaf_keys() {
    // inside a SubTree instance: full name, then name attribute, then ID
    let body = "<SubTree ID=\"Sub\" name=\"S\"/>";
    for key in ["S/P/if", "P/if", "Precondition/if"] {
        let f = xml_root(body, &format!("{A}\"{key}\": {{ps: 0.5}}"));
        check_figures(f, 0.25, Some(1.0), Some(0.25 * 0.5 / 0.75));
    }
    // missing: named with the keys tried
    let e = err(body, A);
    assert!(
        e.message
            .contains("keys tried: S/P/if, P/if, Precondition/if"),
        "{e}"
    );
    // an entry for a predicate port that no node has is a typo
    let e = err(
        body,
        &format!("{A}\"P/if\": {{ps: 0.5}}\n\"P/iff\": {{ps: 1}}"),
    );
    assert!(
        e.message.contains("`P/iff` matches no action or condition"),
        "{e}"
    );
}

#[test]
fn precondition_refusals_are_located() {
    let params = format!("{A}\"Precondition/if\": {{ps: 0.5}}");
    for (body, at, what, semantic) in [
        (
            "<Precondition if=\"x\" else=\"RUNNING\"><A/></Precondition>",
            (3, 22),
            "never finishes",
            true,
        ),
        (
            "<Precondition if=\"x\" else=\"SKIPPED\"><A/></Precondition>",
            (3, 22),
            "skips the node",
            true,
        ),
        (
            "<Precondition if=\"x\" else=\"{st}\"><A/></Precondition>",
            (3, 22),
            "blackboard reference",
            true,
        ),
        (
            "<Precondition if=\"x\" else=\"MAYBE\"><A/></Precondition>",
            (3, 22),
            "not a node status",
            false,
        ),
        (
            "<Precondition else=\"FAILURE\"><A/></Precondition>",
            (3, 1),
            "needs `if`",
            false,
        ),
        (
            "<Precondition if=\"x\"><A/><A/></Precondition>",
            (3, 1),
            "exactly one child",
            false,
        ),
    ] {
        let e = err(body, &params);
        assert_eq!((e.line, e.column), at, "{body}: {e}");
        assert!(e.message.contains(what), "{body}: {e}");
        assert_eq!(is_unsupported(&e), semantic, "{body}: {e}");
    }
}

#[test]
fn loops_over_a_literal_queue_repeat_their_child() {
    // three runs of A until a failure: ps 1/8, MTTS 3; failure at run k
    // (probability 2^-k) after k - 1 successes: MTTF = Σ 2^-k (k - 1/2) / (7/8)
    let mttf3 = (0.5 * 0.5 + 0.25 * 1.5 + 0.125 * 2.5) / 0.875;
    for ty in [
        "LoopInt",
        "LoopDouble",
        "LoopString",
        "LoopBool",
        "LoopPose",
    ] {
        let body = format!("<{ty} queue=\"1;2;3\" value=\"{{v}}\"><A/></{ty}>");
        check_figures(xml_root(&body, A), 0.125, Some(3.0), Some(mttf3));
    }
    // a trailing `;` adds no element (BT.CPP's splitString)
    let body = "<LoopDouble queue=\"1;2;\"><A/></LoopDouble>";
    check_figures(
        xml_root(body, A),
        0.25,
        Some(2.0),
        Some((0.25 + 0.25 * 1.5) / 0.75),
    );
    // if_empty = FAILURE: the emptied queue fails (after 3 s)
    let body = "<LoopInt queue=\"1;2;3\" if_empty=\"FAILURE\"><A/></LoopInt>";
    check_figures(
        xml_root(body, A),
        0.0,
        None,
        Some(mttf3 * 0.875 + 0.125 * 3.0),
    );
    // an empty queue returns if_empty at once, the child never runs
    let body = "<LoopInt queue=\"\"><B/></LoopInt>";
    check_figures(xml_root(body, ""), 1.0, Some(0.0), None);
    let body = "<LoopInt queue=\"\" if_empty=\"FAILURE\"><B/></LoopInt>";
    check_figures(xml_root(body, ""), 0.0, None, Some(0.0));
    // a blackboard queue: its length from the params file
    let body = "<LoopPose queue=\"{waypoints}\" value=\"{wp}\"><A/></LoopPose>";
    let f = xml_root(body, &format!("{A}\"{{waypoints}}\": {{value: 4}}"));
    assert!(close(f.ps, 1.0 / 16.0), "{f:?}");
    assert!(close(f.mtts.unwrap(), 4.0), "{f:?}");
}

#[test]
fn loop_refusals_are_located() {
    for (body, at, what, semantic) in [
        (
            "<LoopPose queue=\"{waypoints}\"><A/></LoopPose>",
            (3, 11),
            "missing parameters for 1 node",
            false,
        ),
        (
            "<LoopInt queue=\"1\" if_empty=\"SKIPPED\"><A/></LoopInt>",
            (3, 20),
            "skips the node",
            true,
        ),
        (
            "<LoopInt queue=\"1\" if_empty=\"NO\"><A/></LoopInt>",
            (3, 20),
            "not a valid status",
            false,
        ),
        ("<LoopInt><A/></LoopInt>", (3, 1), "needs `queue`", false),
        (
            "<LoopInt queue=\"1\" valu=\"{v}\"><A/></LoopInt>",
            (3, 20),
            "unknown attribute `valu`",
            false,
        ),
    ] {
        let e = err(body, A);
        assert_eq!((e.line, e.column), at, "{body}: {e}");
        assert!(e.message.contains(what), "{body}: {e}");
        assert_eq!(is_unsupported(&e), semantic, "{body}: {e}");
    }
    let e = err(
        "<LoopInt queue=\"{n}\"><A/></LoopInt>",
        &format!("{A}\"{{n}}\": {{value: -1}}"),
    );
    assert!(e.message.contains("queue length -1"), "{e}");
}

/// B: a condition of ps 0.9.
const B: &str = "B: {ps: 0.9}\n";

#[test]
fn a_skipped_child_of_a_sequence_is_passed_over_as_a_success() {
    // A is skipped with 0.3 (at time 0), else runs: A' succeeds with
    // 0.3 + 0.7·0.5 = 0.65 (mean time 0.35·1/0.65), fails with 0.35 (1/2)
    let params = format!("{A}{B}\"A/_skipIf\": {{ps: 0.3}}");
    let body = "<Sequence><A _skipIf=\"s\"/><B/></Sequence>";
    let mttf = (0.35 * 0.5 + 0.065 * (0.35 / 0.65)) / 0.415;
    check_figures(
        xml_root(body, &params),
        0.585,
        Some(0.35 / 0.65),
        Some(mttf),
    );
    // `_while` false skips: the same with P(while) = 0.7
    let params = format!("{A}{B}\"A/_while\": {{ps: 0.7}}");
    let body = "<Sequence><A _while=\"w\"/><B/></Sequence>";
    check_figures(
        xml_root(body, &params),
        0.585,
        Some(0.35 / 0.65),
        Some(mttf),
    );
    let t = xml(body, &params).unwrap();
    let names: Vec<&str> = t.nodes().iter().map(|n| n.name.as_str()).collect();
    assert_eq!(names, ["Sequence", "A/guard", "A/_while", "A", "B"]);
}

#[test]
fn a_skipped_child_of_a_fallback_is_passed_over_as_a_failure() {
    // A' fails with 0.65 (0.3 at 0, 0.35 at mean 1/2), then B (zero time)
    let params = format!("{A}{B}\"A/_skipIf\": {{ps: 0.3}}");
    let body = "<Fallback><A _skipIf=\"s\"/><B/></Fallback>";
    let mtts = (0.35 * 1.0 + 0.9 * 0.35 * 0.5) / 0.935;
    check_figures(
        xml_root(body, &params),
        0.935,
        Some(mtts),
        Some(0.35 * 0.5 / 0.65),
    );
    // a constant `_skipIf="true"` always skips, without an entry
    let body = "<Fallback><A _skipIf=\"true\"/><B/></Fallback>";
    check_figures(
        xml_root(body, &format!("{A}{B}")),
        0.9,
        Some(0.0),
        Some(0.0),
    );
}

#[test]
fn failure_if_is_checked_before_success_if() {
    // _failureIf (0.2) → Failure at 0; else _successIf (0.5) → Success at 0;
    // else A: ps 0.8·0.5 + 0.4·0.5 = 0.6 (success if _successIf were first:
    // 0.5 + 0.5·0.8·0.5 = 0.7)
    let params = format!("{A}\"A/_failureIf\": {{ps: 0.2}}\n\"A/_successIf\": {{ps: 0.5}}");
    let body = "<A _successIf=\"s\" _failureIf=\"f\"/>";
    check_figures(
        xml_root(body, &params),
        0.6,
        Some(0.2 / 0.6),
        Some(0.2 * 0.5 / 0.4),
    );
}

#[test]
fn a_skipped_subtree_is_keyed_by_its_id() {
    // as BT.CPP's ex03_sqlite_log: the SubTree is skipped with 0.5 in a
    // Sequence; B after it
    let body = "<Sequence><SubTree ID=\"Sub\" _skipIf=\" type!='A' \"/><B/></Sequence>";
    let params = format!("{A}{B}\"Sub/_skipIf\": {{ps: 0.5}}\n\"Precondition/if\": {{ps: 1}}");
    // Sub = Precondition(if ps 1, A): Sub' succeeds with 0.5 + 0.25 = 0.75
    let ps = 0.75 * 0.9;
    let mttf = (0.25 * 0.5 + 0.75 * 0.1 * (0.25 / 0.75)) / (1.0 - ps);
    check_figures(xml_root(body, &params), ps, Some(0.25 / 0.75), Some(mttf));
}

#[test]
fn skips_without_a_meaning_are_refused_with_their_location() {
    let params = format!("{A}{B}\"A/_skipIf\": {{ps: 0.5}}\n\"B/_skipIf\": {{ps: 0.5}}");
    for (body, at, what) in [
        (
            "<Sequence><A _skipIf=\"s\"/><B _skipIf=\"t\"/></Sequence>",
            (3, 14),
            "every child of its parent <Sequence> may be skipped",
        ),
        (
            "<Parallel><A _skipIf=\"s\"/><B/></Parallel>",
            (3, 14),
            "its parent <Parallel> is not a Sequence or Fallback",
        ),
        (
            "<Inverter><A _skipIf=\"s\"/></Inverter>",
            (3, 14),
            "its parent <Inverter>",
        ),
        ("<A _skipIf=\"s\"/>", (3, 4), "a BehaviorTree's root"),
        (
            "<Sequence><A _failureIf=\"{x}\"/><B/></Sequence>",
            (3, 14),
            "not a blackboard reference",
        ),
    ] {
        let e = err(body, &params);
        assert_eq!((e.line, e.column), at, "{body}: {e}");
        assert!(e.message.contains(what), "{body}: {e}");
        assert!(is_unsupported(&e), "{body}: {e}");
    }
}

#[test]
fn a_switch_runs_the_child_of_the_first_matching_case() {
    // case_1 matches with 0.5 → A; else case_2 with 0.4 → AlwaysSuccess;
    // else the default AlwaysFailure: ps 0.25 + 0.2, failures 0.25 at A's
    // mean 1/2 and 0.3 at 0
    let body = "<Switch2 variable=\"{v}\" case_1=\"1\" case_2=\"true\"><A/><AlwaysSuccess/><AlwaysFailure/></Switch2>";
    let params = format!("{A}\"Switch2/case_1\": {{ps: 0.5}}\n\"Switch2/case_2\": {{ps: 0.4}}");
    check_figures(
        xml_root(body, &params),
        0.45,
        Some(0.25 / 0.45),
        Some(0.125 / 0.55),
    );
    // a missing case never matches (BT.CPP skips a case it cannot read);
    // `true` is a case value, not a constant predicate: it needs an entry
    let body = "<Switch2 name=\"S\" variable=\"{v}\" case_1=\"1\"><A/><AlwaysSuccess/><AlwaysFailure/></Switch2>";
    let params = format!("{A}\"S/case_1\": {{ps: 0.5}}");
    check_figures(xml_root(body, &params), 0.25, Some(1.0), Some(0.125 / 0.75));
    let body = "<Switch2 variable=\"{v}\" case_1=\"true\" case_2=\"2\"><A/><A/><A/></Switch2>";
    let e = err(body, A);
    assert!(e.message.contains("missing parameters for 2 nodes"), "{e}");
    assert!(e.message.contains("`Switch2/case_1`"), "{e}");
    // N + 1 children, as BT.CPP requires
    let body = "<Switch3 variable=\"{v}\" case_1=\"1\"><A/><A/></Switch3>";
    let e = err(body, A);
    assert_eq!((e.line, e.column), (3, 1), "{e}");
    assert!(e.message.contains("<Switch3> has 2 children"), "{e}");
    assert!(!is_unsupported(&e));
    let body = "<Switch2 variable=\"{v}\" case_3=\"1\"><A/><A/><A/></Switch2>";
    let e = err(body, A);
    assert!(e.message.contains("unknown attribute `case_3`"), "{e}");
}
