//! YAML front end: reads a tree file, validates it, and builds a [`Tree`].
//!
//! The format (see the README for the full reference):
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

mod fast;

use serde::Deserialize;

use super::action::{sloc, validate_action, ActionParams, At, TimeDef};
use super::error::{nearest, TreeError, TreeErrorKind as Kind};
use super::{Action, Decorator, Flow, FlowNext, FlowState, Node, NodeKind, Tree};

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

const NODE_KINDS: &[&str] = &[
    "sequence",
    "fallback",
    "parallel",
    "action",
    "condition",
    "inverter",
    "force_success",
    "force_failure",
    "retry",
    "repeat",
    "until_failure",
    "until_success",
    "if_then_else",
    "flow",
];

impl NodeDef {
    /// Number of nodes in the definition (iterative: any depth).
    fn count(&self) -> usize {
        let mut stack = vec![self];
        let mut n = 0;
        while let Some(d) = stack.pop() {
            n += 1;
            match d {
                NodeDef::Sequence(c) | NodeDef::Fallback(c) | NodeDef::IfThenElse(c) => {
                    stack.extend(c.children.value.iter().map(|c| &c.value))
                }
                NodeDef::Flow(f) => stack.extend(f.children.value.iter().map(|c| &c.value)),
                NodeDef::Parallel(p) => stack.extend(p.children.value.iter().map(|c| &c.value)),
                NodeDef::Action(_) | NodeDef::Condition(_) => {}
                NodeDef::Inverter(d)
                | NodeDef::ForceSuccess(d)
                | NodeDef::ForceFailure(d)
                | NodeDef::UntilFailure(d)
                | NodeDef::UntilSuccess(d) => stack.push(&d.child.value),
                NodeDef::Retry(r) => stack.push(&r.child.value),
                NodeDef::Repeat(r) => stack.push(&r.child.value),
            }
        }
        n
    }
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FileDef {
    #[serde(default)]
    name: Option<String>,
    tree: At<NodeDef>,
}

#[derive(Deserialize)]
#[serde(rename_all = "snake_case")]
enum NodeDef {
    Sequence(ControlDef),
    Fallback(ControlDef),
    Parallel(ParallelDef),
    Action(Box<ActionDef>),
    Condition(ConditionDef),
    Inverter(Box<DecoratorDef>),
    ForceSuccess(Box<DecoratorDef>),
    ForceFailure(Box<DecoratorDef>),
    Retry(Box<RetryDef>),
    Repeat(Box<RepeatDef>),
    UntilFailure(Box<DecoratorDef>),
    UntilSuccess(Box<DecoratorDef>),
    IfThenElse(ControlDef),
    Flow(FlowDef),
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FlowDef {
    #[serde(default)]
    name: Option<At<String>>,
    children: At<Vec<At<NodeDef>>>,
    states: At<Vec<At<StateDef>>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct StateDef {
    run: At<f64>,
    success: At<NextDef>,
    failure: At<NextDef>,
}

/// Where a flow state leads: a state number or `success` / `failure`.
#[derive(Deserialize)]
#[serde(untagged)]
enum NextDef {
    State(f64),
    Outcome(String),
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct DecoratorDef {
    #[serde(default)]
    name: Option<At<String>>,
    child: At<NodeDef>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RetryDef {
    #[serde(default)]
    name: Option<At<String>>,
    attempts: At<f64>,
    child: At<NodeDef>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RepeatDef {
    #[serde(default)]
    name: Option<At<String>>,
    times: At<f64>,
    child: At<NodeDef>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ControlDef {
    #[serde(default)]
    name: Option<At<String>>,
    children: At<Vec<At<NodeDef>>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ParallelDef {
    #[serde(default)]
    name: Option<At<String>>,
    #[serde(default)]
    success_threshold: Option<At<f64>>,
    #[serde(default)]
    failure_threshold: Option<At<f64>>,
    children: At<Vec<At<NodeDef>>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ActionDef {
    #[serde(default)]
    name: Option<At<String>>,
    ps: At<f64>,
    #[serde(default)]
    pf: Option<At<f64>>,
    #[serde(default)]
    mu: Option<At<f64>>,
    #[serde(default)]
    nu: Option<At<f64>>,
    #[serde(default)]
    tau_s: Option<At<f64>>,
    #[serde(default)]
    tau_f: Option<At<f64>>,
    #[serde(default)]
    success_time: Option<At<TimeDef>>,
    #[serde(default)]
    failure_time: Option<At<TimeDef>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ConditionDef {
    #[serde(default)]
    name: Option<At<String>>,
    ps: At<f64>,
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
pub fn parse_str_with(source: &str, file: &str, limits: ParseLimits) -> Result<Tree, TreeError> {
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

fn build(def: FileDef, source: &str, file: &str, limits: &ParseLimits) -> Result<Tree, TreeError> {
    // one allocation for a million-node tree instead of repeated doubling
    let count = def.tree.value.count();
    let mut b = Builder {
        source,
        file,
        nodes: Vec::with_capacity(count),
        max_depth: limits.max_depth,
        locations: Vec::with_capacity(count),
    };
    b.node(&def.tree, None, 0, "0".into())?;
    b.check_names()?;
    Ok(Tree {
        title: def.name,
        nodes: b.nodes,
    })
}

fn yaml_error(
    e: &serde_saphyr::Error,
    source: &str,
    file: &str,
    limits: &ParseLimits,
) -> TreeError {
    use serde_saphyr::Error as E;
    let loc = e
        .location()
        .map_or((0, 0), |l| (l.line() as usize, l.column() as usize));
    let inner = e.without_snippet();
    if let Some(err) = common_mistake(inner, source, file, loc) {
        return err;
    }
    let (kind, message, help): (Kind, String, Option<String>) = match inner {
        E::SerdeUnknownField {
            field, expected, ..
        } => {
            let keys: Vec<&str> = expected.to_vec();
            let hint = match nearest(field, &keys) {
                Some(k) => format!("did you mean `{k}`? accepted keys: {}", keys.join(", ")),
                None => format!("accepted keys: {}", keys.join(", ")),
            };
            (
                Kind::Structure,
                format!("unknown key `{field}`"),
                Some(hint),
            )
        }
        E::SerdeUnknownVariant { variant, .. } => {
            let hint = match nearest(variant, NODE_KINDS) {
                Some(k) => format!("did you mean `{k}`? node kinds: {}", NODE_KINDS.join(", ")),
                None if NODE_KEYS.contains(&variant.as_str()) => format!(
                    "`{variant}` is a key inside a node: write the node's kind first, e.g. \
                     `- action: {{ps: 0.5, mu: 1, nu: 1}}` (node kinds: {})",
                    NODE_KINDS.join(", ")
                ),
                None => format!("node kinds: {}", NODE_KINDS.join(", ")),
            };
            (
                Kind::UnknownNode,
                format!("unknown node kind `{variant}`"),
                Some(hint),
            )
        }
        E::SerdeMissingField { field, .. } => {
            // serde reports the mapping's last key; point at the node instead
            if let Some(at) = enclosing_node(source, loc) {
                let mut err = TreeError::at(
                    missing_key_kind(field),
                    file,
                    source,
                    at,
                    format!("missing key `{field}`"),
                );
                err.help = Some(missing_help(field));
                return err;
            }
            let hint = match *field {
                "ps" => {
                    "every action and condition needs `ps`, its probability of success in [0, 1]"
                }
                "children" => "a control node needs `children:`, a list of at least one node",
                "tree" => "a tree file needs a `tree:` key holding the root node",
                _ => "add the missing key",
            };
            (
                missing_key_kind(field),
                format!("missing key `{field}`"),
                Some(hint.to_string()),
            )
        }
        E::InvalidScalar { ty, .. } => (
            Kind::InvalidValue,
            format!("expected a number ({ty})"),
            Some("write a plain number such as 0.25 or 1e-3".into()),
        ),
        E::Budget { breach, .. } => {
            let msg = format!("{breach:?}");
            if msg.starts_with("Depth") {
                (
                    Kind::Budget,
                    "the tree is nested too deeply".into(),
                    Some(format!(
                        "btrel accepts trees up to {} levels deep",
                        limits.max_depth
                    )),
                )
            } else {
                (
                    Kind::Budget,
                    format!("the document exceeds a size limit ({msg})"),
                    Some("is this really a behavior tree? alias expansion and very large documents are bounded".into()),
                )
            }
        }
        E::AliasError { .. } | E::AliasReplayLimitExceeded { .. } => (
            Kind::Budget,
            strip_location(&inner.to_string()),
            Some("alias expansion is bounded; expand fewer or smaller aliases".into()),
        ),
        other => {
            let text = strip_location(&other.to_string());
            let deep = text.contains("recursion limit");
            let help = if deep {
                Some(format!(
                    "btrel accepts trees up to {} levels deep",
                    limits.max_depth
                ))
            } else if text.contains("expected mapping") {
                Some("a node is written `kind: {key: value, ...}` or as a block mapping".into())
            } else {
                None
            };
            let kind = if deep { Kind::Budget } else { Kind::Syntax };
            (kind, text, help)
        }
    };
    let mut err = TreeError::at(kind, file, source, loc, message);
    err.help = help;
    err
}

/// A missing YAML key is a missing parameter when it is one of a leaf's
/// parameters, else a structural error (`children`, `tree`, ...).
fn missing_key_kind(field: &str) -> Kind {
    match field {
        "ps" | "pf" | "mu" | "nu" | "tau_s" | "tau_f" => Kind::MissingParameter,
        _ => Kind::Structure,
    }
}

/// Keys that belong inside a node (what a missing kind line leaves behind).
const NODE_KEYS: &[&str] = &[
    "name",
    "ps",
    "pf",
    "mu",
    "nu",
    "tau_s",
    "tau_f",
    "success_time",
    "failure_time",
    "children",
    "child",
    "attempts",
    "times",
    "success_threshold",
    "failure_threshold",
];

/// The 1-based line `line` of `source` (empty if out of range).
fn line_of<'a>(lines: &[&'a str], line: usize) -> &'a str {
    line.checked_sub(1)
        .and_then(|l| lines.get(l).copied())
        .unwrap_or("")
}

/// Number of leading spaces.
fn indent_of(text: &str) -> usize {
    text.len() - text.trim_start_matches(' ').len()
}

fn is_blank_or_comment(text: &str) -> bool {
    let t = text.trim();
    t.is_empty() || t.starts_with('#')
}

/// The identifier (key or kind) starting at 1-based `column` of `text`.
fn word_at(text: &str, column: usize) -> String {
    text.chars()
        .skip(column.saturating_sub(1))
        .take_while(|c| c.is_alphanumeric() || *c == '_')
        .collect()
}

/// The key whose value starts at `(line, column)`: on the same line before
/// the column (`child: [...]`), else the nearest line above that is
/// indented less and ends with `key:`.
fn owner_key(lines: &[&str], (line, column): (usize, usize)) -> Option<(usize, String)> {
    let text = line_of(lines, line);
    let before: String = text.chars().take(column.saturating_sub(1)).collect();
    let key_of = |t: &str| -> Option<String> {
        let t = t.trim_end().strip_suffix(':')?;
        let t = t.trim_start().trim_start_matches("- ").trim_start();
        let t = t.rsplit(['{', ',', ' ']).next().unwrap_or(t);
        (!t.is_empty() && t.chars().all(|c| c.is_alphanumeric() || c == '_')).then(|| t.to_string())
    };
    if !before.trim().is_empty() {
        return key_of(&before).map(|k| (line, k));
    }
    let indent = indent_of(text);
    (1..line)
        .rev()
        .map(|l| (l, line_of(lines, l)))
        .filter(|(_, t)| !is_blank_or_comment(t))
        .find(|(_, t)| indent_of(t) < indent || indent == 0)
        .and_then(|(l, t)| key_of(t).map(|k| (l, k)))
}

/// The lines enclosing `line`: going up, each non-blank line indented less
/// than the previous one found (their indentations are where a line may start).
fn enclosing_lines(lines: &[&str], line: usize) -> Vec<(usize, usize, String)> {
    let mut out: Vec<(usize, usize, String)> = Vec::new();
    let mut limit = usize::MAX;
    for l in (1..line).rev() {
        let t = line_of(lines, l);
        if is_blank_or_comment(t) {
            continue;
        }
        let i = indent_of(t);
        if i < limit {
            out.push((l, i, t.trim().to_string()));
            limit = i;
            if i == 0 {
                break;
            }
        }
    }
    out
}

/// The last token before `(line, column)` (skipping white space), with its
/// location.
fn token_before(
    lines: &[&str],
    (line, column): (usize, usize),
) -> Option<((usize, usize), String)> {
    let mut l = line;
    let mut limit = column.saturating_sub(1);
    while l >= 1 {
        let text: String = line_of(lines, l).chars().take(limit).collect();
        let trimmed = text.trim_end();
        if !trimmed.is_empty() && !trimmed.trim_start().starts_with('#') {
            let token: String = {
                let rev: String = trimmed
                    .chars()
                    .rev()
                    .take_while(|c| !c.is_whitespace() && !"-[{,".contains(*c))
                    .collect();
                rev.chars().rev().collect()
            };
            let col = trimmed.chars().count() - token.chars().count() + 1;
            return Some(((l, col), token));
        }
        l -= 1;
        limit = usize::MAX;
    }
    None
}

/// Plain-language messages, with the fix, for the YAML mistakes people
/// make most (a list under `child:`, two kinds in one node, tabs, bad
/// indentation) instead of the parser's own words.
fn common_mistake(
    e: &serde_saphyr::Error,
    source: &str,
    file: &str,
    loc: (usize, usize),
) -> Option<TreeError> {
    use serde_saphyr::Error as E;
    let (line, column) = loc;
    let lines: Vec<&str> = source.lines().collect();
    let text = line_of(&lines, line);
    let at = |l: (usize, usize), m: String, h: String| {
        Some(TreeError::at(Kind::Syntax, file, source, l, m).with_help(h))
    };
    let raw = e.to_string();
    // tabs anywhere in the indentation of this line (the scanner's message
    // varies with the context)
    if raw.contains("tab") {
        let lead: String = text
            .chars()
            .take_while(|c| *c == ' ' || *c == '\t')
            .collect();
        if let Some(i) = lead.chars().position(|c| c == '\t') {
            return at(
                (line, i + 1),
                "a tab indents this line".into(),
                "YAML indents with spaces only: replace each tab by spaces (e.g. 2 per level)"
                    .into(),
            );
        }
    }
    match e {
        E::ExternallyTaggedEnumExpectedScalarOrMapping { .. } => {
            let list = text
                .chars()
                .skip(column.saturating_sub(1))
                .collect::<String>()
                .trim_start()
                .starts_with(['-', '[']);
            if !list {
                return None;
            }
            match owner_key(&lines, loc) {
                Some((_, k)) if k == "child" => at(
                    loc,
                    "`child:` takes one node, not a list".into(),
                    "remove the `- ` (or the brackets) before the node: a decorator has exactly \
                     one child; to decorate several nodes put them in a sequence or fallback \
                     under `child:`"
                        .into(),
                ),
                Some((_, k)) if k == "tree" => at(
                    loc,
                    "`tree:` takes the root node, not a list".into(),
                    "remove the `- ` (or the brackets): to run several nodes put them in the \
                     `children:` list of a sequence, fallback or parallel"
                        .into(),
                ),
                _ => at(
                    loc,
                    "a node is expected here, not a list".into(),
                    "a node is written `kind: {key: value, ...}`; lists of nodes go under \
                     `children:`"
                        .into(),
                ),
            }
        }
        E::ExpectedMappingEndAfterEnumVariantValue { .. } => {
            let second = word_at(text, column);
            let first =
                enclosing_node(source, loc).map(|(l, c)| (l, word_at(line_of(&lines, l), c)));
            let (fl, first) = first.unwrap_or((0, "the node's kind".into()));
            let first_at = if fl > 0 {
                format!(" (line {fl})")
            } else {
                String::new()
            };
            if second == first {
                at(
                    loc,
                    format!("the node kind `{first}` appears twice in one node (line {fl} and line {line})"),
                    "a node has one kind; several nodes go in a `children:` list (each after its \
                     own `- `) under a sequence, fallback or parallel"
                        .into(),
                )
            } else if NODE_KINDS.contains(&second.as_str()) {
                at(
                    loc,
                    format!("two node kinds in one node: `{first}`{first_at} and `{second}`"),
                    format!(
                        "a node has one kind: to run both, make `{first}` and `{second}` two \
                         items of a `children:` list (each after its own `- `) under a sequence, \
                         fallback or parallel"
                    ),
                )
            } else {
                at(
                    loc,
                    format!(
                        "`{second}` is next to the node kind `{first}`{first_at}, not inside it"
                    ),
                    format!(
                        "indent `{second}:` further, under `{first}:` with its other keys (or put \
                         it inside the braces after `{first}:`)"
                    ),
                )
            }
        }
        E::DuplicateMappingKey { key, .. } => {
            let key = key.clone().unwrap_or_else(|| word_at(text, column));
            let help = if NODE_KINDS.contains(&key.as_str()) {
                "a node has one kind; several nodes go in a `children:` list, each after its own `- `"
                    .to_string()
            } else {
                format!("remove one of the two `{key}:`")
            };
            at(
                loc,
                format!("`{key}` appears twice in the same mapping"),
                help,
            )
        }
        E::Unexpected { expected, .. } if *expected == "sequence start" => {
            let key = owner_key(&lines, loc).map(|(_, k)| k);
            let key = key.as_deref().unwrap_or("children");
            at(
                loc,
                format!("`{key}:` takes a list of nodes"),
                "write each child on its own line after `- ` (e.g. `- action: {ps: 0.5, mu: 1, nu: 1}`), \
                 indented under `children:`, or as a flow list `[...]`"
                    .into(),
            )
        }
        E::Unexpected { expected, .. } if *expected == "mapping start" => {
            let rest: String = text.chars().skip(column.saturating_sub(1)).collect();
            let rest = rest.trim();
            let (tl, token) = if rest.starts_with(':') {
                let ((l, c), t) = token_before(&lines, loc)?;
                ((l, c), format!("{t}:"))
            } else {
                token_before(&lines, loc)?
            };
            if let Some(kind) = token.strip_suffix(':') {
                if NODE_KINDS.contains(&kind) && !rest.is_empty() && !rest.starts_with([':', '#']) {
                    return at(
                        loc,
                        format!("the keys of `{kind}:` must be in braces or on their own lines"),
                        format!(
                            "write `{kind}: {{{rest}, ...}}`, or each `key: value` on its own line \
                             indented under `{kind}:`"
                        ),
                    );
                }
                if NODE_KINDS.contains(&kind) {
                    return at(
                        tl,
                        format!("`{kind}:` has no keys"),
                        format!(
                            "indent its keys on the lines below, further than `{kind}` (e.g. 2 \
                             more spaces), or write them inline: `{kind}: {{ps: 0.5, mu: 1, nu: 1}}`"
                        ),
                    );
                }
            } else if NODE_KINDS.contains(&token.as_str()) {
                return at(
                    tl,
                    format!("the node kind `{token}` is written without its keys"),
                    format!("write `{token}:` followed by its keys, e.g. `{token}: {{ps: 0.5, mu: 1, nu: 1}}`"),
                );
            }
            None
        }
        E::ExternalMessage { msg, .. }
            if msg.contains("did not find expected key")
                || msg.contains("did not find expected '-'") =>
        {
            let indent = indent_of(text);
            let start = (line, indent + 1);
            if column != indent + 1 && !(text.trim_start().starts_with('-') && column == indent + 3)
            {
                return None;
            }
            let dash = text.trim_start().starts_with('-');
            let enclosing = enclosing_lines(&lines, line);
            if enclosing.iter().any(|(_, i, _)| *i == indent) {
                return None;
            }
            // where siblings of this line start: lines of the same shape
            let mut places: Vec<String> = enclosing
                .iter()
                .filter(|(_, _, t)| t.starts_with('-') == dash)
                .map(|(l, i, t)| {
                    let head: String = t.chars().take(24).collect();
                    format!("{i} like line {l} (`{head}`)")
                })
                .collect();
            places.truncate(3);
            let help = if places.is_empty() {
                "indent it like the lines it belongs with; YAML indents with spaces, the same \
                 number for siblings"
                    .to_string()
            } else {
                format!(
                    "indent it by the same number of spaces as the block it belongs to: {}",
                    places.join(", or ")
                )
            };
            at(
                start,
                format!(
                    "line {line} is indented {indent} spaces, which matches none of the blocks above it"
                ),
                help,
            )
        }
        E::ExternalMessage { msg, .. } if msg.contains("mapping values are not allowed") => at(
            loc,
            "a second `key:` on one line".into(),
            "write one `key: value` per line, with the keys of a node indented under its kind, \
             or put them in braces: `action: {ps: 0.5, mu: 1, nu: 1}`"
                .into(),
        ),
        _ => None,
    }
}

fn missing_help(field: &str) -> String {
    match field {
        "ps" => "every action and condition needs `ps`, its probability of success in [0, 1]",
        "children" => "a control node needs `children:`, a list of at least one node",
        "tree" => "a tree file needs a `tree:` key holding the root node",
        _ => "add the missing key",
    }
    .to_string()
}

/// The location of the node keyword (`action:`, `sequence:`, ...) that
/// encloses `(line, column)`: the nearest one before it in the text.
fn enclosing_node(source: &str, (line, column): (usize, usize)) -> Option<(usize, usize)> {
    if line == 0 {
        return None;
    }
    let lines: Vec<&str> = source.lines().collect();
    for l in (0..line.min(lines.len())).rev() {
        let text = lines[l];
        let limit = if l + 1 == line {
            text.char_indices()
                .nth(column.saturating_sub(1))
                .map_or(text.len(), |(i, _)| i)
        } else {
            text.len()
        };
        let head = &text[..limit];
        let mut best: Option<usize> = None;
        for kind in NODE_KINDS {
            let mut from = 0;
            while let Some(pos) = head[from..].find(kind) {
                let start = from + pos;
                let end = start + kind.len();
                let before_ok = start == 0
                    || !head[..start]
                        .chars()
                        .next_back()
                        .is_some_and(|c| c.is_alphanumeric() || c == '_');
                let after = head[end..].trim_start();
                if before_ok && after.starts_with(':') {
                    best = Some(best.map_or(start, |b: usize| b.max(start)));
                }
                from = end;
            }
        }
        if let Some(b) = best {
            return Some((l + 1, head[..b].chars().count() + 1));
        }
    }
    None
}

/// serde-saphyr appends " at line L, column C"; the location is shown separately.
fn strip_location(s: &str) -> String {
    match s.rfind(" at line ") {
        Some(i) => s[..i].to_string(),
        None => s.to_string(),
    }
}

struct Builder<'a> {
    source: &'a str,
    file: &'a str,
    nodes: Vec<Node>,
    locations: Vec<(usize, usize)>,
    max_depth: usize,
}

fn loc<T>(s: &At<T>) -> (usize, usize) {
    sloc(s)
}

impl Builder<'_> {
    fn err(&self, kind: Kind, at: (usize, usize), msg: impl Into<String>) -> TreeError {
        TreeError::at(kind, self.file, self.source, at, msg)
    }

    fn node(
        &mut self,
        def: &At<NodeDef>,
        parent: Option<usize>,
        depth: usize,
        path: String,
    ) -> Result<usize, TreeError> {
        let at = loc(def);
        if depth >= self.max_depth {
            return Err(self
                .err(Kind::Budget, at, "the tree is nested too deeply")
                .with_help(format!(
                    "btrel accepts trees up to {} levels deep",
                    self.max_depth
                )));
        }
        let id = self.nodes.len();
        if let Some((name, decorator, child)) = self.decorator(&def.value)? {
            let name = self.node_name(name, decorator.keyword(), &path)?;
            self.nodes.push(Node {
                name,
                path: path.clone(),
                depth,
                parent,
                kind: NodeKind::Decorator {
                    decorator,
                    child: 0,
                },
                location: Some(at),
            });
            self.locations.push(name_location(def).unwrap_or(at));
            let c = self.node(child, Some(id), depth + 1, child_path(&path, 0))?;
            if let NodeKind::Decorator { child, .. } = &mut self.nodes[id].kind {
                *child = c;
            }
            return Ok(id);
        }
        let (name, kind, children) = match &def.value {
            NodeDef::Action(a) => (&a.name, NodeKind::Action(self.action(a)?), None),
            NodeDef::Condition(c) => {
                let ps = self.probability("ps", &c.ps)?;
                (&c.name, NodeKind::Condition { ps }, None)
            }
            NodeDef::Sequence(c) => (
                &c.name,
                NodeKind::Sequence {
                    children: Vec::new(),
                },
                Some(&c.children),
            ),
            NodeDef::Fallback(c) => (
                &c.name,
                NodeKind::Fallback {
                    children: Vec::new(),
                },
                Some(&c.children),
            ),
            NodeDef::Parallel(p) => (
                &p.name,
                NodeKind::Parallel {
                    success_threshold: 0,
                    failure_threshold: 0,
                    children: Vec::new(),
                },
                Some(&p.children),
            ),
            NodeDef::IfThenElse(c) => (
                &c.name,
                NodeKind::Flow(Flow {
                    children: Vec::new(),
                    states: Vec::new(),
                }),
                Some(&c.children),
            ),
            NodeDef::Flow(f) => (
                &f.name,
                NodeKind::Flow(Flow {
                    children: Vec::new(),
                    states: Vec::new(),
                }),
                Some(&f.children),
            ),
            _ => unreachable!("decorators are handled above"),
        };
        let keyword = match &def.value {
            NodeDef::IfThenElse(_) => "if_then_else",
            _ => kind.keyword(),
        };
        let name = self.node_name(name, keyword, &path)?;
        self.nodes.push(Node {
            name,
            path: path.clone(),
            depth,
            parent,
            kind,
            location: Some(at),
        });
        self.locations.push(name_location(def).unwrap_or(at));
        if let Some(list) = children {
            if list.value.is_empty() {
                let keyword = self.nodes[id].kind.keyword();
                return Err(self
                    .err(
                        Kind::Structure,
                        loc(list),
                        format!("{keyword} has no children"),
                    )
                    .with_help("a control node needs at least one child"));
            }
            let mut ids = Vec::with_capacity(list.value.len());
            for (i, child) in list.value.iter().enumerate() {
                ids.push(self.node(child, Some(id), depth + 1, child_path(&path, i))?);
            }
            let thresholds = match &def.value {
                NodeDef::Parallel(p) => Some(self.thresholds(p, ids.len())?),
                _ => None,
            };
            let flow = match &def.value {
                NodeDef::IfThenElse(_) => {
                    if !(2..=3).contains(&ids.len()) {
                        return Err(self
                            .err(
                                Kind::Structure,
                                loc(list),
                                format!("if_then_else has {} children", ids.len()),
                            )
                            .with_help(
                                "if_then_else takes 2 or 3 children: condition, then, else \
                                 (without else it fails when the condition fails)",
                            ));
                    }
                    Some(Flow::if_then_else(ids[0], ids[1], ids.get(2).copied()))
                }
                NodeDef::Flow(f) => Some(self.flow(f, ids.clone())?),
                _ => None,
            };
            match &mut self.nodes[id].kind {
                NodeKind::Sequence { children } | NodeKind::Fallback { children } => {
                    *children = ids
                }
                NodeKind::Parallel {
                    children,
                    success_threshold,
                    failure_threshold,
                } => {
                    *children = ids;
                    (*success_threshold, *failure_threshold) = thresholds.unwrap_or((0, 0));
                }
                NodeKind::Flow(f) => *f = flow.expect("a flow definition"),
                _ => unreachable!("only control nodes have children"),
            }
        }
        Ok(id)
    }

    fn node_name(
        &self,
        name: &Option<At<String>>,
        keyword: &str,
        path: &str,
    ) -> Result<String, TreeError> {
        match name {
            Some(n) if n.value.trim().is_empty() => Err(self
                .err(Kind::InvalidValue, loc(n), "a node name must not be empty")
                .with_help("omit `name` to get a generated one")),
            Some(n) => Ok(n.value.clone()),
            None => Ok(format!("{keyword}@{path}")),
        }
    }

    #[allow(clippy::type_complexity)]
    fn decorator<'d>(
        &self,
        def: &'d NodeDef,
    ) -> Result<Option<(&'d Option<At<String>>, Decorator, &'d At<NodeDef>)>, TreeError> {
        Ok(Some(match def {
            NodeDef::Inverter(d) => (&d.name, Decorator::Inverter, &d.child),
            NodeDef::ForceSuccess(d) => (&d.name, Decorator::ForceSuccess, &d.child),
            NodeDef::ForceFailure(d) => (&d.name, Decorator::ForceFailure, &d.child),
            NodeDef::UntilFailure(d) => (&d.name, Decorator::UntilFailure, &d.child),
            NodeDef::UntilSuccess(d) => (&d.name, Decorator::UntilSuccess, &d.child),
            NodeDef::Retry(d) => (
                &d.name,
                Decorator::Retry {
                    attempts: self.count("attempts", &d.attempts)?,
                },
                &d.child,
            ),
            NodeDef::Repeat(d) => (
                &d.name,
                Decorator::Repeat {
                    times: self.count("times", &d.times)?,
                },
                &d.child,
            ),
            _ => return Ok(None),
        }))
    }

    /// The states of a `flow:` over children `ids`.
    fn flow(&self, def: &FlowDef, ids: Vec<usize>) -> Result<Flow, TreeError> {
        let n_states = def.states.value.len();
        let index = |v: &At<f64>, what: &str, bound: usize| -> Result<usize, TreeError> {
            let x = v.value;
            if !(x.is_finite() && x.fract() == 0.0 && x >= 0.0 && x < bound as f64) {
                return Err(self
                    .err(
                        Kind::InvalidValue,
                        loc(v),
                        format!("{what} {x} does not exist"),
                    )
                    .with_help(format!(
                        "{what}s are numbered from 0 to {} in the order written",
                        bound.saturating_sub(1)
                    )));
            }
            Ok(x as usize)
        };
        let mut states = Vec::with_capacity(n_states);
        for (i, s) in def.states.value.iter().enumerate() {
            let child = index(&s.value.run, "child", ids.len())?;
            let next = |n: &At<NextDef>| -> Result<FlowNext, TreeError> {
                match &n.value {
                    NextDef::Outcome(w) if w == "success" => Ok(FlowNext::Success),
                    NextDef::Outcome(w) if w == "failure" => Ok(FlowNext::Failure),
                    NextDef::Outcome(w) => Err(self
                        .err(Kind::InvalidValue, loc(n), format!("`{w}` is not a state"))
                        .with_help("write a later state's number, `success` or `failure`")),
                    NextDef::State(_) => {
                        let at = At {
                            value: match n.value {
                                NextDef::State(x) => x,
                                _ => unreachable!(),
                            },
                            line: n.line,
                            column: n.column,
                        };
                        let j = index(&at, "state", n_states)?;
                        if j <= i {
                            return Err(self
                                .err(
                                    Kind::Structure,
                                    loc(n),
                                    format!("state {i} goes back to state {j}"),
                                )
                                .with_help(
                                    "a flow is acyclic: a state may only lead to a later state \
                                     (repeat with retry/repeat around the flow instead)",
                                ));
                        }
                        Ok(FlowNext::State(j))
                    }
                }
            };
            states.push(FlowState {
                child,
                on_success: next(&s.value.success)?,
                on_failure: next(&s.value.failure)?,
            });
        }
        Flow::new(ids, states).map_err(|what| {
            self.err(
                Kind::Structure,
                loc(&def.states),
                format!("invalid flow: {what}"),
            )
            .with_help("every child must be run by some state; state 0 runs first")
        })
    }

    /// A repetition count: a whole number from 1 to 1,000,000.
    fn count(&self, key: &str, v: &At<f64>) -> Result<usize, TreeError> {
        let x = v.value;
        if !(x.is_finite() && x.fract() == 0.0 && (1.0..=1e6).contains(&x)) {
            return Err(self
                .err(
                    Kind::InvalidValue,
                    loc(v),
                    format!("{key} = {x} is not a valid count"),
                )
                .with_help(format!("{key} must be a whole number from 1 to 1000000")));
        }
        Ok(x as usize)
    }

    fn thresholds(&self, p: &ParallelDef, n: usize) -> Result<(usize, usize), TreeError> {
        let check = |t: &At<f64>, key: &str, meaning: &str| -> Result<usize, TreeError> {
            let v = t.value;
            if !(v.is_finite() && v.fract() == 0.0 && v >= 1.0 && v <= n as f64) {
                return Err(self
                    .err(
                        Kind::InvalidValue,
                        loc(t),
                        format!(
                            "{key} = {v} is not valid for {n} {}",
                            if n == 1 { "child" } else { "children" }
                        ),
                    )
                    .with_help(format!(
                        "{key} must be a whole number from 1 to {n}: {meaning}"
                    )));
            }
            Ok(v as usize)
        };
        let m = match &p.success_threshold {
            Some(t) => check(t, "success_threshold", "Success at >= M successes")?,
            None => n,
        };
        let f = match &p.failure_threshold {
            Some(t) => check(t, "failure_threshold", "Failure at >= F failures")?,
            None => n - m + 1,
        };
        Ok((m, f))
    }

    fn probability(&self, key: &str, v: &At<f64>) -> Result<f64, TreeError> {
        let x = v.value;
        if !x.is_finite() || !(0.0..=1.0).contains(&x) {
            return Err(self
                .err(
                    Kind::InvalidValue,
                    loc(v),
                    format!("{key} = {x} is not a probability"),
                )
                .with_help(format!("{key} must be a number in [0, 1]")));
        }
        Ok(x)
    }

    fn action(&self, a: &ActionDef) -> Result<Action, TreeError> {
        let params = ActionParams {
            ps: Some(a.ps.clone()),
            pf: a.pf.clone(),
            mu: a.mu.clone(),
            nu: a.nu.clone(),
            tau_s: a.tau_s.clone(),
            tau_f: a.tau_f.clone(),
            success_time: a.success_time.clone(),
            failure_time: a.failure_time.clone(),
        };
        let err = |at: (usize, usize), message: String, help: String| {
            self.err(Kind::InvalidValue, at, message).with_help(help)
        };
        match validate_action(&params, &err)? {
            Ok(action) => Ok(action),
            Err(missing) => {
                let (what, help) = missing.split_once(": ").unwrap_or((&missing, ""));
                Err(self
                    .err(Kind::MissingParameter, loc(&a.ps), format!("action {what}"))
                    .with_help(help.to_string()))
            }
        }
    }

    fn check_names(&self) -> Result<(), TreeError> {
        let mut seen: std::collections::HashMap<&str, usize> =
            std::collections::HashMap::with_capacity(self.nodes.len());
        for (i, n) in self.nodes.iter().enumerate() {
            if let Some(&j) = seen.get(n.name.as_str()) {
                let (l, c) = self.locations[j];
                return Err(self
                    .err(
                        Kind::Structure,
                        self.locations[i],
                        format!("duplicate node name '{}'", n.name),
                    )
                    .with_help(format!(
                        "names must be unique; '{}' is already used at line {l}, column {c}",
                        n.name
                    )));
            }
            seen.insert(&n.name, i);
        }
        Ok(())
    }
}

/// `{path}.{i}` without the formatting machinery (a million-node tree
/// builds a million of these).
fn child_path(path: &str, i: usize) -> String {
    let mut digits = [0u8; 20];
    let mut k = digits.len();
    let mut n = i;
    loop {
        k -= 1;
        digits[k] = b'0' + (n % 10) as u8;
        n /= 10;
        if n == 0 {
            break;
        }
    }
    let mut p = String::with_capacity(path.len() + 1 + digits.len() - k);
    p.push_str(path);
    p.push('.');
    p.extend(digits[k..].iter().map(|&d| d as char));
    p
}

fn name_location(def: &At<NodeDef>) -> Option<(usize, usize)> {
    let name = match &def.value {
        NodeDef::Action(a) => &a.name,
        NodeDef::Condition(c) => &c.name,
        NodeDef::Sequence(c) | NodeDef::Fallback(c) | NodeDef::IfThenElse(c) => &c.name,
        NodeDef::Parallel(p) => &p.name,
        NodeDef::Flow(f) => &f.name,
        NodeDef::Inverter(d)
        | NodeDef::ForceSuccess(d)
        | NodeDef::ForceFailure(d)
        | NodeDef::UntilFailure(d)
        | NodeDef::UntilSuccess(d) => &d.name,
        NodeDef::Retry(d) => &d.name,
        NodeDef::Repeat(d) => &d.name,
    };
    name.as_ref().map(loc)
}
