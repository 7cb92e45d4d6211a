//! The planar section of a mesh: its intersection with the horizontal plane through the
//! centre of mass.

use std::collections::HashMap;

use super::Object;
use super::error::MeshWarning;
use super::samples::{Polygons, Section, SurfaceSamples, loop_adjacency, polar_angle};
use super::validate::diagonal;
use crate::math::{Real, Vec3};

/// Segments shorter than this times the bounding-box diagonal are dropped.
const MIN_SEGMENT: Real = 1e-9;

/// Cuts `object` with the plane `z = centre_of_mass.z`; a warning if the plane misses the
/// surface or cuts it in several loops.
pub(super) fn mesh_section(object: &Object) -> (Section, Vec<MeshWarning>) {
    let mut normals = vec![None; object.faces.len()];
    for (k, &f) in object.facet_faces.iter().enumerate() {
        normals[f as usize] = Some(object.facets.normals[k]);
    }
    let min_length = MIN_SEGMENT * diagonal(&object.vertices);
    let (section, loops) = cut(
        &object.vertices,
        &object.faces,
        &normals,
        &object.centre_of_mass,
        min_length,
    );
    let height = section.height;
    let warnings = match loops {
        0 => vec![MeshWarning::SectionEmpty { height }],
        1 => vec![],
        loops => vec![MeshWarning::SectionLoops { loops, height }],
    };
    (section, warnings)
}

/// One piece of the cut: from crossing `start` to crossing `end`, inside face `face`.
#[derive(Debug, Clone, Copy)]
struct Piece {
    start: usize,
    end: usize,
    face: usize,
}

/// Intersects the closed surface with the plane `z = centre.z`.
///
/// A vertex is *below* if `z < height`, otherwise above (on the plane counts as above), so
/// every edge with one end below and one above crosses the plane once, at a point computed
/// once per edge (exactly the vertex if it lies on the plane). Each face contributes
/// segments joining its crossings (paired in order along the cut line when a non-convex face
/// has more than two); as every crossed edge belongs to exactly two faces, the segments chain
/// into closed loops. Each loop is oriented with the outward normals on the right of the
/// direction of travel (counter-clockwise seen from +z around the material), and segments
/// shorter than
/// `min_length` are dropped (they arise where the plane passes through vertices). Each
/// remaining segment gives a sample: its midpoint, the face normal projected into the plane
/// and renormalised (the in-plane perpendicular of the segment if the face is degenerate or
/// nearly horizontal), and its length. Returns the section and the number of non-empty loops.
fn cut(
    vertices: &[Vec3],
    faces: &Polygons,
    normals: &[Option<Vec3>],
    centre: &Vec3,
    min_length: Real,
) -> (Section, usize) {
    let height = centre.z;
    let below = |v: u32| vertices[v as usize].z < height;
    let mut crossing_of: HashMap<(u32, u32), usize> = HashMap::new();
    let mut points: Vec<Vec3> = Vec::new();
    let mut pieces: Vec<Piece> = Vec::new();
    for (face, polygon) in faces.iter().enumerate() {
        let mut here: Vec<usize> = Vec::new();
        for (&a, &b) in polygon.iter().zip(polygon.iter().cycle().skip(1)) {
            if below(a) == below(b) {
                continue;
            }
            let (lo, hi) = if below(a) { (a, b) } else { (b, a) };
            let index = *crossing_of.entry((lo, hi)).or_insert_with(|| {
                points.push(crossing_point(
                    vertices[lo as usize],
                    vertices[hi as usize],
                    height,
                ));
                points.len() - 1
            });
            here.push(index);
        }
        if here.len() > 2 {
            // Collinear crossings of a non-convex face: pair them in order along the line.
            let origin = points[here[0]];
            let far = here
                .iter()
                .map(|&c| points[c] - origin)
                .max_by(|p, q| p.norm_squared().total_cmp(&q.norm_squared()))
                .unwrap_or_else(Vec3::zeros);
            here.sort_by(|&p, &q| {
                (points[p] - origin)
                    .dot(&far)
                    .total_cmp(&(points[q] - origin).dot(&far))
            });
        }
        for pair in here.chunks_exact(2) {
            pieces.push(Piece {
                start: pair[0],
                end: pair[1],
                face,
            });
        }
    }

    let loops = chain(&pieces, points.len());
    let mut samples = SurfaceSamples::default();
    let mut loop_lengths = Vec::new();
    for mut pieces_of_loop in loops {
        let direction = |p: &Piece| points[p.end] - points[p.start];
        let vote: Real = pieces_of_loop
            .iter()
            .filter_map(|p| normals[p.face].map(|n| outward_side(&direction(p)).dot(&n)))
            .sum();
        if vote < 0.0 {
            pieces_of_loop.reverse();
            for p in &mut pieces_of_loop {
                std::mem::swap(&mut p.start, &mut p.end);
            }
        }
        let before = samples.len();
        for p in &pieces_of_loop {
            let d = direction(p);
            let length = d.norm();
            if length <= min_length {
                continue;
            }
            let projected = normals[p.face].map(|n| Vec3::new(n.x, n.y, 0.0));
            let normal = match projected {
                Some(n) if n.norm() > 1e-6 => n.normalize(),
                _ => outward_side(&d).normalize(),
            };
            samples.points.push((points[p.start] + points[p.end]) / 2.0);
            samples.normals.push(normal);
            samples.areas.push(length);
        }
        if samples.len() > before {
            loop_lengths.push(samples.len() - before);
        }
    }
    samples.adjacency = loop_adjacency(&loop_lengths);
    let angles = samples
        .points
        .iter()
        .map(|p| polar_angle(p, centre))
        .collect();
    (
        Section {
            samples,
            angles,
            height,
        },
        loop_lengths.len(),
    )
}

/// The in-plane vector on the right of direction `d` (seen from +z): `d x z`.
fn outward_side(d: &Vec3) -> Vec3 {
    Vec3::new(d.y, -d.x, 0.0)
}

/// Where the edge from `lo` (below) to `hi` (on or above) meets the plane.
fn crossing_point(lo: Vec3, hi: Vec3, height: Real) -> Vec3 {
    if hi.z == height {
        return hi;
    }
    let t = (height - lo.z) / (hi.z - lo.z);
    let mut p = lo + (hi - lo) * t;
    p.z = height;
    p
}

/// Chains pieces sharing crossings into closed loops (each crossing joins exactly two pieces
/// on a closed manifold surface); the pieces of a loop are returned in order of travel.
fn chain(pieces: &[Piece], crossing_count: usize) -> Vec<Vec<Piece>> {
    const NONE: usize = usize::MAX;
    let mut incident = vec![[NONE; 2]; crossing_count];
    for (i, p) in pieces.iter().enumerate() {
        for c in [p.start, p.end] {
            if let Some(slot) = incident[c].iter_mut().find(|s| **s == NONE) {
                *slot = i;
            }
        }
    }
    let mut used = vec![false; pieces.len()];
    let mut loops = Vec::new();
    for first in 0..pieces.len() {
        if used[first] {
            continue;
        }
        let mut this_loop = Vec::new();
        let (mut current, mut at) = (first, pieces[first].start);
        loop {
            used[current] = true;
            let p = pieces[current];
            let travelled = if p.start == at {
                p
            } else {
                Piece {
                    start: p.end,
                    end: p.start,
                    face: p.face,
                }
            };
            this_loop.push(travelled);
            at = travelled.end;
            let [x, y] = incident[at];
            let next = if x == current { y } else { x };
            if next == NONE || used[next] {
                break;
            }
            current = next;
        }
        loops.push(this_loop);
    }
    loops
}

#[cfg(test)]
mod tests {
    use std::f64::consts::PI;

    use super::*;
    use crate::object::validate::tests::cube;

    /// The regular octahedron with vertices at +-1 on the axes.
    fn octahedron() -> (Vec<Vec3>, Polygons) {
        let v = vec![
            Vec3::x(),
            Vec3::y(),
            -Vec3::x(),
            -Vec3::y(),
            Vec3::z(),
            -Vec3::z(),
        ];
        let mut faces = Vec::new();
        for k in 0..4u32 {
            faces.push(vec![4, k, (k + 1) % 4]);
            faces.push(vec![5, (k + 1) % 4, k]);
        }
        (v, Polygons::from_lists(&faces))
    }

    fn normals(v: &[Vec3], f: &Polygons) -> Vec<Option<Vec3>> {
        f.iter()
            .map(|p| {
                let (a, b, c) = (v[p[0] as usize], v[p[1] as usize], v[p[2] as usize]);
                Some((b - a).cross(&(c - a)).normalize())
            })
            .collect()
    }

    #[test]
    fn cube_section_is_its_four_sides() {
        let (v, f) = cube();
        let o = Object::from_polygons("cube", v, f).unwrap();
        let s = &o.section;
        assert_eq!(s.height, 0.5);
        assert_eq!(s.samples.len(), 4);
        assert!((s.samples.areas.iter().sum::<Real>() - 4.0).abs() < 1e-15);
        for k in 0..4 {
            let p = s.samples.points[k];
            let n = s.samples.normals[k];
            assert_eq!(p.z, 0.5);
            // Midpoint of a side, normal pointing away from the centre.
            assert!((p - Vec3::new(0.5, 0.5, 0.5) - n / 2.0).norm() < 1e-15);
            assert_eq!(s.samples.adjacency.neighbours(k).len(), 2);
        }
        // Counter-clockwise seen from +z: angles increase along the loop.
        let mut order: Vec<Real> = s.angles.clone();
        let start = order
            .iter()
            .cloned()
            .enumerate()
            .min_by(|a, b| a.1.total_cmp(&b.1))
            .unwrap()
            .0;
        order.rotate_left(start);
        assert!(order.windows(2).all(|w| w[0] < w[1]), "{order:?}");
    }

    #[test]
    fn vertices_on_the_plane_give_no_duplicates() {
        let (v, f) = octahedron();
        let n = normals(&v, &f);
        // Four vertices lie exactly on z = 0.
        let (s, loops) = cut(&v, &f, &n, &Vec3::zeros(), 1e-12);
        assert_eq!(loops, 1);
        assert_eq!(s.samples.len(), 4);
        for k in 0..4 {
            assert!((s.samples.areas[k] - 2f64.sqrt()).abs() < 1e-15);
            let p = s.samples.points[k];
            assert!((p.x.abs() - 0.5).abs() < 1e-15 && (p.y.abs() - 0.5).abs() < 1e-15);
            let expected = Vec3::new(p.x, p.y, 0.0).normalize();
            assert!((s.samples.normals[k] - expected).norm() < 1e-15);
            assert!((s.angles[k] % (PI / 2.0) - PI / 4.0).abs() < 1e-12);
        }
        // Through a vertex where the surface only touches the plane: nothing.
        for z in [1.0, -1.0] {
            let (s, loops) = cut(&v, &f, &n, &Vec3::new(0.0, 0.0, z), 1e-12);
            assert_eq!((s.samples.len(), loops), (0, 0));
        }
    }

    #[test]
    fn non_convex_face_crossings_are_paired_along_the_line() {
        // A U-shaped prism: the front and back faces are U-shaped octagons, cut across both
        // arms (4 crossings each), giving two loops.
        let u = [
            (0.0, 0.0),
            (3.0, 0.0),
            (3.0, 2.0),
            (2.0, 2.0),
            (2.0, 1.0),
            (1.0, 1.0),
            (1.0, 2.0),
            (0.0, 2.0),
        ];
        // The U lies in the xz plane (z up), extruded along y from 0 to 1.
        let mut v: Vec<Vec3> = u.iter().map(|&(x, z)| Vec3::new(x, 0.0, z)).collect();
        v.extend(u.iter().map(|&(x, z)| Vec3::new(x, 1.0, z)));
        let m = u.len() as u32;
        // Front face y = 0: seen from -y (outside) with z up, x points right, so the U order
        // (counter-clockwise in x-z) is counter-clockwise seen from outside.
        let mut faces = vec![
            (0..m).collect::<Vec<u32>>(),
            (0..m).rev().map(|i| i + m).collect(),
        ];
        for i in 0..m {
            let j = (i + 1) % m;
            faces.push(vec![j, i, i + m, j + m]);
        }
        let o = Object::from_polygons("u", v, faces).unwrap();
        // At its own centre of mass (z = 0.9, below the arms) the cut is a single loop.
        assert!(o.warnings.is_empty(), "{:?}", o.warnings);
        assert!((o.section.height - 0.9).abs() < 1e-15);
        let (s, loops) = cut(
            &o.vertices,
            &o.faces,
            &normals(&o.vertices, &o.faces),
            &Vec3::new(1.5, 0.5, 1.5),
            1e-12,
        );
        assert_eq!(loops, 2);
        assert_eq!(s.samples.len(), 8);
        // Each arm's cut is a unit square: perimeter 4.
        assert!((s.samples.areas.iter().sum::<Real>() - 8.0).abs() < 1e-14);
        for k in 0..8 {
            assert_eq!(s.samples.adjacency.neighbours(k).len(), 2);
            let n = s.samples.normals[k];
            assert!((n.norm() - 1.0).abs() < 1e-15 && n.z == 0.0);
        }
    }

    #[test]
    fn cutting_the_sphere_mesh_through_its_equator_ring() {
        let sphere = Object::sphere(1.0, 72, 72).unwrap();
        let faces = sphere.faces.iter().map(<[u32]>::to_vec).collect();
        let o = Object::from_polygons("cut", sphere.vertices.clone(), faces).unwrap();
        assert!(o.warnings.is_empty(), "{:?}", o.warnings);
        // Whichever side of the ring of vertices the computed centre of mass falls on, the
        // cut is the 72-gon of the equator: no duplicates, no zero-length pieces.
        assert!(o.section.height.abs() < 1e-12, "{}", o.section.height);
        assert_eq!(o.section.samples.len(), 72);
        let chord = 2.0 * (PI / 72.0).sin();
        for k in 0..72 {
            assert!((o.section.samples.areas[k] - chord).abs() < 1e-12);
            assert!((o.section.samples.normals[k].norm() - 1.0).abs() < 1e-15);
        }
    }

    #[test]
    fn two_separate_cubes_give_two_loops_and_a_warning() {
        let (v, f) = cube();
        let mut vertices = v.clone();
        vertices.extend(v.iter().map(|p| p + Vec3::new(3.0, 0.0, 0.0)));
        let mut faces = f.clone();
        faces.extend(
            f.iter()
                .map(|p| p.iter().map(|i| i + 8).collect::<Vec<u32>>()),
        );
        let o = Object::from_polygons("two", vertices, faces).unwrap();
        assert_eq!(
            o.warnings,
            vec![MeshWarning::SectionLoops {
                loops: 2,
                height: 0.5
            }]
        );
        assert_eq!(o.section.samples.len(), 8);
        assert!((o.volume - 2.0).abs() < 1e-14);
        assert!((o.centre_of_mass - Vec3::new(2.0, 0.5, 0.5)).norm() < 1e-14);
    }

    #[test]
    fn a_plane_missing_the_surface_is_reported() {
        // A cube sitting above a second one with nothing crossing the com plane: two cubes
        // stacked with a gap, so z = com.z falls in the gap.
        let (v, f) = cube();
        let mut vertices = v.clone();
        vertices.extend(v.iter().map(|p| p + Vec3::new(0.0, 0.0, 2.0)));
        let mut faces = f.clone();
        faces.extend(
            f.iter()
                .map(|p| p.iter().map(|i| i + 8).collect::<Vec<u32>>()),
        );
        let o = Object::from_polygons("gap", vertices, faces).unwrap();
        assert!(o.section.samples.is_empty());
        assert!(
            matches!(o.warnings[..], [MeshWarning::SectionEmpty { height }] if (height - 1.5).abs() < 1e-15)
        );
    }
}
