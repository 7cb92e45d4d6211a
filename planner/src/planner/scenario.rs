//! The planar scenario ([`Scenario`]): the problem, its checks, its initial grasp and its plan.

use icrflow_grasp::math::{Real, Vec3};
use icrflow_grasp::quality::{GraspError, GraspProblem};

use super::plan::vertical;
use super::roll::degrees;
use super::{
    Deadline, FingerState, MAX_STEP, NoSwitch, Phase, Plan, PlanError, QUALITY_SLACK, Roll,
    Settings, Start, Step, Stepper, Switched, drive, link_clearance, rolling_residuals,
};
use crate::hand::{Finger, Hand};

/// The problem the planner solves.
#[derive(Clone)]
pub struct Scenario<'a> {
    /// Grasp problem whose candidates are the object's section in the hand's plane.
    pub problem: &'a GraspProblem,
    /// The hand.
    pub hand: &'a Hand,
    /// The object's centre of mass (body frame).
    pub centre: Vec3,
    /// Section angle of each candidate (rad), for reporting.
    pub angles: Option<&'a [Real]>,
    /// Initial contacts: (finger, candidate, cap angle). Without a cap angle the planner
    /// picks the one with the most rolling room.
    pub initial: Vec<(u32, usize, Option<Real>)>,
    /// Where the plan starts: the object's rotation and the hand's pose.
    pub start: Start,
    /// Settings.
    pub settings: Settings,
}

/// A finger in contact.
#[derive(Debug, Clone, PartialEq)]
pub struct Contact {
    /// Finger number.
    pub finger: u32,
    /// Candidate index of the contact point.
    pub candidate: usize,
    /// Cap angle gamma (rad).
    pub gamma: Real,
    /// Joint angles (rad).
    pub q: Vec<Real>,
}

impl Stepper for Scenario<'_> {
    type Contact = Contact;

    fn finger_of(c: &Contact) -> u32 {
        c.finger
    }

    fn fingers(&self) -> usize {
        self.hand.fingers.len()
    }

    fn roll(&self, contacts: &[Contact], theta: Real, step: Real) -> Result<Roll, PlanError> {
        Scenario::roll(self, contacts, theta, step)
    }

    fn switch(
        &self,
        contacts: &[Contact],
        k: usize,
        theta: Real,
        why: &str,
        _progress: &mut dyn FnMut(Real),
        _deadline: &Deadline,
    ) -> Result<Result<Switched<Contact>, NoSwitch>, PlanError> {
        // (A planar switch search takes milliseconds: the loop's check before every step
        // bounds it.)
        Scenario::switch(self, contacts, k, theta, why)
    }

    fn record(
        &self,
        step: usize,
        phase: Phase,
        theta: Real,
        quality: Real,
        contacts: &[Contact],
    ) -> Step {
        let cands = self.problem.candidates();
        let fingers = self
            .hand
            .fingers
            .iter()
            .map(|f| {
                let contact = contacts.iter().find(|c| c.finger == f.id);
                let q = contact.map_or(&f.home, |c| &c.q);
                let pose = f.fk(q);
                let p = contact.map(|c| cands.points[c.candidate]);
                FingerState {
                    finger: f.id,
                    contact: contact.map(|c| c.candidate),
                    point: p.map(|p| [p.x, p.y, p.z]),
                    normal: None,
                    angle: contact.and_then(|c| self.angles.map(|a| a[c.candidate])),
                    cap_angle: contact.map(|c| c.gamma),
                    tip_rotation: pose.cap_axis.y.atan2(pose.cap_axis.x),
                    tip_centre: [pose.tip_centre.x, pose.tip_centre.y, pose.tip_centre.z],
                    joints: q.to_vec(),
                }
            })
            .collect();
        Step::new(step, phase, theta, quality, fingers)
    }
}

impl Scenario<'_> {
    #[expect(
        clippy::expect_used,
        reason = "the scenario's fingers are checked against the hand when it is made"
    )]
    pub(super) fn finger(&self, id: u32) -> &Finger {
        self.hand.finger(id).expect("fingers are checked up front")
    }

    /// World position and normal of candidate `c` with the object at `theta`.
    pub(super) fn world(&self, c: usize, theta: Real) -> (Vec3, Vec3) {
        let cands = self.problem.candidates();
        let r = nalgebra::Rotation3::from_axis_angle(&Vec3::z_axis(), theta);
        (r * (cands.points[c] - self.centre), r * cands.normals[c])
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
        if !self.start.rotation.is_finite() {
            return Err(PlanError::Settings(format!(
                "the start rotation must be finite, got {}",
                self.start.rotation
            )));
        }
        positive("step_deg", s.step)?;
        if s.step > MAX_STEP {
            return Err(PlanError::Settings(format!(
                "plan.step_deg: a rolling step of {} deg is more than one step can represent (at most {} deg: one straight joint-space move)",
                degrees(s.step),
                degrees(MAX_STEP)
            )));
        }
        positive("attach_resolution_deg", s.attach_resolution)?;
        if !(s.cap_margin.is_finite() && s.cap_margin >= 0.0) {
            return Err(PlanError::Settings(format!(
                "plan.cap_margin_deg: must be >= 0, got {}",
                s.cap_margin.to_degrees()
            )));
        }
        if !(s.squeeze_reserve.is_finite() && s.squeeze_reserve >= 0.0) {
            return Err(PlanError::Settings(format!(
                "plan.squeeze_reserve_mm: must be >= 0, got {}",
                s.squeeze_reserve * 1e3
            )));
        }
        if !(s.min_manipulability.is_finite() && s.min_manipulability >= 0.0) {
            return Err(PlanError::Settings(format!(
                "plan.min_manipulability: must be >= 0, got {}",
                s.min_manipulability
            )));
        }
        let known: Vec<u32> = self.hand.fingers.iter().map(|f| f.id).collect();
        for &(id, _, _) in &self.initial {
            let Some(f) = self.hand.finger(id) else {
                return Err(PlanError::UnknownFinger { finger: id, known });
            };
            if !f.in_hand_plane() {
                return Err(PlanError::NotPlanar { finger: id });
            }
        }
        for f in &self.hand.fingers {
            cap_left(f, s.cap_margin)?;
        }
        Ok(())
    }

    pub(super) fn describe(&self, c: usize) -> String {
        match self.angles {
            Some(a) => format!("{:.1} deg", a[c].to_degrees()),
            None => {
                let p = self.problem.candidates().points[c];
                format!("[{:.4}, {:.4}, {:.4}] m", p.x, p.y, p.z)
            }
        }
    }

    pub(super) fn overlap(&self, contacts: &[Contact]) -> Option<PlanError> {
        let tips: Vec<(u32, Vec3, Real)> = contacts
            .iter()
            .map(|c| {
                let f = self.finger(c.finger);
                (c.finger, f.fk(&c.q).tip_centre, f.tip_radius)
            })
            .collect();
        for (i, a) in tips.iter().enumerate() {
            for b in &tips[i + 1..] {
                let d = (a.1 - b.1).norm();
                if d < a.2 + b.2 {
                    return Some(PlanError::Overlap {
                        a: a.0,
                        b: b.0,
                        distance_mm: 1e3 * d,
                    });
                }
            }
        }
        None
    }

    pub(super) fn quality(&self, contacts: &[Contact]) -> Result<(Real, Real), GraspError> {
        let idx: Vec<usize> = contacts.iter().map(|c| c.candidate).collect();
        let e = self.problem.evaluate(&idx)?;
        Ok((if e.force_closure() { e.quality } else { 0.0 }, e.epsilon))
    }

    /// The initial grasp, checked (force closure, quality >= alpha, every finger placed,
    /// no fingertips overlapping): its contacts and quality.
    pub fn start(&self) -> Result<(Vec<Contact>, Real), PlanError> {
        self.check()?;
        let alpha = self.settings.alpha;
        let floor = alpha * (1.0 - QUALITY_SLACK);
        let theta = self.start.rotation;
        // The initial grasp.
        let idx: Vec<usize> = self.initial.iter().map(|c| c.1).collect();
        let e = self.problem.evaluate(&idx)?;
        if !e.force_closure() {
            return Err(PlanError::NotForceClosure { epsilon: e.epsilon });
        }
        if e.quality < floor {
            return Err(PlanError::BelowMargin {
                quality: e.quality,
                alpha,
            });
        }
        let mut contacts = Vec::with_capacity(self.initial.len());
        for &(id, c, cap) in &self.initial {
            let f = self.finger(id);
            let near = self
                .start
                .joints
                .iter()
                .find(|(finger, q)| *finger == id && q.len() == f.dof())
                .map_or(&f.home, |(_, q)| q);
            let unreachable = |reason: String| PlanError::Unreachable {
                finger: id,
                where_: self.describe(c),
                reason,
            };
            let (gamma, q) = match cap {
                Some(gamma) => {
                    let q = self.place(f, c, theta, gamma, near, false).map_err(|b| {
                        unreachable(format!("with cap angle {:.1} deg: {b}", gamma.to_degrees()))
                    })?;
                    (gamma, q)
                }
                None => self
                    .best_attach(f, c, theta)
                    .map(|(g, q, _)| (g, q))
                    .ok_or_else(|| {
                        unreachable(match self.place(f, c, theta, 0.0, near, false) {
                            Err(b) => format!("at any cap angle (at the cap's centre: {b})"),
                            Ok(_) => "at any cap angle".into(),
                        })
                    })?,
            };
            contacts.push(Contact {
                finger: id,
                candidate: c,
                gamma,
                q,
            });
        }
        if let Some(e) = self.overlap(&contacts) {
            return Err(e);
        }
        Ok((contacts, e.quality))
    }

    /// Plans the scenario. `progress` is called after every step with the rotation done
    /// (rad).
    pub fn plan(&self, progress: &mut dyn FnMut(Real)) -> Result<Plan, PlanError> {
        let deadline = Deadline::after(self.settings.max_plan);
        let started = self.start()?;
        let driven = drive(
            self,
            &self.settings,
            self.start.rotation,
            started,
            &deadline,
            progress,
            &mut |_| {},
            &mut |_| {},
        )?;
        let closest = link_clearance(self, &driven.steps);
        if closest.clearance < 0.0 {
            return Err(PlanError::LinkInObject {
                finger: closest.finger,
                link: closest.link,
                step: closest.step,
                depth_mm: -closest.clearance * 1e3,
            });
        }
        let residual = rolling_residuals(self, &driven.steps)
            .into_iter()
            .fold(0.0, Real::max);
        let reserve = self.min_squeeze_reserve(&driven.steps);
        Ok(driven.into_plan(
            &self.settings,
            vertical(),
            residual,
            closest.clearance,
            reserve,
        ))
    }
}

/// Whether finger `f`'s fingertip cap leaves room for contacts `cap_margin` (rad) inside its
/// edge (both planners' settings check): an error naming `plan.cap_margin_deg` if not.
pub(crate) fn cap_left(f: &Finger, cap_margin: Real) -> Result<(), PlanError> {
    if f.cap_half_angle <= cap_margin {
        return Err(PlanError::Settings(format!(
            "plan.cap_margin_deg: {} deg leaves no usable cap on finger {} (half-angle {} deg)",
            cap_margin.to_degrees(),
            f.id,
            f.cap_half_angle.to_degrees()
        )));
    }
    Ok(())
}
