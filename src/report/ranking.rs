//! Output of `btrel compare`: a ranked table, JSON or CSV.

use std::io::{self, Write};

use serde_json::{json, Map, Value};

use super::number::{full, significant, significant_or_dash};
use crate::compare::{Candidate, Comparison, Objective};
use crate::tree::Tree;

fn order_label(tree: &Tree, order: &[usize]) -> String {
    order
        .iter()
        .map(|&c| tree.node(c).name.as_str())
        .collect::<Vec<_>>()
        .join(" > ")
}

fn candidate_label(tree: &Tree, cmp: &Comparison, c: &Candidate) -> String {
    if cmp.nodes.len() == 1 {
        order_label(tree, &c.orders[0])
    } else {
        cmp.nodes
            .iter()
            .zip(&c.orders)
            .map(|(&n, o)| format!("{}: {}", tree.node(n).name, order_label(tree, o)))
            .collect::<Vec<_>>()
            .join("; ")
    }
}

fn objective_text(cmp: &Comparison) -> String {
    match cmp.objective {
        Objective::SuccessBy => format!(
            "largest P(success by {} s)",
            full(cmp.deadline.unwrap_or(0.0))
        ),
        Objective::MeanTime => "smallest mean time E[T]".into(),
        Objective::Mtts => "smallest MTTS".into(),
        Objective::Mttf => "smallest MTTF".into(),
    }
}

fn value(cmp: &Comparison, c: &Candidate) -> Option<f64> {
    match cmp.objective {
        Objective::MeanTime => Some(c.root.mean_time()),
        Objective::Mtts => c.root.mtts,
        Objective::Mttf => c.root.mttf,
        Objective::SuccessBy => c.success_by_deadline,
    }
}

/// The ranked table, best first, top `k` rows (plus the given ordering if
/// it is not among them).
pub fn write_table(tree: &Tree, cmp: &Comparison, k: usize, out: &mut dyn Write) -> io::Result<()> {
    let names: Vec<&str> = cmp
        .nodes
        .iter()
        .map(|&n| tree.node(n).name.as_str())
        .collect();
    writeln!(
        out,
        "{} orderings of {} — objective: {} — method: {} — search: {}{}",
        cmp.candidates.len(),
        names.join(", "),
        objective_text(cmp),
        cmp.method.name(),
        cmp.search.name(),
        if cmp.proven_optimal {
            " (best is proven optimal)"
        } else {
            " (best is not proven optimal)"
        }
    )?;
    for n in &cmp.notes {
        writeln!(out, "note: {n}")?;
    }
    let given = cmp.candidates.iter().find(|c| c.given);
    let mut header = vec!["rank", "ordering", "ps", "MTTS", "MTTF", "E[T]"];
    let deadline_header = cmp.deadline.map(|d| format!("P(S by {})", full(d)));
    if let Some(h) = &deadline_header {
        header.push(h);
    }
    header.push("");
    let mut rows: Vec<Vec<String>> = Vec::new();
    for (i, c) in cmp.candidates.iter().enumerate() {
        if i >= k && !c.given {
            continue;
        }
        let mut row = vec![
            (i + 1).to_string(),
            candidate_label(tree, cmp, c),
            significant(c.root.ps, 5),
            significant_or_dash(c.root.mtts, 5),
            significant_or_dash(c.root.mttf, 5),
            significant(c.root.mean_time(), 5),
        ];
        if cmp.deadline.is_some() {
            row.push(significant_or_dash(c.success_by_deadline, 5));
        }
        let mut mark = Vec::new();
        if i == 0 {
            mark.push("best".to_string());
        }
        if c.given {
            mark.push("given".to_string());
        }
        if i == 0 && !c.given {
            if let (Some(b), Some(g)) = (value(cmp, c), given.and_then(|g| value(cmp, g))) {
                let sign = if b >= g { "+" } else { "" };
                mark.push(format!("{sign}{} vs given", significant(b - g, 4)));
            }
        }
        row.push(mark.join(", "));
        rows.push(row);
    }
    rows.insert(0, header.iter().map(|h| h.to_string()).collect());
    super::table::write_aligned(&rows, |j, n| j == 1 || j + 1 == n, out)?;
    Ok(())
}

fn candidate_json(tree: &Tree, cmp: &Comparison, c: &Candidate) -> Value {
    let names =
        |o: &[usize]| -> Vec<String> { o.iter().map(|&i| tree.node(i).name.clone()).collect() };
    let mut m = Map::new();
    m.insert("order".into(), json!(names(&c.orders[0])));
    if cmp.nodes.len() > 1 {
        let mut orders = Map::new();
        for (&n, o) in cmp.nodes.iter().zip(&c.orders) {
            orders.insert(tree.node(n).name.clone(), json!(names(o)));
        }
        m.insert("orders".into(), Value::Object(orders));
    }
    m.insert("given".into(), json!(c.given));
    m.insert("ps".into(), json!(c.root.ps));
    m.insert("mtts".into(), json!(c.root.mtts));
    m.insert("mttf".into(), json!(c.root.mttf));
    m.insert("mean_time".into(), json!(c.root.mean_time()));
    m.insert("success_by_deadline".into(), json!(c.success_by_deadline));
    Value::Object(m)
}

/// JSON: `{"objective", "deadline", "method", "nodes", "search",
/// "proven_optimal", "orderings": [...]}` with the top `k` orderings.
pub fn write_json(tree: &Tree, cmp: &Comparison, k: usize, out: &mut dyn Write) -> io::Result<()> {
    let v = json!({
        "objective": cmp.objective.name(),
        "deadline": cmp.deadline,
        "method": cmp.method.name(),
        "nodes": cmp.nodes.iter().map(|&n| tree.node(n).name.clone()).collect::<Vec<_>>(),
        "search": cmp.search.name(),
        "proven_optimal": cmp.proven_optimal,
        "notes": cmp.notes,
        "orderings": cmp.candidates.iter().take(k).map(|c| candidate_json(tree, cmp, c)).collect::<Vec<_>>(),
    });
    serde_json::to_writer_pretty(&mut *out, &v)?;
    writeln!(out)
}

/// CSV: `rank,ordering,given,ps,mtts,mttf,mean_time,success_by_deadline`.
pub fn write_csv(tree: &Tree, cmp: &Comparison, k: usize, out: &mut dyn Write) -> io::Result<()> {
    write_csv_inner(tree, cmp, k, out).map_err(super::csv::io_error)
}

fn write_csv_inner(
    tree: &Tree,
    cmp: &Comparison,
    k: usize,
    out: &mut dyn Write,
) -> csv::Result<()> {
    let mut w = csv::Writer::from_writer(out);
    w.write_record([
        "rank",
        "ordering",
        "given",
        "ps",
        "mtts",
        "mttf",
        "mean_time",
        "success_by_deadline",
    ])?;
    let opt = |x: Option<f64>| x.map_or_else(String::new, full);
    for (i, c) in cmp.candidates.iter().take(k).enumerate() {
        w.write_record([
            (i + 1).to_string(),
            candidate_label(tree, cmp, c),
            c.given.to_string(),
            full(c.root.ps),
            opt(c.root.mtts),
            opt(c.root.mttf),
            full(c.root.mean_time()),
            opt(c.success_by_deadline),
        ])?;
    }
    w.flush()?;
    Ok(())
}

/// The ordering's label used in the `ordering` column of `--curves`.
pub fn label(tree: &Tree, cmp: &Comparison, c: &Candidate) -> String {
    candidate_label(tree, cmp, c)
}
