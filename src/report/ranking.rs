//! Output of `btrel compare`: a ranked table, JSON or CSV.

use std::io::{self, Write};

use serde_json::{json, Map, Value};

use crate::compare::{Candidate, Comparison, Objective, Search};
use crate::number::{full, significant, significant_or_dash};
use crate::tree::Tree;

fn order_label(tree: &Tree, order: &[usize]) -> String {
    order
        .iter()
        .map(|&c| tree.node(c).name.as_str())
        .collect::<Vec<_>>()
        .join(" > ")
}

fn candidate_label(tree: &Tree, cmp: &Comparison, c: &Candidate) -> String {
    if cmp.nodes.is_empty() {
        "(as given)".to_string()
    } else if cmp.nodes.len() == 1 {
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

/// Width of the table (and of every line of `compare`'s text output).
pub const TABLE_WIDTH: usize = 100;

fn width(s: &str) -> usize {
    textwrap::core::display_width(s)
}

/// Joins words that [`wrap_prose`] keeps on one line (printed as a space).
const NBSP: char = '\u{a0}';

fn unbreakable(s: &str) -> String {
    s.replace(' ', &NBSP.to_string())
}

/// Wraps prose to `TABLE_WIDTH`, continuation lines indented by two.
fn wrap_prose(text: &str, out: &mut dyn Write) -> io::Result<()> {
    let options = textwrap::Options::new(TABLE_WIDTH).subsequent_indent("  ");
    for line in textwrap::wrap(text, options) {
        writeln!(out, "{}", line.replace(NBSP, " "))?;
    }
    Ok(())
}

/// The ordering as units that stay on one line: `name >`, `node:`, `name;`.
fn ordering_units(
    tree: &Tree,
    cmp: &Comparison,
    c: &Candidate,
    given: Option<&Candidate>,
) -> Vec<String> {
    let order_units = |o: &[usize], last_sep: &str| -> Vec<String> {
        o.iter()
            .enumerate()
            .map(|(i, &n)| {
                let sep = if i + 1 < o.len() { " >" } else { last_sep };
                format!("{}{sep}", tree.node(n).name)
            })
            .collect()
    };
    if cmp.nodes.len() <= 1 {
        return c
            .orders
            .first()
            .map_or_else(|| vec!["(as given)".to_string()], |o| order_units(o, ""));
    }
    let differing: Vec<usize> = (0..cmp.nodes.len())
        .filter(|&k| given.is_none_or(|g| g.orders[k] != c.orders[k]))
        .collect();
    if differing.is_empty() {
        return vec!["(as given)".to_string()];
    }
    let mut units = Vec::new();
    for (i, &k) in differing.iter().enumerate() {
        units.push(format!("{}:", tree.node(cmp.nodes[k]).name));
        let sep = if i + 1 < differing.len() { ";" } else { "" };
        units.extend(order_units(&c.orders[k], sep));
    }
    units
}

/// Greedy line filling of units joined by spaces; a unit wider than
/// `w` is broken.
fn fill(units: &[String], w: usize) -> Vec<String> {
    let mut lines: Vec<String> = Vec::new();
    let mut line = String::new();
    for u in units {
        let pieces: Vec<String> = if width(u) > w {
            textwrap::wrap(u, textwrap::Options::new(w).break_words(true))
                .into_iter()
                .map(|c| c.into_owned())
                .collect()
        } else {
            vec![u.clone()]
        };
        for p in pieces {
            if line.is_empty() {
                line = p;
            } else if width(&line) + 1 + width(&p) <= w {
                line.push(' ');
                line.push_str(&p);
            } else {
                lines.push(std::mem::take(&mut line));
                line = p;
            }
        }
    }
    if !line.is_empty() || lines.is_empty() {
        lines.push(line);
    }
    lines
}

/// The candidates shown, in order: the top `k` and the given ordering.
fn shown(cmp: &Comparison, k: usize) -> impl Iterator<Item = &Candidate> {
    cmp.candidates
        .iter()
        .enumerate()
        .filter(move |(i, c)| *i < k || c.given)
        .map(|(_, c)| c)
}

/// The ranked table, best first, top `k` rows (plus the given ordering if
/// it is not among them), at most [`TABLE_WIDTH`] columns wide: long
/// orderings wrap within their column; with several Fallbacks only those
/// whose order differs from the given one are listed. Tied ranks are
/// marked `=`.
pub fn write_table(tree: &Tree, cmp: &Comparison, k: usize, out: &mut dyn Write) -> io::Result<()> {
    let names: Vec<String> = cmp
        .nodes
        .iter()
        .map(|&n| unbreakable(&tree.node(n).name))
        .collect();
    let title = tree
        .title
        .clone()
        .unwrap_or_else(|| tree.node(Tree::ROOT).name.clone());
    let given = cmp.candidates.iter().find(|c| c.given);
    let ps = given.map_or(f64::NAN, |g| g.root.ps);
    if cmp.search == Search::NothingToReorder {
        wrap_prose(&format!("{title}: nothing to reorder."), out)?;
        for n in &cmp.notes {
            wrap_prose(&format!("note: {n}"), out)?;
        }
        if let Some(g) = given {
            wrap_prose(
                &format!(
                    "the tree as given: ps {}, MTTS {}, MTTF {}, E[T] {}{}",
                    significant(g.root.ps, 5),
                    significant_or_dash(g.root.mtts, 5),
                    significant_or_dash(g.root.mttf, 5),
                    significant(g.root.mean_time(), 5),
                    match (cmp.deadline, g.success_by_deadline) {
                        (Some(d), Some(p)) =>
                            format!(", P(success by {} s) {}", full(d), significant(p, 5)),
                        _ => String::new(),
                    }
                ),
                out,
            )?;
        }
        return Ok(());
    }
    let what = if names.len() == 1 {
        format!("'{}'", names[0])
    } else {
        let list = if names.len() > 4 {
            format!("{}, {}, …, {}", names[0], names[1], names[names.len() - 1])
        } else {
            names.join(", ")
        };
        format!("{} Fallbacks ({list})", names.len())
    };
    wrap_prose(
        &format!(
            "{title}: {} orderings of the children of {what}",
            crate::compare::count_text(cmp.space)
        ),
        out,
    )?;
    wrap_prose(
        &format!(
            "objective: {} — method: {} — root ps {} for every ordering",
            objective_text(cmp),
            cmp.method.name(),
            significant(ps, 5)
        ),
        out,
    )?;
    wrap_prose(
        &format!(
            "search: {} ({} of {} orderings evaluated) — the best is {}",
            cmp.search.name(),
            crate::compare::count_text(cmp.evaluated as f64),
            crate::compare::count_text(cmp.space),
            if cmp.proven_optimal {
                "proven optimal"
            } else {
                "not proven optimal"
            }
        ),
        out,
    )?;
    for n in &cmp.notes {
        wrap_prose(&format!("note: {n}"), out)?;
    }
    if cmp.nodes.len() > 1 {
        wrap_prose(
            "orderings list only the Fallbacks whose children are in another order than given",
            out,
        )?;
    }

    let mut header: Vec<String> = ["rank", "ordering", "MTTS", "MTTF", "E[T]"]
        .map(String::from)
        .to_vec();
    if let Some(d) = cmp.deadline {
        header.push(format!("P(S by {})", full(d)));
    }
    header.push(String::new());
    let mut rows: Vec<(Vec<String>, Vec<String>)> = Vec::new();
    for c in shown(cmp, k) {
        let rank = format!("{}{}", c.rank, if c.tied { "=" } else { "" });
        let mut cells = vec![
            rank,
            String::new(),
            significant_or_dash(c.root.mtts, 5),
            significant_or_dash(c.root.mttf, 5),
            significant(c.root.mean_time(), 5),
        ];
        if cmp.deadline.is_some() {
            cells.push(significant_or_dash(c.success_by_deadline, 5));
        }
        let mark = match (c.rank == 1, c.given) {
            (true, true) => "best, given",
            (true, false) => "best",
            (false, true) => "given",
            _ => "",
        };
        cells.push(mark.to_string());
        rows.push((cells, ordering_units(tree, cmp, c, given)));
    }
    let n = header.len();
    let mut widths: Vec<usize> = header.iter().map(|h| width(h)).collect();
    for (cells, _) in &rows {
        for (j, c) in cells.iter().enumerate() {
            widths[j] = widths[j].max(width(c));
        }
    }
    let others: usize = widths
        .iter()
        .enumerate()
        .filter(|&(j, _)| j != 1)
        .map(|(_, w)| w)
        .sum::<usize>()
        + 2 * (n - 1);
    let widest_ordering = rows
        .iter()
        .map(|(_, u)| width(&u.join(" ")))
        .max()
        .unwrap_or(0)
        .max(width("ordering"));
    widths[1] = widest_ordering.min(TABLE_WIDTH.saturating_sub(others).max(16));
    let line = |cells: &[String], out: &mut dyn Write| -> io::Result<()> {
        let mut s = String::new();
        for (j, c) in cells.iter().enumerate() {
            let pad = " ".repeat(widths[j].saturating_sub(width(c)));
            if j == 1 || j + 1 == n {
                s.push_str(c);
                s.push_str(&pad);
            } else {
                s.push_str(&pad);
                s.push_str(c);
            }
            s.push_str("  ");
        }
        writeln!(out, "{}", s.trim_end())
    };
    line(&header, out)?;
    for (mut cells, units) in rows {
        let mut lines = fill(&units, widths[1]);
        if lines.len() > 1 && cmp.nodes.len() > 1 {
            // one Fallback per line (or more)
            lines.clear();
            let mut part: Vec<String> = Vec::new();
            for u in units {
                let end = u.ends_with(';');
                part.push(u);
                if end {
                    lines.extend(fill(&part, widths[1]));
                    part.clear();
                }
            }
            if !part.is_empty() {
                lines.extend(fill(&part, widths[1]));
            }
        }
        cells[1] = lines[0].clone();
        line(&cells, out)?;
        for l in &lines[1..] {
            let mut blank = vec![String::new(); n];
            blank[1] = l.clone();
            line(&blank, out)?;
        }
    }
    if cmp.candidates.iter().any(|c| c.tied) {
        wrap_prose(
            "= : tied with another ordering (objective equal within 1e-9 relative for times, 1e-11 for probabilities)",
            out,
        )?;
    }
    if let (Some(b), Some(g)) = (cmp.candidates.first(), given) {
        if !b.given {
            if let (Some(bv), Some(gv)) = (value(cmp, b), value(cmp, g)) {
                let sign = if bv >= gv { "+" } else { "" };
                let unit = if cmp.objective == Objective::SuccessBy {
                    ""
                } else {
                    " s"
                };
                wrap_prose(
                    &format!(
                        "best vs given: {} vs {} ({sign}{}{unit})",
                        significant(bv, 5),
                        significant(gv, 5),
                        significant(bv - gv, 4)
                    ),
                    out,
                )?;
            }
        }
    }
    Ok(())
}

fn candidate_json(tree: &Tree, cmp: &Comparison, c: &Candidate) -> Value {
    let names =
        |o: &[usize]| -> Vec<String> { o.iter().map(|&i| tree.node(i).name.clone()).collect() };
    let mut m = Map::new();
    m.insert(
        "order".into(),
        json!(c.orders.first().map_or_else(Vec::new, |o| names(o))),
    );
    if cmp.nodes.len() > 1 {
        let mut orders = Map::new();
        for (&n, o) in cmp.nodes.iter().zip(&c.orders) {
            orders.insert(tree.node(n).name.clone(), json!(names(o)));
        }
        m.insert("orders".into(), Value::Object(orders));
    }
    m.insert("rank".into(), json!(c.rank));
    m.insert("tied".into(), json!(c.tied));
    m.insert("given".into(), json!(c.given));
    m.insert("ps".into(), json!(c.root.ps));
    m.insert("mtts".into(), json!(c.root.mtts));
    m.insert("mttf".into(), json!(c.root.mttf));
    m.insert("mean_time".into(), json!(c.root.mean_time()));
    m.insert("success_by_deadline".into(), json!(c.success_by_deadline));
    Value::Object(m)
}

/// JSON: `{"objective", "deadline", "method", "nodes", "search",
/// "proven_optimal", "orderings_total", "evaluated", "notes", "orderings":
/// [...]}` with the top `k` orderings and the given one, in table order.
pub fn write_json(tree: &Tree, cmp: &Comparison, k: usize, out: &mut dyn Write) -> io::Result<()> {
    let v = json!({
        "objective": cmp.objective.name(),
        "deadline": cmp.deadline,
        "method": cmp.method.name(),
        "nodes": cmp.nodes.iter().map(|&n| tree.node(n).name.clone()).collect::<Vec<_>>(),
        "search": cmp.search.name(),
        "proven_optimal": cmp.proven_optimal,
        "orderings_total": cmp.space,
        "evaluated": cmp.evaluated,
        "notes": cmp.notes,
        "orderings": shown(cmp, k).map(|c| candidate_json(tree, cmp, c)).collect::<Vec<_>>(),
    });
    serde_json::to_writer_pretty(&mut *out, &v)?;
    writeln!(out)
}

/// CSV: `rank,ordering,given,ps,mtts,mttf,mean_time,success_by_deadline,tied`,
/// the rows of the table in its order (the top `k` and the given ordering).
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
        "tied",
    ])?;
    let opt = |x: Option<f64>| x.map_or_else(String::new, full);
    for c in shown(cmp, k) {
        w.write_record([
            c.rank.to_string(),
            candidate_label(tree, cmp, c),
            c.given.to_string(),
            full(c.root.ps),
            opt(c.root.mtts),
            opt(c.root.mttf),
            full(c.root.mean_time()),
            opt(c.success_by_deadline),
            c.tied.to_string(),
        ])?;
    }
    w.flush()?;
    Ok(())
}

/// The ordering's label used in the `ordering` column of `--curves`.
pub fn label(tree: &Tree, cmp: &Comparison, c: &Candidate) -> String {
    candidate_label(tree, cmp, c)
}
