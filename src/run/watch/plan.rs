//! The plan stream as the run sees it: each plan step (switches, re-plans, the goal), and
//! whether the plan still goes on ([`Watch::stalled`]).

use std::time::Instant;

use icrflow_interfaces::topics::TopicId;
use icrflow_interfaces::{PlanPhase, PlanStepHeader, read_text};

use super::Watch;
use crate::run::status::say;
use crate::run::stop::StopReason;

impl Watch {
    /// A plan step.
    pub(super) fn plan_step(&mut self, p: &PlanStepHeader) {
        self.plan_published += 1;
        self.arrived.insert(TopicId::PlanStep.name());
        if let Some(physics) = &mut self.physics {
            physics.plan_step(p);
        }
        if let [.., taken, published] = p.header.trace.as_slice() {
            self.plan_compute
                .add(published.saturating_sub(*taken) as f64 * 1e-3);
        }
        if self.first_plan.is_none() {
            let now = Instant::now();
            self.first_plan = Some(now);
            self.status.clear();
            say!(
                "run: the plan's first steps came after {:.1} s (the hand held the initial grasp meanwhile); the hand follows them",
                now.duration_since(self.limits.started).as_secs_f64()
            );
            self.show(true);
        }
        // The hand waiting for the planner (no stall); once it no longer waits, the step it
        // waited at is timed afresh.
        let (now, was) = (Instant::now(), self.waits.waiting());
        self.waits.see(p.planning, now);
        if was && !self.waits.waiting() {
            self.progress = Some((p.step, now));
        }
        if p.phase == PlanPhase::Done as u32 {
            self.done = true;
            return;
        }
        // A plan made on from the end of one short of the goal (a leg): not done.
        self.done = false;
        self.last_step = self.last_step.max(p.step);
        if self.progress.is_none_or(|(step, _)| step != p.step) {
            self.progress = Some((p.step, Instant::now()));
        }
        if p.phase == PlanPhase::Attach as u32 {
            self.attaches.insert(p.step);
        }
        if p.phase == PlanPhase::Start as u32
            && p.step > 0
            && self.replans.insert(p.step)
            && let Some(why) = self.replan_progress.replanned(p.rotation, self.limits.goal)
        {
            self.gave_up.get_or_insert(why);
        }
    }

    /// Whether a run to the goal cannot go on: a plan that does not go on while the hand
    /// tracks (a target it never reaches, and the planner node does not plan again), or
    /// ended short of the goal (a plan made again from the estimate may); a hand that holds
    /// too long.
    pub(super) fn stalled(&self) -> Option<StopReason> {
        let l = &self.limits;
        if l.live {
            return None;
        }
        let short = self.rotation < l.goal - icrflow_plan::follow::GOAL_TOLERANCE;
        // Before the first plan step the planner node plans: however long that takes, it is
        // no stall (a planner node that fails is the supervisor's, and said).
        let (step, since) = self.progress.map(|(step, t)| (step, t.elapsed()))?;
        // Nor is a hand that holds its target while the planner makes the rest of the plan or
        // a plan made again (the plan-step messages say so; `TIMEOUT` bounds the run).
        if (!self.done || short)
            && self.holding.is_none()
            && !self.waits.waiting()
            && since >= l.max_hold
        {
            return Some(if self.done {
                StopReason::PlanEndedShort {
                    step,
                    rotation: self.rotation,
                }
            } else {
                StopReason::PlanStalled {
                    step,
                    since,
                    rotation: self.rotation,
                }
            });
        }
        // A run to the goal does not wait for ever on a hand that cannot go on.
        match self.holding {
            Some((since, _)) if since.elapsed() >= l.max_hold => Some(StopReason::HandHeld {
                since: since.elapsed(),
                reason: read_text(&self.hold_reason),
            }),
            _ => None,
        }
    }
}
