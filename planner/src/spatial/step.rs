//! The spatial rolling step ([`SpatialScenario::roll`]): each finger's joint rates integrated
//! over the step's parts, its contact kept in its ICR, its pose checked.

use icrflow_grasp::icr::IcrError;
use icrflow_grasp::math::{Real, Vec3};
use nalgebra::{DMatrix, DVector};

use super::{Roll, STEERS, SpatialScenario, Steer, Touch, pinch, surface};
use crate::hand::Finger;
use crate::planner::{PlanError, QUALITY_SLACK};

/// How much nearer to a pinch ([`pinch::unbalanced`], of unit-sum normal forces) the grasp
/// left by releasing one of two clashing fingers must come than the other's for that finger
/// to be released: a tenth of the unit force (the Allegro's ring and thumb at right angles
/// leave 0.71, a pinch 0).
pub const PINCH_PREFERENCE: Real = 0.1;

/// How far (m) one integration part may leave a fingertip centre off the surface before the
/// Newton correction puts it back (the correction turns the fingertip a little, which is
/// slip); a part that leaves it farther is halved.
const DRIFT: Real = 1e-6;

/// Newton corrections of the fingertip centre onto the surface per integration part.
const CORRECTIONS: usize = 3;

impl SpatialScenario<'_> {
    /// Where finger `f` at `q` touches the surface with the object at `theta`: the body
    /// point, normal and signed distance of the fingertip centre from the surface.
    pub(super) fn touch_of(&self, f: &Finger, q: &[Real], theta: Real) -> surface::Closest {
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
    pub(super) fn pose_check(
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

    /// Finger `f` placed by inverse kinematics touching the surface at the body point nearest
    /// `p`, with the object at `theta`, from `seed`: the pose with its joints centred, or, if
    /// `nearest`, the pose nearest `seed` (a finger already in contact there: turning its
    /// fingertip about its centre toward the middle of the joint ranges would spin it on the
    /// object).
    pub(super) fn place(
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
    pub(super) fn roll_finger(
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
            // The finger that rolls into the other stops (a switch may free it).
            return Ok(
                match self.stopped_by_clash(touches, &next, theta + step, fingers) {
                    Some(i) => Roll::Blocked(i, why),
                    None => Roll::Stuck(format!("rolling on: {why}")),
                },
            );
        }
        let floor = self.settings.alpha * (1.0 - QUALITY_SLACK);
        let grid = self.grid_quality(&next)?;
        if grid < floor {
            return Ok(Roll::Stuck(format!(
                "the next grasp's candidates would have quality {grid:.6} < alpha = {} (a defect: the ICRs guarantee the margin)",
                self.settings.alpha
            )));
        }
        let quality = self.quality(&next)?;
        if quality < floor {
            return Ok(match self.lost_by(touches, &next)? {
                Some(i) => Roll::Blocked(
                    i,
                    format!(
                        "rolling on, its contact would take the grasp to alpha* {quality:.4} < alpha = {} where the fingertips touch (its candidates' grasp keeps {grid:.4}: the contacts lie between the candidates)",
                        self.settings.alpha
                    ),
                ),
                None => Roll::Stuck(format!(
                    "the next grasp would keep alpha* {quality:.4} < alpha = {} where the fingertips touch",
                    self.settings.alpha
                )),
            });
        }
        if let Some((i, why)) = self.one_off(&next)? {
            return Ok(Roll::Blocked(i, why));
        }
        Ok(Roll::Moved(next, quality))
    }
}

impl SpatialScenario<'_> {
    /// Which contact of `after` (rolled from `before`, the object at `theta`) stops for the
    /// clash of `fingers`: the one in contact of the two (the other at its home pose). Of two
    /// in contact, the one without which the others' normal forces come nearer to squeezing
    /// the object alone ([`pinch::unbalanced`], by more than [`PINCH_PREFERENCE`]): the grasp
    /// keeps its pinch through the switch; else the one whose own step brings it into the
    /// other (the clash gone with it kept where it was and not with the other kept), else the
    /// one whose fingertip moved farther. (Stopping the first in the grasp's order instead
    /// released the Allegro's index at the sphere's pole for the thumb rolling up to it, in
    /// plans made again from the estimate, leaving middle, ring and thumb to hold the sphere
    /// along its axis by friction alone: in MuJoCo under load the middle finger lost its
    /// contact and the sphere was dropped in 6 of 18 runs, 2026-12-05; so too, once in 18
    /// lockstep runs, with the finger whose own step made the clash stopping.)
    fn stopped_by_clash(
        &self,
        before: &[Touch],
        after: &[Touch],
        theta: Real,
        fingers: [u32; 2],
    ) -> Option<usize> {
        let of = |finger: u32| after.iter().position(|t| t.finger == finger);
        let (a, b) = match (of(fingers[0]), of(fingers[1])) {
            (Some(a), Some(b)) if a != b => (a, b),
            (Some(a), _) => return Some(a),
            (None, b) => return b,
        };
        let without = |i: usize| {
            let rest: Vec<(Vec3, Vec3)> = after
                .iter()
                .enumerate()
                .filter(|&(j, _)| j != i)
                .map(|(_, t)| (t.point, t.normal))
                .collect();
            pinch::unbalanced(self.problem.frame(), &rest)
        };
        let (rest_a, rest_b) = (without(a), without(b));
        if rest_a + PINCH_PREFERENCE < rest_b {
            return Some(a);
        }
        if rest_b + PINCH_PREFERENCE < rest_a {
            return Some(b);
        }
        let clears_kept = |i: usize| {
            let mut kept = after.to_vec();
            kept[i] = before[i].clone();
            self.clash(&kept, theta).is_none()
        };
        match (clears_kept(a), clears_kept(b)) {
            (true, false) => Some(a),
            (false, true) => Some(b),
            _ => {
                let moved = |i: usize| {
                    let f = self.finger(after[i].finger);
                    (f.tip_centre(&after[i].q) - f.tip_centre(&before[i].q)).norm()
                };
                Some(if moved(b) > moved(a) { b } else { a })
            }
        }
    }

    /// Which contact's roll from `before` to `after` lost the margin where the fingertips
    /// touch: the one whose contact put back where it was restores the most quality (`None`
    /// without contacts).
    fn lost_by(&self, before: &[Touch], after: &[Touch]) -> Result<Option<usize>, PlanError> {
        let mut best: Option<(usize, Real)> = None;
        let mut trial = after.to_vec();
        for (i, t) in before.iter().enumerate() {
            trial[i] = t.clone();
            let q = self.quality(&trial)?;
            trial[i] = after[i].clone();
            if best.is_none_or(|(_, b)| q > b) {
                best = Some((i, q));
            }
        }
        Ok(best.map(|(i, _)| i))
    }
}

/// The smallest singular value of finger `f`'s fingertip-centre Jacobian at `q` (m per rad).
pub fn mobility(f: &Finger, q: &[Real]) -> Real {
    let jac = f.jacobian6(q).rows(0, 3).into_owned();
    jac.singular_values().min()
}
