//! Hand model: fingers as serial revolute chains with joint limits and a spherical fingertip.
//!
//! # Frames and conventions
//! - The *hand frame* is the world frame of the planner: the hand moves in (or around) its
//!   horizontal plane `z = 0`, the object's centre of mass sits at the origin.
//! - A finger is `base * (origin_1 * R(axis_1, q_1)) * ... * (origin_n * R(axis_n, q_n)) * tip`:
//!   `base` places the chain in the hand frame, each joint has a fixed `origin` (parent frame
//!   to joint frame at `q = 0`) and rotates about its unit `axis` (joint frame), and `tip` is
//!   the translation from the last joint frame to the fingertip sphere's centre.
//! - The fingertip is a sphere of radius `tip_radius` of which only a cap can touch: the
//!   points within `cap_half_angle` of the *cap axis*, the direction of `tip` in the last
//!   joint frame (along the distal link). A hemispherical fingertip has a half-angle of 90 deg.
//! - Angles are radians; joint limits are inclusive.
//!
//! # Planar fingers
//! A finger whose joint axes are all parallel to the hand's z axis and whose joints and tip
//! lie in one horizontal plane is *planar*. Its fingertip pose in the plane is
//! `(x, y, phi)`, with `phi` the world angle of the cap axis. For three joints that pose
//! fixes the joints (up to the elbow branch) and [`Finger::ik_planar`] solves it in closed
//! form; other chains use damped least squares ([`Finger::ik_position`]).

use icrflow_grasp::math::{Isometry3, Real, UnitQuaternion, Vec3};
use nalgebra::{DMatrix, DVector, Translation3, Unit};
use std::f64::consts::PI;

/// Tolerance (m, rad) for treating a chain as planar.
const PLANAR_TOLERANCE: Real = 1e-9;
/// Steps along which [`Finger::reach_along`] and [`Finger::reach_along_planar`] follow a path
/// to measure a reserve.
pub const REACH_STEPS: usize = 8;
/// The most joints [`Finger::shift_point`] moves (a finger of more is not shifted).
pub const SHIFT_JOINTS: usize = 8;
/// The shortest lever [`Finger::shift_point`] moves a fingertip with (m): a joint may turn by
/// at most the move over it.
pub const SHIFT_LEVER: Real = 0.01;
/// [`Finger::shift_point`]'s Gauss-Newton steps at most.
pub const SHIFT_STEPS: usize = 4;
/// The damping of [`Finger::shift_point`]'s steps (m^2): none to speak of away from a singular
/// pose.
const SHIFT_DAMPING: Real = 1e-9;
/// Most null-space steps [`Finger::ik_position_centred`] takes toward the middle of the joint
/// ranges.
pub const CENTRING_STEPS: usize = 30;
/// Largest joint motion of one such step (rad).
pub const CENTRING_STEP: Real = 0.05;

/// Why a hand description or a kinematic query failed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum HandError {
    /// A value of the description is impossible.
    #[error("finger {finger}: {what}")]
    Invalid {
        /// Finger number.
        finger: u32,
        /// What is wrong.
        what: String,
    },
    /// The URDF could not be used.
    #[error("URDF: {0}")]
    Urdf(String),
}

/// Why inverse kinematics found no admissible solution.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum IkError {
    /// The target is out of reach of the chain (ignoring limits).
    #[error("target out of reach by {distance:.3e} m")]
    OutOfReach {
        /// How far beyond the reachable annulus.
        distance: Real,
    },
    /// Solutions exist but each violates a joint limit.
    #[error(
        "joint {} would be at {:.2} deg, outside [{:.2}, {:.2}] deg",
        joint + 1,
        angle.to_degrees(),
        lower.to_degrees(),
        upper.to_degrees()
    )]
    JointLimit {
        /// Joint index (0-based) of the first violated limit of the best solution.
        joint: usize,
        /// The angle it would need (rad).
        angle: Real,
        /// Its lower limit (rad).
        lower: Real,
        /// Its upper limit (rad).
        upper: Real,
    },
    /// Damped least squares did not converge.
    #[error("no convergence: residual {residual:.3e} m after {iterations} iterations")]
    NoConvergence {
        /// Remaining error.
        residual: Real,
        /// Iterations used.
        iterations: usize,
    },
    /// The finger is not planar, so a planar pose cannot be asked of it.
    #[error("the finger is not a planar chain")]
    NotPlanar,
}

/// One revolute joint.
#[derive(Debug, Clone, PartialEq)]
pub struct Joint {
    /// Name (from the URDF, or `j1`, `j2`, ... for TOML hands).
    pub name: String,
    /// Parent frame to joint frame at `q = 0`.
    pub origin: Isometry3,
    /// Rotation axis in the joint frame.
    pub axis: Unit<Vec3>,
    /// Lower limit (rad).
    pub lower: Real,
    /// Upper limit (rad).
    pub upper: Real,
}

/// The planar description of a planar finger, derived from its chain.
#[derive(Debug, Clone, PartialEq)]
pub struct PlanarChain {
    /// Height of the plane in the hand frame.
    pub z: Real,
    /// Position of the first joint in the plane.
    pub root: [Real; 2],
    /// Lengths of the links: joint 1 to 2, ..., last joint to the fingertip centre.
    pub lengths: Vec<Real>,
    /// World angle of each link at `q = 0`.
    pub angles0: Vec<Real>,
    /// `+1` or `-1`: the sign of each joint axis along the hand's z.
    pub signs: Vec<Real>,
    /// World angle of the cap axis minus that of the last link (constant).
    pub cap_offset: Real,
}

/// A finger.
#[derive(Debug, Clone, PartialEq)]
pub struct Finger {
    /// Finger number as the config uses it.
    pub id: u32,
    /// Places the chain in the hand frame.
    pub base: Isometry3,
    /// The joints, from the palm out.
    pub joints: Vec<Joint>,
    /// Last joint frame to the fingertip centre.
    pub tip: Vec3,
    /// Fingertip sphere radius (m).
    pub tip_radius: Real,
    /// Half-angle of the fingertip cap that can touch (rad).
    pub cap_half_angle: Real,
    /// Joint angles when the finger is not in contact.
    pub home: Vec<Real>,
    /// The planar description, if the chain is planar.
    pub planar: Option<PlanarChain>,
}

/// A finger's pose from forward kinematics.
#[derive(Debug, Clone, PartialEq)]
pub struct FingerPose {
    /// Origin of each joint frame in the hand frame (index `i`: joint `i`).
    pub joints: Vec<Vec3>,
    /// Fingertip sphere centre.
    pub tip_centre: Vec3,
    /// Orientation of the last joint frame (the fingertip's).
    pub tip_rotation: UnitQuaternion,
    /// Unit cap axis in the hand frame.
    pub cap_axis: Vec3,
}

/// The hand.
#[derive(Debug, Clone, PartialEq)]
pub struct Hand {
    /// Fingers, in ascending `id`.
    pub fingers: Vec<Finger>,
}

/// Wraps an angle to `(-pi, pi]`.
pub fn wrap(a: Real) -> Real {
    let w = (a + PI).rem_euclid(2.0 * PI) - PI;
    if w <= -PI { w + 2.0 * PI } else { w }
}

impl Finger {
    /// Builds a finger and checks it: at least one joint, finite values, `lower <= upper`,
    /// a tip beyond the last joint, a positive radius, a cap half-angle in (0, 180) deg and a
    /// home pose inside the limits.
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        id: u32,
        base: Isometry3,
        joints: Vec<Joint>,
        tip: Vec3,
        tip_radius: Real,
        cap_half_angle: Real,
        home: Option<Vec<Real>>,
    ) -> Result<Self, HandError> {
        let bad = |what: String| HandError::Invalid { finger: id, what };
        if joints.is_empty() {
            return Err(bad("has no revolute joint".into()));
        }
        for (i, j) in joints.iter().enumerate() {
            let finite = j.origin.translation.vector.iter().all(|x| x.is_finite())
                && j.origin.rotation.coords.iter().all(|x| x.is_finite())
                && j.axis.iter().all(|x| x.is_finite());
            if !finite {
                return Err(bad(format!("joint {} ({}) is not finite", i + 1, j.name)));
            }
            if !(j.lower.is_finite() && j.upper.is_finite()) || j.lower > j.upper {
                return Err(bad(format!(
                    "joint {} ({}) has limits [{}, {}] deg: need finite lower <= upper",
                    i + 1,
                    j.name,
                    j.lower.to_degrees(),
                    j.upper.to_degrees()
                )));
            }
        }
        if !tip.iter().all(|x| x.is_finite()) || tip.norm() <= 0.0 {
            return Err(bad(
                "the fingertip centre must be a finite, non-zero offset from the last joint".into(),
            ));
        }
        if !tip_radius.is_finite() || tip_radius <= 0.0 {
            return Err(bad(format!(
                "fingertip radius must be > 0, got {tip_radius}"
            )));
        }
        if !(cap_half_angle > 0.0 && cap_half_angle < PI) {
            return Err(bad(format!(
                "cap half-angle must be in (0, 180) deg, got {}",
                cap_half_angle.to_degrees()
            )));
        }
        let home = home.unwrap_or_else(|| {
            joints
                .iter()
                .map(|j| 0.0_f64.clamp(j.lower, j.upper))
                .collect()
        });
        if home.len() != joints.len() {
            return Err(bad(format!(
                "home pose has {} angles for {} joints",
                home.len(),
                joints.len()
            )));
        }
        for (i, (h, j)) in home.iter().zip(&joints).enumerate() {
            if !(j.lower..=j.upper).contains(h) {
                return Err(bad(format!(
                    "home angle of joint {} is {:.2} deg, outside its limits [{:.2}, {:.2}] deg",
                    i + 1,
                    h.to_degrees(),
                    j.lower.to_degrees(),
                    j.upper.to_degrees()
                )));
            }
        }
        let mut finger = Self {
            id,
            base,
            joints,
            tip,
            tip_radius,
            cap_half_angle,
            home,
            planar: None,
        };
        finger.planar = finger.planar_chain();
        Ok(finger)
    }

    /// Whether the finger is a planar three-joint chain in the hand's plane `z = 0`: what the
    /// planar planner ([`crate::planner`]) takes; others go to [`crate::spatial`].
    pub fn in_hand_plane(&self) -> bool {
        self.dof() == 3 && self.planar.as_ref().is_some_and(|p| p.z.abs() <= 1e-9)
    }

    /// Number of joints.
    pub fn dof(&self) -> usize {
        self.joints.len()
    }

    /// Forward kinematics.
    pub fn fk(&self, q: &[Real]) -> FingerPose {
        let mut joints = Vec::with_capacity(self.joints.len());
        let t = self.chain(q, |origin| joints.push(origin));
        FingerPose {
            joints,
            tip_centre: (t * nalgebra::Point3::from(self.tip)).coords,
            tip_rotation: t.rotation,
            cap_axis: t.rotation * self.tip.normalize(),
        }
    }

    /// The fingertip sphere's centre and the unit cap axis at `q` (as [`Finger::fk`] gives
    /// them), without allocating: for loops that run at the pipeline's rate.
    pub fn fk_tip(&self, q: &[Real]) -> (Vec3, Vec3) {
        let t = self.chain(q, |_| {});
        (
            (t * nalgebra::Point3::from(self.tip)).coords,
            t.rotation * self.tip.normalize(),
        )
    }

    /// The last joint frame at `q` (the fingertip's: its centre is at `frame * tip`), without
    /// allocating.
    pub fn tip_frame(&self, q: &[Real]) -> Isometry3 {
        self.chain(q, |_| {})
    }

    /// The last joint frame at `q`, calling `at_joint` with each joint frame's origin.
    fn chain(&self, q: &[Real], mut at_joint: impl FnMut(Vec3)) -> Isometry3 {
        let mut t = self.base;
        for (j, &qi) in self.joints.iter().zip(q) {
            t *= j.origin;
            at_joint(t.translation.vector);
            t *= Isometry3::from_parts(
                Translation3::identity(),
                UnitQuaternion::from_axis_angle(&j.axis, qi),
            );
        }
        t
    }

    /// The finger's links at `q` as line segments, passed to `visit(link, from, to)`: from
    /// each joint origin to the next (link `i` from joint `i`, counted from 1), and the distal
    /// link from the last joint to where it enters the fingertip sphere (the fingertip itself
    /// touches the object, and is checked on its own). The links' thickness is the caller's
    /// margin. No allocation.
    pub fn link_segments(&self, q: &[Real], mut visit: impl FnMut(usize, Vec3, Vec3)) {
        let mut previous: Option<Vec3> = None;
        let mut link = 0;
        let t = self.chain(q, |origin| {
            if let Some(p) = previous {
                link += 1;
                visit(link, p, origin);
            }
            previous = Some(origin);
        });
        if let Some(p) = previous {
            let centre = (t * nalgebra::Point3::from(self.tip)).coords;
            let along = centre - p;
            let length = along.norm();
            if length > self.tip_radius {
                visit(
                    link + 1,
                    p,
                    p + along * ((length - self.tip_radius) / length),
                );
            }
        }
    }

    /// How close the finger's links ([`Self::link_segments`]) come to the hand frame's origin
    /// (the object's centre) at `q`, and which link. No allocation.
    pub fn link_distance(&self, q: &[Real]) -> (Real, usize) {
        let mut closest = (Real::INFINITY, 0);
        self.link_segments(q, |link, a, b| {
            let d = segment_distance(&a, &b);
            if d < closest.0 {
                closest = (d, link);
            }
        });
        closest
    }

    /// The first joint whose limits `q` violates (beyond `slack` rad), if any.
    pub fn limit_violation(&self, q: &[Real], slack: Real) -> Option<IkError> {
        self.joints
            .iter()
            .zip(q)
            .enumerate()
            .find(|(_, (j, a))| **a < j.lower - slack || **a > j.upper + slack)
            .map(|(i, (j, a))| IkError::JointLimit {
                joint: i,
                angle: *a,
                lower: j.lower,
                upper: j.upper,
            })
    }

    /// Jacobian of the fingertip centre (3 x n) and of the rotation about the hand's z axis
    /// (1 x n, the last row), at `q`: rows 0, 1, 2 and 5 of [`Finger::jacobian6`].
    pub fn jacobian(&self, q: &[Real]) -> DMatrix<Real> {
        self.jacobian6(q).select_rows(&[0, 1, 2, 5])
    }

    /// The whole Jacobian of the fingertip (6 x n) at `q`: rows 0-2 the fingertip centre's
    /// velocity, rows 3-5 the fingertip's angular velocity (the joint axes), both in the
    /// hand frame, per unit joint rate.
    pub fn jacobian6(&self, q: &[Real]) -> DMatrix<Real> {
        let n = self.dof();
        let mut jac = DMatrix::zeros(6, n);
        let mut t = self.base;
        let mut axes = Vec::with_capacity(n);
        for (j, &qi) in self.joints.iter().zip(q) {
            t *= j.origin;
            axes.push((t.translation.vector, t.rotation * j.axis.into_inner()));
            t *= Isometry3::from_parts(
                Translation3::identity(),
                UnitQuaternion::from_axis_angle(&j.axis, qi),
            );
        }
        let p = (t * nalgebra::Point3::from(self.tip)).coords;
        for (c, (o, a)) in axes.iter().enumerate() {
            let v = a.cross(&(p - o));
            for r in 0..3 {
                jac[(r, c)] = v[r];
                jac[(r + 3, c)] = a[r];
            }
        }
        jac
    }

    /// The contact Jacobian (3 x n) at `q` of a fingertip touching a surface whose outward
    /// unit normal there is `n` (hand frame; the fingertip touches at `centre - r_f n`): the
    /// velocity of the fingertip's material point at the contact per unit joint rate, `J_v +
    /// r_f [n]x J_w`. Rolling without slipping on a still object is `A q' = 0`.
    pub fn contact_jacobian(&self, q: &[Real], n: &Vec3) -> DMatrix<Real> {
        let jac = self.jacobian6(q);
        let mut a = jac.rows(0, 3).into_owned();
        for c in 0..self.dof() {
            let w = Vec3::new(jac[(3, c)], jac[(4, c)], jac[(5, c)]);
            let v = n.cross(&w) * self.tip_radius;
            for r in 0..3 {
                a[(r, c)] += v[r];
            }
        }
        a
    }

    /// Manipulability `sqrt(det(J J^T))` of the task the planner uses: `(x, y, phi)` for a
    /// planar finger, the fingertip centre otherwise. Zero at a singularity.
    pub fn manipulability(&self, q: &[Real]) -> Real {
        let jac = self.jacobian6(q);
        let task = if self.planar.is_some() {
            jac.select_rows(&[0, 1, 5])
        } else {
            jac.rows(0, 3).into_owned()
        };
        (task.clone() * task.transpose())
            .determinant()
            .max(0.0)
            .sqrt()
    }

    /// The fingertip sphere's centre at `q` (hand frame): [`Finger::fk`]'s `tip_centre`
    /// without the rest of the pose, allocating nothing.
    pub fn tip_centre(&self, q: &[Real]) -> Vec3 {
        (self.chain(q, |_| {}) * nalgebra::Point3::from(self.tip)).coords
    }

    /// How far (m, at most `probe`) the fingertip centre of the finger at `q` can move along
    /// the unit direction `dir` on a continuous path inside the joint limits: for a finger in
    /// contact, with `dir` the inward contact normal, the room it has to press further into
    /// the object (its *squeeze reserve*). The path is followed in [`REACH_STEPS`] steps of
    /// local damped least squares, each from the last; where a step does not converge the
    /// reserve is the last distance reached, refined by bisection to `probe / 256`.
    pub fn reach_along(&self, q: &[Real], dir: &Vec3, probe: Real) -> Real {
        let start = self.tip_centre(q);
        reach(q, probe, REACH_STEPS, |d, from| {
            self.dls(&(start + dir * d), from).ok()
        })
    }

    /// [`Finger::reach_along`] for a planar three-joint finger with the cap axis kept (the
    /// fingertip presses with the same point of its cap, as a hand pressing on without
    /// turning its fingertip does): with no redundancy left, a joint at its limit or a
    /// straight finger stops it. `dir` is taken in the hand's plane. Each step is the closed
    /// form ([`Finger::ik_planar`]) on the branch of the last, no joint moving more than
    /// 0.5 rad at once; 0 for a finger that is not planar.
    /// `steps` sets how finely the path is followed ([`REACH_STEPS`] to measure; fewer to
    /// check that `probe` is reached, which then costs `steps` solutions).
    pub fn reach_along_planar(&self, q: &[Real], dir: &Vec3, probe: Real, steps: usize) -> Real {
        let Some((x, y, phi)) = self.planar_pose(q) else {
            return 0.0;
        };
        reach(q, probe, steps, |d, from| {
            let next = self
                .ik_planar(x + dir.x * d, y + dir.y * d, phi, from)
                .ok()?;
            let jump = next.iter().zip(from).any(|(a, b)| (a - b).abs() > 0.5);
            (!jump).then_some(next)
        })
    }

    /// Inverse kinematics of the fingertip centre by damped least squares, from `q0`, within
    /// the joint limits: joints at a limit that the step would push further out are frozen
    /// for that step (an active set), and each step is halved until the error decreases.
    /// Converges to `1e-10` m. A local minimum against a limit is escaped by restarting from
    /// the middle of the joint ranges and from points between it and `q0`; a target out of
    /// reach gives [`IkError::NoConvergence`] with the smallest residual found.
    pub fn ik_position(&self, target: &Vec3, q0: &[Real]) -> Result<Vec<Real>, IkError> {
        let mid: Vec<Real> = self
            .joints
            .iter()
            .map(|j| 0.5 * (j.lower + j.upper))
            .collect();
        let mut best = match self.dls(target, q0) {
            Ok(q) => return Ok(q),
            Err(e) => e,
        };
        // Then from seeds moved toward the middle of the joint ranges, and toward their lower
        // and upper ends (a pose near a limit and a straight finger can hold the descent in a
        // local minimum short of the target).
        let lower: Vec<Real> = self.joints.iter().map(|j| j.lower).collect();
        let upper: Vec<Real> = self.joints.iter().map(|j| j.upper).collect();
        let toward = [
            (&mid, 1.0),
            (&mid, 0.5),
            (&mid, 0.25),
            (&mid, 0.75),
            (&lower, 0.5),
            (&upper, 0.5),
        ];
        for (to, t) in toward {
            let seed: Vec<Real> = q0.iter().zip(to).map(|(a, m)| a + t * (m - a)).collect();
            match self.dls(target, &seed) {
                Ok(q) => return Ok(q),
                Err(e) => {
                    let residual = |x: &IkError| match x {
                        IkError::NoConvergence { residual, .. } => *residual,
                        _ => Real::INFINITY,
                    };
                    if residual(&e) < residual(&best) {
                        best = e;
                    }
                }
            }
        }
        Err(best)
    }

    /// How far the joints `q` are from their limits, each as a fraction of its range from the
    /// nearer end (0 at a limit, 0.5 mid-range): the smallest, the finger's limit margin.
    pub fn limit_margin(&self, q: &[Real]) -> Real {
        self.joints
            .iter()
            .zip(q)
            .map(|(j, a)| {
                let range = j.upper - j.lower;
                if range > 0.0 {
                    ((a - j.lower).min(j.upper - a) / range).max(0.0)
                } else {
                    0.0
                }
            })
            .fold(0.5, Real::min)
    }

    /// The joint-limit cost of `q`: `sum range_i^2 / (4 (upper_i - q_i) (q_i - lower_i))`,
    /// the number of joints when every joint is mid-range, growing without bound as one
    /// nears a limit (infinite at it). Joints of zero range count nothing.
    pub fn limit_cost(&self, q: &[Real]) -> Real {
        self.joints
            .iter()
            .zip(q)
            .map(|(j, a)| {
                let range = j.upper - j.lower;
                if range <= 0.0 {
                    return 0.0;
                }
                let room = (j.upper - a) * (a - j.lower);
                if room <= 0.0 {
                    Real::INFINITY
                } else {
                    range * range / (4.0 * room)
                }
            })
            .sum()
    }

    /// The gradient of [`Finger::limit_cost`] at `q`, its joints kept a hair (1e-6 of their
    /// range) inside their limits.
    pub fn limit_cost_gradient(&self, q: &[Real]) -> DVector<Real> {
        DVector::from_iterator(
            self.dof(),
            self.joints.iter().zip(q).map(|(j, &a)| {
                let range = j.upper - j.lower;
                if range <= 0.0 {
                    return 0.0;
                }
                let hair = 1e-6 * range;
                let a = a.clamp(j.lower + hair, j.upper - hair);
                let (up, down) = (j.upper - a, a - j.lower);
                -(range * range * (up - down) / (4.0 * up * up * down * down))
            }),
        )
    }

    /// [`Finger::ik_position`], then the finger's redundancy used to keep its joints off
    /// their limits: steps in the null space of the fingertip-centre Jacobian (which leave
    /// the centre where it is, to first order) down the gradient of [`Finger::limit_cost`],
    /// each re-converged on the target by damped least squares and kept only if it lowers the
    /// cost with the centre still within `1e-10` m, until no null-space direction lowers it
    /// or [`CENTRING_STEPS`] steps. A finger without redundancy (three joints for the three
    /// coordinates) keeps the plain solution. (The 4-joint fingers of the Allegro hand have one
    /// redundant direction: the self-motion of their parallel flexion joints.)
    pub fn ik_position_centred(&self, target: &Vec3, q0: &[Real]) -> Result<Vec<Real>, IkError> {
        let mut q = self.ik_position(target, q0)?;
        let n = self.dof();
        for _ in 0..CENTRING_STEPS {
            let jac = self.jacobian6(&q).rows(0, 3).into_owned();
            // The null-space projector I - J^+ J (J^+ by the pseudo-inverse of its SVD).
            let Ok(pinv) = jac.clone().pseudo_inverse(1e-9) else {
                break;
            };
            let projector = DMatrix::<Real>::identity(n, n) - &pinv * &jac;
            let dq = -(&projector * self.limit_cost_gradient(&q));
            if dq.amax() < 1e-9 {
                break;
            }
            let mut step = CENTRING_STEP / dq.amax();
            let before = self.limit_cost(&q);
            let mut moved = None;
            for _ in 0..8 {
                let trial: Vec<Real> = q.iter().zip(dq.iter()).map(|(a, d)| a + step * d).collect();
                if let Ok(t) = self.dls(target, &trial)
                    && self.limit_cost(&t) < before - 1e-12
                    && (self.tip_centre(&t) - target).norm() <= 1e-10
                {
                    moved = Some(t);
                    break;
                }
                step *= 0.5;
            }
            match moved {
                Some(t) => q = t,
                None => break,
            }
        }
        Ok(q)
    }

    /// One damped-least-squares descent from `q0`.
    fn dls(&self, target: &Vec3, q0: &[Real]) -> Result<Vec<Real>, IkError> {
        const ITERATIONS: usize = 500;
        const DAMPING: Real = 1e-3;
        let n = self.dof();
        let clamp = |q: &mut Vec<Real>| {
            for (a, j) in q.iter_mut().zip(&self.joints) {
                *a = a.clamp(j.lower, j.upper);
            }
        };
        let mut q: Vec<Real> = q0.to_vec();
        q.resize(n, 0.0);
        clamp(&mut q);
        let mut e = target - self.tip_centre(&q);
        for iteration in 0..ITERATIONS {
            if e.norm() <= 1e-10 {
                return Ok(q);
            }
            let full = self.jacobian6(&q).rows(0, 3).into_owned();
            let mut frozen = vec![false; n];
            let mut dq = DVector::zeros(n);
            for _ in 0..=n {
                let mut jac = full.clone();
                for (c, _) in frozen.iter().enumerate().filter(|(_, f)| **f) {
                    jac.column_mut(c).fill(0.0);
                }
                // Damping shrinks near the solution so the last steps are Gauss-Newton.
                let lambda = DAMPING * e.norm().min(1.0).sqrt();
                let jjt = &jac * jac.transpose() + DMatrix::identity(3, 3) * lambda * lambda;
                let Some(chol) = jjt.cholesky() else { break };
                dq = jac.transpose() * chol.solve(&DVector::from_column_slice(e.as_slice()));
                let mut changed = false;
                for (c, j) in self.joints.iter().enumerate() {
                    let at_lower = q[c] <= j.lower + 1e-12 && dq[c] < 0.0;
                    let at_upper = q[c] >= j.upper - 1e-12 && dq[c] > 0.0;
                    if (at_lower || at_upper) && !frozen[c] {
                        frozen[c] = true;
                        changed = true;
                    }
                }
                if !changed {
                    break;
                }
            }
            // The longest step along dq that stays within the limits, and at most 0.3 rad
            // for any joint; scaled, not clipped, so it stays a descent direction.
            let mut step = (0.3 / dq.amax().max(1e-300)).min(1.0);
            for (c, j) in self.joints.iter().enumerate() {
                if frozen[c] || dq[c] == 0.0 {
                    continue;
                }
                let room = if dq[c] > 0.0 {
                    j.upper - q[c]
                } else {
                    j.lower - q[c]
                };
                step = step.min((room / dq[c]).max(0.0));
            }
            let mut improved = false;
            for _ in 0..20 {
                let mut trial: Vec<Real> =
                    q.iter().zip(dq.iter()).map(|(a, d)| a + step * d).collect();
                clamp(&mut trial);
                let et = target - self.tip_centre(&trial);
                if et.norm() < e.norm() {
                    (q, e) = (trial, et);
                    improved = true;
                    break;
                }
                step *= 0.5;
            }
            if !improved {
                return Err(IkError::NoConvergence {
                    residual: e.norm(),
                    iterations: iteration + 1,
                });
            }
        }
        Err(IkError::NoConvergence {
            residual: e.norm(),
            iterations: ITERATIONS,
        })
    }

    /// Closed-form inverse kinematics of a planar three-joint finger: the fingertip centre at
    /// `(x, y)` with the cap axis at world angle `phi`. Of the two elbow branches, returns the
    /// one inside the joint limits, the nearer to `near` if both are.
    pub fn ik_planar(
        &self,
        x: Real,
        y: Real,
        phi: Real,
        near: &[Real],
    ) -> Result<Vec<Real>, IkError> {
        let p = self.planar.as_ref().ok_or(IkError::NotPlanar)?;
        if self.dof() != 3 {
            return Err(IkError::NotPlanar);
        }
        let (l1, l2, l3) = (p.lengths[0], p.lengths[1], p.lengths[2]);
        let a3 = phi - p.cap_offset;
        // The wrist (third joint) and the fingertip centre lie along link 3.
        let wx = x - l3 * a3.cos() - p.root[0];
        let wy = y - l3 * a3.sin() - p.root[1];
        let r = (wx * wx + wy * wy).sqrt();
        let (lo, hi) = ((l1 - l2).abs(), l1 + l2);
        if r > hi || r < lo {
            let distance = if r > hi { r - hi } else { lo - r };
            return Err(IkError::OutOfReach { distance });
        }
        let c = ((r * r - l1 * l1 - l2 * l2) / (2.0 * l1 * l2)).clamp(-1.0, 1.0);
        let bend = c.acos();
        let mut best: Option<(Real, Vec<Real>)> = None;
        let mut first_violation = None;
        for elbow in [bend, -bend] {
            let a1 = wy.atan2(wx) - (l2 * elbow.sin()).atan2(l1 + l2 * elbow.cos());
            let a2 = a1 + elbow;
            let abs = [a1, a2, a3];
            let q: Vec<Real> = (0..3)
                .map(|i| {
                    let rel = if i == 0 {
                        abs[0] - p.angles0[0]
                    } else {
                        (abs[i] - abs[i - 1]) - (p.angles0[i] - p.angles0[i - 1])
                    };
                    // Of the angle's representatives `target + 2 pi k`, the one inside the
                    // limits nearest the reference pose (or just the nearest).
                    let target = wrap(p.signs[i] * rel);
                    let reference = near.get(i).copied().unwrap_or(0.0);
                    let j = &self.joints[i];
                    let key = |a: &Real| {
                        let outside = *a < j.lower - 1e-12 || *a > j.upper + 1e-12;
                        (outside, (a - reference).abs())
                    };
                    [target - 2.0 * PI, target, target + 2.0 * PI]
                        .into_iter()
                        .min_by(|a, b| {
                            let (ka, kb) = (key(a), key(b));
                            ka.0.cmp(&kb.0).then(ka.1.total_cmp(&kb.1))
                        })
                        .expect("three candidates")
                })
                .collect();
            match self.limit_violation(&q, 1e-12) {
                None => {
                    let d: Real = q.iter().zip(near).map(|(a, b)| (a - b).powi(2)).sum();
                    if best.as_ref().is_none_or(|(bd, _)| d < *bd) {
                        best = Some((d, q));
                    }
                }
                Some(v) => {
                    first_violation.get_or_insert(v);
                }
            }
        }
        match best {
            Some((_, q)) => Ok(q
                .iter()
                .zip(&self.joints)
                .map(|(a, j)| a.clamp(j.lower, j.upper))
                .collect()),
            None => Err(first_violation.expect("a violation was recorded")),
        }
    }

    /// The joints of the finger at `q` with the fingertip's material point at `point` (hand
    /// frame, at `q`) moved by `d` (m, hand frame), into `out`: Gauss-Newton steps of that
    /// point's Jacobian from `q`, each the least joint motion that makes it (the fingertip may
    /// turn about the point). Allocation-free, for the command loop: what follows an object
    /// whose centre has moved by millimetres with a pose planned about its old centre, for any
    /// finger ([`Finger::shift_planar`] is the planar three-joint finger's exact one). For a
    /// finger in contact the point is the fingertip's at the contact: the fingertip then
    /// carries the object with it, where moving its centre alone could let it roll on the
    /// object instead; for a free finger, its centre ([`Finger::tip_centre`]). `false` (`out`
    /// still the last step's joints) when the point is not within a micrometre of its goal
    /// after [`SHIFT_STEPS`] steps (a goal out of reach), when a joint would move more than
    /// `|d|` over [`SHIFT_LEVER`] (a pose near a singular one, a stretched finger: its joints
    /// would swing for a fraction of a millimetre), or the finger has more than
    /// [`SHIFT_JOINTS`] joints; the result is not clamped to the joint limits.
    pub fn shift_point(&self, q: &[Real], point: &Vec3, d: &Vec3, out: &mut [Real]) -> bool {
        let n = self.dof();
        if n > SHIFT_JOINTS || q.len() < n || out.len() < n {
            return false;
        }
        out[..n].copy_from_slice(&q[..n]);
        // The point in the last joint's frame: it moves with the fingertip.
        let local = self.tip_frame(q).inverse() * nalgebra::Point3::from(*point);
        let goal = point + d;
        let mut columns = [Vec3::zeros(); SHIFT_JOINTS];
        let mut reached = false;
        for _ in 0..SHIFT_STEPS {
            let mut axes = [(Vec3::zeros(), Vec3::zeros()); SHIFT_JOINTS];
            let mut t = self.base;
            for (k, (j, &qi)) in self.joints.iter().zip(&out[..n]).enumerate() {
                t *= j.origin;
                axes[k] = (t.translation.vector, t.rotation * j.axis.into_inner());
                t *= Isometry3::from_parts(
                    Translation3::identity(),
                    UnitQuaternion::from_axis_angle(&j.axis, qi),
                );
            }
            let at = (t * local).coords;
            let e = goal - at;
            if e.norm() <= 1e-6 {
                reached = true;
                break;
            }
            let mut jjt = nalgebra::Matrix3::identity() * SHIFT_DAMPING;
            for (c, (o, a)) in columns.iter_mut().zip(&axes).take(n) {
                *c = a.cross(&(at - o));
                jjt += *c * c.transpose();
            }
            let Some(inverse) = jjt.try_inverse() else {
                return false;
            };
            let y = inverse * e;
            for (x, c) in out.iter_mut().zip(&columns).take(n) {
                *x += c.dot(&y);
            }
        }
        reached = reached || (goal - (self.tip_frame(&out[..n]) * local).coords).norm() <= 1e-6;
        let swing = q
            .iter()
            .zip(&out[..n])
            .fold(0.0_f64, |m, (a, b)| m.max((a - b).abs()));
        reached && swing * SHIFT_LEVER <= d.norm()
    }

    /// The joints of a planar three-joint finger at `q` with its fingertip centre moved by
    /// `d` in the hand's plane (m) and the cap axis kept (so the fingertip touches with the same
    /// point of its cap), the elbow on the same branch, each joint the representative nearest
    /// its angle in `q`, into `out`. Exact (closed form) and allocation-free: what follows an
    /// object whose centre has moved by `d` with a pose planned about its old centre. `false`
    /// (`out` unchanged) for a finger that is not planar with three joints, or a wrist moved
    /// out of reach; the result is not clamped to the joint limits.
    pub fn shift_planar(&self, q: &[Real], d: [Real; 2], out: &mut [Real]) -> bool {
        let Some(p) = self.planar.as_ref() else {
            return false;
        };
        if self.dof() != 3 || q.len() < 3 || out.len() < 3 {
            return false;
        }
        let (l1, l2) = (p.lengths[0], p.lengths[1]);
        let mut abs = [0.0; 3];
        let mut turned = 0.0;
        for i in 0..3 {
            turned += p.signs[i] * q[i];
            abs[i] = p.angles0[i] + turned;
        }
        // The wrist relative to the root, moved with the fingertip (the last link keeps its
        // direction).
        let wx = l1 * abs[0].cos() + l2 * abs[1].cos() + d[0];
        let wy = l1 * abs[0].sin() + l2 * abs[1].sin() + d[1];
        let r2 = wx * wx + wy * wy;
        let (lo, hi) = ((l1 - l2).abs(), l1 + l2);
        if r2 > hi * hi || r2 < lo * lo {
            return false;
        }
        let bend = ((r2 - l1 * l1 - l2 * l2) / (2.0 * l1 * l2))
            .clamp(-1.0, 1.0)
            .acos();
        let elbow = if wrap(abs[1] - abs[0]) >= 0.0 {
            bend
        } else {
            -bend
        };
        let a1 = wy.atan2(wx) - (l2 * elbow.sin()).atan2(l1 + l2 * elbow.cos());
        let moved = [a1, a1 + elbow, abs[2]];
        for i in 0..3 {
            let rel = if i == 0 {
                moved[0] - p.angles0[0]
            } else {
                (moved[i] - moved[i - 1]) - (p.angles0[i] - p.angles0[i - 1])
            };
            out[i] = q[i] + wrap(p.signs[i] * rel - q[i]);
        }
        true
    }

    /// The planar pose `(x, y, phi)` of the fingertip at `q` (planar fingers).
    pub fn planar_pose(&self, q: &[Real]) -> Option<(Real, Real, Real)> {
        self.planar.as_ref()?;
        let pose = self.fk(q);
        Some((
            pose.tip_centre.x,
            pose.tip_centre.y,
            pose.cap_axis.y.atan2(pose.cap_axis.x),
        ))
    }

    /// Derives the planar description if the chain is planar.
    fn planar_chain(&self) -> Option<PlanarChain> {
        let zero = vec![0.0; self.dof()];
        let pose = self.fk(&zero);
        let mut t = self.base;
        let mut signs = Vec::with_capacity(self.dof());
        for j in &self.joints {
            t *= j.origin;
            let a = t.rotation * j.axis.into_inner();
            if a.x.abs() > PLANAR_TOLERANCE || a.y.abs() > PLANAR_TOLERANCE {
                return None;
            }
            signs.push(a.z.signum());
        }
        let z = pose.joints[0].z;
        let mut points: Vec<Vec3> = pose.joints.clone();
        points.push(pose.tip_centre);
        if points.iter().any(|p| (p.z - z).abs() > PLANAR_TOLERANCE)
            || pose.cap_axis.z.abs() > PLANAR_TOLERANCE
        {
            return None;
        }
        let mut lengths = Vec::with_capacity(points.len() - 1);
        let mut angles0 = Vec::with_capacity(points.len() - 1);
        for w in points.windows(2) {
            let d = w[1] - w[0];
            lengths.push(d.norm());
            angles0.push(d.y.atan2(d.x));
        }
        // A zero-length link carries no angle: such a chain is not handled as planar.
        if lengths.iter().any(|l| *l <= PLANAR_TOLERANCE) {
            return None;
        }
        let last_link = angles0[angles0.len() - 1];
        let cap = pose.cap_axis.y.atan2(pose.cap_axis.x);
        Some(PlanarChain {
            z,
            root: [points[0].x, points[0].y],
            lengths,
            angles0,
            signs,
            cap_offset: wrap(cap - last_link),
        })
    }
}

/// How far (at most `probe`) a finger starting at joints `q` gets by `step(d, from)`, which
/// gives the joints at distance `d` from those at `from` (or `None`: not reachable from
/// there): `steps` steps, each from the last, then bisection to `probe / 256` between the last
/// reached and the first not.
fn reach(
    q: &[Real],
    probe: Real,
    steps: usize,
    mut step: impl FnMut(Real, &[Real]) -> Option<Vec<Real>>,
) -> Real {
    let mut q = q.to_vec();
    let mut reached = 0.0;
    let steps = steps.max(1);
    let h = probe / steps as Real;
    for k in 1..=steps {
        let d = h * k as Real;
        match step(d, &q) {
            Some(next) => {
                q = next;
                reached = d;
            }
            None => {
                let (mut lo, mut hi) = (reached, d);
                while hi - lo > probe / 256.0 {
                    let mid = 0.5 * (lo + hi);
                    match step(mid, &q) {
                        Some(next) => {
                            q = next;
                            lo = mid;
                        }
                        None => hi = mid,
                    }
                }
                return lo;
            }
        }
    }
    reached
}

impl Hand {
    /// A hand from fingers; ids must be unique.
    pub fn new(mut fingers: Vec<Finger>) -> Result<Self, HandError> {
        if fingers.is_empty() {
            return Err(HandError::Invalid {
                finger: 0,
                what: "the hand has no fingers".into(),
            });
        }
        fingers.sort_by_key(|f| f.id);
        if let Some(w) = fingers.windows(2).find(|w| w[0].id == w[1].id) {
            return Err(HandError::Invalid {
                finger: w[0].id,
                what: "appears twice".into(),
            });
        }
        Ok(Self { fingers })
    }

    /// The finger numbered `id`.
    pub fn finger(&self, id: u32) -> Option<&Finger> {
        self.fingers.iter().find(|f| f.id == id)
    }
}

/// Distance of the origin from the segment `a`-`b`.
pub(crate) fn segment_distance(a: &Vec3, b: &Vec3) -> Real {
    let ab = b - a;
    let l2 = ab.norm_squared();
    let u = if l2 > 0.0 {
        (-a.dot(&ab) / l2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (a + ab * u).norm()
}

/// A planar finger from link lengths: base at `(x, y)` in the hand's plane `z = 0`, first
/// link along world angle `yaw` at `q = 0`, joints about +z, links of the given lengths
/// (the last one ends at the fingertip centre, so it is the distal link plus the offset to
/// the sphere's centre).
pub fn planar_finger(
    id: u32,
    base: [Real; 3],
    lengths: &[Real],
    limits: &[[Real; 2]],
    tip_radius: Real,
    cap_half_angle: Real,
    home: Option<Vec<Real>>,
) -> Result<Finger, HandError> {
    let bad = |what: String| HandError::Invalid { finger: id, what };
    if lengths.len() < 2 {
        return Err(bad(format!(
            "needs at least 2 links (joints + fingertip offset), got {}",
            lengths.len()
        )));
    }
    if limits.len() != lengths.len() {
        return Err(bad(format!(
            "has {} links but {} joint limits",
            lengths.len(),
            limits.len()
        )));
    }
    if let Some((i, l)) = lengths
        .iter()
        .enumerate()
        .find(|(_, l)| !l.is_finite() || **l <= 0.0)
    {
        return Err(bad(format!("link {} has length {l}: must be > 0", i + 1)));
    }
    if base.iter().any(|x| !x.is_finite()) {
        return Err(bad(format!("base {base:?} is not finite")));
    }
    let z = Unit::new_unchecked(Vec3::z());
    let joints = limits
        .iter()
        .enumerate()
        .map(|(i, lim)| Joint {
            name: format!("j{}", i + 1),
            origin: if i == 0 {
                Isometry3::new(Vec3::new(base[0], base[1], 0.0), Vec3::z() * base[2])
            } else {
                Isometry3::translation(lengths[i - 1], 0.0, 0.0)
            },
            axis: z,
            lower: lim[0],
            upper: lim[1],
        })
        .collect();
    Finger::new(
        id,
        Isometry3::identity(),
        joints,
        Vec3::new(lengths[lengths.len() - 1], 0.0, 0.0),
        tip_radius,
        cap_half_angle,
        home,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn finger() -> Finger {
        planar_finger(
            1,
            [0.14, 0.0, PI],
            &[0.05, 0.04, 0.025],
            &[[-1.5, 1.5], [-2.5, 2.5], [-2.5, 2.5]],
            0.025,
            PI / 2.0,
            None,
        )
        .unwrap()
    }

    #[test]
    fn planar_fk_matches_link_sums() {
        let f = finger();
        assert!(f.planar.is_some());
        let q = [0.3, -0.7, 1.1];
        let pose = f.fk(&q);
        let (a1, a2, a3) = (PI + 0.3, PI + 0.3 - 0.7, PI + 0.3 - 0.7 + 1.1);
        let x = 0.14 + 0.05 * a1.cos() + 0.04 * a2.cos() + 0.025 * a3.cos();
        let y = 0.05 * a1.sin() + 0.04 * a2.sin() + 0.025 * a3.sin();
        assert!((pose.tip_centre - Vec3::new(x, y, 0.0)).norm() < 1e-15);
        let (_, _, phi) = f.planar_pose(&q).unwrap();
        assert!(wrap(phi - a3).abs() < 1e-12);
    }

    #[test]
    fn link_distance_is_that_of_the_nearest_link_outside_the_fingertip() {
        let f = finger();
        // Straight at the origin: links from x = 0.14 to 0.09 and 0.09 to 0.05; the distal
        // link (0.05 to the fingertip centre at 0.025) lies inside the fingertip sphere.
        let (d, link) = f.link_distance(&[0.0; 3]);
        assert!((d - 0.05).abs() < 1e-12 && link == 2, "{d} {link}");
        // Elsewhere: the same as the distance of densely sampled points of the links.
        for q in [
            [0.3, -0.7, 1.1],
            [-0.2, 0.9, -0.4],
            [1.0, 1.5, 0.2],
            [0.1, -1.9, 1.8],
        ] {
            let pose = f.fk(&q);
            let mut ends = pose.joints.clone();
            let last = *ends.last().unwrap();
            let along = pose.tip_centre - last;
            ends.push(last + along * (1.0 - f.tip_radius / along.norm()));
            let mut sampled = (Real::INFINITY, 0);
            for (i, w) in ends.windows(2).enumerate() {
                for k in 0..=10_000 {
                    let p = w[0] + (w[1] - w[0]) * (k as Real / 10_000.0);
                    if p.norm() < sampled.0 {
                        sampled = (p.norm(), i + 1);
                    }
                }
            }
            let (d, link) = f.link_distance(&q);
            assert!(
                d <= sampled.0 + 1e-12 && sampled.0 - d < 1e-6,
                "{q:?}: {d} vs {sampled:?}"
            );
            assert_eq!(link, sampled.1, "{q:?}");
        }
    }

    #[test]
    fn planar_ik_inverts_fk_on_both_branches() {
        let f = finger();
        for q in [[0.3, -0.7, 1.1], [-0.2, 0.9, -0.4], [1.0, 1.5, 0.2]] {
            let (x, y, phi) = f.planar_pose(&q).unwrap();
            let sol = f.ik_planar(x, y, phi, &q).unwrap();
            for (a, b) in sol.iter().zip(&q) {
                assert!((a - b).abs() < 1e-9, "{sol:?} vs {q:?}");
            }
        }
    }

    #[test]
    fn a_planar_shift_moves_the_fingertip_and_keeps_its_cap_axis() {
        let f = finger();
        for q in [[0.3, -0.7, 1.1], [-0.2, 0.9, -0.4], [1.0, 1.5, 0.2]] {
            let (x, y, phi) = f.planar_pose(&q).unwrap();
            let mut out = [0.0; 3];
            for d in [[1e-3, 0.0], [-0.8e-3, 2.5e-3], [0.0, 0.0]] {
                assert!(f.shift_planar(&q, d, &mut out));
                let (x2, y2, phi2) = f.planar_pose(&out).unwrap();
                assert!((x2 - x - d[0]).abs() < 1e-12, "{q:?} {d:?}");
                assert!((y2 - y - d[1]).abs() < 1e-12, "{q:?} {d:?}");
                assert!(wrap(phi2 - phi).abs() < 1e-12);
                // The same elbow branch: a small move moves the joints a little.
                for (a, b) in out.iter().zip(&q) {
                    assert!((a - b).abs() < 0.2, "{out:?} vs {q:?}");
                }
            }
        }
        // Out of reach: refused, `out` untouched.
        let mut out = [7.0; 3];
        assert!(!f.shift_planar(&[0.0; 3], [1.0, 0.0], &mut out));
        assert_eq!(out, [7.0; 3]);
    }

    #[test]
    fn the_reach_along_a_direction_ends_at_the_workspace_or_a_limit() {
        let f = finger();
        let q = [0.3, -0.7, 1.1];
        let probe = 5e-3;
        let centre = f.fk(&q).tip_centre;
        // Toward the finger's root: inside the workspace, the whole probe.
        let root = f.fk(&q).joints[0];
        let inward = (root - centre).normalize();
        assert!((f.reach_along(&q, &inward, probe) - probe).abs() < 1e-12);
        // A straight finger cannot reach further out along its own length.
        let straight = [0.0, 0.0, 0.0];
        let c = f.fk(&straight).tip_centre;
        let out = (c - f.fk(&straight).joints[0]).normalize();
        assert!(f.reach_along(&straight, &out, probe) < probe / 100.0);
        // Joints held at their angles by their limits: no reach at all.
        let mut held = f.clone();
        for (j, a) in held.joints.iter_mut().zip(q) {
            (j.lower, j.upper) = (a, a);
        }
        assert_eq!(held.reach_along(&q, &inward, probe), 0.0);
        // With the cap axis kept (the planner's measure): the same inside the workspace, in
        // two steps or eight, with the fingertip's orientation unchanged at the end.
        for steps in [2, REACH_STEPS] {
            assert!((f.reach_along_planar(&q, &inward, probe, steps) - probe).abs() < 1e-12);
        }
        assert_eq!(
            held.reach_along_planar(&q, &inward, probe, REACH_STEPS),
            0.0
        );
        // A joint 1 mm of fingertip travel from its limit stops it there: no redundancy is
        // left to go round it (the position-only reach goes on with the other joints).
        let (x, y, phi) = f.planar_pose(&q).unwrap();
        let end = f
            .ik_planar(x + inward.x * 1e-3, y + inward.y * 1e-3, phi, &q)
            .unwrap();
        let (k, _) = end
            .iter()
            .zip(&q)
            .enumerate()
            .max_by(|a, b| (a.1.0 - a.1.1).abs().total_cmp(&(b.1.0 - b.1.1).abs()))
            .unwrap();
        let mut limited = f.clone();
        if end[k] > q[k] {
            limited.joints[k].upper = end[k];
        } else {
            limited.joints[k].lower = end[k];
        }
        let reach = limited.reach_along_planar(&q, &inward, probe, REACH_STEPS);
        assert!((reach - 1e-3).abs() < probe / 200.0, "{reach}");
        assert!(limited.reach_along(&q, &inward, probe) > 2e-3);
        // Straight along its own length, it cannot press on at all.
        assert!(f.reach_along_planar(&straight, &out, probe, REACH_STEPS) < probe / 100.0);
    }

    #[test]
    fn unreachable_and_limited_targets_are_errors() {
        let f = finger();
        assert!(matches!(
            f.ik_planar(-0.2, 0.0, PI, &[0.0; 3]),
            Err(IkError::OutOfReach { .. })
        ));
        let tight = planar_finger(
            1,
            [0.14, 0.0, PI],
            &[0.05, 0.04, 0.025],
            &[[-0.1, 0.1], [0.5, 0.6], [-0.1, 0.1]],
            0.025,
            PI / 2.0,
            Some(vec![0.0, 0.55, 0.0]),
        )
        .unwrap();
        assert!(matches!(
            tight.ik_planar(0.05, 0.0, PI, &[0.0; 3]),
            Err(IkError::JointLimit { .. })
        ));
    }

    #[test]
    fn bad_descriptions_name_the_finger() {
        let e = planar_finger(
            7,
            [0.0; 3],
            &[0.05, -1.0],
            &[[0.0, 1.0]; 2],
            0.02,
            1.0,
            None,
        )
        .unwrap_err();
        assert!(e.to_string().contains("finger 7") && e.to_string().contains("link 2"));
        let e = planar_finger(
            3,
            [0.0; 3],
            &[0.05, 0.02],
            &[[1.0, 0.0]; 2],
            0.02,
            1.0,
            None,
        )
        .unwrap_err();
        assert!(e.to_string().contains("limits"), "{e}");
        let e = planar_finger(3, [0.0; 3], &[0.05, 0.02], &[[0.0, 1.0]; 2], 0.0, 1.0, None)
            .unwrap_err();
        assert!(e.to_string().contains("radius"), "{e}");
    }

    #[test]
    fn manipulability_vanishes_when_stretched() {
        let f = finger();
        assert!(f.manipulability(&[0.0, 0.0, 0.0]) < 1e-12);
        assert!(f.manipulability(&[0.0, 1.0, 0.0]) > 1e-4);
    }
}
