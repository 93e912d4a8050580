//! Command-line interface: argument parsing and dispatch to the library.
//!
//! Exit codes: 0 success; 2 invalid input or usage (bad tree file, bad
//! option); 1 the analysis could not be completed (a budget exceeded, an
//! unsupported combination) or an internal error.

use std::io::{self, Write};
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use clap::{Parser, Subcommand, ValueEnum};

use btrel::compile::{analyze, AnalysisError, Method, Options, DEFAULT_MAX_STATES};
use btrel::curve::{CurveOptions, Timing};
use btrel::report::number::full;
use btrel::report::{Format, Report};
use btrel::tree::{parse_file, Tree};

const EXAMPLES: &str = "\
Examples:
  btrel report trees/search-and-grasp.yaml
  btrel report trees/search-and-grasp.xml --params trees/search-and-grasp.params.yaml
  btrel report nav.xml --params nav.params.yaml --include nav2_tree_nodes.xml --include subtrees/
  btrel curve trees/search-and-grasp.yaml --t-end 1000 --points 101 -o curve.csv
  btrel compare trees/search-and-grasp.yaml --node search --deadline 100
  btrel simulate trees/search-and-grasp.yaml --runs 1e6
  btrel sensitivity trees/search-and-grasp.yaml --deadline 100
  btrel fit run.btlog -o params.yaml && btrel report tree.xml --params params.yaml --ci
  btrel plot trees/search-and-grasp.yaml -o sg.svg --mc 1e5
  btrel check trees/search-and-grasp.yaml
  btrel completions bash > ~/.local/share/bash-completion/completions/btrel

TREE is a YAML tree file or a BehaviorTree.CPP v4 XML file (.xml, with --params);
`-` reads it from standard input. `-o -` writes to standard output.
Exit codes: 0 ok, 2 invalid input or usage, 1 analysis not possible or internal error.";

const REPORT_EXAMPLES: &str = "\
Examples:
  btrel report trees/search-and-grasp.yaml
  btrel report trees/search-and-grasp.yaml --method book --format json
  btrel report trees/two-arm-parallel.yaml --format csv -o figures.csv
  btrel report trees/search-and-grasp.yaml --mc 1e6 --seed 7     # Table 9.1-style check
  btrel report trees/search-and-grasp.xml --params trees/search-and-grasp.params.yaml
  btrel report trees/search-and-grasp.xml --params docs/fit/search-and-grasp.fitted.params.yaml --ci
  btrel report trees/search-and-grasp.xml --params docs/fit/search-and-grasp.fitted.params.yaml --ci 90 --format json
  cat trees/search-and-grasp.yaml | btrel report -

TREE is YAML or BehaviorTree.CPP v4 XML (.xml, or --input-format xml; parameters from
--params, default TREE with the extension .params.yaml); `-` reads standard input.
A node that may never return (a loop whose child cannot end it, a ReactiveSequence's restart
loop) gets a `never` column, P(never returns); MTTS and MTTF are conditional on returning; a
warning on standard error names each such loop.
Exit codes: 0 ok, 2 invalid input or usage, 1 analysis not possible or internal error.";

const CHECK_EXAMPLES: &str = "\
Examples:
  btrel check trees/search-and-grasp.yaml
  btrel check trees/search-and-grasp.xml --params trees/search-and-grasp.params.yaml
  generate-tree | btrel check -
  btrel check trees/search-and-grasp.yaml --require 'ps >= 0.45' --require 'search.mtts <= 200'
  btrel check trees/search-and-grasp.yaml --require 'success_by(100) >= 0.15' --mc --alpha 0.01
  btrel check trees/search-and-grasp.xml --params docs/fit/search-and-grasp.fitted.params.yaml --require 'ps >= 0.45' --ci

TREE is YAML or BehaviorTree.CPP v4 XML (.xml, or --input-format xml); `-` reads standard input.
Without --require the tree is only validated. A requirement is [NODE.]FIGURE OP NUMBER: FIGURE
is ps, pf, never (P(never returns)), mtts, mttf (s), success_by(T) or failure_by(T) (P(returned
Success / Failure by T s)); OP is >=, <=, > or <; NODE a name or a path such as 0.1 (default the
root). One line per requirement: PASS or FAIL (UNDECIDED with --mc), the requirement, the value.
Decided by the exact engine; --ci by the interval from the fitted parameters (the lower bound
for >= and >, the upper for <= and <); --mc by simulation: a probability by Wald's sequential
probability ratio test of p >= θ+δ (holds) against p <= θ−δ (fails), δ = --indifference, so a
requirement that holds with margin δ is failed with probability at most α/(1−β) and one that
fails by δ passes with at most β/(1−α) (--alpha, --beta); a mean time by a Chow–Robbins
fixed-width interval of half-width --time-indifference at the one-sided normal quantile of
min(α, β), then the side of the threshold its mean lies on (asymptotically the same error
bounds). Exit codes: 0 every requirement holds, 1 one fails or is undecided (or the analysis is
not possible), 2 invalid input or usage (an unknown node, figure or operator, located with a
caret under the requirement).";

const COMPLETIONS_EXAMPLES: &str = "\
Examples:
  btrel completions bash > ~/.local/share/bash-completion/completions/btrel
  btrel completions zsh > ~/.zfunc/_btrel        # with fpath+=~/.zfunc before compinit
  btrel completions fish > ~/.config/fish/completions/btrel.fish";

const FIT_EXAMPLES: &str = "\
Examples:
  btrel fit run.btlog -o params.yaml && btrel report tree.xml --params params.yaml
  btrel report tree.xml --params params.yaml --ci     # intervals from the fit's statistics
  btrel fit day1.btlog day2.btlog --by name -o params.yaml
  btrel fit runs.db3 -o params.yaml                   # every session of a SqliteLogger file
  btrel fit episodes.csv --tree tree.xml -o tree.params.yaml
  btrel fit run.btlog --timing auto -o params.yaml    # Erlang, shifted, ... per outcome by BIC
  btrel fit my_bag/ --tree navigate.xml -o params.yaml  # Nav2's /behavior_tree_log (rosbag2)

LOG is a BehaviorTree.CPP v4 FileLogger2 file (.btlog), a BehaviorTree.CPP v4 SqliteLogger
database (.db3/.btdb, or any file starting with `SQLite format 3`; opened read-only, each
session one run), or a CSV with the columns run,node,start,end,status (times in s; status
success|failure|halted), or a rosbag2 recording of Nav2's behavior_tree_log topic (a bag folder
or its .mcap / .db3 files; --tree names the tree that ran: changes are mapped to its nodes by
uid, or, in bags without uid, by replaying them against the tree's structure). Halted episodes
are right-censored.";

#[derive(clap::Args)]
struct FitArgs {
    /// The logs: .btlog (BT.CPP FileLogger2), .db3 (BT.CPP SqliteLogger) or CSV files, or rosbag2
    /// recordings of Nav2's behavior_tree_log (a bag folder, or its .mcap / .db3 files; need --tree);
    /// episodes of all are pooled.
    #[arg(required = true, value_name = "LOG")]
    logs: Vec<PathBuf>,
    /// The topic of Nav2's behavior tree log in rosbag2 recordings (default: the one topic of type
    /// nav2_msgs/msg/BehaviorTreeLog, in any namespace).
    #[arg(long, value_name = "TOPIC")]
    topic: Option<String>,
    /// The XML tree the params file is for (default: the tree in the first .btlog or SQLite session);
    /// the fitted file is checked against it.
    #[arg(long, value_name = "TREE.xml")]
    tree: Option<PathBuf>,
    /// Key the entries by registration ID (all nodes of one ID pooled) or by node name.
    #[arg(long, value_enum, default_value = "id")]
    by: FitBy,
    /// Write the params file here (atomically) instead of standard output (- is standard output).
    #[arg(short, long, value_name = "PARAMS.yaml")]
    output: Option<PathBuf>,
    /// Timing families: `exponential` (the book's model; deterministic when every duration of
    /// each outcome is one time) or `auto` (per outcome deterministic, exponential, shifted
    /// exponential, Erlang-k, k ≤ 20, or hyperexponential-2 (EM), by BIC; needs 10 completed
    /// episodes of the outcome; writes the covariance of each leaf's parameters, `cov_theta`,
    /// which `--ci` draws).
    #[arg(long, value_enum, default_value = "exponential")]
    timing: FitTiming,
}

#[derive(Clone, Copy, clap::ValueEnum)]
enum FitTiming {
    Exponential,
    Auto,
}

const SENSITIVITY_EXAMPLES: &str = "\
Examples:
  btrel sensitivity trees/search-and-grasp.yaml
  btrel sensitivity trees/search-and-grasp.yaml --of success-by --deadline 100
  btrel sensitivity trees/search-and-grasp.yaml --of mttf --format json

For every leaf parameter (ps, mu, nu, tau_s, tau_f; the shift of a shifted `success_time` /
`failure_time` is its tau_s / tau_f; the rate of an Erlang-k time is success_rate /
failure_rate, a two-branch hyperexponential's are success_p, success_rate1, success_rate2 (and
failure_...); the rates of hypoexponential stages and the alpha, T of general phase-type laws
are held, not differentiated)
the derivative of the root's figure and
its elasticity d ln O / d ln θ, ranked by |elasticity|; the table ends with sentences for the
top entries (ps changed by 0.1, other parameters by 10%, the new figure computed again).
Derivatives: exact (dual numbers through Sequence, Fallback, flows, decorators, loops, the
P(S)/P(F) of Parallels with the book's thresholds, product phase chains and the count
quadrature of wide Parallels; success-by of a phase chain by uniformising the doubled chain);
otherwise (mixed-timing races and Parallels, --strategy book Parallels, Nav2 trees, success-by
of a tree with deterministic, hybrid or shifted times or a wide Parallel)
Richardson-extrapolated central differences through the engine (one-sided at ps = 0 or 1 and
at a time of 0), with an error estimate. Each row's method column (JSON: \"method\") says
which: exact or richardson. Changing an action's ps
changes pf = 1 - ps with it. Default objective: success-by with --deadline, else ps.";

#[derive(clap::Args)]
struct SensitivityArgs {
    /// The tree: YAML, or BehaviorTree.CPP v4 XML (.xml; actions' parameters from --params); - reads standard input.
    tree: PathBuf,
    /// The root's figure: ps, mtts, mttf, mean-time (ps·MTTS + pf·MTTF) or success-by
    /// (P(Success by --deadline)).
    #[arg(long, value_enum)]
    of: Option<OfArg>,
    /// Deadline T (s) of success-by.
    #[arg(long, value_name = "T", allow_hyphen_values = true)]
    deadline: Option<String>,
    /// Output format.
    #[arg(long, value_enum, default_value_t = FormatArg::Table)]
    format: FormatArg,
    /// Write to this file (atomically) instead of standard output (- is standard output).
    #[arg(short, long, value_name = "FILE")]
    output: Option<PathBuf>,
    /// exact (default) or book.
    #[arg(long, value_enum, default_value_t = MethodArg::Exact)]
    method: MethodArg,
    /// Largest chain (number of states) an exact analysis may build.
    #[arg(long, value_name = "N", default_value_t = DEFAULT_MAX_STATES)]
    max_states: usize,
}

#[derive(Clone, Copy, PartialEq, Eq, ValueEnum)]
enum OfArg {
    Ps,
    Mtts,
    Mttf,
    MeanTime,
    SuccessBy,
}

#[derive(Clone, Copy, PartialEq, Eq, ValueEnum)]
enum FitBy {
    Id,
    Name,
}

const MAN_EXAMPLES: &str = "\
Examples:
  btrel man | man -l -
  btrel man report -o btrel-report.1
  mkdir -p ~/.local/share/man/man1 && btrel man -o ~/.local/share/man/man1/btrel.1";

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
    /// More BehaviorTree.CPP XML for an XML tree: a file, or a folder whose .xml files are
    /// all read, holding the BehaviorTrees its SubTrees refer to and node models
    /// (<TreeNodesModel>). Repeatable.
    #[arg(long, value_name = "FILE|DIR", global = true)]
    include: Vec<PathBuf>,
}

#[derive(Clone, Copy, PartialEq, Eq, ValueEnum)]
enum InputFormat {
    Yaml,
    Xml,
}

/// How tree files are read (set once from the global options).
static INPUT: std::sync::OnceLock<(Option<InputFormat>, Option<PathBuf>, Vec<PathBuf>)> =
    std::sync::OnceLock::new();

#[derive(Subcommand)]
enum Command {
    /// Analyse a tree and print every node's ps, pf, MTTS, MTTF, mu and nu.
    #[command(after_help = REPORT_EXAMPLES)]
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
    /// How much the root's figure depends on each leaf parameter: derivatives and elasticities.
    #[command(after_help = SENSITIVITY_EXAMPLES)]
    Sensitivity(SensitivityArgs),
    /// Estimate the leaves' parameters from execution logs (.btlog, CSV) into a params file.
    #[command(after_help = FIT_EXAMPLES)]
    Fit(FitArgs),
    #[command(after_help = CHECK_EXAMPLES)]
    /// Validate a tree file, or gate it on requirements (`--require 'ps >= 0.95'`): exit 0 / 1.
    Check(CheckArgs),
    /// Print a shell completion script (bash, zsh, fish, elvish, powershell).
    #[command(after_help = COMPLETIONS_EXAMPLES)]
    Completions {
        /// The shell.
        shell: clap_complete::Shell,
    },
    /// Print the manual page (roff) of btrel or of one of its commands.
    #[command(after_help = MAN_EXAMPLES)]
    Man {
        /// The command whose page to print (default: btrel itself).
        command: Option<String>,
        /// Write to this file (atomically) instead of standard output (- is standard output).
        #[arg(short, long, value_name = "FILE")]
        output: Option<PathBuf>,
    },
}

#[derive(clap::Args)]
struct ReportArgs {
    /// The tree: YAML, or BehaviorTree.CPP v4 XML (.xml; actions' parameters from --params); - reads standard input.
    tree: PathBuf,
    /// exact: compose the actions' phase-type distributions exactly;
    /// book: the chapter's recursion (subtrees replaced by exponential actions).
    #[arg(long, value_enum, default_value_t = MethodArg::Exact)]
    method: MethodArg,
    /// Output format.
    #[arg(long, value_enum, default_value_t = FormatArg::Table)]
    format: FormatArg,
    /// Write to this file (atomically) instead of standard output (- is standard output).
    #[arg(short, long, value_name = "FILE")]
    output: Option<PathBuf>,
    /// Largest chain (number of states) an exact analysis may build.
    #[arg(long, value_name = "N", default_value_t = DEFAULT_MAX_STATES)]
    max_states: usize,
    /// Also simulate N runs per node and compare (Table 9.1 style).
    #[arg(long, value_name = "N")]
    mc: Option<String>,
    #[command(flatten)]
    sim: McArgs,
    #[command(flatten)]
    ci: CiArgs,
}

/// `--ci [LEVEL]` of `report` and `curve`, with its draws and seed.
#[derive(clap::Args)]
struct CiArgs {
    /// Also give LEVEL confidence intervals (default 0.95; 90 means 0.90) of every figure from the
    /// fitted parameters' sampling uncertainty (the `fit:` statistics `btrel fit` writes in the
    /// params file): a parametric bootstrap through the engine (ps ~ Beta, rates ~ Gamma; a leaf
    /// with halted episodes draws ps, mu, nu jointly from the fit's covariance; percentile
    /// intervals). Leaves without `fit:` statistics stay fixed (the output lists them).
    #[arg(long, value_name = "LEVEL", num_args = 0..=1, default_missing_value = "0.95")]
    ci: Option<String>,
    /// Bootstrap draws, with --ci (default 1000).
    #[arg(long, value_name = "N", requires = "ci")]
    ci_draws: Option<String>,
    /// Seed of the bootstrap draws, with --ci (decimal or 0x hex; default 0x5EEDC1); the intervals
    /// do not depend on the number of threads.
    #[arg(long, value_name = "S", allow_hyphen_values = true, requires = "ci")]
    ci_seed: Option<String>,
}

const CURVE_EXAMPLES: &str = "\
Examples:
  btrel curve trees/search-and-grasp.yaml --t-end 1000 --points 101
  btrel curve trees/search-and-grasp.yaml --times 10,100,1000 --method book
  btrel curve trees/search-and-grasp.yaml --node search --t-end 500 --dt 5 -o search.csv
  btrel curve trees/search-and-grasp.yaml --timing deterministic --t-end 1000 --points 1001
  btrel curve trees/search-and-grasp.xml --params trees/search-and-grasp.params.yaml --times 100
  btrel curve trees/search-and-grasp.xml --params docs/fit/search-and-grasp.fitted.params.yaml --times 60,120 --ci

Output: CSV with header node,t,success,failure,running; one row per node per time,
in the order of the requested times; numbers at full precision. --ci adds success_lo,
success_hi, failure_lo, failure_hi, running_lo, running_hi (parametric bootstrap of the
parameters fitted by btrel fit; leaves without fit: statistics are fixed, noted on stderr).";

#[derive(clap::Args)]
struct CurveArgs {
    /// The tree: YAML, or BehaviorTree.CPP v4 XML (.xml; actions' parameters from --params); - reads standard input.
    tree: PathBuf,
    /// Node to report, by name or path (repeatable); default: the root.
    #[arg(long = "node", value_name = "NAME")]
    nodes: Vec<String>,
    #[command(flatten)]
    grid: TimeArgs,
    /// exact (default): exact chain; book: the chapter's recursion.
    #[arg(long, value_enum, default_value_t = MethodArg::Exact)]
    method: MethodArg,
    /// as-given, or deterministic: every exponential time replaced by 1/rate (an Erlang,
    /// hypo-, hyperexponential, phase-type or shifted time by its mean).
    #[arg(long, value_enum, default_value_t = TimingArg::AsGiven)]
    timing: TimingArg,
    /// Also simulate N runs and add mc_success, mc_failure, mc_running columns.
    #[arg(long, value_name = "N")]
    mc: Option<String>,
    #[command(flatten)]
    sim: McArgs,
    #[command(flatten)]
    ci: CiArgs,
    /// Write to this file (atomically) instead of standard output (- is standard output).
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
  btrel compare trees/search-and-grasp.xml --params trees/search-and-grasp.params.yaml --node search

Without --node every Fallback is reordered (the product of their permutations).
Default objective: success-by with --deadline, else mean-time. Orderings are enumerated
exhaustively when that fits the budget (about 2 s of estimated work, or --max-candidates N);
beyond it, the exact ordering rule ps/E[T] (mean time; refined by a local search under a
Parallel) or a local search answers. The output says which search was used and whether the
best is proven optimal.";

#[derive(clap::Args)]
struct CompareArgs {
    /// The tree: YAML, or BehaviorTree.CPP v4 XML (.xml; actions' parameters from --params); - reads standard input.
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
    /// Largest chain (number of states) an exact analysis may build.
    #[arg(long, value_name = "N", default_value_t = DEFAULT_MAX_STATES)]
    max_states: usize,
    /// Write to this file (atomically) instead of standard output (- is standard output).
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
  btrel simulate trees/two-arm-parallel.xml --params trees/two-arm-parallel.params.yaml --runs 1e5
  btrel report trees/search-and-grasp.yaml --mc 1e6        # Table 9.1-style check
  btrel curve trees/search-and-grasp.yaml --t-end 1000 --mc 1e5
  btrel simulate trees/search-and-grasp.yaml --precision 0.01            # every probability ±0.01
  btrel simulate trees/search-and-grasp.yaml --precision 0.005 --time-precision 2 --confidence 0.99

--precision EPS runs until every probability (ps, pf, never, the curve's points) is within ±EPS:
Okamoto's (Chernoff–Hoeffding) bound, n = ceil(ln(2/δ)/(2·EPS²)) runs, δ = 1 − confidence, an
exact guarantee for any tree. --time-precision S runs until every MTTS and MTTF is within ±S
seconds: the Chow–Robbins fixed-width sequential rule (stop at the first check with m >= 30
durations and z·sqrt((s²+1/m)/m) <= S; coverage tends to the confidence as S shrinks). Each
interval has the confidence on its own (not all at once). The output gives the runs used and
every figure ± the half-width of its interval; a figure that could not reach its precision
within --max-runs (default 1e8) is named (warning, exit 0). Runs are made in chunks with one
seed each, merged and checked in order: the same seed gives the same runs and figures whatever
--threads is. A progress bar is shown on a terminal.

The same seed gives bit-identical output whatever --threads is (default seed 0x5EEDB7E1).
For a simulated curve as CSV use `btrel curve --mc N`. A run that reaches a loop whose child
can never return the outcome that ends it never returns (judged exactly, not by a horizon):
counted in a `never` column, running at every time point.";

const PLOT_EXAMPLES: &str = "\
Examples:
  btrel plot trees/search-and-grasp.yaml -o sg.svg --mc 1e5                 # Fig. 9.18
  btrel plot trees/search-and-grasp.yaml -o sg.png --mc 1e5                 # the same as PNG
  btrel plot trees/search-and-grasp.yaml -o nodes.svg --node search --node grasp
  btrel plot trees/search-and-grasp.yaml -o det.svg --timing both           # Fig. 9.20
  btrel plot trees/search-and-grasp.yaml -o order.svg --compare search --deadline 100   # Fig. 9.22
  btrel plot trees/search-and-grasp.xml --params trees/search-and-grasp.params.yaml -o - > sg.svg

--deadline and --top go with --compare, which draws the orderings with the times as given
(no --node, no --timing); --seed and --threads go with --mc.";

#[derive(Clone, Copy, ValueEnum)]
enum PlotTiming {
    AsGiven,
    Deterministic,
    Both,
}

#[derive(clap::Args)]
struct PlotArgs {
    /// The tree: YAML, or BehaviorTree.CPP v4 XML (.xml; actions' parameters from --params); - reads standard input.
    tree: PathBuf,
    /// The image to write (atomically): FILE.svg or FILE.png; - writes SVG (or
    /// --format png) to standard output.
    #[arg(short, long, value_name = "FILE.svg|FILE.png")]
    output: PathBuf,
    /// Image format; default: from the extension of -o (.svg or .png).
    #[arg(long, value_enum)]
    format: Option<ImageFormatArg>,
    /// Node to plot, by name or path (repeatable); default: the root.
    #[arg(long = "node", value_name = "NAME", conflicts_with = "compare")]
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
    sim: McArgs,
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
    #[arg(long, value_name = "K", default_value_t = 2, requires = "compare")]
    top: usize,
    /// exact (default) or book.
    #[arg(long, value_enum, default_value_t = MethodArg::Exact)]
    method: MethodArg,
    /// Largest chain (number of states) an exact analysis may build.
    #[arg(long, value_name = "N", default_value_t = DEFAULT_MAX_STATES)]
    max_states: usize,
}

const EXPORT_EXAMPLES: &str = "\
Examples:
  btrel export trees/search-and-grasp.yaml --to dot -o tree.dot && dot -Tsvg tree.dot -o tree.svg
  btrel export trees/search-and-grasp.yaml --to dot --mrg search -o search-mrg.dot
  btrel export trees/search-and-grasp.yaml --to prism -o sg.sm --properties sg.csl
  btrel export trees/two-arm-parallel.xml --params trees/two-arm-parallel.params.yaml --to dot -o -
  prism sg.sm sg.csl -const T=100 -prop success_by_T     # P(success by 100 s), weighted over the start
  btrel export trees/search-and-grasp.yaml --to prism-explicit -o sg --properties sg.csl
  prism -importmodel sg.all -ctmc sg.csl -const T=100    # sg.tra, sg.sta, sg.lab, sg.srew (large chains)
  btrel export trees/search-and-grasp.yaml --to drn -o sg.drn
  python3 scripts/storm_check.py sg.drn --times 100       # Storm (stormpy), weighted over the start

DOT uses the book's notation: Sequence ->, Fallback ?, Parallel =>, decorators <>.";

#[derive(Clone, Copy, ValueEnum)]
enum ExportFormat {
    Dot,
    Prism,
    PrismExplicit,
    Drn,
}

#[derive(clap::Args)]
struct ExportArgs {
    /// The tree: YAML, or BehaviorTree.CPP v4 XML (.xml; actions' parameters from --params); - reads standard input.
    tree: PathBuf,
    /// dot: the tree (or with --mrg a node's MRG); prism: a node's exact CTMC
    /// as a PRISM model; prism-explicit: the same as PRISM's explicit files
    /// BASE.tra/.sta/.lab/.srew (with -o BASE; for large chains); drn: the
    /// same in Storm's explicit DRN format.
    #[arg(long, value_enum)]
    to: ExportFormat,
    /// Draw this control node's marking reachability graph instead of the tree (DOT).
    #[arg(long, value_name = "NODE")]
    mrg: Option<String>,
    /// Node whose chain is exported to PRISM or Storm (default: the root).
    #[arg(long, value_name = "NAME")]
    node: Option<String>,
    /// Write the matching PRISM properties file here (with --to prism or prism-explicit).
    #[arg(long, value_name = "FILE")]
    properties: Option<PathBuf>,
    /// Method of the figures shown in DOT labels.
    #[arg(long, value_enum, default_value_t = MethodArg::Exact)]
    method: MethodArg,
    /// Largest chain (number of states) an exact analysis may build.
    #[arg(long, value_name = "N", default_value_t = DEFAULT_MAX_STATES)]
    max_states: usize,
    /// Write to this file (atomically) instead of standard output (- is
    /// standard output); with --to prism-explicit, the base name of the four
    /// files (required).
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
    /// Grid spacing (s): 0, D, 2D, ... up to T, and T itself when it is not a multiple of D.
    #[arg(long, value_name = "D", requires = "t_end", allow_hyphen_values = true)]
    dt: Option<String>,
}

/// Monte Carlo options of `simulate`.
#[derive(clap::Args)]
struct SimArgs {
    /// Seed of the random streams (decimal or 0x hex; default 0x5EEDB7E1).
    #[arg(long, value_name = "S", allow_hyphen_values = true)]
    seed: Option<String>,
    #[arg(long, value_name = "K", help = threads_help("Worker threads"))]
    threads: Option<usize>,
}

/// The Monte Carlo check of `report --mc`, `curve --mc` and `plot --mc`:
/// its options need `--mc`.
#[derive(clap::Args)]
struct McArgs {
    /// Seed of the simulation's random streams, with --mc (decimal or 0x hex; default 0x5EEDB7E1).
    #[arg(long, value_name = "S", allow_hyphen_values = true, requires = "mc")]
    seed: Option<String>,
    #[arg(long, value_name = "K", help = threads_help("Worker threads of the simulation, with --mc"), requires = "mc")]
    threads: Option<usize>,
}

impl McArgs {
    fn sim(&self) -> SimArgs {
        SimArgs {
            seed: self.seed.clone(),
            threads: self.threads,
        }
    }
}

/// `RAYON_NUM_THREADS`, which sizes rayon's global pool when set to a positive number.
fn rayon_env_threads() -> Option<usize> {
    std::env::var("RAYON_NUM_THREADS")
        .ok()
        .and_then(|v| v.trim().parse::<usize>().ok())
        .filter(|&n| n > 0)
}

/// The help of `--threads`, with the real default: the size of rayon's
/// global pool (`RAYON_NUM_THREADS`, else one thread per core), computed
/// without starting the pool.
fn threads_help(what: &str) -> String {
    let (n, why) = match rayon_env_threads() {
        Some(n) => (n, "from RAYON_NUM_THREADS"),
        None => (
            std::thread::available_parallelism().map_or(1, |n| n.get()),
            "one per core",
        ),
    };
    format!("{what} [default: {n}, {why}]; the result does not depend on it")
}

#[derive(clap::Args)]
struct SimulateArgs {
    /// The tree: YAML, or BehaviorTree.CPP v4 XML (.xml; actions' parameters from --params); - reads standard input.
    tree: PathBuf,
    /// Runs per node (e.g. 1000000 or 1e6).
    #[arg(long, value_name = "N", default_value = "1000000")]
    runs: String,
    /// Run until every probability (ps, pf, never, the curve's points) is within ±EPS, instead of
    /// --runs: Okamoto's pre-computed bound (exact for any tree).
    #[arg(
        long,
        value_name = "EPS",
        conflicts_with = "runs",
        allow_hyphen_values = true
    )]
    precision: Option<String>,
    /// Run until every MTTS and MTTF is within ±S seconds, instead of --runs: the Chow–Robbins
    /// sequential rule (asymptotically exact).
    #[arg(
        long,
        value_name = "S",
        conflicts_with = "runs",
        allow_hyphen_values = true
    )]
    time_precision: Option<String>,
    /// Confidence of each interval, with --precision or --time-precision (default 0.95).
    #[arg(long, value_name = "LEVEL")]
    confidence: Option<String>,
    /// Most runs per node, with --precision or --time-precision (default 1e8).
    #[arg(long, value_name = "N")]
    max_runs: Option<String>,
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
    /// Write to this file (atomically) instead of standard output (- is standard output).
    #[arg(short, long, value_name = "FILE")]
    output: Option<PathBuf>,
}

#[derive(clap::Args)]
struct CheckArgs {
    /// The tree: YAML, or BehaviorTree.CPP v4 XML (.xml; actions' parameters from --params); - reads standard input.
    tree: PathBuf,
    /// A requirement the tree must meet (repeatable): [NODE.]FIGURE OP NUMBER, e.g. 'ps >= 0.95',
    /// 'NavigateRecovery.mtts <= 90', 'success_by(120) >= 0.8'. FIGURE: ps, pf, never, mtts,
    /// mttf, success_by(T), failure_by(T); OP: >=, <=, >, <.
    #[arg(long = "require", value_name = "EXPR", allow_hyphen_values = true)]
    require: Vec<String>,
    /// Decide by Monte Carlo instead of the exact engine: Wald's SPRT for probabilities, a
    /// Chow–Robbins interval for mean times (see below); prints the decision and the runs used.
    #[arg(long, requires = "require")]
    mc: bool,
    /// With --mc: bound on failing a requirement that holds with margin (default 0.05).
    #[arg(long, value_name = "A", requires = "mc")]
    alpha: Option<String>,
    /// With --mc: bound on passing a requirement that fails by the margin (default 0.05).
    #[arg(long, value_name = "B", requires = "mc")]
    beta: Option<String>,
    /// With --mc: half-width δ of the indifference region θ ± δ of a probability (default 0.01).
    #[arg(long, value_name = "D", requires = "mc")]
    indifference: Option<String>,
    /// With --mc: half-width of the indifference region of a mean time, in s (default 1% of
    /// its threshold).
    #[arg(long, value_name = "S", requires = "mc")]
    time_indifference: Option<String>,
    /// With --mc: most runs per requirement (default 1e8); a test still undecided then fails.
    #[arg(long, value_name = "N", requires = "mc")]
    max_runs: Option<String>,
    /// With --mc: seed of the runs (decimal or 0x hex; default 0x5EEDB7E1).
    #[arg(long, value_name = "S", allow_hyphen_values = true, requires = "mc")]
    seed: Option<String>,
    #[arg(long, value_name = "K", help = threads_help("Worker threads of the simulation, with --mc"), requires = "mc")]
    threads: Option<usize>,
    /// Largest chain (number of states) an exact analysis may build.
    #[arg(long, value_name = "N", default_value_t = DEFAULT_MAX_STATES)]
    max_states: usize,
    /// Decide by the LEVEL interval (default 0.95; 90 means 0.90) from the fitted parameters'
    /// sampling uncertainty (the `fit:` statistics `btrel fit` writes in the params file; the
    /// parametric bootstrap of `report --ci`): its lower bound must meet a >= or >
    /// requirement, its upper bound a <= or <.
    #[arg(long, value_name = "LEVEL", num_args = 0..=1, default_missing_value = "0.95", requires = "require")]
    ci: Option<String>,
    /// Bootstrap draws, with --ci (default 1000).
    #[arg(long, value_name = "N", requires = "ci")]
    ci_draws: Option<String>,
    /// Seed of the bootstrap draws, with --ci (decimal or 0x hex; default 0x5EEDC1).
    #[arg(long, value_name = "S", allow_hyphen_values = true, requires = "ci")]
    ci_seed: Option<String>,
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

/// The command that was run, for advice that names only its own options.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Cmd {
    Report,
    Check,
    Curve,
    Compare,
    Plot,
    ExportDot,
    ExportPrism,
}

/// Joins alternatives: `a`, `a or b`, `a, b or c`.
fn or_list(items: &[String]) -> String {
    match items {
        [] => String::new(),
        [one] => one.clone(),
        [rest @ .., last] => format!("{} or {last}", rest.join(", ")),
    }
}

/// An analysis error with advice naming only the options of `cmd`.
fn analysis_failure(cmd: Cmd, method: Method) -> impl Fn(AnalysisError) -> Failure {
    move |e| {
        let exact = method == Method::Exact;
        let has_method = !matches!(cmd, Cmd::ExportPrism | Cmd::Check);
        let has_timing = matches!(cmd, Cmd::Curve | Cmd::Plot);
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
            AnalysisError::MixedTiming { .. } => {
                fixes.push(simulate);
                if has_timing {
                    fixes.push(
                        "`--timing deterministic` (every exponential time becomes 1/rate)"
                            .to_string(),
                    );
                }
            }
            AnalysisError::Stiff { .. } => {
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
            AnalysisError::RenewalInside { start, .. } => {
                if cmd == Cmd::Curve {
                    fixes.push(format!("`--node '{start}'` (its exact curve)"));
                }
                fixes.push(simulate);
            }
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
fn with_article(word: &str) -> String {
    let an = word.starts_with(['a', 'e', 'i', 'o', 'u']);
    format!("{} {word}", if an { "an" } else { "a" })
}

/// A comparison error with advice for `cmd` (compare, or plot --compare).
fn compare_failure(cmd: Cmd, method: Method) -> impl Fn(btrel::compare::CompareError) -> Failure {
    use btrel::compare::CompareError;
    move |e| {
        match e {
        CompareError::Analysis(a) => analysis_failure(cmd, method)(a),
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

pub fn main() -> ExitCode {
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) => {
            let _ = e.print();
            return ExitCode::from(if e.use_stderr() { 2 } else { 0 });
        }
    };
    let _ = INPUT.set((cli.input_format, cli.params.clone(), cli.include.clone()));
    let result = match cli.command {
        Command::Report(args) => report(args),
        Command::Check(args) => check(args),
        Command::Fit(args) => fit(args),
        Command::Sensitivity(args) => sensitivity(args),
        Command::Curve(args) => curve(args),
        Command::Compare(args) => compare(args),
        Command::Simulate(args) => simulate(args),
        Command::Export(args) => export(args),
        Command::Plot(args) => plot(args),
        Command::Completions { .. } | Command::Man { .. } if tree_options_given() => {
            Err(Failure::input(
                "--input-format, --params and --include go with a command that reads a tree: remove them",
            ))
        }
        Command::Completions { shell } => completions(shell),
        Command::Man { command, output } => man(command.as_deref(), output.as_deref()),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(f) => {
            eprintln!("error: {}", f.message);
            ExitCode::from(f.code)
        }
    }
}

/// The name standard input goes by in messages.
const STDIN_NAME: &str = "<stdin>";

/// Reads standard input (at most the parser's size limit, plus one byte so
/// that a larger input is recognised as such).
fn read_stdin() -> Result<Vec<u8>, Failure> {
    use std::io::Read;
    let limit = btrel::tree::ParseLimits::default().max_bytes as u64;
    let mut bytes = Vec::new();
    io::stdin()
        .lock()
        .take(limit + 1)
        .read_to_end(&mut bytes)
        .map_err(|e| Failure::input(format!("{STDIN_NAME}: cannot read standard input: {e}")))?;
    Ok(bytes)
}

fn load(path: &Path) -> Result<Tree, Failure> {
    load_keyed(path).map(|(tree, _)| tree)
}

/// An XML tree's params file: each node's key in it, and the file's text and name.
struct ParamsSource {
    keys: Vec<Option<String>>,
    text: String,
    name: String,
}

/// Reads a tree; for an XML tree also where its parameters came from.
fn load_keyed(path: &Path) -> Result<(Tree, Option<ParamsSource>), Failure> {
    let (format, params, include) = INPUT.get().cloned().unwrap_or((None, None, Vec::new()));
    let stdin = path == Path::new("-");
    let xml = match format {
        Some(f) => f == InputFormat::Xml,
        None => path
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("xml")),
    };
    if !xml {
        if params.is_some() {
            return Err(Failure::input(
                "--params goes with an XML tree (YAML trees carry their parameters): remove --params, or add --input-format xml",
            ));
        }
        if !include.is_empty() {
            return Err(Failure::input(
                "--include goes with an XML tree (a YAML tree is one file): remove --include",
            ));
        }
        if stdin {
            return btrel::tree::parse_bytes(read_stdin()?, STDIN_NAME)
                .map(|t| (t, None))
                .map_err(Failure::input);
        }
        return parse_file(path).map(|t| (t, None)).map_err(Failure::input);
    }
    if stdin {
        let Some(params) = params else {
            return Err(Failure::input(format!(
                "{STDIN_NAME}: an XML tree read from standard input needs its parameters file: give it with --params FILE"
            )));
        };
        let params_text = std::fs::read(&params).map_err(|e| {
            Failure::input(format!("{}: cannot read the file: {e}", params.display()))
        })?;
        let name = params.display().to_string();
        let params_text =
            btrel::tree::parse::text_from_bytes(params_text, &name).map_err(Failure::input)?;
        let xml_text = btrel::tree::parse::text_from_bytes(read_stdin()?, STDIN_NAME)
            .map_err(Failure::input)?;
        let keyed =
            btrel::tree::xml::parse_xml_str_keyed(&xml_text, STDIN_NAME, &params_text, &name)
                .map_err(Failure::input)?;
        return Ok((
            keyed.tree,
            Some(ParamsSource {
                keys: keyed.keys,
                text: params_text,
                name,
            }),
        ));
    }
    let params = params.unwrap_or_else(|| path.with_extension("params.yaml"));
    if !params.exists() {
        return Err(Failure::input(format!(
            "{}: an XML tree needs a parameters file; {} does not exist (give one with --params)",
            path.display(),
            params.display()
        )));
    }
    for inc in &include {
        if !inc.exists() {
            return Err(Failure::input(format!(
                "{}: --include {} does not exist",
                path.display(),
                inc.display()
            )));
        }
    }
    let keyed = btrel::tree::xml::parse_xml_files_keyed(path, &params, &include).map_err(|mut e| {
        if e.message.contains("for this SubTree") {
            let h = e.help.take().unwrap_or_default();
            e.help = Some(format!(
                "{h}{}pass the file that defines it with --include FILE (or a folder: --include DIR)",
                if h.is_empty() { "" } else { "; " }
            ));
        }
        if btrel::tree::xml::is_unsupported(&e) {
            Failure::analysis(e)
        } else {
            Failure::input(e)
        }
    })?;
    let name = params.display().to_string();
    let text = std::fs::read(&params)
        .map_err(|e| Failure::input(format!("{name}: cannot read the file: {e}")))?;
    let text = btrel::tree::parse::text_from_bytes(text, &name).map_err(Failure::input)?;
    Ok((
        keyed.tree,
        Some(ParamsSource {
            keys: keyed.keys,
            text,
            name,
        }),
    ))
}

/// `--ci` parsed: level, draws, seed.
struct CiSettings {
    level: f64,
    draws: usize,
    seed: u64,
}

/// The settings of `--ci`, `None` without it.
fn ci_settings(args: &CiArgs) -> Result<Option<CiSettings>, Failure> {
    let Some(level) = args.ci.as_deref() else {
        return Ok(None);
    };
    let bad = || {
        Failure::input(format!(
            "--ci: '{level}' is not a confidence level (a number in (0, 1) such as 0.95, or a \
             percentage from 50 to 99.9 such as 90; the tree comes before --ci)"
        ))
    };
    let mut x: f64 = level
        .trim()
        .trim_end_matches('%')
        .parse()
        .map_err(|_| bad())?;
    if (50.0..100.0).contains(&x) {
        x /= 100.0;
    }
    if !(x > 0.0 && x < 1.0) {
        return Err(bad());
    }
    let draws = match args.ci_draws.as_deref() {
        None => btrel::uncertainty::DEFAULT_DRAWS as u64,
        Some(n) => parse_count("--ci-draws", n)?,
    };
    if !(2..=1_000_000).contains(&draws) {
        return Err(Failure::input("--ci-draws must be between 2 and 1000000"));
    }
    let seed = match args.ci_seed.as_deref() {
        None => btrel::uncertainty::DEFAULT_SEED,
        Some(s) => parse_seed("--ci-seed", s)?,
    };
    Ok(Some(CiSettings {
        level: x,
        draws: draws as usize,
        seed,
    }))
}

/// The sampler of `--ci`: the params file's `fit:` statistics by node.
/// Refuses a tree in which nothing would vary.
fn ci_sampler(
    tree: &Tree,
    source: Option<&ParamsSource>,
    ci: &CiSettings,
    values_per_draw: usize,
) -> Result<btrel::uncertainty::Sampler, Failure> {
    let Some(src) = source else {
        return Err(Failure::input(
            "--ci needs fitted parameters: an XML tree with a params file written by `btrel fit` \
             (its `fit:` statistics give the parameters' uncertainty); a YAML tree has none",
        ));
    };
    let stats = btrel::uncertainty::read_fit_stats(&src.text, &src.name).map_err(Failure::input)?;
    let sampler = btrel::uncertainty::Sampler::new(tree, &src.keys, &stats);
    if sampler.varied() == 0 {
        return Err(Failure::input(format!(
            "--ci: no parameter of this tree has `fit:` statistics in {} (write the file with \
             `btrel fit LOG... -o {}`), so there is no uncertainty to propagate",
            src.name, src.name
        )));
    }
    let values_per_draw = values_per_draw + sampler.kept_per_draw();
    if ci.draws.saturating_mul(values_per_draw) > btrel::uncertainty::MAX_VALUES {
        return Err(Failure::analysis(format!(
            "--ci: {} draws of {values_per_draw} figures exceed the limit of {} values; lower \
             --ci-draws",
            ci.draws,
            btrel::uncertainty::MAX_VALUES
        )));
    }
    Ok(sampler)
}

/// The notes of `--ci` on standard error: the intervals' level, draws, seed
/// and method, then the parameters held fixed and how the sampler drew the
/// others.
fn ci_notes(ci: &CiSettings, sampler: &btrel::uncertainty::Sampler) {
    eprintln!(
        "note: {} intervals from {} draws (seed {}): {}",
        btrel::report::intervals::percent(ci.level),
        ci.draws,
        ci.seed,
        btrel::uncertainty::METHOD
    );
    if !sampler.fixed.is_empty() {
        eprintln!(
            "note: fixed (no `fit:` statistics in the params file): {}",
            sampler.fixed.join(", ")
        );
    }
    for h in sampler.held.iter().chain(&sampler.independent) {
        eprintln!("note: {h}");
    }
}

fn completions(shell: clap_complete::Shell) -> Result<(), Failure> {
    use clap::CommandFactory;
    let mut cmd = Cli::command();
    emit(None, |out| {
        clap_complete::generate(shell, &mut cmd, "btrel", out);
        Ok(())
    })
}

fn man(command: Option<&str>, output: Option<&Path>) -> Result<(), Failure> {
    use clap::CommandFactory;
    let mut root = Cli::command();
    root.build();
    let page = match command {
        None => root,
        Some(name) => {
            let names: Vec<String> = root
                .get_subcommands()
                .map(|c| c.get_name().to_string())
                .collect();
            let sub = root.find_subcommand(name).cloned().ok_or_else(|| {
                Failure::input(format!(
                    "no command '{name}'; the commands are: {}",
                    names.join(", ")
                ))
            })?;
            sub.name(format!("btrel-{name}"))
        }
    };
    let mut text = Vec::new();
    clap_mangen::Man::new(page)
        .render(&mut text)
        .map_err(|e| Failure::analysis(format!("cannot render the manual page: {e}")))?;
    emit(output, |out| out.write_all(&text))
}

/// Whether any of the tree-input options (`--input-format`, `--params`,
/// `--include`) was given.
fn tree_options_given() -> bool {
    INPUT
        .get()
        .is_some_and(|(f, p, i)| f.is_some() || p.is_some() || !i.is_empty())
}

fn fit(args: FitArgs) -> Result<(), Failure> {
    let (format, params, include) = INPUT.get().cloned().unwrap_or((None, None, Vec::new()));
    if params.is_some() {
        return Err(Failure::input(
            "fit writes a params file, it reads none: remove --params (write with -o FILE)",
        ));
    }
    if format.is_some() {
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
            logs.extend(btrel::logs::read_logs(path).map_err(Failure::input)?);
            continue;
        }
        let Some(tree) = &args.tree else {
            return Err(Failure::input(format!(
                "{}: a rosbag2 recording: Nav2's behavior_tree_log carries no tree, give the tree \
                 bt_navigator ran with --tree TREE.xml",
                path.display()
            )));
        };
        let bag = btrel::logs::rosbag::read(path, tree, &include, args.topic.as_deref())
            .map_err(Failure::input)?;
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
    let by = match args.by {
        FitBy::Id => btrel::fit::By::Id,
        FitBy::Name => btrel::fit::By::Name,
    };
    let mode = match args.timing {
        FitTiming::Exponential => btrel::fit::TimingMode::Exponential,
        FitTiming::Auto => btrel::fit::TimingMode::Auto,
    };
    let fitted = btrel::fit::fit_logs_with(&logs, by, mode)
        .map_err(|e| Failure::input(format!("{e}; key by ID instead with --by id")))?;
    for l in &fitted.leaves {
        for w in &l.warnings {
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
                    btrel::tree::xml::parse_xml_files(tree, &dir, &include).map_err(|mut e| {
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

fn sensitivity(args: SensitivityArgs) -> Result<(), Failure> {
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
    let tree = load(&args.tree)?;
    let options = Options {
        method: method(args.method),
        max_states: args.max_states,
    };
    let fail = |e: SensitivityError| match e {
        SensitivityError::Analysis(e) => analysis_failure(Cmd::Report, options.method)(e),
        SensitivityError::Undefined(m) => {
            Failure::analysis(format!("{m}: choose another objective with --of"))
        }
    };
    let s = btrel::sensitivity::sensitivity(&tree, objective, &options).map_err(fail)?;
    // the laws whose parameters have no rows: say so
    let held: Vec<String> = tree
        .nodes
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

fn check(args: CheckArgs) -> Result<(), Failure> {
    if !args.require.is_empty() {
        return check_requirements(args);
    }
    let path = args.tree.as_path();
    let tree = load(path)?;
    warn_endless(&tree);
    emit(None, |out| {
        writeln!(
            out,
            "{}: ok ({}, {})",
            display_path(path),
            plural(tree.nodes.len(), "node", "nodes"),
            plural(tree.leaf_count(), "leaf", "leaves")
        )
    })
}

/// Most "can run forever" warnings printed (the rest are counted).
const ENDLESS_WARNINGS: usize = 3;

/// Warns (standard error) about the loops of `tree` that never return when
/// they run ([`btrel::sim::endless_loops`]): where P(never returns) > 0
/// comes from.
fn warn_endless(tree: &Tree) {
    let endless = btrel::sim::endless_loops(tree);
    for (_, why) in endless.iter().take(ENDLESS_WARNINGS) {
        eprintln!("warning: {why}");
    }
    if endless.len() > ENDLESS_WARNINGS {
        eprintln!(
            "warning: and {} more such nodes (copies made by RecoveryNode, RetryUntilSuccessful, \
             SubTrees): runs that reach one never return",
            endless.len() - ENDLESS_WARNINGS
        );
    }
    if endless.iter().any(|(_, why)| why.contains("restart loop")) {
        eprintln!(
            "  help: an action that returns within its tick (e.g. Nav2's synchronous \
             TruncatePathLocal) is never restarted: give it `tau_s: 0` (and `tau_f: 0`) in the \
             params file"
        );
    }
}

/// `n thing` / `n things`.
fn plural(n: usize, one: &str, many: &str) -> String {
    format!("{n} {}", if n == 1 { one } else { many })
}

/// A TREE argument as messages name it.
fn display_path(path: &Path) -> String {
    if path == Path::new("-") {
        STDIN_NAME.to_string()
    } else {
        path.display().to_string()
    }
}

fn report(args: ReportArgs) -> Result<(), Failure> {
    let ci = ci_settings(&args.ci)?;
    if ci.is_some() && args.mc.is_some() {
        return Err(Failure::input(
            "--ci and --mc make two different tables: run the report once with each",
        ));
    }
    let (tree, source) = load_keyed(&args.tree)?;
    warn_endless(&tree);
    let options = Options {
        method: method(args.method),
        max_states: args.max_states,
    };
    let mc = optional_count("--mc", &args.mc)?;
    let sim = mc
        .map(|runs| sim_options(&args.sim.sim(), runs, Vec::new(), true))
        .transpose()?;
    let analysis =
        analyze(&tree, &options).map_err(analysis_failure(Cmd::Report, options.method))?;
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
    if let Some(ci) = &ci {
        use btrel::report::intervals;
        let sampler = ci_sampler(&tree, source.as_ref(), ci, 4 * tree.nodes.len())?;
        let flat = sampler
            .intervals(ci.level, ci.draws, ci.seed, |t| {
                analyze(t, &options).map(|a| {
                    a.nodes
                        .iter()
                        .flat_map(|f| [Some(f.ps), Some(f.pf), f.mtts, f.mttf])
                        .collect()
                })
            })
            .map_err(analysis_failure(Cmd::Report, options.method))?;
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
    if end <= 0.0 {
        return Err(Failure::input(
            "--t-end must be > 0 (for the time 0 alone use --times 0)",
        ));
    }
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
        // 0, D, 2D, ... up to T, and T itself when it is not on the grid
        let mut times: Vec<f64> = (0..count as usize)
            .map(|k| (k as f64 * dt).min(end))
            .collect();
        if times.last().is_some_and(|&last| last < end * (1.0 - 1e-12)) {
            times.push(end);
        }
        return Ok(Some(times));
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

/// A seed: decimal or 0x hex, `_` allowed.
fn parse_seed(what: &str, s: &str) -> Result<u64, Failure> {
    let t = s.trim();
    let parsed = match t.strip_prefix("0x").or_else(|| t.strip_prefix("0X")) {
        Some(hex) => u64::from_str_radix(&hex.replace('_', ""), 16),
        None => t.replace('_', "").parse::<u64>(),
    };
    parsed.map_err(|_| {
        Failure::input(format!(
            "{what}: '{s}' is not a seed (a whole number from 0 to 2^64-1, decimal or 0x hex)"
        ))
    })
}

fn sim_options(
    args: &SimArgs,
    runs: u64,
    times: Vec<f64>,
    per_node: bool,
) -> Result<btrel::sim::SimOptions, Failure> {
    let seed = match args.seed.as_deref() {
        None => btrel::sim::DEFAULT_SEED,
        Some(s) => parse_seed("--seed", s)?,
    };
    Ok(btrel::sim::SimOptions {
        runs,
        seed,
        threads: args.threads.unwrap_or(0),
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
    if args.precision.is_some() || args.time_precision.is_some() {
        return simulate_precision(args);
    }
    for (given, name) in [
        (args.confidence.is_some(), "--confidence"),
        (args.max_runs.is_some(), "--max-runs"),
    ] {
        if given {
            return Err(Failure::input(format!(
                "{name} goes with --precision EPS or --time-precision S (runs until the figures \
                 are that precise): add one, or remove {name}"
            )));
        }
    }
    let runs = parse_count("--runs", &args.runs)?;
    let times = grid_times(&args.grid)?.unwrap_or_default();
    if matches!(args.format, FormatArg::Csv) && !times.is_empty() {
        return Err(Failure::input(
            "--format csv prints the per-node figures; for a simulated curve as CSV use `btrel curve --mc N`",
        ));
    }
    let options = sim_options(&args.sim, runs, times, true)?;
    let tree = load(&args.tree)?;
    warn_endless(&tree);
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

/// A spinner with the elapsed time on standard error (a terminal only),
/// shown once the work it watches has taken more than a second: a curve of
/// a large mixed-timing tree can take minutes, with nothing else to show.
struct Spinner(Option<indicatif::ProgressBar>);

impl Spinner {
    fn start(message: String) -> Spinner {
        use std::io::IsTerminal;
        if !io::stderr().is_terminal() {
            return Spinner(None);
        }
        let bar = indicatif::ProgressBar::hidden();
        bar.set_style(
            indicatif::ProgressStyle::with_template(
                "{spinner} {msg} ({elapsed}; `btrel simulate` estimates it in seconds)",
            )
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_spinner()),
        );
        bar.set_message(message);
        let watch = bar.clone();
        std::thread::spawn(move || {
            std::thread::sleep(std::time::Duration::from_secs(1));
            if !watch.is_finished() {
                watch.set_draw_target(indicatif::ProgressDrawTarget::stderr());
                watch.enable_steady_tick(std::time::Duration::from_millis(200));
            }
        });
        Spinner(Some(bar))
    }
}

impl Drop for Spinner {
    fn drop(&mut self) {
        if let Some(bar) = &self.0 {
            bar.finish_and_clear();
        }
    }
}

fn curve(args: CurveArgs) -> Result<(), Failure> {
    if matches!(args.timing, TimingArg::Deterministic) && matches!(args.method, MethodArg::Book) {
        return Err(Failure::input(
            "--timing deterministic cannot be combined with --method book (the book's chain makes every time exponential again): use --method exact",
        ));
    }
    let times = requested_times(&args)?;
    let ci = ci_settings(&args.ci)?;
    let (tree, source) = load_keyed(&args.tree)?;
    warn_endless(&tree);
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
        .map(|runs| sim_options(&args.sim.sim(), runs, times.clone(), false))
        .transpose()?;
    let mut curves = Vec::with_capacity(nodes.len());
    for &id in &nodes {
        let spinner = Spinner::start(format!("computing π(t) of '{}'", tree.node(id).name));
        let points = btrel::curve::curve(&tree, id, &times, &options)
            .map_err(analysis_failure(Cmd::Curve, options.method))?;
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
                    for &id in &nodes {
                        for p in btrel::curve::curve(t, id, &times, &options)? {
                            v.extend([Some(p.success), Some(p.failure), Some(p.running)]);
                        }
                    }
                    Ok(v)
                })
                .map_err(analysis_failure(Cmd::Curve, options.method))?;
            ci_notes(ci, &sampler);
            Some(flat)
        }
    };
    emit(args.output.as_deref(), |out| {
        let mut row = 0;
        write!(out, "node,t,success,failure,running")?;
        if bands.is_some() {
            write!(
                out,
                ",success_lo,success_hi,failure_lo,failure_hi,running_lo,running_hi"
            )?;
        }
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
                if let Some(b) = &bands {
                    for i in &b[3 * row..3 * row + 3] {
                        match i {
                            Some((lo, hi)) => write!(out, ",{},{}", full(*lo), full(*hi))?,
                            None => write!(out, ",,")?,
                        }
                    }
                }
                row += 1;
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
    // standard output: SVG unless --format says otherwise
    if path == Path::new("-") {
        return Ok(ImageFormat::Svg);
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
    if args.compare.is_some() && !matches!(args.timing, PlotTiming::AsGiven) {
        return Err(Failure::input(
            "--timing deterministic/both cannot be combined with --compare (the orderings are drawn with the times as given): drop one of them",
        ));
    }
    let t_end = optional_time("--t-end", &args.t_end)?;
    let deadline = optional_time("--deadline", &args.deadline)?;
    let mc = optional_count("--mc", &args.mc)?;
    let format = image_format(&args.output, args.format)?;
    let tree = load(&args.tree)?;
    warn_endless(&tree);
    let nodes = if args.nodes.is_empty() {
        vec![Tree::ROOT]
    } else {
        find_nodes(&tree, &args.nodes, &args.tree)?
    };
    let base = CurveOptions {
        method: method(args.method),
        max_states: args.max_states,
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
                max_states: args.max_states,
                keep: args.top,
                ..btrel::compare::CompareOptions::default()
            },
        )
        .map_err(compare_failure(Cmd::Plot, base.method))?;
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
        let spinner = Spinner::start(format!("computing π(t) of '{}'", t.node(*id).name));
        let computed = btrel::curve::curve(t, *id, &times, &options);
        drop(spinner);
        match computed {
            Ok(points) => {
                exact_drawn = true;
                series.extend(curve_series(label, &points, *style))
            }
            Err(e) if mc.is_some() => eprintln!(
                "note: no exact curves for '{}' ({e}); plotting the simulation only",
                t.node(*id).name
            ),
            Err(e) => {
                let mut f = analysis_failure(Cmd::Plot, base.method)(e);
                f.message = format!(
                    "cannot plot the exact curves of '{}': {}",
                    t.node(*id).name,
                    f.message
                );
                return Err(f);
            }
        }
    }
    if let Some(runs) = mc {
        let mc_times: Vec<f64> = (0..41).map(|k| end * k as f64 / 40.0).collect();
        let o = sim_options(&args.sim.sim(), runs, mc_times, false)?;
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
    let tree_title = btrel::report::title(&tree);
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
    emit(Some(&args.output), |out| out.write_all(&bytes))
}

fn export(args: ExportArgs) -> Result<(), Failure> {
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
    let chain = |id| {
        btrel::compile::phase::phase_chain(&tree, id, args.max_states).map_err(Failure::analysis)
    };
    let what = |id: usize| {
        let n = tree.node(id);
        format!("node '{}' ({})", n.name, n.kind.keyword())
    };
    let text = match args.to {
        ExportFormat::Dot => {
            let analysis = analyze(&tree, &options);
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
                        let f = analysis_failure(Cmd::ExportDot, options.method)(e);
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
                .map(|_| btrel::export::prism_explicit_properties(&chain));
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
                let all: Vec<&str> = tree.nodes.iter().map(|x| x.name.as_str()).collect();
                let hint = match btrel::tree::error::nearest(n, &all) {
                    Some(near) => format!("did you mean '{near}'?"),
                    None if all.len() <= 12 => {
                        format!("give one of {}, or a path such as 0.1", all.join(", "))
                    }
                    None => "give a node name, or a path such as 0.1 (`btrel report --format csv` lists both)"
                        .to_string(),
                };
                Failure::input(format!(
                    "no node named '{n}' in {}; {hint}",
                    display_path(file)
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
    let cmp = result.map_err(compare_failure(Cmd::Compare, options.method))?;
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
                .map_err(analysis_failure(Cmd::Compare, options.method))?;
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
    match path.filter(|p| *p != Path::new("-")) {
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

/// A probability-like option in (0, 1): `0.95`, or a percentage `95`.
fn parse_level(what: &str, s: &str) -> Result<f64, Failure> {
    let bad = || {
        Failure::input(format!(
            "{what}: '{s}' is not a level (a number in (0, 1) such as 0.95, or a percentage from \
             50 to 99.99 such as 95)"
        ))
    };
    let mut x: f64 = s.trim().trim_end_matches('%').parse().map_err(|_| bad())?;
    if (50.0..100.0).contains(&x) {
        x /= 100.0;
    }
    if !(x > 0.0 && x < 1.0) {
        return Err(bad());
    }
    Ok(x)
}

/// A positive finite number option.
fn parse_positive(what: &str, s: &str) -> Result<f64, Failure> {
    match s.trim().parse::<f64>() {
        Ok(x) if x.is_finite() && x > 0.0 => Ok(x),
        _ => Err(Failure::input(format!("{what}: '{s}' is not a number > 0"))),
    }
}

/// `simulate --precision / --time-precision`: runs until the figures are
/// that precise ([`btrel::sim::sequential`]).
fn simulate_precision(args: SimulateArgs) -> Result<(), Failure> {
    use btrel::report::sequential as out_seq;
    use btrel::sim::sequential::{simulate_to_precision, Precision, Progress, DEFAULT_MAX_RUNS};
    use std::io::IsTerminal;
    let probability = args
        .precision
        .as_deref()
        .map(|s| parse_positive("--precision", s))
        .transpose()?;
    if let Some(p) = probability.filter(|&p| p >= 0.5) {
        return Err(Failure::input(format!(
            "--precision {p}: a probability's half-width must be below 0.5 (e.g. 0.01)"
        )));
    }
    let time = args
        .time_precision
        .as_deref()
        .map(|s| parse_positive("--time-precision", s))
        .transpose()?;
    let confidence = match args.confidence.as_deref() {
        None => 0.95,
        Some(c) => parse_level("--confidence", c)?,
    };
    let max_runs = match args.max_runs.as_deref() {
        None => DEFAULT_MAX_RUNS,
        Some(n) => parse_count("--max-runs", n)?,
    };
    if max_runs == 0 || max_runs > btrel::sim::MAX_RUNS {
        return Err(Failure::input(format!(
            "--max-runs must be between 1 and {} (10^12)",
            btrel::sim::MAX_RUNS
        )));
    }
    let times = grid_times(&args.grid)?.unwrap_or_default();
    if matches!(args.format, FormatArg::Csv) && !times.is_empty() {
        return Err(Failure::input(
            "--format csv prints the per-node figures; for the curve with intervals use --format table or json",
        ));
    }
    let base = sim_options(&args.sim, 1, times, true)?;
    let tree = load(&args.tree)?;
    warn_endless(&tree);
    let node = match &args.node {
        Some(n) => find_nodes(&tree, std::slice::from_ref(n), &args.tree)?[0],
        None => Tree::ROOT,
    };
    let precision = Precision {
        probability,
        time,
        confidence,
        max_runs,
    };
    let bar = io::stderr().is_terminal().then(|| {
        let b = indicatif::ProgressBar::new(1);
        b.set_style(
            indicatif::ProgressStyle::with_template(
                "simulating to a precision {bar:40} {pos}/{len} runs (estimated; {elapsed})",
            )
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
        );
        b
    });
    let callback = |p: &Progress| {
        if let Some(b) = &bar {
            b.set_length(p.needed.max(p.runs));
            b.set_position(p.runs);
        }
    };
    let result = simulate_to_precision(
        &tree,
        node,
        &base,
        &precision,
        bar.as_ref()
            .map(|_| &callback as &(dyn Fn(&Progress) + Sync)),
    );
    if let Some(b) = bar {
        b.finish_and_clear();
    }
    let result = result.map_err(Failure::input)?;
    let missed = out_seq::missed_phrases(&tree, &result);
    if !missed.is_empty() {
        eprintln!(
            "warning: stopped at --max-runs {} before every figure reached its precision: {}",
            result.sim.runs,
            missed.join(", ")
        );
    }
    emit(args.output.as_deref(), |out| match args.format {
        FormatArg::Table => out_seq::write_table(&tree, &result, out),
        FormatArg::Json => out_seq::write_json(&tree, &result, out),
        FormatArg::Csv => out_seq::write_csv(&tree, &result, out),
    })
}

/// `check --require`: every requirement decided, one line each; exit 1 when
/// one fails.
fn check_requirements(args: CheckArgs) -> Result<(), Failure> {
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
    let (tree, source) = load_keyed(&args.tree)?;
    warn_endless(&tree);
    let reqs = args
        .require
        .iter()
        .map(|text| gate::parse(text, &tree))
        .collect::<Result<Vec<_>, _>>()
        .map_err(|e| {
            let text = e.to_string();
            Failure::input(format!(
                "--require{}",
                text.strip_prefix("requirement").unwrap_or(&text)
            ))
        })?;
    if let Some(s) = &mc_settings {
        for r in &reqs {
            s.validate(r).map_err(|e| {
                let help = match e {
                    gate::TestError::Region { .. } => {
                        "\n  help: a smaller --indifference, or decide it exactly (without --mc)"
                    }
                    _ => "",
                };
                Failure::input(format!("{e}{help}"))
            })?;
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
            .map_err(analysis_failure(Cmd::Check, options.method))?;
        let bounds = match &ci {
            None => None,
            Some(ci) => {
                let sampler = ci_sampler(&tree, source.as_ref(), ci, reqs.len())?;
                let b = sampler
                    .intervals(ci.level, ci.draws, ci.seed, |t| {
                        gate::exact_values(t, &reqs, &options)
                    })
                    .map_err(analysis_failure(Cmd::Check, options.method))?;
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
