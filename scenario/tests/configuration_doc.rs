//! The configuration reference, `docs/configuration.md`, lists every key: each bounded key of
//! `bounds::KEYS` on a row that gives its allowed values, and every key of the raw serde
//! structs (`src/raw.rs`, the keys a config file may have).

#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    reason = "a test, bench or example: a panic is its failure, with the message it gives"
)]

use std::path::{Path, PathBuf};

use icrflow_scenario::bounds::KEYS;

fn manifest() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn read(path: &Path) -> String {
    std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

fn reference() -> String {
    read(&manifest().join("../docs/configuration.md"))
}

/// The keys of the raw serde structs, as `section.key` (`grasp.contacts[i].point` for an array
/// of tables): each struct's or enum variant's fields, prefixed by where the struct sits.
fn raw_keys() -> Vec<String> {
    let source = read(&manifest().join("src/raw.rs"));
    let prefix = |item: &str| -> Option<&str> {
        Some(match item {
            "RawObject" => "object",
            "RawGrasp" => "grasp",
            "RawContact" => "grasp.contacts[i]",
            "RawHand" => "hand",
            "RawFinger" => "hand.fingers[i]",
            "RawPlan" => "plan",
            "RawPipeline" => "pipeline",
            "RawPlant" => "plant",
            "RawZenoh" => "zenoh",
            "RawVisualizer" => "visualizer",
            // The sections themselves.
            "RawConfig" => return None,
            other => panic!("src/raw.rs: {other} is not known to this test: add its section"),
        })
    };
    let mut keys = Vec::new();
    let mut current: Option<&str> = None;
    let mut items = 0;
    for line in source.lines() {
        let t = line.trim();
        if let Some(rest) = t
            .strip_prefix("pub struct ")
            .or_else(|| t.strip_prefix("pub enum "))
        {
            let name = rest.split([' ', '{']).next().unwrap_or_default();
            current = prefix(name);
            items += 1;
            continue;
        }
        if t == "}" && !line.starts_with(' ') {
            current = None;
            continue;
        }
        let Some(section) = current else { continue };
        // A field: `pub name: Type,` in a struct, `name: Type,` in an enum variant.
        let field = t.strip_prefix("pub ").unwrap_or(t);
        if let Some((name, _)) = field.split_once(": ")
            && !name.is_empty()
            && name.chars().all(|c| c.is_ascii_lowercase() || c == '_')
        {
            keys.push(format!("{section}.{name}"));
        }
    }
    assert!(items >= 11, "src/raw.rs: {items} structs read");
    keys.push("object.shape".into());
    keys.sort();
    keys.dedup();
    keys
}

#[test]
fn every_bounded_key_is_in_the_reference_with_its_range() {
    let doc = reference();
    let mut missing = Vec::new();
    for (key, bound) in KEYS {
        let allowed = bound.allowed();
        let found = doc
            .lines()
            .any(|l| l.contains(&format!("`{key}`")) && l.contains(&allowed));
        if !found {
            missing.push(format!("{key}: {allowed}"));
        }
    }
    assert!(
        missing.is_empty(),
        "docs/configuration.md has no row naming these keys with their allowed values: {missing:#?}"
    );
}

#[test]
fn every_key_of_the_raw_structs_is_in_the_reference() {
    let doc = reference();
    let keys = raw_keys();
    assert!(keys.len() > 80, "{} keys read: {keys:?}", keys.len());
    for key in [
        "plan.axis",
        "grasp.contacts[i].point",
        "hand.fingers[i].tip_link",
    ] {
        assert!(keys.iter().any(|k| k == key), "{key} not read: {keys:?}");
    }
    let missing: Vec<&String> = keys
        .iter()
        .filter(|k| !doc.contains(&format!("| `{k}` |")))
        .collect();
    assert!(
        missing.is_empty(),
        "docs/configuration.md has no row for these keys: {missing:?}"
    );
}
