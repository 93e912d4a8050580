//! Parallel nodes with the book's thresholds (`F = N − M + 1`) by counting
//! children instead of building their product chain.
//!
//! # Why counting is exact
//!
//! Until a Parallel node returns, its N children run independently. Take
//! the children *unhalted* (each runs to its own end) and let `K_t` (`J_t`)
//! be the number that have succeeded (failed) by t. The node's thresholds
//! cannot both be met, since `M + (N − M + 1) > N`: if `J_∞ ≥ F` then
//! `K_∞ ≤ N − F = M − 1`. Hence the node returns Success iff `K_∞ ≥ M`, and
//! then at the M-th success time (the F-th failure never comes); it has
//! succeeded by t iff `K_t ≥ M`. Halting the other children when the node
//! returns changes nothing about these events. So
//!
//! * `P(S) = P(K_∞ ≥ M)`, `S(t) = P(K_t ≥ M)`, and likewise for Failure with
//!   `J` and `F` — a dynamic programme over the children with the counts
//!   capped at the thresholds ([`status_by_counts`]);
//! * `E[T·1{S}] = ∫₀^∞ P(S, T > t) dt` with
//!   `g(t) = P(S, T > t) = P(K_t < M ≤ K_∞)`. Each child is, at time t, in
//!   one of three classes: *done* (succeeded by t, probability `S_h(t)`),
//!   *pending* (running, will succeed: `s_h − S_h(t)`) or *never* (will not
//!   succeed: `1 − s_h`), independently; `g(t)` sums the products over
//!   assignments with fewer than M done and at least M done or pending
//!   ([`pending_by_counts`], O(N·M²)).
//!
//! # The integral, with a rigorous bound
//!
//! `∫₀^∞ g` is computed by composite Gauss–Legendre quadrature on panels
//! that grow geometrically from `0.1/Σ_h Λ_h` (Λ_h the child's largest exit
//! rate), and the returned bound adds three parts:
//!
//! 1. **Quadrature.** `g` is entire: each child's `S_h(t) = a₀ + Σ_k
//!    Pois(k; Λt) a_k` and `s_h − S_h(t) = π₀ e^{Qt} h_S` are uniformization
//!    series with non-negative coefficients, so for complex `z = x + iy`,
//!    `|S_h(z)| ≤ e^{Λ(|z|−x)} S_h(|z|)` and `|s_h − S_h(z)| ≤ e^{Λ(|z|−x)}
//!    (s_h − S_h(|z|))`. On the Bernstein ellipse of a panel `|z| − x` is
//!    bounded by [`Ellipse::excess`], `|z|` lies between the panel's
//!    neighbouring end points (the ellipse is sized so), and both functions
//!    are monotone in real time; putting these bounds into the same
//!    programme (all terms non-negative) bounds `|g|` on the ellipse, and
//!    [`GaussLegendre::error_bound`] the panel's error. The best of several
//!    ellipses is taken, and panels are split until the sum is small.
//! 2. **Tail.** `g(t) ≤ Σ_h (s_h − S_h(t)) q_h`, where `q_h` is the
//!    probability that at least M − 1 of the other children eventually
//!    reach the outcome (a pending child is needed, and it matters only
//!    then), and `∫_T^∞ (s_h − S_h) = π_h(T)·m_h` with `m_h` the per-phase
//!    `E_i[T·1{S}]` (computed alongside, [`absorption_by_phase`]).
//! 3. **Evaluation.** Children's figures come from closed forms (a child
//!    whose phases exit directly, such as an action) or from uniformization
//!    with dropped Poisson mass ≤ 1e-15 (error ≤ 2e-15 times the child's
//!    probability of the outcome); `g` is multilinear, and its
//!    partial derivatives in child h's inputs lie in `[0, q_h]`, so its
//!    error is at most `Σ_h (error of done + error of pending)·q_h`, times
//!    the horizon.
//! 4. **Rounding** is *estimated*, not bounded: uniformization raises the
//!    rounded `1 − q/Λ` to about Λt powers, which shifts a slow rate q by
//!    about `(Λ/q)·u` relative (u the unit roundoff; an independent 50-digit
//!    check found errors up to 8e-12 with Λ/q = 2e5, where the three bounds
//!    above gave 3e-13). The term `4u·max_h(Λ_h/q_h,min)` per child, plus
//!    `4u` for the sums, times the integral, is added to the bound; so the
//!    bound is rigorous for truncation, quadrature and tail, and a
//!    first-order estimate for rounding.
//!
//! The analysis accepts the result only if the bound is below 1e-9 of the
//! integral (in practice it is ~1e-12). Children with fast and slow phases
//! over a long horizon are not integrated here at all
//! ([`crate::compile::STIFF_STEPS`]): the ellipse bounds grow like
//! `e^{Λ·width}` and the panels would have to be tiny.

use crate::solve::chain::PhaseChain;
use crate::solve::quadrature::{Ellipse, GaussLegendre};
use crate::solve::transient::{
    absorption_by_phase, transient_split_kept, PhaseAbsorption, SplitPoint, WeightedSteps,
};

/// Truncation error allowed for each uniformized figure of a child.
const CHILD_TOLERANCE: f64 = 1e-15;

/// Points of the Gauss–Legendre rule on each panel.
const RULE_POINTS: usize = 16;

/// Target of the bound relative to the integral, and the largest accepted.
const TARGET: f64 = 1e-11;
/// Largest relative bound accepted.
pub const ACCEPTED: f64 = 1e-9;

/// `(P(≥ M succeeded), P(≥ F failed))` from each child's
/// `(P(succeeded), P(failed))` at one time: the trinomial count programme
/// with both counts capped at their thresholds (see the module docs).
pub fn status_by_counts(points: &[(f64, f64)], m: usize, f_cap: usize) -> (f64, f64) {
    let with_densities: Vec<[f64; 4]> = points.iter().map(|&(s, f)| [s, f, 0.0, 0.0]).collect();
    let [success, failure, _, _] = status_and_densities_by_counts(&with_densities, m, f_cap);
    (success, failure)
}

/// [`status_by_counts`] with time derivatives: from each child's
/// `[S_h, F_h, s_h, f_h]` (probabilities of having succeeded and failed by
/// t and their densities) the node's `[S, F, s, f]`. The programme is
/// multilinear in the children's inputs, so it is run in dual numbers
/// (value, derivative): a child's running probability `1 − S_h − F_h` has
/// derivative `−s_h − f_h`.
pub(crate) fn status_and_densities_by_counts(
    points: &[[f64; 4]],
    m: usize,
    f_cap: usize,
) -> [f64; 4] {
    let width = f_cap + 1;
    // (value, derivative) per cell
    let mut dp = vec![(0.0f64, 0.0f64); (m + 1) * width];
    dp[0] = (1.0, 0.0);
    for &[ps, pf, ds, df] in points {
        let running = (1.0 - ps - pf).max(0.0);
        let d_running = -ds - df;
        for s in (0..m).rev() {
            for f in (0..f_cap).rev() {
                let (x, dx) = dp[s * width + f];
                if x == 0.0 && dx == 0.0 {
                    continue;
                }
                dp[s * width + f] = (x * running, dx * running + x * d_running);
                let up = &mut dp[(s + 1) * width + f];
                *up = (up.0 + x * ps, up.1 + dx * ps + x * ds);
                let right = &mut dp[s * width + f + 1];
                *right = (right.0 + x * pf, right.1 + dx * pf + x * df);
            }
        }
    }
    let mut out = [0.0; 4];
    for &(v, d) in &dp[m * width..] {
        out[0] += v;
        out[2] += d;
    }
    for s in 0..m {
        let (v, d) = dp[s * width + f_cap];
        out[1] += v;
        out[3] += d;
    }
    out
}

/// `Σ Π` over assignments of each child to *done* / *pending* / *never`
/// (weights `(u, v, w)`) with fewer than `m` done and at least `m` done or
/// pending. With probabilities it is `P(K_t < m ≤ K_∞)`; with upper bounds
/// of moduli it bounds the modulus of that function. `scratch` is reused.
pub fn pending_by_counts(
    weights: impl Iterator<Item = (f64, f64, f64)>,
    m: usize,
    scratch: &mut Vec<f64>,
) -> f64 {
    if m == 0 {
        return 0.0;
    }
    let width = m + 1;
    scratch.clear();
    scratch.resize(m * width, 0.0);
    let dp = scratch;
    dp[0] = 1.0;
    for (u, v, w) in weights {
        for a in (0..m).rev() {
            for b in (a..=m).rev() {
                let x = dp[a * width + b];
                if x == 0.0 {
                    continue;
                }
                let nb = (b + 1).min(m);
                if b == m {
                    dp[a * width + b] = x * (w + v);
                } else {
                    dp[a * width + b] = x * w;
                    dp[a * width + nb] += x * v;
                }
                if a + 1 < m {
                    dp[(a + 1) * width + nb] += x * u;
                }
            }
        }
    }
    (0..m).map(|a| dp[a * width + m]).sum()
}

/// One child of a Parallel node, ready to be evaluated at any times.
#[derive(Debug, Clone)]
pub struct ChildLaw {
    chain: PhaseChain,
    absorption: PhaseAbsorption,
    /// Probability that the child ends in Success.
    pub success: f64,
    /// Probability that the child ends in Failure.
    pub failure: f64,
    rate: f64,
    /// `E[T·1{Success}]`, `E[T·1{Failure}]` from the start.
    time: [f64; 2],
    closed_form: bool,
    /// Largest exit rate over the smallest (`Λ/q_min`): rounding in
    /// uniformization is about this many unit roundoffs, relative.
    stiffness: f64,
    /// The uniformization pass, kept across the quadrature's rounds (each
    /// asks new times: the pass is extended, not run again from 0).
    pass: std::cell::RefCell<Option<WeightedSteps>>,
}

/// A child's figures at one time. Each is a Poisson average of a sequence
/// `π₀Pᵏ·h` (non-negative `h` with `h ≥ P h`, so non-increasing in k and at
/// most its start `π₀·h`; or the absorbed mass, at most its limit), truncated
/// with dropped mass ≤ `error`: after renormalising, its absolute error is at
/// most `2·error` times the child's probability of the outcome (or its
/// `E[T·1{outcome}]` for the time integrals).
#[derive(Debug, Clone, Copy)]
struct ChildPoint {
    at: SplitPoint,
    error: f64,
    /// ln of an upper bound on `running_to_success` (exact for closed forms).
    ln_to_success: f64,
    ln_to_failure: f64,
}

impl ChildLaw {
    /// Prepares a child from its exact phase chain.
    pub fn new(chain: PhaseChain) -> ChildLaw {
        let absorption = absorption_by_phase(&chain);
        let start = |h: &[f64]| chain.initial.iter().map(|&(i, p)| p * h[i]).sum::<f64>();
        let success = chain.initial_success + start(&absorption.to_success);
        let failure = chain.initial_failure + start(&absorption.to_failure);
        let rate = (0..chain.len())
            .map(|i| chain.total_rate(i))
            .fold(0.0, f64::max);
        let time = [
            start(&absorption.time_to_success),
            start(&absorption.time_to_failure),
        ];
        let closed_form = chain.transitions.iter().all(Vec::is_empty);
        let slowest = (0..chain.len())
            .map(|i| chain.total_rate(i))
            .fold(f64::INFINITY, f64::min);
        // closed forms are evaluated directly, without powers of 1 − q/Λ
        let stiffness = if closed_form || chain.is_empty() {
            0.0
        } else {
            rate / slowest
        };
        ChildLaw {
            stiffness,
            time,
            chain,
            absorption,
            success,
            failure,
            rate,
            closed_form,
            pass: Default::default(),
        }
    }

    fn at(&self, times: &[f64]) -> Result<Vec<ChildPoint>, String> {
        if self.closed_form {
            // every phase exits directly: π_i(t) = α_i e^{−q_i t}
            let terms: Vec<(f64, f64, f64)> = self
                .chain
                .initial
                .iter()
                .map(|&(i, p)| (p, self.chain.total_rate(i), self.absorption.to_success[i]))
                .collect();
            let ln_sum = |t: f64, h: &dyn Fn(f64) -> f64| {
                let logs: Vec<f64> = terms
                    .iter()
                    .filter(|&&(p, _, hs)| p * h(hs) > 0.0)
                    .map(|&(p, q, hs)| (p * h(hs)).ln() - q * t)
                    .collect();
                let top = logs.iter().copied().fold(f64::NEG_INFINITY, f64::max);
                if top == f64::NEG_INFINITY {
                    top
                } else {
                    top + logs.iter().map(|l| (l - top).exp()).sum::<f64>().ln()
                }
            };
            return Ok(times
                .iter()
                .map(|&t| {
                    let mut at = SplitPoint {
                        t,
                        success: self.chain.initial_success,
                        failure: self.chain.initial_failure,
                        running_to_success: 0.0,
                        running_to_failure: 0.0,
                        time_to_success: 0.0,
                        time_to_failure: 0.0,
                    };
                    for &(p, q, hs) in &terms {
                        let (gone, left) = (-(-q * t).exp_m1(), (-q * t).exp());
                        at.success += p * hs * gone;
                        at.failure += p * (1.0 - hs) * gone;
                        at.running_to_success += p * hs * left;
                        at.running_to_failure += p * (1.0 - hs) * left;
                        at.time_to_success += p * hs * left / q;
                        at.time_to_failure += p * (1.0 - hs) * left / q;
                    }
                    ChildPoint {
                        at,
                        error: 0.0,
                        ln_to_success: ln_sum(t, &|hs| hs),
                        ln_to_failure: ln_sum(t, &|hs| 1.0 - hs),
                    }
                })
                .collect());
        }
        let (success, failure) = (self.success, self.failure);
        let points = transient_split_kept(
            &mut self.pass.borrow_mut(),
            &self.chain,
            times,
            CHILD_TOLERANCE,
            &self.absorption,
        )
        .ok_or("a child is too stiff for uniformization over the horizon of its mean times")?;
        Ok(points
            .into_iter()
            .map(|at| ChildPoint {
                at,
                error: CHILD_TOLERANCE,
                ln_to_success: (at.running_to_success + 2.0 * CHILD_TOLERANCE * success).ln(),
                ln_to_failure: (at.running_to_failure + 2.0 * CHILD_TOLERANCE * failure).ln(),
            })
            .collect())
    }
}

/// Which outcome's mean time is integrated.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Side {
    Success,
    Failure,
}

impl Side {
    /// (done, pending, ln pending bound) of a child at a point.
    fn split(self, p: &ChildPoint) -> (f64, f64, f64) {
        match self {
            Side::Success => (p.at.success, p.at.running_to_success, p.ln_to_success),
            Side::Failure => (p.at.failure, p.at.running_to_failure, p.ln_to_failure),
        }
    }

    fn total(self, c: &ChildLaw) -> f64 {
        match self {
            Side::Success => c.success,
            Side::Failure => c.failure,
        }
    }

    /// Upper bound on `∫_t^∞ P(child pending at u) du` from a point.
    fn tail(self, c: &ChildLaw, p: &ChildPoint) -> f64 {
        let (time, total) = match self {
            Side::Success => (p.at.time_to_success, c.time[0]),
            Side::Failure => (p.at.time_to_failure, c.time[1]),
        };
        time + 2.0 * p.error * total
    }

    /// Absolute errors of (done, pending) at a point.
    fn errors(self, c: &ChildLaw, p: &ChildPoint) -> (f64, f64) {
        let e = 2.0 * p.error * self.total(c);
        (e, e)
    }

    /// The child's mean time to this outcome, given it (0 if impossible).
    fn mean(self, c: &ChildLaw) -> f64 {
        let (p, h) = match self {
            Side::Success => (c.success, &c.absorption.time_to_success),
            Side::Failure => (c.failure, &c.absorption.time_to_failure),
        };
        let m: f64 = c.chain.initial.iter().map(|&(i, a)| a * h[i]).sum();
        if p > 0.0 {
            m / p
        } else {
            0.0
        }
    }
}

/// `P(outcome)`, `E[T·1{outcome}]` and a rigorous bound on the latter's
/// absolute error.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CertifiedMean {
    /// Probability of the outcome.
    pub probability: f64,
    /// `E[T·1{outcome}]`.
    pub time: f64,
    /// Bound on the absolute error of `time`.
    pub bound: f64,
}

/// Success and Failure of a Parallel node with `m` of `children.len()` to
/// succeed and the book's failure threshold, by counting (module docs).
pub fn parallel_means(
    children: &[ChildLaw],
    m: usize,
) -> Result<(CertifiedMean, CertifiedMean), String> {
    let n = children.len();
    let f_cap = n + 1 - m;
    let rule = GaussLegendre::new(RULE_POINTS);
    Ok((
        side_mean(children, m, Side::Success, &rule)?,
        side_mean(children, f_cap, Side::Failure, &rule)?,
    ))
}

fn side_mean(
    children: &[ChildLaw],
    m: usize,
    side: Side,
    rule: &GaussLegendre,
) -> Result<CertifiedMean, String> {
    let mut scratch = Vec::new();
    let probability = pending_by_counts(
        children
            .iter()
            .map(|c| (0.0, side.total(c), 1.0 - side.total(c))),
        m,
        &mut scratch,
    );
    let lam_sum: f64 = children.iter().map(|c| c.rate).sum();
    let zero = CertifiedMean {
        probability,
        time: 0.0,
        bound: 0.0,
    };
    if probability <= 0.0 || lam_sum == 0.0 {
        return Ok(zero);
    }
    // q_h = P(at least m − 1 of the others reach the outcome): child h
    // matters to g only then, which bounds ∂g/∂(child h) and its share of
    // the tail
    let others: Vec<f64> = (0..children.len())
        .map(|h| {
            if m == 1 {
                return 1.0;
            }
            let rest = children
                .iter()
                .enumerate()
                .filter(|&(j, _)| j != h)
                .map(|(_, c)| (0.0, side.total(c), 1.0 - side.total(c)));
            pending_by_counts(rest, m - 1, &mut scratch)
        })
        .collect();
    let scale = children.iter().map(|c| side.mean(c)).fold(0.0, f64::max);
    let first = 0.1 / lam_sum;
    // end points: 0, then geometric growth by 30% per panel
    let mut ends = vec![0.0, first];
    let extend = |ends: &mut Vec<f64>, to: f64| {
        while *ends.last().expect("non-empty") < to {
            let last = *ends.last().expect("non-empty");
            ends.push(last * 1.3);
        }
    };
    extend(&mut ends, 32.0 * scale);
    let mut result = zero;
    let mut parts = [0.0; 3];
    for _ in 0..40 {
        // the last panel's right neighbour, for its ellipse
        let k = ends.len() - 1;
        let extra = ends[k] + (ends[k] - ends[k - 1]);
        let mut times: Vec<f64> = ends.clone();
        times.push(extra);
        let panels = k;
        for p in 0..panels {
            let (c, h) = ((ends[p] + ends[p + 1]) / 2.0, (ends[p + 1] - ends[p]) / 2.0);
            times.extend(rule.nodes.iter().map(|x| c + h * x));
        }
        let values = children
            .iter()
            .map(|c| c.at(&times))
            .collect::<Result<Vec<_>, _>>()?;
        let at = |child: usize, idx: usize| side.split(&values[child][idx]);
        // integral and per-panel bounds
        let mut integral = 0.0;
        let mut panel_bounds = vec![0.0; panels];
        for (p, panel_bound) in panel_bounds.iter_mut().enumerate() {
            let (a, b) = (ends[p], ends[p + 1]);
            let h = (b - a) / 2.0;
            let base = ends.len() + 1 + p * rule.len();
            for (j, w) in rule.weights.iter().enumerate() {
                let g = pending_by_counts(
                    (0..children.len()).map(|ci| {
                        let (done, pending, _) = at(ci, base + j);
                        (done, pending, 1.0 - side.total(&children[ci]))
                    }),
                    m,
                    &mut scratch,
                );
                integral += w * h * g;
            }
            // ellipses that stay between the neighbouring end points
            let right_idx = p + 2; // ends[p + 2], or `extra` (index ends.len())
            let gap_right = times[right_idx] - b;
            let gap = if p == 0 {
                gap_right
            } else {
                gap_right.min(a - ends[p - 1])
            };
            let left_idx = p.saturating_sub(1);
            let rho_max = Ellipse::largest_rho(a, b, gap).min(64.0);
            let mut best = f64::INFINITY;
            for rho in [1.25, 1.5, 2.0, 3.0, 4.0, 6.0, 8.0, 16.0, 32.0, rho_max] {
                if rho > rho_max || rho <= 1.0 {
                    continue;
                }
                let e = Ellipse::new(a, b, rho).excess();
                let big_m = pending_by_counts(
                    children.iter().enumerate().map(|(ci, c)| {
                        let grow = c.rate * e;
                        let (_, _, ln_pending) = at(ci, left_idx);
                        let v = if ln_pending == f64::NEG_INFINITY {
                            0.0
                        } else {
                            (grow + ln_pending).exp()
                        };
                        let (done_right, _, _) = at(ci, right_idx);
                        let (err, _) = side.errors(c, &values[ci][right_idx]);
                        let u = (grow.exp() * (done_right + err)).min(side.total(c) + v);
                        (u, v, 1.0 - side.total(c))
                    }),
                    m,
                    &mut scratch,
                );
                best = best.min(rule.error_bound(h, rho, big_m));
            }
            *panel_bound = best;
        }
        let horizon = ends[k];
        let tail: f64 = values
            .iter()
            .zip(children)
            .zip(&others)
            .map(|((v, c), q)| side.tail(c, &v[k]) * q)
            .sum();
        // the part of the tail bound that a longer horizon cannot reduce
        let tail_floor: f64 = values
            .iter()
            .zip(children)
            .zip(&others)
            .map(|((v, c), q)| 2.0 * v[k].error * (c.time[0] + c.time[1]) * q)
            .sum();
        let evaluation: f64 = horizon
            * values
                .iter()
                .zip(children)
                .zip(&others)
                .map(|((v, c), q)| {
                    let (done, pending) = side.errors(c, &v[0]);
                    (done + pending) * q
                        + 4.0 * f64::EPSILON * (1.0 + c.stiffness) * integral / horizon
                })
                .sum::<f64>();
        let quadrature: f64 = panel_bounds.iter().sum();
        let bound = quadrature + tail + evaluation;
        result = CertifiedMean {
            probability,
            time: integral,
            bound,
        };
        parts = [quadrature, tail, evaluation];
        let target = TARGET * integral;
        if bound <= target {
            break;
        }
        let mut changed = false;
        if tail > target / 3.0 && tail > 2.0 * tail_floor {
            let to = horizon * 2.0;
            extend(&mut ends, to);
            changed = true;
        }
        if quadrature > target / 3.0 || !quadrature.is_finite() {
            let share = target / 3.0 / panels as f64;
            let mut refined = Vec::with_capacity(ends.len() * 2);
            for p in 0..panels {
                refined.push(ends[p]);
                if panel_bounds[p] > share || panel_bounds[p].is_nan() {
                    refined.push((ends[p] + ends[p + 1]) / 2.0);
                    changed = true;
                }
            }
            refined.extend_from_slice(&ends[panels..]);
            ends = refined;
        }
        if !changed || ends.len() > 200_000 {
            break;
        }
    }
    let accepted = result.bound <= ACCEPTED * result.time;
    if !accepted {
        return Err(format!(
            "could not bound the mean time's integral well enough: bound {:.1e} on {:.6e} \
             (quadrature {:.1e}, tail {:.1e}, evaluation {:.1e})",
            result.bound, result.time, parts[0], parts[1], parts[2]
        ));
    }
    Ok(result)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn brute_pending(cats: &[(f64, f64, f64)], m: usize) -> f64 {
        let n = cats.len();
        let mut total = 0.0;
        for code in 0..3usize.pow(n as u32) {
            let (mut c, mut done, mut reach, mut prod) = (code, 0, 0, 1.0);
            for &(u, v, w) in cats {
                match c % 3 {
                    0 => {
                        prod *= u;
                        done += 1;
                        reach += 1;
                    }
                    1 => {
                        prod *= v;
                        reach += 1;
                    }
                    _ => prod *= w,
                }
                c /= 3;
            }
            if done < m && reach >= m {
                total += prod;
            }
        }
        total
    }

    #[test]
    fn pending_programme_matches_enumeration() {
        let cats = [
            (0.1, 0.3, 0.6),
            (0.5, 0.2, 0.3),
            (0.0, 0.9, 0.1),
            (0.25, 0.25, 0.5),
            (0.7, 0.1, 0.2),
        ];
        for m in 1..=5 {
            let mut s = Vec::new();
            let dp = pending_by_counts(cats.iter().copied(), m, &mut s);
            assert!((dp - brute_pending(&cats, m)).abs() < 1e-15, "m={m}");
        }
    }

    #[test]
    fn one_action_mean_is_its_own() {
        // a Parallel of one action: MTTS = 1/mu, MTTF = 1/nu
        let chain = PhaseChain {
            initial: vec![(0, 0.3), (1, 0.7)],
            transitions: vec![vec![], vec![]],
            exit_success: vec![2.0, 0.0],
            exit_failure: vec![0.0, 0.5],
            ..Default::default()
        };
        let (s, f) = parallel_means(&[ChildLaw::new(chain)], 1).unwrap();
        assert!((s.probability - 0.3).abs() < 1e-15);
        assert!((s.time / s.probability - 0.5).abs() < 1e-12, "{s:?}");
        assert!((f.time / f.probability - 2.0).abs() < 1e-12, "{f:?}");
        assert!(s.bound < 1e-10 * s.time && f.bound < 1e-10 * f.time);
    }

    #[test]
    fn densities_by_counts_match_enumeration() {
        // children as (S, F, s, f); node: S = P(≥ m succeeded), F = P(≥ f
        // failed); the densities by enumerating the 3^n outcomes of the
        // children and differentiating each product by the product rule
        let kids = [
            [0.1, 0.2, 0.5, 0.3],
            [0.4, 0.1, 0.2, 0.7],
            [0.0, 0.6, 1.5, 0.1],
            [0.3, 0.3, 0.05, 0.4],
        ];
        for m in 1..=4 {
            let f_cap = kids.len() - m + 1;
            let mut want = [0.0; 4];
            for code in 0..3usize.pow(kids.len() as u32) {
                let digits: Vec<usize> = (0..kids.len())
                    .map(|h| code / 3usize.pow(h as u32) % 3)
                    .collect();
                let factor = |h: usize, d: bool| {
                    let [ps, pf, ds, df] = kids[h];
                    match (digits[h], d) {
                        (0, false) => ps,
                        (0, true) => ds,
                        (1, false) => pf,
                        (1, true) => df,
                        (_, false) => 1.0 - ps - pf,
                        (_, true) => -ds - df,
                    }
                };
                let value: f64 = (0..kids.len()).map(|h| factor(h, false)).product();
                let derivative: f64 = (0..kids.len())
                    .map(|j| (0..kids.len()).map(|h| factor(h, h == j)).product::<f64>())
                    .sum();
                let succeeded = digits.iter().filter(|&&d| d == 0).count();
                let failed = digits.iter().filter(|&&d| d == 1).count();
                if succeeded >= m {
                    want[0] += value;
                    want[2] += derivative;
                } else if failed >= f_cap {
                    want[1] += value;
                    want[3] += derivative;
                }
            }
            let got = status_and_densities_by_counts(&kids, m, f_cap);
            for c in 0..4 {
                assert!(
                    (got[c] - want[c]).abs() < 1e-14,
                    "m={m} c={c}: {got:?} vs {want:?}"
                );
            }
            let plain = status_by_counts(&kids.map(|k| (k[0], k[1])), m, f_cap);
            assert!((plain.0 - got[0]).abs() < 1e-15 && (plain.1 - got[1]).abs() < 1e-15);
        }
    }
}
