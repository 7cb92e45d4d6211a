//! The spatial in-hand rolling planner: a hand of serial fingers ending in fingertip spheres
//! (the Allegro hand's four 4-joint fingers, or any such URDF) turns an object about any axis
//! through its centre of mass, the contacts rolling without slipping inside their 6D ICRs, a
//! free finger taking over at a rendezvous point when one reaches a limit: the planar
//! planner's algorithm ([`crate::planner`]) in space.
//!
//! # Model
//! - The object's centre of mass is held at the hand frame's origin; the object turns by
//!   `theta` about the unit axis `a` (hand frame): body point `b` is at `R(a, theta) (b - c)`.
//! - The object's surface, where the fingertips roll, is a smooth convex surface
//!   ([`surface::Convex`]: the exact sphere or ellipsoid the mesh approximates). A contact is
//!   an exact surface point; its grasp is evaluated at the nearest candidate of the grasp
//!   problem (the mesh's facets: 6D ICRs by the zone rule, rendezvous regions by brute force).
//! - A finger in contact has its fingertip centre at `p_w + r_f n_w`, its joints given by
//!   forward kinematics; what part of the fingertip touches follows from its joints.
//!
//! # Rolling step
//! The object turns by `step` in equal parts of at most [`Spatial::part`]. Over each, every finger's
//! joint rates keep its fingertip's material point at the contact moving with the object's
//! (`A q' = w_o x p_w`, [`rolling`]): rolling without slipping. That is three equations; a
//! finger with more joints spends the rest ([`Steer`], tried in the order of [`STEERS`]) on
//! keeping its contact as still on the object as it can, or else on moving away from its
//! joint limits (null-space descent of [`Finger::limit_cost`]). What slipping the
//! integration leaves is measured: the contact's travel over the object against its travel
//! over the fingertip ([`Touch::slip`], the plan's `max_rolling_residual`). The contact then is where the fingertip touches
//! ([`surface::Convex::closest`] of its centre), with a Newton correction of the fingertip
//! centre along the normal against the integration's drift (second-order midpoint steps). The
//! contact's candidate must stay in its ICR (shrunk by [`Settings::region_erosion`]) at every
//! part; the finger must stay inside its joint limits, touch within its fingertip cap (the
//! angle from the cap axis at most the cap's half-angle less the margin), keep its mobility
//! (the smallest singular value of its fingertip centre's Jacobian at least
//! [`Spatial::min_mobility`]), keep its links' capsules off the object, and be able to press on
//! ([`Settings::squeeze_reserve`]); fingers keep their fingertips and link capsules off each
//! other. A finger that cannot is blocked; a switch may help. Where
//! [`Settings::neighbour_alpha`] is asked for, the grasp at the step's end keeps it with any
//! one contact moved to a candidate within [`Settings::neighbour_rings`] of its own, or the
//! finger whose neighbour loses it is blocked: headroom for a hand that makes its contacts a
//! few candidates off the plan's (on a mesh of small facets their cones turn enough between
//! neighbours to lose a quarter of alpha*).
//!
//! # Finger switching As in the planar planner: the exact rendezvous region by brute force over the
//! candidates (beside the zone rule and eq. 8), the free finger placed by inverse kinematics (its
//! redundancy used to centre its joints; seeded from its [`ReachMap`], which also rules out
//! candidates far from its reach) at each candidate of the region, ahead of the released contact
//! about the axis first, then the most rolling room, the attach and detach grasps verified (and,
//! with [`Settings::neighbour_alpha`], kept a few candidates off as a rolling step's), and one
//! rolling step of lookahead. The attaching finger's approach from its home pose and the released
//! finger's retreat to it are straight joint-space moves through poses with the fingertip lifted
//! off the contact along its normal ([`LIFTS`]; first, if need be, through a pose turned at the
//! finger's base but not yet curled, or the other way round), each checked clear of the object (the
//! fingertip touching only at its end, the link capsules off it) and of the other fingers; they are
//! recorded in the switch ([`Switch::approach`](crate::planner::Switch::approach),
//! [`Switch::retreat`](crate::planner::Switch::retreat)).

mod clearance;
pub mod follow;
mod pinch;
mod reach;
pub mod rolling;
mod scenario;
mod step;
pub mod surface;
mod switch;
pub mod times;

use icrflow_grasp::math::{Real, Vec3};
use icrflow_grasp::quality::GraspProblem;
use nalgebra::{Rotation3, Unit};

use crate::hand::{Finger, Hand};
use crate::planner::Settings;
use surface::Convex;

pub use clearance::{TRACE_TOLERANCE, segment_segment_distance, segment_surface_distance};
pub use reach::ReachMap;
pub use step::mobility;

/// What the spatial planner needs beyond the planar planner's [`Settings`].
#[derive(Debug, Clone, PartialEq)]
pub struct Spatial {
    /// The unit axis (hand frame) the object turns about, positive by the right-hand rule.
    pub axis: Vec3,
    /// The radius of the capsules the fingers' links are taken as (m): kept off the object
    /// and off each other.
    pub link_radius: Real,
    /// Smallest admissible singular value of a finger's fingertip-centre Jacobian in contact
    /// (m per rad): how fast the fingertip can move in its worst direction.
    pub min_mobility: Real,
    /// The largest object rotation (rad, > 0) of one part of a rolling step's integration:
    /// a step is integrated, and its contacts checked in their ICRs, in equal parts no
    /// larger.
    pub part: Real,
}

/// The spatial planning problem.
#[derive(Clone)]
pub struct SpatialScenario<'a> {
    /// Grasp problem whose candidates are the object's facets, its cones' tangent rule about
    /// the axis ([`icrflow_grasp::wrench::WrenchFrame::with_tangent_axis`]).
    pub problem: &'a GraspProblem,
    /// The hand.
    pub hand: &'a Hand,
    /// The surface the fingertips roll on (body frame).
    pub surface: &'a Convex,
    /// The object's centre of mass (body frame).
    pub centre: Vec3,
    /// Initial contacts: (finger, body-frame point on the surface, within its tolerance).
    pub initial: Vec<(u32, Vec3)>,
    /// The object's rotation the plan starts at (rad, about the axis).
    pub start_rotation: Real,
    /// Where the fingers start from: per finger its joints, from which the inverse kinematics
    /// of its initial contact sets off (a plan made again from the estimate starts from the
    /// hand's joints: the nearest pose that touches there); a finger not listed sets off from
    /// its free pose.
    pub start_joints: Vec<(u32, Vec<Real>)>,
    /// Planner settings (the planar planner's; `attach_resolution` and `min_manipulability`
    /// are not used).
    pub settings: Settings,
    /// The spatial settings.
    pub spatial: Spatial,
}

/// A finger in contact.
#[derive(Debug, Clone, PartialEq)]
pub struct Touch {
    /// Finger number.
    pub finger: u32,
    /// Body-frame contact point on the surface.
    pub point: Vec3,
    /// Body-frame outward normal there.
    pub normal: Vec3,
    /// The grasp problem's candidate nearest the point.
    pub candidate: usize,
    /// Joint angles (rad).
    pub q: Vec<Real>,
    /// How much the contact's travel over the object and over the fingertip differed in the
    /// rolling step that brought it here (m; the chords of the step's parts summed on each; 0
    /// when placed): what of the rolling was not without slipping.
    pub slip: Real,
}

/// What a spatial rolling step found.
pub type Roll = crate::planner::Roll<Touch>;

/// How a finger with more joints than rolling needs spends the rest over a rolling step.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Steer {
    /// Its contact kept as still on the object as it can (the least contact velocity over
    /// the surface): a contact near the axis stays there, spinning.
    Still,
    /// Its joints moved off their limits (down [`Finger::limit_cost`]).
    Centre,
}

/// The ways a finger may steer its contact, tried in order in each rolling step.
pub const STEERS: [Steer; 2] = [Steer::Still, Steer::Centre];

/// The largest part of a rolling step's integration ([`Spatial::part`] of a config's plan:
/// 1 deg; a 5 deg step in five parts).
pub const PART: Real = std::f64::consts::PI / 180.0;

/// How far (m) a finger's fingertip is lifted off its contact, along the normal, just before
/// it touches at a switch and just after it leaves.
pub const LIFT: Real = 0.01;

/// The lifted poses a finger's way to and from its contact at a switch may pass through, tried
/// in order (heights above the contact, m): none (straight from home, touching only at the
/// end), 3 mm (a finger at a limit may lift little), one [`LIFT`], or farther off first.
pub const LIFTS: [&[Real]; 5] = [
    &[],
    &[0.003],
    &[LIFT],
    &[3.0 * LIFT, LIFT],
    &[5.0 * LIFT, 2.0 * LIFT, LIFT],
];

impl SpatialScenario<'_> {
    #[expect(
        clippy::expect_used,
        reason = "the scenario's fingers are checked against the hand when it is made"
    )]
    fn finger(&self, id: u32) -> &Finger {
        self.hand.finger(id).expect("fingers are checked up front")
    }

    /// The object as it turns about the axis: where fingertips touch it.
    pub fn turning(&self) -> rolling::Turning<'_> {
        rolling::Turning {
            surface: self.surface,
            centre: self.centre,
            axis: Unit::new_normalize(self.spatial.axis),
            held: Vec3::zeros(),
        }
    }

    fn rotation(&self, theta: Real) -> Rotation3<Real> {
        Rotation3::from_axis_angle(&Unit::new_normalize(self.spatial.axis), theta)
    }

    /// World (hand frame) position of body point `b` with the object at `theta`.
    pub fn to_world(&self, theta: Real, b: &Vec3) -> Vec3 {
        self.rotation(theta) * (b - self.centre)
    }

    /// Body point at world position `w` with the object at `theta`.
    pub fn to_body(&self, theta: Real, w: &Vec3) -> Vec3 {
        self.rotation(theta).inverse() * w + self.centre
    }

    fn describe(&self, p: &Vec3) -> String {
        format!("[{:.1}, {:.1}, {:.1}] mm", 1e3 * p.x, 1e3 * p.y, 1e3 * p.z)
    }

    /// The candidate of contact point `p` ([`Self::nearest`]), checked to be in `region` if given: `Err` with it when it is not. Called at
    /// every part of a rolling step (at most 1 degree), so a contact leaving its ICR is caught
    /// within a facet or two.
    fn candidate_of(&self, p: &Vec3, region: Option<&[u32]>) -> Result<usize, usize> {
        let n = self.nearest(p);
        match region {
            Some(r) if r.binary_search(&(n as u32)).is_err() => Err(n),
            _ => Ok(n),
        }
    }

    /// The candidate of surface point `p`: on a polyhedron the facet it lies on (the facet
    /// whose centre is nearest is often another: a contact near a thin facet's edge lies
    /// closer to its neighbour's centre), else the candidate nearest it.
    fn nearest(&self, p: &Vec3) -> usize {
        candidate_at(self.surface, self.problem, p)
    }
}

/// The candidate of `problem` (whose candidates are the facets of the object `surface` is
/// made from) that surface point `p` belongs to: on a polyhedron the facet it lies on, else
/// the candidate nearest it (0 for a point that is not finite). The planner's rule, and the
/// estimator's for a spatial hand.
pub fn candidate_at(surface: &Convex, problem: &GraspProblem, p: &Vec3) -> usize {
    surface
        .facet_at(p)
        .filter(|&f| f < problem.candidates().len())
        .unwrap_or_else(|| problem.nearest_candidate(p).map_or(0, |(i, _)| i))
}
