//! Number formatting shared by the exporters.

/// Formats `x` with `digits` significant digits: fixed notation for
/// magnitudes in [1e-4, 1e6), scientific otherwise; trailing zeros kept so
/// columns line up.
pub fn significant(x: f64, digits: usize) -> String {
    if x == 0.0 {
        return "0".to_string();
    }
    if !x.is_finite() {
        return x.to_string();
    }
    let digits = digits.max(1);
    let magnitude = x.abs().log10().floor() as i32;
    if (-4..6).contains(&magnitude) {
        let decimals = (digits as i32 - 1 - magnitude).max(0) as usize;
        let s = format!("{x:.decimals$}");
        // rounding can carry into a new digit (9.99995 -> 10.0000): drop one
        let rounded: f64 = s.parse().unwrap_or(x);
        if rounded.abs().log10().floor() as i32 > magnitude && decimals > 0 {
            let d = decimals - 1;
            return format!("{x:.d$}");
        }
        s
    } else {
        format!("{:.*e}", digits - 1, x)
    }
}

/// Formats an optional figure; undefined values are an em dash.
pub fn significant_or_dash(x: Option<f64>, digits: usize) -> String {
    x.map_or_else(|| "—".to_string(), |v| significant(v, digits))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn formats() {
        assert_eq!(significant(0.488400000001, 5), "0.48840");
        assert_eq!(significant(169.37764, 5), "169.38");
        assert_eq!(significant(5.903967e-3, 5), "0.0059040");
        assert_eq!(significant(2.5e-7, 5), "2.5000e-7");
        assert_eq!(significant(1234567.0, 5), "1.2346e6");
        assert_eq!(significant(9.99999, 5), "10.000");
        assert_eq!(significant(0.0, 5), "0");
        assert_eq!(significant_or_dash(None, 5), "—");
    }
}
