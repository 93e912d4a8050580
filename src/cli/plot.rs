//! `btrel plot`: π(t) as SVG or PNG, with orderings or a simulation overlaid.

use std::path::Path;

use btrel::curve::{CurveOptions, Timing};
use btrel::report::number::full;
use btrel::tree::Tree;

use super::advice::{self, compare_failure, model_failure, Cmd};
use super::args::{ImageFormatArg, PlotArgs, PlotTiming};
use super::input::{find_nodes, warn_endless, InputOptions};
use super::options::{method, optional_count, optional_time, sim_options};
use super::output::emit;
use super::progress::{run_simulation, Spinner};
use super::Failure;

use ImageFormatArg as ImageFormat;

fn image_format(path: &Path, given: Option<ImageFormat>) -> Result<ImageFormat, Failure> {
    if let Some(f) = given {
        return Ok(f);
    }
    // standard output: SVG unless --format says otherwise
    if path == Path::new("-") {
        return Ok(ImageFormat::Svg);
    }
    match path
        .extension()
        .and_then(|e| e.to_str())
        .map(|e| e.to_ascii_lowercase())
        .as_deref()
    {
        Some("svg") => Ok(ImageFormat::Svg),
        Some("png") => Ok(ImageFormat::Png),
        other => Err(Failure::input(format!(
            "-o {}: {}; btrel writes SVG and PNG images: name the file *.svg or *.png, \
             or give --format svg|png",
            path.display(),
            match other {
                Some(e) => format!("unknown image format '.{e}'"),
                None => "the file name has no extension".to_string(),
            }
        ))),
    }
}

/// Timing of the actions of a node's subtree: all exponential, all fixed,
/// or a mixture.
fn subtree_timing(tree: &Tree, node: usize) -> (&'static str, bool) {
    use btrel::tree::{Duration, NodeKind};
    let (mut random, mut fixed) = (false, false);
    let mut stack = vec![node];
    while let Some(id) = stack.pop() {
        let n = tree.node(id);
        if let NodeKind::Action(a) = &n.kind {
            for (d, p) in [(a.success, a.ps), (a.failure, a.pf)] {
                match d {
                    Some(Duration::Fixed { .. }) if p > 0.0 => fixed = true,
                    Some(_) if p > 0.0 => random = true,
                    _ => {}
                }
            }
        }
        stack.extend_from_slice(n.kind.children());
    }
    match (random, fixed) {
        (true, false) => ("stochastic", false),
        (false, _) => ("deterministic (as given)", true),
        (true, true) => ("as given", false),
    }
}

pub(super) fn run(args: PlotArgs, input: &InputOptions) -> Result<(), Failure> {
    use btrel::plot::{
        curve_series, default_horizon, mc_series, render_png, render_svg, Marker, PlotSpec, Series,
        Style, VerticalMarker,
    };
    if args.points < 2 || args.points > 100_000 {
        return Err(Failure::input("--points must be between 2 and 100000"));
    }
    if args.top == 0 {
        return Err(Failure::input("--top must be at least 1"));
    }
    if args.compare.is_some() && !matches!(args.timing, PlotTiming::AsGiven) {
        return Err(Failure::input(
            "--timing deterministic/both cannot be combined with --compare (the orderings are drawn with the times as given): drop one of them",
        ));
    }
    let t_end = optional_time("--t-end", &args.t_end)?;
    let deadline = optional_time("--deadline", &args.deadline)?;
    let mc = optional_count("--mc", &args.mc)?;
    let format = image_format(&args.output, args.format)?;
    let tree = input.load(&args.tree)?;
    warn_endless(&tree);
    let nodes = if args.nodes.is_empty() {
        vec![Tree::ROOT]
    } else {
        find_nodes(&tree, &args.nodes, &args.tree)?
    };
    let base = CurveOptions {
        method: method(args.method),
        max_states: args.max_states,
        ..CurveOptions::default()
    };
    // the trees, and the curves to draw: (label, tree index, node, style,
    // timing); one model per tree serves all its curves and the horizon
    let mut trees: Vec<Tree> = Vec::new();
    let mut drawn: Vec<(String, usize, usize, Style, Timing)> = Vec::new();
    if let Some(name) = &args.compare {
        let node = find_nodes(&tree, std::slice::from_ref(name), &args.tree)?[0];
        let mut cmp = btrel::compare::compare(
            &tree,
            &btrel::compare::CompareOptions {
                nodes: vec![node],
                deadline,
                method: base.method,
                max_states: args.max_states,
                keep: args.top,
                ..btrel::compare::CompareOptions::default()
            },
        )
        .map_err(compare_failure(Cmd::Plot, base.method))?;
        advice::restate_budget(&mut cmp);
        for n in &cmp.notes {
            eprintln!("note: {n}");
        }
        // the top K orderings, and the given one (as in Fig. 9.22)
        let shown: Vec<_> = cmp
            .candidates
            .iter()
            .enumerate()
            .filter(|(i, c)| *i < args.top || c.given)
            .map(|(_, c)| c)
            .collect();
        for (i, c) in shown.into_iter().enumerate() {
            let t = cmp.reordered(&tree, c);
            let mut label = btrel::report::ranking::label(&tree, &cmp, c);
            if c.given {
                label.push_str(" (given)");
            }
            trees.push(t);
            drawn.push((
                label,
                trees.len() - 1,
                Tree::ROOT,
                Style::overlay(i),
                Timing::AsGiven,
            ));
        }
    } else {
        trees.push(tree.clone());
        for (i, &id) in nodes.iter().enumerate() {
            let name = if nodes.len() > 1 {
                tree.node(id).name.clone()
            } else {
                String::new()
            };
            let (as_given, all_fixed) = subtree_timing(&tree, id);
            let timings: Vec<(Timing, &str)> = match args.timing {
                PlotTiming::AsGiven => vec![(Timing::AsGiven, "")],
                PlotTiming::Deterministic => vec![(Timing::Deterministic, "deterministic")],
                PlotTiming::Both if all_fixed => {
                    eprintln!(
                        "note: every action of '{}' has fixed times already: --timing both \
                         draws one set of curves",
                        tree.node(id).name
                    );
                    vec![(Timing::AsGiven, as_given)]
                }
                PlotTiming::Both => vec![
                    (Timing::AsGiven, as_given),
                    (Timing::Deterministic, "deterministic (τ = 1/rate)"),
                ],
            };
            let k = timings.len();
            for (j, (timing, what)) in timings.into_iter().enumerate() {
                let label = [name.as_str(), what]
                    .iter()
                    .filter(|x| !x.is_empty())
                    .copied()
                    .collect::<Vec<_>>()
                    .join(", ");
                drawn.push((label, 0, id, Style::overlay(i * k + j), timing));
            }
        }
    }
    let model_options = btrel::Options {
        method: base.method,
        max_states: base.max_states,
    };
    let models: Vec<Result<btrel::Model, btrel::Error>> = trees
        .iter()
        .map(|t| btrel::Model::with_options(t, model_options))
        .collect();
    let end = match t_end {
        Some(t) if t > 0.0 => t,
        Some(_) => return Err(Failure::input("--t-end must be > 0")),
        None => {
            let items: Vec<_> = drawn
                .iter()
                .map(|&(_, k, id, _, tm)| (models[k].as_ref().map_err(|_| &trees[k]), id, tm))
                .collect();
            let h = default_horizon(&items);
            match deadline {
                Some(d) if d * 1.1 > h => btrel::plot::nice_ceil(d * 1.1),
                _ => h,
            }
        }
    };
    let times: Vec<f64> = (0..args.points)
        .map(|k| end * k as f64 / (args.points - 1) as f64)
        .collect();
    let mut series: Vec<Series> = Vec::new();
    let mut exact_drawn = false;
    for (label, k, id, style, timing) in &drawn {
        let t = &trees[*k];
        let spinner = Spinner::start(format!("computing π(t) of '{}'", t.node(*id).name));
        let computed = match &models[*k] {
            Ok(m) => m.curve_with(*id, &times, *timing),
            Err(e) => Err(e.clone()),
        };
        drop(spinner);
        match computed {
            Ok(points) => {
                exact_drawn = true;
                series.extend(curve_series(label, &points, *style))
            }
            Err(e) if mc.is_some() => eprintln!(
                "note: no exact curves for '{}' ({e}); plotting the simulation only",
                t.node(*id).name
            ),
            Err(e) => {
                let mut f = model_failure(Cmd::Plot, base.method)(e);
                f.message = format!(
                    "cannot plot the exact curves of '{}': {}",
                    t.node(*id).name,
                    f.message
                );
                return Err(f);
            }
        }
    }
    if let Some(runs) = mc {
        let mc_times: Vec<f64> = (0..41).map(|k| end * k as f64 / 40.0).collect();
        let o = sim_options(&args.sim.sim(), runs, mc_times, false)?;
        let mut i = 0;
        for (label, k, id, _, timing) in &drawn {
            let t = &trees[*k];
            if *timing == Timing::Deterministic {
                continue;
            }
            let r = run_simulation(t, *id, &o)?;
            let prefix = if label.is_empty() {
                format!(
                    "Monte Carlo, {} runs",
                    btrel::compare::count_text(runs as f64)
                )
            } else {
                format!("{label}, Monte Carlo")
            };
            series.extend(mc_series(&prefix, &r.curve, Marker::overlay(i)));
            i += 1;
        }
    }
    let tree_title = btrel::report::title(&tree);
    let title = match (&args.compare, deadline) {
        (Some(n), Some(d)) => format!(
            "{tree_title}: orderings of '{n}', best by P(success by {} s) first",
            full(d)
        ),
        (Some(n), None) => format!("{tree_title}: orderings of '{n}', best by mean time first"),
        _ => {
            let names: Vec<&str> = nodes.iter().map(|&n| tree.node(n).name.as_str()).collect();
            if exact_drawn {
                format!("{} — {} method", names.join(", "), base.method.name())
            } else {
                format!("{} — Monte Carlo only", names.join(", "))
            }
        }
    };
    let mut spec = PlotSpec::new(title, series);
    if let Some(d) = deadline {
        spec.markers.push(VerticalMarker {
            t: d,
            label: format!("deadline {} s", full(d)),
        });
    }
    let bytes = match format {
        ImageFormat::Svg => render_svg(&spec).map_err(Failure::analysis)?.into_bytes(),
        ImageFormat::Png => render_png(&spec).map_err(Failure::analysis)?,
    };
    emit(Some(&args.output), |out| out.write_all(&bytes))
}
