//! YAML front end: reads a tree file, validates it, and builds a [`Tree`].
//!
//! The format (see docs/TREE-FORMAT.md for the full reference):
//!
//! ```yaml
//! name: search and grasp          # optional title
//! tree:
//!   sequence:                     # or fallback, parallel, action, condition
//!     name: root                  # optional, unique
//!     children:
//!       - condition: {name: ready, ps: 0.9}
//!       - action: {name: grasp, ps: 0.5, mu: 0.1, nu: 0.05}
//! ```
//!
//! Parsing is bounded: file size, number of YAML nodes, alias expansion and
//! nesting depth are limited ([`ParseLimits`]), and parsing runs on a thread
//! with a stack large enough for the deepest tree allowed, so hostile input
//! is rejected with an error instead of exhausting memory or the stack.

mod builder;
mod defs;
mod diagnose;
mod fast;

use super::error::{TreeError, TreeErrorKind as Kind};
use super::Tree;
use builder::build;
use defs::FileDef;
use diagnose::yaml_error;

/// Bounds on what the parser accepts.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ParseLimits {
    /// Largest file, in bytes.
    pub max_bytes: usize,
    /// Deepest nesting of tree nodes (the root is level 1).
    pub max_depth: usize,
    /// Most YAML nodes (after alias expansion).
    pub max_yaml_nodes: usize,
}

impl Default for ParseLimits {
    fn default() -> Self {
        ParseLimits {
            max_bytes: 256 << 20,
            max_depth: 200,
            max_yaml_nodes: 50_000_000,
        }
    }
}

/// Reads and parses a tree file with default limits.
pub fn parse_file(path: &std::path::Path) -> Result<Tree, TreeError> {
    let file = path.display().to_string();
    let io_err = |e: std::io::Error| {
        TreeError::file(Kind::Io, &file, format!("cannot read the file: {e}"))
            .with_help(read_help(&e))
    };
    let limits = ParseLimits::default();
    let meta = std::fs::metadata(path).map_err(io_err)?;
    if meta.len() > limits.max_bytes as u64 {
        return Err(too_large(&file, meta.len() as usize, &limits));
    }
    let bytes = std::fs::read(path).map_err(io_err)?;
    parse_bytes(bytes, &file)
}

/// Parses a tree from the raw bytes of a YAML document (e.g. standard
/// input) with default limits; `file` names the source in error messages.
pub fn parse_bytes(bytes: Vec<u8>, file: &str) -> Result<Tree, TreeError> {
    let limits = ParseLimits::default();
    if bytes.len() > limits.max_bytes {
        return Err(too_large(file, bytes.len(), &limits));
    }
    let source = text_from_bytes(bytes, file)?;
    parse_str_with(&source, file, limits)
}

/// The bytes as UTF-8 text, or an error located at the first invalid byte.
pub fn text_from_bytes(bytes: Vec<u8>, file: &str) -> Result<String, TreeError> {
    String::from_utf8(bytes).map_err(|e| {
        let before = &e.as_bytes()[..e.utf8_error().valid_up_to()];
        let line = before.iter().filter(|&&b| b == b'\n').count() + 1;
        let column = before.iter().rev().take_while(|&&b| b != b'\n').count() + 1;
        TreeError {
            line,
            column,
            ..TreeError::file(Kind::Syntax, file, "the input is not valid UTF-8 text")
        }
        .with_help("a tree file is YAML or XML text; is this the right file?")
    })
}

/// Advice for a file that cannot be read.
pub(crate) fn read_help(e: &std::io::Error) -> &'static str {
    match e.kind() {
        std::io::ErrorKind::NotFound => {
            "check the path (relative paths start from the current directory)"
        }
        std::io::ErrorKind::PermissionDenied => "check the file's permissions",
        _ => "check that the path names a readable file",
    }
}

/// Parses a tree from YAML text with default limits; `file` names the source
/// in error messages.
pub fn parse_str(source: &str, file: &str) -> Result<Tree, TreeError> {
    parse_str_with(source, file, ParseLimits::default())
}

fn too_large(file: &str, len: usize, limits: &ParseLimits) -> TreeError {
    TreeError::file(
        Kind::Budget,
        file,
        format!(
            "the file is {len} bytes, more than the limit of {} bytes",
            limits.max_bytes
        ),
    )
}

/// Parses a tree from YAML text within `limits`.
pub(crate) fn parse_str_with(
    source: &str,
    file: &str,
    limits: ParseLimits,
) -> Result<Tree, TreeError> {
    if source.len() > limits.max_bytes {
        return Err(too_large(file, source.len(), &limits));
    }
    // serde recursion uses stack per YAML level: run on a thread whose stack
    // fits the deepest document the depth budget admits.
    std::thread::scope(|s| {
        std::thread::Builder::new()
            .name("btrel-parse".into())
            .stack_size(256 << 20)
            .spawn_scoped(s, || parse_on_this_thread(source, file, limits))
            .map_err(|e| {
                TreeError::file(
                    Kind::Internal,
                    file,
                    format!("cannot start the parser thread: {e}"),
                )
            })?
            .join()
            .unwrap_or_else(|_| {
                Err(
                    TreeError::file(Kind::Internal, file, "internal error: the parser panicked")
                        .with_help("please report this file as a bug"),
                )
            })
    })
}

fn parse_on_this_thread(source: &str, file: &str, limits: ParseLimits) -> Result<Tree, TreeError> {
    let only_comments = source
        .lines()
        .all(|l| l.trim().is_empty() || l.trim_start().starts_with('#'));
    if only_comments {
        return Err(
            TreeError::at(Kind::Structure, file, source, (1, 1), "the file is empty").with_help(
                "a tree file needs a `tree:` key, e.g. `tree: {action: {ps: 0.5, mu: 1, nu: 1}}`",
            ),
        );
    }
    // the common subset first; anything else, and every error, through the
    // full parser
    if let Some(def) = fast::read(source, limits.max_depth) {
        if let Ok(tree) = build(def, source, file, &limits) {
            return Ok(tree);
        }
    }
    parse_full(source, file, limits)
}

/// Whether the fast reader reads `source` (for tests and benchmarks).
#[doc(hidden)]
pub fn fast_reader_accepts(source: &str) -> bool {
    fast::read(source, ParseLimits::default().max_depth).is_some()
}

/// Parses with serde-saphyr only, never the fast reader (for tests and
/// benchmarks that compare the two; runs on the caller's stack).
#[doc(hidden)]
pub fn parse_full(source: &str, file: &str, limits: ParseLimits) -> Result<Tree, TreeError> {
    // each tree level is three YAML levels: kind map, node map, children list
    let options = serde_saphyr::options! {
        budget: serde_saphyr::budget! {
            max_depth: 3 * limits.max_depth + 4,
            max_nodes: limits.max_yaml_nodes,
            max_events: 4 * limits.max_yaml_nodes,
            max_total_scalar_bytes: limits.max_bytes,
            flow_nesting_limit: 3 * limits.max_depth + 4,
        },
        alias_limits: serde_saphyr::alias_limits! {
            max_total_replayed_events: 4 * limits.max_yaml_nodes,
        },
        with_snippet: false,
    };
    let def: FileDef = serde_saphyr::from_str_with_options(source, options)
        .map_err(|e| yaml_error(&e, source, file, &limits))?;
    build(def, source, file, &limits)
}
