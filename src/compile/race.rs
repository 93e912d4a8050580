//! Parallel nodes with any thresholds and mixed timing: the *race* of the
//! children, by counting.
//!
//! Until a Parallel node returns, its N children run independently. Take
//! them unhalted and let `K_t`, `J_t` be the numbers that have succeeded and
//! failed by t. The node (success threshold M, failure threshold F; it also
//! fails once success is impossible, so `F_eff = min(F, N − M + 1)`) is
//! still running at t⁻ iff `K_{t⁻} < M` and `J_{t⁻} < F_eff`: counts only
//! grow, and a threshold met earlier would have ended it. When both
//! thresholds can be met (`F_eff < N − M + 1`, an "independent" failure
//! threshold) which one comes first matters, and the node's law is:
//!
//! * **densities** between instants: child h returning Success at t ends the
//!   node with Success iff among the others exactly M − 1 have succeeded and
//!   fewer than F_eff failed, so
//!   `s(t) = Σ_h s_h(t) · P(others: K = M − 1, J < F_eff at t)` and likewise
//!   `f(t)`; a dynamic programme over the children with the counts capped
//!   (and a "which child returns now" layer, as in dual numbers) gives both
//!   and the running probability in O(N·M·F) ([`race_densities`]);
//! * **atoms** at the instants where children may return with positive
//!   probability (conditions at 0, fixed times, shifted atoms): BT.CPP's
//!   rule — children that returned before the instant are already counted,
//!   then within the instant the children are visited in child order and the
//!   node returns at the first threshold met ([`resolve_instant`], a
//!   programme over the counts before the instant and the order of the
//!   returns within it). Instants equal within 1e-12 relative are the same.
//!
//! The children's laws are their exact phase chains, shifted phase-type
//! mixtures ([`shifted`]), counted Parallels with the book's thresholds
//! (whose `S(t) = P(K_t ≥ M)` needs no integral) or races themselves.
//! `S(t) = Σ_{τ ≤ t} atom_S(τ) + ∫_0^t s`, computed by Gauss–Legendre
//! quadrature on panels cut at every instant and shift of the subtree (where
//! the densities jump or kink) and, for fast phases, at 8^k / the fastest
//! rate; each panel's 24-point sum is accepted when it agrees with the
//! 12-point one to 1e-13 relative (1e-16 absolute), panels are halved
//! otherwise. The figures are the limits: `P(S) = S(∞)`, `E[T·1{S}] = Σ τ
//! atom_S(τ) + ∫ t s(t) dt`, the tail integrated on doubling panels until the
//! running probability (exact, from the programme) is below 1e-16 and its
//! contribution to the mean below 1e-14 relative. The quadrature error is
//! an *estimate*, not a bound.
//!
//! Size: one concern, the race of a Parallel's children: its racers, the
//! counting at instants and between them, and the figures and curve entry
//! points (about 200 lines are comments, 120 tests).

use std::cell::RefCell;

use super::chain_curve::{sample_weighted, sample_weighted_kept, shifted_times};
use super::children::{Children, Representation, ReturnLaw};
use super::curve_options::CurvePoint;
use super::phase::ChainSize;
use super::renewal::Renewal;
use super::renewal_curve;
use super::shifted::{self, ShiftedLaw};
use super::{counts, AnalysisError, Figures};
use crate::ir::{Graph, Op};
use crate::solve::chain::PhaseChain;
use crate::solve::quadrature::GaussLegendre;
use crate::solve::transient::{uniformization_work, WeightedSteps};
use crate::tree::nav2::MAX_RERUN_TERMS;
use crate::tree::same_instant;
use crate::tree::{Duration, NodeId};

/// Points of the quadrature rule (the error is estimated against half).
const RULE: usize = 24;
/// Relative and absolute acceptance of a panel.
const RELATIVE: f64 = 1e-13;
const ABSOLUTE: f64 = 1e-16;
/// Most refinement rounds.
const MAX_ROUNDS: usize = 60;
/// Largest resolution programme (children × M³ × F³ cells) for the atoms.
const MAX_INSTANT_WORK: f64 = 1e9;

/// Whether a Parallel with these thresholds is a race (both thresholds can
/// be met), rather than a count with the book's thresholds.
pub(crate) fn is_race(n: usize, m: usize, f: usize) -> bool {
    f.min(n + 1 - m) < n + 1 - m
}

/// The law of a subtree, ready to be evaluated at any times.
pub(crate) enum Racer {
    /// An exact phase chain, and its uniformization pass kept between
    /// calls (the quadrature's rounds ask it at new times).
    Chain(PhaseChain, Box<RefCell<Option<WeightedSteps>>>),
    /// A shifted phase-type mixture.
    Shifted(ShiftedLaw),
    /// A Parallel whose failure threshold is the book's (F = N − M + 1).
    Counted {
        m: usize,
        f: usize,
        children: Vec<Racer>,
    },
    /// A Parallel whose thresholds can both be met.
    Race(Box<Race>),
    /// The first failure of a re-run process (a renewal loop) from its
    /// levels on `[0, horizon]` ([`renewal_curve::prepare_process`]).
    Renewal(Box<RenewalLoop>),
    /// A map of a racer's outcomes (an inverter, a force decorator).
    Mapped {
        inner: Box<Racer>,
        /// Where the inner Success and Failure go (0: Success, 1: Failure).
        to: [usize; 2],
    },
    /// Any subtree: its composed law ([`HorizonLaw`]) on a horizon past
    /// which it has returned but for [`LAW_TAIL`] of its mass.
    Law(Box<dyn ReturnLaw>),
}

/// Mass a [`Racer::Law`] may leave unreturned past its horizon (its
/// probabilities are held there: the race's figures change by at most
/// this, its mean times by this times the node's time scale).
const LAW_TAIL: f64 = 1e-13;

/// Numerical error a [`Racer::Law`] may have in its returned mass where
/// its horizon is past its tail bound: the interpolation's error
/// estimates (1e-15 of mass per panel) over thousands of panels and
/// convolutions.
const LAW_ERROR: f64 = 1e-11;

/// Most work (operations) of one uniformization pass of a race's chains
/// to the time by which it has returned, as the curve's default limit: its
/// figures take a few such passes (one per round of adaptive panels). An
/// upper bound (the tail bound's time can be several times the one the
/// integration stops at, and the solver skips zero entries): MoveIt Pro's
/// satellite tree, estimated at 2e10, is answered in 1.7 s.
const MAX_PASS_WORK: f64 = super::curve_options::DEFAULT_MAX_WORK;

/// Most phases (over all components) of a shifted mixture that a race
/// samples: every row of it is one transient pass per component, so a
/// loop's mixture (one component per number of re-runs, each a chain of
/// that many cycles) costs the square of its re-runs per row — its
/// composed law ([`Racer::Law`]) is sampled at the cost of interpolation.
const MAX_SHIFTED_PHASES: usize = 1024;

/// Most doublings of a [`Racer::Law`]'s horizon.
const LAW_DOUBLINGS: usize = 12;

/// How far past a [`Racer::Law`]'s horizon its settled time may be for the
/// horizon to jump there at once (a deficit within [`LAW_ERROR`]) instead
/// of doubling towards it.
const SETTLED_JUMP: f64 = 8.0;

/// How far past `32 ×` its mean time a [`Racer::Law`]'s settled time may
/// be for its first horizon to be the settled time: a law whose
/// interpolation error exceeds [`LAW_TAIL`] (loops, lattices of fixed
/// times) ends there anyway, and one build at a horizon up to this much
/// longer costs less than the builds of the doublings towards it (the
/// random-tree survey: 75 s → 63 s over 300 trees, its slowest 13 s → 4.7 s).
const START_AT_SETTLED: f64 = 4.0;

/// A re-run process's law of first failure on `[0, horizon]`, level by
/// level; beyond the horizon its Failure stays at its value there (its
/// race's horizon is chosen where that no longer matters, see
/// [`renewal_race`]).
pub(crate) struct RenewalLoop {
    levels: Vec<renewal_curve::Level>,
    /// The period `d` and the start of level 0 `t₀`.
    d: f64,
    t0: f64,
    horizon: f64,
}

impl RenewalLoop {
    /// `[S, F, s, f]` at `t`: never Success; Failure by `t` and its
    /// density (continuous: no atoms).
    fn row(&self, t: f64) -> Row {
        if t < self.t0 || self.levels.is_empty() {
            return [0.0; 4];
        }
        if t > self.horizon {
            let [_, f, _, _] = self.row(self.horizon);
            return [0.0, f, 0.0, 0.0];
        }
        let k = (((t - self.t0) / self.d).floor().max(0.0) as usize).min(self.levels.len() - 1);
        let l = &self.levels[k];
        let [_, f, _, fd] = l.at((t - l.start).clamp(0.0, self.d));
        [0.0, f, 0.0, fd]
    }
}

/// A race node: its children and its atoms.
pub(crate) struct Race {
    name: String,
    m: usize,
    f: usize,
    children: Vec<Racer>,
    /// `(τ, atom_S, atom_F)`, by time.
    atoms: Vec<(f64, f64, f64)>,
    /// Where its densities may jump or kink.
    cuts: Vec<f64>,
}

/// `[S, F, s, f]`: probabilities of having succeeded and failed, and densities.
type Row = [f64; 4];

fn sorted_unique(mut v: Vec<f64>) -> Vec<f64> {
    v.retain(|t| t.is_finite() && *t >= 0.0);
    v.sort_by(f64::total_cmp);
    v.dedup_by(|a, b| same_instant(*a, *b));
    v
}

fn numerical(name: &str, what: &str) -> AnalysisError {
    AnalysisError::Numerical {
        node: name.to_string(),
        what: what.to_string(),
    }
}

fn stiff(name: &str, chain: &PhaseChain, times: &[f64]) -> AnalysisError {
    AnalysisError::Stiff {
        node: name.to_string(),
        work: crate::solve::transient::uniformization_work(chain, times),
        limit: crate::solve::transient::MAX_SINGLE_PASS_STEPS as f64,
    }
}

impl Racer {
    /// A chain racer, its pass not run yet.
    fn chain(c: PhaseChain) -> Racer {
        Racer::Chain(c, Box::default())
    }

    /// The law of the subtree at `id`, from its planned representation
    /// ([`Plan`]): its phase chain, a shifted mixture (deterministic, mixed
    /// or looping subtrees), or a counted Parallel or race of its children's
    /// laws.
    ///
    /// Exact on `[0, horizon]` only (a child of a node that has returned by
    /// `horizon` whatever happens; `f64::INFINITY` for all time): a shifted
    /// mixture keeps only the components that start by then
    /// ([`shifted::shifted_law_within`]).
    fn build_within(plan: &dyn Children, id: NodeId, horizon: f64) -> Result<Racer, AnalysisError> {
        let tree = plan.tree();
        let node = tree.node(id);
        // the shifted mixture where it holds the subtree within
        // MAX_SHIFTED_PHASES (its rows cost more than the composed law
        // beyond: a loop's many re-run counts, each a chain of its own),
        // by its size estimated before building (`mixture_size`); else the
        // subtree's composed law (any subtree)
        let budget = MAX_SHIFTED_PHASES.min(plan.max_states());
        let shifted = || match shifted::mixture_size(tree, id, budget, horizon)? {
            shifted::MixtureSize::Holds(_) => {
                match shifted::shifted_law_within(tree, id, plan.max_states(), horizon)? {
                    Some(law) => Ok(Racer::Shifted(law)),
                    None => Racer::law(plan, id, horizon),
                }
            }
            // no mixture, or a larger one: the law
            shifted::MixtureSize::CannotHold | shifted::MixtureSize::Over => {
                Racer::law(plan, id, horizon)
            }
        };
        match plan.representation(id)? {
            Representation::Chain => Ok(Racer::chain(plan.chain(id)?)),
            // a leaf or a loop: its chain when Markovian
            Representation::Closed | Representation::Loop if plan.markovian(id) => {
                Ok(Racer::chain(plan.chain(id)?))
            }
            Representation::Closed | Representation::Loop => shifted(),
            Representation::Atoms | Representation::Shifted => shifted(),
            Representation::Mapped => {
                let (child, to) = node.kind.as_map().expect("planned as a map");
                Ok(Racer::Mapped {
                    inner: Box::new(Racer::build_within(plan, child, horizon)?),
                    to,
                })
            }
            Representation::Counted | Representation::Race => {
                let (m, f, kids) = parallel_racers(plan, id, horizon)?;
                if !is_race(kids.len(), m, f) {
                    return Ok(Racer::Counted {
                        m,
                        f,
                        children: kids,
                    });
                }
                Ok(Racer::Race(Box::new(Race::new(
                    node.name.clone(),
                    m,
                    f,
                    kids,
                )?)))
            }
            // a chain over the budget (a wide Parallel below): its refusal
            Representation::Composed | Representation::Book => match plan.chain_size(id)? {
                ChainSize::Over(e) | ChainSize::NotMarkovian(e) => Err(e),
                ChainSize::Within(_) => Ok(Racer::chain(plan.chain(id)?)),
            },
        }
    }

    /// The composed law of `id` ([`Racer::Law`]) on `[0, horizon]`, or,
    /// for all time, on a horizon doubled from 32 times its mean time
    /// until all but [`LAW_TAIL`] of its returning mass is within it (its
    /// figures say how much returns). Past the time by which the subtree's
    /// structure bounds its unreturned mass below `LAW_TAIL / 2`
    /// ([`super::tail`]) a longer horizon cannot help: a deficit left there
    /// is the interpolation's error, accepted up to [`LAW_ERROR`] and
    /// refused beyond. `refusal`: the error where the subtree's figures are
    /// not known.
    fn law(plan: &dyn Children, id: NodeId, horizon: f64) -> Result<Racer, AnalysisError> {
        let tree = plan.tree();
        if horizon.is_finite() {
            return Ok(Racer::Law(plan.horizon_law(id, horizon)?));
        }
        let figures = plan.subtree_figures(id)?[0];
        let returns = figures.ps + figures.pf;
        let scale = figures.mtts.unwrap_or(0.0).max(figures.mttf.unwrap_or(0.0));
        let mut end = 32.0 * scale.max(f64::MIN_POSITIVE);
        if returns == 0.0 || scale == 0.0 {
            // it never returns, or returns at once
            end = end.max(1.0);
        }
        let known = plan.known_subtree_figures(id);
        let settled = super::tail::settled_after(tree, id, &known, scale, LAW_TAIL / 2.0);
        if let Some(s) = settled.filter(|&s| s > end && s <= START_AT_SETTLED * end) {
            end = s;
        }
        for _ in 0..LAW_DOUBLINGS {
            let law = plan.horizon_law(id, end)?;
            let deficit = returns - law.mass();
            if deficit <= LAW_TAIL {
                return Ok(Racer::Law(law));
            }
            if let Some(settled) = settled.filter(|&s| end >= s) {
                if deficit <= LAW_ERROR {
                    return Ok(Racer::Law(law));
                }
                return Err(numerical(
                    &tree.node(id).name,
                    &format!(
                        "its composed law misses {deficit:.1e} of its mass by {end:.4e} s, \
                         where all but {:.0e} has returned (by {settled:.4e} s)",
                        LAW_TAIL / 2.0
                    ),
                ));
            }
            end = match settled {
                Some(s) if s > end && s < 2.0 * end => s,
                // a deficit this small is the interpolation's error more
                // than unreturned mass: a doubling short of the settled
                // time would not pass the test, the settled time will
                // (the law there is the one the doublings end with)
                Some(s) if s > end && s <= SETTLED_JUMP * end && deficit <= LAW_ERROR => s,
                _ => 2.0 * end,
            };
        }
        Err(numerical(
            &tree.node(id).name,
            "its composed law did not return its mass within 2^12 times its mean time",
        ))
    }

    /// The probabilities a composed-law racer holds past its horizon (its
    /// limit, within its tail of the figures'), `None` for the others.
    fn held_limit(&self) -> Option<Row> {
        match self {
            Racer::Law(l) => Some(l.row(f64::INFINITY, false)),
            Racer::Mapped { inner, to } => inner.held_limit().map(|r| mapped_row(r, *to)),
            _ => None,
        }
    }

    /// [`Race::pass_work`] of this racer.
    fn pass_work(&self, end: f64) -> f64 {
        match self {
            Racer::Chain(c, _) => uniformization_work(c, &[end]),
            Racer::Shifted(l) => l
                .success
                .iter()
                .chain(&l.failure)
                .map(|c| uniformization_work(&c.chain, &[(end - c.shift).max(0.0)]))
                .sum(),
            Racer::Counted { children, .. } => children.iter().map(|c| c.pass_work(end)).sum(),
            Racer::Race(r) => r.pass_work(end),
            Racer::Mapped { inner, .. } => inner.pass_work(end),
            // budgeted where they are built
            Racer::Renewal(_) | Racer::Law(_) => 0.0,
        }
    }

    /// Instants at which the subtree may return with positive probability.
    fn instants(&self, out: &mut Vec<f64>) {
        match self {
            Racer::Chain(c, _) => {
                if c.initial_success + c.initial_failure > 0.0 {
                    out.push(0.0);
                }
            }
            Racer::Shifted(l) => out.extend(
                l.success
                    .iter()
                    .chain(&l.failure)
                    .filter(|c| c.chain.initial_success != 0.0)
                    .map(|c| c.shift),
            ),
            Racer::Counted { children, .. } => children.iter().for_each(|c| c.instants(out)),
            Racer::Race(r) => out.extend(r.atoms.iter().map(|a| a.0)),
            Racer::Mapped { inner, .. } => inner.instants(out),
            Racer::Renewal(_) => {}
            Racer::Law(l) => out.extend(l.instants()),
        }
    }

    /// Instants where the subtree's densities may jump or kink.
    fn cuts(&self, out: &mut Vec<f64>) {
        match self {
            Racer::Chain(..) => {}
            Racer::Shifted(l) => out.extend(l.shifts()),
            Racer::Counted { children, .. } => children.iter().for_each(|c| c.cuts(out)),
            Racer::Race(r) => out.extend(&r.cuts),
            Racer::Mapped { inner, .. } => inner.cuts(out),
            // the densities may jump or kink where waits end, the level
            // starts: in the first levels (each smooths by one order) and
            // where waits start with an atom (`renewal_law`'s pieces)
            Racer::Renewal(l) => out.extend(
                l.levels
                    .iter()
                    .enumerate()
                    .filter(|&(k, v)| {
                        k < super::renewal_law::SMOOTHING_LEVELS
                            || v.atoms > super::renewal_law::ATOM_FLOOR
                    })
                    .map(|(_, v)| v.start)
                    .filter(|&t| t <= l.horizon),
            ),
            Racer::Law(l) => out.extend(l.cuts()),
        }
    }

    /// Largest exit rate of any phase (boundary layers of width 1/rate).
    fn fastest(&self) -> f64 {
        let chain_rate = |c: &PhaseChain| (0..c.len()).map(|i| c.total_rate(i)).fold(0.0, f64::max);
        match self {
            Racer::Chain(c, _) => chain_rate(c),
            Racer::Shifted(l) => l
                .success
                .iter()
                .chain(&l.failure)
                .map(|c| chain_rate(&c.chain))
                .fold(0.0, f64::max),
            Racer::Counted { children, .. } => {
                children.iter().map(Racer::fastest).fold(0.0, f64::max)
            }
            Racer::Race(r) => r.children.iter().map(Racer::fastest).fold(0.0, f64::max),
            Racer::Mapped { inner, .. } => inner.fastest(),
            Racer::Renewal(l) => l.levels.iter().map(|v| v.rate()).fold(0.0, f64::max),
            // its interpolation panels resolve its boundary layers
            Racer::Law(_) => 0.0,
        }
    }

    /// `[S, F, s, f]` at `times`; `left`: the probabilities just before
    /// each time (without a return exactly then).
    fn rows(&self, name: &str, times: &[f64], left: bool) -> Result<Vec<Row>, AnalysisError> {
        match self {
            Racer::Chain(c, pass) => {
                let weights = [&c.exit_success[..], &c.exit_failure[..]];
                let rows = sample_weighted_kept(&mut pass.borrow_mut(), c, times, &weights)
                    .ok_or_else(|| stiff(name, c, times))?;
                Ok(times
                    .iter()
                    .zip(rows)
                    .map(|(&t, r)| {
                        if left && t <= 0.0 {
                            [0.0, 0.0, r[2], r[3]]
                        } else {
                            [r[0], r[1], r[2], r[3]]
                        }
                    })
                    .collect())
            }
            Racer::Shifted(l) => {
                let mut out = vec![[0.0; 4]; times.len()];
                for (o, part) in [&l.success, &l.failure].into_iter().enumerate() {
                    for c in part {
                        let (idx, local) = shifted_times(times, c.shift, left);
                        if idx.is_empty() {
                            continue;
                        }
                        if c.chain.is_empty() {
                            for &k in &idx {
                                out[k][o] += c.weight * c.chain.initial_success;
                            }
                            continue;
                        }
                        let weights = [&c.chain.exit_success[..]];
                        let rows = sample_weighted(&c.chain, &local, &weights)
                            .ok_or_else(|| stiff(name, &c.chain, &local))?;
                        for (&k, r) in idx.iter().zip(rows) {
                            out[k][o] += c.weight * r[0];
                            out[k][2 + o] += c.weight * r[2];
                        }
                    }
                }
                Ok(out)
            }
            Racer::Counted { m, f, children } => {
                let columns = children
                    .iter()
                    .map(|c| c.rows(name, times, left))
                    .collect::<Result<Vec<_>, _>>()?;
                let mut row = vec![[0.0; 4]; children.len()];
                Ok((0..times.len())
                    .map(|k| {
                        for (r, col) in row.iter_mut().zip(&columns) {
                            *r = col[k];
                        }
                        counts::status_and_densities_by_counts(&row, *m, *f)
                    })
                    .collect())
            }
            Racer::Race(r) => r.rows(times, left),
            Racer::Mapped { inner, to } => Ok(inner
                .rows(name, times, left)?
                .into_iter()
                .map(|r| mapped_row(r, *to))
                .collect()),
            Racer::Renewal(l) => Ok(times.iter().map(|&t| l.row(t)).collect()),
            Racer::Law(l) => Ok(times.iter().map(|&t| l.row(t, left)).collect()),
        }
    }
}

/// A row `[S, F, s, f]` with its Success and Failure sent to `to[0]` and
/// `to[1]` (0: Success, 1: Failure).
fn mapped_row(r: Row, to: [usize; 2]) -> Row {
    let mut out = [0.0; 4];
    for o in 0..2 {
        out[to[o]] += r[o];
        out[2 + to[o]] += r[2 + o];
    }
    out
}

impl Race {
    fn new(name: String, m: usize, f: usize, children: Vec<Racer>) -> Result<Race, AnalysisError> {
        let n = children.len() as f64;
        let work = n * (m as f64).powi(3) * (f as f64).powi(3);
        if work > MAX_INSTANT_WORK {
            return Err(AnalysisError::StateBudget {
                node: name,
                states: work,
                budget: MAX_INSTANT_WORK as usize,
            });
        }
        let mut instants = vec![0.0];
        let mut cuts = vec![];
        for c in &children {
            c.instants(&mut instants);
            c.cuts(&mut cuts);
        }
        let instants = sorted_unique(instants);
        cuts.extend(&instants);
        let mut race = Race {
            name,
            m,
            f,
            children,
            atoms: Vec::new(),
            cuts: sorted_unique(cuts),
        };
        let before = race.child_rows(&instants, true)?;
        let after = race.child_rows(&instants, false)?;
        for (k, &t) in instants.iter().enumerate() {
            let rows: Vec<Row> = before
                .iter()
                .zip(&after)
                .map(|(b, a)| {
                    let (b, a) = (b[k], a[k]);
                    [b[0], b[1], (a[0] - b[0]).max(0.0), (a[1] - b[1]).max(0.0)]
                })
                .collect();
            let (s, f) = resolve_instant(&rows, m, f);
            if s > 0.0 || f > 0.0 {
                race.atoms.push((t, s, f));
            }
        }
        Ok(race)
    }

    /// `(τ, atom_S, atom_F)`: its returns at instants, by time.
    pub(crate) fn atoms(&self) -> &[(f64, f64, f64)] {
        &self.atoms
    }

    /// The instants where its densities may jump or kink.
    pub(crate) fn cuts(&self) -> &[f64] {
        &self.cuts
    }

    /// Per child, its rows at `times`.
    fn child_rows(&self, times: &[f64], left: bool) -> Result<Vec<Vec<Row>>, AnalysisError> {
        self.children
            .iter()
            .map(|c| c.rows(&self.name, times, left))
            .collect()
    }

    /// `[s, f, running]` at `times` (not at instants of atoms).
    pub(crate) fn densities(&self, times: &[f64]) -> Result<Vec<[f64; 3]>, AnalysisError> {
        let columns = self.child_rows(times, false)?;
        let mut row = vec![[0.0; 4]; self.children.len()];
        Ok((0..times.len())
            .map(|k| {
                for (r, col) in row.iter_mut().zip(&columns) {
                    *r = col[k];
                }
                race_densities(&row, self.m, self.f)
            })
            .collect())
    }

    /// Integrals of `[s, f, t·s, t·f]` over each panel, adaptively.
    fn integrate(&self, panels: &[(f64, f64)]) -> Result<Vec<[f64; 4]>, AnalysisError> {
        let full = GaussLegendre::new(RULE);
        let half = GaussLegendre::new(RULE / 2);
        let mut totals = vec![[0.0f64; 4]; panels.len()];
        // (panel index, a, b)
        let mut pending: Vec<(usize, f64, f64)> = panels
            .iter()
            .enumerate()
            .filter(|(_, p)| p.1 > p.0)
            .map(|(k, p)| (k, p.0, p.1))
            .collect();
        for _ in 0..MAX_ROUNDS {
            if pending.is_empty() {
                return Ok(totals);
            }
            let mut times = Vec::with_capacity(pending.len() * (RULE + RULE / 2));
            for &(_, a, b) in &pending {
                let (c, h) = (0.5 * (a + b), 0.5 * (b - a));
                times.extend(full.nodes.iter().chain(&half.nodes).map(|x| c + h * x));
            }
            let values = self.densities(&times)?;
            let per = full.len() + half.len();
            let mut next = Vec::new();
            for (q, &(k, a, b)) in pending.iter().enumerate() {
                let h = 0.5 * (b - a);
                let v = &values[q * per..(q + 1) * per];
                let t = &times[q * per..(q + 1) * per];
                let sum = |w: &[f64], off: usize| {
                    let mut s = [0.0f64; 4];
                    for (i, w) in w.iter().enumerate() {
                        let (x, d) = (t[off + i], v[off + i]);
                        s[0] += w * d[0];
                        s[1] += w * d[1];
                        s[2] += w * x * d[0];
                        s[3] += w * x * d[1];
                    }
                    s.map(|x| x * h)
                };
                let (s_full, s_half) = (sum(&full.weights, 0), sum(&half.weights, full.len()));
                let ok = (0..4).all(|i| {
                    let scale = if i < 2 { 1.0 } else { b.max(1.0) };
                    (s_full[i] - s_half[i]).abs() <= ABSOLUTE * scale + RELATIVE * s_full[i].abs()
                });
                if ok || b - a <= 1e-12 * b.max(1.0) {
                    for i in 0..4 {
                        totals[k][i] += s_full[i];
                    }
                } else {
                    let mid = 0.5 * (a + b);
                    next.push((k, a, mid));
                    next.push((k, mid, b));
                }
            }
            pending = next;
        }
        Err(numerical(
            &self.name,
            "the quadrature of its densities did not converge",
        ))
    }

    /// Panels from 0 to `end` cut at every instant and shift, and near 0
    /// at 8^k / the fastest rate.
    fn panels_to(&self, points: &[f64], end: f64) -> Vec<(f64, f64)> {
        let mut cuts: Vec<f64> = self.cuts.iter().copied().filter(|&t| t < end).collect();
        cuts.extend(points.iter().copied().filter(|&t| t < end));
        cuts.push(0.0);
        cuts.push(end);
        let fastest = self.children.iter().map(Racer::fastest).fold(0.0, f64::max);
        if fastest > 0.0 {
            let mut t = 1.0 / fastest;
            while t < end {
                cuts.push(t);
                t *= 8.0;
            }
        }
        let cuts = sorted_unique(cuts);
        cuts.windows(2).map(|w| (w[0], w[1])).collect()
    }

    /// `[S, F, s, f]` at `times` (any order).
    fn rows(&self, times: &[f64], left: bool) -> Result<Vec<Row>, AnalysisError> {
        let end = times.iter().copied().fold(0.0, f64::max);
        let panels = self.panels_to(times, end);
        let sums = self.integrate(&panels)?;
        // cumulative integrals at panel ends
        let mut ends = Vec::with_capacity(panels.len() + 1);
        let mut acc = [0.0f64; 2];
        ends.push((0.0, acc));
        for (p, s) in panels.iter().zip(&sums) {
            acc[0] += s[0];
            acc[1] += s[1];
            ends.push((p.1, acc));
        }
        let dens = self.densities(times)?;
        Ok(times
            .iter()
            .zip(dens)
            .map(|(&t, d)| {
                let k = ends.partition_point(|e| e.0 < t && !same_instant(e.0, t));
                let base = ends[k.min(ends.len() - 1)];
                let mut row = [base.1[0], base.1[1], d[0], d[1]];
                for &(tau, s, f) in &self.atoms {
                    let counted = if left {
                        tau < t && !same_instant(tau, t)
                    } else {
                        tau <= t || same_instant(tau, t)
                    };
                    if counted {
                        row[0] += s;
                        row[1] += f;
                    }
                }
                row
            })
            .collect())
    }

    /// `[P(S), P(F), E[T·1{S}], E[T·1{F}]]`: the limits of the curve.
    /// `ends`: the children's own figures, in child order, whose limits
    /// give the probability that the race never returns (children that
    /// never return may leave both thresholds unmet for ever): the tail
    /// is integrated until the running probability is within rounding of
    /// that limit, not of zero.
    /// The work of one uniformization pass of every chain the race
    /// samples (its children's, its shifted mixtures' components, those of
    /// races and counts below) up to `end`.
    fn pass_work(&self, end: f64) -> f64 {
        self.children.iter().map(|c| c.pass_work(end)).sum()
    }

    fn limits(&self, scale: f64, ends: &[Figures]) -> Result<[f64; 4], AnalysisError> {
        let never = if ends.len() == self.children.len() {
            // a composed-law child holds its probabilities past its horizon:
            // its limit is those (within its tail of the figures')
            let rows: Vec<Row> = ends
                .iter()
                .zip(&self.children)
                .map(|(c, r)| r.held_limit().unwrap_or([c.ps, c.pf, 0.0, 0.0]))
                .collect();
            race_densities(&rows, self.m, self.f)[2].max(0.0)
        } else {
            0.0
        };
        let mut out = [0.0f64; 4];
        for &(t, s, f) in &self.atoms {
            out[0] += s;
            out[1] += f;
            out[2] += t * s;
            out[3] += t * f;
        }
        let last = self.cuts.last().copied().unwrap_or(0.0);
        let mut start = last.max(scale);
        for s in self.integrate(&self.panels_to(&[], start))? {
            (0..4).for_each(|i| out[i] += s[i]);
        }
        let mut width = scale.max(start / 8.0).max(f64::MIN_POSITIVE);
        for _ in 0..200 {
            let running = (self.densities(&[start])?[0][2] - never).max(0.0);
            let mean = (out[2] + out[3]).max(f64::MIN_POSITIVE);
            // (a floor of a few 1e-16 is rounding in `1 − S_h − F_h`)
            if running <= 1e-14 || running <= 1e-12 && running * width <= 1e-12 * mean {
                return Ok(out);
            }
            // one doubling panel at a time: a batch of several overshot
            // the settled time up to 16-fold, and every pass of a chain
            // racer's uniformization runs from 0 to the batch's end
            let panels = [(start, start + width)];
            start += width;
            width *= 2.0;
            for s in self.integrate(&panels)? {
                (0..4).for_each(|i| out[i] += s[i]);
            }
        }
        Err(numerical(
            &self.name,
            "its running probability did not vanish",
        ))
    }
}

/// `[s, f, running]` of a race from its children's `[S, F, s, f]` at one
/// time (module docs): `V[k][j]` the probability of k successes and j
/// failures (k < m, j < f), `D_S` the same with one child's success density
/// in place of its probability (up to m successes), `D_F` likewise.
pub fn race_densities(rows: &[Row], m: usize, f: usize) -> [f64; 3] {
    let (w, ws) = (f, f);
    let mut v = vec![0.0f64; m * w];
    let mut ds = vec![0.0f64; (m + 1) * ws];
    let mut df = vec![0.0f64; m * (f + 1)];
    v[0] = 1.0;
    for &[s_cdf, f_cdf, s_den, f_den] in rows {
        let r = (1.0 - s_cdf - f_cdf).max(0.0);
        let mut nv = vec![0.0f64; v.len()];
        let mut nds = vec![0.0f64; ds.len()];
        let mut ndf = vec![0.0f64; df.len()];
        for k in 0..=m {
            for j in 0..=f {
                // V
                if k < m && j < f {
                    let x = v[k * w + j];
                    if x != 0.0 {
                        nv[k * w + j] += x * r;
                        if k + 1 < m {
                            nv[(k + 1) * w + j] += x * s_cdf;
                        }
                        if j + 1 < f {
                            nv[k * w + j + 1] += x * f_cdf;
                        }
                        // this child returns now
                        nds[(k + 1) * ws + j] += x * s_den;
                        ndf[k * (f + 1) + j + 1] += x * f_den;
                    }
                }
                // D_S: k ≤ m, j < f
                if j < f {
                    let x = ds[k * ws + j];
                    if x != 0.0 {
                        nds[k * ws + j] += x * r;
                        if k < m {
                            nds[(k + 1) * ws + j] += x * s_cdf;
                        }
                        if j + 1 < f {
                            nds[k * ws + j + 1] += x * f_cdf;
                        }
                    }
                }
                // D_F: k < m, j ≤ f
                if k < m {
                    let x = df[k * (f + 1) + j];
                    if x != 0.0 {
                        ndf[k * (f + 1) + j] += x * r;
                        if k + 1 < m {
                            ndf[(k + 1) * (f + 1) + j] += x * s_cdf;
                        }
                        if j < f {
                            ndf[k * (f + 1) + j + 1] += x * f_cdf;
                        }
                    }
                }
            }
        }
        v = nv;
        ds = nds;
        df = ndf;
    }
    let s: f64 = (0..f).map(|j| ds[m * ws + j]).sum();
    let fail: f64 = (0..m).map(|k| df[k * (f + 1) + f]).sum();
    [
        s.max(0.0),
        fail.max(0.0),
        v.iter().sum::<f64>().clamp(0.0, 1.0),
    ]
}

/// The node's atom `(P(Success at τ), P(Failure at τ))` at one instant τ
/// from each child's `[S(τ⁻), F(τ⁻), P(Success at τ), P(Failure at τ)]`:
/// the counts before τ are `(K0, J0)` (below the thresholds, else the node
/// returned earlier), then the returns at τ are taken in child order until
/// a threshold is met (BT.CPP's tick). For each `(K0, J0)` a programme over
/// the children in order tracks the children counted before τ (to match
/// K0, J0 at the end) and the returns at τ so far.
pub fn resolve_instant(rows: &[Row], m: usize, f: usize) -> (f64, f64) {
    let (mut out_s, mut out_f) = (0.0, 0.0);
    for k0 in 0..m {
        for j0 in 0..f {
            let (need_s, need_f) = (m - k0, f - j0);
            // classes: undecided (a, b) with a < need_s, b < need_f; then S, F
            let undecided = need_s * need_f;
            let classes = undecided + 2;
            let (cls_s, cls_f) = (undecided, undecided + 1);
            let idx = |k: usize, j: usize, c: usize| (k * (j0 + 1) + j) * classes + c;
            let mut dp = vec![0.0f64; (k0 + 1) * (j0 + 1) * classes];
            dp[idx(0, 0, 0)] = 1.0;
            for &[before_s, before_f, at_s, at_f] in rows {
                let after = (1.0 - before_s - before_f - at_s - at_f).max(0.0);
                let mut next = vec![0.0f64; dp.len()];
                for k in 0..=k0 {
                    for j in 0..=j0 {
                        for c in 0..classes {
                            let x = dp[idx(k, j, c)];
                            if x == 0.0 {
                                continue;
                            }
                            if k < k0 {
                                next[idx(k + 1, j, c)] += x * before_s;
                            }
                            if j < j0 {
                                next[idx(k, j + 1, c)] += x * before_f;
                            }
                            if c >= undecided {
                                next[idx(k, j, c)] += x * (after + at_s + at_f);
                                continue;
                            }
                            next[idx(k, j, c)] += x * after;
                            let (a, b) = (c / need_f, c % need_f);
                            let up = if a + 1 == need_s {
                                cls_s
                            } else {
                                (a + 1) * need_f + b
                            };
                            next[idx(k, j, up)] += x * at_s;
                            let right = if b + 1 == need_f {
                                cls_f
                            } else {
                                a * need_f + b + 1
                            };
                            next[idx(k, j, right)] += x * at_f;
                        }
                    }
                }
                dp = next;
            }
            out_s += dp[idx(k0, j0, cls_s)];
            out_f += dp[idx(k0, j0, cls_f)];
        }
    }
    (out_s, out_f)
}

/// The thresholds `(M, F capped at N − M + 1)` of Parallel `id` and its
/// children's laws, exact on `[0, horizon]` and up to the instant by which
/// the node has surely returned ([`sure_return`]), after which they are
/// never read.
fn parallel_racers(
    plan: &dyn Children,
    id: NodeId,
    horizon: f64,
) -> Result<(usize, usize, Vec<Racer>), AnalysisError> {
    let tree = plan.tree();
    let Op::KOfN {
        success: m,
        failure: f,
        children,
    } = &tree.node(id).kind
    else {
        unreachable!("counted nodes and races are k-of-n nodes")
    };
    let f = (*f).min(children.len() + 1 - m);
    let horizon = horizon.min(sure_return(tree, *m, f, children));
    let kids = children
        .iter()
        .map(|&c| Racer::build_within(plan, c, horizon))
        .collect::<Result<Vec<_>, _>>()?;
    Ok((*m, f, kids))
}

/// An instant by which a Parallel with thresholds `m` and `f` (capped) has
/// surely returned, or infinity: with `m = f = 1` (it returns with its first
/// child, BT.CPP's `Timeout`) the earliest time by which a leaf child has
/// surely returned — a deadline's fixed time.
fn sure_return(tree: &Graph, m: usize, f: usize, children: &[NodeId]) -> f64 {
    if m != 1 || f != 1 {
        return f64::INFINITY;
    }
    let latest = |c: NodeId| -> Option<f64> {
        let a = tree.node(c).kind.action()?;
        let side = |p: f64, d: Option<Duration>| match (p > 0.0, d) {
            (false, _) => Some(0.0),
            (true, Some(Duration::Fixed { time })) => Some(time),
            _ => None,
        };
        (a.ps + a.pf >= 1.0).then_some(())?;
        Some(side(a.ps, a.success)?.max(side(a.pf, a.failure)?))
    };
    children
        .iter()
        .filter_map(|&c| latest(c))
        .fold(f64::INFINITY, f64::min)
}

/// Running probability of `R` (computed as `1 − S − F`, so above its
/// rounding) at half the horizon of a re-run process's law
/// ([`renewal_race`]).
const REST_TAIL: f64 = 1e-13;

/// `Parallel{1, 1}(process, R)` (either order) with a re-run process and
/// an `R` without a phase chain (a fixed wait inside it, a race of its
/// own), or a `C′` without one: the race of the process's law of first
/// failure — from its levels where `C′` has a phase chain
/// ([`renewal_curve::prepare_process`]), else its composed law on
/// `[0, horizon]` — against R's law, with no series over the re-runs.
/// Exact on `[0, horizon]`; `None` for the horizon takes R's tail: for
/// the levels, twice the first doubling of `scale` where R is still
/// running with probability below [`REST_TAIL`]; for a composed law (its
/// cost grows with its horizon), that doubling backed off by quarter
/// octaves while R's running probability stays below it. Beyond the
/// horizon the process's Failure is held at its value, which changes the node's
/// probabilities by less than R's running probability at the horizon
/// (below 1e-13 at half of it; R's phase-type tail decays exponentially)
/// and its mean times by less than the integral of it beyond. `Ok(None)` when
/// `id` is no such race, R may never return, or the re-run can fail at
/// its start (atoms at every wait's end).
pub(crate) fn renewal_race(
    plan: &dyn Children,
    id: NodeId,
    horizon: Option<f64>,
    scale: f64,
) -> Result<Option<Race>, AnalysisError> {
    let tree = plan.tree();
    let Some(parts) = super::renewal::parts(tree, id) else {
        return Ok(None);
    };
    let super::renewal::Rest::Node(r) = parts.rest else {
        return Ok(None);
    };
    let Op::KOfN { children, .. } = &tree.node(id).kind else {
        return Ok(None);
    };
    let name = tree.node(id).name.clone();
    let rest = Racer::build_within(plan, r, horizon.unwrap_or(f64::INFINITY))?;
    // `horizon` for the levels; `tight`, where R is still running with
    // probability at most REST_TAIL, for a composed law (whose cost grows
    // with its horizon squared)
    let (horizon, tight) = match horizon {
        Some(h) => (h, h),
        None => {
            let running = |t: f64| -> Option<f64> {
                let [s, f, _, _] = rest.rows(&name, &[t], false).ok()?[0];
                Some(1.0 - s - f)
            };
            let mut t = scale.max(parts.wait).max(1.0);
            let mut tail = None;
            // an R that may never return keeps a running probability: stop
            // after 2^30 times the scale (or where R's own sampling gives up)
            for _ in 0..30 {
                let Some(r) = running(t) else {
                    return Ok(None);
                };
                if r <= REST_TAIL {
                    tail = Some(t);
                    break;
                }
                t *= 2.0;
            }
            let Some(t) = tail else {
                return Ok(None);
            };
            // the doubling overshoots by up to 2: back off in quarter octaves
            let mut tight = t;
            for _ in 0..3 {
                let c = tight * 0.5f64.powf(0.25);
                match running(c) {
                    Some(r) if r <= REST_TAIL && c >= parts.wait => tight = c,
                    _ => break,
                }
            }
            (2.0 * t, tight)
        }
    };
    let process =
        match renewal_curve::prepare_process(tree, parts.process, horizon, plan.max_states())? {
            Some(prepared) if prepared.instant_failure() > 0.0 => return Ok(None),
            Some(prepared) => {
                let (d, t0) = prepared.period();
                let mut levels = Vec::new();
                prepared.run(|_, level| {
                    levels.push(level);
                    Ok(())
                })?;
                Racer::Renewal(Box::new(RenewalLoop {
                    levels,
                    d,
                    t0,
                    horizon,
                }))
            }
            // C′ without a phase chain (a shifted, fixed or hybrid time): the
            // process's composed law on [0, horizon] only — R has returned by
            // then, so the race's cost follows R's horizon, not the number of
            // re-runs until the process fails
            None => Racer::law(plan, parts.process, tight)?,
        };
    let kids = if children.first() == Some(&parts.process) {
        vec![process, rest]
    } else {
        vec![rest, process]
    };
    Race::new(name, 1, 1, kids).map(Some)
}

/// The race node `id` (a Parallel whose thresholds can both be met).
pub(crate) fn race_of(plan: &dyn Children, id: NodeId) -> Result<Race, AnalysisError> {
    race_within(plan, id, f64::INFINITY)
}

/// The race node `id`, exact on `[0, horizon]` only.
pub(crate) fn race_within(
    plan: &dyn Children,
    id: NodeId,
    horizon: f64,
) -> Result<Race, AnalysisError> {
    let (m, f, kids) = parallel_racers(plan, id, horizon)?;
    Race::new(plan.tree().node(id).name.clone(), m, f, kids)
}

/// Figures of race `id` (module docs); `child_figures` set the scale of the
/// horizon.
pub(crate) fn figures(
    plan: &dyn Children,
    id: NodeId,
    child_figures: &[Figures],
) -> Result<Figures, AnalysisError> {
    let (tree, max_states) = (plan.tree(), plan.max_states());
    // a race against a renewal process of re-runs: exact without a series
    let scale = child_figures
        .iter()
        .map(Figures::mean_time)
        .fold(0.0, f64::max);
    let limits = |race: Race| race.limits(scale, child_figures).map(Figures::from_moments);
    match super::renewal::figures(tree, id, max_states)? {
        Renewal::Figures(f) => return Ok(f),
        // R without a phase chain: the process's law from its levels
        Renewal::TooLarge { error, .. } => match renewal_race(plan, id, None, scale) {
            Ok(Some(race)) => return limits(race),
            // a side over the budget: the product chain's refusal says more
            Err(AnalysisError::StateBudget { .. }) => return Err(error),
            Err(e) => return Err(e),
            Ok(None) => {}
        },
        Renewal::NotApplicable => {
            if let Some(race) = renewal_race(plan, id, None, scale)? {
                return limits(race);
            }
        }
    }
    // a deadline over such a race (its law by levels, cut at the deadline)
    if let Some(moments) = plan.deadline_figures(id)? {
        return Ok(Figures::from_moments(moments));
    }
    let race = race_of(plan, id)?;
    // its integration runs to where it has returned: every pass of its
    // chains' uniformization is counted before the first
    // (its own figures are what is being computed: not known yet)
    let known = plan.known_subtree_figures(id);
    if let Some(end) = super::tail::settled_after(tree, id, &known, scale, LAW_TAIL) {
        let work = race.pass_work(end);
        if work > MAX_PASS_WORK {
            return Err(AnalysisError::Stiff {
                node: tree.node(id).name.clone(),
                work,
                limit: MAX_PASS_WORK,
            });
        }
    }
    limits(race)
}

/// `π(t)` of race `id` at `times` (module docs).
pub(crate) fn curve(
    plan: &dyn Children,
    id: NodeId,
    times: &[f64],
) -> Result<Vec<CurvePoint>, AnalysisError> {
    let (tree, max_states) = (plan.tree(), plan.max_states());
    // the law of a renewal race is its loop's series (its figures are
    // not), or the process's law from its levels where R has no chain
    let end = times.iter().copied().fold(0.0, f64::max);
    let mut race = None;
    if let Some((process, terms)) = super::renewal::series(tree, id, max_states) {
        if terms > MAX_RERUN_TERMS as f64 {
            race = renewal_race(plan, id, Some(end), 0.0)?;
            let _ = process;
        }
    }
    // the curve reads the race on [0, end] only
    let race = match race {
        Some(r) => r,
        None => race_within(plan, id, end)?,
    };
    let rows = race.rows(times, false)?;
    Ok(times
        .iter()
        .zip(rows)
        .map(|(&t, r)| {
            let (success, failure) = (r[0].clamp(0.0, 1.0), r[1].clamp(0.0, 1.0));
            CurvePoint {
                t,
                success,
                failure,
                running: (1.0 - success - failure).max(0.0),
            }
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Brute force over the 5^n classes of the children at an instant,
    /// replaying BT.CPP's tick.
    fn brute_instant(rows: &[Row], m: usize, f: usize) -> (f64, f64) {
        let n = rows.len();
        let (mut s, mut fl) = (0.0, 0.0);
        for code in 0..5usize.pow(n as u32) {
            let cls: Vec<usize> = (0..n).map(|h| code / 5usize.pow(h as u32) % 5).collect();
            let mut p = 1.0;
            for (h, &c) in cls.iter().enumerate() {
                let [bs, bf, a_s, a_f] = rows[h];
                p *= [bs, bf, a_s, a_f, 1.0 - bs - bf - a_s - a_f][c];
            }
            let k0 = cls.iter().filter(|&&c| c == 0).count();
            let j0 = cls.iter().filter(|&&c| c == 1).count();
            if k0 >= m || j0 >= f {
                continue;
            }
            let (mut k, mut j) = (k0, j0);
            for &c in &cls {
                if c == 2 {
                    k += 1;
                    if k >= m {
                        s += p;
                        break;
                    }
                } else if c == 3 {
                    j += 1;
                    if j >= f {
                        fl += p;
                        break;
                    }
                }
            }
        }
        (s, fl)
    }

    #[test]
    fn instants_match_brute_force() {
        let rows = [
            [0.1, 0.2, 0.3, 0.1],
            [0.0, 0.3, 0.2, 0.4],
            [0.25, 0.05, 0.1, 0.3],
            [0.2, 0.2, 0.0, 0.5],
        ];
        for m in 1..=4 {
            for f in 1..=4 {
                let got = resolve_instant(&rows, m, f);
                let want = brute_instant(&rows, m, f);
                assert!(
                    (got.0 - want.0).abs() < 1e-15 && (got.1 - want.1).abs() < 1e-15,
                    "m={m} f={f}: {got:?} vs {want:?}"
                );
            }
        }
    }

    #[test]
    fn densities_match_enumeration() {
        // s(t) = Σ_h s_h · P(others: exactly m − 1 succeeded, < f failed)
        let rows = [
            [0.1, 0.2, 0.5, 0.3],
            [0.4, 0.1, 0.2, 0.7],
            [0.0, 0.6, 1.5, 0.1],
            [0.3, 0.3, 0.05, 0.4],
        ];
        let n = rows.len();
        for m in 1..=4 {
            for f in 1..=4 {
                let mut want = [0.0; 3];
                for code in 0..3usize.pow(n as u32) {
                    let cls: Vec<usize> = (0..n).map(|h| code / 3usize.pow(h as u32) % 3).collect();
                    let p = |skip: usize| -> f64 {
                        (0..n)
                            .filter(|&h| h != skip)
                            .map(|h| {
                                let [s, fl, _, _] = rows[h];
                                [s, fl, 1.0 - s - fl][cls[h]]
                            })
                            .product()
                    };
                    let (k, j) = (
                        cls.iter().filter(|&&c| c == 0).count(),
                        cls.iter().filter(|&&c| c == 1).count(),
                    );
                    if k < m && j < f {
                        want[2] += p(usize::MAX);
                    }
                    // child h returns now, the others as classed (h's class
                    // must be "running" to count each configuration once)
                    for h in 0..n {
                        if cls[h] != 2 {
                            continue;
                        }
                        if k == m - 1 && j < f {
                            want[0] += rows[h][2] * p(h);
                        }
                        if k < m && j == f - 1 {
                            want[1] += rows[h][3] * p(h);
                        }
                    }
                }
                let got = race_densities(&rows, m, f);
                for i in 0..3 {
                    assert!(
                        (got[i] - want[i]).abs() < 1e-14,
                        "m={m} f={f} i={i}: {got:?} vs {want:?}"
                    );
                }
            }
        }
    }
}
