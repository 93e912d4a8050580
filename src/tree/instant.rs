//! When two return times are one instant: the tie rule shared by the
//! analysis and the simulator (ties are resolved in child order, §1.3).

/// Relative tolerance under which two return times are the same instant:
/// deterministic times are decimal numbers whose sums are rounded in binary
/// (0.1 + 0.2 ≠ 0.3), so `|a − b| ≤ 1e-12 · max(|a|, |b|, 1 s)` counts as a tie.
pub const SAME_INSTANT: f64 = 1e-12;

/// Whether `a` and `b` are the same instant (within [`SAME_INSTANT`]
/// relative); ∞ (never) is no instant.
pub fn same_instant(a: f64, b: f64) -> bool {
    a.is_finite() && b.is_finite() && (a - b).abs() <= SAME_INSTANT * a.abs().max(b.abs()).max(1.0)
}

#[cfg(test)]
mod tests {
    use super::same_instant;

    #[test]
    fn ties_are_decimal_sums_and_never_infinity() {
        assert!(same_instant(0.1 + 0.2, 0.3));
        assert!(same_instant(1e6 * (0.1 + 0.2), 3e5));
        assert!(!same_instant(1.0, 1.0 + 1e-9));
        assert!(!same_instant(5.0, f64::INFINITY));
        assert!(!same_instant(f64::INFINITY, f64::INFINITY));
        assert!(!same_instant(f64::NAN, f64::NAN));
    }
}
