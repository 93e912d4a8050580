//! Monte Carlo throughput: root episodes of search-and-grasp per second.
//!
//! `cargo bench --bench simulate`; criterion reports the throughput in
//! elements (episodes) per second.

use std::time::Duration;

use btrel::sim::{simulate, SimOptions};
use criterion::{criterion_group, criterion_main, Criterion, Throughput};

const RUNS: u64 = 1 << 23;

fn bench(c: &mut Criterion) {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/trees/search-and-grasp.yaml");
    let tree =
        btrel::tree::parse_file(std::path::Path::new(path)).expect("search-and-grasp parses");
    let mut group = c.benchmark_group("simulate");
    group
        .sample_size(10)
        .measurement_time(Duration::from_secs(3))
        .warm_up_time(Duration::from_secs(1))
        .throughput(Throughput::Elements(RUNS));
    for threads in [0, 1] {
        let opts = SimOptions {
            runs: RUNS,
            threads,
            per_node: false,
            times: vec![10.0, 50.0, 100.0, 200.0, 500.0, 1000.0],
            ..Default::default()
        };
        let label = if threads == 0 {
            "search-and-grasp root, all cores".to_string()
        } else {
            format!("search-and-grasp root, {threads} thread")
        };
        group.bench_function(label, |b| {
            b.iter(|| simulate(&tree, &opts, None).expect("simulates"))
        });
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
