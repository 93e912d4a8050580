//! Large-tree goals: `report` of a 1M-leaf Sequence/Fallback tree end to end
//! (YAML text → parsed tree → analysis → table; goal < 10 s, < 2 GB), and the
//! root curve of a 100k-leaf tree at 1,000 time points to t = 1000 (goal
//! < 10 s). Memory is measured on the binary (README: `/usr/bin/time -v`).
//!
//! Run: `cargo bench --bench scale` (about three minutes: each sample of the
//! million-leaf report takes seconds).

use std::time::Duration;

use criterion::{criterion_group, criterion_main, Criterion};

use btrel::compile::{analyze, Options};
use btrel::curve::{curve, CurveOptions};
use btrel::generate::{random_tree_yaml, Shape};
use btrel::report::{table::TableExporter, Exporter, Report};
use btrel::tree::parse_str;

// as in the `btrel` binary
#[global_allocator]
static ALLOCATOR: mimalloc::MiMalloc = mimalloc::MiMalloc;

fn scale(c: &mut Criterion) {
    let mut group = c.benchmark_group("scale");
    group.sample_size(10);
    group.measurement_time(Duration::from_secs(60));

    let yaml = random_tree_yaml(&Shape::sequence_fallback(1_000_000), 1);
    group.bench_function("report_1m_leaves_end_to_end", |b| {
        b.iter(|| {
            let tree = parse_str(&yaml, "1m.yaml").expect("valid tree");
            let analysis = analyze(&tree, &Options::default()).expect("analysable");
            TableExporter
                .write(&Report::new(&tree, &analysis), &mut std::io::sink())
                .expect("sink");
        })
    });
    drop(yaml);

    let tree = parse_str(
        &random_tree_yaml(&Shape::sequence_fallback(100_000), 1),
        "100k.yaml",
    )
    .expect("valid tree");
    let times: Vec<f64> = (0..1000).map(|k| 1000.0 * k as f64 / 999.0).collect();
    group.bench_function("curve_100k_leaves_1000_points", |b| {
        b.iter(|| curve(&tree, 0, &times, &CurveOptions::default()).expect("curve"))
    });
    group.finish();
}

criterion_group!(benches, scale);
criterion_main!(benches);
