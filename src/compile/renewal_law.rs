//! The **outcome law** on `[0, T]` of a race against a renewal process of
//! re-runs (Nav2's re-planning PipelineSequence, lowered to
//! `Parallel{1, 1}(until_failure(Sequence(wait d, C′)), R)`), and of the
//! Sequence that starts it after Markovian children: its atoms at 0 and
//! the sub-densities `s(t)`, `f(t)` of its return time with Success and
//! with Failure, as piecewise Chebyshev interpolants — what
//! [`super::law`] composes with the rest of the tree (a RecoveryNode, a
//! Fallback, a Sequence around the pipeline).
//!
//! **Densities, not derivatives.** [`super::renewal_curve`] computes `S(t)`
//! as a linear functional of the stacked level state (`acc_k + W_k,S +
//! V_k,S − (W_{k−1} e^{Q̄d})_S`). Its density is another linear functional
//! of the same state, read off the process rather than differentiated:
//! Success happens at `t` when R succeeds while a run of `C′` is under way
//! (the product states' rates `h_S` into Success), when the prefix succeeds
//! and R succeeds at once, or when R succeeds during a wait. The waits
//! under way at `t` are those entered in this level (`W_k`'s R phases) and
//! those entered in the previous one after `θ` (`V_k`'s R phases less the
//! part of the entries up to `θ`, `W_{k−1}(θ)·E`): so
//!
//! `s(t) = Σ_{states} x_k(θ)·(rates into Success) − W_{k−1}(θ)_R·(E h_S)`,
//!
//! likewise Failure (R's and `C′`'s failure rates). Both are sums over the
//! uniformized steps with the same Poisson weights as the curve, so the
//! densities carry the curve's error (≤ `K·2e-16` after `K` levels, module
//! docs of `renewal_curve`) and nothing from a numerical derivative (which
//! would lose `ε·Λ` absolutely to cancellation, enough to stall the
//! panels' convergence test where the density is small). The one
//! subtraction, `V_k − W_{k−1}E` on R's phases, is between masses of the
//! waits' size, not of 1.
//!
//! **One pass.** The levels are run once ([`renewal_curve::Prepared::run`]),
//! each keeping only its steps' four functionals (`S, F, s, f`: four numbers
//! a step, counted in the method's memory budget); the panels are then
//! built adaptively ([`build_on`]: every round one batch of points, each
//! point one weighted sum of its level's functionals), so no level is
//! rerun. Pieces break at the level boundaries `t₀ + kd` where the
//! densities may jump or kink: the first [`SMOOTHING_LEVELS`] (the delay
//! equation's solution gains one order of smoothness per level, and a
//! panel's polynomial has degree 16), and every later one where waits start
//! with an atom (they leave together one period later); beyond, one piece
//! halved as the panels' test asks. Before `t₀` (a SpeedController's first
//! wait) R runs alone: its chain's densities. The interpolation adds the
//! usual estimate of 1e-15 in mass per panel; Nav2's default attempt over
//! 300 s takes 111 panels.
//!
//! **Atoms.** The law has atoms at 0 only (the prefix's or R's
//! instantaneous outcomes). A re-run that can fail at its start (`C′` with
//! an instantaneous Failure, e.g. a Sequence that opens with a condition)
//! fails with an atom at the end of each wait entered by an atom — after
//! 0, which the composed laws do not hold yet: refused as mixed timing.

use super::chain_curve::sample_weighted_kept;
use super::renewal_curve::{self, Level};
use super::AnalysisError;
use crate::ir::{Graph, Op};
use crate::solve::interpolant::{build_on, BuildError, Interpolant};
use crate::tree::NodeId;

/// Levels after which the densities are taken as smooth across level
/// boundaries (each level smooths the delay equation's solution by one
/// order; a panel's polynomial has degree 16), unless waits start there
/// with an atom.
pub(super) const SMOOTHING_LEVELS: usize = 24;
/// Atom entering waits at a level's start below which the density's jump
/// there is left to the panels' halving.
pub(super) const ATOM_FLOOR: f64 = 1e-15;

/// A race's law on `[0, T]`: its Success and Failure atoms at 0, and its
/// Success and Failure sub-densities.
pub(super) type RaceLaw = ([f64; 2], [Interpolant; 2]);

/// The law of node `id` on `[0, end]` — atoms at 0 and the Success and
/// Failure sub-densities — when it is a renewal race, or a Sequence ending
/// with one after Markovian children; `None` when it is not (or a side
/// has no phase chain).
pub(super) fn law(
    tree: &Graph,
    id: NodeId,
    end: f64,
    max_states: usize,
) -> Result<Option<RaceLaw>, AnalysisError> {
    let Some(run) = renewal_curve::prepare(tree, id, end, max_states)? else {
        return Ok(None);
    };
    let name = &tree.node(id).name;
    if run.instant_failure() > 0.0 {
        // a re-run that can fail as it starts ends the race at an instant
        // of the wait's lattice: atoms the levels' densities do not hold —
        // the composed laws' race takes it
        return Ok(None);
    }
    let atoms = run.atoms_at_zero();
    if end <= 0.0 {
        let zero = Interpolant::zero(0.0);
        return Ok(Some((atoms, [zero.clone(), zero])));
    }
    let not_converged = |e: BuildError<AnalysisError>| match e {
        BuildError::Sample(e) => e,
        BuildError::NotConverged => AnalysisError::Numerical {
            node: name.clone(),
            what: "the interpolated densities of the renewal race did not converge".into(),
        },
    };
    let (d, t0) = run.period();
    // one pass of the levels; each keeps its steps' four functionals
    let mut levels: Vec<Level> = Vec::new();
    run.run(|_, level| {
        levels.push(level);
        Ok(())
    })?;
    let starts: Vec<f64> = levels.iter().map(|l| l.start).collect();
    // the pieces: before t₀, then level by level while the densities may
    // jump or kink at the boundaries, then in one (halved as needed)
    let mut edges = vec![0.0];
    for (k, l) in levels.iter().enumerate() {
        let breaks = k < SMOOTHING_LEVELS || l.atoms > ATOM_FLOOR;
        if l.start > 0.0 && l.start < end && breaks {
            edges.push(l.start);
        }
    }
    edges.push(end);
    // the level holding `t` in piece `[a, b]`: its left limit at a level
    // start `t > a`, its right limit at `a`
    let level_at = |t: f64, a: f64| -> usize {
        let n = if t > a {
            starts.partition_point(|&s| s < t)
        } else {
            starts.partition_point(|&s| s <= t)
        };
        n.saturating_sub(1)
    };
    let mut parts: [Vec<Interpolant>; 2] = [Vec::new(), Vec::new()];
    for piece in edges.windows(2) {
        let (a, b) = (piece[0], piece[1]);
        let built = if a < t0 {
            // R alone until the first wait ends
            let r = run.rest();
            let weights = [&r.exit_success[..], &r.exit_failure[..]];
            let mut pass = None;
            build_on(a, b, true, 2, |points| {
                let rows =
                    sample_weighted_kept(&mut pass, r, points, &weights).ok_or_else(|| {
                        AnalysisError::Stiff {
                            node: name.clone(),
                            work: f64::INFINITY,
                            limit: f64::INFINITY,
                        }
                    })?;
                Ok(rows.iter().flat_map(|row| [row[2], row[3]]).collect())
            })
        } else {
            // the first level holds the prefix's fast phases
            build_on(a, b, a <= t0, 2, |points| {
                Ok(points
                    .iter()
                    .flat_map(|&t| {
                        let l = &levels[level_at(t, a)];
                        let [_, _, s, f] = l.at((t - l.start).clamp(0.0, d));
                        [s, f]
                    })
                    .collect())
            })
        }
        .map_err(not_converged)?;
        for (part, b) in parts.iter_mut().zip(built) {
            part.push(b);
        }
    }
    let [s, f] = parts.map(|p| Interpolant::join(&p));
    Ok(Some((atoms, [s, f])))
}

/// Whether a renewal race lies in the subtree of `id` (its law is then
/// composed from its children's, the race's own from [`law`]).
pub(super) fn holds_race(tree: &Graph, id: NodeId) -> bool {
    tree.subtree(id).any(|n| {
        matches!(tree.node(n).kind, Op::KOfN { .. }) && super::renewal::parts(tree, n).is_some()
    })
}
