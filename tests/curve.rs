//! π(t) against independent derivations: closed forms, hand-computed atoms
//! of deterministic trees, and reference/refs.json (an independent
//! Python/mpmath implementation, see reference/README.md).

use std::path::Path;

mod common;

use common::tree;

use btrel::compile::Method;
use btrel::curve::{curve, CurveOptions, CurvePoint, Timing};
use btrel::tree::{parse_file, Tree};
use serde_json::Value;

fn refs() -> Value {
    let text = std::fs::read_to_string("reference/refs.json").expect("reference/refs.json");
    serde_json::from_str(&text).expect("valid JSON")
}

fn file(name: &str) -> Tree {
    parse_file(Path::new(name)).expect("valid tree file")
}

fn at(tree: &Tree, node: &str, times: &[f64], options: &CurveOptions) -> Vec<CurvePoint> {
    let id = tree.find(node).unwrap_or_else(|| panic!("no node {node}"));
    curve(tree, id, times, options).expect("curve")
}

fn exact() -> CurveOptions {
    CurveOptions::default()
}

fn book() -> CurveOptions {
    CurveOptions {
        method: Method::Book,
        ..CurveOptions::default()
    }
}

fn floats(v: &Value) -> Vec<f64> {
    v.as_array()
        .expect("array")
        .iter()
        .map(|x| x.as_f64().expect("number"))
        .collect()
}

/// Compares a curve with a refs.json series {t, p_success, p_failure}.
fn check_series(points: &[CurvePoint], series: &Value, tol: f64) {
    let s = floats(&series["p_success"]);
    let f = floats(&series["p_failure"]);
    for (i, p) in points.iter().enumerate() {
        assert!(
            (p.success - s[i]).abs() <= tol,
            "t={}: success {} vs {}",
            p.t,
            p.success,
            s[i]
        );
        assert!(
            (p.failure - f[i]).abs() <= tol,
            "t={}: failure {} vs {}",
            p.t,
            p.failure,
            f[i]
        );
        assert!((p.success + p.failure + p.running - 1.0).abs() <= 1e-12);
    }
}

/// CDF of Exp(a) + Exp(b), a ≠ b.
fn hypo2(a: f64, b: f64, t: f64) -> f64 {
    1.0 - (b * (-a * t).exp() - a * (-b * t).exp()) / (b - a)
}

#[test]
fn single_action_is_the_mixture_of_def_9_7() {
    let t = tree("tree: {action: {ps: 0.3, mu: 0.5, nu: 2.0}}");
    let times = [0.0, 0.1, 1.0, 4.0, 50.0];
    for p in curve(&t, 0, &times, &exact()).unwrap() {
        // eqs. 9.15-9.16
        assert!((p.success - 0.3 * (1.0 - (-0.5 * p.t).exp())).abs() < 1e-13);
        assert!((p.failure - 0.7 * (1.0 - (-2.0 * p.t).exp())).abs() < 1e-13);
    }
}

#[test]
fn two_action_fallback_closed_form() {
    let t = tree(
        "tree: {fallback: {children: [{action: {ps: 0.4, mu: 1.0, nu: 3.0}}, {action: {ps: 0.7, mu: 0.5, nu: 0.2}}]}}",
    );
    let times = [0.2, 1.0, 2.5, 10.0, 40.0];
    for p in curve(&t, 0, &times, &exact()).unwrap() {
        let s = 0.4 * (1.0 - (-p.t).exp()) + 0.6 * 0.7 * hypo2(3.0, 0.5, p.t);
        let f = 0.6 * 0.3 * hypo2(3.0, 0.2, p.t);
        assert!((p.success - s).abs() < 1e-12, "{p:?} vs {s}");
        assert!((p.failure - f).abs() < 1e-12, "{p:?} vs {f}");
    }
}

#[test]
fn example_9_7_matches_reference() {
    let r = refs();
    let ex = &r["example_9_7"];
    let t = file("trees/three-action-fallback.yaml");
    let times = floats(&ex["t"]);
    check_series(&at(&t, "fallback", &times, &exact()), ex, 1e-11);
}

#[test]
fn search_and_grasp_exact_matches_reference() {
    let r = refs();
    let sg = &r["search_and_grasp"]["probabilities_over_time"];
    let t = file("trees/search-and-grasp.yaml");
    for (node, key) in [
        ("search and grasp", "root"),
        ("search", "search"),
        ("grasp", "grasp"),
        ("find object", "find object"),
        ("grasp object", "grasp object"),
    ] {
        let times = floats(&sg[key]["t"]);
        check_series(&at(&t, node, &times, &exact()), &sg[key], 1e-11);
    }
    // the figures
    let p = at(&t, "search and grasp", &[100.0], &exact())[0];
    assert!((p.success - 0.1977).abs() < 5e-5 && (p.failure - 0.1516).abs() < 5e-5);
}

#[test]
fn drawer_first_is_better_by_100s() {
    let r = refs();
    let df = &r["search_and_grasp"]["drawer_first"]["probabilities_over_time"]["root"];
    let t = file("trees/search-and-grasp-drawer-first.yaml");
    let times = floats(&df["t"]);
    check_series(&at(&t, "search and grasp", &times, &exact()), df, 1e-11);
    let p = at(&t, "search and grasp", &[100.0], &exact())[0];
    assert!((p.success - 0.2704).abs() < 5e-5);
}

#[test]
fn book_method_matches_reference() {
    let r = refs();
    let b = &r["book_method"];
    let t = file("trees/search-and-grasp.yaml");
    for (node, key) in [
        ("search and grasp", "root"),
        ("search", "search"),
        ("grasp", "grasp"),
    ] {
        let times = floats(&b[key]["t"]);
        check_series(&at(&t, node, &times, &book()), &b[key], 1e-11);
    }
    let p = at(&t, "search and grasp", &[100.0], &book())[0];
    assert!((p.success - 0.1801).abs() < 5e-5 && (p.failure - 0.1944).abs() < 5e-5);
    let d = file("trees/search-and-grasp-drawer-first.yaml");
    let times = floats(&b["root_drawer_first"]["t"]);
    check_series(
        &at(&d, "search and grasp", &times, &book()),
        &b["root_drawer_first"],
        1e-11,
    );
}

#[test]
fn book_method_eliminates_zero_duration_children() {
    // Sequence[condition .5, action]: the action is one exponential of mean
    // SJ = ps/mu + pf/nu in the book's CTMC
    let t = tree(
        "tree: {sequence: {children: [{condition: {ps: 0.5}}, {action: {ps: 0.6, mu: 2.0, nu: 0.5}}]}}",
    );
    let sj = 0.6 / 2.0 + 0.4 / 0.5;
    for p in curve(&t, 0, &[0.0, 0.3, 2.0, 9.0], &book()).unwrap() {
        let cdf = 1.0 - (-p.t / sj).exp();
        assert!((p.success - 0.5 * 0.6 * cdf).abs() < 1e-13, "{p:?}");
        assert!((p.failure - (0.5 + 0.5 * 0.4 * cdf)).abs() < 1e-13, "{p:?}");
    }
}

#[test]
fn parallel_cases_match_reference() {
    let r = refs();
    let par = &r["parallel"];
    for (key, m) in [("a_M1_of_2", 1), ("b_M2_of_2", 2), ("c_M2_of_3", 2)] {
        let case = &par[key];
        let children: Vec<String> = case["children"]
            .as_array()
            .unwrap()
            .iter()
            .map(|c| {
                let c = floats(c);
                format!("{{action: {{ps: {}, mu: {}, nu: {}}}}}", c[0], c[1], c[2])
            })
            .collect();
        let yaml = format!(
            "tree: {{parallel: {{success_threshold: {m}, children: [{}]}}}}",
            children.join(", ")
        );
        let t = tree(&yaml);
        let times = floats(&case["t"]);
        check_series(&curve(&t, 0, &times, &exact()).unwrap(), case, 1e-11);
    }
}

#[test]
fn stiff_tree_matches_high_precision_reference() {
    // rates from 1e-4 to 1e5, horizon 1e7: plain uniformization would need
    // ~1e12 steps; reference from mpmath at 50 digits
    let r = refs();
    let st = &r["stiff"];
    let t = tree(
        "tree:\n  sequence:\n    children:\n      - action: {ps: 0.9, mu: 1e5, nu: 1e4}\n      - action: {ps: 0.99, mu: 1e-4, nu: 2e-4}\n      - fallback:\n          children:\n            - action: {ps: 0.5, mu: 10, nu: 1}\n            - action: {ps: 0.5, mu: 1e-3, nu: 1e-2}\n",
    );
    let times = floats(&st["t"]);
    let points = curve(&t, 0, &times, &exact()).unwrap();
    check_series(&points, st, 1e-10);
    // also on a fine grid: monotone and within [0, 1]
    let grid: Vec<f64> = (0..=200).map(|k| 5e4 * k as f64).collect();
    let pts = curve(&t, 0, &grid, &exact()).unwrap();
    for w in pts.windows(2) {
        assert!(w[1].success >= w[0].success - 1e-12 && w[1].failure >= w[0].failure - 1e-12);
    }
}

#[test]
fn deterministic_example_9_8_atoms_by_hand() {
    // three-action Fallback with tau = 1/rate: (ts, tf) = (2, 1), (5, 2.5), (10, 4)
    // Success at 2 (.3), at 1 + 5 = 6 (.7*.6 = .42), at 1 + 2.5 + 10 = 13.5 (.7*.4*.5 = .14)
    // Failure at 1 + 2.5 + 4 = 7.5 (.14)
    let t = file("trees/three-action-fallback.yaml");
    let options = CurveOptions {
        timing: Timing::Deterministic,
        ..CurveOptions::default()
    };
    let expect = [
        (1.999, 0.0, 0.0),
        (2.0, 0.3, 0.0),
        (5.99, 0.3, 0.0),
        (6.0, 0.72, 0.0),
        (7.4999, 0.72, 0.0),
        (7.5, 0.72, 0.14),
        (13.5, 0.86, 0.14),
        (1e3, 0.86, 0.14),
    ];
    let times: Vec<f64> = expect.iter().map(|e| e.0).collect();
    let pts = at(&t, "fallback", &times, &options);
    for (p, &(tt, s, f)) in pts.iter().zip(&expect) {
        assert!((p.success - s).abs() < 1e-15, "t={tt}: {p:?}");
        assert!((p.failure - f).abs() < 1e-15, "t={tt}: {p:?}");
    }
    // report uses the same means (eqs. 9.74-9.75 with t = 1/rate)
    let a = btrel::compile::analyze(
        &btrel::curve::deterministic_version(&t),
        &Default::default(),
    )
    .unwrap();
    assert!(
        (a.nodes[0].mtts.unwrap() - (0.3 * 2.0 + 0.42 * 6.0 + 0.14 * 13.5) / 0.86).abs() < 1e-12
    );
    assert!((a.nodes[0].mttf.unwrap() - 7.5).abs() < 1e-12);
}

#[test]
fn deterministic_parallel_by_hand() {
    // M = 1 of A (ps .5, ts 3, tf 1) and B (ps .8, ts 2, tf 4):
    // outcomes (A, B): SS .4 -> S at 2; SF .1 -> S at 3; FS .4 -> S at 2;
    // FF .1 -> F at 4 (the second failure)
    let t = tree(
        "tree: {parallel: {success_threshold: 1, children: [{action: {ps: 0.5, tau_s: 3, tau_f: 1}}, {action: {ps: 0.8, tau_s: 2, tau_f: 4}}]}}",
    );
    let pts = curve(&t, 0, &[1.0, 2.0, 3.0, 4.0], &exact()).unwrap();
    let expect = [(0.0, 0.0), (0.8, 0.0), (0.9, 0.0), (0.9, 0.1)];
    for (p, (s, f)) in pts.iter().zip(expect) {
        assert!(
            (p.success - s).abs() < 1e-15 && (p.failure - f).abs() < 1e-15,
            "{p:?}"
        );
    }
    let a = btrel::compile::analyze(&t, &Default::default()).unwrap();
    let f = a.nodes[0];
    assert!((f.ps - 0.9).abs() < 1e-15);
    assert!((f.mtts.unwrap() - (0.8 * 2.0 + 0.1 * 3.0) / 0.9).abs() < 1e-14);
    assert!((f.mttf.unwrap() - 4.0).abs() < 1e-14);
}

#[test]
fn mixed_timing_sequence_is_exact() {
    // Sequence(d: ps 0.5 at 3 s, else Failure at 1 s; s: ps 0.8, Exp(2) /
    // Exp(4)): S(t) = 0.4 (1 − e^{-2(t−3)}) and F(t) = 0.5 + 0.1 (1 −
    // e^{-4(t−3)}) for t ≥ 3; F = 0.5 on [1, 3).
    let t = tree(
        "tree: {sequence: {children: [{action: {ps: 0.5, tau_s: 3, tau_f: 1}}, {action: {ps: 0.8, mu: 2, nu: 4}}]}}",
    );
    let pts = curve(&t, 0, &[0.5, 1.0, 2.9, 3.0, 3.5, 10.0], &exact()).unwrap();
    for p in pts {
        let u = (p.t - 3.0).max(0.0);
        let s = if p.t >= 3.0 {
            0.4 * (1.0 - (-2.0 * u).exp())
        } else {
            0.0
        };
        let f = if p.t >= 1.0 { 0.5 } else { 0.0 }
            + if p.t >= 3.0 {
                0.1 * (1.0 - (-4.0 * u).exp())
            } else {
                0.0
            };
        assert!(
            (p.success - s).abs() < 1e-14 && (p.failure - f).abs() < 1e-14,
            "{p:?}"
        );
    }
}

/// A Parallel over a fixed-time and an exponential action inside a
/// Sequence (refused before the composed laws held atoms after 0): its
/// curve against 400,000 simulated runs, |z| < 5, with the book's
/// thresholds (counted) and with M = F = 1 (a race).
#[test]
fn mixed_parallel_inside_a_sequence_matches_simulation() {
    for parallel in [
        "parallel: {",
        "parallel: {success_threshold: 1, failure_threshold: 1, ",
    ] {
        let t = tree(&format!(
            "tree: {{sequence: {{children: [{{action: {{ps: 0.9, mu: 1, nu: 1}}}}, {{{parallel}children: [\
             {{action: {{ps: 0.5, tau_s: 3, tau_f: 1}}}}, {{action: {{ps: 0.8, mu: 2, nu: 4}}}}]}}}}]}}}}"
        ));
        let times = [0.5, 1.0, 2.0, 3.5, 5.0];
        let exact = curve(&t, 0, &times, &exact()).expect("curve");
        let sim = common::simulate_root(&t, 400_000, &times);
        for (p, s) in exact.iter().zip(&sim.curve) {
            let at = |what: &str| format!("{parallel} t = {}: {what}", p.t);
            common::assert_within_z(&at("success"), &s.success, p.success);
            common::assert_within_z(&at("failure"), &s.failure, p.failure);
        }
    }
}

#[test]
fn outputs_sum_to_one_and_are_monotone() {
    let t = file("trees/two-arm-parallel.yaml");
    let times: Vec<f64> = (0..=100).map(|k| 0.1 * k as f64).collect();
    for node in ["lift tray", "localise", "both arms"] {
        let pts = at(&t, node, &times, &exact());
        for w in pts.windows(2) {
            assert!(w[1].success >= w[0].success - 1e-13);
            assert!(w[1].failure >= w[0].failure - 1e-13);
        }
        for p in &pts {
            assert!((p.success + p.failure + p.running - 1.0).abs() <= 1e-12);
        }
    }
}

/// A lone action in closed form whatever its timing: hybrid with a fixed
/// success time (Success w.p. ps at tau_s; Failure w.p. pf at min(X, tau_s),
/// X ~ Exp(nu)), and hybrid with a fixed failure time, by hand.
#[test]
fn hybrid_actions_in_closed_form() {
    let t = tree("tree: {action: {ps: 0.3, tau_s: 2, nu: 0.5}}");
    let pts = curve(&t, 0, &[0.0, 1.0, 1.999, 2.0, 5.0], &exact()).unwrap();
    let expected = [
        (0.0, 0.0),
        (0.0, 0.7 * (1.0 - (-0.5f64).exp())),
        (0.0, 0.7 * (1.0 - (-0.5f64 * 1.999).exp())),
        (0.3, 0.7),
        (0.3, 0.7),
    ];
    for (p, (s, f)) in pts.iter().zip(expected) {
        assert!(
            (p.success - s).abs() < 1e-15 && (p.failure - f).abs() < 1e-15,
            "{p:?}"
        );
    }
    let t = tree("tree: {action: {ps: 0.6, mu: 2, tau_f: 1}}");
    let pts = curve(&t, 0, &[0.5, 1.0], &exact()).unwrap();
    assert!((pts[0].success - 0.6 * (1.0 - (-1.0f64).exp())).abs() < 1e-15);
    assert_eq!(pts[0].failure, 0.0);
    assert!((pts[1].success - 0.6).abs() < 1e-15 && (pts[1].failure - 0.4).abs() < 1e-15);
}
