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

use icrflow_grasp::math::{Real, Vec3};
use nalgebra::{Matrix2, Vector2};

use super::surface::Convex;

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
