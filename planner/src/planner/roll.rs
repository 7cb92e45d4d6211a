//! The planar scenario's rolling step ([`Scenario::roll`]): each contact's next contact in
//! its ICR, the fingertip placed by inverse kinematics, and why a finger is blocked.

use std::f64::consts::PI;

use icrflow_grasp::icr::IcrError;
use icrflow_grasp::math::{Real, Vec3};

use super::{Contact, PlanError, QUALITY_SLACK, Roll, Scenario};
use crate::hand::{Finger, IkError, wrap};

/// Why a finger cannot take a step.
#[derive(Debug, Clone, PartialEq)]
pub(super) enum Blocked {
    Cap {
        gamma: Real,
    },
    Ik(IkError),
    Mobility {
        value: Real,
    },
    Squeeze {
        reach: Real,
        needed: Real,
    },
    Jump {
        joint: usize,
        degrees: Real,
    },
    OutOfRegion {
        from: String,
        past: String,
    },
    Drag {
        step: Real,
        still: String,
        to: String,
        drag: Real,
    },
}

/// ICR members tried, nearest the target first, for a finger's next contact. One: trying
/// farther members lets the contacts drift from where the fingers' rolling room was planned,
/// which ends in overlapping fingertips and stranded fingers on the shipped scenarios.
const NEXT_CONTACT_TRIES: usize = 1;

/// Largest joint motion accepted in one rolling step (rad): more means the inverse
/// kinematics jumped to the other elbow branch, which the finger cannot do in contact.
const MAX_JOINT_STEP: Real = 0.5;

/// Largest turn of a contact point in the world, about the object's centre, in one rolling
/// step (rad, 10 deg): a contact that rolls short of its stay-still point (that point is out
/// of its ICR) moves its fingertip around the object by the difference, along the straight
/// joint-space move of the step instead of an arc; at 10 deg the fingertip's path stays within
/// about 0.3 mm of the arc on the paper's sphere. Steps of 5 deg (the paper's) never come near.
pub const MAX_DRAG: Real = 10.0 * PI / 180.0;

/// Largest object rotation of one rolling step (rad, 30 deg): one step is one straight
/// joint-space move, and a joint may move at most [`MAX_JOINT_STEP`] (28.6 deg) in one; far
/// below the half turn at which a contact's stay-still point no longer says which way it
/// rolled. `plan.step_deg` is bounded by the same.
pub const MAX_STEP: Real = 30.0 * PI / 180.0;

/// An angle in degrees for messages, rounded to a millionth (30, not 29.999999999999996).
pub(super) fn degrees(x: Real) -> String {
    format!("{}", (x.to_degrees() * 1e6).round() / 1e6)
}

impl std::fmt::Display for Blocked {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Blocked::Cap { gamma } => write!(
                f,
                "the contact would leave the fingertip cap (cap angle {:.1} deg)",
                gamma.to_degrees()
            ),
            Blocked::Ik(e) => write!(f, "{e}"),
            Blocked::Mobility { value } => {
                write!(f, "mobility lost (manipulability {value:.3e})")
            }
            Blocked::Squeeze { reach, needed } => write!(
                f,
                "the finger could press only {:.2} mm further into the object (needs {:.2} mm)",
                reach * 1e3,
                needed * 1e3
            ),
            Blocked::Jump { joint, degrees } => write!(
                f,
                "joint {} would have to jump by {degrees:.1} deg (the other elbow branch)",
                joint + 1
            ),
            Blocked::OutOfRegion { from, past } => write!(
                f,
                "its contact would roll out of its ICR on the way from {from} (past {past})"
            ),
            Blocked::Drag {
                step,
                still,
                to,
                drag,
            } => write!(
                f,
                "its contact would roll out of its ICR: turning the object by {:.1} deg takes it to {still}, outside the region, and rolling to {to} instead would drag the fingertip {:.1} deg around the object in one step (at most {} deg)",
                step.to_degrees(),
                drag.abs().to_degrees(),
                degrees(MAX_DRAG)
            ),
        }
    }
}

impl Scenario<'_> {
    /// The fingertip pose for a contact at `c` with cap angle `gamma`: centre and phi.
    fn tip_pose(&self, finger: &Finger, c: usize, theta: Real, gamma: Real) -> (Vec3, Real) {
        let (p, n) = self.world(c, theta);
        let centre = p + finger.tip_radius * n;
        let inward = (-n.y).atan2(-n.x);
        (centre, wrap(inward - gamma))
    }

    /// Joint angles for finger `finger` touching `c` at cap angle `gamma`, or why not. With
    /// `continuous`, the joints must stay within [`MAX_JOINT_STEP`] of `near`.
    pub(super) fn place(
        &self,
        finger: &Finger,
        c: usize,
        theta: Real,
        gamma: Real,
        near: &[Real],
        continuous: bool,
    ) -> Result<Vec<Real>, Blocked> {
        let s = &self.settings;
        if gamma.abs() > finger.cap_half_angle - s.cap_margin {
            return Err(Blocked::Cap { gamma });
        }
        let (centre, phi) = self.tip_pose(finger, c, theta, gamma);
        let q = finger
            .ik_planar(centre.x, centre.y, phi, near)
            .map_err(Blocked::Ik)?;
        let jump = q
            .iter()
            .zip(near)
            .map(|(a, b)| (a - b).abs())
            .enumerate()
            .find(|(_, d)| *d > MAX_JOINT_STEP);
        if let (true, Some((joint, d))) = (continuous, jump) {
            return Err(Blocked::Jump {
                joint,
                degrees: d.to_degrees(),
            });
        }
        let m = finger.manipulability(&q);
        if m < s.min_manipulability {
            return Err(Blocked::Mobility { value: m });
        }
        if s.squeeze_reserve > 0.0 {
            // Checked in two steps (half way, all the way); where they fall short, measured
            // finely, which decides (and says how far it gets).
            let short = |reach: Real| reach < s.squeeze_reserve * (1.0 - 1e-6);
            if short(self.squeeze_reserve(finger, c, theta, &q, s.squeeze_reserve, 2)) {
                let reach = self.squeeze_reserve(
                    finger,
                    c,
                    theta,
                    &q,
                    s.squeeze_reserve,
                    crate::hand::REACH_STEPS,
                );
                if short(reach) {
                    return Err(Blocked::Squeeze {
                        reach,
                        needed: s.squeeze_reserve,
                    });
                }
            }
        }
        Ok(q)
    }

    /// How far (m, at most `probe`) `finger` at joints `q`, touching candidate `c` with the
    /// object at `theta`, can press further into the object along the inward normal: for a
    /// planar finger in the hand's plane with its fingertip's cap axis kept
    /// ([`Finger::reach_along_planar`]: pressing on with the same point of the cap), for
    /// others by the fingertip centre alone ([`Finger::reach_along`]); the path followed in
    /// `steps` steps (see [`Finger::reach_along_planar`]).
    #[allow(clippy::too_many_arguments)]
    pub fn squeeze_reserve(
        &self,
        finger: &Finger,
        c: usize,
        theta: Real,
        q: &[Real],
        probe: Real,
        steps: usize,
    ) -> Real {
        let (_, n) = self.world(c, theta);
        let mut inward = -n;
        if finger.planar.is_some() {
            inward.z = 0.0;
        }
        match inward.try_normalize(1e-12) {
            Some(d) if finger.planar.is_some() && finger.dof() == 3 => {
                finger.reach_along_planar(q, &d, probe, steps)
            }
            Some(d) => finger.reach_along(q, &d, probe),
            None => 0.0,
        }
    }

    /// Signed arc length (counter-clockwise positive) along the section from `a` to `b`,
    /// from the chord and the turn of the normal (exact on circles).
    pub(super) fn arc(&self, a: usize, b: usize) -> Real {
        if a == b {
            return 0.0;
        }
        let cands = self.problem.candidates();
        let (na, nb) = (cands.normals[a], cands.normals[b]);
        let turn = wrap(nb.y.atan2(nb.x) - na.y.atan2(na.x));
        let chord = (cands.points[b] - cands.points[a]).xy().norm();
        let half = 0.5 * turn.abs();
        let length = if half < 1e-12 {
            chord
        } else {
            chord * half / half.sin()
        };
        if turn == 0.0 {
            // A flat stretch: the sense of travel from the positions.
            let (pa, pb) = (cands.points[a] - self.centre, cands.points[b] - self.centre);
            length * pa.xy().perp(&pb.xy()).signum()
        } else {
            length * turn.signum()
        }
    }

    /// The members of a region (sorted candidate indices) whose neighbours, to
    /// [`Settings::region_erosion`] rings of the candidates' adjacency, are all members too.
    pub(super) fn erode(&self, members: &[u32]) -> Vec<u32> {
        self.problem
            .candidates()
            .adjacency
            .erode(members, self.settings.region_erosion)
    }

    /// The body point that stays still in the world when the object turns by `step`.
    pub(super) fn behind(&self, c: usize, step: Real) -> Vec3 {
        let r = nalgebra::Rotation3::from_axis_angle(&Vec3::z_axis(), -step);
        self.centre + r * (self.problem.candidates().points[c] - self.centre)
    }

    /// The candidate nearest to `target`, found by walking the neighbourhood graph from
    /// `from` to ever nearer neighbours (a local search: it touches only the points on the
    /// way).
    pub(super) fn walk(&self, from: usize, target: &Vec3) -> usize {
        match self.walk_within(from, target, None) {
            Ok(at) | Err(at) => at,
        }
    }

    /// [`Self::walk`], every point on the way (but `from`) checked to be in `region` (sorted
    /// candidate indices, if given): the end, or `Err` with the first point outside.
    fn walk_within(
        &self,
        from: usize,
        target: &Vec3,
        region: Option<&[u32]>,
    ) -> Result<usize, usize> {
        walk_candidates(self.problem.candidates(), from, target, region)
    }

    /// Why contact `c` cannot travel to `n` in one rolling step of `step` from `theta`, if it
    /// cannot: every candidate on the way along the section must be in its `region`, and
    /// where `n` falls short of the stay-still point `target` (the point itself is outside the
    /// region), the fingertip is dragged around the object by the difference within the step,
    /// at most [`MAX_DRAG`].
    fn travel(
        &self,
        c: usize,
        n: usize,
        target: &Vec3,
        theta: Real,
        step: Real,
        region: &icrflow_grasp::icr::Region,
    ) -> Option<Blocked> {
        let pts = &self.problem.candidates().points;
        if let Err(out) = self.walk_within(c, &pts[n], Some(&region.members)) {
            return Some(Blocked::OutOfRegion {
                from: self.describe(c),
                past: self.describe(out),
            });
        }
        // How far the contact point turns in the world about the object's centre.
        let world = |k: usize, at: Real| {
            let (p, _) = self.world(k, at);
            p.y.atan2(p.x)
        };
        let drag = wrap(world(n, theta + step) - world(c, theta));
        if drag.abs() > MAX_DRAG {
            let still = self.walk(c, target);
            return Some(Blocked::Drag {
                step,
                still: self.describe(still),
                to: self.describe(n),
                drag,
            });
        }
        None
    }

    /// One rolling step of every contact, the object turning from `theta` by `step`: the new
    /// contacts and their quality, or the first finger that cannot move and why.
    pub fn roll(&self, contacts: &[Contact], theta: Real, step: Real) -> Result<Roll, PlanError> {
        if !(step > 0.0 && step <= MAX_STEP) {
            return Err(PlanError::Settings(format!(
                "a rolling step of {} deg: one step turns the object by more than 0 and at most {} deg (one straight joint-space move)",
                degrees(step),
                degrees(MAX_STEP)
            )));
        }
        let idx: Vec<usize> = contacts.iter().map(|c| c.candidate).collect();
        let eval = self.problem.evaluate(&idx)?;
        let regions = match self.problem.icrs(&idx, &eval, self.settings.alpha) {
            Ok(r) => r,
            Err(e @ (IcrError::NotForceClosure | IcrError::MarginAboveQuality { .. })) => {
                return Ok(Roll::Stuck(format!("the grasp lost its margin: {e}")));
            }
            Err(e) => return Ok(Roll::Stuck(e.to_string())),
        };
        let regions: Vec<icrflow_grasp::icr::Region> = if self.settings.region_erosion == 0 {
            regions
        } else {
            regions
                .into_iter()
                .map(|r| icrflow_grasp::icr::Region {
                    members: self.erode(&r.members),
                    ..r
                })
                .collect()
        };
        let mut next = Vec::with_capacity(contacts.len());
        for (i, (c, region)) in contacts.iter().zip(&regions).enumerate() {
            let f = self.finger(c.finger);
            let target = self.behind(c.candidate, step);
            // The ICR members nearest the target, tried in order: the first the finger can
            // reach by rolling is the next contact.
            let pts = &self.problem.candidates().points;
            let mut order: Vec<usize> = region.members.iter().map(|&m| m as usize).collect();
            order.sort_by(|&a, &b| {
                (pts[a] - target)
                    .norm_squared()
                    .total_cmp(&(pts[b] - target).norm_squared())
                    .then(a.cmp(&b))
            });
            let mut first_block = None;
            let mut placed = None;
            for &n in order.iter().take(NEXT_CONTACT_TRIES) {
                if let Some(why) = self.travel(c.candidate, n, &target, theta, step, region) {
                    first_block.get_or_insert(why);
                    continue;
                }
                let gamma = c.gamma - self.arc(c.candidate, n) / f.tip_radius;
                match self.place(f, n, theta + step, gamma, &c.q, true) {
                    Ok(q) => {
                        placed = Some(Contact {
                            finger: c.finger,
                            candidate: n,
                            gamma,
                            q,
                        });
                        break;
                    }
                    Err(b) => {
                        first_block.get_or_insert(b);
                    }
                }
            }
            match (placed, first_block) {
                (Some(contact), _) => next.push(contact),
                (None, Some(b)) => return Ok(Roll::Blocked(i, b.to_string())),
                (None, None) => {
                    let why = match self.settings.region_erosion {
                        0 => "its ICR is empty".to_string(),
                        n => format!("its ICR shrunk by {n} ring(s) of candidates is empty"),
                    };
                    return Ok(Roll::Blocked(i, why));
                }
            }
        }
        if let Some(e) = self.overlap(&next) {
            return Ok(Roll::Stuck(format!("rolling on: {e}")));
        }
        let (quality, _) = self.quality(&next)?;
        if quality < self.settings.alpha * (1.0 - QUALITY_SLACK) {
            return Ok(Roll::Stuck(format!(
                "the next grasp would have quality {quality:.6} < alpha = {} (a defect: the ICRs guarantee the margin)",
                self.settings.alpha
            )));
        }
        Ok(Roll::Moved(next, quality))
    }
}

/// The candidate of `cands` nearest to `target`, found by walking their adjacency from `from`
/// to ever nearer neighbours (a local search: it touches only the points on the way), every
/// point on the way (but `from`) checked to be in `region` (sorted candidate indices, if
/// given): the end, or `Err` with the first point outside.
pub(crate) fn walk_candidates(
    cands: &icrflow_grasp::object::SurfaceSamples,
    from: usize,
    target: &Vec3,
    region: Option<&[u32]>,
) -> Result<usize, usize> {
    let dist = |i: usize| (cands.points[i] - target).norm_squared();
    let mut at = from;
    loop {
        let next = cands
            .adjacency
            .neighbours(at)
            .iter()
            .map(|&m| m as usize)
            .min_by(|&a, &b| dist(a).total_cmp(&dist(b)));
        match next {
            Some(n) if dist(n) < dist(at) => {
                if region.is_some_and(|r| r.binary_search(&(n as u32)).is_err()) {
                    return Err(n);
                }
                at = n;
            }
            _ => return Ok(at),
        }
    }
}
