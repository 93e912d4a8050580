//! Accumulators: per-chunk raw sums, and their exact-order merge.
//!
//! Within a chunk, durations are summed *shifted* by the chunk's first value
//! (`Σ(x−K)`, `Σ(x−K)²`), which is cheap (no division per sample) and keeps
//! the variance free of catastrophic cancellation, since `K` is a typical
//! value (it is exact for constant durations). Each chunk is then turned into
//! (count, mean, M2) and merged into the total with Chan et al.'s pairwise
//! formula, always in chunk order, so the result does not depend on which
//! thread ran which chunk.

use super::{Estimate, Z95};

/// Shifted sums of the durations of one chunk.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct Raw {
    n: u64,
    shift: f64,
    s1: f64,
    s2: f64,
}

impl Raw {
    #[inline(always)]
    pub(crate) fn push(&mut self, x: f64) {
        if self.n == 0 {
            self.shift = x;
        }
        let d = x - self.shift;
        self.n += 1;
        self.s1 += d;
        self.s2 += d * d;
    }
}

/// Count, mean and sum of squared deviations (M2) of a set of durations.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(crate) struct Moments {
    pub(crate) n: u64,
    mean: f64,
    m2: f64,
}

impl Moments {
    /// Adds one chunk's sums (Chan, Golub & LeVeque's parallel update).
    pub(crate) fn merge(&mut self, raw: &Raw) {
        if raw.n == 0 {
            return;
        }
        let nb = raw.n as f64;
        let d_mean = raw.s1 / nb;
        let mean_b = raw.shift + d_mean;
        let m2_b = (raw.s2 - raw.s1 * d_mean).max(0.0);
        if self.n == 0 {
            *self = Moments {
                n: raw.n,
                mean: mean_b,
                m2: m2_b,
            };
            return;
        }
        let na = self.n as f64;
        let n = na + nb;
        let delta = mean_b - self.mean;
        self.mean += delta * (nb / n);
        self.m2 += m2_b + delta * delta * (na * nb / n);
        self.n += raw.n;
    }

    /// Mean with standard error `s/√n` (`s` the sample standard deviation);
    /// `None` without data. With a single value `se` is infinite (unknown).
    pub(crate) fn estimate(&self) -> Option<Estimate> {
        if self.n == 0 {
            return None;
        }
        let n = self.n as f64;
        let se = if self.n < 2 {
            f64::INFINITY
        } else {
            (self.m2 / (n - 1.0) / n).sqrt()
        };
        Some(Estimate::with_se(self.mean, se, self.n))
    }
}

/// Binomial proportion `k / n` with standard error `√(p(1−p)/n)`.
pub(crate) fn proportion(k: u64, n: u64) -> Estimate {
    let nf = n as f64;
    let p = k as f64 / nf;
    Estimate::with_se(p, (p * (1.0 - p) / nf).sqrt(), n)
}

impl Estimate {
    /// An estimate with its Wald 95 % interval `mean ± 1.96·se`.
    pub(crate) fn with_se(mean: f64, se: f64, count: u64) -> Estimate {
        Estimate {
            mean,
            se,
            ci95: (mean - Z95 * se, mean + Z95 * se),
            count,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn chan_merge_matches_two_pass() {
        let xs: Vec<f64> = (0..1000)
            .map(|i| 1e6 + ((i * 37) % 101) as f64 * 0.01)
            .collect();
        let mut m = Moments::default();
        for chunk in xs.chunks(77) {
            let mut r = Raw::default();
            chunk.iter().for_each(|&x| r.push(x));
            m.merge(&r);
        }
        let n = xs.len() as f64;
        let mean = xs.iter().sum::<f64>() / n;
        let m2: f64 = xs.iter().map(|x| (x - mean) * (x - mean)).sum();
        assert_eq!(m.n, 1000);
        assert!((m.mean - mean).abs() < 1e-9);
        assert!((m.m2 - m2).abs() < 1e-9 * m2);
    }

    #[test]
    fn constant_has_zero_variance() {
        let mut m = Moments::default();
        for _ in 0..3 {
            let mut r = Raw::default();
            (0..10).for_each(|_| r.push(0.1));
            m.merge(&r);
        }
        let e = m.estimate().unwrap();
        assert_eq!((e.mean, e.se, e.count), (0.1, 0.0, 30));
    }
}
