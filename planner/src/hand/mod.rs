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
//!
//! The planar fingers' kinematics (closed-form inverse kinematics, the planar shift, the
//! planar description) are in `planar.rs`; that of any chain (damped least squares, joints
//! centred by the redundancy, the shift of a fingertip point, the reach along a direction) in
//! `spatial.rs`; a finger's body as capsules, and the gap between two, in `capsules.rs`.

mod capsules;
mod planar;
mod spatial;

use icrflow_grasp::math::{Isometry3, Real, UnitQuaternion, Vec3};
use nalgebra::{DMatrix, DVector, Translation3, Unit};
use std::f64::consts::PI;

pub use capsules::{Capsule, gap, segment_segment_distance};
pub use planar::{PlanarChain, planar_finger};
pub use spatial::{CENTRING_STEP, CENTRING_STEPS, SHIFT_JOINTS, SHIFT_LEVER, SHIFT_STEPS};

/// Steps along which [`Finger::reach_along`] and [`Finger::reach_along_planar`] follow a path
/// to measure a reserve.
pub const REACH_STEPS: usize = 8;

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

    /// An upper bound (m) of how far the fingertip centre moves along the straight joint-space
    /// move from `from` to `to`: each joint's change times the farthest the fingertip centre
    /// can be from that joint's axis (the lengths of the joint origins beyond it and the
    /// fingertip's offset, summed; every joint turns about an axis through its origin).
    pub fn tip_travel_bound(&self, from: &[Real], to: &[Real]) -> Real {
        let mut beyond = self.tip.norm();
        let mut bound = 0.0;
        for (j, joint) in self.joints.iter().enumerate().rev() {
            if let (Some(a), Some(b)) = (from.get(j), to.get(j)) {
                bound += (b - a).abs() * beyond;
            }
            beyond += joint.origin.translation.vector.norm();
        }
        bound
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
