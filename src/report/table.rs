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
        let mut rows: Vec<[String; 8]> = Vec::with_capacity(report.nodes.len());
        for n in &report.nodes {
            let f = &n.figures;
            rows.push([
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
        let width = |i: usize| {
            rows.iter()
                .map(|r| r[i].chars().count())
                .chain(std::iter::once(header[i].len()))
                .max()
                .unwrap_or(0)
        };
        let widths: Vec<usize> = (0..8).map(width).collect();
        writeln!(
            out,
            "{} — method: {} (times in s, rates in 1/s)",
            report.tree,
            report.method.name()
        )?;
        let line = |cells: &[&str]| -> String {
            let mut s = String::new();
            for (i, c) in cells.iter().enumerate() {
                let pad = widths[i] - c.chars().count();
                if i < 2 {
                    s.push_str(c);
                    s.push_str(&" ".repeat(pad));
                } else {
                    s.push_str(&" ".repeat(pad));
                    s.push_str(c);
                }
                if i + 1 < cells.len() {
                    s.push_str("  ");
                }
            }
            s.trim_end().to_string()
        };
        writeln!(out, "{}", line(&header))?;
        for r in &rows {
            let cells: Vec<&str> = r.iter().map(String::as_str).collect();
            writeln!(out, "{}", line(&cells))?;
        }
        Ok(())
    }
}
