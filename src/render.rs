//! `icrflow render REC.rrd --at END|STEP --out PNG [--size WxH]`: a picture of a recording as
//! the Rerun viewer shows it, headless. The work is the visualizer's render mode
//! (`icrflow-visualizer --render ...`, see `visualizer/README.md`): Rerun stays out of this
//! binary. This checks the arguments and finds the viewer.

use std::path::{Path, PathBuf};
use std::process::Command;

use anyhow::{Context as _, Result, bail};

/// Renders `rrd` at `at` (`END` or a plan step) into the PNG `out`, `size` (`WxH`) large.
pub fn run(rrd: &Path, at: &str, out: &Path, size: &str) -> Result<u8> {
    if !rrd.is_file() {
        bail!("no recording at {}", rrd.display());
    }
    if !(at.eq_ignore_ascii_case("end") || at.parse::<u64>().is_ok()) {
        bail!("--at {at:?}: expected END or a plan step number (0, 1, ...)");
    }
    let dims = size
        .split_once(['x', 'X'])
        .and_then(|(w, h)| Some((w.parse::<u32>().ok()?, h.parse::<u32>().ok()?)));
    if !dims.is_some_and(|(w, h)| (64..=8192).contains(&w) && (64..=8192).contains(&h)) {
        bail!("--size {size:?}: expected WIDTHxHEIGHT, e.g. 1280x720 (64 to 8192 each)");
    }
    let viewer = viewer()?;
    // A file the viewer cannot read would leave it waiting for data until the render's
    // time-out: refuse it by its header (every Rerun 0.36 file starts with `RRF2`).
    let mut head = [0u8; 4];
    let read = std::fs::File::open(rrd)
        .and_then(|mut f| std::io::Read::read_exact(&mut f, &mut head))
        .is_ok();
    if !read || &head != b"RRF2" {
        bail!(
            "{} is not a Rerun recording: it does not start with the RRF2 header of Rerun 0.36 files",
            rrd.display()
        );
    }
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
