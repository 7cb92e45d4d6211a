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
//! # Finger switching
//! As in the planar planner: the exact rendezvous region by brute force over the candidates
//! (beside the zone rule and eq. 8), the free finger placed by inverse kinematics (its
//! redundancy used to centre its joints; seeded from its [`ReachMap`], which also rules out
//! candidates far from its reach) at each candidate of the region, ahead of the released
//! contact about the axis first, then the most rolling room, the attach and detach grasps
//! verified (and, with [`Settings::neighbour_alpha`], kept a few candidates off as a rolling
//! step's), and one rolling step of lookahead. The attaching finger's approach from its home
//! pose and the released finger's retreat to it are straight joint-space moves through poses
//! with the fingertip lifted off the contact along its normal ([`LIFTS`]; first, if need be,
//! through a pose turned at the finger's base but not yet curled, or the other way round),
//! each checked clear of the object (the fingertip touching only at its end, the link capsules
//! off it) and of the other fingers; they are recorded in the switch ([`Switch::approach`],
//! [`Switch::retreat`]).

pub mod follow;
pub mod rolling;
pub mod surface;

use std::f64::consts::PI;

use icrflow_grasp::icr::IcrError;
use icrflow_grasp::math::{Real, Vec3};
use icrflow_grasp::quality::{GraspError, GraspProblem};
use nalgebra::{DMatrix, DVector, Rotation3, Unit};

use crate::hand::{Finger, Hand};
use crate::planner::{
    FingerState, NoSwitch, Phase, Plan, PlanError, QUALITY_SLACK, SQUEEZE_PROBE, Settings, Step,
    Stepper, Switch, Switched, drive,
};
use surface::Convex;

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

/// A finger's links and fingertip as capsules: (from, to, radius); the fingertip a capsule
/// of zero length.
type Capsules = Vec<(Vec3, Vec3, Real)>;

/// A switch that passed its checks ([`SpatialScenario::try_switch`]).
struct Chosen {
    t: Touch,
    attach: Vec<Touch>,
    detach: Vec<Touch>,
    q_attach: Real,
    q_detach: Real,
    approach: Vec<Vec<Real>>,
    retreat: Vec<Vec<Real>>,
}

/// What trying one rendezvous placement found.
enum Attempt {
    /// It passed.
    Chosen(Box<Chosen>),
    /// It did not (said in the rejections).
    Rejected,
    /// Its grasps fell below the margin: a defect, which stops the plan.
    Defect(String),
}

/// A spatial scenario with its fingers' reach maps (the seeds of a switch's placements): what
/// the planning loop ([`drive`]) steps.
struct Mapped<'s, 'a> {
    scenario: &'s SpatialScenario<'a>,
    maps: Vec<ReachMap>,
}

impl Stepper for Mapped<'_, '_> {
    type Contact = Touch;

    fn finger_of(t: &Touch) -> u32 {
        t.finger
    }

    fn fingers(&self) -> usize {
        self.scenario.hand.fingers.len()
    }

    fn roll(&self, touches: &[Touch], theta: Real, step: Real) -> Result<Roll, PlanError> {
        self.scenario.roll(touches, theta, step)
    }

    fn switch(
        &self,
        touches: &[Touch],
        k: usize,
        theta: Real,
        why: &str,
        progress: &mut dyn FnMut(Real),
    ) -> Result<Result<Switched<Touch>, NoSwitch>, PlanError> {
        self.scenario
            .switch(touches, k, theta, why, &self.maps, progress)
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

/// How far (m) one integration part may leave a fingertip centre off the surface before the
/// Newton correction puts it back (the correction turns the fingertip a little, which is
/// slip); a part that leaves it farther is halved.
const DRIFT: Real = 1e-6;

/// The largest spacing (m) of the fingertip's travel between two poses at which an approach or
/// a retreat is checked.
const ROUTE_SPACING: Real = 0.1e-3;

/// Newton corrections of the fingertip centre onto the surface per integration part.
const CORRECTIONS: usize = 3;

/// How many of a switch's reachable options (best limit margin first) get their rolling room
/// simulated.
const ROOM_OPTIONS: usize = 12;

/// Most rolling steps simulated for a rendezvous option's rolling room.
const ROOM_LIMIT: usize = 36;

impl SpatialScenario<'_> {
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

    /// The candidate of contact point `p`: the nearest, all compared (a walk over the
    /// candidates' adjacency to ever nearer neighbours, the planar planner's `walk_candidates`, stops at a local
    /// minimum on a mesh of thin triangles: a contact on the STL ellipsoid was given a facet
    /// 2 away), checked to be in `region` if given: `Err` with it when it is not. Called at
    /// every part of a rolling step (at most 1 degree), so a contact leaving its ICR is caught
    /// within a facet or two.
    fn candidate_of(&self, p: &Vec3, region: Option<&[u32]>) -> Result<usize, usize> {
        let n = self.nearest(p);
        match region {
            Some(r) if r.binary_search(&(n as u32)).is_err() => Err(n),
            _ => Ok(n),
        }
    }

    /// The candidate nearest `p`.
    fn nearest(&self, p: &Vec3) -> usize {
        self.problem.nearest_candidate(p).map_or(0, |(i, _)| i)
    }

    /// Where finger `f` at `q` touches the surface with the object at `theta`: the body
    /// point, normal and signed distance of the fingertip centre from the surface.
    fn touch_of(&self, f: &Finger, q: &[Real], theta: Real) -> surface::Closest {
        let b = self.to_body(theta, &f.tip_centre(q));
        self.surface.closest(&b)
    }

    /// Joint rates (per unit of object rotation) that keep finger `f`'s fingertip rolling
    /// without slipping on the object turning about the axis, the rest of its joints' freedom
    /// spent as `steer` says.
    fn rates(&self, f: &Finger, q: &[Real], theta: Real, steer: Steer) -> Option<DVector<Real>> {
        let c = self.touch_of(f, q, theta);
        let r = self.rotation(theta);
        let (p_w, n_w) = (r * (c.point - self.centre), r * c.normal);
        let a = f.contact_jacobian(q, &n_w);
        let axis = self.spatial.axis;
        let v = axis.cross(&p_w);
        let pinv = a.clone().pseudo_inverse(1e-9).ok()?;
        let wanted = DVector::from_column_slice(v.as_slice());
        let track = &pinv * &wanted;
        // A contact Jacobian short of rank cannot keep the fingertip from slipping.
        if (&a * &track - &wanted).norm() > 1e-9 * (1.0 + wanted.norm()) {
            return None;
        }
        let n = f.dof();
        let projector = DMatrix::<Real>::identity(n, n) - &pinv * &a;
        match steer {
            Steer::Centre => {
                let free = -(&projector * f.limit_cost_gradient(q));
                let norm = free.norm();
                // As much self-motion as tracking motion at most.
                let free = if norm > 1e-12 {
                    free * (track.norm().min(norm * 0.05) / norm)
                } else {
                    free
                };
                Some(track + free)
            }
            Steer::Still => {
                // The contact's velocity over the object is G (J_v q' - w_o x b) (the
                // fingertip centre's velocity relative to the object, through (I + r_f W)^-1
                // on the tangent plane): its least-squares zero over the null space of A.
                let w = r.matrix() * self.surface.shape_operator(&c.point) * r.matrix().transpose();
                let (t1, t2) = icrflow_grasp::wrench::tangent_basis_about(&axis, &n_w);
                let tb = nalgebra::Matrix3x2::from_columns(&[t1, t2]);
                let k = tb.transpose() * (nalgebra::Matrix3::identity() + w * f.tip_radius) * tb;
                let g = k.try_inverse()? * tb.transpose();
                let g = DMatrix::from_row_slice(2, 3, g.transpose().as_slice());
                let jv = f.jacobian6(q).rows(0, 3).into_owned();
                let drift = axis.cross(&f.tip_centre(q));
                let g0 = &g * (&jv * &track - DVector::from_column_slice(drift.as_slice()));
                let m = &g * &jv * &projector;
                let z = m.pseudo_inverse(1e-9).ok()? * (-g0);
                Some(track + &projector * z)
            }
        }
    }

    /// Moves finger `f`'s fingertip centre onto the surface (distance `r_f`) along the normal.
    fn settle(&self, f: &Finger, q: &mut [Real], theta: Real) {
        for _ in 0..CORRECTIONS {
            let c = self.touch_of(f, q, theta);
            let gap = c.distance - f.tip_radius;
            if gap.abs() < 1e-12 {
                break;
            }
            let n_w = self.rotation(theta) * c.normal;
            let jac = f.jacobian6(q).rows(0, 3).into_owned();
            let Ok(pinv) = jac.pseudo_inverse(1e-9) else {
                break;
            };
            let dq = pinv * DVector::from_column_slice((-n_w * gap).as_slice());
            for (a, d) in q.iter_mut().zip(dq.iter()) {
                *a += d;
            }
        }
    }

    /// What stops finger `f` at `q` touching at `touch` with the object at `theta`, if
    /// anything: its joint limits, its fingertip cap, its mobility, its links' capsules in
    /// the object, and with `squeeze` its squeeze reserve.
    fn pose_check(
        &self,
        f: &Finger,
        q: &[Real],
        theta: Real,
        touch: &surface::Closest,
        squeeze: bool,
    ) -> Option<String> {
        let s = &self.settings;
        if let Some(e) = f.limit_violation(q, 1e-9) {
            return Some(e.to_string());
        }
        let (_, axis) = f.fk_tip(q);
        let n_w = self.rotation(theta) * touch.normal;
        let cap = axis.dot(&-n_w).clamp(-1.0, 1.0).acos();
        if cap > f.cap_half_angle - s.cap_margin {
            return Some(format!(
                "the contact would leave the fingertip cap ({:.1} deg from its axis)",
                cap.to_degrees()
            ));
        }
        let m = mobility(f, q);
        if m < self.spatial.min_mobility {
            return Some(format!(
                "mobility lost (the fingertip moves only {:.2} mm/rad in its worst direction)",
                m * 1e3
            ));
        }
        let (clear, link) = self.link_clearance(f, q, theta);
        if clear < self.spatial.link_radius {
            return Some(format!(
                "its link {link} would come {:.2} mm from the object (its capsule's radius is {:.1} mm)",
                clear * 1e3,
                self.spatial.link_radius * 1e3
            ));
        }
        if squeeze && s.squeeze_reserve > 0.0 {
            let reach = f.reach_along(q, &-n_w, s.squeeze_reserve);
            if reach < s.squeeze_reserve * (1.0 - 1e-6) {
                return Some(format!(
                    "the finger could press only {:.2} mm further into the object (needs {:.2} mm)",
                    reach * 1e3,
                    s.squeeze_reserve * 1e3
                ));
            }
        }
        None
    }

    /// How close finger `f`'s links (as lines) come to the object's surface at `q` with the
    /// object at `theta` (m; negative inside), and which link.
    pub fn link_clearance(&self, f: &Finger, q: &[Real], theta: Real) -> (Real, usize) {
        let mut closest = (Real::INFINITY, 0);
        f.link_segments(q, |link, a, b| {
            let (a, b) = (self.to_body(theta, &a), self.to_body(theta, &b));
            let d = segment_surface_distance(self.surface, &a, &b);
            if d < closest.0 {
                closest = (d, link);
            }
        });
        closest
    }

    /// Which two fingers of `touches` (the others at their home poses) come closer than their
    /// fingertips' radii or their link capsules allow, if any, with the object at `theta`;
    /// and any free finger at home in the object.
    fn clash(&self, touches: &[Touch], theta: Real) -> Option<(String, [u32; 2])> {
        let poses: Vec<(u32, &Finger, Vec<Real>)> = self
            .hand
            .fingers
            .iter()
            .map(|f| {
                let q = touches
                    .iter()
                    .find(|t| t.finger == f.id)
                    .map_or_else(|| f.home.clone(), |t| t.q.clone());
                (f.id, f, q)
            })
            .collect();
        let parts: Vec<(u32, Capsules)> = poses
            .iter()
            .map(|(id, f, q)| {
                let mut segs = Vec::new();
                f.link_segments(q, |_, a, b| segs.push((a, b, self.spatial.link_radius)));
                let tip = f.tip_centre(q);
                segs.push((tip, tip, f.tip_radius));
                (*id, segs)
            })
            .collect();
        for (i, (a, sa)) in parts.iter().enumerate() {
            for (b, sb) in &parts[i + 1..] {
                for x in sa {
                    for y in sb {
                        let d = segment_segment_distance(&x.0, &x.1, &y.0, &y.1);
                        if d < x.2 + y.2 {
                            return Some((
                                format!(
                                    "fingers {a} and {b} would touch ({:.2} mm apart where {:.2} mm is needed)",
                                    d * 1e3,
                                    (x.2 + y.2) * 1e3
                                ),
                                [*a, *b],
                            ));
                        }
                    }
                }
            }
        }
        for (id, f, q) in &poses {
            if touches.iter().any(|t| t.finger == *id) {
                continue;
            }
            let tip = self.to_body(theta, &f.tip_centre(q));
            let (clear, _) = self.link_clearance(f, q, theta);
            let tip_clear = self.surface.closest(&tip).distance - f.tip_radius;
            if clear < self.spatial.link_radius || tip_clear < 0.0 {
                return Some((
                    format!("free finger {id} at its home pose would be in the object"),
                    [*id, *id],
                ));
            }
        }
        None
    }

    /// Finger `f` placed by inverse kinematics touching the surface at the body point nearest
    /// `p`, with the object at `theta`, from `seed`: the pose with its joints centred, or, if
    /// `nearest`, the pose nearest `seed` (a finger already in contact there: turning its
    /// fingertip about its centre toward the middle of the joint ranges would spin it on the
    /// object).
    fn place(
        &self,
        f: &Finger,
        p: &Vec3,
        theta: Real,
        seed: &[Real],
        squeeze: bool,
        nearest: bool,
    ) -> Result<Touch, String> {
        let c = self.surface.closest(p);
        let target = self.to_world(theta, &(c.point + c.normal * f.tip_radius));
        let q = if nearest {
            f.ik_position(&target, seed)
        } else {
            f.ik_position_centred(&target, seed)
        }
        .map_err(|e| e.to_string())?;
        let touch = self.touch_of(f, &q, theta);
        if let Some(why) = self.pose_check(f, &q, theta, &touch, squeeze) {
            return Err(why);
        }
        Ok(Touch {
            finger: f.id,
            point: touch.point,
            normal: touch.normal,
            candidate: self.nearest(&touch.point),
            q,
            slip: 0.0,
        })
    }

    /// Finger `t.finger` rolled from `t` as the object turns from `theta` by `step`, its
    /// contact's candidate kept in `region` (sorted) if given.
    fn roll_finger(
        &self,
        t: &Touch,
        theta: Real,
        step: Real,
        region: Option<&[u32]>,
        squeeze: bool,
        steer: Steer,
    ) -> Result<Touch, String> {
        let f = self.finger(t.finger);
        let parts = ((step / self.spatial.part).ceil() as usize).max(1);
        let mut q = t.q.clone();
        let mut candidate = t.candidate;
        let mut at = theta;
        // The contact's travel over the object (body frame) and over the fingertip (its
        // frame), summed chords of the parts: equal when it rolls without slipping.
        let on_tip = |q: &[Real], at: Real, p: &Vec3| -> Vec3 {
            let pose = f.fk(q);
            pose.tip_rotation.inverse() * (self.to_world(at, p) - pose.tip_centre)
        };
        let (mut p, mut u) = (t.point, on_tip(&t.q, theta, &t.point));
        let (mut over_object, mut over_tip) = (0.0, 0.0);
        let end = theta + step;
        let mut h = step / parts as Real;
        while at < end - 1e-15 {
            h = h.min(end - at);
            // Midpoint rule, the part halved while it leaves the fingertip centre more than
            // DRIFT off the surface (fast joint rates near a singular pose).
            let next = loop {
                let k1 = self
                    .rates(f, &q, at, steer)
                    .ok_or("its contact Jacobian is singular")?;
                let mid: Vec<Real> = q
                    .iter()
                    .zip(k1.iter())
                    .map(|(a, d)| a + 0.5 * h * d)
                    .collect();
                let k2 = self
                    .rates(f, &mid, at + 0.5 * h, steer)
                    .ok_or("its contact Jacobian is singular")?;
                let next: Vec<Real> = q.iter().zip(k2.iter()).map(|(a, d)| a + h * d).collect();
                let gap = self.touch_of(f, &next, at + h).distance - f.tip_radius;
                if gap.abs() <= DRIFT {
                    break next;
                }
                if h < step / parts as Real / 1024.0 {
                    return Err(format!(
                        "its rolling cannot be followed: the finger is near a singular pose ({:.3} mm off the surface after a part of {:.4} deg)",
                        gap * 1e3,
                        h.to_degrees()
                    ));
                }
                h *= 0.5;
            };
            q = next;
            at += h;
            self.settle(f, &mut q, at);
            if let Some(e) = f.limit_violation(&q, 1e-9) {
                return Err(e.to_string());
            }
            let touch = self.touch_of(f, &q, at);
            let u_next = on_tip(&q, at, &touch.point);
            over_object += (touch.point - p).norm();
            over_tip += (u_next - u).norm();
            (p, u) = (touch.point, u_next);
            candidate = self.candidate_of(&touch.point, region).map_err(|out| {
                format!(
                    "its contact would roll out of its ICR (from {} past {})",
                    self.describe(&t.point),
                    self.describe(&self.problem.candidates().points[out])
                )
            })?;
        }
        let touch = self.touch_of(f, &q, at);
        if let Some(why) = self.pose_check(f, &q, at, &touch, squeeze) {
            return Err(why);
        }
        Ok(Touch {
            finger: t.finger,
            point: touch.point,
            normal: touch.normal,
            candidate,
            q,
            slip: (over_object - over_tip).abs(),
        })
    }

    /// The way of finger `t.finger` between its home pose and its contact `t` (`what`: its
    /// approach or its retreat), the fingers of `others` holding still, the object at `theta`:
    /// straight joint-space moves from home (through a pose turned at the finger's base but
    /// not yet curled, if the straight way is not clear) through poses with the fingertip
    /// lifted off the contact along its normal ([`LIFTS`], the farthest first) to the
    /// contact, each checked
    /// at [`crate::route::SAMPLES`] poses: the fingertip off the object (touching only at the
    /// contact), the link capsules off it, no two fingers touching. The first of [`LIFTS`]
    /// whose way is clear: its poses; or why the way straight from home was not.
    fn route(
        &self,
        t: &Touch,
        others: &[Touch],
        theta: Real,
        what: &str,
    ) -> Result<Vec<Vec<Real>>, String> {
        let f = self.finger(t.finger);
        let n_w = self.rotation(theta) * t.normal;
        let contact = self.to_world(theta, &t.point);
        let mut why: Option<String> = None;
        'ways: for heights in LIFTS {
            let mut vias = Vec::with_capacity(heights.len());
            for h in heights {
                let lifted = contact + n_w * (f.tip_radius + h);
                match f.ik_position_centred(&lifted, &t.q) {
                    Ok(q) => vias.push(q),
                    Err(e) => {
                        why.get_or_insert(format!(
                            "on its {what} its fingertip cannot lift {:.0} mm off the contact: {e}",
                            h * 1e3
                        ));
                        continue 'ways;
                    }
                }
            }
            // From home straight to the first lifted pose, or first to that pose with its
            // distal joints (from the second, or the third, on) still at home (the finger
            // turns at its base before it curls: a thumb swinging home past a fingertip), or
            // with its base joints still at home (it curls first).
            let first = vias.first().unwrap_or(&t.q);
            let split = |from: usize, base_first: bool| -> Vec<Real> {
                first
                    .iter()
                    .zip(&f.home)
                    .enumerate()
                    .map(|(j, (q, h))| if (j < from) == base_first { *q } else { *h })
                    .collect()
            };
            let uncurled: Vec<Vec<Real>> = (1..f.dof().saturating_sub(1))
                .flat_map(|from| [split(from, true), split(from, false)])
                .collect();
            'turns: for turn in std::iter::once(None).chain(uncurled.iter().map(Some)) {
                let mut way: Vec<&[Real]> = vec![&f.home];
                way.extend(turn.map(Vec::as_slice));
                way.extend(vias.iter().map(Vec::as_slice));
                way.push(&t.q);
                let legs = way.len() - 1;
                for (leg, pair) in way.windows(2).enumerate() {
                    // The last leg ends touching: it may not press in.
                    let floor = if leg + 1 == legs {
                        f.tip_radius - 1e-9
                    } else {
                        f.tip_radius
                    };
                    if let Err(e) = self.clear_move(f, pair[0], pair[1], floor, t, others, theta) {
                        why.get_or_insert(format!("on its {what} {e}"));
                        continue 'turns;
                    }
                }
                let mut poses: Vec<Vec<Real>> = turn.into_iter().cloned().collect();
                poses.extend(vias);
                return Ok(poses);
            }
        }
        Err(why.unwrap_or_default())
    }

    /// Whether finger `f` moving straight in joint space from `from` to `to` (checked at
    /// [`crate::route::SAMPLES`] poses, its fingertip also every [`ROUTE_SPACING`]) keeps its fingertip centre at least `floor` from the
    /// object, its link capsules off it, and off the fingers of `others` (`t`: the finger's
    /// contact, for its identity).
    #[allow(clippy::too_many_arguments)]
    fn clear_move(
        &self,
        f: &Finger,
        from: &[Real],
        to: &[Real],
        floor: Real,
        t: &Touch,
        others: &[Touch],
        theta: Real,
    ) -> Result<(), String> {
        let at =
            |s: Real| -> Vec<Real> { from.iter().zip(to).map(|(a, b)| a + s * (b - a)).collect() };
        // The fingertip at least every ROUTE_SPACING of its straight-line travel: a fingertip
        // grazing the object between two checked poses dips in by about the square of their
        // spacing times the path's curvature. The distance from the object changes by at most
        // the distance moved, so a pose whose fingertip is nearer the last one measured than
        // that one's distance less the floor is clear without measuring it.
        let travel = (f.tip_centre(to) - f.tip_centre(from)).norm();
        let fine = crate::route::SAMPLES.max((travel / ROUTE_SPACING).ceil() as usize + 1);
        let mut measured: Option<(Vec3, Real)> = None;
        for i in 0..fine {
            let tip = self.to_body(theta, &f.tip_centre(&at(i as Real / (fine - 1) as Real)));
            if measured.is_some_and(|(p, d)| (tip - p).norm() < d - floor) {
                continue;
            }
            let d = self.surface.closest(&tip).distance;
            if d < floor {
                return Err("its fingertip would hit the object".into());
            }
            measured = Some((tip, d));
        }
        // The links and the other fingers at the route's samples; a link whose ends both
        // moved less than its last measured clearance beyond the capsule's radius is clear
        // (every point of it moved less).
        let samples = crate::route::SAMPLES;
        let mut links: Vec<Option<(Vec3, Vec3, Real)>> = Vec::new();
        for i in 0..samples {
            let q = at(i as Real / (samples - 1) as Real);
            let mut hit: Option<(Real, usize)> = None;
            f.link_segments(&q, |link, a, b| {
                if hit.is_some() {
                    return;
                }
                let (a, b) = (self.to_body(theta, &a), self.to_body(theta, &b));
                if links.len() <= link {
                    links.resize(link + 1, None);
                }
                if let Some((a0, b0, d0)) = links[link] {
                    let moved = (a - a0).norm().max((b - b0).norm());
                    if moved < d0 - self.spatial.link_radius {
                        return;
                    }
                }
                let d = segment_surface_distance(self.surface, &a, &b);
                if d < self.spatial.link_radius {
                    hit = Some((d, link));
                }
                links[link] = Some((a, b, d));
            });
            if let Some((clear, link)) = hit {
                return Err(format!(
                    "its link {link} would come {:.2} mm from the object",
                    clear * 1e3
                ));
            }
            let mut trial = others.to_vec();
            trial.push(Touch { q, ..t.clone() });
            if let Some((why, _)) = self.clash(&trial, theta) {
                return Err(why);
            }
        }
        Ok(())
    }

    /// Steps finger `t.finger` could roll alone from `t` (no ICR), up to `limit`.
    fn room(&self, t: &Touch, mut theta: Real, limit: usize) -> usize {
        let mut t = t.clone();
        for k in 0..limit {
            match STEERS.iter().find_map(|&w| {
                self.roll_finger(&t, theta, self.settings.step, None, false, w)
                    .ok()
            }) {
                Some(next) => t = next,
                None => return k,
            }
            theta += self.settings.step;
        }
        limit
    }

    fn quality(&self, touches: &[Touch]) -> Result<Real, GraspError> {
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
    fn one_off(&self, touches: &[Touch]) -> Result<Option<(usize, String)>, GraspError> {
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
        let idx: Vec<usize> = touches.iter().map(|t| t.candidate).collect();
        let e = self.problem.evaluate(&idx)?;
        if !e.force_closure() {
            return Err(PlanError::NotForceClosure { epsilon: e.epsilon });
        }
        if e.quality < alpha * (1.0 - QUALITY_SLACK) {
            return Err(PlanError::BelowMargin {
                quality: e.quality,
                alpha,
            });
        }
        if let Some((why, _)) = self.clash(&touches, theta) {
            return Err(PlanError::Settings(format!("the initial grasp: {why}")));
        }
        Ok((touches, e.quality))
    }

    /// One rolling step of every contact, the object turning from `theta` by `step`.
    pub fn roll(&self, touches: &[Touch], theta: Real, step: Real) -> Result<Roll, PlanError> {
        let idx: Vec<usize> = touches.iter().map(|t| t.candidate).collect();
        let eval = self.problem.evaluate(&idx)?;
        let regions = match self.problem.icrs(&idx, &eval, self.settings.alpha) {
            Ok(r) => r,
            Err(e @ (IcrError::NotForceClosure | IcrError::MarginAboveQuality { .. })) => {
                return Ok(Roll::Stuck(format!("the grasp lost its margin: {e}")));
            }
            Err(e) => return Ok(Roll::Stuck(e.to_string())),
        };
        let mut next = Vec::with_capacity(touches.len());
        for (i, (t, region)) in touches.iter().zip(&regions).enumerate() {
            let members = if self.settings.region_erosion == 0 {
                region.members.clone()
            } else {
                self.problem
                    .candidates()
                    .adjacency
                    .erode(&region.members, self.settings.region_erosion)
            };
            let mut first = None;
            let mut moved = None;
            for steer in STEERS {
                match self.roll_finger(t, theta, step, Some(&members), true, steer) {
                    Ok(n) => {
                        moved = Some(n);
                        break;
                    }
                    Err(why) => {
                        first.get_or_insert(why);
                    }
                }
            }
            match (moved, first) {
                (Some(n), _) => next.push(n),
                (None, why) => return Ok(Roll::Blocked(i, why.unwrap_or_default())),
            }
        }
        if let Some((why, fingers)) = self.clash(&next, theta + step) {
            // The first finger of the two that is in contact stops (a switch may free it).
            return Ok(
                match next.iter().position(|t| fingers.contains(&t.finger)) {
                    Some(i) => Roll::Blocked(i, why),
                    None => Roll::Stuck(format!("rolling on: {why}")),
                },
            );
        }
        let quality = self.quality(&next)?;
        if quality < self.settings.alpha * (1.0 - QUALITY_SLACK) {
            return Ok(Roll::Stuck(format!(
                "the next grasp would have quality {quality:.6} < alpha = {} (a defect: the ICRs guarantee the margin)",
                self.settings.alpha
            )));
        }
        if let Some((i, why)) = self.one_off(&next)? {
            return Ok(Roll::Blocked(i, why));
        }
        Ok(Roll::Moved(next, quality))
    }

    /// The signed angle (rad, in [0, 2 pi)) about the axis from body point `a` to `b`, or
    /// `None` where either is within a millimetre of the axis.
    fn ahead(&self, a: &Vec3, b: &Vec3) -> Option<Real> {
        let axis = self.spatial.axis;
        let flat = |p: &Vec3| {
            let v = p - self.centre;
            v - axis * axis.dot(&v)
        };
        let (u, v) = (flat(a), flat(b));
        if u.norm() < 1e-3 || v.norm() < 1e-3 {
            return None;
        }
        let angle = axis.dot(&u.cross(&v)).atan2(u.dot(&v));
        Some(angle.rem_euclid(2.0 * PI))
    }

    /// Switches finger `touches[k]` for the best free finger; `progress(theta)` is called as
    /// the search goes on (per candidate placed, per placement tried: a search that takes a
    /// second still reports).
    fn switch(
        &self,
        touches: &[Touch],
        k: usize,
        theta: Real,
        why: &str,
        maps: &[ReachMap],
        progress: &mut dyn FnMut(Real),
    ) -> Result<Result<Switched<Touch>, NoSwitch>, PlanError> {
        let released = touches[k].finger;
        let free: Vec<&Finger> = self
            .hand
            .fingers
            .iter()
            .filter(|f| touches.iter().all(|t| t.finger != f.id))
            .collect();
        if free.is_empty() {
            return Ok(Err(NoSwitch::none(format!(
                "finger {released} cannot roll on ({why}) and no free finger can take over"
            ))));
        }
        let idx: Vec<usize> = touches.iter().map(|t| t.candidate).collect();
        let regions = crate::rendezvous::regions(self.problem, &idx, k, self.settings.alpha)?;
        let chosen_from: Vec<usize> = if self.settings.region_erosion == 0 {
            regions.exact.clone()
        } else {
            let exact: Vec<u32> = regions.exact.iter().map(|&c| c as u32).collect();
            self.problem
                .candidates()
                .adjacency
                .erode(&exact, self.settings.region_erosion)
                .into_iter()
                .map(|c| c as usize)
                .collect()
        };
        let cands = self.problem.candidates();
        let here = touches[k].point;
        let is_ahead = |a: Option<Real>| a.is_some_and(|a| a > 0.0 && a < PI);
        // The candidates ahead first; those behind only when none ahead serves.
        let (ahead, behind): (Vec<usize>, Vec<usize>) = chosen_from
            .iter()
            .partition(|&&c| is_ahead(self.ahead(&here, &cands.points[c])));
        // Every reachable placement of a tier: (limit margin, touch).
        let placements = |tier: &[usize], progress: &mut dyn FnMut(Real)| {
            let mut options: Vec<(Real, Touch)> = Vec::new();
            for f in &free {
                let map = maps.iter().find(|m| m.finger == f.id);
                for &c in tier {
                    progress(theta);
                    // Far from every sampled pose of the finger: out of its reach (or
                    // nearly), not worth an inverse kinematics; else the nearest sample seeds
                    // it.
                    let p = self.surface.closest(&cands.points[c]);
                    let tip = self.to_world(theta, &(p.point + p.normal * f.tip_radius));
                    let seed = match map.map(|m| m.nearest(&tip)) {
                        Some(Some((d, _))) if d > REACH_MAP_GAP => continue,
                        Some(Some((_, q))) => q,
                        _ => &f.home,
                    };
                    let Ok(t) = self.place(f, &cands.points[c], theta, seed, false, false) else {
                        continue;
                    };
                    if t.candidate != c {
                        continue;
                    }
                    let mut trial = touches.to_vec();
                    trial.push(t.clone());
                    if self.clash(&trial, theta).is_some() {
                        continue;
                    }
                    options.push((f.limit_margin(&t.q), t));
                }
            }
            // The best centred joints first; of the first ROOM_OPTIONS, the most rolling
            // room first; then the rest (their room measured if one is chosen).
            options.sort_by(|x, y| {
                y.0.total_cmp(&x.0)
                    .then(x.1.finger.cmp(&y.1.finger))
                    .then(x.1.candidate.cmp(&y.1.candidate))
            });
            let limit = ((self.settings.goal - theta) / self.settings.step)
                .ceil()
                .clamp(1.0, ROOM_LIMIT as Real) as usize;
            let rest = options.split_off(options.len().min(ROOM_OPTIONS));
            let mut ranked: Vec<(Option<usize>, Touch)> = options
                .into_iter()
                .map(|(_, t)| (Some(self.room(&t, theta, limit)), t))
                .collect();
            ranked.sort_by(|x, y| {
                y.0.cmp(&x.0)
                    .then(x.1.finger.cmp(&y.1.finger))
                    .then(x.1.candidate.cmp(&y.1.candidate))
            });
            ranked.extend(rest.into_iter().map(|(_, t)| (None, t)));
            (ranked, limit)
        };
        let floor = self.settings.alpha * (1.0 - QUALITY_SLACK);
        let mut rejected = Vec::new();
        let mut chosen = None;
        let mut tried = 0;
        'tiers: for tier in [&ahead, &behind] {
            let (ranked, limit) = placements(tier, progress);
            tried += ranked.len();
            for (room, t) in ranked {
                progress(theta);
                let room = room.unwrap_or_else(|| self.room(&t, theta, limit));
                let ahead = self.ahead(&here, &t.point);
                match self.try_switch(touches, k, theta, t, floor, &mut rejected)? {
                    Attempt::Chosen(c) => {
                        chosen = Some((room, ahead, *c));
                        break 'tiers;
                    }
                    Attempt::Rejected => {}
                    Attempt::Defect(why) => return Ok(Err(NoSwitch::defect(why))),
                }
            }
        }
        let Some((
            room,
            ahead,
            Chosen {
                t,
                attach,
                detach,
                q_attach,
                q_detach,
                approach,
                retreat,
            },
        )) = chosen
        else {
            return Ok(Err(NoSwitch::none(format!(
                "finger {released} cannot roll on ({why}); of the {} candidates that keep the margin with the remaining contacts, none is reachable by a free finger ({:?}) with a rolling step after it ({tried} placements tried){}",
                chosen_from.len(),
                free.iter().map(|f| f.id).collect::<Vec<_>>(),
                rejections(&rejected)
            ))));
        };
        let info = Switch {
            released,
            attached: t.finger,
            reason: why.to_string(),
            icr_region: regions.icr.clone(),
            lp_region: regions.lp.clone(),
            brute_force: regions.exact.clone(),
            chosen_from: chosen_from.len(),
            rendezvous: t.candidate,
            rendezvous_angle: None,
            room_steps: room,
            ahead: ahead.unwrap_or(0.0),
            approach: Some(approach),
            retreat: Some(retreat),
        };
        Ok(Ok((attach, detach, info, q_attach, q_detach)))
    }

    /// Finger `t.finger` attaching at `t` in place of `touches[k]` with the object at
    /// `theta`, checked: its squeeze reserve, its approach and the released finger's retreat,
    /// the attach and detach grasps' quality (against `floor`: below is a defect, the region
    /// being exact), and one rolling step after it. Why not goes to `rejected`.
    fn try_switch(
        &self,
        touches: &[Touch],
        k: usize,
        theta: Real,
        t: Touch,
        floor: Real,
        rejected: &mut Vec<String>,
    ) -> Result<Attempt, PlanError> {
        let mut reject = |why: String| {
            rejected.push(format!(
                "{} by finger {}: {why}",
                self.describe(&t.point),
                t.finger
            ));
            Ok(Attempt::Rejected)
        };
        let f = self.finger(t.finger);
        let touch = self.touch_of(f, &t.q, theta);
        if let Some(why) = self.pose_check(f, &t.q, theta, &touch, true) {
            return reject(why);
        }
        // The approach from home and the released finger's retreat to it.
        let mut detach_set = touches.to_vec();
        detach_set.push(t.clone());
        let gone = detach_set.remove(k);
        let routes = self
            .route(&t, touches, theta, "approach")
            .and_then(|approach| {
                self.route(&gone, &detach_set, theta, "retreat")
                    .map(|retreat| (approach, retreat))
            });
        let (approach, retreat) = match routes {
            Ok(r) => r,
            Err(why) => return reject(why),
        };
        let mut attach = touches.to_vec();
        attach.push(t.clone());
        let q_attach = self.quality(&attach)?;
        let mut detach = attach.clone();
        detach.remove(k);
        let q_detach = self.quality(&detach)?;
        if q_attach < floor || q_detach < floor {
            return Ok(Attempt::Defect(format!(
                "switch of finger {} to finger {} at {} fails verification: quality {q_attach:.6} attached, {q_detach:.6} detached, alpha = {} (a defect: the region is exact)",
                touches[k].finger,
                t.finger,
                self.describe(&t.point),
                self.settings.alpha
            )));
        }
        for (grasp, name) in [(&attach, "attached"), (&detach, "detached")] {
            if let Some((_, why)) = self.one_off(grasp)? {
                return reject(format!("{name}: {why}"));
            }
        }
        let step = self.settings.step.min(self.settings.goal - theta);
        if step > 1e-12 {
            let new = detach.len() - 1;
            match self.roll(&detach, theta, step)? {
                Roll::Blocked(j, why) if j == new => return reject(why),
                Roll::Stuck(why) => return reject(why),
                _ => {}
            }
        }
        Ok(Attempt::Chosen(Box::new(Chosen {
            t,
            attach,
            detach,
            q_attach,
            q_detach,
            approach,
            retreat,
        })))
    }

    /// Plans the scenario. `progress` is called after every step with the rotation done
    /// (rad).
    pub fn plan(&self, progress: &mut dyn FnMut(Real)) -> Result<Plan, PlanError> {
        let started = self.start()?;
        let mapped = Mapped {
            scenario: self,
            maps: self.hand.fingers.iter().map(ReachMap::new).collect(),
        };
        let mut slip: Real = 0.0;
        let driven = drive(
            &mapped,
            &self.settings,
            self.start_rotation,
            started,
            progress,
            &mut |next: &[Touch]| slip = next.iter().map(|t| t.slip).fold(slip, Real::max),
        )?;
        let clearance = self.plan_link_clearance(&driven.steps);
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
        Ok(driven.into_plan(&self.settings, axis, slip, clearance.0, reserve))
    }

    /// The smallest squeeze reserve (m, up to [`SQUEEZE_PROBE`]) of any finger in contact at
    /// any of `steps`.
    fn min_squeeze_reserve(&self, steps: &[Step]) -> Real {
        let mut least = SQUEEZE_PROBE;
        for step in steps {
            for fs in &step.fingers {
                let Some(n) = fs.normal else { continue };
                let f = self.finger(fs.finger);
                let n_w = self.rotation(step.rotation) * Vec3::from(n);
                least = least.min(f.reach_along(&fs.joints, &-n_w, SQUEEZE_PROBE));
            }
        }
        least
    }

    /// How close any finger's links (as lines) come to the object, at every step and along
    /// the moves between them ([`crate::route::SAMPLES`] poses per straight joint-space move,
    /// the object's rotation interpolated alike): a finger in contact in both steps, or free in
    /// both, straight; an attaching finger along its approach and a released finger along its
    /// retreat ([`Switch::approach`], [`Switch::retreat`]): (distance m, finger, link, step).
    pub fn plan_link_clearance(&self, steps: &[Step]) -> (Real, u32, usize, usize) {
        let mut closest = (Real::INFINITY, 0, 0, 0);
        for (k, step) in steps.iter().enumerate() {
            let previous = if k > 0 { &steps[k - 1] } else { step };
            let samples = if k > 0 { crate::route::SAMPLES } else { 1 };
            // The switch this move belongs to: attaching at `step`, or detaching after it.
            let switch = match step.phase {
                Phase::Attach => step.switch.as_ref(),
                Phase::Detach => previous.switch.as_ref(),
                _ => None,
            };
            for (a, b) in previous.fingers.iter().zip(&step.fingers) {
                let f = self.finger(b.finger);
                let vias: &[Vec<Real>] = match (switch, step.phase) {
                    (Some(w), Phase::Attach) if w.attached == b.finger => {
                        w.approach.as_deref().unwrap_or_default()
                    }
                    (Some(w), Phase::Detach) if w.released == b.finger => {
                        w.retreat.as_deref().unwrap_or_default()
                    }
                    _ => &[],
                };
                // The way from a's joints to b's: an approach runs home -> vias -> contact, a
                // retreat the same way back (its vias listed from home).
                let mut way: Vec<&[Real]> = vec![&a.joints];
                if step.phase == Phase::Detach {
                    way.extend(vias.iter().rev().map(Vec::as_slice));
                } else {
                    way.extend(vias.iter().map(Vec::as_slice));
                }
                way.push(&b.joints);
                for pair in way.windows(2) {
                    for i in 0..samples {
                        let s = if samples > 1 {
                            i as Real / (samples - 1) as Real
                        } else {
                            1.0
                        };
                        let q: Vec<Real> = pair[0]
                            .iter()
                            .zip(pair[1])
                            .map(|(x, y)| x + s * (y - x))
                            .collect();
                        let theta = previous.rotation + s * (step.rotation - previous.rotation);
                        let (d, link) = self.link_clearance(f, &q, theta);
                        if d < closest.0 {
                            closest = (d, b.finger, link, step.step);
                        }
                    }
                }
            }
        }
        closest
    }
}

/// Joint values per joint of a [`ReachMap`]'s grid.
const REACH_MAP_GRID: usize = 7;

/// How far (m) a fingertip target may be from every pose of a finger's [`ReachMap`] and still
/// be tried: a little more than the grid's spacing at the fingertip (a seventh of a joint's
/// range at a 50 mm lever).
const REACH_MAP_GAP: Real = 0.012;

/// A finger's reach map: its fingertip centre at poses on a grid over its joint ranges, to
/// rule out targets far from all of them and to seed the inverse kinematics of the others.
pub struct ReachMap {
    /// The finger.
    pub finger: u32,
    /// (fingertip centre, joints) at each pose of the grid.
    pub poses: Vec<(Vec3, Vec<Real>)>,
}

impl ReachMap {
    /// The map of finger `f`: [`REACH_MAP_GRID`] values per joint, its ends inside the limits
    /// (of a finger of more than six joints, the seventh and eighth held at their lowest
    /// grid value).
    pub fn new(f: &Finger) -> Self {
        let n = f.dof();
        let count = REACH_MAP_GRID.pow(n.min(6) as u32);
        let poses = (0..count)
            .map(|mut k| {
                let q: Vec<Real> = f
                    .joints
                    .iter()
                    .map(|j| {
                        let i = k % REACH_MAP_GRID;
                        k /= REACH_MAP_GRID;
                        let u = (i as Real + 0.5) / REACH_MAP_GRID as Real;
                        j.lower + u * (j.upper - j.lower)
                    })
                    .collect();
                (f.tip_centre(&q), q)
            })
            .collect();
        Self {
            finger: f.id,
            poses,
        }
    }

    /// The pose whose fingertip centre is nearest `target`: its distance and joints.
    pub fn nearest(&self, target: &Vec3) -> Option<(Real, &[Real])> {
        self.poses
            .iter()
            .map(|(p, q)| ((p - target).norm_squared(), q))
            .min_by(|a, b| a.0.total_cmp(&b.0))
            .map(|(d, q)| (d.sqrt(), q.as_slice()))
    }
}

/// The smallest singular value of finger `f`'s fingertip-centre Jacobian at `q` (m per rad).
pub fn mobility(f: &Finger, q: &[Real]) -> Real {
    let jac = f.jacobian6(q).rows(0, 3).into_owned();
    jac.singular_values().min()
}

/// What the placements of a switch that failed ran into, for its message: each reason (the
/// text after the placement's `point by finger N: `) with how many placements it stopped,
/// the most frequent first, and the first three placements as examples; empty for none.
fn rejections(rejected: &[String]) -> String {
    if rejected.is_empty() {
        return String::new();
    }
    let mut counts: Vec<(&str, usize)> = Vec::new();
    for r in rejected {
        let why = r.split_once(": ").map_or(r.as_str(), |(_, why)| why);
        match counts.iter_mut().find(|(w, _)| *w == why) {
            Some((_, n)) => *n += 1,
            None => counts.push((why, 1)),
        }
    }
    counts.sort_by_key(|c| std::cmp::Reverse(c.1));
    let reasons: Vec<String> = counts.iter().map(|(w, n)| format!("{n} x {w}")).collect();
    let examples = rejected
        .iter()
        .take(3)
        .cloned()
        .collect::<Vec<_>>()
        .join("; ");
    format!(" (stopped by: {}; e.g. {examples})", reasons.join(", "))
}

/// The distance of the segment `ab` (body frame) from the surface (m; negative: a point of it
/// inside, by how deep). Exact for a sphere; for the other surfaces the smallest signed
/// distance of the points along it found by a golden-section search, to within
/// [`TRACE_TOLERANCE`]: the signed distance from a convex body is a convex function of the
/// point (the largest of the affine `n . x - h(n)` over its supporting planes), so along the
/// segment it has one minimum, and it changes by at most the length moved. About 15 closest
/// points for a 50 mm link, where tracing it at 0.5 mm steps took up to a hundred.
pub fn segment_surface_distance(surface: &Convex, a: &Vec3, b: &Vec3) -> Real {
    match surface {
        Convex::Sphere { centre, radius } => point_segment_distance(centre, a, b) - radius,
        _ => {
            let at = |s: Real| surface.closest(&(a + (b - a) * s)).distance;
            let length = (b - a).norm();
            let (da, db) = (at(0.0), at(1.0));
            if length <= TRACE_TOLERANCE {
                return da.min(db);
            }
            // Golden section on [lo, hi] (fractions of the segment), the bracket of the
            // minimum, until it is shorter than the tolerance.
            const G: Real = 0.618_033_988_749_894_9;
            let (mut lo, mut hi) = (0.0, 1.0);
            let (mut x1, mut x2) = (hi - G * (hi - lo), lo + G * (hi - lo));
            let (mut f1, mut f2) = (at(x1), at(x2));
            let mut least = da.min(db).min(f1).min(f2);
            while (hi - lo) * length > TRACE_TOLERANCE {
                if f1 <= f2 {
                    hi = x2;
                    (x2, f2) = (x1, f1);
                    x1 = hi - G * (hi - lo);
                    f1 = at(x1);
                    least = least.min(f1);
                } else {
                    lo = x1;
                    (x1, f1) = (x2, f2);
                    x2 = lo + G * (hi - lo);
                    f2 = at(x2);
                    least = least.min(f2);
                }
            }
            least
        }
    }
}

/// How close (m) to the smallest distance of a link from an ellipsoid or a polyhedron
/// [`segment_surface_distance`] comes.
pub const TRACE_TOLERANCE: Real = 0.05e-3;

/// Distance from point `p` to segment `ab`.
fn point_segment_distance(p: &Vec3, a: &Vec3, b: &Vec3) -> Real {
    let ab = b - a;
    let len2 = ab.norm_squared();
    let t = if len2 > 0.0 {
        ((p - a).dot(&ab) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (a + ab * t - p).norm()
}

/// Distance between segments `p0 p1` and `q0 q1` (Ericson, Real-Time Collision Detection,
/// 5.1.9); either may be a point.
pub fn segment_segment_distance(p0: &Vec3, p1: &Vec3, q0: &Vec3, q1: &Vec3) -> Real {
    let (d1, d2, r) = (p1 - p0, q1 - q0, p0 - q0);
    let (a, e, f) = (d1.norm_squared(), d2.norm_squared(), d2.dot(&r));
    let eps = 1e-18;
    let (s, t);
    if a <= eps && e <= eps {
        return r.norm();
    }
    if a <= eps {
        s = 0.0;
        t = (f / e).clamp(0.0, 1.0);
    } else {
        let c = d1.dot(&r);
        if e <= eps {
            t = 0.0;
            s = (-c / a).clamp(0.0, 1.0);
        } else {
            let b = d1.dot(&d2);
            let denom = a * e - b * b;
            let mut s0 = if denom > eps {
                ((b * f - c * e) / denom).clamp(0.0, 1.0)
            } else {
                0.0
            };
            let mut t0 = (b * s0 + f) / e;
            if t0 < 0.0 {
                t0 = 0.0;
                s0 = (-c / a).clamp(0.0, 1.0);
            } else if t0 > 1.0 {
                t0 = 1.0;
                s0 = ((b - c) / a).clamp(0.0, 1.0);
            }
            s = s0;
            t = t0;
        }
    }
    ((p0 + d1 * s) - (q0 + d2 * t)).norm()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn segment_distances() {
        let z = Vec3::zeros();
        let d = segment_segment_distance(
            &z,
            &Vec3::x(),
            &Vec3::new(0.5, 1.0, -1.0),
            &Vec3::new(0.5, 1.0, 1.0),
        );
        assert!((d - 1.0).abs() < 1e-15);
        let d = segment_segment_distance(
            &z,
            &Vec3::x(),
            &Vec3::new(2.0, 0.0, 0.0),
            &Vec3::new(3.0, 0.0, 0.0),
        );
        assert!((d - 1.0).abs() < 1e-15);
        let d =
            segment_segment_distance(&z, &z, &Vec3::new(0.0, 2.0, 0.0), &Vec3::new(0.0, 2.0, 0.0));
        assert!((d - 2.0).abs() < 1e-15);
        let s = Convex::Sphere {
            centre: z,
            radius: 1.0,
        };
        let d = segment_surface_distance(&s, &Vec3::new(-2.0, 1.5, 0.0), &Vec3::new(2.0, 1.5, 0.0));
        assert!((d - 0.5).abs() < 1e-15);
    }

    /// A failed switch's message counts the placements per reason, the most frequent first,
    /// with three examples, however many were tried (it once listed all 804).
    #[test]
    fn a_failed_switch_says_what_stopped_its_placements_in_a_line() {
        assert_eq!(rejections(&[]), "");
        let rejected: Vec<String> = (0..800)
            .map(|i| {
                let why = if i % 100 == 7 {
                    "on its approach its fingertip would hit the object"
                } else {
                    "on its retreat its fingertip would hit the object"
                };
                format!("[{i}.0, 0.0, 0.0] mm by finger 2: {why}")
            })
            .collect();
        let said = rejections(&rejected);
        assert_eq!(
            said,
            " (stopped by: 792 x on its retreat its fingertip would hit the object, 8 x on its \
             approach its fingertip would hit the object; e.g. [0.0, 0.0, 0.0] mm by finger 2: on \
             its retreat its fingertip would hit the object; [1.0, 0.0, 0.0] mm by finger 2: on \
             its retreat its fingertip would hit the object; [2.0, 0.0, 0.0] mm by finger 2: on \
             its retreat its fingertip would hit the object)"
        );
    }

    /// On an ellipsoid and a cube as a polyhedron, a segment's distance from the surface is
    /// the smallest of its points' to within TRACE_TOLERANCE (sampled every 0.01 mm): segments
    /// outside, grazing, and through the object.
    #[test]
    fn a_segment_s_distance_from_a_convex_surface_is_its_nearest_point_s() {
        let surfaces = [
            Convex::Ellipsoid {
                centre: Vec3::new(0.002, -0.001, 0.003),
                semi_axes: Vec3::new(0.055, 0.045, 0.04),
            },
            Convex::polyhedron(
                &icrflow_grasp::object::Object::cuboid(Vec3::new(0.03, 0.03, 0.03), 4).unwrap(),
            )
            .unwrap(),
        ];
        let mut next = surface::uniform(3);
        for s in &surfaces {
            for _ in 0..200 {
                let a = Vec3::new(next(), next(), next()) * 0.09;
                let b = a + Vec3::new(next(), next(), next()) * 0.06;
                let d = segment_surface_distance(s, &a, &b);
                let n = ((b - a).norm() / 1e-5).ceil() as usize;
                let sampled = (0..=n)
                    .map(|i| s.closest(&(a + (b - a) * (i as Real / n as Real))).distance)
                    .fold(Real::INFINITY, Real::min);
                assert!(
                    (d - sampled).abs() <= TRACE_TOLERANCE,
                    "{a} {b}: {d} vs {sampled}"
                );
            }
        }
    }
}
