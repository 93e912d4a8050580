//! Output of `btrel simulate`, and the Monte Carlo columns of `report --mc`.

use std::io::{self, Write};

use serde_json::{json, Map, Value};

use super::Report;
use crate::number::{full, significant, significant_or_dash};
use crate::sim::{CurvePoint, Estimate, NodeEstimate, SimResult};
use crate::tree::Tree;

fn finite(x: f64) -> Option<f64> {
    x.is_finite().then_some(x)
}

/// One node's simulated figures as flat JSON fields.
fn node_fields(n: &NodeEstimate) -> Map<String, Value> {
    let mut m = Map::new();
    m.insert("ps".into(), json!(n.ps.mean));
    m.insert("ps_se".into(), json!(finite(n.ps.se)));
    m.insert("pf".into(), json!(n.pf.mean));
    m.insert("pf_se".into(), json!(finite(n.pf.se)));
    // runs that never return: only when some did
    if n.never.mean > 0.0 {
        m.insert("never".into(), json!(n.never.mean));
        m.insert("never_se".into(), json!(finite(n.never.se)));
    }
    for (key, e) in [("mtts", &n.mtts), ("mttf", &n.mttf)] {
        m.insert(key.into(), json!(e.map(|e| e.mean)));
        m.insert(format!("{key}_se"), json!(e.and_then(|e| finite(e.se))));
        m.insert(
            format!("{key}_ci95"),
            json!(e.filter(|e| e.se.is_finite()).map(|e| [e.ci95.0, e.ci95.1])),
        );
        m.insert(format!("{key}_runs"), json!(e.map_or(0, |e| e.count)));
    }
    m
}

/// JSON: `{"runs", "seed", "nodes": [{"name", "path", "kind", "ps", "ps_se",
/// "pf", "pf_se", "mtts", "mtts_se", "mtts_ci95", ...}], "curve": [{"t",
/// "success", "success_se", "failure", "failure_se", "running",
/// "running_se"}]}`.
pub fn write_json(tree: &Tree, r: &SimResult, out: &mut dyn Write) -> io::Result<()> {
    let nodes: Vec<Value> = r
        .nodes
        .iter()
        .map(|n| {
            let node = tree.node(n.node);
            let mut m = Map::new();
            m.insert("name".into(), json!(node.name));
            m.insert("path".into(), json!(node.path));
            m.insert("kind".into(), json!(node.kind.keyword()));
            m.extend(node_fields(n));
            Value::Object(m)
        })
        .collect();
    let curve: Vec<Value> = r
        .curve
        .iter()
        .map(|p| {
            json!({
                "t": p.t,
                "success": p.success.mean, "success_se": p.success.se,
                "failure": p.failure.mean, "failure_se": p.failure.se,
                "running": p.running.mean, "running_se": p.running.se,
            })
        })
        .collect();
    let v = json!({"runs": r.runs, "seed": r.seed, "nodes": nodes, "curve": curve});
    serde_json::to_writer_pretty(&mut *out, &v)?;
    writeln!(out)
}

fn pm(e: Option<&Estimate>) -> String {
    match e {
        None => "—".into(),
        Some(e) if e.se.is_finite() => {
            format!("{} ± {}", significant(e.mean, 5), significant(e.se, 2))
        }
        Some(e) => format!("{} ± ∞", significant(e.mean, 5)),
    }
}

/// `1 run`, `20 runs`.
fn runs(n: u64) -> String {
    format!("{n} {}", if n == 1 { "run" } else { "runs" })
}

/// Conditional means (MTTS, MTTF) resting on fewer runs than this are
/// marked in tables: their standard error is itself too uncertain to trust.
pub const FEW_RUNS: u64 = 30;

/// A conditional mean ± its standard error, marked `[n runs]` when it rests
/// on fewer than [`FEW_RUNS`] runs.
fn pm_conditional(e: Option<&Estimate>, marked: &mut bool) -> String {
    match e {
        Some(x) if x.count < FEW_RUNS => {
            *marked = true;
            format!("{} [{}]", pm(e), runs(x.count))
        }
        _ => pm(e),
    }
}

fn aligned(rows: &[Vec<String>], left: usize, out: &mut dyn Write) -> io::Result<()> {
    super::table::write_aligned(rows, |j, _| j < left, out)
}

/// The simulation as tables: per node (mean ± standard error), then the
/// curve if times were requested.
pub fn write_table(tree: &Tree, r: &SimResult, out: &mut dyn Write) -> io::Result<()> {
    writeln!(
        out,
        "{} — Monte Carlo: {} per node, seed {} (estimate ± standard error; times in s)",
        super::title(tree),
        runs(r.runs),
        r.seed
    )?;
    let mut marked = false;
    write_node_table(
        tree,
        &r.nodes,
        |_, n| {
            [
                pm(Some(&n.ps)),
                pm(Some(&n.never)),
                pm_conditional(n.mtts.as_ref(), &mut marked),
                pm_conditional(n.mttf.as_ref(), &mut marked),
            ]
        },
        out,
    )?;
    if marked {
        writeln!(
            out,
            "[n runs]: a mean time from fewer than {FEW_RUNS} successful (MTTS) or failed (MTTF) runs; \
             its standard error is unreliable — simulate more runs"
        )?;
    }
    write_curve_table(&r.curve, |e| pm(Some(e)), out)
}

/// The per-node table of a simulation, one row per node of `nodes`: the
/// node (indented by depth), its kind, then `cells(i, n)` for the i-th
/// node: ps, never, MTTS, MTTF; the never column only where some runs never
/// returned.
pub(super) fn write_node_table(
    tree: &Tree,
    nodes: &[NodeEstimate],
    mut cells: impl FnMut(usize, &NodeEstimate) -> [String; 4],
    out: &mut dyn Write,
) -> io::Result<()> {
    // a column for the runs that never return, when some did
    let never = nodes.iter().any(|n| n.never.mean > 0.0);
    let columns = |node: String, kind: String, [ps, nv, mtts, mttf]: [String; 4]| {
        let mut row = vec![node, kind, ps, mtts, mttf];
        if never {
            row.insert(3, nv);
        }
        row
    };
    let header = ["ps", "never", "MTTS", "MTTF"].map(String::from);
    let mut rows = vec![columns("node".into(), "kind".into(), header)];
    let root_depth = tree.node(nodes[0].node).depth;
    for (i, n) in nodes.iter().enumerate() {
        let node = tree.node(n.node);
        rows.push(columns(
            format!("{}{}", "  ".repeat(node.depth - root_depth), node.name),
            node.kind.keyword().into(),
            cells(i, n),
        ));
    }
    aligned(&rows, 2, out)
}

/// The curve of a simulation as a table after a blank line (nothing when
/// there is no curve): t, then `cell` of P(success by t), P(failure by t)
/// and P(running).
pub(super) fn write_curve_table(
    curve: &[CurvePoint],
    cell: impl Fn(&Estimate) -> String,
    out: &mut dyn Write,
) -> io::Result<()> {
    if curve.is_empty() {
        return Ok(());
    }
    writeln!(out)?;
    let mut rows = vec![vec![
        "t".to_string(),
        "P(success by t)".into(),
        "P(failure by t)".into(),
        "P(running)".into(),
    ]];
    for p in curve {
        rows.push(vec![
            full(p.t),
            cell(&p.success),
            cell(&p.failure),
            cell(&p.running),
        ]);
    }
    aligned(&rows, 0, out)
}

/// CSV of the per-node figures:
/// `name,path,kind,runs,ps,ps_se,pf,pf_se,mtts,mtts_se,mttf,mttf_se`.
pub fn write_csv(tree: &Tree, r: &SimResult, out: &mut dyn Write) -> io::Result<()> {
    let mut w = csv::Writer::from_writer(out);
    let opt = |x: Option<f64>| x.filter(|v| v.is_finite()).map_or_else(String::new, full);
    let res: csv::Result<()> = (|| {
        w.write_record([
            "name", "path", "kind", "runs", "ps", "ps_se", "pf", "pf_se", "mtts", "mtts_se",
            "mttf", "mttf_se",
        ])?;
        for n in &r.nodes {
            let node = tree.node(n.node);
            w.write_record([
                node.name.clone(),
                node.path.clone(),
                node.kind.keyword().to_string(),
                r.runs.to_string(),
                full(n.ps.mean),
                opt(Some(n.ps.se)),
                full(n.pf.mean),
                opt(Some(n.pf.se)),
                opt(n.mtts.map(|e| e.mean)),
                opt(n.mtts.map(|e| e.se)),
                opt(n.mttf.map(|e| e.mean)),
                opt(n.mttf.map(|e| e.se)),
            ])?;
        }
        w.flush()?;
        Ok(())
    })();
    res.map_err(super::csv::io_error)
}

/// One analytic-versus-simulated comparison.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Check {
    /// The analytic value.
    pub analytical: f64,
    /// The simulated estimate.
    pub numerical: f64,
    /// Its standard error.
    pub se: f64,
}

impl Check {
    /// `|numerical − analytical| / |analytical|`.
    pub fn relative_error(&self) -> Option<f64> {
        (self.analytical != 0.0)
            .then(|| ((self.numerical - self.analytical) / self.analytical).abs())
    }
    /// `(numerical − analytical) / se`.
    pub fn z(&self) -> Option<f64> {
        (self.se > 0.0 && self.se.is_finite()).then(|| (self.numerical - self.analytical) / self.se)
    }
}

/// The checks of one node: ps, mu = 1/MTTS and nu = 1/MTTF (standard errors
/// of the rates by the delta method, se(1/X) ≈ se(X)/X²), as in Table 9.1.
pub(crate) fn node_checks(
    report: &super::NodeReport,
    mc: &NodeEstimate,
) -> Vec<(&'static str, Check)> {
    let f = &report.figures;
    let mut out = vec![(
        "ps",
        Check {
            analytical: f.ps,
            numerical: mc.ps.mean,
            se: mc.ps.se,
        },
    )];
    for (name, rate, e) in [("mu", f.mu(), mc.mtts), ("nu", f.nu(), mc.mttf)] {
        if let (Some(a), Some(e)) = (rate, e) {
            if e.mean > 0.0 {
                out.push((
                    name,
                    Check {
                        analytical: a,
                        numerical: 1.0 / e.mean,
                        se: e.se / (e.mean * e.mean),
                    },
                ));
            }
        }
    }
    out
}

/// The Table 9.1-style comparison printed by `report --mc`: every control
/// node's ps, mu and nu, analytical against simulated.
pub fn write_check_table(report: &Report, r: &SimResult, out: &mut dyn Write) -> io::Result<()> {
    writeln!(
        out,
        "\nMonte Carlo check ({} per node, seed {}): z = (numerical − analytical) / standard error",
        runs(r.runs),
        r.seed
    )?;
    let mut rows = vec![vec![
        "node".to_string(),
        "measure".into(),
        "analytical".into(),
        "numerical".into(),
        "relative error".into(),
        "z".into(),
    ]];
    for (n, mc) in report.nodes.iter().zip(&r.nodes) {
        if n.kind == "action" || n.kind == "condition" {
            continue;
        }
        for (measure, c) in node_checks(n, mc) {
            rows.push(vec![
                format!("{}{}", "  ".repeat(n.depth), n.name),
                measure.into(),
                significant(c.analytical, 5),
                significant(c.numerical, 5),
                significant_or_dash(c.relative_error(), 2),
                c.z().map_or("—".into(), |z| format!("{z:.2}")),
            ]);
        }
    }
    aligned(&rows, 2, out)
}

/// `report --mc` as JSON: the report's JSON with an `mc` object, relative
/// errors and z-scores added to each node.
pub fn report_json_with_mc(report: &Report, r: &SimResult) -> Value {
    let mut v = super::json::report_value(report);
    v["mc_runs"] = json!(r.runs);
    v["mc_seed"] = json!(r.seed);
    if let Some(nodes) = v["nodes"].as_array_mut() {
        for ((node, n), mc) in nodes.iter_mut().zip(&report.nodes).zip(&r.nodes) {
            node["mc"] = Value::Object(node_fields(mc));
            let mut rel = Map::new();
            let mut z = Map::new();
            for (measure, c) in node_checks(n, mc) {
                rel.insert(measure.into(), json!(c.relative_error()));
                z.insert(measure.into(), json!(c.z()));
            }
            node["relative_error"] = Value::Object(rel);
            node["z"] = Value::Object(z);
        }
    }
    v
}
