//! Gauss–Legendre quadrature with a rigorous error bound for analytic
//! integrands.
//!
//! If `f` is analytic inside the Bernstein ellipse `E_ρ` of `[-1, 1]` (foci
//! ±1, semi-axes `(ρ + 1/ρ)/2` and `(ρ − 1/ρ)/2`) and `|f| ≤ M` there, the
//! `n`-point Gauss–Legendre rule satisfies
//!
//! ```text
//! |∫_{-1}^{1} f − Q_n f| ≤ (64/15) · M · ρ^{-2(n-1)} / (ρ² − 1)
//! ```
//!
//! (Trefethen, *Is Gauss quadrature better than Clenshaw–Curtis?*, SIAM
//! Review 50 (2008), Theorem 4.5: `64 M / (15 (1 − ρ^{-2}) ρ^{2n})` for the
//! `n`-point rule, which is the same expression; there is no extra margin).
//! On a panel `[a, b]` with half-width `h` the ellipse is scaled by `h` and
//! the bound multiplied by `h`.

/// Nodes and weights of the `n`-point Gauss–Legendre rule on `[-1, 1]`.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct GaussLegendre {
    /// Nodes, increasing.
    pub nodes: Vec<f64>,
    /// Weights (positive, summing to 2).
    pub weights: Vec<f64>,
}

impl GaussLegendre {
    /// The `n`-point rule (Newton's method on the Legendre recurrence, from
    /// Tricomi's initial guesses; converges to machine precision).
    pub fn new(n: usize) -> GaussLegendre {
        assert!(n >= 1);
        let mut nodes = vec![0.0; n];
        let mut weights = vec![0.0; n];
        let nf = n as f64;
        for i in 0..n.div_ceil(2) {
            let mut x = (std::f64::consts::PI * (i as f64 + 0.75) / (nf + 0.5)).cos();
            let mut dp = 1.0;
            for _ in 0..100 {
                let (p, d) = legendre(n, x);
                dp = d;
                let dx = p / d;
                x -= dx;
                if dx.abs() < 1e-16 {
                    break;
                }
            }
            let (_, d) = legendre(n, x);
            dp = if d != 0.0 { d } else { dp };
            let w = 2.0 / ((1.0 - x * x) * dp * dp);
            nodes[i] = -x;
            nodes[n - 1 - i] = x;
            weights[i] = w;
            weights[n - 1 - i] = w;
        }
        if n % 2 == 1 {
            nodes[n / 2] = 0.0;
        }
        GaussLegendre { nodes, weights }
    }

    /// Number of points.
    pub fn len(&self) -> usize {
        self.nodes.len()
    }

    /// The bound above on `[a, b]` with half-width `h`, for `|f| ≤ m` on the
    /// scaled ellipse of parameter `rho > 1`.
    pub fn error_bound(&self, h: f64, rho: f64, m: f64) -> f64 {
        let n = self.len() as f64;
        h * 64.0 / 15.0 * m * rho.powf(-2.0 * (n - 1.0)) / (rho * rho - 1.0)
    }
}

/// `(P_n(x), P_n'(x))`.
fn legendre(n: usize, x: f64) -> (f64, f64) {
    let (mut p0, mut p1) = (1.0, x);
    for k in 2..=n {
        let k = k as f64;
        let p2 = ((2.0 * k - 1.0) * x * p1 - (k - 1.0) * p0) / k;
        p0 = p1;
        p1 = p2;
    }
    if n == 0 {
        return (1.0, 0.0);
    }
    let d = n as f64 * (x * p1 - p0) / (x * x - 1.0);
    (p1, d)
}

/// The Bernstein ellipse of parameter `rho` around the panel `[a, b]`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Ellipse {
    /// Centre (real).
    pub centre: f64,
    /// Semi-axis along the real line, `h (ρ + 1/ρ)/2`.
    pub semi_major: f64,
    /// Semi-axis along the imaginary line, `h (ρ − 1/ρ)/2`.
    pub semi_minor: f64,
}

impl Ellipse {
    /// The ellipse of `[a, b]` with parameter `rho`.
    pub fn new(a: f64, b: f64, rho: f64) -> Ellipse {
        let h = (b - a) / 2.0;
        Ellipse {
            centre: (a + b) / 2.0,
            semi_major: h * (rho + 1.0 / rho) / 2.0,
            semi_minor: h * (rho - 1.0 / rho) / 2.0,
        }
    }

    /// Leftmost real point.
    pub fn left(&self) -> f64 {
        self.centre - self.semi_major
    }

    /// An upper bound on `|z| − Re z` over the ellipse: at most `|Im z|`
    /// where `Re z ≥ 0`, at most `y²/(2 Re z)` when `Re z ≥ x₀ > 0`, and at
    /// most `|Im z| + 2|Re z|` where `Re z < 0`.
    pub fn excess(&self) -> f64 {
        let (b, x_lo) = (self.semi_minor, self.left());
        if x_lo > 0.0 {
            b.min(b * b / (2.0 * x_lo))
        } else {
            b + 2.0 * (-x_lo)
        }
    }

    /// Largest `ρ` whose ellipse around `[a, b]` reaches at most `gap`
    /// beyond each end.
    pub fn largest_rho(a: f64, b: f64, gap: f64) -> f64 {
        let h = (b - a) / 2.0;
        let k = 2.0 * (1.0 + gap / h);
        (k + (k * k - 4.0).sqrt()) / 2.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rules_integrate_polynomials_exactly() {
        for n in [1, 2, 5, 16, 24] {
            let g = GaussLegendre::new(n);
            assert!((g.weights.iter().sum::<f64>() - 2.0).abs() < 1e-14);
            // exact up to degree 2n − 1: ∫ x^k over [-1, 1]
            for k in 0..2 * n {
                let q: f64 = g
                    .nodes
                    .iter()
                    .zip(&g.weights)
                    .map(|(x, w)| w * x.powi(k as i32))
                    .sum();
                let exact = if k % 2 == 1 {
                    0.0
                } else {
                    2.0 / (k as f64 + 1.0)
                };
                assert!((q - exact).abs() < 1e-13, "n={n} k={k}: {q} vs {exact}");
            }
        }
    }

    #[test]
    fn bound_holds_for_an_exponential() {
        // ∫_0^2 e^{-3t} dt on one panel: |e^{-3z}| ≤ e^{3(h(ρ+1/ρ)/2 − c)}
        let g = GaussLegendre::new(8);
        let (a, b) = (0.0f64, 2.0f64);
        let (c, h) = ((a + b) / 2.0, (b - a) / 2.0);
        let q: f64 = g
            .nodes
            .iter()
            .zip(&g.weights)
            .map(|(x, w)| w * h * (-3.0 * (c + h * x)).exp())
            .sum();
        let exact = (1.0 - (-6.0f64).exp()) / 3.0;
        for rho in [1.5, 2.0, 4.0, 8.0] {
            let e = Ellipse::new(a, b, rho);
            let m = (-3.0 * e.left()).exp();
            let bound = g.error_bound(h, rho, m);
            assert!(
                (q - exact).abs() <= bound,
                "ρ={rho}: {} > {bound}",
                q - exact
            );
        }
    }

    #[test]
    fn largest_rho_reaches_the_gap() {
        let rho = Ellipse::largest_rho(1.0, 3.0, 0.5);
        let e = Ellipse::new(1.0, 3.0, rho);
        assert!((e.left() - 0.5).abs() < 1e-12 && (e.centre + e.semi_major - 3.5).abs() < 1e-12);
    }
}
