//! `π(t)` of a node one of whose children has no phase chain within the
//! budget — typically a wide Parallel, whose curve is counted
//! ([`super::parallel_by_counts`]) — by composing that child's distribution
//! with the rest of the node.
//!
//! Let X be a Sequence or Fallback and C a node below it without a chain,
//! reached through Sequences, Fallbacks, inverters and force decorators
//! only. C runs at most once per run of X, and the other nodes' durations
//! and outcomes are independent of C's. Replace C by a
//! *marker* that returns outcome `o` instantly (or, for `∅`, ends the run
//! with no outcome) and build X's phase chain for each: its curves are
//! `A_o(t)` and `N(t)`. `N` is the part of X's runs that never start C;
//! `X_o = A_o − N` is the part that starts C, sees outcome `o`, and ends
//! within the time of the other children. Since X's time on those runs is
//! C's time plus an independent remainder with distribution `X_o`, for
//! either outcome r of X
//!
//! ```text
//! R(t) = N_r(t) + Σ_o ∫_{[0,t]} C_o(t − v) dX_{o,r}(v)
//!      = N_r(t) + Σ_o [ X_{o,r}(0) C_o(t) + ∫_0^t x_{o,r}(v) C_o(t − v) dv ]
//! ```
//!
//! where `C_o(w)` is the probability that C returned o by w and
//! `x_{o,r} = a_{o,r} − n_r` the outcome densities of the marker chains
//! (uniformization gives `π(v)·exit` as a Poisson sum of non-negative
//! terms). The integral is computed by adaptive Gauss–Legendre quadrature
//! (16 points per panel on a graded initial grid; a panel is accepted when
//! it agrees with its two halves within `1e-12·(width/t)`, its halves'
//! value kept). This is an error *estimate*, not a bound; tests check the
//! result against the product chain (small cases, 1e-9) and simulation.

use super::{curve, CurveOptions};
use crate::compile::{phase, AnalysisError};
use crate::solve::chain::PhaseChain;
use crate::solve::quadrature::GaussLegendre;
use crate::solve::transient::{transient_weighted, CurvePoint};
use crate::tree::{Decorator, NodeId, NodeKind, Tree};

/// Truncation error allowed in the marker chains' figures.
const TOLERANCE: f64 = 1e-15;
/// Accepted disagreement of a panel with its halves, per unit of `t`.
const PANEL_TOLERANCE: f64 = 1e-12;
/// Most halvings of a panel.
const MAX_ROUNDS: usize = 30;

/// `π(t)` of `id` by composition, or `None` when the node is not of the
/// form above; the caller then reports its own error.
///
/// An inverter or force decorator transforms its child's curve directly.
/// For a Sequence or Fallback, the child without a chain is followed down
/// through further Sequences, Fallbacks, inverters and force decorators
/// (which all run their children at most once) to the node C that has no
/// chain itself, and C is replaced by the markers at that depth: one
/// composition whatever the nesting.
pub(super) fn with_opaque_child(
    tree: &Tree,
    id: NodeId,
    times: &[f64],
    options: &CurveOptions,
) -> Option<Result<Vec<CurvePoint>, AnalysisError>> {
    let node = tree.node(id);
    match node.kind {
        NodeKind::Sequence { .. } | NodeKind::Fallback { .. } => {}
        NodeKind::Decorator {
            decorator: d @ (Decorator::Inverter | Decorator::ForceSuccess | Decorator::ForceFailure),
            child,
        } => {
            return Some(curve(tree, child, times, options).map(|points| {
                points
                    .into_iter()
                    .map(|p| {
                        let (success, failure) = match d {
                            Decorator::Inverter => (p.failure, p.success),
                            Decorator::ForceSuccess => (p.success + p.failure, 0.0),
                            _ => (0.0, p.success + p.failure),
                        };
                        CurvePoint {
                            success,
                            failure,
                            ..p
                        }
                    })
                    .collect()
            }))
        }
        _ => return None,
    }
    let target = opaque_descendant(tree, id, options.max_states)?;
    let build = |initial_success: f64, initial_failure: f64| {
        let marker = PhaseChain {
            initial_success,
            initial_failure,
            ..PhaseChain::default()
        };
        chain_with(tree, id, target, &marker, options.max_states)
    };
    let rest = match (build(0.0, 0.0), build(1.0, 0.0), build(0.0, 1.0)) {
        (Ok(n), Ok(s), Ok(f)) => [n, s, f],
        (Err(e), _, _) | (_, Err(e), _) | (_, _, Err(e)) => return Some(Err(e)),
    };
    Some(compose(tree, target, &rest, times, options, &node.name))
}

/// Whether a node runs each child at most once and only composes their
/// outcomes in sequence.
fn single_run(kind: &NodeKind) -> bool {
    matches!(
        kind,
        NodeKind::Sequence { .. }
            | NodeKind::Fallback { .. }
            | NodeKind::Decorator {
                decorator: Decorator::Inverter | Decorator::ForceSuccess | Decorator::ForceFailure,
                ..
            }
    )
}

/// The node below `id` without a chain, reached through single-run nodes
/// each of which has exactly one child without a chain; `None` otherwise.
fn opaque_descendant(tree: &Tree, id: NodeId, max_states: usize) -> Option<NodeId> {
    let mut at = id;
    loop {
        let mut opaque = None;
        for &c in tree.node(at).kind.children() {
            match phase::phase_chain(tree, c, max_states) {
                Ok(_) => {}
                Err(AnalysisError::StateBudget { .. }) if opaque.is_none() => opaque = Some(c),
                Err(_) => return None,
            }
        }
        let c = opaque?;
        if !single_run(&tree.node(c).kind) {
            return Some(c);
        }
        at = c;
    }
}

/// The phase chain of `id` with the subtree `target` replaced by `marker`.
fn chain_with(
    tree: &Tree,
    id: NodeId,
    target: NodeId,
    marker: &PhaseChain,
    max_states: usize,
) -> Result<PhaseChain, AnalysisError> {
    if id == target {
        return Ok(marker.clone());
    }
    let mut up = tree.node(target).parent;
    while let Some(p) = up {
        if p == id {
            let chains = tree
                .node(id)
                .kind
                .children()
                .iter()
                .map(|&c| chain_with(tree, c, target, marker, max_states))
                .collect::<Result<Vec<_>, _>>()?;
            return phase::combine(tree, id, chains, max_states);
        }
        up = tree.node(p).parent;
    }
    phase::phase_chain(tree, id, max_states)
}

/// The marker chains `[∅, S, F]` evaluated at points: per point and chain,
/// `[S, F, density of S, density of F]`.
fn marker_rows(
    rest: &[PhaseChain; 3],
    points: &[f64],
    name: &str,
) -> Result<Vec<[[f64; 4]; 3]>, AnalysisError> {
    let mut out = vec![[[0.0; 4]; 3]; points.len()];
    for (c, chain) in rest.iter().enumerate() {
        let rows = transient_weighted(
            chain,
            points,
            TOLERANCE,
            &[&chain.exit_success, &chain.exit_failure],
        )
        .ok_or_else(|| AnalysisError::Stiff {
            node: name.to_string(),
            work: f64::INFINITY,
            limit: super::DEFAULT_MAX_WORK,
        })?;
        for (o, r) in out.iter_mut().zip(rows) {
            o[c].copy_from_slice(&r[..4]);
        }
    }
    Ok(out)
}

#[derive(Debug, Clone, Copy)]
struct Panel {
    /// Index of the time point.
    t: usize,
    a: f64,
    b: f64,
    /// `∫ x_{o,r} C_o` over the panel, for (o, r) = (S,S), (S,F), (F,S), (F,F).
    q: [f64; 4],
}

fn compose(
    tree: &Tree,
    child: NodeId,
    rest: &[PhaseChain; 3],
    times: &[f64],
    options: &CurveOptions,
    name: &str,
) -> Result<Vec<CurvePoint>, AnalysisError> {
    let rule = GaussLegendre::new(16);
    // Q of many panels at once: the marker chains at the nodes v, the child
    // at t − v
    let integrate = |panels: &[(usize, f64, f64)]| -> Result<Vec<[f64; 4]>, AnalysisError> {
        let mut v_points = Vec::with_capacity(panels.len() * rule.len());
        let mut w_points = Vec::with_capacity(panels.len() * rule.len());
        for &(t, a, b) in panels {
            let (c, h) = ((a + b) / 2.0, (b - a) / 2.0);
            for x in &rule.nodes {
                let v = c + h * x;
                v_points.push(v);
                w_points.push((times[t] - v).max(0.0));
            }
        }
        let rows = marker_rows(rest, &v_points, name)?;
        let inner = curve(tree, child, &w_points, options)?;
        Ok(panels
            .iter()
            .enumerate()
            .map(|(p, &(_, a, b))| {
                let h = (b - a) / 2.0;
                let mut q = [0.0; 4];
                for (j, w) in rule.weights.iter().enumerate() {
                    let i = p * rule.len() + j;
                    let (r, c) = (&rows[i], &inner[i]);
                    for (o, c_o) in [(1, c.success), (2, c.failure)] {
                        for out in 0..2 {
                            let density = r[o][2 + out] - r[0][2 + out];
                            q[2 * (o - 1) + out] += w * h * density * c_o;
                        }
                    }
                }
                q
            })
            .collect())
    };
    // graded initial panels, finer near both ends where fast phases act
    const GRID: [f64; 15] = [
        0.0, 1e-4, 1e-3, 1e-2, 0.05, 0.15, 0.3, 0.5, 0.7, 0.85, 0.95, 0.99, 0.999, 0.9999, 1.0,
    ];
    let mut active: Vec<(usize, f64, f64)> = Vec::new();
    for (t, &tv) in times.iter().enumerate() {
        if tv > 0.0 {
            active.extend(GRID.windows(2).map(|g| (t, g[0] * tv, g[1] * tv)));
        }
    }
    let mut panels: Vec<Panel> = integrate(&active)?
        .into_iter()
        .zip(&active)
        .map(|(q, &(t, a, b))| Panel { t, a, b, q })
        .collect();
    let mut totals = vec![[0.0f64; 4]; times.len()];
    for _ in 0..MAX_ROUNDS {
        if panels.is_empty() {
            break;
        }
        let halves: Vec<(usize, f64, f64)> = panels
            .iter()
            .flat_map(|p| {
                let m = (p.a + p.b) / 2.0;
                [(p.t, p.a, m), (p.t, m, p.b)]
            })
            .collect();
        let hq = integrate(&halves)?;
        let mut next = Vec::new();
        for (i, p) in panels.iter().enumerate() {
            let (l, r) = (hq[2 * i], hq[2 * i + 1]);
            let fine: [f64; 4] = std::array::from_fn(|j| l[j] + r[j]);
            let diff = (0..4).map(|j| (fine[j] - p.q[j]).abs()).fold(0.0, f64::max);
            if diff <= PANEL_TOLERANCE * (p.b - p.a) / times[p.t] {
                for (acc, x) in totals[p.t].iter_mut().zip(fine) {
                    *acc += x;
                }
            } else {
                let (ha, hb) = (halves[2 * i], halves[2 * i + 1]);
                next.push(Panel {
                    t: ha.0,
                    a: ha.1,
                    b: ha.2,
                    q: l,
                });
                next.push(Panel {
                    t: hb.0,
                    a: hb.1,
                    b: hb.2,
                    q: r,
                });
            }
        }
        panels = next;
    }
    if !panels.is_empty() {
        return Err(AnalysisError::Numerical {
            node: name.to_string(),
            what: "the composition integral did not converge".into(),
        });
    }
    // the atoms at 0 of the remainder, and the no-C part
    let at_t = marker_rows(rest, times, name)?;
    let child_at_t = curve(tree, child, times, options)?;
    Ok(times
        .iter()
        .enumerate()
        .map(|(t, &tv)| {
            let (r, c) = (&at_t[t], &child_at_t[t]);
            let mut out = [r[0][0], r[0][1]];
            for (o, c_o) in [(1, c.success), (2, c.failure)] {
                for (x, acc) in out.iter_mut().enumerate() {
                    let atom = initial(&rest[o], x) - initial(&rest[0], x);
                    *acc += atom * c_o + totals[t][2 * (o - 1) + x];
                }
            }
            let (success, failure) = (out[0].clamp(0.0, 1.0), out[1].clamp(0.0, 1.0));
            CurvePoint {
                t: tv,
                success,
                failure,
                running: (1.0 - success - failure).max(0.0),
            }
        })
        .collect())
}

/// Instantaneous Success (`x = 0`) or Failure (`x = 1`) of a chain.
fn initial(chain: &PhaseChain, x: usize) -> f64 {
    if x == 0 {
        chain.initial_success
    } else {
        chain.initial_failure
    }
}
