//! Node types whose control flow depends on a person, a queue on the
//! blackboard or the robot's motion: BT.CPP v3's ManualSelector and
//! ConsumeQueue, MoveIt Pro's ForEach and RepeatUnlessFailureEachTick,
//! Nav2's GoalUpdatedController, PathLongerOnApproach, DistanceController
//! and SpeedController. The expected figures are hand calculations from
//! the nodes' sources (BT.CPP `manual_node.cpp`, `consume_queue.h`; Nav2
//! `goal_updated_controller.cpp`, `path_longer_on_approach.cpp`,
//! `distance_controller.cpp`, `speed_controller.{c,h}pp`) under the SBT
//! assumptions, and Monte Carlo runs of btrel's simulator (|z| < 5).

mod common;

use btrel::compile::{analyze, Figures, Options};
use btrel::tree::xml::{is_unsupported, parse_xml_str};
use btrel::tree::{Tree, TreeError, TreeErrorKind};
use common::{
    assert_root_matches_simulation, assert_within_z, check_figures, close, root_curve_at,
    simulate_root,
};

fn xml(body: &str, params: &str) -> Result<Tree, TreeError> {
    let src = format!(
        "<root BTCPP_format=\"4\">\n<BehaviorTree ID=\"Main\">\n{body}\n</BehaviorTree>\n</root>\n"
    );
    parse_xml_str(&src, "t.xml", params, "t.params.yaml")
}

fn xml_tree(body: &str, params: &str) -> Tree {
    xml(body, params).unwrap_or_else(|e| panic!("{e}"))
}

fn xml_root(body: &str, params: &str) -> Figures {
    analyze(&xml_tree(body, params), &Options::default())
        .unwrap_or_else(|e| panic!("{e}"))
        .nodes[0]
}

fn err(body: &str, params: &str) -> TreeError {
    match xml(body, params) {
        Ok(t) => panic!("expected an error, got {t:?}"),
        Err(e) => e,
    }
}

/// Action A: ps 1/2, success time Exp(1) (mean 1 s), failure time Exp(2)
/// (mean 1/2 s).
const A: &str = "A: {ps: 0.5, mu: 1, nu: 2}\n";

#[test]
fn manual_selector_is_a_choice_with_the_params_probabilities() {
    // picks X with 0.2, Y with 0.8·0.5 = 0.4, Z (the rest) with 0.4
    // X: ps 0.8, success Exp(2), failure Exp(1); Y: ps 0.4, Exp(1), Exp(4);
    // Z: a condition of ps 0.3
    let params = "X: {ps: 0.8, mu: 2, nu: 1}\nY: {ps: 0.4, mu: 1, nu: 4}\nZ: {ps: 0.3}\n\
                  \"Pick/select_1\": {ps: 0.2}\n\"Pick/select_2\": {ps: 0.5}\n";
    let body =
        "<ManualSelector name=\"Pick\" repeat_last_selection=\"0\"><X/><Y/><Z/></ManualSelector>";
    // ps = 0.2·0.8 + 0.4·0.4 + 0.4·0.3 = 0.44
    // MTTS = (0.16·(1/2) + 0.16·1 + 0.12·0) / 0.44
    // MTTF = (0.04·1 + 0.24·(1/4) + 0.28·0) / 0.56
    check_figures(
        xml_root(body, params),
        0.44,
        Some(0.24 / 0.44),
        Some(0.1 / 0.56),
    );
    assert_root_matches_simulation(&xml_tree(body, params), 200_000);
    // the type keys the predicates when there is no name
    let body = "<ManualSelector><X/><Y/></ManualSelector>";
    let f = xml_root(body, "X: {ps: 0.8, mu: 2, nu: 1}\nY: {ps: 0.4, mu: 1, nu: 4}\n\"ManualSelector/select_1\": {ps: 0.25}\n");
    check_figures(
        f,
        0.25 * 0.8 + 0.75 * 0.4,
        Some((0.2 * 0.5 + 0.3) / 0.5),
        Some((0.05 + 0.45 * 0.25) / 0.5),
    );
    // without children the user picks the status: a condition keyed like a
    // leaf
    check_figures(
        xml_root("<ManualSelector name=\"Ask\"/>", "Ask: {ps: 0.3}"),
        0.3,
        Some(0.0),
        Some(0.0),
    );
    // one child: the child itself, no predicate
    check_figures(
        xml_root("<ManualSelector><A/></ManualSelector>", A),
        0.5,
        Some(1.0),
        Some(0.5),
    );
}

#[test]
fn manual_selector_refusals_and_missing_predicates() {
    // the first pick kept for all later executions: refused, located
    let e = err(
        "<Repeat num_cycles=\"2\"><ManualSelector repeat_last_selection=\"true\"><A/><A/></ManualSelector></Repeat>",
        A,
    );
    assert!(is_unsupported(&e), "{e}");
    assert!(
        e.to_string().contains("t.xml:3:") && e.to_string().contains("repeat_last_selection"),
        "{e}"
    );
    // the predicates are parameters: all listed at once
    let e = err("<ManualSelector><A/><A/><A/></ManualSelector>", A);
    assert!(!is_unsupported(&e));
    let text = e.to_string();
    assert!(
        text.contains("ManualSelector/select_1") && text.contains("ManualSelector/select_2"),
        "{text}"
    );
}

#[test]
fn consume_queue_and_foreach_run_the_child_once_per_element() {
    // A three times: ps 1/8; success after three Exp(1): MTTS 3; failure at
    // run k with probability 2^-k, at (k − 1) + 1/2 on average
    let mttf = (0.5 * 0.5 + 0.25 * 1.5 + 0.125 * 2.5) / 0.875;
    let params = format!("{A}\"{{q}}\": {{value: 3}}\n");
    for body in [
        "<ConsumeQueue queue=\"{q}\" popped_item=\"{x}\"><A/></ConsumeQueue>",
        "<Decorator ID=\"ForEach\" vector_in=\"{q}\" out=\"{x}\" index=\"{i}\"><A/></Decorator>",
    ] {
        check_figures(xml_root(body, &params), 0.125, Some(3.0), Some(mttf));
        // the success curve: 1/8 times the Erlang(3, 1) CDF
        let t = 2.0f64;
        let erlang = 1.0 - (-t).exp() * (1.0 + t + t * t / 2.0);
        let (s, _) = root_curve_at(&xml_tree(body, &params), t);
        assert!((s - 0.125 * erlang).abs() < 1e-9, "{body}: {s}");
        assert_root_matches_simulation(&xml_tree(body, &params), 100_000);
    }
    // ConsumeQueue on an empty queue: Success at once
    let f = xml_root(
        "<ConsumeQueue queue=\"{q}\"><A/></ConsumeQueue>",
        "\"{q}\": {value: 0}\n",
    );
    check_figures(f, 1.0, Some(0.0), None);
    // ForEach on an empty vector: MoveIt Pro does not say; refused
    let e = err(
        "<ForEach vector_in=\"{q}\"><A/></ForEach>",
        &format!("{A}\"{{q}}\": {{value: 0}}\n"),
    );
    assert!(
        is_unsupported(&e) && e.to_string().contains("empty vector"),
        "{e}"
    );
    // a literal is not a queue object: refused; a reference without a
    // value: a missing parameter, naming the key to add
    let e = err("<ConsumeQueue queue=\"1;2;3\"><A/></ConsumeQueue>", A);
    assert!(
        is_unsupported(&e) && e.to_string().contains("not a blackboard reference"),
        "{e}"
    );
    let e = err("<ForEach vector_in=\"{v}\"><A/></ForEach>", A);
    assert!(
        e.kind == TreeErrorKind::MissingParameter
            && e.message.starts_with("missing parameters for 1 node")
            && e.to_string().contains("`\"{v}\": {value: N}`"),
        "{e}"
    );
}

#[test]
fn repeat_unless_failure_each_tick_is_repeat() {
    // two Successes in a row: ps 1/4, MTTS 2
    let body = "<Decorator ID=\"RepeatUnlessFailureEachTick\" num_cycles=\"2\"><A/></Decorator>";
    check_figures(
        xml_root(body, A),
        0.25,
        Some(2.0),
        Some((0.5 * 0.5 + 0.25 * 1.5) / 0.75),
    );
    // -1: until a Failure, which is its Failure: ps 0; the failing run is
    // the k-th with probability 2^-k, after k − 1 successes: MTTF
    // 1/2 + E[k − 1] = 1/2 + 1
    let body = "<RepeatUnlessFailureEachTick num_cycles=\"-1\"><A/></RepeatUnlessFailureEachTick>";
    check_figures(xml_root(body, A), 0.0, None, Some(1.5));
}

#[test]
fn path_longer_on_approach_runs_its_child_when_the_path_got_longer() {
    // the path got longer with 0.3: A runs (ps 1/2), else Success at once
    let body = "<PathLongerOnApproach path=\"{path}\" prox_len=\"3.0\" length_factor=\"2.0\"><A/></PathLongerOnApproach>";
    let params = format!("{A}\"PathLongerOnApproach/longer\": {{ps: 0.3}}\n");
    check_figures(xml_root(body, &params), 0.85, Some(0.15 / 0.85), Some(0.5));
    assert_root_matches_simulation(&xml_tree(body, &params), 100_000);
    // the predicate is a parameter
    let e = err(body, A);
    assert!(e.to_string().contains("PathLongerOnApproach/longer"), "{e}");
}

#[test]
fn goal_updated_controller_runs_its_child_once() {
    let body = "<GoalUpdatedController><A/></GoalUpdatedController>";
    check_figures(xml_root(body, A), 0.5, Some(1.0), Some(0.5));
    // an earlier pipeline child: re-ticked it returns RUNNING without
    // ticking its child, so the pipeline is a Sequence (ps 1/2 · 4/5)
    let body = "<PipelineSequence><GoalUpdatedController><A/></GoalUpdatedController><B/></PipelineSequence>";
    let params = format!("{A}B: {{ps: 0.8, mu: 1, nu: 1}}\n");
    let f = xml_root(body, &params);
    assert!(close(f.ps, 0.4) && close(f.mtts.unwrap(), 2.0), "{f:?}");
    assert_root_matches_simulation(&xml_tree(body, &params), 100_000);
    // ... which btrel cannot express when the child is a subtree that takes
    // time and can fail (its re-tick would re-run it): refused, located
    let body = "<PipelineSequence><GoalUpdatedController><Sequence><A/><A/></Sequence></GoalUpdatedController><B/></PipelineSequence>";
    let e = err(body, &params);
    assert!(
        is_unsupported(&e) && e.to_string().contains("t.xml:3:19"),
        "{e}"
    );
    assert!(e.to_string().contains("GoalUpdatedController"), "{e}");
}

/// A pipeline whose planner `A` (ps 1/2, 0.5 s either way) is re-run by a
/// controller while `B` (0.5 s + `b` s after A's first run) runs: with fixed
/// times, the pipeline succeeds iff A's first run and every re-run that
/// ends before B do.
fn replanning(tag: &str, attrs: &str, b: f64) -> (String, String) {
    let body = format!("<PipelineSequence><{tag} {attrs}><A/></{tag}><B/></PipelineSequence>");
    let params = format!("A: {{ps: 0.5, tau_s: 0.5, tau_f: 0.5}}\nB: {{ps: 1, tau_s: {b}}}\n");
    (body, params)
}

#[test]
fn distance_controller_is_a_rate_controller_of_period_distance_over_speed() {
    // outside a pipeline: its child once
    let params = format!("{A}\"DistanceController/speed\": {{value: 0.5}}\n");
    check_figures(
        xml_root(
            "<DistanceController distance=\"1.0\"><A/></DistanceController>",
            &params,
        ),
        0.5,
        Some(1.0),
        Some(0.5),
    );
    // period 1 m / 0.5 m/s = 2 s: re-runs end at 0.5 + 2.5k s; B ends at
    // 6.5 s, so re-runs 1 and 2 (3.0, 5.5 s) must succeed: ps 1/2³
    let (body, params) = replanning("DistanceController", "distance=\"1.0\"", 6.0);
    let params = format!("{params}\"DistanceController/speed\": {{value: 0.5}}\n");
    let f = xml_root(&body, &params);
    assert!(close(f.ps, 0.125), "{f:?}");
    let sim = simulate_root(&xml_tree(&body, &params), 40_000, &[]);
    assert_within_z("ps", &sim.nodes[0].ps, 0.125);
    // a missing speed is a missing parameter, listed with the others
    let e = err("<DistanceController><A/></DistanceController>", "");
    assert!(!is_unsupported(&e));
    let text = e.to_string();
    assert!(
        text.contains("missing parameters for 2 nodes")
            && text.contains("t.xml:3:1: DistanceController")
            && text.contains("\"DistanceController/speed\": {value: 0.3}"),
        "{text}"
    );
}

#[test]
fn speed_controller_waits_two_over_the_rate_sum_first() {
    // rate = 0.5 + (v − 0)/(1 − 0)·(1.5 − 0.5), clamped to [0.5, 1.5]
    let ports = "min_rate=\"0.5\" max_rate=\"1.5\" min_speed=\"0.0\" max_speed=\"1.0\"";
    // v = 1: rate 1.5, period 2/3 s; the first wait is 2/(0.5 + 1.5) = 1 s.
    // Re-runs end at 0.5 + 1 + 0.5 = 2.0, then every 7/6 s: 3.1667, 4.3333.
    // B ends at 4.1 s: two re-runs must succeed, ps 1/8 (with the period
    // 2/3 s from the start three would: 1.667, 2.833, 4.0)
    let (body, params) = replanning("SpeedController", ports, 3.6);
    let params = format!("{params}\"SpeedController/speed\": {{value: 1.0}}\n");
    // Failures: A's first run at 0.5 s (1/2), re-run 1 at 2.0 s (1/4),
    // re-run 2 at 3.1667 s (1/8); Success at 4.1 s. The lowering runs one
    // cycle with the first wait, then the loop with the later one.
    let t = xml_tree(&body, &params);
    let mttf = (0.5 * 0.5 + 0.25 * 2.0 + 0.125 * (2.0 + 7.0 / 6.0)) / 0.875;
    check_figures(xml_root(&body, &params), 0.125, Some(4.1), Some(mttf));
    let sim = simulate_root(&t, 40_000, &[]);
    assert_within_z("ps", &sim.nodes[0].ps, 0.125);
    // v = 0.5: rate 1 Hz = (0.5 + 1.5)/2, both waits 1 s: exact. Re-runs end
    // at 2.0, 3.5, 5.0; B ends at 4.1: ps 1/8
    let params = params.replace("{value: 1.0}", "{value: 0.5}");
    let f = xml_root(&body, &params);
    assert!(close(f.ps, 0.125), "{f:?}");
    // Nav2's default ports at half the top speed: rate 0.55 Hz, both waits
    // 2/1.1 = 1/0.55 s (equal up to rounding: one period)
    let t = xml_tree(
        "<SpeedController min_rate=\"0.1\" max_rate=\"1.0\" min_speed=\"0.0\" max_speed=\"0.26\"><A/></SpeedController>",
        &format!("{A}\"SpeedController/speed\": {{value: 0.13}}\n"),
    );
    match t.nodes()[0].kind {
        btrel::tree::NodeKind::Decorator {
            decorator: btrel::tree::Decorator::Rate { first, period },
            ..
        } => assert!(
            first == period && (period - 1.0 / 0.55).abs() < 1e-12,
            "{first} {period}"
        ),
        ref k => panic!("{k:?}"),
    }
    // speeds above max_speed clamp to max_rate, a negative one is invalid
    let params2 = params.replace("{value: 0.5}", "{value: -1}");
    let e = err(&body, &params2);
    assert!(e.to_string().contains("speed -1"), "{e}");
}

#[test]
fn port_values_are_checked_like_other_params() {
    // an entry that no node reads is a typo
    let e = err(
        "<A/>",
        &format!("{A}\"DistanceControler/speed\": {{value: 0.5}}\n"),
    );
    assert!(e.to_string().contains("port value"), "{e}");
    // a port value takes only `value`
    let e = err(
        "<DistanceController><A/></DistanceController>",
        &format!("{A}\"DistanceController/speed\": {{value: 0.5, ps: 1}}\n"),
    );
    assert!(e.to_string().contains("takes only `value`"), "{e}");
    // rates too small for a finite period, a bad range: located errors
    let speed = format!("{A}\"SpeedController/speed\": {{value: 0.1}}\n");
    let e = err(
        "<SpeedController min_rate=\"1e-320\" max_rate=\"1e-320\"><A/></SpeedController>",
        &speed,
    );
    assert!(
        e.to_string().contains("t.xml:3:1") && e.to_string().contains("no finite period"),
        "{e}"
    );
    let e = err(
        "<SpeedController min_speed=\"1\" max_speed=\"1\"><A/></SpeedController>",
        &speed,
    );
    assert!(e.to_string().contains("min_speed < max_speed"), "{e}");
    let e = err(
        "<SpeedController max_rate=\"fast\"><A/></SpeedController>",
        &speed,
    );
    assert!(e.to_string().contains("is not a number"), "{e}");
}

#[test]
fn replanning_controllers_with_random_times_agree_with_the_simulator() {
    // the planner A (ps 1/2, Exp(2) either way) re-run while B (ps 0.9,
    // success Exp(1/2), failure Exp(1)) runs: the exact race of the lowered
    // pipeline against btrel's simulator, which plays the controller's
    // waits itself
    let params = "A: {ps: 0.5, mu: 2, nu: 2}\nB: {ps: 0.9, mu: 0.5, nu: 1}\n";
    for (controller, speed) in [
        (
            "<DistanceController distance=\"0.5\">",
            "\"DistanceController/speed\": {value: 0.25}",
        ),
        // v = 0.5 in [0, 1]: rate 1 Hz = (0.5 + 1.5)/2, both waits 1 s
        (
            "<SpeedController min_rate=\"0.5\" max_rate=\"1.5\" min_speed=\"0\" max_speed=\"1\">",
            "\"SpeedController/speed\": {value: 0.5}",
        ),
        // v = 1: rate 1.5 Hz, the first wait 1 s and the later ones 2/3 s
        // (one cycle of its own, then the renewal loop)
        (
            "<SpeedController min_rate=\"0.5\" max_rate=\"1.5\" min_speed=\"0\" max_speed=\"1\">",
            "\"SpeedController/speed\": {value: 1.0}",
        ),
    ] {
        let tag = &controller[1..controller.find(' ').unwrap()];
        let body = format!("<PipelineSequence>{controller}<A/></{tag}><B/></PipelineSequence>");
        let t = xml_tree(&body, &format!("{params}{speed}\n"));
        assert_root_matches_simulation(&t, 200_000);
    }
}

#[test]
fn path_longer_on_approach_below_a_reactive_sequence_is_not_restarted() {
    // ReactiveSequence(PathLongerOnApproach(A), B): re-ticked while B runs,
    // it finds the path it stored and returns Success at once, so the node
    // is Sequence(flow, B): ps (0.7 + 0.3·1/2)·0.8
    let longer = "<PathLongerOnApproach path=\"{path}\"><A/></PathLongerOnApproach>";
    let params =
        format!("{A}B: {{ps: 0.8, mu: 1, nu: 1}}\n\"PathLongerOnApproach/longer\": {{ps: 0.3}}\n");
    let body = format!("<ReactiveSequence>{longer}<B/></ReactiveSequence>");
    let f = xml_root(&body, &params);
    assert!(close(f.ps, 0.85 * 0.8), "{f:?}");
    assert_root_matches_simulation(&xml_tree(&body, &params), 100_000);
    // after B, or below a ReactiveFallback (a re-tick's Success would end
    // the fallback): B would be restarted or halted, refused
    for body in [
        format!("<ReactiveSequence><B/>{longer}</ReactiveSequence>"),
        format!("<ReactiveFallback>{longer}<B/></ReactiveFallback>"),
    ] {
        let e = err(&body, &params);
        assert!(
            is_unsupported(&e) && e.to_string().contains("restarted"),
            "{e}"
        );
    }
}
