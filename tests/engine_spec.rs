//! The engine's specification: random trees over every node kind and every
//! leaf timing family (`common::anytree`) are answered by `report` and
//! `curve`; every node's report equals its curve's limit; the root agrees
//! with a Monte Carlo written in the test from the node semantics.
//!
//! `BTREL_SPEC_SURVEY=N` runs N trees and prints every refusal and slow
//! tree instead of stopping at the first (a survey, for engine work; each
//! tree is printed as it starts and its verdict as it ends, on stderr);
//! `BTREL_SPEC_FROM=K` starts at seed K.

mod common;

use std::time::{Duration, Instant};

use btrel::curve::{curve, CurveOptions};
use btrel::{analyze, Options};
use common::anytree::{random_tree, Node};

/// A time by which every generated tree has returned but for less than
/// 1e-12 of its mass (rates ≥ 0.25, loops whose child ends them with
/// probability ≥ 0.1 a run, at most a few levels of them)... is not
/// guaranteed for loops of loops: the limit check uses the report's own
/// never-mass and a generous horizon instead.
const HORIZON: f64 = 1e4;

/// Fewest runs with an outcome for its mean time to be checked against
/// the simulation (its standard error is estimated from those runs).
const MIN_OUTCOMES: f64 = 50.0;

/// The two-sided tail probability of a 5-standard-error deviation of a
/// normal variable: a count's Poisson tail below it fails the check.
const RARE: f64 = 5.7e-7;

/// The probability that a Poisson count of mean `mean` is at least as far
/// from its mean as `count`, on `count`'s side: `P(X ≥ count)` above the
/// mean, `P(X ≤ count)` below it.
fn poisson_tail(count: f64, mean: f64) -> f64 {
    let k = count as u64;
    // the terms e^{-λ} λ^j / j! for j = 0..=k
    let mut term = (-mean).exp();
    let mut below = 0.0; // P(X < k)
    for j in 0..k {
        below += term;
        term *= mean / (j + 1) as f64;
    }
    if count >= mean {
        (1.0 - below).max(0.0)
    } else {
        below + term
    }
}

/// The Poisson tails against sums of its probabilities computed apart
/// (Python, `math.exp(-l) * l**j / math.factorial(j)`).
#[test]
fn poisson_tails() {
    let close = |a: f64, b: f64| (a - b).abs() <= 1e-12 * b;
    assert!(close(poisson_tail(1.0, 0.0137), 0.01360658209503196));
    assert!(close(poisson_tail(5.0, 16.7), 0.0008381680617587639));
    assert!(close(poisson_tail(10.0, 2.0), 4.6498075017109564e-05));
}

/// Checks one tree; `Ok(false)` when its Monte Carlo ran past the test's
/// leaf budget (loops of loops whose runs take ~10^10 leaf runs): then
/// only the report-equals-limit check was made.
fn check(seed: u64, node: &Node) -> Result<bool, String> {
    let yaml = node.yaml();
    let tree = btrel::parse_str(&yaml, "spec.yaml").map_err(|e| format!("parse: {e}"))?;
    let analysis = analyze(&tree, &Options::default()).map_err(|e| format!("report: {e}"))?;
    let root = analysis.nodes[0];
    let times = [0.5, 2.0, 8.0];
    // a tree that loops for long (a mean of minutes) has not returned by
    // HORIZON: its limit is read at a hundred times its mean times
    let slowest = root.mtts.unwrap_or(0.0).max(root.mttf.unwrap_or(0.0));
    let horizon = HORIZON.max(100.0 * slowest);
    let mut all = times.to_vec();
    all.push(horizon);
    let pts = curve(&tree, 0, &all, &CurveOptions::default()).map_err(|e| format!("curve: {e}"))?;
    let lim = pts[times.len()];
    if (lim.success - root.ps).abs() > 1e-9 || (lim.failure - root.pf).abs() > 1e-9 {
        return Err(format!(
            "root: report ps {} pf {} vs curve({horizon}) {} {}",
            root.ps, root.pf, lim.success, lim.failure
        ));
    }
    let est = node.estimate(20_000, &times, seed ^ 0xABCD);
    if !est.complete {
        return Ok(false);
    }
    let z = |what: &str, (m, se): (f64, f64), exact: f64| -> Result<(), String> {
        let res = 5.0 / est.runs as f64;
        if (se == 0.0 && (m - exact).abs() > res) || (se > 0.0 && ((m - exact) / se).abs() > 5.0) {
            return Err(format!("{what}: simulated {m} ± {se} vs exact {exact}"));
        }
        Ok(())
    };
    // a probability is tested under the hypothesis, from the exact value:
    // the simulated proportion's own standard error understates the spread
    // where the outcome is rare (seed 2267: F(0.5) = 8.3e-4, 5 failures by
    // then in 20,000 runs where 16.7 are expected — "0.00025 ± 0.00011",
    // z = -5.2, where the exact value's standard error gives z = -2.9;
    // 100,000,000 simulated runs agree within 1.1 SE). Where fewer than
    // MIN_OUTCOMES runs are expected on either side, the count's Poisson
    // tail is the test (seed 2766: F(0.5) = 6.9e-7, one run of 20,000 by
    // then where 0.014 are expected — P = 1.4 %, but 8.4 "standard errors")
    let prob = |what: &str, (m, _): (f64, f64), exact: f64| {
        let n = est.runs as f64;
        let (count, expected) = if exact <= 0.5 {
            ((m * n).round(), exact * n)
        } else {
            (((1.0 - m) * n).round(), (1.0 - exact) * n)
        };
        if expected >= MIN_OUTCOMES || expected <= 0.0 {
            let se = (exact * (1.0 - exact) / n).max(0.0).sqrt();
            return z(what, (m, se), exact);
        }
        if poisson_tail(count, expected) < RARE {
            return Err(format!(
                "{what}: simulated {m} ({count} of {n} runs) vs exact {exact} ({expected:.3} expected)"
            ));
        }
        Ok(())
    };
    prob("ps", est.ps, root.ps)?;
    prob("pf", est.pf, root.pf)?;
    // a mean time's standard error is estimated from the runs with that
    // outcome: from a handful of them it is no error bar (seed 1316's root
    // fails with probability 9.4e-5, about twice in 20,000 runs: its MTTF
    // came out "17.3 ± 0.78" against the exact 11.78, which btrel's own
    // simulator confirms with 20,000,000 runs, 11.75 ± 0.07), so a mean is
    // checked where its outcome came at least MIN_OUTCOMES times
    let enough = |p: (f64, f64)| p.0 * est.runs as f64 >= MIN_OUTCOMES;
    if let (Some(e), Some(m)) = (est.mtts, root.mtts) {
        if enough(est.ps) {
            z("MTTS", e, m)?;
        }
    }
    if let (Some(e), Some(m)) = (est.mttf, root.mttf) {
        if enough(est.pf) {
            z("MTTF", e, m)?;
        }
    }
    for (k, q) in pts[..times.len()].iter().enumerate() {
        prob(&format!("S({})", q.t), est.success_by[k], q.success)?;
        prob(&format!("F({})", q.t), est.failure_by[k], q.failure)?;
    }
    Ok(true)
}

#[test]
fn random_trees_of_every_kind_and_timing_are_answered_and_agree_with_simulation() {
    let survey: Option<u64> = std::env::var("BTREL_SPEC_SURVEY")
        .ok()
        .and_then(|s| s.parse().ok());
    let n = survey.unwrap_or(200);
    let from: u64 = std::env::var("BTREL_SPEC_FROM")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(0);
    // the seeds on two workers (the machine's cores), in seed order after
    let next = std::sync::atomic::AtomicU64::new(from);
    let results = std::sync::Mutex::new(Vec::new());
    std::thread::scope(|s| {
        for _ in 0..2 {
            s.spawn(|| loop {
                let seed = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                if seed >= from + n {
                    break;
                }
                let node = random_tree(seed, 10);
                if survey.is_some() {
                    // the tree first, so that one that never ends is known
                    eprintln!("survey: seed {seed} starts: {}", node.yaml().trim_end());
                }
                let start = Instant::now();
                let r = check(seed, &node);
                let took = start.elapsed();
                if survey.is_some() {
                    // as they come, so that a survey cut short still tells
                    eprintln!(
                        "survey: seed {seed} {} in {took:.2?}",
                        match &r {
                            Ok(true) => "ok".to_string(),
                            Ok(false) => "ok (simulation over budget)".to_string(),
                            Err(e) => e.lines().next().unwrap_or("").to_string(),
                        }
                    );
                }
                results
                    .lock()
                    .expect("no worker panics")
                    .push((seed, node, r, took));
            });
        }
    });
    let mut results = results.into_inner().expect("no worker panics");
    results.sort_by_key(|r| r.0);
    let mut failures = Vec::new();
    let mut slow = Vec::new();
    let mut unsimulated = Vec::new();
    for (seed, node, r, took) in results {
        if let Ok(false) = r {
            unsimulated.push(seed);
        }
        if took > Duration::from_secs(2) {
            if survey.is_some() {
                println!("seed {seed}: slow ({took:?})\n{}", node.yaml());
            }
            slow.push((seed, took));
        }
        if let Err(e) = r {
            if survey.is_none() {
                panic!(
                    "seed {seed} ({} leaves): {e}\n{}",
                    node.leaves(),
                    node.yaml()
                );
            }
            println!("seed {seed}: {e}\n{}", node.yaml());
            failures.push(seed);
        }
    }
    if survey.is_some() {
        println!(
            "{} of {n} trees failed: {failures:?}; slow (> 2 s): {slow:?}; \
             simulation over budget: {unsimulated:?}",
            failures.len()
        );
    } else {
        // the budget is for the rare loops of slow loops, not a way out
        assert!(
            unsimulated.len() * 50 <= n as usize,
            "the Monte Carlo of too many trees ran over its budget: {unsimulated:?}"
        );
    }
}

/// Trees a survey beyond the default seeds found (`BTREL_SPEC_SURVEY=200
/// BTREL_SPEC_FROM=60`): 113 and 240, a ForceFailure / ForceSuccess over a
/// child that may never return (the report said pf / ps 1); 162, nested
/// loops with a mean of 584 s (the limit was read at 1e4 s, where 3e-8 of
/// the runs still go on); 146, a loop inside a race whose composed law
/// misses about 3e-13 of its mass at every horizon — its quadrature's
/// rounding (refused after 12 doublings of its horizon until the tail
/// bound showed that, past its time, the deficit is the law's own error).
/// From `BTREL_SPEC_FROM=300`: 452, a Parallel's MTTS by quadrature of its
/// counted curve over a ForceSuccess whose composed law is 3e-13 short of
/// its limit (that gap integrated without end gave 6.6e6 s for 2.54 s, and
/// the race above refused the law); 550, the same quadrature's tail pushed
/// to where the stiff solver's bound failed (a refusal after 9 s); 559, a
/// loop whose child repeats it at once 80% of the time, unrolled into 145
/// copies of a 900-phase chain (a report of 230 s, now 1.3 s: an instant
/// repetition takes no time and is folded into the loop's entry).
/// From `BTREL_SPEC_FROM=700`: 701, a 3-of-4 Parallel whose slowest child
/// is a 16,290-phase loop chain: its figures' tail was integrated in
/// batches of four doubling panels, each batch up to 16 times past where
/// the mass had settled and every quadrature round a uniformization pass
/// from 0 to the batch's end (a report of more than 100 s, now 3 s).
/// From `BTREL_SPEC_FROM=1500`: 1510, an `until_success` run ~100 times
/// whose run fails at a lattice instant or after a shifted exponential: its
/// renewal density was marched with every point convolving the thousands
/// of panels before it within the exponential's reach (a report of 25 s,
/// now 0.5 s: the exponential's recursion, `ErlangMarch`); 1735, a
/// race of a lattice loop against a Markovian Retry (a report of 48 s and
/// 13 GB, now 1.3 s: `tests/limits.rs`). From `BTREL_SPEC_FROM=1800`: 2014,
/// an `until_success` over a Retry 4 of a lattice-timed and a hybrid
/// action, refused after 43 s (the convolution work limit): its run's
/// failure law is 30 shifted Erlang terms of one rate, now kept in closed
/// form through the Retry's convolutions and marched by the Erlang
/// recursion (0.6 s). From `BTREL_SPEC_FROM=2700`: 2786, a counted
/// Parallel over a Repeat of an `until_success` whose chain, the loop
/// unrolled to where its repetitions end but for 1e-14, has 36,126 phases
/// (six its own): every uniformization pass of its mean-time quadrature
/// stepped them all (a report of 113 s; now 0.2 s: the loop's cyclic chain
/// and the composed laws above it). 1948, an `until_success` whose run's
/// failure density has two rates (a hybrid's and an Erlang-3's): 5.6 s, now
/// 0.13 s (kernels of two rates, by partial fractions).
#[test]
fn survey_regressions() {
    for seed in [
        113, 146, 162, 240, 452, 550, 559, 701, 1510, 1735, 1948, 2014, 2786,
    ] {
        let node = random_tree(seed, 10);
        match check(seed, &node) {
            Ok(true) => {}
            Ok(false) => panic!("seed {seed}: its simulation ran over budget"),
            Err(e) => panic!("seed {seed}: {e}\n{}", node.yaml()),
        }
    }
}

/// Survey tree 942, an `until_failure` over a Parallel run about 24,500
/// times (mean 27,334 s): its curve at a hundred mean times is its figures
/// within 1e-9. Its tail bound was 20 times its exact tail (a Parallel's
/// MGF bound charged the sum of its children's times; since 2026-12-07
/// only in the terms past the first moment), so that time was read from
/// the loop's marched law, 2.7e-9 short of P(F) = 1. Its Monte Carlo is
/// over the test's budget: the check is the report against the curve.
#[test]
fn a_loop_over_a_parallel_far_out_is_its_limit() {
    let node = random_tree(942, 10);
    if let Err(e) = check(942, &node) {
        panic!("seed 942: {e}\n{}", node.yaml());
    }
}

/// Survey tree 272, a loop of loops with a mean of 3,713 s: its curve at
/// 1e7 s is its figures (the tail bound puts all but 1e-13 of its mass
/// before 1.9e6 s) — it was searched for by computing the curve at 16 ×
/// its mean time and beyond, which ran for many minutes.
#[test]
fn a_far_time_of_a_slow_loop_is_its_limit() {
    let yaml = random_tree(272, 10).yaml();
    let tree = btrel::parse_str(&yaml, "spec.yaml").expect("a valid tree");
    let root = analyze(&tree, &Options::default()).expect("figures").nodes[0];
    assert!(root.mtts.is_some_and(|m| m > 3000.0), "{root:?}");
    let p = curve(&tree, 0, &[1e7], &CurveOptions::default()).expect("the curve")[0];
    assert!((p.success - root.ps).abs() <= 1e-13, "{p:?} vs {root:?}");
    assert!((p.failure - root.pf).abs() <= 1e-13, "{p:?} vs {root:?}");
}

/// A Sequence above a race whose children mix fixed, hybrid, shifted,
/// Erlang and exponential times (refused as mixed timing before the race's
/// children could enter as their composed laws): answered, and agreeing
/// with the simulation of the node semantics.
#[test]
fn a_sequence_above_a_mixed_race_is_answered() {
    use common::anytree::Law;
    let action = |ps: f64, s: Law, f: Law| Node::Action { ps, s, f };
    let node = Node::Sequence(vec![
        action(0.9, Law::Exp(2.0), Law::Exp(1.0)),
        Node::Parallel {
            m: 2,
            f: 1,
            kids: vec![
                action(0.8, Law::Fixed(0.7), Law::Capped(1.5, 0.7)),
                action(
                    0.7,
                    Law::Shifted(0.3, Box::new(Law::Exp(2.0))),
                    Law::Erlang(2, 3.0),
                ),
                action(0.6, Law::Capped(1.2, 0.9), Law::Fixed(0.9)),
            ],
        },
    ]);
    assert_eq!(check(7, &node), Ok(true), "{}", node.yaml());
}

/// Survey tree 272 to t = 100: its loops' composed laws jump on a 0.125 s
/// lattice (sums of fixed times). They were refused on their convolution
/// work after ~40 s: next to every jump the march halved its panel dozens
/// of times, because a panel's end was sampled nudged off the jump by less
/// than the tie tolerance, and a race's density read there the value after
/// the instant. Answered now, within 5 standard errors of the test's own
/// Monte Carlo.
#[test]
fn a_long_horizon_over_a_lattice_of_jumps_is_answered() {
    let node = random_tree(272, 10);
    let tree = btrel::parse_str(&node.yaml(), "spec.yaml").expect("a valid tree");
    let p = curve(&tree, 0, &[100.0], &CurveOptions::default()).expect("the curve")[0];
    // its runs are long (a root loop of ~360 rounds): no budget
    let est = node.estimate_within(20_000, &[100.0], 272 ^ 0xABCD, u64::MAX);
    let (m, se) = est.success_by[0];
    assert!(
        se > 0.0 && ((m - p.success) / se).abs() <= 5.0,
        "{p:?} vs {m} ± {se}"
    );
    assert!(((est.failure_by[0].0 - p.failure) / est.failure_by[0].1.max(1e-9)).abs() <= 5.0);
}
