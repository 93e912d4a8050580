//! Erlang-k, hypoexponential and shifted outcome times (`success_time` /
//! `failure_time`): the format, closed forms worked out by hand, Monte
//! Carlo through btrel's simulator (|z| < 5) and `btrel fit --timing auto`
//! on synthetic samples with a known family.

mod common;

use btrel::curve::{curve, CurveOptions};
use btrel::fit::timing::Family;
use btrel::fit::{fit_leaf_with, Counts, Timing, TimingMode};
use btrel::logs::Declared;
use btrel::tree::{parse_str, Duration, NodeKind};
use common::{root_figures, run_btrel, tree};
use rand::SeedableRng;
use rand_distr::{Distribution, Exp1};
use rand_xoshiro::Xoshiro256PlusPlus;

/// `P(Erlang(k, λ) ≤ t) = 1 − Σ_{j<k} e^{−λt} (λt)^j / j!`.
fn erlang_cdf(k: u32, rate: f64, t: f64) -> f64 {
    let x = rate * t;
    let mut term = (-x).exp();
    let mut sum = 0.0;
    for j in 0..k {
        sum += term;
        term *= x / f64::from(j + 1);
    }
    1.0 - sum
}

#[test]
fn an_erlang_leaf_has_its_closed_form_mean_and_cdf() {
    let t = tree("tree: {action: {ps: 1, success_time: {erlang: {k: 3, rate: 0.5}}}}");
    let f = root_figures(&t);
    assert!((f.mtts.expect("succeeds") - 6.0).abs() < 1e-12, "{f:?}");
    for x in [0.5, 2.0, 6.0, 20.0] {
        let p = curve(&t, 0, &[x], &CurveOptions::default()).expect("curve")[0];
        assert!(
            (p.success - erlang_cdf(3, 0.5, x)).abs() < 1e-12,
            "{x}: {p:?}"
        );
    }
}

#[test]
fn a_sequence_of_two_erlangs_is_an_erlang_and_of_two_rates_a_hypoexponential() {
    // Erlang(2, 1.5) then Erlang(3, 1.5) = Erlang(5, 1.5)
    let t = tree(
        "tree: {sequence: {children: [\
           {action: {ps: 1, success_time: {erlang: {k: 2, rate: 1.5}}}}, \
           {action: {ps: 1, success_time: {erlang: {k: 3, rate: 1.5}}}}]}}",
    );
    let f = root_figures(&t);
    assert!((f.mtts.expect("succeeds") - 5.0 / 1.5).abs() < 1e-12);
    for x in [0.4, 2.0, 3.3, 9.0] {
        let p = curve(&t, 0, &[x], &CurveOptions::default()).expect("curve")[0];
        assert!(
            (p.success - erlang_cdf(5, 1.5, x)).abs() < 1e-10,
            "{x}: {p:?}"
        );
    }
    // Exp(1) (an Erlang-1 written as a hypoexponential) then Exp(3):
    // 1 − (3 e^{−t} − e^{−3t}) / 2
    let t = tree(
        "tree: {sequence: {children: [\
           {action: {ps: 1, success_time: {hypoexponential: [1]}}}, \
           {action: {ps: 1, success_time: {rate: 3}}}]}}",
    );
    for x in [0.1f64, 0.8, 2.5] {
        let want = 1.0 - (3.0 * (-x).exp() - (-3.0 * x).exp()) / 2.0;
        let p = curve(&t, 0, &[x], &CurveOptions::default()).expect("curve")[0];
        assert!((p.success - want).abs() < 1e-10, "{x}: {p:?}");
    }
    // the same law as one leaf
    let one = tree("tree: {action: {ps: 1, success_time: {hypoexponential: [3, 1]}}}");
    let p = curve(&one, 0, &[0.8], &CurveOptions::default()).expect("curve")[0];
    let want = 1.0 - (3.0 * (-0.8f64).exp() - (-2.4f64).exp()) / 2.0;
    assert!((p.success - want).abs() < 1e-10, "{p:?}");
}

#[test]
fn a_race_of_a_shifted_exponential_against_an_exponential_by_hand() {
    // A succeeds after δ + Exp(λ), B fails after Exp(ν); Parallel(1, 1).
    let (d, l, n) = (0.5f64, 2.0f64, 1.5f64);
    let t = tree(
        "tree: {parallel: {success_threshold: 1, failure_threshold: 1, children: [\
           {action: {ps: 1, success_time: {shift: 0.5, rate: 2}}}, {action: {ps: 0, nu: 1.5}}]}}",
    );
    let f = root_figures(&t);
    // P(S) = P(Y > δ) · λ/(λ+ν); given S, T = δ + min(X, Y−δ) ~ δ + Exp(λ+ν)
    let ps = (-n * d).exp() * l / (l + n);
    let mtts = d + 1.0 / (l + n);
    // E[T; F] = E[Y; Y < δ] + P(Y > δ) ν/(λ+ν) (δ + 1/(λ+ν))
    let head = (1.0 - (-n * d).exp() * (1.0 + n * d)) / n;
    let tail = (-n * d).exp() * n / (l + n) * (d + 1.0 / (l + n));
    let mttf = (head + tail) / (1.0 - ps);
    assert!((f.ps - ps).abs() < 1e-12, "{} vs {ps}", f.ps);
    assert!((f.mtts.expect("S") - mtts).abs() < 1e-10 * mtts);
    assert!((f.mttf.expect("F") - mttf).abs() < 1e-10 * mttf);
    // S(t) = e^{−νδ} λ/(λ+ν) (1 − e^{−(λ+ν)(t−δ)}) for t ≥ δ, 0 before
    for x in [0.3f64, 0.5, 0.9, 2.0] {
        let want = if x < d {
            0.0
        } else {
            ps * (1.0 - (-(l + n) * (x - d)).exp())
        };
        let p = curve(&t, 0, &[x], &CurveOptions::default()).expect("curve")[0];
        assert!(
            (p.success - want).abs() < 1e-9,
            "{x}: {} vs {want}",
            p.success
        );
        // F(t) = 1 − e^{−νt} before δ (nothing can succeed yet)
        if x < d {
            assert!(
                (p.failure - (1.0 - (-n * x).exp())).abs() < 1e-9,
                "{x}: {p:?}"
            );
        }
    }
}

/// Figures and curves of trees mixing the new families agree with btrel's
/// simulator (an independent implementation of the tick semantics).
#[test]
fn simulation_agrees_with_the_exact_figures_and_curves() {
    let cases = [
        "tree: {sequence: {children: [\
           {action: {ps: 0.8, success_time: {erlang: {k: 3, rate: 2}}, nu: 1}}, \
           {action: {ps: 0.7, success_time: {hypoexponential: [1, 3]}, \
             failure_time: {shift: 0.4, rate: 2}}}]}}",
        "tree: {parallel: {success_threshold: 1, children: [\
           {action: {ps: 0.7, success_time: {shift: 0.25, erlang: {k: 2, rate: 4}}, \
             failure_time: {fixed: 0.6}}}, \
           {action: {ps: 0.5, success_time: {erlang: {k: 2, rate: 2}}, nu: 3}}]}}",
        "tree: {fallback: {children: [\
           {action: {ps: 0.4, success_time: {shift: 1, hypoexponential: [2, 5, 5]}, \
             failure_time: {erlang: {k: 4, rate: 8}}}}, \
           {parallel: {success_threshold: 2, children: [\
             {action: {ps: 0.9, success_time: {erlang: {k: 2, rate: 3}}, failure_time: {rate: 1}}}, \
             {action: {ps: 0.6, mu: 1.2, failure_time: {erlang: {k: 3, rate: 4}}}}]}}]}}",
        // a retry loop racing a shifted deadline
        "tree: {parallel: {success_threshold: 1, failure_threshold: 1, children: [\
           {until_success: {child: {action: {ps: 0.4, \
             success_time: {shift: 0.3, erlang: {k: 2, rate: 5}}, \
             failure_time: {hypoexponential: [3, 6]}}}}}, \
           {action: {ps: 0, failure_time: {shift: 1.5, rate: 2}}}]}}",
    ];
    common::assert_cases_match_simulation(&cases, &[0.5, 1.0, 2.0, 4.0], 200_000);
}

#[test]
fn the_format_reads_every_family() {
    let t = tree(
        "tree: {sequence: {children: [\
           {action: {name: a, ps: 0.5, success_time: {erlang: {k: 3, rate: 0.5}}, \
             failure_time: {hypoexponential: [1.0, 2.0]}}}, \
           {action: {name: b, ps: 0.5, success_time: {shift: 8.0, rate: 0.5}, \
             failure_time: {fixed: 2}}}, \
           {action: {name: c, ps: 1, success_time: {rate: 4}}}]}}",
    );
    let NodeKind::Action(a) = t.nodes()[1].kind else {
        panic!("an action")
    };
    let (s, f) = (a.success.expect("S"), a.failure.expect("F"));
    assert_eq!((s.family(), s.mean()), ("Erlang", 6.0));
    assert_eq!((f.family(), f.mean()), ("hypoexponential", 1.5));
    let NodeKind::Action(b) = t.nodes()[2].kind else {
        panic!("an action")
    };
    let s = b.success.expect("S");
    assert_eq!(
        (s.family(), s.mean(), s.shift()),
        ("shifted exponential", 10.0, 8.0)
    );
    assert_eq!(b.failure, Some(Duration::Fixed { time: 2.0 }));
    let NodeKind::Action(c) = t.nodes()[3].kind else {
        panic!("an action")
    };
    assert_eq!(c.success, Some(Duration::Exponential { rate: 4.0 }));
    // the written form reads back to the same law
    for d in [a.success, a.failure, b.success, b.failure] {
        let d = d.expect("a time");
        let y = format!("tree: {{action: {{ps: 1, success_time: {}}}}}", d.to_yaml());
        let NodeKind::Action(r) = tree(&y).nodes()[0].kind else {
            panic!("an action")
        };
        assert_eq!(r.success, Some(d), "{y}");
    }
}

#[test]
fn bad_times_are_located_errors() {
    let cases: [(&str, (usize, usize), &str); 7] = [
        (
            "tree:\n  action: {ps: 1, success_time: {erlang: {k: 2.5, rate: 1}}}\n",
            (2, 46),
            "not a valid stage count",
        ),
        (
            "tree:\n  action: {ps: 1, success_time: {rate: -1}}\n",
            (2, 40),
            "not a valid rate",
        ),
        (
            "tree:\n  action: {ps: 1, success_time: {rate: 1, fixed: 2}}\n",
            (2, 33),
            "gives 2 laws",
        ),
        (
            "tree:\n  action: {ps: 1, success_time: {shift: 1, fixed: 2}}\n",
            (2, 51),
            "both `fixed` and `shift`",
        ),
        (
            "tree:\n  action: {ps: 0.5, success_time: {rate: 1}, tau_f: 2}\n",
            (2, 53),
            "`tau_f` with `success_time`",
        ),
        (
            "tree:\n  action: {ps: 1, mu: 1, success_time: {rate: 1}}\n",
            (2, 40),
            "both `mu` and `success_time`",
        ),
        (
            "tree:\n  action: {ps: 1, success_time: {hypoexponential: []}}\n",
            (2, 51),
            "is empty",
        ),
    ];
    for (y, (line, column), what) in cases {
        let e = parse_str(y, "t.yaml").expect_err(y);
        assert!(e.message.contains(what), "{y}: {}", e.message);
        assert_eq!((e.line, e.column), (line, column), "{y}: {}", e.message);
    }
    // and through the CLI: exit 2 with file:line:column
    let dir = tempfile::tempdir().expect("tempdir");
    let p = dir.path().join("bad.yaml");
    std::fs::write(&p, cases[0].0).expect("written");
    let (code, _, err) = run_btrel(&["check", p.to_str().expect("path")]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("bad.yaml:2:46"), "{err}");
}

#[test]
fn a_shifted_time_is_refused_by_the_prism_export_and_erlang_is_k_states() {
    let dir = tempfile::tempdir().expect("tempdir");
    let p = dir.path().join("t.yaml");
    std::fs::write(
        &p,
        "tree: {action: {ps: 1, success_time: {shift: 1, rate: 2}}}\n",
    )
    .expect("written");
    let (code, _, err) = run_btrel(&["export", "--to", "prism", p.to_str().expect("path")]);
    assert_eq!(code, 1, "{err}");
    assert!(err.contains("no CTMC"), "{err}");
    std::fs::write(
        &p,
        "tree: {action: {ps: 1, success_time: {erlang: {k: 4, rate: 2}}}}\n",
    )
    .expect("written");
    let (code, out, err) = run_btrel(&["export", "--to", "prism", p.to_str().expect("path")]);
    assert_eq!(code, 0, "{err}");
    // four phases, then Success (4) and Failure (5)
    assert!(
        out.contains("s = 0..3 are phases, s = 4 is Success"),
        "{out}"
    );
}

/// Durations drawn from a family with a fixed seed.
fn draw(n: usize, seed: u64, f: impl Fn(&mut Xoshiro256PlusPlus) -> f64) -> Vec<f64> {
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(seed);
    (0..n).map(|_| f(&mut rng)).collect()
}

fn exp(rng: &mut Xoshiro256PlusPlus) -> f64 {
    Exp1.sample(rng)
}

fn counts_of(success: Vec<f64>, failure: Vec<f64>, censored: Vec<f64>) -> Counts {
    Counts {
        successes: success.len(),
        failures: failure.len(),
        halted: censored.len(),
        instants: 0,
        success_time: success.iter().sum(),
        failure_time: failure.iter().sum(),
        censored,
        success_durations: success,
        failure_durations: failure,
    }
}

fn families(c: Counts) -> (Option<Family>, Option<Family>, Vec<String>) {
    let f = fit_leaf_with("A", Declared::Action, c, TimingMode::Auto).expect("fitted");
    let Timing::Families {
        success, failure, ..
    } = f.timing
    else {
        panic!("auto timing: {:?}", f.timing)
    };
    (
        success.map(|s| s.family),
        failure.map(|s| s.family),
        f.warnings,
    )
}

#[test]
fn auto_timing_picks_the_true_family_of_clear_samples() {
    let n = 400;
    // Erlang-3 of rate 2 (mean 1.5) for Success, exponential (mean 2) for Failure
    let erl = draw(n, 1, |r| (exp(r) + exp(r) + exp(r)) / 2.0);
    let ex = draw(n, 2, |r| 2.0 * exp(r));
    let (s, f, _) = families(counts_of(erl, ex, Vec::new()));
    let Some(Family::Erlang { k: 3, rate }) = s else {
        panic!("Erlang-3 expected: {s:?}")
    };
    // the MLE n k / Σt has relative se 1/√(n k)
    assert!(
        (rate - 2.0).abs() < 5.0 * 2.0 / (3.0 * n as f64).sqrt(),
        "{rate}"
    );
    assert!(matches!(f, Some(Family::Exponential { .. })), "{f:?}");
    // shifted exponential: 8 s + Exp(mean 2); deterministic: 3 s exactly
    let sh = draw(n, 3, |r| 8.0 + 2.0 * exp(r));
    let (s, f, _) = families(counts_of(sh, vec![3.0; 50], Vec::new()));
    let Some(Family::ShiftedExponential { shift, rate }) = s else {
        panic!("shifted exponential expected: {s:?}")
    };
    assert!((8.0..8.1).contains(&shift), "{shift}");
    assert!((rate - 0.5).abs() < 5.0 * 0.5 / (n as f64).sqrt(), "{rate}");
    assert_eq!(f, Some(Family::Deterministic { time: 3.0 }));
}

#[test]
fn auto_timing_enters_halts_in_the_likelihood() {
    // Erlang-3 (rate 2) successes only, every episode halted at an
    // independent Exp(mean 2) time when it would run longer: ignoring the
    // halts would bias the rate up (only the short runs complete)
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(11);
    let (mut done, mut halted) = (Vec::new(), Vec::new());
    for _ in 0..3000 {
        let t: f64 = (exp(&mut rng) + exp(&mut rng) + exp(&mut rng)) / 2.0;
        let c = 2.0 * exp(&mut rng);
        if t <= c {
            done.push(t);
        } else {
            halted.push(c);
        }
    }
    assert!(halted.len() > 500, "{}", halted.len());
    let naive = 3.0 * done.len() as f64 / done.iter().sum::<f64>();
    let (s, _, _) = families(counts_of(done, Vec::new(), halted));
    let Some(Family::Erlang { k: 3, rate }) = s else {
        panic!("Erlang-3 expected: {s:?}")
    };
    // se of the rate ≈ rate/√(3·completed) ≈ 0.03
    assert!(
        (rate - 2.0).abs() < 0.15,
        "{rate} (ignoring halts: {naive})"
    );
    assert!(naive - 2.0 > 0.3, "the halts matter here: {naive}");
}

#[test]
fn few_episodes_keep_the_exponential_with_a_warning() {
    let erl = draw(8, 5, |r| (exp(r) + exp(r) + exp(r)) / 2.0);
    let (s, _, w) = families(counts_of(erl, Vec::new(), Vec::new()));
    assert!(matches!(s, Some(Family::Exponential { .. })), "{s:?}");
    assert!(w.iter().any(|w| w.contains("fewer than 10")), "{w:?}");
}

#[test]
fn xml_params_files_take_the_time_laws() {
    let dir = tempfile::tempdir().expect("tempdir");
    let (xml, params) = common::write_xml_sequence(
        dir.path(),
        &[("Dock", "dock"), ("Grasp", "grasp")],
        "dock: {ps: 1, success_time: {shift: 8, erlang: {k: 3, rate: 0.5}}}\n\
         grasp: {ps: 0.5, success_time: {hypoexponential: [1, 4]}, failure_time: {fixed: 2}}\n",
    );
    let (code, out, err) = run_btrel(&[
        "report",
        xml.to_str().expect("path"),
        "--params",
        params.to_str().expect("path"),
        "--format",
        "json",
    ]);
    assert_eq!(code, 0, "{err}");
    let v: serde_json::Value = serde_json::from_str(&out).expect("JSON");
    let node = |name: &str| {
        v["nodes"]
            .as_array()
            .expect("nodes")
            .iter()
            .find(|n| n["name"] == name)
            .cloned()
            .expect("node")
    };
    // dock: 8 + 3/0.5 = 14; grasp: 1 + 1/4 on Success, 2 on Failure
    assert!((node("dock")["mtts"].as_f64().expect("mtts") - 14.0).abs() < 1e-12);
    assert!((node("grasp")["mtts"].as_f64().expect("mtts") - 1.25).abs() < 1e-12);
    let seq = node("seq");
    assert!(
        (seq["mtts"].as_f64().expect("mtts") - 15.25).abs() < 1e-12,
        "{seq}"
    );
    assert!(
        (seq["mttf"].as_f64().expect("mttf") - 16.0).abs() < 1e-12,
        "{seq}"
    );
    // a bad value in the params file: located there
    std::fs::write(
        &params,
        "dock: {ps: 1, success_time: {erlang: {k: 0, rate: 0.5}}}\ngrasp: {ps: 1, mu: 1}\n",
    )
    .expect("written");
    let (code, _, err) = run_btrel(&[
        "check",
        xml.to_str().expect("path"),
        "--params",
        params.to_str().expect("path"),
    ]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("t.params.yaml:1:42"), "{err}");
    assert!(err.contains("not a valid stage count"), "{err}");
}

#[test]
fn instant_successes_with_halts_still_get_a_success_time() {
    // 20 successes in zero time, 30 timed failures, 5 halts: every outcome
    // that occurred needs a time in the params file
    let ex = draw(30, 9, |r| 2.0 * exp(r));
    let mut c = counts_of(vec![0.0; 20], ex, vec![0.5, 1.0, 1.5, 2.0, 2.5]);
    c.instants = 20;
    let f = fit_leaf_with("A", Declared::Action, c, TimingMode::Auto).expect("fitted");
    let line = btrel::fit::params_line(&f);
    assert!(
        line.contains("mu: ") || line.contains("success_time: "),
        "{line}"
    );
    assert!(
        f.warnings.iter().any(|w| w.contains("instantly")),
        "{:?}",
        f.warnings
    );
}

#[test]
fn sensitivity_moves_a_shift_as_its_tau() {
    use btrel::sensitivity::{sensitivity, Objective, Param};
    // MTTS = shift + k/rate: dMTTS/dshift = 1, elasticity 2/4; P(S by 5)
    // = Erlang-2 CDF at 5 − shift, so its derivative is −(density at 3) =
    // −3 e^{−3}
    let t = tree("tree: {action: {ps: 1, success_time: {shift: 2, erlang: {k: 2, rate: 1}}}}");
    let s = sensitivity(&t, Objective::Mtts, &Default::default()).expect("sensitivity");
    let row = s
        .rows
        .iter()
        .find(|r| r.param == Param::TauS)
        .expect("the shift is a parameter");
    assert_eq!(row.value, 2.0);
    assert!((row.derivative - 1.0).abs() < 1e-8, "{row:?}");
    assert!(
        (row.elasticity.expect("defined") - 0.5).abs() < 1e-8,
        "{row:?}"
    );
    let s = sensitivity(&t, Objective::SuccessBy(5.0), &Default::default()).expect("sensitivity");
    let row = s
        .rows
        .iter()
        .find(|r| r.param == Param::TauS)
        .expect("shift");
    let want = -3.0 * (-3.0f64).exp();
    assert!((row.derivative - want).abs() < 1e-7, "{row:?} vs {want}");
}

/// `Tree::with_action_times`: a variant of a validated tree with other leaf
/// times is a new tree (the tree itself is immutable outside the crate);
/// invalid times are refused naming the action and the outcome.
#[test]
fn a_tree_with_other_action_times() {
    let t = tree(
        "tree: {sequence: {children: [{action: {name: a, ps: 0.9, mu: 1, nu: 2}}, \
         {action: {name: b, ps: 0.5, mu: 4, nu: 4}}]}}",
    );
    // a's Success takes exactly 2 s, b keeps its times: the Sequence
    // succeeds after 2 + 1/4 s on average (a closed form), with 0.45
    let fixed = t
        .with_action_times(|id, a| {
            if t.node(id).name == "a" {
                (Some(Duration::Fixed { time: 2.0 }), a.failure)
            } else {
                (a.success, a.failure)
            }
        })
        .unwrap();
    let f = root_figures(&fixed);
    assert!((f.ps - 0.45).abs() < 1e-12, "{}", f.ps);
    assert!((f.mtts.unwrap() - 2.25).abs() < 1e-12, "{:?}", f.mtts);
    // the original is unchanged: 1 + 1/4
    assert!((root_figures(&t).mtts.unwrap() - 1.25).abs() < 1e-12);
    let e = t
        .with_action_times(|_, a| (Some(Duration::Exponential { rate: -1.0 }), a.failure))
        .unwrap_err();
    assert_eq!((e.node.as_str(), e.outcome), ("a", "success"));
    assert!(e.to_string().contains("rate -1"), "{e}");
    let e = t.with_action_times(|_, a| (a.success, None)).unwrap_err();
    assert_eq!((e.node.as_str(), e.outcome), ("a", "failure"));
    assert!(e.to_string().contains("is missing"), "{e}");
    let e = t
        .with_action_times(|_, a| {
            let capped = Duration::TruncatedExponential {
                rate: 1.0,
                cap: f64::NAN,
            };
            (Some(capped), a.failure)
        })
        .unwrap_err();
    assert!(e.to_string().contains("cap NaN"), "{e}");
}
