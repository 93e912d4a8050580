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
use btrel::curve::{CurveOptions, Timing};
use btrel::report::number::full;
use btrel::report::{Format, Report};
use btrel::tree::{parse_file, Tree};

const EXAMPLES: &str = "\
Examples:
  btrel report trees/search-and-grasp.yaml
  btrel report trees/search-and-grasp.yaml --method book --format json
  btrel report trees/two-arm-parallel.yaml --format csv -o figures.csv
  btrel check trees/search-and-grasp.yaml
  btrel report trees/search-and-grasp.xml --params trees/search-and-grasp.params.yaml
  btrel curve trees/search-and-grasp.yaml --t-end 1000 --points 101 -o curve.csv
  btrel curve trees/search-and-grasp.yaml --node search --node grasp --times 10,100,1000

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
    /// Input format of TREE (default: by extension, .xml is BehaviorTree.CPP v4 XML).
    #[arg(long, value_enum, global = true)]
    input_format: Option<InputFormat>,
    /// Parameters of an XML tree's actions and conditions (YAML; default: TREE with
    /// the extension .params.yaml).
    #[arg(long, value_name = "PARAMS.yaml", global = true)]
    params: Option<PathBuf>,
}

#[derive(Clone, Copy, PartialEq, Eq, ValueEnum)]
enum InputFormat {
    Yaml,
    Xml,
}

/// How tree files are read (set once from the global options).
static INPUT: std::sync::OnceLock<(Option<InputFormat>, Option<PathBuf>)> =
    std::sync::OnceLock::new();

#[derive(Subcommand)]
enum Command {
    /// Analyse a tree and print every node's ps, pf, MTTS, MTTF, mu and nu.
    #[command(after_help = EXAMPLES)]
    Report(ReportArgs),
    /// Probabilities of Success/Failure/Running over time, as CSV.
    #[command(after_help = CURVE_EXAMPLES)]
    Curve(CurveArgs),
    /// Rank the orderings of Fallback children (equivalent trees, Def. 9.10).
    #[command(after_help = COMPARE_EXAMPLES)]
    Compare(CompareArgs),
    /// Monte Carlo simulation of the tree's tick semantics (cross-checks every figure).
    #[command(after_help = SIMULATE_EXAMPLES)]
    Simulate(SimulateArgs),
    /// Export the tree or a node's MRG as Graphviz DOT, or a node's exact CTMC for PRISM.
    #[command(after_help = EXPORT_EXAMPLES)]
    Export(ExportArgs),
    /// Plot Success/Failure/Running over time as SVG or PNG (Figs. 9.18–9.22).
    #[command(after_help = PLOT_EXAMPLES)]
    Plot(PlotArgs),
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
    /// Also simulate N runs per node and compare (Table 9.1 style).
    #[arg(long, value_name = "N")]
    mc: Option<String>,
    #[command(flatten)]
    sim: SimArgs,
}

const CURVE_EXAMPLES: &str = "\
Examples:
  btrel curve trees/search-and-grasp.yaml --t-end 1000 --points 101
  btrel curve trees/search-and-grasp.yaml --times 10,100,1000 --method book
  btrel curve trees/search-and-grasp.yaml --node search --t-end 500 --dt 5 -o search.csv
  btrel curve trees/search-and-grasp.yaml --timing deterministic --t-end 1000 --points 1001

Output: CSV with header node,t,success,failure,running; one row per node per time,
in the order of the requested times; numbers at full precision.";

#[derive(clap::Args)]
struct CurveArgs {
    /// The tree file (YAML).
    tree: PathBuf,
    /// Node to report, by name or path (repeatable); default: the root.
    #[arg(long = "node", value_name = "NAME")]
    nodes: Vec<String>,
    #[command(flatten)]
    grid: TimeArgs,
    /// exact (default): exact chain; book: the chapter's recursion.
    #[arg(long, value_enum, default_value_t = MethodArg::Exact)]
    method: MethodArg,
    /// as-given, or deterministic: every exponential time replaced by 1/rate.
    #[arg(long, value_enum, default_value_t = TimingArg::AsGiven)]
    timing: TimingArg,
    /// Also simulate N runs and add mc_success, mc_failure, mc_running columns.
    #[arg(long, value_name = "N")]
    mc: Option<String>,
    #[command(flatten)]
    sim: SimArgs,
    /// Write to this file (atomically) instead of standard output.
    #[arg(short, long, value_name = "FILE")]
    output: Option<PathBuf>,
    /// Largest chain (number of states) an exact analysis may build.
    #[arg(long, value_name = "N", default_value_t = DEFAULT_MAX_STATES)]
    max_states: usize,
}

#[derive(Clone, Copy, ValueEnum)]
enum TimingArg {
    AsGiven,
    Deterministic,
}

const COMPARE_EXAMPLES: &str = "\
Examples:
  btrel compare trees/search-and-grasp.yaml --node search --deadline 100
  btrel compare trees/search-and-grasp.yaml --by mean-time --format json
  btrel compare trees/search-and-grasp.yaml --node search --deadline 100 --top 3 --curves top3.csv

Without --node every Fallback is reordered (the product of their permutations).
Default objective: success-by with --deadline, else mean-time. Orderings are enumerated
exhaustively when that fits the budget (about 2 s of estimated work, or --max-candidates N);
beyond it, the exact ordering rule ps/E[T] (mean time; refined by a local search under a
Parallel) or a local search answers. The output says which search was used and whether the
best is proven optimal.";

#[derive(clap::Args)]
struct CompareArgs {
    /// The tree file (YAML).
    tree: PathBuf,
    /// Fallback node whose children are permuted, by name or path (repeatable); default: all.
    #[arg(long = "node", value_name = "NAME")]
    nodes: Vec<String>,
    /// Objective: mean-time (E[T]), mtts, mttf, or success-by (P(success by --deadline)).
    #[arg(long, value_enum)]
    by: Option<ObjectiveArg>,
    /// Deadline T (s) for success-by.
    #[arg(long, value_name = "T", allow_hyphen_values = true)]
    deadline: Option<String>,
    /// How many orderings to show (the given one is always shown in the table).
    #[arg(long, value_name = "K", default_value_t = 10)]
    top: usize,
    /// exact (default) or book.
    #[arg(long, value_enum, default_value_t = MethodArg::Exact)]
    method: MethodArg,
    /// Output format.
    #[arg(long, value_enum, default_value_t = FormatArg::Table)]
    format: FormatArg,
    /// Also write the root's π(t) of the top K orderings to this CSV file.
    #[arg(long, value_name = "FILE")]
    curves: Option<PathBuf>,
    /// Horizon (s) of --curves (default: where the curves have settled, as in `plot`).
    #[arg(long, value_name = "T", allow_hyphen_values = true)]
    t_end: Option<String>,
    /// Enumerate every ordering when there are at most N (default: as many as about
    /// 2 s of estimated work allow, at most 100000); beyond, the ordering rule / local search.
    #[arg(long, value_name = "N")]
    max_candidates: Option<usize>,
    /// Write to this file (atomically) instead of standard output.
    #[arg(short, long, value_name = "FILE")]
    output: Option<PathBuf>,
}

#[derive(Clone, Copy, ValueEnum)]
enum ObjectiveArg {
    MeanTime,
    Mtts,
    Mttf,
    SuccessBy,
}

const SIMULATE_EXAMPLES: &str = "\
Examples:
  btrel simulate trees/search-and-grasp.yaml --runs 1e6
  btrel simulate trees/search-and-grasp.yaml --runs 1e6 --times 10,100,1000 --format json
  btrel report trees/search-and-grasp.yaml --mc 1e6        # Table 9.1-style check
  btrel curve trees/search-and-grasp.yaml --t-end 1000 --mc 1e5

The same seed gives bit-identical output whatever --threads is (default seed 0x5EEDB7E1).
For a simulated curve as CSV use `btrel curve --mc N`.";

const PLOT_EXAMPLES: &str = "\
Examples:
  btrel plot trees/search-and-grasp.yaml -o sg.svg --mc 1e5                 # Fig. 9.18
  btrel plot trees/search-and-grasp.yaml -o sg.png --mc 1e5                 # the same as PNG
  btrel plot trees/search-and-grasp.yaml -o nodes.svg --node search --node grasp
  btrel plot trees/search-and-grasp.yaml -o det.svg --timing both           # Fig. 9.20
  btrel plot trees/search-and-grasp.yaml -o order.svg --compare search --deadline 100   # Fig. 9.22";

#[derive(Clone, Copy, ValueEnum)]
enum PlotTiming {
    AsGiven,
    Deterministic,
    Both,
}

#[derive(clap::Args)]
struct PlotArgs {
    /// The tree file (YAML).
    tree: PathBuf,
    /// The image to write (atomically): FILE.svg or FILE.png.
    #[arg(short, long, value_name = "FILE.svg|FILE.png")]
    output: PathBuf,
    /// Image format; default: from the extension of -o (.svg or .png).
    #[arg(long, value_enum)]
    format: Option<ImageFormatArg>,
    /// Node to plot, by name or path (repeatable); default: the root.
    #[arg(long = "node", value_name = "NAME")]
    nodes: Vec<String>,
    /// Horizon (s); default: where every curve has settled (running below 1e-3), rounded up.
    #[arg(long, value_name = "T", allow_hyphen_values = true)]
    t_end: Option<String>,
    /// Points of each curve.
    #[arg(long, value_name = "K", default_value_t = 401)]
    points: usize,
    /// Overlay a simulation with N runs (markers).
    #[arg(long, value_name = "N")]
    mc: Option<String>,
    #[command(flatten)]
    sim: SimArgs,
    /// as-given, deterministic (every rate r becomes a fixed 1/r), or both overlaid.
    #[arg(long, value_enum, default_value_t = PlotTiming::AsGiven)]
    timing: PlotTiming,
    /// Overlay the best orderings of this Fallback's children (with --deadline: by success by then).
    #[arg(long, value_name = "NODE")]
    compare: Option<String>,
    /// Deadline (s): drawn as a marker; ranks the orderings of --compare.
    #[arg(long, value_name = "T", allow_hyphen_values = true)]
    deadline: Option<String>,
    /// How many orderings --compare overlays.
    #[arg(long, value_name = "K", default_value_t = 2)]
    top: usize,
    /// exact (default) or book.
    #[arg(long, value_enum, default_value_t = MethodArg::Exact)]
    method: MethodArg,
}

const EXPORT_EXAMPLES: &str = "\
Examples:
  btrel export trees/search-and-grasp.yaml --to dot -o tree.dot && dot -Tsvg tree.dot -o tree.svg
  btrel export trees/search-and-grasp.yaml --to dot --mrg search -o search-mrg.dot
  btrel export trees/search-and-grasp.yaml --to prism -o sg.sm --properties sg.csl
  prism sg.sm sg.csl -const T=100 -prop success_by_T     # P(success by 100 s), weighted over the start

DOT uses the book's notation: Sequence ->, Fallback ?, Parallel =>, decorators <>.";

#[derive(Clone, Copy, ValueEnum)]
enum ExportFormat {
    Dot,
    Prism,
}

#[derive(clap::Args)]
struct ExportArgs {
    /// The tree file (YAML).
    tree: PathBuf,
    /// dot: the tree (or with --mrg a node's MRG); prism: a node's exact CTMC.
    #[arg(long, value_enum)]
    to: ExportFormat,
    /// Draw this control node's marking reachability graph instead of the tree (DOT).
    #[arg(long, value_name = "NODE")]
    mrg: Option<String>,
    /// Node whose chain is exported to PRISM (default: the root).
    #[arg(long, value_name = "NAME")]
    node: Option<String>,
    /// Write the matching PRISM properties file here (with --to prism).
    #[arg(long, value_name = "FILE")]
    properties: Option<PathBuf>,
    /// Method of the figures shown in DOT labels.
    #[arg(long, value_enum, default_value_t = MethodArg::Exact)]
    method: MethodArg,
    /// Largest chain (number of states) an exact analysis may build.
    #[arg(long, value_name = "N", default_value_t = DEFAULT_MAX_STATES)]
    max_states: usize,
    /// Write to this file (atomically) instead of standard output.
    #[arg(short, long, value_name = "FILE")]
    output: Option<PathBuf>,
}

/// Time points: a list, or an evenly spaced grid from 0.
#[derive(clap::Args)]
struct TimeArgs {
    /// Comma-separated times (s), e.g. 0,10,100.
    #[arg(long, value_delimiter = ',', value_name = "T1,T2,...", allow_hyphen_values = true, conflicts_with_all = ["t_end", "points", "dt"])]
    times: Vec<String>,
    /// Last time (s) of an evenly spaced grid starting at 0.
    #[arg(long, value_name = "T", allow_hyphen_values = true)]
    t_end: Option<String>,
    /// Number of grid points from 0 to T inclusive (default 101).
    #[arg(long, value_name = "K", conflicts_with = "dt", requires = "t_end")]
    points: Option<usize>,
    /// Grid spacing (s), from 0 up to T.
    #[arg(long, value_name = "D", requires = "t_end", allow_hyphen_values = true)]
    dt: Option<String>,
}

/// Monte Carlo options shared by `simulate`, `report --mc` and `curve --mc`.
#[derive(clap::Args)]
struct SimArgs {
    /// Seed of the random streams (decimal or 0x hex; default 0x5EEDB7E1).
    #[arg(long, value_name = "S", allow_hyphen_values = true)]
    seed: Option<String>,
    /// Worker threads (default: one per core); the result does not depend on it.
    #[arg(long, value_name = "K", default_value_t = 0)]
    threads: usize,
}

#[derive(clap::Args)]
struct SimulateArgs {
    /// The tree file (YAML).
    tree: PathBuf,
    /// Runs per node (e.g. 1000000 or 1e6).
    #[arg(long, value_name = "N", default_value = "1000000")]
    runs: String,
    #[command(flatten)]
    sim: SimArgs,
    /// Simulate this node's subtree instead of the whole tree (name or path).
    #[arg(long, value_name = "NAME")]
    node: Option<String>,
    #[command(flatten)]
    grid: TimeArgs,
    /// Output format.
    #[arg(long, value_enum, default_value_t = FormatArg::Table)]
    format: FormatArg,
    /// Write to this file (atomically) instead of standard output.
    #[arg(short, long, value_name = "FILE")]
    output: Option<PathBuf>,
}

/// Most time points one request may ask for.
const MAX_POINTS: usize = 10_000_000;

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
    let _ = INPUT.set((cli.input_format, cli.params.clone()));
    let result = match cli.command {
        Command::Report(args) => report(args),
        Command::Check { tree } => check(&tree),
        Command::Curve(args) => curve(args),
        Command::Compare(args) => compare(args),
        Command::Simulate(args) => simulate(args),
        Command::Export(args) => export(args),
        Command::Plot(args) => plot(args),
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
    let (format, params) = INPUT.get().cloned().unwrap_or((None, None));
    let xml = match format {
        Some(f) => f == InputFormat::Xml,
        None => path
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("xml")),
    };
    if !xml {
        if params.is_some() {
            return Err(Failure::input(
                "--params goes with an XML tree (YAML trees carry their parameters): remove --params",
            ));
        }
        return parse_file(path).map_err(Failure::input);
    }
    let params = params.unwrap_or_else(|| path.with_extension("params.yaml"));
    if !params.exists() {
        return Err(Failure::input(format!(
            "{}: an XML tree needs a parameters file; {} does not exist (give one with --params)",
            path.display(),
            params.display()
        )));
    }
    btrel::tree::xml::parse_xml_file(path, &params).map_err(Failure::input)
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
        method: method(args.method),
        max_states: args.max_states,
    };
    let mc = optional_count("--mc", &args.mc)?;
    let sim = mc
        .map(|runs| sim_options(&args.sim, runs, Vec::new(), true))
        .transpose()?;
    let analysis = analyze(&tree, &options).map_err(Failure::analysis)?;
    let report = Report::new(&tree, &analysis);
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

fn method(m: MethodArg) -> Method {
    match m {
        MethodArg::Exact => Method::Exact,
        MethodArg::Book => Method::Book,
    }
}

/// A time given on the command line: finite and ≥ 0.
fn parse_time(what: &str, s: &str) -> Result<f64, Failure> {
    let t: f64 = s
        .trim()
        .parse()
        .map_err(|_| Failure::input(format!("{what}: '{s}' is not a number")))?;
    if !t.is_finite() || t < 0.0 {
        return Err(Failure::input(format!(
            "{what}: {s} is not a valid time (times must be finite and >= 0)"
        )));
    }
    Ok(t)
}

fn requested_times(args: &CurveArgs) -> Result<Vec<f64>, Failure> {
    grid_times(&args.grid)?.ok_or_else(|| {
        Failure::input("which times? give --times T1,T2,... or --t-end T [--points K | --dt D]")
    })
}

/// Times from `--times`, or from `--t-end` with `--points`/`--dt`; `None`
/// when neither is given.
fn grid_times(grid: &TimeArgs) -> Result<Option<Vec<f64>>, Failure> {
    let (list, t_end, points, dt) = (
        &grid.times,
        grid.t_end.as_deref(),
        grid.points,
        grid.dt.as_deref(),
    );
    if !list.is_empty() {
        let times = list
            .iter()
            .map(|s| parse_time("--times", s))
            .collect::<Result<Vec<_>, _>>()?;
        if times.len() > MAX_POINTS {
            return Err(Failure::input(format!(
                "--times: at most {MAX_POINTS} times"
            )));
        }
        return Ok(Some(times));
    }
    let Some(end) = t_end else {
        return Ok(None);
    };
    let end = parse_time("--t-end", end)?;
    if let Some(dt) = dt {
        let dt = parse_time("--dt", dt)?;
        if dt <= 0.0 {
            return Err(Failure::input("--dt must be > 0"));
        }
        let count = (end / dt * (1.0 + 1e-12)).floor() + 1.0;
        if count > MAX_POINTS as f64 {
            return Err(Failure::input(format!(
                "--t-end / --dt gives {count:.0} points, more than the limit of {MAX_POINTS}"
            )));
        }
        return Ok(Some(
            (0..count as usize)
                .map(|k| (k as f64 * dt).min(end))
                .collect(),
        ));
    }
    let points = points.unwrap_or(101);
    if points == 0 || points > MAX_POINTS {
        return Err(Failure::input(format!(
            "--points must be between 1 and {MAX_POINTS}"
        )));
    }
    if points == 1 {
        return Ok(Some(vec![end]));
    }
    Ok(Some(
        (0..points)
            .map(|k| end * k as f64 / (points - 1) as f64)
            .collect(),
    ))
}

/// An optional time option (finite, ≥ 0).
fn optional_time(what: &str, value: &Option<String>) -> Result<Option<f64>, Failure> {
    value.as_deref().map(|t| parse_time(what, t)).transpose()
}

/// An optional count option (see [`parse_count`]).
fn optional_count(what: &str, value: &Option<String>) -> Result<Option<u64>, Failure> {
    value.as_deref().map(|n| parse_count(what, n)).transpose()
}

/// A count such as `1000000`, `1_000_000` or `1e6`.
fn parse_count(what: &str, s: &str) -> Result<u64, Failure> {
    let clean = s.trim().replace('_', "");
    if let Ok(n) = clean.parse::<u64>() {
        return Ok(n);
    }
    match clean.parse::<f64>() {
        Ok(x) if x.is_finite() && x >= 0.0 && x.fract() == 0.0 && x < 1.8e19 => Ok(x as u64),
        _ => Err(Failure::input(format!(
            "{what}: '{s}' is not a whole number of runs (e.g. 100000 or 1e5)"
        ))),
    }
}

fn sim_options(
    args: &SimArgs,
    runs: u64,
    times: Vec<f64>,
    per_node: bool,
) -> Result<btrel::sim::SimOptions, Failure> {
    let seed = match args.seed.as_deref() {
        None => btrel::sim::DEFAULT_SEED,
        Some(s) => {
            let t = s.trim();
            let parsed = match t.strip_prefix("0x").or_else(|| t.strip_prefix("0X")) {
                Some(hex) => u64::from_str_radix(&hex.replace('_', ""), 16),
                None => t.replace('_', "").parse::<u64>(),
            };
            parsed.map_err(|_| {
                Failure::input(format!(
                    "--seed: '{s}' is not a seed (a whole number from 0 to 2^64-1, decimal or 0x hex)"
                ))
            })?
        }
    };
    Ok(btrel::sim::SimOptions {
        runs,
        seed,
        threads: args.threads,
        times,
        per_node,
    })
}

/// Runs a simulation with a progress bar on a terminal.
fn run_simulation(
    tree: &Tree,
    node: usize,
    options: &btrel::sim::SimOptions,
) -> Result<btrel::sim::SimResult, Failure> {
    use std::io::IsTerminal;
    let nodes = if options.per_node {
        tree.subtree(node).len() as u64
    } else {
        1
    };
    let show = io::stderr().is_terminal() && options.runs.saturating_mul(nodes) >= 20_000_000;
    let bar = show.then(|| {
        let b = indicatif::ProgressBar::new(options.runs);
        b.set_style(
            indicatif::ProgressStyle::with_template(
                "simulating {bar:40} {pos}/{len} runs ({eta} left)",
            )
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
        );
        b
    });
    let callback = |done: u64| {
        if let Some(b) = &bar {
            b.set_position(done);
        }
    };
    let result = btrel::sim::simulate_node(
        tree,
        node,
        options,
        bar.as_ref().map(|_| &callback as &(dyn Fn(u64) + Sync)),
    )
    .map_err(Failure::input);
    if let Some(b) = bar {
        b.finish_and_clear();
    }
    result
}

fn simulate(args: SimulateArgs) -> Result<(), Failure> {
    use btrel::report::simulation;
    let runs = parse_count("--runs", &args.runs)?;
    let times = grid_times(&args.grid)?.unwrap_or_default();
    if matches!(args.format, FormatArg::Csv) && !times.is_empty() {
        return Err(Failure::input(
            "--format csv prints the per-node figures; for a simulated curve as CSV use `btrel curve --mc N`",
        ));
    }
    let options = sim_options(&args.sim, runs, times, true)?;
    let tree = load(&args.tree)?;
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

fn curve(args: CurveArgs) -> Result<(), Failure> {
    let times = requested_times(&args)?;
    let tree = load(&args.tree)?;
    let nodes = if args.nodes.is_empty() {
        vec![Tree::ROOT]
    } else {
        find_nodes(&tree, &args.nodes, &args.tree)?
    };
    let options = CurveOptions {
        method: method(args.method),
        timing: match args.timing {
            TimingArg::AsGiven => Timing::AsGiven,
            TimingArg::Deterministic => Timing::Deterministic,
        },
        max_states: args.max_states,
        ..CurveOptions::default()
    };
    let mc = optional_count("--mc", &args.mc)?;
    let sim = mc
        .map(|runs| sim_options(&args.sim, runs, times.clone(), false))
        .transpose()?;
    let mut curves = Vec::with_capacity(nodes.len());
    for &id in &nodes {
        let points = btrel::curve::curve(&tree, id, &times, &options).map_err(Failure::analysis)?;
        let simulated = match &sim {
            Some(o) => Some(run_simulation(&tree, id, o)?.curve),
            None => None,
        };
        curves.push((id, points, simulated));
    }
    emit(args.output.as_deref(), |out| {
        write!(out, "node,t,success,failure,running")?;
        if sim.is_some() {
            write!(out, ",mc_success,mc_failure,mc_running")?;
        }
        writeln!(out)?;
        for (id, points, simulated) in &curves {
            let name = csv_field(&tree.node(*id).name);
            for (k, p) in points.iter().enumerate() {
                write!(
                    out,
                    "{name},{},{},{},{}",
                    full(p.t),
                    full(p.success),
                    full(p.failure),
                    full(p.running)
                )?;
                if let Some(s) = simulated {
                    let m = &s[k];
                    write!(
                        out,
                        ",{},{},{}",
                        full(m.success.mean),
                        full(m.failure.mean),
                        full(m.running.mean)
                    )?;
                }
                writeln!(out)?;
            }
        }
        Ok(())
    })
}

/// The image format of a plot's output file.
#[derive(Clone, Copy, PartialEq, Eq, ValueEnum)]
enum ImageFormatArg {
    Svg,
    Png,
}
use ImageFormatArg as ImageFormat;

fn image_format(path: &Path, given: Option<ImageFormat>) -> Result<ImageFormat, Failure> {
    if let Some(f) = given {
        return Ok(f);
    }
    match path
        .extension()
        .and_then(|e| e.to_str())
        .map(|e| e.to_ascii_lowercase())
        .as_deref()
    {
        Some("svg") => Ok(ImageFormat::Svg),
        Some("png") => Ok(ImageFormat::Png),
        other => Err(Failure::input(format!(
            "-o {}: {}; btrel writes SVG and PNG images: name the file *.svg or *.png, \
             or give --format svg|png",
            path.display(),
            match other {
                Some(e) => format!("unknown image format '.{e}'"),
                None => "the file name has no extension".to_string(),
            }
        ))),
    }
}

/// Timing of the actions of a node's subtree: all exponential, all fixed,
/// or a mixture.
fn subtree_timing(tree: &Tree, node: usize) -> (&'static str, bool) {
    use btrel::tree::{Duration, NodeKind};
    let (mut random, mut fixed) = (false, false);
    let mut stack = vec![node];
    while let Some(id) = stack.pop() {
        let n = tree.node(id);
        if let NodeKind::Action(a) = &n.kind {
            for (d, p) in [(a.success, a.ps), (a.failure, a.pf)] {
                match d {
                    Some(Duration::Fixed { .. }) if p > 0.0 => fixed = true,
                    Some(_) if p > 0.0 => random = true,
                    _ => {}
                }
            }
        }
        stack.extend_from_slice(n.kind.children());
    }
    match (random, fixed) {
        (true, false) => ("stochastic", false),
        (false, _) => ("deterministic (as given)", true),
        (true, true) => ("as given", false),
    }
}

fn plot(args: PlotArgs) -> Result<(), Failure> {
    use btrel::plot::{
        curve_series, default_horizon, mc_series, render_png, render_svg, Marker, PlotSpec, Series,
        Style, VerticalMarker,
    };
    if args.points < 2 || args.points > 100_000 {
        return Err(Failure::input("--points must be between 2 and 100000"));
    }
    if args.top == 0 {
        return Err(Failure::input("--top must be at least 1"));
    }
    let t_end = optional_time("--t-end", &args.t_end)?;
    let deadline = optional_time("--deadline", &args.deadline)?;
    let mc = optional_count("--mc", &args.mc)?;
    let format = image_format(&args.output, args.format)?;
    let tree = load(&args.tree)?;
    let nodes = if args.nodes.is_empty() {
        vec![Tree::ROOT]
    } else {
        find_nodes(&tree, &args.nodes, &args.tree)?
    };
    let base = CurveOptions {
        method: method(args.method),
        ..CurveOptions::default()
    };
    // the trees to draw: (label, tree, node, style, timing)
    let mut drawn: Vec<(String, Tree, usize, Style, Timing)> = Vec::new();
    if let Some(name) = &args.compare {
        let node = find_nodes(&tree, std::slice::from_ref(name), &args.tree)?[0];
        let cmp = btrel::compare::compare(
            &tree,
            &btrel::compare::CompareOptions {
                nodes: vec![node],
                deadline,
                method: base.method,
                keep: args.top,
                ..btrel::compare::CompareOptions::default()
            },
        )
        .map_err(|e| compare_failure(e, true))?;
        for n in &cmp.notes {
            eprintln!("note: {n}");
        }
        // the top K orderings, and the given one (as in Fig. 9.22)
        let shown: Vec<_> = cmp
            .candidates
            .iter()
            .enumerate()
            .filter(|(i, c)| *i < args.top || c.given)
            .map(|(_, c)| c)
            .collect();
        for (i, c) in shown.into_iter().enumerate() {
            let mut t = tree.clone();
            for (&n, o) in cmp.nodes.iter().zip(&c.orders) {
                if let btrel::tree::NodeKind::Fallback { children } = &mut t.nodes[n].kind {
                    children.clone_from(o);
                }
            }
            let mut label = btrel::report::ranking::label(&tree, &cmp, c);
            if c.given {
                label.push_str(" (given)");
            }
            drawn.push((label, t, Tree::ROOT, Style::overlay(i), Timing::AsGiven));
        }
    } else {
        for (i, &id) in nodes.iter().enumerate() {
            let name = if nodes.len() > 1 {
                tree.node(id).name.clone()
            } else {
                String::new()
            };
            let (as_given, all_fixed) = subtree_timing(&tree, id);
            let timings: Vec<(Timing, &str)> = match args.timing {
                PlotTiming::AsGiven => vec![(Timing::AsGiven, "")],
                PlotTiming::Deterministic => vec![(Timing::Deterministic, "deterministic")],
                PlotTiming::Both if all_fixed => {
                    eprintln!(
                        "note: every action of '{}' has fixed times already: --timing both \
                         draws one set of curves",
                        tree.node(id).name
                    );
                    vec![(Timing::AsGiven, as_given)]
                }
                PlotTiming::Both => vec![
                    (Timing::AsGiven, as_given),
                    (Timing::Deterministic, "deterministic (τ = 1/rate)"),
                ],
            };
            let k = timings.len();
            for (j, (timing, what)) in timings.into_iter().enumerate() {
                let label = [name.as_str(), what]
                    .iter()
                    .filter(|x| !x.is_empty())
                    .copied()
                    .collect::<Vec<_>>()
                    .join(", ");
                drawn.push((label, tree.clone(), id, Style::overlay(i * k + j), timing));
            }
        }
    }
    let end = match t_end {
        Some(t) if t > 0.0 => t,
        Some(_) => return Err(Failure::input("--t-end must be > 0")),
        None => {
            let items: Vec<(&Tree, usize, Timing)> = drawn
                .iter()
                .map(|(_, t, id, _, tm)| (t, *id, *tm))
                .collect();
            let h = default_horizon(&items, base.method);
            match deadline {
                Some(d) if d * 1.1 > h => btrel::plot::nice_ceil(d * 1.1),
                _ => h,
            }
        }
    };
    let times: Vec<f64> = (0..args.points)
        .map(|k| end * k as f64 / (args.points - 1) as f64)
        .collect();
    let mut series: Vec<Series> = Vec::new();
    let mut exact_drawn = false;
    for (label, t, id, style, timing) in &drawn {
        let options = CurveOptions {
            timing: *timing,
            ..base
        };
        match btrel::curve::curve(t, *id, &times, &options) {
            Ok(points) => {
                exact_drawn = true;
                series.extend(curve_series(label, &points, *style))
            }
            Err(e) if mc.is_some() => eprintln!(
                "note: no exact curves for '{}' ({e}); plotting the simulation only",
                t.node(*id).name
            ),
            Err(e) => {
                return Err(Failure::analysis(format!(
                    "cannot plot the exact curves of '{}': {e}; plot a simulation instead \
                     with --mc N",
                    t.node(*id).name
                )))
            }
        }
    }
    if let Some(runs) = mc {
        let mc_times: Vec<f64> = (0..41).map(|k| end * k as f64 / 40.0).collect();
        let o = sim_options(&args.sim, runs, mc_times, false)?;
        let mut i = 0;
        for (label, t, id, _, timing) in &drawn {
            if *timing == Timing::Deterministic {
                continue;
            }
            let r = run_simulation(t, *id, &o)?;
            let prefix = if label.is_empty() {
                format!(
                    "Monte Carlo, {} runs",
                    btrel::compare::count_text(runs as f64)
                )
            } else {
                format!("{label}, Monte Carlo")
            };
            series.extend(mc_series(&prefix, &r.curve, Marker::overlay(i)));
            i += 1;
        }
    }
    let tree_title = tree
        .title
        .clone()
        .unwrap_or_else(|| tree.nodes[0].name.clone());
    let title = match (&args.compare, deadline) {
        (Some(n), Some(d)) => format!(
            "{tree_title}: orderings of '{n}', best by P(success by {} s) first",
            full(d)
        ),
        (Some(n), None) => format!("{tree_title}: orderings of '{n}', best by mean time first"),
        _ => {
            let names: Vec<&str> = nodes.iter().map(|&n| tree.node(n).name.as_str()).collect();
            if exact_drawn {
                format!("{} — {} method", names.join(", "), base.method.name())
            } else {
                format!("{} — Monte Carlo only", names.join(", "))
            }
        }
    };
    let mut spec = PlotSpec::new(title, series);
    if let Some(d) = deadline {
        spec.markers.push(VerticalMarker {
            t: d,
            label: format!("deadline {} s", full(d)),
        });
    }
    let bytes = match format {
        ImageFormat::Svg => render_svg(&spec).map_err(Failure::analysis)?.into_bytes(),
        ImageFormat::Png => render_png(&spec).map_err(Failure::analysis)?,
    };
    btrel::output::write_atomic(&args.output, |out| out.write_all(&bytes))
        .map_err(|e| Failure::input(write_error(&args.output, &e)))
}

fn export(args: ExportArgs) -> Result<(), Failure> {
    let tree = load(&args.tree)?;
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
    let text = match args.to {
        ExportFormat::Dot => {
            let analysis = analyze(&tree, &options).ok();
            match &args.mrg {
                None => btrel::export::dot_tree(&tree, analysis.as_ref()),
                Some(_) => {
                    let id = one(&args.mrg)?;
                    let analysis = analysis.ok_or_else(|| {
                        Failure::analysis(
                            "the tree cannot be analysed, so its MRG cannot be labelled",
                        )
                    })?;
                    let figs: Vec<_> = tree
                        .node(id)
                        .kind
                        .children()
                        .iter()
                        .map(|&c| analysis.nodes[c])
                        .collect();
                    btrel::export::dot_mrg(&tree, id, &figs).map_err(Failure::input)?
                }
            }
        }
        ExportFormat::Prism => {
            if args.mrg.is_some() {
                return Err(Failure::input("--mrg goes with --to dot"));
            }
            btrel::export::prism_ctmc(&tree, one(&args.node)?, args.max_states)
                .map_err(Failure::analysis)?
        }
    };
    if let Some(path) = &args.properties {
        if !matches!(args.to, ExportFormat::Prism) {
            return Err(Failure::input("--properties goes with --to prism"));
        }
        btrel::output::write_atomic(path, |out| {
            out.write_all(btrel::export::PRISM_PROPERTIES.as_bytes())
        })
        .map_err(|e| Failure::input(write_error(path, &e)))?;
    }
    emit(args.output.as_deref(), |out| out.write_all(text.as_bytes()))
}

fn find_nodes(tree: &Tree, names: &[String], file: &Path) -> Result<Vec<usize>, Failure> {
    names
        .iter()
        .map(|n| {
            tree.find(n).ok_or_else(|| {
                Failure::input(format!(
                    "no node named '{n}' in {} (give a node name or a path such as 0.1)",
                    file.display()
                ))
            })
        })
        .collect()
}

fn compare(args: CompareArgs) -> Result<(), Failure> {
    use btrel::compare::{CompareOptions, Objective};
    use btrel::report::ranking;
    use std::io::IsTerminal;
    let deadline = optional_time("--deadline", &args.deadline)?;
    let t_end = optional_time("--t-end", &args.t_end)?;
    if args.top == 0 {
        return Err(Failure::input("--top must be at least 1"));
    }
    let tree = load(&args.tree)?;
    let nodes = find_nodes(&tree, &args.nodes, &args.tree)?;
    let options = CompareOptions {
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
    let cmp = result.map_err(|e| compare_failure(e, false))?;
    if matches!(
        cmp.search,
        btrel::compare::Search::OrderingRule | btrel::compare::Search::LocalSearch
    ) && cmp.space < 1e15
    {
        eprintln!(
            "note: `--max-candidates {}` enumerates all {} orderings (estimated {})",
            cmp.space as u64,
            btrel::compare::count_text(cmp.space),
            btrel::compare::duration_text(cmp.budget.estimate(cmp.space))
        );
    }
    if let Some(path) = &args.curves {
        let top: Vec<_> = cmp.candidates.iter().take(args.top).collect();
        let trees: Vec<Tree> = top
            .iter()
            .map(|c| {
                let mut t = tree.clone();
                for (&n, o) in cmp.nodes.iter().zip(&c.orders) {
                    if let btrel::tree::NodeKind::Fallback { children } = &mut t.nodes[n].kind {
                        children.clone_from(o);
                    }
                }
                t
            })
            .collect();
        let end = match t_end {
            Some(t) if t > 0.0 => t,
            Some(_) => return Err(Failure::input("--t-end must be > 0")),
            None => {
                let items: Vec<(&Tree, usize, Timing)> = trees
                    .iter()
                    .map(|t| (t, Tree::ROOT, Timing::AsGiven))
                    .collect();
                let h = btrel::plot::default_horizon(&items, options.method);
                match deadline {
                    Some(d) if d * 1.1 > h => btrel::plot::nice_ceil(d * 1.1),
                    _ => h,
                }
            }
        };
        let times: Vec<f64> = (0..=200).map(|k| end * k as f64 / 200.0).collect();
        let curve_options = CurveOptions {
            method: options.method,
            ..CurveOptions::default()
        };
        let mut rows = Vec::new();
        for (c, t) in top.iter().zip(&trees) {
            let points = btrel::curve::curve(t, Tree::ROOT, &times, &curve_options)
                .map_err(Failure::analysis)?;
            rows.push((ranking::label(&tree, &cmp, c), points));
        }
        let root = csv_field(&tree.node(Tree::ROOT).name);
        btrel::output::write_atomic(path, |out| {
            writeln!(out, "ordering,node,t,success,failure,running")?;
            for (label, points) in &rows {
                let label = csv_field(label);
                for p in points {
                    writeln!(
                        out,
                        "{label},{root},{},{},{},{}",
                        full(p.t),
                        full(p.success),
                        full(p.failure),
                        full(p.running)
                    )?;
                }
            }
            Ok(())
        })
        .map_err(|e| Failure::input(write_error(path, &e)))?;
    }
    emit(args.output.as_deref(), |out| match args.format {
        FormatArg::Table => ranking::write_table(&tree, &cmp, args.top, out),
        FormatArg::Json => ranking::write_json(&tree, &cmp, args.top, out),
        FormatArg::Csv => ranking::write_csv(&tree, &cmp, args.top, out),
    })
}

/// A failed comparison, with the CLI's advice.
fn compare_failure(e: btrel::compare::CompareError, plot: bool) -> Failure {
    use btrel::compare::CompareError;
    match e {
        CompareError::Analysis(a) => Failure::analysis(a),
        CompareError::NeedsDeadline => Failure::input("--by success-by needs --deadline T"),
        other @ CompareError::NotReorderable(..) if plot => {
            Failure::input(format!("{other}: give a Fallback with --compare"))
        }
        other @ CompareError::NotReorderable(..) => Failure::input(format!(
            "{other}: give a Fallback with --node, or omit --node to reorder every Fallback"
        )),
    }
}

/// A failed output file, with what to do about it.
fn write_error(path: &Path, e: &io::Error) -> String {
    let advice = match e.kind() {
        io::ErrorKind::NotFound => "create the directory first or choose another -o path",
        io::ErrorKind::PermissionDenied => "check the permissions or choose another -o path",
        _ => "choose another path, or check the disk",
    };
    format!("cannot write {}: {e}; {advice}", path.display())
}

/// Quotes a CSV field when needed.
fn csv_field(s: &str) -> String {
    if s.contains([',', '"', '\n', '\r']) {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s.to_string()
    }
}

/// Writes to a file atomically, or to standard output. A closed pipe on
/// standard output (e.g. `| head`) ends the program quietly.
fn emit(
    path: Option<&Path>,
    write: impl FnOnce(&mut dyn Write) -> io::Result<()>,
) -> Result<(), Failure> {
    match path {
        Some(p) => {
            btrel::output::write_atomic(p, write).map_err(|e| Failure::input(write_error(p, &e)))
        }
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
