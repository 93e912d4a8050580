//! `btrel compare`: the orderings of Fallback children, ranked.

use std::io;

use btrel::curve::Timing;
use btrel::tree::Tree;
use btrel::Model;

use super::advice::{self, compare_failure, model_failure, write_error, Cmd};
use super::args::{CompareArgs, FormatArg, ObjectiveArg};
use super::input::{find_nodes, InputOptions};
use super::options::{method, optional_time};
use super::output::{emit, write_orderings_csv};
use super::Failure;

pub(super) fn run(args: CompareArgs, input: &InputOptions) -> Result<(), Failure> {
    use btrel::compare::{CompareOptions, Objective};
    use btrel::report::ranking;
    use std::io::IsTerminal;
    let deadline = optional_time("--deadline", &args.deadline)?;
    let t_end = optional_time("--t-end", &args.t_end)?;
    if args.top == 0 {
        return Err(Failure::input("--top must be at least 1"));
    }
    let tree = input.load(&args.tree)?;
    let nodes = find_nodes(&tree, &args.nodes, &args.tree)?;
    let mut options = CompareOptions {
        nodes,
        objective: args.by.map(|b| match b {
            ObjectiveArg::MeanTime => Objective::MeanTime,
            ObjectiveArg::Mtts => Objective::Mtts,
            ObjectiveArg::Mttf => Objective::Mttf,
            ObjectiveArg::SuccessBy => Objective::SuccessBy,
        }),
        deadline,
        method: method(args.method),
        max_candidates: args.max_candidates,
        keep: args.top,
        ..CompareOptions::default()
    };
    options.max_states = args.max_states;
    let bar = io::stderr().is_terminal().then(|| {
        let b = indicatif::ProgressBar::hidden();
        b.set_style(
            indicatif::ProgressStyle::with_template(
                "comparing {bar:40} {pos}/{len} orderings ({eta} left)",
            )
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
        );
        b
    });
    let started = std::time::Instant::now();
    let progress = |done: u64, total: u64| {
        if let Some(b) = &bar {
            // only for runs long enough to watch
            if b.is_hidden() && started.elapsed().as_secs_f64() > 0.5 && done < total {
                b.set_draw_target(indicatif::ProgressDrawTarget::stderr());
            }
            b.set_length(total);
            b.set_position(done);
        }
    };
    let result = btrel::compare::compare_with_progress(&tree, &options, &progress);
    if let Some(b) = &bar {
        b.finish_and_clear();
    }
    let mut cmp = result.map_err(compare_failure(Cmd::Compare, options.method))?;
    advice::restate_budget(&mut cmp);
    if matches!(
        cmp.search,
        btrel::compare::Search::OrderingRule | btrel::compare::Search::LocalSearch
    ) && cmp.space < 1e15
    {
        eprintln!("{}", advice::enumerate_all(&cmp));
    }
    if let Some(path) = &args.curves {
        let top: Vec<_> = cmp.candidates.iter().take(args.top).collect();
        let trees: Vec<Tree> = top.iter().map(|c| cmp.reordered(&tree, c)).collect();
        let model_options = btrel::Options {
            method: options.method,
            ..btrel::Options::default()
        };
        let failure = model_failure(Cmd::Compare, options.method);
        let models = trees
            .iter()
            .map(|t| Model::with_options(t, model_options))
            .collect::<Result<Vec<Model>, _>>()
            .map_err(&failure)?;
        let end = match t_end {
            Some(t) if t > 0.0 => t,
            Some(_) => return Err(Failure::input("--t-end must be > 0")),
            None => {
                let items: Vec<_> = models
                    .iter()
                    .map(|m| (Ok(m), Tree::ROOT, Timing::AsGiven))
                    .collect();
                let h = btrel::plot::default_horizon(&items);
                match deadline {
                    Some(d) if d * 1.1 > h => btrel::plot::nice_ceil(d * 1.1),
                    _ => h,
                }
            }
        };
        let times: Vec<f64> = (0..=200).map(|k| end * k as f64 / 200.0).collect();
        let mut rows = Vec::new();
        for (c, m) in top.iter().zip(&models) {
            let points = m.curve(Tree::ROOT, &times).map_err(&failure)?;
            rows.push((ranking::label(&tree, &cmp, c), points));
        }
        let root = &tree.node(Tree::ROOT).name;
        btrel::output::write_atomic(path, |out| write_orderings_csv(root, &rows, out))
            .map_err(|e| Failure::input(write_error(path, &e)))?;
    }
    emit(args.output.as_deref(), |out| match args.format {
        FormatArg::Table => ranking::write_table(&tree, &cmp, args.top, out),
        FormatArg::Json => ranking::write_json(&tree, &cmp, args.top, out),
        FormatArg::Csv => ranking::write_csv(&tree, &cmp, args.top, out),
    })
}
