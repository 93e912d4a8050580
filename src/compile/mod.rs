//! The bottom-up compiler: from a tree's core IR ([`crate::ir`], made by
//! [`lower`]) to every node's success and failure probabilities and mean
//! times.
//!
//! Nodes are visited children first. For each control node the compiler
//! builds the node's marking reachability graph ([`mrg`]) and a chain over it,
//! which [`crate::solve`] solves:
//!
//! * **Sequence / Fallback**, both methods: the DTMC over the MRG whose
//!   transitions are the children's outcomes with probabilities `ps_h`,
//!   `pf_h` (Remark 9.5) and mean durations `MTTS_h`, `MTTF_h`. Mean times
//!   add along paths whatever the children's time distributions, so this is
//!   exact, and it is linear in the number of children.
//! * **Parallel, `exact`**: the children's exact phase chains run jointly
//!   ([`phase`]); the node's figures come from that product CTMC.
//! * **Parallel, `book`**: the chapter's recursion. Each child is summarised
//!   as an exponential action `(ps, pf, mu = 1/MTTS, nu = 1/MTTF)`; the DTMC
//!   over the MRG has probabilities (9.38)–(9.39) and the marking's mean
//!   sojourn (9.40) as the duration of each transition.

pub(crate) mod atoms;
pub(crate) mod book_ctmc;
mod chain_curve;
pub(crate) mod children;
pub mod counts;
pub mod curve;
mod curve_options;
pub(crate) mod flow;
pub(crate) mod law;
pub(crate) mod mrg;
mod parallel_times;
pub mod phase;
pub(crate) mod plan;
pub(crate) mod race;
mod renewal;
mod renewal_curve;
mod renewal_law;
pub(crate) mod shifted;
mod tail;

use crate::ir::{Leaf, Lowered, Op};
use crate::solve::chain::{AbsorbingChain, Edge, Target};
use crate::solve::{solve_absorbing, Absorption};
use crate::tree::{Duration, Kind, NodeId, Tree};
pub use children::Representation;
use mrg::{Mrg, Outcome, Policy, Status};
pub(crate) use plan::Plan;

/// Which analysis to run.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Method {
    /// Exact composition of the actions' phase-type distributions (default).
    #[default]
    Exact,
    /// The book's recursion: every subtree replaced by an exponential action.
    Book,
}

impl Method {
    /// The method's name as used on the command line and in outputs.
    pub fn name(&self) -> &'static str {
        match self {
            Method::Exact => "exact",
            Method::Book => "book",
        }
    }
}

/// Default limit on the number of states of one chain.
pub const DEFAULT_MAX_STATES: usize = 4_000_000;

/// Options of an analysis.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Options {
    /// Which method.
    pub method: Method,
    /// Largest chain (number of transient states) the analysis may build.
    pub max_states: usize,
}

impl Default for Options {
    fn default() -> Self {
        Options {
            method: Method::Exact,
            max_states: DEFAULT_MAX_STATES,
        }
    }
}

/// Success/failure probabilities and conditional mean times of one node.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Figures {
    /// Probability that the node returns Success.
    pub ps: f64,
    /// Probability that the node returns Failure.
    pub pf: f64,
    /// Mean Time To Succeed, E[T | Success]; `None` when `ps = 0`.
    pub mtts: Option<f64>,
    /// Mean Time To Fail, E[T | Failure]; `None` when `pf = 0`.
    pub mttf: Option<f64>,
}

impl Figures {
    /// Success rate `mu = 1 / MTTS` (eq. 9.54); `None` when MTTS is undefined
    /// or zero.
    pub fn mu(&self) -> Option<f64> {
        self.mtts.filter(|&t| t > 0.0).map(|t| 1.0 / t)
    }

    /// Failure rate `nu = 1 / MTTF` (eq. 9.55).
    pub fn nu(&self) -> Option<f64> {
        self.mttf.filter(|&t| t > 0.0).map(|t| 1.0 / t)
    }

    /// Probability that the node never returns, `1 − ps − pf` (a loop
    /// whose child never ends it, a ReactiveSequence's restart loop).
    pub fn never(&self) -> f64 {
        (1.0 - self.ps - self.pf).max(0.0)
    }

    /// Mean execution time `E[T]` = ps·MTTS + pf·MTTF (the time-weighted
    /// mass of the runs that return).
    pub fn mean_time(&self) -> f64 {
        self.ps * self.mtts.unwrap_or(0.0) + self.pf * self.mttf.unwrap_or(0.0)
    }

    /// From `[P(S), P(F), E[T·1{S}], E[T·1{F}]]`: the mean times are the
    /// moments over the probabilities (undefined for an outcome that never
    /// happens).
    pub(crate) fn from_moments([ps, pf, ts, tf]: [f64; 4]) -> Figures {
        Figures {
            ps,
            pf,
            mtts: (ps > 0.0).then(|| ts / ps),
            mttf: (pf > 0.0).then(|| tf / pf),
        }
    }

    /// Figures of a node that only ever returns `o`: with probability `p`
    /// after a mean time `t`.
    fn one_sided(o: Outcome, p: f64, t: Option<f64>) -> Figures {
        match o {
            Outcome::Success => Figures {
                ps: p,
                pf: 0.0,
                mtts: t,
                mttf: None,
            },
            Outcome::Failure => Figures {
                ps: 0.0,
                pf: p,
                mtts: None,
                mttf: t,
            },
        }
    }

    fn from_absorption(a: &Absorption) -> Figures {
        Figures {
            ps: a.success,
            pf: a.failure,
            mtts: (a.success > 0.0).then(|| a.time_success / a.success),
            mttf: (a.failure > 0.0).then(|| a.time_failure / a.failure),
        }
    }
}

/// What can go wrong while analysing a valid tree.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum AnalysisError {
    /// A deterministic, hybrid or shifted action where the analysis needs phase-type times.
    #[error(
        "action '{leaf}' has deterministic, hybrid or shifted times, which the exact analysis of a \
         Parallel node does not support yet"
    )]
    NotMarkovian {
        /// The offending leaf.
        leaf: String,
    },
    /// A chain would exceed the state budget.
    #[error(
        "node '{node}' needs a chain of up to {states:.3e} states, more than the budget of \
         {budget} states"
    )]
    StateBudget {
        /// The node whose chain is too large.
        node: String,
        /// Estimated number of states.
        states: f64,
        /// The budget.
        budget: usize,
    },
    /// Uniformization would need too much work (a stiff chain over a long horizon).
    #[error(
        "node '{node}' is too stiff for the transient solver over this horizon (max rate × \
         horizon × chain size ≈ {work:.2e} operations, limit {limit:.2e})"
    )]
    Stiff {
        /// The node analysed.
        node: String,
        /// Estimated work.
        work: f64,
        /// The limit.
        limit: f64,
    },
    /// The composed outcome laws would need too much work: the
    /// convolutions of densities interpolated on many panels (a long horizon
    /// over a subtree whose densities jump or kink often).
    #[error(
        "node '{node}': its composed outcome law on [0, {horizon}] needs about {work:.2e} \
         panel-piece evaluations in its convolutions, more than the limit of {limit:.2e}"
    )]
    ConvolutionWork {
        /// The node whose law was being built.
        node: String,
        /// The horizon of the law (s).
        horizon: f64,
        /// Estimated work, counted before each convolution.
        work: f64,
        /// The limit.
        limit: f64,
    },
    /// A loop decorator whose child can never end the loop.
    #[error("node '{node}' never returns: it repeats its child until {until}, and the child never returns {until}")]
    NeverReturns {
        /// The loop node.
        node: String,
        /// `Success` or `Failure`.
        until: &'static str,
    },
    /// A loop without a bound (`until_failure`, `until_success`) whose time
    /// distribution the analysis needs but cannot build: its child goes on
    /// at once for sure (it would repeat within one instant), or a re-run
    /// process's series is too long where no other method applies.
    #[error(
        "node '{node}' repeats its child without a bound, and its distribution over time is not \
         available here (its child goes on at once for sure, or its series of repetitions is too \
         long for the subtree around it); its figures are exact"
    )]
    Unbounded {
        /// The loop node.
        node: String,
    },
    /// A Nav2 node (PipelineSequence, RoundRobin, ...) that is not exactly
    /// one of the primitives where it stands ([`crate::tree::nav2::primitive_view`]).
    #[error("node '{node}' ({kind}, path {path}{at}) has no exact analysis yet: {reason}")]
    Nav2 {
        /// The node.
        node: String,
        /// `, line L, column C` when the node's place in its file is known.
        at: String,
        /// Its kind keyword.
        kind: &'static str,
        /// Its path.
        path: String,
        /// Why.
        reason: String,
    },
    /// The linear algebra produced a non-finite or out-of-range number.
    #[error("numerical failure at node '{node}': {what}")]
    Numerical {
        /// The node.
        node: String,
        /// What was wrong.
        what: String,
    },
}

/// The analysis of a whole tree: one [`Figures`] per node, indexed by [`NodeId`].
#[derive(Debug, Clone, PartialEq)]
pub struct Analysis {
    /// The method used.
    pub method: Method,
    /// Figures of every node, in tree order.
    pub nodes: Vec<Figures>,
}

/// The tree lowered to the core IR ([`crate::ir::lower`]), or the refusal
/// naming the Nav2 node that has no exact equivalent where it stands.
pub fn lower(tree: &Tree) -> Result<Lowered, AnalysisError> {
    crate::ir::lower(tree).map_err(|e| {
        let n = tree.node(e.node);
        AnalysisError::Nav2 {
            node: n.name.clone(),
            at: n
                .location
                .map_or(String::new(), |(l, c)| format!(", line {l}, column {c}")),
            kind: n.kind.keyword(),
            path: n.path.clone(),
            reason: e.reason,
        }
    })
}

impl Analysis {
    /// The figures of node `id`'s children, in child order.
    pub fn children<K: Kind>(&self, tree: &Tree<K>, id: NodeId) -> Vec<Figures> {
        tree.node(id)
            .kind
            .children()
            .iter()
            .map(|&c| self.nodes[c])
            .collect()
    }
}

/// Analyses every node of the tree, bottom-up, each from its planned
/// representation (`plan`).
pub fn analyze(tree: &Tree, options: &Options) -> Result<Analysis, AnalysisError> {
    let lowered = lower(tree)?;
    analysis_of(
        &Plan::new(&lowered.graph, options.method, options.max_states),
        lowered.image.as_deref(),
    )
}

/// Every node's figures from `plan` (of a tree's IR), for the nodes of the
/// tree (`image`: the node standing for each, [`Lowered::image`]).
pub(crate) fn analysis_of(
    plan: &Plan,
    image: Option<&[NodeId]>,
) -> Result<Analysis, AnalysisError> {
    let mut nodes = subtree_figures(plan, 0)?;
    // the original tree's nodes, each as the node standing for it
    if let Some(image) = image {
        nodes = image.iter().map(|&i| nodes[i]).collect();
    }
    Ok(Analysis {
        method: plan.method(),
        nodes,
    })
}

/// The figures of every node of `id`'s subtree (`[k]`: node `id + k`),
/// bottom-up, each from its planned representation. A subtree's figures
/// depend on it alone: a copy of an analysed subtree (a RecoveryNode's
/// retries, a re-run's copies) takes its figures.
pub(crate) fn subtree_figures(plan: &Plan, id: NodeId) -> Result<Vec<Figures>, AnalysisError> {
    let tree = plan.tree();
    let range = tree.subtree(id);
    let base = range.start;
    let mut figures: Vec<Option<Figures>> = vec![None; range.len()];
    let prints = plan.fingerprints();
    let mut seen: std::collections::HashMap<u64, NodeId> = std::collections::HashMap::new();
    // pre-order: children come after their parent, so reverse order is bottom-up
    for n in range.rev() {
        if let Some(f) = plan.known_figures(n) {
            figures[n - base] = Some(f);
            continue;
        }
        if let Some(&twin) = seen.get(&prints[n]) {
            if tree.same_subtree(twin, n) {
                figures[n - base] = figures[twin - base];
                if let Some(f) = figures[n - base] {
                    plan.remember_figures(n, f);
                }
                continue;
            }
        }
        seen.entry(prints[n]).or_insert(n);
        let child_figs: Vec<Figures> = tree
            .node(n)
            .kind
            .children()
            .iter()
            .map(|&c| figures[c - base].expect("children are analysed first"))
            .collect();
        let f = plan.figures(n, &child_figs)?;
        check(&f, &tree.node(n).name)?;
        plan.remember_figures(n, f);
        figures[n - base] = Some(f);
    }
    Ok(figures.into_iter().flatten().collect())
}

/// Figures of a leaf, identical under both methods.
pub(crate) fn leaf_figures(op: &Op) -> Option<Figures> {
    match op {
        Op::Leaf(Leaf::Action(a)) => Some(Figures {
            ps: a.ps,
            pf: a.pf,
            mtts: (a.ps > 0.0).then(|| a.success.map_or(0.0, |d: Duration| d.mean())),
            mttf: (a.pf > 0.0).then(|| a.failure.map_or(0.0, |d: Duration| d.mean())),
        }),
        Op::Leaf(Leaf::Condition { ps }) => Some(Figures {
            ps: *ps,
            pf: 1.0 - ps,
            mtts: (*ps > 0.0).then_some(0.0),
            mttf: (*ps < 1.0).then_some(0.0),
        }),
        _ => None,
    }
}

/// Largest product (upper bound `Π (phases_h + 2)`) for which a Parallel
/// node with the book's thresholds is solved through its product chain;
/// wider ones are counted ([`counts`]).
pub const PRODUCT_LIMIT: f64 = 20_000.0;

/// Figures of a Parallel node with the book's thresholds by counting its
/// children ([`counts`]), when its product chain would be larger than
/// [`PRODUCT_LIMIT`] (or than the budget's Parallel share). `Ok(None)` when
/// the product is small enough, or when a
/// child has no phase chain (deterministic times: the atoms path applies).
pub(crate) fn parallel_by_counts(
    plan: &Plan,
    id: NodeId,
    m: usize,
    child_figs: &[Figures],
) -> Result<Option<Figures>, AnalysisError> {
    let tree = plan.tree();
    let options = Options {
        method: Method::Exact,
        max_states: plan.max_states(),
    };
    let memo = &plan.laws;
    let node = tree.node(id);
    let children = node.kind.children();
    if children
        .iter()
        .any(|&c| !children::Children::markovian(plan, c))
    {
        return Ok(None);
    }
    // a child holding a wide Parallel itself (its chain estimated over the
    // budget): the children's composed laws
    for &c in children {
        if !plan.chain_size(c)?.fits() {
            return means_from_laws(plan, id, m, child_figs, &options, memo).map(Some);
        }
    }
    let chains = children
        .iter()
        .map(|&c| plan.chain(c))
        .collect::<Result<Vec<_>, _>>()?;
    let product: f64 = chains.iter().map(|c| (c.len() + 2) as f64).product();
    // the product chain is built only where it is both small and within the
    // budget's Parallel share (beyond which `phase` refuses it)
    let share = (options.max_states / phase::BOOK_PARALLEL_SHARE) as f64;
    if product <= PRODUCT_LIMIT.min(share) {
        return Ok(None);
    }
    // stiff children (fast and slow phases over a long horizon) make the
    // certified quadrature's uniformization passes and its ellipse bounds
    // (which grow like e^{Λ·width}) very costly: composed laws instead
    let longest = child_figs
        .iter()
        .map(Figures::mean_time)
        .fold(0.0, f64::max);
    let fastest = chains
        .iter()
        .flat_map(|c| (0..c.len()).map(|i| c.total_rate(i)))
        .fold(0.0, f64::max);
    // and the passes' work: steps times the chains' phases and moves (a
    // loop's chain is its child's, unrolled to where its repetitions end
    // but for 1e-14: survey tree 2786's counted Parallel has a loop child of
    // 36,126 phases whose passes over 60,000 steps took 113 s)
    let steps = fastest * 32.0 * longest;
    let moves: f64 = chains
        .iter()
        .map(|c| (c.len() + c.transitions.iter().map(Vec::len).sum::<usize>()) as f64)
        .sum();
    if steps > STIFF_STEPS || steps * moves > STIFF_WORK {
        let (ps, pf) = counts::status_by_counts(
            &child_figs.iter().map(|f| (f.ps, f.pf)).collect::<Vec<_>>(),
            m,
            children.len() + 1 - m,
        );
        let [ts, tf] = plan.parallel_times_by_quadrature(id, m, child_figs)?;
        return Ok(Some(Figures::from_moments([ps, pf, ts, tf])));
    }
    let laws: Vec<counts::ChildLaw> = chains.into_iter().map(counts::ChildLaw::new).collect();
    let (s, f) = counts::parallel_means(&laws, m).map_err(|what| AnalysisError::Numerical {
        node: node.name.clone(),
        what,
    })?;
    Ok(Some(Figures {
        ps: s.probability,
        pf: f.probability,
        mtts: (s.probability > 0.0).then(|| s.time / s.probability),
        mttf: (f.probability > 0.0).then(|| f.time / f.probability),
    }))
}

/// Uniformization steps over 32 × the longest child mean beyond which a
/// counted Parallel's mean times come from composed laws rather than the
/// certified quadrature ([`counts`] module docs).
pub(crate) const STIFF_STEPS: f64 = 1e5;

/// Work of the certified quadrature's uniformization passes (steps over 32
/// × the longest child mean, times the children's phases and moves) beyond
/// which a counted Parallel's mean times come from composed laws.
pub(crate) const STIFF_WORK: f64 = 1e8;

/// Figures of a counted Parallel from composed laws: P(S), P(F) by counting
/// the children's exact figures, the mean times as first moments of the
/// node's outcome law ([`law::counted_parallel_times`]; an
/// error estimate, not a bound). Used when a child holds a wide Parallel
/// itself, or when the children are stiff.
fn means_from_laws(
    plan: &Plan,
    id: NodeId,
    m: usize,
    child_figs: &[Figures],
    options: &Options,
    memo: &law::LawMemo,
) -> Result<Figures, AnalysisError> {
    let outcomes: Vec<(f64, f64)> = child_figs.iter().map(|f| (f.ps, f.pf)).collect();
    let (ps, pf) = counts::status_by_counts(&outcomes, m, child_figs.len() + 1 - m);
    let means: Vec<f64> = child_figs.iter().map(Figures::mean_time).collect();
    let [ts, tf] = law::counted_parallel_times(plan, id, m, &means, options.max_states, memo)?;
    Ok(Figures::from_moments([ps, pf, ts, tf]))
}

/// Figures of a loop without a bound, from its child's: a loop until
/// Failure returns Failure after `K` successful runs, `P(K = k, Failure) =
/// ps^k·pf`, so `P(F) = pf/(1 − ps)` and, given that it returns,
/// `E[K] = ps/(1 − ps)`: `MTTF = ps/(1 − ps)·MTTS + MTTF_child`; a loop
/// until Success likewise with the outcomes exchanged. The rest,
/// `1 − P(F)`, never returns: a child that never fails (`pf = 0`) makes the
/// loop run forever (`ps = 1`), or a run of the child that never returns
/// (a defective child law).
pub(crate) fn loop_figures(until: Outcome, child: Figures) -> Figures {
    let (p_end, p_again, t_end, t_again) = match until {
        Outcome::Failure => (child.pf, child.ps, child.mttf, child.mtts),
        Outcome::Success => (child.ps, child.pf, child.mtts, child.mttf),
    };
    let (p, t) = if p_end <= 0.0 {
        (0.0, None)
    } else {
        let again = p_again / (1.0 - p_again);
        (
            (p_end / (1.0 - p_again)).min(1.0),
            Some(again * t_again.unwrap_or(0.0) + t_end.unwrap_or(0.0)),
        )
    };
    Figures::one_sided(until, p, t)
}

/// Figures of a [`Op::Map`] from its child's (exact under both methods):
/// each outcome gathers the child's outcomes mapped to it, with their
/// probability-weighted mean time (an inverter swaps the figures; a
/// force_success has the child's mean time `E[T]` over the runs that
/// return — a child that may never return leaves that mass never
/// returning).
pub(crate) fn map_figures(on_success: Outcome, on_failure: Outcome, child: Figures) -> Figures {
    if on_success != on_failure {
        return match on_success {
            Outcome::Success => child,
            Outcome::Failure => Figures {
                ps: child.pf,
                pf: child.ps,
                mtts: child.mttf,
                mttf: child.mtts,
            },
        };
    }
    let returns = child.ps + child.pf;
    let mean = (returns > 0.0).then(|| child.mean_time() / returns);
    Figures::one_sided(on_success, returns, mean)
}

/// Figures of a flow repeating one child (`stop`: the outcome that ends it
/// early, Success for a Retry, Failure for a Repeat): the DTMC over the MRG
/// of a Fallback (Sequence) of `times` fresh copies.
pub(crate) fn repeat_figures(
    times: usize,
    stop: Outcome,
    child: Figures,
) -> Result<Figures, String> {
    let chain = mrg_chain(
        &Mrg::build(Policy::stopping_at(stop), times),
        &vec![child; times],
        false,
    );
    Ok(Figures::from_absorption(&solve_absorbing(&chain)?))
}

/// The DTMC over an MRG with children summarised by their figures.
///
/// Each event "child h returns Success (Failure)" has probability
/// `ps_h`/`pf_h` when h is the only feasible child, and otherwise
/// (Parallel, `book`) the share (9.38)–(9.39) of the competing children's
/// rates `1 / SJ_h` with `SJ_h = ps_h·MTTS_h + pf_h·MTTF_h` (9.41). The
/// duration of an event is the child's MTTS/MTTF when it is the only
/// feasible child (as in Lemma 9.2) and the marking's mean sojourn (9.40)
/// otherwise. Children of zero mean duration (conditions) return first,
/// in order, in zero time.
pub(crate) fn mrg_chain(g: &Mrg, children: &[Figures], competing: bool) -> AbsorbingChain {
    // transient markings are renumbered densely, keeping their order
    let mut dense = vec![usize::MAX; g.len()];
    let mut n = 0;
    for (i, s) in g.status.iter().enumerate() {
        if *s == Status::Running {
            dense[i] = n;
            n += 1;
        }
    }
    let target = |m: usize| match g.status[m] {
        Status::Running => Target::State(dense[m]),
        Status::Success => Target::Success,
        Status::Failure => Target::Failure,
    };
    let edges = weighted_events(g, children, competing)
        .into_iter()
        .filter(|w| w.prob > 0.0)
        .map(|w| Edge {
            from: dense[w.event.from],
            to: target(w.event.to),
            prob: w.prob,
            duration: w.duration,
        })
        .collect();
    AbsorbingChain {
        n,
        initial: vec![(0, 1.0)],
        initial_success: 0.0,
        initial_failure: 0.0,
        edges,
    }
}

/// An MRG event with its DTMC probability and mean duration.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct WeightedEvent {
    /// The event.
    pub event: mrg::Event,
    /// Its probability from its marking (0 for a child pre-empted by a
    /// zero-duration sibling).
    pub prob: f64,
    /// Its mean duration.
    pub duration: f64,
}

/// Every event of `g` with the probability and duration described on
/// `mrg_chain`'s rules: the child's own ps/pf and MTTS/MTTF when it is the
/// only feasible child (or `competing` is false), otherwise the share
/// (9.38)–(9.39) of rates `1/SJ_h` and the marking's mean sojourn (9.40);
/// zero-duration children return first.
pub(crate) fn weighted_events(
    g: &Mrg,
    children: &[Figures],
    competing: bool,
) -> Vec<WeightedEvent> {
    let sojourn = |h: usize| children[h].mean_time();
    let mut out = Vec::with_capacity(g.events.len());
    let mut start = 0;
    while start < g.events.len() {
        let from = g.events[start].from;
        let end = start + g.events[start..].partition_point(|e| e.from == from);
        let events = &g.events[start..end];
        let feasible: Vec<usize> = events
            .iter()
            .filter(|e| e.outcome == Outcome::Success)
            .map(|e| e.child)
            .collect();
        let instantaneous = feasible.iter().copied().find(|&h| sojourn(h) == 0.0);
        let single = feasible.len() == 1 || !competing;
        let total_rate: f64 = feasible.iter().map(|&h| 1.0 / sojourn(h)).sum();
        for e in events {
            let f = &children[e.child];
            let p_outcome = match e.outcome {
                Outcome::Success => f.ps,
                Outcome::Failure => f.pf,
            };
            let (prob, duration) = if single {
                let t = match e.outcome {
                    Outcome::Success => f.mtts,
                    Outcome::Failure => f.mttf,
                };
                (p_outcome, t.unwrap_or(0.0))
            } else if let Some(h) = instantaneous {
                (if e.child == h { p_outcome } else { 0.0 }, 0.0)
            } else {
                let share = (1.0 / sojourn(e.child)) / total_rate;
                (p_outcome * share, 1.0 / total_rate)
            };
            out.push(WeightedEvent {
                event: *e,
                prob,
                duration,
            });
        }
        start = end;
    }
    out
}

fn check(f: &Figures, node: &str) -> Result<(), AnalysisError> {
    let bad = |what: &str, x: f64| AnalysisError::Numerical {
        node: node.to_string(),
        what: format!("{what} = {x}"),
    };
    for (what, x) in [("ps", f.ps), ("pf", f.pf)] {
        if !x.is_finite() || !(-1e-9..=1.0 + 1e-9).contains(&x) {
            return Err(bad(what, x));
        }
    }
    // a law may be defective (the rest never returns), never above 1
    if f.ps + f.pf - 1.0 > 1e-6 {
        return Err(bad("ps + pf", f.ps + f.pf));
    }
    for (what, x) in [("MTTS", f.mtts), ("MTTF", f.mttf)] {
        if let Some(x) = x {
            if !x.is_finite() || x < 0.0 {
                return Err(bad(what, x));
            }
        }
    }
    Ok(())
}
