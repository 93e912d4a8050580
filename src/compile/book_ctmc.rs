//! The book's CTMC of a control node (Section 9.3.3).
//!
//! Each child h is summarised as in the chapter's recursion: it leaves its
//! marking at rate `1 / SJ_h`, `SJ_h = ps_h/mu_h + pf_h/nu_h` (9.41), with
//! Success or Failure in proportion `ps_h : pf_h`. A marking's generator
//! row is the sum over its feasible children (9.38)–(9.40), so its sojourn
//! is exponential with mean (9.40). This is the chain whose transient
//! solution the book plots; it replaces every child's time distribution by
//! a single exponential, which is where it departs from the exact chain.
//!
//! Children of zero mean duration (conditions, or subtrees of conditions)
//! would have infinite rates: markings where one is feasible are vanishing,
//! and are eliminated by routing their probability straight on.

use super::mrg::{Mrg, Outcome, Policy, Status};
use super::Figures;
use crate::solve::chain::PhaseChain;

#[derive(Clone, Default)]
struct Entry {
    phases: Vec<(usize, f64)>,
    success: f64,
    failure: f64,
}

impl Entry {
    fn add_scaled(&mut self, other: &Entry, w: f64) {
        self.phases
            .extend(other.phases.iter().map(|&(j, p)| (j, p * w)));
        self.success += other.success * w;
        self.failure += other.failure * w;
    }
}

/// The book's CTMC of a loop whose child is summarised by `child`: the
/// node summarised by its own figures, as the book does.
pub(crate) fn book_loop(until: Outcome, child: Figures) -> PhaseChain {
    let f = super::loop_figures(until, child);
    let mut c = PhaseChain::default();
    for (p, t, success) in [(f.ps, f.mtts, true), (f.pf, f.mttf, false)] {
        if p <= 0.0 {
            continue;
        }
        match t {
            Some(t) if t > 0.0 => {
                let i = c.push_phase();
                if success {
                    c.exit_success[i] = 1.0 / t;
                } else {
                    c.exit_failure[i] = 1.0 / t;
                }
                c.initial.push((i, p));
            }
            _ if success => c.initial_success += p,
            _ => c.initial_failure += p,
        }
    }
    c
}

/// The book's CTMC of a map (inverter, force decorator, identity): the
/// child's one exponential phase (rate 1/SJ) leads to the mapped outcomes;
/// a map to one outcome sends all its mass there.
pub(crate) fn book_map(on_success: Outcome, on_failure: Outcome, child: Figures) -> PhaseChain {
    let (s, f) = match (on_success, on_failure) {
        (Outcome::Success, Outcome::Failure) => (child.ps, child.pf),
        (Outcome::Failure, Outcome::Success) => (child.pf, child.ps),
        (Outcome::Success, Outcome::Success) => (1.0, 0.0),
        (Outcome::Failure, Outcome::Failure) => (0.0, 1.0),
    };
    let sj = child.mean_time();
    if sj == 0.0 {
        return PhaseChain {
            initial_success: s,
            initial_failure: f,
            ..PhaseChain::default()
        };
    }
    let mut c = PhaseChain::default();
    let i = c.push_phase();
    c.exit_success[i] = s / sj;
    c.exit_failure[i] = f / sj;
    c.initial.push((i, 1.0));
    c
}

/// The book's CTMC of a flow repeating its child `times` times (a Retry
/// is a Fallback of fresh copies, a Repeat a Sequence).
pub(crate) fn book_repeat(times: usize, stop: Outcome, child: Figures) -> PhaseChain {
    book_ctmc(
        &Mrg::build(Policy::stopping_at(stop), times),
        &vec![child; times],
    )
}

/// The book's CTMC over `g` with children summarised by `children`.
pub fn book_ctmc(g: &Mrg, children: &[Figures]) -> PhaseChain {
    let sojourn = |h: usize| children[h].mean_time();
    let events_of = |m: usize| {
        let start = g.events.partition_point(|e| e.from < m);
        let end = g.events.partition_point(|e| e.from <= m);
        &g.events[start..end]
    };
    let vanishing_child = |m: usize| {
        events_of(m)
            .iter()
            .map(|e| e.child)
            .find(|&h| sojourn(h) == 0.0)
    };
    // phases: running markings that are not vanishing, in marking order
    let mut phase_of = vec![usize::MAX; g.len()];
    let mut chain = PhaseChain::default();
    for (m, phase) in phase_of.iter_mut().enumerate() {
        if g.status[m] == Status::Running && vanishing_child(m).is_none() {
            *phase = chain.push_phase();
        }
    }
    // entries, from the last marking back (events go forward)
    let mut entry: Vec<Entry> = vec![Entry::default(); g.len()];
    for m in (0..g.len()).rev() {
        entry[m] = match g.status[m] {
            Status::Success => Entry {
                success: 1.0,
                ..Entry::default()
            },
            Status::Failure => Entry {
                failure: 1.0,
                ..Entry::default()
            },
            Status::Running => match vanishing_child(m) {
                None => Entry {
                    phases: vec![(phase_of[m], 1.0)],
                    ..Entry::default()
                },
                Some(h) => {
                    let mut e = Entry::default();
                    for ev in events_of(m).iter().filter(|ev| ev.child == h) {
                        let p = match ev.outcome {
                            Outcome::Success => children[h].ps,
                            Outcome::Failure => children[h].pf,
                        };
                        if p > 0.0 {
                            let target = entry[ev.to].clone();
                            e.add_scaled(&target, p);
                        }
                    }
                    e
                }
            },
        };
    }
    for (m, &i) in phase_of.iter().enumerate() {
        if i == usize::MAX {
            continue;
        }
        for ev in events_of(m) {
            let f = &children[ev.child];
            let p = match ev.outcome {
                Outcome::Success => f.ps,
                Outcome::Failure => f.pf,
            };
            if p <= 0.0 {
                continue;
            }
            let rate = p / sojourn(ev.child);
            let target = &entry[ev.to];
            chain.exit_success[i] += rate * target.success;
            chain.exit_failure[i] += rate * target.failure;
            let moves: Vec<(usize, f64)> =
                target.phases.iter().map(|&(j, w)| (j, rate * w)).collect();
            chain.transitions[i].extend(moves);
        }
    }
    let start = entry[0].clone();
    chain.initial = start.phases;
    chain.initial_success = start.success;
    chain.initial_failure = start.failure;
    chain
}
