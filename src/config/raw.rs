//! The config file as written: serde structs that reject unknown keys.

use std::path::PathBuf;

use serde::Deserialize;

/// A whole config file.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawConfig {
    pub object: RawObject,
    pub grasp: RawGrasp,
}

/// `[object]`: the shape is chosen by `shape`.
#[derive(Debug, Deserialize)]
#[serde(tag = "shape", rename_all = "lowercase", deny_unknown_fields)]
pub enum RawObject {
    Sphere {
        radius: f64,
        /// `[longitude, latitude]` segments.
        segments: Option<[usize; 2]>,
    },
    Ellipsoid {
        semi_axes: [f64; 3],
        segments: Option<[usize; 2]>,
    },
    Cuboid {
        half_extents: [f64; 3],
        /// Quads along each edge of each face.
        segments: Option<usize>,
    },
    Cylinder {
        radius: f64,
        height: f64,
        /// `[around, along the axis]` segments.
        segments: Option<[usize; 2]>,
    },
    Mesh {
        /// STL or OBJ file, relative to the config file.
        path: PathBuf,
    },
}

/// `[grasp]`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawGrasp {
    pub space: String,
    pub friction: f64,
    pub cone_edges: Option<usize>,
    pub alpha: f64,
    pub rho: Option<f64>,
    pub contacts: Vec<RawContact>,
}

/// `[[grasp.contacts]]`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawContact {
    pub finger: u32,
    pub angle_deg: Option<f64>,
    pub point: Option<[f64; 3]>,
}
