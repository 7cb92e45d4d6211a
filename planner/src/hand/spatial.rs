//! Kinematics of any chain (what the spatial planner uses): inverse kinematics of the fingertip
//! centre by damped least squares, with the joints centred by the finger's redundancy, the
//! shift of a fingertip point, and the reach along a direction.

use icrflow_grasp::math::{Isometry3, Real, UnitQuaternion, Vec3};
use nalgebra::{DMatrix, DVector, Translation3};

use super::{Finger, IkError, REACH_STEPS, reach};

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

impl Finger {
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
}
