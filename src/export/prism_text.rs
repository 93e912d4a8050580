//! Text in PRISM's language shared by the PRISM exporters: numbers that read
//! back as the same `f64`, and comments.

/// A number PRISM parses back to exactly `x` (`x ≥ 0`, finite).
pub fn prism_number(x: f64) -> String {
    let a = x.abs();
    if x == 0.0 {
        "0.0".to_string()
    } else if (1e-4..1e15).contains(&a) {
        let s = format!("{x}");
        if s.contains('.') {
            s
        } else {
            format!("{s}.0")
        }
    } else {
        format!("{x:e}")
    }
}

/// `text` on one line, for a `//` comment.
pub(crate) fn comment(text: &str) -> String {
    text.replace(['\n', '\r'], " ")
}
