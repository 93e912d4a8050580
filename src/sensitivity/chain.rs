//! Exact derivatives through phase chains: the engine's chain of a subtree
//! rebuilt in dual numbers (value, derivative along one leaf parameter),
//! then solved in dual numbers.
//!
//! * **The tangent chain.** Every rate and initial probability of a phase
//!   chain is built from the leaves' parameters by sums and products
//!   (`compile::phase`: an action's two-phase mixture, the concatenation
//!   of a Sequence/Fallback/retry/repeat, the glue of a flow, the unrolled
//!   loop, the product of a Parallel). The same constructions run here on
//!   dual numbers: the leaf on the path carries its tangent (`d ps = 1`,
//!   `d pf = −1`, `d mu = 1`, ...), subtrees off the path are the engine's
//!   own chains (`Plan::chain`, tangent zero). An entry whose value is 0 but
//!   whose tangent is not (a leaf at `ps = 0`) is kept, so one-sided
//!   derivatives at the boundary are exact too.
//! * **Absorption** (P(S), P(F), E\[T·1S\], E\[T·1F\]): the chain is acyclic
//!   and topologically ordered, so `(−T) h = s` is a backward substitution;
//!   run in dual numbers it is exactly `dh = (−T)⁻¹(ds + dT·h)` with the
//!   same (triangular) factorisation, one extra pass per parameter. (The
//!   adjoint — one transposed solve for all parameters — would not be
//!   cheaper here: `dT` itself has to be built per parameter, which costs
//!   as much as the forward pass.)
//! * **Transient probabilities** (`P(Success by t)`): uniformisation of the
//!   doubled chain `[[Q, dQ], [0, Q]]` — the derivative of `α e^{Qt}` along
//!   `dQ` is its upper-right block — i.e. the series `Σ_k Pois(k; Λt) s_k`
//!   differentiated term by term with the uniformisation rate Λ held fixed
//!   (`dP = dQ/Λ`): `v_{k+1} = v_k P`, `dv_{k+1} = dv_k P + v_k dP`, and
//!   `s_k` (mass absorbed in Success after k steps) likewise. The Poisson
//!   window drops mass ≤ 1e-14; `|ds_k| ≤ |dα|₁ + k‖dP‖`, so the dropped
//!   part of the derivative is below 1e-14·(|dα|₁ + k_max‖dP‖).
//!
//! Size: one concern, the engine's chain rebuilt in dual numbers: each node
//! kind's chain, their products and the dual solves (about 100 lines are
//! comments).

use super::dual::D;
use super::Param;
use crate::compile::counts::pending_by_counts;
use crate::compile::mrg::{Policy, Status};
use crate::compile::plan::Plan;
use crate::ir::{Flow, FlowGraph, Graph, Leaf, Op, Outcome};
use crate::solve::chain::PhaseChain;
use crate::solve::quadrature::GaussLegendre;
use crate::solve::transient::{
    absorption_by_phase, poisson_window, transient, uniformization_work,
};
use crate::tree::{Duration, FlowNext, NodeId};
use std::cell::RefCell;
use std::collections::HashMap;
use std::rc::Rc;

/// A phase chain in dual numbers (the fields of [`PhaseChain`]).
#[derive(Debug, Clone, Default)]
pub(crate) struct DChain {
    pub initial: Vec<(usize, D)>,
    pub initial_success: D,
    pub initial_failure: D,
    pub transitions: Vec<Vec<(usize, D)>>,
    pub exit_success: Vec<D>,
    pub exit_failure: Vec<D>,
}

/// Whether an entry matters: a nonzero value or tangent (the engine keeps
/// entries with a positive value).
fn nz(x: D) -> bool {
    x.v != 0.0 || x.d != 0.0
}

impl DChain {
    fn constant(c: &PhaseChain) -> DChain {
        let k = |v: &[(usize, f64)]| v.iter().map(|&(j, p)| (j, D::c(p))).collect();
        DChain {
            initial: k(&c.initial),
            initial_success: D::c(c.initial_success),
            initial_failure: D::c(c.initial_failure),
            transitions: c.transitions.iter().map(|r| k(r)).collect(),
            exit_success: c.exit_success.iter().map(|&r| D::c(r)).collect(),
            exit_failure: c.exit_failure.iter().map(|&r| D::c(r)).collect(),
        }
    }

    /// The values alone.
    fn value(&self) -> PhaseChain {
        let k = |v: &[(usize, D)]| v.iter().map(|&(j, p)| (j, p.v)).collect();
        PhaseChain {
            initial: k(&self.initial),
            initial_success: self.initial_success.v,
            initial_failure: self.initial_failure.v,
            transitions: self.transitions.iter().map(|r| k(r)).collect(),
            exit_success: self.exit_success.iter().map(|r| r.v).collect(),
            exit_failure: self.exit_failure.iter().map(|r| r.v).collect(),
        }
    }

    pub fn len(&self) -> usize {
        self.exit_success.len()
    }

    fn push_phase(&mut self) -> usize {
        self.transitions.push(Vec::new());
        self.exit_success.push(D::ZERO);
        self.exit_failure.push(D::ZERO);
        self.len() - 1
    }

    fn total_rate(&self, i: usize) -> D {
        self.transitions[i].iter().fold(
            self.exit_success[i].add(self.exit_failure[i]),
            |a, &(_, r)| a.add(r),
        )
    }

    fn nnz(&self) -> usize {
        self.transitions.iter().map(Vec::len).sum::<usize>() + 2 * self.len()
    }
}

/// What the dual chain is built for: one leaf parameter, and the chain of
/// one node on the path already built (reused by the nodes above it).
pub(crate) struct Ctx<'a, 'p> {
    pub plan: &'a Plan<'p>,
    pub leaf: NodeId,
    pub param: Param,
    /// Ancestors-or-self of the leaf.
    pub on_path: Vec<bool>,
    pub cache: Option<(NodeId, DChain)>,
    /// Quadrature grids of counted Parallels, shared across parameters.
    pub grids: &'a Grids,
}

/// Quadrature grids of counted Parallels by node (`None`: none possible).
pub(crate) type Grids = RefCell<HashMap<NodeId, Option<Rc<CountedGrid>>>>;

impl<'a, 'p> Ctx<'a, 'p> {
    pub fn new(plan: &'a Plan<'p>, grids: &'a Grids, leaf: NodeId, param: Param) -> Ctx<'a, 'p> {
        let tree = plan.tree();
        let mut on_path = vec![false; tree.nodes.len()];
        let mut n = Some(leaf);
        while let Some(id) = n {
            on_path[id] = true;
            n = tree.node(id).parent;
        }
        Ctx {
            plan,
            leaf,
            param,
            on_path,
            cache: None,
            grids,
        }
    }

    /// The dual chain of node `id` (on the path), kept for the next call.
    pub fn chain(&mut self, id: NodeId) -> Option<DChain> {
        let c = self.build(id)?;
        self.cache = Some((id, c.clone()));
        Some(c)
    }

    fn build(&mut self, id: NodeId) -> Option<DChain> {
        if let Some((cid, c)) = &self.cache {
            if *cid == id {
                return Some(c.clone());
            }
        }
        let tree = self.plan.tree();
        if !self.on_path[id] {
            // off the path: its chain where its size is within the budget
            if !self.plan.chain_size(id).ok()?.fits() {
                return None;
            }
            return self.plan.chain(id).ok().map(|c| DChain::constant(&c));
        }
        let max_states = self.plan.max_states();
        let node = tree.node(id);
        if id == self.leaf {
            return leaf_chain(&node.kind, self.param, max_states);
        }
        let chains = node
            .kind
            .children()
            .iter()
            .map(|&c| self.build(c))
            .collect::<Option<Vec<_>>>()?;
        combine(tree, id, chains, max_states)
    }
}

/// The dual chain of a leaf along its own parameter (`compile::phase::chain_of`).
fn leaf_chain(kind: &Op, param: Param, max_states: usize) -> Option<DChain> {
    // a stage law's parameters move the stages themselves: not rebuilt in
    // dual numbers here (differences instead)
    if param.of_stages() {
        return None;
    }
    match kind {
        Op::Leaf(Leaf::Condition { ps }) => Some(DChain {
            initial_success: D { v: *ps, d: 1.0 },
            initial_failure: D {
                v: 1.0 - ps,
                d: -1.0,
            },
            ..DChain::default()
        }),
        Op::Leaf(Leaf::Action(a)) => {
            let mut c = DChain::default();
            let dps = if param == Param::Ps { 1.0 } else { 0.0 };
            for (p, d, success) in [
                (D { v: a.ps, d: dps }, a.success, true),
                (D { v: a.pf, d: -dps }, a.failure, false),
            ] {
                if !nz(p) {
                    continue;
                }
                let d = d?;
                if let Duration::Fixed { time: 0.0 } = d {
                    if matches!(param, Param::TauS | Param::TauF) {
                        // a zero time moved off zero is no phase chain
                        return None;
                    }
                    if success {
                        c.initial_success = c.initial_success.add(p);
                    } else {
                        c.initial_failure = c.initial_failure.add(p);
                    }
                    continue;
                }
                // stages in series (exponential, Erlang, hypoexponential);
                // a general phase-type law is not differentiated here
                let rates = match d {
                    Duration::Exponential { rate } => vec![rate],
                    Duration::PhaseType { shift: 0.0, stages } if stages.as_general().is_none() => {
                        stages.series()
                    }
                    _ => return None,
                };
                // the rate parameter of an exponential outcome
                let own = if success { Param::Mu } else { Param::Nu };
                let d_rate = match d {
                    Duration::Exponential { .. } if param == own => 1.0,
                    _ => 0.0,
                };
                if c.len() + rates.len() > max_states {
                    return None;
                }
                let first = c.len();
                for (j, &rate) in rates.iter().enumerate() {
                    let r = D { v: rate, d: d_rate };
                    let i = c.push_phase();
                    if j + 1 < rates.len() {
                        c.transitions[i].push((i + 1, r));
                    } else if success {
                        c.exit_success[i] = r;
                    } else {
                        c.exit_failure[i] = r;
                    }
                }
                c.initial.push((first, p));
            }
            Some(c)
        }
        _ => None,
    }
}

/// `compile::phase::combine` in dual numbers.
fn combine(tree: &Graph, id: NodeId, chains: Vec<DChain>, max_states: usize) -> Option<DChain> {
    let node = tree.node(id);
    match &node.kind {
        Op::Leaf(_) => None,
        Op::Flow(flow) => match flow.graph {
            FlowGraph::Chain { stop } => {
                let total: usize = chains.iter().map(DChain::len).sum();
                if total > max_states {
                    return None;
                }
                Some(concatenate(chains, stop == Outcome::Failure))
            }
            FlowGraph::Repeat { times, stop } => {
                let c = chains.into_iter().next()?;
                if c.len() as f64 * times as f64 > max_states as f64 {
                    return None;
                }
                Some(concatenate(vec![c; times], stop == Outcome::Failure))
            }
            FlowGraph::States(_) => {
                let total: usize = (0..flow.state_count())
                    .map(|i| chains[flow.state(i).child].len())
                    .sum();
                if total > max_states {
                    return None;
                }
                Some(glue(flow, &chains))
            }
        },
        Op::Map {
            on_success,
            on_failure,
            ..
        } => Some(map_outcomes(
            chains.into_iter().next()?,
            *on_success,
            *on_failure,
        )),
        Op::Loop { until, .. } => unrolled_loop(
            chains.into_iter().next()?,
            *until == Outcome::Success,
            max_states,
        ),
        Op::KOfN { .. } => {
            let policy = Policy::of(&node.kind)?;
            product(&chains, policy, max_states)
        }
    }
}

/// Every exit (and instantaneous outcome) made a Success (Failure).
fn force(c: DChain, success: bool) -> DChain {
    let to = if success {
        Outcome::Success
    } else {
        Outcome::Failure
    };
    map_outcomes(c, to, to)
}

/// A chain whose exits to Success lead to `on_success` and whose exits to
/// Failure lead to `on_failure` (`compile::phase`'s rule).
fn map_outcomes(mut c: DChain, on_success: Outcome, on_failure: Outcome) -> DChain {
    let map = |s: D, f: D| {
        let mut out = [D::ZERO; 2];
        out[on_success.index()] = out[on_success.index()].add(s);
        out[on_failure.index()] = out[on_failure.index()].add(f);
        (out[0], out[1])
    };
    for i in 0..c.len() {
        (c.exit_success[i], c.exit_failure[i]) = map(c.exit_success[i], c.exit_failure[i]);
    }
    (c.initial_success, c.initial_failure) = map(c.initial_success, c.initial_failure);
    c
}

/// `compile::phase::unrolled_loop` in dual numbers: the same number of
/// copies (from the values), so the same truncation (≤ 1e-14).
fn unrolled_loop(c: DChain, until_success: bool, max_states: usize) -> Option<DChain> {
    let value = c.value();
    let absorption = absorption_by_phase(&value);
    let from_start = |h: &[f64]| value.initial.iter().map(|&(i, p)| p * h[i]).sum::<f64>();
    let success = value.initial_success + from_start(&absorption.to_success);
    let failure = value.initial_failure + from_start(&absorption.to_failure);
    let (again, end) = if until_success {
        (failure, success)
    } else {
        (success, failure)
    };
    if end <= 0.0 {
        return None;
    }
    if c.len() == 0 || again <= 0.0 {
        return Some(force(c, until_success));
    }
    let copies = (crate::compile::phase::LOOP_TAIL.ln() / again.min(1.0 - 1e-300).ln())
        .ceil()
        .max(1.0);
    if copies * c.len() as f64 > max_states as f64 {
        return None;
    }
    Some(force(
        concatenate(vec![c; copies as usize], !until_success),
        until_success,
    ))
}

/// "Where a run goes next".
#[derive(Debug, Clone, Default)]
struct Entry {
    states: Vec<(usize, D)>,
    success: D,
    failure: D,
}

impl Entry {
    fn outcome(success: bool) -> Entry {
        Entry {
            states: Vec::new(),
            success: if success { D::ONE } else { D::ZERO },
            failure: if success { D::ZERO } else { D::ONE },
        }
    }

    fn add_scaled(&mut self, other: &Entry, w: D) {
        if !nz(w) {
            return;
        }
        self.states
            .extend(other.states.iter().map(|&(j, p)| (j, p.mul(w))));
        self.success = self.success.add(other.success.mul(w));
        self.failure = self.failure.add(other.failure.mul(w));
    }
}

/// Routes exit `rate` of phase `g` to `to` (phases, or outcomes).
fn route(out: &mut DChain, g: usize, rate: D, to: &Entry) {
    if !nz(rate) {
        return;
    }
    out.transitions[g].extend(to.states.iter().map(|&(j, w)| (j, rate.mul(w))));
    out.exit_success[g] = out.exit_success[g].add(rate.mul(to.success));
    out.exit_failure[g] = out.exit_failure[g].add(rate.mul(to.failure));
}

fn with_phases(total: usize) -> DChain {
    DChain {
        transitions: vec![Vec::new(); total],
        exit_success: vec![D::ZERO; total],
        exit_failure: vec![D::ZERO; total],
        ..DChain::default()
    }
}

/// `compile::phase::concatenate` in dual numbers.
fn concatenate(chains: Vec<DChain>, sequence: bool) -> DChain {
    let mut offsets = Vec::with_capacity(chains.len());
    let mut total = 0;
    for c in &chains {
        offsets.push(total);
        total += c.len();
    }
    let mut out = with_phases(total);
    let mut next = Entry::outcome(sequence);
    let stop_outcome = Entry::outcome(!sequence);
    for (k, c) in chains.iter().enumerate().rev() {
        let off = offsets[k];
        for i in 0..c.len() {
            let gi = off + i;
            out.transitions[gi].extend(c.transitions[i].iter().map(|&(j, r)| (off + j, r)));
            let (cont, stop) = if sequence {
                (c.exit_success[i], c.exit_failure[i])
            } else {
                (c.exit_failure[i], c.exit_success[i])
            };
            route(&mut out, gi, stop, &stop_outcome);
            route(&mut out, gi, cont, &next);
        }
        let (cont0, stop0) = if sequence {
            (c.initial_success, c.initial_failure)
        } else {
            (c.initial_failure, c.initial_success)
        };
        let mut entry = Entry {
            states: c.initial.iter().map(|&(j, p)| (off + j, p)).collect(),
            ..Entry::default()
        };
        entry.add_scaled(&stop_outcome, stop0);
        entry.add_scaled(&next, cont0);
        next = entry;
    }
    out.initial = next.states;
    out.initial_success = next.success;
    out.initial_failure = next.failure;
    out
}

/// `compile::flow::glue` in dual numbers.
fn glue(flow: &Flow, chains: &[DChain]) -> DChain {
    let states = flow.states();
    let mut offsets = Vec::with_capacity(states.len());
    let mut total = 0;
    for s in states.iter() {
        offsets.push(total);
        total += chains[s.child].len();
    }
    let mut out = with_phases(total);
    let ends = [Entry::outcome(true), Entry::outcome(false)];
    let mut entries = vec![Entry::default(); states.len()];
    let next = |entries: &[Entry], n: FlowNext| match n {
        FlowNext::State(j) => entries[j].clone(),
        FlowNext::Success => ends[0].clone(),
        FlowNext::Failure => ends[1].clone(),
    };
    for (i, s) in states.iter().enumerate().rev() {
        let c = &chains[s.child];
        let off = offsets[i];
        let on_s = next(&entries, s.on_success);
        let on_f = next(&entries, s.on_failure);
        for k in 0..c.len() {
            let g = off + k;
            out.transitions[g].extend(c.transitions[k].iter().map(|&(j, r)| (off + j, r)));
            route(&mut out, g, c.exit_success[k], &on_s);
            route(&mut out, g, c.exit_failure[k], &on_f);
        }
        let mut entry = Entry {
            states: c.initial.iter().map(|&(j, p)| (off + j, p)).collect(),
            ..Entry::default()
        };
        entry.add_scaled(&on_s, c.initial_success);
        entry.add_scaled(&on_f, c.initial_failure);
        entries[i] = entry;
    }
    let start = std::mem::take(&mut entries[0]);
    out.initial = start.states;
    out.initial_success = start.success;
    out.initial_failure = start.failure;
    out
}

const SUCCEEDED: u32 = u32::MAX - 1;
const FAILED: u32 = u32::MAX;

/// `compile::phase::product` in dual numbers: the reachable tuples of the
/// children's local states, renumbered by rank (topological).
fn product(chains: &[DChain], policy: Policy, max_states: usize) -> Option<DChain> {
    let n = chains.len();
    let bound: f64 = chains.iter().map(|c| (c.len() + 2) as f64).product();
    if bound > 16.0 * max_states as f64 {
        return None;
    }
    let status_of = |key: &[u32]| {
        let s = key.iter().filter(|&&x| x == SUCCEEDED).count();
        let f = key.iter().filter(|&&x| x == FAILED).count();
        policy.status(n, s, f)
    };
    let rank = |key: &[u32]| -> u64 {
        key.iter()
            .zip(chains)
            .map(|(&x, c)| {
                if x >= SUCCEEDED {
                    c.len() as u64 + 1
                } else {
                    x as u64 + 1
                }
            })
            .sum()
    };
    let mut keys: Vec<Box<[u32]>> = Vec::new();
    let mut index: HashMap<Box<[u32]>, usize> = HashMap::new();
    let mut out = DChain::default();
    let mut intern = |key: Box<[u32]>, keys: &mut Vec<Box<[u32]>>, out: &mut DChain| {
        if let Some(&i) = index.get(&key) {
            return Some(i);
        }
        if keys.len() >= max_states {
            return None;
        }
        let i = out.push_phase();
        keys.push(key.clone());
        index.insert(key, i);
        Some(i)
    };
    let mut partial: Vec<(Vec<u32>, D)> = vec![(Vec::with_capacity(n), D::ONE)];
    for c in chains {
        let mut next = Vec::new();
        for (key, p) in &partial {
            let mut options: Vec<(u32, D)> =
                c.initial.iter().map(|&(j, q)| (j as u32, q)).collect();
            options.push((SUCCEEDED, c.initial_success));
            options.push((FAILED, c.initial_failure));
            for (x, q) in options {
                if !nz(q) {
                    continue;
                }
                let mut k = key.clone();
                k.push(x);
                let w = p.mul(q);
                match status_of(&k) {
                    Status::Success => out.initial_success = out.initial_success.add(w),
                    Status::Failure => out.initial_failure = out.initial_failure.add(w),
                    Status::Running => next.push((k, w)),
                }
            }
        }
        partial = next;
        if partial.len() > max_states.saturating_mul(4) {
            return None;
        }
    }
    for (key, p) in partial {
        let i = intern(key.into_boxed_slice(), &mut keys, &mut out)?;
        out.initial.push((i, p));
    }
    let mut next = 0;
    while next < keys.len() {
        let key = keys[next].clone();
        for (h, c) in chains.iter().enumerate() {
            let x = key[h];
            if x >= SUCCEEDED {
                continue;
            }
            let p = x as usize;
            let mut moves: Vec<(u32, D)> = c.transitions[p]
                .iter()
                .map(|&(j, r)| (j as u32, r))
                .collect();
            moves.push((SUCCEEDED, c.exit_success[p]));
            moves.push((FAILED, c.exit_failure[p]));
            for (y, r) in moves {
                if !nz(r) {
                    continue;
                }
                let mut k = key.clone();
                k[h] = y;
                match status_of(&k) {
                    Status::Success => out.exit_success[next] = out.exit_success[next].add(r),
                    Status::Failure => out.exit_failure[next] = out.exit_failure[next].add(r),
                    Status::Running => {
                        let j = intern(k, &mut keys, &mut out)?;
                        out.transitions[next].push((j, r));
                    }
                }
            }
        }
        next += 1;
    }
    let mut order: Vec<usize> = (0..keys.len()).collect();
    order.sort_by_key(|&i| rank(&keys[i]));
    let mut new_index = vec![0usize; keys.len()];
    for (new, &old) in order.iter().enumerate() {
        new_index[old] = new;
    }
    let mut sorted = DChain {
        initial: out
            .initial
            .iter()
            .map(|&(i, p)| (new_index[i], p))
            .collect(),
        initial_success: out.initial_success,
        initial_failure: out.initial_failure,
        ..DChain::default()
    };
    for &old in &order {
        sorted.transitions.push(
            out.transitions[old]
                .iter()
                .map(|&(j, r)| (new_index[j], r))
                .collect(),
        );
        sorted.exit_success.push(out.exit_success[old]);
        sorted.exit_failure.push(out.exit_failure[old]);
    }
    Some(sorted)
}

/// `[P(S), P(F), E[T·1S], E[T·1F]]` of a dual chain from its start: the
/// backward substitution of the acyclic chain in dual numbers (module
/// docs). `None` for a phase without exits or a backward transition.
pub(crate) fn absorb(c: &DChain) -> Option<[D; 4]> {
    let n = c.len();
    let mut at = vec![[D::ZERO; 4]; n];
    for i in (0..n).rev() {
        let q = c.total_rate(i);
        if q.v <= 0.0 {
            return None;
        }
        let mut s = [c.exit_success[i], c.exit_failure[i], D::ZERO, D::ZERO];
        for &(j, r) in &c.transitions[i] {
            if j <= i {
                return None;
            }
            for (x, y) in s.iter_mut().zip(at[j]) {
                *x = x.add(r.mul(y));
            }
        }
        let hs = s[0].div(q);
        let hf = s[1].div(q);
        at[i] = [hs, hf, hs.add(s[2]).div(q), hf.add(s[3]).div(q)];
    }
    let mut out = [c.initial_success, c.initial_failure, D::ZERO, D::ZERO];
    for &(i, p) in &c.initial {
        for (x, y) in out.iter_mut().zip(at[i]) {
            *x = x.add(p.mul(y));
        }
    }
    Some(out)
}

/// Truncation of the Poisson weights in [`dual_curve`].
const WINDOW: f64 = 1e-14;

/// `[P(Success by t), P(Failure by t)]` of a dual chain at every time, by
/// uniformisation of the doubled chain (module docs): one pass to the
/// largest time, each time a Poisson-weighted sum of the absorbed masses.
/// `None` when it needs more than `max_work` operations.
pub(crate) fn dual_curve(c: &DChain, times: &[f64], max_work: f64) -> Option<Vec<[D; 2]>> {
    let n = c.len();
    let lambda = (0..n).map(|i| c.total_rate(i).v).fold(0.0, f64::max);
    if times.iter().any(|t| !(t.is_finite() && *t >= 0.0)) {
        return None;
    }
    let horizon = times.iter().copied().fold(0.0, f64::max);
    if n == 0 || lambda == 0.0 || horizon == 0.0 {
        return Some(vec![[c.initial_success, c.initial_failure]; times.len()]);
    }
    let windows: Vec<_> = times
        .iter()
        .map(|&t| poisson_window(lambda * t, WINDOW))
        .collect();
    let last = windows
        .iter()
        .map(|w| w.left + w.weights.len())
        .max()
        .unwrap_or(1);
    if 2.0 * last as f64 * c.nnz() as f64 > max_work {
        return None;
    }
    let inv = 1.0 / lambda;
    let stay: Vec<D> = (0..n)
        .map(|i| {
            let q = c.total_rate(i);
            D {
                v: 1.0 - q.v * inv,
                d: -q.d * inv,
            }
        })
        .collect();
    let (mut v, mut dv) = (vec![0.0; n], vec![0.0; n]);
    for &(i, p) in &c.initial {
        v[i] += p.v;
        dv[i] += p.d;
    }
    // absorbed masses after k steps: [s, ds, f, df]
    let mut absorbed = Vec::with_capacity(last);
    let mut a = [
        c.initial_success.v,
        c.initial_success.d,
        c.initial_failure.v,
        c.initial_failure.d,
    ];
    let (mut nv, mut ndv) = (vec![0.0; n], vec![0.0; n]);
    for k in 0..last {
        absorbed.push(a);
        if k + 1 == last {
            break;
        }
        nv.iter_mut().for_each(|x| *x = 0.0);
        ndv.iter_mut().for_each(|x| *x = 0.0);
        for i in 0..n {
            let (x, dx) = (v[i], dv[i]);
            if x == 0.0 && dx == 0.0 {
                continue;
            }
            nv[i] += x * stay[i].v;
            ndv[i] += dx * stay[i].v + x * stay[i].d;
            for &(j, r) in &c.transitions[i] {
                nv[j] += x * r.v * inv;
                ndv[j] += (dx * r.v + x * r.d) * inv;
            }
            let (es, ef) = (c.exit_success[i], c.exit_failure[i]);
            a[0] += x * es.v * inv;
            a[1] += (dx * es.v + x * es.d) * inv;
            a[2] += x * ef.v * inv;
            a[3] += (dx * ef.v + x * ef.d) * inv;
        }
        std::mem::swap(&mut v, &mut nv);
        std::mem::swap(&mut dv, &mut ndv);
    }
    Some(
        windows
            .iter()
            .map(|w| {
                let mut sum = [0.0; 4];
                for (j, &wk) in w.weights.iter().enumerate() {
                    for (x, y) in sum.iter_mut().zip(absorbed[w.left + j]) {
                        *x += wk * y;
                    }
                }
                [
                    D {
                        v: sum[0],
                        d: sum[1],
                    },
                    D {
                        v: sum[2],
                        d: sum[3],
                    },
                ]
            })
            .collect(),
    )
}

/// `P(Success by t)` of a dual chain ([`dual_curve`]).
pub(crate) fn success_by(c: &DChain, t: f64, max_work: f64) -> Option<D> {
    Some(dual_curve(c, &[t], max_work)?[0][0])
}

/// A counted Parallel's quadrature grid and its children's curves on it,
/// shared by every parameter below the node.
#[derive(Debug)]
pub(crate) struct CountedGrid {
    /// Quadrature nodes and their weights.
    nodes: Vec<f64>,
    weights: Vec<f64>,
    /// Per child: `(S_h(t), F_h(t))` at every node.
    curves: Vec<Vec<(f64, f64)>>,
    /// Per child: `(s_h, f_h)`, the probabilities of its outcomes.
    totals: Vec<(f64, f64)>,
    /// The node's `[E[T·1S], E[T·1F]]` on this grid.
    values: [f64; 2],
    /// Per child: its weighted partials (`CountedGrid::partials`).
    partials: RefCell<HashMap<usize, Rc<Partials>>>,
}

/// One child's weighted partials `∂g/∂(done, pending, never)` at every
/// node, for the Success and the Failure side.
type Partials = [Vec<[f64; 3]>; 2];

/// Points of the Gauss–Legendre rule per panel.
const RULE_POINTS: usize = 16;

impl CountedGrid {
    /// Composite Gauss–Legendre on panels growing by 30% from `0.1/ΣΛ_h`
    /// (as the engine's certified quadrature, `compile::counts`) to a
    /// horizon where every child has returned but for 1e-13, with the
    /// panels halved until the node's `E[T·1S] + E[T·1F]` moves by less than
    /// 1e-13 relative.
    fn new(chains: &[PhaseChain], m: usize, max_work: f64) -> Option<CountedGrid> {
        let totals: Vec<(f64, f64)> = chains
            .iter()
            .map(|c| {
                let a = absorption_by_phase(c);
                let start = |h: &[f64]| c.initial.iter().map(|&(i, p)| p * h[i]).sum::<f64>();
                (
                    c.initial_success + start(&a.to_success),
                    c.initial_failure + start(&a.to_failure),
                )
            })
            .collect();
        let rate = |c: &PhaseChain| (0..c.len()).map(|i| c.total_rate(i)).fold(0.0, f64::max);
        let lam_sum: f64 = chains.iter().map(rate).sum();
        if lam_sum == 0.0 {
            return None;
        }
        let curves_at = |times: &[f64]| -> Option<Vec<Vec<(f64, f64)>>> {
            chains
                .iter()
                .map(|c| {
                    if c.is_empty() {
                        return Some(vec![(c.initial_success, c.initial_failure); times.len()]);
                    }
                    if uniformization_work(c, times) > max_work {
                        return None;
                    }
                    Some(
                        transient(c, times, 1e-15)
                            .iter()
                            .map(|p| (p.success, p.failure))
                            .collect(),
                    )
                })
                .collect()
        };
        // the horizon: every child returned but for 1e-13 (the curves'
        // truncation is 1e-15 each)
        let mut horizon = 32.0
            / chains.iter().map(rate).fold(
                f64::INFINITY,
                |a, r| {
                    if r > 0.0 {
                        a.min(r)
                    } else {
                        a
                    }
                },
            );
        let mut done = false;
        for _ in 0..30 {
            let at = curves_at(&[horizon])?;
            let running: f64 = at.iter().map(|c| (1.0 - c[0].0 - c[0].1).max(0.0)).sum();
            if running <= 1e-13 {
                done = true;
                break;
            }
            horizon *= 1.5;
        }
        if !done {
            return None;
        }
        let mut ends = vec![0.0, 0.1 / lam_sum];
        while *ends.last()? < horizon {
            let last = *ends.last()?;
            ends.push(last * 1.3);
        }
        let rule = GaussLegendre::new(RULE_POINTS);
        let n = chains.len();
        let mut previous: Option<(f64, CountedGrid)> = None;
        for _ in 0..4 {
            let mut nodes = Vec::new();
            let mut weights = Vec::new();
            for p in 0..ends.len() - 1 {
                let (c, h) = ((ends[p] + ends[p + 1]) / 2.0, (ends[p + 1] - ends[p]) / 2.0);
                nodes.extend(rule.nodes.iter().map(|x| c + h * x));
                weights.extend(rule.weights.iter().map(|w| w * h));
            }
            let mut grid = CountedGrid {
                curves: curves_at(&nodes)?,
                nodes,
                weights,
                totals: totals.clone(),
                values: [0.0; 2],
                partials: RefCell::default(),
            };
            grid.values = [grid.integral(m, true), grid.integral(n + 1 - m, false)];
            let total = grid.values[0] + grid.values[1];
            if let Some((before, _)) = &previous {
                if (total - before).abs() <= 1e-13 * total.abs() {
                    return Some(grid);
                }
            }
            previous = Some((total, grid));
            ends = ends
                .windows(2)
                .flat_map(|w| [w[0], (w[0] + w[1]) / 2.0])
                .chain(ends.last().copied())
                .collect();
        }
        None
    }

    /// `∫ g` of one side (threshold `m`): `g(t) = P(K_t < m ≤ K_∞)` over
    /// the children's done / pending / never weights (`compile::counts`);
    /// with `unit = Some((h, j))` child `h`'s weights replaced by the `j`-th
    /// unit vector instead: the partial derivative of `g` in that weight
    /// (`g` is linear in each child's weights), per node, times its weight.
    fn terms(&self, m: usize, success: bool, unit: Option<(usize, usize)>) -> Vec<f64> {
        let side = |x: (f64, f64)| if success { x.0 } else { x.1 };
        let mut scratch = Vec::new();
        self.weights
            .iter()
            .enumerate()
            .map(|(k, w)| {
                let weights =
                    self.curves
                        .iter()
                        .zip(&self.totals)
                        .enumerate()
                        .map(|(h, (c, t))| {
                            let (done, total) = (side(c[k]), side(*t));
                            match unit {
                                Some((p, j)) if p == h => {
                                    let e = |i: usize| f64::from(u8::from(i == j));
                                    (e(0), e(1), e(2))
                                }
                                _ => (done, (total - done).max(0.0), 1.0 - total),
                            }
                        });
                w * pending_by_counts(weights, m, &mut scratch)
            })
            .collect()
    }

    fn integral(&self, m: usize, success: bool) -> f64 {
        self.terms(m, success, None).iter().sum()
    }

    /// Child `h`'s weighted partials `∂g/∂(done, pending, never)` at every
    /// node, per side (computed once per child, shared by the parameters
    /// below it).
    fn partials(&self, h: usize, m: usize, n: usize) -> Rc<Partials> {
        if let Some(p) = self.partials.borrow().get(&h) {
            return p.clone();
        }
        let side = |m: usize, success: bool| {
            let [a, b, c] = [0, 1, 2].map(|j| self.terms(m, success, Some((h, j))));
            (0..a.len()).map(|k| [a[k], b[k], c[k]]).collect::<Vec<_>>()
        };
        let p = Rc::new([side(m, true), side(n + 1 - m, false)]);
        self.partials.borrow_mut().insert(h, p.clone());
        p
    }
}

/// `[E[T·1S], E[T·1F]]` of counted Parallel `id` (success threshold `m`) in
/// dual numbers along the context's parameter, whose leaf is below child
/// number `path`: the integrals of `g` and of its derivative on the grid
/// (`None` where a child has no chain, or is too stiff).
pub(crate) fn counted_means(ctx: &mut Ctx, id: NodeId, m: usize, path: usize) -> Option<[D; 2]> {
    let tree = ctx.plan.tree();
    let children = tree.node(id).kind.children();
    let max_work = crate::curve::CurveOptions::default().max_work;
    let grid = {
        let mut grids = ctx.grids.borrow_mut();
        match grids.get(&id) {
            Some(g) => g.clone()?,
            None => {
                let chains = children
                    .iter()
                    .map(|&c| {
                        let fits = ctx.plan.chain_size(c).ok()?.fits();
                        fits.then(|| ctx.plan.chain(c).ok()).flatten()
                    })
                    .collect::<Option<Vec<_>>>();
                let g = chains
                    .and_then(|c| CountedGrid::new(&c, m, max_work))
                    .map(Rc::new);
                grids.insert(id, g.clone());
                g?
            }
        }
    };
    let child = ctx.chain(children[path])?;
    let [s, f, _, _] = absorb(&child)?;
    let curve = dual_curve(&child, &grid.nodes, max_work)?;
    let n = children.len();
    let partials = grid.partials(path, m, n);
    // d∫g = Σ_k ∂g/∂done·d done + ∂g/∂pending·d pending + ∂g/∂never·d never,
    // with done = S(t), pending = s − S(t), never = 1 − s
    let derivative = |side: usize, total: D| {
        partials[side]
            .iter()
            .zip(&curve)
            .map(|(p, c)| {
                let dd = c[side].d;
                p[0] * dd + p[1] * (total.d - dd) - p[2] * total.d
            })
            .sum::<f64>()
    };
    Some([
        D {
            v: grid.values[0],
            d: derivative(0, s),
        },
        D {
            v: grid.values[1],
            d: derivative(1, f),
        },
    ])
}
