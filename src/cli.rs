//! Command-line interface: argument parsing and dispatch to the library.
//!
//! Exit codes: 0 success; 2 invalid input or usage (bad tree file, bad
//! option); 1 the analysis could not be completed (a budget exceeded, an
//! unsupported combination) or an internal error.

use std::io::{self, Write};
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use clap::{Parser, Subcommand, ValueEnum};

use btrel::compile::{analyze, Method, Options, DEFAULT_MAX_STATES};
use btrel::report::{Format, Report};
use btrel::tree::{parse_file, Tree};

const EXAMPLES: &str = "\
Examples:
  btrel report trees/search-and-grasp.yaml
  btrel report trees/search-and-grasp.yaml --method book --format json
  btrel report trees/two-arm-parallel.yaml --format csv -o figures.csv
  btrel check trees/search-and-grasp.yaml

Exit codes: 0 ok, 2 invalid input or usage, 1 analysis not possible or internal error.";

#[derive(Parser)]
#[command(
    name = "btrel",
    version,
    about = "Reliability of Stochastic Behavior Trees: success/failure probabilities, MTTS and MTTF per node",
    long_about = "btrel computes how reliable a Stochastic Behavior Tree is (chapter 9 of \
Colledanchise & Ögren, Behavior Trees in Robotics and AI): for every node the probability \
to succeed and to fail, the Mean Time To Succeed (MTTS) and the Mean Time To Fail (MTTF).",
    after_help = EXAMPLES
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Analyse a tree and print every node's ps, pf, MTTS, MTTF, mu and nu.
    #[command(after_help = EXAMPLES)]
    Report(ReportArgs),
    /// Validate a tree file without analysing it.
    #[command(after_help = "Example:\n  btrel check trees/search-and-grasp.yaml")]
    Check {
        /// The tree file (YAML).
        tree: PathBuf,
    },
}

#[derive(clap::Args)]
struct ReportArgs {
    /// The tree file (YAML).
    tree: PathBuf,
    /// exact: compose the actions' phase-type distributions exactly;
    /// book: the chapter's recursion (subtrees replaced by exponential actions).
    #[arg(long, value_enum, default_value_t = MethodArg::Exact)]
    method: MethodArg,
    /// Output format.
    #[arg(long, value_enum, default_value_t = FormatArg::Table)]
    format: FormatArg,
    /// Write to this file (atomically) instead of standard output.
    #[arg(short, long, value_name = "FILE")]
    output: Option<PathBuf>,
    /// Largest chain (number of states) an exact analysis may build.
    #[arg(long, value_name = "N", default_value_t = DEFAULT_MAX_STATES)]
    max_states: usize,
}

#[derive(Clone, Copy, ValueEnum)]
enum MethodArg {
    Exact,
    Book,
}

#[derive(Clone, Copy, ValueEnum)]
enum FormatArg {
    Table,
    Json,
    Csv,
}

/// An error with its exit code.
struct Failure {
    code: u8,
    message: String,
}

impl Failure {
    fn input(message: impl ToString) -> Failure {
        Failure {
            code: 2,
            message: message.to_string(),
        }
    }
    fn analysis(message: impl ToString) -> Failure {
        Failure {
            code: 1,
            message: message.to_string(),
        }
    }
}

pub fn main() -> ExitCode {
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) => {
            let _ = e.print();
            return ExitCode::from(if e.use_stderr() { 2 } else { 0 });
        }
    };
    let result = match cli.command {
        Command::Report(args) => report(args),
        Command::Check { tree } => check(&tree),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(f) => {
            eprintln!("error: {}", f.message);
            ExitCode::from(f.code)
        }
    }
}

fn load(path: &Path) -> Result<Tree, Failure> {
    parse_file(path).map_err(Failure::input)
}

fn check(path: &Path) -> Result<(), Failure> {
    let tree = load(path)?;
    emit(None, |out| {
        writeln!(
            out,
            "{}: ok ({} nodes, {} leaves)",
            path.display(),
            tree.nodes.len(),
            tree.leaf_count()
        )
    })
}

fn report(args: ReportArgs) -> Result<(), Failure> {
    let tree = load(&args.tree)?;
    let options = Options {
        method: match args.method {
            MethodArg::Exact => Method::Exact,
            MethodArg::Book => Method::Book,
        },
        max_states: args.max_states,
    };
    let analysis = analyze(&tree, &options).map_err(Failure::analysis)?;
    let report = Report::new(&tree, &analysis);
    let format = match args.format {
        FormatArg::Table => Format::Table,
        FormatArg::Json => Format::Json,
        FormatArg::Csv => Format::Csv,
    };
    let exporter = format.exporter();
    emit(args.output.as_deref(), |out| exporter.write(&report, out))
}

/// Writes to a file atomically, or to standard output. A closed pipe on
/// standard output (e.g. `| head`) ends the program quietly.
fn emit(
    path: Option<&Path>,
    write: impl FnOnce(&mut dyn Write) -> io::Result<()>,
) -> Result<(), Failure> {
    match path {
        Some(p) => btrel::output::write_atomic(p, write)
            .map_err(|e| Failure::input(format!("cannot write {}: {e}", p.display()))),
        None => {
            let stdout = io::stdout();
            let mut lock = io::BufWriter::new(stdout.lock());
            match write(&mut lock).and_then(|()| lock.flush()) {
                Ok(()) => Ok(()),
                Err(e) if e.kind() == io::ErrorKind::BrokenPipe => Ok(()),
                Err(e) => Err(Failure::analysis(format!(
                    "cannot write to standard output: {e}"
                ))),
            }
        }
    }
}
