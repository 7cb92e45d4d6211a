//! `icrflow render REC.rrd --at END|STEP --out PNG [--size WxH]`: a picture of a recording as
//! the Rerun viewer shows it, headless. The work is the visualizer's render mode
//! (`icrflow-visualizer --render ...`, see `visualizer/README.md`): Rerun stays out of this
//! binary. This finds the viewer and starts the render mode, which checks the arguments.

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

/// The `rerun` viewer: beside `$ICRFLOW_PYTHON` (a venv with rerun-sdk), else on the PATH.
fn viewer() -> Result<PathBuf> {
    if let Some(python) = std::env::var_os("ICRFLOW_PYTHON") {
        let beside = Path::new(&python).with_file_name("rerun");
        if beside.is_file() {
            return Ok(beside);
        }
    }
    std::env::var_os("PATH")
        .iter()
        .flat_map(std::env::split_paths)
        .map(|d| d.join("rerun"))
        .find(|p| p.is_file())
        .context(
            "no Rerun viewer: put `rerun` 0.36 on the PATH (`pip install rerun-sdk==0.36.3`) or \
             set ICRFLOW_PYTHON to the Python of a venv that has it",
        )
}
