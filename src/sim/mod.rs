//! Monte Carlo simulation of a Stochastic Behavior Tree: the independent
//! referee for the analytic engine.
//!
//! The simulator plays the real tick semantics of the tree in continuous time
//! (*Behavior Trees in Robotics and AI*, §1.3 and ch. 9) and shares nothing
//! with [`compile`](crate::compile) and [`solve`](crate::solve) but the parsed
//! [`Tree`]:
//!
//! * an **action** draws its outcome (Success with probability `ps`), then a
//!   duration from that outcome's [`Duration`](crate::tree::Duration):
//!   `Exp(rate)`, a fixed time, or `min(Exp(rate), cap)`;
//! * a **condition** takes no time and succeeds with probability `ps`;
//! * a **Sequence** runs its children in order and fails at the first
//!   Failure; a **Fallback** succeeds at the first Success;
//! * a **Parallel** node with threshold M over N children starts them all at
//!   once; it succeeds the moment the M-th child succeeds and fails the moment
//!   the (N−M+1)-th child fails, halting the others.
//!
//! Every node is run once per execution of its parent, and a node's duration
//! is the time from its start to its outcome.
//!
//! # What is estimated
//!
//! * **Per node** ([`SimOptions::per_node`]): [`SimOptions::runs`] runs of
//!   every node's subtree as if it were the root, giving `ps`, `pf`
//!   (binomial), MTTS and MTTF (means of the durations of the successful and
//!   of the failed runs), comparable with the analytic per-node report. Most
//!   of them come from the root's own episodes (below).
//! * **Curve** ([`SimOptions::times`]): for the simulated root, the
//!   probabilities of having returned Success, Failure, or neither by each
//!   time point.
//!
//! # Reproducibility
//!
//! The same seed gives a bit-identical [`SimResult`] whatever the number of
//! threads. Runs are cut into fixed chunks of [`CHUNK_RUNS`]; chunk `k` draws
//! from a xoshiro256++ generator seeded with
//! [`seed_from_u64`](rand::SeedableRng::seed_from_u64)`(seed)` and then
//! [`jump`](rand_xoshiro::Xoshiro256PlusPlus::jump)ed `k` times (2^128 draws
//! apart, so streams never overlap). Within a chunk the root's runs come
//! first, then each other node's own runs in tree order (below), so the
//! root's figures are also the same with and without `per_node`. Chunks run
//! in parallel, and their sums are merged strictly in chunk order.
//!
//! Memory is O(threads × (nodes + time points)), independent of the number
//! of runs: only counts and sums are kept, never samples.
//!
//! # One episode for all nodes
//!
//! With `per_node`, each episode of the root also records, for every node
//! it runs, that node's **first run in the episode** (its outcome and
//! duration; a run that never returns too). That run is a run of the node
//! on its own: whether an episode reaches a node is decided before the
//! node starts (by the draws of the nodes run before it), the node's run
//! then uses fresh draws of its own, and the engine runs a halted node to
//! its end (a Parallel's losers, a PipelineSequence's children), so its
//! outcome and duration are those it would have alone. In each chunk, a
//! node reached in `v` of the chunk's `n` root episodes gets `n − v` more
//! runs of its own subtree (drawn after the root's episodes, in tree
//! order): exactly `n` independent runs, as if it had been simulated on its
//! own. Only the first run counts: later runs in the same episode (a
//! retry, a re-plan) are independent too, but how many there are depends on
//! the earlier runs' outcomes, which would weight the sample.
//!
//! This holds for a node whose subtree has **no state across runs**. A
//! RoundRobin's or SequenceWithMemory's index carries over from one run to
//! the next within an episode (the copies a RecoveryNode makes share it), so
//! a node with one in its subtree may start a run at an index other than
//! 0, which a run on its own never does: such nodes (and their ancestors)
//! are run on their own `runs` times, as before. For a tree of Sequences,
//! Fallbacks, Parallels and decorators, simulating every node costs about
//! as much as the root alone plus the nodes the root seldom reaches.
//!
//! ```
//! let tree = btrel::tree::parse_str(
//!     "tree:\n  fallback:\n    children:\n      - action: {ps: 0.5, mu: 1.0, nu: 2.0}\n      - action: {ps: 0.5, mu: 1.0, nu: 2.0}\n",
//!     "example.yaml",
//! ).unwrap();
//! let opts = btrel::sim::SimOptions { runs: 100_000, times: vec![1.0], ..Default::default() };
//! let result = btrel::sim::simulate(&tree, &opts, None).unwrap();
//! let root = &result.nodes[0];
//! // ps = 1 − 0.5 · 0.5 = 0.75
//! assert!((root.ps.mean - 0.75).abs() < 5.0 * root.ps.se);
//! // MTTF = 1/nu + 1/nu = 1
//! let mttf = root.mttf.unwrap();
//! assert!((mttf.mean - 1.0).abs() < 5.0 * mttf.se);
//! ```
//!
//! Size: one concern, the simulator's public entry (options, results, the
//! chunked seeded runs and their merge); about 210 lines are comments and
//! the crate example, 75 tests. The episode engine is `engine.rs`.

mod engine;
pub mod sequential;
mod stats;

use rand::SeedableRng;
use rand_xoshiro::Xoshiro256PlusPlus;
use rayon::prelude::*;
use serde::Serialize;

use crate::tree::{NodeId, Tree};
use engine::{Program, Scratch};
use stats::{proportion, Moments, Raw};

/// Seed used when none is given: `0x5EED_B7E1` ("seed btrel"). Any `u64`
/// works; results are reproducible for a given seed.
pub const DEFAULT_SEED: u64 = 0x5EED_B7E1;

/// Runs per chunk: the unit of random streams, parallel work, progress
/// reports and merging. Fixed, so results do not depend on the thread count.
pub const CHUNK_RUNS: u64 = 1 << 16;

/// Largest accepted [`SimOptions::runs`] (10^12; hours of work for even a
/// small tree).
pub const MAX_RUNS: u64 = 1_000_000_000_000;

/// The normal quantile of the 95 % confidence intervals.
pub(crate) const Z95: f64 = 1.96;

/// Subtrees deeper than this are compiled and run on a dedicated thread pool
/// with large stacks (compiling and episodes recurse once per level).
const DEEP_TREE: usize = 1_000;

/// What to simulate.
#[derive(Debug, Clone, PartialEq)]
pub struct SimOptions {
    /// Independent episodes of the root, and of every node with `per_node`
    /// (1 ..= [`MAX_RUNS`]). Default 1,000,000.
    pub runs: u64,
    /// Seed of the random streams. Default [`DEFAULT_SEED`].
    pub seed: u64,
    /// Worker threads; 0 uses rayon's global pool (one per core). Does not
    /// change the result.
    pub threads: usize,
    /// Time points of the root curve, in any order, each finite and ≥ 0.
    /// Default none.
    pub times: Vec<f64>,
    /// Also simulate every other node's subtree on its own. Default `true`.
    pub per_node: bool,
}

impl Default for SimOptions {
    fn default() -> Self {
        SimOptions {
            runs: 1_000_000,
            seed: DEFAULT_SEED,
            threads: 0,
            times: Vec::new(),
            per_node: true,
        }
    }
}

/// A Monte Carlo estimate.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Estimate {
    /// Sample mean (a proportion for probabilities).
    pub mean: f64,
    /// Standard error of the mean: `√(p(1−p)/n)` for a proportion, `s/√n`
    /// for a mean duration (`s` the sample standard deviation; infinite
    /// when only one run contributed).
    pub se: f64,
    /// Wald 95 % confidence interval, `mean ± 1.96·se` (not clamped).
    pub ci95: (f64, f64),
    /// Number of runs that contributed: all runs for a probability, the
    /// successful (failed) runs for MTTS (MTTF).
    pub count: u64,
}

/// Simulated figures of one node, its subtree run on its own.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct NodeEstimate {
    /// The node.
    pub node: NodeId,
    /// Probability of Success.
    pub ps: Estimate,
    /// Probability of Failure.
    pub pf: Estimate,
    /// Probability that the run never returns (`1 − ps − pf`): it reached
    /// a loop whose child can never end it (an endless loop, judged from
    /// which outcomes each node can return at all), directly or through a
    /// node that waits for it (`outcomes`; module docs).
    pub never: Estimate,
    /// Mean Time To Succeed, `E[T | Success]`; `None` if no run succeeded.
    pub mtts: Option<Estimate>,
    /// Mean Time To Fail, `E[T | Failure]`; `None` if no run failed.
    pub mttf: Option<Estimate>,
}

/// The simulated root's state at one time point.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct CurvePoint {
    /// The time.
    pub t: f64,
    /// P(returned Success at a time ≤ t).
    pub success: Estimate,
    /// P(returned Failure at a time ≤ t).
    pub failure: Estimate,
    /// P(still running at t) = 1 − both.
    pub running: Estimate,
}

/// Result of a simulation.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SimResult {
    /// Runs per node.
    pub runs: u64,
    /// The seed used.
    pub seed: u64,
    /// The simulated root first, then (with `per_node`) every other node of
    /// its subtree, in tree order.
    pub nodes: Vec<NodeEstimate>,
    /// The root curve, in the order of [`SimOptions::times`].
    pub curve: Vec<CurvePoint>,
}

/// Invalid simulation options.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SimError {
    /// `runs` is 0.
    #[error("the number of runs must be at least 1")]
    ZeroRuns,
    /// `runs` is over [`MAX_RUNS`].
    #[error("{0} runs is absurd: at most {MAX_RUNS} (10^12) are allowed")]
    AbsurdRuns(u64),
    /// A time point is negative, infinite or NaN.
    #[error("time point #{index} is {value}: time points must be finite and >= 0")]
    BadTime {
        /// Position in [`SimOptions::times`].
        index: usize,
        /// The value given.
        value: f64,
    },
    /// The node to simulate is not in the tree.
    #[error("node {node} does not exist: the tree has {len} nodes")]
    NoSuchNode {
        /// The id given.
        node: NodeId,
        /// Number of nodes in the tree.
        len: usize,
    },
    /// A loop decorator whose child can never end it (e.g. `until_failure`
    /// over a child that always succeeds): an episode would never end.
    #[error("node '{0}' never returns: its child can never end the loop")]
    NeverReturns(String),
    /// The worker thread pool could not be created.
    #[error("cannot create the simulation thread pool: {0}")]
    ThreadPool(String),
}

/// Which outcomes each node of the subtree at `root` can return at all
/// (probability > 0), `(can succeed, can fail)`, indexed by node (other
/// nodes `(false, false)`). A loop (`until_failure` / `until_success`)
/// whose child can never return the outcome that ends it can return
/// neither: it never returns (an *endless* loop).
pub(crate) fn outcomes(tree: &Tree, root: NodeId) -> Vec<(bool, bool)> {
    use crate::tree::{Decorator, NodeKind};
    let range = tree.subtree(root);
    // (can succeed, can fail), filled bottom-up
    let mut can = vec![(false, false); tree.nodes.len()];
    for id in range.rev() {
        let kids = tree.node(id).kind.children();
        can[id] = match &tree.node(id).kind {
            NodeKind::Action(a) => (a.ps > 0.0, a.pf > 0.0),
            NodeKind::Condition { ps } => (*ps > 0.0, *ps < 1.0),
            // a SequenceWithMemory passes a child only after its Success
            NodeKind::Sequence { .. } | NodeKind::SequenceWithMemory { .. } => {
                let all = kids.iter().all(|&c| can[c].0);
                let fail = kids
                    .iter()
                    .scan(true, |ok, &c| {
                        let here = *ok && can[c].1;
                        *ok &= can[c].0;
                        Some(here)
                    })
                    .any(|x| x);
                (all, fail)
            }
            NodeKind::Pipeline { .. } => crate::tree::nav2::outcomes(tree, id),
            // without wrap_around the last child's Success is a Failure
            NodeKind::RoundRobin { wrap: false, .. } => crate::tree::nav2::outcomes(tree, id),
            NodeKind::Fallback { .. } | NodeKind::RoundRobin { .. } => {
                let all = kids.iter().all(|&c| can[c].1);
                let succeed = kids
                    .iter()
                    .scan(true, |ok, &c| {
                        let here = *ok && can[c].0;
                        *ok &= can[c].1;
                        Some(here)
                    })
                    .any(|x| x);
                (succeed, all)
            }
            NodeKind::Parallel {
                success_threshold,
                failure_threshold,
                ..
            } => {
                let s = kids.iter().filter(|&&c| can[c].0).count();
                let f = kids.iter().filter(|&&c| can[c].1).count();
                let f_needed = (*failure_threshold).min(kids.len() + 1 - success_threshold);
                (s >= *success_threshold, f >= f_needed)
            }
            NodeKind::Flow(flow) => {
                use crate::tree::FlowNext;
                // which states, and which outcomes, some run reaches
                let mut reached = vec![false; flow.states.len()];
                reached[0] = true;
                let (mut s, mut f) = (false, false);
                for (i, st) in flow.states.iter().enumerate() {
                    if !reached[i] {
                        continue;
                    }
                    let (cs, cf) = can[flow.children[st.child]];
                    for (possible, next) in [(cs, st.on_success), (cf, st.on_failure)] {
                        match next {
                            _ if !possible => {}
                            FlowNext::State(j) => reached[j] = true,
                            FlowNext::Success => s = true,
                            FlowNext::Failure => f = true,
                        }
                    }
                }
                (s, f)
            }
            NodeKind::Decorator { decorator, child } => {
                let (s, f) = can[*child];
                match decorator {
                    Decorator::Inverter => (f, s),
                    Decorator::ForceSuccess => (true, false),
                    Decorator::ForceFailure => (false, true),
                    Decorator::Retry { .. }
                    | Decorator::Repeat { .. }
                    | Decorator::Rate { .. }
                    | Decorator::SingleTrigger => (s, f),
                    Decorator::UntilFailure if !f => (false, false),
                    Decorator::UntilSuccess if !s => (false, false),
                    Decorator::UntilFailure => (false, true),
                    Decorator::UntilSuccess => (true, false),
                }
            }
        };
    }
    can
}

/// The loops (`until_failure` / `until_success`) of `tree` that never
/// return when they run: their child can never return the outcome that
/// ends them (`outcomes`). Each with a sentence saying why; a loop made
/// for a ReactiveSequence / ReactiveFallback's restarts (named
/// `<node>/restarts`) is described as that restart loop.
pub fn endless_loops(tree: &Tree) -> Vec<(NodeId, String)> {
    use crate::tree::{Decorator, NodeKind};
    let can = outcomes(tree, Tree::ROOT);
    let mut out = Vec::new();
    for (id, node) in tree.nodes.iter().enumerate() {
        let NodeKind::Decorator { decorator, child } = node.kind else {
            continue;
        };
        let until = match decorator {
            Decorator::UntilFailure => "Failure",
            Decorator::UntilSuccess => "Success",
            _ => continue,
        };
        if can[id] != (false, false) {
            continue;
        }
        let child = &tree.node(child).name;
        let parent = node.parent.map(|p| tree.node(p));
        let why = match parent {
            Some(p) if node.name.strip_suffix("/restarts") == Some(p.name.as_str()) => {
                let (ty, other) = if until == "Failure" {
                    ("ReactiveSequence", "Success")
                } else {
                    ("ReactiveFallback", "Failure")
                };
                format!(
                    "the restart loop of {ty} '{}': '{child}' is ticked again from IDLE (a fresh \
                     run) while a later child that takes time runs, which is halted, and \
                     '{child}' never returns {until} (it returns {other} or never returns)",
                    p.name
                )
            }
            _ => format!("it repeats '{child}' until {until}, and '{child}' never returns {until}"),
        };
        out.push((id, format!("node '{}' can run forever: {why}", node.name)));
    }
    out
}

/// Simulates the whole tree: root curve and (with `per_node`) every node.
///
/// `progress`, if given, is called with the number of runs completed so far
/// (per node), at most once per chunk of [`CHUNK_RUNS`], and finally with
/// `opts.runs`.
pub fn simulate(
    tree: &Tree,
    opts: &SimOptions,
    progress: Option<&(dyn Fn(u64) + Sync)>,
) -> Result<SimResult, SimError> {
    simulate_node(tree, Tree::ROOT, opts, progress)
}

/// Simulates the subtree rooted at `node` as if it were the whole tree: its
/// curve and (with `per_node`) the figures of every node of the subtree.
/// `simulate_node(tree, Tree::ROOT, ..)` is [`simulate`].
pub fn simulate_node(
    tree: &Tree,
    node: NodeId,
    opts: &SimOptions,
    progress: Option<&(dyn Fn(u64) + Sync)>,
) -> Result<SimResult, SimError> {
    if opts.runs == 0 {
        return Err(SimError::ZeroRuns);
    }
    if opts.runs > MAX_RUNS {
        return Err(SimError::AbsurdRuns(opts.runs));
    }
    if let Some((index, &value)) = opts
        .times
        .iter()
        .enumerate()
        .find(|(_, t)| !(t.is_finite() && **t >= 0.0))
    {
        return Err(SimError::BadTime { index, value });
    }
    if node >= tree.nodes.len() {
        return Err(SimError::NoSuchNode {
            node,
            len: tree.nodes.len(),
        });
    }

    let targets: Vec<usize> = if opts.per_node {
        tree.subtree(node).collect()
    } else {
        vec![node]
    };
    // Time points sorted ascending; `order[i]` is the position in
    // `opts.times` of the i-th smallest.
    let mut order: Vec<usize> = (0..opts.times.len()).collect();
    order.sort_by(|&a, &b| opts.times[a].total_cmp(&opts.times[b]));
    let sorted: Vec<f64> = order.iter().map(|&i| opts.times[i]).collect();

    // Compiling recurses too, so it runs on the pool as well.
    let run = || {
        // which outcomes each node can return: once for the whole subtree
        let can = std::sync::Arc::new(outcomes(tree, node));
        let programs: Vec<Program> = targets
            .iter()
            .map(|&id| Program::with_outcomes(tree, id, can.clone()))
            .collect();
        // with per_node, the root's episodes also record every node's first
        // run (module docs, "One episode for all nodes")
        let recording = opts
            .per_node
            .then(|| Program::recording(tree, node, can.clone()));
        let reuse: Vec<bool> = targets.iter().map(|&id| stateless(tree, id)).collect();
        let job = Job {
            programs: &programs,
            recording: recording.as_ref(),
            reuse: &reuse,
            root: node,
            targets: &targets,
            sorted: &sorted,
        };
        job.run_all(opts.runs, opts.seed, progress)
    };
    let max_depth = tree.subtree(node).map(|i| tree.nodes[i].depth).max();
    let depth = max_depth.unwrap_or(0) - tree.nodes[node].depth;
    let deep = depth > DEEP_TREE;
    let total = if opts.threads > 0 || deep {
        let mut builder = rayon::ThreadPoolBuilder::new().num_threads(opts.threads);
        if deep {
            builder = builder.stack_size((8 << 20) + depth * 4096);
        }
        let pool = builder
            .build()
            .map_err(|e| SimError::ThreadPool(e.to_string()))?;
        pool.install(run)
    } else {
        run()
    };
    Ok(total.finish(opts, &targets, &order, &sorted))
}

/// Whether the subtree at `id` has no state that outlives a run within an
/// episode (the index of a RoundRobin or SequenceWithMemory, which its copies
/// made by a RecoveryNode share): then each of its runs in an episode is a
/// fresh run, and its first run in an episode of an ancestor is a sample of
/// it run on its own.
fn stateless(tree: &Tree, id: NodeId) -> bool {
    use crate::tree::NodeKind;
    tree.subtree(id).all(|i| {
        !matches!(
            tree.nodes[i].kind,
            NodeKind::RoundRobin { .. } | NodeKind::SequenceWithMemory { .. }
        )
    })
}

/// The fixed inputs of a simulation.
struct Job<'a> {
    /// One per simulated node; the first has the curve.
    programs: &'a [Program],
    /// With `per_node`: the first program, recording.
    recording: Option<&'a Program>,
    /// Per program: whether its node's first run in a root episode stands
    /// for a run on its own ([`stateless`]).
    reuse: &'a [bool],
    /// The tree node of the first program.
    root: NodeId,
    /// The tree node of each program.
    targets: &'a [NodeId],
    /// Curve time points, ascending.
    sorted: &'a [f64],
}

/// Sums of one chunk. Pairs are indexed by outcome: 0 Failure, 1 Success.
struct ChunkSums {
    runs: u64,
    /// Per program: durations of the failed and of the successful runs.
    nodes: Vec<[Raw; 2]>,
    /// Runs of the first program ending at a time in
    /// `(sorted[j-1], sorted[j]]`, for `j` in `0..=sorted.len()`.
    hist: Vec<[u64; 2]>,
}

/// Sums of all chunks so far.
struct Totals {
    runs: u64,
    nodes: Vec<[Moments; 2]>,
    hist: Vec<[u64; 2]>,
}

/// Time points up to this many are searched linearly (branch-free).
const LINEAR_SEARCH: usize = 32;

impl Job<'_> {
    /// Runs every chunk, in batches of a few chunks per thread, merging the
    /// batch's sums in chunk order before starting the next batch.
    fn run_all(&self, runs: u64, seed: u64, progress: Option<&(dyn Fn(u64) + Sync)>) -> Totals {
        let mut totals = Totals {
            runs: 0,
            nodes: vec![Default::default(); self.programs.len()],
            hist: vec![[0; 2]; self.sorted.len() + 1],
        };
        let chunks = runs.div_ceil(CHUNK_RUNS);
        let batch = (4 * rayon::current_num_threads()).max(1) as u64;
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(seed);
        let mut k = 0;
        while k < chunks {
            let jobs: Vec<(Xoshiro256PlusPlus, u64)> = (k..chunks.min(k + batch))
                .map(|c| {
                    let state = rng.clone();
                    rng.jump();
                    (state, CHUNK_RUNS.min(runs - c * CHUNK_RUNS))
                })
                .collect();
            k += jobs.len() as u64;
            let sums: Vec<ChunkSums> = jobs
                .into_par_iter()
                .map(|(mut rng, n)| self.chunk(&mut rng, n))
                .collect();
            for s in &sums {
                totals.merge(s);
            }
            if let Some(p) = progress {
                p(totals.runs);
            }
        }
        totals
    }

    /// Runs `n` episodes of each program in turn, the first with its curve.
    fn chunk(&self, rng: &mut Xoshiro256PlusPlus, n: u64) -> ChunkSums {
        let mut sums = ChunkSums {
            runs: n,
            nodes: vec![Default::default(); self.programs.len()],
            hist: vec![[0; 2]; self.sorted.len() + 1],
        };
        let (first, rest) = self.programs.split_first().expect("at least one node");
        let first = self.recording.unwrap_or(first);
        let mut scratch = first.scratch();
        let recording = self.recording.is_some();
        match (self.sorted.len() <= LINEAR_SEARCH, recording) {
            (true, false) => self.episodes_with_curve::<false>(
                first,
                n,
                rng,
                &mut scratch,
                &mut sums,
                |t, times| times.iter().filter(|&&x| x < t).count(),
            ),
            (false, false) => self.episodes_with_curve::<false>(
                first,
                n,
                rng,
                &mut scratch,
                &mut sums,
                |t, times| times.partition_point(|&x| x < t),
            ),
            (true, true) => self.episodes_with_curve::<true>(
                first,
                n,
                rng,
                &mut scratch,
                &mut sums,
                |t, times| times.iter().filter(|&&x| x < t).count(),
            ),
            (false, true) => self.episodes_with_curve::<true>(
                first,
                n,
                rng,
                &mut scratch,
                &mut sums,
                |t, times| times.partition_point(|&x| x < t),
            ),
        }
        let records = if recording {
            scratch.take_records()
        } else {
            Vec::new()
        };
        for (k, (program, raw)) in rest.iter().zip(&mut sums.nodes[1..]).enumerate() {
            // the node's first runs in the root's episodes, topped up with
            // runs of its own to n
            let mut own = n;
            if self.reuse[k + 1] {
                if let Some(r) = records.get(self.targets[k + 1] - self.root) {
                    *raw = r.raw;
                    own = n - r.visits;
                }
            }
            if own == 0 {
                continue;
            }
            let mut scratch = program.scratch();
            for _ in 0..own {
                let (ok, t) = program.episode(rng, &mut scratch);
                // a run that never returns (t = ∞) counts in neither
                if t.is_finite() {
                    raw[ok as usize].push(t);
                }
            }
        }
        sums
    }

    /// `bin(t, sorted)` is the number of time points before `t`; `REC`:
    /// `program` is recording.
    #[inline(always)]
    fn episodes_with_curve<const REC: bool>(
        &self,
        program: &Program,
        n: u64,
        rng: &mut Xoshiro256PlusPlus,
        scratch: &mut Scratch,
        sums: &mut ChunkSums,
        bin: impl Fn(f64, &[f64]) -> usize,
    ) {
        let raw = &mut sums.nodes[0];
        if let (false, Some(entry)) = (REC, program.root_chain()) {
            // one flat chain: the episodes inlined into this loop, the
            // generator in a local (kept in registers), the same draws
            let mut r = rng.clone();
            for _ in 0..n {
                let (ok, t) = program.run_chain(entry, &mut r);
                if t.is_finite() {
                    raw[ok as usize].push(t);
                    sums.hist[bin(t, self.sorted)][ok as usize] += 1;
                }
            }
            *rng = r;
            return;
        }
        for _ in 0..n {
            let (ok, t) = if REC {
                program.episode_recording(rng, scratch)
            } else {
                program.episode(rng, scratch)
            };
            // a run that never returns (t = ∞) counts in neither: running
            // at every time point
            if t.is_finite() {
                raw[ok as usize].push(t);
                // The run counts at every time point >= t.
                sums.hist[bin(t, self.sorted)][ok as usize] += 1;
            }
        }
    }
}

impl Totals {
    fn merge(&mut self, c: &ChunkSums) {
        self.runs += c.runs;
        for (m, r) in self.nodes.iter_mut().zip(&c.nodes) {
            m[0].merge(&r[0]);
            m[1].merge(&r[1]);
        }
        for (a, b) in self.hist.iter_mut().zip(&c.hist) {
            a[0] += b[0];
            a[1] += b[1];
        }
    }

    fn finish(
        self,
        opts: &SimOptions,
        targets: &[usize],
        order: &[usize],
        sorted: &[f64],
    ) -> SimResult {
        let n = self.runs;
        let nodes = targets
            .iter()
            .zip(&self.nodes)
            .map(|(&node, [f, s])| NodeEstimate {
                node,
                ps: proportion(s.n, n),
                pf: proportion(f.n, n),
                never: proportion(n - s.n - f.n, n),
                mtts: s.estimate(),
                mttf: f.estimate(),
            })
            .collect();
        let mut curve = vec![None; sorted.len()];
        let (mut ks, mut kf) = (0, 0);
        for (i, &t) in sorted.iter().enumerate() {
            kf += self.hist[i][0];
            ks += self.hist[i][1];
            curve[order[i]] = Some(CurvePoint {
                t,
                success: proportion(ks, n),
                failure: proportion(kf, n),
                running: proportion(n - ks - kf, n),
            });
        }
        SimResult {
            runs: n,
            seed: opts.seed,
            nodes,
            curve: curve.into_iter().map(|p| p.expect("every point")).collect(),
        }
    }
}

/// A tree no parser builds (deeper than any parse limit), made in the crate.
#[cfg(test)]
mod deep {
    use super::*;

    /// A chain 5,000 levels deep (beyond any parser limit): compiled and run on
    /// big-stack threads. Level k is a Sequence (k even) or a Fallback (k odd)
    /// of [level k + 1, condition ps .5]; the bottom is an action (.5, 1, 1), so
    /// every run lasts the action's Exp(1) time whatever the outcome.
    #[test]
    fn very_deep_tree() {
        use crate::tree::{Action, Duration, Node, NodeKind};
        const D: usize = 5_000;
        let node = |depth: usize, parent: Option<usize>, kind: NodeKind| Node {
            name: format!("n{depth}"),
            path: String::new(),
            depth,
            parent,
            kind,
            location: None,
        };
        // Pre-order ids: levels 0..D, the action (D), then the conditions from
        // level D−1 up to level 0.
        let cond_id = |k: usize| D + 1 + (D - 1 - k);
        let mut nodes: Vec<Node> = (0..D)
            .map(|k| {
                let children = vec![k + 1, cond_id(k)];
                let kind = if k % 2 == 0 {
                    NodeKind::Sequence { children }
                } else {
                    NodeKind::Fallback { children }
                };
                node(k, k.checked_sub(1), kind)
            })
            .collect();
        let exp1 = Some(Duration::Exponential { rate: 1.0 });
        let leaf = Action {
            ps: 0.5,
            pf: 0.5,
            success: exp1,
            failure: exp1,
        };
        nodes.push(node(D, Some(D - 1), NodeKind::Action(leaf)));
        for k in (0..D).rev() {
            nodes.push(node(k + 1, Some(k), NodeKind::Condition { ps: 0.5 }));
        }
        let t = Tree { title: None, nodes };
        let mut ps = 0.5;
        for k in (0..D).rev() {
            ps = if k % 2 == 0 {
                ps * 0.5
            } else {
                ps + (1.0 - ps) * 0.5
            };
        }
        let opts = SimOptions {
            runs: 4_000,
            per_node: false,
            ..Default::default()
        };
        let r = simulate(&t, &opts, None).unwrap();
        let root = &r.nodes[0];
        let z = |what: &str, est: &Estimate, exact: f64| {
            assert!(
                (est.mean - exact).abs() < 5.0 * est.se,
                "deep {what}: {} ± {} vs {exact}",
                est.mean,
                est.se
            );
        };
        z("ps", &root.ps, ps);
        z("MTTS", root.mtts.as_ref().expect("succeeds"), 1.0);
        z("MTTF", root.mttf.as_ref().expect("fails"), 1.0);
    }
}
