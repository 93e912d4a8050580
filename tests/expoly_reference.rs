//! btrel's exact figures and curves against an independent closed-form
//! reference: `reference/expoly.py` keeps every outcome law as atoms at
//! exact rational instants plus sums of `c·(t−τ)^k·e^{−λ(t−τ)}·H(t−τ)`
//! (exact rational k, λ, τ; coefficients at 60 digits), which are closed
//! under convolution, products of CDFs and integration — no phase chains,
//! uniformization, quadrature or interpolation, and the tie rule written out
//! as an enumeration of every child's state at each instant.
//!
//! Compared on every node of random trees of every timing of Def. 9.11
//! (stochastic, deterministic, both hybrids, conditions; decimal
//! deterministic times so that ties occur) under Sequence, Fallback,
//! Parallel (any M, the book's F or a smaller one), inverter, force and
//! Retry/Repeat, plus hand-picked tie cases: P(S), P(F) and π(t) within
//! 1e-9 absolute, MTTS and MTTF within 1e-9 relative, wherever btrel
//! answers (a refusal is counted, not failed: refusals are tested
//! elsewhere; a floor on the number of answered nodes keeps the test from
//! passing vacuously).
//!
//! The test needs a Python with mpmath (`BTREL_PYTHON`, else the venv
//! `target/pyvenv` the tests create: tests/common/python.rs); without one
//! it says SKIPPED and passes (fails with `BTREL_REQUIRE_PYTHON=1`).

mod common;

use btrel::tree::Tree;
use common::expoly::{expoly, to_json};
use common::python::python;
use common::{random_mixed_tree, tree};
use serde_json::Value;

/// Times at which π(t) is compared (decimal, read exactly by the reference).
const TIMES: [&str; 6] = ["0.05", "0.3", "0.75", "1.5", "2.95", "7"];

/// Hand-picked ties and mixed cases (the random trees add breadth).
const CASES: &[&str] = &[
    // 0.1 + 0.2 ties with 0.3: child order decides
    "tree: {parallel: {success_threshold: 1, failure_threshold: 1, children: [\
       {sequence: {children: [{action: {ps: 1, tau_s: 0.1}}, {action: {ps: 1, tau_s: 0.2}}]}}, \
       {action: {ps: 0, tau_f: 0.3}}]}}",
    "tree: {parallel: {success_threshold: 1, failure_threshold: 1, children: [\
       {action: {ps: 0, tau_f: 0.3}}, \
       {sequence: {children: [{action: {ps: 1, tau_s: 0.1}}, {action: {ps: 1, tau_s: 0.2}}]}}]}}",
    // conditions meeting both thresholds at once (the example)
    "tree: {parallel: {success_threshold: 1, failure_threshold: 1, children: [\
       {condition: {ps: 0.4}}, {condition: {ps: 1.0}}]}}",
    // the book's Example 9.2 shape: deterministic ∥ stochastic
    "tree: {parallel: {success_threshold: 2, children: [\
       {action: {ps: 0.9, tau_s: 1.5, tau_f: 0.5}}, {action: {ps: 0.7, mu: 1.3, nu: 0.8}}]}}",
    // a deadline racing a hybrid inside a Sequence (BT.CPP Timeout's shape)
    "tree: {sequence: {children: [{action: {ps: 0.8, mu: 2, nu: 1}}, \
       {parallel: {success_threshold: 1, failure_threshold: 1, children: [\
         {action: {ps: 0, tau_f: 1.2}}, {action: {ps: 0.6, tau_s: 0.9, nu: 1.7}}]}}]}}",
    // flows: IfThenElse over a mixed condition subtree, and a Retry of a
    // SequenceWithMemory (states (attempt, child)) with a hybrid and a Parallel
    "tree: {if_then_else: {children: [\
       {sequence: {children: [{condition: {ps: 0.7}}, {action: {ps: 0.6, mu: 1.1, tau_f: 0.5}}]}}, \
       {action: {ps: 0.8, tau_s: 0.3, nu: 2}}, \
       {parallel: {success_threshold: 1, children: [{action: {ps: 0.5, tau_s: 0.4, tau_f: 0.9}}, \
         {action: {ps: 0.4, mu: 2.2, nu: 0.7}}]}}]}}",
    "tree: {flow: {children: [{action: {ps: 0.5, tau_s: 1, nu: 1.3}}, \
       {parallel: {success_threshold: 2, children: [{action: {ps: 0.7, mu: 1.9, nu: 1.9}}, \
         {action: {ps: 0.9, tau_s: 0.6, tau_f: 1.1}}]}}], \
       states: [{run: 0, success: 1, failure: 2}, {run: 1, success: success, failure: 3}, \
         {run: 0, success: 3, failure: failure}, {run: 1, success: success, failure: failure}]}}",
    // equal rates (repeated poles) and Retry over a mixed Fallback
    "tree: {retry: {attempts: 3, child: {fallback: {children: [\
       {action: {ps: 0.3, mu: 1.5, nu: 1.5}}, {action: {ps: 0.5, mu: 1.5, tau_f: 0.4}}]}}}}",
    // Erlang, hypoexponential and shifted times (`success_time` /
    // `failure_time`): in a Sequence, a Fallback, a Markovian Parallel
    // (phase product), a race of a shifted exponential against an
    // exponential, and a Retry
    "tree: {sequence: {children: [\
       {action: {ps: 0.8, success_time: {erlang: {k: 3, rate: 2}}, nu: 1}}, \
       {action: {ps: 0.7, success_time: {hypoexponential: [1, 3]}, \
         failure_time: {shift: 0.4, rate: 2}}}]}}",
    "tree: {fallback: {children: [\
       {action: {ps: 0.5, success_time: {shift: 0.2, erlang: {k: 2, rate: 5}}, \
         failure_time: {fixed: 0.3}}}, \
       {action: {ps: 0.9, mu: 2, failure_time: {hypoexponential: [2, 2, 0.5]}}}]}}",
    "tree: {parallel: {success_threshold: 2, children: [\
       {action: {ps: 0.9, success_time: {erlang: {k: 2, rate: 3}}, failure_time: {rate: 1}}}, \
       {action: {ps: 0.6, mu: 1.2, failure_time: {erlang: {k: 3, rate: 4}}}}]}}",
    "tree: {parallel: {success_threshold: 1, failure_threshold: 1, children: [\
       {action: {ps: 1, success_time: {shift: 0.5, rate: 2}}}, {action: {ps: 0, nu: 1.5}}]}}",
    "tree: {parallel: {success_threshold: 1, children: [\
       {action: {ps: 0.7, success_time: {shift: 0.25, erlang: {k: 2, rate: 4}}, \
         failure_time: {fixed: 0.6}}}, \
       {action: {ps: 0.5, success_time: {erlang: {k: 2, rate: 2}}, nu: 3}}]}}",
    "tree: {retry: {attempts: 2, child: {action: {ps: 0.6, \
       success_time: {shift: 0.1, hypoexponential: [4, 1.5]}, failure_time: {erlang: {k: 2, rate: 6}}}}}}",
];

#[test]
fn exact_figures_and_curves_match_the_closed_form_reference() {
    let Some(py) = python("the mpmath expoly reference") else {
        return;
    };
    let mut trees: Vec<(String, Tree)> = CASES.iter().map(|y| (y.to_string(), tree(y))).collect();
    for seed in 0..60 {
        let yaml = random_mixed_tree(seed, 3);
        let t = tree(&yaml);
        trees.push((yaml, t));
    }
    let jobs: Vec<Value> = trees
        .iter()
        .map(|(_, t)| to_json(t, 0).expect("no loops in these trees"))
        .collect();
    let reference = expoly(&py, &TIMES, &jobs);
    let times: Vec<f64> = TIMES.iter().map(|t| t.parse().expect("time")).collect();
    let num = |v: &Value| -> Option<f64> { v.as_str().map(|s| s.parse().expect("a number")) };

    let (mut nodes, mut figures, mut curves, mut worst_p, mut worst_m) = (0, 0, 0, 0.0f64, 0.0f64);
    for ((yaml, t), want) in trees.iter().zip(&reference) {
        assert_eq!(want.len(), t.nodes().len(), "node count of {yaml}");
        let report = btrel::analyze(t, &Default::default());
        for (id, w) in want.iter().enumerate() {
            nodes += 1;
            let at = || format!("node {} ({}) of {yaml}", t.node(id).path, t.node(id).name);
            if let Ok(a) = &report {
                figures += 1;
                let f = a.nodes[id];
                for (what, got, exact) in [("ps", f.ps, &w["ps"]), ("pf", f.pf, &w["pf"])] {
                    let e = num(exact).expect("probabilities are defined");
                    worst_p = worst_p.max((got - e).abs());
                    assert!((got - e).abs() < 1e-9, "{what} {got} vs {e}: {}", at());
                }
                for (what, got, exact) in
                    [("MTTS", f.mtts, &w["mtts"]), ("MTTF", f.mttf, &w["mttf"])]
                {
                    match (got, num(exact)) {
                        (Some(g), Some(e)) => {
                            let rel = (g - e).abs() / e.abs().max(1e-300);
                            worst_m = worst_m.max(if e == 0.0 { g.abs() } else { rel });
                            assert!(
                                (g - e).abs() <= 1e-9 * e.abs().max(1e-12),
                                "{what} {g} vs {e}: {}",
                                at()
                            );
                        }
                        // an outcome of probability below 1e-40 has no mean in the reference
                        (g, e) => assert!(
                            g.is_none() == e.is_none() || (f.ps.min(f.pf) < 1e-12),
                            "{what} {g:?} vs {e:?}: {}",
                            at()
                        ),
                    }
                }
            }
            if let Ok(pts) = btrel::curve::curve(t, id, &times, &Default::default()) {
                curves += 1;
                for (k, p) in pts.iter().enumerate() {
                    let (s, f) = (
                        num(&w["success"][k]).expect("S(t)"),
                        num(&w["failure"][k]).expect("F(t)"),
                    );
                    worst_p = worst_p
                        .max((p.success - s).abs())
                        .max((p.failure - f).abs());
                    assert!(
                        (p.success - s).abs() < 1e-9 && (p.failure - f).abs() < 1e-9,
                        "π({}) = ({}, {}) vs ({s}, {f}): {}",
                        p.t,
                        p.success,
                        p.failure,
                        at()
                    );
                }
            }
        }
    }
    println!(
        "{figures} of {nodes} nodes' figures and {curves} curves compared; largest difference \
         {worst_p:.1e} in probability, {worst_m:.1e} relative in mean time"
    );
    // floors: what btrel answers today (refusals are the engine's open cases)
    assert!(
        figures * 10 >= nodes * 8,
        "only {figures} of {nodes} figures answered"
    );
    assert!(
        curves * 10 >= nodes * 8,
        "only {curves} of {nodes} curves answered"
    );
}
