//! Transient analysis of small stiff chains: the matrix exponential by
//! scaling and squaring of a non-negative matrix, in double-double.
//!
//! Uniformization needs about `Λt` steps; with rates from 1e-4 to 1e5 and
//! horizons of 1e7 that is 1e12. For a chain of `m` states (phases plus
//! Success and Failure), this module computes `X = e^{Qh}` for the interval
//! `h` instead, with a rigorous bound on `‖X̃ − X‖_∞`:
//!
//! 1. `h₀ = h / 2^s` with `Λh₀ ≤ 1/2`; `B = (Q + ΛI)h₀ ≥ 0` elementwise, so
//!    `e^{Qh₀} = e^{−Λh₀} Σ_k B^k/k!` is a sum of non-negative terms. The
//!    series is cut after 28 terms: the tail is below `0.5^29/29! < 1e-38`.
//! 2. `X = (e^{Qh₀})^{2^s}` by `s` squarings. Every matrix is row-sub-
//!    stochastic (‖·‖_∞ ≤ 1) and non-negative, so no cancellation occurs,
//!    each product adds at most `m·u` (u = 2⁻¹⁰⁰ in double-double) and an
//!    error δ before a squaring becomes at most `δ(2 + δ)` after it:
//!    `δ_s ≤ 2.0001^s (δ₀ + m·u·(s+30))`.
//!
//! With `s ≤ 64` and `m ≤ 256` the bound is below 1e-8 in the worst case
//! and typically far smaller; it is computed and checked against the
//! requested tolerance. Products exploit the upper-triangular structure of
//! acyclic chains.

use super::chain::PhaseChain;
use super::dd::{Dd, EPS};
use super::transient::CurvePoint;

/// Largest chain (phases + 2) handled densely.
pub const MAX_DENSE_STATES: usize = 256;

/// Dense upper-triangular matrix in double-double, row major.
#[derive(Clone)]
struct Matrix {
    m: usize,
    a: Vec<Dd>,
}

impl Matrix {
    fn zeros(m: usize) -> Matrix {
        Matrix {
            m,
            a: vec![Dd::ZERO; m * m],
        }
    }
    fn identity(m: usize) -> Matrix {
        let mut x = Matrix::zeros(m);
        for i in 0..m {
            x.a[i * m + i] = Dd::ONE;
        }
        x
    }
    /// Product of upper-triangular matrices.
    fn mul(&self, b: &Matrix) -> Matrix {
        let m = self.m;
        let mut c = Matrix::zeros(m);
        for i in 0..m {
            for k in i..m {
                let aik = self.a[i * m + k];
                if aik.hi == 0.0 {
                    continue;
                }
                for j in k..m {
                    let bkj = b.a[k * m + j];
                    if bkj.hi != 0.0 {
                        c.a[i * m + j] = c.a[i * m + j] + aik * bkj;
                    }
                }
            }
        }
        c
    }
}

/// `e^{Qh}` of a phase chain (with Success = state n, Failure = n + 1) and
/// its error bound in the ∞-norm.
struct Exponential {
    x: Matrix,
    bound: f64,
}

fn exponential(chain: &PhaseChain, h: f64) -> Exponential {
    let n = chain.len();
    let m = n + 2;
    let lambda = (0..n).map(|i| chain.total_rate(i)).fold(0.0, f64::max);
    let mut s = 0u32;
    while lambda * h / 2f64.powi(s as i32) > 0.5 {
        s += 1;
    }
    let h0 = h / 2f64.powi(s as i32); // exact: power-of-two scaling
                                      // B = (Q + ΛI) h0
    let mut b = Matrix::zeros(m);
    for i in 0..n {
        b.a[i * m + i] = Dd::difference(lambda, chain.total_rate(i)) * Dd::from_f64(h0);
        for &(j, r) in &chain.transitions[i] {
            b.a[i * m + j] = b.a[i * m + j] + Dd::product(r, h0);
        }
        b.a[i * m + n] = Dd::product(chain.exit_success[i], h0);
        b.a[i * m + n + 1] = Dd::product(chain.exit_failure[i], h0);
    }
    for i in n..m {
        b.a[i * m + i] = Dd::product(lambda, h0);
    }
    // Σ_{k≤28} B^k/k! by Horner: I + B(I + B/2(I + ... (I + B/28)))
    const TERMS: usize = 28;
    let mut t = Matrix::identity(m);
    for k in (1..=TERMS).rev() {
        let mut bt = b.mul(&t);
        for v in &mut bt.a {
            *v = v.div_f64(k as f64);
        }
        for i in 0..m {
            bt.a[i * m + i] = bt.a[i * m + i] + Dd::ONE;
        }
        t = bt;
    }
    let scale = Dd::exp_neg(Dd::product(lambda, h0));
    for v in &mut t.a {
        *v = *v * scale;
    }
    let mut x = t;
    for _ in 0..s {
        x = x.mul(&x);
    }
    let u = EPS * m as f64;
    let delta0 = 1e-38 + u * (TERMS as f64 + 4.0);
    let bound = 2.0001f64.powi(s as i32) * (delta0 + u * (s as f64 + 1.0));
    Exponential { x, bound }
}

/// `e^{Qh}` of a phase chain as a dense row-major `(n + 2)²` matrix in
/// double-double (phases, then Success = n, Failure = n + 1; upper
/// triangular), and the rigorous bound on its error in the ∞-norm (module
/// docs). The chain must have at most [`MAX_DENSE_STATES`] − 2 phases.
pub(crate) fn exponential_matrix(chain: &PhaseChain, h: f64) -> (Vec<Dd>, f64) {
    let e = exponential(chain, h);
    (e.x.a, e.bound)
}

/// Rough operation count of [`transient_dense`], to choose between it and
/// uniformization: one exponential (28 Taylor products and `s` squarings
/// of an upper-triangular m × m double-double matrix, ~m³/6 multiply-adds
/// each, ~20 flops apiece) per distinct interval, and m²/2 per time point.
pub(crate) fn dense_work(chain: &PhaseChain, times: &[f64]) -> f64 {
    let m = (chain.len() + 2) as f64;
    let lambda = (0..chain.len())
        .map(|i| chain.total_rate(i))
        .fold(0.0, f64::max);
    let mut sorted: Vec<f64> = times.to_vec();
    sorted.sort_by(f64::total_cmp);
    let mut distinct = 0usize;
    let mut last_interval: Option<f64> = None;
    let mut now = 0.0;
    for &t in &sorted {
        let dt = t - now;
        let same = last_interval.is_some_and(|h| (h - dt).abs() <= 1e-9 * h);
        if dt > 0.0 && !same {
            distinct += 1;
            last_interval = Some(dt);
        }
        now = t;
    }
    let horizon = sorted.last().copied().unwrap_or(0.0);
    let squarings = (2.0 * lambda * horizon).max(1.0).log2().ceil().max(0.0);
    let per_exponential = (28.0 + squarings) * m * m * m / 6.0 * 20.0;
    distinct as f64 * per_exponential + times.len() as f64 * m * m * 10.0
}

/// π(t) at `times` (finite, ≥ 0, any order) by dense exponentials; also
/// returns a rigorous bound on the absolute error of every probability.
/// Equal consecutive intervals (e.g. an evenly spaced grid) share one
/// exponential.
pub fn transient_dense(chain: &PhaseChain, times: &[f64]) -> (Vec<CurvePoint>, f64) {
    let n = chain.len();
    let mut out = vec![
        CurvePoint {
            t: 0.0,
            success: 0.0,
            failure: 0.0,
            running: 0.0,
        };
        times.len()
    ];
    let bound = dense_pass(chain, times, |idx, v| {
        let s = v[n].to_f64();
        let f = v[n + 1].to_f64();
        let running = v[..n].iter().fold(Dd::ZERO, |a, &b| a + b).to_f64();
        out[idx] = CurvePoint {
            t: times[idx],
            success: s.clamp(0.0, 1.0),
            failure: f.clamp(0.0, 1.0),
            running: running.clamp(0.0, 1.0),
        };
    });
    (out, bound)
}

/// Like [`crate::solve::transient::transient_weighted`] but by dense
/// exponentials: at each time `[S(t), F(t), π(t)·h₁, ...]` for the weight
/// vectors `h` (non-negative), and the rigorous bound on the error of the
/// probabilities (an entry `π(t)·h` is within that times `max h`).
pub(crate) fn transient_dense_weighted(
    chain: &PhaseChain,
    times: &[f64],
    weights: &[&[f64]],
) -> (Vec<Vec<f64>>, f64) {
    let n = chain.len();
    let mut out = vec![Vec::new(); times.len()];
    let bound = dense_pass(chain, times, |idx, v| {
        let mut row = Vec::with_capacity(2 + weights.len());
        row.push(v[n].to_f64());
        row.push(v[n + 1].to_f64());
        for w in weights {
            let dot = v[..n]
                .iter()
                .zip(w.iter())
                .fold(Dd::ZERO, |a, (&x, &h)| a + x * Dd::from_f64(h));
            row.push(dot.to_f64());
        }
        out[idx] = row;
    });
    (out, bound)
}

/// Walks `times` in increasing order, handing `visit` the index of each
/// time and the distribution over phases, Success (index n) and Failure
/// (n + 1) then; returns the error bound of every entry.
fn dense_pass(chain: &PhaseChain, times: &[f64], mut visit: impl FnMut(usize, &[Dd])) -> f64 {
    let n = chain.len();
    let m = n + 2;
    let mut order: Vec<usize> = (0..times.len()).collect();
    order.sort_by(|&a, &b| times[a].total_cmp(&times[b]));
    let mut v = vec![Dd::ZERO; m];
    for &(i, p) in &chain.initial {
        v[i] = v[i] + Dd::from_f64(p);
    }
    v[n] = Dd::from_f64(chain.initial_success);
    v[n + 1] = Dd::from_f64(chain.initial_failure);
    let mut now = 0.0;
    let mut cached: Option<(f64, Exponential)> = None;
    let mut bound = 0.0;
    // a common spacing: treat intervals equal to 1e-9 (relative) as equal
    for &idx in &order {
        let t = times[idx];
        let dt = t - now;
        if dt > 0.0 && n > 0 {
            let reuse = matches!(&cached, Some((h, _)) if (h - dt).abs() <= 1e-9 * h);
            if !reuse {
                cached = Some((dt, exponential(chain, dt)));
            }
            let (_, e) = cached.as_ref().expect("just set");
            let mut next = vec![Dd::ZERO; m];
            for (i, vi) in v.iter().enumerate() {
                if vi.hi == 0.0 {
                    continue;
                }
                for (j, nj) in next.iter_mut().enumerate().skip(i) {
                    let x = e.x.a[i * m + j];
                    if x.hi != 0.0 {
                        *nj = *nj + *vi * x;
                    }
                }
            }
            v = next;
            bound += e.bound + EPS * m as f64;
        }
        now = t;
        visit(idx, &v);
    }
    bound
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stiff_two_phase_sequence_matches_closed_form() {
        // Exp(1e5) then Exp(1e-4) to Success: CDF = 1 - (a e^{-bt} - b e^{-at})/(a - b)
        let c = PhaseChain {
            initial: vec![(0, 1.0)],
            transitions: vec![vec![(1, 1e5)], vec![]],
            exit_success: vec![0.0, 1e-4],
            exit_failure: vec![0.0, 0.0],
            ..Default::default()
        };
        let times = [1e-6, 1e-3, 1.0, 1e3, 1e4, 1e7];
        let (pts, bound) = transient_dense(&c, &times);
        assert!(bound < 1e-12, "bound {bound}");
        let (a, b) = (1e5f64, 1e-4f64);
        for p in pts {
            let exact = 1.0 - (a * (-b * p.t).exp() - b * (-a * p.t).exp()) / (a - b);
            assert!((p.success - exact).abs() < 1e-13, "{p:?} vs {exact}");
            assert!((p.success + p.failure + p.running - 1.0).abs() < 1e-13);
        }
    }
}
