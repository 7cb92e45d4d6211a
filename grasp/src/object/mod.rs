//! Objects: closed polygonal surface meshes with candidate contact points.
//!
//! An [`Object`] is a closed, consistently oriented polygon mesh (counter-clockwise seen from
//! outside) in its body frame, built by [`Object::from_polygons`], which validates it, or by
//! the primitives ([`Object::sphere`], [`Object::ellipsoid`], [`Object::cuboid`],
//! [`Object::cylinder`]) and [`Object::from_file`] (STL or OBJ), which go through it.
//!
//! Candidate contact points come in two sets:
//! - [`Object::facets`]: one per non-degenerate face, at its area-weighted centroid, with its
//!   outward unit normal (Newell's method), area, and edge adjacency (for spatial problems);
//! - [`Object::section`]: the candidates in the hand's plane, the horizontal plane through
//!   the centre of mass (for the planar problem of the paper). Primitives get an analytic
//!   section; other meshes are cut with the plane.
//!
//! The centre of mass and volume are those of the solid bounded by the mesh, with uniform
//! density (divergence theorem).

mod distance;
mod error;
mod io;
mod primitives;
mod samples;
mod section;
mod validate;

pub use distance::closest_on_triangle;
pub use error::{MeshWarning, ObjectError};
pub use samples::{Adjacency, NearestPoints, Polygons, Section, SurfaceSamples};

use crate::math::{Isometry3, Real, Vec3};

/// A rigid object: a closed polygon mesh with its candidate contact points.
///
/// Everything is in the body frame. Built only through [`Object::from_polygons`] (directly or
/// via the primitives and [`Object::from_file`]), so the invariants below hold.
#[derive(Debug, Clone)]
pub struct Object {
    /// A name for messages and recordings (the file stem for meshes read from files).
    pub name: String,
    /// Vertex positions; every vertex is used by some face.
    pub vertices: Vec<Vec3>,
    /// Polygons (indices into `vertices`), counter-clockwise seen from outside; the surface
    /// is closed, each edge shared by exactly two faces traversing it in opposite directions.
    pub faces: Polygons,
    /// One candidate per non-degenerate face: area-weighted centroid, outward unit normal,
    /// area, and the faces sharing an edge with it.
    pub facets: SurfaceSamples,
    /// For each facet, the index of its face in `faces`.
    pub facet_faces: Vec<u32>,
    /// The candidates in the horizontal plane `z = centre_of_mass.z`.
    ///
    /// Primitives: analytic (see each constructor). Other meshes: the mesh cut by the plane,
    /// one sample per segment of the cut (its midpoint; the face normal projected into the
    /// plane and renormalised; the segment's length as `area`), stored loop after loop, each
    /// loop in order of travel with the outward normals on its right (counter-clockwise seen
    /// from +z for an outer boundary, clockwise around a hole), with previous/next adjacency
    /// along each loop. A vertex
    /// exactly on the plane counts as above it, and segments shorter than 1e-9 times the
    /// bounding-box diagonal are dropped, so there are no duplicate or zero-length samples.
    /// An empty cut or several loops are reported in `warnings`.
    pub section: Section,
    /// Centre of mass of the solid (uniform density).
    pub centre_of_mass: Vec3,
    /// Volume of the solid (positive).
    pub volume: Real,
    /// What was repaired or is worth knowing about the mesh.
    pub warnings: Vec<MeshWarning>,
}

impl Object {
    /// The largest distance of a vertex from the centre of mass: the default torque
    /// normalisation length rho.
    pub fn max_radius(&self) -> Real {
        self.vertices
            .iter()
            .map(|v| (v - self.centre_of_mass).norm())
            .fold(0.0, Real::max)
    }

    /// The same object moved rigidly by `motion`.
    ///
    /// Vertices, facets, centre of mass and the section's samples are all moved with it
    /// (normals rotated); areas, volume, faces and adjacency are unchanged. The section is
    /// *carried along*, not recut: sample `k` is the same material point before and after, and
    /// analytic sections stay exact. Its `height` becomes the new centre of mass's z and its
    /// `angles` are recomputed about the new centre of mass in the xy plane. For a motion
    /// whose rotation is about z the carried section is exactly the horizontal section of the
    /// moved object; for any other rotation it is not horizontal any more: to cut the moved
    /// object anew, pass its `vertices` and faces to [`Object::from_polygons`].
    pub fn transformed(&self, motion: &Isometry3) -> Object {
        let move_samples = |s: &SurfaceSamples| SurfaceSamples {
            points: s
                .points
                .iter()
                .map(|p| motion.transform_point(&(*p).into()).coords)
                .collect(),
            normals: s.normals.iter().map(|n| motion.rotation * n).collect(),
            areas: s.areas.clone(),
            adjacency: s.adjacency.clone(),
        };
        let centre_of_mass = motion.transform_point(&self.centre_of_mass.into()).coords;
        let section_samples = move_samples(&self.section.samples);
        let angles = section_samples
            .points
            .iter()
            .map(|p| samples::polar_angle(p, &centre_of_mass))
            .collect();
        Object {
            name: self.name.clone(),
            vertices: self
                .vertices
                .iter()
                .map(|v| motion.transform_point(&(*v).into()).coords)
                .collect(),
            faces: self.faces.clone(),
            facets: move_samples(&self.facets),
            facet_faces: self.facet_faces.clone(),
            section: Section {
                samples: section_samples,
                angles,
                height: centre_of_mass.z,
            },
            centre_of_mass,
            volume: self.volume,
            warnings: self.warnings.clone(),
        }
    }
}

#[cfg(test)]
mod tests {
    use std::f64::consts::PI;

    use super::*;
    use crate::math::UnitQuaternion;

    #[test]
    fn transformed_keeps_areas_and_moves_everything_consistently() {
        let o = Object::ellipsoid(Vec3::new(0.05, 0.04, 0.03), 24, 12).unwrap();
        let motion = Isometry3::from_parts(
            nalgebra::Translation3::new(0.1, -0.2, 0.3),
            UnitQuaternion::from_axis_angle(&Vec3::z_axis(), PI / 6.0),
        );
        let m = o.transformed(&motion);
        assert!((m.centre_of_mass - Vec3::new(0.1, -0.2, 0.3)).norm() < 1e-15);
        assert_eq!(m.facets.areas, o.facets.areas);
        assert_eq!(m.section.samples.areas, o.section.samples.areas);
        assert_eq!(m.volume, o.volume);
        assert!((m.max_radius() - o.max_radius()).abs() < 1e-15);
        assert!((m.section.height - 0.3).abs() < 1e-15);
        for k in 0..o.facets.len() {
            let expected = motion.transform_point(&o.facets.points[k].into()).coords;
            assert!((m.facets.points[k] - expected).norm() < 1e-15);
            assert!((m.facets.normals[k] - motion.rotation * o.facets.normals[k]).norm() < 1e-15);
            // Still outward.
            assert!(m.facets.normals[k].dot(&(m.facets.points[k] - m.centre_of_mass)) > 0.0);
        }
        // A rotation about z by 30 degrees shifts every section angle by 30 degrees.
        for k in 0..o.section.angles.len() {
            let d = samples::angular_distance(m.section.angles[k], o.section.angles[k] + PI / 6.0);
            assert!(d < 1e-12, "sample {k}: {d}");
            assert!((m.section.samples.points[k].z - 0.3).abs() < 1e-15);
        }
    }

    #[test]
    fn max_radius_of_a_box_is_half_its_diagonal() {
        let o = Object::cuboid(Vec3::new(1.0, 2.0, 2.0), 2).unwrap();
        assert!((o.max_radius() - 3.0).abs() < 1e-15);
    }
}
