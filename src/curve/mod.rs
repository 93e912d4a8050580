//! Probabilities over time: `π(t)` of any node, by three methods.
//!
//! * **exact** (default): the node's exact phase chain ([`compile::phase`])
//!   solved by uniformization ([`solve::transient`](crate::solve::transient)) with a rigorous
//!   truncation bound, or, when that would take too many steps (a stiff
//!   chain over a long horizon) and the chain is small, by dense
//!   exponentials in double-double ([`solve::expm`](crate::solve::expm)); for subtrees whose actions all have deterministic
//!   times, the exact finitely many return instants ([`compile::atoms`],
//!   Prop. 9.2's zero-order hold without rounding to a grid).
//! * nodes whose chain exceeds the budget (wide Parallels and everything
//!   above them): Parallels with the book's thresholds by counting their
//!   children's curves, and every other node from composed outcome laws
//!   (interpolated densities, `law`).
//! * **book**: the chapter's recursion: the node's CTMC over its MRG with
//!   every child replaced by an exponential ([`compile::book_ctmc`]).
//! * **`Timing::Deterministic`**: every exponential time becomes a fixed
//!   time `τ = 1/rate` first (the book's Figs. 9.20–9.21 comparison).

use crate::compile::mrg::{Mrg, Policy};
use crate::compile::{self, analyze, atoms, book_ctmc, counts, phase, AnalysisError, Method};
use crate::solve::chain::PhaseChain;
use crate::solve::expm;
use crate::solve::transient::{self, uniformization_work};
use crate::tree::{Duration, NodeId, NodeKind, Tree};

pub use crate::solve::transient::CurvePoint;

pub(crate) mod law;

/// How action times are taken.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Timing {
    /// As written in the tree file.
    #[default]
    AsGiven,
    /// Every exponential time replaced by a fixed time `1/rate`.
    Deterministic,
}

/// Error bound accepted from the dense stiff solver.
pub const DENSE_TOLERANCE: f64 = 1e-10;

/// Default limit on uniformization work (vector operations × nonzeros; an
/// upper bound, since the solver skips zero entries: about a few seconds).
pub const DEFAULT_MAX_WORK: f64 = 1e11;

/// Options of a curve computation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CurveOptions {
    /// exact or book.
    pub method: Method,
    /// Times as given or made deterministic.
    pub timing: Timing,
    /// Largest chain or number of atoms.
    pub max_states: usize,
    /// Bound on the absolute error of the truncated series.
    pub tolerance: f64,
    /// Largest uniformization effort before refusing.
    pub max_work: f64,
}

impl Default for CurveOptions {
    fn default() -> Self {
        CurveOptions {
            method: Method::Exact,
            timing: Timing::AsGiven,
            max_states: compile::DEFAULT_MAX_STATES,
            tolerance: transient::DEFAULT_TOLERANCE,
            max_work: DEFAULT_MAX_WORK,
        }
    }
}

/// The tree with every exponential time replaced by its mean (`τ = 1/rate`).
pub fn deterministic_version(tree: &Tree) -> Tree {
    let mut t = tree.clone();
    let fix = |d: Option<Duration>| {
        d.map(|d| match d {
            Duration::Exponential { rate } | Duration::TruncatedExponential { rate, .. } => {
                Duration::Fixed { time: 1.0 / rate }
            }
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

/// `π(t)` of node `id` at `times` (finite, ≥ 0; any order), in the order given.
pub fn curve(
    tree: &Tree,
    id: NodeId,
    times: &[f64],
    options: &CurveOptions,
) -> Result<Vec<CurvePoint>, AnalysisError> {
    if options.timing == Timing::Deterministic {
        let det = deterministic_version(tree);
        let opts = CurveOptions {
            timing: Timing::AsGiven,
            ..*options
        };
        return curve(&det, id, times, &opts);
    }
    let node = tree.node(id);
    let is_control = !node.kind.children().is_empty();
    // a leaf in closed form (any timing: exponential, fixed or hybrid)
    if let NodeKind::Action(a) = &node.kind {
        return Ok(times
            .iter()
            .map(|&t| {
                // an outcome without a duration has probability 0
                let cdf = |d: Option<Duration>| d.map_or(0.0, |d| d.cdf(t));
                let (success, failure) = (a.ps * cdf(a.success), a.pf * cdf(a.failure));
                CurvePoint {
                    t,
                    success,
                    failure,
                    running: (1.0 - success - failure).max(0.0),
                }
            })
            .collect());
    }
    if options.method == Method::Exact {
        if let NodeKind::Parallel {
            success_threshold,
            failure_threshold,
            children,
        } = &node.kind
        {
            if *failure_threshold == children.len() - success_threshold + 1 {
                return parallel_by_counts(tree, children, *success_threshold, times, options);
            }
        }
    }
    // deterministic subtrees: exact atoms (both methods agree on a leaf)
    if options.method == Method::Exact || !is_control {
        if let Some(a) = atoms::atoms(tree, id, options.max_states)? {
            return Ok(times
                .iter()
                .map(|&t| {
                    let (s, f) = atoms::cumulative(&a, t);
                    CurvePoint {
                        t,
                        success: s,
                        failure: f,
                        running: (1.0 - s - f).max(0.0),
                    }
                })
                .collect());
        }
    }
    let chain = match (options.method, is_control) {
        (Method::Book, true) => {
            let analysis = analyze(
                tree,
                &compile::Options {
                    method: Method::Book,
                    max_states: options.max_states,
                },
            )?;
            let children = node.kind.children();
            let figs: Vec<_> = children.iter().map(|&c| analysis.nodes[c]).collect();
            if let NodeKind::Decorator { decorator, .. } = node.kind {
                book_ctmc::book_decorator(decorator, figs[0])
            } else {
                let policy = Policy::of(&node.kind).expect("control node");
                if let Policy::Parallel {
                    success_threshold,
                    failure_threshold,
                } = policy
                {
                    let est = compile::mrg::parallel_marking_count(
                        children.len(),
                        success_threshold,
                        failure_threshold,
                    );
                    if est > options.max_states as f64 {
                        return Err(AnalysisError::StateBudget {
                            node: node.name.clone(),
                            states: est,
                            budget: options.max_states,
                        });
                    }
                }
                book_ctmc::book_ctmc(&Mrg::build(policy, children.len()), &figs)
            }
        }
        _ => match phase::phase_chain(tree, id, options.max_states) {
            Ok(c) => c,
            Err(AnalysisError::NotMarkovian { leaf }) => {
                return Err(AnalysisError::MixedTiming {
                    node: node.name.clone(),
                    leaf,
                })
            }
            Err(e @ AnalysisError::StateBudget { .. }) if options.method == Method::Exact => {
                return law::curve_by_laws(tree, id, times, options, e);
            }
            Err(e) => return Err(e),
        },
    };
    solve_chain(&chain, times, options, &node.name)
}

/// `π(t)` of a Parallel node with the book's thresholds (F = N − M + 1),
/// exactly, from its children's own curves.
///
/// Before the node returns its children run independently, and its two
/// thresholds cannot both be met (M + (N − M + 1) > N). So the node has
/// succeeded by t iff at least M children have succeeded by t — had it
/// failed first, N − M + 1 children would have failed, leaving fewer than M
/// to succeed — and likewise for Failure. With `S_h(t)`, `F_h(t)` the
/// children's curves (independent), the counts of children that have
/// succeeded and failed by t follow a trinomial Poisson-binomial law,
/// computed by a dynamic programme over the children with both counts capped
/// at their thresholds ([`counts::status_by_counts`]): O(N·M·(N−M+1)) per time point instead of a product
/// chain of up to 4^N states. Children are analysed on their own (any kind,
/// including deterministic ones).
fn parallel_by_counts(
    tree: &Tree,
    children: &[NodeId],
    m: usize,
    times: &[f64],
    options: &CurveOptions,
) -> Result<Vec<CurvePoint>, AnalysisError> {
    let n = children.len();
    let f_cap = n - m + 1;
    let curves = children
        .iter()
        .map(|&c| curve(tree, c, times, options))
        .collect::<Result<Vec<_>, _>>()?;
    Ok(times
        .iter()
        .enumerate()
        .map(|(k, &t)| {
            let points: Vec<(f64, f64)> = curves
                .iter()
                .map(|c| (c[k].success, c[k].failure))
                .collect();
            let (success, failure) = counts::status_by_counts(&points, m, f_cap);
            CurvePoint {
                t,
                success: success.clamp(0.0, 1.0),
                failure: failure.clamp(0.0, 1.0),
                running: (1.0 - success - failure).max(0.0),
            }
        })
        .collect())
}

fn solve_chain(
    chain: &PhaseChain,
    times: &[f64],
    options: &CurveOptions,
    name: &str,
) -> Result<Vec<CurvePoint>, AnalysisError> {
    let work = uniformization_work(chain, times);
    let small = chain.len() + 2 <= expm::MAX_DENSE_STATES;
    // the cheaper of the two: uniformization needs ~Λt steps, the dense
    // exponential of a small chain costs the same at any horizon
    let dense = small && expm::dense_work(chain, times) < work;
    let points = if !dense && work <= options.max_work {
        transient::transient(chain, times, options.tolerance)
    } else if small {
        // long horizon or stiff, but small: dense exponentials with a
        // rigorous bound
        let (points, bound) = expm::transient_dense(chain, times);
        if bound > options.tolerance.max(DENSE_TOLERANCE) {
            return Err(AnalysisError::Numerical {
                node: name.to_string(),
                what: format!("the error bound {bound:.1e} of the stiff solver is too large"),
            });
        }
        points
    } else {
        return Err(AnalysisError::Stiff {
            node: name.to_string(),
            work,
            limit: options.max_work,
        });
    };
    for p in &points {
        if ![p.success, p.failure, p.running]
            .iter()
            .all(|x| x.is_finite())
        {
            return Err(AnalysisError::Numerical {
                node: name.to_string(),
                what: format!("non-finite probability at t = {}", p.t),
            });
        }
    }
    Ok(points)
}
