//! `btrel check --require`: requirements parsed with located errors, decided
//! by the exact engine against closed forms, by `--ci` bounds, and by the
//! sequential tests (`--mc`) whose error rates are checked over repeated
//! seeds on trees with exact ps just above and below the threshold.

mod common;

use btrel::gate::{self, Figure, Op, TestSettings};
use btrel::sim::sequential::Decision;
use btrel::Tree;
use common::{run_btrel, tree};

const SG: &str = "trees/search-and-grasp.yaml";

/// Search and grasp (the book's Example 9.9, with the file's errata) by
/// hand: P(find) = 1 − 0.7·0.2·0.8 = 0.888, P(grasp) = 1 − 0.9·0.5 = 0.55.
const SG_PS: f64 = 0.888 * 0.55;
/// MTTS of `search`: (0.3·(1/0.0167) + 0.7·0.8·(100 + 100) + 0.7·0.2·0.2·(100
/// + 100 + 200)) / 0.888.
fn sg_search_mtts() -> f64 {
    (0.3 / 0.0167 + 0.56 * 200.0 + 0.028 * 400.0) / 0.888
}

/// A Fallback of two exponential actions with success probabilities `a`
/// and `b`: P(S) = 1 − (1−a)(1−b).
fn fallback(a: f64, b: f64) -> Tree {
    tree(&format!(
        "tree:\n  fallback:\n    name: root\n    children:\n      - action: {{name: a, ps: {a}, mu: 1.0, nu: 2.0}}\n      - action: {{name: b, ps: {b}, mu: 0.5, nu: 1.0}}\n"
    ))
}

#[test]
fn requirements_parse() {
    let t = common::tree(&std::fs::read_to_string(SG).expect("tree"));
    let r = gate::parse("  ps >= 0.95 ", &t).expect("parses");
    assert_eq!(
        (r.node, r.figure, r.op, r.threshold, r.text.as_str()),
        (Tree::ROOT, Figure::Ps, Op::Ge, 0.95, "ps >= 0.95")
    );
    let r = gate::parse("search and grasp.mtts<=90", &t).expect("a name with spaces");
    assert_eq!((r.node, r.figure, r.op), (0, Figure::Mtts, Op::Le));
    let r = gate::parse("'search'.success_by(120.5) > 0.8", &t).expect("quoted");
    assert_eq!(t.node(r.node).name, "search");
    assert_eq!((r.figure, r.op), (Figure::SuccessBy(120.5), Op::Gt));
    let r = gate::parse("0.1.failure_by(0) < 1e-3", &t).expect("a path");
    assert_eq!(t.node(r.node).path, "0.1");
    assert_eq!((r.figure, r.threshold), (Figure::FailureBy(0.0), 1e-3));
    let r = gate::parse("grasp.never ≤ 0", &t).expect("unicode operator");
    assert_eq!((r.figure, r.op), (Figure::Never, Op::Le));
}

#[test]
fn errors_are_located_in_the_expression() {
    let t = common::tree(&std::fs::read_to_string(SG).expect("tree"));
    // (expression, column, width, words of the message, words of the help)
    let cases = [
        (
            "serch.ps >= 0.5",
            1,
            5,
            "no node named 'serch'",
            "did you mean 'search'?",
        ),
        (
            "ps => 0.5",
            4,
            2,
            "unknown operator '=>'",
            "did you mean '>='?",
        ),
        ("ps == 0.5", 4, 2, "unknown operator '=='", ">=, <=, > or <"),
        (
            "search.pz >= 0.5",
            8,
            2,
            "unknown figure 'pz'",
            "did you mean 'p",
        ),
        (
            "search >= 0.5",
            1,
            6,
            "unknown figure 'search'",
            "'search' is a node",
        ),
        ("ps >= abc", 7, 3, "'abc' is not a number", "0.95"),
        ("ps >=", 6, 1, "expected a number after '>='", "0.95"),
        (
            "success_by(x) >= 0.5",
            12,
            1,
            "'x' is not a time",
            "success_by(120)",
        ),
        (
            "success_by >= 0.5",
            1,
            10,
            "needs a time in parentheses",
            "success_by(120)",
        ),
        ("ps(3) >= 0.5", 3, 3, "ps takes no time", "success_by(T)"),
        ("ps 0.5", 1, 6, "no comparison", "FIGURE OP NUMBER"),
        (
            "search ps >= 0.5",
            7,
            1,
            "expected '.' between the node and the figure",
            "NODE.FIGURE",
        ),
    ];
    for (text, column, width, message, help) in cases {
        let e = gate::parse(text, &t).expect_err(text);
        assert_eq!((e.column, e.width), (column, width), "{text}: {e}");
        assert!(e.message.contains(message), "{text}: {e}");
        assert!(
            e.help.as_deref().unwrap_or("").contains(help),
            "{text}: {e}"
        );
        // the caret line marks the columns
        let caret = e
            .to_string()
            .lines()
            .nth(2)
            .expect("caret line")
            .to_string();
        assert_eq!(
            caret,
            format!("  {}{}", " ".repeat(column - 1), "^".repeat(width)),
            "{text}"
        );
    }
}

#[test]
fn cli_errors_exit_2_with_the_caret() {
    let (code, out, err) = run_btrel(&[
        "check",
        SG,
        "--require",
        "ps >= 0.4",
        "--require",
        "grasp.mtts =< 20",
    ]);
    assert_eq!(code, 2);
    assert!(
        out.is_empty(),
        "nothing decided before every requirement parses"
    );
    assert_eq!(
        err,
        "error: --require 'grasp.mtts =< 20', column 12: unknown operator '=<'\n  grasp.mtts =< 20\n             ^^\n  help: did you mean '<='?\n"
    );
    for (args, needle) in [
        (
            vec!["check", SG, "--alpha", "0.1", "--require", "ps >= 0.4"],
            "--mc",
        ),
        (vec!["check", SG, "--mc"], "--require"),
        (vec!["check", SG, "--ci"], "--require"),
        (
            vec!["check", SG, "--require", "ps >= 0.4", "--mc", "--ci"],
            "give one of them",
        ),
        (
            vec!["check", SG, "--require", "ps >= 0.995", "--mc"],
            "indifference region [0.985, 1.005]",
        ),
        (
            vec![
                "check",
                SG,
                "--require",
                "ps >= 0.4",
                "--mc",
                "--alpha",
                "0.7",
                "--beta",
                "0.5",
            ],
            "sum below 1",
        ),
        (
            vec!["check", SG, "--require", "nowhere.ps >= 0.4"],
            "no node named 'nowhere'",
        ),
    ] {
        let (code, out, err) = run_btrel(&args);
        assert_eq!(code, 2, "{args:?}: {err}");
        assert!(out.is_empty(), "{args:?}");
        assert!(err.contains(needle), "{args:?}: {err}");
    }
}

#[test]
fn exact_values_against_closed_forms() {
    let t = common::tree(&std::fs::read_to_string(SG).expect("tree"));
    let reqs: Vec<_> = [
        "ps >= 0.4",
        "pf <= 0.6",
        "search.mtts <= 200",
        "grasp.mttf <= 30",
        "never <= 0.01",
    ]
    .iter()
    .map(|s| gate::parse(s, &t).expect("parses"))
    .collect();
    let v = gate::exact_values(&t, &reqs, &Default::default()).expect("analysed");
    let close = |a: f64, b: f64| (a - b).abs() <= 1e-9 * b.abs().max(1.0);
    assert!(close(v[0].unwrap(), SG_PS), "{v:?}");
    assert!(close(v[1].unwrap(), 1.0 - SG_PS), "{v:?}");
    assert!(close(v[2].unwrap(), sg_search_mtts()), "{v:?}");
    // grasp fails after both hands failed: 1/2 + 1/0.05
    assert!(close(v[3].unwrap(), 20.5), "{v:?}");
    assert!(v[4].unwrap().abs() < 1e-12, "{v:?}");
    // P(success by t) of one exponential action: ps (1 − e^{−mu t})
    let one = tree("tree:\n  action: {name: go, ps: 0.7, mu: 0.1, nu: 0.2}\n");
    let reqs: Vec<_> = [
        "success_by(10) >= 0.5",
        "failure_by(10) <= 0.5",
        "go.success_by(0) >= 0",
    ]
    .iter()
    .map(|s| gate::parse(s, &one).expect("parses"))
    .collect();
    let v = gate::exact_values(&one, &reqs, &Default::default()).expect("curve");
    assert!(close(v[0].unwrap(), 0.7 * (1.0 - (-1.0f64).exp())), "{v:?}");
    assert!(close(v[1].unwrap(), 0.3 * (1.0 - (-2.0f64).exp())), "{v:?}");
    assert_eq!(v[2], Some(0.0));
    // a condition that never succeeds has no MTTS
    let r = gate::parse("object grasped.mtts <= 1", &t).expect("parses");
    assert_eq!(
        gate::exact_values(&t, &[r], &Default::default()).expect("ok"),
        [None]
    );
}

#[test]
fn cli_gate_exits_0_when_all_hold_and_1_when_one_fails() {
    let (code, out, err) = run_btrel(&[
        "check",
        SG,
        "--require",
        "ps >= 0.488",
        "--require",
        "search.mtts <= 159",
    ]);
    assert_eq!(code, 0, "{err}");
    assert_eq!(
        out,
        "PASS  ps >= 0.488: 0.48840 (exact)\nPASS  search.mtts <= 159: 158.97 s (exact)\n"
    );
    let (code, out, err) = run_btrel(&[
        "check",
        SG,
        "--require",
        "ps >= 0.489",
        "--require",
        "search.mtts <= 158.9",
        "--require",
        "object grasped.mtts <= 1",
    ]);
    assert_eq!(code, 1);
    assert_eq!(
        out,
        "FAIL  ps >= 0.489: 0.48840 (exact)\nFAIL  search.mtts <= 158.9: 158.97 s (exact)\nFAIL  object grasped.mtts <= 1: undefined (exact)\n"
    );
    assert_eq!(err, "error: 3 of 3 requirements failed\n");
    // without --require: the validation it always was
    let (code, out, _) = run_btrel(&["check", SG]);
    assert_eq!(code, 0);
    assert_eq!(
        out,
        "trees/search-and-grasp.yaml: ok (12 nodes, 7 leaves)\n"
    );
}

#[test]
fn ci_gate_uses_the_lower_or_upper_bound_of_report_ci() {
    let xml = "trees/search-and-grasp.xml";
    let params = "docs/fit/search-and-grasp.fitted.params.yaml";
    let (code, out, _) = run_btrel(&[
        "report", xml, "--params", params, "--ci", "--format", "json",
    ]);
    assert_eq!(code, 0);
    let v: serde_json::Value = serde_json::from_str(&out).expect("JSON");
    let root = &v["nodes"][0];
    let ps_lo = root["ci"]["ps"][0].as_f64().unwrap();
    let mtts_hi = root["ci"]["mtts"][1].as_f64().unwrap();
    let pass = format!("ps >= {}", ps_lo - 1e-6);
    let fail = format!("ps >= {}", ps_lo + 1e-6);
    let mtts = format!("mtts <= {}", mtts_hi + 1e-6);
    let (code, out, err) = run_btrel(&[
        "check",
        xml,
        "--params",
        params,
        "--ci",
        "--require",
        &pass,
        "--require",
        &mtts,
    ]);
    assert_eq!(code, 0, "{err}");
    let lines: Vec<&str> = out.lines().collect();
    assert!(
        lines[0].starts_with("PASS  ps >= ") && lines[0].contains("lower bound"),
        "{out}"
    );
    assert!(
        lines[1].starts_with("PASS  mtts <= ") && lines[1].contains("upper bound"),
        "{out}"
    );
    assert!(err.contains("note: 95% intervals from 1000 draws"), "{err}");
    let (code, out, _) = run_btrel(&["check", xml, "--params", params, "--ci", "--require", &fail]);
    assert_eq!(code, 1);
    assert!(out.starts_with("FAIL  ps >= "), "{out}");
    // a YAML tree has no fitted statistics
    let (code, _, err) = run_btrel(&["check", SG, "--ci", "--require", "ps >= 0.1"]);
    assert_eq!(code, 2);
    assert!(err.contains("--ci needs fitted parameters"), "{err}");
}

/// Runs the SPRT of `text` on `tree` over `reps` seeds: how often it
/// decided each way, and the mean number of runs.
fn sprt_rates(tree: &Tree, text: &str, reps: u64) -> (usize, usize, f64) {
    let r = gate::parse(text, tree).expect("parses");
    let (mut holds, mut fails, mut runs) = (0, 0, 0u64);
    for seed in 0..reps {
        let s = TestSettings {
            seed,
            ..Default::default()
        };
        let t = gate::test(tree, &r, 0, &s).expect("tests");
        match t.decision {
            Decision::Holds => holds += 1,
            Decision::Fails => fails += 1,
            Decision::Undecided => panic!("undecided after {} runs", t.runs),
        }
        runs += t.runs;
    }
    (holds, fails, runs as f64 / reps as f64)
}

/// The observed rate `k / reps` is at most `bound + 3·SE`.
fn assert_rate_at_most(what: &str, k: usize, reps: u64, bound: f64) {
    let se = (bound * (1.0 - bound) / reps as f64).sqrt();
    let rate = k as f64 / reps as f64;
    eprintln!("{what}: {k}/{reps} = {rate:.3} (bound {bound:.4})");
    assert!(
        rate <= bound + 3.0 * se,
        "{what}: {k} of {reps} = {rate:.3}, above {bound:.4} + 3 SE"
    );
}

#[test]
fn sprt_error_rates_just_above_and_below_the_threshold() {
    // θ = 0.9, δ = 0.01 (default), α = β = 0.05: Wald's bounds α/(1−β)
    let bound = 0.05 / 0.95;
    let reps = 200;
    // exact ps = 1 − 0.3·0.3 = 0.91 = θ + δ: the requirement holds with margin
    let above = fallback(0.7, 0.7);
    let (_, fails, runs) = sprt_rates(&above, "ps >= 0.9", reps);
    eprintln!("mean runs at 0.91: {runs:.0}");
    assert_rate_at_most("failed at ps = 0.91", fails, reps, bound);
    // exact ps = 1 − 0.5·0.22 = 0.89 = θ − δ: it fails by the margin
    let below = fallback(0.5, 0.78);
    let (holds, _, _) = sprt_rates(&below, "ps >= 0.9", reps);
    assert_rate_at_most("passed at ps = 0.89", holds, reps, bound);
    // the mirror image, `pf <= 0.1`: pf = 0.09 holds, 0.11 fails
    let (_, fails, _) = sprt_rates(&above, "pf <= 0.1", reps);
    assert_rate_at_most("failed at pf = 0.09", fails, reps, bound);
    let (holds, _, _) = sprt_rates(&below, "pf <= 0.1", reps);
    assert_rate_at_most("passed at pf = 0.11", holds, reps, bound);
    // far from the threshold it is right every time, and quickly
    let (holds, _, runs) = sprt_rates(&fallback(0.8, 0.8), "ps >= 0.9", 50);
    assert_eq!(holds, 50);
    assert!(runs <= 4096.0, "{runs}");
}

#[test]
fn mean_time_test_error_rates_at_the_margin() {
    // Sequence of two exponential actions with ps 1: MTTS = 1/1 + 1/0.5 = 3 s
    // (variance 5)
    let t = tree(
        "tree:\n  sequence:\n    name: root\n    children:\n      - action: {name: a, ps: 1.0, mu: 1.0, nu: 2.0}\n      - action: {name: b, ps: 1.0, mu: 0.5, nu: 1.0}\n",
    );
    let reps = 200;
    let s = |seed| TestSettings {
        seed,
        time_indifference: Some(0.1),
        ..Default::default()
    };
    let bound = 0.05;
    for (text, wrong) in [
        ("mtts <= 3.1", Decision::Fails),
        ("mtts <= 2.9", Decision::Holds),
        ("mtts >= 2.9", Decision::Fails),
    ] {
        let r = gate::parse(text, &t).expect("parses");
        let mut k = 0;
        for seed in 0..reps {
            let o = gate::test(&t, &r, 0, &s(seed)).expect("tests");
            assert_ne!(o.decision, Decision::Undecided);
            assert!(o.half_width.unwrap() <= 0.1, "{o:?}");
            k += usize::from(o.decision == wrong);
        }
        assert_rate_at_most(text, k, reps, bound);
    }
}

#[test]
fn cli_mc_prints_the_decision_and_runs_whatever_the_threads() {
    let args = |threads: &'static str| {
        vec![
            "check",
            SG,
            "--mc",
            "--seed",
            "3",
            "--threads",
            threads,
            "--require",
            "ps >= 0.45",
            "--require",
            "search.mtts <= 170",
            "--require",
            "success_by(100) <= 0.1",
        ]
    };
    let (code, one, err) = run_btrel(&args("1"));
    assert_eq!(code, 1, "{err}");
    let (_, two, _) = run_btrel(&args("2"));
    assert_eq!(one, two);
    let lines: Vec<&str> = one.lines().collect();
    assert_eq!(lines.len(), 3, "{one}");
    assert!(
        lines[0].starts_with("PASS  ps >= 0.45: ")
            && lines[0].contains(" runs (SPRT of p >= 0.46 against p <= 0.44, α = 0.05, β = 0.05)"),
        "{one}"
    );
    assert!(
        lines[1].starts_with("PASS  search.mtts <= 170: ") && lines[1].contains("Chow–Robbins"),
        "{one}"
    );
    // P(success by 100) = 0.1977 (README): fails
    assert!(
        lines[2].starts_with("FAIL  success_by(100) <= 0.1: "),
        "{one}"
    );
    assert_eq!(err, "error: 1 of 3 requirements failed\n");
    // a cap too small to decide: UNDECIDED, counted as failing
    let (code, out, _) = run_btrel(&[
        "check",
        SG,
        "--mc",
        "--max-runs",
        "100",
        "--require",
        "ps >= 0.48",
    ]);
    assert_eq!(code, 1);
    assert!(
        out.starts_with("UNDECIDED  ps >= 0.48: ") && out.contains("after 100 runs"),
        "{out}"
    );
}

#[test]
fn help_describes_the_gate() {
    let (code, out, _) = run_btrel(&["check", "--help"]);
    assert_eq!(code, 0);
    for needle in [
        "--require <EXPR>",
        "--mc",
        "--alpha",
        "--beta",
        "--indifference",
        "--time-indifference",
        "--ci",
        "success_by(T)",
        "Wald's sequential",
        "Chow–Robbins",
        "Exit codes: 0 every requirement holds, 1",
    ] {
        assert!(
            out.contains(needle),
            "{needle} missing from check --help:\n{out}"
        );
    }
}

#[test]
fn nav2_default_tree_gated_exactly_and_by_simulation() {
    let Some(corpus) = common::corpus() else {
        eprintln!("skipped: the published corpus (../shared/realworld) is not there");
        return;
    };
    let xml = corpus.join("nav2/navigate_to_pose_w_replanning_and_recovery.xml");
    let nodes = corpus.join("nav2/nav2_tree_nodes.xml");
    let (xml, nodes) = (xml.to_str().unwrap(), nodes.to_str().unwrap());
    let base = [
        "check",
        xml,
        "--include",
        nodes,
        "--params",
        "trees/nav2-default.params.yaml",
    ];
    // exact ps 0.94534, MTTS 62.594 s (README, against 100,000 simulated runs)
    for mode in [None, Some("--mc")] {
        let mut args = base.to_vec();
        args.extend(mode);
        args.extend([
            "--require",
            "ps >= 0.93",
            "--require",
            "NavigateRecovery.mtts <= 70",
        ]);
        let (code, out, err) = run_btrel(&args);
        assert_eq!(code, 0, "{mode:?}: {out}{err}");
        let mut args = base.to_vec();
        args.extend(mode);
        args.extend(["--require", "ps >= 0.96"]);
        let (code, out, _) = run_btrel(&args);
        assert_eq!(code, 1, "{mode:?}: {out}");
        assert!(out.starts_with("FAIL  ps >= 0.96: "), "{out}");
    }
}
