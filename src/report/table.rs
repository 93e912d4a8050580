//! Aligned text table for the terminal.

use std::io::{self, Write};

use rayon::prelude::*;

use super::{Exporter, Report};
use crate::number::significant_or_dash;

/// Significant digits in the table.
pub(crate) const DIGITS: usize = 5;

/// P(never returns) above which the table shows a `never` column (below,
/// `1 − ps − pf` is rounding).
pub(crate) const NEVER_SHOWN: f64 = 1e-12;

/// One row per node, names indented by depth, 5 significant digits,
/// undefined figures shown as `—`.
#[derive(Debug, Clone, Copy, Default)]
pub struct TableExporter;

impl Exporter for TableExporter {
    fn write(&self, report: &Report, out: &mut dyn Write) -> io::Result<()> {
        // a column for P(never returns) when some node may never return
        let defective = report.nodes.iter().any(|n| n.figures.never() > NEVER_SHOWN);
        let header: &[&str] = if defective {
            &[
                "node", "kind", "ps", "pf", "never", "MTTS", "MTTF", "mu", "nu",
            ]
        } else {
            &["node", "kind", "ps", "pf", "MTTS", "MTTF", "mu", "nu"]
        };
        let mut cells = Cells::with_capacity(header.len(), report.nodes.len() + 1);
        cells.push_row(header.iter().copied());
        // formatting numbers dominates on large trees: chunks in parallel
        let chunks: Vec<Cells> = report
            .nodes
            .par_chunks(16_384)
            .map(|chunk| {
                let mut part = Cells::with_capacity(header.len(), chunk.len());
                let mut name = String::new();
                for n in chunk {
                    let f = &n.figures;
                    name.clear();
                    name.extend(std::iter::repeat_n("  ", n.depth));
                    name.push_str(&n.name);
                    let kind = n.kind.to_string();
                    let mut numbers = vec![Some(f.ps), Some(f.pf), f.mtts, f.mttf, f.mu(), f.nu()];
                    if defective {
                        numbers.insert(2, Some(f.never()));
                    }
                    let numbers: Vec<String> = numbers
                        .into_iter()
                        .map(|x| significant_or_dash(x, DIGITS))
                        .collect();
                    part.push_row(
                        [name.as_str(), kind.as_str()]
                            .into_iter()
                            .chain(numbers.iter().map(String::as_str)),
                    );
                }
                part
            })
            .collect();
        for part in &chunks {
            cells.append(part);
        }
        writeln!(
            out,
            "{} — method: {} (times in s, rates in 1/s)",
            report.tree,
            report.method.name()
        )?;
        cells.write_aligned(|j, _| j < 2, out)
    }
}

/// A table's cells in one buffer (a million-row table would otherwise be
/// millions of small strings), with each cell's display width (terminal columns).
#[derive(Debug, Clone, Default)]
pub struct Cells {
    text: String,
    /// End offset in `text` and width of every cell, row after row.
    cells: Vec<(u32, u32)>,
    /// Index in `cells` where each row starts.
    rows: Vec<usize>,
}

impl Cells {
    /// An empty table with room for `rows` rows of `columns` cells.
    pub fn with_capacity(columns: usize, rows: usize) -> Cells {
        Cells {
            text: String::with_capacity(rows * columns * 8),
            cells: Vec::with_capacity(rows * columns),
            rows: Vec::with_capacity(rows),
        }
    }

    /// Appends a row.
    pub fn push_row<'a>(&mut self, row: impl IntoIterator<Item = &'a str>) {
        self.rows.push(self.cells.len());
        for c in row {
            self.text.push_str(c);
            // columns on a terminal: CJK and other wide characters take two
            let width = if c.is_ascii() {
                c.len()
            } else {
                unicode_width::UnicodeWidthStr::width(c)
            };
            self.cells.push((self.text.len() as u32, width as u32));
        }
    }

    /// Appends the rows of another table.
    pub fn append(&mut self, other: &Cells) {
        let (text, cells) = (self.text.len() as u32, self.cells.len());
        self.text.push_str(&other.text);
        self.cells
            .extend(other.cells.iter().map(|&(end, w)| (end + text, w)));
        self.rows.extend(other.rows.iter().map(|&r| r + cells));
    }

    fn row(&self, r: usize) -> impl Iterator<Item = (&str, usize)> {
        let from = self.rows[r];
        let to = self.rows.get(r + 1).copied().unwrap_or(self.cells.len());
        (from..to).map(move |i| {
            let start = if i == 0 {
                0
            } else {
                self.cells[i - 1].0 as usize
            };
            let (end, width) = self.cells[i];
            (&self.text[start..end as usize], width as usize)
        })
    }

    /// Writes the rows as columns separated by two spaces, each as wide as
    /// its widest cell; `left(column, columns)` says which columns are
    /// left-aligned (the others are right-aligned). Trailing spaces are
    /// trimmed.
    pub fn write_aligned(
        &self,
        left: impl Fn(usize, usize) -> bool,
        out: &mut dyn Write,
    ) -> io::Result<()> {
        let mut widths: Vec<usize> = Vec::new();
        for r in 0..self.rows.len() {
            for (j, (_, w)) in self.row(r).enumerate() {
                if j == widths.len() {
                    widths.push(0);
                }
                widths[j] = widths[j].max(w);
            }
        }
        let mut line = String::new();
        for r in 0..self.rows.len() {
            line.clear();
            let n = self.row(r).count();
            for (j, (c, w)) in self.row(r).enumerate() {
                let pad = widths[j] - w;
                if left(j, n) {
                    line.push_str(c);
                    line.extend(std::iter::repeat_n(' ', pad));
                } else {
                    line.extend(std::iter::repeat_n(' ', pad));
                    line.push_str(c);
                }
                line.push_str("  ");
            }
            line.truncate(line.trim_end().len());
            line.push('\n');
            out.write_all(line.as_bytes())?;
        }
        Ok(())
    }
}

/// [`Cells::write_aligned`] for rows of strings (small tables).
pub fn write_aligned(
    rows: &[Vec<String>],
    left: impl Fn(usize, usize) -> bool,
    out: &mut dyn Write,
) -> io::Result<()> {
    let mut cells = Cells::default();
    for r in rows {
        cells.push_row(r.iter().map(String::as_str));
    }
    cells.write_aligned(left, out)
}
