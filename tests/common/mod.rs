//! Helpers shared by the CLI tests: the real binary, run from the repository root.

#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// The repository root.
pub fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

/// Runs `icrflow` with `args` from the repository root.
pub fn icrflow(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_icrflow"))
        .args(args)
        .current_dir(root())
        .output()
        .expect("running icrflow")
}

/// A fresh scratch directory for one test.
pub fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("icrflow-cli-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}
