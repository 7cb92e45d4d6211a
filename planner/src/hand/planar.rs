//! Planar fingers: the planar description of a chain in a horizontal plane, its closed-form
//! inverse kinematics and exact shift, its reach with the cap axis kept, and planar fingers
//! from link lengths.

use icrflow_grasp::math::{Isometry3, Real, Vec3};
use nalgebra::Unit;
use std::f64::consts::PI;

use super::{Finger, HandError, IkError, Joint, reach, wrap};

/// Tolerance (m, rad) for treating a chain as planar.
const PLANAR_TOLERANCE: Real = 1e-9;

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

impl Finger {
    /// Whether the finger is a planar three-joint chain in the hand's plane `z = 0`: what the
    /// planar planner ([`crate::planner`]) takes; others go to [`crate::spatial`].
    pub fn in_hand_plane(&self) -> bool {
        self.dof() == 3 && self.planar.as_ref().is_some_and(|p| p.z.abs() <= 1e-9)
    }

    /// [`Finger::reach_along`] for a planar three-joint finger with the cap axis kept (the
    /// fingertip presses with the same point of its cap, as a hand pressing on without turning its
    /// fingertip does): with no redundancy left, a joint at its limit or a straight finger stops
    /// it. `dir` is taken in the hand's plane. Each step is the closed form ([`Finger::ik_planar`])
    /// on the branch of the last, no joint moving more than 0.5 rad at once; 0 for a finger that is
    /// not planar. `steps` sets how finely the path is followed
    /// ([`REACH_STEPS`](super::REACH_STEPS) to measure; fewer to check that `probe` is reached,
    /// which then costs `steps` solutions).
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
                        .unwrap_or(target) // never: three candidates
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
            #[expect(
                clippy::expect_used,
                reason = "no candidate within the limits: each recorded its violation"
            )]
            None => Err(first_violation.expect("a violation was recorded")),
        }
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
    pub(super) fn planar_chain(&self) -> Option<PlanarChain> {
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
