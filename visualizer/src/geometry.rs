//! What the recording shows, computed from the run's messages and the config's setup: plain
//! data (no Rerun types), so that it can be tested on its own.

use icrflow_grasp::hull::Hull;
use icrflow_grasp::math::{Real, Vec3};
use icrflow_grasp::object::Object;
use icrflow_grasp::quality::GraspProblem;
use icrflow_grasp::wrench::{Space, tangent_basis};
use nalgebra::{Quaternion, UnitQuaternion};

/// A point for the recording (single precision, as Rerun stores it).
pub type P3 = [f32; 3];

/// Single precision.
pub fn p3(v: &Vec3) -> P3 {
    [v.x as f32, v.y as f32, v.z as f32]
}

/// A triangle mesh.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Mesh {
    /// Vertex positions.
    pub positions: Vec<P3>,
    /// Triangles (indices into `positions`), counter-clockwise seen from outside.
    pub triangles: Vec<[u32; 3]>,
}

/// The object's surface in its body frame: its faces, fanned into triangles.
pub fn object_mesh(object: &Object) -> Mesh {
    let mut triangles = Vec::new();
    for face in object.faces.iter() {
        for k in 1..face.len().saturating_sub(1) {
            triangles.push([face[0], face[k], face[k + 1]]);
        }
    }
    Mesh {
        positions: object.vertices.iter().map(p3).collect(),
        triangles,
    }
}

/// The object's pose in the hand frame from a grasp state's centre of mass `position` and
/// `orientation` `[w, x, y, z]`, given the body-frame centre of mass `com`: translation and
/// rotation taking body-frame points to the hand frame.
pub fn pose(position: [f64; 3], orientation: [f64; 4], com: &Vec3) -> (Vec3, UnitQuaternion<Real>) {
    let [w, x, y, z] = orientation;
    let q = Quaternion::new(w, x, y, z);
    let r = if q.norm() > 1e-12 && q.coords.iter().all(|c| c.is_finite()) {
        UnitQuaternion::from_quaternion(q)
    } else {
        UnitQuaternion::identity()
    };
    let p = Vec3::from(position);
    (p - r * com, r)
}

/// The linearised friction cone at a contact (point `p`, outward normal `n`, both in the hand
/// frame): its edges as segments from the contact outwards (the directions a fingertip may
/// push from), `length` long; `edges` around the normal in space, or the two in the plane.
pub fn cone_edges(
    p: &Vec3,
    n: &Vec3,
    mu: Real,
    edges: usize,
    space: Space,
    length: Real,
) -> Vec<Vec<P3>> {
    let n = n.normalize();
    let directions: Vec<Vec3> = match space {
        Space::Planar => {
            let t = Vec3::z().cross(&n).normalize();
            vec![n + mu * t, n - mu * t]
        }
        Space::Spatial => {
            let (t1, t2) = tangent_basis(&n);
            (0..edges.max(3))
                .map(|k| {
                    let a = std::f64::consts::TAU * k as f64 / edges.max(3) as f64;
                    n + mu * (a.cos() * t1 + a.sin() * t2)
                })
                .collect()
        }
    };
    directions
        .iter()
        .map(|d| vec![p3(p), p3(&(p + length * d.normalize()))])
        .collect()
}

/// The coordinates shown of a wrench: `(f_x, f_y, tau_z / rho)`, the reduced space of paper
/// Fig. 9 (a 6D wrench is projected onto them).
pub fn reduced(w: &[Real], space: Space) -> P3 {
    match space {
        Space::Planar => [w[0] as f32, w[1] as f32, w[2] as f32],
        Space::Spatial => [w[0] as f32, w[1] as f32, w[5] as f32],
    }
}

/// The convex hull of `points` (in the shown coordinates) as a triangle mesh. Points that
/// span a plane of two coordinates only (a sphere's object wrenches have no torque) give
/// their flat hull in that plane, fanned into triangles; fewer dimensions give no mesh.
pub fn hull_mesh(points: &[P3]) -> Mesh {
    let flat: Vec<Real> = points.iter().flatten().map(|&c| c as Real).collect();
    let Ok(hull) = Hull::new(&flat, 3) else {
        return flat_hull_mesh(points);
    };
    let mut triangles = Vec::new();
    for f in 0..hull.facet_count() {
        let a = hull.normal(f);
        let normal = Vec3::new(a[0], a[1], a[2]);
        let vertices = hull.facet_vertices(f);
        if vertices.len() < 3 {
            continue;
        }
        // The facet's points in order around their centroid, seen from outside.
        let at = |i: u32| {
            let p = points[i as usize];
            Vec3::new(p[0] as Real, p[1] as Real, p[2] as Real)
        };
        let centre = vertices.iter().map(|&i| at(i)).sum::<Vec3>() / vertices.len() as Real;
        let u = (at(vertices[0]) - centre).normalize();
        let v = normal.cross(&u);
        let mut ordered: Vec<(Real, u32)> = vertices
            .iter()
            .map(|&i| {
                let d = at(i) - centre;
                (d.dot(&v).atan2(d.dot(&u)), i)
            })
            .collect();
        ordered.sort_by(|x, y| x.0.total_cmp(&y.0));
        for k in 1..ordered.len() - 1 {
            triangles.push([ordered[0].1, ordered[k].1, ordered[k + 1].1]);
        }
    }
    Mesh {
        positions: points.to_vec(),
        triangles,
    }
}

/// The hull of `points` that lie in a plane of two coordinates (the third constant), fanned
/// into triangles; empty otherwise, or when they span less than a plane.
fn flat_hull_mesh(points: &[P3]) -> Mesh {
    let range = |k: usize| {
        let (lo, hi) = points
            .iter()
            .fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), p| {
                (lo.min(p[k]), hi.max(p[k]))
            });
        hi - lo
    };
    let ranges = [range(0), range(1), range(2)];
    let big = ranges.iter().copied().fold(0.0f32, f32::max);
    // Not finite or all one point: no plane.
    if big.is_nan() || big <= 0.0 {
        return Mesh::default();
    }
    let Some(k) = (0..3).find(|&k| ranges[k] <= 1e-6 * big) else {
        return Mesh::default();
    };
    let (u, v) = match k {
        0 => (1, 2),
        1 => (0, 2),
        _ => (0, 1),
    };
    // Andrew's monotone chain over (p[u], p[v]).
    let mut order: Vec<usize> = (0..points.len()).collect();
    order.sort_by(|&a, &b| {
        (points[a][u], points[a][v])
            .partial_cmp(&(points[b][u], points[b][v]))
            .unwrap_or(std::cmp::Ordering::Equal)
    });
    let cross = |o: usize, a: usize, b: usize| {
        let (o, a, b) = (points[o], points[a], points[b]);
        (a[u] - o[u]) * (b[v] - o[v]) - (a[v] - o[v]) * (b[u] - o[u])
    };
    let mut chain: Vec<usize> = Vec::new();
    for pass in 0..2 {
        let start = chain.len();
        let sweep: Vec<usize> = if pass == 0 {
            order.clone()
        } else {
            order.iter().rev().copied().collect()
        };
        for i in sweep {
            while chain.len() >= start + 2
                && cross(chain[chain.len() - 2], chain[chain.len() - 1], i) <= 0.0
            {
                chain.pop();
            }
            chain.push(i);
        }
        chain.pop();
    }
    if chain.len() < 3 {
        return Mesh::default();
    }
    let triangles = (1..chain.len() - 1)
        .map(|j| [chain[0] as u32, chain[j] as u32, chain[j + 1] as u32])
        .collect();
    Mesh {
        positions: points.to_vec(),
        triangles,
    }
}

/// The object wrench space (all its facets' wrenches) scaled by `alpha`, in the shown
/// coordinates: the set the grasp's wrench space must contain (paper eq. 6).
pub fn scaled_ows(problem: &GraspProblem, alpha: Real) -> Vec<P3> {
    let space = problem.space();
    (0..problem.ows_count())
        .map(|k| {
            let w: Vec<Real> = problem.ows_wrench(k).iter().map(|x| alpha * x).collect();
            reduced(&w, space)
        })
        .collect()
}

/// The primitive wrenches (friction-cone edges) of candidate `i`, in the shown coordinates.
pub fn candidate_wrenches(problem: &GraspProblem, i: usize) -> Vec<P3> {
    let dim = problem.dim();
    problem
        .candidate_wrenches(i)
        .chunks_exact(dim)
        .map(|w| reduced(w, problem.space()))
        .collect()
}

/// How far outside the surface the ICR points are drawn, as a fraction of rho (the torque
/// length, the object's largest radius by default).
pub const ICR_OFFSET: Real = 0.1;

/// How long the friction-cone edges are drawn (m): longer than a fingertip's radius (the
/// paper's are 2.5 cm), so that they show beyond the fingertip they start under.
pub const CONE_LENGTH: Real = 0.04;

/// The surface's colour, per vertex: twelve 30-degree sectors of longitude around the centre
/// of mass (about the body's z axis), alternately light and dark grey, the first (0 to 30
/// degrees, starting at the body's x axis) painted white, so that the object's turn shows.
pub fn object_colours(object: &Object) -> Vec<u32> {
    object
        .vertices
        .iter()
        .map(|v| {
            let d = v - object.centre_of_mass;
            let longitude = d.y.atan2(d.x).to_degrees().rem_euclid(360.0);
            match (longitude / 30.0) as u32 {
                0 => 0xf2f2f2ff,
                k if k % 2 == 0 => 0x9da3abff,
                _ => 0x5b6169ff,
            }
        })
        .collect()
}

/// The radius (m) around the hand frame's origin within which the hand and the object lie:
/// the farthest finger base, joint or fingertip (at the home joint angles) plus the
/// fingertip's radius, and at least the object's radius `object`.
pub fn hand_radius(hand: &icrflow_plan::hand::Hand, object: Real) -> Real {
    let mut r = object;
    for f in &hand.fingers {
        r = r.max(f.base.translation.vector.xy().norm());
        if f.home.len() == f.dof() && f.home.iter().all(|q| q.is_finite()) {
            let pose = f.fk(&f.home);
            for p in pose.joints.iter().chain([&pose.tip_centre]) {
                r = r.max(p.xy().norm() + f.tip_radius);
            }
        }
    }
    r
}

/// `angle` (deg) moved by whole turns to within half a turn of `previous`: a continuous
/// angle where `atan2` jumps at +-180 degrees.
pub fn unwrap_deg(previous: f64, angle: f64) -> f64 {
    previous + (angle - previous + 180.0).rem_euclid(360.0) - 180.0
}

/// The angle (deg) of a hand-frame point around the object's centre, in the hand's plane.
pub fn angle_deg(point: &Vec3, centre: &Vec3) -> f64 {
    let d = point - centre;
    d.y.atan2(d.x).to_degrees()
}

#[cfg(test)]
mod tests {
    use super::*;
    use icrflow_grasp::object::Object;

    #[test]
    fn the_hull_mesh_of_a_cube_is_its_twelve_outward_triangles() {
        let mut points = Vec::new();
        for i in 0..8 {
            points.push([
                (i & 1) as f32 * 2.0 - 1.0,
                ((i >> 1) & 1) as f32 * 2.0 - 1.0,
                ((i >> 2) & 1) as f32 * 2.0 - 1.0,
            ]);
        }
        points.push([0.0, 0.0, 0.0]); // inside: on no triangle
        let mesh = hull_mesh(&points);
        assert_eq!(mesh.triangles.len(), 12);
        for t in &mesh.triangles {
            assert!(t.iter().all(|&i| i < 8), "{t:?}");
            // Counter-clockwise seen from outside: the normal points away from the centre.
            let v = |i: u32| {
                let p = points[i as usize];
                Vec3::new(p[0] as f64, p[1] as f64, p[2] as f64)
            };
            let n = (v(t[1]) - v(t[0])).cross(&(v(t[2]) - v(t[0])));
            assert!(n.dot(&v(t[0])) > 0.0, "{t:?}");
        }
        // Flat input: its hull in its plane (a square and its centre: two triangles).
        let square = [
            [0.0, 0.0, 0.5],
            [1.0, 0.0, 0.5],
            [0.5, 0.5, 0.5],
            [1.0, 1.0, 0.5],
            [0.0, 1.0, 0.5],
        ];
        let flat = hull_mesh(&square);
        assert_eq!(flat.triangles.len(), 2, "{flat:?}");
        assert!(flat.triangles.iter().flatten().all(|&i| i != 2));
        // A segment: no mesh, no panic.
        assert!(
            hull_mesh(&[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0]])
                .triangles
                .is_empty()
        );
    }

    #[test]
    fn the_object_mesh_covers_the_surface_and_the_pose_moves_it() {
        let sphere = Object::sphere(0.05, 12, 8).unwrap();
        let mesh = object_mesh(&sphere);
        assert!(!mesh.triangles.is_empty());
        assert_eq!(mesh.positions.len(), sphere.vertices.len());
        let area: f64 = mesh
            .triangles
            .iter()
            .map(|t| {
                let v = |i: u32| sphere.vertices[i as usize];
                0.5 * (v(t[1]) - v(t[0])).cross(&(v(t[2]) - v(t[0]))).norm()
            })
            .sum();
        let exact = 4.0 * std::f64::consts::PI * 0.05f64.powi(2);
        assert!((area - exact).abs() < 0.1 * exact, "{area} vs {exact}");
        // A quarter turn about z around a centre of mass at (0.1, 0, 0) in the hand frame.
        let half = std::f64::consts::FRAC_PI_4;
        let (t, r) = pose(
            [0.1, 0.0, 0.0],
            [half.cos(), 0.0, 0.0, half.sin()],
            &Vec3::zeros(),
        );
        let p = t + r * Vec3::new(0.05, 0.0, 0.0);
        assert!((p - Vec3::new(0.1, 0.05, 0.0)).norm() < 1e-12, "{p}");
        assert!((angle_deg(&p, &Vec3::new(0.1, 0.0, 0.0)) - 90.0).abs() < 1e-9);
    }

    #[test]
    fn unwrapped_angles_do_not_jump_at_half_a_turn() {
        let mut last = 170.0;
        let mut seen = vec![last];
        for raw in [178.0, -178.0, -170.0, 179.0, 10.0] {
            last = unwrap_deg(last, raw);
            seen.push(last);
        }
        assert_eq!(seen, vec![170.0, 178.0, 182.0, 190.0, 179.0, 10.0]);
        assert_eq!(unwrap_deg(720.0, 5.0), 725.0);
    }

    #[test]
    fn the_object_is_painted_by_sectors_of_longitude() {
        let sphere = Object::sphere(0.05, 24, 12).unwrap();
        let colours = object_colours(&sphere);
        assert_eq!(colours.len(), sphere.vertices.len());
        let distinct: std::collections::BTreeSet<u32> = colours.iter().copied().collect();
        assert_eq!(distinct.len(), 3, "{distinct:x?}");
        for (v, c) in sphere.vertices.iter().zip(&colours) {
            let lon = v.y.atan2(v.x).to_degrees();
            if (1.0..29.0).contains(&lon) && v.xy().norm() > 1e-3 {
                assert_eq!(*c, 0xf2f2f2ff, "{v}");
            }
        }
    }

    #[test]
    fn cone_edges_open_around_the_normal_at_the_friction_angle() {
        let p = Vec3::new(0.0, 0.05, 0.0);
        let n = Vec3::new(0.0, 1.0, 0.0);
        for (space, count) in [(Space::Planar, 2), (Space::Spatial, 8)] {
            let edges = cone_edges(&p, &n, 0.3, 8, space, 0.02);
            assert_eq!(edges.len(), count);
            for e in &edges {
                let d = Vec3::new(
                    (e[1][0] - e[0][0]) as f64,
                    (e[1][1] - e[0][1]) as f64,
                    (e[1][2] - e[0][2]) as f64,
                );
                assert!((d.norm() - 0.02).abs() < 1e-6);
                let angle = d.normalize().dot(&n).acos();
                assert!((angle - 0.3f64.atan()).abs() < 1e-5, "{angle}");
                if space == Space::Planar {
                    assert!(d.z.abs() < 1e-9);
                }
            }
        }
    }
}
