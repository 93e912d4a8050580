//! `btrel export`: DOT, PRISM (model or explicit files) and Storm's DRN.

use std::path::PathBuf;

use btrel::compile::Options;
use btrel::tree::Tree;
use btrel::Model;

use super::advice::{analysis_failure, model_failure, with_article, write_error, Cmd};
use super::args::{ExportArgs, ExportFormat, MethodArg};
use super::input::{find_nodes, InputOptions};
use super::options::{method, parse_time};
use super::output::emit;
use super::Failure;

pub(super) fn run(args: ExportArgs, input: &InputOptions) -> Result<(), Failure> {
    match args.to {
        ExportFormat::Dot if args.node.is_some() => {
            return Err(Failure::input(
                "--node goes with --to prism (the DOT export draws the whole tree, or with --mrg NODE one node's MRG)",
            ))
        }
        ExportFormat::Prism if matches!(args.method, MethodArg::Book) => {
            return Err(Failure::input(
                "--method book goes with --to dot (its labels); --to prism always exports the exact chain: remove --method book",
            ))
        }
        _ => {}
    }
    let tree = input.load(&args.tree)?;
    let one = |name: &Option<String>| -> Result<usize, Failure> {
        match name {
            Some(n) => Ok(find_nodes(&tree, std::slice::from_ref(n), &args.tree)?[0]),
            None => Ok(Tree::ROOT),
        }
    };
    let options = Options {
        method: method(args.method),
        max_states: args.max_states,
    };
    if args.mrg.is_some() && !matches!(args.to, ExportFormat::Dot) {
        return Err(Failure::input("--mrg goes with --to dot"));
    }
    if args.properties.is_some()
        && !matches!(args.to, ExportFormat::Prism | ExportFormat::PrismExplicit)
    {
        return Err(Failure::input(match args.to {
            ExportFormat::Drn => {
                "--properties goes with --to prism or prism-explicit: Storm's property language \
                 cannot weight results by the initial distribution (weight them by the DRN's \
                 w_init reward, as scripts/storm_check.py does)"
            }
            _ => "--properties goes with --to prism or prism-explicit",
        }));
    }
    let times = args
        .times
        .iter()
        .map(|s| parse_time("--times", s))
        .collect::<Result<Vec<f64>, Failure>>()?;
    let chain = |id| {
        btrel::compile::phase::phase_chain(&tree, id, args.max_states).map_err(Failure::analysis)
    };
    let what = |id: usize| {
        let n = tree.node(id);
        format!("node '{}' ({})", n.name, n.kind.keyword())
    };
    let text = match args.to {
        ExportFormat::Dot => {
            let analysis = Model::with_options(&tree, options).and_then(|m| m.analysis().cloned());
            match &args.mrg {
                None => btrel::export::dot_tree(&tree, analysis.as_ref().ok()),
                Some(_) => {
                    let id = one(&args.mrg)?;
                    let kind = &tree.node(id).kind;
                    if matches!(
                        kind,
                        btrel::tree::NodeKind::Action(_)
                            | btrel::tree::NodeKind::Condition { .. }
                            | btrel::tree::NodeKind::Decorator { .. }
                            | btrel::tree::NodeKind::Flow(_)
                    ) {
                        return Err(Failure::input(format!(
                            "node '{}' is {}: only Sequence, Fallback and Parallel nodes have a marking reachability graph\n  help: give --mrg one of those",
                            tree.node(id).name,
                            with_article(kind.keyword())
                        )));
                    }
                    let analysis = analysis.map_err(|e| {
                        let f = model_failure(Cmd::ExportDot, options.method)(e);
                        Failure::analysis(format!(
                            "the tree cannot be analysed, so its MRG cannot be labelled: {}",
                            f.message
                        ))
                    })?;
                    let figs = analysis.children(&tree, id);
                    btrel::export::dot_mrg(&tree, id, &figs).map_err(Failure::input)?
                }
            }
        }
        ExportFormat::Prism => btrel::export::prism_ctmc(&tree, one(&args.node)?, args.max_states)
            .map_err(analysis_failure(Cmd::ExportPrism, options.method))?,
        ExportFormat::Drn => {
            let id = one(&args.node)?;
            let chain = chain(id)?;
            return emit(args.output.as_deref(), |out| {
                btrel::export::write_drn(&chain, &what(id), out)
            });
        }
        ExportFormat::PrismExplicit => {
            let Some(base) = &args.output else {
                return Err(Failure::input(
                    "--to prism-explicit writes four files: give their base name with -o BASE \
                     (BASE.tra, BASE.sta, BASE.lab, BASE.srew)",
                ));
            };
            let chain = chain(one(&args.node)?)?;
            // `-o sg`, `-o sg.tra` and `-o sg.all` all name sg.tra, sg.sta, ...
            let base = match base.extension().and_then(|e| e.to_str()) {
                Some(e) if e == "all" || btrel::export::PRISM_EXPLICIT_EXTENSIONS.contains(&e) => {
                    base.with_extension("")
                }
                _ => base.clone(),
            };
            let properties = args
                .properties
                .as_ref()
                .map(|_| btrel::export::prism_explicit_properties(&chain, &times));
            let paths: Vec<PathBuf> = btrel::export::PRISM_EXPLICIT_EXTENSIONS
                .iter()
                .map(|ext| {
                    let mut name = base.clone().into_os_string();
                    name.push(".");
                    name.push(ext);
                    PathBuf::from(name)
                })
                .collect();
            let mut files: Vec<btrel::output::FileWriter> = paths
                .iter()
                .zip(btrel::export::PRISM_EXPLICIT_EXTENSIONS)
                .map(|(path, ext)| {
                    let chain = &chain;
                    let write: btrel::output::WriteFn =
                        Box::new(move |w| btrel::export::write_prism_explicit(chain, ext, w));
                    (path.as_path(), write)
                })
                .collect();
            if let (Some(path), Some(text)) = (&args.properties, &properties) {
                files.push((path.as_path(), Box::new(|w| w.write_all(text.as_bytes()))));
            }
            return btrel::output::write_atomic_all(files)
                .map_err(|(path, e)| Failure::input(write_error(path, &e)));
        }
    };
    if let Some(path) = &args.properties {
        let text = btrel::export::prism_properties(&times);
        btrel::output::write_atomic(path, |out| out.write_all(text.as_bytes()))
            .map_err(|e| Failure::input(write_error(path, &e)))?;
    }
    emit(args.output.as_deref(), |out| out.write_all(text.as_bytes()))
}
