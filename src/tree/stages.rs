//! Sums of independent exponential stages: the Erlang, hypoexponential and
//! (with a deterministic shift, see [`super::Duration::PhaseType`]) shifted
//! timing families of an action's outcome.
//!
//! A [`Stages`] is `count_i` stages of rate `rate_i` for each distinct rate,
//! run one after the other: an Erlang-k is one rate with count `k`, a
//! hypoexponential one count per rate of its list (equal rates merged, which
//! does not change the law of a sum). The order of the stages does not
//! change the law either, so the phase chain lists them by decreasing rate.
//! A [`super::Duration`] holds its stages as an interned `&'static Stages`
//! ([`intern`]: one copy per distinct set of stages for the life of the
//! process), so that it stays `Copy` and 24 bytes and a tree's nodes do not
//! grow for the families most trees do not use.

use rand::Rng;
use rand_distr::{Distribution, Exp1, Gamma};

/// Most distinct rates a [`Stages`] holds.
pub const MAX_STAGES: usize = 8;

/// Most stages (phases) in all, e.g. the largest Erlang `k`.
pub const MAX_PHASES: u32 = 1000;

/// `counts[i]` exponential stages of rate `rates[i]` for `i < len`, summed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Stages {
    len: u8,
    rates: [f64; MAX_STAGES],
    counts: [u32; MAX_STAGES],
}

impl Stages {
    /// The sum of `count` stages of each `(rate, count)`. Fails (with the
    /// reason) on a rate that is not finite and > 0, a count of 0, more than
    /// [`MAX_STAGES`] distinct rates or more than [`MAX_PHASES`] stages.
    pub fn new(list: &[(f64, u32)]) -> Result<Stages, String> {
        let mut s = Stages {
            len: 0,
            rates: [0.0; MAX_STAGES],
            counts: [0; MAX_STAGES],
        };
        if list.is_empty() {
            return Err("no stage".into());
        }
        let mut total: u64 = 0;
        for &(rate, count) in list {
            if !(rate.is_finite() && rate > 0.0) {
                return Err(format!("rate {rate} is not a finite number > 0"));
            }
            if count == 0 {
                return Err("a stage count is 0".into());
            }
            total += u64::from(count);
            if total > u64::from(MAX_PHASES) {
                return Err(format!("more than {MAX_PHASES} stages"));
            }
            let n = usize::from(s.len);
            match s.rates[..n].iter().position(|&r| r == rate) {
                Some(i) => s.counts[i] += count,
                None if n == MAX_STAGES => {
                    return Err(format!("more than {MAX_STAGES} distinct rates"))
                }
                None => {
                    s.rates[n] = rate;
                    s.counts[n] = count;
                    s.len += 1;
                }
            }
        }
        // a canonical order (by decreasing rate): equal laws compare equal
        let n = usize::from(s.len);
        let mut pairs: Vec<(f64, u32)> = s.iter().collect();
        pairs.sort_by(|a, b| b.0.total_cmp(&a.0));
        for (i, (r, c)) in pairs.into_iter().enumerate().take(n) {
            s.rates[i] = r;
            s.counts[i] = c;
        }
        Ok(s)
    }

    /// Erlang-`k` of `rate`: `k` stages of the same rate.
    pub fn erlang(k: u32, rate: f64) -> Result<Stages, String> {
        Stages::new(&[(rate, k)])
    }

    /// Hypoexponential: one stage of each rate.
    pub fn hypoexponential(rates: &[f64]) -> Result<Stages, String> {
        Stages::new(&rates.iter().map(|&r| (r, 1)).collect::<Vec<_>>())
    }

    /// The distinct rates with their counts.
    pub fn iter(&self) -> impl Iterator<Item = (f64, u32)> + '_ {
        (0..usize::from(self.len)).map(|i| (self.rates[i], self.counts[i]))
    }

    /// Total number of stages.
    pub fn phases(&self) -> u32 {
        self.iter().map(|(_, c)| c).sum()
    }

    /// `Some((k, rate))` when every stage has the same rate (an Erlang-k).
    pub fn as_erlang(&self) -> Option<(u32, f64)> {
        (self.len == 1).then(|| (self.counts[0], self.rates[0]))
    }

    /// The rate of every stage, stage by stage (decreasing).
    pub fn series(&self) -> Vec<f64> {
        self.iter()
            .flat_map(|(r, c)| std::iter::repeat_n(r, c as usize))
            .collect()
    }

    /// Mean `Σ count/rate`.
    pub fn mean(&self) -> f64 {
        self.iter().map(|(r, c)| f64::from(c) / r).sum()
    }

    /// Variance `Σ count/rate²`.
    pub fn variance(&self) -> f64 {
        self.iter().map(|(r, c)| f64::from(c) / (r * r)).sum()
    }

    /// `P(sum ≤ t)`: the regularized lower incomplete gamma function for an
    /// Erlang; the transient solution of the stage chain otherwise.
    pub fn cdf(&self, t: f64) -> f64 {
        if t.is_nan() || t <= 0.0 {
            return 0.0;
        }
        if t.is_infinite() {
            return 1.0;
        }
        if let Some((k, rate)) = self.as_erlang() {
            return erlang_cdf(k, rate, t);
        }
        let chain = self.chain();
        crate::solve::transient::transient(&chain, &[t], 1e-14)
            .first()
            .map_or(0.0, |p| p.success)
            .clamp(0.0, 1.0)
    }

    /// The stages as a phase chain: stage `i` enters `i + 1`, the last
    /// exits to Success.
    pub fn chain(&self) -> crate::solve::chain::PhaseChain {
        let mut c = crate::solve::chain::PhaseChain::default();
        let series = self.series();
        for (i, &r) in series.iter().enumerate() {
            let p = c.push_phase();
            debug_assert_eq!(p, i);
            if i + 1 < series.len() {
                c.transitions[i].push((i + 1, r));
            } else {
                c.exit_success[i] = r;
            }
        }
        c.initial.push((0, 1.0));
        c
    }

    /// One draw of the sum.
    pub fn sample<R: Rng + ?Sized>(&self, rng: &mut R) -> f64 {
        self.iter()
            .map(|(r, c)| {
                if c <= 16 {
                    (0..c).map(|_| -> f64 { Exp1.sample(rng) }).sum::<f64>() / r
                } else {
                    // shape c ≥ 17 and scale 1/r > 0 are valid parameters
                    Gamma::new(f64::from(c), 1.0 / r).map_or(f64::from(c) / r, |g| g.sample(rng))
                }
            })
            .sum()
    }
}

/// `ln Γ(n + 1) = ln n!` by summation (exact enough for n ≤ MAX_PHASES).
fn ln_factorial(n: u32) -> f64 {
    (2..=n).map(|i| f64::from(i).ln()).sum()
}

/// The interned copy of `s` (the same reference for equal stages).
pub fn intern(s: Stages) -> &'static Stages {
    use std::collections::HashMap;
    use std::sync::{Mutex, OnceLock};
    type Key = ([u64; MAX_STAGES], [u32; MAX_STAGES], u8);
    static TABLE: OnceLock<Mutex<HashMap<Key, &'static Stages>>> = OnceLock::new();
    let key: Key = (s.rates.map(f64::to_bits), s.counts, s.len);
    let mut table = TABLE
        .get_or_init(Default::default)
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner);
    table.entry(key).or_insert_with(|| Box::leak(Box::new(s)))
}

/// `P(Erlang(k, rate) ≤ t) = 1 − Σ_{j<k} e^{−x} x^j / j!`, `x = rate·t`;
/// for `x` small the complementary sum `Σ_{j≥k}` (no cancellation).
pub fn erlang_cdf(k: u32, rate: f64, t: f64) -> f64 {
    if t <= 0.0 {
        return 0.0;
    }
    let x = rate * t;
    if !x.is_finite() {
        return 1.0;
    }
    let ln_x = x.ln();
    let term = |j: u32| (-x + f64::from(j) * ln_x - ln_factorial(j)).exp();
    if x < f64::from(k) {
        // Σ_{j≥k}: terms decrease once j > x
        let mut sum = 0.0;
        let mut tj = term(k);
        let mut j = k;
        while tj > sum * 1e-17 && j < k + 100_000 {
            sum += tj;
            j += 1;
            tj *= x / f64::from(j);
        }
        sum.clamp(0.0, 1.0)
    } else {
        let mut q = 0.0;
        let mut tj = (-x).exp();
        if tj == 0.0 {
            // underflow of e^{−x}: terms from their logarithms
            q = (0..k).map(term).sum();
        } else {
            for j in 0..k {
                q += tj;
                tj *= x / f64::from(j + 1);
            }
        }
        (1.0 - q).clamp(0.0, 1.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn erlang_cdf_closed_forms() {
        // Erlang-2 of rate 1: 1 − e^{−t}(1 + t)
        for t in [0.01f64, 0.5, 1.0, 3.0, 40.0] {
            let want: f64 = 1.0 - (-t).exp() * (1.0 + t);
            assert!((erlang_cdf(2, 1.0, t) - want).abs() < 1e-15, "{t}");
        }
        // Erlang-1 is the exponential
        assert!((erlang_cdf(1, 2.0, 0.3) - (1.0 - (-0.6f64).exp())).abs() < 1e-15);
        // far tail: 1 − e^{−800}·… rounds to 1, deep head to ~0
        assert_eq!(erlang_cdf(3, 1.0, 800.0), 1.0);
        assert!(erlang_cdf(50, 1.0, 1.0) < 1e-60);
    }

    #[test]
    fn hypoexponential_cdf_matches_the_two_rate_closed_form() {
        // Hypo(a, b): 1 − (b e^{−at} − a e^{−bt}) / (b − a)
        let (a, b) = (1.0f64, 3.0f64);
        let s = Stages::hypoexponential(&[a, b]).expect("valid");
        for t in [0.1, 0.7, 2.0, 6.0] {
            let want = 1.0 - (b * (-a * t).exp() - a * (-b * t).exp()) / (b - a);
            assert!(
                (s.cdf(t) - want).abs() < 1e-11,
                "{t}: {} vs {want}",
                s.cdf(t)
            );
        }
        assert!((s.mean() - (1.0 / a + 1.0 / b)).abs() < 1e-15);
    }

    #[test]
    fn equal_rates_merge_and_limits_hold() {
        let s = Stages::hypoexponential(&[2.0, 2.0, 2.0]).expect("valid");
        assert_eq!(s.as_erlang(), Some((3, 2.0)));
        assert_eq!(s, Stages::erlang(3, 2.0).expect("valid"));
        assert!(Stages::erlang(MAX_PHASES + 1, 1.0).is_err());
        assert!(Stages::hypoexponential(&[1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0]).is_err());
        assert!(Stages::hypoexponential(&[1.0, -2.0]).is_err());
        assert!(Stages::erlang(0, 1.0).is_err());
    }
}
