//! Helpers shared by the bus and node-process tests: an isolated iceoryx2 bus and its cleanup.

#![allow(dead_code)]

use std::path::PathBuf;

use icrflow_nodes::bus::BusConfig;

/// A bus of this test process alone (its own prefix and root).
pub fn isolated(tag: &str) -> BusConfig {
    let id = format!("icrt_{tag}_{}_", std::process::id());
    let root = PathBuf::from(format!("/tmp/icrflow-test-{tag}-{}", std::process::id()));
    BusConfig::new("test", &id, root).unwrap()
}

/// Files of this run left in /dev/shm (but the one global counter iceoryx2 keeps by design)
/// and under its root.
pub fn leftovers(c: &BusConfig) -> Vec<String> {
    let mut out = Vec::new();
    for e in std::fs::read_dir("/dev/shm").unwrap().flatten() {
        let n = e.file_name().to_string_lossy().into_owned();
        if n.starts_with(&c.prefix) && !n.ends_with("global_mgmt") {
            out.push(n);
        }
    }
    fn walk(p: &std::path::Path, out: &mut Vec<String>) {
        if let Ok(rd) = std::fs::read_dir(p) {
            for e in rd.flatten() {
                let path = e.path();
                if path.is_dir() {
                    walk(&path, out);
                } else {
                    out.push(path.display().to_string());
                }
            }
        }
    }
    walk(&c.root, &mut out);
    out
}

pub fn remove(c: &BusConfig) {
    for e in std::fs::read_dir("/dev/shm").unwrap().flatten() {
        if e.file_name().to_string_lossy().starts_with(&c.prefix) {
            let _ = std::fs::remove_file(e.path());
        }
    }
    let _ = std::fs::remove_dir_all(&c.root);
}
