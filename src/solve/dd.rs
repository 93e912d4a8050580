//! Double-double arithmetic (about 32 significant digits) for the few
//! computations whose error bounds need more than `f64`.
//!
//! A value is the unevaluated sum `hi + lo` with `|lo| ≤ ulp(hi)/2`. The
//! operations are the classic error-free transformations (Knuth's two-sum,
//! fused-multiply-add two-product). Used on non-negative operands only,
//! where the relative error of each operation is below 2⁻¹⁰⁰.

use std::ops::{Add, Mul};

/// A double-double number.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub(crate) struct Dd {
    /// Leading part.
    pub hi: f64,
    /// Trailing part.
    pub lo: f64,
}

/// Unit roundoff bound used in error analyses (2⁻¹⁰⁰, conservative).
pub const EPS: f64 = 7.888609052210118e-31;

#[inline]
fn two_sum(a: f64, b: f64) -> (f64, f64) {
    let s = a + b;
    let bb = s - a;
    (s, (a - (s - bb)) + (b - bb))
}

#[inline]
fn quick_two_sum(a: f64, b: f64) -> Dd {
    let s = a + b;
    Dd {
        hi: s,
        lo: b - (s - a),
    }
}

#[inline]
fn two_prod(a: f64, b: f64) -> (f64, f64) {
    let p = a * b;
    (p, a.mul_add(b, -p))
}

impl Dd {
    /// Zero.
    pub const ZERO: Dd = Dd { hi: 0.0, lo: 0.0 };
    /// One.
    pub const ONE: Dd = Dd { hi: 1.0, lo: 0.0 };

    /// An exact `f64`.
    pub fn from_f64(x: f64) -> Dd {
        Dd { hi: x, lo: 0.0 }
    }

    /// The exact product of two `f64`s.
    pub fn product(a: f64, b: f64) -> Dd {
        let (p, e) = two_prod(a, b);
        Dd { hi: p, lo: e }
    }

    /// The exact difference of two `f64`s.
    pub fn difference(a: f64, b: f64) -> Dd {
        let (s, e) = two_sum(a, -b);
        Dd { hi: s, lo: e }
    }

    /// Rounded to `f64`.
    pub fn to_f64(self) -> f64 {
        self.hi + self.lo
    }

    /// Division by an `f64` (one Newton correction).
    pub fn div_f64(self, b: f64) -> Dd {
        let q1 = self.hi / b;
        let (p, e) = two_prod(q1, b);
        let (s, f) = two_sum(self.hi, -p);
        let r = (s + (f - e + self.lo)) / b;
        quick_two_sum(q1, r)
    }

    /// `e^{-x}` for `0 ≤ x ≤ 1` by its Taylor series (terms alternate and
    /// shrink, the error is below the first omitted term).
    pub fn exp_neg(x: Dd) -> Dd {
        // e^{-x} = 1/e^{x}; sum e^{x} (all terms positive) then invert
        let mut term = Dd::ONE;
        let mut sum = Dd::ONE;
        for k in 1..40 {
            term = (term * x).div_f64(k as f64);
            sum = sum + term;
            if term.hi < 1e-34 * sum.hi {
                break;
            }
        }
        Dd::ONE.div_dd(sum)
    }

    /// Division by a double-double.
    pub fn div_dd(self, b: Dd) -> Dd {
        let q1 = self.hi / b.hi;
        let r = self + (b * Dd::from_f64(-q1));
        let q2 = r.hi / b.hi;
        let r = r + (b * Dd::from_f64(-q2));
        let q3 = r.hi / b.hi;
        let q = quick_two_sum(q1, q2);
        q + Dd::from_f64(q3)
    }
}

impl Add for Dd {
    type Output = Dd;
    #[inline]
    fn add(self, b: Dd) -> Dd {
        let (s, e) = two_sum(self.hi, b.hi);
        let (t, f) = two_sum(self.lo, b.lo);
        let e = e + t;
        let r = quick_two_sum(s, e);
        quick_two_sum(r.hi, r.lo + f)
    }
}

impl Mul for Dd {
    type Output = Dd;
    #[inline]
    fn mul(self, b: Dd) -> Dd {
        let (p, e) = two_prod(self.hi, b.hi);
        let e = e + (self.hi * b.lo + self.lo * b.hi);
        quick_two_sum(p, e)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn arithmetic_beyond_f64() {
        // (1 + 2^-60)^2 = 1 + 2^-59 + 2^-120
        let x = Dd::ONE + Dd::from_f64(2f64.powi(-60));
        let y = x * x;
        assert_eq!(y.hi, 1.0);
        assert_eq!(y.lo, 2f64.powi(-59));
        let third = Dd::ONE.div_f64(3.0);
        let back = third * Dd::from_f64(3.0);
        assert!((back.hi - 1.0).abs() + back.lo.abs() < 1e-31);
    }

    #[test]
    fn exp_neg_matches_known_values() {
        let e = Dd::exp_neg(Dd::ONE);
        // 1/e = 0.36787944117144232159552377016146...
        let err = (e.hi - 0.36787944117144233) + e.lo;
        assert!(err.abs() < 1e-16, "{e:?}");
        assert!((Dd::exp_neg(Dd::from_f64(0.5)).to_f64() - (-0.5f64).exp()).abs() < 1e-16);
    }
}
