//! The convolution of an exponential density with a measure, anywhere in
//! O(1) after O(panels) set-up.
//!
//! For a measure `μ = Σ a_i δ_{τ_i} + g` (atoms and an [`Interpolant`]
//! density) and a rate `λ`, `z = λe^{−λ·} ⊛ μ` solves `z' = λ(g − z)` with
//! a jump of `λ a_i` at each `τ_i`. So, with checkpoints `x_k` at `g`'s panel
//! edges and the atoms, and `Z_k = z(x_k+)`,
//!
//! ```text
//! z(t) = e^{−λ(t − x_k)} Z_k + λ ∫_{x_k}^{t} e^{−λ(t − v)} g(v) dv,   x_k ≤ t < x_{k+1},
//! ```
//!
//! one Gauss–Legendre rule over `[x_k, t]`, where `g` is one polynomial.
//! The rule is split so that `λ` times each part's length is at most 8
//! (the `POINTS`-point rule's error for `e^{−x}` on such a part is below
//! 1e-30 relative), and the integral starts at `t − 50/λ` at the latest:
//! the kernel weighs less than `e^{−50} ≈ 2e-22` before that. This is the
//! cost of a convolution with a leaf's exponential time linear in the
//! panels, where a density ⊛ density convolution is quadratic.

use super::interpolant::{Interpolant, POINTS};
use super::quadrature::GaussLegendre;
use std::sync::OnceLock;

/// Longest part of an integral in units of `1/λ`.
const PART: f64 = 8.0;

/// Where the kernel is taken as 0, in units of `1/λ`.
const REACH: f64 = 50.0;

fn rule() -> &'static GaussLegendre {
    static RULE: OnceLock<GaussLegendre> = OnceLock::new();
    RULE.get_or_init(|| GaussLegendre::new(POINTS))
}

/// `z = λe^{−λ·} ⊛ μ`, ready to evaluate.
#[derive(Debug, Clone)]
pub(crate) struct ExponentialConvolution<'a> {
    rate: f64,
    density: Option<&'a Interpolant>,
    /// Checkpoints, increasing.
    at: Vec<f64>,
    /// `z` just after each checkpoint.
    value: Vec<f64>,
}

impl<'a> ExponentialConvolution<'a> {
    /// `λe^{−λ·} ⊛ (Σ atoms + density)` for `rate` `λ > 0`, `atoms`
    /// `(instant ≥ 0, mass)` in any order.
    pub fn new(
        rate: f64,
        atoms: &[(f64, f64)],
        density: Option<&'a Interpolant>,
    ) -> ExponentialConvolution<'a> {
        let mut points: Vec<(f64, f64)> = atoms.to_vec();
        if let Some(g) = density {
            points.extend(g.edges().iter().map(|&e| (e, 0.0)));
        }
        points.push((0.0, 0.0));
        points.sort_by(|a, b| a.0.total_cmp(&b.0));
        let mut out = ExponentialConvolution {
            rate,
            density,
            at: Vec::with_capacity(points.len()),
            value: Vec::with_capacity(points.len()),
        };
        let mut z = 0.0;
        for (x, a) in points {
            match out.at.last() {
                Some(&last) if x == last => {}
                Some(&last) => {
                    z = (-rate * (x - last)).exp() * z + rate * out.integral(last, x);
                    out.at.push(x);
                    out.value.push(z);
                }
                None => {
                    out.at.push(x);
                    out.value.push(z);
                }
            }
            z += rate * a;
            *out.value.last_mut().expect("a checkpoint was pushed") = z;
        }
        out
    }

    /// `z(t)` (its right limit at an atom; 0 before 0).
    pub fn at(&self, t: f64) -> f64 {
        if t < 0.0 {
            return 0.0;
        }
        let k = self.at.partition_point(|&x| x <= t) - 1;
        let x = self.at[k];
        (-self.rate * (t - x)).exp() * self.value[k] + self.rate * self.integral(x, t)
    }

    /// `∫_a^t e^{−λ(t − v)} g(v) dv` for `[a, t]` within one panel of `g`.
    fn integral(&self, a: f64, t: f64) -> f64 {
        match self.density {
            Some(g) => integral(self.rate, g, a, t),
            None => 0.0,
        }
    }
}

/// `∫_a^t e^{−λ(t − v)} g(v) dv` for `[a, t]` within one panel of `g`.
fn integral(rate: f64, g: &Interpolant, a: f64, t: f64) -> f64 {
    let a = a.max(t - REACH / rate);
    if t <= a || a >= g.end() {
        return 0.0;
    }
    let panel = g.panel_of((a + t) / 2.0);
    if g.panel_is_zero(panel) {
        return 0.0;
    }
    let parts = ((rate * (t - a) / PART).ceil() as usize).max(1);
    let width = (t - a) / parts as f64;
    let rule = rule();
    let mut total = 0.0;
    for p in 0..parts {
        let (c, h) = (a + (p as f64 + 0.5) * width, width / 2.0);
        let v: [f64; POINTS] = std::array::from_fn(|j| c + h * rule.nodes[j]);
        let gv = g.eval_block_in(panel, &v);
        total += h
            * (0..POINTS)
                .map(|j| rule.weights[j] * (-rate * (t - v[j])).exp() * gv[j])
                .sum::<f64>();
    }
    total
}

/// `z = λe^{−λ·} ⊛ g` for a density `g` that grows panel by panel (a
/// renewal equation marched in time, `compile::law`): the checkpoints of
/// [`ExponentialConvolution`] at `g`'s panel edges, extended as panels
/// come ([`Self::catch_up`]); past `g`'s end, `z` is what came before it,
/// decaying — the convolution with `g` cut at its end.
#[derive(Debug, Clone)]
pub(crate) struct ExponentialMarch {
    rate: f64,
    /// `g`'s panel edges so far.
    at: Vec<f64>,
    /// `z` at each.
    value: Vec<f64>,
}

impl ExponentialMarch {
    /// For rate `λ > 0`, before any panel.
    pub fn new(rate: f64) -> ExponentialMarch {
        ExponentialMarch {
            rate,
            at: Vec::new(),
            value: Vec::new(),
        }
    }

    /// Takes in the panels of `g` added since the last call (`g` only
    /// grows: its earlier panels are the ones seen before).
    pub fn catch_up(&mut self, g: &Interpolant) {
        let edges = g.edges();
        if self.at.is_empty() {
            let Some(&first) = edges.first() else { return };
            self.at.push(first);
            self.value.push(0.0);
        }
        for &e in &edges[self.at.len()..] {
            let last = *self.at.last().expect("a checkpoint");
            let z = *self.value.last().expect("a checkpoint");
            let next =
                (-self.rate * (e - last)).exp() * z + self.rate * integral(self.rate, g, last, e);
            self.at.push(e);
            self.value.push(next);
        }
    }

    /// `z(t)` of `g` as taken in (0 before `g`'s start).
    pub fn at(&self, g: &Interpolant, t: f64) -> f64 {
        let Some(&first) = self.at.first() else {
            return 0.0;
        };
        if t <= first {
            return 0.0;
        }
        let last = self.at.len() - 1;
        if t >= self.at[last] {
            return (-self.rate * (t - self.at[last])).exp() * self.value[last];
        }
        let k = self.at.partition_point(|&x| x <= t) - 1;
        (-self.rate * (t - self.at[k])).exp() * self.value[k]
            + self.rate * integral(self.rate, g, self.at[k], t)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::solve::interpolant::build1 as density;

    #[test]
    fn atoms_give_shifted_exponentials() {
        // λ a e^{−λ(t − τ)} after each atom τ
        let (l, atoms) = (3.0, [(0.5, 0.25), (0.0, 0.5), (2.0, 0.125)]);
        let z = ExponentialConvolution::new(l, &atoms, None);
        for t in [0.0, 0.3, 0.5, 1.0, 2.0, 2.5, 10.0] {
            let exact: f64 = atoms
                .iter()
                .filter(|a| a.0 <= t)
                .map(|&(tau, a)| l * a * (-l * (t - tau)).exp())
                .sum();
            assert!((z.at(t) - exact).abs() < 1e-15, "t = {t}");
        }
        assert_eq!(z.at(-1.0), 0.0);
    }

    #[test]
    fn exponential_densities_give_hypoexponential_and_erlang() {
        // λe^{−λt} ⊛ κe^{−κt} = λκ (e^{−κt} − e^{−λt}) / (λ − κ)
        let (l, k, end) = (10.0, 0.05, 100.0);
        let g = density(end, |t| k * (-k * t).exp());
        let z = ExponentialConvolution::new(l, &[], Some(&g));
        for t in [1e-6, 0.01, 0.7, 3.0, 33.3, 99.9] {
            let exact = l * k * ((-k * t).exp() - (-l * t).exp()) / (l - k);
            assert!((z.at(t) - exact).abs() < 1e-13 * exact.max(1e-3), "t = {t}");
        }
        // equal rates: the Erlang-2 density λ²te^{−λt}
        let g = density(end, |t| 2.0 * (-2.0 * t).exp());
        let z = ExponentialConvolution::new(2.0, &[], Some(&g));
        for t in [0.1f64, 1.0, 5.0, 40.0] {
            let exact = 4.0 * t * (-2.0 * t).exp();
            assert!((z.at(t) - exact).abs() < 1e-14, "t = {t}");
        }
    }

    /// The marched recursion (as a renewal density's panels come) against
    /// the closed form of `λe^{−λ·} ⊛ κe^{−κ·}` on the density's domain, and
    /// past its end the value there decaying (the density cut at its end:
    /// `z(T)e^{−λ(t − T)}`, by hand).
    #[test]
    fn the_march_is_the_convolution_with_the_density_so_far() {
        let (l, k, end) = (3.0, 0.7, 12.0);
        let g = density(end, |t| k * (-k * t).exp());
        let mut z = ExponentialMarch::new(l);
        assert_eq!(z.at(&g, 1.0), 0.0, "before any panel");
        z.catch_up(&g);
        z.catch_up(&g);
        let exact = |t: f64| l * k * ((-k * t).exp() - (-l * t).exp()) / (l - k);
        for t in [1e-6, 0.01, 0.7, 3.0, 7.77, 11.99, 12.0] {
            assert!((z.at(&g, t) - exact(t)).abs() < 1e-13, "t = {t}");
        }
        for t in [12.5, 20.0] {
            let cut = exact(end) * (-l * (t - end)).exp();
            assert!((z.at(&g, t) - cut).abs() < 1e-13, "t = {t}");
        }
        assert_eq!(z.at(&g, -1.0), 0.0);
    }
}
