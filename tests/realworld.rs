//! The published BehaviorTree.CPP trees of ../shared/realworld (see its
//! INDEX.md): every tree is read as published, with its params file, the
//! files it needs for its SubTrees, and its project's node model. A tree
//! may be refused only because it uses node types btrel has no stochastic
//! meaning for yet (`btrel::tree::xml::is_unsupported`), never for
//! front-end reasons (syntax, leaves without a model, metadata attributes,
//! explicit forms, SubTrees in other files, missing parameters). Every tree
//! that is read must also be analysed.

mod common;

use std::path::{Path, PathBuf};

use btrel::compile::{analyze, Options};
use btrel::tree::xml::{is_unsupported, parse_xml_files};

/// Trees that BehaviorTree.CPP itself cannot load, with the reason
/// (INDEX.md's notes): btrel must refuse them with this text.
const INVALID_AS_PUBLISHED: &[(&str, &str)] = &[(
    // `<inverter>` (lower case) is registered by no factory
    "nav2/application_example.xml",
    "unknown node <inverter> with children (did you mean <Inverter>?)",
)];

/// The trees with a PipelineSequence that are read but not analysed:
/// Nav2's routing tree (its two RateControllers' re-planning race: a chain
/// of 151,270 states at rate 100/s to the 4,478 s by which its law has
/// returned, about 3e11 operations a pass, refused on that estimate) and
/// Jazzy's goal-patience tree (two RoundRobin indexes to follow).
const PIPELINES_NOT_ANALYSED: &[&str] = &[
    "nav2/navigate_w_routing_global_planning_and_control_w_recovery.xml",
    "nav2/navigate_to_pose_w_replanning_goal_patience_and_recovery.xml",
];

/// Reads corpus tree `row` as the corpus test does: its params file as
/// published (it carries the predicate probabilities, branch choices and
/// blackboard values btrel reads: INDEX.md, "its params file adds it under
/// a comment"), the files of its SubTrees and its project's node model.
fn read(root: &Path, row: &Row) -> Result<btrel::tree::Tree, btrel::tree::TreeError> {
    let xml = root.join(&row.file);
    let dir = xml.parent().unwrap().to_path_buf();
    let params = xml.with_extension("params.yaml");
    let mut includes: Vec<PathBuf> = row.needs.iter().map(|n| dir.join(n)).collect();
    // the project's node model, shipped as a separate file
    let folder = row.file.split('/').next().unwrap();
    match folder {
        "nav2" | "nav2_humble" => includes.push(dir.join("nav2_tree_nodes.xml")),
        "roscon24" if row.file.contains("pyrobosim_btcpp") => includes
            .push(dir.join("BehaviorTree.CPP__pyrobosim_btcpp__trees__pyrobosim_btcpp_model.xml")),
        _ => {}
    }
    parse_xml_files(&xml, &params, &includes)
}

struct Row {
    file: String,
    kind: String,
    needs: Vec<String>,
    /// INDEX.md's *node types* name PipelineSequence
    pipeline: bool,
}

fn rows(index: &str) -> Vec<Row> {
    index
        .lines()
        .filter(|l| l.starts_with("| `"))
        .map(|l| l.split('|').map(str::trim).collect::<Vec<&str>>())
        // the file table has 9 columns (11 cells with the outer empty ones)
        .filter(|cells| cells.len() == 11)
        .map(|cells| {
            // | file | kind | repo | commit | path | licence | needs | node types | notes |
            let needs = cells[7]
                .split(", ")
                .map(str::trim)
                .filter(|n| n.ends_with(".xml") && !n.starts_with('('))
                .map(str::to_string)
                .collect();
            Row {
                file: cells[1].trim_matches('`').to_string(),
                kind: cells[2].to_string(),
                needs,
                pipeline: cells[8].split(", ").any(|t| t.trim() == "PipelineSequence"),
            }
        })
        .collect()
}

#[test]
fn published_trees_are_read_or_refused_for_node_semantics_only() {
    // BTREL_REALWORLD overrides the place (e.g. for a checkout elsewhere)
    let root = std::env::var_os("BTREL_REALWORLD")
        .map(PathBuf::from)
        .unwrap_or_else(|| Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/realworld"));
    let Ok(index) = std::fs::read_to_string(root.join("INDEX.md")) else {
        println!(
            "note: {} is absent; skipping the corpus test",
            root.display()
        );
        return;
    };
    let trees: Vec<Row> = rows(&index)
        .into_iter()
        .filter(|r| r.kind == "tree")
        .collect();
    assert!(trees.len() >= 100, "INDEX.md lists {} trees", trees.len());
    let (mut parsed, mut semantic, mut invalid) = (Vec::new(), Vec::new(), Vec::new());
    let mut front_end = Vec::new();
    let mut limited = Vec::new();
    let mut nevers: Vec<(String, f64)> = Vec::new();
    let mut curves = 0;
    // analysed trees with a PipelineSequence (the re-planning ones by the
    // renewal method)
    let mut pipelines = 0;
    // of those, the trees where every PipelineSequence has its curve
    let mut pipeline_curves = 0;
    let mut no_pipeline_curve = Vec::new();
    // read trees with a PipelineSequence (analysed or not)
    let mut pipeline_read: Vec<String> = Vec::new();
    // analysed trees whose root has no curve, with the reason
    let mut no_root_curve: Vec<(String, String)> = Vec::new();
    // read, but a Nav2 node has no exact analysis yet: simulated instead
    let mut nav2 = Vec::new();
    let mut unsimulated = Vec::new();
    for row in &trees {
        match read(&root, row) {
            Ok(tree) => {
                // the tree as read has a PipelineSequence iff INDEX.md's
                // node types (of the tree and its needs) name one
                let has_pipe = tree
                    .nodes()
                    .iter()
                    .any(|n| matches!(n.kind, btrel::tree::NodeKind::Pipeline { .. }));
                assert_eq!(
                    has_pipe, row.pipeline,
                    "{}: INDEX.md and the tree as read disagree on PipelineSequence",
                    row.file
                );
                if has_pipe {
                    pipeline_read.push(row.file.clone());
                }
                match analyze(&tree, &Options::default()) {
                    Ok(a) => {
                        // BT.CPP's behaviour with the published params: the
                        // part of the runs that never returns
                        if a.nodes[0].never() > 1e-9 {
                            nevers.push((row.file.clone(), a.nodes[0].never()));
                        }
                        let pipes: Vec<usize> = (0..tree.nodes().len())
                            .filter(|&id| {
                                matches!(
                                    tree.nodes()[id].kind,
                                    btrel::tree::NodeKind::Pipeline { .. }
                                )
                            })
                            .collect();
                        if !pipes.is_empty() {
                            pipelines += 1;
                            // every PipelineSequence's own curve (the re-planning
                            // ones by the renewal levels, `compile::renewal_curve`)
                            let mut refused = Vec::new();
                            for &id in &pipes {
                                if let Err(e) =
                                    btrel::curve::curve(&tree, id, &[100.0], &Default::default())
                                {
                                    refused.push(format!("'{}': {e}", tree.nodes()[id].name));
                                }
                            }
                            if refused.is_empty() {
                                pipeline_curves += 1;
                            } else {
                                no_pipeline_curve.push((row.file.clone(), refused.join("; ")));
                            }
                        }
                        // the simulator referees every analysed tree: the root's
                        // P(Success), MTTS and MTTF and, where the root has a
                        // curve, its points at 10 s and 100 s, |z| < 5 over
                        // 4,000 runs (fixed seed)
                        let times = [10.0, 100.0];
                        let sim = common::simulate_root(&tree, 4000, &times);
                        let pts = btrel::curve::curve(&tree, 0, &times, &Default::default());
                        match &pts {
                            Ok(_) => curves += 1,
                            Err(e) => no_root_curve.push((row.file.clone(), e.to_string())),
                        }
                        let pts = pts.unwrap_or_default();
                        common::assert_root_and_curve_within_z(&row.file, a.nodes[0], &pts, &sim);
                        parsed.push((row.file.clone(), tree.nodes().len()));
                    }
                    // a documented limit of the engine, not of the front end
                    Err(
                        e @ (btrel::AnalysisError::Unbounded { .. }
                        | btrel::AnalysisError::NeverReturns { .. }
                        | btrel::AnalysisError::StateBudget { .. }
                        | btrel::AnalysisError::Stiff { .. }),
                    ) => limited.push((row.file.clone(), e.to_string())),
                    Err(e @ btrel::AnalysisError::Nav2 { .. }) => {
                        let opts = btrel::sim::SimOptions {
                            runs: 2000,
                            per_node: false,
                            ..Default::default()
                        };
                        if let Err(s) = btrel::sim::simulate(&tree, &opts, None) {
                            unsimulated.push(format!("{}: {s}", row.file));
                        }
                        nav2.push((row.file.clone(), e.to_string()))
                    }
                    Err(e) => panic!(
                        "{}: read ({} nodes) but not analysed: {e}",
                        row.file,
                        tree.nodes().len()
                    ),
                }
            }
            Err(e) if is_unsupported(&e) => semantic.push((row.file.clone(), e.to_string())),
            Err(e) => match INVALID_AS_PUBLISHED.iter().find(|(f, _)| *f == row.file) {
                Some((_, why)) if e.message.contains(why) => invalid.push(row.file.clone()),
                _ => front_end.push(format!("{}:\n{e}", row.file)),
            },
        }
    }
    println!(
        "{} trees: {} read and analysed ({} with the root's curve too, {} with a \
         PipelineSequence), {} read but refused by the analysis (the state budget), {} read and \
         simulated but without an exact analysis of a Nav2 node, {} refused for node semantics \
         only, {} invalid as published",
        trees.len(),
        parsed.len(),
        curves,
        pipelines,
        limited.len(),
        nav2.len(),
        semantic.len(),
        invalid.len()
    );
    println!(
        "{pipeline_curves} of the {pipelines} trees with a PipelineSequence have the curve of \
         every PipelineSequence (the re-planning race by the renewal levels)"
    );
    for (f, e) in &no_root_curve {
        println!("  no root curve: {f}: {e}");
    }
    for (f, e) in &no_pipeline_curve {
        println!("  no pipeline curve: {f}: {e}");
    }
    // the corpus' own count of trees with a PipelineSequence (INDEX.md's
    // node types; 24: 12 Nav2 Jazzy, 12 Humble): every one is read (and as
    // read has one, checked above), and every one but those of
    // PIPELINES_NOT_ANALYSED is analysed
    let indexed: Vec<&str> = trees
        .iter()
        .filter(|r| r.pipeline)
        .map(|r| r.file.as_str())
        .collect();
    assert_eq!(
        pipeline_read.len(),
        indexed.len(),
        "INDEX.md lists {} trees with a PipelineSequence, {} read: {pipeline_read:?}",
        indexed.len(),
        pipeline_read.len()
    );
    let analysed_pipelines = indexed
        .iter()
        .filter(|f| parsed.iter().any(|(p, _)| p == *f))
        .count();
    assert_eq!(analysed_pipelines, pipelines);
    for f in &indexed {
        assert!(
            parsed.iter().any(|(p, _)| p == f) || PIPELINES_NOT_ANALYSED.contains(f),
            "{f}: a tree with a PipelineSequence not analysed"
        );
    }
    // the re-planning pipelines have their curve: the renewal levels, or
    // the race's law composed with the earlier children's (the 2
    // SpeedController pipelines: a first wait of their own, off the
    // period's grid after the earlier children; 20 of 22 before)
    assert!(
        pipelines >= indexed.len() - PIPELINES_NOT_ANALYSED.len() && pipeline_curves == pipelines,
        "{pipeline_curves} of {pipelines} analysed trees with a PipelineSequence have its curve \
         ({} in INDEX.md)",
        indexed.len()
    );
    for (f, e) in &limited {
        println!("  analysis limit: {f}: {e}");
    }
    for (f, e) in &nav2 {
        println!("  Nav2 analysis limit: {f}: {e}");
    }
    for (f, n) in &parsed {
        println!("  read: {f} ({n} nodes)");
    }
    for (f, p) in &nevers {
        println!("  never returns: {f}: P(never returns) = {p:.6}");
    }
    for (f, e) in &semantic {
        println!("  node semantics: {f}: {}", e.lines().nth(1).unwrap_or(""));
    }
    assert!(
        front_end.is_empty(),
        "{} trees refused for front-end reasons:\n{}",
        front_end.len(),
        front_end.join("\n\n")
    );
    assert_eq!(invalid.len(), INVALID_AS_PUBLISHED.len());
    // every tree read is simulated, Jazzy's goal-patience tree too (its
    // PipelineSequence halts the SequenceWithMemory `CancelingControlAndWait`,
    // which keeps the running child's index in BT.CPP v4)
    assert!(
        unsimulated.is_empty(),
        "read but not simulated:\n{}",
        unsimulated
            .iter()
            .map(|u| u.as_str())
            .collect::<Vec<_>>()
            .join("\n")
    );
    // no tree is refused for the length of its re-run series: the lowering
    // refuses none (the re-planning race is the renewal method's where the
    // rest is Markovian, else the re-run loop's law against the rest's)
    for (f, e) in &nav2 {
        assert!(
            !e.contains("re-runs"),
            "{f} refused for its re-run series:\n{e}"
        );
    }
    assert!(
        !semantic
            .iter()
            .any(|(_, e)| e.contains("<SequenceWithMemory>") || e.contains("<SequenceStar>")),
        "a tree is refused for its SequenceWithMemory"
    );
    // Nav2's own node types, ManualSelector, the queue loops and MoveIt
    // Pro's loops are read now: no refusal names them
    for (f, e) in &semantic {
        for ty in [
            "PipelineSequence",
            "RateController",
            "RoundRobin",
            "GoalUpdater>",
            "GoalUpdatedController",
            "DistanceController",
            "SpeedController",
            "PathLongerOnApproach",
            "ManualSelector",
            "ConsumeQueue",
            "ForEach",
            "RepeatUnlessFailureEachTick",
        ] {
            assert!(!e.contains(&format!("<{ty}")), "{f} refused for {ty}:\n{e}");
        }
    }
    assert_eq!(
        parsed.len() + limited.len() + nav2.len() + semantic.len() + invalid.len(),
        trees.len()
    );
    // 100 analysed, all with the root's curve (99 before the composed laws
    // took a loop without a bound, MoveIt Pro's hangar_sim looping tree; 97
    // before the SpeedController
    // pipelines' race law composed with their earlier children, 99 and 96
    // before the
    // re-planning race against a rest with a fixed Wait took the process's
    // law from its levels: Humble's goal-patience tree; 96 before a race's
    // law composed
    // (MoveIt Pro's space satellite tree), 85 before the re-planning
    // race's law composed with the RecoveryNodes around it and the composed
    // laws held the recoveries' fixed Wait; 98 and 94 before MoveIt Pro's MPC
    // tree — a Timeout over a Parallel with a KeepRunningUntilFailure over a
    // Delay — became a renewal race cut at its deadline) and 1 over the
    // work budget (Nav2's routing tree: its two RateControllers'
    // re-planning race; over the chain budget before its law's horizon
    // came from the tail bound) when this was written; 92 before the ReactiveSequence
    // restart loop and laws that never return (5 Nav2 trees, 4 of them with
    // P(never returns) 1, 1, 1 and 0.298766), 86 before the RoundRobin's
    // index became a flow and the renewal method took a first cycle. Read but
    // not analysed: Jazzy's goal-patience tree (two indexes to follow). MoveIt Pro's
    // sample_april_tag SubTree is analysed with the `{num_samples}` its caller
    // passes (in its params file)
    assert!(parsed.len() >= 100, "{} analysed", parsed.len());
    assert!(curves >= 100, "{curves} root curves");
    for f in [
        "moveitpro/lab_sim__mpc_pose_tracking.xml",
        "nav2_humble/navigate_to_pose_w_replanning_goal_patience_and_recovery.xml",
    ] {
        assert!(parsed.iter().any(|(p, _)| p == f), "{f} analysed");
    }
    assert!(parsed.len() + nav2.len() + limited.len() >= 101);
    // the route-graph tree's restart loops end (their restarted actions can
    // fail): analysed, returning with probability 1
    let route = "nav2/navigate_on_route_graph_w_recovery.xml";
    assert!(parsed.iter().any(|(f, _)| f == route), "{route} analysed");
    assert!(!nevers.iter().any(|(f, _)| f == route), "{route} returns");
    // the trees whose restart loop cannot end: BT.CPP ticks them for ever
    for (file, p) in [
        (
            "nav2/nav_to_pose_with_consistent_replanning_and_if_path_becomes_invalid.xml",
            1.0,
        ),
        (
            "nav2/navigate_through_poses_w_replanning_and_recovery.xml",
            1.0,
        ),
        (
            "nav2_humble/navigate_through_poses_w_replanning_and_recovery.xml",
            1.0,
        ),
    ] {
        let found = nevers.iter().find(|(f, _)| f == file);
        assert!(
            found.is_some_and(|(_, q)| (q - p).abs() < 1e-12),
            "{file}: P(never returns) {found:?}, expected {p}"
        );
    }
    // no tree is refused for its RoundRobin any more
    for (f, e) in &nav2 {
        assert!(
            !e.contains("round_robin"),
            "{f} refused for its RoundRobin:\n{e}"
        );
    }
    assert!(semantic.len() <= 1, "{} refused", semantic.len());
}

/// The leaf `d` as `fit --timing auto` would write it for real durations
/// of the same mean: a Success time `1/mu` as a shifted exponential (half
/// the mean fixed, then Exp(2·mu)), a Failure time `1/nu` as an Erlang-2
/// (rate 2·nu); other times as they are.
fn fitted(d: Option<btrel::tree::Duration>, success: bool) -> Option<btrel::tree::Duration> {
    use btrel::tree::{stages::Stages, Duration};
    match d {
        Some(Duration::Exponential { rate }) if success => Some(Duration::phase_type(
            0.5 / rate,
            Stages::erlang(1, 2.0 * rate).expect("a rate > 0"),
        )),
        Some(Duration::Exponential { rate }) => Some(Duration::phase_type(
            0.0,
            Stages::erlang(2, 2.0 * rate).expect("a rate > 0"),
        )),
        other => other,
    }
}

/// Issue 29, deliverable 8: every corpus tree that is analysed as
/// published, again with fitted timings (each `mu` a shifted exponential
/// of the same mean, each `nu` an Erlang-2 of the same mean): `report` and
/// the root's `curve` answer, and the root agrees with 4,000 simulated runs
/// (|z| < 5). Lists the trees refused with the reason.
#[test]
fn published_trees_with_fitted_timings() {
    let Some(root) = common::corpus() else {
        println!("note: the corpus is absent; skipping");
        return;
    };
    let index = std::fs::read_to_string(root.join("INDEX.md")).unwrap();
    let (mut answered, mut refused) = (Vec::new(), Vec::new());
    // `BTREL_CORPUS_ONLY=part` runs the trees whose file name holds `part`
    let only = std::env::var("BTREL_CORPUS_ONLY").ok();
    let chosen = |f: &str| only.as_deref().is_none_or(|p| f.contains(p));
    for row in rows(&index)
        .iter()
        .filter(|r| r.kind == "tree" && chosen(&r.file))
    {
        println!("fitted timings: {} starts", row.file);
        let Ok(published) = read(&root, row) else {
            continue;
        };
        if analyze(&published, &Options::default()).is_err() {
            continue;
        }
        let tree = published
            .with_action_times(|_, a| (fitted(a.success, true), fitted(a.failure, false)))
            .expect("fitted times are valid");
        let start = std::time::Instant::now();
        let times = [10.0, 100.0];
        let result = analyze(&tree, &Options::default()).and_then(|a| {
            btrel::curve::curve(&tree, 0, &times, &Default::default()).map(|c| (a.nodes[0], c))
        });
        let took = start.elapsed();
        match result {
            Ok((f, pts)) => {
                let sim = common::simulate_root(&tree, 4000, &times);
                common::assert_root_and_curve_within_z(&row.file, f, &pts, &sim);
                answered.push((row.file.clone(), took));
            }
            Err(e) => refused.push((row.file.clone(), took, e.to_string())),
        }
    }
    println!(
        "{} trees analysed as published: {} answered with fitted timings, {} refused",
        answered.len() + refused.len(),
        answered.len(),
        refused.len()
    );
    for (f, t) in &answered {
        println!("  answered: {f} in {t:.2?}");
    }
    for (f, t, e) in &refused {
        println!("  refused: {f} after {t:.2?}: {e}");
    }
    // every tree is answered (Nav2's route-graph tree, whose pipeline child
    // `ComputeRoute` re-runs back to back with mixed timing — a series of
    // about 612 re-runs — was refused by the lowering until 2026-12-07:
    // its race is now the re-run loop's composed law against the rest)
    assert!(
        refused.is_empty(),
        "refused with fitted timings:\n{}",
        refused
            .iter()
            .map(|(f, _, e)| format!("{f}: {e}"))
            .collect::<Vec<_>>()
            .join("\n")
    );
    if only.is_none() {
        assert!(answered.len() >= 100, "{} answered", answered.len());
    }
}
