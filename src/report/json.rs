//! JSON output, numbers at full precision (shortest text that round-trips).

use std::io::{self, Write};

use serde_json::{json, Value};

use super::{Exporter, Report};

/// `{"tree", "method", "nodes": [{"name", "path", "kind", "ps", "pf", "mtts",
/// "mttf", "mu", "nu"}]}`; undefined figures are `null`.
#[derive(Debug, Clone, Copy, Default)]
pub struct JsonExporter;

/// The report as a JSON value.
pub fn report_value(report: &Report) -> Value {
    let nodes: Vec<Value> = report
        .nodes
        .iter()
        .map(|n| {
            let f = &n.figures;
            json!({
                "name": n.name,
                "path": n.path,
                "kind": n.kind,
                "ps": f.ps,
                "pf": f.pf,
                "mtts": f.mtts,
                "mttf": f.mttf,
                "mu": f.mu(),
                "nu": f.nu(),
            })
        })
        .collect();
    json!({
        "tree": report.tree,
        "method": report.method.name(),
        "nodes": nodes,
    })
}

impl Exporter for JsonExporter {
    fn write(&self, report: &Report, out: &mut dyn Write) -> io::Result<()> {
        serde_json::to_writer_pretty(&mut *out, &report_value(report))?;
        writeln!(out)
    }
}
