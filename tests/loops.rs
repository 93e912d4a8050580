//! Loops without a bound (BehaviorTree.CPP `KeepRunningUntilFailure`,
//! `Repeat num_cycles="-1"`, `RetryUntilSuccessful num_attempts="-1"`):
//! figures in closed form, the loop's own curve from its cyclic chain, both
//! checked against hand derivations and simulation (loops inside Parallels:
//! tests/race.rs).

mod common;
use common::*;

#[test]
fn until_failure_over_an_action_matches_closed_form() {
    // child: ps 0.7 after Exp(2), else Failure after Exp(1). The loop fails
    // after K successes, K ~ Geometric (P(K = k) = 0.7^k 0.3): a geometric
    // sum of Exp(2) is 0 w.p. 0.3, else Exp(2 · 0.3) = Exp(0.6); so
    // T = Z + Y, Y ~ Exp(1), and
    //   F(t) = 0.3 (1 − e^{-t}) + 0.7 (1 − (e^{-0.6t} − 0.6 e^{-t}) / 0.4),
    //   MTTF = 0.7/0.6 + 1 = (0.7/0.3)·0.5 + 1.
    let t = tree("tree: {until_failure: {child: {action: {ps: 0.7, mu: 2.0, nu: 1.0}}}}");
    let f = root_figures(&t);
    assert_eq!((f.ps, f.pf), (0.0, 1.0));
    assert!((f.mttf.unwrap() - (0.7 / 0.6 + 1.0)).abs() < 1e-12);
    let times = [0.1, 0.5, 2.0, 5.0, 30.0];
    let pts = btrel::curve::curve(&t, 0, &times, &Default::default()).unwrap();
    for p in &pts {
        let x = p.t;
        let exact =
            0.3 * (1.0 - (-x).exp()) + 0.7 * (1.0 - ((-0.6 * x).exp() - 0.6 * (-x).exp()) / 0.4);
        assert!((p.failure - exact).abs() < 1e-12, "{p:?} vs {exact}");
        assert_eq!(p.success, 0.0);
    }
    let sim = simulate_root(&t, 200_000, &times);
    assert_within_z("MTTF", sim.nodes[0].mttf.as_ref().unwrap(), f.mttf.unwrap());
    for (p, e) in pts.iter().zip(&sim.curve) {
        assert_within_z("F(t)", &e.failure, p.failure);
    }
}

#[test]
fn until_success_with_an_instant_outcome_in_a_sequence() {
    // child: Sequence(condition 0.4, action Exp(1) always succeeding): an
    // attempt fails at once w.p. 0.6 (zero time), else succeeds after Exp(1).
    // The loop succeeds after Exp(1) — instant failures cost no time:
    // MTTS = (0.6/0.4)·0 + 1 = 1 and S(t) = 1 − e^{-t}.
    let t = tree(
        "tree: {sequence: {children: [{action: {ps: 0.8, mu: 4.0, nu: 2.0}}, \
         {until_success: {name: loop, child: {sequence: {children: [\
         {condition: {ps: 0.4}}, {action: {ps: 1.0, mu: 1.0}}]}}}}]}}",
    );
    let a = btrel::analyze(&t, &Default::default()).unwrap();
    let id = t.find("loop").unwrap();
    let l = a.nodes[id];
    assert_eq!((l.ps, l.pf), (1.0, 0.0));
    assert!((l.mtts.unwrap() - 1.0).abs() < 1e-12);
    let pts = btrel::curve::curve(&t, id, &[0.5, 2.0], &Default::default()).unwrap();
    for p in pts {
        assert!((p.success - (1.0 - (-p.t).exp())).abs() < 1e-12, "{p:?}");
    }
    // the root: 0.8 then the loop; MTTS = 0.25 + 1
    let r = a.nodes[0];
    assert!((r.ps - 0.8).abs() < 1e-12 && (r.mtts.unwrap() - 1.25).abs() < 1e-12);
    let sim = simulate_root(&t, 200_000, &[]);
    assert_within_z("ps", &sim.nodes[0].ps, 0.8);
    assert_within_z("MTTS", sim.nodes[0].mtts.as_ref().unwrap(), 1.25);
}

/// A loop whose child can never end it never returns (BT.CPP returns
/// RUNNING for ever): P(S) = P(F) = 0, P(never) = 1 in `report`, π_R(t) = 1
/// in `curve`, every simulated run counted as never returning (no hang),
/// and a warning naming the loop in the CLI.
#[test]
fn a_loop_that_cannot_end_never_returns_everywhere() {
    let yaml = "tree: {until_failure: {name: spin, child: {action: {ps: 1.0, mu: 1.0}}}}";
    let t = tree(yaml);
    let f = root_figures(&t);
    assert_eq!((f.ps, f.pf, f.never()), (0.0, 0.0, 1.0));
    let p = btrel::curve::curve(&t, 0, &[0.0, 10.0], &Default::default()).unwrap();
    assert!(p.iter().all(|p| p.running == 1.0), "{p:?}");
    let sim = simulate_root(&t, 1000, &[10.0]);
    assert_eq!(sim.nodes[0].never.mean, 1.0);
    assert_eq!(sim.curve[0].running.mean, 1.0);
    let dir = std::env::temp_dir().join(format!("btrel-loops-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("spin.yaml");
    std::fs::write(&file, yaml).unwrap();
    let (code, out, err) = run_btrel(&["report", file.to_str().unwrap()]);
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("never"), "{out}");
    assert!(
        err.contains("warning: node 'spin' can run forever: it repeats"),
        "{err}"
    );
}

#[test]
fn bt_cpp_forms_of_the_loops() {
    let xml = r#"<root BTCPP_format="4"><BehaviorTree ID="M"><Sequence>
        <KeepRunningUntilFailure name="k"><Step/></KeepRunningUntilFailure>
        <Repeat name="r" num_cycles="-1"><Step/></Repeat>
        <RetryUntilSuccessful name="u" num_attempts="-1"><Step/></RetryUntilSuccessful>
      </Sequence></BehaviorTree></root>"#;
    let params = "Step: {ps: 0.5, mu: 1.0, nu: 2.0}\n";
    let t = btrel::tree::xml::parse_xml_str(xml, "t.xml", params, "t.params.yaml").unwrap();
    use btrel::tree::{Decorator, NodeKind};
    let kind = |n: &str| match &t.nodes()[t.find(n).unwrap()].kind {
        NodeKind::Decorator { decorator, .. } => *decorator,
        k => panic!("{k:?}"),
    };
    assert_eq!(kind("k"), Decorator::UntilFailure);
    assert_eq!(kind("r"), Decorator::UntilFailure);
    assert_eq!(kind("u"), Decorator::UntilSuccess);
    // the Sequence fails at its first child, after E = (0.5/0.5)·1 + 0.5
    let f = root_figures(&t);
    assert_eq!(f.pf, 1.0);
    assert!((f.mttf.unwrap() - 1.5).abs() < 1e-12);
}
