//! btrel's CTMC exports solved by a real model checker: Storm, through its
//! Python bindings (stormpy) and `scripts/storm_check.py`.
//!
//! For bundled trees, every export format (`--to prism`: the PRISM-language
//! model, parsed in Storm's PRISM-compatibility mode; `--to prism-explicit`:
//! PRISM's `.tra/.sta/.lab/.srew`, converted to Storm's explicit dialect by
//! the script; `--to drn`: Storm's DRN) is solved by Storm — ps, pf, the
//! mean time `R{"time"}=? [F "done"]` and `P=? [F<=t "success"/"failure"]`,
//! weighted over the initial distribution — and compared with btrel's own
//! figures and curves, which btrel computes by other means (its closed
//! forms, counting products of Parallel children, its own transient
//! solver). Storm runs in its sound environment at precision 1e-12.
//! Agreement: relative 1e-9, with an absolute floor of 1e-12 for values near
//! 0 (Storm's uniformisation truncates with an absolute error bound).
//!
//! The test needs a Python with stormpy: `BTREL_PYTHON`, else the venv
//! `target/pyvenv` the tests create from tests/python-requirements.txt
//! (`tests/common/python.rs`); without one it says SKIPPED and passes
//! (fails with `BTREL_REQUIRE_PYTHON=1`).

mod common;

use std::path::Path;
use std::process::Command;

use btrel::compile::phase::phase_chain;
use btrel::compile::{analyze, Options};
use btrel::curve::{curve, CurveOptions};
use btrel::tree::{parse_file, NodeKind, Tree};
use common::python::python;
use serde_json::Value;

const ROOT: &str = env!("CARGO_MANIFEST_DIR");

fn btrel(args: &[&str]) {
    let out = Command::new(env!("CARGO_BIN_EXE_btrel"))
        .args(args)
        .output()
        .expect("run btrel");
    assert!(
        out.status.success(),
        "btrel {args:?} failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
}

fn storm(python: &Path, args: &[&str]) -> Value {
    let out = Command::new(python)
        .arg(Path::new(ROOT).join("scripts/storm_check.py"))
        .args(args)
        .output()
        .expect("run the Storm script with the tests' Python");
    assert!(
        out.status.success(),
        "storm_check.py {args:?} failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).unwrap_or_else(|e| {
        panic!(
            "storm_check.py {args:?}: bad JSON ({e}): {}",
            String::from_utf8_lossy(&out.stdout)
        )
    })
}

use std::cell::Cell;

thread_local! {
    /// The largest relative difference seen (values above 1e-6 only).
    static WORST: Cell<f64> = const { Cell::new(0.0) };
}

fn close(what: &str, storm: f64, btrel: f64) {
    let err = (storm - btrel).abs();
    let scale = storm.abs().max(btrel.abs());
    assert!(
        err <= 1e-9 * scale + 1e-12,
        "{what}: Storm {storm:e} vs btrel {btrel:e} (difference {err:e})"
    );
    if scale > 1e-6 {
        WORST.with(|w| w.set(w.get().max(err / scale)));
    }
}

fn num(v: &Value, key: &str) -> f64 {
    v[key]
        .as_f64()
        .unwrap_or_else(|| panic!("no number {key} in {v}"))
}

/// Exports node `node` of `tree` in every format, solves each with Storm and
/// compares with btrel; returns the number of models checked.
fn check(python: &Path, file: &str, node: Option<&str>, times: &[f64]) -> usize {
    let path = Path::new(ROOT).join(file);
    let tree: Tree = parse_file(&path).unwrap_or_else(|e| panic!("{e}"));
    let id = node.map_or(Tree::ROOT, |n| {
        tree.find(n).unwrap_or_else(|| panic!("no node {n}"))
    });
    let figures = analyze(&tree, &Options::default()).expect("analysis").nodes[id];
    let points = curve(&tree, id, times, &CurveOptions::default()).expect("curve");
    let chain = phase_chain(&tree, id, 16_000_000).expect("phase chain");
    // `--to prism` writes a Parallel as one module per child
    let modular = matches!(tree.node(id).kind, NodeKind::Parallel { .. });
    let fastest = (0..chain.len())
        .map(|i| chain.total_rate(i))
        .fold(0.0f64, f64::max);

    let dir = tempfile::tempdir().unwrap();
    let at = |name: &str| dir.path().join(name).to_str().unwrap().to_string();
    let tree_arg = path.to_str().unwrap();
    let mut common = vec!["export", tree_arg, "--to"];
    let node_args: Vec<&str> = node.map_or(vec![], |n| vec!["--node", n]);
    let (sm, drn, base, csl) = (at("m.sm"), at("m.drn"), at("m"), at("m.csl"));
    let times_arg = times
        .iter()
        .map(|t| format!("{t:?}"))
        .collect::<Vec<_>>()
        .join(",");
    let sm_csl = at("sm.csl");
    common.extend([
        "prism",
        "-o",
        &sm,
        "--properties",
        &sm_csl,
        "--times",
        &times_arg,
    ]);
    btrel(&[common.as_slice(), node_args.as_slice()].concat());
    common.truncate(3);
    common.extend(["drn", "-o", &drn]);
    btrel(&[common.as_slice(), node_args.as_slice()].concat());
    common.truncate(3);
    common.extend([
        "prism-explicit",
        "-o",
        &base,
        "--properties",
        &csl,
        "--times",
        &times_arg,
    ]);
    btrel(&[common.as_slice(), node_args.as_slice()].concat());
    let tra = format!("{base}.tra");
    let runs: [Vec<&str>; 3] = [
        vec![&sm, "--prism-properties", &sm_csl, "--times", &times_arg],
        vec![&drn, "--times", &times_arg],
        vec![&tra, "--prism-properties", &csl, "--times", &times_arg],
    ];
    for args in &runs {
        let what = format!("{file} {} ({})", node.unwrap_or("root"), args[0]);
        let r = storm(python, args);
        if modular && args[0] == sm {
            // one module per child: PRISM's product, whose decided states
            // keep the children's positions (the flat chain merges them)
            assert!(
                r["states"].as_u64() > Some(chain.len() as u64 + 2),
                "{what}: {r}"
            );
        } else {
            assert_eq!(
                r["states"].as_u64(),
                Some(chain.len() as u64 + 2),
                "{what}: {r}"
            );
        }
        close(&format!("{what}: ps"), num(&r, "ps"), figures.ps);
        close(&format!("{what}: pf"), num(&r, "pf"), figures.pf);
        close(
            &format!("{what}: mean time"),
            num(&r, "mean_time"),
            figures.mean_time(),
        );
        let storm_curve = r["curve"].as_array().expect("curve");
        assert_eq!(storm_curve.len(), points.len());
        for (s, p) in storm_curve.iter().zip(&points) {
            assert_eq!(num(s, "t"), p.t);
            close(
                &format!("{what}: success by {}", p.t),
                num(s, "success"),
                p.success,
            );
            close(
                &format!("{what}: failure by {}", p.t),
                num(s, "failure"),
                p.failure,
            );
        }
        // the properties files as written, the times in them (PRISM takes
        // no -const with an imported model), checked by Storm
        if args.contains(&"--prism-properties") {
            let props = &r["properties"];
            for p in &points {
                for (o, want) in [("success", p.success), ("failure", p.failure)] {
                    // PRISM's names are identifiers: `p` for the point
                    let name = format!("{o}_by_{}", p.t).replace('.', "p");
                    close(&format!("{what}: property {name}"), num(props, &name), want);
                }
            }
            close(
                &format!("{what}: property ps"),
                num(props, "ps"),
                figures.ps,
            );
            close(
                &format!("{what}: property mean_time"),
                num(props, "mean_time"),
                figures.mean_time(),
            );
        }
        // the absorbing self-loops do not raise the uniformisation rate
        if !chain.is_empty() {
            // (equal up to the order of summation of a row)
            let (all, running) = (num(&r, "max_exit_rate"), num(&r, "max_running_exit_rate"));
            assert!(
                all <= running * (1.0 + 4.0 * f64::EPSILON),
                "{what}: {all} > {running}"
            );
            close(
                &format!("{what}: fastest rate"),
                num(&r, "max_exit_rate"),
                fastest,
            );
        }
    }
    runs.len()
}

#[test]
fn storm_solves_the_exports_like_btrel() {
    let Some(python) = python("Storm (stormpy) on the exports") else {
        return;
    };
    let t = [0.0, 1.0, 10.0, 100.0, 1000.0];
    let mut models = 0;
    models += check(&python, "trees/search-and-grasp.yaml", None, &t);
    models += check(
        &python,
        "trees/search-and-grasp.yaml",
        Some("find object"),
        &t,
    );
    models += check(&python, "trees/search-and-grasp.yaml", Some("grasp"), &t);
    models += check(&python, "trees/three-action-fallback.yaml", None, &t);
    models += check(&python, "trees/two-arm-parallel.yaml", None, &t);
    models += check(
        &python,
        "trees/two-arm-parallel.yaml",
        Some("both arms"),
        &t,
    );
    models += check(&python, "trees/keys-table-or-drawer.yaml", None, &t);
    // Parallels as modules: conditions returning at once (the tick order
    // decides), a nested Parallel split into modules and one kept whole,
    // and the 8-action Parallel of the README's "which route"
    models += check(&python, "tests/data/parallel-modules.yaml", None, &t);
    models += check(
        &python,
        "tests/data/parallel-modules.yaml",
        Some("inner"),
        &t,
    );
    models += check(
        &python,
        "tests/data/eight-action-parallel.yaml",
        None,
        &[0.0, 0.5, 2.0, 10.0],
    );
    // hyperexponential and phase-type leaves (one with a cycle): their chains
    models += check(&python, "trees/phase-type.yaml", None, &t);
    models += check(&python, "trees/phase-type.yaml", Some("get help"), &t);
    // rates up to 1.1e5/s: uniformisation takes 1e5 steps per second of
    // horizon, so the horizon stays short (the mean time and the eventual
    // probabilities need none)
    let short = [0.0, 1e-5, 1e-4, 1e-3, 0.1, 1.0];
    models += check(&python, "trees/extremes.yaml", None, &short);
    models += check(
        &python,
        "trees/extremes.yaml",
        Some("pair"),
        &[0.0, 1.0, 10.0, 100.0],
    );
    eprintln!(
        "{models} exported models solved by Storm agree with btrel (largest relative \
         difference {:.1e})",
        WORST.with(Cell::get)
    );
}
