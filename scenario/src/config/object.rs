//! `[object]`: the shape the hand holds, validated ([`ObjectSpec`]) and built.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use icrflow_grasp::math::{Real, Vec3};
use icrflow_grasp::object::Object;

use super::each;
use super::existing_file;
use crate::bounds::{self, Count};
use crate::raw::RawObject;

/// Default sphere/ellipsoid discretisation (the paper's 72 x 72).
pub const DEFAULT_SEGMENTS: [usize; 2] = [72, 72];

/// A validated object description.
#[derive(Debug, Clone, PartialEq)]
pub enum ObjectSpec {
    /// UV sphere.
    Sphere {
        /// Radius (m).
        radius: Real,
        /// Longitude, latitude segments.
        segments: [usize; 2],
    },
    /// UV ellipsoid.
    Ellipsoid {
        /// Semi-axes (m).
        semi_axes: [Real; 3],
        /// Longitude, latitude segments.
        segments: [usize; 2],
    },
    /// Box.
    Cuboid {
        /// Half extents (m).
        half_extents: [Real; 3],
        /// Quads per face edge.
        segments: usize,
    },
    /// Cylinder about z.
    Cylinder {
        /// Radius (m).
        radius: Real,
        /// Height (m).
        height: Real,
        /// Segments around and along the axis.
        segments: [usize; 2],
    },
    /// A mesh file (absolute path, checked to exist).
    Mesh {
        /// Path to the STL or OBJ file.
        path: PathBuf,
    },
}

impl ObjectSpec {
    /// Builds (and validates) the object.
    pub fn build(&self) -> Result<Object> {
        self.build_with(&mut icrflow_grasp::progress::Silent)
    }

    /// [`ObjectSpec::build`], reporting a mesh file's loading to `progress`.
    pub fn build_with(
        &self,
        progress: &mut dyn icrflow_grasp::progress::Progress,
    ) -> Result<Object> {
        let object = match self {
            ObjectSpec::Sphere { radius, segments } => {
                Object::sphere(*radius, segments[0], segments[1])
            }
            ObjectSpec::Ellipsoid {
                semi_axes,
                segments,
            } => Object::ellipsoid(Vec3::from(*semi_axes), segments[0], segments[1]),
            ObjectSpec::Cuboid {
                half_extents,
                segments,
            } => Object::cuboid(Vec3::from(*half_extents), *segments),
            ObjectSpec::Cylinder {
                radius,
                height,
                segments,
            } => Object::cylinder(*radius, *height, segments[0], segments[1]),
            ObjectSpec::Mesh { path } => Object::from_file_with(path, progress),
        };
        match self {
            // The mesh error names the file.
            ObjectSpec::Mesh { .. } => object.context("object"),
            _ => object.with_context(|| format!("object: {}", self.describe())),
        }
    }

    /// One-line description.
    pub fn describe(&self) -> String {
        match self {
            ObjectSpec::Sphere { radius, segments } => {
                format!(
                    "sphere r = {radius} m, {} x {} segments",
                    segments[0], segments[1]
                )
            }
            ObjectSpec::Ellipsoid {
                semi_axes,
                segments,
            } => format!(
                "ellipsoid semi-axes {:?} m, {} x {} segments",
                semi_axes, segments[0], segments[1]
            ),
            ObjectSpec::Cuboid {
                half_extents,
                segments,
            } => format!("box half-extents {half_extents:?} m, {segments} quads per edge"),
            ObjectSpec::Cylinder {
                radius,
                height,
                segments,
            } => format!(
                "cylinder r = {radius} m, h = {height} m, {} x {} segments",
                segments[0], segments[1]
            ),
            ObjectSpec::Mesh { path } => format!("mesh {}", path.display()),
        }
    }
}

fn segments(s: [usize; 2], around: Count, along: Count) -> Result<[usize; 2]> {
    around.check("object.segments[0]", s[0])?;
    along.check("object.segments[1]", s[1])?;
    Ok(s)
}

pub(crate) fn object_spec(raw: RawObject, base: &Path) -> Result<ObjectSpec> {
    Ok(match raw {
        RawObject::Sphere {
            radius,
            segments: s,
        } => ObjectSpec::Sphere {
            radius: bounds::SIZE.check("object.radius", radius)?,
            segments: segments(
                s.unwrap_or(DEFAULT_SEGMENTS),
                bounds::LONGITUDE,
                bounds::LATITUDE,
            )?,
        },
        RawObject::Ellipsoid {
            semi_axes,
            segments: s,
        } => ObjectSpec::Ellipsoid {
            semi_axes: each("object.semi_axes", semi_axes, bounds::SIZE)?,
            segments: segments(
                s.unwrap_or(DEFAULT_SEGMENTS),
                bounds::LONGITUDE,
                bounds::LATITUDE,
            )?,
        },
        RawObject::Cuboid {
            half_extents,
            segments: s,
        } => ObjectSpec::Cuboid {
            half_extents: each("object.half_extents", half_extents, bounds::SIZE)?,
            segments: bounds::CUBOID_SEGMENTS.check("object.segments", s.unwrap_or(8))?,
        },
        RawObject::Cylinder {
            radius,
            height,
            segments: s,
        } => ObjectSpec::Cylinder {
            radius: bounds::SIZE.check("object.radius", radius)?,
            height: bounds::SIZE.check("object.height", height)?,
            segments: segments(
                s.unwrap_or([72, 8]),
                bounds::CYLINDER_AROUND,
                bounds::CYLINDER_ALONG,
            )?,
        },
        RawObject::Mesh { path } => ObjectSpec::Mesh {
            path: existing_file("object.path", "a mesh file", base.join(&path))?,
        },
    })
}
