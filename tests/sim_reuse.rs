//! `simulate` with every node (`per_node`) takes each node's runs from the
//! root's episodes (its first run in each episode, topped up with runs of
//! its own; `btrel::sim` module docs, "One episode for all nodes"), and the
//! root's episodes run as a flattened chain or as recording nested ops:
//!
//! * every node's ps, pf, MTTS and MTTF agree with the **exact** per-node
//!   figures of the analytic engine (|z| < 5), for search-and-grasp and
//!   random trees with Parallels, decorators and deterministic times, and
//!   every node has exactly `runs` runs;
//! * the root's figures and curve are bit-identical with and without
//!   `per_node` (the recording program draws the same numbers and adds the
//!   same times in the same order as the flattened one), also on trees
//!   whose rewrites drop conditions and empty Sequences;
//! * a tree whose RoundRobin index carries over a RecoveryNode's retries
//!   (state across runs: its nodes are run on their own) still agrees.

mod common;

use btrel::sim::{simulate, SimOptions};
use btrel::sim::{simulate_node, Estimate};
use btrel::{analyze, Options};
use common::{random_mixed_tree, tree, Z};

/// `est` within [`Z`] standard errors of `exact`, or equal to it up to
/// rounding (a node's durations are differences of episode times: constant
/// ones may differ in the last bits, with a standard error near 0).
fn assert_within_z(what: &str, est: &Estimate, exact: f64) {
    if (est.mean - exact).abs() <= 1e-9 * exact.abs().max(1.0) {
        return;
    }
    common::assert_within_z(what, est, exact);
}

/// Two estimates within [`Z`] standard errors of their difference.
fn agree(what: &str, a: &Estimate, b: &Estimate) {
    let se = (a.se * a.se + b.se * b.se).sqrt();
    let d = a.mean - b.mean;
    assert!(
        d.abs() <= 1e-9 * a.mean.abs().max(1.0) || d.abs() < Z * se,
        "{what}: {} ± {} vs {} ± {}",
        a.mean,
        a.se,
        b.mean,
        b.se
    );
}

/// Every node of `t` simulated with `per_node` against its exact figures.
fn every_node_agrees(label: &str, t: &btrel::tree::Tree, runs: u64) {
    let exact = analyze(t, &Options::default()).expect("analysed");
    let opts = SimOptions {
        runs,
        seed: 11,
        ..Default::default()
    };
    let sim = simulate(t, &opts, None).expect("simulates");
    assert_eq!(sim.nodes.len(), t.nodes().len());
    for est in &sim.nodes {
        let f = exact.nodes[est.node];
        let what = format!("{label} node {} '{}'", est.node, t.node(est.node).name);
        assert_eq!(est.ps.count, runs, "{what}: runs");
        assert_within_z(&format!("{what} ps"), &est.ps, f.ps);
        assert_within_z(&format!("{what} pf"), &est.pf, f.pf);
        if let (Some(e), Some(m)) = (&est.mtts, f.mtts) {
            assert_within_z(&format!("{what} MTTS"), e, m);
        }
        if let (Some(e), Some(m)) = (&est.mttf, f.mttf) {
            assert_within_z(&format!("{what} MTTF"), e, m);
        }
    }
}

#[test]
fn search_and_grasp_every_node_from_the_root_episodes() {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/trees/search-and-grasp.yaml");
    let t = btrel::tree::parse_file(std::path::Path::new(path)).expect("parses");
    every_node_agrees("search-and-grasp", &t, 200_000);
}

#[test]
fn random_trees_every_node_agrees_with_exact_figures() {
    let mut checked = 0;
    for seed in 0..30 {
        let t = tree(&random_mixed_tree(seed, 3));
        // a tree the analytic engine refuses is tested elsewhere
        if analyze(&t, &Options::default()).is_err() {
            continue;
        }
        every_node_agrees(&format!("seed {seed}"), &t, 40_000);
        checked += 1;
    }
    assert!(checked >= 20, "only {checked} trees analysed");
}

/// The root's figures and curve with and without `per_node`.
fn root_same_with_and_without_per_node(yaml: &str) {
    let t = tree(yaml);
    let base = SimOptions {
        runs: 150_000,
        seed: 5,
        times: vec![0.1, 0.3, 0.6, 1.0, 2.5],
        ..Default::default()
    };
    let all = simulate(&t, &base, None).expect("simulates");
    let root = simulate(
        &t,
        &SimOptions {
            per_node: false,
            ..base.clone()
        },
        None,
    )
    .expect("simulates");
    assert_eq!(root.nodes[..], all.nodes[..1], "{yaml}");
    assert_eq!(root.curve, all.curve, "{yaml}");
}

#[test]
fn root_is_bit_identical_with_and_without_per_node() {
    let cases = [
        // decimal times whose sums tie with the time points: the order in
        // which times are added must be the same
        "tree: {sequence: {children: [{action: {ps: .9, tau_s: 0.1, tau_f: 0.2}}, \
         {fallback: {children: [{action: {ps: .5, tau_s: 0.2, tau_f: 0.1}}, \
         {action: {ps: .5, tau_s: 0.3, tau_f: 0.4}}]}}, {action: {ps: .8, tau_s: 0.3, tau_f: 0.1}}]}}",
        // neutral conditions and Sequences left empty, spliced or not
        "tree: {fallback: {children: [{sequence: {children: [{sequence: {children: \
         [{condition: {ps: 1}}]}}]}}, {action: {ps: .5, mu: 1, nu: 2}}]}}",
        "tree: {sequence: {children: [{action: {ps: .7, mu: 1, nu: 2}}, {sequence: {children: \
         [{condition: {ps: 1}}]}}, {fallback: {children: [{condition: {ps: 0}}, \
         {inverter: {child: {action: {ps: .4, tau_s: 0.3, nu: 3}}}}]}}]}}",
        // chains under a Parallel and a retry
        "tree: {parallel: {success_threshold: 1, children: [{sequence: {children: \
         [{action: {ps: .6, tau_s: 0.2, tau_f: 0.1}}, {force_success: {child: {action: \
         {ps: .3, tau_s: 0.1, tau_f: 0.2}}}}]}}, {retry: {attempts: 3, child: {fallback: \
         {children: [{condition: {ps: .2}}, {action: {ps: .5, mu: 2, tau_f: 0.3}}]}}}}]}}",
    ];
    for c in cases {
        root_same_with_and_without_per_node(c);
    }
    for seed in 0..20 {
        root_same_with_and_without_per_node(&random_mixed_tree(100 + seed, 3));
    }
}

#[test]
fn state_across_runs_is_run_on_its_own() {
    // A RecoveryNode whose main branch holds a RoundRobin (the copies made
    // for the retries share its index). The exact report gives a flow's
    // figures for the nodes inside it, so each node is compared with a
    // simulation of that node alone (its own runs, another seed); the root
    // with its exact figures.
    let xml = r#"<root BTCPP_format="4"><BehaviorTree ID="T">
      <RecoveryNode number_of_retries="2" name="R">
        <Sequence name="main">
          <RoundRobin name="RR"><A1/><A2/><A3/></RoundRobin>
          <B/>
        </Sequence>
        <C/>
      </RecoveryNode></BehaviorTree></root>"#;
    let params = "A1: {ps: 0.3, mu: 1, nu: 2}\nA2: {ps: 0.5, mu: 2, nu: 1}\n\
                  A3: {ps: 0.6, mu: 1, nu: 1}\nB: {ps: 0.7, mu: 3, nu: 2}\n\
                  C: {ps: 0.9, mu: 4, nu: 4}\n";
    let t = btrel::tree::xml::parse_xml_str(xml, "t.xml", params, "t.params.yaml")
        .expect("the tree parses");
    let runs = 100_000;
    let opts = SimOptions {
        runs,
        seed: 3,
        ..Default::default()
    };
    let all = simulate(&t, &opts, None).expect("simulates");
    let exact = analyze(&t, &Options::default()).expect("analysed").nodes[0];
    assert_within_z("root ps", &all.nodes[0].ps, exact.ps);
    assert_within_z(
        "root MTTS",
        all.nodes[0].mtts.as_ref().unwrap(),
        exact.mtts.unwrap(),
    );
    for est in &all.nodes {
        let alone = simulate_node(
            &t,
            est.node,
            &SimOptions {
                per_node: false,
                seed: 99,
                ..opts.clone()
            },
            None,
        )
        .expect("simulates");
        let a = &alone.nodes[0];
        let what = format!("node '{}'", t.node(est.node).name);
        assert_eq!(est.ps.count, runs, "{what}");
        agree(&format!("{what} ps"), &est.ps, &a.ps);
        agree(&format!("{what} pf"), &est.pf, &a.pf);
        if let (Some(x), Some(y)) = (&est.mtts, &a.mtts) {
            agree(&format!("{what} MTTS"), x, y);
        }
        if let (Some(x), Some(y)) = (&est.mttf, &a.mttf) {
            agree(&format!("{what} MTTF"), x, y);
        }
    }
}
