//! Decorators and independent Parallel failure thresholds, against
//! hand-derived closed forms, exact atoms, and the simulator.

mod common;

use common::{root_figures, tree};

use btrel::compile::{analyze, Method, Options};
use btrel::curve::{curve, CurveOptions};
use btrel::sim::{simulate, SimOptions};
use btrel::tree::parse_str;

fn close(a: f64, b: f64, tol: f64) -> bool {
    (a - b).abs() <= tol * b.abs().max(1.0)
}

const ACTION: &str = "{action: {ps: 0.3, mu: 1.0, nu: 2.0}}";

#[test]
fn inverter_swaps_outcomes_and_curves() {
    let t = tree(&format!("tree: {{inverter: {{child: {ACTION}}}}}"));
    let f = root_figures(&t);
    assert!(close(f.ps, 0.7, 1e-15) && close(f.mtts.unwrap(), 0.5, 1e-15));
    assert!(close(f.mttf.unwrap(), 1.0, 1e-15));
    for p in curve(&t, 0, &[0.5, 2.0], &CurveOptions::default()).unwrap() {
        assert!(close(p.success, 0.7 * (1.0 - (-2.0 * p.t).exp()), 1e-13));
        assert!(close(p.failure, 0.3 * (1.0 - (-p.t).exp()), 1e-13));
    }
}

#[test]
fn force_success_keeps_the_time() {
    let t = tree(&format!("tree: {{force_success: {{child: {ACTION}}}}}"));
    let f = root_figures(&t);
    assert_eq!((f.ps, f.pf), (1.0, 0.0));
    assert!(close(f.mtts.unwrap(), 0.3 / 1.0 + 0.7 / 2.0, 1e-15));
    assert_eq!(f.mttf, None);
    for p in curve(&t, 0, &[0.5, 2.0], &CurveOptions::default()).unwrap() {
        let s = 0.3 * (1.0 - (-p.t).exp()) + 0.7 * (1.0 - (-2.0 * p.t).exp());
        assert!(close(p.success, s, 1e-13) && p.failure == 0.0);
    }
    let t = tree(&format!("tree: {{force_failure: {{child: {ACTION}}}}}"));
    let f = root_figures(&t);
    assert_eq!((f.ps, f.pf), (0.0, 1.0));
    assert!(close(f.mttf.unwrap(), 0.65, 1e-15));
}

#[test]
fn retry_is_a_fallback_of_fresh_copies() {
    // ps .4, mean success time 1, failure 0.5; 3 attempts
    let t = tree("tree: {retry: {attempts: 3, child: {action: {ps: 0.4, mu: 1.0, nu: 2.0}}}}");
    let f = root_figures(&t);
    assert!(close(f.ps, 1.0 - 0.6f64.powi(3), 1e-14));
    // success on attempt k after k-1 failures: (k-1)·0.5 + 1
    let ets: f64 = (1..=3)
        .map(|k| 0.6f64.powi(k - 1) * 0.4 * ((k - 1) as f64 * 0.5 + 1.0))
        .sum();
    assert!(close(f.mtts.unwrap(), ets / f.ps, 1e-13));
    assert!(close(f.mttf.unwrap(), 1.5, 1e-13));
    // failure by t: all three attempts fail: 0.6^3 · Erlang(3, 2) CDF
    for p in curve(&t, 0, &[0.3, 1.0, 4.0], &CurveOptions::default()).unwrap() {
        let x = 2.0 * p.t;
        let erlang = 1.0 - (-x).exp() * (1.0 + x + x * x / 2.0);
        assert!(close(p.failure, 0.216 * erlang, 1e-12), "{p:?}");
    }
}

#[test]
fn repeat_is_a_sequence_of_fresh_copies() {
    let t = tree("tree: {repeat: {times: 2, child: {action: {ps: 0.7, mu: 1.0, nu: 3.0}}}}");
    let f = root_figures(&t);
    assert!(close(f.ps, 0.49, 1e-14));
    assert!(close(f.mtts.unwrap(), 2.0, 1e-14));
    let etf = 0.3 * (1.0 / 3.0) + 0.7 * 0.3 * (1.0 + 1.0 / 3.0);
    assert!(close(f.mttf.unwrap(), etf / 0.51, 1e-13));
    // success by t: two Exp(1) phases, probability 0.49
    for p in curve(&t, 0, &[0.5, 2.0], &CurveOptions::default()).unwrap() {
        let erlang2 = 1.0 - (-p.t).exp() * (1.0 + p.t);
        assert!(close(p.success, 0.49 * erlang2, 1e-12), "{p:?}");
    }
}

#[test]
fn deterministic_retry_atoms() {
    // retry 2 of (ps .5, tau_s 2, tau_f 1): S at 2 (.5), S at 1 + 2 = 3 (.25), F at 2 (.25)
    let t = tree("tree: {retry: {attempts: 2, child: {action: {ps: 0.5, tau_s: 2, tau_f: 1}}}}");
    let pts = curve(&t, 0, &[1.9, 2.0, 2.9, 3.0], &CurveOptions::default()).unwrap();
    let expect = [(0.0, 0.0), (0.5, 0.25), (0.5, 0.25), (0.75, 0.25)];
    for (p, (s, f)) in pts.iter().zip(expect) {
        assert!(
            close(p.success, s, 1e-15) && close(p.failure, f, 1e-15),
            "{p:?}"
        );
    }
    let f = root_figures(&t);
    assert!(close(
        f.mtts.unwrap(),
        (0.5 * 2.0 + 0.25 * 3.0) / 0.75,
        1e-14
    ));
}

#[test]
fn independent_failure_threshold_by_hand() {
    // M = 2, F = 1 over A (ps .5, ts 1, tf 2), B (ps .5, ts 3, tf .5), C (ps 1, ts 2.5):
    // SS: successes at 1 and 2.5 -> S at 2.5 (.25); A S, B F at .5 -> F at .5 (.25)
    // A F at 2, B S -> F at 2 (.25); A F, B F at .5 -> F at .5 (.25)
    let t = tree(
        "tree: {parallel: {success_threshold: 2, failure_threshold: 1, children: [\
         {action: {ps: 0.5, tau_s: 1, tau_f: 2}}, {action: {ps: 0.5, tau_s: 3, tau_f: 0.5}}, \
         {action: {ps: 1, tau_s: 2.5}}]}}",
    );
    let f = root_figures(&t);
    assert!(close(f.ps, 0.25, 1e-15));
    assert!(close(f.mtts.unwrap(), 2.5, 1e-15));
    assert!(close(
        f.mttf.unwrap(),
        (0.5 * 0.5 + 0.25 * 2.0) / 0.75,
        1e-14
    ));
    // the simulator agrees (deterministic times: exact up to sampling of outcomes)
    let r = simulate(
        &t,
        &SimOptions {
            runs: 200_000,
            ..Default::default()
        },
        None,
    )
    .unwrap();
    let ps = r.nodes[0].ps;
    assert!((ps.mean - 0.25).abs() < 5.0 * ps.se);
    assert!((r.nodes[0].mtts.unwrap().mean - 2.5).abs() < 1e-12);
}

#[test]
fn decorated_stochastic_trees_agree_with_simulation() {
    let yaml = "tree:\n  sequence:\n    children:\n      - retry:\n          attempts: 3\n          child:\n            parallel:\n              success_threshold: 1\n              failure_threshold: 1\n              children:\n                - action: {ps: 0.6, mu: 1, nu: 2}\n                - action: {ps: 0.3, mu: 0.5, nu: 0.25}\n      - inverter:\n          child: {repeat: {times: 2, child: {action: {ps: 0.8, mu: 2, nu: 1}}}}\n      - force_success:\n          child: {action: {ps: 0.5, mu: 3, nu: 1}}\n";
    let t = tree(yaml);
    let exact = analyze(&t, &Options::default()).unwrap();
    let r = simulate(
        &t,
        &SimOptions {
            runs: 400_000,
            times: vec![1.0, 4.0],
            ..Default::default()
        },
        None,
    )
    .unwrap();
    for (n, mc) in exact.nodes.iter().zip(&r.nodes) {
        assert!(
            (mc.ps.mean - n.ps).abs() <= 5.0 * mc.ps.se + 1e-12,
            "{n:?} vs {mc:?}"
        );
        if let (Some(a), Some(e)) = (n.mtts, mc.mtts) {
            assert!(
                (e.mean - a).abs() <= 5.0 * e.se + 1e-12,
                "MTTS {a} vs {e:?}"
            );
        }
        if let (Some(a), Some(e)) = (n.mttf, mc.mttf) {
            assert!(
                (e.mean - a).abs() <= 5.0 * e.se + 1e-12,
                "MTTF {a} vs {e:?}"
            );
        }
    }
    let pts = curve(&t, 0, &[1.0, 4.0], &CurveOptions::default()).unwrap();
    for (p, m) in pts.iter().zip(&r.curve) {
        assert!((p.success - m.success.mean).abs() <= 5.0 * m.success.se + 1e-12);
        assert!((p.failure - m.failure.mean).abs() <= 5.0 * m.failure.se + 1e-12);
    }
    // the book method runs on decorators too; its ps differs here only
    // because the Parallel's thresholds can both be met (then who comes
    // first depends on the time distributions, which the book approximates)
    let book = analyze(
        &t,
        &Options {
            method: Method::Book,
            ..Options::default()
        },
    )
    .unwrap();
    let inv = t.find("inverter@0.1").unwrap();
    assert!(close(book.nodes[inv].ps, exact.nodes[inv].ps, 1e-12));
    assert!(close(
        book.nodes[inv].mttf.unwrap(),
        exact.nodes[inv].mttf.unwrap(),
        1e-12
    ));
    curve(
        &t,
        0,
        &[1.0],
        &CurveOptions {
            method: Method::Book,
            ..CurveOptions::default()
        },
    )
    .unwrap();
}

#[test]
fn invalid_decorators_are_located_errors() {
    for (yaml, phrase) in [
        ("tree: {retry: {attempts: 0, child: {condition: {ps: 1}}}}", "attempts = 0"),
        ("tree: {repeat: {times: 1.5, child: {condition: {ps: 1}}}}", "times = 1.5"),
        ("tree: {inverter: {name: x}}", "missing key `child`"),
        ("tree: {invertr: {child: {condition: {ps: 1}}}}", "did you mean `inverter`"),
        (
            "tree: {parallel: {failure_threshold: 3, children: [{condition: {ps: 1}}, {condition: {ps: 1}}]}}",
            "failure_threshold = 3",
        ),
    ] {
        let e = parse_str(yaml, "d.yaml").unwrap_err().to_string();
        assert!(e.contains(phrase), "{yaml}: {e}");
        assert!(e.starts_with("d.yaml:1:"), "{e}");
    }
}
