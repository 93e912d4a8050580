//! The output layer: where results go (a file written atomically, or
//! standard output) and the CLI's own CSV tables, written by `csv::Writer`.

use std::io::{self, Write};
use std::path::Path;

use btrel::curve::CurvePoint;
use btrel::report::number::full;
use btrel::sim::CurvePoint as SimPoint;
use btrel::tree::Tree;

use super::advice::write_error;
use super::Failure;

/// Writes to a file atomically, or to standard output. A closed pipe on
/// standard output (e.g. `| head`) ends the program quietly.
pub(super) fn emit(
    path: Option<&Path>,
    write: impl FnOnce(&mut dyn Write) -> io::Result<()>,
) -> Result<(), Failure> {
    match path.filter(|p| *p != Path::new("-")) {
        Some(p) => {
            btrel::output::write_atomic(p, write).map_err(|e| Failure::input(write_error(p, &e)))
        }
        None => {
            let stdout = io::stdout();
            let mut lock = io::BufWriter::new(stdout.lock());
            match write(&mut lock).and_then(|()| lock.flush()) {
                Ok(()) => Ok(()),
                Err(e) if e.kind() == io::ErrorKind::BrokenPipe => Ok(()),
                Err(e) => Err(Failure::analysis(format!(
                    "cannot write to standard output: {e}"
                ))),
            }
        }
    }
}

/// A CSV writer over `out`: fields quoted only when needed, `\n` line ends.
fn csv_writer(out: &mut dyn Write) -> csv::Writer<&mut dyn Write> {
    csv::WriterBuilder::new().from_writer(out)
}

/// A `csv` error as the I/O error it wraps.
fn csv_error(e: csv::Error) -> io::Error {
    match e.into_kind() {
        csv::ErrorKind::Io(e) => e,
        other => io::Error::other(format!("{other:?}")),
    }
}

/// One node's π(t), with its simulated curve (`curve --mc`).
pub(super) type NodeCurve = (usize, Vec<CurvePoint>, Option<Vec<SimPoint>>);

/// The CSV of `btrel curve`: `node,t,success,failure,running`, then the
/// `--ci` bands and the `--mc` columns when given; one row per node per time,
/// numbers at full precision.
pub(super) struct CurveCsv<'a> {
    pub(super) tree: &'a Tree,
    pub(super) curves: &'a [NodeCurve],
    /// Three intervals (success, failure, running) per row, in row order.
    pub(super) bands: Option<&'a [Option<(f64, f64)>]>,
    pub(super) simulated: bool,
}

impl CurveCsv<'_> {
    pub(super) fn write(&self, out: &mut dyn Write) -> io::Result<()> {
        let mut w = csv_writer(out);
        let mut header = vec!["node", "t", "success", "failure", "running"];
        if self.bands.is_some() {
            header.extend([
                "success_lo",
                "success_hi",
                "failure_lo",
                "failure_hi",
                "running_lo",
                "running_hi",
            ]);
        }
        if self.simulated {
            header.extend(["mc_success", "mc_failure", "mc_running"]);
        }
        w.write_record(&header).map_err(csv_error)?;
        let mut row = 0;
        for (id, points, simulated) in self.curves {
            let name = &self.tree.node(*id).name;
            for (k, p) in points.iter().enumerate() {
                let mut record = vec![
                    name.clone(),
                    full(p.t),
                    full(p.success),
                    full(p.failure),
                    full(p.running),
                ];
                if let Some(b) = self.bands {
                    for i in &b[3 * row..3 * row + 3] {
                        match i {
                            Some((lo, hi)) => record.extend([full(*lo), full(*hi)]),
                            None => record.extend([String::new(), String::new()]),
                        }
                    }
                }
                row += 1;
                if let Some(s) = simulated {
                    let m = &s[k];
                    record.extend([
                        full(m.success.mean),
                        full(m.failure.mean),
                        full(m.running.mean),
                    ]);
                }
                w.write_record(&record).map_err(csv_error)?;
            }
        }
        w.flush()
    }
}

/// The CSV of `compare --curves`: the root's π(t) under each ordering,
/// `ordering,node,t,success,failure,running`.
pub(super) fn write_orderings_csv(
    root: &str,
    rows: &[(String, Vec<CurvePoint>)],
    out: &mut dyn Write,
) -> io::Result<()> {
    let mut w = csv_writer(out);
    w.write_record(["ordering", "node", "t", "success", "failure", "running"])
        .map_err(csv_error)?;
    for (label, points) in rows {
        for p in points {
            w.write_record([
                label.as_str(),
                root,
                &full(p.t),
                &full(p.success),
                &full(p.failure),
                &full(p.running),
            ])
            .map_err(csv_error)?;
        }
    }
    w.flush()
}
