//! Stopping rules: simulate until every figure is as precise as asked, and
//! sequential tests of a requirement (`P ≥ θ`, `MTTS ≤ d`).
//!
//! # The rules
//!
//! * **Probabilities** (ps, pf, P(never returns), the curve's points) —
//!   the **Okamoto (Chernoff–Hoeffding) bound**, pre-computed: after
//!   `n ≥ ln(2/δ) / (2ε²)` runs, `P(|p̂ − p| ≥ ε) ≤ 2·exp(−2nε²) ≤ δ` for
//!   every `p` (Okamoto 1959), so the interval `p̂ ± ε` has confidence at
//!   least `1 − δ` whatever the tree. The number of runs is known before the
//!   first one; the interval reported is `p̂ ± √(ln(2/δ)/(2n))` at the runs
//!   used.
//! * **Mean times** (MTTS, MTTF: means of the durations of the successful,
//!   of the failed runs) — the **Chow–Robbins** fixed-width rule (Chow &
//!   Robbins 1965): with `m` durations of sample variance `s²`, stop at the
//!   first check with `m ≥ 30` and `z·√((s² + 1/m)/m) ≤ ε`, `z` the normal
//!   quantile `Φ⁻¹(1 − δ/2)`; the interval `x̄ ± z·s/√m` then covers the mean
//!   with probability → `1 − δ` as `ε → 0` for any distribution with a finite
//!   variance (asymptotic, not exact: coverage at a coarse ε is checked by
//!   the tests).
//! * **Requirements on a probability** (`ps >= θ`) — **Wald's sequential
//!   probability ratio test** ([`Sprt`]) of `H0: p ≥ θ + δ` (holds) against
//!   `H1: p ≤ θ − δ` (fails), `δ` the half-width of the indifference region:
//!   with the thresholds `A = (1−β)/α`, `B = β/(1−α)` the probability of
//!   declaring a requirement failed that holds with margin is at most
//!   `α/(1−β)`, of passing one that fails by `δ` at most `β/(1−α)` (Wald's
//!   inequalities; they hold for any stopping time, so also for the checks
//!   made after each chunk of runs rather than after each run).
//! * **Requirements on a mean time** (`mtts <= d`) — the Chow–Robbins rule
//!   with half-width `δ` and the one-sided quantile `z = Φ⁻¹(1 − min(α, β))`,
//!   then the side of `d` on which the mean lies: a mean at least `δ` on the
//!   wrong side of `d` is misjudged with probability → at most `min(α, β)`
//!   (asymptotically, as `δ → 0`).
//!
//! Confidence is per figure: every interval covers its own figure with the
//! stated probability (not all of them at once).
//!
//! # Reproducibility
//!
//! Runs are made in chunks whose sizes depend only on the runs before them
//! (the first chunk is the pre-computed Okamoto count, or [`SEQ_CHUNK`]
//! runs; then at least [`SEQ_CHUNK`] runs, or 1/32 of the runs so far); chunk
//! `k` is [`simulate_node`] with the seed [`chunk_seed`]`(seed, k)`. Chunks
//! run in parallel but are merged and checked strictly in order, and the
//! rule stops at the first chunk after which it holds: the runs used and
//! every figure are the same for a seed whatever the number of threads.

use rayon::prelude::*;

use super::stats::proportion;
use super::{
    outcomes, simulate_node, CurvePoint, Estimate, NodeEstimate, SimError, SimOptions, SimResult,
    MAX_RUNS,
};
use crate::tree::{NodeId, Tree};

/// Runs of a chunk (at least; later chunks are 1/32 of the runs so far).
pub const SEQ_CHUNK: u64 = 4096;

/// Runs of a chunk of a sequential test of a requirement (smaller: a test
/// often decides in a few thousand runs).
pub(crate) const TEST_CHUNK: u64 = 512;

/// Default cap on the runs of [`simulate_to_precision`] and of the tests
/// (10^8).
pub const DEFAULT_MAX_RUNS: u64 = 100_000_000;

/// Fewest durations the Chow–Robbins rule accepts (its `n₀`).
pub const MIN_MEAN_SAMPLES: u64 = 30;

/// The standard normal quantile `Φ⁻¹(p)`, `0 < p < 1` (Acklam's rational
/// approximation, relative error below 1.2e-9).
pub(crate) fn normal_quantile(p: f64) -> f64 {
    const A: [f64; 6] = [
        -3.969_683_028_665_376e1,
        2.209_460_984_245_205e2,
        -2.759_285_104_469_687e2,
        1.383_577_518_672_69e2,
        -3.066_479_806_614_716e1,
        2.506_628_277_459_239,
    ];
    const B: [f64; 5] = [
        -5.447_609_879_822_406e1,
        1.615_858_368_580_409e2,
        -1.556_989_798_598_866e2,
        6.680_131_188_771_972e1,
        -1.328_068_155_288_572e1,
    ];
    const C: [f64; 6] = [
        -7.784_894_002_430_293e-3,
        -3.223_964_580_411_365e-1,
        -2.400_758_277_161_838,
        -2.549_732_539_343_734,
        4.374_664_141_464_968,
        2.938_163_982_698_783,
    ];
    const D: [f64; 4] = [
        7.784_695_709_041_462e-3,
        3.224_671_290_700_398e-1,
        2.445_134_137_142_996,
        3.754_408_661_907_416,
    ];
    const LOW: f64 = 0.02425;
    if p <= 0.0 {
        return f64::NEG_INFINITY;
    }
    if p >= 1.0 {
        return f64::INFINITY;
    }
    let tail = |q: f64| {
        (((((C[0] * q + C[1]) * q + C[2]) * q + C[3]) * q + C[4]) * q + C[5])
            / ((((D[0] * q + D[1]) * q + D[2]) * q + D[3]) * q + 1.0)
    };
    if p < LOW {
        tail((-2.0 * p.ln()).sqrt())
    } else if p > 1.0 - LOW {
        -tail((-2.0 * (1.0 - p).ln()).sqrt())
    } else {
        let q = p - 0.5;
        let r = q * q;
        (((((A[0] * r + A[1]) * r + A[2]) * r + A[3]) * r + A[4]) * r + A[5]) * q
            / (((((B[0] * r + B[1]) * r + B[2]) * r + B[3]) * r + B[4]) * r + 1.0)
    }
}

/// Runs after which every probability's estimate is within `eps` of the
/// truth with probability at least `confidence` (Okamoto:
/// `⌈ln(2/δ)/(2ε²)⌉`, `δ = 1 − confidence`).
pub fn okamoto_runs(eps: f64, confidence: f64) -> u64 {
    let delta = 1.0 - confidence;
    ((2.0 / delta).ln() / (2.0 * eps * eps)).ceil().max(1.0) as u64
}

/// Half-width of the Okamoto interval after `n` runs: `√(ln(2/δ)/(2n))`.
pub(crate) fn okamoto_half_width(n: u64, confidence: f64) -> f64 {
    let delta = 1.0 - confidence;
    ((2.0 / delta).ln() / (2.0 * n as f64)).sqrt()
}

/// Whether the Chow–Robbins rule stops with `m` values of sample variance
/// `var`: `m ≥ MIN_MEAN_SAMPLES` and `z²(var + 1/m) ≤ m·eps²`.
pub(crate) fn chow_robbins_stops(m: u64, var: f64, z: f64, eps: f64) -> bool {
    let mf = m as f64;
    m >= MIN_MEAN_SAMPLES && z * z * (var + 1.0 / mf) <= mf * eps * eps
}

/// The seed of chunk `k` of a sequential run seeded with `seed`: element
/// `k + 1` of the SplitMix64 sequence started at `seed` (distinct chunks,
/// distinct seeds).
pub fn chunk_seed(seed: u64, k: u64) -> u64 {
    let mut z = seed.wrapping_add((k + 1).wrapping_mul(0x9E37_79B9_7F4A_7C15));
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// Count, mean and sum of squared deviations of some durations.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(crate) struct MeanAcc {
    /// Number of values.
    pub n: u64,
    /// Their mean.
    pub mean: f64,
    /// Σ(x − mean)².
    pub m2: f64,
}

impl MeanAcc {
    /// Adds a chunk's estimate (count, mean, `se = s/√n`), exactly as the
    /// chunk's sums (Chan et al.'s pairwise update).
    fn merge(&mut self, e: Option<&Estimate>) {
        let Some(e) = e else { return };
        if e.count == 0 {
            return;
        }
        let nb = e.count as f64;
        let m2b = if e.count < 2 || !e.se.is_finite() {
            0.0
        } else {
            e.se * e.se * nb * (nb - 1.0)
        };
        if self.n == 0 {
            *self = MeanAcc {
                n: e.count,
                mean: e.mean,
                m2: m2b,
            };
            return;
        }
        let na = self.n as f64;
        let n = na + nb;
        let delta = e.mean - self.mean;
        self.mean += delta * (nb / n);
        self.m2 += m2b + delta * delta * (na * nb / n);
        self.n += e.count;
    }

    /// The sample variance (n − 1 denominator); `None` below 2 values.
    pub fn variance(&self) -> Option<f64> {
        (self.n >= 2).then(|| self.m2 / (self.n - 1) as f64)
    }

    fn estimate(&self) -> Option<Estimate> {
        if self.n == 0 {
            return None;
        }
        let se = match self.variance() {
            Some(v) => (v / self.n as f64).sqrt(),
            None => f64::INFINITY,
        };
        Some(Estimate::with_se(self.mean, se, self.n))
    }
}

/// One node's sums over the chunks so far.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(crate) struct NodeAcc {
    /// The node.
    pub node: NodeId,
    /// Runs that returned Success.
    pub successes: u64,
    /// Runs that returned Failure.
    pub failures: u64,
    /// Durations of the successful runs.
    pub mtts: MeanAcc,
    /// Durations of the failed runs.
    pub mttf: MeanAcc,
}

/// The sums of a sequential run so far.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Acc {
    /// Runs per node.
    pub runs: u64,
    /// The simulated node first, then (per node) the rest of its subtree.
    pub nodes: Vec<NodeAcc>,
    /// Per time point (in the order asked): runs that succeeded, failed by it.
    pub curve: Vec<(f64, u64, u64)>,
}

impl Acc {
    fn merge(&mut self, r: &SimResult) {
        let count = |e: &Estimate| (e.mean * e.count as f64).round() as u64;
        if self.nodes.is_empty() {
            self.nodes = r
                .nodes
                .iter()
                .map(|n| NodeAcc {
                    node: n.node,
                    ..Default::default()
                })
                .collect();
            self.curve = r.curve.iter().map(|p| (p.t, 0, 0)).collect();
        }
        self.runs += r.runs;
        for (a, n) in self.nodes.iter_mut().zip(&r.nodes) {
            a.successes += count(&n.ps);
            a.failures += count(&n.pf);
            a.mtts.merge(n.mtts.as_ref());
            a.mttf.merge(n.mttf.as_ref());
        }
        for (a, p) in self.curve.iter_mut().zip(&r.curve) {
            a.1 += count(&p.success);
            a.2 += count(&p.failure);
        }
    }

    /// The sums as a [`SimResult`] (standard errors as [`simulate`](super::simulate)'s).
    pub fn result(&self, seed: u64) -> SimResult {
        let n = self.runs;
        SimResult {
            runs: n,
            seed,
            nodes: self
                .nodes
                .iter()
                .map(|a| NodeEstimate {
                    node: a.node,
                    ps: proportion(a.successes, n),
                    pf: proportion(a.failures, n),
                    never: proportion(n - a.successes - a.failures, n),
                    mtts: a.mtts.estimate(),
                    mttf: a.mttf.estimate(),
                })
                .collect(),
            curve: self
                .curve
                .iter()
                .map(|&(t, s, f)| CurvePoint {
                    t,
                    success: proportion(s, n),
                    failure: proportion(f, n),
                    running: proportion(n - s - f, n),
                })
                .collect(),
        }
    }
}

/// How a sequential run makes its chunks.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Chunking {
    /// Runs of the first chunk (run on its own).
    pub first: u64,
    /// Fewest runs of every later chunk.
    pub chunk: u64,
    /// Most runs in all.
    pub max_runs: u64,
}

impl Chunking {
    /// The size of the chunk that starts after `done` runs (0 when the cap
    /// is reached).
    fn size_after(&self, done: u64) -> u64 {
        let size = if done == 0 {
            self.first
        } else {
            (done / 32 / self.chunk * self.chunk).max(self.chunk)
        };
        size.min(self.max_runs.saturating_sub(done))
    }
}

/// Simulates the subtree of `node` chunk after chunk (`base` gives the seed,
/// threads, time points and `per_node`; its `runs` is ignored), calling
/// `stop` after each chunk, in order, until it returns `true` or
/// `chunking.max_runs` runs are done. Returns the sums and whether `stop`
/// ended the run.
pub(crate) fn run_until(
    tree: &Tree,
    node: NodeId,
    base: &SimOptions,
    chunking: Chunking,
    mut stop: impl FnMut(&Acc) -> bool + Send,
) -> Result<(Acc, bool), SimError> {
    if chunking.max_runs == 0 {
        return Err(SimError::ZeroRuns);
    }
    if chunking.max_runs > MAX_RUNS {
        return Err(SimError::AbsurdRuns(chunking.max_runs));
    }
    let chunk_opts = |k: u64, runs: u64| SimOptions {
        runs,
        seed: chunk_seed(base.seed, k),
        threads: 0,
        times: base.times.clone(),
        per_node: base.per_node,
    };
    let mut body = || -> Result<(Acc, bool), SimError> {
        let mut acc = Acc {
            runs: 0,
            nodes: Vec::new(),
            curve: Vec::new(),
        };
        let batch = (2 * rayon::current_num_threads()).max(1);
        let mut k = 0u64;
        loop {
            // the next chunks' sizes depend only on the runs before them
            let mut plan = Vec::new();
            let mut done = acc.runs;
            while plan.len() < if k == 0 { 1 } else { batch } {
                let size = chunking.size_after(done);
                if size == 0 {
                    break;
                }
                plan.push((k + plan.len() as u64, size));
                done += size;
            }
            if plan.is_empty() {
                return Ok((acc, false));
            }
            k += plan.len() as u64;
            let results: Vec<Result<SimResult, SimError>> = plan
                .into_par_iter()
                .map(|(k, size)| simulate_node(tree, node, &chunk_opts(k, size), None))
                .collect();
            for r in results {
                acc.merge(&r?);
                if stop(&acc) {
                    return Ok((acc, true));
                }
            }
        }
    };
    if base.threads > 0 {
        rayon::ThreadPoolBuilder::new()
            .num_threads(base.threads)
            .build()
            .map_err(|e| SimError::ThreadPool(e.to_string()))?
            .install(body)
    } else {
        body()
    }
}

/// What [`simulate_to_precision`] must reach.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Precision {
    /// Half-width of every probability's interval (ps, pf, P(never), the
    /// curve's points), in (0, 0.5); `None`: not a target.
    pub probability: Option<f64>,
    /// Half-width of every mean time's interval (MTTS, MTTF), in s; `None`:
    /// not a target.
    pub time: Option<f64>,
    /// Confidence of each interval, in (0, 1). Default 0.95.
    pub confidence: f64,
    /// Most runs per node. Default [`DEFAULT_MAX_RUNS`].
    pub max_runs: u64,
}

impl Default for Precision {
    fn default() -> Self {
        Precision {
            probability: None,
            time: None,
            confidence: 0.95,
            max_runs: DEFAULT_MAX_RUNS,
        }
    }
}

/// A figure that did not reach its precision within the cap.
#[derive(Debug, Clone, PartialEq)]
pub struct Missed {
    /// The node.
    pub node: NodeId,
    /// `ps`, `mtts`, ...
    pub figure: &'static str,
    /// The half-width reached (`None`: too few runs for any interval).
    pub half_width: Option<f64>,
    /// The half-width asked.
    pub target: f64,
}

/// A figure's interval.
pub(crate) type Interval = Option<(f64, f64)>;

/// The result of [`simulate_to_precision`].
#[derive(Debug, Clone, PartialEq)]
pub struct PrecisionResult {
    /// The estimates at the runs used (`sim.runs`).
    pub sim: SimResult,
    /// What was asked.
    pub precision: Precision,
    /// Runs the Okamoto bound asks for (with a probability target).
    pub okamoto_runs: Option<u64>,
    /// The normal quantile of the mean times' intervals.
    pub z: f64,
    /// Half-width of every probability's interval at the runs used,
    /// `√(ln(2/δ)/(2n))` (before clamping to [0, 1]).
    pub probability_half_width: f64,
    /// Per node of `sim.nodes`: the intervals of ps, pf, P(never), MTTS,
    /// MTTF (`None` where undefined).
    pub intervals: Vec<[Interval; 5]>,
    /// Per curve point: the intervals of success, failure, running by t.
    pub curve: Vec<[Interval; 3]>,
    /// Figures short of their target (empty: every target reached).
    pub missed: Vec<Missed>,
}

/// Progress of [`simulate_to_precision`], after each chunk.
#[derive(Debug, Clone, PartialEq)]
pub struct Progress {
    /// Runs per node so far.
    pub runs: u64,
    /// The runs the rules look like needing (an estimate; grows or shrinks
    /// as the variances are learnt).
    pub needed: u64,
}

/// Invalid precision settings, or a failed simulation.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PrecisionError {
    /// Neither target given.
    #[error("give a precision for the probabilities, for the mean times, or both")]
    NoTarget,
    /// A probability half-width outside (0, 0.5).
    #[error("the precision of probabilities must be in (0, 0.5), not {0}")]
    Probability(f64),
    /// A time half-width not finite and > 0.
    #[error("the precision of mean times must be a finite number of seconds > 0, not {0}")]
    Time(f64),
    /// A confidence outside (0, 1).
    #[error("the confidence must be in (0, 1), not {0}")]
    Confidence(f64),
    /// The simulation itself.
    #[error(transparent)]
    Sim(#[from] SimError),
}

/// Simulates the subtree of `node` (every node of it with
/// `base.per_node`, and its curve at `base.times`) until every probability
/// is within `±precision.probability` and every mean time within
/// `±precision.time` at `precision.confidence` (module docs: the rules), or
/// `precision.max_runs` runs per node. A mean time whose outcome the node
/// can never return (a condition that always fails has no MTTS) is no
/// target. `progress` is called after each chunk.
pub fn simulate_to_precision(
    tree: &Tree,
    node: NodeId,
    base: &SimOptions,
    precision: &Precision,
    progress: Option<&(dyn Fn(&Progress) + Sync)>,
) -> Result<PrecisionResult, PrecisionError> {
    let Precision {
        probability,
        time,
        confidence,
        max_runs,
    } = *precision;
    if probability.is_none() && time.is_none() {
        return Err(PrecisionError::NoTarget);
    }
    if let Some(p) = probability.filter(|p| !(*p > 0.0 && *p < 0.5)) {
        return Err(PrecisionError::Probability(p));
    }
    if let Some(t) = time.filter(|t| !(t.is_finite() && *t > 0.0)) {
        return Err(PrecisionError::Time(t));
    }
    if !(confidence > 0.0 && confidence < 1.0) {
        return Err(PrecisionError::Confidence(confidence));
    }
    if node >= tree.nodes.len() {
        return Err(SimError::NoSuchNode {
            node,
            len: tree.nodes.len(),
        }
        .into());
    }
    let z = normal_quantile(1.0 - (1.0 - confidence) / 2.0);
    let n_p = probability.map(|eps| okamoto_runs(eps, confidence));
    let can = outcomes(tree, node);
    let chunking = Chunking {
        first: n_p.unwrap_or(SEQ_CHUNK).clamp(1, MAX_RUNS),
        chunk: SEQ_CHUNK,
        max_runs,
    };
    // the mean times that are targets: (index in acc.nodes, outcome 1 = Success)
    let stop = |acc: &Acc| {
        let mut needed = n_p.unwrap_or(0).max(acc.runs);
        let mut met = n_p.is_none_or(|n| acc.runs >= n);
        if let Some(eps) = time {
            for a in &acc.nodes {
                let (cs, cf) = can[a.node];
                for (possible, m, k) in [(cs, &a.mtts, a.successes), (cf, &a.mttf, a.failures)] {
                    if !possible {
                        continue;
                    }
                    let done = m
                        .variance()
                        .is_some_and(|v| chow_robbins_stops(m.n, v, z, eps));
                    if !done {
                        met = false;
                        // runs needed if the variance and the outcome's rate hold
                        let rate = k.max(1) as f64 / acc.runs as f64;
                        let want = match m.variance() {
                            Some(v) => (z * z * v / (eps * eps)).max(MIN_MEAN_SAMPLES as f64),
                            None => MIN_MEAN_SAMPLES as f64,
                        };
                        needed = needed.max((want / rate).min(max_runs as f64) as u64);
                    }
                }
            }
        }
        if let Some(p) = progress {
            p(&Progress {
                runs: acc.runs,
                needed: needed.min(max_runs),
            });
        }
        met
    };
    let (acc, _) = run_until(tree, node, base, chunking, stop)?;
    let sim = acc.result(base.seed);
    let n = acc.runs;
    let h = okamoto_half_width(n, confidence);
    let prob = |e: &Estimate| Some(((e.mean - h).max(0.0), (e.mean + h).min(1.0)));
    let mean = |m: &MeanAcc| {
        m.variance().map(|v| {
            let hw = z * (v / m.n as f64).sqrt();
            (m.mean - hw, m.mean + hw)
        })
    };
    let intervals = sim
        .nodes
        .iter()
        .zip(&acc.nodes)
        .map(|(e, a)| {
            [
                prob(&e.ps),
                prob(&e.pf),
                prob(&e.never),
                mean(&a.mtts),
                mean(&a.mttf),
            ]
        })
        .collect();
    let curve = sim
        .curve
        .iter()
        .map(|p| [prob(&p.success), prob(&p.failure), prob(&p.running)])
        .collect();
    let mut missed = Vec::new();
    if let Some(eps) = probability {
        if n < n_p.unwrap_or(0) {
            for a in &acc.nodes {
                missed.push(Missed {
                    node: a.node,
                    figure: "ps",
                    half_width: Some(h),
                    target: eps,
                });
            }
        }
    }
    if let Some(eps) = time {
        for a in &acc.nodes {
            let (cs, cf) = can[a.node];
            for (possible, m, figure) in [(cs, &a.mtts, "mtts"), (cf, &a.mttf, "mttf")] {
                let done = m
                    .variance()
                    .is_some_and(|v| chow_robbins_stops(m.n, v, z, eps));
                if possible && !done {
                    missed.push(Missed {
                        node: a.node,
                        figure,
                        half_width: m.variance().map(|v| z * (v / m.n as f64).sqrt()),
                        target: eps,
                    });
                }
            }
        }
    }
    Ok(PrecisionResult {
        sim,
        precision: *precision,
        okamoto_runs: n_p,
        z,
        probability_half_width: h,
        intervals,
        curve,
        missed,
    })
}

/// Wald's sequential probability ratio test of a Bernoulli probability `p`:
/// `H0: p = p0` against `H1: p = p1` (module docs).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sprt {
    /// The probability under H0 (the requirement holds with margin).
    pub p0: f64,
    /// The probability under H1 (it fails by the margin).
    pub p1: f64,
    /// `ln((1−β)/α)`: accept H1 at or above it.
    pub upper: f64,
    /// `ln(β/(1−α))`: accept H0 at or below it.
    pub lower: f64,
}

/// The outcome of a sequential test.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Decision {
    /// H0 accepted: the requirement holds.
    Holds,
    /// H1 accepted: the requirement fails.
    Fails,
    /// The cap on runs came first.
    Undecided,
}

impl Sprt {
    /// The test of `H0: p = p0` against `H1: p = p1` with error bounds
    /// `alpha` (rejecting H0) and `beta` (accepting H0 under H1); `p0 ≠ p1`,
    /// both in (0, 1), `alpha`, `beta` in (0, 1) with `alpha + beta < 1`.
    pub fn new(p0: f64, p1: f64, alpha: f64, beta: f64) -> Sprt {
        Sprt {
            p0,
            p1,
            upper: ((1.0 - beta) / alpha).ln(),
            lower: (beta / (1.0 - alpha)).ln(),
        }
    }

    /// The log-likelihood ratio `ln(L1/L0)` after `k` successes in `n` trials.
    pub fn llr(&self, k: u64, n: u64) -> f64 {
        let (k, f) = (k as f64, (n - k) as f64);
        k * (self.p1 / self.p0).ln() + f * ((1.0 - self.p1) / (1.0 - self.p0)).ln()
    }

    /// The decision after `k` successes in `n` trials: `Undecided` while
    /// the ratio is between the thresholds.
    pub fn decide(&self, k: u64, n: u64) -> Decision {
        let l = self.llr(k, n);
        if l >= self.upper {
            Decision::Fails
        } else if l <= self.lower {
            Decision::Holds
        } else {
            Decision::Undecided
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn normal_quantiles() {
        for (p, z) in [
            (0.975, 1.959_963_984_540_054),
            (0.95, 1.644_853_626_951_472),
            (0.5, 0.0),
            (0.995, 2.575_829_303_548_901),
            (0.001, -3.090_232_306_167_813),
        ] {
            assert!((normal_quantile(p) - z).abs() < 1e-8, "{p}");
        }
    }

    #[test]
    fn okamoto_counts() {
        // ln(40) / (2 · 1e-4) = 18444.4
        assert_eq!(okamoto_runs(0.01, 0.95), 18_445);
        assert!((okamoto_half_width(18_445, 0.95) - 0.01).abs() < 1e-6);
    }

    #[test]
    fn chunk_sizes_grow_and_stop_at_the_cap() {
        let c = Chunking {
            first: 100,
            chunk: 4096,
            max_runs: 1_000_000,
        };
        assert_eq!(c.size_after(0), 100);
        assert_eq!(c.size_after(100), 4096);
        assert_eq!(c.size_after(32 * 8192 + 5), 8192);
        assert_eq!(c.size_after(999_000), 1000);
        assert_eq!(c.size_after(1_000_000), 0);
    }

    #[test]
    fn sprt_thresholds() {
        let t = Sprt::new(0.96, 0.94, 0.05, 0.05);
        assert!((t.upper - 19f64.ln()).abs() < 1e-12);
        assert!((t.lower + 19f64.ln()).abs() < 1e-12);
        // all successes accept H0 (p0 > p1), failures push towards H1
        assert_eq!(t.decide(2000, 2000), Decision::Holds);
        assert_eq!(t.decide(0, 100), Decision::Fails);
        assert_eq!(t.decide(1, 1), Decision::Undecided);
    }

    #[test]
    fn merged_moments_are_exact() {
        let xs: Vec<f64> = (0..100).map(|i| (i * 7 % 13) as f64).collect();
        let mut acc = MeanAcc::default();
        for c in xs.chunks(17) {
            let n = c.len() as f64;
            let mean = c.iter().sum::<f64>() / n;
            let var = c.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0);
            acc.merge(Some(&Estimate::with_se(
                mean,
                (var / n).sqrt(),
                c.len() as u64,
            )));
        }
        let n = xs.len() as f64;
        let mean = xs.iter().sum::<f64>() / n;
        let var = xs.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0);
        assert!((acc.mean - mean).abs() < 1e-12);
        assert!((acc.variance().unwrap() - var).abs() < 1e-10);
    }
}
