//! The bad-input corpus (`tests/bad_input/`, described in its README): every case is refused
//! by every verb it names, with a non-zero exit status, no panic, and the expected text in
//! stderr.

#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    reason = "a test, bench or example: a panic is its failure, with the message it gives"
)]

mod common;

use std::path::{Path, PathBuf};

use common::{icrflow, root};

/// One case: its file and what its header says.
struct Case {
    path: PathBuf,
    expect: Vec<String>,
    absent: Vec<String>,
    verbs: Vec<String>,
    args: Vec<String>,
}

fn corpus() -> PathBuf {
    root().join("tests/bad_input")
}

/// The header of a case: its leading comment lines `# key: value`.
fn read(path: &Path) -> Case {
    let text = std::fs::read_to_string(path).unwrap();
    let mut case = Case {
        path: path.to_path_buf(),
        expect: Vec::new(),
        absent: Vec::new(),
        verbs: Vec::new(),
        args: Vec::new(),
    };
    for line in text.lines().take_while(|l| l.starts_with('#')) {
        let Some((key, value)) = line.trim_start_matches('#').trim().split_once(": ") else {
            continue;
        };
        match key {
            "expect" => case.expect.push(value.to_string()),
            "absent" => case.absent.push(value.to_string()),
            "verbs" => case.verbs = value.split_whitespace().map(String::from).collect(),
            "args" => case.args = value.split_whitespace().map(String::from).collect(),
            _ => {}
        }
    }
    if case.verbs.is_empty() {
        case.verbs.push("validate".into());
    }
    case
}

fn cases() -> Vec<Case> {
    let mut paths: Vec<PathBuf> = std::fs::read_dir(corpus())
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| {
            p.extension().is_some_and(|e| e == "toml")
                && !p.file_name().unwrap().to_string_lossy().starts_with('_')
        })
        .collect();
    paths.sort();
    paths.iter().map(|p| read(p)).collect()
}

#[test]
fn every_bad_input_is_refused_with_its_reason_and_no_panic() {
    let cases = cases();
    assert!(cases.len() >= 40, "only {} cases", cases.len());
    let mut failures = Vec::new();
    let mut runs = 0;
    for case in &cases {
        let name = case.path.file_name().unwrap().to_string_lossy();
        if case.expect.is_empty() {
            failures.push(format!("{name}: no `# expect:` line"));
            continue;
        }
        for verb in &case.verbs {
            let mut args = vec![verb.as_str(), case.path.to_str().unwrap()];
            args.extend(case.args.iter().map(String::as_str));
            let o = icrflow(&args);
            runs += 1;
            let err = String::from_utf8_lossy(&o.stderr);
            let what = format!("{name} ({verb})");
            if o.status.success() || o.status.code() == Some(101) || o.status.code().is_none() {
                failures.push(format!("{what}: exit status {:?}", o.status));
            }
            if err.contains("panicked") {
                failures.push(format!("{what}: panicked:\n{err}"));
            }
            for e in &case.expect {
                if !err.contains(e.as_str()) {
                    failures.push(format!("{what}: {e:?} not in stderr:\n{err}"));
                }
            }
            for a in &case.absent {
                if err.contains(a.as_str()) {
                    failures.push(format!("{what}: {a:?} in stderr:\n{err}"));
                }
            }
        }
    }
    assert!(
        failures.is_empty(),
        "{} of {runs} runs failed:\n{}",
        failures.len(),
        failures.join("\n")
    );
}

/// The good config the cases are variations of is accepted by every verb the cases use but
/// `run` (so each case fails for its own reason), and nothing is left behind.
#[test]
fn the_base_of_the_cases_is_good() {
    let base = corpus().join("_base.toml");
    let base = base.to_str().unwrap();
    for verb in ["validate", "analyze"] {
        let o = icrflow(&[verb, base]);
        assert!(
            o.status.success(),
            "{verb}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
    }
    let out = common::scratch("bad-input-base");
    let o = icrflow(&["plan", base, "--out", out.to_str().unwrap()]);
    assert!(
        o.status.success(),
        "plan: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    let _ = std::fs::remove_dir_all(&out);
}

/// A config that is missing or is a directory is said to be so.
#[test]
fn a_missing_config_or_a_directory_is_named() {
    for (config, says) in [
        ("tests/bad_input/no_such_config.toml", "No such file"),
        ("tests/bad_input", "is a directory, not a file"),
    ] {
        for verb in ["validate", "analyze", "plan", "run"] {
            let o = icrflow(&[verb, config]);
            let err = String::from_utf8_lossy(&o.stderr);
            assert_eq!(o.status.code(), Some(1), "{verb} {config}: {err}");
            assert!(
                err.contains(says) && err.contains(config),
                "{verb} {config}: {err}"
            );
        }
    }
}
