//! BehaviorTree.CPP v4 FileLogger2 (`.btlog`) files.
//!
//! Layout (BT.CPP `bt_file_logger_v2.cpp`, all integers little-endian):
//! the 18 bytes `BTCPP4-FileLogger2`, a protocol byte (1), an `i32` length
//! N, N bytes of the tree's XML (every node with its `_uid`, SubTrees with
//! `_fullpath`, plus a `<TreeNodesModel>`), an `i64` first timestamp (µs
//! since the epoch), then 9-byte transition records: a 6-byte timestamp in
//! µs relative to the first, the node's `u16` uid, and its new status
//! (0 IDLE, 1 RUNNING, 2 SUCCESS, 3 FAILURE, 4 SKIPPED). The logger writes a
//! record for every status change, transitions to IDLE included.

use std::collections::HashMap;

use super::{Declared, End, Episode, LeafLog, Log, LogError};
use crate::tree::xml::{scan_elements, XmlElement};

/// The file's first bytes.
pub(crate) const MAGIC: &[u8] = b"BTCPP4-FileLogger2";
/// The protocol version this reader knows.
pub(crate) const PROTOCOL: u8 = 1;
/// Bytes per transition record.
pub const RECORD: usize = 9;

/// Largest step back in time (µs) accepted between consecutive records.
/// BT.CPP's FileLogger2 takes a transition's timestamp in the thread that
/// changes the node's status and queues it under a lock, so records of two
/// threads (an asynchronous action, a halt) can reach the file in the other
/// order, a few µs to ms apart; such a record keeps its own timestamp (each
/// node's transitions stay in their order). A larger step means a mixed-up
/// file.
pub(crate) const MAX_STEP_BACK_US: u64 = 100_000;

/// Leaves BT.CPP runs itself in zero time (btrel models them without a
/// params entry); they are not fitted.
pub(super) const BUILTIN_LEAVES: &[&str] = &[
    "AlwaysSuccess",
    "AlwaysFailure",
    "Script",
    "SetBlackboard",
    "UnsetBlackboard",
];

#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub(super) enum Status {
    Idle,
    Running,
    Success,
    Failure,
    Skipped,
}

impl Status {
    pub(super) fn from_byte(b: u8) -> Option<Status> {
        Some(match b {
            0 => Status::Idle,
            1 => Status::Running,
            2 => Status::Success,
            3 => Status::Failure,
            4 => Status::Skipped,
            _ => return None,
        })
    }
    fn text(self) -> &'static str {
        match self {
            Status::Idle => "IDLE",
            Status::Running => "RUNNING",
            Status::Success => "SUCCESS",
            Status::Failure => "FAILURE",
            Status::Skipped => "SKIPPED",
        }
    }
}

/// A node of the logged tree.
pub(super) struct Node {
    /// Index into the leaves, for leaves that are fitted.
    pub(super) leaf: Option<usize>,
    pub(super) status: Status,
    /// Start of the running episode (µs).
    pub(super) started: u64,
    pub(super) label: String,
}

/// Reads a FileLogger2 log.
pub fn read(bytes: &[u8], file: &str) -> Result<Log, LogError> {
    let at_byte = |o: usize| Some(format!("byte offset {o}"));
    if bytes.len() < MAGIC.len() || &bytes[..MAGIC.len()] != MAGIC {
        let what = if bytes.starts_with(b"BTCPP4-") {
            "a BT.CPP log of another kind"
        } else {
            "not a BT.CPP FileLogger2 log"
        };
        return Err(LogError::new(
            file,
            at_byte(0),
            format!(
                "{what}: the file does not start with `BTCPP4-FileLogger2` \
                 (is it a .btlog written by BT::FileLogger2?)"
            ),
        ));
    }
    let mut pos = MAGIC.len();
    let need = |pos: usize, n: usize, what: &str| -> Result<(), LogError> {
        if bytes.len() < pos + n {
            Err(LogError::new(
                file,
                Some(format!("byte offset {pos}")),
                format!(
                    "the file is truncated: {what} needs {n} bytes, {} remain",
                    bytes.len() - pos
                ),
            ))
        } else {
            Ok(())
        }
    };
    need(pos, 1, "the protocol byte")?;
    let protocol = bytes[pos];
    if protocol != PROTOCOL {
        return Err(LogError::new(
            file,
            at_byte(pos),
            format!("protocol version {protocol}; btrel reads version {PROTOCOL}"),
        ));
    }
    pos += 1;
    need(pos, 4, "the XML length")?;
    let len = i32::from_le_bytes([bytes[pos], bytes[pos + 1], bytes[pos + 2], bytes[pos + 3]]);
    if len < 0 {
        return Err(LogError::new(
            file,
            at_byte(pos),
            format!("the tree's XML length is negative ({len})"),
        ));
    }
    pos += 4;
    let len = len as usize;
    need(pos, len, "the tree's XML")?;
    let xml_at = pos;
    let xml = std::str::from_utf8(&bytes[pos..pos + len]).map_err(|e| {
        LogError::new(
            file,
            at_byte(xml_at + e.valid_up_to()),
            "the tree's XML is not valid UTF-8",
        )
    })?;
    pos += len;
    need(pos, 8, "the first timestamp")?;
    pos += 8;

    let elems = scan_elements(xml, "XML").map_err(|e| {
        LogError::new(
            file,
            Some(format!(
                "the tree's XML (from byte offset {xml_at}), line {} column {}",
                e.line, e.column
            )),
            e.message.clone(),
        )
    })?;
    let (mut nodes, mut leaves) = tree_nodes(
        &elems,
        file,
        &format!("the tree's XML (from byte offset {xml_at})"),
    )?;

    let rest = bytes.len() - pos;
    let records = rest / RECORD;
    if !rest.is_multiple_of(RECORD) {
        let off = pos + records * RECORD;
        return Err(LogError::new(
            file,
            Some(format!("record {} (byte offset {off})", records + 1)),
            format!(
                "the file is truncated: the last record has {} of {RECORD} bytes \
                 (the logger was stopped while writing?)",
                rest % RECORD
            ),
        ));
    }
    let (kept, repeated_tail) = without_repeated_tail(&bytes[pos..pos + records * RECORD]);
    let mut last_t = 0u64;
    let (mut out_of_order, mut max_back) = (0usize, 0u64);
    for r in 0..kept {
        let off = pos + r * RECORD;
        let b = &bytes[off..off + RECORD];
        let t = u64::from_le_bytes([b[0], b[1], b[2], b[3], b[4], b[5], 0, 0]);
        let uid = u16::from_le_bytes([b[6], b[7]]);
        let where_ = || Some(format!("record {} (byte offset {off})", r + 1));
        let Some(status) = Status::from_byte(b[8]) else {
            return Err(LogError::new(
                file,
                where_(),
                format!(
                    "status code {} is not a BT.CPP status (0 IDLE, 1 RUNNING, 2 SUCCESS, 3 FAILURE, 4 SKIPPED)",
                    b[8]
                ),
            ));
        };
        if t < last_t {
            let back = last_t - t;
            if back > MAX_STEP_BACK_US {
                return Err(LogError::new(
                    file,
                    where_(),
                    format!(
                        "the timestamp goes back in time ({t} µs after {last_t} µs), by more than \
                         the {} ms that records of BT.CPP's logging threads can be swapped by: \
                         records are out of order or the file is mixed up",
                        MAX_STEP_BACK_US / 1000
                    ),
                ));
            }
            out_of_order += 1;
            max_back = max_back.max(back);
        }
        last_t = last_t.max(t);
        let Some(node) = nodes.get_mut(&uid) else {
            let mut known: Vec<u16> = Vec::new();
            known.extend(nodes.keys().copied());
            known.sort_unstable();
            return Err(LogError::new(
                file,
                where_(),
                format!(
                    "node uid {uid} is not in the log's tree (its uids are {}..{}): \
                     is the record stream from another tree?",
                    known.first().copied().unwrap_or(0),
                    known.last().copied().unwrap_or(0)
                ),
            ));
        };
        let episode = step(node, status, t, |d| d as f64 * 1e-6)
            .map_err(|m| LogError::new(file, where_(), m))?;
        if let (Some(e), Some(l)) = (episode, node.leaf) {
            leaves[l].episodes.push(e);
        }
    }
    // still running when the log ended: censored at the last record
    for node in nodes.values() {
        if let (Status::Running, Some(l)) = (node.status, node.leaf) {
            leaves[l].episodes.push(Episode {
                duration: last_t.saturating_sub(node.started) as f64 * 1e-6,
                end: End::Halted,
                instant: false,
            });
        }
    }
    Ok(Log {
        file: file.to_string(),
        xml: Some(xml.to_string()),
        leaves,
        records,
        out_of_order,
        max_step_back: max_back as f64 * 1e-6,
        repeated_tail,
    })
}

/// How many of the `records` (a whole number of [`RECORD`]s) to read, and
/// how many at the end to drop because they repeat the block just before
/// them byte for byte. BT.CPP's FileLogger2 has been seen (behaviortreepy
/// 0.1.4, about one log in twenty-five) to write its last batch of records
/// twice when the logger is flushed and destroyed; such a copy is never a
/// real change (the same node changing to the same status at the same
/// microsecond), so it is dropped rather than read as new episodes.
pub(super) fn without_repeated_tail(records: &[u8]) -> (usize, usize) {
    let mut n = records.len() / RECORD;
    let total = n;
    'again: loop {
        for k in (1..=n / 2).rev() {
            let tail = &records[(n - k) * RECORD..n * RECORD];
            let before = &records[(n - 2 * k) * RECORD..(n - k) * RECORD];
            if tail == before {
                n -= k;
                continue 'again;
            }
        }
        return (n, total - n);
    }
}

/// Applies one status change (at `t` ticks) to a node: the episode it
/// ends, if any, or why the change cannot happen. `secs` turns ticks into
/// seconds.
pub(super) fn step(
    node: &mut Node,
    status: Status,
    t: u64,
    secs: impl Fn(u64) -> f64,
) -> Result<Option<Episode>, String> {
    let prev = node.status;
    use Status::*;
    let mut episode = None;
    match (prev, status) {
        (a, b) if a == b => {
            return Err(format!(
                "{} goes from {} to {}: the logger records changes only, \
                 so the file is mixed up",
                node.label,
                a.text(),
                b.text()
            ))
        }
        (Idle | Skipped | Success | Failure, Running) => node.started = t,
        (Running, Success | Failure) => {
            episode = Some(Episode {
                duration: secs(t.saturating_sub(node.started)),
                end: if status == Success {
                    End::Success
                } else {
                    End::Failure
                },
                instant: false,
            })
        }
        (Running, Idle) => {
            episode = Some(Episode {
                duration: secs(t.saturating_sub(node.started)),
                end: End::Halted,
                instant: false,
            })
        }
        (Idle | Skipped | Success | Failure, Success | Failure) => {
            episode = Some(Episode {
                duration: 0.0,
                end: if status == Success {
                    End::Success
                } else {
                    End::Failure
                },
                instant: true,
            })
        }
        (Success | Failure | Skipped, Idle) | (Idle, Skipped) => {}
        (a, b) => {
            return Err(format!(
                "{} goes from {} to {}, which BT.CPP never does",
                node.label,
                a.text(),
                b.text()
            ))
        }
    }
    node.status = status;
    Ok(episode)
}

/// The logged tree's nodes by uid, and its fitted leaves.
pub(super) fn tree_nodes(
    elems: &[XmlElement],
    file: &str,
    xml_where: &str,
) -> Result<(HashMap<u16, Node>, Vec<LeafLog>), LogError> {
    let mut declared: HashMap<&str, Declared> = HashMap::new();
    let mut in_tree = vec![false; elems.len()];
    for (i, e) in elems.iter().enumerate() {
        if e.name == "TreeNodesModel" {
            for &c in &e.children {
                let m = &elems[c];
                if let Some(id) = m.attr("ID") {
                    let d = match m.name.as_str() {
                        "Action" => Declared::Action,
                        "Condition" => Declared::Condition,
                        _ => continue,
                    };
                    declared.insert(id, d);
                }
            }
        }
        if e.name == "BehaviorTree" {
            in_tree[i] = true;
        }
        if in_tree[i] {
            for &c in &e.children {
                in_tree[c] = true;
            }
        }
    }
    let mut nodes = HashMap::new();
    let mut leaves: Vec<LeafLog> = Vec::new();
    for (i, e) in elems.iter().enumerate() {
        if !in_tree[i] || e.name == "BehaviorTree" {
            continue;
        }
        let Some(uid) = e.attr("_uid") else { continue };
        let loc = || Some(format!("{xml_where}, line {} column {}", e.line, e.column));
        let uid: u16 = uid.trim().parse().map_err(|_| {
            LogError::new(
                file,
                loc(),
                format!("`_uid=\"{uid}\"` is not a node uid (0..65535)"),
            )
        })?;
        let explicit = matches!(e.name.as_str(), "Action" | "Condition");
        let id = if explicit || e.name == "SubTree" {
            e.attr("ID").unwrap_or(&e.name).to_string()
        } else {
            e.name.clone()
        };
        let name = e.attr("name").map(str::to_string);
        let is_leaf =
            e.children.is_empty() && e.name != "SubTree" && !BUILTIN_LEAVES.contains(&id.as_str());
        let leaf = if is_leaf {
            let d = match e.name.as_str() {
                "Action" => Declared::Action,
                "Condition" => Declared::Condition,
                _ => declared
                    .get(id.as_str())
                    .copied()
                    .unwrap_or(Declared::Unknown),
            };
            leaves.push(LeafLog {
                id: id.clone(),
                name: name.clone(),
                declared: d,
                episodes: Vec::new(),
            });
            Some(leaves.len() - 1)
        } else {
            None
        };
        let label = match &name {
            Some(n) if *n != id => format!("node {uid} (`{n}`, {id})"),
            _ => format!("node {uid} ({id})"),
        };
        let old = nodes.insert(
            uid,
            Node {
                leaf,
                status: Status::Idle,
                started: 0,
                label,
            },
        );
        if old.is_some() {
            return Err(LogError::new(
                file,
                loc(),
                format!("two nodes have `_uid=\"{uid}\"`"),
            ));
        }
    }
    if nodes.is_empty() {
        return Err(LogError::new(
            file,
            Some(xml_where.to_string()),
            "the tree has no node with a `_uid`: not a tree written by a BT.CPP logger",
        ));
    }
    Ok((nodes, leaves))
}
