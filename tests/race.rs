//! Parallels whose two thresholds can both be met ("races": F < N − M + 1)
//! over children with mixed timing, and loops without a bound inside
//! Parallels: closed forms derived by hand below (Laplace transforms and
//! renewal arguments), BT.CPP's tie rule, `report` = the limit of `curve`
//! on random trees, and simulation.

mod common;
use common::*;

use std::f64::consts::E;

fn close(what: &str, got: f64, want: f64, tol: f64) {
    assert!(
        (got - want).abs() <= tol * want.abs().max(1.0),
        "{what}: {got} vs {want} (diff {:.2e})",
        got - want
    );
}

/// Nav2's re-planning race: `until_failure(Sequence(wait 1 s, planner))`
/// (every 1 s after a successful plan, plan again; fail at the first failed
/// plan) raced by Parallel{M = 1, F = 1} against the path follower.
const NAV2_RACE: &str = "tree: {parallel: {name: race, success_threshold: 1, \
    failure_threshold: 1, children: [\
    {until_failure: {name: replan, child: {sequence: {children: [\
      {action: {name: wait, ps: 1.0, tau_s: 1.0}}, \
      {action: {name: planner, ps: 0.7, mu: 2.0, nu: 1.0}}]}}}}, \
    {action: {name: follow, ps: 0.9, mu: 0.2, nu: 0.5}}]}}";

/// Closed forms of [`NAV2_RACE`] by a renewal argument. One round of the
/// loop: the wait (1 s), then the planner: again (Success) with Laplace
/// transform `a(s) = 0.7 e^{-s} 2/(2+s)`, end (Failure) with `b(s) = 0.3
/// e^{-s}/(1+s)`; the loop's time T_L has `L(s) = E[e^{-sT_L}] = b/(1 − a)`
/// (it always fails). The node returns at the first return: Success iff
/// the follower (Exp(0.2) w.p. 0.9) succeeds before T_L, so with X ~ Exp(μ)
/// `P(S) = 0.9 (1 − L(μ))` and `E[T·1{S}] = 0.9 ∫ t μe^{-μt} (1 − F_L(t)) dt
/// = 0.9 (1/μ − L(μ)/μ + L'(μ))`; `E[T] = E[min(T_A, T_L)] = Σ_o p_o (1 −
/// L(r_o))/r_o` over the follower's outcomes (rates r_o).
fn nav2_closed_form() -> [f64; 3] {
    let a = |s: f64| 0.7 * (-s).exp() * 2.0 / (2.0 + s);
    let b = |s: f64| 0.3 * (-s).exp() / (1.0 + s);
    let l = |s: f64| b(s) / (1.0 - a(s));
    let dl = |s: f64| {
        let (x, y) = (a(s), b(s));
        let (dx, dy) = (-x * (1.0 + 1.0 / (2.0 + s)), -y * (1.0 + 1.0 / (1.0 + s)));
        (dy * (1.0 - x) + y * dx) / (1.0 - x).powi(2)
    };
    let (ps, mu, nu) = (0.9, 0.2, 0.5);
    let p_s = ps * (1.0 - l(mu));
    let t_s = ps * (1.0 / mu - l(mu) / mu + dl(mu));
    let mean = ps * (1.0 - l(mu)) / mu + (1.0 - ps) * (1.0 - l(nu)) / nu;
    [p_s, t_s / p_s, (mean - t_s) / (1.0 - p_s)]
}

/// `(S(t), F(t))` of [`NAV2_RACE`] before the second round can end (t ≤ 2):
/// the loop cannot return before 1 s, and in [1, 2] only by a failed first
/// plan, with density `0.3 e^{-(t−1)}`.
fn nav2_early(t: f64) -> (f64, f64) {
    let (ps, mu, nu) = (0.9f64, 0.2f64, 0.5f64);
    let pf = 1.0 - ps;
    if t <= 1.0 {
        return (ps * (1.0 - (-mu * t).exp()), pf * (1.0 - (-nu * t).exp()));
    }
    // ∫_1^t r e^{-ru} (1 − 0.3 (1 − e^{-(u−1)})) du
    let side = |r: f64| {
        (1.0 - (-r).exp())
            + 0.7 * ((-r).exp() - (-r * t).exp())
            + 0.3 * r * E / (r + 1.0) * ((-(r + 1.0)).exp() - (-(r + 1.0) * t).exp())
    };
    // ∫_1^t 0.3 e^{-(u−1)} P(follower still running at u) du
    let lead = |r: f64| (((-(r + 1.0)).exp()) - (-(r + 1.0) * t).exp()) / (r + 1.0);
    let loop_first = 0.3 * E * (ps * lead(mu) + pf * lead(nu));
    (ps * side(mu), pf * side(nu) + loop_first)
}

#[test]
fn nav2_replanning_race_matches_its_renewal_closed_form() {
    let t = tree(NAV2_RACE);
    let [ps, mtts, mttf] = nav2_closed_form();
    let f = root_figures(&t);
    close("ps", f.ps, ps, 1e-9);
    close("pf", f.pf, 1.0 - ps, 1e-9);
    close("MTTS", f.mtts.unwrap(), mtts, 1e-9);
    close("MTTF", f.mttf.unwrap(), mttf, 1e-9);
    let times = [0.3, 0.999, 1.0, 1.5, 2.0, 3.5, 8.0, 200.0];
    let pts = btrel::curve::curve(&t, 0, &times, &Default::default()).unwrap();
    for p in &pts[..5] {
        let (s, fl) = nav2_early(p.t);
        close(&format!("S({})", p.t), p.success, s, 1e-11);
        close(&format!("F({})", p.t), p.failure, fl, 1e-11);
    }
    // the curve's limit is the report
    close("S(∞)", pts[7].success, f.ps, 1e-9);
    close("F(∞)", pts[7].failure, f.pf, 1e-9);
    let sim = simulate_root(&t, 300_000, &times[..7]);
    let r = &sim.nodes[0];
    assert_within_z("ps", &r.ps, ps);
    assert_within_z("MTTS", r.mtts.as_ref().unwrap(), mtts);
    assert_within_z("MTTF", r.mttf.as_ref().unwrap(), mttf);
    for (p, e) in pts.iter().zip(&sim.curve) {
        assert_within_z(&format!("S({})", p.t), &e.success, p.success);
        assert_within_z(&format!("F({})", p.t), &e.failure, p.failure);
    }
}

#[test]
fn the_replanning_loop_alone_is_a_geometric_series() {
    // The loop's own curve (a truncated geometric series of shifted
    // components): F_L(t) = Σ_k 0.7^k 0.3 P(k + 1 + Erlang(k, 2) + Exp(1) ≤ t).
    // For t < 3 only k ≤ 1 count: k = 0: 0.3 (1 − e^{-(t−1)}) for t ≥ 1;
    // k = 1: 0.21 P(Exp(2) + Exp(1) ≤ t − 2) = 0.21 (1 − 2e^{-u} + e^{-2u}).
    let t = tree(NAV2_RACE);
    let id = t.find("replan").unwrap();
    let times = [0.5, 1.5, 2.5, 2.9];
    let pts = btrel::curve::curve(&t, id, &times, &Default::default()).unwrap();
    for p in &pts {
        let mut want = 0.0;
        if p.t >= 1.0 {
            want += 0.3 * (1.0 - (-(p.t - 1.0)).exp());
        }
        if p.t >= 2.0 {
            let u = p.t - 2.0;
            want += 0.21 * (1.0 - 2.0 * (-u).exp() + (-2.0 * u).exp());
        }
        close(&format!("F_L({})", p.t), p.failure, want, 1e-12);
        assert_eq!(p.success, 0.0);
    }
    // MTTF = (0.7/0.3)·1.5 + 2 = 5.5 (renewal: E[again] = 1.5, E[end] = 2)
    let a = btrel::analyze(&t, &Default::default()).unwrap();
    close("loop MTTF", a.nodes[id].mttf.unwrap(), 5.5, 1e-12);
    let far = btrel::curve::curve(&t, id, &[120.0], &Default::default()).unwrap();
    close("F_L(∞)", far[0].failure, 1.0, 1e-12);
}

#[test]
fn a_markovian_loop_inside_a_parallel_is_phase_type() {
    // patrol: until_failure over Exp(1) with ps 0.5: a Geometric(1/2) sum of
    // Exp(1) is Exp(0.5), always Failure. Raced (M = F = 1) by A: Exp(1),
    // ps 0.5: min is Exp(1.5); Success iff A is first and succeeds:
    // P(S) = 0.5 · 1/1.5 = 1/3, MTTS = MTTF = 1/1.5.
    let t = tree(
        "tree: {parallel: {success_threshold: 1, failure_threshold: 1, children: [\
         {until_failure: {name: patrol, child: {action: {ps: 0.5, mu: 1.0, nu: 1.0}}}}, \
         {action: {ps: 0.5, mu: 1.0, nu: 1.0}}]}}",
    );
    let f = root_figures(&t);
    close("ps", f.ps, 1.0 / 3.0, 1e-12);
    close("MTTS", f.mtts.unwrap(), 1.0 / 1.5, 1e-12);
    close("MTTF", f.mttf.unwrap(), 1.0 / 1.5, 1e-12);
    let pts = btrel::curve::curve(&t, 0, &[0.4, 2.0], &Default::default()).unwrap();
    for p in pts {
        let done = 1.0 - (-1.5 * p.t).exp();
        close("S(t)", p.success, done / 3.0, 1e-12);
        close("F(t)", p.failure, 2.0 * done / 3.0, 1e-12);
    }
    // and inside a book Parallel beside a deterministic action (counted):
    // M = 2 of [patrol-like loop that always fails, ...] is refused by no one
    let t = tree(
        "tree: {parallel: {success_threshold: 1, children: [\
         {until_failure: {child: {sequence: {children: [{action: {ps: 1.0, tau_s: 0.5}}, \
           {action: {ps: 0.5, mu: 1.0, nu: 1.0}}]}}}}, \
         {action: {ps: 0.5, tau_s: 2.0, tau_f: 1.0}}]}}",
    );
    // M = 1, F = 2: Success iff the action succeeds (the loop only fails):
    // at 2 s, whatever the loop does.
    let f = root_figures(&t);
    close("ps", f.ps, 0.5, 1e-12);
    close("MTTS", f.mtts.unwrap(), 2.0, 1e-9);
    assert_root_matches_simulation(&t, 100_000);
}

/// A deadline (ps 0, Failure at 1 s) first, B (ps 0.7: Success at 1 s,
/// else Failure at 0.5 s), C (ps 0.5, Exp(1) / Exp(2)); M = F = 1: the first
/// return wins, and at 1 s the deadline and B tie.
fn deadline_race(deadline_first: bool) -> String {
    let deadline = "{action: {name: deadline, ps: 0.0, tau_f: 1.0}}";
    let b = "{action: {name: b, ps: 0.7, tau_s: 1.0, tau_f: 0.5}}";
    let c = "{action: {name: c, ps: 0.5, mu: 1.0, nu: 2.0}}";
    let kids = if deadline_first {
        format!("{deadline}, {b}, {c}")
    } else {
        format!("{b}, {deadline}, {c}")
    };
    format!(
        "tree: {{parallel: {{success_threshold: 1, failure_threshold: 1, children: [{kids}]}}}}"
    )
}

#[test]
fn ties_at_an_instant_follow_child_order() {
    // E[X; X < a] for X ~ Exp(r): (1 − e^{-ra}(1 + ra))/r.
    let part = |r: f64, a: f64| (1.0 - (-r * a).exp() * (1.0 + r * a)) / r;
    let cdf = |r: f64, a: f64| 1.0 - (-r * a).exp();
    // C wins if it returns before B's (or the deadline's) instant
    let ps_c_wins = 0.3 * 0.5 * cdf(1.0, 0.5) + 0.7 * 0.5 * cdf(1.0, 1.0);
    let ts_c_wins = 0.3 * 0.5 * part(1.0, 0.5) + 0.7 * 0.5 * part(1.0, 1.0);
    let c_late_05 = 0.5 * (-0.5f64).exp() + 0.5 * (-1.0f64).exp();
    let c_late_1 = 0.5 * (-1.0f64).exp() + 0.5 * (-2.0f64).exp();
    let tf_common = 0.3 * (0.5 * part(2.0, 0.5) + c_late_05 * 0.5) + 0.7 * 0.5 * part(2.0, 1.0);
    for deadline_first in [true, false] {
        let t = tree(&deadline_race(deadline_first));
        let f = root_figures(&t);
        // at 1 s (probability 0.7 · P(C later than 1)) the first child wins
        let (ps, ts, tf) = if deadline_first {
            (ps_c_wins, ts_c_wins, tf_common + 0.7 * c_late_1)
        } else {
            (
                ps_c_wins + 0.7 * c_late_1,
                ts_c_wins + 0.7 * c_late_1,
                tf_common,
            )
        };
        close("ps", f.ps, ps, 1e-10);
        close("MTTS", f.mtts.unwrap(), ts / ps, 1e-10);
        close("MTTF", f.mttf.unwrap(), tf / (1.0 - ps), 1e-10);
        // the curve jumps at 1 s by the tie's atom
        let pts = btrel::curve::curve(&t, 0, &[0.999999, 1.0, 50.0], &Default::default()).unwrap();
        let jump_s = pts[1].success - pts[0].success;
        let jump_f = pts[1].failure - pts[0].failure;
        let atom = 0.7 * c_late_1;
        if deadline_first {
            assert!(jump_s < 1e-6 && (jump_f - atom).abs() < 1e-6, "{pts:?}");
        } else {
            assert!(jump_f < 1e-6 && (jump_s - atom).abs() < 1e-6, "{pts:?}");
        }
        close("S(∞)", pts[2].success, f.ps, 1e-9);
        assert_root_matches_simulation(&t, 100_000);
    }
}

#[test]
fn a_two_of_three_race_with_one_failure_to_fail() {
    // M = 2, F = 1 over three independent children with every timing:
    // A fixed (Success at 1 w.p. 0.8, else Failure at 2), B Exp(1) with ps
    // 0.6 (Exp(1) either way), C a hybrid (Success at 1.5 w.p. 0.5, else
    // Failure at min(Y, 1.5), Y ~ Exp(1)). Success needs two successes
    // before any failure. Checked against simulation and the curve's limit;
    // P(S) by hand: with B's time X ~ Exp(1) (independent of its outcome):
    // A S & C S (0.4): Success at 1.5 unless B fails before 1.5:
    //   0.4 (0.6 + 0.4 e^{-1.5}) — plus A S & B S before 1.5 ... already
    //   counted (B's success is a second success only if before C's).
    // Enumerate: Success iff two successes come before the first failure.
    // A S (0.8, t=1), C S (0.5, t=1.5), B S (0.6, t=X) / B F (0.4, t=X);
    // C F at U = min(Y, 1.5) w.p. 0.5.
    let t = tree(
        "tree: {parallel: {success_threshold: 2, failure_threshold: 1, children: [\
         {action: {ps: 0.8, tau_s: 1.0, tau_f: 2.0}}, \
         {action: {ps: 0.6, mu: 1.0, nu: 1.0}}, \
         {action: {ps: 0.5, tau_s: 1.5, nu: 1.0}}]}}",
    );
    // By hand, conditioning on A and C:
    //  A S, C S (0.4): two successes by 1.5 at the latest; fails only if B
    //   fails before the second success: B F at X < 1 (before A), or X in
    //   [1, 1.5) (before C); so Success w.p. 1 − 0.4 (1 − e^{-1.5}) … but if
    //   B succeeds at X < 1.5 then A (1) and B make two: Success anyway.
    //  A S, C F (0.4): C fails at U = min(Y, 1.5). Success iff B succeeds
    //   and both A (1) and B (X) come before U: 0.6 P(max(1, X) < U).
    //  A F, C S (0.1): A fails at 2; C at 1.5: Success iff B succeeds before 2.
    //  A F, C F (0.1): Success iff B S and A? no: A fails; one success
    //   at most: never.
    let e = |x: f64| (-x).exp();
    let p_ss = 0.4 * (1.0 - 0.4 * (1.0 - e(1.5)));
    // P(max(1, X) < U), X, Y ~ Exp(1), U = min(Y, 1.5): need Y > 1 and
    // X < min(Y, 1.5): ∫ over Y: Y in (1, 1.5): e^{-y}(1 − e^{-y}) dy; Y ≥ 1.5:
    // e^{-1.5}(1 − e^{-1.5}).
    let inner = (e(1.0) - e(1.5)) - (e(2.0) - e(3.0)) / 2.0 + e(1.5) * (1.0 - e(1.5));
    let p_sf = 0.4 * 0.6 * inner;
    let p_fs = 0.1 * 0.6 * (1.0 - e(2.0));
    let ps = p_ss + p_sf + p_fs;
    let f = root_figures(&t);
    close("ps", f.ps, ps, 1e-10);
    let pts = btrel::curve::curve(&t, 0, &[80.0], &Default::default()).unwrap();
    close("S(∞)", pts[0].success, f.ps, 1e-9);
    close("F(∞)", pts[0].failure, f.pf, 1e-9);
    assert_root_matches_simulation(&t, 200_000);
}

/// A random race-heavy tree: Parallels with random thresholds (mostly an
/// independent F) over actions of every timing, conditions, loops (over a
/// Sequence of a fixed wait and a stochastic step, or over an action) and
/// nested Parallels.
fn random_race(rng: &mut rand_xoshiro::Xoshiro256PlusPlus, depth: usize) -> String {
    use rand::RngExt;
    let ps = |rng: &mut rand_xoshiro::Xoshiro256PlusPlus| rng.random_range(1..10) as f64 / 10.0;
    let rate = |rng: &mut rand_xoshiro::Xoshiro256PlusPlus| 0.5 + 2.0 * rng.random::<f64>();
    let tenth = |rng: &mut rand_xoshiro::Xoshiro256PlusPlus| rng.random_range(1..16) as f64 / 10.0;
    let leaf = |rng: &mut rand_xoshiro::Xoshiro256PlusPlus| {
        let p = ps(rng);
        match rng.random_range(0..7) {
            0 | 1 => format!("{{action: {{ps: {p}, mu: {}, nu: {}}}}}", rate(rng), rate(rng)),
            2 => format!("{{action: {{ps: {p}, tau_s: {}, tau_f: {}}}}}", tenth(rng), tenth(rng)),
            3 => format!("{{action: {{ps: {p}, tau_s: {}, nu: {}}}}}", tenth(rng), rate(rng)),
            4 => format!(
                "{{until_failure: {{child: {{sequence: {{children: [\
                 {{action: {{ps: 1.0, tau_s: {}}}}}, {{action: {{ps: {}, mu: {}, nu: {}}}}}]}}}}}}}}",
                tenth(rng),
                ps(rng).min(0.6),
                rate(rng),
                rate(rng)
            ),
            5 => format!(
                "{{until_success: {{child: {{action: {{ps: {}, mu: {}, nu: {}}}}}}}}}",
                ps(rng).max(0.4),
                rate(rng),
                rate(rng)
            ),
            _ => format!("{{condition: {{ps: {p}}}}}"),
        }
    };
    if depth == 0 || rng.random::<f64>() < 0.3 {
        return leaf(rng);
    }
    let n = rng.random_range(2..4usize);
    let kids: Vec<String> = (0..n).map(|_| random_race(rng, depth - 1)).collect();
    let m = rng.random_range(1..=n);
    let f = rng.random_range(1..=n);
    format!(
        "{{parallel: {{success_threshold: {m}, failure_threshold: {f}, children: [{}]}}}}",
        kids.join(", ")
    )
}

#[test]
fn random_races_report_is_the_limit_of_the_curve_and_agrees_with_simulation() {
    use rand::SeedableRng;
    let mut simulated = 0;
    for seed in 0..12u64 {
        let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(seed);
        let yaml = format!("tree: {}\n", random_race(&mut rng, 2));
        let t = tree(&yaml);
        let a = btrel::analyze(&t, &Default::default())
            .unwrap_or_else(|e| panic!("seed {seed}: {e} in {yaml}"));
        // the root and its children (deeper nodes are such nodes of other seeds)
        let top = std::iter::once(0).chain(t.nodes()[0].kind.children().iter().copied());
        for id in top {
            let pts = btrel::curve::curve(&t, id, &[150.0], &Default::default())
                .unwrap_or_else(|e| panic!("seed {seed} node {id}: {e} in {yaml}"));
            let f = a.nodes[id];
            assert!(
                (pts[0].success - f.ps).abs() < 1e-9 && (pts[0].failure - f.pf).abs() < 1e-9,
                "seed {seed} node {id}: curve {:?} vs report {f:?} in {yaml}",
                pts[0]
            );
        }
        if seed % 3 == 0 {
            simulated += 1;
            let times = [0.5, 1.2, 3.0];
            let pts = btrel::curve::curve(&t, 0, &times, &Default::default()).unwrap();
            let sim = simulate_root(&t, 40_000, &times);
            assert_root_and_curve_within_z(&format!("seed {seed}"), a.nodes[0], &pts, &sim);
        }
    }
    assert_eq!(simulated, 4);
}

#[test]
fn xml_timeout_is_a_race_against_a_deadline_that_wins_ties() {
    // Timeout 1500 ms over Step (ps 0.8, Exp(1) / Exp(2)): Success iff Step
    // succeeds before 1.5 s: 0.8 (1 − e^{-1.5}), MTTS = E[X | X < 1.5];
    // Failure: Step fails first (before 1.5), or the deadline at 1.5.
    let xml = r#"<root BTCPP_format="4"><BehaviorTree ID="M"><Sequence>
        <Timeout name="t" msec="1500"><Step/></Timeout>
        <Timeout name="tie" msec="1000"><Sleep msec="1000"/></Timeout>
        <Timeout name="none" msec="0"><Step/></Timeout>
      </Sequence></BehaviorTree></root>"#;
    let params = "Step: {ps: 0.8, mu: 1.0, nu: 2.0}\n";
    let t = btrel::tree::xml::parse_xml_str(xml, "t.xml", params, "t.params.yaml").unwrap();
    let a = btrel::analyze(&t, &Default::default()).unwrap();
    let id = t.find("t").unwrap();
    assert!(t.find("t/deadline").is_some());
    let e = |x: f64| (-x).exp();
    let ps = 0.8 * (1.0 - e(1.5));
    let ts = 0.8 * (1.0 - e(1.5) * 2.5);
    let tf = 0.2 * (1.0 - e(3.0) * 4.0) / 2.0 + (1.0 - ps - 0.2 * (1.0 - e(3.0))) * 1.5;
    let f = a.nodes[id];
    close("ps", f.ps, ps, 1e-10);
    close("MTTS", f.mtts.unwrap(), ts / ps, 1e-10);
    close("MTTF", f.mttf.unwrap(), tf / (1.0 - ps), 1e-10);
    // a child returning exactly at the deadline: the timer fires first
    let tie = a.nodes[t.find("tie").unwrap()];
    assert_eq!((tie.ps, tie.pf), (0.0, 1.0));
    close("tie MTTF", tie.mttf.unwrap(), 1.0, 1e-12);
    // msec = 0: BT.CPP starts no timer: the child's own figures
    let none = a.nodes[t.find("none").unwrap()];
    close("no timer ps", none.ps, 0.8, 1e-12);
    close("no timer MTTS", none.mtts.unwrap(), 1.0, 1e-12);
    let sim = btrel::sim::simulate(
        &t,
        &btrel::sim::SimOptions {
            runs: 100_000,
            ..Default::default()
        },
        None,
    )
    .unwrap();
    // the root first, then every node in tree order
    assert_within_z("ps", &sim.nodes[id].ps, ps);
    assert_within_z("MTTS", sim.nodes[id].mtts.as_ref().unwrap(), ts / ps);
    let tie = &sim.nodes[t.find("tie").unwrap()];
    assert_within_z("tie pf", &tie.pf, 1.0);
}

/// A Sequence above a race of exponential actions, `Sequence(A,
/// Parallel{1, 1}(B, C))`, by the composed laws (a budget of 2 states: the
/// race's product chain does not fit, its children do), against a closed
/// form: the race returns with the first of B and C, so its Success density
/// is `Σ_X ps_X μ_X e^{−μ_X t} · P(the other running at t)` (`P(running) =
/// ps e^{−μt} + pf e^{−νt}`), a sum of terms `c e^{−λt}`, likewise Failure;
/// after A's Success (density `pa μa e^{−μa t}`) a term contributes
/// `pa μa c ((1 − e^{−λt})/λ − (1 − e^{−μa t})/μa)/(μa − λ)` by t.
#[test]
fn a_sequence_above_a_race_composes_the_race_s_law() {
    let (pa, ma, na) = (0.9, 2.0, 3.0);
    let (pb, mb, nb) = (0.7, 0.5, 1.5);
    let (pc, mc, nc) = (0.6, 0.8, 0.3);
    let (qb, qc) = (1.0 - pb, 1.0 - pc);
    let yaml = format!(
        "tree: {{sequence: {{children: [{{action: {{name: A, ps: {pa}, mu: {ma}, nu: {na}}}}}, \
         {{parallel: {{name: race, success_threshold: 1, failure_threshold: 1, children: [\
         {{action: {{name: B, ps: {pb}, mu: {mb}, nu: {nb}}}}}, \
         {{action: {{name: C, ps: {pc}, mu: {mc}, nu: {nc}}}}}]}}}}]}}}}"
    );
    let success = [
        (pb * mb * pc, mb + mc),
        (pb * mb * qc, mb + nc),
        (pc * mc * pb, mc + mb),
        (pc * mc * qb, mc + nb),
    ];
    let failure = [
        (qb * nb * pc, nb + mc),
        (qb * nb * qc, nb + nc),
        (qc * nc * pb, nc + mb),
        (qc * nc * qb, nc + nb),
    ];
    let after_a = |terms: &[(f64, f64)], t: f64| -> f64 {
        terms
            .iter()
            .map(|&(c, l)| {
                pa * ma * c * ((1.0 - (-l * t).exp()) / l - (1.0 - (-ma * t).exp()) / ma) / (ma - l)
            })
            .sum()
    };
    let t = tree(&yaml);
    let times = [0.3, 1.0, 2.5, 6.0];
    let opts = btrel::curve::CurveOptions {
        max_states: 2,
        ..Default::default()
    };
    let pts = btrel::curve::curve(&t, 0, &times, &opts).expect("curve by the composed laws");
    for p in &pts {
        let s = after_a(&success, p.t);
        let f = (1.0 - pa) * (1.0 - (-na * p.t).exp()) + after_a(&failure, p.t);
        close(&format!("S({})", p.t), p.success, s, 1e-9);
        close(&format!("F({})", p.t), p.failure, f, 1e-9);
    }
}
