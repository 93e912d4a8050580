//! Honest limits: inputs that used to abort the process, or to run for
//! seconds and gigabytes before a refusal with a made-up figure, are now
//! answered (checked against simulation and the report) — regression tests
//! of the engine issue's cases. No timing is asserted (machines are shared).

mod common;
use common::*;

fn wide(child: &str, n: usize, m: usize) -> String {
    let kids = vec![child; n].join(", ");
    format!("{{parallel: {{success_threshold: {m}, children: [{kids}]}}}}")
}

/// `btrel report` of `yaml` under a 2 GB address-space limit: exits 0 (an
/// allocation past the limit aborts the process).
fn report_within_two_gigabytes(yaml: &str) {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("tree.yaml");
    std::fs::write(&file, yaml).unwrap();
    let script = format!(
        "ulimit -v 2000000; exec '{}' report '{}' --format json",
        env!("CARGO_BIN_EXE_btrel"),
        file.display()
    );
    let o = std::process::Command::new("sh")
        .args(["-c", &script])
        .output()
        .unwrap();
    assert_eq!(
        o.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
}

#[test]
fn stiff_action_before_a_wide_parallel_over_a_long_horizon() {
    // a rate-1e6 action, then a Parallel of 16 two-action subtrees (a
    // product of 6^16 states), curve to t = 1e7: this aborted (allocation
    // failure) and later was refused as "≈ inf operations"
    let sub = "{sequence: {children: [{action: {ps: 0.9, mu: 1.0, nu: 2.0}}, \
               {action: {ps: 0.9, mu: 0.5, nu: 1.0}}]}}";
    let yaml = format!(
        "tree: {{sequence: {{children: [{{action: {{ps: 0.9, mu: 1e6, nu: 1e6}}}}, {}]}}}}",
        wide(sub, 16, 8)
    );
    let t = tree(&yaml);
    let times = [10.0, 30.0, 1e7];
    let pts = btrel::curve::curve(&t, 0, &times, &Default::default()).expect("answered");
    let f = root_figures(&t);
    assert!((pts[2].success - f.ps).abs() < 1e-9 && (pts[2].failure - f.pf).abs() < 1e-9);
    let sim = simulate_root(&t, 200_000, &times);
    for (p, e) in pts.iter().zip(&sim.curve) {
        assert_within_z("S(t)", &e.success, p.success);
        assert_within_z("F(t)", &e.failure, p.failure);
    }
}

#[test]
fn sixteen_stiff_subtrees_are_reported() {
    // 16 × Sequence(rate 1e6, rate 1e-3), M = 8: ran 11-35 s and 2.75 GB,
    // then was refused with "≈ inf operations … shorten the horizon"
    let sub = "{sequence: {children: [{action: {ps: 0.99, mu: 1e6, nu: 1e6}}, \
               {action: {ps: 0.9, mu: 0.001, nu: 0.001}}]}}";
    let t = tree(&format!("tree: {}\n", wide(sub, 16, 8)));
    assert_root_matches_simulation(&t, 100_000);
}

#[test]
fn a_mixed_timing_tree_too_large_for_its_shifted_mixture_is_answered_within_the_memory_limit() {
    // a random Sequence/Fallback tree, a third each deterministic, hybrid
    // and exponential actions. At 300 leaves its shifted phase-type mixture
    // would hold ~4e7 phases: its convolutions were built before the budget
    // was checked (24 s and 4.5 GB, and under a 2 GB address-space limit
    // the process aborted); then the size was checked first and the curve
    // refused. Now the mixture hands over to the composed laws with atoms
    // where it exceeds the budget: a 40-leaf tree is answered under the same
    // 2 GB limit, every point written (its values: tests/law_atoms.rs and
    // tests/mixed_timing.rs; 300 leaves take about a minute, docs/BENCHMARKS.md).
    use btrel::generate::{random_tree_yaml, Shape};
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("mixed40.yaml");
    std::fs::write(&file, random_tree_yaml(&Shape::mixed_timing(40), 1)).unwrap();
    let out = dir.path().join("c.csv");
    let script = format!(
        "ulimit -v 2000000; exec '{}' curve '{}' --t-end 100 --points 1000 -o '{}'",
        env!("CARGO_BIN_EXE_btrel"),
        file.display(),
        out.display()
    );
    let o = std::process::Command::new("sh")
        .args(["-c", &script])
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(0), "{stderr}");
    let csv = std::fs::read_to_string(&out).unwrap();
    assert_eq!(csv.lines().count(), 1001, "a header and 1,000 points");
}

/// Issue 29's 9-leaf tree: `report` grew past 24 GB until the kernel killed
/// it (the mean times' quadrature halved panels whose gaps were rounding,
/// doubling them each round). By hand: `c8` (ps 1) succeeds at 0, so `p5`
/// (M = 1) and `p2` (M = 1) and the root (M = 1) succeed at 0 with
/// probability 1: ps 1, MTTS 0. Run under a 2 GB address-space limit.
#[test]
fn a_parallel_that_surely_succeeds_at_once_is_reported_within_the_memory_limit() {
    let yaml = "tree:
  parallel:
    name: p1
    success_threshold: 1
    children:
      - parallel:
          name: p2
          success_threshold: 1
          children:
            - retry: {name: ret3, attempts: 1, child: {action: {name: a4, ps: 0.8, mu: 5, nu: 2}}}
            - parallel:
                name: p5
                success_threshold: 1
                failure_threshold: 3
                children:
                  - action: {name: a6, ps: 0.6, tau_s: 0.2, nu: 5}
                  - condition: {name: c7, ps: 0.2}
                  - condition: {name: c8, ps: 1}
            - action: {name: a9, ps: 0.5, tau_s: 0.2, nu: 5}
      - action: {name: a10, ps: 0.7, tau_s: 0.2, tau_f: 0.5}
";
    report_within_two_gigabytes(yaml);
    let t = tree(yaml);
    let f = root_figures(&t);
    assert_eq!((f.ps, f.pf), (1.0, 0.0), "{f:?}");
    assert_eq!(f.mtts, Some(0.0), "{f:?}");
    let (s, fl) = root_curve_at(&t, 0.0);
    assert_eq!((s, fl), (1.0, 0.0));
}

/// Issue 29: a Retry of a Parallel `{M = 2, F = 1}` over a deterministic, a
/// stochastic and a hybrid action: `curve` refused. Answered, and agreeing
/// with the simulated tick semantics; the curve tends to the report.
#[test]
fn a_retry_of_a_mixed_race_has_its_curve() {
    let t = tree(
        "tree:
  retry:
    name: r
    attempts: 3
    child:
      parallel:
        name: p
        success_threshold: 2
        failure_threshold: 1
        children:
          - action: {name: det, ps: 0.7, tau_s: 1, tau_f: 2}
          - action: {name: sto, ps: 0.8, mu: 1, nu: 2}
          - action: {name: hyb, ps: 0.6, tau_s: 0.5, nu: 1}
",
    );
    let times = [0.75, 1.0, 2.0, 5.0];
    let pts = btrel::curve::curve(&t, 0, &times, &Default::default()).expect("answered");
    let f = root_figures(&t);
    let late = root_curve_at(&t, 200.0);
    assert!((late.0 - f.ps).abs() < 1e-9 && (late.1 - f.pf).abs() < 1e-9);
    let sim = simulate_root(&t, 200_000, &times);
    assert_root_and_curve_within_z("retry of a mixed race", f, &pts, &sim);
}

/// Random survey tree 1735 (docs/TESTING.md): a Parallel racing a loop
/// over fixed times (an atom at every instant of its lattice: 23,707 on
/// the race's 5,934 s horizon) against a Markovian Retry. Its quadrature
/// asked the Retry's phase chain at 853,632 times, and each time's Poisson
/// window (≈ 1,300 terms) was held until all were made: `report` took 48 s
/// and 13 GB. Now the chain is stepped from time to time (an estimate
/// chooses it), and the loop's CDF reads running sums of its atoms. Run
/// under a 2 GB address-space limit; the figures against simulation.
#[test]
fn a_race_with_a_lattice_loop_is_reported_within_the_memory_limit() {
    let yaml = "tree: {parallel: {name: n1, success_threshold: 2, failure_threshold: 1, children: [\
        {fallback: {name: n2, children: [{until_success: {name: n3, child: {repeat: {name: n4, times: 2, \
        child: {repeat: {name: n5, times: 2, child: {if_then_else: {name: n6, children: [\
        {condition: {name: n7, ps: 0.8}}, {action: {name: n8, ps: 0.4, tau_s: 1.25, tau_f: 1.75}}]}}}}}}}}, \
        {until_failure: {name: n9, child: {fallback: {name: n10, children: [\
        {action: {name: n11, ps: 0.5, tau_s: 0.625, nu: 0.679}}, \
        {action: {name: n12, ps: 0.6, success_time: {rate: 1.697}, failure_time: {rate: 0.291}}}, \
        {retry: {name: n13, attempts: 3, child: {action: {name: n14, ps: 0.7, \
        success_time: {erlang: {k: 3, rate: 0.546}}, failure_time: {shift: 0.25, rate: 3.162}}}}}]}}}}]}}, \
        {retry: {name: n15, attempts: 3, child: {force_success: {name: n16, child: {inverter: {name: n17, \
        child: {retry: {name: n18, attempts: 3, child: {parallel: {name: n19, success_threshold: 2, \
        failure_threshold: 1, children: [{parallel: {name: n20, success_threshold: 1, failure_threshold: 2, \
        children: [{condition: {name: n21, ps: 0.5}}, {condition: {name: n22, ps: 0.5}}]}}, \
        {action: {name: n23, ps: 0.5, success_time: {rate: 2.828}, failure_time: \
        {hyperexponential: [{p: 0.4, rate: 2.05}, {p: 0.6, rate: 1.926}]}}}]}}}}}}}}}}]}}\n";
    report_within_two_gigabytes(yaml);
    assert_root_matches_simulation(&tree(yaml), 50_000);
}
