//! `icrflow render REC.rrd --at END|STEP --out PNG [--size WxH]`: a picture of a recording as
//! the Rerun viewer shows it, headless. The work is the visualizer's render mode
//! (`icrflow-visualizer --render ...`, see `visualizer/README.md`): Rerun stays out of this
//! binary. This finds the viewer and starts the render mode, which checks the arguments.

use std::ffi::OsStr;
use std::path::{Path, PathBuf};
use std::process::Command;

use anyhow::{Context as _, Result, bail};

/// Renders `rrd` at `at` (`END` or a plan step) into the PNG `out`, `size` (`WxH`) large.
pub fn run(rrd: &Path, at: &str, out: &Path, size: &str) -> Result<u8> {
    if !rrd.is_file() {
        bail!("no recording at {}", rrd.display());
    }
    // The arguments and the file are checked by the render mode (`At::parse`, `parse_size`,
    // the file's header), before it starts the viewer.
    let viewer = viewer()?;
    let program =
        crate::run::launch::node_program(icrflow_interfaces::topics::NodeRole::Visualizer)?;
    let status = Command::new(&program)
        .arg("--render")
        .arg(rrd)
        .args(["--at", at, "--size", size, "--out"])
        .arg(out)
        .arg("--viewer")
        .arg(&viewer)
        .status()
        .with_context(|| format!("starting {}", program.display()))?;
    if !status.success() {
        bail!("no picture written ({} {status})", program.display());
    }
    Ok(0)
}

/// The `rerun` viewer, from this process's environment: see [`find_viewer`].
fn viewer() -> Result<PathBuf> {
    let var = |name| std::env::var_os(name).filter(|v| !v.is_empty());
    find_viewer(
        var("ICRFLOW_PYTHON").as_deref(),
        var("ICRFLOW_CACHE").as_deref(),
        var("HOME").as_deref(),
        var("PATH").as_deref(),
    )
}

/// The `rerun` viewer: beside `python` (`$ICRFLOW_PYTHON`, a venv with rerun-sdk), else in the
/// project's venv that `scripts/setup.sh` makes (`${ICRFLOW_CACHE:-$HOME/.cache/icrflow}/venv/bin`,
/// from `cache` and `home`), else in a directory of `path` (`$PATH`); the error names every
/// place looked at.
fn find_viewer(
    python: Option<&OsStr>,
    cache: Option<&OsStr>,
    home: Option<&OsStr>,
    path: Option<&OsStr>,
) -> Result<PathBuf> {
    let mut places: Vec<PathBuf> = Vec::new();
    if let Some(python) = python {
        places.push(Path::new(python).with_file_name("rerun"));
    }
    let cache = cache
        .map(PathBuf::from)
        .or_else(|| home.map(|h| Path::new(h).join(".cache/icrflow")));
    if let Some(cache) = cache {
        places.push(cache.join("venv/bin/rerun"));
    }
    let on_path: Vec<PathBuf> = path
        .map(|p| std::env::split_paths(p).map(|d| d.join("rerun")).collect())
        .unwrap_or_default();
    if let Some(found) = places.iter().chain(&on_path).find(|p| p.is_file()) {
        return Ok(found.clone());
    }
    let looked: Vec<String> = places.iter().map(|p| p.display().to_string()).collect();
    bail!(
        "no Rerun viewer: looked at {}{}the PATH ({}); run scripts/setup.sh (it installs \
         the viewer into the project's venv), put `rerun` 0.36 on the PATH (`pip install \
         rerun-sdk==0.36.3`), or set ICRFLOW_PYTHON to the Python of a venv that has it",
        looked.join(", "),
        if looked.is_empty() { "" } else { " and " },
        if on_path.is_empty() {
            "not set".to_string()
        } else {
            format!("{} directories", on_path.len())
        }
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A scratch directory of its own, with an executable-looking `rerun` at each of `at`.
    fn scratch(name: &str, at: &[&str]) -> PathBuf {
        let dir =
            std::env::temp_dir().join(format!("icrflow-render-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        for a in at {
            let file = dir.join(a);
            std::fs::create_dir_all(file.parent().unwrap()).unwrap();
            std::fs::write(&file, "#!/bin/sh\n").unwrap();
        }
        dir
    }

    #[test]
    fn the_viewer_is_found_in_the_projects_venv_and_the_error_names_where_it_looked() {
        let dir = scratch(
            "venv",
            &[
                "cache/venv/bin/rerun",
                "home/.cache/icrflow/venv/bin/rerun",
                "bin/rerun",
                "py/rerun",
            ],
        );
        let os = |p: PathBuf| p.into_os_string();
        let (cache, home, bin) = (
            os(dir.join("cache")),
            os(dir.join("home")),
            os(dir.join("bin")),
        );
        let python = os(dir.join("py/python"));
        let empty = os(dir.join("empty"));
        // ICRFLOW_CACHE's venv, else $HOME/.cache/icrflow's; both before the PATH.
        let found = |py: Option<&OsStr>,
                     c: Option<&OsStr>,
                     h: Option<&OsStr>,
                     p: Option<&OsStr>| { find_viewer(py, c, h, p) };
        assert_eq!(
            found(None, Some(&cache), Some(&home), Some(&bin)).unwrap(),
            dir.join("cache/venv/bin/rerun")
        );
        assert_eq!(
            found(None, None, Some(&home), Some(&bin)).unwrap(),
            dir.join("home/.cache/icrflow/venv/bin/rerun")
        );
        // Beside $ICRFLOW_PYTHON first; the PATH last.
        assert_eq!(
            found(Some(&python), Some(&cache), None, Some(&bin)).unwrap(),
            dir.join("py/rerun")
        );
        assert_eq!(
            found(None, Some(&empty), None, Some(&bin)).unwrap(),
            dir.join("bin/rerun")
        );
        // None: the error names the places.
        let e = found(
            Some(&os(dir.join("nopy/python"))),
            Some(&empty),
            None,
            Some(&empty),
        )
        .unwrap_err()
        .to_string();
        for place in [dir.join("nopy/rerun"), dir.join("empty/venv/bin/rerun")] {
            assert!(e.contains(&place.display().to_string()), "{e}");
        }
        assert!(e.contains("the PATH (1 directories)"), "{e}");
        let e = found(None, None, None, None).unwrap_err().to_string();
        assert!(e.contains("looked at the PATH (not set)"), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
