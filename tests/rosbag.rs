//! `btrel fit` on rosbag2 recordings of Nav2's `behavior_tree_log`: bags
//! written by the `rosbags` Python library (tests/python-requirements.txt,
//! in the tests' Python, tests/common/python.rs) from simulated runs with known parameters
//! (tests/rosbag/make_bags.py), MCAP and SQLite storage, both message
//! layouts; and the public bt_tools recording (tests/data/rosbag/).

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;

use btrel::fit::{fit_logs, By, Counts, Estimate, Timing};
use btrel::logs::rosbag;

const ROOT: &str = env!("CARGO_MANIFEST_DIR");

/// Tree `nav` of make_bags.py: uids 1..5 depth-first.
const NAV_XML: &str = r#"<root BTCPP_format="4" main_tree_to_execute="MainTree">
  <BehaviorTree ID="MainTree">
    <Sequence name="Navigate">
      <RecoveryNode number_of_retries="1" name="ComputePathToPose">
        <ComputePathToPose goal="{goal}" path="{path}"/>
        <ClearEntireCostmap name="ClearGlobalCostmap" service_name="global_costmap/clear_entirely_global_costmap"/>
      </RecoveryNode>
      <FollowPath path="{path}"/>
    </Sequence>
  </BehaviorTree>
</root>
"#;

/// Tree `twins` of make_bags.py: two leaves named W.
const TWINS_XML: &str = r#"<root BTCPP_format="4" main_tree_to_execute="MainTree">
  <BehaviorTree ID="MainTree">
    <Sequence>
      <Wait name="W" wait_duration="1"/>
      <Wait name="W" wait_duration="1"/>
    </Sequence>
  </BehaviorTree>
</root>
"#;

fn bin() -> assert_cmd::Command {
    assert_cmd::Command::cargo_bin("btrel").expect("binary")
}

/// Runs make_bags.py into `dir` and returns its JSON.
fn make_bags(py: &Path, dir: &Path, args: &[&str]) -> serde_json::Value {
    let o = Command::new(py)
        .arg(format!("{ROOT}/tests/rosbag/make_bags.py"))
        .arg(dir)
        .args(args)
        .output()
        .unwrap();
    assert!(
        o.status.success(),
        "make_bags.py: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    serde_json::from_slice(&o.stdout).unwrap()
}

fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

fn counts_of(log: &btrel::logs::Log, id: &str) -> Counts {
    Counts::from_episodes(
        log.leaves
            .iter()
            .filter(|l| l.id == id)
            .flat_map(|l| l.episodes.iter()),
    )
}

/// Every bag's episodes, read back, are the simulation's exactly (counts,
/// and total times to 1 µs): for each storage and layout, with halted goals,
/// several goals per bag, the RecoveryNode named like its action, and an
/// unrelated topic.
#[test]
fn episodes_are_the_simulated_ones() {
    let Some(py) = common::python::python("rosbag2 recordings made with rosbags") else {
        return;
    };
    let tree_dir = tempfile::tempdir().unwrap();
    let tree = write(tree_dir.path(), "nav.xml", NAV_XML);
    for (storage, layout, extra) in [
        ("mcap", "uid", None),
        ("sqlite3", "uid", None),
        ("mcap", "nouid", None),
        ("sqlite3", "nouid", Some("--no-definition")),
        ("mcap", "uid", Some("--no-definition")),
    ] {
        let dir = tempfile::tempdir().unwrap();
        let mut args = vec![
            "--bags",
            "2",
            "--goals",
            "150",
            "--seed",
            "11",
            "--storage",
            storage,
            "--layout",
            layout,
            "--cancel",
            "0.3",
        ];
        args.extend(extra);
        let out = make_bags(&py, dir.path(), &args);
        for b in 0..2 {
            let bag = dir.path().join(format!("bag_{b}"));
            let read = rosbag::read(&bag, &tree, &[], None)
                .unwrap_or_else(|e| panic!("{storage} {layout} {extra:?}: {e}"));
            let (l, from) = read.layout.clone().unwrap();
            assert_eq!(
                l,
                if layout == "uid" {
                    rosbag::Layout::WithUid
                } else {
                    rosbag::Layout::WithoutUid
                },
                "{storage} {layout} {extra:?}"
            );
            if extra.is_some() {
                assert!(from.starts_with("tried on message"), "{from}");
            } else {
                assert_eq!(from, "the message definition in the bag");
            }
            assert_eq!(read.topic, "/behavior_tree_log");
            for (id, truth) in out["bags"][b].as_object().unwrap() {
                let c = counts_of(&read.log, id);
                let what = format!("{storage} {layout} {extra:?} bag {b} {id}");
                assert_eq!(
                    c.successes as u64,
                    truth["successes"].as_u64().unwrap(),
                    "{what}"
                );
                assert_eq!(
                    c.failures as u64,
                    truth["failures"].as_u64().unwrap(),
                    "{what}"
                );
                assert_eq!(c.halted as u64, truth["halted"].as_u64().unwrap(), "{what}");
                let close = |a: f64, b: &serde_json::Value| (a - b.as_f64().unwrap()).abs() < 1e-6;
                assert!(
                    close(c.success_time, &truth["success_time"]),
                    "{what}: {c:?}"
                );
                assert!(
                    close(c.failure_time, &truth["failure_time"]),
                    "{what}: {c:?}"
                );
                let cens: f64 = c.censored.iter().sum();
                assert!(close(cens, &truth["censored_time"]), "{what}: {c:?}");
            }
        }
    }
}

fn covers(e: &Estimate, truth: f64) -> bool {
    e.ci95.0 <= truth && truth <= e.ci95.1
}

/// The fit's 95% intervals cover the simulation's parameters in about 95%
/// of repeated bags (each bag fitted alone), for both layouts; the bags
/// pooled give estimates within 4 standard errors of the truth.
#[test]
fn intervals_cover_the_parameters() {
    let Some(py) = common::python::python("rosbag2 recordings made with rosbags") else {
        return;
    };
    let tree_dir = tempfile::tempdir().unwrap();
    let tree = write(tree_dir.path(), "nav.xml", NAV_XML);
    let bags = 30;
    for (storage, layout, seed) in [("mcap", "uid", "21"), ("sqlite3", "nouid", "22")] {
        let dir = tempfile::tempdir().unwrap();
        let n = bags.to_string();
        let out = make_bags(
            &py,
            dir.path(),
            &[
                "--bags",
                &n,
                "--goals",
                "200",
                "--seed",
                seed,
                "--storage",
                storage,
                "--layout",
                layout,
                "--cancel",
                "0.3",
            ],
        );
        let truth = &out["truth"];
        let (mut checks, mut hits) = (0usize, 0usize);
        let mut logs = Vec::new();
        for b in 0..bags {
            let read = rosbag::read(&dir.path().join(format!("bag_{b}")), &tree, &[], None)
                .unwrap_or_else(|e| panic!("{e}"));
            let f = fit_logs(std::slice::from_ref(&read.log), By::Id).unwrap();
            for leaf in &f.leaves {
                let t = &truth[&leaf.key];
                let Timing::Exponential { mu, nu, .. } = &leaf.timing else {
                    panic!("{}: not exponential", leaf.key)
                };
                for (e, name) in [
                    (Some(&leaf.ps), "ps"),
                    (mu.as_ref(), "mu"),
                    (nu.as_ref(), "nu"),
                ] {
                    if let Some(e) = e {
                        checks += 1;
                        hits += usize::from(covers(e, t[name].as_f64().unwrap()));
                    }
                }
            }
            logs.push(read.log);
        }
        // binomial(checks, 0.95): 4 standard deviations below its mean
        let rate = hits as f64 / checks as f64;
        let sd = (0.95 * 0.05 / checks as f64).sqrt();
        eprintln!("{storage} {layout}: {hits} of {checks} intervals cover the truth ({rate:.3})");
        assert!(checks >= bags * 8, "{checks} checks");
        assert!(
            rate > 0.95 - 4.0 * sd,
            "{storage} {layout}: coverage {rate:.3}"
        );
        // pooled
        let f = fit_logs(&logs, By::Id).unwrap();
        assert_eq!(f.leaves.len(), 3);
        for leaf in &f.leaves {
            let t = &truth[&leaf.key];
            let Timing::Exponential { mu, nu, .. } = &leaf.timing else {
                panic!()
            };
            for (e, name) in [
                (Some(&leaf.ps), "ps"),
                (mu.as_ref(), "mu"),
                (nu.as_ref(), "nu"),
            ] {
                let e = e.unwrap();
                let (v, se, x) = (e.value, e.se.unwrap(), t[name].as_f64().unwrap());
                eprintln!("pooled {} {name}: {v:.4} ± {se:.4}, truth {x}", leaf.key);
                assert!(
                    (v - x).abs() < 4.0 * se,
                    "pooled {} {name}: {v} ± {se}, truth {x}",
                    leaf.key
                );
            }
        }
    }
}

/// The command line: several bags pooled into a params file that `report
/// --ci`, `sensitivity` and `check --ci --require` take.
#[test]
fn fit_command_and_the_chain() {
    let Some(py) = common::python::python("rosbag2 recordings made with rosbags") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    make_bags(
        &py,
        dir.path(),
        &["--bags", "2", "--goals", "100", "--seed", "5"],
    );
    let tree = write(dir.path(), "nav.xml", NAV_XML);
    let params = dir.path().join("nav.params.yaml");
    let bag0 = dir.path().join("bag_0");
    let mcap = dir.path().join("bag_1/bag_1.mcap");
    let o = bin()
        .args(["fit"])
        .arg(&bag0)
        .arg(&mcap)
        .arg("--tree")
        .arg(&tree)
        .arg("-o")
        .arg(&params)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(err.contains("messages of /behavior_tree_log"), "{err}");
    let text = std::fs::read_to_string(&params).unwrap();
    for id in ["ComputePathToPose", "ClearEntireCostmap", "FollowPath"] {
        assert!(text.contains(id), "{text}");
    }
    for args in [vec!["report", "--ci"], vec!["sensitivity"]] {
        let o = bin()
            .args(&args[..1])
            .arg(&tree)
            .args(&args[1..])
            .arg("--params")
            .arg(&params)
            .output()
            .unwrap();
        assert!(
            o.status.success(),
            "{args:?}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
    }
    // The gate on the fitted params: the root's exact P(S) with the truth
    // above is 0.7 + 0.3 * 0.8 * 0.7 = 0.868 for the RecoveryNode, times
    // 0.85 for FollowPath = 0.7378; 200 goals put the 95% interval's lower
    // bound well above 0.5 and its upper bound well below 0.95.
    for (bound, code) in [("ps >= 0.5", 0), ("ps >= 0.95", 1)] {
        let o = bin()
            .arg("check")
            .arg(&tree)
            .arg("--params")
            .arg(&params)
            .args(["--ci", "--require", bound])
            .output()
            .unwrap();
        let out = String::from_utf8_lossy(&o.stdout);
        assert_eq!(o.status.code(), Some(code), "{bound}: {out}");
        assert!(out.contains("lower bound"), "{out}");
    }
    // without --tree: told to give it
    let o = bin().arg("fit").arg(&bag0).output().unwrap();
    assert_eq!(o.status.code(), Some(2));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("--tree"), "{err}");
}

/// Runs `btrel fit BAG --tree TREE` expecting a located input error.
fn fit_error(bag: &Path, tree: &Path) -> String {
    let o = bin()
        .arg("fit")
        .arg(bag)
        .arg("--tree")
        .arg(tree)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr).to_string();
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(!err.contains("panicked"), "{err}");
    err
}

/// Names that the replay cannot tell apart without uid are a located error
/// naming the nodes; with uid they are read.
#[test]
fn ambiguous_names() {
    let Some(py) = common::python::python("rosbag2 recordings made with rosbags") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let tree = write(dir.path(), "twins.xml", TWINS_XML);
    let nouid = dir.path().join("nouid");
    make_bags(
        &py,
        &nouid,
        &["--tree", "twins", "--layout", "nouid", "--goals", "20"],
    );
    let err = fit_error(&nouid.join("bag_0"), &tree);
    assert!(err.contains("message 1"), "{err}");
    assert!(err.contains("`W`"), "{err}");
    assert!(err.contains("fits 2 nodes"), "{err}");
    assert!(
        err.contains("line 4 column 7") && err.contains("line 5 column 7"),
        "{err}"
    );
    let uid = dir.path().join("uid");
    let out = make_bags(
        &py,
        &uid,
        &["--tree", "twins", "--layout", "uid", "--goals", "20"],
    );
    let read = rosbag::read(&uid.join("bag_0"), &tree, &[], None).unwrap();
    let c = counts_of(&read.log, "Wait");
    assert_eq!(
        c.successes as u64,
        out["bags"][0]["Wait"]["successes"].as_u64().unwrap()
    );
}

/// A bag without the topic, a wrong tree, truncated storage files: located
/// errors, never a panic.
#[test]
fn bad_bags() {
    let Some(py) = common::python::python("rosbag2 recordings made with rosbags") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let tree = write(dir.path(), "nav.xml", NAV_XML);
    // no behavior_tree_log
    let none = dir.path().join("none");
    make_bags(&py, &none, &["--no-log-topic", "--goals", "5"]);
    let err = fit_error(&none.join("bag_0"), &tree);
    assert!(
        err.contains("no topic of type nav2_msgs/msg/BehaviorTreeLog"),
        "{err}"
    );
    assert!(err.contains("/chatter (std_msgs/msg/String)"), "{err}");
    let o = bin()
        .arg("fit")
        .arg(none.join("bag_0"))
        .arg("--tree")
        .arg(&tree)
        .args(["--topic", "/nav/behavior_tree_log"])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("no topic `/nav/behavior_tree_log`"), "{err}");
    // a wrong tree: FollowPath missing
    let wrong = write(
        dir.path(),
        "wrong.xml",
        &NAV_XML.replace("      <FollowPath path=\"{path}\"/>\n", ""),
    );
    for layout in ["uid", "nouid"] {
        let d = dir.path().join(layout);
        make_bags(
            &py,
            &d,
            &["--layout", layout, "--goals", "30", "--cancel", "0"],
        );
        let err = fit_error(&d.join("bag_0"), &wrong);
        assert!(err.contains("message "), "{err}");
        assert!(err.contains("change "), "{err}");
        assert!(err.contains("FollowPath"), "{err}");
        assert!(err.contains("wrong.xml"), "{err}");
        if layout == "uid" {
            assert!(err.contains("node uid 5"), "{err}");
        }
    }
    // truncated storage files
    for storage in ["mcap", "sqlite3"] {
        let d = dir.path().join(format!("t_{storage}"));
        make_bags(&py, &d, &["--storage", storage, "--goals", "200"]);
        let ext = if storage == "mcap" { "mcap" } else { "db3" };
        let file = d.join(format!("bag_0/bag_0.{ext}"));
        let bytes = std::fs::read(&file).unwrap();
        for keep in [bytes.len() / 2, 100, 10] {
            std::fs::write(&file, &bytes[..keep]).unwrap();
            let err = fit_error(&d.join("bag_0"), &tree);
            assert!(err.contains("bag_0"), "{err}");
            if storage == "mcap" {
                assert!(
                    err.contains("after message") || err.contains("byte offset"),
                    "{keep}: {err}"
                );
            }
        }
    }
}

/// The public bt_tools recording (Nav2 Humble, no uid, no transitions to
/// IDLE but the root's): the episodes read by hand from its messages
/// (decoded with the rosbags library).
#[test]
fn bt_tools_recording() {
    let data = Path::new(ROOT).join("tests/data/rosbag/bt_tools_2023_03_30");
    let bag = data.join("rosbag2_2023_03_30-17_15_57");
    let tree = data.join("navigate.xml");
    let read = rosbag::read(&bag, &tree, &[], None).unwrap();
    assert_eq!(read.messages, 38);
    assert_eq!(read.log.records, 85);
    let (layout, from) = read.layout.clone().unwrap();
    assert_eq!(layout, rosbag::Layout::WithoutUid);
    assert_eq!(from, "tried on message 1");
    // ComputePathToPose (the action, inside the RecoveryNode of that name):
    // 12 successes, 0.240666114 s in all
    let c = counts_of(&read.log, "ComputePathToPose");
    assert_eq!((c.successes, c.failures, c.halted), (12, 0, 0));
    assert!((c.success_time - 0.240666114).abs() < 1e-9, "{c:?}");
    // FollowPath: failed after 11.379877431 s, retried, failed after 0.328717736 s
    let c = counts_of(&read.log, "FollowPath");
    assert_eq!((c.successes, c.failures, c.halted), (0, 2, 0));
    assert!(
        (c.failure_durations[0] - 11.379877431).abs() < 1e-9,
        "{c:?}"
    );
    assert!((c.failure_durations[1] - 0.328717736).abs() < 1e-9, "{c:?}");
    // the GoalUpdated of FollowPath's fallback: one instant failure; the
    // local costmap clearing: one instant success
    let c = counts_of(&read.log, "GoalUpdated");
    assert_eq!((c.successes, c.failures, c.instants), (0, 1, 1));
    let c = counts_of(&read.log, "ClearEntireCostmap");
    assert_eq!((c.successes, c.failures, c.instants), (1, 0, 1));
    let named = |name: &str| {
        read.log
            .leaves
            .iter()
            .filter(|l| l.name.as_deref() == Some(name))
            .map(|l| l.episodes.len())
            .sum::<usize>()
    };
    assert_eq!(named("ClearLocalCostmap-Context"), 1);
    assert_eq!(named("ClearGlobalCostmap-Context"), 0);
    // the storage file alone reads the same
    let db3 = bag.join("rosbag2_2023_03_30-17_15_57_0.db3");
    let again = rosbag::read(&db3, &tree, &[], None).unwrap();
    assert_eq!(again.log.records, 85);
    // the command line
    let o = bin()
        .arg("fit")
        .arg(&bag)
        .arg("--tree")
        .arg(&tree)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

/// The CDR decoder on hand-made messages: both layouts, big-endian, and a
/// truncated message.
#[test]
fn cdr_decoding() {
    // little-endian, with uid: Time(1, 2), [ Time(3, 4), "ab", uid 7, "IDLE", "RUNNING" ]
    let mut m = vec![0u8, 1, 0, 0];
    m.extend(1u32.to_le_bytes());
    m.extend(2u32.to_le_bytes());
    m.extend(1u32.to_le_bytes()); // one change
    m.extend(3u32.to_le_bytes());
    m.extend(4u32.to_le_bytes());
    m.extend(3u32.to_le_bytes());
    m.extend(b"ab\0");
    // offset from the data start is 27: u16 at 28 after one byte of padding
    m.push(0);
    m.extend(7u16.to_le_bytes());
    m.extend([0, 0]); // align to 4
    m.extend(5u32.to_le_bytes());
    m.extend(b"IDLE\0");
    m.extend([0, 0, 0]); // align to 4
    m.extend(8u32.to_le_bytes());
    m.extend(b"RUNNING\0");
    let c = rosbag::decode(&m, rosbag::Layout::WithUid).unwrap();
    assert_eq!(c.len(), 1);
    assert_eq!(c[0].t_ns, 3_000_000_004);
    assert_eq!(c[0].name, "ab");
    assert_eq!(c[0].uid, Some(7));
    assert!(rosbag::decode(&m, rosbag::Layout::WithoutUid).is_err());
    for cut in [3, 10, 20, m.len() - 1] {
        let e = rosbag::decode(&m[..cut], rosbag::Layout::WithUid).unwrap_err();
        assert!(e.0 <= cut, "{cut}: {e:?}");
    }
    // the definitions rosbag2 stores
    let with = "builtin_interfaces/Time timestamp\nBehaviorTreeStatusChange[] event_log\n\
        ================================================================================\n\
        MSG: nav2_msgs/BehaviorTreeStatusChange\nbuiltin_interfaces/Time timestamp\n\
        string node_name\nuint16 uid # the node's uid\nstring previous_status\nstring current_status\n";
    assert_eq!(
        rosbag::layout_from_definition(with),
        Some(rosbag::Layout::WithUid)
    );
    assert_eq!(
        rosbag::layout_from_definition(&with.replace("uint16 uid # the node's uid\n", "")),
        Some(rosbag::Layout::WithoutUid)
    );
    assert_eq!(rosbag::layout_from_definition(""), None);
}
