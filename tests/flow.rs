//! The flow primitive (`flow:`, `if_then_else:`): every representation
//! against hand derivations — figures, phase chains, atoms, shifted
//! mixtures, interpolated laws, the book's CTMC — and the simulator.

mod common;
use btrel::compile::curve::CurveOptions;
use btrel::Method;
use common::*;

/// P(X + Y ≤ t), X ~ Exp(a), Y ~ Exp(b), a ≠ b.
fn hypo(a: f64, b: f64, t: f64) -> f64 {
    1.0 - (b * (-a * t).exp() - a * (-b * t).exp()) / (b - a)
}

const ITE: &str = "tree:
  if_then_else:
    children:
      - action: {ps: 0.3, mu: 1.0, nu: 2.0}
      - action: {ps: 0.6, mu: 3.0, nu: 4.0}
      - action: {ps: 0.8, mu: 5.0, nu: 6.0}
";

#[test]
fn if_then_else_figures_and_curve_match_closed_forms() {
    let t = tree(ITE);
    let f = root_figures(&t);
    // Success: C succeeds then T (0.3·0.6), or C fails then E (0.7·0.8)
    assert!((f.ps - 0.74).abs() < 1e-14);
    let mtts = (0.18 * (1.0 + 1.0 / 3.0) + 0.56 * (0.5 + 0.2)) / 0.74;
    let mttf = (0.12 * (1.0 + 0.25) + 0.14 * (0.5 + 1.0 / 6.0)) / 0.26;
    assert!((f.mtts.unwrap() - mtts).abs() < 1e-13);
    assert!((f.mttf.unwrap() - mttf).abs() < 1e-13);
    let times = [0.2, 0.7, 1.5, 4.0];
    let exact = |x: f64| {
        (
            0.18 * hypo(1.0, 3.0, x) + 0.56 * hypo(2.0, 5.0, x),
            0.12 * hypo(1.0, 4.0, x) + 0.14 * hypo(2.0, 6.0, x),
        )
    };
    // phase chain (default) and interpolated laws (a budget of 2 phases:
    // the flow's glued chain of 6 phases does not fit, its children do)
    for max_states in [btrel::compile::DEFAULT_MAX_STATES, 2] {
        let opts = CurveOptions {
            max_states,
            ..Default::default()
        };
        let pts = btrel::curve::curve(&t, 0, &times, &opts).unwrap();
        for p in &pts {
            let (s, fl) = exact(p.t);
            assert!((p.success - s).abs() < 1e-9, "{max_states}: {p:?} vs {s}");
            assert!((p.failure - fl).abs() < 1e-9, "{max_states}: {p:?} vs {fl}");
        }
    }
    let sim = simulate_root(&t, 200_000, &times);
    assert_within_z("MTTS", sim.nodes[0].mtts.as_ref().unwrap(), mtts);
    assert_within_z("ps", &sim.nodes[0].ps, 0.74);
    for (k, &x) in times.iter().enumerate() {
        assert_within_z("S(t)", &sim.curve[k].success, exact(x).0);
    }
}

#[test]
fn if_then_else_book_curve_is_exact_when_each_child_time_is_one_exponential() {
    // mu = nu: each child's time is Exp(rate) whatever its outcome, so the
    // book's one-phase summaries are exact
    let t = tree(
        "tree:
  if_then_else:
    children:
      - action: {ps: 0.3, mu: 1.0, nu: 1.0}
      - action: {ps: 0.6, mu: 3.0, nu: 3.0}
      - action: {ps: 0.8, mu: 5.0, nu: 5.0}
",
    );
    let opts = CurveOptions {
        method: Method::Book,
        ..Default::default()
    };
    let pts = btrel::curve::curve(&t, 0, &[0.3, 1.0, 3.0], &opts).unwrap();
    for p in &pts {
        let s = 0.18 * hypo(1.0, 3.0, p.t) + 0.56 * hypo(1.0, 5.0, p.t);
        let f = 0.12 * hypo(1.0, 3.0, p.t) + 0.14 * hypo(1.0, 5.0, p.t);
        assert!((p.success - s).abs() < 1e-9, "{p:?} vs {s}");
        assert!((p.failure - f).abs() < 1e-9, "{p:?} vs {f}");
    }
    let book = btrel::analyze(
        &t,
        &btrel::Options {
            method: Method::Book,
            ..Default::default()
        },
    )
    .unwrap();
    assert!((book.nodes[0].ps - 0.74).abs() < 1e-14);
}

#[test]
fn if_then_else_without_else_fails_when_the_condition_fails() {
    let t = tree(
        "tree:
  if_then_else:
    children:
      - condition: {ps: 0.25}
      - action: {ps: 0.5, mu: 2.0, nu: 1.0}
",
    );
    let f = root_figures(&t);
    assert!((f.ps - 0.125).abs() < 1e-15);
    // Failure: at once (0.75) or after T's Exp(1) failure (0.125)
    assert!((f.mttf.unwrap() - 0.125 / 0.875).abs() < 1e-14);
    let (s, fl) = root_curve_at(&t, 1.0);
    assert!((s - 0.125 * (1.0 - (-2.0f64).exp())).abs() < 1e-12);
    assert!((fl - (0.75 + 0.125 * (1.0 - (-1.0f64).exp()))).abs() < 1e-12);
}

/// SequenceWithMemory(A, B) under RetryUntilSuccessful(2): a failed child
/// is retried where it failed, one failure allowed in all. States: (try 1,
/// A), (try 1, B), (try 2, A), (try 2, B).
const MEMORY: &str = "tree:
  flow:
    children:
      - action: {ps: 0.5, tau_s: 1.0, tau_f: 2.0}
      - action: {ps: 0.25, tau_s: 10.0, tau_f: 20.0}
    states:
      - {run: 0, success: 1, failure: 2}
      - {run: 1, success: success, failure: 3}
      - {run: 0, success: 3, failure: failure}
      - {run: 1, success: success, failure: failure}
";

#[test]
fn shared_continuation_atoms_by_hand() {
    let t = tree(MEMORY);
    let f = root_figures(&t);
    // paths: AS BS @11 .125; AS BF BS @31 .09375; AS BF BF @41 .28125;
    // AF AS BS @13 .0625; AF AS BF @23 .1875; AF AF @4 .25
    let ps = 0.125 + 0.09375 + 0.0625;
    assert!((f.ps - ps).abs() < 1e-15);
    assert!((f.ps - 0.5 * 0.25 * (1.0 + 0.5 + 0.75)).abs() < 1e-15);
    let mtts = (0.125 * 11.0 + 0.09375 * 31.0 + 0.0625 * 13.0) / ps;
    let mttf = (0.28125 * 41.0 + 0.1875 * 23.0 + 0.25 * 4.0) / (1.0 - ps);
    assert!((f.mtts.unwrap() - mtts).abs() < 1e-12);
    assert!((f.mttf.unwrap() - mttf).abs() < 1e-12);
    for (x, s, fl) in [
        (3.9, 0.0, 0.0),
        (4.0, 0.0, 0.25),
        (12.0, 0.125, 0.25),
        (25.0, 0.1875, 0.4375),
        (50.0, ps, 1.0 - ps),
    ] {
        let (gs, gf) = root_curve_at(&t, x);
        assert!(
            (gs - s).abs() < 1e-14 && (gf - fl).abs() < 1e-14,
            "t={x}: {gs} {gf}"
        );
    }
    let sim = simulate_root(&t, 100_000, &[12.0, 25.0]);
    assert_within_z("ps", &sim.nodes[0].ps, ps);
    assert_within_z("MTTF", sim.nodes[0].mttf.as_ref().unwrap(), mttf);
    assert_within_z("F(25)", &sim.curve[1].failure, 0.4375);
}

#[test]
fn mixed_timing_flow_by_shifted_mixtures() {
    // C fixed (1 s on Success, 2 s on Failure), T and E exponential
    let t = tree(
        "tree:
  if_then_else:
    children:
      - action: {ps: 0.3, tau_s: 1.0, tau_f: 2.0}
      - action: {ps: 0.6, mu: 3.0, nu: 4.0}
      - action: {ps: 0.8, mu: 5.0, nu: 6.0}
",
    );
    for x in [0.5, 1.5, 2.5, 6.0] {
        let (s, f) = root_curve_at(&t, x);
        let after = |d: f64, r: f64| {
            if x > d {
                1.0 - (-r * (x - d)).exp()
            } else {
                0.0
            }
        };
        let es = 0.18 * after(1.0, 3.0) + 0.56 * after(2.0, 5.0);
        let ef = 0.12 * after(1.0, 4.0) + 0.14 * after(2.0, 6.0);
        assert!(
            (s - es).abs() < 1e-9 && (f - ef).abs() < 1e-9,
            "t={x}: {s} {f}"
        );
    }
}

#[test]
fn a_flow_of_one_path_is_a_sequence() {
    let body = "- action: {ps: 0.7, mu: 1.0, nu: 3.0}
      - condition: {ps: 0.9}
      - action: {ps: 0.4, mu: 2.0, nu: 0.5}";
    let flow = tree(&format!(
        "tree:
  flow:
    children:
      {body}
    states:
      - {{run: 0, success: 1, failure: failure}}
      - {{run: 1, success: 2, failure: failure}}
      - {{run: 2, success: success, failure: failure}}
"
    ));
    let seq = tree(&format!(
        "tree:\n  sequence:\n    children:\n      {body}\n"
    ));
    let (a, b) = (root_figures(&flow), root_figures(&seq));
    assert!((a.ps - 0.7 * 0.9 * 0.4).abs() < 1e-15);
    assert!((a.ps - b.ps).abs() < 1e-15);
    assert!((a.mtts.unwrap() - b.mtts.unwrap()).abs() < 1e-13);
    assert!((a.mttf.unwrap() - b.mttf.unwrap()).abs() < 1e-13);
    for x in [0.5, 2.0] {
        let (p, q) = (root_curve_at(&flow, x), root_curve_at(&seq, x));
        assert!((p.0 - q.0).abs() < 1e-12 && (p.1 - q.1).abs() < 1e-12);
    }
}

#[test]
fn bad_flows_are_refused_with_their_location() {
    for (yaml, needle) in [
        (
            "tree:\n  if_then_else:\n    children:\n      - condition: {ps: 0.5}\n",
            "if_then_else has 1 children",
        ),
        (
            "tree:\n  flow:\n    children:\n      - condition: {ps: 0.5}\n    states:\n      - {run: 0, success: 0, failure: failure}\n",
            "goes back to state 0",
        ),
        (
            "tree:\n  flow:\n    children:\n      - condition: {ps: 0.5}\n    states:\n      - {run: 1, success: success, failure: failure}\n",
            "child 1 does not exist",
        ),
        (
            "tree:\n  flow:\n    children:\n      - condition: {ps: 0.5}\n      - condition: {ps: 0.5}\n    states:\n      - {run: 0, success: success, failure: failure}\n",
            "child 1 is run by no state",
        ),
        (
            "tree:\n  flow:\n    children:\n      - condition: {ps: 0.5}\n    states:\n      - {run: 0, success: win, failure: failure}\n",
            "`win` is not a state",
        ),
    ] {
        let e = btrel::parse_str(yaml, "f.yaml").unwrap_err().to_string();
        assert!(e.contains(needle), "{e}");
        assert!(e.contains("f.yaml:"), "{e}");
    }
}

/// Reads a BT.CPP tree; `params` may hold entries for leaves the body does
/// not use (they are dropped: btrel refuses unused keys).
fn xml(body: &str, params: &str) -> Result<btrel::Tree, btrel::tree::TreeError> {
    let params: String = params
        .lines()
        .filter(|l| {
            let key = l.split(':').next().unwrap_or("");
            body.contains(&format!("<{key}/>"))
        })
        .map(|l| format!("{l}\n"))
        .collect();
    let params = params.as_str();
    let text =
        format!(r#"<root BTCPP_format="4"><BehaviorTree ID="Main">{body}</BehaviorTree></root>"#);
    btrel::tree::xml::parse_xml_str(&text, "t.xml", params, "t.params.yaml")
}

#[test]
fn btcpp_if_then_else_and_while_do_else() {
    let params = "C: {ps: 0.25}\nG: {ps: 0.5, mu: 1, nu: 1}\nT: {ps: 0.6, mu: 1, nu: 1}\nE: {ps: 0.8, mu: 1, nu: 1}\n";
    // a general condition subtree: Sequence(C, G) succeeds w.p. 0.125
    let t = xml(
        "<IfThenElse><Sequence><C/><G/></Sequence><T/><E/></IfThenElse>",
        params,
    )
    .unwrap();
    assert!((root_figures(&t).ps - (0.125 * 0.6 + 0.875 * 0.8)).abs() < 1e-15);
    let t = xml("<IfThenElse><C/><T/></IfThenElse>", params).unwrap();
    assert!((root_figures(&t).ps - 0.25 * 0.6).abs() < 1e-15);
    let t = xml("<WhileDoElse><C/><T/><E/></WhileDoElse>", params).unwrap();
    assert!((root_figures(&t).ps - (0.25 * 0.6 + 0.75 * 0.8)).abs() < 1e-15);
    // an action in WhileDoElse's condition child would be ticked again
    let e = xml(
        "<WhileDoElse><Sequence><C/><G/></Sequence><T/><E/></WhileDoElse>",
        params,
    )
    .unwrap_err();
    assert!(btrel::tree::xml::is_unsupported(&e), "{e}");
    assert!(
        e.to_string().contains("condition child holds an action"),
        "{e}"
    );
    // BT.CPP throws on other child counts: invalid input, not a refusal
    let e = xml("<IfThenElse><C/></IfThenElse>", params).unwrap_err();
    assert!(!btrel::tree::xml::is_unsupported(&e));
    assert!(e.to_string().contains("<IfThenElse> has 1 children"), "{e}");
}

#[test]
fn btcpp_retry_over_sequence_with_memory_resumes_at_the_failed_child() {
    let params = "A: {ps: 0.5, tau_s: 1, tau_f: 2}\nB: {ps: 0.25, tau_s: 10, tau_f: 20}\n";
    let t = xml(
        r#"<RetryUntilSuccessful num_attempts="2"><SequenceWithMemory><A/><B/></SequenceWithMemory></RetryUntilSuccessful>"#,
        params,
    )
    .unwrap();
    // the hand derivation of `shared_continuation_atoms_by_hand`
    let f = root_figures(&t);
    let ps = 0.125 + 0.09375 + 0.0625;
    assert!((f.ps - ps).abs() < 1e-15);
    let mttf = (0.28125 * 41.0 + 0.1875 * 23.0 + 0.25 * 4.0) / (1.0 - ps);
    assert!((f.mttf.unwrap() - mttf).abs() < 1e-12);
    // three attempts over three children: Success iff the failures before
    // the third success number at most 2: P = p1 p2 p3 · Σ_{a+b+c ≤ 2} q1^a q2^b q3^c
    let params = "A: {ps: 0.5}\nB: {ps: 0.6}\nC: {ps: 0.7}\n";
    let t = xml(
        r#"<RetryUntilSuccessful num_attempts="3"><SequenceWithMemory><A/><B/><C/></SequenceWithMemory></RetryUntilSuccessful>"#,
        params,
    )
    .unwrap();
    let q: [f64; 3] = [0.5, 0.4, 0.3];
    let mut sum = 0.0;
    for a in 0..3 {
        for b in 0..3 {
            for c in 0..3 {
                if a + b + c <= 2 {
                    sum += q[0].powi(a) * q[1].powi(b) * q[2].powi(c);
                }
            }
        }
    }
    assert!((root_figures(&t).ps - 0.5 * 0.6 * 0.7 * sum).abs() < 1e-15);
    // below another retry the kept index carries over to the outer retry's
    // next attempt: Retry 2 of Retry 2 allows 3 failures in all before the
    // third success, P = p1 p2 p3 · Σ_{a+b+c ≤ 3} q1^a q2^b q3^c
    let t = xml(
        r#"<RetryUntilSuccessful num_attempts="2"><RetryUntilSuccessful num_attempts="2"><SequenceWithMemory><A/><B/><C/></SequenceWithMemory></RetryUntilSuccessful></RetryUntilSuccessful>"#,
        params,
    )
    .unwrap();
    let mut sum = 0.0;
    for a in 0..4 {
        for b in 0..4 {
            for c in 0..4 {
                if a + b + c <= 3 {
                    sum += q[0].powi(a) * q[1].powi(b) * q[2].powi(c);
                }
            }
        }
    }
    assert!((root_figures(&t).ps - 0.5 * 0.6 * 0.7 * sum).abs() < 1e-15);
}

#[test]
fn exports_draw_or_refuse_a_flow() {
    let t = tree(ITE);
    let a = btrel::analyze(&t, &Default::default()).unwrap();
    let dot = btrel::export::dot_tree(&t, Some(&a));
    assert!(dot.contains("flow, 3 states"), "{dot}");
    let figs: Vec<_> = t.nodes()[0]
        .kind
        .children()
        .iter()
        .map(|&c| a.nodes[c])
        .collect();
    let e = btrel::export::dot_mrg(&t, 0, &figs).unwrap_err();
    assert!(e.contains("is a flow"), "{e}");
    // the glued phase chain: one copy of each 2-phase action per state
    let prism = btrel::export::prism_ctmc(&t, 0, 1000).unwrap();
    assert!(prism.contains("ctmc"), "{prism}");
    let chain = btrel::compile::phase::phase_chain(&t, 0, 1000).unwrap();
    assert_eq!(chain.len(), 6);
}
