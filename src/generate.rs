//! Random trees for benchmarks and stress tests.
//!
//! [`random_tree_yaml`] writes a Sequence/Fallback tree (optionally with
//! Parallel nodes) with a given number of leaves in the YAML format, so that
//! benchmarks measure the whole pipeline from text to figures.

use std::fmt::Write;

use rand::{RngExt, SeedableRng};
use rand_xoshiro::Xoshiro256PlusPlus;

/// Shape of a generated tree.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Shape {
    /// Number of leaves.
    pub leaves: usize,
    /// Most children of a control node (at least 2).
    pub max_children: usize,
    /// Fraction of leaves that are conditions.
    pub condition_fraction: f64,
    /// Fraction of control nodes that are Parallel (with at most
    /// `max_parallel_children` leaf children each).
    pub parallel_fraction: f64,
    /// Largest Parallel node generated.
    pub max_parallel_children: usize,
    /// Fraction of actions with fixed times (`tau_s`, `tau_f`, Def. 9.8).
    pub deterministic_fraction: f64,
    /// Fraction of actions with hybrid times (`tau_s` + `nu` or `mu` +
    /// `tau_f`, Def. 9.9); the rest are exponential.
    pub hybrid_fraction: f64,
}

impl Shape {
    /// A Sequence/Fallback tree with `leaves` leaves, up to 8 children per
    /// node and 10% conditions.
    pub fn sequence_fallback(leaves: usize) -> Shape {
        Shape {
            leaves,
            max_children: 8,
            condition_fraction: 0.1,
            parallel_fraction: 0.0,
            max_parallel_children: 3,
            deterministic_fraction: 0.0,
            hybrid_fraction: 0.0,
        }
    }

    /// [`Shape::sequence_fallback`] with mixed timing (Def. 9.11): a third
    /// of the actions deterministic, a third hybrid, a third exponential.
    pub fn mixed_timing(leaves: usize) -> Shape {
        Shape {
            deterministic_fraction: 1.0 / 3.0,
            hybrid_fraction: 1.0 / 3.0,
            ..Shape::sequence_fallback(leaves)
        }
    }
}

/// A random tree in the YAML format, reproducible from `seed`.
pub fn random_tree_yaml(shape: &Shape, seed: u64) -> String {
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(seed);
    let mut out = String::with_capacity(shape.leaves * 64);
    let _ = writeln!(
        out,
        "name: random tree ({} leaves, seed {seed})",
        shape.leaves
    );
    out.push_str("tree:\n");
    let mut counter = 0usize;
    node(
        &mut out,
        &mut rng,
        shape,
        shape.leaves.max(1),
        "  ",
        1,
        &mut counter,
    );
    out
}

/// Writes one node. Its first line starts with `first` (e.g. `"    - "`),
/// its other lines with `indent` levels of two spaces.
fn node(
    out: &mut String,
    rng: &mut Xoshiro256PlusPlus,
    shape: &Shape,
    leaves: usize,
    first: &str,
    indent: usize,
    counter: &mut usize,
) {
    let pad = "  ".repeat(indent);
    *counter += 1;
    let id = *counter;
    out.push_str(first);
    if leaves == 1 {
        if rng.random::<f64>() < shape.condition_fraction {
            let ps: f64 = rng.random_range(0.0..1.0);
            let _ = writeln!(out, "condition: {{name: c{id}, ps: {ps:.4}}}");
        } else {
            let ps: f64 = rng.random_range(0.05..0.95);
            let mu: f64 = 10f64.powf(rng.random_range(-2.0..1.0));
            let nu: f64 = 10f64.powf(rng.random_range(-2.0..1.0));
            // (no draw without mixed timing: seeds keep their trees)
            let mixed = shape.deterministic_fraction + shape.hybrid_fraction > 0.0;
            let u: f64 = if mixed { rng.random() } else { 1.0 };
            let timing = if u < shape.deterministic_fraction {
                format!("tau_s: {:.5}, tau_f: {:.5}", 1.0 / mu, 1.0 / nu)
            } else if u < shape.deterministic_fraction + shape.hybrid_fraction {
                if rng.random::<bool>() {
                    format!("tau_s: {:.5}, nu: {nu:.5}", 1.0 / mu)
                } else {
                    format!("mu: {mu:.5}, tau_f: {:.5}", 1.0 / nu)
                }
            } else {
                format!("mu: {mu:.5}, nu: {nu:.5}")
            };
            let _ = writeln!(out, "action: {{name: a{id}, ps: {ps:.4}, {timing}}}");
        }
        return;
    }
    let parallel = leaves <= shape.max_parallel_children
        && leaves >= 2
        && rng.random::<f64>() < shape.parallel_fraction;
    let k = if parallel {
        leaves
    } else {
        rng.random_range(2..=shape.max_children.max(2)).min(leaves)
    };
    if parallel {
        let m = rng.random_range(1..=k);
        let _ = writeln!(
            out,
            "parallel:\n{pad}  name: p{id}\n{pad}  success_threshold: {m}"
        );
    } else {
        let kind = if rng.random::<bool>() {
            "sequence"
        } else {
            "fallback"
        };
        let _ = writeln!(out, "{kind}:\n{pad}  name: n{id}");
    }
    let _ = writeln!(out, "{pad}  children:");
    // split the leaves among k children, each at least one
    let mut sizes = vec![1usize; k];
    for _ in 0..leaves - k {
        let i = rng.random_range(0..k);
        sizes[i] += 1;
    }
    let dash = format!("{pad}  - ");
    for s in sizes {
        node(out, rng, shape, s, &dash, indent + 2, counter);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn generated_trees_parse_with_the_requested_leaves() {
        for seed in 0..5 {
            let yaml = random_tree_yaml(&Shape::sequence_fallback(200), seed);
            let tree = crate::tree::parse_str(&yaml, "gen.yaml").unwrap();
            assert_eq!(tree.leaf_count(), 200);
        }
    }
}
