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

use crate::compile::{self, AnalysisError, Plan};
use crate::ir::{Graph, Leaf, Op};
use crate::tree::{Action, Duration, NodeId, NodeKind, Tree};

pub use super::curve_options::{CurveOptions, CurvePoint, Timing};

/// The tree with every random time replaced by its mean (`τ = 1/rate`; an
/// Erlang, hypo-, hyperexponential, phase-type or shifted time by its mean).
pub fn deterministic_version(tree: &Tree) -> Tree {
    let mut t = tree.clone();
    for n in &mut t.nodes {
        if let NodeKind::Action(a) = &mut n.kind {
            fix_times(a);
        }
    }
    t
}

/// [`deterministic_version`] of a tree's IR.
pub(crate) fn deterministic_graph(tree: &Graph) -> Graph {
    let mut t = tree.clone();
    for n in &mut t.nodes {
        if let Op::Leaf(Leaf::Action(a)) = &mut n.kind {
            fix_times(a);
        }
    }
    t
}

/// An action's random times made their means.
fn fix_times(a: &mut Action) {
    let fix = |d: Option<Duration>| {
        d.map(|d| match d {
            Duration::Exponential { rate } | Duration::TruncatedExponential { rate, .. } => {
                Duration::Fixed { time: 1.0 / rate }
            }
            d @ Duration::PhaseType { .. } => Duration::Fixed { time: d.mean() },
            fixed => fixed,
        })
    };
    a.success = fix(a.success);
    a.failure = fix(a.failure);
}

/// `π(t)` of node `id` at `times` (finite, ≥ 0; any order), in the order
/// given: the query on the node's planned representation (`compile::plan`).
pub fn curve(
    tree: &Tree,
    id: NodeId,
    times: &[f64],
    options: &CurveOptions,
) -> Result<Vec<CurvePoint>, AnalysisError> {
    let lowered = super::lower(tree)?;
    curve_of(&lowered.graph, lowered.node(id), times, options)
}

/// [`curve`] of a tree's IR.
pub(crate) fn curve_of(
    tree: &Graph,
    id: NodeId,
    times: &[f64],
    options: &CurveOptions,
) -> Result<Vec<CurvePoint>, AnalysisError> {
    let opts = CurveOptions {
        timing: Timing::AsGiven,
        ..*options
    };
    if options.timing == Timing::Deterministic {
        let det = deterministic_graph(tree);
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

/// Times past this multiple of the sum of a node's leaves' mean times ask
/// its figures and tail bound first (cheap next to a long curve: Nav2's
/// route-graph tree's figures take 0.17 s, its curve at 2,000 s 135 s).
const FIGURES_PAST: f64 = 1.0;

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
/// only when the last time is past the sum of the node's actions' mean
/// times ([`FIGURES_PAST`]); without figures (a node whose figures the engine does not
/// answer) or a finite bound every time is computed.
pub(crate) fn with_tail(
    plan: &Plan,
    id: NodeId,
    times: &[f64],
    options: &CurveOptions,
) -> Result<Vec<CurvePoint>, AnalysisError> {
    let last = times.iter().copied().fold(0.0, f64::max);
    // the figures are asked only for times past one run of every leaf
    // below (a cheap scale: a loop's may be longer)
    let leaves = leaf_time_scale(plan.tree(), id);
    if last <= FIGURES_PAST * leaves {
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
fn leaf_time_scale(tree: &Graph, id: NodeId) -> f64 {
    tree.subtree(id)
        .map(|n| match &tree.node(n).kind {
            Op::Leaf(Leaf::Action(a)) => [a.success, a.failure]
                .iter()
                .flatten()
                .map(Duration::mean)
                .fold(0.0, f64::max),
            _ => 0.0,
        })
        .sum()
}
