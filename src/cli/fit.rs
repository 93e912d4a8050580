//! `btrel fit`: leaf parameters from execution logs into a params file.

use std::path::Path;

use super::advice;
use super::args::{FitArgs, FitBy, FitTiming};
use super::input::{plural, InputOptions};
use super::output::emit;
use super::Failure;

pub(super) fn run(args: FitArgs, input: &InputOptions) -> Result<(), Failure> {
    let include = &input.include;
    if input.params.is_some() {
        return Err(Failure::input(
            "fit writes a params file, it reads none: remove --params (write with -o FILE)",
        ));
    }
    if input.format.is_some() {
        return Err(Failure::input(
            "--input-format does nothing for fit (LOG formats go by extension, TREE is XML): remove it",
        ));
    }
    if !include.is_empty() && args.tree.is_none() {
        return Err(Failure::input(
            "--include goes with --tree (the tree embedded in a .btlog is complete): remove --include or add --tree",
        ));
    }
    let mut logs = Vec::new();
    let mut bags = 0;
    for path in &args.logs {
        if !btrel::logs::rosbag::is_rosbag(path) {
            logs.extend(btrel::logs::read_logs(path).map_err(advice::log_failure)?);
            continue;
        }
        let Some(tree) = &args.tree else {
            return Err(Failure::input(format!(
                "{}: a rosbag2 recording: Nav2's behavior_tree_log carries no tree, give the tree \
                 bt_navigator ran with --tree TREE.xml",
                path.display()
            )));
        };
        let bag = btrel::logs::rosbag::read(path, tree, include, args.topic.as_deref())
            .map_err(advice::log_failure)?;
        bags += 1;
        eprintln!(
            "note: {}: {} messages of {}, {} status changes{}",
            bag.log.file,
            bag.messages,
            bag.topic,
            bag.log.records,
            bag.layout
                .as_ref()
                .map(|(l, from)| format!(" ({}, from {from})", l.describe()))
                .unwrap_or_default()
        );
        for n in &bag.notes {
            eprintln!("note: {}: {n}", bag.log.file);
        }
        logs.push(bag.log);
    }
    if args.topic.is_some() && bags == 0 {
        return Err(Failure::input(
            "--topic goes with rosbag2 recordings; none of the LOGs is one: remove --topic",
        ));
    }
    for log in logs.iter().filter(|l| l.out_of_order > 0) {
        eprintln!(
            "note: {}: {} out of time order, by up to {:.3} ms (BT.CPP's logger queues the records \
             of different threads in either order); each keeps its own timestamp",
            log.file,
            plural(log.out_of_order, "record", "records"),
            log.max_step_back * 1e3
        );
    }
    for log in logs.iter().filter(|l| l.repeated_tail > 0) {
        eprintln!(
            "note: {}: the last {} repeated the block before them byte for byte (BT.CPP's \
             FileLogger2 can write its last batch twice); the copy was dropped",
            log.file,
            plural(log.repeated_tail, "record", "records"),
        );
    }
    let by = match args.by {
        FitBy::Id => btrel::fit::By::Id,
        FitBy::Name => btrel::fit::By::Name,
    };
    let mode = match args.timing {
        FitTiming::Exponential => btrel::fit::TimingMode::Exponential,
        FitTiming::Auto => btrel::fit::TimingMode::Auto,
    };
    let fitted = btrel::fit::fit_logs_with(&logs, by, mode).map_err(advice::fit_failure)?;
    for l in &fitted.leaves {
        for w in advice::fit_warnings(l) {
            eprintln!("warning: {}: {w}", l.key);
        }
    }
    for (key, c) in &fitted.unfitted {
        eprintln!(
            "warning: {key}: no completed episode ({} halted): no entry written; add one by hand",
            c.halted
        );
    }
    if fitted.leaves.is_empty() {
        return Err(Failure::analysis(
            "the logs hold no completed episode of any leaf: nothing to fit",
        ));
    }
    let text = btrel::fit::render(&fitted, by);
    // check the file against the tree it is for
    let params_name = args
        .output
        .as_ref()
        .filter(|p| *p != Path::new("-"))
        .map_or("<fitted params>".to_string(), |p| p.display().to_string());
    let check = match &args.tree {
        Some(tree) => {
            let dir =
                std::env::temp_dir().join(format!(".btrel-fit-{}.params.yaml", std::process::id()));
            let r = std::fs::write(&dir, &text)
                .map_err(|e| Failure::analysis(format!("cannot write a temporary file: {e}")))
                .map(|()| {
                    btrel::tree::xml::parse_xml_files(tree, &dir, include).map_err(|mut e| {
                        e.message = e.message.replace(&dir.display().to_string(), &params_name);
                        e
                    })
                });
            let _ = std::fs::remove_file(&dir);
            Some((tree.display().to_string(), r?))
        }
        None => logs.iter().find_map(|l| {
            l.xml.as_ref().map(|xml| {
                (
                    format!("the tree in {}", l.file),
                    btrel::tree::xml::parse_xml_str(xml, &l.file, &text, &params_name),
                )
            })
        }),
    };
    match check {
        Some((what, Err(e))) => eprintln!(
            "warning: the fitted parameters do not make {what} analysable yet: {}",
            e.message
        ),
        Some(_) => {}
        None => eprintln!(
            "note: CSV logs carry no tree: give --tree TREE.xml to check the params file against it"
        ),
    }
    emit(args.output.as_deref(), |out| out.write_all(text.as_bytes()))
}
