//! Exact derivatives of the root's figures by forward-mode dual numbers.
//!
//! Every node is summarised by `[P(S), P(F), E[T·1S], E[T·1F]]` (the time
//! integrals rather than MTTS/MTTF, so that no division by a probability is
//! needed below the root), each a dual number `(value, tangent)` along one
//! leaf parameter. The tangent starts at the leaf (`d ps = 1`, `d pf = −1`,
//! `d E[T·1S] = mean_S`, ...; a rate or time moves the mean of its outcome)
//! and goes up the path to the root; every other node on the way is a
//! constant. Each node's map is differentiated exactly:
//!
//! * Sequence, Fallback, Retry N, Repeat N (their MRG's DTMC) and flows (the
//!   DTMC over their states): the absorption `h(i) = Σ_e p_e h(to_e)` and
//!   the time integrals `g(i) = Σ_e (W_e h(to_e) + p_e g(to_e))` (with
//!   `W_e = p_e·d_e` the child's `E[T·1{outcome}]`) are evaluated backwards
//!   over the acyclic chain in dual numbers — the same as
//!   `dx = (I − Q)⁻¹(dr + dQ·x)` for the solve;
//! * inverter, force_success/force_failure, until_success/until_failure:
//!   their closed forms (e.g. `E[T·1F]` of until_failure is
//!   `(E[T·1S] + E[T·1F]) / pf` of the child);
//! * a Parallel solved as a product phase chain (any thresholds; or
//!   conditions only): the absorption of its chain rebuilt in dual numbers
//!   (`sensitivity::chain`);
//! * a counted Parallel (the book's thresholds `F ≥ N − M + 1`, strategy
//!   `exact`): P(S), P(F) by the count programme, which is multilinear in
//!   the children's ps/pf and run in dual numbers
//!   ([`status_and_densities_by_counts`]); its mean times by the count
//!   quadrature in dual numbers when every child has a phase chain
//!   (`sensitivity::chain::counted_means`), else NaN.
//!
//! Anything else (a race over deterministic, hybrid or shifted leaves,
//! strategy `book`'s Parallels) gives no tangent or a NaN one, and the row
//! falls back to Richardson.

use crate::compile::counts::status_and_densities_by_counts;
use crate::compile::mrg::{Mrg, Outcome, Policy, Status};
use crate::compile::{Analysis, Figures, Method, Plan, Representation};

pub(crate) use super::chain::Grids;
use super::chain::{self, success_by, Ctx};
use crate::ir::{FlowGraph, Graph, Leaf, Op};
use crate::tree::{Duration, FlowNext, NodeId};

pub(crate) use super::dual::D;
use super::Param;

/// `[P(S), P(F), E[T·1S], E[T·1F]]` of a node, in dual numbers.
pub(crate) type Node = [D; 4];

fn constant(f: &Figures) -> Node {
    [
        D::c(f.ps),
        D::c(f.pf),
        D::c(f.ps * f.mtts.unwrap_or(0.0)),
        D::c(f.pf * f.mttf.unwrap_or(0.0)),
    ]
}

/// `(d mean / d rate, d mean / d cap)` of a duration, where defined.
fn mean_derivatives(d: &Duration) -> (f64, f64) {
    match *d {
        Duration::Exponential { rate } => (-1.0 / (rate * rate), 0.0),
        Duration::TruncatedExponential { rate, cap } => {
            let e = (-rate * cap).exp();
            // mean = (1 − e^{−λc})/λ
            (cap * e / rate + (-rate * cap).exp_m1() / (rate * rate), e)
        }
        Duration::Fixed { .. } | Duration::PhaseType { .. } => (0.0, 0.0),
    }
}

/// The tangent of a leaf's node along one of its parameters.
fn leaf_tangent(kind: &Op, f: &Figures, param: Param) -> Option<Node> {
    let mut n = constant(f);
    match kind {
        Op::Leaf(Leaf::Condition { .. }) => {
            n[0].d = 1.0;
            n[1].d = -1.0;
        }
        Op::Leaf(Leaf::Action(a)) => {
            let ms = a.success.map_or(0.0, |d| d.mean());
            let mf = a.failure.map_or(0.0, |d| d.mean());
            // the values from the parameters themselves (a mean defined at
            // ps = 0 too)
            n[2].v = a.ps * ms;
            n[3].v = a.pf * mf;
            let (dms, dmf) = match param {
                Param::Ps => {
                    n[0].d = 1.0;
                    n[1].d = -1.0;
                    n[2].d = ms;
                    n[3].d = -mf;
                    return Some(n);
                }
                Param::Mu => (mean_derivatives(a.success.as_ref()?).0, 0.0),
                Param::Nu => (0.0, mean_derivatives(a.failure.as_ref()?).0),
                Param::TauS | Param::TauF => {
                    let (own, other) = if param == Param::TauS {
                        (a.success, a.failure)
                    } else {
                        (a.failure, a.success)
                    };
                    let d_own = match own? {
                        Duration::Fixed { .. } | Duration::PhaseType { .. } => 1.0,
                        _ => 0.0,
                    };
                    let d_other = match other {
                        Some(d @ Duration::TruncatedExponential { .. }) => mean_derivatives(&d).1,
                        _ => 0.0,
                    };
                    if param == Param::TauS {
                        (d_own, d_other)
                    } else {
                        (d_other, d_own)
                    }
                }
                Param::StageRate(success)
                | Param::Branch(success)
                | Param::Rate1(success)
                | Param::Rate2(success) => {
                    let own = if success { a.success } else { a.failure };
                    let (_, law) = super::StageLaw::of(own.as_ref()?)?;
                    let d = law.mean_derivative(param)?;
                    if success {
                        (d, 0.0)
                    } else {
                        (0.0, d)
                    }
                }
            };
            n[2].d = a.ps * dms;
            n[3].d = a.pf * dmf;
        }
        _ => return None,
    }
    Some(n)
}

/// One transition of an acyclic chain whose edges are children's outcomes.
struct Step {
    from: usize,
    child: usize,
    success: bool,
    to: FlowNext,
}

/// The node's `[P(S), P(F), E[T·1S], E[T·1F]]` from state 0 of the chain
/// with `n` states (every step goes forward).
fn absorb(n: usize, steps: &[Step], children: &[Node]) -> Option<Node> {
    // per state: [h_S, h_F, g_S, g_F]
    let mut at: Vec<Node> = vec![[D::ZERO; 4]; n];
    let mut order: Vec<usize> = (0..steps.len()).collect();
    order.sort_by_key(|&i| std::cmp::Reverse(steps[i].from));
    for i in order {
        let s = &steps[i];
        let next = match s.to {
            FlowNext::State(j) if j > s.from && j < n => at[j],
            FlowNext::State(_) => return None,
            FlowNext::Success => [D::ONE, D::ZERO, D::ZERO, D::ZERO],
            FlowNext::Failure => [D::ZERO, D::ONE, D::ZERO, D::ZERO],
        };
        let c = &children[s.child];
        let (p, w) = if s.success {
            (c[0], c[2])
        } else {
            (c[1], c[3])
        };
        let h = &mut at[s.from];
        h[0] = h[0].add(p.mul(next[0]));
        h[1] = h[1].add(p.mul(next[1]));
        h[2] = h[2].add(w.mul(next[0])).add(p.mul(next[2]));
        h[3] = h[3].add(w.mul(next[1])).add(p.mul(next[3]));
    }
    Some(at[0])
}

/// The steps of an MRG (Sequence/Fallback of `n` children), markings
/// renumbered densely as in the engine's chain.
fn mrg_steps(policy: Policy, n: usize) -> (usize, Vec<Step>) {
    let g = Mrg::build(policy, n);
    let mut dense = vec![usize::MAX; g.status.len()];
    let mut k = 0;
    for (i, s) in g.status.iter().enumerate() {
        if *s == Status::Running {
            dense[i] = k;
            k += 1;
        }
    }
    let steps = g
        .events
        .iter()
        .map(|e| Step {
            from: dense[e.from],
            child: e.child,
            success: e.outcome == Outcome::Success,
            to: match g.status[e.to] {
                Status::Running => FlowNext::State(dense[e.to]),
                Status::Success => FlowNext::Success,
                Status::Failure => FlowNext::Failure,
            },
        })
        .collect();
    (k, steps)
}

const NAN: D = D {
    v: f64::NAN,
    d: f64::NAN,
};

/// Node `id`'s dual figures from its children's (in child order);
/// `None` where the node's map has no exact tangent at all.
fn node_map(
    tree: &Graph,
    id: NodeId,
    method: Method,
    fig: &Figures,
    children: &[Node],
    ctx: &mut Ctx,
) -> Option<Node> {
    let kind = &tree.node(id).kind;
    Some(match kind {
        Op::Leaf(_) => return None,
        Op::Flow(flow) => match flow.graph {
            FlowGraph::Chain { stop } => {
                let (n, steps) = mrg_steps(Policy::stopping_at(stop), children.len());
                absorb(n, &steps, children)?
            }
            FlowGraph::Repeat { times, stop } => {
                let (k, steps) = mrg_steps(Policy::stopping_at(stop), times);
                absorb(k, &steps, &vec![children[0]; times])?
            }
            FlowGraph::States(ref states) => {
                let steps: Vec<Step> = states
                    .iter()
                    .enumerate()
                    .flat_map(|(i, s)| {
                        [(true, s.on_success), (false, s.on_failure)].map(|(success, to)| Step {
                            from: i,
                            child: s.child,
                            success,
                            to,
                        })
                    })
                    .collect();
                absorb(states.len(), &steps, children)?
            }
        },
        // the child's runs that return (a child may never return) go where
        // the map sends them
        Op::Map {
            on_success,
            on_failure,
            ..
        } => {
            let c = children[0];
            let mut out = [D::ZERO; 4];
            for (to, p, t) in [(*on_success, c[0], c[2]), (*on_failure, c[1], c[3])] {
                out[to.index()] = out[to.index()].add(p);
                out[2 + to.index()] = out[2 + to.index()].add(t);
            }
            out
        }
        // E[T] of the loop = (E[T·1S] + E[T·1F]) / p_end of the child
        Op::Loop { until, .. } => {
            let c = children[0];
            match until {
                Outcome::Failure => [D::ZERO, D::ONE, D::ZERO, c[2].add(c[3]).div(c[1])],
                Outcome::Success => [D::ONE, D::ZERO, c[2].add(c[3]).div(c[0]), D::ZERO],
            }
        }
        Op::KOfN {
            success: m,
            failure: f,
            children: ids,
        } => {
            let n = ids.len();
            if method != Method::Exact {
                return None;
            }
            // a product phase chain (or instantaneous outcomes only, the
            // atoms of conditions): its absorption in dual numbers
            if matches!(
                ctx.plan.representation(id).ok()?,
                Representation::Chain | Representation::Atoms
            ) {
                if let Some(c) = ctx.chain(id) {
                    return chain::absorb(&c);
                }
            }
            if *f <= n - m {
                return None;
            }
            let points: Vec<[f64; 4]> = children
                .iter()
                .map(|c| [c[0].v, c[1].v, c[0].d, c[1].d])
                .collect();
            let [s, fl, ds, df] = status_and_densities_by_counts(&points, *m, n + 1 - m);
            let mut out = constant(fig);
            out[0] = D { v: s, d: ds };
            out[1] = D { v: fl, d: df };
            // the mean times: the count quadrature in dual numbers, when the
            // children have chains (else unknown: NaN)
            let path = ids.iter().position(|&c| ctx.on_path[c])?;
            match chain::counted_means(ctx, id, *m, path) {
                Some([ts, tf]) => {
                    out[2] = ts;
                    out[3] = tf;
                }
                None => {
                    out[2].d = NAN.d;
                    out[3].d = NAN.d;
                }
            }
            out
        }
    })
}

/// The tangent of the root's `[P(S), P(F), E[T·1S], E[T·1F]]` along leaf
/// `leaf`'s parameter `param`, from the analysis of `tree` (a primitive
/// tree). `None` where some node on the path has no exact map, or where
/// the dual values disagree with the engine's figures (then the caller
/// differences instead). A component whose tangent is unknown is NaN.
pub(crate) fn root_tangent(
    plan: &Plan,
    grids: &Grids,
    analysis: &Analysis,
    leaf: NodeId,
    param: Param,
) -> Option<Node> {
    let tree = plan.tree();
    let mut ctx = Ctx::new(plan, grids, leaf, param);
    let mut node = leaf_tangent(&tree.node(leaf).kind, &analysis.nodes[leaf], param)?;
    let mut id = leaf;
    while let Some(parent) = tree.node(id).parent {
        let kids: Vec<Node> = tree
            .node(parent)
            .kind
            .children()
            .iter()
            .map(|&c| {
                if c == id {
                    node
                } else {
                    constant(&analysis.nodes[c])
                }
            })
            .collect();
        let fig = &analysis.nodes[parent];
        node = node_map(tree, parent, analysis.method, fig, &kids, &mut ctx)?;
        // the dual values must be the engine's figures (a check of the map)
        let engine = constant(fig);
        for (a, b) in node.iter().zip(engine.iter()) {
            if (a.v - b.v).abs() > 1e-9 * b.v.abs().max(1.0) {
                return None;
            }
        }
        id = parent;
    }
    Some(node)
}

/// The tangent of the root's `P(Success by t)` along leaf `leaf`'s
/// `param`, when the root is a phase chain (every leaf below exponential,
/// Erlang or hypoexponential, or a condition; the chain within the
/// budget): uniformisation of the doubled chain (`sensitivity::chain`).
/// `None` otherwise (a deterministic time's atoms among them).
pub(crate) fn success_by_tangent(
    plan: &Plan,
    grids: &Grids,
    leaf: NodeId,
    param: Param,
    t: f64,
    max_work: f64,
) -> Option<D> {
    if !matches!(
        plan.representation(0).ok()?,
        Representation::Chain | Representation::Closed | Representation::Atoms
    ) {
        return None;
    }
    let mut ctx = Ctx::new(plan, grids, leaf, param);
    success_by(&ctx.chain(0)?, t, max_work)
}
