//! Helpers shared by the CLI tests: the real binary, run from the repository root.

#![allow(dead_code)]

use std::path::PathBuf;
use std::process::{Command, Output};

/// The repository root.
pub fn root() -> PathBuf {
    PathBuf::from(manifest_dir())
}
/// The package's directory, as cargo gives it when running the test (a test binary cached from
/// another checkout of the same commit would carry that checkout's compile-time path).
fn manifest_dir() -> std::ffi::OsString {
    std::env::var_os("CARGO_MANIFEST_DIR").unwrap_or_else(|| env!("CARGO_MANIFEST_DIR").into())
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

/// The Python interpreter of the test venv (scripts/setup-python.sh installs eclipse-zenoh).
pub fn python() -> String {
    if let Ok(py) = std::env::var("ICRFLOW_PYTHON") {
        return py;
    }
    let out = Command::new(root().join("scripts/setup-python.sh"))
        .output()
        .expect("running scripts/setup-python.sh");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout)
        .unwrap()
        .lines()
        .last()
        .unwrap()
        .trim()
        .to_string()
}

/// What the Python Rerun SDK reads in the recording `rrd` (tests/read_rrd.py), its
/// `entities` checked to hold every one of `expected`.
pub fn recorded(rrd: &std::path::Path, expected: &[&str]) -> serde_json::Value {
    let r = Command::new(python())
        .arg(root().join("tests/read_rrd.py"))
        .arg(rrd)
        .output()
        .unwrap();
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let r: serde_json::Value = serde_json::from_slice(&r.stdout).unwrap();
    let entities = r["entities"].to_string();
    for e in expected {
        assert!(
            entities.contains(&format!("\"{e}\"")),
            "{e} missing: {entities}"
        );
    }
    r
}
