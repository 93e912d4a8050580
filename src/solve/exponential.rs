//! The convolution of an Erlang density with a measure, anywhere in O(1)
//! after O(panels) set-up.
//!
//! For a measure `μ = Σ a_i δ_{τ_i} + g` (atoms and an [`Interpolant`]
//! density), a rate `λ` and `E_j(u) = λ(λu)^{j−1}e^{−λu}/(j − 1)!` (the
//! Erlang-`j` density; `E_1` the exponential), `z_j = E_j ⊛ μ`. Since
//! `E_j(a + b) = Σ_{i ≤ j} P_{j−i}(λa) E_i(b)` with
//! `P_n(y) = yⁿe^{−y}/n!` (the binomial theorem), with checkpoints `x_k` at
//! `g`'s panel edges and the atoms, and `Z_{k,i} = z_i(x_k+)`,
//!
//! ```text
//! z_j(t) = Σ_{i ≤ j} P_{j−i}(λ(t − x_k)) Z_{k,i} + ∫_{x_k}^{t} E_j(t − v) g(v) dv,   x_k ≤ t < x_{k+1},
//! ```
//!
//! one Gauss–Legendre rule over `[x_k, t]`, where `g` is one polynomial
//! (an atom `a` at `x_k` adds `λa` to `z_1` only: `E_j(0) = 0` for `j ≥ 2`).
//! The rule is split so that `λ` times each part's length is at most 8
//! (the `POINTS`-point rule's error for `e^{−x}` on such a part is below
//! 1e-30 relative; with at most [`MAX_STAGES`] stages the rest of the
//! integrand is a polynomial the rule integrates exactly), and the
//! integral starts where the kernel has fallen below `e^{−50} ≈ 2e-22`
//! ([`reach`]). This is the cost of a convolution with a leaf's
//! exponential or Erlang time (or a sum of them, shifted) linear in the
//! panels, where a density ⊛ density convolution is quadratic.

use super::interpolant::{
    chebyshev_coefficients, chebyshev_sum, panel_points, Interpolant, POINTS,
};
use super::quadrature::GaussLegendre;
use std::sync::OnceLock;

/// Longest part of an integral in units of `1/λ`.
const PART: f64 = 8.0;

/// Most stages a convolution computes (the rule integrates `E_j` times a
/// panel's polynomial exactly up to there).
pub(crate) const MAX_STAGES: usize = 16;

fn rule() -> &'static GaussLegendre {
    static RULE: OnceLock<GaussLegendre> = OnceLock::new();
    RULE.get_or_init(|| GaussLegendre::new(POINTS))
}

/// Where `E_j` for `j ≤ stages` has fallen below `e^{−50}` of its peak
/// scale, in units of `1/λ` (`(λu)^{15}/15! e^{−λu} < e^{−50}` past 100).
fn reach(stages: usize) -> f64 {
    50.0 + 3.2 * (stages as f64 - 1.0)
}

/// `P_n(y) = yⁿe^{−y}/n!` for `n < out.len()`.
fn poisson_weights(y: f64, out: &mut [f64]) {
    let mut p = (-y).exp();
    for (n, o) in out.iter_mut().enumerate() {
        if n > 0 {
            p *= y / n as f64;
        }
        *o = p;
    }
}

/// `E_j(u)` for `j = 1..=out.len()` (`u ≥ 0`).
pub(crate) fn erlang_densities(rate: f64, u: f64, out: &mut [f64]) {
    let mut e = rate * (-rate * u).exp();
    for (j, o) in out.iter_mut().enumerate() {
        if j > 0 {
            e *= rate * u / j as f64;
        }
        *o = e;
    }
}

/// `z ← Σ_{i ≤ j} P_{j−i}(λh) z_i` for every `j` (the stages' values `h`
/// later, with nothing new convolved).
fn decay(rate: f64, h: f64, z: &mut [f64]) {
    let mut p = [0.0; MAX_STAGES];
    let p = &mut p[..z.len()];
    poisson_weights(rate * h, p);
    for j in (0..z.len()).rev() {
        z[j] = (0..=j).map(|i| p[j - i] * z[i]).sum();
    }
}

/// Adds `∫_a^t E_j(t − v) g(v) dv` to `acc[j − 1]` for every stage, for
/// `[a, t]` within one panel of `g`.
fn integral(rate: f64, g: &Interpolant, a: f64, t: f64, acc: &mut [f64]) {
    let a = a.max(t - reach(acc.len()) / rate);
    if t <= a || a >= g.end() {
        return;
    }
    let panel = g.panel_of((a + t) / 2.0);
    if g.panel_is_zero(panel) {
        return;
    }
    let parts = ((rate * (t - a) / PART).ceil() as usize).max(1);
    let width = (t - a) / parts as f64;
    let rule = rule();
    let mut e = [0.0; MAX_STAGES];
    let e = &mut e[..acc.len()];
    for p in 0..parts {
        let (c, h) = (a + (p as f64 + 0.5) * width, width / 2.0);
        let v: [f64; POINTS] = std::array::from_fn(|j| c + h * rule.nodes[j]);
        let gv = g.eval_block_in(panel, &v);
        for j in 0..POINTS {
            erlang_densities(rate, t - v[j], e);
            let w = h * rule.weights[j] * gv[j];
            for (s, x) in acc.iter_mut().zip(e.iter()) {
                *s += w * x;
            }
        }
    }
}

/// `z_j = E_j ⊛ μ` for `j ≤ stages`, ready to evaluate.
#[derive(Debug, Clone)]
pub(crate) struct ErlangConvolution<'a> {
    rate: f64,
    stages: usize,
    density: Option<&'a Interpolant>,
    /// Checkpoints, increasing.
    at: Vec<f64>,
    /// `z_1..z_stages` just after each checkpoint, one after another.
    value: Vec<f64>,
}

impl<'a> ErlangConvolution<'a> {
    /// `E_j ⊛ (Σ atoms + density)` for `rate` `λ > 0`, `j ≤ stages`
    /// (`1..=MAX_STAGES`), `atoms` `(instant ≥ 0, mass)` in any order.
    pub fn new(
        rate: f64,
        stages: usize,
        atoms: &[(f64, f64)],
        density: Option<&'a Interpolant>,
    ) -> ErlangConvolution<'a> {
        assert!((1..=MAX_STAGES).contains(&stages), "{stages} stages");
        let mut points: Vec<(f64, f64)> = atoms.to_vec();
        if let Some(g) = density {
            points.extend(g.edges().iter().map(|&e| (e, 0.0)));
        }
        points.push((0.0, 0.0));
        points.sort_by(|a, b| a.0.total_cmp(&b.0));
        let mut out = ErlangConvolution {
            rate,
            stages,
            density,
            at: Vec::with_capacity(points.len()),
            value: Vec::with_capacity(points.len() * stages),
        };
        let mut z = vec![0.0; stages];
        for (x, a) in points {
            match out.at.last() {
                Some(&last) if x == last => {
                    out.value.truncate(out.value.len() - stages);
                }
                Some(&last) => {
                    decay(rate, x - last, &mut z);
                    if let Some(g) = density {
                        integral(rate, g, last, x, &mut z);
                    }
                    out.at.push(x);
                }
                None => out.at.push(x),
            }
            z[0] += rate * a;
            out.value.extend_from_slice(&z);
        }
        out
    }

    /// `z_1(t), …, z_stages(t)` into `out` (right limits at an atom; 0
    /// before 0).
    pub fn at(&self, t: f64, out: &mut [f64]) {
        let out = &mut out[..self.stages];
        if t < 0.0 {
            out.fill(0.0);
            return;
        }
        let k = self.at.partition_point(|&x| x <= t) - 1;
        let x = self.at[k];
        out.copy_from_slice(&self.value[k * self.stages..(k + 1) * self.stages]);
        decay(self.rate, t - x, out);
        if let Some(g) = self.density {
            integral(self.rate, g, x, t, out);
        }
    }
}

/// Widest panel, in units of `1/λ`, on which [`ErlangMarch`] keeps `z`
/// as a polynomial: there `z_j` is `e^{−λ·}` times a polynomial plus the
/// convolution of the panel's polynomial, and its interpolation at the
/// panel's [`POINTS`] Chebyshev points errs by about `2·1^{17}/17! ≈ 6e-15`
/// of its size at most.
const SMOOTH: f64 = 2.0;

/// `z_j = E_j ⊛ g` for a density `g` that grows panel by panel (a renewal
/// equation marched in time, `compile::law`): the checkpoints of
/// [`ErlangConvolution`] at `g`'s panel edges, extended as panels come
/// ([`Self::catch_up`]); past `g`'s end, `z` is what came before it,
/// decaying — the convolution with `g` cut at its end. On a panel no wider
/// than [`SMOOTH`]`/λ`, `z` is kept as one polynomial per stage
/// (interpolated at the panel's points when the panel comes): the march
/// asks `z` at each of its points once per shift of its kernel's terms, and
/// the polynomial answers without an integral.
#[derive(Debug, Clone)]
pub(crate) struct ErlangMarch {
    rate: f64,
    stages: usize,
    /// `g`'s panel edges so far.
    at: Vec<f64>,
    /// `z_1..z_stages` at each, one after another.
    value: Vec<f64>,
    /// Per panel, where its `z` is kept as polynomials: the offset of their
    /// Chebyshev coefficients in `chebyshev` (`stages · POINTS` of them).
    smooth: Vec<Option<usize>>,
    chebyshev: Vec<f64>,
}

impl ErlangMarch {
    /// For rate `λ > 0` and `1..=MAX_STAGES` stages, before any panel.
    pub fn new(rate: f64, stages: usize) -> ErlangMarch {
        assert!((1..=MAX_STAGES).contains(&stages), "{stages} stages");
        ErlangMarch {
            rate,
            stages,
            at: Vec::new(),
            value: Vec::new(),
            smooth: Vec::new(),
            chebyshev: Vec::new(),
        }
    }

    /// Takes in the panels of `g` added since the last call (`g` only
    /// grows: its earlier panels are the ones seen before).
    pub fn catch_up(&mut self, g: &Interpolant) {
        let edges = g.edges();
        if self.at.is_empty() {
            let Some(&first) = edges.first() else { return };
            self.at.push(first);
            self.value.extend(std::iter::repeat_n(0.0, self.stages));
        }
        let n = self.stages;
        let mut z = vec![0.0; n];
        let mut values = vec![[0.0; POINTS]; n];
        for &e in &edges[self.at.len()..] {
            let last = *self.at.last().expect("a checkpoint");
            let from = self.value.len() - n;
            if self.rate * (e - last) <= SMOOTH {
                for (j, p) in panel_points(last, e).into_iter().enumerate() {
                    z.copy_from_slice(&self.value[from..]);
                    decay(self.rate, p - last, &mut z);
                    integral(self.rate, g, last, p, &mut z);
                    for (v, x) in values.iter_mut().zip(&z) {
                        v[j] = *x;
                    }
                }
                self.smooth.push(Some(self.chebyshev.len()));
                for v in &values {
                    self.chebyshev.extend(chebyshev_coefficients(v));
                }
            } else {
                self.smooth.push(None);
            }
            z.copy_from_slice(&self.value[from..]);
            decay(self.rate, e - last, &mut z);
            integral(self.rate, g, last, e, &mut z);
            self.at.push(e);
            self.value.extend_from_slice(&z);
        }
    }

    /// `z_1(t), …, z_stages(t)` of `g` as taken in, into `out` (0 before
    /// `g`'s start).
    pub fn at(&self, g: &Interpolant, t: f64, out: &mut [f64]) {
        let out = &mut out[..self.stages];
        let Some(&first) = self.at.first() else {
            out.fill(0.0);
            return;
        };
        if t <= first {
            out.fill(0.0);
            return;
        }
        let k = self.at.partition_point(|&x| x <= t) - 1;
        if let Some(Some(from)) = self.smooth.get(k) {
            let (a, b) = (self.at[k], self.at[k + 1]);
            for (j, o) in out.iter_mut().enumerate() {
                let c = &self.chebyshev[from + j * POINTS..from + (j + 1) * POINTS];
                *o = chebyshev_sum(c, a, b, t);
            }
            return;
        }
        out.copy_from_slice(&self.value[k * self.stages..(k + 1) * self.stages]);
        decay(self.rate, t - self.at[k], out);
        if k + 1 < self.at.len() {
            integral(self.rate, g, self.at[k], t, out);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::solve::interpolant::build1 as density;

    /// `z_1` of the stages at `t`.
    fn first(z: &ErlangConvolution, t: f64) -> f64 {
        let mut out = [0.0; MAX_STAGES];
        z.at(t, &mut out);
        out[0]
    }

    /// `Γ(j)`-free Erlang density by hand: `λ(λu)^{j−1}e^{−λu}/(j−1)!`.
    fn erlang(l: f64, j: u32, u: f64) -> f64 {
        let fact: f64 = (1..j).map(f64::from).product();
        l * (l * u).powi(j as i32 - 1) * (-l * u).exp() / fact
    }

    #[test]
    fn atoms_give_shifted_erlang_densities() {
        // a E_j(t − τ) after each atom τ
        let (l, atoms) = (3.0, [(0.5, 0.25), (0.0, 0.5), (2.0, 0.125)]);
        let z = ErlangConvolution::new(l, 4, &atoms, None);
        let mut out = [0.0; MAX_STAGES];
        for t in [0.0, 0.3, 0.5, 1.0, 2.0, 2.5, 10.0] {
            z.at(t, &mut out);
            for j in 1..=4 {
                let exact: f64 = atoms
                    .iter()
                    .filter(|a| a.0 <= t)
                    .map(|&(tau, a)| a * erlang(l, j, t - tau))
                    .sum();
                let got = out[j as usize - 1];
                assert!(
                    (got - exact).abs() < 1e-15,
                    "t = {t}, j = {j}: {got} vs {exact}"
                );
            }
        }
        assert_eq!(first(&z, -1.0), 0.0);
    }

    #[test]
    fn exponential_densities_give_hypoexponential_and_erlang() {
        // λe^{−λt} ⊛ κe^{−κt} = λκ (e^{−κt} − e^{−λt}) / (λ − κ)
        let (l, k, end) = (10.0, 0.05, 100.0);
        let g = density(end, |t| k * (-k * t).exp());
        let z = ErlangConvolution::new(l, 1, &[], Some(&g));
        for t in [1e-6, 0.01, 0.7, 3.0, 33.3, 99.9] {
            let exact = l * k * ((-k * t).exp() - (-l * t).exp()) / (l - k);
            assert!(
                (first(&z, t) - exact).abs() < 1e-13 * exact.max(1e-3),
                "t = {t}"
            );
        }
        // equal rates: E_j ⊛ E_1 = E_{j+1}
        let g = density(end, |t| 2.0 * (-2.0 * t).exp());
        let z = ErlangConvolution::new(2.0, MAX_STAGES - 1, &[], Some(&g));
        let mut out = [0.0; MAX_STAGES];
        for t in [0.1f64, 1.0, 5.0, 12.5, 40.0] {
            z.at(t, &mut out);
            for j in 1..MAX_STAGES as u32 {
                let exact = erlang(2.0, j + 1, t);
                let got = out[j as usize - 1];
                assert!(
                    (got - exact).abs() < 1e-14,
                    "t = {t}, j = {j}: {got} vs {exact}"
                );
            }
        }
    }

    /// `E_2(λ) ⊛ κe^{−κ·}`: by partial fractions,
    /// `λ²κ [e^{−κt} − e^{−λt} − (λ − κ)te^{−λt}] / (λ − κ)²`.
    #[test]
    fn an_erlang_two_against_another_rate() {
        let (l, k, end) = (1.5, 0.4, 60.0);
        let g = density(end, |t| k * (-k * t).exp());
        let z = ErlangConvolution::new(l, 2, &[(0.0, 0.0)], Some(&g));
        let mut out = [0.0; MAX_STAGES];
        for t in [0.01f64, 0.5, 2.0, 9.0, 30.0, 59.0] {
            z.at(t, &mut out);
            let d = l - k;
            let exact =
                l * l * k * ((-k * t).exp() - (-l * t).exp() - d * t * (-l * t).exp()) / (d * d);
            assert!(
                (out[1] - exact).abs() < 1e-13,
                "t = {t}: {} vs {exact}",
                out[1]
            );
        }
    }

    /// The marched recursion (as a renewal density's panels come) against
    /// the closed form of `λe^{−λ·} ⊛ κe^{−κ·}` and of `E_2(λ) ⊛ κe^{−κ·}`
    /// on the density's domain, and past its end the values there decaying
    /// (the density cut at its end: `z_1(T)e^{−λ(t − T)}` and
    /// `z_2(T)e^{−λ(t−T)} + z_1(T)λ(t − T)e^{−λ(t − T)}`, by hand).
    #[test]
    fn the_march_is_the_convolution_with_the_density_so_far() {
        let (l, k, end) = (3.0, 0.7, 12.0);
        let g = density(end, |t| k * (-k * t).exp());
        let mut z = ErlangMarch::new(l, 2);
        let mut out = [0.0; MAX_STAGES];
        z.at(&g, 1.0, &mut out);
        assert_eq!(out[..2], [0.0, 0.0], "before any panel");
        z.catch_up(&g);
        z.catch_up(&g);
        let d = l - k;
        let one = |t: f64| l * k * ((-k * t).exp() - (-l * t).exp()) / d;
        let two = |t: f64| {
            l * l * k * ((-k * t).exp() - (-l * t).exp() - d * t * (-l * t).exp()) / (d * d)
        };
        for t in [1e-6, 0.01, 0.7, 3.0, 7.77, 11.99, 12.0] {
            z.at(&g, t, &mut out);
            assert!((out[0] - one(t)).abs() < 1e-13, "t = {t}");
            assert!((out[1] - two(t)).abs() < 1e-13, "t = {t}");
        }
        for t in [12.5, 20.0] {
            let h = t - end;
            let cut1 = one(end) * (-l * h).exp();
            let cut2 = two(end) * (-l * h).exp() + one(end) * l * h * (-l * h).exp();
            z.at(&g, t, &mut out);
            assert!((out[0] - cut1).abs() < 1e-13, "t = {t}");
            assert!((out[1] - cut2).abs() < 1e-13, "t = {t}");
        }
        z.at(&g, -1.0, &mut out);
        assert_eq!(out[0], 0.0);
    }

    /// With panels narrower than `SMOOTH/λ` (a slow rate), `z` is read from
    /// the polynomials kept per panel: against the closed forms of
    /// `E_1 ⊛ κe^{−κ·}` and `E_3(λ) ⊛ κe^{−κ·}` (the latter by partial
    /// fractions: `λ³κ/d³ [e^{−κt} − e^{−λt}(1 + dt + (dt)²/2)]`, `d = λ − κ`).
    #[test]
    fn the_march_reads_kept_polynomials_on_narrow_panels() {
        let (l, k, end) = (0.05, 0.9, 40.0);
        let g = density(end, |t| k * (-k * t).exp());
        assert!(g.edges().windows(2).all(|w| l * (w[1] - w[0]) <= SMOOTH));
        let mut z = ErlangMarch::new(l, 3);
        z.catch_up(&g);
        assert!(z.smooth.iter().all(Option::is_some));
        let d = l - k;
        let one = |t: f64| l * k * ((-k * t).exp() - (-l * t).exp()) / d;
        let three = |t: f64| {
            let dt = d * t;
            l.powi(3) * k / d.powi(3)
                * ((-k * t).exp() - (-l * t).exp() * (1.0 + dt + dt * dt / 2.0))
        };
        let mut out = [0.0; MAX_STAGES];
        for t in [1e-5, 0.013, 0.5, 1.7, 6.0, 19.3, 33.0, 39.99] {
            z.at(&g, t, &mut out);
            assert!(
                (out[0] - one(t)).abs() < 1e-14,
                "t = {t}: {} vs {}",
                out[0],
                one(t)
            );
            assert!(
                (out[2] - three(t)).abs() < 1e-14,
                "t = {t}: {} vs {}",
                out[2],
                three(t)
            );
        }
    }
}
