//! Why a run stops ([`StopReason`]), as its summary says it.

use std::fmt;
use std::time::Duration;

/// Why the run stopped.
#[derive(Debug, Clone, PartialEq)]
pub enum StopReason {
    /// The plan is done and the object at the goal.
    GoalReached,
    /// SIGTERM or SIGINT (Ctrl-C).
    Signal,
    /// SIGHUP: the terminal closed.
    Hangup,
    /// The supervisor gave up on this essential node.
    NodeFailed(String),
    /// The run took longer than its time limit (`watch::TIMEOUT`).
    TimedOut(Duration),
    /// Plans made again from the estimate get nowhere (the reason
    /// `track::ReplanProgress::replanned` gives).
    ReplanStuck(String),
    /// The plan ended at `step` with the object at `rotation` (rad), short of the goal.
    PlanEndedShort {
        /// The last plan step.
        step: u64,
        /// The object's rotation (rad).
        rotation: f64,
    },
    /// No plan step came after `step` for `since` (`pipeline.max_hold_s`) while the hand
    /// tracked.
    PlanStalled {
        /// The last plan step.
        step: u64,
        /// Since it came.
        since: Duration,
        /// The object's rotation (rad).
        rotation: f64,
    },
    /// The hand held for `since` (`pipeline.max_hold_s`), for `reason`.
    HandHeld {
        /// Since when it holds.
        since: Duration,
        /// The last hold's reason.
        reason: String,
    },
    /// Waiting for the bus failed.
    WaitFailed(String),
}

impl StopReason {
    /// Whether a signal stopped the run (a `--live` run ends so, successfully).
    pub fn by_signal(&self) -> bool {
        matches!(self, Self::Signal | Self::Hangup)
    }
}

impl fmt::Display for StopReason {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::GoalReached => f.write_str("goal reached"),
            Self::Signal => f.write_str("stopped by a signal (Ctrl-C or SIGTERM)"),
            Self::Hangup => f.write_str("stopped by SIGHUP (the terminal closed)"),
            Self::NodeFailed(n) => write!(f, "node {n} failed too often"),
            Self::TimedOut(t) => write!(f, "timed out after {t:?}"),
            Self::ReplanStuck(why) => f.write_str(why),
            Self::PlanEndedShort { step, rotation } => write!(
                f,
                "gave up: the plan ended at step {step} with the object at {:.1} deg, short of the goal (see the planner's messages)",
                rotation.to_degrees()
            ),
            Self::PlanStalled {
                step,
                since,
                rotation,
            } => write!(
                f,
                "gave up: no plan step after step {step} for {:.1} s (pipeline.max_hold_s); the object at {:.1} deg",
                since.as_secs_f64(),
                rotation.to_degrees()
            ),
            Self::HandHeld { since, reason } => write!(
                f,
                "gave up: the hand held for {:.1} s (pipeline.max_hold_s): {reason}",
                since.as_secs_f64()
            ),
            Self::WaitFailed(why) => write!(f, "waiting for the bus failed: {why}"),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_reasons_read_as_the_summaries_said_them_and_only_signals_are_interruptions() {
        let held = StopReason::HandHeld {
            since: Duration::from_millis(30_040),
            reason: "no plan step yet".into(),
        };
        assert_eq!(
            held.to_string(),
            "gave up: the hand held for 30.0 s (pipeline.max_hold_s): no plan step yet"
        );
        let stalled = StopReason::PlanStalled {
            step: 12,
            since: Duration::from_secs(31),
            rotation: std::f64::consts::FRAC_PI_2,
        };
        assert_eq!(
            stalled.to_string(),
            "gave up: no plan step after step 12 for 31.0 s (pipeline.max_hold_s); the object at 90.0 deg"
        );
        assert_eq!(
            StopReason::TimedOut(Duration::from_secs(600)).to_string(),
            "timed out after 600s"
        );
        for (r, by_signal) in [
            (StopReason::Signal, true),
            (StopReason::Hangup, true),
            (StopReason::GoalReached, false),
            (StopReason::NodeFailed("plant".into()), false),
            (held, false),
        ] {
            assert_eq!(r.by_signal(), by_signal, "{r}");
            assert_eq!(r.to_string().starts_with("stopped by"), by_signal, "{r}");
        }
    }
}
