//! `btrel simulate`: Monte Carlo figures, for a number of runs or to a
//! precision.

use std::io;

use btrel::tree::Tree;

use super::args::{FormatArg, SimulateArgs};
use super::input::{find_nodes, warn_endless, InputOptions};
use super::options::{grid_times, parse_count, parse_level, parse_positive, sim_options};
use super::output::emit;
use super::progress::run_simulation;
use super::Failure;

pub(super) fn run(args: SimulateArgs, input: &InputOptions) -> Result<(), Failure> {
    use btrel::report::simulation;
    if args.precision.is_some() || args.time_precision.is_some() {
        return simulate_precision(args, input);
    }
    for (given, name) in [
        (args.confidence.is_some(), "--confidence"),
        (args.max_runs.is_some(), "--max-runs"),
    ] {
        if given {
            return Err(Failure::input(format!(
                "{name} goes with --precision EPS or --time-precision S (runs until the figures \
                 are that precise): add one, or remove {name}"
            )));
        }
    }
    let runs = parse_count("--runs", &args.runs)?;
    let times = grid_times(&args.grid)?.unwrap_or_default();
    if matches!(args.format, FormatArg::Csv) && !times.is_empty() {
        return Err(Failure::input(
            "--format csv prints the per-node figures; for a simulated curve as CSV use `btrel curve --mc N`",
        ));
    }
    let options = sim_options(&args.sim, runs, times, true)?;
    let tree = input.load(&args.tree)?;
    warn_endless(&tree);
    let node = match &args.node {
        Some(n) => find_nodes(&tree, std::slice::from_ref(n), &args.tree)?[0],
        None => Tree::ROOT,
    };
    let result = run_simulation(&tree, node, &options)?;
    emit(args.output.as_deref(), |out| match args.format {
        FormatArg::Table => simulation::write_table(&tree, &result, out),
        FormatArg::Json => simulation::write_json(&tree, &result, out),
        FormatArg::Csv => simulation::write_csv(&tree, &result, out),
    })
}

/// `simulate --precision / --time-precision`: runs until the figures are
/// that precise ([`btrel::sim::sequential`]).
fn simulate_precision(args: SimulateArgs, input: &InputOptions) -> Result<(), Failure> {
    use btrel::report::sequential as out_seq;
    use btrel::sim::sequential::{simulate_to_precision, Precision, Progress, DEFAULT_MAX_RUNS};
    use std::io::IsTerminal;
    let probability = args
        .precision
        .as_deref()
        .map(|s| parse_positive("--precision", s))
        .transpose()?;
    if let Some(p) = probability.filter(|&p| p >= 0.5) {
        return Err(Failure::input(format!(
            "--precision {p}: a probability's half-width must be below 0.5 (e.g. 0.01)"
        )));
    }
    let time = args
        .time_precision
        .as_deref()
        .map(|s| parse_positive("--time-precision", s))
        .transpose()?;
    let confidence = match args.confidence.as_deref() {
        None => 0.95,
        Some(c) => parse_level("--confidence", c)?,
    };
    let max_runs = match args.max_runs.as_deref() {
        None => DEFAULT_MAX_RUNS,
        Some(n) => parse_count("--max-runs", n)?,
    };
    if max_runs == 0 || max_runs > btrel::sim::MAX_RUNS {
        return Err(Failure::input(format!(
            "--max-runs must be between 1 and {} (10^12)",
            btrel::sim::MAX_RUNS
        )));
    }
    let times = grid_times(&args.grid)?.unwrap_or_default();
    if matches!(args.format, FormatArg::Csv) && !times.is_empty() {
        return Err(Failure::input(
            "--format csv prints the per-node figures; for the curve with intervals use --format table or json",
        ));
    }
    let base = sim_options(&args.sim, 1, times, true)?;
    let tree = input.load(&args.tree)?;
    warn_endless(&tree);
    let node = match &args.node {
        Some(n) => find_nodes(&tree, std::slice::from_ref(n), &args.tree)?[0],
        None => Tree::ROOT,
    };
    let precision = Precision {
        probability,
        time,
        confidence,
        max_runs,
    };
    let bar = io::stderr().is_terminal().then(|| {
        let b = indicatif::ProgressBar::new(1);
        b.set_style(
            indicatif::ProgressStyle::with_template(
                "simulating to a precision {bar:40} {pos}/{len} runs (estimated; {elapsed})",
            )
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
        );
        b
    });
    let callback = |p: &Progress| {
        if let Some(b) = &bar {
            b.set_length(p.needed.max(p.runs));
            b.set_position(p.runs);
        }
    };
    let result = simulate_to_precision(
        &tree,
        node,
        &base,
        &precision,
        bar.as_ref()
            .map(|_| &callback as &(dyn Fn(&Progress) + Sync)),
    );
    if let Some(b) = bar {
        b.finish_and_clear();
    }
    let result = result.map_err(Failure::input)?;
    let missed = out_seq::missed_phrases(&tree, &result);
    if !missed.is_empty() {
        eprintln!(
            "warning: stopped at --max-runs {} before every figure reached its precision: {}",
            result.sim.runs,
            missed.join(", ")
        );
    }
    emit(args.output.as_deref(), |out| match args.format {
        FormatArg::Table => out_seq::write_table(&tree, &result, out),
        FormatArg::Json => out_seq::write_json(&tree, &result, out),
        FormatArg::Csv => out_seq::write_csv(&tree, &result, out),
    })
}
