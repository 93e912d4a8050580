//! Comparing equivalent trees (Def. 9.10): every ordering of the children of
//! chosen Fallback nodes, ranked by an objective.
//!
//! Reordering a Fallback's children never changes the root's final success
//! probability (the set of outcomes is the same) but changes how long runs
//! take. Reordering a Parallel's children changes nothing at all in this
//! model (its children start together and are independent), and a
//! Sequence's order is part of the plan (Def. 9.10 does not permute it).
//!
//! **Search.** Up to `max_candidates` orderings (the product of the chosen
//! nodes' permutations) are enumerated exhaustively. Each candidate only
//! re-analyses the reordered nodes and their ancestors
//! ([`Model::reorder`]). Beyond the limit:
//!
//! * for the mean time `E[T]`, the ordering rule below is exact;
//! * for other objectives a local search (best improving swap of two
//!   children of one node, until none improves) starts from that rule; the
//!   result is a local optimum and is reported as not proven.
//!
//! **The ordering rule.** A Fallback whose children have success
//! probabilities `p_i` and mean times `E_i` has
//! `E[T] = Σ_k (Π_{j<k} (1 − p_j)) E_k`. Swapping adjacent children `i`,
//! `i+1` changes only their two terms, `P·(E_i + (1−p_i)E_{i+1})` against
//! `P·(E_{i+1} + (1−p_{i+1})E_i)` (P the common prefix product), so `i`
//! should come first iff `p_i E_{i+1} ≥ p_{i+1} E_i`, i.e.
//! `p_i/E_i ≥ p_{i+1}/E_{i+1}`. Any ordering not sorted by that ratio has an
//! adjacent pair whose swap does not increase `E[T]`; bubble-sorting by it
//! therefore reaches a minimum, and all orderings sorted by the ratio (ties
//! in any order) have the same `E[T]`: sorting by `p_i/E_i` descending is
//! optimal. In a Sequence/Fallback tree a parent's `E[T]` is a non-negative
//! combination of its children's `E[T]` with coefficients (products of the
//! children's `p_s`, `p_f`) that do not depend on any ordering, so
//! minimising each Fallback's `E[T]` bottom-up minimises the root's: the rule
//! is globally optimal. Under a Parallel the mean time is not linear in the
//! children's means, and the rule is then reported as not proven.
//!
//! Size: one concern, ranking Fallback orderings: the search space, the
//! exhaustive and greedy searches and their budget (about 140 lines are
//! comments).

use std::collections::HashMap;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;

use rayon::prelude::*;

use crate::compile::{self, AnalysisError, Figures, Method};
use crate::ir::Op;
use crate::model::Model;
use crate::tree::{NodeId, NodeKind, Tree};

/// What to optimise.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Objective {
    /// Smallest `E[T]` = ps·MTTS + pf·MTTF.
    MeanTime,
    /// Smallest MTTS.
    Mtts,
    /// Smallest MTTF.
    Mttf,
    /// Largest P(root returned Success by the deadline).
    SuccessBy,
}

impl Objective {
    /// The objective's name on the command line.
    pub fn name(&self) -> &'static str {
        match self {
            Objective::MeanTime => "mean-time",
            Objective::Mtts => "mtts",
            Objective::Mttf => "mttf",
            Objective::SuccessBy => "success-by",
        }
    }
}

/// How the candidates were found.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Search {
    /// Every ordering evaluated.
    Exhaustive,
    /// The ordering rule (mean time).
    OrderingRule,
    /// Local search from the ordering rule.
    LocalSearch,
    /// Nothing to reorder: the given ordering is the only one.
    NothingToReorder,
}

impl Search {
    /// A short description.
    pub fn name(&self) -> &'static str {
        match self {
            Search::Exhaustive => "exhaustive",
            Search::OrderingRule => "ordering rule ps/E[T]",
            Search::LocalSearch => "local search from the ordering rule",
            Search::NothingToReorder => "none (nothing to reorder)",
        }
    }
}

/// Options of a comparison.
#[derive(Debug, Clone, PartialEq)]
pub struct CompareOptions {
    /// Fallback nodes whose children are permuted; empty: every Fallback.
    pub nodes: Vec<NodeId>,
    /// Objective; default: success-by with a deadline, else mean-time.
    pub objective: Option<Objective>,
    /// Deadline for `success_by_deadline` (s).
    pub deadline: Option<f64>,
    /// exact or book.
    pub method: Method,
    /// Largest number of orderings enumerated exhaustively. `None`: the
    /// automatic budget — at most [`DEFAULT_MAX_CANDIDATES`], and only as
    /// many as [`WORK_BUDGET_SECONDS`] of estimated work allow.
    pub max_candidates: Option<usize>,
    /// How many of the best candidates are kept (the given ordering is kept
    /// in any case).
    pub keep: usize,
    /// State budget of each analysis.
    pub max_states: usize,
}

impl Default for CompareOptions {
    fn default() -> Self {
        CompareOptions {
            nodes: Vec::new(),
            objective: None,
            deadline: None,
            method: Method::Exact,
            max_candidates: None,
            keep: 1000,
            max_states: compile::DEFAULT_MAX_STATES,
        }
    }
}

/// Default limit of exhaustive enumeration (8! = 40,320 fits).
pub const DEFAULT_MAX_CANDIDATES: usize = 100_000;

/// Estimated work (seconds of one core, times the number of worker
/// threads) the automatic budget allows for exhaustive enumeration.
pub const WORK_BUDGET_SECONDS: f64 = 2.0;

/// One ordering and the root's figures under it.
#[derive(Debug, Clone, PartialEq)]
pub struct Candidate {
    /// Children order of each compared node (same order as
    /// [`Comparison::nodes`]).
    pub orders: Vec<Vec<NodeId>>,
    /// The root's figures.
    pub root: Figures,
    /// P(root returned Success by the deadline), if a deadline was given.
    pub success_by_deadline: Option<f64>,
    /// Whether this is the ordering of the input file.
    pub given: bool,
    /// Rank among the evaluated orderings (1 = best); tied candidates share
    /// the rank of the first of them.
    pub rank: u64,
    /// Whether another evaluated ordering has the same objective value
    /// (within [`TIE_RELATIVE`] for times, [`TIE_ABSOLUTE`] for
    /// probabilities).
    pub tied: bool,
}

/// Two mean times closer than this, relative, are a tie (the certified
/// error of a counted Parallel's mean times is below 1e-9).
pub const TIE_RELATIVE: f64 = 1e-9;
/// Two probabilities closer than this are a tie.
pub const TIE_ABSOLUTE: f64 = 1e-11;

/// The enumeration budget that decided the search.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Budget {
    /// Largest number of orderings enumerated exhaustively.
    pub limit: usize,
    /// Whether the limit was given (`max_candidates`) rather than derived
    /// from the estimated work.
    pub explicit: bool,
    /// Measured time of one evaluation (s, one thread).
    pub seconds_per_candidate: f64,
    /// Worker threads of the exhaustive enumeration.
    pub threads: usize,
}

impl Budget {
    /// Estimated wall time (s) of enumerating `n` orderings.
    pub fn estimate(&self, n: f64) -> f64 {
        n * self.seconds_per_candidate / self.threads.max(1) as f64
    }
}

/// A ranked comparison.
#[derive(Debug, Clone, PartialEq)]
pub struct Comparison {
    /// The objective used.
    pub objective: Objective,
    /// The deadline, if any.
    pub deadline: Option<f64>,
    /// The method used.
    pub method: Method,
    /// The nodes whose children were permuted.
    pub nodes: Vec<NodeId>,
    /// How candidates were found.
    pub search: Search,
    /// Whether the best candidate is proven optimal over all orderings.
    pub proven_optimal: bool,
    /// Number of orderings in the full space (may be huge).
    pub space: f64,
    /// Number of orderings evaluated.
    pub evaluated: u64,
    /// The budget that chose the search.
    pub budget: Budget,
    /// Candidates, best first, at most `keep` of them plus the given
    /// ordering; ties keep enumeration order (the given ordering first).
    pub candidates: Vec<Candidate>,
    /// Remarks (e.g. Parallel nodes skipped, why the search was chosen).
    pub notes: Vec<String>,
    /// The index in `notes` of the one saying that the orderings exceed the
    /// budget's limit (then not enumerated): a front end may restate it in
    /// terms of its own option for the limit.
    pub over_budget: Option<usize>,
}

impl Comparison {
    /// `tree` (the compared tree) with the children of each compared
    /// Fallback, and of its copies, in `candidate`'s order: the tree a
    /// candidate stands for.
    pub fn reordered(&self, tree: &Tree, candidate: &Candidate) -> Tree {
        let copies = Copies::of(tree);
        let mut t = tree.clone();
        for (&node, order) in self.nodes.iter().zip(&candidate.orders) {
            for (copy, o) in copies.orders(node, order) {
                t.set_fallback_order(copy, &o);
            }
        }
        t
    }
}

/// Errors of a comparison.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CompareError {
    /// A node that cannot be reordered.
    #[error(
        "node '{0}' is a {1}: only the children of Fallback nodes can be reordered (Def. 9.10)"
    )]
    NotReorderable(String, &'static str),
    /// success-by needs a deadline.
    #[error("the success-by objective needs a deadline")]
    NeedsDeadline,
    /// A node may never return: orderings are not compared.
    #[error(
        "node '{0}' may never return (a loop whose child cannot end it): orderings are compared \
         by figures of runs that return, which do not cover this tree"
    )]
    NeverReturns(String),
    /// An analysis failed.
    #[error(transparent)]
    Analysis(#[from] AnalysisError),
    /// The model refused a query (other than by its analysis).
    #[error(transparent)]
    Model(crate::model::Error),
}

impl From<crate::model::Error> for CompareError {
    fn from(e: crate::model::Error) -> CompareError {
        match e {
            crate::model::Error::Analysis(a) => CompareError::Analysis(a),
            e => CompareError::Model(e),
        }
    }
}

/// The value minimised (success-by is negated).
pub(crate) fn objective_value(objective: Objective, c: &Candidate) -> f64 {
    match objective {
        Objective::MeanTime => c.root.mean_time(),
        Objective::Mtts => c.root.mtts.unwrap_or(f64::INFINITY),
        Objective::Mttf => c.root.mttf.unwrap_or(f64::INFINITY),
        Objective::SuccessBy => -c.success_by_deadline.unwrap_or(0.0),
    }
}

/// Whether two objective values are a tie.
fn ties(objective: Objective, a: f64, b: f64) -> bool {
    if a == b {
        return true;
    }
    match objective {
        Objective::SuccessBy => (a - b).abs() <= TIE_ABSOLUTE,
        _ => (a - b).abs() <= TIE_RELATIVE * a.abs().max(b.abs()),
    }
}

/// All permutations of `0..k` in lexicographic order (identity first).
fn permutations(k: usize) -> Vec<Vec<usize>> {
    let mut p: Vec<usize> = (0..k).collect();
    let mut out = vec![p.clone()];
    loop {
        let Some(i) = (1..k).rev().find(|&i| p[i - 1] < p[i]) else {
            return out;
        };
        let j = (i..k).rev().find(|&j| p[j] > p[i - 1]).expect("exists");
        p.swap(i - 1, j);
        p[i..].reverse();
        out.push(p.clone());
    }
}

/// The copies of one source Fallback in the tree: a RecoveryNode's
/// retries (the XML front end unrolls them) and the uses of one SubTree
/// copy its nodes, which keep the source element's location. An ordering
/// is of the source element: every copy takes it.
struct Copies {
    /// Each copy's original (the first in pre-order), by node.
    original: HashMap<NodeId, NodeId>,
    /// Each original's copies, itself first.
    copies: HashMap<NodeId, Vec<NodeId>>,
    /// The given children of every Fallback.
    given: HashMap<NodeId, Vec<NodeId>>,
    /// Fallbacks that the front end made (a RecoveryNode's unrolled
    /// attempts: a child shares their location).
    unrolled: Vec<bool>,
}

impl Copies {
    fn of(tree: &Tree) -> Copies {
        let mut out = Copies {
            original: HashMap::new(),
            copies: HashMap::new(),
            given: HashMap::new(),
            unrolled: vec![false; tree.nodes.len()],
        };
        // (location, children's locations) of a source Fallback
        let mut seen: HashMap<SourceKey, NodeId> = HashMap::new();
        for (id, node) in tree.nodes.iter().enumerate() {
            let NodeKind::Fallback { children } = &node.kind else {
                continue;
            };
            out.given.insert(id, children.clone());
            let locations: Vec<_> = children.iter().map(|&c| tree.node(c).location).collect();
            out.unrolled[id] = node.location.is_some() && locations.contains(&node.location);
            let original = match node.location {
                Some(at) => *seen.entry((at, locations)).or_insert(id),
                None => id,
            };
            out.original.insert(id, original);
            out.copies.entry(original).or_default().push(id);
        }
        out
    }

    fn original(&self, id: NodeId) -> NodeId {
        self.original.get(&id).copied().unwrap_or(id)
    }

    fn unrolled(&self, id: NodeId) -> bool {
        self.unrolled[id]
    }

    /// `order` of original `node`'s children, for it and each copy (the
    /// copy's children at the same given positions).
    fn orders(&self, node: NodeId, order: &[NodeId]) -> Vec<(NodeId, Vec<NodeId>)> {
        let Some(given) = self.given.get(&node) else {
            return vec![(node, order.to_vec())];
        };
        let positions: Vec<usize> = order
            .iter()
            .map(|c| given.iter().position(|g| g == c).unwrap_or(0))
            .collect();
        self.copies
            .get(&node)
            .map_or(&[node][..], Vec::as_slice)
            .iter()
            .filter_map(|&copy| {
                let kids = self.given.get(&copy)?;
                Some((copy, positions.iter().map(|&p| kids[p]).collect()))
            })
            .collect()
    }
}

/// A source Fallback: its location and its children's.
type SourceKey = ((usize, usize), Vec<Option<(usize, usize)>>);

/// The model of the compared tree under the ordering being evaluated.
struct Evaluator<'a> {
    model: Model,
    options: &'a CompareOptions,
    copies: &'a Copies,
}

impl Evaluator<'_> {
    /// Puts the children of `node` (an original) and of its copies in
    /// `order`.
    fn set_order(&mut self, node: NodeId, order: &[NodeId]) -> Result<(), CompareError> {
        let orders = self.copies.orders(node, order);
        let changes: Vec<(NodeId, &[NodeId])> =
            orders.iter().map(|(n, o)| (*n, o.as_slice())).collect();
        Ok(self.model.reorder(&changes)?)
    }

    fn children(&self, node: NodeId) -> Vec<NodeId> {
        self.model.tree().node(node).kind.children().to_vec()
    }

    fn evaluate(&self, nodes: &[NodeId], given: bool) -> Result<Candidate, CompareError> {
        let root = self.model.figures(Tree::ROOT)?;
        let success_by_deadline = match self.options.deadline {
            Some(d) => Some(self.model.curve(Tree::ROOT, &[d])?[0].success),
            None => None,
        };
        Ok(Candidate {
            orders: nodes.iter().map(|&n| self.children(n)).collect(),
            root,
            success_by_deadline,
            given,
            rank: 0,
            tied: false,
        })
    }
}

/// The exhaustive enumeration: orderings numbered in mixed radix (the last
/// node fastest, identity first), evaluated in parallel chunks, each chunk
/// keeping its best `keep`.
struct Space {
    perms: Vec<Vec<Vec<usize>>>,
    originals: Vec<Vec<NodeId>>,
}

impl Space {
    fn digits(&self, mut index: u64) -> Vec<usize> {
        let mut d = vec![0; self.perms.len()];
        for h in (0..self.perms.len()).rev() {
            let r = self.perms[h].len() as u64;
            d[h] = (index % r) as usize;
            index /= r;
        }
        d
    }

    fn order(&self, h: usize, digit: usize) -> Vec<NodeId> {
        self.perms[h][digit]
            .iter()
            .map(|&i| self.originals[h][i])
            .collect()
    }
}

type Scored = (f64, u64, Candidate);
/// A chunk's kept candidates, the given ordering if the chunk had it, and
/// how many of its candidates are better than / tied with the given one.
type Chunk = (Vec<Scored>, Option<Scored>, u64, u64);

fn prune(objective: Objective, kept: &mut Vec<Scored>, keep: usize) {
    kept.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
    // keep the tie group straddling the cut, so ranks stay right
    let mut cut = keep.min(kept.len());
    while cut > 0 && cut < kept.len() && ties(objective, kept[cut - 1].0, kept[cut].0) {
        cut += 1;
    }
    kept.truncate(cut);
}

/// What a worker thread makes its own model from: the compared tree and
/// the figures of the given ordering's model (a model stays on its thread).
struct Seed<'a> {
    tree: &'a Tree,
    model_options: compile::Options,
    known: Vec<Option<Figures>>,
    options: &'a CompareOptions,
    copies: &'a Copies,
}

impl Seed<'_> {
    fn evaluator(&self) -> Result<Evaluator<'_>, CompareError> {
        Ok(Evaluator {
            model: Model::with_known(self.tree, self.model_options, &self.known)?,
            options: self.options,
            copies: self.copies,
        })
    }
}

#[allow(clippy::too_many_arguments)]
fn exhaustive(
    seed: &Seed,
    nodes: &[NodeId],
    space: &Space,
    total: u64,
    objective: Objective,
    keep: usize,
    given_value: f64,
    progress: &(dyn Fn(u64, u64) + Sync),
) -> Result<Chunk, CompareError> {
    let threads = rayon::current_num_threads().max(1) as u64;
    let chunks = (threads * 8).min(total).max(1);
    let done = AtomicU64::new(0);
    let parts: Vec<Result<Chunk, CompareError>> = (0..chunks)
        .into_par_iter()
        .map(|k| {
            let (lo, hi) = (total * k / chunks, total * (k + 1) / chunks);
            let mut ev = seed.evaluator()?;
            let mut kept: Vec<Scored> = Vec::new();
            let mut given = None;
            let (mut better, mut tied) = (0u64, 0u64);
            let mut digits = space.digits(lo);
            for (h, &d) in digits.iter().enumerate() {
                let o = space.order(h, d);
                ev.set_order(nodes[h], &o)?;
            }
            let mut since = 0u64;
            for index in lo..hi {
                if index > lo {
                    // odometer step
                    let mut h = nodes.len();
                    while h > 0 {
                        h -= 1;
                        digits[h] += 1;
                        let wrapped = digits[h] == space.perms[h].len();
                        if wrapped {
                            digits[h] = 0;
                        }
                        let o = space.order(h, digits[h]);
                        ev.set_order(nodes[h], &o)?;
                        if !wrapped {
                            break;
                        }
                    }
                }
                let c = ev.evaluate(nodes, index == 0)?;
                let v = objective_value(objective, &c);
                if index == 0 {
                    given = Some((v, index, c.clone()));
                } else if ties(objective, v, given_value) {
                    tied += 1;
                } else if v < given_value {
                    better += 1;
                }
                kept.push((v, index, c));
                if kept.len() >= 2 * keep.max(16) {
                    prune(objective, &mut kept, keep);
                }
                since += 1;
                if since == 64 || index + 1 == hi {
                    let d = done.fetch_add(since, Ordering::Relaxed) + since;
                    progress(d, total);
                    since = 0;
                }
            }
            prune(objective, &mut kept, keep);
            Ok((kept, given, better, tied))
        })
        .collect();
    let mut all = Vec::new();
    let mut given = None;
    let (mut better, mut tied) = (0, 0);
    for p in parts {
        let (kept, g, b, t) = p?;
        all.extend(kept);
        given = given.or(g);
        better += b;
        tied += t;
    }
    prune(objective, &mut all, keep);
    Ok((all, given, better, tied))
}

/// Compares the orderings of the chosen Fallback nodes' children.
pub fn compare(tree: &Tree, options: &CompareOptions) -> Result<Comparison, CompareError> {
    compare_with_progress(tree, options, &|_, _| {})
}

/// [`compare`], calling `progress(done, total)` now and then during an
/// exhaustive enumeration (from worker threads).
pub fn compare_with_progress(
    tree: &Tree,
    options: &CompareOptions,
    progress: &(dyn Fn(u64, u64) + Sync),
) -> Result<Comparison, CompareError> {
    let objective = match (options.objective, options.deadline) {
        (Some(Objective::SuccessBy), None) => return Err(CompareError::NeedsDeadline),
        (Some(o), _) => o,
        (None, Some(_)) => Objective::SuccessBy,
        (None, None) => Objective::MeanTime,
    };
    let mut notes = Vec::new();
    let mut over_budget = None;
    let mut nodes = Vec::new();
    let requested: Vec<NodeId> = if options.nodes.is_empty() {
        (0..tree.nodes.len())
            .filter(|&i| matches!(tree.node(i).kind, NodeKind::Fallback { .. }))
            .collect()
    } else {
        options.nodes.clone()
    };
    let copies = Copies::of(tree);
    for id in requested {
        let node = tree.node(id);
        match &node.kind {
            NodeKind::Fallback { .. } if copies.unrolled(id) => {
                if !options.nodes.is_empty() {
                    return Err(CompareError::NotReorderable(
                        node.name.clone(),
                        "unrolled RecoveryNode",
                    ));
                }
            }
            NodeKind::Fallback { children } if children.len() >= 2 => {
                nodes.push(copies.original(id))
            }
            NodeKind::Fallback { .. } => notes.push(format!(
                "'{}' has a single child: nothing to reorder",
                node.name
            )),
            NodeKind::Parallel { .. } => notes.push(format!(
                "'{}' is a Parallel: its children start together and are independent, so \
                 reordering them changes nothing in this model",
                node.name
            )),
            other => {
                return Err(CompareError::NotReorderable(
                    node.name.clone(),
                    other.keyword(),
                ))
            }
        }
    }
    nodes.sort_unstable();
    nodes.dedup();
    let model = Model::with_options(
        tree,
        compile::Options {
            method: options.method,
            max_states: options.max_states,
        },
    )?;
    // the objectives and ties assume runs that return: a node that may run
    // for ever (a loop its child cannot end) makes the root's figures depend
    // on the ordering in a way they do not compare; named bottom-up (the
    // last such node in pre-order, e.g. the loop rather than its ancestors)
    if let Some((id, _)) = model
        .all_figures()?
        .iter()
        .enumerate()
        .rev()
        .find(|(_, f)| f.never() > 1e-12)
    {
        return Err(CompareError::NeverReturns(tree.node(id).name.clone()));
    }
    let mut ev = Evaluator {
        model,
        options,
        copies: &copies,
    };
    let threads = rayon::current_num_threads().max(1);
    let mut given = ev.evaluate(&nodes, true)?;
    given.rank = 1;
    if nodes.is_empty() {
        if options.nodes.is_empty() {
            notes.push(
                "the tree has no Fallback with two or more children: there is nothing to \
                 reorder, so the given ordering is the only one"
                    .into(),
            );
        } else {
            notes.push(
                "the chosen nodes have nothing to reorder: the given ordering is the only one"
                    .into(),
            );
        }
        return Ok(Comparison {
            objective,
            deadline: options.deadline,
            method: options.method,
            nodes,
            search: Search::NothingToReorder,
            proven_optimal: true,
            space: 1.0,
            evaluated: 1,
            budget: Budget {
                limit: options.max_candidates.unwrap_or(DEFAULT_MAX_CANDIDATES),
                explicit: options.max_candidates.is_some(),
                seconds_per_candidate: 0.0,
                threads,
            },
            candidates: vec![given],
            notes,
            over_budget: None,
        });
    }
    let sizes: Vec<usize> = nodes
        .iter()
        .map(|&n| tree.node(n).kind.children().len())
        .collect();
    let space: f64 = sizes
        .iter()
        .map(|&k| (1..=k).map(|x| x as f64).product::<f64>())
        .product();
    // below a count of independent children (a Parallel, a Timeout, a
    // pipeline's re-planning race), in the core IR
    let under_parallel = nodes.iter().any(|&n| {
        let graph = ev.model.planned_graph();
        let mut p = graph.node(ev.model.planned_node(n)).parent;
        while let Some(id) = p {
            if matches!(graph.node(id).kind, Op::KOfN { .. }) {
                return true;
            }
            p = graph.node(id).parent;
        }
        false
    });

    // cost of one candidate: re-analyse the last node and its ancestors
    // (what most odometer steps do), median of three
    let last = *nodes.last().expect("nodes");
    let mut times = Vec::new();
    for _ in 0..3 {
        let start = Instant::now();
        ev.set_order(last, &ev.children(last))?;
        ev.evaluate(&nodes, false)?;
        times.push(start.elapsed().as_secs_f64());
    }
    times.sort_by(f64::total_cmp);
    let per = times[1].max(1e-9);
    let budget = Budget {
        limit: options.max_candidates.unwrap_or_else(|| {
            ((WORK_BUDGET_SECONDS * threads as f64 / per) as usize).min(DEFAULT_MAX_CANDIDATES)
        }),
        explicit: options.max_candidates.is_some(),
        seconds_per_candidate: per,
        threads,
    };
    let keep = options.keep.max(1);

    let mut given_rank: Option<(u64, bool)> = None;
    let (search, proven_optimal, evaluated, mut scored) = if space <= budget.limit as f64 {
        let sp = Space {
            perms: sizes.iter().map(|&k| permutations(k)).collect(),
            originals: nodes.iter().map(|&n| ev.children(n)).collect(),
        };
        let total = space as u64;
        let given_value = objective_value(objective, &given);
        let seed = Seed {
            tree,
            model_options: compile::Options {
                method: options.method,
                max_states: options.max_states,
            },
            known: ev.model.known_planned_figures(),
            options,
            copies: &copies,
        };
        let (kept, g, better, tied) = exhaustive(
            &seed,
            &nodes,
            &sp,
            total,
            objective,
            keep,
            given_value,
            progress,
        )?;
        if let Some(g) = g {
            given = g.2;
        }
        given_rank = Some((better + 1, tied > 0));
        (Search::Exhaustive, true, total, kept)
    } else {
        let (reason, advice) = if budget.explicit {
            (
                format!(
                    "the given limit of {} orderings",
                    count_text(budget.limit as f64)
                ),
                String::new(),
            )
        } else {
            (
                format!(
                    "the default budget ({} s of estimated work, at most {} orderings)",
                    WORK_BUDGET_SECONDS,
                    count_text(DEFAULT_MAX_CANDIDATES as f64)
                ),
                format!(
                    "; enumerating all would take about {}",
                    duration_text(budget.estimate(space))
                ),
            )
        };
        over_budget = Some(notes.len());
        notes.push(format!(
            "{} orderings exceed {reason}{advice}",
            count_text(space)
        ));
        let mut evaluated = 1u64;
        // ordering rule, bottom-up (children have larger ids)
        for &n in nodes.iter().rev() {
            let ratio = |f: Figures| {
                let e = f.mean_time();
                if e > 0.0 {
                    f.ps / e
                } else if f.ps > 0.0 {
                    f64::INFINITY
                } else {
                    0.0
                }
            };
            let mut kids = ev
                .children(n)
                .into_iter()
                .map(|c| Ok((c, ratio(ev.model.figures(c)?))))
                .collect::<Result<Vec<(NodeId, f64)>, CompareError>>()?;
            kids.sort_by(|a, b| b.1.total_cmp(&a.1));
            let kids: Vec<NodeId> = kids.into_iter().map(|k| k.0).collect();
            ev.set_order(n, &kids)?;
        }
        let mut best = ev.evaluate(&nodes, false)?;
        evaluated += 1;
        let mut candidates = vec![given.clone()];
        if objective == Objective::MeanTime && !under_parallel {
            candidates.push(best);
            let scored = candidates
                .into_iter()
                .enumerate()
                .map(|(i, c)| (objective_value(objective, &c), i as u64, c))
                .collect();
            (Search::OrderingRule, true, evaluated, scored)
        } else {
            if objective == Objective::MeanTime {
                notes.push(
                    "the ordering rule is proven for Sequence/Fallback trees only; under a \
                     Parallel a local search refines it"
                        .into(),
                );
            }
            // best-improvement swaps, within the budget of evaluations
            let max_evaluations = (budget.limit as u64).max(64);
            let mut improved = true;
            let mut stopped = false;
            while improved {
                improved = false;
                let mut best_swap: Option<(NodeId, Vec<NodeId>, Candidate)> = None;
                'nodes: for (k, &n) in nodes.iter().enumerate() {
                    let base = best.orders[k].clone();
                    for i in 0..base.len() {
                        for j in i + 1..base.len() {
                            if evaluated >= max_evaluations {
                                stopped = true;
                                ev.set_order(n, &base)?;
                                break 'nodes;
                            }
                            let mut o = base.clone();
                            o.swap(i, j);
                            ev.set_order(n, &o)?;
                            let c = ev.evaluate(&nodes, false)?;
                            evaluated += 1;
                            let target = best_swap.as_ref().map_or(&best, |b| &b.2);
                            let (cv, tv) = (
                                objective_value(objective, &c),
                                objective_value(objective, target),
                            );
                            if cv < tv && !ties(objective, cv, tv) {
                                best_swap = Some((n, o, c));
                            }
                        }
                    }
                    ev.set_order(n, &base)?;
                }
                if let Some((n, o, c)) = best_swap {
                    ev.set_order(n, &o)?;
                    candidates.push(best.clone());
                    best = c;
                    improved = !stopped;
                }
            }
            if stopped {
                notes.push(format!(
                    "the local search stopped after {evaluated} evaluations (the budget)"
                ));
            }
            candidates.push(best);
            let scored = candidates
                .into_iter()
                .enumerate()
                .map(|(i, c)| (objective_value(objective, &c), i as u64, c))
                .collect();
            (Search::LocalSearch, false, evaluated, scored)
        }
    };
    // the same ordering may have been found twice (e.g. rule == given)
    let given_orders = given.orders.clone();
    scored.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
    let mut seen = std::collections::HashSet::new();
    scored.retain(|s| seen.insert(s.2.orders.clone()));
    // tie groups: within one, enumeration order (the given ordering first)
    let mut candidates: Vec<Candidate> = Vec::with_capacity(scored.len());
    let mut start = 0;
    while start < scored.len() {
        let mut end = start + 1;
        while end < scored.len() && ties(objective, scored[start].0, scored[end].0) {
            end += 1;
        }
        let mut group: Vec<Scored> = scored[start..end].to_vec();
        group.sort_by_key(|s| s.1);
        let tied = group.len() > 1;
        for (_, _, mut c) in group {
            c.rank = start as u64 + 1;
            c.tied = tied;
            c.given = c.orders == given_orders;
            candidates.push(c);
        }
        start = end;
    }
    if !candidates.iter().any(|c| c.given) {
        // exhaustive with the given ordering beyond the kept ones: its rank
        // was counted during the enumeration
        let (rank, tied) = given_rank.unwrap_or((scored.len() as u64 + 1, false));
        given.rank = rank;
        given.tied = tied;
        given.given = true;
        candidates.push(given);
    }
    let mut i = 0;
    candidates.retain(|c| {
        i += 1;
        i <= keep || c.given
    });
    Ok(Comparison {
        objective,
        deadline: options.deadline,
        method: options.method,
        nodes,
        search,
        proven_optimal,
        space,
        evaluated,
        budget,
        candidates,
        notes,
        over_budget,
    })
}

/// `65,536`, or `2.1e+13` beyond a trillion.
pub fn count_text(n: f64) -> String {
    if n < 1e12 {
        let s = format!("{}", n as u64);
        let mut out = String::new();
        for (i, ch) in s.chars().enumerate() {
            if i > 0 && (s.len() - i) % 3 == 0 {
                out.push(',');
            }
            out.push(ch);
        }
        out
    } else {
        format!("{n:.2e}")
    }
}

/// `3 s`, `19 min`, `5.2 h`, `40 days`.
pub fn duration_text(s: f64) -> String {
    if s < 90.0 {
        format!("{} s", (s.max(0.1) * 10.0).round() / 10.0)
    } else if s < 5400.0 {
        format!("{} min", (s / 60.0).round())
    } else if s < 2.0 * 86400.0 {
        format!("{:.1} h", s / 3600.0)
    } else if s < 1e4 * 86400.0 * 365.0 {
        format!("{:.0} days", s / 86400.0)
    } else {
        format!("{:.1e} years", s / (86400.0 * 365.0))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn permutations_are_complete_and_start_with_identity() {
        let p = permutations(4);
        assert_eq!(p.len(), 24);
        assert_eq!(p[0], vec![0, 1, 2, 3]);
        let mut sorted = p.clone();
        sorted.sort();
        sorted.dedup();
        assert_eq!(sorted.len(), 24);
    }
}
