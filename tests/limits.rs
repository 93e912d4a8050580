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
    // tests/mixed_timing.rs; 300 leaves take about a minute, README).
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
