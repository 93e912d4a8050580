//! CSV output: one row per node, full precision, empty cells for undefined
//! figures.

use std::io::{self, Write};

use super::{Exporter, Report};
use crate::number::full;

/// Header `name,path,kind,depth,ps,pf,mtts,mttf,mu,nu`.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct CsvExporter;

fn cell(x: Option<f64>) -> String {
    x.map_or_else(String::new, full)
}

/// A CSV error as the I/O error it wraps (so a closed pipe stays a
/// `BrokenPipe`), or as a generic I/O error.
pub(crate) fn io_error(e: csv::Error) -> io::Error {
    match e.into_kind() {
        csv::ErrorKind::Io(e) => e,
        other => io::Error::other(format!("{other:?}")),
    }
}

impl Exporter for CsvExporter {
    fn write(&self, report: &Report, out: &mut dyn Write) -> io::Result<()> {
        self.write_csv(report, out).map_err(io_error)
    }
}

impl CsvExporter {
    fn write_csv(&self, report: &Report, out: &mut dyn Write) -> csv::Result<()> {
        let mut w = csv::Writer::from_writer(out);
        w.write_record([
            "name", "path", "kind", "depth", "ps", "pf", "mtts", "mttf", "mu", "nu",
        ])?;
        for n in &report.nodes {
            let f = &n.figures;
            w.write_record([
                n.name.clone(),
                n.path.clone(),
                n.kind.to_string(),
                n.depth.to_string(),
                full(f.ps),
                full(f.pf),
                cell(f.mtts),
                cell(f.mttf),
                cell(f.mu()),
                cell(f.nu()),
            ])?;
        }
        w.flush()?;
        Ok(())
    }
}
