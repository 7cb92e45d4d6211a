//! `[grasp]`: the wrench space, the contact model, the quality margin and the initial
//! contacts ([`GraspSpec`]).

use anyhow::{Result, bail};
use icrflow_grasp::math::{Real, Vec3};
use icrflow_grasp::wrench::{ContactModel, Space};

use super::{components, each};
use crate::bounds;
use crate::raw::{self, RawContact};

/// Default number of friction-cone edges.
pub const DEFAULT_CONE_EDGES: usize = 8;

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
    /// Where the contact lies on the fingertip cap (rad from the cap axis), if given.
    pub cap_angle: Option<Real>,
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

pub(crate) fn grasp_spec(raw: raw::RawGrasp) -> Result<GraspSpec> {
    let space = match raw.space.as_str() {
        "planar" => Space::Planar,
        "spatial" => Space::Spatial,
        other => bail!("grasp.space: must be \"planar\" or \"spatial\", got {other:?}"),
    };
    let edges = raw.cone_edges.unwrap_or(DEFAULT_CONE_EDGES);
    bounds::FRICTION.check("grasp.friction", raw.friction)?;
    let model = ContactModel::new(raw.friction, edges).map_err(|e| {
        let key = match e {
            icrflow_grasp::wrench::WrenchError::ConeEdges { .. } => "grasp.cone_edges",
            _ => "grasp.friction",
        };
        anyhow::anyhow!("{key}: {e}")
    })?;
    let alpha = bounds::ALPHA.check("grasp.alpha", raw.alpha)?;
    let rho = raw
        .rho
        .map(|r| bounds::RHO.check("grasp.rho", r))
        .transpose()?;
    if raw.contacts.is_empty() {
        bail!("grasp.contacts: at least one contact is needed");
    }
    let mut contacts: Vec<FingerContact> = Vec::with_capacity(raw.contacts.len());
    for (i, c) in raw.contacts.into_iter().enumerate() {
        let contact = contact_spec(i, c)?;
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
        alpha,
        rho,
        contacts,
    })
}

fn contact_spec(i: usize, c: RawContact) -> Result<FingerContact> {
    let at = match (c.angle_deg, c.point) {
        (Some(_), Some(_)) => bail!("grasp.contacts[{i}]: give `angle_deg` or `point`, not both"),
        (None, None) => bail!("grasp.contacts[{i}]: give `angle_deg` or `point`"),
        (Some(a), None) => ContactSpec::Angle(
            bounds::CONTACT_ANGLE
                .check(&format!("grasp.contacts[{i}].angle_deg"), a)?
                .to_radians(),
        ),
        (None, Some(p)) => {
            let key = format!("grasp.contacts[{i}].point");
            let p = components(&key, &p, "[x, y, z] (m, body frame)")?;
            ContactSpec::Point(Vec3::from(each(&key, p, bounds::CONTACT_POINT)?))
        }
    };
    let cap_angle = c
        .cap_angle_deg
        .map(|a| {
            bounds::CAP_ANGLE
                .check(&format!("grasp.contacts[{i}].cap_angle_deg"), a)
                .map(Real::to_radians)
        })
        .transpose()?;
    Ok(FingerContact {
        finger: c.finger,
        at,
        cap_angle,
    })
}
