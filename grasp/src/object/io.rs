//! Reading meshes from STL and OBJ files, writing binary STL.

use std::collections::HashMap;
use std::io::{BufReader, Cursor};
use std::path::Path;

use super::Object;
use super::error::ObjectError;
use super::validate::face_geometry;
use crate::math::Vec3;
use crate::progress::{Progress, Silent, Stage, tick};

impl Object {
    /// Reads a closed mesh from an `.stl` (binary or ASCII) or `.obj` file, chosen by the
    /// extension (case-insensitive), and builds it with [`Object::from_polygons`].
    ///
    /// Vertices with exactly equal coordinates are welded first (STL repeats every vertex in
    /// each triangle; OBJ objects and groups can repeat them too), `-0.0` counting as `0.0`.
    /// OBJ polygons are kept as polygons (not triangulated); point and line elements, normals,
    /// texture coordinates and materials are ignored. The object's name is the file stem.
    ///
    /// Errors: [`ObjectError::UnsupportedExtension`], [`ObjectError::ReadFile`],
    /// [`ObjectError::Parse`] (including an empty file), or any validation error wrapped in
    /// [`ObjectError::InvalidMesh`] with the path.
    pub fn from_file(path: &Path) -> Result<Object, ObjectError> {
        Self::from_file_with(path, &mut Silent)
    }

    /// [`Object::from_file`], reporting its stages to `progress` ([`Stage::Read`],
    /// [`Stage::Weld`], then those of [`Object::from_polygons_with`]).
    pub fn from_file_with(path: &Path, progress: &mut dyn Progress) -> Result<Object, ObjectError> {
        let extension = path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase);
        let parse: fn(&[u8], &mut dyn Progress) -> Result<RawMesh, String> =
            match extension.as_deref() {
                Some("stl") => parse_stl,
                Some("obj") => parse_obj,
                _ => {
                    return Err(ObjectError::UnsupportedExtension {
                        path: path.to_owned(),
                    });
                }
            };
        let format = if extension.as_deref() == Some("stl") {
            "STL"
        } else {
            "OBJ"
        };
        let bytes = std::fs::read(path).map_err(|source| ObjectError::ReadFile {
            path: path.to_owned(),
            source,
        })?;
        let parse_error = |message: String| ObjectError::Parse {
            path: path.to_owned(),
            format,
            message,
        };
        if bytes.is_empty() {
            return Err(parse_error("the file is empty".to_owned()));
        }
        let (vertices, faces) = parse(&bytes, progress).map_err(parse_error)?;
        drop(bytes);
        let (vertices, faces) = weld(&vertices, faces, progress);
        let name = path
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default();
        Object::from_polygons_with(&name, vertices, faces, progress).map_err(|e| {
            ObjectError::InvalidMesh {
                path: path.to_owned(),
                source: Box::new(e),
            }
        })
    }

    /// Writes the surface as a binary STL file: each face fan-triangulated from its first
    /// vertex (exact for convex faces, which all primitives have), every triangle carrying its
    /// face's Newell normal, coordinates rounded to `f32` as the format requires.
    ///
    /// Errors: [`ObjectError::WriteFile`] with the path.
    pub fn write_stl(&self, path: &Path) -> Result<(), ObjectError> {
        let write_error = |source| ObjectError::WriteFile {
            path: path.to_owned(),
            source,
        };
        let f32s = |v: Vec3| [v.x as f32, v.y as f32, v.z as f32];
        let mut triangles = Vec::new();
        for face in self.faces.iter() {
            let normal =
                face_geometry(&self.vertices, face, 0.0).map_or(Vec3::zeros(), |g| g.normal);
            let corner = |i: u32| stl_io::Vertex::new(f32s(self.vertices[i as usize]));
            for w in face[1..].windows(2) {
                triangles.push(stl_io::Triangle {
                    normal: stl_io::Normal::new(f32s(normal)),
                    vertices: [corner(face[0]), corner(w[0]), corner(w[1])],
                });
            }
        }
        if u32::try_from(triangles.len()).is_err() {
            return Err(write_error(std::io::Error::other(
                "too many triangles for binary STL",
            )));
        }
        let mut file = std::fs::File::create(path).map_err(write_error)?;
        stl_io::write_stl(&mut file, triangles.iter()).map_err(write_error)
    }
}

/// Vertices and polygons as read from a file, before welding and validation.
type RawMesh = (Vec<Vec3>, Vec<Vec<u32>>);

/// Reads binary or ASCII STL with `stl_io`. A binary file whose 80-byte header happens to
/// start with `solid` (some exporters write that) would be taken for ASCII, so a file whose
/// size is exactly that of a binary STL with its stated triangle count is read as binary.
fn parse_stl(bytes: &[u8], progress: &mut dyn Progress) -> Result<RawMesh, String> {
    let mut bytes = std::borrow::Cow::Borrowed(bytes);
    if let Some(count) = bytes.get(80..84) {
        let count = u32::from_le_bytes([count[0], count[1], count[2], count[3]]) as u64;
        if bytes.starts_with(b"solid") && bytes.len() as u64 == 84 + 50 * count {
            bytes.to_mut()[0] = 0; // the header is not data: make the ASCII probe fail
        }
    }
    let mut cursor = Cursor::new(bytes.as_ref());
    let reader = stl_io::create_stl_reader(&mut cursor).map_err(|e| e.to_string())?;
    // A binary file's stated count (an ASCII file's is not known before the end); what is
    // reserved is bounded by the file's size, whatever the header says.
    let stated = reader.size_hint().1.unwrap_or(0);
    let reserve = stated.min(bytes.len() / 50);
    let mut vertices = Vec::with_capacity(3 * reserve);
    let mut faces = Vec::with_capacity(reserve);
    progress.report(Stage::Read, 0, stated);
    for (i, triangle) in reader.enumerate() {
        tick(progress, Stage::Read, i, stated);
        let triangle = triangle.map_err(|e| format!("triangle {i}: {e}"))?;
        let first = u32::try_from(vertices.len())
            .ok()
            .filter(|f| f.checked_add(2).is_some())
            .ok_or_else(|| format!("triangle {i}: too many vertices"))?;
        for v in triangle.vertices {
            vertices.push(Vec3::new(v[0].into(), v[1].into(), v[2].into()));
        }
        faces.push(vec![first, first + 1, first + 2]);
    }
    progress.report(Stage::Read, faces.len(), faces.len());
    Ok((vertices, faces))
}

fn parse_obj(bytes: &[u8], progress: &mut dyn Progress) -> Result<RawMesh, String> {
    progress.report(Stage::Read, 0, 0);
    let options = tobj::LoadOptions {
        single_index: false,
        triangulate: false,
        ignore_points: true,
        ignore_lines: true,
    };
    let (models, _materials) =
        tobj::load_obj_buf(&mut BufReader::new(Cursor::new(bytes)), &options, |_| {
            Err(tobj::LoadError::OpenFileFailed)
        })
        .map_err(|e| e.to_string())?;
    let mut vertices = Vec::new();
    let mut faces = Vec::new();
    for model in models {
        let mesh = &model.mesh;
        let base = vertices.len() as u32;
        vertices.extend(
            mesh.positions
                .chunks_exact(3)
                .map(|p| Vec3::new(p[0].into(), p[1].into(), p[2].into())),
        );
        let mut start = 0;
        let arities: Vec<usize> = if mesh.face_arities.is_empty() {
            vec![3; mesh.indices.len() / 3]
        } else {
            mesh.face_arities.iter().map(|&a| a as usize).collect()
        };
        for arity in arities {
            let Some(face) = mesh.indices.get(start..start + arity) else {
                return Err(format!("object {:?}: face indices end early", model.name));
            };
            faces.push(face.iter().map(|&i| base + i).collect());
            start += arity;
        }
    }
    progress.report(Stage::Read, faces.len(), faces.len());
    Ok((vertices, faces))
}

/// Merges vertices with exactly equal coordinates (`-0.0 == 0.0`; NaN coordinates are kept
/// distinct, for validation to report).
fn weld(
    vertices: &[Vec3],
    mut faces: Vec<Vec<u32>>,
    progress: &mut dyn Progress,
) -> (Vec<Vec3>, Vec<Vec<u32>>) {
    let key = |v: &Vec3| v.map(|c| (c + 0.0).to_bits());
    let mut index: HashMap<_, u32> = HashMap::with_capacity(vertices.len());
    let mut welded = Vec::with_capacity(vertices.len());
    let mut new_index = Vec::with_capacity(vertices.len());
    let total = vertices.len();
    progress.report(Stage::Weld, 0, total);
    for (k, v) in vertices.iter().enumerate() {
        tick(progress, Stage::Weld, k, total);
        let i = if v.iter().all(|c| c.is_finite()) {
            *index.entry(key(v)).or_insert_with(|| {
                welded.push(*v);
                (welded.len() - 1) as u32
            })
        } else {
            welded.push(*v);
            (welded.len() - 1) as u32
        };
        new_index.push(i);
    }
    for i in faces.iter_mut().flatten() {
        // Out-of-range indices are left for validation to report.
        if let Some(&n) = new_index.get(*i as usize) {
            *i = n;
        }
    }
    progress.report(Stage::Weld, total, total);
    (welded, faces)
}

/// A path for a test file in the system's temporary directory, unique to this process.
#[cfg(test)]
pub(super) fn temp_path(name: &str) -> std::path::PathBuf {
    std::env::temp_dir().join(format!("icrflow-object-{}-{name}", std::process::id()))
}

#[cfg(test)]
mod tests {
    use std::path::PathBuf;

    use super::*;
    use crate::math::Real;
    use crate::object::MeshWarning;

    fn write(name: &str, contents: &str) -> PathBuf {
        let path = temp_path(name);
        std::fs::write(&path, contents).unwrap();
        path
    }

    #[test]
    fn binary_stl_round_trip_keeps_facets() {
        let o = Object::sphere(0.05, 24, 12).unwrap();
        let path = temp_path("sphere.STL");
        o.write_stl(&path).unwrap();
        let back = Object::from_file(&path).unwrap();
        std::fs::remove_file(&path).unwrap();
        assert_eq!(
            back.name,
            "icrflow-object-".to_owned() + &std::process::id().to_string() + "-sphere"
        );
        // Quads are split into two triangles: 2 x 24 pole triangles + 2 x 24 x 10 quads.
        assert_eq!(back.facets.len(), 2 * 24 + 2 * 24 * 10);
        assert_eq!(back.vertices.len(), o.vertices.len());
        assert!(back.warnings.is_empty(), "{:?}", back.warnings);
        let (a, b): (Real, Real) = (o.facets.areas.iter().sum(), back.facets.areas.iter().sum());
        assert!((a - b).abs() / a < 1e-6, "{a} vs {b}");
        assert!((o.volume - back.volume).abs() / o.volume < 1e-6);
        assert!(back.centre_of_mass.norm() < 1e-8);
    }

    #[test]
    fn binary_stl_with_a_solid_header_is_read_as_binary() {
        let o = Object::cuboid(Vec3::new(1.0, 2.0, 3.0), 1).unwrap();
        let path = temp_path("solid-header.stl");
        o.write_stl(&path).unwrap();
        let mut bytes = std::fs::read(&path).unwrap();
        bytes[..11].copy_from_slice(b"solid box\n\n");
        std::fs::write(&path, &bytes).unwrap();
        let back = Object::from_file(&path).unwrap();
        std::fs::remove_file(&path).unwrap();
        assert_eq!(back.facets.len(), 12);
        assert!((back.volume - 48.0).abs() < 1e-12);
    }

    #[test]
    fn ascii_stl_round_trip_keeps_facets() {
        // Write the binary file's triangles back out as ASCII STL.
        let o = Object::cuboid(crate::math::Vec3::new(0.5, 1.0, 1.5), 2).unwrap();
        let mut text = String::from("solid box\n");
        for face in o.faces.iter() {
            for w in face[1..].windows(2) {
                text += "facet normal 0 0 0\nouter loop\n";
                for i in [face[0], w[0], w[1]] {
                    let v = o.vertices[i as usize];
                    text += &format!("vertex {} {} {}\n", v.x, v.y, v.z);
                }
                text += "endloop\nendfacet\n";
            }
        }
        text += "endsolid box\n";
        let path = write("box.stl", &text);
        let back = Object::from_file(&path).unwrap();
        std::fs::remove_file(&path).unwrap();
        assert_eq!(back.facets.len(), 2 * o.facets.len());
        assert!((back.volume - 6.0).abs() < 1e-12);
        let total: Real = back.facets.areas.iter().sum();
        assert!((total - o.facets.areas.iter().sum::<Real>()).abs() < 1e-12);
        // The cut runs along the ring of vertices at z = 0: one sample per mesh edge of it
        // (the zero-length pieces through those vertices are dropped), 2 per side.
        assert_eq!(back.section.samples.len(), 8);
        assert!((back.section.samples.areas.iter().sum::<Real>() - 6.0).abs() < 1e-12);
    }

    #[test]
    fn hand_written_ascii_stl_tetrahedron() {
        let text = "solid tet
  facet normal 0 0 -1
    outer loop
      vertex 0 0 0
      vertex 0 1 0
      vertex 1 0 0
    endloop
  endfacet
  facet normal 0 -1 0
    outer loop
      vertex 0 0 0
      vertex 1 0 0
      vertex 0 0 1
    endloop
  endfacet
  facet normal -1 0 0
    outer loop
      vertex 0 0 0
      vertex 0 0 1
      vertex 0 1 0
    endloop
  endfacet
  facet normal 1 1 1
    outer loop
      vertex 1 0 0
      vertex 0 1 0
      vertex 0 0 1
    endloop
  endfacet
endsolid tet
";
        let path = write("tet.stl", text);
        let o = Object::from_file(&path).unwrap();
        std::fs::remove_file(&path).unwrap();
        assert_eq!(o.name, format!("icrflow-object-{}-tet", std::process::id()));
        assert_eq!(o.vertices.len(), 4);
        assert!((o.volume - 1.0 / 6.0).abs() < 1e-15);
        assert!((o.centre_of_mass - Vec3::repeat(0.25)).norm() < 1e-15);
        let slanted = o.facets.normals[3];
        assert!((slanted - Vec3::repeat(1.0 / 3f64.sqrt())).norm() < 1e-15);
        // The plane z = 1/4 cuts a triangle: 3 samples.
        assert_eq!(o.section.samples.len(), 3);
        assert!(o.warnings.is_empty());
    }

    #[test]
    fn hand_written_obj_cube_with_quads() {
        let text = "# unit cube
o cube
v 0 0 0
v 1 0 0
v 0 1 0
v 1 1 0
v 0 0 1
v 1 0 1
v 0 1 1
v 1 1 1
f 1 3 4 2
f 5 6 8 7
f 1 2 6 5
f 3 7 8 4
f 1 5 7 3
f 2 4 8 6
";
        let path = write("cube.OBJ", text);
        let o = Object::from_file(&path).unwrap();
        std::fs::remove_file(&path).unwrap();
        assert_eq!(o.faces.len(), 6);
        assert!(o.faces.iter().all(|f| f.len() == 4));
        assert!((o.volume - 1.0).abs() < 1e-15);
        assert!((o.centre_of_mass - Vec3::repeat(0.5)).norm() < 1e-15);
        assert_eq!(o.section.samples.len(), 4);
        assert!(o.warnings.is_empty());
    }

    #[test]
    fn obj_inward_cube_is_flipped() {
        let text = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nv 0 0 1\nv 1 0 1\nv 0 1 1\nv 1 1 1\n\
                    f 2 4 3 1\nf 7 8 6 5\nf 5 6 2 1\nf 4 8 7 3\nf 3 7 5 1\nf 6 8 4 2\n";
        let path = write("inward.obj", text);
        let o = Object::from_file(&path).unwrap();
        std::fs::remove_file(&path).unwrap();
        assert_eq!(o.warnings, vec![MeshWarning::InwardOrientation]);
        assert!((o.volume - 1.0).abs() < 1e-15);
    }

    #[test]
    fn file_errors_name_the_file_and_the_problem() {
        let path = write("empty.stl", "");
        let e = Object::from_file(&path).unwrap_err();
        std::fs::remove_file(&path).unwrap();
        assert!(matches!(e, ObjectError::Parse { format: "STL", .. }), "{e}");
        assert!(
            e.to_string().contains("empty.stl") && e.to_string().contains("empty"),
            "{e}"
        );

        let path = write("empty.obj", "# nothing\n");
        let e = Object::from_file(&path).unwrap_err();
        std::fs::remove_file(&path).unwrap();
        assert!(
            matches!(&e, ObjectError::InvalidMesh { source, .. } if matches!(**source, ObjectError::NoVertices)),
            "{e}"
        );

        let path = write("truncated.stl", &"x".repeat(120));
        let e = Object::from_file(&path).unwrap_err();
        std::fs::remove_file(&path).unwrap();
        assert!(matches!(e, ObjectError::Parse { .. }), "{e}");

        let path = write("bad.obj", "v 0 0 zero\n");
        let e = Object::from_file(&path).unwrap_err();
        std::fs::remove_file(&path).unwrap();
        assert!(matches!(e, ObjectError::Parse { format: "OBJ", .. }), "{e}");

        let path = write("nan.obj", "v 0 0 nan\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 1 3 2\n");
        let e = Object::from_file(&path).unwrap_err();
        std::fs::remove_file(&path).unwrap();
        let ObjectError::InvalidMesh { source, path: p } = e else {
            panic!("{e}")
        };
        assert!(p.ends_with(format!("icrflow-object-{}-nan.obj", std::process::id())));
        assert!(
            matches!(*source, ObjectError::NonFiniteVertex { vertex: 0, .. }),
            "{source}"
        );

        let e = Object::from_file(Path::new("mesh.ply")).unwrap_err();
        assert!(matches!(e, ObjectError::UnsupportedExtension { .. }));
        assert!(e.to_string().contains("mesh.ply"));
        let e = Object::from_file(Path::new("no_extension")).unwrap_err();
        assert!(matches!(e, ObjectError::UnsupportedExtension { .. }));

        let e = Object::from_file(&temp_path("does-not-exist.stl")).unwrap_err();
        assert!(matches!(e, ObjectError::ReadFile { .. }), "{e}");
        assert!(e.to_string().contains("does-not-exist.stl"));
    }

    #[test]
    fn stl_cube_minus_a_face_is_an_open_mesh() {
        let o = Object::cuboid(Vec3::repeat(1.0), 1).unwrap();
        let mut text = String::from("solid open\n");
        for face in o.faces.iter().skip(1) {
            for w in face[1..].windows(2) {
                text += "facet normal 0 0 0\nouter loop\n";
                for i in [face[0], w[0], w[1]] {
                    let v = o.vertices[i as usize];
                    text += &format!("vertex {} {} {}\n", v.x, v.y, v.z);
                }
                text += "endloop\nendfacet\n";
            }
        }
        text += "endsolid open\n";
        let path = write("open.stl", &text);
        let e = Object::from_file(&path).unwrap_err();
        std::fs::remove_file(&path).unwrap();
        let ObjectError::InvalidMesh { source, .. } = &e else {
            panic!("{e}")
        };
        assert!(matches!(**source, ObjectError::OpenEdge { .. }), "{e}");
        assert!(source.to_string().contains("open surface"), "{source}");
    }

    #[test]
    fn stl_ellipsoid_section_normals_are_unit_and_horizontal() {
        let o = Object::ellipsoid(Vec3::new(0.06, 0.04, 0.03), 40, 21).unwrap();
        let path = temp_path("ellipsoid.stl");
        o.write_stl(&path).unwrap();
        let back = Object::from_file(&path).unwrap();
        std::fs::remove_file(&path).unwrap();
        assert!(back.warnings.is_empty(), "{:?}", back.warnings);
        let s = &back.section;
        assert!((s.height - back.centre_of_mass.z).abs() < 1e-15);
        assert!(s.samples.len() >= 40, "{}", s.samples.len());
        for k in 0..s.samples.len() {
            let n = s.samples.normals[k];
            assert!((n.norm() - 1.0).abs() < 1e-12);
            assert_eq!(n.z, 0.0);
            assert_eq!(s.samples.points[k].z, s.height);
            assert!(s.samples.areas[k] > 0.0);
            // Outward: away from the centre of mass in the plane.
            assert!(n.dot(&(s.samples.points[k] - back.centre_of_mass)) > 0.0);
            assert_eq!(s.samples.adjacency.neighbours(k).len(), 2);
            let angle = polar(s.samples.points[k] - back.centre_of_mass);
            assert!((s.angles[k] - angle).abs() < 1e-12);
        }
        // The cut's perimeter is close to the ellipse's (0.06, 0.04): 0.3173 (Ramanujan).
        let total: Real = s.samples.areas.iter().sum();
        assert!((total - 0.317_310_5).abs() < 0.01 * 0.3173, "{total}");
    }

    fn polar(p: Vec3) -> Real {
        p.y.atan2(p.x).rem_euclid(std::f64::consts::TAU)
    }

    #[test]
    fn welding_merges_exact_duplicates_only() {
        let v = vec![
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(-0.0, 0.0, 0.0),
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(1.0 + 1e-15, 0.0, 0.0),
            Vec3::new(Real::NAN, 0.0, 0.0),
            Vec3::new(Real::NAN, 0.0, 0.0),
        ];
        let (w, f) = weld(&v, vec![vec![0, 1, 2, 3, 4, 5, 9]], &mut Silent);
        assert_eq!(w.len(), 5);
        assert_eq!(f, vec![vec![0, 0, 1, 2, 3, 4, 9]]);
    }
}
