//! The covariance of a `--timing auto` fit's parameters, for `--ci`.
//!
//! A leaf fitted with `--timing auto` has ps and, per outcome, a family
//! with its own parameters ([`super::timing`]). Their joint sampling law is
//! taken as the maximum-likelihood estimator's asymptotic one: normal, with
//! the inverse of the observed information as covariance, on an
//! unconstrained scale — `logit` for probabilities (ps, a
//! hyperexponential's branch probability), `ln` for rates — where the
//! normal law keeps every draw in range and is closer to the estimator's
//! skewed law. The information is the negative Hessian of the leaf's joint
//! log-likelihood (completed successes and failures, and halts as
//! `log(p S_s(c) + (1−p) S_f(c))`; [`Laws::log_likelihood`]) in those
//! parameters, by central differences of step [`STEP`] (relative error
//! about `1e-8`, from rounding in `log L` over `STEP²`).
//!
//! Not in it: a family's whole number k (Erlang) and a shifted law's shift
//! `δ̂`, the shortest completed duration — the likelihood is not smooth in
//! `δ` (it rises up to `δ̂` and is zero beyond), so the normal theory does
//! not hold; `--ci` draws the shift from its exact pivot instead
//! ([`crate::uncertainty`]). A deterministic time has no parameter either
//! (its durations did not vary).
//!
//! `fit` writes the matrix under `fit: {cov_theta: {params: [...], matrix:
//! [[...], ...]}}`, with the parameters' names ([`Param::name`]).

use super::timing::Family;
use super::Counts;

/// Step of the central differences, on the unconstrained scale.
pub const STEP: f64 = 1e-4;

/// An outcome of a leaf.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Outcome {
    Success,
    Failure,
}

impl Outcome {
    /// `success` or `failure`.
    pub fn name(self) -> &'static str {
        match self {
            Outcome::Success => "success",
            Outcome::Failure => "failure",
        }
    }
}

/// One free parameter of an auto fit, on its unconstrained scale.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Param {
    /// `logit ps`.
    LogitPs,
    /// `ln` of the rate of an exponential, shifted exponential or Erlang
    /// time.
    LnRate(Outcome),
    /// `logit p` of a hyperexponential `p·Exp(rate1) + (1−p)·Exp(rate2)`.
    LogitBranch(Outcome),
    /// `ln rate1` of a hyperexponential.
    LnRate1(Outcome),
    /// `ln rate2` of a hyperexponential.
    LnRate2(Outcome),
}

const OUTCOMES: [Outcome; 2] = [Outcome::Success, Outcome::Failure];

impl Param {
    /// Its name in the params file (`logit_ps`, `ln_success_rate`,
    /// `logit_failure_p`, `ln_failure_rate1`, ...).
    pub fn name(self) -> String {
        match self {
            Param::LogitPs => "logit_ps".into(),
            Param::LnRate(o) => format!("ln_{}_rate", o.name()),
            Param::LogitBranch(o) => format!("logit_{}_p", o.name()),
            Param::LnRate1(o) => format!("ln_{}_rate1", o.name()),
            Param::LnRate2(o) => format!("ln_{}_rate2", o.name()),
        }
    }

    /// The parameter of a name ([`Param::name`]).
    pub fn parse(name: &str) -> Option<Param> {
        if name == "logit_ps" {
            return Some(Param::LogitPs);
        }
        OUTCOMES
            .into_iter()
            .flat_map(|o| {
                [
                    Param::LnRate(o),
                    Param::LogitBranch(o),
                    Param::LnRate1(o),
                    Param::LnRate2(o),
                ]
            })
            .find(|p| p.name() == name)
    }

    /// Whether it is a hyperexponential's parameter (no exact pivot: drawn
    /// from the normal law even without halts).
    pub fn is_hyperexponential(self) -> bool {
        matches!(
            self,
            Param::LogitBranch(_) | Param::LnRate1(_) | Param::LnRate2(_)
        )
    }
}

fn logit(p: f64) -> f64 {
    (p / (1.0 - p)).ln()
}

fn logistic(x: f64) -> f64 {
    1.0 / (1.0 + (-x).exp())
}

/// A leaf's fitted laws: ps and each observed outcome's family.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Laws {
    pub ps: f64,
    pub success: Option<Family>,
    pub failure: Option<Family>,
}

impl Laws {
    /// The law of an outcome.
    pub fn side(&self, o: Outcome) -> Option<Family> {
        match o {
            Outcome::Success => self.success,
            Outcome::Failure => self.failure,
        }
    }

    /// The law of an outcome, to change.
    pub fn side_mut(&mut self, o: Outcome) -> &mut Option<Family> {
        match o {
            Outcome::Success => &mut self.success,
            Outcome::Failure => &mut self.failure,
        }
    }

    /// The free parameters the laws have (module docs): `logit_ps` when
    /// both outcomes have a law and `0 < ps < 1`, then each outcome's.
    pub fn params(&self) -> Vec<Param> {
        let mut v = Vec::new();
        if self.success.is_some() && self.failure.is_some() && self.ps > 0.0 && self.ps < 1.0 {
            v.push(Param::LogitPs);
        }
        for o in OUTCOMES {
            match self.side(o) {
                Some(
                    Family::Exponential { .. }
                    | Family::ShiftedExponential { .. }
                    | Family::Erlang { .. },
                ) => v.push(Param::LnRate(o)),
                Some(Family::Hyperexponential { .. }) => {
                    v.extend([Param::LogitBranch(o), Param::LnRate1(o), Param::LnRate2(o)])
                }
                Some(Family::Deterministic { .. }) | None => {}
            }
        }
        v
    }

    /// The value of a parameter on its unconstrained scale; None when the
    /// laws do not have it.
    pub fn get(&self, p: Param) -> Option<f64> {
        match (p, p_outcome(p).and_then(|o| self.side(o))) {
            (Param::LogitPs, _) => Some(logit(self.ps)),
            (
                Param::LnRate(_),
                Some(
                    Family::Exponential { rate }
                    | Family::ShiftedExponential { rate, .. }
                    | Family::Erlang { rate, .. },
                ),
            ) => Some(rate.ln()),
            (Param::LogitBranch(_), Some(Family::Hyperexponential { p, .. })) => Some(logit(p)),
            (Param::LnRate1(_), Some(Family::Hyperexponential { rate1, .. })) => Some(rate1.ln()),
            (Param::LnRate2(_), Some(Family::Hyperexponential { rate2, .. })) => Some(rate2.ln()),
            _ => None,
        }
    }

    /// Sets a parameter from its unconstrained value; false when the laws
    /// do not have it.
    pub fn set(&mut self, p: Param, x: f64) -> bool {
        if p == Param::LogitPs {
            self.ps = logistic(x);
            return true;
        }
        let Some(side) = p_outcome(p).map(|o| self.side_mut(o)) else {
            return false;
        };
        match (p, side) {
            (
                Param::LnRate(_),
                Some(
                    Family::Exponential { rate }
                    | Family::ShiftedExponential { rate, .. }
                    | Family::Erlang { rate, .. },
                ),
            ) => *rate = x.exp(),
            (Param::LogitBranch(_), Some(Family::Hyperexponential { p, .. })) => *p = logistic(x),
            (Param::LnRate1(_), Some(Family::Hyperexponential { rate1, .. })) => *rate1 = x.exp(),
            (Param::LnRate2(_), Some(Family::Hyperexponential { rate2, .. })) => *rate2 = x.exp(),
            _ => return false,
        }
        true
    }

    /// The leaf's joint log-likelihood: `n_s ln p + n_f ln(1−p)`, each
    /// completed duration's `ln f`, each halt's `ln(p S_s(c) + (1−p)
    /// S_f(c))`.
    pub fn log_likelihood(&self, counts: &Counts) -> f64 {
        let (ns, nf) = (counts.successes as f64, counts.failures as f64);
        let p = self.ps;
        let mut ll = 0.0;
        if ns > 0.0 {
            ll += ns * p.ln();
        }
        if nf > 0.0 {
            ll += nf * (1.0 - p).ln();
        }
        for (f, ev) in [
            (&self.success, &counts.success_durations),
            (&self.failure, &counts.failure_durations),
        ] {
            if let Some(f) = f {
                ll += ev.iter().map(|&t| f.log_pdf(t)).sum::<f64>();
            }
        }
        let log_sf = |f: &Option<Family>, c: f64| f.map_or(f64::NEG_INFINITY, |f| f.log_sf(c));
        for &c in &counts.censored {
            ll += super::log_mix(p, log_sf(&self.success, c), log_sf(&self.failure, c));
        }
        ll
    }
}

fn p_outcome(p: Param) -> Option<Outcome> {
    match p {
        Param::LogitPs => None,
        Param::LnRate(o) | Param::LogitBranch(o) | Param::LnRate1(o) | Param::LnRate2(o) => Some(o),
    }
}

/// The covariance of the unconstrained parameters' estimator.
#[derive(Clone, Debug, PartialEq)]
pub struct ThetaCovariance {
    pub params: Vec<Param>,
    /// Rows and columns in the order of `params`.
    pub matrix: Vec<Vec<f64>>,
}

/// The inverse observed information of `laws` (the maximum of the
/// likelihood of `counts`) in their free parameters (module docs); None
/// when there is none, the likelihood is not finite around the maximum, or
/// the information is not positive definite (not a strict maximum).
pub fn covariance(counts: &Counts, laws: &Laws) -> Option<ThetaCovariance> {
    let params = laws.params();
    let n = params.len();
    if n == 0 {
        return None;
    }
    let theta: Vec<f64> = params.iter().map(|&p| laws.get(p)).collect::<Option<_>>()?;
    let ll = |shift: &[(usize, f64)]| {
        let mut l = *laws;
        for &(i, d) in shift {
            l.set(params[i], theta[i] + d);
        }
        l.log_likelihood(counts)
    };
    let h = STEP;
    let centre = ll(&[]);
    let mut info = vec![vec![0.0; n]; n];
    #[allow(clippy::needless_range_loop)] // a symmetric matrix filled by halves
    for i in 0..n {
        info[i][i] = -(ll(&[(i, h)]) - 2.0 * centre + ll(&[(i, -h)])) / (h * h);
        for j in 0..i {
            let v = -(ll(&[(i, h), (j, h)]) - ll(&[(i, h), (j, -h)]) - ll(&[(i, -h), (j, h)])
                + ll(&[(i, -h), (j, -h)]))
                / (4.0 * h * h);
            info[i][j] = v;
            info[j][i] = v;
        }
    }
    let matrix = super::covariance::inverse_pd(&info)?;
    Some(ThetaCovariance { params, matrix })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip() {
        for p in [
            Param::LogitPs,
            Param::LnRate(Outcome::Failure),
            Param::LogitBranch(Outcome::Success),
            Param::LnRate1(Outcome::Failure),
            Param::LnRate2(Outcome::Success),
        ] {
            assert_eq!(Param::parse(&p.name()), Some(p));
        }
        assert_eq!(Param::parse("ln_rate"), None);
    }

    /// Without halts the information is diagonal with closed forms: `n
    /// p(1−p)` for logit ps, `k·n_s` for the ln rate of an Erlang-k time
    /// (`n_s` for an exponential or shifted exponential).
    #[test]
    fn closed_forms_without_halts() {
        let counts = Counts {
            successes: 30,
            failures: 10,
            success_durations: (1..=30).map(|i| 0.1 * i as f64).collect(),
            failure_durations: (1..=10).map(|i| 1.0 + 0.05 * i as f64).collect(),
            ..Default::default()
        };
        let laws = Laws {
            ps: 0.75,
            success: Some(Family::Erlang {
                k: 3,
                rate: 90.0 / 46.5,
            }),
            failure: Some(Family::ShiftedExponential {
                shift: 1.05,
                rate: 10.0 / 2.25,
            }),
        };
        let c = covariance(&counts, &laws).unwrap();
        assert_eq!(
            c.params,
            [
                Param::LogitPs,
                Param::LnRate(Outcome::Success),
                Param::LnRate(Outcome::Failure)
            ]
        );
        let want = [1.0 / (40.0 * 0.75 * 0.25), 1.0 / 90.0, 1.0 / 10.0];
        for (i, (row, want)) in c.matrix.iter().zip(want).enumerate() {
            for (j, &x) in row.iter().enumerate() {
                let w = if i == j { want } else { 0.0 };
                assert!((x - w).abs() < 1e-6 * want, "{i}{j}: {c:?}");
            }
        }
    }

    /// With halts, for exponential times: the analytic inverse information
    /// of (p̂, μ̂, ν̂) that `fit --timing exponential` writes (`*_se`,
    /// `cov:`), carried to (logit p, ln μ, ln ν) by the delta method, is
    /// the matrix found here by differences.
    #[test]
    fn exponential_with_halts_matches_the_analytic_information() {
        use crate::logs::{End, Episode};
        // a fixed pseudo-random log: durations from a linear congruence
        let mut x = 12345u64;
        let mut u = || {
            x = x
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((x >> 11) as f64 + 0.5) / (1u64 << 53) as f64
        };
        let eps: Vec<Episode> = (0..400)
            .map(|_| {
                let ok = u() < 0.7;
                let d = -u().ln() / if ok { 0.5 } else { 1.0 };
                let c = -u().ln() / 0.6;
                let end = match (d < c, ok) {
                    (false, _) => End::Halted,
                    (true, true) => End::Success,
                    (true, false) => End::Failure,
                };
                Episode {
                    duration: d.min(c),
                    end,
                    instant: false,
                }
            })
            .collect();
        let counts = Counts::from_episodes(&eps);
        assert!(counts.halted > 100, "{}", counts.halted);
        let m = super::super::mle_exponential(&counts).unwrap();
        let (p, mu, nu) = (m.ps.value, m.mu.unwrap().value, m.nu.unwrap().value);
        let se = [
            m.ps.se.unwrap(),
            m.mu.unwrap().se.unwrap(),
            m.nu.unwrap().se.unwrap(),
        ];
        let sigma = m.cov.unwrap().matrix(se);
        let d = [1.0 / (p * (1.0 - p)), 1.0 / mu, 1.0 / nu];
        let laws = Laws {
            ps: p,
            success: Some(Family::Exponential { rate: mu }),
            failure: Some(Family::Exponential { rate: nu }),
        };
        let c = covariance(&counts, &laws).unwrap();
        for i in 0..3 {
            for j in 0..3 {
                let want = sigma[i][j] * d[i] * d[j];
                let scale = (sigma[i][i] * sigma[j][j]).sqrt() * d[i] * d[j];
                assert!(
                    (c.matrix[i][j] - want).abs() < 1e-5 * scale,
                    "{i}{j}: {} vs {want}",
                    c.matrix[i][j]
                );
            }
        }
    }

    /// A parameter the data say nothing about (a rate with no event and no
    /// exposure) has zero information: no covariance, rather than a
    /// made-up one.
    #[test]
    fn no_covariance_without_information() {
        let counts = Counts {
            failures: 10,
            failure_durations: vec![1.0; 10],
            ..Default::default()
        };
        let laws = Laws {
            ps: 0.5,
            success: Some(Family::Exponential { rate: 1.0 }),
            failure: Some(Family::Exponential { rate: 1.0 }),
        };
        assert_eq!(covariance(&counts, &laws), None);
    }
}
