//! rosbag2 recordings of Nav2's `behavior_tree_log` topic
//! (`nav2_msgs/msg/BehaviorTreeLog`), for `btrel fit BAG... --tree TREE.xml`.
//!
//! Nav2's bt_navigator publishes, after every tick of its tree, the status
//! changes of that tick:
//!
//! ```text
//! # nav2_msgs/msg/BehaviorTreeLog
//! builtin_interfaces/Time timestamp
//! BehaviorTreeStatusChange[] event_log
//! # nav2_msgs/msg/BehaviorTreeStatusChange
//! builtin_interfaces/Time timestamp   # the change's own time
//! string node_name
//! uint16 uid                          # since navigation2 PR #3750 (2023); older bags lack it
//! string previous_status              # IDLE, RUNNING, SUCCESS, FAILURE (SKIPPED)
//! string current_status
//! ```
//!
//! A recording (`ros2 bag record /behavior_tree_log`) is a folder with a
//! `metadata.yaml` and one or more storage files: MCAP (`.mcap`, the default
//! since ROS 2 Iron; read with Foxglove's `mcap` crate, zstd and lz4 chunks)
//! or SQLite (`.db3`, Humble and older: tables `topics` and `messages`,
//! `message_definitions` since Iron). BAG may name the folder or one of its
//! storage files. A `.db3` of rosbag2 is told from a BT.CPP SqliteLogger file
//! by its tables (`topics`/`messages` versus `Definitions`/`Transitions`).
//!
//! Messages are CDR (XCDR1, the ROS 2 default): a 4-byte encapsulation header
//! (`00 01` little-endian, `00 00` big-endian), then the fields, each aligned
//! to its size counted from the end of the header; a string is a `u32`
//! length counting its terminating NUL, then the bytes and the NUL; a
//! sequence is a `u32` count then its elements. [`decode`] reads these two
//! messages (a few dozen lines; no generic CDR crate is needed for them).
//!
//! The layout (with or without `uid`) comes from the message definition
//! stored in the bag (MCAP schema, `message_definitions` table) when there is
//! one; otherwise both layouts are tried on the first message with changes —
//! a wrong layout reads the `uid` bytes as a string length or the other way
//! round, which almost always gives no valid status strings; when both
//! decode, the one whose uids name the tree's nodes by their names wins —
//! and every later message must decode with the one chosen.
//!
//! The topic carries no tree, so the tree comes from `--tree`; mapping the
//! changes to its nodes (by uid, or by replaying the change sequence against
//! the tree's structure when there is no uid) is in `logs::rosbag_map`.
//!
//! Size: one concern, reading rosbag2 recordings: both storages (MCAP,
//! SQLite), the CDR decoding of the message and the bag's file layout.

use std::path::{Path, PathBuf};

use super::btlog::Status;
pub use super::rosbag_map::Change;
use super::rosbag_map::{BagTree, Replay};
use super::{cannot_read, checked_len, Log, LogError, LogHint};

/// The message type of Nav2's behavior tree log.
pub(crate) const MESSAGE_TYPE: &str = "nav2_msgs/msg/BehaviorTreeLog";
/// The default topic's last name component (any namespace).
pub const TOPIC: &str = "behavior_tree_log";
/// The first 8 bytes of an MCAP file.
pub(crate) const MCAP_MAGIC: &[u8] = b"\x89MCAP0\r\n";

/// Which `BehaviorTreeStatusChange` layout the bag holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Layout {
    /// With `uint16 uid` (navigation2 since 2023).
    WithUid,
    /// Without `uid` (older bags).
    WithoutUid,
}

impl Layout {
    pub fn describe(self) -> &'static str {
        match self {
            Layout::WithUid => "with uid",
            Layout::WithoutUid => "without uid",
        }
    }
}

/// A bag, read.
#[derive(Debug)]
pub struct BagRead {
    pub log: Log,
    /// The topic read.
    pub topic: String,
    /// Messages of that topic.
    pub messages: usize,
    /// The layout, and where it was learnt ("the message definition in the
    /// bag" or "tried on message N").
    pub layout: Option<(Layout, String)>,
    /// Things the user should know (left-truncated episodes, inferred halts).
    pub notes: Vec<String>,
}

/// Whether `path` looks like a rosbag2 recording: a folder with a
/// `metadata.yaml` or a storage file, an MCAP file, or an SQLite file with
/// rosbag2's `topics` and `messages` tables.
pub fn is_rosbag(path: &Path) -> bool {
    if path.is_dir() {
        return path.join("metadata.yaml").is_file()
            || std::fs::read_dir(path).is_ok_and(|d| {
                d.flatten().any(|e| {
                    let p = e.path();
                    matches!(ext(&p).as_str(), "mcap" | "db3")
                })
            });
    }
    let mut head = [0u8; 16];
    let n = std::fs::File::open(path)
        .and_then(|mut f| {
            use std::io::Read;
            f.read(&mut head)
        })
        .unwrap_or(0);
    if head[..n].starts_with(MCAP_MAGIC) || (n == 0 && ext(path) == "mcap") {
        return true;
    }
    if head[..n].starts_with(super::sqlite::MAGIC) {
        return sqlite_tables(path)
            .is_ok_and(|t| t.iter().any(|x| x == "topics") && t.iter().any(|x| x == "messages"));
    }
    ext(path) == "mcap"
}

fn ext(p: &Path) -> String {
    p.extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default()
}

fn sqlite_tables(path: &Path) -> Result<Vec<String>, rusqlite::Error> {
    use rusqlite::{Connection, OpenFlags};
    let db = Connection::open_with_flags(
        path,
        OpenFlags::SQLITE_OPEN_READ_ONLY | OpenFlags::SQLITE_OPEN_NO_MUTEX,
    )?;
    let mut st = db.prepare("SELECT name FROM sqlite_master WHERE type = 'table'")?;
    let rows = st.query_map([], |r| r.get::<_, String>(0))?;
    rows.collect()
}

/// Reads a bag: the `behavior_tree_log` topic (or `topic`) of every storage
/// file, mapped onto the tree of `tree` (plus `includes`, for SubTrees
/// defined in other files).
pub fn read(
    path: &Path,
    tree: &Path,
    includes: &[PathBuf],
    topic: Option<&str>,
) -> Result<BagRead, LogError> {
    let bag = path.display().to_string();
    let tree = BagTree::load(tree, includes)?;
    let files = storage_files(path, &bag)?;
    // the messages of the wanted topics, per file, in order
    let mut topics: Vec<Topic> = Vec::new();
    let mut messages: Vec<Raw> = Vec::new();
    let want = |name: &str, ty: &str| match topic {
        Some(t) => name.trim_start_matches('/') == t.trim_start_matches('/'),
        None => ty == MESSAGE_TYPE,
    };
    for f in &files {
        let (t, m) = read_storage(f, &want)?;
        for x in t {
            if !topics.iter().any(|y| y.name == x.name) {
                topics.push(x);
            }
        }
        messages.extend(m);
    }
    let listing = || {
        if topics.is_empty() {
            "the bag has no topic".to_string()
        } else {
            format!(
                "its topics are {}",
                topics
                    .iter()
                    .map(|t| format!("{} ({})", t.name, t.type_))
                    .collect::<Vec<_>>()
                    .join(", ")
            )
        }
    };
    let chosen: Vec<&Topic> = topics.iter().filter(|t| want(&t.name, &t.type_)).collect();
    let chosen = match (chosen.as_slice(), topic) {
        ([one], _) => *one,
        ([], Some(t)) => {
            return Err(LogError::new(
                &bag,
                None,
                format!("there is no topic `{t}` in the bag: {}", listing()),
            ))
        }
        ([], None) => {
            return Err(LogError::new(
                &bag,
                None,
                format!(
                    "no topic of type {MESSAGE_TYPE} (Nav2's /{TOPIC}) in the bag: {}; \
                     record it with `ros2 bag record /{TOPIC}`",
                    listing()
                ),
            )
            .with_hint(LogHint::ChooseTopic))
        }
        (many, _) => {
            return Err(LogError::new(
                &bag,
                None,
                format!(
                    "{} topics of type {MESSAGE_TYPE}: {}",
                    many.len(),
                    many.iter()
                        .map(|t| t.name.as_str())
                        .collect::<Vec<_>>()
                        .join(", ")
                ),
            )
            .with_hint(LogHint::ChooseOneTopic))
        }
    };
    if chosen.type_ != MESSAGE_TYPE {
        return Err(LogError::new(
            &bag,
            None,
            format!(
                "topic {} has type {}, not {MESSAGE_TYPE}",
                chosen.name, chosen.type_
            ),
        ));
    }
    let topic_name = chosen.name.clone();
    let mut layout: Option<(Layout, String)> = chosen
        .definition
        .as_deref()
        .and_then(layout_from_definition)
        .map(|l| (l, "the message definition in the bag".to_string()));
    let mut replay = Replay::new(tree, &bag);
    let mut count = 0usize;
    for m in messages.iter().filter(|m| m.topic == topic_name) {
        count += 1;
        let at = |extra: &str| format!("{}, message {count} ({}){extra}", m.file, m.at);
        let changes = match layout {
            Some((l, ref from)) => decode(&m.data, l).map_err(|(off, e)| {
                LogError::new(
                    &bag,
                    Some(at(&format!(", byte offset {off}"))),
                    format!(
                        "cannot decode the message as {MESSAGE_TYPE} ({}, from {from}): {e}",
                        l.describe()
                    ),
                )
            })?,
            None => {
                let a = decode(&m.data, Layout::WithUid);
                let b = decode(&m.data, Layout::WithoutUid);
                match (a, b) {
                    (Ok(a), Ok(b)) if a.is_empty() && b.is_empty() => Vec::new(),
                    (Ok(a), Err(_)) => {
                        layout = Some((Layout::WithUid, format!("tried on message {count}")));
                        a
                    }
                    (Err(_), Ok(b)) => {
                        layout = Some((Layout::WithoutUid, format!("tried on message {count}")));
                        b
                    }
                    // both decode (the strings can line up by chance): the
                    // uids must name the tree's nodes by their names
                    (Ok(a), Ok(b)) if replay.uids_fit(&a) || replay.uids_fit(&b) => {
                        if replay.uids_fit(&a) {
                            layout = Some((Layout::WithUid, format!("tried on message {count}")));
                            a
                        } else {
                            layout =
                                Some((Layout::WithoutUid, format!("tried on message {count}")));
                            b
                        }
                    }
                    (Ok(_), Ok(_)) => {
                        return Err(LogError::new(
                            &bag,
                            Some(at("")),
                            format!(
                                "the message decodes as {MESSAGE_TYPE} both with and without \
                                 `uid`: cannot tell its layout"
                            ),
                        ))
                    }
                    (Err((oa, ea)), Err((ob, eb))) => {
                        return Err(LogError::new(
                            &bag,
                            Some(at("")),
                            format!(
                                "cannot decode the message as {MESSAGE_TYPE}, neither with `uid` \
                                 (byte offset {oa}: {ea}) nor without (byte offset {ob}: {eb}): \
                                 truncated, or not Nav2's message?"
                            ),
                        ))
                    }
                }
            }
        };
        for (k, c) in changes.iter().enumerate() {
            replay.apply(c, &|| at(&format!(", change {}", k + 1)))?;
        }
    }
    if count == 0 {
        return Err(LogError::new(
            &bag,
            None,
            format!("topic {topic_name} has no message in the bag: nothing to fit"),
        ));
    }
    let (log, notes) = replay.finish();
    Ok(BagRead {
        log,
        topic: topic_name,
        messages: count,
        layout,
        notes,
    })
}

/// The layout a stored message definition gives: the field list of
/// `BehaviorTreeStatusChange` (ros2msg text, as rosbag2 stores it) has a
/// `uint16 uid` line or not. `None` when the definition has no such section
/// (another encoding such as ros2idl, or empty).
pub fn layout_from_definition(text: &str) -> Option<Layout> {
    let mut in_change = false;
    let mut fields = Vec::new();
    let mut found = false;
    for line in text.lines() {
        let line = line.split('#').next().unwrap_or("").trim();
        if line.starts_with("===") {
            in_change = false;
            continue;
        }
        if let Some(ty) = line.strip_prefix("MSG:") {
            in_change = ty.trim().ends_with("BehaviorTreeStatusChange");
            found |= in_change;
            continue;
        }
        if in_change && !line.is_empty() {
            fields.push(line.split_whitespace().collect::<Vec<_>>());
        }
    }
    if !found || fields.is_empty() {
        return None;
    }
    Some(if fields.iter().any(|f| f.len() >= 2 && f[1] == "uid") {
        Layout::WithUid
    } else {
        Layout::WithoutUid
    })
}

/// A little-endian or big-endian CDR reader; offsets and alignment count from
/// the end of the 4-byte encapsulation header.
struct Cdr<'a> {
    b: &'a [u8],
    pos: usize,
    le: bool,
}

type DecodeError = (usize, String);

impl<'a> Cdr<'a> {
    fn new(b: &'a [u8]) -> Result<Cdr<'a>, DecodeError> {
        if b.len() < 4 {
            return Err((
                0,
                format!("{} bytes, too short for the CDR header", b.len()),
            ));
        }
        let le = match (b[0], b[1]) {
            (0, 1) => true,
            (0, 0) => false,
            (x, y) => {
                return Err((
                    0,
                    format!("encapsulation {x:02x} {y:02x} is not plain CDR (00 00 or 00 01)"),
                ))
            }
        };
        Ok(Cdr { b, pos: 4, le })
    }
    fn take(&mut self, n: usize, what: &str) -> Result<&'a [u8], DecodeError> {
        self.take_aligned(n, n.min(8), what)
    }
    fn take_aligned(
        &mut self,
        n: usize,
        align: usize,
        what: &str,
    ) -> Result<&'a [u8], DecodeError> {
        if align > 1 {
            let rel = self.pos - 4;
            self.pos += (align - rel % align) % align;
        }
        if self.pos + n > self.b.len() {
            return Err((
                self.pos.min(self.b.len()),
                format!(
                    "{what} needs {n} bytes, {} remain (truncated?)",
                    self.b.len().saturating_sub(self.pos)
                ),
            ));
        }
        let s = &self.b[self.pos..self.pos + n];
        self.pos += n;
        Ok(s)
    }
    fn u32(&mut self, what: &str) -> Result<u32, DecodeError> {
        let s = self.take(4, what)?;
        let a = [s[0], s[1], s[2], s[3]];
        Ok(if self.le {
            u32::from_le_bytes(a)
        } else {
            u32::from_be_bytes(a)
        })
    }
    fn u16(&mut self, what: &str) -> Result<u16, DecodeError> {
        let s = self.take(2, what)?;
        let a = [s[0], s[1]];
        Ok(if self.le {
            u16::from_le_bytes(a)
        } else {
            u16::from_be_bytes(a)
        })
    }
    fn string(&mut self, what: &str) -> Result<String, DecodeError> {
        let at = self.pos;
        let n = self.u32(what)? as usize;
        if n > self.b.len().saturating_sub(self.pos) {
            return Err((
                at,
                format!(
                    "{what}: a string of {n} bytes, more than the {} left",
                    self.b.len().saturating_sub(self.pos)
                ),
            ));
        }
        let s = self.take_aligned(n, 1, what)?;
        let s = match s.split_last() {
            Some((0, body)) => body,
            Some(_) => return Err((at, format!("{what}: the string has no terminating NUL"))),
            None => s,
        };
        String::from_utf8(s.to_vec()).map_err(|_| (at, format!("{what} is not UTF-8")))
    }
    fn time(&mut self, what: &str) -> Result<i64, DecodeError> {
        let sec = self.u32(what)? as i32;
        let nsec = self.u32(what)?;
        if nsec >= 1_000_000_000 {
            return Err((
                self.pos - 4,
                format!("{what}: {nsec} ns is not below one second"),
            ));
        }
        Ok(i64::from(sec) * 1_000_000_000 + i64::from(nsec))
    }
}

fn status(s: &str) -> Option<Status> {
    Some(match s {
        "IDLE" => Status::Idle,
        "RUNNING" => Status::Running,
        "SUCCESS" => Status::Success,
        "FAILURE" => Status::Failure,
        "SKIPPED" => Status::Skipped,
        _ => return None,
    })
}

/// Decodes one serialized `BehaviorTreeLog` (CDR with its header) in the
/// given layout: its status changes, or the byte offset and reason it fails.
/// Trailing bytes beyond 3 of alignment padding are an error.
pub fn decode(data: &[u8], layout: Layout) -> Result<Vec<Change>, (usize, String)> {
    let mut c = Cdr::new(data)?;
    c.time("the message's timestamp")?;
    let at = c.pos;
    let n = c.u32("the number of changes")? as usize;
    // each change takes at least 8 + 3·5 bytes
    if n > data.len() / 20 + 1 {
        return Err((
            at,
            format!(
                "{n} changes cannot fit in the message's {} bytes",
                data.len()
            ),
        ));
    }
    let mut out = Vec::with_capacity(n);
    for k in 1..=n {
        let t_ns = c.time(&format!("change {k}'s timestamp"))?;
        let name = c.string(&format!("change {k}'s node_name"))?;
        let uid = match layout {
            Layout::WithUid => Some(c.u16(&format!("change {k}'s uid"))?),
            Layout::WithoutUid => None,
        };
        let mut st = |what: &str| -> Result<Status, DecodeError> {
            let at = c.pos;
            let s = c.string(&format!("change {k}'s {what}"))?;
            status(&s).ok_or_else(|| {
                (
                    at,
                    format!(
                        "change {k}'s {what} `{}` is not a status (IDLE, RUNNING, SUCCESS, FAILURE, SKIPPED)",
                        s.escape_debug()
                    ),
                )
            })
        };
        let prev = st("previous_status")?;
        let cur = st("current_status")?;
        out.push(Change {
            t_ns,
            name,
            uid,
            prev,
            cur,
        });
    }
    let rest = data.len() - c.pos;
    if rest > 3 {
        return Err((
            c.pos,
            format!("{rest} bytes after the last change (another layout or message type?)"),
        ));
    }
    Ok(out)
}

/// A topic of a storage file.
struct Topic {
    name: String,
    type_: String,
    definition: Option<String>,
}

/// A stored message of a wanted topic.
struct Raw {
    topic: String,
    /// The storage file.
    file: String,
    /// Where in it (row id, log time).
    at: String,
    data: Vec<u8>,
}

/// The storage files of a bag: those `metadata.yaml` lists, else the
/// folder's `.mcap` and `.db3` files in natural order; a file is itself.
fn storage_files(path: &Path, bag: &str) -> Result<Vec<PathBuf>, LogError> {
    if !path.is_dir() {
        return Ok(vec![path.to_path_buf()]);
    }
    let meta = path.join("metadata.yaml");
    if meta.is_file() {
        #[derive(serde::Deserialize)]
        struct Info {
            #[serde(default)]
            relative_file_paths: Vec<String>,
            #[serde(default)]
            compression_format: String,
            #[serde(default)]
            compression_mode: String,
        }
        #[derive(serde::Deserialize)]
        struct Meta {
            rosbag2_bagfile_information: Info,
        }
        let text = std::fs::read_to_string(&meta).map_err(|e| {
            LogError::new(
                &meta.display().to_string(),
                None,
                format!("cannot read: {e}"),
            )
        })?;
        let m: Meta = serde_saphyr::from_str(&text).map_err(|e| {
            LogError::new(
                &meta.display().to_string(),
                None,
                format!("not a rosbag2 metadata.yaml: {e}"),
            )
        })?;
        let i = m.rosbag2_bagfile_information;
        if !i.compression_format.is_empty() && i.compression_mode.eq_ignore_ascii_case("file") {
            return Err(LogError::new(
                &meta.display().to_string(),
                None,
                format!(
                    "the bag's files are compressed whole ({}): decompress them first \
                     (`ros2 bag convert`), or record with per-message or MCAP chunk compression",
                    i.compression_format
                ),
            ));
        }
        let files: Vec<PathBuf> = i.relative_file_paths.iter().map(|f| path.join(f)).collect();
        if let Some(missing) = files.iter().find(|f| !f.is_file()) {
            return Err(LogError::new(
                &meta.display().to_string(),
                None,
                format!(
                    "lists the storage file {}, which is missing",
                    missing.display()
                ),
            ));
        }
        if !files.is_empty() {
            return Ok(files);
        }
    }
    let mut files: Vec<PathBuf> = std::fs::read_dir(path)
        .map_err(|e| LogError::new(bag, None, format!("cannot read the folder: {e}")))?
        .flatten()
        .map(|e| e.path())
        .filter(|p| p.is_file() && matches!(ext(p).as_str(), "mcap" | "db3"))
        .collect();
    files.sort_by_key(|p| natural_key(&p.display().to_string()));
    if files.is_empty() {
        return Err(LogError::new(
            bag,
            None,
            "not a rosbag2 recording: the folder has no metadata.yaml and no .mcap or .db3 file",
        ));
    }
    Ok(files)
}

/// Sorts `bag_2` before `bag_10`.
fn natural_key(s: &str) -> Vec<(String, u64)> {
    let mut out = Vec::new();
    let mut text = String::new();
    let mut digits = String::new();
    for ch in s.chars() {
        if ch.is_ascii_digit() {
            digits.push(ch);
        } else {
            if !digits.is_empty() {
                out.push((
                    std::mem::take(&mut text),
                    digits.parse().unwrap_or(u64::MAX),
                ));
                digits.clear();
            }
            text.push(ch);
        }
    }
    out.push((text, digits.parse().unwrap_or(0)));
    out
}

type Storage = (Vec<Topic>, Vec<Raw>);

fn read_storage(path: &Path, want: &dyn Fn(&str, &str) -> bool) -> Result<Storage, LogError> {
    let file = path.display().to_string();
    checked_len(path, &file)?;
    let bytes = std::fs::read(path).map_err(|e| cannot_read(&file, e))?;
    if bytes.starts_with(super::sqlite::MAGIC) {
        drop(bytes);
        return read_db3(path, &file, want);
    }
    if bytes.starts_with(MCAP_MAGIC) {
        return read_mcap(&bytes, &file, want);
    }
    let what = match ext(path).as_str() {
        "db3" => "not an SQLite database: the file does not start with `SQLite format 3`",
        "mcap" => "not an MCAP file: the file does not start with the MCAP magic bytes",
        _ => "neither an MCAP file nor an SQLite database",
    };
    Err(LogError::new(
        &file,
        Some("byte offset 0".into()),
        format!(
            "{what} ({} bytes; truncated, or compressed whole?)",
            bytes.len()
        ),
    ))
}

fn read_mcap(
    bytes: &[u8],
    file: &str,
    want: &dyn Fn(&str, &str) -> bool,
) -> Result<Storage, LogError> {
    let mut topics: Vec<Topic> = Vec::new();
    let mut out = Vec::new();
    let stream = mcap::MessageStream::new(bytes).map_err(|e| {
        LogError::new(
            file,
            Some("byte offset 0".into()),
            format!("cannot read the MCAP file: {e}"),
        )
    })?;
    let mut n = 0usize;
    for m in stream {
        let m = m.map_err(|e| {
            LogError::new(
                file,
                Some(format!(
                    "after message {n} of the file ({} bytes)",
                    bytes.len()
                )),
                format!("the MCAP file cannot be read further (truncated or damaged?): {e}"),
            )
        })?;
        n += 1;
        let ch = &m.channel;
        let ty = ch
            .schema
            .as_ref()
            .map(|s| s.name.clone())
            .unwrap_or_default();
        if !topics.iter().any(|t| t.name == ch.topic) {
            let definition = ch
                .schema
                .as_ref()
                .filter(|s| s.encoding == "ros2msg")
                .and_then(|s| std::str::from_utf8(&s.data).ok().map(str::to_string));
            topics.push(Topic {
                name: ch.topic.clone(),
                type_: ty.clone(),
                definition,
            });
        }
        if want(&ch.topic, &ty) {
            out.push((
                m.log_time,
                Raw {
                    topic: ch.topic.clone(),
                    file: file.to_string(),
                    at: format!("message {n} of the file, log time {} ns", m.log_time),
                    data: m.data.into_owned(),
                },
            ));
        }
    }
    out.sort_by_key(|(t, _)| *t);
    Ok((topics, out.into_iter().map(|(_, r)| r).collect()))
}

fn read_db3(
    path: &Path,
    file: &str,
    want: &dyn Fn(&str, &str) -> bool,
) -> Result<Storage, LogError> {
    use super::sqlite;
    let what = "the rosbag2 SQLite file";
    let damaged = |at: &str| sqlite::damaged(file, what, at);
    let db = sqlite::open_read_only(path).map_err(damaged("opening"))?;
    let tables = sqlite::table_names(&db, file, what)?;
    for t in ["topics", "messages"] {
        if !tables.iter().any(|x| x == t) {
            let btcpp = tables.iter().any(|x| x == "Transitions");
            let e = LogError::new(
                file,
                Some("the schema".into()),
                format!(
                    "there is no table `{t}`: not a rosbag2 SQLite file{}",
                    if btcpp {
                        " (it is a BT.CPP SqliteLogger file)"
                    } else {
                        ""
                    }
                ),
            );
            return Err(if btcpp {
                e.with_hint(LogHint::NotABag)
            } else {
                e
            });
        }
    }
    let mut defs: Vec<(String, String)> = Vec::new();
    if tables.iter().any(|x| x == "message_definitions") {
        let at = "table message_definitions";
        let mut st = db
            .prepare(
                "SELECT topic_type, encoding, encoded_message_definition FROM message_definitions",
            )
            .map_err(damaged(at))?;
        let mut rows = st.query([]).map_err(damaged(at))?;
        while let Some(r) = rows.next().map_err(damaged(at))? {
            let ty: String = r.get(0).map_err(damaged(at))?;
            let enc: String = r.get(1).map_err(damaged(at))?;
            let text: String = r.get(2).map_err(damaged(at))?;
            if enc == "ros2msg" {
                defs.push((ty, text));
            }
        }
    }
    let mut topics = Vec::new();
    let mut ids = Vec::new();
    {
        let at = "table topics";
        let mut st = db
            .prepare("SELECT id, name, type FROM topics ORDER BY id")
            .map_err(damaged(at))?;
        let mut rows = st.query([]).map_err(damaged(at))?;
        while let Some(r) = rows.next().map_err(damaged(at))? {
            let id: i64 = r.get(0).map_err(damaged(at))?;
            let name: String = r.get(1).map_err(damaged(at))?;
            let ty: String = r.get(2).map_err(damaged(at))?;
            if want(&name, &ty) {
                ids.push((id, name.clone()));
            }
            let definition = defs.iter().find(|(t, _)| *t == ty).map(|(_, d)| d.clone());
            topics.push(Topic {
                name,
                type_: ty,
                definition,
            });
        }
    }
    let mut out = Vec::new();
    let at = "table messages";
    let mut st = db
        .prepare(
            "SELECT id, timestamp, data FROM messages WHERE topic_id = ?1 ORDER BY timestamp, id",
        )
        .map_err(damaged(at))?;
    for (id, name) in ids {
        let mut rows = st.query([id]).map_err(damaged(at))?;
        while let Some(r) = rows.next().map_err(damaged(at))? {
            let rowid: i64 = r.get(0).map_err(damaged(at))?;
            let t: i64 = r.get(1).map_err(damaged(&format!("{at}, row {rowid}")))?;
            let data: Vec<u8> = r.get(2).map_err(damaged(&format!("{at}, row {rowid}")))?;
            out.push((
                t,
                Raw {
                    topic: name.clone(),
                    file: file.to_string(),
                    at: format!("table messages, row {rowid}"),
                    data,
                },
            ));
        }
    }
    out.sort_by_key(|(t, _)| *t);
    Ok((topics, out.into_iter().map(|(_, r)| r).collect()))
}
