//! Hardening (issue 8): the YAML and XML front ends never panic, hang or
//! blow up on malformed input (a proptest-driven generator of broken
//! documents, the CI guard next to the cargo-fuzz targets in fuzz/), and the
//! command line's outputs are honest: undefined figures are null / — / empty,
//! times are validated, files are written atomically, `| head` is quiet,
//! exit codes follow the README and every error says what to do.

use std::io::{BufRead, BufReader, Read};
use std::path::{Path, PathBuf};
use std::process::{Command as StdCommand, Stdio};
use std::time::{Duration, Instant};

use assert_cmd::Command;
use btrel::tree::xml::parse_xml_str;
use btrel::tree::{parse_str, Tree, TreeError, TreeErrorKind};
use proptest::prelude::*;
use serde_json::Value;

// ---------------------------------------------------------------------------
// Front ends: Ok or a located Err, quickly, never a panic
// ---------------------------------------------------------------------------

/// Per-input time bound (release build; generous, typical inputs take < 1 ms).
const PER_INPUT: Duration = Duration::from_secs(2);

fn repo(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(rel)
}

fn read(rel: &str) -> String {
    std::fs::read_to_string(repo(rel)).unwrap()
}

fn yaml_trees() -> Vec<String> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(repo("trees"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|x| x == "yaml"))
        .filter(|p| !p.to_string_lossy().ends_with(".params.yaml"))
        .collect();
    files.sort();
    files
        .iter()
        .map(|p| std::fs::read_to_string(p).unwrap())
        .collect()
}

/// The error is a real diagnosis, not a caught panic, and it renders.
/// The parsers run on a thread and turn a panic into an error of kind
/// Internal (inputs may echo "internal error" into messages, not the kind).
fn is_caught_panic(e: &TreeError) -> bool {
    e.kind == TreeErrorKind::Internal
}

fn sane_error(e: &TreeError, input: &str) {
    assert!(!is_caught_panic(e), "parser panicked on {input:?}: {e}");
    assert!(!e.message.is_empty());
    let _ = e.to_string();
}

fn sane_tree(t: &Tree) {
    assert!(!t.nodes().is_empty());
    for n in t.nodes() {
        if let btrel::tree::NodeKind::Action(a) = n.kind {
            assert!((0.0..=1.0).contains(&a.ps) && (0.0..=1.0).contains(&a.pf));
        }
    }
}

fn yaml_survives(input: &str) {
    let start = Instant::now();
    match parse_str(input, "fuzz.yaml") {
        Ok(t) => sane_tree(&t),
        Err(e) => sane_error(&e, input),
    }
    let took = start.elapsed();
    assert!(took < PER_INPUT, "YAML parse took {took:?} on {input:?}");
}

fn xml_survives(xml: &str, params: &str) {
    let start = Instant::now();
    match parse_xml_str(xml, "fuzz.xml", params, "fuzz.params.yaml") {
        Ok(t) => sane_tree(&t),
        Err(e) => sane_error(&e, xml),
    }
    let took = start.elapsed();
    assert!(took < PER_INPUT, "XML parse took {took:?} on {xml:?}");
}

fn sg_xml() -> (String, String) {
    (
        read("trees/search-and-grasp.xml"),
        read("trees/search-and-grasp.params.yaml"),
    )
}

#[test]
fn yaml_every_prefix_of_a_tree() {
    let src = read("trees/search-and-grasp.yaml");
    for (i, _) in src.char_indices() {
        yaml_survives(&src[..i]);
    }
}

#[test]
fn xml_every_prefix_of_a_tree_and_of_its_params() {
    let (xml, params) = sg_xml();
    for (i, _) in xml.char_indices() {
        xml_survives(&xml[..i], &params);
    }
    for (i, _) in params.char_indices() {
        xml_survives(&xml, &params[..i]);
    }
}

#[test]
fn seed_corpus_survives() {
    for dir in ["fuzz/corpus/yaml", "fuzz/corpus/xml"] {
        let mut n = 0;
        let default_params = read("trees/search-and-grasp.params.yaml");
        for e in std::fs::read_dir(repo(dir)).unwrap() {
            let bytes = std::fs::read(e.unwrap().path()).unwrap();
            n += 1;
            if dir.ends_with("yaml") {
                yaml_survives(&String::from_utf8_lossy(&bytes));
            } else {
                // same split as fuzz_targets/xml.rs
                let (x, p) = match bytes.iter().position(|&b| b == 0) {
                    Some(i) => (&bytes[..i], &bytes[i + 1..]),
                    None => (&bytes[..], default_params.as_bytes()),
                };
                xml_survives(&String::from_utf8_lossy(x), &String::from_utf8_lossy(p));
            }
        }
        assert!(n >= 5, "seed corpus {dir}");
    }
}

/// Hostile documents built by hand: deep nesting, alias bombs, huge numbers,
/// NUL bytes, long lines, odd Unicode.
#[test]
fn hostile_yaml() {
    let mut cases: Vec<String> = Vec::new();
    for depth in [150, 201, 1_000, 20_000] {
        cases.push(format!(
            "tree: {}{{condition: {{ps: 0.5}}}}{}\n",
            "{sequence: {children: [".repeat(depth),
            "]}}".repeat(depth)
        ));
        // block style
        let mut s = String::from("tree:\n");
        for d in 0..depth.min(2_000) {
            let ind = "  ".repeat(2 * d + 1);
            s.push_str(&format!("{ind}inverter:\n{ind}  child:\n"));
        }
        s.push_str(&format!(
            "{}condition: {{ps: 0.5}}\n",
            "  ".repeat(2 * depth.min(2_000) + 1)
        ));
        cases.push(s);
        cases.push(format!("tree: {}x{}", "[".repeat(depth), "]".repeat(depth)));
    }
    // billion laughs: the alias budget must stop it
    let mut bomb = String::from("l0: &l0 [lol, lol, lol, lol, lol, lol, lol, lol, lol, lol]\n");
    for i in 1..12 {
        bomb.push_str(&format!(
            "l{i}: &l{i} [{}]\n",
            vec![format!("*l{}", i - 1); 10].join(", ")
        ));
    }
    cases.push(bomb.clone() + "tree: {condition: {ps: 0.5}}\n");
    cases.push("tree: &t {sequence: {children: [*t]}}\n".into());
    // the bomb as a node list
    let mut tb = String::from("a0: &a0 {condition: {ps: 0.5}}\n");
    for i in 1..12 {
        tb.push_str(&format!(
            "a{i}: &a{i} {{sequence: {{children: [{}]}}}}\n",
            vec![format!("*a{}", i - 1); 10].join(", ")
        ));
    }
    cases.push(tb.replace("a11: &a11", "tree:"));
    for num in [
        "1e308",
        "1e309",
        "-1e309",
        "1e-400",
        "-0",
        "-0.0",
        "0x10",
        "0o7",
        "1_000",
        "99999999999999999999999999999",
        ".nan",
        ".NaN",
        ".inf",
        "-.inf",
        "1e-324",
        "4.9e-324",
        "0.1e",
        "--1",
        "NaN",
        "inf",
        "~",
        "null",
        "true",
        "''",
        "[]",
        "{}",
    ] {
        for key in ["ps", "mu", "nu", "tau_s", "pf"] {
            cases.push(format!(
                "tree: {{action: {{name: a, {key}: {num}, ps: 0.5, nu: 1}}}}\n"
            ));
            cases.push(format!(
                "tree:\n  action: {{ps: {}, mu: {}, nu: 1}}\n",
                if key == "ps" { num } else { "0.5" },
                if key == "mu" { num } else { "1" }
            ));
        }
        cases.push(format!(
            "tree: {{retry: {{attempts: {num}, child: {{condition: {{ps: 0.5}}}}}}}}\n"
        ));
        cases.push(format!(
            "tree: {{parallel: {{success_threshold: {num}, children: [{{condition: {{ps: 1}}}}]}}}}\n"
        ));
    }
    cases.push(
        "tree: {retry: {attempts: 1000000, child: {action: {ps: 0.5, mu: 1, nu: 1}}}}\n".into(),
    );
    cases.push("tree: {repeat: {times: 1e6, child: {repeat: {times: 1e6, child: {condition: {ps: 1}}}}}}\n".into());
    cases.push(format!(
        "tree: {{condition: {{name: {}, ps: 0.5}}}}\n",
        "x".repeat(1 << 20)
    ));
    cases.push(format!(
        "# {}\ntree: {{condition: {{ps: 0.5}}}}",
        "é".repeat(100_000)
    ));
    cases.push("tree: {condition: {name: \"\u{0}\", ps: 0.5}}\n".into());
    cases.push("tree:\0 {condition: {ps: 0.5}}\n".into());
    cases.push("\u{feff}tree: {condition: {ps: 0.5}}\n".into());
    cases.push("tree: {condition: {name: \"\u{202e}\u{1F916}\u{10FFFF}\", ps: 0.5}}\n".into());
    cases.push("tree:\n\tcondition: {ps: 0.5}\n".into());
    cases.push("---\ntree: {condition: {ps: 0.5}}\n---\ntree: {condition: {ps: 0.5}}\n".into());
    cases.push("tree: !!binary aGVsbG8=\n".into());
    cases.push("tree: {condition: {ps: !!str 0.5}}\n".into());
    cases.push("tree: {? [a, b] : c}\n".into());
    cases.push("\"tree\": {\"condition\": {\"ps\": 0.5, \"ps\": 0.6}}\n".into());
    let mut wide = String::from("tree:\n  fallback:\n    children:\n");
    for _ in 0..20_000 {
        wide.push_str("      - condition: {ps: 0.5}\n");
    }
    cases.push(wide);
    for c in &cases {
        yaml_survives(c);
    }
}

#[test]
fn hostile_xml() {
    let (_, params) = sg_xml();
    let head = "<root BTCPP_format=\"4\" main_tree_to_execute=\"M\"><BehaviorTree ID=\"M\">";
    let tail = "</BehaviorTree></root>";
    let mut cases: Vec<String> = Vec::new();
    for depth in [150, 201, 1_000, 50_000] {
        cases.push(format!(
            "{head}{}<AlwaysSuccess/>{}{tail}",
            "<Inverter>".repeat(depth),
            "</Inverter>".repeat(depth)
        ));
        cases.push(format!("{head}{}{tail}", "<Sequence>".repeat(depth)));
    }
    // SubTree fan-out: 2^30 nodes if expanded blindly
    let mut fan = String::from("<root BTCPP_format=\"4\" main_tree_to_execute=\"T30\">");
    fan.push_str("<BehaviorTree ID=\"T0\"><AlwaysSuccess/></BehaviorTree>");
    for i in 1..=30 {
        fan.push_str(&format!(
            "<BehaviorTree ID=\"T{i}\"><Sequence><SubTree ID=\"T{0}\"/><SubTree ID=\"T{0}\"/></Sequence></BehaviorTree>",
            i - 1
        ));
    }
    fan.push_str("</root>");
    cases.push(fan);
    cases.push(
        "<!DOCTYPE r [<!ENTITY a \"aaaaaaaaaa\"><!ENTITY b \"&a;&a;&a;&a;&a;&a;&a;&a;\">]><root/>"
            .into(),
    );
    cases.push(format!(
        "{head}<Action ID=\"{}\"/>{tail}",
        "x".repeat(1 << 20)
    ));
    cases.push(format!(
        "{head}<Action ID=\"a\" {}/>{tail}",
        "k=\"v\" ".repeat(10_000)
    ));
    for junk in [
        "", "<", "<root", "<root>", "</root>", "<root/>", "<?xml?>", "<!-- ", "<![CDATA[",
        "<root BTCPP_format=\"4\">\0</root>", "<root BTCPP_format=\"4\"><BehaviorTree ID=\"\"/></root>",
        "<root BTCPP_format=\"4\"><BehaviorTree/></root>", "&#0;", "&#x110000;", "&#xFFFFFFFFFF;",
        "<root a=\"1\" a=\"2\"/>", "<ü/>", "<root BTCPP_format=\"4\"><BehaviorTree ID=\"M\"><Parallel success_count=\"99999999999999999999\"><AlwaysSuccess/></Parallel></BehaviorTree></root>",
        "<root BTCPP_format=\"4\"><BehaviorTree ID=\"M\"><RetryUntilSuccessful num_attempts=\"-1\"><AlwaysFailure/></RetryUntilSuccessful></BehaviorTree></root>",
        "<root BTCPP_format=\"4\"><BehaviorTree ID=\"M\"><Repeat num_cycles=\"1e400\"><AlwaysFailure/></Repeat></BehaviorTree></root>",
    ] {
        cases.push(junk.to_string());
        cases.push(format!("{head}{junk}{tail}"));
    }
    for c in &cases {
        xml_survives(c, &params);
    }
    let (xml, _) = sg_xml();
    for p in [
        "",
        "\0",
        "SearchFloor: {ps: 1e309, mu: -1, nu: .nan}",
        "*x",
        "a: &a [*a]",
        "SearchFloor: [[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[]]]",
    ] {
        xml_survives(&xml, p);
    }
}

/// One random edit of a document.
#[derive(Debug, Clone)]
enum Edit {
    FlipByte(usize, u8),
    InsertByte(usize, u8),
    Truncate(usize),
    DeleteLine(usize),
    DuplicateLine(usize, usize),
    Indent(usize, usize),
    Dedent(usize),
    Insert(usize, &'static str),
    ReplaceNumber(usize, &'static str),
}

const SNIPPETS: &[&str] = &[
    "\0",
    "é",
    "\u{1F916}",
    "\u{feff}",
    "\u{202e}",
    "\t",
    "\r",
    "\r\n",
    ":",
    "- ",
    "{",
    "}",
    "[",
    "]",
    "&a ",
    "*a",
    "!!str ",
    "? ",
    "|",
    ">",
    "'",
    "\"",
    "#",
    "%YAML 1.2\n",
    "---\n",
    "<",
    ">",
    "/>",
    "</",
    "<!--",
    "-->",
    "&amp;",
    "&#x41;",
    "<![CDATA[",
    "=\"",
    "<Sequence>",
    "</Sequence>",
    "<SubTree ID=\"SearchAndGrasp\"/>",
    "name: x\n",
    "children: [{sequence: {children: [{sequence: {children: []}}]}}]",
];

const NUMBERS: &[&str] = &[
    "1e308",
    "1e309",
    "-1",
    "-0",
    "0",
    "1",
    "2",
    "1e-12",
    "1e-400",
    ".nan",
    ".inf",
    "-.inf",
    "99999999999999999999",
    "0.5e",
    "x",
    "",
    "1e5",
    "1e-4",
    "4294967296",
    "-1e309",
];

fn edit() -> impl Strategy<Value = Edit> {
    let n = any::<prop::sample::Index>();
    prop_oneof![
        (any::<usize>(), any::<u8>()).prop_map(|(i, b)| Edit::FlipByte(i, b)),
        (any::<usize>(), any::<u8>()).prop_map(|(i, b)| Edit::InsertByte(i, b)),
        any::<usize>().prop_map(Edit::Truncate),
        any::<usize>().prop_map(Edit::DeleteLine),
        (any::<usize>(), 1usize..50).prop_map(|(i, k)| Edit::DuplicateLine(i, k)),
        (any::<usize>(), 1usize..9).prop_map(|(i, k)| Edit::Indent(i, k)),
        any::<usize>().prop_map(Edit::Dedent),
        (any::<usize>(), n.clone()).prop_map(|(i, s)| Edit::Insert(i, s.get::<&str>(SNIPPETS))),
        (any::<usize>(), n).prop_map(|(i, s)| Edit::ReplaceNumber(i, s.get::<&str>(NUMBERS))),
    ]
}

fn apply(doc: &[u8], e: &Edit) -> Vec<u8> {
    let mut d = doc.to_vec();
    let len = d.len().max(1);
    let lines =
        |d: &[u8]| -> Vec<Vec<u8>> { d.split(|&b| b == b'\n').map(|l| l.to_vec()).collect() };
    match *e {
        Edit::FlipByte(i, b) if !d.is_empty() => d[i % len] ^= b | 1,
        Edit::FlipByte(..) => {}
        Edit::InsertByte(i, b) => d.insert(i % (d.len() + 1), b),
        Edit::Truncate(i) => d.truncate(i % len),
        Edit::DeleteLine(i) => {
            let mut l = lines(&d);
            let k = i % l.len();
            l.remove(k);
            d = l.join(&b'\n');
        }
        Edit::DuplicateLine(i, times) => {
            let mut l = lines(&d);
            let k = i % l.len();
            for _ in 0..times {
                l.insert(k, l[k].clone());
            }
            d = l.join(&b'\n');
        }
        Edit::Indent(i, by) => {
            let mut l = lines(&d);
            let k = i % l.len();
            let mut s = vec![b' '; by];
            s.extend_from_slice(&l[k]);
            l[k] = s;
            d = l.join(&b'\n');
        }
        Edit::Dedent(i) => {
            let mut l = lines(&d);
            let k = i % l.len();
            let lead = l[k].iter().take_while(|&&b| b == b' ').count();
            l[k].drain(..lead.min(1 + i % 4));
            d = l.join(&b'\n');
        }
        Edit::Insert(i, s) => {
            let at = i % (d.len() + 1);
            d.splice(at..at, s.bytes());
        }
        Edit::ReplaceNumber(i, s) => {
            // the k-th run of digits/dots
            let runs: Vec<(usize, usize)> = {
                let mut v = Vec::new();
                let mut j = 0;
                while j < d.len() {
                    if d[j].is_ascii_digit() {
                        let st = j;
                        while j < d.len() && (d[j].is_ascii_digit() || d[j] == b'.') {
                            j += 1;
                        }
                        v.push((st, j));
                    } else {
                        j += 1;
                    }
                }
                v
            };
            if !runs.is_empty() {
                let (a, b) = runs[i % runs.len()];
                d.splice(a..b, s.bytes());
            }
        }
    }
    d
}

fn mutate(doc: &str, edits: &[Edit]) -> String {
    let mut d = doc.as_bytes().to_vec();
    for e in edits {
        d = apply(&d, e);
    }
    // the front ends take text; invalid UTF-8 is rejected before them
    String::from_utf8_lossy(&d).into_owned()
}

proptest! {
    #![proptest_config(ProptestConfig {
        cases: 384,
        failure_persistence: None,
        .. ProptestConfig::default()
    })]

    #[test]
    fn mutated_yaml_trees_never_panic(
        which in any::<prop::sample::Index>(),
        edits in prop::collection::vec(edit(), 1..6),
    ) {
        let trees = yaml_trees();
        let doc = which.get(&trees);
        yaml_survives(&mutate(doc, &edits));
    }

    #[test]
    fn mutated_xml_trees_never_panic(
        which in 0usize..2,
        edits in prop::collection::vec(edit(), 1..6),
        params_edits in prop::collection::vec(edit(), 0..3),
    ) {
        let (xml, params) = if which == 0 {
            sg_xml()
        } else {
            (read("trees/two-arm-parallel.xml"), read("trees/two-arm-parallel.params.yaml"))
        };
        xml_survives(&mutate(&xml, &edits), &mutate(&params, &params_edits));
    }

    #[test]
    fn arbitrary_text_never_panics(s in "\\PC{0,200}") {
        yaml_survives(&s);
        xml_survives(&s, "");
    }
}

// ---------------------------------------------------------------------------
// Honest outputs (CLI)
// ---------------------------------------------------------------------------

fn btrel() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_btrel"));
    c.current_dir(env!("CARGO_MANIFEST_DIR"))
        .timeout(Duration::from_secs(60));
    c
}

const SG: &str = "trees/search-and-grasp.yaml";

/// A tree with undefined figures at every level: `never` (ps = 0: no MTTS),
/// `always` (pf = 0: no MTTF), `stuck` never succeeds.
const UNDEFINED: &str = "tree:
  fallback:
    name: root
    children:
      - sequence:
          name: stuck
          children:
            - condition: {name: never, ps: 0}
            - action: {name: act, ps: 0.5, mu: 1, nu: 2}
      - condition: {name: always, ps: 1}
";

struct Run {
    code: i32,
    stdout: String,
    stderr: String,
}

fn run(args: &[&str]) -> Run {
    let out = btrel().args(args).output().unwrap();
    Run {
        code: out.status.code().unwrap_or(-1),
        stdout: String::from_utf8_lossy(&out.stdout).into(),
        stderr: String::from_utf8_lossy(&out.stderr).into(),
    }
}

/// A Parallel whose failure threshold (1) is below N − M + 1: whichever
/// threshold is met first wins, so it needs its product chain (16 states).
const INDEPENDENT_PARALLEL: &str = "tree: {parallel: {success_threshold: 2, failure_threshold: 1, \
    children: [{sequence: {children: [{action: {ps: 0.9, mu: 1, nu: 2}}, {action: {ps: 0.9, mu: 3, nu: 2}}]}}, {action: {ps: 0.8, mu: 2, nu: 1}}, {action: {ps: 0.7, mu: 1, nu: 1}}]}}\n";

fn temp_tree(yaml: &str) -> (tempfile::TempDir, String) {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("t.yaml");
    std::fs::write(&p, yaml).unwrap();
    (dir, p.to_str().unwrap().to_string())
}

fn no_nan(s: &str) {
    let lower = s.to_lowercase();
    for w in lower.split(|c: char| !c.is_ascii_alphanumeric()) {
        assert!(w != "nan" && w != "inf" && w != "infinity", "{s}");
    }
}

#[test]
fn undefined_figures_are_null_dash_or_empty() {
    let (_d, t) = temp_tree(UNDEFINED);
    let json = run(&["report", &t, "--format", "json"]);
    assert_eq!(json.code, 0, "{}", json.stderr);
    let v: Value = serde_json::from_str(&json.stdout).unwrap();
    let node = |n: &str| {
        v["nodes"]
            .as_array()
            .unwrap()
            .iter()
            .find(|x| x["name"] == n)
            .unwrap()
            .clone()
    };
    for n in ["never", "stuck"] {
        assert!(node(n)["mtts"].is_null() && node(n)["mu"].is_null(), "{n}");
    }
    assert!(node("always")["mttf"].is_null() && node("always")["nu"].is_null());
    // zero-duration: MTTS = 0 is defined, its rate 1/0 is not
    assert_eq!(node("always")["mtts"], 0.0);
    assert!(node("always")["mu"].is_null());

    let table = run(&["report", &t]);
    let line = table.stdout.lines().find(|l| l.contains("stuck")).unwrap();
    assert!(line.contains('—'), "{line}");
    let line = table.stdout.lines().find(|l| l.contains("never")).unwrap();
    assert_eq!(line.matches('—').count(), 3, "{line}"); // MTTS, mu, nu = 1/0
    let csv = run(&["report", &t, "--format", "csv"]);
    let row = csv
        .stdout
        .lines()
        .find(|l| l.starts_with("stuck,"))
        .unwrap();
    let cells: Vec<&str> = row.split(',').collect();
    assert_eq!((cells[6], cells[8]), ("", ""), "{row}");
    for out in [&json.stdout, &table.stdout, &csv.stdout] {
        no_nan(out);
        assert!(!out.contains("null") || out == &json.stdout);
    }
}

#[test]
fn simulated_undefined_figures_are_null_or_dash() {
    let (_d, t) = temp_tree(UNDEFINED);
    let json = run(&["simulate", &t, "--runs", "2000", "--format", "json"]);
    assert_eq!(json.code, 0, "{}", json.stderr);
    no_nan(&json.stdout);
    let v: Value = serde_json::from_str(&json.stdout).unwrap();
    let never = v["nodes"]
        .as_array()
        .unwrap()
        .iter()
        .find(|x| x["name"] == "never")
        .unwrap();
    assert!(never["mtts"].is_null(), "{never}");
    for fmt in ["table", "csv"] {
        let r = run(&["simulate", &t, "--runs", "2000", "--format", fmt]);
        assert_eq!(r.code, 0);
        no_nan(&r.stdout);
    }
    let r = run(&["report", &t, "--mc", "2000"]);
    assert_eq!(r.code, 0);
    no_nan(&r.stdout);
    let r = run(&["report", &t, "--mc", "2000", "--format", "json"]);
    assert_eq!(r.code, 0);
    no_nan(&r.stdout);
    let r = run(&["compare", &t, "--format", "json"]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    no_nan(&r.stdout);
}

/// What a good error message looks like: `error: `, then something that
/// tells the user what to do.
fn has_hint(stderr: &str) -> bool {
    let s = stderr.to_lowercase();
    [
        "help:",
        "give ",
        "use ",
        "must ",
        "did you mean",
        "accepted",
        "e.g.",
        "try ",
        "add ",
        "remove ",
        "choose ",
        "create ",
        "expected ",
        "works with",
        "instead",
        "between ",
        "at most",
        "check ",
        "should ",
    ]
    .iter()
    .any(|h| s.contains(h))
}

#[test]
fn requested_times_must_be_finite_and_non_negative() {
    let mut cases: Vec<Vec<&str>> = Vec::new();
    for bad in [
        "-1", "nan", "NaN", "inf", "-inf", "1e400", "abc", "", "-0.5",
    ] {
        cases.push(vec!["curve", SG, "--times", bad]);
        cases.push(vec!["curve", SG, "--t-end", bad]);
        cases.push(vec!["simulate", SG, "--runs", "100", "--t-end", bad]);
        cases.push(vec!["simulate", SG, "--runs", "100", "--times", bad]);
        cases.push(vec!["compare", SG, "--deadline", bad]);
        cases.push(vec!["plot", SG, "-o", "/dev/null", "--t-end", bad]);
        cases.push(vec!["curve", SG, "--t-end", "10", "--dt", bad]);
    }
    cases.push(vec!["curve", SG, "--times", "1,2,-3"]);
    cases.push(vec!["curve", SG, "--t-end", "10", "--dt", "0"]);
    cases.push(vec!["curve", SG, "--t-end", "10", "--points", "0"]);
    for args in cases {
        let r = run(&args);
        assert_eq!(r.code, 2, "{args:?}: {}", r.stderr);
        assert!(r.stdout.is_empty(), "{args:?}");
        assert!(!r.stderr.contains("panicked"), "{args:?}");
        assert!(r.stderr.starts_with("error"), "{args:?}: {}", r.stderr);
    }
    // 0 itself is fine
    assert_eq!(run(&["curve", SG, "--times", "0"]).code, 0);
}

#[test]
fn time_errors_say_what_is_accepted() {
    for args in [
        vec!["curve", SG, "--times", "-1"],
        vec!["curve", SG, "--t-end", "nan"],
        vec!["compare", SG, "--deadline", "inf"],
        vec!["plot", SG, "-o", "/dev/null", "--t-end", "-5"],
    ] {
        let r = run(&args);
        assert!(
            r.stderr.contains("finite and >= 0") || r.stderr.contains(">= 0"),
            "{args:?}: {}",
            r.stderr
        );
    }
}

fn dir_entries(d: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(d)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

#[test]
fn output_into_a_missing_directory_fails_cleanly() {
    let dir = tempfile::tempdir().unwrap();
    let target = dir.path().join("no-such-dir").join("out.csv");
    let target = target.to_str().unwrap();
    for args in [
        vec!["report", SG, "-o", target],
        vec!["curve", SG, "--t-end", "10", "-o", target],
        vec!["simulate", SG, "--runs", "100", "-o", target],
        vec!["export", SG, "--to", "dot", "-o", target],
        vec!["plot", SG, "--format", "svg", "-o", target],
        vec!["compare", SG, "--curves", target],
    ] {
        let r = run(&args);
        assert_eq!(r.code, 2, "{args:?}: {}", r.stderr);
        assert!(r.stderr.contains("cannot write"), "{args:?}: {}", r.stderr);
        assert!(
            dir_entries(dir.path()).is_empty(),
            "{:?}",
            dir_entries(dir.path())
        );
    }
}

#[test]
fn a_failed_command_leaves_the_existing_output_untouched() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("existing.txt");
    let bad = dir.path().join("bad.yaml");
    std::fs::write(&bad, "tree: {action: {ps: 2}}\n").unwrap();
    let (_independent_dir, independent) = temp_tree(INDEPENDENT_PARALLEL);
    let o = out.to_str().unwrap();
    let b = bad.to_str().unwrap();
    for args in [
        vec!["report", b, "-o", o],
        vec!["report", &independent, "--max-states", "2", "-o", o],
        vec![
            "curve",
            SG,
            "--node",
            "no such node",
            "--t-end",
            "1",
            "-o",
            o,
        ],
        vec!["curve", b, "--t-end", "1", "-o", o],
        vec!["simulate", SG, "--runs", "-5", "-o", o],
        vec!["export", SG, "--to", "prism", "--mrg", "nope", "-o", o],
        vec!["plot", SG, "--node", "nope", "-o", o],
        vec!["compare", SG, "--node", "nope", "-o", o],
    ] {
        std::fs::write(&out, "precious\n").unwrap();
        let r = run(&args);
        assert_ne!(r.code, 0, "{args:?}");
        assert_eq!(
            std::fs::read_to_string(&out).unwrap(),
            "precious\n",
            "{args:?}"
        );
        assert_eq!(
            dir_entries(dir.path()),
            ["bad.yaml", "existing.txt"],
            "{args:?}"
        );
    }
    // and a successful run replaces it with no stray temporary file
    assert_eq!(run(&["report", SG, "-o", o]).code, 0);
    assert!(std::fs::read_to_string(&out)
        .unwrap()
        .contains("search and grasp"));
    assert_eq!(dir_entries(dir.path()), ["bad.yaml", "existing.txt"]);
}

/// Runs btrel with stdout into a pipe, reads one line (like `| head -1`) and
/// closes the pipe; btrel must end quietly (exit 0, nothing on stderr).
fn head_1(args: &[&str]) {
    let mut child = StdCommand::new(env!("CARGO_BIN_EXE_btrel"))
        .args(args)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut first = String::new();
    {
        let mut r = BufReader::new(child.stdout.take().unwrap());
        r.read_line(&mut first).unwrap();
    } // pipe closed here
    let start = Instant::now();
    let status = loop {
        if let Some(s) = child.try_wait().unwrap() {
            break s;
        }
        assert!(start.elapsed() < Duration::from_secs(60), "{args:?} hangs");
        std::thread::sleep(Duration::from_millis(10));
    };
    let mut err = String::new();
    child
        .stderr
        .take()
        .unwrap()
        .read_to_string(&mut err)
        .unwrap();
    assert!(!first.is_empty(), "{args:?}");
    assert!(
        !err.contains("panicked") && !err.to_lowercase().contains("broken pipe"),
        "{args:?}: {err}"
    );
    assert_eq!(status.code(), Some(0), "{args:?}: {err}");
}

#[test]
fn piping_into_head_is_quiet() {
    // outputs larger than a pipe buffer, so the writer sees the closed pipe
    let big =
        btrel::generate::random_tree_yaml(&btrel::generate::Shape::sequence_fallback(3_000), 7);
    let (_d, t) = temp_tree(&big);
    for fmt in ["table", "json", "csv"] {
        head_1(&["report", &t, "--format", fmt]);
        head_1(&["simulate", &t, "--runs", "200", "--format", fmt]);
    }
    head_1(&[
        "simulate", SG, "--runs", "1000", "--t-end", "1000", "--points", "20000", "--format",
        "json",
    ]);
    head_1(&["curve", SG, "--t-end", "1000", "--points", "200000"]);
    head_1(&[
        "curve", SG, "--t-end", "1000", "--points", "20000", "--mc", "1000",
    ]);
    let mut eight = String::from("tree:\n  fallback:\n    children:\n");
    for i in 0..8 {
        eight.push_str(&format!(
            "      - action: {{name: a{i}, ps: 0.{}, mu: {}, nu: 1}}\n",
            i + 1,
            i + 1
        ));
    }
    let (_d2, t2) = temp_tree(&eight);
    for fmt in ["table", "json", "csv"] {
        head_1(&["compare", &t2, "--top", "40320", "--format", fmt]);
    }
    head_1(&["export", &t, "--to", "dot"]);
    head_1(&["export", SG, "--to", "prism"]);
    head_1(&["check", SG]);
}

#[test]
fn exit_codes_follow_the_readme() {
    let (_d, ok) = temp_tree("tree: {condition: {ps: 0.5}}\n");
    assert_eq!(run(&["check", &ok]).code, 0);
    assert_eq!(run(&["--help"]).code, 0);
    assert_eq!(run(&["report", "--help"]).code, 0);
    // 2: invalid input or usage
    for args in [
        vec!["report"],
        vec!["no-such-command"],
        vec!["report", SG, "--format", "xlsx"],
        vec!["report", "does/not/exist.yaml"],
        vec!["report", "README.md"],
        vec!["curve", SG],
        vec!["simulate", SG, "--runs", "ten"],
        vec!["export", SG, "--to", "pdf"],
        vec!["report", SG, "--params", "x.yaml"],
    ] {
        let r = run(&args);
        assert_eq!(r.code, 2, "{args:?}: {}", r.stderr);
        assert!(r.stdout.is_empty(), "{args:?}");
    }
    // 1: the analysis cannot be done as asked (an independent failure
    // threshold needs the product chain)
    let (_dir, independent) = temp_tree(INDEPENDENT_PARALLEL);
    let r = run(&["report", &independent, "--max-states", "2"]);
    assert_eq!(r.code, 1, "{}", r.stderr);
    assert!(r.stdout.is_empty());
}

#[test]
fn every_error_says_what_to_do() {
    let (_independent_dir, independent) = temp_tree(INDEPENDENT_PARALLEL);
    let dir = tempfile::tempdir().unwrap();
    let write = |name: &str, text: &str| {
        let p = dir.path().join(name);
        std::fs::write(&p, text).unwrap();
        p.to_str().unwrap().to_string()
    };
    let typo = write(
        "typo.yaml",
        "tree: {action: {name: a, ps: 0.3, mux: 0.1, nu: 0.2}}\n",
    );
    let range = write("range.yaml", "tree: {action: {ps: 1.5, mu: 1, nu: 1}}\n");
    let kind = write("kind.yaml", "tree: {fallbak: {children: []}}\n");
    let empty = write("empty.yaml", "# nothing\n");
    let syntax = write("syntax.yaml", "tree: {action: [}\n");
    let notime = write("notime.yaml", "tree: {action: {ps: 0.5, mu: 1}}\n");
    let dup = write(
        "dup.yaml",
        "tree: {sequence: {children: [{condition: {name: a, ps: 1}}, {condition: {name: a, ps: 1}}]}}\n",
    );
    let nonfinite = write("nan.yaml", "tree: {action: {ps: 0.5, mu: .nan, nu: 1}}\n");
    let binary = write("bin.yaml", "\u{0}\u{1}tree");
    let xml = write("t.xml", "<root BTCPP_format=\"4\"><BehaviorTree ID=\"M\"><ScriptCondition code=\"x==1\"/></BehaviorTree></root>");
    let _ = write("t.params.yaml", "{}\n");
    let cases: Vec<Vec<&str>> = vec![
        vec!["report", &typo],
        vec!["report", &range],
        vec!["report", &kind],
        vec!["report", &empty],
        vec!["report", &syntax],
        vec!["report", &notime],
        vec!["report", &dup],
        vec!["report", &nonfinite],
        vec!["report", &binary],
        vec!["report", &xml],
        vec!["report", "does/not/exist.yaml"],
        vec!["curve", SG],
        vec!["curve", SG, "--times", "-1"],
        vec!["curve", SG, "--node", "no such node", "--times", "1"],
        vec!["simulate", SG, "--runs", "ten"],
        vec!["report", &independent, "--max-states", "2"],
        vec!["report", SG, "--mc", "100", "--format", "csv"],
        vec!["report", SG, "--bogus-flag"],
    ];
    let mut missing = Vec::new();
    for args in &cases {
        let r = run(args);
        assert_ne!(r.code, 0, "{args:?}");
        assert!(r.stderr.contains("error"), "{args:?}: {}", r.stderr);
        if !has_hint(&r.stderr) {
            missing.push(format!("{args:?}: {}", r.stderr.trim()));
        }
    }
    assert!(
        missing.is_empty(),
        "errors without a hint of what to do:\n{}",
        missing.join("\n")
    );
}

#[test]
fn cli_errors_without_advice() {
    let dir = tempfile::tempdir().unwrap();
    let target = dir.path().join("no-such-dir").join("out.csv");
    let (_d, t) = temp_tree(UNDEFINED);
    let cases: Vec<Vec<&str>> = vec![
        vec!["report", SG, "-o", target.to_str().unwrap()],
        vec!["compare", SG, "--node", "search and grasp"],
        vec!["report", &t, "--params", "x.yaml"],
    ];
    for args in &cases {
        let r = run(args);
        assert_ne!(r.code, 0);
        assert!(has_hint(&r.stderr), "no hint in {args:?}: {}", r.stderr);
    }
}
