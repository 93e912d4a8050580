//! Requirements on a tree's figures — `ps >= 0.95`,
//! `NavigateRecovery.mtts <= 90`, `success_by(120) >= 0.8` — and their
//! decision: by the exact engine, by the lower (upper) bound of an interval
//! from fitted parameters, or by a sequential Monte Carlo test
//! ([`crate::sim::sequential`]: Wald's SPRT for probabilities, a
//! Chow–Robbins fixed-width interval for mean times). `btrel check
//! --require` is built on it.
//!
//! # Grammar
//!
//! ```text
//! requirement := [NODE "."] FIGURE OP NUMBER
//! FIGURE      := ps | pf | never | mtts | mttf | success_by(T) | failure_by(T)
//! OP          := >= | <= | > | <   (also ≥ ≤)
//! ```
//!
//! `NODE` is a node's name or path (`0.1`), optionally in quotes; without it
//! the figure is the root's. A node's figures are those of its subtree run
//! on its own, as `btrel report` gives them. `never` is P(never returns);
//! `success_by(T)` is P(returned Success by time T) (`failure_by` alike).
//!
//! ```
//! let tree = btrel::parse_str(
//!     "tree:\n  fallback:\n    name: root\n    children:\n      - action: {name: a, ps: 0.5, mu: 1.0, nu: 2.0}\n      - action: {name: b, ps: 0.5, mu: 1.0, nu: 2.0}\n",
//!     "example.yaml",
//! )?;
//! let r = btrel::gate::parse("a.mtts <= 1.5", &tree).unwrap();
//! let values = btrel::gate::exact_values(&tree, &[r.clone()], &Default::default())?;
//! assert_eq!(values[0], Some(1.0));
//! assert!(r.holds(1.0));
//! let e = btrel::gate::parse("c.ps >= 0.5", &tree).unwrap_err();
//! assert_eq!((e.column, e.width), (1, 1));
//! # Ok::<(), btrel::Error>(())
//! ```

use std::fmt;

use crate::compile::Options;
use crate::number::significant;
use crate::sim::sequential::{
    chow_robbins_stops, chunk_seed, normal_quantile, run_until, Acc, Chunking, Decision, Sprt,
    TEST_CHUNK,
};
use crate::sim::{SimError, SimOptions};
use crate::tree::{NodeId, Tree};
use crate::Model;

/// A figure a requirement is about.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Figure {
    /// P(Success).
    Ps,
    /// P(Failure).
    Pf,
    /// P(never returns).
    Never,
    /// Mean Time To Succeed.
    Mtts,
    /// Mean Time To Fail.
    Mttf,
    /// P(returned Success by T).
    SuccessBy(f64),
    /// P(returned Failure by T).
    FailureBy(f64),
}

impl Figure {
    /// Whether the figure is a mean time (in s), not a probability.
    pub fn is_time(&self) -> bool {
        matches!(self, Figure::Mtts | Figure::Mttf)
    }
}

impl fmt::Display for Figure {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Figure::Ps => write!(f, "ps"),
            Figure::Pf => write!(f, "pf"),
            Figure::Never => write!(f, "never"),
            Figure::Mtts => write!(f, "mtts"),
            Figure::Mttf => write!(f, "mttf"),
            Figure::SuccessBy(t) => write!(f, "success_by({t})"),
            Figure::FailureBy(t) => write!(f, "failure_by({t})"),
        }
    }
}

/// A comparison.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Op {
    /// `>=`
    Ge,
    /// `>`
    Gt,
    /// `<=`
    Le,
    /// `<`
    Lt,
}

impl Op {
    /// Whether the figure must be large (`>=`, `>`).
    pub fn at_least(&self) -> bool {
        matches!(self, Op::Ge | Op::Gt)
    }
}

/// One parsed requirement.
#[derive(Debug, Clone, PartialEq)]
pub struct Requirement {
    /// The text as given, trimmed.
    pub text: String,
    /// The node whose figure it is.
    pub node: NodeId,
    /// The figure.
    pub figure: Figure,
    /// The comparison.
    pub op: Op,
    /// The number compared with.
    pub threshold: f64,
}

impl Requirement {
    /// Whether `value` satisfies the requirement.
    pub fn holds(&self, value: f64) -> bool {
        match self.op {
            Op::Ge => value >= self.threshold,
            Op::Gt => value > self.threshold,
            Op::Le => value <= self.threshold,
            Op::Lt => value < self.threshold,
        }
    }
}

/// A requirement that cannot be parsed, located: `column` (1-based, in
/// characters) and `width` mark the offending part of `text`.
#[derive(Debug, Clone, PartialEq)]
pub struct ExprError {
    /// The requirement as given.
    pub text: String,
    /// What is wrong.
    pub message: String,
    /// First character of the offending part, 1-based.
    pub column: usize,
    /// Its length in characters (at least 1).
    pub width: usize,
    /// A suggestion.
    pub help: Option<String>,
    /// An unknown node in a tree with too many nodes for the help to list
    /// them: a front end may say how to list them.
    pub nodes_unlisted: bool,
}

impl fmt::Display for ExprError {
    /// `requirement 'TEXT', column C: MESSAGE`, the text with carets under
    /// the offending part, and the help.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "requirement '{}', column {}: {}",
            self.text, self.column, self.message
        )?;
        writeln!(f, "  {}", self.text)?;
        write!(
            f,
            "  {}{}",
            " ".repeat(self.column - 1),
            "^".repeat(self.width.max(1))
        )?;
        if let Some(h) = &self.help {
            write!(f, "\n  help: {h}")?;
        }
        Ok(())
    }
}

impl std::error::Error for ExprError {}

const FIGURES: &str = "ps, pf, never, mtts, mttf, success_by(T) or failure_by(T)";
const OPERATORS: &str = ">=, <=, > or <";

fn is_op_char(c: char) -> bool {
    matches!(c, '<' | '>' | '=' | '!' | '≥' | '≤' | '≠')
}

/// Parses a requirement on `tree`'s figures (module docs: the grammar).
pub fn parse(text: &str, tree: &Tree) -> Result<Requirement, ExprError> {
    let trimmed = text.trim();
    let chars: Vec<char> = trimmed.chars().collect();
    let err = |message: String, start: usize, end: usize, help: Option<String>| ExprError {
        text: trimmed.to_string(),
        message,
        column: start + 1,
        width: end.saturating_sub(start).max(1),
        help,
        nodes_unlisted: false,
    };
    if chars.is_empty() {
        return Err(err(
            "the requirement is empty".into(),
            0,
            1,
            Some("write FIGURE OP NUMBER, e.g. 'ps >= 0.95'".into()),
        ));
    }
    // the operator: the last run of comparison characters
    let Some(op_end) = chars.iter().rposition(|&c| is_op_char(c)).map(|i| i + 1) else {
        return Err(err(
            format!("no comparison: expected {OPERATORS} between the figure and a number"),
            0,
            chars.len(),
            Some("write FIGURE OP NUMBER, e.g. 'ps >= 0.95' or 'search.mtts <= 90'".into()),
        ));
    };
    let op_start = chars[..op_end]
        .iter()
        .rposition(|&c| !is_op_char(c))
        .map_or(0, |i| i + 1);
    let op_text: String = chars[op_start..op_end].iter().collect();
    let op = match op_text.as_str() {
        ">=" | "≥" => Op::Ge,
        "<=" | "≤" => Op::Le,
        ">" => Op::Gt,
        "<" => Op::Lt,
        "=" | "==" | "!=" | "≠" => {
            return Err(err(
                format!("unknown operator '{op_text}': a requirement is an inequality"),
                op_start,
                op_end,
                Some(format!(
                    "use {OPERATORS} (a computed or estimated figure is never exactly a number)"
                )),
            ))
        }
        _ => {
            let help = match op_text.as_str() {
                "=>" => "did you mean '>='?".to_string(),
                "=<" => "did you mean '<='?".to_string(),
                _ => format!("use {OPERATORS}"),
            };
            return Err(err(
                format!("unknown operator '{op_text}'"),
                op_start,
                op_end,
                Some(help),
            ));
        }
    };
    // the number
    let rhs_start = op_end
        + chars[op_end..]
            .iter()
            .take_while(|c| c.is_whitespace())
            .count();
    let rhs: String = chars[rhs_start..].iter().collect();
    let threshold: f64 = match rhs.trim().parse::<f64>() {
        Ok(x) if x.is_finite() => x,
        _ => {
            let (start, end) = if rhs.is_empty() {
                (chars.len(), chars.len() + 1)
            } else {
                (rhs_start, chars.len())
            };
            return Err(ExprError {
                text: trimmed.to_string(),
                message: if rhs.is_empty() {
                    format!("expected a number after '{op_text}'")
                } else {
                    format!("'{}' is not a number", rhs.trim())
                },
                column: start + 1,
                width: end - start,
                help: Some("e.g. 0.95 for a probability, 90 for a mean time in seconds".into()),
                nodes_unlisted: false,
            });
        }
    };
    // the figure: at the end of the left-hand side
    let lhs_end = chars[..op_start]
        .iter()
        .rposition(|c| !c.is_whitespace())
        .map_or(0, |i| i + 1);
    if lhs_end == 0 {
        return Err(err(
            format!("expected a figure before '{op_text}'"),
            op_start,
            op_end,
            Some(format!("the figures are {FIGURES}")),
        ));
    }
    let (fig_start, name_end, arg) = if chars[lhs_end - 1] == ')' {
        let Some(open) = chars[..lhs_end - 1].iter().rposition(|&c| c == '(') else {
            return Err(err("')' without '('".into(), lhs_end - 1, lhs_end, None));
        };
        let name_start = chars[..open]
            .iter()
            .rposition(|c| !(c.is_alphanumeric() || *c == '_'))
            .map_or(0, |i| i + 1);
        (name_start, open, Some((open + 1, lhs_end - 1)))
    } else {
        let name_start = chars[..lhs_end]
            .iter()
            .rposition(|c| !(c.is_alphanumeric() || *c == '_'))
            .map_or(0, |i| i + 1);
        (name_start, lhs_end, None)
    };
    let name: String = chars[fig_start..name_end].iter().collect();
    let node_part = chars[..fig_start].iter().collect::<String>();
    let unknown_figure = |name: &str| {
        let known = [
            "ps",
            "pf",
            "never",
            "mtts",
            "mttf",
            "success_by",
            "failure_by",
        ];
        let is_node = tree.find(name).is_some();
        let help = if is_node && node_part.trim().is_empty() && arg.is_none() {
            format!("'{name}' is a node: name one of its figures, e.g. '{name}.ps'")
        } else {
            match crate::tree::error::nearest(name, &known) {
                Some(near) => format!("did you mean '{near}'? The figures are {FIGURES}"),
                None => format!("the figures are {FIGURES}"),
            }
        };
        err(
            if name.is_empty() {
                "expected a figure here".to_string()
            } else {
                format!("unknown figure '{name}'")
            },
            fig_start,
            name_end.max(fig_start + 1),
            Some(help),
        )
    };
    let figure = match (name.to_ascii_lowercase().as_str(), arg) {
        ("ps", None) => Figure::Ps,
        ("pf", None) => Figure::Pf,
        ("never", None) => Figure::Never,
        ("mtts", None) => Figure::Mtts,
        ("mttf", None) => Figure::Mttf,
        (f @ ("success_by" | "failure_by"), Some((a, b))) => {
            let arg: String = chars[a..b].iter().collect();
            let t = arg
                .trim()
                .parse::<f64>()
                .ok()
                .filter(|t| t.is_finite() && *t >= 0.0);
            let Some(t) = t else {
                return Err(err(
                    if arg.trim().is_empty() {
                        format!("{f} needs a time")
                    } else {
                        format!("'{}' is not a time", arg.trim())
                    },
                    if a == b { a - 1 } else { a },
                    if a == b { b + 1 } else { b },
                    Some(format!("a time in seconds, finite and >= 0, e.g. {f}(120)")),
                ));
            };
            if f == "success_by" {
                Figure::SuccessBy(t)
            } else {
                Figure::FailureBy(t)
            }
        }
        (f @ ("success_by" | "failure_by"), None) => {
            return Err(err(
                format!("{f} needs a time in parentheses"),
                fig_start,
                name_end,
                Some(format!("e.g. {f}(120)")),
            ))
        }
        (f @ ("ps" | "pf" | "never" | "mtts" | "mttf"), Some((_, b))) => {
            return Err(err(
                format!("{f} takes no time"),
                name_end,
                b + 1,
                Some("success_by(T) and failure_by(T) are the figures at a time".into()),
            ))
        }
        _ => return Err(unknown_figure(&name)),
    };
    // the node: what comes before ".FIGURE"
    let node = if node_part.trim().is_empty() {
        Tree::ROOT
    } else {
        let dot = fig_start - 1;
        if chars[dot] != '.' {
            let before = chars[..fig_start]
                .iter()
                .rposition(|c| !c.is_whitespace())
                .unwrap_or(0);
            return Err(err(
                format!("expected '.' between the node and the figure '{name}'"),
                before + 1,
                fig_start,
                Some("write NODE.FIGURE, e.g. 'search.ps'".into()),
            ));
        }
        let raw: String = chars[..dot].iter().collect();
        let lead = raw.chars().take_while(|c| c.is_whitespace()).count();
        let mut inner = raw.trim().to_string();
        let mut node_start = lead;
        let mut node_end = lead + inner.chars().count();
        for q in ['\'', '"', '`'] {
            if inner.len() >= 2 && inner.starts_with(q) && inner.ends_with(q) {
                inner = inner[1..inner.len() - 1].to_string();
                node_start += 1;
                node_end -= 1;
                break;
            }
        }
        match tree.find(&inner) {
            Some(id) => id,
            None => {
                let all: Vec<&str> = tree.nodes.iter().map(|x| x.name.as_str()).collect();
                let near = crate::tree::error::nearest(&inner, &all);
                let nodes_unlisted = near.is_none() && all.len() > 12;
                let help = match near {
                    Some(near) => format!("did you mean '{near}'?"),
                    None if all.len() <= 12 => {
                        format!(
                            "the nodes are {}; or give a path such as 0.1",
                            all.join(", ")
                        )
                    }
                    None => "give a node's name or its path such as 0.1".to_string(),
                };
                let mut e = err(
                    format!("no node named '{inner}'"),
                    node_start,
                    node_end,
                    Some(help),
                );
                e.nodes_unlisted = nodes_unlisted;
                return Err(e);
            }
        }
    };
    Ok(Requirement {
        text: trimmed.to_string(),
        node,
        figure,
        op,
        threshold,
    })
}

/// The exact value of each requirement's figure (`None` where undefined:
/// the MTTS of a node that never succeeds), from one [`Model`] of the tree:
/// every node's figures when a requirement needs them, one curve per node
/// with `success_by` / `failure_by` figures (all its times at once).
pub fn exact_values(
    tree: &Tree,
    reqs: &[Requirement],
    options: &Options,
) -> Result<Vec<Option<f64>>, crate::Error> {
    let model = Model::with_options(tree, *options)?;
    let mut out = vec![None; reqs.len()];
    // curves: all the times of a node at once
    let mut nodes: Vec<NodeId> = reqs
        .iter()
        .filter(|r| matches!(r.figure, Figure::SuccessBy(_) | Figure::FailureBy(_)))
        .map(|r| r.node)
        .collect();
    nodes.sort_unstable();
    nodes.dedup();
    for node in nodes {
        let idx: Vec<usize> = (0..reqs.len())
            .filter(|&i| {
                reqs[i].node == node
                    && matches!(reqs[i].figure, Figure::SuccessBy(_) | Figure::FailureBy(_))
            })
            .collect();
        let times: Vec<f64> = idx
            .iter()
            .map(|&i| match reqs[i].figure {
                Figure::SuccessBy(t) | Figure::FailureBy(t) => t,
                _ => unreachable!("curve figures only"),
            })
            .collect();
        let points = model.curve(node, &times)?;
        for (&i, p) in idx.iter().zip(&points) {
            out[i] = Some(match reqs[i].figure {
                Figure::SuccessBy(_) => p.success,
                _ => p.failure,
            });
        }
    }
    for (i, r) in reqs.iter().enumerate() {
        if matches!(r.figure, Figure::SuccessBy(_) | Figure::FailureBy(_)) {
            continue;
        }
        // every node's figures, computed at the first of these
        let f = model.figures(r.node)?;
        out[i] = match r.figure {
            Figure::Ps => Some(f.ps),
            Figure::Pf => Some(f.pf),
            Figure::Never => Some(f.never()),
            Figure::Mtts => f.mtts,
            Figure::Mttf => f.mttf,
            Figure::SuccessBy(_) | Figure::FailureBy(_) => unreachable!("skipped above"),
        };
    }
    Ok(out)
}

/// Settings of the sequential Monte Carlo tests.
#[derive(Debug, Clone, PartialEq)]
pub struct TestSettings {
    /// Bound on the probability of declaring a requirement failed that
    /// holds with margin (type I error of H0 "holds").
    pub alpha: f64,
    /// Bound on the probability of passing a requirement that fails by the
    /// margin.
    pub beta: f64,
    /// Half-width δ of the indifference region of a probability:
    /// `[θ − δ, θ + δ]`.
    pub indifference: f64,
    /// Half-width of the indifference region of a mean time, in s (`None`:
    /// 1% of the threshold).
    pub time_indifference: Option<f64>,
    /// Most runs per requirement.
    pub max_runs: u64,
    /// Seed; requirement `i` uses [`chunk_seed`]`(seed ^ 0xC4EC, i)`.
    pub seed: u64,
    /// Worker threads (0: rayon's global pool); the decisions do not depend
    /// on it.
    pub threads: usize,
}

impl Default for TestSettings {
    fn default() -> Self {
        TestSettings {
            alpha: 0.05,
            beta: 0.05,
            indifference: 0.01,
            time_indifference: None,
            max_runs: crate::sim::sequential::DEFAULT_MAX_RUNS,
            seed: crate::sim::DEFAULT_SEED,
            threads: 0,
        }
    }
}

/// The outcome of a sequential test of one requirement.
#[derive(Debug, Clone, PartialEq)]
pub struct TestOutcome {
    /// The decision.
    pub decision: Decision,
    /// Runs of the node it took.
    pub runs: u64,
    /// The figure's estimate at the end (`None`: no run returned the
    /// outcome of a mean time).
    pub estimate: Option<f64>,
    /// The half-width of the interval a mean time was decided with.
    pub half_width: Option<f64>,
    /// What was tested, in words (`SPRT of p ≥ 0.96 against p ≤ 0.94, α =
    /// 0.05, β = 0.05`).
    pub method: String,
}

/// Settings that cannot test a requirement.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum TestError {
    /// α or β outside (0, 1), or α + β ≥ 1.
    #[error(
        "the error bounds alpha and beta must be in (0, 1) with alpha + beta < 1 (got {0} and {1})"
    )]
    Errors(f64, f64),
    /// The indifference region leaves (0, 1).
    #[error(
        "requirement '{text}': the indifference region [{lo}, {hi}] must lie inside (0, 1) for a \
         sequential test"
    )]
    Region {
        /// The requirement.
        text: String,
        /// θ − δ.
        lo: f64,
        /// θ + δ.
        hi: f64,
    },
    /// A non-positive indifference.
    #[error("the indifference of requirement '{0}' must be > 0")]
    Indifference(String),
    /// The simulation.
    #[error(transparent)]
    Sim(#[from] SimError),
}

impl TestSettings {
    /// Checks the settings against a requirement before any run.
    pub fn validate(&self, r: &Requirement) -> Result<(), TestError> {
        if !(self.alpha > 0.0 && self.beta > 0.0 && self.alpha + self.beta < 1.0) {
            return Err(TestError::Errors(self.alpha, self.beta));
        }
        if r.figure.is_time() {
            let d = self.time_indifference.unwrap_or(r.threshold.abs() / 100.0);
            if !(d.is_finite() && d > 0.0) {
                return Err(TestError::Indifference(r.text.clone()));
            }
        } else {
            let d = self.indifference;
            if !(d.is_finite() && d > 0.0) {
                return Err(TestError::Indifference(r.text.clone()));
            }
            let (lo, hi) = (r.threshold - d, r.threshold + d);
            if !(lo > 0.0 && hi < 1.0) {
                return Err(TestError::Region {
                    text: r.text.clone(),
                    lo,
                    hi,
                });
            }
        }
        Ok(())
    }
}

/// Decides requirement number `index` of a check by simulation (module
/// docs of [`crate::sim::sequential`]: a probability by Wald's SPRT with
/// indifference region `θ ± δ`, a mean time by a Chow–Robbins interval of
/// half-width δ_t at the one-sided quantile of `min(α, β)`).
pub fn test(
    tree: &Tree,
    r: &Requirement,
    index: usize,
    s: &TestSettings,
) -> Result<TestOutcome, TestError> {
    s.validate(r)?;
    let times = match r.figure {
        Figure::SuccessBy(t) | Figure::FailureBy(t) => vec![t],
        _ => Vec::new(),
    };
    let base = SimOptions {
        runs: 1,
        seed: chunk_seed(s.seed ^ 0xC4EC, index as u64),
        threads: s.threads,
        times,
        per_node: false,
    };
    let chunking = Chunking {
        first: TEST_CHUNK,
        chunk: TEST_CHUNK,
        max_runs: s.max_runs,
    };
    // successes of the Bernoulli variable the figure is the mean of
    let count = |acc: &Acc| {
        let a = &acc.nodes[0];
        match r.figure {
            Figure::Ps => a.successes,
            Figure::Pf => a.failures,
            Figure::Never => acc.runs - a.successes - a.failures,
            Figure::SuccessBy(_) => acc.curve[0].1,
            Figure::FailureBy(_) => acc.curve[0].2,
            Figure::Mtts | Figure::Mttf => unreachable!("probabilities only"),
        }
    };
    if r.figure.is_time() {
        let d = s.time_indifference.unwrap_or(r.threshold.abs() / 100.0);
        let z = normal_quantile(1.0 - s.alpha.min(s.beta));
        let can = crate::sim::outcomes(tree, r.node)[r.node];
        let possible = if r.figure == Figure::Mtts {
            can.0
        } else {
            can.1
        };
        let method = format!("Chow–Robbins interval ±{} s at z = {:.3}", short(d), z);
        if !possible {
            return Ok(TestOutcome {
                decision: Decision::Fails,
                runs: 0,
                estimate: None,
                half_width: None,
                method,
            });
        }
        let mean = |acc: &Acc| {
            let a = &acc.nodes[0];
            if r.figure == Figure::Mtts {
                a.mtts
            } else {
                a.mttf
            }
        };
        let (acc, stopped) = run_until(tree, r.node, &base, chunking, |acc| {
            let m = mean(acc);
            m.variance()
                .is_some_and(|v| chow_robbins_stops(m.n, v, z, d))
        })?;
        let m = mean(&acc);
        let decision = if !stopped {
            Decision::Undecided
        } else if r.holds(m.mean) {
            Decision::Holds
        } else {
            Decision::Fails
        };
        return Ok(TestOutcome {
            decision,
            runs: acc.runs,
            estimate: (m.n > 0).then_some(m.mean),
            half_width: m.variance().map(|v| z * (v / m.n as f64).sqrt()),
            method,
        });
    }
    let d = s.indifference;
    let (p0, p1) = if r.op.at_least() {
        (r.threshold + d, r.threshold - d)
    } else {
        (r.threshold - d, r.threshold + d)
    };
    let sprt = Sprt::new(p0, p1, s.alpha, s.beta);
    let mut decision = Decision::Undecided;
    let (acc, _) = run_until(tree, r.node, &base, chunking, |acc| {
        decision = sprt.decide(count(acc), acc.runs);
        decision != Decision::Undecided
    })?;
    let k = count(&acc);
    let (ge, le) = if r.op.at_least() {
        (">=", "<=")
    } else {
        ("<=", ">=")
    };
    Ok(TestOutcome {
        decision,
        runs: acc.runs,
        estimate: Some(k as f64 / acc.runs as f64),
        half_width: None,
        method: format!(
            "SPRT of p {ge} {} against p {le} {}, α = {}, β = {}",
            short(p0),
            short(p1),
            s.alpha,
            s.beta
        ),
    })
}

/// A figure's value as printed: 5 significant digits, ` s` after a time.
pub fn show(figure: Figure, value: Option<f64>) -> String {
    match value {
        None => "undefined".to_string(),
        Some(v) if figure.is_time() => format!("{} s", significant(v, 5)),
        Some(v) => significant(v, 5),
    }
}

/// A threshold as written: at most 12 decimals, trailing zeros dropped
/// (`0.94 - 0.01` prints as `0.93`).
fn short(x: f64) -> String {
    let s = format!("{x:.12}");
    let s = s.trim_end_matches('0').trim_end_matches('.');
    if s.is_empty() || s == "-" {
        "0".to_string()
    } else {
        s.to_string()
    }
}
