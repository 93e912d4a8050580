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
    let f = root_figures(&t);
    let sim = simulate_root(&t, 400_000, &[]);
    let r = &sim.nodes[0];
    assert_within_z("ps", &r.ps, f.ps);
    assert_within_z(
        "MTTS",
        r.mtts.as_ref().expect("successes"),
        f.mtts.expect("MTTS"),
    );
    assert_within_z(
        "MTTF",
        r.mttf.as_ref().expect("failures"),
        f.mttf.expect("MTTF"),
    );
    // the Parallel itself (path 0.1): report vs the limit of its curve
    let id = t.find("0.1").expect("the Parallel");
    let a = btrel::analyze(&t, &Default::default()).expect("analysed");
    let p = btrel::curve::curve(&t, id, &[400.0], &Default::default()).expect("curve")[0];
    assert!((p.success - a.nodes[id].ps).abs() < 1e-9);
    assert!((p.failure - a.nodes[id].pf).abs() < 1e-9);
}
