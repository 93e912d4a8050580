//! Estimating leaf parameters from logged episodes (`btrel fit`).
//!
//! # The model and its likelihood
//!
//! Under the SBT model an action first draws its outcome (Success with
//! probability p), then its duration: Exp(μ) after a Success draw, Exp(ν)
//! after a Failure draw. A log shows, per episode, either a completed
//! Success after t (likelihood `p μ e^{−μt}`), a completed Failure after t
//! (`(1−p) ν e^{−νt}`), or a halt after c — right-censored, the outcome
//! drawn but not seen: `p e^{−μc} + (1−p) e^{−νc}`. With n_s successes of
//! total time T_s, n_f failures of total time T_f and halts c_1..c_m:
//!
//! ```text
//! log L = n_s log p + n_f log(1−p) + n_s log μ − μ T_s + n_f log ν − ν T_f
//!         + Σ_j log(p e^{−μ c_j} + (1−p) e^{−ν c_j})
//! ```
//!
//! Without halts the maximum is closed: p = n_s/(n_s+n_f), μ = n_s/T_s,
//! ν = n_f/T_f. With halts it is found by EM: the E-step gives each halt the
//! posterior probability that it was a Success draw,
//! `w_j = p e^{−μc_j} / (p e^{−μc_j} + (1−p) e^{−νc_j})`, the M-step sets
//! p = (n_s + Σw)/(n_s+n_f+m), μ = n_s/(T_s + Σ w_j c_j),
//! ν = n_f/(T_f + Σ (1−w_j) c_j) — "events over the exposure of the episodes
//! that could still end that way". EM increases L at every step; it stops
//! when the parameters change by less than 1e-12 relative. When no episode
//! failed, the maximum is on the boundary p = 1 and μ = n_s/(T_s + Σ c_j)
//! (closed); likewise p = 0 when none succeeded.
//!
//! Standard errors are the square roots of the diagonal of the inverse
//! observed information (the negative Hessian of log L at the maximum,
//! computed analytically); with halts its off-diagonal entries, the
//! covariances of (p̂, μ̂, ν̂), are kept too ([`covariance`]), where the
//! matrix is positive definite. 95% intervals: p ± 1.96·se clipped to [0, 1]
//! (at p = 1 or 0 with n episodes, the exact Clopper–Pearson bound
//! 0.025^{1/n}); rates on the log scale, `rate·exp(±1.96·se/rate)`.
//!
//! Size: the leaf estimates and their params lines share the estimate types;
//! the likelihoods of timing families, the information matrix and the
//! covariances are in submodules.

use crate::logs::{Declared, End, Episode};

pub(crate) mod covariance;
pub(crate) mod information;
pub mod timing;

pub use covariance::Covariance;

/// Which timing families `fit` considers.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum TimingMode {
    /// Exponential times (deterministic when every duration of each outcome
    /// is one time): the book's model.
    #[default]
    Exponential,
    /// Per outcome: deterministic, exponential, shifted exponential or
    /// Erlang-k by BIC ([`timing`]).
    Auto,
}

/// z of a two-sided 95% interval.
pub(crate) const Z95: f64 = 1.959963984540054;
/// Figures resting on fewer episodes than this get a warning.
pub(crate) const FEW: usize = 30;
/// Deterministic timing: at least this many completed episodes of an
/// outcome, all within [`DET_SPREAD`] of their mean (or 2 µs).
pub(crate) const DET_MIN: usize = 3;
/// Relative spread (max − min over the mean) below which durations are one
/// fixed time.
pub const DET_SPREAD: f64 = 0.01;

/// Counts of one leaf's episodes.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Counts {
    pub successes: usize,
    pub failures: usize,
    pub halted: usize,
    pub instants: usize,
    /// Total seconds of the completed successes / failures.
    pub success_time: f64,
    pub failure_time: f64,
    /// Halt (censoring) times.
    pub censored: Vec<f64>,
    pub success_durations: Vec<f64>,
    pub failure_durations: Vec<f64>,
}

impl Counts {
    pub fn from_episodes<'a>(eps: impl IntoIterator<Item = &'a Episode>) -> Counts {
        let mut c = Counts::default();
        for e in eps {
            if e.instant {
                c.instants += 1;
            }
            match e.end {
                End::Success => {
                    c.successes += 1;
                    c.success_time += e.duration;
                    c.success_durations.push(e.duration);
                }
                End::Failure => {
                    c.failures += 1;
                    c.failure_time += e.duration;
                    c.failure_durations.push(e.duration);
                }
                End::Halted => {
                    c.halted += 1;
                    c.censored.push(e.duration);
                }
            }
        }
        c
    }
    pub fn episodes(&self) -> usize {
        self.successes + self.failures + self.halted
    }
}

/// An estimate with its standard error (None where it is undefined) and
/// 95% interval.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Estimate {
    pub value: f64,
    pub se: Option<f64>,
    pub ci95: (f64, f64),
}

/// The maximum-likelihood estimate of (p, μ, ν); a rate is None when its
/// outcome never completed.
#[derive(Clone, Debug, PartialEq)]
pub struct Mle {
    pub ps: Estimate,
    pub mu: Option<Estimate>,
    pub nu: Option<Estimate>,
    /// Covariances of the estimates, where halts couple them and the
    /// inverse information is positive definite (module docs).
    pub cov: Option<Covariance>,
    pub em_iterations: usize,
}

/// Maximum likelihood for exponential timing with censoring (module docs).
/// None when no episode completed (or a completed outcome has no exposure).
pub fn mle_exponential(c: &Counts) -> Option<Mle> {
    let (ns, nf) = (c.successes as f64, c.failures as f64);
    let cens_total: f64 = c.censored.iter().sum();
    if c.successes == 0 && c.failures == 0 {
        return None;
    }
    let rate_est = |rate: f64, n: f64| {
        let se = rate / n.sqrt();
        Estimate {
            value: rate,
            se: Some(se),
            ci95: log_ci(rate, se),
        }
    };
    if c.failures == 0 || c.successes == 0 {
        let (n, t) = if c.failures == 0 {
            (ns, c.success_time + cens_total)
        } else {
            (nf, c.failure_time + cens_total)
        };
        if t <= 0.0 {
            return None;
        }
        let rate = n / t;
        // boundary: the information for p is not defined; exact bound
        let bound = 0.025f64.powf(1.0 / (ns + nf).max(1.0));
        let ps = if c.failures == 0 {
            Estimate {
                value: 1.0,
                se: None,
                ci95: (bound, 1.0),
            }
        } else {
            Estimate {
                value: 0.0,
                se: None,
                ci95: (0.0, 1.0 - bound),
            }
        };
        let r = Some(rate_est(rate, n));
        return Some(if c.failures == 0 {
            Mle {
                ps,
                mu: r,
                nu: None,
                cov: None,
                em_iterations: 0,
            }
        } else {
            Mle {
                ps,
                mu: None,
                nu: r,
                cov: None,
                em_iterations: 0,
            }
        });
    }
    let m = c.censored.len() as f64;
    let mut p = ns / (ns + nf);
    let mut mu = ns / (c.success_time + p * cens_total);
    let mut nu = nf / (c.failure_time + (1.0 - p) * cens_total);
    if !(mu.is_finite() && nu.is_finite()) {
        return None;
    }
    let mut iterations = 0;
    if !c.censored.is_empty() {
        for it in 1..=200_000 {
            iterations = it;
            let (mut sw, mut swc, mut s1wc) = (0.0, 0.0, 0.0);
            for &cj in &c.censored {
                let w = posterior_success(p, mu, nu, cj);
                sw += w;
                swc += w * cj;
                s1wc += (1.0 - w) * cj;
            }
            let p2 = (ns + sw) / (ns + nf + m);
            let mu2 = ns / (c.success_time + swc);
            let nu2 = nf / (c.failure_time + s1wc);
            let change = ((p2 - p) / p)
                .abs()
                .max(((mu2 - mu) / mu).abs())
                .max(((nu2 - nu) / nu).abs());
            p = p2;
            mu = mu2;
            nu = nu2;
            if change < 1e-12 {
                break;
            }
        }
    }
    // observed information (negative Hessian) in (p, mu, nu)
    let mut h = [[0.0f64; 3]; 3];
    h[0][0] = ns / (p * p) + nf / ((1.0 - p) * (1.0 - p));
    h[1][1] = ns / (mu * mu);
    h[2][2] = nf / (nu * nu);
    for &cj in &c.censored {
        let a = (-mu * cj).exp();
        let b = (-nu * cj).exp();
        let g = p * a + (1.0 - p) * b;
        if g <= 0.0 {
            continue;
        }
        let gp = (a - b) / g;
        let gm = -p * cj * a / g;
        let gn = -(1.0 - p) * cj * b / g;
        // second derivatives of log g
        let hpp = -gp * gp;
        let hpm = -cj * a / g - gp * gm;
        let hpn = cj * b / g - gp * gn;
        let hmm = p * cj * cj * a / g - gm * gm;
        let hnn = (1.0 - p) * cj * cj * b / g - gn * gn;
        let hmn = -gm * gn;
        h[0][0] -= hpp;
        h[0][1] -= hpm;
        h[0][2] -= hpn;
        h[1][1] -= hmm;
        h[2][2] -= hnn;
        h[1][2] -= hmn;
    }
    h[1][0] = h[0][1];
    h[2][0] = h[0][2];
    h[2][1] = h[1][2];
    let cov = invert3(&h);
    let se = |i: usize| {
        cov.and_then(|c| {
            let v = c[i][i];
            (v.is_finite() && v > 0.0).then(|| v.sqrt())
        })
    };
    let ps_se = se(0);
    let ps = Estimate {
        value: p,
        se: ps_se,
        ci95: ps_se.map_or((0.0, 1.0), |s| {
            ((p - Z95 * s).max(0.0), (p + Z95 * s).min(1.0))
        }),
    };
    let rate = |r: f64, s: Option<f64>| Estimate {
        value: r,
        se: s,
        ci95: s.map_or((0.0, f64::INFINITY), |s| log_ci(r, s)),
    };
    // the joint covariance, where halts make it more than the diagonal and
    // it is a covariance (positive definite: a strict maximum)
    let joint = cov
        .filter(|m| !c.censored.is_empty() && covariance::positive_definite(m))
        .map(|m| Covariance::from_matrix(&m));
    Some(Mle {
        ps,
        mu: Some(rate(mu, se(1))),
        nu: Some(rate(nu, se(2))),
        cov: joint,
        em_iterations: iterations,
    })
}

/// P(Success draw | still running at c).
pub(crate) fn posterior_success(p: f64, mu: f64, nu: f64, c: f64) -> f64 {
    // p e^{-mu c} / (p e^{-mu c} + (1-p) e^{-nu c}), computed without underflow
    let d = (mu - nu) * c;
    if d >= 0.0 {
        let a = p * (-d).exp();
        a / (a + (1.0 - p))
    } else {
        let b = (1.0 - p) * d.exp();
        p / (p + b)
    }
}

fn log_ci(rate: f64, se: f64) -> (f64, f64) {
    let f = (Z95 * se / rate).exp();
    (rate / f, rate * f)
}

fn invert3(m: &[[f64; 3]; 3]) -> Option<[[f64; 3]; 3]> {
    let det = m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
        - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
        + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
    if !(det.is_finite() && det.abs() > 0.0) {
        return None;
    }
    let mut r = [[0.0; 3]; 3];
    for (i, row) in r.iter_mut().enumerate() {
        for (j, v) in row.iter_mut().enumerate() {
            let (a1, a2) = ((j + 1) % 3, (j + 2) % 3);
            let (b1, b2) = ((i + 1) % 3, (i + 2) % 3);
            *v = (m[a1][b1] * m[a2][b2] - m[a1][b2] * m[a2][b1]) / det;
        }
    }
    Some(r)
}

/// How a leaf's times were fitted.
#[derive(Clone, Debug, PartialEq)]
pub enum Timing {
    /// No RUNNING state: a condition (ps only).
    Condition,
    /// Every completed episode took (nearly) the same time per outcome.
    Deterministic {
        tau_s: Option<f64>,
        tau_f: Option<f64>,
    },
    Exponential {
        mu: Option<Estimate>,
        nu: Option<Estimate>,
        /// The covariances of (p̂, μ̂, ν̂), for a leaf with halts ([`Mle::cov`]).
        cov: Option<Covariance>,
        em_iterations: usize,
    },
    /// `--timing auto`: each outcome's family chosen by BIC, then fitted
    /// jointly ([`timing`]).
    Families {
        success: Option<timing::SideFit>,
        failure: Option<timing::SideFit>,
        em_iterations: usize,
        log_likelihood: f64,
        /// The covariance of the free parameters ([`information`]).
        cov: Option<information::ThetaCovariance>,
    },
}

/// One leaf's fitted parameters.
#[derive(Clone, Debug, PartialEq)]
pub struct LeafFit {
    pub key: String,
    pub counts: Counts,
    pub ps: Estimate,
    pub timing: Timing,
    /// Warnings about this leaf (few episodes, instants mixed with timed ones).
    pub warnings: Vec<String>,
    /// The index in `warnings` of the one saying that no `cov_theta` was
    /// written (the likelihood has no strict maximum): the leaf's times are
    /// then held fixed by the intervals drawn from the file.
    pub no_covariance: Option<usize>,
}

fn near_constant(d: &[f64]) -> Option<f64> {
    if d.len() < DET_MIN {
        return None;
    }
    let mean = d.iter().sum::<f64>() / d.len() as f64;
    let (lo, hi) = d
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &x| {
            (a.min(x), b.max(x))
        });
    (hi - lo <= (DET_SPREAD * mean).max(2e-6)).then_some(mean)
}

fn count_ps(c: &Counts) -> Estimate {
    let n = (c.successes + c.failures) as f64;
    let p = c.successes as f64 / n;
    if c.successes == 0 || c.failures == 0 {
        let bound = 0.025f64.powf(1.0 / n);
        return Estimate {
            value: p,
            se: None,
            ci95: if p == 1.0 {
                (bound, 1.0)
            } else {
                (0.0, 1.0 - bound)
            },
        };
    }
    let se = (p * (1.0 - p) / n).sqrt();
    Estimate {
        value: p,
        se: Some(se),
        ci95: ((p - Z95 * se).max(0.0), (p + Z95 * se).min(1.0)),
    }
}

/// Fits one leaf; None when no episode completed (only halts, or none).
pub fn fit_leaf(key: &str, declared: Declared, counts: Counts) -> Option<LeafFit> {
    fit_leaf_with(key, declared, counts, TimingMode::Exponential)
}

/// `log(p e^{a} + (1−p) e^{b})` without underflow (`a`, `b` log survivals).
fn log_mix(p: f64, a: f64, b: f64) -> f64 {
    let x = if p > 0.0 {
        p.ln() + a
    } else {
        f64::NEG_INFINITY
    };
    let y = if p < 1.0 {
        (1.0 - p).ln() + b
    } else {
        f64::NEG_INFINITY
    };
    let m = x.max(y);
    if m == f64::NEG_INFINITY {
        return m;
    }
    m + ((x - m).exp() + (y - m).exp()).ln()
}

/// `--timing auto` for a leaf whose episodes are not all instants: the
/// families by BIC, then the joint EM ([`timing`] module docs).
fn fit_families(
    counts: &Counts,
    warnings: &mut Vec<String>,
    no_covariance: &mut Option<usize>,
) -> Option<(Estimate, Timing)> {
    use timing::{choose, refit, Side};
    let m = mle_exponential(counts)?;
    let n = counts.episodes() as f64;
    let (ns, nf) = (counts.successes as f64, counts.failures as f64);
    let mut p = m.ps.value;
    let mut w: Vec<f64> = match (m.mu, m.nu) {
        (Some(mu), Some(nu)) => counts
            .censored
            .iter()
            .map(|&c| posterior_success(p, mu.value, nu.value, c))
            .collect(),
        _ => vec![p; counts.censored.len()],
    };
    let wf: Vec<f64> = w.iter().map(|x| 1.0 - x).collect();
    let success = choose(
        &Side {
            events: &counts.success_durations,
            censored: &counts.censored,
            weights: &w,
        },
        n,
        near_constant(&counts.success_durations),
    );
    let failure = choose(
        &Side {
            events: &counts.failure_durations,
            censored: &counts.censored,
            weights: &wf,
        },
        n,
        near_constant(&counts.failure_durations),
    );
    // an outcome whose completed episodes have no exposure of their own
    // (instants, every halt weighed to the other outcome): the exponential
    // maximum of the whole likelihood
    let fallback = |rate: Option<Estimate>, done: usize| {
        (done > 0).then_some(()).and(rate).map(|r| timing::SideFit {
            family: timing::Family::Exponential { rate: r.value },
            candidates: Vec::new(),
            ks: None,
        })
    };
    let success = success.or_else(|| fallback(m.mu, counts.successes));
    let failure = failure.or_else(|| fallback(m.nu, counts.failures));
    if counts.instants > 0 {
        warnings.push(format!(
            "{} of its {} completed episodes returned instantly (no RUNNING state); \
             no family fitted here has instants, so its rates are too high",
            counts.instants,
            counts.successes + counts.failures
        ));
    }
    for (fit, what, done) in [
        (&success, "success", counts.successes),
        (&failure, "failure", counts.failures),
    ] {
        if let Some(f) = fit {
            if f.candidates.is_empty()
                && done < timing::FAMILY_MIN
                && !matches!(f.family, timing::Family::Deterministic { .. })
            {
                warnings.push(format!(
                    "the {what} time's family was not chosen: {done} completed {what} episode{} \
                     (fewer than {}); exponential kept",
                    if done == 1 { "" } else { "s" },
                    timing::FAMILY_MIN
                ));
            }
        }
    }
    let (mut fs, mut ff) = (
        success.as_ref().map(|f| f.family),
        failure.as_ref().map(|f| f.family),
    );
    // joint EM over the halts under the chosen families
    let log_sf = |f: &Option<timing::Family>, c: f64| f.map_or(f64::NEG_INFINITY, |f| f.log_sf(c));
    let mut iterations = 0;
    if !counts.censored.is_empty() {
        for it in 1..=10_000 {
            iterations = it;
            for (j, &c) in counts.censored.iter().enumerate() {
                let (a, b) = (log_sf(&fs, c), log_sf(&ff, c));
                let mix = log_mix(p, a, b);
                w[j] = if mix == f64::NEG_INFINITY {
                    p
                } else if p > 0.0 {
                    (p.ln() + a - mix).exp()
                } else {
                    0.0
                };
            }
            let sw: f64 = w.iter().sum();
            let p2 = (ns + sw) / n;
            let wf: Vec<f64> = w.iter().map(|x| 1.0 - x).collect();
            let fs2 = fs.and_then(|f| {
                refit(
                    &Side {
                        events: &counts.success_durations,
                        censored: &counts.censored,
                        weights: &w,
                    },
                    &f,
                )
            });
            let ff2 = ff.and_then(|f| {
                refit(
                    &Side {
                        events: &counts.failure_durations,
                        censored: &counts.censored,
                        weights: &wf,
                    },
                    &f,
                )
            });
            let rate = |f: &Option<timing::Family>| match f {
                Some(
                    timing::Family::Exponential { rate }
                    | timing::Family::ShiftedExponential { rate, .. }
                    | timing::Family::Erlang { rate, .. }
                    | timing::Family::Hyperexponential { rate1: rate, .. },
                ) => *rate,
                _ => 1.0,
            };
            let change = ((p2 - p) / p.max(1e-300))
                .abs()
                .max(((rate(&fs2) - rate(&fs)) / rate(&fs)).abs())
                .max(((rate(&ff2) - rate(&ff)) / rate(&ff)).abs());
            p = p2;
            fs = fs2.or(fs);
            ff = ff2.or(ff);
            if change < 1e-12 {
                break;
            }
        }
    }
    let laws = information::Laws {
        ps: p,
        success: fs,
        failure: ff,
    };
    let ll = laws.log_likelihood(counts);
    let cov = information::covariance(counts, &laws);
    if cov.is_none() && !laws.params().is_empty() {
        *no_covariance = Some(warnings.len());
        warnings.push(
            "its likelihood has no strict maximum here (the observed information is not positive \
             definite): no `cov_theta` written"
                .to_string(),
        );
    }
    let with = |fit: Option<timing::SideFit>, f: Option<timing::Family>| {
        fit.map(|mut s| {
            if let Some(f) = f {
                s.family = f;
            }
            s
        })
    };
    // with halts: ps's standard error from the joint information (delta
    // method from logit ps), else the binomial one of the completed episodes
    let completed = ns + nf;
    let se = cov
        .as_ref()
        .filter(|c| c.params.first() == Some(&information::Param::LogitPs))
        .map_or((p * (1.0 - p) / completed).sqrt(), |c| {
            p * (1.0 - p) * c.matrix[0][0].sqrt()
        });
    let ps = if counts.censored.is_empty() || p == 0.0 || p == 1.0 {
        count_ps(counts)
    } else {
        Estimate {
            value: p,
            se: Some(se),
            ci95: ((p - Z95 * se).max(0.0), (p + Z95 * se).min(1.0)),
        }
    };
    Some((
        ps,
        Timing::Families {
            success: with(success, fs),
            failure: with(failure, ff),
            em_iterations: iterations,
            log_likelihood: ll,
            cov,
        },
    ))
}

/// Fits one leaf with the timing families of `mode`; None when no episode
/// completed (only halts, or none).
pub fn fit_leaf_with(
    key: &str,
    declared: Declared,
    counts: Counts,
    mode: TimingMode,
) -> Option<LeafFit> {
    if counts.successes + counts.failures == 0 {
        return None;
    }
    let mut warnings = Vec::new();
    let mut no_covariance = None;
    let completed = counts.successes + counts.failures;
    let all_instant = counts.instants == completed && counts.halted == 0;
    let (ps, timing) = if all_instant && declared != Declared::Action {
        (count_ps(&counts), Timing::Condition)
    } else if all_instant {
        (
            count_ps(&counts),
            Timing::Deterministic {
                tau_s: (counts.successes > 0).then_some(0.0),
                tau_f: (counts.failures > 0).then_some(0.0),
            },
        )
    } else if mode == TimingMode::Auto {
        fit_families(&counts, &mut warnings, &mut no_covariance)?
    } else {
        let ds = near_constant(&counts.success_durations);
        let df = near_constant(&counts.failure_durations);
        let det = match (counts.successes, counts.failures) {
            (_, 0) => ds.map(|s| (Some(s), None)),
            (0, _) => df.map(|f| (None, Some(f))),
            _ => ds.zip(df).map(|(s, f)| (Some(s), Some(f))),
        };
        if let Some((tau_s, tau_f)) = det {
            (count_ps(&counts), Timing::Deterministic { tau_s, tau_f })
        } else {
            let m = mle_exponential(&counts)?;
            if counts.instants > 0 {
                warnings.push(format!(
                    "{} of its {} completed episodes returned instantly (no RUNNING state); \
                     the exponential model has no instants, so its rates are too high",
                    counts.instants, completed
                ));
            }
            (
                m.ps,
                Timing::Exponential {
                    mu: m.mu,
                    nu: m.nu,
                    cov: m.cov,
                    em_iterations: m.em_iterations,
                },
            )
        }
    };
    if counts.episodes() < FEW {
        warnings.push(format!(
            "ps rests on {} episode{} (fewer than {FEW}): its interval is rough",
            counts.episodes(),
            if counts.episodes() == 1 { "" } else { "s" }
        ));
    }
    if let Timing::Exponential { mu, nu, .. } = &timing {
        if mu.is_some() && counts.successes < FEW {
            warnings.push(format!(
                "mu rests on {} completed success{} (fewer than {FEW})",
                counts.successes,
                if counts.successes == 1 { "" } else { "es" }
            ));
        }
        if nu.is_some() && counts.failures < FEW {
            warnings.push(format!(
                "nu rests on {} completed failure{} (fewer than {FEW})",
                counts.failures,
                if counts.failures == 1 { "" } else { "s" }
            ));
        }
    }
    Some(LeafFit {
        key: key.to_string(),
        counts,
        ps,
        timing,
        warnings,
        no_covariance,
    })
}

fn num(x: f64) -> String {
    if x == f64::NEG_INFINITY {
        return "-.inf".into();
    }
    if x.is_nan() {
        return ".nan".into();
    }
    if x.is_finite() {
        let s = format!("{x}");
        if s.contains(['.', 'e']) {
            s
        } else {
            format!("{s}.0")
        }
    } else {
        ".inf".into()
    }
}

fn est_fields(out: &mut String, name: &str, e: &Estimate) {
    if let Some(se) = e.se {
        out.push_str(&format!(", {name}_se: {}", num(se)));
    }
    out.push_str(&format!(
        ", {name}_ci95: [{}, {}]",
        num(e.ci95.0),
        num(e.ci95.1)
    ));
}

/// One params-file line for a leaf: the parameters, then a `fit:` mapping
/// with counts, standard errors, intervals and, for an exponential leaf with
/// halts, the covariances `cov: {ps_mu, ps_nu, mu_nu}` (ignored by the
/// analysis; `--ci` reads them).
pub fn params_line(f: &LeafFit) -> String {
    let key = serde_json::to_string(&f.key).unwrap_or_else(|_| format!("{:?}", f.key));
    let mut s = format!("{key}: {{ps: {}", num(f.ps.value));
    let c = &f.counts;
    let mut stats = format!(
        "episodes: {}, successes: {}, failures: {}, halted: {}, instants: {}",
        c.episodes(),
        c.successes,
        c.failures,
        c.halted,
        c.instants
    );
    match &f.timing {
        Timing::Condition => {}
        Timing::Deterministic { tau_s, tau_f } => {
            if let Some(t) = tau_s {
                s.push_str(&format!(", tau_s: {}", num(*t)));
            }
            if let Some(t) = tau_f {
                s.push_str(&format!(", tau_f: {}", num(*t)));
            }
            stats.push_str(", timing: deterministic");
        }
        Timing::Families {
            success,
            failure,
            log_likelihood,
            cov,
            ..
        } => {
            families_fields(&mut s, &mut stats, success, failure);
            stats.push_str(&format!(
                ", timing: auto, log_likelihood: {}",
                num(*log_likelihood)
            ));
            if let Some(c) = cov {
                let names: Vec<String> = c.params.iter().map(|p| p.name()).collect();
                let rows: Vec<String> = c
                    .matrix
                    .iter()
                    .map(|r| {
                        let v: Vec<String> = r.iter().map(|&x| num(x)).collect();
                        format!("[{}]", v.join(", "))
                    })
                    .collect();
                stats.push_str(&format!(
                    ", cov_theta: {{params: [{}], matrix: [{}]}}",
                    names.join(", "),
                    rows.join(", ")
                ));
            }
        }
        Timing::Exponential { mu, nu, .. } => {
            if let Some(m) = mu {
                s.push_str(&format!(", mu: {}", num(m.value)));
            }
            if let Some(n) = nu {
                s.push_str(&format!(", nu: {}", num(n.value)));
            }
            stats.push_str(&format!(
                ", timing: exponential, exposure_s: {}",
                num(c.success_time + c.failure_time + c.censored.iter().sum::<f64>())
            ));
        }
    }
    est_fields(&mut stats, "ps", &f.ps);
    if let Timing::Exponential { mu, nu, cov, .. } = &f.timing {
        if let Some(m) = mu {
            est_fields(&mut stats, "mu", m);
        }
        if let Some(n) = nu {
            est_fields(&mut stats, "nu", n);
        }
        if let Some(c) = cov {
            stats.push_str(&format!(
                ", cov: {{ps_mu: {}, ps_nu: {}, mu_nu: {}}}",
                num(c.ps_mu),
                num(c.ps_nu),
                num(c.mu_nu)
            ));
        }
    }
    s.push_str(&format!(", fit: {{{stats}}}}}"));
    s
}

/// The times and statistics of a `--timing auto` fit: `mu`/`nu` when both
/// outcomes are exponential, `tau_s`/`tau_f` when both are deterministic,
/// else `success_time`/`failure_time` for both (mixture semantics, never
/// the hybrid race of `mu` + `tau_f`).
fn families_fields(
    s: &mut String,
    stats: &mut String,
    success: &Option<timing::SideFit>,
    failure: &Option<timing::SideFit>,
) {
    use timing::Family;
    let sides = [
        (success, "success", "mu", "tau_s"),
        (failure, "failure", "nu", "tau_f"),
    ];
    let present = || sides.iter().filter_map(|(f, ..)| f.as_ref());
    let all_exp = present().all(|f| matches!(f.family, Family::Exponential { .. }));
    let all_det = present().all(|f| matches!(f.family, Family::Deterministic { .. }));
    for (fit, what, rate_key, tau_key) in sides {
        let Some(f) = fit else { continue };
        match f.family {
            Family::Exponential { rate } if all_exp => {
                s.push_str(&format!(", {rate_key}: {}", num(rate)))
            }
            Family::Deterministic { time } if all_det => {
                s.push_str(&format!(", {tau_key}: {}", num(time)))
            }
            family => s.push_str(&format!(", {what}_time: {}", family.duration().to_yaml())),
        }
        let name = serde_json::to_string(&f.family.name()).unwrap_or_default();
        stats.push_str(&format!(", {what}_family: {name}"));
        if let Some(best) = f.candidates.first() {
            stats.push_str(&format!(", {what}_bic: {}", num(best.bic)));
            if let Some(e) = f
                .candidates
                .iter()
                .find(|c| matches!(c.family, Family::Exponential { .. }))
            {
                stats.push_str(&format!(", {what}_bic_exponential: {}", num(e.bic)));
            }
        }
        if let Some(ks) = f.ks {
            stats.push_str(&format!(
                ", {what}_ks_d: {}, {what}_ks_stephens: {}, {what}_exponential_rejected_5pct: {}",
                num(ks.d),
                num(ks.modified),
                ks.rejected
            ));
        }
    }
}

/// How leaves are keyed (and pooled) in the params file.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum By {
    /// By registration ID: all nodes of one ID share one entry.
    Id,
    /// By the node's `name` attribute (the ID where it has none).
    Name,
}

/// The fit of several logs.
#[derive(Clone, Debug)]
pub struct Fitted {
    /// Fitted leaves, in order of first appearance.
    pub leaves: Vec<LeafFit>,
    /// Keys whose leaves have no completed episode (not written).
    pub unfitted: Vec<(String, Counts)>,
    /// Per file: (file, records, leaf episodes).
    pub files: Vec<(String, usize, usize)>,
    /// Per file with records out of time order: (file, how many, the
    /// largest step back in seconds).
    pub out_of_order: Vec<(String, usize, f64)>,
    /// Per file whose last records repeated the block before them (dropped):
    /// (file, how many).
    pub repeated_tail: Vec<(String, usize)>,
}

/// Pools the logs' leaves by key and fits each. Errors when one name is
/// used by leaves of different IDs (`By::Name`).
pub fn fit_logs(logs: &[crate::logs::Log], by: By) -> Result<Fitted, String> {
    fit_logs_with(logs, by, TimingMode::Exponential)
}

/// [`fit_logs`] with the timing families of `mode`.
pub fn fit_logs_with(
    logs: &[crate::logs::Log],
    by: By,
    mode: TimingMode,
) -> Result<Fitted, String> {
    let mut order: Vec<String> = Vec::new();
    let mut pooled: std::collections::HashMap<String, (Declared, String, Vec<Episode>)> =
        std::collections::HashMap::new();
    let mut files = Vec::new();
    let mut out_of_order = Vec::new();
    let mut repeated_tail = Vec::new();
    for log in logs {
        let mut n = 0;
        for leaf in &log.leaves {
            n += leaf.episodes.len();
            let key = match by {
                By::Id => leaf.id.clone(),
                By::Name => leaf.name.clone().unwrap_or_else(|| leaf.id.clone()),
            };
            let entry = pooled.entry(key.clone()).or_insert_with(|| {
                order.push(key.clone());
                (leaf.declared, leaf.id.clone(), Vec::new())
            });
            if entry.1 != leaf.id {
                return Err(format!(
                    "{}: the name `{key}` is used by nodes of two IDs, `{}` and `{}`: \
                     their parameters cannot be pooled under one key",
                    log.file, entry.1, leaf.id
                ));
            }
            if entry.0 == Declared::Unknown {
                entry.0 = leaf.declared;
            }
            entry.2.extend_from_slice(&leaf.episodes);
        }
        files.push((log.file.clone(), log.records, n));
        if log.out_of_order > 0 {
            out_of_order.push((log.file.clone(), log.out_of_order, log.max_step_back));
        }
        if log.repeated_tail > 0 {
            repeated_tail.push((log.file.clone(), log.repeated_tail));
        }
    }
    let mut leaves = Vec::new();
    let mut unfitted = Vec::new();
    for key in order {
        let Some((declared, _, eps)) = pooled.remove(&key) else {
            continue;
        };
        let counts = Counts::from_episodes(&eps);
        match fit_leaf_with(&key, declared, counts.clone(), mode) {
            Some(f) => leaves.push(f),
            None => unfitted.push((key, counts)),
        }
    }
    Ok(Fitted {
        leaves,
        unfitted,
        files,
        out_of_order,
        repeated_tail,
    })
}

/// The params file text: a comment header naming the logs and their
/// episode counts, then one line per fitted leaf.
pub fn render(f: &Fitted, by: By) -> String {
    let mut s = String::new();
    s.push_str(&format!(
        "# btrel fit: leaf parameters estimated from {} log file{}, keyed by {}\n",
        f.files.len(),
        if f.files.len() == 1 { "" } else { "s" },
        match by {
            By::Id => "ID",
            By::Name => "name",
        }
    ));
    for (file, records, eps) in &f.files {
        s.push_str(&format!(
            "#   {file}: {records} records, {eps} leaf episodes\n"
        ));
    }
    for (file, n, back) in &f.out_of_order {
        s.push_str(&format!(
            "#   {file}: {n} of them out of time order by up to {:.3} ms, kept as logged\n",
            back * 1e3
        ));
    }
    for (file, n) in &f.repeated_tail {
        s.push_str(&format!(
            "#   {file}: its last {n} records repeated the {n} before them byte for byte \
             (the logger wrote its last batch twice) and were dropped\n"
        ));
    }
    let auto = f
        .leaves
        .iter()
        .any(|l| matches!(l.timing, Timing::Families { .. }));
    if auto {
        s.push_str(
            "# timing: per outcome deterministic, exponential, shifted exponential, Erlang-k or\n\
             # hyperexponential-2 by BIC, maximum likelihood with halted episodes censored;\n\
             # `fit:` holds counts, the families compared, standard errors and 95% intervals\n\
             # (ignored by the analysis), and `cov_theta:` the covariance of the free\n\
             # parameters on the logit/ln scale (inverse observed information), from which the\n\
             # parametric bootstrap of the figures' intervals draws\n",
        );
    } else {
        s.push_str(
            "# timing: exponential rates by maximum likelihood with halted episodes censored;\n\
             # `fit:` holds counts, standard errors and 95% intervals (ignored by the analysis)\n",
        );
    }
    if f.leaves
        .iter()
        .any(|l| matches!(l.timing, Timing::Exponential { cov: Some(_), .. }))
    {
        s.push_str(
            "# `cov:` (leaves with halts): covariances of the estimates of ps, mu and nu, which\n\
             # halted episodes correlate; the bootstrap of the intervals draws the three jointly\n",
        );
    }
    for (key, c) in &f.unfitted {
        s.push_str(&format!(
            "# not fitted: {key} ({} episodes, none completed)\n",
            c.episodes()
        ));
    }
    for l in &f.leaves {
        s.push_str(&params_line(l));
        s.push('\n');
    }
    s
}
