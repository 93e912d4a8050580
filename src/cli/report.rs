//! `btrel report`: every node's figures, with `--mc` or `--ci`.

use btrel::compile::Options;
use btrel::report::{Format, Report};
use btrel::tree::Tree;
use btrel::Model;

use super::advice::{model_failure, Cmd};
use super::args::{FormatArg, ReportArgs};
use super::ci::ci_sampler;
use super::input::{warn_endless, InputOptions};
use super::options::{ci_settings, method, optional_count, sim_options};
use super::output::emit;
use super::progress::run_simulation;
use super::Failure;

pub(super) fn run(args: ReportArgs, input: &InputOptions) -> Result<(), Failure> {
    let ci = ci_settings(&args.ci)?;
    if ci.is_some() && args.mc.is_some() {
        return Err(Failure::input(
            "--ci and --mc make two different tables: run the report once with each",
        ));
    }
    let (tree, source) = input.load_keyed(&args.tree)?;
    warn_endless(&tree);
    let options = Options {
        method: method(args.method),
        max_states: args.max_states,
    };
    let mc = optional_count("--mc", &args.mc)?;
    let sim = mc
        .map(|runs| sim_options(&args.sim.sim(), runs, Vec::new(), true))
        .transpose()?;
    let failure = model_failure(Cmd::Report, options.method);
    let model = Model::with_options(&tree, options).map_err(&failure)?;
    let report = Report::new(&tree, model.analysis().map_err(&failure)?);
    let simulated = match &sim {
        Some(o) => Some(run_simulation(&tree, Tree::ROOT, o)?),
        None => None,
    };
    let format = match args.format {
        FormatArg::Table => Format::Table,
        FormatArg::Json => Format::Json,
        FormatArg::Csv => Format::Csv,
    };
    if simulated.is_some() && format == Format::Csv {
        return Err(Failure::input(
            "--mc works with --format table or json; `btrel simulate --format csv` gives the simulated figures as CSV",
        ));
    }
    if let Some(ci) = &ci {
        use btrel::report::intervals;
        let sampler = ci_sampler(&tree, source.as_ref(), ci, 4 * tree.nodes().len())?;
        let flat = sampler
            .intervals(ci.level, ci.draws, ci.seed, |t| {
                let model = Model::with_options(t, options)?;
                let figures = model.all_figures()?;
                Ok(figures
                    .iter()
                    .flat_map(|f| [Some(f.ps), Some(f.pf), f.mtts, f.mttf])
                    .collect())
            })
            .map_err(model_failure(Cmd::Report, options.method))?;
        let intervals = intervals::Intervals {
            level: ci.level,
            draws: ci.draws,
            seed: ci.seed,
            nodes: flat.chunks(4).map(|c| [c[0], c[1], c[2], c[3]]).collect(),
            fixed: sampler.fixed.clone(),
            held: sampler.held.clone(),
            independent: sampler.independent.clone(),
        };
        if format == Format::Csv {
            for note in intervals.notes() {
                eprintln!("note: {note}");
            }
        }
        return emit(args.output.as_deref(), |out| match format {
            Format::Table => intervals::write_table(&report, &intervals, out),
            Format::Json => intervals::write_json(&report, &intervals, out),
            Format::Csv => intervals::write_csv(&report, &intervals, out),
        });
    }
    let exporter = format.exporter();
    emit(args.output.as_deref(), |out| match (&simulated, format) {
        (None, _) => exporter.write(&report, out),
        (Some(r), Format::Json) => {
            serde_json::to_writer_pretty(
                &mut *out,
                &btrel::report::simulation::report_json_with_mc(&report, r),
            )?;
            writeln!(out)
        }
        (Some(r), _) => {
            exporter.write(&report, out)?;
            btrel::report::simulation::write_check_table(&report, r, out)
        }
    })
}
