//! Helpers shared by the integration tests.
#![allow(dead_code)]

use btrel::curve::{curve, CurveOptions};
use btrel::sim::{simulate, Estimate, SimOptions, SimResult};
use btrel::tree::{parse_str, Tree};
use btrel::{analyze, Figures, Options};

/// Largest accepted |z| of a Monte Carlo figure against its exact value.
pub const Z: f64 = 5.0;

/// Parses a YAML tree written in a test.
pub fn tree(yaml: &str) -> Tree {
    parse_str(yaml, "test.yaml").expect("test tree parses")
}

/// The exact figures of the root.
pub fn root_figures(tree: &Tree) -> Figures {
    analyze(tree, &Options::default()).expect("analysed").nodes[0]
}

/// `(success, failure)` of the root's exact curve at `t`.
pub fn root_curve_at(tree: &Tree, t: f64) -> (f64, f64) {
    let p = curve(tree, 0, &[t], &CurveOptions::default()).expect("curve")[0];
    (p.success, p.failure)
}

/// The root alone, `runs` episodes, default seed.
pub fn simulate_root(tree: &Tree, runs: u64, times: &[f64]) -> SimResult {
    let opts = SimOptions {
        runs,
        times: times.to_vec(),
        per_node: false,
        ..Default::default()
    };
    simulate(tree, &opts, None).expect("simulates")
}

/// Asserts that a Monte Carlo estimate is within [`Z`] standard errors of
/// `exact` (exactly equal when the estimate has no spread).
pub fn assert_within_z(what: &str, est: &Estimate, exact: f64) {
    if est.se == 0.0 {
        assert!(
            (est.mean - exact).abs() <= 1e-12 * exact.abs().max(1.0),
            "{what}: simulated {} (no spread) vs exact {exact}",
            est.mean
        );
        return;
    }
    let z = (est.mean - exact) / est.se;
    assert!(
        z.abs() < Z,
        "{what}: simulated {} ± {} vs exact {exact} (z = {z:.2})",
        est.mean,
        est.se
    );
}
