//! The model of a config: its hand and object under its `[plant]` settings.

use anyhow::{Result, anyhow};
use icrflow_grasp::math::{Real, Vec3};
use icrflow_scenario::{Config, ObjectSpec, Setup};

use crate::scene::{Params, Shape, mjcf};
use crate::sim::{Controls, Sim};

/// The MJCF of the config's hand and object under its `[plant]` settings.
pub fn model(config: &Config, setup: &Setup) -> Result<String> {
    let p = &config.plant;
    let shape = match config.object {
        ObjectSpec::Sphere { radius, .. } => Shape::Sphere { radius },
        ObjectSpec::Ellipsoid { semi_axes, .. } => Shape::Ellipsoid { semi_axes },
        _ => Shape::Mesh,
    };
    let params = Params {
        timestep: p.timestep,
        gravity: Vec3::from(p.gravity),
        density: p.density,
        friction: config.grasp.model.mu(),
        link_radius: p.link_radius,
        kp: p.kp,
        kv: p.kv,
        noslip_iterations: p.noslip_iterations,
    };
    mjcf(&setup.hand, &setup.object, shape, &params).map_err(|e| anyhow!("plant: {e}"))
}

/// Whether MuJoCo can build the config's model with the hand at `joints` (each finger's, in
/// the hand's order; for `validate`): its mass, or why not.
pub fn check(config: &Config, setup: &Setup, joints: &[Vec<Real>]) -> Result<Real> {
    let xml = model(config, setup)?;
    let sim = Sim::new(&xml, &setup.hand, joints, controls(config))
        .map_err(|e| anyhow!("plant.kind = \"mujoco\": {e}"))?;
    Ok(sim.object_mass())
}

/// How the config drives the hand.
pub fn controls(config: &Config) -> Controls {
    Controls {
        feedforward: config.plant.feedforward,
        squeeze: config.plant.squeeze,
    }
}
