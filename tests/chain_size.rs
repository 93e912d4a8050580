//! The planner decides whether a subtree gets its phase chain from the
//! chain's size estimated before building it (`phase::chain_size`). The
//! estimate is sound — where it is within the budget the chain is built,
//! never longer than the estimate — and not vacuous: over random trees of
//! every node kind it lets through almost every chain that fits.

mod common;

use btrel::compile::phase::{phase_chain, phase_chain_bound};
use btrel::AnalysisError;
use common::anytree::{random_phase_type_tree, random_tree};

#[test]
fn the_estimate_bounds_every_chain_and_refuses_few_that_fit() {
    // small budgets, so that Parallels and loops exceed them
    let (mut fitting, mut let_through, mut nodes, mut over) = (0, 0, 0, 0);
    // the engine spec's trees, and the same trees with phase-type leaves
    // only (a chain for every subtree)
    let trees = (0..300).flat_map(|seed| [random_tree(seed, 10), random_phase_type_tree(seed, 10)]);
    for (case, generated) in trees.enumerate() {
        let (yaml, s) = (generated.yaml(), case / 2);
        let tree = btrel::parse_str(&yaml, "size.yaml").expect("a generated tree parses");
        for (id, max_states) in
            (0..tree.nodes().len()).flat_map(|id| [(id, 12), (id, 60), (id, 400)])
        {
            nodes += 1;
            let bound = phase_chain_bound(&tree, id, max_states).expect("an estimate");
            let built = phase_chain(&tree, id, max_states);
            match (&built, bound) {
                (Ok(c), Some(b)) => {
                    assert!(
                        c.len() as f64 <= b,
                        "tree {case} (seed {s}) node {id}: chain of {} phases, estimate {b}\n{yaml}",
                        c.len()
                    );
                    fitting += 1;
                    let_through += 1;
                }
                (Ok(_), None) => fitting += 1,
                (Err(e), Some(b)) => {
                    panic!(
                        "tree {case} (seed {s}) node {id}: estimate {b} within the budget, built: {e}\n{yaml}"
                    )
                }
                (Err(AnalysisError::StateBudget { .. }), None) => over += 1,
                (Err(AnalysisError::NotMarkovian { .. }), None) => {}
                (Err(e), None) => panic!("tree {case} (seed {s}) node {id}: {e:?}"),
            }
        }
    }
    println!(
        "{let_through} of {fitting} chains that fit let through, {over} over the budget ({nodes} nodes)"
    );
    assert!(
        over > 20,
        "only {over} chains over the budget: the budget is not exercised"
    );
    assert!(
        fitting > 1000,
        "only {fitting} chains built: the test checks little"
    );
    assert!(
        let_through as f64 >= 0.98 * fitting as f64,
        "the estimate refuses {} of {fitting} chains that fit",
        fitting - let_through
    );
}
