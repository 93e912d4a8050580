//! `btrel sensitivity`: derivatives and elasticities of the root's figure,
//! checked against closed forms (Sequence ps = Π ps_i, eqs. 9.74–9.75 for
//! the means, P(success by T) of one action) and the sentences' values by
//! hand.

mod common;

use btrel::sensitivity::{
    sensitivity, sensitivity_by_differences, Objective, Param, Scheme, Sensitivity,
};
use btrel::Options;
use serde_json::Value;

const SEQ: &str = "tree:
  sequence:
    name: root
    children:
      - action: {name: a, ps: 0.9, mu: 1.0, nu: 3.0}
      - action: {name: b, ps: 0.8, mu: 2.0, nu: 5.0}
      - action: {name: c, ps: 0.7, mu: 4.0, nu: 6.0}
";

const FB: &str = "tree:
  fallback:
    name: root
    children:
      - action: {name: a, ps: 0.6, mu: 1.0, nu: 2.0}
      - action: {name: b, ps: 0.7, mu: 0.5, nu: 1.0}
";

fn row(
    s: &Sensitivity,
    tree: &btrel::Tree,
    leaf: &str,
    p: Param,
) -> (f64, Option<f64>, f64, Scheme) {
    let r = s
        .rows
        .iter()
        .find(|r| tree.nodes()[r.leaf].name == leaf && r.param == p)
        .unwrap_or_else(|| panic!("no row {leaf} {p:?}"));
    (r.derivative, r.elasticity, r.error, r.scheme)
}

fn close(what: &str, got: f64, exact: f64) {
    assert!(
        (got - exact).abs() <= 1e-7 * exact.abs().max(1.0),
        "{what}: {got} vs exact {exact}"
    );
}

#[test]
fn sequence_closed_forms() {
    let tree = common::tree(SEQ);
    let o = Options::default();
    let s = sensitivity(&tree, Objective::Ps, &o).unwrap();
    close("ps", s.value, 0.9 * 0.8 * 0.7);
    // d/dps_1 of ps_1 ps_2 ps_3 = ps_2 ps_3; elasticity 1
    let (d, e, err, scheme) = row(&s, &tree, "a", Param::Ps);
    close("d ps / d ps_a", d, 0.8 * 0.7);
    close("elasticity", e.unwrap(), 1.0);
    assert!(err == 0.0 && scheme == Scheme::Exact);
    close("d ps / d ps_c", row(&s, &tree, "c", Param::Ps).0, 0.9 * 0.8);
    // rates do not move ps
    close("d ps / d mu_a", row(&s, &tree, "a", Param::Mu).0, 0.0);
    // the ps rows (elasticity 1) come first
    assert!(s.rows[..3].iter().all(|r| r.param == Param::Ps));
    // MTTS of a Sequence = sum 1/mu_i (eq. 9.74): d/dmu_b = -1/mu_b^2
    let s = sensitivity(&tree, Objective::Mtts, &o).unwrap();
    let mtts = 1.0 + 0.5 + 0.25;
    close("MTTS", s.value, mtts);
    let (d, e, _, _) = row(&s, &tree, "b", Param::Mu);
    close("d MTTS / d mu_b", d, -0.25);
    close("elasticity", e.unwrap(), -0.5 / mtts);
    close("d MTTS / d ps_a", row(&s, &tree, "a", Param::Ps).0, 0.0);
    // ranked by |elasticity|: mu of a (1/mu_a is the largest share) first
    assert_eq!(tree.nodes()[s.rows[0].leaf].name, "a");
    assert_eq!(s.rows[0].param, Param::Mu);
}

#[test]
fn fallback_closed_forms() {
    let tree = common::tree(FB);
    let o = Options::default();
    let (pa, mua, nua) = (0.6, 1.0, 2.0);
    let (pb, mub, nub) = (0.7, 0.5, 1.0);
    // ps = 1 - (1 - pa)(1 - pb): d/dpa = 1 - pb
    let s = sensitivity(&tree, Objective::Ps, &o).unwrap();
    close("d ps / d pa", row(&s, &tree, "a", Param::Ps).0, 1.0 - pb);
    // MTTF = 1/nu_a + 1/nu_b (eq. 9.75): d/dnu_a = -1/nu_a^2
    let s = sensitivity(&tree, Objective::Mttf, &o).unwrap();
    close("MTTF", s.value, 1.0 / nua + 1.0 / nub);
    close(
        "d MTTF / d nu_a",
        row(&s, &tree, "a", Param::Nu).0,
        -1.0 / (nua * nua),
    );
    // E[T] = pa/mu_a + (1-pa)(1/nu_a + pb/mu_b + (1-pb)/nu_b)
    let s = sensitivity(&tree, Objective::MeanTime, &o).unwrap();
    close(
        "E[T]",
        s.value,
        pa / mua + (1.0 - pa) * (1.0 / nua + pb / mub + (1.0 - pb) / nub),
    );
    close(
        "d E[T] / d pa",
        row(&s, &tree, "a", Param::Ps).0,
        1.0 / mua - 1.0 / nua - pb / mub - (1.0 - pb) / nub,
    );
    close(
        "d E[T] / d mu_b",
        row(&s, &tree, "b", Param::Mu).0,
        -(1.0 - pa) * pb / (mub * mub),
    );
}

#[test]
fn success_by_a_deadline() {
    // one action: P(S by T) = ps (1 - e^{-mu T})
    let tree = common::tree("tree:\n  action: {name: a, ps: 0.5, mu: 0.02, nu: 0.1}\n");
    let t = 60.0;
    let s = sensitivity(&tree, Objective::SuccessBy(t), &Options::default()).unwrap();
    let e = (-0.02 * t).exp();
    close("P", s.value, 0.5 * (1.0 - e));
    close("d/d ps", row(&s, &tree, "a", Param::Ps).0, 1.0 - e);
    close("d/d mu", row(&s, &tree, "a", Param::Mu).0, 0.5 * t * e);
    close("d/d nu", row(&s, &tree, "a", Param::Nu).0, 0.0);
    assert!(s.rows.iter().all(|r| r.scheme == Scheme::Exact), "{s:?}");
}

#[test]
fn boundary_parameters_are_one_sided() {
    // search and grasp: ps = (c1 + (1-c1) S)(c2 + (1-c2) G) with c1 = c2 = 0,
    // S = 1 - 0.7*0.2*0.8 (three searches), G = 1 - 0.9*0.5 (two grasps):
    // d ps / d c1 = (1 - S) G
    let tree = btrel::parse_file(std::path::Path::new("trees/search-and-grasp.yaml")).unwrap();
    let s = sensitivity(&tree, Objective::Ps, &Options::default()).unwrap();
    let (big_s, g) = (1.0 - 0.7 * 0.2 * 0.8, 1.0 - 0.9 * 0.5);
    let (d, _, _, scheme) = row(&s, &tree, "object position retrieved", Param::Ps);
    close("d ps / d c1", d, (1.0 - big_s) * g);
    // exact at the boundary too (ps is a polynomial in c1)...
    assert_eq!(scheme, Scheme::Exact);
    // ...and the differences there are one-sided
    let r = sensitivity_by_differences(&tree, Objective::Ps, &Options::default()).unwrap();
    let (d, _, _, scheme) = row(&r, &tree, "object position retrieved", Param::Ps);
    close("one-sided d ps / d c1", d, (1.0 - big_s) * g);
    assert_eq!(scheme, Scheme::Forward);
    close(
        "d ps / d c2",
        row(&s, &tree, "object grasped", Param::Ps).0,
        (1.0 - g) * big_s,
    );
}

fn run(args: &[&str]) -> String {
    let (code, out, err) = common::run_btrel(args);
    assert_eq!(code, 0, "{err}");
    out
}

#[test]
fn cli_table_sentences_and_json() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("seq.yaml");
    std::fs::write(&path, SEQ).unwrap();
    let p = path.to_str().unwrap();
    let table = run(&["sensitivity", p]);
    // 0.9 * 0.8 * 0.7 = 0.504; with ps_a = 1: 0.8 * 0.7 = 0.56
    assert!(
        table.contains(
            "* raising a's ps from 0.900 to 1.00 raises the root's P(Success) from 0.504 to 0.560"
        ),
        "{table}"
    );
    let v: Value = serde_json::from_str(&run(&["sensitivity", p, "--format", "json"])).unwrap();
    let keys: Vec<&str> = v.as_object().unwrap().keys().map(String::as_str).collect();
    assert_eq!(keys, ["objective", "deadline", "rows"]);
    assert_eq!(v["objective"], "ps");
    assert_eq!(v["deadline"], Value::Null);
    let row_keys: Vec<&str> = v["rows"][0]
        .as_object()
        .unwrap()
        .keys()
        .map(String::as_str)
        .collect();
    assert_eq!(
        row_keys,
        [
            "leaf",
            "path",
            "parameter",
            "value",
            "derivative",
            "elasticity",
            "method"
        ]
    );
    assert!(v["rows"]
        .as_array()
        .unwrap()
        .iter()
        .all(|r| r["method"] == "exact"));
    assert_eq!(v["rows"].as_array().unwrap().len(), 9);
    let v: Value = serde_json::from_str(&run(&[
        "sensitivity",
        p,
        "--deadline",
        "2",
        "--format",
        "json",
    ]))
    .unwrap();
    assert_eq!(v["objective"], "success-by");
    assert_eq!(v["deadline"], 2.0);
    // a point of the curve of a phase chain: exact (the doubled chain)
    assert!(v["rows"]
        .as_array()
        .unwrap()
        .iter()
        .all(|r| r["method"] == "exact"));
    // a deterministic time: the curve's atoms are differenced
    let fixed = dir.path().join("fixed.yaml");
    std::fs::write(
        &fixed,
        "tree:\n  sequence:\n    children:\n      - action: {name: a, ps: 0.9, tau_s: 1.0, tau_f: 0.5}\n      - action: {name: b, ps: 0.8, mu: 2.0, nu: 5.0}\n",
    )
    .unwrap();
    let v: Value = serde_json::from_str(&run(&[
        "sensitivity",
        fixed.to_str().unwrap(),
        "--deadline",
        "2",
        "--format",
        "json",
    ]))
    .unwrap();
    assert!(v["rows"]
        .as_array()
        .unwrap()
        .iter()
        .all(|r| r["method"] == "richardson"));
    let csv = run(&["sensitivity", p, "--of", "mtts", "--format", "csv"]);
    assert!(csv.starts_with("leaf,path,parameter,value,derivative,elasticity,error,method\n"));
    for args in [
        vec!["sensitivity", p, "--of", "success-by"],
        vec!["sensitivity", p, "--of", "mtts", "--deadline", "3"],
    ] {
        let (code, out, err) = common::run_btrel(&args);
        assert_eq!(code, 2, "{args:?}");
        assert!(out.is_empty() && err.contains("--deadline"), "{err}");
    }
}

#[test]
fn loops_retry_flows_and_counted_parallels_by_hand() {
    let o = Options::default();
    // until_failure of (ps, mu, nu): MTTF = (ps/pf)/mu + 1/nu (a geometric
    // number of successful runs, then the failing one):
    // d/dps = 1/(mu pf²), d/dmu = -(ps/pf)/mu², d/dnu = -1/nu²
    let (p, mu, nu) = (0.6, 2.0, 0.5);
    let tree = common::tree(&format!(
        "tree:\n  until_failure:\n    name: root\n    child: {{action: {{name: a, ps: {p}, mu: {mu}, nu: {nu}}}}}\n"
    ));
    let s = sensitivity(&tree, Objective::Mttf, &o).unwrap();
    let q = 1.0 - p;
    close("MTTF", s.value, p / q / mu + 1.0 / nu);
    let (d, _, _, scheme) = row(&s, &tree, "a", Param::Ps);
    close("d MTTF / d ps", d, 1.0 / (mu * q * q));
    assert_eq!(scheme, Scheme::Exact);
    close(
        "d MTTF / d mu",
        row(&s, &tree, "a", Param::Mu).0,
        -p / q / (mu * mu),
    );
    close(
        "d MTTF / d nu",
        row(&s, &tree, "a", Param::Nu).0,
        -1.0 / (nu * nu),
    );

    // retry 3 of (ps, mu, nu): ps = 1 - pf³, d/dps = 3 pf²;
    // E[T] = (1/mu) ps_root... by hand: E[T] = Σ_{k<3} pf^k (p/mu + pf/nu)
    let tree = common::tree(&format!(
        "tree:\n  retry:\n    attempts: 3\n    child: {{action: {{name: a, ps: {p}, mu: {mu}, nu: {nu}}}}}\n"
    ));
    let s = sensitivity(&tree, Objective::Ps, &o).unwrap();
    close(
        "d ps / d ps_a",
        row(&s, &tree, "a", Param::Ps).0,
        3.0 * q * q,
    );
    let s = sensitivity(&tree, Objective::MeanTime, &o).unwrap();
    let run = p / mu + q / nu;
    // d/dps of (1 + q + q²)(p/mu + q/nu) with q = 1 - p
    let d_by_hand = -(1.0 + 2.0 * q) * run + (1.0 + q + q * q) * (1.0 / mu - 1.0 / nu);
    close("E[T]", s.value, (1.0 + q + q * q) * run);
    close(
        "d E[T] / d ps_a",
        row(&s, &tree, "a", Param::Ps).0,
        d_by_hand,
    );

    // if_then_else (c, t, e) with conditions and actions:
    // ps = c pt + (1-c) pe, MTTS = ... ; d ps / d c = pt - pe
    let tree = common::tree(
        "tree:\n  if_then_else:\n    children:\n      - condition: {name: c, ps: 0.3}\n      - action: {name: t, ps: 0.9, mu: 1.0, nu: 1.0}\n      - action: {name: e, ps: 0.4, mu: 0.25, nu: 1.0}\n",
    );
    let s = sensitivity(&tree, Objective::Ps, &o).unwrap();
    let (d, _, _, scheme) = row(&s, &tree, "c", Param::Ps);
    close("d ps / d c", d, 0.9 - 0.4);
    assert_eq!(scheme, Scheme::Exact);
    // E[T·1S] = c·pt·1 + (1-c)·pe·4, MTTS = that / ps: d MTTS / d mu_e by hand
    let s = sensitivity(&tree, Objective::Mtts, &o).unwrap();
    let ps = 0.3 * 0.9 + 0.7 * 0.4;
    close(
        "d MTTS / d mu_e",
        row(&s, &tree, "e", Param::Mu).0,
        0.7 * 0.4 * -16.0 / ps,
    );

    // a Parallel with the book's thresholds, M = 1 of 2: ps = 1 - pf1 pf2
    // exactly by counting
    let tree = common::tree(
        "tree:\n  parallel:\n    success_threshold: 1\n    children:\n      - action: {name: a, ps: 0.3, mu: 1.0, nu: 2.0}\n      - action: {name: b, ps: 0.6, mu: 0.5, nu: 1.0}\n",
    );
    let s = sensitivity(&tree, Objective::Ps, &o).unwrap();
    let (d, _, _, scheme) = row(&s, &tree, "a", Param::Ps);
    close("d ps / d ps_a", d, 0.4);
    assert_eq!(scheme, Scheme::Exact);
}

/// A Parallel M = 1 of two exponential actions (its product phase chain):
/// the mean times and P(success by t) and their derivatives by hand.
///
/// Each action is a success type (prob. p_i, Exp(mu_i) then Success) or a
/// failure type (q_i = 1 − p_i, Exp(nu_i) then Failure). The node succeeds
/// at the first success; it fails only when both have failed. So
/// E[T·1S] = p1 p2/(mu1 + mu2) + p1 q2/mu1 + q1 p2/mu2, ps = 1 − q1 q2,
/// MTTF = E[max(Y1, Y2)] = 1/nu1 + 1/nu2 − 1/(nu1 + nu2), and it has
/// succeeded by t iff a child has: P = 1 − (1 − p1 F1)(1 − p2 F2) with
/// F_i = 1 − e^{−mu_i t}.
#[test]
fn product_chain_parallel_by_hand() {
    let o = Options::default();
    let (p1, m1, n1) = (0.3, 1.0, 2.0);
    let (p2, m2, n2) = (0.6, 0.5, 1.0);
    let (q1, q2) = (1.0 - p1, 1.0 - p2);
    let tree = common::tree(&format!(
        "tree:\n  parallel:\n    success_threshold: 1\n    children:\n      - action: {{name: a, ps: {p1}, mu: {m1}, nu: {n1}}}\n      - action: {{name: b, ps: {p2}, mu: {m2}, nu: {n2}}}\n"
    ));
    let ts = p1 * p2 / (m1 + m2) + p1 * q2 / m1 + q1 * p2 / m2;
    let ps = 1.0 - q1 * q2;
    let s = sensitivity(&tree, Objective::Mtts, &o).unwrap();
    close("MTTS", s.value, ts / ps);
    assert!(s.rows.iter().all(|r| r.scheme == Scheme::Exact), "{s:?}");
    // d MTTS / d mu1 = (−p1 p2/(mu1 + mu2)² − p1 q2/mu1²)/ps
    close(
        "d MTTS / d mu_a",
        row(&s, &tree, "a", Param::Mu).0,
        (-p1 * p2 / (m1 + m2).powi(2) - p1 * q2 / (m1 * m1)) / ps,
    );
    // d MTTS / d p1 = (dts·ps − ts·q2)/ps² with dts = p2/(mu1+mu2) + q2/mu1 − p2/mu2
    let dts = p2 / (m1 + m2) + q2 / m1 - p2 / m2;
    close(
        "d MTTS / d ps_a",
        row(&s, &tree, "a", Param::Ps).0,
        (dts * ps - ts * q2) / (ps * ps),
    );
    close("d MTTS / d nu_a", row(&s, &tree, "a", Param::Nu).0, 0.0);
    let s = sensitivity(&tree, Objective::Mttf, &o).unwrap();
    close("MTTF", s.value, 1.0 / n1 + 1.0 / n2 - 1.0 / (n1 + n2));
    close(
        "d MTTF / d nu_a",
        row(&s, &tree, "a", Param::Nu).0,
        -1.0 / (n1 * n1) + 1.0 / (n1 + n2).powi(2),
    );
    // E[T] = E[T·1S] + q1 q2 E[max]: d/dp1 = dts − q2 E[max]
    let s = sensitivity(&tree, Objective::MeanTime, &o).unwrap();
    let emax = 1.0 / n1 + 1.0 / n2 - 1.0 / (n1 + n2);
    close("E[T]", s.value, ts + q1 * q2 * emax);
    close(
        "d E[T] / d ps_a",
        row(&s, &tree, "a", Param::Ps).0,
        dts - q2 * emax,
    );
    assert!(s.rows.iter().all(|r| r.scheme == Scheme::Exact), "{s:?}");
    // P(success by t): d/dmu1 = p1 t e^{−mu1 t}(1 − p2 F2), d/dp1 = F1 (1 − p2 F2)
    let t = 1.7;
    let (f1, f2) = (1.0 - (-m1 * t).exp(), 1.0 - (-m2 * t).exp());
    let s = sensitivity(&tree, Objective::SuccessBy(t), &o).unwrap();
    close(
        "P(S by t)",
        s.value,
        1.0 - (1.0 - p1 * f1) * (1.0 - p2 * f2),
    );
    assert!(s.rows.iter().all(|r| r.scheme == Scheme::Exact), "{s:?}");
    close(
        "d P / d mu_a",
        row(&s, &tree, "a", Param::Mu).0,
        p1 * t * (-m1 * t).exp() * (1.0 - p2 * f2),
    );
    close(
        "d P / d ps_b",
        row(&s, &tree, "b", Param::Ps).0,
        f2 * (1.0 - p1 * f1),
    );
    close("d P / d nu_b", row(&s, &tree, "b", Param::Nu).0, 0.0);
}

/// A counted Parallel (M = 1 of 10 identical exponential actions: its
/// product bound 4¹⁰ is over the limit, so the engine counts): the mean
/// times' derivatives along child 1's parameters by hand, and exact.
///
/// With A the set of success-type children, the node succeeds at
/// min_{i∈A} X_i: E[T·1S] = Σ_{A≠∅} P(A)/μ(A) (μ(A) = Σ_{i∈A} μ_i), so
/// d/dμ₁ = −Σ_{A∋1} P(A)/μ(A)² = −Σ_{k≥1} C(N−1, k−1) p^k q^{N−k}/(kμ)², and
/// d/dp₁ = Σ_j C(N−1, j) p^j q^{N−1−j} [1/((j+1)μ) − 1{j≥1}/(jμ)]. It fails
/// when all have failed, at the maximum: MTTF = E[max Y_i] and
/// d/dν₁ = −∫ t e^{−νt}(1 − e^{−νt})^{N−1} dt = −Σ_j C(N−1, j)(−1)^j/((j+1)ν)².
#[test]
fn counted_parallel_by_hand() {
    let o = Options::default();
    let (n, p, mu, nu) = (10usize, 0.3, 1.5, 0.5);
    let q = 1.0 - p;
    let kids: String = (0..n)
        .map(|i| format!("      - action: {{name: a{i}, ps: {p}, mu: {mu}, nu: {nu}}}\n"))
        .collect();
    let tree = common::tree(&format!(
        "tree:\n  parallel:\n    success_threshold: 1\n    children:\n{kids}"
    ));
    let choose = |n: usize, k: usize| -> f64 {
        (0..k).fold(1.0, |c, i| c * (n - i) as f64 / (i + 1) as f64)
    };
    let pw = |x: f64, k: usize| x.powi(k as i32);
    let ts: f64 = (1..=n)
        .map(|k| choose(n, k) * pw(p, k) * pw(q, n - k) / (k as f64 * mu))
        .sum();
    let ps = 1.0 - pw(q, n);
    let d_mu: f64 = -(1..=n)
        .map(|k| choose(n - 1, k - 1) * pw(p, k) * pw(q, n - k) / (k as f64 * mu).powi(2))
        .sum::<f64>();
    let d_p: f64 = (0..n)
        .map(|j| {
            let w = choose(n - 1, j) * pw(p, j) * pw(q, n - 1 - j);
            let lose = if j >= 1 { 1.0 / (j as f64 * mu) } else { 0.0 };
            w * (1.0 / ((j + 1) as f64 * mu) - lose)
        })
        .sum();
    let s = sensitivity(&tree, Objective::Mtts, &o).unwrap();
    close("MTTS", s.value, ts / ps);
    assert!(s.rows.iter().all(|r| r.scheme == Scheme::Exact), "{s:?}");
    close(
        "d MTTS / d mu_1",
        row(&s, &tree, "a0", Param::Mu).0,
        d_mu / ps,
    );
    // dps/dp1 = q^{N−1}
    close(
        "d MTTS / d ps_1",
        row(&s, &tree, "a0", Param::Ps).0,
        (d_p * ps - ts * pw(q, n - 1)) / (ps * ps),
    );
    let s = sensitivity(&tree, Objective::Mttf, &o).unwrap();
    let d_nu: f64 = -(0..n)
        .map(|j| {
            choose(n - 1, j) * if j % 2 == 0 { 1.0 } else { -1.0 } / ((j + 1) as f64 * nu).powi(2)
        })
        .sum::<f64>();
    assert!(s.rows.iter().all(|r| r.scheme == Scheme::Exact), "{s:?}");
    close("d MTTF / d nu_1", row(&s, &tree, "a0", Param::Nu).0, d_nu);
}

/// Exact derivatives agree with the Richardson-extrapolated differences on
/// random trees (every node kind, every leaf timing; Parallels and curves
/// over the same shapes with exponential times only, where every row must
/// be exact).
#[test]
fn exact_matches_richardson_on_random_trees() {
    let o = Options::default();
    let (mut exact_rows, mut curve_rows, mut parallel_time_rows) = (0, 0, 0);
    for seed in 0..200 {
        let mixed = common::random_mixed_tree(seed, 3);
        // the same shape with exponential times only (a fixed time as a
        // rate): phase chains, whose Parallels and curves are differentiated
        // exactly (the differences of mixed-timing races are slow)
        let exponential = mixed.replace("tau_s:", "mu:").replace("tau_f:", "nu:");
        let tree_mixed = common::tree(&mixed);
        let tree_exponential = common::tree(&exponential);
        for objective in [
            Objective::Ps,
            Objective::Mtts,
            Objective::Mttf,
            Objective::MeanTime,
            Objective::SuccessBy(1.3),
        ] {
            let (yaml, tree) =
                if mixed.contains("parallel") || matches!(objective, Objective::SuccessBy(_)) {
                    (&exponential, &tree_exponential)
                } else {
                    (&mixed, &tree_mixed)
                };
            let Ok(s) = sensitivity(tree, objective, &o) else {
                continue;
            };
            // a perturbed tree's analysis may fail where the exact pass
            // does not (e.g. the stiff solver's error bound)
            let Ok(r) = sensitivity_by_differences(tree, objective, &o) else {
                continue;
            };
            for a in &s.rows {
                let b = r
                    .rows
                    .iter()
                    .find(|b| b.leaf == a.leaf && b.param == a.param)
                    .unwrap();
                if a.scheme != Scheme::Exact {
                    // every derivative of a tree of exponential leaves is exact
                    assert!(
                        !std::ptr::eq(tree, &tree_exponential),
                        "seed {seed} {objective:?} {} {:?} differenced",
                        tree.nodes()[a.leaf].path,
                        a.param
                    );
                    // the same differences
                    assert_eq!(a.derivative, b.derivative);
                    continue;
                }
                exact_rows += 1;
                match objective {
                    Objective::SuccessBy(_) => curve_rows += 1,
                    Objective::Ps => {}
                    _ if yaml.contains("parallel") => parallel_time_rows += 1,
                    _ => {}
                }
                let scale = a.derivative.abs().max(1.0);
                assert!(
                    (a.derivative - b.derivative).abs() <= 1e-7 * scale + 2.0 * b.error,
                    "seed {seed} {objective:?} {} {:?}: exact {} vs differences {} (error {})",
                    tree.nodes()[a.leaf].path,
                    a.param,
                    a.derivative,
                    b.derivative,
                    b.error
                );
            }
        }
    }
    assert!(exact_rows > 300, "{exact_rows}");
    assert!(curve_rows > 100, "{curve_rows}");
    assert!(parallel_time_rows > 50, "{parallel_time_rows}");
}

/// A counted Parallel inside a mission (its product bound 6⁶ = 46,656 is
/// over the limit): every mean-time derivative is exact (the count
/// quadrature in dual numbers) and agrees with the differences.
#[test]
fn counted_parallel_matches_differences() {
    let o = Options::default();
    let kids: String = (0..6)
        .map(|i| {
            format!(
                "            - sequence: {{children: [{{action: {{name: f{i}, ps: 0.9{i}, mu: 0.{}, nu: 0.2}}}}, {{action: {{name: s{i}, ps: 0.8, mu: 0.1, nu: 0.5}}}}]}}\n",
                i + 2
            )
        })
        .collect();
    let tree = common::tree(&format!(
        "tree:\n  sequence:\n    children:\n      - action: {{name: check, ps: 0.99, mu: 0.2, nu: 0.5}}\n      - parallel:\n          success_threshold: 4\n          children:\n{kids}"
    ));
    for objective in [Objective::Mtts, Objective::Mttf, Objective::MeanTime] {
        let s = sensitivity(&tree, objective, &o).unwrap();
        let r = sensitivity_by_differences(&tree, objective, &o).unwrap();
        assert_eq!(s.rows.len(), 3 + 6 * 2 * 3);
        for a in &s.rows {
            assert_eq!(a.scheme, Scheme::Exact, "{objective:?} {a:?}");
            let b = r
                .rows
                .iter()
                .find(|b| b.leaf == a.leaf && b.param == a.param)
                .unwrap();
            assert!(
                (a.derivative - b.derivative).abs()
                    <= 1e-7 * a.derivative.abs().max(1.0) + 2.0 * b.error,
                "{objective:?} {}: exact {} vs differences {} ({})",
                tree.nodes()[a.leaf].name,
                a.derivative,
                b.derivative,
                b.error
            );
        }
    }
}

/// The stage parameters of Erlang, shifted and hyperexponential times
/// (`fit --timing auto`'s families) have rows, against closed forms: a
/// Fallback by its means (exact, dual numbers), a Parallel waiting for
/// both children by `E[max(X, Y)]` and P(success by T) (differences
/// through the engine).
#[test]
fn stage_parameters_of_phase_type_times() {
    // Fallback(A, B): A Erlang-3(2) / 0.5 + Exp(4), B hyperexponential
    // 0.3·Exp(5) + 0.7·Exp(0.5) / Exp(1)
    let tree = common::tree(
        "tree:
  fallback:
    name: root
    children:
      - action: {name: A, ps: 0.7, success_time: {erlang: {k: 3, rate: 2.0}}, failure_time: {shift: 0.5, rate: 4.0}}
      - action: {name: B, ps: 0.6, success_time: {hyperexponential: [{p: 0.3, rate: 5.0}, {p: 0.7, rate: 0.5}]}, nu: 1.0}
",
    );
    // MTTS = (pA·ESa + (1−pA)·pB·(EFa + ESb)) / ps, ps = pA + (1−pA)·pB
    let (pa, pb) = (0.7, 0.6);
    let ps = pa + (1.0 - pa) * pb;
    let s = sensitivity(&tree, Objective::Mtts, &Options::default()).unwrap();
    let c = (1.0 - pa) * pb / ps;
    let want = [
        ("A", Param::StageRate(true), pa / ps * (-3.0 / 4.0)),
        ("A", Param::StageRate(false), c * (-1.0 / 16.0)),
        ("A", Param::TauF, c),
        ("B", Param::Branch(true), c * (1.0 / 5.0 - 1.0 / 0.5)),
        ("B", Param::Rate1(true), c * (-0.3 / 25.0)),
        ("B", Param::Rate2(true), c * (-0.7 / 0.25)),
    ];
    for (leaf, p, d) in want {
        let (got, _, _, scheme) = row(&s, &tree, leaf, p);
        close(&format!("{leaf} {}", p.name()), got, d);
        assert_eq!(scheme, Scheme::Exact, "{leaf} {p:?}");
    }
    // the same by differences through the engine
    let by_diff = sensitivity_by_differences(&tree, Objective::Mtts, &Options::default()).unwrap();
    for (leaf, p, d) in want {
        let (got, _, err, _) = row(&by_diff, &tree, leaf, p);
        assert!(
            (got - d).abs() <= 1e-6 * d.abs().max(1.0) + err,
            "{leaf} {p:?}: {got} vs {d}"
        );
    }

    // Parallel (both must succeed) of A Erlang-2(λ) and B Exp(μ), ps 1:
    // MTTS = E[max] = 2/λ + 1/μ − E[min], E[min] = 1/(λ+μ) + λ/(λ+μ)²
    let (l, m) = (1.5, 0.8);
    let tree = common::tree(&format!(
        "tree:
  parallel:
    name: root
    success_threshold: 2
    children:
      - action: {{name: A, ps: 1.0, success_time: {{erlang: {{k: 2, rate: {l}}}}}}}
      - action: {{name: B, ps: 1.0, mu: {m}}}
"
    ));
    let s = sensitivity(&tree, Objective::Mtts, &Options::default()).unwrap();
    let lm = l + m;
    let d = -2.0 / (l * l) + 1.0 / (lm * lm) - (m - l) / (lm * lm * lm);
    let (got, _, err, _) = row(&s, &tree, "A", Param::StageRate(true));
    assert!((got - d).abs() <= 1e-7 + err, "{got} vs {d} (error {err})");
    // P(S by T) = (1 − e^{−λT}(1+λT))(1 − e^{−μT}); d/dλ = λT² e^{−λT}(1 − e^{−μT})
    let t = 2.0;
    let s = sensitivity(&tree, Objective::SuccessBy(t), &Options::default()).unwrap();
    let d = l * t * t * (-l * t).exp() * (1.0 - (-m * t).exp());
    let (got, _, err, _) = row(&s, &tree, "A", Param::StageRate(true));
    assert!((got - d).abs() <= 1e-7 + err, "{got} vs {d} (error {err})");
}
