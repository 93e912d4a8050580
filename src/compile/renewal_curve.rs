//! `π(t)` of the race of a subtree against a **renewal process of re-runs**
//! with a fixed wait (`crate::compile::renewal`: Nav2's re-planning
//! PipelineSequence, lowered to
//! `Parallel{1, 1}(until_failure(Sequence(wait d, C′)), R)`), exactly and
//! without a series over the re-runs; also of a Sequence that ends with
//! such a race after Markovian children (the lowered pipeline itself:
//! `Sequence(c₀, …, c_k, race)`, the prefix `c₀ … c_k` one phase chain `P`).
//!
//! **The process.** While `C′` runs, R and `C′` form a product chain; when
//! `C′` succeeds, the race *waits* `d` (R runs alone), then `C′` runs
//! again. The flux `φ(t)` (a row vector over R's phases) of runs that
//! enter a wait at `t` leaves it at `t + d` with R's phases `φ(t)·E`,
//! `E = e^{Q_R d}` — a linear delay equation `z′(t) = z(t) A₀ + z(t − d)
//! A₁` over the run states. Cut time into *levels* `[t₀ + kd, t₀ + (k+1)d)`
//! (`θ` the time within a level; `t₀ = 0`, or the first wait `d₀` of a
//! SpeedController, during which R runs alone): a level's state `x_k(θ)`
//! obeys `x_k′ = x_k A₀ + x_{k−1} A₁` (the method of steps), so the levels
//! `k − m … k`, stacked, are one linear system whose generator is block
//! bidiagonal, and `x_k(θ) = Σ_m x_{k−m}(0) G_m(θ)`.
//!
//! A level's state holds the prefix `P`'s phases, the product `(R, C′)`
//! (and `(R, C′₀)` of a first cycle of its own), `W` — R's phases and
//! outcomes of the runs that entered a wait *in this level*, evolved by
//! R's chain with its Success and Failure kept (`Q̄`) —, `V` — the previous
//! level's `W(d)` evolved on (`W_{k−1}(d) e^{Q̄θ}`) — and the Success and
//! Failure the node reached in this level (R's exits while `C′` runs,
//! `C′`'s failures, and the outcomes `φ·a(d)` of waits that end here, `a`
//! R's absorption by `d`). Then at `t = t₀ + kd + θ`
//!
//! `S(t) = S₀ + Σ_{j<k} acc_j(d) + acc_k(θ) + W_k(θ)_S + V_k(θ)_S −
//! (W_{k−1}(θ) e^{Q̄ d})_S`
//!
//! — the last three terms are the Success reached in waits still under way
//! (entered in this level, or in the previous one after `θ`: their
//! entries up to `θ` have left, and `W_{k−1}(θ) e^{Q̄d}` is exactly their
//! part of `V`); likewise Failure. Entries at a level's start (the first
//! wait after the prefix's instantaneous Success, `C′`'s instantaneous
//! Success when it starts) are atoms of `W_k(0)` and leave at `x_{k+1}(0)`.
//!
//! **Solution.** Each level is one uniformized transient of the stacked
//! system over `[0, d]` (the levels below it start from their own `x(0)`;
//! every term non-negative, as `W` keeps a copy of what enters a wait, the
//! stacked matrix's rows sum to at most `1 + c/Λ`, `c` the fastest flux
//! into waits: the Poisson window is taken at `(Λ + c)d`); each step's
//! outcome functionals (`S`, `F` above and their densities,
//! `crate::compile::renewal_law`) are kept — four numbers a step, for
//! every level — so every time within the level costs one weighted sum,
//! and `x_k(d)`, summed as the steps go, starts the next level. The stack is truncated below
//! `M + 1` levels: a contribution of `x_{k−m}(0)` to `x_k(θ)` passes through
//! `m` re-runs of `C′` whose run times add up to at most `θ ≤ d`; a fresh
//! run needs a phase change of `C′` unless it succeeds at once (probability
//! `p₀`), and `C′`'s phase changes in a time `d` are at most Poisson(`q_C
//! d`) (`q_C` its fastest phase), so the mass left out per level is at
//! most `P(Poisson(q_C d) ≥ Binomial(m − 1, 1 − p₀))`; and as each of the
//! `m − 1` fresh runs must succeed within `d`, also at most `g^{m−1}`, `g =
//! P(C′ succeeds within d)`. The smaller bound fixes `M` for 1e-16 (no
//! truncation when the stack reaches time 0). Per level the
//! error is at most that plus the Poisson windows' 1e-17 (1e-20 per point),
//! so at most `K·2e-16` after `K` levels, whatever the number of re-runs;
//! prefix phases whose mass fell below 1e-30 are dropped (they only set
//! the uniformization rate).
//!
//! **One slot a level.** The stacked system is block bidiagonal: a slot's
//! steps depend on the slots below it only, never on the level above. So
//! the steps of level `k − 1`'s slot in level `k`'s stack are the steps
//! level `k − 1` took as its own top, when both step at the same rate
//! `Λ` — and level `k − 1`'s top summed up every level below it, not only
//! `M` of them. Each level therefore keeps, per step, what the level above
//! reads of it (the flux leaving its top into waits, `nr` numbers, and its
//! waits' part, `nr + 2`), and the next level at the same rate steps its
//! top alone over them; the stack is stepped only where the rate changes
//! (the first levels, while the prefix's phases die out), so the
//! truncation above applies there only. Cost: `K·N·nnz` for `K = t/d`
//! levels, `N ≈ (Λ + c)d` steps (plus `N·(M + 1)·nnz` per level where the
//! rate changes); refused beyond 4e9 operations or when the numbers kept
//! exceed the state budget (8 a state).
//!
//! Size: one concern, the renewal race's curve by levels (about 200 lines
//! are comments).

use super::chain_curve::solve_chain;
use super::curve_options::{CurveOptions, CurvePoint};
use super::renewal;
use super::{phase, AnalysisError};
use crate::ir::Graph;
use crate::solve::chain::PhaseChain;
use crate::solve::transient::poisson_window;
use crate::tree::NodeId;

/// Most operations the method takes on.
const MAX_WORK: f64 = 4e9;
/// Numbers kept per state of the budget.
const CELLS_PER_STATE: f64 = 8.0;
/// Poisson mass left out of a level's steps.
const LEVEL_EPS: f64 = 1e-17;
/// Poisson mass left out of a point's weights.
const POINT_EPS: f64 = 1e-20;
/// Mass of the stack left out per level.
const STACK_EPS: f64 = 1e-16;
/// Prefix mass below which a phase is dropped.
const DROP: f64 = 1e-30;

/// The node's chains: the optional prefix `P`, the race's rest `R`, the
/// re-run `C′` and its wait `d`, a first cycle `(d₀, C′₀)`.
struct Chains {
    prefix: Option<PhaseChain>,
    rest: PhaseChain,
    rerun: PhaseChain,
    wait: f64,
    first: Option<(f64, PhaseChain)>,
}

/// Outcome of [`chains`]: `None` when node `id` is not such a race (or a
/// side has no phase chain).
fn chains(tree: &Graph, id: NodeId, max_states: usize) -> Result<Option<Chains>, AnalysisError> {
    let (race, prefix_ids): (NodeId, &[NodeId]) = if renewal::parts(tree, id).is_some() {
        (id, &[])
    } else {
        match tree
            .node(id)
            .kind
            .sequence()
            .and_then(<[NodeId]>::split_last)
        {
            Some((&last, rest)) if renewal::parts(tree, last).is_some() => (last, rest),
            _ => return Ok(None),
        }
    };
    let Some(p) = renewal::parts(tree, race) else {
        return Ok(None);
    };
    let chain = |n: NodeId| phase::markovian_chain_of(tree, n, max_states);
    let mut pre = Vec::new();
    for &c in prefix_ids {
        match chain(c)? {
            Some(c) => pre.push(c),
            None => return Ok(None),
        }
    }
    let rest = renewal::rest_chain(tree, &p.rest, max_states)?;
    let (Some(rest), Some(rerun)) = (rest, chain(p.rerun)?) else {
        return Ok(None);
    };
    let first = match p.first {
        None => None,
        Some((d0, c0)) => match chain(c0)? {
            Some(c0) => Some((d0, c0)),
            None => return Ok(None),
        },
    };
    let prefix = (!pre.is_empty()).then(|| phase::concatenate(pre, true));
    Ok(Some(Chains {
        prefix,
        rest,
        rerun,
        wait: p.wait,
        first,
    }))
}

/// Sparse rows: `out[to] += x[from] · rate`.
type Rows = Vec<Vec<(usize, f64)>>;

/// The level system (module docs).
struct Levels {
    d: f64,
    /// Start of level 0 (the first wait of a first cycle, else 0).
    t0: f64,
    dim: usize,
    /// Prefix phases `0..np`; the states carried from one level to the
    /// next are `0..w` (prefix and run states).
    np: usize,
    w: usize,
    v: usize,
    nr: usize,
    acc: usize,
    /// Off-diagonal rates within a level and each state's total rate.
    a0: Rows,
    q: Vec<f64>,
    /// Flux into waits per state, over R's phases: what leaves a wait in
    /// the next level (with what re-enters it at once, [`Levels::leave`]).
    lag: Rows,
    /// Fastest flux into waits (the stacked rows sum to ≤ 1 + c/Λ), and
    /// each state's (with what re-enters at once).
    c: f64,
    flux: Vec<f64>,
    /// `E` and R's absorption `a(d)` per phase.
    e: Vec<f64>,
    a: Vec<[f64; 2]>,
    /// `C′`'s entry: phases, instantaneous Success and Failure.
    entry: (Vec<(usize, f64)>, f64, f64),
    nc: usize,
    /// `x_0(0)` and the outcomes before level 0.
    x0: Vec<f64>,
    base: [f64; 2],
    /// `(q_C d, p₀)` for the stack's truncation.
    stack: (f64, f64),
    /// `g = P(C′ succeeds within d)`: also `P(m − 1 fresh runs in a time
    /// d) ≤ g^{m−1}` (each must).
    succeeds_within: f64,
    /// The densities of Success and Failure as functionals of a level's
    /// state (`[S, F]`): rates into the outcomes of the level's own
    /// states, and `−(E·h)_i` on the previous level's `W` (its waits that
    /// ended: [`Levels::outcomes`]).
    density_top: [Vec<(usize, f64)>; 2],
    density_below: [Vec<f64>; 2],
    /// The outcomes at time 0, and the largest probability of an
    /// instantaneous Failure of a re-run (`C′`, `C′₀`): an atom after 0
    /// when a wait ends with one.
    atoms_at_zero: [f64; 2],
    instant_failure: f64,
}

impl Levels {
    fn new(ch: &Chains) -> Option<Levels> {
        let (r, c) = (&ch.rest, &ch.rerun);
        let d = ch.wait;
        let (nr, nc) = (r.len(), c.len());
        let np = ch.prefix.as_ref().map_or(0, |p| p.len());
        let nc0 = ch.first.as_ref().map_or(0, |(_, c0)| c0.len());
        let y = np;
        let y0 = y + nr * nc;
        let w = y0 + nr * nc0;
        let v = w + nr + 2;
        let acc = v + nr + 2;
        let dim = acc + 2;
        let (acc_s, acc_f) = (acc, acc + 1);
        let (e, a) = renewal::wait_exponential(r, d)?;
        let mut a0: Rows = vec![Vec::new(); dim];
        let mut q = vec![0.0f64; dim];
        let mut lag: Rows = vec![Vec::new(); dim];
        let mut c_max = 0.0f64;
        let alpha_r: Vec<(usize, f64)> = r.initial.clone();
        // the prefix: its Success starts the race (the first wait, R at α_R)
        if let Some(p) = &ch.prefix {
            for s in 0..np {
                q[s] = p.total_rate(s);
                a0[s].extend(p.transitions[s].iter().copied());
                let rate = p.exit_success[s];
                if rate > 0.0 {
                    let flux: Vec<(usize, f64)> =
                        alpha_r.iter().map(|&(i, x)| (i, rate * x)).collect();
                    for &(i, x) in &flux {
                        a0[s].push((w + i, x));
                    }
                    a0[s].push((acc_s, rate * r.initial_success));
                    a0[s].push((acc_f, rate * r.initial_failure));
                    c_max = c_max.max(flux.iter().map(|f| f.1).sum());
                    lag[s] = flux;
                }
                a0[s].push((acc_f, p.exit_failure[s]));
            }
        }
        // the product of R with a re-run (C′, or C′₀ of the first cycle)
        let mut product = |off: usize, cc: &PhaseChain, lag: &mut Rows| {
            let n = cc.len();
            for i in 0..nr {
                for j in 0..n {
                    let s = off + i * n + j;
                    q[s] = r.total_rate(i) + cc.total_rate(j);
                    for &(i2, rate) in &r.transitions[i] {
                        a0[s].push((off + i2 * n + j, rate));
                    }
                    for &(j2, rate) in &cc.transitions[j] {
                        a0[s].push((off + i * n + j2, rate));
                    }
                    a0[s].push((acc_s, r.exit_success[i]));
                    a0[s].push((acc_f, r.exit_failure[i] + cc.exit_failure[j]));
                    let rate = cc.exit_success[j];
                    if rate > 0.0 {
                        a0[s].push((w + i, rate));
                        c_max = c_max.max(rate);
                        lag[s].push((i, rate));
                    }
                }
            }
        };
        product(y, c, &mut lag);
        if let Some((_, c0)) = &ch.first {
            product(y0, c0, &mut lag);
        }
        // W and V: R's chain with its outcomes kept
        for off in [w, v] {
            for i in 0..nr {
                q[off + i] = r.total_rate(i);
                a0[off + i].extend(r.transitions[i].iter().map(|&(i2, x)| (off + i2, x)));
                a0[off + i].push((off + nr, r.exit_success[i]));
                a0[off + i].push((off + nr + 1, r.exit_failure[i]));
            }
        }
        for rows in [&mut a0, &mut lag] {
            for row in rows.iter_mut() {
                row.retain(|&(_, x)| x > 0.0);
            }
        }
        // C′'s instantaneous Success re-enters at once: the flux goes round
        // again, up to (1 + p₀ + p₀² + …) times
        let p0 = c.initial_success;
        let again = if p0 < 1.0 {
            1.0 / (1.0 - p0)
        } else {
            f64::INFINITY
        };
        let flux: Vec<f64> = lag
            .iter()
            .map(|row| row.iter().map(|f| f.1).sum::<f64>() * again)
            .collect();
        c_max = flux.iter().copied().fold(c_max * again, f64::max);
        // x_0(0) and the outcomes before level 0
        let mut x0 = vec![0.0f64; dim];
        let mut base = [0.0f64; 2];
        let t0 = match &ch.first {
            Some((d0, c0)) => {
                // R alone for d₀, then C′₀ beside it
                let (e0, a0d) = renewal::wait_exponential(r, *d0)?;
                base = [r.initial_success, r.initial_failure];
                let mut after = vec![0.0f64; nr];
                for &(i, x) in &alpha_r {
                    base[0] += x * a0d[i][0];
                    base[1] += x * a0d[i][1];
                    for i2 in i..nr {
                        after[i2] += x * e0[i * nr + i2];
                    }
                }
                let n0 = c0.len();
                for (i, &x) in after.iter().enumerate() {
                    for &(j, wgt) in &c0.initial {
                        x0[y0 + i * n0 + j] += x * wgt;
                    }
                    x0[w + i] += x * c0.initial_success;
                    x0[acc_f] += x * c0.initial_failure;
                }
                *d0
            }
            None => {
                let (ps, pf) = match &ch.prefix {
                    Some(p) => {
                        for &(s, x) in &p.initial {
                            x0[s] += x;
                        }
                        (p.initial_success, p.initial_failure)
                    }
                    None => (1.0, 0.0),
                };
                for &(i, x) in &alpha_r {
                    x0[w + i] += ps * x;
                }
                x0[acc_s] += ps * r.initial_success;
                x0[acc_f] += pf + ps * r.initial_failure;
                0.0
            }
        };
        let qc = (0..nc)
            .map(|j| c.total_rate(j))
            .chain(
                ch.first
                    .iter()
                    .flat_map(|(_, c0)| (0..c0.len()).map(|j| c0.total_rate(j))),
            )
            .fold(0.0, f64::max);
        let succeeds_within = if nc == 0 {
            c.initial_success
        } else {
            let (_, ca) = renewal::wait_exponential(c, d)?;
            c.initial_success + c.initial.iter().map(|&(j, x)| x * ca[j][0]).sum::<f64>()
        };
        // the densities (module docs of `renewal_law`): the rates of the
        // level's states into its outcomes, less those of the waits entered
        // in the previous level that have ended (their R phases moved by E)
        let mut density_top: [Vec<(usize, f64)>; 2] = [Vec::new(), Vec::new()];
        for (s, row) in a0.iter().enumerate() {
            for (side, out) in density_top.iter_mut().enumerate() {
                let rate: f64 = row
                    .iter()
                    .filter(|&&(t, _)| t == acc + side || t == w + nr + side || t == v + nr + side)
                    .map(|&(_, x)| x)
                    .sum();
                if rate > 0.0 {
                    out.push((s, rate));
                }
            }
        }
        let density_below = [&r.exit_success, &r.exit_failure].map(|h| {
            (0..nr)
                .map(|i| -(i..nr).map(|i2| e[i * nr + i2] * h[i2]).sum::<f64>())
                .collect::<Vec<f64>>()
        });
        let atoms_at_zero = match &ch.first {
            Some(_) => [r.initial_success, r.initial_failure],
            None => [x0[acc_s], x0[acc_f]],
        };
        let instant_failure = ch
            .first
            .as_ref()
            .map_or(0.0, |(_, c0)| c0.initial_failure)
            .max(c.initial_failure);
        Some(Levels {
            density_top,
            density_below,
            atoms_at_zero,
            instant_failure,
            succeeds_within: succeeds_within.min(1.0),
            d,
            t0,
            dim,
            np,
            w,
            v,
            nr,
            acc,
            a0,
            q,
            lag,
            c: c_max,
            flux,
            e,
            a,
            entry: (c.initial.clone(), c.initial_success, c.initial_failure),
            nc,
            x0,
            base,
            stack: (qc * d, c.initial_success),
        })
    }

    fn nnz(&self) -> usize {
        self.a0.iter().chain(&self.lag).map(Vec::len).sum::<usize>()
            + self.dim
            + self.nr * (self.nr + self.nc + 4)
    }

    /// The flux `phi` (over R's phases) leaving its waits into the level
    /// state `to`: R's outcomes during the wait `φ·a(d)`, the phases after
    /// it `φ·E` entering C′, and what re-enters at once (C′'s instantaneous
    /// Success), returned: it is flux into the level's waits too.
    fn leave(&self, phi: &[f64], to: &mut [f64]) -> Vec<f64> {
        let (nr, nc, y, w) = (self.nr, self.nc, self.np, self.w);
        let (init, ps, pf) = &self.entry;
        let mut again = vec![0.0f64; nr];
        for (i, &f) in phi.iter().enumerate() {
            if f == 0.0 {
                continue;
            }
            to[self.acc] += f * self.a[i][0];
            to[self.acc + 1] += f * self.a[i][1];
            for i2 in i..nr {
                let out = f * self.e[i * nr + i2];
                if out == 0.0 {
                    continue;
                }
                for &(j, wgt) in init {
                    to[y + i2 * nc + j] += out * wgt;
                }
                to[w + i2] += out * ps;
                again[i2] += out * ps;
                to[self.acc + 1] += out * pf;
            }
        }
        again
    }

    /// Levels below a level that its stack keeps (`M + 1`, module docs),
    /// at most `cap` (no truncation then).
    fn depth(&self, cap: usize) -> usize {
        let (lambda, p0) = self.stack;
        let window = poisson_window(lambda, 1e-30);
        let right = window.left + window.weights.len();
        // tail[b] = P(Poisson ≥ b)
        let mut tail = vec![0.0f64; right + 1];
        for b in (0..right).rev() {
            let wgt = if b >= window.left {
                window.weights[b - window.left]
            } else {
                0.0
            };
            tail[b] = tail[b + 1] + wgt;
        }
        for t in tail.iter_mut().take(window.left + 1) {
            *t = t.max(1.0 - window.outside).min(1.0);
        }
        let tail_at = |b: usize| tail.get(b).copied().unwrap_or(0.0);
        // dist: Binomial(m − 1, 1 − p₀) over the fresh runs that take time
        let mut dist = vec![1.0f64];
        let g = self.succeeds_within;
        for m in 1..=cap {
            let out: f64 = dist.iter().enumerate().map(|(b, &x)| x * tail_at(b)).sum();
            // m − 1 fresh runs, each succeeding within d: at most g^{m−1}
            let out = out.min(g.powi(m as i32 - 1));
            if out <= STACK_EPS {
                return m;
            }
            let mut next = vec![0.0f64; dist.len() + 1];
            for (b, &x) in dist.iter().enumerate() {
                next[b] += x * p0;
                next[b + 1] += x * (1.0 - p0);
            }
            dist = next;
        }
        cap
    }

    /// `[S, F, s, f]` less the outcomes before the level, of the stack
    /// with this level's state `top` and the previous one's `below`: `S(t)
    /// = acc_k + W_k,S + V_k,S − (W_{k−1} e^{Q̄d})_S` (module docs), its
    /// density `s(t)` the functional `density_*`; likewise Failure.
    fn outcomes(&self, below: &[f64], top: &[f64]) -> [f64; 4] {
        let (nr, w, v, acc) = (self.nr, self.w, self.v, self.acc);
        let mut o = [0.0f64; 4];
        for side in 0..2 {
            let left: f64 = (0..nr).map(|i| below[w + i] * self.a[i][side]).sum();
            o[side] = top[acc + side] + top[w + nr + side] + top[v + nr + side]
                - (left + below[w + nr + side]);
            let here: f64 = self.density_top[side]
                .iter()
                .map(|&(s, rate)| top[s] * rate)
                .sum();
            let ended: f64 = (0..nr)
                .map(|i| below[w + i] * self.density_below[side][i])
                .sum();
            o[2 + side] = here + ended;
        }
        o
    }

    /// The next level's start from this one's start and end.
    fn next_start(&self, start: &[f64], end: &[f64]) -> Vec<f64> {
        let (nr, w) = (self.nr, self.w);
        let mut x = vec![0.0f64; self.dim];
        x[..w].copy_from_slice(&end[..w]);
        x[self.v..self.v + nr + 2].copy_from_slice(&end[w..w + nr + 2]);
        // atoms entered at the start leave now
        let atoms = start[self.w..self.w + nr].to_vec();
        self.leave(&atoms, &mut x);
        x
    }
}

/// A renewal race (or the Sequence that starts it) ready for its levels
/// up to a horizon: its chains, level system and stack depth, within the
/// budgets (checked before anything is allocated).
pub(super) struct Prepared {
    ch: Chains,
    lv: Levels,
    /// Levels up to the horizon, and the levels below one that its stack
    /// keeps.
    levels: usize,
    depth: usize,
    name: String,
}

/// One level's outcome functionals step by step: what [`Prepared::run`]
/// hands over, read at any time within the level by [`Level::at`].
#[derive(Clone)]
pub(super) struct Level {
    /// The level's start `t₀ + kd` (s).
    pub(super) start: f64,
    /// The mass entering waits at the start (atoms: they leave together at
    /// the next level's start, where the densities may jump).
    pub(super) atoms: f64,
    lambda: f64,
    before: [f64; 2],
    rows: Vec<[f64; 4]>,
}

impl Level {
    /// `[S, F, s, f]` at time `θ` within the level: the outcomes by `t =
    /// start + θ` and their densities at `t`, one weighted sum of the
    /// steps' functionals each.
    /// The level's uniformization rate `Λ`.
    pub(super) fn rate(&self) -> f64 {
        self.lambda
    }

    pub(super) fn at(&self, theta: f64) -> [f64; 4] {
        let win = poisson_window(self.lambda * theta, POINT_EPS);
        let mut o = [self.before[0], self.before[1], 0.0, 0.0];
        for (k, &wgt) in win.weights.iter().enumerate() {
            let Some(row) = self.rows.get(win.left + k) else {
                break;
            };
            for (a, &b) in o.iter_mut().zip(row) {
                *a += wgt * b;
            }
        }
        o
    }
}

/// Node `id` prepared for its levels up to `t_max` when it is a renewal
/// race, or a Sequence ending with one after Markovian children (module
/// docs); `None` when it is not, a side has no phase chain, or the re-run
/// cannot fail (the race is then R's alone).
pub(super) fn prepare(
    tree: &Graph,
    id: NodeId,
    t_max: f64,
    max_states: usize,
) -> Result<Option<Prepared>, AnalysisError> {
    let Some(ch) = chains(tree, id, max_states)? else {
        return Ok(None);
    };
    prepare_chains(ch, tree.node(id).name.clone(), t_max, max_states)
}

/// The re-run process `process` alone (`until_failure(Sequence(wait d,
/// C′))`, or with a first cycle of its own) prepared for its levels up to
/// `t_max`: the race against an `R` that never returns (one phase without
/// exits), so a level's `F` and `f` are the process's Failure by `t` and
/// its density — the law of its first failure, for a race with an `R` that
/// has no phase chain (`race::renewal_race`). `None` when it is no such
/// process, `C′` has no phase chain, or it never fails.
pub(super) fn prepare_process(
    tree: &Graph,
    process: NodeId,
    t_max: f64,
    max_states: usize,
) -> Result<Option<Prepared>, AnalysisError> {
    let Some((wait, rerun, first)) = renewal::process(tree, process) else {
        return Ok(None);
    };
    let chain = |n: NodeId| phase::markovian_chain_of(tree, n, max_states);
    let Some(rerun) = chain(rerun)? else {
        return Ok(None);
    };
    let first = match first {
        None => None,
        Some((d0, c0)) => match chain(c0)? {
            Some(c0) => Some((d0, c0)),
            None => return Ok(None),
        },
    };
    let never = PhaseChain {
        initial: vec![(0, 1.0)],
        initial_success: 0.0,
        initial_failure: 0.0,
        transitions: vec![Vec::new()],
        exit_success: vec![0.0],
        exit_failure: vec![0.0],
    };
    let ch = Chains {
        prefix: None,
        rest: never,
        rerun,
        wait,
        first,
    };
    prepare_chains(ch, tree.node(process).name.clone(), t_max, max_states)
}

/// [`prepare`] from the node's chains.
fn prepare_chains(
    ch: Chains,
    name: String,
    t_max: f64,
    max_states: usize,
) -> Result<Option<Prepared>, AnalysisError> {
    if ch.first.is_some() && ch.prefix.is_some() {
        // a first wait of its own after a random start: not on the grid
        return Ok(None);
    }
    let too_large = |states: f64| AnalysisError::StateBudget {
        node: name.clone(),
        states,
        budget: max_states,
    };
    let product =
        ch.rest.len() as f64 * (ch.rerun.len() + ch.first.as_ref().map_or(0, |f| f.1.len())) as f64;
    if product > max_states as f64 {
        return Err(too_large(product));
    }
    let Some(lv) = Levels::new(&ch) else {
        return Err(AnalysisError::Stiff {
            node: name.clone(),
            work: f64::INFINITY,
            limit: MAX_WORK,
        });
    };
    if !lv.c.is_finite() {
        // C′ always succeeds at once: never fails, the race is R's alone
        return Ok(None);
    }
    let levels = if t_max < lv.t0 {
        0
    } else {
        ((t_max - lv.t0) / lv.d).floor() as usize + 1
    };
    let depth = lv.depth(levels + 1);
    let stack = depth + 1;
    let lambda_all = lv.q.iter().copied().fold(0.0, f64::max);
    let steps = steps_of(&lv, lambda_all, lv.c);
    // the prefix's phases run out: the later levels step at the rate of
    // the race's own states (the work is counted as it is done too)
    let lambda_race = lv.q[lv.np..].iter().copied().fold(0.0, f64::max);
    let c_race = lv.flux[lv.np..].iter().copied().fold(0.0, f64::max);
    // the first levels step the stack; once the rate settles, a level
    // steps its top alone over the previous level's (`Prepared::run`)
    let early_levels = levels.min(2) as f64;
    let work = lv.nnz() as f64
        * (early_levels * stack as f64 * steps as f64
            + (levels as f64 - early_levels) * steps_of(&lv, lambda_race, c_race) as f64);
    // the levels' states, the stack's, the steps' four functionals of
    // every level (kept for the law), and two levels' tops
    let cells = (levels as f64 + 4.0 * stack as f64) * lv.dim as f64
        + 4.0 * levels as f64 * steps as f64
        + 2.0 * (2 * lv.nr + 2) as f64 * steps as f64;
    if cells / CELLS_PER_STATE > max_states as f64 {
        return Err(too_large(cells / CELLS_PER_STATE));
    }
    if work > MAX_WORK {
        return Err(AnalysisError::Stiff {
            node: name,
            work,
            limit: MAX_WORK,
        });
    }
    Ok(Some(Prepared {
        ch,
        lv,
        levels,
        depth,
        name,
    }))
}

/// Steps of a level's uniformization at rate `lambda` with flux `c` into
/// waits.
fn steps_of(lv: &Levels, lambda: f64, c: f64) -> usize {
    let win = poisson_window((lambda + c) * lv.d, LEVEL_EPS);
    win.left + win.weights.len()
}

impl Prepared {
    /// The period `d` and the start `t₀` of level 0.
    pub(super) fn period(&self) -> (f64, f64) {
        (self.lv.d, self.lv.t0)
    }

    /// The race's rest `R` (alone before `t₀`).
    pub(super) fn rest(&self) -> &PhaseChain {
        &self.ch.rest
    }

    /// The probabilities of Success and Failure at time 0.
    pub(super) fn atoms_at_zero(&self) -> [f64; 2] {
        self.lv.atoms_at_zero
    }

    /// The largest probability that a re-run fails at its start.
    pub(super) fn instant_failure(&self) -> f64 {
        self.lv.instant_failure
    }

    /// Runs the levels once, in order, handing each to `visit` (module
    /// docs); the steps keep only the outcome functionals, and the state at
    /// the level's end starts the next one.
    pub(super) fn run(
        &self,
        mut visit: impl FnMut(usize, Level) -> Result<(), AnalysisError>,
    ) -> Result<(), AnalysisError> {
        let lv = &self.lv;
        let (levels, depth) = (self.levels, self.depth);
        let stack = depth + 1;
        let (dim, nr, acc, w) = (lv.dim, lv.nr, lv.acc, lv.w);
        let mut done = 0.0f64;
        let mut starts: Vec<Vec<f64>> = Vec::with_capacity(levels);
        let mut before = lv.base;
        let mut start = lv.x0.clone();
        let mut u = vec![0.0f64; stack * dim];
        let mut next = vec![0.0f64; stack * dim];
        let mut end = vec![0.0f64; dim];
        // the previous level's top, step by step (module docs: one slot)
        let mut prev: Option<Top> = None;
        let mut below = vec![0.0f64; dim];
        for level in 0..levels {
            // drop prefix mass that no longer matters
            for x in start[..lv.np].iter_mut() {
                if x.abs() < DROP {
                    *x = 0.0;
                }
            }
            let atoms: f64 = start[w..w + nr].iter().sum();
            starts.push(start.clone());
            let lowest = level.saturating_sub(depth);
            let first_slot = stack - 1 - (level - lowest);
            // the rate: the prefix's phases before its first live one are dead
            let live_p = (0..lv.np)
                .find(|&s| starts[lowest..].iter().any(|x| x[s] != 0.0))
                .unwrap_or(lv.np);
            let lambda = lv.q[live_p..]
                .iter()
                .copied()
                .fold(0.0, f64::max)
                .max(1e-300);
            let c = lv.flux[live_p..].iter().copied().fold(0.0, f64::max);
            let n_steps = steps_of(lv, lambda, c);
            // the previous level's top at the same rate: this level's
            // levels below it are summed up in its steps
            let from = prev
                .take()
                .filter(|p| p.lambda == lambda && p.phi.len() == n_steps * nr);
            let slots = if from.is_some() {
                1
            } else {
                stack - first_slot
            };
            done += n_steps as f64 * slots as f64 * lv.nnz() as f64;
            if done > 2.0 * MAX_WORK {
                // the prefix lived longer than the estimate assumed
                return Err(AnalysisError::Stiff {
                    node: self.name.clone(),
                    work: done / (level + 1) as f64 * levels as f64,
                    limit: MAX_WORK,
                });
            }
            let mut top = Top {
                lambda,
                phi: Vec::with_capacity(n_steps * nr),
                waits: Vec::with_capacity(n_steps * (nr + 2)),
            };
            let mut rows: Vec<[f64; 4]> = Vec::with_capacity(n_steps);
            // the state at the level's end, summed as the steps go
            let closing = poisson_window(lambda * lv.d, LEVEL_EPS);
            end.iter_mut().for_each(|x| *x = 0.0);
            // the slots stepped here: the stack (levels level − depth ..=
            // level), or the top alone over the previous level's steps
            let (lo, len) = match from {
                Some(_) => (stack - 1, stack * dim),
                None => (first_slot, stack * dim),
            };
            u[..len].iter_mut().for_each(|x| *x = 0.0);
            if from.is_some() {
                u[lo * dim..].copy_from_slice(&start);
            } else {
                for (l, x) in starts.iter().enumerate().skip(lowest) {
                    let at = (stack - 1 - (level - l)) * dim;
                    u[at..at + dim].copy_from_slice(x);
                }
            }
            let top_at = (stack - 1) * dim;
            for step in 0..n_steps {
                let below_w = match &from {
                    Some(p) => &p.waits[step * (nr + 2)..(step + 1) * (nr + 2)],
                    None => &u[top_at - dim + w..top_at - dim + w + nr + 2],
                };
                below[w..w + nr + 2].copy_from_slice(below_w);
                rows.push(lv.outcomes(&below, &u[top_at..top_at + dim]));
                top.waits
                    .extend_from_slice(&u[top_at + w..top_at + w + nr + 2]);
                if let Some(&wgt) = step
                    .checked_sub(closing.left)
                    .and_then(|k| closing.weights.get(k))
                {
                    for (a, &b) in end.iter_mut().zip(&u[top_at..top_at + dim]) {
                        *a += wgt * b;
                    }
                }
                next[lo * dim..].iter_mut().for_each(|x| *x = 0.0);
                // flux re-entering at once from the level below
                let mut again = match &from {
                    Some(p) => lv.leave(
                        &p.phi[step * nr..(step + 1) * nr],
                        &mut next[top_at..top_at + dim],
                    ),
                    None => vec![0.0f64; nr],
                };
                for l in lo..stack {
                    let base = l * dim;
                    let mut phi = std::mem::take(&mut again);
                    for s in 0..dim {
                        let x = u[base + s];
                        if x == 0.0 {
                            continue;
                        }
                        let x = x / lambda;
                        next[base + s] += x * (lambda - lv.q[s]);
                        for &(t, rate) in &lv.a0[s] {
                            next[base + t] += x * rate;
                        }
                        for &(i, rate) in &lv.lag[s] {
                            phi[i] += x * rate;
                        }
                    }
                    if l + 1 < stack {
                        again = lv.leave(&phi, &mut next[base + dim..base + 2 * dim]);
                    } else {
                        top.phi.extend_from_slice(&phi);
                    }
                }
                std::mem::swap(&mut u, &mut next);
            }
            prev = Some(top);
            visit(
                level,
                Level {
                    start: lv.t0 + level as f64 * lv.d,
                    atoms,
                    lambda,
                    before,
                    rows,
                },
            )?;
            if level + 1 < levels {
                before[0] += end[acc];
                before[1] += end[acc + 1];
                start = lv.next_start(&starts[level], &end);
            }
        }
        Ok(())
    }
}

/// A level's top slot, step by step, for the level above: the flux
/// leaving it into waits (`nr` a step) and its waits' part (`W`, `nr + 2`
/// a step), what the next level reads of the level below it.
struct Top {
    lambda: f64,
    phi: Vec<f64>,
    waits: Vec<f64>,
}

/// `π(t)` at `times` of node `id` when it is a renewal race, or a Sequence
/// ending with one after Markovian children (module docs); `None` when it
/// is not, or a side has no phase chain.
pub(crate) fn curve(
    tree: &Graph,
    id: NodeId,
    times: &[f64],
    options: &CurveOptions,
) -> Result<Option<Vec<CurvePoint>>, AnalysisError> {
    let t_max = times.iter().copied().fold(0.0, f64::max);
    let Some(run) = prepare(tree, id, t_max, options.max_states)? else {
        return Ok(None);
    };
    let name = &run.name;
    let (d, t0) = run.period();
    let mut out: Vec<Option<CurvePoint>> = vec![None; times.len()];
    // before level 0 (a first wait of its own): R alone
    let early: Vec<usize> = (0..times.len()).filter(|&k| times[k] < t0).collect();
    if !early.is_empty() {
        let ts: Vec<f64> = early.iter().map(|&k| times[k]).collect();
        let pts = solve_chain(run.rest(), &ts, options, name)?;
        for (k, p) in early.into_iter().zip(pts) {
            out[k] = Some(p);
        }
    }
    // the points of each level, by level
    let mut by_level: Vec<Vec<(usize, f64)>> = vec![Vec::new(); run.levels];
    for (k, &t) in times.iter().enumerate() {
        if t >= t0 {
            let level = (((t - t0) / d).floor() as usize).min(run.levels - 1);
            let theta = (t - t0 - level as f64 * d).clamp(0.0, d);
            by_level[level].push((k, theta));
        }
    }
    run.run(|level, steps| {
        for &(k, theta) in &by_level[level] {
            let [s, f, _, _] = steps.at(theta);
            let (success, failure) = (s.clamp(0.0, 1.0), f.clamp(0.0, 1.0));
            out[k] = Some(CurvePoint {
                t: times[k],
                success,
                failure,
                running: (1.0 - success - failure).max(0.0),
            });
        }
        Ok(())
    })?;
    let points: Option<Vec<CurvePoint>> = out.into_iter().collect();
    match points {
        Some(p)
            if p.iter()
                .all(|x| x.success.is_finite() && x.failure.is_finite()) =>
        {
            Ok(Some(p))
        }
        _ => Err(AnalysisError::Numerical {
            node: name.clone(),
            what: "the renewal race's curve gave a non-finite probability".into(),
        }),
    }
}
