//! Files and includes: the XML files of a tree (the main file first, then
//! `<include>`d files and `--include` files or folders), each lexed once.

use super::*;

/// The BehaviorTree.CPP format a file declares (`BTCPP_format`).
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub(super) enum Format {
    V3,
    V4,
    Unspecified,
}

/// One XML file of the tree: the main file is source 0, included files
/// follow.
pub(super) struct Source {
    pub(super) name: String,
    pub(super) text: String,
    pub(super) format: Format,
}

/// Most XML files (the main file and everything it includes).
pub(crate) const MAX_FILES: usize = 10_000;

/// The XML files of a tree, read and parsed.
pub(super) struct Files {
    pub(super) sources: Vec<Source>,
    pub(super) elems: Vec<Elem>,
    /// Root element of each source.
    pub(super) roots: Vec<usize>,
    /// Canonical paths of the files read from disk.
    pub(super) seen: HashSet<std::path::PathBuf>,
    pub(super) bytes: usize,
}

impl Files {
    pub(super) fn new() -> Files {
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
    pub(super) fn add(
        &mut self,
        name: String,
        text: String,
        dir: Option<&Path>,
    ) -> Result<(), TreeError> {
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
    pub(super) fn add_file(&mut self, path: &Path) -> Result<(), TreeError> {
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
    pub(super) fn add_include(&mut self, path: &Path) -> Result<(), TreeError> {
        let name = path.display().to_string();
        if path.is_dir() {
            let rd = std::fs::read_dir(path).map_err(|e| {
                TreeError::file(Kind::Io, &name, format!("cannot read the folder: {e}"))
                    .with_help(crate::tree::parse::read_help(&e))
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

pub(super) fn too_large(file: &str, len: usize) -> TreeError {
    TreeError::file(
        Kind::Budget,
        file,
        format!("the file is {len} bytes, more than the limit of {MAX_BYTES} bytes"),
    )
}

pub(super) fn read_text(path: &Path, file: &str) -> Result<String, TreeError> {
    let io_err = |e: std::io::Error| {
        TreeError::file(Kind::Io, file, format!("cannot read the file: {e}"))
            .with_help(crate::tree::parse::read_help(&e))
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

#[cfg(test)]
mod tests {
    use super::*;

    fn add(files: &mut Files, name: &str, text: &str) -> Result<(), TreeError> {
        files.add(name.into(), text.into(), None)
    }

    #[test]
    fn each_source_has_its_root_and_format() {
        let mut f = Files::new();
        add(&mut f, "a.xml", "<root BTCPP_format=\"3\"><A/></root>").unwrap();
        add(&mut f, "b.xml", "<root><B/><C/></root>").unwrap();
        let formats: Vec<Format> = f.sources.iter().map(|s| s.format).collect();
        assert_eq!(formats, [Format::V3, Format::Unspecified]);
        // elements of both files in one list: a.xml's root and A, then
        // b.xml's root, B and C
        assert_eq!(f.roots, [0, 2]);
        assert_eq!(f.elems.len(), 5);
        assert_eq!(f.elems[2].children, [3, 4]);
        assert_eq!((f.elems[3].doc, f.elems[3].name.as_str()), (1, "B"));
        assert_eq!(f.bytes, 34 + 21);
    }

    #[test]
    fn formats_and_includes_without_a_folder() {
        let mut f = Files::new();
        let e = add(&mut f, "a.xml", "<root BTCPP_format=\"5\"/>").unwrap_err();
        assert_eq!((e.kind, e.line, e.column), (Kind::InvalidValue, 1, 7));
        let e = add(&mut f, "a.xml", "<root><include path=\"b.xml\"/></root>").unwrap_err();
        assert_eq!((e.kind, e.line, e.column), (Kind::Structure, 1, 7));
        assert!(e.message.contains("not read from a file"), "{e}");
        let e = add(&mut f, "a.xml", "<root><include/></root>").unwrap_err();
        assert_eq!(e.message, "<include> needs a `path` attribute");
    }

    #[test]
    fn files_on_disk() {
        let dir = std::env::temp_dir().join(format!("btrel-files-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let main = dir.join("main.xml");
        std::fs::write(&main, "<root><include path=\"sub/b.xml\"/></root>").unwrap();
        std::fs::create_dir_all(dir.join("sub")).unwrap();
        std::fs::write(
            dir.join("sub/b.xml"),
            "<root><include path=\"../main.xml\"/></root>",
        )
        .unwrap();
        let mut f = Files::new();
        f.add_file(&main).unwrap();
        // main.xml, then b.xml; b.xml's include of main.xml is read once
        assert_eq!(f.sources.len(), 2);
        let e = read_text(&dir.join("none.xml"), "none.xml").unwrap_err();
        assert_eq!((e.kind, e.line), (Kind::Io, 0));
        std::fs::write(dir.join("bad.xml"), b"<r>\n\xff</r>").unwrap();
        let e = read_text(&dir.join("bad.xml"), "bad.xml").unwrap_err();
        assert_eq!((e.kind, e.line, e.column), (Kind::Syntax, 2, 1));
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn too_large_names_the_limit() {
        let e = too_large("a.xml", MAX_BYTES + 1);
        assert_eq!(e.kind, Kind::Budget);
        assert_eq!(
            e.message,
            format!(
                "the file is {} bytes, more than the limit of {MAX_BYTES} bytes",
                MAX_BYTES + 1
            )
        );
    }
}
