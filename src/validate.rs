//! `icrflow validate CONFIG`: everything `plan` and `run` check before starting, nothing
//! started or written.

use std::io::Write;
use std::path::Path;

use anyhow::Result;
use icrflow_scenario::{Config, HandSpec, PlantKind, Setup};

use crate::plan::section_note;

/// `icrflow validate CONFIG`: everything `plan` and `run` check before starting. Returns the
/// exit status: [`crate::exit::INCOMPLETE`] when the initial grasp is not force closure or
/// below the margin (said on stderr), the config being valid otherwise. A spatial hand's
/// ([`Setup::spatial`]) initial grasp is the spatial planner's placement.
pub fn run(path: &Path, progress_after: std::time::Duration) -> Result<u8> {
    let config = Config::load(path)?;
    let mut shown = crate::progress::Shown::new(progress_after);
    let setup = Setup::new_with(&config, &mut shown)?;
    drop(shown);
    let spatial = setup.spatial_scenario(&config);
    let started = match &spatial {
        Some(s) => s.start().map(|(_, quality)| quality),
        None => setup.scenario(&config).start().map(|(_, quality)| quality),
    };
    let started = match started {
        Ok(q) => Ok(q),
        Err(e) if crate::exit::is_grasp_answer(&e) => Err(e),
        Err(e) => return Err(anyhow::Error::new(e).context("cannot start")),
    };
    // What the plant rolls fingertips on: a spatial hand's surface, a planar hand's section
    // (or why `run` cannot take it); the simulated slip is refused off a sphere (circle).
    let rolls_on = match &spatial {
        Some(s) => {
            crate::run::spatial_slip(&config, s.surface)?;
            Ok(s.surface.describe())
        }
        None => match setup.surface() {
            Ok(s) => {
                crate::run::slip(&config, s)?;
                Ok(s.describe())
            }
            Err(e) => Err(e),
        },
    };
    // MuJoCo builds the model (and says why not) before the config is called valid, the hand
    // at its initial grip (at its home pose where the grasp cannot start).
    let mass = match config.plant.kind {
        PlantKind::Mujoco => {
            let joints = setup.initial_grip(&config).map_or_else(
                |_| setup.hand.fingers.iter().map(|f| f.home.clone()).collect(),
                |(joints, _)| joints,
            );
            Some(icrflow_physics::configured::check(
                &config, &setup, &joints,
            )?)
        }
        PlantKind::Kinematic => None,
    };
    let mut o = std::io::stdout().lock();
    writeln!(o, "config     {} is valid", path.display())?;
    match &spatial {
        Some(_) => writeln!(
            o,
            "object     {} ({} facets: the contact candidates)",
            config.object.describe(),
            setup.object.facets.len(),
        )?,
        None => writeln!(
            o,
            "object     {} ({} facets, {} candidates in the hand's plane)",
            config.object.describe(),
            setup.object.facets.len(),
            setup.problem.candidates().points.len()
        )?,
    }
    for w in &setup.object.warnings {
        writeln!(o, "warning    {w}")?;
    }
    match &rolls_on {
        Ok(s) => writeln!(
            o,
            "pipeline   the plant rolls fingertips on {s}{}{}",
            if config.pipeline.slip != 0.0 {
                format!(
                    "; the object slips by {:.1} deg at {} s",
                    config.pipeline.slip.to_degrees(),
                    config.pipeline.slip_at
                )
            } else {
                String::new()
            },
            if spatial.is_some() {
                "; the plan is made again from the estimate where the object stops off it"
            } else {
                ""
            }
        )?,
        Err(e) => writeln!(o, "warning    `run` cannot take this object: {e:#}")?,
    }
    let pl = &config.plant;
    match mass {
        Some(mass) => writeln!(
            o,
            "plant      MuJoCo {}: the object {mass:.3} kg, timestep {} ms, gravity [{}, {}, {}] m/s^2; {}squeeze {} mm, friction margin {}",
            icrflow_physics::sim::MUJOCO_VERSION,
            pl.timestep * 1e3,
            pl.gravity[0],
            pl.gravity[1],
            pl.gravity[2],
            if pl.feedforward {
                "force targets fed forward, "
            } else {
                "no force feed-forward, "
            },
            pl.squeeze * 1e3,
            pl.friction_margin
        )?,
        None => writeln!(
            o,
            "plant      kinematic (our quasi-static model: fingertips roll by the rolling kinematics, nothing slips)"
        )?,
    }
    let hand = match &config.hand {
        HandSpec::Paper => "the paper's hand".to_string(),
        HandSpec::Links { .. } => "link lengths".to_string(),
        HandSpec::Urdf { path, .. } => format!("URDF {}", path.display()),
    };
    match &spatial {
        Some(_) => {
            let a = config.turn.axis;
            writeln!(
                o,
                "hand       {} fingers in space ({hand}); the object turns about [{:.3}, {:.3}, {:.3}]",
                setup.hand.fingers.len(),
                a.x,
                a.y,
                a.z
            )?
        }
        None => writeln!(
            o,
            "hand       {} fingers ({hand})",
            setup.hand.fingers.len()
        )?,
    }
    let fingers: Vec<u32> = config.grasp.contacts.iter().map(|c| c.finger).collect();
    let placed = if spatial.is_some() {
        " on the facets nearest the points"
    } else {
        ""
    };
    match &started {
        Ok(quality) => writeln!(
            o,
            "grasp      {} contacts (fingers {fingers:?}){placed}, force closure, alpha* = {quality:.6} >= alpha = {}",
            fingers.len(),
            config.plan.alpha
        )?,
        Err(e) => writeln!(
            o,
            "grasp      {} contacts (fingers {fingers:?}): {e}",
            fingers.len()
        )?,
    }
    if spatial.is_none() {
        for line in section_note(&config) {
            writeln!(o, "           {line}")?;
        }
    }
    if config.pipeline.split() {
        let links = icrflow_interfaces::topics::links(&config.pipeline.nodes);
        writeln!(
            o,
            "nodes      {} on this host; the others over Zenoh (sending {:?}, taking {:?})",
            config.pipeline.nodes.join(", "),
            links.export,
            links.import
        )?;
    }
    Ok(match started {
        Ok(_) => crate::exit::DONE,
        Err(e) => {
            drop(o);
            eprintln!("validate: cannot start: {e}");
            crate::exit::INCOMPLETE
        }
    })
}
