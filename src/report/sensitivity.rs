//! Output of `btrel sensitivity`: table, JSON, CSV.

use std::io::{self, Write};

use serde_json::json;

use super::csv::io_error;
use super::table::write_aligned;
use crate::number::{full, significant};
use crate::sensitivity::{Objective, Sensitivity};
use crate::tree::Tree;

/// Digits of the table.
const DIGITS: usize = 5;

fn deadline(o: Objective) -> Option<f64> {
    match o {
        Objective::SuccessBy(t) => Some(t),
        _ => None,
    }
}

/// The table: the objective, one row per parameter ranked by |elasticity|
/// with the derivative's method and error estimate, then the sentences.
pub fn write_table(
    tree: &Tree,
    s: &Sensitivity,
    sentences: &[String],
    out: &mut dyn Write,
) -> io::Result<()> {
    writeln!(
        out,
        "sensitivity of {} = {} to each leaf parameter, ranked by |elasticity| (d ln O / d ln θ)",
        s.objective.describe(),
        significant(s.value, DIGITS)
    )?;
    let mut rows = vec![[
        "leaf",
        "path",
        "parameter",
        "value",
        "derivative",
        "elasticity",
        "error",
        "method",
    ]
    .map(String::from)
    .to_vec()];
    for r in &s.rows {
        rows.push(vec![
            tree.nodes[r.leaf].name.clone(),
            tree.nodes[r.leaf].path.clone(),
            r.param.name().to_string(),
            significant(r.value, DIGITS),
            significant(r.derivative, DIGITS),
            r.elasticity
                .map_or_else(|| "—".to_string(), |e| significant(e, DIGITS)),
            significant(r.error, 2),
            r.scheme.name().to_string(),
        ]);
    }
    write_aligned(&rows, |j, _| j < 3 || j == 7, out)?;
    for sk in &s.skipped {
        writeln!(out, "not varied: {sk}")?;
    }
    for line in sentences {
        writeln!(out, "* {line}")?;
    }
    Ok(())
}

/// `{"objective", "deadline", "rows": [{"leaf", "path", "parameter",
/// "value", "derivative", "elasticity", "method"}]}`, `method` being
/// `exact` or `richardson`.
pub fn write_json(tree: &Tree, s: &Sensitivity, out: &mut dyn Write) -> io::Result<()> {
    let rows: Vec<_> = s
        .rows
        .iter()
        .map(|r| {
            json!({
                "leaf": tree.nodes[r.leaf].name,
                "path": tree.nodes[r.leaf].path,
                "parameter": r.param.name(),
                "value": r.value,
                "derivative": r.derivative,
                "elasticity": r.elasticity,
                "method": r.scheme.method(),
            })
        })
        .collect();
    let v = json!({
        "objective": s.objective.name(),
        "deadline": deadline(s.objective),
        "rows": rows,
    });
    serde_json::to_writer_pretty(&mut *out, &v)?;
    writeln!(out)
}

/// `leaf,path,parameter,value,derivative,elasticity,error,method`, full
/// precision.
pub fn write_csv(tree: &Tree, s: &Sensitivity, out: &mut dyn Write) -> io::Result<()> {
    let mut w = csv::Writer::from_writer(out);
    w.write_record([
        "leaf",
        "path",
        "parameter",
        "value",
        "derivative",
        "elasticity",
        "error",
        "method",
    ])
    .map_err(io_error)?;
    for r in &s.rows {
        w.write_record([
            tree.nodes[r.leaf].name.clone(),
            tree.nodes[r.leaf].path.clone(),
            r.param.name().to_string(),
            full(r.value),
            full(r.derivative),
            r.elasticity.map_or_else(String::new, full),
            full(r.error),
            r.scheme.name().to_string(),
        ])
        .map_err(io_error)?;
    }
    w.flush()
}
