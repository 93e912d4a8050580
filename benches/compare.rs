//! `compare` goals: all 40,320 orderings of an 8-child Fallback under the
//! mean time (< 1 s) and under a deadline objective (< 10 s).
//!
//! Run: `cargo bench --bench compare`

use criterion::{criterion_group, criterion_main, Criterion};

use btrel::compare::{compare, CompareOptions};
use btrel::tree::parse_str;

fn eight_child_fallback() -> String {
    let kids: Vec<String> = (0..8)
        .map(|i| {
            let ps = 0.1 + 0.1 * i as f64;
            let mu = 0.05 * (1 + i % 3) as f64;
            let nu = 0.1 * (1 + (i * 5) % 4) as f64;
            format!("{{action: {{name: a{i}, ps: {ps:.2}, mu: {mu}, nu: {nu}}}}}")
        })
        .collect();
    format!(
        "tree: {{fallback: {{name: f, children: [{}]}}}}",
        kids.join(", ")
    )
}

fn orderings(c: &mut Criterion) {
    let tree = parse_str(&eight_child_fallback(), "8.yaml").expect("tree");
    let mut group = c.benchmark_group("compare");
    group.sample_size(10);
    group.bench_function("8_children_40320_orderings_mean_time", |b| {
        b.iter(|| {
            let r = compare(&tree, &CompareOptions::default()).expect("compare");
            assert_eq!(r.evaluated, 40_320);
        })
    });
    group.bench_function("8_children_40320_orderings_deadline", |b| {
        b.iter(|| {
            compare(
                &tree,
                &CompareOptions {
                    deadline: Some(20.0),
                    ..CompareOptions::default()
                },
            )
            .expect("compare")
        })
    });
    group.finish();
}

criterion_group!(benches, orderings);
criterion_main!(benches);
