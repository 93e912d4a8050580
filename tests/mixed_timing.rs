//! Parallels that mix deterministic or hybrid actions with stochastic ones
//! (Def. 9.11; the book's Example 9.2 is a deterministic ∥ stochastic
//! Parallel): `report` answers them exactly, agreeing with closed forms
//! derived by hand below, with the limit of `curve`, and with simulation.

mod common;
use common::*;

const E: f64 = std::f64::consts::E;

fn close(what: &str, got: f64, want: f64) {
    assert!(
        (got - want).abs() <= 1e-10 * want.abs().max(1.0),
        "{what}: {got} vs {want}"
    );
}

/// Report vs hand values, the curve's limit, and simulation.
fn check(yaml: &str, ps: f64, mtts: f64, mttf: f64, t_done: f64) {
    let t = tree(yaml);
    let f = root_figures(&t);
    close("ps", f.ps, ps);
    close("pf", f.pf, 1.0 - ps);
    close("MTTS", f.mtts.expect("MTTS"), mtts);
    close("MTTF", f.mttf.expect("MTTF"), mttf);
    let (s, fl) = root_curve_at(&t, t_done);
    assert!((s - ps).abs() < 1e-9 && (fl - (1.0 - ps)).abs() < 1e-9);
    let sim = simulate_root(&t, 400_000, &[]);
    let r = &sim.nodes[0];
    assert_within_z("ps", &r.ps, ps);
    assert_within_z("MTTS", r.mtts.as_ref().expect("successes"), mtts);
    assert_within_z("MTTF", r.mttf.as_ref().expect("failures"), mttf);
}

#[test]
fn example_9_2_deterministic_parallel_stochastic() {
    // A: ps 0.9 at 2 s, else Failure at 1 s. B: ps 0.8, Exp(0.5) / Exp(1).
    // M = N = 2, F = 1. Success iff both: 0.72, at max(2, X), X ~ Exp(0.5):
    // E = 2 + E[(X − 2)⁺] = 2 + 2e^{-1}. Failure: A fails, B would succeed
    // (0.08): at 1; both fail (0.02): at min(1, Y), Y ~ Exp(1), mean
    // 1 − e^{-1}; A succeeds, B fails (0.18): at Y, mean 1.
    let yaml = "tree: {parallel: {children: [\
                {action: {ps: 0.9, tau_s: 2.0, tau_f: 1.0}}, \
                {action: {ps: 0.8, mu: 0.5, nu: 1.0}}]}}";
    let mttf = (0.08 + 0.02 * (1.0 - 1.0 / E) + 0.18) / 0.28;
    check(yaml, 0.72, 2.0 + 2.0 / E, mttf, 80.0);
}

#[test]
fn hybrid_action_beside_a_stochastic_one() {
    // A hybrid (Def. 9.9): ps 0.6 Success at 3 s, else Failure at min(Y, 3),
    // Y ~ Exp(0.5). B: ps 0.5 with Exp(1) either way. M = 1, F = 2.
    // Success (1 − 0.4·0.5 = 0.8):
    //   A S, B S (0.3): min(3, X), mean 1 − e^{-3};  A S, B F (0.3): at 3;
    //   A F, B S (0.2): at X, mean 1.   E[T·1{S}] = 1.4 − 0.3 e^{-3}.
    // Failure (0.2): at max(U, X), U = min(Y, 3):
    //   E[U] + E[X] − E[min(U, X)] = 2(1 − e^{-1.5}) + 1 − (1 − e^{-4.5})/1.5.
    let yaml = "tree: {parallel: {success_threshold: 1, children: [\
                {action: {ps: 0.6, tau_s: 3.0, nu: 0.5}}, \
                {action: {ps: 0.5, mu: 1.0, nu: 1.0}}]}}";
    let mtts = (1.4 - 0.3 * (-3.0f64).exp()) / 0.8;
    let mttf = 2.0 * (1.0 - (-1.5f64).exp()) + 1.0 - (1.0 - (-4.5f64).exp()) / 1.5;
    check(yaml, 0.8, mtts, mttf, 80.0);
}

#[test]
fn mixed_parallels_nested_in_sequences_and_parallels() {
    // No closed form worked out: report against simulation and the curve's
    // limit. An inner mixed Parallel (1 of 2) inside a 2-of-3 Parallel with a
    // deterministic subtree, the whole in a Sequence after a stochastic action.
    let yaml = "tree: {sequence: {children: [\
                {action: {ps: 0.95, mu: 2.0, nu: 1.0}}, \
                {parallel: {success_threshold: 2, children: [\
                  {parallel: {success_threshold: 1, children: [\
                    {action: {ps: 0.5, tau_s: 1.5, tau_f: 0.5}}, \
                    {action: {ps: 0.4, mu: 0.8, nu: 1.2}}]}}, \
                  {sequence: {children: [{action: {ps: 0.9, tau_s: 0.7, tau_f: 0.2}}, \
                                         {action: {ps: 0.8, tau_s: 1.1, tau_f: 0.4}}]}}, \
                  {action: {ps: 0.7, mu: 0.3, nu: 0.9}}]}}]}}";
    let t = tree(yaml);
    assert_root_matches_simulation(&t, 400_000);
    // the Parallel itself (path 0.1): report vs the limit of its curve
    let id = t.find("0.1").expect("the Parallel");
    let a = btrel::analyze(&t, &Default::default()).expect("analysed");
    let p = btrel::curve::curve(&t, id, &[400.0], &Default::default()).expect("curve")[0];
    assert!((p.success - a.nodes[id].ps).abs() < 1e-9);
    assert!((p.failure - a.nodes[id].pf).abs() < 1e-9);
}

#[test]
fn deterministic_then_fallback_with_a_hybrid_matches_closed_form() {
    // Sequence(d: ps 0.9 at 1 s, else Failure at 0.5 s;
    //          Fallback(a: ps 0.8, Exp(2) / Exp(1); h: ps 0.6 at 3 s, else
    //          Failure at U = min(Y, 3), Y ~ Exp(0.5))).
    // With u = t − 1 the Fallback's time:
    //   S(t) = 0.9 [0.8 (1 − e^{-2u}) + 0.12 (1 − e^{-(u−3)}) 1{u ≥ 3}]
    //   F(t) = 0.1·1{t ≥ 0.5} + 0.9 · 0.08 · P(X + U ≤ u), X ~ Exp(1), and
    //   P(X + U ≤ u) = 1 − e^{-u} − 2e^{-u/2}(e^{-max(u−3, 0)/2} − e^{-u/2}).
    let yaml = "tree: {sequence: {children: [{action: {ps: 0.9, tau_s: 1.0, tau_f: 0.5}}, \
                {fallback: {children: [{action: {ps: 0.8, mu: 2.0, nu: 1.0}}, \
                {action: {ps: 0.6, tau_s: 3.0, nu: 0.5}}]}}]}}";
    let t = tree(yaml);
    let exact = |t: f64| -> (f64, f64) {
        let u = t - 1.0;
        let f_d = if t >= 0.5 { 0.1 } else { 0.0 };
        if u < 0.0 {
            return (0.0, f_d);
        }
        let s = 0.9
            * (0.8 * (1.0 - (-2.0 * u).exp())
                + if u >= 3.0 {
                    0.12 * (1.0 - (-(u - 3.0)).exp())
                } else {
                    0.0
                });
        let p = 1.0
            - (-u).exp()
            - 2.0 * (-u / 2.0).exp() * ((-(u - 3.0).max(0.0) / 2.0).exp() - (-u / 2.0).exp());
        (s, f_d + 0.9 * 0.08 * p)
    };
    let times = [0.2, 0.5, 0.7, 1.0, 1.5, 2.5, 3.9, 4.0, 4.1, 6.0, 12.0, 60.0];
    let pts = btrel::curve::curve(&t, 0, &times, &Default::default()).expect("curve");
    for p in &pts {
        let (s, f) = exact(p.t);
        assert!(
            (p.success - s).abs() < 1e-12,
            "t = {}: S {} vs {s}",
            p.t,
            p.success
        );
        assert!(
            (p.failure - f).abs() < 1e-12,
            "t = {}: F {} vs {f}",
            p.t,
            p.failure
        );
    }
    // and against simulation
    let sim = simulate_root(&t, 400_000, &times);
    for (p, e) in pts.iter().zip(&sim.curve) {
        assert_within_z("S(t)", &e.success, p.success);
        assert_within_z("F(t)", &e.failure, p.failure);
    }
}

#[test]
fn random_mixed_trees_report_and_curve_agree_on_every_node() {
    // every tree is answered (no shape is refused), and every node's curve
    // at a time past which it has returned equals its report
    for seed in 0..80 {
        let yaml = random_mixed_tree(seed, 3);
        let t = tree(&yaml);
        let report = btrel::analyze(&t, &Default::default())
            .unwrap_or_else(|e| panic!("seed {seed}: report refused: {e} in {yaml}"));
        for id in 0..t.nodes().len() {
            let f = report.nodes[id];
            let p = btrel::curve::curve(&t, id, &[600.0], &Default::default())
                .unwrap_or_else(|e| panic!("seed {seed} node {id}: curve refused: {e} in {yaml}"));
            assert!(p[0].running < 1e-9, "seed {seed} node {id}: {p:?}");
            assert!(
                (p[0].success - f.ps).abs() < 1e-9 && (p[0].failure - f.pf).abs() < 1e-9,
                "seed {seed} node {id}: curve {p:?} vs report {f:?} in {yaml}"
            );
        }
    }
}

#[test]
fn random_mixed_trees_agree_with_simulation() {
    for seed in 100..160 {
        let yaml = random_mixed_tree(seed, 3);
        let t = tree(&yaml);
        let a = btrel::analyze(&t, &Default::default())
            .unwrap_or_else(|e| panic!("seed {seed}: report refused: {e} in {yaml}"));
        let times = [0.5, 1.5, 4.0];
        let pts = btrel::curve::curve(&t, 0, &times, &Default::default())
            .unwrap_or_else(|e| panic!("seed {seed}: curve refused: {e} in {yaml}"));
        let sim = simulate_root(&t, 100_000, &times);
        assert_root_and_curve_within_z(&format!("seed {seed}"), a.nodes[0], &pts, &sim);
    }
}

#[test]
fn bt_cpp_sleep_and_delay_are_fixed_times() {
    // Sleep 500 ms, then Delay 1500 ms before Step (ps 0.8, Exp(2) / Exp(1)):
    // Step starts at 2 s, so S(t) = 0.8 (1 − e^{-2(t−2)}), F(t) = 0.2 (1 −
    // e^{-(t−2)}) for t ≥ 2, nothing before; MTTS = 2.5, MTTF = 3.
    let xml = r#"<root BTCPP_format="4"><BehaviorTree ID="M"><Sequence>
        <Sleep msec="500"/>
        <Delay delay_msec="1500"><Step/></Delay>
      </Sequence></BehaviorTree></root>"#;
    let t = btrel::tree::xml::parse_xml_str(
        xml,
        "d.xml",
        "Step: {ps: 0.8, mu: 2.0, nu: 1.0}\n",
        "d.params.yaml",
    )
    .expect("read");
    let f = root_figures(&t);
    close("MTTS", f.mtts.unwrap(), 2.5);
    close("MTTF", f.mttf.unwrap(), 3.0);
    let pts =
        btrel::curve::curve(&t, 0, &[1.0, 1.999, 2.0, 2.5, 4.0], &Default::default()).unwrap();
    for p in pts {
        let u = (p.t - 2.0).max(0.0);
        let s = 0.8 * (1.0 - (-2.0 * u).exp());
        let fl = 0.2 * (1.0 - (-u).exp());
        assert!(
            (p.success - s).abs() < 1e-12 && (p.failure - fl).abs() < 1e-12,
            "{p:?}"
        );
    }
}

/// `P(Gamma(n, rate) ≤ x)` for an integer shape `n` (Erlang).
fn erlang_cdf(n: u32, rate: f64, x: f64) -> f64 {
    if x <= 0.0 {
        return 0.0;
    }
    let (mut term, mut sum) = (1.0, 1.0);
    for k in 1..n {
        term *= rate * x / k as f64;
        sum += term;
    }
    1.0 - (-rate * x).exp() * sum
}

/// BT.CPP's `Timeout` over a loop with a fixed wait whose series, unbounded,
/// exceeds the budget (`p = 0.999`: the unrolled repetitions would hold
/// about 4e6 phases): the deadline ends the node by 3 s, so only the
/// repetitions that start by then are built (`shifted_law_within`).
///
/// Closed form: the watch loop repeats `wait 0.1; check` until the check
/// fails (each check Exp(20) long whatever its outcome, failing w.p.
/// 0.001), so after N ~ Geometric(0.001) checks it fails at `L = 0.1 N +
/// Gamma(N, 20)`; then `fix` succeeds after Y ~ Exp(1) w.p. 0.9. With `x =
/// t − 0.1 n`, `P(Gamma(n, 20) + Y ≤ x) = P(Gamma(n, 20) ≤ x) − e^{−x}
/// (20/19)^n P(Gamma(n, 19) ≤ x)`, so `S(t) = 0.9 Σ_n 0.001·0.999^{n−1}
/// P(Gamma(n, 20) + Y ≤ t − 0.1 n)` for t < 3, and `P(S) = S(3⁻)`.
#[test]
fn a_timeout_over_a_long_loop_with_a_fixed_wait_is_exact() {
    let yaml = "tree: {parallel: {name: timeout, success_threshold: 1, failure_threshold: 1, \
        children: [{action: {name: deadline, ps: 0.0, pf: 1.0, tau_f: 3}}, \
        {fallback: {children: [{until_failure: {name: watch, child: {sequence: {children: [\
        {action: {ps: 1.0, tau_s: 0.1}}, {action: {name: check, ps: 0.999, mu: 20, nu: 20}}]}}}}, \
        {action: {name: fix, ps: 0.9, mu: 1, nu: 2}}]}}]}}";
    let s = |t: f64| -> f64 {
        (1..)
            .map(|n: u32| (n, t - 0.1 * n as f64))
            .take_while(|&(_, x)| x > 0.0)
            .map(|(n, x)| {
                let pn = 0.001 * 0.999f64.powi(n as i32 - 1);
                let both = erlang_cdf(n, 20.0, x)
                    - (-x).exp() * (20.0f64 / 19.0).powi(n as i32) * erlang_cdf(n, 19.0, x);
                0.9 * pn * both
            })
            .sum()
    };
    let t = tree(yaml);
    let f = root_figures(&t);
    close("ps", f.ps, s(3.0));
    close("pf", f.pf, 1.0 - s(3.0));
    let times = [1.0, 2.0, 2.95, 3.0, 5.0];
    let pts = btrel::curve::curve(&t, 0, &times, &Default::default()).expect("curve");
    for p in &pts {
        let want = if p.t < 3.0 { s(p.t) } else { s(3.0) };
        close(&format!("S({})", p.t), p.success, want);
    }
    assert_eq!(pts[3].running, 0.0, "{pts:?}");
    let sim = simulate_root(&t, 400_000, &times);
    assert_root_and_curve_within_z("timeout over a loop", f, &pts, &sim);
}

/// A Parallel over a Retry of hybrid actions (fixed successes, shifted
/// exponential failures): the Retry's shifted mixture has hundreds of
/// components, and its mean times need none of them (flows of figures),
/// but the quadrature of the Parallel's mean times read its cut points
/// from that mixture built within the whole budget, and refused the tree
/// under `--max-states 300` ("needs a chain of up to 508 states") until
/// 2026-12-07. Cut points are read within a small budget now: the figures
/// under 300 states are those under the default budget, and agree with
/// simulation.
#[test]
fn a_parallel_reads_its_cut_points_within_a_small_budget() {
    let t = tree(
        "tree:\n  parallel:\n    success_threshold: 2\n    children:\n      - action: {ps: 0.9, mu: 1, nu: 2}\n      - retry:\n          attempts: 6\n          child:\n            sequence:\n              children:\n                - action: {ps: 0.7, success_time: {fixed: 0.11}, failure_time: {shift: 0.013, rate: 2}}\n                - action: {ps: 0.7, success_time: {fixed: 0.23}, failure_time: {shift: 0.029, rate: 3}}\n                - action: {ps: 0.7, success_time: {fixed: 0.37}, failure_time: {shift: 0.047, rate: 5}}\n",
    );
    let small = btrel::analyze(
        &t,
        &btrel::Options {
            max_states: 300,
            ..btrel::Options::default()
        },
    )
    .expect("answered under 300 states")
    .nodes[0];
    let f = root_figures(&t);
    close("ps", small.ps, f.ps);
    close("MTTS", small.mtts.unwrap(), f.mtts.unwrap());
    close("MTTF", small.mttf.unwrap(), f.mttf.unwrap());
    let sim = simulate_root(&t, 400_000, &[]);
    let r = &sim.nodes[0];
    assert_within_z("ps", &r.ps, small.ps);
    assert_within_z(
        "MTTS",
        r.mtts.as_ref().expect("successes"),
        small.mtts.unwrap(),
    );
    assert_within_z(
        "MTTF",
        r.mttf.as_ref().expect("failures"),
        small.mttf.unwrap(),
    );
}
