//! Monte Carlo throughput: root episodes per second of search-and-grasp and
//! of Nav2's default tree (when the published corpus is there), and
//! `simulate` with every node.
//!
//! `cargo bench --bench simulate`; criterion reports the throughput in
//! elements (episodes) per second. With `BTREL_PYTHON` set to a Python with
//! numpy and PyYAML, the numpy anchor (`scripts/numpy_mc.py`, one core) is
//! run side by side first and its episodes per second printed.

use std::path::Path;
use std::time::Duration;

use btrel::sim::{simulate, SimOptions};
use criterion::{criterion_group, criterion_main, Criterion, Throughput};

const RUNS: u64 = 1 << 23;
const NAV2_RUNS: u64 = 1 << 18;

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

/// Runs the numpy anchor with `args`; prints its throughput.
fn numpy_anchor(label: &str, args: &[&str]) {
    let Some(py) = std::env::var_os("BTREL_PYTHON") else {
        eprintln!("numpy anchor skipped: set BTREL_PYTHON (numpy, PyYAML)");
        return;
    };
    let out = std::process::Command::new(py)
        .arg(root().join("scripts/numpy_mc.py"))
        .args(args)
        .arg("--json")
        .current_dir(root())
        .output();
    match out {
        Ok(o) if o.status.success() => {
            let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap_or_default();
            let rate = v["episodes_per_second"].as_f64().unwrap_or(f64::NAN);
            eprintln!(
                "numpy anchor, {label}: {:.3} M episodes/s (one core)",
                rate / 1e6
            );
        }
        _ => eprintln!("numpy anchor, {label}: scripts/numpy_mc.py failed"),
    }
}

fn bench(c: &mut Criterion) {
    let path = root().join("trees/search-and-grasp.yaml");
    let tree = btrel::tree::parse_file(&path).expect("search-and-grasp parses");
    numpy_anchor(
        "search-and-grasp",
        &[
            "trees/search-and-grasp.yaml",
            "--runs",
            "4000000",
            "--times",
            "10,100,1000",
        ],
    );
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
            times: vec![10.0, 100.0, 1000.0],
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
    // every node: runs of each of the 12 nodes (throughput in root episodes)
    let opts = SimOptions {
        runs: RUNS,
        per_node: true,
        ..Default::default()
    };
    group.bench_function("search-and-grasp every node, all cores", |b| {
        b.iter(|| simulate(&tree, &opts, None).expect("simulates"))
    });
    group.finish();

    let corpus = std::env::var_os("BTREL_REALWORLD")
        .map(std::path::PathBuf::from)
        .unwrap_or_else(|| root().join("../shared/realworld"));
    let nav2 = corpus.join("nav2");
    let Ok(tree) = btrel::tree::xml::parse_xml_files(
        &nav2.join("navigate_to_pose_w_replanning_and_recovery.xml"),
        &root().join("trees/nav2-default.params.yaml"),
        &[nav2.join("nav2_tree_nodes.xml")],
    ) else {
        eprintln!("Nav2 benches skipped: the published corpus (../shared/realworld) is not there");
        return;
    };
    numpy_anchor(
        "Nav2 default tree",
        &[
            "--nav2",
            "trees/nav2-default.params.yaml",
            "--runs",
            "200000",
        ],
    );
    let mut group = c.benchmark_group("simulate_nav2");
    group
        .sample_size(10)
        .measurement_time(Duration::from_secs(5))
        .warm_up_time(Duration::from_secs(1))
        .throughput(Throughput::Elements(NAV2_RUNS));
    for threads in [0, 1] {
        let opts = SimOptions {
            runs: NAV2_RUNS,
            threads,
            per_node: false,
            ..Default::default()
        };
        let label = if threads == 0 {
            "nav2 default root, all cores".to_string()
        } else {
            format!("nav2 default root, {threads} thread")
        };
        group.bench_function(label, |b| {
            b.iter(|| simulate(&tree, &opts, None).expect("simulates"))
        });
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
