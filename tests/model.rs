//! The library facade (`btrel::Model`) and the planner's table
//! (`compile::plan`): one representation per node, decided by the first
//! rule that applies, and figures and curves that agree with closed forms.

mod common;

use common::tree;

use btrel::{Error, Method, Model, Options, Representation, Tree};

fn rep(model: &Model, id: usize) -> Representation {
    model.representation(id).expect("planned")
}

/// Sequence(exponential action, hybrid action: Success at exactly 3 s,
/// Failure at min(X, 3) with X ~ Exp(0.5), Def. 9.9): the figures and the
/// curve in closed form.
#[test]
fn figures_and_curve_of_a_mixed_sequence_in_closed_form() {
    let t = tree(
        "tree: {sequence: {children: [{action: {ps: 0.9, mu: 1.0, nu: 2.0}}, \
         {action: {ps: 0.8, tau_s: 3.0, nu: 0.5}}]}}",
    );
    let m = Model::new(&t).unwrap();
    let root = m.figures(Tree::ROOT).expect("figures");
    // P(S) = 0.9 · 0.8; MTTS = 1/mu + tau_s
    assert!((root.ps - 0.72).abs() < 1e-15);
    assert!((root.mtts.unwrap() - 4.0).abs() < 1e-12);
    // P(F) = 0.1 + 0.9 · 0.2; E[T·1{F}] = 0.1/nu1 + 0.18 (1/mu1 + E[min(X, 3)]),
    // E[min(X, c)] = (1 − e^{−nu c}) / nu
    assert!((root.pf - 0.28).abs() < 1e-15);
    let truncated = (1.0 - (-1.5f64).exp()) / 0.5;
    let mttf = (0.1 * 0.5 + 0.18 * (1.0 + truncated)) / 0.28;
    assert!((root.mttf.unwrap() - mttf).abs() < 1e-12);
    // S(t) = 0.72 (1 − e^{−(t − 3)}) for t ≥ 3, 0 before
    let pi = m.curve(Tree::ROOT, &[2.5, 3.0, 4.0, 10.0]).unwrap();
    for p in &pi {
        let s = if p.t >= 3.0 {
            0.72 * (1.0 - (-(p.t - 3.0)).exp())
        } else {
            0.0
        };
        assert!(
            (p.success - s).abs() < 1e-12,
            "S({}) = {} vs {s}",
            p.t,
            p.success
        );
        assert!((p.success + p.failure + p.running - 1.0).abs() < 1e-12);
    }
}

/// Each row of the planner's table, on the smallest tree it applies to.
#[test]
fn the_planner_table_row_by_row() {
    let det = "{action: {ps: 0.7, tau_s: 1.0, tau_f: 2.0}}";
    let exp = "{action: {ps: 0.7, mu: 1.0, nu: 2.0}}";
    let hyb = "{action: {ps: 0.7, tau_s: 1.0, nu: 2.0}}";
    let cases: Vec<(String, Representation)> = vec![
        (format!("tree: {exp}"), Representation::Closed),
        (format!("tree: {{sequence: {{children: [{det}, {det}]}}}}"), Representation::Atoms),
        (format!("tree: {{sequence: {{children: [{exp}, {exp}]}}}}"), Representation::Chain),
        (format!("tree: {{until_failure: {{child: {exp}}}}}"), Representation::Loop),
        (format!("tree: {{parallel: {{children: [{exp}, {exp}]}}}}"), Representation::Chain),
        (format!("tree: {{parallel: {{children: [{det}, {exp}]}}}}"), Representation::Counted),
        (
            format!(
                "tree: {{parallel: {{success_threshold: 1, failure_threshold: 1, children: [{det}, {exp}]}}}}"
            ),
            Representation::Race,
        ),
        (format!("tree: {{fallback: {{children: [{hyb}, {exp}]}}}}"), Representation::Shifted),
        // phase-type leaves are Markovian, a shift is not
        (
            format!("tree: {{sequence: {{children: [{exp}, {{action: {{ps: 0.6, success_time: {{erlang: {{k: 3, rate: 2.0}}}}, failure_time: {{rate: 1.0}}}}}}]}}}}"),
            Representation::Chain,
        ),
        (
            format!("tree: {{sequence: {{children: [{exp}, {{action: {{ps: 0.6, success_time: {{shift: 0.5, rate: 2.0}}, failure_time: {{rate: 1.0}}}}}}]}}}}"),
            Representation::Shifted,
        ),
        // a zero-time outcome is instantaneous: still a chain
        (
            format!("tree: {{sequence: {{children: [{exp}, {{action: {{ps: 0.6, tau_s: 0, tau_f: 0}}}}]}}}}"),
            Representation::Chain,
        ),
    ];
    for (yaml, expected) in &cases {
        let m = Model::new(&tree(yaml)).unwrap();
        assert_eq!(rep(&m, Tree::ROOT), *expected, "{yaml}");
        // whatever the representation, the curve's limit is the figures
        let root = m.figures(Tree::ROOT).expect("figures");
        let far = m.curve(Tree::ROOT, &[200.0]).unwrap()[0];
        assert!(
            (far.success - root.ps).abs() < 1e-9,
            "{yaml}: {far:?} vs {root:?}"
        );
        assert!(
            (far.failure - root.pf).abs() < 1e-9,
            "{yaml}: {far:?} vs {root:?}"
        );
    }
    // a Parallel of 16 two-action subtrees: its product (4^16 states) is
    // counted, and the Sequence above it gets composed laws
    let sub = format!("{{sequence: {{children: [{exp}, {exp}]}}}}");
    let wide = format!(
        "tree: {{sequence: {{children: [{exp}, {{parallel: {{success_threshold: 8, children: [{}]}}}}]}}}}",
        vec![sub; 16].join(", ")
    );
    let m = Model::new(&tree(&wide)).unwrap();
    assert_eq!(rep(&m, Tree::ROOT), Representation::Composed);
    assert_eq!(rep(&m, 2), Representation::Counted);
    // the book's strategy plans every control node as its CTMC
    let m = Model::with_options(
        &tree(&format!("tree: {{sequence: {{children: [{exp}, {exp}]}}}}")),
        Options {
            method: Method::Book,
            ..Options::default()
        },
    )
    .unwrap();
    assert_eq!(rep(&m, Tree::ROOT), Representation::Book);
    assert_eq!(rep(&m, 1), Representation::Closed);
}

#[test]
fn typed_errors_for_bad_queries() {
    let m = Model::new(&tree("tree: {action: {ps: 0.5, mu: 1.0, nu: 1.0}}")).unwrap();
    assert!(matches!(
        m.curve(7, &[1.0]),
        Err(Error::NoSuchNode { node: 7, len: 1 })
    ));
    assert!(matches!(
        m.curve(0, &[1.0, f64::NAN]),
        Err(Error::BadTime { index: 1, .. })
    ));
    let e = btrel::parse_str("tree: {action: {ps: 1.5}}", "bad.yaml")
        .map_err(Error::from)
        .unwrap_err();
    assert!(matches!(e, Error::Tree(_)), "{e}");
    assert!(e.to_string().contains("bad.yaml"), "{e}");
}

/// A Timeout-shaped race (Parallel{1, 1}: a deadline failing at τ against
/// an exponential action) inside a Sequence: the race is a signed shifted
/// mixture, so the Sequence has a curve. Closed form with A ~ Exp(a) then
/// B ~ Exp(b) before the deadline τ, m = min(t, τ):
/// S(t) = (1 − e^{−bm}) − b e^{−at} (e^{(a−b)m} − 1)/(a − b),
/// F(t) = e^{−bτ} (1 − e^{−a(t−τ)}) for t ≥ τ, 0 before.
#[test]
fn a_timeout_inside_a_sequence_has_an_exact_curve() {
    let (a, b, tau) = (1.5f64, 0.4f64, 2.0f64);
    let t = tree(&format!(
        "tree: {{sequence: {{children: [{{action: {{ps: 1, mu: {a}}}}}, \
         {{parallel: {{success_threshold: 1, failure_threshold: 1, children: [\
         {{action: {{ps: 0, tau_f: {tau}}}}}, {{action: {{ps: 1, mu: {b}}}}}]}}}}]}}}}"
    ));
    let m = Model::new(&t).unwrap();
    assert_eq!(rep(&m, Tree::ROOT), Representation::Shifted);
    let times = [0.5, 1.0, 1.999, 2.0, 2.5, 4.0, 9.0, 60.0];
    let pi = m.curve(Tree::ROOT, &times).unwrap();
    for p in &pi {
        let t = p.t;
        let mm = t.min(tau);
        let s =
            (1.0 - (-b * mm).exp()) - b * (-a * t).exp() * (((a - b) * mm).exp() - 1.0) / (a - b);
        let f = if t >= tau {
            (-b * tau).exp() * (1.0 - (-a * (t - tau)).exp())
        } else {
            0.0
        };
        assert!(
            (p.success - s).abs() < 1e-10,
            "S({t}) = {} vs {s}",
            p.success
        );
        assert!(
            (p.failure - f).abs() < 1e-10,
            "F({t}) = {} vs {f}",
            p.failure
        );
    }
    // the limit is the report's
    let root = m.figures(Tree::ROOT).expect("figures");
    assert!((pi[7].success - root.ps).abs() < 1e-10);
}

/// Sequence(action, Timeout(deadline, hybrid-free action with both
/// outcomes), action) and a second deadline child: π(t) against the
/// simulator, |z| < 5, and the report's figures at the limit.
#[test]
fn first_return_races_inside_sequences_agree_with_simulation() {
    let yaml = "tree: {sequence: {children: [{action: {ps: 0.9, mu: 1.0, nu: 2.0}}, \
        {parallel: {success_threshold: 1, failure_threshold: 1, children: [\
        {action: {ps: 0, tau_f: 3.0}}, {action: {ps: 0.8, mu: 0.5, nu: 1.0}}, \
        {sequence: {children: [{action: {ps: 0.5, tau_s: 1.0, tau_f: 2.0}}, {action: {ps: 0.6, tau_s: 1.5, tau_f: 0.5}}]}}]}}, \
        {action: {ps: 0.9, mu: 1.0, nu: 2.0}}]}}";
    let t = tree(yaml);
    let m = Model::new(&t).unwrap();
    let times = [1.0, 2.5, 3.0, 4.0, 6.0, 12.0];
    let pi = m.curve(Tree::ROOT, &times).unwrap();
    let sim = btrel::simulate(
        &t,
        &btrel::SimOptions {
            runs: 400_000,
            times: times.to_vec(),
            seed: 11,
            ..Default::default()
        },
        None,
    )
    .unwrap();
    for (p, e) in pi.iter().zip(&sim.curve) {
        for (what, est, exact) in [("S", &e.success, p.success), ("F", &e.failure, p.failure)] {
            let se = est.se.max(1e-9);
            let z = (est.mean - exact) / se;
            assert!(
                z.abs() < 5.0,
                "{what}({}) = {exact}, simulated {} ± {se}",
                p.t,
                est.mean
            );
        }
    }
    let root = m.figures(Tree::ROOT).expect("figures");
    let far = m.curve(Tree::ROOT, &[200.0]).unwrap()[0];
    assert!((far.success - root.ps).abs() < 1e-9 && (far.failure - root.pf).abs() < 1e-9);
}

/// The model keeps its plan: on a tree with Nav2 nodes (planned as their
/// lowering) every node's curve, asked twice, with both timings, equals
/// the curve planned afresh for that one query, and the root's curve past
/// its return is its figures (the curve then reuses the model's figures).
#[test]
fn the_model_answers_from_its_own_plan() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("trees");
    let t = btrel::tree::xml::parse_xml_files(
        &dir.join("nav2-default-attempt.xml"),
        &dir.join("nav2-default-attempt.params.yaml"),
        &[],
    )
    .expect("the attempt parses");
    let m = Model::new(&t).expect("analysed");
    let times = [0.5, 3.0, 20.0];
    for timing in [
        btrel::curve::Timing::AsGiven,
        btrel::curve::Timing::Deterministic,
    ] {
        let options = btrel::curve::CurveOptions {
            timing,
            ..Default::default()
        };
        for id in 0..t.nodes().len() {
            let fresh = btrel::curve::curve(&t, id, &times, &options).expect("a curve");
            for _ in 0..2 {
                let kept = m.curve_with(id, &times, timing).expect("a curve");
                for (a, b) in kept.iter().zip(&fresh) {
                    assert_eq!((a.success, a.failure), (b.success, b.failure), "node {id}");
                }
            }
        }
    }
    let root = m.figures(Tree::ROOT).expect("figures");
    let far = m.curve(Tree::ROOT, &[1e7]).expect("a curve")[0];
    assert!(
        (far.success - root.ps).abs() <= 1e-13,
        "{far:?} vs {root:?}"
    );
    assert!(
        (far.failure - root.pf).abs() <= 1e-13,
        "{far:?} vs {root:?}"
    );
}

/// `Model::reorder` (Def. 9.10): a Fallback of two actions put in the
/// other order has, by its paths, P(S) = 1 − (1 − p1)(1 − p2) either way,
/// `E[T·1{S}] = p2/mu2 + (1 − p2)·p1·(1/nu2 + 1/mu1)` with the second
/// action first, and the other figures of the tree kept; a node that is
/// not a Fallback, or an order that is not a permutation, is refused and
/// leaves the model as it was.
#[test]
fn reorder_gives_the_figures_of_the_equivalent_tree() {
    let t = tree(
        "tree: {sequence: {children: [{action: {name: a, ps: 0.9, mu: 2.0, nu: 1.0}}, \
         {fallback: {name: f, children: [{action: {name: a1, ps: 0.3, mu: 1.0, nu: 2.0}}, \
         {action: {name: a2, ps: 0.6, mu: 0.5, nu: 4.0}}]}}]}}",
    );
    let mut m = Model::new(&t).unwrap();
    let before = m.figures(2).unwrap();
    let (p1, mu1, nu1) = (0.3, 1.0, 2.0);
    let (p2, mu2, nu2) = (0.6, 0.5, 4.0);
    let given = (p1 / mu1 + (1.0 - p1) * p2 * (1.0 / nu1 + 1.0 / mu2)) / before.ps;
    assert!((before.mtts.unwrap() - given).abs() < 1e-12, "{before:?}");
    m.reorder(&[(2, &[4, 3])]).unwrap();
    let f = m.figures(2).unwrap();
    assert!((f.ps - (1.0 - 0.7 * 0.4)).abs() < 1e-15);
    let swapped = (p2 / mu2 + (1.0 - p2) * p1 * (1.0 / nu2 + 1.0 / mu1)) / f.ps;
    assert!((f.mtts.unwrap() - swapped).abs() < 1e-12, "{f:?}");
    // both fail after both ran: MTTF = 1/nu1 + 1/nu2 either way
    assert!((f.mttf.unwrap() - (1.0 / nu1 + 1.0 / nu2)).abs() < 1e-12);
    // the root: the first action, then the Fallback
    let root = m.figures(Tree::ROOT).unwrap();
    assert!((root.ps - 0.9 * f.ps).abs() < 1e-15);
    assert!((root.mtts.unwrap() - (0.5 + swapped)).abs() < 1e-12);
    assert_eq!(m.tree().node(2).kind.children(), &[4, 3]);
    // refusals change nothing
    let e = m.reorder(&[(1, &[])]).unwrap_err();
    assert!(e.to_string().contains("not a Fallback"), "{e}");
    let e = m.reorder(&[(2, &[3, 3])]).unwrap_err();
    assert!(e.to_string().contains("not a permutation"), "{e}");
    assert_eq!(m.figures(2).unwrap(), f);
    assert!(matches!(
        m.reorder(&[(99, &[])]),
        Err(Error::NoSuchNode { node: 99, .. })
    ));
}

/// A model can move to another thread (a server, a worker pool); its
/// caches are per model, not shared.
#[test]
fn a_model_can_move_between_threads() {
    fn send<T: Send>(_: &T) {}
    let t = tree("tree: {action: {ps: 0.9, mu: 1.0, nu: 2.0}}");
    let m = Model::new(&t).unwrap();
    send(&m);
    let ps = std::thread::spawn(move || m.figures(Tree::ROOT).unwrap().ps)
        .join()
        .unwrap();
    assert!((ps - 0.9).abs() < 1e-15);
}
