//! The README and docs/*.md cannot drift: their examples are run and the synopsis is checked
//! against the binary.
//!
//! * Every ```` ```console ```` block is a transcript: each `$ btrel ...` line
//!   is run (the built binary, working directory the crate root, no shell) and
//!   the lines that follow it, up to the next `$` line or the end of the block,
//!   must be exactly its standard output followed by its standard error.
//!   A stage `| head -N` or `| tail -N` (also `-n N`) after the command is
//!   applied to the standard output in Rust, and `cat FILE |` before it makes
//!   FILE its standard input (otherwise it has none); any other shell syntax
//!   is an error. A line that is exactly `...` matches any number of lines (zero or
//!   more): the one elision marker, for output that may legitimately vary
//!   (none does today: simulations are seeded and bit-identical for any thread
//!   count). The commands must exit with 0, or with the code given in the
//!   fence's info string: ```` ```console exit=2 ````; a command that fails
//!   must leave its standard output empty.
//! * Every line of a ```` ```sh ```` block that starts with `btrel` or
//!   `cargo run ... --` names an existing command and only options of that
//!   command (from `btrel COMMAND --help`), with valid values where the option
//!   has a fixed set. A line whose `-o` writes a file that exists under `docs/`
//!   is run with the output redirected to a temporary file, which must equal
//!   the committed file byte for byte (the figures in the README).
//! * Inline code spans outside blocks that start with `btrel COMMAND` are
//!   checked the same way (a `...` word stands for elided arguments).
//! * The synopsis (the first block under `## Commands`) lists every option of
//!   every command and no option that does not exist; a `btrel [...] COMMAND`
//!   line lists the global options.
//!
//! Set `BTREL_README_BLESS=1` to rewrite the outputs of failing transcripts in
//! README.md with what the binary prints now (blocks with `...` are left
//! alone); then check that the prose around them still agrees.

use std::collections::{BTreeMap, BTreeSet};
use std::path::PathBuf;
use std::process::{Command, Stdio};

const BIN: &str = env!("CARGO_BIN_EXE_btrel");
const BLESS: &str = "BTREL_README_BLESS";

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// The documents checked: README.md, then every `docs/*.md`, as
/// (path relative to the crate root, text).
fn documents() -> Vec<(String, String)> {
    let mut names = vec!["README.md".to_string()];
    let mut docs: Vec<String> = std::fs::read_dir(root().join("docs"))
        .expect("docs/ is readable")
        .filter_map(|e| e.ok())
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".md"))
        .map(|n| format!("docs/{n}"))
        .collect();
    docs.sort();
    names.extend(docs);
    names
        .into_iter()
        .map(|n| {
            let text = std::fs::read_to_string(root().join(&n))
                .unwrap_or_else(|e| panic!("{n} is readable: {e}"));
            (n, text)
        })
        .collect()
}

/// A fenced code block of the README.
struct Block {
    /// The info string after the opening fence (`console exit=2`).
    info: String,
    /// 1-based README line of each content line.
    line_numbers: Vec<usize>,
    /// Content lines with the fence's indentation removed.
    lines: Vec<String>,
    /// Indentation of the fence (blocks inside list items).
    indent: usize,
}

impl Block {
    fn lang(&self) -> &str {
        self.info.split_whitespace().next().unwrap_or("")
    }
}

fn blocks(text: &str) -> Vec<Block> {
    let mut out = Vec::new();
    let mut open: Option<Block> = None;
    for (i, line) in text.lines().enumerate() {
        let trimmed = line.trim_start();
        let indent = line.len() - trimmed.len();
        match open.take() {
            None => {
                if let Some(info) = trimmed.strip_prefix("```") {
                    open = Some(Block {
                        info: info.trim().to_string(),
                        line_numbers: Vec::new(),
                        lines: Vec::new(),
                        indent,
                    });
                }
            }
            Some(mut b) => {
                if trimmed.trim_end() == "```" {
                    out.push(b);
                } else {
                    let cut = line
                        .char_indices()
                        .take_while(|&(k, c)| k < b.indent && c == ' ')
                        .count();
                    b.lines.push(line[cut..].to_string());
                    b.line_numbers.push(i + 1);
                    open = Some(b);
                }
            }
        }
    }
    assert!(open.is_none(), "README.md: a code block is not closed");
    out
}

/// Removes a trailing shell comment (`  # ...` outside quotes).
fn strip_comment(line: &str) -> &str {
    let (mut single, mut double) = (false, false);
    let mut prev = ' ';
    for (k, c) in line.char_indices() {
        match c {
            '\'' if !double => single = !single,
            '"' if !single => double = !double,
            '#' if !single && !double && prev.is_whitespace() => return line[..k].trim_end(),
            _ => {}
        }
        prev = c;
    }
    line.trim_end()
}

fn words(line: &str) -> Result<Vec<String>, String> {
    shlex::split(strip_comment(line)).ok_or_else(|| format!("cannot split `{line}` into words"))
}

/// `head`/`tail` stage of a transcript's pipeline.
enum Stage {
    Head(usize),
    Tail(usize),
}

fn parse_stage(w: &[String]) -> Result<Stage, String> {
    let n = match w {
        [_, n] if n.starts_with('-') => &n[1..],
        [_, flag, n] if flag == "-n" => n.as_str(),
        _ => return Err(format!("unsupported pipeline stage `{}`", w.join(" "))),
    };
    let n: usize = n
        .parse()
        .map_err(|_| format!("bad line count in `{}`", w.join(" ")))?;
    match w[0].as_str() {
        "head" => Ok(Stage::Head(n)),
        "tail" => Ok(Stage::Tail(n)),
        _ => Err(format!(
            "unsupported pipeline stage `{}` (only head and tail)",
            w.join(" ")
        )),
    }
}

/// A parsed transcript line.
struct Pipeline {
    /// `cat FILE |` before the command: FILE is its standard input.
    stdin: Option<String>,
    args: Vec<String>,
    stages: Vec<Stage>,
}

/// A transcript line `$ [cat FILE |] btrel ARGS [| head -N | tail -N ...]`, split.
fn parse_command(line: &str) -> Result<Pipeline, String> {
    let w = words(line)?;
    let mut parts = w.split(|t| t == "|").peekable();
    let mut stdin = None;
    if let Some([cat, file]) = parts.peek().map(|p| &p[..]) {
        if cat == "cat" {
            stdin = Some(file.clone());
            parts.next();
        }
    }
    let first = parts.next().unwrap_or(&[]);
    if first.first().map(String::as_str) != Some("btrel") {
        return Err("a transcript command must start with `btrel`".into());
    }
    if let Some(op) = first.iter().find(|t| {
        matches!(
            t.as_str(),
            ">" | ">>" | "<" | "&&" | "||" | ";" | "2>" | "&"
        )
    }) {
        return Err(format!(
            "unsupported shell syntax `{op}` (transcripts are run without a shell)"
        ));
    }
    let stages = parts.map(parse_stage).collect::<Result<Vec<_>, _>>()?;
    Ok(Pipeline {
        stdin,
        args: first[1..].to_vec(),
        stages,
    })
}

/// Whether `actual` matches `expected`, where an expected line `...` matches
/// any number of lines.
fn matches(expected: &[String], actual: &[String]) -> bool {
    // reach[j]: expected[..i] can match actual[..j].
    let mut reach = vec![false; actual.len() + 1];
    reach[0] = true;
    for e in expected {
        let mut next = vec![false; actual.len() + 1];
        if e == "..." {
            let mut any = false;
            for j in 0..=actual.len() {
                any |= reach[j];
                next[j] = any;
            }
        } else {
            for j in 0..actual.len() {
                next[j + 1] = reach[j] && actual[j] == *e;
            }
        }
        reach = next;
    }
    reach[actual.len()]
}

fn diff(expected: &[String], actual: &[String]) -> String {
    difflib::unified_diff(expected, actual, "README", "binary", "", "", 2)
        .iter()
        .map(|l| {
            if l.ends_with('\n') {
                l.clone()
            } else {
                format!("{l}\n")
            }
        })
        .collect()
}

struct Transcript {
    /// README line of the `$` line.
    line: usize,
    command: String,
    /// README lines (1-based) of the expected output.
    output_lines: Vec<usize>,
    expected: Vec<String>,
    exit: i32,
    indent: usize,
}

fn transcripts(text: &str) -> Vec<Transcript> {
    let mut out: Vec<Transcript> = Vec::new();
    for b in blocks(text).iter().filter(|b| b.lang() == "console") {
        let exit = b
            .info
            .split_whitespace()
            .find_map(|w| w.strip_prefix("exit="))
            .map(|c| c.parse::<i32>().expect("exit=N in a console fence"))
            .unwrap_or(0);
        let mut first = true;
        for (line, no) in b.lines.iter().zip(&b.line_numbers) {
            if let Some(cmd) = line.strip_prefix("$ ") {
                out.push(Transcript {
                    line: *no,
                    command: cmd.to_string(),
                    output_lines: Vec::new(),
                    expected: Vec::new(),
                    exit,
                    indent: b.indent,
                });
                first = false;
            } else {
                assert!(
                    !first,
                    "README.md:{no}: a console block must start with a `$ ` command line"
                );
                let t = out.last_mut().expect("a command precedes");
                t.expected.push(line.clone());
                t.output_lines.push(*no);
            }
        }
    }
    out
}

fn lines_of(s: &str) -> Vec<String> {
    s.lines().map(str::to_string).collect()
}

/// Runs a transcript; returns (exit code, output lines, whether the
/// standard output was empty).
fn run(p: &Pipeline) -> (i32, Vec<String>, bool) {
    let stdin = match &p.stdin {
        Some(f) => std::fs::File::open(root().join(f))
            .map(Stdio::from)
            .unwrap_or_else(|e| panic!("README transcript: cannot open {f}: {e}")),
        None => Stdio::null(),
    };
    let out = Command::new(BIN)
        .args(&p.args)
        .stdin(stdin)
        .current_dir(root())
        .env("NO_COLOR", "1")
        .env_remove("CLICOLOR_FORCE")
        .output()
        .expect("the binary runs");
    let mut stdout = lines_of(&String::from_utf8_lossy(&out.stdout));
    for s in &p.stages {
        stdout = match *s {
            Stage::Head(n) => stdout.into_iter().take(n).collect(),
            Stage::Tail(n) => {
                let skip = stdout.len().saturating_sub(n);
                stdout.into_iter().skip(skip).collect()
            }
        };
    }
    let quiet = out.stdout.is_empty();
    stdout.extend(lines_of(&String::from_utf8_lossy(&out.stderr)));
    (out.status.code().unwrap_or(-1), stdout, quiet)
}

#[test]
fn console_examples_print_what_the_binary_prints() {
    let bless = std::env::var_os(BLESS).is_some();
    let mut failures = Vec::new();
    let mut total = 0;
    for (name, text) in documents() {
        let ts = transcripts(&text);
        total += ts.len();
        let mut rewrites: Vec<(usize, usize, Vec<String>)> = Vec::new();
        for t in &ts {
            let pipeline = match parse_command(&t.command) {
                Ok(p) => p,
                Err(e) => {
                    failures.push(format!("{name}:{}: `{}`: {e}", t.line, t.command));
                    continue;
                }
            };
            let (code, actual, quiet) = run(&pipeline);
            if code != 0 && !quiet {
                failures.push(format!(
                    "{name}:{}: `$ {}` failed (exit {code}) but wrote to standard output",
                    t.line, t.command
                ));
            }
            if code != t.exit {
                failures.push(format!(
                    "{name}:{}: `$ {}` exited with {code}, the README expects {} \
                 (write ```console exit=N for an error example)\n{}",
                    t.line,
                    t.command,
                    t.exit,
                    actual.join("\n")
                ));
                continue;
            }
            if matches(&t.expected, &actual) {
                continue;
            }
            let elided = t.expected.iter().any(|l| l == "...");
            if bless && !elided {
                let first = t.line; // replace the lines after the `$` line
                rewrites.push((
                    first,
                    t.expected.len(),
                    actual
                        .iter()
                        .map(|l| format!("{}{l}", " ".repeat(t.indent)))
                        .collect(),
                ));
                continue;
            }
            failures.push(format!(
                "{name}:{}: `$ {}` prints something else (- document, + binary):\n{}",
                t.line,
                t.command,
                diff(&t.expected, &actual)
            ));
        }
        if !rewrites.is_empty() {
            let mut lines = lines_of(&text);
            rewrites.sort_by_key(|r| std::cmp::Reverse(r.0));
            for (after, len, new) in rewrites {
                lines.splice(after..after + len, new);
            }
            let mut new = lines.join("\n");
            new.push('\n');
            std::fs::write(root().join(&name), new).expect("the document is writable");
            eprintln!("{BLESS}: {name} transcripts rewritten; check the prose around them");
        }
    }
    assert!(total >= 5, "found only {total} transcripts");
    assert!(
        failures.is_empty(),
        "{} transcript(s) do not match the binary (set {BLESS}=1 to rewrite them):\n\n{}",
        failures.len(),
        failures.join("\n\n")
    );
}

/// An option of a command, from `--help`.
#[derive(Debug, Clone)]
struct Opt {
    long: String,
    short: Option<char>,
    takes_value: bool,
    /// The fixed set of values, if any.
    values: Vec<String>,
}

fn help(args: &[&str]) -> String {
    let out = Command::new(BIN)
        .args(args)
        .arg("--help")
        .output()
        .expect("the binary runs");
    assert!(out.status.success(), "btrel {args:?} --help fails");
    String::from_utf8(out.stdout).expect("help is UTF-8")
}

/// The options of `btrel ARGS --help` (without --help and --version).
fn options(args: &[&str]) -> Vec<Opt> {
    let text = help(args);
    let mut opts: Vec<(Opt, String)> = Vec::new();
    let mut in_options = false;
    for line in text.lines() {
        if line.ends_with(':') && !line.starts_with(' ') {
            in_options = line == "Options:";
            continue;
        }
        if !in_options {
            continue;
        }
        let t = line.trim_start();
        let indent = line.len() - t.len();
        if t.starts_with('-') && indent <= 6 {
            let mut short = None;
            let mut rest = t;
            if let Some(r) = rest.strip_prefix('-').filter(|r| !r.starts_with('-')) {
                short = r.chars().next();
                rest = r[1..].trim_start_matches(',').trim_start();
            }
            let Some(r) = rest.strip_prefix("--") else {
                continue;
            };
            let end = r
                .find(|c: char| !(c.is_ascii_alphanumeric() || c == '-'))
                .unwrap_or(r.len());
            let long = r[..end].to_string();
            let takes_value = r[end..].trim_start().starts_with('<');
            opts.push((
                Opt {
                    long,
                    short,
                    takes_value,
                    values: Vec::new(),
                },
                t.to_string(),
            ));
        } else if let Some((_, text)) = opts.last_mut() {
            text.push('\n');
            text.push_str(t);
        }
    }
    opts.into_iter()
        .filter(|(o, _)| o.long != "help" && o.long != "version")
        .map(|(mut o, text)| {
            o.values = possible_values(&text);
            o
        })
        .collect()
}

/// `[possible values: a, b]` (short help) or `Possible values:` followed by
/// `- a: ...` lines (long help).
fn possible_values(text: &str) -> Vec<String> {
    if let Some(k) = text.find("[possible values: ") {
        let rest = &text[k + "[possible values: ".len()..];
        let end = rest.find(']').unwrap_or(rest.len());
        return rest[..end].split(", ").map(str::to_string).collect();
    }
    if let Some(k) = text.find("Possible values:") {
        return text[k..]
            .lines()
            .skip(1)
            .filter_map(|l| l.trim().strip_prefix("- "))
            .map(|l| l.split(':').next().unwrap_or("").trim().to_string())
            .collect();
    }
    Vec::new()
}

/// The commands of `btrel --help` (without `help`).
fn commands() -> Vec<String> {
    let text = help(&[]);
    let mut out = Vec::new();
    let mut inside = false;
    for line in text.lines() {
        if line == "Commands:" {
            inside = true;
        } else if inside {
            match line.split_whitespace().next() {
                Some(c) if line.starts_with("  ") => {
                    if c != "help" {
                        out.push(c.to_string())
                    }
                }
                _ => break,
            }
        }
    }
    assert!(out.len() >= 5, "btrel --help lists commands: {out:?}");
    out
}

/// Every command's options, by name.
struct Cli {
    global: Vec<Opt>,
    commands: BTreeMap<String, Vec<Opt>>,
}

impl Cli {
    fn get() -> Cli {
        Cli {
            global: options(&[]),
            commands: commands()
                .into_iter()
                .map(|c| {
                    let o = options(&[c.as_str()]);
                    (c, o)
                })
                .collect(),
        }
    }
}

fn find<'a>(opts: &'a [Opt], token: &str) -> Option<&'a Opt> {
    let name = token.split('=').next().unwrap_or(token);
    if let Some(long) = name.strip_prefix("--") {
        opts.iter().find(|o| o.long == long)
    } else {
        let mut c = name[1..].chars();
        let s = c.next()?;
        if c.next().is_some() {
            return None;
        }
        opts.iter().find(|o| o.short == Some(s))
    }
}

/// Checks a command line's words (after `btrel`) against the CLI.
fn check_words(cli: &Cli, w: &[String]) -> Result<(), String> {
    let mut k = 0;
    // global options before the command
    while k < w.len() && w[k].starts_with('-') {
        let o = find(&cli.global, &w[k]).ok_or(format!("no global option `{}`", w[k]))?;
        k += if o.takes_value && !w[k].contains('=') {
            2
        } else {
            1
        };
    }
    let cmd = w.get(k).ok_or("no command")?;
    let opts = cli.commands.get(cmd).ok_or(format!(
        "no command `{cmd}` (btrel has {})",
        cli.commands.keys().cloned().collect::<Vec<_>>().join(", ")
    ))?;
    k += 1;
    while k < w.len() {
        let t = &w[k];
        k += 1;
        if !t.starts_with('-') || t == "-" {
            continue;
        }
        let o = find(opts, t).ok_or(format!("`btrel {cmd}` has no option `{t}`"))?;
        if !o.takes_value {
            continue;
        }
        let value = match t.split_once('=') {
            Some((_, v)) => v.to_string(),
            None => {
                k += 1;
                w.get(k - 1)
                    .cloned()
                    .ok_or(format!("`{t}` needs a value"))?
            }
        };
        if !o.values.is_empty() && !o.values.contains(&value) {
            return Err(format!(
                "`{t} {value}`: the values are {}",
                o.values.join(", ")
            ));
        }
    }
    Ok(())
}

/// The btrel part of a `sh` line: the words after `btrel` (or after `cargo run
/// ... --`), up to the first shell operator; None for other lines.
fn btrel_words(line: &str) -> Option<Result<Vec<String>, String>> {
    let t = line.trim_start();
    if !(t.starts_with("btrel ") || t.starts_with("cargo run")) {
        return None;
    }
    let w = match words(t) {
        Ok(w) => w,
        Err(e) => return Some(Err(e)),
    };
    let w: Vec<String> = w
        .into_iter()
        .take_while(|t| {
            !matches!(
                t.as_str(),
                "|" | ">" | ">>" | "<" | "&&" | "||" | ";" | "2>" | "&"
            )
        })
        .collect();
    if w[0] == "btrel" {
        return Some(Ok(w[1..].to_vec()));
    }
    // cargo run: the binary's arguments follow `--`; `--example` runs another program
    if w.iter().any(|t| t == "--example") {
        return None;
    }
    let k = w.iter().position(|t| t == "--")?;
    Some(Ok(w[k + 1..].to_vec()))
}

#[test]
fn sh_examples_name_existing_commands_and_options() {
    let cli = Cli::get();
    let mut failures = Vec::new();
    let mut checked = 0;
    let dir = tempfile::tempdir().expect("temp dir");
    for (name, text) in documents() {
        for b in blocks(&text)
            .iter()
            .filter(|b| matches!(b.lang(), "sh" | "bash" | "shell"))
        {
            for (line, no) in b.lines.iter().zip(&b.line_numbers) {
                let Some(w) = btrel_words(line) else { continue };
                checked += 1;
                let w = match w.and_then(|w| check_words(&cli, &w).map(|()| w)) {
                    Ok(w) => w,
                    Err(e) => {
                        failures.push(format!("{name}:{no}: `{}`: {e}", line.trim()));
                        continue;
                    }
                };
                // a committed figure: regenerate it and compare
                let Some(k) = w.iter().position(|t| t == "-o" || t == "--output") else {
                    continue;
                };
                let Some(target) = w.get(k + 1).filter(|p| p.starts_with("docs/")) else {
                    continue;
                };
                let committed = root().join(target);
                if !committed.is_file() {
                    continue;
                }
                // the same extension: it may choose the format (plot: .svg, .png)
                let mut fresh = dir
                    .path()
                    .join(format!("out{}-{no}", name.replace('/', "-")));
                if let Some(ext) = committed.extension() {
                    fresh.set_extension(ext);
                }
                let mut args = w.clone();
                args[k + 1] = fresh.display().to_string();
                let out = Command::new(BIN)
                    .args(&args)
                    .current_dir(root())
                    .output()
                    .expect("the binary runs");
                let same = out.status.success()
                    && std::fs::read(&fresh).ok() == std::fs::read(&committed).ok();
                if !same {
                    failures.push(format!(
                        "{name}:{no}: {target} is not what `{}` writes now (exit {:?}, {}); \
                     regenerate it with that command",
                        strip_comment(line).trim(),
                        out.status.code(),
                        String::from_utf8_lossy(&out.stderr).trim()
                    ));
                }
            }
        }
    }
    assert!(
        checked >= 5,
        "found only {checked} btrel lines in sh blocks"
    );
    assert!(
        failures.is_empty(),
        "sh examples that do not fit the binary:\n{}",
        failures.join("\n")
    );
}

/// Single-backtick code spans outside code blocks, with their README lines.
fn inline_spans(text: &str) -> Vec<(usize, String)> {
    let mut out = Vec::new();
    let mut in_block = false;
    for (i, line) in text.lines().enumerate() {
        if line.trim_start().starts_with("```") {
            in_block = !in_block;
            continue;
        }
        if in_block {
            continue;
        }
        // split at backtick runs; single-backtick spans are the odd pieces
        let mut rest = line;
        while let Some(a) = rest.find('`') {
            let run = rest[a..].chars().take_while(|&c| c == '`').count();
            let after = &rest[a + run..];
            let fence = "`".repeat(run);
            let Some(b) = after.find(&fence) else { break };
            if run == 1 {
                out.push((i + 1, after[..b].to_string()));
            }
            rest = &after[b + run..];
        }
    }
    out
}

#[test]
fn inline_commands_name_existing_commands_and_options() {
    let cli = Cli::get();
    let mut failures = Vec::new();
    let mut checked = 0;
    for (name, text) in documents() {
        for (no, span) in inline_spans(&text) {
            if !span.starts_with("btrel ") {
                continue;
            }
            let Some(Ok(w)) = btrel_words(&span) else {
                continue;
            };
            let w: Vec<String> = w.into_iter().filter(|t| t != "...").collect();
            let Some(cmd) = w.first() else { continue };
            if !cli.commands.contains_key(cmd) && !cmd.starts_with('-') {
                // prose such as `btrel <command>`: only real command names count
                if cmd.chars().all(|c| c.is_ascii_lowercase()) {
                    failures.push(format!("{name}:{no}: `{span}`: no command `{cmd}`"));
                }
                continue;
            }
            checked += 1;
            if let Err(e) = check_words(&cli, &w) {
                failures.push(format!("{name}:{no}: `{span}`: {e}"));
            }
        }
    }
    assert!(checked >= 5, "found only {checked} inline btrel commands");
    assert!(
        failures.is_empty(),
        "inline commands that do not fit the binary:\n{}",
        failures.join("\n")
    );
}

/// Strips synopsis punctuation from a word: `[--mc`, `N]`, `(--times`, `...`.
fn clean(word: &str) -> &str {
    word.trim_matches(|c| matches!(c, '[' | ']' | '(' | ')' | ','))
}

#[test]
fn synopsis_lists_every_option_and_no_other() {
    let cli = Cli::get();
    // exactly one synopsis, so that no second copy can drift unchecked
    let mut with_synopsis: Vec<(String, String)> = documents()
        .into_iter()
        .filter(|(_, t)| t.lines().any(|l| l.trim_end() == "## Commands"))
        .collect();
    let names: Vec<&str> = with_synopsis.iter().map(|(n, _)| n.as_str()).collect();
    assert_eq!(
        names.len(),
        1,
        "exactly one of README.md and docs/*.md has a `## Commands` synopsis: {names:?}"
    );
    let (name, text) = with_synopsis.remove(0);
    let lines: Vec<&str> = text.lines().collect();
    let start = lines
        .iter()
        .position(|l| l.trim_end() == "## Commands")
        .expect("found above");
    let synopsis = blocks(&lines[start..].join("\n"))
        .into_iter()
        .next()
        .expect("a code block under ## Commands");
    let line0 = start; // README line of the heading, 0-based
                       // command (None: global options) -> (option long names, README line)
    let mut listed: BTreeMap<Option<String>, BTreeSet<String>> = BTreeMap::new();
    let mut failures = Vec::new();
    let mut current: Option<Option<String>> = None;
    for (line, no) in synopsis.lines.iter().zip(&synopsis.line_numbers) {
        let no = no + line0;
        let line = strip_comment(line);
        let w: Vec<&str> = line.split_whitespace().collect();
        if w.is_empty() {
            continue;
        }
        let mut rest = &w[..];
        if !line.starts_with(' ') {
            if w[0] != "btrel" {
                failures.push(format!("{name}:{no}: a synopsis line starts with `btrel`"));
                continue;
            }
            let second = clean(w.get(1).copied().unwrap_or(""));
            if second.starts_with('-') {
                current = Some(None); // global options line
                rest = &w[1..];
            } else {
                if !cli.commands.contains_key(second) {
                    failures.push(format!("{name}:{no}: no command `{second}`"));
                }
                current = Some(Some(second.to_string()));
                rest = &w[2..];
            }
        }
        let Some(cmd) = current.clone() else {
            failures.push(format!("{name}:{no}: continuation without a command"));
            continue;
        };
        let opts: &[Opt] = match &cmd {
            None => &cli.global,
            Some(c) => cli.commands.get(c).map(Vec::as_slice).unwrap_or(&[]),
        };
        let set = listed.entry(cmd.clone()).or_default();
        for (k, word) in rest.iter().enumerate() {
            let word = clean(word);
            if !word.starts_with('-') || word == "-" || word == "|" {
                continue;
            }
            let Some(o) = find(opts, word) else {
                failures.push(format!(
                    "{name}:{no}: `btrel {}` has no option `{word}`",
                    cmd.as_deref().unwrap_or("(global)")
                ));
                continue;
            };
            set.insert(o.long.clone());
            // `--method exact|book`: the listed values are the real ones
            if let Some(v) = rest.get(k + 1).map(|v| clean(v)) {
                if !o.values.is_empty() && v.contains('|') {
                    let shown: BTreeSet<&str> = v.split('|').collect();
                    let real: BTreeSet<&str> = o.values.iter().map(String::as_str).collect();
                    if shown != real {
                        failures.push(format!(
                            "{name}:{no}: `{word} {v}`: the values are {}",
                            o.values.join("|")
                        ));
                    }
                }
            }
        }
    }
    let global: BTreeSet<String> = cli.global.iter().map(|o| o.long.clone()).collect();
    let missing = |have: Option<&BTreeSet<String>>, want: &BTreeSet<String>| -> Vec<String> {
        want.iter()
            .filter(|o| !have.is_some_and(|h| h.contains(*o)))
            .map(|o| format!("--{o}"))
            .collect()
    };
    let m = missing(listed.get(&None), &global);
    if !m.is_empty() {
        failures.push(format!(
            "the synopsis's `btrel [...] COMMAND` line lacks the global option(s) {}",
            m.join(", ")
        ));
    }
    for (cmd, opts) in &cli.commands {
        let want: BTreeSet<String> = opts
            .iter()
            .map(|o| o.long.clone())
            .filter(|o| !global.contains(o))
            .collect();
        let Some(have) = listed.get(&Some(cmd.clone())) else {
            failures.push(format!("the synopsis has no `btrel {cmd}` line"));
            continue;
        };
        let m = missing(Some(have), &want);
        if !m.is_empty() {
            failures.push(format!(
                "the synopsis of `btrel {cmd}` lacks {} (from `btrel {cmd} --help`)",
                m.join(", ")
            ));
        }
    }
    assert!(
        failures.is_empty(),
        "{name} synopsis (## Commands) does not match the binary:\n{}",
        failures.join("\n")
    );
}

#[test]
fn elision_marker_matches_any_number_of_lines() {
    let s = |v: &[&str]| v.iter().map(|x| x.to_string()).collect::<Vec<_>>();
    assert!(matches(&s(&["a", "...", "d"]), &s(&["a", "b", "c", "d"])));
    assert!(matches(&s(&["a", "...", "b"]), &s(&["a", "b"])));
    assert!(matches(&s(&["..."]), &s(&[])));
    assert!(!matches(&s(&["a", "...", "d"]), &s(&["a", "b", "c"])));
    assert!(!matches(&s(&["a", "b"]), &s(&["a", "b", "c"])));
    assert!(!matches(&s(&["a"]), &s(&["a "])));
}

/// Every relative link of README.md and docs/*.md (`[text](path)` or
/// `[text](path#anchor)`, outside code blocks) names a file or folder that
/// exists, relative to the document; a `#anchor` into a Markdown file names
/// one of its headings (GitHub's slugs: lower case, spaces to `-`,
/// punctuation other than `-` and `_` dropped).
#[test]
fn relative_links_resolve() {
    let slug = |heading: &str| -> String {
        heading
            .trim()
            .to_lowercase()
            .chars()
            .filter_map(|c| match c {
                ' ' => Some('-'),
                c if c.is_alphanumeric() || c == '-' || c == '_' => Some(c),
                _ => None,
            })
            .collect()
    };
    let headings = |text: &str| -> Vec<String> {
        let mut fenced = false;
        text.lines()
            .filter(|l| {
                if l.trim_start().starts_with("```") {
                    fenced = !fenced;
                }
                !fenced && l.starts_with('#')
            })
            .map(|l| slug(l.trim_start_matches('#')))
            .collect()
    };
    let mut failures = Vec::new();
    for (name, text) in documents() {
        let dir = root()
            .join(&name)
            .parent()
            .expect("in a folder")
            .to_path_buf();
        let mut fenced = false;
        for (i, line) in text.lines().enumerate() {
            if line.trim_start().starts_with("```") {
                fenced = !fenced;
            }
            if fenced {
                continue;
            }
            let mut rest = line;
            while let Some(k) = rest.find("](") {
                let after = &rest[k + 2..];
                let Some(end) = after.find(')') else { break };
                let target = &after[..end];
                rest = &after[end..];
                if target.contains("://") || target.starts_with("mailto:") || target.is_empty() {
                    continue;
                }
                let (path, anchor) = match target.split_once('#') {
                    Some((p, a)) => (p, Some(a)),
                    None => (target, None),
                };
                let file = if path.is_empty() {
                    root().join(&name)
                } else {
                    dir.join(path)
                };
                if !file.exists() {
                    failures.push(format!("{name}:{}: `{target}`: no such file", i + 1));
                    continue;
                }
                if let (Some(a), true) = (anchor, path.is_empty() || path.ends_with(".md")) {
                    let target_text = std::fs::read_to_string(&file).unwrap_or_default();
                    if !headings(&target_text).iter().any(|h| h == a) {
                        failures.push(format!("{name}:{}: `{target}`: no heading `#{a}`", i + 1));
                    }
                }
            }
        }
    }
    assert!(
        failures.is_empty(),
        "broken links:\n{}",
        failures.join("\n")
    );
}
