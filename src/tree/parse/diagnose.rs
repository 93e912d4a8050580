//! serde-saphyr's errors as located messages that say what to write
//! instead: unknown node kinds and keys with the nearest valid one, common
//! indentation and syntax mistakes, missing keys as missing parameters.

use super::super::error::{nearest, TreeError, TreeErrorKind as Kind};
use super::defs::NODE_KINDS;
use super::ParseLimits;

pub(super) fn yaml_error(
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
