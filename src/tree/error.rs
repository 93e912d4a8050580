//! Located errors for invalid tree files.

use std::fmt;

/// What kind of problem a [`TreeError`] reports, for callers that react to
/// it (exit codes, tests) without reading the message.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum TreeErrorKind {
    /// The text is not valid XML or YAML (also: not UTF-8, an empty file).
    Syntax,
    /// Well-formed, but not a tree: an unknown key, element or attribute, a
    /// required attribute or key missing, a wrong number of children, a
    /// duplicate or recursive definition.
    Structure,
    /// Node types btrel does not know (leaves need no declaration; a node
    /// with children must be a known control node or decorator), with or
    /// without SubTrees defined in no file read.
    UnknownNode,
    /// SubTrees whose `<BehaviorTree>` is defined in no file read (and no
    /// unknown node type): fixed by reading the file that defines them.
    UndefinedSubTree,
    /// Parameters the params file (or a YAML leaf) lacks: leaf parameters,
    /// blackboard values known only at run time. Fixed by adding entries.
    MissingParameter,
    /// A value of the wrong type or out of range (a probability above 1, a
    /// negative count, an unused params key).
    InvalidValue,
    /// Known node types (or attributes) that btrel has no stochastic
    /// meaning for yet: the input is valid, the analysis is not available.
    NoMeaning,
    /// Over one of btrel's size limits (bytes, nodes, depth, files).
    Budget,
    /// A file or folder cannot be read.
    Io,
    /// btrel failed (a parser thread could not start or panicked).
    Internal,
}

/// An invalid tree file: where, what, and how to fix it.
///
/// Displays as `file:line:column: message`, then the offending source line
/// with a caret, then a `help:` line when there is advice.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error, miette::Diagnostic)]
pub struct TreeError {
    /// What kind of problem this is.
    pub kind: TreeErrorKind,
    /// The file name as given by the user.
    pub file: String,
    /// 1-based line, 0 if unknown.
    pub line: usize,
    /// 1-based column (in characters), 0 if unknown.
    pub column: usize,
    /// What is wrong.
    pub message: String,
    /// How to fix it (accepted range, nearest valid key, ...).
    #[help]
    pub help: Option<String>,
    /// The source line, for display.
    pub source_line: Option<String>,
}

impl TreeError {
    /// An error at a location in `source`.
    pub fn at(
        kind: TreeErrorKind,
        file: &str,
        source: &str,
        (line, column): (usize, usize),
        message: impl Into<String>,
    ) -> TreeError {
        let source_line = (line > 0)
            .then(|| source.lines().nth(line - 1))
            .flatten()
            .map(|l| l.chars().take(200).collect());
        TreeError {
            kind,
            file: file.to_string(),
            line,
            column,
            message: message.into(),
            help: None,
            source_line,
        }
    }

    /// An error about a whole file (no line or column).
    pub fn file(kind: TreeErrorKind, file: &str, message: impl Into<String>) -> TreeError {
        TreeError {
            kind,
            file: file.to_string(),
            line: 0,
            column: 0,
            message: message.into(),
            help: None,
            source_line: None,
        }
    }

    /// Adds advice.
    pub fn with_help(mut self, help: impl Into<String>) -> TreeError {
        self.help = Some(help.into());
        self
    }
}

impl fmt::Display for TreeError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.line > 0 {
            write!(
                f,
                "{}:{}:{}: {}",
                self.file, self.line, self.column, self.message
            )?;
        } else {
            write!(f, "{}: {}", self.file, self.message)?;
        }
        if let Some(src) = &self.source_line {
            let num = self.line.to_string();
            let pad = " ".repeat(num.len());
            write!(f, "\n {pad} |\n {num} | {src}")?;
            if self.column > 0 && self.column <= src.chars().count() + 1 {
                // keep tabs so the caret lines up
                let lead: String = src
                    .chars()
                    .take(self.column - 1)
                    .map(|c| if c == '\t' { '\t' } else { ' ' })
                    .collect();
                write!(f, "\n {pad} | {lead}^")?;
            }
        }
        if let Some(h) = &self.help {
            write!(f, "\n  help: {h}")?;
        }
        Ok(())
    }
}

/// The candidate closest to `word` by edit distance, if it is close enough
/// to be a plausible typo.
pub fn nearest<'a>(word: &str, candidates: &[&'a str]) -> Option<&'a str> {
    candidates
        .iter()
        .map(|&c| (levenshtein(&word.to_lowercase(), c), c))
        .min()
        .filter(|&(d, c)| d <= 2.max(c.len() / 3))
        .map(|(_, c)| c)
}

fn levenshtein(a: &str, b: &str) -> usize {
    let b: Vec<char> = b.chars().collect();
    let mut prev: Vec<usize> = (0..=b.len()).collect();
    for (i, ca) in a.chars().enumerate() {
        let mut cur = vec![i + 1; b.len() + 1];
        for (j, &cb) in b.iter().enumerate() {
            cur[j + 1] = (prev[j] + usize::from(ca != cb))
                .min(prev[j + 1] + 1)
                .min(cur[j] + 1);
        }
        prev = cur;
    }
    prev[b.len()]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nearest_key() {
        let keys = ["name", "ps", "pf", "mu", "nu", "tau_s", "tau_f"];
        assert_eq!(nearest("mux", &keys), Some("mu"));
        assert_eq!(nearest("tau_S", &keys), Some("tau_s"));
        assert_eq!(nearest("probability", &keys), None);
        assert_eq!(
            nearest("fallbak", &["sequence", "fallback", "parallel"]),
            Some("fallback")
        );
    }

    #[test]
    fn display_has_location_caret_and_help() {
        let e = TreeError::at(
            TreeErrorKind::InvalidValue,
            "t.yaml",
            "a: 1\nps: 2\n",
            (2, 5),
            "ps = 2 is out of range",
        )
        .with_help("ps must be in [0, 1]");
        let s = e.to_string();
        assert!(s.starts_with("t.yaml:2:5: ps = 2 is out of range"));
        assert!(s.contains("2 | ps: 2"));
        assert!(s.contains("    ^"));
        assert!(s.ends_with("help: ps must be in [0, 1]"));
        assert_eq!(e.kind, TreeErrorKind::InvalidValue);
    }

    #[test]
    fn file_error_has_no_location() {
        let e = TreeError::file(TreeErrorKind::Io, "t.xml", "cannot read the file");
        assert_eq!(e.to_string(), "t.xml: cannot read the file");
        assert_eq!((e.line, e.column, e.kind), (0, 0, TreeErrorKind::Io));
    }
}
