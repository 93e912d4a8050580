//! Helpers shared by the integration tests.
#![allow(dead_code)]

pub mod anytree;
pub mod expoly;
pub mod python;

use btrel::curve::{curve, CurveOptions};
use btrel::sim::{simulate, Estimate, SimOptions, SimResult};
use btrel::tree::{parse_str, Tree};
use btrel::{analyze, Figures, Options};

/// The published corpus (`../shared/realworld`, or `BTREL_REALWORLD`),
/// when it is there.
pub fn corpus() -> Option<std::path::PathBuf> {
    let root = std::env::var_os("BTREL_REALWORLD")
        .map(std::path::PathBuf::from)
        .unwrap_or_else(|| {
            std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/realworld")
        });
    root.join("INDEX.md").exists().then_some(root)
}

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
        // every run gave the same value: it may differ from the exact one by
        // less than one run's weight (a probability of 1 − 3e-8 in 2e5 runs)
        let resolution = Z / est.count.max(1) as f64;
        assert!(
            (est.mean - exact).abs() <= (1e-12 * exact.abs().max(1.0)).max(resolution),
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

/// A small random tree in YAML flow style, reproducible from `seed`: up to
/// `depth` levels of Sequence / Fallback / Parallel (any M, the book's F or
/// a smaller one) / decorators over leaves of every timing of Def. 9.11 —
/// stochastic, deterministic, both hybrids — and conditions. Deterministic
/// times are multiples of 0.1 s, so that decimal ties occur.
pub fn random_mixed_tree(seed: u64, depth: usize) -> String {
    use rand::SeedableRng;
    let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(seed);
    format!("tree: {}\n", random_node(&mut rng, depth))
}

fn random_node(rng: &mut rand_xoshiro::Xoshiro256PlusPlus, depth: usize) -> String {
    use rand::RngExt;
    let ps = |rng: &mut rand_xoshiro::Xoshiro256PlusPlus| (rng.random_range(1..10) as f64) / 10.0;
    let rate = |rng: &mut rand_xoshiro::Xoshiro256PlusPlus| 0.5 + 2.0 * rng.random::<f64>();
    let tenth = |rng: &mut rand_xoshiro::Xoshiro256PlusPlus| rng.random_range(1..16) as f64 / 10.0;
    if depth == 0 || rng.random::<f64>() < 0.3 {
        let p = ps(rng);
        return match rng.random_range(0..5) {
            0 => format!(
                "{{action: {{ps: {p}, mu: {}, nu: {}}}}}",
                rate(rng),
                rate(rng)
            ),
            1 => format!(
                "{{action: {{ps: {p}, tau_s: {}, tau_f: {}}}}}",
                tenth(rng),
                tenth(rng)
            ),
            2 => format!(
                "{{action: {{ps: {p}, tau_s: {}, nu: {}}}}}",
                tenth(rng),
                rate(rng)
            ),
            3 => format!(
                "{{action: {{ps: {p}, mu: {}, tau_f: {}}}}}",
                rate(rng),
                tenth(rng)
            ),
            _ => format!("{{condition: {{ps: {p}}}}}"),
        };
    }
    let n = rng.random_range(1..4usize);
    let kids: Vec<String> = (0..n).map(|_| random_node(rng, depth - 1)).collect();
    let kids = kids.join(", ");
    match rng.random_range(0..6) {
        0 | 1 => format!("{{sequence: {{children: [{kids}]}}}}"),
        2 => format!("{{fallback: {{children: [{kids}]}}}}"),
        3 => {
            let m = rng.random_range(1..=n);
            let f = if rng.random::<f64>() < 0.7 {
                n - m + 1
            } else {
                rng.random_range(1..=n)
            };
            format!(
                "{{parallel: {{success_threshold: {m}, failure_threshold: {f}, children: [{kids}]}}}}"
            )
        }
        4 => {
            let child = random_node(rng, depth - 1);
            match rng.random_range(0..5) {
                0 => format!("{{inverter: {{child: {child}}}}}"),
                1 => format!("{{force_success: {{child: {child}}}}}"),
                2 => format!("{{force_failure: {{child: {child}}}}}"),
                3 => format!("{{retry: {{attempts: 2, child: {child}}}}}"),
                _ => format!("{{repeat: {{times: 2, child: {child}}}}}"),
            }
        }
        _ => format!("{{fallback: {{children: [{kids}]}}}}"),
    }
}

/// Simulates the root `runs` times and checks its ps, MTTS and MTTF (where
/// defined) against the exact report, |z| < [`Z`].
pub fn assert_root_matches_simulation(tree: &Tree, runs: u64) {
    let f = root_figures(tree);
    let sim = simulate_root(tree, runs, &[]);
    let r = &sim.nodes[0];
    assert_within_z("ps", &r.ps, f.ps);
    if let (Some(e), Some(m)) = (&r.mtts, f.mtts) {
        assert_within_z("MTTS", e, m);
    }
    if let (Some(e), Some(m)) = (&r.mttf, f.mttf) {
        assert_within_z("MTTF", e, m);
    }
}

/// Asserts that a simulation of the root (with `pts`' times) agrees with
/// the exact figures `f` and curve points `pts`, |z| < [`Z`]; `label`
/// names the case in messages.
pub fn assert_root_and_curve_within_z(
    label: &str,
    f: Figures,
    pts: &[btrel::curve::CurvePoint],
    sim: &SimResult,
) {
    let r = &sim.nodes[0];
    assert_within_z(&format!("{label} ps"), &r.ps, f.ps);
    if let (Some(e), Some(m)) = (&r.mtts, f.mtts) {
        assert_within_z(&format!("{label} MTTS"), e, m);
    }
    if let (Some(e), Some(m)) = (&r.mttf, f.mttf) {
        assert_within_z(&format!("{label} MTTF"), e, m);
    }
    for (p, e) in pts.iter().zip(&sim.curve) {
        assert_within_z(&format!("{label} S({})", p.t), &e.success, p.success);
        assert_within_z(&format!("{label} F({})", p.t), &e.failure, p.failure);
    }
}

/// For each YAML tree of `cases`: the root's exact figures and curve at
/// `times` against `runs` simulated episodes, |z| < [`Z`] (labelled `case i`).
pub fn assert_cases_match_simulation<S: AsRef<str>>(cases: &[S], times: &[f64], runs: u64) {
    for (i, y) in cases.iter().enumerate() {
        let t = tree(y.as_ref());
        let f = root_figures(&t);
        let pts = curve(&t, 0, times, &CurveOptions::default()).expect("curve");
        let sim = simulate_root(&t, runs, times);
        assert_root_and_curve_within_z(&format!("case {i}"), f, &pts, &sim);
    }
}

/// Runs the built binary with `args` (from the crate root): exit code,
/// standard output, standard error.
pub fn run_btrel(args: &[&str]) -> (i32, String, String) {
    let out = assert_cmd::Command::cargo_bin("btrel")
        .expect("the binary is built")
        .args(args)
        .output()
        .expect("the binary runs");
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8(out.stdout).expect("UTF-8 output"),
        String::from_utf8(out.stderr).expect("UTF-8 errors"),
    )
}

/// Whether `a` and `b` agree to 1e-12, relative (absolute below 1).
pub fn close(a: f64, b: f64) -> bool {
    (a - b).abs() <= 1e-12 * a.abs().max(b.abs()).max(1.0)
}

/// Asserts that figures `f` have success probability `ps` (and failure
/// probability 1 − ps) and the given mean times, `None` where the time is
/// undefined, each to 1e-12 ([`close`]).
pub fn check_figures(f: Figures, ps: f64, mtts: Option<f64>, mttf: Option<f64>) {
    assert!(close(f.ps, ps) && close(f.pf, 1.0 - ps), "{f:?} vs ps {ps}");
    for (got, want) in [(f.mtts, mtts), (f.mttf, mttf)] {
        match (got, want) {
            (Some(g), Some(w)) => assert!(close(g, w), "{f:?}: {g} vs {w}"),
            (g, w) => assert_eq!(g.is_some(), w.is_some(), "{f:?}"),
        }
    }
}

/// Writes a BT.CPP v4 file `t.xml` into `dir` — a Sequence `seq` of actions
/// given as `(ID, name)`, declared in a `<TreeNodesModel>` — and the params
/// file `t.params.yaml` with `params`; returns both paths.
pub fn write_xml_sequence(
    dir: &std::path::Path,
    actions: &[(&str, &str)],
    params: &str,
) -> (std::path::PathBuf, std::path::PathBuf) {
    let leaves: String = actions
        .iter()
        .map(|(id, name)| format!("      <{id} name=\"{name}\"/>\n"))
        .collect();
    let model: String = actions
        .iter()
        .map(|(id, _)| format!("<Action ID=\"{id}\"/>"))
        .collect();
    let xml = dir.join("t.xml");
    std::fs::write(
        &xml,
        format!(
            "<root BTCPP_format=\"4\" main_tree_to_execute=\"Main\">\n  <BehaviorTree ID=\"Main\">\n    \
             <Sequence name=\"seq\">\n{leaves}    </Sequence>\n  </BehaviorTree>\n  \
             <TreeNodesModel>{model}</TreeNodesModel>\n</root>"
        ),
    )
    .expect("tree written");
    let path = dir.join("t.params.yaml");
    std::fs::write(&path, params).expect("params written");
    (xml, path)
}

/// Gauss–Legendre nodes and weights on [−1, 1] (Newton on P_n).
pub fn gauss_legendre(n: usize) -> Vec<(f64, f64)> {
    (0..n)
        .map(|i| {
            let mut x = (std::f64::consts::PI * (i as f64 + 0.75) / (n as f64 + 0.5)).cos();
            let mut dp = 0.0;
            for _ in 0..100 {
                let (mut p0, mut p1) = (1.0, x);
                for k in 2..=n {
                    let p2 = ((2 * k - 1) as f64 * x * p1 - (k - 1) as f64 * p0) / k as f64;
                    p0 = p1;
                    p1 = p2;
                }
                dp = n as f64 * (x * p1 - p0) / (x * x - 1.0);
                let step = p1 / dp;
                x -= step;
                if step.abs() < 1e-16 {
                    break;
                }
            }
            (x, 2.0 / ((1.0 - x * x) * dp * dp))
        })
        .collect()
}

/// MTTS of the root from its curve, `E[T·1{S}] / P(S)` with `E[T·1{S}] =
/// ∫ (P(S) − S(t)) dt`, by the trapezoid rule on a 0.1 s grid of `steps`
/// intervals (a check of the order of 1e-3 relative).
pub fn mtts_by_trapezoid(tree: &Tree, ps: f64, steps: usize) -> f64 {
    let times: Vec<f64> = (0..=steps).map(|k| k as f64 * 0.1).collect();
    let pts = curve(tree, 0, &times, &CurveOptions::default()).expect("curve");
    let tail: f64 = pts
        .windows(2)
        .map(|w| 0.05 * ((ps - w[0].success) + (ps - w[1].success)))
        .sum();
    tail / ps
}
