//! The engine issue's cases: the book's Example 9.2 (deterministic ∥
//! stochastic), a mixed-timing Sequence/Fallback tree, 16 stiff subtree
//! children (rates 1e6 and 1e-3), D nested wide Parallels over 1,000
//! actions, and two races (Parallel M = 1, F = 1): BT.CPP's Timeout shape
//! (a deadline against a hybrid action) and Nav2's re-planning (a loop of
//! a 1 s wait and a planner against the follower; a short series, and a
//! long one that the renewal method answers).
//!
//! Run: `cargo bench --bench engine`

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion};

use btrel::compile::{analyze, Options};
use btrel::curve::{curve, CurveOptions};
use btrel::tree::parse_str;

#[global_allocator]
static ALLOCATOR: mimalloc::MiMalloc = mimalloc::MiMalloc;

const EXAMPLE_9_2: &str = "tree: {parallel: {children: [\
    {action: {ps: 0.9, tau_s: 2.0, tau_f: 1.0}}, {action: {ps: 0.8, mu: 0.5, nu: 1.0}}]}}";

/// Sequence(deterministic, Fallback(stochastic, hybrid)) repeated `k` times
/// under a Fallback: shifts and phase chains combined.
fn mixed(k: usize) -> String {
    let unit = "{sequence: {children: [{action: {ps: 0.9, tau_s: 1.0, tau_f: 0.5}}, \
                {fallback: {children: [{action: {ps: 0.8, mu: 2.0, nu: 1.0}}, \
                {action: {ps: 0.6, tau_s: 3.0, nu: 0.5}}]}}]}}";
    format!(
        "tree: {{fallback: {{children: [{}]}}}}",
        vec![unit; k].join(", ")
    )
}

/// Timeout(1.2 s) over a hybrid action, as the XML front end lowers it.
const TIMEOUT_RACE: &str = "tree: {parallel: {success_threshold: 1, failure_threshold: 1, \
    children: [{action: {ps: 0, tau_f: 1.2}}, {action: {ps: 0.6, tau_s: 0.9, nu: 1.7}}]}}";

/// Re-planning every 1 s (planner ps 0.7) raced against the follower.
const REPLANNING_RACE: &str = "tree: {parallel: {success_threshold: 1, failure_threshold: 1, \
    children: [{until_failure: {child: {sequence: {children: [{action: {ps: 1, tau_s: 1}}, \
    {action: {ps: 0.7, mu: 4, nu: 2}}]}}}}, {action: {ps: 0.9, mu: 0.2, nu: 0.1}}]}}";

/// The same with a planner failing 0.5% of the time (its series would need
/// about 6,430 re-runs; the renewal method needs none): report only, its
/// curve needs the series.
const LONG_REPLANNING_RACE: &str = "tree: {parallel: {success_threshold: 1, \
    failure_threshold: 1, children: [{until_failure: {child: {sequence: {children: [\
    {action: {ps: 1, tau_s: 1}}, {action: {ps: 0.995, mu: 4, nu: 2}}]}}}}, \
    {action: {ps: 0.9, mu: 0.0166667, nu: 0.05}}]}}";

fn stiff16() -> String {
    let sub = "{sequence: {children: [{action: {ps: 0.99, mu: 1e6, nu: 1e6}}, \
               {action: {ps: 0.9, mu: 0.001, nu: 0.001}}]}}";
    format!(
        "tree: {{parallel: {{success_threshold: 8, children: [{}]}}}}",
        vec![sub; 16].join(", ")
    )
}

/// D nested Parallels (M = half) over 1,000 actions in all, each level
/// holding 1000/D actions and the next level.
fn nested(d: usize) -> String {
    let per = 1000 / d;
    let mut inner = String::new();
    for level in (0..d).rev() {
        let mut kids: Vec<String> = (0..per)
            .map(|i| {
                format!(
                    "{{action: {{ps: 0.99, mu: {}, nu: 2.0}}}}",
                    1.0 + 0.01 * i as f64
                )
            })
            .collect();
        if level < d - 1 {
            kids.push(std::mem::take(&mut inner));
        }
        inner = format!(
            "{{parallel: {{success_threshold: {}, children: [{}]}}}}",
            (kids.len() / 2).max(1),
            kids.join(", ")
        );
    }
    format!("tree: {inner}")
}

fn engine(c: &mut Criterion) {
    let mut group = c.benchmark_group("engine");
    group.sample_size(10);
    let grid: Vec<f64> = (0..1000).map(|k| 0.02 * k as f64).collect();
    let mut cases = vec![
        ("example_9_2".to_string(), EXAMPLE_9_2.to_string()),
        ("mixed_fallback_of_4".to_string(), mixed(4)),
        ("stiff_16_subtrees".to_string(), stiff16()),
        ("timeout_race".to_string(), TIMEOUT_RACE.to_string()),
        ("replanning_race".to_string(), REPLANNING_RACE.to_string()),
        (
            "long_replanning_race".to_string(),
            LONG_REPLANNING_RACE.to_string(),
        ),
    ];
    for d in [25, 50, 100] {
        cases.push((format!("nested_{d}_levels"), nested(d)));
    }
    for (name, yaml) in &cases {
        let tree = parse_str(yaml, "bench.yaml").expect("valid tree");
        group.bench_with_input(BenchmarkId::new("report", name), &tree, |b, tree| {
            b.iter(|| analyze(tree, &Options::default()).expect("analysable"))
        });
        if !name.starts_with("nested") && !name.starts_with("stiff") && !name.starts_with("long") {
            group.bench_with_input(
                BenchmarkId::new("curve_1000_points", name),
                &tree,
                |b, tree| {
                    b.iter(|| curve(tree, 0, &grid, &CurveOptions::default()).expect("curve"))
                },
            );
        }
    }
    // one attempt of Nav2's default tree (trees/nav2-default-attempt.xml):
    // re-planning at 1 Hz with a costmap-clearing retry, raced by the
    // follower with its own
    let attempt = btrel::tree::xml::parse_xml_files(
        std::path::Path::new("trees/nav2-default-attempt.xml"),
        std::path::Path::new("trees/nav2-default-attempt.params.yaml"),
        &[],
    )
    .expect("the bundled tree reads");
    group.bench_with_input(
        BenchmarkId::new("report", "nav2_default_attempt_race"),
        &attempt,
        |b, tree| b.iter(|| analyze(tree, &Options::default()).expect("analysable")),
    );
    group.finish();
}

criterion_group!(benches, engine);
criterion_main!(benches);
