//! Probabilities over time: `π(t)` of any node, by three methods.
//!
//! * **exact** (default): the node's exact phase chain ([`compile::phase`])
//!   solved by uniformization ([`solve::transient`](crate::solve::transient)) with a rigorous
//!   truncation bound, or, when that would take too many steps (a stiff
//!   chain over a long horizon) and the chain is small, by dense
//!   exponentials in double-double ([`solve::expm`](crate::solve::expm)); for subtrees whose actions all have deterministic
//!   times, the exact finitely many return instants (`compile::atoms`,
//!   Prop. 9.2's zero-order hold without rounding to a grid).
//! * nodes whose chain exceeds the budget (wide Parallels and everything
//!   above them): Parallels with the book's thresholds by counting their
//!   children's curves, and every other node from composed outcome laws
//!   (interpolated densities, `law`).
//! * **book**: the chapter's recursion: the node's CTMC over its MRG with
//!   every child replaced by an exponential (`compile::book_ctmc`).
//! * **`Timing::Deterministic`**: every exponential time becomes a fixed
//!   time `τ = 1/rate` first (the book's Figs. 9.20–9.21 comparison).

use super::chain_curve::curve_by_shifted;
use crate::compile::{self, atoms, counts, phase, shifted, AnalysisError, Plan};
use crate::solve::quadrature;
use crate::solve::transient::{self, uniformization_work};
use crate::tree::{Decorator, Duration, NodeId, NodeKind, Tree};

pub use super::curve_options::{CurveOptions, CurvePoint, Timing};

/// The tree with every random time replaced by its mean (`τ = 1/rate`; an
/// Erlang, hypo-, hyperexponential, phase-type or shifted time by its mean).
pub fn deterministic_version(tree: &Tree) -> Tree {
    let mut t = tree.clone();
    let fix = |d: Option<Duration>| {
        d.map(|d| match d {
            Duration::Exponential { rate } | Duration::TruncatedExponential { rate, .. } => {
                Duration::Fixed { time: 1.0 / rate }
            }
            d @ Duration::PhaseType { .. } => Duration::Fixed { time: d.mean() },
            fixed => fixed,
        })
    };
    for n in &mut t.nodes {
        if let NodeKind::Action(a) = &mut n.kind {
            a.success = fix(a.success);
            a.failure = fix(a.failure);
        }
    }
    t
}

/// `π(t)` of node `id` at `times` (finite, ≥ 0; any order), in the order
/// given: the query on the node's planned representation (`compile::plan`).
pub fn curve(
    tree: &Tree,
    id: NodeId,
    times: &[f64],
    options: &CurveOptions,
) -> Result<Vec<CurvePoint>, AnalysisError> {
    match super::primitive_view(tree)? {
        Some(view) => curve_of(&view.tree, view.image[id], times, options),
        None => curve_of(tree, id, times, options),
    }
}

fn curve_of(
    tree: &Tree,
    id: NodeId,
    times: &[f64],
    options: &CurveOptions,
) -> Result<Vec<CurvePoint>, AnalysisError> {
    let opts = CurveOptions {
        timing: Timing::AsGiven,
        ..*options
    };
    if options.timing == Timing::Deterministic {
        let det = deterministic_version(tree);
        return with_tail(
            &Plan::new(&det, options.method, options.max_states),
            id,
            times,
            &opts,
        );
    }
    with_tail(
        &Plan::new(tree, options.method, options.max_states),
        id,
        times,
        &opts,
    )
}

/// Mass still to return below which `π(t)` is answered from the figures.
pub const TAIL_TOLERANCE: f64 = 1e-13;

/// `π(t)` of node `id` at `times`, the times far past the node's mean time
/// answered from its figures.
///
/// `S(t) + F(t)` only grows, to `P(S) + P(F)`: once the mass still to
/// return after some `t*` is below [`TAIL_TOLERANCE`], every `t ≥ t*` has
/// `|S(t) − P(S)|` and `|F(t) − P(F)|` below it too, and is answered
/// `(P(S), P(F))`. `t*` comes from a bound on the node's return time's
/// moment generating function ([`super::tail`]: from the tree's structure,
/// before any law is built), so a curve to `t = 10⁷` of a node that returns
/// within seconds costs its figures and the curve before `t*`. It is asked
/// only when the last time is past 16 × the sum of the node's actions' mean
/// times; without figures (a node whose figures the engine does not
/// answer) or a finite bound every time is computed.
pub(crate) fn with_tail(
    plan: &Plan,
    id: NodeId,
    times: &[f64],
    options: &CurveOptions,
) -> Result<Vec<CurvePoint>, AnalysisError> {
    let last = times.iter().copied().fold(0.0, f64::max);
    // the figures are asked only for times far past one run of every leaf
    // below (a cheap scale: a loop's may be longer)
    let leaves = leaf_time_scale(plan.tree(), id);
    if last <= 16.0 * leaves {
        return plan.curve(id, times, options);
    }
    let Ok(all) = compile::subtree_figures(plan, id) else {
        return plan.curve(id, times, options);
    };
    let figures = all[0];
    let limit = |t: f64| CurvePoint {
        t,
        success: figures.ps,
        failure: figures.pf,
        running: (1.0 - figures.ps - figures.pf).max(0.0),
    };
    if figures.ps + figures.pf == 0.0 {
        // it never returns
        return Ok(times.iter().map(|&t| limit(t)).collect());
    }
    let scale = figures
        .mtts
        .unwrap_or(0.0)
        .max(figures.mttf.unwrap_or(0.0))
        .max(leaves);
    let known = plan.known_subtree_figures(id);
    let Some(tail) = super::tail::settled_after(plan.tree(), id, &known, scale, TAIL_TOLERANCE)
    else {
        return plan.curve(id, times, options);
    };
    let before: Vec<f64> = times.iter().copied().filter(|&t| t < tail).collect();
    let mut computed = plan.curve(id, &before, options)?.into_iter();
    Ok(times
        .iter()
        .map(|&t| {
            if t < tail {
                computed.next().expect("one point per time before the tail")
            } else {
                limit(t)
            }
        })
        .collect())
}

/// The sum of the mean times of the actions below `id`.
fn leaf_time_scale(tree: &Tree, id: NodeId) -> f64 {
    tree.subtree(id)
        .map(|n| match &tree.node(n).kind {
            NodeKind::Action(a) => [a.success, a.failure]
                .iter()
                .flatten()
                .map(Duration::mean)
                .fold(0.0, f64::max),
            _ => 0.0,
        })
        .sum()
}

/// `π(t)` of a loop without a bound over a child with a phase chain: the
/// child's chain with the exit that repeats it ("again": Success for
/// `until_failure`) routed back to its entry distribution — a cyclic chain,
/// solved by uniformization (which needs no order of the phases). An
/// instantaneous "again" at entry is folded in by renormalising the entry:
/// the entry is `initial / (1 − p₀)`, `p₀` the child's instantaneous
/// probability of "again".
pub(super) fn loop_curve(
    tree: &Tree,
    id: NodeId,
    child: NodeId,
    decorator: Decorator,
    times: &[f64],
    options: &CurveOptions,
) -> Result<Vec<CurvePoint>, AnalysisError> {
    let node = tree.node(id);
    let unbounded = || AnalysisError::Unbounded {
        node: node.name.clone(),
    };
    let mut c = match phase::chain_of(tree, child, options.max_states) {
        Ok(c) => c,
        // a child with mixed timing: the loop's truncated geometric series
        // as a shifted mixture where it is small (as the planner's
        // `Shifted` rule), else the loop's composed law (`law`: the
        // geometric sum by binary powering, any child)
        Err(AnalysisError::NotMarkovian { .. }) => {
            let first = options.max_states.min(super::plan::SHIFTED_FIRST);
            return match shifted::shifted_law(tree, id, first) {
                Ok(Some(law)) => curve_by_shifted(&law, times, options, &node.name),
                Ok(None) | Err(AnalysisError::StateBudget { .. }) => {
                    super::law::curve_by_laws(tree, id, times, options, unbounded())
                }
                Err(e) => Err(e),
            };
        }
        Err(e) => return Err(e),
    };
    // work with "again" as the Success exit, then swap back
    let until_success = decorator == Decorator::UntilSuccess;
    if until_success {
        std::mem::swap(&mut c.exit_success, &mut c.exit_failure);
        std::mem::swap(&mut c.initial_success, &mut c.initial_failure);
    }
    let again0 = c.initial_success;
    if again0 >= 1.0 || (c.initial.is_empty() && c.initial_failure <= 0.0) {
        // the child never ends the loop: it runs forever
        return Ok(times
            .iter()
            .map(|&t| CurvePoint {
                t,
                success: 0.0,
                failure: 0.0,
                running: 1.0,
            })
            .collect());
    }
    let scale = 1.0 / (1.0 - again0);
    let entry: Vec<(usize, f64)> = c.initial.iter().map(|&(j, p)| (j, p * scale)).collect();
    let end0 = c.initial_failure * scale;
    for i in 0..c.len() {
        let again = std::mem::take(&mut c.exit_success[i]);
        if again > 0.0 {
            c.transitions[i].extend(entry.iter().map(|&(j, p)| (j, again * p)));
            c.exit_failure[i] += again * end0;
        }
    }
    c.initial = entry;
    c.initial_success = 0.0;
    c.initial_failure = end0;
    let work = uniformization_work(&c, times);
    if work > options.max_work {
        return Err(AnalysisError::Stiff {
            node: node.name.clone(),
            work,
            limit: options.max_work,
        });
    }
    let mut points = transient::transient(&c, times, options.tolerance);
    if until_success {
        for p in &mut points {
            std::mem::swap(&mut p.success, &mut p.failure);
        }
    }
    Ok(points)
}

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
pub(crate) fn parallel_times_by_quadrature(
    plan: &Plan,
    id: NodeId,
    m: usize,
    child_figures: &[compile::Figures],
) -> Result<[f64; 2], AnalysisError> {
    let tree = plan.tree();
    let max_states = plan.max_states();
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
        let points = plan.counted_curve(id, m, times, &options)?;
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
    let fastest = children
        .iter()
        .filter_map(|&c| plan.chain(c).ok())
        .flat_map(|c| (0..c.len()).map(move |i| c.total_rate(i)))
        .fold(0.0, f64::max);
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
        // extend the tail while the mass still running matters
        // extend the tail while the mass still running matters: its
        // remainder is about `gap × width`; a gap within rounding of the
        // outcome probabilities (the curve's `1e-16`-level error) is done
        let running = gaps(&[start])?[0];
        let gap = running[0] + running[1];
        if gap > TAIL_ROUNDING * (ps + pf)
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
    tree: &Tree,
    id: NodeId,
    max_states: usize,
    out: &mut Vec<f64>,
) -> Result<(), AnalysisError> {
    match &tree.node(id).kind {
        NodeKind::Action(a) => {
            for d in [a.success, a.failure].into_iter().flatten() {
                match d {
                    Duration::Fixed { time } => out.push(time),
                    Duration::TruncatedExponential { cap, .. } => out.push(cap),
                    Duration::PhaseType { shift, .. } if shift > 0.0 => out.push(shift),
                    Duration::Exponential { .. } | Duration::PhaseType { .. } => {}
                }
            }
        }
        NodeKind::Condition { .. } => {}
        kind => {
            if let Some(a) = atoms::atoms(tree, id, max_states)? {
                out.extend(a.iter().map(|a| a.time));
            } else if matches!(kind, NodeKind::Parallel { .. }) {
                for &c in kind.children() {
                    breakpoints(tree, c, max_states, out)?;
                }
            } else if let Some(law) = shifted::shifted_law(tree, id, max_states)? {
                out.extend(law.shifts());
            }
        }
    }
    Ok(())
}
