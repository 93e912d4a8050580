//! A phase chain as an explicit state list, shared by the PRISM (language
//! and explicit files) and Storm (DRN) exporters.
//!
//! States `0..n` are the chain's phases, `n` is Success and `n + 1` is
//! Failure, so every exporter numbers the states the same way (the PRISM
//! variable `s` equals the state index).
//!
//! # Absorbing states and uniformisation
//!
//! Success and Failure have no outgoing transition. Model checkers treat a
//! state without transitions as a *deadlock* and "fix" it by adding a
//! self-loop of rate 1 (PRISM does this both for PRISM-language models and
//! for imported `.tra` files). A CTMC self-loop changes no probability or
//! time, but it counts in the exit rate from which PRISM and Storm derive
//! the uniformisation rate `q ≥ max_i E(i)`: with rates of `0.01/s`, a
//! rate-1 loop makes transient analysis iterate tens of times more than
//! needed. So the exporters give the absorbing states an explicit self-loop
//! whose rate is [`absorbing_rate`]: the chain's fastest exit rate, which
//! leaves `max_i E(i)` — and so the uniformisation rate — unchanged.

use crate::solve::chain::PhaseChain;

/// The rate of the self-loops on the absorbing Success and Failure states:
/// the largest exit rate of any phase (1 for a chain without phases, where
/// nothing is ever uniformised). Each exit rate is summed over the phase's
/// [`row`] in target order, as a checker reading the explicit files sums it,
/// so the loops do not exceed it even by rounding.
pub fn absorbing_rate(chain: &PhaseChain) -> f64 {
    let max = (0..chain.len())
        .map(|i| row(chain, i, 0.0).iter().map(|&(_, r)| r).sum::<f64>())
        .fold(0.0f64, f64::max);
    if max > 0.0 && max.is_finite() {
        max
    } else {
        1.0
    }
}

/// The initial distribution over states: `(state, probability)` with
/// positive probabilities, sorted by state, duplicates merged; instantaneous
/// Success and Failure are mass on states `n` and `n + 1`.
pub(crate) fn initial_weights(chain: &PhaseChain) -> Vec<(usize, f64)> {
    let n = chain.len();
    let mut weights: Vec<(usize, f64)> = chain
        .initial
        .iter()
        .copied()
        .chain([(n, chain.initial_success), (n + 1, chain.initial_failure)])
        .filter(|&(_, w)| w > 0.0)
        .collect();
    weights.sort_by_key(|&(s, _)| s);
    weights.dedup_by(|later, earlier| {
        if later.0 == earlier.0 {
            earlier.1 += later.1;
            true
        } else {
            false
        }
    });
    weights
}

/// The outgoing transitions of state `i` (`0..n + 2`) as `(target, rate)`,
/// sorted by target, parallel transitions to the same target added up (as
/// PRISM's CTMC semantics adds parallel commands), zero rates dropped; the
/// absorbing states have their self-loop of rate `absorbing`.
pub fn row(chain: &PhaseChain, i: usize, absorbing: f64) -> Vec<(usize, f64)> {
    let n = chain.len();
    if i >= n {
        return vec![(i, absorbing)];
    }
    let mut out: Vec<(usize, f64)> = chain.transitions[i]
        .iter()
        .copied()
        .chain([(n, chain.exit_success[i]), (n + 1, chain.exit_failure[i])])
        .filter(|&(_, r)| r > 0.0)
        .collect();
    out.sort_by_key(|&(j, _)| j);
    out.dedup_by(|later, earlier| {
        if later.0 == earlier.0 {
            earlier.1 += later.1;
            true
        } else {
            false
        }
    });
    out
}

/// Number of transitions over all states, self-loops of the absorbing
/// states included (the `.tra` header's count).
pub(crate) fn transition_count(chain: &PhaseChain) -> usize {
    (0..chain.len())
        .map(|i| row(chain, i, 1.0).len())
        .sum::<usize>()
        + 2
}
