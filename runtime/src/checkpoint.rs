//! A node's state kept on disk for its restart, written beside its loop.

use std::path::PathBuf;
use std::time::Duration;

use anyhow::{Context as _, Result};

/// Period of a [`Checkpoint`]'s writes.
pub const CHECKPOINT_PERIOD: Duration = Duration::from_millis(10);

/// A file in which a node keeps the state a restarted incarnation resumes from, written off
/// the event loop: the loop only stores the newest text in memory ([`Checkpoint::store`]: no
/// system call, no allocation once the text has grown to its longest), and a thread of the
/// node writes it, to a temporary file renamed over the file, every [`CHECKPOINT_PERIOD`] when
/// it changed, and once more when the checkpoint is dropped.
///
/// On the loop itself the write cost the plant and the estimator a tick: a write and a rename
/// take ~1.3 ms p50 (2.6 ms p99) on the test VM's ext4 `/tmp`, so every tenth 1 kHz tick was
/// late and its measurement went out back to back with the next one.
pub struct Checkpoint {
    shared: std::sync::Arc<CheckpointState>,
    writer: Option<std::thread::JoinHandle<()>>,
}

struct CheckpointState {
    /// The newest text, and whether the writer has not taken it yet.
    newest: std::sync::Mutex<(String, bool)>,
    stop: std::sync::atomic::AtomicBool,
}

impl Checkpoint {
    /// Keeps `path` up to date from its own thread (named after the file).
    pub fn new(path: PathBuf) -> Result<Self> {
        let shared = std::sync::Arc::new(CheckpointState {
            newest: std::sync::Mutex::new((String::with_capacity(1024), false)),
            stop: std::sync::atomic::AtomicBool::new(false),
        });
        let state = shared.clone();
        let writer = std::thread::Builder::new()
            .name("checkpoint".into())
            .spawn(move || {
                let tmp = path.with_extension("tmp");
                let mut text = String::with_capacity(1024);
                loop {
                    let stopping = state.stop.load(std::sync::atomic::Ordering::Acquire);
                    let fresh = {
                        let mut newest = state.newest.lock().unwrap_or_else(|e| e.into_inner());
                        let fresh = std::mem::take(&mut newest.1);
                        if fresh {
                            text.clear();
                            text.push_str(&newest.0);
                        }
                        fresh
                    };
                    if fresh && std::fs::write(&tmp, &text).is_ok() {
                        let _ = std::fs::rename(&tmp, &path);
                    }
                    if stopping {
                        return;
                    }
                    std::thread::park_timeout(CHECKPOINT_PERIOD);
                }
            })
            .context("starting the checkpoint thread")?;
        Ok(Self {
            shared,
            writer: Some(writer),
        })
    }

    /// Replaces the text to write by what `fill` writes into the (cleared) kept buffer.
    pub fn store(&self, fill: impl FnOnce(&mut String)) {
        let mut newest = self.shared.newest.lock().unwrap_or_else(|e| e.into_inner());
        newest.0.clear();
        fill(&mut newest.0);
        newest.1 = true;
    }
}

impl Drop for Checkpoint {
    /// Writes the newest text, if the writer has not yet, and stops the thread.
    fn drop(&mut self) {
        self.shared
            .stop
            .store(true, std::sync::atomic::Ordering::Release);
        if let Some(writer) = self.writer.take() {
            writer.thread().unpark();
            let _ = writer.join();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scratch(name: &str) -> PathBuf {
        let dir =
            std::env::temp_dir().join(format!("icrflow-checkpoint-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }

    #[test]
    fn checkpoint_writes_the_newest_text_from_its_thread_and_on_drop() {
        let dir = scratch("newest");
        let path = dir.join("node.state");
        let saved = Checkpoint::new(path.clone()).unwrap();
        saved.store(|t| t.push_str("one"));
        saved.store(|t| t.push_str("2 2"));
        // The writer gets there by itself, without a drop.
        let deadline = std::time::Instant::now() + Duration::from_secs(10);
        while std::fs::read_to_string(&path).ok().as_deref() != Some("2 2") {
            assert!(
                std::time::Instant::now() < deadline,
                "the checkpoint thread never wrote the newest text"
            );
            std::thread::sleep(Duration::from_millis(5));
        }
        // The last text stored is written when the checkpoint goes, however soon.
        saved.store(|t| t.push_str("3 3 3"));
        drop(saved);
        assert_eq!(std::fs::read_to_string(&path).unwrap(), "3 3 3");
        assert!(!path.with_extension("tmp").exists(), "temporary file left");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn checkpoint_into_a_missing_directory_fails_quietly() {
        let dir = scratch("missing");
        let path = dir.join("gone").join("node.state");
        let saved = Checkpoint::new(path.clone()).unwrap();
        saved.store(|t| t.push_str("one"));
        drop(saved);
        assert!(!path.exists());
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
