//! `btrel sensitivity`: derivatives and elasticities of the root's figure.

use btrel::compile::Options;

use super::advice::{self, analysis_failure, Cmd};
use super::args::{FormatArg, OfArg, SensitivityArgs};
use super::input::InputOptions;
use super::options::{method, optional_time};
use super::output::emit;
use super::Failure;

pub(super) fn run(args: SensitivityArgs, input: &InputOptions) -> Result<(), Failure> {
    use btrel::sensitivity::{Objective, SensitivityError};
    let deadline = optional_time("--deadline", &args.deadline)?;
    let objective = match (args.of, deadline) {
        (Some(OfArg::SuccessBy) | None, Some(t)) => Objective::SuccessBy(t),
        (Some(OfArg::SuccessBy), None) => {
            return Err(Failure::input("--of success-by needs --deadline T"))
        }
        (Some(_), Some(_)) => {
            return Err(Failure::input(
                "--deadline goes with --of success-by: remove it, or use --of success-by",
            ))
        }
        (None | Some(OfArg::Ps), None) => Objective::Ps,
        (Some(OfArg::Mtts), None) => Objective::Mtts,
        (Some(OfArg::Mttf), None) => Objective::Mttf,
        (Some(OfArg::MeanTime), None) => Objective::MeanTime,
    };
    let tree = input.load(&args.tree)?;
    let options = Options {
        method: method(args.method),
        max_states: args.max_states,
    };
    let fail = |e: SensitivityError| match e {
        SensitivityError::Analysis(e) => analysis_failure(Cmd::Report, options.method)(e),
        SensitivityError::Undefined(m) => advice::undefined_objective(m),
    };
    let s = btrel::sensitivity::sensitivity(&tree, objective, &options).map_err(fail)?;
    // the laws whose parameters have no rows: say so
    let held: Vec<String> = tree
        .nodes()
        .iter()
        .filter_map(|n| match &n.kind {
            btrel::tree::NodeKind::Action(a) => {
                let families: Vec<&str> = [a.success, a.failure]
                    .into_iter()
                    .flatten()
                    .filter(|d| {
                        matches!(d, btrel::tree::Duration::PhaseType { .. })
                            && btrel::sensitivity::StageLaw::of(d).is_none()
                    })
                    .map(|d| d.family())
                    .collect();
                (!families.is_empty()).then(|| format!("{} ({})", n.name, families.join(", ")))
            }
            _ => None,
        })
        .collect();
    if !held.is_empty() {
        eprintln!(
            "note: the stage rates and phase-type parameters (alpha, T) of {} are held, not \
             differentiated (a shift is listed as the outcome's tau; an Erlang's rate and a \
             two-branch hyperexponential's p, rate1, rate2 have rows)",
            held.join("; ")
        );
    }
    let mut sentences = Vec::new();
    if matches!(args.format, FormatArg::Table) {
        for row in s.rows.iter().filter(|r| r.derivative != 0.0).take(3) {
            sentences.push(btrel::sensitivity::sentence(&tree, &s, row, &options).map_err(fail)?);
        }
    }
    use btrel::report::sensitivity as out_s;
    emit(args.output.as_deref(), |out| match args.format {
        FormatArg::Table => out_s::write_table(&tree, &s, &sentences, out),
        FormatArg::Json => out_s::write_json(&tree, &s, out),
        FormatArg::Csv => out_s::write_csv(&tree, &s, out),
    })
}
