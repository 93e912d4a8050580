//! Reading robots' execution logs into per-leaf episodes, for `btrel fit`.
//!
//! Two formats: BehaviorTree.CPP v4 FileLogger2 files (`.btlog`, [`btlog`])
//! and a plain CSV of episodes (`run,node,start,end,status`, [`csv`]).
//! SQLite logger files (`.db3`, `.sqlite`) are not supported yet.
//!
//! An *episode* is one execution of a leaf: it starts when the leaf goes
//! IDLE → RUNNING and ends at SUCCESS or FAILURE; RUNNING → IDLE is a halt:
//! the leaf was interrupted, its duration is right-censored (it would have
//! returned later, with an outcome nobody saw). A leaf that returns without
//! going through RUNNING (IDLE → SUCCESS/FAILURE) is an *instant*: a
//! zero-duration episode, as conditions always are.

pub mod btlog;
pub mod csv;

use std::fmt;
use std::path::Path;

/// How an episode ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum End {
    Success,
    Failure,
    /// Halted while running (or still running when the log ended):
    /// right-censored, the outcome is unknown.
    Halted,
}

/// One execution of a leaf.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Episode {
    /// Seconds from the start to the end (or to the halt).
    pub duration: f64,
    pub end: End,
    /// Returned without a RUNNING state (zero duration).
    pub instant: bool,
}

/// What a log says a leaf is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Declared {
    Action,
    Condition,
    Unknown,
}

/// A leaf of the logged tree and its episodes.
#[derive(Clone, Debug)]
pub struct LeafLog {
    /// The registration ID (BT.CPP) or the CSV's node column.
    pub id: String,
    /// The `name` attribute (BT.CPP logs always write one; it is the ID when
    /// the tree gave none). `None` for CSV rows.
    pub name: Option<String>,
    pub declared: Declared,
    pub episodes: Vec<Episode>,
}

/// One log file, read.
#[derive(Clone, Debug)]
pub struct Log {
    /// The file, as named in messages.
    pub file: String,
    /// The tree's XML embedded in a `.btlog` (None for CSV).
    pub xml: Option<String>,
    /// The leaves, in document (or first-appearance) order.
    pub leaves: Vec<LeafLog>,
    /// Transition records (btlog) or rows (CSV) read.
    pub records: usize,
}

/// A located error in a log file.
#[derive(Clone, Debug, PartialEq)]
pub struct LogError {
    pub file: String,
    /// Where: e.g. `record 12 (byte offset 8301)` or `line 4`.
    pub at: Option<String>,
    pub message: String,
}

impl LogError {
    pub(crate) fn new(file: &str, at: Option<String>, message: impl Into<String>) -> LogError {
        LogError {
            file: file.to_string(),
            at,
            message: message.into(),
        }
    }
}

impl fmt::Display for LogError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match &self.at {
            Some(at) => write!(f, "{}: {}: {}", self.file, at, self.message),
            None => write!(f, "{}: {}", self.file, self.message),
        }
    }
}

impl std::error::Error for LogError {}

/// Largest log file read, in bytes.
pub const MAX_LOG_BYTES: u64 = 1 << 30;

/// Reads a log file, choosing the format by its extension (`.btlog`,
/// `.csv`) or, failing that, by its first bytes.
pub fn read_file(path: &Path) -> Result<Log, LogError> {
    let file = path.display().to_string();
    let ext = path
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default();
    if matches!(ext.as_str(), "db3" | "sqlite" | "sqlite3" | "db") {
        return Err(LogError::new(
            &file,
            None,
            "SQLite logger files (BT.CPP's SqliteLogger) are not supported yet; \
             log with FileLogger2 (.btlog) or convert to the CSV episode format",
        ));
    }
    let meta = std::fs::metadata(path)
        .map_err(|e| LogError::new(&file, None, format!("cannot read the file: {e}")))?;
    if meta.len() > MAX_LOG_BYTES {
        return Err(LogError::new(
            &file,
            None,
            format!(
                "the file has {} bytes, more than the {} bytes btrel reads",
                meta.len(),
                MAX_LOG_BYTES
            ),
        ));
    }
    let bytes = std::fs::read(path)
        .map_err(|e| LogError::new(&file, None, format!("cannot read the file: {e}")))?;
    read_bytes(&bytes, &file, &ext)
}

/// Reads a log from memory; `ext` (lower case, no dot) chooses the format,
/// else the first bytes do.
pub fn read_bytes(bytes: &[u8], file: &str, ext: &str) -> Result<Log, LogError> {
    if bytes.starts_with(b"SQLite format 3\0") {
        return Err(LogError::new(
            file,
            None,
            "this is an SQLite database (BT.CPP's SqliteLogger?); SQLite logs are not supported yet",
        ));
    }
    if ext == "btlog" || bytes.starts_with(b"BTCPP4-") {
        btlog::read(bytes, file)
    } else {
        csv::read(bytes, file)
    }
}
