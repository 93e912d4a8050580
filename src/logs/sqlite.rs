//! BehaviorTree.CPP v4 SqliteLogger files (`.db3`, `.btdb`).
//!
//! Schema (BT.CPP `bt_sqlite_logger.cpp`, 4.6 and later; 4.1–4.5 name the
//! uid column `uid`, which is read too):
//!
//! ```text
//! Definitions (session_id INTEGER PRIMARY KEY AUTOINCREMENT, date TEXT, xml_tree TEXT)
//! Nodes       (session_id INTEGER, fullpath VARCHAR, node_uid INTEGER)
//! Transitions (timestamp INTEGER PRIMARY KEY, session_id INTEGER, node_uid INTEGER,
//!              duration INTEGER, state INTEGER, extra_data VARCHAR)
//! ```
//!
//! Every logger opened on the file adds a *session*: one row of
//! `Definitions` with the tree's XML (every node with its `_uid`, as in a
//! `.btlog`), its nodes in `Nodes`, and one `Transitions` row per status
//! change (transitions to IDLE included), `state` being 0 IDLE, 1 RUNNING,
//! 2 SUCCESS, 3 FAILURE, 4 SKIPPED. `timestamp` is in µs — since the epoch
//! by default, since the logger started with relative timestamps — and made
//! strictly increasing by the logger (a change in the same µs as the last
//! one is logged 1 µs later). Only differences of timestamps are used;
//! `duration`, `extra_data` and `Nodes` are not needed.
//!
//! Each session is read as one log (one run of the tree).

use std::collections::HashMap;
use std::path::Path;

use rusqlite::types::ValueRef;
use rusqlite::{Connection, OpenFlags};

use super::btlog::{step, tree_nodes, Node, Status};
use super::{End, Episode, LeafLog, Log, LogError};
use crate::tree::xml::scan_elements;

/// The first 16 bytes of every SQLite 3 database.
pub(crate) const MAGIC: &[u8] = b"SQLite format 3\0";

/// One session being read.
struct Session {
    id: i64,
    xml: String,
    nodes: HashMap<u16, Node>,
    leaves: Vec<LeafLog>,
    first: Option<i64>,
    last: u64,
    records: usize,
}

fn kind(v: ValueRef<'_>) -> &'static str {
    match v {
        ValueRef::Null => "NULL",
        ValueRef::Integer(_) => "an integer",
        ValueRef::Real(_) => "a real number",
        ValueRef::Text(_) => "text",
        ValueRef::Blob(_) => "a blob",
    }
}

/// Opens an SQLite file read-only (a SqliteLogger database or a rosbag2
/// `.db3`).
pub(crate) fn open_read_only(path: &Path) -> rusqlite::Result<Connection> {
    let flags = OpenFlags::SQLITE_OPEN_READ_ONLY | OpenFlags::SQLITE_OPEN_NO_MUTEX;
    Connection::open_with_flags(path, flags)
}

/// The error for a failed read of `what` (e.g. "the SQLite database") in
/// `file`, located at `at` (e.g. "the schema").
pub(crate) fn damaged(
    file: &str,
    what: &str,
    at: &str,
) -> impl FnOnce(rusqlite::Error) -> LogError {
    let (file, what, at) = (file.to_string(), what.to_string(), at.to_string());
    move |e| {
        LogError::new(
            &file,
            Some(at),
            format!("{what} cannot be read (damaged or truncated?): {e}"),
        )
    }
}

/// The names of the tables of an SQLite file, sorted; a failure is
/// reported as `damaged(file, what, "the schema")`.
pub(crate) fn table_names(
    db: &Connection,
    file: &str,
    what: &str,
) -> Result<Vec<String>, LogError> {
    let damaged = || damaged(file, what, "the schema");
    let mut st = db
        .prepare("SELECT name FROM sqlite_master WHERE type = 'table' ORDER BY name")
        .map_err(damaged())?;
    let rows = st
        .query_map([], |r| r.get::<_, String>(0))
        .map_err(damaged())?;
    rows.collect::<Result<Vec<_>, _>>().map_err(damaged())
}

/// Reads every session of a SqliteLogger database, opened read-only.
pub fn read(path: &Path, file: &str) -> Result<Vec<Log>, LogError> {
    let db = open_read_only(path)
        .map_err(|e| LogError::new(file, None, format!("cannot open the SQLite database: {e}")))?;
    let what = "the SQLite database";
    let damaged = |at: &str| damaged(file, what, at);

    // the schema
    let tables = table_names(&db, file, what)?;
    let columns = |table: &str| -> Result<Vec<String>, LogError> {
        let at = format!("table {table}");
        let mut st = db
            .prepare("SELECT name FROM pragma_table_info(?1)")
            .map_err(damaged(&at))?;
        let mut rows = st.query([table]).map_err(damaged(&at))?;
        let mut cols = Vec::new();
        while let Some(r) = rows.next().map_err(damaged(&at))? {
            cols.push(r.get::<_, String>(0).map_err(damaged(&at))?);
        }
        Ok(cols)
    };
    for (table, needed) in [
        ("Definitions", &["session_id", "xml_tree"][..]),
        ("Transitions", &["timestamp", "session_id", "state"][..]),
    ] {
        if !tables.iter().any(|t| t == table) {
            return Err(LogError::new(
                file,
                Some("the schema".into()),
                format!(
                    "there is no table `{table}` (the tables are: {}): \
                     not a database written by BT.CPP's SqliteLogger",
                    if tables.is_empty() {
                        "none".to_string()
                    } else {
                        tables.join(", ")
                    }
                ),
            ));
        }
        let cols = columns(table)?;
        for c in needed {
            if !cols.iter().any(|x| x == c) {
                return Err(LogError::new(
                    file,
                    Some(format!("table {table}")),
                    format!(
                        "there is no column `{c}` (the columns are: {}): \
                         not a table written by BT.CPP's SqliteLogger",
                        cols.join(", ")
                    ),
                ));
            }
        }
    }
    let tcols = columns("Transitions")?;
    let uid_col = ["node_uid", "uid"]
        .into_iter()
        .find(|c| tcols.iter().any(|x| x == c))
        .ok_or_else(|| {
            LogError::new(
                file,
                Some("table Transitions".into()),
                format!(
                    "there is no column `node_uid` (nor `uid`) (the columns are: {}): \
                     not a table written by BT.CPP's SqliteLogger",
                    tcols.join(", ")
                ),
            )
        })?;

    // the sessions and their trees
    let mut sessions: Vec<Session> = Vec::new();
    let mut by_id: HashMap<i64, usize> = HashMap::new();
    {
        let at = "table Definitions";
        let mut st = db
            .prepare("SELECT rowid, session_id, xml_tree FROM Definitions ORDER BY session_id")
            .map_err(damaged(at))?;
        let mut rows = st.query([]).map_err(damaged(at))?;
        while let Some(r) = rows.next().map_err(damaged(at))? {
            let rowid: i64 = r.get(0).map_err(damaged(at))?;
            let row_at = || Some(format!("table Definitions, row {rowid}"));
            let sid = match r.get_ref(1).map_err(damaged(at))? {
                ValueRef::Integer(i) => i,
                v => {
                    return Err(LogError::new(
                        file,
                        row_at(),
                        format!("session_id is {}, not an integer", kind(v)),
                    ))
                }
            };
            let xml = match r.get_ref(2).map_err(damaged(at))? {
                ValueRef::Text(t) => std::str::from_utf8(t)
                    .map_err(|_| LogError::new(file, row_at(), "xml_tree is not valid UTF-8"))?
                    .to_string(),
                v => {
                    return Err(LogError::new(
                        file,
                        row_at(),
                        format!("xml_tree is {}, not the tree's XML text", kind(v)),
                    ))
                }
            };
            let xml_where = format!("table Definitions, row {rowid} (session {sid}), xml_tree");
            let elems = scan_elements(&xml, "XML").map_err(|e| {
                LogError::new(
                    file,
                    Some(format!("{xml_where}, line {} column {}", e.line, e.column)),
                    e.message.clone(),
                )
            })?;
            let (nodes, leaves) = tree_nodes(&elems, file, &xml_where)?;
            if by_id.insert(sid, sessions.len()).is_some() {
                return Err(LogError::new(
                    file,
                    row_at(),
                    format!("session {sid} is defined twice"),
                ));
            }
            sessions.push(Session {
                id: sid,
                xml,
                nodes,
                leaves,
                first: None,
                last: 0,
                records: 0,
            });
        }
    }
    if sessions.is_empty() {
        return Err(LogError::new(
            file,
            Some("table Definitions".into()),
            "the table is empty: the database holds no logged session",
        ));
    }

    // the transitions, in time order
    let at = "table Transitions";
    let mut st = db
        .prepare(&format!(
            "SELECT rowid, timestamp, session_id, {uid_col}, state FROM Transitions \
             ORDER BY timestamp, rowid"
        ))
        .map_err(damaged(at))?;
    let mut rows = st.query([]).map_err(damaged(at))?;
    while let Some(r) = rows.next().map_err(damaged(at))? {
        let rowid: i64 = r.get(0).map_err(damaged(at))?;
        let row_at = || Some(format!("table Transitions, row {rowid}"));
        let int = |i: usize, name: &str| -> Result<i64, LogError> {
            match r.get_ref(i).map_err(damaged(at))? {
                ValueRef::Integer(v) => Ok(v),
                v => Err(LogError::new(
                    file,
                    row_at(),
                    format!("{name} is {}, not an integer", kind(v)),
                )),
            }
        };
        let t = int(1, "timestamp")?;
        let sid = int(2, "session_id")?;
        let uid = int(3, uid_col)?;
        let state = int(4, "state")?;
        let Some(&si) = by_id.get(&sid) else {
            return Err(LogError::new(
                file,
                row_at(),
                format!("session_id {sid} has no row in the table Definitions (no tree)"),
            ));
        };
        let s = &mut sessions[si];
        let Some(status) = u8::try_from(state).ok().and_then(Status::from_byte) else {
            return Err(LogError::new(
                file,
                row_at(),
                format!(
                    "state {state} is not a BT.CPP status (0 IDLE, 1 RUNNING, 2 SUCCESS, 3 FAILURE, 4 SKIPPED)"
                ),
            ));
        };
        let node = u16::try_from(uid).ok().and_then(|u| s.nodes.get_mut(&u));
        let Some(node) = node else {
            return Err(LogError::new(
                file,
                row_at(),
                format!(
                    "node uid {uid} is not in the tree of session {sid} \
                     (the uids of its nodes are {})",
                    uid_range(&s.nodes)
                ),
            ));
        };
        let first = *s.first.get_or_insert(t);
        // rows come in time order, so t ≥ first
        let rel = u64::try_from(i128::from(t) - i128::from(first)).unwrap_or(0);
        let episode = step(node, status, rel, |d| d as f64 / 1e6)
            .map_err(|m| LogError::new(file, row_at(), format!("(session {sid}) {m}")))?;
        if let (Some(e), Some(l)) = (episode, node.leaf) {
            s.leaves[l].episodes.push(e);
        }
        s.last = rel;
        s.records += 1;
    }

    Ok(sessions
        .into_iter()
        .map(|mut s| {
            // still running when the session ended: censored at its last row
            for node in s.nodes.values() {
                if let (Status::Running, Some(l)) = (node.status, node.leaf) {
                    s.leaves[l].episodes.push(Episode {
                        duration: s.last.saturating_sub(node.started) as f64 / 1e6,
                        end: End::Halted,
                        instant: false,
                    });
                }
            }
            Log {
                file: format!("{file} (session {})", s.id),
                xml: Some(s.xml),
                leaves: s.leaves,
                records: s.records,
                out_of_order: 0,
                max_step_back: 0.0,
                repeated_tail: 0,
            }
        })
        .collect())
}

fn uid_range(nodes: &HashMap<u16, Node>) -> String {
    let lo = nodes.keys().min().copied().unwrap_or(0);
    let hi = nodes.keys().max().copied().unwrap_or(0);
    format!("{lo}..{hi}")
}
