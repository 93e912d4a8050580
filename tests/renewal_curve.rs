//! `π(t)` of the race of a subtree against a renewal process of re-runs
//! with a fixed wait (Nav2's re-planning, `compile::renewal_curve`):
//! against closed forms derived by hand, against the exact figures of
//! `report` (the curve's limit), and against simulation of the published
//! PipelineSequence with its real tick semantics (|z| < 5).

mod common;
use common::*;

use btrel::compile::curve::{curve, CurveOptions};
use btrel::tree::xml::parse_xml_files;
use std::path::Path;

fn race_yaml(d: f64, rerun: &str, rest: &str) -> String {
    format!(
        "tree: {{parallel: {{name: race, success_threshold: 1, failure_threshold: 1, children: [\
         {{until_failure: {{name: replan, child: {{sequence: {{children: [\
         {{action: {{name: wait, ps: 1.0, tau_s: {d}}}}}, {rerun}]}}}}}}}}, {rest}]}}}}"
    )
}

/// `P(Poisson(λ) ≥ n)` as a sum of non-negative terms.
fn poisson_upper(n: usize, lambda: f64) -> f64 {
    if n == 0 {
        return 1.0;
    }
    // P(k) from log-space, then the tail term by term
    let ln_fact: f64 = (1..=n).map(|k| (k as f64).ln()).sum();
    let mut term = (n as f64 * lambda.ln() - lambda - ln_fact).exp();
    let mut sum = 0.0;
    let mut k = n;
    while term > 1e-300 && (term > 1e-20 * sum || (k as f64) < lambda) {
        sum += term;
        k += 1;
        term *= lambda / k as f64;
    }
    sum
}

/// `P(L ≤ x)` for the re-run process whose first wait is `d0` and later
/// ones `d`, each re-plan succeeding w.p. `p` after Exp(a), else failing
/// after Exp(b) (a > b): it fails after n successful runs at `L = d0 + nd +
/// E_n(a) + Exp(b)` w.p. `pⁿ(1 − p)` (`E_n` an Erlang), and `P(E_n(a) +
/// Exp(b) ≤ y) = P(E_n(a) ≤ y) − e^{−by} (a/(a − b))ⁿ P(E_n(a − b) ≤ y)`,
/// `P(E_n(r) ≤ y) = P(Poisson(ry) ≥ n)`.
fn replan_fails_by(x: f64, (p, a, b): (f64, f64, f64), d0: f64, d: f64) -> f64 {
    let mut total = 0.0;
    let mut n = 0;
    while d0 + n as f64 * d < x {
        let y = x - d0 - n as f64 * d;
        let h = poisson_upper(n, a * y)
            - (-b * y).exp() * (a / (a - b)).powi(n as i32) * poisson_upper(n, (a - b) * y);
        total += p.powi(n as i32) * (1.0 - p) * h;
        n += 1;
    }
    total
}

/// `∫_a^b f` by 30-point Gauss–Legendre on panels of width ≤ 0.25 cut at
/// the multiples of `cut` (where the integrand kinks).
fn integrate(f: &dyn Fn(f64) -> f64, a: f64, b: f64, cut: f64) -> f64 {
    let rule = gauss_legendre(30);
    let mut edges = vec![a];
    let mut k = (a / cut).floor() + 1.0;
    while k * cut < b {
        edges.push(k * cut);
        k += 1.0;
    }
    edges.push(b);
    let mut total = 0.0;
    for w in edges.windows(2) {
        let pieces = ((w[1] - w[0]) / 0.25).ceil().max(1.0) as usize;
        let h = (w[1] - w[0]) / pieces as f64;
        for p in 0..pieces {
            let (lo, hi) = (w[0] + p as f64 * h, w[0] + (p + 1) as f64 * h);
            let (mid, half) = ((lo + hi) / 2.0, (hi - lo) / 2.0);
            total += rule
                .iter()
                .map(|&(x, wt)| wt * f(mid + half * x))
                .sum::<f64>()
                * half;
        }
    }
    total
}

/// The curve of a race whose rest R is one action (Success w.p. `s` after
/// Exp(μ), else Failure after Exp(ν)) against a re-run process whose
/// failure time L is independent of R, with `P(L > x)` given: the node
/// succeeds by t iff R's Success time X ≤ t comes before L, so `S(t) = s
/// ∫_0^t μ e^{−μx} P(L > x) dx`, and it is still running at t iff both
/// are, `P(X > t) P(L > t)`.
fn against_one_action(
    survive: &dyn Fn(f64) -> f64,
    (s, mu, nu): (f64, f64, f64),
    d: f64,
    t: f64,
) -> (f64, f64) {
    let success = s * integrate(&|x| mu * (-mu * x).exp() * survive(x), 0.0, t, d);
    let running = (s * (-mu * t).exp() + (1.0 - s) * (-nu * t).exp()) * survive(t);
    (success, 1.0 - success - running)
}

/// Each point of `pts` (at `times`) against `want(t)` = (S, F) by hand.
fn assert_points(
    pts: &[btrel::curve::CurvePoint],
    times: &[f64],
    tol: f64,
    want: impl Fn(f64) -> (f64, f64),
) {
    for (pt, &tt) in pts.iter().zip(times) {
        let what = format!("t = {tt}");
        assert_curve(&what, (pt.success, pt.failure), want(tt), tol);
    }
}

fn assert_curve(what: &str, got: (f64, f64), want: (f64, f64), tol: f64) {
    assert!(
        (got.0 - want.0).abs() <= tol && (got.1 - want.1).abs() <= tol,
        "{what}: curve {got:?} vs hand {want:?} (diff {:.2e}, {:.2e})",
        got.0 - want.0,
        got.1 - want.1
    );
}

#[test]
fn a_bernoulli_replan_every_period_matches_the_closed_form() {
    // the re-plan is a condition: at d, 2d, 3d, … it fails (and fails the
    // node) w.p. 1 − p, so P(L > x) = p^⌊x/d⌋; a failure at t = kd counts
    // at t. p = 0.97 at 2 Hz: the loop's series would need
    // ln(1e-14)/ln(0.97) ≈ 1,060 re-runs.
    let (p, d): (f64, f64) = (0.97, 0.5);
    let rest = (0.8, 0.05, 0.02);
    let t = tree(&race_yaml(
        d,
        &format!("{{condition: {{name: plan, ps: {p}}}}}"),
        "{action: {name: follow, ps: 0.8, mu: 0.05, nu: 0.02}}",
    ));
    let survive = |x: f64| p.powi((x / d + 1e-12).floor() as i32);
    let times = [0.0, 0.2, 0.5, 1.3, 7.0, 30.25, 100.0, 400.0];
    let pts = curve(&t, 0, &times, &CurveOptions::default()).expect("curve");
    assert_points(&pts, &times, 1e-10, |tt| {
        against_one_action(&survive, rest, d, tt)
    });
    // the limit is report's figures
    let f = root_figures(&t);
    let late = curve(&t, 0, &[2000.0], &CurveOptions::default()).unwrap()[0];
    assert!((late.success - f.ps).abs() < 1e-10, "{late:?} vs {f:?}");
    assert!((late.failure - f.pf).abs() < 1e-10, "{late:?} vs {f:?}");
}

#[test]
fn an_exponential_replan_matches_the_closed_form() {
    // the re-plan succeeds w.p. p after Exp(a), else fails after Exp(b):
    // the process fails after n successful cycles at L = (n + 1)d + E_n(a)
    // + Exp(b) (E_n an Erlang), w.p. pⁿ(1 − p); with a > b,
    // P(E_n(a) + Exp(b) ≤ y) = P(E_n(a) ≤ y) − e^{−by} (a/(a − b))ⁿ
    // P(E_n(a − b) ≤ y), P(E_n(r) ≤ y) = P(Poisson(ry) ≥ n).
    let (p, a, b, d): (f64, f64, f64, f64) = (0.9, 2.0, 0.5, 1.0);
    let rest = (0.8, 0.5, 0.25);
    let t = tree(&race_yaml(
        d,
        &format!("{{action: {{name: plan, ps: {p}, mu: {a}, nu: {b}}}}}"),
        "{action: {name: follow, ps: 0.8, mu: 0.5, nu: 0.25}}",
    ));
    let fails_by = |x: f64| replan_fails_by(x, (p, a, b), d, d);
    let survive = |x: f64| 1.0 - fails_by(x);
    let times = [0.3, 1.0, 1.7, 2.5, 4.0, 9.9, 20.0];
    let pts = curve(&t, 0, &times, &CurveOptions::default()).expect("curve");
    assert_points(&pts, &times, 1e-10, |tt| {
        against_one_action(&survive, rest, d, tt)
    });
}

/// The exponential re-plan above against a rest with a **fixed wait**
/// (Nav2's goal-patience trees: `Sequence(wait τ, follow)`), which has no
/// phase chain: the race of the process's law of first failure, from its
/// levels, against the rest's law (`race::renewal_race`; the loop's series
/// would need 306 re-runs). With `G(t) = P(L > t)` as above and the rest
/// returning at τ + X: `P(S) = s ∫ μe^{−μx} G(τ + x) dx`, `E[T·1{S}] = s ∫
/// (τ + x) μe^{−μx} G(τ + x) dx`, `E[T] = ∫ G(t) P(rest running at t) dt`;
/// the curve `S(t)` is the first integral up to `t − τ`. `report` within
/// 1e-9, `curve` within 1e-10.
#[test]
fn a_rest_with_a_fixed_wait_races_the_process_s_law() {
    let (p, a, b, d, tau): (f64, f64, f64, f64, f64) = (0.9, 2.0, 0.5, 1.0, 2.5);
    let (s, mu, nu) = (0.8, 0.5, 0.25);
    let t = tree(&race_yaml(
        d,
        &format!("{{action: {{name: plan, ps: {p}, mu: {a}, nu: {b}}}}}"),
        &format!(
            "{{sequence: {{name: rest, children: [{{action: {{name: patience, ps: 1.0, tau_s: {tau}}}}}, \
             {{action: {{name: follow, ps: {s}, mu: {mu}, nu: {nu}}}}}]}}}}"
        ),
    ));
    let fails_by = |x: f64| replan_fails_by(x, (p, a, b), d, d);
    let survive = |x: f64| 1.0 - fails_by(x);
    // the rest's density is below 1e-17 beyond x = 80
    let far = 80.0;
    let ps = s * integrate(&|x| mu * (-mu * x).exp() * survive(tau + x), 0.0, far, d);
    let ts = s * integrate(
        &|x| (tau + x) * mu * (-mu * x).exp() * survive(tau + x),
        0.0,
        far,
        d,
    );
    let running = |t: f64| {
        if t < tau {
            1.0
        } else {
            s * (-mu * (t - tau)).exp() + (1.0 - s) * (-nu * (t - tau)).exp()
        }
    };
    let mean = integrate(&|t| survive(t) * running(t), 0.0, tau + 2.0 * far, d / 2.0);
    let (pf, tf) = (1.0 - ps, mean - ts);
    let f = root_figures(&t);
    let close = |what: &str, got: f64, want: f64| {
        assert!(
            (got - want).abs() <= 1e-9 * want.abs().max(1.0),
            "{what}: report {got} vs closed form {want} (diff {:.2e})",
            got - want
        );
    };
    close("ps", f.ps, ps);
    close("pf", f.pf, pf);
    close("MTTS", f.mtts.expect("succeeds"), ts / ps);
    close("MTTF", f.mttf.expect("fails"), tf / pf);
    let times = [1.0, 2.5, 3.7, 8.0, 20.0];
    let pts = curve(&t, 0, &times, &CurveOptions::default()).expect("curve");
    assert_points(&pts, &times, 1e-10, |tt| {
        let upto = (tt - tau).max(0.0);
        let success = s * integrate(&|x| mu * (-mu * x).exp() * survive(tau + x), 0.0, upto, d);
        let failure = 1.0 - success - survive(tt) * running(tt);
        (success, failure)
    });
}

/// A SpeedController's pipeline: the re-plan race with a first wait of
/// its own (`d₀` = 1.8 s, then every 1 s) after a prefix A (Success w.p.
/// 0.9 after Exp(3), else Failure after Exp(1)) — off the period's grid, so
/// the levels cannot carry the prefix: the race's law in its own time
/// (`renewal_law`, the levels from `d₀`) convolved with A's by the
/// composed laws. By hand: the process fails after n successful runs at
/// `L = d₀ + nd + E_n(a) + Exp(b)` w.p. `pⁿ(1 − p)` (as above with `d₀`
/// for the first wait), the race's `S_race(t) = s ∫_0^t μe^{−μx} P(L > x)
/// dx`, and the pipeline's `S(t) = 0.9 ∫ 3e^{−3u} S_race(t − u) du`;
/// likewise Failure. Within 1e-10 (it agrees to 1e-12).
#[test]
fn a_first_wait_off_the_grid_after_a_prefix_matches_the_closed_form() {
    let (p, a, b, d, d0): (f64, f64, f64, f64, f64) = (0.9, 2.0, 0.5, 1.0, 1.8);
    let rest = (0.8, 0.5, 0.25);
    let plan = |name: &str| format!("{{action: {{name: {name}, ps: {p}, mu: {a}, nu: {b}}}}}");
    let (first, later) = (plan("first plan"), plan("plan"));
    let race = format!(
        "{{parallel: {{name: race, success_threshold: 1, failure_threshold: 1, children: [\
         {{sequence: {{name: replan, children: [{{action: {{name: first wait, ps: 1.0, tau_s: {d0}}}}}, \
         {first}, {{until_failure: {{name: loop, child: {{sequence: {{children: [\
         {{action: {{name: wait, ps: 1.0, tau_s: {d}}}}}, {later}]}}}}}}}}]}}}}, \
         {{action: {{name: follow, ps: 0.8, mu: 0.5, nu: 0.25}}}}]}}}}"
    );
    let t = tree(&format!(
        "tree: {{sequence: {{name: pipeline, children: [{{action: {{name: A, ps: 0.9, mu: 3.0, nu: 1.0}}}}, {race}]}}}}"
    ));
    let fails_by = |x: f64| replan_fails_by(x, (p, a, b), d0, d);
    let survive = |x: f64| 1.0 - fails_by(x);
    let times = [1.0, 2.5, 4.0, 9.0];
    let pts = curve(&t, 0, &times, &CurveOptions::default()).expect("curve");
    assert_points(&pts, &times, 1e-10, |tt| {
        // the race's kinks sit at d₀ + kd (after A): cut at 0.1 s steps
        let race = |x: f64| against_one_action(&survive, rest, 0.1, x);
        let success = 0.9 * integrate(&|u| 3.0 * (-3.0 * u).exp() * race(tt - u).0, 0.0, tt, 0.1);
        let failure = 0.1 * (1.0 - (-tt).exp())
            + 0.9 * integrate(&|u| 3.0 * (-3.0 * u).exp() * race(tt - u).1, 0.0, tt, 0.1);
        (success, failure)
    });
}

/// A loop without a bound alone (`until_failure(Sequence(wait 0.05 s,
/// plan))`, the re-plan failing 3% of the time: about 300 runs by 15 s)
/// under a Fallback whose second child B then runs (Success w.p. 0.8
/// after Exp(2), else Failure after Exp(1)), with a budget of 1,000 states
/// that the loop's shifted mixture exceeds: the composed laws' loop by
/// doubling. By hand: the loop fails at `L = (n + 1)d + E_n(a) + Exp(b)`
/// w.p. `pⁿ(1 − p)` (as above), so `S(t) = 0.8 ∫_0^t P(L ≤ u)' (1 −
/// e^{−2(t−u)}) du = 0.8 ∫_0^t P(L ≤ u) 2e^{−2(t−u)} du`, and B fails
/// likewise. Within 1e-10.
#[test]
fn a_loop_without_a_bound_composes_by_doubling() {
    let (p, a, b, d): (f64, f64, f64, f64) = (0.97, 20.0, 5.0, 0.05);
    let t = tree(&format!(
        "tree: {{fallback: {{name: top, children: [\
         {{until_failure: {{name: replan, child: {{sequence: {{children: [\
         {{action: {{name: wait, ps: 1.0, tau_s: {d}}}}}, \
         {{action: {{name: plan, ps: {p}, mu: {a}, nu: {b}}}}}]}}}}}}}}, \
         {{action: {{name: B, ps: 0.8, mu: 2.0, nu: 1.0}}}}]}}}}"
    ));
    let fails_by = |x: f64| replan_fails_by(x, (p, a, b), d, d);
    let times = [0.5, 1.5, 3.2, 7.0, 15.0];
    // a budget the loop's shifted mixture (about 300 terms, Erlang-k each)
    // exceeds: the composed laws answer
    let small = CurveOptions {
        max_states: 1000,
        ..CurveOptions::default()
    };
    let pts = curve(&t, 0, &times, &small).expect("curve");
    assert_points(&pts, &times, 1e-10, |tt| {
        // B starts when the loop fails: by parts, S(t) = 0.8 ∫ F_L(u) 2e^{−2(t−u)} du
        let success = 0.8 * integrate(&|u| fails_by(u) * 2.0 * (-2.0 * (tt - u)).exp(), 0.0, tt, d);
        let failure = 0.2 * integrate(&|u| fails_by(u) * (-(tt - u)).exp(), 0.0, tt, d);
        (success, failure)
    });
}

/// The exponential re-plan above after a fast prefix A (Success w.p. 0.9
/// after Exp(10), else Failure after Exp(10)): the race starts when A
/// succeeds, so `S(t) = 0.9 ∫ 10 e^{−10a} S_race(t − a) da`, likewise
/// Failure plus A's own. The prefix's phases die out after a few levels,
/// the rate of the levels drops from A's to the race's, and the later
/// levels step their top alone over the level below it (`Prepared::run`).
#[test]
fn a_fast_prefix_then_an_exponential_replan_matches_the_closed_form() {
    let (p, a, b, d): (f64, f64, f64, f64) = (0.9, 2.0, 0.5, 1.0);
    let rest = (0.8, 0.5, 0.25);
    let yaml = race_yaml(
        d,
        &format!("{{action: {{name: plan, ps: {p}, mu: {a}, nu: {b}}}}}"),
        "{action: {name: follow, ps: 0.8, mu: 0.5, nu: 0.25}}",
    )
    .replacen(
        "tree: {parallel:",
        "tree: {sequence: {name: seq, children: [{action: {name: A, ps: 0.9, mu: 10.0, nu: 10.0}}, {parallel:",
        1,
    ) + "]}}";
    let t = tree(&yaml);
    let fails_by = |x: f64| replan_fails_by(x, (p, a, b), d, d);
    let survive = |x: f64| 1.0 - fails_by(x);
    let times = [3.0, 8.0, 12.0];
    let pts = curve(&t, 0, &times, &CurveOptions::default()).expect("curve");
    assert_points(&pts, &times, 1e-10, |tt| {
        // A's density beyond 4 s is below 1e-16
        let upto = tt.min(4.0);
        let race = |x: f64| against_one_action(&survive, rest, d, x);
        let success = 0.9 * integrate(&|s| 10.0 * (-10.0 * s).exp() * race(tt - s).0, 0.0, upto, d);
        let failure = 0.1 * (1.0 - (-10.0 * tt).exp())
            + 0.9 * integrate(&|s| 10.0 * (-10.0 * s).exp() * race(tt - s).1, 0.0, upto, d);
        (success, failure)
    });
}

#[test]
fn a_prefix_starts_the_race_at_a_random_time() {
    // Sequence(A, race): the race starts when A succeeds (Exp(3), w.p.
    // 0.9); with a re-plan that always succeeds the race is R alone, so
    // the node is A then R in turn: S(t) = 0.9·0.8·P(Exp(3) + Exp(0.5) ≤ t)
    let yaml = race_yaml(
        1.0,
        "{action: {name: plan, ps: 1.0, mu: 2.0}}",
        "{action: {name: follow, ps: 0.8, mu: 0.5, nu: 0.5}}",
    )
    .replacen(
        "tree: {parallel:",
        "tree: {sequence: {name: seq, children: [{action: {name: A, ps: 0.9, mu: 3.0, nu: 1.0}}, {parallel:",
        1,
    ) + "]}}";
    let t = tree(&yaml);
    for tt in [0.5, 1.0, 2.2, 6.0] {
        let pt = curve(&t, 0, &[tt], &CurveOptions::default()).unwrap()[0];
        // P(Exp(3) + Exp(0.5) ≤ t) = 1 − (3e^{−0.5t} − 0.5e^{−3t})/2.5
        let both = 1.0 - (3.0 * (-0.5 * tt).exp() - 0.5 * (-3.0 * tt).exp()) / 2.5;
        let a_fails = 0.1 * (1.0 - (-tt).exp());
        let want = (0.9 * 0.8 * both, a_fails + 0.9 * 0.2 * both);
        assert_curve(&format!("t = {tt}"), (pt.success, pt.failure), want, 1e-12);
    }
}

/// Nav2's default attempt as published (`trees/nav2-default-attempt.xml`).
fn nav2_attempt() -> btrel::tree::Tree {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("trees");
    parse_xml_files(
        &dir.join("nav2-default-attempt.xml"),
        &dir.join("nav2-default-attempt.params.yaml"),
        &[],
    )
    .expect("the attempt parses")
}

#[test]
fn nav2_default_attempt_curve_tends_to_the_report() {
    let t = nav2_attempt();
    let f = root_figures(&t);
    let late = curve(&t, 0, &[1500.0], &CurveOptions::default()).expect("curve")[0];
    assert!(late.running < 1e-12, "{late:?}");
    assert!((late.success - f.ps).abs() < 1e-10, "{late:?} vs {f:?}");
    assert!((late.failure - f.pf).abs() < 1e-10, "{late:?} vs {f:?}");
    // MTTS from the curve: E[T·1{S}] = ∫ (P(S) − S(t)) dt over the levels
    // trapezoid on a 0.1 s grid: a check of the order of 1e-3 relative
    let mtts = mtts_by_trapezoid(&t, f.ps, 15000);
    assert!(
        (mtts - f.mtts.unwrap()).abs() < 1e-3 * f.mtts.unwrap(),
        "{mtts} vs {f:?}"
    );
}

#[test]
fn nav2_default_attempt_curve_matches_simulation() {
    // the simulator runs the published PipelineSequence and RateController
    // with their tick semantics, not the lowering
    let t = nav2_attempt();
    let times = [2.0, 10.0, 30.0, 60.0, 120.0];
    let pts = curve(&t, 0, &times, &CurveOptions::default()).expect("curve");
    let sim = simulate_root(&t, 100_000, &times);
    assert_root_and_curve_within_z("attempt", root_figures(&t), &pts, &sim);
}
