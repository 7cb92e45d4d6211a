//! The output paths a verb was given, checked before it starts anything: a run that would
//! plan or drive the hand for a minute and then fail to write its summary fails at once.

use std::path::{Path, PathBuf};

use anyhow::{Result, bail};

/// What a path names.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    /// A file written in a directory that must exist (`--summary-json`).
    File,
    /// A file whose missing parent directories are created (`--rrd`).
    FileInNewDirs,
    /// A directory, created with its parents if missing (`plan --out`).
    Dir,
}

/// One output: the flag that named it, its path (if given) and what it names.
pub type Output<'a> = (&'static str, Option<&'a Path>, Kind);

/// The outputs of `run`: `--summary-json` (a file in an existing directory) and `--rrd` (the
/// visualizer creates its directories).
pub fn run<'a>(summary_json: &'a Option<PathBuf>, rrd: &'a Option<PathBuf>) -> [Output<'a>; 2] {
    [
        ("--summary-json", summary_json.as_deref(), Kind::File),
        ("--rrd", rrd.as_deref(), Kind::FileInNewDirs),
    ]
}

/// Checks every given output: a file's path is not a directory, and the directory it goes in
/// exists (or, where missing directories are created, its nearest existing ancestor does),
/// is a directory and is writable (a file is created in it and removed, which also catches
/// read-only file systems and root's lack of permission bits); a directory's path is not a
/// file. Errors name the flag and the path.
pub fn check(outputs: &[Output<'_>]) -> Result<()> {
    for &(flag, path, kind) in outputs {
        let Some(path) = path else { continue };
        if path.as_os_str().is_empty() {
            bail!("{flag}: the path is empty");
        }
        let dir = match kind {
            Kind::File | Kind::FileInNewDirs => {
                if path.is_dir() {
                    bail!("{flag}: {} is a directory, not a file", path.display());
                }
                parent(path)
            }
            Kind::Dir => {
                if path.exists() && !path.is_dir() {
                    bail!("{flag}: {} is not a directory", path.display());
                }
                path
            }
        };
        let dir = if kind == Kind::File {
            if !dir.is_dir() {
                bail!(
                    "{flag}: cannot write {}: its directory {} {}",
                    path.display(),
                    dir.display(),
                    if dir.exists() {
                        "is not a directory"
                    } else {
                        "does not exist"
                    }
                );
            }
            dir
        } else {
            // The nearest existing ancestor, which must be a directory.
            let mut at = dir;
            while !at.exists() && parent(at) != at {
                at = parent(at);
            }
            if !at.is_dir() {
                bail!(
                    "{flag}: cannot write {}: {} is not a directory",
                    path.display(),
                    at.display()
                );
            }
            at
        };
        writable(dir).map_err(|e| {
            anyhow::anyhow!(
                "{flag}: cannot write {}: directory {} is not writable ({e})",
                path.display(),
                dir.display()
            )
        })?;
    }
    Ok(())
}

/// The directory `path` is in (`.` for a bare file name; `/` stays `/`).
fn parent(path: &Path) -> &Path {
    match path.parent() {
        Some(p) if p.as_os_str().is_empty() => Path::new("."),
        Some(p) => p,
        None => path,
    }
}

/// Whether a file can be created in `dir`: creates one and removes it.
fn writable(dir: &Path) -> std::io::Result<()> {
    let probe = dir.join(format!(".icrflow-write-check-{}", std::process::id()));
    std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(&probe)?;
    std::fs::remove_file(&probe)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn outputs_are_checked_before_anything_starts() {
        let dir = std::env::temp_dir().join(format!("icrflow-output-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let file = dir.join("file");
        std::fs::write(&file, "x").unwrap();
        let ok = |o: Output<'_>| check(&[o]).map_err(|e| e.to_string());
        assert!(ok(("--summary-json", Some(&dir.join("s.json")), Kind::File)).is_ok());
        assert!(ok(("--summary-json", None, Kind::File)).is_ok());
        assert!(ok(("--rrd", Some(&dir.join("a/b/x.rrd")), Kind::FileInNewDirs)).is_ok());
        assert!(ok(("--out", Some(&dir.join("a/b")), Kind::Dir)).is_ok());
        assert!(ok(("--out", Some(&dir), Kind::Dir)).is_ok());
        let e = ok(("--summary-json", Some(&dir), Kind::File)).unwrap_err();
        assert!(
            e.contains("--summary-json") && e.contains("is a directory"),
            "{e}"
        );
        let e = ok(("--summary-json", Some(&dir.join("no/s.json")), Kind::File)).unwrap_err();
        assert!(e.contains("does not exist"), "{e}");
        let e = ok(("--out", Some(&file), Kind::Dir)).unwrap_err();
        assert!(e.contains("is not a directory"), "{e}");
        let e = ok(("--rrd", Some(&file.join("x.rrd")), Kind::FileInNewDirs)).unwrap_err();
        assert!(e.contains("is not a directory"), "{e}");
        // Nothing is left behind.
        let left: Vec<_> = std::fs::read_dir(&dir).unwrap().collect();
        assert_eq!(left.len(), 1);
        let _ = std::fs::remove_dir_all(&dir);
    }
}
