//! `btrel curve` from the command line: output format and option errors.

use assert_cmd::Command;

fn btrel() -> Command {
    Command::cargo_bin("btrel").expect("binary")
}

const TREE: &str = "trees/search-and-grasp.yaml";

#[test]
fn csv_has_header_and_rows_in_requested_order() {
    let out = btrel()
        .args(["curve", TREE, "--times", "100,10,1000"])
        .output()
        .unwrap();
    assert!(out.status.success());
    let text = String::from_utf8(out.stdout).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    assert_eq!(lines[0], "node,t,success,failure,running");
    let ts: Vec<&str> = lines[1..]
        .iter()
        .map(|l| l.split(',').nth(1).unwrap())
        .collect();
    assert_eq!(ts, ["100", "10", "1000"]);
    for l in &lines[1..] {
        let v: Vec<f64> = l.split(',').skip(2).map(|x| x.parse().unwrap()).collect();
        assert!((v.iter().sum::<f64>() - 1.0).abs() < 1e-12, "{l}");
    }
}

#[test]
fn several_nodes_and_grids() {
    let out = btrel()
        .args([
            "curve", TREE, "--node", "search", "--node", "0.1.1", "--t-end", "100", "--points",
            "11",
        ])
        .output()
        .unwrap();
    assert!(out.status.success());
    let text = String::from_utf8(out.stdout).unwrap();
    assert_eq!(text.lines().count(), 1 + 22);
    assert!(text.lines().nth(1).unwrap().starts_with("search,0,"));
    assert!(text.lines().nth(12).unwrap().starts_with("grasp,0,"));
    let out = btrel()
        .args(["curve", TREE, "--t-end", "10", "--dt", "2.5"])
        .output()
        .unwrap();
    let text = String::from_utf8(out.stdout).unwrap();
    let ts: Vec<&str> = text
        .lines()
        .skip(1)
        .map(|l| l.split(',').nth(1).unwrap())
        .collect();
    assert_eq!(ts, ["0", "2.5", "5", "7.5", "10"]);
}

#[test]
fn output_file_is_written() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("c.csv");
    btrel()
        .args(["curve", TREE, "--times", "1,2", "-o"])
        .arg(&path)
        .assert()
        .success()
        .stdout("");
    let text = std::fs::read_to_string(&path).unwrap();
    assert_eq!(text.lines().count(), 3);
}

fn fails_with(args: &[&str], code: i32, phrase: &str) {
    let out = btrel().args(args).output().unwrap();
    assert_eq!(out.status.code(), Some(code), "{args:?}");
    assert!(out.stdout.is_empty(), "{args:?} printed on stdout");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains(phrase), "{args:?}: {err}");
}

#[test]
fn option_errors() {
    fails_with(&["curve", TREE, "--times", "-1"], 2, "finite and >= 0");
    fails_with(&["curve", TREE, "--times", "1,inf"], 2, "finite and >= 0");
    fails_with(&["curve", TREE, "--times", "NaN"], 2, "finite and >= 0");
    fails_with(&["curve", TREE, "--times", "1,abc"], 2, "not a number");
    fails_with(&["curve", TREE, "--times", ""], 2, "not a number");
    fails_with(&["curve", TREE], 2, "--t-end");
    fails_with(
        &["curve", TREE, "--t-end", "10", "--points", "0"],
        2,
        "--points",
    );
    fails_with(
        &["curve", TREE, "--t-end", "10", "--dt", "0"],
        2,
        "--dt must be > 0",
    );
    fails_with(
        &["curve", TREE, "--t-end", "1e9", "--dt", "1e-3"],
        2,
        "more than the limit",
    );
    fails_with(
        &["curve", TREE, "--times", "1", "--t-end", "3"],
        2,
        "cannot be used with",
    );
    fails_with(
        &["curve", TREE, "--times", "1", "--node", "nosuch"],
        2,
        "no node named 'nosuch'",
    );
    fails_with(
        &["curve", TREE, "--times", "1", "--method", "magic"],
        2,
        "invalid value",
    );
}
