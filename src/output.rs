//! Writing output files atomically: the data goes to a temporary file in the
//! destination's directory, which is renamed over the destination only once
//! everything is written and flushed. A failed run leaves no half-written file.

use std::fs;
use std::io::{self, BufWriter, Write};
use std::path::Path;

/// Writes `path` atomically with the bytes produced by `write`.
///
/// A destination that exists but is not a regular file (`/dev/null`, a
/// FIFO, a terminal) is written directly: renaming over it would replace the
/// device with a file.
pub fn write_atomic(
    path: &Path,
    write: impl FnOnce(&mut dyn Write) -> io::Result<()>,
) -> io::Result<()> {
    if let Ok(meta) = fs::metadata(path) {
        if !meta.is_file() && !meta.is_dir() {
            let mut w = BufWriter::new(fs::OpenOptions::new().write(true).open(path)?);
            write(&mut w)?;
            return w.flush();
        }
    }
    let tmp = temp_path(path)?;
    let result = (|| {
        let file = fs::File::create(&tmp)?;
        let mut w = BufWriter::new(file);
        write(&mut w)?;
        let file = w.into_inner().map_err(|e| e.into_error())?;
        file.sync_all()?;
        fs::rename(&tmp, path)
    })();
    if result.is_err() {
        let _ = fs::remove_file(&tmp);
    }
    result
}

/// The temporary beside `path` that is renamed over it: `.NAME.PID.tmp` in
/// the same directory (a rename never crosses a device).
fn temp_path(path: &Path) -> io::Result<std::path::PathBuf> {
    let dir = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    let name = path
        .file_name()
        .ok_or_else(|| io::Error::new(io::ErrorKind::InvalidInput, "not a file name"))?;
    Ok(dir.join(format!(
        ".{}.{}.tmp",
        name.to_string_lossy(),
        std::process::id()
    )))
}

/// A function writing a file's bytes.
pub type WriteFn<'a> = Box<dyn FnOnce(&mut dyn Write) -> io::Result<()> + 'a>;

/// A file for [`write_atomic_all`]: its path and the function writing its
/// bytes.
pub type FileWriter<'a> = (&'a Path, WriteFn<'a>);

/// Writes several files that belong together (a model split over files):
/// every file goes to its temporary first, and the temporaries are renamed
/// into place only once all of them are written, so a failed run leaves
/// none of the files changed (short of a rename failing midway, which is
/// checked for beforehand). On error, the failing path is returned with the
/// error.
pub fn write_atomic_all<'a>(files: Vec<FileWriter<'a>>) -> Result<(), (&'a Path, io::Error)> {
    let mut temps: Vec<(std::path::PathBuf, &Path)> = Vec::new();
    let cleanup = |temps: &[(std::path::PathBuf, &Path)]| {
        for (t, _) in temps {
            let _ = fs::remove_file(t);
        }
    };
    for (path, write) in files {
        let result = (|| {
            let tmp = temp_path(path)?;
            temps.push((tmp.clone(), path));
            let file = fs::File::create(&tmp)?;
            let mut w = BufWriter::new(file);
            write(&mut w)?;
            let file = w.into_inner().map_err(|e| e.into_error())?;
            file.sync_all()
        })();
        if let Err(e) = result {
            cleanup(&temps);
            return Err((path, e));
        }
    }
    // the renames are the only step left that can fail: a destination that
    // is a directory is the likely cause, so refuse before renaming any
    for (_, path) in &temps {
        if fs::metadata(path).is_ok_and(|m| m.is_dir()) {
            cleanup(&temps);
            return Err((path, io::Error::other("a directory is in the way")));
        }
    }
    for (i, (tmp, path)) in temps.iter().enumerate() {
        if let Err(e) = fs::rename(tmp, path) {
            cleanup(&temps[i..]);
            return Err((path, e));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn failed_write_leaves_nothing() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("out.csv");
        let r = write_atomic(&p, |w| {
            w.write_all(b"partial")?;
            Err(io::Error::other("boom"))
        });
        assert!(r.is_err());
        assert!(!p.exists());
        assert_eq!(fs::read_dir(dir.path()).unwrap().count(), 0);
        write_atomic(&p, |w| w.write_all(b"ok")).unwrap();
        assert_eq!(fs::read_to_string(&p).unwrap(), "ok");
    }

    #[cfg(unix)]
    #[test]
    fn devices_are_written_not_replaced() {
        let null = Path::new("/dev/null");
        let before = fs::metadata(null).unwrap();
        assert!(!before.is_file());
        write_atomic(null, |w| w.write_all(b"discarded")).unwrap();
        let after = fs::metadata(null).unwrap();
        assert!(!after.is_file(), "/dev/null must stay a device");
    }

    #[test]
    fn failed_set_leaves_nothing() {
        let dir = tempfile::tempdir().unwrap();
        let (a, b) = (dir.path().join("m.tra"), dir.path().join("m.lab"));
        let r = write_atomic_all(vec![
            (
                a.as_path(),
                Box::new(|w: &mut dyn Write| w.write_all(b"1 0\n")),
            ),
            (
                b.as_path(),
                Box::new(|_: &mut dyn Write| Err(io::Error::other("disk full"))),
            ),
        ]);
        assert_eq!(r.unwrap_err().0, b.as_path());
        assert_eq!(fs::read_dir(dir.path()).unwrap().count(), 0);
        write_atomic_all(vec![
            (a.as_path(), Box::new(|w: &mut dyn Write| w.write_all(b"a"))),
            (b.as_path(), Box::new(|w: &mut dyn Write| w.write_all(b"b"))),
        ])
        .unwrap();
        assert_eq!(fs::read(&a).unwrap(), b"a");
        assert_eq!(fs::read(&b).unwrap(), b"b");
        assert_eq!(fs::read_dir(dir.path()).unwrap().count(), 2);
    }
}
