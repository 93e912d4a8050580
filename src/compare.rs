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
//! ([`compile::reanalyze`]). Beyond the limit:
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

use crate::compile::{self, analyze, AnalysisError, Figures, Method};
use crate::curve::{curve, CurveOptions};
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
}

impl Search {
    /// A short description.
    pub fn name(&self) -> &'static str {
        match self {
            Search::Exhaustive => "exhaustive",
            Search::OrderingRule => "ordering rule ps/E[T]",
            Search::LocalSearch => "local search from the ordering rule",
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
    /// Largest number of orderings enumerated exhaustively.
    pub max_candidates: usize,
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
            max_candidates: DEFAULT_MAX_CANDIDATES,
            max_states: compile::DEFAULT_MAX_STATES,
        }
    }
}

/// Default limit of exhaustive enumeration (8! = 40,320 fits).
pub const DEFAULT_MAX_CANDIDATES: usize = 100_000;

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
    /// Candidates, best first; ties keep enumeration order (the given
    /// ordering first).
    pub candidates: Vec<Candidate>,
    /// Remarks (e.g. Parallel nodes skipped).
    pub notes: Vec<String>,
}

/// Errors of a comparison.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CompareError {
    /// A node that cannot be reordered.
    #[error(
        "node '{0}' is a {1}: only the children of Fallback nodes can be reordered (Def. 9.10); \
         give a Fallback with --node, or omit --node to reorder every Fallback"
    )]
    NotReorderable(String, &'static str),
    /// Nothing to compare.
    #[error("the tree has no Fallback node with two or more children to reorder")]
    NothingToCompare,
    /// success-by needs a deadline.
    #[error("--by success-by needs --deadline T")]
    NeedsDeadline,
    /// An analysis failed.
    #[error(transparent)]
    Analysis(#[from] AnalysisError),
}

fn objective_value(objective: Objective, c: &Candidate) -> f64 {
    match objective {
        Objective::MeanTime => c.root.mean_time(),
        Objective::Mtts => c.root.mtts.unwrap_or(f64::INFINITY),
        Objective::Mttf => c.root.mttf.unwrap_or(f64::INFINITY),
        Objective::SuccessBy => -c.success_by_deadline.unwrap_or(0.0),
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

struct Evaluator<'a> {
    tree: Tree,
    analysis: compile::Analysis,
    options: &'a CompareOptions,
    compile_options: compile::Options,
}

impl Evaluator<'_> {
    fn set_order(&mut self, node: NodeId, order: &[NodeId]) {
        if let NodeKind::Fallback { children } = &mut self.tree.nodes[node].kind {
            children.copy_from_slice(order);
        }
    }

    fn children(&self, node: NodeId) -> Vec<NodeId> {
        self.tree.node(node).kind.children().to_vec()
    }

    fn evaluate(
        &mut self,
        changed: &[NodeId],
        nodes: &[NodeId],
        given: bool,
    ) -> Result<Candidate, CompareError> {
        compile::reanalyze(
            &self.tree,
            &mut self.analysis,
            changed,
            &self.compile_options,
        )?;
        let success_by_deadline = match self.options.deadline {
            Some(d) => Some(
                curve(
                    &self.tree,
                    Tree::ROOT,
                    &[d],
                    &CurveOptions {
                        method: self.options.method,
                        max_states: self.options.max_states,
                        ..CurveOptions::default()
                    },
                )?[0]
                    .success,
            ),
            None => None,
        };
        Ok(Candidate {
            orders: nodes.iter().map(|&n| self.children(n)).collect(),
            root: self.analysis.nodes[Tree::ROOT],
            success_by_deadline,
            given,
        })
    }
}

/// Compares the orderings of the chosen Fallback nodes' children.
pub fn compare(tree: &Tree, options: &CompareOptions) -> Result<Comparison, CompareError> {
    let objective = match (options.objective, options.deadline) {
        (Some(Objective::SuccessBy), None) => return Err(CompareError::NeedsDeadline),
        (Some(o), _) => o,
        (None, Some(_)) => Objective::SuccessBy,
        (None, None) => Objective::MeanTime,
    };
    let mut notes = Vec::new();
    let mut nodes = Vec::new();
    let requested: Vec<NodeId> = if options.nodes.is_empty() {
        (0..tree.nodes.len())
            .filter(|&i| matches!(tree.node(i).kind, NodeKind::Fallback { .. }))
            .collect()
    } else {
        options.nodes.clone()
    };
    for id in requested {
        let node = tree.node(id);
        match &node.kind {
            NodeKind::Fallback { children } if children.len() >= 2 => nodes.push(id),
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
    if nodes.is_empty() {
        return Err(CompareError::NothingToCompare);
    }
    let compile_options = compile::Options {
        method: options.method,
        max_states: options.max_states,
    };
    let analysis = analyze(tree, &compile_options)?;
    let mut ev = Evaluator {
        tree: tree.clone(),
        analysis,
        options,
        compile_options,
    };
    let sizes: Vec<usize> = nodes
        .iter()
        .map(|&n| tree.node(n).kind.children().len())
        .collect();
    let space: f64 = sizes
        .iter()
        .map(|&k| (1..=k).map(|x| x as f64).product::<f64>())
        .product();
    let under_parallel = nodes.iter().any(|&n| {
        let mut p = tree.node(n).parent;
        while let Some(id) = p {
            if matches!(tree.node(id).kind, NodeKind::Parallel { .. }) {
                return true;
            }
            p = tree.node(id).parent;
        }
        false
    });

    let (search, proven_optimal, mut candidates) = if space <= options.max_candidates as f64 {
        let perms: Vec<Vec<Vec<usize>>> = sizes.iter().map(|&k| permutations(k)).collect();
        let originals: Vec<Vec<NodeId>> = nodes.iter().map(|&n| ev.children(n)).collect();
        let mut pick = vec![0usize; nodes.len()];
        let mut candidates = Vec::with_capacity(space as usize);
        let mut changed: Vec<NodeId> = Vec::new();
        loop {
            let c = ev.evaluate(&changed, &nodes, candidates.is_empty())?;
            candidates.push(c);
            // odometer: advance the last node fastest
            changed.clear();
            let mut h = nodes.len();
            loop {
                if h == 0 {
                    break;
                }
                h -= 1;
                pick[h] += 1;
                let wrapped = pick[h] == perms[h].len();
                if wrapped {
                    pick[h] = 0;
                }
                let order: Vec<NodeId> =
                    perms[h][pick[h]].iter().map(|&i| originals[h][i]).collect();
                ev.set_order(nodes[h], &order);
                changed.push(nodes[h]);
                if !wrapped {
                    break;
                }
                if h == 0 {
                    changed.clear();
                }
            }
            if changed.is_empty() {
                break;
            }
        }
        (Search::Exhaustive, true, candidates)
    } else {
        let given = ev.evaluate(&[], &nodes, true)?;
        // ordering rule, bottom-up (children have larger ids)
        for &n in nodes.iter().rev() {
            let mut kids = ev.children(n);
            let ratio = |c: NodeId, ev: &Evaluator| {
                let f = ev.analysis.nodes[c];
                let e = f.mean_time();
                if e > 0.0 {
                    f.ps / e
                } else if f.ps > 0.0 {
                    f64::INFINITY
                } else {
                    0.0
                }
            };
            kids.sort_by(|&a, &b| ratio(b, &ev).total_cmp(&ratio(a, &ev)));
            ev.set_order(n, &kids);
            compile::reanalyze(&ev.tree, &mut ev.analysis, &[n], &ev.compile_options)?;
        }
        let mut best = ev.evaluate(&nodes, &nodes, false)?;
        let mut candidates = vec![given];
        if objective == Objective::MeanTime {
            candidates.push(best);
            (Search::OrderingRule, !under_parallel, candidates)
        } else {
            // best-improvement swaps
            let mut improved = true;
            let mut rounds = 0;
            while improved && rounds < 1000 {
                improved = false;
                rounds += 1;
                let mut best_swap: Option<(NodeId, Vec<NodeId>, Candidate)> = None;
                for (k, &n) in nodes.iter().enumerate() {
                    let base = best.orders[k].clone();
                    for i in 0..base.len() {
                        for j in i + 1..base.len() {
                            let mut o = base.clone();
                            o.swap(i, j);
                            ev.set_order(n, &o);
                            let c = ev.evaluate(&[n], &nodes, false)?;
                            let target = best_swap.as_ref().map_or(&best, |b| &b.2);
                            if objective_value(objective, &c)
                                < objective_value(objective, target) - 1e-15
                            {
                                best_swap = Some((n, o, c));
                            }
                        }
                    }
                    ev.set_order(n, &base);
                    compile::reanalyze(&ev.tree, &mut ev.analysis, &[n], &ev.compile_options)?;
                }
                if let Some((n, o, c)) = best_swap {
                    ev.set_order(n, &o);
                    compile::reanalyze(&ev.tree, &mut ev.analysis, &[n], &ev.compile_options)?;
                    candidates.push(best.clone());
                    best = c;
                    improved = true;
                }
            }
            candidates.push(best);
            (Search::LocalSearch, false, candidates)
        }
    };
    let given_orders: Vec<Vec<NodeId>> = nodes
        .iter()
        .map(|&n| tree.node(n).kind.children().to_vec())
        .collect();
    for c in &mut candidates {
        c.given = c.orders == given_orders;
    }
    candidates
        .sort_by(|a, b| objective_value(objective, a).total_cmp(&objective_value(objective, b)));
    // the given ordering may appear twice (e.g. rule == given): keep the first
    let mut seen = std::collections::HashSet::new();
    candidates.retain(|c| seen.insert(c.orders.clone()));
    Ok(Comparison {
        objective,
        deadline: options.deadline,
        method: options.method,
        nodes,
        search,
        proven_optimal,
        space,
        candidates,
        notes,
    })
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
