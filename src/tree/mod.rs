//! The tree model: what a parsed, validated Stochastic Behavior Tree is.
//!
//! A [`Tree`] is an arena of [`Node`]s in pre-order (tree order): index 0 is
//! the root and every node's children follow it. Trees are built by
//! [`parse`] from YAML (or [`xml`] from BehaviorTree.CPP XML), which validates every parameter,
//! so code downstream can rely on the invariants documented on each type.
//!
//! Size: one concern, the validated tree's types (every node kind, decorator,
//! flow and duration, with the invariants each keeps); about 220 lines are
//! comments. Reading and checking live in `parse/` and `xml/`.

mod action;
pub mod error;
mod instant;
pub(crate) mod nav2;
pub mod parse;
pub mod stages;
pub mod xml;

pub use error::{TreeError, TreeErrorKind};
pub use instant::{same_instant, SAME_INSTANT};
pub use parse::{parse_bytes, parse_file, parse_str, ParseLimits};
pub use stages::Stages;

/// Index of a node in [`Tree::nodes`].
pub type NodeId = usize;

/// A validated Stochastic Behavior Tree: read from a file (or text), then
/// immutable outside the crate ([`Tree::nodes`], [`Tree::title`]); a variant
/// with other leaf times is a new tree ([`Tree::with_action_times`]).
///
/// The same arena holds the engine's core IR ([`crate::ir::Graph`], a
/// `Tree<Op>`): `K` is what a node is, [`NodeKind`] for a tree as read.
#[derive(Debug, Clone, PartialEq)]
pub struct Tree<K = NodeKind> {
    /// Optional title (`name:` at the top of the file).
    pub(crate) title: Option<String>,
    /// Nodes in pre-order; `nodes[0]` is the root.
    pub(crate) nodes: Vec<Node<K>>,
}

/// What a node of a [`Tree`] can be: the surface kinds ([`NodeKind`]) or
/// the core IR's operators ([`crate::ir::Op`]).
pub trait Kind: Clone + std::fmt::Debug {
    /// Children of a control node; empty for leaves.
    fn children(&self) -> &[NodeId];
    /// [`Kind::children`], to renumber them.
    fn children_mut(&mut self) -> &mut [NodeId];
    /// Whether the two nodes have the same kind and parameters (their
    /// children aside).
    fn same_parameters(&self, other: &Self) -> bool;
}

/// A time given to [`Tree::with_action_times`] that is not a valid duration.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("action '{node}': its {outcome} time {what}")]
pub struct InvalidTime {
    /// The action's name.
    pub node: String,
    /// `success` or `failure`.
    pub outcome: &'static str,
    /// What is wrong.
    pub what: String,
}

/// A node of the tree.
#[derive(Debug, Clone, PartialEq)]
pub struct Node<K = NodeKind> {
    /// Unique name: the explicit `name`, or one generated from kind and path
    /// (e.g. `fallback@0.1`).
    pub name: String,
    /// Dotted child indices from the root, which is `0` (first child `0.0`).
    pub path: String,
    /// Depth in the tree (root 0).
    pub depth: usize,
    /// Parent node, `None` for the root.
    pub parent: Option<NodeId>,
    /// What the node is.
    pub kind: K,
    /// 1-based line and column of the node in its source file, if known.
    pub location: Option<(usize, usize)>,
}

/// The kind of a node, with its parameters.
#[derive(Debug, Clone, PartialEq)]
pub enum NodeKind {
    /// A leaf that runs for some time, then succeeds or fails (Defs. 9.7–9.9).
    Action(Action),
    /// A leaf of zero duration that succeeds with probability `ps` (Assumption 9.2).
    Condition {
        /// Probability of Success; Failure has probability `1 - ps`.
        ps: f64,
    },
    /// Ticks children in order; fails at the first Failure, succeeds when all succeed.
    Sequence {
        /// Children, in order (at least one).
        children: Vec<NodeId>,
    },
    /// Ticks children in order; succeeds at the first Success, fails when all fail.
    Fallback {
        /// Children, in order (at least one).
        children: Vec<NodeId>,
    },
    /// Runs all children at once; Success when `success_threshold` (M)
    /// children have succeeded; Failure when `failure_threshold` (F) have
    /// failed or success has become impossible (more than N − M failed). The
    /// book's Parallel has F = N − M + 1 (the default).
    Parallel {
        /// M, in `1..=children.len()`.
        success_threshold: usize,
        /// F, in `1..=children.len()`.
        failure_threshold: usize,
        /// Children (at least one).
        children: Vec<NodeId>,
    },
    /// Nav2's PipelineSequence: ticks its children in order like a Sequence,
    /// but re-ticks the children that have already returned Success on every
    /// tick while a later child runs; a Failure of any of them halts all and
    /// fails; the last child's Success ends it. What a re-tick does depends
    /// on the child ([`nav2::retick`]).
    Pipeline {
        /// Children, in order (at least one).
        children: Vec<NodeId>,
    },
    /// Nav2's RoundRobin: a Fallback that starts at the child after the one
    /// that last succeeded, remembered across executions (and across the
    /// copies of one XML element, which share `slot`). With `wrap` it tries
    /// every child once, wrapping around; without (Nav2's default since
    /// 2025), it stops after the last child and returns Failure even when
    /// that child succeeded (Nav2's `round_robin_node.cpp` breaks out of its
    /// loop before looking at the last child's status). A Failure resets the
    /// index to 0.
    RoundRobin {
        /// Children, in order (at least one).
        children: Vec<NodeId>,
        /// Whether the index wraps around to the first child.
        wrap: bool,
        /// Identity of the index: nodes with the same slot share one index.
        slot: usize,
    },
    /// BehaviorTree.CPP's SequenceWithMemory (v3: SequenceStar) where its
    /// index may matter: below a node that ticks it again after a Failure
    /// (a RecoveryNode's main branch, a RetryUntilSuccessful). A Sequence
    /// that starts at the child where it last stopped: a child's Failure
    /// returns Failure and keeps the index at that child (the next tick runs
    /// it afresh); the last child's Success returns Success and resets the
    /// index to 0 (`sequence_with_memory_node.cpp`). The index survives its
    /// parent's reset (BT.CPP halts only RUNNING children) and is 0 at the
    /// start of every run of the tree; copies of one XML element (a
    /// RecoveryNode's retries) share `slot` with each other (and with no
    /// RoundRobin). `halt_resets`: a halt while a child runs sets the index
    /// to 0 (v3's `SequenceStarNode::halt`); v4's `SequenceWithMemory::halt`
    /// keeps it.
    SequenceWithMemory {
        /// Children, in order (at least one).
        children: Vec<NodeId>,
        /// Identity of the index: nodes with the same slot share one index.
        slot: usize,
        /// Whether a halt resets the index (BT.CPP v3) or keeps it (v4).
        halt_resets: bool,
    },
    /// A flow: a finite acyclic graph of states, each running one child (a
    /// fresh, independent run at every visit), whose Success and Failure
    /// edges lead to a later state or to the node's own Success or Failure.
    /// The run starts in state 0. Sequence, Fallback, IfThenElse, Switch and
    /// a Retry of a SequenceWithMemory are flows (see [`Flow`]).
    Flow(Flow),
    /// A node with one child that changes its outcome or repeats it.
    Decorator {
        /// Which decorator.
        decorator: Decorator,
        /// The child.
        child: NodeId,
    },
}

/// Where a flow goes after a state's child returns.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FlowNext {
    /// Run the state with this index (greater than the current one).
    State(usize),
    /// The flow returns Success.
    Success,
    /// The flow returns Failure.
    Failure,
}

/// One state of a [`Flow`]: run child `children[child]`, then follow
/// `on_success` or `on_failure`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FlowState {
    /// Position of the child in [`Flow::children`].
    pub child: usize,
    /// Where to go when the child returns Success.
    pub on_success: FlowNext,
    /// Where to go when the child returns Failure.
    pub on_failure: FlowNext,
}

/// The branching primitive: see [`NodeKind::Flow`].
///
/// Invariants (checked by [`Flow::new`]): at least one state; every state's
/// child exists; every edge to a state goes to a later one (the graph is
/// acyclic and its states are in topological order); every child is run by
/// some state.
#[derive(Debug, Clone, PartialEq)]
pub struct Flow {
    /// The children (distinct subtrees), in tree order.
    pub children: Vec<NodeId>,
    /// The states; the run starts in `states[0]`.
    pub states: Vec<FlowState>,
}

impl Flow {
    /// A flow over `children` with `states`, or what is wrong with it.
    pub fn new(children: Vec<NodeId>, states: Vec<FlowState>) -> Result<Flow, String> {
        if states.is_empty() {
            return Err("a flow needs at least one state".into());
        }
        let mut used = vec![false; children.len()];
        for (i, s) in states.iter().enumerate() {
            let Some(u) = used.get_mut(s.child) else {
                return Err(format!(
                    "state {i} runs child {} but the flow has {} children",
                    s.child,
                    children.len()
                ));
            };
            *u = true;
            for next in [s.on_success, s.on_failure] {
                if let FlowNext::State(j) = next {
                    if j <= i || j >= states.len() {
                        return Err(format!(
                            "state {i} goes to state {j}: a state may only go to a later state \
                             (1..{} here), to success or to failure",
                            states.len()
                        ));
                    }
                }
            }
        }
        if let Some(c) = used.iter().position(|u| !u) {
            return Err(format!("child {c} is run by no state"));
        }
        Ok(Flow { children, states })
    }

    /// `IfThenElse(C, T, E)`: run C; on Success run T, on Failure run E (or
    /// return Failure without `E`); return what T or E returns.
    pub fn if_then_else(condition: NodeId, then: NodeId, otherwise: Option<NodeId>) -> Flow {
        let mut children = vec![condition, then];
        let mut states = vec![FlowState {
            child: 0,
            on_success: FlowNext::State(1),
            on_failure: FlowNext::Failure,
        }];
        states.push(FlowState {
            child: 1,
            on_success: FlowNext::Success,
            on_failure: FlowNext::Failure,
        });
        if let Some(e) = otherwise {
            children.push(e);
            states[0].on_failure = FlowNext::State(2);
            states.push(FlowState {
                child: 2,
                on_success: FlowNext::Success,
                on_failure: FlowNext::Failure,
            });
        }
        Flow { children, states }
    }
}

/// Decorators (BehaviorTree.CPP semantics under the SBT assumptions).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Decorator {
    /// Success ↔ Failure.
    Inverter,
    /// Always Success, after the child returns.
    ForceSuccess,
    /// Always Failure, after the child returns.
    ForceFailure,
    /// RetryUntilSuccessful: run a fresh child until it succeeds, at most
    /// `attempts` times (Failure if every attempt fails).
    Retry {
        /// Most attempts (≥ 1).
        attempts: usize,
    },
    /// Repeat: run a fresh child until it has succeeded `times` times in a
    /// row (Failure at the first failure).
    Repeat {
        /// Successes needed (≥ 1).
        times: usize,
    },
    /// Run a fresh child until it fails, then return Failure
    /// (BehaviorTree.CPP `KeepRunningUntilFailure`, `Repeat num_cycles="-1"`).
    UntilFailure,
    /// Run a fresh child until it succeeds, then return Success
    /// (BehaviorTree.CPP `RetryUntilSuccessful num_attempts="-1"`).
    UntilSuccess,
    /// Nav2's RateController: runs its child once per execution; as an
    /// earlier child of a [`NodeKind::Pipeline`] it runs the child again
    /// `period` seconds after each Success until the pipeline ends.
    Rate {
        /// Seconds between a Success of the child and its next start (1/hz).
        period: f64,
        /// Seconds between the child's first Success and its first re-run
        /// (`period` for a RateController or a DistanceController; Nav2's
        /// SpeedController waits 2/(min_rate + max_rate) s first).
        first: f64,
    },
    /// Nav2's SingleTrigger: runs its child once per execution; ticked
    /// again without being reset (as an earlier child of a
    /// [`NodeKind::Pipeline`]) it returns Failure.
    SingleTrigger,
}

impl Decorator {
    /// The primitive decorator that runs the child the same way within one
    /// execution: RateController and SingleTrigger run their child once
    /// (`repeat` 1); they differ only when ticked again without a reset, which
    /// [`nav2::primitive_view`] refuses.
    pub fn as_primitive(self) -> Decorator {
        match self {
            Decorator::Rate { .. } | Decorator::SingleTrigger => Decorator::Repeat { times: 1 },
            d => d,
        }
    }

    /// The keyword in the YAML format.
    pub fn keyword(&self) -> &'static str {
        match self {
            Decorator::Inverter => "inverter",
            Decorator::ForceSuccess => "force_success",
            Decorator::ForceFailure => "force_failure",
            Decorator::Retry { .. } => "retry",
            Decorator::Repeat { .. } => "repeat",
            Decorator::UntilFailure => "until_failure",
            Decorator::UntilSuccess => "until_success",
            Decorator::Rate { .. } => "rate_controller",
            Decorator::SingleTrigger => "single_trigger",
        }
    }
}

impl NodeKind {
    /// The kind's keyword as written in the YAML format.
    pub fn keyword(&self) -> &'static str {
        match self {
            NodeKind::Action(_) => "action",
            NodeKind::Condition { .. } => "condition",
            NodeKind::Sequence { .. } => "sequence",
            NodeKind::Fallback { .. } => "fallback",
            NodeKind::Parallel { .. } => "parallel",
            NodeKind::Pipeline { .. } => "pipeline_sequence",
            NodeKind::RoundRobin { .. } => "round_robin",
            NodeKind::SequenceWithMemory { .. } => "sequence_with_memory",
            NodeKind::Flow(_) => "flow",
            NodeKind::Decorator { decorator, .. } => decorator.keyword(),
        }
    }

    /// Children of a control node; empty for leaves.
    pub fn children(&self) -> &[NodeId] {
        match self {
            NodeKind::Sequence { children }
            | NodeKind::Fallback { children }
            | NodeKind::Pipeline { children }
            | NodeKind::RoundRobin { children, .. }
            | NodeKind::SequenceWithMemory { children, .. }
            | NodeKind::Parallel { children, .. }
            | NodeKind::Flow(Flow { children, .. }) => children,
            NodeKind::Decorator { child, .. } => std::slice::from_ref(child),
            NodeKind::Action(_) | NodeKind::Condition { .. } => &[],
        }
    }

    /// [`NodeKind::children`], to renumber them.
    pub(crate) fn children_mut(&mut self) -> &mut [NodeId] {
        match self {
            NodeKind::Sequence { children }
            | NodeKind::Fallback { children }
            | NodeKind::Pipeline { children }
            | NodeKind::RoundRobin { children, .. }
            | NodeKind::SequenceWithMemory { children, .. }
            | NodeKind::Parallel { children, .. }
            | NodeKind::Flow(Flow { children, .. }) => children,
            NodeKind::Decorator { child, .. } => std::slice::from_mut(child),
            NodeKind::Action(_) | NodeKind::Condition { .. } => &mut [],
        }
    }
}

impl Kind for NodeKind {
    fn children(&self) -> &[NodeId] {
        NodeKind::children(self)
    }

    fn children_mut(&mut self) -> &mut [NodeId] {
        NodeKind::children_mut(self)
    }

    fn same_parameters(&self, other: &Self) -> bool {
        if std::mem::discriminant(self) != std::mem::discriminant(other) {
            return false;
        }
        match (self, other) {
            (NodeKind::Action(p), NodeKind::Action(q)) => p == q,
            (NodeKind::Condition { ps: p }, NodeKind::Condition { ps: q }) => p == q,
            (
                NodeKind::Parallel {
                    success_threshold: m1,
                    failure_threshold: f1,
                    ..
                },
                NodeKind::Parallel {
                    success_threshold: m2,
                    failure_threshold: f2,
                    ..
                },
            ) => (m1, f1) == (m2, f2),
            (
                NodeKind::RoundRobin {
                    wrap: w1, slot: s1, ..
                },
                NodeKind::RoundRobin {
                    wrap: w2, slot: s2, ..
                },
            ) => (w1, s1) == (w2, s2),
            (
                NodeKind::SequenceWithMemory {
                    slot: s1,
                    halt_resets: h1,
                    ..
                },
                NodeKind::SequenceWithMemory {
                    slot: s2,
                    halt_resets: h2,
                    ..
                },
            ) => (s1, h1) == (s2, h2),
            (NodeKind::Flow(f1), NodeKind::Flow(f2)) => f1.states == f2.states,
            (
                NodeKind::Decorator { decorator: d1, .. },
                NodeKind::Decorator { decorator: d2, .. },
            ) => d1 == d2,
            // Sequence, Fallback, Pipeline: their children alone
            _ => true,
        }
    }
}

/// An action's outcome probabilities and the time each outcome takes.
///
/// Invariants (checked by the parser): `ps, pf ∈ [0, 1]`, `ps + pf = 1`
/// within 1e-9; `success` is `Some` whenever `ps > 0` and `failure` is `Some`
/// whenever `pf > 0`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Action {
    /// Probability of Success.
    pub ps: f64,
    /// Probability of Failure.
    pub pf: f64,
    /// How long a run that ends in Success takes.
    pub success: Option<Duration>,
    /// How long a run that ends in Failure takes.
    pub failure: Option<Duration>,
}

/// The time an action takes to reach one of its outcomes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Duration {
    /// Exponentially distributed with this rate (`mu` or `nu`, Def. 9.7).
    Exponential {
        /// Rate > 0 (1/s).
        rate: f64,
    },
    /// Exactly this long (`tau_s` or `tau_f`, Def. 9.8).
    Fixed {
        /// Time ≥ 0 (s).
        time: f64,
    },
    /// Exponential with `rate`, cut off at `cap`: the time is `min(X, cap)`,
    /// `X ~ Exp(rate)`. This is the random side of a hybrid action (Def. 9.9),
    /// where the other outcome happens at the deterministic time `cap`.
    TruncatedExponential {
        /// Rate > 0 (1/s).
        rate: f64,
        /// The deterministic time of the other outcome (s).
        cap: f64,
    },
    /// A deterministic `shift` followed by a sum of independent exponential
    /// stages: Erlang-k (one rate, k stages), hypoexponential (one stage
    /// per rate) and their shifted forms (`success_time` / `failure_time`).
    /// A single stage without shift is always written
    /// [`Duration::Exponential`] (see [`Duration::phase_type`]).
    PhaseType {
        /// Deterministic delay before the first stage (s, ≥ 0).
        shift: f64,
        /// The exponential stages (interned, see [`stages::intern`]).
        stages: &'static Stages,
    },
}

impl Duration {
    /// The largest rate of its random part (1/s; 0 for a fixed time): how
    /// fast its density can change.
    pub fn fastest_rate(&self) -> f64 {
        match *self {
            Duration::Exponential { rate } | Duration::TruncatedExponential { rate, .. } => rate,
            Duration::Fixed { .. } => 0.0,
            Duration::PhaseType { stages, .. } => stages.fastest(),
        }
    }

    /// Why this is not a valid duration (`None` when it is): a rate must be
    /// finite and > 0, a time, cap or shift finite and >= 0 (stages are
    /// valid by construction).
    pub fn invalid(&self) -> Option<String> {
        let rate = |r: f64| {
            (!(r.is_finite() && r > 0.0)).then(|| format!("has rate {r}, not a finite number > 0"))
        };
        let time = |t: f64, what: &str| {
            (!(t.is_finite() && t >= 0.0))
                .then(|| format!("has {what} {t}, not a finite number >= 0"))
        };
        match *self {
            Duration::Exponential { rate: r } => rate(r),
            Duration::Fixed { time: t } => time(t, "time"),
            Duration::TruncatedExponential { rate: r, cap } => rate(r).or_else(|| time(cap, "cap")),
            Duration::PhaseType { shift, .. } => time(shift, "shift"),
        }
    }

    /// Mean of the duration.
    pub fn mean(&self) -> f64 {
        match *self {
            Duration::Exponential { rate } => 1.0 / rate,
            Duration::Fixed { time } => time,
            // E[min(X, c)] = ∫_0^c e^{-λt} dt = (1 - e^{-λc}) / λ
            Duration::TruncatedExponential { rate, cap } => -(-rate * cap).exp_m1() / rate,
            Duration::PhaseType { shift, stages } => shift + stages.mean(),
        }
    }

    /// `P(duration ≤ t)`.
    pub fn cdf(&self, t: f64) -> f64 {
        match *self {
            Duration::Exponential { rate } => -(-rate * t).exp_m1(),
            Duration::Fixed { time } => f64::from(u8::from(t >= time)),
            Duration::TruncatedExponential { cap, .. } if t >= cap => 1.0,
            Duration::TruncatedExponential { rate, .. } => -(-rate * t).exp_m1(),
            Duration::PhaseType { shift, stages } => stages.cdf(t - shift),
        }
    }

    /// Whether the duration is a single exponential phase.
    pub fn is_exponential(&self) -> bool {
        matches!(self, Duration::Exponential { .. })
    }

    /// `shift` then `stages`, written in its simplest form: one stage
    /// without shift is [`Duration::Exponential`].
    pub fn phase_type(shift: f64, stages: Stages) -> Duration {
        match stages.iter().collect::<Vec<_>>()[..] {
            [(rate, 1)] if shift == 0.0 => Duration::Exponential { rate },
            _ => Duration::PhaseType {
                shift,
                stages: stages::intern(stages),
            },
        }
    }

    /// The deterministic part of the duration: the fixed time, the shift of
    /// a shifted law, 0 otherwise.
    pub fn shift(&self) -> f64 {
        match *self {
            Duration::Fixed { time } => time,
            Duration::PhaseType { shift, .. } => shift,
            Duration::Exponential { .. } | Duration::TruncatedExponential { .. } => 0.0,
        }
    }

    /// The exponential stages after the shift: one for an exponential, none
    /// for a fixed time or a truncated (hybrid) exponential.
    pub fn stages(&self) -> Option<Stages> {
        match *self {
            Duration::Exponential { rate } => Stages::erlang(1, rate).ok(),
            Duration::PhaseType { stages, .. } => Some(*stages),
            Duration::Fixed { .. } | Duration::TruncatedExponential { .. } => None,
        }
    }

    /// The duration as a phase chain whose Success exit ends the outcome,
    /// when it is exactly phase-type: an exponential, an Erlang, a
    /// hypoexponential, a hyperexponential or a general phase-type law,
    /// without shift. `None` for fixed, hybrid and shifted times.
    pub fn phase_chain(&self) -> Option<crate::solve::chain::PhaseChain> {
        match *self {
            Duration::Exponential { rate } => Stages::erlang(1, rate).ok().map(|s| s.chain()),
            Duration::PhaseType { shift: 0.0, stages } => Some(stages.chain()),
            _ => None,
        }
    }

    /// Whether [`Duration::phase_chain`] is `Some` (without building it).
    pub fn is_phase_type(&self) -> bool {
        matches!(
            self,
            Duration::Exponential { .. } | Duration::PhaseType { shift: 0.0, .. }
        )
    }

    /// The family's name as in outputs: `exponential`, `deterministic`,
    /// `truncated exponential`, `Erlang`, `hypoexponential`,
    /// `hyperexponential`, `phase-type`, and `shifted` before each of the
    /// last five and `exponential`.
    pub fn family(&self) -> &'static str {
        match *self {
            Duration::Exponential { .. } => "exponential",
            Duration::Fixed { .. } => "deterministic",
            Duration::TruncatedExponential { .. } => "truncated exponential",
            Duration::PhaseType { shift, stages } => {
                let shifted = shift > 0.0;
                if let Some(g) = stages.as_general() {
                    return match (shifted, g.is_hyperexponential()) {
                        (false, true) => "hyperexponential",
                        (false, false) => "phase-type",
                        (true, true) => "shifted hyperexponential",
                        (true, false) => "shifted phase-type",
                    };
                }
                match (shifted, stages.as_erlang()) {
                    (false, Some(_)) => "Erlang",
                    (false, None) => "hypoexponential",
                    (true, Some((1, _))) => "shifted exponential",
                    (true, Some(_)) => "shifted Erlang",
                    (true, None) => "shifted hypoexponential",
                }
            }
        }
    }

    /// The duration in the `success_time` / `failure_time` syntax of the
    /// tree and params files (a flow mapping), e.g. `{erlang: {k: 3, rate:
    /// 0.5}}` or `{shift: 8, rate: 0.5}`. A truncated exponential has no
    /// such form (it is written with `mu`/`nu` and `tau_f`/`tau_s`): its rate.
    pub fn to_yaml(&self) -> String {
        let list = |v: &mut dyn Iterator<Item = String>| v.collect::<Vec<_>>().join(", ");
        let body = |s: &Stages| match (s.as_general(), s.as_erlang()) {
            (Some(g), _) if g.is_hyperexponential() => format!(
                "hyperexponential: [{}]",
                list(&mut (0..g.len()).map(|i| format!(
                    "{{p: {}, rate: {}}}",
                    g.alpha()[i],
                    -g.t(i, i)
                )))
            ),
            (Some(g), _) => format!(
                "phase_type: {{alpha: [{}], T: [{}]}}",
                list(&mut g.alpha().iter().map(|a| a.to_string())),
                list(&mut (0..g.len()).map(|i| format!(
                    "[{}]",
                    list(&mut (0..g.len()).map(|j| g.t(i, j).to_string()))
                )))
            ),
            (None, Some((1, rate))) => format!("rate: {rate}"),
            (None, Some((k, rate))) => format!("erlang: {{k: {k}, rate: {rate}}}"),
            (None, None) => format!(
                "hypoexponential: [{}]",
                list(&mut s.series().iter().map(|r| r.to_string()))
            ),
        };
        match self {
            Duration::Exponential { rate } | Duration::TruncatedExponential { rate, .. } => {
                format!("{{rate: {rate}}}")
            }
            Duration::Fixed { time } => format!("{{fixed: {time}}}"),
            Duration::PhaseType { shift, stages } if *shift > 0.0 => {
                format!("{{shift: {shift}, {}}}", body(stages))
            }
            Duration::PhaseType { stages, .. } => format!("{{{}}}", body(stages)),
        }
    }

    /// One draw of the duration.
    pub fn sample<R: rand::Rng + ?Sized>(&self, rng: &mut R) -> f64 {
        use rand_distr::{Distribution, Exp1};
        match *self {
            Duration::Exponential { rate } => {
                let e: f64 = Exp1.sample(rng);
                e / rate
            }
            Duration::Fixed { time } => time,
            Duration::TruncatedExponential { rate, cap } => {
                let e: f64 = Exp1.sample(rng);
                (e / rate).min(cap)
            }
            Duration::PhaseType { shift, stages } => shift + stages.sample(rng),
        }
    }
}

/// How an action's timing was specified (Defs. 9.7–9.9).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TimingKind {
    /// `mu`, `nu`: exponential times (Def. 9.7).
    Stochastic,
    /// `tau_s`, `tau_f`: fixed times (Def. 9.8).
    Deterministic,
    /// `tau_s` + `nu`: deterministic success time (Def. 9.9).
    HybridDeterministicSuccess,
    /// `mu` + `tau_f`: deterministic failure time (Def. 9.9).
    HybridDeterministicFailure,
}

impl Action {
    /// Classifies the action's timing.
    pub fn timing_kind(&self) -> TimingKind {
        use Duration::*;
        match (self.success, self.failure) {
            (Some(Fixed { .. }), Some(TruncatedExponential { .. })) => {
                TimingKind::HybridDeterministicSuccess
            }
            (Some(TruncatedExponential { .. }), Some(Fixed { .. })) => {
                TimingKind::HybridDeterministicFailure
            }
            (Some(Fixed { .. }), _) | (_, Some(Fixed { .. })) => TimingKind::Deterministic,
            _ => TimingKind::Stochastic,
        }
    }

    /// Whether every outcome time is phase-type (exponential, Erlang,
    /// hypoexponential, hyperexponential or general phase-type, no shift): the action is a mixture of phase chains
    /// that a CTMC represents exactly.
    pub fn is_markovian(&self) -> bool {
        self.success.is_none_or(|d| d.is_phase_type())
            && self.failure.is_none_or(|d| d.is_phase_type())
    }
}

impl<K: Kind> Tree<K> {
    /// The node with this id.
    pub fn node(&self, id: NodeId) -> &Node<K> {
        &self.nodes[id]
    }

    /// Every node, in pre-order (`nodes()[0]` is the root); a node's id is
    /// its index.
    pub fn nodes(&self) -> &[Node<K>] {
        &self.nodes
    }

    /// The title (`name:` at the top of a YAML file, the main tree's ID of
    /// an XML file).
    pub fn title(&self) -> Option<&str> {
        self.title.as_deref()
    }

    /// Finds a node by name, or by path (`0.1.2`).
    pub fn find(&self, name_or_path: &str) -> Option<NodeId> {
        self.nodes
            .iter()
            .position(|n| n.name == name_or_path)
            .or_else(|| self.nodes.iter().position(|n| n.path == name_or_path))
    }

    /// Number of leaves (actions and conditions).
    pub fn leaf_count(&self) -> usize {
        self.nodes
            .iter()
            .filter(|n| n.kind.children().is_empty())
            .count()
    }

    /// Ids of the nodes of the subtree rooted at `id` (pre-order, `id` first).
    pub fn subtree(&self, id: NodeId) -> std::ops::Range<NodeId> {
        let depth = self.nodes[id].depth;
        let end = self.nodes[id + 1..]
            .iter()
            .position(|n| n.depth <= depth)
            .map_or(self.nodes.len(), |p| id + 1 + p);
        id..end
    }

    /// A hash of each node's subtree as [`Tree::same_subtree`] compares it
    /// (kinds and parameters in place, names aside): copies have equal
    /// fingerprints, so `same_subtree` need only confirm equal ones.
    pub fn fingerprints(&self) -> Vec<u64> {
        let mut out = vec![0u64; self.nodes.len()];
        for id in (0..self.nodes.len()).rev() {
            out[id] = self.fingerprint(id, &out);
        }
        out
    }

    /// The fingerprint of node `id` ([`Tree::fingerprints`]) from its
    /// children's in `prints`.
    pub fn fingerprint(&self, id: NodeId, prints: &[u64]) -> u64 {
        use std::hash::{Hash, Hasher};
        // the kind without its children's ids (their fingerprints below)
        let mut kind = self.nodes[id].kind.clone();
        kind.children_mut().iter_mut().for_each(|c| *c = 0);
        let mut h = std::collections::hash_map::DefaultHasher::new();
        format!("{kind:?}").hash(&mut h);
        for &c in self.nodes[id].kind.children() {
            prints[c].hash(&mut h);
        }
        h.finish()
    }

    /// Whether the subtrees of `a` and `b` are copies of each other (the
    /// same kinds and parameters in the same places; names aside), as the
    /// lowering of a RecoveryNode's retries makes them.
    pub fn same_subtree(&self, a: NodeId, b: NodeId) -> bool {
        let (ka, kb) = (&self.node(a).kind, &self.node(b).kind);
        if !ka.same_parameters(kb) || ka.children().len() != kb.children().len() {
            return false;
        }
        let (ra, rb) = (self.subtree(a), self.subtree(b));
        if ra.len() != rb.len() {
            return false;
        }
        let shift = |ids: &[NodeId], from: NodeId| -> Vec<usize> {
            ids.iter().map(|&c| c - from).collect()
        };
        ra.zip(rb).all(|(x, y)| {
            let (kx, ky) = (&self.node(x).kind, &self.node(y).kind);
            if shift(kx.children(), a) != shift(ky.children(), b) {
                return false;
            }
            kx.same_parameters(ky)
        })
    }
}

impl Tree {
    /// The root node's id (always 0).
    pub const ROOT: NodeId = 0;

    /// Puts the children of Fallback `node` in `order` (a permutation of
    /// them, checked by the caller); nothing for another kind.
    pub(crate) fn set_fallback_order(&mut self, node: NodeId, order: &[NodeId]) {
        if let NodeKind::Fallback { children } = &mut self.nodes[node].kind {
            children.copy_from_slice(order);
        }
    }

    /// This tree with each action's Success and Failure times replaced by
    /// `times(id, action)` (outcome probabilities and everything else kept):
    /// e.g. the same tree with fitted timing families. Refused, naming the
    /// action, when a time is not a valid duration (a rate that is not finite
    /// and > 0, a time or shift that is not finite and >= 0) or an outcome
    /// with positive probability is left without a time.
    pub fn with_action_times(
        &self,
        mut times: impl FnMut(NodeId, &Action) -> (Option<Duration>, Option<Duration>),
    ) -> Result<Tree, InvalidTime> {
        let mut tree = self.clone();
        for (id, node) in tree.nodes.iter_mut().enumerate() {
            let NodeKind::Action(a) = &mut node.kind else {
                continue;
            };
            let (success, failure) = times(id, a);
            for (outcome, p, d) in [("success", a.ps, success), ("failure", a.pf, failure)] {
                let invalid = |what: String| InvalidTime {
                    node: node.name.clone(),
                    outcome,
                    what,
                };
                match d {
                    None if p > 0.0 => {
                        return Err(invalid(format!(
                            "is missing, though the outcome has probability {p}"
                        )))
                    }
                    None => {}
                    Some(d) => {
                        if let Some(what) = d.invalid() {
                            return Err(invalid(what));
                        }
                    }
                }
            }
            a.success = success;
            a.failure = failure;
        }
        Ok(tree)
    }
}
