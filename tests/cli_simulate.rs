//! `btrel simulate`, `report --mc` and `curve --mc` from the command line.

use assert_cmd::Command;
use serde_json::Value;

fn btrel() -> Command {
    Command::cargo_bin("btrel").expect("binary")
}

const TREE: &str = "trees/search-and-grasp.yaml";

fn stdout(args: &[&str]) -> String {
    let out = btrel().args(args).output().unwrap();
    assert!(
        out.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).unwrap()
}

#[test]
fn simulate_json_has_the_documented_fields() {
    let text = stdout(&[
        "simulate", TREE, "--runs", "2e4", "--times", "100,1000", "--format", "json",
    ]);
    let v: Value = serde_json::from_str(&text).unwrap();
    assert_eq!(v["runs"], 20000);
    assert_eq!(v["seed"], 0x5EED_B7E1u64);
    let root = &v["nodes"][0];
    for key in [
        "name", "path", "ps", "ps_se", "mtts", "mtts_se", "mttf", "mttf_se",
    ] {
        assert!(root.get(key).is_some(), "missing {key}");
    }
    assert_eq!(v["nodes"].as_array().unwrap().len(), 12);
    let c = &v["curve"][0];
    assert_eq!(c["t"], 100.0);
    for key in ["success", "failure", "running", "success_se"] {
        assert!(c.get(key).is_some(), "missing {key}");
    }
    // p_s(100) = 0.197740 (reference/refs.json), within 5 standard errors
    let (p, se) = (
        c["success"].as_f64().unwrap(),
        c["success_se"].as_f64().unwrap(),
    );
    assert!((p - 0.197740).abs() < 5.0 * se, "{p} ± {se}");
}

#[test]
fn same_seed_same_output_whatever_the_threads() {
    let a = stdout(&[
        "simulate",
        TREE,
        "--runs",
        "200000",
        "--seed",
        "7",
        "--threads",
        "1",
        "--format",
        "json",
    ]);
    let b = stdout(&[
        "simulate",
        TREE,
        "--runs",
        "200000",
        "--seed",
        "7",
        "--threads",
        "2",
        "--format",
        "json",
    ]);
    assert_eq!(a, b);
    let c = stdout(&[
        "simulate", TREE, "--runs", "200000", "--seed", "8", "--format", "json",
    ]);
    assert_ne!(a, c);
}

#[test]
fn report_mc_reads_like_table_9_1() {
    let text = stdout(&["report", TREE, "--mc", "2e5", "--format", "json"]);
    let v: Value = serde_json::from_str(&text).unwrap();
    for node in v["nodes"].as_array().unwrap() {
        assert!(node["mc"].is_object());
        for (_, z) in node["z"].as_object().unwrap() {
            if let Some(z) = z.as_f64() {
                assert!(z.abs() < 5.0, "{}: z = {z}", node["name"]);
            }
        }
    }
    let table = stdout(&["report", TREE, "--mc", "1e5"]);
    assert!(table.contains("Monte Carlo check"));
    assert!(table.contains("relative error"));
}

#[test]
fn curve_mc_adds_columns_within_tolerance() {
    let text = stdout(&["curve", TREE, "--times", "50,100,500", "--mc", "2e5"]);
    let mut lines = text.lines();
    assert_eq!(
        lines.next().unwrap(),
        "node,t,success,failure,running,mc_success,mc_failure,mc_running"
    );
    for l in lines {
        let v: Vec<f64> = l.split(',').skip(1).map(|x| x.parse().unwrap()).collect();
        // binomial standard error with n = 2e5 is at most 0.0012
        for k in 0..3 {
            assert!((v[1 + k] - v[4 + k]).abs() < 5.0 * 0.0012, "{l}");
        }
    }
}

fn fails_with(args: &[&str], phrase: &str) {
    let out = btrel().args(args).output().unwrap();
    assert_eq!(out.status.code(), Some(2), "{args:?}");
    assert!(out.stdout.is_empty());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains(phrase), "{args:?}: {err}");
}

#[test]
fn bad_options() {
    fails_with(&["simulate", TREE, "--runs", "0"], "at least 1");
    fails_with(&["simulate", TREE, "--runs", "many"], "not a whole number");
    fails_with(&["simulate", TREE, "--runs", "1.5"], "not a whole number");
    fails_with(&["simulate", TREE, "--runs", "1e13"], "absurd");
    fails_with(&["simulate", TREE, "--seed", "-3"], "not a seed");
    fails_with(&["simulate", TREE, "--seed", "0xZZ"], "not a seed");
    fails_with(&["simulate", TREE, "--times", "-1"], "finite and >= 0");
    fails_with(
        &["simulate", TREE, "--format", "csv", "--times", "1"],
        "curve --mc",
    );
    fails_with(&["simulate", TREE, "--node", "nosuch"], "no node named");
    fails_with(&["report", TREE, "--mc", "0"], "at least 1");
}
