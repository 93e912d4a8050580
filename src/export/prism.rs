//! PRISM models of exact phase chains: a PRISM-language `ctmc` model
//! ([`prism_model`], [`prism_ctmc`]) and PRISM's explicit model files
//! ([`write_prism_explicit`]), for chains too large for one command per
//! transition.
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
//! `[] s>=n -> q : true;`, is a self-loop on the absorbing states so that
//! PRISM does not report them as deadlocks; its rate `q` is the chain's
//! fastest exit rate ([`absorbing_rate`]), so it does not raise PRISM's
//! uniformisation rate (PRISM's own deadlock fix would add rate-1 loops).
//! Labels: `"success"` (`s=n`), `"failure"` (`s=n+1`), `"done"` (either) and
//! `"running"`; the reward structure `"time"` earns 1 per unit time while
//! running, and `"w_init"` holds each state's initial probability (for
//! tools such as Storm whose property language cannot weight results by
//! a state expression).
//!
//! Rates and weights are written so that they parse back to the same `f64`
//! (shortest round-trip digits): plain decimals such as `0.0167` for
//! ordinary magnitudes, and scientific notation such as `1.5e-7` (which
//! PRISM's `REG_DOUBLE` token accepts) otherwise. Integral values get a
//! `.0` so PRISM never reads them as (overflowing) integer literals.
//!
//! The explicit files number the states the same way: `.tra` (header
//! `states transitions`, then `i j rate` sorted by `i` then `j`, parallel
//! transitions added up, the absorbing self-loops included), `.sta`
//! (variable `s`), `.lab` (`"init"`, `"success"`, `"failure"`, `"done"`,
//! `"running"`) and `.srew` (the time reward).
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
//!   distribution. [`PRISM_PROPERTIES`] holds the usual ones;
//!   [`prism_explicit_properties`] the same with the weights written out
//!   (an imported model has no formulas).
//!
//! A plain `P=? [...]` on such a model reports, per PRISM's default filter,
//! the value in the first initial state only, which is *not* the node's
//! figure when the initial distribution is a mixture.

use std::fmt::Write as _;
use std::io::{self, Write};

use super::explicit::{absorbing_rate, initial_weights, row, transition_count};
use super::prism_text::comment;
pub use super::prism_text::prism_number;
use crate::compile::phase::phase_chain;
use crate::compile::AnalysisError;
use crate::solve::chain::PhaseChain;
use crate::tree::{NodeId, Tree};

/// Properties for a model written by [`prism_model`]/[`prism_ctmc`]:
/// probabilities to have succeeded and failed by time `T` (give it with
/// `-const T=...`), the final success and failure probabilities and the
/// mean execution time, all over the node's initial distribution.
///
/// Usage: `prism node.sm btrel.csl -const T=100`; [`prism_properties`]
/// writes the times in instead (an imported model takes no `-const`).
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

/// The exact phase chain of node `node` as a PRISM CTMC (see the module
/// documentation for the format and the initial distribution). A Parallel
/// is written as one module per child ([`super::prism_parallel`]): PRISM
/// builds its product, which is not built here.
///
/// Errors like [`phase_chain`]: non-exponential leaves, or more than
/// `max_states` phases (for a Parallel: in one child's chain).
pub fn prism_ctmc(tree: &Tree, node: NodeId, max_states: usize) -> Result<String, AnalysisError> {
    if let Some(model) = super::prism_parallel::parallel_model(tree, node, max_states)? {
        return Ok(model);
    }
    let chain = phase_chain(tree, node, max_states)?;
    let n = tree.node(node);
    let what = format!("node '{}' ({})", comment(&n.name), n.kind.keyword());
    Ok(prism_model(&chain, &what))
}

/// A phase chain as a PRISM CTMC; `what` names it in the header comment.
pub fn prism_model(chain: &PhaseChain, what: &str) -> String {
    let n = chain.len();
    let (success, failure) = (n, n + 1);
    let weights = initial_weights(chain);

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
    let _ = writeln!(out, "formula w_init = {};\n", weight_expression(&weights));
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
    out.push_str("\n  // absorbing outcomes: a self-loop (so PRISM sees no deadlock) at the\n");
    out.push_str("  // fastest exit rate (so the uniformisation rate stays that of the phases)\n");
    let _ = writeln!(
        out,
        "  [] s>={success} -> {} : true;",
        prism_number(absorbing_rate(chain))
    );
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
    out.push_str("\n// the initial probability of each state, for tools that cannot use w_init\n");
    out.push_str("rewards \"w_init\"\n");
    for &(s, w) in &weights {
        let _ = writeln!(out, "  s={s} : {};", prism_number(w));
    }
    out.push_str("endrewards\n");
    out
}

/// `(s=i ? w : 0.0) + ...`: the initial probability of the current state.
fn weight_expression(weights: &[(usize, f64)]) -> String {
    if weights.is_empty() {
        return "0.0".to_string();
    }
    weights
        .iter()
        .map(|&(s, w)| format!("(s={s} ? {} : 0.0)", prism_number(w)))
        .collect::<Vec<_>>()
        .join(" + ")
}

/// The file extensions of PRISM's explicit model files written by
/// [`write_prism_explicit`], in its order.
pub const PRISM_EXPLICIT_EXTENSIONS: [&str; 4] = ["tra", "sta", "lab", "srew"];

/// Writes one of PRISM's explicit model files for `chain`: `ext` is one of
/// [`PRISM_EXPLICIT_EXTENSIONS`] (the transitions, states, labels and state
/// rewards files; see the module documentation). The files are streamed,
/// so chains of millions of states need no extra memory.
///
/// Import them with `prism -importmodel BASE.all -ctmc`; check them with
/// [`prism_explicit_properties`].
pub fn write_prism_explicit(chain: &PhaseChain, ext: &str, w: &mut dyn Write) -> io::Result<()> {
    let n = chain.len();
    let states = n + 2;
    match ext {
        "tra" => {
            let absorbing = absorbing_rate(chain);
            writeln!(w, "{states} {}", transition_count(chain))?;
            for i in 0..states {
                for (j, r) in row(chain, i, absorbing) {
                    writeln!(w, "{i} {j} {}", prism_number(r))?;
                }
            }
        }
        "sta" => {
            writeln!(w, "(s)")?;
            for i in 0..states {
                writeln!(w, "{i}:({i})")?;
            }
        }
        "lab" => {
            writeln!(
                w,
                "0=\"init\" 1=\"success\" 2=\"failure\" 3=\"done\" 4=\"running\""
            )?;
            let weights = initial_weights(chain);
            let mut init = weights.iter().map(|&(s, _)| s).peekable();
            for i in 0..states {
                let mut labels = String::new();
                if init.peek() == Some(&i) {
                    init.next();
                    labels.push_str(" 0");
                }
                labels.push_str(match i {
                    _ if i < n => " 4",
                    _ if i == n => " 1 3",
                    _ => " 2 3",
                });
                writeln!(w, "{i}:{labels}")?;
            }
        }
        "srew" => {
            writeln!(w, "{states} {n}")?;
            for i in 0..n {
                writeln!(w, "{i} 1.0")?;
            }
        }
        other => {
            return Err(io::Error::new(
                io::ErrorKind::InvalidInput,
                format!("no PRISM explicit file with extension .{other}"),
            ))
        }
    }
    Ok(())
}

/// Properties for the explicit files of [`write_prism_explicit`]: the same
/// figures as [`PRISM_PROPERTIES`], with the initial weights written out
/// over the variable `s` of the `.sta` file (an imported model has no
/// `w_init` formula) and the time reward as the model's only reward.
pub fn prism_explicit_properties(chain: &PhaseChain, times: &[f64]) -> String {
    let w = weight_expression(&initial_weights(chain));
    let mut out = String::new();
    out.push_str("// Properties for a phase-chain CTMC exported by btrel as PRISM explicit\n");
    out.push_str("// files (import with the .sta file, which defines the variable s):\n");
    if times.is_empty() {
        out.push_str("//   prism -importmodel BASE.all -ctmc THIS_FILE -const T=100\n");
    } else {
        let t = times_label(times[0]);
        let _ = writeln!(
            out,
            "//   prism -importmodel BASE.all -ctmc THIS_FILE -prop success_by_{t}"
        );
    }
    out.push_str("// Every figure is a sum over the \"init\" states weighted by their initial\n");
    out.push_str("// probability (the parenthesised expression).\n");
    if times.is_empty() {
        out.push_str("const double T;\n\n");
    } else {
        out.push('\n');
    }
    for (name, what) in timed_properties(times) {
        let _ = writeln!(out, "\"{name}\": filter(+, ({w}) * {what}, \"init\");");
    }
    out
}

/// The properties by name: with `times`, `success_by_<t>` and
/// `failure_by_<t>` for each, the time written in (PRISM refuses an
/// undefined constant on an imported model); without, `success_by_T` and
/// `failure_by_T` over the constant `T` (declared before them).
fn timed_properties(times: &[f64]) -> Vec<(String, String)> {
    let mut out = Vec::new();
    if times.is_empty() {
        for o in ["success", "failure"] {
            out.push((format!("{o}_by_T"), format!("P=? [ F<=T \"{o}\" ]")));
        }
    } else {
        let mut seen = std::collections::HashSet::new();
        for &t in times.iter().filter(|&&t| seen.insert(t.to_bits())) {
            for o in ["success", "failure"] {
                out.push((
                    format!("{o}_by_{}", times_label(t)),
                    format!("P=? [ F<={} \"{o}\" ]", prism_number(t)),
                ));
            }
        }
    }
    for (name, what) in [
        ("ps", "P=? [ F \"success\" ]"),
        ("pf", "P=? [ F \"failure\" ]"),
        ("mean_time", "R=? [ F \"done\" ]"),
    ] {
        out.push((name.to_string(), what.to_string()));
    }
    out
}

/// The properties file for a model written by [`prism_model`]/[`prism_ctmc`]:
/// [`PRISM_PROPERTIES`] without `times`; with them, the same figures with
/// each time written in (`success_by_100`: no `-const` needed).
pub fn prism_properties(times: &[f64]) -> String {
    if times.is_empty() {
        return PRISM_PROPERTIES.to_string();
    }
    let mut out = String::new();
    out.push_str("// Properties for a phase-chain CTMC exported by btrel.\n");
    out.push_str("// The model's initial distribution is `w_init` over its initial states, so\n");
    out.push_str("// every figure is a w_init-weighted sum over the \"init\" states.\n\n");
    for (name, what) in timed_properties(times) {
        let what = what.replace("R=?", "R{\"time\"}=?");
        let _ = writeln!(out, "\"{name}\": filter(+, w_init * {what}, \"init\");");
    }
    out
}

/// A time as it appears in a property's name, which PRISM reads as an
/// identifier: Rust's shortest decimal form with `p` for the point (`100`,
/// `2p5`, `0p0000001`).
fn times_label(t: f64) -> String {
    format!("{t}").replace('.', "p")
}
