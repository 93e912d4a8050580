//! Reading the TREE argument: YAML or BehaviorTree.CPP XML, from a file or
//! standard input, with the global `--input-format`, `--params` and
//! `--include` options; finding nodes by name or path.

use std::io;
use std::path::{Path, PathBuf};

use btrel::tree::{parse_file, Tree};

use super::advice;
use super::args::InputFormat;
use super::Failure;

/// How tree files are read: the global options, typed.
pub(super) struct InputOptions {
    pub(super) format: Option<InputFormat>,
    pub(super) params: Option<PathBuf>,
    pub(super) include: Vec<PathBuf>,
}

/// The name standard input goes by in messages.
pub(super) const STDIN_NAME: &str = "<stdin>";

/// Reads standard input (at most the parser's size limit, plus one byte so
/// that a larger input is recognised as such).
pub(super) fn read_stdin() -> Result<Vec<u8>, Failure> {
    use std::io::Read;
    let limit = btrel::tree::ParseLimits::default().max_bytes as u64;
    let mut bytes = Vec::new();
    io::stdin()
        .lock()
        .take(limit + 1)
        .read_to_end(&mut bytes)
        .map_err(|e| Failure::input(format!("{STDIN_NAME}: cannot read standard input: {e}")))?;
    Ok(bytes)
}

/// An XML tree's params file: each node's key in it, and the file's text and name.
pub(super) struct ParamsSource {
    pub(super) keys: Vec<Option<String>>,
    pub(super) text: String,
    pub(super) name: String,
}

impl InputOptions {
    /// Whether any of the tree-input options (`--input-format`, `--params`,
    /// `--include`) was given.
    pub(super) fn given(&self) -> bool {
        self.format.is_some() || self.params.is_some() || !self.include.is_empty()
    }

    /// Reads a tree.
    pub(super) fn load(&self, path: &Path) -> Result<Tree, Failure> {
        self.load_keyed(path).map(|(tree, _)| tree)
    }

    /// Reads a tree; for an XML tree also where its parameters came from.
    pub(super) fn load_keyed(&self, path: &Path) -> Result<(Tree, Option<ParamsSource>), Failure> {
        load_keyed(self.format, self.params.clone(), &self.include, path)
    }
}

/// Reads a tree; for an XML tree also where its parameters came from.
fn load_keyed(
    format: Option<InputFormat>,
    params: Option<PathBuf>,
    include: &[PathBuf],
    path: &Path,
) -> Result<(Tree, Option<ParamsSource>), Failure> {
    let stdin = path == Path::new("-");
    let xml = match format {
        Some(f) => f == InputFormat::Xml,
        None => path
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("xml")),
    };
    if !xml {
        if params.is_some() {
            return Err(Failure::input(
                "--params goes with an XML tree (YAML trees carry their parameters): remove --params, or add --input-format xml",
            ));
        }
        if !include.is_empty() {
            return Err(Failure::input(
                "--include goes with an XML tree (a YAML tree is one file): remove --include",
            ));
        }
        if stdin {
            return btrel::tree::parse_bytes(read_stdin()?, STDIN_NAME)
                .map(|t| (t, None))
                .map_err(Failure::input);
        }
        return parse_file(path).map(|t| (t, None)).map_err(Failure::input);
    }
    if stdin {
        let Some(params) = params else {
            return Err(Failure::input(format!(
                "{STDIN_NAME}: an XML tree read from standard input needs its parameters file: give it with --params FILE"
            )));
        };
        let params_text = std::fs::read(&params).map_err(|e| {
            Failure::input(format!("{}: cannot read the file: {e}", params.display()))
        })?;
        let name = params.display().to_string();
        let params_text =
            btrel::tree::parse::text_from_bytes(params_text, &name).map_err(Failure::input)?;
        let xml_text = btrel::tree::parse::text_from_bytes(read_stdin()?, STDIN_NAME)
            .map_err(Failure::input)?;
        let keyed =
            btrel::tree::xml::parse_xml_str_keyed(&xml_text, STDIN_NAME, &params_text, &name)
                .map_err(Failure::input)?;
        return Ok((
            keyed.tree,
            Some(ParamsSource {
                keys: keyed.keys,
                text: params_text,
                name,
            }),
        ));
    }
    let params = params.unwrap_or_else(|| path.with_extension("params.yaml"));
    if !params.exists() {
        return Err(Failure::input(format!(
            "{}: an XML tree needs a parameters file; {} does not exist (give one with --params)",
            path.display(),
            params.display()
        )));
    }
    for inc in include {
        if !inc.exists() {
            return Err(Failure::input(format!(
                "{}: --include {} does not exist",
                path.display(),
                inc.display()
            )));
        }
    }
    let keyed =
        btrel::tree::xml::parse_xml_files_keyed(path, &params, include).map_err(|mut e| {
            if e.kind == btrel::tree::error::TreeErrorKind::UndefinedSubTree {
                e.help = Some(advice::include_subtree(e.help.take()));
            }
            if btrel::tree::xml::is_unsupported(&e) {
                Failure::analysis(e)
            } else {
                Failure::input(e)
            }
        })?;
    let name = params.display().to_string();
    let text = std::fs::read(&params)
        .map_err(|e| Failure::input(format!("{name}: cannot read the file: {e}")))?;
    let text = btrel::tree::parse::text_from_bytes(text, &name).map_err(Failure::input)?;
    Ok((
        keyed.tree,
        Some(ParamsSource {
            keys: keyed.keys,
            text,
            name,
        }),
    ))
}

/// Most "can run forever" warnings printed (the rest are counted).
pub(super) const ENDLESS_WARNINGS: usize = 3;

/// Warns (standard error) about the loops of `tree` that never return when
/// they run ([`btrel::sim::endless_loops`]): where P(never returns) > 0
/// comes from.
pub(super) fn warn_endless(tree: &Tree) {
    let endless = btrel::sim::endless_loops(tree);
    for (_, why) in endless.iter().take(ENDLESS_WARNINGS) {
        eprintln!("warning: {why}");
    }
    if endless.len() > ENDLESS_WARNINGS {
        eprintln!(
            "warning: and {} more such nodes (copies made by RecoveryNode, RetryUntilSuccessful, \
             SubTrees): runs that reach one never return",
            endless.len() - ENDLESS_WARNINGS
        );
    }
    if endless.iter().any(|(_, why)| why.contains("restart loop")) {
        eprintln!("{}", advice::RESTART_LOOP);
    }
}

/// `n thing` / `n things`.
pub(super) fn plural(n: usize, one: &str, many: &str) -> String {
    format!("{n} {}", if n == 1 { one } else { many })
}

/// A TREE argument as messages name it.
pub(super) fn display_path(path: &Path) -> String {
    if path == Path::new("-") {
        STDIN_NAME.to_string()
    } else {
        path.display().to_string()
    }
}

/// The nodes named (by name or path) in `names`.
pub(super) fn find_nodes(
    tree: &Tree,
    names: &[String],
    file: &Path,
) -> Result<Vec<usize>, Failure> {
    names
        .iter()
        .map(|n| {
            tree.find(n).ok_or_else(|| {
                let all: Vec<&str> = tree.nodes().iter().map(|x| x.name.as_str()).collect();
                let hint = advice::unknown_node(n, &all);
                Failure::input(format!(
                    "no node named '{n}' in {}; {hint}",
                    display_path(file)
                ))
            })
        })
        .collect()
}
