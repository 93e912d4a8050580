//! The planner: one table that picks, for every node, how the engine
//! represents the law of its return — the time and outcome of its Success
//! or Failure — and the two queries every command asks of it, the node's
//! figures (P(S), P(F), MTTS, MTTF) and its curve `π(t)`.
//!
//! A [`Plan`] is made once per tree (its core IR, [`crate::ir`]) and
//! strategy. It first records each node's *shape* bottom-up in
//! one pass — whether every leaf below is exponential (the subtree has a
//! phase chain), deterministic (finitely many return instants), or loops
//! without a bound — and then decides a node's [`Representation`] the first
//! time it is asked, by the first rule of the table below that applies,
//! and keeps it (and the phase chains of Parallel nodes, which ancestors
//! reuse instead of rebuilding). `report` (figures), `curve`, `compare`,
//! `plot`, `sensitivity` and `--ci` all query the same plan, so every
//! command answers a node from the same representation, with the same tie
//! rule (BehaviorTree.CPP's child order, `compile::race`).
//!
//! | # | rule (first match wins) | representation |
//! |---|---|---|
//! | 1 | an action or condition | [`Representation::Closed`]: its parameters, its CDFs in closed form |
//! | 2 | strategy `book`, a control node | [`Representation::Book`]: the book's CTMC over the node's MRG, children as exponential actions |
//! | 3 | `until_failure` / `until_success` | [`Representation::Loop`]: the cyclic chain over the child's phase chain, or the shifted law's truncated series |
//! | 4 | every leaf below deterministic (or a condition), no loop | [`Representation::Atoms`]: the finitely many return instants |
//! | 5 | every leaf below phase-type (exponential, Erlang, hypoexponential), the chain within the budget (a Parallel with the book's thresholds: its product ≤ [`super::PRODUCT_LIMIT`]; a loop below unrolled into at most [`phase::LONG_UNROLLED`] phases in all) | [`Representation::Chain`]: the exact phase chain |
//! | 5b | a map (inverter, force decorator) | [`Representation::Mapped`]: its child's law, its outcomes mapped |
//! | 6 | a Parallel with the book's thresholds (`F ≥ N − M + 1`) | [`Representation::Counted`]: the count programme over the children's own laws |
//! | 7 | a Parallel whose two thresholds can both be met | [`Representation::Race`]: the race of the children's laws |
//! | 8 | a leaf below is deterministic, hybrid or shifted | [`Representation::Shifted`]: the shifted phase-type mixture; where it exceeds the budget (every distinct sum of fixed times is a component; a curve takes it where its size, estimated before building (`shifted::mixture_size`), is within `SHIFTED_FIRST` = 65,536 phases) or cannot hold a Parallel below, the curve comes from the composed outcome laws with atoms at any instant ([`law`]) |
//! | 9 | otherwise (a chain over the budget: a wide Parallel below) | [`Representation::Composed`]: the composed outcome laws (interpolated densities) |
//!
//! One rule goes before the table for the curve: a race against a renewal
//! process of re-runs (Nav2's re-planning) and the Sequence that starts it
//! are answered by its levels (`renewal_curve`), and a node *above* such a
//! race by the composed outcome laws (`law::curve_by_laws`) when its
//! loop's series is long — the race's own law from its levels
//! (`renewal_law`) where they hold it, else the composed laws' race. Its
//! representation, and so its figures, are the table's.
//!
//! The figures of a Sequence, Fallback, decorator or flow come from its
//! children's figures over the DTMC of its MRG whatever its representation:
//! mean times add along paths for any distributions, so this is exact and
//! linear in the number of children. A Parallel's figures come from its
//! representation.

use std::cell::{OnceCell, RefCell};
use std::collections::HashMap;

use super::children::{Children, Representation, ReturnLaw};
use super::curve_options::{CurveOptions, CurvePoint, Timing};
use super::mrg::{self, Mrg, Policy};
use super::shifted::{FirstMixture, SHIFTED_FIRST};
use super::{
    atoms, book_ctmc, chain_curve, counts, flow, law, parallel_times, phase, race, AnalysisError,
    Figures, Method,
};
use crate::ir::{FlowGraph, Graph, Leaf, Op};
use crate::solve::chain::PhaseChain;
use crate::solve::solve_absorbing;
use crate::tree::nav2::MAX_RERUN_TERMS;
use crate::tree::{Duration, NodeId};

/// What the planner knows of a subtree before building anything.
#[derive(Debug, Clone, Copy)]
struct Shape {
    /// Every leaf has exponential times (or is a condition).
    exponential: bool,
    /// Every leaf has fixed times (or is a condition).
    deterministic: bool,
    /// A loop without a bound below (or here).
    looped: bool,
}

/// `(exponential, deterministic)` of one outcome's time of an action.
fn side(p: f64, d: Option<Duration>) -> (bool, bool) {
    if p <= 0.0 {
        return (true, true);
    }
    // a zero-time outcome is instantaneous in a phase chain too;
    // exponential, Erlang, hypo-, hyperexponential, phase-type: phases
    let markovian = phase::outcome_markovian(p, d);
    match d {
        Some(Duration::Fixed { .. }) => (markovian, true),
        _ => (markovian, false),
    }
}

fn shapes(tree: &Graph) -> Vec<Shape> {
    let mut out = vec![
        Shape {
            exponential: true,
            deterministic: true,
            looped: false,
        };
        tree.nodes.len()
    ];
    // pre-order: reverse order is bottom-up
    for id in (0..tree.nodes.len()).rev() {
        out[id] = match &tree.node(id).kind {
            Op::Leaf(Leaf::Action(a)) => {
                let (es, ds) = side(a.ps, a.success);
                let (ef, df) = side(a.pf, a.failure);
                Shape {
                    exponential: es && ef,
                    deterministic: ds && df,
                    looped: false,
                }
            }
            Op::Leaf(Leaf::Condition { .. }) => out[id],
            kind => {
                let mut s = out[id];
                for &c in kind.children() {
                    s.exponential &= out[c].exponential;
                    s.deterministic &= out[c].deterministic;
                    s.looped |= out[c].looped;
                }
                s.looped |= matches!(kind, Op::Loop { .. });
                s
            }
        };
    }
    out
}

/// `(M, F capped at N − M + 1, N)` of a Parallel.
fn thresholds(kind: &Op) -> Option<(usize, usize, usize)> {
    match kind {
        Op::KOfN {
            success,
            failure,
            children,
        } => Some((*success, *failure, children.len())),
        _ => None,
    }
}

/// Whether a Parallel has the book's thresholds (`F ≥ N − M + 1`): it
/// returns Success iff ≥ M children have succeeded.
fn book_thresholds(kind: &Op) -> bool {
    thresholds(kind).is_some_and(|(m, f, n)| f > n - m)
}

/// The planner answers the representations' questions about the subtrees
/// below them (module [`super::children`]).
impl Children for Plan<'_> {
    fn tree(&self) -> &Graph {
        Plan::tree(self)
    }
    fn max_states(&self) -> usize {
        self.max_states
    }
    fn representation(&self, id: NodeId) -> Result<Representation, AnalysisError> {
        Plan::representation(self, id)
    }
    fn markovian(&self, id: NodeId) -> bool {
        self.shapes[id].exponential
    }
    fn chain_size(&self, id: NodeId) -> Result<phase::ChainSize, AnalysisError> {
        Plan::chain_size(self, id)
    }
    fn chain(&self, id: NodeId) -> Result<PhaseChain, AnalysisError> {
        Plan::chain(self, id)
    }
    fn known_subtree_figures(&self, id: NodeId) -> Vec<Option<Figures>> {
        Plan::known_subtree_figures(self, id)
    }
    fn subtree_figures(&self, id: NodeId) -> Result<Vec<Figures>, AnalysisError> {
        super::subtree_figures(self, id)
    }
    fn horizon_law(&self, id: NodeId, end: f64) -> Result<Box<dyn ReturnLaw>, AnalysisError> {
        Ok(Box::new(law::HorizonLaw::build(self, id, end)?))
    }
    fn deadline_figures(&self, id: NodeId) -> Result<Option<[f64; 4]>, AnalysisError> {
        law::deadline_figures(self, id)
    }
}

impl Plan<'static> {
    /// [`Plan::new`] owning its tree (a plan kept beside the tree it was
    /// made from, as the `Model` keeps it).
    pub fn owned(tree: Graph, method: Method, max_states: usize) -> Plan<'static> {
        Plan::with_tree(std::borrow::Cow::Owned(tree), method, max_states)
    }

    /// Puts the children of each Fallback chain `node` of `changes` in its
    /// `order` (ids of the IR): the plan of that tree, keeping the figures
    /// and fingerprints of every node off the paths from those nodes to the
    /// root (the rest of the plan's work is made again where a query needs
    /// it).
    pub(crate) fn reorder(&mut self, changes: &[(NodeId, &[NodeId])]) {
        let (method, max_states) = (self.method, self.max_states);
        let empty = Graph {
            title: None,
            nodes: Vec::new(),
        };
        let old = std::mem::replace(self, Plan::owned(empty, method, max_states));
        let n = old.tree.nodes.len();
        let known: Vec<Option<Figures>> = (0..n).map(|i| old.known_figures(i)).collect();
        let prints = old.prints.into_inner();
        let mut graph = old.tree.into_owned();
        let mut dirty = vec![false; n];
        for &(node, order) in changes {
            if let Op::Flow(flow) = &mut graph.nodes[node].kind {
                flow.children.copy_from_slice(order);
            }
            let mut up = Some(node);
            while let Some(a) = up.filter(|&a| !dirty[a]) {
                dirty[a] = true;
                up = graph.nodes[a].parent;
            }
        }
        // the fingerprints on those paths again (children first: larger ids)
        let prints = prints.map(|mut p| {
            for id in (0..n).rev().filter(|&i| dirty[i]) {
                p[id] = graph.fingerprint(id, &p);
            }
            p
        });
        *self = Plan::owned(graph, method, max_states);
        if let Some(p) = prints {
            let _ = self.prints.set(p);
        }
        for (i, f) in known.into_iter().enumerate() {
            if let Some(f) = f.filter(|_| !dirty[i]) {
                self.remember_figures(i, f);
            }
        }
    }
}

/// The planned model of one tree under one strategy: every node's
/// representation, decided once, and the queries on it.
pub struct Plan<'t> {
    /// The tree's IR: borrowed, or owned by a plan that outlives its
    /// caller's ([`Plan::owned`], the `Model`'s).
    tree: std::borrow::Cow<'t, Graph>,
    method: Method,
    max_states: usize,
    shapes: Vec<Shape>,
    representations: Vec<OnceCell<Representation>>,
    /// Phase chains of Parallel nodes (products), reused by ancestors.
    chains: RefCell<HashMap<NodeId, PhaseChain>>,
    /// Every node's phase-chain size, estimated before building
    /// ([`phase::chain_size`]).
    sizes: RefCell<HashMap<NodeId, phase::ChainSize>>,
    /// Laws of counted Parallels by node and horizon (mean times).
    pub(crate) laws: law::LawMemo,
    /// Composed laws and first shifted mixtures kept across curve queries.
    kept: law::Kept,
    /// The book's figures of every node (strategy `book`, curves).
    book: OnceCell<Vec<Figures>>,
    /// Races against a renewal process whose loop's series is long:
    /// `(race, process)`, in pre-order.
    long_renewals: OnceCell<Vec<(NodeId, NodeId)>>,
    /// Every node's figures, once computed ([`super::subtree_figures`]).
    figures: Vec<OnceCell<Figures>>,
    /// Every node's fingerprint ([`Graph::fingerprints`]: copies of a
    /// subtree take its figures), made on first use.
    prints: OnceCell<Vec<u64>>,
}

impl<'t> Plan<'t> {
    /// The plan of `tree` (a tree's core IR, [`super::lower`]) under
    /// `method`, with at most `max_states` states in any chain.
    pub fn new(tree: &'t Graph, method: Method, max_states: usize) -> Plan<'t> {
        Plan::with_tree(std::borrow::Cow::Borrowed(tree), method, max_states)
    }

    fn with_tree(tree: std::borrow::Cow<'t, Graph>, method: Method, max_states: usize) -> Plan<'t> {
        let n = tree.nodes.len();
        Plan {
            shapes: shapes(&tree),
            tree,
            method,
            max_states,
            representations: (0..n).map(|_| OnceCell::new()).collect(),
            chains: RefCell::default(),
            sizes: RefCell::default(),
            laws: law::LawMemo::default(),
            kept: law::Kept::default(),
            book: OnceCell::new(),
            long_renewals: OnceCell::new(),
            figures: (0..n).map(|_| OnceCell::new()).collect(),
            prints: OnceCell::new(),
        }
    }

    /// The IR planned.
    pub fn tree(&self) -> &Graph {
        &self.tree
    }

    /// The figures of node `id` if they were computed
    /// ([`super::subtree_figures`] keeps them).
    pub(crate) fn known_figures(&self, id: NodeId) -> Option<Figures> {
        self.figures[id].get().copied()
    }

    /// The figures of every node of `id`'s subtree (`[k]`: node `id + k`)
    /// that were computed, `None` for the others (the tail bound's input).
    pub(crate) fn known_subtree_figures(&self, id: NodeId) -> Vec<Option<Figures>> {
        self.tree
            .subtree(id)
            .map(|n| self.known_figures(n))
            .collect()
    }

    /// Every node's fingerprint ([`Graph::fingerprints`]).
    pub(crate) fn fingerprints(&self) -> &[u64] {
        self.prints.get_or_init(|| self.tree.fingerprints())
    }

    /// Keeps the figures of node `id`.
    pub(crate) fn remember_figures(&self, id: NodeId, figures: Figures) {
        let _ = self.figures[id].set(figures);
    }

    /// The strategy planned for.
    pub fn method(&self) -> Method {
        self.method
    }

    /// The largest chain (or number of atoms) the plan builds.
    pub fn max_states(&self) -> usize {
        self.max_states
    }

    /// The representation of node `id` (decided on first use).
    pub fn representation(&self, id: NodeId) -> Result<Representation, AnalysisError> {
        if let Some(r) = self.representations[id].get() {
            return Ok(*r);
        }
        let r = self.decide(id)?;
        Ok(*self.representations[id].get_or_init(|| r))
    }

    /// The planner's table (module docs).
    fn decide(&self, id: NodeId) -> Result<Representation, AnalysisError> {
        let kind = &self.tree.node(id).kind;
        let shape = self.shapes[id];
        if kind.children().is_empty() {
            return Ok(Representation::Closed);
        }
        if self.method == Method::Book {
            return Ok(Representation::Book);
        }
        if matches!(kind, Op::Loop { .. }) {
            return Ok(Representation::Loop);
        }
        if shape.deterministic && !shape.looped {
            return Ok(Representation::Atoms);
        }
        if shape.exponential && self.chain_fits(id)? && !self.long_unrolled(id)? {
            return Ok(Representation::Chain);
        }
        if matches!(kind, Op::Map { .. }) {
            return Ok(Representation::Mapped);
        }
        if book_thresholds(kind) {
            return Ok(Representation::Counted);
        }
        if thresholds(kind).is_some() {
            return Ok(Representation::Race);
        }
        if !shape.exponential {
            return Ok(Representation::Shifted);
        }
        Ok(Representation::Composed)
    }

    /// Whether `id` (exponential) has a phase chain within the budget, by
    /// its size estimated before building ([`phase::chain_size`]); a
    /// Parallel with the book's thresholds only if its product is small
    /// (larger ones are counted).
    fn chain_fits(&self, id: NodeId) -> Result<bool, AnalysisError> {
        let kind = &self.tree.node(id).kind;
        if book_thresholds(kind) {
            let mut product = 1.0;
            for &c in kind.children() {
                match self.chain_size(c)? {
                    phase::ChainSize::Within(n) => product *= n + 2.0,
                    _ => return Ok(false),
                }
            }
            let share = (self.max_states / phase::BOOK_PARALLEL_SHARE) as f64;
            if product > super::PRODUCT_LIMIT.min(share) {
                return Ok(false);
            }
        }
        Ok(self.chain_size(id)?.fits())
    }

    /// Whether `id`'s chain holds a loop unrolled into many copies (over
    /// [`phase::LONG_UNROLLED`] phases in all): its uniformization passes
    /// step every copy, where the composed laws take the loop's own cyclic
    /// chain.
    fn long_unrolled(&self, id: NodeId) -> Result<bool, AnalysisError> {
        if !self.shapes[id].looped {
            return Ok(false);
        }
        Ok(phase::long_unrolled(&self.chain_size(id)?, true))
    }

    /// The size of `id`'s phase chain, estimated before building it.
    pub(crate) fn chain_size(&self, id: NodeId) -> Result<phase::ChainSize, AnalysisError> {
        phase::chain_size(
            &self.tree,
            id,
            self.max_states,
            &mut self.sizes.borrow_mut(),
        )
    }

    /// The exact phase chain of `id` (Parallel nodes' chains are kept).
    pub fn chain(&self, id: NodeId) -> Result<PhaseChain, AnalysisError> {
        if let Some(c) = self.chains.borrow().get(&id) {
            return Ok(c.clone());
        }
        let node = self.tree.node(id);
        if node.kind.children().is_empty() {
            return phase::chain_of(&self.tree, id, self.max_states);
        }
        let children = node
            .kind
            .children()
            .iter()
            .map(|&c| self.chain(c))
            .collect::<Result<Vec<_>, _>>()?;
        let chain = phase::combine(&self.tree, id, children, self.max_states)?;
        if thresholds(&node.kind).is_some() {
            self.chains.borrow_mut().insert(id, chain.clone());
        }
        Ok(chain)
    }

    /// Figures of control node `id` from its children's `child_figs` (in
    /// child order).
    pub fn figures(&self, id: NodeId, child_figs: &[Figures]) -> Result<Figures, AnalysisError> {
        let node = self.tree.node(id);
        if let Some(f) = super::leaf_figures(&node.kind) {
            return Ok(f);
        }
        let numerical = |what: String| AnalysisError::Numerical {
            node: node.name.clone(),
            what,
        };
        match &node.kind {
            Op::Loop { until, .. } => return Ok(super::loop_figures(*until, child_figs[0])),
            Op::Map {
                on_success,
                on_failure,
                ..
            } => return Ok(super::map_figures(*on_success, *on_failure, child_figs[0])),
            Op::Flow(flow) => match flow.graph {
                FlowGraph::Chain { .. } => {}
                FlowGraph::Repeat { times, stop } => {
                    return super::repeat_figures(times, stop, child_figs[0]).map_err(numerical)
                }
                FlowGraph::States(_) => {
                    let chain = flow::figures_chain(flow, child_figs);
                    let a = solve_absorbing(&chain).map_err(numerical)?;
                    return Ok(Figures::from_absorption(&a));
                }
            },
            _ => {}
        }
        let policy = Policy::of(&node.kind).expect("control node");
        let n = child_figs.len();
        let Some((m, f, _)) = thresholds(&node.kind) else {
            let chain = super::mrg_chain(&Mrg::build(policy, n), child_figs, false);
            let a = solve_absorbing(&chain).map_err(numerical)?;
            return Ok(Figures::from_absorption(&a));
        };
        let chain = match self.representation(id)? {
            Representation::Book => {
                self.check_markings(id, m, f, n)?;
                super::mrg_chain(&Mrg::build(policy, n), child_figs, true)
            }
            Representation::Chain => self.chain(id)?.jump_chain(),
            Representation::Atoms => {
                let a = atoms::atoms(&self.tree, id, self.max_states)?
                    .expect("a deterministic subtree has atoms");
                return Ok(atoms::figures(&a));
            }
            Representation::Counted => return self.counted_figures(id, m, child_figs),
            Representation::Race => return race::figures(self, id, child_figs),
            r => unreachable!("a Parallel is never planned as {}", r.name()),
        };
        let a = solve_absorbing(&chain).map_err(numerical)?;
        Ok(Figures::from_absorption(&a))
    }

    /// Figures of a counted Parallel (success threshold `m`): P(S), P(F) by
    /// the count programme over the children's figures; the mean times by
    /// the certified quadrature when every child has a chain, from the
    /// composed laws when a child is itself over the budget, by the race's
    /// counting when a loop is below, and by quadrature of the counted curve
    /// otherwise (mixed timing).
    fn counted_figures(
        &self,
        id: NodeId,
        m: usize,
        child_figs: &[Figures],
    ) -> Result<Figures, AnalysisError> {
        if let Some(f) = super::parallel_by_counts(self, id, m, child_figs)? {
            return Ok(f);
        }
        if self.shapes[id].looped {
            // a loop's law is a long series: built once by the race's
            // counting rather than at every quadrature pass
            return race::figures(self, id, child_figs);
        }
        let n = child_figs.len();
        let outcomes: Vec<(f64, f64)> = child_figs.iter().map(|f| (f.ps, f.pf)).collect();
        let (ps, pf) = counts::status_by_counts(&outcomes, m, n + 1 - m);
        let [ts, tf] = self.parallel_times_by_quadrature(id, m, child_figs)?;
        Ok(Figures::from_moments([ps, pf, ts, tf]))
    }

    /// The mean times of Parallel `id` (success threshold `m`) by
    /// quadrature of its counted curve ([`parallel_times`]).
    pub(crate) fn parallel_times_by_quadrature(
        &self,
        id: NodeId,
        m: usize,
        child_figs: &[Figures],
    ) -> Result<[f64; 2], AnalysisError> {
        let fastest = || {
            self.tree
                .node(id)
                .kind
                .children()
                .iter()
                .filter(|&&c| self.chain_size(c).is_ok_and(|s| s.fits()))
                .filter_map(|&c| self.chain(c).ok())
                .flat_map(|c| (0..c.len()).map(move |i| c.total_rate(i)))
                .fold(0.0, f64::max)
        };
        parallel_times::parallel_times_by_quadrature(
            &self.tree,
            id,
            (m, self.max_states),
            child_figs,
            &fastest,
            &|times, options| self.counted_curve(id, m, times, options),
            &|scale, epsilon| {
                let known = self.known_subtree_figures(id);
                super::tail::settled_after(&self.tree, id, &known, scale, epsilon)
            },
        )
    }

    /// `π(t)` of node `id` at `times` (finite, ≥ 0, any order), in the
    /// order given. `options.timing` must be [`Timing::AsGiven`] (the
    /// deterministic version of a tree is another tree, with its own plan).
    pub fn curve(
        &self,
        id: NodeId,
        times: &[f64],
        options: &CurveOptions,
    ) -> Result<Vec<CurvePoint>, AnalysisError> {
        debug_assert_eq!(options.timing, Timing::AsGiven);
        let node = self.tree.node(id);
        // a race against a renewal process of re-runs (or the Sequence that
        // starts it): exact by levels of its wait, without a series
        if self.method != Method::Book
            && (matches!(node.kind, Op::KOfN { .. }) || node.kind.sequence().is_some())
        {
            if let Some(points) = super::renewal_curve::curve(&self.tree, id, times, options)? {
                return Ok(points);
            }
        }
        // a node above such a race whose series is long: the race's law
        // (`renewal_law`) composed with the rest (module docs)
        if self.method != Method::Book && self.holds_long_renewal(id) {
            return law::curve_by_laws(self, id, times, options, &self.kept);
        }
        self.curve_by_representation(id, times, options)
    }

    /// `π(t)` of node `id` by its representation (the planner's table).
    fn curve_by_representation(
        &self,
        id: NodeId,
        times: &[f64],
        options: &CurveOptions,
    ) -> Result<Vec<CurvePoint>, AnalysisError> {
        let node = self.tree.node(id);
        let points = |f: &dyn Fn(f64) -> (f64, f64)| -> Vec<CurvePoint> {
            times
                .iter()
                .map(|&t| {
                    let (success, failure) = f(t);
                    CurvePoint {
                        t,
                        success,
                        failure,
                        running: (1.0 - success - failure).max(0.0),
                    }
                })
                .collect()
        };
        match self.representation(id)? {
            Representation::Closed => Ok(match &node.kind {
                // an outcome without a duration has probability 0
                Op::Leaf(Leaf::Action(a)) => points(&|t| {
                    let cdf = |d: Option<Duration>| d.map_or(0.0, |d| d.cdf(t));
                    (a.ps * cdf(a.success), a.pf * cdf(a.failure))
                }),
                Op::Leaf(Leaf::Condition { ps }) => points(&|_| (*ps, 1.0 - ps)),
                _ => unreachable!("closed form is for leaves"),
            }),
            Representation::Loop => {
                let Op::Loop { child, until } = node.kind else {
                    unreachable!("planned as a loop")
                };
                law::loop_curve(self, id, child, until, times, options, &self.kept)
            }
            Representation::Atoms => {
                let a = atoms::atoms(&self.tree, id, self.max_states)?
                    .expect("a deterministic subtree has atoms");
                Ok(points(&|t| atoms::cumulative(&a, t)))
            }
            Representation::Chain => {
                chain_curve::solve_chain(&self.chain(id)?, times, options, &node.name)
            }
            Representation::Counted => {
                let (m, _, _) = thresholds(&node.kind).expect("a counted node is a Parallel");
                self.counted_curve(id, m, times, options)
            }
            Representation::Race => race::curve(self, id, times),
            Representation::Mapped => {
                let (child, to) = node.kind.as_map().expect("planned as a map");
                Ok(self
                    .curve(child, times, options)?
                    .into_iter()
                    .map(|p| {
                        let mut v = [0.0; 2];
                        v[to[0]] += p.success;
                        v[to[1]] += p.failure;
                        CurvePoint {
                            t: p.t,
                            success: v[0],
                            failure: v[1],
                            running: p.running,
                        }
                    })
                    .collect())
            }
            Representation::Shifted => {
                // the mixture where its estimated size is within a smaller
                // budget: past it (every distinct sum of fixed times is a
                // component), or where the mixture cannot hold the node,
                // the composed laws
                let first = self.max_states.min(SHIFTED_FIRST);
                match self
                    .kept
                    .mixtures
                    .first(&self.tree, id, first, self.max_states)?
                {
                    FirstMixture::Built(law) => {
                        chain_curve::curve_by_shifted(&law, times, options, &node.name)
                    }
                    FirstMixture::CannotHold | FirstMixture::Over => {
                        law::curve_by_laws(self, id, times, options, &self.kept)
                    }
                }
            }
            Representation::Composed => law::curve_by_laws(self, id, times, options, &self.kept),
            Representation::Book => {
                let figs = self.book_figures()?;
                let children = node.kind.children();
                let child_figs: Vec<Figures> = children.iter().map(|&c| figs[c]).collect();
                let chain = if let Op::Map {
                    on_success,
                    on_failure,
                    ..
                } = node.kind
                {
                    book_ctmc::book_map(on_success, on_failure, child_figs[0])
                } else if let Op::Loop { until, .. } = node.kind {
                    book_ctmc::book_loop(until, child_figs[0])
                } else if let Some(flow) = not_chain(&node.kind) {
                    match flow.graph {
                        FlowGraph::Repeat { times, stop } => {
                            book_ctmc::book_repeat(times, stop, child_figs[0])
                        }
                        _ => flow::book_chain(flow, &child_figs),
                    }
                } else {
                    let policy = Policy::of(&node.kind).expect("control node");
                    if let Some((m, f, n)) = thresholds(&node.kind) {
                        self.check_markings(id, m, f, n)?;
                    }
                    book_ctmc::book_ctmc(&Mrg::build(policy, children.len()), &child_figs)
                };
                chain_curve::solve_chain(&chain, times, options, &node.name)
            }
        }
    }

    /// Whether a race against a renewal process whose loop's series is long
    /// lies below `id`.
    fn holds_long_renewal(&self, id: NodeId) -> bool {
        let races = self.long_renewals();
        !races.is_empty()
            && self
                .tree
                .subtree(id)
                .any(|n| races.iter().any(|r| r.0 == n))
    }

    /// The races against a renewal process whose loop's series exceeds
    /// what the series path computes (found once).
    fn long_renewals(&self) -> &[(NodeId, NodeId)] {
        self.long_renewals.get_or_init(|| {
            (0..self.tree.nodes.len())
                .filter(|&id| matches!(self.tree.node(id).kind, Op::KOfN { .. }))
                .filter_map(|id| {
                    let (process, terms) = super::renewal::series(&self.tree, id, self.max_states)?;
                    (terms > MAX_RERUN_TERMS as f64).then_some((id, process))
                })
                .collect()
        })
    }

    /// `π(t)` of a counted Parallel (success threshold `m`) from its
    /// children's curves: before the node returns its children run
    /// independently and its two thresholds cannot both be met, so it has
    /// succeeded by t iff at least M children have ([`counts`]).
    pub(crate) fn counted_curve(
        &self,
        id: NodeId,
        m: usize,
        times: &[f64],
        options: &CurveOptions,
    ) -> Result<Vec<CurvePoint>, AnalysisError> {
        let children = self.tree.node(id).kind.children();
        let f_cap = children.len() + 1 - m;
        let curves = children
            .iter()
            .map(|&c| self.curve(c, times, options))
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

    /// Refuses a Parallel whose MRG (the book's CTMC) would have more
    /// markings than the budget.
    fn check_markings(
        &self,
        id: NodeId,
        m: usize,
        f: usize,
        n: usize,
    ) -> Result<(), AnalysisError> {
        let est = mrg::parallel_marking_count(n, m, f);
        if est > self.max_states as f64 {
            return Err(AnalysisError::StateBudget {
                node: self.tree.node(id).name.clone(),
                states: est,
                budget: self.max_states,
            });
        }
        Ok(())
    }

    /// The book's figures of every node (computed once).
    fn book_figures(&self) -> Result<&[Figures], AnalysisError> {
        if let Some(f) = self.book.get() {
            return Ok(f);
        }
        let mut figs = vec![
            Figures {
                ps: 0.0,
                pf: 0.0,
                mtts: None,
                mttf: None,
            };
            self.tree.nodes.len()
        ];
        for id in (0..self.tree.nodes.len()).rev() {
            let child_figs: Vec<Figures> = self
                .tree
                .node(id)
                .kind
                .children()
                .iter()
                .map(|&c| figs[c])
                .collect();
            figs[id] = self.figures(id, &child_figs)?;
        }
        Ok(self.book.get_or_init(|| figs))
    }
}

/// The flow of `op` when it is a flow other than a chain (a repetition or
/// any graph of states).
fn not_chain(op: &Op) -> Option<&crate::ir::Flow> {
    match op {
        Op::Flow(f) if !matches!(f.graph, FlowGraph::Chain { .. }) => Some(f),
        _ => None,
    }
}
