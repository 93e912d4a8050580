//! Confidence intervals of a tree's figures from the sampling uncertainty of
//! its fitted leaf parameters (`report --ci`, `curve --ci`).
//!
//! # Method: a parametric bootstrap through the exact engine
//!
//! `btrel fit` writes, under each params entry's `fit:` key, the episode
//! counts and the standard errors of the estimates. From them every fitted
//! parameter gets a sampling distribution:
//!
//! * `ps` ~ Beta(s + ½, f + ½), with s successes and f failures among the
//!   completed episodes (the Jeffreys posterior: well calibrated, and proper
//!   at the boundary ps = 0 or 1).
//! * a rate (`mu`, `nu`) with n events over an exposure T ~ Gamma(shape n,
//!   rate T), T = n / rate: for exponential times 2·rate·T ~ χ²(2n) exactly,
//!   so its percentile interval is the exact pivotal one.
//! * the rate of an Erlang-k time (`fit --timing auto`; a shifted
//!   exponential is k = 1) fitted to n durations without halts ~ Gamma(k·n,
//!   k·n / rate): `rate·Σt` is a sum of k·n unit exponential stages, the
//!   same pivot.
//! * the shift δ̂ of a shifted exponential (`fit --timing auto`: the
//!   shortest of n completed durations): δ = δ̂ − E, E ~ Exp(n·rate) — the
//!   exact pivot of a minimum (`δ̂ − δ` is the shortest of n Exp(rate)
//!   draws), with the drawn rate, clipped at 0.
//! * every other parameter of an auto fit — a hyperexponential's (p, rate1,
//!   rate2), and with halts every parameter of the leaf, ps included — from
//!   the normal law on the logit/ln scale with the fit's `cov_theta:`
//!   ([`crate::fit::information`]: the inverse observed information), by
//!   its Cholesky factor. Without halts the information is block-diagonal
//!   (ps, each outcome's law), so the hyperexponential's block is drawn
//!   alone beside the exact laws above.
//!
//! These are drawn independently, which is right to first order when no
//! episode was halted: a leaf's log-likelihood then separates into a `p`
//! part (the counts), a `mu` part (the successes' durations) and a `nu`
//! part (the failures'), so the information is diagonal and the estimators
//! asymptotically independent.
//!
//! **With halts** a censored episode's `log(p e^{−μc} + (1−p) e^{−νc})`
//! couples the three (correlations ≈ 0.1 at 20% halted, up to 0.9 at 76%;
//! docs/LOGS.md), and `btrel fit` writes the covariances of (p̂, μ̂, ν̂) as `fit:
//! {cov: {ps_mu, ps_nu, mu_nu}}` ([`crate::fit::covariance`]). Such a leaf's
//! three parameters are drawn together: θ = (logit ps, ln mu, ln nu) ~
//! N(θ̂, J Σ J), Σ the covariance of (p̂, μ̂, ν̂) (`*_se²` on its diagonal)
//! and J = diag(1/(p(1−p)), 1/μ, 1/ν) the derivative of the transform (the
//! delta method), by its Cholesky factor. The maximum-likelihood estimator
//! is asymptotically normal with the inverse information as covariance, and
//! so is any smooth transform of it with the transformed covariance (the
//! MLE of θ is the transformed MLE); on the logit/log scale the normal law
//! keeps every draw in range (0 < ps < 1, rates > 0) and is closer to the
//! estimator's skewed law than on the natural scale. A leaf with halts
//! whose entry has no `cov:` (written by an older `btrel fit`) falls back
//! to the independent laws with the effective counts n = p(1 − p)/se²
//! (ps) and (rate/se)² (rates), and is named in [`Sampler::independent`].
//!
//! Each draw sets every fitted leaf's parameters (one draw per params key:
//! leaves sharing a key share it), runs the engine on the whole tree, and
//! the interval of each figure is the percentile interval of its draws.
//! Fixed times (`tau_s`, `tau_f`) and leaves without `fit:` statistics stay
//! fixed, and so does the ps of an action whose other outcome never happened
//! (it has no time for it); so do the laws of an auto fit without
//! `cov_theta:` (a params file from an older `btrel fit`) other than the
//! Erlang-type rates fitted without halts. [`Sampler::fixed`] and
//! [`Sampler::held`] list them.
//!
//! Draw `i` uses its own random stream (seeded from the seed and `i`), so
//! the intervals do not depend on the number of threads.
//!
//! Size: one concern, `--ci`'s parametric bootstrap: reading the fit statistics
//! and sampling leaf parameters from them (about 160 lines are comments, 80
//! tests).

use std::collections::BTreeMap;

use rand::SeedableRng;
use rand_distr::{Beta, Distribution, Exp, Gamma, StandardNormal};
use rand_xoshiro::Xoshiro256PlusPlus;
use rayon::prelude::*;
use serde::Deserialize;
use serde_saphyr::Spanned;

use crate::fit::covariance::{cholesky, cholesky_n, scale, Covariance, Matrix, NotPsd};
use crate::fit::information::{Laws, Outcome, Param};
use crate::fit::timing::Family;
use crate::tree::{Duration, NodeId, NodeKind, Tree};

/// Draws when none are asked for.
pub const DEFAULT_DRAWS: usize = 1000;
/// Seed when none is given.
pub const DEFAULT_SEED: u64 = 0x005E_EDC1;
/// Most draws × figures kept in memory at once (8 bytes each).
pub const MAX_VALUES: usize = 25_000_000;

/// One line of the method, for output headers.
pub const METHOD: &str =
    "parametric bootstrap: ps ~ Beta(s+1/2, f+1/2), rates ~ Gamma(events, exposure) \
(Erlang-k: Gamma(k events, exposure)), shifts ~ shortest time - Exp(n rate); with halts, and for \
hyperexponential laws: logit/ln parameters jointly normal with the fit's covariance; \
figures recomputed per draw, percentile intervals";

/// The `fit:` statistics of one params entry, as `btrel fit` writes them
/// (other keys are ignored).
#[derive(Clone, Debug, Default, PartialEq, Deserialize)]
pub struct FitStats {
    #[serde(default)]
    pub successes: Option<u64>,
    #[serde(default)]
    pub failures: Option<u64>,
    #[serde(default)]
    pub halted: Option<u64>,
    #[serde(default)]
    pub ps_se: Option<f64>,
    #[serde(default)]
    pub mu_se: Option<f64>,
    #[serde(default)]
    pub nu_se: Option<f64>,
    /// The covariances of (ps, mu, nu) off the diagonal, written for a leaf
    /// with halts ([`crate::fit::covariance`]).
    #[serde(default)]
    pub cov: Option<CovEntry>,
    /// The covariance of an auto fit's free parameters
    /// ([`crate::fit::information`]).
    #[serde(default)]
    pub cov_theta: Option<ThetaEntry>,
}

/// A `cov_theta: {params, matrix}` mapping and where it was written.
#[derive(Clone, Debug, PartialEq)]
pub struct ThetaEntry {
    pub params: Vec<String>,
    pub matrix: Vec<Vec<f64>>,
    pub line: usize,
    pub column: usize,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawTheta {
    params: Vec<String>,
    matrix: Vec<Vec<f64>>,
}

impl<'de> Deserialize<'de> for ThetaEntry {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let s = Spanned::<RawTheta>::deserialize(d)?;
        Ok(ThetaEntry {
            params: s.value.params,
            matrix: s.value.matrix,
            line: s.referenced.line() as usize,
            column: s.referenced.column() as usize,
        })
    }
}

impl ThetaEntry {
    /// The parameters and the matrix, checked: known names, each once, a
    /// square matrix of their number, a covariance (positive
    /// semidefinite).
    pub fn parsed(&self, key: &str) -> Result<(Vec<Param>, Vec<Vec<f64>>), String> {
        let mut params = Vec::new();
        for name in &self.params {
            let p = Param::parse(name).ok_or_else(|| {
                format!(
                    "`{key}`: `cov_theta` names an unknown parameter `{name}` (known: logit_ps, \
                     ln_<outcome>_rate, logit_<outcome>_p, ln_<outcome>_rate1, ln_<outcome>_rate2 \
                     with <outcome> success or failure)"
                )
            })?;
            if params.contains(&p) {
                return Err(format!("`{key}`: `cov_theta` names `{name}` twice"));
            }
            params.push(p);
        }
        let n = params.len();
        if self.matrix.len() != n || self.matrix.iter().any(|r| r.len() != n) {
            return Err(format!(
                "`{key}`: `cov_theta`'s matrix is not {n}×{n} (one row and one column per \
                 name in `params`)"
            ));
        }
        match cholesky_n(&self.matrix) {
            Ok(_) => Ok((params, self.matrix.clone())),
            Err(NotPsd::NotFinite) => Err(format!(
                "`{key}`: `cov_theta`'s matrix has a value that is not finite"
            )),
            Err(NotPsd::Block(_)) => Err(format!(
                "`{key}`: `cov_theta`'s matrix is not a covariance matrix (not positive \
                 semidefinite)"
            )),
        }
    }
}

/// A `cov: {ps_mu, ps_nu, mu_nu}` mapping and where it was written
/// (1-based line and column).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CovEntry {
    pub cov: Covariance,
    pub line: usize,
    pub column: usize,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawCov {
    ps_mu: f64,
    ps_nu: f64,
    mu_nu: f64,
}

impl<'de> Deserialize<'de> for CovEntry {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let s = Spanned::<RawCov>::deserialize(d)?;
        Ok(CovEntry {
            cov: Covariance {
                ps_mu: s.value.ps_mu,
                ps_nu: s.value.ps_nu,
                mu_nu: s.value.mu_nu,
            },
            line: s.referenced.line() as usize,
            column: s.referenced.column() as usize,
        })
    }
}

impl FitStats {
    /// The standard errors of (ps, mu, nu), when all three are positive.
    fn standard_errors(&self) -> Option<[f64; 3]> {
        let se = [self.ps_se?, self.mu_se?, self.nu_se?];
        se.iter().all(|x| x.is_finite() && *x > 0.0).then_some(se)
    }

    /// The full covariance matrix of (ps, mu, nu), when `cov` is given.
    pub fn matrix(&self) -> Option<Matrix> {
        Some(self.cov?.cov.matrix(self.standard_errors()?))
    }

    /// Checks `cov`: the standard errors it goes with are given, and the
    /// matrix they make is a covariance (positive semidefinite).
    fn check(&self, key: &str) -> Result<(), (CovEntry, String)> {
        let Some(c) = self.cov else { return Ok(()) };
        let Some(se) = self.standard_errors() else {
            return Err((
                c,
                format!(
                    "`{key}`: `cov` needs positive `ps_se`, `mu_se` and `nu_se` beside it \
                     (the variances of its matrix)"
                ),
            ));
        };
        let m = c.cov.matrix(se);
        match cholesky(&m) {
            Ok(_) => Ok(()),
            Err(NotPsd::NotFinite) => {
                Err((c, format!("`{key}`: `cov` has a value that is not finite")))
            }
            Err(NotPsd::Block(_)) => {
                let r = |a: f64, i: usize, j: usize| a / (se[i] * se[j]);
                Err((
                    c,
                    format!(
                        "`{key}`: `cov` with `ps_se`, `mu_se`, `nu_se` is not a covariance matrix \
                         (not positive semidefinite; correlations ps–mu {:.3}, ps–nu {:.3}, mu–nu {:.3})",
                        r(c.cov.ps_mu, 0, 1),
                        r(c.cov.ps_nu, 0, 2),
                        r(c.cov.mu_nu, 1, 2)
                    ),
                ))
            }
        }
    }
}

#[derive(Deserialize)]
struct Entry {
    #[serde(default)]
    fit: Option<FitStats>,
}

/// Reads the `fit:` statistics of a params file, by key. Entries without
/// `fit:` are left out. A `cov:` mapping that is malformed, lacks the
/// standard errors or is not positive semidefinite is an error at its
/// line and column.
pub fn read_fit_stats(text: &str, file: &str) -> Result<BTreeMap<String, FitStats>, String> {
    if text
        .lines()
        .all(|l| l.trim().is_empty() || l.trim_start().starts_with('#'))
    {
        return Ok(BTreeMap::new());
    }
    let entries: BTreeMap<String, Entry> = serde_saphyr::from_str(text).map_err(|e| {
        let at = e
            .location()
            .map_or(String::new(), |l| format!("{}:{}: ", l.line(), l.column()));
        format!(
            "{file}:{at}cannot read the `fit:` statistics: {}",
            e.without_snippet()
        )
    })?;
    let stats: BTreeMap<String, FitStats> = entries
        .into_iter()
        .filter_map(|(k, e)| e.fit.map(|f| (k, f)))
        .collect();
    for (k, st) in &stats {
        st.check(k)
            .map_err(|(c, msg)| format!("{file}:{}:{}: {msg}", c.line, c.column))?;
        if let Some(t) = &st.cov_theta {
            t.parsed(k)
                .map_err(|msg| format!("{file}:{}:{}: {msg}", t.line, t.column))?;
        }
    }
    Ok(stats)
}

/// The sampling distributions of one params key's parameters.
#[derive(Clone, Debug)]
struct Group {
    nodes: Vec<NodeId>,
    ps: Option<Beta<f64>>,
    mu: Option<Gamma<f64>>,
    nu: Option<Gamma<f64>>,
    /// (ps, mu, nu) drawn together, for a leaf with halts (module docs);
    /// then `ps`, `mu` and `nu` are None.
    joint: Option<Joint>,
    /// An auto-fitted action with `cov_theta`: its laws and how they are
    /// drawn (then `mu`, `nu` and `joint` are None).
    auto: Option<Auto>,
}

/// An auto-fitted action's laws and how each of their parameters is drawn
/// (module docs).
#[derive(Clone, Debug)]
struct Auto {
    laws: Laws,
    /// Parameters drawn from the normal law, its mean and the Cholesky
    /// factor of its covariance.
    normal: Vec<Param>,
    mean: Vec<f64>,
    factor: Vec<Vec<f64>>,
    /// Exact laws of the rates (no halts), per outcome.
    rates: [Option<Gamma<f64>>; 2],
    /// Completed durations of a shifted outcome: its shift is drawn from
    /// the pivot `δ̂ − δ ~ Exp(n·rate)`.
    shift_events: [Option<f64>; 2],
}

const OUTCOMES: [Outcome; 2] = [Outcome::Success, Outcome::Failure];

impl Auto {
    /// Whether `a` is an auto fit with a usable `cov_theta` (else the
    /// other rules apply), and then its draws; what stays fixed is pushed
    /// to `held`.
    fn new(
        name: &str,
        a: &crate::tree::Action,
        st: &FitStats,
        held: &mut Vec<String>,
    ) -> Option<(Option<Beta<f64>>, Auto)> {
        let (params, matrix) = st.cov_theta.as_ref()?.parsed(name).ok()?;
        let family = |d: Option<Duration>| match d {
            None => Some(None),
            Some(d) => Family::from_duration(&d).map(Some),
        };
        let laws = family(a.success)
            .zip(family(a.failure))
            .map(|(success, failure)| Laws {
                ps: a.ps,
                success,
                failure,
            })
            .filter(|laws| params.iter().all(|&p| laws.get(p).is_some()));
        let Some(laws) = laws else {
            held.push(format!(
                "{name}: `cov_theta` names parameters its times do not have (edited since the \
                 fit?): ignored, the times drawn as without it"
            ));
            return None;
        };
        let halted = st.halted.unwrap_or(0) > 0;
        let normal: Vec<Param> = params
            .iter()
            .copied()
            .filter(|p| halted || p.is_hyperexponential())
            .collect();
        let idx: Vec<usize> = normal
            .iter()
            .map(|p| params.iter().position(|q| q == p).unwrap_or(0))
            .collect();
        let block: Vec<Vec<f64>> = idx
            .iter()
            .map(|&i| idx.iter().map(|&j| matrix[i][j]).collect())
            .collect();
        let factor = cholesky_n(&block).ok()?;
        let mean = normal.iter().filter_map(|&p| laws.get(p)).collect();
        let both = laws.success.is_some() && laws.failure.is_some();
        let mut ps = None;
        if !both {
            let what = if laws.success.is_none() {
                "success"
            } else {
                "failure"
            };
            held.push(format!(
                "{name}: ps held at {} (no {what} was observed, so it has no time)",
                a.ps
            ));
        } else if !halted {
            ps = ps_law(a.ps, st);
        } else if !params.contains(&Param::LogitPs) {
            held.push(format!("{name}: ps held at {} (on its boundary)", a.ps));
        }
        let mut rates = [None, None];
        let mut shift_events = [None, None];
        for (k, o) in OUTCOMES.into_iter().enumerate() {
            let events = match o {
                Outcome::Success => st.successes,
                Outcome::Failure => st.failures,
            };
            let f = laws.side(o);
            if let Some(Family::Deterministic { .. }) = f {
                held.push(format!(
                    "{name}: fixed times held (its durations did not vary)"
                ));
            }
            if let Some(Family::ShiftedExponential { .. }) = f {
                shift_events[k] = events.filter(|&n| n > 0).map(|n| n as f64);
                if shift_events[k].is_none() {
                    held.push(format!("{name}: {} shift held (no count)", o.name()));
                }
            }
            if halted {
                continue;
            }
            let law = match f {
                Some(Family::Exponential { rate }) => Some(rate_law(rate, None, events)),
                Some(Family::ShiftedExponential { rate, .. }) => Some(erlang_law(1, rate, events)),
                Some(Family::Erlang { k, rate }) => Some(erlang_law(k, rate, events)),
                _ => None,
            };
            if let Some(law) = law {
                rates[k] = law;
                if rates[k].is_none() {
                    held.push(format!("{name}: {} rate held (no count)", o.name()));
                }
            }
        }
        Some((
            ps,
            Auto {
                laws,
                normal,
                mean,
                factor,
                rates,
                shift_events,
            },
        ))
    }

    /// The number of phase-type laws each draw makes.
    fn laws_drawn(&self) -> usize {
        OUTCOMES
            .into_iter()
            .filter(|&o| {
                matches!(
                    self.laws.side(o),
                    Some(
                        Family::ShiftedExponential { .. }
                            | Family::Erlang { .. }
                            | Family::Hyperexponential { .. }
                    )
                )
            })
            .count()
    }

    /// The number of parameters that vary.
    fn varied(&self) -> usize {
        self.normal.len()
            + self.rates.iter().flatten().count()
            + self.shift_events.iter().flatten().count()
    }

    /// One draw of the laws (`ps`: a drawn ps, if any).
    fn sample(&self, ps: Option<f64>, rng: &mut Xoshiro256PlusPlus) -> Laws {
        let mut laws = self.laws;
        if let Some(p) = ps {
            laws.ps = p;
        }
        for (o, law) in OUTCOMES.into_iter().zip(&self.rates) {
            if let Some(d) = law {
                let r: f64 = d.sample(rng);
                if r > 0.0 && r.is_finite() {
                    laws.set(Param::LnRate(o), r.ln());
                }
            }
        }
        if !self.normal.is_empty() {
            let z: Vec<f64> = (0..self.normal.len())
                .map(|_| StandardNormal.sample(rng))
                .collect();
            for (i, &p) in self.normal.iter().enumerate() {
                let x = self.mean[i] + (0..=i).map(|k| self.factor[i][k] * z[k]).sum::<f64>();
                laws.set(p, x);
            }
        }
        for (o, n) in OUTCOMES.into_iter().zip(self.shift_events) {
            let (Some(n), Some(Family::ShiftedExponential { shift, rate })) = (n, laws.side_mut(o))
            else {
                continue;
            };
            if let Ok(e) = Exp::new(n * *rate) {
                *shift = (*shift - e.sample(rng)).max(0.0);
            }
        }
        laws
    }
}

/// A normal law of (logit ps, ln mu, ln nu): its mean and the Cholesky
/// factor of its covariance.
#[derive(Clone, Copy, Debug)]
struct Joint {
    mean: [f64; 3],
    factor: Matrix,
}

impl Joint {
    /// From the estimates (p, μ, ν) and their covariance: the delta method
    /// through x ↦ (logit x₀, ln x₁, ln x₂), whose derivatives are
    /// 1/(p(1 − p)), 1/μ, 1/ν. None at p = 0 or 1 or a rate ≤ 0.
    fn new(p: f64, mu: f64, nu: f64, m: &Matrix) -> Option<Joint> {
        if !(p > 0.0 && p < 1.0 && mu > 0.0 && nu > 0.0) {
            return None;
        }
        let d = [1.0 / (p * (1.0 - p)), 1.0 / mu, 1.0 / nu];
        let factor = cholesky(&scale(m, d)).ok()?;
        Some(Joint {
            mean: [(p / (1.0 - p)).ln(), mu.ln(), nu.ln()],
            factor,
        })
    }

    /// One draw of (ps, mu, nu).
    fn sample(&self, rng: &mut Xoshiro256PlusPlus) -> (f64, f64, f64) {
        let z: [f64; 3] = std::array::from_fn(|_| StandardNormal.sample(rng));
        let x: [f64; 3] = std::array::from_fn(|i| {
            self.mean[i] + (0..=i).map(|k| self.factor[i][k] * z[k]).sum::<f64>()
        });
        (1.0 / (1.0 + (-x[0]).exp()), x[1].exp(), x[2].exp())
    }
}

/// Draws trees whose fitted parameters vary by their sampling
/// distributions (module docs).
#[derive(Clone, Debug)]
pub struct Sampler {
    base: Tree,
    groups: Vec<Group>,
    /// Leaves without `fit:` statistics (their names).
    pub fixed: Vec<String>,
    /// Parameters of fitted leaves that stay fixed, and why.
    pub held: Vec<String>,
    /// Leaves with halts whose `fit:` has no `cov:` (a params file from an
    /// older `btrel fit`): their ps, mu and nu are drawn independently.
    pub independent: Vec<String>,
    /// Phase-type times drawn per draw: each draw keeps one interned law
    /// for each ([`Sampler::kept_per_draw`]).
    law_draws: usize,
}

/// Beta(s + ½, f + ½) for ps = p, from the counts (or, with halts, from
/// the standard error).
fn ps_law(p: f64, st: &FitStats) -> Option<Beta<f64>> {
    let halted = st.halted.unwrap_or(0) > 0;
    let (s, f) = match (st.successes, st.failures, st.ps_se) {
        (_, _, Some(se))
            if (halted || st.successes.is_none()) && se > 0.0 && p > 0.0 && p < 1.0 =>
        {
            let n = p * (1.0 - p) / (se * se);
            (p * n, (1.0 - p) * n)
        }
        (Some(s), Some(f), _) if s + f > 0 => (s as f64, f as f64),
        _ => return None,
    };
    Beta::new(s + 0.5, f + 0.5).ok()
}

/// Gamma(n, n / rate) for a rate, n = (rate / se)² (the events, without
/// halts), or the count when there is no standard error.
fn rate_law(rate: f64, se: Option<f64>, events: Option<u64>) -> Option<Gamma<f64>> {
    let n = match (se, events) {
        (Some(se), _) if se > 0.0 && se.is_finite() => (rate / se).powi(2),
        (None, Some(k)) if k > 0 => k as f64,
        _ => return None,
    };
    if !(n.is_finite() && n > 0.0 && rate > 0.0) {
        return None;
    }
    Gamma::new(n, rate / n).ok()
}

fn rate_of(d: Option<Duration>) -> Option<f64> {
    match d? {
        Duration::Exponential { rate } | Duration::TruncatedExponential { rate, .. } => Some(rate),
        // the parameters of Erlang, hypoexponential and shifted times are
        // held (their fit statistics give no standard error per parameter)
        Duration::Fixed { .. } | Duration::PhaseType { .. } => None,
    }
}

/// `(k, rate)` of an Erlang-k time with or without a shift (a shifted
/// exponential is k = 1): one rate, drawn as `k·n` exponential stages.
fn erlang_of(d: Option<Duration>) -> Option<(u32, f64)> {
    match d? {
        Duration::PhaseType { stages, .. } => stages.as_erlang(),
        _ => None,
    }
}

/// Gamma(k·n, rate / (k·n)) for the rate of an Erlang-k time fitted to `n`
/// completed durations without halts: `rate · Σt ~ Gamma(k·n, 1)` exactly
/// (a sum of `k·n` unit exponential stages), so its percentile interval is
/// the exact pivotal one, as for an exponential rate (`k = 1`); the shift
/// of a shifted law is held (its error is of order `1/(n·rate)`, beside
/// the rate's `1/√n`).
fn erlang_law(k: u32, rate: f64, events: Option<u64>) -> Option<Gamma<f64>> {
    let n = events.filter(|&n| n > 0)? as f64 * f64::from(k);
    if !(rate > 0.0 && rate.is_finite()) {
        return None;
    }
    Gamma::new(n, rate / n).ok()
}

fn set_rate(d: &mut Option<Duration>, r: f64) {
    match d {
        Some(Duration::Exponential { rate } | Duration::TruncatedExponential { rate, .. }) => {
            *rate = r;
        }
        Some(Duration::PhaseType { shift, stages }) => {
            if let Some(k) = stages.as_erlang().map(|(k, _)| k) {
                if let Ok(erlang) = crate::tree::stages::Stages::erlang(k, r) {
                    *d = Some(Duration::phase_type(*shift, erlang));
                }
            }
        }
        _ => {}
    }
}

impl Sampler {
    /// `keys[id]` is the params key of node `id` (as
    /// [`crate::tree::xml::Keyed`] gives them); `stats` the file's `fit:`
    /// statistics by key.
    pub fn new(
        tree: &Tree,
        keys: &[Option<String>],
        stats: &BTreeMap<String, FitStats>,
    ) -> Sampler {
        let mut groups: Vec<Group> = Vec::new();
        let mut by_key: BTreeMap<&str, usize> = BTreeMap::new();
        let (mut fixed, mut held, mut independent) = (Vec::new(), Vec::new(), Vec::new());
        let mut law_draws = 0;
        for (id, node) in tree.nodes.iter().enumerate() {
            if !node.kind.children().is_empty() {
                continue;
            }
            let key = keys.get(id).and_then(|k| k.as_deref());
            let Some((key, st)) = key.and_then(|k| stats.get_key_value(k)) else {
                fixed.push(node.name.clone());
                continue;
            };
            if let Some(&g) = by_key.get(key.as_str()) {
                groups[g].nodes.push(id);
                continue;
            }
            let mut g = Group {
                nodes: vec![id],
                ps: None,
                mu: None,
                nu: None,
                joint: None,
                auto: None,
            };
            match &node.kind {
                NodeKind::Condition { ps } => g.ps = ps_law(*ps, st),
                NodeKind::Action(a) => {
                    if let Some((ps, auto)) = Auto::new(&node.name, a, st, &mut held) {
                        law_draws += auto.laws_drawn();
                        g.ps = ps;
                        g.auto = Some(auto);
                        by_key.insert(key.as_str(), groups.len());
                        groups.push(g);
                        continue;
                    }
                    let missing = match (a.success, a.failure) {
                        (Some(_), Some(_)) => None,
                        (None, _) => Some("success"),
                        (_, None) => Some("failure"),
                    };
                    match missing {
                        None => g.ps = ps_law(a.ps, st),
                        Some(what) => held.push(format!(
                            "{}: ps held at {} (no {what} was observed, so it has no time)",
                            node.name, a.ps
                        )),
                    }
                    let rates = rate_of(a.success).zip(rate_of(a.failure));
                    let joint = rates
                        .filter(|_| missing.is_none())
                        .zip(
                            st.matrix()
                                .filter(|_| st.cov.is_some_and(|c| !c.cov.is_zero())),
                        )
                        .and_then(|((mu, nu), m)| Joint::new(a.ps, mu, nu, &m));
                    if let Some(j) = joint {
                        g.ps = None;
                        g.joint = Some(j);
                        by_key.insert(key.as_str(), groups.len());
                        groups.push(g);
                        continue;
                    }
                    if rates.is_some() && missing.is_none() && st.halted.unwrap_or(0) > 0 {
                        independent.push(match st.cov {
                            None => format!(
                                "{}: ps, mu, nu drawn independently — its `fit:` counts halted \
                                 episodes but has no `cov:` (a params file from an older `btrel \
                                 fit`; fit again to draw them jointly)",
                                node.name
                            ),
                            Some(c) if c.cov.is_zero() => format!(
                                "{}: ps, mu, nu drawn independently (its `cov:` is zero)",
                                node.name
                            ),
                            Some(_) => format!(
                                "{}: ps, mu, nu drawn independently — its `cov:` does not fit its \
                                 values (ps = {} is not strictly between 0 and 1, or a rate is not \
                                 positive)",
                                node.name, a.ps
                            ),
                        });
                    }
                    if let Some(r) = rate_of(a.success) {
                        g.mu = rate_law(r, st.mu_se, st.successes.filter(|_| st.halted == Some(0)));
                        if g.mu.is_none() {
                            held.push(format!("{}: mu held (no standard error)", node.name));
                        }
                    }
                    if let Some(r) = rate_of(a.failure) {
                        g.nu = rate_law(r, st.nu_se, st.failures.filter(|_| st.halted == Some(0)));
                        if g.nu.is_none() {
                            held.push(format!("{}: nu held (no standard error)", node.name));
                        }
                    }
                    if matches!(a.success, Some(Duration::Fixed { .. }))
                        || matches!(a.failure, Some(Duration::Fixed { .. }))
                    {
                        held.push(format!("{}: fixed times held", node.name));
                    }
                    // Erlang-k and shifted exponential rates, fitted without
                    // halts: Gamma(k·n, …); other phase-type laws are held
                    let unhalted = st.halted == Some(0);
                    for (d, events, law) in [
                        (a.success, st.successes, &mut g.mu),
                        (a.failure, st.failures, &mut g.nu),
                    ] {
                        let Some(d @ Duration::PhaseType { .. }) = d else {
                            continue;
                        };
                        *law = erlang_of(Some(d))
                            .filter(|_| unhalted)
                            .and_then(|(k, r)| erlang_law(k, r, events));
                        law_draws += usize::from(law.is_some());
                        if law.is_none() {
                            let why = if unhalted || erlang_of(Some(d)).is_none() {
                                ""
                            } else {
                                " (its episodes were halted)"
                            };
                            held.push(format!("{}: {} time held{why}", node.name, d.family()));
                        }
                    }
                }
                _ => {}
            }
            by_key.insert(key.as_str(), groups.len());
            groups.push(g);
        }
        Sampler {
            base: tree.clone(),
            groups,
            fixed,
            held,
            independent,
            law_draws,
        }
    }

    /// Memory that each draw keeps for the rest of the process, in 8-byte
    /// values (to count with the figures against [`MAX_VALUES`]): a drawn
    /// phase-type time is an interned law of its own (a hyperexponential's
    /// with its matrix: counted as 16 more values).
    pub fn kept_per_draw(&self) -> usize {
        let per_law = (std::mem::size_of::<crate::tree::stages::Stages>()
            + std::mem::size_of::<crate::tree::stages::General>())
        .div_ceil(8)
            + 16;
        self.law_draws * per_law
    }

    /// Number of parameters that vary.
    pub fn varied(&self) -> usize {
        self.groups
            .iter()
            .map(|g| {
                usize::from(g.ps.is_some())
                    + usize::from(g.mu.is_some())
                    + usize::from(g.nu.is_some())
                    + 3 * usize::from(g.joint.is_some())
                    + g.auto.as_ref().map_or(0, Auto::varied)
            })
            .sum()
    }

    /// One tree with freshly drawn parameters.
    pub fn draw(&self, rng: &mut Xoshiro256PlusPlus) -> Tree {
        let mut tree = self.base.clone();
        for g in &self.groups {
            let ps = g.ps.map(|d| d.sample(rng).clamp(0.0, 1.0));
            let positive = |x: f64| {
                if x > 0.0 && x.is_finite() {
                    x
                } else {
                    f64::MIN_POSITIVE
                }
            };
            if let Some(au) = &g.auto {
                let laws = au.sample(ps, rng);
                for &id in &g.nodes {
                    if let NodeKind::Action(a) = &mut tree.nodes[id].kind {
                        a.ps = laws.ps;
                        a.pf = 1.0 - laws.ps;
                        a.success = laws.success.map(|f| f.duration());
                        a.failure = laws.failure.map(|f| f.duration());
                    }
                }
                continue;
            }
            let (ps, mu, nu) = match g.joint {
                Some(j) => {
                    let (p, m, n) = j.sample(rng);
                    (Some(p), Some(positive(m)), Some(positive(n)))
                }
                None => (
                    ps,
                    g.mu.map(|d| positive(d.sample(rng))),
                    g.nu.map(|d| positive(d.sample(rng))),
                ),
            };
            for &id in &g.nodes {
                match &mut tree.nodes[id].kind {
                    NodeKind::Condition { ps: p } => {
                        if let Some(x) = ps {
                            *p = x;
                        }
                    }
                    NodeKind::Action(a) => {
                        if let Some(x) = ps {
                            a.ps = x;
                            a.pf = 1.0 - x;
                        }
                        if let Some(r) = mu {
                            set_rate(&mut a.success, r);
                        }
                        if let Some(r) = nu {
                            set_rate(&mut a.failure, r);
                        }
                    }
                    _ => {}
                }
            }
        }
        tree
    }

    /// The `level` percentile intervals of the figures `figures(tree)`
    /// (`None` where undefined) over `draws` drawn trees, seeded by `seed`.
    /// An interval is `None` when the figure was undefined in every draw.
    pub fn intervals<E, F>(
        &self,
        level: f64,
        draws: usize,
        seed: u64,
        figures: F,
    ) -> Result<Vec<Option<(f64, f64)>>, E>
    where
        E: Send,
        F: Fn(&Tree) -> Result<Vec<Option<f64>>, E> + Sync,
    {
        let draws = if self.varied() == 0 { 1 } else { draws.max(1) };
        // undefined figures are kept as NaN (8 bytes a value, not 16)
        let rows: Vec<Vec<f64>> = (0..draws)
            .into_par_iter()
            .map(|i| {
                let mut rng = Xoshiro256PlusPlus::seed_from_u64(
                    seed ^ (i as u64 + 1).wrapping_mul(0x9E37_79B9_7F4A_7C15),
                );
                figures(&self.draw(&mut rng))
                    .map(|v| v.into_iter().map(|x| x.unwrap_or(f64::NAN)).collect())
            })
            .collect::<Result<_, E>>()?;
        let m = rows.first().map_or(0, Vec::len);
        let mut column = Vec::with_capacity(draws);
        Ok((0..m)
            .map(|j| {
                column.clear();
                column.extend(rows.iter().filter_map(|r| r.get(j).copied()));
                column.retain(|x| !x.is_nan());
                column.sort_by(f64::total_cmp);
                let alpha = (1.0 - level) / 2.0;
                (!column.is_empty())
                    .then(|| (quantile(&column, alpha), quantile(&column, 1.0 - alpha)))
            })
            .collect())
    }
}

/// The `q` quantile of sorted values (linear interpolation between order
/// statistics, Hyndman–Fan type 7).
pub fn quantile(sorted: &[f64], q: f64) -> f64 {
    let h = (sorted.len() - 1) as f64 * q.clamp(0.0, 1.0);
    let (lo, frac) = (h.floor() as usize, h - h.floor());
    match sorted.get(lo + 1) {
        Some(&next) if frac > 0.0 => sorted[lo] + frac * (next - sorted[lo]),
        _ => sorted[lo],
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quantiles() {
        let v = [1.0, 2.0, 3.0, 4.0, 5.0];
        assert_eq!(quantile(&v, 0.0), 1.0);
        assert_eq!(quantile(&v, 0.5), 3.0);
        assert_eq!(quantile(&v, 0.125), 1.5);
        assert_eq!(quantile(&v, 1.0), 5.0);
        assert_eq!(quantile(&[7.0], 0.3), 7.0);
    }

    #[test]
    fn laws_have_the_stated_moments() {
        // Beta(s + 1/2, f + 1/2): mean (s + 1/2) / (n + 1)
        let st = FitStats {
            successes: Some(30),
            failures: Some(10),
            halted: Some(0),
            ..Default::default()
        };
        let b = ps_law(0.75, &st).unwrap();
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(1);
        let n = 200_000;
        let mean: f64 = (0..n).map(|_| b.sample(&mut rng)).sum::<f64>() / n as f64;
        // sd of Beta(30.5, 10.5) = sqrt(ab/((a+b)^2 (a+b+1))) ~ 0.0668
        let sd = (30.5f64 * 10.5 / (41.0f64.powi(2) * 42.0)).sqrt();
        assert!(((mean - 30.5 / 41.0) / (sd / (n as f64).sqrt())).abs() < 5.0);
        // Gamma(n, n / rate): mean rate, sd rate / sqrt(n)
        let g = rate_law(2.0, Some(0.5), None).unwrap(); // n = 16
        let mean: f64 = (0..n).map(|_| g.sample(&mut rng)).sum::<f64>() / n as f64;
        assert!(((mean - 2.0) / (0.5 / (n as f64).sqrt())).abs() < 5.0);
    }

    #[test]
    fn joint_draws_have_the_delta_method_covariance() {
        // p = 0.7, mu = 0.5, nu = 1 with correlations -0.7, 0.9, -0.7
        let (p, mu, nu) = (0.7, 0.5, 1.0);
        let se = [0.05, 0.08, 0.2];
        let r = [[1.0, -0.7, 0.9], [-0.7, 1.0, -0.7], [0.9, -0.7, 1.0]];
        let m: Matrix = std::array::from_fn(|i| std::array::from_fn(|j| r[i][j] * se[i] * se[j]));
        let j = Joint::new(p, mu, nu, &m).unwrap();
        // by hand: d(logit p)/dp = 1/(0.7·0.3), d(ln mu)/dmu = 2, d(ln nu)/dnu = 1
        let d = [1.0 / 0.21, 2.0, 1.0];
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(9);
        let n = 200_000;
        let xs: Vec<[f64; 3]> = (0..n)
            .map(|_| {
                let (a, b, c) = j.sample(&mut rng);
                [(a / (1.0 - a)).ln(), b.ln(), c.ln()]
            })
            .collect();
        let centre = [(0.7f64 / 0.3).ln(), 0.5f64.ln(), 0.0];
        for i in 0..3 {
            let sd = se[i] * d[i];
            let mean = xs.iter().map(|x| x[i]).sum::<f64>() / n as f64;
            assert!(
                ((mean - centre[i]) / (sd / (n as f64).sqrt())).abs() < 5.0,
                "{i}"
            );
            for k in 0..3 {
                let c = xs
                    .iter()
                    .map(|x| (x[i] - centre[i]) * (x[k] - centre[k]))
                    .sum::<f64>()
                    / n as f64;
                let want = r[i][k] * sd * se[k] * d[k];
                // the sd of a product-moment estimate is below 2·sd_i·sd_k/√n
                let tol = 5.0 * 2.0 * sd * se[k] * d[k] / (n as f64).sqrt();
                assert!((c - want).abs() < tol, "{i}{k}: {c} vs {want}");
            }
        }
        // at the boundary there is no logit
        assert!(Joint::new(1.0, mu, nu, &m).is_none());
    }
}
