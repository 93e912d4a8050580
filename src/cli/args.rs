//! The command line's clap definitions: the commands, their arguments and
//! their help texts. Values stay as given here; [`super::options`] parses
//! and validates them.
//!
//! The longest module of the CLI (close to 800 lines): the help texts
//! (examples, the meaning of each option) belong with the definitions they
//! document.

use std::path::PathBuf;

use clap::{Parser, Subcommand, ValueEnum};

use btrel::compile::DEFAULT_MAX_STATES;

pub(super) const EXAMPLES: &str = "\
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

pub(super) const REPORT_EXAMPLES: &str = "\
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

pub(super) const CHECK_EXAMPLES: &str = "\
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

pub(super) const COMPLETIONS_EXAMPLES: &str = "\
Examples:
  btrel completions bash > ~/.local/share/bash-completion/completions/btrel
  btrel completions zsh > ~/.zfunc/_btrel        # with fpath+=~/.zfunc before compinit
  btrel completions fish > ~/.config/fish/completions/btrel.fish";

pub(super) const FIT_EXAMPLES: &str = "\
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
pub(super) struct FitArgs {
    /// The logs: .btlog (BT.CPP FileLogger2), .db3 (BT.CPP SqliteLogger) or CSV files, or rosbag2
    /// recordings of Nav2's behavior_tree_log (a bag folder, or its .mcap / .db3 files; need --tree);
    /// episodes of all are pooled.
    #[arg(required = true, value_name = "LOG")]
    pub(super) logs: Vec<PathBuf>,
    /// The topic of Nav2's behavior tree log in rosbag2 recordings (default: the one topic of type
    /// nav2_msgs/msg/BehaviorTreeLog, in any namespace).
    #[arg(long, value_name = "TOPIC")]
    pub(super) topic: Option<String>,
    /// The XML tree the params file is for (default: the tree in the first .btlog or SQLite session);
    /// the fitted file is checked against it.
    #[arg(long, value_name = "TREE.xml")]
    pub(super) tree: Option<PathBuf>,
    /// Key the entries by registration ID (all nodes of one ID pooled) or by node name.
    #[arg(long, value_enum, default_value = "id")]
    pub(super) by: FitBy,
    /// Write the params file here (atomically) instead of standard output (- is standard output).
    #[arg(short, long, value_name = "PARAMS.yaml")]
    pub(super) output: Option<PathBuf>,
    /// Timing families: `exponential` (the book's model; deterministic when every duration of
    /// each outcome is one time) or `auto` (per outcome deterministic, exponential, shifted
    /// exponential, Erlang-k, k ≤ 20, or hyperexponential-2 (EM), by BIC; needs 10 completed
    /// episodes of the outcome; writes the covariance of each leaf's parameters, `cov_theta`,
    /// which `--ci` draws).
    #[arg(long, value_enum, default_value = "exponential")]
    pub(super) timing: FitTiming,
}

#[derive(Clone, Copy, clap::ValueEnum)]
pub(super) enum FitTiming {
    Exponential,
    Auto,
}

pub(super) const SENSITIVITY_EXAMPLES: &str = "\
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
pub(super) struct SensitivityArgs {
    /// The tree: YAML, or BehaviorTree.CPP v4 XML (.xml; actions' parameters from --params); - reads standard input.
    pub(super) tree: PathBuf,
    /// The root's figure: ps, mtts, mttf, mean-time (ps·MTTS + pf·MTTF) or success-by
    /// (P(Success by --deadline)).
    #[arg(long, value_enum)]
    pub(super) of: Option<OfArg>,
    /// Deadline T (s) of success-by.
    #[arg(long, value_name = "T", allow_hyphen_values = true)]
    pub(super) deadline: Option<String>,
    /// Output format.
    #[arg(long, value_enum, default_value_t = FormatArg::Table)]
    pub(super) format: FormatArg,
    /// Write to this file (atomically) instead of standard output (- is standard output).
    #[arg(short, long, value_name = "FILE")]
    pub(super) output: Option<PathBuf>,
    /// exact (default) or book.
    #[arg(long, value_enum, default_value_t = MethodArg::Exact)]
    pub(super) method: MethodArg,
    /// Largest chain (number of states) an exact analysis may build.
    #[arg(long, value_name = "N", default_value_t = DEFAULT_MAX_STATES)]
    pub(super) max_states: usize,
}

#[derive(Clone, Copy, PartialEq, Eq, ValueEnum)]
pub(super) enum OfArg {
    Ps,
    Mtts,
    Mttf,
    MeanTime,
    SuccessBy,
}

#[derive(Clone, Copy, PartialEq, Eq, ValueEnum)]
pub(super) enum FitBy {
    Id,
    Name,
}

pub(super) const MAN_EXAMPLES: &str = "\
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
pub(super) struct Cli {
    #[command(subcommand)]
    pub(super) command: Command,
    /// Input format of TREE (default: by extension, .xml is BehaviorTree.CPP v4 XML).
    #[arg(long, value_enum, global = true)]
    pub(super) input_format: Option<InputFormat>,
    /// Parameters of an XML tree's actions and conditions (YAML; default: TREE with
    /// the extension .params.yaml).
    #[arg(long, value_name = "PARAMS.yaml", global = true)]
    pub(super) params: Option<PathBuf>,
    /// More BehaviorTree.CPP XML for an XML tree: a file, or a folder whose .xml files are
    /// all read, holding the BehaviorTrees its SubTrees refer to and node models
    /// (<TreeNodesModel>). Repeatable.
    #[arg(long, value_name = "FILE|DIR", global = true)]
    pub(super) include: Vec<PathBuf>,
}

#[derive(Clone, Copy, PartialEq, Eq, ValueEnum)]
pub(super) enum InputFormat {
    Yaml,
    Xml,
}

#[derive(Subcommand)]
pub(super) enum Command {
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
pub(super) struct ReportArgs {
    /// The tree: YAML, or BehaviorTree.CPP v4 XML (.xml; actions' parameters from --params); - reads standard input.
    pub(super) tree: PathBuf,
    /// exact: compose the actions' phase-type distributions exactly;
    /// book: the chapter's recursion (subtrees replaced by exponential actions).
    #[arg(long, value_enum, default_value_t = MethodArg::Exact)]
    pub(super) method: MethodArg,
    /// Output format.
    #[arg(long, value_enum, default_value_t = FormatArg::Table)]
    pub(super) format: FormatArg,
    /// Write to this file (atomically) instead of standard output (- is standard output).
    #[arg(short, long, value_name = "FILE")]
    pub(super) output: Option<PathBuf>,
    /// Largest chain (number of states) an exact analysis may build.
    #[arg(long, value_name = "N", default_value_t = DEFAULT_MAX_STATES)]
    pub(super) max_states: usize,
    /// Also simulate N runs per node and compare (Table 9.1 style).
    #[arg(long, value_name = "N")]
    pub(super) mc: Option<String>,
    #[command(flatten)]
    pub(super) sim: McArgs,
    #[command(flatten)]
    pub(super) ci: CiArgs,
}

/// `--ci [LEVEL]` of `report` and `curve`, with its draws and seed.
#[derive(clap::Args)]
pub(super) struct CiArgs {
    /// Also give LEVEL confidence intervals (default 0.95; 90 means 0.90) of every figure from the
    /// fitted parameters' sampling uncertainty (the `fit:` statistics `btrel fit` writes in the
    /// params file): a parametric bootstrap through the engine (ps ~ Beta, rates ~ Gamma; a leaf
    /// with halted episodes draws ps, mu, nu jointly from the fit's covariance; percentile
    /// intervals). Leaves without `fit:` statistics stay fixed (the output lists them).
    #[arg(long, value_name = "LEVEL", num_args = 0..=1, default_missing_value = "0.95")]
    pub(super) ci: Option<String>,
    /// Bootstrap draws, with --ci (default 1000).
    #[arg(long, value_name = "N", requires = "ci")]
    pub(super) ci_draws: Option<String>,
    /// Seed of the bootstrap draws, with --ci (decimal or 0x hex; default 0x5EEDC1); the intervals
    /// do not depend on the number of threads.
    #[arg(long, value_name = "S", allow_hyphen_values = true, requires = "ci")]
    pub(super) ci_seed: Option<String>,
}

pub(super) const CURVE_EXAMPLES: &str = "\
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
pub(super) struct CurveArgs {
    /// The tree: YAML, or BehaviorTree.CPP v4 XML (.xml; actions' parameters from --params); - reads standard input.
    pub(super) tree: PathBuf,
    /// Node to report, by name or path (repeatable); default: the root.
    #[arg(long = "node", value_name = "NAME")]
    pub(super) nodes: Vec<String>,
    #[command(flatten)]
    pub(super) grid: TimeArgs,
    /// exact (default): exact chain; book: the chapter's recursion.
    #[arg(long, value_enum, default_value_t = MethodArg::Exact)]
    pub(super) method: MethodArg,
    /// as-given, or deterministic: every exponential time replaced by 1/rate (an Erlang,
    /// hypo-, hyperexponential, phase-type or shifted time by its mean).
    #[arg(long, value_enum, default_value_t = TimingArg::AsGiven)]
    pub(super) timing: TimingArg,
    /// Also simulate N runs and add mc_success, mc_failure, mc_running columns.
    #[arg(long, value_name = "N")]
    pub(super) mc: Option<String>,
    #[command(flatten)]
    pub(super) sim: McArgs,
    #[command(flatten)]
    pub(super) ci: CiArgs,
    /// Write to this file (atomically) instead of standard output (- is standard output).
    #[arg(short, long, value_name = "FILE")]
    pub(super) output: Option<PathBuf>,
    /// Largest chain (number of states) an exact analysis may build.
    #[arg(long, value_name = "N", default_value_t = DEFAULT_MAX_STATES)]
    pub(super) max_states: usize,
}

#[derive(Clone, Copy, ValueEnum)]
pub(super) enum TimingArg {
    AsGiven,
    Deterministic,
}

pub(super) const COMPARE_EXAMPLES: &str = "\
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
pub(super) struct CompareArgs {
    /// The tree: YAML, or BehaviorTree.CPP v4 XML (.xml; actions' parameters from --params); - reads standard input.
    pub(super) tree: PathBuf,
    /// Fallback node whose children are permuted, by name or path (repeatable); default: all.
    #[arg(long = "node", value_name = "NAME")]
    pub(super) nodes: Vec<String>,
    /// Objective: mean-time (E[T]), mtts, mttf, or success-by (P(success by --deadline)).
    #[arg(long, value_enum)]
    pub(super) by: Option<ObjectiveArg>,
    /// Deadline T (s) for success-by.
    #[arg(long, value_name = "T", allow_hyphen_values = true)]
    pub(super) deadline: Option<String>,
    /// How many orderings to show (the given one is always shown in the table).
    #[arg(long, value_name = "K", default_value_t = 10)]
    pub(super) top: usize,
    /// exact (default) or book.
    #[arg(long, value_enum, default_value_t = MethodArg::Exact)]
    pub(super) method: MethodArg,
    /// Output format.
    #[arg(long, value_enum, default_value_t = FormatArg::Table)]
    pub(super) format: FormatArg,
    /// Also write the root's π(t) of the top K orderings to this CSV file.
    #[arg(long, value_name = "FILE")]
    pub(super) curves: Option<PathBuf>,
    /// Horizon (s) of --curves (default: where the curves have settled, as in `plot`).
    #[arg(long, value_name = "T", allow_hyphen_values = true)]
    pub(super) t_end: Option<String>,
    /// Enumerate every ordering when there are at most N (default: as many as about
    /// 2 s of estimated work allow, at most 100000); beyond, the ordering rule / local search.
    #[arg(long, value_name = "N")]
    pub(super) max_candidates: Option<usize>,
    /// Largest chain (number of states) an exact analysis may build.
    #[arg(long, value_name = "N", default_value_t = DEFAULT_MAX_STATES)]
    pub(super) max_states: usize,
    /// Write to this file (atomically) instead of standard output (- is standard output).
    #[arg(short, long, value_name = "FILE")]
    pub(super) output: Option<PathBuf>,
}

#[derive(Clone, Copy, ValueEnum)]
pub(super) enum ObjectiveArg {
    MeanTime,
    Mtts,
    Mttf,
    SuccessBy,
}

pub(super) const SIMULATE_EXAMPLES: &str = "\
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

pub(super) const PLOT_EXAMPLES: &str = "\
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
pub(super) enum PlotTiming {
    AsGiven,
    Deterministic,
    Both,
}

#[derive(clap::Args)]
pub(super) struct PlotArgs {
    /// The tree: YAML, or BehaviorTree.CPP v4 XML (.xml; actions' parameters from --params); - reads standard input.
    pub(super) tree: PathBuf,
    /// The image to write (atomically): FILE.svg or FILE.png; - writes SVG (or
    /// --format png) to standard output.
    #[arg(short, long, value_name = "FILE.svg|FILE.png")]
    pub(super) output: PathBuf,
    /// Image format; default: from the extension of -o (.svg or .png).
    #[arg(long, value_enum)]
    pub(super) format: Option<ImageFormatArg>,
    /// Node to plot, by name or path (repeatable); default: the root.
    #[arg(long = "node", value_name = "NAME", conflicts_with = "compare")]
    pub(super) nodes: Vec<String>,
    /// Horizon (s); default: where every curve has settled (running below 1e-3), rounded up.
    #[arg(long, value_name = "T", allow_hyphen_values = true)]
    pub(super) t_end: Option<String>,
    /// Points of each curve.
    #[arg(long, value_name = "K", default_value_t = 401)]
    pub(super) points: usize,
    /// Overlay a simulation with N runs (markers).
    #[arg(long, value_name = "N")]
    pub(super) mc: Option<String>,
    #[command(flatten)]
    pub(super) sim: McArgs,
    /// as-given, deterministic (every rate r becomes a fixed 1/r), or both overlaid.
    #[arg(long, value_enum, default_value_t = PlotTiming::AsGiven)]
    pub(super) timing: PlotTiming,
    /// Overlay the best orderings of this Fallback's children (with --deadline: by success by then).
    #[arg(long, value_name = "NODE")]
    pub(super) compare: Option<String>,
    /// Deadline (s): drawn as a marker; ranks the orderings of --compare.
    #[arg(long, value_name = "T", allow_hyphen_values = true)]
    pub(super) deadline: Option<String>,
    /// How many orderings --compare overlays.
    #[arg(long, value_name = "K", default_value_t = 2, requires = "compare")]
    pub(super) top: usize,
    /// exact (default) or book.
    #[arg(long, value_enum, default_value_t = MethodArg::Exact)]
    pub(super) method: MethodArg,
    /// Largest chain (number of states) an exact analysis may build.
    #[arg(long, value_name = "N", default_value_t = DEFAULT_MAX_STATES)]
    pub(super) max_states: usize,
}

pub(super) const EXPORT_EXAMPLES: &str = "\
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
pub(super) enum ExportFormat {
    Dot,
    Prism,
    PrismExplicit,
    Drn,
}

#[derive(clap::Args)]
pub(super) struct ExportArgs {
    /// The tree: YAML, or BehaviorTree.CPP v4 XML (.xml; actions' parameters from --params); - reads standard input.
    pub(super) tree: PathBuf,
    /// dot: the tree (or with --mrg a node's MRG); prism: a node's exact CTMC
    /// as a PRISM model; prism-explicit: the same as PRISM's explicit files
    /// BASE.tra/.sta/.lab/.srew (with -o BASE; for large chains); drn: the
    /// same in Storm's explicit DRN format.
    #[arg(long, value_enum)]
    pub(super) to: ExportFormat,
    /// Draw this control node's marking reachability graph instead of the tree (DOT).
    #[arg(long, value_name = "NODE")]
    pub(super) mrg: Option<String>,
    /// Node whose chain is exported to PRISM or Storm (default: the root).
    #[arg(long, value_name = "NAME")]
    pub(super) node: Option<String>,
    /// Write the matching PRISM properties file here (with --to prism or prism-explicit).
    #[arg(long, value_name = "FILE")]
    pub(super) properties: Option<PathBuf>,
    /// Write these times (s) into the properties file (`success_by_100`,
    /// ...) instead of the constant T; PRISM needs this with an imported
    /// (prism-explicit) model, which cannot take -const T.
    #[arg(
        long,
        value_delimiter = ',',
        value_name = "T1,T2,...",
        requires = "properties"
    )]
    pub(super) times: Vec<String>,
    /// Method of the figures shown in DOT labels.
    #[arg(long, value_enum, default_value_t = MethodArg::Exact)]
    pub(super) method: MethodArg,
    /// Largest chain (number of states) an exact analysis may build.
    #[arg(long, value_name = "N", default_value_t = DEFAULT_MAX_STATES)]
    pub(super) max_states: usize,
    /// Write to this file (atomically) instead of standard output (- is
    /// standard output); with --to prism-explicit, the base name of the four
    /// files (required).
    #[arg(short, long, value_name = "FILE")]
    pub(super) output: Option<PathBuf>,
}

/// Time points: a list, or an evenly spaced grid from 0.
#[derive(clap::Args)]
pub(super) struct TimeArgs {
    /// Comma-separated times (s), e.g. 0,10,100.
    #[arg(long, value_delimiter = ',', value_name = "T1,T2,...", allow_hyphen_values = true, conflicts_with_all = ["t_end", "points", "dt"])]
    pub(super) times: Vec<String>,
    /// Last time (s) of an evenly spaced grid starting at 0.
    #[arg(long, value_name = "T", allow_hyphen_values = true)]
    pub(super) t_end: Option<String>,
    /// Number of grid points from 0 to T inclusive (default 101).
    #[arg(long, value_name = "K", conflicts_with = "dt", requires = "t_end")]
    pub(super) points: Option<usize>,
    /// Grid spacing (s): 0, D, 2D, ... up to T, and T itself when it is not a multiple of D.
    #[arg(long, value_name = "D", requires = "t_end", allow_hyphen_values = true)]
    pub(super) dt: Option<String>,
}

/// Monte Carlo options of `simulate`.
#[derive(clap::Args)]
pub(super) struct SimArgs {
    /// Seed of the random streams (decimal or 0x hex; default 0x5EEDB7E1).
    #[arg(long, value_name = "S", allow_hyphen_values = true)]
    pub(super) seed: Option<String>,
    #[arg(long, value_name = "K", help = threads_help("Worker threads"))]
    pub(super) threads: Option<usize>,
}

/// The Monte Carlo check of `report --mc`, `curve --mc` and `plot --mc`:
/// its options need `--mc`.
#[derive(clap::Args)]
pub(super) struct McArgs {
    /// Seed of the simulation's random streams, with --mc (decimal or 0x hex; default 0x5EEDB7E1).
    #[arg(long, value_name = "S", allow_hyphen_values = true, requires = "mc")]
    pub(super) seed: Option<String>,
    #[arg(long, value_name = "K", help = threads_help("Worker threads of the simulation, with --mc"), requires = "mc")]
    pub(super) threads: Option<usize>,
}

impl McArgs {
    pub(super) fn sim(&self) -> SimArgs {
        SimArgs {
            seed: self.seed.clone(),
            threads: self.threads,
        }
    }
}

/// `RAYON_NUM_THREADS`, which sizes rayon's global pool when set to a positive number.
pub(super) fn rayon_env_threads() -> Option<usize> {
    std::env::var("RAYON_NUM_THREADS")
        .ok()
        .and_then(|v| v.trim().parse::<usize>().ok())
        .filter(|&n| n > 0)
}

/// The help of `--threads`, with the real default: the size of rayon's
/// global pool (`RAYON_NUM_THREADS`, else one thread per core), computed
/// without starting the pool.
pub(super) fn threads_help(what: &str) -> String {
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
pub(super) struct SimulateArgs {
    /// The tree: YAML, or BehaviorTree.CPP v4 XML (.xml; actions' parameters from --params); - reads standard input.
    pub(super) tree: PathBuf,
    /// Runs per node (e.g. 1000000 or 1e6).
    #[arg(long, value_name = "N", default_value = "1000000")]
    pub(super) runs: String,
    /// Run until every probability (ps, pf, never, the curve's points) is within ±EPS, instead of
    /// --runs: Okamoto's pre-computed bound (exact for any tree).
    #[arg(
        long,
        value_name = "EPS",
        conflicts_with = "runs",
        allow_hyphen_values = true
    )]
    pub(super) precision: Option<String>,
    /// Run until every MTTS and MTTF is within ±S seconds, instead of --runs: the Chow–Robbins
    /// sequential rule (asymptotically exact).
    #[arg(
        long,
        value_name = "S",
        conflicts_with = "runs",
        allow_hyphen_values = true
    )]
    pub(super) time_precision: Option<String>,
    /// Confidence of each interval, with --precision or --time-precision (default 0.95).
    #[arg(long, value_name = "LEVEL")]
    pub(super) confidence: Option<String>,
    /// Most runs per node, with --precision or --time-precision (default 1e8).
    #[arg(long, value_name = "N")]
    pub(super) max_runs: Option<String>,
    #[command(flatten)]
    pub(super) sim: SimArgs,
    /// Simulate this node's subtree instead of the whole tree (name or path).
    #[arg(long, value_name = "NAME")]
    pub(super) node: Option<String>,
    #[command(flatten)]
    pub(super) grid: TimeArgs,
    /// Output format.
    #[arg(long, value_enum, default_value_t = FormatArg::Table)]
    pub(super) format: FormatArg,
    /// Write to this file (atomically) instead of standard output (- is standard output).
    #[arg(short, long, value_name = "FILE")]
    pub(super) output: Option<PathBuf>,
}

#[derive(clap::Args)]
pub(super) struct CheckArgs {
    /// The tree: YAML, or BehaviorTree.CPP v4 XML (.xml; actions' parameters from --params); - reads standard input.
    pub(super) tree: PathBuf,
    /// A requirement the tree must meet (repeatable): [NODE.]FIGURE OP NUMBER, e.g. 'ps >= 0.95',
    /// 'NavigateRecovery.mtts <= 90', 'success_by(120) >= 0.8'. FIGURE: ps, pf, never, mtts,
    /// mttf, success_by(T), failure_by(T); OP: >=, <=, >, <.
    #[arg(long = "require", value_name = "EXPR", allow_hyphen_values = true)]
    pub(super) require: Vec<String>,
    /// Decide by Monte Carlo instead of the exact engine: Wald's SPRT for probabilities, a
    /// Chow–Robbins interval for mean times (see below); prints the decision and the runs used.
    #[arg(long, requires = "require")]
    pub(super) mc: bool,
    /// With --mc: bound on failing a requirement that holds with margin (default 0.05).
    #[arg(long, value_name = "A", requires = "mc")]
    pub(super) alpha: Option<String>,
    /// With --mc: bound on passing a requirement that fails by the margin (default 0.05).
    #[arg(long, value_name = "B", requires = "mc")]
    pub(super) beta: Option<String>,
    /// With --mc: half-width δ of the indifference region θ ± δ of a probability (default 0.01).
    #[arg(long, value_name = "D", requires = "mc")]
    pub(super) indifference: Option<String>,
    /// With --mc: half-width of the indifference region of a mean time, in s (default 1% of
    /// its threshold).
    #[arg(long, value_name = "S", requires = "mc")]
    pub(super) time_indifference: Option<String>,
    /// With --mc: most runs per requirement (default 1e8); a test still undecided then fails.
    #[arg(long, value_name = "N", requires = "mc")]
    pub(super) max_runs: Option<String>,
    /// With --mc: seed of the runs (decimal or 0x hex; default 0x5EEDB7E1).
    #[arg(long, value_name = "S", allow_hyphen_values = true, requires = "mc")]
    pub(super) seed: Option<String>,
    #[arg(long, value_name = "K", help = threads_help("Worker threads of the simulation, with --mc"), requires = "mc")]
    pub(super) threads: Option<usize>,
    /// Largest chain (number of states) an exact analysis may build.
    #[arg(long, value_name = "N", default_value_t = DEFAULT_MAX_STATES)]
    pub(super) max_states: usize,
    /// Decide by the LEVEL interval (default 0.95; 90 means 0.90) from the fitted parameters'
    /// sampling uncertainty (the `fit:` statistics `btrel fit` writes in the params file; the
    /// parametric bootstrap of `report --ci`): its lower bound must meet a >= or >
    /// requirement, its upper bound a <= or <.
    #[arg(long, value_name = "LEVEL", num_args = 0..=1, default_missing_value = "0.95", requires = "require")]
    pub(super) ci: Option<String>,
    /// Bootstrap draws, with --ci (default 1000).
    #[arg(long, value_name = "N", requires = "ci")]
    pub(super) ci_draws: Option<String>,
    /// Seed of the bootstrap draws, with --ci (decimal or 0x hex; default 0x5EEDC1).
    #[arg(long, value_name = "S", allow_hyphen_values = true, requires = "ci")]
    pub(super) ci_seed: Option<String>,
}

#[derive(Clone, Copy, ValueEnum)]
pub(super) enum MethodArg {
    Exact,
    Book,
}

#[derive(Clone, Copy, ValueEnum)]
pub(super) enum FormatArg {
    Table,
    Json,
    Csv,
}

/// The image format of a plot's output file.
#[derive(Clone, Copy, PartialEq, Eq, ValueEnum)]
pub(super) enum ImageFormatArg {
    Svg,
    Png,
}
