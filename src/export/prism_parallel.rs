//! A Parallel node as a *modular* PRISM model: one module per child,
//! interleaved, instead of one command per state of their product.
//!
//! PRISM builds a model from its modules symbolically, so a Parallel whose
//! product chain has tens of thousands of states (an 8-action Parallel with
//! `success_threshold: 4`: 56,290) is built in a moment from eight small
//! modules, where the flat export ([`super::prism::prism_model`], one
//! command per product state) takes PRISM minutes to parse and build.
//!
//! # Format
//!
//! The children of a Parallel run independently until the node decides
//! (continuous time: no two children return at once), which is exactly
//! PRISM's interleaving of unsynchronised CTMC modules. So:
//!
//! * each child whose subtree is not itself split ("part") becomes a module
//!   `c<k>` over one variable `s<k> : [0..n+1]`, its own exact phase chain
//!   numbered as in the flat export (`s<k> = n` Success, `n + 1` Failure);
//!   formulas `c<k>_s` / `c<k>_f` say it has succeeded / failed;
//! * a Parallel `p<j>` counts its parts' successes and failures:
//!   `p<j>_s` is "at least M successes", `p<j>_f` "at least
//!   min(F, N − M + 1) failures" (the failure threshold, or M successes no
//!   longer possible); `p<j>_run` is "running": its parent runs and it has
//!   not decided. Every command of a part is guarded by its Parallel's
//!   `_run`, so a decided Parallel stops its children, as a halt does;
//! * a Parallel child of a Parallel is split the same way (nested modules),
//!   unless one of its children can return at once (a condition): then it
//!   is one part with its own product chain, because which of several
//!   instantaneous returns decides depends on the tick order, not on counts;
//! * module `outcome` holds `o : [0..2]`: 0 while the node runs or has
//!   returned by a child's event, 1 / 2 for the instantaneous Success /
//!   Failure the tick order gives at time 0 (children visited in order,
//!   the node returns at the first threshold met, as in BehaviorTree.CPP),
//!   and the self-loop on the decided states (rate: the sum of the parts'
//!   fastest exit rates, at least PRISM's uniformisation rate of the
//!   running states; see the flat export for why not 1).
//!
//! Labels, rewards, the properties and `w_init` are those of the flat export
//! ([`super::prism::PRISM_PROPERTIES`]): the initial states are the tuples
//! of the parts' initial states that have not decided (each weighted by the
//! product of the parts' initial probabilities) and the two `o` states;
//! `w_init` is 0 outside them. Same figures as the flat export, to the
//! rounding of the products.

use std::fmt::Write as _;

use super::explicit::initial_weights;
use super::prism_text::{comment, prism_number};
use crate::compile::phase::chain_of;
use crate::compile::AnalysisError;
use crate::ir::{Graph, Op};
use crate::solve::chain::PhaseChain;
use crate::tree::{NodeId, Tree};

/// One part of the modular model.
enum Part {
    /// A module: a subtree's exact phase chain.
    Chain { name: String, chain: PhaseChain },
    /// A Parallel split into its children's parts.
    Parallel {
        name: String,
        /// Success at this many successes.
        successes: usize,
        /// Failure at this many failures.
        failures: usize,
        parts: Vec<Part>,
    },
}

impl Part {
    /// The probability that the part returns Success / Failure at once.
    fn instant(&self) -> (f64, f64) {
        match self {
            Part::Chain { chain, .. } => (chain.initial_success, chain.initial_failure),
            // split only when no child returns at once
            Part::Parallel { .. } => (0.0, 0.0),
        }
    }
}

/// The modular PRISM model of node `id` when it is a Parallel (after the
/// Nav2 view), `None` otherwise. Each part's chain is limited to
/// `max_states` phases; their product is not built.
pub(super) fn parallel_model(
    tree: &Tree,
    id: NodeId,
    max_states: usize,
) -> Result<Option<String>, AnalysisError> {
    let lowered = crate::compile::lower(tree)?;
    let (tree, id) = (&lowered.graph, lowered.node(id));
    if !matches!(tree.node(id).kind, Op::KOfN { .. }) {
        return Ok(None);
    }
    let top = part(tree, id, true, max_states)?;
    Ok(Some(Writer::default().model(&top)))
}

fn part(tree: &Graph, id: NodeId, top: bool, max_states: usize) -> Result<Part, AnalysisError> {
    let node = tree.node(id);
    if let Op::KOfN {
        success: success_threshold,
        failure: failure_threshold,
        children,
    } = &node.kind
    {
        let parts = children
            .iter()
            .map(|&c| part(tree, c, false, max_states))
            .collect::<Result<Vec<_>, _>>()?;
        let at_once = parts.iter().any(|p| {
            let (s, f) = p.instant();
            s + f > 0.0
        });
        if top || !at_once {
            let n = children.len();
            return Ok(Part::Parallel {
                name: node.name.clone(),
                successes: *success_threshold,
                failures: (*failure_threshold).min(n + 1 - success_threshold.min(&n)),
                parts,
            });
        }
    }
    Ok(Part::Chain {
        name: node.name.clone(),
        chain: chain_of(tree, id, max_states)?,
    })
}

/// The model's text, written in one walk of the parts.
#[derive(Default)]
struct Writer {
    /// Modules: `(name, variable declaration and commands)`.
    modules: Vec<(String, String)>,
    /// The `_s` / `_f` formulas, each after those it uses (post-order).
    formulas: Vec<String>,
    /// The `_run` formulas, each after its parent's (pre-order).
    runs: Vec<String>,
    /// Number of chain parts and of Parallels numbered so far.
    chains: usize,
    parallels: usize,
    /// Product of the parts' state counts (`n + 2` each).
    states: f64,
}

/// What a written part offers its Parallel.
struct Written {
    /// Formulas "has succeeded", "has failed".
    succeeded: String,
    failed: String,
    /// The part's initial states (a predicate) and their initial
    /// probability (an expression, 0 outside them).
    support: String,
    weight: String,
    /// The part's fastest total exit rate.
    fastest: f64,
}

impl Writer {
    fn model(mut self, top: &Part) -> String {
        let Part::Parallel { name, parts, .. } = top else {
            unreachable!("the top part is a Parallel")
        };
        self.states = 1.0;
        let written = self.write(top, "o=0");
        let (at_once_s, at_once_f) = instant_outcome(top);
        let fastest = if written.fastest > 0.0 && written.fastest.is_finite() {
            written.fastest
        } else {
            1.0
        };
        let zero: String = self
            .modules
            .iter()
            .map(|(v, _)| format!(" & {v}=0"))
            .collect();

        let mut out = String::new();
        let _ = writeln!(
            out,
            "// Parallel node '{}' as one module per part, exported by btrel.",
            comment(name)
        );
        let _ = writeln!(
            out,
            "// {} children, {} modules; their product has at most {} states (PRISM builds it).",
            parts.len(),
            self.modules.len(),
            self.states
        );
        out.push_str(
            "// Module c<k>: a part's exact phase chain (s<k> = n Success, n+1 Failure);\n",
        );
        out.push_str("// p<j>: a Parallel (p<j>_s / p<j>_f: it has succeeded / failed);\n");
        out.push_str("// o = 1 / 2: Success / Failure at once (the tick order at time 0).\n");
        out.push_str("// Check properties weighted by w_init (see btrel's PRISM_PROPERTIES).\n");
        out.push_str("\nctmc\n\n");
        for f in self.formulas.iter().chain(&self.runs) {
            out.push_str(f);
            out.push('\n');
        }
        let _ = writeln!(out, "formula done = !p0_run;");
        let _ = writeln!(
            out,
            "formula w_init = o=1 ? {} : (o=2 ? {} : (done ? 0.0 : {}));\n",
            prism_number(at_once_s),
            prism_number(at_once_f),
            written.weight
        );
        out.push_str("label \"success\" = o=1 | (o=0 & p0_s);\n");
        out.push_str("label \"failure\" = o=2 | (o=0 & p0_f);\n");
        out.push_str("label \"done\" = done;\n");
        out.push_str("label \"running\" = !done;\n\n");
        for (_, text) in &self.modules {
            out.push_str(text);
        }
        out.push_str("module outcome\n  o : [0..2];\n\n");
        out.push_str(
            "  // decided states: a self-loop (so PRISM sees no deadlock) at the sum of\n",
        );
        out.push_str("  // the parts' fastest exit rates (the uniformisation rate stays theirs)\n");
        let _ = writeln!(out, "  [] done -> {} : true;", prism_number(fastest));
        out.push_str("endmodule\n\n");
        let mut init = Vec::new();
        if at_once_s > 0.0 {
            init.push(format!("(o=1{zero})"));
        }
        if at_once_f > 0.0 {
            init.push(format!("(o=2{zero})"));
        }
        if at_once_s + at_once_f < 1.0 {
            init.push(format!("(o=0 & !p0_s & !p0_f & {})", written.support));
        }
        let _ = writeln!(out, "init\n  {}\nendinit\n", init.join("\n  | "));
        out.push_str("rewards \"time\"\n  !done : 1.0;\nendrewards\n\n");
        out.push_str(
            "// the initial probability of each state, for tools that cannot use w_init\n",
        );
        out.push_str("rewards \"w_init\"\n  true : w_init;\nendrewards\n");
        out
    }

    /// Writes part `p`, whose commands run while `run` holds.
    fn write(&mut self, p: &Part, run: &str) -> Written {
        match p {
            Part::Chain { name, chain } => {
                let k = self.chains;
                self.chains += 1;
                let v = format!("s{k}");
                let n = chain.len();
                self.states *= (n + 2) as f64;
                let mut text = format!("// child '{}'\nmodule c{k}\n", comment(name));
                let _ = writeln!(text, "  {v} : [0..{}];\n", n + 1);
                let mut fastest = 0.0f64;
                for i in 0..n {
                    fastest = fastest.max(chain.total_rate(i));
                    let exits = [(chain.exit_success[i], n), (chain.exit_failure[i], n + 1)];
                    for (j, r) in chain.transitions[i]
                        .iter()
                        .copied()
                        .chain(exits.iter().map(|&(r, j)| (j, r)))
                    {
                        if r > 0.0 {
                            let _ = writeln!(
                                text,
                                "  [] {run} & {v}={i} -> {} : ({v}'={j});",
                                prism_number(r)
                            );
                        }
                    }
                }
                text.push_str("endmodule\n\n");
                self.modules.push((v.clone(), text));
                self.formulas.push(format!("formula c{k}_s = {v}={n};"));
                self.formulas
                    .push(format!("formula c{k}_f = {v}={};", n + 1));
                let weights = initial_weights(chain);
                let support = weights
                    .iter()
                    .map(|&(s, _)| format!("{v}={s}"))
                    .collect::<Vec<_>>()
                    .join(" | ");
                let weight = weights
                    .iter()
                    .rev()
                    .fold("0.0".to_string(), |rest, &(s, w)| {
                        format!("({v}={s} ? {} : {rest})", prism_number(w))
                    });
                Written {
                    succeeded: format!("c{k}_s"),
                    failed: format!("c{k}_f"),
                    support: format!(
                        "({})",
                        if support.is_empty() {
                            "false"
                        } else {
                            &support
                        }
                    ),
                    weight,
                    fastest,
                }
            }
            Part::Parallel {
                successes,
                failures,
                parts,
                ..
            } => {
                let j = self.parallels;
                self.parallels += 1;
                let p = format!("p{j}");
                let own_run = format!("{p}_run");
                // pre-order: after its parent's
                self.runs
                    .push(format!("formula {own_run} = {run} & !{p}_s & !{p}_f;"));
                let written: Vec<Written> = parts.iter().map(|q| self.write(q, &own_run)).collect();
                // post-order: after its parts'
                let (s, f) = counts(&p, *successes, *failures, &written);
                self.formulas.push(s);
                self.formulas.push(f);
                Written {
                    succeeded: format!("{p}_s"),
                    failed: format!("{p}_f"),
                    support: written
                        .iter()
                        .map(|w| w.support.as_str())
                        .collect::<Vec<_>>()
                        .join(" & "),
                    weight: written
                        .iter()
                        .map(|w| w.weight.as_str())
                        .collect::<Vec<_>>()
                        .join(" * "),
                    fastest: written.iter().map(|w| w.fastest).sum(),
                }
            }
        }
    }
}

/// The formulas `<p>_s` and `<p>_f` of a Parallel over `parts`.
fn counts(p: &str, successes: usize, failures: usize, parts: &[Written]) -> (String, String) {
    let sum = |f: &dyn Fn(&Written) -> &str| {
        parts
            .iter()
            .map(|w| format!("({} ? 1 : 0)", f(w)))
            .collect::<Vec<_>>()
            .join(" + ")
    };
    (
        format!(
            "formula {p}_s = {} >= {successes};",
            sum(&|w| w.succeeded.as_str())
        ),
        format!(
            "formula {p}_f = {} >= {failures};",
            sum(&|w| w.failed.as_str())
        ),
    )
}

/// The probabilities that a Parallel returns Success / Failure at time 0:
/// its children visited in order, each returning at once with its
/// instantaneous probabilities, the node returning at the first threshold
/// met.
fn instant_outcome(top: &Part) -> (f64, f64) {
    let Part::Parallel {
        successes,
        failures,
        parts,
        ..
    } = top
    else {
        return top.instant();
    };
    let (successes, failures, n) = (*successes, *failures, parts.len());
    // running mass by (successes, failures) so far
    let mut mass = vec![vec![0.0f64; n + 1]; n + 1];
    mass[0][0] = 1.0;
    let (mut at_s, mut at_f) = (0.0, 0.0);
    for part in parts {
        let (qs, qf) = part.instant();
        let qr = (1.0 - qs - qf).max(0.0);
        let mut next = vec![vec![0.0f64; n + 1]; n + 1];
        for (s, row) in mass.iter().enumerate() {
            for (f, &m) in row.iter().enumerate() {
                if m == 0.0 {
                    continue;
                }
                for (ds, df, q) in [(1, 0, qs), (0, 1, qf), (0, 0, qr)] {
                    if q <= 0.0 {
                        continue;
                    }
                    let (s2, f2) = (s + ds, f + df);
                    if s2 >= successes {
                        at_s += m * q;
                    } else if f2 >= failures {
                        at_f += m * q;
                    } else {
                        next[s2][f2] += m * q;
                    }
                }
            }
        }
        mass = next;
    }
    (at_s, at_f)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A part returning at once with these probabilities (a condition).
    fn at_once(ps: f64, pf: f64) -> Part {
        Part::Chain {
            name: String::new(),
            chain: PhaseChain {
                initial_success: ps,
                initial_failure: pf,
                ..PhaseChain::default()
            },
        }
    }

    fn parallel(successes: usize, failures: usize, parts: Vec<Part>) -> Part {
        Part::Parallel {
            name: String::new(),
            successes,
            failures,
            parts,
        }
    }

    #[test]
    fn the_tick_order_decides_at_time_0() {
        // Success at 1, Failure at 1: a failing first child fails the node
        // although a later one succeeds (counts alone would say both)
        let p = parallel(1, 1, vec![at_once(0.0, 1.0), at_once(1.0, 0.0)]);
        assert_eq!(instant_outcome(&p), (0.0, 1.0));
        let p = parallel(1, 1, vec![at_once(1.0, 0.0), at_once(0.0, 1.0)]);
        assert_eq!(instant_outcome(&p), (1.0, 0.0));
    }

    #[test]
    fn instant_outcomes_by_hand() {
        // tests/data/parallel-modules.yaml's root, M = 2, F = 2: c1 (ps
        // 0.5), an action, c2 (ps 0.3), a Parallel without instant
        // returns, "guarded" (Success at once iff its condition, 0.2).
        // Failure: c1 and c2 fail, 0.5·0.7 = 0.35. Success: c1 and c2
        // succeed, 0.15; or one of them and "guarded": 0.5·0.7·0.2 +
        // 0.5·0.3·0.2 = 0.1; total 0.25.
        let action = Part::Chain {
            name: String::new(),
            chain: PhaseChain {
                initial: vec![(0, 1.0)],
                transitions: vec![vec![]],
                exit_success: vec![1.0],
                exit_failure: vec![0.0],
                ..PhaseChain::default()
            },
        };
        let inner = parallel(1, 1, vec![]);
        let p = parallel(
            2,
            2,
            vec![
                at_once(0.5, 0.5),
                action,
                at_once(0.3, 0.7),
                inner,
                at_once(0.2, 0.0),
            ],
        );
        let (s, f) = instant_outcome(&p);
        assert!(
            (s - 0.25).abs() < 1e-15 && (f - 0.35).abs() < 1e-15,
            "{s} {f}"
        );
    }
}
