//! The run against the physics: what MuJoCo's truth says of the plan's execution (the
//! summary's `physics`).
//!
//! Fed every [`PlantTruth`] of a MuJoCo plant and every plan step: the object's true rotation
//! and the largest distance of its centre from the start; per contact planned to roll, the
//! largest tangential slip speed and friction use `|f_t| / (mu f_n)`; contacts lost while the
//! plan has them (a finger off the object for [`LOST_AFTER`] truths in a row while planned in
//! contact); at every plan step, the quality alpha* of the grasp at MuJoCo's true contact
//! points (each taken into the object's frame and snapped to the nearest candidate of the
//! section); whether the object was dropped (its centre further than [`DROP_FRACTION`] of its
//! size from the start).

use icrflow_grasp::math::{Real, UnitQuaternion, Vec3};
use icrflow_interfaces::{MAX_FINGERS, PlanStepHeader, PlantEngine, PlantTruth};
use icrflow_scenario::{Config, Setup};
use serde::Serialize;

/// Truths in a row without contact after which a finger planned in contact is lost (30 ms at
/// the truth's 100 Hz: MuJoCo's contacts flicker on a rolling fingertip for a step or two).
pub const LOST_AFTER: u32 = 3;
/// The object is dropped when its centre has moved this fraction of its largest radius.
pub const DROP_FRACTION: Real = 0.5;

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
    /// The smallest alpha* of the true contacts over the plan steps (`None`: no step had a
    /// grasp in force closure to evaluate, or none came).
    pub min_true_quality: Option<Real>,
    /// Plan steps whose true grasp was evaluated, and those of them not in force closure.
    pub steps_evaluated: u32,
    /// See `steps_evaluated`.
    pub steps_not_closed: u32,
    /// Whether the object left the hand.
    pub dropped: bool,
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
    min_quality: Option<Real>,
    evaluated: u32,
    not_closed: u32,
    dropped: bool,
    /// Per slot of the newest plan step: its finger, and whether it is planned in contact.
    planned: [(u32, bool); MAX_FINGERS],
    /// Per finger slot of the truth: truths in a row without contact while planned, and
    /// whether the loss was counted.
    off: [(u32, bool); MAX_FINGERS],
    /// A plan step came since the last evaluation.
    step_due: bool,
    last_step: Option<u64>,
}

impl PhysicsTrack {
    /// The track of a run of `config` on MuJoCo `version` (builds its own setup: the grasp
    /// problem it evaluates the true contacts with).
    pub fn new(config: &Config, version: &str) -> anyhow::Result<Self> {
        let setup = Setup::new(config)?;
        let drop_distance = DROP_FRACTION * setup.object.max_radius();
        Ok(Self {
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
            min_quality: None,
            evaluated: 0,
            not_closed: 0,
            dropped: false,
            planned: [(0, false); MAX_FINGERS],
            off: [(0, false); MAX_FINGERS],
            step_due: false,
            last_step: None,
        })
    }

    /// A plan step: which fingers the plan has in contact; its grasp is evaluated at the
    /// next truth.
    pub fn plan_step(&mut self, p: &PlanStepHeader) {
        let n = (p.finger_count as usize).min(MAX_FINGERS);
        self.planned = [(0, false); MAX_FINGERS];
        for (slot, t) in p.targets.iter().enumerate().take(n) {
            self.planned[slot] = (t.finger, t.in_contact == 1);
        }
        if self.last_step != Some(p.step) {
            self.last_step = Some(p.step);
            self.step_due = true;
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
            let (count, counted) = &mut self.off[slot];
            if planned && !on {
                *count += 1;
                if *count >= LOST_AFTER && !*counted {
                    *counted = true;
                    self.losses += 1;
                }
            } else {
                *count = 0;
                *counted = false;
            }
        }
        if self.step_due {
            self.step_due = false;
            self.evaluate(t);
        }
    }

    /// The quality of the grasp at the truth's contacts, in the object's frame.
    fn evaluate(&mut self, t: &PlantTruth) {
        let [w, x, y, z] = t.orientation;
        let q = UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(w, x, y, z));
        let origin = Vec3::from(t.position) - q * self.setup.object.centre_of_mass;
        let cands = self.setup.problem.candidates();
        let mut contacts = Vec::with_capacity(MAX_FINGERS);
        for slot in 0..(t.finger_count as usize).min(MAX_FINGERS) {
            if t.in_contact[slot] != 1 {
                continue;
            }
            let p = q.inverse() * (Vec3::from(t.contact_points[slot]) - origin);
            let nearest = (0..cands.points.len()).min_by(|&a, &b| {
                (cands.points[a] - p)
                    .norm_squared()
                    .total_cmp(&(cands.points[b] - p).norm_squared())
            });
            if let Some(c) = nearest
                && !contacts.contains(&c)
            {
                contacts.push(c);
            }
        }
        if contacts.len() < 2 {
            self.evaluated += 1;
            self.not_closed += 1;
            self.min_quality = Some(0.0);
            return;
        }
        match self.setup.problem.evaluate(&contacts) {
            Ok(e) => {
                self.evaluated += 1;
                let alpha = e.quality;
                if alpha <= 0.0 {
                    self.not_closed += 1;
                }
                self.min_quality = Some(self.min_quality.map_or(alpha, |m| m.min(alpha)));
            }
            Err(_) => {
                self.evaluated += 1;
                self.not_closed += 1;
                self.min_quality = Some(0.0);
            }
        }
    }

    /// What it found.
    pub fn summary(&self) -> PhysicsSummary {
        PhysicsSummary {
            engine: self.engine.clone(),
            rotation_deg: self.rotation.to_degrees(),
            drift_m: self.drift,
            max_slip_m_s: self.max_slip,
            max_friction_use: self.max_use,
            unplanned_losses: self.losses,
            min_true_quality: self.min_quality,
            steps_evaluated: self.evaluated,
            steps_not_closed: self.not_closed,
            dropped: self.dropped,
        }
    }
}
