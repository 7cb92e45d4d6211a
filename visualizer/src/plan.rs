//! The visualizer's plan mode: `icrflow-visualizer --plan CONFIG TRAJECTORY`, started by
//! `icrflow plan ... --rrd PATH` (or `--spawn-viewer`, `--connect-viewer URL`) once the plan
//! is written. It records the plan in `TRAJECTORY` (the `trajectory.json` that `icrflow plan`
//! wrote for `CONFIG`) on the `step` timeline: per step, the same entities as a run's
//! recording (the object at the step's rotation, the contacts and their cones, the fingers at
//! the planned joint angles, each finger's ICR, the rendezvous region of an attach step, the
//! wrench space, the angles, alpha* against alpha and the phase). There is no `time`
//! timeline and no latency: nothing ran.

use std::path::Path;

use anyhow::{Context as _, Result, bail};
use icrflow_grasp::math::Vec3;
use icrflow_plan::planner::Step;
use icrflow_runtime::launch::RecordingLaunch;
use icrflow_scenario::{Config, Recording, Setup};
use nalgebra::{Unit, UnitQuaternion};
use serde::Deserialize;

use crate::geometry::p3;
use crate::record::{self, Frame};

/// The part of `trajectory.json` this mode reads.
#[derive(Deserialize)]
struct Trajectory {
    steps: Vec<Step>,
}

/// Records the plan in `trajectory` (written by `icrflow plan` for `config`) to the target in
/// `launch`; returns the frames logged.
pub fn run(config: &Path, trajectory: &Path, launch: &RecordingLaunch) -> Result<u64> {
    let recording = Recording::parse(&launch.target)?;
    let id = launch.id.clone();
    let config = Config::load(config)?;
    let setup = Setup::new(&config)?;
    let text = std::fs::read_to_string(trajectory)
        .with_context(|| format!("cannot read the plan {}", trajectory.display()))?;
    let plan: Trajectory = serde_json::from_str(&text).with_context(|| {
        format!(
            "{} is not a trajectory.json of `icrflow plan`",
            trajectory.display()
        )
    })?;
    if plan.steps.is_empty() {
        bail!("{}: the plan has no steps", trajectory.display());
    }
    // The plan's margin (`plan.alpha`, at least the gate's): the recording shows the plan.
    let alpha = config.plan.alpha;
    let frames = plan
        .steps
        .iter()
        .map(|step| frames(step, &config, &setup))
        .collect::<Result<Vec<_>>>()?;
    let statics = crate::statics(&setup, &id, alpha, &config.turn.axis, false);
    let rec = record::open(&recording, &id, true, &statics.layout)?;
    record::statics(&rec, &statics)?;
    let logged = record::log_frames(&rec, alpha, frames.into_iter().flatten())?;
    rec.flush_with_timeout(std::time::Duration::from_secs(10))
        .map_err(|e| anyhow::anyhow!("flushing the recording: {e}"))?;
    eprintln!(
        "icrflow-visualizer: {} plan steps recorded ({logged} frames)",
        plan.steps.len()
    );
    Ok(logged)
}

/// A planned step's two frames: the step (ICRs, rendezvous, wrench space) and the scene.
fn frames(step: &Step, config: &Config, setup: &Setup) -> Result<[Frame; 2]> {
    let problem = &setup.problem;
    let count = problem.candidates().points.len();
    let contacts: Vec<usize> = step.fingers.iter().filter_map(|f| f.contact).collect();
    if let Some(&c) = contacts.iter().find(|&&c| c >= count) {
        bail!(
            "step {}: contact at candidate {c}, but the object of this config has {count}: \
             the plan was made for another config",
            step.step
        );
    }
    // The step's ICRs, as the planner node computes them for its plan-step messages.
    let evaluation = problem
        .evaluate(&contacts)
        .with_context(|| format!("step {}: evaluating the grasp", step.step))?;
    let regions = problem
        .icrs(&contacts, &evaluation, config.plan.alpha)
        .map(|r| r.into_iter().map(|r| r.members).collect::<Vec<_>>())
        .unwrap_or_default();
    let mut region = regions.iter();
    let fingers: Vec<(u32, Option<usize>, &[u32])> = step
        .fingers
        .iter()
        .map(|f| {
            let members = match f.contact {
                Some(_) => region.next().map_or(&[][..], Vec::as_slice),
                None => &[],
            };
            (f.finger, f.contact, members)
        })
        .collect();
    let rendezvous: Option<(u32, Vec<u32>)> = step.switch.as_ref().map(|s| {
        (
            s.attached,
            s.brute_force.iter().map(|&c| c as u32).collect(),
        )
    });
    let number = step.step as u64;
    let step_frame = crate::step_frame(
        None,
        number,
        step.phase as u32,
        &fingers,
        rendezvous.as_ref().map(|(f, r)| (*f, r.as_slice())),
        problem,
    );
    Ok([step_frame, scene(step, config, setup)])
}

/// The scene of a planned step: the object turned by the step's rotation about the plan's
/// axis through its centre of mass (held at the hand frame's origin), the contacts (a spatial
/// plan's exact points and normals, a planar plan's candidates), their cones, and the fingers.
fn scene(step: &Step, config: &Config, setup: &Setup) -> Frame {
    let com = setup.object.centre_of_mass;
    let theta = step.rotation;
    let rotation = UnitQuaternion::from_axis_angle(&Unit::new_normalize(config.turn.axis), theta);
    let translation = -(rotation * com);
    let candidates = setup.problem.candidates();
    let (contacts, cones) = crate::contacts_view(
        step.fingers
            .iter()
            .filter(|f| f.contact.is_some_and(|c| c < candidates.points.len()))
            .map(|f| {
                let c = f.contact.unwrap_or_default();
                let (p, n) = match (f.point, f.normal) {
                    (Some(p), Some(n)) => (Vec3::from(p), Vec3::from(n)),
                    _ => (candidates.points[c], candidates.normals[c]),
                };
                (translation + rotation * p, rotation * n)
            }),
        &config.grasp,
    );
    let mut fingers = Vec::new();
    for f in &step.fingers {
        if let Some(finger) = setup.hand.finger(f.finger) {
            fingers.extend(crate::finger_view(finger, &f.joints, &Vec3::zeros()));
        }
    }
    let q = rotation.quaternion();
    Frame::Tick {
        t: None,
        pose: (
            p3(&translation),
            [q.i as f32, q.j as f32, q.k as f32, q.w as f32],
        ),
        object_deg: step.rotation.to_degrees(),
        contacts,
        cones,
        fingers,
        quality: Some(step.quality),
        latency: None,
        truth: None,
        dropped: 0,
    }
}
