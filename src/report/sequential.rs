//! Output of `btrel simulate --precision`: every figure with its interval,
//! the rules that stopped the runs and the runs they took.

use std::io::{self, Write};

use serde_json::{json, Map, Value};

use crate::number::{full, significant};
use crate::sim::sequential::{Interval, PrecisionResult};
use crate::sim::Estimate;
use crate::tree::Tree;

/// The rule of the probabilities, in words.
pub(crate) const PROBABILITY_RULE: &str = "Okamoto (Chernoff–Hoeffding) bound, pre-computed";
/// The rule of the mean times, in words.
pub(crate) const TIME_RULE: &str = "Chow–Robbins fixed-width sequential interval";

fn percent(level: f64) -> String {
    super::intervals::percent(level)
}

/// `p ± h`, `h` the Okamoto half-width (the interval is clamped to [0, 1]).
fn pm_p(p: f64, r: &PrecisionResult) -> String {
    format!(
        "{} ± {}",
        significant(p, 5),
        significant(r.probability_half_width, 2)
    )
}

/// `estimate ± half-width` (`—` where undefined).
fn pm(mean: Option<f64>, i: &Interval) -> String {
    match (mean, i) {
        (None, _) => "—".into(),
        (Some(m), Some((lo, hi))) => {
            format!(
                "{} ± {}",
                significant(m, 5),
                significant((hi - lo) / 2.0, 2)
            )
        }
        (Some(m), None) => format!("{} ± ∞", significant(m, 5)),
    }
}

/// The sentence on the rules and the runs, without a final newline.
pub(crate) fn rules_line(r: &PrecisionResult) -> String {
    let mut parts = Vec::new();
    if let (Some(eps), Some(n)) = (r.precision.probability, r.okamoto_runs) {
        parts.push(format!(
            "probabilities ±{} by the {PROBABILITY_RULE} ({n} runs)",
            full(eps)
        ));
    }
    if let Some(eps) = r.precision.time {
        parts.push(format!(
            "MTTS and MTTF ±{} s by the {TIME_RULE} (z = {:.3})",
            full(eps),
            r.z
        ));
    }
    format!(
        "stopping rules: {}; {} confidence per figure",
        parts.join("; "),
        percent(r.precision.confidence)
    )
}

/// The figures short of their target, one phrase each.
pub fn missed_phrases(tree: &Tree, r: &PrecisionResult) -> Vec<String> {
    r.missed
        .iter()
        .map(|m| {
            let unit = if m.figure == "ps" { "" } else { " s" };
            let reached = m.half_width.map_or("no interval yet".to_string(), |h| {
                format!("±{}{unit}", significant(h, 2))
            });
            format!(
                "{} of '{}' ({reached}, asked ±{}{unit})",
                if m.figure == "ps" {
                    "the probabilities".to_string()
                } else {
                    m.figure.to_uppercase()
                },
                tree.node(m.node).name,
                significant(m.target, 3)
            )
        })
        .collect()
}

/// The table: a title with the runs used, the rules, per node `estimate ±
/// half-width`, then the curve if times were asked.
pub fn write_table(tree: &Tree, r: &PrecisionResult, out: &mut dyn Write) -> io::Result<()> {
    let s = &r.sim;
    writeln!(
        out,
        "{} — Monte Carlo to a precision: {} runs per node, seed {} (estimate ± half-width \
         of the {} interval; times in s)",
        super::title(tree),
        s.runs,
        s.seed,
        percent(r.precision.confidence)
    )?;
    writeln!(out, "{}", rules_line(r))?;
    super::simulation::write_node_table(
        tree,
        &s.nodes,
        |k, n| {
            let i = &r.intervals[k];
            [
                pm_p(n.ps.mean, r),
                pm_p(n.never.mean, r),
                pm(n.mtts.map(|e| e.mean), &i[3]),
                pm(n.mttf.map(|e| e.mean), &i[4]),
            ]
        },
        out,
    )?;
    super::simulation::write_curve_table(&s.curve, |e| pm_p(e.mean, r), out)?;
    let missed = missed_phrases(tree, r);
    if !missed.is_empty() {
        writeln!(
            out,
            "not reached within {} runs: {}",
            s.runs,
            missed.join(", ")
        )?;
    }
    Ok(())
}

fn interval_fields(m: &mut Map<String, Value>, key: &str, e: Option<&Estimate>, i: &Interval) {
    m.insert(key.into(), json!(e.map(|e| e.mean)));
    m.insert(format!("{key}_lo"), json!(i.map(|x| x.0)));
    m.insert(format!("{key}_hi"), json!(i.map(|x| x.1)));
}

/// JSON: `{"runs", "seed", "confidence", "precision": {"probability",
/// "time"}, "rules": {"probability", "time"}, "okamoto_runs", "reached",
/// "missed": [{"node", "figure", "half_width", "target"}], "nodes":
/// [{"name", "path", "kind", "ps", "ps_lo", "ps_hi", "pf", ..., "never",
/// ..., "mtts", "mtts_lo", "mtts_hi", "mtts_runs", "mttf", ...}], "curve":
/// [{"t", "success", "success_lo", "success_hi", "failure", ...,
/// "running", ...}]}`.
pub fn write_json(tree: &Tree, r: &PrecisionResult, out: &mut dyn Write) -> io::Result<()> {
    let s = &r.sim;
    let nodes: Vec<Value> = s
        .nodes
        .iter()
        .zip(&r.intervals)
        .map(|(n, i)| {
            let node = tree.node(n.node);
            let mut m = Map::new();
            m.insert("name".into(), json!(node.name));
            m.insert("path".into(), json!(node.path));
            m.insert("kind".into(), json!(node.kind.keyword()));
            interval_fields(&mut m, "ps", Some(&n.ps), &i[0]);
            interval_fields(&mut m, "pf", Some(&n.pf), &i[1]);
            interval_fields(&mut m, "never", Some(&n.never), &i[2]);
            interval_fields(&mut m, "mtts", n.mtts.as_ref(), &i[3]);
            m.insert("mtts_runs".into(), json!(n.mtts.map_or(0, |e| e.count)));
            interval_fields(&mut m, "mttf", n.mttf.as_ref(), &i[4]);
            m.insert("mttf_runs".into(), json!(n.mttf.map_or(0, |e| e.count)));
            Value::Object(m)
        })
        .collect();
    let curve: Vec<Value> = s
        .curve
        .iter()
        .zip(&r.curve)
        .map(|(p, i)| {
            let mut m = Map::new();
            m.insert("t".into(), json!(p.t));
            interval_fields(&mut m, "success", Some(&p.success), &i[0]);
            interval_fields(&mut m, "failure", Some(&p.failure), &i[1]);
            interval_fields(&mut m, "running", Some(&p.running), &i[2]);
            Value::Object(m)
        })
        .collect();
    let missed: Vec<Value> = r
        .missed
        .iter()
        .map(|m| {
            json!({
                "node": tree.node(m.node).name,
                "figure": m.figure,
                "half_width": m.half_width,
                "target": m.target,
            })
        })
        .collect();
    let v = json!({
        "runs": s.runs,
        "seed": s.seed,
        "confidence": r.precision.confidence,
        "precision": {"probability": r.precision.probability, "time": r.precision.time},
        "rules": {
            "probability": r.precision.probability.map(|_| PROBABILITY_RULE),
            "time": r.precision.time.map(|_| TIME_RULE),
        },
        "okamoto_runs": r.okamoto_runs,
        "probability_half_width": r.probability_half_width,
        "reached": r.missed.is_empty(),
        "missed": missed,
        "nodes": nodes,
        "curve": curve,
    });
    serde_json::to_writer_pretty(&mut *out, &v)?;
    writeln!(out)
}

/// CSV: `name,path,kind,runs,ps,ps_lo,ps_hi,pf,pf_lo,pf_hi,mtts,mtts_lo,
/// mtts_hi,mttf,mttf_lo,mttf_hi` (empty cells where undefined).
pub fn write_csv(tree: &Tree, r: &PrecisionResult, out: &mut dyn Write) -> io::Result<()> {
    let mut w = csv::Writer::from_writer(out);
    let opt = |x: Option<f64>| x.filter(|v| v.is_finite()).map_or_else(String::new, full);
    let res: csv::Result<()> = (|| {
        w.write_record([
            "name", "path", "kind", "runs", "ps", "ps_lo", "ps_hi", "pf", "pf_lo", "pf_hi", "mtts",
            "mtts_lo", "mtts_hi", "mttf", "mttf_lo", "mttf_hi",
        ])?;
        for (n, i) in r.sim.nodes.iter().zip(&r.intervals) {
            let node = tree.node(n.node);
            let mut rec = vec![
                node.name.clone(),
                node.path.clone(),
                node.kind.keyword().to_string(),
                r.sim.runs.to_string(),
            ];
            for (mean, iv) in [
                (Some(n.ps.mean), &i[0]),
                (Some(n.pf.mean), &i[1]),
                (n.mtts.map(|e| e.mean), &i[3]),
                (n.mttf.map(|e| e.mean), &i[4]),
            ] {
                rec.push(opt(mean));
                rec.push(opt(iv.map(|x| x.0)));
                rec.push(opt(iv.map(|x| x.1)));
            }
            w.write_record(rec)?;
        }
        w.flush()?;
        Ok(())
    })();
    res.map_err(super::csv::io_error)
}
