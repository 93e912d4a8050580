//! `compare`: orderings of Fallback children against hand-derived values
//! and brute force.

use std::path::Path;

use btrel::compare::{compare, CompareError, CompareOptions, Objective, Search};
use btrel::tree::{parse_file, parse_str, NodeKind, Tree};
use proptest::prelude::*;

fn sg() -> Tree {
    parse_file(Path::new("trees/search-and-grasp.yaml")).unwrap()
}

fn names(tree: &Tree, order: &[usize]) -> Vec<String> {
    order.iter().map(|&i| tree.node(i).name.clone()).collect()
}

#[test]
fn drawer_first_is_best_by_100_seconds() {
    let t = sg();
    let options = CompareOptions {
        nodes: vec![t.find("search").unwrap()],
        deadline: Some(100.0),
        ..CompareOptions::default()
    };
    let c = compare(&t, &options).unwrap();
    assert_eq!(c.objective, Objective::SuccessBy);
    assert_eq!(c.search, Search::Exhaustive);
    assert_eq!(c.candidates.len(), 6);
    let best = &c.candidates[0];
    assert_eq!(
        names(&t, &best.orders[0]),
        ["search drawer", "search floor", "search closet"]
    );
    // reference/refs.json: 0.270403 drawer first, 0.197740 as given
    assert!((best.success_by_deadline.unwrap() - 0.270403325).abs() < 1e-8);
    let given = c.candidates.iter().find(|x| x.given).unwrap();
    assert!((given.success_by_deadline.unwrap() - 0.197739766).abs() < 1e-8);
    // the tree the best candidate stands for: drawer first, and its own
    // curve gives the reference value
    let drawer_first = c.reordered(&t, best);
    let search = drawer_first.find("search").unwrap();
    assert_eq!(
        names(&drawer_first, drawer_first.node(search).kind.children()),
        ["search drawer", "search floor", "search closet"]
    );
    let by_100 = btrel::curve::curve(&drawer_first, 0, &[100.0], &Default::default()).unwrap();
    assert!((by_100[0].success - 0.270403325).abs() < 1e-8);
    // the final success probability is the same for every ordering
    for x in &c.candidates {
        assert!((x.root.ps - 0.4884).abs() < 1e-12);
    }
}

/// E[T] of an action: ps/mu + pf/nu.
fn action_mean(ps: f64, mu: f64, nu: f64) -> f64 {
    ps / mu + (1.0 - ps) / nu
}

#[test]
fn mean_time_of_every_ordering_matches_the_path_formula() {
    // search = Fallback of floor, drawer, closet; E[T_search] = Σ_k Π_{j<k} pf_j E_k;
    // root = Sequence(find object, grasp object), conditions take no time:
    // E[T_root] = E[T_search] + ps_search · E[T_grasp]
    let t = sg();
    let actions = [
        ("search floor", 0.3, action_mean(0.3, 0.0167, 0.01)),
        ("search drawer", 0.8, action_mean(0.8, 0.01, 0.01)),
        ("search closet", 0.2, action_mean(0.2, 0.005, 0.0056)),
    ];
    let grasp = action_mean(0.1, 0.1, 2.0) + 0.9 * action_mean(0.5, 0.1, 0.05);
    let c = compare(
        &t,
        &CompareOptions {
            nodes: vec![t.find("search").unwrap()],
            ..CompareOptions::default()
        },
    )
    .unwrap();
    assert_eq!(c.objective, Objective::MeanTime);
    for cand in &c.candidates {
        let order = names(&t, &cand.orders[0]);
        let mut prefix = 1.0;
        let mut search = 0.0;
        for name in &order {
            let &(_, ps, e) = actions.iter().find(|a| a.0 == name).unwrap();
            search += prefix * e;
            prefix *= 1.0 - ps;
        }
        let expected = search + 0.888 * grasp;
        assert!(
            (cand.root.mean_time() - expected).abs() < 1e-9 * expected,
            "{order:?}: {} vs {expected}",
            cand.root.mean_time()
        );
    }
    // ranked ascending
    for w in c.candidates.windows(2) {
        assert!(w[0].root.mean_time() <= w[1].root.mean_time());
    }
}

#[test]
fn refusals_and_notes() {
    let t = sg();
    let seq = t.find("search and grasp").unwrap();
    let e = compare(
        &t,
        &CompareOptions {
            nodes: vec![seq],
            ..CompareOptions::default()
        },
    )
    .unwrap_err();
    assert!(matches!(e, CompareError::NotReorderable(_, "sequence")));
    let single = parse_str(
        "tree: {fallback: {children: [{action: {ps: .5, mu: 1, nu: 1}}]}}",
        "t.yaml",
    )
    .unwrap();
    // nothing to reorder is an answer, not an error: the given ordering alone
    let alone = compare(&single, &CompareOptions::default()).unwrap();
    assert_eq!(alone.search, Search::NothingToReorder);
    assert_eq!(alone.candidates.len(), 1);
    assert!(alone.candidates[0].given);
    assert!(alone.notes.iter().any(|n| n.contains("nothing to reorder")));
    let par = parse_str(
        "tree: {sequence: {children: [{parallel: {name: p, children: [{action: {ps: .5, mu: 1, nu: 1}}, {action: {ps: .5, mu: 2, nu: 1}}]}}, {fallback: {children: [{action: {ps: .5, mu: 1, nu: 1}}, {action: {ps: .9, mu: 3, nu: 1}}]}}]}}",
        "t.yaml",
    )
    .unwrap();
    let c = compare(
        &par,
        &CompareOptions {
            nodes: vec![par.find("p").unwrap(), par.find("fallback@0.1").unwrap()],
            ..CompareOptions::default()
        },
    )
    .unwrap();
    assert!(c.notes.iter().any(|n| n.contains("Parallel")));
    assert_eq!(c.candidates.len(), 2);
    let e = compare(
        &t,
        &CompareOptions {
            objective: Some(Objective::SuccessBy),
            ..CompareOptions::default()
        },
    )
    .unwrap_err();
    assert_eq!(e, CompareError::NeedsDeadline);
}

#[test]
fn ties_keep_the_given_ordering_first() {
    // identical children: every ordering ties; the given one ranks first
    let t = parse_str(
        "tree: {fallback: {children: [{action: {name: a, ps: .5, mu: 1, nu: 1}}, {action: {name: b, ps: .5, mu: 1, nu: 1}}, {action: {name: c, ps: .5, mu: 1, nu: 1}}]}}",
        "t.yaml",
    )
    .unwrap();
    let c = compare(&t, &CompareOptions::default()).unwrap();
    assert_eq!(c.candidates.len(), 6);
    assert!(c.candidates[0].given);
}

fn fallback_yaml(children: &[(f64, f64, f64)]) -> String {
    let kids: Vec<String> = children
        .iter()
        .enumerate()
        .map(|(i, (ps, mu, nu))| {
            format!("{{action: {{name: a{i}, ps: {ps}, mu: {mu}, nu: {nu}}}}}")
        })
        .collect();
    format!(
        "tree: {{sequence: {{children: [{{action: {{name: pre, ps: 0.9, mu: 2, nu: 1}}}}, {{fallback: {{name: f, children: [{}]}}}}]}}}}",
        kids.join(", ")
    )
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    /// The ordering rule ps/E[T] (used beyond the enumeration limit) finds
    /// the brute-force optimum of the mean time.
    #[test]
    fn ordering_rule_matches_brute_force(
        children in proptest::collection::vec((0.01f64..0.99, 0.01f64..10.0, 0.01f64..10.0), 2..=6)
    ) {
        let t = parse_str(&fallback_yaml(&children), "t.yaml").unwrap();
        let f = t.find("f").unwrap();
        let is_fallback = matches!(t.node(f).kind, NodeKind::Fallback { .. });
        prop_assert!(is_fallback);
        let brute = compare(&t, &CompareOptions { nodes: vec![f], ..CompareOptions::default() }).unwrap();
        prop_assert_eq!(brute.search, Search::Exhaustive);
        let rule = compare(&t, &CompareOptions { nodes: vec![f], max_candidates: Some(1), ..CompareOptions::default() }).unwrap();
        prop_assert_eq!(rule.search, Search::OrderingRule);
        prop_assert!(rule.proven_optimal);
        let best = brute.candidates[0].root.mean_time();
        let found = rule.candidates[0].root.mean_time();
        prop_assert!((best - found).abs() <= 1e-9 * best, "brute {} rule {}", best, found);
    }
}
