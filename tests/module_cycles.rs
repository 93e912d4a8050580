//! No import cycle between the source files of `src/`.
//!
//! Every file is a module (`foo/mod.rs` is `foo`). A module depends on
//! another when it names it by a path through `crate::`, `super::` or
//! `self::` (in a `use`, braces expanded, or inline), resolved to the
//! longest module prefix that exists — and through a re-export there to the
//! module that defines the name (`super::Plan`, re-exported by `compile`
//! from `compile::plan`, is a dependency on `compile::plan`); its own
//! descendants do not count (a parent declares and drives its children),
//! its ancestors do. Comments and the `#[cfg(test)] mod tests` at a file's
//! end are left out. The graph's strongly connected components must all be
//! single modules: any cycle fails this test.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

fn files(dir: &Path, out: &mut Vec<PathBuf>) {
    for e in std::fs::read_dir(dir).expect("src is readable") {
        let p = e.expect("entry").path();
        if p.is_dir() {
            files(&p, out);
        } else if p.extension().is_some_and(|x| x == "rs") {
            out.push(p);
        }
    }
}

fn module_of(src: &Path, file: &Path) -> String {
    let rel = file.strip_prefix(src).expect("under src");
    let mut parts: Vec<String> = rel
        .iter()
        .map(|c| c.to_string_lossy().into_owned())
        .collect();
    let last = parts.pop().expect("a file name");
    let stem = last.trim_end_matches(".rs");
    if !matches!(stem, "mod" | "lib" | "main") {
        parts.push(stem.to_string());
    }
    if parts.first().is_some_and(|p| p == "bin") {
        // binaries are crates of their own
        parts.insert(0, "bin".into());
    }
    std::iter::once("crate".to_string())
        .chain(parts)
        .collect::<Vec<_>>()
        .join("::")
}

/// The file's text without comments and without its trailing test module.
fn code(text: &str) -> String {
    let text = match text.find("#[cfg(test)]\nmod tests") {
        Some(i) => &text[..i],
        None => text,
    };
    text.lines()
        .map(|l| match l.find("//") {
            Some(i) => &l[..i],
            None => l,
        })
        .collect::<Vec<_>>()
        .join("\n")
}

/// `a::{b, c::{d, e}}` → `a::b`, `a::c::d`, `a::c::e`.
fn expand(path: &str) -> Vec<String> {
    let path: String = path.chars().filter(|c| !c.is_whitespace()).collect();
    let Some(open) = path.find('{') else {
        return vec![path];
    };
    let (prefix, inner) = (&path[..open], &path[open + 1..path.len() - 1]);
    let mut parts = Vec::new();
    let (mut depth, mut cur) = (0, String::new());
    for ch in inner.chars() {
        match ch {
            '{' => depth += 1,
            '}' => depth -= 1,
            ',' if depth == 0 => {
                parts.push(std::mem::take(&mut cur));
                continue;
            }
            _ => {}
        }
        cur.push(ch);
    }
    parts.push(cur);
    parts
        .into_iter()
        .filter(|p| !p.is_empty())
        .flat_map(|p| expand(&format!("{prefix}{p}")))
        .collect()
}

/// Names each module re-exports (`pub use` / `pub(crate) use`, braces
/// expanded): `(module, name)` → the path it re-exports.
type Reexports = BTreeMap<(String, String), String>;

/// The module that `path`, written in `module`, names: the longest existing
/// module prefix, or, where the next segment is a name that module
/// re-exports, the module the re-export names (followed a few levels).
fn resolve_through(
    module: &str,
    path: &str,
    modules: &BTreeSet<String>,
    reexports: &Reexports,
) -> Option<String> {
    let mut found = resolve(module, path, modules)?;
    let mut rest: Vec<String> = path.split("::").map(str::to_string).collect();
    for _ in 0..4 {
        // the segment after the module found, if any
        let depth = found.split("::").count();
        let absolute = absolute(module, &rest)?;
        let Some(name) = absolute.get(depth) else {
            break;
        };
        let Some(target) = reexports.get(&(found.clone(), name.clone())) else {
            break;
        };
        match resolve(&found, target, modules) {
            Some(next) if next != found => {
                rest = absolute_path(&found, target)?;
                found = next;
            }
            _ => break,
        }
    }
    Some(found)
}

/// `path` (`crate::`, `super::` or `self::` relative to `module`) as
/// absolute segments starting with `crate`.
fn absolute(module: &str, path: &[String]) -> Option<Vec<String>> {
    let mut parts: Vec<&str> = path.iter().map(String::as_str).collect();
    let mut base: Vec<&str> = match parts.first() {
        Some(&"crate") => {
            parts.remove(0);
            vec!["crate"]
        }
        Some(&"super") | Some(&"self") => {
            let mut b: Vec<&str> = module.split("::").collect();
            while parts.first() == Some(&"super") || parts.first() == Some(&"self") {
                if parts.remove(0) == "super" {
                    b.pop();
                }
            }
            b
        }
        _ => return None,
    };
    base.extend(parts);
    Some(base.into_iter().map(str::to_string).collect())
}

/// [`absolute`] of a path written as text.
fn absolute_path(module: &str, path: &str) -> Option<Vec<String>> {
    let parts: Vec<String> = path.split("::").map(str::to_string).collect();
    absolute(module, &parts)
}

/// The longest existing module that `path`, written in `module`, names.
fn resolve(module: &str, path: &str, modules: &BTreeSet<String>) -> Option<String> {
    let parts = absolute_path(module, path)?;
    let mut best = None;
    for n in 1..=parts.len() {
        let candidate = parts[..n].join("::");
        if modules.contains(&candidate) {
            best = Some(candidate);
        } else if best.is_some() {
            break;
        }
    }
    best
}

fn graph() -> BTreeMap<String, BTreeSet<String>> {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut all = Vec::new();
    files(&src, &mut all);
    let texts: Vec<(String, String)> = all
        .iter()
        .map(|f| {
            let text = std::fs::read_to_string(f).expect("readable source");
            (module_of(&src, f), code(&text))
        })
        .collect();
    let modules: BTreeSet<String> = texts.iter().map(|(m, _)| m.clone()).collect();
    let mut reexports = Reexports::new();
    for (module, text) in &texts {
        for start in ["pub use ", "pub(crate) use ", "pub(super) use "] {
            for (i, _) in text.match_indices(start) {
                let rest = &text[i + start.len()..];
                let body = &rest[..rest.find(';').unwrap_or(rest.len())];
                for path in expand(body.trim()) {
                    // `a::b::Name` or `a::b::Name as Alias`
                    let (path, name) = match path.split_once(" as ").or(path.split_once("as")) {
                        Some((p, alias)) if path.contains(" as ") => (p.trim(), alias.trim()),
                        _ => (path.as_str(), path.rsplit("::").next().unwrap_or("")),
                    };
                    let path = if path.starts_with("crate::")
                        || path.starts_with("super::")
                        || path.starts_with("self::")
                    {
                        path.to_string()
                    } else {
                        format!("self::{path}")
                    };
                    reexports.insert((module.clone(), name.to_string()), path);
                }
            }
        }
    }
    let mut g = BTreeMap::new();
    for (module, text) in &texts {
        let mut paths = Vec::new();
        // `use` declarations (braces expanded)
        let mut rest = text.as_str();
        while let Some(i) = rest.find("use ") {
            let before = rest[..i].chars().last();
            rest = &rest[i + 4..];
            if before.is_some_and(|c| c.is_alphanumeric() || c == '_') {
                continue;
            }
            let end = rest.find(';').unwrap_or(rest.len());
            let body = rest[..end].trim();
            if ["crate::", "super::", "self::"]
                .iter()
                .any(|p| body.starts_with(p))
            {
                paths.extend(expand(body));
            }
        }
        // inline paths
        for start in ["crate::", "super::"] {
            for (i, _) in text.match_indices(start) {
                if text[..i]
                    .chars()
                    .last()
                    .is_some_and(|c| c.is_alphanumeric() || c == '_' || c == ':')
                {
                    continue;
                }
                let end = text[i..]
                    .find(|c: char| !(c.is_alphanumeric() || c == '_' || c == ':'))
                    .map_or(text.len(), |e| i + e);
                paths.push(text[i..end].trim_end_matches(':').to_string());
            }
        }
        let deps: BTreeSet<String> = paths
            .iter()
            .filter_map(|p| resolve_through(module, p, &modules, &reexports))
            .filter(|d| d != module && !d.starts_with(&format!("{module}::")))
            .collect();
        g.insert(module.clone(), deps);
    }
    g
}

/// Strongly connected components with more than one module (Tarjan).
fn cycles(g: &BTreeMap<String, BTreeSet<String>>) -> Vec<BTreeSet<String>> {
    struct State<'a> {
        g: &'a BTreeMap<String, BTreeSet<String>>,
        index: BTreeMap<&'a str, usize>,
        low: BTreeMap<&'a str, usize>,
        stack: Vec<&'a str>,
        on: BTreeSet<&'a str>,
        out: Vec<BTreeSet<String>>,
    }
    fn visit<'a>(s: &mut State<'a>, v: &'a str) {
        let n = s.index.len();
        s.index.insert(v, n);
        s.low.insert(v, n);
        s.stack.push(v);
        s.on.insert(v);
        for w in s.g.get(v).into_iter().flatten() {
            let w = w.as_str();
            if !s.index.contains_key(w) {
                visit(s, w);
                let lw = s.low[w];
                let lv = s.low[v];
                s.low.insert(v, lv.min(lw));
            } else if s.on.contains(w) {
                let iw = s.index[w];
                let lv = s.low[v];
                s.low.insert(v, lv.min(iw));
            }
        }
        if s.low[v] == s.index[v] {
            let mut comp = BTreeSet::new();
            loop {
                let w = s.stack.pop().expect("on the stack");
                s.on.remove(w);
                comp.insert(w.to_string());
                if w == v {
                    break;
                }
            }
            if comp.len() > 1 {
                s.out.push(comp);
            }
        }
    }
    let mut s = State {
        g,
        index: BTreeMap::new(),
        low: BTreeMap::new(),
        stack: Vec::new(),
        on: BTreeSet::new(),
        out: Vec::new(),
    };
    for v in g.keys() {
        if !s.index.contains_key(v.as_str()) {
            visit(&mut s, v);
        }
    }
    s.out
}

#[test]
fn no_import_cycle() {
    let g = graph();
    assert!(g.len() > 50, "read the sources: {} modules", g.len());
    let found = cycles(&g);
    assert!(
        found.is_empty(),
        "import cycles between {found:?}: move what both sides need into a module of its \
         own, or pass the dependency in (as `compile::children` does)"
    );
    // re-exports are followed: `model` names `crate::compile::Representation`,
    // which `compile` re-exports from `compile::children`
    assert!(g["crate::model"].contains("crate::compile::children"));
}

/// The checker itself finds a cycle, through `use` braces and `super::`.
#[test]
fn the_checker_sees_a_cycle() {
    let modules: BTreeSet<String> = ["crate", "crate::a", "crate::a::b", "crate::c"]
        .iter()
        .map(|s| s.to_string())
        .collect();
    assert_eq!(
        resolve("crate::a::b", "super::super::c::Thing", &modules).as_deref(),
        Some("crate::c")
    );
    // a re-export is followed to the module that defines the name
    let mut reexports = Reexports::new();
    reexports.insert(
        ("crate::a".to_string(), "Thing".to_string()),
        "self::b::Thing".to_string(),
    );
    assert_eq!(
        resolve_through("crate::c", "crate::a::Thing", &modules, &reexports).as_deref(),
        Some("crate::a::b")
    );
    assert_eq!(
        resolve_through("crate::c", "crate::a::Other", &modules, &reexports).as_deref(),
        Some("crate::a")
    );
    // ... also named from a sibling through `super::` (`super::Plan` in
    // `compile::race` is a dependency on `compile::plan`)
    assert_eq!(
        resolve_through("crate::a::b", "super::Thing", &modules, &reexports).as_deref(),
        Some("crate::a::b")
    );
    assert_eq!(
        resolve_through("crate::a::b", "super::Other", &modules, &reexports).as_deref(),
        Some("crate::a")
    );
    assert_eq!(
        expand("crate::{a::b::X, c::{Y, Z}}"),
        ["crate::a::b::X", "crate::c::Y", "crate::c::Z"]
    );
    let mut g = BTreeMap::new();
    g.insert(
        "crate::a".to_string(),
        BTreeSet::from(["crate::c".to_string()]),
    );
    g.insert(
        "crate::c".to_string(),
        BTreeSet::from(["crate::a".to_string()]),
    );
    g.insert(
        "crate::d".to_string(),
        BTreeSet::from(["crate::a".to_string()]),
    );
    assert_eq!(
        cycles(&g),
        [BTreeSet::from([
            "crate::a".to_string(),
            "crate::c".to_string()
        ])]
    );
}
