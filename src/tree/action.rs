//! Validation of an action's parameters, shared by the YAML and XML front
//! ends: probabilities in [0, 1] summing to 1, rates > 0, times ≥ 0, at most
//! one time key per outcome, a time for every possible outcome, and the
//! hybrid combinations of Def. 9.9.

use serde::Deserialize;
use serde_saphyr::Spanned;

use super::error::TreeError;
use super::parse::PROBABILITY_SUM_TOLERANCE;
use super::{Action, Duration};

/// A 1-based (line, column).
pub(crate) type Loc = (usize, usize);

/// An action's parameters as written (each with its location).
#[derive(Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub(crate) struct ActionParams {
    #[serde(default)]
    pub ps: Option<At<f64>>,
    #[serde(default)]
    pub pf: Option<At<f64>>,
    #[serde(default)]
    pub mu: Option<At<f64>>,
    #[serde(default)]
    pub nu: Option<At<f64>>,
    #[serde(default)]
    pub tau_s: Option<At<f64>>,
    #[serde(default)]
    pub tau_f: Option<At<f64>>,
}

/// The location of a value.
/// A value with the 1-based line and column where it was written (read
/// through serde-saphyr's `Spanned`, or set by the fast YAML reader).
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct At<T> {
    pub value: T,
    pub line: u32,
    pub column: u32,
}

impl<'de, T: Deserialize<'de>> Deserialize<'de> for At<T> {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let s = Spanned::<T>::deserialize(d)?;
        Ok(At {
            value: s.value,
            line: s.referenced.line() as u32,
            column: s.referenced.column() as u32,
        })
    }
}

pub(crate) fn sloc<T>(s: &At<T>) -> Loc {
    (s.line as usize, s.column as usize)
}

/// Validates `p`. An invalid value is an error built by `e(location,
/// message, help)`; missing parameters are returned as `Ok(Err(what))` so
/// that a caller can collect them (`what` says what to add).
pub(crate) fn validate_action(
    p: &ActionParams,
    e: &dyn Fn(Loc, String, String) -> TreeError,
) -> Result<Result<Action, String>, TreeError> {
    let probability = |key: &str, v: &At<f64>| {
        let x = v.value;
        if !x.is_finite() || !(0.0..=1.0).contains(&x) {
            return Err(e(
                sloc(v),
                format!("{key} = {x} is not a probability"),
                format!("{key} must be a number in [0, 1]"),
            ));
        }
        Ok(x)
    };
    let rate = |key: &str, v: &At<f64>| {
        let x = v.value;
        if !x.is_finite() || x <= 0.0 {
            return Err(e(
                sloc(v),
                format!("{key} = {x} is not a valid rate"),
                format!(
                    "{key} is a rate in 1/s and must be a finite number > 0 (mean time = 1/{key})"
                ),
            ));
        }
        Ok(x)
    };
    let time = |key: &str, v: &At<f64>| {
        let x = v.value;
        if !x.is_finite() || x < 0.0 {
            return Err(e(
                sloc(v),
                format!("{key} = {x} is not a valid time"),
                format!("{key} is a time in s and must be a finite number >= 0"),
            ));
        }
        Ok(x)
    };
    let Some(ps_def) = &p.ps else {
        return Ok(Err("missing `ps` (probability of success in [0, 1])".into()));
    };
    let ps = probability("ps", ps_def)?;
    let pf = match &p.pf {
        None => 1.0 - ps,
        Some(pf_def) => {
            let pf = probability("pf", pf_def)?;
            if (ps + pf - 1.0).abs() > PROBABILITY_SUM_TOLERANCE {
                return Err(e(
                    sloc(pf_def),
                    format!("ps + pf = {} but must be 1", ps + pf),
                    format!(
                        "ps = {ps} and pf = {pf}; the outcomes are exclusive, so pf = 1 - ps \
                         (within {PROBABILITY_SUM_TOLERANCE:e}); omit pf to get 1 - ps"
                    ),
                ));
            }
            pf
        }
    };
    if let (Some(m), Some(t)) = (&p.mu, &p.tau_s) {
        return Err(e(
            sloc(m).max(sloc(t)),
            "both `mu` and `tau_s` give the success time".into(),
            "give `mu` (exponential, rate) or `tau_s` (deterministic, time), not both".into(),
        ));
    }
    if let (Some(n), Some(t)) = (&p.nu, &p.tau_f) {
        return Err(e(
            sloc(n).max(sloc(t)),
            "both `nu` and `tau_f` give the failure time".into(),
            "give `nu` (exponential, rate) or `tau_f` (deterministic, time), not both".into(),
        ));
    }
    let mu = p.mu.as_ref().map(|v| rate("mu", v)).transpose()?;
    let nu = p.nu.as_ref().map(|v| rate("nu", v)).transpose()?;
    let tau_s = p.tau_s.as_ref().map(|v| time("tau_s", v)).transpose()?;
    let tau_f = p.tau_f.as_ref().map(|v| time("tau_f", v)).transpose()?;
    let mut missing = Vec::new();
    if ps > 0.0 && mu.is_none() && tau_s.is_none() {
        missing.push(format!(
            "can succeed (ps = {ps}) but has no success time: add `mu` (1/s) or `tau_s` (s)"
        ));
    }
    if pf > 0.0 && nu.is_none() && tau_f.is_none() {
        missing.push(format!(
            "can fail (pf = {pf}) but has no failure time: add `nu` (1/s) or `tau_f` (s)"
        ));
    }
    if !missing.is_empty() {
        return Ok(Err(missing.join("; ")));
    }
    // Def. 9.9: in a hybrid action the random side is cut off at the
    // deterministic time of the other outcome.
    let success = match (mu, tau_s, tau_f) {
        (Some(rate), _, Some(cap)) => Some(Duration::TruncatedExponential { rate, cap }),
        (Some(rate), _, None) => Some(Duration::Exponential { rate }),
        (None, Some(time), _) => Some(Duration::Fixed { time }),
        (None, None, _) => None,
    };
    let failure = match (nu, tau_f, tau_s) {
        (Some(rate), _, Some(cap)) => Some(Duration::TruncatedExponential { rate, cap }),
        (Some(rate), _, None) => Some(Duration::Exponential { rate }),
        (None, Some(time), _) => Some(Duration::Fixed { time }),
        (None, None, _) => None,
    };
    Ok(Ok(Action {
        ps,
        pf,
        success: success.filter(|_| ps > 0.0),
        failure: failure.filter(|_| pf > 0.0),
    }))
}
