//! Transient analysis of phase chains by uniformization.
//!
//! For a CTMC with generator `Q` and uniformization rate `Λ ≥ max_i q_i`,
//! `P = I + Q/Λ` is stochastic and
//!
//! ```text
//! π(t) = Σ_{k≥0} e^{-Λt} (Λt)^k / k! · π(0) P^k .
//! ```
//!
//! The series is truncated at both ends around the mode of the Poisson
//! weights (the idea of Fox and Glynn, 1988), with rigorous bounds on the
//! mass dropped: beyond `k > Λt` successive weights fall at least by the
//! ratio `Λt/(k+2)`, so the right tail after index `R` is at most
//! `w_{R+1} / (1 − Λt/(R+2))`; below the mode the ratio `k/Λt` bounds the
//! left tail in the same way ([`poisson_window`]). `P^k` is stochastic, so
//! dropping Poisson mass `δ` changes every probability by at most `δ`; the
//! kept weights are renormalised.
//!
//! [`transient`] needs one pass to the horizon for all requested times
//! (each time point's error is bounded separately, by `tolerance`, default
//! 1e-13); [`transient_by_intervals`] restarts on each interval and splits
//! the budget, for horizons too long to keep the per-step absorbed masses.

use super::chain::PhaseChain;

/// Probabilities of having returned Success and Failure by each time.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CurvePoint {
    /// The time.
    pub t: f64,
    /// P(returned Success by t).
    pub success: f64,
    /// P(returned Failure by t).
    pub failure: f64,
    /// P(still running at t) = 1 − success − failure.
    pub running: f64,
}

/// Error budget of the truncated Poisson sums, in total.
pub(crate) const DEFAULT_TOLERANCE: f64 = 1e-13;

/// A window of Poisson(λ) weights with a rigorous bound on the mass outside.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct PoissonWindow {
    /// First index kept.
    pub left: usize,
    /// Weights for `left..left + weights.len()`, summing to 1 − `outside`
    /// (up to rounding).
    pub weights: Vec<f64>,
    /// Upper bound on the probability outside the window.
    pub outside: f64,
}

/// Poisson(λ) weights truncated so that the mass outside is at most `eps`.
pub fn poisson_window(lambda: f64, eps: f64) -> PoissonWindow {
    poisson_window_with(lambda, eps, &[])
}

/// Reciprocals `1/k` for `k < len` (index 0 unused), to avoid divisions in
/// the weight recurrences.
fn reciprocals(len: usize) -> Vec<f64> {
    (0..len).map(|k| 1.0 / k.max(1) as f64).collect()
}

/// [`poisson_window`] with a table of reciprocals `inv[k] = 1/k`.
fn poisson_window_with(lambda: f64, eps: f64, inv: &[f64]) -> PoissonWindow {
    let mut out = PoissonWindow::default();
    poisson_window_into(lambda, eps, inv, &mut out);
    out
}

/// [`poisson_window_with`] written into `out`, its weights' buffer reused
/// (a chain stepped from time to time makes one window an interval:
/// hundreds of thousands in a race's quadrature).
fn poisson_window_into(lambda: f64, eps: f64, inv: &[f64], out: &mut PoissonWindow) {
    let recip = |k: usize| -> f64 { inv.get(k).copied().unwrap_or_else(|| 1.0 / k as f64) };
    let inv_lambda = 1.0 / lambda.max(f64::MIN_POSITIVE);
    assert!(lambda >= 0.0 && lambda.is_finite());
    out.weights.clear();
    if lambda == 0.0 {
        out.left = 0;
        out.weights.push(1.0);
        out.outside = 0.0;
        return;
    }
    // log w_m at the mode, via lgamma-free Stirling series for accuracy
    let mode = lambda.floor() as usize;
    let log_wm = mode as f64 * lambda.ln() - lambda - ln_factorial(mode);
    let wm = log_wm.exp();
    let half = eps / 2.0;
    // right side: w_{k+1} = w_k λ/(k+1). Once k+1 > λ every later ratio is
    // at most r = λ/(k+2), so Σ_{j>k} w_j ≤ w_{k+1}/(1−r); the test below is
    // that bound ≤ half, multiplied out to avoid divisions.
    let expected_right = (lambda + 8.0 * lambda.sqrt() + 16.0) as usize;
    let weights = &mut out.weights;
    weights.reserve(2 * expected_right.saturating_sub(mode) + 2);
    // left side first, from the mode down, then put in increasing order:
    // w_{k-1} = w_k k/λ; every earlier ratio is at most (k−1)/λ, so
    // Σ_{j≤k−1} w_j ≤ w_{k−1}/(1 − (k−1)/λ)
    let mut k = mode;
    let mut left_tail = 0.0;
    let mut w = wm;
    while k > 0 {
        let prev = w * k as f64 * inv_lambda;
        let km1 = k as f64 - 1.0;
        if prev * lambda <= half * (lambda - km1) {
            left_tail = prev * lambda / (lambda - km1);
            break;
        }
        weights.push(prev);
        w = prev;
        k -= 1;
    }
    let left = mode - weights.len();
    weights.reverse();
    // the mode and the right side: w_{k+1} = w_k λ/(k+1)
    weights.push(wm);
    let mut k = mode;
    let mut w = wm;
    let right_tail;
    loop {
        let k1 = k as f64 + 1.0;
        let next = w * lambda * recip(k + 1);
        if k1 > lambda && next * (k1 + 1.0) <= half * (k1 + 1.0 - lambda) {
            right_tail = next * (k1 + 1.0) / (k1 + 1.0 - lambda);
            break;
        }
        weights.push(next);
        w = next;
        k += 1;
    }
    out.left = left;
    out.outside = left_tail + right_tail;
}

/// ln k! (exact sum for small k, Stirling series beyond).
fn ln_factorial(k: usize) -> f64 {
    if k < 64 {
        return (2..=k).map(|i| (i as f64).ln()).sum();
    }
    let x = k as f64 + 1.0;
    // ln Γ(x), Stirling with 4 correction terms: error < 1e-15 for x ≥ 64
    (x - 0.5) * x.ln() - x + 0.5 * (2.0 * std::f64::consts::PI).ln() + 1.0 / (12.0 * x)
        - 1.0 / (360.0 * x.powi(3))
        + 1.0 / (1260.0 * x.powi(5))
        - 1.0 / (1680.0 * x.powi(7))
}

/// Work estimate of [`transient`] (vector-matrix products × nonzeros), to
/// refuse problems too stiff for uniformization before starting.
pub(crate) fn uniformization_work(chain: &PhaseChain, times: &[f64]) -> f64 {
    let lambda = max_rate(chain);
    let horizon = times.iter().copied().fold(0.0, f64::max);
    let lt = lambda * horizon;
    let steps = lt + 10.0 * lt.sqrt() + 20.0 * times.len() as f64;
    let nnz: usize = chain.transitions.iter().map(Vec::len).sum::<usize>() + 2 * chain.len();
    steps * nnz.max(1) as f64
}

fn max_rate(chain: &PhaseChain) -> f64 {
    (0..chain.len())
        .map(|i| chain.total_rate(i))
        .fold(0.0, f64::max)
}

/// Longest run of the single-pass method (steps); beyond it the interval
/// method keeps memory bounded.
pub const MAX_SINGLE_PASS_STEPS: usize = 20_000_000;

/// π(t) of a phase chain at the given times (any order, finite, ≥ 0),
/// returned in the order given. The absolute error of every probability is
/// at most `tolerance` plus rounding.
///
/// Only the absorbed probabilities are needed (`running = 1 − S − F`), so
/// one pass computes the scalars `s_k`, `f_k` (mass absorbed in Success and
/// Failure after k steps of the uniformized chain) up to the largest
/// truncation point, and every time point is a Poisson-weighted sum of them:
/// `S(t) = Σ_k Pois(k; Λt) s_k`. Each point's truncation error is bounded
/// on its own (at most `tolerance`), and the work is that of one
/// uniformization to the horizon, whatever the number of points.
pub fn transient(chain: &PhaseChain, times: &[f64], tolerance: f64) -> Vec<CurvePoint> {
    let horizon = times.iter().copied().fold(0.0, f64::max);
    let rows = if chain.is_empty() || max_rate(chain) == 0.0 || horizon == 0.0 {
        None
    } else {
        transient_weighted(chain, times, tolerance, &[])
    };
    let Some(rows) = rows else {
        return transient_by_intervals(chain, times, tolerance);
    };
    times
        .iter()
        .zip(rows)
        .map(|(&t, r)| {
            let success = r[0].clamp(0.0, 1.0);
            let failure = r[1].clamp(0.0, 1.0);
            CurvePoint {
                t,
                success,
                failure,
                running: (1.0 - success - failure).max(0.0),
            }
        })
        .collect()
}

/// `P = I + Q/Λ` in compressed rows.
#[derive(Debug, Clone)]
struct Uniformized {
    stay: Vec<f64>,
    exit_s: Vec<f64>,
    exit_f: Vec<f64>,
    row_start: Vec<usize>,
    cols: Vec<usize>,
    vals: Vec<f64>,
}

/// What [`Uniformized::advance`] works in, made once for many intervals:
/// the next step's distribution and the Poisson-weighted sum (each of the
/// chain's length) and the interval's Poisson window.
struct Scratch {
    next: Vec<f64>,
    acc: Vec<f64>,
    window: PoissonWindow,
}

impl Scratch {
    fn new(n: usize) -> Scratch {
        Scratch {
            next: vec![0.0; n],
            acc: vec![0.0; n],
            window: PoissonWindow::default(),
        }
    }
}

impl Uniformized {
    fn new(chain: &PhaseChain, lambda: f64) -> Uniformized {
        let n = chain.len();
        let mut u = Uniformized {
            stay: (0..n).map(|i| 1.0 - chain.total_rate(i) / lambda).collect(),
            exit_s: chain.exit_success.iter().map(|r| r / lambda).collect(),
            exit_f: chain.exit_failure.iter().map(|r| r / lambda).collect(),
            row_start: Vec::with_capacity(n + 1),
            cols: Vec::new(),
            vals: Vec::new(),
        };
        u.row_start.push(0);
        for row in &chain.transitions {
            for &(j, r) in row {
                u.cols.push(j);
                u.vals.push(r / lambda);
            }
            u.row_start.push(u.cols.len());
        }
        u
    }

    /// Advances the distribution `state` by `Λ·dt = lambda_dt` (`state ←
    /// Σ_k Pois(k; Λ·dt) state·Pᵏ`, the Poisson window truncated within
    /// `eps`); returns the mass absorbed into Success and Failure
    /// meanwhile.
    fn advance(
        &self,
        lambda_dt: f64,
        eps: f64,
        state: &mut Vec<f64>,
        scratch: &mut Scratch,
    ) -> (f64, f64) {
        let Scratch { next, acc, window } = scratch;
        poisson_window_into(lambda_dt, eps, &[], window);
        let window = &*window;
        acc.iter_mut().for_each(|x| *x = 0.0);
        let (mut acc_s, mut acc_f) = (0.0, 0.0);
        // v_k = state · P^k, absorbed mass of v_k tracked as s_k, f_k
        let (mut s_k, mut f_k) = (0.0, 0.0);
        let last = window.left + window.weights.len();
        for k in 0..last {
            if k >= window.left {
                let w = window.weights[k - window.left];
                for (a, v) in acc.iter_mut().zip(state.iter()) {
                    *a += w * v;
                }
                acc_s += w * s_k;
                acc_f += w * f_k;
            }
            if k + 1 == last {
                break;
            }
            // one step of P
            let (ds, df) = self.step(state, next);
            s_k += ds;
            f_k += df;
            std::mem::swap(state, next);
            next.iter_mut().for_each(|x| *x = 0.0);
        }
        // mass absorbed during the interval, on top of what was before
        let total: f64 = window.weights.iter().sum();
        let scale = 1.0 / total;
        for (s, a) in state.iter_mut().zip(acc.iter()) {
            // nothing below the smallest normal number (see `step`)
            *s = if a.abs() < f64::MIN_POSITIVE {
                0.0
            } else {
                a * scale
            };
        }
        (acc_s * scale, acc_f * scale)
    }

    /// `next += state · P` on the transient part; returns the mass absorbed
    /// into Success and Failure by this step. A phase holding less than the
    /// smallest normal number (2.2e-308) is taken as empty: its mass is
    /// nothing, and subnormal arithmetic is a hundred times slower — a
    /// chain decaying over a long horizon kept phases subnormal through
    /// millions of steps (random survey tree 1735: a race's Markovian
    /// racer stepped 8.2 million times, 4.9 s; `report` + `curve` 11 s →
    /// 3.4 s without them).
    fn step(&self, state: &[f64], next: &mut [f64]) -> (f64, f64) {
        let (mut s, mut f) = (0.0, 0.0);
        for (i, &v) in state.iter().enumerate() {
            if v.abs() < f64::MIN_POSITIVE {
                continue;
            }
            next[i] += v * self.stay[i];
            for e in self.row_start[i]..self.row_start[i + 1] {
                next[self.cols[e]] += v * self.vals[e];
            }
            s += v * self.exit_s[i];
            f += v * self.exit_f[i];
        }
        (s, f)
    }
}

/// The same by restarting uniformization on each interval between
/// consecutive times (bounded memory for very long horizons); the error
/// budget is split over the intervals.
pub fn transient_by_intervals(
    chain: &PhaseChain,
    times: &[f64],
    tolerance: f64,
) -> Vec<CurvePoint> {
    let mut order: Vec<usize> = (0..times.len()).collect();
    order.sort_by(|&a, &b| times[a].total_cmp(&times[b]));
    let n = chain.len();
    let lambda = max_rate(chain);
    let mut state = vec![0.0; n];
    for &(i, p) in &chain.initial {
        state[i] += p;
    }
    let mut success = chain.initial_success;
    let mut failure = chain.initial_failure;
    let mut now = 0.0;
    let eps = tolerance / times.len().max(1) as f64;
    let mut out = vec![
        CurvePoint {
            t: 0.0,
            success: 0.0,
            failure: 0.0,
            running: 0.0
        };
        times.len()
    ];
    let mut scratch = Scratch::new(n);
    let p = Uniformized::new(chain, lambda.max(f64::MIN_POSITIVE));
    for &idx in &order {
        let t = times[idx];
        let dt = t - now;
        if dt > 0.0 && n > 0 && lambda > 0.0 {
            let (ds, df) = p.advance(lambda * dt, eps, &mut state, &mut scratch);
            success += ds;
            failure += df;
            now = t;
        } else if dt > 0.0 {
            now = t;
        }
        let running: f64 = state.iter().sum();
        out[idx] = CurvePoint {
            t,
            success: success.clamp(0.0, 1.0),
            failure: failure.clamp(0.0, 1.0),
            running: running.clamp(0.0, 1.0),
        };
    }
    out
}

/// π(t) split by destination: besides the absorbed masses, the probability
/// still running at t that will end in Success (`running_to_success`) and in
/// Failure.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SplitPoint {
    /// The time.
    pub t: f64,
    /// P(returned Success by t).
    pub success: f64,
    /// P(returned Failure by t).
    pub failure: f64,
    /// P(running at t and ending in Success later).
    pub running_to_success: f64,
    /// P(running at t and ending in Failure later).
    pub running_to_failure: f64,
    /// `∫_t^∞ P(running at u, ending in Success) du`.
    pub time_to_success: f64,
    /// `∫_t^∞ P(running at u, ending in Failure) du`.
    pub time_to_failure: f64,
}

/// Per-phase quantities of an absorbing phase chain ([`absorption_by_phase`]).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PhaseAbsorption {
    /// Probability of ending in Success from each phase.
    pub to_success: Vec<f64>,
    /// Probability of ending in Failure from each phase.
    pub to_failure: Vec<f64>,
    /// `E_i[T·1{Success}]` from each phase.
    pub time_to_success: Vec<f64>,
    /// `E_i[T·1{Failure}]` from each phase.
    pub time_to_failure: Vec<f64>,
}

/// Probability of ending in Success and in Failure from each phase, and the
/// time integrals `E_i[T·1{outcome}]` (backward over the topological order:
/// `h_i = (exit_i + Σ_j r_ij h_j)/q_i`, `m_i = (h_i + Σ_j r_ij m_j)/q_i`).
pub fn absorption_by_phase(chain: &PhaseChain) -> PhaseAbsorption {
    let n = chain.len();
    let mut a = PhaseAbsorption {
        to_success: vec![0.0; n],
        to_failure: vec![0.0; n],
        time_to_success: vec![0.0; n],
        time_to_failure: vec![0.0; n],
    };
    for i in (0..n).rev() {
        let q = chain.total_rate(i);
        if q <= 0.0 {
            // a trap: never absorbed
            continue;
        }
        let (mut s, mut f) = (chain.exit_success[i], chain.exit_failure[i]);
        let (mut ms, mut mf) = (0.0, 0.0);
        for &(j, r) in &chain.transitions[i] {
            s += r * a.to_success[j];
            f += r * a.to_failure[j];
            ms += r * a.time_to_success[j];
            mf += r * a.time_to_failure[j];
        }
        a.to_success[i] = s / q;
        a.to_failure[i] = f / q;
        a.time_to_success[i] = (a.to_success[i] + ms) / q;
        a.time_to_failure[i] = (a.to_failure[i] + mf) / q;
    }
    a
}

/// [`transient`] with the running mass split by destination ([`SplitPoint`]),
/// given the chain's [`absorption_by_phase`]. Each figure is a Poisson
/// average of `π₀Pᵏ·h` for a non-negative `h`, so its truncation error is
/// at most `tolerance · max h` (`tolerance` for the probabilities); and each
/// is computed from
/// non-negative terms, so small values keep their relative accuracy (no
/// cancellation as in `P(S) − S(t)`). `None` if the horizon needs more than
/// [`MAX_SINGLE_PASS_STEPS`].
pub(crate) fn transient_split(
    chain: &PhaseChain,
    times: &[f64],
    tolerance: f64,
    absorption: &PhaseAbsorption,
) -> Option<Vec<SplitPoint>> {
    transient_split_kept(&mut None, chain, times, tolerance, absorption)
}

/// Most numbers a kept pass holds between calls (64 MB); a longer pass is
/// dropped after its call.
const MAX_KEPT_SUMS: usize = 1 << 23;

/// [`transient_split`] for a caller that asks the same chain again (a
/// quadrature's rounds, each at new times): the uniformization pass is kept
/// in `pass` and extended, not run again from 0 (the same numbers).
pub(crate) fn transient_split_kept(
    pass: &mut Option<WeightedSteps>,
    chain: &PhaseChain,
    times: &[f64],
    tolerance: f64,
    absorption: &PhaseAbsorption,
) -> Option<Vec<SplitPoint>> {
    let weights = [
        &absorption.to_success[..],
        &absorption.to_failure[..],
        &absorption.time_to_success[..],
        &absorption.time_to_failure[..],
    ];
    let rows = WeightedSteps::with_kept(pass, chain, &weights, |s| s.rows(times, tolerance))?;
    Some(
        times
            .iter()
            .zip(rows)
            .map(|(&t, r)| SplitPoint {
                t,
                success: r[0],
                failure: r[1],
                running_to_success: r[2],
                running_to_failure: r[3],
                time_to_success: r[4],
                time_to_failure: r[5],
            })
            .collect(),
    )
}

/// One uniformization pass giving, at each time, `[S(t), F(t), π(t)·h₁,
/// π(t)·h₂, ...]` for the transient distribution `π(t)` and the given
/// per-phase weight vectors (e.g. exit rates, for the outcome densities).
/// The truncation error of `π(t)·h` is at most `2·tolerance·sup_k |π₀Pᵏ·h|`.
/// `None` if the horizon needs more than [`MAX_SINGLE_PASS_STEPS`].
pub(crate) fn transient_weighted(
    chain: &PhaseChain,
    times: &[f64],
    tolerance: f64,
    weights: &[&[f64]],
) -> Option<Vec<Vec<f64>>> {
    WeightedSteps::new(chain, weights).rows(times, tolerance)
}

/// [`transient_weighted`]'s pass kept for later calls: the uniformized
/// chain's steps from the initial distribution are the same whatever the
/// times asked (only their Poisson mixtures differ), so a caller that asks
/// again — an adaptive interpolation's rounds, each at new points — extends
/// the steps it has instead of starting a pass from 0 (the same numbers,
/// in the same order, as one pass to the latest time).
#[derive(Debug, Clone)]
pub(crate) struct WeightedSteps {
    lambda: f64,
    initial: (f64, f64),
    empty: bool,
    weights: Vec<Vec<f64>>,
    p: Uniformized,
    /// The initial distribution over the phases.
    start: Vec<f64>,
    state: Vec<f64>,
    next: Vec<f64>,
    absorbed: (f64, f64),
    /// per step, flattened: absorbed S, absorbed F, then π·h for each weight
    sums: Vec<f64>,
}

impl WeightedSteps {
    /// `rows` of the pass kept in `pass` (made for `chain` and `weights` at
    /// the first call); a pass longer than [`MAX_KEPT_SUMS`] is not kept
    /// after the call (it would hold its numbers for as long as its caller
    /// lives).
    pub(crate) fn with_kept<R>(
        pass: &mut Option<WeightedSteps>,
        chain: &PhaseChain,
        weights: &[&[f64]],
        rows: impl FnOnce(&mut WeightedSteps) -> R,
    ) -> R {
        let steps = pass.get_or_insert_with(|| WeightedSteps::new(chain, weights));
        let out = rows(steps);
        if steps.kept() > MAX_KEPT_SUMS {
            *pass = None;
        }
        out
    }

    pub(crate) fn new(chain: &PhaseChain, weights: &[&[f64]]) -> WeightedSteps {
        let lambda = max_rate(chain);
        let n = chain.len();
        let mut state = vec![0.0; n];
        for &(i, q) in &chain.initial {
            state[i] += q;
        }
        WeightedSteps {
            lambda,
            initial: (chain.initial_success, chain.initial_failure),
            empty: chain.is_empty(),
            weights: weights.iter().map(|w| w.to_vec()).collect(),
            p: Uniformized::new(chain, lambda),
            start: state.clone(),
            state,
            next: vec![0.0; n],
            absorbed: (0.0, 0.0),
            sums: Vec::new(),
        }
    }

    /// [`Self::rows`], or the same by [`Self::rows_by_intervals`] where
    /// that costs less, by both costs estimated before either runs: each
    /// time a Poisson mixture of the kept pass's steps (about
    /// `10·sqrt(Λt)` terms a time: cheap for few times, and the pass is
    /// kept for the next call), or, for many times, the chain stepped from
    /// each time to the next (about `Λ·Δt + 8` steps of the chain an
    /// interval, whatever the horizon). A race's quadrature asks hundreds
    /// of thousands of times on long horizons (random survey tree 1735:
    /// 853,632 times to 5,934 s at rate 2.8, 1,300 terms a time in the
    /// mixtures). The intervals' rounding adds up over the intervals
    /// (about 1e-16 each), where each mixture's error is its own: callers
    /// that test convergence at 1e-13 (the sensitivity's count grids) keep
    /// to [`Self::rows`].
    pub(crate) fn rows_by_cost(&mut self, times: &[f64], tolerance: f64) -> Option<Vec<Vec<f64>>> {
        let horizon = times.iter().copied().fold(0.0, f64::max);
        let max_lt = self.lambda * horizon;
        if !self.empty && self.lambda > 0.0 && max_lt <= MAX_SINGLE_PASS_STEPS as f64 {
            let width = (2 + self.weights.len()) as f64;
            let n = times.len() as f64;
            let states = self.p.stay.len() as f64;
            let per_step = self.p.cols.len() as f64 + 2.0 * states;
            let mixtures = n * (10.0 * max_lt.sqrt() + 8.0) * width;
            let intervals = (max_lt + 8.0 * n) * per_step + n * width * states;
            if mixtures > 4.0 * intervals {
                return Some(self.rows_by_intervals(times, tolerance));
            }
        }
        self.rows(times, tolerance)
    }

    /// `[S, F, π·h₁, ...]` at `times` ([`transient_weighted`]), `None` when
    /// the pass would take more than [`MAX_SINGLE_PASS_STEPS`] steps: each
    /// time a Poisson mixture of the kept pass's steps, its window made
    /// when its row is (never all at once).
    pub(crate) fn rows(&mut self, times: &[f64], tolerance: f64) -> Option<Vec<Vec<f64>>> {
        let lambda = self.lambda;
        let horizon = times.iter().copied().fold(0.0, f64::max);
        let width = 2 + self.weights.len();
        if self.empty || lambda == 0.0 {
            let mut row = vec![0.0; width];
            row[0] = self.initial.0;
            row[1] = self.initial.1;
            return Some(vec![row; times.len()]);
        }
        let max_lt = lambda * horizon;
        // refuse before allocating the Poisson tables: the pass needs at
        // least Λt steps
        let table = max_lt + 10.0 * max_lt.sqrt() + 64.0;
        if max_lt > MAX_SINGLE_PASS_STEPS as f64 {
            return None;
        }
        let inv = reciprocals(table.min(1e8) as usize);
        // the window of the latest time reaches furthest; one more step is
        // taken where a window reaches past it (each window is made when its
        // row is: never all at once)
        let last = poisson_window_with(max_lt, tolerance, &inv);
        let mut steps = last.left + last.weights.len();
        if steps > MAX_SINGLE_PASS_STEPS {
            return None;
        }
        self.extend(steps);
        let mut rows = Vec::with_capacity(times.len());
        for &t in times {
            let w = poisson_window_with(lambda * t, tolerance, &inv);
            if w.left + w.weights.len() > steps {
                steps = w.left + w.weights.len();
                if steps > MAX_SINGLE_PASS_STEPS {
                    return None;
                }
                self.extend(steps);
            }
            let sums = &self.sums;
            let total: f64 = w.weights.iter().sum();
            let mut acc = vec![0.0; width];
            for (j, &wk) in w.weights.iter().enumerate() {
                let row = &sums[(w.left + j) * width..(w.left + j + 1) * width];
                for (a, x) in acc.iter_mut().zip(row) {
                    *a += wk * x;
                }
            }
            acc.iter_mut().for_each(|a| *a /= total);
            acc[0] += self.initial.0;
            acc[1] += self.initial.1;
            rows.push(acc);
        }
        Some(rows)
    }

    /// [`Self::rows`] by stepping the chain from each time to the next, in
    /// increasing order (as [`transient_by_intervals`]; the error budget
    /// split over the intervals): the distribution at each time, its
    /// absorbed masses and its weighted sums.
    fn rows_by_intervals(&self, times: &[f64], tolerance: f64) -> Vec<Vec<f64>> {
        let width = 2 + self.weights.len();
        let n = self.start.len();
        let mut order: Vec<usize> = (0..times.len()).collect();
        order.sort_by(|&a, &b| times[a].total_cmp(&times[b]));
        let eps = tolerance / times.len().max(1) as f64;
        let mut state = self.start.clone();
        let mut scratch = Scratch::new(n);
        let (mut success, mut failure) = (0.0, 0.0);
        let mut now = 0.0;
        let mut rows = vec![Vec::new(); times.len()];
        for &idx in &order {
            let t = times[idx];
            let dt = t - now;
            if dt > 0.0 {
                let (ds, df) = self
                    .p
                    .advance(self.lambda * dt, eps, &mut state, &mut scratch);
                success += ds;
                failure += df;
                now = t;
            }
            let mut row = Vec::with_capacity(width);
            row.push(success + self.initial.0);
            row.push(failure + self.initial.1);
            row.extend(
                self.weights
                    .iter()
                    .map(|h| state.iter().zip(h).map(|(a, b)| a * b).sum::<f64>()),
            );
            rows[idx] = row;
        }
        rows
    }

    /// The numbers the pass holds.
    pub(crate) fn kept(&self) -> usize {
        self.sums.len()
    }

    /// Runs the pass on to `steps` steps (the initial distribution is
    /// step 0).
    fn extend(&mut self, steps: usize) {
        let width = 2 + self.weights.len();
        let dot = |v: &[f64], h: &[f64]| v.iter().zip(h).map(|(a, b)| a * b).sum::<f64>();
        let push =
            |sums: &mut Vec<f64>, (s, f): (f64, f64), state: &[f64], weights: &[Vec<f64>]| {
                sums.push(s);
                sums.push(f);
                sums.extend(weights.iter().map(|h| dot(state, h)));
            };
        let done = self.sums.len() / width;
        if steps == 0 || done >= steps {
            return;
        }
        self.sums.reserve((steps - done) * width);
        if done == 0 {
            push(&mut self.sums, self.absorbed, &self.state, &self.weights);
        }
        for _ in done.max(1)..steps {
            let (ds, df) = self.p.step(&self.state, &mut self.next);
            self.absorbed.0 += ds;
            self.absorbed.1 += df;
            std::mem::swap(&mut self.state, &mut self.next);
            self.next.iter_mut().for_each(|x| *x = 0.0);
            push(&mut self.sums, self.absorbed, &self.state, &self.weights);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two exponential phases in series (rates 2 then 3, Success after the
    /// second): a step moves a normal mass as `P` says, and a subnormal
    /// one (below 2.2e-308) not at all — it is taken as empty.
    #[test]
    fn subnormal_masses_are_empty() {
        let mut chain = PhaseChain::default();
        let (a, b) = (chain.push_phase(), chain.push_phase());
        chain.transitions[a].push((b, 2.0));
        chain.exit_success[b] = 3.0;
        chain.initial.push((a, 1.0));
        let p = Uniformized::new(&chain, 4.0);
        let mut next = vec![0.0; 2];
        let (s, f) = p.step(&[0.5, 0.25], &mut next);
        // P = [[1 − 2/4, 2/4], [0, 1 − 3/4]], exit 3/4 from the second
        assert_eq!(next, vec![0.25, 0.25 + 0.0625]);
        assert_eq!((s, f), (0.1875, 0.0));
        let mut next = vec![0.0; 2];
        let (s, f) = p.step(&[1e-310, 1e-320], &mut next);
        assert_eq!(next, vec![0.0, 0.0]);
        assert_eq!((s, f), (0.0, 0.0));
    }

    #[test]
    fn poisson_window_bounds_hold() {
        for &lambda in &[0.1, 1.0, 7.5, 100.0, 12345.6, 1e6] {
            let w = poisson_window(lambda, 1e-12);
            let kept: f64 = w.weights.iter().sum();
            assert!(w.outside <= 1e-12, "λ={lambda}: outside {}", w.outside);
            // the weights are Poisson probabilities up to a common relative
            // rounding error of about |ln w_mode|·ε (removed by normalising),
            // so they sum to 1 − (outside mass) within that
            let rounding = 1e-15 * (lambda + 10.0);
            assert!(
                (kept - 1.0).abs() <= 1e-12 + rounding,
                "λ={lambda}: kept {kept}"
            );
        }
    }

    /// Both ways of [`WeightedSteps::rows`] against the closed form of a
    /// hypoexponential time (Exp(2) then Exp(1), Success w.p. 3/4): the
    /// absorbed masses and the running mass weighted by the exit rates (the
    /// outcome densities), at 2,000 times in shuffled order.
    #[test]
    fn weighted_rows_by_mixtures_and_by_intervals_match_the_closed_form() {
        let c = PhaseChain {
            initial: vec![(0, 1.0)],
            transitions: vec![vec![(1, 2.0)], vec![]],
            exit_success: vec![0.0, 0.75],
            exit_failure: vec![0.0, 0.25],
            ..Default::default()
        };
        let times: Vec<f64> = (0..2000)
            .map(|k| ((k * 7919) % 2000) as f64 * 0.01)
            .collect();
        let weights = [&c.exit_success[..], &c.exit_failure[..]];
        let steps = WeightedSteps::new(&c, &weights);
        let by_intervals = steps.rows_by_intervals(&times, 1e-16);
        let mut steps = WeightedSteps::new(&c, &weights);
        // few times at once: the mixtures of the kept pass
        let by_mixtures: Vec<Vec<f64>> = times
            .chunks(2)
            .flat_map(|ts| steps.rows(ts, 1e-16).expect("a short pass"))
            .collect();
        for ((&t, a), b) in times.iter().zip(&by_intervals).zip(&by_mixtures) {
            let cdf = 1.0 - (2.0 * (-t).exp() - (-2.0 * t).exp());
            let in_second = 2.0 * ((-t).exp() - (-2.0 * t).exp());
            let want = [0.75 * cdf, 0.25 * cdf, 0.75 * in_second, 0.25 * in_second];
            for row in [a, b] {
                for (g, w) in row.iter().zip(want) {
                    assert!((g - w).abs() < 1e-13, "t = {t}: {row:?} vs {want:?}");
                }
            }
        }
    }

    #[test]
    fn single_phase_matches_exponential_cdf() {
        // Exp(2) ending in Success w.p. .25 (rate .5) and Failure (rate 1.5)
        let c = PhaseChain {
            initial: vec![(0, 1.0)],
            transitions: vec![vec![]],
            exit_success: vec![0.5],
            exit_failure: vec![1.5],
            ..Default::default()
        };
        let times = [0.0, 0.1, 1.0, 3.0, 20.0];
        for p in transient(&c, &times, 1e-13) {
            let cdf = -(-2.0 * p.t).exp_m1();
            assert!((p.success - 0.25 * cdf).abs() < 1e-13, "{p:?}");
            assert!((p.failure - 0.75 * cdf).abs() < 1e-13, "{p:?}");
            assert!((p.success + p.failure + p.running - 1.0).abs() < 1e-12);
        }
    }
}
