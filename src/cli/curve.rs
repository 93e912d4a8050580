//! `btrel curve`: π(t) of nodes as CSV, with `--mc` or `--ci` columns.

use btrel::compile::Options;
use btrel::curve::Timing;
use btrel::tree::Tree;
use btrel::Model;

use super::advice::{model_failure, Cmd};
use super::args::{CurveArgs, MethodArg, TimingArg};
use super::ci::{ci_notes, ci_sampler};
use super::input::{find_nodes, warn_endless, InputOptions};
use super::options::{ci_settings, method, optional_count, requested_times, sim_options};
use super::output::{emit, CurveCsv};
use super::progress::{run_simulation, Spinner};
use super::Failure;

pub(super) fn run(args: CurveArgs, input: &InputOptions) -> Result<(), Failure> {
    if matches!(args.timing, TimingArg::Deterministic) && matches!(args.method, MethodArg::Book) {
        return Err(Failure::input(
            "--timing deterministic cannot be combined with --method book (the book's chain makes every time exponential again): use --method exact",
        ));
    }
    let times = requested_times(&args)?;
    let ci = ci_settings(&args.ci)?;
    let (tree, source) = input.load_keyed(&args.tree)?;
    warn_endless(&tree);
    let nodes = if args.nodes.is_empty() {
        vec![Tree::ROOT]
    } else {
        find_nodes(&tree, &args.nodes, &args.tree)?
    };
    let options = Options {
        method: method(args.method),
        max_states: args.max_states,
    };
    let timing = match args.timing {
        TimingArg::AsGiven => Timing::AsGiven,
        TimingArg::Deterministic => Timing::Deterministic,
    };
    let failure = model_failure(Cmd::Curve, options.method);
    // one plan for every node asked (and its figures, if far times need them)
    let model = Model::with_options(&tree, options).map_err(&failure)?;
    let mc = optional_count("--mc", &args.mc)?;
    let sim = mc
        .map(|runs| sim_options(&args.sim.sim(), runs, times.clone(), false))
        .transpose()?;
    let mut curves = Vec::with_capacity(nodes.len());
    for &id in &nodes {
        let spinner = Spinner::start(format!("computing π(t) of '{}'", tree.node(id).name));
        let points = model.curve_with(id, &times, timing).map_err(&failure)?;
        drop(spinner);
        let simulated = match &sim {
            Some(o) => Some(run_simulation(&tree, id, o)?.curve),
            None => None,
        };
        curves.push((id, points, simulated));
    }
    let bands = match &ci {
        None => None,
        Some(ci) => {
            let sampler = ci_sampler(&tree, source.as_ref(), ci, 3 * times.len() * nodes.len())?;
            let flat = sampler
                .intervals(ci.level, ci.draws, ci.seed, |t| {
                    let mut v = Vec::with_capacity(3 * times.len() * nodes.len());
                    let model = Model::with_options(t, options)?;
                    for &id in &nodes {
                        for p in model.curve_with(id, &times, timing)? {
                            v.extend([Some(p.success), Some(p.failure), Some(p.running)]);
                        }
                    }
                    Ok(v)
                })
                .map_err(model_failure(Cmd::Curve, options.method))?;
            ci_notes(ci, &sampler);
            Some(flat)
        }
    };
    let table = CurveCsv {
        tree: &tree,
        curves: &curves,
        bands: bands.as_deref(),
        simulated: sim.is_some(),
    };
    emit(args.output.as_deref(), |out| table.write(out))
}
