//! `icrflow.Object`: a closed mesh with its candidate contact points.

use icrflow_grasp::math::{Real, Vec3};
use icrflow_grasp::object::{Object as Mesh, ObjectError};
use numpy::PyArrayDyn;
use pyo3::prelude::*;

use crate::convert::{self, Numbers, array_out, points_out, value_error};

/// A rigid object: a closed, consistently oriented polygon mesh in its body frame, with its
/// candidate contact points.
///
/// Build one with `Object.sphere`, `Object.ellipsoid`, `Object.mesh` (an STL or OBJ file)
/// or `Object.from_arrays` (vertices and faces, e.g. a `trimesh.Trimesh`'s). Every
/// constructor validates the mesh (closed, manifold, consistently oriented, non-zero
/// volume) and raises `ValueError` naming the face or vertex at fault.
///
/// Candidates: `facet_points` / `facet_normals` (one per non-degenerate face, at its
/// area-weighted centroid, outward unit normal) are the contacts of spatial problems;
/// `section_points` / `section_normals` (the cut by the horizontal plane through the centre
/// of mass) those of planar ones. Units are SI (metres).
#[pyclass(module = "icrflow", frozen)]
pub struct Object {
    pub(crate) inner: Mesh,
}

/// The message of an error and its sources, `a: b: c`.
pub fn chain(e: &dyn std::error::Error) -> String {
    let mut message = e.to_string();
    let mut source = e.source();
    while let Some(s) = source {
        message.push_str(": ");
        message.push_str(&s.to_string());
        source = s.source();
    }
    message
}

/// An object error as Python's: a missing or unreadable file is an `OSError`
/// (`FileNotFoundError`), everything else bad input (`ValueError`).
fn object_error(e: ObjectError) -> PyErr {
    if let ObjectError::ReadFile { source, .. } = &e {
        return convert::io_error(source.kind(), chain(&e));
    }
    value_error(chain(&e))
}

fn segments_arg(segments: (usize, usize)) -> PyResult<(usize, usize)> {
    if segments.0 < 3 || segments.1 < 2 {
        return Err(value_error(format!(
            "segments: needs at least (3, 2) (longitude, latitude), got {segments:?}"
        )));
    }
    Ok(segments)
}

#[pymethods]
impl Object {
    /// A UV sphere of `radius` (m) centred at the origin with `segments = (longitude,
    /// latitude)` faces (the paper's is 72 x 72 = 5184 facets). Its planar section is the
    /// equator's `longitude` points, at angles `2 pi k / longitude`.
    #[staticmethod]
    #[pyo3(signature = (radius, segments = (72, 72)))]
    fn sphere(radius: Real, segments: (usize, usize)) -> PyResult<Self> {
        let (lon, lat) = segments_arg(segments)?;
        let inner = Mesh::sphere(radius, lon, lat)
            .map_err(|e| value_error(format!("radius: {}", chain(&e))))?;
        Ok(Self { inner })
    }

    /// An ellipsoid with `semi_axes = (a, b, c)` (m) along x, y, z, centred at the origin:
    /// the `Object.sphere` mesh of radius 1 scaled by the semi-axes.
    #[staticmethod]
    #[pyo3(signature = (semi_axes, segments = (72, 72)))]
    fn ellipsoid(semi_axes: (Real, Real, Real), segments: (usize, usize)) -> PyResult<Self> {
        let (lon, lat) = segments_arg(segments)?;
        let axes = Vec3::new(semi_axes.0, semi_axes.1, semi_axes.2);
        let inner = Mesh::ellipsoid(axes, lon, lat).map_err(|e| value_error(chain(&e)))?;
        Ok(Self { inner })
    }

    /// Reads a closed mesh from an `.stl` (binary or ASCII) or `.obj` file. Vertices with
    /// equal coordinates are welded; OBJ polygons are kept as polygons. Raises
    /// `FileNotFoundError` for a missing file and `ValueError` for one that is not a valid
    /// closed mesh (naming the file and the face or vertex).
    #[staticmethod]
    fn mesh(path: &Bound<'_, PyAny>) -> PyResult<Self> {
        let path = convert::path_arg(path, "path")?;
        let inner = Mesh::from_file(&path).map_err(object_error)?;
        Ok(Self { inner })
    }

    /// Builds an object from `vertices` (an `(V, 3)` array, m) and `faces` (an `(F, k)`
    /// integer array of vertex indices, e.g. `trimesh.Trimesh.faces`, or a list of
    /// polygons of any sizes), each face counter-clockwise seen from outside (a mesh
    /// oriented entirely inward is reversed, with a warning). Vertices are used as given
    /// (not welded): pass a watertight mesh's shared vertices.
    #[staticmethod]
    #[pyo3(signature = (vertices, faces, name = "arrays"))]
    fn from_arrays(
        vertices: &Bound<'_, PyAny>,
        faces: &Bound<'_, PyAny>,
        name: &str,
    ) -> PyResult<Self> {
        let v = convert::real_array(
            vertices,
            "vertices",
            &[None, Some(3)],
            "an array of shape (V, 3)",
        )?;
        let v = v.as_array();
        let points: Vec<Vec3> = (0..v.shape()[0])
            .map(|i| convert::point(&v, &[i]))
            .collect();
        let polygons = face_lists(faces, points.len())?;
        let inner = Mesh::from_polygons(name, points, polygons).map_err(object_error)?;
        Ok(Self { inner })
    }

    /// The name (the file stem for meshes read from files).
    #[getter]
    fn name(&self) -> &str {
        &self.inner.name
    }

    /// Vertex positions, `(V, 3)` (m); every vertex is used by a face.
    #[getter]
    fn vertices<'py>(&self, py: Python<'py>) -> Bound<'py, PyArrayDyn<f64>> {
        points_out(py, self.inner.vertices.iter().copied())
    }

    /// The faces, a list of vertex-index lists (counter-clockwise seen from outside).
    #[getter]
    fn faces(&self) -> Vec<Vec<u32>> {
        self.inner.faces.iter().map(<[u32]>::to_vec).collect()
    }

    /// Candidate points of spatial problems: one per non-degenerate face, `(m, 3)` (m).
    #[getter]
    fn facet_points<'py>(&self, py: Python<'py>) -> Bound<'py, PyArrayDyn<f64>> {
        points_out(py, self.inner.facets.points.iter().copied())
    }

    /// Outward unit normals of the facets, `(m, 3)`.
    #[getter]
    fn facet_normals<'py>(&self, py: Python<'py>) -> Bound<'py, PyArrayDyn<f64>> {
        points_out(py, self.inner.facets.normals.iter().copied())
    }

    /// Candidate points of planar problems: the section by the plane `z = centre_of_mass.z`,
    /// `(k, 3)` (m).
    #[getter]
    fn section_points<'py>(&self, py: Python<'py>) -> Bound<'py, PyArrayDyn<f64>> {
        points_out(py, self.inner.section.samples.points.iter().copied())
    }

    /// Outward unit normals of the section's points (in the plane), `(k, 3)`.
    #[getter]
    fn section_normals<'py>(&self, py: Python<'py>) -> Bound<'py, PyArrayDyn<f64>> {
        points_out(py, self.inner.section.samples.normals.iter().copied())
    }

    /// Angles of the section's points about the centre of mass, radians in [0, 2 pi), `(k,)`.
    #[getter]
    fn section_angles<'py>(&self, py: Python<'py>) -> Bound<'py, PyArrayDyn<f64>> {
        let a = self.inner.section.angles.clone();
        let n = a.len();
        array_out(py, a, &[n])
    }

    /// Centre of mass of the solid (uniform density), `(3,)` (m).
    #[getter]
    fn centre_of_mass<'py>(&self, py: Python<'py>) -> Bound<'py, PyArrayDyn<f64>> {
        let c = self.inner.centre_of_mass;
        array_out(py, vec![c.x, c.y, c.z], &[3])
    }

    /// Volume of the solid (m^3).
    #[getter]
    fn volume(&self) -> Real {
        self.inner.volume
    }

    /// Largest distance of a vertex from the centre of mass (m): the default `rho`.
    #[getter]
    fn max_radius(&self) -> Real {
        self.inner.max_radius()
    }

    /// What was repaired or is worth knowing about the mesh (one sentence each).
    #[getter]
    fn warnings(&self) -> Vec<String> {
        self.inner.warnings.iter().map(|w| w.to_string()).collect()
    }

    fn __repr__(&self) -> String {
        format!(
            "Object(name={:?}, vertices={}, faces={}, facets={}, section_points={})",
            self.inner.name,
            self.inner.vertices.len(),
            self.inner.faces.len(),
            self.inner.facets.len(),
            self.inner.section.samples.len()
        )
    }
}

/// Faces as vertex-index lists: an `(F, k)` integer array, or a sequence of sequences.
fn face_lists(faces: &Bound<'_, PyAny>, vertex_count: usize) -> PyResult<Vec<Vec<u32>>> {
    let index = |face: usize, v: i64| -> PyResult<u32> {
        if v < 0 || v as u64 >= vertex_count as u64 {
            return Err(value_error(format!(
                "faces[{face}]: vertex index {v} out of range (there are {vertex_count} vertices)"
            )));
        }
        Ok(v as u32)
    };
    // A rectangular integer array (trimesh's faces): read in place.
    if let Ok(Numbers::Integer(a)) = convert::numbers(faces, "faces") {
        let a = a.as_array();
        if a.ndim() != 2 {
            return Err(value_error(format!(
                "faces: expected an (F, k) array of vertex indices or a list of polygons, got an array of shape {}",
                convert::shape_str(a.shape())
            )));
        }
        return a
            .outer_iter()
            .enumerate()
            .map(|(f, row)| row.iter().map(|&v| index(f, v)).collect())
            .collect();
    }
    // Polygons of different sizes.
    let mut out = Vec::new();
    for (f, face) in faces
        .try_iter()
        .map_err(|_| {
            value_error("faces: expected an (F, k) array of vertex indices or a list of polygons")
        })?
        .enumerate()
    {
        let face = face?;
        let ids: Vec<i64> = face.extract().map_err(|_| {
            value_error(format!(
                "faces[{f}]: expected a sequence of vertex indices (integers)"
            ))
        })?;
        out.push(
            ids.into_iter()
                .map(|v| index(f, v))
                .collect::<PyResult<Vec<u32>>>()?,
        );
    }
    Ok(out)
}
