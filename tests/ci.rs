//! `report --ci` / `curve --ci`: intervals of the figures from the fitted
//! parameters' sampling uncertainty. Checked against independent truth:
//! the coverage of the intervals over many simulated logs of known
//! parameters (closed-form figures), and the Beta / Gamma quantiles of
//! single leaves computed here by numerical integration.

mod common;

use std::path::Path;

use btrel::fit::{fit_leaf, params_line, Counts};
use btrel::logs::{Declared, End, Episode};
use btrel::uncertainty::{read_fit_stats, Sampler};
use rand::{RngExt, SeedableRng};
use rand_distr::{Distribution, Exp};
use rand_xoshiro::Xoshiro256PlusPlus;
use serde_json::Value;

fn bin() -> assert_cmd::Command {
    assert_cmd::Command::cargo_bin("btrel").expect("the binary is built")
}

const FALLBACK: &str = r#"<root BTCPP_format="4" main_tree_to_execute="T">
  <BehaviorTree ID="T">
    <Fallback name="root">
      <A name="a"/>
      <B name="b"/>
    </Fallback>
  </BehaviorTree>
  <TreeNodesModel><Action ID="A"/><Action ID="B"/></TreeNodesModel>
</root>"#;

/// `n` episodes of an action (ps, mu, nu), each halted at an Exp(halt)
/// time when that comes first (no halts when `halt` is 0).
fn episodes(
    rng: &mut Xoshiro256PlusPlus,
    n: usize,
    (p, mu, nu): (f64, f64, f64),
    halt: f64,
) -> Vec<Episode> {
    drawn_episodes(rng, n, p, |r| exp(r, mu), |r| exp(r, nu), halt)
}

/// A CSV log (`run,node,start,end,status`) of leaf `A`'s episodes.
fn csv_log(eps: &[Episode]) -> String {
    let mut csv = String::from("run,node,start,end,status\n");
    for (i, e) in eps.iter().enumerate() {
        let status = match e.end {
            End::Success => "success",
            End::Failure => "failure",
            End::Halted => "halted",
        };
        csv.push_str(&format!("{i},A,0,{},{status}\n", e.duration));
    }
    csv
}

/// The params line of a `--timing auto` fit of an action's episodes.
fn auto_line(key: &str, e: &[Episode]) -> String {
    params_line(
        &btrel::fit::fit_leaf_with(
            key,
            Declared::Action,
            Counts::from_episodes(e),
            btrel::fit::TimingMode::Auto,
        )
        .unwrap(),
    )
}

/// Whether the `level` intervals (400 draws, seeded by `seed`) of the
/// root's ps, MTTS and MTTF cover `truth`.
fn root_covers(sampler: &Sampler, level: f64, seed: u64, truth: [f64; 3]) -> [bool; 3] {
    let ci = sampler
        .intervals(level, 400, seed, |t| {
            btrel::analyze(t, &Default::default()).map(|an| {
                let f = an.nodes[0];
                vec![Some(f.ps), f.mtts, f.mttf]
            })
        })
        .unwrap();
    std::array::from_fn(|k| {
        let (lo, hi) = ci[k].unwrap();
        lo <= truth[k] && truth[k] <= hi
    })
}

/// Each named figure's coverage over `reps` logs is within 3.5 binomial
/// standard errors of nominal `level`.
fn assert_nominal(names: &[&str], covered: &[usize], level: f64, reps: usize) {
    let sd = (level * (1.0 - level) / reps as f64).sqrt();
    for (what, &n) in names.iter().zip(covered) {
        let c = n as f64 / reps as f64;
        assert!(
            ((c - level) / sd).abs() < 3.5,
            "{what}: coverage {c} of nominal {level} over {reps} logs"
        );
    }
}

/// Coverage: logs simulated from known parameters, fitted, intervals of the
/// root's ps, MTTS and MTTF; the closed forms of a two-action Fallback
/// (eqs. 9.74–9.75) are the truth. Each level's coverage must be within
/// 3.5 binomial standard errors of nominal, at 90% (both sides can fail).
#[test]
fn intervals_cover_the_truth_at_their_level() {
    let (a, b) = ((0.6, 1.0, 2.0), (0.7, 0.5, 1.0));
    let ps = a.0 + (1.0 - a.0) * b.0;
    let mtts = (a.0 / a.1 + (1.0 - a.0) * b.0 * (1.0 / a.2 + 1.0 / b.1)) / ps;
    let mttf = 1.0 / a.2 + 1.0 / b.2;
    let truth = [ps, mtts, mttf];
    let reps = 300;
    let level = 0.9;
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(2026);
    let mut covered = [0usize; 3];
    let mut halted = 0;
    for rep in 0..reps {
        let ea = episodes(&mut rng, 40, a, 0.0);
        // B is halted now and then (censored durations, the EM path)
        let eb = episodes(&mut rng, 40, b, 0.15);
        halted += eb.iter().filter(|e| e.end == End::Halted).count();
        let fa = fit_leaf("A", Declared::Action, Counts::from_episodes(&ea)).unwrap();
        let fb = fit_leaf("B", Declared::Action, Counts::from_episodes(&eb)).unwrap();
        let params = format!("{}\n{}\n", params_line(&fa), params_line(&fb));
        let keyed =
            btrel::tree::xml::parse_xml_str_keyed(FALLBACK, "t.xml", &params, "p.yaml").unwrap();
        let stats = read_fit_stats(&params, "p.yaml").unwrap();
        let sampler = Sampler::new(&keyed.tree, &keyed.keys, &stats);
        assert_eq!(sampler.varied(), 6);
        for (c, hit) in covered
            .iter_mut()
            .zip(root_covers(&sampler, level, rep as u64, truth))
        {
            *c += usize::from(hit);
        }
    }
    assert!(
        halted > 200,
        "the halts path was exercised ({halted} halts)"
    );
    eprintln!("coverage of nominal {level} over {reps} logs (ps, MTTS, MTTF): {covered:?}");
    assert_nominal(&["ps", "MTTS", "MTTF"], &covered, level, reps);
}

/// The quantile `q` of a density on a grid (trapezoids), and the density there.
fn grid_quantile(lo: f64, hi: f64, log_density: impl Fn(f64) -> f64, q: f64) -> (f64, f64) {
    let n = 400_000;
    let h = (hi - lo) / n as f64;
    let xs: Vec<f64> = (0..=n).map(|i| lo + h * i as f64).collect();
    let lmax = xs[1..n]
        .iter()
        .map(|&x| log_density(x))
        .fold(f64::MIN, f64::max);
    let f: Vec<f64> = xs
        .iter()
        .enumerate()
        .map(|(i, &x)| {
            if i == 0 || i == n {
                0.0
            } else {
                (log_density(x) - lmax).exp()
            }
        })
        .collect();
    let mut cum = vec![0.0; n + 1];
    for i in 1..=n {
        cum[i] = cum[i - 1] + 0.5 * h * (f[i - 1] + f[i]);
    }
    let total = cum[n];
    let i = cum.iter().position(|&c| c >= q * total).unwrap();
    let frac = (q * total - cum[i - 1]) / (cum[i] - cum[i - 1]);
    (xs[i - 1] + frac * h, f[i] / total)
}

fn json_ci(v: &Value, node: &str, fig: &str) -> (f64, f64) {
    let n = v["nodes"]
        .as_array()
        .unwrap()
        .iter()
        .find(|n| n["name"] == node)
        .unwrap();
    let p = &n["ci"][fig];
    (p[0].as_f64().unwrap(), p[1].as_f64().unwrap())
}

const TREE: &str = "trees/search-and-grasp.xml";
const FITTED: &str = "docs/fit/search-and-grasp.fitted.params.yaml";

/// A condition's ps interval is the Beta(s + ½, f + ½) quantiles; an
/// action's MTTS interval is 1 / the Gamma(n, n/mu) quantiles (both
/// integrated numerically here), within 5 standard errors of a percentile
/// of 20,000 draws.
#[test]
fn single_leaf_intervals_are_the_beta_and_gamma_quantiles() {
    let out = bin()
        .args([
            "report",
            TREE,
            "--params",
            FITTED,
            "--ci",
            "--ci-draws",
            "20000",
            "--format",
            "json",
        ])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: Value = serde_json::from_slice(&out.stdout).unwrap();
    let draws = 20_000.0;
    let check = |what: &str, got: f64, (x, density): (f64, f64), q: f64| {
        let se = (q * (1.0 - q) / draws).sqrt() / density;
        assert!(
            ((got - x) / se).abs() < 5.0,
            "{what}: {got} vs quantile {x} (se {se})"
        );
    };
    // object position retrieved: 14 successes, 66 failures in the file
    let (lo, hi) = json_ci(&v, "object position retrieved", "ps");
    let beta = |x: f64| 13.5 * x.ln() + 65.5 * (1.0 - x).ln();
    check("ps lo", lo, grid_quantile(0.0, 1.0, beta, 0.025), 0.025);
    check("ps hi", hi, grid_quantile(0.0, 1.0, beta, 0.975), 0.975);
    // search floor: mu = 0.015064067478988134 with 30 successes
    let (mu, n) = (0.015064067478988134, 30.0);
    let gamma = |x: f64| (n - 1.0) * x.ln() - n / mu * x;
    let (lo, hi) = json_ci(&v, "search floor", "mtts");
    // MTTS = 1/mu: its lower bound is 1 / mu's upper quantile
    let (q_hi, d_hi) = grid_quantile(0.0, 4.0 * mu, gamma, 0.975);
    let (q_lo, d_lo) = grid_quantile(0.0, 4.0 * mu, gamma, 0.025);
    // density of 1/mu at 1/q is d * q^2
    check("mtts lo", lo, (1.0 / q_hi, d_hi * q_hi * q_hi), 0.975);
    check("mtts hi", hi, (1.0 / q_lo, d_lo * q_lo * q_lo), 0.025);
    // pf's interval mirrors ps's: every node returns
    let (plo, phi) = json_ci(&v, "search and grasp", "ps");
    let (flo, fhi) = json_ci(&v, "search and grasp", "pf");
    assert!((plo + fhi - 1.0).abs() < 1e-12 && (phi + flo - 1.0).abs() < 1e-12);
    assert_eq!(v["ci"]["level"], 0.95);
    assert_eq!(v["ci"]["draws"], 20000);
}

fn report_ci(extra: &[&str]) -> (String, String) {
    let out = bin()
        .args(["report", TREE, "--params", FITTED, "--ci"])
        .args(extra)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    (
        String::from_utf8(out.stdout).unwrap(),
        String::from_utf8(out.stderr).unwrap(),
    )
}

#[test]
fn reproducible_and_independent_of_threads() {
    let one = bin()
        .env("RAYON_NUM_THREADS", "1")
        .args([
            "report", TREE, "--params", FITTED, "--ci", "90", "--format", "csv",
        ])
        .output()
        .unwrap();
    let two = bin()
        .env("RAYON_NUM_THREADS", "2")
        .args([
            "report", TREE, "--params", FITTED, "--ci", "0.9", "--format", "csv",
        ])
        .output()
        .unwrap();
    assert!(one.status.success());
    assert_eq!(one.stdout, two.stdout);
    let (other, _) = report_ci(&["90", "--format", "csv", "--ci-seed", "7"]);
    assert_ne!(String::from_utf8(one.stdout.clone()).unwrap(), other);
    let text = String::from_utf8(one.stdout).unwrap();
    assert!(text.starts_with(
        "name,path,kind,depth,ps,ps_lo,ps_hi,pf,pf_lo,pf_hi,mtts,mtts_lo,mtts_hi,mttf,mttf_lo,mttf_hi\n"
    ));
    // every interval holds its point estimate here (80 episodes a leaf)
    for line in text.lines().skip(1) {
        let cells: Vec<&str> = line.split(',').collect();
        for k in [4, 7, 10, 13] {
            let [x, lo, hi] =
                [cells[k], cells[k + 1], cells[k + 2]].map(|c| c.parse::<f64>().unwrap());
            assert!(lo <= x + 1e-12 && x <= hi + 1e-12, "{line}");
        }
    }
}

#[test]
fn leaves_without_statistics_are_fixed_and_named() {
    let dir = tempfile::tempdir().unwrap();
    let params = dir.path().join("p.yaml");
    let text = std::fs::read_to_string(FITTED).unwrap();
    // strip two entries' statistics: hand-written parameters
    let text: String = text
        .lines()
        .map(|l| {
            if l.starts_with("\"SearchFloor\"") {
                "SearchFloor: {ps: 0.375, mu: 0.015, nu: 0.0089}".to_string()
            } else if l.starts_with("\"object grasped\"") {
                "object grasped: {ps: 0.05}".to_string()
            } else {
                l.to_string()
            }
        })
        .collect::<Vec<_>>()
        .join("\n");
    std::fs::write(&params, text).unwrap();
    let p = params.to_str().unwrap();
    let out = bin()
        .args(["report", TREE, "--params", p, "--ci", "--format", "json"])
        .output()
        .unwrap();
    assert!(out.status.success());
    let v: Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(
        v["ci"]["fixed"],
        serde_json::json!(["search floor", "object grasped"])
    );
    // a fixed leaf's interval is its value
    assert_eq!(json_ci(&v, "search floor", "ps"), (0.375, 0.375));
    assert_eq!(json_ci(&v, "object grasped", "ps"), (0.05, 0.05));
    let out = bin()
        .args(["report", TREE, "--params", p, "--ci"])
        .output()
        .unwrap();
    let text = String::from_utf8(out.stdout).unwrap();
    assert!(
        text.contains(
            "fixed (no `fit:` statistics in the params file): search floor, object grasped"
        ),
        "{text}"
    );
}

#[test]
fn curve_bands() {
    let out = bin()
        .args([
            "curve",
            TREE,
            "--params",
            FITTED,
            "--times",
            "0,100,1000",
            "--ci",
            "--ci-draws",
            "300",
        ])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8(out.stdout).unwrap();
    let mut lines = text.lines();
    assert_eq!(
        lines.next().unwrap(),
        "node,t,success,failure,running,success_lo,success_hi,failure_lo,failure_hi,running_lo,running_hi"
    );
    let rows: Vec<Vec<f64>> = lines
        .map(|l| l.split(',').skip(1).map(|c| c.parse().unwrap()).collect())
        .collect();
    assert_eq!(rows.len(), 3);
    // at t = 0 only the two conditions' instant success (or the first's
    // instant failure and no search yet) can have happened
    assert!(rows[0][1] > 0.0 && rows[0][1] < 0.05 && rows[0][2] == 0.0);
    for r in &rows {
        for k in 0..3 {
            assert!(
                r[4 + 2 * k] <= r[1 + k] && r[1 + k] <= r[5 + 2 * k],
                "{r:?}"
            );
            assert!(r[5 + 2 * k] >= r[4 + 2 * k]);
        }
    }
    let stderr = String::from_utf8(out.stderr).unwrap();
    assert!(stderr.contains("95% intervals from 300 draws"), "{stderr}");
}

#[test]
fn refusals() {
    let err = |args: &[&str]| {
        let out = bin().args(args).output().unwrap();
        assert_eq!(out.status.code(), Some(2), "{args:?}");
        assert!(out.stdout.is_empty());
        String::from_utf8(out.stderr).unwrap()
    };
    let e = err(&["report", "trees/search-and-grasp.yaml", "--ci"]);
    assert!(e.contains("--ci needs fitted parameters"), "{e}");
    let e = err(&[
        "report",
        TREE,
        "--params",
        "trees/search-and-grasp.params.yaml",
        "--ci",
    ]);
    assert!(
        e.contains("no parameter of this tree has `fit:` statistics"),
        "{e}"
    );
    for bad in ["0", "1.5", "100", "x"] {
        let e = err(&["report", TREE, "--params", FITTED, "--ci", bad]);
        assert!(e.contains("is not a confidence level"), "{e}");
    }
    let e = err(&["report", TREE, "--params", FITTED, "--ci-draws", "10"]);
    assert!(e.contains("--ci"), "{e}");
    let e = err(&[
        "report",
        TREE,
        "--params",
        FITTED,
        "--ci",
        "--ci-draws",
        "1",
    ]);
    assert!(e.contains("--ci-draws must be between"), "{e}");
    let e = err(&["report", TREE, "--params", FITTED, "--ci", "--mc", "100"]);
    assert!(e.contains("--ci and --mc"), "{e}");
    assert!(Path::new(FITTED).exists());
}

// ---------------------------------------------------------------------------
// Leaves with halts: the joint covariance of (ps, mu, nu)
// ---------------------------------------------------------------------------

/// `log L` of exponential timing with halts, written here from the model
/// (successes `ts`, failures `tf`, halts `tc`).
fn log_likelihood(ts: &[f64], tf: &[f64], tc: &[f64], p: f64, mu: f64, nu: f64) -> f64 {
    let s: f64 = ts.iter().map(|t| (p * mu).ln() - mu * t).sum();
    let f: f64 = tf.iter().map(|t| ((1.0 - p) * nu).ln() - nu * t).sum();
    let c: f64 = tc
        .iter()
        .map(|c| (p * (-mu * c).exp() + (1.0 - p) * (-nu * c).exp()).ln())
        .sum();
    s + f + c
}

/// The inverse of a 3×3 matrix by Gauss–Jordan elimination with pivoting.
fn inverse(m: [[f64; 3]; 3]) -> [[f64; 3]; 3] {
    let mut a = [[0.0; 6]; 3];
    for i in 0..3 {
        a[i][..3].copy_from_slice(&m[i]);
        a[i][3 + i] = 1.0;
    }
    for c in 0..3 {
        let p = (c..3)
            .max_by(|&x, &y| a[x][c].abs().total_cmp(&a[y][c].abs()))
            .unwrap();
        a.swap(c, p);
        let d = a[c][c];
        for v in a[c].iter_mut() {
            *v /= d;
        }
        for r in 0..3 {
            if r != c {
                let f = a[r][c];
                let row = a[c];
                for (v, x) in a[r].iter_mut().zip(row) {
                    *v -= f * x;
                }
            }
        }
    }
    let mut inv = [[0.0; 3]; 3];
    for i in 0..3 {
        inv[i].copy_from_slice(&a[i][3..]);
    }
    inv
}

/// The number after `key: ` in a params line.
fn field(line: &str, key: &str) -> f64 {
    let at = line
        .find(&format!(" {key}: "))
        .or_else(|| line.find(&format!("{{{key}: ")))
        .unwrap_or_else(|| panic!("{key} in {line}"));
    let rest = &line[at + key.len() + 3..];
    let end = rest.find([',', '}', ']']).unwrap();
    rest[..end].trim().parse().unwrap()
}

/// `fit`'s covariance of (p̂, μ̂, ν̂) — the standard errors and the `cov:`
/// it writes — against the inverse of a finite-difference Hessian of the
/// log-likelihood written above, at the estimates `fit` writes.
#[test]
fn fitted_covariance_is_the_inverse_finite_difference_information() {
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(77);
    let eps = episodes(&mut rng, 400, (0.7, 0.5, 1.0), 1.5);
    let pick = |e: End| -> Vec<f64> {
        eps.iter()
            .filter(|x| x.end == e)
            .map(|x| x.duration)
            .collect()
    };
    let (ts, tf, tc) = (pick(End::Success), pick(End::Failure), pick(End::Halted));
    assert!(tc.len() > 240, "{} halts", tc.len());
    let f = fit_leaf("A", Declared::Action, Counts::from_episodes(&eps)).unwrap();
    let line = params_line(&f);
    let x = [field(&line, "ps"), field(&line, "mu"), field(&line, "nu")];
    let ll = |y: [f64; 3]| log_likelihood(&ts, &tf, &tc, y[0], y[1], y[2]);
    // central second differences, steps 1e-4 of each value
    let mut info = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            let (hi, hj) = (1e-4 * x[i], 1e-4 * x[j]);
            let at = |si: f64, sj: f64| {
                let mut y = x;
                y[i] += si * hi;
                y[j] += sj * hj;
                ll(y)
            };
            info[i][j] =
                -(at(1.0, 1.0) - at(1.0, -1.0) - at(-1.0, 1.0) + at(-1.0, -1.0)) / (4.0 * hi * hj);
        }
    }
    let cov = inverse(info);
    let got_se = [
        field(&line, "ps_se"),
        field(&line, "mu_se"),
        field(&line, "nu_se"),
    ];
    let got_cov = [
        (0, 1, field(&line, "ps_mu")),
        (0, 2, field(&line, "ps_nu")),
        (1, 2, field(&line, "mu_nu")),
    ];
    for i in 0..3 {
        let se = cov[i][i].sqrt();
        assert!(
            ((got_se[i] - se) / se).abs() < 1e-4,
            "se {i}: {} vs {se}",
            got_se[i]
        );
    }
    for (i, j, got) in got_cov {
        let scale = (cov[i][i] * cov[j][j]).sqrt();
        assert!(
            ((got - cov[i][j]) / scale).abs() < 1e-4,
            "cov {i}{j}: {got} vs {}",
            cov[i][j]
        );
    }
    // a correlation that is not small, of the sign docs/LOGS.md states
    assert!(got_cov[1].2 / (got_se[0] * got_se[2]) > 0.5, "{line}");
    // without halts: no `cov:`
    let eps = episodes(&mut rng, 400, (0.7, 0.5, 1.0), 0.0);
    let f = fit_leaf("A", Declared::Action, Counts::from_episodes(&eps)).unwrap();
    assert!(!params_line(&f).contains("cov"), "{}", params_line(&f));
}

const SEQUENCE: &str = r#"<root BTCPP_format="4" main_tree_to_execute="T">
  <BehaviorTree ID="T">
    <Sequence name="root">
      <A name="a"/>
      <C name="c"/>
    </Sequence>
  </BehaviorTree>
  <TreeNodesModel><Action ID="A"/><Condition ID="C"/></TreeNodesModel>
</root>"#;

/// The params text without its `cov:` mappings (as an older `btrel fit`
/// wrote it).
fn without_cov(params: &str) -> String {
    params
        .lines()
        .map(|l| match l.find(", cov: {") {
            Some(i) => {
                let end = i + l[i..].find('}').unwrap() + 1;
                format!("{}{}", &l[..i], &l[end..])
            }
            None => l.to_string(),
        })
        .collect::<Vec<_>>()
        .join("\n")
}

/// Coverage with heavy halting (≈ 70% of A's episodes halted): CSV logs
/// simulated from known (p, μ, ν), fitted, and the 90% intervals of
/// Sequence(A, C)'s figures (C a hand-written condition, ps 0.7, fixed).
/// The root's MTTF, (q/ν + 0.3p/μ)/(q + 0.3p), depends on all three of A's
/// parameters together: with the joint draws its coverage is nominal within
/// 3.5 binomial standard errors; the same fits without `cov:` (independent
/// draws) over-cover it far beyond that (by the asymptotic covariance, the
/// independent standard deviation of this MTTF is 1.9 times the joint one
/// here, so 90% intervals would cover ≈ 99.8%). ps = 0.7p and MTTS = 1/μ
/// depend on one parameter each: both ways cover them.
#[test]
fn joint_draws_cover_a_correlated_figure_with_heavy_halting() {
    let (p, mu, nu) = (0.7, 0.5, 1.0);
    // C succeeds with 0.7: the root fails when A fails, or when A succeeds
    // and C fails (probability p·0.3, after A's success time)
    let truth = [
        p * 0.7,
        1.0 / mu,
        ((1.0 - p) / nu + p * 0.3 / mu) / (1.0 - p + p * 0.3),
    ];
    let (reps, n, draws, level) = (400, 2000, 400, 0.9);
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(15);
    let mut covered = [[0usize; 3]; 2];
    let (mut halted, mut total) = (0, 0);
    for rep in 0..reps {
        let eps = episodes(&mut rng, n, (p, mu, nu), 1.5);
        let csv = csv_log(&eps);
        halted += eps.iter().filter(|e| e.end == End::Halted).count();
        total += n;
        let log = btrel::logs::read_bytes(csv.as_bytes(), "run.csv", "csv").unwrap();
        let fitted = btrel::fit::fit_logs(&[log], btrel::fit::By::Id).unwrap();
        let params = format!(
            "{}C: {{ps: 0.7}}\n",
            btrel::fit::render(&fitted, btrel::fit::By::Id)
        );
        assert!(params.contains("cov: {ps_mu: "), "{params}");
        for (way, text) in [params.clone(), without_cov(&params)].iter().enumerate() {
            let keyed =
                btrel::tree::xml::parse_xml_str_keyed(SEQUENCE, "t.xml", text, "p.yaml").unwrap();
            let stats = read_fit_stats(text, "p.yaml").unwrap();
            let sampler = Sampler::new(&keyed.tree, &keyed.keys, &stats);
            assert_eq!(sampler.varied(), 3);
            assert_eq!(sampler.independent.len(), way, "{:?}", sampler.independent);
            let ci = sampler
                .intervals(level, draws, rep as u64, |t| {
                    btrel::analyze(t, &Default::default()).map(|an| {
                        let f = an.nodes[0];
                        vec![Some(f.ps), f.mtts, f.mttf]
                    })
                })
                .unwrap();
            for k in 0..3 {
                let (lo, hi) = ci[k].unwrap();
                covered[way][k] += usize::from(lo <= truth[k] && truth[k] <= hi);
            }
        }
    }
    let share = halted as f64 / total as f64;
    eprintln!(
        "{:.1}% halted; coverage of nominal {level} over {reps} logs (ps, MTTS, MTTF): \
         joint {:?}, independent {:?}",
        100.0 * share,
        covered[0],
        covered[1]
    );
    assert!(share > 0.6, "{share}");
    let sd = (level * (1.0 - level) / reps as f64).sqrt();
    let z = |c: usize| (c as f64 / reps as f64 - level) / sd;
    for (k, what) in ["ps", "MTTS", "MTTF"].iter().enumerate() {
        assert!(
            z(covered[0][k]).abs() < 3.5,
            "joint draws, {what}: coverage {} of {reps} at nominal {level}",
            covered[0][k]
        );
    }
    // the independent draws miss the correlation: MTTF over-covered
    assert!(
        z(covered[1][2]) > 3.5,
        "independent draws, MTTF: coverage {} of {reps} at nominal {level}",
        covered[1][2]
    );
}

/// A fitted CSV log with halts through the binary: `fit` writes `cov:`,
/// `report --ci` reads it and draws jointly (no note); the same file
/// without `cov:` still works, with a note naming the leaf drawn
/// independently.
#[test]
fn cli_fit_then_ci_with_halts() {
    let dir = tempfile::tempdir().unwrap();
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(3);
    let csv = csv_log(&episodes(&mut rng, 300, (0.7, 0.5, 1.0), 1.5));
    let log = dir.path().join("runs.csv");
    std::fs::write(&log, csv).unwrap();
    let params = dir.path().join("p.yaml");
    let out = bin()
        .args(["fit", log.to_str().unwrap(), "-o", params.to_str().unwrap()])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let mut text = std::fs::read_to_string(&params).unwrap();
    assert!(text.contains("# `cov:` (leaves with halts)"), "{text}");
    assert!(text.contains(", cov: {ps_mu: -"), "{text}");
    text.push_str("C: {ps: 0.7}\n");
    std::fs::write(&params, &text).unwrap();
    let tree = dir.path().join("t.xml");
    std::fs::write(&tree, SEQUENCE).unwrap();
    let run = |p: &Path| {
        let out = bin()
            .args([
                "report",
                tree.to_str().unwrap(),
                "--params",
                p.to_str().unwrap(),
            ])
            .args(["--ci", "--ci-draws", "200", "--format", "json"])
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        serde_json::from_slice::<Value>(&out.stdout).unwrap()
    };
    let v = run(&params);
    assert_eq!(v["ci"]["independent"], serde_json::json!([]));
    assert!(v["ci"]["method"]
        .as_str()
        .unwrap()
        .contains("jointly normal"));
    let old = dir.path().join("old.yaml");
    std::fs::write(&old, without_cov(&text)).unwrap();
    let v = run(&old);
    let notes = v["ci"]["independent"].as_array().unwrap();
    assert_eq!(notes.len(), 1, "{notes:?}");
    assert!(notes[0]
        .as_str()
        .unwrap()
        .starts_with("a: ps, mu, nu drawn independently"));
}

/// `cov:` is checked where `--ci` reads it: malformed, without its
/// standard errors, or not positive semidefinite, it is an error naming
/// the file, line and column of the mapping.
#[test]
fn a_bad_covariance_is_a_located_error() {
    let head = "# fitted\n";
    let entry =
        |fit: &str| format!("{head}A: {{ps: 0.7, mu: 0.5, nu: 1.0, fit: {{halted: 5, {fit}}}}}\n");
    let se = "ps_se: 0.05, mu_se: 0.1, nu_se: 0.2";
    // the column of `{` after `cov: ` on line 2
    let col = |text: &str| text.lines().nth(1).unwrap().find("cov: {").unwrap() + 6;
    // correlation ps–mu = 0.006 / (0.05 · 0.1) = 1.2: not a covariance
    let text = entry(&format!(
        "{se}, cov: {{ps_mu: 0.006, ps_nu: 0.0, mu_nu: 0.0}}"
    ));
    let e = read_fit_stats(&text, "p.yaml").unwrap_err();
    assert!(e.starts_with(&format!("p.yaml:2:{}: ", col(&text))), "{e}");
    assert!(e.contains("not positive semidefinite"), "{e}");
    assert!(e.contains("ps–mu 1.200, ps–nu 0.000, mu–nu 0.000"), "{e}");
    // each pair fine (|corr| 0.9) but the three together impossible:
    // corr(ps,mu) = corr(ps,nu) = 0.9, corr(mu,nu) = -0.9
    let text = entry(&format!(
        "{se}, cov: {{ps_mu: 0.0045, ps_nu: 0.009, mu_nu: -0.018}}"
    ));
    let e = read_fit_stats(&text, "p.yaml").unwrap_err();
    assert!(e.contains("not positive semidefinite"), "{e}");
    // without the standard errors
    let text = entry("cov: {ps_mu: 0.001, ps_nu: 0.0, mu_nu: 0.0}");
    let e = read_fit_stats(&text, "p.yaml").unwrap_err();
    assert!(e.starts_with(&format!("p.yaml:2:{}: ", col(&text))), "{e}");
    assert!(
        e.contains("needs positive `ps_se`, `mu_se` and `nu_se`"),
        "{e}"
    );
    // malformed: a missing key, an unknown key, a list
    for bad in [
        "cov: {ps_mu: 0.001, ps_nu: 0.0}",
        "cov: {ps_mu: 0.001, ps_nu: 0.0, mu_nu: 0.0, nu_ps: 0.0}",
        "cov: [0.001, 0.0, 0.0]",
        "cov: {ps_mu: x, ps_nu: 0.0, mu_nu: 0.0}",
    ] {
        let text = entry(&format!("{se}, {bad}"));
        let e = read_fit_stats(&text, "p.yaml").unwrap_err();
        assert!(e.starts_with("p.yaml:2:"), "{bad}: {e}");
        assert!(
            e.contains("cannot read the `fit:` statistics"),
            "{bad}: {e}"
        );
    }
    // a valid one is read; old entries without it still are
    let text = entry(&format!(
        "{se}, cov: {{ps_mu: -0.003, ps_nu: 0.008, mu_nu: -0.012}}"
    ));
    let st = &read_fit_stats(&text, "p.yaml").unwrap()["A"];
    let c = st.cov.unwrap();
    assert_eq!((c.line, c.column), (2, col(&text)));
    assert_eq!(c.cov.mu_nu, -0.012);
    let st = &read_fit_stats(&entry(se), "p.yaml").unwrap()["A"];
    assert_eq!(st.cov, None);
    // the analysis itself ignores `fit:` (a bad `cov:` there is --ci's concern)
    let text = entry(&format!(
        "{se}, cov: {{ps_mu: 0.006, ps_nu: 0.0, mu_nu: 0.0}}"
    ));
    let tree = r#"<root BTCPP_format="4"><BehaviorTree ID="T"><A/></BehaviorTree>
        <TreeNodesModel><Action ID="A"/></TreeNodesModel></root>"#;
    let keyed = btrel::tree::xml::parse_xml_str_keyed(tree, "t.xml", &text, "p.yaml")
        .unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(keyed.tree.nodes().len(), 1);
    assert_eq!(keyed.tree.nodes()[0].name, "A");
}

/// Coverage with `--timing auto`: A's Success times are Erlang-3 (rate 6,
/// mean 0.5 s), its Failure times exponential (rate 20), B's exponential
/// and fast (rates 10), no halts; each log is fitted by `--timing auto`
/// and the 90% intervals of the Fallback's ps and MTTS are checked against
/// the closed forms (MTTS = (p_A·3/λ + q_A·p_B·(1/ν_A + 1/μ_B)) / ps,
/// which A's Erlang rate dominates). The Erlang rate is drawn from
/// Gamma(k·n, k·n/λ̂) (`rate·Σt` is a sum of k·n unit stages); held fixed,
/// as before, MTTS is covered far too rarely, which this test catches.
/// MTTF (exponential times only) is printed, not asserted: where `auto`
/// picks another family for an exponential truth (a shifted or
/// hyperexponential law in a few logs), that law's shift or mixture is
/// held, and its coverage is a few points low (docs/LOGS.md).
#[test]
fn auto_fitted_erlang_times_are_drawn_and_cover_the_truth() {
    let (p_a, lam, nu_a) = (0.9, 6.0, 20.0);
    let b = (0.7, 10.0, 10.0);
    let ps = p_a + (1.0 - p_a) * b.0;
    let mtts = (p_a * 3.0 / lam + (1.0 - p_a) * b.0 * (1.0 / nu_a + 1.0 / b.1)) / ps;
    let mttf = 1.0 / nu_a + 1.0 / b.2;
    let truth = [ps, mtts, mttf];
    let (reps, level) = (300, 0.9);
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(2027);
    let mut covered = [0usize; 3];
    let (mut erlang, mut other) = (0, 0);
    for rep in 0..reps {
        let ea: Vec<Episode> = (0..100)
            .map(|_| {
                let ok = rng.random::<f64>() < p_a;
                let duration = if ok {
                    (0..3)
                        .map(|_| Exp::new(lam).unwrap().sample(&mut rng))
                        .sum()
                } else {
                    Exp::new(nu_a).unwrap().sample(&mut rng)
                };
                Episode {
                    duration,
                    end: if ok { End::Success } else { End::Failure },
                    instant: false,
                }
            })
            .collect();
        let eb = episodes(&mut rng, 100, b, 0.0);
        let (la, lb) = (auto_line("A", &ea), auto_line("B", &eb));
        erlang += usize::from(la.contains("success_time: {erlang: {k: "));
        let params = format!("{la}\n{lb}\n");
        let keyed =
            btrel::tree::xml::parse_xml_str_keyed(FALLBACK, "t.xml", &params, "p.yaml").unwrap();
        let stats = read_fit_stats(&params, "p.yaml").unwrap();
        let sampler = Sampler::new(&keyed.tree, &keyed.keys, &stats);
        // an Erlang's rate is drawn; other phase-type laws are held
        assert!(
            !la.contains("erlang") || !sampler.held.iter().any(|h| h.contains("Erlang")),
            "{:?}\n{la}",
            sampler.held
        );
        other += usize::from(!sampler.held.is_empty());
        for (c, hit) in covered
            .iter_mut()
            .zip(root_covers(&sampler, level, rep as u64, truth))
        {
            *c += usize::from(hit);
        }
    }
    assert!(
        erlang > reps * 3 / 4,
        "auto picked an Erlang for A's Success in {erlang} of {reps} logs"
    );
    eprintln!(
        "auto fits: coverage of nominal {level} over {reps} logs (ps, MTTS, MTTF): {covered:?}; \
         an Erlang picked {erlang} times, a law held in {other} logs"
    );
    assert_nominal(&["ps", "MTTS"], &covered, level, reps);
}

/// `n` episodes of an action whose outcome is drawn with `p`, then its
/// duration by `success` or `failure`, halted at an Exp(`halt`) time when
/// that comes first (no halts when `halt` is 0).
fn drawn_episodes(
    rng: &mut Xoshiro256PlusPlus,
    n: usize,
    p: f64,
    success: impl Fn(&mut Xoshiro256PlusPlus) -> f64,
    failure: impl Fn(&mut Xoshiro256PlusPlus) -> f64,
    halt: f64,
) -> Vec<Episode> {
    (0..n)
        .map(|_| {
            let ok = rng.random::<f64>() < p;
            let d = if ok { success(rng) } else { failure(rng) };
            let c = if halt > 0.0 {
                Exp::new(halt).unwrap().sample(rng)
            } else {
                f64::INFINITY
            };
            let (duration, end) = match (d < c, ok) {
                (false, _) => (c, End::Halted),
                (true, true) => (d, End::Success),
                (true, false) => (d, End::Failure),
            };
            Episode {
                duration,
                end,
                instant: false,
            }
        })
        .collect()
}

fn exp(rng: &mut Xoshiro256PlusPlus, rate: f64) -> f64 {
    Exp::new(rate).unwrap().sample(rng)
}

/// `n` episodes of an action succeeding with `p` after a bimodal time
/// (0.5·Exp(10) + 0.5·Exp(0.5)), failing after a shifted one (0.3 s +
/// Exp(5)), halted at Exp(`halt`) times.
fn bimodal_and_shifted(rng: &mut Xoshiro256PlusPlus, n: usize, p: f64, halt: f64) -> Vec<Episode> {
    drawn_episodes(
        rng,
        n,
        p,
        |r| {
            if r.random::<f64>() < 0.5 {
                exp(r, 10.0)
            } else {
                exp(r, 0.5)
            }
        },
        |r| 0.3 + exp(r, 5.0),
        halt,
    )
}

/// Coverage of `--timing auto` fits whose laws have no exact pivot: A's
/// Success time bimodal (hyperexponential: 0.5·Exp(10) + 0.5·Exp(0.5)),
/// its Failure time shifted (0.3 s + Exp(5)); `halt` > 0 halts A's
/// episodes. Returns the coverage of (ps, MTTS, MTTF, A's Failure shift),
/// the logs where each family was picked, and the held parameters' count.
fn auto_coverage(seed: u64, reps: usize, halt: f64) -> ([usize; 4], [usize; 2], usize) {
    let (p_a, b) = (0.8, (0.6, 2.0, 1.0));
    let mean_s = 0.5 / 10.0 + 1.0; // 0.5/10 + 0.5/0.5
    let mean_f = 0.3 + 1.0 / 5.0;
    let ps = p_a + (1.0 - p_a) * b.0;
    let mtts = (p_a * mean_s + (1.0 - p_a) * b.0 * (mean_f + 1.0 / b.1)) / ps;
    let mttf = mean_f + 1.0 / b.2;
    let truth = [ps, mtts, mttf, 0.3];
    let level = 0.9;
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(seed);
    let mut covered = [0usize; 4];
    let mut picked = [0usize; 2];
    let mut held = 0;
    for rep in 0..reps {
        let ea = bimodal_and_shifted(&mut rng, 300, p_a, halt);
        let eb = episodes(&mut rng, 100, b, 0.0);
        let (la, lb) = (auto_line("A", &ea), auto_line("B", &eb));
        assert!(la.contains("cov_theta: {params: ["), "{la}");
        picked[0] += usize::from(la.contains("success_family: \"hyperexponential-2\""));
        picked[1] += usize::from(la.contains("failure_family: \"shifted exponential\""));
        let params = format!("{la}\n{lb}\n");
        let keyed =
            btrel::tree::xml::parse_xml_str_keyed(FALLBACK, "t.xml", &params, "p.yaml").unwrap();
        let stats = read_fit_stats(&params, "p.yaml").unwrap();
        let sampler = Sampler::new(&keyed.tree, &keyed.keys, &stats);
        held += sampler.held.len();
        let a = keyed
            .tree
            .nodes()
            .iter()
            .position(|n| n.name == "a")
            .unwrap();
        let ci = sampler
            .intervals(level, 400, rep as u64, |t| {
                btrel::analyze(t, &Default::default()).map(|an| {
                    let f = an.nodes[0];
                    let btrel::tree::NodeKind::Action(x) = &t.nodes()[a].kind else {
                        unreachable!()
                    };
                    vec![Some(f.ps), f.mtts, f.mttf, x.failure.map(|d| d.shift())]
                })
            })
            .unwrap();
        for k in 0..4 {
            let (lo, hi) = ci[k].unwrap();
            covered[k] += usize::from(lo <= truth[k] && truth[k] <= hi);
        }
    }
    (covered, picked, held)
}

/// Hyperexponential and shifted times fitted without halts: the
/// hyperexponential's (p, rate1, rate2) drawn from the fit's `cov_theta`,
/// the shift from its pivot; every interval at its nominal coverage, and
/// nothing held.
#[test]
fn auto_fitted_hyperexponential_and_shifted_times_cover_the_truth() {
    let reps = 300;
    let (covered, picked, held) = auto_coverage(31, reps, 0.0);
    eprintln!(
        "coverage of nominal 0.9 over {reps} logs (ps, MTTS, MTTF): {covered:?}; \
         hyperexponential picked {}, shifted {}",
        picked[0], picked[1]
    );
    assert!(
        picked[0] > reps * 3 / 4 && picked[1] > reps * 3 / 4,
        "{picked:?}"
    );
    assert_eq!(held, 0);
    assert_nominal(&["ps", "MTTS", "MTTF", "shift"], &covered, 0.9, reps);
}

/// The same laws with a third of A's episodes halted: (logit ps and every
/// rate and branch probability) drawn jointly from `cov_theta`, the shift
/// from its pivot.
#[test]
fn auto_fitted_times_with_halts_cover_the_truth() {
    let reps = 300;
    let (covered, picked, held) = auto_coverage(32, reps, 0.4);
    eprintln!(
        "with halts: coverage of nominal 0.9 over {reps} logs (ps, MTTS, MTTF): {covered:?}; \
         hyperexponential picked {}, shifted {}",
        picked[0], picked[1]
    );
    assert!(picked[0] > reps / 2 && picked[1] > reps / 2, "{picked:?}");
    assert_eq!(held, 0);
    assert_nominal(&["ps", "MTTS", "MTTF", "shift"], &covered, 0.9, reps);
}

/// A `cov_theta:` that is not a covariance of its named parameters is an
/// error at its line and column: an unknown or repeated name, a matrix of
/// the wrong shape, a matrix that is not positive semidefinite.
#[test]
fn a_bad_cov_theta_is_a_located_error() {
    let entry = |theta: &str| {
        format!(
            "# fitted\nA: {{ps: 0.7, mu: 0.5, nu: 1.0, fit: {{timing: auto, halted: 5, \
             cov_theta: {theta}}}}}\n"
        )
    };
    let col = |text: &str| text.lines().nth(1).unwrap().find("cov_theta: {").unwrap() + 12;
    for (theta, says) in [
        (
            "{params: [logit_ps, ln_sucess_rate], matrix: [[1.0, 0.0], [0.0, 1.0]]}",
            "unknown parameter `ln_sucess_rate`",
        ),
        (
            "{params: [logit_ps, logit_ps], matrix: [[1.0, 0.0], [0.0, 1.0]]}",
            "names `logit_ps` twice",
        ),
        (
            "{params: [logit_ps, ln_success_rate], matrix: [[1.0, 0.0]]}",
            "is not 2×2",
        ),
        // correlation 2: not a covariance
        (
            "{params: [logit_ps, ln_success_rate], matrix: [[1.0, 2.0], [2.0, 1.0]]}",
            "not positive semidefinite",
        ),
    ] {
        let text = entry(theta);
        let e = read_fit_stats(&text, "p.yaml").unwrap_err();
        assert!(
            e.starts_with(&format!("p.yaml:2:{}: `A`: ", col(&text))),
            "{theta}: {e}"
        );
        assert!(e.contains(says), "{theta}: {e}");
    }
    let text = entry("{params: [logit_ps], matrix: 3}");
    let e = read_fit_stats(&text, "p.yaml").unwrap_err();
    assert!(e.contains("cannot read the `fit:` statistics"), "{e}");
}

/// Through the binary: a CSV log of a bimodal, halted leaf, `fit --timing
/// auto` writes `cov_theta`, and `report --ci` draws every parameter (no
/// note of a held one), its MTTS interval covering the sample's mean time.
#[test]
fn cli_auto_fit_then_ci_holds_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(77);
    let eps = bimodal_and_shifted(&mut rng, 600, 0.8, 0.2);
    let csv = csv_log(&eps);
    let log = dir.path().join("run.csv");
    std::fs::write(&log, csv).unwrap();
    let params = dir.path().join("params.yaml");
    bin()
        .args(["fit", "--timing", "auto", "-o"])
        .arg(&params)
        .arg(&log)
        .assert()
        .success();
    let text = std::fs::read_to_string(&params).unwrap();
    assert!(text.contains("cov_theta: {params: [logit_ps, logit_success_p, ln_success_rate1, ln_success_rate2, ln_failure_rate]"), "{text}");
    assert!(text.contains("`cov_theta:` the covariance"), "{text}");
    let tree = dir.path().join("t.xml");
    std::fs::write(
        &tree,
        r#"<root BTCPP_format="4"><BehaviorTree ID="T"><A name="a"/></BehaviorTree>
        <TreeNodesModel><Action ID="A"/></TreeNodesModel></root>"#,
    )
    .unwrap();
    let out = bin()
        .args(["report", "--ci", "--format", "json", "--params"])
        .arg(&params)
        .arg(&tree)
        .assert()
        .success();
    let stdout = String::from_utf8_lossy(&out.get_output().stdout).to_string();
    let v: Value = serde_json::from_str(&stdout).unwrap();
    assert_eq!(v["ci"]["held"], serde_json::json!([]), "{stdout}");
    let (lo, hi) = json_ci(&v, "a", "mtts");
    // the true mean Success time 0.5/10 + 0.5/0.5 = 1.05 s
    assert!(lo < 1.05 && 1.05 < hi, "({lo}, {hi})");
    assert!(hi - lo > 0.05, "({lo}, {hi}): the rates vary");
}

/// A `cov_theta` whose parameters the leaf's times do not have (the time
/// edited since the fit) is named and ignored, not silently used.
#[test]
fn a_cov_theta_that_does_not_fit_the_times_is_named() {
    let params =
        "A: {ps: 0.7, success_time: {erlang: {k: 2, rate: 3.0}}, nu: 1.0, fit: {successes: 70, \
                  failures: 30, halted: 0, cov_theta: {params: [logit_ps, logit_success_p], \
                  matrix: [[0.05, 0.0], [0.0, 0.1]]}}}\nB: {ps: 0.5, mu: 1.0, nu: 1.0}\n";
    let keyed = btrel::tree::xml::parse_xml_str_keyed(FALLBACK, "t.xml", params, "p.yaml").unwrap();
    let stats = read_fit_stats(params, "p.yaml").unwrap();
    let sampler = Sampler::new(&keyed.tree, &keyed.keys, &stats);
    assert!(
        sampler
            .held
            .iter()
            .any(|h| h.starts_with("a: `cov_theta` names parameters its times do not have")),
        "{:?}",
        sampler.held
    );
    // the same with a matching matrix: drawn, nothing held
    let params = params.replace("logit_success_p", "ln_success_rate");
    let stats = read_fit_stats(&params, "p.yaml").unwrap();
    let keyed =
        btrel::tree::xml::parse_xml_str_keyed(FALLBACK, "t.xml", &params, "p.yaml").unwrap();
    let sampler = Sampler::new(&keyed.tree, &keyed.keys, &stats);
    assert!(sampler.held.is_empty(), "{:?}", sampler.held);
    assert_eq!(sampler.varied(), 3); // ps (Beta), the Erlang rate (Gamma), nu (Gamma)
}
