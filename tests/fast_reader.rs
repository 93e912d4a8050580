//! The fast YAML reader must never change what a document means: every
//! document it reads gives the same tree as serde-saphyr, and every other
//! document (or error) is left to serde-saphyr.

use btrel::generate::{random_tree_yaml, Shape};
use btrel::tree::parse::{fast_reader_accepts, parse_full};
use btrel::tree::{parse_str, ParseLimits};
use proptest::prelude::*;

/// `parse_str` (fast reader first) and the full parser agree: the same
/// tree, or the same error.
fn same_as_full(source: &str) -> Result<(), String> {
    // a file of comments only is refused before either reader runs
    if source
        .lines()
        .all(|l| l.trim().is_empty() || l.trim_start().starts_with('#'))
    {
        return Ok(());
    }
    let a = parse_str(source, "t.yaml");
    let b = parse_full(source, "t.yaml", ParseLimits::default());
    match (&a, &b) {
        (Ok(x), Ok(y)) if x == y => Ok(()),
        (Err(x), Err(y)) if x == y => Ok(()),
        _ => Err(format!("fast: {a:?}\nfull: {b:?}\nsource:\n{source}")),
    }
}

#[test]
fn bundled_trees_take_the_fast_path_and_agree() {
    for entry in std::fs::read_dir("trees").unwrap() {
        let path = entry.unwrap().path();
        let name = path.to_string_lossy().to_string();
        if !name.ends_with(".yaml") || name.ends_with(".params.yaml") {
            continue;
        }
        let source = std::fs::read_to_string(&path).unwrap();
        assert!(fast_reader_accepts(&source), "{name} is not read fast");
        same_as_full(&source).unwrap();
    }
}

#[test]
fn generated_trees_take_the_fast_path_and_agree() {
    for seed in 0..20 {
        let shape = Shape {
            leaves: 300,
            max_children: 6,
            condition_fraction: 0.2,
            parallel_fraction: 0.2,
            max_parallel_children: 4,
            ..Shape::sequence_fallback(300)
        };
        let source = random_tree_yaml(&shape, seed);
        assert!(fast_reader_accepts(&source));
        same_as_full(&source).unwrap();
    }
}

/// Styles inside the subset: all read fast, all the same tree as the full
/// parser.
#[test]
fn subset_styles_agree() {
    let docs = [
        "tree: {action: {ps: 0.5, mu: 1, nu: 2}}\n",
        "name: \"quoted title\"\ntree: {action: {name: 'a b', ps: 0.5, mu: 1e-3, nu: 2.5E+2}}\n",
        "# comment\ntree:   # trailing comment\n  sequence:\n    children:\n    - condition: {ps: 0.9}   # c\n    - action:\n        ps: 0.25\n        mu: 1.0\n        nu: 0.5\n",
        "tree:\n  fallback:\n    name: root\n    children: [{action: {ps: 0.5, mu: 1, nu: 1}}, {condition: {ps: 0.1}}]\n",
        "tree:\n  parallel:\n    success_threshold: 2\n    children:\n      -   action: {ps: 0.5, mu: 1, nu: 1}\n      -   action:\n            ps: 0.7\n            tau_s: 2\n            tau_f: 3\n",
        "tree:\n  retry:\n    attempts: 3\n    child:\n      inverter:\n        child: {action: {ps: 0.5, mu: 1, nu: 1}}\n",
        "tree:\r\n  repeat:\r\n    times: 2\r\n    child: {force_success: {child: {condition: {ps: 0.5}}}}\r\n",
        "tree: {sequence: {children: [{action: {name: é-ü, ps: 0.5, mu: 1, nu: 1}}, {condition: {name: c, ps: -0.0}}]}}\n",
    ];
    for d in docs {
        assert!(fast_reader_accepts(d), "not read fast:\n{d}");
        same_as_full(d).unwrap();
    }
}

/// Documents outside the subset go to the full parser (same result).
#[test]
fn outside_the_subset_is_left_to_the_full_parser() {
    let docs = [
        "tree: &a {action: {ps: 0.5, mu: 1, nu: 1}}\n",
        "tree: {action: {ps: !!float 0.5, mu: 1, nu: 1}}\n",
        "tree:\n  action:\n    name: a long\n      name\n    ps: 0.5\n    mu: 1\n    nu: 1\n",
        "tree:\n  action: {ps: 0.5, mu: 1, nu: 1, mu: 2}\n",
        "tree:\n\taction: {ps: 0.5, mu: 1, nu: 1}\n",
        "---\ntree: {action: {ps: 0.5, mu: 1, nu: 1}}\n",
        "tree: {action: {name: \"a\\tb\", ps: 0.5, mu: 1, nu: 1}}\n",
        "tree: {action: {name: yes, ps: 0.5, mu: 1, nu: 1}}\n",
        "tree: {action: {ps: .5, mu: 1, nu: 1}}\n",
        "tree: {action: {ps: 0x1, mu: 1, nu: 1}}\n",
        "tree: {action: {ps: 0.5, mu: 1, nu: 1}\n",
        "tree:\n  action:\n    ps: |\n      0.5\n",
        "tree: {actoin: {ps: 0.5, mu: 1, nu: 1}}\n",
    ];
    for d in docs {
        assert!(!fast_reader_accepts(d), "read fast:\n{d}");
        same_as_full(d).unwrap();
    }
}

const BASES: [&str; 3] = [
    include_str!("../trees/two-arm-parallel.yaml"),
    include_str!("../trees/search-and-grasp.yaml"),
    "tree: {retry: {attempts: 2, child: {sequence: {children: [{condition: {name: c, ps: 0.5}}, \
     {action: {name: a b, ps: 0.5, mu: 1e-3, tau_f: 2}}]}}}}\n",
];

proptest! {
    #![proptest_config(ProptestConfig::with_cases(1500))]

    /// Random edits of a real file: whatever the fast reader makes of the
    /// result, the outcome equals the full parser's.
    #[test]
    fn edits_never_change_the_meaning(
        base in 0usize..3,
        edits in proptest::collection::vec(
            (0usize..10_000, 0usize..3, proptest::sample::select(
                vec![' ', ':', '-', '#', '{', '}', '[', ']', ',', '\n', '"', '\'', 'a', '1', '.', '&', '*', '!', '|', '\t', 'e', '?'],
            )),
            1..4,
        ),
    ) {
        let mut s: Vec<char> = BASES[base].chars().collect();
        for (at, op, c) in edits {
            let at = at % (s.len() + 1);
            match op {
                0 => s.insert(at, c),
                1 if at < s.len() => { s.remove(at); }
                _ if at < s.len() => s[at] = c,
                _ => {}
            }
        }
        let doc: String = s.into_iter().collect();
        prop_assert!(same_as_full(&doc).is_ok(), "{}", same_as_full(&doc).unwrap_err());
    }
}
