//! The true margin of a MuJoCo run: the quality alpha* of the grasp the fingertips really make,
//! at every truth the plant publishes (100 Hz), and how far the object tilts off the plan's
//! axis (the summary's `physics`).
//!
//! Each fingertip touching the object at a truth is a contact where MuJoCo puts it: the point
//! taken into the object's frame from the true pose, then onto the exact surface the planner
//! rolls on (the sphere, the ellipsoid, or the mesh's facet: [`Convex::closest`]), with that
//! surface's normal there. Not snapped to a candidate, and no last point kept for a fingertip
//! that lifted: a finger off the object is out of the grasp. Sampling starts once the hand
//! has made its first grasp (every finger the plan has in contact touching at one truth);
//! from then on every truth counts.
//!
//! The tilt is the angle of the object's rotation since the first truth that is not about the
//! plan's axis (the swing of its swing-twist decomposition about the axis).

use icrflow_grasp::math::{Real, UnitQuaternion, Vec3};
use icrflow_grasp::object::Object;
use icrflow_grasp::quality::GraspProblem;
use icrflow_interfaces::{MAX_FINGERS, PlantTruth};
use icrflow_plan::rolling::tilt;
use icrflow_plan::spatial::surface::Convex;
use icrflow_scenario::{ObjectSpec, Setup};
use nalgebra::{Quaternion, Unit};
use serde::Serialize;

use super::collisions::First;
use crate::percentile;

/// The intervals below the margin a summary lists (it counts them all).
pub const KEPT: usize = 16;

/// An interval of truths whose true grasp kept less than the margin.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct Below {
    /// Seconds since the first truth: the first truth below, and the last.
    pub from_s: Real,
    /// See `from_s`.
    pub to_s: Real,
    /// The smallest alpha* in it (0: not in force closure).
    pub min_quality: Real,
    /// The newest plan step at its start, and its phase.
    pub step: u64,
    /// See `step`.
    pub phase: &'static str,
    /// The object's true rotation at its start (deg).
    pub rotation_deg: Real,
    /// The fingers touching at its worst truth.
    pub fingers: Vec<u32>,
}

/// The plan's step when a truth comes: its number and phase, and per finger slot (finger,
/// planned in contact).
pub struct Planned<'a> {
    /// The newest plan step.
    pub step: u64,
    /// Its phase's name.
    pub phase: &'static str,
    /// Per slot: its finger, and whether the plan has it in contact.
    pub fingers: &'a [(u32, bool)],
}

/// What the true margin found, for the summary.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Margin {
    /// The smallest alpha* over the samples (`None`: none came).
    pub min: Option<Real>,
    /// Its 1st percentile (nearest rank).
    pub p01: Option<Real>,
    /// Truths sampled, and those not in force closure.
    pub samples: u32,
    /// See `samples`.
    pub samples_not_closed: u32,
    /// Seconds with alpha* below the margin (a sample counts the time since the one before).
    pub below_s: Real,
    /// When (the first [`KEPT`] intervals).
    pub below: Vec<Below>,
    /// Plan steps sampled, and those with a sample not in force closure (and which).
    pub steps: u32,
    /// See `steps`.
    pub steps_not_closed: u32,
    /// The largest tilt off the plan's axis (rad).
    pub max_tilt: Real,
    /// When it was largest: seconds since the first truth, and the true rotation then.
    pub max_tilt_at: Option<First>,
    /// The object's rotation off the plan's axis accrued truth to truth, by the plan step's
    /// phase then (rad; "none" before the first step): the swing of each truth's rotation
    /// since the one before, summed. Where the tilt comes from, which [`Margin::max_tilt`]
    /// (the net rotation off the axis) does not say.
    pub off_axis: std::collections::BTreeMap<&'static str, Real>,
}

/// The sampler.
pub struct TrueMargin {
    /// The surface the contacts are put on (`None`: a mesh that is not convex; then MuJoCo's
    /// own points and normals).
    surface: Option<Convex>,
    centre: Vec3,
    alpha: Real,
    axis: Unit<Vec3>,
    first_orientation: Option<UnitQuaternion>,
    last_orientation: Option<UnitQuaternion>,
    made: bool,
    qualities: Vec<Real>,
    last_s: Option<Real>,
    open: Option<Below>,
    step: Option<(u64, bool)>,
    out: Margin,
    contacts: Vec<(Vec3, Vec3)>,
    fingers: Vec<u32>,
}

impl TrueMargin {
    /// The sampler of a run of `setup`, its margin `alpha` (`grasp.alpha`), the plan's `axis`.
    pub fn new(setup: &Setup, spec: &ObjectSpec, alpha: Real, axis: Vec3) -> Self {
        Self {
            surface: surface_of(setup, spec),
            centre: setup.object.centre_of_mass,
            alpha,
            axis: Unit::new_normalize(axis),
            first_orientation: None,
            last_orientation: None,
            made: false,
            qualities: Vec::new(),
            last_s: None,
            open: None,
            step: None,
            out: Margin::default(),
            contacts: Vec::with_capacity(MAX_FINGERS),
            fingers: Vec::with_capacity(MAX_FINGERS),
        }
    }

    /// The margin the samples are held to.
    pub fn alpha(&self) -> Real {
        self.alpha
    }

    /// Whether the hand has made its first grasp (every finger the plan has in contact
    /// touching at one truth): sampling has begun.
    pub fn made(&self) -> bool {
        self.made
    }

    /// Truth `t`, `at_s` seconds after the first, under the plan's step `plan` (`None`: no
    /// step yet), evaluated with `problem`.
    pub fn truth(
        &mut self,
        problem: &GraspProblem,
        t: &PlantTruth,
        at_s: Real,
        plan: Option<&Planned<'_>>,
    ) {
        let [w, x, y, z] = t.orientation;
        let q = UnitQuaternion::from_quaternion(Quaternion::new(w, x, y, z));
        let first = *self.first_orientation.get_or_insert(q);
        let tilted = tilt(&(q * first.inverse()), &self.axis);
        if tilted > self.out.max_tilt {
            self.out.max_tilt = tilted;
            self.out.max_tilt_at = Some(First {
                at_s,
                rotation_deg: t.rotation.to_degrees(),
            });
        }
        if let Some(last) = self.last_orientation.replace(q) {
            let phase = plan.map_or("none", |p| p.phase);
            *self.out.off_axis.entry(phase).or_default() += tilt(&(q * last.inverse()), &self.axis);
        }
        let Some(plan) = plan else { return };
        let n = (t.finger_count as usize).min(MAX_FINGERS);
        let touching =
            |finger: u32| (0..n).any(|s| t.finger_ids[s] == finger && t.in_contact[s] == 1);
        self.made |= plan
            .fingers
            .iter()
            .filter(|(_, on)| *on)
            .all(|&(f, _)| touching(f));
        if !self.made {
            return;
        }
        let origin = Vec3::from(t.position) - q * self.centre;
        self.contacts.clear();
        self.fingers.clear();
        for s in 0..n {
            if t.in_contact[s] != 1 {
                continue;
            }
            let b = q.inverse() * (Vec3::from(t.contact_points[s]) - origin);
            self.contacts.push(match &self.surface {
                Some(surface) => {
                    let c = surface.closest(&b);
                    (c.point, c.normal)
                }
                None => (b, q.inverse() * Vec3::from(t.contact_normals[s])),
            });
            self.fingers.push(t.finger_ids[s]);
        }
        let quality = if self.contacts.len() < 2 {
            0.0
        } else {
            problem
                .evaluate_at(&self.contacts)
                .map_or(0.0, |e| if e.force_closure() { e.quality } else { 0.0 })
        };
        self.count(quality, at_s, t.rotation, plan);
    }

    fn count(&mut self, quality: Real, at_s: Real, rotation: Real, plan: &Planned<'_>) {
        let o = &mut self.out;
        o.min = Some(o.min.map_or(quality, |m| m.min(quality)));
        o.samples += 1;
        self.qualities.push(quality);
        let dt = self.last_s.map_or(0.0, |last| (at_s - last).max(0.0));
        self.last_s = Some(at_s);
        // The step's count.
        if self.step.is_none_or(|(s, _)| s != plan.step) {
            self.step = Some((plan.step, false));
            o.steps += 1;
        }
        if quality <= 0.0 {
            o.samples_not_closed += 1;
            if let Some((_, failed @ false)) = &mut self.step {
                *failed = true;
                o.steps_not_closed += 1;
            }
        }
        // Below the margin: the interval it opens or extends.
        if quality < self.alpha {
            o.below_s += dt;
            let open = self.open.get_or_insert_with(|| Below {
                from_s: at_s,
                to_s: at_s,
                min_quality: quality,
                step: plan.step,
                phase: plan.phase,
                rotation_deg: rotation.to_degrees(),
                fingers: self.fingers.clone(),
            });
            open.to_s = at_s;
            if quality < open.min_quality {
                open.min_quality = quality;
                open.fingers.clone_from(&self.fingers);
            }
        } else if let Some(done) = self.open.take()
            && o.below.len() < KEPT
        {
            o.below.push(done);
        }
    }

    /// What it found so far (an interval still open counts as it stands).
    pub fn margin(&self) -> Margin {
        let mut m = self.out.clone();
        if let Some(open) = &self.open
            && m.below.len() < KEPT
        {
            m.below.push(open.clone());
        }
        let mut sorted = self.qualities.clone();
        sorted.sort_by(Real::total_cmp);
        m.p01 = percentile::of_sorted(&sorted, 0.01);
        m
    }
}

/// The surface the planner rolls on (a spatial hand's), or the exact sphere or ellipsoid, or
/// the mesh as its convex polyhedron; `None` for a mesh that is not convex.
fn surface_of(setup: &Setup, spec: &ObjectSpec) -> Option<Convex> {
    if let Some(s) = &setup.spatial {
        return Some(s.surface.clone());
    }
    let centre = setup.object.centre_of_mass;
    match spec {
        ObjectSpec::Sphere { radius, .. } => Some(Convex::Sphere {
            centre,
            radius: *radius,
        }),
        ObjectSpec::Ellipsoid { semi_axes, .. } => Some(Convex::Ellipsoid {
            centre,
            semi_axes: Vec3::from(*semi_axes),
        }),
        _ => polyhedron(&setup.object),
    }
}

fn polyhedron(object: &Object) -> Option<Convex> {
    Convex::polyhedron(object).ok()
}
