//! Statistical tests of the Monte Carlo engine against independently derived
//! numbers: `reference/refs.json` (computed offline by `reference/refs.py`,
//! see `reference/README.md`) and closed forms worked out by hand below.
//!
//! Every random figure must lie within 5 standard errors of its exact value
//! (|z| < 5). Probabilities use the exact binomial error `√(p(1−p)/N)`,
//! mean durations the sample error. Seeds are fixed, so the tests are
//! deterministic.

mod common;

use common::tree;

use std::sync::{Mutex, OnceLock};

use btrel::sim::{
    simulate, simulate_node, Estimate, SimError, SimOptions, SimResult, DEFAULT_SEED, MAX_RUNS,
};
use btrel::tree::Tree;
use serde_json::Value;

const Z: f64 = 5.0;
const RUNS: u64 = 1_000_000;

fn sim(tree: &Tree, runs: u64, times: &[f64]) -> SimResult {
    let opts = SimOptions {
        runs,
        times: times.to_vec(),
        ..Default::default()
    };
    simulate(tree, &opts, None).expect("simulates")
}

fn refs() -> &'static Value {
    static REFS: OnceLock<Value> = OnceLock::new();
    REFS.get_or_init(|| {
        serde_json::from_str(include_str!("../reference/refs.json")).expect("refs.json parses")
    })
}

fn num(v: &Value) -> f64 {
    v.as_f64().unwrap_or_else(|| panic!("not a number: {v}"))
}

fn nums(v: &Value) -> Vec<f64> {
    v.as_array().expect("array").iter().map(num).collect()
}

/// A simulated proportion within Z binomial standard errors of `p`; exact
/// when `p` is 0 or 1.
#[track_caller]
fn check_p(what: &str, e: &Estimate, p: f64) {
    let se = (p * (1.0 - p) / e.count as f64).sqrt();
    let diff = (e.mean - p).abs();
    if se == 0.0 {
        assert_eq!(e.mean, p, "{what}: {} but exactly {p}", e.mean);
    } else {
        assert!(
            diff < Z * se,
            "{what}: simulated {} vs exact {p}: z = {:.2}",
            e.mean,
            diff / se
        );
    }
}

/// A simulated mean duration within Z of its standard errors of `m`; exact
/// (to rounding) when every run had the same duration.
#[track_caller]
fn check_mean(what: &str, e: Option<&Estimate>, m: f64) {
    let e = e.unwrap_or_else(|| panic!("{what}: no run contributed"));
    let diff = (e.mean - m).abs();
    if e.se == 0.0 {
        assert!(
            diff <= 1e-12 * m.abs().max(1.0),
            "{what}: {} but exactly {m}",
            e.mean
        );
    } else {
        assert!(
            diff < Z * e.se,
            "{what}: simulated {} ± {} vs exact {m}: z = {:.2}",
            e.mean,
            e.se,
            diff / e.se
        );
    }
}

/// Checks a node's four figures.
#[track_caller]
fn check_node(what: &str, r: &SimResult, i: usize, ps: f64, mtts: Option<f64>, mttf: Option<f64>) {
    let n = &r.nodes[i];
    check_p(&format!("{what} ps"), &n.ps, ps);
    check_p(&format!("{what} pf"), &n.pf, 1.0 - ps);
    match mtts {
        Some(m) => check_mean(&format!("{what} MTTS"), n.mtts.as_ref(), m),
        None => assert!(
            n.mtts.is_none(),
            "{what}: MTTS {:?} but never succeeds",
            n.mtts
        ),
    }
    match mttf {
        Some(m) => check_mean(&format!("{what} MTTF"), n.mttf.as_ref(), m),
        None => assert!(
            n.mttf.is_none(),
            "{what}: MTTF {:?} but never fails",
            n.mttf
        ),
    }
}

/// Checks the root curve against exact P(Success by t), P(Failure by t).
#[track_caller]
fn check_curve(what: &str, r: &SimResult, times: &[f64], ps: &[f64], pf: &[f64]) {
    assert_eq!(r.curve.len(), times.len());
    for (k, point) in r.curve.iter().enumerate() {
        assert_eq!(point.t, times[k]);
        let t = times[k];
        check_p(&format!("{what} p_s({t})"), &point.success, ps[k]);
        check_p(&format!("{what} p_f({t})"), &point.failure, pf[k]);
        check_p(
            &format!("{what} p_r({t})"),
            &point.running,
            1.0 - ps[k] - pf[k],
        );
    }
}

// ---------------------------------------------------------------------------
// Search and grasp (book Example 9.9)

const SEARCH_AND_GRASP: &str = include_str!("../trees/search-and-grasp.yaml");
const SG_TIMES: [f64; 6] = [10.0, 50.0, 100.0, 200.0, 500.0, 1000.0];

/// Tree node names → names in refs.json.
const SG_NAMES: [(&str, &str); 12] = [
    ("search and grasp", "root"),
    ("find object", "find object"),
    ("object position retrieved", "object position retrieved"),
    ("search", "search"),
    ("search floor", "search on the floor"),
    ("search drawer", "search in the drawer"),
    ("search closet", "search in the closet"),
    ("grasp object", "grasp object"),
    ("object grasped", "object grasped"),
    ("grasp", "grasp"),
    ("one hand grasp", "one hand grasp"),
    ("two hands grasp", "two hands grasp"),
];

fn search_and_grasp() -> &'static (Tree, SimResult) {
    static SG: OnceLock<(Tree, SimResult)> = OnceLock::new();
    SG.get_or_init(|| {
        let t = tree(SEARCH_AND_GRASP);
        let r = sim(&t, RUNS, &SG_TIMES);
        (t, r)
    })
}

#[test]
fn search_and_grasp_every_node_matches_reference() {
    let (t, r) = search_and_grasp();
    let nodes = &refs()["search_and_grasp"]["nodes"];
    assert_eq!(r.nodes.len(), t.nodes().len());
    for (i, n) in r.nodes.iter().enumerate() {
        assert_eq!(n.node, i, "tree order");
        assert_eq!(n.ps.count, RUNS);
        let name = &t.nodes()[i].name;
        let (_, key) = SG_NAMES
            .iter()
            .find(|(a, _)| a == name)
            .expect("known node");
        let x = &nodes[key];
        check_node(
            name,
            r,
            i,
            num(&x["ps"]),
            x["MTTS"].as_f64(),
            x["MTTF"].as_f64(),
        );
    }
    // Spot-check the brief's numbers, so a wrong refs.json cannot go unnoticed.
    assert_eq!(num(&nodes["root"]["ps"]), 0.4884);
    assert!((num(&nodes["root"]["MTTS"]) - 169.37764).abs() < 1e-5);
    assert!((num(&nodes["root"]["MTTF"]) - 223.05636).abs() < 1e-5);
}

/// Book Table 9.1: mu = 1/MTTS and nu = 1/MTTF of nodes 0 (root), 3
/// (search) and 5 (grasp), with standard errors by the delta method
/// (se(1/X) = se(X)/X²). The exact values are the book's to its printed
/// digits (but for its mu5 typo, see reference/README.md).
#[test]
fn search_and_grasp_table_9_1() {
    let (t, r) = search_and_grasp();
    let table = &refs()["search_and_grasp"]["book_table_9_1_check"];
    for (label, node) in [("0", "search and grasp"), ("3", "search"), ("5", "grasp")] {
        let n = &r.nodes[t.find(node).unwrap()];
        for (rate, time) in [("mu", n.mtts.unwrap()), ("nu", n.mttf.unwrap())] {
            let exact = num(&table[format!("{rate}{label}")]["exact"]);
            let sim = 1.0 / time.mean;
            let se = time.se / (time.mean * time.mean);
            assert!(
                (sim - exact).abs() < Z * se,
                "{rate}{label}: simulated {sim} ± {se} vs exact {exact}"
            );
        }
    }
}

#[test]
fn search_and_grasp_probabilities_over_time() {
    let (_, r) = search_and_grasp();
    let x = &refs()["search_and_grasp"]["probabilities_over_time"]["root"];
    assert_eq!(nums(&x["t"]), SG_TIMES);
    let (ps, pf) = (nums(&x["p_success"]), nums(&x["p_failure"]));
    assert!((ps[2] - 0.197740).abs() < 1e-6 && (pf[2] - 0.151618).abs() < 1e-6);
    check_curve("search and grasp", r, &SG_TIMES, &ps, &pf);
}

#[test]
fn simulate_node_runs_a_subtree_alone() {
    let t = tree(SEARCH_AND_GRASP);
    let opts = SimOptions {
        runs: 200_000,
        times: vec![10.0, 50.0],
        per_node: false,
        ..Default::default()
    };
    let grasp = t.find("grasp").unwrap();
    let r = simulate_node(&t, grasp, &opts, None).unwrap();
    assert_eq!(r.nodes.len(), 1);
    assert_eq!(r.nodes[0].node, grasp);
    // grasp = Fallback[one hand (.1, .1, 2), two hands (.5, .1, .05)]:
    // MTTS = (.1 · 10 + .9 · .5 · (1/2 + 10)) / .55, MTTF = 1/2 + 1/.05.
    check_node("grasp", &r, 0, 0.55, Some(5.725 / 0.55), Some(20.5));
    let x = &refs()["search_and_grasp"]["probabilities_over_time"]["grasp"];
    let (ts, ps, pf) = (nums(&x["t"]), nums(&x["p_success"]), nums(&x["p_failure"]));
    assert_eq!(&ts[..2], &[10.0, 50.0]);
    check_curve("grasp", &r, &ts[..2], &ps[..2], &pf[..2]);
}

// ---------------------------------------------------------------------------
// Example 9.7 and Parallel nodes

fn action(ps: f64, mu: f64, nu: f64) -> String {
    format!("{{action: {{ps: {ps}, mu: {mu}, nu: {nu}}}}}")
}

#[test]
fn example_9_7_fallback() {
    let t = tree(&format!(
        "tree: {{fallback: {{children: [{}, {}, {}]}}}}",
        action(0.3, 0.5, 1.0),
        action(0.6, 0.2, 0.4),
        action(0.5, 0.1, 0.25)
    ));
    let x = &refs()["example_9_7"];
    let times = nums(&x["t"]);
    let r = sim(&t, RUNS, &times);
    check_node("example 9.7", &r, 0, 0.86, Some(501.0 / 86.0), Some(7.5));
    check_curve(
        "example 9.7",
        &r,
        &times,
        &nums(&x["p_success"]),
        &nums(&x["p_failure"]),
    );
    check_node("A2", &r, 2, 0.6, Some(5.0), Some(2.5));
}

fn parallel_case(key: &str, m: usize, ps: f64, mtts: f64, mttf: f64) {
    let x = &refs()["parallel"][key];
    assert_eq!(x["M"].as_u64(), Some(m as u64));
    let children: Vec<String> = x["children"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| {
            let c = nums(c);
            action(c[0], c[1], c[2])
        })
        .collect();
    let t = tree(&format!(
        "tree: {{parallel: {{success_threshold: {m}, children: [{}]}}}}",
        children.join(", ")
    ));
    let times = nums(&x["t"]);
    let r = sim(&t, RUNS, &times);
    check_node(key, &r, 0, ps, Some(mtts), Some(mttf));
    check_curve(
        key,
        &r,
        &times,
        &nums(&x["p_success"]),
        &nums(&x["p_failure"]),
    );
}

#[test]
fn parallel_one_of_two() {
    parallel_case("a_M1_of_2", 1, 18.0 / 25.0, 13.0 / 12.0, 73.0 / 18.0);
}

#[test]
fn parallel_two_of_two() {
    parallel_case("b_M2_of_2", 2, 9.0 / 50.0, 7.0 / 3.0, 839.0 / 369.0);
}

#[test]
fn parallel_two_of_three() {
    parallel_case("c_M2_of_3", 2, 4.0 / 5.0, 3961.0 / 2400.0, 28.0 / 25.0);
}

/// Rates from 1e-4 to 1e5 in one tree (reference/README.md §6).
#[test]
fn stiff_tree() {
    let t = tree(&format!(
        "tree: {{sequence: {{children: [{}, {}, {{fallback: {{children: [{}, {}]}}}}]}}}}",
        action(0.9, 1e5, 1e4),
        action(0.99, 1e-4, 2e-4),
        action(0.5, 10.0, 1.0),
        action(0.5, 1e-3, 1e-2)
    ));
    let x = &refs()["stiff"];
    let times = nums(&x["t"]);
    let r = sim(&t, RUNS, &times);
    let node = &x["node"];
    check_node(
        "stiff",
        &r,
        0,
        0.66825,
        Some(num(&node["MTTS"])),
        Some(num(&node["MTTF"])),
    );
    check_curve(
        "stiff",
        &r,
        &times,
        &nums(&x["p_success"]),
        &nums(&x["p_failure"]),
    );
}

// ---------------------------------------------------------------------------
// Deterministic and hybrid timing (closed forms by hand)

/// Fallback[A1 (ps .4, τs 2, τf 1), A2 (ps .7, τs 3, τf .5)]: Success at 2
/// (p .4) or at 1 + 3 = 4 (p .6 · .7 = .42); Failure at 1 + .5 = 1.5
/// (p .6 · .3 = .18).
#[test]
fn deterministic_fallback() {
    let t = tree(
        "tree: {fallback: {children: [{action: {ps: 0.4, tau_s: 2, tau_f: 1}}, \
         {action: {ps: 0.7, tau_s: 3, tau_f: 0.5}}]}}",
    );
    let times = [0.0, 1.4999, 1.5, 1.9999, 2.0, 3.9999, 4.0, 100.0];
    let r = sim(&t, RUNS, &times);
    check_node(
        "fallback",
        &r,
        0,
        0.82,
        Some((0.4 * 2.0 + 0.42 * 4.0) / 0.82),
        Some(1.5),
    );
    assert_eq!(r.nodes[0].mttf.unwrap().se, 0.0, "every failure takes 1.5");
    let ps = [0.0, 0.0, 0.0, 0.0, 0.4, 0.4, 0.82, 0.82];
    let pf = [0.0, 0.0, 0.18, 0.18, 0.18, 0.18, 0.18, 0.18];
    check_curve("fallback", &r, &times, &ps, &pf);
    // The leaves, each on its own.
    check_node("A1", &r, 1, 0.4, Some(2.0), Some(1.0));
    check_node("A2", &r, 2, 0.7, Some(3.0), Some(0.5));
}

/// Hybrid actions (Def. 9.9): the random side is cut off at the fixed time of
/// the other, E[min(Exp(λ), τ)] = (1 − e^{−λτ})/λ.
#[test]
fn hybrid_actions() {
    // τs = 2, ν = .5: Success at exactly 2; Failure at min(Exp(.5), 2).
    let t = tree("tree: {action: {ps: 0.5, tau_s: 2, nu: 0.5}}");
    let times = [1.0, 1.999, 2.0, 5.0];
    let r = sim(&t, RUNS, &times);
    let mttf = (1.0 - (-0.5f64 * 2.0).exp()) / 0.5;
    check_node("tau_s + nu", &r, 0, 0.5, Some(2.0), Some(mttf));
    let pf_before = |t: f64| 0.5 * (1.0 - (-0.5 * t).exp());
    let ps = [0.0, 0.0, 0.5, 0.5];
    let pf = [pf_before(1.0), pf_before(1.999), 0.5, 0.5];
    check_curve("tau_s + nu", &r, &times, &ps, &pf);

    // μ = 1, τf = 3: Failure at exactly 3; Success at min(Exp(1), 3).
    let t = tree("tree: {action: {ps: 0.3, mu: 1, tau_f: 3}}");
    let r = sim(&t, RUNS, &[2.0, 3.0]);
    check_node(
        "mu + tau_f",
        &r,
        0,
        0.3,
        Some(1.0 - (-3.0f64).exp()),
        Some(3.0),
    );
    check_curve(
        "mu + tau_f",
        &r,
        &[2.0, 3.0],
        &[0.3 * (1.0 - (-2.0f64).exp()), 0.3],
        &[0.0, 0.7],
    );
}

/// Parallel M = 2 of [c1 (ps .5), A (ps .6, τs 2, τf 1), c2 (ps .7)].
/// Enumerating the 8 outcome vectors: Success at 0 when both conditions
/// succeed (p .35), at 2 when A and exactly one condition succeed
/// (.6 · .5 = .3); Failure at 0 when both conditions fail (.15), at 1 when A
/// and exactly one condition fail (.4 · .5 = .2).
#[test]
fn parallel_with_deterministic_child_and_conditions() {
    let t = tree(
        "tree: {parallel: {success_threshold: 2, children: [{condition: {ps: 0.5}}, \
         {action: {ps: 0.6, tau_s: 2, tau_f: 1}}, {condition: {ps: 0.7}}]}}",
    );
    let times = [0.0, 0.5, 1.0, 1.5, 2.0, 3.0];
    let r = sim(&t, RUNS, &times);
    check_node("parallel", &r, 0, 0.65, Some(0.6 / 0.65), Some(0.2 / 0.35));
    let ps = [0.35, 0.35, 0.35, 0.35, 0.65, 0.65];
    let pf = [0.15, 0.15, 0.35, 0.35, 0.35, 0.35];
    check_curve("parallel", &r, &times, &ps, &pf);
    // A condition on its own: zero duration.
    check_node("c1", &r, 1, 0.5, Some(0.0), Some(0.0));
}

/// Parallel M = 1 of a Sequence and a Fallback of conditions, nested in a
/// Sequence after a fixed-time action: exercises nested control nodes.
/// Seq[A (ps 1, τs 1), Par1[Seq[c .5, c .5], Fb[c .2, c .2]]]: the Parallel
/// succeeds iff either child does: 1 − .75 · .64 = .52, all at time 1.
#[test]
fn nested_zero_time_subtrees() {
    let t = tree(
        "tree: {sequence: {children: [{action: {ps: 1, tau_s: 1}}, \
         {parallel: {success_threshold: 1, children: [\
         {sequence: {children: [{condition: {ps: 0.5}}, {condition: {ps: 0.5}}]}}, \
         {fallback: {children: [{condition: {ps: 0.2}}, {condition: {ps: 0.2}}]}}]}}]}}",
    );
    let r = sim(&t, RUNS, &[0.5, 1.0]);
    check_node("root", &r, 0, 0.52, Some(1.0), Some(1.0));
    check_curve("root", &r, &[0.5, 1.0], &[0.0, 0.52], &[0.0, 0.48]);
}

// ---------------------------------------------------------------------------
// Reproducibility, options and errors

#[test]
fn same_seed_same_result_whatever_the_threads() {
    let t = tree(SEARCH_AND_GRASP);
    // 4 full chunks and a partial one.
    let base = SimOptions {
        runs: 4 * btrel::sim::CHUNK_RUNS + 12_345,
        times: vec![100.0, 10.0, 1000.0, 100.0],
        ..Default::default()
    };
    let with = |threads, seed| {
        simulate(
            &t,
            &SimOptions {
                threads,
                seed,
                ..base.clone()
            },
            None,
        )
        .unwrap()
    };
    let one = with(1, DEFAULT_SEED);
    assert_eq!(one, with(2, DEFAULT_SEED));
    assert_eq!(one, with(3, DEFAULT_SEED));
    assert_eq!(one, simulate(&t, &base, None).unwrap());
    assert_eq!(one.seed, DEFAULT_SEED);
    assert_eq!(one.runs, base.runs);

    let other = with(2, 42);
    assert_ne!(one.nodes[0].ps, other.nodes[0].ps);
    assert_ne!(one.nodes[0].mtts, other.nodes[0].mtts);

    // The root's runs come first in each chunk: same with or without per_node.
    let root_only = simulate(
        &t,
        &SimOptions {
            per_node: false,
            ..base.clone()
        },
        None,
    )
    .unwrap();
    assert_eq!(root_only.nodes, one.nodes[..1]);
    assert_eq!(root_only.curve, one.curve);

    // Curve in the order given, duplicates included.
    let ts: Vec<f64> = one.curve.iter().map(|p| p.t).collect();
    assert_eq!(ts, base.times);
    assert_eq!(one.curve[0], one.curve[3]);
    assert!(one.curve[1].success.mean <= one.curve[0].success.mean);
}

#[test]
fn estimates_are_consistent() {
    let (_, r) = search_and_grasp();
    let root = &r.nodes[0];
    assert_eq!(root.ps.count, RUNS);
    let (s, f) = (root.mtts.unwrap(), root.mttf.unwrap());
    assert_eq!(s.count + f.count, RUNS);
    assert_eq!(s.count as f64 / RUNS as f64, root.ps.mean);
    assert!((root.ps.mean + root.pf.mean - 1.0).abs() < 1e-15);
    assert!((root.ps.se - (root.ps.mean * root.pf.mean / RUNS as f64).sqrt()).abs() < 1e-15);
    assert_eq!(s.ci95, (s.mean - 1.96 * s.se, s.mean + 1.96 * s.se));
    for p in &r.curve {
        let total = p.success.mean + p.failure.mean + p.running.mean;
        assert!((total - 1.0).abs() < 1e-12);
    }
}

#[test]
fn progress_reports_runs_done() {
    let t = tree("tree: {action: {ps: 0.5, mu: 1, nu: 1}}");
    let calls = Mutex::new(Vec::new());
    let report = |n: u64| calls.lock().unwrap().push(n);
    let runs = 10 * btrel::sim::CHUNK_RUNS + 1;
    let opts = SimOptions {
        runs,
        threads: 2,
        ..Default::default()
    };
    simulate(&t, &opts, Some(&report)).unwrap();
    let calls = calls.into_inner().unwrap();
    assert!(!calls.is_empty() && calls.len() <= 11, "{calls:?}");
    assert!(calls.windows(2).all(|w| w[0] < w[1]), "{calls:?}");
    assert_eq!(*calls.last().unwrap(), runs);
}

#[test]
fn bad_options_are_rejected() {
    let t = tree("tree: {condition: {ps: 0.5}}");
    let err = |opts: SimOptions| simulate(&t, &opts, None).unwrap_err();
    let opts = |runs, times: Vec<f64>| SimOptions {
        runs,
        times,
        ..Default::default()
    };
    assert_eq!(err(opts(0, vec![])), SimError::ZeroRuns);
    assert_eq!(
        err(opts(MAX_RUNS + 1, vec![])),
        SimError::AbsurdRuns(MAX_RUNS + 1)
    );
    assert!(err(opts(u64::MAX, vec![])).to_string().contains("absurd"));
    for (bad, index) in [(-1.0, 1), (f64::NAN, 1), (f64::INFINITY, 1)] {
        match err(opts(10, vec![1.0, bad])) {
            SimError::BadTime { index: i, .. } => assert_eq!(i, index),
            e => panic!("{e}"),
        }
    }
    assert!(err(opts(10, vec![-2.0])).to_string().contains("-2"));
    let e = simulate_node(&t, 7, &opts(10, vec![]), None).unwrap_err();
    assert_eq!(e, SimError::NoSuchNode { node: 7, len: 1 });
    // Zero is a valid time; one run is enough.
    let r = simulate(&t, &opts(1, vec![0.0]), None).unwrap();
    assert_eq!(r.runs, 1);
}
