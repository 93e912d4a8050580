//! The outcome law of a race against a renewal process of re-runs (Nav2's
//! re-planning PipelineSequence, `compile::renewal_law`) composed with the
//! tree around it — a RecoveryNode, a Fallback, a Sequence — into the
//! curve of nodes above the race: the curve's limit against `report`'s
//! figures (exact, and independent: the figures of a flow come from its
//! children's figures), against a convolution computed here by quadrature
//! from the pipeline's own curve, and against simulation of the published
//! tick semantics (|z| < 5).

mod common;
use common::*;

use btrel::compile::curve::{curve, CurveOptions};
use btrel::tree::xml::parse_xml_str;
use btrel::tree::Tree;
use std::path::Path;

fn xml(body: &str, params: &str) -> Tree {
    let text = format!(
        "<root BTCPP_format=\"4\">\n<BehaviorTree ID=\"T\">\n{body}\n</BehaviorTree>\n</root>\n"
    );
    parse_xml_str(&text, "t.xml", params, "t.params.yaml").expect("test tree parses")
}

/// A pipeline that re-plans every 2 s while the follower runs: a re-plan
/// succeeds with 0.9, so the loop's series would need 306 re-runs (the
/// composed law needs none).
const PIPELINE: &str = "<PipelineSequence name=\"pipe\">\n<Sel/>\n\
                        <RateController hz=\"0.5\"><Plan/></RateController>\n<Follow/>\n\
                        </PipelineSequence>";

const PARAMS: &str = "Sel: {ps: 1.0, mu: 100}\nPlan: {ps: 0.9, mu: 2, nu: 4}\n\
                      Follow: {ps: 0.8, mu: 0.05, nu: 0.1}\n";
const ACT: &str = "Act: {ps: 0.7, mu: 0.2, nu: 0.3}\n";
const RECOVER: &str = "Recover: {ps: 0.8, mu: 0.5, nu: 1}\n";

/// The trees around the pipeline: a RecoveryNode with two retries, a
/// Fallback and a Sequence with an exponential action.
fn around() -> Vec<(&'static str, Tree)> {
    vec![
        (
            "recovery",
            xml(
                &format!(
                    "<RecoveryNode number_of_retries=\"2\" name=\"top\">\n{PIPELINE}\n<Recover/>\n</RecoveryNode>"
                ),
                &format!("{PARAMS}{RECOVER}"),
            ),
        ),
        (
            "fallback",
            xml(
                &format!("<Fallback name=\"top\">\n{PIPELINE}\n<Act/>\n</Fallback>"),
                &format!("{PARAMS}{ACT}"),
            ),
        ),
        (
            "sequence",
            xml(
                &format!("<Sequence name=\"top\">\n<Act/>\n{PIPELINE}\n</Sequence>"),
                &format!("{PARAMS}{ACT}"),
            ),
        ),
    ]
}

fn node(tree: &Tree, name: &str) -> usize {
    tree.nodes()
        .iter()
        .position(|n| n.name == name)
        .expect("the node exists")
}

#[test]
fn the_composed_curve_tends_to_the_report() {
    for (label, t) in around() {
        let f = root_figures(&t);
        // the follower's tail is below e^{-40} by 800 s
        let late = curve(&t, 0, &[800.0], &CurveOptions::default()).expect("curve")[0];
        assert!(late.running < 1e-12, "{label}: {late:?}");
        assert!(
            (late.success - f.ps).abs() < 1e-9,
            "{label}: {late:?} vs {f:?}"
        );
        assert!(
            (late.failure - f.pf).abs() < 1e-9,
            "{label}: {late:?} vs {f:?}"
        );
        // MTTS from the curve: E[T·1{S}] = ∫ (P(S) − S(t)) dt (trapezoid
        // on a 0.1 s grid: a check of the order of 1e-3 relative)
        let mtts = mtts_by_trapezoid(&t, f.ps, 8000);
        let want = f.mtts.expect("it succeeds");
        assert!(
            (mtts - want).abs() < 1e-3 * want,
            "{label}: {mtts} vs {f:?}"
        );
    }
}

#[test]
fn the_composed_curve_matches_simulation() {
    // the simulator runs the published PipelineSequence, RateController and
    // RecoveryNode with their tick semantics, not the lowering
    let times = [2.0, 5.0, 15.0, 40.0, 100.0];
    for (label, t) in around() {
        let pts = curve(&t, 0, &times, &CurveOptions::default()).expect("curve");
        let sim = simulate_root(&t, 200_000, &times);
        assert_root_and_curve_within_z(label, root_figures(&t), &pts, &sim);
    }
}

#[test]
fn a_fallback_after_the_pipeline_is_the_convolution_of_its_failure() {
    // Fallback(pipe, Act): S(t) = S_P(t) + ∫_0^t F_P(s) s_A(t − s) ds and
    // F(t) = ∫_0^t F_P(s) f_A(t − s) ds (by parts: F_P(0) = 0 and Act has
    // no atom), with s_A(u) = 0.7·0.2 e^{−0.2u}, f_A(u) = 0.3·0.3 e^{−0.3u}
    // and S_P, F_P the pipeline's own curve (the levels, not the law);
    // 30-point Gauss–Legendre on panels of 0.25 s cut at the period's
    // multiples, where F_P may kink
    let (_, t) = around().swap_remove(1);
    let pipe = node(&t, "pipe");
    let rule = gauss_legendre(30);
    let ends: [f64; 4] = [3.0, 10.0, 25.0, 60.0];
    let mut nodes: Vec<(usize, f64, f64)> = Vec::new(); // (end index, s, weight)
    for (k, &end) in ends.iter().enumerate() {
        let panels = (end / 0.25).round() as usize;
        for p in 0..panels {
            let (a, b) = (p as f64 * 0.25, (p + 1) as f64 * 0.25);
            for &(x, w) in &rule {
                nodes.push((k, (a + b) / 2.0 + (b - a) / 2.0 * x, w * (b - a) / 2.0));
            }
        }
    }
    let mut times: Vec<f64> = nodes.iter().map(|n| n.1).collect();
    times.extend_from_slice(&ends);
    let p = curve(&t, pipe, &times, &CurveOptions::default()).expect("the pipeline's curve");
    let got = curve(&t, 0, &ends, &CurveOptions::default()).expect("the fallback's curve");
    for (k, &end) in ends.iter().enumerate() {
        let (mut s, mut f) = (p[nodes.len() + k].success, 0.0);
        for (n, pt) in nodes.iter().zip(&p) {
            if n.0 == k {
                let u = end - n.1;
                s += n.2 * pt.failure * 0.7 * 0.2 * (-0.2 * u).exp();
                f += n.2 * pt.failure * 0.3 * 0.3 * (-0.3 * u).exp();
            }
        }
        let g = got[k];
        assert!(
            (g.success - s).abs() < 1e-10 && (g.failure - f).abs() < 1e-10,
            "t = {end}: composed ({}, {}) vs quadrature ({s}, {f}): diff {:.2e}, {:.2e}",
            g.success,
            g.failure,
            g.success - s,
            g.failure - f
        );
    }
}

/// A fixed 5 s Wait as the recovery around the race (atoms after 0 in the
/// composed laws): the curve's limit is `report`'s figures, and the curve
/// agrees with simulation (|z| < 5) before and after the Wait's instants.
#[test]
fn a_fixed_wait_around_the_race_composes() {
    let t = xml(
        &format!("<RecoveryNode number_of_retries=\"2\" name=\"top\">\n{PIPELINE}\n<Wait/>\n</RecoveryNode>"),
        &format!("{PARAMS}Wait: {{ps: 1.0, tau_s: 5.0}}\n"),
    );
    let f = root_figures(&t);
    let late = curve(&t, 0, &[800.0], &CurveOptions::default()).expect("curve")[0];
    assert!(late.running < 1e-12, "{late:?}");
    assert!((late.success - f.ps).abs() < 1e-9, "{late:?} vs {f:?}");
    assert!((late.failure - f.pf).abs() < 1e-9, "{late:?} vs {f:?}");
    let times = [2.0, 4.9, 5.1, 9.0, 15.0, 40.0, 100.0];
    let pts = curve(&t, 0, &times, &CurveOptions::default()).expect("curve");
    let sim = simulate_root(&t, 200_000, &times);
    assert_root_and_curve_within_z("fixed wait", f, &pts, &sim);
}

/// Nav2's default pipeline as published inside its RecoveryNode, the
/// recovery one exponential Spin (`trees/nav2-default-recovering.xml`).
#[test]
fn nav2_default_pipeline_in_its_recovery_node_tends_to_the_report() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("trees");
    let t = btrel::tree::xml::parse_xml_files(
        &dir.join("nav2-default-recovering.xml"),
        &dir.join("nav2-default-recovering.params.yaml"),
        &[],
    )
    .expect("the tree parses");
    let f = root_figures(&t);
    let late = curve(&t, 0, &[2500.0], &CurveOptions::default()).expect("curve")[0];
    assert!(late.running < 1e-10, "{late:?}");
    assert!((late.success - f.ps).abs() < 1e-9, "{late:?} vs {f:?}");
    assert!((late.failure - f.pf).abs() < 1e-9, "{late:?} vs {f:?}");
}

/// Nav2's default tree as published (its fixed 5 s `Wait` an atom of the
/// composed laws) with `trees/nav2-default.params.yaml`, docs/NAV2.md's
/// *Nav2's default tree*: the curve tends to `report`'s figures and agrees
/// with simulation of the published tick semantics (|z| < 5) at the times
/// docs/NAV2.md quotes.
#[test]
fn nav2_default_tree_as_published_has_its_curve() {
    let Some(root) = corpus() else {
        println!("note: the corpus is absent; skipping");
        return;
    };
    let dir = root.join("nav2");
    let t = btrel::tree::xml::parse_xml_files(
        &dir.join("navigate_to_pose_w_replanning_and_recovery.xml"),
        &Path::new(env!("CARGO_MANIFEST_DIR")).join("trees/nav2-default.params.yaml"),
        &[dir.join("nav2_tree_nodes.xml")],
    )
    .expect("the tree parses");
    let f = root_figures(&t);
    let late = curve(&t, 0, &[3000.0], &CurveOptions::default()).expect("curve")[0];
    assert!(late.running < 1e-10, "{late:?}");
    assert!((late.success - f.ps).abs() < 1e-9, "{late:?} vs {f:?}");
    assert!((late.failure - f.pf).abs() < 1e-9, "{late:?} vs {f:?}");
    let times = [10.0, 30.0, 60.0, 100.0, 300.0];
    let pts = curve(&t, 0, &times, &CurveOptions::default()).expect("curve");
    let sim = simulate_root(&t, 100_000, &times);
    assert_root_and_curve_within_z("Nav2 default tree", f, &pts, &sim);
}

/// A re-plan that can fail as it starts (a condition, after each 0.5 s
/// wait) ends the race at an instant of the wait's lattice: the levels'
/// densities do not hold those atoms, and the curve of every node above
/// the race was refused ("'ok' has deterministic, hybrid or shifted
/// times"). The composed laws' race takes it: the root's curve tends to
/// `report`'s figures and agrees with simulation (|z| < 5).
#[test]
fn a_rerun_that_fails_at_its_start_is_composed() {
    let t = tree(
        "tree: {fallback: {name: top, children: [{sequence: {name: s, children: [\
         {action: {name: pre, ps: 0.9, success_time: {shift: 0.2, rate: 3}, nu: 1}}, \
         {parallel: {name: race, success_threshold: 1, failure_threshold: 1, children: [\
         {until_failure: {name: replan, child: {sequence: {children: [\
         {action: {name: wait, ps: 1.0, tau_s: 0.5}}, {condition: {name: ok, ps: 0.9}}]}}}}, \
         {sequence: {name: rest, children: [\
         {action: {name: a, ps: 0.9, mu: 2, failure_time: {erlang: {k: 2, rate: 3}}}}, \
         {action: {name: b, ps: 0.8, mu: 0.5, nu: 1}}]}}]}}]}}, \
         {action: {name: c, ps: 0.5, tau_s: 1, nu: 2}}]}}\n",
    );
    let times = [0.5, 1.0, 2.0, 5.0];
    let pts = curve(&t, 0, &times, &CurveOptions::default()).expect("answered");
    let f = root_figures(&t);
    let late = root_curve_at(&t, 60.0);
    assert!(
        (late.0 - f.ps).abs() < 1e-9 && (late.1 - f.pf).abs() < 1e-9,
        "{late:?} {f:?}"
    );
    let sim = simulate_root(&t, 400_000, &times);
    assert_root_and_curve_within_z("re-run failing at its start", f, &pts, &sim);
}
