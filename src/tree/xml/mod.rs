//! BehaviorTree.CPP XML front end (formats 3 and 4), for trees as published.
//!
//! A tree is read from the BT.CPP XML (structure), optionally more XML files
//! (SubTrees defined elsewhere, node models), and a small YAML params file
//! (the stochastic parameters of each action and condition):
//!
//! ```yaml
//! # keyed by the node's name attribute first, then its ID
//! search floor: {ps: 0.3, mu: 0.0167, nu: 0.01}
//! OneHandGrasp: {ps: 0.1, mu: 0.1, nu: 2}
//! ObjectGrasped: {ps: 0.0}          # conditions: ps only
//! ```
//!
//! A leaf's parameters are looked up by its final (unique, prefixed) name,
//! then its `name` attribute, then its `ID`; the first key present wins.
//! Action parameters follow the YAML format's rules exactly. Every params
//! key must be used by some node. All leaves whose parameters are missing are
//! listed in one error, one line each with the node's file, line and column.
//!
//! # Leaves
//!
//! An element without children that is not a known node type is a leaf. It
//! is an action or a condition by, in this order: its explicit form
//! (`<Action ID>` / `<Condition ID>`), a `<TreeNodesModel>` entry (in any file
//! read), or its params entry: an entry with `ps` only is a condition (an
//! action with `ps` alone would lack its outcome times), an entry with any
//! of `pf`, `mu`, `nu`, `tau_s`, `tau_f` is an action. A `<SubTree ID>` that
//! no file defines but that has a params entry is one such leaf (a black
//! box).
//!
//! # Files
//!
//! The main file's trees come first: a BehaviorTree ID defined there shadows
//! included definitions; an ID defined by two included files is an error
//! when used. `<include path="..."/>` is followed relative to the including
//! file (`ros_pkg` is refused); each file is read once. Without
//! `main_tree_to_execute` the first tree of the main file is analysed; a
//! file's only `<BehaviorTree>` may have no ID (not in an included file).
//!
//! # Node types
//!
//! * `Sequence`, `SequenceWithMemory` (v3: `SequenceStar`),
//!   `ReactiveSequence` become a Sequence; `Fallback`, `ReactiveFallback` a
//!   Fallback. Under the SBT assumptions (a condition is evaluated once per
//!   execution of its parent and keeps its outcome; a running action is never
//!   interrupted by a re-evaluated sibling) a reactive node runs exactly like
//!   its non-reactive counterpart — when at most one child holds actions. BT.CPP
//!   halts the other children when one returns RUNNING and re-ticks them from
//!   IDLE, so with actions in two children an earlier action is restarted
//!   while a later one runs (found by `tests/btcpp_referee.rs`): read as that
//!   restart loop (`reactive.rs`), which may never return; refused when a
//!   child may return within its first tick.
//!   `SequenceWithMemory` resumes at the failed
//!   child when ticked again after a failure, so below a node that ticks a
//!   failed child again (`RetryUntilSuccessful` with more than one attempt,
//!   the main branch of a `RecoveryNode`) it differs from a fresh Sequence:
//!   there it is a `NodeKind::SequenceWithMemory` whose copies share one
//!   index slot, followed as a flow by `tree::nav2` — except as the direct
//!   child of a `RetryUntilSuccessful` without a retrying ancestor, which
//!   becomes one flow over (failures so far, child index)
//!   (`Builder::retry_with_memory`).
//! * `IfThenElse` (2 or 3 children) is the flow C → (Success: T, Failure: E
//!   or Failure); `WhileDoElse` likewise when its condition child holds
//!   conditions only (BT.CPP re-ticks it while a branch runs, which changes
//!   nothing while conditions keep their value); with an action there it is
//!   refused.
//! * `Parallel`: v4 `success_count` (default −1), `failure_count` (default
//!   1); v3 `success_threshold` (required), `failure_threshold` (default 1);
//!   a negative count k means N + k + 1. A file without `BTCPP_format` uses
//!   the v3 names if the node does, else the v4 rules.
//! * `Inverter`, `ForceSuccess`, `ForceFailure`, `RetryUntilSuccessful` (v3:
//!   `RetryUntilSuccesful`) `num_attempts`, `Repeat num_cycles` (1 to
//!   1 000 000).
//! * Nav2's `RecoveryNode(main, recovery) number_of_retries=n` (default 1,
//!   0 to 1000): Fallback(main, Sequence(recovery, RecoveryNode(n − 1))) with
//!   RecoveryNode(0) = main, built from fresh copies (named `R/recovery k/..`
//!   and `R/attempt k/..`): Nav2's loop exactly; the index of a RoundRobin
//!   or SequenceWithMemory in the main branch, which carries over the
//!   retries, is followed as a flow (`tree::nav2`).
//! * `AlwaysSuccess` / `AlwaysFailure`: conditions with ps 1 / 0.
//! * `Script`, `SetBlackboard`, `UnsetBlackboard`: BT.CPP runs them at once
//!   and they return Success: a condition with ps 1, unless the params file
//!   has an entry for them (then that entry models them, e.g. a run time).
//! * The explicit forms `<Control ID="X">`, `<Decorator ID="X">`,
//!   `<Action ID="X">`, `<Condition ID="X">` are the node type X;
//!   `SubTreePlus` (v3) is `SubTree`.
//!
//! * ManualSelector, ConsumeQueue, MoveIt Pro's ForEach and
//!   RepeatUnlessFailureEachTick, Nav2's GoalUpdatedController,
//!   PathLongerOnApproach, DistanceController and SpeedController: see
//!   `controllers.rs` and `predicates.rs` (branch probabilities, queue
//!   lengths and the robot's speed from the params file).
//!
//! Known node types without a stochastic meaning yet (RunOnce, ParallelAll,
//! Nav2's PersistentSequence, ...), custom control nodes
//! and decorators, counts from the blackboard (unless the params file gives
//! the reference a value: `"{name}": {value: N}`) or −1 (forever), and
//! pre-conditions (`_skipIf`, `_failureIf`, `_successIf`, `_while`, unless
//! constant no-ops such as `_skipIf="false"`) are all listed in one error
//! (see [`is_unsupported`]); unknown nodes with children and SubTrees defined
//! nowhere are listed in one error too, each with its file, line and column.
//!
//! # Accepted as BT.CPP's parser does
//!
//! Other attributes starting with `_` (Groot and MoveIt Pro metadata such as
//! `_description`, `_collapsed`; `_autoremap`; the post-conditions
//! `_onSuccess`, `_onFailure`, `_onHalted`, `_post`, which only write the
//! blackboard after the node has returned) are ignored; data ports of leaves,
//! SubTrees and BehaviorTrees are ignored (the params file gives the outcome
//! distribution). Like tinyxml2, a `&` that does not start a known reference
//! is kept as it is (`a && b`), text anywhere (also around the root element)
//! is ignored, and a comment ends at the first `-->`. CDATA, DOCTYPE and
//! processing instructions are refused.
//!
//! # Names
//!
//! A node's name is its `name` attribute, else its ID (the tag for control
//! nodes and decorators, e.g. `Sequence`). Nodes expanded from a SubTree are
//! prefixed with the SubTree instance's name (its `name`, else its ID) and
//! `/`, nested instances with each instance in turn (`Outer/Inner/grasp`).
//! Names must be unique, so a later node whose name is taken gets `#2`, `#3`,
//! ... (the first free one) appended, in pre-order.
//!
//! # Limits
//!
//! Input up to 256 MiB (all XML files together), at most 10 000 files, XML
//! elements nested at most 202 deep (`root`, `BehaviorTree` and 200 tree
//! levels), expanded trees at most 200 levels deep, at most 5 million nodes
//! after SubTree and RecoveryNode expansion (checked before building) and
//! 256 MiB of node names. The XML reader is iterative and the tree builder's
//! recursion is bounded by those depths.

use std::collections::{BTreeMap, HashMap, HashSet};
use std::path::Path;

use super::action::{sloc, validate_action, ActionParams, At, Loc, TimeDef};
use super::error::{nearest, TreeError, TreeErrorKind as Kind};
use super::{Decorator, Flow, FlowNext, FlowState, Node, NodeKind, Tree};

mod controllers;
mod predicates;
mod reactive;

/// Largest XML or params file, in bytes.
pub const MAX_BYTES: usize = 256 << 20;
/// Deepest tree after SubTree expansion (the root is level 1).
pub const MAX_DEPTH: usize = 200;
/// Deepest XML element nesting: `root`, `BehaviorTree`, then the tree.
pub const MAX_XML_DEPTH: usize = MAX_DEPTH + 2;
/// Most nodes after SubTree expansion.
pub const MAX_NODES: usize = 5_000_000;
/// Most bytes of node names after SubTree expansion.
pub const MAX_NAME_BYTES: usize = 256 << 20;

// ---------------------------------------------------------------------------
// A small, strict XML reader
// ---------------------------------------------------------------------------

#[derive(Debug)]
struct Attr {
    name: String,
    value: String,
    loc: Loc,
}

#[derive(Debug)]
struct Elem {
    /// Index of the source file (0: the main tree file).
    doc: usize,
    name: String,
    loc: Loc,
    attrs: Vec<Attr>,
    children: Vec<usize>,
    /// Location of the first non-whitespace text directly inside.
    text: Option<Loc>,
}

impl Elem {
    fn attr(&self, name: &str) -> Option<&Attr> {
        self.attrs.iter().find(|a| a.name == name)
    }
}

struct Reader<'a> {
    src: &'a str,
    file: &'a str,
    doc: usize,
    pos: usize,
    line: usize,
    col: usize,
}

impl<'a> Reader<'a> {
    fn loc(&self) -> Loc {
        (self.line, self.col)
    }

    fn err(&self, kind: Kind, at: Loc, msg: impl Into<String>) -> TreeError {
        TreeError::at(kind, self.file, self.src, at, msg)
    }

    fn rest(&self) -> &'a str {
        &self.src[self.pos..]
    }

    fn peek(&self) -> Option<char> {
        self.rest().chars().next()
    }

    fn bump(&mut self) -> Option<char> {
        let c = self.peek()?;
        self.pos += c.len_utf8();
        if c == '\n' {
            self.line += 1;
            self.col = 1;
        } else {
            self.col += 1;
        }
        Some(c)
    }

    fn starts_with(&self, s: &str) -> bool {
        self.rest().starts_with(s)
    }

    /// Consumes `s` if the input continues with it.
    fn eat(&mut self, s: &str) -> bool {
        if !self.starts_with(s) {
            return false;
        }
        for _ in s.chars() {
            self.bump();
        }
        true
    }

    fn skip_ws(&mut self) -> bool {
        let mut any = false;
        while matches!(self.peek(), Some(' ' | '\t' | '\r' | '\n')) {
            self.bump();
            any = true;
        }
        any
    }

    /// Consumes everything up to and including `end`; `what` names the
    /// construct opened at `start` for the error.
    fn skip_past(&mut self, end: &str, start: Loc, what: &str) -> Result<(), TreeError> {
        match self.rest().find(end) {
            Some(i) => {
                let stop = self.pos + i + end.len();
                while self.pos < stop {
                    self.bump();
                }
                Ok(())
            }
            None => Err(self
                .err(Kind::Syntax, start, format!("unterminated {what}"))
                .with_help(format!("close it with `{end}`"))),
        }
    }

    fn name(&mut self, what: &str) -> Result<String, TreeError> {
        let at = self.loc();
        match self.peek() {
            Some(c) if c.is_alphabetic() || c == '_' || c == ':' => {}
            Some(c) => {
                return Err(self
                    .err(Kind::Syntax, at, format!("expected {what}, found {c:?}"))
                    .with_help("XML names start with a letter or `_`"))
            }
            None => {
                return Err(self.err(
                    Kind::Syntax,
                    at,
                    format!("expected {what}, found the end of the file"),
                ))
            }
        }
        let start = self.pos;
        while let Some(c) = self.peek() {
            if c.is_alphanumeric() || matches!(c, '_' | ':' | '-' | '.') {
                self.bump();
            } else {
                break;
            }
        }
        Ok(self.src[start..self.pos].to_string())
    }

    /// Skips comments and whitespace; refuses DOCTYPE, processing
    /// instructions and CDATA wherever markup may appear.
    fn misc(&mut self) -> Result<(), TreeError> {
        loop {
            self.skip_ws();
            let at = self.loc();
            if self.starts_with("<!--") {
                // BT.CPP (tinyxml2) accepts `--` inside comments: the
                // comment ends at the first `-->` after `<!--`
                self.eat("<!--");
                self.skip_past("-->", at, "comment")?;
            } else if self.starts_with("<![CDATA[") {
                return Err(self
                    .err(Kind::Syntax, at, "CDATA sections are not supported")
                    .with_help("a behavior tree needs no text content; remove the CDATA section"));
            } else if self.starts_with("<!") {
                return Err(self
                    .err(
                        Kind::Syntax,
                        at,
                        "DOCTYPE and other declarations are not supported",
                    )
                    .with_help("remove the declaration; BT.CPP files do not need it"));
            } else if self.starts_with("<?") {
                return Err(self
                    .err(
                        Kind::Syntax,
                        at,
                        "processing instructions are not supported",
                    )
                    .with_help("only `<?xml ...?>` at the very start of the file is accepted"));
            } else {
                return Ok(());
            }
        }
    }

    /// Decodes entity and character references in `raw`. Like BT.CPP's
    /// parser (tinyxml2), a `&` that does not start a known reference is
    /// kept as it is (`a && b` in scripts).
    fn decode(raw: &str) -> String {
        if !raw.contains('&') {
            return raw.to_string();
        }
        let mut out = String::with_capacity(raw.len());
        let mut rest = raw;
        while let Some(i) = rest.find('&') {
            out.push_str(&rest[..i]);
            let tail = &rest[i + 1..];
            let ch = tail.find(';').filter(|&e| e <= 12).and_then(|end| {
                let ent = &tail[..end];
                let c = match ent {
                    "lt" => Some('<'),
                    "gt" => Some('>'),
                    "amp" => Some('&'),
                    "quot" => Some('"'),
                    "apos" => Some('\''),
                    _ => {
                        let num = if let Some(h) = ent.strip_prefix("#x") {
                            (!h.is_empty() && h.chars().all(|c| c.is_ascii_hexdigit()))
                                .then(|| u32::from_str_radix(h, 16).ok())
                                .flatten()
                        } else if let Some(d) = ent.strip_prefix('#') {
                            (!d.is_empty() && d.chars().all(|c| c.is_ascii_digit()))
                                .then(|| d.parse::<u32>().ok())
                                .flatten()
                        } else {
                            None
                        };
                        num.and_then(char::from_u32).filter(|&c| xml_char(c))
                    }
                };
                c.map(|c| (c, end))
            });
            match ch {
                Some((c, end)) => {
                    out.push(c);
                    rest = &tail[end + 1..];
                }
                None => {
                    out.push('&');
                    rest = tail;
                }
            }
        }
        out.push_str(rest);
        out
    }

    fn attr_value(&mut self) -> Result<String, TreeError> {
        let at = self.loc();
        let quote = match self.peek() {
            Some(q @ ('"' | '\'')) => q,
            _ => {
                return Err(self
                    .err(Kind::Syntax, at, "expected a quoted attribute value")
                    .with_help("write attributes as name=\"value\" or name='value'"))
            }
        };
        self.bump();
        let start = self.pos;
        loop {
            match self.peek() {
                None => {
                    return Err(self
                        .err(Kind::Syntax, at, "unterminated attribute value")
                        .with_help(format!("close the value with {quote}")))
                }
                Some('<') => {
                    return Err(self
                        .err(Kind::Syntax, self.loc(), "`<` inside an attribute value")
                        .with_help("write it as &lt;"))
                }
                Some(c) if c == quote => break,
                Some(_) => {
                    self.bump();
                }
            }
        }
        let raw = &self.src[start..self.pos];
        self.bump();
        // attribute-value normalisation: white space characters become spaces
        let v = Self::decode(raw);
        Ok(v.replace(['\t', '\n', '\r'], " "))
    }

    /// Skips comments, white space and stray text (which BT.CPP's parser
    /// accepts outside the root element too, e.g. `// clang-format off`).
    fn misc_and_text(&mut self) -> Result<(), TreeError> {
        loop {
            self.misc()?;
            match self.peek() {
                Some('<') | None => return Ok(()),
                Some(_) => {
                    while !matches!(self.peek(), Some('<') | None) {
                        self.bump();
                    }
                }
            }
        }
    }

    fn parse(mut self) -> Result<Vec<Elem>, TreeError> {
        if let Some((i, c)) = self
            .src
            .char_indices()
            .find(|&(_, c)| !xml_char(c) && c != '\u{feff}')
        {
            let before = &self.src[..i];
            let line = before.matches('\n').count() + 1;
            let col = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
            return Err(self
                .err(
                    Kind::Syntax,
                    (line, col),
                    format!("character U+{:04X} is not allowed in XML", c as u32),
                )
                .with_help("is this really a BehaviorTree.CPP XML file?"));
        }
        self.eat("\u{feff}");
        if self.starts_with("<?xml") {
            let at = self.loc();
            self.skip_past("?>", at, "XML declaration")?;
        }
        self.misc_and_text()?;
        if self.peek().is_none() {
            return Err(self
                .err(Kind::Syntax, (1, 1), "the file has no root element")
                .with_help("is this really a BehaviorTree.CPP XML file? It is `<root BTCPP_format=\"4\"> <BehaviorTree ID=\"Main\"> ... </BehaviorTree> </root>`"));
        }
        let mut elems: Vec<Elem> = Vec::new();
        let mut stack: Vec<usize> = Vec::new();
        loop {
            // here we are at markup or text inside the open element on top of
            // the stack (or at the root element if the stack is empty)
            let at = self.loc();
            if self.peek().is_none() {
                let Some(e) = stack.last().map(|&open| &elems[open]) else {
                    return Err(self.err(Kind::Syntax, at, "unexpected end of the file"));
                };
                return Err(self
                    .err(
                        Kind::Syntax,
                        e.loc,
                        format!("element <{}> is never closed", e.name),
                    )
                    .with_help(format!("add </{}>", e.name)));
            }
            if self.starts_with("</") {
                self.eat("</");
                let name = self.name("an element name")?;
                self.skip_ws();
                if !self.eat(">") {
                    return Err(self.err(
                        Kind::Syntax,
                        self.loc(),
                        "expected `>` to end the closing tag",
                    ));
                }
                let Some(&open) = stack.last() else {
                    return Err(self.err(
                        Kind::Syntax,
                        at,
                        format!("closing tag </{name}> without an opening tag"),
                    ));
                };
                if elems[open].name != name {
                    let e = &elems[open];
                    return Err(self
                        .err(
                            Kind::Syntax,
                            at,
                            format!("</{name}> does not close <{}>", e.name),
                        )
                        .with_help(format!(
                            "<{}> opened at line {}, column {} must be closed first",
                            e.name, e.loc.0, e.loc.1
                        )));
                }
                stack.pop();
                if stack.is_empty() {
                    break;
                }
            } else if self.starts_with("<!") || self.starts_with("<?") {
                self.misc()?;
            } else if self.starts_with("<") {
                self.bump();
                let name = self.name("an element name")?;
                let mut attrs: Vec<Attr> = Vec::new();
                let self_closing = loop {
                    let ws = self.skip_ws();
                    if self.eat("/>") {
                        break true;
                    }
                    if self.eat(">") {
                        break false;
                    }
                    let aloc = self.loc();
                    if self.peek().is_none() {
                        return Err(self
                            .err(Kind::Syntax, at, format!("unterminated tag <{name}"))
                            .with_help("end it with `>` or `/>`"));
                    }
                    if !ws {
                        return Err(self
                            .err(Kind::Syntax, aloc, "expected white space, `>` or `/>`")
                            .with_help("separate attributes with spaces"));
                    }
                    let aname = self.name("an attribute name or `>`")?;
                    self.skip_ws();
                    if !self.eat("=") {
                        return Err(self
                            .err(
                                Kind::Syntax,
                                self.loc(),
                                format!("expected `=` after attribute `{aname}`"),
                            )
                            .with_help("write attributes as name=\"value\""));
                    }
                    self.skip_ws();
                    let value = self.attr_value()?;
                    if let Some(prev) = attrs.iter().find(|a| a.name == aname) {
                        return Err(self
                            .err(Kind::Syntax, aloc, format!("duplicate attribute `{aname}`"))
                            .with_help(format!(
                                "`{aname}` is already given at line {}, column {}",
                                prev.loc.0, prev.loc.1
                            )));
                    }
                    attrs.push(Attr {
                        name: aname,
                        value,
                        loc: aloc,
                    });
                };
                let id = elems.len();
                elems.push(Elem {
                    doc: self.doc,
                    name,
                    loc: at,
                    attrs,
                    children: Vec::new(),
                    text: None,
                });
                if let Some(&parent) = stack.last() {
                    elems[parent].children.push(id);
                }
                if self_closing {
                    if stack.is_empty() {
                        break;
                    }
                } else {
                    if stack.len() >= MAX_XML_DEPTH {
                        return Err(self
                            .err(Kind::Budget, at, "the XML is nested too deeply")
                            .with_help(format!(
                                "btrel accepts trees up to {MAX_DEPTH} levels deep"
                            )));
                    }
                    stack.push(id);
                }
            } else {
                let mut first: Option<Loc> = None;
                while let Some(c) = self.peek() {
                    if c == '<' {
                        break;
                    }
                    if first.is_none() && !c.is_whitespace() {
                        first = Some(self.loc());
                    }
                    self.bump();
                }
                if let (Some(f), Some(&top)) = (first, stack.last()) {
                    elems[top].text.get_or_insert(f);
                }
            }
        }
        // after the root element: only comments, white space and text
        self.misc_and_text()?;
        if self.peek().is_some() {
            return Err(self
                .err(Kind::Syntax, self.loc(), "content after the root element")
                .with_help("an XML file has exactly one root element"));
        }
        Ok(elems)
    }
}

fn xml_char(c: char) -> bool {
    matches!(c, '\t' | '\n' | '\r')
        || (' '..='\u{d7ff}').contains(&c)
        || ('\u{e000}'..='\u{fffd}').contains(&c)
        || c >= '\u{10000}'
}

/// One element of an XML document as [`scan_elements`] returns it.
#[derive(Debug, Clone)]
pub struct XmlElement {
    /// The element's name (tag).
    pub name: String,
    /// Its attributes, in document order.
    pub attrs: Vec<(String, String)>,
    /// 1-based line and column of its start tag.
    pub line: usize,
    pub column: usize,
    /// Indices of its child elements.
    pub children: Vec<usize>,
}

impl XmlElement {
    /// The value of attribute `name`.
    pub fn attr(&self, name: &str) -> Option<&str> {
        self.attrs
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, v)| v.as_str())
    }
}

/// Reads an XML document with btrel's strict XML reader and returns its
/// elements in document order (element 0 is the root). `file` names the
/// source in error messages.
pub fn scan_elements(src: &str, file: &str) -> Result<Vec<XmlElement>, TreeError> {
    if src.len() > MAX_BYTES {
        return Err(too_large(file, src.len()));
    }
    let elems = Reader {
        src,
        file,
        doc: 0,
        pos: 0,
        line: 1,
        col: 1,
    }
    .parse()?;
    Ok(elems
        .into_iter()
        .map(|e| XmlElement {
            name: e.name,
            attrs: e.attrs.into_iter().map(|a| (a.name, a.value)).collect(),
            line: e.loc.0,
            column: e.loc.1,
            children: e.children,
        })
        .collect())
}

// ---------------------------------------------------------------------------
// Params file
// ---------------------------------------------------------------------------

/// A params file entry: an action's keys, plus an optional `fit:` mapping
/// (written by `btrel fit`: counts, standard errors, intervals) that the
/// analysis ignores.
#[derive(serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct ParamsEntry {
    #[serde(default)]
    ps: Option<At<f64>>,
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
    #[serde(default)]
    #[allow(dead_code)]
    fit: Option<serde::de::IgnoredAny>,
    /// The value of a blackboard entry (keys written `"{name}"`).
    #[serde(default)]
    value: Option<At<f64>>,
}

/// The params file: leaf entries by name or ID, and blackboard values by
/// their reference as written in the XML (`{num_samples}`).
struct ParamsTable {
    leaves: BTreeMap<String, At<ActionParams>>,
    blackboard: BTreeMap<String, At<f64>>,
}

/// Whether a params key names a blackboard entry (`{name}`).
fn is_blackboard_key(key: &str) -> bool {
    key.len() > 2 && key.starts_with('{') && key.ends_with('}')
}

fn parse_params(src: &str, file: &str) -> Result<ParamsTable, TreeError> {
    let entries: BTreeMap<String, At<ParamsEntry>> = parse_params_entries(src, file)?;
    let mut table = ParamsTable {
        leaves: BTreeMap::new(),
        blackboard: BTreeMap::new(),
    };
    for (k, e) in entries {
        let p = e.value;
        let at = |line: u32, column: u32| (line as usize, column as usize);
        // `"<node>/<port>": {value: x}`: a number a node reads for a port
        // whose value comes from the robot (a DistanceController's speed)
        let port_value = k.contains('/') && p.value.is_some();
        if is_blackboard_key(&k) || port_value {
            let leaf_key = [&p.ps, &p.pf, &p.mu, &p.nu, &p.tau_s, &p.tau_f]
                .into_iter()
                .flatten()
                .map(|x| (x.line, x.column))
                .chain(
                    [&p.success_time, &p.failure_time]
                        .into_iter()
                        .flatten()
                        .map(|x| (x.line, x.column)),
                )
                .next();
            let Some(v) = p.value else {
                return Err(TreeError::at(
                    Kind::Structure,
                    file,
                    src,
                    at(e.line, e.column),
                    format!("blackboard entry `{k}` needs a `value`"),
                )
                .with_help(format!(
                    "a key written `{{name}}` gives the value a port `{{name}}` reads, e.g. \
                     `\"{k}\": {{value: 3}}`"
                )));
            };
            if leaf_key.is_some() || p.fit.is_some() {
                let (line, column) = leaf_key.unwrap_or((e.line, e.column));
                let what = if port_value {
                    "port value"
                } else {
                    "blackboard entry"
                };
                return Err(TreeError::at(
                    Kind::Structure,
                    file,
                    src,
                    at(line, column),
                    format!("{what} `{k}` takes only `value`"),
                )
                .with_help("leaf parameters (ps, mu, ...) belong under the leaf's name or ID"));
            }
            // errors about the entry point at its key
            let v = At {
                value: v.value,
                line: e.line,
                column: e.column,
            };
            table.blackboard.insert(k, v);
            continue;
        }
        if let Some(v) = p.value {
            return Err(TreeError::at(
                Kind::Structure,
                file,
                src,
                at(v.line, v.column),
                format!(
                    "`value` in the entry of `{k}`, which is not a blackboard reference or a \
                     node's port"
                ),
            )
            .with_help(format!(
                "`value` gives a blackboard entry, keyed as the XML writes it: `\"{{{k}}}\": \
                 {{value: ...}}`, or a node's port, keyed `\"<node>/<port>\"` (e.g. \
                 `\"DistanceController/speed\": {{value: 0.3}}`); a leaf takes ps, pf, mu, nu, \
                 tau_s, tau_f"
            )));
        }
        let params = ActionParams {
            ps: p.ps,
            pf: p.pf,
            mu: p.mu,
            nu: p.nu,
            tau_s: p.tau_s,
            tau_f: p.tau_f,
            success_time: p.success_time,
            failure_time: p.failure_time,
        };
        table.leaves.insert(
            k,
            At {
                value: params,
                line: e.line,
                column: e.column,
            },
        );
    }
    Ok(table)
}

fn parse_params_entries(
    src: &str,
    file: &str,
) -> Result<BTreeMap<String, At<ParamsEntry>>, TreeError> {
    let only_comments = src
        .lines()
        .all(|l| l.trim().is_empty() || l.trim_start().starts_with('#'));
    if only_comments {
        return Ok(BTreeMap::new());
    }
    let options = serde_saphyr::options! {
        budget: serde_saphyr::budget! {
            max_depth: 16,
            max_nodes: 50_000_000,
            max_events: 200_000_000,
            max_total_scalar_bytes: MAX_BYTES,
            flow_nesting_limit: 16,
        },
        alias_limits: serde_saphyr::alias_limits! {
            max_total_replayed_events: 200_000_000,
        },
        with_snippet: false,
    };
    serde_saphyr::from_str_with_options(src, options).map_err(|e| {
        let at = e
            .location()
            .map_or((0, 0), |l| (l.line() as usize, l.column() as usize));
        let text = e.without_snippet().to_string();
        let text = match text.rfind(" at line ") {
            Some(i) => text[..i].to_string(),
            None => text,
        };
        TreeError::at(Kind::Syntax, file, src, at, format!("invalid params file: {text}")).with_help(
            "the params file maps a node's name or ID to its parameters, e.g. \
             `grasp: {ps: 0.5, mu: 0.1, nu: 0.2}`; accepted keys: ps, pf, mu, nu, tau_s, tau_f, \
             success_time, failure_time (and `fit`, the statistics `btrel fit` writes, which the analysis ignores)",
        )
    })
}

// ---------------------------------------------------------------------------
// Building the tree
// ---------------------------------------------------------------------------

/// The BehaviorTree.CPP format a file declares (`BTCPP_format`).
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
enum Format {
    V3,
    V4,
    Unspecified,
}

/// One XML file of the tree: the main file is source 0, included files
/// follow.
struct Source {
    name: String,
    text: String,
    format: Format,
}

#[derive(Clone, Copy, PartialEq, Eq)]
enum Decl {
    Action,
    Condition,
    /// A custom control node or decorator declared in the model.
    Other(&'static str),
}

/// The queue loops: BT.CPP's `LoopInt`, ... (`queue`, literal or from the
/// blackboard, `if_empty`), `ConsumeQueue` (`queue` from the blackboard,
/// empty: Success) and MoveIt Pro's `ForEach` (`vector_in` from the
/// blackboard; an empty vector is refused).
#[derive(Clone, Copy, PartialEq, Eq)]
enum Queue {
    Loop,
    Consume,
    ForEach,
}

/// How a leaf's kind is decided.
#[derive(Clone, Copy, PartialEq, Eq)]
enum LeafKind {
    Action,
    Condition,
    /// By its params entry: `ps` alone is a condition, anything else an
    /// action.
    Inferred,
    /// A node BT.CPP runs as an immediate Success (Script, SetBlackboard,
    /// UnsetBlackboard): its params entry if it has one (as `Inferred`),
    /// else a condition with ps 1.
    ZeroTime,
}

/// A leaf waiting for its parameters.
struct Leaf {
    node: usize,
    kind: LeafKind,
    id: String,
    name_attr: Option<String>,
    doc: usize,
}

/// A node that cannot be read, collected so that all of them are reported
/// at once. `semantic`: a known node type (or attribute) that btrel has no
/// stochastic meaning for; otherwise a front-end problem (an unknown node, a
/// SubTree defined nowhere).
struct Problem {
    doc: usize,
    loc: Loc,
    text: String,
    semantic: bool,
}

/// The first line of the error that lists nodes without a stochastic
/// meaning; [`is_unsupported`] tells such refusals from invalid input.
pub const UNSUPPORTED: &str = "btrel has no stochastic meaning yet for";

/// Whether `e` refuses a tree only because it uses node types (or
/// pre-condition attributes) that btrel has no stochastic meaning for yet,
/// as opposed to invalid or incomplete input.
pub fn is_unsupported(e: &TreeError) -> bool {
    e.kind == Kind::NoMeaning
}

/// Known node types of BehaviorTree.CPP v3/v4, Nav2 and MoveIt Pro that
/// btrel has no stochastic meaning for yet, with what they depend on.
fn unsupported(ty: &str) -> Option<&'static str> {
    Some(match ty {
        "WasEntryUpdated"
        | "SkipUnlessUpdated"
        | "WaitValueUpdate"
        | "EntryUpdated"
        | "BlackboardCheckInt"
        | "BlackboardCheckDouble"
        | "BlackboardCheckString"
        | "BlackboardCheckBool" => "its outcome is computed from blackboard values",
        "RunOnce" => "it runs its child at most once, keeping its status across executions",
        "ParallelAll" => {
            "it runs every child to the end and compares the failures with a threshold"
        }
        "NonblockingSequence" | "PersistentSequence" | "PauseResumeController" => {
            "Nav2 control node: it keeps state across executions or waits for an external request"
        }
        _ => return None,
    })
}

/// Pre-conditions (BT.CPP v4): they may skip a node or end it early
/// depending on the blackboard. The value that makes each a no-op.
const PRECONDITIONS: &[(&str, &str)] = &[
    ("_skipIf", "false"),
    ("_failureIf", "false"),
    ("_successIf", "false"),
    ("_while", "true"),
];

/// Node types btrel reads (for "did you mean").
const BUILTINS: &[&str] = &[
    "Sequence",
    "SequenceWithMemory",
    "SequenceStar",
    "ReactiveSequence",
    "Fallback",
    "ReactiveFallback",
    "Parallel",
    "Inverter",
    "ForceSuccess",
    "ForceFailure",
    "RetryUntilSuccessful",
    "Repeat",
    "RecoveryNode",
    "PipelineSequence",
    "RoundRobin",
    "RateController",
    "SingleTrigger",
    "GoalUpdater",
    "IfThenElse",
    "WhileDoElse",
    "Timeout",
    "Action",
    "Condition",
    "Control",
    "Decorator",
    "SubTree",
    "AlwaysSuccess",
    "AlwaysFailure",
    "Script",
    "SetBlackboard",
    "UnsetBlackboard",
    "ScriptCondition",
    "Precondition",
    "LoopInt",
    "LoopDouble",
    "LoopString",
    "LoopBool",
    "Switch2",
    "Switch3",
    "ManualSelector",
    "ConsumeQueue",
    "ForEach",
    "RepeatUnlessFailureEachTick",
    "DistanceController",
    "SpeedController",
    "GoalUpdatedController",
    "PathLongerOnApproach",
];

/// Most states of a flow built from BT.CPP nodes (a RetryUntilSuccessful
/// over a SequenceWithMemory has attempts × children states).
pub const MAX_FLOW_STATES: usize = 1_000_000;

/// Most retries of a RecoveryNode (each adds two levels to the tree).
pub const MAX_RECOVERY_RETRIES: u64 = 1000;

/// BT.CPP v3 spellings and their v4 names.
fn canonical(ty: &str) -> &str {
    match ty {
        "SequenceStar" => "SequenceWithMemory",
        "RetryUntilSuccesful" => "RetryUntilSuccessful",
        // MoveIt Pro 9.3+: Repeat with one iteration per parent tick, which
        // in continuous time (ticks without gaps) is Repeat
        "RepeatUnlessFailureEachTick" => "Repeat",
        t => t,
    }
}

fn has_timing(p: &ActionParams) -> bool {
    [&p.pf, &p.mu, &p.nu, &p.tau_s, &p.tau_f]
        .into_iter()
        .any(Option::is_some)
        || p.time_law_at().is_some()
}

struct Builder<'a> {
    sources: &'a [Source],
    elems: &'a [Elem],
    table: &'a ParamsTable,
    /// Blackboard entries of the params file read by some port.
    blackboard_used: std::cell::RefCell<HashSet<String>>,
    /// BehaviorTree elements by ID; a definition in the main file comes
    /// first.
    trees: HashMap<&'a str, Vec<usize>>,
    model: HashMap<&'a str, Decl>,
    nodes: Vec<Node>,
    used: HashSet<String>,
    name_bytes: usize,
    leaves: Vec<Leaf>,
    /// ReactiveSequence / ReactiveFallback nodes (node, source, location,
    /// type), checked once the leaves are known to be actions or conditions.
    reactive: Vec<(usize, usize, Loc, &'a str)>,
    /// WhileDoElse nodes (node, source, location), checked once the leaves
    /// are known: their condition child must take no time.
    while_do_else: Vec<(usize, usize, Loc)>,
    /// Port values the params file lacks (source, location, message),
    /// listed with the leaves' missing parameters.
    missing_values: Vec<(usize, Loc, String)>,
    /// Nodes whose re-tick after returning changes nothing under the SBT
    /// assumptions (node, source, location, type): refused as an earlier
    /// PipelineSequence child whose re-tick btrel would read as a re-run.
    once: Vec<(usize, usize, Loc, &'static str)>,
    problems: Vec<Problem>,
    seen_problems: HashSet<(usize, Loc, String)>,
    /// The source of the element being built (for error locations).
    cur: std::cell::Cell<usize>,
    /// SubTree IDs being expanded, outermost first, with the instance
    /// location.
    expanding: Vec<(&'a str, Loc)>,
    /// Node counts of expanded trees (memo for [`Builder::tree_size`]).
    sizes: HashMap<&'a str, u64>,
    sizing: HashSet<&'a str>,
    /// RoundRobin index slots by element and SubTree instance: the copies
    /// of one element made by a RecoveryNode share their index.
    slots: HashMap<String, usize>,
    /// The parent element of each element (for pre-conditions that skip a
    /// node: its parent decides what a skip means).
    elem_parent: Vec<Option<usize>>,
    /// Elements whose pre-condition attributes are modelled (by
    /// [`Builder::guarded`]), by source and location.
    pre_handled: HashSet<(usize, Loc)>,
}

impl<'a> Builder<'a> {
    fn err_in(&self, kind: Kind, doc: usize, at: Loc, msg: impl Into<String>) -> TreeError {
        let s = &self.sources[doc];
        TreeError::at(kind, &s.name, &s.text, at, msg)
    }

    fn err(&self, kind: Kind, at: Loc, msg: impl Into<String>) -> TreeError {
        self.err_in(kind, self.cur.get(), at, msg)
    }

    fn elem(&self, i: usize) -> &'a Elem {
        &self.elems[i]
    }

    fn problem(&mut self, doc: usize, loc: Loc, text: String, semantic: bool) {
        if self.seen_problems.insert((doc, loc, text.clone())) {
            self.problems.push(Problem {
                doc,
                loc,
                text,
                semantic,
            });
        }
    }

    /// Refuses attributes not in `allowed`; `ports` accepts data ports
    /// (attributes not starting with `_`). Attributes starting with `_`
    /// are metadata (`_description`, `_collapsed`, ...), `_autoremap`, or
    /// post-conditions (`_onSuccess`, ...), which BT.CPP runs after the node
    /// has returned and which only write the blackboard: all are ignored.
    /// Pre-conditions (`_skipIf`, `_while`, ...) are recorded as problems
    /// unless their value is the constant that makes them a no-op.
    fn check_attrs(&mut self, e: &Elem, allowed: &[&str], ports: bool) -> Result<(), TreeError> {
        for a in &e.attrs {
            if allowed.contains(&a.name.as_str()) {
                continue;
            }
            if a.name.starts_with('_') {
                if self.pre_handled.contains(&(e.doc, e.loc)) {
                    continue;
                }
                if let Some(&(_, noop)) = PRECONDITIONS.iter().find(|(p, _)| *p == a.name) {
                    if a.value.trim() != noop {
                        self.problem(
                            e.doc,
                            a.loc,
                            format!(
                                "`{}` attribute on <{}>: a pre-condition skips the node or ends it \
                                 early depending on blackboard values (only {}=\"{noop}\", a no-op, \
                                 is read)",
                                a.name, e.name, a.name
                            ),
                            true,
                        );
                    }
                }
                continue;
            }
            if ports {
                continue;
            }
            let hint = match nearest(&a.name, allowed) {
                Some(k) => format!(
                    "did you mean `{k}`? <{}> accepts: {}",
                    e.name,
                    allowed.join(", ")
                ),
                None if allowed.is_empty() => format!(
                    "<{}> accepts no attributes here; blackboard ports have no stochastic meaning",
                    e.name
                ),
                None => format!(
                    "<{}> accepts: {}; blackboard ports have no stochastic meaning",
                    e.name,
                    allowed.join(", ")
                ),
            };
            return Err(self
                .err_in(
                    Kind::Structure,
                    e.doc,
                    a.loc,
                    format!("unknown attribute `{}` on <{}>", a.name, e.name),
                )
                .with_help(hint));
        }
        Ok(())
    }

    /// A duration in milliseconds (BT.CPP's `msec`, `delay_msec`: a whole
    /// number ≥ 0), in seconds; `None` (a problem recorded) for a blackboard
    /// reference.
    fn milliseconds(&mut self, e: &Elem, key: &str) -> Result<Option<f64>, TreeError> {
        if let Some(a) = e.attr(key).filter(|a| self.unresolved(&a.value)) {
            let (at, ty) = (a.loc, e.name.clone());
            self.missing_value(e, at, &ty, key, "give it in milliseconds", "N");
            return Ok(None);
        }
        match self.int_attr(e, key)? {
            Some((n, _)) if n >= 0 => Ok(Some(n as f64 / 1000.0)),
            Some((n, at)) => Err(self
                .err(
                    Kind::InvalidValue,
                    at,
                    format!("{key} = {n} is not a valid duration"),
                )
                .with_help(format!("{key} is a whole number of milliseconds >= 0"))),
            None => Err(self
                .err(
                    Kind::Structure,
                    e.loc,
                    format!("<{}> needs `{key}`", e.name),
                )
                .with_help(format!("write {key}=\"N\", N in milliseconds"))),
        }
    }

    /// RateController's `hz` (default 10, as in Nav2) as a period in
    /// seconds; `None` (a problem recorded) for a blackboard reference.
    fn period(&mut self, e: &Elem, ty: &str) -> Result<Option<f64>, TreeError> {
        let Some(a) = e.attr("hz") else {
            return Ok(Some(0.1));
        };
        let v = a.value.trim();
        let given = self.table.blackboard.get(v).map(|g| g.value);
        if given.is_some() {
            self.blackboard_used.borrow_mut().insert(v.to_string());
        } else if v.starts_with('{') {
            self.missing_value(e, a.loc, ty, "hz", "give the rate in Hz", "x");
            return Ok(None);
        }
        match given.map_or_else(|| v.parse::<f64>().ok(), Some) {
            Some(hz) if hz.is_finite() && hz > 0.0 && (1.0 / hz).is_finite() => Ok(Some(1.0 / hz)),
            _ => Err(self
                .err(
                    Kind::InvalidValue,
                    a.loc,
                    format!("hz = \"{v}\" is not a valid rate"),
                )
                .with_help("hz is a number of re-runs per second, > 0 (e.g. 1.0 or 0.5)")),
        }
    }

    /// RoundRobin's `wrap_around`; by default `false` in BehaviorTree.CPP v4
    /// files (Nav2's default since 2025) and `true` in v3 files (Nav2 Humble
    /// and Iron always wrapped). `None` (a problem recorded) for a
    /// blackboard reference.
    fn wrap_around(&mut self, e: &Elem, ty: &str) -> Result<Option<bool>, TreeError> {
        let Some(a) = e.attr("wrap_around") else {
            return Ok(Some(self.sources[e.doc].format != Format::V4));
        };
        let v = a.value.trim();
        if v.starts_with('{') {
            self.problem(
                e.doc,
                a.loc,
                format!("<{ty}> with wrap_around = \"{v}\", a blackboard reference: known only at run time"),
                true,
            );
            return Ok(None);
        }
        match v {
            "true" | "True" | "TRUE" | "1" => Ok(Some(true)),
            "false" | "False" | "FALSE" | "0" => Ok(Some(false)),
            _ => Err(self
                .err(
                    Kind::InvalidValue,
                    a.loc,
                    format!("wrap_around = \"{v}\" is not a boolean"),
                )
                .with_help("write wrap_around=\"true\" or \"false\"")),
        }
    }

    /// Records a blackboard reference the params file lacks as a missing
    /// parameter: `<ty> key = "{v}"`, and what to give (`give`, with the
    /// entry's placeholder `n`).
    pub(super) fn missing_value(
        &mut self,
        e: &Elem,
        at: Loc,
        ty: &str,
        key: &str,
        give: &str,
        n: &str,
    ) {
        let v = e.attr(key).map_or("", |a| a.value.trim());
        self.missing_values.push((
            e.doc,
            at,
            format!(
                "<{ty}> {key} = \"{v}\": a blackboard value known only at run time; {give}: \
                 `\"{v}\": {{value: {n}}}`"
            ),
        ));
    }

    /// Whether `value` is a blackboard reference (`{name}`) without a value
    /// in the params file.
    fn unresolved(&self, value: &str) -> bool {
        let v = value.trim();
        v.starts_with('{') && !self.table.blackboard.contains_key(v)
    }

    /// A whole-number attribute; `None` if absent. A blackboard reference
    /// (`{name}`) reads the params file's `"{name}": {value: N}`.
    fn int_attr(&self, e: &Elem, key: &str) -> Result<Option<(i64, Loc)>, TreeError> {
        let Some(a) = e.attr(key) else {
            return Ok(None);
        };
        let v = a.value.trim();
        if let Some(given) = self.table.blackboard.get(v) {
            self.blackboard_used.borrow_mut().insert(v.to_string());
            let n = given.value;
            if n.fract() != 0.0 || !n.is_finite() || n.abs() > 1e15 {
                return Err(self
                    .err(
                        Kind::InvalidValue,
                        a.loc,
                        format!(
                            "{key} = \"{v}\" reads {n} from the params file, not a whole number"
                        ),
                    )
                    .with_help(format!("give `\"{v}\": {{value: N}}` a whole number N")));
            }
            return Ok(Some((n as i64, a.loc)));
        }
        if v.starts_with('{') {
            return Err(self
                .err(
                    Kind::MissingParameter,
                    a.loc,
                    format!("{key} = \"{v}\" is a blackboard reference"),
                )
                .with_help(format!(
                    "btrel needs a literal whole number for {key}, or the reference's value in the \
                     params file: `\"{v}\": {{value: N}}`"
                )));
        }
        let ok = !v.is_empty()
            && v.strip_prefix('-')
                .unwrap_or(v)
                .chars()
                .all(|c| c.is_ascii_digit())
            && v != "-";
        match v.parse::<i64>() {
            Ok(n) if ok => Ok(Some((n, a.loc))),
            _ => Err(self
                .err(
                    Kind::InvalidValue,
                    a.loc,
                    format!("{key} = \"{v}\" is not a whole number"),
                )
                .with_help(format!("write {key} as a whole number such as 3"))),
        }
    }

    fn name_attr(&self, e: &Elem) -> Result<Option<String>, TreeError> {
        match e.attr("name") {
            Some(a) if a.value.trim().is_empty() => Err(self
                .err_in(
                    Kind::InvalidValue,
                    e.doc,
                    a.loc,
                    "a node name must not be empty",
                )
                .with_help("omit `name` to name the node by its ID")),
            Some(a) => Ok(Some(a.value.clone())),
            None => Ok(None),
        }
    }

    fn id_attr(&self, e: &'a Elem) -> Result<&'a str, TreeError> {
        match e.attr("ID") {
            Some(a) if !a.value.trim().is_empty() => Ok(a.value.as_str()),
            Some(a) => Err(self.err_in(
                Kind::Structure,
                e.doc,
                a.loc,
                format!("<{}> has an empty ID", e.name),
            )),
            None => Err(self
                .err_in(
                    Kind::Structure,
                    e.doc,
                    e.loc,
                    format!("<{}> needs an ID attribute", e.name),
                )
                .with_help(format!("write <{} ID=\"...\"/>", e.name))),
        }
    }

    /// A unique name: `prefix + base`, with `#k` appended if taken.
    fn unique(&mut self, base: String, at: Loc) -> Result<String, TreeError> {
        let mut name = base.clone();
        let mut k = 2usize;
        while self.used.contains(&name) {
            name = format!("{base}#{k}");
            k += 1;
        }
        self.name_bytes += name.len();
        if self.name_bytes > MAX_NAME_BYTES {
            return Err(self
                .err(Kind::Budget, at, "the node names after SubTree expansion are too long")
                .with_help(format!(
                    "btrel accepts at most {MAX_NAME_BYTES} bytes of node names; shorten names or nest fewer SubTrees"
                )));
        }
        self.used.insert(name.clone());
        Ok(name)
    }

    #[allow(clippy::too_many_arguments)]
    fn push(
        &mut self,
        e: &Elem,
        base: &str,
        prefix: &str,
        parent: Option<usize>,
        depth: usize,
        path: &str,
        kind: NodeKind,
    ) -> Result<usize, TreeError> {
        if self.nodes.len() >= MAX_NODES {
            return Err(self
                .err(
                    Kind::Budget,
                    e.loc,
                    "the tree has too many nodes after SubTree expansion",
                )
                .with_help(format!("btrel accepts at most {MAX_NODES} nodes")));
        }
        if depth >= MAX_DEPTH {
            return Err(self
                .err(Kind::Budget, e.loc, "the tree is nested too deeply")
                .with_help(format!("btrel accepts trees up to {MAX_DEPTH} levels deep")));
        }
        let name = self.unique(format!("{prefix}{base}"), e.loc)?;
        self.nodes.push(Node {
            name,
            path: path.to_string(),
            depth,
            parent,
            kind,
            location: Some(e.loc),
        });
        Ok(self.nodes.len() - 1)
    }

    fn set_children(&mut self, id: usize, ids: Vec<usize>) {
        match &mut self.nodes[id].kind {
            NodeKind::Sequence { children }
            | NodeKind::Fallback { children }
            | NodeKind::Pipeline { children }
            | NodeKind::RoundRobin { children, .. }
            | NodeKind::SequenceWithMemory { children, .. }
            | NodeKind::Parallel { children, .. } => *children = ids,
            NodeKind::Decorator { child, .. } => *child = ids[0],
            // a flow is built whole once its children are known
            NodeKind::Action(_) | NodeKind::Condition { .. } | NodeKind::Flow(_) => {}
        }
    }

    /// Builds the children of `e` below node `id`.
    fn children(
        &mut self,
        e: &'a Elem,
        id: usize,
        depth: usize,
        path: &str,
        prefix: &str,
        retry: Option<&'static str>,
    ) -> Result<Vec<usize>, TreeError> {
        let mut ids = Vec::with_capacity(e.children.len());
        for (i, &c) in e.children.iter().enumerate() {
            ids.push(self.node(c, Some(id), depth + 1, format!("{path}.{i}"), prefix, retry)?);
        }
        Ok(ids)
    }

    /// `RetryUntilSuccessful(n ≥ 2)` over a `SequenceWithMemory` (element
    /// `swm`): BT.CPP's SequenceWithMemory keeps its index after a failure,
    /// so the next attempt resumes at the failed child. One flow over
    /// (failures so far f < n, child i): child i's Success goes to (f, i + 1)
    /// (Success after the last child), its Failure to (f + 1, i) (Failure at
    /// the n-th). The flow node carries the Retry's name; the
    /// SequenceWithMemory's children are its children. Exact as long as
    /// nothing ticks the Retry again after it failed (checked by the caller:
    /// no retrying ancestor), where the kept index would carry over.
    #[allow(clippy::too_many_arguments)]
    fn retry_with_memory(
        &mut self,
        e: &'a Elem,
        swm: usize,
        base: &str,
        attempts: usize,
        parent: Option<usize>,
        depth: usize,
        path: &str,
        prefix: &str,
    ) -> Result<usize, TreeError> {
        let s = self.elem(swm);
        self.check_attrs(s, &["name"], false)?;
        let k = s.children.len();
        if k == 0 {
            return Err(self
                .err(
                    Kind::Structure,
                    s.loc,
                    format!("<{}> has no children", s.name),
                )
                .with_help("a control node needs at least one child"));
        }
        if attempts.saturating_mul(k) > MAX_FLOW_STATES {
            self.problem(
                e.doc,
                e.loc,
                format!(
                    "<{}> of {attempts} attempts over a SequenceWithMemory of {k} children: \
                     {} states, more than the {MAX_FLOW_STATES} btrel builds",
                    e.name,
                    attempts.saturating_mul(k)
                ),
                true,
            );
            return self.placeholder(e, base, parent, depth, path, prefix, None);
        }
        let kind = NodeKind::Flow(Flow {
            children: Vec::new(),
            states: Vec::new(),
        });
        let id = self.push(e, base, prefix, parent, depth, path, kind)?;
        // the SequenceWithMemory's children sit directly below the flow;
        // below them, a failed child is ticked again (on the next attempt)
        let ids = self.children(s, id, depth, path, prefix, Some("RetryUntilSuccessful"))?;
        let mut states = Vec::with_capacity(attempts * k);
        for f in 0..attempts {
            for i in 0..k {
                states.push(FlowState {
                    child: i,
                    on_success: if i + 1 < k {
                        FlowNext::State(f * k + i + 1)
                    } else {
                        FlowNext::Success
                    },
                    on_failure: if f + 1 < attempts {
                        FlowNext::State((f + 1) * k + i)
                    } else {
                        FlowNext::Failure
                    },
                });
            }
        }
        self.nodes[id].kind = NodeKind::Flow(
            Flow::new(ids, states).expect("the states of a retried SequenceWithMemory are valid"),
        );
        Ok(id)
    }

    /// A stand-in for a node that is reported as a problem: its children
    /// are still built, so that every problem of the tree is found.
    #[allow(clippy::too_many_arguments)]
    fn placeholder(
        &mut self,
        e: &'a Elem,
        base: &str,
        parent: Option<usize>,
        depth: usize,
        path: &str,
        prefix: &str,
        retry: Option<&'static str>,
    ) -> Result<usize, TreeError> {
        if e.children.is_empty() {
            return self.push(
                e,
                base,
                prefix,
                parent,
                depth,
                path,
                NodeKind::Condition { ps: 1.0 },
            );
        }
        let kind = NodeKind::Sequence {
            children: Vec::new(),
        };
        let id = self.push(e, base, prefix, parent, depth, path, kind)?;
        let ids = self.children(e, id, depth, path, prefix, retry)?;
        self.set_children(id, ids);
        Ok(id)
    }

    /// Builds element `ei`; `retry` names the nearest ancestor that ticks a
    /// failed child again (RetryUntilSuccessful, RecoveryNode), if any.
    fn node(
        &mut self,
        ei: usize,
        parent: Option<usize>,
        depth: usize,
        path: String,
        prefix: &str,
        retry: Option<&'static str>,
    ) -> Result<usize, TreeError> {
        let saved = self.cur.replace(self.elem(ei).doc);
        let r = if self.has_preconditions(ei) {
            self.guarded(ei, parent, depth, path, prefix, retry)
        } else {
            self.node_here(ei, parent, depth, path, prefix, retry)
        };
        self.cur.set(saved);
        r
    }

    fn node_here(
        &mut self,
        ei: usize,
        parent: Option<usize>,
        depth: usize,
        path: String,
        prefix: &str,
        retry: Option<&'static str>,
    ) -> Result<usize, TreeError> {
        let e = self.elem(ei);
        if depth >= MAX_DEPTH {
            return Err(self
                .err(Kind::Budget, e.loc, "the tree is nested too deeply")
                .with_help(format!("btrel accepts trees up to {MAX_DEPTH} levels deep")));
        }
        if matches!(e.name.as_str(), "SubTree" | "SubTreePlus") {
            return self.subtree(e, parent, depth, path, prefix, retry);
        }
        // the explicit form <Control ID="Sequence">: the ID is the node type
        let (ty, form) = match e.name.as_str() {
            "Action" | "Condition" | "Control" | "Decorator" => {
                (self.id_attr(e)?, Some(e.name.as_str()))
            }
            t => (t, None),
        };
        let with_id: &[&str] = if form.is_some() {
            &["name", "ID"]
        } else {
            &["name"]
        };
        let attrs = |extra: &[&'static str]| -> Vec<&str> {
            with_id
                .iter()
                .copied()
                .chain(extra.iter().copied())
                .collect()
        };
        let canon = canonical(ty);
        let default_name = || ty.to_string();
        match canon {
            "PipelineSequence" | "RoundRobin" => {
                let robin = canon == "RoundRobin";
                let keys: &[&'static str] = if robin { &["wrap_around"] } else { &[] };
                self.check_attrs(e, &attrs(keys), false)?;
                if e.children.is_empty() {
                    return Err(self
                        .err(Kind::Structure, e.loc, format!("<{ty}> has no children"))
                        .with_help("a control node needs at least one child"));
                }
                let base = self.name_attr(e)?.unwrap_or_else(default_name);
                let kind = if robin {
                    let Some(wrap) = self.wrap_around(e, ty)? else {
                        return self.placeholder(e, &base, parent, depth, &path, prefix, retry);
                    };
                    let key = format!("{ei}|{:?}", self.expanding);
                    let next = self.slots.len();
                    let slot = *self.slots.entry(key).or_insert(next);
                    NodeKind::RoundRobin {
                        children: Vec::new(),
                        wrap,
                        slot,
                    }
                } else {
                    NodeKind::Pipeline {
                        children: Vec::new(),
                    }
                };
                let id = self.push(e, &base, prefix, parent, depth, &path, kind)?;
                let ids = self.children(e, id, depth, &path, prefix, retry)?;
                self.set_children(id, ids);
                Ok(id)
            }
            // GoalUpdater copies an updated goal to the blackboard and
            // returns its child's status: the child itself
            "GoalUpdater" => {
                self.check_attrs(e, &attrs(&[]), true)?;
                self.one_child(e, ty)?;
                self.node(e.children[0], parent, depth, path, prefix, retry)
            }
            // GoalUpdatedController (`goal_updated_controller.cpp`) ticks its
            // child at its first tick and again only while it runs or when
            // the goal on the blackboard changed; it returns the child's
            // status. The goal keeps its value during the run (the SBT
            // assumption for blackboard values), so it runs its child once
            // per execution: the child itself. Ticked again after returning
            // (an earlier PipelineSequence child) it returns RUNNING without
            // ticking the child, which does not block the pipeline: checked
            // after the build (`once`)
            "GoalUpdatedController" => {
                self.check_attrs(e, &attrs(&[]), true)?;
                self.one_child(e, ty)?;
                let id = self.node(e.children[0], parent, depth, path, prefix, retry)?;
                self.once.push((id, e.doc, e.loc, "GoalUpdatedController"));
                Ok(id)
            }
            "DistanceController" | "SpeedController" => {
                let distance = canon == "DistanceController";
                let keys: &[&'static str] = if distance {
                    &["distance", "global_frame", "robot_base_frame"]
                } else {
                    &[
                        "min_rate",
                        "max_rate",
                        "min_speed",
                        "max_speed",
                        "filter_duration",
                    ]
                };
                self.check_attrs(e, &attrs(keys), false)?;
                self.motion_controller(e, ty, distance, parent, depth, &path, prefix, retry)
            }
            "PathLongerOnApproach" => {
                self.check_attrs(e, &attrs(&["path", "prox_len", "length_factor"]), false)?;
                self.path_longer(e, ty, parent, depth, &path, prefix, retry)
            }
            "ManualSelector" => {
                self.check_attrs(e, &attrs(&["repeat_last_selection"]), false)?;
                self.manual_selector(e, ty, parent, depth, &path, prefix, retry)
            }
            "RateController" | "SingleTrigger" => {
                let rate = canon == "RateController";
                self.check_attrs(e, &attrs(if rate { &["hz"] } else { &[] }), false)?;
                self.one_child(e, ty)?;
                let base = self.name_attr(e)?.unwrap_or_else(default_name);
                let decorator = if rate {
                    let Some(period) = self.period(e, ty)? else {
                        return self.placeholder(e, &base, parent, depth, &path, prefix, retry);
                    };
                    Decorator::Rate {
                        period,
                        first: period,
                    }
                } else {
                    Decorator::SingleTrigger
                };
                let kind = NodeKind::Decorator {
                    decorator,
                    child: 0,
                };
                let id = self.push(e, &base, prefix, parent, depth, &path, kind)?;
                let ids = self.children(e, id, depth, &path, prefix, retry)?;
                self.set_children(id, ids);
                Ok(id)
            }
            "Sequence" | "SequenceWithMemory" | "ReactiveSequence" | "Fallback"
            | "ReactiveFallback" | "Parallel" => {
                let parallel = canon == "Parallel";
                let version = self.parallel_version(e);
                let keys: &[&'static str] = match (parallel, version) {
                    (false, _) => &[],
                    (true, Format::V3) => &["success_threshold", "failure_threshold"],
                    (true, _) => &["success_count", "failure_count"],
                };
                self.check_attrs(e, &attrs(keys), false)?;
                if e.children.is_empty() {
                    return Err(self
                        .err(Kind::Structure, e.loc, format!("<{ty}> has no children"))
                        .with_help("a control node needs at least one child"));
                }
                let base = self.name_attr(e)?.unwrap_or_else(default_name);
                let kind = match canon {
                    "Fallback" | "ReactiveFallback" => NodeKind::Fallback {
                        children: Vec::new(),
                    },
                    "Parallel" => NodeKind::Parallel {
                        success_threshold: 0,
                        failure_threshold: 0,
                        children: Vec::new(),
                    },
                    // ticked again after a Failure, it resumes at the failed
                    // child: its index is followed (`tree::nav2`), shared by
                    // the copies a RecoveryNode makes
                    "SequenceWithMemory" if retry.is_some() => {
                        let key = format!("memory|{ei}|{:?}", self.expanding);
                        let next = self.slots.len();
                        let slot = *self.slots.entry(key).or_insert(next);
                        NodeKind::SequenceWithMemory {
                            children: Vec::new(),
                            slot,
                            // v3's SequenceStarNode::halt resets the index,
                            // v4's SequenceWithMemory::halt keeps it
                            halt_resets: ty == "SequenceStar"
                                || self.sources[e.doc].format == Format::V3,
                        }
                    }
                    _ => NodeKind::Sequence {
                        children: Vec::new(),
                    },
                };
                let id = self.push(e, &base, prefix, parent, depth, &path, kind)?;
                let ids = self.children(e, id, depth, &path, prefix, retry)?;
                if parallel {
                    let (m, f) = self.thresholds(e, ids.len(), version)?;
                    if let NodeKind::Parallel {
                        success_threshold,
                        failure_threshold,
                        ..
                    } = &mut self.nodes[id].kind
                    {
                        (*success_threshold, *failure_threshold) = (m, f);
                    }
                }
                self.set_children(id, ids);
                if matches!(canon, "ReactiveSequence" | "ReactiveFallback") {
                    self.reactive.push((id, e.doc, e.loc, ty));
                }
                Ok(id)
            }
            "IfThenElse" | "WhileDoElse" => {
                self.check_attrs(e, &attrs(&[]), false)?;
                if !(2..=3).contains(&e.children.len()) {
                    return Err(self
                        .err(
                            Kind::Structure,
                            e.loc,
                            format!("<{ty}> has {} children", e.children.len()),
                        )
                        .with_help(format!(
                            "<{ty}> takes 2 or 3 children: the condition, the branch run on its \
                             Success, and (optionally) the one run on its Failure"
                        )));
                }
                let base = self.name_attr(e)?.unwrap_or_else(default_name);
                let kind = NodeKind::Flow(Flow {
                    children: Vec::new(),
                    states: Vec::new(),
                });
                let id = self.push(e, &base, prefix, parent, depth, &path, kind)?;
                let ids = self.children(e, id, depth, &path, prefix, retry)?;
                self.nodes[id].kind =
                    NodeKind::Flow(Flow::if_then_else(ids[0], ids[1], ids.get(2).copied()));
                if canon == "WhileDoElse" {
                    self.while_do_else.push((id, e.doc, e.loc));
                }
                Ok(id)
            }
            "Inverter"
            | "ForceSuccess"
            | "ForceFailure"
            | "RetryUntilSuccessful"
            | "Repeat"
            | "KeepRunningUntilFailure" => {
                let (decorator, child_retry) = match canon {
                    "KeepRunningUntilFailure" => {
                        self.check_attrs(e, &attrs(&[]), false)?;
                        (Decorator::UntilFailure, retry)
                    }
                    "RetryUntilSuccessful" if self.forever(e, "num_attempts") => {
                        self.check_attrs(e, &attrs(&["num_attempts"]), false)?;
                        (Decorator::UntilSuccess, Some("RetryUntilSuccessful"))
                    }
                    "Repeat" if self.forever(e, "num_cycles") => {
                        self.check_attrs(e, &attrs(&["num_cycles"]), false)?;
                        (Decorator::UntilFailure, retry)
                    }
                    "Inverter" => {
                        self.check_attrs(e, &attrs(&[]), false)?;
                        (Decorator::Inverter, retry)
                    }
                    "ForceSuccess" => {
                        self.check_attrs(e, &attrs(&[]), false)?;
                        (Decorator::ForceSuccess, retry)
                    }
                    "ForceFailure" => {
                        self.check_attrs(e, &attrs(&[]), false)?;
                        (Decorator::ForceFailure, retry)
                    }
                    "RetryUntilSuccessful" => {
                        self.check_attrs(e, &attrs(&["num_attempts"]), false)?;
                        let Some(attempts) = self.count(e, "num_attempts")? else {
                            let base = self.name_attr(e)?.unwrap_or_else(default_name);
                            return self.placeholder(e, &base, parent, depth, &path, prefix, retry);
                        };
                        if attempts > 1 && retry.is_none() {
                            if let [only] = e.children[..] {
                                if canonical(&self.elem(only).name) == "SequenceWithMemory" {
                                    let base = self.name_attr(e)?.unwrap_or_else(default_name);
                                    return self.retry_with_memory(
                                        e, only, &base, attempts, parent, depth, &path, prefix,
                                    );
                                }
                            }
                        }
                        // one attempt never ticks a failed child again
                        let r = if attempts > 1 {
                            Some("RetryUntilSuccessful")
                        } else {
                            retry
                        };
                        (Decorator::Retry { attempts }, r)
                    }
                    _ => {
                        self.check_attrs(e, &attrs(&["num_cycles"]), false)?;
                        let Some(times) = self.count(e, "num_cycles")? else {
                            let base = self.name_attr(e)?.unwrap_or_else(default_name);
                            return self.placeholder(e, &base, parent, depth, &path, prefix, retry);
                        };
                        (Decorator::Repeat { times }, retry)
                    }
                };
                self.one_child(e, ty)?;
                let base = self.name_attr(e)?.unwrap_or_else(default_name);
                let kind = NodeKind::Decorator {
                    decorator,
                    child: 0,
                };
                let id = self.push(e, &base, prefix, parent, depth, &path, kind)?;
                let ids = self.children(e, id, depth, &path, prefix, child_retry)?;
                self.set_children(id, ids);
                Ok(id)
            }
            "RecoveryNode" => {
                self.check_attrs(e, &attrs(&["number_of_retries"]), false)?;
                self.recovery(e, ty, parent, depth, path, prefix, retry)
            }
            // BT.CPP Sleep: Success after `msec`; Delay: waits `delay_msec`,
            // then runs its child and returns what it returns
            "Sleep" | "Delay" => {
                let key = if canon == "Sleep" {
                    "msec"
                } else {
                    "delay_msec"
                };
                self.check_attrs(e, &attrs(&[key]), false)?;
                let Some(seconds) = self.milliseconds(e, key)? else {
                    let base = self.name_attr(e)?.unwrap_or_else(default_name);
                    return self.placeholder(e, &base, parent, depth, &path, prefix, retry);
                };
                let wait = |ps| {
                    NodeKind::Action(crate::tree::Action {
                        ps,
                        pf: 0.0,
                        success: Some(crate::tree::Duration::Fixed { time: seconds }),
                        failure: None,
                    })
                };
                let base = self.name_attr(e)?.unwrap_or_else(default_name);
                if canon == "Sleep" {
                    self.no_children(e)?;
                    return self.push(e, &base, prefix, parent, depth, &path, wait(1.0));
                }
                self.one_child(e, ty)?;
                let sq = self.push(
                    e,
                    &base,
                    prefix,
                    parent,
                    depth,
                    &path,
                    NodeKind::Sequence {
                        children: Vec::new(),
                    },
                )?;
                let w = self.push(
                    e,
                    &format!("{base}/wait"),
                    prefix,
                    Some(sq),
                    depth + 1,
                    &format!("{path}.0"),
                    wait(1.0),
                )?;
                let c = self.node(
                    e.children[0],
                    Some(sq),
                    depth + 1,
                    format!("{path}.1"),
                    prefix,
                    retry,
                )?;
                self.set_children(sq, vec![w, c]);
                Ok(sq)
            }
            // BT.CPP Timeout: a timer started with the child halts it at
            // `msec` if it is still running, and the next tick returns
            // Failure (no timer for msec 0): the child raced by a deadline,
            // Parallel{M = 1, F = 1}(deadline, child), the deadline first so
            // that it wins a tie (the timer fires before the tick that would
            // see the child's return at the same instant)
            "Timeout" => {
                self.check_attrs(e, &attrs(&["msec"]), false)?;
                let Some(seconds) = self.milliseconds(e, "msec")? else {
                    let base = self.name_attr(e)?.unwrap_or_else(default_name);
                    return self.placeholder(e, &base, parent, depth, &path, prefix, retry);
                };
                self.one_child(e, ty)?;
                let base = self.name_attr(e)?.unwrap_or_else(default_name);
                let race = self.push(
                    e,
                    &base,
                    prefix,
                    parent,
                    depth,
                    &path,
                    NodeKind::Parallel {
                        success_threshold: 1,
                        failure_threshold: 1,
                        children: Vec::new(),
                    },
                )?;
                let mut kids = Vec::new();
                if seconds > 0.0 {
                    let deadline = NodeKind::Action(crate::tree::Action {
                        ps: 0.0,
                        pf: 1.0,
                        success: None,
                        failure: Some(crate::tree::Duration::Fixed { time: seconds }),
                    });
                    kids.push(self.push(
                        e,
                        &format!("{base}/deadline"),
                        prefix,
                        Some(race),
                        depth + 1,
                        &format!("{path}.0"),
                        deadline,
                    )?);
                }
                let c = self.node(
                    e.children[0],
                    Some(race),
                    depth + 1,
                    format!("{path}.{}", kids.len()),
                    prefix,
                    retry,
                )?;
                kids.push(c);
                self.set_children(race, kids);
                Ok(race)
            }
            "AlwaysSuccess" | "AlwaysFailure" => {
                self.check_attrs(e, &attrs(&[]), false)?;
                self.no_children(e)?;
                let base = self.name_attr(e)?.unwrap_or_else(default_name);
                let ps = if canon == "AlwaysSuccess" { 1.0 } else { 0.0 };
                self.push(
                    e,
                    &base,
                    prefix,
                    parent,
                    depth,
                    &path,
                    NodeKind::Condition { ps },
                )
            }
            "Script" | "SetBlackboard" | "UnsetBlackboard" => {
                self.check_attrs(e, &attrs(&[]), true)?;
                self.leaf(e, ty, LeafKind::ZeroTime, parent, depth, &path, prefix)
            }
            // a condition whose outcome is a script over the blackboard: its
            // probability of success comes from the params file (any form,
            // `<Action ID="ScriptCondition">` included)
            "ScriptCondition" => {
                self.check_attrs(e, &attrs(&["code"]), false)?;
                self.leaf(e, ty, LeafKind::Condition, parent, depth, &path, prefix)
            }
            "Precondition" => {
                self.check_attrs(e, &attrs(&["if", "else"]), false)?;
                self.precondition(e, ty, parent, depth, &path, prefix, retry)
            }
            "Switch2" | "Switch3" | "Switch4" | "Switch5" | "Switch6" => {
                let cases = usize::from(canon.as_bytes()[6] - b'0');
                let keys: Vec<String> = (1..=cases).map(|k| format!("case_{k}")).collect();
                let mut allowed = attrs(&["variable"]);
                allowed.extend(keys.iter().map(String::as_str));
                self.check_attrs(e, &allowed, false)?;
                self.switch(e, ty, cases, parent, depth, &path, prefix, retry)
            }
            // BT.CPP's LoopNode<T>; LoopPose is LoopNode<Pose2D> as its
            // t18_waypoints example registers it
            "LoopInt" | "LoopDouble" | "LoopString" | "LoopBool" | "LoopPose" => {
                self.check_attrs(e, &attrs(&["queue", "if_empty", "value"]), false)?;
                self.loop_queue(e, ty, Queue::Loop, parent, depth, &path, prefix, retry)
            }
            // BT.CPP's ConsumeQueue<T> (v3, deprecated in v4 for LoopNode):
            // pops one item per child run from a queue object on the
            // blackboard, a child Failure is its Failure, an empty queue is
            // Success
            "ConsumeQueue" => {
                self.check_attrs(e, &attrs(&["queue", "popped_item"]), false)?;
                self.loop_queue(e, ty, Queue::Consume, parent, depth, &path, prefix, retry)
            }
            // MoveIt Pro's ForEach: ticks its child once per element of
            // `vector_in`, a child Failure ends it with Failure
            "ForEach" => {
                self.check_attrs(e, &attrs(&["vector_in", "out", "index"]), false)?;
                self.loop_queue(e, ty, Queue::ForEach, parent, depth, &path, prefix, retry)
            }
            _ => {
                self.check_attrs(e, &attrs(&[]), true)?;
                let base = self.name_attr(e)?.unwrap_or_else(default_name);
                if let Some(why) = unsupported(canon) {
                    self.problem(e.doc, e.loc, format!("<{ty}>: {why}"), true);
                    return self.placeholder(e, &base, parent, depth, &path, prefix, retry);
                }
                let decl = match form {
                    Some("Action") => Some(Decl::Action),
                    Some("Condition") => Some(Decl::Condition),
                    Some("Control") => Some(Decl::Other("control node")),
                    Some(_) => Some(Decl::Other("decorator")),
                    None => self.model.get(ty).copied(),
                };
                match decl {
                    Some(Decl::Action) => {
                        self.leaf(e, ty, LeafKind::Action, parent, depth, &path, prefix)
                    }
                    Some(Decl::Condition) => {
                        self.leaf(e, ty, LeafKind::Condition, parent, depth, &path, prefix)
                    }
                    Some(Decl::Other(what)) => {
                        self.problem(
                            e.doc,
                            e.loc,
                            format!(
                                "<{ty}>: a custom {what}; btrel models only its own control nodes \
                                 and decorators"
                            ),
                            true,
                        );
                        self.placeholder(e, &base, parent, depth, &path, prefix, retry)
                    }
                    None if e.children.is_empty() => {
                        self.leaf(e, ty, LeafKind::Inferred, parent, depth, &path, prefix)
                    }
                    None => {
                        let mut known: Vec<&str> = BUILTINS.to_vec();
                        known.extend(self.model.keys().copied());
                        let hint = match nearest(ty, &known) {
                            Some(k) => format!(" (did you mean <{k}>?)"),
                            None => String::new(),
                        };
                        self.problem(
                            e.doc,
                            e.loc,
                            format!(
                                "unknown node <{ty}> with children{hint}: a node with children must \
                                 be a control node or decorator that btrel knows, or be declared \
                                 in a <TreeNodesModel>"
                            ),
                            false,
                        );
                        self.placeholder(e, &base, parent, depth, &path, prefix, retry)
                    }
                }
            }
        }
    }

    /// The format that decides a Parallel's attributes: the file's, or for
    /// a file without `BTCPP_format`, v3 if the node uses v3 names.
    fn parallel_version(&self, e: &Elem) -> Format {
        match self.sources[e.doc].format {
            Format::Unspecified
                if e.attr("success_threshold").is_some()
                    || e.attr("failure_threshold").is_some() =>
            {
                Format::V3
            }
            Format::Unspecified => Format::V4,
            f => f,
        }
    }

    /// Nav2's RecoveryNode(main, recovery, n): tick main; Success is
    /// Success; on Failure, if fewer than n retries were used, tick
    /// recovery: Failure is Failure, Success ticks main again. Built as
    /// Fallback(main, Sequence(recovery, RecoveryNode(main, recovery,
    /// n − 1))) with RecoveryNode(main, recovery, 0) = main, each copy
    /// fresh.
    #[allow(clippy::too_many_arguments)]
    fn recovery(
        &mut self,
        e: &'a Elem,
        ty: &str,
        parent: Option<usize>,
        depth: usize,
        path: String,
        prefix: &str,
        retry: Option<&'static str>,
    ) -> Result<usize, TreeError> {
        if e.children.len() != 2 {
            return Err(self
                .err(
                    Kind::Structure,
                    e.loc,
                    format!(
                        "<{ty}> needs exactly two children (the main branch and the recovery), found {}",
                        e.children.len()
                    ),
                )
                .with_help("Nav2's RecoveryNode throws at run time for any other number of children"));
        }
        if let Some(a) = e
            .attr("number_of_retries")
            .filter(|a| self.unresolved(&a.value))
        {
            let at = a.loc;
            self.missing_value(e, at, ty, "number_of_retries", "give the count", "N");
            let base = self.name_attr(e)?.unwrap_or_else(|| ty.to_string());
            return self.placeholder(e, &base, parent, depth, &path, prefix, retry);
        }
        let n = match self.int_attr(e, "number_of_retries")? {
            None => 1,
            Some((n, at)) => {
                if !(0..=MAX_RECOVERY_RETRIES as i64).contains(&n) {
                    return Err(self
                        .err(Kind::InvalidValue, at, format!("number_of_retries = {n} is not a valid count"))
                        .with_help(format!(
                            "number_of_retries must be a whole number from 0 to {MAX_RECOVERY_RETRIES}"
                        )));
                }
                n as usize
            }
        };
        let base = self.name_attr(e)?.unwrap_or_else(|| ty.to_string());
        let (main, rec) = (e.children[0], e.children[1]);
        // the main branch is ticked again after its failure
        let main_retry = if n > 0 { Some("RecoveryNode") } else { retry };
        // (fallback, main copy, sequence, recovery copy) per retry
        let mut levels: Vec<(usize, usize, usize, usize)> = Vec::with_capacity(n);
        let (mut up, mut d, mut p) = (parent, depth, path);
        for k in 1..=n {
            let fb_name = if k == 1 {
                base.clone()
            } else {
                format!("{base}/attempt {k}")
            };
            let main_prefix = if k == 1 {
                prefix.to_string()
            } else {
                format!("{prefix}{base}/attempt {k}/")
            };
            let fb = self.push(
                e,
                &fb_name,
                prefix,
                up,
                d,
                &p,
                NodeKind::Fallback {
                    children: Vec::new(),
                },
            )?;
            let m = self.node(
                main,
                Some(fb),
                d + 1,
                format!("{p}.0"),
                &main_prefix,
                main_retry,
            )?;
            let sq = self.push(
                e,
                &format!("{base}/recovery {k}"),
                prefix,
                Some(fb),
                d + 1,
                &format!("{p}.1"),
                NodeKind::Sequence {
                    children: Vec::new(),
                },
            )?;
            let r = self.node(
                rec,
                Some(sq),
                d + 2,
                format!("{p}.1.0"),
                &format!("{prefix}{base}/recovery {k}/"),
                retry,
            )?;
            levels.push((fb, m, sq, r));
            (up, d, p) = (Some(sq), d + 2, format!("{p}.1.1"));
        }
        let last_prefix = if n == 0 {
            prefix.to_string()
        } else {
            format!("{prefix}{base}/attempt {}/", n + 1)
        };
        let mut next = self.node(main, up, d, p, &last_prefix, main_retry)?;
        for (fb, m, sq, r) in levels.into_iter().rev() {
            self.set_children(sq, vec![r, next]);
            self.set_children(fb, vec![m, sq]);
            next = fb;
        }
        Ok(next)
    }

    /// Number of nodes of tree `id` after SubTree expansion (saturating),
    /// computed without expanding. Cycles and over-deep SubTree chains
    /// count as 0 here: the builder reports them.
    fn tree_size(&mut self, id: &'a str, guard: usize) -> u64 {
        if let Some(&s) = self.sizes.get(id) {
            return s;
        }
        let Some(&tree) = self.trees.get(id).and_then(|v| v.first()) else {
            return 1;
        };
        if guard > MAX_DEPTH || !self.sizing.insert(id) {
            return 0;
        }
        let total = match self.elems[tree].children.first() {
            Some(&root) => self.elem_size(root, guard),
            None => 0,
        };
        self.sizing.remove(id);
        self.sizes.insert(id, total);
        total
    }

    fn elem_size(&mut self, ei: usize, guard: usize) -> u64 {
        let e = self.elem(ei);
        if matches!(e.name.as_str(), "SubTree" | "SubTreePlus") {
            return match e.attr("ID") {
                Some(a) => self.tree_size(&a.value, guard + 1),
                None => 1,
            };
        }
        let recovery = e.name == "RecoveryNode"
            || (e.name == "Control" && e.attr("ID").is_some_and(|a| a.value == "RecoveryNode"));
        if recovery && e.children.len() == 2 {
            let n = e
                .attr("number_of_retries")
                .and_then(|a| a.value.trim().parse::<u64>().ok())
                .unwrap_or(1)
                .min(MAX_RECOVERY_RETRIES);
            let m = self.elem_size(e.children[0], guard);
            let r = self.elem_size(e.children[1], guard);
            return (2 * n)
                .saturating_add((n + 1).saturating_mul(m))
                .saturating_add(n.saturating_mul(r));
        }
        let mut total = 1u64;
        for &c in &e.children {
            total = total.saturating_add(self.elem_size(c, guard));
        }
        total
    }

    /// A decorator's child count must be one.
    fn one_child(&self, e: &Elem, ty: &str) -> Result<(), TreeError> {
        if e.children.len() != 1 {
            return Err(self
                .err(
                    Kind::Structure,
                    e.loc,
                    format!("<{ty}> needs exactly one child, found {}", e.children.len()),
                )
                .with_help("a decorator wraps exactly one node; wrap several in a <Sequence>"));
        }
        Ok(())
    }

    fn no_children(&self, e: &Elem) -> Result<(), TreeError> {
        if let Some(&c) = e.children.first() {
            return Err(self
                .err(
                    Kind::Structure,
                    self.elem(c).loc,
                    format!("<{}> is a leaf and takes no children", e.name),
                )
                .with_help("remove the child elements"));
        }
        Ok(())
    }

    #[allow(clippy::too_many_arguments)]
    fn leaf(
        &mut self,
        e: &Elem,
        id: &str,
        kind: LeafKind,
        parent: Option<usize>,
        depth: usize,
        path: &str,
        prefix: &str,
    ) -> Result<usize, TreeError> {
        self.no_children(e)?;
        let name_attr = self.name_attr(e)?;
        let base = name_attr.clone().unwrap_or_else(|| id.to_string());
        // placeholder parameters, filled in from the params file
        let node = self.push(
            e,
            &base,
            prefix,
            parent,
            depth,
            path,
            NodeKind::Condition { ps: 0.0 },
        )?;
        self.leaves.push(Leaf {
            node,
            kind,
            id: id.to_string(),
            name_attr,
            doc: e.doc,
        });
        Ok(node)
    }

    /// The BehaviorTree with this ID: the main file's definition, else the
    /// only included one.
    fn lookup_tree(&self, id: &str, at: Loc) -> Result<Option<usize>, TreeError> {
        let Some(defs) = self.trees.get(id) else {
            return Ok(None);
        };
        if defs.len() > 1 && self.elem(defs[0]).doc != 0 {
            let places: Vec<String> = defs
                .iter()
                .map(|&d| {
                    let el = self.elem(d);
                    format!("{}:{}:{}", self.sources[el.doc].name, el.loc.0, el.loc.1)
                })
                .collect();
            return Err(self
                .err(
                    Kind::Structure,
                    at,
                    format!("BehaviorTree `{id}` is defined in several included files"),
                )
                .with_help(format!(
                    "defined at {}; include only one of them",
                    places.join(", ")
                )));
        }
        Ok(defs.first().copied())
    }

    fn subtree(
        &mut self,
        e: &'a Elem,
        parent: Option<usize>,
        depth: usize,
        path: String,
        prefix: &str,
        retry: Option<&'static str>,
    ) -> Result<usize, TreeError> {
        self.check_attrs(e, &["name", "ID"], true)?;
        self.no_children(e)?;
        let id = self.id_attr(e)?;
        let name_attr = self.name_attr(e)?;
        let instance = name_attr.clone().unwrap_or_else(|| id.to_string());
        let Some(tree) = self.lookup_tree(id, e.loc)? else {
            // a SubTree defined nowhere but given a params entry is one leaf
            let full = format!("{prefix}{instance}");
            let has_entry = [Some(full.as_str()), name_attr.as_deref(), Some(id)]
                .into_iter()
                .flatten()
                .any(|k| self.table.leaves.contains_key(k));
            if has_entry {
                return self.leaf(e, id, LeafKind::Inferred, parent, depth, &path, prefix);
            }
            let ids: Vec<&str> = self.trees.keys().copied().collect();
            let mut sorted = ids.clone();
            sorted.sort_unstable();
            let hint = match nearest(id, &ids) {
                Some(k) => format!("did you mean `{k}`? "),
                None => String::new(),
            };
            let trees = if sorted.is_empty() {
                "none".to_string()
            } else {
                sorted.join(", ")
            };
            self.problem(
                e.doc,
                e.loc,
                format!(
                    "no <BehaviorTree ID=\"{id}\"> for this SubTree ({hint}trees read: {trees}); \
                     include the file that defines it, or give `{id}` a params entry to treat \
                     the SubTree as one leaf"
                ),
                false,
            );
            return self.push(
                e,
                &instance,
                prefix,
                parent,
                depth,
                &path,
                NodeKind::Condition { ps: 1.0 },
            );
        };
        if let Some(pos) = self.expanding.iter().position(|(t, _)| *t == id) {
            let cycle: Vec<&str> = self.expanding[pos..]
                .iter()
                .map(|(t, _)| *t)
                .chain(std::iter::once(id))
                .collect();
            return Err(self
                .err(
                    Kind::Structure,
                    e.loc,
                    format!("recursive SubTree: {}", cycle.join(" -> ")),
                )
                .with_help("a tree cannot contain itself; break the cycle"));
        }
        if self.expanding.len() > MAX_DEPTH {
            return Err(self
                .err(Kind::Budget, e.loc, "SubTrees are nested too deeply")
                .with_help(format!("btrel expands at most {MAX_DEPTH} nested SubTrees")));
        }
        let inner = format!("{prefix}{instance}/");
        self.expanding.push((id, e.loc));
        let root = self.elem(tree).children[0];
        let r = self.node(root, parent, depth, path, &inner, retry);
        self.expanding.pop();
        r
    }

    /// `num_attempts` / `num_cycles`: required, 1..=1e6. A count from the
    /// blackboard or −1 (forever) is recorded as a problem (`None`).
    /// Whether the count attribute `key` is -1 (BT.CPP: repeat without a
    /// bound, read as `until_success` / `until_failure`).
    fn forever(&self, e: &Elem, key: &str) -> bool {
        e.attr(key).is_some_and(|a| a.value.trim() == "-1")
    }

    fn count(&mut self, e: &Elem, key: &str) -> Result<Option<usize>, TreeError> {
        if let Some(a) = e.attr(key).filter(|a| self.unresolved(&a.value)) {
            let (at, ty) = (a.loc, e.name.clone());
            self.missing_value(e, at, &ty, key, "give the count", "N");
            return Ok(None);
        }
        if let Some((-1, at)) = self.int_attr(e, key)? {
            self.problem(
                e.doc,
                at,
                format!(
                    "<{}> with {key} = -1 (forever): an endless loop has no finite MTTS/MTTF",
                    e.name
                ),
                true,
            );
            return Ok(None);
        }
        let Some((n, at)) = self.int_attr(e, key)? else {
            return Err(self
                .err(
                    Kind::Structure,
                    e.loc,
                    format!("<{}> needs `{key}`", e.name),
                )
                .with_help(format!(
                    "write {key}=\"N\" with N a whole number from 1 to 1000000"
                )));
        };
        if !(1..=1_000_000).contains(&n) {
            return Err(self
                .err(
                    Kind::InvalidValue,
                    at,
                    format!("{key} = {n} is not a valid count"),
                )
                .with_help(format!("{key} must be a whole number from 1 to 1000000")));
        }
        Ok(Some(n as usize))
    }

    /// Parallel thresholds. v4: `success_count` (default −1),
    /// `failure_count` (default 1); v3: `success_threshold` (required),
    /// `failure_threshold` (default 1). A negative count k means N + k + 1.
    fn thresholds(&self, e: &Elem, n: usize, version: Format) -> Result<(usize, usize), TreeError> {
        let resolve = |key: &str,
                       default: Option<i64>,
                       meaning: &str|
         -> Result<usize, TreeError> {
            let (k, at) = match (self.int_attr(e, key)?, default) {
                (Some(v), _) => v,
                (None, Some(d)) => (d, e.loc),
                (None, None) => {
                    return Err(self
                        .err(Kind::Structure, e.loc, format!("<{}> needs `{key}` (BT.CPP v3)", e.name))
                        .with_help(format!(
                            "BT.CPP v3 has no default for {key}; write {key}=\"M\" (M from 1 to {n}, or -1 for all children)"
                        )))
                }
            };
            let v = if k < 0 { n as i64 + k + 1 } else { k };
            if v < 1 || v > n as i64 {
                return Err(self
                    .err(Kind::InvalidValue, at, format!("{key} = {k} is not valid for {n} children"))
                    .with_help(format!(
                        "{key} must be from 1 to {n}, or negative (-1 = all children, -2 = all but one, ...): {meaning}"
                    )));
            }
            Ok(v as usize)
        };
        if version == Format::V3 {
            let m = resolve("success_threshold", None, "Success at >= M successes")?;
            let f = resolve("failure_threshold", Some(1), "Failure at >= F failures")?;
            return Ok((m, f));
        }
        let m = resolve("success_count", Some(-1), "Success at >= M successes")?;
        let f = resolve("failure_count", Some(1), "Failure at >= F failures")?;
        Ok((m, f))
    }
}

// ---------------------------------------------------------------------------
// Reading the files
// ---------------------------------------------------------------------------

/// Most XML files (the main file and everything it includes).
pub const MAX_FILES: usize = 10_000;

/// The XML files of a tree, read and parsed.
struct Files {
    sources: Vec<Source>,
    elems: Vec<Elem>,
    /// Root element of each source.
    roots: Vec<usize>,
    /// Canonical paths of the files read from disk.
    seen: HashSet<std::path::PathBuf>,
    bytes: usize,
}

impl Files {
    fn new() -> Files {
        Files {
            sources: Vec::new(),
            elems: Vec::new(),
            roots: Vec::new(),
            seen: HashSet::new(),
            bytes: 0,
        }
    }

    /// Parses `text` as a new source; `dir` resolves its `<include>`s
    /// (`None`: the text was not read from a file, and includes are
    /// refused).
    fn add(&mut self, name: String, text: String, dir: Option<&Path>) -> Result<(), TreeError> {
        if self.sources.len() >= MAX_FILES {
            return Err(TreeError::file(
                Kind::Budget,
                &name,
                format!("more than {MAX_FILES} XML files"),
            ));
        }
        self.bytes = self.bytes.saturating_add(text.len());
        if self.bytes > MAX_BYTES {
            return Err(TreeError::file(
                Kind::Budget,
                &name,
                format!("the XML files are more than {MAX_BYTES} bytes together"),
            ));
        }
        let doc = self.sources.len();
        let elems = Reader {
            src: &text,
            file: &name,
            doc,
            pos: 0,
            line: 1,
            col: 1,
        }
        .parse()?;
        let base = self.elems.len();
        self.roots.push(base);
        self.elems.extend(elems.into_iter().map(|mut e| {
            for c in &mut e.children {
                *c += base;
            }
            e
        }));
        let root = &self.elems[base];
        let err = |kind: Kind, at: Loc, msg: String| TreeError::at(kind, &name, &text, at, msg);
        let format = match root.attr("BTCPP_format") {
            None => Format::Unspecified,
            Some(a) => match a.value.trim() {
                "4" => Format::V4,
                "3" => Format::V3,
                v => {
                    return Err(err(
                        Kind::InvalidValue,
                        a.loc,
                        format!("BTCPP_format = \"{v}\" is not supported"),
                    )
                    .with_help("btrel reads the BehaviorTree.CPP formats 3 and 4"))
                }
            },
        };
        let mut includes: Vec<(Loc, String)> = Vec::new();
        for &c in &root.children {
            let e = &self.elems[c];
            if e.name != "include" {
                continue;
            }
            if let Some(a) = e.attr("ros_pkg") {
                return Err(err(
                    Kind::Structure,
                    a.loc,
                    "<include ros_pkg=...> is not supported: btrel cannot locate ROS packages"
                        .into(),
                )
                .with_help("include the file by its path instead"));
            }
            let Some(p) = e.attr("path") else {
                return Err(err(
                    Kind::Structure,
                    e.loc,
                    "<include> needs a `path` attribute".into(),
                )
                .with_help("write <include path=\"other_file.xml\"/>"));
            };
            includes.push((e.loc, p.value.clone()));
        }
        if !includes.is_empty() && dir.is_none() {
            return Err(err(
                Kind::Structure,
                includes[0].0,
                "<include> cannot be resolved: the tree was not read from a file".into(),
            )
            .with_help("read the tree from a file, or pass the included file's text with it"));
        }
        self.sources.push(Source { name, text, format });
        if let Some(dir) = dir {
            for (at, p) in includes {
                let path = dir.join(&p);
                let src = &self.sources[doc];
                if !path.is_file() {
                    return Err(TreeError::at(
                        Kind::Io,
                        &src.name,
                        &src.text,
                        at,
                        format!("included file `{}` does not exist", path.display()),
                    )
                    .with_help("the path is relative to the folder of the including file"));
                }
                self.add_file(&path)?;
            }
        }
        Ok(())
    }

    /// Reads a file (once: a file already read is skipped).
    fn add_file(&mut self, path: &Path) -> Result<(), TreeError> {
        let name = path.display().to_string();
        if let Ok(c) = std::fs::canonicalize(path) {
            if !self.seen.insert(c) {
                return Ok(());
            }
        }
        let text = read_text(path, &name)?;
        let dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
        self.add(name, text, Some(&dir))
    }

    /// `--include FILE|DIR`: a file, or every `.xml` file of a folder (not
    /// its subfolders), in name order.
    fn add_include(&mut self, path: &Path) -> Result<(), TreeError> {
        let name = path.display().to_string();
        if path.is_dir() {
            let rd = std::fs::read_dir(path).map_err(|e| {
                TreeError::file(Kind::Io, &name, format!("cannot read the folder: {e}"))
                    .with_help(super::parse::read_help(&e))
            })?;
            let mut files: Vec<std::path::PathBuf> = rd
                .filter_map(|d| d.ok().map(|d| d.path()))
                .filter(|p| {
                    p.is_file() && p.extension().is_some_and(|x| x.eq_ignore_ascii_case("xml"))
                })
                .collect();
            files.sort();
            for f in files {
                self.add_file(&f)?;
            }
            return Ok(());
        }
        self.add_file(path)
    }
}

/// Parses a BehaviorTree.CPP XML tree (format 3 or 4) with its params file.
/// `file` and `params_file` name the sources in error messages. The text
/// was not read from a file, so `<include>` is refused.
pub fn parse_xml_str(
    xml: &str,
    file: &str,
    params: &str,
    params_file: &str,
) -> Result<Tree, TreeError> {
    parse_xml_str_with(xml, file, &[], params, params_file)
}

/// Like [`parse_xml_str`], with more XML texts (`(name, text)`) whose
/// BehaviorTrees and node models the tree may use, as `--include` files.
pub fn parse_xml_str_with(
    xml: &str,
    file: &str,
    includes: &[(&str, &str)],
    params: &str,
    params_file: &str,
) -> Result<Tree, TreeError> {
    parse_xml_str_with_keyed(xml, file, includes, params, params_file).map(|k| k.tree)
}

/// [`parse_xml_str_with`], also giving each node's params-file key.
fn parse_xml_str_with_keyed(
    xml: &str,
    file: &str,
    includes: &[(&str, &str)],
    params: &str,
    params_file: &str,
) -> Result<Keyed, TreeError> {
    for (src, name) in [(xml, file), (params, params_file)]
        .into_iter()
        .chain(includes.iter().map(|&(n, t)| (t, n)))
    {
        if src.len() > MAX_BYTES {
            return Err(too_large(name, src.len()));
        }
    }
    on_parser_thread(file, || {
        let mut files = Files::new();
        files.add(file.to_string(), xml.to_string(), None)?;
        for &(name, text) in includes {
            files.add(name.to_string(), text.to_string(), None)?;
        }
        build_keyed(files, params, params_file)
    })
}

/// Reads a BehaviorTree.CPP XML file and its params file.
pub fn parse_xml_file(xml: &Path, params: &Path) -> Result<Tree, TreeError> {
    parse_xml_files(xml, params, &[])
}

/// Reads a BehaviorTree.CPP XML file, its params file, and the files (or
/// folders of `.xml` files) in `includes`, whose BehaviorTrees and node
/// models the tree may use. `<include path>` elements are followed
/// (relative to the including file); every file is read once.
pub fn parse_xml_files(
    xml: &Path,
    params: &Path,
    includes: &[std::path::PathBuf],
) -> Result<Tree, TreeError> {
    parse_xml_files_keyed(xml, params, includes).map(|k| k.tree)
}

/// Like [`parse_xml_str`], also giving each node's params-file key.
pub fn parse_xml_str_keyed(
    xml: &str,
    file: &str,
    params: &str,
    params_file: &str,
) -> Result<Keyed, TreeError> {
    parse_xml_str_with_keyed(xml, file, &[], params, params_file)
}

/// Like [`parse_xml_files`], also giving each node's params-file key.
pub fn parse_xml_files_keyed(
    xml: &Path,
    params: &Path,
    includes: &[std::path::PathBuf],
) -> Result<Keyed, TreeError> {
    let xml_name = xml.display().to_string();
    let params_name = params.display().to_string();
    let params_src = read_text(params, &params_name)?;
    on_parser_thread(&xml_name, || {
        let mut files = Files::new();
        files.add_file(xml)?;
        for inc in includes {
            files.add_include(inc)?;
        }
        build_keyed(files, &params_src, &params_name)
    })
}

/// Runs `f` on a thread with a dedicated stack: the builder recurses once
/// per tree level and SubTree (both bounded).
fn on_parser_thread<T: Send, F>(file: &str, f: F) -> Result<T, TreeError>
where
    F: FnOnce() -> Result<T, TreeError> + Send,
{
    std::thread::scope(|s| {
        std::thread::Builder::new()
            .name("btrel-xml".into())
            .stack_size(64 << 20)
            .spawn_scoped(s, f)
            .map_err(|e| {
                TreeError::file(
                    Kind::Internal,
                    file,
                    format!("cannot start the parser thread: {e}"),
                )
            })?
            .join()
            .unwrap_or_else(|_| {
                Err(TreeError::file(
                    Kind::Internal,
                    file,
                    "internal error: the XML parser panicked",
                )
                .with_help("please report this file as a bug"))
            })
    })
}

fn too_large(file: &str, len: usize) -> TreeError {
    TreeError::file(
        Kind::Budget,
        file,
        format!("the file is {len} bytes, more than the limit of {MAX_BYTES} bytes"),
    )
}

/// One error for every node of `problems` (none: `None`), located at the
/// first, with `help`.
fn unsupported_nodes(
    b: &Builder,
    sources: &[Source],
    problems: &[Problem],
    help: &str,
) -> Option<TreeError> {
    let first = problems.first()?;
    let n = problems.len();
    let refs: Vec<&Problem> = problems.iter().collect();
    Some(
        b.err_in(
            Kind::NoMeaning,
            first.doc,
            first.loc,
            format!(
                "{UNSUPPORTED} {n} node{} of this tree:\n{}",
                if n == 1 { "" } else { "s" },
                problem_lines(sources, &refs)
            ),
        )
        .with_help(help.to_string()),
    )
}

/// Formats collected problems as `file:line:column: text` lines.
fn problem_lines(sources: &[Source], ps: &[&Problem]) -> String {
    ps.iter()
        .map(|p| {
            format!(
                "  {}:{}:{}: {}",
                sources[p.doc].name, p.loc.0, p.loc.1, p.text
            )
        })
        .collect::<Vec<_>>()
        .join("\n")
}

/// A tree read from XML with, for every node, the params-file key its
/// parameters came from (`None` for control nodes and leaves without an
/// entry, e.g. a Script).
#[derive(Debug, Clone)]
pub struct Keyed {
    pub tree: Tree,
    /// Indexed like `tree.nodes`.
    pub keys: Vec<Option<String>>,
}

fn build_keyed(files: Files, params: &str, params_file: &str) -> Result<Keyed, TreeError> {
    let Files {
        sources,
        elems,
        roots,
        ..
    } = files;
    let table = parse_params(params, params_file)?;
    let mut b = Builder {
        sources: &sources,
        elems: &elems,
        table: &table,
        blackboard_used: Default::default(),
        trees: HashMap::new(),
        model: HashMap::new(),
        nodes: Vec::new(),
        used: HashSet::new(),
        name_bytes: 0,
        leaves: Vec::new(),
        reactive: Vec::new(),
        while_do_else: Vec::new(),
        missing_values: Vec::new(),
        once: Vec::new(),
        problems: Vec::new(),
        seen_problems: HashSet::new(),
        cur: std::cell::Cell::new(0),
        expanding: Vec::new(),
        sizes: HashMap::new(),
        sizing: HashSet::new(),
        slots: HashMap::new(),
        elem_parent: predicates::parents(&elems),
        pre_handled: HashSet::new(),
    };
    // (ID, BehaviorTree element) of the main file, in order
    let mut order: Vec<(&str, usize)> = Vec::new();
    let mut unnamed_main: Option<usize> = None;
    for (doc, &ri) in roots.iter().enumerate() {
        b.cur.set(doc);
        let root = &elems[ri];
        let src = &sources[doc];
        let err =
            |kind: Kind, at: Loc, msg: String| TreeError::at(kind, &src.name, &src.text, at, msg);
        if root.name != "root" {
            return Err(err(Kind::Structure, root.loc, format!("the root element is <{}>, not <root>", root.name))
                .with_help("a BT.CPP file is `<root BTCPP_format=\"4\"> <BehaviorTree ID=\"Main\"> ... </BehaviorTree> </root>`"));
        }
        b.check_attrs(root, &["BTCPP_format", "main_tree_to_execute"], false)?;
        let lone = root
            .children
            .iter()
            .filter(|&&c| elems[c].name == "BehaviorTree")
            .count()
            == 1;
        for &c in &root.children {
            let e = &elems[c];
            match e.name.as_str() {
                "BehaviorTree" => {
                    // other attributes are the SubTree's port defaults
                    b.check_attrs(e, &["ID"], true)?;
                    let id = match e.attr("ID") {
                        // BT.CPP accepts a lone BehaviorTree without an ID
                        None if lone && doc == 0 => {
                            unnamed_main = Some(c);
                            None
                        }
                        None if lone => {
                            return Err(err(Kind::Structure, e.loc, "<BehaviorTree> needs an ID attribute in an included file".into())
                                .with_help("a SubTree refers to an included tree by its ID: write <BehaviorTree ID=\"...\">"))
                        }
                        None => {
                            return Err(err(Kind::Structure, e.loc, "<BehaviorTree> needs an ID attribute".into())
                                .with_help("only a file's only BehaviorTree may omit its ID; write <BehaviorTree ID=\"...\">"))
                        }
                        Some(_) => Some(b.id_attr(e)?),
                    };
                    if e.children.len() != 1 {
                        return Err(err(
                            Kind::Structure,
                            e.loc,
                            format!(
                                "<BehaviorTree{}> must hold exactly one node, found {}",
                                id.map(|i| format!(" ID=\"{i}\"")).unwrap_or_default(),
                                e.children.len()
                            ),
                        )
                        .with_help("wrap several nodes in a <Sequence> or <Fallback>"));
                    }
                    let Some(id) = id else { continue };
                    let defs = b.trees.entry(id).or_default();
                    if let Some(&prev) = defs.iter().find(|&&p| elems[p].doc == doc) {
                        let p = elems[prev].loc;
                        return Err(err(
                            Kind::Structure,
                            e.loc,
                            format!("duplicate BehaviorTree ID `{id}`"),
                        )
                        .with_help(format!(
                            "`{id}` is already defined at line {}, column {}",
                            p.0, p.1
                        )));
                    }
                    defs.push(c);
                    if doc == 0 {
                        order.push((id, c));
                    }
                }
                "TreeNodesModel" => {
                    for &m in &e.children {
                        let d = &elems[m];
                        let decl = match d.name.as_str() {
                            "Action" => Decl::Action,
                            "Condition" => Decl::Condition,
                            "Decorator" => Decl::Other("decorator"),
                            "Control" => Decl::Other("control node"),
                            // a SubTree's model (ports, metadata) says nothing about leaves
                            "SubTree" => continue,
                            other => {
                                return Err(err(Kind::Structure, d.loc, format!("unknown <{other}> in <TreeNodesModel>"))
                                    .with_help("<TreeNodesModel> declares <Action>, <Condition>, <Decorator>, <Control> and <SubTree> entries"));
                            }
                        };
                        let id = b.id_attr(d)?;
                        if let Some(&prev) = b.model.get(id) {
                            if prev != decl {
                                return Err(err(
                                    Kind::Structure,
                                    d.loc,
                                    format!("`{id}` is declared twice with different kinds"),
                                )
                                .with_help("declare each ID once, as an Action or a Condition"));
                            }
                        }
                        b.model.insert(id, decl);
                    }
                }
                // resolved when the file was read
                "include" => {}
                other => {
                    return Err(err(
                        Kind::Structure,
                        e.loc,
                        format!("unknown <{other}> in <root>"),
                    )
                    .with_help(
                        "<root> holds <BehaviorTree>, <TreeNodesModel> and <include> elements",
                    ));
                }
            }
        }
    }
    b.cur.set(0);
    let root = &elems[roots[0]];
    let err = |kind: Kind, at: Loc, msg: String| {
        TreeError::at(kind, &sources[0].name, &sources[0].text, at, msg)
    };
    let (main_id, main): (Option<&str>, usize) = match root.attr("main_tree_to_execute") {
        Some(a) => match b.lookup_tree(&a.value, a.loc)? {
            Some(t) => (Some(a.value.as_str()), t),
            None => {
                let ids: Vec<&str> = b.trees.keys().copied().collect();
                let mut sorted = ids.clone();
                sorted.sort_unstable();
                let hint = match nearest(&a.value, &ids) {
                    Some(k) => format!("did you mean `{k}`? trees: {}", sorted.join(", ")),
                    None => format!("trees: {}", sorted.join(", ")),
                };
                return Err(err(
                    Kind::Structure,
                    a.loc,
                    format!("no <BehaviorTree ID=\"{}\">", a.value),
                )
                .with_help(hint));
            }
        },
        None => match (order.first(), unnamed_main) {
            (Some(&(id, t)), _) => (Some(id), t),
            (None, Some(t)) => (None, t),
            (None, None) => {
                return Err(err(
                    Kind::Structure,
                    root.loc,
                    "the file has no <BehaviorTree>".into(),
                )
                .with_help("add <BehaviorTree ID=\"Main\"> holding the root node"))
            }
        },
    };
    let size = match main_id {
        Some(id) => b.tree_size(id, 0),
        None => b.elem_size(elems[main].children[0], 0),
    };
    if size > MAX_NODES as u64 {
        return Err(err(
            Kind::Budget,
            elems[main].loc,
            format!("the tree has too many nodes after SubTree expansion ({size})"),
        )
        .with_help(format!("btrel accepts at most {MAX_NODES} nodes")));
    }
    if let Some(id) = main_id {
        b.expanding.push((id, elems[main].loc));
    }
    b.node(elems[main].children[0], None, 0, "0".into(), "", None)?;
    b.expanding.pop();

    // Nodes without a stochastic meaning wait while the params file lacks
    // blackboard values: the fix for those is a params entry, so they are
    // reported as missing parameters, with these nodes listed after them.
    let mut no_meaning_after: Option<String> = None;
    if !b.problems.is_empty() {
        let (semantic, front): (Vec<&Problem>, Vec<&Problem>) =
            b.problems.iter().partition(|p| p.semantic);
        if front.is_empty() && !b.missing_values.is_empty() {
            let n = semantic.len();
            no_meaning_after = Some(format!(
                "\nand {UNSUPPORTED} {n} node{} of this tree:\n{}",
                if n == 1 { "" } else { "s" },
                problem_lines(&sources, &semantic)
            ));
        }
    }
    if !b.problems.is_empty() && no_meaning_after.is_none() {
        let (semantic, front): (Vec<&Problem>, Vec<&Problem>) =
            b.problems.iter().partition(|p| p.semantic);
        let (kind, first, message, help) = if front.is_empty() {
            let n = semantic.len();
            (
                Kind::NoMeaning,
                semantic[0],
                format!(
                    "{UNSUPPORTED} {n} node{} of this tree:\n{}",
                    if n == 1 { "" } else { "s" },
                    problem_lines(&sources, &semantic)
                ),
                "these BT.CPP node types (or attributes) have no model as a Stochastic Behavior \
                 Tree in btrel yet; read: Sequence, SequenceWithMemory, ReactiveSequence, \
                 Fallback, ReactiveFallback, Parallel, Inverter, ForceSuccess, ForceFailure, \
                 RetryUntilSuccessful, Repeat, RecoveryNode, SubTree, AlwaysSuccess, \
                 AlwaysFailure, Script, SetBlackboard, UnsetBlackboard, ScriptCondition, \
                 Precondition, Switch2..Switch6, LoopInt/LoopDouble/LoopString/LoopBool/LoopPose, \
                 pre-conditions \
                 (_failureIf, _successIf; _skipIf, _while below a Sequence or Fallback) and \
                 custom leaves"
                    .to_string(),
            )
        } else {
            let n = front.len();
            let mut message = format!(
                "{n} node{} cannot be read:\n{}",
                if n == 1 { "" } else { "s" },
                problem_lines(&sources, &front)
            );
            if !semantic.is_empty() {
                message.push_str(&format!(
                    "\nand {UNSUPPORTED} {} node{}:\n{}",
                    semantic.len(),
                    if semantic.len() == 1 { "" } else { "s" },
                    problem_lines(&sources, &semantic)
                ));
            }
            let mut help = Vec::new();
            if front.iter().any(|p| p.text.starts_with("unknown node")) {
                help.push(
                    "a leaf (an element without children) needs no declaration, its params entry \
                     makes it an action or a condition; a node with children must be a known \
                     control node or decorator",
                );
            }
            if front.iter().any(|p| p.text.starts_with("no <BehaviorTree")) {
                help.push("a SubTree's BehaviorTree may be defined in an included file");
            }
            (Kind::UnknownNode, front[0], message, help.join("; "))
        };
        return Err(b
            .err_in(kind, first.doc, first.loc, message)
            .with_help(help));
    }

    // parameters
    let perr_as = |kind: Kind, at: Loc, msg: String, help: String| {
        TreeError::at(kind, params_file, params, at, msg).with_help(help)
    };
    let perr = |at: Loc, msg: String, help: String| perr_as(Kind::InvalidValue, at, msg, help);
    let mut used_keys: HashSet<&str> = HashSet::new();
    let mut param_keys: Vec<(usize, String)> = Vec::new();
    // (document, location, line, what copies of one element share: its keys)
    let mut missing: Vec<(usize, Loc, String, Option<String>)> = Vec::new();
    let leaves = std::mem::take(&mut b.leaves);
    for leaf in &leaves {
        let shared = Some(format!(
            "{}\0{}",
            leaf.id,
            leaf.name_attr.as_deref().unwrap_or("")
        ));
        let node = &b.nodes[leaf.node];
        let at = node.location.unwrap_or((0, 0));
        let mut keys = vec![node.name.as_str()];
        for k in leaf.name_attr.iter().chain(std::iter::once(&leaf.id)) {
            if !keys.contains(&k.as_str()) {
                keys.push(k);
            }
        }
        let found = keys.iter().find_map(|k| table.leaves.get_key_value(*k));
        let is_action = match (leaf.kind, found) {
            (LeafKind::Action, _) => true,
            (LeafKind::Condition, _) => false,
            (LeafKind::ZeroTime, None) => {
                b.nodes[leaf.node].kind = NodeKind::Condition { ps: 1.0 };
                continue;
            }
            (LeafKind::Inferred | LeafKind::ZeroTime, Some((_, def))) => has_timing(&def.value),
            (LeafKind::Inferred, None) => {
                let typo = match nearest(&leaf.id, BUILTINS) {
                    Some(k) if k != leaf.id => format!(" (or did you mean <{k}>?)"),
                    _ => String::new(),
                };
                missing.push((
                    leaf.doc,
                    at,
                    format!(
                        "leaf `{}` (ID `{}`): no entry (keys tried: {}); give `{{ps: ...}}` for a \
                         condition or `{{ps: ..., mu: ..., nu: ...}}` for an action{typo}",
                        node.name,
                        leaf.id,
                        keys.join(", ")
                    ),
                    shared,
                ));
                continue;
            }
        };
        let kind = if is_action { "action" } else { "condition" };
        let who = format!("{kind} `{}` (ID `{}`)", node.name, leaf.id);
        let Some((key, def)) = found else {
            missing.push((
                leaf.doc,
                at,
                format!("{who}: no entry (keys tried: {})", keys.join(", ")),
                shared,
            ));
            continue;
        };
        used_keys.insert(key.as_str());
        param_keys.push((leaf.node, key.clone()));
        let p = &def.value;
        let new_kind = if is_action {
            match validate_action(p, &perr)? {
                Ok(a) => NodeKind::Action(a),
                Err(m) => {
                    missing.push((leaf.doc, at, format!("{who} (key `{key}`): {m}"), shared));
                    continue;
                }
            }
        } else {
            if let Some(extra) = [&p.pf, &p.mu, &p.nu, &p.tau_s, &p.tau_f]
                .into_iter()
                .flatten()
                .map(sloc)
                .chain(p.time_law_at())
                .next()
            {
                return Err(perr_as(
                    Kind::Structure,
                    extra,
                    format!("`{key}` is used by {who}, and a condition takes only `ps`"),
                    "a condition returns in zero time; give only its probability of success `ps`"
                        .into(),
                ));
            }
            let Some(ps) = &p.ps else {
                missing.push((
                    leaf.doc,
                    at,
                    format!("{who} (key `{key}`): missing `ps` (probability of success in [0, 1])"),
                    shared,
                ));
                continue;
            };
            if !ps.value.is_finite() || !(0.0..=1.0).contains(&ps.value) {
                return Err(perr_as(
                    Kind::InvalidValue,
                    sloc(ps),
                    format!("ps = {} is not a probability", ps.value),
                    "ps must be a number in [0, 1]".into(),
                ));
            }
            NodeKind::Condition { ps: ps.value }
        };
        b.nodes[leaf.node].kind = new_kind;
    }
    let values_missing = !b.missing_values.is_empty();
    missing.extend(
        b.missing_values
            .drain(..)
            .map(|(d, at, m)| (d, at, m, None)),
    );
    if let Some(&(doc, first, ..)) = missing.first() {
        // copies of one element (a RecoveryNode's retries, a SubTree used
        // twice) share its keys: one line each, with the number of copies
        let mut lines: Vec<String> = Vec::new();
        let mut seen: HashMap<(usize, Loc, &str), (usize, usize)> = HashMap::new();
        for (d, at, m, shared) in &missing {
            let (l, c) = at;
            let line = format!("  {}:{l}:{c}: {m}", sources[*d].name);
            let Some(shared) = shared else {
                lines.push(line);
                continue;
            };
            match seen.get_mut(&(*d, *at, shared.as_str())) {
                Some((_, copies)) => *copies += 1,
                None => {
                    seen.insert((*d, *at, shared), (lines.len(), 1));
                    lines.push(line);
                }
            }
        }
        for &(line, copies) in seen.values() {
            if copies > 1 {
                lines[line].push_str(&format!(
                    " [{copies} copies of this element (retries, SubTrees): one entry keyed by \
                     its name or ID covers them all]"
                ));
            }
        }
        let n = lines.len();
        return Err(b
            .err_in(
                Kind::MissingParameter,
                doc,
                first,
                format!(
                    "missing parameters for {n} node{} in {params_file}:\n{}{}",
                    if n == 1 { "" } else { "s" },
                    lines.join("\n"),
                    no_meaning_after.unwrap_or_default()
                ),
            )
            .with_help(format!(
                "add an entry per node to {params_file}, keyed by name or ID, e.g. \
                 `grasp: {{ps: 0.5, mu: 0.1, nu: 0.2}}` (actions) or `ready: {{ps: 0.9}}` \
                 (conditions){}",
                if values_missing {
                    ", and one per blackboard value, keyed by the reference as written, e.g. \
                     `\"{waypoints}\": {value: 5}`"
                } else {
                    ""
                }
            )));
    }
    let blackboard_used = b.blackboard_used.take();
    if let Some((key, def)) = table
        .blackboard
        .iter()
        .filter(|(k, _)| !blackboard_used.contains(k.as_str()))
        .min_by_key(|(_, d)| sloc(d))
    {
        return Err(perr_as(
            Kind::InvalidValue,
            sloc(def),
            format!(
                "params key `{key}` matches no blackboard reference or port value that btrel reads"
            ),
            "blackboard values (keys written `{name}`) are read where a count, a duration or a \
             queue (num_cycles, num_attempts, number_of_retries, msec, delay_msec, queue, \
             vector_in, ...) is written as that reference; port values (keys written \
             `<node>/<port>`) are read by DistanceController and SpeedController (`speed`); \
             remove the entry or check its spelling"
                .into(),
        ));
    }
    if let Some((key, def)) = table
        .leaves
        .iter()
        .filter(|(k, _)| !used_keys.contains(k.as_str()))
        .min_by_key(|(_, d)| sloc(d))
    {
        let names: Vec<&str> = leaves
            .iter()
            .flat_map(|l| {
                [b.nodes[l.node].name.as_str(), l.id.as_str()]
                    .into_iter()
                    .chain(l.name_attr.as_deref())
            })
            .collect();
        let hint = match nearest(key, &names) {
            Some(k) => format!("did you mean `{k}`? keys are leaf names or IDs"),
            None => "keys are the names or IDs of the tree's actions and conditions; remove unused entries".into(),
        };
        return Err(perr_as(
            Kind::InvalidValue,
            sloc(def),
            format!("params key `{key}` matches no action or condition"),
            hint,
        ));
    }
    // A Reactive node halts (resets) its other children when one returns
    // RUNNING and ticks them again from IDLE on the next tick: an action in
    // an earlier child is restarted while a later child runs (and that one
    // is halted), which a Sequence / Fallback does not model. Refused when
    // two or more children hold actions that take time; conditions only
    // re-read their value, and zero-time actions (`tau_s: 0`, `tau_f: 0`:
    // synchronous, never RUNNING) return in the tick that starts them.
    let has_action = |root: usize| {
        let mut stack = vec![root];
        while let Some(n) = stack.pop() {
            match &b.nodes[n].kind {
                NodeKind::Action(a)
                    if [a.success, a.failure].iter().flatten().any(
                        |d| !matches!(d, crate::tree::Duration::Fixed { time } if *time == 0.0),
                    ) =>
                {
                    return true
                }
                NodeKind::Action(_) => {}
                k => stack.extend(k.children().iter().copied()),
            }
        }
        false
    };
    let mut restarts: Vec<Problem> = Vec::new();
    let mut loops: HashMap<usize, reactive::Restart> = HashMap::new();
    for &(id, doc, loc, ty) in &b.reactive {
        // a PathLongerOnApproach that returned Success below a
        // ReactiveSequence, ticked again (even from IDLE), finds the path it
        // stored and returns Success at once: it is never restarted, though
        // a later child that runs is halted while its own child runs
        let once = |c: usize| {
            ty == "ReactiveSequence"
                && b.once
                    .iter()
                    .any(|o| o.0 == c && o.3 == "PathLongerOnApproach")
        };
        let children = b.nodes[id].kind.children();
        let kids: Vec<usize> = (0..children.len())
            .filter(|&i| has_action(children[i]))
            .collect();
        let restarted = kids
            .split_last()
            .is_some_and(|(_, earlier)| earlier.iter().any(|&i| !once(children[i])));
        if !restarted {
            continue;
        }
        // the restart loop (reactive.rs): the first two children that take
        // time must surely return RUNNING at their first tick, and the
        // first must be restarted (not a PathLongerOnApproach)
        let (first, second) = (kids[0], kids[1]);
        let name = |i: usize| format!("'{}'", b.nodes[children[i]].name);
        let unsure: Vec<String> = [first, second]
            .into_iter()
            .filter(|&i| !reactive::surely_timed(&b.nodes, children[i]))
            .map(name)
            .collect();
        if !unsure.is_empty() || once(children[first]) {
            let why = if unsure.is_empty() {
                format!(
                    "its first child that takes time, {}, is a PathLongerOnApproach, which is \
                     not restarted while a later child is",
                    name(first)
                )
            } else {
                format!(
                    "{} may return within its first tick or take time, which decides whether \
                     the children are restarted",
                    unsure.join(" and ")
                )
            };
            restarts.push(Problem {
                doc,
                loc,
                text: format!(
                    "<{ty}> with actions that take time in {} children ({}): BT.CPP halts its \
                     other children when one returns RUNNING and ticks them again from IDLE; \
                     btrel reads this restart loop exactly when the first two such children \
                     surely return RUNNING at their first tick, but {why}",
                    kids.len(),
                    kids.iter().map(|&i| name(i)).collect::<Vec<_>>().join(", "),
                ),
                semantic: true,
            });
            continue;
        }
        loops.insert(
            id,
            reactive::Restart {
                first,
                second,
                sequence: ty == "ReactiveSequence",
            },
        );
    }
    // WhileDoElse ticks its condition child again at every tick of a
    // running branch and halts the branch if the outcome changes: with
    // conditions only (which keep their value) that is IfThenElse; an action
    // there would be ticked again after it returned, which no fresh run
    // models.
    for &(id, doc, loc) in &b.while_do_else {
        let condition = b.nodes[id].kind.children()[0];
        if has_action(condition) {
            restarts.push(Problem {
                doc,
                loc,
                text: "<WhileDoElse> whose condition child holds an action: BT.CPP ticks that \
                       child again at every tick while a branch runs (and halts the branch when \
                       its outcome changes); read as IfThenElse only when the condition child \
                       takes no time (conditions only)"
                    .to_string(),
                semantic: true,
            });
        }
    }
    if let Some(e) = unsupported_nodes(
        &b,
        &sources,
        &restarts,
        "ReactiveSequence and ReactiveFallback are read as Sequence and Fallback when \
                 at most one child holds actions (conditions before it are re-ticked, which \
                 changes nothing while they keep their value), and as their restart loop when \
                 two children hold actions that surely take time (README, node table); \
                 WhileDoElse is read as IfThenElse when its condition child holds conditions \
                 only",
    ) {
        return Err(e);
    }
    let mut keys = vec![None; b.nodes.len()];
    for (node, key) in param_keys {
        keys[node] = Some(key);
    }
    // GoalUpdatedController and PathLongerOnApproach ticked again after
    // returning (an earlier PipelineSequence child) do not run their child
    // again while the goal and the path keep their values; btrel reads a
    // re-ticked subtree that takes time and can fail as re-run
    let mut again: Vec<Problem> = Vec::new();
    let view = Tree {
        title: None,
        nodes: if b.once.is_empty() {
            Vec::new()
        } else {
            b.nodes.clone()
        },
    };
    for &(id, doc, loc, ty) in &b.once {
        let tree = &view;
        let Some(p) = tree.nodes[id].parent else {
            continue;
        };
        let earlier = match &tree.nodes[p].kind {
            NodeKind::Pipeline { children } => children.last() != Some(&id),
            _ => false,
        };
        if earlier && super::nav2::retick(tree, id) != super::nav2::Retick::Inert {
            again.push(Problem {
                doc,
                loc,
                text: format!(
                    "<{ty}> as an earlier child of a PipelineSequence: ticked again while a later \
                     child runs it does not run its child again (the goal and the path keep \
                     their values), while btrel's PipelineSequence would re-run a subtree that \
                     takes time and can fail"
                ),
                semantic: true,
            });
        }
    }
    if let Some(e) = unsupported_nodes(
        &b,
        &sources,
        &again,
        "as an earlier PipelineSequence child, GoalUpdatedController is read exactly when \
                 its child is a leaf, takes no time or cannot fail, and PathLongerOnApproach when \
                 its child takes no time or cannot fail",
    ) {
        return Err(e);
    }
    let tree = Tree {
        title: main_id.map(str::to_string),
        nodes: b.nodes,
    };
    if loops.is_empty() {
        return Ok(Keyed { tree, keys });
    }
    // the restart loops, once every check on the built tree is done
    let (tree, keys) =
        reactive::rewrite(&tree, &keys, &loops, MAX_NODES, MAX_DEPTH).map_err(|e| {
            let &(_, doc, loc, _) = b
                .reactive
                .iter()
                .find(|r| loops.contains_key(&r.0))
                .expect("a rewritten node is reactive");
            let s = &sources[doc];
            TreeError::at(Kind::Budget, &s.name, &s.text, loc, e)
        })?;
    Ok(Keyed { tree, keys })
}

fn read_text(path: &Path, file: &str) -> Result<String, TreeError> {
    let io_err = |e: std::io::Error| {
        TreeError::file(Kind::Io, file, format!("cannot read the file: {e}"))
            .with_help(super::parse::read_help(&e))
    };
    let meta = std::fs::metadata(path).map_err(io_err)?;
    if meta.len() > MAX_BYTES as u64 {
        return Err(too_large(file, meta.len() as usize));
    }
    let bytes = std::fs::read(path).map_err(io_err)?;
    String::from_utf8(bytes).map_err(|e| {
        let before = &e.as_bytes()[..e.utf8_error().valid_up_to()];
        let line = before.iter().filter(|&&b| b == b'\n').count() + 1;
        let column = before.iter().rev().take_while(|&&b| b != b'\n').count() + 1;
        TreeError {
            line,
            column,
            ..TreeError::file(Kind::Syntax, file, "the file is not valid UTF-8 text")
        }
        .with_help("is this the right file?")
    })
}
