//! General phase-type outcome times (`{phase_type: {alpha, T}}`) and the
//! hyperexponential shorthand: closed forms worked out by hand, a transient
//! probability from mpmath's matrix exponential (40 digits), Monte Carlo
//! through btrel's simulator (|z| < 5), located errors, and `btrel fit
//! --timing auto` recovering a hyperexponential from synthetic durations.

mod common;

use btrel::curve::{curve, CurveOptions};
use btrel::fit::timing::Family;
use btrel::fit::{fit_leaf_with, Counts, Timing, TimingMode};
use btrel::logs::Declared;
use btrel::tree::parse::{fast_reader_accepts, parse_full};
use btrel::tree::{parse_str, NodeKind, ParseLimits};
use common::{root_figures, run_btrel, tree};
use rand::{RngExt, SeedableRng};
use rand_distr::{Distribution, Exp1};
use rand_xoshiro::Xoshiro256PlusPlus;

const HYPER: &str = "{hyperexponential: [{p: 0.3, rate: 2}, {p: 0.7, rate: 0.5}]}";
const PH: &str = "{phase_type: {alpha: [0.3, 0.7], T: [[-2, 1], [0, -3]]}}";

fn curve_at(t: &btrel::tree::Tree, x: f64) -> (f64, f64) {
    let p = curve(t, 0, &[x], &CurveOptions::default()).expect("curve")[0];
    (p.success, p.failure)
}

#[test]
fn a_hyperexponential_leaf_has_its_closed_form_mean_and_cdf() {
    // 0.3·Exp(2) + 0.7·Exp(0.5): mean 0.3/2 + 0.7/0.5 = 1.55,
    // P(T ≤ t) = 1 − 0.3 e^{−2t} − 0.7 e^{−0.5t}
    let t = tree(&format!(
        "tree: {{action: {{ps: 1, success_time: {HYPER}}}}}"
    ));
    let f = root_figures(&t);
    assert!((f.mtts.expect("succeeds") - 1.55).abs() < 1e-12, "{f:?}");
    for x in [0.1f64, 0.7, 2.0, 9.0] {
        let want = 1.0 - 0.3 * (-2.0 * x).exp() - 0.7 * (-0.5 * x).exp();
        let (s, _) = curve_at(&t, x);
        assert!((s - want).abs() < 1e-11, "{x}: {s} vs {want}");
    }
    let NodeKind::Action(a) = t.nodes()[0].kind else {
        panic!("an action")
    };
    let d = a.success.expect("a time");
    assert_eq!(d.family(), "hyperexponential");
    // variance: E[T²] = 2(0.3/4 + 0.7/0.25) = 5.75, minus 1.55²
    let stages = d.stages().expect("phase-type");
    assert!((stages.variance() - (5.75 - 1.55 * 1.55)).abs() < 1e-12);
    assert_eq!(stages.phases(), 2);
}

#[test]
fn a_phase_type_leaf_then_an_exponential_matches_the_matrix_exponential() {
    // PH(α = (0.3, 0.7), T = [[−2, 1], [0, −3]]), then Exp(1.5): the time to
    // absorption of α′ = (0.3, 0.7, 0), T′ = [[−2, 1, 1], [0, −3, 3],
    // [0, 0, −1.5]]. Reference values: mpmath (mp.dps = 40),
    //   1 − (α′ · expm(T′ t) · 1)
    // and mean α′(−T′)⁻¹1 = (0.3·2/3 + 0.7/3) + 1/1.5 = 1.1 by hand.
    const REF: [(f64, f64); 4] = [
        (0.25, 0.08137611644803501),
        (1.0, 0.549501824698073),
        (2.5, 0.9370927516071839),
        (6.0, 0.9996161543011505),
    ];
    let t = tree(&format!(
        "tree: {{sequence: {{children: [\
           {{action: {{ps: 1, success_time: {PH}}}}}, \
           {{action: {{ps: 1, mu: 1.5}}}}]}}}}"
    ));
    let f = root_figures(&t);
    assert!((f.mtts.expect("succeeds") - 1.1).abs() < 1e-12, "{f:?}");
    for (x, want) in REF {
        let (s, _) = curve_at(&t, x);
        assert!((s - want).abs() < 1e-11, "{x}: {s} vs {want}");
    }
    // with outcomes: ps 0.8 then 0.6 scale the success curve by 0.48
    let t = tree(&format!(
        "tree: {{sequence: {{children: [\
           {{action: {{ps: 0.8, success_time: {PH}, nu: 4}}}}, \
           {{action: {{ps: 0.6, mu: 1.5, nu: 2}}}}]}}}}"
    ));
    for (x, want) in REF {
        let (s, _) = curve_at(&t, x);
        assert!(
            (s - 0.48 * want).abs() < 1e-11,
            "{x}: {s} vs {}",
            0.48 * want
        );
    }
}

#[test]
fn the_stored_order_is_topological_and_the_law_is_unchanged() {
    // the same law with its phases listed backwards (phase 2 enters 1)
    let a = tree(&format!("tree: {{action: {{ps: 1, success_time: {PH}}}}}"));
    let b = tree(
        "tree: {action: {ps: 1, success_time: \
         {phase_type: {alpha: [0.7, 0.3], T: [[-3, 0], [1, -2]]}}}}",
    );
    for x in [0.2, 1.0, 3.0] {
        let (sa, _) = curve_at(&a, x);
        let (sb, _) = curve_at(&b, x);
        assert!((sa - sb).abs() < 1e-13, "{x}: {sa} vs {sb}");
    }
    // mean 0.3·(1 + 1/3)/2 + 0.7/3 by hand
    let want = 0.3 * (4.0 / 3.0) / 2.0 + 0.7 / 3.0;
    assert!((root_figures(&b).mtts.expect("succeeds") - want).abs() < 1e-12);
}

#[test]
fn a_cyclic_law_is_taken_in_its_canonical_acyclic_form() {
    // T = [[−2, 1], [1, −3]] (phases 1 ⇄ 2), then Exp(1.5): mpmath
    // (mp.dps = 40) on α′ = (0.3, 0.7, 0), T′ = [[−2, 1, 1], [1, −3, 2],
    // [0, 0, −1.5]]: 1 − α′ expm(T′t) 1 and the mean α′(−T′)⁻¹1
    const REF: [(f64, f64); 4] = [
        (0.25, 0.05987998508444627),
        (1.0, 0.45237571217824335),
        (2.5, 0.8861319444262953),
        (6.0, 0.9984780859912117),
    ];
    let t = tree(
        "tree: {sequence: {children: [\
           {action: {ps: 1, success_time: {phase_type: {alpha: [0.3, 0.7], T: [[-2, 1], [1, -3]]}}}}, \
           {action: {ps: 1, mu: 1.5}}]}}",
    );
    let f = root_figures(&t);
    assert!(
        (f.mtts.expect("succeeds") - 1.3266666666666667).abs() < 1e-12,
        "{f:?}"
    );
    for (x, want) in REF {
        let (s, _) = curve_at(&t, x);
        assert!((s - want).abs() < 1e-11, "{x}: {s} vs {want}");
    }
    // a 3-phase law with cycles everywhere (real eigenvalues −3.386,
    // −1.946, −0.668): mpmath gives the mean 1.4375 and P(T ≤ 0.5), P(T ≤ 2)
    let alpha = [0.2, 0.3, 0.5];
    let m = [[-3.0, 1.0, 1.0], [0.5, -2.0, 0.5], [0.2, 0.3, -1.0]];
    let t = tree(
        "tree: {action: {ps: 1, success_time: {phase_type: {alpha: [0.2, 0.3, 0.5], \
           T: [[-3, 1, 1], [0.5, -2, 0.5], [0.2, 0.3, -1]]}}}}",
    );
    assert!((root_figures(&t).mtts.expect("succeeds") - 1.4375).abs() < 1e-12);
    let refs = [(0.5, 0.3049427279668464), (2.0, 0.7516641881642597)];
    for (x, want) in refs {
        let (s, _) = curve_at(&t, x);
        assert!((s - want).abs() < 1e-11, "{x}: {s} vs {want}");
    }
    // and a walk of the cyclic chain as written (not btrel's form):
    // 200 000 draws, |z| < 5 on both probabilities
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(5);
    let n = 200_000;
    let mut below = [0usize; 2];
    for _ in 0..n {
        let u: f64 = rng.random();
        let mut i = if u < alpha[0] {
            0
        } else if u < alpha[0] + alpha[1] {
            1
        } else {
            2
        };
        let mut time = 0.0;
        loop {
            let q = -m[i][i];
            let e: f64 = Exp1.sample(&mut rng);
            time += e / q;
            let u: f64 = rng.random::<f64>() * q;
            let mut acc = 0.0;
            let mut next = None;
            for (j, &r) in m[i].iter().enumerate() {
                if j != i {
                    acc += r;
                    if u < acc {
                        next = Some(j);
                        break;
                    }
                }
            }
            match next {
                Some(j) => i = j,
                None => break,
            }
        }
        for (k, (x, _)) in refs.iter().enumerate() {
            if time <= *x {
                below[k] += 1;
            }
        }
    }
    for (k, (x, _)) in refs.iter().enumerate() {
        let (s, _) = curve_at(&t, *x);
        let est = below[k] as f64 / n as f64;
        let se = (s * (1.0 - s) / n as f64).sqrt();
        assert!(((est - s) / se).abs() < 5.0, "{x}: walk {est} vs {s}");
    }
}

/// Figures and curves agree with btrel's simulator, which draws a
/// phase-type time by walking its phases (|z| < 5).
#[test]
fn simulation_agrees_through_a_parallel_and_a_fallback() {
    let cases = [
        format!(
            "tree: {{parallel: {{success_threshold: 1, children: [\
               {{action: {{ps: 0.7, success_time: {PH}, failure_time: {HYPER}}}}}, \
               {{action: {{ps: 0.5, success_time: {{erlang: {{k: 2, rate: 2}}}}, nu: 3}}}}]}}}}"
        ),
        format!(
            "tree: {{fallback: {{children: [\
               {{action: {{ps: 0.4, success_time: {{shift: 0.5, phase_type: \
                 {{alpha: [0.5, 0.25, 0.25], T: [[-4, 2, 1], [0, -1, 0.5], [0, 0, -3]]}}}}, \
                 failure_time: {HYPER}}}}}, \
               {{parallel: {{success_threshold: 2, children: [\
                 {{action: {{ps: 0.9, success_time: {HYPER}, failure_time: {{rate: 1}}}}}}, \
                 {{action: {{ps: 0.6, mu: 1.2, failure_time: {PH}}}}}]}}}}]}}}}"
        ),
    ];
    common::assert_cases_match_simulation(&cases, &[0.5, 1.0, 2.0, 4.0], 200_000);
}

#[test]
fn the_written_form_reads_back_to_the_same_law() {
    let t = tree(&format!(
        "tree: {{action: {{ps: 0.5, success_time: {{shift: 2, phase_type: \
           {{alpha: [0.3, 0.7], T: [[-2, 1], [0, -3]]}}}}, failure_time: {HYPER}}}}}"
    ));
    let NodeKind::Action(a) = t.nodes()[0].kind else {
        panic!("an action")
    };
    let y = format!(
        "tree: {{action: {{ps: 0.5, success_time: {{shift: 2, phase_type: \
           {{alpha: [0.3, 0.7], T: [[-2, 1], [0, -3]]}}}}, failure_time: {HYPER}}}}}"
    );
    assert!(fast_reader_accepts(&y));
    let full = parse_full(&y, "t.yaml", ParseLimits::default()).expect("parses");
    assert_eq!(full, t);
    let (s, f) = (a.success.expect("S"), a.failure.expect("F"));
    assert_eq!(s.family(), "shifted phase-type");
    assert_eq!(f.family(), "hyperexponential");
    for d in [s, f] {
        let y = format!("tree: {{action: {{ps: 1, success_time: {}}}}}", d.to_yaml());
        let NodeKind::Action(r) = tree(&y).nodes()[0].kind else {
            panic!("an action")
        };
        assert_eq!(r.success, Some(d), "{y}");
    }
    // one phase is the exponential
    let t = tree("tree: {action: {ps: 1, success_time: {phase_type: {alpha: [1], T: [[-2]]}}}}");
    let NodeKind::Action(a) = t.nodes()[0].kind else {
        panic!("an action")
    };
    assert_eq!(a.success.expect("S").family(), "exponential");
}

#[test]
fn bad_phase_type_laws_are_located_errors() {
    let at = |head: &str| head.len() + 1;
    let head = "tree:\n  action: {ps: 1, success_time: {phase_type: ";
    let col = at("  action: {ps: 1, success_time: {phase_type: ");
    let cases: Vec<(String, (usize, usize), &str)> = vec![
        // a cycle through three phases with complex eigenvalues −2.75 ±
        // 1.299i: no acyclic form of order 3
        (
            format!(
                "{head}{{alpha: [1, 0, 0], T: [[-2, 1.5, 0], [0, -2, 1.5], [1.5, 0, -2]]}}}}}}\n"
            ),
            (2, col),
            "complex eigenvalue",
        ),
        // no exit from either phase: absorption is not certain
        (
            format!("{head}{{alpha: [0.5, 0.5], T: [[-1, 1], [1, -1]]}}}}}}\n"),
            (2, col),
            "absorption is not certain",
        ),
        // an atom at 0
        (
            format!("{head}{{alpha: [0.3, 0.6], T: [[-2, 1], [0, -3]]}}}}}}\n"),
            (2, col),
            "not 1",
        ),
        // a positive diagonal, located at the entry
        (
            format!("{head}{{alpha: [0.3, 0.7], T: [[-2, 1], [0, 3]]}}}}}}\n"),
            (2, col + "{alpha: [0.3, 0.7], T: [[-2, 1], [0, ".len()),
            "must be a finite number < 0",
        ),
        // a row summing to > 0
        (
            format!("{head}{{alpha: [0.3, 0.7], T: [[-2, 3], [0, -3]]}}}}}}\n"),
            (2, col),
            "row 1 of T sums to 1 > 0",
        ),
        // a ragged row, located at the row
        (
            format!("{head}{{alpha: [0.3, 0.7], T: [[-2, 1], [0]]}}}}}}\n"),
            (2, col + "{alpha: [0.3, 0.7], T: [[-2, 1], ".len()),
            "has 1 entries, not 2",
        ),
        (
            "tree:\n  action: {ps: 1, success_time: {hyperexponential: \
             [{p: 0.3, rate: 2}, {p: 0.3, rate: 1}]}}\n"
                .into(),
            (2, at("  action: {ps: 1, success_time: {hyperexponential: ")),
            "not 1",
        ),
        (
            "tree:\n  action: {ps: 1, success_time: {hyperexponential: \
             [{p: 0.3, rate: 2}, {p: 0.7, rate: 0}]}}\n"
                .into(),
            (
                2,
                at("  action: {ps: 1, success_time: {hyperexponential: [{p: 0.3, rate: 2}, {p: 0.7, rate: "),
            ),
            "not a valid rate",
        ),
    ];
    for (y, (line, column), what) in &cases {
        // the fast reader and the full parser give the same error
        let full = parse_full(y, "t.yaml", ParseLimits::default()).expect_err(y);
        assert!(fast_reader_accepts(y), "{y}");
        let e = parse_str(y, "t.yaml").expect_err(y);
        assert_eq!(e, full, "{y}");
        assert!(e.message.contains(what), "{y}: {}", e.message);
        assert_eq!((e.line, e.column), (*line, *column), "{y}: {}", e.message);
    }
    // more than 64 phases
    let n = 65;
    let alpha = std::iter::once("1".to_string())
        .chain((1..n).map(|_| "0".to_string()))
        .collect::<Vec<_>>()
        .join(", ");
    let rows = (0..n)
        .map(|i| {
            let r: Vec<&str> = (0..n).map(|j| if i == j { "-1" } else { "0" }).collect();
            format!("[{}]", r.join(", "))
        })
        .collect::<Vec<_>>()
        .join(", ");
    let y = format!("tree:\n  action: {{ps: 1, success_time: {{phase_type: {{alpha: [{alpha}], T: [{rows}]}}}}}}\n");
    let e = parse_str(&y, "t.yaml").expect_err("too many phases");
    assert!(e.message.contains("65 entries"), "{}", e.message);
    // and through the CLI: exit 2 with file:line:column
    let dir = tempfile::tempdir().expect("tempdir");
    let p = dir.path().join("bad.yaml");
    std::fs::write(&p, &cases[0].0).expect("written");
    let (code, _, err) = run_btrel(&["check", p.to_str().expect("path")]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains(&format!("bad.yaml:2:{col}")), "{err}");
}

#[test]
fn the_prism_export_has_one_state_per_phase() {
    let dir = tempfile::tempdir().expect("tempdir");
    let p = dir.path().join("t.yaml");
    std::fs::write(
        &p,
        format!("tree: {{action: {{ps: 1, success_time: {PH}}}}}\n"),
    )
    .expect("written");
    let (code, out, err) = run_btrel(&["export", "--to", "prism", p.to_str().expect("path")]);
    assert_eq!(code, 0, "{err}");
    assert!(
        out.contains("s = 0..1 are phases, s = 2 is Success"),
        "{out}"
    );
    // a shifted phase-type law has no CTMC
    std::fs::write(
        &p,
        "tree: {action: {ps: 1, success_time: {shift: 1, hyperexponential: \
         [{p: 0.3, rate: 2}, {p: 0.7, rate: 0.5}]}}}\n",
    )
    .expect("written");
    let (code, _, err) = run_btrel(&["export", "--to", "prism", p.to_str().expect("path")]);
    assert_eq!(code, 1, "{err}");
    assert!(err.contains("no CTMC"), "{err}");
}

fn families(success: Vec<f64>) -> Option<Family> {
    let c = Counts {
        successes: success.len(),
        failures: 0,
        halted: 0,
        instants: 0,
        success_time: success.iter().sum(),
        failure_time: 0.0,
        censored: Vec::new(),
        success_durations: success,
        failure_durations: Vec::new(),
    };
    let f = fit_leaf_with("A", Declared::Action, c, TimingMode::Auto).expect("fitted");
    let Timing::Families { success, .. } = f.timing else {
        panic!("auto timing: {:?}", f.timing)
    };
    success.map(|s| s.family)
}

#[test]
fn auto_timing_recovers_a_hyperexponential() {
    // 0.4·Exp(5) + 0.6·Exp(0.4): a fast mode (mean 0.2 s) and a slow one
    // (mean 2.5 s), 3000 draws
    let n = 3000;
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(21);
    let x: Vec<f64> = (0..n)
        .map(|_| {
            let e: f64 = Exp1.sample(&mut rng);
            let u: f64 = Exp1.sample(&mut rng);
            // the mode from an Exp(1) draw: P(u < −ln 0.6) = 0.4
            if u < -(0.6f64).ln() {
                e / 5.0
            } else {
                e / 0.4
            }
        })
        .collect();
    let Some(Family::Hyperexponential { p, rate1, rate2 }) = families(x) else {
        panic!("a hyperexponential expected")
    };
    // standard errors, roughly: √(p(1−p)/n) ≈ 0.009 for p, rate/√(count
    // of the mode) ≈ 0.14 and 0.009 for the rates, each inflated by the
    // modes' overlap; about 5 of them:
    assert!((p - 0.4).abs() < 0.06, "p = {p}");
    assert!((rate1 - 5.0).abs() < 1.0, "rate1 = {rate1}");
    assert!((rate2 - 0.4).abs() < 0.05, "rate2 = {rate2}");
    // an exponential sample keeps its family
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(22);
    let x: Vec<f64> = (0..n)
        .map(|_| {
            let e: f64 = Exp1.sample(&mut rng);
            2.0 * e
        })
        .collect();
    let f = families(x);
    assert!(matches!(f, Some(Family::Exponential { .. })), "{f:?}");
}

#[test]
fn xml_params_files_take_phase_type_laws() {
    let dir = tempfile::tempdir().expect("tempdir");
    let (xml, params) = common::write_xml_sequence(
        dir.path(),
        &[("Pick", "pick"), ("Place", "place")],
        &format!("pick: {{ps: 1, success_time: {HYPER}}}\nplace: {{ps: 1, success_time: {PH}}}\n"),
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
    // 1.55 (hyperexponential) + 0.3·(2/3) + 0.7/3 (phase-type) by hand
    let mtts = v["nodes"][0]["mtts"].as_f64().expect("mtts");
    assert!((mtts - (1.55 + 0.2 + 0.7 / 3.0)).abs() < 1e-12, "{mtts}");
    // a bad entry: located in the params file
    std::fs::write(
        &params,
        "pick: {ps: 1, mu: 1}\nplace: {ps: 1, success_time: {phase_type: {alpha: [1], T: [[2]]}}}\n",
    )
    .expect("written");
    let (code, _, err) = run_btrel(&[
        "check",
        xml.to_str().expect("path"),
        "--params",
        params.to_str().expect("path"),
    ]);
    assert_eq!(code, 2, "{err}");
    let col = "place: {ps: 1, success_time: {phase_type: {alpha: [1], T: [[".len() + 1;
    assert!(err.contains(&format!("t.params.yaml:2:{col}")), "{err}");
}

#[test]
fn sensitivity_holds_general_phase_type_parameters_only() {
    let (code, out, err) = run_btrel(&["sensitivity", "trees/phase-type.yaml"]);
    assert_eq!(code, 0, "{err}");
    // a general law's alpha and T are held; Erlang and hyperexponential
    // laws have rows
    assert!(
        err.contains(
            "of place (phase-type); page operator (phase-type) are held, not differentiated"
        ),
        "{err}"
    );
    let params = |leaf: &str| -> Vec<String> {
        out.lines()
            .filter(|l| l.starts_with(&format!("{leaf} ")))
            .map(|l| l.split_whitespace().nth(2).unwrap_or("").to_string())
            .collect()
    };
    let mut pick = params("pick");
    pick.sort();
    assert_eq!(
        pick,
        ["nu", "ps", "success_p", "success_rate1", "success_rate2"],
        "{out}"
    );
    let mut place = params("place");
    place.sort();
    assert_eq!(place, ["failure_rate", "ps"], "{out}");
}
