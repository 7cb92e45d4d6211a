//! Convex surfaces that fingertip spheres roll on in space: the exact sphere and ellipsoid
//! (body frame), and a convex mesh as the polyhedron it is, with the closest point to a point,
//! the outward normal, and the shape operator (the derivative of the normal along the surface)
//! that the rolling kinematics ([`super::rolling`]) needs.
//!
//! On a polyhedron a fingertip sphere rolls across a face (the contact moves, the normal
//! stays), and pivots about an edge or a vertex (the contact stays, the normal turns): its
//! centre moves on the polyhedron's offset by `r_f`, which is smooth (continuously
//! differentiable), so the rolling of [`super`] integrates on it as on the smooth surfaces;
//! the shape operator is zero on the faces and unbounded at the edges, where the contact's
//! velocity over the object is zero.
//!
//! A fingertip sphere of radius `r_f` touches a convex surface at `p` when its centre is
//! `b = p + r_f n(p)`; `p` is then the surface's closest point to `b` ([`Convex::closest`]),
//! so the contact is a function of the fingertip centre alone, whatever the fingertip's
//! orientation.

use icrflow_grasp::math::{Real, Vec3};
use icrflow_grasp::object::{Object, closest_on_triangle};
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
    /// A convex polyhedron: a mesh's faces fanned into triangles ([`Convex::polyhedron`]).
    Polyhedron {
        /// The object's centre of mass.
        centre: Vec3,
        /// The triangles, counter-clockwise seen from outside.
        triangles: Vec<[Vec3; 3]>,
        /// Each triangle's outward unit normal and its plane's offset (`n . x = offset` on it).
        planes: Vec<(Vec3, Real)>,
    },
}

/// Why a mesh is not a polyhedron fingertips can roll on.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum PolyhedronError {
    /// A vertex lies outside a face's plane.
    #[error(
        "the mesh is not convex: vertex {vertex} lies {outside_mm:.3} mm outside the plane of face {face}; fingertips roll on convex objects only"
    )]
    NotConvex {
        /// The vertex.
        vertex: usize,
        /// The face.
        face: usize,
        /// How far outside (mm).
        outside_mm: Real,
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
            Convex::Polyhedron { triangles, .. } => format!(
                "the mesh as a convex polyhedron ({} triangles: fingertips roll across its faces and pivot about its edges)",
                triangles.len()
            ),
        }
    }

    /// The convex polyhedron of `object`'s mesh, its faces fanned into triangles (degenerate
    /// ones left out), its convexity checked: every vertex on or inside every face's plane
    /// (to 1e-9 of the object's size, and the rounding of planar quads).
    pub fn polyhedron(object: &Object) -> Result<Self, PolyhedronError> {
        let v = &object.vertices;
        let mut triangles = Vec::new();
        let mut planes = Vec::new();
        let mut face_of = Vec::new();
        for (f, face) in object.faces.iter().enumerate() {
            let a = v[face[0] as usize];
            for w in face[1..].windows(2) {
                let (b, c) = (v[w[0] as usize], v[w[1] as usize]);
                let n = (b - a).cross(&(c - a));
                // Degenerate (a sliver of no area): left out.
                let Some(n) = n.try_normalize(1e-18) else {
                    continue;
                };
                triangles.push([a, b, c]);
                planes.push((n, n.dot(&a)));
                face_of.push(f);
            }
        }
        let size = object.max_radius().max(Real::MIN_POSITIVE);
        let tolerance = 1e-7 * size;
        for (i, (n, offset)) in planes.iter().enumerate() {
            for (k, x) in v.iter().enumerate() {
                let out = n.dot(x) - offset;
                if out > tolerance {
                    return Err(PolyhedronError::NotConvex {
                        vertex: k,
                        face: face_of[i],
                        outside_mm: out * 1e3,
                    });
                }
            }
        }
        Ok(Convex::Polyhedron {
            centre: object.centre_of_mass,
            triangles,
            planes,
        })
    }

    /// The surface's centre.
    pub fn centre(&self) -> Vec3 {
        match self {
            Convex::Sphere { centre, .. }
            | Convex::Ellipsoid { centre, .. }
            | Convex::Polyhedron { centre, .. } => *centre,
        }
    }

    /// The outward unit normal at surface point `p`.
    pub fn normal(&self, p: &Vec3) -> Vec3 {
        match self {
            Convex::Sphere { centre, .. } => (p - centre).normalize(),
            Convex::Ellipsoid { centre, semi_axes } => (p - centre)
                .component_div(&semi_axes.component_mul(semi_axes))
                .normalize(),
            // The plane the point lies nearest outside of (on an edge: one of its faces').
            Convex::Polyhedron { planes, .. } => planes
                .iter()
                .map(|(n, o)| (n.dot(p) - o, n))
                .max_by(|a, b| a.0.total_cmp(&b.0))
                .map_or(Vec3::z(), |(_, n)| *n),
        }
    }

    /// The shape operator at surface point `p`: `W = dn/dp` on the tangent plane (symmetric,
    /// positive semi-definite for a convex surface), as a 3 x 3 matrix that maps the normal to
    /// zero. Sphere of radius `R`: `(I - n n^T) / R`; ellipsoid `(x - c)^T Q (x - c) = 1`,
    /// `Q = diag(1 / a_i^2)`: `P Q P / |Q (p - c)|`, `P = I - n n^T`; polyhedron: zero (its
    /// faces'; unbounded at its edges, which this does not say).
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
            Convex::Polyhedron { .. } => Matrix3::zeros(),
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
            Convex::Polyhedron {
                triangles, planes, ..
            } => closest_on_polyhedron(x, triangles, planes),
        }
    }
}

/// The closest point of the convex polyhedron of `triangles` (with their `planes`) to `x`:
/// outside, the nearest of the triangles' closest points (a triangle whose plane is farther
/// than the best so far is passed over), the normal along `x - p` (the offset surface's); inside
/// (every plane ahead), the foot on the nearest plane.
fn closest_on_polyhedron(x: &Vec3, triangles: &[[Vec3; 3]], planes: &[(Vec3, Real)]) -> Closest {
    let Some((first, ahead)) = planes
        .iter()
        .map(|(n, o)| n.dot(x) - o)
        .enumerate()
        .max_by(|a, b| a.1.total_cmp(&b.1))
    else {
        return Closest {
            point: *x,
            normal: Vec3::z(),
            distance: 0.0,
        };
    };
    if ahead <= 0.0 {
        let n = planes[first].0;
        return Closest {
            point: x - n * ahead,
            normal: n,
            distance: ahead,
        };
    }
    let [a, b, c] = &triangles[first];
    let mut point = closest_on_triangle(x, a, b, c);
    let mut best = (x - point).norm();
    for (t, (n, o)) in triangles.iter().zip(planes) {
        if (n.dot(x) - o).abs() >= best {
            continue;
        }
        let q = closest_on_triangle(x, &t[0], &t[1], &t[2]);
        let d = (x - q).norm();
        if d < best {
            (point, best) = (q, d);
        }
    }
    let normal = if best > 0.0 {
        (x - point) / best
    } else {
        planes[first].0
    };
    Closest {
        point,
        normal,
        distance: best,
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
                        Convex::Polyhedron { .. } => unreachable!("not among these surfaces"),
                    };
                    assert!((q - x).norm() >= c.distance.abs() - 1e-12);
                }
            }
        }
    }

    /// A box's mesh as a polyhedron: outside it, the closest point is on the mesh at the
    /// mesh's own distance (every face compared), the normal along the offset; inside, the
    /// nearest face's plane.
    #[test]
    fn a_polyhedron_s_closest_points_are_the_mesh_s() {
        let object = Object::cuboid(Vec3::new(0.03, 0.02, 0.025), 3).unwrap();
        let s = Convex::polyhedron(&object).unwrap();
        let mut rng = 99u64;
        let mut next = || {
            rng = rng
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((rng >> 11) as Real / (1u64 << 53) as Real) * 2.0 - 1.0
        };
        for _ in 0..500 {
            let x = Vec3::new(next(), next(), next()) * 0.06;
            let c = s.closest(&x);
            if c.distance > 0.0 {
                assert!((c.distance - object.surface_distance(&x)).abs() < 1e-12);
                assert!(object.surface_distance(&c.point) < 1e-12);
                assert!((c.point + c.normal * c.distance - x).norm() < 1e-12);
            } else {
                // The box's nearest face, by its plane.
                let h = Vec3::new(0.03, 0.02, 0.025);
                let inner = (0..3)
                    .map(|i| h[i] - x[i].abs())
                    .fold(Real::INFINITY, Real::min);
                assert!(
                    (c.distance + inner).abs() < 1e-12,
                    "{} {}",
                    c.distance,
                    inner
                );
            }
        }
        // Not convex: a box with one vertex pushed in is refused, naming a vertex and a face.
        let mut dented = object.clone();
        dented.vertices[0] *= 0.5;
        assert!(matches!(
            Convex::polyhedron(&dented),
            Err(PolyhedronError::NotConvex { .. })
        ));
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
