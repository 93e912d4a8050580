//! Reading robots' execution logs into per-leaf episodes, for `btrel fit`.
//!
//! Three formats: BehaviorTree.CPP v4 FileLogger2 files (`.btlog`,
//! [`btlog`]), BehaviorTree.CPP v4 SqliteLogger databases (`.db3`, `.btdb`,
//! any file starting with the SQLite magic bytes, [`sqlite`]; one log per
//! session) and a plain CSV of episodes (`run,node,start,end,status`,
//! [`csv`]), plus rosbag2 recordings of Nav2's `behavior_tree_log` topic
//! ([`rosbag`]; they carry no tree, so they are read with the tree's XML).
//!
//! An *episode* is one execution of a leaf: it starts when the leaf goes
//! IDLE → RUNNING and ends at SUCCESS or FAILURE; RUNNING → IDLE is a halt:
//! the leaf was interrupted, its duration is right-censored (it would have
//! returned later, with an outcome nobody saw). A leaf that returns without
//! going through RUNNING (IDLE → SUCCESS/FAILURE) is an *instant*: a
//! zero-duration episode, as conditions always are.

pub(crate) mod btlog;
pub mod csv;
pub mod rosbag;
mod rosbag_map;
pub(crate) mod sqlite;

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
    /// The file, as named in messages (`FILE (session N)` for a session of
    /// an SQLite log).
    pub file: String,
    /// The tree's XML embedded in a `.btlog` or an SQLite session (None for
    /// CSV).
    pub xml: Option<String>,
    /// The leaves, in document (or first-appearance) order.
    pub leaves: Vec<LeafLog>,
    /// Transition records (btlog, SQLite) or rows (CSV) read.
    pub records: usize,
    /// Records whose timestamp is earlier than an earlier record's (within
    /// the [`btlog::MAX_STEP_BACK_US`] that BT.CPP's logging threads can swap
    /// records by; each keeps its own timestamp).
    pub out_of_order: usize,
    /// The largest such step back in time, in seconds (0 when none).
    pub max_step_back: f64,
    /// Records at the end of a `.btlog` that repeated the block before them
    /// byte for byte and were dropped (BT.CPP's FileLogger2 can write its
    /// last batch twice); 0 for other formats.
    pub repeated_tail: usize,
}

/// A located error in a log file.
#[derive(Clone, Debug, PartialEq)]
pub struct LogError {
    pub file: String,
    /// Where: e.g. `record 12 (byte offset 8301)` or `line 4`.
    pub at: Option<String>,
    pub message: String,
    /// What the reader could change to get past the error, when the library
    /// knows (typed: a front end phrases it with its own options).
    pub hint: Option<LogHint>,
}

/// The remedy a [`LogError`] points to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LogHint {
    /// A bag without a topic of Nav2's log type: another topic may hold it.
    ChooseTopic,
    /// A bag with several topics of Nav2's log type: one must be chosen.
    ChooseOneTopic,
    /// A SubTree defined in none of the XML files read: the file that
    /// defines it must be read too.
    DefineSubTree,
    /// Status changes that do not fit the tree: the tree read may not be
    /// the one that ran, or the bag mixes runs.
    WrongTree,
    /// A BT.CPP SqliteLogger file given where a rosbag2 file was expected:
    /// it is read as a log on its own.
    NotABag,
    /// A rosbag2 recording read without the tree that ran.
    NeedsTree,
}

impl LogError {
    pub(crate) fn new(file: &str, at: Option<String>, message: impl Into<String>) -> LogError {
        LogError {
            file: file.to_string(),
            at,
            message: message.into(),
            hint: None,
        }
    }

    /// The same error with its remedy.
    pub(crate) fn with_hint(mut self, hint: LogHint) -> LogError {
        self.hint = Some(hint);
        self
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

/// The error for a log file that cannot be read (`file` names it).
pub(crate) fn cannot_read(file: &str, e: std::io::Error) -> LogError {
    LogError::new(file, None, format!("cannot read the file: {e}"))
}

/// The size of a log file in bytes, refused past [`MAX_LOG_BYTES`].
pub(crate) fn checked_len(path: &Path, file: &str) -> Result<u64, LogError> {
    let len = std::fs::metadata(path)
        .map_err(|e| cannot_read(file, e))?
        .len();
    if len > MAX_LOG_BYTES {
        return Err(LogError::new(
            file,
            None,
            format!("the file has {len} bytes, more than the {MAX_LOG_BYTES} bytes btrel reads"),
        ));
    }
    Ok(len)
}

/// File extensions of SQLite logs (BT.CPP requires `.db3` or `.btdb`).
const SQLITE_EXTENSIONS: &[&str] = &["db3", "btdb", "db", "sqlite", "sqlite3"];

/// Reads a log file: an SQLite database (by its first bytes, whatever the
/// extension) gives one log per session; a `.btlog` or CSV file gives one.
pub fn read_logs(path: &Path) -> Result<Vec<Log>, LogError> {
    use std::io::Read;
    let file = path.display().to_string();
    let ext = path
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default();
    let cannot = |e: std::io::Error| cannot_read(&file, e);
    if rosbag::is_rosbag(path) {
        return Err(LogError::new(
            &file,
            None,
            "a rosbag2 recording: its behavior_tree_log carries no tree, so it is read with \
             the tree that ran (rosbag::read)",
        )
        .with_hint(LogHint::NeedsTree));
    }
    let len = checked_len(path, &file)?;
    let mut head = Vec::with_capacity(sqlite::MAGIC.len());
    std::fs::File::open(path)
        .and_then(|f| f.take(sqlite::MAGIC.len() as u64).read_to_end(&mut head))
        .map_err(cannot)?;
    if head == sqlite::MAGIC {
        return sqlite::read(path, &file);
    }
    if SQLITE_EXTENSIONS.contains(&ext.as_str()) {
        return Err(LogError::new(
            &file,
            Some("byte offset 0".into()),
            format!(
                "not an SQLite database: the file does not start with `SQLite format 3` \
                 ({} bytes; truncated, or not written by BT.CPP's SqliteLogger?)",
                len
            ),
        ));
    }
    let bytes = std::fs::read(path).map_err(cannot)?;
    read_bytes(&bytes, &file, &ext).map(|l| vec![l])
}

/// Reads a log file that holds one log: a `.btlog`, a CSV, or an SQLite
/// database of one session ([`read_logs`] reads several).
pub fn read_file(path: &Path) -> Result<Log, LogError> {
    let mut logs = read_logs(path)?;
    if logs.len() != 1 {
        return Err(LogError::new(
            &path.display().to_string(),
            None,
            format!("the database holds {} sessions, not one", logs.len()),
        ));
    }
    Ok(logs.remove(0))
}

/// Reads a `.btlog` or CSV log from memory; `ext` (lower case, no dot)
/// chooses the format, else the first bytes do. SQLite databases are read
/// from their file ([`read_logs`]).
pub fn read_bytes(bytes: &[u8], file: &str, ext: &str) -> Result<Log, LogError> {
    if bytes.starts_with(sqlite::MAGIC) {
        return Err(LogError::new(
            file,
            None,
            "this is an SQLite database: SQLite logs are read from their file, not from memory",
        ));
    }
    if ext == "btlog" || bytes.starts_with(b"BTCPP4-") {
        btlog::read(bytes, file)
    } else {
        csv::read(bytes, file)
    }
}
