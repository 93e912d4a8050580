//! Property tests on random trees, written as YAML text and parsed (so the
//! parser is exercised too).
//!
//! * (i) ps + pf = 1 at every node;
//! * (ii) `exact` and `book` agree on Sequence/Fallback trees;
//! * (iii) `analyze` agrees with the root's full exact phase chain, solved
//!   directly (`phase_chain` → `jump_chain` → `solve_absorbing`);
//! * (iv) a Parallel node's ps is the brute-force probability over all 2^N
//!   outcome vectors that at least M children succeed, under both methods;
//! * (v) permuting a Fallback's (or a Sequence's) children leaves ps
//!   unchanged, and the Fallback's MTTF (the Sequence's MTTS) is the sum of
//!   the children's, whatever the order.

use btrel::compile::phase::phase_chain;
use btrel::compile::{analyze, Analysis, Figures, Method, Options};
use btrel::solve::solve_absorbing;
use btrel::tree::{parse_str, Tree};
use proptest::prelude::*;

/// 64 cases; no regression files are written (the test tree is shared).
fn config() -> ProptestConfig {
    ProptestConfig {
        cases: 64,
        failure_persistence: None,
        ..ProptestConfig::default()
    }
}

/// A random tree, rendered to YAML by [`Gen::yaml`].
#[derive(Debug, Clone)]
enum Gen {
    Action {
        ps: f64,
        mu: f64,
        nu: f64,
    },
    Condition {
        ps: f64,
    },
    Sequence(Vec<Gen>),
    Fallback(Vec<Gen>),
    /// Parallel with success threshold M.
    Parallel(Vec<Gen>, usize),
}

impl Gen {
    fn yaml(&self) -> String {
        format!("tree:\n{}", self.block(1))
    }

    /// Block-style YAML at `indent` (two spaces per level).
    fn block(&self, indent: usize) -> String {
        let pad = "  ".repeat(indent);
        match self {
            // `{}` prints the shortest text that round-trips, never exponents
            Gen::Action { ps, mu, nu } => {
                format!("{pad}action: {{ps: {ps}, mu: {mu}, nu: {nu}}}\n")
            }
            Gen::Condition { ps } => format!("{pad}condition: {{ps: {ps}}}\n"),
            Gen::Parallel(c, m) => {
                let mut s =
                    format!("{pad}parallel:\n{pad}  success_threshold: {m}\n{pad}  children:\n");
                for child in c {
                    s.push_str(&format!("{pad}    -\n"));
                    s.push_str(&child.block(indent + 3));
                }
                s
            }
            Gen::Sequence(c) | Gen::Fallback(c) => {
                let kw = if matches!(self, Gen::Sequence(_)) {
                    "sequence"
                } else {
                    "fallback"
                };
                let mut s = format!("{pad}{kw}:\n{pad}  children:\n");
                for child in c {
                    s.push_str(&format!("{pad}    -\n"));
                    s.push_str(&child.block(indent + 3));
                }
                s
            }
        }
    }
}

fn probability() -> impl Strategy<Value = f64> {
    prop_oneof![
        1 => Just(0.0),
        1 => Just(1.0),
        6 => 0.0..=1.0f64,
    ]
}

fn rate() -> impl Strategy<Value = f64> {
    // log-uniform in [1e-2, 1e2]
    (-2.0..2.0f64).prop_map(|e| 10f64.powf(e))
}

fn leaf() -> impl Strategy<Value = Gen> {
    prop_oneof![
        4 => (probability(), rate(), rate()).prop_map(|(ps, mu, nu)| Gen::Action { ps, mu, nu }),
        1 => probability().prop_map(|ps| Gen::Condition { ps }),
    ]
}

/// Sequence/Fallback trees of depth ≤ 4 with ≤ 5 children per node.
fn tree_gen() -> impl Strategy<Value = Gen> {
    leaf().prop_recursive(4, 200, 5, |inner| {
        prop_oneof![
            prop::collection::vec(inner.clone(), 1..=5).prop_map(Gen::Sequence),
            prop::collection::vec(inner, 1..=5).prop_map(Gen::Fallback),
        ]
    })
}

/// Like [`tree_gen`], with small Parallel nodes (2–3 leaves) mixed in.
fn mixed_tree_gen() -> impl Strategy<Value = Gen> {
    let parallel = prop::collection::vec(leaf(), 2..=3)
        .prop_flat_map(|c| {
            let n = c.len();
            (Just(c), 1..=n)
        })
        .prop_map(|(c, m)| Gen::Parallel(c, m));
    prop_oneof![3 => leaf(), 1 => parallel].prop_recursive(3, 60, 4, |inner| {
        prop_oneof![
            prop::collection::vec(inner.clone(), 1..=4).prop_map(Gen::Sequence),
            prop::collection::vec(inner, 1..=4).prop_map(Gen::Fallback),
        ]
    })
}

fn parse(yaml: &str) -> Tree {
    parse_str(yaml, "generated.yaml").unwrap_or_else(|e| panic!("{e}\n--- yaml:\n{yaml}"))
}

fn run(tree: &Tree, method: Method) -> Analysis {
    let options = Options {
        method,
        ..Options::default()
    };
    analyze(tree, &options).unwrap_or_else(|e| panic!("analysis ({method:?}): {e}"))
}

fn rel_close(a: f64, b: f64, rel: f64) -> bool {
    (a - b).abs() <= rel * a.abs().max(b.abs()) || (a - b).abs() <= 1e-300
}

fn same_time(what: &str, a: Option<f64>, b: Option<f64>, rel: f64) -> Result<(), TestCaseError> {
    match (a, b) {
        (Some(x), Some(y)) => prop_assert!(rel_close(x, y, rel), "{what}: {x:e} vs {y:e}"),
        (None, None) => {}
        _ => prop_assert!(false, "{what}: {a:?} vs {b:?}"),
    }
    Ok(())
}

proptest! {
    #![proptest_config(config())]

    /// (i) ps + pf = 1 at every node, under both methods, and every figure
    /// is a probability / a finite non-negative time, defined exactly when
    /// its outcome is possible.
    #[test]
    fn probabilities_sum_to_one(g in tree_gen()) {
        let tree = parse(&g.yaml());
        for method in [Method::Exact, Method::Book] {
            let a = run(&tree, method);
            prop_assert_eq!(a.nodes.len(), tree.nodes().len());
            for (node, f) in tree.nodes().iter().zip(&a.nodes) {
                prop_assert!((f.ps + f.pf - 1.0).abs() <= 1e-12,
                    "{} ({:?}): ps {} + pf {} = {}", node.name, method, f.ps, f.pf, f.ps + f.pf);
                // rounding may leave a probability 1 ulp outside [0, 1]
                let unit = -1e-12..=1.0 + 1e-12;
                prop_assert!(unit.contains(&f.ps) && unit.contains(&f.pf),
                    "{}: ps {} pf {}", node.name, f.ps, f.pf);
                prop_assert_eq!(f.mtts.is_some(), f.ps > 0.0, "{}: MTTS {:?} with ps {}", node.name, f.mtts, f.ps);
                prop_assert_eq!(f.mttf.is_some(), f.pf > 0.0, "{}: MTTF {:?} with pf {}", node.name, f.mttf, f.pf);
                for t in [f.mtts, f.mttf].into_iter().flatten() {
                    prop_assert!(t.is_finite() && t >= 0.0, "{}: time {}", node.name, t);
                }
            }
        }
    }

    /// (i) and (iii) on trees with Parallel nodes: the bottom-up analysis
    /// (Parallel figures composed by Sequence/Fallback) equals the root's
    /// full phase chain, in which every Parallel is a product chain.
    #[test]
    fn mixed_trees_match_full_phase_chain(g in mixed_tree_gen()) {
        let tree = parse(&g.yaml());
        let a = run(&tree, Method::Exact);
        for (node, f) in tree.nodes().iter().zip(&a.nodes) {
            prop_assert!((f.ps + f.pf - 1.0).abs() <= 1e-12,
                "{}: ps {} + pf {}", node.name, f.ps, f.pf);
        }
        let root = a.nodes[0];
        let abs = solve_absorbing(&phase_chain(&tree, 0, usize::MAX).unwrap().jump_chain()).unwrap();
        prop_assert!((root.ps - abs.success).abs() <= 1e-12, "ps {} vs {}", root.ps, abs.success);
        if root.ps > 1e-9 {
            let want = abs.time_success / abs.success;
            prop_assert!(rel_close(root.mtts.unwrap(), want, 1e-9), "MTTS {:?} vs {}", root.mtts, want);
        }
        if root.pf > 1e-9 {
            let want = abs.time_failure / abs.failure;
            prop_assert!(rel_close(root.mttf.unwrap(), want, 1e-9), "MTTF {:?} vs {}", root.mttf, want);
        }
        // the book method agrees on the probabilities
        let book = run(&tree, Method::Book).nodes[0];
        prop_assert!((book.ps - root.ps).abs() <= 1e-12, "book ps {} vs exact {}", book.ps, root.ps);
    }

    /// (ii) On Sequence/Fallback trees the book's recursion is exact: both
    /// methods give the same figures at every node.
    #[test]
    fn exact_and_book_agree_on_sequence_fallback(g in tree_gen()) {
        let tree = parse(&g.yaml());
        let e = run(&tree, Method::Exact);
        let b = run(&tree, Method::Book);
        for ((node, x), y) in tree.nodes().iter().zip(&e.nodes).zip(&b.nodes) {
            prop_assert!((x.ps - y.ps).abs() <= 1e-12, "{}: ps {} vs {}", node.name, x.ps, y.ps);
            same_time(&format!("{} MTTS", node.name), x.mtts, y.mtts, 1e-9)?;
            same_time(&format!("{} MTTF", node.name), x.mttf, y.mttf, 1e-9)?;
        }
    }

    /// (iii) The root's figures equal those of its full exact phase chain,
    /// solved directly: an independent path through the library.
    #[test]
    fn analyze_matches_full_phase_chain(g in tree_gen()) {
        let tree = parse(&g.yaml());
        let root = run(&tree, Method::Exact).nodes[0];
        let chain = phase_chain(&tree, 0, usize::MAX).expect("stochastic tree");
        let abs = solve_absorbing(&chain.jump_chain()).expect("solvable");
        prop_assert!((root.ps - abs.success).abs() <= 1e-12, "ps {} vs {}", root.ps, abs.success);
        prop_assert!((root.pf - abs.failure).abs() <= 1e-12, "pf {} vs {}", root.pf, abs.failure);
        if root.ps > 1e-9 {
            let mtts = abs.time_success / abs.success;
            let got = root.mtts.expect("MTTS defined");
            prop_assert!(rel_close(got, mtts, 1e-9), "MTTS {:e} vs chain {:e}", got, mtts);
        }
        if root.pf > 1e-9 {
            let mttf = abs.time_failure / abs.failure;
            let got = root.mttf.expect("MTTF defined");
            prop_assert!(rel_close(got, mttf, 1e-9), "MTTF {:e} vs chain {:e}", got, mttf);
        }
    }
}

// ---------------------------------------------------------------------------
// (iv) Parallel: threshold semantics
// ---------------------------------------------------------------------------

fn parallel_gen() -> impl Strategy<Value = (Vec<Gen>, usize)> {
    prop::collection::vec(leaf(), 1..=4).prop_flat_map(|children| {
        let n = children.len();
        (Just(children), 1..=n)
    })
}

fn parallel_yaml(children: &[Gen], m: usize) -> String {
    let mut s = format!("tree:\n  parallel:\n    success_threshold: {m}\n    children:\n");
    for c in children {
        s.push_str("      -\n");
        s.push_str(&c.block(4));
    }
    s
}

fn leaf_ps(g: &Gen) -> f64 {
    match *g {
        Gen::Action { ps, .. } | Gen::Condition { ps } => ps,
        _ => unreachable!("leaves only"),
    }
}

/// P(at least M of the independent outcomes are Success), by enumeration
/// of all 2^N outcome vectors.
fn brute_force_ps(ps: &[f64], m: usize) -> f64 {
    let n = ps.len();
    let mut total = 0.0;
    for mask in 0u32..(1 << n) {
        let successes = mask.count_ones() as usize;
        if successes < m {
            continue;
        }
        let p: f64 = (0..n)
            .map(|i| {
                if mask & (1 << i) != 0 {
                    ps[i]
                } else {
                    1.0 - ps[i]
                }
            })
            .product();
        total += p;
    }
    total
}

proptest! {
    #![proptest_config(config())]

    #[test]
    fn parallel_ps_is_threshold_probability((children, m) in parallel_gen()) {
        let yaml = parallel_yaml(&children, m);
        let tree = parse(&yaml);
        let ps: Vec<f64> = children.iter().map(leaf_ps).collect();
        let want = brute_force_ps(&ps, m);
        for method in [Method::Exact, Method::Book] {
            let f: Figures = run(&tree, method).nodes[0];
            prop_assert!((f.ps - want).abs() <= 1e-12,
                "{:?}: ps {} vs brute force {}\n{}", method, f.ps, want, yaml);
            prop_assert!((f.pf - (1.0 - want)).abs() <= 1e-12,
                "{:?}: pf {} vs brute force {}\n{}", method, f.pf, 1.0 - want, yaml);
        }
    }
}

// ---------------------------------------------------------------------------
// (v) permutations
// ---------------------------------------------------------------------------

fn children_and_permutation() -> impl Strategy<Value = (Vec<Gen>, Vec<usize>)> {
    let child = leaf().prop_recursive(2, 30, 4, |inner| {
        prop_oneof![
            prop::collection::vec(inner.clone(), 1..=4).prop_map(Gen::Sequence),
            prop::collection::vec(inner, 1..=4).prop_map(Gen::Fallback),
        ]
    });
    prop::collection::vec(child, 1..=5).prop_flat_map(|children| {
        let order: Vec<usize> = (0..children.len()).collect();
        (Just(children), Just(order).prop_shuffle())
    })
}

proptest! {
    #![proptest_config(config())]

    #[test]
    fn fallback_permutation_keeps_ps_and_mttf((children, order) in children_and_permutation()) {
        let permuted: Vec<Gen> = order.iter().map(|&i| children[i].clone()).collect();
        let a = run(&parse(&Gen::Fallback(children.clone()).yaml()), Method::Exact).nodes[0];
        let b = run(&parse(&Gen::Fallback(permuted).yaml()), Method::Exact).nodes[0];
        prop_assert!((a.ps - b.ps).abs() <= 1e-12, "ps {} vs {} after {:?}", a.ps, b.ps, order);
        // a Fallback fails only after every child failed: MTTF = Σ MTTF_i
        same_time("Fallback MTTF", a.mttf, b.mttf, 1e-9)?;
        let tree = parse(&Gen::Fallback(children).yaml());
        let an = run(&tree, Method::Exact);
        if let Some(mttf) = an.nodes[0].mttf {
            let sum: f64 = tree.nodes()[0].kind.children().iter()
                .map(|&c| an.nodes[c].mttf.expect("every child can fail"))
                .sum();
            prop_assert!(rel_close(mttf, sum, 1e-9), "MTTF {} vs Σ {}", mttf, sum);
        }
    }

    #[test]
    fn sequence_permutation_keeps_ps_and_mtts((children, order) in children_and_permutation()) {
        let permuted: Vec<Gen> = order.iter().map(|&i| children[i].clone()).collect();
        let a = run(&parse(&Gen::Sequence(children.clone()).yaml()), Method::Exact).nodes[0];
        let b = run(&parse(&Gen::Sequence(permuted).yaml()), Method::Exact).nodes[0];
        prop_assert!((a.ps - b.ps).abs() <= 1e-12, "ps {} vs {} after {:?}", a.ps, b.ps, order);
        // a Sequence succeeds only after every child succeeded: MTTS = Σ MTTS_i
        same_time("Sequence MTTS", a.mtts, b.mtts, 1e-9)?;
    }
}

/// The generator's YAML is what the parser expects (a fixed example, so a
/// rendering bug cannot hide behind the properties).
#[test]
fn generated_yaml_shape() {
    let g = Gen::Fallback(vec![
        Gen::Action {
            ps: 0.25,
            mu: 2.0,
            nu: 0.5,
        },
        Gen::Sequence(vec![Gen::Condition { ps: 1.0 }]),
    ]);
    let tree = parse(&g.yaml());
    assert_eq!(tree.nodes().len(), 4);
    assert_eq!(tree.nodes()[0].kind.keyword(), "fallback");
    assert_eq!(tree.nodes()[2].kind.keyword(), "sequence");
    assert_eq!(tree.nodes()[3].path, "0.1.0");
    // Fallback[A(.25), Sequence[cond 1]] always succeeds
    let f = run(&tree, Method::Exact).nodes[0];
    assert_eq!(f.ps, 1.0);
    assert_eq!(brute_force_ps(&[0.5, 0.5], 1), 0.75);
    assert_eq!(brute_force_ps(&[0.5, 0.5], 2), 0.25);
}
