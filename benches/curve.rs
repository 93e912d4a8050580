//! `curve` goals: 1,000 time points of search-and-grasp; 1,000 points of a
//! 10k-leaf tree; a stiff tree (rates 1e-4..1e5) over a 1e7 s horizon;
//! 1,000 points of one attempt of Nav2's default tree (re-planning at 1 Hz
//! raced by the follower: the renewal levels) over 300 s, and of that
//! attempt inside Nav2's RecoveryNode with an exponential recovery (the
//! race's law composed by the flow around it), and of the whole published
//! tree (its fixed 5 s Wait an atom; needs ../shared/realworld); 1,000 points of a random
//! 300- and a 10k-leaf tree with mixed timing (composed laws with atoms).
//!
//! Run: `cargo bench --bench curve` (one: `cargo bench --bench curve -- nav2`)

use std::path::Path;

use criterion::{criterion_group, criterion_main, Criterion};

use btrel::curve::{curve, CurveOptions};
use btrel::generate::{random_tree_yaml, Shape};
use btrel::tree::{parse_file, parse_str};

fn grid(end: f64, points: usize) -> Vec<f64> {
    (0..points)
        .map(|k| end * k as f64 / (points - 1) as f64)
        .collect()
}

fn curves(c: &mut Criterion) {
    let mut group = c.benchmark_group("curve");
    group.sample_size(10);
    let sg = parse_file(Path::new("trees/search-and-grasp.yaml")).expect("tree");
    let times = grid(1000.0, 1000);
    group.bench_function("search_and_grasp_1000_points", |b| {
        b.iter(|| curve(&sg, 0, &times, &CurveOptions::default()).expect("curve"))
    });

    let big = parse_str(
        &random_tree_yaml(&Shape::sequence_fallback(10_000), 1),
        "10k.yaml",
    )
    .expect("tree");
    let times = grid(1000.0, 1000);
    group.bench_function("10k_leaves_1000_points", |b| {
        b.iter(|| curve(&big, 0, &times, &CurveOptions::default()).expect("curve"))
    });

    let stiff = parse_str(
        "tree:\n  sequence:\n    children:\n      - action: {ps: 0.9, mu: 1e5, nu: 1e4}\n      - action: {ps: 0.99, mu: 1e-4, nu: 2e-4}\n      - fallback:\n          children:\n            - action: {ps: 0.5, mu: 10, nu: 1}\n            - action: {ps: 0.5, mu: 1e-3, nu: 1e-2}\n",
        "stiff.yaml",
    )
    .expect("tree");
    let times = grid(1e7, 1000);
    group.bench_function("stiff_horizon_1e7_1000_points", |b| {
        b.iter(|| curve(&stiff, 0, &times, &CurveOptions::default()).expect("curve"))
    });

    // mixed timing (a third each deterministic, hybrid, exponential): the
    // shifted mixture exceeds the budget, the composed laws with atoms
    // answer, as flows over the leaves (convolutions with leaves' laws)
    let times = grid(100.0, 1000);
    for leaves in [300, 10_000] {
        let mixed = parse_str(
            &random_tree_yaml(&Shape::mixed_timing(leaves), 1),
            "mixed.yaml",
        )
        .expect("tree");
        group.bench_function(format!("mixed_{leaves}_leaves_1000_points"), |b| {
            b.iter(|| curve(&mixed, 0, &times, &CurveOptions::default()).expect("curve"))
        });
    }

    let nav2 = btrel::tree::xml::parse_xml_files(
        Path::new("trees/nav2-default-attempt.xml"),
        Path::new("trees/nav2-default-attempt.params.yaml"),
        &[],
    )
    .expect("tree");
    let times = grid(300.0, 1000);
    group.bench_function("nav2_default_attempt_1000_points", |b| {
        b.iter(|| curve(&nav2, 0, &times, &CurveOptions::default()).expect("curve"))
    });

    // the same pipeline inside the published RecoveryNode (6 retries), its
    // recovery one exponential Spin: the race's law composed by the flow
    let recovering = btrel::tree::xml::parse_xml_files(
        Path::new("trees/nav2-default-recovering.xml"),
        Path::new("trees/nav2-default-recovering.params.yaml"),
        &[],
    )
    .expect("tree");
    group.bench_function("nav2_default_recovering_1000_points", |b| {
        b.iter(|| curve(&recovering, 0, &times, &CurveOptions::default()).expect("curve"))
    });

    // the whole tree as published (its fixed 5 s Wait an atom in the
    // composed laws), with trees/nav2-default.params.yaml; skipped without
    // the corpus
    let published = Path::new("../shared/realworld/nav2");
    if published.is_dir() {
        let whole = btrel::tree::xml::parse_xml_files(
            &published.join("navigate_to_pose_w_replanning_and_recovery.xml"),
            Path::new("trees/nav2-default.params.yaml"),
            &[published.join("nav2_tree_nodes.xml")],
        )
        .expect("tree");
        group.bench_function("nav2_default_published_1000_points", |b| {
            b.iter(|| curve(&whole, 0, &times, &CurveOptions::default()).expect("curve"))
        });
        // the same with fitted timings (a shifted planner, an Erlang-3
        // follower): report and curve, the goal is 1 s for both
        let fitted = btrel::tree::xml::parse_xml_files(
            &published.join("navigate_to_pose_w_replanning_and_recovery.xml"),
            Path::new("trees/nav2-fitted.params.yaml"),
            &[published.join("nav2_tree_nodes.xml")],
        )
        .expect("tree");
        group.bench_function("nav2_fitted_report", |b| {
            b.iter(|| btrel::analyze(&fitted, &btrel::Options::default()).expect("report"))
        });
        group.bench_function("nav2_fitted_1000_points", |b| {
            b.iter(|| curve(&fitted, 0, &times, &CurveOptions::default()).expect("curve"))
        });
        // a time far past its return: answered from its figures past the
        // tail bound (it was found by computing the curve at 16 × its mean
        // time, doubling)
        group.bench_function("nav2_fitted_far_time", |b| {
            b.iter(|| curve(&fitted, 0, &[1e7], &CurveOptions::default()).expect("curve"))
        });
    } else {
        eprintln!("nav2_default_published_1000_points skipped: ../shared/realworld is absent");
    }
    group.finish();
}

criterion_group!(benches, curves);
criterion_main!(benches);
