//! Spatial rolling without slipping of a fingertip sphere on a smooth convex object.
//!
//! # The contact kinematics
//! Work in the object's frame (the object still; every velocity below is relative to it). The
//! fingertip is a sphere of radius `r_f`, centre `b`, turning with angular velocity `omega`
//! (the fingertip's minus the object's). It touches the surface at `p` with outward unit
//! normal `n = n(p)`, so `b = p + r_f n` ([`super::surface`]).
//!
//! - **No slip**: the fingertip's material point at the contact does not move,
//!   `b' + omega x (p - b) = 0`, and with `p - b = -r_f n`: **`b' = r_f omega x n`**. Only the
//!   tangential part of `omega` rolls (its part along `n` spins the fingertip in place).
//! - **The contact on the object**: differentiating `b = p + r_f n(p)` with the shape
//!   operator `W = dn/dp` ([`super::surface::Convex::shape_operator`]): `b' = (I + r_f W) p'`,
//!   so **`p' = (W + I / r_f)^-1 (omega x n)`** on the tangent plane (`W` is positive
//!   semi-definite on a convex surface, so the inverse exists), and **`n' = W p'`**. On a
//!   sphere of radius `R`: `p' = (R r_f / (R + r_f)) omega x n`.
//! - **The contact on the fingertip**: its position in the fingertip's frame is `u = R_f^T
//!   (p - b)`; `R_f u' = (p' - b') - omega x (p - b) = p' - b' + b' = p'`. The contact moves
//!   over the fingertip at the same speed as over the object: equal arc lengths, the
//!   statement of rolling without slipping (Montana's equations for a sphere, 1988, in this
//!   form).
//!
//! A finger of the hand drives this through its joints: the velocity of the fingertip's
//! material point at the contact is `A q'`, `A = J_v + r_f [n]x J_w`
//! ([`crate::hand::Finger::contact_jacobian`]), which must equal the object's material
//! point's, `v_o + w_o x (p - c)`: three equations on the finger's joint rates. A four-joint
//! finger keeps one free direction, along which it rolls on the object (the object still) in
//! the one direction its joints allow.
//!
//! # The object turned by the fingers
//! The other way round, as the pipeline's kinematic plant and its estimator use it
//! ([`Turning`]): the object held at its centre `c` and turning about the unit axis `a`, a
//! finger in contact at `p` (hand frame) moves its joints over a tick, its fingertip frame
//! from `(R_1, b_1)` to `(R_2, b_2)`. Its material point at the contact moves by
//! `d = b_2 - b_1 + (R_2 R_1^T - I)(p - b_1)`; the object's material point there by
//! `dtheta a x (p - c)` to first order. Without slipping the two are equal; the rotation that
//! comes nearest, in least squares over the fingers `i` in contact, is
//! `dtheta = sum_i (a x (p_i - c)) . d_i / sum_i |a x (p_i - c)|^2`: each finger's
//! tangential displacement about the axis, weighted by its lever arm (a contact on the axis
//! turns nothing). On a plan's own joint motions the fingers agree and this is the plan's
//! rotation (`tests`: the Allegro's plan of the sphere, to its integration's accuracy).

use icrflow_grasp::math::{Real, Vec3};
use nalgebra::{Matrix2, Rotation3, Unit, Vector2};

use super::surface::Convex;
use crate::hand::Finger;

/// An object turning about an axis through its centre of mass, which is held at `held` in the
/// hand frame (the spatial planner's model holds it at the origin): where fingertips touch it
/// and how far their rolling turns it ([`Turning::turn`]).
#[derive(Debug, Clone, Copy)]
pub struct Turning<'a> {
    /// The surface the fingertips roll on (body frame).
    pub surface: &'a Convex,
    /// The object's centre of mass (body frame).
    pub centre: Vec3,
    /// The unit axis (hand frame) it turns about.
    pub axis: Unit<Vec3>,
    /// Where the centre of mass is (hand frame): the origin in the plan; elsewhere when the
    /// object has moved from there (the estimator's, by the pose measurements).
    pub held: Vec3,
}

/// Where a fingertip is against a [`Turning`] object.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TipContact {
    /// Signed distance of the fingertip sphere from the surface (m): 0 touching, negative
    /// inside.
    pub gap: Real,
    /// The surface point nearest the fingertip centre (body frame).
    pub point: Vec3,
    /// The outward unit normal there (body frame).
    pub normal: Vec3,
}

impl Turning<'_> {
    /// The object's rotation at `theta` (body to hand frame, about the centre).
    pub fn rotation(&self, theta: Real) -> Rotation3<Real> {
        Rotation3::from_axis_angle(&self.axis, theta)
    }

    /// Hand-frame position of body point `b` with the object at `theta`.
    pub fn to_world(&self, theta: Real, b: &Vec3) -> Vec3 {
        self.rotation(theta) * (b - self.centre) + self.held
    }

    /// Body point at hand-frame position `w` with the object at `theta`.
    pub fn to_body(&self, theta: Real, w: &Vec3) -> Vec3 {
        self.rotation(theta).inverse() * (w - self.held) + self.centre
    }

    /// Where finger `f`'s fingertip at joints `q` is against the object at `theta`.
    pub fn contact_of(&self, f: &Finger, q: &[Real], theta: Real) -> TipContact {
        let b = self.to_body(theta, &f.tip_centre(q));
        let c = self.surface.closest(&b);
        TipContact {
            gap: c.distance - f.tip_radius,
            point: c.point,
            normal: c.normal,
        }
    }

    /// How close finger `f`'s links (as lines, [`Finger::link_segments`]) come to the
    /// surface at `q` with the object at `theta` (m; negative inside), and which link.
    pub fn link_gap(&self, f: &Finger, q: &[Real], theta: Real) -> (Real, usize) {
        let mut closest = (Real::INFINITY, 0);
        f.link_segments(q, |link, a, b| {
            let (a, b) = (self.to_body(theta, &a), self.to_body(theta, &b));
            let d = super::segment_surface_distance(self.surface, &a, &b);
            if d < closest.0 {
                closest = (d, link);
            }
        });
        closest
    }

    /// Finger `f` touching the object at `theta` moves its joints from `qa` to `qb`: the
    /// object's rotation its rolling implies, as `(numerator, weight)` of the least squares of
    /// the module's derivation (the rotation is `numerator / weight`, and over several fingers
    /// the sums' quotient). The contact is where the fingertip touches at `qa`.
    pub fn turn(&self, f: &Finger, qa: &[Real], qb: &[Real], theta: Real) -> (Real, Real) {
        let (ta, tb) = (f.tip_frame(qa), f.tip_frame(qb));
        let c = self.contact_of(f, qa, theta);
        let p = self.to_world(theta, &c.point);
        // The fingertip's material point at the contact, carried by the fingertip's motion.
        let carried = (tb * ta.inverse() * nalgebra::Point3::from(p)).coords;
        let d = carried - p;
        let lever = self.axis.cross(&(p - self.held));
        (lever.dot(&d), lever.norm_squared())
    }
}

/// The velocity of the fingertip sphere's centre (object frame) when it rolls without slipping
/// with angular velocity `omega` relative to the object, touching at outward normal `n`:
/// `r_f omega x n`.
pub fn centre_velocity(n: &Vec3, tip_radius: Real, omega: &Vec3) -> Vec3 {
    omega.cross(n) * tip_radius
}

/// The velocity of the contact point over the object's surface (object frame) when a fingertip
/// of radius `tip_radius` touching at surface point `p` rolls without slipping with angular
/// velocity `omega` relative to the object: `(W + I / r_f)^-1 (omega x n)` on the tangent
/// plane. It is also the contact's velocity over the fingertip (rotated into the object's
/// frame): see the module's derivation.
pub fn contact_velocity(surface: &Convex, p: &Vec3, tip_radius: Real, omega: &Vec3) -> Vec3 {
    let n = surface.normal(p);
    let w = surface.shape_operator(p);
    let (t1, t2) = icrflow_grasp::wrench::tangent_basis_about(&Vec3::z(), &n);
    let rhs = omega.cross(&n);
    let m = |a: &Vec3, b: &Vec3| a.dot(&(w * b));
    let k = 1.0 / tip_radius;
    let mat = Matrix2::new(m(&t1, &t1) + k, m(&t1, &t2), m(&t2, &t1), m(&t2, &t2) + k);
    let v = Vector2::new(t1.dot(&rhs), t2.dot(&rhs));
    match mat.lu().solve(&v) {
        Some(x) => t1 * x[0] + t2 * x[1],
        None => Vec3::zeros(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn on_a_sphere_the_contact_moves_at_the_closed_form_rate() {
        let (r, rf) = (0.035, 0.012);
        let s = Convex::Sphere {
            centre: Vec3::zeros(),
            radius: r,
        };
        let p = Vec3::new(0.0, 0.6, 0.8) * r;
        let omega = Vec3::new(1.0, -2.0, 0.5);
        let v = contact_velocity(&s, &p, rf, &omega);
        let expected = omega.cross(&(p / r)) * (r * rf / (r + rf));
        assert!((v - expected).norm() < 1e-14, "{v} vs {expected}");
    }
}
