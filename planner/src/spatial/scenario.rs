//! The spatial scenario's checks, its initial grasp, the quality of its grasps, and its plan
//! through the planning loop ([`drive`]).

use icrflow_grasp::math::{Real, Vec3};
use icrflow_grasp::quality::GraspError;

use super::times::{PhaseTimes, Timing};
use super::{ReachMap, Roll, SpatialScenario, Touch};
use crate::planner::{
    Deadline, FingerState, NoSwitch, Phase, Plan, PlanError, QUALITY_SLACK, Step, Stepper,
    Switched, drive,
};

/// A spatial scenario with its fingers' reach maps (the seeds of a switch's placements): what
/// the planning loop ([`drive`]) steps.
struct Mapped<'s, 'a> {
    scenario: &'s SpatialScenario<'a>,
    maps: Vec<ReachMap>,
    timing: Timing,
}

/// Where a plan's settled steps go ([`SpatialScenario::plan_streamed`]).
type Settled<'f> = &'f mut dyn FnMut(&[Step]);

impl Stepper for Mapped<'_, '_> {
    type Contact = Touch;

    fn finger_of(t: &Touch) -> u32 {
        t.finger
    }

    fn fingers(&self) -> usize {
        self.scenario.hand.fingers.len()
    }

    fn roll(&self, touches: &[Touch], theta: Real, step: Real) -> Result<Roll, PlanError> {
        self.timing
            .rolling
            .time(|| self.scenario.roll(touches, theta, step))
    }

    fn switch(
        &self,
        touches: &[Touch],
        k: usize,
        theta: Real,
        why: &str,
        progress: &mut dyn FnMut(Real),
        deadline: &Deadline,
    ) -> Result<Result<Switched<Touch>, NoSwitch>, PlanError> {
        self.timing.switches.time(|| {
            self.scenario.switch(
                touches,
                k,
                theta,
                why,
                &self.maps,
                progress,
                deadline,
                &self.timing,
            )
        })
    }

    fn record(
        &self,
        step: usize,
        phase: Phase,
        theta: Real,
        quality: Real,
        touches: &[Touch],
    ) -> Step {
        let s = self.scenario;
        let fingers = s
            .hand
            .fingers
            .iter()
            .map(|f| {
                let touch = touches.iter().find(|t| t.finger == f.id);
                let q = touch.map_or(&f.home, |t| &t.q);
                let (centre, axis) = f.fk_tip(q);
                let n_w = touch.map(|t| s.rotation(theta) * t.normal);
                FingerState {
                    finger: f.id,
                    contact: touch.map(|t| t.candidate),
                    point: touch.map(|t| [t.point.x, t.point.y, t.point.z]),
                    normal: touch.map(|t| [t.normal.x, t.normal.y, t.normal.z]),
                    angle: None,
                    cap_angle: n_w.map(|n| axis.dot(&-n).clamp(-1.0, 1.0).acos()),
                    tip_rotation: axis.y.atan2(axis.x),
                    tip_centre: [centre.x, centre.y, centre.z],
                    joints: q.to_vec(),
                }
            })
            .collect();
        Step::new(step, phase, theta, quality, fingers)
    }
}

impl SpatialScenario<'_> {
    /// The quality of `touches`' grasp where they touch: at their exact points and normals on
    /// the surface (0: not in force closure). What the plan keeps >= alpha at every step,
    /// attach and detach: their candidates' grasp (the ICRs' guarantee) may keep more than
    /// the contacts between the candidates do.
    pub(super) fn quality(&self, touches: &[Touch]) -> Result<Real, GraspError> {
        let at: Vec<(Vec3, Vec3)> = touches.iter().map(|t| (t.point, t.normal)).collect();
        let e = self.problem.evaluate_at(&at)?;
        Ok(if e.force_closure() { e.quality } else { 0.0 })
    }

    /// The quality of `touches`' grasp at their candidates: what their ICRs guarantee.
    pub(super) fn grid_quality(&self, touches: &[Touch]) -> Result<Real, GraspError> {
        let idx: Vec<usize> = touches.iter().map(|t| t.candidate).collect();
        self.quality_at(&idx)
    }

    /// The quality of the grasp at candidates `idx` (0: not in force closure).
    fn quality_at(&self, idx: &[usize]) -> Result<Real, GraspError> {
        let e = self.problem.evaluate(idx)?;
        Ok(if e.force_closure() { e.quality } else { 0.0 })
    }

    /// Where `touches` would lose [`Settings::neighbour_alpha`] with one contact moved to a
    /// candidate within [`Settings::neighbour_rings`] rings of its own: that contact, and why;
    /// `None` where every such grasp keeps it, or it is not asked for.
    pub(super) fn one_off(&self, touches: &[Touch]) -> Result<Option<(usize, String)>, GraspError> {
        let Some(alpha) = self.settings.neighbour_alpha else {
            return Ok(None);
        };
        let rings = self.settings.neighbour_rings;
        let adjacency = &self.problem.candidates().adjacency;
        let mut idx: Vec<usize> = touches.iter().map(|t| t.candidate).collect();
        for (i, t) in touches.iter().enumerate() {
            for n in adjacency.rings(t.candidate, rings) {
                idx[i] = n as usize;
                let q = self.quality_at(&idx)?;
                if q < alpha * (1.0 - QUALITY_SLACK) {
                    return Ok(Some((
                        i,
                        format!(
                            "with finger {}'s contact at {n}, within {rings} rings of candidates of its own, the grasp would keep {q:.6} < plan.neighbour_alpha = {alpha}",
                            t.finger
                        ),
                    )));
                }
            }
            idx[i] = t.candidate;
        }
        Ok(None)
    }

    fn check(&self) -> Result<(), PlanError> {
        let s = &self.settings;
        let positive = |name: &str, x: Real| {
            if x.is_finite() && x > 0.0 {
                Ok(())
            } else {
                Err(PlanError::Settings(format!(
                    "plan.{name}: must be a finite number > 0, got {x}"
                )))
            }
        };
        positive("rotation_deg", s.goal)?;
        positive("step_deg", s.step)?;
        if s.step > crate::planner::MAX_STEP {
            return Err(PlanError::Settings(format!(
                "plan.step_deg: at most {} deg",
                crate::planner::MAX_STEP.to_degrees()
            )));
        }
        let axis = self.spatial.axis;
        if !(axis.iter().all(|x| x.is_finite()) && (axis.norm() - 1.0).abs() < 1e-9) {
            return Err(PlanError::Settings(format!(
                "plan.axis: must be a unit vector, got [{}, {}, {}]",
                axis.x, axis.y, axis.z
            )));
        }
        if !self.start_rotation.is_finite() {
            return Err(PlanError::Settings(format!(
                "the start rotation must be finite, got {}",
                self.start_rotation
            )));
        }
        for (name, x) in [
            ("the link radius", self.spatial.link_radius),
            ("plan.min_mobility_mm", self.spatial.min_mobility),
            ("plan.squeeze_reserve_mm", s.squeeze_reserve),
            ("plan.cap_margin_deg", s.cap_margin),
        ] {
            if !(x.is_finite() && x >= 0.0) {
                return Err(PlanError::Settings(format!(
                    "{name}: must be >= 0, got {x}"
                )));
            }
        }
        if let Some(a) = s.neighbour_alpha {
            if !(a.is_finite() && (0.0..=s.alpha).contains(&a)) {
                return Err(PlanError::Settings(format!(
                    "neighbour_alpha must be in [0, alpha = {}], got {a}",
                    s.alpha
                )));
            }
            if s.neighbour_rings == 0 {
                return Err(PlanError::Settings(
                    "neighbour_rings must be at least 1 where neighbour_alpha is checked".into(),
                ));
            }
        }
        if !(self.spatial.part.is_finite() && self.spatial.part > 0.0) {
            return Err(PlanError::Settings(format!(
                "the integration part must be > 0, got {}",
                self.spatial.part
            )));
        }
        let known: Vec<u32> = self.hand.fingers.iter().map(|f| f.id).collect();
        for &(id, _) in &self.initial {
            if self.hand.finger(id).is_none() {
                return Err(PlanError::UnknownFinger { finger: id, known });
            }
        }
        for f in &self.hand.fingers {
            crate::planner::cap_left(f, s.cap_margin)?;
            if f.dof() < 3 {
                return Err(PlanError::Settings(format!(
                    "finger {}: {} joints cannot place a fingertip in space (at least 3)",
                    f.id,
                    f.dof()
                )));
            }
        }
        Ok(())
    }

    /// The initial grasp, checked (force closure, quality >= alpha, every finger placed, no
    /// fingers touching): its contacts and quality.
    pub fn start(&self) -> Result<(Vec<Touch>, Real), PlanError> {
        self.check()?;
        let alpha = self.settings.alpha;
        let theta = self.start_rotation;
        let mut touches = Vec::with_capacity(self.initial.len());
        for (id, p) in &self.initial {
            let f = self.finger(*id);
            let from = self.start_joints.iter().find(|(finger, _)| finger == id);
            let seed = from.map_or(&f.home, |(_, q)| q);
            let t = self
                .place(f, p, theta, seed, true, from.is_some())
                .map_err(|reason| PlanError::Unreachable {
                    finger: *id,
                    where_: self.describe(p),
                    reason,
                })?;
            touches.push(t);
        }
        let at: Vec<(Vec3, Vec3)> = touches.iter().map(|t| (t.point, t.normal)).collect();
        let e = self.problem.evaluate_at(&at)?;
        if !e.force_closure() {
            return Err(PlanError::NotForceClosure { epsilon: e.epsilon });
        }
        if e.quality < alpha * (1.0 - QUALITY_SLACK) {
            return Err(PlanError::BelowMargin {
                quality: e.quality,
                alpha,
            });
        }
        // Only fingers that overlap refuse the start (a plan made again from the estimate may
        // start with two fingers nearer than the gap the planner keeps: its first step on
        // blocks one of them, and a switch frees it).
        if let Some((why, _)) = self.clash_with(&touches, theta, 0.0) {
            return Err(PlanError::Settings(format!("the initial grasp: {why}")));
        }
        Ok((touches, e.quality))
    }

    /// Plans the scenario. `progress` is called after every step with the rotation done
    /// (rad).
    pub fn plan(&self, progress: &mut dyn FnMut(Real)) -> Result<Plan, PlanError> {
        self.plan_timed(progress).map(|(plan, _)| plan)
    }

    /// [`Self::plan`], and where its time went, per phase ([`PhaseTimes`]).
    pub fn plan_timed(
        &self,
        progress: &mut dyn FnMut(Real),
    ) -> Result<(Plan, PhaseTimes), PlanError> {
        self.plan_handing(progress, None)
    }

    /// [`Self::plan`], handing `settled` the plan's steps a part at a time, in order, as soon
    /// as no later step can drop them (the planning loop's settled steps): a hand may follow
    /// them while the rest is planned. Each part is checked first as the whole plan is, the
    /// links along the moves from the step before it ([`Self::plan_link_clearance`]); from a
    /// part that fails it, nothing more is handed on, and the plan fails as [`Self::plan`]
    /// does. The plan returned is [`Self::plan`]'s.
    pub fn plan_streamed(
        &self,
        progress: &mut dyn FnMut(Real),
        settled: &mut dyn FnMut(&[Step]),
    ) -> Result<Plan, PlanError> {
        self.plan_handing(progress, Some(settled))
            .map(|(plan, _)| plan)
    }

    /// [`Self::plan_timed`], handing the settled steps to `settled` if given
    /// ([`Self::plan_streamed`]).
    fn plan_handing(
        &self,
        progress: &mut dyn FnMut(Real),
        mut settled: Option<Settled<'_>>,
    ) -> Result<(Plan, PhaseTimes), PlanError> {
        let deadline = Deadline::after(self.settings.max_plan);
        let started = self.start()?;
        let mapped = Mapped {
            scenario: self,
            maps: self.hand.fingers.iter().map(ReachMap::new).collect(),
            timing: Timing::default(),
        };
        let mut slip: Real = 0.0;
        // The last step handed on (the moves from it are checked with the next part), whether
        // a part failed the links' check, and the closest the links came in the parts checked.
        let (mut last, mut refused): (Option<Step>, bool) = (None, false);
        let mut closest: Option<(Real, u32, usize, usize)> = None;
        let mut hand_on = |part: &[Step]| {
            let Some(out) = settled.as_mut().filter(|_| !refused) else {
                return;
            };
            let mut checked = Vec::with_capacity(part.len() + 1);
            checked.extend(last.take());
            checked.extend_from_slice(part);
            let here = self.plan_link_clearance(&checked);
            if here.0 < 0.0 {
                refused = true;
                return;
            }
            closest = Some(closest.filter(|c| c.0 <= here.0).unwrap_or(here));
            out(part);
            last = part.last().cloned();
        };
        let driven = drive(
            &mapped,
            &self.settings,
            self.start_rotation,
            started,
            &deadline,
            progress,
            &mut |next: &[Touch]| slip = next.iter().map(|t| t.slip).fold(slip, Real::max),
            &mut hand_on,
        )?;
        // Every step handed on was checked with the step before it, in order (`drive` hands
        // each on once): the parts' closest is the whole plan's, not checked a second time (2.5
        // s of the mesh ellipsoid's 28; in the planner node's worker, a silence long enough
        // under load to be taken for a hung thread).
        let clearance = match closest {
            Some(c) if !refused && settled.is_some() => c,
            _ => self.plan_link_clearance(&driven.steps),
        };
        if clearance.0 < 0.0 {
            return Err(PlanError::LinkInObject {
                finger: clearance.1,
                link: clearance.2,
                step: clearance.3,
                depth_mm: -clearance.0 * 1e3,
            });
        }
        let reserve = self.min_squeeze_reserve(&driven.steps);
        let axis = [
            self.spatial.axis.x,
            self.spatial.axis.y,
            self.spatial.axis.z,
        ];
        let times = mapped.timing.read();
        Ok((
            driven.into_plan(&self.settings, axis, slip, clearance.0, reserve),
            times,
        ))
    }
}
