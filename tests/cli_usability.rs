//! What a new user trips over (issue #16, items 1, 4 and 6): options that
//! would do nothing are refused, `-` means standard input / output, every
//! hint names only options of the command that was run, common YAML
//! mistakes are explained with the fix, `--node` suggests the nearest name,
//! tables align with wide characters, `simulate` marks means from few runs,
//! and the shell completions and manual page work.
//!
//! Every expected line and column below was counted by hand in the fixture
//! (1-based, columns in characters).

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::{Command as StdCommand, Stdio};

use assert_cmd::Command;
use tempfile::TempDir;
use unicode_width::UnicodeWidthStr;

/// A path inside the crate.
fn repo(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(rel)
}

/// A file in its own temporary directory (removed on drop).
struct Fixture {
    _dir: TempDir,
    path: PathBuf,
}

fn fixture(name: &str, content: &str) -> Fixture {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join(name);
    std::fs::write(&path, content).unwrap();
    Fixture { _dir: dir, path }
}

fn btrel() -> Command {
    Command::new(env!("CARGO_BIN_EXE_btrel"))
}

const SG: &str = "trees/search-and-grasp.yaml";

/// Runs btrel; returns (exit code, stdout, stderr).
fn run(args: &[&str]) -> (i32, String, String) {
    let out = btrel().args(args).current_dir(repo(".")).output().unwrap();
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// Runs btrel with `input` on standard input.
fn run_stdin(args: &[&str], input: &[u8]) -> (i32, String, String) {
    let out = btrel()
        .args(args)
        .current_dir(repo("."))
        .write_stdin(input.to_vec())
        .output()
        .unwrap();
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// The command is refused as a usage error (exit 2, nothing on stdout)
/// with a message naming every one of `names`.
fn refused(args: &[&str], names: &[&str]) {
    let (code, out, err) = run(args);
    assert_eq!(code, 2, "{args:?}: exit code; stderr:\n{err}");
    assert!(out.is_empty(), "{args:?}: stdout must be empty:\n{out}");
    for n in names {
        assert!(err.contains(n), "{args:?}: stderr lacks {n:?}:\n{err}");
    }
}

// ---------------------------------------------------------------------------
// 1. options that do nothing are errors
// ---------------------------------------------------------------------------

#[test]
fn plot_options_that_need_compare_are_refused_without_it() {
    let svg = std::env::temp_dir().join("btrel-never-written.svg");
    // a leftover from another run must not decide the check below
    let _ = std::fs::remove_file(&svg);
    let svg = svg.to_str().unwrap();
    // (--deadline alone draws a deadline marker: tests/plot_output.rs)
    refused(
        &["plot", SG, "-o", svg, "--top", "3"],
        &["--compare", "--top"],
    );
    refused(
        &[
            "plot",
            SG,
            "-o",
            svg,
            "--compare",
            "search",
            "--timing",
            "both",
        ],
        &["--compare", "--timing"],
    );
    refused(
        &[
            "plot",
            SG,
            "-o",
            svg,
            "--compare",
            "search",
            "--timing",
            "deterministic",
        ],
        &["--compare", "--timing"],
    );
    refused(
        &[
            "plot",
            SG,
            "-o",
            svg,
            "--compare",
            "search",
            "--node",
            "grasp",
        ],
        &["--compare", "--node"],
    );
    assert!(!std::path::Path::new(svg).exists());
    // the defaults of --top and --timing do not count as given
    let (code, out, err) = run(&[
        "plot",
        SG,
        "-o",
        "-",
        "--compare",
        "search",
        "--points",
        "5",
    ]);
    assert_eq!(code, 0, "{err}");
    assert!(out.starts_with("<svg"), "{out}");
}

#[test]
fn curve_deterministic_timing_with_the_book_method_is_refused() {
    refused(
        &[
            "curve",
            SG,
            "--times",
            "100",
            "--timing",
            "deterministic",
            "--method",
            "book",
        ],
        &["--timing deterministic", "--method book"],
    );
    // each alone works
    assert_eq!(
        run(&["curve", SG, "--times", "100", "--method", "book"]).0,
        0
    );
    assert_eq!(
        run(&["curve", SG, "--times", "100", "--timing", "deterministic"]).0,
        0
    );
}

#[test]
fn monte_carlo_options_without_mc_are_refused() {
    for cmd in ["report", "curve"] {
        let times: &[&str] = if cmd == "curve" {
            &["--times", "1"]
        } else {
            &[]
        };
        for opt in [["--seed", "7"], ["--threads", "2"]] {
            let mut args = vec![cmd, SG];
            args.extend_from_slice(times);
            args.extend_from_slice(&opt);
            refused(&args, &["--mc", opt[0]]);
        }
    }
    // with --mc they are accepted; simulate takes them on its own
    assert_eq!(
        run(&[
            "report",
            SG,
            "--mc",
            "1000",
            "--seed",
            "7",
            "--threads",
            "1"
        ])
        .0,
        0
    );
    assert_eq!(
        run(&[
            "simulate",
            SG,
            "--runs",
            "1000",
            "--seed",
            "7",
            "--threads",
            "1"
        ])
        .0,
        0
    );
}

#[test]
fn export_options_of_the_other_format_are_refused() {
    refused(
        &["export", SG, "--to", "dot", "--node", "search"],
        &["--node", "--to prism"],
    );
    refused(
        &["export", SG, "--to", "prism", "--method", "book"],
        &["--method book", "--to prism"],
    );
    refused(
        &["export", SG, "--to", "prism", "--mrg", "search"],
        &["--mrg", "--to dot"],
    );
    refused(
        &["export", SG, "--to", "dot", "--properties", "p.csl"],
        &["--properties", "--to prism"],
    );
    assert!(!repo("p.csl").exists());
    // times go into a properties file: without one they would do nothing
    refused(
        &["export", SG, "--to", "prism", "--times", "100"],
        &["--properties"],
    );
    assert_eq!(run(&["export", SG, "--to", "dot", "--method", "book"]).0, 0);
    assert_eq!(
        run(&["export", SG, "--to", "prism", "--node", "search"]).0,
        0
    );
}

#[test]
fn a_zero_horizon_is_refused() {
    refused(&["curve", SG, "--t-end", "0"], &["--t-end", "> 0"]);
    refused(&["curve", SG, "--t-end", "0", "--dt", "1"], &["--t-end"]);
    refused(
        &["simulate", SG, "--runs", "100", "--t-end", "0"],
        &["--t-end"],
    );
    // the single time 0 is still available
    let (code, out, _) = run(&["curve", SG, "--times", "0"]);
    assert_eq!(code, 0);
    assert_eq!(out.lines().nth(1), Some("search and grasp,0,0,0,1"));
}

fn curve_times(out: &str) -> Vec<String> {
    out.lines()
        .skip(1)
        .map(|l| l.split(',').nth(1).unwrap().to_string())
        .collect()
}

#[test]
fn a_dt_grid_ends_at_t_end() {
    // 0, 30, 60, 90 and the end point 100 itself
    let (code, out, err) = run(&["curve", SG, "--t-end", "100", "--dt", "30"]);
    assert_eq!(code, 0, "{err}");
    assert_eq!(curve_times(&out), ["0", "30", "60", "90", "100"]);
    // a multiple of dt is not repeated
    let (_, out, _) = run(&["curve", SG, "--t-end", "90", "--dt", "30"]);
    assert_eq!(curve_times(&out), ["0", "30", "60", "90"]);
    // the help says so
    let (_, help, _) = run(&["curve", "--help"]);
    assert!(
        help.contains("T itself when it is not a multiple of D"),
        "{help}"
    );
}

#[test]
fn dash_output_is_standard_output() {
    let (_, plain, _) = run(&["report", SG]);
    let (code, dashed, err) = run(&["report", SG, "-o", "-"]);
    assert_eq!(code, 0, "{err}");
    assert_eq!(dashed, plain);
    assert!(!repo("-").exists(), "no file named '-' is created");
    let cases: &[&[&str]] = &[
        &["curve", SG, "--times", "1,10", "-o", "-"],
        &["compare", SG, "--node", "search", "-o", "-"],
        &["simulate", SG, "--runs", "1000", "-o", "-"],
        &["export", SG, "--to", "dot", "-o", "-"],
        &["man", "-o", "-"],
    ];
    for args in cases {
        let without: Vec<&str> = args[..args.len() - 2].to_vec();
        let (code, out, err) = run(args);
        assert_eq!(code, 0, "{args:?}: {err}");
        assert_eq!(out, run(&without).1, "{args:?}");
        assert!(!out.is_empty());
    }
    let (code, svg, err) = run(&["plot", SG, "-o", "-", "--points", "5"]);
    assert_eq!(code, 0, "{err}");
    assert!(svg.starts_with("<svg") && svg.trim_end().ends_with("</svg>"));
    assert!(!repo("-").exists());
}

#[test]
fn dash_tree_is_standard_input() {
    let yaml = std::fs::read(repo(SG)).unwrap();
    for args in [
        vec!["report"],
        vec!["report", "--format", "json"],
        vec!["curve", "--times", "10,100"],
        vec!["compare", "--node", "search"],
    ] {
        let mut from_file = args.clone();
        from_file.insert(1, SG);
        let mut from_stdin = args.clone();
        from_stdin.insert(1, "-");
        let (code, out, err) = run_stdin(&from_stdin, &yaml);
        assert_eq!(code, 0, "{from_stdin:?}: {err}");
        assert_eq!(out, run(&from_file).1, "{args:?}");
    }
    let (code, out, _) = run_stdin(&["check", "-"], &yaml);
    assert_eq!(code, 0);
    assert_eq!(out, "<stdin>: ok (12 nodes, 7 leaves)\n");
    // XML from standard input with its parameters file
    let xml = std::fs::read(repo("trees/search-and-grasp.xml")).unwrap();
    let params = "trees/search-and-grasp.params.yaml";
    let (code, out, err) = run_stdin(
        &["report", "-", "--input-format", "xml", "--params", params],
        &xml,
    );
    assert_eq!(code, 0, "{err}");
    assert_eq!(
        out,
        run(&["report", "trees/search-and-grasp.xml", "--params", params]).1
    );
    // ... whose default parameters path cannot be derived from `-`
    let (code, out, err) = run_stdin(&["report", "-", "--input-format", "xml"], &xml);
    assert_eq!(code, 2);
    assert!(out.is_empty());
    assert!(err.contains("--params"), "{err}");
    // a mistake on standard input is located like one in a file (2:25: `abc`)
    let (code, _, err) = run_stdin(
        &["report", "-"],
        b"tree:\n  action: {ps: 0.5, mu: abc, nu: 1}\n",
    );
    assert_eq!(code, 2);
    assert!(err.starts_with("error: <stdin>:2:25: "), "{err}");
}

const MAX_STATES_COMMANDS: &[&str] = &[
    "report",
    "curve",
    "compare",
    "plot",
    "export",
    "sensitivity",
];

#[test]
fn every_analysing_command_takes_max_states() {
    for cmd in MAX_STATES_COMMANDS {
        let (code, help, _) = run(&[cmd, "--help"]);
        assert_eq!(code, 0);
        assert!(help.contains("--max-states"), "{cmd} --help:\n{help}");
    }
    // a Parallel with an independent failure threshold needs its product
    // chain: 2 states are too few for every command
    let f = fixture(
        "independent.yaml",
        "tree: {parallel: {name: team, success_threshold: 2, failure_threshold: 1, children: \
         [{sequence: {children: [{action: {ps: 0.9, mu: 1, nu: 2}}, {action: {ps: 0.9, mu: 3, nu: 2}}]}}, {action: {ps: 0.8, mu: 2, nu: 1}}, {action: {ps: 0.7, mu: 1, nu: 1}}]}}\n",
    );
    let p = f.path.to_str().unwrap();
    for args in [
        vec!["report", p],
        vec!["curve", p, "--times", "1"],
        vec!["plot", p, "-o", "-", "--t-end", "5"],
        vec!["export", p, "--to", "prism"],
    ] {
        let mut small = args.clone();
        small.extend(["--max-states", "2"]);
        let (code, out, err) = run(&small);
        assert_eq!(code, 1, "{small:?}: {err}");
        assert!(out.is_empty());
        assert!(err.contains("--max-states"), "{small:?}: {err}");
        assert_eq!(run(&args).0, 0, "{args:?} with the default budget");
    }
}

// ---------------------------------------------------------------------------
// hints name only options of the command that was run
// ---------------------------------------------------------------------------

/// The `--flag` words of a message.
fn flags(text: &str) -> Vec<String> {
    text.split(|c: char| !(c.is_ascii_alphanumeric() || c == '-'))
        .filter(|w| w.starts_with("--") && w.len() > 2)
        .map(str::to_string)
        .collect()
}

/// Every flag named in `err` is an option of `cmd` (per its --help).
fn hints_are_options_of(cmd: &str, err: &str) {
    let (_, help, _) = run(&[cmd, "--help"]);
    let named = flags(err);
    assert!(
        !named.is_empty(),
        "{cmd}: the message names no option:\n{err}"
    );
    for f in named {
        assert!(
            help.contains(&format!("{f} "))
                || help.contains(&format!("{f}\n"))
                || help.contains(&format!("{f} <")),
            "`btrel {cmd}` has no {f}, but its error names it:\n{err}"
        );
    }
}

#[test]
fn analysis_hints_name_only_options_of_the_command() {
    // a mixed Parallel with an independent failure threshold inside a
    // Sequence, refused for a state budget of 1
    let mixed = fixture(
        "mixed.yaml",
        "tree: {sequence: {children: [{action: {ps: 0.9, mu: 1, nu: 1}}, {parallel: \
         {success_threshold: 2, failure_threshold: 1, children: [\
         {action: {name: timer, ps: 0.5, tau_s: 3, tau_f: 1}}, \
         {action: {ps: 0.8, mu: 2, nu: 4}}, {action: {ps: 0.7, mu: 1, nu: 1}}]}}]}}\n",
    );
    let m = mixed.path.to_str().unwrap();
    let (code, _, err) = run(&["curve", m, "--times", "1", "--max-states", "1"]);
    assert_eq!(code, 1, "{err}");
    assert!(
        err.contains("btrel simulate") && err.contains("--max-states 2"),
        "{err}"
    );
    hints_are_options_of("curve", &err);

    // a race with a fixed time that the shifted mixture holds, over a small
    // budget: the refusal names the budget and a larger one, which answers
    let race = fixture(
        "race.yaml",
        "tree: {sequence: {children: [{action: {ps: 0.9, mu: 1, nu: 1}}, {parallel: \
         {success_threshold: 1, failure_threshold: 1, children: [\
         {action: {name: timer, ps: 0.5, tau_s: 3, tau_f: 1}}, \
         {action: {ps: 0.8, mu: 2, nu: 4}}]}}]}}\n",
    );
    let r = race.path.to_str().unwrap();
    let mut budget = 1;
    let mut refusals = 0;
    loop {
        let b = budget.to_string();
        let (code, _, err) = run(&["curve", r, "--times", "1", "--max-states", &b]);
        if code == 0 {
            break;
        }
        assert_eq!(code, 1, "{err}");
        assert!(!err.contains("mixes deterministic"), "{err}");
        hints_are_options_of("curve", &err);
        let at = err
            .find("`--max-states ")
            .expect("a larger budget is named");
        let named: usize = err[at + 14..]
            .split('`')
            .next()
            .and_then(|n| n.parse().ok())
            .expect("a number");
        assert!(named > budget, "{err}");
        budget = named;
        refusals += 1;
        assert!(
            refusals < 5,
            "the named budgets do not reach an answer: {err}"
        );
    }
    assert!(refusals >= 1, "a budget of 1 is too small for this race");

    // a budget exceeded: report has --method and --max-states, no --timing
    let f = fixture(
        "independent.yaml",
        "tree: {parallel: {success_threshold: 2, failure_threshold: 1, children: \
         [{sequence: {children: [{action: {ps: 0.9, mu: 1, nu: 2}}, {action: {ps: 0.9, mu: 3, nu: 2}}]}}, {action: {ps: 0.8, mu: 2, nu: 1}}, {action: {ps: 0.7, mu: 1, nu: 1}}]}}\n",
    );
    let p = f.path.to_str().unwrap();
    for cmd in ["report", "curve", "plot", "export"] {
        let mut args = vec![cmd, p, "--max-states", "2"];
        match cmd {
            "curve" => args.extend(["--times", "1"]),
            "plot" => args.extend(["-o", "-", "--t-end", "5"]),
            "export" => args.extend(["--to", "prism"]),
            _ => {}
        }
        let (code, _, err) = run(&args);
        assert_eq!(code, 1, "{args:?}: {err}");
        hints_are_options_of(cmd, &err);
        // PRISM export has no --method: it exports the exact chain
        assert_eq!(
            err.contains("--method book"),
            cmd != "export",
            "{cmd}: {err}"
        );
    }
    // already under --method book: the hint does not suggest it again
    let (code, _, err) = run(&["report", "trees/drone-fleet.yaml", "--method", "book"]);
    assert_eq!(code, 1, "{err}");
    assert!(!err.contains("--method book"), "{err}");
    assert!(err.contains("--max-states"), "{err}");
    hints_are_options_of("report", &err);
}

#[test]
fn library_errors_name_no_command_line_options() {
    use btrel::compile::AnalysisError;
    let errors = [
        AnalysisError::NotMarkovian { leaf: "a".into() },
        AnalysisError::StateBudget {
            node: "n".into(),
            states: 1e9,
            budget: 10,
        },
        AnalysisError::Stiff {
            node: "n".into(),
            work: 1e12,
            limit: 1e11,
        },
        AnalysisError::Numerical {
            node: "n".into(),
            what: "x".into(),
        },
    ];
    for e in errors {
        let text = e.to_string();
        assert!(flags(&text).is_empty(), "{text}");
        assert!(!text.contains("btrel "), "{text}");
    }
}

// ---------------------------------------------------------------------------
// 4. messages
// ---------------------------------------------------------------------------

#[test]
fn unknown_node_names_get_did_you_mean() {
    refused(
        &["curve", SG, "--node", "serch", "--times", "1"],
        &["'serch'", "did you mean 'search'?"],
    );
    refused(
        &["compare", SG, "--node", "grsp"],
        &["did you mean 'grasp'?"],
    );
    refused(
        &["simulate", SG, "--node", "Search Floor"],
        &["did you mean 'search floor'?"],
    );
    // nothing close: a small tree lists its nodes
    let f = fixture(
        "two.yaml",
        "tree: {fallback: {name: root, children: [{action: {name: go, ps: 0.5, mu: 1, nu: 1}}]}}\n",
    );
    let p = f.path.to_str().unwrap();
    refused(
        &["curve", p, "--node", "xylophone", "--times", "1"],
        &["give one of root, go, or a path"],
    );
}

#[test]
fn articles_and_plurals() {
    // compare and export name the node's kind with the right article
    refused(
        &["compare", SG, "--node", "search floor"],
        &["is an action", "Fallback"],
    );
    refused(
        &["compare", SG, "--node", "search and grasp"],
        &["is a sequence"],
    );
    refused(
        &["export", SG, "--to", "dot", "--mrg", "search floor"],
        &["is an action", "--mrg"],
    );
    let f = fixture("one.yaml", "tree: {action: {ps: 0.5, mu: 1, nu: 1}}\n");
    let (code, out, _) = run(&["check", f.path.to_str().unwrap()]);
    assert_eq!(code, 0);
    assert!(out.ends_with(": ok (1 node, 1 leaf)\n"), "{out}");
}

/// The tree is refused at `(line, column)` with all of `phrases`, and
/// without the parser's own words `raw`.
fn yaml_mistake(yaml: &str, (line, column): (usize, usize), phrases: &[&str], raw: &str) {
    let f = fixture("mistake.yaml", yaml);
    let p = f.path.to_str().unwrap();
    let (code, out, err) = run(&["check", p]);
    assert_eq!(code, 2, "{err}");
    assert!(out.is_empty());
    assert!(
        err.starts_with(&format!("error: {p}:{line}:{column}: ")),
        "expected {line}:{column}:\n{err}"
    );
    for ph in phrases {
        assert!(err.contains(ph), "lacks {ph:?}:\n{err}");
    }
    assert!(
        !err.contains(raw),
        "the parser's raw text {raw:?} is shown:\n{err}"
    );
    assert!(err.contains("help: "), "{err}");
}

#[test]
fn a_list_under_child_or_tree() {
    // line 4 "      - action: ..." : the `-` is at column 7
    yaml_mistake(
        "tree:\n  inverter:\n    child:\n      - action: {ps: 0.5, mu: 1, nu: 1}\n",
        (4, 7),
        &["`child:` takes one node, not a list", "remove the `- `"],
        "externally tagged enum",
    );
    // "    child: [{" : the `[` is at column 12
    yaml_mistake(
        "tree:\n  inverter:\n    child: [{action: {ps: 0.5, mu: 1, nu: 1}}]\n",
        (3, 12),
        &["`child:` takes one node"],
        "externally tagged enum",
    );
    yaml_mistake(
        "tree:\n  - action: {ps: 0.5, mu: 1, nu: 1}\n",
        (2, 3),
        &["`tree:` takes the root node, not a list", "children:"],
        "externally tagged enum",
    );
}

#[test]
fn two_node_kinds_under_one_key() {
    // line 5 "        condition: ..." starts at column 9; the first kind is on line 4
    yaml_mistake(
        "tree:\n  sequence:\n    children:\n      - action: {ps: 0.5, mu: 1, nu: 1}\n        condition: {ps: 0.5}\n",
        (5, 9),
        &["two node kinds in one node: `action` (line 4) and `condition`", "children:", "- "],
        "expected end of mapping",
    );
    // a node key at the kind's level: `name` (line 5, column 9)
    yaml_mistake(
        "tree:\n  sequence:\n    children:\n      - action: {ps: 0.5, mu: 1, nu: 1}\n        name: x\n",
        (5, 9),
        &["`name` is next to the node kind `action` (line 4), not inside it", "indent `name:` further"],
        "expected end of mapping",
    );
    // the same kind twice: `action` at 3:3
    yaml_mistake(
        "tree:\n  action: {ps: 0.5, mu: 1, nu: 1}\n  action: {ps: 0.2, mu: 1, nu: 1}\n",
        (3, 3),
        &[
            "the node kind `action` appears twice in one node (line 2 and line 3)",
            "children:",
        ],
        "expected end of mapping",
    );
}

#[test]
fn tabs_in_the_indentation() {
    // line 2 starts with a tab (column 1); line 4 has 4 spaces then a tab (column 5)
    yaml_mistake(
        "tree:\n\tsequence:\n\t\tchildren:\n\t\t\t- action: {ps: 0.5, mu: 1, nu: 1}\n",
        (2, 1),
        &["a tab indents this line", "spaces"],
        "disallowed",
    );
    yaml_mistake(
        "tree:\n  sequence:\n    children:\n    \t- action: {ps: 0.5, mu: 1, nu: 1}\n",
        (4, 5),
        &["a tab indents this line"],
        "disallowed",
    );
}

#[test]
fn bad_indentation() {
    // line 5 has 5 spaces; its sibling on line 4 has 6
    yaml_mistake(
        "tree:\n  sequence:\n    children:\n      - action: {ps: 0.5, mu: 1, nu: 1}\n     - action: {ps: 0.5, mu: 1, nu: 1}\n",
        (5, 6),
        &["line 5 is indented 5 spaces", "6 like line 4"],
        "did not find expected key",
    );
    // a key with 3 spaces between blocks indented 4 (line 3) and 2 (line 2)
    yaml_mistake(
        "tree:\n  sequence:\n    children:\n      - action: {ps: 0.5, mu: 1, nu: 1}\n   name: x\n",
        (5, 4),
        &[
            "line 5 is indented 3 spaces",
            "4 like line 3 (`children:`)",
            "2 like line 2 (`sequence:`)",
        ],
        "did not find expected key",
    );
    // keys not indented under their kind: `action:` (4:9) has none
    yaml_mistake(
        "tree:\n  sequence:\n    children:\n      - action:\n        ps: 0.5\n        mu: 1\n",
        (4, 9),
        &["`action:` has no keys", "2 more spaces", "action: {ps: 0.5"],
        "expected mapping start",
    );
    // a kind written without a colon: `action` at 4:9
    yaml_mistake(
        "tree:\n  sequence:\n    children:\n      - action\n",
        (4, 9),
        &["`action` is written without its keys"],
        "expected mapping start",
    );
    // children as a mapping instead of a list: 4:7
    yaml_mistake(
        "tree:\n  sequence:\n    children:\n      action: {ps: 0.5, mu: 1, nu: 1}\n",
        (4, 7),
        &["`children:` takes a list of nodes", "- action"],
        "expected sequence start",
    );
    // a node written without its kind: `ps` at 4:10
    yaml_mistake(
        "tree:\n  sequence:\n    children:\n      - {ps: 0.5, mu: 1, nu: 1}\n",
        (4, 10),
        &["unknown node kind `ps`", "write the node's kind first"],
        "expected one of",
    );
}

const COMMANDS: &[&str] = &[
    "report",
    "curve",
    "compare",
    "simulate",
    "plot",
    "export",
    "check",
    "sensitivity",
];

#[test]
fn every_command_help_has_its_examples_and_says_tree_may_be_xml() {
    for cmd in COMMANDS {
        let (code, help, _) = run(&[cmd, "--help"]);
        assert_eq!(code, 0);
        assert!(help.contains("Examples:"), "{cmd}:\n{help}");
        assert!(
            help.contains(&format!("btrel {cmd} trees/")),
            "{cmd}: no example of itself:\n{help}"
        );
        assert!(help.contains("XML"), "{cmd}: TREE may be XML:\n{help}");
        assert!(
            help.contains(".xml"),
            "{cmd}: an XML example or extension:\n{help}"
        );
        assert!(
            help.contains("standard input"),
            "{cmd}: TREE may be -:\n{help}"
        );
    }
}

#[test]
fn threads_help_shows_the_real_default() {
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let help = |cmd: &str, env: Option<&str>| {
        let mut c = btrel();
        c.args([cmd, "--help"]).env_remove("RAYON_NUM_THREADS");
        if let Some(n) = env {
            c.env("RAYON_NUM_THREADS", n);
        }
        String::from_utf8(c.output().unwrap().stdout).unwrap()
    };
    for cmd in ["simulate", "report", "curve", "plot"] {
        let text = help(cmd, None);
        assert!(
            text.contains(&format!("[default: {cores}, one per core]")),
            "{cmd}:\n{text}"
        );
        // rayon's pool honours RAYON_NUM_THREADS, and so does the help
        let text = help(cmd, Some("3"));
        assert!(
            text.contains("[default: 3, from RAYON_NUM_THREADS]"),
            "{cmd}:\n{text}"
        );
    }
}

/// A Fallback of one action: with `runs` runs, its MTTS rests on the
/// successful ones only.
const RARE: &str =
    "tree: {fallback: {name: root, children: [{action: {name: rare, ps: 0.5, mu: 1, nu: 2}}]}}\n";

#[test]
fn simulate_marks_means_from_few_runs() {
    let f = fixture("rare.yaml", RARE);
    let p = f.path.to_str().unwrap();
    // 20 runs: at most 20 successes and 20 failures, so every mean time is marked
    let (code, table, err) = run(&["simulate", p, "--runs", "20"]);
    assert_eq!(code, 0, "{err}");
    let (_, json, _) = run(&["simulate", p, "--runs", "20", "--format", "json"]);
    let v: serde_json::Value = serde_json::from_str(&json).unwrap();
    let root = &v["nodes"][0];
    let s = root["mtts_runs"].as_u64().unwrap();
    let fl = root["mttf_runs"].as_u64().unwrap();
    assert_eq!(s + fl, 20);
    let row = table
        .lines()
        .skip(2)
        .find(|l| l.starts_with("root"))
        .unwrap();
    assert!(row.contains(&format!("[{s} runs]")), "{table}");
    assert!(row.contains(&format!("[{fl} runs]")), "{table}");
    assert!(table.contains("fewer than 30"), "{table}");
    // 10,000 runs: thousands of each, nothing marked
    let (_, table, _) = run(&["simulate", p, "--runs", "10000"]);
    assert!(!table.contains(" runs]"), "{table}");
    assert!(!table.contains("fewer than 30"), "{table}");
}

/// Display column (terminal cells) where `needle` starts in `line`.
fn display_column(line: &str, needle: &str) -> usize {
    let i = line
        .find(needle)
        .unwrap_or_else(|| panic!("{needle:?} not in {line:?}"));
    UnicodeWidthStr::width(&line[..i])
}

#[test]
fn tables_align_with_wide_characters() {
    let yaml = "name: 探索と把持\ntree:\n  sequence:\n    name: 探索と把持\n    children:\n      \
                - action: {name: 探す, ps: 0.5, mu: 1, nu: 1}\n      \
                - action: {name: grasp, ps: 0.5, mu: 1, nu: 1}\n      \
                - action: {name: 物体を掴む動作, ps: 0.5, mu: 1, nu: 1}\n";
    let f = fixture("cjk.yaml", yaml);
    let p = f.path.to_str().unwrap();
    let (code, table, err) = run(&["report", p]);
    assert_eq!(code, 0, "{err}");
    let lines: Vec<&str> = table.lines().skip(1).collect();
    assert_eq!(lines.len(), 5, "{table}");
    // the kind column starts at one display column in every row ...
    let kind_col = display_column(lines[0], "kind");
    for (l, kind) in lines[1..]
        .iter()
        .zip(["sequence", "action", "action", "action"])
    {
        assert_eq!(display_column(l, kind), kind_col, "{table}");
    }
    // ... and the right-aligned numbers end at one display column
    let width = UnicodeWidthStr::width(lines[0]);
    for l in &lines {
        assert_eq!(UnicodeWidthStr::width(*l), width, "{table}");
    }
    // the simulation table too
    let (_, table, _) = run(&["simulate", p, "--runs", "1000"]);
    let lines: Vec<&str> = table.lines().skip(1).collect();
    let kind_col = display_column(lines[0], "kind");
    for (l, kind) in lines[1..]
        .iter()
        .zip(["sequence", "action", "action", "action"])
    {
        assert_eq!(display_column(l, kind), kind_col, "{table}");
    }
}

// ---------------------------------------------------------------------------
// 6. shell completions and manual page
// ---------------------------------------------------------------------------

fn have(program: &str) -> bool {
    StdCommand::new(program)
        .arg("--version")
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .is_ok()
}

/// Checks a script's syntax with `shell -n` when that shell is installed.
fn syntax_ok(shell: &str, script: &str) {
    if !have(shell) {
        println!("note: {shell} is not installed; its completion script's syntax is not checked");
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("completion");
    std::fs::write(&path, script).unwrap();
    let out = StdCommand::new(shell)
        .arg("-n")
        .arg(&path)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{shell} -n: {}",
        String::from_utf8_lossy(&out.stderr)
    );
}

#[test]
fn completions_cover_every_command() {
    for shell in ["bash", "zsh", "fish"] {
        let (code, script, err) = run(&["completions", shell]);
        assert_eq!(code, 0, "{err}");
        for cmd in COMMANDS.iter().chain(&["completions", "man"]) {
            assert!(script.contains(cmd), "{shell}: no {cmd}");
        }
        for opt in ["max-states", "t-end", "input-format"] {
            assert!(script.contains(opt), "{shell}: no --{opt}");
        }
        syntax_ok(shell, &script);
    }
    // bash: the script defines its completion function and registers it
    let (_, bash, _) = run(&["completions", "bash"]);
    assert!(bash.contains("complete -F _btrel"), "{bash}");
    if have("bash") {
        // sourcing it and asking for the words after `btrel ` lists the commands
        let mut child = StdCommand::new("bash")
            .arg("--norc")
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .spawn()
            .unwrap();
        write!(
            child.stdin.take().unwrap(),
            "{bash}\nCOMP_WORDS=(btrel \"\"); COMP_CWORD=1; COMP_LINE='btrel '; COMP_POINT=6; _btrel btrel '' btrel; printf '%s\\n' \"${{COMPREPLY[@]}}\"\n"
        )
        .unwrap();
        let out = child.wait_with_output().unwrap();
        let words = String::from_utf8_lossy(&out.stdout);
        for cmd in COMMANDS {
            assert!(
                words.lines().any(|w| w == *cmd),
                "bash completes {cmd}: {words}"
            );
        }
    }
    refused(&["completions", "tcsh"], &["tcsh"]);
}

#[test]
fn man_page_renders() {
    let (code, page, err) = run(&["man"]);
    assert_eq!(code, 0, "{err}");
    assert!(
        page.starts_with(".ie") || page.contains(".TH btrel 1"),
        "{page}"
    );
    for cmd in COMMANDS {
        assert!(page.contains(cmd), "the page lists {cmd}");
    }
    let (code, sub, _) = run(&["man", "report"]);
    assert_eq!(code, 0);
    assert!(sub.contains(".TH btrel-report 1"), "{sub}");
    assert!(sub.contains("max\\-states"), "{sub}");
    refused(&["man", "frobnicate"], &["frobnicate", "report"]);
    if !have("groff") {
        println!("note: groff is not installed; the page is checked as roff text only");
        return;
    }
    for roff in [page, sub] {
        let mut child = StdCommand::new("groff")
            .args(["-k", "-man", "-Tutf8", "-ww", "-P", "-cbou"])
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        child
            .stdin
            .take()
            .unwrap()
            .write_all(roff.as_bytes())
            .unwrap();
        let out = child.wait_with_output().unwrap();
        assert!(out.status.success());
        let text = String::from_utf8_lossy(&out.stdout);
        let warnings = String::from_utf8_lossy(&out.stderr);
        assert!(warnings.trim().is_empty(), "groff warns: {warnings}");
        assert!(text.contains("NAME") && text.contains("SYNOPSIS"), "{text}");
        assert!(text.contains("btrel"), "{text}");
    }
}

/// The example lines `btrel CMD ...` of `CMD --help` (comments removed).
fn examples_of(cmd: &str) -> Vec<String> {
    let (_, help, _) = run(&[cmd, "--help"]);
    let section = help.split("Examples:").nth(1).unwrap_or("");
    section
        .lines()
        .map(|l| l.split("  #").next().unwrap().trim().to_string())
        .filter(|l| l.starts_with(&format!("btrel {cmd} ")))
        .collect()
}

#[test]
fn every_help_example_runs() {
    let dir = tempfile::tempdir().unwrap();
    let mut ran = 0;
    for cmd in COMMANDS.iter().chain(&["completions", "man"]) {
        for line in examples_of(cmd) {
            // the words (shell quoting: `--require 'ps >= 0.9'` is one) before a
            // shell pipe, redirection or `&&`
            let all = shlex::split(&line).unwrap_or_else(|| panic!("`{line}`: unbalanced quotes"));
            let end = all
                .iter()
                .position(|w| matches!(w.as_str(), "|" | "&&") || w.starts_with('>'))
                .unwrap_or(all.len());
            let words: Vec<&str> = all[1..end].iter().map(String::as_str).collect();
            if words.contains(&"-") && words.get(1) == Some(&"-") {
                continue; // reads standard input
            }
            let mut args: Vec<String> = Vec::new();
            let mut out_next = false;
            for w in words {
                if out_next && w != "-" {
                    // outputs go to the temporary directory
                    let name = Path::new(w).file_name().unwrap();
                    args.push(dir.path().join(name).to_string_lossy().into_owned());
                } else {
                    args.push(w.to_string());
                }
                out_next = matches!(w, "-o" | "--curves" | "--properties");
            }
            let refs: Vec<&str> = args.iter().map(String::as_str).collect();
            let (code, _, err) = run(&refs);
            assert_eq!(code, 0, "`{line}` fails:\n{err}");
            ran += 1;
        }
    }
    assert!(ran >= 25, "only {ran} examples found");
}

#[test]
fn tree_options_are_refused_where_no_tree_is_read() {
    for args in [
        &["completions", "bash", "--params", "x.yaml"][..],
        &["man", "--input-format", "xml"][..],
        &["completions", "zsh", "--include", "trees"][..],
    ] {
        refused(args, &["--params", "--include"]);
    }
}
