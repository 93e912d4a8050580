//! The node-type tables: which BT.CPP / Nav2 / MoveIt Pro types btrel
//! reads, their v3 spellings, the known types it has no stochastic meaning
//! for, the pre-condition attributes, and how a leaf's kind is decided.

use super::*;

#[derive(Clone, Copy, PartialEq, Eq)]
pub(super) enum Decl {
    Action,
    Condition,
    /// A custom control node or decorator declared in the model.
    Other(&'static str),
}

/// The queue loops: BT.CPP's `LoopInt`, ... (`queue`, literal or from the
/// blackboard, `if_empty`), `ConsumeQueue` (`queue` from the blackboard,
/// empty: Success) and MoveIt Pro's `ForEach` (`vector_in` from the
/// blackboard; an empty vector is refused).
#[derive(Clone, Copy, PartialEq, Eq)]
pub(super) enum Queue {
    Loop,
    Consume,
    ForEach,
}

/// How a leaf's kind is decided.
#[derive(Clone, Copy, PartialEq, Eq)]
pub(super) enum LeafKind {
    Action,
    Condition,
    /// By its params entry: `ps` alone is a condition, anything else an
    /// action.
    Inferred,
    /// A node BT.CPP runs as an immediate Success (Script, SetBlackboard,
    /// UnsetBlackboard): its params entry if it has one (as `Inferred`),
    /// else a condition with ps 1.
    ZeroTime,
}

/// The first line of the error that lists nodes without a stochastic
/// meaning; [`is_unsupported`] tells such refusals from invalid input.
pub(crate) const UNSUPPORTED: &str = "btrel has no stochastic meaning yet for";

/// Whether `e` refuses a tree only because it uses node types (or
/// pre-condition attributes) that btrel has no stochastic meaning for yet,
/// as opposed to invalid or incomplete input.
pub fn is_unsupported(e: &TreeError) -> bool {
    e.kind == Kind::NoMeaning
}

/// Known node types of BehaviorTree.CPP v3/v4, Nav2 and MoveIt Pro that
/// btrel has no stochastic meaning for yet, with what they depend on.
pub(super) fn unsupported(ty: &str) -> Option<&'static str> {
    Some(match ty {
        "WasEntryUpdated"
        | "SkipUnlessUpdated"
        | "WaitValueUpdate"
        | "EntryUpdated"
        | "BlackboardCheckInt"
        | "BlackboardCheckDouble"
        | "BlackboardCheckString"
        | "BlackboardCheckBool" => "its outcome is computed from blackboard values",
        "RunOnce" => "it runs its child at most once, keeping its status across executions",
        "ParallelAll" => {
            "it runs every child to the end and compares the failures with a threshold"
        }
        "NonblockingSequence" | "PersistentSequence" | "PauseResumeController" => {
            "Nav2 control node: it keeps state across executions or waits for an external request"
        }
        _ => return None,
    })
}

/// Pre-conditions (BT.CPP v4): they may skip a node or end it early
/// depending on the blackboard. The value that makes each a no-op.
pub(super) const PRECONDITIONS: &[(&str, &str)] = &[
    ("_skipIf", "false"),
    ("_failureIf", "false"),
    ("_successIf", "false"),
    ("_while", "true"),
];

/// Node types btrel reads (for "did you mean").
pub(super) const BUILTINS: &[&str] = &[
    "Sequence",
    "SequenceWithMemory",
    "SequenceStar",
    "ReactiveSequence",
    "Fallback",
    "ReactiveFallback",
    "Parallel",
    "Inverter",
    "ForceSuccess",
    "ForceFailure",
    "RetryUntilSuccessful",
    "Repeat",
    "RecoveryNode",
    "PipelineSequence",
    "RoundRobin",
    "RateController",
    "SingleTrigger",
    "GoalUpdater",
    "IfThenElse",
    "WhileDoElse",
    "Timeout",
    "Action",
    "Condition",
    "Control",
    "Decorator",
    "SubTree",
    "AlwaysSuccess",
    "AlwaysFailure",
    "Script",
    "SetBlackboard",
    "UnsetBlackboard",
    "ScriptCondition",
    "Precondition",
    "LoopInt",
    "LoopDouble",
    "LoopString",
    "LoopBool",
    "Switch2",
    "Switch3",
    "ManualSelector",
    "ConsumeQueue",
    "ForEach",
    "RepeatUnlessFailureEachTick",
    "DistanceController",
    "SpeedController",
    "GoalUpdatedController",
    "PathLongerOnApproach",
];

/// Most states of a flow built from BT.CPP nodes (a RetryUntilSuccessful
/// over a SequenceWithMemory has attempts × children states).
pub(crate) const MAX_FLOW_STATES: usize = 1_000_000;

/// Most retries of a RecoveryNode (each adds two levels to the tree).
pub(crate) const MAX_RECOVERY_RETRIES: u64 = 1000;

/// BT.CPP v3 spellings and their v4 names.
pub(super) fn canonical(ty: &str) -> &str {
    match ty {
        "SequenceStar" => "SequenceWithMemory",
        "RetryUntilSuccesful" => "RetryUntilSuccessful",
        // MoveIt Pro 9.3+: Repeat with one iteration per parent tick, which
        // in continuous time (ticks without gaps) is Repeat
        "RepeatUnlessFailureEachTick" => "Repeat",
        t => t,
    }
}

pub(super) fn has_timing(p: &ActionParams) -> bool {
    [&p.pf, &p.mu, &p.nu, &p.tau_s, &p.tau_f]
        .into_iter()
        .any(Option::is_some)
        || p.time_law_at().is_some()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn v3_spellings_map_to_read_types() {
        assert_eq!(canonical("SequenceStar"), "SequenceWithMemory");
        assert_eq!(canonical("RetryUntilSuccesful"), "RetryUntilSuccessful");
        assert_eq!(canonical("RepeatUnlessFailureEachTick"), "Repeat");
        assert_eq!(canonical("Sequence"), "Sequence");
        for t in BUILTINS {
            assert!(BUILTINS.contains(&canonical(t)), "{t}");
        }
    }

    #[test]
    fn read_types_and_types_without_meaning_are_disjoint() {
        assert!(unsupported("RunOnce").is_some());
        assert!(unsupported("PersistentSequence").is_some());
        assert!(unsupported("BlackboardCheckInt").is_some());
        assert!(unsupported("MyCustomNode").is_none());
        for t in BUILTINS {
            assert!(unsupported(t).is_none(), "{t}");
        }
    }

    #[test]
    fn preconditions_have_a_no_op_value() {
        let noop: HashMap<&str, &str> = PRECONDITIONS.iter().copied().collect();
        assert_eq!(noop["_skipIf"], "false");
        assert_eq!(noop["_while"], "true");
        assert_eq!(noop.len(), 4);
    }

    #[test]
    fn timing_makes_an_action() {
        let at = |v| {
            Some(At {
                value: v,
                line: 1,
                column: 1,
            })
        };
        let p = ActionParams {
            ps: at(0.5),
            ..Default::default()
        };
        assert!(!has_timing(&p));
        let p = ActionParams {
            ps: at(0.5),
            mu: at(1.0),
            ..Default::default()
        };
        assert!(has_timing(&p));
    }

    #[test]
    fn kind_decides_is_unsupported() {
        let e = TreeError::file(Kind::NoMeaning, "t.xml", "x");
        assert!(is_unsupported(&e));
        let e = TreeError::file(Kind::MissingParameter, "t.xml", UNSUPPORTED);
        assert!(!is_unsupported(&e));
    }
}
