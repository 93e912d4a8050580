//! `compare` on wide trees: a default that answers quickly, the budget,
//! a table within 100 columns, CSV in table order, ties and trees with
//! nothing to reorder.

use std::sync::atomic::{AtomicU64, Ordering};

use btrel::compare::{compare_with_progress, CompareOptions, Search};
use btrel::tree::parse_str;

mod common;
use common::run_btrel as btrel;

fn assert_narrow(text: &str) {
    for line in text.lines() {
        assert!(
            line.chars().count() <= 100,
            "line of {} columns: {line}",
            line.chars().count()
        );
    }
}

/// A Fallback of nine actions (9! = 362,880 orderings, beyond the default
/// limit of 100,000): (ps, mu, nu) of each.
const NINE: [(f64, f64, f64); 9] = [
    (0.3, 0.5, 1.0),
    (0.8, 0.1, 0.4),
    (0.5, 1.0, 2.0),
    (0.2, 2.0, 0.5),
    (0.6, 0.3, 0.3),
    (0.45, 0.7, 1.5),
    (0.9, 0.05, 0.2),
    (0.1, 3.0, 3.0),
    (0.7, 0.2, 1.0),
];

fn nine_yaml() -> String {
    let kids: Vec<String> = NINE
        .iter()
        .enumerate()
        .map(|(i, (ps, mu, nu))| {
            format!("{{action: {{name: a{i}, ps: {ps}, mu: {mu}, nu: {nu}}}}}")
        })
        .collect();
    format!(
        "tree: {{fallback: {{name: f, children: [{}]}}}}\n",
        kids.join(", ")
    )
}

/// The smallest E[T] over all 9! orderings by the path formula
/// E = Σ_k Π_{j<k} pf_j · E_k (Heap's algorithm, independent of btrel).
fn brute_force_best() -> f64 {
    let e: Vec<(f64, f64)> = NINE
        .iter()
        .map(|&(ps, mu, nu)| (ps, ps / mu + (1.0 - ps) / nu))
        .collect();
    let mean = |p: &[usize]| {
        let (mut prefix, mut total) = (1.0, 0.0);
        for &i in p {
            total += prefix * e[i].1;
            prefix *= 1.0 - e[i].0;
        }
        total
    };
    let mut p: Vec<usize> = (0..9).collect();
    let mut c = [0usize; 9];
    let mut best = mean(&p);
    let mut i = 1;
    while i < 9 {
        if c[i] < i {
            if i % 2 == 0 {
                p.swap(0, i);
            } else {
                p.swap(c[i], i);
            }
            best = best.min(mean(&p));
            c[i] += 1;
            i = 1;
        } else {
            c[i] = 0;
            i += 1;
        }
    }
    best
}

#[test]
fn drone_fleet_answers_by_a_stated_search_within_100_columns() {
    let (code, out, err) = btrel(&["compare", "trees/drone-fleet.yaml"]);
    assert_eq!(code, 0, "{err}");
    assert_narrow(&out);
    assert!(err.contains("--max-candidates 65536"), "{err}");
    let out = out.split_whitespace().collect::<Vec<_>>().join(" ");
    assert!(out.contains("65,536 orderings"), "{out}");
    assert!(
        out.contains("search: local search from the ordering rule"),
        "{out}"
    );
    assert!(out.contains("not proven optimal"), "{out}");
    assert!(out.contains("exceed the default budget"), "{out}");
    // the rule puts the re-scan first in every sector: ps/E[T] is
    // 0.7/(0.7/0.02 + 0.3/0.05) = 0.0171 against 0.85/(0.85/0.01 + 0.15/0.05) = 0.00966
    assert!(
        out.contains("survey sector 16: rescan 16 > scan 16"),
        "{out}"
    );
    assert!(out.contains("(as given)"), "{out}");
}

#[test]
fn max_candidates_raises_the_enumeration_limit() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("nine.yaml");
    std::fs::write(&path, nine_yaml()).unwrap();
    let p = path.to_str().unwrap();
    let expected = brute_force_best();
    let best_of = |out: &str| -> f64 {
        let v: serde_json::Value = serde_json::from_str(out).unwrap();
        v["orderings"][0]["mean_time"].as_f64().unwrap()
    };
    let (code, out, err) = btrel(&["compare", p, "--format", "json"]);
    assert_eq!(code, 0, "{err}");
    let v: serde_json::Value = serde_json::from_str(&out).unwrap();
    assert_eq!(v["search"], "ordering rule ps/E[T]");
    assert_eq!(v["proven_optimal"], true);
    assert_eq!(v["evaluated"], 2);
    assert!((best_of(&out) - expected).abs() <= 1e-12 * expected);

    let (code, out, err) = btrel(&[
        "compare",
        p,
        "--format",
        "json",
        "--max-candidates",
        "400000",
    ]);
    assert_eq!(code, 0, "{err}");
    let v: serde_json::Value = serde_json::from_str(&out).unwrap();
    assert_eq!(v["search"], "exhaustive");
    assert_eq!(v["evaluated"], 362_880);
    assert!((best_of(&out) - expected).abs() <= 1e-12 * expected);
    // and an explicit limit below the space is obeyed too
    let (_, out, _) = btrel(&[
        "compare",
        "trees/search-and-grasp.yaml",
        "--node",
        "search",
        "--max-candidates",
        "5",
    ]);
    let out = out.split_whitespace().collect::<Vec<_>>().join(" ");
    assert!(out.contains("search: ordering rule"), "{out}");
    assert!(
        out.contains("6 orderings exceed --max-candidates 5"),
        "{out}"
    );
}

/// The rank column of table rows (lines starting with a rank).
fn table_ranks(out: &str) -> Vec<(String, bool)> {
    out.lines()
        .skip_while(|l| !l.starts_with("rank"))
        .skip(1)
        .filter(|l| l.trim_start().starts_with(|c: char| c.is_ascii_digit()))
        .map(|l| {
            let rank = l.split_whitespace().next().unwrap().to_string();
            (rank, l.contains("given"))
        })
        .collect()
}

#[test]
fn csv_rows_follow_the_table_with_the_given_ordering() {
    for args in [
        vec![
            "compare",
            "trees/search-and-grasp.yaml",
            "--node",
            "search",
            "--top",
            "2",
        ],
        vec!["compare", "trees/search-and-grasp.yaml", "--top", "3"],
        vec![
            "compare",
            "trees/search-and-grasp.yaml",
            "--node",
            "search",
            "--deadline",
            "100",
            "--top",
            "1",
        ],
    ] {
        let (code, table, err) = btrel(&args);
        assert_eq!(code, 0, "{err}");
        assert_narrow(&table);
        let mut csv_args = args.clone();
        csv_args.extend(["--format", "csv"]);
        let (_, csv, _) = btrel(&csv_args);
        let rows: Vec<(String, bool)> = csv
            .lines()
            .skip(1)
            .map(|l| {
                let mut r = csv::ReaderBuilder::new()
                    .has_headers(false)
                    .from_reader(l.as_bytes());
                let rec = r.records().next().unwrap().unwrap();
                let tied = &rec[8] == "true";
                (
                    format!("{}{}", &rec[0], if tied { "=" } else { "" }),
                    &rec[2] == "true",
                )
            })
            .collect();
        assert_eq!(table_ranks(&table), rows, "{table}\n{csv}");
        // the given ordering's rank does not depend on how many rows are shown
        let mut all_args = args.clone();
        let k = all_args.iter().position(|a| *a == "--top").unwrap();
        all_args[k + 1] = "1000";
        let (_, all, _) = btrel(&all_args);
        let all_ranks = table_ranks(&all);
        let given_rank = |r: &[(String, bool)]| r.iter().find(|x| x.1).unwrap().0.clone();
        assert_eq!(given_rank(&rows), given_rank(&all_ranks), "{all}");
        assert!(rows.iter().any(|r| r.1), "the given ordering is listed");
    }
}

#[test]
fn ties_are_marked() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("same.yaml");
    std::fs::write(
        &path,
        "tree: {fallback: {children: [{action: {name: a, ps: .5, mu: 1, nu: 1}}, {action: {name: b, ps: .5, mu: 1, nu: 1}}, {action: {name: c, ps: .9, mu: 0.1, nu: 1}}]}}\n",
    )
    .unwrap();
    let (code, out, err) = btrel(&["compare", path.to_str().unwrap()]);
    assert_eq!(code, 0, "{err}");
    let ranks: Vec<String> = table_ranks(&out).into_iter().map(|r| r.0).collect();
    // c first, then a and b in either order: two ties of two; the rest
    // (c later) are worse and tie pairwise as well
    assert_eq!(ranks, ["1=", "1=", "3=", "3=", "5=", "5="], "{out}");
    assert!(out.contains("= : tied"), "{out}");
}

#[test]
fn nothing_to_reorder_is_a_statement() {
    let (code, out, err) = btrel(&["compare", "trees/two-arm-parallel.yaml"]);
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("nothing to reorder"), "{out}");
    assert!(err.is_empty(), "{err}");
    let (code, out, _) = btrel(&["compare", "trees/two-arm-parallel.yaml", "--format", "json"]);
    assert_eq!(code, 0);
    let v: serde_json::Value = serde_json::from_str(&out).unwrap();
    assert_eq!(v["orderings"].as_array().unwrap().len(), 1);
    assert_eq!(v["orderings"][0]["given"], true);
    // a Sequence is still refused: its order is the plan
    let (code, _, err) = btrel(&[
        "compare",
        "trees/search-and-grasp.yaml",
        "--node",
        "search and grasp",
    ]);
    assert_eq!(code, 2);
    assert!(err.contains("--node"), "{err}");
}

#[test]
fn progress_reaches_the_total() {
    let t = parse_str(&nine_yaml(), "nine.yaml").unwrap();
    let f = t.find("f").unwrap();
    let done = AtomicU64::new(0);
    let total = AtomicU64::new(0);
    let c = compare_with_progress(
        &t,
        &CompareOptions {
            nodes: vec![f],
            max_candidates: Some(400_000),
            keep: 3,
            ..CompareOptions::default()
        },
        &|d, n| {
            done.fetch_max(d, Ordering::Relaxed);
            total.store(n, Ordering::Relaxed);
        },
    )
    .unwrap();
    assert_eq!(c.search, Search::Exhaustive);
    assert_eq!(total.load(Ordering::Relaxed), 362_880);
    assert_eq!(done.load(Ordering::Relaxed), 362_880);
    // three kept plus the given one (identity is far from the best)
    assert_eq!(c.candidates.len(), 4);
    assert!(c.candidates[3].given);
}
