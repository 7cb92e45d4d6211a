//! The [`Follower`]: leads a hand through a plan's targets from the estimated grasp, and plans
//! again from the estimate where the object stops off the plan.

use std::fmt;

use icrflow_grasp::math::Real;

use super::{Estimate, ReplanError, Target, replan, targets};
use crate::planner::{Plan, PlanError, Scenario, Step};
use crate::rolling::Surface;

/// How close the estimated rotation must come to a step's target (rad).
pub const ROTATION_TOLERANCE: Real = 0.3 * std::f64::consts::PI / 180.0;

/// How close a free finger's joints must come to a way point (rad), beyond the encoder noise
/// (five standard deviations of `pipeline.joint_noise_deg` are added: [`Tolerances::new`]).
pub const WAY_POINT_TOLERANCE: Real = 1.0 * std::f64::consts::PI / 180.0;
/// How far from a sub-target inside a rolling step the object may be for the target to count as
/// passed (rad): the hand goes on to the next while the object follows. With a physical plant the
/// object lags the hand's sub-target by about a degree at rest (the contacts give under the squeeze
/// and the tangential loads), and waiting for it to settle at each sub-target ([`SETTLED_NS`])
/// crawled at 1 deg/s. The command then leads the object by at most `LEAD` plus a
/// [`SUBSTEP`](super::SUBSTEP); an object that stops (a slip) stops the hand there, and one that
/// slipped ahead of it by more is held there too, to be planned again from.
pub const LEAD: Real = 1.5 * std::f64::consts::PI / 180.0;
/// How far short of a rolling step the object may settle and the step still count as reached
/// (rad); a hand held still farther away waits.
pub const SETTLED_TOLERANCE: Real = 2.0 * std::f64::consts::PI / 180.0;
/// How close the joints of the fingers in contact must come to a rolling target's for the
/// hand to count as there (rad), beyond the encoder noise (five standard deviations of
/// `pipeline.joint_noise_deg` are added: [`Tolerances::new`]): the rolling hand moves them on
/// by more between the sub-targets of a step.
pub const HAND_AT_TARGET: Real = 0.1 * std::f64::consts::PI / 180.0;
/// How close to the goal a run must turn the object (rad): the last target, stopped farther
/// short of it, is planned again from the estimate; `icrflow run` counts a run completed within
/// it.
pub const GOAL_TOLERANCE: Real = 0.5 * std::f64::consts::PI / 180.0;
/// How long the estimated rotation must stay within [`STOPPED`] for the object to count as
/// settled (ns).
pub const SETTLED_NS: u64 = 500_000_000;
/// How long the object must stand still short of a rolling step's target before the follower
/// plans again from the estimate (ns): longer than [`SETTLED_NS`], so that a step that settles
/// within [`SETTLED_TOLERANCE`] counts as reached first.
pub const REPLAN_NS: u64 = 1_000_000_000;
/// How far a plan made again from the estimate turns the object at most (rad, 90 deg): the
/// rest is planned at its end. On the Allegro's 5,040-facet ellipsoid a plan made again for
/// the 157 deg left took over 40 s in a MuJoCo run (2026-12-05), the hand held all the while
/// ("plan step is stale") until the run gave up; the whole 270 deg plan takes 25 s alone.
pub const REPLAN_HORIZON: Real = std::f64::consts::FRAC_PI_2;
/// How far a plan must have turned the object for the follower to plan on from its end when it
/// does not reach the goal (rad): a plan that gets nowhere is not made again for ever.
pub const MIN_PROGRESS: Real = 1.0 * std::f64::consts::PI / 180.0;
/// Band the estimated rotation must stay in for the object to count as stopped, for a settled
/// step and for a re-plan (rad): wider than the estimate's noise (the pose measurements' 0.2
/// deg, corrected with the estimator's gain), far narrower than a rolling hand turns it in
/// [`SETTLED_NS`] (~14 deg in the paper's run). A band of 0.05 deg, used for settling until
/// session 11, was never met through that noise: an object that stopped 0.3 to 2 deg short of
/// a step was neither reached nor re-planned, and the run waited for its timeout.
pub const STOPPED: Real = 0.5 * std::f64::consts::PI / 180.0;

/// How close the estimate must come to a target's joints (rad): the constants plus five
/// standard deviations of the joint encoders' noise.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Tolerances {
    /// A free finger to a way point ([`WAY_POINT_TOLERANCE`] plus the noise).
    pub joint: Real,
    /// The fingers in contact to a rolling target ([`HAND_AT_TARGET`] plus the noise).
    pub hand: Real,
}

impl Tolerances {
    /// The tolerances under joint-encoder noise of standard deviation `joint_noise` (rad).
    pub fn new(joint_noise: Real) -> Self {
        Self {
            joint: WAY_POINT_TOLERANCE + 5.0 * joint_noise,
            hand: HAND_AT_TARGET + 5.0 * joint_noise,
        }
    }
}

/// Since when, at which rotation and on which target the object has been stopped (within
/// [`STOPPED`]).
#[derive(Debug, Clone, Copy)]
struct Stopped {
    /// Since when (ns); `None`: from the next estimate on (after a failed re-plan, whose
    /// planning took a while).
    since: Option<u64>,
    rotation: Real,
    target: usize,
}

/// What one estimate made a [`Follower`] do.
#[derive(Debug, Clone, Default)]
pub struct Followed {
    /// The first estimate: the follower starts (or resumes) at this target.
    pub resumed: Option<usize>,
    /// What followed from the estimate, if anything.
    pub event: Option<Event>,
}

impl Followed {
    /// The targets to command now, in order (an index equal to the number of targets: the
    /// plan is done).
    pub fn commands(&self) -> impl Iterator<Item = usize> + '_ {
        let then = match &self.event {
            Some(Event::Advanced(k)) => Some(*k),
            Some(Event::Replanned(_)) => Some(0),
            _ => None,
        };
        self.resumed.into_iter().chain(then)
    }
}

/// What an estimate changed.
#[derive(Debug, Clone)]
pub enum Event {
    /// The estimate reached its target; this one is next (the number of targets: done).
    Advanced(usize),
    /// The object stood still off the plan: it was planned again from the estimate, and its
    /// first target is commanded.
    Replanned(Box<Replanned>),
    /// The object stood still off the plan, and a follower that plans nothing itself
    /// ([`Follower::waiting`]) asks for a plan made again from the estimate: the target is held
    /// until [`Follower::begin`] starts the new plan (or [`Follower::replan_failed`] says there
    /// is none).
    ReplanDue(Box<ReplanDue>),
    /// The object stood still off the plan and planning again failed: the target is held, and
    /// planning is tried again after another [`REPLAN_NS`].
    ReplanFailed {
        /// The estimated rotation (rad).
        rotation: Real,
        /// The target's rotation (rad).
        target: Real,
        /// Why planning failed.
        error: ReplanError,
    },
}

/// A plan to be made again from the estimate ([`Event::ReplanDue`]): what
/// [`Planning::replan_streamed`] is given.
#[derive(Debug, Clone)]
pub struct ReplanDue {
    /// The estimate to plan from.
    pub estimate: Estimate,
    /// The step of the target held (its fingers' commanded joints are where a plan made
    /// again starts them: [`crate::spatial::follow::replan`]).
    pub held: Step,
    /// The number of the new plan's first step.
    pub first: usize,
    /// The rotation of the target the object stopped short of (rad).
    pub target: Real,
    /// Re-plans so far, this one included.
    pub count: u32,
}

/// A re-plan ([`Event::Replanned`]), for the record.
#[derive(Debug, Clone)]
pub struct Replanned {
    /// The estimated rotation it was planned from (rad).
    pub rotation: Real,
    /// The rotation of the target the object stopped short of (rad).
    pub target: Real,
    /// Re-plans so far, this one included.
    pub count: u32,
    /// The number of the new plan's first step.
    pub first: usize,
    /// The new plan's summary and steps.
    pub plan: Plan,
    /// The rotation offset it was planned with (rad).
    pub delta: Real,
    /// What [`targets`] noted.
    pub notes: Vec<String>,
    /// Whether the new plan ends at the goal (not: a leg of [`REPLAN_HORIZON`], or a plan that
    /// stopped short).
    pub at_goal: bool,
}

impl fmt::Display for Replanned {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let p = &self.plan;
        let (rotation, target) = (self.rotation.to_degrees(), self.target.to_degrees());
        write!(
            f,
            "the object stopped at {rotation:.1} deg, {:+.1} deg off the target {target:.1} deg: \
             planned again from the estimate (re-plan {}: {} steps from step {}, {} switches, \
             {:.1} deg to go; the plan's candidates {:+.2} deg from the contacts)",
            rotation - target,
            self.count,
            p.steps.len(),
            self.first,
            p.summary.switches,
            (p.summary.goal - p.steps.first().map_or(0.0, |s| s.rotation) - self.delta)
                .to_degrees(),
            self.delta.to_degrees(),
        )?;
        if !self.at_goal && p.summary.completed {
            write!(f, "; a leg: planned on at its end")?;
        }
        Ok(())
    }
}

impl fmt::Display for Event {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Event::Advanced(k) => write!(f, "on to target {k}"),
            Event::Replanned(r) => r.fmt(f),
            Event::ReplanDue(r) => write!(
                f,
                "the object stopped at {:.1} deg, {:+.1} deg off the target {:.1} deg: planning \
                 again from the estimate (re-plan {})",
                r.estimate.rotation.to_degrees(),
                (r.estimate.rotation - r.target).to_degrees(),
                r.target.to_degrees(),
                r.count
            ),
            Event::ReplanFailed {
                rotation,
                target,
                error,
            } => write!(
                f,
                "the object stopped at {:.1} deg, off the target {:.1} deg, and planning again \
                 from the estimate failed: {error}",
                rotation.to_degrees(),
                target.to_degrees()
            ),
        }
    }
}

/// What a [`Follower`] plans with: a planar hand's scenario and the section its fingertips
/// roll on, or a spatial hand's scenario.
#[derive(Clone)]
pub enum Planning<'a> {
    /// The planar planner ([`Scenario`]) on the object's section.
    Planar(Scenario<'a>, &'a Surface),
    /// The spatial planner ([`crate::spatial`]).
    Spatial(crate::spatial::SpatialScenario<'a>),
}

/// What a follower waits for the planner for ([`Follower::waiting_for`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Wait {
    /// The plan's first targets: the hand holds its initial grasp.
    FirstPlan,
    /// The targets after the last one made: the hand holds there while the plan goes on.
    Ahead,
    /// A plan made again from the estimate: the hand holds the target it stopped short of.
    Again,
}

impl Planning<'_> {
    /// The margin plans are made at (`plan.alpha`).
    pub fn alpha(&self) -> Real {
        match self {
            Self::Planar(scenario, _) => scenario.settings.alpha,
            Self::Spatial(scenario) => scenario.settings.alpha,
        }
    }

    /// The plan, its targets handed to `settled` a part at a time, in order, with the margin
    /// planned at: a spatial plan's as its steps are settled
    /// ([`crate::spatial::SpatialScenario::plan_streamed`]), so that the hand follows them while
    /// the rest is planned; a planar plan's (made in a fraction of a second) all at once when
    /// it is made. Where the plan fails after a part was handed on, the error says why; the
    /// parts handed on stay valid (each checked as the whole plan is).
    pub fn plan_streamed(
        &self,
        clearance: Real,
        note: &mut dyn FnMut(String),
        progress: &mut dyn FnMut(Real),
        settled: &mut dyn FnMut(&[Target], Real),
    ) -> Result<Plan, PlanError> {
        let alpha = self.alpha();
        match self {
            Self::Planar(..) => {
                let (plan, targets) = self.plan(clearance, note, progress)?;
                settled(&targets, alpha);
                Ok(plan)
            }
            Self::Spatial(scenario) => {
                let (mut made, mut prev) = (Vec::new(), None::<Step>);
                scenario.plan_streamed(progress, &mut |part| {
                    let from = made.len();
                    crate::spatial::follow::targets_after(
                        prev.as_ref(),
                        part,
                        scenario,
                        &mut made,
                        &mut || {},
                    );
                    prev = part.last().cloned();
                    settled(&made[from..], alpha);
                })
            }
        }
    }

    /// A plan made again as `due` asks ([`replan`], [`crate::spatial::follow::replan`]),
    /// its targets handed to `settled` as [`Self::plan_streamed`] hands them on.
    pub fn replan_streamed(
        &self,
        due: &ReplanDue,
        clearance: Real,
        progress: &mut dyn FnMut(Real),
        settled: &mut dyn FnMut(&[Target], Real),
    ) -> Result<super::Replan, ReplanError> {
        match self {
            Self::Planar(scenario, surface) => {
                let again = replan(
                    scenario,
                    &due.estimate,
                    surface,
                    due.first,
                    clearance,
                    &mut || {},
                )?;
                settled(&again.targets, again.plan.summary.alpha);
                Ok(again)
            }
            Self::Spatial(scenario) => crate::spatial::follow::replan_streamed(
                scenario,
                &due.estimate,
                Some(&due.held),
                due.first,
                progress,
                Some(settled),
            ),
        }
    }

    /// The plan and its targets ([`targets`], [`crate::spatial::follow::targets`]).
    fn plan(
        &self,
        clearance: Real,
        note: &mut dyn FnMut(String),
        progress: &mut dyn FnMut(Real),
    ) -> Result<(Plan, Vec<Target>), PlanError> {
        Ok(match self {
            Self::Planar(scenario, surface) => {
                let plan = scenario.plan(progress)?;
                let targets = targets(&plan.steps, scenario.hand, surface, clearance, note);
                (plan, targets)
            }
            Self::Spatial(scenario) => {
                let plan = scenario.plan(progress)?;
                let targets = crate::spatial::follow::targets(&plan.steps, scenario);
                (plan, targets)
            }
        })
    }
}

/// Leads a hand through a plan from the estimated grasp: a pure step ([`Follower::on_estimate`]:
/// an estimate and the time in, the target to command out), with no I/O or clock inside.
pub struct Follower<'a> {
    /// The scenario planned, which re-plans start from.
    planning: Planning<'a>,
    clearance: Real,
    tolerances: Tolerances,
    targets: Vec<Target>,
    /// Whether the plan's last step is the goal (a plan made again may end short of it).
    ends_at_goal: bool,
    /// The rotation the plan followed starts at (rad).
    plan_from: Real,
    /// When the follower reached the end of the plan (ns), if it has.
    at_end: Option<u64>,
    /// Plans made again from the estimate; 0 while the first plan is followed.
    replans: u32,
    /// The target being commanded; chosen from the first estimate (a restart resumes).
    current: Option<usize>,
    stopped: Stopped,
    /// Whether it plans nothing itself ([`Follower::waiting`]): a plan made again is asked
    /// for ([`Event::ReplanDue`]).
    deferred: bool,
    /// Whether the plan followed is still being made (more targets to come).
    pending: bool,
    /// A plan made again asked for and not yet begun: the estimated rotation it is planned
    /// from.
    awaiting: Option<Real>,
    /// Whether the hand holds the last target made, reached, while the plan is being made.
    held_ahead: bool,
}

impl<'a> Follower<'a> {
    /// Whether the estimated object has turned past the last target's rotation, in the
    /// direction the plan turns it.
    fn past_goal(&self, e: &Estimate) -> bool {
        let (Some(first), Some(last)) = (self.targets.first(), self.targets.last()) else {
            return false;
        };
        let goal = last.step.rotation;
        let direction = (goal - first.step.rotation).signum();
        direction != 0.0 && (e.rotation - goal) * direction > 0.0
    }

    /// Plans `planning`'s scenario and follows the plan's targets ([`targets`], `clearance`
    /// and `note` as there; a spatial plan's, [`crate::spatial::follow::targets`]).
    pub fn new(
        planning: Planning<'a>,
        clearance: Real,
        tolerances: Tolerances,
        note: &mut dyn FnMut(String),
    ) -> Result<Self, PlanError> {
        Self::new_with(planning, clearance, tolerances, note, &mut |_| {})
    }

    /// [`Follower::new`], reporting the planning's progress to `progress` (the rotation
    /// planned so far, rad, as [`Scenario::plan`] does).
    pub fn new_with(
        planning: Planning<'a>,
        clearance: Real,
        tolerances: Tolerances,
        note: &mut dyn FnMut(String),
        progress: &mut dyn FnMut(Real),
    ) -> Result<Self, PlanError> {
        let (plan, targets) = planning.plan(clearance, note, progress)?;
        let mut follower = Self::waiting(planning, clearance, tolerances);
        follower.deferred = false;
        follower.begin(targets, 0);
        follower.finish(plan.summary.completed);
        Ok(follower)
    }

    /// A follower of a plan made elsewhere (the planner node's worker thread): no targets
    /// until [`Self::begin`] gives the plan's first ones, more with [`Self::extend`] while the
    /// hand follows, its end with [`Self::finish`]; it plans nothing itself: where the object
    /// stops off the plan it asks for a plan made again ([`Event::ReplanDue`]), which comes
    /// the same way (or [`Self::replan_failed`]). Meanwhile it holds where it is
    /// ([`Self::waiting_for`]).
    pub fn waiting(planning: Planning<'a>, clearance: Real, tolerances: Tolerances) -> Self {
        Self {
            planning,
            clearance,
            tolerances,
            plan_from: 0.0,
            at_end: None,
            targets: Vec::new(),
            ends_at_goal: false,
            replans: 0,
            current: None,
            stopped: Stopped {
                since: Some(0),
                rotation: f64::NAN,
                target: usize::MAX,
            },
            deferred: true,
            pending: true,
            awaiting: None,
            held_ahead: false,
        }
    }

    /// The first targets of a plan being made, at `now_ns`: the first plan's (the first
    /// estimate picks the target to start at), or the plan made again that
    /// [`Event::ReplanDue`] asked for (followed from its first target on).
    pub fn begin(&mut self, targets: Vec<Target>, now_ns: u64) {
        self.plan_from = targets.first().map_or(0.0, |t| t.step.rotation);
        self.targets = targets;
        self.ends_at_goal = false;
        self.pending = true;
        self.held_ahead = false;
        self.at_end = None;
        if let Some(rotation) = self.awaiting.take() {
            self.replans += 1;
            self.plan_from = rotation;
            self.current = Some(0);
            self.stopped = Stopped {
                since: Some(now_ns),
                rotation,
                target: usize::MAX,
            };
        }
    }

    /// More targets of the plan being made, after the last.
    pub fn extend(&mut self, targets: &[Target]) {
        self.targets.extend_from_slice(targets);
        self.held_ahead = false;
    }

    /// The plan being made is complete (`at_goal`: its last target is the goal; not: a leg
    /// of [`REPLAN_HORIZON`], or a plan that stopped short, at whose end the follower plans
    /// on).
    pub fn finish(&mut self, at_goal: bool) {
        self.pending = false;
        self.ends_at_goal = at_goal;
    }

    /// The plan made again that [`Event::ReplanDue`] asked for could not be made: the
    /// target is held, and planning is asked for again after another [`REPLAN_NS`] (as
    /// [`Event::ReplanFailed`]).
    pub fn replan_failed(&mut self) {
        self.awaiting = None;
        self.pending = false;
        self.stopped.since = None;
        self.at_end = None;
    }

    /// What the follower waits for the planner for, if anything.
    pub fn waiting_for(&self) -> Option<Wait> {
        if self.awaiting.is_some() {
            Some(Wait::Again)
        } else if self.targets.is_empty() {
            Some(Wait::FirstPlan)
        } else if self.pending && self.held_ahead {
            Some(Wait::Ahead)
        } else {
            None
        }
    }

    /// Whether the plan followed ends at the goal (not: a leg of a plan made again, or a plan
    /// that stopped short, at whose end the follower may plan on).
    pub fn ends_at_goal(&self) -> bool {
        self.ends_at_goal
    }

    /// The targets being followed.
    pub fn targets(&self) -> &[Target] {
        &self.targets
    }

    /// The target being commanded (the number of targets: done); `None` before the first
    /// estimate.
    pub fn current(&self) -> Option<usize> {
        self.current
    }

    /// Plans made again from the estimate so far.
    pub fn replans(&self) -> u32 {
        self.replans
    }

    /// The target nearest to `e`: the same fingers in contact, the closest rotation, then the
    /// free fingers' nearest way point (a fresh run is at the start), so that a restarted
    /// follower never sends the hand back, and a free finger between two way points goes on
    /// to one of them, along the move checked between them.
    fn nearest(&self, e: &Estimate) -> usize {
        let steps = &self.targets;
        (0..steps.len())
            .filter(|&k| e.same_contacts(&steps[k].step))
            .min_by(|&a, &b| {
                let d = |k: usize| (e.rotation - steps[k].step.rotation).abs();
                let j = |k: usize| e.joint_error(&steps[k].step, false);
                d(a).total_cmp(&d(b))
                    .then(j(a).total_cmp(&j(b)))
                    .then(b.cmp(&a))
            })
            .unwrap_or(0)
    }

    /// Takes the estimate `e` at `now_ns` (ns, any monotonic clock): starts at the target
    /// nearest to the first one, moves on as it reaches a target, and plans again when the
    /// object has stopped off the plan for good (`beat` is called as that planning goes on).
    pub fn on_estimate(&mut self, e: &Estimate, now_ns: u64, beat: &mut dyn FnMut()) -> Followed {
        let mut out = Followed::default();
        // No plan yet, or a plan made again asked for: the hand holds where it is.
        if self.targets.is_empty() || self.awaiting.is_some() {
            return out;
        }
        let k = match self.current {
            Some(k) => k,
            None => {
                let k = self.nearest(e);
                // While the plan is being made, the target to start (or resume) at must lie
                // within what has been made: not its last target, and where the estimate is
                // (a restarted node's plan reaches the object's rotation only later).
                if self.pending
                    && (k + 1 >= self.targets.len()
                        || (e.rotation - self.targets[k].step.rotation).abs() > SETTLED_TOLERANCE
                        || !e.same_contacts(&self.targets[k].step))
                {
                    return out;
                }
                self.current = Some(k);
                out.resumed = Some(k);
                k
            }
        };
        // Settled: the rotation has stayed within STOPPED for SETTLED_NS on this target. (The
        // first estimate restarts this, so it never re-plans: `resumed` and a re-plan never
        // come together.)
        if (e.rotation - self.stopped.rotation).abs() > STOPPED || self.stopped.target != k {
            self.stopped = Stopped {
                since: Some(now_ns),
                rotation: e.rotation,
                target: k,
            };
        }
        let since = *self.stopped.since.get_or_insert(now_ns);
        let stopped_ns = now_ns.saturating_sub(since);
        let n = self.targets.len();
        let tol = self.tolerances;
        // Or the hand is at the target's joints: the object, rolled by them, is where the
        // hand put it and goes no farther. After a re-plan it can stay about a degree off the
        // plan's rotation (the contacts are not where the plan has them); waiting SETTLED_NS
        // for each sub-target then crawled at 1 deg/s.
        let hand_there = k < n && self.targets[k].hand_at(e, tol.hand);
        // The last target, when it is the goal, is reached within ROTATION_TOLERANCE, or,
        // settled, anywhere past it (the hand cannot turn the object back; after a re-plan the
        // object can end a degree beyond the plan's rotation); stopped farther than
        // GOAL_TOLERANCE short of it, the object is turned on by a plan made again (a physical
        // hand's rolling turns the object a little less than the plan's, and the hand at the
        // goal turns it no farther). A plan that ends short of the goal ends as it settles.
        let settling = stopped_ns >= SETTLED_NS || hand_there;
        let goal = k + 1 == n && self.ends_at_goal;
        let settled = settling && !goal;
        let at_target = k < n
            && (self.targets[k].reached(e, settled, tol.joint)
                || (goal
                    && settling
                    && self.past_goal(e)
                    && e.same_contacts(&self.targets[k].step)));
        let short = if goal {
            GOAL_TOLERANCE
        } else {
            SETTLED_TOLERANCE
        };
        // At the end of a plan short of the goal (a leg of REPLAN_HORIZON, or a plan that
        // stopped short), the object settled there with two contacts or more: plan on, if that
        // plan turned the object on.
        // (How long since the plan's end, not how long the object has stood within STOPPED:
        // at rest the estimate wanders by a degree on the Allegro's sphere, and the hand,
        // holding its last target, turns the object no farther.)
        let end_ns = if k >= n {
            now_ns.saturating_sub(*self.at_end.get_or_insert(now_ns))
        } else {
            self.at_end = None;
            0
        };
        let leg_done = k >= n
            && n > 0
            && !self.pending
            && !self.ends_at_goal
            && end_ns >= REPLAN_NS
            && e.touching().count() >= 2
            && (e.rotation - self.plan_from).abs() >= MIN_PROGRESS;
        // (While the plan is being made, the follower waits at the last target made.)
        if leg_done
            || (k < n
                && !self.pending
                && !at_target
                && self.targets[k].stalled(e, stopped_ns, tol.joint, short))
        {
            // Stuck short of the target, or at the end of the plan: plan again from the
            // estimate.
            let k = k.min(n - 1);
            let target = self.targets[k].step.rotation;
            let first = self.targets[k].step.step + 1;
            if self.deferred {
                self.awaiting = Some(e.rotation);
                out.event = Some(Event::ReplanDue(Box::new(ReplanDue {
                    estimate: e.clone(),
                    held: self.targets[k].step.clone(),
                    first,
                    target,
                    count: self.replans + 1,
                })));
                return out;
            }
            let again = match &self.planning {
                Planning::Planar(scenario, surface) => {
                    replan(scenario, e, surface, first, self.clearance, beat)
                }
                Planning::Spatial(scenario) => {
                    let held = &self.targets[k].step;
                    crate::spatial::follow::replan(scenario, e, Some(held), first, beat)
                }
            };
            match again {
                Ok(again) => {
                    self.replans += 1;
                    self.targets = again.targets;
                    self.ends_at_goal = again.at_goal;
                    self.plan_from = e.rotation;
                    self.at_end = None;
                    self.current = Some(0);
                    self.stopped = Stopped {
                        since: Some(now_ns),
                        rotation: e.rotation,
                        target: usize::MAX,
                    };
                    out.event = Some(Event::Replanned(Box::new(Replanned {
                        rotation: e.rotation,
                        target,
                        count: self.replans,
                        first,
                        plan: again.plan,
                        delta: again.delta,
                        notes: again.notes,
                        at_goal: again.at_goal,
                    })));
                    return out;
                }
                Err(error) => {
                    // Tried again after another REPLAN_NS from the next estimate on (the
                    // planning took a while); the target is held.
                    self.stopped.since = None;
                    self.at_end = None;
                    out.event = Some(Event::ReplanFailed {
                        rotation: e.rotation,
                        target,
                        error,
                    });
                }
            }
        }
        // The last target made is not passed while the plan is being made: it is held.
        if at_target && self.pending && k + 1 >= n {
            self.held_ahead = true;
        } else if at_target {
            self.current = Some(k + 1);
            out.event = Some(Event::Advanced(k + 1));
        }
        out
    }
}
