//! Storm's explicit DRN format ("direct encoding") of exact phase chains.
//!
//! One file holds the whole CTMC: states numbered as in the PRISM exports
//! (phases `0..n`, Success `n`, Failure `n + 1`), each with its exit rate
//! (`!E`), its rewards `[time, w_init]`, its labels (`init`, `success`,
//! `failure`, `done`) and its transition rates. Phases carry no label (a
//! label on every phase makes Storm 2.0's DRN parser about 15 times
//! slower): "running" is `!"done"`. Storm reads it
//! without building anything (`storm --explicit-drn FILE`, or stormpy's
//! `build_model_from_drn`), so it suits chains of millions of states.
//!
//! The initial distribution: every state of positive initial probability is
//! labelled `init`, and the reward model `w_init` holds that probability.
//! Storm reports results per initial state; the node's figure is the sum of
//! `w_init(s) · value(s)` over the states (see `scripts/storm_check.py`).
//! The absorbing states carry a self-loop at the chain's fastest exit rate,
//! for the reason given in [`super::explicit`].

use std::io::{self, Write};

use super::explicit::{absorbing_rate, initial_weights, row};
use super::prism::prism_number;
use crate::solve::chain::PhaseChain;

/// Writes `chain` as a Storm DRN file; `what` names it in the header
/// comment.
pub fn write_drn(chain: &PhaseChain, what: &str, w: &mut dyn Write) -> io::Result<()> {
    let n = chain.len();
    let states = n + 2;
    let absorbing = absorbing_rate(chain);
    let weights = initial_weights(chain);
    let what = what.replace(['\n', '\r'], " ");
    writeln!(w, "// Exact phase chain of {what}, exported by btrel.")?;
    writeln!(
        w,
        "// States 0..{} are phases, {n} is Success, {} is Failure. Weight per-state",
        n as isize - 1,
        n + 1
    )?;
    writeln!(
        w,
        "// results by the reward w_init (the initial distribution) and sum them."
    )?;
    writeln!(w, "@type: CTMC")?;
    writeln!(w, "@value_type: double")?;
    writeln!(w, "@parameters")?;
    writeln!(w)?;
    writeln!(w, "@reward_models")?;
    writeln!(w, "time w_init")?;
    writeln!(w, "@nr_states")?;
    writeln!(w, "{states}")?;
    writeln!(w, "@nr_choices")?;
    writeln!(w, "{states}")?;
    writeln!(w, "@model")?;
    let mut init = weights.iter().peekable();
    for i in 0..states {
        let out = row(chain, i, absorbing);
        let exit: f64 = out.iter().map(|&(_, r)| r).sum();
        let weight = match init.peek() {
            Some(&&(s, x)) if s == i => {
                init.next();
                Some(x)
            }
            _ => None,
        };
        write!(
            w,
            "state {i} !{} [{}, {}]",
            prism_number(exit),
            if i < n { "1.0" } else { "0.0" },
            prism_number(weight.unwrap_or(0.0))
        )?;
        if weight.is_some() {
            write!(w, " init")?;
        }
        let labels = match i {
            _ if i < n => "",
            _ if i == n => " success done",
            _ => " failure done",
        };
        writeln!(w, "{labels}")?;
        writeln!(w, "\taction 0")?;
        for (j, r) in out {
            writeln!(w, "\t\t{j} : {}", prism_number(r))?;
        }
    }
    Ok(())
}
