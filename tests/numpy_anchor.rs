//! The numpy Monte Carlo of `scripts/numpy_mc.py` — the anchor docs/BENCHMARKS.md's
//! *Performance* table times btrel's simulator against — simulates the same
//! trees: its estimates agree with btrel's **exact** figures (the analytic
//! engine, not the simulator) within their standard errors, for
//! search-and-grasp (P(S), P(F), MTTS, MTTF and the curve at 10, 100 and
//! 1000 s) and, when the published corpus is there, for Nav2's default tree
//! with `trees/nav2-default.params.yaml` (its hand-written semantics: the
//! re-planning race, the RecoveryNode's retries and the RoundRobin whose
//! index survives them).
//!
//! The test needs a Python with numpy and PyYAML (`BTREL_PYTHON`, else the
//! venv `target/pyvenv` the tests create: tests/common/python.rs); without
//! one it says SKIPPED and passes (fails with `BTREL_REQUIRE_PYTHON=1`).

mod common;

use common::python::python;

use std::path::{Path, PathBuf};
use std::process::Command;

use btrel::curve::{curve, CurveOptions};
use btrel::{analyze, Options};
use serde_json::Value;

/// Largest accepted |z| (a fixed seed: the check is deterministic).
const Z: f64 = 4.0;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// Runs scripts/numpy_mc.py with `args` and `--json`.
fn numpy_mc(python: &Path, args: &[&str]) -> Value {
    let out = Command::new(python)
        .arg(root().join("scripts/numpy_mc.py"))
        .args(args)
        .arg("--json")
        .current_dir(root())
        .output()
        .expect("run scripts/numpy_mc.py with the tests' Python");
    assert!(
        out.status.success(),
        "numpy_mc.py failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("numpy_mc.py prints JSON")
}

fn within(what: &str, est: &Value, exact: f64) {
    let (mean, se) = (est["mean"].as_f64().unwrap(), est["se"].as_f64().unwrap());
    let z = (mean - exact) / se;
    assert!(
        z.abs() < Z,
        "{what}: numpy {mean} ± {se} vs btrel's exact {exact} (z = {z:.2})"
    );
    eprintln!("{what}: numpy {mean:.6} ± {se:.2e}, exact {exact:.6} (z = {z:+.2})");
}

/// Compares the numpy estimates `r` with the exact figures and curve of the
/// root of `tree` at `times`.
fn compare(tree: &btrel::tree::Tree, r: &Value, times: &[f64]) {
    let exact = analyze(tree, &Options::default()).expect("analysed").nodes[0];
    within("ps", &r["ps"], exact.ps);
    within("pf", &r["pf"], exact.pf);
    within("mtts", &r["mtts"], exact.mtts.expect("MTTS"));
    within("mttf", &r["mttf"], exact.mttf.expect("MTTF"));
    let points = curve(tree, 0, times, &CurveOptions::default()).expect("exact curve");
    for (p, est) in points.iter().zip(r["curve"].as_array().expect("curve")) {
        within(&format!("P(S by {})", p.t), &est["success"], p.success);
        within(&format!("P(F by {})", p.t), &est["failure"], p.failure);
    }
}

#[test]
fn numpy_search_and_grasp_agrees_with_exact_figures() {
    let Some(py) = python("the numpy anchor on search-and-grasp") else {
        return;
    };
    let path = root().join("trees/search-and-grasp.yaml");
    let tree = btrel::tree::parse_file(&path).expect("search-and-grasp parses");
    let r = numpy_mc(
        &py,
        &[
            "trees/search-and-grasp.yaml",
            "--runs",
            "1000000",
            "--times",
            "10,100,1000",
            "--seed",
            "7",
        ],
    );
    assert_eq!(r["runs"], 1_000_000);
    compare(&tree, &r, &[10.0, 100.0, 1000.0]);
}

#[test]
fn numpy_nav2_default_agrees_with_exact_figures() {
    let Some(py) = python("the numpy anchor on Nav2's default tree") else {
        return;
    };
    let Some(corpus) = common::corpus() else {
        eprintln!("skipped: the published corpus (../shared/realworld) is not there");
        return;
    };
    let nav2 = corpus.join("nav2");
    let tree = btrel::tree::xml::parse_xml_files(
        &nav2.join("navigate_to_pose_w_replanning_and_recovery.xml"),
        &root().join("trees/nav2-default.params.yaml"),
        &[nav2.join("nav2_tree_nodes.xml")],
    )
    .expect("Nav2's default tree parses");
    let r = numpy_mc(
        &py,
        &[
            "--nav2",
            "trees/nav2-default.params.yaml",
            "--runs",
            "200000",
            "--times",
            "10,30,100,300",
            "--seed",
            "7",
        ],
    );
    compare(&tree, &r, &[10.0, 30.0, 100.0, 300.0]);
}

#[test]
fn numpy_mc_refuses_what_it_does_not_model() {
    let Some(py) = python("the numpy anchor's refusals") else {
        return;
    };
    let dir = tempfile::tempdir().expect("temporary directory");
    let file = dir.path().join("p.yaml");
    std::fs::write(
        &file,
        "tree: {parallel: {success_threshold: 1, children: [{action: {ps: 1, mu: 1}}]}}\n",
    )
    .expect("write");
    let out = Command::new(&py)
        .arg(root().join("scripts/numpy_mc.py"))
        .arg(&file)
        .output()
        .expect("run numpy_mc.py");
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("'parallel' is not supported"), "{err}");
}
