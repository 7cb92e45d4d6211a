//! Progress of loading a mesh and building the grasp problem, drawn on stderr, and the
//! warning for large meshes.
//!
//! The grasp library reports its stages ([`icrflow_grasp::progress`]); this draws them once
//! the whole has taken longer than `--progress-after` (1 s by default): a bar on a terminal,
//! else plain lines, one when a stage ends (`progress   reading the mesh: 2002224 faces in
//! 3.41 s`) and one every 2 s inside a long stage. A mesh file of more than
//! [`LARGE_MESH_FACES`] faces gets a warning as soon as its size is known, whatever the delay.

use std::io::{IsTerminal, Write};
use std::time::{Duration, Instant};

use icrflow_grasp::progress::{Progress, Stage};

/// Faces of a mesh file above which `validate`, `analyze` and `plan` warn of the cost (and
/// say what to do): docs/configuration.md, "Large meshes".
pub const LARGE_MESH_FACES: usize = 500_000;

/// Seconds per million faces, measured (BENCHMARKS.md, "Large meshes"), for the warning:
/// loading and checking the mesh and building the grasp problem; then analyze's ICRs.
const LOAD_S_PER_MILLION: f64 = 6.0;

/// Interval between two plain lines inside one stage.
const LINE_EVERY: Duration = Duration::from_secs(2);

/// Draws progress reports on stderr (see the module's docs).
pub struct Shown {
    start: Instant,
    after: Duration,
    bar: Option<indicatif::ProgressBar>,
    terminal: bool,
    visible: bool,
    /// The current stage and when it started.
    stage: Option<(Stage, Instant)>,
    last_line: Instant,
    warned: bool,
}

impl Shown {
    /// Progress shown once the whole has taken `after`.
    pub fn new(after: Duration) -> Self {
        let now = Instant::now();
        Self {
            start: now,
            after,
            bar: None,
            terminal: std::io::stderr().is_terminal(),
            visible: after.is_zero(),
            stage: None,
            last_line: now,
            warned: false,
        }
    }

    /// Clears the bar (the plain lines stay).
    pub fn finish(&mut self) {
        if let Some(bar) = self.bar.take() {
            bar.finish_and_clear();
        }
    }

    fn warn_large(&mut self, faces: usize) {
        if self.warned || faces <= LARGE_MESH_FACES {
            return;
        }
        self.warned = true;
        let millions = faces as f64 / 1e6;
        let text = format!(
            "warning    the mesh has {faces} faces (more than {LARGE_MESH_FACES}): expect ~{:.0} s to load it and build the grasp problem, and far longer for analyze and plan (BENCHMARKS.md, \"Large meshes\"); the grasp quality changes little above ~100000 faces: decimate it (docs/configuration.md, \"Large meshes\")",
            LOAD_S_PER_MILLION * millions
        );
        self.line(&text);
    }

    /// One line on stderr, above the bar if there is one.
    fn line(&self, text: &str) {
        match &self.bar {
            Some(bar) => bar.println(text),
            None => {
                let _ = writeln!(std::io::stderr().lock(), "{text}");
            }
        }
    }
}

impl Progress for Shown {
    fn report(&mut self, stage: Stage, done: usize, total: usize) {
        let now = Instant::now();
        if stage == Stage::Read {
            self.warn_large(total.max(done));
        }
        let first = self.stage.is_none_or(|(s, _)| s != stage);
        if first {
            self.stage = Some((stage, now));
        }
        let since = self.stage.map_or(now, |(_, t)| t);
        if !self.visible && now.duration_since(self.start) >= self.after {
            self.visible = true;
        }
        if !self.visible {
            return;
        }
        let ended = !first && done == total;
        if self.terminal {
            let bar = self.bar.get_or_insert_with(|| {
                let bar = indicatif::ProgressBar::new(0);
                if let Ok(style) = indicatif::ProgressStyle::with_template(
                    "{msg:40} {bar:30} {pos:>9}/{len:9} {elapsed_precise}",
                ) {
                    bar.set_style(style);
                }
                bar
            });
            bar.set_message(stage.describe());
            bar.set_length(total as u64);
            bar.set_position(done as u64);
            if ended {
                bar.println(format!(
                    "progress   {}: {done} {} in {:.2} s",
                    stage.describe(),
                    stage.unit(),
                    now.duration_since(since).as_secs_f64()
                ));
            }
        } else if ended {
            self.line(&format!(
                "progress   {}: {done} {} in {:.2} s",
                stage.describe(),
                stage.unit(),
                now.duration_since(since).as_secs_f64()
            ));
            self.last_line = now;
        } else if now.duration_since(self.last_line) >= LINE_EVERY {
            let of = if total > 0 {
                format!(" of {total} ({:.0} %)", 100.0 * done as f64 / total as f64)
            } else {
                String::new()
            };
            self.line(&format!(
                "progress   {}: {done}{of} {} so far, {:.1} s",
                stage.describe(),
                stage.unit(),
                now.duration_since(since).as_secs_f64()
            ));
            self.last_line = now;
        }
    }
}

impl Drop for Shown {
    fn drop(&mut self) {
        self.finish();
    }
}

/// The `--progress-after` value: seconds, 0 to 3600.
pub fn parse_after(text: &str) -> Result<Duration, String> {
    let seconds: f64 = text
        .trim()
        .parse()
        .map_err(|_| format!("{text:?} is not a number of seconds"))?;
    if !(0.0..=3600.0).contains(&seconds) {
        return Err(format!("{text} s is outside 0 to 3600 s"));
    }
    Ok(Duration::from_secs_f64(seconds))
}
