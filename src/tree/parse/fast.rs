//! A fast reader for the common subset of the tree format.
//!
//! serde-saphyr reads ~14 MB/s, which is most of the time of a
//! million-leaf `report`. Tree files are almost always written in a small
//! subset of YAML: block mappings and sequences indented with spaces,
//! single-line flow mappings and sequences (`{ps: 0.5, mu: 1}`), plain or
//! simply quoted scalars, and comments. This module reads exactly that
//! subset into the same definitions serde would produce, about ten times
//! faster, and gives up (`None`) on anything else — anchors, aliases, tags,
//! block scalars, multi-line scalars or flows, escapes, tabs, duplicate or
//! unknown keys, values whose YAML type is not obviously a number or a
//! string, nesting deeper than the parser's budget. The caller then parses
//! the file with serde-saphyr, so every document either means the same
//! under both readers or is read by serde-saphyr alone; and every error
//! message (including those found while building the tree) comes from the
//! full parser. Tests check that both readers build identical trees.
//!
//! Size: one concern, a self-contained reader of the common subset (its
//! tokenizer and its value-to-definition mapping are one pass).

use super::super::action::At;
use super::super::action::{ErlangDef, HyperBranchDef, PhaseTypeDef, TimeDef};
use super::defs::{
    ActionDef, ConditionDef, ControlDef, DecoratorDef, FileDef, NodeDef, ParallelDef, RepeatDef,
    RetryDef,
};

/// A YAML value of the subset, with the 1-based line and column of its
/// first character.
struct Value<'a> {
    kind: Kind<'a>,
    line: u32,
    column: u32,
}

enum Kind<'a> {
    Map(Vec<(&'a str, Value<'a>)>),
    Seq(Vec<Value<'a>>),
    Plain(&'a str),
    Quoted(&'a str),
}

/// A non-empty line: its indentation and content (comment removed,
/// trailing blanks trimmed), as byte ranges of the source.
#[derive(Clone, Copy)]
struct Line {
    number: u32,
    indent: usize,
    /// Byte offset of the line's first character.
    line_start: usize,
    start: usize,
    end: usize,
}

/// Reads `source` if it is in the subset; `None` otherwise.
pub(super) fn read(source: &str, max_depth: usize) -> Option<FileDef> {
    let lines = lines(source)?;
    let mut p = Reader {
        src: source,
        lines,
        i: 0,
        max_depth,
    };
    if p.lines.is_empty() || p.lines[0].indent != 0 {
        return None;
    }
    let top = p.block(0, 0)?;
    if p.i != p.lines.len() {
        return None;
    }
    file_def(top)
}

fn lines(src: &str) -> Option<Vec<Line>> {
    let mut out = Vec::with_capacity(src.len() / 40);
    let mut offset = 0;
    for (k, raw) in src.split('\n').enumerate() {
        let line_start = offset;
        offset += raw.len() + 1;
        let raw = raw.strip_suffix('\r').unwrap_or(raw);
        let indent = raw.bytes().take_while(|&b| b == b' ').count();
        let rest = &raw[indent..];
        if rest.starts_with('\t') {
            return None;
        }
        let content = strip_comment(rest)?;
        if content.is_empty() {
            continue;
        }
        // document markers and directives are outside the subset
        if indent == 0 && (content.starts_with("---") || content.starts_with("...")) {
            return None;
        }
        if content.starts_with('%') {
            return None;
        }
        let start = line_start + indent;
        out.push(Line {
            number: u32::try_from(k + 1).ok()?,
            indent,
            line_start,
            start,
            end: start + content.len(),
        });
    }
    Some(out)
}

/// The line's content before a comment, trimmed at the end; `None` when
/// quotes make the comment rule uncertain (e.g. an unterminated quote).
fn strip_comment(s: &str) -> Option<&str> {
    let b = s.as_bytes();
    let mut quote: Option<u8> = None;
    for (i, &c) in b.iter().enumerate() {
        match quote {
            Some(q) if c == q => quote = None,
            Some(_) => {}
            None => match c {
                b'"' | b'\'' => quote = Some(c),
                b'#' if i == 0 || b[i - 1] == b' ' || b[i - 1] == b'\t' => {
                    return Some(s[..i].trim_end());
                }
                _ => {}
            },
        }
    }
    if quote.is_some() {
        return None;
    }
    Some(s.trim_end())
}

struct Reader<'a> {
    src: &'a str,
    lines: Vec<Line>,
    i: usize,
    max_depth: usize,
}

impl<'a> Reader<'a> {
    fn content(&self, i: usize) -> &'a str {
        let l = self.lines[i];
        &self.src[l.start..l.end]
    }

    /// 1-based column of byte offset `at` on line `i`.
    fn column(&self, i: usize, at: usize) -> Option<u32> {
        let l = self.lines[i];
        let before = &self.src[l.line_start..at];
        let n = if before.is_ascii() {
            before.len()
        } else {
            before.chars().count()
        };
        u32::try_from(n + 1).ok()
    }

    fn is_item(s: &str) -> bool {
        s == "-" || s.starts_with("- ")
    }

    /// The block node starting at the current line, indented `indent`.
    fn block(&mut self, indent: usize, depth: usize) -> Option<Value<'a>> {
        if depth > 3 * self.max_depth + 4 {
            return None;
        }
        if Self::is_item(self.content(self.i)) {
            self.seq(indent, depth)
        } else {
            self.map(indent, depth)
        }
    }

    fn seq(&mut self, indent: usize, depth: usize) -> Option<Value<'a>> {
        let line = self.lines[self.i].number;
        let column = self.column(self.i, self.lines[self.i].start)?;
        let mut items = Vec::new();
        while self.i < self.lines.len()
            && self.lines[self.i].indent == indent
            && Self::is_item(self.content(self.i))
        {
            let content = self.content(self.i);
            let after = &content[1..];
            let rest = after.trim_start();
            if rest.is_empty() {
                return None;
            }
            let offset = self.lines[self.i].start + 1 + (after.len() - rest.len());
            if starts_inline(rest) {
                items.push(self.inline(offset, rest, depth)?);
                self.i += 1;
                if self.i < self.lines.len() && self.lines[self.i].indent > indent {
                    return None;
                }
            } else {
                // "- key: value": a block mapping whose keys align with `key`
                let new_indent = offset - self.lines[self.i].line_start;
                let l = &mut self.lines[self.i];
                l.indent = new_indent;
                l.start = offset;
                items.push(self.map(new_indent, depth + 1)?);
            }
        }
        if self.i < self.lines.len() && self.lines[self.i].indent > indent {
            return None;
        }
        Some(Value {
            kind: Kind::Seq(items),
            line,
            column,
        })
    }

    fn map(&mut self, indent: usize, depth: usize) -> Option<Value<'a>> {
        let line = self.lines[self.i].number;
        let column = self.column(self.i, self.lines[self.i].start)?;
        let mut entries: Vec<(&'a str, Value<'a>)> = Vec::new();
        while self.i < self.lines.len() && self.lines[self.i].indent == indent {
            let content = self.content(self.i);
            if Self::is_item(content) {
                return None;
            }
            let colon = content.find(':')?;
            let key = &content[..colon];
            if !is_key(key) || entries.iter().any(|(k, _)| *k == key) {
                return None;
            }
            let after = &content[colon + 1..];
            if !after.is_empty() && !after.starts_with(' ') {
                return None;
            }
            let rest = after.trim_start();
            let value = if rest.is_empty() {
                self.i += 1;
                if self.i >= self.lines.len() {
                    return None;
                }
                let next = self.lines[self.i];
                if next.indent > indent {
                    self.block(next.indent, depth + 1)?
                } else if next.indent == indent && Self::is_item(self.content(self.i)) {
                    self.seq(indent, depth + 1)?
                } else {
                    return None; // an empty (null) value
                }
            } else {
                let offset = self.lines[self.i].start + colon + 1 + (after.len() - rest.len());
                if !starts_inline(rest) {
                    return None;
                }
                let v = self.inline(offset, rest, depth)?;
                self.i += 1;
                if self.i < self.lines.len() && self.lines[self.i].indent > indent {
                    return None; // a continuation line
                }
                v
            };
            entries.push((key, value));
        }
        if self.i < self.lines.len() && self.lines[self.i].indent > indent {
            return None;
        }
        Some(Value {
            kind: Kind::Map(entries),
            line,
            column,
        })
    }

    /// A flow collection or scalar that fills the rest of the current line.
    fn inline(&self, offset: usize, text: &'a str, depth: usize) -> Option<Value<'a>> {
        let mut f = Flow {
            text,
            pos: 0,
            line: self.lines[self.i].number,
            base_column: self.column(self.i, offset)?,
            ascii: text.is_ascii(),
            max_depth: 3 * self.max_depth + 4,
        };
        let v = if text.starts_with(['{', '[', '"', '\'']) {
            f.value(false, depth)?
        } else {
            // a plain scalar in block context: the whole rest of the line
            if !plain_start(text) || text.bytes().any(|c| c == b':' || c == b'#') {
                return None;
            }
            f.pos = text.len();
            Value {
                kind: Kind::Plain(text),
                line: f.line,
                column: f.base_column,
            }
        };
        f.skip_spaces();
        (f.pos == text.len()).then_some(v)
    }
}

/// Whether a value written after `key: ` or `- ` is inline (not the first
/// key of a block mapping).
fn starts_inline(rest: &str) -> bool {
    if rest.starts_with(['{', '[', '"', '\'']) {
        return true;
    }
    // "key: value" or "key:" opens a block mapping
    !(rest.contains(": ") || rest.ends_with(':'))
}

fn is_key(k: &str) -> bool {
    // `T`: a phase-type law's sub-generator (the one upper-case key)
    if k == "T" {
        return true;
    }
    let mut b = k.bytes();
    matches!(b.next(), Some(c) if c.is_ascii_lowercase() || c == b'_')
        && b.all(|c| c.is_ascii_lowercase() || c.is_ascii_digit() || c == b'_')
}

/// Whether a plain scalar may start this way (no YAML indicator).
fn plain_start(s: &str) -> bool {
    let b = s.as_bytes();
    match b.first() {
        None => false,
        Some(b'-' | b'?' | b':') => b.get(1).is_some_and(|&c| c != b' '),
        Some(c) => !b",[]{}#&*!|>'\"%@`".contains(c),
    }
}

/// Whether a plain scalar in a flow collection contains a character that
/// YAML may treat specially there (flow indicators, `:`, `#`, quotes,
/// anchors, tags...): such scalars are left to the full parser. (In block
/// context only `:` and `#` are refused.)
fn has_indicator(s: &str) -> bool {
    s.bytes()
        .skip(1)
        .any(|c| b"[]{}:#&*!|>'\"%@`?,".contains(&c))
}

struct Flow<'a> {
    text: &'a str,
    pos: usize,
    line: u32,
    base_column: u32,
    ascii: bool,
    max_depth: usize,
}

impl<'a> Flow<'a> {
    fn skip_spaces(&mut self) {
        while self.text.as_bytes().get(self.pos) == Some(&b' ') {
            self.pos += 1;
        }
    }

    fn column(&self, at: usize) -> u32 {
        let n = if self.ascii {
            at
        } else {
            self.text[..at].chars().count()
        };
        self.base_column + n as u32
    }

    fn peek(&self) -> Option<u8> {
        self.text.as_bytes().get(self.pos).copied()
    }

    fn value(&mut self, in_flow: bool, depth: usize) -> Option<Value<'a>> {
        if depth > self.max_depth {
            return None;
        }
        self.skip_spaces();
        let (line, column) = (self.line, self.column(self.pos));
        let at = |kind| Value { kind, line, column };
        match self.peek()? {
            b'{' => {
                self.pos += 1;
                let mut entries: Vec<(&'a str, Value<'a>)> = Vec::new();
                loop {
                    self.skip_spaces();
                    if self.peek()? == b'}' {
                        self.pos += 1;
                        return Some(at(Kind::Map(entries)));
                    }
                    let rest = &self.text[self.pos..];
                    let colon = rest.find(':')?;
                    let key = &rest[..colon];
                    if !is_key(key) || entries.iter().any(|(k, _)| *k == key) {
                        return None;
                    }
                    self.pos += colon + 1;
                    if self.peek()? != b' ' {
                        return None;
                    }
                    let v = self.value(true, depth + 1)?;
                    entries.push((key, v));
                    self.skip_spaces();
                    match self.peek()? {
                        b',' => self.pos += 1,
                        b'}' => {}
                        _ => return None,
                    }
                }
            }
            b'[' => {
                self.pos += 1;
                let mut items = Vec::new();
                loop {
                    self.skip_spaces();
                    if self.peek()? == b']' {
                        self.pos += 1;
                        return Some(at(Kind::Seq(items)));
                    }
                    items.push(self.value(true, depth + 1)?);
                    self.skip_spaces();
                    match self.peek()? {
                        b',' => self.pos += 1,
                        b']' => {}
                        _ => return None,
                    }
                }
            }
            q @ (b'"' | b'\'') => {
                let rest = &self.text[self.pos + 1..];
                let end = rest.find(q as char)?;
                let s = &rest[..end];
                // escapes and doubled quotes are left to the full parser
                if s.contains('\\') || rest[end + 1..].starts_with(q as char) {
                    return None;
                }
                self.pos += end + 2;
                Some(at(Kind::Quoted(s)))
            }
            _ if in_flow => {
                let rest = &self.text[self.pos..];
                let end = rest.find([',', '}', ']']).unwrap_or(rest.len());
                // a scalar running to the end of the line is outside the subset
                if end == rest.len() {
                    return None;
                }
                let s = rest[..end].trim_end();
                if !plain_start(s) || has_indicator(s) {
                    return None;
                }
                self.pos += end;
                Some(at(Kind::Plain(s)))
            }
            _ => None,
        }
    }
}

// ---- from values to the serde definitions (same shapes, same checks) ----

fn file_def(v: Value) -> Option<FileDef> {
    let mut name = None;
    let mut tree = None;
    for (k, v) in map(v)? {
        match k {
            "name" => name = Some(string(v)?.value),
            "tree" => tree = Some(node(v)?),
            _ => return None,
        }
    }
    Some(FileDef { name, tree: tree? })
}

fn map(v: Value<'_>) -> Option<Vec<(&str, Value<'_>)>> {
    match v.kind {
        Kind::Map(e) => Some(e),
        _ => None,
    }
}

fn node(v: Value) -> Option<At<NodeDef>> {
    let (line, column) = (v.line, v.column);
    let mut entries = map(v)?;
    if entries.len() != 1 {
        return None;
    }
    let (kind, body) = entries.pop()?;
    let def = match kind {
        "sequence" => NodeDef::Sequence(control(body)?),
        "fallback" => NodeDef::Fallback(control(body)?),
        "parallel" => NodeDef::Parallel(parallel(body)?),
        "action" => NodeDef::Action(Box::new(action(body)?)),
        "condition" => NodeDef::Condition(condition(body)?),
        "inverter" => NodeDef::Inverter(Box::new(decorator(body)?)),
        "force_success" => NodeDef::ForceSuccess(Box::new(decorator(body)?)),
        "force_failure" => NodeDef::ForceFailure(Box::new(decorator(body)?)),
        "retry" => NodeDef::Retry(Box::new(retry(body)?)),
        "repeat" => NodeDef::Repeat(Box::new(repeat(body)?)),
        "until_failure" => NodeDef::UntilFailure(Box::new(decorator(body)?)),
        "until_success" => NodeDef::UntilSuccess(Box::new(decorator(body)?)),
        _ => return None,
    };
    Some(At {
        value: def,
        line,
        column,
    })
}

fn children(v: Value) -> Option<At<Vec<At<NodeDef>>>> {
    let (line, column) = (v.line, v.column);
    match v.kind {
        Kind::Seq(items) => Some(At {
            value: items.into_iter().map(node).collect::<Option<Vec<_>>>()?,
            line,
            column,
        }),
        _ => None,
    }
}

fn number(v: Value) -> Option<At<f64>> {
    let s = match v.kind {
        Kind::Plain(s) => s,
        _ => return None,
    };
    if !is_decimal(s) {
        return None;
    }
    Some(At {
        value: s.parse().ok()?,
        line: v.line,
        column: v.column,
    })
}

/// `-?D+(.D+)?([eE][-+]?D+)?` without leading zeros: a number under every
/// YAML schema.
fn is_decimal(s: &str) -> bool {
    let b = s.as_bytes();
    let mut i = usize::from(b.first() == Some(&b'-'));
    let digits = |i: &mut usize| {
        let s = *i;
        while *i < b.len() && b[*i].is_ascii_digit() {
            *i += 1;
        }
        *i - s
    };
    let int_start = i;
    let n = digits(&mut i);
    if n == 0 || (n > 1 && b[int_start] == b'0') {
        return false;
    }
    if i < b.len() && b[i] == b'.' {
        i += 1;
        if digits(&mut i) == 0 {
            return false;
        }
    }
    if i < b.len() && (b[i] == b'e' || b[i] == b'E') {
        i += 1;
        if i < b.len() && (b[i] == b'-' || b[i] == b'+') {
            i += 1;
        }
        if digits(&mut i) == 0 {
            return false;
        }
    }
    i == b.len()
}

fn string(v: Value) -> Option<At<String>> {
    let s = match v.kind {
        Kind::Quoted(s) => s,
        // plain scalars that YAML might read as null, a boolean or a number
        // are left to the full parser
        Kind::Plain(s) => {
            let c = s.chars().next()?;
            let lower = s.to_ascii_lowercase();
            if !(c.is_alphabetic() || c == '_')
                || matches!(
                    lower.as_str(),
                    "null" | "true" | "false" | "yes" | "no" | "on" | "off" | "y" | "n"
                )
                || lower.starts_with(".")
            {
                return None;
            }
            s
        }
        _ => return None,
    };
    Some(At {
        value: s.to_string(),
        line: v.line,
        column: v.column,
    })
}

/// Fills the named fields of a definition from a mapping; `None` on an
/// unknown key.
fn fields<'a>(v: Value<'a>, mut put: impl FnMut(&'a str, Value<'a>) -> Option<bool>) -> Option<()> {
    for (k, v) in map(v)? {
        if !put(k, v)? {
            return None;
        }
    }
    Some(())
}

fn control(v: Value) -> Option<ControlDef> {
    let (mut name, mut kids) = (None, None);
    fields(v, |k, v| {
        match k {
            "name" => name = Some(string(v)?),
            "children" => kids = Some(children(v)?),
            _ => return Some(false),
        }
        Some(true)
    })?;
    Some(ControlDef {
        name,
        children: kids?,
    })
}

fn parallel(v: Value) -> Option<ParallelDef> {
    let (mut name, mut kids, mut m, mut f) = (None, None, None, None);
    fields(v, |k, v| {
        match k {
            "name" => name = Some(string(v)?),
            "children" => kids = Some(children(v)?),
            "success_threshold" => m = Some(number(v)?),
            "failure_threshold" => f = Some(number(v)?),
            _ => return Some(false),
        }
        Some(true)
    })?;
    Some(ParallelDef {
        name,
        success_threshold: m,
        failure_threshold: f,
        children: kids?,
    })
}

fn action(v: Value) -> Option<ActionDef> {
    let mut d = ActionDef {
        name: None,
        ps: At {
            value: f64::NAN,
            line: 0,
            column: 0,
        },
        pf: None,
        mu: None,
        nu: None,
        tau_s: None,
        tau_f: None,
        success_time: None,
        failure_time: None,
    };
    let mut has_ps = false;
    fields(v, |k, v| {
        match k {
            "name" => d.name = Some(string(v)?),
            "ps" => {
                d.ps = number(v)?;
                has_ps = true;
            }
            "pf" => d.pf = Some(number(v)?),
            "mu" => d.mu = Some(number(v)?),
            "nu" => d.nu = Some(number(v)?),
            "tau_s" => d.tau_s = Some(number(v)?),
            "tau_f" => d.tau_f = Some(number(v)?),
            "success_time" => d.success_time = Some(time_law(v)?),
            "failure_time" => d.failure_time = Some(time_law(v)?),
            _ => return Some(false),
        }
        Some(true)
    })?;
    has_ps.then_some(d)
}

/// A time law (`{erlang: {k: 3, rate: 0.5}}`, `{shift: 2, rate: 1}`, ...);
/// `None` on an unknown or repeated key, which the full parser reports.
fn time_law(v: Value) -> Option<At<TimeDef>> {
    let (line, column) = (v.line, v.column);
    let mut d = TimeDef::default();
    fields(v, |k, v| {
        let slot_taken = match k {
            "rate" => d.rate.replace(number(v)?).is_some(),
            "fixed" => d.fixed.replace(number(v)?).is_some(),
            "shift" => d.shift.replace(number(v)?).is_some(),
            "erlang" => {
                let (el, ec) = (v.line, v.column);
                let (mut kk, mut rate) = (None, None);
                fields(v, |k, v| {
                    let taken = match k {
                        "k" => kk.replace(number(v)?).is_some(),
                        "rate" => rate.replace(number(v)?).is_some(),
                        _ => return Some(false),
                    };
                    Some(!taken)
                })?;
                d.erlang
                    .replace(At {
                        value: ErlangDef {
                            k: kk?,
                            rate: rate?,
                        },
                        line: el,
                        column: ec,
                    })
                    .is_some()
            }
            "hypoexponential" => {
                let (hl, hc) = (v.line, v.column);
                let Kind::Seq(items) = v.kind else {
                    return None;
                };
                let rates = items.into_iter().map(number).collect::<Option<Vec<_>>>()?;
                d.hypoexponential
                    .replace(At {
                        value: rates,
                        line: hl,
                        column: hc,
                    })
                    .is_some()
            }
            "hyperexponential" => {
                let (hl, hc) = (v.line, v.column);
                let Kind::Seq(items) = v.kind else {
                    return None;
                };
                let branches = items
                    .into_iter()
                    .map(|b| {
                        let (bl, bc) = (b.line, b.column);
                        let (mut p, mut rate) = (None, None);
                        fields(b, |k, v| {
                            let taken = match k {
                                "p" => p.replace(number(v)?).is_some(),
                                "rate" => rate.replace(number(v)?).is_some(),
                                _ => return Some(false),
                            };
                            Some(!taken)
                        })?;
                        Some(At {
                            value: HyperBranchDef { p: p?, rate: rate? },
                            line: bl,
                            column: bc,
                        })
                    })
                    .collect::<Option<Vec<_>>>()?;
                d.hyperexponential
                    .replace(At {
                        value: branches,
                        line: hl,
                        column: hc,
                    })
                    .is_some()
            }
            "phase_type" => {
                let (pl, pc) = (v.line, v.column);
                let (mut alpha, mut t) = (None, None);
                fields(v, |k, v| {
                    let taken = match k {
                        "alpha" => alpha.replace(numbers(v)?).is_some(),
                        "T" => {
                            let (tl, tc) = (v.line, v.column);
                            let Kind::Seq(rows) = v.kind else {
                                return None;
                            };
                            let rows = rows.into_iter().map(numbers).collect::<Option<Vec<_>>>()?;
                            t.replace(At {
                                value: rows,
                                line: tl,
                                column: tc,
                            })
                            .is_some()
                        }
                        _ => return Some(false),
                    };
                    Some(!taken)
                })?;
                d.phase_type
                    .replace(At {
                        value: PhaseTypeDef {
                            alpha: alpha?,
                            t: t?,
                        },
                        line: pl,
                        column: pc,
                    })
                    .is_some()
            }
            _ => return Some(false),
        };
        Some(!slot_taken)
    })?;
    Some(At {
        value: d,
        line,
        column,
    })
}

/// A flow sequence of numbers, located.
fn numbers(v: Value) -> Option<At<Vec<At<f64>>>> {
    let (line, column) = (v.line, v.column);
    let Kind::Seq(items) = v.kind else {
        return None;
    };
    Some(At {
        value: items.into_iter().map(number).collect::<Option<Vec<_>>>()?,
        line,
        column,
    })
}

fn condition(v: Value) -> Option<ConditionDef> {
    let (mut name, mut ps) = (None, None);
    fields(v, |k, v| {
        match k {
            "name" => name = Some(string(v)?),
            "ps" => ps = Some(number(v)?),
            _ => return Some(false),
        }
        Some(true)
    })?;
    Some(ConditionDef { name, ps: ps? })
}

fn decorator(v: Value) -> Option<DecoratorDef> {
    let (mut name, mut child) = (None, None);
    fields(v, |k, v| {
        match k {
            "name" => name = Some(string(v)?),
            "child" => child = Some(node(v)?),
            _ => return Some(false),
        }
        Some(true)
    })?;
    Some(DecoratorDef {
        name,
        child: child?,
    })
}

/// A repetition decorator's name, count (under `key`) and child.
#[allow(clippy::type_complexity)]
fn repetition(v: Value<'_>, key: &str) -> Option<(Option<At<String>>, At<f64>, At<NodeDef>)> {
    let (mut name, mut count, mut child) = (None, None, None);
    fields(v, |k, v| {
        match k {
            "name" => name = Some(string(v)?),
            "child" => child = Some(node(v)?),
            _ if k == key => count = Some(number(v)?),
            _ => return Some(false),
        }
        Some(true)
    })?;
    Some((name, count?, child?))
}

fn retry(v: Value) -> Option<RetryDef> {
    let (name, attempts, child) = repetition(v, "attempts")?;
    Some(RetryDef {
        name,
        attempts,
        child,
    })
}

fn repeat(v: Value) -> Option<RepeatDef> {
    let (name, times, child) = repetition(v, "times")?;
    Some(RepeatDef { name, times, child })
}
