//! A report with confidence intervals of every node's figures
//! (`report --ci`), in the three output formats.

use std::io::{self, Write};

use serde_json::{json, Value};

use super::csv::io_error;
use super::table::write_aligned;
use super::Report;
use crate::number::{full, significant, significant_or_dash};
use crate::uncertainty::METHOD;

/// An interval, `None` where the figure is undefined in every draw.
pub(crate) type Interval = Option<(f64, f64)>;

/// The intervals of a report's figures and how they were made.
#[derive(Debug, Clone, PartialEq)]
pub struct Intervals {
    /// Confidence level in (0, 1).
    pub level: f64,
    pub draws: usize,
    pub seed: u64,
    /// Per node (in report order): ps, pf, MTTS, MTTF.
    pub nodes: Vec<[Interval; 4]>,
    /// Leaves without `fit:` statistics (fixed).
    pub fixed: Vec<String>,
    /// Fitted parameters held fixed, and why.
    pub held: Vec<String>,
    /// Leaves with halts drawn independently for want of `cov:` statistics.
    pub independent: Vec<String>,
}

impl Intervals {
    /// The level as a percentage for headers (`95%`).
    pub fn percent(&self) -> String {
        format!(
            "{}%",
            significant(self.level * 100.0, 4)
                .trim_end_matches('0')
                .trim_end_matches('.')
        )
    }

    /// The notes on fixed parameters, one line each.
    pub fn notes(&self) -> Vec<String> {
        let mut v = Vec::new();
        if !self.fixed.is_empty() {
            v.push(format!(
                "fixed (no `fit:` statistics in the params file): {}",
                self.fixed.join(", ")
            ));
        }
        v.extend(self.held.iter().cloned());
        v.extend(self.independent.iter().cloned());
        v
    }
}

/// A level as a percentage: `95%`, `99.5%`.
pub fn percent(level: f64) -> String {
    let s = significant(level * 100.0, 4);
    let s = if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.')
    } else {
        &s
    };
    format!("{s}%")
}

fn cell(i: Interval) -> String {
    i.map_or_else(
        || "—".to_string(),
        |(lo, hi)| format!("[{}, {}]", significant(lo, 4), significant(hi, 4)),
    )
}

/// Table: ps, MTTS and MTTF each followed by its interval (pf = 1 − ps and
/// its interval mirrors ps's: JSON and CSV have it); the method and the
/// fixed parameters below.
pub fn write_table(report: &Report, ci: &Intervals, out: &mut dyn Write) -> io::Result<()> {
    let p = ci.percent();
    let mut rows = vec![[
        "node",
        "kind",
        "ps",
        &format!("ps {p}"),
        "MTTS",
        &format!("MTTS {p}"),
        "MTTF",
        &format!("MTTF {p}"),
    ]
    .map(str::to_string)
    .to_vec()];
    for (n, c) in report.nodes.iter().zip(&ci.nodes) {
        let f = &n.figures;
        let d = |x: Option<f64>| significant_or_dash(x, super::table::DIGITS);
        rows.push(vec![
            format!("{}{}", "  ".repeat(n.depth), n.name),
            n.kind.to_string(),
            d(Some(f.ps)),
            cell(c[0]),
            d(f.mtts),
            cell(c[2]),
            d(f.mttf),
            cell(c[3]),
        ]);
    }
    writeln!(
        out,
        "{} — method: {} (times in s); {p} intervals from {} draws (seed {})",
        report.tree,
        report.method.name(),
        ci.draws,
        ci.seed
    )?;
    write_aligned(&rows, |j, _| j < 2, out)?;
    writeln!(out, "intervals: {METHOD}")?;
    for note in ci.notes() {
        writeln!(out, "{note}")?;
    }
    Ok(())
}

fn pair(i: Interval) -> Value {
    i.map_or(Value::Null, |(lo, hi)| json!([lo, hi]))
}

/// JSON: the report's document, each node with `"ci": {"ps": [lo, hi],
/// "pf", "mtts", "mttf"}`, and a top-level `"ci"` with level, method,
/// draws, seed, the fixed parameters and the leaves with halts drawn
/// independently (no `cov:`).
pub fn report_json(report: &Report, ci: &Intervals) -> Value {
    let mut v = super::json::report_value(report);
    if let Some(nodes) = v.get_mut("nodes").and_then(Value::as_array_mut) {
        for (n, c) in nodes.iter_mut().zip(&ci.nodes) {
            if let Some(o) = n.as_object_mut() {
                o.insert(
                    "ci".into(),
                    json!({"ps": pair(c[0]), "pf": pair(c[1]), "mtts": pair(c[2]), "mttf": pair(c[3])}),
                );
            }
        }
    }
    if let Some(o) = v.as_object_mut() {
        o.insert(
            "ci".into(),
            json!({
                "level": ci.level,
                "method": METHOD,
                "draws": ci.draws,
                "seed": ci.seed,
                "fixed": ci.fixed,
                "held": ci.held,
                "independent": ci.independent,
            }),
        );
    }
    v
}

/// Writes [`report_json`].
pub fn write_json(report: &Report, ci: &Intervals, out: &mut dyn Write) -> io::Result<()> {
    serde_json::to_writer_pretty(&mut *out, &report_json(report, ci))?;
    writeln!(out)
}

/// CSV: `name,path,kind,depth` then each figure with `_lo` and `_hi`
/// columns (empty where undefined), full precision.
pub fn write_csv(report: &Report, ci: &Intervals, out: &mut dyn Write) -> io::Result<()> {
    let mut w = csv::Writer::from_writer(out);
    let mut header: Vec<String> = ["name", "path", "kind", "depth"].map(String::from).to_vec();
    for f in ["ps", "pf", "mtts", "mttf"] {
        header.extend([f.to_string(), format!("{f}_lo"), format!("{f}_hi")]);
    }
    w.write_record(&header).map_err(io_error)?;
    let opt = |x: Option<f64>| x.map_or_else(String::new, full);
    for (n, c) in report.nodes.iter().zip(&ci.nodes) {
        let f = &n.figures;
        let mut row = vec![
            n.name.clone(),
            n.path.clone(),
            n.kind.to_string(),
            n.depth.to_string(),
        ];
        for (x, i) in [Some(f.ps), Some(f.pf), f.mtts, f.mttf].into_iter().zip(c) {
            row.extend([opt(x), opt(i.map(|p| p.0)), opt(i.map(|p| p.1))]);
        }
        w.write_record(&row).map_err(io_error)?;
    }
    w.flush()
}
