//! CSV output: one row per node, full precision, empty cells for undefined
//! figures.

use std::io::{self, Write};

use super::number::full;
use super::{Exporter, Report};

/// Header `name,path,kind,depth,ps,pf,mtts,mttf,mu,nu`.
#[derive(Debug, Clone, Copy, Default)]
pub struct CsvExporter;

fn cell(x: Option<f64>) -> String {
    x.map_or_else(String::new, full)
}

impl Exporter for CsvExporter {
    fn write(&self, report: &Report, out: &mut dyn Write) -> io::Result<()> {
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
        w.flush()
    }
}
