//! The race of a subtree against a **renewal process of re-runs** with a
//! fixed wait, exactly and without a series: Nav2's re-planning
//! PipelineSequence (`crate::tree::nav2::primitive_view` lowers a
//! `RateController(hz)` over a planner `C` to
//! `Parallel{M = 1, F = 1}(until_failure(Sequence(wait d, C′)), R)`, with
//! `d = 1/hz` and `R` the rest of the pipeline; a SpeedController, whose
//! first wait `d₀` differs from the later ones, to the process
//! `Sequence(wait d₀, C′₀, until_failure(Sequence(wait d, C′)))`).
//!
//! When `R` and `C′` have exact phase chains (generator `Q_R` over R's
//! transient phases, exit vectors to Success and Failure, initial vector
//! `α_R`; likewise `C′`), take the process at the start of each wait and
//! describe it by the row vector `v` over R's phases (sub-stochastic: the
//! mass of runs still going). One cycle is a linear map of `v`:
//!
//! * the wait: R runs alone for `d`. With `X = e^{Q d}` of R's chain (dense,
//!   double-double, rigorous bound, [`crate::solve::expm`]; or, where that
//!   is dearer, by uniformization row by row over the sparse chain, the
//!   Poisson mass left out below 1e-16) the phases
//!   after the wait are `v·E` (`E` the phase block of `X`), R's Success and
//!   Failure within the wait are `v·X_S`, `v·X_F`, and the first moments
//!   `E_i[τ·1{S, τ ≤ d}] = m_S(i) − Σ_k E_ik (d·h_S(k) + m_S(k))` (`h`, `m`
//!   R's absorption probabilities and time integrals per phase, in
//!   double-double: the one difference of the method);
//! * the re-run: `C′` runs beside R, a product chain of `(R phase, C′
//!   phase)` (the Kronecker sum; acyclic, since both chains are). From R
//!   phase `k` and `C′`'s initial vector, one forward pass in topological
//!   order gives `G[k][i]` = P(C′ succeeds while R is in phase i) (the next
//!   cycle starts there), its time integral `G₁`, and the probabilities and
//!   time integrals of R's Success, and of R's or `C′`'s Failure (both fail
//!   the node). `C′`'s instantaneous Success starts the next wait at once,
//!   its instantaneous Failure fails the node then.
//!
//! So `M = E·G` maps `v` from one cycle to the next, `M₁ = E·(d·G + G₁)` is
//! its time-weighted version, and the outcome vectors are `a = X_· + E·a_C`
//! (probabilities) and `b = b_wait + E·(d·a_C + b_C)` (time integrals). All
//! cycles together: `V = α_R (I − M)⁻¹`, `W = V M₁ (I − M)⁻¹` (the
//! time-weighted visits: the block map `[[M, M₁], [0, M]]`), and
//! `P(S) = α_S + V·a_S`, `E[T·1{S}] = W·a_S + V·b_S`, likewise Failure.
//! A first cycle of its own (wait `d₀`, re-run `C′₀`: its maps `M⁰`, `M⁰₁`,
//! `a⁰`, `b⁰` by the same passes) starts the loop at `v₁ = α_R M⁰` with
//! time-weighted mass `w₁ = α_R M⁰₁`: then `V = v₁ (I − M)⁻¹`,
//! `W = (w₁ + V M₁)(I − M)⁻¹`, and the first cycle adds `α_R·a⁰` and
//! `α_R·b⁰` to the outcomes (its passes and exponential add to the cost).
//!
//! Both chains are acyclic, so `M` is upper triangular, the solves are
//! substitutions, and its diagonal's complement
//! `1 − M_kk = (1 − e^{−q_k d}) + e^{−q_k d}·P(C′ does not succeed while R
//! stays in k)` is a sum of non-negative terms: every step but the wait's
//! moments adds non-negative terms only, so the figures keep their
//! relative accuracy (rounding, about 1e-13; no truncation of the
//! re-runs). Cost: `O(n_R³)` for the exponential (or `n_R · Λd · edges`
//! by uniformization) and `O(n_R² n_C)` for the passes, independent of the
//! number of re-runs; refused beyond 4e9 operations, or when the product
//! chain's states or the numbers kept (8 a state) exceed the state budget.
//!
//! Ties: R returns at time 0 only (a phase chain has no atom later), before
//! any re-run can fail (`d, d₀ > 0`); `C′` fails at a cycle's start only at
//! instants where R has no atom. So BT.CPP's child order decides nothing
//! here and either order of the Parallel's children is accepted.
//!
//! Size: one concern, a renewal loop's figures (the series of re-runs, its
//! cycle and the absorption solves with their exponential method chosen by
//! work); about 160 lines are comments, 60 tests.

use std::collections::HashMap;

use super::mrg::Policy;
use super::phase::ChainSize;
use super::{phase, AnalysisError, Figures};
use crate::ir::outcomes;
use crate::ir::{Graph, Op, Outcome};
use crate::solve::chain::PhaseChain;
use crate::solve::dd::Dd;
use crate::solve::expm::{self, MAX_DENSE_STATES};
use crate::tree::{Duration, NodeId};

/// Most operations (exponential and passes) the method takes on.
const MAX_WORK: f64 = 4e9;
/// The numbers it keeps (five `n_R × n_R` matrices and two vectors over
/// the product chain) count against the state budget at this many per
/// state (the default budget allows 3.2e7 numbers, 256 MB).
const CELLS_PER_STATE: f64 = 8.0;

/// What [`figures`] found.
pub(crate) enum Renewal {
    /// The node's exact figures.
    Figures(Figures),
    /// The node is not such a race, or a side has no phase chain.
    NotApplicable,
    /// Such a race, too large for the method.
    TooLarge { error: AnalysisError },
}

/// The parts of a renewal race.
pub(super) struct Parts {
    /// The re-run process: `until_failure(Sequence(wait, C′))`, or
    /// `Sequence(wait d₀, C′₀, until_failure(Sequence(wait, C′)))`.
    pub(super) process: NodeId,
    /// The fixed wait `d` (s).
    pub(super) wait: f64,
    /// The re-run `C′`.
    pub(super) rerun: NodeId,
    /// A first cycle that differs: its wait `d₀` (s) and re-run `C′₀`.
    pub(super) first: Option<(f64, NodeId)>,
    /// The raced subtree `R`.
    pub(super) rest: Rest,
}

/// The side `R` that the re-run process races.
pub(super) enum Rest {
    /// A subtree.
    Node(NodeId),
    /// The other returning children of a wider Parallel (`node`) with
    /// failure threshold 1: `R` is their Parallel with success threshold
    /// `m` and failure threshold 1 (see [`parts`]).
    Parallel {
        node: NodeId,
        m: usize,
        children: Vec<NodeId>,
    },
}

/// The size of `R`'s phase chain ([`rest_chain`]), estimated before
/// building it.
pub(super) fn rest_size(
    tree: &Graph,
    rest: &Rest,
    max_states: usize,
) -> Result<ChainSize, AnalysisError> {
    let mut memo = HashMap::new();
    match rest {
        Rest::Node(n) => phase::chain_size(tree, *n, max_states, &mut memo),
        Rest::Parallel { node, m, children } => {
            let sizes = match phase::children_sizes(tree, children, max_states, &mut memo)? {
                Ok(sizes) => sizes,
                Err(refusal) => return Ok(refusal),
            };
            let policy = Policy::Parallel {
                success_threshold: *m,
                failure_threshold: 1,
            };
            Ok(phase::product_size(
                &tree.node(*node).name,
                &sizes,
                policy,
                max_states,
            ))
        }
    }
}

/// The phase chain of `R`.
pub(super) fn rest_chain(
    tree: &Graph,
    rest: &Rest,
    max_states: usize,
) -> Result<Option<PhaseChain>, AnalysisError> {
    match rest {
        Rest::Node(n) => phase::markovian_chain_of(tree, *n, max_states),
        Rest::Parallel { node, m, children } => {
            if !children.iter().all(|&c| phase::markovian(tree, c)) {
                return Ok(None);
            }
            let chains = children
                .iter()
                .map(|&c| phase::chain_of(tree, c, max_states))
                .collect::<Result<Vec<_>, _>>()?;
            phase::parallel_chain(&tree.node(*node).name, &chains, *m, 1, max_states).map(Some)
        }
    }
}

/// The time of `w` when it is a wait: an action with ps 1 and a fixed
/// success time in (0, ∞).
fn wait_time(tree: &Graph, w: NodeId) -> Option<f64> {
    match &tree.node(w).kind {
        Op::Leaf(crate::ir::Leaf::Action(a)) if a.ps == 1.0 && a.pf == 0.0 => match a.success {
            Some(Duration::Fixed { time }) if time > 0.0 && time.is_finite() => Some(time),
            _ => None,
        },
        _ => None,
    }
}

/// `until_failure(Sequence(wait d, C′))`: `(d, C′)`.
fn renewal_loop(tree: &Graph, p: NodeId) -> Option<(f64, NodeId)> {
    let Op::Loop {
        child,
        until: Outcome::Failure,
    } = tree.node(p).kind
    else {
        return None;
    };
    let [w, c] = *tree.node(child).kind.sequence()? else {
        return None;
    };
    Some((wait_time(tree, w)?, c))
}

/// A re-run process: `(d, C′, first cycle)` (see [`Parts`]).
type Process = (f64, NodeId, Option<(f64, NodeId)>);

/// The re-run process `p` (see [`Parts`]).
pub(super) fn process(tree: &Graph, p: NodeId) -> Option<Process> {
    if let Some((d, c)) = renewal_loop(tree, p) {
        return Some((d, c, None));
    }
    // a first cycle of its own (Nav2's SpeedController), then the loop
    let [w0, c0, l] = *tree.node(p).kind.sequence()? else {
        return None;
    };
    let d0 = wait_time(tree, w0)?;
    let (d, c) = renewal_loop(tree, l)?;
    Some((d, c, Some((d0, c0))))
}

/// `Parallel{1, 1}(process, R)` (either order) with a re-run process; or
/// a Parallel with M ≥ 1 and (effective) failure threshold 1 over one
/// re-run process, children that never return (an endless loop: they
/// count towards neither threshold) and others: the process never
/// succeeds and its Failure fails the node, so the node is the race of the
/// process against `R` = Parallel{M, 1}(the others), which returns when
/// M of them have succeeded or one has failed (MoveIt Pro's
/// `KeepRunningUntilFailure` beside the actions it watches).
pub(super) fn parts(tree: &Graph, id: NodeId) -> Option<Parts> {
    let Op::KOfN {
        success: m,
        failure: f,
        children,
    } = &tree.node(id).kind
    else {
        return None;
    };
    let (m, n) = (*m, children.len());
    if m == 0 || m > n || (*f).min(n + 1 - m) != 1 {
        return None;
    }
    // two children: the process (which may never return) and R
    if let [a, b] = children[..] {
        if m == 1 && *f == 1 {
            let (p, rest) = if process(tree, a).is_some() {
                (a, b)
            } else {
                (b, a)
            };
            let (wait, rerun, first) = process(tree, p)?;
            return Some(Parts {
                process: p,
                wait,
                rerun,
                first,
                rest: Rest::Node(rest),
            });
        }
    }
    let returning: Vec<NodeId> = children
        .iter()
        .copied()
        .filter(|&c| outcomes(tree, c) != (false, false))
        .collect();
    let mut procs = returning.iter().filter(|&&c| process(tree, c).is_some());
    let (Some(&p), None) = (procs.next(), procs.next()) else {
        return None;
    };
    let (wait, rerun, first) = process(tree, p)?;
    let others: Vec<NodeId> = returning.iter().copied().filter(|&c| c != p).collect();
    let rest = match others[..] {
        _ if m <= others.len() => Rest::Parallel {
            node: id,
            m,
            children: others,
        },
        _ => return None,
    };
    Some(Parts {
        process: p,
        wait,
        rerun,
        first,
        rest,
    })
}

/// The re-runs a truncated series would need (`p^K ≤ 1e-14`, `p` = P(C′
/// succeeds)), as the loop series counts them.
fn series_terms(c: &PhaseChain) -> f64 {
    let a = crate::solve::transient::absorption_by_phase(c);
    let p: f64 = c.initial_success
        + c.initial
            .iter()
            .map(|&(i, w)| w * a.to_success[i])
            .sum::<f64>();
    if p <= 0.0 {
        return 1.0;
    }
    (1e-14f64.ln() / p.min(1.0 - 1e-16).ln()).ceil().max(1.0)
}

/// When node `id` is a renewal race whose re-run has a phase chain: the
/// re-run process and the number of re-runs its law's series needs.
pub(crate) fn series(tree: &Graph, id: NodeId, max_states: usize) -> Option<(NodeId, f64)> {
    let p = parts(tree, id)?;
    let c = phase::chain_within(tree, p.rerun, max_states).ok()??;
    Some((p.process, series_terms(&c)))
}

/// The exact figures of node `id` when it is a renewal race whose sides
/// have phase chains (module docs).
pub(crate) fn figures(
    tree: &Graph,
    id: NodeId,
    max_states: usize,
) -> Result<Renewal, AnalysisError> {
    let Some(p) = parts(tree, id) else {
        return Ok(Renewal::NotApplicable);
    };
    let name = &tree.node(id).name;
    // a side's chain, `None` where it has none, its refusal where its size
    // is over the budget (estimated before building)
    let chain = |n: NodeId| match phase::chain_size(tree, n, max_states, &mut HashMap::new())? {
        ChainSize::Within(_) => phase::chain_of(tree, n, max_states).map(Ok),
        ChainSize::NotMarkovian(_) => Ok(Err(None)),
        ChainSize::Over(e) => Ok(Err(Some(e))),
    };
    let c = match chain(p.rerun)? {
        Ok(c) => c,
        Err(None) => return Ok(Renewal::NotApplicable),
        Err(Some(error)) => return Ok(Renewal::TooLarge { error }),
    };
    let r = match rest_size(tree, &p.rest, max_states)? {
        ChainSize::Within(_) => {
            rest_chain(tree, &p.rest, max_states)?.expect("a rest with a chain size has a chain")
        }
        ChainSize::NotMarkovian(_) => return Ok(Renewal::NotApplicable),
        ChainSize::Over(error) => return Ok(Renewal::TooLarge { error }),
    };
    let first = match p.first {
        None => None,
        Some((d0, c0)) => match chain(c0)? {
            Ok(c0) => Some((d0, c0)),
            Err(None) => return Ok(Renewal::NotApplicable),
            Err(Some(error)) => return Ok(Renewal::TooLarge { error }),
        },
    };
    let nr = r.len();
    let edges_r: usize = r.transitions.iter().map(Vec::len).sum::<usize>() + 3 * nr;
    // one cycle's work: its wait's exponential and the passes (from each
    // start phase, the product rows below it)
    let cycle_work = |c: &PhaseChain, d: f64| {
        let nc = c.len();
        let edges_c: usize = c.transitions.iter().map(Vec::len).sum::<usize>() + 3 * nc;
        let passes = nr as f64 * (edges_r as f64 * nc as f64 + edges_c as f64 * nr as f64);
        let wait_work = match wait_method(&r, d) {
            Some(Exponential::Dense) => expm::dense_work(&r, &[d]),
            Some(Exponential::Uniformized) => uniformized_work(&r, d),
            None => f64::INFINITY,
        };
        wait_work + passes + 4.0 * (nr as f64).powi(3)
    };
    let mut work = cycle_work(&c, p.wait);
    // the product chains' states (the first cycle's, when it has one, are
    // freed before the loop's are kept)
    let mut product = nr as f64 * c.len() as f64;
    if let Some((d0, c0)) = &first {
        work += cycle_work(c0, *d0);
        product = product.max(nr as f64 * c0.len() as f64);
    }
    let too_large = |states: f64, budget: usize| Renewal::TooLarge {
        error: AnalysisError::StateBudget {
            node: name.clone(),
            states,
            budget,
        },
    };
    // the numbers kept, as states of the budget (8 numbers a state)
    let cells = (5.0 * (nr as f64).powi(2) + 2.0 * product) / CELLS_PER_STATE;
    if product.max(cells) > max_states as f64 {
        return Ok(too_large(product.max(cells), max_states));
    }
    if work > MAX_WORK {
        return Ok(Renewal::TooLarge {
            error: AnalysisError::Stiff {
                node: name.clone(),
                work,
                limit: MAX_WORK,
            },
        });
    }
    let first = first.as_ref().map(|(d0, c0)| (c0, *d0));
    let f = solve(&r, &c, p.wait, first).ok_or_else(|| AnalysisError::Numerical {
        node: name.clone(),
        what: "the renewal race of its re-runs gave a non-finite or negative figure".into(),
    })?;
    Ok(Renewal::Figures(f))
}

fn neg(x: Dd) -> Dd {
    Dd {
        hi: -x.hi,
        lo: -x.lo,
    }
}

/// R's absorption per phase, in double-double: `(h_S, h_F, m_S, m_F)`.
fn absorption_dd(r: &PhaseChain) -> [Vec<Dd>; 4] {
    let n = r.len();
    let mut out = [(); 4].map(|_| vec![Dd::ZERO; n]);
    for i in (0..n).rev() {
        let q = r.total_rate(i);
        if q <= 0.0 {
            // a trap: never absorbed
            continue;
        }
        let mut acc = [
            Dd::from_f64(r.exit_success[i]),
            Dd::from_f64(r.exit_failure[i]),
            Dd::ZERO,
            Dd::ZERO,
        ];
        for &(j, rate) in &r.transitions[i] {
            let rate = Dd::from_f64(rate);
            for (a, o) in acc.iter_mut().zip(&out) {
                *a = *a + rate * o[j];
            }
        }
        let (hs, hf) = (acc[0].div_f64(q), acc[1].div_f64(q));
        out[0][i] = hs;
        out[1][i] = hf;
        out[2][i] = (hs + acc[2]).div_f64(q);
        out[3][i] = (hf + acc[3]).div_f64(q);
    }
    out
}

/// One cycle (a wait `d`, then a run of C beside R) as maps of the row
/// vector over R's phases at its start (module docs; `n = n_R`, row major).
struct Cycle {
    /// `M = E·G`: the phases at the next cycle's start.
    mm: Vec<f64>,
    /// `M₁ = E·(d·G + G₁)`: its time-weighted version.
    m1: Vec<f64>,
    /// The node's outcomes within the cycle per start phase: `[P(S), P(F)]`.
    a: Vec<[f64; 2]>,
    /// Their time integrals from the cycle's start.
    b: Vec<[f64; 2]>,
    /// `1 − M_kk` as non-negative terms.
    stay: Vec<f64>,
}

/// The cycle of wait `d` and re-run C beside R (`r.len() > 0`); `None`
/// when a phase has no exit.
fn cycle(r: &PhaseChain, c: &PhaseChain, d: f64) -> Option<Cycle> {
    let (nr, nc) = (r.len(), c.len());
    // the wait: E, R's returns by d, and their time integrals
    let (e, wait_a) = match wait_method(r, d) {
        Some(Exponential::Dense) => dense_exponential(r, d),
        _ => uniformized_exponential(r, d),
    };
    let [hs, hf, ms, mf] = absorption_dd(r);
    let mut wait_b = vec![[0.0f64; 2]; nr];
    let dd = Dd::from_f64(d);
    for i in 0..nr {
        let (mut after_s, mut after_f) = (Dd::ZERO, Dd::ZERO);
        for k in i..nr {
            let eik = e[i * nr + k];
            if eik != 0.0 {
                let eik = Dd::from_f64(eik);
                after_s = after_s + eik * (dd * hs[k] + ms[k]);
                after_f = after_f + eik * (dd * hf[k] + mf[k]);
            }
        }
        wait_b[i] = [
            (ms[i] + neg(after_s)).to_f64().max(0.0),
            (mf[i] + neg(after_f)).to_f64().max(0.0),
        ];
    }
    // the re-run beside R: forward passes over the product chain
    let qr: Vec<f64> = (0..nr).map(|i| r.total_rate(i)).collect();
    let qc: Vec<f64> = (0..nc).map(|j| c.total_rate(j)).collect();
    let mut g = vec![0.0f64; nr * nr];
    let mut g1 = vec![0.0f64; nr * nr];
    // [P(S), P(F), E[τ·1{S}], E[τ·1{F}]] of the node during the re-run
    let mut run = vec![[0.0f64; 4]; nr];
    // P(C′ does not succeed while R stays in the start phase)
    let mut leave = vec![0.0f64; nr];
    let mut prob = vec![0.0f64; nr * nc];
    let mut time = vec![0.0f64; nr * nc];
    for k in 0..nr {
        prob[k * nc..].iter_mut().for_each(|x| *x = 0.0);
        time[k * nc..].iter_mut().for_each(|x| *x = 0.0);
        g[k * nr + k] += c.initial_success;
        run[k][1] += c.initial_failure;
        leave[k] += c.initial_failure;
        for &(j, w) in &c.initial {
            prob[k * nc + j] += w;
        }
        for i in k..nr {
            for j in 0..nc {
                let at = i * nc + j;
                let p = prob[at];
                if p == 0.0 {
                    continue;
                }
                let q = qr[i] + qc[j];
                if q <= 0.0 {
                    return None;
                }
                // E[time on leaving · 1{here}]
                let t = time[at] + p / q;
                let (pq, tq) = (p / q, t / q);
                for &(i2, rate) in &r.transitions[i] {
                    prob[i2 * nc + j] += pq * rate;
                    time[i2 * nc + j] += tq * rate;
                }
                for &(j2, rate) in &c.transitions[j] {
                    prob[i * nc + j2] += pq * rate;
                    time[i * nc + j2] += tq * rate;
                }
                let fail = r.exit_failure[i] + c.exit_failure[j];
                run[k][0] += pq * r.exit_success[i];
                run[k][2] += tq * r.exit_success[i];
                run[k][1] += pq * fail;
                run[k][3] += tq * fail;
                g[k * nr + i] += pq * c.exit_success[j];
                g1[k * nr + i] += tq * c.exit_success[j];
                if i == k {
                    leave[k] += pq * (qr[k] + c.exit_failure[j]);
                }
            }
        }
    }
    // one cycle: M = E·G, M₁ = E·(d·G + G₁), outcome vectors a, b
    let mut mm = vec![0.0f64; nr * nr];
    let mut m1 = vec![0.0f64; nr * nr];
    let mut a = vec![[0.0f64; 2]; nr];
    let mut b = vec![[0.0f64; 2]; nr];
    for k in 0..nr {
        a[k] = wait_a[k];
        b[k] = wait_b[k];
        for i in k..nr {
            let eki = e[k * nr + i];
            if eki == 0.0 {
                continue;
            }
            for j in i..nr {
                mm[k * nr + j] += eki * g[i * nr + j];
                m1[k * nr + j] += eki * (d * g[i * nr + j] + g1[i * nr + j]);
            }
            for o in 0..2 {
                a[k][o] += eki * run[i][o];
                b[k][o] += eki * (d * run[i][o] + run[i][2 + o]);
            }
        }
    }
    // 1 − M_kk as non-negative terms
    let stay: Vec<f64> = (0..nr)
        .map(|k| {
            let gone = -(-qr[k] * d).exp_m1();
            gone + (1.0 - gone) * leave[k]
        })
        .collect();
    Some(Cycle { mm, m1, a, b, stay })
}

/// The figures of the race of R against the re-runs of C with wait `d`,
/// after a first cycle of its own when `first` = `(C₀, d₀)` is given (the
/// process `Sequence(wait d₀, C₀, until_failure(Sequence(wait d, C)))`):
/// module docs; `None` when a figure is not finite.
///
/// The first cycle maps R's initial vector `α` (at time 0) to
/// `v₁ = α M₀` and the time-weighted `w₁ = α M₀₁`, with outcomes `α·a₀`,
/// `α·b₀`; the cycles from there visit `V = v₁ (I − M)⁻¹` and
/// `W = (w₁ + V M₁)(I − M)⁻¹` (`w_{n+1} = w_n M + v_n M₁`, summed).
fn solve(
    r: &PhaseChain,
    c: &PhaseChain,
    d: f64,
    first: Option<(&PhaseChain, f64)>,
) -> Option<Figures> {
    let nr = r.len();
    let (a_s0, a_f0) = (r.initial_success, r.initial_failure);
    if nr == 0 {
        return finish(a_s0, a_f0, 0.0, 0.0);
    }
    let mut alpha = vec![0.0f64; nr];
    for &(i, w) in &r.initial {
        alpha[i] += w;
    }
    let (mut ps, mut pf, mut ts, mut tf) = (a_s0, a_f0, 0.0, 0.0);
    // the start of the loop's first cycle: mass and time-weighted mass
    let mut start = alpha;
    let mut start_w = vec![0.0f64; nr];
    if let Some((c0, d0)) = first {
        let f = cycle(r, c0, d0)?;
        let mut v1 = vec![0.0f64; nr];
        for (i, &x) in start.iter().enumerate() {
            if x == 0.0 {
                continue;
            }
            for j in i..nr {
                v1[j] += x * f.mm[i * nr + j];
                start_w[j] += x * f.m1[i * nr + j];
            }
            ps += x * f.a[i][0];
            pf += x * f.a[i][1];
            ts += x * f.b[i][0];
            tf += x * f.b[i][1];
        }
        start = v1;
    }
    let Cycle { mm, m1, a, b, stay } = cycle(r, c, d)?;
    if stay.iter().any(|&s| s <= 0.0 || !s.is_finite()) {
        return None;
    }
    // V (I − M) = v₁ and W (I − M) = w₁ + V M₁ (v₁ = α_R, w₁ = 0 without
    // a first cycle), by forward substitution
    let substitute = |rhs: &[f64]| -> Vec<f64> {
        let mut out = vec![0.0f64; nr];
        for j in 0..nr {
            let mut s = rhs[j];
            for i in 0..j {
                s += out[i] * mm[i * nr + j];
            }
            out[j] = s / stay[j];
        }
        out
    };
    let v = substitute(&start);
    let mut u = start_w;
    for i in 0..nr {
        for j in i..nr {
            u[j] += v[i] * m1[i * nr + j];
        }
    }
    let w = substitute(&u);
    for k in 0..nr {
        ps += v[k] * a[k][0];
        pf += v[k] * a[k][1];
        ts += w[k] * a[k][0] + v[k] * b[k][0];
        tf += w[k] * a[k][1] + v[k] * b[k][1];
    }
    finish(ps, pf, ts, tf)
}

/// `E` (R's phases after a wait `d`, row major) and `[P_i(S by d),
/// P_i(F by d)]` by the cheaper exact method; `None` when both exceed the
/// work limit (the renewal curve's use, `super::renewal_curve`).
pub(super) fn wait_exponential(r: &PhaseChain, d: f64) -> Option<(Vec<f64>, Vec<[f64; 2]>)> {
    match wait_method(r, d)? {
        Exponential::Dense => Some(dense_exponential(r, d)),
        Exponential::Uniformized => Some(uniformized_exponential(r, d)),
    }
}

/// How `e^{Q_R d}` is computed.
#[derive(Clone, Copy, PartialEq)]
enum Exponential {
    /// Dense scaling and squaring in double-double ([`expm`]).
    Dense,
    /// Uniformization, row by row over the sparse chain.
    Uniformized,
}

/// The cheaper way to `e^{Q_R d}` and its operation count, `None` when
/// both exceed [`MAX_WORK`].
fn wait_method(r: &PhaseChain, d: f64) -> Option<Exponential> {
    let n = r.len();
    let dense = if n + 2 <= MAX_DENSE_STATES {
        expm::dense_work(r, &[d])
    } else {
        f64::INFINITY
    };
    let uniformized = uniformized_work(r, d);
    let (method, work) = if dense <= uniformized {
        (Exponential::Dense, dense)
    } else {
        (Exponential::Uniformized, uniformized)
    };
    (work <= MAX_WORK).then_some(method)
}

/// Operations of [`uniformized_exponential`]: one row per phase, each
/// `Λd + 8√(Λd) + 16` steps over the chain's transitions.
fn uniformized_work(r: &PhaseChain, d: f64) -> f64 {
    let n = r.len();
    let lambda = (0..n).map(|i| r.total_rate(i)).fold(0.0, f64::max) * d;
    let nnz = r.transitions.iter().map(Vec::len).sum::<usize>() + 3 * n;
    n as f64 * (lambda + 8.0 * lambda.sqrt() + 16.0) * nnz as f64
}

/// `E` (phases, row major) and `[P_i(S by d), P_i(F by d)]` from the dense
/// double-double exponential (rigorous bound in [`expm`]).
fn dense_exponential(r: &PhaseChain, d: f64) -> (Vec<f64>, Vec<[f64; 2]>) {
    let n = r.len();
    let m = n + 2;
    let (x, _bound) = expm::exponential_matrix(r, d);
    let mut e = vec![0.0f64; n * n];
    let mut a = vec![[0.0f64; 2]; n];
    for i in 0..n {
        for k in i..n {
            e[i * n + k] = x[i * m + k].to_f64().max(0.0);
        }
        a[i] = [
            x[i * m + n].to_f64().max(0.0),
            x[i * m + n + 1].to_f64().max(0.0),
        ];
    }
    (e, a)
}

/// The same by uniformization: row i is `Σ_k Poisson(k; Λd) e_i P^k` with
/// `P = I + Q/Λ` (non-negative terms), the Poisson mass left out at most
/// 1e-16 ([`crate::solve::transient::poisson_window`]).
fn uniformized_exponential(r: &PhaseChain, d: f64) -> (Vec<f64>, Vec<[f64; 2]>) {
    let n = r.len();
    let q: Vec<f64> = (0..n).map(|i| r.total_rate(i)).collect();
    let lambda = q.iter().copied().fold(0.0, f64::max);
    let window = crate::solve::transient::poisson_window(lambda * d, 1e-16);
    let steps = window.left + window.weights.len();
    let mut e = vec![0.0f64; n * n];
    let mut a = vec![[0.0f64; 2]; n];
    let mut v = vec![0.0f64; n];
    let mut next = vec![0.0f64; n];
    for i in 0..n {
        v[i..].iter_mut().for_each(|x| *x = 0.0);
        v[i] = 1.0;
        let (mut s, mut f) = (0.0f64, 0.0f64);
        for step in 0..steps {
            if step >= window.left {
                let w = window.weights[step - window.left];
                for k in i..n {
                    e[i * n + k] += w * v[k];
                }
                a[i][0] += w * s;
                a[i][1] += w * f;
            }
            if step + 1 == steps {
                break;
            }
            next[i..].iter_mut().for_each(|x| *x = 0.0);
            for k in i..n {
                let x = v[k];
                if x == 0.0 {
                    continue;
                }
                let x = x / lambda;
                next[k] += x * (lambda - q[k]);
                for &(j, rate) in &r.transitions[k] {
                    next[j] += x * rate;
                }
                s += x * r.exit_success[k];
                f += x * r.exit_failure[k];
            }
            std::mem::swap(&mut v, &mut next);
        }
    }
    (e, a)
}

fn finish(ps: f64, pf: f64, ts: f64, tf: f64) -> Option<Figures> {
    let all = [ps, pf, ts, tf];
    if all.iter().any(|x| !x.is_finite() || *x < 0.0) {
        return None;
    }
    Some(Figures::from_moments([ps, pf, ts, tf]))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A chain with branching and rates over three decades.
    fn chain() -> PhaseChain {
        let mut c = PhaseChain::default();
        for _ in 0..5 {
            c.push_phase();
        }
        c.initial = vec![(0, 0.6), (1, 0.4)];
        c.transitions[0] = vec![(2, 3.0), (3, 0.5)];
        c.transitions[1] = vec![(3, 0.02)];
        c.transitions[2] = vec![(4, 7.0)];
        c.exit_success = vec![0.1, 0.01, 0.0, 0.3, 2.0];
        c.exit_failure = vec![0.05, 0.0, 1.0, 0.2, 0.5];
        c
    }

    #[test]
    fn dense_and_uniformized_exponentials_agree() {
        let c = chain();
        for d in [0.01, 0.7, 3.0] {
            let (e1, a1) = dense_exponential(&c, d);
            let (e2, a2) = uniformized_exponential(&c, d);
            for (x, y) in e1.iter().zip(&e2) {
                assert!((x - y).abs() < 1e-14, "d = {d}: {x} vs {y}");
            }
            for (x, y) in a1.iter().zip(&a2) {
                assert!((x[0] - y[0]).abs() < 1e-14 && (x[1] - y[1]).abs() < 1e-14);
            }
            // rows are distributions: phases, Success and Failure sum to 1
            for i in 0..c.len() {
                let row: f64 =
                    e1[i * c.len()..(i + 1) * c.len()].iter().sum::<f64>() + a1[i][0] + a1[i][1];
                assert!((row - 1.0).abs() < 1e-14, "row {i}: {row}");
            }
        }
    }

    #[test]
    fn a_rerun_that_cannot_fail_leaves_the_rest_alone() {
        // C′ always succeeds: the node returns when R does, with R's figures
        let r = chain();
        let mut c = PhaseChain::default();
        let i = c.push_phase();
        c.exit_success[i] = 4.0;
        c.initial.push((i, 1.0));
        let f = solve(&r, &c, 0.5, None).expect("finite");
        let a = crate::solve::transient::absorption_by_phase(&r);
        let (mut ps, mut ts, mut pf, mut tf) = (0.0, 0.0, 0.0, 0.0);
        for &(i, w) in &r.initial {
            ps += w * a.to_success[i];
            ts += w * a.time_to_success[i];
            pf += w * a.to_failure[i];
            tf += w * a.time_to_failure[i];
        }
        assert!((f.ps - ps).abs() < 1e-14, "{f:?} vs {ps}");
        assert!((f.pf - pf).abs() < 1e-14, "{f:?} vs {pf}");
        assert!((f.mtts.unwrap() - ts / ps).abs() < 1e-12 * ts / ps);
        assert!((f.mttf.unwrap() - tf / pf).abs() < 1e-12 * tf / pf);
    }
}
