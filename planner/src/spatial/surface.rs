//! Smooth convex surfaces that fingertip spheres roll on in space: the exact sphere and
//! ellipsoid (body frame), with the closest point to a point, the outward normal, and the
//! shape operator (the derivative of the normal along the surface) that the rolling
//! kinematics ([`super::rolling`]) needs.
//!
//! A fingertip sphere of radius `r_f` touches a convex surface at `p` when its centre is
//! `b = p + r_f n(p)`; `p` is then the surface's closest point to `b` ([`Convex::closest`]),
//! so the contact is a function of the fingertip centre alone, whatever the fingertip's
//! orientation.

use icrflow_grasp::math::{Real, Vec3};
use nalgebra::Matrix3;

/// A smooth convex surface in the body frame.
#[derive(Debug, Clone, PartialEq)]
pub enum Convex {
    /// A sphere.
    Sphere {
        /// Its centre.
        centre: Vec3,
        /// Its radius (m, > 0).
        radius: Real,
    },
    /// An ellipsoid with its semi-axes along the body axes: `sum ((x_i - c_i) / a_i)^2 = 1`.
    Ellipsoid {
        /// Its centre.
        centre: Vec3,
        /// Semi-axes along x, y, z (m, > 0).
        semi_axes: Vec3,
    },
}

/// A point's closest point on a [`Convex`] surface.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Closest {
    /// The closest surface point.
    pub point: Vec3,
    /// The outward unit normal there.
    pub normal: Vec3,
    /// Signed distance of the point from the surface (m; negative inside).
    pub distance: Real,
}

impl Convex {
    /// One-line description for messages.
    pub fn describe(&self) -> String {
        match self {
            Convex::Sphere { radius, .. } => format!("the exact sphere of radius {radius} m"),
            Convex::Ellipsoid { semi_axes, .. } => format!(
                "the exact ellipsoid of semi-axes [{}, {}, {}] m",
                semi_axes.x, semi_axes.y, semi_axes.z
            ),
        }
    }

    /// The surface's centre.
    pub fn centre(&self) -> Vec3 {
        match self {
            Convex::Sphere { centre, .. } | Convex::Ellipsoid { centre, .. } => *centre,
        }
    }

    /// The outward unit normal at surface point `p`.
    pub fn normal(&self, p: &Vec3) -> Vec3 {
        match self {
            Convex::Sphere { centre, .. } => (p - centre).normalize(),
            Convex::Ellipsoid { centre, semi_axes } => (p - centre)
                .component_div(&semi_axes.component_mul(semi_axes))
                .normalize(),
        }
    }

    /// The shape operator at surface point `p`: `W = dn/dp` on the tangent plane (symmetric,
    /// positive semi-definite for a convex surface), as a 3 x 3 matrix that maps the normal to
    /// zero. Sphere of radius `R`: `(I - n n^T) / R`; ellipsoid `(x - c)^T Q (x - c) = 1`,
    /// `Q = diag(1 / a_i^2)`: `P Q P / |Q (p - c)|`, `P = I - n n^T`.
    pub fn shape_operator(&self, p: &Vec3) -> Matrix3<Real> {
        let n = self.normal(p);
        let proj = Matrix3::identity() - n * n.transpose();
        match self {
            Convex::Sphere { radius, .. } => proj / *radius,
            Convex::Ellipsoid { centre, semi_axes } => {
                let q = Matrix3::from_diagonal(&semi_axes.map(|a| 1.0 / (a * a)));
                let g = (q * (p - centre)).norm();
                proj * q * proj / g
            }
        }
    }

    /// The closest surface point to `x`, its outward normal and the signed distance. At the
    /// centre itself (where every direction is as close) the answer is one of the closest.
    pub fn closest(&self, x: &Vec3) -> Closest {
        match self {
            Convex::Sphere { centre, radius } => {
                let d = x - centre;
                let r = d.norm();
                let normal = if r > 0.0 { d / r } else { Vec3::z() };
                Closest {
                    point: centre + normal * *radius,
                    normal,
                    distance: r - radius,
                }
            }
            Convex::Ellipsoid { centre, semi_axes } => {
                closest_on_ellipsoid(&(x - centre), semi_axes, centre)
            }
        }
    }
}

/// The closest point on the ellipsoid of semi-axes `a` (centred at the origin) to `y`, moved
/// by `centre`. The closest point is `p_i = a_i^2 y_i / (a_i^2 + t)` for the root `t` of
/// `F(t) = sum (a_i y_i / (a_i^2 + t))^2 - 1` (decreasing on `t > -min a_i^2`; `t > 0`
/// outside, `t < 0` inside), found by Newton's method kept inside a bisection bracket.
fn closest_on_ellipsoid(y: &Vec3, a: &Vec3, centre: &Vec3) -> Closest {
    let a2 = a.component_mul(a);
    let f = |t: Real| -> (Real, Real) {
        let mut v = -1.0;
        let mut dv = 0.0;
        for i in 0..3 {
            let s = a[i] * y[i] / (a2[i] + t);
            v += s * s;
            dv -= 2.0 * s * s / (a2[i] + t);
        }
        (v, dv)
    };
    let smallest = a2.min();
    let mut lo = -smallest;
    let mut hi = y.norm() * a.max() + a2.max();
    let mut t = 0.0;
    for _ in 0..200 {
        let (v, dv) = f(t);
        if v.abs() < 1e-15 {
            break;
        }
        if v > 0.0 {
            lo = t;
        } else {
            hi = t;
        }
        let newton = t - v / dv;
        t = if dv < 0.0 && newton > lo && newton < hi {
            newton
        } else {
            0.5 * (lo + hi)
        };
        if (hi - lo).abs() <= 1e-15 * (1.0 + t.abs()) {
            break;
        }
    }
    let p = Vec3::from_fn(|i, _| a2[i] * y[i] / (a2[i] + t));
    let g = p.component_div(&a2);
    let normal = if g.norm() > 0.0 {
        g.normalize()
    } else {
        Vec3::z()
    };
    let distance = (y - p).norm() * if t < 0.0 { -1.0 } else { 1.0 };
    Closest {
        point: p + centre,
        normal,
        distance,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn closest_points_lie_on_the_surface_with_the_offset_along_the_normal() {
        let surfaces = [
            Convex::Sphere {
                centre: Vec3::new(0.01, -0.02, 0.03),
                radius: 0.035,
            },
            Convex::Ellipsoid {
                centre: Vec3::new(0.01, -0.02, 0.03),
                semi_axes: Vec3::new(0.055, 0.045, 0.04),
            },
        ];
        let mut rng = 12345u64;
        let mut next = || {
            rng = rng
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((rng >> 11) as Real / (1u64 << 53) as Real) * 2.0 - 1.0
        };
        for s in &surfaces {
            for _ in 0..500 {
                let x = s.centre() + Vec3::new(next(), next(), next()) * 0.1;
                let c = s.closest(&x);
                // On the surface, the normal there, the offset along it.
                if let Convex::Ellipsoid { centre, semi_axes } = s {
                    let u = (c.point - centre).component_div(semi_axes);
                    assert!(
                        (u.norm_squared() - 1.0).abs() < 1e-12,
                        "{} at {x}",
                        u.norm_squared()
                    );
                }
                assert!((s.normal(&c.point) - c.normal).norm() < 1e-9);
                let back = c.point + c.normal * c.distance;
                assert!((back - x).norm() < 1e-12, "{back} vs {x}");
                // No sampled surface point is closer.
                for _ in 0..20 {
                    let d = Vec3::new(next(), next(), next()).normalize();
                    let q = match s {
                        Convex::Sphere { centre, radius } => centre + d * *radius,
                        Convex::Ellipsoid { centre, semi_axes } => {
                            centre + semi_axes.component_mul(&d) / d.norm()
                        }
                    };
                    assert!((q - x).norm() >= c.distance.abs() - 1e-12);
                }
            }
        }
    }

    #[test]
    fn the_shape_operator_is_the_normals_derivative() {
        let s = Convex::Ellipsoid {
            centre: Vec3::zeros(),
            semi_axes: Vec3::new(0.055, 0.045, 0.04),
        };
        let p = s.closest(&Vec3::new(0.03, 0.02, 0.05)).point;
        let n = s.normal(&p);
        let w = s.shape_operator(&p);
        let (t1, t2) = icrflow_grasp::wrench::tangent_basis_about(&Vec3::z(), &n);
        for t in [t1, t2] {
            let h = 1e-6;
            let pp = s.closest(&(p + t * h)).point;
            let pm = s.closest(&(p - t * h)).point;
            let fd = (s.normal(&pp) - s.normal(&pm)) / (pp - pm).norm();
            assert!(
                (fd - w * t).norm() < 1e-5 * (w * t).norm(),
                "{fd} vs {}",
                w * t
            );
        }
        assert!((w * n).norm() < 1e-12);
    }
}
