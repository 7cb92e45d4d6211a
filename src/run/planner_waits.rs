//! The hand waiting for the planner, as the run sees it: the spells in which the planner
//! node's plan steps say the hand waits for the planner (`PlanStepHeader::planning`:
//! the rest of the plan being made, or a plan made again from the estimate), timed by the
//! run's own clock from the first plan step that says so to the first that does not.

use std::time::Instant;

use icrflow_interfaces::PlanWait;
use serde::Serialize;

/// Spells of one kind: how many, and how long in all and at most (s).
#[derive(Debug, Default, Clone, PartialEq, Serialize)]
pub struct Spells {
    /// How many.
    pub count: u64,
    /// How long in all (s).
    pub total_s: f64,
    /// The longest (s).
    pub max_s: f64,
}

impl Spells {
    fn add(&mut self, s: f64) {
        self.count += 1;
        self.total_s += s;
        self.max_s = self.max_s.max(s);
    }
}

/// The waits for the planner after the first plan step (the start-up's is `planned_after_s`).
#[derive(Debug, Default, Clone, PartialEq, Serialize)]
pub struct PlannerWaits {
    /// At the last target planned so far, while the rest of the plan was made.
    pub ahead: Spells,
    /// For each plan made again from the estimate, in order: from the first plan step holding
    /// for it to the new plan's first target (s).
    pub again_s: Vec<f64>,
}

/// The open spell, if any, and the waits so far.
#[derive(Debug, Default)]
pub struct WaitTrack {
    open: Option<(u32, Instant)>,
    waits: PlannerWaits,
}

impl WaitTrack {
    /// A plan step saying `planning` ([`PlanWait`] as `u32`) came at `at`.
    pub fn see(&mut self, planning: u32, at: Instant) {
        if self.open.is_some_and(|(kind, _)| kind == planning) {
            return;
        }
        self.close(at);
        if planning != PlanWait::None as u32 {
            self.open = Some((planning, at));
        }
    }

    /// Whether the hand waits for the planner now.
    pub fn waiting(&self) -> bool {
        self.open.is_some()
    }

    /// The waits, one still open ended at `at`.
    pub fn summary(mut self, at: Instant) -> PlannerWaits {
        self.close(at);
        self.waits
    }

    fn close(&mut self, at: Instant) {
        if let Some((kind, since)) = self.open.take() {
            let s = at.duration_since(since).as_secs_f64();
            if kind == PlanWait::Again as u32 {
                self.waits.again_s.push(s);
            } else {
                self.waits.ahead.add(s);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use std::time::Duration;

    use super::*;

    #[test]
    fn spells_are_timed_from_the_first_step_saying_so_to_the_first_that_does_not() {
        let t0 = Instant::now();
        let at = |ms: u64| t0 + Duration::from_millis(ms);
        let (ahead, again, none) = (
            PlanWait::Ahead as u32,
            PlanWait::Again as u32,
            PlanWait::None as u32,
        );
        let mut w = WaitTrack::default();
        w.see(none, at(0));
        assert!(!w.waiting());
        // Ahead 100 ms (repeated steps do not restart it), then a re-plan of 250 ms straight
        // after, then ahead again, open at the end.
        w.see(ahead, at(100));
        w.see(ahead, at(150));
        assert!(w.waiting());
        w.see(again, at(200));
        w.see(again, at(300));
        w.see(none, at(450));
        w.see(ahead, at(1000));
        w.see(none, at(1300));
        w.see(ahead, at(2000));
        let s = w.summary(at(2050));
        assert_eq!(s.again_s, vec![0.25]);
        assert_eq!(s.ahead.count, 3);
        assert!((s.ahead.total_s - 0.45).abs() < 1e-9, "{s:?}");
        assert!((s.ahead.max_s - 0.3).abs() < 1e-9, "{s:?}");
    }
}
