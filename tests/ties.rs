//! One tie rule everywhere (BehaviorTree.CPP's): within one instant the
//! children of a Parallel are visited in child order and the node returns at
//! the first threshold met. `report`, `curve` and `simulate` must agree on
//! every tie case; the expected figures are worked out by hand below.
//!
//! Deterministic instants that are equal as decimals tie even when their
//! binary sums differ (0.1 + 0.2 vs 0.3): the documented tolerance is 1e-12
//! relative (of max(|t|, 1 s)).

mod common;
use common::*;

const RUNS: u64 = 200_000;

/// Checks the root's ps and pf by report, by the curve at `t_done` (after
/// every return) and by simulation; and MTTS/MTTF by report and simulation.
fn check_root(yaml: &str, ps: f64, mtts: Option<f64>, mttf: Option<f64>, t_done: f64) {
    let t = tree(yaml);
    let f = root_figures(&t);
    assert!((f.ps - ps).abs() < 1e-12, "report ps {} vs {ps}", f.ps);
    assert!((f.pf - (1.0 - ps)).abs() < 1e-12, "report pf {}", f.pf);
    for (got, want, what) in [(f.mtts, mtts, "MTTS"), (f.mttf, mttf, "MTTF")] {
        match (got, want) {
            (Some(g), Some(w)) => assert!((g - w).abs() < 1e-12, "report {what} {g} vs {w}"),
            (None, None) => {}
            _ => panic!("report {what} {got:?} vs {want:?}"),
        }
    }
    let (s, fl) = root_curve_at(&t, t_done);
    assert!((s - ps).abs() < 1e-12, "curve success {s} vs {ps}");
    assert!((fl - (1.0 - ps)).abs() < 1e-12, "curve failure {fl}");
    let sim = simulate_root(&t, RUNS, &[]);
    let root = &sim.nodes[0];
    assert_within_z("simulated ps", &root.ps, ps);
    if let (Some(e), Some(w)) = (&root.mtts, mtts) {
        assert_within_z("simulated MTTS", e, w);
    }
    if let (Some(e), Some(w)) = (&root.mttf, mttf) {
        assert_within_z("simulated MTTF", e, w);
    }
}

#[test]
fn conditions_meeting_both_thresholds_count_in_child_order() {
    // M = 1, F = 1: the first child decides. Child 0 (ps 0.4) succeeds →
    // Success; fails → one failure = F → Failure. The second never matters.
    let yaml = "tree: {parallel: {success_threshold: 1, failure_threshold: 1, children: [\
                {condition: {ps: 0.4}}, {condition: {ps: 1.0}}]}}";
    check_root(yaml, 0.4, Some(0.0), Some(0.0), 1.0);
    // reversed: child 0 always succeeds first
    let yaml = "tree: {parallel: {success_threshold: 1, failure_threshold: 1, children: [\
                {condition: {ps: 1.0}}, {condition: {ps: 0.4}}]}}";
    check_root(yaml, 1.0, Some(0.0), None, 1.0);
}

#[test]
fn instant_outcomes_decide_before_running_children() {
    // M = 2, F = 1 over [cond 0.5, action, cond 0.3]. Child 0 fails (0.5):
    // F = 1 → Failure at 0. Otherwise the action runs, and child 2 decides at
    // once: Success (0.3) makes 2 successes → Success at 0; Failure (0.7) →
    // Failure at 0. So ps = 0.5 · 0.3 = 0.15, every return at t = 0.
    let yaml = "tree: {parallel: {success_threshold: 2, failure_threshold: 1, children: [\
                {condition: {ps: 0.5}}, {action: {ps: 0.5, mu: 1.0, nu: 2.0}}, \
                {condition: {ps: 0.3}}]}}";
    check_root(yaml, 0.15, Some(0.0), Some(0.0), 0.0);
}

#[test]
fn decimal_instants_tie_and_child_order_decides() {
    // Sequence(0.1 s, 0.2 s) succeeds at 0.1 + 0.2 (0.30000000000000004 in
    // binary) while the other child fails at 0.3: the same instant. M = 1,
    // F = 1, so the child visited first wins.
    let seq =
        "{sequence: {children: [{action: {ps: 1, tau_s: 0.1}}, {action: {ps: 1, tau_s: 0.2}}]}}";
    let fail = "{action: {ps: 0, tau_f: 0.3}}";
    let yaml = format!(
        "tree: {{parallel: {{success_threshold: 1, failure_threshold: 1, children: [{seq}, {fail}]}}}}"
    );
    check_root(&yaml, 1.0, Some(0.3), None, 0.5);
    let yaml = format!(
        "tree: {{parallel: {{success_threshold: 1, failure_threshold: 1, children: [{fail}, {seq}]}}}}"
    );
    check_root(&yaml, 0.0, None, Some(0.3), 0.5);
}

#[test]
fn random_outcomes_at_a_common_instant_replay_in_child_order() {
    // M = 2, F = 1 over three deterministic actions all returning at 1 s
    // (child 2 at 0.4 + 0.6): a = ps 0.7, b = ps 0.6, c = ps 0.5. In child
    // order the node returns at the first failure, or at the second success:
    //   a F → F;  a S, b F → F;  a S, b S → S (c never counts).
    // ps = 0.7 · 0.6 = 0.42, all at 1 s.
    let yaml = "tree: {parallel: {success_threshold: 2, failure_threshold: 1, children: [\
                {action: {ps: 0.7, tau_s: 1.0, tau_f: 1.0}}, \
                {action: {ps: 0.6, tau_s: 1.0, tau_f: 1.0}}, \
                {sequence: {children: [{action: {ps: 1, tau_s: 0.4}}, \
                 {action: {ps: 0.5, tau_s: 0.6, tau_f: 0.6}}]}}]}}";
    check_root(yaml, 0.42, Some(1.0), Some(1.0), 2.0);
}

#[test]
fn instant_outcomes_then_a_running_child() {
    // M = 2, F = 2 over [cond a 0.5, action x (ps 0.5, mu 1, nu 2), cond b
    // 0.3]. At t = 0, a and b decide when they agree: SS → Success (0.15),
    // FF → Failure (0.35). Otherwise (0.5) x decides at its return:
    // Success w.p. 0.5 after Exp(1), Failure after Exp(2).
    // ps = 0.15 + 0.25 = 0.4; E[T·1{S}] = 0.25 · 1 → MTTS = 0.625;
    // E[T·1{F}] = 0.25 · 0.5 → MTTF = 0.125 / 0.6.
    let yaml = "tree: {parallel: {success_threshold: 2, failure_threshold: 2, children: [\
                {condition: {ps: 0.5}}, {action: {ps: 0.5, mu: 1.0, nu: 2.0}}, \
                {condition: {ps: 0.3}}]}}";
    check_root(yaml, 0.4, Some(0.625), Some(0.125 / 0.6), 60.0);
}
