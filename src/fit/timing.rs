//! `btrel fit --timing auto`: the family of each outcome's duration.
//!
//! For each outcome (Success, Failure) of a leaf the candidates are
//!
//! * **deterministic** — chosen, without likelihood, when the completed
//!   durations are one time within [`super::DET_SPREAD`] (as `--timing
//!   exponential` does; a point mass has no density to compare);
//! * **exponential** `Exp(λ)` (1 parameter);
//! * **shifted exponential** `δ + Exp(λ)` (2 parameters; `δ̂` is the
//!   shortest completed duration, the maximum of the likelihood);
//! * **Erlang-k** `Gamma(k, λ)`, `k = 2..=`[`MAX_K`] by profile likelihood
//!   (2 parameters, k and λ; k = 1 is the exponential);
//! * **hyperexponential-2** `p·Exp(λ₁) + (1−p)·Exp(λ₂)` (3 parameters), the
//!   phase-type law of bimodal durations (a fast and a slow mode), by EM
//!   ([`fit_hyperexponential`]: the E-step splits each duration, and each
//!   halt, between the modes; the M-step is the exponential's events over
//!   exposure per mode), from a few starts, the best likelihood kept;
//!
//! and the one of least **BIC** = `−2 log L + params · ln n` is kept, `n`
//! the leaf's episodes (completed and halted). BIC rather than AIC: it
//! penalises the extra parameter by `ln n` instead of 2, so an
//! exponential sample keeps its family more often (the shift, fitted at the
//! shortest duration, always raises the likelihood a little).
//!
//! **Censoring.** A halted episode after `c` contributes `log(p S_s(c) +
//! (1−p) S_f(c))` to the leaf's likelihood (`S` the survival functions):
//! the outcome was drawn but not seen. The selection treats each outcome
//! separately, a halt entering the Success part as `w log S_s(c)` and the
//! Failure part as `(1−w) log S_f(c)`, `w` its posterior probability of a
//! Success draw under the exponential fit (exact when no episode was
//! halted: the likelihood then separates). The chosen pair of families is
//! then fitted jointly by EM (the E-step recomputes `w` under the chosen
//! families, the M-step refits each family to its weighted data) and the
//! joint log-likelihood is reported.
//!
//! **Goodness of fit of the exponential.** Per outcome, the
//! Kolmogorov–Smirnov distance `D` between the completed durations and the
//! fitted exponential, and Stephens' modified statistic `(D − 0.2/n)(√n +
//! 0.26 + 0.5/√n)` for an estimated rate, whose 5% critical value is 1.094
//! (Stephens 1974). Computed only when no episode was halted (the completed
//! durations are then a sample of the outcome's law; with halts they are
//! biased short).
//!
//! An outcome with fewer than [`FAMILY_MIN`] completed episodes keeps the
//! exponential (or deterministic) family, with a warning.

use crate::tree::{Duration, Stages};

/// Largest Erlang k tried.
pub const MAX_K: u32 = 20;
/// Fewest completed episodes of an outcome for its family to be chosen.
pub const FAMILY_MIN: usize = 10;
/// Stephens' 5% critical value of the modified KS statistic (exponential,
/// estimated rate).
pub(crate) const KS_CRITICAL_5: f64 = 1.094;

/// A fitted duration law.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Family {
    Deterministic {
        time: f64,
    },
    Exponential {
        rate: f64,
    },
    ShiftedExponential {
        shift: f64,
        rate: f64,
    },
    Erlang {
        k: u32,
        rate: f64,
    },
    /// `p·Exp(rate1) + (1−p)·Exp(rate2)`, `rate1 > rate2`.
    Hyperexponential {
        p: f64,
        rate1: f64,
        rate2: f64,
    },
}

impl Family {
    /// The family a leaf's duration is written as, when it is one of the
    /// families fitted here ([`Family::duration`] back; a lone Erlang stage
    /// is the exponential).
    pub fn from_duration(d: &Duration) -> Option<Family> {
        match *d {
            Duration::Exponential { rate } => Some(Family::Exponential { rate }),
            Duration::Fixed { time } => Some(Family::Deterministic { time }),
            Duration::TruncatedExponential { .. } => None,
            Duration::PhaseType { shift, stages } => {
                if let Some((k, rate)) = stages.as_erlang() {
                    return match (k, shift > 0.0) {
                        (1, true) => Some(Family::ShiftedExponential { shift, rate }),
                        (1, false) => Some(Family::Exponential { rate }),
                        (_, false) => Some(Family::Erlang { k, rate }),
                        (_, true) => None,
                    };
                }
                let [a, b] = stages.as_two_branches().filter(|_| shift == 0.0)?;
                let ((p, rate1), (_, rate2)) = if a.1 >= b.1 { (a, b) } else { (b, a) };
                Some(Family::Hyperexponential { p, rate1, rate2 })
            }
        }
    }

    /// Free parameters (for BIC).
    pub fn parameters(&self) -> usize {
        match self {
            Family::Deterministic { .. } | Family::Exponential { .. } => 1,
            Family::ShiftedExponential { .. } | Family::Erlang { .. } => 2,
            Family::Hyperexponential { .. } => 3,
        }
    }

    /// The family's name in the params file's `fit:` statistics.
    pub fn name(&self) -> String {
        match self {
            Family::Deterministic { .. } => "deterministic".into(),
            Family::Exponential { .. } => "exponential".into(),
            Family::ShiftedExponential { .. } => "shifted exponential".into(),
            Family::Erlang { k, .. } => format!("Erlang-{k}"),
            Family::Hyperexponential { .. } => "hyperexponential-2".into(),
        }
    }

    /// The law as a leaf's duration.
    pub fn duration(&self) -> Duration {
        match *self {
            Family::Deterministic { time } => Duration::Fixed { time },
            Family::Exponential { rate } => Duration::Exponential { rate },
            Family::ShiftedExponential { shift, rate } => match Stages::erlang(1, rate) {
                Ok(s) => Duration::phase_type(shift, s),
                Err(_) => Duration::Exponential { rate },
            },
            Family::Erlang { k, rate } => match Stages::erlang(k, rate) {
                Ok(s) => Duration::phase_type(0.0, s),
                Err(_) => Duration::Exponential { rate },
            },
            Family::Hyperexponential { p, rate1, rate2 } => {
                match Stages::hyperexponential(&[(p, rate1), (1.0 - p, rate2)]) {
                    Ok(s) => Duration::phase_type(0.0, s),
                    Err(_) => Duration::Exponential {
                        rate: 1.0 / (p / rate1 + (1.0 - p) / rate2),
                    },
                }
            }
        }
    }

    /// `log f(t)`.
    pub fn log_pdf(&self, t: f64) -> f64 {
        match *self {
            Family::Deterministic { time } => {
                if t == time {
                    0.0
                } else {
                    f64::NEG_INFINITY
                }
            }
            Family::Exponential { rate } => rate.ln() - rate * t,
            Family::ShiftedExponential { shift, rate } if t >= shift => {
                rate.ln() - rate * (t - shift)
            }
            Family::ShiftedExponential { .. } => f64::NEG_INFINITY,
            Family::Erlang { k, rate } => {
                if t <= 0.0 {
                    return f64::NEG_INFINITY;
                }
                let k = f64::from(k);
                k * rate.ln() + (k - 1.0) * t.ln() - rate * t - ln_gamma_int(k)
            }
            Family::Hyperexponential { p, rate1, rate2 } => {
                if t < 0.0 {
                    return f64::NEG_INFINITY;
                }
                log_sum_exp(
                    p.ln() + rate1.ln() - rate1 * t,
                    (1.0 - p).ln() + rate2.ln() - rate2 * t,
                )
            }
        }
    }

    /// `log P(T > c)`.
    pub fn log_sf(&self, c: f64) -> f64 {
        match *self {
            Family::Deterministic { time } => {
                if c < time {
                    0.0
                } else {
                    f64::NEG_INFINITY
                }
            }
            Family::Exponential { rate } => -rate * c.max(0.0),
            Family::ShiftedExponential { shift, rate } => -rate * (c - shift).max(0.0),
            Family::Erlang { k, rate } => erlang_log_sf(k, rate * c.max(0.0)).0,
            Family::Hyperexponential { p, rate1, rate2 } => {
                let c = c.max(0.0);
                log_sum_exp(p.ln() - rate1 * c, (1.0 - p).ln() - rate2 * c)
            }
        }
    }
}

/// `ln(eᵃ + eᵇ)` without overflow (−∞ terms allowed).
fn log_sum_exp(a: f64, b: f64) -> f64 {
    let m = a.max(b);
    if m == f64::NEG_INFINITY {
        return m;
    }
    m + ((a - m).exp() + (b - m).exp()).ln()
}

/// Most EM iterations of [`fit_hyperexponential`] per start.
pub(crate) const HYPER_EM_ITERATIONS: usize = 500;

/// The hyperexponential-2 maximum of the likelihood by EM, from `start`
/// (`(p, rate1, rate2)`) when given, else from a few starts (the modes
/// split at the 30th, 50th and 70th percentiles of the completed
/// durations), the best kept. E-step: each duration `t` (halt `c`, weight
/// `w`) goes to mode 1 with its posterior probability `r(t) ∝ p λ₁ e^{−λ₁t}`
/// (`s(c) ∝ p e^{−λ₁c}`); M-step: `p = (Σ r + Σ w s) / (n + Σ w)`, `λ₁ = Σ r /
/// (Σ r t + Σ w s c)`, `λ₂` likewise. `None` for fewer than 3 durations
/// or when the modes merge (a rate not finite > 0 or `p` at 0 or 1).
pub fn fit_hyperexponential(s: &Side, start: Option<(f64, f64, f64)>) -> Option<Family> {
    let n = s.events.len();
    if n < 3 {
        return None;
    }
    let starts: Vec<(f64, f64, f64)> = match start {
        Some(x) => vec![x],
        None => {
            let mut x = s.events.to_vec();
            x.sort_by(f64::total_cmp);
            [0.3, 0.5, 0.7]
                .iter()
                .filter_map(|&q| {
                    let cut = ((n as f64 * q) as usize).clamp(1, n - 1);
                    let (lo, hi) = x.split_at(cut);
                    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
                    let (m1, m2) = (mean(lo), mean(hi));
                    (m1 > 0.0 && m2 > m1).then_some((q, 1.0 / m1, 1.0 / m2))
                })
                .collect()
        }
    };
    let weighted: Vec<(f64, f64)> = s
        .censored
        .iter()
        .zip(s.weights)
        .filter(|(_, &w)| w > 0.0)
        .map(|(&c, &w)| (c, w))
        .collect();
    let total_w: f64 = weighted.iter().map(|x| x.1).sum();
    let valid = |(p, a, b): (f64, f64, f64)| {
        p > 1e-12 && p < 1.0 - 1e-12 && a.is_finite() && b.is_finite() && a > 0.0 && b > 0.0
    };
    let mut best: Option<(f64, Family)> = None;
    for (mut p, mut a, mut b) in starts {
        if !valid((p, a, b)) {
            continue;
        }
        for _ in 0..HYPER_EM_ITERATIONS {
            let post = |la: f64, lb: f64| {
                // P(mode 1) from log weights of the two modes
                1.0 / (1.0 + (lb - la).exp())
            };
            let (mut r_sum, mut r_t, mut o_t) = (0.0, 0.0, 0.0);
            for &t in s.events {
                let r = post(p.ln() + a.ln() - a * t, (1.0 - p).ln() + b.ln() - b * t);
                r_sum += r;
                r_t += r * t;
                o_t += (1.0 - r) * t;
            }
            let (mut s_sum, mut s_c, mut o_c) = (0.0, 0.0, 0.0);
            for &(c, w) in &weighted {
                let r = post(p.ln() - a * c, (1.0 - p).ln() - b * c);
                s_sum += w * r;
                s_c += w * r * c;
                o_c += w * (1.0 - r) * c;
            }
            let p2 = (r_sum + s_sum) / (n as f64 + total_w);
            let a2 = r_sum / (r_t + s_c);
            let b2 = (n as f64 - r_sum) / (o_t + o_c);
            let change = ((p2 - p).abs() / p)
                .max(((a2 - a) / a).abs())
                .max(((b2 - b) / b).abs());
            (p, a, b) = (p2, a2, b2);
            if !valid((p, a, b)) || change < 1e-10 {
                break;
            }
        }
        if !valid((p, a, b)) {
            continue;
        }
        // the faster mode first
        let f = if a >= b {
            Family::Hyperexponential {
                p,
                rate1: a,
                rate2: b,
            }
        } else {
            Family::Hyperexponential {
                p: 1.0 - p,
                rate1: b,
                rate2: a,
            }
        };
        let ll = s.log_likelihood(&f);
        if ll.is_finite() && best.as_ref().is_none_or(|(b, _)| ll > *b) {
            best = Some((ll, f));
        }
    }
    best.map(|(_, f)| f)
}

/// `ln (k−1)!` for a whole `k ≥ 1`.
fn ln_gamma_int(k: f64) -> f64 {
    (1..(k as u32)).map(|i| f64::from(i).ln()).sum()
}

/// `(log Q(k, x), h)`: the log survival of Gamma(k, 1) at `x`, `Q = e^{−x}
/// Σ_{j<k} x^j/j!`, and its hazard `h = (x^{k−1}/(k−1)!) / Σ_{j<k} x^j/j!`
/// (log-sum-exp: no overflow).
fn erlang_log_sf(k: u32, x: f64) -> (f64, f64) {
    if x <= 0.0 {
        return (0.0, if k == 1 { 1.0 } else { 0.0 });
    }
    let lx = x.ln();
    let mut la = Vec::with_capacity(k as usize);
    let mut acc = 0.0;
    for j in 0..k {
        if j > 0 {
            acc += lx - f64::from(j).ln();
        }
        la.push(acc);
    }
    let m = la.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let s: f64 = la.iter().map(|a| (a - m).exp()).sum();
    let h = (la[k as usize - 1] - m).exp() / s;
    (-x + m + s.ln(), h)
}

/// One outcome's completed durations and the halts with their weights.
#[derive(Clone, Copy, Debug)]
pub struct Side<'a> {
    pub events: &'a [f64],
    pub censored: &'a [f64],
    /// Weight of each halt in this outcome's likelihood.
    pub weights: &'a [f64],
}

impl Side<'_> {
    fn exposure_beyond(&self, shift: f64) -> f64 {
        self.censored
            .iter()
            .zip(self.weights)
            .map(|(c, w)| w * (c - shift).max(0.0))
            .sum()
    }

    /// `Σ log f(t) + Σ w log S(c)`.
    pub fn log_likelihood(&self, f: &Family) -> f64 {
        let e: f64 = self.events.iter().map(|&t| f.log_pdf(t)).sum();
        let c: f64 = self
            .censored
            .iter()
            .zip(self.weights)
            .filter(|(_, &w)| w > 0.0)
            .map(|(&c, &w)| w * f.log_sf(c))
            .sum();
        e + c
    }
}

/// The exponential's maximum: events over exposure.
pub(crate) fn fit_exponential(s: &Side) -> Option<Family> {
    let n = s.events.len() as f64;
    let exposure = s.events.iter().sum::<f64>() + s.exposure_beyond(0.0);
    (n > 0.0 && exposure > 0.0).then(|| Family::Exponential { rate: n / exposure })
}

/// The shifted exponential's maximum: `δ` the shortest completed duration,
/// then events over the exposure beyond `δ`.
pub(crate) fn fit_shifted(s: &Side) -> Option<Family> {
    let shift = s.events.iter().copied().fold(f64::INFINITY, f64::min);
    let n = s.events.len() as f64;
    let exposure: f64 = s.events.iter().map(|t| t - shift).sum::<f64>() + s.exposure_beyond(shift);
    (shift.is_finite() && shift > 0.0 && exposure > 0.0).then(|| Family::ShiftedExponential {
        shift,
        rate: n / exposure,
    })
}

/// The Erlang-k maximum in λ: closed (`n k / Σ t`) without halts, else the
/// root of the (decreasing) score `n k/λ − Σ t − Σ w c h(k, λc)` by
/// bisection on `ln λ`.
pub(crate) fn fit_erlang(s: &Side, k: u32) -> Option<Family> {
    let n = s.events.len() as f64;
    let total: f64 = s.events.iter().sum();
    if n == 0.0 || total <= 0.0 {
        return None;
    }
    let kf = f64::from(k);
    let closed = n * kf / total;
    if s.weights.iter().all(|&w| w == 0.0) {
        return Some(Family::Erlang { k, rate: closed });
    }
    let score = |rate: f64| {
        let c: f64 = s
            .censored
            .iter()
            .zip(s.weights)
            .map(|(&c, &w)| w * c * erlang_log_sf(k, rate * c).1)
            .sum();
        n * kf / rate - total - c
    };
    // the root lies below the closed form (halts only add exposure)
    let (mut lo, mut hi) = ((closed * 1e-6).ln(), closed.ln());
    if score(lo.exp()) < 0.0 {
        return Some(Family::Erlang { k, rate: lo.exp() });
    }
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if score(mid.exp()) > 0.0 {
            lo = mid;
        } else {
            hi = mid;
        }
        if hi - lo < 1e-13 {
            break;
        }
    }
    Some(Family::Erlang {
        k,
        rate: (0.5 * (lo + hi)).exp(),
    })
}

/// A candidate's fit: family, log-likelihood and BIC.
#[derive(Clone, Debug, PartialEq)]
pub struct Candidate {
    pub family: Family,
    pub log_likelihood: f64,
    pub bic: f64,
}

/// Kolmogorov–Smirnov check of the exponential (module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ks {
    /// `sup |F_n − F|`.
    pub d: f64,
    /// Stephens' modified statistic.
    pub modified: f64,
    /// Whether the exponential is rejected at 5%.
    pub rejected: bool,
}

/// KS distance of `sample` to `Exp(rate)` and Stephens' modified statistic.
pub(crate) fn ks_exponential(sample: &[f64], rate: f64) -> Option<Ks> {
    let n = sample.len();
    if n == 0 {
        return None;
    }
    let mut x = sample.to_vec();
    x.sort_by(f64::total_cmp);
    let nf = n as f64;
    let d = x
        .iter()
        .enumerate()
        .map(|(i, &t)| {
            let f = -(-rate * t).exp_m1();
            (f - i as f64 / nf).max((i + 1) as f64 / nf - f)
        })
        .fold(0.0, f64::max);
    let modified = (d - 0.2 / nf) * (nf.sqrt() + 0.26 + 0.5 / nf.sqrt());
    Some(Ks {
        d,
        modified,
        rejected: modified > KS_CRITICAL_5,
    })
}

/// One outcome's chosen family, the candidates compared and the KS check.
#[derive(Clone, Debug, PartialEq)]
pub struct SideFit {
    pub family: Family,
    /// Candidates by increasing BIC (empty when the family was not chosen
    /// by likelihood: deterministic, or too few episodes).
    pub candidates: Vec<Candidate>,
    pub ks: Option<Ks>,
}

fn candidate(s: &Side, family: Family, n_bic: f64) -> Option<Candidate> {
    let ll = s.log_likelihood(&family);
    ll.is_finite().then(|| Candidate {
        family,
        log_likelihood: ll,
        bic: -2.0 * ll + family.parameters() as f64 * n_bic.max(1.0).ln(),
    })
}

/// The best Erlang by profile likelihood over `k = 2..=MAX_K`.
fn best_erlang(s: &Side, n_bic: f64) -> Option<Candidate> {
    (2..=MAX_K)
        .filter_map(|k| fit_erlang(s, k).and_then(|f| candidate(s, f, n_bic)))
        .min_by(|a, b| a.bic.total_cmp(&b.bic))
}

/// Chooses the family of one outcome (module docs). `n_bic`: the leaf's
/// episodes; `deterministic`: the common time when the completed durations
/// are one time. `None` when the outcome never completed.
pub fn choose(s: &Side, n_bic: f64, deterministic: Option<f64>) -> Option<SideFit> {
    if s.events.is_empty() {
        return None;
    }
    if let Some(time) = deterministic {
        return Some(SideFit {
            family: Family::Deterministic { time },
            candidates: Vec::new(),
            ks: None,
        });
    }
    let exp = fit_exponential(s)?;
    let ks = match exp {
        Family::Exponential { rate } if s.censored.is_empty() => ks_exponential(s.events, rate),
        _ => None,
    };
    if s.events.len() < FAMILY_MIN {
        return Some(SideFit {
            family: exp,
            candidates: Vec::new(),
            ks,
        });
    }
    let mut c: Vec<Candidate> = [
        candidate(s, exp, n_bic),
        fit_shifted(s).and_then(|f| candidate(s, f, n_bic)),
        best_erlang(s, n_bic),
        fit_hyperexponential(s, None).and_then(|f| candidate(s, f, n_bic)),
    ]
    .into_iter()
    .flatten()
    .collect();
    c.sort_by(|a, b| a.bic.total_cmp(&b.bic));
    Some(SideFit {
        family: c.first().map_or(exp, |c| c.family),
        candidates: c,
        ks,
    })
}

/// Refits `family` (same kind, same k) to weighted data.
pub(crate) fn refit(s: &Side, family: &Family) -> Option<Family> {
    match family {
        Family::Deterministic { .. } => Some(*family),
        Family::Exponential { .. } => fit_exponential(s),
        Family::ShiftedExponential { .. } => fit_shifted(s),
        Family::Erlang { k, .. } => fit_erlang(s, *k),
        Family::Hyperexponential { p, rate1, rate2 } => {
            fit_hyperexponential(s, Some((*p, *rate1, *rate2)))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn erlang_survival_matches_closed_forms() {
        // Q(2, x) = e^{−x}(1 + x), hazard x/(1 + x)
        for x in [0.1f64, 1.0, 7.5, 300.0] {
            let (l, h) = erlang_log_sf(2, x);
            assert!((l - (-x + (1.0 + x).ln())).abs() < 1e-12, "{x}");
            assert!((h - x / (1.0 + x)).abs() < 1e-12, "{x}");
        }
        assert_eq!(erlang_log_sf(1, 2.0), (-2.0, 1.0));
    }

    #[test]
    fn erlang_with_halts_solves_its_score() {
        // events 1, 2, 3 and one halt at 4 with weight 1, k = 2: the
        // maximum of 3·2 ln λ − 6λ + ln Q(2, 4λ) found by a grid
        let s = Side {
            events: &[1.0, 2.0, 3.0],
            censored: &[4.0],
            weights: &[1.0],
        };
        let Some(Family::Erlang { rate, .. }) = fit_erlang(&s, 2) else {
            panic!("an Erlang fit")
        };
        let ll = |r: f64| 6.0 * r.ln() - 6.0 * r - 4.0 * r + (1.0 + 4.0 * r).ln();
        let grid = (1..200_000)
            .map(|i| f64::from(i) * 1e-5)
            .max_by(|a, b| ll(*a).total_cmp(&ll(*b)))
            .expect("grid");
        assert!((rate - grid).abs() < 2e-5, "{rate} vs {grid}");
    }

    #[test]
    fn ks_of_a_perfect_sample_is_small() {
        // quantiles (i − ½)/n of Exp(1): D = 1/(2n)
        let n = 50;
        let x: Vec<f64> = (0..n)
            .map(|i| -(1.0 - (i as f64 + 0.5) / n as f64).ln())
            .collect();
        let ks = ks_exponential(&x, 1.0).expect("sample");
        assert!((ks.d - 0.5 / n as f64).abs() < 1e-12);
        assert!(!ks.rejected);
    }
}
