//! What `run` says on stderr while it works: its messages ([`say_line`], through `say!`), and one status line
//! ([`Status`]): redrawn in place on a terminal, a plain line every [`LINE_EVERY`] otherwise
//! (a log, a pipe, a test).
//!
//! On a terminal, a message first clears the status line, which is drawn again at the next
//! update (the node processes write to the same terminal, and may break into it: the next
//! update draws it whole again).

use std::io::{IsTerminal, Write};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

/// How often a plain status line is printed when stderr is not a terminal.
pub const LINE_EVERY: Duration = Duration::from_secs(3);

/// How often the status line is redrawn on a terminal.
const REDRAW: Duration = Duration::from_millis(200);

/// Whether a status line is on the terminal now (cleared before a message).
static SHOWN: AtomicBool = AtomicBool::new(false);

/// Says `text` on stderr as a line of its own, clearing the status line first if one shows.
pub fn say_line(text: std::fmt::Arguments<'_>) {
    let mut err = std::io::stderr().lock();
    if SHOWN.swap(false, Ordering::Relaxed) {
        let _ = write!(err, "\r\x1b[K");
    }
    let _ = writeln!(err, "{text}");
}

/// `eprintln!` for `run`: a line of its own, clearing the status line first ([`say`]).
macro_rules! say {
    ($($t:tt)*) => {
        $crate::run::status::say_line(format_args!($($t)*))
    };
}
pub(crate) use say;

/// The status line.
pub struct Status {
    terminal: bool,
    /// When it was last drawn or printed.
    last: Option<Instant>,
}

impl Default for Status {
    fn default() -> Self {
        Self {
            terminal: std::io::stderr().is_terminal(),
            last: None,
        }
    }
}

impl Status {
    /// Whether an update now would be drawn (on a terminal every [`REDRAW`], else every
    /// [`LINE_EVERY`]); `now` forces one.
    pub fn due(&self, now: bool) -> bool {
        let every = if self.terminal { REDRAW } else { LINE_EVERY };
        now || self.last.is_none_or(|t| t.elapsed() >= every)
    }

    /// Shows `text` as the status: in place on a terminal, a line otherwise; when [`due`]
    /// (`now` forces it). `text` is built only then.
    ///
    /// [`due`]: Status::due
    pub fn update(&mut self, now: bool, text: impl FnOnce() -> String) {
        if !self.due(now) {
            return;
        }
        self.last = Some(Instant::now());
        let text = text();
        let mut err = std::io::stderr().lock();
        if self.terminal {
            // Cut to the terminal's usual width: a wrapped line cannot be redrawn in place.
            let cut: String = text.chars().take(99).collect();
            let _ = write!(err, "\r\x1b[K{cut}");
            let _ = err.flush();
            SHOWN.store(true, Ordering::Relaxed);
        } else {
            let _ = writeln!(err, "{text}");
        }
    }

    /// Clears the status line (on a terminal), before the summary.
    pub fn clear(&mut self) {
        if SHOWN.swap(false, Ordering::Relaxed) {
            let _ = write!(std::io::stderr().lock(), "\r\x1b[K");
        }
    }
}
