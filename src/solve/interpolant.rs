//! Piecewise Chebyshev interpolants of functions on `[0, T]`: built
//! adaptively from batched samples, integrated exactly, and convolved with
//! Gauss–Legendre rules that are exact for products of the panels'
//! polynomials.
//!
//! This is the representation of outcome densities that have no phase chain
//! (`crate::compile`'s outcome laws). On each panel the function is sampled at the
//! [`POINTS`] Chebyshev points of the second kind and represented by the
//! interpolating polynomial (its Chebyshev coefficients, evaluated by Clenshaw's recurrence). A panel is accepted when
//! the last two Chebyshev coefficients, times the panel's width, are below
//! [`MASS_TOLERANCE`]: for an analytic function the coefficients decay
//! geometrically, so the tail is an *estimate* of the interpolation error
//! (the usual Chebfun criterion, not a bound), and width × error bounds the
//! error of the probability mass carried by the panel. Otherwise the panel
//! is halved. For the densities of phase-type laws and their compositions,
//! which are entire, a few dozen panels reach that tolerance; tests check
//! integrals and convolutions against closed forms.
//!
//! Given the polynomial pieces, integrals are exact (Clenshaw–Curtis
//! weights on whole panels, Gauss–Legendre with enough points on partial
//! ones), and so is the convolution `∫_0^t f(v) g(t − v) dv` up to
//! rounding: `[0, t]` is cut at the panel edges of `f` and at `t` minus
//! those of `g`, and on each piece both factors are polynomials of degree
//! `POINTS − 1`, integrated exactly by the `POINTS`-point Gauss rule.
//!
//! Size: one concern, the piecewise-polynomial interpolant (build by
//! adaptive panels, evaluate, convolve exactly); about 170 lines are
//! comments, 160 tests.

use std::sync::OnceLock;

use rayon::prelude::*;

use super::quadrature::GaussLegendre;

/// Chebyshev points per panel (polynomial degree `POINTS − 1`).
pub const POINTS: usize = 17;

/// Accepted estimate of a panel's error in probability mass.
pub const MASS_TOLERANCE: f64 = 1e-15;

/// Most rounds of halving before giving up.
const MAX_ROUNDS: usize = 64;

/// Shared constants of the panel basis.
struct Basis {
    /// Chebyshev points of the second kind on `[-1, 1]`, decreasing.
    nodes: [f64; POINTS],
    /// Row k: the map from values to the k-th Chebyshev coefficient.
    coefficients: Vec<[f64; POINTS]>,
    /// Clenshaw–Curtis weights on `[-1, 1]` (exact for the interpolant).
    integral: [f64; POINTS],
    /// Gauss–Legendre rule with `POINTS` points.
    gauss: GaussLegendre,
}

fn basis() -> &'static Basis {
    static BASIS: OnceLock<Basis> = OnceLock::new();
    BASIS.get_or_init(|| {
        let n = POINTS - 1;
        let pi = std::f64::consts::PI;
        let nodes: [f64; POINTS] = std::array::from_fn(|j| (pi * j as f64 / n as f64).cos());
        // c_k = (2/n) Σ_j'' f_j cos(π j k / n), halved for k = 0 and k = n
        let coefficients: Vec<[f64; POINTS]> = (0..POINTS)
            .map(|k| {
                std::array::from_fn(|j| {
                    let mut w = 2.0 / n as f64 * (pi * (j * k) as f64 / n as f64).cos();
                    if j == 0 || j == n {
                        w /= 2.0;
                    }
                    if k == 0 || k == n {
                        w /= 2.0;
                    }
                    w
                })
            })
            .collect();
        // ∫ T_k = 2 / (1 − k²) for even k, 0 for odd k
        let integral: [f64; POINTS] = std::array::from_fn(|j| {
            (0..POINTS)
                .step_by(2)
                .map(|k| coefficients[k][j] * 2.0 / (1.0 - (k * k) as f64))
                .sum()
        });
        Basis {
            nodes,
            coefficients,
            integral,
            gauss: GaussLegendre::new(POINTS),
        }
    })
}

/// The Chebyshev points of panel `[a, b]`.
pub fn panel_points(a: f64, b: f64) -> [f64; POINTS] {
    let (c, h) = ((a + b) / 2.0, (b - a) / 2.0);
    let nodes = &basis().nodes;
    std::array::from_fn(|j| {
        if j == 0 {
            b
        } else if j == POINTS - 1 {
            a
        } else {
            c + h * nodes[j]
        }
    })
}

/// The supports of the two functions of a convolution
/// ([`Interpolant::support`]).
pub(crate) type Supports = (Option<(f64, f64)>, Option<(f64, f64)>);

/// The two functions' values at their panels' own Gauss nodes
/// ([`Interpolant::gauss_values`]), where computed.
type GaussCache<'a> = (Option<&'a [[f64; POINTS]]>, Option<&'a [[f64; POINTS]]>);

/// A function on `[edges[0], edges[last]]`, one polynomial per panel.
#[derive(Debug, Clone, PartialEq)]
pub struct Interpolant {
    /// Panel end points, increasing.
    edges: Vec<f64>,
    /// Values at each panel's [`panel_points`], `POINTS` per panel.
    values: Vec<f64>,
    /// `∫` from `edges[0]` to `edges[k]`.
    prefix: Vec<f64>,
    /// Largest absolute value on each panel's points.
    scale: Vec<f64>,
    /// Chebyshev coefficients of each panel's polynomial, `POINTS` per
    /// panel (evaluated by Clenshaw's recurrence: no divisions).
    chebyshev: Vec<f64>,
}

/// Why an interpolant could not be built.
#[derive(Debug, Clone, PartialEq)]
pub enum BuildError<E> {
    /// The sampler failed.
    Sample(E),
    /// Some panel did not converge after 64 rounds of halving, or a
    /// sample was not finite.
    NotConverged,
}

impl Interpolant {
    /// The zero function on `[0, end]`.
    pub fn zero(end: f64) -> Interpolant {
        Interpolant {
            edges: vec![0.0, end],
            values: vec![0.0; POINTS],
            prefix: vec![0.0, 0.0],
            scale: vec![0.0],
            chebyshev: vec![0.0; POINTS],
        }
    }

    fn from_panels(mut panels: Vec<(f64, f64, [f64; POINTS])>) -> Interpolant {
        panels.sort_by(|x, y| x.0.total_cmp(&y.0));
        let b = basis();
        let mut edges = Vec::with_capacity(panels.len() + 1);
        let mut values = Vec::with_capacity(panels.len() * POINTS);
        let mut prefix = vec![0.0];
        let mut scale = Vec::with_capacity(panels.len());
        let mut acc = 0.0;
        for (a, bb, v) in &panels {
            edges.push(*a);
            values.extend_from_slice(v);
            acc += (bb - a) / 2.0 * v.iter().zip(&b.integral).map(|(x, w)| x * w).sum::<f64>();
            prefix.push(acc);
            scale.push(v.iter().fold(0.0f64, |m, x| m.max(x.abs())));
        }
        edges.push(panels.last().map_or(0.0, |p| p.1));
        let chebyshev = values
            .chunks(POINTS)
            .flat_map(|v| {
                b.coefficients
                    .iter()
                    .map(move |row| row.iter().zip(v).map(|(w, x)| w * x).sum::<f64>())
            })
            .collect();
        Interpolant {
            edges,
            values,
            prefix,
            scale,
            chebyshev,
        }
    }

    /// No panels yet, on `[start, start]`: the start of a build panel by
    /// panel ([`build_marching`], [`Self::push_panel`]).
    pub(crate) fn empty(start: f64) -> Interpolant {
        Interpolant {
            edges: vec![start],
            values: Vec::new(),
            prefix: vec![0.0],
            scale: Vec::new(),
            chebyshev: Vec::new(),
        }
    }

    /// Appends panel `[a, b]` (`a` the current end) with values `v` at
    /// its [`panel_points`]: as [`Self::from_panels`] builds each panel.
    pub(crate) fn push_panel(&mut self, a: f64, b: f64, v: &[f64; POINTS]) {
        debug_assert_eq!(a, self.end());
        let basis = basis();
        let acc = self.total()
            + (b - a) / 2.0
                * v.iter()
                    .zip(&basis.integral)
                    .map(|(x, w)| x * w)
                    .sum::<f64>();
        self.edges.push(b);
        self.values.extend_from_slice(v);
        self.prefix.push(acc);
        self.scale
            .push(v.iter().fold(0.0f64, |m, x| m.max(x.abs())));
        self.chebyshev.extend(
            basis
                .coefficients
                .iter()
                .map(|row| row.iter().zip(v).map(|(w, x)| w * x).sum::<f64>()),
        );
    }

    /// `∫ self(v) g(t − v) dv` over `self`'s domain (0 where `self` has no
    /// panels): one point of [`Self::convolution`], for a function being
    /// built panel by panel; `own` and `theirs` are both functions'
    /// [`Self::panel_gauss`] values (all panels).
    pub(crate) fn convolve_point(
        &self,
        g: &Interpolant,
        (own_support, g_support): Supports,
        (own, theirs): (&[[f64; POINTS]], &[[f64; POINTS]]),
        t: f64,
    ) -> f64 {
        if self.panels() == 0 {
            return 0.0;
        }
        self.convolve_within(g, t, (own_support, g_support), (Some(own), Some(theirs)))
    }

    /// Panel `k`'s values at its own Gauss–Legendre nodes (what a
    /// convolution reads for a whole panel).
    pub(crate) fn panel_gauss(&self, k: usize) -> [f64; POINTS] {
        self.eval_block_in(k, &gauss_nodes(self.edges[k], self.edges[k + 1]))
    }

    /// The interpolants of consecutive intervals (each one's domain
    /// starting where the previous one's ends) as one.
    pub fn join(parts: &[Interpolant]) -> Interpolant {
        let panels = parts
            .iter()
            .flat_map(|p| {
                (0..p.panels()).map(move |k| {
                    let v: [f64; POINTS] = std::array::from_fn(|j| p.values[k * POINTS + j]);
                    (p.edges[k], p.edges[k + 1], v)
                })
            })
            .collect();
        Interpolant::from_panels(panels)
    }

    /// Panel end points.
    pub fn edges(&self) -> &[f64] {
        &self.edges
    }

    /// Number of panels.
    pub fn panels(&self) -> usize {
        self.edges.len() - 1
    }

    /// Right end of the domain.
    pub fn end(&self) -> f64 {
        self.edges[self.edges.len() - 1]
    }

    /// Integral over the whole domain.
    pub fn total(&self) -> f64 {
        self.prefix[self.prefix.len() - 1]
    }

    /// The panel holding `t` (clamped to the domain).
    pub(crate) fn panel_of(&self, t: f64) -> usize {
        let k = self.edges.partition_point(|&e| e <= t);
        k.clamp(1, self.panels()) - 1
    }

    /// The interpolant of panel `k` at `t` (Clenshaw's recurrence on its
    /// Chebyshev coefficients).
    fn eval_in(&self, k: usize, t: f64) -> f64 {
        if self.scale[k] == 0.0 {
            return 0.0;
        }
        let (a, b) = (self.edges[k], self.edges[k + 1]);
        chebyshev_sum(&self.chebyshev[k * POINTS..(k + 1) * POINTS], a, b, t)
    }

    /// [`Self::eval_in`] at the [`POINTS`] instants `ts`, all in panel `k`:
    /// the same arithmetic, the recurrences run side by side (independent,
    /// so they pipeline and vectorise instead of waiting on each other).
    pub(crate) fn eval_block_in(&self, k: usize, ts: &[f64; POINTS]) -> [f64; POINTS] {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU has AVX2, checked just above
            return unsafe { self.eval_block_avx2(k, ts) };
        }
        self.eval_block(k, ts)
    }

    /// [`Self::eval_block_in`] with 4-lane vectors: the same operations in
    /// the same order (Rust fuses no multiply-add), so the same values to
    /// the last bit.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    #[inline(never)]
    fn eval_block_avx2(&self, k: usize, ts: &[f64; POINTS]) -> [f64; POINTS] {
        self.eval_block(k, ts)
    }

    #[inline(always)]
    fn eval_block(&self, k: usize, ts: &[f64; POINTS]) -> [f64; POINTS] {
        if self.scale[k] == 0.0 {
            return [0.0; POINTS];
        }
        let (a, b) = (self.edges[k], self.edges[k + 1]);
        let mut x = [0.0; POINTS];
        if b > a {
            for j in 0..POINTS {
                x[j] = ((2.0 * ts[j] - a - b) / (b - a)).clamp(-1.0, 1.0);
            }
        }
        let c = &self.chebyshev[k * POINTS..(k + 1) * POINTS];
        let (mut b1, mut b2) = ([0.0; POINTS], [0.0; POINTS]);
        for &ck in c[1..].iter().rev() {
            for j in 0..POINTS {
                let b0 = ck + 2.0 * x[j] * b1[j] - b2[j];
                b2[j] = b1[j];
                b1[j] = b0;
            }
        }
        let mut out = [0.0; POINTS];
        for j in 0..POINTS {
            out[j] = c[0] + x[j] * b1[j] - b2[j];
        }
        out
    }

    /// Whether panel `k` is identically zero.
    pub(crate) fn panel_is_zero(&self, k: usize) -> bool {
        self.scale[k] == 0.0
    }

    /// The value at `t` (0 outside the domain).
    pub fn eval(&self, t: f64) -> f64 {
        if !(t >= self.edges[0] && t <= self.end()) {
            return 0.0;
        }
        self.eval_in(self.panel_of(t), t)
    }

    /// [`Self::eval`] at many instants: each run of [`POINTS`] that lies
    /// in one panel (a panel's points, shifted) is evaluated as a block.
    pub fn eval_many(&self, ts: &[f64]) -> Vec<f64> {
        let mut out = Vec::with_capacity(ts.len());
        let (start, end) = (self.edges[0], self.end());
        for chunk in ts.chunks(POINTS) {
            let inside = |t: f64| t >= start && t <= end;
            if let Ok(block) = <&[f64; POINTS]>::try_from(chunk) {
                let (lo, hi) = block
                    .iter()
                    .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &t| {
                        (l.min(t), h.max(t))
                    });
                if inside(lo) && inside(hi) {
                    let k = self.panel_of(lo);
                    if self.panel_of(hi) == k {
                        out.extend_from_slice(&self.eval_block_in(k, block));
                        continue;
                    }
                }
            }
            // a run across panels: one block per panel it touches
            let base = out.len();
            out.extend(std::iter::repeat_n(0.0, chunk.len()));
            let mut todo: Vec<(usize, usize)> = chunk
                .iter()
                .enumerate()
                .filter(|&(_, &t)| inside(t))
                .map(|(j, &t)| (self.panel_of(t), j))
                .collect();
            todo.sort_unstable();
            for run in todo.chunk_by(|a, b| a.0 == b.0) {
                let k = run[0].0;
                let mut block = [chunk[run[0].1]; POINTS];
                for (slot, &(_, j)) in block.iter_mut().zip(run) {
                    *slot = chunk[j];
                }
                let v = self.eval_block_in(k, &block);
                for (i, &(_, j)) in run.iter().enumerate() {
                    out[base + j] = v[i];
                }
            }
        }
        out
    }

    /// `|f(t+) − f(t−)|` where a panel starts at `t` (within `1e-13·end`
    /// of an edge), `None` where none does (the function may jump there
    /// without a panel edge: interpolated through).
    pub fn jump_at(&self, t: f64) -> Option<f64> {
        let k = self.edges.partition_point(|&e| e < t);
        let near = |i: usize| {
            self.edges
                .get(i)
                .filter(|&&e| (e - t).abs() <= 1e-13 * self.end().max(1.0))
                .map(|_| i)
        };
        let k = near(k).or_else(|| k.checked_sub(1).and_then(near))?;
        if k == 0 || k >= self.panels() {
            return None;
        }
        let e = self.edges[k];
        Some((self.eval_in(k, e) - self.eval_in(k - 1, e)).abs())
    }

    /// `∫` from the domain's start to `t` (clamped to the domain).
    pub fn integral_to(&self, t: f64) -> f64 {
        if t <= self.edges[0] {
            return 0.0;
        }
        if t >= self.end() {
            return self.total();
        }
        let k = self.panel_of(t);
        let a = self.edges[k];
        let (c, h) = ((a + t) / 2.0, (t - a) / 2.0);
        let g = &basis().gauss;
        let part: f64 = g
            .nodes
            .iter()
            .zip(&g.weights)
            .map(|(x, w)| w * self.eval_in(k, c + h * x))
            .sum();
        self.prefix[k] + h * part
    }

    /// `∫ t·f(t) dt` over the whole domain (exact for the pieces: `t·p(t)`
    /// has degree `POINTS`, within the Gauss rule's `2·POINTS − 1`).
    pub fn first_moment(&self) -> f64 {
        let g = &basis().gauss;
        (0..self.panels())
            .filter(|&k| self.scale[k] != 0.0)
            .map(|k| {
                let (a, b) = (self.edges[k], self.edges[k + 1]);
                let (c, h) = ((a + b) / 2.0, (b - a) / 2.0);
                h * g
                    .nodes
                    .iter()
                    .zip(&g.weights)
                    .map(|(x, w)| {
                        let t = c + h * x;
                        w * t * self.eval_in(k, t)
                    })
                    .sum::<f64>()
            })
            .sum()
    }

    /// `c · self`.
    pub fn scaled(&self, c: f64) -> Interpolant {
        Interpolant {
            edges: self.edges.clone(),
            values: self.values.iter().map(|v| c * v).collect(),
            prefix: self.prefix.iter().map(|v| c * v).collect(),
            scale: self.scale.iter().map(|v| c.abs() * v).collect(),
            chebyshev: self.chebyshev.iter().map(|v| c * v).collect(),
        }
    }

    /// `∫_0^t self(v) g(t − v) dv` (both functions taken as 0 outside their
    /// domains, which start at 0): exact for the polynomial pieces, up to
    /// rounding, but for the panels outside each function's
    /// [`Self::support`]. (The engine convolves through [`Self::convolution`].)
    #[cfg(test)]
    pub(crate) fn convolve_at(&self, g: &Interpolant, t: f64) -> f64 {
        self.convolve_within(g, t, (self.support(), g.support()), (None, None))
    }

    /// Each panel's values at its own Gauss–Legendre nodes: the values a
    /// convolution needs wherever a piece of its integral is the whole
    /// panel (most pieces are a whole panel of one of the two functions),
    /// computed once instead of at every time point.
    pub(crate) fn gauss_values(&self) -> Vec<[f64; POINTS]> {
        (0..self.panels()).map(|k| self.panel_gauss(k)).collect()
    }

    /// `[a, b]`: the span of the panels where the function exceeds
    /// [`TRIM`] times its largest value (`None` when it is 0). Outside it
    /// the function is below that, so leaving it out of a convolution
    /// changes it by less than `TRIM` times the largest value times the
    /// domain's width (relative 1e-30: far below the interpolation's
    /// error) — and a convolution of a long law with a short one (a loop's
    /// cycle) costs the short one's width per point, not the long one's.
    pub fn support(&self) -> Option<(f64, f64)> {
        let max = self.scale.iter().fold(0.0f64, |m, &x| m.max(x));
        if max == 0.0 || !max.is_finite() {
            return (max != 0.0).then(|| (self.edges[0], self.end()));
        }
        let floor = TRIM * max;
        let first = self.scale.iter().position(|&x| x > floor)?;
        let last = self.scale.iter().rposition(|&x| x > floor)?;
        Some((self.edges[first], self.edges[last + 1]))
    }

    /// [`Self::convolve_at`] with both supports given (computed once for
    /// many points), and optionally both functions' [`Self::gauss_values`]:
    /// a piece that is a whole panel of `self` takes its values from them
    /// (the same numbers, the same nodes); a piece that is a whole panel of
    /// `g`, whose nodes `t − v` are that panel's own nodes reversed (the
    /// rule is symmetric), takes g's (nodes equal up to the rounding of
    /// `t − v`).
    #[inline(always)]
    fn convolve_within(
        &self,
        g: &Interpolant,
        t: f64,
        (sf, sg): Supports,
        (cf, cg): GaussCache<'_>,
    ) -> f64 {
        let (Some(sf), Some(sg)) = (sf, sg) else {
            return 0.0;
        };
        if t <= 0.0 {
            return 0.0;
        }
        // v in self's support, t − v in g's
        let lo = sf.0.max(t - sg.1).max(0.0);
        let hi = sf.1.min(t - sg.0).min(t).min(self.end());
        if hi <= lo {
            return 0.0;
        }
        // The pieces between the cuts — own edges and t − g's edges inside
        // (lo, hi) — merged in increasing order (own edges ascend, t − g's
        // edges ascend as g's descend), tracking the panel of each function
        // under the current piece instead of searching for it.
        let (first_own, end_own) = (
            self.edges.partition_point(|&e| e <= lo),
            self.edges.partition_point(|&e| e < hi),
        );
        let (end_theirs, first_theirs) = (
            g.edges.partition_point(|&e| e <= t - hi),
            g.edges.partition_point(|&e| e < t - lo),
        );
        // panels holding v just above lo and t − v just below t − lo
        let (mut kf, mut kg) = (first_own.max(1) - 1, first_theirs.max(1) - 1);
        let (mut own, mut theirs) = (first_own, first_theirs);
        let mut a = lo;
        let mut total = 0.0;
        loop {
            let next_own = if own < end_own {
                self.edges[own]
            } else {
                f64::INFINITY
            };
            let next_theirs = if theirs > end_theirs {
                t - g.edges[theirs - 1]
            } else {
                f64::INFINITY
            };
            let cut = next_own.min(next_theirs);
            let b = cut.min(hi);
            if b > a {
                total += self.piece(g, t, (a, b), (kf, kg), (cf, cg));
                a = b;
            }
            if cut >= hi {
                break;
            }
            if next_own <= next_theirs {
                kf = own;
                own += 1;
            } else {
                kg = theirs - 2;
                theirs -= 1;
            }
        }
        total
    }

    /// `∫_a^b self(v) g(t − v) dv` with `v` in panel `kf` of `self` and
    /// `t − v` in panel `kg` of `g` (one Gauss–Legendre rule: exact for the
    /// product of the two polynomials); see [`Self::convolve_within`] for
    /// the cached values.
    #[inline(always)]
    fn piece(
        &self,
        g: &Interpolant,
        t: f64,
        (a, b): (f64, f64),
        (kf, kg): (usize, usize),
        (cf, cg): GaussCache<'_>,
    ) -> f64 {
        let mid = (a + b) / 2.0;
        if mid > self.end() || t - mid > g.end() || self.scale[kf] == 0.0 || g.scale[kg] == 0.0 {
            return 0.0;
        }
        let v = gauss_nodes(a, b);
        let fv = match cf {
            Some(cf) if a == self.edges[kf] && b == self.edges[kf + 1] => cf[kf],
            _ => self.eval_block_in(kf, &v),
        };
        // explicit loops (not `array::from_fn`, iterator sums): inlined
        // into the AVX2 build of the convolution ([`Convolution::at`])
        let gv = match cg {
            Some(cg) if a == t - g.edges[kg + 1] && b == t - g.edges[kg] => {
                let mut gv = [0.0; POINTS];
                for j in 0..POINTS {
                    gv[j] = cg[kg][POINTS - 1 - j];
                }
                gv
            }
            _ => {
                let mut u = [0.0; POINTS];
                for j in 0..POINTS {
                    u[j] = t - v[j];
                }
                g.eval_block_in(kg, &u)
            }
        };
        let rule = &basis().gauss;
        // summed in order from -0.0, as `Iterator::sum`
        let mut part = -0.0;
        for j in 0..POINTS {
            part += rule.weights[j] * fv[j] * gv[j];
        }
        (b - a) / 2.0 * part
    }

    /// [`Self::convolve_at`] at many times (see [`Convolution::many`]).
    #[cfg(test)]
    pub(crate) fn convolve_many(&self, g: &Interpolant, times: &[f64]) -> Vec<f64> {
        self.convolution(g).many(times)
    }

    /// `self * g` prepared for evaluation at many points, batch after batch
    /// (an adaptive build samples it panel by panel).
    pub fn convolution<'a>(&'a self, g: &'a Interpolant) -> Convolution<'a> {
        Convolution {
            f: self,
            g,
            supports: (self.support(), g.support()),
            cached: (self.gauss_values(), g.gauss_values()),
        }
    }
}

/// A convolution `f * g` with what every point of it needs computed once:
/// both supports and both functions' values at their panels' own Gauss
/// nodes.
pub struct Convolution<'a> {
    f: &'a Interpolant,
    g: &'a Interpolant,
    supports: Supports,
    cached: (Vec<[f64; POINTS]>, Vec<[f64; POINTS]>),
}

impl Convolution<'_> {
    /// `(f * g)(t)` at each of `times`, in parallel: a point costs a piece
    /// per panel edge in its window, often milliseconds, so even a batch of
    /// one panel's 17 points is split (each value is independent of the
    /// split).
    pub fn many(&self, times: &[f64]) -> Vec<f64> {
        let cached = (Some(&self.cached.0[..]), Some(&self.cached.1[..]));
        times
            .par_iter()
            .with_min_len(4)
            .map(|&t| self.at(t, cached))
            .collect()
    }

    /// `(f * g)(t)`; on x86-64 with AVX2, compiled for it.
    fn at(&self, t: f64, cached: GaussCache<'_>) -> f64 {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU has AVX2, checked just above
            return unsafe { self.at_avx2(t, cached) };
        }
        self.f.convolve_within(self.g, t, self.supports, cached)
    }

    /// [`Self::at`] with 4-lane vectors (see [`Interpolant::eval_block_in`]).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn at_avx2(&self, t: f64, cached: GaussCache<'_>) -> f64 {
        self.f.convolve_within(self.g, t, self.supports, cached)
    }
}

/// The Gauss–Legendre nodes of `[a, b]` (the rule of [`Basis::gauss`]).
#[inline(always)]
fn gauss_nodes(a: f64, b: f64) -> [f64; POINTS] {
    let (c, h) = ((a + b) / 2.0, (b - a) / 2.0);
    let nodes = &basis().gauss.nodes;
    let mut out = [0.0; POINTS];
    for j in 0..POINTS {
        out[j] = c + h * nodes[j];
    }
    out
}

/// Values below this fraction of a function's largest value at either end
/// of its domain are left out of its convolutions ([`Interpolant::support`]).
pub const TRIM: f64 = 1e-30;

/// Builds `k` interpolants on shared panels of `[0, end]`. `sample` gets a
/// batch of points and returns `k` values per point (row-major). Panels
/// start from a grid graded towards 0 and are halved until every
/// component's Chebyshev tail, times the panel's width, is below
/// [`MASS_TOLERANCE`] (or its rounding floor). (The engine builds through
/// [`build_with_breaks`] and [`build_on`].)
#[cfg(test)]
pub(crate) fn build<E>(
    end: f64,
    k: usize,
    sample: impl FnMut(&[f64]) -> Result<Vec<f64>, E>,
) -> Result<Vec<Interpolant>, BuildError<E>> {
    build_with_breaks(end, &[], 0.0, k, sample)
}

/// Relative grid of the first panels of `[0, end]`, graded towards 0
/// (where fast phases decay).
const GRID: [f64; 16] = [
    0.0, 1e-8, 1e-7, 1e-6, 1e-5, 1e-4, 1e-3, 1e-2, 0.03, 0.1, 0.2, 0.35, 0.5, 0.65, 0.8, 1.0,
];

/// Relative grid of the first panels between two breaks, graded towards
/// the break that starts them (a density that jumps there may start a fast
/// phase).
const SEGMENT_GRID: [f64; 6] = [0.0, 1e-4, 1e-2, 0.1, 0.5, 1.0];

/// Relative distance from a break at which a panel's end point is sampled:
/// a function that jumps there is sampled on the panel's side, whatever
/// the rounding of the instant (a sum of fixed times) that it jumps at —
/// beyond the tie tolerance ([`crate::tree::SAME_INSTANT`]), or a
/// race's density sampled within it of its instant reads the value after
/// the instant (a loop's march then halved its panel towards the break 37
/// times: 1,180 panels on `[0, 8]` instead of 40).
const BREAK_NUDGE: f64 = 4.0 * crate::tree::SAME_INSTANT;

/// [`build`] for functions that may jump or kink at `breaks` (instants in
/// `(0, end)`, any order; others are ignored): panels start at every break,
/// so that each panel's function is smooth (its values at a break are
/// sampled `BREAK_NUDGE` inside the panel: one-sided limits).
/// `[0, first break]` starts from
/// [`build`]'s grid graded towards 0, every later segment from a coarser
/// grid graded towards its break — or as one panel where it is at most
/// `narrow` wide (see [`first_panels`]); panels are then halved as in
/// [`build`].
pub(crate) fn build_with_breaks<E>(
    end: f64,
    breaks: &[f64],
    narrow: f64,
    k: usize,
    sample: impl FnMut(&[f64]) -> Result<Vec<f64>, E>,
) -> Result<Vec<Interpolant>, BuildError<E>> {
    if end <= 0.0 {
        return Ok(vec![Interpolant::zero(end.max(0.0)); k]);
    }
    let (cuts, pending) = first_panels(end, breaks, narrow);
    refine(pending, &cuts, end, k, sample)
}

/// The cuts of `[0, end]` at `breaks` (sorted, `end` last) and the first
/// panels: `[0, first cut]` on [`GRID`] (graded towards 0), every later
/// segment on [`SEGMENT_GRID`] (graded towards its break), or as one panel
/// where it is at most `narrow` wide. The grading resolves a fast phase
/// that starts at the break; a caller that knows the fastest rate `λ` of
/// the functions' phases passes `narrow = 1/λ`, on which nothing decays by
/// more than `e` (a lattice of fixed times cuts `[0, end]` into hundreds
/// of such segments: graded, each was five panels, and a convolution's
/// cost is quadratic in the panels — random survey tree 2912's curve
/// 7.5 s, 0.45 s as one panel each). Halving still refines any panel.
fn first_panels(end: f64, breaks: &[f64], narrow: f64) -> (Vec<f64>, Vec<(f64, f64)>) {
    let mut cuts: Vec<f64> = breaks
        .iter()
        .copied()
        .filter(|&b| b > 1e-13 * end && b < end * (1.0 - 1e-13))
        .collect();
    cuts.sort_by(f64::total_cmp);
    cuts.dedup_by(|b, a| *b - *a <= 1e-13 * end);
    cuts.push(end);
    let mut pending: Vec<(f64, f64)> =
        Vec::with_capacity(GRID.len() + SEGMENT_GRID.len() * cuts.len());
    let mut from = 0.0;
    for (i, &to) in cuts.iter().enumerate() {
        let width = to - from;
        let grid: &[f64] = if i == 0 {
            &GRID
        } else if width <= narrow {
            &[0.0, 1.0]
        } else {
            &SEGMENT_GRID
        };
        pending.extend(grid.windows(2).map(|g| {
            let b = if g[1] == 1.0 { to } else { from + g[1] * width };
            (from + g[0] * width, b)
        }));
        from = to;
    }
    (cuts, pending)
}

/// The [`panel_points`] of `[a, b]`, an end at one of the `cuts` (sorted)
/// moved [`BREAK_NUDGE`] inside: the one-sided limit there.
fn sample_points(a: f64, b: f64, cuts: &[f64], end: f64) -> [f64; POINTS] {
    let mut p = panel_points(a, b);
    let nudge = |x: f64| (BREAK_NUDGE * x.abs().max(1.0)).min((b - a) / 1024.0);
    if cuts.binary_search_by(|c| c.total_cmp(&b)).is_ok() && b < end {
        p[0] = b - nudge(b);
    }
    if cuts.binary_search_by(|c| c.total_cmp(&a)).is_ok() {
        p[POINTS - 1] = a + nudge(a);
    }
    p
}

/// Values sampled at a panel's [`sample_points`] moved to its
/// [`panel_points`]: an end value sampled nudged inside the panel (at a
/// break) is carried back to the end by a Taylor step along the panel's
/// polynomial, whose slope there is read from the values themselves (a few
/// rounds: the step's own error shrinks by `δ·(2N² + 1)/3/(b − a)` ≤ 0.17
/// each, the nudge being at most 1/1024 of the width).
fn at_panel_points(v: &mut [f64; POINTS], a: f64, b: f64, p: &[f64; POINTS]) {
    let n = POINTS - 1;
    let (db, da) = (b - p[0], p[n] - a);
    if db == 0.0 && da == 0.0 {
        return;
    }
    let sampled = *v;
    for _ in 0..4 {
        let (sb, sa) = end_slopes(v, a, b);
        v[0] = sampled[0] + db * sb;
        v[n] = sampled[n] - da * sa;
    }
}

/// The slopes at `b` and at `a` of the panel polynomial with values `v` at
/// its [`panel_points`] (the end rows of the Chebyshev differentiation
/// matrix, Trefethen's *Spectral Methods in MATLAB*, ch. 6).
fn end_slopes(v: &[f64; POINTS], a: f64, b: f64) -> (f64, f64) {
    let n = POINTS - 1;
    let x = &basis().nodes;
    let c = |j: usize| if j == 0 || j == n { 2.0 } else { 1.0 };
    let sign = |j: usize| if j.is_multiple_of(2) { 1.0 } else { -1.0 };
    let corner = (2.0 * (n * n) as f64 + 1.0) / 6.0;
    let mut top = corner * v[0];
    let mut bottom = -corner * v[n];
    for j in 1..=n {
        top += c(0) / c(j) * sign(j) / (x[0] - x[j]) * v[j];
    }
    for j in 0..n {
        bottom += c(n) / c(j) * sign(n + j) / (x[n] - x[j]) * v[j];
    }
    let scale = 2.0 / (b - a);
    (top * scale, bottom * scale)
}

/// Whether panel values `v` of width `width` pass the interpolation's
/// test: the last two Chebyshev coefficients, times the width, below
/// [`MASS_TOLERANCE`] (or at the rounding floor of the values).
fn resolved(v: &[f64; POINTS], width: f64) -> bool {
    let basis = basis();
    let coefficient = |i: usize| {
        basis.coefficients[i]
            .iter()
            .zip(v)
            .map(|(w, x)| w * x)
            .sum::<f64>()
            .abs()
    };
    let tail = coefficient(POINTS - 1) + coefficient(POINTS - 2);
    let scale = v.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    tail * width <= MASS_TOLERANCE || tail <= 64.0 * f64::EPSILON * scale
}

/// [`build`] on `[a, b]` (`a < b`), the first grid graded towards `a`
/// (`graded`: for a fast transient there) or one panel: for functions
/// smooth inside `[a, b]` that may jump at its ends (an outcome density
/// between the instants where it may jump, the pieces joined with
/// [`Interpolant::join`]).
pub(crate) fn build_on<E>(
    a: f64,
    b: f64,
    graded: bool,
    k: usize,
    sample: impl FnMut(&[f64]) -> Result<Vec<f64>, E>,
) -> Result<Vec<Interpolant>, BuildError<E>> {
    let grid: &[f64] = if graded { &GRID } else { &[0.0, 1.0] };
    let (span, end) = (b - a, b.abs().max(b - a));
    let at = |g: f64| if g == 1.0 { b } else { a + g * span };
    let pending: Vec<(f64, f64)> = grid.windows(2).map(|g| (at(g[0]), at(g[1]))).collect();
    refine(pending, &[], end, k, sample)
}

/// Halves the `pending` panels until every component's Chebyshev tail,
/// times the panel's width, is below [`MASS_TOLERANCE`] (or its rounding
/// floor, relative to `end`); at the `cuts` (sorted) the panels' end values
/// are one-sided limits.
fn refine<E>(
    mut pending: Vec<(f64, f64)>,
    cuts: &[f64],
    end: f64,
    k: usize,
    mut sample: impl FnMut(&[f64]) -> Result<Vec<f64>, E>,
) -> Result<Vec<Interpolant>, BuildError<E>> {
    let mut done: Vec<Vec<(f64, f64, [f64; POINTS])>> = vec![Vec::new(); k];
    for _ in 0..MAX_ROUNDS {
        if pending.is_empty() {
            return Ok(done.into_iter().map(Interpolant::from_panels).collect());
        }
        // at a break, the one-sided limit from inside the panel
        let points: Vec<f64> = pending
            .iter()
            .flat_map(|&(a, b)| sample_points(a, b, cuts, end))
            .collect();
        let values = sample(&points).map_err(BuildError::Sample)?;
        if values.len() != points.len() * k || values.iter().any(|v| !v.is_finite()) {
            return Err(BuildError::NotConverged);
        }
        let mut next = Vec::new();
        for (p, &(a, b)) in pending.iter().enumerate() {
            let width = b - a;
            let at = &points[p * POINTS..(p + 1) * POINTS];
            let at: &[f64; POINTS] = at.try_into().expect("one panel's points");
            let panel: Vec<[f64; POINTS]> = (0..k)
                .map(|c| {
                    let mut v = std::array::from_fn(|j| values[(p * POINTS + j) * k + c]);
                    at_panel_points(&mut v, a, b, at);
                    v
                })
                .collect();
            let converged = panel.iter().all(|v| resolved(v, width));
            // panels narrower than rounding can resolve are taken as they are
            if converged || width <= 1e-13 * end {
                for (c, v) in panel.into_iter().enumerate() {
                    done[c].push((a, b, v));
                }
            } else {
                let m = (a + b) / 2.0;
                next.push((a, m));
                next.push((m, b));
            }
        }
        pending = next;
    }
    Err(BuildError::NotConverged)
}

/// `T_c(ξ(y))`, `c < POINTS`, with `ξ` mapping `[a, b]` onto `[−1, 1]`
/// (clamped): a panel polynomial is `Σ_c coef_c T_c(ξ)`.
fn chebyshev_row(a: f64, b: f64, y: f64) -> [f64; POINTS] {
    let x = if b > a {
        ((2.0 * y - a - b) / (b - a)).clamp(-1.0, 1.0)
    } else {
        0.0
    };
    let mut t = [0.0; POINTS];
    t[0] = 1.0;
    t[1] = x;
    for c in 2..POINTS {
        t[c] = 2.0 * x * t[c - 1] - t[c - 2];
    }
    t
}

/// The Chebyshev coefficients of the polynomial of a panel whose values at
/// its [`panel_points`] are `v` (for [`chebyshev_sum`]).
pub(crate) fn chebyshev_coefficients(v: &[f64; POINTS]) -> [f64; POINTS] {
    let c = &basis().coefficients;
    std::array::from_fn(|k| (0..POINTS).map(|j| c[k][j] * v[j]).sum())
}

/// `Σ c_k T_k(x)` at `t` of panel `[a, b]` (`x` its place in `[−1, 1]`),
/// by Clenshaw's recurrence.
pub(crate) fn chebyshev_sum(c: &[f64], a: f64, b: f64, t: f64) -> f64 {
    let x = if b > a {
        ((2.0 * t - a - b) / (b - a)).clamp(-1.0, 1.0)
    } else {
        0.0
    };
    let (mut b1, mut b2) = (0.0, 0.0);
    for &ck in c[1..].iter().rev() {
        let b0 = ck + 2.0 * x * b1 - b2;
        b2 = b1;
        b1 = b0;
    }
    c[0] + x * b1 - b2
}

/// `ℓ_j(y)`: the weights with which the polynomial of panel `[a, b]`
/// whose values at its [`panel_points`] are `v` takes the value `Σ_j ℓ_j(y)
/// v_j` at `y` (the same polynomial as [`Interpolant::single`]'s).
pub(crate) fn panel_weights(a: f64, b: f64, y: f64) -> [f64; POINTS] {
    let t = chebyshev_row(a, b, y);
    let c = &basis().coefficients;
    std::array::from_fn(|j| (0..POINTS).map(|k| t[k] * c[k][j]).sum())
}

/// `M` with `∫_a^{x_k} p(s) g(x_k − s) ds = Σ_j M[k][j] v_j` for the
/// polynomial `p` of panel `[a, b]` with values `v` at its
/// [`panel_points`], at each of `points` (in the panel): the convolution
/// of the panel with `g` as a matrix, for a value on the panel that
/// depends on the panel itself (a renewal equation). Each piece between
/// `x_k − g`'s edges takes one Gauss–Legendre rule, as a convolution's.
pub(crate) fn panel_convolution(
    g: &Interpolant,
    g_support: Option<(f64, f64)>,
    a: f64,
    b: f64,
    points: &[f64; POINTS],
) -> [[f64; POINTS]; POINTS] {
    let basis = basis();
    let mut out = [[0.0; POINTS]; POINTS];
    let Some((g_lo, g_hi)) = g_support else {
        return out;
    };
    let rule = &basis.gauss;
    for (k, &x) in points.iter().enumerate() {
        // s in [a, x] with x − s in g's support
        let lo = a.max(x - g_hi);
        let hi = x.min(b).min(x - g_lo);
        if hi <= lo {
            continue;
        }
        // cuts at x − g's edges inside (lo, hi)
        let mut cuts: Vec<f64> = g
            .edges
            .iter()
            .map(|&e| x - e)
            .filter(|&c| c > lo && c < hi)
            .collect();
        cuts.push(lo);
        cuts.push(hi);
        cuts.sort_by(f64::total_cmp);
        let mut cheb = [0.0; POINTS];
        for w in cuts.windows(2) {
            let (alpha, beta) = (w[0], w[1]);
            if beta <= alpha {
                continue;
            }
            let nodes = gauss_nodes(alpha, beta);
            let kg = g.panel_of(x - (alpha + beta) / 2.0);
            let mut u = [0.0; POINTS];
            for q in 0..POINTS {
                u[q] = x - nodes[q];
            }
            let gv = g.eval_block_in(kg, &u);
            let half = (beta - alpha) / 2.0;
            for q in 0..POINTS {
                let row = chebyshev_row(a, b, nodes[q]);
                let wq = half * rule.weights[q] * gv[q];
                for c in 0..POINTS {
                    cheb[c] += wq * row[c];
                }
            }
        }
        for (j, o) in out[k].iter_mut().enumerate() {
            *o = (0..POINTS)
                .map(|c| cheb[c] * basis.coefficients[c][j])
                .sum();
        }
    }
    out
}

/// One function on `[0, end]` built panel by panel from the left, for a
/// function whose values on a panel depend on its values before it (a
/// renewal equation marched in time): `sample(done, a, b, points)` gets the
/// interpolant of the panels accepted so far (on `[0, a]`), the panel and
/// its [`panel_points`] (one-sided at the `breaks`, as
/// [`build_with_breaks`]'s) and returns the values there, or `None` to
/// have the panel halved. Panels start from [`build_with_breaks`]'s grids
/// and are halved until the same Chebyshev tail test passes. Where
/// `settled(done)` says the function is negligible from `done`'s end on, the
/// rest of the domain is one zero panel.
pub(crate) fn build_marching<E>(
    end: f64,
    breaks: &[f64],
    narrow: f64,
    settled: impl Fn(&Interpolant) -> bool,
    mut sample: impl FnMut(&Interpolant, f64, f64, &[f64; POINTS]) -> Result<Option<[f64; POINTS]>, E>,
) -> Result<Interpolant, BuildError<E>> {
    if end <= 0.0 {
        return Ok(Interpolant::zero(end.max(0.0)));
    }
    let (cuts, first) = first_panels(end, breaks, narrow);
    // (a, b, halvings so far), the leftmost last
    let mut pending: Vec<(f64, f64, usize)> = first.into_iter().map(|(a, b)| (a, b, 0)).collect();
    pending.reverse();
    let mut done = Interpolant::empty(0.0);
    while let Some((a, b, depth)) = pending.pop() {
        if done.panels() > 0 && settled(&done) {
            done.push_panel(a, end, &[0.0; POINTS]);
            break;
        }
        let p = sample_points(a, b, &cuts, end);
        let width = b - a;
        let values = sample(&done, a, b, &p)
            .map_err(BuildError::Sample)?
            .map(|mut v| {
                at_panel_points(&mut v, a, b, &p);
                v
            });
        let converged = values.is_some_and(|v| resolved(&v, width));
        match values {
            Some(v) if v.iter().any(|x| !x.is_finite()) => return Err(BuildError::NotConverged),
            // panels narrower than rounding can resolve are taken as they are
            Some(v) if converged || width <= 1e-13 * end => done.push_panel(a, b, &v),
            _ if depth >= MAX_ROUNDS || width <= 1e-13 * end => {
                return Err(BuildError::NotConverged)
            }
            _ => {
                let m = (a + b) / 2.0;
                pending.push((m, b, depth + 1));
                pending.push((a, m, depth + 1));
            }
        }
    }
    Ok(done)
}

/// `f` interpolated on `[0, end]` (tests' shorthand).
#[cfg(test)]
pub(crate) fn build1(end: f64, f: impl Fn(f64) -> f64) -> Interpolant {
    build::<()>(end, 1, |pts| Ok(pts.iter().map(|&t| f(t)).collect()))
        .unwrap()
        .remove(0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_panel_as_a_matrix_is_its_convolution_and_its_values() {
        // the polynomial of panel [a, b] through e^{-t}: its values at any
        // point, and its convolution with g at the panel's points, as
        // weights and a matrix on its values
        let (a, b) = (1.0, 1.8);
        let pts = panel_points(a, b);
        let v: [f64; POINTS] = std::array::from_fn(|j| (-pts[j]).exp());
        let mut panel = Interpolant::empty(a);
        panel.push_panel(a, b, &v);
        for y in [1.0, 1.13, 1.5, 1.8] {
            let w = panel_weights(a, b, y);
            let by_weights: f64 = w.iter().zip(&v).map(|(w, x)| w * x).sum();
            assert!((by_weights - panel.eval(y)).abs() < 1e-14, "{y}");
            assert!((by_weights - (-y).exp()).abs() < 1e-14, "{y}");
        }
        // g(u) = 2e^{-2u} on [0, 5] with a break at 0.3 (two segments)
        let g = build_with_breaks::<()>(5.0, &[0.3], 0.0, 1, |p| {
            Ok(p.iter().map(|&u| 2.0 * (-2.0 * u).exp()).collect())
        })
        .unwrap()
        .remove(0);
        let m = panel_convolution(&g, g.support(), a, b, &pts);
        let gauss = g.gauss_values();
        let own = [panel.panel_gauss(0)];
        for (k, &x) in pts.iter().enumerate() {
            let by_matrix: f64 = m[k].iter().zip(&v).map(|(m, v)| m * v).sum();
            let direct =
                panel.convolve_point(&g, (panel.support(), g.support()), (&own, &gauss), x);
            // ∫_a^x e^{-s} 2e^{-2(x-s)} ds = 2e^{-2x}(e^{x} − e^{a})
            let exact = 2.0 * (-2.0 * x).exp() * (x.exp() - a.exp());
            assert!(
                (by_matrix - direct).abs() < 1e-14,
                "{x}: {by_matrix} vs {direct}"
            );
            assert!(
                (by_matrix - exact).abs() < 1e-13,
                "{x}: {by_matrix} vs {exact}"
            );
        }
    }

    #[test]
    fn a_marching_build_solves_a_renewal_equation() {
        // r(t) = 1 + ∫_0^t r(t − u) du has r = e^t: each panel's values
        // are solved from those before (here by iterating the equation on
        // the panel until it settles)
        let r = build_marching::<()>(
            3.0,
            &[1.5],
            0.0,
            |_| false,
            |done, a, b, p| {
                let mut v = [1.0; POINTS];
                for _ in 0..200 {
                    let mut panel = Interpolant::empty(a);
                    panel.push_panel(a, b, &v);
                    let next: [f64; POINTS] = std::array::from_fn(|k| {
                        // ∫_0^x r = r's integral before a plus the panel's to x
                        let before = if done.panels() > 0 { done.total() } else { 0.0 };
                        1.0 + before + panel.integral_to(p[k])
                    });
                    if next == v {
                        break;
                    }
                    v = next;
                }
                Ok(Some(v))
            },
        )
        .unwrap();
        for t in [0.0, 0.7, 1.5, 2.2, 3.0] {
            assert!(
                (r.eval(t) - t.exp()).abs() < 1e-12 * t.exp(),
                "{t}: {}",
                r.eval(t)
            );
        }
        assert!(r.edges().contains(&1.5), "a panel starts at the break");
    }

    #[test]
    fn interpolates_and_integrates_exponential_densities() {
        // density of Exp(3) on [0, 10]: CDF 1 − e^{−3t}
        let f = build1(10.0, |t| 3.0 * (-3.0 * t).exp());
        for t in [0.0, 1e-6, 0.01, 0.3, 1.0, 2.5, 9.99, 10.0] {
            assert!((f.eval(t) - 3.0 * (-3.0 * t).exp()).abs() < 1e-12, "t={t}");
            let cdf = -(-3.0 * t).exp_m1();
            assert!((f.integral_to(t) - cdf).abs() < 1e-13, "t={t}");
        }
        assert!(f.panels() < 40, "{} panels", f.panels());
    }

    #[test]
    fn first_moment_of_a_gamma_density() {
        // Gamma(2, 1) density t e^{−t} on [0, 60]: ∫ t² e^{−t} = 2 (tail e^{−60}·…)
        let f = build1(60.0, |t| t * (-t).exp());
        assert!(
            (f.first_moment() - 2.0).abs() < 1e-12,
            "{}",
            f.first_moment()
        );
        assert!((f.total() - 1.0).abs() < 1e-13);
    }

    #[test]
    fn stiff_density_is_resolved_near_zero() {
        // a mixture of rates 1e5 and 1e-3 on [0, 1e4]
        let f = build1(1e4, |t| {
            0.5 * 1e5 * (-1e5 * t).exp() + 0.5 * 1e-3 * (-1e-3 * t).exp()
        });
        for t in [1e-6f64, 1e-5, 1e-3, 1.0, 100.0, 1e4] {
            let cdf = 0.5 * -(-1e5 * t).exp_m1() + 0.5 * -(-1e-3 * t).exp_m1();
            assert!((f.integral_to(t) - cdf).abs() < 1e-12, "t={t}");
        }
    }

    #[test]
    fn convolution_of_two_exponentials_is_hypoexponential() {
        // Exp(1) * Exp(2): density 2(e^{−t} − e^{−2t})
        let (a, b) = (1.0, 2.0);
        let f = build1(20.0, |t| a * (-a * t).exp());
        let g = build1(20.0, |t| b * (-b * t).exp());
        for t in [0.0, 0.1, 1.0, 3.0, 7.5, 20.0] {
            let exact = a * b / (b - a) * ((-a * t).exp() - (-b * t).exp());
            assert!((f.convolve_at(&g, t) - exact).abs() < 1e-13, "t={t}");
            assert!((g.convolve_at(&f, t) - exact).abs() < 1e-13, "t={t}");
        }
    }

    /// The convolution at many points (whole panels' values cached, pieces
    /// merged): the closed form of Exp(1) * Erlang-2(5) — a stiff density
    /// on panels of its own, so pieces are whole panels of either function
    /// or of neither — and the single-point evaluation, at points on and
    /// between the panels' edges.
    #[test]
    fn convolution_at_many_points_is_the_closed_form() {
        // f = e^{−t}, g = 25 t e^{−5t}: (f * g)(t) = 25 ∫ v e^{−5v} e^{−(t−v)} dv
        // = 25 e^{−t} [1 − e^{−4t}(1 + 4t)] / 16
        let f = build1(30.0, |t| (-t).exp());
        let g = build1(30.0, |t| 25.0 * t * (-5.0 * t).exp());
        let exact = |t: f64| 25.0 * (-t).exp() * (1.0 - (-4.0 * t).exp() * (1.0 + 4.0 * t)) / 16.0;
        let mut times: Vec<f64> = (0..400).map(|k| k as f64 * 0.075).collect();
        times.extend(
            f.edges()
                .iter()
                .chain(g.edges())
                .copied()
                .filter(|&t| t <= 30.0),
        );
        for (fg, gf) in [(&f, &g), (&g, &f)] {
            let many = fg.convolve_many(gf, &times);
            for (&t, &m) in times.iter().zip(&many) {
                assert!((m - exact(t)).abs() < 1e-13, "t={t}: {m} vs {}", exact(t));
                let one = fg.convolve_at(gf, t);
                assert!(
                    (m - one).abs() <= 1e-14 * one.abs().max(1e-300) + 1e-16,
                    "t={t}"
                );
            }
        }
    }

    /// The AVX2 builds of the evaluation and of the convolution compute the
    /// same values as the generic ones to the last bit (same operations in
    /// the same order), so results never depend on the machine's CPU.
    #[test]
    fn the_vector_builds_agree_bit_for_bit() {
        let f = build1(30.0, |t| (-t).exp() * (1.0 + (3.0 * t).sin() / 4.0));
        let g = build1(30.0, |t| 25.0 * t * (-5.0 * t).exp());
        for k in 0..f.panels() {
            let (a, b) = (f.edges[k], f.edges[k + 1]);
            let ts: [f64; POINTS] =
                std::array::from_fn(|j| a + (b - a) * (j as f64 + 0.37) / POINTS as f64);
            let generic = f.eval_block(k, &ts);
            let dispatched = f.eval_block_in(k, &ts);
            for j in 0..POINTS {
                assert_eq!(generic[j].to_bits(), dispatched[j].to_bits(), "panel {k}");
            }
        }
        let c = f.convolution(&g);
        let cached = (Some(&c.cached.0[..]), Some(&c.cached.1[..]));
        for t in (0..300).map(|k| k as f64 * 0.1 + 0.013) {
            let generic = f.convolve_within(&g, t, c.supports, cached);
            assert_eq!(c.at(t, cached).to_bits(), generic.to_bits(), "t={t}");
        }
    }

    #[test]
    fn panels_start_at_breaks_where_the_function_jumps() {
        // e^{−t} before 0.1 + 0.2, 3 e^{−t} from then on: ∫_0^t in closed form
        let at = 0.1 + 0.2;
        let f = |t: f64| if t < at { (-t).exp() } else { 3.0 * (-t).exp() };
        let g = build_with_breaks::<()>(5.0, &[at], 0.0, 1, |pts| {
            Ok(pts.iter().map(|&t| f(t)).collect())
        })
        .unwrap()
        .remove(0);
        assert!(g.edges().contains(&at));
        for t in [0.1, 0.3, 0.7, 5.0] {
            let exact = if t < at {
                -(-t).exp_m1()
            } else {
                -(-at).exp_m1() + 3.0 * ((-at).exp() - (-t).exp())
            };
            assert!((g.integral_to(t) - exact).abs() < 1e-14, "t={t}");
        }
        // without the break the jump is chased by halving: many more panels
        let h = build::<()>(5.0, 1, |pts| Ok(pts.iter().map(|&t| f(t)).collect()))
            .unwrap()
            .remove(0);
        assert!(
            g.panels() * 2 < h.panels(),
            "{} vs {}",
            g.panels(),
            h.panels()
        );
        // the jump 2e^{−0.3} where a panel starts there; none elsewhere
        let jump = g.jump_at(at).expect("a panel starts at the break");
        assert!((jump - 2.0 * (-at).exp()).abs() < 1e-11, "{jump}");
        assert_eq!(g.jump_at(0.123_456), None);
    }

    #[test]
    fn segments_narrower_than_the_fastest_decay_start_as_one_panel() {
        // a density that jumps on a lattice of fixed times: c_k e^{−λt} on
        // [kd, (k+1)d) with c_k = 1 + (k mod 3), d = 0.125, λ = 1.5 — 320
        // segments on [0, 40], each narrower than 1/λ
        let (d, lambda, end) = (0.125, 1.5, 40.0);
        let c = |k: f64| 1.0 + k.rem_euclid(3.0);
        let f = |t: f64| c((t / d).floor()) * (-lambda * t).exp();
        let breaks: Vec<f64> = (1..320).map(|k| k as f64 * d).collect();
        let build = |narrow: f64| {
            build_with_breaks::<()>(end, &breaks, narrow, 1, |pts| {
                Ok(pts.iter().map(|&t| f(t)).collect())
            })
            .unwrap()
            .remove(0)
        };
        // ∫_0^t in closed form, segment by segment
        let exact = |t: f64| {
            let mut sum = 0.0;
            let mut k = 0.0;
            while k * d < t {
                let (a, b) = (k * d, ((k + 1.0) * d).min(t));
                sum += c(k) * ((-lambda * a).exp() - (-lambda * b).exp()) / lambda;
                k += 1.0;
            }
            sum
        };
        let one = build(1.0 / lambda);
        let graded = build(0.0);
        for g in [&one, &graded] {
            for t in [0.06, 1.0, 7.3, 20.0, 40.0] {
                let err = (g.integral_to(t) - exact(t)).abs();
                assert!(err < 1e-14, "t={t}: {err:e} with {} panels", g.panels());
            }
        }
        // one panel a segment (the first segment graded towards 0) where
        // the graded grid starts five
        assert!(one.panels() <= 319 + 15, "{}", one.panels());
        assert!(graded.panels() >= 5 * 319, "{}", graded.panels());
    }

    #[test]
    fn nudged_end_values_are_carried_back_to_the_ends() {
        // e^{2t} on [0.3, 0.5], both ends sampled 1e-6 inside: off by
        // δ·f' ≈ 5e-6 there, by δ²·f''/2 ≈ 1e-11 after the step
        let (a, b) = (0.3, 0.5);
        let mut p = panel_points(a, b);
        let d = 1e-6;
        p[0] = b - d;
        p[POINTS - 1] = a + d;
        let f = |t: f64| (2.0 * t).exp();
        let mut v: [f64; POINTS] = std::array::from_fn(|j| f(p[j]));
        let (sb, sa) = end_slopes(&std::array::from_fn(|j| f(panel_points(a, b)[j])), a, b);
        assert!((sb - 2.0 * f(b)).abs() < 1e-11 * f(b), "{sb}");
        assert!((sa - 2.0 * f(a)).abs() < 1e-11 * f(a), "{sa}");
        assert!((v[0] - f(b)).abs() > 1e-6 * f(b));
        at_panel_points(&mut v, a, b, &p);
        assert!((v[0] - f(b)).abs() < 1e-11 * f(b), "{} vs {}", v[0], f(b));
        assert!((v[POINTS - 1] - f(a)).abs() < 1e-11 * f(a));
    }

    #[test]
    fn many_values_match_single_ones() {
        // runs of POINTS that fall in one panel, across panels, outside
        let g = build1(4.0, |t| (t * 3.0).sin() * (-t).exp());
        let ts: Vec<f64> = (0..400)
            .map(|i| -0.5 + 5.0 * ((i * 37) % 400) as f64 / 400.0)
            .chain(panel_points(1.0, 1.25))
            .collect();
        let many = g.eval_many(&ts);
        for (t, v) in ts.iter().zip(many) {
            assert_eq!(v, g.eval(*t), "t = {t}");
        }
    }

    #[test]
    fn outside_the_domain_is_zero() {
        let f = build1(2.0, |_| 1.0);
        assert_eq!(f.eval(-1.0), 0.0);
        assert_eq!(f.eval(2.5), 0.0);
        assert!((f.integral_to(5.0) - 2.0).abs() < 1e-14);
        assert!((f.total() - 2.0).abs() < 1e-14);
        assert_eq!(Interpolant::zero(1.0).integral_to(1.0), 0.0);
    }

    #[test]
    fn sampler_errors_and_non_finite_values_are_reported() {
        let e = build::<&str>(1.0, 1, |_| Err("no")).unwrap_err();
        assert_eq!(e, BuildError::Sample("no"));
        let e = build::<()>(1.0, 1, |p| Ok(vec![f64::NAN; p.len()])).unwrap_err();
        assert_eq!(e, BuildError::NotConverged);
    }
}
