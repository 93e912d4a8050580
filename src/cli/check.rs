//! `btrel check`: validate a tree, or gate it on requirements.

use btrel::compile::{Method, Options};

use super::advice::{self, model_failure, Cmd};
use super::args::{CheckArgs, CiArgs};
use super::ci::{ci_notes, ci_sampler};
use super::input::{display_path, plural, warn_endless, InputOptions};
use super::options::{ci_settings, parse_count, parse_positive, parse_seed};
use super::output::emit;
use super::Failure;

pub(super) fn run(args: CheckArgs, input: &InputOptions) -> Result<(), Failure> {
    if !args.require.is_empty() {
        return check_requirements(args, input);
    }
    let path = args.tree.as_path();
    let tree = input.load(path)?;
    warn_endless(&tree);
    emit(None, |out| {
        writeln!(
            out,
            "{}: ok ({}, {})",
            display_path(path),
            plural(tree.nodes().len(), "node", "nodes"),
            plural(tree.leaf_count(), "leaf", "leaves")
        )
    })
}

/// `check --require`: every requirement decided, one line each; exit 1 when
/// one fails.
fn check_requirements(args: CheckArgs, input: &InputOptions) -> Result<(), Failure> {
    use btrel::gate::{self, show};
    use btrel::report::intervals::percent;
    use btrel::report::number::significant;
    use btrel::sim::sequential::Decision;
    let ci = ci_settings(&CiArgs {
        ci: args.ci.clone(),
        ci_draws: args.ci_draws.clone(),
        ci_seed: args.ci_seed.clone(),
    })?;
    if ci.is_some() && args.mc {
        return Err(Failure::input(
            "--ci and --mc decide in two different ways (the fitted parameters' interval, a \
             sequential simulation): give one of them",
        ));
    }
    let mc_settings = if args.mc {
        let mut s = gate::TestSettings::default();
        if let Some(a) = args.alpha.as_deref() {
            s.alpha = parse_positive("--alpha", a)?;
        }
        if let Some(b) = args.beta.as_deref() {
            s.beta = parse_positive("--beta", b)?;
        }
        if !(s.alpha < 1.0 && s.beta < 1.0 && s.alpha + s.beta < 1.0) {
            return Err(Failure::input(format!(
                "--alpha {} and --beta {}: each must be in (0, 1), and their sum below 1 (e.g. 0.05)",
                s.alpha, s.beta
            )));
        }
        if let Some(d) = args.indifference.as_deref() {
            s.indifference = parse_positive("--indifference", d)?;
        }
        if let Some(d) = args.time_indifference.as_deref() {
            s.time_indifference = Some(parse_positive("--time-indifference", d)?);
        }
        if let Some(n) = args.max_runs.as_deref() {
            s.max_runs = parse_count("--max-runs", n)?;
            if s.max_runs == 0 || s.max_runs > btrel::sim::MAX_RUNS {
                return Err(Failure::input(format!(
                    "--max-runs must be between 1 and {} (10^12)",
                    btrel::sim::MAX_RUNS
                )));
            }
        }
        if let Some(seed) = args.seed.as_deref() {
            s.seed = parse_seed("--seed", seed)?;
        }
        s.threads = args.threads.unwrap_or(0);
        Some(s)
    } else {
        None
    };
    let (tree, source) = input.load_keyed(&args.tree)?;
    warn_endless(&tree);
    let reqs = args
        .require
        .iter()
        .map(|text| gate::parse(text, &tree))
        .collect::<Result<Vec<_>, _>>()
        .map_err(advice::requirement_failure)?;
    if let Some(s) = &mc_settings {
        for r in &reqs {
            s.validate(r).map_err(advice::test_failure)?;
        }
    }
    let options = Options {
        method: Method::Exact,
        max_states: args.max_states,
    };
    let mut lines = Vec::with_capacity(reqs.len());
    let mut failed = 0;
    let verdict = |ok: bool| if ok { "PASS" } else { "FAIL" };
    if let Some(s) = &mc_settings {
        for (i, r) in reqs.iter().enumerate() {
            let t = gate::test(&tree, r, i, s).map_err(Failure::input)?;
            let word = match t.decision {
                Decision::Holds => "PASS",
                Decision::Fails => "FAIL",
                Decision::Undecided => "UNDECIDED",
            };
            failed += usize::from(t.decision != Decision::Holds);
            let estimate = match (t.estimate, t.half_width) {
                (Some(v), Some(h)) if r.figure.is_time() => {
                    format!("{} ± {} s", significant(v, 5), significant(h, 2))
                }
                (v, _) => show(r.figure, v),
            };
            let why = match t.decision {
                Decision::Undecided => ", the cap (--max-runs): counted as failing",
                _ if t.runs == 0 => ", the node never returns that outcome",
                _ => "",
            };
            lines.push(format!(
                "{word}  {}: {estimate} after {} runs ({}){why}",
                r.text, t.runs, t.method
            ));
        }
    } else {
        let values = gate::exact_values(&tree, &reqs, &options)
            .map_err(model_failure(Cmd::Check, options.method))?;
        let bounds = match &ci {
            None => None,
            Some(ci) => {
                let sampler = ci_sampler(&tree, source.as_ref(), ci, reqs.len())?;
                let b = sampler
                    .intervals(ci.level, ci.draws, ci.seed, |t| {
                        gate::exact_values(t, &reqs, &options)
                    })
                    .map_err(model_failure(Cmd::Check, options.method))?;
                ci_notes(ci, &sampler);
                Some(b)
            }
        };
        for (i, r) in reqs.iter().enumerate() {
            let line = match (&bounds, &ci) {
                (Some(b), Some(ci)) => {
                    let (bound, ok) = match b[i] {
                        Some((lo, hi)) => {
                            let x = if r.op.at_least() { lo } else { hi };
                            (Some(x), r.holds(x))
                        }
                        None => (None, false),
                    };
                    let side = if r.op.at_least() { "lower" } else { "upper" };
                    failed += usize::from(!ok);
                    format!(
                        "{}  {}: {side} bound {} of the {} interval [{}] (estimate {})",
                        verdict(ok),
                        r.text,
                        show(r.figure, bound),
                        percent(ci.level),
                        b[i].map_or("undefined".to_string(), |(lo, hi)| format!(
                            "{}, {}",
                            significant(lo, 5),
                            significant(hi, 5)
                        )),
                        show(r.figure, values[i])
                    )
                }
                _ => {
                    let ok = values[i].is_some_and(|v| r.holds(v));
                    failed += usize::from(!ok);
                    format!(
                        "{}  {}: {} (exact)",
                        verdict(ok),
                        r.text,
                        show(r.figure, values[i])
                    )
                }
            };
            lines.push(line);
        }
    }
    emit(None, |out| {
        for l in &lines {
            writeln!(out, "{l}")?;
        }
        Ok(())
    })?;
    if failed > 0 {
        return Err(Failure::analysis(format!(
            "{failed} of {} failed",
            plural(reqs.len(), "requirement", "requirements")
        )));
    }
    Ok(())
}
