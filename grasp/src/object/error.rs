//! Errors and warnings of mesh construction.

use std::fmt;
use std::path::PathBuf;

use crate::math::Real;

/// Why an [`Object`](super::Object) could not be built, read or written.
///
/// Face and vertex indices refer to the polygon list given to
/// [`Object::from_polygons`](super::Object::from_polygons); for meshes read from a file the
/// vertex indices are those of the welded vertex list (the positions are given as well).
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ObjectError {
    /// The mesh has no vertices.
    #[error("the mesh has no vertices")]
    NoVertices,
    /// The mesh has no faces.
    #[error("the mesh has no faces")]
    NoFaces,
    /// A vertex coordinate is NaN or infinite.
    #[error("vertex {vertex} has a non-finite coordinate {coordinates:?}")]
    NonFiniteVertex {
        /// Index of the vertex.
        vertex: usize,
        /// Its coordinates.
        coordinates: [Real; 3],
    },
    /// A vertex coordinate is so large that areas and volumes would overflow.
    #[error("vertex {vertex} at {coordinates:?} has a coordinate beyond +-{limit:e}")]
    VertexTooFar {
        /// Index of the vertex.
        vertex: usize,
        /// Its coordinates.
        coordinates: [Real; 3],
        /// The largest magnitude accepted.
        limit: Real,
    },
    /// A face has fewer than three vertex indices.
    #[error("face {face} has {count} vertices; a face needs at least 3")]
    TooFewVertices {
        /// Index of the face.
        face: usize,
        /// Number of vertex indices it has.
        count: usize,
    },
    /// A face refers to a vertex that does not exist.
    #[error("face {face} refers to vertex {vertex}, but the mesh has {vertex_count} vertices")]
    VertexOutOfRange {
        /// Index of the face.
        face: usize,
        /// The offending vertex index.
        vertex: u32,
        /// Number of vertices in the mesh.
        vertex_count: usize,
    },
    /// Every face collapsed (fewer than three distinct vertices), so nothing is left.
    #[error("no face has three distinct vertices")]
    NoUsableFaces,
    /// An edge is used by only one face: the surface has a hole.
    #[error(
        "open surface: edge ({from} -> {to}) of face {face} (from {from_position:?} to \
         {to_position:?}) belongs to no other face"
    )]
    OpenEdge {
        /// First vertex of the edge, in the face's order.
        from: u32,
        /// Second vertex of the edge.
        to: u32,
        /// Position of `from`.
        from_position: [Real; 3],
        /// Position of `to`.
        to_position: [Real; 3],
        /// The only face using the edge.
        face: usize,
    },
    /// An edge is used by more than two faces.
    #[error(
        "non-manifold edge ({from} -> {to}) between {from_position:?} and {to_position:?}: \
         used by {count} faces (face {face} among them), a closed surface uses each edge twice"
    )]
    NonManifoldEdge {
        /// First vertex of the edge.
        from: u32,
        /// Second vertex of the edge.
        to: u32,
        /// Position of `from`.
        from_position: [Real; 3],
        /// Position of `to`.
        to_position: [Real; 3],
        /// Number of faces using the edge.
        count: usize,
        /// The first face found using it.
        face: usize,
    },
    /// Two faces traverse a shared edge in the same direction, so they face opposite ways.
    #[error(
        "inconsistent orientation: faces {first_face} and {second_face} both traverse edge \
         {from} -> {to} (from {from_position:?} to {to_position:?}) in the same direction"
    )]
    InconsistentOrientation {
        /// First vertex of the edge.
        from: u32,
        /// Second vertex of the edge.
        to: u32,
        /// Position of `from`.
        from_position: [Real; 3],
        /// Position of `to`.
        to_position: [Real; 3],
        /// The first face.
        first_face: usize,
        /// The second face.
        second_face: usize,
    },
    /// No turning of faces makes the winding consistent: a non-orientable surface (like a
    /// Moebius strip closed up).
    #[error(
        "the mesh cannot be wound consistently: it is not orientable (faces {first_face} and \
         {second_face} disagree whichever way the faces between them are turned)"
    )]
    NonOrientable {
        /// A face.
        first_face: usize,
        /// A face across an edge from the part already wound, which it contradicts.
        second_face: usize,
    },
    /// The closed surface encloses no volume (it is flat, or its parts cancel).
    #[error("the mesh encloses no volume (signed volume {volume:e}, size {size:e})")]
    ZeroVolume {
        /// The signed volume found.
        volume: Real,
        /// The bounding-box diagonal it was compared with.
        size: Real,
    },
    /// A primitive's dimension is not a positive finite number.
    #[error("{name} must be positive and finite, got {value}")]
    InvalidDimension {
        /// Name of the parameter.
        name: &'static str,
        /// The value given.
        value: Real,
    },
    /// A primitive has too few segments.
    #[error("{name} must be at least {min}, got {value}")]
    TooFewSegments {
        /// Name of the parameter.
        name: &'static str,
        /// The value given.
        value: usize,
        /// The smallest value accepted.
        min: usize,
    },
    /// A primitive would have more faces than accepted.
    #[error("the requested {name} would have more than {max} faces")]
    TooManyFaces {
        /// Name of the primitive.
        name: &'static str,
        /// The largest face count accepted.
        max: usize,
    },
    /// A file could not be read.
    #[error("cannot read {}", path.display())]
    ReadFile {
        /// The file.
        path: PathBuf,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },
    /// A file could not be written.
    #[error("cannot write {}", path.display())]
    WriteFile {
        /// The file.
        path: PathBuf,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },
    /// A file's contents are not valid in its format.
    #[error("cannot parse {} as {format}: {message}", path.display())]
    Parse {
        /// The file.
        path: PathBuf,
        /// The format tried (`"STL"` or `"OBJ"`).
        format: &'static str,
        /// What the parser reported.
        message: String,
    },
    /// The file's extension is neither `.stl` nor `.obj`.
    #[error("unsupported mesh file {}: the extension must be .stl or .obj", path.display())]
    UnsupportedExtension {
        /// The file.
        path: PathBuf,
    },
    /// A mesh read from a file failed validation.
    #[error("invalid mesh in {}", path.display())]
    InvalidMesh {
        /// The file.
        path: PathBuf,
        /// What is wrong with the mesh.
        #[source]
        source: Box<ObjectError>,
    },
}

/// Something about a mesh that was accepted, and how it was handled.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub enum MeshWarning {
    /// Faces with (nearly) zero area: kept in the surface, left out of the candidate facets.
    DegenerateFaces {
        /// How many.
        count: usize,
        /// Index of the first one (in [`Object::faces`](super::Object::faces)).
        first: usize,
    },
    /// Faces with fewer than three distinct vertices (after removing repeated consecutive
    /// indices): dropped from the mesh altogether.
    CollapsedFaces {
        /// How many.
        count: usize,
        /// Index of the first one, in the input face list.
        first: usize,
    },
    /// Vertices no face uses: dropped.
    UnusedVertices {
        /// How many.
        count: usize,
        /// Index of the first one, in the input vertex list.
        first: usize,
    },
    /// The faces were oriented inward (negative signed volume) and have all been reversed.
    InwardOrientation,
    /// Faces wound against their neighbours (an inconsistent winding) were turned.
    FacesTurned {
        /// How many.
        count: usize,
        /// Index of the first one, in the input face list.
        first: usize,
    },
    /// The plane `z = height` does not cut the surface: the section is empty.
    SectionEmpty {
        /// Height of the plane.
        height: Real,
    },
    /// The plane `z = height` cuts the surface in several closed loops (all kept).
    SectionLoops {
        /// Number of loops.
        loops: usize,
        /// Height of the plane.
        height: Real,
    },
}

impl fmt::Display for MeshWarning {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::DegenerateFaces { count, first } => write!(
                f,
                "{count} degenerate (zero-area) face(s), first {first}: not used as candidates"
            ),
            Self::CollapsedFaces { count, first } => write!(
                f,
                "{count} face(s) with fewer than 3 distinct vertices, first {first}: dropped"
            ),
            Self::UnusedVertices { count, first } => {
                write!(f, "{count} unused vertex(es), first {first}: dropped")
            }
            Self::FacesTurned { count, first } => write!(
                f,
                "{count} face(s) wound against their neighbours, first {first}: turned"
            ),
            Self::InwardOrientation => {
                write!(
                    f,
                    "faces were oriented inward (negative volume): all reversed"
                )
            }
            Self::SectionEmpty { height } => {
                write!(
                    f,
                    "the plane z = {height} does not cut the surface: no planar section"
                )
            }
            Self::SectionLoops { loops, height } => write!(
                f,
                "the plane z = {height} cuts the surface in {loops} separate loops"
            ),
        }
    }
}
