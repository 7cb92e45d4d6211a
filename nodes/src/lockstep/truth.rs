//! What a lockstep run did against MuJoCo's truth, counted as `icrflow run`'s summary counts
//! it: contacts lost while planned, fingers touching each other and links on the object, the
//! object's tilt off the plan's axis, and the estimate's error against the true rotation.
//! The lockstep example prints it; tests assert on it.

use std::collections::BTreeMap;

use icrflow_interfaces::{PlanPhase, PlantTruth};
use icrflow_plan::rolling::tilt;
use icrflow_scenario::Config;
use nalgebra::{Quaternion, Unit, UnitQuaternion, Vector3};

use super::Tick;

/// Truths in a row (10 ms apart) a fingertip planned in contact, once it touched, is off the
/// object before its contact counts as lost: `run`'s rule, whose own constant (the root crate's
/// `run::physics::LOST_AFTER`, which this crate cannot see) must stay equal to this one.
pub const LOST_AFTER: u32 = 3;

/// A contact lost while planned.
#[derive(Debug, Clone, PartialEq)]
pub struct Lost {
    /// Simulated time (s).
    pub time: f64,
    /// The plan step.
    pub step: u64,
    /// Its phase.
    pub phase: &'static str,
    /// The finger.
    pub finger: u32,
    /// MuJoCo's rotation about the plan's axis (deg).
    pub rotation_deg: f64,
}

impl std::fmt::Display for Lost {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "t {:.3} s, step {} {}, finger {} (true {:.2} deg)",
            self.time, self.step, self.phase, self.finger, self.rotation_deg
        )
    }
}

/// The largest error of the estimated rotation against the truth.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Worst {
    /// |estimated - true| (deg).
    pub deg: f64,
    /// Simulated time (s).
    pub time: f64,
    /// The plan's phase then.
    pub phase: &'static str,
    /// MuJoCo's rotation then (deg).
    pub true_deg: f64,
}

/// The truth of a lockstep run so far ([`TruthWatch::observe`] every tick).
#[derive(Debug, Clone)]
pub struct TruthWatch {
    axis: Unit<Vector3<f64>>,
    /// The gate's bound on the estimate (rad, `pipeline.max_pose_innovation_deg`).
    bound: f64,
    /// Per finger: touched since planned in contact, and truths off in a row.
    made: BTreeMap<u32, (bool, u32)>,
    first_pose: Option<UnitQuaternion<f64>>,
    /// Contacts lost while planned.
    pub losses: Vec<Lost>,
    /// MuJoCo's integration steps.
    pub integrated: u64,
    /// Those with fingers touching each other.
    pub fingers_touching: u64,
    /// Those with a link (not a fingertip) on the object.
    pub links_on_object: u64,
    /// The first time (s) fingers touched each other.
    pub first_touching: Option<f64>,
    /// The first time (s) a link was on the object.
    pub first_link: Option<f64>,
    /// The object's tilt off the plan's axis since the first truth (deg).
    pub tilt_deg: f64,
    /// Its largest (deg), and when (s).
    pub max_tilt: (f64, f64),
    /// The estimate's largest error against the truth, at the truths.
    pub worst_estimate: Worst,
    /// Truths at which a tracking command went out on an estimate off the truth by more than
    /// the gate's bound (`run`'s `tracked_off_truth` counts every such command, ten a truth).
    pub tracked_off: u64,
}

impl TruthWatch {
    /// The watch of a run of `config`.
    pub fn new(config: &Config) -> Self {
        Self {
            axis: Unit::new_normalize(config.turn.axis),
            bound: config.pipeline.max_pose_innovation,
            made: BTreeMap::new(),
            first_pose: None,
            losses: Vec::new(),
            integrated: 0,
            fingers_touching: 0,
            links_on_object: 0,
            first_touching: None,
            first_link: None,
            tilt_deg: 0.0,
            max_tilt: (0.0, 0.0),
            worst_estimate: Worst::default(),
            tracked_off: 0,
        }
    }

    /// The object's true orientation at `truth`.
    pub fn orientation(truth: &PlantTruth) -> UnitQuaternion<f64> {
        let [w, x, y, z] = truth.orientation;
        UnitQuaternion::from_quaternion(Quaternion::new(w, x, y, z))
    }

    /// A tick of the run (only ticks with a truth count).
    pub fn observe(&mut self, tick: &Tick<'_>) {
        let Some(truth) = tick.truth else { return };
        self.integrated += u64::from(truth.physics_steps);
        self.fingers_touching += u64::from(truth.finger_touch_steps);
        self.links_on_object += u64::from(truth.link_object_steps);
        if truth.finger_touch_steps > 0 {
            self.first_touching.get_or_insert(tick.time);
        }
        if truth.link_object_steps > 0 {
            self.first_link.get_or_insert(tick.time);
        }
        let q = Self::orientation(truth);
        let first = *self.first_pose.get_or_insert(q);
        self.tilt_deg = tilt(&(q * first.inverse()), &self.axis).to_degrees();
        if self.tilt_deg > self.max_tilt.0 {
            self.max_tilt = (self.tilt_deg, tick.time);
        }
        let phase = tick.plan.map_or("none", |p| PlanPhase::name_of(p.phase));
        if let Some(g) = tick.grasp {
            let error = (g.rotation - truth.rotation).abs().to_degrees();
            if error > self.worst_estimate.deg {
                self.worst_estimate = Worst {
                    deg: error,
                    time: tick.time,
                    phase,
                    true_deg: truth.rotation.to_degrees(),
                };
            }
            if error > self.bound.to_degrees() && tick.command.is_some_and(|(_, h)| h.is_none()) {
                self.tracked_off += 1;
            }
        }
        let Some(plan) = tick.plan else { return };
        let n = (plan.finger_count as usize).min(plan.targets.len());
        for slot in 0..(truth.finger_count as usize).min(truth.finger_ids.len()) {
            let finger = truth.finger_ids[slot];
            let planned = plan.targets[..n]
                .iter()
                .any(|t| t.finger == finger && t.in_contact == 1);
            let on = truth.in_contact[slot] == 1;
            let (made, off) = self.made.entry(finger).or_default();
            *made = planned && (*made || on);
            if *made && !on {
                *off += 1;
                if *off == LOST_AFTER {
                    self.losses.push(Lost {
                        time: tick.time,
                        step: plan.step,
                        phase,
                        finger,
                        rotation_deg: truth.rotation.to_degrees(),
                    });
                }
            } else {
                *off = 0;
            }
        }
    }

    /// The bound (deg) `tracked_off` counts against.
    pub fn bound_deg(&self) -> f64 {
        self.bound.to_degrees()
    }
}
