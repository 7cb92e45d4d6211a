//! The hand commands as the run sees them: tracking (quality, latency, staleness) and holds,
//! counted by cause ([`HoldCause`]) and reported on stderr while they last.

use std::collections::btree_map::Entry;
use std::time::{Duration, Instant};

use icrflow_interfaces::topics::TopicId;
use icrflow_interfaces::{CommandMode, HandCommand, read_text};

use super::Watch;
use crate::run::hold_cause::HoldCause;
use crate::run::status::say;
use crate::run::summary::BelowMarginAttaches;

/// A hold this long is reported on stderr, and again every time as long.
const HOLD_REPORT: Duration = Duration::from_secs(1);

/// The text a hold because of the estimate starts with (the command node's
/// `Hold::Estimate`).
const ESTIMATE_OFF: &str = "the estimate is off";

impl Watch {
    /// A hand command.
    pub(super) fn command(&mut self, c: &HandCommand) {
        self.sent += 1;
        self.arrived.insert(TopicId::HandCommand.name());
        if CommandMode::moves(c.mode) {
            self.tracked = true;
            if let Some((since, _)) = self.holding.take()
                && since.elapsed() >= HOLD_REPORT
            {
                say!(
                    "run: the hand tracks again after holding {:.1} s",
                    since.elapsed().as_secs_f64()
                );
            }
            if c.mode == CommandMode::Attach as u32 {
                // Below the margin, a finger attaching with the others held: said once a
                // spell, counted apart from tracking (whose minimum alpha* it is not).
                let a = self
                    .attaching_below_margin
                    .get_or_insert(BelowMarginAttaches {
                        commands: 0,
                        min_quality: f64::INFINITY,
                    });
                a.commands += 1;
                a.min_quality = a.min_quality.min(c.quality);
                if !self.attaching {
                    say!("run: {}", read_text(&c.reason));
                }
                self.attaching = true;
            } else {
                self.attaching = false;
                self.min_quality = self.min_quality.min(c.quality);
            }
            self.truth.tracked(1, self.limits.estimate_bound);
            self.doubting = false;
            self.timing.add(c.header.trace.as_slice());
            if c.header.origin_time_ns > 0 {
                let made = c.header.source_time_ns;
                if made.saturating_sub(c.header.origin_time_ns) > self.limits.max_age_ns {
                    self.stale_tracked += 1;
                }
            }
            return;
        }
        let reason = read_text(&c.reason);
        // The start-up: not a hold of the run, and no reason to give up (the planner node's
        // failure is the supervisor's).
        if !self.tracked && startup_hold(&reason) {
            self.startup_holds += 1;
            return;
        }
        self.holds += 1;
        self.attaching = false;
        let cause = HoldCause::of(&reason);
        *self.hold_causes.entry(cause.key()).or_default() += 1;
        match self.hold_figures.entry(cause.key()) {
            Entry::Vacant(e) => {
                e.insert(cause);
            }
            Entry::Occupied(mut e) => e.get_mut().widen(&cause),
        }
        self.hold_reason = c.reason;
        if c.reason.starts_with(ESTIMATE_OFF.as_bytes()) {
            self.estimate_holds += 1;
            // Said at once, once a spell: the loop noticed its estimate is wrong.
            if !self.doubting {
                say!("run: the hand holds: {reason}");
            }
            self.doubting = true;
        } else {
            self.doubting = false;
        }
        // A hold longer than HOLD_REPORT is reported (with its reason), then every
        // HOLD_REPORT again; short ones only count.
        let now = Instant::now();
        let (since, reported) = self.holding.get_or_insert((now, now));
        if now.duration_since(*reported) >= HOLD_REPORT {
            *reported = now;
            say!(
                "run: the hand has held for {:.1} s: {reason}",
                now.duration_since(*since).as_secs_f64()
            );
        }
    }
}

/// Whether a hold before the hand first tracked, for `reason`, is the start-up's: the hand
/// holds its initial grasp until every input has come (`no plan step yet`, while the planner
/// node plans), or answers a wrench space whose grasp state was published before the command
/// node's subscription was made, which it never receives (seen once, CI 2026-12-05: the nodes
/// starting in another order under load).
fn startup_hold(reason: &str) -> bool {
    (reason.starts_with("no ") && reason.ends_with(" yet"))
        || (reason.starts_with("wrench space ") && reason.ends_with(" was not received"))
}

#[cfg(test)]
mod tests {
    use super::startup_hold;

    #[test]
    fn the_start_up_holds_are_those_for_inputs_not_there_yet() {
        assert!(startup_hold("no plan step yet"));
        assert!(startup_hold(
            "wrench space 3: its grasp state 2 was not received"
        ));
        assert!(!startup_hold("no wrench space for 12.0 ms"));
        assert!(!startup_hold(
            "grasp state: stale: 12.1 ms old, limit 10.0 ms"
        ));
    }
}
