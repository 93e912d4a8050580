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
        .find(|r| tree.nodes[r.leaf].name == leaf && r.param == p)
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
    assert_eq!(tree.nodes[s.rows[0].leaf].name, "a");
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
    // a point of the curve is differenced
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
    // exactly by counting; its MTTS is differenced, and says so
    let tree = common::tree(
        "tree:\n  parallel:\n    success_threshold: 1\n    children:\n      - action: {name: a, ps: 0.3, mu: 1.0, nu: 2.0}\n      - action: {name: b, ps: 0.6, mu: 0.5, nu: 1.0}\n",
    );
    let s = sensitivity(&tree, Objective::Ps, &o).unwrap();
    let (d, _, _, scheme) = row(&s, &tree, "a", Param::Ps);
    close("d ps / d ps_a", d, 0.4);
    assert_eq!(scheme, Scheme::Exact);
    let s = sensitivity(&tree, Objective::Mtts, &o).unwrap();
    assert!(s.rows.iter().all(|r| r.scheme == Scheme::Central), "{s:?}");
}

/// Exact derivatives agree with the Richardson-extrapolated differences on
/// random trees (every node kind, every leaf timing).
#[test]
fn exact_matches_richardson_on_random_trees() {
    let o = Options::default();
    let mut exact_rows = 0;
    for seed in 0..200 {
        let yaml = common::random_mixed_tree(seed, 3);
        let tree = common::tree(&yaml);
        for objective in [
            Objective::Ps,
            Objective::Mtts,
            Objective::Mttf,
            Objective::MeanTime,
        ] {
            // a Parallel's mean times are differenced either way, and the
            // differences of its mixed-timing races are slow (its P(S) is
            // checked by hand above)
            if yaml.contains("parallel") {
                continue;
            }
            let Ok(s) = sensitivity(&tree, objective, &o) else {
                continue;
            };
            // a perturbed tree's analysis may fail where the exact pass
            // does not (e.g. the stiff solver's error bound)
            let Ok(r) = sensitivity_by_differences(&tree, objective, &o) else {
                continue;
            };
            for a in &s.rows {
                let b = r
                    .rows
                    .iter()
                    .find(|b| b.leaf == a.leaf && b.param == a.param)
                    .unwrap();
                if a.scheme != Scheme::Exact {
                    // the same differences
                    assert_eq!(a.derivative, b.derivative);
                    continue;
                }
                exact_rows += 1;
                let scale = a.derivative.abs().max(1.0);
                assert!(
                    (a.derivative - b.derivative).abs() <= 1e-7 * scale + 2.0 * b.error,
                    "seed {seed} {objective:?} {} {:?}: exact {} vs differences {} (error {})",
                    tree.nodes[a.leaf].path,
                    a.param,
                    a.derivative,
                    b.derivative,
                    b.error
                );
            }
        }
    }
    assert!(exact_rows > 300, "{exact_rows}");
}
