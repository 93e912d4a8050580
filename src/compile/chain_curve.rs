//! Curves of phase chains, the numerics every representation shares: a
//! chain's `π(t)` by uniformization or dense exponentials, a shifted
//! phase-type law's by its components' chains, and weighted sampling of a
//! chain for the composed laws (a leaf module of the engine: it uses no
//! representation).

use super::curve_options::{CurveOptions, CurvePoint, DENSE_TOLERANCE};
use super::{shifted, AnalysisError};
use crate::solve::chain::PhaseChain;
use crate::solve::expm;
use crate::solve::transient::{self, uniformization_work, WeightedSteps};

/// Dropped Poisson mass in each sampled density (the composed laws'
/// chains, by uniformization).
pub(crate) const SAMPLE_TOLERANCE: f64 = 1e-16;

/// The times at or after `shift` (strictly after with `left`: a left
/// limit, the mass that returns exactly at `shift` not yet counted), as
/// their indices and their times since `shift`. An instant within
/// rounding of `shift` is `shift`.
#[inline]
pub(crate) fn shifted_times(times: &[f64], shift: f64, left: bool) -> (Vec<usize>, Vec<f64>) {
    times
        .iter()
        .enumerate()
        .filter(|&(_, &t)| {
            let at = crate::tree::same_instant(t, shift);
            if left {
                t > shift && !at
            } else {
                t > shift || at
            }
        })
        .map(|(k, &t)| (k, (t - shift).max(0.0)))
        .unzip()
}

/// `π(t)` from a shifted phase-type law ([`shifted`]): each outcome's
/// `Σ w · A(t − τ)`, every component's chain solved like any chain.
pub(crate) fn curve_by_shifted(
    law: &shifted::ShiftedLaw,
    times: &[f64],
    options: &CurveOptions,
    name: &str,
) -> Result<Vec<CurvePoint>, AnalysisError> {
    let mut sums = vec![[0.0f64; 2]; times.len()];
    for (o, part) in [&law.success, &law.failure].into_iter().enumerate() {
        for c in part {
            let (idx, local) = shifted_times(times, c.shift, false);
            if idx.is_empty() {
                continue;
            }
            if c.chain.is_empty() {
                for &k in &idx {
                    sums[k][o] += c.weight * c.chain.initial_success;
                }
                continue;
            }
            let points = solve_chain(&c.chain, &local, options, name)?;
            for (&k, p) in idx.iter().zip(&points) {
                sums[k][o] += c.weight * p.success;
            }
        }
    }
    Ok(times
        .iter()
        .zip(sums)
        .map(|(&t, [s, f])| {
            let (success, failure) = (s.clamp(0.0, 1.0), f.clamp(0.0, 1.0));
            CurvePoint {
                t,
                success,
                failure,
                running: (1.0 - success - failure).max(0.0),
            }
        })
        .collect())
}

pub(crate) fn solve_chain(
    chain: &PhaseChain,
    times: &[f64],
    options: &CurveOptions,
    name: &str,
) -> Result<Vec<CurvePoint>, AnalysisError> {
    let work = uniformization_work(chain, times);
    let small = chain.len() + 2 <= expm::MAX_DENSE_STATES;
    // the cheaper of the two: uniformization needs ~Λt steps, the dense
    // exponential of a small chain costs the same at any horizon
    let dense = small && expm::dense_work(chain, times) < work;
    let points = if !dense && work <= options.max_work {
        transient::transient(chain, times, options.tolerance)
    } else if small {
        // long horizon or stiff, but small: dense exponentials with a
        // rigorous bound
        let (points, bound) = expm::transient_dense(chain, times);
        if bound > options.tolerance.max(DENSE_TOLERANCE) {
            return Err(AnalysisError::Numerical {
                node: name.to_string(),
                what: format!("the error bound {bound:.1e} of the stiff solver is too large"),
            });
        }
        points
    } else {
        return Err(AnalysisError::Stiff {
            node: name.to_string(),
            work,
            limit: options.max_work,
        });
    };
    for p in &points {
        if ![p.success, p.failure, p.running]
            .iter()
            .all(|x| x.is_finite())
        {
            return Err(AnalysisError::Numerical {
                node: name.to_string(),
                what: format!("non-finite probability at t = {}", p.t),
            });
        }
    }
    Ok(points)
}

/// `[S, F, π·h₁, ...]` at `points` by one uniformization pass, or — when that
/// would take too many steps (a stiff chain over a long horizon) and the
/// chain is small — by dense exponentials whose bound is below the sampling
/// tolerance; `None` otherwise.
pub(crate) fn sample_weighted(
    chain: &PhaseChain,
    points: &[f64],
    weights: &[&[f64]],
) -> Option<Vec<Vec<f64>>> {
    sample_weighted_kept(&mut None, chain, points, weights)
}

/// [`sample_weighted`] for a caller that samples the same chain again (an
/// adaptive interpolation's rounds): the uniformization pass is kept in
/// `pass` and extended, not run again from 0.
pub(crate) fn sample_weighted_kept(
    pass: &mut Option<WeightedSteps>,
    chain: &PhaseChain,
    points: &[f64],
    weights: &[&[f64]],
) -> Option<Vec<Vec<f64>>> {
    // phases that only exit (an action, a mixture of exponentials): closed
    // form, π_i(t) = p_i e^{−q_i t}
    if chain.transitions.iter().all(Vec::is_empty) {
        return Some(
            points
                .iter()
                .map(|&t| {
                    let mut row = vec![chain.initial_success, chain.initial_failure];
                    row.resize(2 + weights.len(), 0.0);
                    for &(i, p) in &chain.initial {
                        let q = chain.total_rate(i);
                        let (alive, gone) = ((-q * t).exp(), -(-q * t).exp_m1());
                        if q > 0.0 {
                            row[0] += p * chain.exit_success[i] / q * gone;
                            row[1] += p * chain.exit_failure[i] / q * gone;
                        }
                        for (k, w) in weights.iter().enumerate() {
                            row[2 + k] += p * alive * w[i];
                        }
                    }
                    row
                })
                .collect(),
        );
    }
    let rows = WeightedSteps::with_kept(pass, chain, weights, |s| {
        s.rows_by_cost(points, SAMPLE_TOLERANCE)
    });
    if let Some(rows) = rows {
        return Some(rows);
    }
    if chain.len() + 2 > expm::MAX_DENSE_STATES {
        return None;
    }
    let (rows, bound) = expm::transient_dense_weighted(chain, points, weights);
    (bound <= DENSE_TOLERANCE).then_some(rows)
}
