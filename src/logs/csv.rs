//! The plain CSV episode format, for runtimes other than BehaviorTree.CPP:
//!
//! ```text
//! run,node,start,end,status
//! 1,move,0.0,4.2,success
//! 1,grasp,4.2,4.9,halted
//! ```
//!
//! One row per episode: the run it belongs to (any text), the node's params
//! key, its start and end in seconds (end ≥ start; end = start is an
//! instant), and how it ended: `success`, `failure` or `halted` (interrupted:
//! a right-censored duration, the outcome unknown).

use std::collections::HashMap;

use super::{Declared, End, Episode, LeafLog, Log, LogError};

const HEADER: [&str; 5] = ["run", "node", "start", "end", "status"];

/// Reads a CSV episode log.
pub fn read(bytes: &[u8], file: &str) -> Result<Log, LogError> {
    let mut rdr = ::csv::ReaderBuilder::new()
        .has_headers(true)
        .trim(::csv::Trim::All)
        .from_reader(bytes);
    let header = rdr
        .headers()
        .map_err(|e| LogError::new(file, Some("line 1".into()), format!("{e}")))?
        .clone();
    let got: Vec<&str> = header.iter().collect();
    if got != HEADER {
        return Err(LogError::new(
            file,
            Some("line 1".into()),
            format!(
                "the header is `{}`; a CSV log has the columns `{}` \
                 (or is this a binary log? .btlog files start with BTCPP4-FileLogger2)",
                got.join(","),
                HEADER.join(",")
            ),
        ));
    }
    let mut leaves: Vec<LeafLog> = Vec::new();
    let mut index: HashMap<String, usize> = HashMap::new();
    let mut rows = 0;
    for rec in rdr.records() {
        let rec = rec.map_err(|e| {
            let at = e.position().map(|p| format!("line {}", p.line()));
            LogError::new(file, at, format!("{e}"))
        })?;
        rows += 1;
        let line = rec.position().map_or(rows + 1, |p| p.line() as usize);
        let at = || Some(format!("line {line}"));
        let node = &rec[1];
        if node.is_empty() {
            return Err(LogError::new(file, at(), "the node is empty"));
        }
        let time = |i: usize| -> Result<f64, LogError> {
            let v: f64 = rec[i].parse().map_err(|_| {
                LogError::new(
                    file,
                    at(),
                    format!("{} `{}` is not a number of seconds", HEADER[i], &rec[i]),
                )
            })?;
            if !v.is_finite() || v < 0.0 {
                return Err(LogError::new(
                    file,
                    at(),
                    format!("{} `{}` must be a finite time ≥ 0 s", HEADER[i], &rec[i]),
                ));
            }
            Ok(v)
        };
        let (start, end) = (time(2)?, time(3)?);
        if end < start {
            return Err(LogError::new(
                file,
                at(),
                format!("the episode ends ({end} s) before it starts ({start} s)"),
            ));
        }
        let end_kind = match rec[4].to_ascii_lowercase().as_str() {
            "success" => End::Success,
            "failure" => End::Failure,
            "halted" => End::Halted,
            s => {
                return Err(LogError::new(
                    file,
                    at(),
                    format!("status `{s}` is not success, failure or halted"),
                ))
            }
        };
        let i = *index.entry(node.to_string()).or_insert_with(|| {
            leaves.push(LeafLog {
                id: node.to_string(),
                name: None,
                declared: Declared::Unknown,
                episodes: Vec::new(),
            });
            leaves.len() - 1
        });
        leaves[i].episodes.push(Episode {
            duration: end - start,
            end: end_kind,
            instant: end == start && end_kind != End::Halted,
        });
    }
    Ok(Log {
        file: file.to_string(),
        xml: None,
        leaves,
        records: rows,
        out_of_order: 0,
        max_step_back: 0.0,
        repeated_tail: 0,
    })
}
