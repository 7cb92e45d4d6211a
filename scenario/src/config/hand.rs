//! `[hand]`: fingers from link lengths or from a URDF file ([`HandSpec`]), and the hand they
//! build.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use icrflow_grasp::math::{Isometry3, Real, UnitQuaternion};
use icrflow_plan::hand::{Hand, planar_finger};
use icrflow_plan::urdf::UrdfFinger;

use super::{components, each, existing_file};
use crate::bounds::{self, num};
use crate::raw::RawHand;

/// Default fingertip cap half-angle (a hemisphere).
pub const DEFAULT_CAP_HALF_ANGLE_DEG: Real = 90.0;

/// A finger given by link lengths.
#[derive(Debug, Clone, PartialEq)]
pub struct LinkFinger {
    /// Finger number.
    pub finger: u32,
    /// Base position (m) and yaw of the first link at q = 0 (rad).
    pub base: [Real; 3],
    /// Link lengths (m); the last ends at the fingertip centre.
    pub links: Vec<Real>,
    /// Joint limits (rad).
    pub limits: Vec<[Real; 2]>,
    /// Home pose (rad).
    pub home: Option<Vec<Real>>,
    /// Fingertip radius (m).
    pub tip_radius: Real,
}

/// The validated `[hand]` section.
#[derive(Debug, Clone, PartialEq)]
pub enum HandSpec {
    /// No `[hand]`: the paper's four-finger planar hand (`icrflow_plan::paper`).
    Paper,
    /// Fingers from link lengths.
    Links {
        /// Cap half-angle (rad).
        cap_half_angle: Real,
        /// The fingers.
        fingers: Vec<LinkFinger>,
    },
    /// Fingers from a URDF file.
    Urdf {
        /// The file (checked to exist).
        path: PathBuf,
        /// Placement of the URDF's root in the hand frame.
        root: Isometry3,
        /// The fingers.
        fingers: Vec<UrdfFinger>,
    },
}

impl HandSpec {
    /// Builds the hand; errors name the finger.
    pub fn build(&self) -> Result<Hand> {
        let fingers = match self {
            HandSpec::Paper => return Ok(icrflow_plan::paper::hand()),
            HandSpec::Links {
                cap_half_angle,
                fingers,
            } => fingers
                .iter()
                .map(|f| {
                    planar_finger(
                        f.finger,
                        f.base,
                        &f.links,
                        &f.limits,
                        f.tip_radius,
                        *cap_half_angle,
                        f.home.clone(),
                    )
                })
                .collect::<Result<Vec<_>, _>>()
                .context("hand")?,
            HandSpec::Urdf {
                path,
                root,
                fingers: specs,
            } => {
                let fingers =
                    icrflow_plan::urdf::fingers_from_file(path, *root, specs).context("hand")?;
                for (i, (spec, f)) in specs.iter().zip(&fingers).enumerate() {
                    let max = bounds::MESSAGE_JOINTS;
                    if f.dof() > max {
                        bail!(
                            "hand.fingers[{i}]: finger {} (tip link {:?}) has {} joints from the URDF's root, more than the {max} a pipeline message carries per finger (icrflow_interfaces::MAX_JOINTS)",
                            f.id,
                            spec.tip_link,
                            f.dof()
                        );
                    }
                    if spec.tip_radius.is_none() {
                        bounds::FINGERTIP_RADIUS
                            .check(
                                &format!(
                                    "hand.fingers[{i}]: finger {}'s fingertip radius (the sphere of link {:?} in {})",
                                    f.id,
                                    spec.tip_link,
                                    path.display()
                                ),
                                f.tip_radius,
                            )?;
                    }
                }
                fingers
            }
        };
        Hand::new(fingers).context("hand")
    }
}

/// An angle of the hand's description (degrees in the file), in radians.
fn degrees(key: &str, x: Real) -> Result<Real> {
    Ok(bounds::HAND_ANGLE.check(key, x)?.to_radians())
}

pub(crate) fn hand_spec(raw: RawHand, base: &Path) -> Result<HandSpec> {
    let cap_half_angle = bounds::CAP_HALF_ANGLE
        .or(
            "hand.cap_half_angle_deg",
            raw.cap_half_angle_deg,
            DEFAULT_CAP_HALF_ANGLE_DEG,
        )?
        .to_radians();
    let radius = raw
        .fingertip_radius
        .map(|r| bounds::FINGERTIP_RADIUS.check("hand.fingertip_radius", r))
        .transpose()?;
    if raw.fingers.is_empty() {
        bail!("hand.fingers: at least one finger is needed");
    }
    bounds::FINGERS.check("hand.fingers (their number)", raw.fingers.len())?;
    let home = |i: usize, h: &Option<Vec<Real>>| -> Result<Option<Vec<Real>>> {
        h.as_ref()
            .map(|v| {
                bounds::JOINTS
                    .check(&format!("hand.fingers[{i}].home_deg (its length)"), v.len())?;
                v.iter()
                    .enumerate()
                    .map(|(j, a)| degrees(&format!("hand.fingers[{i}].home_deg[{j}]"), *a))
                    .collect()
            })
            .transpose()
    };
    let mut seen = Vec::new();
    for (i, f) in raw.fingers.iter().enumerate() {
        if seen.contains(&f.finger) {
            bail!(
                "hand.fingers[{i}].finger: finger {} appears twice",
                f.finger
            );
        }
        seen.push(f.finger);
    }
    match raw.urdf {
        Some(file) => {
            let full = existing_file("hand.urdf", "a URDF file", base.join(&file))?;
            let vector = |key: &str, v: &Option<Vec<Real>>, what: &str| -> Result<[Real; 3]> {
                v.as_deref()
                    .map_or(Ok([0.0; 3]), |v| components(key, v, what))
            };
            let o = each(
                "hand.urdf_origin",
                vector("hand.urdf_origin", &raw.urdf_origin, "[x, y, z] (m)")?,
                bounds::HAND_POSITION,
            )?;
            let r = each(
                "hand.urdf_rpy_deg",
                vector(
                    "hand.urdf_rpy_deg",
                    &raw.urdf_rpy_deg,
                    "[roll, pitch, yaw] (deg)",
                )?,
                bounds::HAND_ANGLE,
            )?
            .map(Real::to_radians);
            let root = Isometry3::from_parts(
                nalgebra::Translation3::new(o[0], o[1], o[2]),
                UnitQuaternion::from_euler_angles(r[0], r[1], r[2]),
            );
            let mut fingers = Vec::new();
            for (i, f) in raw.fingers.into_iter().enumerate() {
                let key = |k: &str| format!("hand.fingers[{i}].{k}");
                let link_length = [
                    ("base", f.base.is_some()),
                    ("base_yaw_deg", f.base_yaw_deg.is_some()),
                    ("links", f.links.is_some()),
                    ("limits_deg", f.limits_deg.is_some()),
                ];
                if let Some((k, _)) = link_length.iter().find(|(_, given)| *given) {
                    bail!(
                        "{}: a link-length finger's; a URDF hand takes `tip_link` (and optionally `home_deg`, `fingertip_radius`), not base/base_yaw_deg/links/limits_deg, so it has no effect: leave it out",
                        key(k)
                    );
                }
                let Some(tip_link) = f.tip_link.clone() else {
                    bail!("{}: required for a URDF hand", key("tip_link"));
                };
                let tip_radius = f
                    .fingertip_radius
                    .map(|r| bounds::FINGERTIP_RADIUS.check(&key("fingertip_radius"), r))
                    .transpose()?
                    .or(radius);
                fingers.push(UrdfFinger {
                    id: f.finger,
                    tip_link,
                    tip_radius,
                    cap_half_angle,
                    home: home(i, &f.home_deg)?,
                });
            }
            Ok(HandSpec::Urdf {
                path: full,
                root,
                fingers,
            })
        }
        None => {
            for (key, given) in [
                ("hand.urdf_origin", raw.urdf_origin.is_some()),
                ("hand.urdf_rpy_deg", raw.urdf_rpy_deg.is_some()),
            ] {
                if given {
                    bail!(
                        "{key}: the placement of a URDF's root; this hand's fingers are given by link lengths (no hand.urdf), so it has no effect: leave it out, or set hand.urdf"
                    );
                }
            }
            let mut fingers = Vec::new();
            for (i, f) in raw.fingers.into_iter().enumerate() {
                let key = |k: &str| format!("hand.fingers[{i}].{k}");
                if f.tip_link.is_some() {
                    bail!("{}: only for URDF hands (set hand.urdf)", key("tip_link"));
                }
                let Some(b) = f.base else {
                    bail!("{}: required ([x, y] in metres)", key("base"));
                };
                let b = each(
                    &key("base"),
                    components::<2>(&key("base"), &b, "[x, y] (m)")?,
                    bounds::HAND_POSITION,
                )?;
                let yaw = degrees(&key("base_yaw_deg"), f.base_yaw_deg.unwrap_or(0.0))?;
                let Some(links) = f.links else {
                    bail!("{}: required (link lengths in metres)", key("links"));
                };
                bounds::JOINTS.check(&format!("{} (their number)", key("links")), links.len())?;
                for (j, l) in links.iter().enumerate() {
                    bounds::LINK.check(&format!("hand.fingers[{i}].links[{j}]"), *l)?;
                }
                let Some(limits) = f.limits_deg else {
                    bail!("{}: required ([lower, upper] per joint)", key("limits_deg"));
                };
                if limits.len() != links.len() {
                    bail!(
                        "{}: {} joint limits for {} links (one joint per link)",
                        key("limits_deg"),
                        limits.len(),
                        links.len()
                    );
                }
                let mut lim = Vec::with_capacity(limits.len());
                for (j, limit) in limits.iter().enumerate() {
                    let k = format!("hand.fingers[{i}].limits_deg[{j}]");
                    let [lo, hi] = components(&k, limit, "[lower, upper] (deg)")?;
                    let (lo_rad, hi_rad) = (degrees(&k, lo)?, degrees(&k, hi)?);
                    if lo > hi {
                        bail!(
                            "{k}: lower limit {} deg is above the upper limit {} deg (finger {})",
                            num(lo),
                            num(hi),
                            f.finger
                        );
                    }
                    lim.push([lo_rad, hi_rad]);
                }
                let tip_radius = match f
                    .fingertip_radius
                    .map(|r| bounds::FINGERTIP_RADIUS.check(&key("fingertip_radius"), r))
                    .transpose()?
                    .or(radius)
                {
                    Some(r) => r,
                    None => bail!(
                        "hand.fingertip_radius: required (or per finger: {})",
                        key("fingertip_radius")
                    ),
                };
                fingers.push(LinkFinger {
                    finger: f.finger,
                    base: [b[0], b[1], yaw],
                    links,
                    limits: lim,
                    home: home(i, &f.home_deg)?,
                    tip_radius,
                });
            }
            Ok(HandSpec::Links {
                cap_half_angle,
                fingers,
            })
        }
    }
}
