//! Wide and nested Parallel nodes: `report` (figures with certified mean
//! times) and `curve` at 4 time points of Parallels of 10, 16 and 24 leaf
//! children, of a Sequence(action, Parallel of 8 subtrees, action), and of
//! a three-phase mission with three Parallels of 8 subtrees.
//!
//! Run: `cargo bench --bench parallel`

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion};

use btrel::compile::{analyze, Options};
use btrel::curve::{curve, CurveOptions};
use btrel::tree::parse_str;

#[global_allocator]
static ALLOCATOR: mimalloc::MiMalloc = mimalloc::MiMalloc;

fn action(i: usize) -> String {
    let i = i as f64;
    format!(
        "{{action: {{ps: {}, mu: {}, nu: {}}}}}",
        0.5 + 0.015 * i,
        0.5 + 0.1 * i,
        1.0 + 0.05 * i
    )
}

fn wide(n: usize) -> String {
    let kids: Vec<String> = (0..n).map(action).collect();
    format!(
        "tree: {{parallel: {{success_threshold: {}, children: [{}]}}}}",
        n / 2,
        kids.join(", ")
    )
}

/// Sequence(action, Parallel(5 of 8 subtrees of 2-3 actions), action):
/// product bound 1.7e7 states.
fn nested() -> String {
    let subtrees: Vec<String> = (0..8)
        .map(|i| {
            let kind = if i % 2 == 0 { "sequence" } else { "fallback" };
            format!(
                "{{{kind}: {{children: [{}, {}]}}}}",
                action(i),
                action(i + 8)
            )
        })
        .collect();
    format!(
        "tree: {{sequence: {{children: [{}, {{parallel: {{success_threshold: 5, children: [{}]}}}}, {}]}}}}",
        action(20),
        subtrees.join(", "),
        action(21)
    )
}

/// Sequence(8 of 8, 6 of 8, Retry 2 × (7 of 8)) over two-level robot
/// subtrees: three wide Parallels in one Sequence, one under a Retry.
fn mission() -> String {
    let robot = |i: usize| {
        format!(
            "{{sequence: {{children: [{}, {{fallback: {{children: [{}, {}]}}}}]}}}}",
            action(i),
            action(i + 8),
            action(i + 16)
        )
    };
    let parallel = |m: usize| {
        let kids: Vec<String> = (0..8).map(robot).collect();
        format!(
            "{{parallel: {{success_threshold: {m}, children: [{}]}}}}",
            kids.join(", ")
        )
    };
    format!(
        "tree: {{sequence: {{children: [{}, {}, {{retry: {{attempts: 2, child: {}}}}}]}}}}",
        parallel(8),
        parallel(6),
        parallel(7)
    )
}

fn parallels(c: &mut Criterion) {
    let mut group = c.benchmark_group("parallel");
    group.sample_size(20);
    let times = [0.5, 1.0, 2.0, 5.0];
    let mut cases: Vec<(String, String)> = [10, 16, 24]
        .iter()
        .map(|&n| (format!("wide_{n}"), wide(n)))
        .collect();
    cases.push(("nested_8_subtrees".into(), nested()));
    cases.push(("mission_3_wide".into(), mission()));
    for (name, yaml) in &cases {
        let tree = parse_str(yaml, "bench.yaml").expect("valid tree");
        group.bench_with_input(BenchmarkId::new("report", name), &tree, |b, tree| {
            b.iter(|| analyze(tree, &Options::default()).expect("analysable"))
        });
        group.bench_with_input(
            BenchmarkId::new("curve_4_points", name),
            &tree,
            |b, tree| b.iter(|| curve(tree, 0, &times, &CurveOptions::default()).expect("curve")),
        );
    }
    group.finish();
}

criterion_group!(benches, parallels);
criterion_main!(benches);
