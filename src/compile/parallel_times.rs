//! The mean times of a Parallel with the book's thresholds whose children
//! have curves but not all phase chains, by quadrature of its counted curve
//! (a leaf of the engine: the curve comes in from the planner).

use super::curve_options::{CurveOptions, CurvePoint};
use crate::compile::{self, atoms, counts, shifted, AnalysisError};
use crate::ir::{Graph, Leaf, Op};
use crate::solve::quadrature;
use crate::tree::{Duration, NodeId};

/// A Parallel's curve at some times, by the planner's count programme.
pub(crate) type CountedCurve<'a> =
    dyn Fn(&[f64], &CurveOptions) -> Result<Vec<CurvePoint>, AnalysisError> + 'a;

/// Gauss–Legendre points per panel (the error is estimated against the
/// rule with half as many).
const MEAN_RULE: usize = 24;

/// Relative accuracy asked of each mean time by quadrature.
const MEAN_QUADRATURE_TOLERANCE: f64 = 1e-13;

/// Most rounds of panel refinement (each halves the panels not yet accepted).
const MAX_REFINEMENTS: usize = 40;

/// Most panels of one round of the mean times' quadrature (each samples
/// every child's curve at 36 points).
const MAX_MEAN_PANELS: usize = 1 << 16;

/// A gap `P(S) − S(t)` below this fraction of the outcome probabilities is
/// rounding of the children's curves: the tail stops there (what it drops
/// is about this fraction of the mean times, below their tolerance).
const TAIL_ROUNDING: f64 = 1e-15;

/// `[E[T·1{S}], E[T·1{F}]]` of Parallel `id` with the book's thresholds
/// (success threshold `m`) whose children have curves but not all phase
/// chains — deterministic or hybrid actions beside stochastic ones, e.g. the
/// book's Example 9.2 — or whose children are stiff (their curves then come
/// from dense exponentials), by quadrature of its curve:
/// `E[T·1{S}] = ∫₀^∞ (P(S) − S(t)) dt`, with `S(t)` the count programme over
/// the children's exact curves ([`parallel_by_counts`]).
///
/// The integrand jumps or kinks only where a child's curve does — at the
/// deterministic instants of its actions and atoms — and is smooth (a sum of
/// exponential polynomials) between them, so the panels start at those
/// instants (and, for fast phases, at 8^k / the fastest rate up to the
/// longest child mean); beyond the last one they double in width until the probability
/// still running times the next width is below 1e-16 of the integral. Each
/// panel's `MEAN_RULE`-point Gauss–Legendre sum is accepted when it agrees
/// with the half-order rule to 1e-13 of the integral (panels are halved
/// otherwise). The result is an error *estimate*, not a bound.
///
/// `counted_curve(times, options)` is the node's curve by the count
/// programme (the planner's), `fastest()` the largest total rate of the
/// children's phase chains (0 without any), asked only when needed, and
/// `settled(scale, ε)` a time after which the node has all but `ε` of its
/// mass returned ([`super::tail`], from the structure): the tail stops
/// there, whatever gap the children's curves still show — that gap is their
/// error (an interpolated law's 1e-13), and integrating it further grew a
/// mean time without bound (a survey tree's MTTS of 6.6e6 s for 2.5 s).
pub(crate) fn parallel_times_by_quadrature(
    tree: &Graph,
    id: NodeId,
    (m, max_states): (usize, usize),
    child_figures: &[compile::Figures],
    fastest: &dyn Fn() -> f64,
    counted_curve: &CountedCurve<'_>,
    settled: &dyn Fn(f64, f64) -> Option<f64>,
) -> Result<[f64; 2], AnalysisError> {
    let node = tree.node(id);
    let children = node.kind.children();
    let f_cap = children.len() + 1 - m;
    let outcomes: Vec<(f64, f64)> = child_figures.iter().map(|f| (f.ps, f.pf)).collect();
    let (ps, pf) = counts::status_by_counts(&outcomes, m, f_cap);
    let longest = child_figures
        .iter()
        .map(compile::Figures::mean_time)
        .fold(0.0, f64::max);
    if longest == 0.0 {
        return Ok([0.0, 0.0]);
    }
    let options = CurveOptions {
        max_states,
        ..CurveOptions::default()
    };
    // P(S) − S(t) and P(F) − F(t) at `times`
    let gaps = |times: &[f64]| -> Result<Vec<[f64; 2]>, AnalysisError> {
        let points = counted_curve(times, &options)?;
        Ok(points
            .iter()
            .map(|p| [(ps - p.success).max(0.0), (pf - p.failure).max(0.0)])
            .collect())
    };
    let mut cuts = vec![0.0];
    for &c in children {
        breakpoints(tree, c, max_states, &mut cuts)?;
    }
    // fast phases make boundary layers of width ~1/rate near 0: cut there
    // too, geometrically up to the longest mean
    let fastest = fastest();
    if fastest > 0.0 {
        let mut t = 1.0 / fastest;
        while t < longest {
            cuts.push(t);
            t *= 8.0;
        }
    }
    cuts.retain(|t| t.is_finite() && *t >= 0.0);
    cuts.sort_by(f64::total_cmp);
    cuts.dedup_by(|a, b| (*a - *b).abs() <= 1e-12 * a.abs().max(1.0));
    let mut panels: Vec<(f64, f64)> = cuts.windows(2).map(|w| (w[0], w[1])).collect();
    let full = quadrature::GaussLegendre::new(MEAN_RULE);
    let half = quadrature::GaussLegendre::new(MEAN_RULE / 2);
    let mut total = [0.0f64; 2];
    // the tail: panels of doubling width after the last instant
    let mut start = *cuts.last().expect("0 is a cut");
    let mut width = longest.max(start / 8.0);
    let mut pending = std::mem::take(&mut panels);
    let settled = settled(longest, TAIL_ROUNDING * (ps + pf)).unwrap_or(f64::INFINITY);
    for _ in 0..MAX_REFINEMENTS + 64 {
        let mut next = Vec::new();
        let (sums, errors) = integrate_panels(&pending, &full, &half, &gaps)?;
        let scale = (total[0] + total[1] + sums.iter().map(|s| s[0] + s[1]).sum::<f64>())
            .max(f64::MIN_POSITIVE);
        for ((p, s), e) in pending.iter().zip(&sums).zip(&errors) {
            // a panel whose rules differ by no more than the rounding of the
            // children's curves (TAIL_ROUNDING of the outcome probabilities
            // per unit of time) is as good as it gets: halving it again only
            // resolves that rounding (a Parallel that has surely returned at
            // 0 has gaps of 1e-16 everywhere, and halving them for ever
            // doubled the panels until memory ran out)
            let rounding = TAIL_ROUNDING * (ps + pf) * (p.1 - p.0);
            if *e <= MEAN_QUADRATURE_TOLERANCE * scale
                || *e <= rounding
                || p.1 - p.0 <= 1e-12 * p.1.max(1.0)
            {
                total[0] += s[0];
                total[1] += s[1];
            } else {
                let mid = 0.5 * (p.0 + p.1);
                next.push((p.0, mid));
                next.push((mid, p.1));
            }
        }
        // extend the tail while the mass still running matters: its
        // remainder is about `gap × width`; a gap within rounding of the
        // outcome probabilities (the curve's `1e-16`-level error) is done
        let running = gaps(&[start])?[0];
        let gap = running[0] + running[1];
        if start < settled
            && gap > TAIL_ROUNDING * (ps + pf)
            && gap * width > 1e-16 * (total[0] + total[1]).max(1e-300)
        {
            next.push((start, start + width));
            start += width;
            width *= 2.0;
        }
        if next.is_empty() {
            // below the rounding of the curves over the children's time
            // scale a mean is 0 (a Parallel that returns at once)
            let floor = TAIL_ROUNDING * (ps + pf) * longest;
            return Ok(total.map(|x| if x <= floor { 0.0 } else { x }));
        }
        // each panel is a batch of the children's curves: bounded before
        // the next round allocates them
        if next.len() > MAX_MEAN_PANELS {
            break;
        }
        pending = next;
    }
    Err(AnalysisError::Numerical {
        node: node.name.clone(),
        what: "the quadrature of its mean times did not converge".into(),
    })
}

/// Integrals of `gaps` over each panel by the full rule, and the difference
/// from the half rule (largest of the two outcomes).
#[allow(clippy::type_complexity)]
fn integrate_panels(
    panels: &[(f64, f64)],
    full: &quadrature::GaussLegendre,
    half: &quadrature::GaussLegendre,
    gaps: &dyn Fn(&[f64]) -> Result<Vec<[f64; 2]>, AnalysisError>,
) -> Result<(Vec<[f64; 2]>, Vec<f64>), AnalysisError> {
    let mut times = Vec::with_capacity(panels.len() * (full.len() + half.len()));
    for &(a, b) in panels {
        let (c, h) = (0.5 * (a + b), 0.5 * (b - a));
        times.extend(full.nodes.iter().chain(&half.nodes).map(|x| c + h * x));
    }
    let values = gaps(&times)?;
    let per = full.len() + half.len();
    let mut sums = Vec::with_capacity(panels.len());
    let mut errors = Vec::with_capacity(panels.len());
    for (k, &(a, b)) in panels.iter().enumerate() {
        let h = 0.5 * (b - a);
        let v = &values[k * per..(k + 1) * per];
        let rule = |w: &[f64], v: &[[f64; 2]], o: usize| -> f64 {
            h * w.iter().zip(v).map(|(w, v)| w * v[o]).sum::<f64>()
        };
        let (vf, vh) = v.split_at(full.len());
        let s = [rule(&full.weights, vf, 0), rule(&full.weights, vf, 1)];
        let e = (0..2)
            .map(|o| (s[o] - rule(&half.weights, vh, o)).abs())
            .fold(0.0, f64::max);
        sums.push(s);
        errors.push(e);
    }
    Ok((sums, errors))
}

/// Instants where the curve of the subtree at `id` may jump or kink: the
/// fixed times and hybrid caps of its actions, the atoms of a deterministic
/// subtree, the union of a Parallel's children's. Subtrees of exponential
/// actions have smooth curves and add none.
fn breakpoints(
    tree: &Graph,
    id: NodeId,
    max_states: usize,
    out: &mut Vec<f64>,
) -> Result<(), AnalysisError> {
    match &tree.node(id).kind {
        Op::Leaf(Leaf::Action(a)) => {
            for d in [a.success, a.failure].into_iter().flatten() {
                match d {
                    Duration::Fixed { time } => out.push(time),
                    Duration::TruncatedExponential { cap, .. } => out.push(cap),
                    Duration::PhaseType { shift, .. } if shift > 0.0 => out.push(shift),
                    Duration::Exponential { .. } | Duration::PhaseType { .. } => {}
                }
            }
        }
        Op::Leaf(Leaf::Condition { .. }) => {}
        kind => {
            // cuts are hints to the quadrature, read within a small budget:
            // past it there are too many instants to cut at (the panels'
            // halving finds the jumps); a mixture's shifts come from its
            // sizes, no chain built
            let budget = max_states.min(shifted::SHIFTED_FIRST);
            let many = |e: &AnalysisError| matches!(e, AnalysisError::StateBudget { .. });
            match atoms::atoms(tree, id, budget) {
                Ok(Some(a)) => out.extend(a.iter().map(|a| a.time)),
                Err(e) if many(&e) => {}
                Err(e) => return Err(e),
                Ok(None) if matches!(kind, Op::KOfN { .. }) => {
                    for &c in kind.children() {
                        breakpoints(tree, c, max_states, out)?;
                    }
                }
                Ok(None) => {
                    if let Some(shifts) = shifted::mixture_shifts(tree, id, budget)? {
                        out.extend(shifts);
                    }
                }
            }
        }
    }
    Ok(())
}
