//! The race of a subtree against a renewal process of re-runs with a fixed
//! wait (Nav2's re-planning PipelineSequence, lowered to
//! `Parallel{1, 1}(until_failure(Sequence(wait d, C′)), R)`), by the exact
//! renewal method without a series: against closed forms derived by hand
//! (Laplace transforms of the loop's time, below), against the series path
//! (an independent algorithm: shifted phase-type components and quadrature)
//! where the series is short, and against simulation (|z| < 5).

mod common;
use common::*;

use btrel::compile::curve::{curve, CurveOptions};
use btrel::tree::xml::{parse_xml_files, parse_xml_str};
use btrel::tree::Tree;
use btrel::Figures;

/// One way a run of C′ can end: `coef · Π_i Exp(rates_i)` (the phases it
/// passes through), its Laplace transform `coef · Π r/(r + x)`.
struct Path {
    coef: f64,
    rates: Vec<f64>,
}

/// The Laplace transform `Λ(x) = E[e^{−xL}]` of the loop's time L and its
/// derivative. One round of the loop: the wait `d`, then C′: again (its
/// Success paths) with transform `a(x) = e^{−xd} Σ coef Π r/(r+x)`, end
/// (its Failure paths) with `b(x)` likewise. The rounds are independent,
/// so `Λ = b / (1 − a)` (the loop always ends when C′ can fail), and
/// `Λ′ = (b′(1 − a) + b a′)/(1 − a)²`, with `(e^{−xd} Π r/(r+x))′ = −(d +
/// Σ 1/(r + x)) · itself`.
fn loop_transform(d: f64, again: &[Path], end: &[Path], x: f64) -> (f64, f64) {
    let (a, da) = round_side(d, again, x);
    let (b, db) = round_side(d, end, x);
    let l = b / (1.0 - a);
    let dl = (db * (1.0 - a) + b * da) / (1.0 - a).powi(2);
    (l, dl)
}

/// `e^{−xd} Σ coef Π r/(r+x)` over `paths` and its derivative in x.
fn round_side(d: f64, paths: &[Path], x: f64) -> (f64, f64) {
    paths.iter().fold((0.0, 0.0), |(v, dv), p| {
        let val = p.coef * (-x * d).exp() * p.rates.iter().map(|r| r / (r + x)).product::<f64>();
        let slope = -(d + p.rates.iter().map(|r| 1.0 / (r + x)).sum::<f64>());
        (v + val, dv + val * slope)
    })
}

/// The transform of the process with a first round of its own (Nav2's
/// SpeedController: `Sequence(wait d₀, C′₀, loop)`): the first round ends
/// the process (`b₀`, C′₀'s Failure paths after the wait d₀) or is
/// followed by an independent loop (`a₀`, its Success paths), so
/// `Λ₀ = b₀ + a₀ Λ` and `Λ₀′ = b₀′ + a₀′ Λ + a₀ Λ′`.
fn first_transform(
    (d0, again0, end0): (f64, &[Path], &[Path]),
    lam: &dyn Fn(f64) -> (f64, f64),
    x: f64,
) -> (f64, f64) {
    let (a0, da0) = round_side(d0, again0, x);
    let (b0, db0) = round_side(d0, end0, x);
    let (l, dl) = lam(x);
    (b0 + a0 * l, db0 + da0 * l + a0 * dl)
}

/// `∫ e^{−μt} P(L > t) dt = (1 − Λ(μ))/μ` and `∫ t e^{−μt} P(L > t) dt =
/// 1/μ² − Λ(μ)/μ² + Λ′(μ)/μ` (the transform of the CDF is Λ/μ; its
/// derivative in μ gives the second).
fn i_j(lam: &dyn Fn(f64) -> (f64, f64), mu: f64) -> (f64, f64) {
    let (l, dl) = lam(mu);
    ((1.0 - l) / mu, 1.0 / (mu * mu) - l / (mu * mu) + dl / mu)
}

/// `(ps, MTTS, MTTF)` when R is one action: Success w.p. `s` after
/// Exp(μ), Failure after Exp(ν). The node succeeds iff R's success time X
/// comes before L: `P(S) = s(1 − Λ(μ))`, `E[T·1{S}] = s μ J(μ)`, and
/// `E[T] = E[min(T_R, L)] = s I(μ) + (1 − s) I(ν)`.
fn one_action(lam: &dyn Fn(f64) -> (f64, f64), s: f64, mu: f64, nu: f64) -> (f64, f64, f64) {
    let (i_mu, j_mu) = i_j(lam, mu);
    let (i_nu, _) = i_j(lam, nu);
    let ps = s * mu * i_mu;
    let ts = s * mu * j_mu;
    let mean = s * i_mu + (1.0 - s) * i_nu;
    (ps, ts / ps, (mean - ts) / (1.0 - ps))
}

/// `(ps, MTTS, MTTF)` when R is two actions in turn that always succeed,
/// after Exp(μ₁) then Exp(μ₂) (μ₁ ≠ μ₂): with
/// `P(X > t) = (μ₂e^{−μ₁t} − μ₁e^{−μ₂t})/(μ₂ − μ₁)` and density
/// `μ₁μ₂/(μ₂ − μ₁)(e^{−μ₁t} − e^{−μ₂t})`, `P(S) = P(X < L) = ∫ f_X P(L > t)`,
/// `E[T·1{S}] = ∫ t f_X P(L > t)`, `E[T] = ∫ P(X > t) P(L > t)`.
fn two_in_turn(lam: &dyn Fn(f64) -> (f64, f64), m1: f64, m2: f64) -> (f64, f64, f64) {
    let ((i1, j1), (i2, j2)) = (i_j(lam, m1), i_j(lam, m2));
    let k = m1 * m2 / (m2 - m1);
    let ps = k * (i1 - i2);
    let ts = k * (j1 - j2);
    let mean = (m2 * i1 - m1 * i2) / (m2 - m1);
    (ps, ts / ps, (mean - ts) / (1.0 - ps))
}

fn race_yaml(d: f64, rerun: &str, rest: &str) -> String {
    format!(
        "tree: {{parallel: {{name: race, success_threshold: 1, failure_threshold: 1, children: [\
         {{until_failure: {{name: replan, child: {{sequence: {{children: [\
         {{action: {{name: wait, ps: 1.0, tau_s: {d}}}}}, {rerun}]}}}}}}}}, {rest}]}}}}"
    )
}

/// The race with a first cycle of its own: `Sequence(wait d₀, C′₀,
/// until_failure(Sequence(wait d, C′)))` against `rest`.
fn first_race_yaml(d0: f64, first: &str, d: f64, rerun: &str, rest: &str) -> String {
    format!(
        "tree: {{parallel: {{name: race, success_threshold: 1, failure_threshold: 1, children: [\
         {{sequence: {{name: replan, children: [{{action: {{name: first wait, ps: 1.0, tau_s: {d0}}}}}, \
         {first}, {{until_failure: {{name: loop, child: {{sequence: {{children: [\
         {{action: {{name: wait, ps: 1.0, tau_s: {d}}}}}, {rerun}]}}}}}}}}]}}}}, {rest}]}}}}"
    )
}

fn assert_figures(what: &str, f: Figures, want: (f64, f64, f64), tol: f64) {
    let got = (f.ps, f.mtts.unwrap(), f.mttf.unwrap());
    for (name, g, w) in [
        ("ps", got.0, want.0),
        ("MTTS", got.1, want.1),
        ("MTTF", got.2, want.2),
    ] {
        assert!(
            (g - w).abs() <= tol * w.abs().max(1.0),
            "{what} {name}: {g} vs {w} (diff {:.2e})",
            g - w
        );
    }
    assert!((f.ps + f.pf - 1.0).abs() < 1e-12, "{what}: {f:?}");
}

#[test]
fn long_series_match_the_renewal_closed_form() {
    // a planner failing 0.5% of the time: the series would need
    // ln(1e-14)/ln(0.995) ≈ 6,430 re-runs; the renewal method needs none
    let (p, a, b) = (0.995, 2.0, 4.0);
    let lam = |x: f64| {
        loop_transform(
            1.0,
            &[Path {
                coef: p,
                rates: vec![a],
            }],
            &[Path {
                coef: 1.0 - p,
                rates: vec![b],
            }],
            x,
        )
    };
    let want = one_action(&lam, 0.85, 1.0 / 60.0, 0.05);
    // sanity of the derivation: 60 s of following meets ~40 re-plans, each
    // failing 0.5%: the race costs about 18% of the follower's 0.85
    assert!(want.0 < 0.85 * 0.9 && want.0 > 0.85 * 0.75, "{want:?}");
    let t = tree(&race_yaml(
        1.0,
        "{action: {name: plan, ps: 0.995, mu: 2.0, nu: 4.0}}",
        "{action: {name: follow, ps: 0.85, mu: 0.016666666666666666, nu: 0.05}}",
    ));
    assert_figures("one action", root_figures(&t), want, 1e-9);
    // the budget is checked before allocating: with 1 state the product
    // chain (2 states) is refused, not the series tried
    let small = btrel::Options {
        max_states: 1,
        ..Default::default()
    };
    let e = btrel::analyze(&t, &small).unwrap_err();
    assert!(
        // (the planner's own two phases already exceed a budget of one)
        matches!(&e, btrel::AnalysisError::StateBudget { node, .. } if node == "race" || node == "plan"),
        "{e}"
    );
    // its law needs no series either (`compile::renewal_curve`): the
    // curve tends to the closed form's ps
    assert_curve_limit(&t, want.0);

    // C′ two actions in turn (a plan then a check), R two phases in turn
    let (p1, a1, b1, p2, a2, b2) = (0.99, 1.5, 3.0, 0.98, 5.0, 0.7);
    let lam = |x: f64| {
        loop_transform(
            0.5,
            &[Path {
                coef: p1 * p2,
                rates: vec![a1, a2],
            }],
            &[
                Path {
                    coef: 1.0 - p1,
                    rates: vec![b1],
                },
                Path {
                    coef: p1 * (1.0 - p2),
                    rates: vec![a1, b2],
                },
            ],
            x,
        )
    };
    let want = two_in_turn(&lam, 0.1, 0.03);
    let t = tree(&race_yaml(
        0.5,
        "{sequence: {children: [{action: {ps: 0.99, mu: 1.5, nu: 3.0}}, \
         {action: {ps: 0.98, mu: 5.0, nu: 0.7}}]}}",
        "{sequence: {children: [{action: {ps: 1.0, mu: 0.1}}, {action: {ps: 1.0, mu: 0.03}}]}}",
    ));
    assert_figures("two in turn", root_figures(&t), want, 1e-9);
}

#[test]
fn a_first_cycle_with_its_own_wait_matches_the_closed_form() {
    // Nav2's SpeedController at full speed (min_rate 0.1, max_rate 1):
    // the first re-plan 2/1.1 s after the first plan, the later ones 1 s
    // after each; the planner fails 0.5% of the time (thousands of re-runs)
    let plan = || {
        (
            vec![Path {
                coef: 0.995,
                rates: vec![2.0],
            }],
            vec![Path {
                coef: 0.005,
                rates: vec![4.0],
            }],
        )
    };
    let d0 = 2.0 / 1.1;
    let (again, end) = plan();
    let lam = |x: f64| loop_transform(1.0, &again, &end, x);
    let (again0, end0) = plan();
    let lam0 = |x: f64| first_transform((d0, &again0, &end0), &lam, x);
    let want = one_action(&lam0, 0.85, 1.0 / 60.0, 0.05);
    // the first re-plan comes later than with one period throughout (1 s)
    // and earlier than with 2/1.1 s throughout: ps between theirs
    let lam_long = |x: f64| loop_transform(d0, &again, &end, x);
    let (short, long) = (
        one_action(&lam, 0.85, 1.0 / 60.0, 0.05).0,
        one_action(&lam_long, 0.85, 1.0 / 60.0, 0.05).0,
    );
    assert!(short < want.0 && want.0 < long, "{short} {want:?} {long}");
    let planner = "{action: {ps: 0.995, mu: 2.0, nu: 4.0}}";
    let t = tree(&first_race_yaml(
        d0,
        planner,
        1.0,
        planner,
        "{action: {name: follow, ps: 0.85, mu: 0.016666666666666666, nu: 0.05}}",
    ));
    assert_figures("speed controller", root_figures(&t), want, 1e-9);
    // the curve (R alone during the first wait, then the levels of the
    // period) tends to the closed form's ps
    assert_curve_limit(&t, want.0);

    // a first re-run unlike the later ones and a first wait shorter than
    // the period: C′₀ one action, C′ two in turn, R two phases in turn
    let (p1, a1, b1, p2, a2, b2) = (0.99, 1.5, 3.0, 0.98, 5.0, 0.7);
    let again = [Path {
        coef: p1 * p2,
        rates: vec![a1, a2],
    }];
    let end = [
        Path {
            coef: 1.0 - p1,
            rates: vec![b1],
        },
        Path {
            coef: p1 * (1.0 - p2),
            rates: vec![a1, b2],
        },
    ];
    let lam = |x: f64| loop_transform(0.5, &again, &end, x);
    let again0 = [Path {
        coef: 0.9,
        rates: vec![3.0],
    }];
    let end0 = [Path {
        coef: 0.1,
        rates: vec![1.0],
    }];
    let lam0 = |x: f64| first_transform((0.25, &again0, &end0), &lam, x);
    let want = two_in_turn(&lam0, 0.1, 0.03);
    let t = tree(&first_race_yaml(
        0.25,
        "{action: {ps: 0.9, mu: 3.0, nu: 1.0}}",
        0.5,
        "{sequence: {children: [{action: {ps: 0.99, mu: 1.5, nu: 3.0}}, \
         {action: {ps: 0.98, mu: 5.0, nu: 0.7}}]}}",
        "{sequence: {children: [{action: {ps: 1.0, mu: 0.1}}, {action: {ps: 1.0, mu: 0.03}}]}}",
    ));
    assert_figures("first re-run of its own", root_figures(&t), want, 1e-9);

    // an instantaneous first re-run (a condition of ps 0.6, at d₀ = 3 s):
    // its paths have no phases
    let again0 = [Path {
        coef: 0.6,
        rates: vec![],
    }];
    let end0 = [Path {
        coef: 0.4,
        rates: vec![],
    }];
    let lam0 = |x: f64| first_transform((3.0, &again0, &end0), &lam, x);
    let want = one_action(&lam0, 0.7, 0.2, 0.4);
    let t = tree(&first_race_yaml(
        3.0,
        "{condition: {ps: 0.6}}",
        0.5,
        "{sequence: {children: [{action: {ps: 0.99, mu: 1.5, nu: 3.0}}, \
         {action: {ps: 0.98, mu: 5.0, nu: 0.7}}]}}",
        "{action: {ps: 0.7, mu: 0.2, nu: 0.4}}",
    ));
    assert_figures("instantaneous first re-run", root_figures(&t), want, 1e-9);
}

#[test]
fn a_long_rest_is_exact_too() {
    // R = until_failure(A), A succeeding w.p. 0.9 after Exp(0.05) and
    // failing after Exp(0.05): a geometric number of Exp(0.05) times, so R
    // fails after Exp(0.005) and never succeeds. Its phase chain is the
    // loop unrolled (306 copies of A, 612 phases: too many for the dense
    // exponential, so the wait is uniformized). The node fails at
    // min(R, L): MTTF = ∫ P(R > t) P(L > t) dt = (1 − Λ(0.005))/0.005.
    let lam = |x: f64| {
        loop_transform(
            1.0,
            &[Path {
                coef: 0.99,
                rates: vec![2.0],
            }],
            &[Path {
                coef: 0.01,
                rates: vec![4.0],
            }],
            x,
        )
    };
    let rate = 0.05 * 0.1;
    let want = (1.0 - lam(rate).0) / rate;
    let t = tree(&race_yaml(
        1.0,
        "{action: {ps: 0.99, mu: 2.0, nu: 4.0}}",
        "{until_failure: {child: {action: {ps: 0.9, mu: 0.05, nu: 0.05}}}}",
    ));
    let f = root_figures(&t);
    assert_eq!(f.ps, 0.0, "{f:?}");
    assert!((f.pf - 1.0).abs() < 1e-12, "{f:?}");
    let mttf = f.mttf.unwrap();
    assert!(
        (mttf - want).abs() < 1e-9 * want,
        "MTTF {mttf} vs {want} (diff {:.2e})",
        mttf - want
    );
}

/// The same race with `R` followed by an action of fixed time 1e-300 s
/// (the same instant as 0 for the analysis, whose instants within 1e-12
/// relative are one), which has no phase chain: the analysis takes the
/// series path (shifted phase-type components, counted races, quadrature)
/// for the same law.
fn with_series(d: f64, rerun: &str, rest: &str) -> (Tree, Tree) {
    let zero = "{action: {name: zero, ps: 1.0, tau_s: 1e-300}}";
    (
        tree(&race_yaml(d, rerun, rest)),
        tree(&race_yaml(
            d,
            rerun,
            &format!("{{sequence: {{children: [{rest}, {zero}]}}}}"),
        )),
    )
}

#[test]
fn short_series_agree_with_the_renewal_method() {
    // (wait, C′, R): re-runs that succeed with probability ≤ 0.7 (at most
    // ~90 terms), multi-phase sides, instantaneous outcomes of C′ (a
    // condition first) and of R (atoms at 0)
    let cases = [
        (
            1.0,
            "{action: {ps: 0.7, mu: 2.0, nu: 1.0}}",
            "{action: {ps: 0.9, mu: 0.2, nu: 0.5}}",
        ),
        (
            0.3,
            "{sequence: {children: [{action: {ps: 0.9, mu: 3.0, nu: 1.0}}, \
             {action: {ps: 0.7, mu: 1.0, nu: 2.0}}]}}",
            "{fallback: {children: [{sequence: {children: [{action: {ps: 0.8, mu: 0.5, nu: 1.5}}, \
             {action: {ps: 0.9, mu: 0.7, nu: 0.4}}]}}, {action: {ps: 0.6, mu: 0.25, nu: 0.9}}]}}",
        ),
        (
            2.0,
            "{fallback: {children: [{condition: {ps: 0.2}}, {action: {ps: 0.5, mu: 1.0, nu: 3.0}}]}}",
            "{fallback: {children: [{condition: {ps: 0.25}}, {action: {ps: 0.8, mu: 0.1, nu: 0.3}}]}}",
        ),
        (
            0.7,
            "{action: {ps: 0.6, mu: 0.8, nu: 0.8}}",
            "{parallel: {success_threshold: 2, children: [{action: {ps: 0.95, mu: 0.3, nu: 1.0}}, \
             {action: {ps: 0.9, mu: 0.6, nu: 0.2}}]}}",
        ),
    ];
    for (k, (d, rerun, rest)) in cases.iter().enumerate() {
        let (renewal, series) = with_series(*d, rerun, rest);
        renewal_agrees_with_series(k, &renewal, &series);
    }
}

/// The root's figures by the renewal method against the series, to 1e-9
/// relative (case `k` in messages).
fn renewal_agrees_with_series(k: usize, renewal: &btrel::tree::Tree, series: &btrel::tree::Tree) {
    let (a, b) = (root_figures(renewal), root_figures(series));
    for (name, x, y) in [
        ("ps", a.ps, b.ps),
        ("pf", a.pf, b.pf),
        ("MTTS", a.mtts.unwrap(), b.mtts.unwrap()),
        ("MTTF", a.mttf.unwrap(), b.mttf.unwrap()),
    ] {
        assert!(
            (x - y).abs() <= 1e-9 * y.abs().max(1.0),
            "case {k} {name}: renewal {x} vs series {y} (diff {:.2e})",
            x - y
        );
    }
}

#[test]
fn short_series_with_a_first_wait_agree_with_the_renewal_method() {
    // (first wait, first re-run, wait, C′, R), re-runs succeeding with
    // probability ≤ 0.7: the series path (the rest ended by a 1e-300 s
    // action, see `with_series`) is an independent algorithm
    let zero = "{action: {name: zero, ps: 1.0, tau_s: 1e-300}}";
    let cases = [
        (
            1.8,
            "{action: {ps: 0.7, mu: 2.0, nu: 1.0}}",
            1.0,
            "{action: {ps: 0.7, mu: 2.0, nu: 1.0}}",
            "{action: {ps: 0.9, mu: 0.2, nu: 0.5}}",
        ),
        (
            0.2,
            "{fallback: {children: [{condition: {ps: 0.2}}, {action: {ps: 0.5, mu: 1.0, nu: 3.0}}]}}",
            0.9,
            "{sequence: {children: [{action: {ps: 0.9, mu: 3.0, nu: 1.0}}, \
             {action: {ps: 0.7, mu: 1.0, nu: 2.0}}]}}",
            "{fallback: {children: [{condition: {ps: 0.25}}, {action: {ps: 0.8, mu: 0.1, nu: 0.3}}]}}",
        ),
    ];
    for (k, (d0, first, d, rerun, rest)) in cases.iter().enumerate() {
        let renewal = tree(&first_race_yaml(*d0, first, *d, rerun, rest));
        let series = tree(&first_race_yaml(
            *d0,
            first,
            *d,
            rerun,
            &format!("{{sequence: {{children: [{rest}, {zero}]}}}}"),
        ));
        renewal_agrees_with_series(k, &renewal, &series);
    }
    // and the simulator plays the race with its first wait (|z| < 5)
    let (_, first, _, rerun, rest) = cases[1];
    assert_root_matches_simulation(
        &tree(&first_race_yaml(2.5, first, 0.4, rerun, rest)),
        200_000,
    );
}

#[test]
fn either_child_order_gives_the_same_race() {
    let rerun = "{action: {ps: 0.99, mu: 2.0, nu: 1.0}}";
    let rest =
        "{fallback: {children: [{condition: {ps: 0.3}}, {action: {ps: 0.8, mu: 0.1, nu: 0.3}}]}}";
    let first = tree(&race_yaml(1.0, rerun, rest));
    let swapped = tree(&format!(
        "tree: {{parallel: {{success_threshold: 1, failure_threshold: 1, children: [{rest}, \
         {{until_failure: {{child: {{sequence: {{children: [\
         {{action: {{ps: 1.0, tau_s: 1.0}}}}, {rerun}]}}}}}}}}]}}}}"
    ));
    let (a, b) = (root_figures(&first), root_figures(&swapped));
    assert!((a.ps - b.ps).abs() < 1e-14, "{a:?} vs {b:?}");
    assert!((a.mtts.unwrap() - b.mtts.unwrap()).abs() < 1e-12 * a.mtts.unwrap());
    assert!((a.mttf.unwrap() - b.mttf.unwrap()).abs() < 1e-12 * a.mttf.unwrap());
    // and the simulator plays the same race
    assert_root_matches_simulation(&first, 200_000);
}

fn xml(body: &str, params: &str) -> Tree {
    let text = format!(
        "<root BTCPP_format=\"4\">\n<BehaviorTree ID=\"T\">\n{body}\n</BehaviorTree>\n</root>\n"
    );
    parse_xml_str(&text, "t.xml", params, "t.params.yaml").expect("test tree parses")
}

#[test]
fn a_replanning_pipeline_with_a_long_series_is_reported_exactly_and_simulated() {
    // Nav2's shape: selectors, a re-planning RateController over a planner
    // with a costmap-clearing retry, the follower with its own retry
    let body = "<PipelineSequence name=\"pipe\">\n<Sel/>\n<RateController hz=\"2\">\n\
        <RecoveryNode number_of_retries=\"1\"><Plan/><Clear/></RecoveryNode>\n</RateController>\n\
        <RecoveryNode number_of_retries=\"1\"><Follow/><Clear/></RecoveryNode>\n</PipelineSequence>";
    let params = "Sel: {ps: 1.0, mu: 100}\nPlan: {ps: 0.95, mu: 1, nu: 0.5}\n\
        Clear: {ps: 0.99, mu: 2, nu: 2}\nFollow: {ps: 0.85, mu: 0.0166667, nu: 0.05}\n";
    let t = xml(body, params);
    let f = root_figures(&t);
    // below the figures without re-planning: the first plan (0.95, or a
    // clear and a second plan: 0.95 + 0.05·0.99·0.95) times the follower
    // with its retry (0.85 + 0.15·0.99·0.85)
    let plain = (0.95 + 0.05 * 0.99 * 0.95) * (0.85 + 0.15 * 0.99 * 0.85);
    assert!(f.ps > 0.5 && f.ps < plain - 0.05, "{f:?} vs {plain}");
    assert_root_matches_simulation(&t, 100_000);
    // its curve needs no series (thousands of re-runs): exact, against the
    // simulated tick semantics
    let times = [1.0, 4.0, 15.0, 50.0];
    let pts = curve(&t, 0, &times, &CurveOptions::default()).expect("curve");
    let sim = simulate_root(&t, 100_000, &times);
    assert_root_and_curve_within_z("pipe", f, &pts, &sim);
}

/// The root's curve at a late time is the closed form's ps (to 1e-9).
fn assert_curve_limit(t: &Tree, ps: f64) {
    let late = curve(t, 0, &[4000.0], &CurveOptions::default()).expect("curve")[0];
    assert!(late.running < 1e-12, "{late:?}");
    assert!((late.success - ps).abs() < 1e-9, "{late:?} vs {ps}");
}

#[test]
fn corpus_speed_controller_trees_match_the_closed_form_and_simulation() {
    // nav2{,_humble}/navigate_w_replanning_speed.xml: PipelineSequence(
    // [ControllerSelector, PlannerSelector,] SpeedController(Plan), Follow)
    // at 0.26 m/s (= max_speed: rate max_rate = 1 Hz), first wait
    // 2/(0.1 + 1.0) s; params: Plan ps 0.95, Exp(1) / Exp(0.5); Follow ps
    // 0.85, Exp(0.0166667) / Exp(0.05); the selectors (jazzy only) ps 1,
    // Exp(100) each, before everything
    let Some(root) = corpus() else {
        println!("note: the corpus is absent; skipping");
        return;
    };
    let (ps_plan, mu_plan, nu_plan) = (0.95, 1.0, 0.5);
    let (s, mu, nu) = (0.85, 0.0166667, 0.05);
    let again = [Path {
        coef: ps_plan,
        rates: vec![mu_plan],
    }];
    let end = [Path {
        coef: 1.0 - ps_plan,
        rates: vec![nu_plan],
    }];
    let lam = |x: f64| loop_transform(1.0, &again, &end, x);
    let lam0 = |x: f64| first_transform((2.0 / 1.1, &again, &end), &lam, x);
    let (race_ps, race_mtts, race_mttf) = one_action(&lam0, s, mu, nu);
    let scratch = tempfile::tempdir().expect("tempdir");
    for (dir, selectors) in [("nav2", 2.0 / 100.0), ("nav2_humble", 0.0)] {
        let dir = root.join(dir);
        let xml = dir.join("navigate_w_replanning_speed.xml");
        let params = scratch.path().join("speed.params.yaml");
        let published = std::fs::read_to_string(xml.with_extension("params.yaml")).expect("params");
        // the corpus' params file gives the speed (INDEX.md: "its params
        // file adds it"); an older copy without it gets it appended (a key
        // may not appear twice)
        let speed = "\"SpeedController/speed\": {value: 0.26}";
        let given: Vec<&str> = published
            .lines()
            .filter(|l| l.starts_with("\"SpeedController/speed\":"))
            .collect();
        let text = match given[..] {
            [] => format!("{published}\n{speed}\n"),
            [l] if l.trim() == speed => published.clone(),
            _ => panic!(
                "{}: the published speed is not 0.26 m/s: {given:?}",
                xml.display()
            ),
        };
        std::fs::write(&params, text).expect("writes");
        let t = parse_xml_files(&xml, &params, &[dir.join("nav2_tree_nodes.xml")]).expect("reads");
        // the root: the selectors, the first plan, then the race
        let ps = ps_plan * race_ps;
        let mtts = selectors + 1.0 / mu_plan + race_mtts;
        let failed_plan = (1.0 - ps_plan) * (selectors + 1.0 / nu_plan);
        let failed_race = ps_plan * (1.0 - race_ps) * (selectors + 1.0 / mu_plan + race_mttf);
        let mttf = (failed_plan + failed_race) / (1.0 - ps);
        assert_figures(
            &dir.display().to_string(),
            root_figures(&t),
            (ps, mtts, mttf),
            1e-9,
        );
        assert_root_matches_simulation(&t, 100_000);
    }
}

/// One attempt of Nav2's default tree: its PipelineSequence as published
/// (re-planning at 1 Hz with a costmap-clearing retry, raced by the
/// follower with its own), and the corpus' params for its leaves, with the
/// two synchronous checks of its ReactiveSequence taking no time (as docs/NAV2.md's
/// *Nav2's default tree* does: two actions that take time there are
/// refused). The whole tree's RoundRobin without wrap_around has no exact
/// meaning yet.
fn nav2_default_attempt(root: &std::path::Path, scratch: &std::path::Path) -> Tree {
    let dir = root.join("nav2");
    let published =
        std::fs::read_to_string(dir.join("navigate_to_pose_w_replanning_and_recovery.xml"))
            .expect("tree");
    let (open, close) = (
        "<PipelineSequence name=\"NavigateWithReplanning\">",
        "</PipelineSequence>",
    );
    let from = published.find(open).expect("the pipeline");
    let to = published.find(close).expect("its end") + close.len();
    let xml = format!(
        "<root BTCPP_format=\"4\" main_tree_to_execute=\"Attempt\">\n  <BehaviorTree ID=\"Attempt\">\n      {}\n  </BehaviorTree>\n</root>\n",
        &published[from..to]
    );
    let params: String =
        std::fs::read_to_string(dir.join("navigate_to_pose_w_replanning_and_recovery.params.yaml"))
            .expect("params")
            .lines()
            // the recovery branch's leaves are not in the attempt
            .filter(|l| {
                !["GoalUpdated:", "Spin:", "Wait:", "BackUp:"]
                    .iter()
                    .any(|k| l.starts_with(k))
            })
            .map(|l| {
                if l.starts_with("TruncatePathLocal:") {
                    "TruncatePathLocal: {ps: 1.0, tau_s: 0}".to_string()
                } else if l.starts_with("ValidatePath:") {
                    "ValidatePath: {ps: 0.9, tau_s: 0, tau_f: 0}".to_string()
                } else {
                    l.to_string()
                }
            })
            .collect::<Vec<_>>()
            .join("\n");
    let (x, p) = (
        scratch.join("attempt.xml"),
        scratch.join("attempt.params.yaml"),
    );
    std::fs::write(&x, xml).expect("writes");
    std::fs::write(&p, params).expect("writes");
    parse_xml_files(&x, &p, &[dir.join("nav2_tree_nodes.xml")]).expect("reads")
}

#[test]
fn nav2_default_attempt_is_reported_exactly_and_matches_simulation() {
    let Some(root) = corpus() else {
        println!("note: the corpus is absent; skipping");
        return;
    };
    let scratch = tempfile::tempdir().expect("tempdir");
    let tree = nav2_default_attempt(&root, scratch.path());
    let started = std::time::Instant::now();
    let f = root_figures(&tree);
    println!("Nav2 default attempt: {f:?} in {:?}", started.elapsed());
    assert_root_matches_simulation(&tree, 100_000);
}

/// `(ps, MTTS, MTTF)` of the race of the loop's time L (transform `lam`)
/// against R, given R's Success density `Σ c e^{−λt}` (`success`) and its
/// running probability `Σ r e^{−κt}` (`running`): the node succeeds iff R
/// succeeds before L, so `P(S) = Σ c I(λ)`, `E[T·1{S}] = Σ c J(λ)` and
/// `E[T] = ∫ P(R running) P(L > t) dt = Σ r I(κ)` ([`i_j`]).
fn race_of_sums(
    lam: &dyn Fn(f64) -> (f64, f64),
    success: &[(f64, f64)],
    running: &[(f64, f64)],
) -> (f64, f64, f64) {
    let (mut ps, mut ts, mut mean) = (0.0, 0.0, 0.0);
    for &(c, l) in success {
        let (i, j) = i_j(lam, l);
        ps += c * i;
        ts += c * j;
    }
    for &(r, k) in running {
        mean += r * i_j(lam, k).0;
    }
    (ps, ts / ps, (mean - ts) / (1.0 - ps))
}

/// MoveIt Pro's `mpc_pose_tracking` shape: a Parallel with success
/// threshold 2 and failure threshold 1 over a loop that never returns (its
/// body cannot fail), a loop that re-runs an action after a fixed wait until
/// it fails, and two actions A and B. The first loop counts towards no
/// threshold; the second never succeeds and its Failure fails the node; so
/// the node is the race of the second loop's time L against R =
/// Parallel{2, 1}(A, B): with A succeeding w.p. `pa` after Exp(μa), failing
/// after Exp(νa) (`qa = 1 − pa`), likewise B, R's Success density is
/// `pa pb (μa e^{−μa t} + μb e^{−μb t} − (μa + μb) e^{−(μa+μb)t})` and its
/// running probability `P(no failure by t) − P(both succeeded by t)`, a sum
/// of exponentials.
#[test]
fn a_wider_parallel_with_a_loop_is_the_race_of_the_loop_and_the_rest() {
    let (d, p, a, b) = (0.1, 0.99, 10.0, 100.0);
    let (pa, ma, na, pb, mb, nb) = (0.98, 5.0, 5.0, 0.9, 0.1, 0.2);
    let (qa, qb) = (1.0 - pa, 1.0 - pb);
    let lam = |x: f64| {
        loop_transform(
            d,
            &[Path {
                coef: p,
                rates: vec![a],
            }],
            &[Path {
                coef: 1.0 - p,
                rates: vec![b],
            }],
            x,
        )
    };
    let success = [
        (pa * pb * ma, ma),
        (pa * pb * mb, mb),
        (-pa * pb * (ma + mb), ma + mb),
    ];
    let running = [
        (pa * qb, nb),
        (qa * pb, na),
        (qa * qb, na + nb),
        (pa * pb, ma),
        (pa * pb, mb),
        (-pa * pb, ma + mb),
    ];
    let want = race_of_sums(&lam, &success, &running);
    let process = format!(
        "{{until_failure: {{name: watch, child: {{sequence: {{children: [\
         {{action: {{ps: 1.0, tau_s: {d}}}}}, {{action: {{name: check, ps: {p}, mu: {a}, nu: {b}}}}}]}}}}}}}}"
    );
    let endless = "{until_failure: {name: endless, child: {sequence: {children: [\
         {action: {ps: 1.0, tau_s: 0.01}}, {action: {ps: 1.0, mu: 30}}]}}}}";
    let node = format!(
        "{{parallel: {{name: node, success_threshold: 2, failure_threshold: 1, children: [\
         {endless}, {process}, {{action: {{name: A, ps: {pa}, mu: {ma}, nu: {na}}}}}, \
         {{action: {{name: B, ps: {pb}, mu: {mb}, nu: {nb}}}}}]}}}}"
    );
    let t = tree(&format!("tree: {node}"));
    assert_figures("Parallel{2, 1}", root_figures(&t), want, 1e-9);
    // its curve (by levels of the wait) tends to the closed form's ps
    let late = curve(&t, 0, &[400.0], &CurveOptions::default()).expect("curve")[0];
    assert!(late.running < 1e-12, "{late:?}");
    assert!(
        (late.success - want.0).abs() < 1e-9,
        "{late:?} vs {}",
        want.0
    );

    // BT.CPP's Timeout over it (a 15 s deadline racing it, the deadline
    // first): its law is the race's, cut at 15 s, where the rest fails
    let tt = tree(&format!(
        "tree: {{parallel: {{name: timeout, success_threshold: 1, failure_threshold: 1, children: [\
         {{action: {{name: deadline, ps: 0.0, pf: 1.0, tau_f: 15}}}}, {node}]}}}}"
    ));
    let f = root_figures(&tt);
    // P(S) is the race's S(15) (it has no atom there), from its curve
    let s15 = curve(&t, 0, &[15.0], &CurveOptions::default()).expect("curve")[0].success;
    assert!((f.ps - s15).abs() < 1e-9, "{f:?} vs S(15) = {s15}");
    assert!(f.ps < want.0 && (f.ps + f.pf - 1.0).abs() < 1e-12, "{f:?}");
    let times = [1.0, 10.0, 14.9, 15.0, 30.0];
    let pts = curve(&tt, 0, &times, &CurveOptions::default()).expect("curve");
    assert!(
        pts[4].running == 0.0 && (pts[4].success - f.ps).abs() < 1e-9,
        "{pts:?}"
    );
    let sim = simulate_root(&tt, 200_000, &times);
    assert_root_and_curve_within_z("timeout", f, &pts, &sim);
}
