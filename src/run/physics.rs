//! The run against the physics: what MuJoCo's truth says of the plan's execution (the
//! summary's `physics`).
//!
//! Fed every [`PlantTruth`] of a MuJoCo plant and every plan step: the object's true rotation
//! and the largest distance of its centre from the start; per contact planned to roll, the
//! largest tangential slip speed and friction use `|f_t| / (mu f_n)`; contacts lost while the
//! plan has them (a finger that touched the object while planned in contact, then is off it
//! for [`LOST_AFTER`] truths in a row while still planned in contact: an attaching finger
//! still on its way to the object has lost nothing); for every plan step from the hand's first
//! grasp on (every finger the plan has in contact touching at one truth), the quality alpha*
//! of the grasp at MuJoCo's true contact points at the step's last truth, as the hand has made
//! it (each point taken into the object's frame and snapped to the nearest candidate of the
//! section; a contact planned that flickered off for fewer than [`LOST_AFTER`] truths counts at
//! its last point); whether the object was dropped (its centre further than [`DROP_FRACTION`] of
//! its size from the start); and the true margin at every truth ([`TrueMargin`]: alpha* where
//! the fingertips really touch, on the exact surface, a lifted finger out of the grasp) with
//! the object's tilt off the plan's axis.

use icrflow_grasp::math::{Real, UnitQuaternion, Vec3};
use icrflow_interfaces::{MAX_FINGERS, PlanPhase, PlanStepHeader, PlantEngine, PlantTruth};
use icrflow_scenario::{Config, Setup};
use serde::Serialize;

use super::collisions::{CollisionSummary, CollisionTrack, First};
use super::true_margin::{Below, Planned, TrueMargin};

/// Truths in a row without contact after which a finger planned in contact is lost (30 ms at
/// the truth's 100 Hz: MuJoCo's contacts flicker on a rolling fingertip for a step or two).
/// The lockstep counts losses alike (`icrflow_nodes::lockstep::truth::LOST_AFTER`, equal).
pub const LOST_AFTER: u32 = 3;
/// The object is dropped when its centre has moved this fraction of its largest radius.
pub const DROP_FRACTION: Real = 0.5;

/// The losses a summary lists (it counts them all).
pub const LOSSES_KEPT: usize = 16;

/// A contact lost while planned: when, and what the plan was doing.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct Loss {
    /// The finger.
    pub finger: u32,
    /// The newest plan step when it was lost, and its phase (`"rolling"`, `"attach"`, ...).
    pub step: u64,
    /// See `step`.
    pub phase: &'static str,
    /// The object's true rotation then (deg).
    pub rotation_deg: Real,
    /// Seconds since the first truth.
    pub at_s: Real,
}

/// A plan step whose true grasp was not in force closure when it was evaluated (at the step's
/// last truth).
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct NotClosed {
    /// The plan step, and its phase.
    pub step: u64,
    /// See `step`.
    pub phase: &'static str,
    /// The fingers whose contacts made the grasp evaluated (touching, or planned in contact
    /// and off for fewer truths than make a loss).
    pub fingers: Vec<u32>,
    /// The object's true rotation then (deg).
    pub rotation_deg: Real,
    /// Seconds since the first truth.
    pub at_s: Real,
}

/// When the hand first made its grasp.
#[derive(Debug, Clone, Copy, Serialize, PartialEq)]
pub struct FirstGrasp {
    /// The plan step then.
    pub step: u64,
    /// Seconds since the first truth.
    pub at_s: Real,
    /// The object's true rotation then (deg).
    pub rotation_deg: Real,
}

/// The summary's `physics`.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct PhysicsSummary {
    /// The simulator, `"MuJoCo 3.17.0"`.
    pub engine: String,
    /// The object's true rotation about z at the end (deg).
    pub rotation_deg: Real,
    /// The largest distance of its centre of mass from its start (m).
    pub drift_m: Real,
    /// The largest tangential slip speed at a contact planned to roll (m/s).
    pub max_slip_m_s: Real,
    /// The largest `|f_t| / (mu f_n)` at a contact planned to roll.
    pub max_friction_use: Real,
    /// Contacts lost while planned.
    pub unplanned_losses: u32,
    /// When each of them was lost (the first [`LOSSES_KEPT`]).
    pub losses: Vec<Loss>,
    /// The smallest alpha* of the true contacts over the plan steps (`None`: no step had a
    /// grasp in force closure to evaluate, or none came).
    pub min_true_quality: Option<Real>,
    /// The smallest alpha* of the true contacts over the plan steps whose true grasp was in
    /// force closure (`None`: none was).
    pub min_true_quality_closed: Option<Real>,
    /// Plan steps whose true grasp was evaluated (from the hand's first grasp on: every finger
    /// the plan has in contact touching at one truth), and those of them not in force closure.
    pub steps_evaluated: u32,
    /// See `steps_evaluated`.
    pub steps_not_closed: u32,
    /// Which steps were not (the first [`LOSSES_KEPT`]).
    pub not_closed: Vec<NotClosed>,
    /// When the hand first made its grasp (every finger the plan has in contact touching at
    /// one truth), and the plan step then (`None`: never).
    pub first_grasp: Option<FirstGrasp>,
    /// Plan steps that ended before it (their true grasps not taken: the hand still closing).
    pub steps_before_first_grasp: u32,
    /// Whether the object left the hand.
    pub dropped: bool,
    /// The margin the true grasp is held to (`grasp.alpha`).
    pub alpha: Real,
    /// The smallest alpha* of the true grasp at every truth since the hand made its first
    /// grasp: where MuJoCo's fingertips touch, on the exact surface, a finger off the object
    /// out of the grasp (0: a truth not in force closure; `None`: no truth came after it).
    pub true_quality_min: Option<Real>,
    /// Its 1st percentile (nearest rank).
    pub true_quality_p01: Option<Real>,
    /// Truths sampled, and those whose true grasp was not in force closure.
    pub true_quality_samples: u32,
    /// See `true_quality_samples`.
    pub samples_not_closed: u32,
    /// Plan steps with a truth sampled, and those with a truth not in force closure.
    pub true_quality_steps: u32,
    /// See `true_quality_steps`.
    pub true_quality_steps_not_closed: u32,
    /// Seconds with the true alpha* below `alpha`.
    pub time_below_alpha_s: Real,
    /// When (the first intervals).
    pub below_alpha: Vec<Below>,
    /// The largest angle the object turned off the plan's axis since the first truth (deg).
    pub max_tilt_deg: Real,
    /// When the tilt was largest (`None`: no tilt at all).
    pub max_tilt_at: Option<First>,
    /// The rotation off the plan's axis accrued truth to truth, by the plan step's phase
    /// (deg; "none": before the first step).
    pub off_axis_deg: std::collections::BTreeMap<&'static str, Real>,
    /// Gravity in the hand frame (m/s^2), as the plant simulates it.
    pub gravity: [Real; 3],
    /// Fingers touching each other and links touching the object.
    #[serde(flatten)]
    pub collisions: CollisionSummary,
}

/// The physics of a run so far.
pub struct PhysicsTrack {
    setup: Setup,
    mu: Real,
    engine: String,
    drop_distance: Real,
    start: Option<Vec3>,
    rotation: Real,
    drift: Real,
    max_slip: Real,
    max_use: Real,
    losses: u32,
    lost: Vec<Loss>,
    first_stamp: Option<u64>,
    phase: &'static str,
    steps: TrueSteps,
    not_closed: Vec<NotClosed>,
    dropped: bool,
    /// Per slot of the newest plan step: its finger, and whether it is planned in contact.
    planned: [(u32, bool); MAX_FINGERS],
    /// Per finger slot of the truth: truths in a row without contact while planned, and
    /// whether the loss was counted.
    off: [(u32, bool); MAX_FINGERS],
    /// Per finger slot of the truth: whether it has touched the object since the plan has had
    /// it in contact.
    made: [bool; MAX_FINGERS],
    /// Per finger slot of the truth: its last contact point (hand frame) and truths since.
    last_touch: [Option<(Vec3, u32)>; MAX_FINGERS],
    /// The candidates of the current plan step's grasp at the newest truth, if a truth came
    /// since the step: its quality is counted when the next step comes (or at the summary),
    /// so that each step's grasp is taken as the hand has made it (at a step's first truth an
    /// attaching finger may not touch yet); none before the hand's first grasp.
    pending: Vec<usize>,
    /// The fingers of `pending`, and the object's true rotation (rad) and the seconds since
    /// the first truth at it.
    pending_fingers: Vec<u32>,
    pending_at: (Real, Real),
    pending_due: bool,
    last_step: Option<u64>,
    first_grasp: Option<FirstGrasp>,
    steps_before_first_grasp: u32,
    gravity: [Real; 3],
    margin: TrueMargin,
    collisions: CollisionTrack,
}

impl PhysicsTrack {
    /// The track of a run of `config` on MuJoCo `version` (builds its own setup: the grasp
    /// problem it evaluates the true contacts with).
    pub fn new(config: &Config, version: &str) -> anyhow::Result<Self> {
        let setup = Setup::new(config)?;
        let drop_distance = DROP_FRACTION * setup.object.max_radius();
        let margin = TrueMargin::new(&setup, &config.object, config.grasp.alpha, config.turn.axis);
        Ok(Self {
            gravity: config.plant.gravity,
            margin,
            collisions: CollisionTrack::default(),
            mu: config.grasp.model.mu(),
            engine: format!("MuJoCo {version}"),
            drop_distance,
            setup,
            start: None,
            rotation: 0.0,
            drift: 0.0,
            max_slip: 0.0,
            max_use: 0.0,
            losses: 0,
            lost: Vec::new(),
            first_stamp: None,
            phase: "none",
            steps: TrueSteps::default(),
            not_closed: Vec::new(),
            dropped: false,
            planned: [(0, false); MAX_FINGERS],
            off: [(0, false); MAX_FINGERS],
            made: [false; MAX_FINGERS],
            last_touch: [None; MAX_FINGERS],
            pending: Vec::with_capacity(MAX_FINGERS),
            pending_fingers: Vec::with_capacity(MAX_FINGERS),
            pending_at: (0.0, 0.0),
            pending_due: false,
            last_step: None,
            first_grasp: None,
            steps_before_first_grasp: 0,
        })
    }

    /// A plan step: which fingers the plan has in contact; its grasp is evaluated at the
    /// next truth.
    pub fn plan_step(&mut self, p: &PlanStepHeader) {
        if self.last_step != Some(p.step) {
            if std::mem::take(&mut self.pending_due) {
                let alpha = self.quality(&self.pending);
                self.steps.count(alpha);
                if alpha <= 0.0 && self.not_closed.len() < LOSSES_KEPT {
                    self.not_closed.push(self.open_step());
                }
            } else if self.last_step.is_some() && self.first_grasp.is_none() {
                // The step before ended with the hand still closing.
                self.steps_before_first_grasp += 1;
            }
            self.last_step = Some(p.step);
        }
        let n = (p.finger_count as usize).min(MAX_FINGERS);
        self.planned = [(0, false); MAX_FINGERS];
        self.phase = PlanPhase::name_of(p.phase);
        for (slot, t) in p.targets.iter().enumerate().take(n) {
            self.planned[slot] = (t.finger, t.in_contact == 1);
        }
    }

    /// The step under way, its grasp pending, as one not in force closure.
    fn open_step(&self) -> NotClosed {
        NotClosed {
            step: self.last_step.unwrap_or(0),
            phase: self.phase,
            fingers: self.pending_fingers.clone(),
            rotation_deg: self.pending_at.0.to_degrees(),
            at_s: self.pending_at.1,
        }
    }

    fn planned_in_contact(&self, finger: u32) -> bool {
        self.planned.iter().any(|&(f, on)| on && f == finger)
    }

    /// A truth from the plant (other plants' are ignored).
    pub fn truth(&mut self, t: &PlantTruth) {
        if t.engine != PlantEngine::Mujoco as u32 {
            return;
        }
        self.first_stamp.get_or_insert(t.header.source_time_ns);
        let centre = Vec3::from(t.position);
        let start = *self.start.get_or_insert(centre);
        self.drift = self.drift.max((centre - start).norm());
        self.dropped |= self.drift > self.drop_distance;
        self.rotation = t.rotation;
        let n = (t.finger_count as usize).min(MAX_FINGERS);
        for slot in 0..n {
            let finger = t.finger_ids[slot];
            let planned = self.planned_in_contact(finger);
            let on = t.in_contact[slot] == 1;
            if planned && on {
                self.max_slip = self.max_slip.max(t.slip_speeds[slot]);
                let f = Vec3::from(t.contact_forces[slot]);
                let normal = Vec3::from(t.contact_normals[slot]);
                let fn_ = -f.dot(&normal);
                if fn_ > 1e-6 {
                    let ft = (f + normal * fn_).norm();
                    self.max_use = self.max_use.max(ft / (self.mu * fn_));
                }
            }
            self.last_touch[slot] = if on {
                Some((Vec3::from(t.contact_points[slot]), 0))
            } else {
                self.last_touch[slot].map(|(p, n)| (p, n + 1))
            };
            // A contact is lost only once it was made: planned, it touched.
            let made = &mut self.made[slot];
            *made = planned && (*made || on);
            let (count, counted) = &mut self.off[slot];
            if *made && !on {
                *count += 1;
                if *count >= LOST_AFTER && !*counted {
                    *counted = true;
                    self.losses += 1;
                    if self.lost.len() < LOSSES_KEPT {
                        let first = *self.first_stamp.get_or_insert(t.header.source_time_ns);
                        self.lost.push(Loss {
                            finger,
                            step: self.last_step.unwrap_or(0),
                            phase: self.phase,
                            rotation_deg: t.rotation.to_degrees(),
                            at_s: t.header.source_time_ns.saturating_sub(first) as Real * 1e-9,
                        });
                    }
                }
            } else {
                *count = 0;
                *counted = false;
            }
        }
        let first = self.first_stamp.unwrap_or(t.header.source_time_ns);
        let at_s = t.header.source_time_ns.saturating_sub(first) as Real * 1e-9;
        self.collisions.truth(t, at_s);
        let plan = self.last_step.map(|step| Planned {
            step,
            phase: self.phase,
            fingers: &self.planned,
        });
        self.margin
            .truth(&self.setup.problem, t, at_s, plan.as_ref());
        // A step's grasp is taken from the hand's first grasp on, as the true margin's
        // samples are: MuJoCo steps from the first command on, and the start step may end
        // before a fingertip placed at the surface has been pressed in (a run of 2026-12-05
        // took the Allegro's start at its first truths, the thumb not yet touching).
        if let Some(step) = self.last_step
            && self.margin.made()
        {
            self.first_grasp.get_or_insert(FirstGrasp {
                step,
                at_s,
                rotation_deg: t.rotation.to_degrees(),
            });
            self.contacts(t);
            self.pending_due = true;
        }
    }

    /// The candidates of the grasp at truth `t`'s contacts, in the object's frame, into
    /// `pending`: each fingertip touching, or planned in contact and off for fewer truths than
    /// make a loss (MuJoCo's contacts flicker on a rolling fingertip), at its last point,
    /// snapped to the nearest candidate.
    fn contacts(&mut self, t: &PlantTruth) {
        let [w, x, y, z] = t.orientation;
        let q = UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(w, x, y, z));
        let origin = Vec3::from(t.position) - q * self.setup.object.centre_of_mass;
        self.pending.clear();
        self.pending_fingers.clear();
        let first = self.first_stamp.unwrap_or(t.header.source_time_ns);
        self.pending_at = (
            t.rotation,
            t.header.source_time_ns.saturating_sub(first) as Real * 1e-9,
        );
        for slot in 0..(t.finger_count as usize).min(MAX_FINGERS) {
            let planned = self.planned_in_contact(t.finger_ids[slot]);
            let Some((point, _)) =
                self.last_touch[slot].filter(|&(_, off)| off == 0 || (planned && off < LOST_AFTER))
            else {
                continue;
            };
            let p = q.inverse() * (point - origin);
            if let Some((c, _)) = self.setup.problem.nearest_candidate(&p)
                && !self.pending.contains(&c)
            {
                self.pending.push(c);
                self.pending_fingers.push(t.finger_ids[slot]);
            }
        }
    }

    /// The quality alpha* of the grasp at `contacts` (0: not in force closure, or fewer than
    /// two).
    fn quality(&self, contacts: &[usize]) -> Real {
        if contacts.len() < 2 {
            return 0.0;
        }
        self.setup
            .problem
            .evaluate(contacts)
            .map_or(0.0, |e| e.quality.max(0.0))
    }

    /// What it found.
    pub fn summary(&self) -> PhysicsSummary {
        // The step under way counts as it stands.
        let mut steps = self.steps;
        let mut not_closed = self.not_closed.clone();
        if self.pending_due {
            let alpha = self.quality(&self.pending);
            steps.count(alpha);
            if alpha <= 0.0 && not_closed.len() < LOSSES_KEPT {
                not_closed.push(self.open_step());
            }
        }
        let m = self.margin.margin();
        PhysicsSummary {
            engine: self.engine.clone(),
            rotation_deg: self.rotation.to_degrees(),
            drift_m: self.drift,
            max_slip_m_s: self.max_slip,
            max_friction_use: self.max_use,
            unplanned_losses: self.losses,
            losses: self.lost.clone(),
            min_true_quality: steps.min,
            min_true_quality_closed: steps.min_closed,
            steps_evaluated: steps.evaluated,
            steps_not_closed: steps.not_closed,
            not_closed,
            first_grasp: self.first_grasp,
            steps_before_first_grasp: self.steps_before_first_grasp,
            dropped: self.dropped,
            alpha: self.margin.alpha(),
            true_quality_min: m.min,
            true_quality_p01: m.p01,
            true_quality_samples: m.samples,
            samples_not_closed: m.samples_not_closed,
            true_quality_steps: m.steps,
            true_quality_steps_not_closed: m.steps_not_closed,
            time_below_alpha_s: m.below_s,
            below_alpha: m.below,
            max_tilt_deg: m.max_tilt.to_degrees(),
            max_tilt_at: m.max_tilt_at,
            off_axis_deg: m
                .off_axis
                .iter()
                .map(|(k, v)| (*k, v.to_degrees()))
                .collect(),
            gravity: self.gravity,
            collisions: self.collisions.summary(),
        }
    }
}

/// The plan steps' true grasps so far: the smallest quality (of all, and of those in force
/// closure), the steps evaluated and those not in force closure.
#[derive(Debug, Clone, Copy, Default)]
struct TrueSteps {
    min: Option<Real>,
    min_closed: Option<Real>,
    evaluated: u32,
    not_closed: u32,
}

impl TrueSteps {
    /// A step of quality `alpha` (0: not in force closure) counted in.
    fn count(&mut self, alpha: Real) {
        self.min = Some(self.min.map_or(alpha, |m| m.min(alpha)));
        self.evaluated += 1;
        if alpha <= 0.0 {
            self.not_closed += 1;
        } else {
            self.min_closed = Some(self.min_closed.map_or(alpha, |m| m.min(alpha)));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use icrflow_interfaces::FingerTarget;

    /// The paper's scenario in MuJoCo, and the candidates of its initial contacts (fingers 1,
    /// 2 and 4; finger 3 starts free).
    fn paper() -> (Config, Vec<usize>) {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("config/paper_sphere_mujoco.toml");
        let config = Config::load(&path).unwrap();
        let setup = Setup::new(&config).unwrap();
        let (start, _) = setup.scenario(&config).start().unwrap();
        (config, start.iter().map(|c| c.candidate).collect())
    }

    /// Plan step `step` with `contacts` (finger, planned in contact) in slots 0-3.
    fn step(step: u64, contacts: [bool; 4]) -> PlanStepHeader {
        let mut p = PlanStepHeader {
            step,
            finger_count: 4,
            ..Default::default()
        };
        for (slot, on) in contacts.into_iter().enumerate() {
            p.targets[slot] = FingerTarget {
                finger: slot as u32 + 1,
                in_contact: u32::from(on),
                ..Default::default()
            };
        }
        p
    }

    /// A truth with the object at rest at the origin and the fingers of slots 0-3 touching
    /// where `touch` says (at those candidates' points).
    fn truth(config: &Config, touch: [Option<usize>; 4]) -> PlantTruth {
        let setup = Setup::new(config).unwrap();
        let cands = setup.problem.candidates();
        let mut t = PlantTruth {
            orientation: [1.0, 0.0, 0.0, 0.0],
            finger_count: 4,
            engine: PlantEngine::Mujoco as u32,
            ..Default::default()
        };
        for (slot, c) in touch.into_iter().enumerate() {
            t.finger_ids[slot] = slot as u32 + 1;
            if let Some(c) = c {
                let p = cands.points[c] - setup.object.centre_of_mass;
                t.in_contact[slot] = 1;
                t.contact_points[slot] = [p.x, p.y, p.z];
            }
        }
        t
    }

    /// Feeds a truth to a track, the truths 10 ms apart as the plant publishes them.
    fn feeder() -> impl FnMut(&mut PhysicsTrack, &PlantTruth) {
        let mut sent = 0u64;
        move |track: &mut PhysicsTrack, t: &PlantTruth| {
            let mut t = *t;
            t.header.source_time_ns = 5_000_000_000 + sent * 10_000_000;
            sent += 1;
            track.truth(&t);
        }
    }

    /// A finger planned in contact that has not touched yet (an attach on its way) has lost
    /// nothing; once it touched, LOST_AFTER truths off it while still planned are one loss.
    #[test]
    fn a_contact_is_lost_only_once_it_was_made() {
        let (config, c) = paper();
        let mut track = PhysicsTrack::new(&config, "3.17.0").unwrap();
        let mut feed = feeder();
        // Finger 3 (slot 2) attaches at a candidate between fingers 2's and 4's.
        let attach = (c[1] + c[2]) / 2;
        let mut attaching = step(5, [true, true, true, true]);
        attaching.phase = PlanPhase::Attach as u32;
        track.plan_step(&attaching);
        let approaching = truth(&config, [Some(c[0]), Some(c[1]), None, Some(c[2])]);
        for _ in 0..10 {
            feed(&mut track, &approaching);
        }
        assert_eq!(track.summary().unplanned_losses, 0);
        let touching = truth(&config, [Some(c[0]), Some(c[1]), Some(attach), Some(c[2])]);
        feed(&mut track, &touching);
        for k in 0..LOST_AFTER {
            assert_eq!(track.summary().unplanned_losses, 0, "after {k} truths off");
            feed(&mut track, &approaching);
        }
        let s = track.summary();
        assert_eq!(s.unplanned_losses, 1);
        // The summary says which finger, in which step and phase, and when: the loss is
        // counted at the run's fourteenth truth, 130 ms after its first.
        assert_eq!(s.losses.len(), 1);
        let l = &s.losses[0];
        assert_eq!((l.finger, l.step, l.phase), (3, 5, "attach"));
        assert!((l.at_s - 0.13).abs() < 1e-9, "{l:?}");
    }

    /// A plan step's grasp is taken at its last truth, as the hand has made it: at the first
    /// truth of the run the hand has not yet pressed (two contacts, no force closure), by the
    /// step's end all three touch; a contact that flickers off for a truth still counts.
    #[test]
    fn a_steps_grasp_is_taken_as_the_hand_has_made_it() {
        let (config, c) = paper();
        let mut track = PhysicsTrack::new(&config, "3.17.0").unwrap();
        track.plan_step(&step(1, [true, true, false, true]));
        track.truth(&truth(&config, [Some(c[0]), Some(c[1]), None, None]));
        let made = truth(&config, [Some(c[0]), Some(c[1]), None, Some(c[2])]);
        track.truth(&made);
        let flicker = truth(&config, [Some(c[0]), None, None, Some(c[2])]);
        track.truth(&flicker);
        let s = track.summary();
        assert_eq!((s.steps_evaluated, s.steps_not_closed), (1, 0), "{s:?}");
        let alpha = s.min_true_quality.unwrap();
        assert!(alpha >= config.grasp.alpha, "{alpha}");
        // The next step commits the first; off for LOST_AFTER truths, the contact is gone.
        track.plan_step(&step(2, [true, true, false, true]));
        for _ in 0..LOST_AFTER {
            track.truth(&flicker);
        }
        let s = track.summary();
        assert_eq!((s.steps_evaluated, s.steps_not_closed), (2, 1), "{s:?}");
        assert_eq!(s.min_true_quality, Some(0.0));
        // Which: step 2 (phase 0 in these messages: "start"), only fingers 1 and 4 touching.
        assert_eq!(s.not_closed.len(), 1, "{s:?}");
        assert_eq!((s.not_closed[0].step, s.not_closed[0].phase), (2, "start"));
        assert_eq!(s.not_closed[0].fingers, vec![1, 4]);
        // The step in force closure keeps its quality apart.
        assert_eq!(s.min_true_quality_closed, Some(alpha));
    }

    /// A step that ends before the hand has made its first grasp is not taken (its fingertips
    /// placed at the surface, MuJoCo not yet pressing them in): the next, once made, is.
    #[test]
    fn a_step_before_the_first_grasp_is_not_taken() {
        let (config, c) = paper();
        let mut track = PhysicsTrack::new(&config, "3.17.0").unwrap();
        track.plan_step(&step(0, [true, true, false, true]));
        track.truth(&truth(&config, [Some(c[0]), Some(c[1]), None, None]));
        track.plan_step(&step(1, [true, true, false, true]));
        let s = track.summary();
        assert_eq!((s.steps_evaluated, s.min_true_quality), (0, None), "{s:?}");
        assert_eq!(
            (s.first_grasp, s.steps_before_first_grasp),
            (None, 1),
            "{s:?}"
        );
        track.truth(&truth(&config, [Some(c[0]), Some(c[1]), None, Some(c[2])]));
        track.plan_step(&step(2, [true, true, false, true]));
        let s = track.summary();
        assert_eq!((s.steps_evaluated, s.steps_not_closed), (1, 0), "{s:?}");
        // Made under step 1; step 0 ended before it.
        let first = s.first_grasp.unwrap();
        assert_eq!((first.step, s.steps_before_first_grasp), (1, 1), "{s:?}");
        // Once made, a step whose grasp has lost a finger is taken as it is.
        track.truth(&truth(&config, [Some(c[0]), Some(c[1]), None, None]));
        for _ in 0..LOST_AFTER {
            track.truth(&truth(&config, [Some(c[0]), Some(c[1]), None, None]));
        }
        let s = track.summary();
        assert_eq!((s.steps_evaluated, s.steps_not_closed), (2, 1), "{s:?}");
    }

    /// The true grasp at every truth once the hand has made it: before every planned finger
    /// first touches (the hand closing) nothing is sampled; then a finger that lifts for one
    /// truth is out of the grasp at that truth (two contacts: no force closure), the time
    /// below the margin and the step counted.
    #[test]
    fn the_true_grasp_is_taken_at_every_truth_once_made() {
        let (config, c) = paper();
        let mut track = PhysicsTrack::new(&config, "3.17.0").unwrap();
        let mut feed = feeder();
        track.plan_step(&step(1, [true, true, false, true]));
        feed(
            &mut track,
            &truth(&config, [Some(c[0]), Some(c[1]), None, None]),
        );
        let s = track.summary();
        assert_eq!(
            (s.true_quality_samples, s.true_quality_min),
            (0, None),
            "{s:?}"
        );
        let made = truth(&config, [Some(c[0]), Some(c[1]), None, Some(c[2])]);
        feed(&mut track, &made);
        feed(&mut track, &made);
        let s = track.summary();
        assert_eq!(
            (s.true_quality_samples, s.samples_not_closed),
            (2, 0),
            "{s:?}"
        );
        let alpha = s.true_quality_min.unwrap();
        assert!(alpha >= config.grasp.alpha, "{alpha}");
        assert_eq!(s.time_below_alpha_s, 0.0);
        // The contacts at the candidates' points, on the exact sphere: the candidates' grasp.
        let setup = Setup::new(&config).unwrap();
        let grid = setup.problem.evaluate(&c).unwrap().quality;
        assert!((alpha - grid).abs() < 1e-9, "{alpha} {grid}");
        // Finger 2 lifts for one truth in step 2.
        track.plan_step(&step(2, [true, true, false, true]));
        let flicker = truth(&config, [Some(c[0]), None, None, Some(c[2])]);
        feed(&mut track, &flicker);
        feed(&mut track, &made);
        let s = track.summary();
        assert_eq!(
            (s.true_quality_samples, s.samples_not_closed),
            (4, 1),
            "{s:?}"
        );
        assert_eq!(s.true_quality_min, Some(0.0));
        assert!((s.time_below_alpha_s - 0.01).abs() < 1e-9, "{s:?}");
        assert_eq!(s.below_alpha.len(), 1, "{s:?}");
        let b = &s.below_alpha[0];
        assert_eq!(
            (b.step, b.min_quality, b.fingers.clone()),
            (2, 0.0, vec![1, 4])
        );
        assert!(
            (b.from_s - 0.03).abs() < 1e-9 && (b.to_s - 0.03).abs() < 1e-9,
            "{b:?}"
        );
        assert_eq!(
            (s.true_quality_steps, s.true_quality_steps_not_closed),
            (2, 1)
        );
        assert_eq!(s.true_quality_p01, Some(0.0));
        assert_eq!(s.max_tilt_deg, 0.0);
        assert_eq!(
            (s.max_tilt_at, s.off_axis_deg.get("start")),
            (None, Some(&0.0))
        );
        assert_eq!(s.gravity, config.plant.gravity);
    }

    /// The tilt: the largest rotation off the plan's axis since the first truth, when it came,
    /// and what each phase added truth to truth (a tilt there and back counts twice).
    #[test]
    fn the_tilt_says_when_and_in_which_phase() {
        let (config, _) = paper();
        let mut track = PhysicsTrack::new(&config, "3.17.0").unwrap();
        let mut feed = feeder();
        let about = |axis: Vec3, deg: f64| {
            let q = UnitQuaternion::from_axis_angle(
                &nalgebra::Unit::new_normalize(axis),
                deg.to_radians(),
            );
            [q.w, q.i, q.j, q.k]
        };
        let mut t = truth(&config, [None; 4]);
        track.plan_step(&step(1, [true, true, false, true]));
        feed(&mut track, &t);
        // Turned 10 deg about the plan's axis (z): no tilt.
        t.orientation = about(Vec3::z(), 10.0);
        t.rotation = 10f64.to_radians();
        feed(&mut track, &t);
        // Then, in an attach step, 3 deg about x on top, and back.
        let mut attach = step(2, [true, true, true, true]);
        attach.phase = PlanPhase::Attach as u32;
        track.plan_step(&attach);
        let z = UnitQuaternion::from_axis_angle(&Vec3::z_axis(), 10f64.to_radians());
        let x = UnitQuaternion::from_axis_angle(&Vec3::x_axis(), 3f64.to_radians());
        let tilted = x * z;
        t.orientation = [tilted.w, tilted.i, tilted.j, tilted.k];
        feed(&mut track, &t);
        t.orientation = about(Vec3::z(), 10.0);
        feed(&mut track, &t);
        let s = track.summary();
        assert!((s.max_tilt_deg - 3.0).abs() < 1e-9, "{s:?}");
        let at = s.max_tilt_at.unwrap();
        assert!(
            (at.at_s - 0.02).abs() < 1e-9 && (at.rotation_deg - 10.0).abs() < 1e-9,
            "{at:?}"
        );
        assert!(s.off_axis_deg["start"].abs() < 1e-9, "{s:?}");
        assert!((s.off_axis_deg["attach"] - 6.0).abs() < 1e-9, "{s:?}");
    }
}
