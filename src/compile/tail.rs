//! A bound on the mass a node still has to return after a time `t`, from
//! its structure alone, before any law or curve is built.
//!
//! For `θ ≥ 0` the node's return time `T` has `P(t < T < ∞) ≤ E[e^{θT};
//! T < ∞] · e^{−θt}` (Markov's inequality on `e^{θT}`), so with an upper
//! bound `M(θ)` of that moment generating function the mass still to return
//! after `t` is at most `ε` once `t ≥ ln(M(θ)/ε)/θ`; [`settled_after`]
//! minimises that over `θ`. Every time btrel reads has a light tail (phase
//! types, fixed times, exponentials cut off), so some `θ > 0` has a finite
//! `M` unless a loop almost never ends.
//!
//! `M` is kept per outcome, `[E[e^{θT}; S], E[e^{θT}; F]]`, bottom-up:
//!
//! * a leaf: its probability times its time's MGF (closed forms; a general
//!   phase type's by back substitution, `Stages::mgf`);
//! * Sequence, Fallback, a flow, Retry N, Repeat N, Inverter, Force*:
//!   exact — fresh independent runs one after the other multiply their
//!   MGFs, paths add;
//! * a loop without a bound: the geometric series `stop / (1 − go)`, finite
//!   where the bound of `go` is below 1;
//! * a Parallel (any thresholds, races and Timeouts included): it returns
//!   at the return of one of its children, so on `T < ∞`, `e^{θT} ≤ Π_i
//!   e^{θT_i}` over the children that return (each factor ≥ 1), and by
//!   their independence `E[e^{θT}; T < ∞] ≤ B = Π_i (M_i(θ) + never_i)`;
//!   as `e^{θT} ≥ 1`, each outcome's part is at most `B` minus the other
//!   outcome's probability (the node's figures). A Parallel that returns
//!   at the first return of any child (M = F = 1: a race, a Timeout, the
//!   re-planning race) has `T ≤ T_i` on `T_i < ∞` for every child `i`, so
//!   also `E[e^{θT}; T < ∞] ≤ M_i(θ) + never_i · Π_{j≠i} (M_j(θ) +
//!   never_j)`: the least of these and `B` (a fast child bounds a race
//!   with a slow one). Where the node's and its children's figures are
//!   known, its first moment is taken exact and only the rest from the
//!   product: with `X_i` child `i`'s time where it returns (0 where it
//!   never does), `T ≤ Σ X_i` on `T < ∞`, and `f(x) = e^{θx} − 1 − θx`
//!   increases on `x ≥ 0`, so `E[f(T); T < ∞] ≤ E[f(Σ X_i)] = B − 1 −
//!   θ Σ_i E[X_i]` (the `E[X_i]` exact: `ps·MTTS + pf·MTTF`); each
//!   outcome's part is then at most `p + θ·p·(its mean time) + B − 1 −
//!   θ Σ_i E[X_i]`. The product charges a Parallel the sum of its
//!   children's times where it waits for the slowest; this keeps only the
//!   second- and higher-order terms of that excess, so a loop run
//!   thousands of times over such a Parallel settles near its exact tail.
//!
//! The bound is an upper bound at every step (no estimate): a time past
//! [`settled_after`] has all but `ε` of the node's returning mass behind it.

use super::Figures;
use crate::ir::{FlowGraph, Graph, Leaf, Op, Outcome};
use crate::tree::{Duration, FlowNext, NodeId};

/// `[E[e^{θT}; S], E[e^{θT}; F]]` bounded above; `∞` where the bound
/// diverges.
type Mgf = [f64; 2];

/// A time after which node `id` has less than `epsilon` of its mass still
/// to return (`P(t < T < ∞) ≤ ε`), from a bound on its return time's
/// moment generating function; `None` where no `θ > 0` gives a finite
/// bound. `figures[k]` are the figures of node `id + k` (its subtree, in
/// tree order) where known (a Parallel's unknown figures loosen its bound:
/// each outcome's part is then all of `B`, and a child's never-returning
/// mass is taken as 1); `scale` a time scale of the node (its mean time,
/// say) around which `θ` is searched.
pub(crate) fn settled_after(
    tree: &Graph,
    id: NodeId,
    figures: &[Option<Figures>],
    scale: f64,
    epsilon: f64,
) -> Option<f64> {
    if !(scale.is_finite() && scale > 0.0) {
        return None;
    }
    let at = |theta: f64| -> Option<f64> {
        let [s, f] = mgf_bound(tree, id, figures, theta)?;
        let m = s + f;
        (m.is_finite() && m > 0.0).then(|| ((m / epsilon).ln() / theta).max(0.0))
    };
    // θ on a geometric grid around 1/scale; then refined around the best
    let mut best: Option<(f64, f64)> = None;
    for k in -40..=40 {
        let theta = 2f64.powf(f64::from(k) / 2.0) / scale;
        if let Some(t) = at(theta) {
            if best.is_none_or(|(_, b)| t < b) {
                best = Some((theta, t));
            }
        }
    }
    let (theta, mut t) = best?;
    for k in -8..=8 {
        if let Some(u) = at(theta * 2f64.powf(f64::from(k) / 16.0)) {
            t = t.min(u);
        }
    }
    Some(t)
}

/// The bound of node `id` at `θ` (`None`: none known).
fn mgf_bound(tree: &Graph, id: NodeId, figures: &[Option<Figures>], theta: f64) -> Option<Mgf> {
    let base = id;
    let mut out: Vec<Mgf> = vec![[0.0; 2]; figures.len()];
    for n in tree.subtree(id).rev() {
        let m = |c: NodeId| out[c - base];
        let v = match &tree.node(n).kind {
            Op::Leaf(Leaf::Condition { ps }) => [*ps, 1.0 - ps],
            Op::Leaf(Leaf::Action(a)) => [
                part(a.ps, a.success.as_ref(), theta),
                part(a.pf, a.failure.as_ref(), theta),
            ],
            Op::Flow(flow) => match flow.graph {
                FlowGraph::Chain { stop } => in_turn(
                    flow.children.iter().map(|&c| m(c)),
                    stop == Outcome::Failure,
                ),
                FlowGraph::Repeat { times, stop } => in_turn(
                    std::iter::repeat_n(m(flow.children[0]), times),
                    stop == Outcome::Failure,
                ),
                FlowGraph::States(ref states) => {
                    let mut reach = vec![0.0; states.len()];
                    reach[0] = 1.0;
                    let mut end = [0.0; 2];
                    for (i, s) in states.iter().enumerate() {
                        let child = m(flow.children[s.child]);
                        for (next, p) in [(s.on_success, child[0]), (s.on_failure, child[1])] {
                            let w = mul(reach[i], p);
                            match next {
                                FlowNext::State(j) => reach[j] += w,
                                FlowNext::Success => end[0] += w,
                                FlowNext::Failure => end[1] += w,
                            }
                        }
                    }
                    end
                }
            },
            Op::Map {
                child,
                on_success,
                on_failure,
            } => {
                let [s, f] = m(*child);
                let mut v = [0.0; 2];
                v[on_success.index()] += s;
                v[on_failure.index()] += f;
                v
            }
            Op::Loop { child, until } => {
                let [s, f] = m(*child);
                match until {
                    Outcome::Success => [geometric(s, f), 0.0],
                    Outcome::Failure => [0.0, geometric(f, s)],
                }
            }
            Op::KOfN {
                children,
                success,
                failure,
            } => {
                let never = |c: NodeId| figures[c - base].map_or(1.0, |f| f.never());
                let returns = |c: NodeId| {
                    let [s, f] = m(c);
                    s + f
                };
                let product = |skip: Option<NodeId>| {
                    children
                        .iter()
                        .filter(|&&c| Some(c) != skip)
                        .fold(1.0, |b, &c| mul(b, returns(c) + never(c)))
                };
                let mut b = product(None);
                // returning at the first return of any child (M = F = 1: a
                // race, a Timeout, the re-planning race): on T_i < ∞,
                // T ≤ T_i, so the bound is also M_i + never_i·B_{−i}
                if *success == 1 && *failure == 1 {
                    for &c in children {
                        let first = returns(c) + mul(never(c), product(Some(c)));
                        b = b.min(first);
                    }
                }
                match figures[n - base] {
                    // `b` is at least the mass that returns: both are ≥ 0
                    Some(own) => {
                        let mut v = [(b - own.pf).max(0.0), (b - own.ps).max(0.0)];
                        // the first moment exact, the rest from the product
                        // (module docs)
                        let means: Option<f64> = children
                            .iter()
                            .map(|&c| figures[c - base].map(|f| f.mean_time()))
                            .sum();
                        if let Some(sum) = means {
                            let full = product(None);
                            // B − 1 − θΣm ≥ 0 exactly (Jensen); a margin for
                            // its rounding keeps it an upper bound
                            let rest = (full - 1.0 - theta * sum).max(0.0)
                                + 4.0 * f64::EPSILON * full * children.len() as f64;
                            let first = [
                                own.ps * (1.0 + theta * own.mtts.unwrap_or(0.0)),
                                own.pf * (1.0 + theta * own.mttf.unwrap_or(0.0)),
                            ];
                            for o in 0..2 {
                                if first[o] > 0.0 {
                                    v[o] = v[o].min(first[o] + rest);
                                }
                            }
                        }
                        v
                    }
                    None => [b, b],
                }
            }
        };
        out[n - base] = v;
    }
    Some(out[0])
}

/// `p · E[e^{θX}]` of an outcome with probability `p` and time `X`.
fn part(p: f64, time: Option<&Duration>, theta: f64) -> f64 {
    match time {
        _ if p == 0.0 => 0.0,
        None => p,
        Some(d) => p * duration_mgf(d, theta),
    }
}

/// `E[e^{θX}]` of a duration (`∞` where it diverges).
pub(crate) fn duration_mgf(d: &Duration, theta: f64) -> f64 {
    match *d {
        Duration::Exponential { rate } => exponential_mgf(rate, theta),
        Duration::Fixed { time } => (theta * time).exp(),
        // E[e^{θ min(X, c)}] = ∫_0^c e^{θt} λe^{−λt} dt + e^{(θ−λ)c}
        Duration::TruncatedExponential { rate, cap } => {
            let d = theta - rate;
            let tail = (d * cap).exp();
            if d == 0.0 {
                rate * cap + tail
            } else {
                rate * (d * cap).exp_m1() / d + tail
            }
        }
        Duration::PhaseType { shift, stages } => (theta * shift).exp() * stages.mgf(theta),
    }
}

fn exponential_mgf(rate: f64, theta: f64) -> f64 {
    if theta < rate {
        rate / (rate - theta)
    } else {
        f64::INFINITY
    }
}

/// Children run one after the other (`sequence`: a Sequence, going on
/// with Success; else a Fallback): the MGF of each way out is the product
/// along its path.
fn in_turn(children: impl Iterator<Item = Mgf>, sequence: bool) -> Mgf {
    let (go, stop) = if sequence { (0, 1) } else { (1, 0) };
    let mut reached = 1.0;
    let mut out = [0.0; 2];
    for c in children {
        out[stop] += mul(reached, c[stop]);
        reached = mul(reached, c[go]);
    }
    out[go] = reached;
    out
}

/// `a · b` of bounds where a part of mass 0 stays 0 whatever the other's
/// bound (`0 · ∞ = 0`: a way out never taken adds nothing).
fn mul(a: f64, b: f64) -> f64 {
    if a == 0.0 || b == 0.0 {
        0.0
    } else {
        a * b
    }
}

/// `stop / (1 − go)`: runs until one that stops.
fn geometric(stop: f64, go: f64) -> f64 {
    if stop == 0.0 {
        0.0
    } else if go < 1.0 {
        stop / (1.0 - go)
    } else {
        f64::INFINITY
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The closed forms against the MGFs' series `Σ θ^k E[X^k]/k!`, from
    /// the moments of each law written out here.
    #[test]
    fn duration_mgfs_are_their_closed_forms() {
        let theta = 0.3;
        let exp = Duration::Exponential { rate: 2.0 };
        // E[X^k] = k!/λ^k: Σ (θ/λ)^k
        assert!((duration_mgf(&exp, theta) - 1.0 / (1.0 - 0.15)).abs() < 1e-15);
        assert_eq!(duration_mgf(&exp, 2.5), f64::INFINITY);
        // min(X, c): P(X > c) e^{θc} + ∫_0^c e^{θt} λ e^{−λt} dt by Simpson
        let (rate, cap) = (2.0, 1.5);
        let cut = Duration::TruncatedExponential { rate, cap };
        let n = 20_000;
        let h = cap / n as f64;
        let f = |t: f64| (theta * t).exp() * rate * (-rate * t).exp();
        let simpson: f64 = (0..n)
            .map(|i| {
                let a = i as f64 * h;
                h / 6.0 * (f(a) + 4.0 * f(a + h / 2.0) + f(a + h))
            })
            .sum();
        let expect = simpson + (-rate * cap).exp() * (theta * cap).exp();
        assert!((duration_mgf(&cut, theta) - expect).abs() < 1e-12);
        // at θ = λ the integral is λc
        let at = Duration::TruncatedExponential { rate, cap };
        let e = rate * cap + 1.0;
        assert!((duration_mgf(&at, rate) - e).abs() < 1e-12);
    }

    /// A loop of an exponential action (`until_success`, ps = 1/2, rate 1
    /// both ways) returns after a Exp(1/2) time (a geometric number of
    /// Exp(1) runs): `P(T > t) = e^{−t/2}`, so the bound's time for ε must
    /// be at least `2 ln(1/ε)`, and Markov's bound at the best θ is within
    /// a few units of it.
    #[test]
    fn a_geometric_loop_settles_after_its_exact_tail() {
        let tree = crate::parse_str(
            "tree:\n  until_success:\n    child: {action: {ps: 0.5, mu: 1, nu: 1}}\n",
            "loop.yaml",
        )
        .unwrap();
        let half = Figures::from_moments([0.5, 0.5, 0.5, 0.5]);
        let root = Figures::from_moments([1.0, 0.0, 2.0, 0.0]);
        let eps = 1e-13;
        let t = settled_after(
            &crate::ir::graph_of(&tree),
            0,
            &[Some(root), Some(half)],
            2.0,
            eps,
        )
        .unwrap();
        let exact = 2.0 * (1.0 / eps).ln();
        assert!(t >= exact, "{t} < {exact}");
        assert!(t < exact + 2.0 * (2.0 * exact).ln() + 4.0, "{t} vs {exact}");
    }

    /// A race (M = F = 1) of a fast action (Exp(1)) and a slow one
    /// (Exp(0.001)) returns at the first: `P(T > t) = e^{−1.001 t}`, so the
    /// bound's time for ε must be at least `ln(1/ε)/1.001`. The product of
    /// the children's bounds alone is finite only for θ < 0.001 (the slow
    /// child's): about a thousand times longer; the first-return bound
    /// `M_fast(θ)` keeps it within a few units of the exact tail.
    #[test]
    fn a_race_settles_with_its_fast_child() {
        let tree = crate::parse_str(
            "tree:\n  parallel:\n    success_threshold: 1\n    failure_threshold: 1\n    children:\n      - action: {ps: 1, mu: 1}\n      - action: {ps: 1, mu: 0.001}\n",
            "race.yaml",
        )
        .unwrap();
        let f = |ts: f64| Figures::from_moments([1.0, 0.0, ts, 0.0]);
        let eps = 1e-13;
        let t = settled_after(
            &crate::ir::graph_of(&tree),
            0,
            &[Some(f(1.0 / 1.001)), Some(f(1.0)), Some(f(1000.0))],
            1.0 / 1.001,
            eps,
        )
        .unwrap();
        let exact = (1.0 / eps).ln() / 1.001;
        assert!(t >= exact, "{t} < {exact}");
        assert!(t < exact + 2.0 * (2.0 * exact).ln() + 4.0, "{t} vs {exact}");
    }

    /// A way out of mass 0 adds nothing even where its time's bound is
    /// infinite: the inner Sequence never reaches its action (`0 · ∞`),
    /// and the Parallel returns with its other child, an Exp(1) time; the
    /// root fails at once or runs the Parallel: `P(T > t) = e^{−t}/2`,
    /// which needs `t ≥ ln(1/(2ε))`. (A NaN from `0 · ∞` once made the
    /// Parallel's bound 0 past θ = 1, and the root's `1/2`.)
    #[test]
    fn a_path_never_taken_does_not_void_the_bound() {
        let tree = crate::parse_str(
            "tree:\n  sequence:\n    children:\n      - condition: {ps: 0.5}\n      - parallel:\n          success_threshold: 1\n          children:\n            - sequence:\n                children:\n                  - condition: {ps: 0}\n                  - action: {ps: 1, mu: 1}\n            - action: {ps: 1, mu: 1}\n",
            "p.yaml",
        )
        .unwrap();
        let f = |ps: f64, ts: f64| Figures::from_moments([ps, 1.0 - ps, ts, 0.0]);
        let figures = [
            f(0.5, 0.5),
            f(0.5, 0.0),
            f(1.0, 1.0),
            f(0.0, 0.0),
            f(0.0, 0.0),
            f(1.0, 1.0),
            f(1.0, 1.0),
        ]
        .map(Some);
        let eps = 1e-13;
        let t = settled_after(&crate::ir::graph_of(&tree), 0, &figures, 1.0, eps).unwrap();
        assert!(t >= (0.5 / eps).ln(), "{t}");
    }

    /// A Parallel of two fixed-time actions returns at 3: the bound (by
    /// the product of the children's MGFs, `e^{4θ}`) settles by `4 +
    /// ln(1/ε)/θ`, close to 4 at the largest θ whose bound is finite in
    /// floating point (`e^{4θ}` overflows past θ ≈ 177).
    #[test]
    fn a_parallel_of_fixed_times_settles_near_its_last_child() {
        let tree = crate::parse_str(
            "tree:\n  parallel:\n    success_threshold: 2\n    children:\n      - action: {ps: 1, tau_s: 1}\n      - action: {ps: 1, tau_s: 3}\n",
            "p.yaml",
        )
        .unwrap();
        let f = |t: f64| Figures::from_moments([1.0, 0.0, t, 0.0]);
        let t = settled_after(
            &crate::ir::graph_of(&tree),
            0,
            &[Some(f(3.0)), Some(f(1.0)), Some(f(3.0))],
            3.0,
            1e-13,
        )
        .unwrap();
        assert!((4.0..4.5).contains(&t), "{t}");
    }

    /// A loop run about 1,000 times over a Parallel waiting for all of ten
    /// Exp(1) actions: each cycle lasts the maximum of the ten (mean
    /// `H_10` = 2.93), which the product of the children's MGFs charges as
    /// their sum (mean 10), so the product alone settles 4.2 times later
    /// than the exact tail (ε = 1e-9: 256,817 s against 60,675 s). With
    /// the first moment exact the loop's bound stays within 1.6 times of
    /// it (77,875 s). The exact tail: the loop is a
    /// phase chain (k children still running, k = 10..1, leaving at rate
    /// k; after the last, again with probability 1 − q), `P(T > t) = α
    /// e^{St} 1`, stepped here with `e^{S}` by scaling and squaring.
    #[test]
    fn a_loop_over_a_parallel_settles_near_its_exact_tail() {
        let n = 10;
        let q = 0.001;
        let mut yaml = String::from(
            "tree:\n  until_failure:\n    child:\n      sequence:\n        children:\n          - parallel:\n              success_threshold: 10\n              children:\n",
        );
        for _ in 0..n {
            yaml.push_str("                - action: {ps: 1, mu: 1}\n");
        }
        yaml.push_str(&format!("          - condition: {{ps: {}}}\n", 1.0 - q));
        let tree = crate::parse_str(&yaml, "loop.yaml").unwrap();
        let h: f64 = (1..=n).map(|k| 1.0 / f64::from(k)).sum();
        let cycle = Figures::from_moments([1.0, 0.0, h, 0.0]);
        let mut figures = vec![
            Some(Figures::from_moments([0.0, 1.0, 0.0, h / q])),
            Some(Figures::from_moments([1.0 - q, q, (1.0 - q) * h, q * h])),
            Some(cycle),
        ];
        figures.extend((0..n).map(|_| Some(Figures::from_moments([1.0, 0.0, 1.0, 0.0]))));
        figures.push(Some(Figures::from_moments([1.0 - q, q, 0.0, 0.0])));
        let eps = 1e-9;
        let graph = crate::ir::graph_of(&tree);
        let t = settled_after(&graph, 0, &figures, h / q, eps).unwrap();
        // S over states k = 10..1 (index 10 − k): k → k − 1 at rate k;
        // from k = 1, back to 10 with probability 1 − q
        let m = n as usize;
        let mut s_mat = vec![vec![0.0f64; m]; m];
        for i in 0..m {
            let rate = f64::from(n) - i as f64;
            s_mat[i][i] = -rate;
            if i + 1 < m {
                s_mat[i][i + 1] = rate;
            } else {
                s_mat[i][0] += rate * (1.0 - q);
            }
        }
        let mul = |a: &Vec<Vec<f64>>, b: &Vec<Vec<f64>>| -> Vec<Vec<f64>> {
            (0..m)
                .map(|i| {
                    (0..m)
                        .map(|j| (0..m).map(|k| a[i][k] * b[k][j]).sum())
                        .collect()
                })
                .collect()
        };
        // e^{S/2^10} by its Taylor series (norm ≤ 0.02), squared 10 times
        let small: Vec<Vec<f64>> = s_mat
            .iter()
            .map(|r| r.iter().map(|x| x / 1024.0).collect())
            .collect();
        let mut step: Vec<Vec<f64>> = (0..m)
            .map(|i| (0..m).map(|j| f64::from(u8::from(i == j))).collect())
            .collect();
        let mut term = step.clone();
        for k in 1..20 {
            term = mul(&term, &small)
                .into_iter()
                .map(|r| r.into_iter().map(|x| x / f64::from(k)).collect())
                .collect();
            for i in 0..m {
                for j in 0..m {
                    step[i][j] += term[i][j];
                }
            }
        }
        for _ in 0..10 {
            step = mul(&step, &step);
        }
        let mut x = vec![0.0; m];
        x[0] = 1.0;
        let mut exact = 0.0;
        while x.iter().sum::<f64>() > eps {
            x = (0..m)
                .map(|j| (0..m).map(|i| x[i] * step[i][j]).sum())
                .collect();
            exact += 1.0;
        }
        assert!(t >= exact - 1.0, "{t} < {exact}");
        assert!(t <= 1.6 * exact, "{t} vs exact {exact}");
    }
}
