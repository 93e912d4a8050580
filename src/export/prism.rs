//! PRISM models of exact phase chains.
//!
//! # Format
//!
//! A node's exact phase chain ([`phase_chain`]) with `n` phases becomes a
//! PRISM `ctmc` with one module `btrel` and one variable `s : [0..n+1]`:
//! `s = i < n` is phase `i`, `s = n` is Success and `s = n + 1` is Failure
//! (both absorbing). Every nonzero transition `i → j` of rate `r` is one
//! command `[] s=i -> r : (s'=j);`, and every nonzero exit to Success or
//! Failure one command to `s=n` or `s=n+1`; parallel commands between the
//! same states add up, as PRISM's CTMC semantics says. One last command,
//! `[] s>=n -> 1 : true;`, is a self-loop on the absorbing states so that
//! PRISM does not report them as deadlocks (a CTMC self-loop changes no
//! probability or time). Labels: `"success"` (`s=n`), `"failure"`
//! (`s=n+1`), `"done"` (either) and `"running"`; the reward structure
//! `"time"` earns 1 per unit time while running.
//!
//! Rates and weights are written so that they parse back to the same `f64`
//! (shortest round-trip digits): plain decimals such as `0.0167` for
//! ordinary magnitudes, and scientific notation such as `1.5e-7` (which
//! PRISM's `REG_DOUBLE` token accepts) otherwise. Integral values get a
//! `.0` so PRISM never reads them as (overflowing) integer literals.
//!
//! # The initial distribution
//!
//! A node's run starts in a *distribution* over phases (an action is a
//! mixture of its success and failure phases), possibly with instantaneous
//! Success or Failure mass (conditions). A PRISM model has a *set* of
//! initial states, not a distribution, and in a CTMC no "start" state can
//! branch in zero time without changing the timing. So, exactly:
//!
//! * every state of positive initial probability is an initial state (`init
//!   ... endinit`, or `s : [..] init k` when there is only one), including
//!   `s=n` / `s=n+1` for instantaneous Success / Failure;
//! * the model defines `formula w_init`, the initial probability of the
//!   current state (0 outside the initial set);
//! * properties weight the per-state results by `w_init` and sum over the
//!   initial states: `filter(+, w_init * P=? [ F<=T "success" ], "init")` is
//!   the node's probability to have succeeded by time `T` from its initial
//!   distribution. [`PRISM_PROPERTIES`] holds the usual ones.
//!
//! A plain `P=? [...]` on such a model reports, per PRISM's default filter,
//! the value in the first initial state only, which is *not* the node's
//! figure when the initial distribution is a mixture.

use std::fmt::Write as _;

use crate::compile::phase::phase_chain;
use crate::compile::AnalysisError;
use crate::solve::chain::PhaseChain;
use crate::tree::{NodeId, Tree};

/// Properties for a model written by [`prism_model`]/[`prism_ctmc`]:
/// probabilities to have succeeded and failed by time `T` (give it with
/// `-const T=...`), the final success and failure probabilities and the
/// mean execution time, all over the node's initial distribution.
///
/// Usage: `prism node.sm btrel.csl -const T=100`.
pub const PRISM_PROPERTIES: &str = r#"// Properties for a phase-chain CTMC exported by btrel.
// The model's initial distribution is `w_init` over its initial states, so
// every figure is a w_init-weighted sum over the "init" states.
const double T;

// Probability that the node has succeeded (failed) by time T
"success_by_T": filter(+, w_init * P=? [ F<=T "success" ], "init");
"failure_by_T": filter(+, w_init * P=? [ F<=T "failure" ], "init");

// Probability of Success and of Failure (ps, pf)
"ps": filter(+, w_init * P=? [ F "success" ], "init");
"pf": filter(+, w_init * P=? [ F "failure" ], "init");

// Mean execution time E[T] = ps*MTTS + pf*MTTF
"mean_time": filter(+, w_init * R{"time"}=? [ F "done" ], "init");
"#;

/// A number PRISM parses back to exactly `x` (`x ≥ 0`, finite).
pub fn prism_number(x: f64) -> String {
    let a = x.abs();
    if x == 0.0 {
        "0.0".to_string()
    } else if (1e-4..1e15).contains(&a) {
        let s = format!("{x}");
        if s.contains('.') {
            s
        } else {
            format!("{s}.0")
        }
    } else {
        format!("{x:e}")
    }
}

fn comment(text: &str) -> String {
    text.replace(['\n', '\r'], " ")
}

/// The exact phase chain of node `node` as a PRISM CTMC (see the module
/// documentation for the format and the initial distribution).
///
/// Errors like [`phase_chain`]: non-exponential leaves, or more than
/// `max_states` phases.
pub fn prism_ctmc(tree: &Tree, node: NodeId, max_states: usize) -> Result<String, AnalysisError> {
    let chain = phase_chain(tree, node, max_states)?;
    let n = tree.node(node);
    let what = format!("node '{}' ({})", comment(&n.name), n.kind.keyword());
    Ok(prism_model(&chain, &what))
}

/// A phase chain as a PRISM CTMC; `what` names it in the header comment.
pub fn prism_model(chain: &PhaseChain, what: &str) -> String {
    let n = chain.len();
    let (success, failure) = (n, n + 1);
    // initial weights per state, duplicates merged, zeros dropped
    let mut weights: Vec<(usize, f64)> = Vec::new();
    let mut add = |state: usize, w: f64| {
        if w > 0.0 {
            match weights.iter_mut().find(|(s, _)| *s == state) {
                Some((_, x)) => *x += w,
                None => weights.push((state, w)),
            }
        }
    };
    for &(i, w) in &chain.initial {
        add(i, w);
    }
    add(success, chain.initial_success);
    add(failure, chain.initial_failure);
    weights.sort_by_key(|&(s, _)| s);

    let mut out = String::new();
    let _ = writeln!(
        out,
        "// Exact phase chain of {}, exported by btrel.",
        comment(what)
    );
    let _ = writeln!(
        out,
        "// s = 0..{} are phases, s = {success} is Success, s = {failure} is Failure.",
        n as isize - 1
    );
    out.push_str("// Initial distribution (check properties weighted by w_init, see btrel's\n");
    out.push_str("// PRISM_PROPERTIES; a plain P=? reports the first initial state only):\n");
    for &(s, w) in &weights {
        let _ = writeln!(out, "//   P(s = {s}) = {}", prism_number(w));
    }
    out.push_str("\nctmc\n\n");
    let w_init = if weights.is_empty() {
        "0.0".to_string()
    } else {
        weights
            .iter()
            .map(|&(s, w)| format!("(s={s} ? {} : 0.0)", prism_number(w)))
            .collect::<Vec<_>>()
            .join(" + ")
    };
    let _ = writeln!(out, "formula w_init = {w_init};\n");
    let _ = writeln!(out, "label \"success\" = s={success};");
    let _ = writeln!(out, "label \"failure\" = s={failure};");
    let _ = writeln!(out, "label \"done\" = s>={success};");
    let _ = writeln!(out, "label \"running\" = s<{success};\n");
    out.push_str("module btrel\n");
    if weights.len() == 1 {
        let _ = writeln!(out, "  s : [0..{failure}] init {};\n", weights[0].0);
    } else {
        let _ = writeln!(out, "  s : [0..{failure}];\n");
    }
    for i in 0..n {
        for &(j, r) in &chain.transitions[i] {
            if r > 0.0 {
                let _ = writeln!(out, "  [] s={i} -> {} : (s'={j});", prism_number(r));
            }
        }
        for (r, to) in [
            (chain.exit_success[i], success),
            (chain.exit_failure[i], failure),
        ] {
            if r > 0.0 {
                let _ = writeln!(out, "  [] s={i} -> {} : (s'={to});", prism_number(r));
            }
        }
    }
    out.push_str("\n  // absorbing outcomes (a self-loop, so PRISM sees no deadlock)\n");
    let _ = writeln!(out, "  [] s>={success} -> 1.0 : true;");
    out.push_str("endmodule\n");
    if weights.len() != 1 {
        let init = weights
            .iter()
            .map(|&(s, _)| format!("s={s}"))
            .collect::<Vec<_>>()
            .join(" | ");
        let init = if init.is_empty() {
            "false".to_string()
        } else {
            init
        };
        let _ = writeln!(out, "\ninit\n  {init}\nendinit");
    }
    out.push_str("\nrewards \"time\"\n");
    let _ = writeln!(out, "  s<{success} : 1.0;");
    out.push_str("endrewards\n");
    out
}
