//! JSON output, numbers at full precision (shortest text that round-trips).

use std::io::{self, Write};

use serde_json::{json, Value};

use super::{Exporter, Report};

/// `{"tree", "method", "nodes": [{"name", "path", "kind", "ps", "pf", "mtts",
/// "mttf", "mu", "nu"}]}`; undefined figures are `null`. When some node
/// may never return, every node also has `"never"` (P(never returns)).
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct JsonExporter;

/// The report as a JSON value.
pub fn report_value(report: &Report) -> Value {
    let defective = report
        .nodes
        .iter()
        .any(|n| n.figures.never() > super::table::NEVER_SHOWN);
    let nodes: Vec<Value> = report
        .nodes
        .iter()
        .map(|n| {
            let f = &n.figures;
            let mut v = json!({
                "name": n.name,
                "path": n.path,
                "kind": n.kind,
                "ps": f.ps,
                "pf": f.pf,
                "mtts": f.mtts,
                "mttf": f.mttf,
                "mu": f.mu(),
                "nu": f.nu(),
            });
            // P(never returns), when some node may never return
            if defective {
                v["never"] = json!(f.never());
            }
            v
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
