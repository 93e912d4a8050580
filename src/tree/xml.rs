//! BehaviorTree.CPP v4 XML front end.
//!
//! A tree is read from two files: the BT.CPP XML (structure) and a small YAML
//! params file (the stochastic parameters of each action and condition):
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
//! listed in one error, one line each with the node's XML location.
//!
//! # Supported XML
//!
//! * `<root BTCPP_format="4" main_tree_to_execute="X">`; without
//!   `main_tree_to_execute` the only tree, or the first one, is analysed.
//! * `<BehaviorTree ID="...">` holding exactly one node; `<SubTree ID="..."/>`
//!   is expanded in place (recursion is an error naming the cycle).
//! * `Sequence`, `SequenceWithMemory`, `ReactiveSequence` become a Sequence;
//!   `Fallback`, `ReactiveFallback` become a Fallback. Under the SBT
//!   assumptions (a condition is evaluated once per execution of its parent
//!   and keeps its outcome; a running action is never interrupted by a
//!   re-evaluated sibling) a reactive node runs exactly like its
//!   non-reactive counterpart. `SequenceWithMemory` does not restart at its
//!   first child after a failure, so below a `RetryUntilSuccessful` (where a
//!   failed child is ticked again) it differs from a fresh Sequence: that
//!   case is refused.
//! * `Parallel success_count failure_count` (BT.CPP v4 defaults −1 and 1; a
//!   negative count k means N + k + 1, so −1 is "all children").
//! * `Inverter`, `ForceSuccess`, `ForceFailure`,
//!   `RetryUntilSuccessful num_attempts="N"`, `Repeat num_cycles="N"`
//!   (N from 1 to 1 000 000; −1, "forever", is refused).
//! * `AlwaysSuccess` / `AlwaysFailure` become conditions with `ps` 1 / 0.
//! * `<Action ID="X"/>`, `<Condition ID="X"/>` and the short form `<X/>` for
//!   IDs declared in `<TreeNodesModel>` as `<Action ID="X"/>` or
//!   `<Condition ID="X"/>`. Data ports of leaves and SubTrees (attributes
//!   that do not start with `_`) are ignored: the params file already gives
//!   the leaf's outcome distribution.
//!
//! Everything else is refused with its line and column and a hint:
//! scripting and blackboard nodes (`Script`, `Switch2`..`Switch6`, ...),
//! time-based decorators (`Timeout`, `Delay`), `KeepRunningUntilFailure`,
//! pre/post-condition attributes (`_skipIf`, `_while`, ...), blackboard
//! references as counts (`num_attempts="{n}"`), text content, CDATA,
//! DOCTYPE, processing instructions and unknown elements.
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
//! Input up to 256 MiB, XML elements nested at most 202 deep (`root`,
//! `BehaviorTree` and 200 tree levels), expanded trees at most 200 levels
//! deep, at most 5 million nodes after SubTree expansion and 256 MiB of node
//! names. The XML reader is iterative and the tree builder's recursion is
//! bounded by those depths.

use std::collections::{BTreeMap, HashMap, HashSet};
use std::path::Path;

use super::action::{sloc, validate_action, ActionParams, At, Loc};
use super::error::{nearest, TreeError};
use super::{Action, Decorator, Node, NodeKind, Tree};

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

/// A parsed document: `elems[0]` is the root element.
struct Doc {
    elems: Vec<Elem>,
}

struct Reader<'a> {
    src: &'a str,
    file: &'a str,
    pos: usize,
    line: usize,
    col: usize,
}

impl<'a> Reader<'a> {
    fn loc(&self) -> Loc {
        (self.line, self.col)
    }

    fn err(&self, at: Loc, msg: impl Into<String>) -> TreeError {
        TreeError::at(self.file, self.src, at, msg)
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
                .err(start, format!("unterminated {what}"))
                .with_help(format!("close it with `{end}`"))),
        }
    }

    fn name(&mut self, what: &str) -> Result<String, TreeError> {
        let at = self.loc();
        match self.peek() {
            Some(c) if c.is_alphabetic() || c == '_' || c == ':' => {}
            Some(c) => {
                return Err(self
                    .err(at, format!("expected {what}, found {c:?}"))
                    .with_help("XML names start with a letter or `_`"))
            }
            None => return Err(self.err(at, format!("expected {what}, found the end of the file"))),
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
                self.skip_past("-->", at, "comment")?;
            } else if self.starts_with("<![CDATA[") {
                return Err(self
                    .err(at, "CDATA sections are not supported")
                    .with_help("a behavior tree needs no text content; remove the CDATA section"));
            } else if self.starts_with("<!") {
                return Err(self
                    .err(at, "DOCTYPE and other declarations are not supported")
                    .with_help("remove the declaration; BT.CPP files do not need it"));
            } else if self.starts_with("<?") {
                return Err(self
                    .err(at, "processing instructions are not supported")
                    .with_help("only `<?xml ...?>` at the very start of the file is accepted"));
            } else {
                return Ok(());
            }
        }
    }

    /// Decodes entity and character references in `raw`, which starts at
    /// `at`.
    fn decode(&self, raw: &str, at: Loc) -> Result<String, TreeError> {
        if !raw.contains('&') {
            return Ok(raw.to_string());
        }
        let mut out = String::with_capacity(raw.len());
        let mut rest = raw;
        while let Some(i) = rest.find('&') {
            out.push_str(&rest[..i]);
            let tail = &rest[i + 1..];
            let bad = |what: String| {
                let before = &raw[..raw.len() - rest.len() + i];
                let (mut l, mut c) = at;
                for ch in before.chars() {
                    if ch == '\n' {
                        l += 1;
                        c = 1;
                    } else {
                        c += 1;
                    }
                }
                self.err((l, c), what).with_help(
                    "use &lt; &gt; &amp; &quot; &apos; or &#N; / &#xH;, and write a literal `&` as &amp;",
                )
            };
            let Some(end) = tail.find(';').filter(|&e| e <= 12) else {
                return Err(bad("`&` does not start an entity reference".into()));
            };
            let ent = &tail[..end];
            let ch = match ent {
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
            match ch {
                Some(c) => out.push(c),
                None => return Err(bad(format!("unknown or invalid entity `&{ent};`"))),
            }
            rest = &tail[end + 1..];
        }
        out.push_str(rest);
        Ok(out)
    }

    fn attr_value(&mut self) -> Result<String, TreeError> {
        let at = self.loc();
        let quote = match self.peek() {
            Some(q @ ('"' | '\'')) => q,
            _ => {
                return Err(self
                    .err(at, "expected a quoted attribute value")
                    .with_help("write attributes as name=\"value\" or name='value'"))
            }
        };
        self.bump();
        let vstart = self.loc();
        let start = self.pos;
        loop {
            match self.peek() {
                None => {
                    return Err(self
                        .err(at, "unterminated attribute value")
                        .with_help(format!("close the value with {quote}")))
                }
                Some('<') => {
                    return Err(self
                        .err(self.loc(), "`<` inside an attribute value")
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
        let v = self.decode(raw, vstart)?;
        Ok(v.replace(['\t', '\n', '\r'], " "))
    }

    fn parse(mut self) -> Result<Doc, TreeError> {
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
        self.misc()?;
        if self.peek().is_none() {
            return Err(self
                .err((1, 1), "the file has no root element")
                .with_help("a BT.CPP file is `<root BTCPP_format=\"4\"> <BehaviorTree ID=\"Main\"> ... </BehaviorTree> </root>`"));
        }
        if self.peek() != Some('<') {
            return Err(self
                .err(self.loc(), "expected `<` to open the root element")
                .with_help("is this really a BehaviorTree.CPP XML file?"));
        }
        let mut elems: Vec<Elem> = Vec::new();
        let mut stack: Vec<usize> = Vec::new();
        loop {
            // here we are at markup or text inside the open element on top of
            // the stack (or at the root element if the stack is empty)
            let at = self.loc();
            if self.peek().is_none() {
                let Some(e) = stack.last().map(|&open| &elems[open]) else {
                    return Err(self.err(at, "unexpected end of the file"));
                };
                return Err(self
                    .err(e.loc, format!("element <{}> is never closed", e.name))
                    .with_help(format!("add </{}>", e.name)));
            }
            if self.starts_with("</") {
                self.eat("</");
                let name = self.name("an element name")?;
                self.skip_ws();
                if !self.eat(">") {
                    return Err(self.err(self.loc(), "expected `>` to end the closing tag"));
                }
                let Some(&open) = stack.last() else {
                    return Err(
                        self.err(at, format!("closing tag </{name}> without an opening tag"))
                    );
                };
                if elems[open].name != name {
                    let e = &elems[open];
                    return Err(self
                        .err(at, format!("</{name}> does not close <{}>", e.name))
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
                            .err(at, format!("unterminated tag <{name}"))
                            .with_help("end it with `>` or `/>`"));
                    }
                    if !ws {
                        return Err(self
                            .err(aloc, "expected white space, `>` or `/>`")
                            .with_help("separate attributes with spaces"));
                    }
                    let aname = self.name("an attribute name or `>`")?;
                    self.skip_ws();
                    if !self.eat("=") {
                        return Err(self
                            .err(
                                self.loc(),
                                format!("expected `=` after attribute `{aname}`"),
                            )
                            .with_help("write attributes as name=\"value\""));
                    }
                    self.skip_ws();
                    let value = self.attr_value()?;
                    if let Some(prev) = attrs.iter().find(|a| a.name == aname) {
                        return Err(self
                            .err(aloc, format!("duplicate attribute `{aname}`"))
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
                        return Err(self.err(at, "the XML is nested too deeply").with_help(
                            format!("btrel accepts trees up to {MAX_DEPTH} levels deep"),
                        ));
                    }
                    stack.push(id);
                }
            } else {
                let start = self.pos;
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
                if stack.is_empty() {
                    return Err(self
                        .err(at, "text outside the root element")
                        .with_help("is this really a BehaviorTree.CPP XML file?"));
                }
                let raw = &self.src[start..self.pos];
                self.decode(raw, at)?;
                if let (Some(f), Some(&top)) = (first, stack.last()) {
                    elems[top].text.get_or_insert(f);
                }
            }
        }
        // after the root element: only comments and white space
        self.misc()?;
        if self.peek().is_some() {
            return Err(self
                .err(self.loc(), "content after the root element")
                .with_help("an XML file has exactly one root element"));
        }
        Ok(Doc { elems })
    }
}

fn xml_char(c: char) -> bool {
    matches!(c, '\t' | '\n' | '\r')
        || (' '..='\u{d7ff}').contains(&c)
        || ('\u{e000}'..='\u{fffd}').contains(&c)
        || c >= '\u{10000}'
}

// ---------------------------------------------------------------------------
// Params file
// ---------------------------------------------------------------------------

fn parse_params(src: &str, file: &str) -> Result<BTreeMap<String, At<ActionParams>>, TreeError> {
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
        TreeError::at(file, src, at, format!("invalid params file: {text}")).with_help(
            "the params file maps a node's name or ID to its parameters, e.g. \
             `grasp: {ps: 0.5, mu: 0.1, nu: 0.2}`; accepted keys: ps, pf, mu, nu, tau_s, tau_f",
        )
    })
}

/// Validates an action's parameters (the rules of the YAML format).
/// `Ok(Err(missing))` describes missing parameters.
// ---------------------------------------------------------------------------
// Building the tree
// ---------------------------------------------------------------------------

#[derive(Clone, Copy, PartialEq, Eq)]
enum Decl {
    Action,
    Condition,
    /// A custom control node, decorator or SubTree declared in the model.
    Other(&'static str),
}

/// A leaf waiting for its parameters.
struct Leaf {
    node: usize,
    is_action: bool,
    id: String,
    name_attr: Option<String>,
}

/// Known BT.CPP v4 nodes that have no meaning in a Stochastic Behavior Tree,
/// with the reason.
fn unsupported(tag: &str) -> Option<&'static str> {
    Some(match tag {
        "Script" | "ScriptCondition" | "SetBlackboard" | "UnsetBlackboard" | "WasEntryUpdated"
        | "SkipUnlessUpdated" | "WaitValueUpdate" | "Precondition" | "EntryUpdated" => {
            "scripting and blackboard nodes have no stochastic meaning; replace the node by an \
             <Action> or <Condition> with parameters, or remove it"
        }
        "Switch2" | "Switch3" | "Switch4" | "Switch5" | "Switch6" | "IfThenElse"
        | "WhileDoElse" | "ManualSelector" => {
            "this control node branches on blackboard values or user input, which have no \
             stochastic meaning; model the choice with a Fallback of Conditions"
        }
        "Timeout"
        | "Delay"
        | "Sleep"
        | "RunOnce"
        | "KeepRunningUntilFailure"
        | "LoopInt"
        | "LoopDouble"
        | "LoopString"
        | "LoopBool"
        | "ParallelAll"
        | "SubTreePlus"
        | "RetryUntilSuccesful"
        | "TestNode" => {
            "this node's behaviour (time limits, delays, endless loops, queues, or a deprecated \
             form) has no stochastic model; supported: Sequence, SequenceWithMemory, \
             ReactiveSequence, Fallback, ReactiveFallback, Parallel, Inverter, ForceSuccess, \
             ForceFailure, RetryUntilSuccessful, Repeat, Action, Condition, SubTree, \
             AlwaysSuccess, AlwaysFailure"
        }
        _ => return None,
    })
}

const BUILTINS: &[&str] = &[
    "Sequence",
    "SequenceWithMemory",
    "ReactiveSequence",
    "Fallback",
    "ReactiveFallback",
    "Parallel",
    "Inverter",
    "ForceSuccess",
    "ForceFailure",
    "RetryUntilSuccessful",
    "Repeat",
    "Action",
    "Condition",
    "SubTree",
    "AlwaysSuccess",
    "AlwaysFailure",
];

struct Builder<'a> {
    doc: &'a Doc,
    src: &'a str,
    file: &'a str,
    trees: HashMap<&'a str, usize>,
    model: HashMap<&'a str, Decl>,
    nodes: Vec<Node>,
    used: HashSet<String>,
    name_bytes: usize,
    leaves: Vec<Leaf>,
    /// SubTree IDs being expanded, outermost first, with the instance
    /// location.
    expanding: Vec<(&'a str, Loc)>,
    /// Node counts of expanded trees (memo for [`Builder::tree_size`]).
    sizes: HashMap<&'a str, u64>,
    sizing: HashSet<&'a str>,
}

impl<'a> Builder<'a> {
    fn err(&self, at: Loc, msg: impl Into<String>) -> TreeError {
        TreeError::at(self.file, self.src, at, msg)
    }

    fn elem(&self, i: usize) -> &'a Elem {
        &self.doc.elems[i]
    }

    /// Refuses attributes not in `allowed`; `ports` accepts data ports
    /// (attributes not starting with `_`).
    fn check_attrs(&self, e: &Elem, allowed: &[&str], ports: bool) -> Result<(), TreeError> {
        for a in &e.attrs {
            if allowed.contains(&a.name.as_str()) || (ports && !a.name.starts_with('_')) {
                continue;
            }
            if a.name.starts_with('_') {
                return Err(self
                    .err(a.loc, format!("attribute `{}` is not supported", a.name))
                    .with_help(
                        "pre/post conditions and other `_` attributes change the control flow \
                         through the blackboard, which has no stochastic meaning; remove it",
                    ));
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
                .err(
                    a.loc,
                    format!("unknown attribute `{}` on <{}>", a.name, e.name),
                )
                .with_help(hint));
        }
        Ok(())
    }

    fn no_text(&self, e: &Elem) -> Result<(), TreeError> {
        if let Some(at) = e.text {
            return Err(self
                .err(at, format!("text inside <{}> has no meaning", e.name))
                .with_help("tree nodes contain only other nodes; remove the text"));
        }
        Ok(())
    }

    /// A whole-number attribute; `None` if absent.
    fn int_attr(&self, e: &Elem, key: &str) -> Result<Option<(i64, Loc)>, TreeError> {
        let Some(a) = e.attr(key) else {
            return Ok(None);
        };
        let v = a.value.trim();
        if v.starts_with('{') {
            return Err(self
                .err(a.loc, format!("{key} = \"{v}\" is a blackboard reference"))
                .with_help(format!("btrel needs a literal whole number for {key}")));
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
                .err(a.loc, format!("{key} = \"{v}\" is not a whole number"))
                .with_help(format!("write {key} as a whole number such as 3"))),
        }
    }

    fn name_attr(&self, e: &Elem) -> Result<Option<String>, TreeError> {
        match e.attr("name") {
            Some(a) if a.value.trim().is_empty() => Err(self
                .err(a.loc, "a node name must not be empty")
                .with_help("omit `name` to name the node by its ID")),
            Some(a) => Ok(Some(a.value.clone())),
            None => Ok(None),
        }
    }

    fn id_attr(&self, e: &'a Elem) -> Result<&'a str, TreeError> {
        match e.attr("ID") {
            Some(a) if !a.value.trim().is_empty() => Ok(a.value.as_str()),
            Some(a) => Err(self.err(a.loc, format!("<{}> has an empty ID", e.name))),
            None => Err(self
                .err(e.loc, format!("<{}> needs an ID attribute", e.name))
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
                .err(at, "the node names after SubTree expansion are too long")
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
                .err(e.loc, "the tree has too many nodes after SubTree expansion")
                .with_help(format!("btrel accepts at most {MAX_NODES} nodes")));
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

    #[allow(clippy::too_many_arguments)]
    fn node(
        &mut self,
        ei: usize,
        parent: Option<usize>,
        depth: usize,
        path: String,
        prefix: &str,
        under_retry: bool,
    ) -> Result<usize, TreeError> {
        let e = self.elem(ei);
        if depth >= MAX_DEPTH {
            return Err(self
                .err(e.loc, "the tree is nested too deeply")
                .with_help(format!("btrel accepts trees up to {MAX_DEPTH} levels deep")));
        }
        self.no_text(e)?;
        let tag = e.name.as_str();
        match tag {
            "Sequence" | "SequenceWithMemory" | "ReactiveSequence" | "Fallback"
            | "ReactiveFallback" | "Parallel" => {
                if tag == "SequenceWithMemory" && under_retry {
                    return Err(self
                        .err(e.loc, "SequenceWithMemory below RetryUntilSuccessful is not supported")
                        .with_help(
                            "after a failure SequenceWithMemory resumes at the failed child instead \
                             of starting afresh, which the SBT model of retries does not cover; \
                             use Sequence",
                        ));
                }
                let parallel = tag == "Parallel";
                if parallel {
                    self.check_attrs(e, &["name", "success_count", "failure_count"], false)?;
                } else {
                    self.check_attrs(e, &["name"], false)?;
                }
                if e.children.is_empty() {
                    return Err(self
                        .err(e.loc, format!("<{tag}> has no children"))
                        .with_help("a control node needs at least one child"));
                }
                let base = self.name_attr(e)?.unwrap_or_else(|| tag.to_string());
                let kind = match tag {
                    "Fallback" | "ReactiveFallback" => NodeKind::Fallback {
                        children: Vec::new(),
                    },
                    "Parallel" => NodeKind::Parallel {
                        success_threshold: 0,
                        failure_threshold: 0,
                        children: Vec::new(),
                    },
                    _ => NodeKind::Sequence {
                        children: Vec::new(),
                    },
                };
                let id = self.push(e, &base, prefix, parent, depth, &path, kind)?;
                let mut ids = Vec::with_capacity(e.children.len());
                for (i, &c) in e.children.iter().enumerate() {
                    ids.push(self.node(
                        c,
                        Some(id),
                        depth + 1,
                        format!("{path}.{i}"),
                        prefix,
                        under_retry,
                    )?);
                }
                let thresholds = if parallel {
                    Some(self.thresholds(e, ids.len())?)
                } else {
                    None
                };
                match &mut self.nodes[id].kind {
                    NodeKind::Sequence { children } | NodeKind::Fallback { children } => {
                        *children = ids
                    }
                    NodeKind::Parallel {
                        success_threshold,
                        failure_threshold,
                        children,
                    } => {
                        *children = ids;
                        (*success_threshold, *failure_threshold) = thresholds.unwrap_or((0, 0));
                    }
                    _ => {}
                }
                Ok(id)
            }
            "Inverter" | "ForceSuccess" | "ForceFailure" | "RetryUntilSuccessful" | "Repeat" => {
                let (decorator, retry) = match tag {
                    "Inverter" => {
                        self.check_attrs(e, &["name"], false)?;
                        (Decorator::Inverter, false)
                    }
                    "ForceSuccess" => {
                        self.check_attrs(e, &["name"], false)?;
                        (Decorator::ForceSuccess, false)
                    }
                    "ForceFailure" => {
                        self.check_attrs(e, &["name"], false)?;
                        (Decorator::ForceFailure, false)
                    }
                    "RetryUntilSuccessful" => {
                        self.check_attrs(e, &["name", "num_attempts"], false)?;
                        let attempts = self.count(e, "num_attempts")?;
                        (Decorator::Retry { attempts }, true)
                    }
                    _ => {
                        self.check_attrs(e, &["name", "num_cycles"], false)?;
                        let times = self.count(e, "num_cycles")?;
                        (Decorator::Repeat { times }, false)
                    }
                };
                if e.children.len() != 1 {
                    return Err(self
                        .err(
                            e.loc,
                            format!(
                                "<{tag}> needs exactly one child, found {}",
                                e.children.len()
                            ),
                        )
                        .with_help(
                            "a decorator wraps exactly one node; wrap several in a <Sequence>",
                        ));
                }
                let base = self.name_attr(e)?.unwrap_or_else(|| tag.to_string());
                let kind = NodeKind::Decorator {
                    decorator,
                    child: 0,
                };
                let id = self.push(e, &base, prefix, parent, depth, &path, kind)?;
                let c = self.node(
                    e.children[0],
                    Some(id),
                    depth + 1,
                    format!("{path}.0"),
                    prefix,
                    under_retry || retry,
                )?;
                if let NodeKind::Decorator { child, .. } = &mut self.nodes[id].kind {
                    *child = c;
                }
                Ok(id)
            }
            "AlwaysSuccess" | "AlwaysFailure" => {
                self.check_attrs(e, &["name"], false)?;
                self.no_children(e)?;
                let base = self.name_attr(e)?.unwrap_or_else(|| tag.to_string());
                let ps = if tag == "AlwaysSuccess" { 1.0 } else { 0.0 };
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
            "Action" | "Condition" => {
                self.check_attrs(e, &["name", "ID"], true)?;
                let id = self.id_attr(e)?;
                self.leaf(e, id, tag == "Action", parent, depth, &path, prefix)
            }
            "SubTree" => self.subtree(e, parent, depth, path, prefix, under_retry),
            _ => {
                if let Some(why) = unsupported(tag) {
                    return Err(self
                        .err(e.loc, format!("<{tag}> is not supported"))
                        .with_help(why));
                }
                match self.model.get(tag).copied() {
                    Some(Decl::Action) | Some(Decl::Condition) => {
                        self.check_attrs(e, &["name"], true)?;
                        let is_action = self.model.get(tag) == Some(&Decl::Action);
                        let id: &'a str = &self.elem(ei).name;
                        self.leaf(e, id, is_action, parent, depth, &path, prefix)
                    }
                    Some(Decl::Other(what)) => Err(self
                        .err(e.loc, format!("custom {what} <{tag}> is not supported"))
                        .with_help(
                            "custom control nodes and decorators have no stochastic model; only \
                             custom Actions and Conditions can be given parameters",
                        )),
                    None => {
                        let hint = match nearest(tag, BUILTINS) {
                            Some(k) => format!(
                                "did you mean <{k}>? If <{tag}> is your own node, declare it in \
                                 <TreeNodesModel> as <Action ID=\"{tag}\"/> or <Condition ID=\"{tag}\"/>"
                            ),
                            None => format!(
                                "declare it in <TreeNodesModel> as <Action ID=\"{tag}\"/> or \
                                 <Condition ID=\"{tag}\"/>, or write <Action ID=\"{tag}\"/>"
                            ),
                        };
                        Err(self
                            .err(e.loc, format!("unknown node <{tag}>"))
                            .with_help(hint))
                    }
                }
            }
        }
    }

    /// Number of nodes of tree `id` after SubTree expansion (saturating),
    /// computed without expanding. Cycles and over-deep SubTree chains
    /// count as 0 here: the builder reports them.
    fn tree_size(&mut self, id: &'a str, guard: usize) -> u64 {
        if let Some(&s) = self.sizes.get(id) {
            return s;
        }
        let Some(&tree) = self.trees.get(id) else {
            return 0;
        };
        if guard > MAX_DEPTH || !self.sizing.insert(id) {
            return 0;
        }
        let doc = self.doc;
        let mut total = 0u64;
        let mut stack: Vec<usize> = doc.elems[tree].children.clone();
        while let Some(i) = stack.pop() {
            let e = &doc.elems[i];
            if e.name == "SubTree" {
                if let Some(a) = e.attr("ID") {
                    total = total.saturating_add(self.tree_size(&a.value, guard + 1));
                }
            } else {
                total = total.saturating_add(1);
                stack.extend_from_slice(&e.children);
            }
        }
        self.sizing.remove(id);
        self.sizes.insert(id, total);
        total
    }

    fn no_children(&self, e: &Elem) -> Result<(), TreeError> {
        if let Some(&c) = e.children.first() {
            return Err(self
                .err(
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
        is_action: bool,
        parent: Option<usize>,
        depth: usize,
        path: &str,
        prefix: &str,
    ) -> Result<usize, TreeError> {
        self.no_children(e)?;
        let name_attr = self.name_attr(e)?;
        let base = name_attr.clone().unwrap_or_else(|| id.to_string());
        // placeholder parameters, filled in from the params file
        let kind = if is_action {
            NodeKind::Action(Action {
                ps: 0.0,
                pf: 1.0,
                success: None,
                failure: None,
            })
        } else {
            NodeKind::Condition { ps: 0.0 }
        };
        let node = self.push(e, &base, prefix, parent, depth, path, kind)?;
        self.leaves.push(Leaf {
            node,
            is_action,
            id: id.to_string(),
            name_attr,
        });
        Ok(node)
    }

    fn subtree(
        &mut self,
        e: &'a Elem,
        parent: Option<usize>,
        depth: usize,
        path: String,
        prefix: &str,
        under_retry: bool,
    ) -> Result<usize, TreeError> {
        self.check_attrs(e, &["name", "ID", "_autoremap"], true)?;
        self.no_children(e)?;
        let id = self.id_attr(e)?;
        let Some(&tree) = self.trees.get(id) else {
            let ids: Vec<&str> = self.trees.keys().copied().collect();
            let mut sorted = ids.clone();
            sorted.sort_unstable();
            let hint = match nearest(id, &ids) {
                Some(k) => format!("did you mean `{k}`? trees: {}", sorted.join(", ")),
                None => format!("trees: {}", sorted.join(", ")),
            };
            return Err(self
                .err(
                    e.loc,
                    format!("no <BehaviorTree ID=\"{id}\"> for this SubTree"),
                )
                .with_help(hint));
        };
        if let Some(pos) = self.expanding.iter().position(|(t, _)| *t == id) {
            let cycle: Vec<&str> = self.expanding[pos..]
                .iter()
                .map(|(t, _)| *t)
                .chain(std::iter::once(id))
                .collect();
            return Err(self
                .err(e.loc, format!("recursive SubTree: {}", cycle.join(" -> ")))
                .with_help("a tree cannot contain itself; break the cycle"));
        }
        if self.expanding.len() > MAX_DEPTH {
            return Err(self
                .err(e.loc, "SubTrees are nested too deeply")
                .with_help(format!("btrel expands at most {MAX_DEPTH} nested SubTrees")));
        }
        let instance = self.name_attr(e)?.unwrap_or_else(|| id.to_string());
        let inner = format!("{prefix}{instance}/");
        self.expanding.push((id, e.loc));
        let root = self.elem(tree).children[0];
        let r = self.node(root, parent, depth, path, &inner, under_retry);
        self.expanding.pop();
        r
    }

    /// `num_attempts` / `num_cycles`: required, 1..=1e6.
    fn count(&self, e: &Elem, key: &str) -> Result<usize, TreeError> {
        let Some((n, at)) = self.int_attr(e, key)? else {
            return Err(self
                .err(e.loc, format!("<{}> needs `{key}`", e.name))
                .with_help(format!(
                    "write {key}=\"N\" with N a whole number from 1 to 1000000"
                )));
        };
        if n == -1 {
            return Err(self
                .err(at, format!("{key} = -1 (forever) is not supported"))
                .with_help(format!(
                    "an endless loop has no finite MTTS/MTTF to analyse; give a finite {key} from 1 to 1000000"
                )));
        }
        if !(1..=1_000_000).contains(&n) {
            return Err(self
                .err(at, format!("{key} = {n} is not a valid count"))
                .with_help(format!("{key} must be a whole number from 1 to 1000000")));
        }
        Ok(n as usize)
    }

    fn thresholds(&self, e: &Elem, n: usize) -> Result<(usize, usize), TreeError> {
        let resolve = |key: &str, default: i64, meaning: &str| -> Result<usize, TreeError> {
            let (k, at) = self.int_attr(e, key)?.unwrap_or((default, e.loc));
            let v = if k < 0 { n as i64 + k + 1 } else { k };
            if v < 1 || v > n as i64 {
                return Err(self
                    .err(at, format!("{key} = {k} is not valid for {n} children"))
                    .with_help(format!(
                        "{key} must be from 1 to {n}, or negative (-1 = all children, -2 = all but one, ...): {meaning}"
                    )));
            }
            Ok(v as usize)
        };
        let m = resolve("success_count", -1, "Success at >= M successes")?;
        let f = resolve("failure_count", 1, "Failure at >= F failures")?;
        Ok((m, f))
    }
}

/// Parses a BehaviorTree.CPP v4 XML tree with its params file. `file` and
/// `params_file` name the sources in error messages.
pub fn parse_xml_str(
    xml: &str,
    file: &str,
    params: &str,
    params_file: &str,
) -> Result<Tree, TreeError> {
    for (src, name) in [(xml, file), (params, params_file)] {
        if src.len() > MAX_BYTES {
            return Err(too_large(name, src.len()));
        }
    }
    // the builder recurses once per tree level and SubTree (both bounded);
    // a dedicated stack keeps that independent of the caller's stack
    std::thread::scope(|s| {
        std::thread::Builder::new()
            .name("btrel-xml".into())
            .stack_size(64 << 20)
            .spawn_scoped(s, || parse_here(xml, file, params, params_file))
            .map_err(|e| plain(file, format!("cannot start the parser thread: {e}")))?
            .join()
            .unwrap_or_else(|_| {
                Err(plain(file, "internal error: the XML parser panicked")
                    .with_help("please report this file as a bug"))
            })
    })
}

fn plain(file: &str, message: impl Into<String>) -> TreeError {
    TreeError {
        file: file.into(),
        line: 0,
        column: 0,
        message: message.into(),
        help: None,
        source_line: None,
    }
}

fn too_large(file: &str, len: usize) -> TreeError {
    plain(
        file,
        format!("the file is {len} bytes, more than the limit of {MAX_BYTES} bytes"),
    )
}

fn parse_here(xml: &str, file: &str, params: &str, params_file: &str) -> Result<Tree, TreeError> {
    let doc = Reader {
        src: xml,
        file,
        pos: 0,
        line: 1,
        col: 1,
    }
    .parse()?;
    let err = |at: Loc, msg: String| TreeError::at(file, xml, at, msg);
    let root = &doc.elems[0];
    if root.name != "root" {
        return Err(err(root.loc, format!("the root element is <{}>, not <root>", root.name))
            .with_help("a BT.CPP file is `<root BTCPP_format=\"4\"> <BehaviorTree ID=\"Main\"> ... </BehaviorTree> </root>`"));
    }
    if let Some(t) = root.text {
        return Err(err(t, "text inside <root> has no meaning".into()).with_help("remove the text"));
    }
    let mut b = Builder {
        doc: &doc,
        src: xml,
        file,
        trees: HashMap::new(),
        model: HashMap::new(),
        nodes: Vec::new(),
        used: HashSet::new(),
        name_bytes: 0,
        leaves: Vec::new(),
        expanding: Vec::new(),
        sizes: HashMap::new(),
        sizing: HashSet::new(),
    };
    b.check_attrs(root, &["BTCPP_format", "main_tree_to_execute"], false)?;
    if let Some(a) = root.attr("BTCPP_format") {
        if a.value.trim() != "4" {
            return Err(err(a.loc, format!("BTCPP_format = \"{}\" is not supported", a.value))
                .with_help("btrel reads the BehaviorTree.CPP v4 format (BTCPP_format=\"4\"); convert older files with BT.CPP's converter"));
        }
    }
    let mut order: Vec<(&str, usize)> = Vec::new();
    for &c in &root.children {
        let e = &doc.elems[c];
        match e.name.as_str() {
            "BehaviorTree" => {
                b.check_attrs(e, &["ID"], false)?;
                let id = b.id_attr(e)?;
                if let Some(&prev) = b.trees.get(id) {
                    let p = doc.elems[prev].loc;
                    return Err(
                        err(e.loc, format!("duplicate BehaviorTree ID `{id}`")).with_help(format!(
                            "`{id}` is already defined at line {}, column {}",
                            p.0, p.1
                        )),
                    );
                }
                if let Some(t) = e.text {
                    return Err(err(t, "text inside <BehaviorTree> has no meaning".into())
                        .with_help("remove the text"));
                }
                if e.children.len() != 1 {
                    return Err(err(
                        e.loc,
                        format!(
                            "<BehaviorTree ID=\"{id}\"> must hold exactly one node, found {}",
                            e.children.len()
                        ),
                    )
                    .with_help("wrap several nodes in a <Sequence> or <Fallback>"));
                }
                b.trees.insert(id, c);
                order.push((id, c));
            }
            "TreeNodesModel" => {
                for &m in &e.children {
                    let d = &doc.elems[m];
                    let decl = match d.name.as_str() {
                        "Action" => Decl::Action,
                        "Condition" => Decl::Condition,
                        "Decorator" => Decl::Other("decorator"),
                        "Control" => Decl::Other("control node"),
                        "SubTree" => Decl::Other("SubTree model"),
                        other => {
                            return Err(err(d.loc, format!("unknown <{other}> in <TreeNodesModel>"))
                                .with_help("<TreeNodesModel> declares <Action>, <Condition>, <Decorator>, <Control> and <SubTree> entries"));
                        }
                    };
                    let id = b.id_attr(d)?;
                    if let Some(&prev) = b.model.get(id) {
                        if prev != decl {
                            return Err(err(
                                d.loc,
                                format!("`{id}` is declared twice with different kinds"),
                            )
                            .with_help("declare each ID once, as an Action or a Condition"));
                        }
                    }
                    b.model.insert(id, decl);
                }
            }
            "include" => {
                return Err(err(e.loc, "<include> is not supported".into())
                    .with_help("paste the included trees into this file"));
            }
            other => {
                return Err(err(e.loc, format!("unknown <{other}> in <root>"))
                    .with_help("<root> holds <BehaviorTree> and <TreeNodesModel> elements"));
            }
        }
    }
    let (main_id, main) = match root.attr("main_tree_to_execute") {
        Some(a) => match b.trees.get(a.value.as_str()) {
            Some(&t) => (a.value.as_str(), t),
            None => {
                let ids: Vec<&str> = order.iter().map(|(i, _)| *i).collect();
                let hint = match nearest(&a.value, &ids) {
                    Some(k) => format!("did you mean `{k}`? trees: {}", ids.join(", ")),
                    None => format!("trees: {}", ids.join(", ")),
                };
                return Err(
                    err(a.loc, format!("no <BehaviorTree ID=\"{}\">", a.value)).with_help(hint)
                );
            }
        },
        None => match order.first() {
            Some(&(id, t)) => (id, t),
            None => {
                return Err(err(root.loc, "the file has no <BehaviorTree>".into())
                    .with_help("add <BehaviorTree ID=\"Main\"> holding the root node"))
            }
        },
    };
    let size = b.tree_size(main_id, 0);
    if size > MAX_NODES as u64 {
        return Err(err(
            doc.elems[main].loc,
            format!("the tree has too many nodes after SubTree expansion ({size})"),
        )
        .with_help(format!("btrel accepts at most {MAX_NODES} nodes")));
    }
    b.expanding.push((main_id, doc.elems[main].loc));
    b.node(doc.elems[main].children[0], None, 0, "0".into(), "", false)?;
    b.expanding.pop();

    // parameters
    let table = parse_params(params, params_file)?;
    let perr = |at: Loc, msg: String, help: String| {
        TreeError::at(params_file, params, at, msg).with_help(help)
    };
    let mut used_keys: HashSet<&str> = HashSet::new();
    let mut missing: Vec<(Loc, String)> = Vec::new();
    let leaves = std::mem::take(&mut b.leaves);
    for leaf in &leaves {
        let node = &b.nodes[leaf.node];
        let at = node.location.unwrap_or((0, 0));
        let kind = if leaf.is_action {
            "action"
        } else {
            "condition"
        };
        let who = format!("{kind} `{}` (ID `{}`)", node.name, leaf.id);
        let mut keys = vec![node.name.as_str()];
        for k in leaf.name_attr.iter().chain(std::iter::once(&leaf.id)) {
            if !keys.contains(&k.as_str()) {
                keys.push(k);
            }
        }
        let Some((key, def)) = keys.iter().find_map(|k| table.get_key_value(*k)) else {
            missing.push((
                at,
                format!("{who}: no entry (keys tried: {})", keys.join(", ")),
            ));
            continue;
        };
        used_keys.insert(key.as_str());
        let p = &def.value;
        let new_kind = if leaf.is_action {
            match validate_action(p, &perr)? {
                Ok(a) => NodeKind::Action(a),
                Err(m) => {
                    missing.push((at, format!("{who} (key `{key}`): {m}")));
                    continue;
                }
            }
        } else {
            if let Some(extra) = [&p.pf, &p.mu, &p.nu, &p.tau_s, &p.tau_f]
                .into_iter()
                .flatten()
                .next()
            {
                return Err(perr(
                    sloc(extra),
                    format!("`{key}` is used by {who}, and a condition takes only `ps`"),
                    "a condition returns in zero time; give only its probability of success `ps`"
                        .into(),
                ));
            }
            let Some(ps) = &p.ps else {
                missing.push((
                    at,
                    format!("{who} (key `{key}`): missing `ps` (probability of success in [0, 1])"),
                ));
                continue;
            };
            if !ps.value.is_finite() || !(0.0..=1.0).contains(&ps.value) {
                return Err(perr(
                    sloc(ps),
                    format!("ps = {} is not a probability", ps.value),
                    "ps must be a number in [0, 1]".into(),
                ));
            }
            NodeKind::Condition { ps: ps.value }
        };
        b.nodes[leaf.node].kind = new_kind;
    }
    if let Some(&(first, _)) = missing.first() {
        let lines: Vec<String> = missing
            .iter()
            .map(|((l, c), m)| format!("  {file}:{l}:{c}: {m}"))
            .collect();
        let n = missing.len();
        return Err(err(
            first,
            format!(
                "missing parameters for {n} node{} in {params_file}:\n{}",
                if n == 1 { "" } else { "s" },
                lines.join("\n")
            ),
        )
        .with_help(format!(
            "add an entry per node to {params_file}, keyed by name or ID, e.g. \
             `grasp: {{ps: 0.5, mu: 0.1, nu: 0.2}}` (actions) or `ready: {{ps: 0.9}}` (conditions)"
        )));
    }
    if let Some((key, def)) = table
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
        return Err(perr(
            sloc(def),
            format!("params key `{key}` matches no action or condition"),
            hint,
        ));
    }
    Ok(Tree {
        title: Some(main_id.to_string()),
        nodes: b.nodes,
    })
}

/// Reads a BehaviorTree.CPP v4 XML file and its params file.
pub fn parse_xml_file(xml: &Path, params: &Path) -> Result<Tree, TreeError> {
    let xml_name = xml.display().to_string();
    let params_name = params.display().to_string();
    let xml_src = read_text(xml, &xml_name)?;
    let params_src = read_text(params, &params_name)?;
    parse_xml_str(&xml_src, &xml_name, &params_src, &params_name)
}

fn read_text(path: &Path, file: &str) -> Result<String, TreeError> {
    let io_err = |e: std::io::Error| {
        plain(file, format!("cannot read the file: {e}")).with_help(super::parse::read_help(&e))
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
            file: file.into(),
            line,
            column,
            message: "the file is not valid UTF-8 text".into(),
            help: Some("is this the right file?".into()),
            source_line: None,
        }
    })
}
