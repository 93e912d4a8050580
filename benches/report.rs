//! `report` on generated Sequence/Fallback trees, end to end (YAML text →
//! parsed tree → analysis → table) and by phase.
//!
//! Run: `cargo bench --bench report`

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};

use btrel::compile::{analyze, Options};
use btrel::generate::{random_tree_yaml, Shape};
use btrel::report::{table::TableExporter, Exporter, Report};
use btrel::tree::parse_str;

// as in the `btrel` binary
#[global_allocator]
static ALLOCATOR: mimalloc::MiMalloc = mimalloc::MiMalloc;

fn report(c: &mut Criterion) {
    let mut group = c.benchmark_group("report");
    group.sample_size(10);
    for leaves in [10_000usize, 100_000] {
        let yaml = random_tree_yaml(&Shape::sequence_fallback(leaves), 1);
        group.throughput(Throughput::Elements(leaves as u64));
        group.bench_with_input(BenchmarkId::new("end_to_end", leaves), &yaml, |b, yaml| {
            b.iter(|| {
                let tree = parse_str(yaml, "bench.yaml").expect("valid tree");
                let analysis = analyze(&tree, &Options::default()).expect("analysable");
                let mut sink = std::io::sink();
                TableExporter
                    .write(&Report::new(&tree, &analysis), &mut sink)
                    .expect("sink");
            })
        });
        let tree = parse_str(&yaml, "bench.yaml").expect("valid tree");
        group.bench_with_input(BenchmarkId::new("analyze", leaves), &tree, |b, tree| {
            b.iter(|| analyze(tree, &Options::default()).expect("analysable"))
        });
    }
    group.finish();
}

criterion_group!(benches, report);
criterion_main!(benches);
