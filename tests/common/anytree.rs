//! The engine's specification as a generator: random trees over **every**
//! node kind the YAML format has (Sequence, Fallback, Parallel with any
//! thresholds, IfThenElse, inverter, force decorators, retry, repeat,
//! until_success / until_failure) and **every** leaf timing family
//! (exponential, fixed, both hybrids, shifted, Erlang, hypo- and
//! hyperexponential, conditions), with a Monte Carlo sampler written here
//! from the node semantics (the README's node table, BT.CPP's Parallel:
//! children's returns taken in time order, simultaneous ones in child
//! order, the success threshold checked before the failure threshold after
//! each) — it shares nothing with `src/sim`.
//!
//! Fixed times are multiples of 1/8 s, so sums of them are exact in binary
//! and ties between subtrees happen exactly where the semantics has them.

use rand::{RngExt, SeedableRng};
use rand_xoshiro::Xoshiro256PlusPlus as Rng;

/// One outcome's time law.
#[derive(Debug, Clone)]
pub enum Law {
    Exp(f64),
    Fixed(f64),
    /// `min(Exp(rate), cap)`: the random side of a hybrid.
    Capped(f64, f64),
    Erlang(usize, f64),
    Hypo(Vec<f64>),
    Hyper(Vec<(f64, f64)>),
    /// A deterministic shift, then the law.
    Shifted(f64, Box<Law>),
}

/// A generated node.
#[derive(Debug, Clone)]
pub enum Node {
    Action { ps: f64, s: Law, f: Law },
    Condition { ps: f64 },
    Sequence(Vec<Node>),
    Fallback(Vec<Node>),
    Parallel { m: usize, f: usize, kids: Vec<Node> },
    IfThenElse(Vec<Node>),
    Inverter(Box<Node>),
    ForceSuccess(Box<Node>),
    ForceFailure(Box<Node>),
    Retry(usize, Box<Node>),
    Repeat(usize, Box<Node>),
    UntilSuccess(Box<Node>),
    UntilFailure(Box<Node>),
}

/// How a run ended.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Outcome {
    Success(f64),
    Failure(f64),
    /// The run never returns (a loop whose child cannot end it, or a
    /// Parallel whose thresholds are never met).
    Never,
}

/// A random tree with at most `max_leaves` leaves, reproducible from `seed`.
pub fn random_tree(seed: u64, max_leaves: usize) -> Node {
    let mut rng = Rng::seed_from_u64(seed);
    let leaves = rng.random_range(1..=max_leaves.max(1));
    node(&mut rng, leaves, 0)
}

/// [`random_tree`] with every leaf's times made phase-type (a fixed time
/// `τ` an exponential of mean `τ`, a hybrid's random side its exponential,
/// a shift dropped): the whole tree has a phase chain.
#[allow(dead_code)]
pub fn random_phase_type_tree(seed: u64, max_leaves: usize) -> Node {
    random_tree(seed, max_leaves).phase_type()
}

impl Law {
    fn phase_type(self) -> Law {
        match self {
            Law::Fixed(t) => Law::Exp(1.0 / t),
            Law::Capped(rate, _) => Law::Exp(rate),
            Law::Shifted(_, l) => l.phase_type(),
            l => l,
        }
    }
}

impl Node {
    fn phase_type(self) -> Node {
        let all = |v: Vec<Node>| v.into_iter().map(Node::phase_type).collect();
        let one = |b: Box<Node>| Box::new(b.phase_type());
        match self {
            Node::Action { ps, s, f } => Node::Action {
                ps,
                s: s.phase_type(),
                f: f.phase_type(),
            },
            Node::Condition { ps } => Node::Condition { ps },
            Node::Sequence(v) => Node::Sequence(all(v)),
            Node::Fallback(v) => Node::Fallback(all(v)),
            Node::Parallel { m, f, kids } => Node::Parallel {
                m,
                f,
                kids: all(kids),
            },
            Node::IfThenElse(v) => Node::IfThenElse(all(v)),
            Node::Inverter(c) => Node::Inverter(one(c)),
            Node::ForceSuccess(c) => Node::ForceSuccess(one(c)),
            Node::ForceFailure(c) => Node::ForceFailure(one(c)),
            Node::Retry(k, c) => Node::Retry(k, one(c)),
            Node::Repeat(k, c) => Node::Repeat(k, one(c)),
            Node::UntilSuccess(c) => Node::UntilSuccess(one(c)),
            Node::UntilFailure(c) => Node::UntilFailure(one(c)),
        }
    }
}

fn tenth(rng: &mut Rng) -> f64 {
    rng.random_range(1..=16) as f64 / 8.0
}

fn rate(rng: &mut Rng) -> f64 {
    // rates 0.25 .. 4: means from a quarter second to 4 s
    let r: f64 = 2f64.powf(rng.random_range(-2.0..2.0));
    (r * 1000.0).round() / 1000.0
}

fn stochastic_law(rng: &mut Rng) -> Law {
    match rng.random_range(0..6) {
        0 | 1 => Law::Exp(rate(rng)),
        2 => Law::Erlang(rng.random_range(2..=4), rate(rng)),
        3 => {
            let n = rng.random_range(2..=3);
            Law::Hypo((0..n).map(|_| rate(rng)).collect())
        }
        4 => {
            let p = rng.random_range(1..=9) as f64 / 10.0;
            Law::Hyper(vec![(p, rate(rng)), (1.0 - p, rate(rng))])
        }
        _ => Law::Shifted(tenth(rng), Box::new(Law::Exp(rate(rng)))),
    }
}

/// The law without its shift (a shift of a shift is written as one).
fn unshifted(l: Law) -> Law {
    match l {
        Law::Shifted(_, inner) => *inner,
        l => l,
    }
}

fn leaf(rng: &mut Rng) -> Node {
    let ps = rng.random_range(0..=10) as f64 / 10.0;
    match rng.random_range(0..10) {
        0 | 1 => Node::Condition { ps },
        2 => Node::Action {
            ps,
            s: Law::Fixed(tenth(rng)),
            f: Law::Fixed(tenth(rng)),
        },
        3 => {
            let c = tenth(rng);
            Node::Action {
                ps,
                s: Law::Fixed(c),
                f: Law::Capped(rate(rng), c),
            }
        }
        4 => {
            let c = tenth(rng);
            Node::Action {
                ps,
                s: Law::Capped(rate(rng), c),
                f: Law::Fixed(c),
            }
        }
        5 => Node::Action {
            ps,
            s: Law::Exp(rate(rng)),
            f: Law::Exp(rate(rng)),
        },
        6 => Node::Action {
            ps,
            s: Law::Shifted(tenth(rng), Box::new(unshifted(stochastic_law(rng)))),
            f: Law::Erlang(2, rate(rng)),
        },
        _ => Node::Action {
            ps,
            s: stochastic_law(rng),
            f: stochastic_law(rng),
        },
    }
}

fn split(rng: &mut Rng, leaves: usize, k: usize) -> Vec<usize> {
    let mut sizes = vec![1usize; k];
    for _ in 0..leaves - k {
        let i = rng.random_range(0..k);
        sizes[i] += 1;
    }
    sizes
}

fn node(rng: &mut Rng, leaves: usize, depth: usize) -> Node {
    if leaves == 1 && rng.random::<f64>() < 0.75 {
        return leaf(rng);
    }
    // a decorator over the same number of leaves (at most a few levels)
    if depth < 6 && rng.random::<f64>() < 0.3 {
        let child = Box::new(node(rng, leaves, depth + 1));
        return match rng.random_range(0..9) {
            0 => Node::Inverter(child),
            1 => Node::ForceSuccess(child),
            2 => Node::ForceFailure(child),
            3 | 4 => Node::Retry(rng.random_range(1..=4), child),
            5 => Node::Repeat(rng.random_range(1..=3), child),
            6 | 7 => Node::UntilSuccess(child),
            _ => Node::UntilFailure(child),
        };
    }
    if leaves == 1 {
        return leaf(rng);
    }
    let k = rng.random_range(2..=leaves.min(4));
    let kids: Vec<Node> = split(rng, leaves, k)
        .into_iter()
        .map(|s| node(rng, s, depth + 1))
        .collect();
    match rng.random_range(0..7) {
        0 | 1 => Node::Sequence(kids),
        2 | 3 => Node::Fallback(kids),
        4 if kids.len() <= 3 => Node::IfThenElse(kids),
        _ => {
            let n = kids.len();
            let m = rng.random_range(1..=n);
            let f = if rng.random::<bool>() {
                n - m + 1
            } else {
                rng.random_range(1..=n)
            };
            Node::Parallel { m, f, kids }
        }
    }
}

fn law_yaml(l: &Law) -> String {
    match l {
        Law::Exp(r) => format!("{{rate: {r}}}"),
        Law::Fixed(t) => format!("{{fixed: {t}}}"),
        Law::Capped(..) => unreachable!("a hybrid is written with its keys"),
        Law::Erlang(k, r) => format!("{{erlang: {{k: {k}, rate: {r}}}}}"),
        Law::Hypo(rs) => format!(
            "{{hypoexponential: [{}]}}",
            rs.iter()
                .map(|r| r.to_string())
                .collect::<Vec<_>>()
                .join(", ")
        ),
        Law::Hyper(bs) => format!(
            "{{hyperexponential: [{}]}}",
            bs.iter()
                .map(|(p, r)| format!("{{p: {p}, rate: {r}}}"))
                .collect::<Vec<_>>()
                .join(", ")
        ),
        Law::Shifted(s, l) => {
            let inner = law_yaml(l);
            format!("{{shift: {s}, {}", &inner[1..])
        }
    }
}

impl Node {
    /// The tree in btrel's YAML format, nodes named `n1`, `n2`, ... in
    /// pre-order.
    pub fn yaml(&self) -> String {
        let mut counter = 0;
        format!("tree: {}\n", self.write(&mut counter))
    }

    fn write(&self, c: &mut usize) -> String {
        *c += 1;
        let name = format!("n{c}");
        let kids = |ks: &[Node], c: &mut usize| {
            ks.iter().map(|k| k.write(c)).collect::<Vec<_>>().join(", ")
        };
        let one = |kind: &str, child: &Node, extra: String, c: &mut usize| {
            format!(
                "{{{kind}: {{name: {name}, {extra}child: {}}}}}",
                child.write(c)
            )
        };
        match self {
            Node::Condition { ps } => format!("{{condition: {{name: {name}, ps: {ps}}}}}"),
            Node::Action { ps, s, f } => {
                let times = match (s, f) {
                    (Law::Fixed(a), Law::Capped(r, _)) => format!("tau_s: {a}, nu: {r}"),
                    (Law::Capped(r, _), Law::Fixed(b)) => format!("mu: {r}, tau_f: {b}"),
                    (Law::Fixed(a), Law::Fixed(b)) => format!("tau_s: {a}, tau_f: {b}"),
                    (s, f) => format!(
                        "success_time: {}, failure_time: {}",
                        law_yaml(s),
                        law_yaml(f)
                    ),
                };
                format!("{{action: {{name: {name}, ps: {ps}, {times}}}}}")
            }
            Node::Sequence(ks) => format!("{{sequence: {{name: {name}, children: [{}]}}}}", kids(ks, c)),
            Node::Fallback(ks) => format!("{{fallback: {{name: {name}, children: [{}]}}}}", kids(ks, c)),
            Node::IfThenElse(ks) => {
                format!("{{if_then_else: {{name: {name}, children: [{}]}}}}", kids(ks, c))
            }
            Node::Parallel { m, f, kids: ks } => format!(
                "{{parallel: {{name: {name}, success_threshold: {m}, failure_threshold: {f}, children: [{}]}}}}",
                kids(ks, c)
            ),
            Node::Inverter(k) => one("inverter", k, String::new(), c),
            Node::ForceSuccess(k) => one("force_success", k, String::new(), c),
            Node::ForceFailure(k) => one("force_failure", k, String::new(), c),
            Node::Retry(n, k) => one("retry", k, format!("attempts: {n}, "), c),
            Node::Repeat(n, k) => one("repeat", k, format!("times: {n}, "), c),
            Node::UntilSuccess(k) => one("until_success", k, String::new(), c),
            Node::UntilFailure(k) => one("until_failure", k, String::new(), c),
        }
    }

    /// Number of leaves.
    pub fn leaves(&self) -> usize {
        match self {
            Node::Action { .. } | Node::Condition { .. } => 1,
            Node::Sequence(ks) | Node::Fallback(ks) | Node::IfThenElse(ks) => {
                ks.iter().map(Node::leaves).sum()
            }
            Node::Parallel { kids, .. } => kids.iter().map(Node::leaves).sum(),
            Node::Inverter(k)
            | Node::ForceSuccess(k)
            | Node::ForceFailure(k)
            | Node::Retry(_, k)
            | Node::Repeat(_, k)
            | Node::UntilSuccess(k)
            | Node::UntilFailure(k) => k.leaves(),
        }
    }
}

/// Most runs of a loop's child in one sampled run before the run counts as
/// never returning (a child that can end the loop with probability q per run
/// is cut with probability (1 − q)^LOOP_CAP).
const LOOP_CAP: usize = 100_000;

/// Most leaf runs one [`Node::estimate`] samples in all. Loops of loops
/// multiply their caps (a loop of a loop whose child rarely ends it may
/// take 10^10 leaf runs for one sampled run): past this budget the
/// estimate stops, and says so ([`Estimates::complete`] false) instead of
/// running for hours or counting cut runs as never returning.
const LEAF_BUDGET: u64 = 200_000_000;

thread_local! {
    /// Leaf runs the current [`Node::estimate`] on this thread may still
    /// take.
    static LEAF_RUNS_LEFT: std::cell::Cell<u64> = const { std::cell::Cell::new(LEAF_BUDGET) };
}

/// Whether the current estimate has spent its budget.
fn over_budget() -> bool {
    LEAF_RUNS_LEFT.with(|c| c.get()) == 0
}

/// Counts one leaf run of the current estimate.
fn count_leaf_run() {
    LEAF_RUNS_LEFT.with(|c| c.set(c.get().saturating_sub(1)));
}

fn draw(l: &Law, rng: &mut Rng) -> f64 {
    let exp = |r: f64, rng: &mut Rng| -(1.0 - rng.random::<f64>()).ln() / r;
    match l {
        Law::Exp(r) => exp(*r, rng),
        Law::Fixed(t) => *t,
        Law::Capped(r, c) => exp(*r, rng).min(*c),
        Law::Erlang(k, r) => (0..*k).map(|_| exp(*r, rng)).sum(),
        Law::Hypo(rs) => rs.iter().map(|&r| exp(r, rng)).sum(),
        Law::Hyper(bs) => {
            let u: f64 = rng.random();
            let mut acc = 0.0;
            for &(p, r) in bs {
                acc += p;
                if u < acc {
                    return exp(r, rng);
                }
            }
            exp(bs[bs.len() - 1].1, rng)
        }
        Law::Shifted(s, l) => s + draw(l, rng),
    }
}

fn at(o: Outcome, t0: f64) -> Outcome {
    match o {
        Outcome::Success(t) => Outcome::Success(t0 + t),
        Outcome::Failure(t) => Outcome::Failure(t0 + t),
        Outcome::Never => Outcome::Never,
    }
}

impl Node {
    /// `[may succeed, may fail]`: false only where the outcome is
    /// impossible by the node's structure (an over-approximation read from
    /// the semantics, so a loop whose child cannot end it is known to run
    /// for ever without sampling `LOOP_CAP` runs).
    pub fn may(&self) -> [bool; 2] {
        match self {
            Node::Condition { ps } | Node::Action { ps, .. } => [*ps > 0.0, *ps < 1.0],
            Node::Sequence(ks) => may_chain(ks, 0),
            Node::Fallback(ks) => {
                let [f, s] = may_chain(ks, 1);
                [s, f]
            }
            Node::IfThenElse(ks) => {
                let [cs, cf] = ks[0].may();
                let [ts, tf] = ks[1].may();
                let [es, ef] = if ks.len() == 3 {
                    ks[2].may()
                } else {
                    [false, true]
                };
                [cs && ts || cf && es, cs && tf || cf && ef]
            }
            Node::Parallel { m, f, kids } => {
                let f = (*f).min(kids.len() - m + 1);
                let count = |o: usize| kids.iter().filter(|k| k.may()[o]).count();
                [count(0) >= *m, count(1) >= f]
            }
            Node::Inverter(k) => {
                let [s, f] = k.may();
                [f, s]
            }
            Node::ForceSuccess(k) => [k.may().iter().any(|&x| x), false],
            Node::ForceFailure(k) => [false, k.may().iter().any(|&x| x)],
            Node::Retry(_, k) | Node::Repeat(_, k) => k.may(),
            Node::UntilSuccess(k) => [k.may()[0], false],
            Node::UntilFailure(k) => [false, k.may()[1]],
        }
    }

    /// One run of the node from time 0 (a fresh, independent run).
    pub fn sample(&self, rng: &mut Rng) -> Outcome {
        match self {
            Node::Condition { ps } => {
                count_leaf_run();
                if rng.random::<f64>() < *ps {
                    Outcome::Success(0.0)
                } else {
                    Outcome::Failure(0.0)
                }
            }
            Node::Action { ps, s, f } => {
                count_leaf_run();
                if rng.random::<f64>() < *ps {
                    Outcome::Success(draw(s, rng))
                } else {
                    Outcome::Failure(draw(f, rng))
                }
            }
            Node::Sequence(ks) => chain(ks, rng, true),
            Node::Fallback(ks) => chain(ks, rng, false),
            Node::IfThenElse(ks) => match ks[0].sample(rng) {
                Outcome::Success(t) => at(ks[1].sample(rng), t),
                Outcome::Failure(t) if ks.len() == 3 => at(ks[2].sample(rng), t),
                o => o,
            },
            Node::Parallel { m, f, kids } => {
                let n = kids.len();
                let f = (*f).min(n - m + 1);
                let mut runs: Vec<(f64, usize, bool)> = kids
                    .iter()
                    .enumerate()
                    .filter_map(|(i, k)| match k.sample(rng) {
                        Outcome::Success(t) => Some((t, i, true)),
                        Outcome::Failure(t) => Some((t, i, false)),
                        Outcome::Never => None,
                    })
                    .collect();
                runs.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
                let (mut ns, mut nf) = (0, 0);
                for (t, _, ok) in runs {
                    if ok {
                        ns += 1;
                    } else {
                        nf += 1;
                    }
                    if ns >= *m {
                        return Outcome::Success(t);
                    }
                    if nf >= f {
                        return Outcome::Failure(t);
                    }
                }
                Outcome::Never
            }
            Node::Inverter(k) => match k.sample(rng) {
                Outcome::Success(t) => Outcome::Failure(t),
                Outcome::Failure(t) => Outcome::Success(t),
                o => o,
            },
            Node::ForceSuccess(k) => match k.sample(rng) {
                Outcome::Success(t) | Outcome::Failure(t) => Outcome::Success(t),
                o => o,
            },
            Node::ForceFailure(k) => match k.sample(rng) {
                Outcome::Success(t) | Outcome::Failure(t) => Outcome::Failure(t),
                o => o,
            },
            Node::Retry(n, k) => repeat_until(k, rng, *n, false),
            Node::Repeat(n, k) => repeat_until(k, rng, *n, true),
            Node::UntilSuccess(k) if !k.may()[0] => Outcome::Never,
            Node::UntilFailure(k) if !k.may()[1] => Outcome::Never,
            Node::UntilSuccess(k) => repeat_until(k, rng, LOOP_CAP, false),
            Node::UntilFailure(k) => {
                let mut t0 = 0.0;
                for _ in 0..LOOP_CAP {
                    if over_budget() {
                        return Outcome::Never;
                    }
                    match k.sample(rng) {
                        Outcome::Success(t) => t0 += t,
                        Outcome::Failure(t) => return Outcome::Failure(t0 + t),
                        Outcome::Never => return Outcome::Never,
                    }
                }
                Outcome::Never
            }
        }
    }
}

/// `[may go on to the end, may stop early]` of children run in turn that
/// go on after outcome `on` (0: Success, a Sequence; 1: Failure).
fn may_chain(ks: &[Node], on: usize) -> [bool; 2] {
    let mut reach = true;
    let mut stop = false;
    for k in ks {
        let m = k.may();
        stop |= reach && m[1 - on];
        reach &= m[on];
    }
    [reach, stop]
}

/// A Sequence (`on = true`: go on after a Success) or a Fallback.
fn chain(ks: &[Node], rng: &mut Rng, on: bool) -> Outcome {
    let mut t0 = 0.0;
    for k in ks {
        match (k.sample(rng), on) {
            (Outcome::Success(t), true) | (Outcome::Failure(t), false) => t0 += t,
            (o, _) => return at(o, t0),
        }
    }
    if on {
        Outcome::Success(t0)
    } else {
        Outcome::Failure(t0)
    }
}

/// Runs a fresh child at most `n` times: Repeat (`on_success`: go on after
/// each Success, Success after n) or Retry (go on after each Failure,
/// Failure after n); past `LOOP_CAP` runs the run never returns.
fn repeat_until(k: &Node, rng: &mut Rng, n: usize, on_success: bool) -> Outcome {
    let mut t0 = 0.0;
    for _ in 0..n {
        if over_budget() {
            return Outcome::Never;
        }
        match (k.sample(rng), on_success) {
            (Outcome::Success(t), true) | (Outcome::Failure(t), false) => t0 += t,
            (o, _) => return at(o, t0),
        }
    }
    if n >= LOOP_CAP {
        Outcome::Never
    } else if on_success {
        Outcome::Success(t0)
    } else {
        Outcome::Failure(t0)
    }
}

/// Monte Carlo estimates of one node: ps, pf, the mean times and S(t),
/// F(t) at `times`, each with its standard error.
#[derive(Debug, Clone)]
pub struct Estimates {
    pub runs: usize,
    pub ps: (f64, f64),
    pub pf: (f64, f64),
    pub mtts: Option<(f64, f64)>,
    pub mttf: Option<(f64, f64)>,
    pub success_by: Vec<(f64, f64)>,
    pub failure_by: Vec<(f64, f64)>,
    /// False when the runs took more than the leaf budget: the estimate
    /// stopped early and its figures are not to be compared.
    pub complete: bool,
}

fn proportion(k: usize, n: usize) -> (f64, f64) {
    let p = k as f64 / n as f64;
    (p, (p * (1.0 - p) / n as f64).sqrt())
}

fn mean(xs: &[f64]) -> Option<(f64, f64)> {
    if xs.len() < 2 {
        return None;
    }
    let n = xs.len() as f64;
    let m = xs.iter().sum::<f64>() / n;
    let v = xs.iter().map(|x| (x - m) * (x - m)).sum::<f64>() / (n - 1.0);
    Some((m, (v / n).sqrt()))
}

impl Node {
    /// `runs` independent runs of the node, within the default budget of
    /// leaf runs.
    pub fn estimate(&self, runs: usize, times: &[f64], seed: u64) -> Estimates {
        self.estimate_within(runs, times, seed, LEAF_BUDGET)
    }

    /// `runs` independent runs of the node, stopped past `budget` leaf runs
    /// in all ([`Estimates::complete`] false).
    pub fn estimate_within(&self, runs: usize, times: &[f64], seed: u64, budget: u64) -> Estimates {
        LEAF_RUNS_LEFT.with(|c| c.set(budget));
        let mut rng = Rng::seed_from_u64(seed);
        let (mut ts, mut tf) = (Vec::new(), Vec::new());
        for _ in 0..runs {
            if over_budget() {
                break;
            }
            match self.sample(&mut rng) {
                Outcome::Success(t) => ts.push(t),
                Outcome::Failure(t) => tf.push(t),
                Outcome::Never => {}
            }
        }
        let complete = !over_budget();
        let by = |xs: &[f64]| -> Vec<(f64, f64)> {
            times
                .iter()
                .map(|&t| proportion(xs.iter().filter(|&&x| x <= t).count(), runs))
                .collect()
        };
        Estimates {
            runs,
            ps: proportion(ts.len(), runs),
            pf: proportion(tf.len(), runs),
            mtts: mean(&ts),
            mttf: mean(&tf),
            success_by: by(&ts),
            failure_by: by(&tf),
            complete,
        }
    }
}
