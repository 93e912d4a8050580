//! Validation of an action's parameters, shared by the YAML and XML front
//! ends: probabilities in [0, 1] summing to 1, rates > 0, times ≥ 0, at most
//! one time key per outcome, a time for every possible outcome, and the
//! hybrid combinations of Def. 9.9.

use serde::Deserialize;
use serde_saphyr::Spanned;

use super::error::TreeError;
use super::stages::MAX_GENERAL_PHASES;
use super::{Action, Duration, Stages};

/// Tolerance on `ps + pf = 1`.
pub(crate) const PROBABILITY_SUM_TOLERANCE: f64 = 1e-9;

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
    #[serde(default)]
    pub success_time: Option<At<TimeDef>>,
    #[serde(default)]
    pub failure_time: Option<At<TimeDef>>,
}

/// An outcome's time law as written under `success_time` / `failure_time`:
/// `{rate: r}`, `{fixed: t}`, `{erlang: {k: 3, rate: r}}`,
/// `{hypoexponential: [r1, r2]}`, `{hyperexponential: [{p: 0.3, rate: r1},
/// ...]}`, `{phase_type: {alpha: [...], T: [[...], ...]}}`, and `shift: s`
/// with any of them but `fixed` (a deterministic delay before it).
#[derive(Deserialize, Default, Debug, Clone, PartialEq)]
#[serde(deny_unknown_fields)]
pub(crate) struct TimeDef {
    #[serde(default)]
    pub rate: Option<At<f64>>,
    #[serde(default)]
    pub fixed: Option<At<f64>>,
    #[serde(default)]
    pub shift: Option<At<f64>>,
    #[serde(default)]
    pub erlang: Option<At<ErlangDef>>,
    #[serde(default)]
    pub hypoexponential: Option<At<Vec<At<f64>>>>,
    #[serde(default)]
    pub hyperexponential: Option<At<Vec<At<HyperBranchDef>>>>,
    #[serde(default)]
    pub phase_type: Option<At<PhaseTypeDef>>,
}

/// One branch `{p: probability, rate: r}` of a hyperexponential.
#[derive(Deserialize, Debug, Clone, PartialEq)]
#[serde(deny_unknown_fields)]
pub(crate) struct HyperBranchDef {
    pub p: At<f64>,
    pub rate: At<f64>,
}

/// `{alpha: [a1, ...], T: [[...], ...]}`: a general phase-type law.
#[derive(Deserialize, Debug, Clone, PartialEq)]
#[serde(deny_unknown_fields)]
pub(crate) struct PhaseTypeDef {
    pub alpha: At<Vec<At<f64>>>,
    #[serde(rename = "T")]
    pub t: At<Vec<At<Vec<At<f64>>>>>,
}

/// `{k: stages, rate: r}`.
#[derive(Deserialize, Debug, Clone, PartialEq)]
#[serde(deny_unknown_fields)]
pub(crate) struct ErlangDef {
    pub k: At<f64>,
    pub rate: At<f64>,
}

impl ActionParams {
    /// The location of the first `success_time` / `failure_time`, if any.
    pub(crate) fn time_law_at(&self) -> Option<Loc> {
        [&self.success_time, &self.failure_time]
            .into_iter()
            .flatten()
            .map(sloc)
            .next()
    }
}

/// What `success_time` / `failure_time` accept (for help texts).
pub(crate) const TIME_LAW_HELP: &str = "write one of `{rate: r}` (exponential, 1/s), \
     `{fixed: t}` (deterministic, s), `{erlang: {k: 3, rate: r}}` (k exponential stages of \
     rate r), `{hypoexponential: [r1, r2, ...]}` (one stage per rate), \
     `{hyperexponential: [{p: 0.3, rate: r1}, {p: 0.7, rate: r2}]}` (rate r_i with probability \
     p_i), `{phase_type: {alpha: [0.3, 0.7], T: [[-2, 1], [0, -3]]}}` (initial probabilities \
     and sub-generator of a phase-type law, at most 64 phases), optionally with \
     `shift: s` before any of them but `fixed` (a deterministic delay, s)";

/// Validates a `success_time` / `failure_time` law.
fn time_law(
    key: &str,
    def: &At<TimeDef>,
    e: &dyn Fn(Loc, String, String) -> TreeError,
) -> Result<Duration, TreeError> {
    let t = &def.value;
    let positive = |what: String, v: &At<f64>| {
        let x = v.value;
        if !x.is_finite() || x <= 0.0 {
            return Err(e(
                sloc(v),
                format!("{what} = {x} is not a valid rate"),
                format!("{what} is a rate in 1/s and must be a finite number > 0"),
            ));
        }
        Ok(x)
    };
    let time = |what: String, v: &At<f64>| {
        let x = v.value;
        if !x.is_finite() || x < 0.0 {
            return Err(e(
                sloc(v),
                format!("{what} = {x} is not a valid time"),
                format!("{what} is a time in s and must be a finite number >= 0"),
            ));
        }
        Ok(x)
    };
    let laws = [
        t.rate.as_ref().map(|_| "rate"),
        t.fixed.as_ref().map(|_| "fixed"),
        t.erlang.as_ref().map(|_| "erlang"),
        t.hypoexponential.as_ref().map(|_| "hypoexponential"),
        t.hyperexponential.as_ref().map(|_| "hyperexponential"),
        t.phase_type.as_ref().map(|_| "phase_type"),
    ];
    let given: Vec<&str> = laws.into_iter().flatten().collect();
    if given.len() != 1 {
        let message = if given.is_empty() {
            format!("`{key}` gives no law")
        } else {
            format!("`{key}` gives {} laws ({})", given.len(), given.join(", "))
        };
        return Err(e(sloc(def), message, TIME_LAW_HELP.into()));
    }
    let shift = t
        .shift
        .as_ref()
        .map(|v| time(format!("{key}.shift"), v))
        .transpose()?;
    if let (Some(fixed), Some(_)) = (&t.fixed, &shift) {
        return Err(e(
            sloc(fixed),
            format!("`{key}` gives both `fixed` and `shift`"),
            "a deterministic time is `{fixed: t}` alone; `shift` delays a random law".into(),
        ));
    }
    let stages_err = |at: Loc, what: String| {
        e(
            at,
            format!("`{key}`: {what}"),
            format!(
                "at most {} distinct rates and {} stages in all",
                super::stages::MAX_STAGES,
                super::stages::MAX_PHASES
            ),
        )
    };
    let stages = if let Some(v) = &t.fixed {
        return Ok(Duration::Fixed {
            time: time(format!("{key}.fixed"), v)?,
        });
    } else if let Some(v) = &t.rate {
        Stages::erlang(1, positive(format!("{key}.rate"), v)?)
            .map_err(|w| stages_err(sloc(v), w))?
    } else if let Some(er) = &t.erlang {
        let k = &er.value.k;
        let max = super::stages::MAX_PHASES;
        if !(k.value.is_finite()
            && k.value.fract() == 0.0
            && (1.0..=f64::from(max)).contains(&k.value))
        {
            return Err(e(
                sloc(k),
                format!("{key}.erlang.k = {} is not a valid stage count", k.value),
                format!("k is the number of exponential stages: a whole number from 1 to {max}"),
            ));
        }
        let rate = positive(format!("{key}.erlang.rate"), &er.value.rate)?;
        Stages::erlang(k.value as u32, rate).map_err(|w| stages_err(sloc(er), w))?
    } else if let Some(list) = &t.hypoexponential {
        if list.value.is_empty() {
            return Err(e(
                sloc(list),
                format!("`{key}.hypoexponential` is empty"),
                "list the stages' rates (1/s), e.g. `{hypoexponential: [1.0, 2.0]}`".into(),
            ));
        }
        let rates = list
            .value
            .iter()
            .map(|v| positive(format!("{key}.hypoexponential rate"), v))
            .collect::<Result<Vec<f64>, TreeError>>()?;
        Stages::hypoexponential(&rates).map_err(|w| stages_err(sloc(list), w))?
    } else if let Some(list) = &t.hyperexponential {
        let help = || {
            "a hyperexponential is `[{p: 0.3, rate: r1}, {p: 0.7, rate: r2}]`: rate r_i (1/s) \
             with probability p_i, the p_i summing to 1, at most 64 branches"
                .to_string()
        };
        if list.value.is_empty() {
            return Err(e(
                sloc(list),
                format!("`{key}.hyperexponential` is empty"),
                help(),
            ));
        }
        let mut branches = Vec::with_capacity(list.value.len().min(MAX_GENERAL_PHASES + 1));
        for b in &list.value {
            let p = b.value.p.value;
            if !(p.is_finite() && (0.0..=1.0).contains(&p)) {
                return Err(e(
                    sloc(&b.value.p),
                    format!("{key}.hyperexponential p = {p} is not a probability"),
                    help(),
                ));
            }
            let rate = positive(format!("{key}.hyperexponential rate"), &b.value.rate)?;
            branches.push((p, rate));
        }
        Stages::hyperexponential(&branches)
            .map_err(|w| e(sloc(list), format!("`{key}.hyperexponential`: {w}"), help()))?
    } else if let Some(ph) = &t.phase_type {
        phase_type_law(key, ph, e)?
    } else {
        unreachable!("exactly one law is given (checked above)")
    };
    Ok(Duration::phase_type(shift.unwrap_or(0.0), stages))
}

/// Validates a `phase_type: {alpha, T}` law: each entry where it is
/// written, then the law as a whole (at `phase_type`).
fn phase_type_law(
    key: &str,
    ph: &At<PhaseTypeDef>,
    e: &dyn Fn(Loc, String, String) -> TreeError,
) -> Result<Stages, TreeError> {
    let help = || {
        format!(
            "a phase-type law is `{{alpha: [a1, ..., an], T: [[T11, ..., T1n], ...]}}`: \
             initial probabilities summing to 1 and an n x n sub-generator (T_ii < 0, \
             T_ij >= 0, rows summing to <= 0, exit rate -row sum), every phase leading to an \
             exit, at most {MAX_GENERAL_PHASES} phases; a T with cycles is taken when it has \
             an acyclic form of the same order (real eigenvalues)"
        )
    };
    let (alpha, t) = (&ph.value.alpha, &ph.value.t);
    let n = alpha.value.len();
    if n == 0 || n > MAX_GENERAL_PHASES {
        return Err(e(
            sloc(alpha),
            format!("`{key}.phase_type.alpha` has {n} entries"),
            help(),
        ));
    }
    if t.value.len() != n {
        return Err(e(
            sloc(t),
            format!(
                "`{key}.phase_type.T` has {} rows but alpha has {n} entries",
                t.value.len()
            ),
            help(),
        ));
    }
    for (i, a) in alpha.value.iter().enumerate() {
        if !(a.value.is_finite() && (0.0..=1.0).contains(&a.value)) {
            return Err(e(
                sloc(a),
                format!(
                    "{key}.phase_type.alpha[{}] = {} is not a probability",
                    i + 1,
                    a.value
                ),
                help(),
            ));
        }
    }
    for (i, row) in t.value.iter().enumerate() {
        if row.value.len() != n {
            return Err(e(
                sloc(row),
                format!(
                    "row {} of `{key}.phase_type.T` has {} entries, not {n}",
                    i + 1,
                    row.value.len()
                ),
                help(),
            ));
        }
        for (j, x) in row.value.iter().enumerate() {
            let v = x.value;
            let ok = v.is_finite() && if i == j { v < 0.0 } else { v >= 0.0 };
            if !ok {
                let want = if i == j { "< 0" } else { ">= 0" };
                return Err(e(
                    sloc(x),
                    format!(
                        "{key}.phase_type.T[{}][{}] = {v} must be a finite number {want}",
                        i + 1,
                        j + 1
                    ),
                    help(),
                ));
            }
        }
    }
    let a: Vec<f64> = alpha.value.iter().map(|x| x.value).collect();
    let m: Vec<Vec<f64>> = t
        .value
        .iter()
        .map(|r| r.value.iter().map(|x| x.value).collect())
        .collect();
    Stages::general(&a, &m).map_err(|w| e(sloc(ph), format!("`{key}.phase_type`: {w}"), help()))
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
    // `success_time` / `failure_time`: one law per outcome, the outcomes
    // independent (a mixture, never the hybrid race of `mu` + `tau_f`)
    let laws = [
        (
            &p.success_time,
            "success_time",
            [(&p.mu, "mu"), (&p.tau_s, "tau_s")],
            (&p.tau_f, "tau_f"),
        ),
        (
            &p.failure_time,
            "failure_time",
            [(&p.nu, "nu"), (&p.tau_f, "tau_f")],
            (&p.tau_s, "tau_s"),
        ),
    ];
    for (law, key, same, other) in &laws {
        let Some(law) = law else { continue };
        for (v, k) in same {
            if let Some(v) = v {
                return Err(e(
                    sloc(v).max(sloc(law)),
                    format!("both `{k}` and `{key}` give the {} time", &key[..7]),
                    format!("give `{key}` or `{k}`, not both"),
                ));
            }
        }
        if let (Some(v), k) = other {
            return Err(e(
                sloc(v).max(sloc(law)),
                format!("`{k}` with `{key}`"),
                format!(
                    "`{k}` next to a rate is the hybrid time of Def. 9.9 (the rate's time cut \
                     at `{k}`), which `{key}` does not take; write the other outcome's time as \
                     `{}: {{fixed: t}}` (independent of this one)",
                    if key.starts_with("success") {
                        "failure_time"
                    } else {
                        "success_time"
                    }
                ),
            ));
        }
    }
    let success_law = p
        .success_time
        .as_ref()
        .map(|d| time_law("success_time", d, e))
        .transpose()?;
    let failure_law = p
        .failure_time
        .as_ref()
        .map(|d| time_law("failure_time", d, e))
        .transpose()?;
    let mu = p.mu.as_ref().map(|v| rate("mu", v)).transpose()?;
    let nu = p.nu.as_ref().map(|v| rate("nu", v)).transpose()?;
    let tau_s = p.tau_s.as_ref().map(|v| time("tau_s", v)).transpose()?;
    let tau_f = p.tau_f.as_ref().map(|v| time("tau_f", v)).transpose()?;
    let mut missing = Vec::new();
    if ps > 0.0 && mu.is_none() && tau_s.is_none() && success_law.is_none() {
        missing.push(format!(
            "can succeed (ps = {ps}) but has no success time: add `mu` (1/s), `tau_s` (s) or \
             `success_time`"
        ));
    }
    if pf > 0.0 && nu.is_none() && tau_f.is_none() && failure_law.is_none() {
        missing.push(format!(
            "can fail (pf = {pf}) but has no failure time: add `nu` (1/s), `tau_f` (s) or \
             `failure_time`"
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
    let success = success_law.or(success);
    let failure = failure_law.or(failure);
    Ok(Ok(Action {
        ps,
        pf,
        success: success.filter(|_| ps > 0.0),
        failure: failure.filter(|_| pf > 0.0),
    }))
}
