//! The Python the referee tests run (behaviortreepy, mpmath, numpy,
//! rosbags, stormpy: `tests/python-requirements.txt`).
//!
//! `BTREL_PYTHON` names it when set. Otherwise the tests make their own:
//! the venv `target/pyvenv` as `.ci/run` makes it (`python3 -m venv`, the
//! requirements' binary wheels from PyPI, the stamp `target/pyvenv/.requirements`
//! a copy of the requirements file; rebuilt only when the stamp differs).
//! Test threads and test binaries may ask at once: one attempt per process
//! (a `OnceLock`), one builder at a time (an exclusive lock on
//! `target/pyvenv.lock`), and the venv is built in a temporary directory
//! and renamed into place, so a half-built venv is never used.
//!
//! Where python3 or PyPI is unreachable the tests are skipped, loudly
//! (`SKIPPED (no Python venv): ...` on stdout of each, the reason once on
//! stderr); with `BTREL_REQUIRE_PYTHON=1` (set by `.ci/run`) they fail
//! instead.

use std::fs;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;

const MANIFEST: &str = env!("CARGO_MANIFEST_DIR");

/// The Python for the referee tests, or `None` (after saying so, naming
/// `what` is skipped) when there is none; panics instead of skipping when
/// `BTREL_REQUIRE_PYTHON=1`.
pub fn python(what: &str) -> Option<PathBuf> {
    static PYTHON: OnceLock<Result<PathBuf, String>> = OnceLock::new();
    let found = PYTHON.get_or_init(|| {
        let found = find();
        if let Err(why) = &found {
            eprintln!(
                "\n**********\n\
                 btrel tests: no Python venv ({why}).\n\
                 The referee tests (BehaviorTree.CPP, the mpmath expoly reference, the numpy \
                 anchor, rosbags, Storm) are SKIPPED. Set BTREL_PYTHON to a Python with \
                 tests/python-requirements.txt, or make python3 (with venv) and PyPI \
                 reachable; BTREL_REQUIRE_PYTHON=1 turns these skips into failures.\n\
                 **********\n"
            );
        }
        found
    });
    match found {
        Ok(p) => Some(p.clone()),
        Err(why) if required() => {
            panic!("BTREL_REQUIRE_PYTHON=1 but no Python venv for {what}: {why}")
        }
        Err(why) => {
            println!("SKIPPED (no Python venv): {what} not run: {why}");
            None
        }
    }
}

fn required() -> bool {
    std::env::var_os("BTREL_REQUIRE_PYTHON").is_some_and(|v| v == "1")
}

/// `BTREL_PYTHON`, else the ready venv (made if need be).
fn find() -> Result<PathBuf, String> {
    match std::env::var_os("BTREL_PYTHON") {
        Some(p) if !p.is_empty() => Ok(PathBuf::from(p)),
        _ => venv(),
    }
}

/// The crate's target directory: `CARGO_TARGET_DIR` (relative to the
/// crate root) when set, else `<crate root>/target`.
fn target_dir() -> PathBuf {
    match std::env::var_os("CARGO_TARGET_DIR") {
        Some(d) if !d.is_empty() => Path::new(MANIFEST).join(d),
        _ => Path::new(MANIFEST).join("target"),
    }
}

/// `venv/bin/python` when its stamp equals the requirements.
fn ready(venv: &Path, requirements: &[u8]) -> Option<PathBuf> {
    let python = venv.join("bin/python");
    let stamp = fs::read(venv.join(".requirements")).ok()?;
    (stamp == requirements && python.exists()).then_some(python)
}

fn venv() -> Result<PathBuf, String> {
    let req_path = Path::new(MANIFEST).join("tests/python-requirements.txt");
    let requirements =
        fs::read(&req_path).map_err(|e| format!("cannot read {}: {e}", req_path.display()))?;
    let target = target_dir();
    let venv = target.join("pyvenv");
    if let Some(p) = ready(&venv, &requirements) {
        return Ok(p);
    }
    fs::create_dir_all(&target).map_err(|e| format!("cannot create {}: {e}", target.display()))?;
    let lock_path = target.join("pyvenv.lock");
    let lock = fs::File::create(&lock_path)
        .map_err(|e| format!("cannot create {}: {e}", lock_path.display()))?;
    lock.lock()
        .map_err(|e| format!("cannot lock {}: {e}", lock_path.display()))?;
    // another process may have built it while this one waited
    if let Some(p) = ready(&venv, &requirements) {
        return Ok(p);
    }
    // the lock holder is the only builder: any temporary venv left is stale
    if let Ok(entries) = fs::read_dir(&target) {
        for e in entries.flatten() {
            if e.file_name().to_string_lossy().starts_with("pyvenv.tmp-") {
                let _ = fs::remove_dir_all(e.path());
            }
        }
    }
    let tmp = target.join(format!("pyvenv.tmp-{}", std::process::id()));
    let built = build(&tmp, &venv, &req_path, &requirements);
    if let Err(why) = built {
        let _ = fs::remove_dir_all(&tmp);
        return Err(why);
    }
    let old = target.join(format!("pyvenv.old-{}", std::process::id()));
    if venv.exists() {
        fs::rename(&venv, &old).map_err(|e| format!("cannot move the old venv aside: {e}"))?;
    }
    fs::rename(&tmp, &venv).map_err(|e| format!("cannot rename the new venv into place: {e}"))?;
    let _ = fs::remove_dir_all(&old);
    ready(&venv, &requirements).ok_or_else(|| format!("{} is not usable", venv.display()))
}

/// Runs a command, or says why it failed (its stderr's last lines).
fn run(cmd: &mut Command, what: &str) -> Result<(), String> {
    let out = cmd.output().map_err(|e| format!("{what}: {e}"))?;
    if out.status.success() {
        return Ok(());
    }
    let stderr = String::from_utf8_lossy(&out.stderr);
    let tail: Vec<_> = stderr.lines().rev().take(4).collect();
    let tail: Vec<_> = tail.into_iter().rev().collect();
    Err(format!(
        "{what} failed ({}): {}",
        out.status,
        tail.join(" | ")
    ))
}

/// Makes the venv in `tmp` as if at `dest` (the paths venv writes into its
/// scripts name `dest`), with the requirements and the stamp.
fn build(tmp: &Path, dest: &Path, req_path: &Path, requirements: &[u8]) -> Result<(), String> {
    eprintln!(
        "btrel tests: creating {} from tests/python-requirements.txt (PyPI, about 1-2 min)",
        dest.display()
    );
    run(
        Command::new("python3").arg("-m").arg("venv").arg(tmp),
        "python3 -m venv",
    )?;
    run(
        Command::new(tmp.join("bin/python"))
            .args([
                "-m",
                "pip",
                "install",
                "--quiet",
                "--disable-pip-version-check",
            ])
            .args(["--only-binary=:all:", "-r"])
            .arg(req_path),
        "pip install -r tests/python-requirements.txt (PyPI)",
    )?;
    // the venv's scripts (pip, activate, ...) name its directory: make them
    // name the place it is renamed to
    let (from, to) = (tmp.to_string_lossy(), dest.to_string_lossy());
    let bin = fs::read_dir(tmp.join("bin")).map_err(|e| format!("venv bin: {e}"))?;
    for entry in bin.flatten() {
        let path = entry.path();
        if path.is_symlink() {
            continue;
        }
        if let Ok(text) = fs::read_to_string(&path) {
            if text.contains(from.as_ref()) {
                fs::write(&path, text.replace(from.as_ref(), to.as_ref()))
                    .map_err(|e| format!("cannot write {}: {e}", path.display()))?;
            }
        }
    }
    fs::write(tmp.join(".requirements"), requirements)
        .map_err(|e| format!("cannot write the venv stamp: {e}"))
}
