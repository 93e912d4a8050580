//! Dual numbers: a value with its derivative along one parameter, the
//! arithmetic of the exact sensitivities (`exact`, `chain`).

/// A dual number: value and derivative along one parameter.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub(crate) struct D {
    pub v: f64,
    pub d: f64,
}

impl D {
    pub(crate) const ZERO: D = D { v: 0.0, d: 0.0 };
    pub(crate) const ONE: D = D { v: 1.0, d: 0.0 };
    pub(crate) fn c(v: f64) -> D {
        D { v, d: 0.0 }
    }
    pub(crate) fn add(self, o: D) -> D {
        D {
            v: self.v + o.v,
            d: self.d + o.d,
        }
    }
    pub(crate) fn mul(self, o: D) -> D {
        // a zero factor with a zero tangent contributes nothing, even
        // against an unknown (NaN) tangent
        let d = match (self.v == 0.0 && self.d == 0.0, o.v == 0.0 && o.d == 0.0) {
            (true, _) | (_, true) => 0.0,
            _ => self.d * o.v + self.v * o.d,
        };
        D { v: self.v * o.v, d }
    }
    pub(crate) fn div(self, o: D) -> D {
        D {
            v: self.v / o.v,
            d: (self.d * o.v - self.v * o.d) / (o.v * o.v),
        }
    }
}
