//! `simulate --precision / --time-precision`: the stopping rules' coverage
//! over repeated seeds against closed-form values, their run counts, and
//! reproducibility whatever the thread count.

mod common;

use btrel::sim::sequential::{simulate_to_precision, Precision, PrecisionResult};
use btrel::sim::SimOptions;
use btrel::Tree;
use common::{run_btrel, tree};

/// A Sequence of two exponential actions: a = (ps 0.5, mu 1, nu 2), b = (ps
/// 0.8, mu 0.5, nu 1).
const SEQ: &str = "tree:\n  sequence:\n    name: root\n    children:\n      - action: {name: a, ps: 0.5, mu: 1.0, nu: 2.0}\n      - action: {name: b, ps: 0.8, mu: 0.5, nu: 1.0}\n";

/// Closed forms of `SEQ`'s root: ps = 0.5·0.8; MTTS = 1/1 + 1/0.5; MTTF =
/// (0.5·(1/2) + 0.5·0.2·(1/1 + 1/1)) / (0.5 + 0.1); P(success by t) =
/// 0.4·P(Exp(1) + Exp(0.5) ≤ t) = 0.4·(1 − 2e^{−t/2} + e^{−t}).
const PS: f64 = 0.4;
const MTTS: f64 = 3.0;
const MTTF: f64 = (0.25 + 0.2) / 0.6;
fn success_by(t: f64) -> f64 {
    0.4 * (1.0 - 2.0 * (-t / 2.0).exp() + (-t).exp())
}

fn run(tree: &Tree, seed: u64, times: &[f64], p: &Precision, threads: usize) -> PrecisionResult {
    let base = SimOptions {
        seed,
        threads,
        times: times.to_vec(),
        per_node: false,
        ..Default::default()
    };
    simulate_to_precision(tree, Tree::ROOT, &base, p, None).expect("simulates")
}

/// At least `rate − 3·SE` of `reps` intervals cover their value.
fn assert_coverage(what: &str, covered: usize, reps: usize, rate: f64) {
    let se = (rate * (1.0 - rate) / reps as f64).sqrt();
    let observed = covered as f64 / reps as f64;
    eprintln!("{what}: coverage {covered}/{reps} = {observed:.3} (promised {rate})");
    assert!(
        observed >= rate - 3.0 * se,
        "{what}: {covered} of {reps} intervals cover the exact value ({observed:.3}); the rule \
         promises {rate} (lowest accepted {:.3})",
        rate - 3.0 * se
    );
}

#[test]
fn okamoto_intervals_cover_at_the_stated_rate_with_the_precomputed_runs() {
    let t = tree(SEQ);
    let p = Precision {
        probability: Some(0.02),
        confidence: 0.95,
        ..Default::default()
    };
    // ln(2/0.05) / (2 · 0.02²) = 4611.1
    let n = ((2.0f64 / 0.05).ln() / (2.0 * 0.02 * 0.02)).ceil() as u64;
    assert_eq!(n, 4612);
    let reps = 200;
    let (mut ps_in, mut curve_in) = (0, 0);
    for seed in 0..reps {
        let r = run(&t, seed, &[2.0], &p, 0);
        assert_eq!(r.sim.runs, n, "the Okamoto count, no more");
        assert!(r.missed.is_empty());
        let (lo, hi) = r.intervals[0][0].expect("ps interval");
        assert!((hi - lo) / 2.0 <= 0.02 + 1e-12, "±{}", (hi - lo) / 2.0);
        ps_in += usize::from(lo <= PS && PS <= hi);
        let (lo, hi) = r.curve[0][0].expect("curve interval");
        curve_in += usize::from(lo <= success_by(2.0) && success_by(2.0) <= hi);
    }
    assert_coverage("ps", ps_in, reps as usize, 0.95);
    assert_coverage("success by 2 s", curve_in, reps as usize, 0.95);
}

#[test]
fn chow_robbins_intervals_of_mean_times_cover_at_the_stated_rate() {
    let t = tree(SEQ);
    let eps = 0.1;
    let p = Precision {
        time: Some(eps),
        confidence: 0.9,
        ..Default::default()
    };
    let reps = 200;
    let (mut mtts_in, mut mttf_in) = (0, 0);
    let mut runs = Vec::new();
    for seed in 0..reps {
        let r = run(&t, 1000 + seed, &[], &p, 0);
        assert!(r.missed.is_empty(), "{:?}", r.missed);
        let (lo, hi) = r.intervals[0][3].expect("MTTS interval");
        assert!((hi - lo) / 2.0 <= eps, "MTTS ±{}", (hi - lo) / 2.0);
        mtts_in += usize::from(lo <= MTTS && MTTS <= hi);
        let (lo, hi) = r.intervals[0][4].expect("MTTF interval");
        assert!((hi - lo) / 2.0 <= eps, "MTTF ±{}", (hi - lo) / 2.0);
        mttf_in += usize::from(lo <= MTTF && MTTF <= hi);
        runs.push(r.sim.runs);
    }
    assert_coverage("MTTS", mtts_in, reps as usize, 0.9);
    assert_coverage("MTTF", mttf_in, reps as usize, 0.9);
    // Var(Exp(1) + Exp(0.5)) = 1 + 4 = 5: about (1.645² · 5 / 0.1²) / 0.4 = 3382 runs
    // for the MTTS; the MTTF needs fewer. Chunks of 4096 runs: one or two.
    let mean_runs = runs.iter().sum::<u64>() as f64 / runs.len() as f64;
    assert!(
        (3382.0..=2.0 * 4096.0).contains(&mean_runs),
        "mean runs {mean_runs}"
    );
}

#[test]
fn the_same_seed_gives_the_same_runs_and_figures_whatever_the_thread_count() {
    let t = tree(SEQ);
    let p = Precision {
        probability: Some(0.003),
        time: Some(0.05),
        confidence: 0.95,
        ..Default::default()
    };
    let one = run(&t, 42, &[1.0, 5.0], &p, 1);
    let two = run(&t, 42, &[1.0, 5.0], &p, 2);
    let three = run(&t, 42, &[1.0, 5.0], &p, 3);
    assert_eq!(one, two);
    assert_eq!(one, three);
    // and another seed gives other runs
    let other = run(&t, 43, &[1.0, 5.0], &p, 2);
    assert_ne!(one.sim.nodes[0].ps, other.sim.nodes[0].ps);
}

#[test]
fn a_figure_out_of_reach_stops_at_the_cap_and_is_named() {
    // the root succeeds once in 10^4 runs: its MTTS cannot be had to ±0.05 s
    // in 20,000 runs (it needs 30 successes at least)
    let t = tree(
        "tree:\n  sequence:\n    name: root\n    children:\n      - action: {name: rare, ps: 0.0001, mu: 1.0, nu: 1.0}\n",
    );
    let p = Precision {
        time: Some(0.05),
        max_runs: 20_000,
        ..Default::default()
    };
    let r = run(&t, 1, &[], &p, 0);
    assert_eq!(r.sim.runs, 20_000);
    assert!(
        r.missed.iter().any(|m| m.figure == "mtts"),
        "{:?}",
        r.missed
    );
    // the MTTF (almost every run fails, Exp(1): (1.96 / 0.05)² = 1537 runs)
    // reaches its precision
    assert!(r.missed.iter().all(|m| m.figure != "mttf"));
}

#[test]
fn cli_reports_the_runs_used_and_the_rules() {
    let (code, out, err) = run_btrel(&[
        "simulate",
        "trees/search-and-grasp.yaml",
        "--precision",
        "0.01",
        "--seed",
        "7",
    ]);
    assert_eq!(code, 0, "{err}");
    // ln(40)/(2·1e-4) = 18444.4
    assert!(
        out.lines()
            .next()
            .unwrap()
            .contains("18445 runs per node, seed 7"),
        "{out}"
    );
    assert!(out.contains("Okamoto"), "{out}");
    // the root's ps, 0.888 · 0.55 = 0.4884, within ±0.01
    let row = out
        .lines()
        .find(|l| l.starts_with("search and grasp ") && l.contains("sequence"))
        .expect("root row");
    let ps: f64 = row.split_whitespace().nth(4).unwrap().parse().unwrap();
    assert!((ps - 0.4884).abs() < 0.01, "{row}");
    assert!(row.contains("± 0.01"), "{row}");
    // the same with 1 and 2 threads, and in JSON
    let (_, one, _) = run_btrel(&[
        "simulate",
        "trees/search-and-grasp.yaml",
        "--precision",
        "0.02",
        "--time-precision",
        "5",
        "--threads",
        "1",
        "--format",
        "json",
    ]);
    let (_, two, _) = run_btrel(&[
        "simulate",
        "trees/search-and-grasp.yaml",
        "--precision",
        "0.02",
        "--time-precision",
        "5",
        "--threads",
        "2",
        "--format",
        "json",
    ]);
    assert_eq!(one, two);
    let v: serde_json::Value = serde_json::from_str(&one).expect("JSON");
    assert_eq!(v["reached"], true);
    assert_eq!(v["okamoto_runs"], 4612);
    assert!(v["runs"].as_u64().unwrap() >= 4612);
    let root = &v["nodes"][0];
    let (lo, hi) = (
        root["mtts_lo"].as_f64().unwrap(),
        root["mtts_hi"].as_f64().unwrap(),
    );
    assert!((hi - lo) / 2.0 <= 5.0, "{root}");
}

#[test]
fn cli_usage_errors() {
    for (args, needle) in [
        (
            vec![
                "simulate",
                "trees/search-and-grasp.yaml",
                "--precision",
                "0.01",
                "--runs",
                "10",
            ],
            "cannot be used with",
        ),
        (
            vec![
                "simulate",
                "trees/search-and-grasp.yaml",
                "--confidence",
                "0.9",
            ],
            "--confidence goes with --precision",
        ),
        (
            vec![
                "simulate",
                "trees/search-and-grasp.yaml",
                "--precision",
                "0.7",
            ],
            "below 0.5",
        ),
        (
            vec![
                "simulate",
                "trees/search-and-grasp.yaml",
                "--precision",
                "-1",
            ],
            "not a number > 0",
        ),
        (
            vec![
                "simulate",
                "trees/search-and-grasp.yaml",
                "--precision",
                "0.01",
                "--confidence",
                "1.5",
            ],
            "not a level",
        ),
    ] {
        let (code, out, err) = run_btrel(&args);
        assert_eq!(code, 2, "{args:?}: {err}");
        assert!(out.is_empty());
        assert!(err.contains(needle), "{args:?}: {err}");
    }
}

#[test]
fn help_names_the_rules() {
    let (code, out, _) = run_btrel(&["simulate", "--help"]);
    assert_eq!(code, 0);
    for needle in [
        "--precision",
        "--time-precision",
        "--confidence",
        "--max-runs",
        "Okamoto",
        "Chow–Robbins",
    ] {
        assert!(
            out.contains(needle),
            "{needle} missing from simulate --help"
        );
    }
}
