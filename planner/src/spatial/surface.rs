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
//! A polyhedron's closest points are searched through a bounding-volume hierarchy over its
//! triangles ([`Tree`]), so that a mesh of thousands of faces costs microseconds a point.
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
        /// Each triangle's facet: the object's candidate of the face it was fanned from
        /// (`None` for a face too small to be one).
        facets: Vec<Option<u32>>,
        /// The boxes over the triangles that closest points are searched through.
        tree: Tree,
    },
}

/// A bounding-volume hierarchy over a polyhedron's triangles: axis-aligned boxes, each split
/// at the median of its triangles' centroids along its longest side, leaves of at most
/// [`LEAF`] triangles. A closest-point query opens only the boxes nearer than the nearest
/// triangle found so far, the nearer child first: a few dozen of the 5,040 triangles of the
/// ellipsoid mesh for a fingertip centre near it, where comparing every triangle's plane took
/// the whole list.
#[derive(Debug, Clone, PartialEq)]
pub struct Tree {
    nodes: Vec<Node>,
    /// Triangle indices, each leaf's a run of them.
    order: Vec<u32>,
}

/// A box of a [`Tree`]: a leaf (`count > 0`: `order[first..first + count]`) or two children
/// (the first at the next index, the second at `first`).
#[derive(Debug, Clone, PartialEq)]
struct Node {
    lo: Vec3,
    hi: Vec3,
    first: u32,
    count: u32,
}

/// Triangles per leaf of a [`Tree`], at most.
const LEAF: usize = 4;
/// Distances to a query point within this of the nearest (m) are ties: a point on an edge is
/// as near to both faces, and the one it lies outside of says which side it is on.
const TIE: Real = 1e-12;

impl Tree {
    /// The tree over `triangles`.
    fn new(triangles: &[[Vec3; 3]]) -> Self {
        let mut order: Vec<u32> = (0..triangles.len() as u32).collect();
        let centroids: Vec<Vec3> = triangles
            .iter()
            .map(|t| (t[0] + t[1] + t[2]) / 3.0)
            .collect();
        let mut nodes = Vec::with_capacity(2 * triangles.len() / LEAF + 1);
        if !triangles.is_empty() {
            Self::build(triangles, &centroids, &mut order, 0, &mut nodes);
        }
        Self { nodes, order }
    }

    /// Appends the node over `order[at..at + part.len()]` (`part`) and its subtree.
    fn build(
        triangles: &[[Vec3; 3]],
        centroids: &[Vec3],
        order: &mut [u32],
        at: usize,
        nodes: &mut Vec<Node>,
    ) {
        let (mut lo, mut hi) = (
            Vec3::repeat(Real::INFINITY),
            Vec3::repeat(Real::NEG_INFINITY),
        );
        for &t in order.iter() {
            for v in &triangles[t as usize] {
                lo = lo.inf(v);
                hi = hi.sup(v);
            }
        }
        let me = nodes.len();
        nodes.push(Node {
            lo,
            hi,
            first: at as u32,
            count: order.len() as u32,
        });
        if order.len() <= LEAF {
            return;
        }
        let extent = hi - lo;
        let axis = extent.imax();
        let half = order.len() / 2;
        order.select_nth_unstable_by(half, |a, b| {
            centroids[*a as usize][axis].total_cmp(&centroids[*b as usize][axis])
        });
        let (left, right) = order.split_at_mut(half);
        Self::build(triangles, centroids, left, at, nodes);
        let second = nodes.len();
        Self::build(triangles, centroids, right, at + half, nodes);
        nodes[me].first = second as u32;
        nodes[me].count = 0;
    }

    /// The triangle nearest to `x` (of `triangles`, with their `planes`), its closest point,
    /// the distance, and how far `x` is outside the plane of the nearest triangle it lies
    /// outside of (of the ties within [`TIE`]; negative when inside every one). `None` without
    /// triangles.
    fn nearest(
        &self,
        x: &Vec3,
        triangles: &[[Vec3; 3]],
        planes: &[(Vec3, Real)],
    ) -> Option<(usize, Vec3, Real, Real)> {
        if self.nodes.is_empty() {
            return None;
        }
        let mut best: Option<(usize, Vec3, Real, Real)> = None;
        let mut bound = Real::INFINITY;
        // Depth-first; median splits keep the depth at log2(triangles / LEAF) + 1.
        let mut stack = [0u32; 64];
        let mut top = 1;
        while top > 0 {
            top -= 1;
            let node = &self.nodes[stack[top] as usize];
            if box_distance_squared(x, &node.lo, &node.hi) > (bound + TIE) * (bound + TIE) {
                continue;
            }
            if node.count > 0 {
                let run = node.first as usize..(node.first + node.count) as usize;
                for &t in &self.order[run] {
                    let t = t as usize;
                    let [a, b, c] = &triangles[t];
                    let q = closest_on_triangle(x, a, b, c);
                    let d = (x - q).norm();
                    let side = planes[t].0.dot(x) - planes[t].1;
                    best = match best {
                        Some((_, _, bd, bs)) if d > bd + TIE || (d >= bd - TIE && side <= bs) => {
                            best
                        }
                        _ => Some((t, q, d, side)),
                    };
                    bound = bound.min(d);
                }
                continue;
            }
            let me = stack[top] + 1;
            let (near, far) = (me, node.first);
            let dn = box_distance_squared(
                x,
                &self.nodes[near as usize].lo,
                &self.nodes[near as usize].hi,
            );
            let df = box_distance_squared(
                x,
                &self.nodes[far as usize].lo,
                &self.nodes[far as usize].hi,
            );
            let (first, second) = if dn <= df { (near, far) } else { (far, near) };
            if top + 2 > stack.len() {
                // Deeper than any median split makes: left unsearched (never happens).
                continue;
            }
            stack[top] = second;
            stack[top + 1] = first;
            top += 2;
        }
        best
    }
}

/// The squared distance from `x` to the box `[lo, hi]` (0 inside it).
fn box_distance_squared(x: &Vec3, lo: &Vec3, hi: &Vec3) -> Real {
    (0..3)
        .map(|i| {
            let d = (lo[i] - x[i]).max(x[i] - hi[i]).max(0.0);
            d * d
        })
        .sum()
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
        let mut facet_of_face = vec![None; object.faces.len()];
        for (k, &f) in object.facet_faces.iter().enumerate() {
            facet_of_face[f as usize] = Some(k as u32);
        }
        let facets = face_of.iter().map(|&f| facet_of_face[f]).collect();
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
        let tree = Tree::new(&triangles);
        Ok(Convex::Polyhedron {
            centre: object.centre_of_mass,
            triangles,
            planes,
            facets,
            tree,
        })
    }

    /// The facet (the object's candidate) that surface point `p` lies on, for a polyhedron:
    /// the face of its nearest triangle (on an edge, one of the two). `None` for the smooth
    /// surfaces, whose candidates are samples of the surface, not pieces of it.
    pub fn facet_at(&self, p: &Vec3) -> Option<usize> {
        match self {
            Convex::Polyhedron {
                triangles,
                planes,
                facets,
                tree,
                ..
            } => tree
                .nearest(p, triangles, planes)
                .and_then(|(t, ..)| facets[t])
                .map(|f| f as usize),
            Convex::Sphere { .. } | Convex::Ellipsoid { .. } => None,
        }
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
            // The nearest triangle's (on an edge: of those as near, the one the point lies
            // farthest outside of).
            Convex::Polyhedron {
                triangles,
                planes,
                tree,
                ..
            } => tree
                .nearest(p, triangles, planes)
                .map_or(Vec3::z(), |(t, ..)| planes[t].0),
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
                triangles,
                planes,
                tree,
                ..
            } => closest_on_polyhedron(x, triangles, planes, tree),
        }
    }
}

/// The closest point of the convex polyhedron of `triangles` (with their `planes`, searched
/// through `tree`) to `x`: the nearest triangle's closest point. Outside (`x` outside the
/// plane of a nearest triangle), the normal along `x - p` (the offset surface's), the face's
/// within [`ON_SURFACE`] of it; inside, the foot on the nearest plane (for a convex
/// polyhedron the nearest triangle's point is that foot) and that plane's normal.
fn closest_on_polyhedron(
    x: &Vec3,
    triangles: &[[Vec3; 3]],
    planes: &[(Vec3, Real)],
    tree: &Tree,
) -> Closest {
    let Some((t, point, d, side)) = tree.nearest(x, triangles, planes) else {
        return Closest {
            point: *x,
            normal: Vec3::z(),
            distance: 0.0,
        };
    };
    // On the surface to rounding (a point that is itself a closest point), `x - p` has no
    // direction: the face's normal.
    let normal = if side > 0.0 && d > ON_SURFACE {
        (x - point) / d
    } else {
        planes[t].0
    };
    Closest {
        point,
        normal,
        distance: if side > 0.0 { d } else { -d },
    }
}

/// Distance from a polyhedron within which a point counts as on it (m): its normal is then
/// its face's, not the direction of the rounding between it and its closest point.
const ON_SURFACE: Real = 1e-10;

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

/// A generator of numbers uniform in [-1, 1) from `seed` (a 64-bit LCG), for the tests.
#[cfg(test)]
pub(crate) fn uniform(seed: u64) -> impl FnMut() -> Real {
    let mut rng = seed;
    move || {
        rng = rng
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((rng >> 11) as Real / (1u64 << 53) as Real) * 2.0 - 1.0
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
        let mut next = uniform(12345);
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
        let mut next = uniform(99);
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

    /// The tree's closest points are every triangle's: on a 64 x 32 UV ellipsoid mesh and a
    /// cube's of 8 quads an edge (coplanar triangles, edges, corners), from points near the surface
    /// in and out (where fingertip centres and links are) and farther, the distance is the
    /// smallest over every triangle, and the side is that of the plane the point is farthest
    /// outside of (inside: the nearest plane's).
    #[test]
    fn the_tree_finds_what_every_triangle_says() {
        let objects = [
            Object::ellipsoid(Vec3::new(0.055, 0.045, 0.04), 64, 32).unwrap(),
            Object::cuboid(Vec3::new(0.03, 0.03, 0.03), 8).unwrap(),
        ];
        let mut next = uniform(7);
        for object in &objects {
            let s = Convex::polyhedron(object).unwrap();
            let Convex::Polyhedron {
                triangles, planes, ..
            } = &s
            else {
                unreachable!()
            };
            for k in 0..2000 {
                let d = Vec3::new(next(), next(), next()).normalize();
                let scale = [0.5, 0.9, 1.0, 1.1, 1.5, 3.0][k % 6];
                let x = d * scale * object.max_radius() * (1.0 + 0.05 * next());
                let c = s.closest(&x);
                let brute = triangles
                    .iter()
                    .map(|t| (x - closest_on_triangle(&x, &t[0], &t[1], &t[2])).norm())
                    .fold(Real::INFINITY, Real::min);
                let ahead = planes
                    .iter()
                    .map(|(n, o)| n.dot(&x) - o)
                    .fold(Real::NEG_INFINITY, Real::max);
                assert!(
                    (c.distance.abs() - brute).abs() < 1e-12,
                    "{x}: {} vs {brute}",
                    c.distance
                );
                if ahead > 1e-12 {
                    assert!(
                        c.distance > 0.0,
                        "{x} is outside by {ahead}: {}",
                        c.distance
                    );
                    assert!((c.point + c.normal * c.distance - x).norm() < 1e-12);
                } else if ahead < -1e-12 {
                    assert!(
                        (c.distance - ahead).abs() < 1e-12,
                        "{} vs {ahead}",
                        c.distance
                    );
                }
            }
        }
    }

    /// A point on a polyhedron's face (a contact candidate: a facet's centre, off the face's
    /// plane by rounding only) has that face's normal, a unit vector of the mesh's, not the
    /// direction of the rounding between the point and its closest point; a fingertip placed
    /// its radius out along it touches there. (That direction once placed the Allegro's
    /// fingertips sideways into the STL ellipsoid: its thumb could not roll at the start and
    /// every placement of a switch hit the object.)
    #[test]
    fn a_point_on_a_polyhedron_has_its_face_s_normal() {
        let object = Object::ellipsoid(Vec3::new(0.055, 0.045, 0.04), 64, 32).unwrap();
        let s = Convex::polyhedron(&object).unwrap();
        let Convex::Polyhedron {
            triangles, planes, ..
        } = &s
        else {
            unreachable!()
        };
        for (t, (n, _)) in triangles.iter().zip(planes) {
            let p = (t[0] + t[1] + t[2]) / 3.0;
            let c = s.closest(&p);
            assert!(c.distance.abs() < 1e-15, "{p}: {}", c.distance);
            assert!((c.normal - n).norm() < 1e-12, "{p}: {} vs {n}", c.normal);
            let b = p + c.normal * 0.0144;
            assert!((s.closest(&b).distance - 0.0144).abs() < 1e-12);
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
