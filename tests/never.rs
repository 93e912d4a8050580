//! Laws that may never return: BT.CPP's ReactiveSequence / ReactiveFallback
//! restart loop and loops whose child never ends them.
//!
//! Expected values are hand calculations (below, at each test), Monte Carlo
//! (|z| < 5) and, in `tests/btcpp_referee.rs`, real BehaviorTree.CPP runs.

use btrel::curve::{curve, CurveOptions};
use btrel::tree::xml::parse_xml_str;
use btrel::tree::Tree;
use btrel::{analyze, Options};

mod common;

fn xml(body: &str, params: &str) -> Tree {
    let text = format!(
        r#"<root BTCPP_format="4" main_tree_to_execute="Main"><BehaviorTree ID="Main">{body}</BehaviorTree></root>"#
    );
    parse_xml_str(&text, "t.xml", params, "t.params.yaml").unwrap_or_else(|e| panic!("{e}"))
}

fn near(a: f64, b: f64) {
    assert!((a - b).abs() <= 1e-9 * b.abs().max(1.0), "{a} vs {b}");
}

/// ReactiveSequence(C: ps 0.6, A: ps 1, mu 1, B timed): C fails at once
/// (0.4); otherwise A succeeds, B starts and halts A, A restarts and halts
/// B, ... for ever: P(never) = 0.6, MTTF = 0 (the Failure is C's).
#[test]
fn reactive_sequence_whose_first_action_cannot_fail_never_returns() {
    let t = xml(
        "<ReactiveSequence name=\"RS\"><C/><A/><B/></ReactiveSequence>",
        "{C: {ps: 0.6}, A: {ps: 1.0, mu: 1}, B: {ps: 0.9, mu: 1, nu: 1}}",
    );
    let f = common::root_figures(&t);
    near(f.ps, 0.0);
    near(f.pf, 0.4);
    near(f.never(), 0.6);
    assert_eq!(f.mttf, Some(0.0));
    // π_R(t) tends to P(never) (here it is 0.6 from t = 0 on)
    for p in curve(&t, 0, &[0.0, 1.0, 100.0], &CurveOptions::default()).expect("curve") {
        near(p.running, 0.6);
        near(p.failure, 0.4);
    }
    // Monte Carlo: the runs that never return are counted as such
    let r = common::simulate_root(&t, 200_000, &[50.0]);
    common::assert_within_z("never", &r.nodes[0].never, 0.6);
    common::assert_within_z("pf", &r.nodes[0].pf, 0.4);
    common::assert_within_z("running at 50", &r.curve[0].running, 0.6);
}

/// ReactiveSequence(A: ps p = 0.8, mu 1, nu 2; B timed): A runs until one
/// run fails (B never completes): P(F) = 1, K ~ Geometric successes before
/// the failing run, E[K] = p/(1 − p) = 4, MTTF = 4·(1/mu) + 1/nu = 4.5.
/// With a condition C (ps 0.6) first: P(F) = 1, MTTF = 0.6·4.5 = 2.7.
#[test]
fn reactive_sequence_restarts_its_first_action_until_it_fails() {
    let params = "{A: {ps: 0.8, mu: 1, nu: 2}, B: {ps: 0.9, mu: 1, nu: 1}}";
    let t = xml("<ReactiveSequence><A/><B/></ReactiveSequence>", params);
    let f = common::root_figures(&t);
    near(f.pf, 1.0);
    near(f.mttf.expect("MTTF"), 4.5);
    let t = xml(
        "<ReactiveSequence><C/><A/><B/></ReactiveSequence>",
        "{C: {ps: 0.6}, A: {ps: 0.8, mu: 1, nu: 2}, B: {ps: 0.9, mu: 1, nu: 1}}",
    );
    let f = common::root_figures(&t);
    near(f.pf, 1.0);
    near(f.mttf.expect("MTTF"), 2.7);
    let r = common::simulate_root(&t, 200_000, &[]);
    common::assert_within_z("pf", &r.nodes[0].pf, 1.0);
    common::assert_within_z("MTTF", r.nodes[0].mttf.as_ref().expect("runs"), 2.7);
    // the time to Failure given C succeeded is A's runs: at t = 1,
    // P(F ≤ 1) = 0.4 + 0.6·P(loop ends by 1); Monte Carlo of the curve
    let exact = curve(&t, 0, &[1.0, 5.0], &CurveOptions::default()).expect("curve");
    let r = common::simulate_root(&t, 200_000, &[1.0, 5.0]);
    for (e, s) in exact.iter().zip(&r.curve) {
        common::assert_within_z("failure by t", &s.failure, e.failure);
    }
}

/// A condition between the two timed children (Q) is evaluated after A's
/// first Success: Sequence(A, Q, until_failure(A′)). A ps .8 mu 1 nu 2,
/// Q ps .5: A fails first (.2, mean .5): .1; A succeeds (.8, mean 1) and Q
/// fails: .8·.5·1 = .4; Q succeeds: .8·.5·(1 + 4.5) = 2.2; MTTF = 2.7.
#[test]
fn a_condition_between_the_timed_children_is_read_after_the_first_success() {
    let t = xml(
        "<ReactiveSequence><A/><Q/><B/></ReactiveSequence>",
        "{A: {ps: 0.8, mu: 1, nu: 2}, Q: {ps: 0.5}, B: {ps: 0.9, mu: 1, nu: 1}}",
    );
    let f = common::root_figures(&t);
    near(f.pf, 1.0);
    near(f.mttf.expect("MTTF"), 2.7);
    assert!(t.nodes().iter().any(|n| n.name.contains("/restart/A")));
    let r = common::simulate_root(&t, 200_000, &[]);
    common::assert_within_z("MTTF", r.nodes[0].mttf.as_ref().expect("runs"), 2.7);
}

/// ReactiveFallback, the mirror image: A (ps 0.3, mu 1, nu 2) runs until
/// one run succeeds: P(S) = 1, MTTS = (0.7/0.3)·(1/2) + 1 = 13/6; with A
/// unable to succeed (ps 0) it never returns.
#[test]
fn reactive_fallback_restarts_its_first_action_until_it_succeeds() {
    let t = xml(
        "<ReactiveFallback><A/><B/></ReactiveFallback>",
        "{A: {ps: 0.3, mu: 1, nu: 2}, B: {ps: 0.9, mu: 1, nu: 1}}",
    );
    let f = common::root_figures(&t);
    near(f.ps, 1.0);
    near(f.mtts.expect("MTTS"), 13.0 / 6.0);
    let r = common::simulate_root(&t, 200_000, &[]);
    common::assert_within_z("MTTS", r.nodes[0].mtts.as_ref().expect("runs"), 13.0 / 6.0);
    let t = xml(
        "<ReactiveFallback><A/><B/></ReactiveFallback>",
        "{A: {ps: 0.0, nu: 2}, B: {ps: 0.9, mu: 1, nu: 1}}",
    );
    near(common::root_figures(&t).never(), 1.0);
}

/// KeepRunningUntilFailure over a child that cannot fail never returns; in
/// a Parallel(success 1, failure 1) beside an action B (ps 0.7, mu 2, nu 3)
/// B decides: ps 0.7, MTTS 1/2, MTTF 1/3. With success 2 (both needed) a
/// Success of B leaves the node waiting for ever: P(never) = 0.7, P(F) =
/// 0.3, MTTF = 1/3.
#[test]
fn a_loop_that_never_returns_inside_a_parallel() {
    let params = "{A: {ps: 1.0, mu: 5}, B: {ps: 0.7, mu: 2, nu: 3}}";
    let body = |m: u32| {
        format!(
            "<Parallel success_count=\"{m}\" failure_count=\"1\">\
             <KeepRunningUntilFailure><A/></KeepRunningUntilFailure><B/></Parallel>"
        )
    };
    let t = xml(&body(1), params);
    let f = common::root_figures(&t);
    near(f.ps, 0.7);
    near(f.mtts.expect("MTTS"), 0.5);
    near(f.mttf.expect("MTTF"), 1.0 / 3.0);
    let t = xml(&body(2), params);
    let f = common::root_figures(&t);
    near(f.never(), 0.7);
    near(f.pf, 0.3);
    near(f.mttf.expect("MTTF"), 1.0 / 3.0);
    let r = common::simulate_root(&t, 200_000, &[]);
    common::assert_within_z("never", &r.nodes[0].never, 0.7);
    common::assert_within_z("MTTF", r.nodes[0].mttf.as_ref().expect("runs"), 1.0 / 3.0);
}

/// The endless loops are named, with the reason, for the CLI's warnings.
#[test]
fn endless_loops_are_named() {
    let t = xml(
        "<ReactiveSequence name=\"RS\"><A/><B/></ReactiveSequence>",
        "{A: {ps: 1.0, mu: 1}, B: {ps: 0.9, mu: 1, nu: 1}}",
    );
    let e = btrel::sim::endless_loops(&t);
    assert_eq!(e.len(), 1);
    assert!(
        e[0].1.contains("restart loop of ReactiveSequence 'RS'"),
        "{}",
        e[0].1
    );
    let t = xml(
        "<ReactiveSequence name=\"RS\"><A/><B/></ReactiveSequence>",
        "{A: {ps: 0.9, mu: 1, nu: 1}, B: {ps: 0.9, mu: 1, nu: 1}}",
    );
    assert!(btrel::sim::endless_loops(&t).is_empty());
}

/// Children whose first tick may or may not return are refused, located.
#[test]
fn a_child_that_may_return_at_its_first_tick_is_refused() {
    let params = "{A: {ps: 0.5, mu: 1, nu: 1}, C: {ps: 0.5}, B: {ps: 0.5, mu: 1, nu: 1}}";
    let text = r#"<root BTCPP_format="4" main_tree_to_execute="Main"><BehaviorTree ID="Main">
<ReactiveSequence><A/><Sequence><C/><B/></Sequence></ReactiveSequence></BehaviorTree></root>"#;
    let e = parse_xml_str(text, "t.xml", params, "t.params.yaml").expect_err("refused");
    assert!(btrel::tree::xml::is_unsupported(&e), "{e}");
    assert_eq!((e.line, e.column), (2, 1), "{e}");
    assert!(
        e.message.contains("may return within its first tick"),
        "{e}"
    );
}

/// `report`'s JSON carries P(never returns) when some node may never
/// return (and not otherwise).
#[test]
fn the_json_report_carries_p_never() {
    let params = "{C: {ps: 0.6}, A: {ps: 1.0, mu: 1}, B: {ps: 0.9, mu: 1, nu: 1}}";
    let t = xml("<ReactiveSequence><C/><A/><B/></ReactiveSequence>", params);
    let a = analyze(&t, &Options::default()).expect("analysed");
    let v = btrel::report::json::report_value(&btrel::report::Report::new(&t, &a));
    let never = v["nodes"][0]["never"].as_f64().expect("never");
    near(never, 0.6);
    let t = xml(
        "<ReactiveSequence><C/><A/></ReactiveSequence>",
        "{C: {ps: 0.6}, A: {ps: 1.0, mu: 1}}",
    );
    let a = analyze(&t, &Options::default()).expect("analysed");
    let v = btrel::report::json::report_value(&btrel::report::Report::new(&t, &a));
    assert!(v["nodes"][0].get("never").is_none(), "{v}");
}

/// Nav2's re-planning race with a planner cycle that may never return: the
/// first planning blocks the pipeline for ever when it never returns (0.5
/// here); a later re-plan that never returns stops the re-plans and leaves
/// the follower to decide. The renewal method's figures against Monte
/// Carlo (|z| < 5), and P(never) by hand: exactly the first planning's 0.5.
#[test]
fn a_replanning_cycle_that_never_returns_leaves_the_follower_to_decide() {
    let text = r#"<root BTCPP_format="4" main_tree_to_execute="Main"><BehaviorTree ID="Main">
<PipelineSequence name="P">
  <RateController hz="1.0">
    <Fallback>
      <ReactiveSequence name="Check"><C/><T/><V/></ReactiveSequence>
      <Plan/>
    </Fallback>
  </RateController>
  <Follow/>
</PipelineSequence></BehaviorTree></root>"#;
    let params = "{C: {ps: 0.5}, T: {ps: 1.0, mu: 10}, V: {ps: 0.9, mu: 10, nu: 10}, \
                  Plan: {ps: 0.9, mu: 1, nu: 0.5}, Follow: {ps: 0.7, mu: 0.05, nu: 0.1}}";
    let t = parse_xml_str(text, "t.xml", params, "t.params.yaml").unwrap_or_else(|e| panic!("{e}"));
    let f = common::root_figures(&t);
    // the first planning never returns when C holds (0.5): the pipeline
    // never starts the follower; after it, the follower (which always
    // returns) decides every run
    near(f.never(), 0.5);
    let r = common::simulate_root(&t, 200_000, &[]);
    let n = &r.nodes[0];
    common::assert_within_z("ps", &n.ps, f.ps);
    common::assert_within_z("pf", &n.pf, f.pf);
    common::assert_within_z("never", &n.never, f.never());
    common::assert_within_z(
        "MTTS",
        n.mtts.as_ref().expect("runs"),
        f.mtts.expect("MTTS"),
    );
    common::assert_within_z(
        "MTTF",
        n.mttf.as_ref().expect("runs"),
        f.mttf.expect("MTTF"),
    );
}

/// A loop over one action inside a Parallel, from its exact folded chain
/// (no unrolling): until_failure(A: ps 0.7, mu 2, nu 1) ends after
/// T = Z + Y (Z = 0 w.p. 0.3, else Exp(0.6); Y ~ Exp(1)), so
/// P(T > t) = 1.75 e^{−0.6t} − 0.75 e^{−t}; raced (success 1, failure 1)
/// against B that fails after Exp(1): Failure at min(T, T_B), MTTF =
/// 1.75/1.6 − 0.75/2 = 0.71875.
#[test]
fn a_loop_over_one_action_races_exactly() {
    let t = common::tree(
        "tree: {parallel: {success_threshold: 1, failure_threshold: 1, children: [\
         {until_failure: {child: {action: {ps: 0.7, mu: 2.0, nu: 1.0}}}}, \
         {action: {ps: 0.0, nu: 1.0}}]}}",
    );
    let f = common::root_figures(&t);
    near(f.pf, 1.0);
    near(f.mttf.expect("MTTF"), 0.71875);
    // the curve: P(F ≤ t) = 1 − P(T > t)·e^{−t}
    for p in curve(&t, 0, &[0.5, 2.0], &CurveOptions::default()).expect("curve") {
        let x = p.t;
        let alive = (1.75 * (-0.6 * x).exp() - 0.75 * (-x).exp()) * (-x).exp();
        assert!((p.failure - (1.0 - alive)).abs() < 1e-9, "{p:?}");
    }
}

/// `compare` refuses a tree with a node that may never return: the root's
/// P(Success) of `Fallback(c, loop)` is 0.4 in the given order and 0 with the
/// loop first, which figures of returning runs cannot rank.
#[test]
fn compare_refuses_a_tree_that_may_never_return() {
    let tree = common::tree(
        "tree: {fallback: {children: [{condition: {name: c, ps: 0.4}}, \
         {until_failure: {child: {action: {name: body, ps: 1.0, mu: 2.0}}}}]}}\n",
    );
    let e = btrel::compare::compare(&tree, &Default::default()).unwrap_err();
    assert!(
        matches!(e, btrel::compare::CompareError::NeverReturns(ref n) if n == "until_failure@0.1"),
        "{e}"
    );
}

/// The CLI's warning about a restart loop says how to model an action that
/// returns within its tick.
#[test]
fn restart_loop_warning_gives_the_zero_time_advice() {
    let dir = tempfile::tempdir().expect("tempdir");
    let xml = dir.path().join("rs.xml");
    std::fs::write(
        &xml,
        "<root BTCPP_format=\"4\"><BehaviorTree ID=\"M\"><ReactiveSequence name=\"RS\">\
         <A/><B/></ReactiveSequence></BehaviorTree></root>",
    )
    .expect("written");
    let params = dir.path().join("rs.params.yaml");
    std::fs::write(&params, "A: {ps: 1, mu: 1}\nB: {ps: 0.9, mu: 1, nu: 1}\n").expect("written");
    let (code, _, err) = common::run_btrel(&[
        "report",
        xml.to_str().expect("path"),
        "--params",
        params.to_str().expect("path"),
    ]);
    assert_eq!(code, 0, "{err}");
    assert!(
        err.contains("restart loop") && err.contains("give it `tau_s: 0`"),
        "{err}"
    );
    // plot warns too
    let png = dir.path().join("rs.png");
    let (code, _, err) = common::run_btrel(&[
        "plot",
        xml.to_str().expect("path"),
        "--params",
        params.to_str().expect("path"),
        "-o",
        png.to_str().expect("path"),
    ]);
    assert_eq!(code, 0, "{err}");
    assert!(err.contains("can run forever"), "{err}");
}

/// ForceSuccess / ForceFailure turn the runs of their child that return
/// into one outcome; a child that may never return leaves that mass never
/// returning (the report claimed ps 1 / pf 1: issue 29's survey, seed 113).
/// By hand: `fb` = Fallback(a, loop) with `a` (ps 0.3, Exp(1) times) and a
/// loop that never returns: `fb` succeeds with 0.3 at Exp(1) and otherwise
/// never returns, so ForceFailure(fb) fails with 0.3, MTTF 1, and
/// P(never) 0.7; ForceSuccess(fb) succeeds with 0.3, MTTS 1. The
/// sensitivity of the root's ps to `a`'s ps is 1 (ForceSuccess).
#[test]
fn force_decorators_keep_the_never_returning_mass() {
    use btrel::sensitivity::{sensitivity, Objective, Param};
    for (force, outcome) in [("force_failure", false), ("force_success", true)] {
        let t = common::tree(&format!(
            "tree:
  {force}:
    name: f
    child:
      fallback:
        name: fb
        children:
          - action: {{name: a, ps: 0.3, mu: 1, nu: 1}}
          - until_success: {{name: loop, child: {{condition: {{name: c, ps: 0}}}}}}
"
        ));
        let f = common::root_figures(&t);
        let (p, q, m) = if outcome {
            (f.ps, f.pf, f.mtts)
        } else {
            (f.pf, f.ps, f.mttf)
        };
        near(p, 0.3);
        near(q, 0.0);
        near(m.expect("a mean time"), 1.0);
        let (s, fl) = common::root_curve_at(&t, 200.0);
        near(s + fl, 0.3);
        if outcome {
            let sens = sensitivity(&t, Objective::Ps, &btrel::Options::default()).unwrap();
            let r = sens
                .rows
                .iter()
                .find(|r| t.nodes()[r.leaf].name == "a" && r.param == Param::Ps)
                .expect("a row for a's ps");
            near(r.derivative, 1.0);
        }
    }
}
