//! The `btrel` binary: every class of invalid input exits with code 2,
//! prints nothing on standard output, and explains on standard error where
//! (`FILE:LINE:COL`) and what is wrong; valid trees check and report in
//! every format.
//!
//! Every expected line and column below was counted by hand in the fixture
//! (1-based, columns in characters).

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Command as StdCommand, Stdio};
use std::time::{Duration, Instant};

use assert_cmd::Command;
use predicates::prelude::*;
use serde_json::Value;
use tempfile::TempDir;

fn btrel() -> Command {
    Command::new(env!("CARGO_BIN_EXE_btrel"))
}

fn repo(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(rel)
}

fn tree_files() -> Vec<PathBuf> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(repo("trees"))
        .expect("trees/")
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|x| x == "yaml"))
        // XML trees' parameter files are not trees
        .filter(|p| !p.to_string_lossy().ends_with(".params.yaml"))
        .collect();
    files.sort();
    assert!(files.len() >= 5, "expected the example trees in trees/");
    files
}

/// A fixture written to a temporary directory.
struct Fixture {
    _dir: TempDir,
    path: PathBuf,
}

fn fixture(name: &str, content: &[u8]) -> Fixture {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join(name);
    std::fs::write(&path, content).unwrap();
    Fixture { _dir: dir, path }
}

/// Runs `btrel check` and `btrel report` on the file; both must exit 2 with
/// empty stdout and no panic. Returns the stderr of `check`.
fn rejected(path: &Path) -> String {
    let mut first = None;
    for args in [
        vec!["check"],
        vec!["report"],
        vec!["report", "--method", "book"],
    ] {
        let out = btrel().args(&args).arg(path).output().unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr).to_string();
        assert_eq!(
            out.status.code(),
            Some(2),
            "btrel {args:?} {}: exit code; stderr:\n{stderr}",
            path.display()
        );
        assert!(
            out.stdout.is_empty(),
            "btrel {args:?}: stdout must be empty, got:\n{}",
            String::from_utf8_lossy(&out.stdout)
        );
        assert!(!stderr.contains("panicked"), "panic:\n{stderr}");
        assert!(stderr.starts_with("error: "), "stderr:\n{stderr}");
        first.get_or_insert(stderr);
    }
    first.unwrap()
}

/// The file is rejected with `FILE:LINE:COL` at one of `locations` and the
/// stderr contains every phrase.
fn rejected_at(name: &str, content: &str, locations: &[(usize, usize)], phrases: &[&str]) {
    let f = fixture(name, content.as_bytes());
    let stderr = rejected(&f.path);
    let file = f.path.display().to_string();
    let found = locations
        .iter()
        .any(|(l, c)| stderr.contains(&format!("{file}:{l}:{c}: ")));
    assert!(
        found,
        "{name}: expected a location {file}:LINE:COL with (LINE, COL) in {locations:?}; stderr:\n{stderr}"
    );
    for p in phrases {
        assert!(
            stderr.contains(p),
            "{name}: stderr lacks {p:?}; stderr:\n{stderr}"
        );
    }
}

// ---------------------------------------------------------------------------
// YAML syntax
// ---------------------------------------------------------------------------

#[test]
fn yaml_syntax_unclosed_flow_mapping() {
    // the `{` opened at 2:11 is never closed; EOF is 3:1
    rejected_at(
        "syntax.yaml",
        "tree:\n  action: {ps: 0.5, mu: 1, nu: 1\n",
        &[(2, 11), (3, 1)],
        &["unclosed"],
    );
}

#[test]
fn yaml_syntax_bad_indentation() {
    // the second list item (line 5) is indented one column less: col 6
    rejected_at(
        "indent.yaml",
        "tree:\n  sequence:\n    children:\n      - action: {ps: 0.5, mu: 1, nu: 1}\n     - action: {ps: 0.5, mu: 1, nu: 1}\n",
        &[(5, 6)],
        &[],
    );
}

#[test]
fn yaml_value_of_wrong_type() {
    // "  action: {ps: 0.5, mu: abc" -> `abc` at column 25
    rejected_at(
        "type.yaml",
        "tree:\n  action: {ps: 0.5, mu: abc, nu: 1}\n",
        &[(2, 25)],
        &["expected a number"],
    );
}

// ---------------------------------------------------------------------------
// Keys and kinds
// ---------------------------------------------------------------------------

#[test]
fn unknown_key_with_hint_flow() {
    // "  action: {ps: 0.5, " is 20 characters: `mux` at column 21
    rejected_at(
        "mux.yaml",
        "tree:\n  action: {ps: 0.5, mux: 1, nu: 1}\n",
        &[(2, 21)],
        &["unknown key `mux`", "did you mean `mu`"],
    );
}

#[test]
fn unknown_key_with_hint_block() {
    let yaml = "\
name: t
tree:
  sequence:
    children:
      - action:
          ps: 0.5
          mux: 1
          nu: 1
";
    // `mux` on line 7 after 10 spaces
    rejected_at(
        "mux-block.yaml",
        yaml,
        &[(7, 11)],
        &["unknown key `mux`", "did you mean `mu`"],
    );
}

#[test]
fn unknown_key_in_parallel_and_file() {
    rejected_at(
        "threshold-typo.yaml",
        "tree:\n  parallel:\n    sucess_threshold: 1\n    children:\n      - action: {ps: 0.5, mu: 1, nu: 1}\n",
        &[(3, 5)],
        &["unknown key `sucess_threshold`", "did you mean `success_threshold`"],
    );
    rejected_at(
        "tre.yaml",
        "tre:\n  action: {ps: 0.5, mu: 1, nu: 1}\n",
        &[(1, 1)],
        &["unknown key `tre`", "did you mean `tree`"],
    );
}

#[test]
fn unknown_node_kind_with_hint() {
    rejected_at(
        "fallbak.yaml",
        "tree:\n  fallbak:\n    children:\n      - action: {ps: 0.5, mu: 1, nu: 1}\n",
        &[(2, 3)],
        &["unknown node kind `fallbak`", "did you mean `fallback`"],
    );
    // nested: "      - fallbak" -> column 9 of line 4
    rejected_at(
        "fallbak-nested.yaml",
        "tree:\n  sequence:\n    children:\n      - condition: {ps: 1}\n      - fallbak: {children: [{action: {ps: 0.5, mu: 1, nu: 1}}]}\n",
        &[(5, 9)],
        &["unknown node kind `fallbak`", "did you mean `fallback`"],
    );
}

#[test]
fn missing_ps_flow() {
    // the node is `action:` at 2:3, its mapping `{` at 2:11
    let f = fixture("nops.yaml", b"tree:\n  action: {mu: 1, nu: 1}\n");
    let stderr = rejected(&f.path);
    assert!(
        stderr.contains(&format!("{}:2:", f.path.display())),
        "{stderr}"
    );
    assert!(stderr.contains("missing key `ps`"), "{stderr}");
    assert!(stderr.contains("[0, 1]"), "{stderr}");
}

#[test]
fn missing_ps_block_points_at_the_node() {
    // The action lacking `ps` starts at line 4 (`action:` at column 9, its
    // mapping at 5:11). An error located at the last key of the mapping
    // (7:11, `nu: 1`) points the user at the wrong key.
    let yaml = "\
tree:
  sequence:
    children:
      - action:
          name: x
          mu: 1
          nu: 1
      - condition: {ps: 1}
";
    rejected_at(
        "nops-block.yaml",
        yaml,
        &[(4, 9), (5, 11)],
        &["missing key `ps`"],
    );
}

#[test]
fn missing_children_key() {
    rejected_at(
        "nochildren.yaml",
        "tree:\n  sequence:\n    name: s\n",
        &[(2, 3), (3, 5)],
        &["missing key `children`"],
    );
}

// ---------------------------------------------------------------------------
// Parameters
// ---------------------------------------------------------------------------

#[test]
fn missing_timing() {
    // "  action: {ps: 0.5" : `{` 11, `ps` 12, `0.5` 16
    rejected_at(
        "nomu.yaml",
        "tree:\n  action: {ps: 0.5, nu: 1}\n",
        &[(2, 3), (2, 11), (2, 12), (2, 16)],
        &["no success time", "mu", "tau_s"],
    );
    rejected_at(
        "nonu.yaml",
        "tree:\n  action: {ps: 0.5, mu: 1}\n",
        &[(2, 3), (2, 11), (2, 12), (2, 16)],
        &["no failure time", "nu", "tau_f"],
    );
}

#[test]
fn probability_out_of_range() {
    rejected_at(
        "ps.yaml",
        "tree:\n  action: {ps: 1.5, mu: 1, nu: 1}\n",
        &[(2, 16)],
        &["ps = 1.5", "[0, 1]"],
    );
    rejected_at(
        "ps-neg.yaml",
        "tree:\n  condition: {ps: -0.1}\n",
        // "  condition: {ps: " is 18 characters
        &[(2, 19)],
        &["ps = -0.1", "[0, 1]"],
    );
}

#[test]
fn nan_and_infinite_parameters() {
    // "  action: {ps: 0.5, mu: " is 24 characters
    rejected_at(
        "nan.yaml",
        "tree:\n  action: {ps: 0.5, mu: .nan, nu: 1}\n",
        &[(2, 25)],
        &["mu = NaN", "finite"],
    );
    rejected_at(
        "inf.yaml",
        "tree:\n  action: {ps: 0.5, mu: .inf, nu: 1}\n",
        &[(2, 25)],
        &["mu = inf", "finite"],
    );
    rejected_at(
        "ps-nan.yaml",
        "tree:\n  action: {ps: .nan, mu: 1, nu: 1}\n",
        &[(2, 16)],
        &["ps = NaN", "[0, 1]"],
    );
    rejected_at(
        "tau-inf.yaml",
        "tree:\n  action: {ps: 1, tau_s: .inf}\n",
        // "  action: {ps: 1, tau_s: " is 25 characters
        &[(2, 26)],
        &["tau_s = inf", "finite"],
    );
}

#[test]
fn negative_or_zero_rate_and_negative_time() {
    // "  action: {ps: 0.5, mu: 1, nu: " is 31 characters
    rejected_at(
        "neg.yaml",
        "tree:\n  action: {ps: 0.5, mu: 1, nu: -2}\n",
        &[(2, 32)],
        &["nu = -2", "> 0"],
    );
    rejected_at(
        "zero.yaml",
        "tree:\n  action: {ps: 0.5, mu: 0, nu: 1}\n",
        &[(2, 25)],
        &["mu = 0", "> 0"],
    );
    rejected_at(
        "tau-neg.yaml",
        "tree:\n  action: {ps: 0, tau_f: -1}\n",
        // "  action: {ps: 0, tau_f: " is 25 characters
        &[(2, 26)],
        &["tau_f = -1"],
    );
}

#[test]
fn probabilities_must_sum_to_one() {
    // `0.6` (pf) at 25, `0.5` (ps) at 16
    rejected_at(
        "sum.yaml",
        "tree:\n  action: {ps: 0.5, pf: 0.6, mu: 1, nu: 1}\n",
        &[(2, 25), (2, 16)],
        &["ps + pf", "must be 1"],
    );
}

#[test]
fn pf_consistent_with_ps_is_accepted() {
    let f = fixture(
        "pf.yaml",
        b"tree:\n  action: {ps: 0.3, pf: 0.7, mu: 1, nu: 1}\n",
    );
    btrel().arg("check").arg(&f.path).assert().success();
}

#[test]
fn mu_and_tau_s_both_given() {
    // `mu` value at 25, `tau_s` key at 28, its value at 35
    rejected_at(
        "both.yaml",
        "tree:\n  action: {ps: 0.5, mu: 1, tau_s: 2, nu: 1}\n",
        &[(2, 21), (2, 25), (2, 28), (2, 35)],
        &["both `mu` and `tau_s`"],
    );
    // "  action: {ps: 0.5, mu: 1, nu: 1, tau_f: 2}": nu key 28, value 32,
    // tau_f key 35, value 42
    rejected_at(
        "both-f.yaml",
        "tree:\n  action: {ps: 0.5, mu: 1, nu: 1, tau_f: 2}\n",
        &[(2, 28), (2, 32), (2, 35), (2, 42)],
        &["both `nu` and `tau_f`"],
    );
}

// ---------------------------------------------------------------------------
// Structure
// ---------------------------------------------------------------------------

#[test]
fn control_node_without_children() {
    // "    children: []": key at 5, `[` at 15
    for kind in ["sequence", "fallback", "parallel"] {
        rejected_at(
            &format!("{kind}-empty.yaml"),
            &format!("tree:\n  {kind}:\n    children: []\n"),
            &[(3, 15), (3, 5), (2, 3)],
            &["no children"],
        );
    }
}

fn parallel_with_threshold(m: &str) -> String {
    format!(
        "tree:\n  parallel:\n    success_threshold: {m}\n    children:\n      \
         - action: {{ps: 0.5, mu: 1, nu: 1}}\n      \
         - action: {{ps: 0.5, mu: 1, nu: 1}}\n"
    )
}

#[test]
fn success_threshold_out_of_range_or_fractional() {
    // "    success_threshold: " is 23 characters: the value is at column 24
    for m in ["0", "3", "1.5", "-1"] {
        rejected_at(
            &format!("threshold-{m}.yaml"),
            &parallel_with_threshold(m),
            &[(3, 24)],
            &["success_threshold", "whole number from 1 to 2"],
        );
    }
    // the valid ones pass
    for m in ["1", "2"] {
        let f = fixture("ok.yaml", parallel_with_threshold(m).as_bytes());
        btrel().arg("check").arg(&f.path).assert().success();
    }
}

#[test]
fn duplicate_names() {
    // "      - action: {name: " is 23 characters: the name is at column 24
    let yaml = "\
tree:
  sequence:
    children:
      - action: {name: grab, ps: 0.5, mu: 1, nu: 1}
      - action: {name: grab, ps: 0.5, mu: 1, nu: 1}
";
    rejected_at(
        "dup.yaml",
        yaml,
        &[(5, 24)],
        &["duplicate", "grab", "line 4"],
    );
    // a control node and a leaf sharing a name: the leaf (line 5) is second
    let yaml = "\
tree:
  sequence:
    name: grab
    children:
      - action: {name: grab, ps: 0.5, mu: 1, nu: 1}
";
    rejected_at(
        "dup2.yaml",
        yaml,
        &[(5, 24)],
        &["duplicate", "grab", "line 3"],
    );
}

#[test]
fn empty_node_name() {
    rejected_at(
        "empty-name.yaml",
        "tree:\n  action: {name: '', ps: 0.5, mu: 1, nu: 1}\n",
        // "  action: {name: " is 17 characters
        &[(2, 18)],
        &["name"],
    );
}

// ---------------------------------------------------------------------------
// Files
// ---------------------------------------------------------------------------

#[test]
fn empty_file() {
    for (name, content) in [("empty.yaml", ""), ("blank.yaml", "\n  \n\n")] {
        let f = fixture(name, content.as_bytes());
        let stderr = rejected(&f.path);
        assert!(stderr.contains(&f.path.display().to_string()), "{stderr}");
        assert!(stderr.contains("empty"), "{stderr}");
        assert!(
            stderr.contains("tree:"),
            "the hint shows the format: {stderr}"
        );
    }
}

#[test]
fn comment_only_file_is_reported_as_empty() {
    // A file with only comments is an empty YAML document; the message
    // should say so (or name the missing `tree:` key), like an empty file.
    let f = fixture("comment.yaml", b"# a tree will go here\n");
    let stderr = rejected(&f.path);
    assert!(
        stderr.contains("empty") || stderr.contains("tree"),
        "unhelpful message for a comment-only file:\n{stderr}"
    );
}

#[test]
fn file_without_tree_key() {
    rejected_at(
        "notree.yaml",
        "name: just a title\n",
        &[(1, 1)],
        &["missing key `tree`"],
    );
}

#[test]
fn non_utf8_file() {
    // invalid bytes after "  action: {name: " (17 characters) on line 2
    let f = fixture(
        "latin1.yaml",
        b"tree:\n  action: {name: \xff\xfe, ps: 0.5, mu: 1, nu: 1}\n",
    );
    let stderr = rejected(&f.path);
    assert!(
        stderr.contains(&format!("{}:2:18: ", f.path.display())),
        "{stderr}"
    );
    assert!(stderr.contains("UTF-8"), "{stderr}");
}

#[test]
fn binary_garbage_file() {
    let mut garbage: Vec<u8> = vec![0x7f, b'E', b'L', b'F', 0x02, 0x01, 0x01, 0x00];
    garbage.extend((0..4096u32).map(|i| (i.wrapping_mul(2_654_435_761) >> 13) as u8));
    let f = fixture("a.out", &garbage);
    let stderr = rejected(&f.path);
    assert!(stderr.contains(&f.path.display().to_string()), "{stderr}");
    // valid UTF-8, but control characters
    let f = fixture("ctrl.yaml", b"\x00\x01\x02\x03tree");
    let stderr = rejected(&f.path);
    assert!(stderr.contains(&f.path.display().to_string()), "{stderr}");
}

#[test]
fn missing_file() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("no-such-tree.yaml");
    let stderr = rejected(&path);
    assert!(stderr.contains(&path.display().to_string()), "{stderr}");
    assert!(stderr.contains("cannot read"), "{stderr}");
}

#[test]
fn directory_instead_of_file() {
    let dir = tempfile::tempdir().unwrap();
    let stderr = rejected(dir.path());
    assert!(
        stderr.contains(&dir.path().display().to_string()),
        "{stderr}"
    );
}

fn nested_block(levels: usize) -> String {
    let mut s = String::from("tree:\n");
    let mut pad = String::from("  ");
    for _ in 0..levels - 1 {
        s.push_str(&format!("{pad}sequence:\n{pad}  children:\n{pad}    -\n"));
        pad.push_str("      ");
    }
    s.push_str(&format!("{pad}action: {{ps: 0.5, mu: 1, nu: 1}}\n"));
    s
}

fn nested_flow(levels: usize) -> String {
    format!(
        "tree: {}{{action: {{ps: 0.5, mu: 1, nu: 1}}}}{}\n",
        "{sequence: {children: [".repeat(levels - 1),
        "]}}".repeat(levels - 1)
    )
}

#[test]
fn deeply_nested_tree_is_rejected_quickly() {
    for (name, yaml) in [
        ("deep-block.yaml", nested_block(300)),
        ("deep-flow.yaml", nested_flow(300)),
        ("very-deep-flow.yaml", nested_flow(100_000)),
    ] {
        let f = fixture(name, yaml.as_bytes());
        let start = Instant::now();
        let stderr = rejected(&f.path);
        assert!(
            start.elapsed() < Duration::from_secs(10),
            "{name}: too slow"
        );
        assert!(
            stderr.contains("levels deep") || stderr.contains("nested too deeply"),
            "{name}: {stderr}"
        );
        assert!(
            stderr.contains(&format!("{}:", f.path.display())),
            "{stderr}"
        );
    }
}

fn assert_nested_accepted(yaml: &str, levels: usize) {
    let f = fixture("deep-ok.yaml", yaml.as_bytes());
    btrel()
        .arg("check")
        .arg(&f.path)
        .assert()
        .success()
        .stdout(predicate::str::contains(format!("{levels} nodes, 1 leaf")));
    // a chain of Sequences over one action: every node is the action
    let out = btrel()
        .args(["report", "--format", "json"])
        .arg(&f.path)
        .output()
        .unwrap();
    assert!(out.status.success());
    let v: Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["nodes"].as_array().unwrap().len(), levels);
    assert_eq!(v["nodes"][0]["ps"], 0.5);
    assert_eq!(v["nodes"][0]["mtts"], 1.0);
}

#[test]
fn nested_block_tree_within_the_limit_is_accepted() {
    // the error message says "btrel accepts trees up to 200 levels deep"
    assert_nested_accepted(&nested_block(200), 200);
}

#[test]
fn nested_flow_tree_within_the_advertised_limit_is_accepted() {
    // the same kind of tree in flow style, 100 levels: within the advertised 200
    assert_nested_accepted(&nested_flow(100), 100);
}

#[test]
fn billion_laughs_is_rejected_quickly() {
    // nine levels of nine aliases each: 9^9 ≈ 3.9e8 actions if expanded
    let mut yaml = String::from(
        "tree:\n  sequence:\n    children:\n      - &a0 {action: {ps: 0.5, mu: 1, nu: 1}}\n",
    );
    for k in 1..=9 {
        let refs = vec![format!("*a{}", k - 1); 9].join(", ");
        yaml.push_str(&format!(
            "      - &a{k} {{sequence: {{children: [{refs}]}}}}\n"
        ));
    }
    let f = fixture("lol.yaml", yaml.as_bytes());
    let start = Instant::now();
    let stderr = rejected(&f.path);
    assert!(
        start.elapsed() < Duration::from_secs(10),
        "alias bomb took {:?}",
        start.elapsed()
    );
    assert!(stderr.contains("alias"), "{stderr}");
    assert!(
        stderr.contains(&format!("{}:", f.path.display())),
        "{stderr}"
    );

    // the classic form, aliases of string lists used as a name
    let mut yaml = String::from("x0: &l0 [lol, lol, lol, lol, lol, lol, lol, lol, lol]\n");
    for k in 1..=9 {
        let refs = vec![format!("*l{}", k - 1); 9].join(", ");
        yaml.push_str(&format!("x{k}: &l{k} [{refs}]\n"));
    }
    yaml.push_str("tree: {action: {name: *l9, ps: 0.5, mu: 1, nu: 1}}\n");
    let f = fixture("lol2.yaml", yaml.as_bytes());
    let start = Instant::now();
    rejected(&f.path);
    assert!(start.elapsed() < Duration::from_secs(10));
}

#[test]
fn huge_file_is_rejected_by_size() {
    // a sparse file bigger than the 256 MiB limit: rejected before reading
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("huge.yaml");
    let file = std::fs::File::create(&path).unwrap();
    file.set_len(300 << 20).unwrap();
    drop(file);
    let start = Instant::now();
    let stderr = rejected(&path);
    assert!(start.elapsed() < Duration::from_secs(10));
    assert!(stderr.contains("limit"), "{stderr}");
    assert!(stderr.contains(&path.display().to_string()), "{stderr}");
}

// ---------------------------------------------------------------------------
// Valid trees: check and report
// ---------------------------------------------------------------------------

#[test]
fn check_every_example_tree() {
    for path in tree_files() {
        btrel()
            .arg("check")
            .arg(&path)
            .assert()
            .success()
            .stderr(predicate::str::is_empty())
            .stdout(predicate::str::contains(": ok ("));
    }
}

const JSON_NODE_KEYS: [&str; 9] = [
    "name", "path", "kind", "ps", "pf", "mtts", "mttf", "mu", "nu",
];

#[test]
fn report_every_example_tree_in_every_format() {
    for path in tree_files() {
        let tree = btrel::tree::parse_file(&path).unwrap();
        let n = tree.nodes().len();
        for method in ["exact", "book"] {
            // table
            let out = btrel()
                .args(["report", "--method", method])
                .arg(&path)
                .output()
                .unwrap();
            if method == "book" && path.ends_with("drone-fleet.yaml") {
                // the book's recursion needs the MRG of the 16-child Parallel
                // (2.4e7 markings): refused before allocating
                let stderr = String::from_utf8(out.stderr).unwrap();
                assert_eq!(out.status.code(), Some(1), "{stderr}");
                assert!(stderr.contains("--max-states"), "{stderr}");
                continue;
            }
            assert!(out.status.success(), "{}: {out:?}", path.display());
            assert!(out.stderr.is_empty());
            let table = String::from_utf8(out.stdout).unwrap();
            let lines: Vec<&str> = table.lines().collect();
            assert_eq!(lines.len(), n + 2, "title, header, one row per node");
            assert!(lines[0].contains(&format!("method: {method}")), "{table}");
            for node in tree.nodes() {
                assert!(table.contains(&node.name), "{table}");
            }

            // json
            let out = btrel()
                .args(["report", "--format", "json", "--method", method])
                .arg(&path)
                .output()
                .unwrap();
            assert!(out.status.success());
            let v: Value = serde_json::from_slice(&out.stdout).expect("valid JSON");
            assert_eq!(v["method"], method);
            assert!(v["tree"].is_string());
            let nodes = v["nodes"].as_array().unwrap();
            assert_eq!(nodes.len(), n);
            for (node, j) in tree.nodes().iter().zip(nodes) {
                for k in JSON_NODE_KEYS {
                    assert!(j.get(k).is_some(), "missing key {k} in {j}");
                }
                assert_eq!(j["name"], node.name.as_str());
                assert_eq!(j["path"], node.path.as_str());
                assert_eq!(j["kind"], node.kind.keyword());
                let ps = j["ps"].as_f64().unwrap();
                let pf = j["pf"].as_f64().unwrap();
                assert!((ps + pf - 1.0).abs() < 1e-12);
                // undefined figures are null, never 0/NaN
                assert_eq!(j["mtts"].is_null(), ps == 0.0, "{j}");
                assert_eq!(j["mttf"].is_null(), pf == 0.0, "{j}");
                if j["mtts"].is_null() {
                    assert!(j["mu"].is_null(), "{j}");
                }
            }

            // csv
            let out = btrel()
                .args(["report", "--format", "csv", "--method", method])
                .arg(&path)
                .output()
                .unwrap();
            assert!(out.status.success());
            let csv = String::from_utf8(out.stdout).unwrap();
            let mut rows = csv.lines();
            assert_eq!(
                rows.next().unwrap(),
                "name,path,kind,depth,ps,pf,mtts,mttf,mu,nu"
            );
            assert_eq!(rows.count(), n);
        }
    }
}

#[test]
fn json_report_values_and_nulls_for_search_and_grasp() {
    let out = btrel()
        .args(["report", "--format", "json"])
        .arg(repo("trees/search-and-grasp.yaml"))
        .output()
        .unwrap();
    assert!(out.status.success());
    let v: Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["tree"], "search and grasp");
    assert_eq!(v["method"], "exact");
    let nodes = v["nodes"].as_array().unwrap();
    let node = |name: &str| {
        nodes
            .iter()
            .find(|n| n["name"] == name)
            .unwrap_or_else(|| panic!("{name}"))
    };
    // root: refs.json ps = 0.4884 = .888 * .55; mu0 ≈ 5.9040e-3 (Table 9.1)
    let root = node("search and grasp");
    assert_eq!(root["path"], "0");
    assert_eq!(root["kind"], "sequence");
    assert!((root["ps"].as_f64().unwrap() - 0.888 * 0.55).abs() < 1e-12);
    assert!((root["mu"].as_f64().unwrap() - 5.9039e-3).abs() < 1e-7);
    // grasp: MTTF = 1/2 + 1/0.05 = 20.5
    assert!((node("grasp")["mttf"].as_f64().unwrap() - 20.5).abs() < 1e-12);
    // a condition that never succeeds and takes no time: MTTS, mu and nu
    // (1/0) undefined -> null; MTTF = 0
    let cond = node("object grasped");
    assert_eq!(cond["kind"], "condition");
    assert_eq!(cond["ps"], 0.0);
    assert!(cond["mtts"].is_null(), "{cond}");
    assert!(cond["mu"].is_null(), "{cond}");
    assert!(cond["nu"].is_null(), "{cond}");
    assert_eq!(cond["mttf"], 0.0);
}

#[test]
fn csv_and_table_show_undefined_figures() {
    let path = repo("trees/search-and-grasp.yaml");
    let out = btrel()
        .args(["report", "--format", "csv"])
        .arg(&path)
        .output()
        .unwrap();
    let csv = String::from_utf8(out.stdout).unwrap();
    let row = csv
        .lines()
        .find(|l| l.starts_with("object grasped,"))
        .unwrap();
    let cells: Vec<&str> = row.split(',').collect();
    // name,path,kind,depth,ps,pf,mtts,mttf,mu,nu
    assert_eq!(cells.len(), 10, "{row}");
    assert_eq!(cells[6], "", "MTTS empty: {row}");
    assert_eq!(cells[8], "", "mu empty: {row}");
    assert_eq!(cells[9], "", "nu empty: {row}");
    assert_eq!(cells[7].parse::<f64>().unwrap(), 0.0);

    let out = btrel().arg("report").arg(&path).output().unwrap();
    let table = String::from_utf8(out.stdout).unwrap();
    let row = table
        .lines()
        .find(|l| l.contains("object grasped"))
        .unwrap();
    assert!(row.contains('—'), "{row}");
    assert!(!row.contains("NaN") && !row.contains("inf"), "{row}");
}

#[test]
fn output_file_option() {
    let dir = tempfile::tempdir().unwrap();
    let out_path = dir.path().join("figures.json");
    btrel()
        .args(["report", "--format", "json", "-o"])
        .arg(&out_path)
        .arg(repo("trees/three-action-fallback.yaml"))
        .assert()
        .success()
        .stdout(predicate::str::is_empty());
    let v: Value = serde_json::from_str(&std::fs::read_to_string(&out_path).unwrap()).unwrap();
    // Example 9.7: ps = .3 + .7 * .6 + .7 * .4 * .5 = .86, MTTF = 1 + 2.5 + 4
    assert!((v["nodes"][0]["ps"].as_f64().unwrap() - 0.86).abs() < 1e-12);
    assert!((v["nodes"][0]["mttf"].as_f64().unwrap() - 7.5).abs() < 1e-12);
    // --output, csv, overwriting an existing file
    let csv_path = dir.path().join("figures.csv");
    std::fs::write(&csv_path, "old").unwrap();
    btrel()
        .args(["report", "--format", "csv", "--output"])
        .arg(&csv_path)
        .arg(repo("trees/search-and-grasp.yaml"))
        .assert()
        .success()
        .stdout(predicate::str::is_empty());
    let csv = std::fs::read_to_string(&csv_path).unwrap();
    assert!(csv.starts_with("name,path,kind,"));
    assert_eq!(csv.lines().count(), 13);
    // nothing else (no temporary file) left in the directory
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 2);
}

#[test]
fn output_to_unwritable_place_fails_cleanly() {
    let dir = tempfile::tempdir().unwrap();
    let out_path = dir.path().join("no-such-dir").join("x.json");
    let out = btrel()
        .args(["report", "-o"])
        .arg(&out_path)
        .arg(repo("trees/search-and-grasp.yaml"))
        .output()
        .unwrap();
    assert!(!out.status.success());
    assert!(out.stdout.is_empty());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("cannot write"), "{stderr}");
    assert!(!stderr.contains("panicked"), "{stderr}");
}

#[test]
fn help_mentions_examples() {
    btrel()
        .arg("--help")
        .assert()
        .success()
        .stdout(predicate::str::contains("Examples"))
        .stdout(predicate::str::contains("btrel report"));
    btrel()
        .args(["report", "--help"])
        .assert()
        .success()
        .stdout(predicate::str::contains("Examples"))
        .stdout(predicate::str::contains("--method"));
}

#[test]
fn usage_errors_exit_2() {
    let tree = repo("trees/search-and-grasp.yaml");
    for args in [
        vec!["report", "--bogus"],
        vec!["report", "--method", "magic"],
        vec!["report", "--format", "xml"],
        vec!["report", "--max-states", "lots"],
        vec!["frobnicate"],
    ] {
        let out = btrel().args(&args).arg(&tree).output().unwrap();
        assert_eq!(out.status.code(), Some(2), "{args:?}");
        assert!(out.stdout.is_empty(), "{args:?}");
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(stderr.contains("error"), "{args:?}: {stderr}");
    }
    // no subcommand, no file
    let out = btrel().output().unwrap();
    assert_eq!(out.status.code(), Some(2));
    let out = btrel().arg("report").output().unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(out.stdout.is_empty());
}

#[test]
fn analysis_errors_exit_1() {
    // a Parallel over a Sequence holding a race of a hybrid and a
    // stochastic action (answered since its children enter as composed
    // laws; tests/engine_spec.rs) refused for a state budget of 1
    let f = fixture(
        "det-parallel.yaml",
        b"tree:\n  parallel:\n    success_threshold: 1\n    failure_threshold: 1\n    children:\n      \
          - sequence: {children: [{parallel: {success_threshold: 1, failure_threshold: 1, children: [\
          {action: {name: timer, ps: 0.5, tau_s: 1, nu: 1}}, {action: {ps: 0.5, mu: 1, nu: 1}}]}}]}\n      \
          - action: {ps: 0.5, mu: 1, nu: 1}\n",
    );
    let out = btrel()
        .args(["report", "--max-states", "1"])
        .arg(&f.path)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    assert!(out.stdout.is_empty());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("budget of 1 states") && stderr.contains("--max-states 2"),
        "the error names the budget and the one that suffices: {stderr}"
    );
    // ... but the book method works, and `check` accepts the file
    btrel()
        .args(["report", "--method", "book"])
        .arg(&f.path)
        .assert()
        .success();
    btrel().arg("check").arg(&f.path).assert().success();

    // a state budget too small for a race's child (a Sequence's chain)
    let f = fixture(
        "independent.yaml",
        b"tree: {parallel: {success_threshold: 2, failure_threshold: 1, children: \
          [{sequence: {children: [{action: {ps: 0.9, mu: 1, nu: 2}}, {action: {ps: 0.9, mu: 3, nu: 2}}]}}, {action: {ps: 0.8, mu: 2, nu: 1}}, {action: {ps: 0.7, mu: 1, nu: 1}}]}}\n",
    );
    let out = btrel()
        .args(["report", "--max-states", "2"])
        .arg(&f.path)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    assert!(out.stdout.is_empty());
    assert!(String::from_utf8_lossy(&out.stderr).contains("--max-states"));
    // with the book's thresholds the same budget is enough: the Parallels
    // are counted, not multiplied out
    btrel()
        .args(["report", "--max-states", "2"])
        .arg(repo("trees/two-arm-parallel.yaml"))
        .assert()
        .success();
}

#[test]
fn broken_pipe_does_not_panic() {
    // a report much larger than a pipe buffer (64 KiB): 3000 rows
    let mut yaml = String::from("tree:\n  fallback:\n    children:\n");
    for i in 0..3000 {
        yaml.push_str(&format!(
            "      - action: {{name: action number {i}, ps: 0.001, mu: 1, nu: 2}}\n"
        ));
    }
    let f = fixture("wide.yaml", yaml.as_bytes());
    for format in ["table", "json", "csv"] {
        let mut child = StdCommand::new(env!("CARGO_BIN_EXE_btrel"))
            .args(["report", "--format", format])
            .arg(&f.path)
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        {
            // read one line, like `| head -1`, then close the pipe
            let mut reader = BufReader::new(child.stdout.take().unwrap());
            let mut line = String::new();
            reader.read_line(&mut line).unwrap();
            assert!(!line.is_empty());
        }
        let out = child.wait_with_output().unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(!stderr.contains("panicked"), "{format}: {stderr}");
        assert!(
            out.status.code().is_some(),
            "{format}: killed by a signal: {:?}",
            out.status
        );
        assert_eq!(out.status.code(), Some(0), "{format}: {stderr}");
    }
}

/// A blackboard value the params file lacks is a missing parameter: exit 2,
/// every missing value listed with its location, the output ending with a
/// newline, also when the tree has a node without a stochastic meaning.
#[test]
fn missing_blackboard_values_exit_2() {
    let dir = tempfile::tempdir().unwrap();
    let xml = dir.path().join("t.xml");
    std::fs::write(
        &xml,
        "<root BTCPP_format=\"4\">\n<BehaviorTree ID=\"Main\">\n<Sequence>\n\
         <LoopPose queue=\"{waypoints}\"><Go/></LoopPose>\n\
         <Timeout msec=\"{relaxation_time_ms}\"><Go/></Timeout>\n\
         <RunOnce><Go/></RunOnce>\n</Sequence>\n</BehaviorTree>\n</root>\n",
    )
    .unwrap();
    std::fs::write(
        dir.path().join("t.params.yaml"),
        "Go: {ps: 0.5, mu: 1, nu: 1}\n",
    )
    .unwrap();
    let out = btrel().arg("check").arg(&xml).output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr).to_string();
    assert_eq!(out.status.code(), Some(2), "stderr:\n{stderr}");
    let file = xml.display().to_string();
    assert!(
        stderr.starts_with(&format!(
            "error: {file}:4:11: missing parameters for 2 nodes"
        )),
        "stderr:\n{stderr}"
    );
    for p in [
        format!("{file}:4:11: <LoopPose> queue = \"{{waypoints}}\""),
        format!("{file}:5:10: <Timeout> msec = \"{{relaxation_time_ms}}\""),
        format!("{file}:6:1: <RunOnce>"),
    ] {
        assert!(stderr.contains(&p), "stderr lacks {p:?}:\n{stderr}");
    }
    assert!(stderr.contains("\n  help: "), "stderr:\n{stderr}");
    assert!(stderr.ends_with('\n'), "stderr:\n{stderr:?}");
}
