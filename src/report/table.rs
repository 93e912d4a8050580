//! Aligned text table for the terminal.

use std::io::{self, Write};

use super::number::significant_or_dash;
use super::{Exporter, Report};

/// Significant digits in the table.
pub const DIGITS: usize = 5;

/// One row per node, names indented by depth, 5 significant digits,
/// undefined figures shown as `—`.
#[derive(Debug, Clone, Copy, Default)]
pub struct TableExporter;

impl Exporter for TableExporter {
    fn write(&self, report: &Report, out: &mut dyn Write) -> io::Result<()> {
        let header = ["node", "kind", "ps", "pf", "MTTS", "MTTF", "mu", "nu"];
        let mut rows: Vec<Vec<String>> = Vec::with_capacity(report.nodes.len() + 1);
        rows.push(header.iter().map(|h| h.to_string()).collect());
        for n in &report.nodes {
            let f = &n.figures;
            rows.push(vec![
                format!("{}{}", "  ".repeat(n.depth), n.name),
                n.kind.to_string(),
                significant_or_dash(Some(f.ps), DIGITS),
                significant_or_dash(Some(f.pf), DIGITS),
                significant_or_dash(f.mtts, DIGITS),
                significant_or_dash(f.mttf, DIGITS),
                significant_or_dash(f.mu(), DIGITS),
                significant_or_dash(f.nu(), DIGITS),
            ]);
        }
        writeln!(
            out,
            "{} — method: {} (times in s, rates in 1/s)",
            report.tree,
            report.method.name()
        )?;
        write_aligned(&rows, |j, _| j < 2, out)?;
        Ok(())
    }
}

/// Writes rows as columns separated by two spaces, each as wide as its
/// widest cell (counted in characters); `left(column, columns)` says which
/// columns are left-aligned (the others are right-aligned). Trailing spaces
/// are trimmed.
pub fn write_aligned(
    rows: &[Vec<String>],
    left: impl Fn(usize, usize) -> bool,
    out: &mut dyn Write,
) -> io::Result<()> {
    let cols = rows.iter().map(Vec::len).max().unwrap_or(0);
    let widths: Vec<usize> = (0..cols)
        .map(|j| {
            rows.iter()
                .map(|r| r.get(j).map_or(0, |c| c.chars().count()))
                .max()
                .unwrap_or(0)
        })
        .collect();
    let mut line = String::new();
    for r in rows {
        line.clear();
        for (j, c) in r.iter().enumerate() {
            let pad = widths[j] - c.chars().count();
            if left(j, r.len()) {
                line.push_str(c);
                line.extend(std::iter::repeat_n(' ', pad));
            } else {
                line.extend(std::iter::repeat_n(' ', pad));
                line.push_str(c);
            }
            line.push_str("  ");
        }
        writeln!(out, "{}", line.trim_end())?;
    }
    Ok(())
}
