//! XML input, `plot` and `export` from the command line.

use assert_cmd::Command;
use serde_json::Value;

fn btrel() -> Command {
    Command::cargo_bin("btrel").expect("binary")
}

fn json_report(args: &[&str]) -> Value {
    let out = btrel()
        .args(args)
        .args(["--format", "json"])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).unwrap()
}

#[test]
fn xml_twin_reports_the_same_numbers() {
    let yaml = json_report(&["report", "trees/search-and-grasp.yaml"]);
    // parameters found next to the tree by default
    let xml = json_report(&["report", "trees/search-and-grasp.xml"]);
    let explicit = json_report(&[
        "report",
        "trees/search-and-grasp.xml",
        "--params",
        "trees/search-and-grasp.params.yaml",
    ]);
    assert_eq!(xml["nodes"], explicit["nodes"]);
    for node in yaml["nodes"].as_array().unwrap() {
        let twin = xml["nodes"]
            .as_array()
            .unwrap()
            .iter()
            .find(|n| n["name"] == node["name"])
            .unwrap_or_else(|| panic!("no {} in the XML twin", node["name"]));
        for key in ["ps", "mtts", "mttf"] {
            match (node[key].as_f64(), twin[key].as_f64()) {
                (Some(a), Some(b)) => assert!((a - b).abs() <= 1e-12 * a.abs().max(1.0), "{key}"),
                (a, b) => assert_eq!(a, b, "{key}"),
            }
        }
    }
}

fn fails_with(args: &[&str], phrase: &str) {
    let out = btrel().args(args).output().unwrap();
    assert_eq!(out.status.code(), Some(2), "{args:?}");
    assert!(out.stdout.is_empty());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains(phrase), "{args:?}: {err}");
}

#[test]
fn input_errors() {
    let dir = tempfile::tempdir().unwrap();
    let xml = dir.path().join("t.xml");
    std::fs::write(
        &xml,
        "<root BTCPP_format=\"4\"><BehaviorTree ID=\"T\"><Action ID=\"A\"/></BehaviorTree></root>",
    )
    .unwrap();
    fails_with(
        &["report", xml.to_str().unwrap()],
        "needs a parameters file",
    );
    fails_with(
        &[
            "report",
            "trees/search-and-grasp.yaml",
            "--params",
            "trees/search-and-grasp.params.yaml",
        ],
        "--params goes with an XML tree",
    );
    // a YAML tree read as XML is refused with a location
    let out = btrel()
        .args([
            "check",
            "trees/search-and-grasp.yaml",
            "--input-format",
            "xml",
            "--params",
        ])
        .arg("trees/search-and-grasp.params.yaml")
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
}

#[test]
fn plots_are_written() {
    let dir = tempfile::tempdir().unwrap();
    for (name, extra) in [
        ("plain.svg", vec![]),
        ("mc.svg", vec!["--mc", "2e4"]),
        ("both.svg", vec!["--timing", "both"]),
        (
            "compare.svg",
            vec!["--compare", "search", "--deadline", "100"],
        ),
        ("nodes.svg", vec!["--node", "search", "--node", "grasp"]),
    ] {
        let path = dir.path().join(name);
        btrel()
            .args(["plot", "trees/search-and-grasp.yaml", "-o"])
            .arg(&path)
            .args(&extra)
            .assert()
            .success()
            .stdout("");
        let svg = std::fs::read_to_string(&path).unwrap();
        assert!(
            svg.contains("<svg") && svg.trim_end().ends_with("</svg>"),
            "{name}"
        );
        assert!(svg.contains("polyline"), "{name}");
    }
    fails_with(
        &[
            "plot",
            "trees/search-and-grasp.yaml",
            "-o",
            "/tmp/x.svg",
            "--points",
            "1",
        ],
        "--points",
    );
    fails_with(&["plot", "trees/search-and-grasp.yaml"], "--output");
}

#[test]
fn exports() {
    let out = btrel()
        .args(["export", "trees/search-and-grasp.yaml", "--to", "dot"])
        .output()
        .unwrap();
    let dot = String::from_utf8(out.stdout).unwrap();
    assert!(dot.starts_with("digraph") && dot.contains("→") && dot.contains('?'));
    let out = btrel()
        .args([
            "export",
            "trees/search-and-grasp.yaml",
            "--to",
            "dot",
            "--mrg",
            "search",
        ])
        .output()
        .unwrap();
    assert!(String::from_utf8(out.stdout)
        .unwrap()
        .contains("[-1,-1,-1]"));
    let dir = tempfile::tempdir().unwrap();
    let (model, props) = (dir.path().join("m.sm"), dir.path().join("m.csl"));
    btrel()
        .args([
            "export",
            "trees/search-and-grasp.yaml",
            "--to",
            "prism",
            "-o",
        ])
        .arg(&model)
        .arg("--properties")
        .arg(&props)
        .assert()
        .success();
    assert!(std::fs::read_to_string(&model).unwrap().contains("ctmc"));
    assert!(std::fs::read_to_string(&props)
        .unwrap()
        .contains("\"success_by_T\""));
    fails_with(
        &[
            "export",
            "trees/search-and-grasp.yaml",
            "--to",
            "prism",
            "--mrg",
            "search",
        ],
        "--mrg goes with --to dot",
    );
    fails_with(
        &[
            "export",
            "trees/search-and-grasp.yaml",
            "--to",
            "dot",
            "--mrg",
            "search floor",
        ],
        "marking reachability graph",
    );
    fails_with(
        &["export", "trees/search-and-grasp.yaml", "--to", "svg"],
        "invalid value",
    );
}
