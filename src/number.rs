//! Number formatting shared by the reports, the exporters and the library's sentences.

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
    // scientific formatting rounds correctly and gives the exponent after
    // rounding (9.99999 -> 1.0000e1)
    let sci = format!("{:.*e}", digits - 1, x.abs());
    let (mantissa, exponent) = sci.split_once('e').expect("scientific notation");
    let exponent: i32 = exponent.parse().expect("integer exponent");
    let sign = if x < 0.0 { "-" } else { "" };
    if !(-4..6).contains(&exponent) {
        return format!("{sign}{mantissa}e{exponent}");
    }
    let significand: String = mantissa.chars().filter(|&c| c != '.').collect();
    let mut out = String::with_capacity(digits + 8);
    out.push_str(sign);
    if exponent >= 0 {
        let int_len = exponent as usize + 1;
        if significand.len() <= int_len {
            out.push_str(&significand);
            out.extend(std::iter::repeat_n('0', int_len - significand.len()));
        } else {
            out.push_str(&significand[..int_len]);
            out.push('.');
            out.push_str(&significand[int_len..]);
        }
    } else {
        out.push_str("0.");
        out.extend(std::iter::repeat_n('0', (-exponent - 1) as usize));
        out.push_str(&significand);
    }
    out
}

/// Full precision: the shortest text that reads back as the same `f64`, in
/// scientific notation for very small or very large magnitudes.
pub fn full(x: f64) -> String {
    let a = x.abs();
    if a != 0.0 && !(1e-5..1e16).contains(&a) {
        format!("{x:e}")
    } else {
        format!("{x}")
    }
}

/// Formats an optional figure; undefined values are an em dash.
pub(crate) fn significant_or_dash(x: Option<f64>, digits: usize) -> String {
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
        assert_eq!(significant(-0.012345678, 4), "-0.01235");
        assert_eq!(significant(100000.0, 3), "100000");
        assert_eq!(significant(0.00012345, 3), "0.000123");
        assert_eq!(significant_or_dash(None, 5), "—");
        assert_eq!(full(1.1102230246251565e-16), "1.1102230246251565e-16");
        assert_eq!(full(0.19773976596072151), "0.19773976596072151");
        for x in [1e-300, 3.0e-6, 0.1, 123456.789, 1e20] {
            assert_eq!(full(x).parse::<f64>().unwrap(), x);
        }
    }
}
