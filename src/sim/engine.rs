//! The episode engine: a subtree compiled into a compact program, and one
//! run of it.
//!
//! A [`Program`] is built once per simulated node. Each node becomes one
//! small `Copy` [`Op`]; children live in one index array and leaves in one
//! parameter array, so an episode is a tight recursive function over indices:
//! no allocation, no dynamic dispatch. Parallel nodes use a [`Scratch`] stack
//! whose capacity is reserved up front, so it never grows.
//!
//! While compiling, a few rewrites that change neither the outcome nor the
//! duration of any run (nor the random draws made) shorten episodes:
//!
//! * a condition with `ps = 0` in a Fallback, or `ps = 1` in a Sequence,
//!   is dropped (it returns the "keep going" outcome at once). It would
//!   draw one number; dropping it only shifts the stream;
//! * a Sequence child of a Sequence (a Fallback child of a Fallback) is
//!   spliced into its parent: `Seq[a, Seq[b, c], d] = Seq[a, b, c, d]`;
//! * a Sequence or Fallback left with one child is that child; one left with
//!   none returns Success (Sequence) or Failure (Fallback) at time 0;
//! * a subtree made only of Sequences, Fallbacks, Inverters, ForceSuccess /
//!   ForceFailure and leaves becomes one [`Op::Chain`]: a flat list of leaf
//!   instructions, each naming the next instruction after its Success and
//!   after its Failure (or the chain's return), run by one loop that adds
//!   the leaves' times (no recursion, no dispatch on node kinds).
//!
//! Per-episode work is proportional to the nodes the episode runs: the
//! RoundRobin / SequenceWithMemory indices read 0 at each episode's start
//! without being cleared ([`Slots`]), and nothing is allocated.
//!
//! A *recording* program ([`Program::recording`], for `simulate` of every
//! node) keeps one op per tree node and records each node's first run of
//! the episode; it draws the same numbers and adds the same times in the
//! same order as the plain program ([`Program::acc`]), so the root's runs
//! are identical to the last bit.
//!
//! A leaf is evaluated without branching on its outcome: its duration is
//! `min(E·a + b, c)` with `E ~ Exp(1)` and `(a, b, c)` picked by the outcome:
//! `(1/rate, 0, ∞)` for an exponential time, `(0, time, ∞)` for a fixed one,
//! `(1/rate, 0, cap)` for a truncated exponential, `(0, shift, ∞)` plus a
//! draw of the exponential stages for Erlang, hypoexponential and shifted
//! times.
//!
//! Size: one concern, the episode engine: the instruction set (`Op`, `Instr`), the
//! scratch state and `Program::episode`'s loop share private layouts tuned for
//! speed (issue 30), so they stay in one file; about 280 lines are comments
//! and 100 are tests.

use rand::Rng;
use rand_distr::{Distribution, Exp1};

use super::stats::Raw;
use crate::tree::{same_instant, Decorator, Duration, FlowNext, NodeId, NodeKind, Stages, Tree};

/// Outcomes compare the top 53 bits of a `u64` draw with `round(ps · 2^53)`.
const ONE53: f64 = (1u64 << 53) as f64;

/// A leaf, ready to sample. Index 0 of each pair is Failure, 1 Success.
#[derive(Debug, Clone, PartialEq)]
struct Leaf {
    /// Success iff `draw >> 11 < thr` (`thr = 2^53` always succeeds).
    thr: u64,
    /// Whether either duration needs an `Exp(1)` draw.
    random: bool,
    a: [f64; 2],
    b: [f64; 2],
    c: [f64; 2],
    /// The exponential stages added to `b` (Erlang, hypoexponential and
    /// shifted times; boxed so that the common leaves stay small).
    stages: Option<Box<[Option<Stages>; 2]>>,
}

impl Leaf {
    fn new(ps: f64, success: Option<Duration>, failure: Option<Duration>) -> Leaf {
        // (a, b, c) of one outcome; an impossible outcome gets zeros.
        let abc = |d: Option<Duration>| match d {
            None => (0.0, 0.0, f64::INFINITY),
            Some(Duration::Fixed { time }) => (0.0, time, f64::INFINITY),
            Some(Duration::Exponential { rate }) => (1.0 / rate, 0.0, f64::INFINITY),
            Some(Duration::TruncatedExponential { rate, cap }) => (1.0 / rate, 0.0, cap),
            Some(Duration::PhaseType { shift, .. }) => (0.0, shift, f64::INFINITY),
        };
        let stages = |d: Option<Duration>| match d {
            Some(Duration::PhaseType { stages, .. }) => Some(*stages),
            _ => None,
        };
        let (f, s) = (abc(failure), abc(success));
        let st = [stages(failure), stages(success)];
        Leaf {
            thr: (ps * ONE53).round().clamp(0.0, ONE53) as u64,
            random: f.0 != 0.0 || s.0 != 0.0,
            a: [f.0, s.0],
            b: [f.1, s.1],
            c: [f.2, s.2],
            stages: st.iter().any(Option::is_some).then(|| Box::new(st)),
        }
    }

    /// A leaf that returns `ok` at time 0.
    fn constant(ok: bool) -> Leaf {
        Leaf::new(if ok { 1.0 } else { 0.0 }, None, None)
    }

    #[inline(always)]
    fn run<R: Rng>(&self, rng: &mut R) -> (bool, f64) {
        let ok = (rng.next_u64() >> 11) < self.thr;
        let e: f64 = if self.random { Exp1.sample(rng) } else { 0.0 };
        let i = ok as usize;
        let (mut t, cap) = (e * self.a[i] + self.b[i], self.c[i]);
        if let Some(st) = &self.stages {
            if let Some(s) = &st[i] {
                t += s.sample(rng);
            }
        }
        // Not `f64::min`: no NaN can occur, and this compiles to one `minsd`.
        (ok, if t < cap { t } else { cap })
    }
}

/// One compiled node. `first..end` index [`Program::kids`] for control
/// nodes, [`Program::leaves`] for the `*Leaves` forms.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Op {
    Leaf(u32),
    /// Returns this outcome at once, drawing nothing (recording programs:
    /// an empty Sequence / Fallback spliced into one of its kind).
    Const(bool),
    /// Recording programs: a chainable subtree ([`Op::Chain`]) as nested
    /// ops, run by [`Program::acc`].
    Acc {
        inner: u32,
    },
    /// A subtree of Sequences, Fallbacks, Inverters, ForceSuccess /
    /// ForceFailure and leaves, flattened: [`Program::code`] from `entry`.
    Chain {
        entry: u32,
    },
    SeqLeaves {
        first: u32,
        end: u32,
    },
    FbLeaves {
        first: u32,
        end: u32,
    },
    Sequence {
        first: u32,
        end: u32,
    },
    Fallback {
        first: u32,
        end: u32,
    },
    Parallel {
        first: u32,
        end: u32,
        m: u32,
        f: u32,
    },
    Decorator {
        child: u32,
        kind: DecoratorOp,
        n: u32,
    },
    /// A loop whose child can never end it: the run never returns.
    Never,
    /// A flow: its states are `Program::steps[first..end]`, state 0 first.
    Flow {
        first: u32,
        end: u32,
    },
    /// Nav2 PipelineSequence; `modes[first..end - 1]` (same offsets as the
    /// children in `kids`) say what re-ticking each earlier child does.
    Pipeline {
        first: u32,
        end: u32,
    },
    /// BT.CPP SequenceWithMemory; its index is `Scratch::rr[slot]`.
    /// `halted`: a Parallel or PipelineSequence above it may halt it (its
    /// index changes are journaled, [`Journal`]); `resets`: a halt sets
    /// the index to 0 (v3's SequenceStar; v4 keeps the running child's).
    SeqMemory {
        first: u32,
        end: u32,
        slot: u32,
        halted: bool,
        resets: bool,
    },
    /// Nav2 RoundRobin; its index is `Scratch::rr[slot]` (`halted` as for
    /// [`Op::SeqMemory`]; Nav2's halt sets the index to 0).
    RoundRobin {
        first: u32,
        end: u32,
        wrap: bool,
        slot: u32,
        halted: bool,
    },
}

/// What a PipelineSequence does with a child that has returned Success
/// while a later child runs (`tree::nav2::Retick`, compiled).
#[derive(Debug, Clone, Copy, PartialEq)]
enum Mode {
    /// Nothing (placeholder for the last child too).
    Inert,
    /// Runs `op` again `first` s after the child's first Success, then
    /// `period` s after each Success (0: back to back), until a run fails.
    Again {
        op: u32,
        period: f64,
        first: f64,
        /// Whether a run of `op` can fail at all (else, while the current
        /// child never returns, the re-runs go on forever: not run).
        can_fail: bool,
    },
    /// Fails at the next tick (SingleTrigger).
    Fail,
}

/// An earlier pipeline child being re-run: when its next run starts, and
/// when a run failed (∞ while none has). `strict`: the failure happened in
/// zero time at the very instant the child first succeeded, i.e. one tick
/// after the later children were ticked at that instant.
#[derive(Debug, Clone, Copy)]
struct Rerun {
    op: u32,
    can_fail: bool,
    period: f64,
    next: f64,
    fail_at: f64,
    strict: bool,
    since: f64,
}

/// One state of a flow: run op `child`, then go to `next[ok as usize]`
/// (a state index relative to the flow's first, or [`FLOW_SUCCESS`] /
/// [`FLOW_FAILURE`]).
#[derive(Debug, Clone, Copy, PartialEq)]
struct Step {
    child: u32,
    next: [u32; 2],
}

const FLOW_SUCCESS: u32 = u32::MAX - 1;
const FLOW_FAILURE: u32 = u32::MAX;

/// One leaf of an [`Op::Chain`]: run `leaves[leaf]`, then go to the
/// instruction `next[ok as usize]`, or return Success ([`FLOW_SUCCESS`]) or
/// Failure ([`FLOW_FAILURE`]) with the time so far.
///
/// A subtree of Sequences and Fallbacks over leaves is an automaton: which
/// leaf runs next depends only on the last leaf and its outcome, and the
/// subtree's duration is the sum of the leaves run. So an episode of it is
/// one loop over instructions (no recursion, no dispatch on node kinds),
/// drawing the same numbers in the same order as the nested ops would.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Instr {
    leaf: u32,
    next: [u32; 2],
}

/// [`Instr`] with its leaf's parameters inline (one 64-byte line, no
/// indirection), run by [`Program::run_chain`]: the same draws, the same
/// arithmetic, so the same runs to the last bit.
#[derive(Debug, Clone, Copy, PartialEq)]
#[repr(C, align(64))]
struct Fast {
    /// [`Leaf::thr`] (bits 0..=53), with [`NO_DRAW`] and [`STAGES`].
    thr: u64,
    a: [f64; 2],
    b: [f64; 2],
    c: [f64; 2],
    next: [u32; 2],
}

/// [`Fast::thr`] flag: the leaf draws no `Exp(1)` ([`Leaf::random`] false).
const NO_DRAW: u64 = 1 << 63;
/// [`Fast::thr`] flag: the leaf has exponential stages: run by
/// [`Leaf::run`] (the [`Instr`] at the same index names it).
const STAGES: u64 = 1 << 62;

impl Fast {
    fn new(leaf: &Leaf, next: [u32; 2]) -> Fast {
        let mut thr = leaf.thr;
        if !leaf.random {
            thr |= NO_DRAW;
        }
        if leaf.stages.is_some() {
            thr |= STAGES;
        }
        Fast {
            thr,
            a: leaf.a,
            b: leaf.b,
            c: leaf.c,
            next,
        }
    }
}

/// What a decorator does with its child's runs.
#[derive(Debug, Clone, Copy, PartialEq)]
enum DecoratorOp {
    Invert,
    Force(bool),
    Retry,
    Repeat,
}

/// Per-thread work space for Parallel nodes: stacks of child finishing times.
#[derive(Debug, Default)]
pub(crate) struct Scratch {
    succ: Vec<f64>,
    fail: Vec<f64>,
    /// `(success, time)` of each child in child order (Parallels with an
    /// independent failure threshold, whose ties are replayed).
    order: Vec<(bool, f64)>,
    /// Index of each RoundRobin and SequenceWithMemory slot (0 at the start
    /// of every episode, without clearing: [`Slots`]).
    rr: Slots,
    /// Earlier children of the PipelineSequences being run.
    reruns: Vec<Rerun>,
    /// Index changes of the nodes a halt may reach ([`Journal`]).
    journal: Vec<Journal>,
    /// Parallels and PipelineSequences being run (the journal is kept
    /// while one is).
    halters: u32,
    /// Per node of a recording program (by offset from its root node).
    rec: Vec<Record>,
}

/// The first runs of one node in the episodes of a recording program.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct Record {
    /// The episode of the last record.
    seen: u32,
    /// Episodes that ran the node (also runs that never returned).
    pub(crate) visits: u64,
    /// Durations of its failed and successful first runs.
    pub(crate) raw: [Raw; 2],
}

impl Scratch {
    /// The records of a recording program, by node offset from its root
    /// (zeroed).
    pub(crate) fn take_records(&mut self) -> Vec<Record> {
        let fresh = vec![Record::default(); self.rec.len()];
        std::mem::replace(&mut self.rec, fresh)
    }
}

/// The index slots of RoundRobin and SequenceWithMemory nodes: each reads 0
/// at the start of an episode. A slot written in an earlier episode is
/// stale (its stamp is not the current episode's) and reads 0, so starting
/// an episode costs O(1) whatever the number of slots: per-episode work is
/// proportional to the nodes the episode visits.
#[derive(Debug, Default)]
pub(crate) struct Slots {
    value: Vec<u32>,
    /// The episode that last wrote each slot.
    stamp: Vec<u32>,
    /// The current episode (≥ 1; stamps start at 0).
    epoch: u32,
}

impl Slots {
    fn new(n: usize) -> Slots {
        Slots {
            value: vec![0; n],
            stamp: vec![0; n],
            epoch: 1,
        }
    }

    /// Starts an episode: every slot reads 0.
    #[inline(always)]
    fn new_episode(&mut self) {
        self.epoch = self.epoch.wrapping_add(1);
        if self.epoch == 0 {
            // after 2^32 episodes on one scratch: stamps could repeat
            self.stamp.fill(0);
            self.epoch = 1;
        }
    }

    #[inline(always)]
    fn get(&self, slot: u32) -> u32 {
        let i = slot as usize;
        if self.stamp[i] == self.epoch {
            self.value[i]
        } else {
            0
        }
    }

    /// Sets a slot; its previous value.
    #[inline(always)]
    fn set(&mut self, slot: u32, v: u32) -> u32 {
        let old = self.get(slot);
        let i = slot as usize;
        self.value[i] = v;
        self.stamp[i] = self.epoch;
        old
    }
}

/// What a halt needs to know of an index slot's past within one episode.
///
/// The episode engine runs a halted child to its end (its draws decide
/// nothing after the halt), so a node's index may have moved on past the
/// instant its Parallel or PipelineSequence returned. Where that index is
/// read again later in the episode (a retry, a RecoveryNode's next
/// attempt), the slot must hold what the halt left: the index as it was at
/// that instant, then the node's own halt (Nav2's RoundRobin: 0; BT.CPP
/// v4's SequenceWithMemory keeps the running child's index, v3's
/// SequenceStar resets it to 0). The journal records each change with its
/// (episode) time, and each run of such a node with its interval; when a
/// halter returns at `h`, the changes after `h` are undone (in reverse
/// order) and the nodes running at `h` are halted.
#[derive(Debug, Clone, Copy)]
enum Journal {
    /// `rr[slot]` was `old` until instant `at`.
    Set { slot: u32, old: u32, at: f64 },
    /// A node with index slot `slot` ran from `from` to `to` (∞: never
    /// returned); `resets`: its halt sets the index to 0.
    Run {
        slot: u32,
        from: f64,
        to: f64,
        resets: bool,
    },
}

/// A subtree compiled for fast episodes; its root is `ops[root]`.
#[derive(Debug, Clone)]
pub(crate) struct Program {
    ops: Vec<Op>,
    kids: Vec<u32>,
    leaves: Vec<Leaf>,
    steps: Vec<Step>,
    /// The instructions of the [`Op::Chain`]s.
    code: Vec<Instr>,
    /// `code` with the leaves inline ([`Fast`]), at the same indices.
    fast: Vec<Fast>,
    root: u32,
    /// Total number of children of Parallel nodes (bounds the scratch stacks).
    parallel_kids: usize,
    /// Re-tick modes of pipeline children, at the children's offsets in
    /// `kids` (other offsets unused).
    modes: Vec<Mode>,
    /// RoundRobin slots of the tree, in order of first appearance.
    slots: Vec<usize>,
    /// Total number of children of pipelines (bounds `Scratch::reruns`).
    pipeline_kids: usize,
    /// Parallels and PipelineSequences around the node being compiled.
    halters: u32,
    /// `(can succeed, can fail)` of each tree node ([`super::outcomes`]),
    /// shared by the programs of one simulation.
    can: std::sync::Arc<Vec<(bool, bool)>>,
    /// A recording program ([`Program::recording`]): every tree node that
    /// is run has an op of its own, `node_of[op]` (its offset from the
    /// program's root node; [`NO_NODE`] for none).
    record: bool,
    node_of: Vec<u32>,
    /// The tree node of the program's root.
    base: usize,
    /// Nodes in the subtree.
    nodes: usize,
    /// Compiling inside an [`Op::Acc`].
    in_chain: bool,
}

/// `Program::node_of` of an op that is no tree node's own.
const NO_NODE: u32 = u32::MAX;

/// The kind of control node a child may be spliced into.
#[derive(Clone, Copy, PartialEq)]
enum Chain {
    Sequence,
    Fallback,
}

impl Program {
    /// Compiles the subtree of `tree` rooted at `id`.
    #[cfg(test)]
    pub(crate) fn new(tree: &Tree, id: NodeId) -> Program {
        Program::with_outcomes(tree, id, std::sync::Arc::new(super::outcomes(tree, id)))
    }

    /// Compiles the subtree of `tree` rooted at `id`, given `can`, the
    /// [`super::outcomes`] of a subtree holding it.
    pub(crate) fn with_outcomes(
        tree: &Tree,
        id: NodeId,
        can: std::sync::Arc<Vec<(bool, bool)>>,
    ) -> Program {
        Program::build(tree, id, can, false)
    }

    /// Compiles the subtree rooted at `id` as a *recording* program: its
    /// episodes draw exactly the random numbers of [`Program::with_outcomes`]'s
    /// and return the same runs, and
    /// [`episode_recording`](Program::episode_recording) also records the
    /// first run, in each episode, of every node of the subtree. Neutral
    /// conditions are still dropped (they are never run: no record), but
    /// nothing is spliced and leaves are not grouped, so that every other
    /// node runs as an op of its own.
    pub(crate) fn recording(
        tree: &Tree,
        id: NodeId,
        can: std::sync::Arc<Vec<(bool, bool)>>,
    ) -> Program {
        Program::build(tree, id, can, true)
    }

    fn build(
        tree: &Tree,
        id: NodeId,
        can: std::sync::Arc<Vec<(bool, bool)>>,
        record: bool,
    ) -> Program {
        let mut p = Program {
            ops: Vec::new(),
            kids: Vec::new(),
            leaves: Vec::new(),
            steps: Vec::new(),
            code: Vec::new(),
            fast: Vec::new(),
            root: 0,
            parallel_kids: 0,
            modes: Vec::new(),
            slots: Vec::new(),
            pipeline_kids: 0,
            halters: 0,
            can,
            record,
            node_of: Vec::new(),
            base: id,
            nodes: tree.subtree(id).len(),
            in_chain: false,
        };
        p.root = p.compile(tree, id);
        p
    }

    fn push(&mut self, op: Op) -> u32 {
        self.ops.push(op);
        (self.ops.len() - 1) as u32
    }

    fn push_leaf(&mut self, leaf: Leaf) -> u32 {
        self.leaves.push(leaf);
        let i = (self.leaves.len() - 1) as u32;
        self.push(Op::Leaf(i))
    }

    /// Children of a Sequence/Fallback after dropping neutral conditions and
    /// (unless `keep`) splicing same-kind children, in execution order.
    fn chain_children(
        tree: &Tree,
        chain: Chain,
        children: &[NodeId],
        keep: bool,
        out: &mut Vec<NodeId>,
    ) {
        for &c in children {
            match (&tree.nodes[c].kind, chain) {
                (NodeKind::Condition { ps }, Chain::Sequence) if *ps == 1.0 => {}
                (NodeKind::Condition { ps }, Chain::Fallback) if *ps == 0.0 => {}
                (NodeKind::Sequence { children }, Chain::Sequence)
                | (NodeKind::Fallback { children }, Chain::Fallback)
                    if !keep =>
                {
                    Self::chain_children(tree, chain, children, keep, out)
                }
                _ => out.push(c),
            }
        }
    }

    /// The scratch index of a tree's index slot.
    fn slot(&mut self, slot: usize) -> u32 {
        (match self.slots.iter().position(|&s| s == slot) {
            Some(i) => i,
            None => {
                self.slots.push(slot);
                self.slots.len() - 1
            }
        }) as u32
    }

    fn compile(&mut self, tree: &Tree, id: NodeId) -> u32 {
        let op = self.compile_node(tree, id);
        if self.record {
            self.node_of.resize(self.ops.len(), NO_NODE);
            self.node_of[op as usize] = (id - self.base) as u32;
        }
        op
    }

    fn compile_node(&mut self, tree: &Tree, id: NodeId) -> u32 {
        if !self.record
            && !matches!(
                tree.nodes[id].kind,
                NodeKind::Action(_) | NodeKind::Condition { .. }
            )
            && Self::chainable(tree, id)
        {
            // (an empty Sequence or Fallback is a constant leaf: never empty)
            let entry = self.chain(tree, id, FLOW_SUCCESS, FLOW_FAILURE);
            return self.push(Op::Chain { entry });
        }
        if self.record && !self.in_chain && Self::chainable(tree, id) {
            // the recording program runs what the other compiles to a chain
            // as nested ops summing the leaves' times in the same order
            // ([`Program::acc`]): the same runs to the last bit
            self.in_chain = true;
            let inner = self.compile_node(tree, id);
            self.in_chain = false;
            if matches!(
                tree.nodes[id].kind,
                NodeKind::Action(_) | NodeKind::Condition { .. }
            ) {
                return inner;
            }
            return self.push(Op::Acc { inner });
        }
        let (chain, children) = match &tree.nodes[id].kind {
            NodeKind::Action(a) => return self.push_leaf(Leaf::new(a.ps, a.success, a.failure)),
            NodeKind::Condition { ps } => return self.push_leaf(Leaf::new(*ps, None, None)),
            NodeKind::Parallel {
                success_threshold,
                failure_threshold,
                children,
            } => {
                self.halters += 1;
                let ids: Vec<u32> = children.iter().map(|&c| self.compile(tree, c)).collect();
                self.halters -= 1;
                self.parallel_kids += ids.len();
                let first = self.kids.len() as u32;
                self.kids.extend(ids);
                let end = self.kids.len() as u32;
                let m = *success_threshold as u32;
                let f = *failure_threshold as u32;
                return self.push(Op::Parallel { first, end, m, f });
            }
            NodeKind::Decorator { decorator, child } => {
                // a loop whose child cannot end it never returns
                if self.can[id] == (false, false)
                    && matches!(decorator, Decorator::UntilFailure | Decorator::UntilSuccess)
                {
                    return self.push(Op::Never);
                }
                let child = self.compile(tree, *child);
                let (kind, n) = match decorator.as_primitive() {
                    Decorator::Inverter => (DecoratorOp::Invert, 1),
                    Decorator::ForceSuccess => (DecoratorOp::Force(true), 1),
                    Decorator::ForceFailure => (DecoratorOp::Force(false), 1),
                    Decorator::Retry { attempts } => (DecoratorOp::Retry, attempts as u32),
                    Decorator::Repeat { times } => (DecoratorOp::Repeat, times as u32),
                    // without a bound (a loop whose child cannot end it is
                    // `Op::Never`): ends with probability 1
                    Decorator::UntilSuccess => (DecoratorOp::Retry, u32::MAX),
                    Decorator::UntilFailure => (DecoratorOp::Repeat, u32::MAX),
                    Decorator::Rate { .. } | Decorator::SingleTrigger => {
                        unreachable!("as_primitive maps Nav2 decorators to repeat 1")
                    }
                };
                return self.push(Op::Decorator { child, kind, n });
            }
            NodeKind::Pipeline { children } => return self.pipeline(tree, children),
            NodeKind::SequenceWithMemory {
                children,
                slot,
                halt_resets,
            } => {
                let ids: Vec<u32> = children.iter().map(|&c| self.compile(tree, c)).collect();
                let (first, end) = self.kids_range(ids);
                let slot = self.slot(*slot);
                return self.push(Op::SeqMemory {
                    first,
                    end,
                    slot,
                    halted: self.halters > 0,
                    resets: *halt_resets,
                });
            }
            NodeKind::RoundRobin {
                children,
                wrap,
                slot,
            } => {
                let ids: Vec<u32> = children.iter().map(|&c| self.compile(tree, c)).collect();
                let (first, end) = self.kids_range(ids);
                let slot = self.slot(*slot);
                let wrap = *wrap;
                return self.push(Op::RoundRobin {
                    first,
                    end,
                    wrap,
                    slot,
                    halted: self.halters > 0,
                });
            }
            NodeKind::Flow(flow) => {
                let ops: Vec<u32> = flow
                    .children
                    .iter()
                    .map(|&c| self.compile(tree, c))
                    .collect();
                let code = |n: FlowNext| match n {
                    FlowNext::State(j) => j as u32,
                    FlowNext::Success => FLOW_SUCCESS,
                    FlowNext::Failure => FLOW_FAILURE,
                };
                let first = self.steps.len() as u32;
                self.steps.extend(flow.states.iter().map(|s| Step {
                    child: ops[s.child],
                    next: [code(s.on_failure), code(s.on_success)],
                }));
                let end = self.steps.len() as u32;
                return self.push(Op::Flow { first, end });
            }
            NodeKind::Sequence { children } => (Chain::Sequence, children),
            NodeKind::Fallback { children } => (Chain::Fallback, children),
        };
        let mut list = Vec::new();
        Self::chain_children(tree, chain, children, self.record, &mut list);
        if self.record {
            // as spliced into a same-kind parent, an empty Sequence (Fallback)
            // adds nothing and draws nothing; one left empty at the top of
            // the splicing is a constant leaf (which draws)
            let mut spliced = Vec::new();
            Self::chain_children(tree, chain, children, false, &mut spliced);
            if spliced.is_empty() {
                let kind_of = |n: NodeId| match tree.nodes[n].kind {
                    NodeKind::Sequence { .. } => Some(Chain::Sequence),
                    NodeKind::Fallback { .. } => Some(Chain::Fallback),
                    _ => None,
                };
                let inside =
                    id != self.base && tree.nodes[id].parent.and_then(kind_of) == Some(chain);
                let ok = chain == Chain::Sequence;
                return if inside {
                    self.push(Op::Const(ok))
                } else {
                    self.push_leaf(Leaf::constant(ok))
                };
            }
        }
        match list[..] {
            [] => return self.push_leaf(Leaf::constant(chain == Chain::Sequence)),
            [only] if !self.record => return self.compile(tree, only),
            _ => {}
        }
        let leaf = |c: &NodeId| match &tree.nodes[*c].kind {
            NodeKind::Action(a) => Some(Leaf::new(a.ps, a.success, a.failure)),
            NodeKind::Condition { ps } => Some(Leaf::new(*ps, None, None)),
            _ => None,
        };
        let leaves = if self.record {
            None
        } else {
            list.iter().map(leaf).collect::<Option<Vec<Leaf>>>()
        };
        if let Some(leaves) = leaves {
            let first = self.leaves.len() as u32;
            self.leaves.extend(leaves);
            let end = self.leaves.len() as u32;
            return self.push(match chain {
                Chain::Sequence => Op::SeqLeaves { first, end },
                Chain::Fallback => Op::FbLeaves { first, end },
            });
        }
        let ids: Vec<u32> = list.iter().map(|&c| self.compile(tree, c)).collect();
        let first = self.kids.len() as u32;
        self.kids.extend(ids);
        let end = self.kids.len() as u32;
        self.push(match chain {
            Chain::Sequence => Op::Sequence { first, end },
            Chain::Fallback => Op::Fallback { first, end },
        })
    }

    /// Whether the subtree at `id` is only Sequences, Fallbacks, Inverters,
    /// ForceSuccess / ForceFailure and leaves ([`Instr`]).
    fn chainable(tree: &Tree, id: NodeId) -> bool {
        tree.subtree(id).all(|i| match &tree.nodes[i].kind {
            NodeKind::Action(_)
            | NodeKind::Condition { .. }
            | NodeKind::Sequence { .. }
            | NodeKind::Fallback { .. } => true,
            NodeKind::Decorator { decorator, .. } => matches!(
                decorator,
                Decorator::Inverter | Decorator::ForceSuccess | Decorator::ForceFailure
            ),
            _ => false,
        })
    }

    /// Flattens the chainable subtree at `id` ([`Instr`]), whose run goes on
    /// at `on_s` after a Success and `on_f` after a Failure (an
    /// instruction, or [`FLOW_SUCCESS`] / [`FLOW_FAILURE`]); its entry.
    /// The rewrites of [`Program::chain_children`] are kept exactly (same
    /// draws): a neutral condition in a Sequence (Fallback) is dropped, an
    /// empty Sequence or Fallback draws one number as a constant leaf.
    fn chain(&mut self, tree: &Tree, id: NodeId, on_s: u32, on_f: u32) -> u32 {
        let leaf = |s: &mut Self, leaf: Leaf| {
            s.fast.push(Fast::new(&leaf, [on_f, on_s]));
            s.leaves.push(leaf);
            s.code.push(Instr {
                leaf: (s.leaves.len() - 1) as u32,
                next: [on_f, on_s],
            });
            (s.code.len() - 1) as u32
        };
        match &tree.nodes[id].kind {
            NodeKind::Action(a) => leaf(self, Leaf::new(a.ps, a.success, a.failure)),
            NodeKind::Condition { ps } => leaf(self, Leaf::new(*ps, None, None)),
            NodeKind::Decorator { decorator, child } => match decorator {
                Decorator::Inverter => self.chain(tree, *child, on_f, on_s),
                Decorator::ForceSuccess => self.chain(tree, *child, on_s, on_s),
                _ => self.chain(tree, *child, on_f, on_f),
            },
            NodeKind::Sequence { children } | NodeKind::Fallback { children } => {
                let kind = if matches!(tree.nodes[id].kind, NodeKind::Sequence { .. }) {
                    Chain::Sequence
                } else {
                    Chain::Fallback
                };
                // the children after the rewrites (spliced into a
                // same-kind parent, they were dropped there already)
                let mut list = Vec::new();
                Self::chain_children(tree, kind, children, false, &mut list);
                if list.is_empty() {
                    return leaf(self, Leaf::constant(kind == Chain::Sequence));
                }
                // built from the last child back: each child goes on to the
                // next on its "keep going" outcome
                let mut next = if kind == Chain::Sequence { on_s } else { on_f };
                for &c in list.iter().rev() {
                    next = match kind {
                        Chain::Sequence => self.chain(tree, c, next, on_f),
                        Chain::Fallback => self.chain(tree, c, on_s, next),
                    };
                }
                next
            }
            _ => unreachable!("chainable subtrees only"),
        }
    }

    /// Appends `ids` to `kids`; their range.
    fn kids_range(&mut self, ids: Vec<u32>) -> (u32, u32) {
        let first = self.kids.len() as u32;
        self.kids.extend(ids);
        (first, self.kids.len() as u32)
    }

    /// A PipelineSequence: its children and what re-ticking each does.
    fn pipeline(&mut self, tree: &Tree, children: &[NodeId]) -> u32 {
        use crate::tree::nav2::{retick, Retick};
        self.halters += 1;
        let ids: Vec<u32> = children.iter().map(|&c| self.compile(tree, c)).collect();
        self.halters -= 1;
        let modes: Vec<Mode> = children
            .iter()
            .zip(&ids)
            .enumerate()
            .map(|(i, (&c, &op))| {
                if i + 1 == children.len() {
                    return Mode::Inert;
                }
                match retick(tree, c) {
                    Retick::Inert => Mode::Inert,
                    Retick::Restart => Mode::Again {
                        op,
                        period: 0.0,
                        first: 0.0,
                        can_fail: self.can[c].1,
                    },
                    // the RateController's child, run afresh each period
                    // (a SpeedController's first wait differs)
                    Retick::Rate(period) => {
                        let first = match tree.nodes[c].kind {
                            NodeKind::Decorator {
                                decorator: Decorator::Rate { first, .. },
                                ..
                            } => first,
                            _ => period,
                        };
                        let can_fail = tree.nodes[c]
                            .kind
                            .children()
                            .first()
                            .is_some_and(|&k| self.can[k].1);
                        match self.ops[op as usize] {
                            Op::Decorator { child, .. } => Mode::Again {
                                op: child,
                                period,
                                first,
                                can_fail,
                            },
                            _ => unreachable!("a RateController compiles to a decorator"),
                        }
                    }
                    Retick::Fail => Mode::Fail,
                }
            })
            .collect();
        self.pipeline_kids += ids.len();
        let (first, end) = self.kids_range(ids);
        self.modes.resize(end as usize, Mode::Inert);
        self.modes[first as usize..end as usize].copy_from_slice(&modes);
        self.push(Op::Pipeline { first, end })
    }

    /// A scratch space big enough for any episode of this program.
    pub(crate) fn scratch(&self) -> Scratch {
        Scratch {
            succ: Vec::with_capacity(self.parallel_kids),
            fail: Vec::with_capacity(self.parallel_kids),
            order: Vec::with_capacity(self.parallel_kids),
            rr: Slots::new(self.slots.len()),
            rec: if self.record {
                vec![Record::default(); self.nodes]
            } else {
                Vec::new()
            },
            reruns: Vec::with_capacity(self.pipeline_kids),
            journal: Vec::new(),
            halters: 0,
        }
    }

    /// Runs the subtree once, from time 0. Returns (`true` for Success,
    /// duration); a run that never returns (it reached a loop whose child
    /// can never end it) is `(false, ∞)`.
    #[inline]
    pub(crate) fn episode<R: Rng>(&self, rng: &mut R, scratch: &mut Scratch) -> (bool, f64) {
        // every run starts with the RoundRobins at their first child: the
        // slots written in the last episode read 0 again, in O(1)
        scratch.rr.new_episode();
        scratch.journal.clear();
        scratch.halters = 0;
        self.run::<R, false>(self.root, 0.0, rng, scratch)
    }

    /// [`Program::episode`] of a [recording](Program::recording) program:
    /// the same run, and the first run of each node of the subtree in this
    /// episode added to [`Scratch::records`].
    #[inline]
    pub(crate) fn episode_recording<R: Rng>(
        &self,
        rng: &mut R,
        scratch: &mut Scratch,
    ) -> (bool, f64) {
        debug_assert!(self.record);
        scratch.rr.new_episode();
        if scratch.rr.epoch == 1 {
            // the stamps started again (after 2^32 episodes)
            scratch.rec.iter_mut().for_each(|r| r.seen = 0);
        }
        scratch.journal.clear();
        scratch.halters = 0;
        self.run::<R, true>(self.root, 0.0, rng, scratch)
    }

    /// The entry of the program's [`Op::Chain`] if the whole program is one
    /// (a tree of Sequences, Fallbacks, Inverters, ForceSuccess /
    /// ForceFailure and leaves): then [`Program::run_chain`] from it is an
    /// episode, without the state an [`Program::episode`] resets.
    pub(crate) fn root_chain(&self) -> Option<u32> {
        match self.ops[self.root as usize] {
            Op::Chain { entry } if !self.record => Some(entry),
            _ => None,
        }
    }

    /// Runs the [`Op::Chain`] from instruction `entry`: one loop over
    /// [`Fast`] instructions adding the leaves' times. Inlined into a
    /// caller's loop of episodes, the generator's state stays in registers.
    #[inline(always)]
    pub(crate) fn run_chain<R: Rng>(&self, entry: u32, rng: &mut R) -> (bool, f64) {
        let (mut pc, mut t) = (entry, 0.0);
        loop {
            let ins = &self.fast[pc as usize];
            let d;
            let ok;
            if ins.thr & STAGES == 0 {
                ok = (rng.next_u64() >> 11) < (ins.thr & !NO_DRAW);
                let e: f64 = if ins.thr & NO_DRAW == 0 {
                    Exp1.sample(rng)
                } else {
                    0.0
                };
                let i = ok as usize;
                let (x, cap) = (e * ins.a[i] + ins.b[i], ins.c[i]);
                d = if x < cap { x } else { cap };
            } else {
                (ok, d) = self.leaves[self.code[pc as usize].leaf as usize].run(rng);
            }
            t += d;
            pc = ins.next[ok as usize];
            if pc >= FLOW_SUCCESS {
                return (pc == FLOW_SUCCESS, t);
            }
        }
    }

    /// Runs op `op`, started at episode time `at` (the journal's clock);
    /// with `REC`, records the run if it is its node's first this episode.
    #[inline(always)]
    fn run<R: Rng, const REC: bool>(
        &self,
        op: u32,
        at: f64,
        rng: &mut R,
        scratch: &mut Scratch,
    ) -> (bool, f64) {
        let r = self.exec::<R, REC>(op, at, rng, scratch);
        if REC {
            self.record(op, r, scratch);
        }
        r
    }

    /// Records run `r` of op `op` if it is its node's first this episode.
    #[inline(never)]
    fn record(&self, op: u32, (ok, t): (bool, f64), scratch: &mut Scratch) {
        let node = self.node_of[op as usize];
        if node == NO_NODE {
            return;
        }
        let epoch = scratch.rr.epoch;
        let rec = &mut scratch.rec[node as usize];
        if rec.seen == epoch {
            return;
        }
        rec.seen = epoch;
        rec.visits += 1;
        // a run that never returns (t = ∞) counts in neither
        if t.is_finite() {
            rec.raw[ok as usize].push(t);
        }
    }

    /// Runs op `op` of a chainable subtree started when the enclosing
    /// [`Op::Acc`] had run for `t0`; returns its outcome and the enclosing
    /// op's time when it returns. The leaves' times are added one by one to
    /// the running total, in the order an [`Op::Chain`] adds them, so the
    /// totals are the chain's to the last bit. With `REC` each node's run is
    /// recorded, its duration the difference of the totals.
    fn acc<R: Rng, const REC: bool>(
        &self,
        op: u32,
        t0: f64,
        rng: &mut R,
        scratch: &mut Scratch,
    ) -> (bool, f64) {
        let (ok, t) = match self.ops[op as usize] {
            Op::Leaf(i) => {
                let (ok, d) = self.leaves[i as usize].run(rng);
                (ok, t0 + d)
            }
            Op::Const(ok) => (ok, t0),
            Op::Sequence { first, end } | Op::Fallback { first, end } => {
                let keep_going = matches!(self.ops[op as usize], Op::Sequence { .. });
                let mut t = t0;
                let mut ok = keep_going;
                for &c in &self.kids[first as usize..end as usize] {
                    (ok, t) = self.acc::<R, REC>(c, t, rng, scratch);
                    if ok != keep_going {
                        break;
                    }
                }
                (ok, t)
            }
            Op::Decorator { child, kind, .. } => {
                let (ok, t) = self.acc::<R, REC>(child, t0, rng, scratch);
                match kind {
                    DecoratorOp::Invert => (!ok, t),
                    DecoratorOp::Force(outcome) => (outcome, t),
                    _ => unreachable!("chainable decorators only"),
                }
            }
            _ => unreachable!("chainable subtrees only"),
        };
        if REC {
            self.record(op, (ok, t - t0), scratch);
        }
        (ok, t)
    }

    /// [`Program::run`] without the record.
    fn exec<R: Rng, const REC: bool>(
        &self,
        op: u32,
        at: f64,
        rng: &mut R,
        scratch: &mut Scratch,
    ) -> (bool, f64) {
        match self.ops[op as usize] {
            Op::Leaf(i) => self.leaves[i as usize].run(rng),
            Op::SeqLeaves { first, end } => {
                let mut t = 0.0;
                for leaf in &self.leaves[first as usize..end as usize] {
                    let (ok, d) = leaf.run(rng);
                    t += d;
                    if !ok {
                        return (false, t);
                    }
                }
                (true, t)
            }
            Op::FbLeaves { first, end } => {
                let mut t = 0.0;
                for leaf in &self.leaves[first as usize..end as usize] {
                    let (ok, d) = leaf.run(rng);
                    t += d;
                    if ok {
                        return (true, t);
                    }
                }
                (false, t)
            }
            Op::Sequence { first, end } => {
                let mut t = 0.0;
                for &c in &self.kids[first as usize..end as usize] {
                    let (ok, d) = self.run::<R, REC>(c, at + t, rng, scratch);
                    t += d;
                    if !ok || !d.is_finite() {
                        return (ok && d.is_finite(), t);
                    }
                }
                (true, t)
            }
            Op::Fallback { first, end } => {
                let mut t = 0.0;
                for &c in &self.kids[first as usize..end as usize] {
                    let (ok, d) = self.run::<R, REC>(c, at + t, rng, scratch);
                    t += d;
                    if ok || !d.is_finite() {
                        return (ok && d.is_finite(), t);
                    }
                }
                (false, t)
            }
            Op::Never => (false, f64::INFINITY),
            Op::Const(ok) => (ok, 0.0),
            Op::Acc { inner } => self.acc::<R, REC>(inner, 0.0, rng, scratch),
            Op::Chain { entry } => self.run_chain(entry, rng),
            Op::Parallel { first, end, m, f } => {
                self.parallel::<R, REC>(first, end, m, f, at, rng, scratch)
            }
            Op::Pipeline { first, end } => {
                self.run_pipeline::<R, REC>(first, end, at, rng, scratch)
            }
            Op::RoundRobin {
                first,
                end,
                wrap,
                slot,
                halted,
            } => {
                let kids = &self.kids[first as usize..end as usize];
                let n = kids.len() as u32;
                let mut idx = scratch.rr.get(slot);
                let mut t = 0.0;
                // the index it leaves (unchanged if it never returns)
                let (kept, mut left) = (idx, idx);
                let mut ok = false;
                for _ in 0..n {
                    let d;
                    (ok, d) = self.run::<R, REC>(kids[idx as usize], at + t, rng, scratch);
                    t += d;
                    if !d.is_finite() {
                        (ok, left) = (false, kept);
                        break;
                    }
                    idx += 1;
                    if idx == n {
                        if !wrap {
                            // Nav2 leaves its loop here, whatever the status
                            (ok, left) = (false, 0);
                            break;
                        }
                        idx = 0;
                    }
                    if ok {
                        left = idx;
                        break;
                    }
                    // all failed: halt() resets the index
                    left = 0;
                }
                if halted {
                    journal_run(scratch, slot, at, at + t, true);
                    journal_set(scratch, slot, left, at + t);
                } else {
                    scratch.rr.set(slot, left);
                }
                (ok, t)
            }
            Op::SeqMemory {
                first,
                end,
                slot,
                halted,
                resets,
            } => {
                // BT.CPP's sequence_with_memory_node.cpp: start at the kept
                // index; a Failure keeps it at the failed child, the last
                // child's Success resets it to 0
                let kids = &self.kids[first as usize..end as usize];
                let mut t = 0.0;
                let start = scratch.rr.get(slot) as usize;
                let mut result = (true, 0);
                for (i, &c) in kids.iter().enumerate().skip(start) {
                    if halted && i > start {
                        // the index while child i runs (what a halt keeps)
                        journal_set(scratch, slot, i as u32, at + t);
                    }
                    let (ok, d) = self.run::<R, REC>(c, at + t, rng, scratch);
                    t += d;
                    if !ok || !d.is_finite() {
                        result = (false, i as u32);
                        break;
                    }
                }
                if halted {
                    journal_run(scratch, slot, at, at + t, resets);
                    journal_set(scratch, slot, result.1, at + t);
                } else {
                    scratch.rr.set(slot, result.1);
                }
                (result.0, t)
            }
            Op::Flow { first, end } => {
                let steps = &self.steps[first as usize..end as usize];
                let (mut state, mut t) = (0u32, 0.0);
                loop {
                    let step = steps[state as usize];
                    let (ok, d) = self.run::<R, REC>(step.child, at + t, rng, scratch);
                    t += d;
                    if !d.is_finite() {
                        return (false, t);
                    }
                    state = step.next[ok as usize];
                    match state {
                        FLOW_SUCCESS => return (true, t),
                        FLOW_FAILURE => return (false, t),
                        _ => {}
                    }
                }
            }
            Op::Decorator { child, kind, n } => match kind {
                DecoratorOp::Invert => {
                    let (ok, d) = self.run::<R, REC>(child, at, rng, scratch);
                    (!ok && d.is_finite(), d)
                }
                DecoratorOp::Force(outcome) => {
                    let d = self.run::<R, REC>(child, at, rng, scratch).1;
                    (outcome && d.is_finite(), d)
                }
                DecoratorOp::Retry | DecoratorOp::Repeat => {
                    // retry stops at the first Success, repeat at the first Failure
                    let stop = kind == DecoratorOp::Retry;
                    let mut t = 0.0;
                    for _ in 0..n {
                        let (ok, d) = self.run::<R, REC>(child, at + t, rng, scratch);
                        t += d;
                        if !d.is_finite() {
                            return (false, t);
                        }
                        if ok == stop {
                            return (ok, t);
                        }
                    }
                    (!stop, t)
                }
            },
        }
    }

    /// A PipelineSequence: child i starts when child i − 1 first succeeds;
    /// meanwhile every earlier child that is ticked again re-runs as its
    /// [`Mode`] says. The node fails at the first Failure among the current
    /// child and the re-runs (a re-run failing at the instant a later child
    /// returns wins: earlier children are ticked first), and succeeds when
    /// the last child succeeds.
    #[inline(never)]
    fn run_pipeline<R: Rng, const REC: bool>(
        &self,
        first: u32,
        end: u32,
        at: f64,
        rng: &mut R,
        scratch: &mut Scratch,
    ) -> (bool, f64) {
        let base = scratch.reruns.len();
        let journal = scratch.journal.len();
        scratch.halters += 1;
        let mut t = 0.0;
        let last = end - 1;
        let mut result = None;
        for i in first..end {
            let (ok, d) = self.run::<R, REC>(self.kids[i as usize], at + t, rng, scratch);
            let stop = t + d;
            // the earliest failure of a re-run that comes before `stop`
            let mut fail = f64::INFINITY;
            for k in base..scratch.reruns.len() {
                let mut r = scratch.reruns[k];
                // while the current child never returns (stop = ∞), re-runs
                // that cannot fail would go on forever: they decide nothing
                let endless = !stop.is_finite() && !r.can_fail;
                while r.fail_at == f64::INFINITY && r.next <= stop && !endless {
                    let (ok, d) = self.run::<R, REC>(r.op, at + r.next, rng, scratch);
                    if !d.is_finite() {
                        // a re-run that never returns: no more re-runs
                        r.next = f64::INFINITY;
                        break;
                    }
                    if ok {
                        r.next += d + r.period;
                    } else {
                        r.fail_at = r.next + d;
                        r.strict = same_instant(r.fail_at, r.since) && d == 0.0;
                    }
                }
                scratch.reruns[k] = r;
                let before = r.fail_at < stop
                    || (same_instant(r.fail_at, stop)
                        && !(r.strict && same_instant(stop, r.since)));
                if before && r.fail_at.is_finite() {
                    fail = fail.min(r.fail_at);
                }
            }
            if fail.is_finite() {
                result = Some((false, fail));
                break;
            }
            if !ok || i == last || !stop.is_finite() {
                result = Some((ok, stop));
                break;
            }
            t = stop;
            match self.modes[i as usize] {
                Mode::Inert => {}
                Mode::Again {
                    op,
                    period,
                    first,
                    can_fail,
                } => scratch.reruns.push(Rerun {
                    op,
                    can_fail,
                    period,
                    next: t + first,
                    fail_at: f64::INFINITY,
                    strict: false,
                    since: t,
                }),
                Mode::Fail => scratch.reruns.push(Rerun {
                    op: 0,
                    can_fail: true,
                    period: 0.0,
                    next: t,
                    fail_at: t,
                    strict: true,
                    since: t,
                }),
            }
        }
        scratch.reruns.truncate(base);
        scratch.halters -= 1;
        let result = result.expect("the last child ends the loop");
        // the current child and the re-runs still running are halted
        halt_at(scratch, journal, at + result.1);
        result
    }

    /// A Parallel node. All children start at 0 and run independently, so
    /// halted children may as well be run to the end. The node fails at the
    /// F'-th failure, F' = min(F, N − M + 1) (F failures, or success no
    /// longer possible), and succeeds at the M-th success if that comes
    /// first. With the book's F = N − M + 1 the outcome vector alone decides
    /// (both thresholds cannot be met); with a smaller F the two times are
    /// compared, and when they are the same instant (within
    /// [`SAME_INSTANT`](crate::tree::SAME_INSTANT)) the returns at that instant are replayed in child
    /// order, the node returning at the first threshold met (a tick visits
    /// the children in order, as in BehaviorTree.CPP).
    #[inline(never)]
    #[allow(clippy::too_many_arguments)]
    fn parallel<R: Rng, const REC: bool>(
        &self,
        first: u32,
        end: u32,
        m: u32,
        f: u32,
        at: f64,
        rng: &mut R,
        scratch: &mut Scratch,
    ) -> (bool, f64) {
        let (s0, f0, o0) = (scratch.succ.len(), scratch.fail.len(), scratch.order.len());
        let journal = scratch.journal.len();
        scratch.halters += 1;
        let n = (end - first) as usize;
        let m = m as usize;
        let f = (f as usize).min(n - m + 1);
        let book = f == n - m + 1;
        for &c in &self.kids[first as usize..end as usize] {
            let (ok, d) = self.run::<R, REC>(c, at, rng, scratch);
            if ok {
                scratch.succ.push(d);
            } else {
                scratch.fail.push(d);
            }
            if !book {
                scratch.order.push((ok, d));
            }
        }
        let successes = scratch.succ.len() - s0;
        let failures = scratch.fail.len() - f0;
        let t_success = (successes >= m).then(|| kth_smallest(&mut scratch.succ[s0..], m - 1));
        let t_failure = (failures >= f).then(|| kth_smallest(&mut scratch.fail[f0..], f - 1));
        let result = match (t_success, t_failure) {
            (Some(ts), Some(tf)) if same_instant(ts, tf) => {
                replay_instant(&scratch.order[o0..], ts.min(tf), m, f)
            }
            (Some(ts), Some(tf)) if tf < ts => (false, tf),
            (Some(ts), _) => (true, ts),
            (None, Some(tf)) => (false, tf),
            (None, None) => unreachable!("a Parallel always reaches a threshold"),
        };
        scratch.succ.truncate(s0);
        scratch.fail.truncate(f0);
        scratch.order.truncate(o0);
        scratch.halters -= 1;
        // the children still running when it returns are halted
        halt_at(scratch, journal, at + result.1);
        // children that never return decide nothing: the node returns at
        // its thresholds' first finite time, or never (∞)
        (result.0 && result.1.is_finite(), result.1)
    }
}

/// Sets `rr[slot]` to `index` at episode time `at`, journaled while a
/// halter runs.
fn journal_set(scratch: &mut Scratch, slot: u32, index: u32, at: f64) {
    let old = scratch.rr.set(slot, index);
    if scratch.halters > 0 && old != index {
        scratch.journal.push(Journal::Set { slot, old, at });
    }
}

/// Records that the node with index slot `slot` ran from `from` to `to`.
fn journal_run(scratch: &mut Scratch, slot: u32, from: f64, to: f64, resets: bool) {
    if scratch.halters > 0 {
        scratch.journal.push(Journal::Run {
            slot,
            from,
            to,
            resets,
        });
    }
}

/// Whether instant `a` comes after instant `h` (not the same instant).
fn after(a: f64, h: f64) -> bool {
    a > h && !same_instant(a, h)
}

/// A halter that started the journal's entries from `from` on returned at
/// episode time `h` ([`Journal`]): the index changes after `h` are undone,
/// the runs that had not started by `h` forgotten, and the nodes running at
/// `h` halted (recorded at `h`, for a halter around this one). With no
/// halter around, the journal is cleared.
fn halt_at(scratch: &mut Scratch, from: usize, h: f64) {
    if scratch.journal.len() == from {
        return;
    }
    if h.is_finite() {
        let Scratch { journal, rr, .. } = scratch;
        for e in journal[from..].iter().rev() {
            if let Journal::Set { slot, old, at } = *e {
                if after(at, h) {
                    rr.set(slot, old);
                }
            }
        }
        let kept: Vec<Journal> = journal
            .drain(from..)
            .filter(|e| match *e {
                Journal::Set { at, .. } => !after(at, h),
                Journal::Run { from, .. } => !after(from, h),
            })
            .collect();
        journal.extend(kept);
        let mut halted = Vec::new();
        for e in journal[from..].iter_mut() {
            if let Journal::Run {
                slot, to, resets, ..
            } = e
            {
                if after(*to, h) {
                    *to = h;
                    if *resets {
                        halted.push(*slot);
                    }
                }
            }
        }
        for slot in halted {
            journal_set(scratch, slot, 0, h);
        }
    }
    if scratch.halters == 0 {
        scratch.journal.clear();
    }
}

/// The outcome of a Parallel whose success and failure thresholds are both
/// reached at instant `t`: the children's returns (`(success, time)` in child
/// order) before `t` count first, then those at `t` in child order until a
/// threshold is met.
fn replay_instant(returns: &[(bool, f64)], t: f64, m: usize, f: usize) -> (bool, f64) {
    let before = |want: bool| {
        returns
            .iter()
            .filter(|&&(ok, d)| ok == want && d < t && !same_instant(d, t))
            .count()
    };
    let (mut s, mut fl) = (before(true), before(false));
    for &(ok, d) in returns {
        if !same_instant(d, t) {
            continue;
        }
        if ok {
            s += 1;
        } else {
            fl += 1;
        }
        if s >= m {
            return (true, t);
        }
        if fl >= f {
            return (false, t);
        }
    }
    unreachable!("both thresholds are met by instant t")
}

/// The `k`-th smallest (0-based) of non-empty `xs`; reorders `xs`.
#[inline]
fn kth_smallest(xs: &mut [f64], k: usize) -> f64 {
    match xs.len() {
        1 => xs[0],
        2 => {
            let (a, b) = (xs[0], xs[1]);
            if k == 0 {
                a.min(b)
            } else {
                a.max(b)
            }
        }
        _ => *xs.select_nth_unstable_by(k, f64::total_cmp).1,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn thresholds() {
        assert_eq!(Leaf::constant(false).thr, 0);
        assert_eq!(Leaf::constant(true).thr, 1 << 53);
        assert_eq!(Leaf::new(0.5, None, None).thr, 1 << 52);
    }

    #[test]
    fn kth() {
        let mut v = [3.0, 1.0, 2.0, 0.5];
        assert_eq!(kth_smallest(&mut v, 1), 1.0);
        assert_eq!(kth_smallest(&mut [2.0, 1.0], 0), 1.0);
        assert_eq!(kth_smallest(&mut [2.0, 1.0], 1), 2.0);
        assert_eq!(kth_smallest(&mut [7.0], 0), 7.0);
    }

    fn compiled(yaml: &str) -> Program {
        let tree = crate::tree::parse_str(yaml, "t.yaml").unwrap();
        Program::new(&tree, 0)
    }

    #[test]
    fn rewrites() {
        // Fallback[cond ps 0, Fallback[a, b]] is one leaf loop over a, b.
        let p = compiled(
            "tree: {fallback: {children: [{condition: {ps: 0}}, {fallback: {children: [\
             {action: {ps: .5, mu: 1, nu: 1}}, {action: {ps: .5, mu: 1, nu: 1}}]}}]}}",
        );
        // (flattened: a, then b on a's Failure)
        assert_eq!(p.leaves.len(), 2);
        let Op::Chain { entry } = p.ops[p.root as usize] else {
            panic!("a chain")
        };
        let b = Instr {
            leaf: 0,
            next: [FLOW_FAILURE, FLOW_SUCCESS],
        };
        assert_eq!(
            p.code,
            vec![
                b,
                Instr {
                    leaf: 1,
                    next: [0, FLOW_SUCCESS]
                }
            ]
        );
        assert_eq!(entry, 1);
        // Sequence[cond ps 1] returns Success at 0 (drawing one number).
        let p = compiled("tree: {sequence: {children: [{condition: {ps: 1}}]}}");
        assert_eq!(p.leaves, vec![Leaf::constant(true)]);
        // A Fallback in a Sequence: the condition's Success goes on to the
        // Fallback's first child, whose Failure to its second.
        let p = compiled(
            "tree: {sequence: {children: [{condition: {ps: .5}}, {fallback: {children: [\
             {action: {ps: .5, mu: 1, nu: 1}}, {condition: {ps: .2}}]}}]}}",
        );
        let (s, f) = (FLOW_SUCCESS, FLOW_FAILURE);
        assert_eq!(
            p.code,
            vec![
                Instr {
                    leaf: 0,
                    next: [f, s]
                },
                Instr {
                    leaf: 1,
                    next: [0, s]
                },
                Instr {
                    leaf: 2,
                    next: [f, 1]
                },
            ]
        );
        assert_eq!(p.ops[p.root as usize], Op::Chain { entry: 2 });
        // Inverter(Sequence[a, b]) swaps the exits; the recording program
        // keeps one op per node.
        let p = compiled(
            "tree: {inverter: {child: {sequence: {children: [{condition: {ps: .5}}, \
             {condition: {ps: .2}}]}}}}",
        );
        assert_eq!(
            p.code,
            vec![
                Instr {
                    leaf: 0,
                    next: [s, f]
                },
                Instr {
                    leaf: 1,
                    next: [s, 0]
                }
            ]
        );
    }
}
