//! The CLI's advice: every hint that names a command-line flag or command.
//! The library's errors state facts (typed variants and fields); here they
//! are matched and given the options of the command that was run.

use std::io;
use std::path::Path;

use btrel::compile::{AnalysisError, Method};

use super::Failure;

/// `completions` and `man` given a tree-input option.
pub(super) const TREE_OPTIONS_WITHOUT_TREE: &str =
    "--input-format, --params and --include go with a command that reads a tree: remove them";

/// The help after the warnings about a restart loop that never returns.
pub(super) const RESTART_LOOP: &str =
    "  help: an action that returns within its tick (e.g. Nav2's synchronous \
     TruncatePathLocal) is never restarted: give it `tau_s: 0` (and `tau_f: 0`) in the \
     params file";

/// The help of an XML tree whose SubTree is defined nowhere: the parser's
/// own help, then `--include`.
pub(super) fn include_subtree(help: Option<String>) -> String {
    let h = help.unwrap_or_default();
    format!(
        "{h}{}pass the file that defines it with --include FILE (or a folder: --include DIR)",
        if h.is_empty() { "" } else { "; " }
    )
}

/// What to give instead of the unknown node `name` (`all`: the tree's node names).
pub(super) fn unknown_node(name: &str, all: &[&str]) -> String {
    match btrel::tree::error::nearest(name, all) {
        Some(near) => format!("did you mean '{near}'?"),
        None if all.len() <= 12 => {
            format!("give one of {}, or a path such as 0.1", all.join(", "))
        }
        None => "give a node name, or a path such as 0.1 (`btrel report --format csv` lists both)"
            .to_string(),
    }
}

/// The command that was run, for advice that names only its own options.
#[derive(Clone, Copy, PartialEq, Eq)]
pub(super) enum Cmd {
    Report,
    Check,
    Curve,
    Compare,
    Plot,
    ExportDot,
    ExportPrism,
}

/// Joins alternatives: `a`, `a or b`, `a, b or c`.
pub(super) fn or_list(items: &[String]) -> String {
    match items {
        [] => String::new(),
        [one] => one.clone(),
        [rest @ .., last] => format!("{} or {last}", rest.join(", ")),
    }
}

/// [`analysis_failure`] for the library's [`btrel::Model`]: its analysis
/// errors get the same advice; any other is stated as it is.
pub(super) fn model_failure(cmd: Cmd, method: Method) -> impl Fn(btrel::Error) -> Failure {
    move |e| match e {
        btrel::Error::Analysis(e) => analysis_failure(cmd, method)(e),
        other => Failure::analysis(other),
    }
}

/// An analysis error with advice naming only the options of `cmd`.
pub(super) fn analysis_failure(cmd: Cmd, method: Method) -> impl Fn(AnalysisError) -> Failure {
    move |e| {
        let exact = method == Method::Exact;
        let has_method = !matches!(cmd, Cmd::ExportPrism | Cmd::Check);
        let mut fixes: Vec<String> = Vec::new();
        let book = "`--method book` (the book's approximation)".to_string();
        let simulate = if cmd == Cmd::Check {
            "`--mc` (a sequential Monte Carlo test)".to_string()
        } else {
            "`btrel simulate` (Monte Carlo)".to_string()
        };
        match &e {
            AnalysisError::NotMarkovian { .. } => {
                if exact && has_method {
                    fixes.push(book);
                }
                fixes.push(simulate);
            }
            AnalysisError::StateBudget { states, .. } => {
                if exact && has_method {
                    fixes.push(book);
                }
                fixes.push(simulate);
                if *states < 1e12 {
                    fixes.push(format!(
                        "a larger budget, `--max-states {}`",
                        (states.ceil() as u64).max(1)
                    ));
                } else {
                    fixes.push("a larger budget, `--max-states N`".to_string());
                }
            }
            AnalysisError::Stiff { .. } | AnalysisError::ConvolutionWork { .. } => {
                match cmd {
                    Cmd::Curve => {
                        fixes.push("fewer or earlier time points (--times, --t-end)".into())
                    }
                    Cmd::Plot => fixes.push("a shorter horizon (--t-end)".into()),
                    _ => {}
                }
                if exact && has_method {
                    fixes.push(book);
                }
                fixes.push(simulate);
            }
            AnalysisError::Unbounded { .. } | AnalysisError::Nav2 { .. } => fixes.push(simulate),
            AnalysisError::Numerical { .. } | AnalysisError::NeverReturns { .. } => {}
        }
        if cmd == Cmd::Plot && !matches!(e, AnalysisError::NeverReturns { .. }) {
            fixes.push("`--mc N` (plot a simulation alone)".to_string());
        }
        let mut message = match (&e, cmd) {
            // an exported model is a CTMC: say why, not what a Parallel supports
            (AnalysisError::NotMarkovian { leaf }, Cmd::ExportPrism) => format!(
                "action '{leaf}' has a fixed, hybrid or shifted time, which no CTMC (PRISM or \
                 Storm model) represents exactly: only exponential, Erlang, hypoexponential, \
                 hyperexponential and phase-type times (without shift) are phases"
            ),
            _ => e.to_string(),
        };
        if !fixes.is_empty() {
            message.push_str(&format!("\n  help: instead use {}", or_list(&fixes)));
        }
        Failure::analysis(message)
    }
}

/// `a sequence`, `an action`.
pub(super) fn with_article(word: &str) -> String {
    let an = word.starts_with(['a', 'e', 'i', 'o', 'u']);
    format!("{} {word}", if an { "an" } else { "a" })
}

/// A comparison error with advice for `cmd` (compare, or plot --compare).
pub(super) fn compare_failure(
    cmd: Cmd,
    method: Method,
) -> impl Fn(btrel::compare::CompareError) -> Failure {
    use btrel::compare::CompareError;
    move |e| {
        match e {
        CompareError::Analysis(a) => analysis_failure(cmd, method)(a),
        CompareError::Model(m) => model_failure(cmd, method)(m),
        CompareError::NotReorderable(name, kind) => Failure::input(format!(
            "node '{name}' is {}: only the children of Fallback nodes can be reordered (Def. 9.10)\n  help: {}",
            with_article(kind),
            if cmd == Cmd::Plot {
                "give --compare a Fallback node"
            } else {
                "give a Fallback with --node, or omit --node to reorder every Fallback"
            }
        )),
        CompareError::NeedsDeadline => {
            Failure::input("--by success-by needs a deadline: add --deadline T")
        }
        e @ CompareError::NeverReturns(_) => Failure::analysis(format!(
            "{e}\n  help: `btrel report` gives each ordering's P(never returns) when you write it \
             out; make the loop's child able to end it to compare orderings"
        )),
    }
    }
}

/// A failed output file, with what to do about it.
pub(super) fn write_error(path: &Path, e: &io::Error) -> String {
    let advice = match e.kind() {
        io::ErrorKind::NotFound => "create the directory first or choose another -o path",
        io::ErrorKind::PermissionDenied => "check the permissions or choose another -o path",
        _ => "choose another path, or check the disk",
    };
    format!("cannot write {}: {e}; {advice}", path.display())
}

/// A log that cannot be read, with the remedy in this command's options.
pub(super) fn log_failure(mut e: btrel::logs::LogError) -> Failure {
    use btrel::logs::LogHint;
    let hint = match e.hint {
        None => "",
        Some(LogHint::ChooseTopic) => ", or choose a topic with --topic",
        Some(LogHint::ChooseOneTopic) => "; choose one with --topic",
        Some(LogHint::DefineSubTree) => ": add the file that defines it with --include",
        Some(LogHint::WrongTree) => " (wrong --tree, or a mixed-up bag?)",
        Some(LogHint::NotABag) => ": give it to btrel fit without a bag",
        Some(LogHint::NeedsTree) => "; give the tree that ran with --tree TREE.xml",
    };
    e.message.push_str(hint);
    Failure::input(e)
}

/// A requirement that cannot be parsed, as `--require` names it.
pub(super) fn requirement_failure(mut e: btrel::gate::ExprError) -> Failure {
    if e.nodes_unlisted {
        if let Some(h) = &mut e.help {
            h.push_str(" (`btrel report --format csv` lists both)");
        }
    }
    let text = e.to_string();
    Failure::input(format!(
        "--require{}",
        text.strip_prefix("requirement").unwrap_or(&text)
    ))
}

/// A requirement `--mc` cannot test, with the options that would.
pub(super) fn test_failure(e: btrel::gate::TestError) -> Failure {
    use btrel::gate::TestError;
    let help = match e {
        TestError::Region { .. } => {
            "\n  help: a smaller --indifference, or decide it exactly (without --mc)"
        }
        _ => "",
    };
    Failure::input(format!("{e}{help}"))
}

/// The warnings of a fitted leaf, with what they mean for `--ci`.
pub(super) fn fit_warnings(leaf: &btrel::fit::LeafFit) -> Vec<String> {
    let mut warnings = leaf.warnings.clone();
    if let Some(w) = leaf.no_covariance.and_then(|i| warnings.get_mut(i)) {
        w.push_str(", so `--ci` holds its fitted times");
    }
    warnings
}

/// Logs that cannot be keyed by name.
pub(super) fn fit_failure(e: impl std::fmt::Display) -> Failure {
    Failure::input(format!("{e}; key by ID instead with --by id"))
}

/// A figure the sensitivity cannot differentiate.
pub(super) fn undefined_objective(m: impl std::fmt::Display) -> Failure {
    Failure::analysis(format!("{m}: choose another objective with --of"))
}

/// Restates the comparison's note on its budget with `--max-candidates`
/// when the limit was given.
pub(super) fn restate_budget(cmp: &mut btrel::compare::Comparison) {
    if !cmp.budget.explicit {
        return;
    }
    if let Some(note) = cmp.over_budget.and_then(|i| cmp.notes.get_mut(i)) {
        *note = format!(
            "{} orderings exceed --max-candidates {}",
            btrel::compare::count_text(cmp.space),
            cmp.budget.limit
        );
    }
}

/// The note after a comparison that did not enumerate every ordering: the
/// option that would.
pub(super) fn enumerate_all(cmp: &btrel::compare::Comparison) -> String {
    format!(
        "note: `--max-candidates {}` enumerates all {} orderings (estimated {})",
        cmp.space as u64,
        btrel::compare::count_text(cmp.space),
        btrel::compare::duration_text(cmp.budget.estimate(cmp.space))
    )
}
