//! `[plant]`: what the pipeline's plant simulates and how the hand is driven
//! ([`PlantSpec`]).

use anyhow::{Result, bail};
use icrflow_grasp::math::Real;

use super::components;
use crate::bounds::{self, num};

/// The plant of the pipeline (`plant.kind`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PlantKind {
    /// Our own quasi-static model: fingertips roll by the rolling kinematics, nothing slips.
    Kinematic,
    /// MuJoCo: the hand and object as rigid bodies with soft contacts and friction.
    Mujoco,
}

/// The validated `[plant]` section: what `icrflow-plant` simulates and how the hand is driven.
/// Lengths in metres, angles in radians.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlantSpec {
    /// Which plant.
    pub kind: PlantKind,
    /// MuJoCo's timestep (s).
    pub timestep: Real,
    /// Gravity in the hand frame (m/s^2).
    pub gravity: [Real; 3],
    /// The object's density (kg/m^3).
    pub density: Real,
    /// Radius of the links' capsules (m).
    pub link_radius: Real,
    /// Joint servos' position gain (N m/rad) and damping (N m s/rad).
    pub kp: Real,
    /// See `kp`.
    pub kv: Real,
    /// Iterations of MuJoCo's no-slip solver after each step (0: none): without it, friction
    /// under a steady tangential load creeps (MuJoCo's soft contacts), and a grasp that leans on
    /// friction drifts out of the hand.
    pub noslip_iterations: u32,
    /// How far past the commanded fingertip position the servos of the finger commanded with
    /// the largest force aim (m); the others' in proportion to their forces.
    pub squeeze: Real,
    /// Whether the fingertip force targets reach the joints as feed-forward torques.
    pub feedforward: bool,
    /// The fraction of mu the hand command's force targets leave unused at every contact.
    pub friction_margin: Real,
}

impl PlantSpec {
    /// The object's weight as a force on it (N, hand frame), for an object of `volume` m^3.
    pub fn weight(&self, volume: Real) -> [Real; 3] {
        let m = self.density * volume;
        self.gravity.map(|g| m * g)
    }
}

pub(crate) fn plant_spec(raw: crate::raw::RawPlant) -> Result<PlantSpec> {
    let kind = match raw.kind.as_deref() {
        None | Some("kinematic") => PlantKind::Kinematic,
        Some("mujoco") => PlantKind::Mujoco,
        Some(other) => bail!(
            "plant.kind: unknown plant {other:?}; the plants are \"kinematic\" (the default: our quasi-static model) and \"mujoco\""
        ),
    };
    if kind == PlantKind::Kinematic {
        for (key, given, what) in [
            (
                "timestep_ms",
                raw.timestep_ms.is_some(),
                "MuJoCo's timestep",
            ),
            (
                "kp",
                raw.kp.is_some(),
                "the MuJoCo plant's joint servo gain",
            ),
            (
                "kv",
                raw.kv.is_some(),
                "the MuJoCo plant's joint servo damping",
            ),
            (
                "noslip_iterations",
                raw.noslip_iterations.is_some(),
                "MuJoCo's no-slip solver",
            ),
            (
                "squeeze_mm",
                raw.squeeze_mm.is_some(),
                "how far past the surface the MuJoCo plant's servos aim",
            ),
            (
                "feedforward",
                raw.feedforward.is_some(),
                "the MuJoCo plant's feed-forward joint torques",
            ),
        ] {
            if given {
                bail!(
                    "plant.{key}: {what}; with the kinematic plant (plant.kind = \"kinematic\", the default) it has no effect: leave it out, or set plant.kind = \"mujoco\""
                );
            }
        }
    }
    let gravity = match &raw.gravity {
        Some(g) => components("plant.gravity", g, "[x, y, z] (m/s^2, hand frame)")?,
        None => [0.0; 3],
    };
    for (i, g) in gravity.iter().enumerate() {
        bounds::GRAVITY.check(&format!("plant.gravity[{i}]"), *g)?;
    }
    if gravity[0] != 0.0 || gravity[1] != 0.0 {
        bail!(
            "plant.gravity: only along the hand's z axis (the axis the object turns about), got [{}, {}, {}]: the force targets are solved once per contact set in the object's frame, which a sideways load would turn with the object",
            num(gravity[0]),
            num(gravity[1]),
            num(gravity[2])
        );
    }
    Ok(PlantSpec {
        kind,
        timestep: bounds::TIMESTEP.or("plant.timestep_ms", raw.timestep_ms, 0.5)? * 1e-3,
        gravity,
        density: bounds::DENSITY.or("plant.density", raw.density, 500.0)?,
        link_radius: bounds::LINK_RADIUS.or("plant.link_radius_mm", raw.link_radius_mm, 4.0)?
            * 1e-3,
        kp: bounds::KP.or("plant.kp", raw.kp, 5.0)?,
        kv: bounds::KV.or("plant.kv", raw.kv, 0.05)?,
        noslip_iterations: bounds::NOSLIP.check(
            "plant.noslip_iterations",
            raw.noslip_iterations.unwrap_or(0),
        )? as u32,
        squeeze: bounds::SQUEEZE.or("plant.squeeze_mm", raw.squeeze_mm, 1.0)? * 1e-3,
        feedforward: raw.feedforward.unwrap_or(true),
        friction_margin: bounds::FRICTION_MARGIN.or(
            "plant.friction_margin",
            raw.friction_margin,
            match kind {
                PlantKind::Kinematic => 0.0,
                PlantKind::Mujoco => 0.2,
            },
        )?,
    })
}
