//! The YAML tree format as serde types (each value with its location), read
//! by serde-saphyr ([`super::parse_full`]) or the fast reader
//! ([`super::fast`]) and turned into a [`crate::tree::Tree`] by
//! [`super::builder`].

use serde::Deserialize;

use super::super::action::{At, TimeDef};

pub(super) const NODE_KINDS: &[&str] = &[
    "sequence",
    "fallback",
    "parallel",
    "action",
    "condition",
    "inverter",
    "force_success",
    "force_failure",
    "retry",
    "repeat",
    "until_failure",
    "until_success",
    "if_then_else",
    "flow",
];

impl NodeDef {
    /// Number of nodes in the definition (iterative: any depth).
    pub(super) fn count(&self) -> usize {
        let mut stack = vec![self];
        let mut n = 0;
        while let Some(d) = stack.pop() {
            n += 1;
            match d {
                NodeDef::Sequence(c) | NodeDef::Fallback(c) | NodeDef::IfThenElse(c) => {
                    stack.extend(c.children.value.iter().map(|c| &c.value))
                }
                NodeDef::Flow(f) => stack.extend(f.children.value.iter().map(|c| &c.value)),
                NodeDef::Parallel(p) => stack.extend(p.children.value.iter().map(|c| &c.value)),
                NodeDef::Action(_) | NodeDef::Condition(_) => {}
                NodeDef::Inverter(d)
                | NodeDef::ForceSuccess(d)
                | NodeDef::ForceFailure(d)
                | NodeDef::UntilFailure(d)
                | NodeDef::UntilSuccess(d) => stack.push(&d.child.value),
                NodeDef::Retry(r) => stack.push(&r.child.value),
                NodeDef::Repeat(r) => stack.push(&r.child.value),
            }
        }
        n
    }
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct FileDef {
    #[serde(default)]
    pub(super) name: Option<String>,
    pub(super) tree: At<NodeDef>,
}

#[derive(Deserialize)]
#[serde(rename_all = "snake_case")]
pub(super) enum NodeDef {
    Sequence(ControlDef),
    Fallback(ControlDef),
    Parallel(ParallelDef),
    Action(Box<ActionDef>),
    Condition(ConditionDef),
    Inverter(Box<DecoratorDef>),
    ForceSuccess(Box<DecoratorDef>),
    ForceFailure(Box<DecoratorDef>),
    Retry(Box<RetryDef>),
    Repeat(Box<RepeatDef>),
    UntilFailure(Box<DecoratorDef>),
    UntilSuccess(Box<DecoratorDef>),
    IfThenElse(ControlDef),
    Flow(FlowDef),
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct FlowDef {
    #[serde(default)]
    pub(super) name: Option<At<String>>,
    pub(super) children: At<Vec<At<NodeDef>>>,
    pub(super) states: At<Vec<At<StateDef>>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct StateDef {
    pub(super) run: At<f64>,
    pub(super) success: At<NextDef>,
    pub(super) failure: At<NextDef>,
}

/// Where a flow state leads: a state number or `success` / `failure`.
#[derive(Deserialize)]
#[serde(untagged)]
pub(super) enum NextDef {
    State(f64),
    Outcome(String),
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct DecoratorDef {
    #[serde(default)]
    pub(super) name: Option<At<String>>,
    pub(super) child: At<NodeDef>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RetryDef {
    #[serde(default)]
    pub(super) name: Option<At<String>>,
    pub(super) attempts: At<f64>,
    pub(super) child: At<NodeDef>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RepeatDef {
    #[serde(default)]
    pub(super) name: Option<At<String>>,
    pub(super) times: At<f64>,
    pub(super) child: At<NodeDef>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct ControlDef {
    #[serde(default)]
    pub(super) name: Option<At<String>>,
    pub(super) children: At<Vec<At<NodeDef>>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct ParallelDef {
    #[serde(default)]
    pub(super) name: Option<At<String>>,
    #[serde(default)]
    pub(super) success_threshold: Option<At<f64>>,
    #[serde(default)]
    pub(super) failure_threshold: Option<At<f64>>,
    pub(super) children: At<Vec<At<NodeDef>>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct ActionDef {
    #[serde(default)]
    pub(super) name: Option<At<String>>,
    pub(super) ps: At<f64>,
    #[serde(default)]
    pub(super) pf: Option<At<f64>>,
    #[serde(default)]
    pub(super) mu: Option<At<f64>>,
    #[serde(default)]
    pub(super) nu: Option<At<f64>>,
    #[serde(default)]
    pub(super) tau_s: Option<At<f64>>,
    #[serde(default)]
    pub(super) tau_f: Option<At<f64>>,
    #[serde(default)]
    pub(super) success_time: Option<At<TimeDef>>,
    #[serde(default)]
    pub(super) failure_time: Option<At<TimeDef>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct ConditionDef {
    #[serde(default)]
    pub(super) name: Option<At<String>>,
    pub(super) ps: At<f64>,
}
