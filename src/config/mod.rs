//! Configuration: parsed from TOML in two steps, raw serde structs that reject unknown keys
//! ([`raw`]), then this validated, typed config, whose [`Config::load`] is the only way in.
//! Every error names the offending key. The keys are documented in `config/README.md`.

mod raw;

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use icrflow_grasp::math::{Real, Vec3};
use icrflow_grasp::object::Object;
use icrflow_grasp::wrench::{ContactModel, Space};

use raw::{RawConfig, RawContact, RawObject};

/// Default number of friction-cone edges.
pub const DEFAULT_CONE_EDGES: usize = 8;
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
            ObjectSpec::Mesh { path } => Object::from_file(path),
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

/// Where a contact is, as given in the config.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ContactSpec {
    /// Angle (radians) on the object's section in the hand's plane.
    Angle(Real),
    /// Body-frame point (m).
    Point(Vec3),
}

/// One finger's contact.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FingerContact {
    /// Finger number as in the config.
    pub finger: u32,
    /// Where it touches.
    pub at: ContactSpec,
}

/// The validated `[grasp]` section.
#[derive(Debug, Clone, PartialEq)]
pub struct GraspSpec {
    /// Wrench space.
    pub space: Space,
    /// Contact model (friction, cone edges).
    pub model: ContactModel,
    /// Quality margin alpha.
    pub alpha: Real,
    /// Torque normalisation length; `None`: the object's largest distance from its COM.
    pub rho: Option<Real>,
    /// Contacts, in config order.
    pub contacts: Vec<FingerContact>,
}

/// A validated config.
#[derive(Debug, Clone, PartialEq)]
pub struct Config {
    /// The file it came from.
    pub path: PathBuf,
    /// The object.
    pub object: ObjectSpec,
    /// The grasp.
    pub grasp: GraspSpec,
}

impl Config {
    /// Reads, parses and validates a config file. Relative paths in it are resolved against
    /// the file's directory.
    pub fn load(path: &Path) -> Result<Self> {
        let text = std::fs::read_to_string(path)
            .with_context(|| format!("cannot read config {}", path.display()))?;
        Self::parse(&text, path).with_context(|| format!("invalid config {}", path.display()))
    }

    /// Parses and validates config text; `path` locates relative file names.
    pub fn parse(text: &str, path: &Path) -> Result<Self> {
        let raw: RawConfig = toml::from_str(text).map_err(|e| anyhow::anyhow!("{e}"))?;
        let base = path.parent().unwrap_or(Path::new("."));
        Ok(Self {
            path: path.to_path_buf(),
            object: object_spec(raw.object, base)?,
            grasp: grasp_spec(raw.grasp)?,
        })
    }
}

fn positive(key: &str, x: Real) -> Result<Real> {
    if !x.is_finite() || x <= 0.0 {
        bail!("{key}: must be a finite number > 0, got {x}");
    }
    Ok(x)
}

fn segments(key: &str, s: [usize; 2], min: [usize; 2]) -> Result<[usize; 2]> {
    if s[0] < min[0] || s[1] < min[1] {
        bail!(
            "{key}: needs at least [{}, {}], got {:?}",
            min[0],
            min[1],
            s
        );
    }
    Ok(s)
}

fn object_spec(raw: RawObject, base: &Path) -> Result<ObjectSpec> {
    Ok(match raw {
        RawObject::Sphere {
            radius,
            segments: s,
        } => ObjectSpec::Sphere {
            radius: positive("object.radius", radius)?,
            segments: segments("object.segments", s.unwrap_or(DEFAULT_SEGMENTS), [3, 2])?,
        },
        RawObject::Ellipsoid {
            semi_axes,
            segments: s,
        } => {
            for (i, a) in semi_axes.iter().enumerate() {
                positive(&format!("object.semi_axes[{i}]"), *a)?;
            }
            ObjectSpec::Ellipsoid {
                semi_axes,
                segments: segments("object.segments", s.unwrap_or(DEFAULT_SEGMENTS), [3, 2])?,
            }
        }
        RawObject::Cuboid {
            half_extents,
            segments: s,
        } => {
            for (i, a) in half_extents.iter().enumerate() {
                positive(&format!("object.half_extents[{i}]"), *a)?;
            }
            let s = s.unwrap_or(8);
            if s == 0 {
                bail!("object.segments: must be >= 1, got 0");
            }
            ObjectSpec::Cuboid {
                half_extents,
                segments: s,
            }
        }
        RawObject::Cylinder {
            radius,
            height,
            segments: s,
        } => ObjectSpec::Cylinder {
            radius: positive("object.radius", radius)?,
            height: positive("object.height", height)?,
            segments: segments("object.segments", s.unwrap_or([72, 8]), [3, 1])?,
        },
        RawObject::Mesh { path } => {
            let full = base.join(&path);
            if !full.is_file() {
                bail!("object.path: mesh file {} does not exist", full.display());
            }
            ObjectSpec::Mesh { path: full }
        }
    })
}

fn grasp_spec(raw: raw::RawGrasp) -> Result<GraspSpec> {
    let space = match raw.space.as_str() {
        "planar" => Space::Planar,
        "spatial" => Space::Spatial,
        other => bail!("grasp.space: must be \"planar\" or \"spatial\", got {other:?}"),
    };
    let edges = raw.cone_edges.unwrap_or(DEFAULT_CONE_EDGES);
    let model = ContactModel::new(raw.friction, edges).map_err(|e| {
        let key = match e {
            icrflow_grasp::wrench::WrenchError::ConeEdges { .. } => "grasp.cone_edges",
            _ => "grasp.friction",
        };
        anyhow::anyhow!("{key}: {e}")
    })?;
    if !raw.alpha.is_finite() || raw.alpha < 0.0 {
        bail!(
            "grasp.alpha: must be a finite number >= 0, got {}",
            raw.alpha
        );
    }
    let rho = raw.rho.map(|r| positive("grasp.rho", r)).transpose()?;
    if raw.contacts.is_empty() {
        bail!("grasp.contacts: at least one contact is needed");
    }
    let mut contacts: Vec<FingerContact> = Vec::with_capacity(raw.contacts.len());
    for (i, c) in raw.contacts.into_iter().enumerate() {
        let contact = contact_spec(i, c, space)?;
        if contacts.iter().any(|o| o.finger == contact.finger) {
            bail!(
                "grasp.contacts[{i}].finger: finger {} appears twice",
                contact.finger
            );
        }
        contacts.push(contact);
    }
    Ok(GraspSpec {
        space,
        model,
        alpha: raw.alpha,
        rho,
        contacts,
    })
}

fn contact_spec(i: usize, c: RawContact, space: Space) -> Result<FingerContact> {
    let at = match (c.angle_deg, c.point) {
        (Some(_), Some(_)) => bail!("grasp.contacts[{i}]: give `angle_deg` or `point`, not both"),
        (None, None) => bail!("grasp.contacts[{i}]: give `angle_deg` or `point`"),
        (Some(a), None) => {
            if space != Space::Planar {
                bail!(
                    "grasp.contacts[{i}].angle_deg: angles are for planar problems; give `point` for a spatial one"
                );
            }
            if !a.is_finite() {
                bail!("grasp.contacts[{i}].angle_deg: must be finite, got {a}");
            }
            ContactSpec::Angle(a.to_radians())
        }
        (None, Some(p)) => {
            if p.iter().any(|x| !x.is_finite()) {
                bail!("grasp.contacts[{i}].point: coordinates must be finite, got {p:?}");
            }
            ContactSpec::Point(Vec3::from(p))
        }
    };
    Ok(FingerContact {
        finger: c.finger,
        at,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    const GOOD: &str = r#"
[object]
shape = "sphere"
radius = 0.0475

[grasp]
space = "planar"
friction = 0.3
alpha = 0.1
contacts = [ { finger = 1, angle_deg = 30.0 }, { finger = 2, angle_deg = -30.0 } ]
"#;

    fn err(text: &str) -> String {
        format!(
            "{:#}",
            Config::parse(text, Path::new("x.toml")).unwrap_err()
        )
    }

    #[test]
    fn defaults_are_filled_in() {
        let c = Config::parse(GOOD, Path::new("x.toml")).unwrap();
        assert_eq!(
            c.object,
            ObjectSpec::Sphere {
                radius: 0.0475,
                segments: [72, 72]
            }
        );
        assert_eq!(c.grasp.model.edges(), 8);
        assert_eq!(c.grasp.contacts.len(), 2);
    }

    #[test]
    fn errors_name_the_key() {
        assert!(err(&GOOD.replace("alpha = 0.1", "alpha = 0.1\nbogus = 1")).contains("bogus"));
        assert!(err(&GOOD.replace("friction = 0.3", "friction = -0.3")).contains("grasp.friction"));
        assert!(
            err(&GOOD.replace("alpha = 0.1", "alpha = 0.1\ncone_edges = 2"))
                .contains("grasp.cone_edges")
        );
        assert!(err(&GOOD.replace("radius = 0.0475", "radius = 0.0")).contains("object.radius"));
        assert!(err(&GOOD.replace("\"planar\"", "\"3d\"")).contains("grasp.space"));
        assert!(
            err(&GOOD.replace("finger = 2", "finger = 1")).contains("grasp.contacts[1].finger")
        );
        assert!(
            err(&GOOD.replace("\"planar\"", "\"spatial\"")).contains("grasp.contacts[0].angle_deg")
        );
        assert!(
            err(&GOOD
                .replace(
                    "shape = \"sphere\"",
                    "shape = \"mesh\"\npath = \"nope.stl\""
                )
                .replace("radius = 0.0475", ""))
            .contains("object.path")
        );
        assert!(err(&GOOD.replace("radius", "radios")).contains("radios"));
    }
}
