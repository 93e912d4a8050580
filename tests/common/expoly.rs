//! Running `reference/expoly.py` (an independent closed-form reference for
//! mixed timing, in mpmath) on trees: their JSON form and the call.

use std::io::Write;
use std::path::PathBuf;
use std::process::{Command, Stdio};

use btrel::tree::{Decorator, Duration, FlowNext, NodeId, NodeKind, Tree};
use serde_json::{json, Value};

/// A number as the reference reads it: Rust's shortest round-trip decimal,
/// which for the trees' decimal inputs is the decimal written.
pub fn dec(x: f64) -> String {
    format!("{x}")
}

pub fn duration(d: Option<Duration>) -> Value {
    match d {
        None => Value::Null,
        Some(Duration::Exponential { rate }) => json!({"exp": dec(rate)}),
        Some(Duration::Fixed { time }) => json!({"fixed": dec(time)}),
        Some(Duration::TruncatedExponential { rate, cap }) => {
            json!({"trunc": [dec(rate), dec(cap)]})
        }
        Some(Duration::PhaseType { shift, stages }) => json!({"phases": {
            "shift": dec(shift),
            "stages": stages.iter().map(|(r, c)| json!([dec(r), c])).collect::<Vec<_>>()
        }}),
    }
}

/// The reference's JSON form of the subtree at `id` (`None` for node kinds
/// the reference does not model: loops without a bound, Nav2's nodes).
pub fn to_json(t: &Tree, id: NodeId) -> Option<Value> {
    let kids = |c: &[NodeId]| c.iter().map(|&c| to_json(t, c)).collect::<Option<Vec<_>>>();
    Some(match &t.node(id).kind {
        NodeKind::Action(a) => json!({"action": {
            "ps": dec(a.ps), "success": duration(a.success), "failure": duration(a.failure)
        }}),
        NodeKind::Condition { ps } => json!({ "condition": dec(*ps) }),
        NodeKind::Sequence { children } => json!({ "sequence": kids(children)? }),
        NodeKind::Fallback { children } => json!({ "fallback": kids(children)? }),
        NodeKind::Parallel {
            success_threshold,
            failure_threshold,
            children,
        } => json!({"parallel": {
            "m": success_threshold, "f": failure_threshold, "children": kids(children)?
        }}),
        NodeKind::Pipeline { .. }
        | NodeKind::RoundRobin { .. }
        | NodeKind::SequenceWithMemory { .. } => return None,
        NodeKind::Flow(f) => {
            let next = |n: FlowNext| match n {
                FlowNext::State(i) => json!(i),
                FlowNext::Success => json!("S"),
                FlowNext::Failure => json!("F"),
            };
            let states: Vec<Value> = f
                .states
                .iter()
                .map(|s| json!([s.child, next(s.on_success), next(s.on_failure)]))
                .collect();
            json!({"flow": {"children": kids(&f.children)?, "states": states}})
        }
        NodeKind::Decorator { decorator, child } => {
            let c = to_json(t, *child)?;
            match decorator {
                Decorator::Inverter => json!({ "inverter": c }),
                Decorator::ForceSuccess => json!({ "force_success": c }),
                Decorator::ForceFailure => json!({ "force_failure": c }),
                Decorator::Retry { attempts } => json!({"retry": [attempts, c]}),
                Decorator::Repeat { times } => json!({"repeat": [times, c]}),
                // loops and Nav2's stateful decorators are not modelled by the reference
                Decorator::UntilFailure
                | Decorator::UntilSuccess
                | Decorator::Rate { .. }
                | Decorator::SingleTrigger => return None,
            }
        }
    })
}

/// The reference's answer for `trees` (JSON forms) at `times` (decimal
/// strings): per tree, the nodes in pre-order (see reference/expoly.py).
pub fn expoly(py: &PathBuf, times: &[&str], trees: &[Value]) -> Vec<Vec<Value>> {
    run_expoly(py, json!({"times": times, "trees": trees}))
}

/// [`expoly`] keeping only what starts by `horizon` (at least every time):
/// each node's `success` and `failure` at the times, exact, without masses
/// or moments — for trees whose laws over all time are too large.
#[allow(dead_code)]
pub fn expoly_within(
    py: &PathBuf,
    times: &[&str],
    horizon: &str,
    trees: &[Value],
) -> Vec<Vec<Value>> {
    run_expoly(
        py,
        json!({"times": times, "horizon": horizon, "trees": trees}),
    )
}

fn run_expoly(py: &PathBuf, job: Value) -> Vec<Vec<Value>> {
    let input = job.to_string();
    let script = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("reference/expoly.py");
    let mut child = Command::new(py)
        .arg(&script)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("the reference starts");
    child
        .stdin
        .take()
        .expect("stdin")
        .write_all(input.as_bytes())
        .expect("input written");
    let out = child.wait_with_output().expect("the reference runs");
    assert!(
        out.status.success(),
        "reference/expoly.py failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("reference JSON")
}
