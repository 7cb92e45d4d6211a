//! `[pipeline]`: the processes of `icrflow run`, their rates, noise and limits
//! ([`PipelineSpec`]), and a push of the object in MuJoCo ([`Push`]).

use anyhow::{Result, bail};
use icrflow_grasp::math::Real;

use super::components;
use crate::bounds::{self, num};
use crate::raw::RawPipeline;

/// The node processes of the control loop, in start order: the names `pipeline.nodes` takes.
/// The one definition: the pipeline's topic graph (`icrflow_interfaces::topics`) and `run`
/// name the same nodes.
pub const NODES: [&str; 5] = ["plant", "estimator", "wrench", "planner", "command"];

/// `pipeline.realtime_priority` by default: the SCHED_FIFO priority ros2_control's
/// controller manager asks for, in the middle of the range.
pub const DEFAULT_REALTIME_PRIORITY: i64 = 50;

/// The validated `[pipeline]` section: rates, noise and limits of `icrflow run`.
#[derive(Debug, Clone, PartialEq)]
pub struct PipelineSpec {
    /// Rig name: the topics are `icrflow/<rig>/<topic>`.
    pub rig: String,
    /// The plant's and the loop's rate (Hz).
    pub rate_hz: Real,
    /// The plant's joint speed limit (rad/s).
    pub joint_speed: Real,
    /// Standard deviation of the joint encoders' noise (rad).
    pub joint_noise: Real,
    /// Rate of the object-pose measurements (Hz).
    pub pose_rate_hz: Real,
    /// Standard deviation of their rotation noise (rad).
    pub pose_noise: Real,
    /// Their latency (s).
    pub pose_latency: Real,
    /// Oldest input the hand command node acts on (s).
    pub max_input_age: Real,
    /// Smallest fingertip normal force commanded (N).
    pub min_normal_force: Real,
    /// Longest hold a scenario run waits through before it gives up (s).
    pub max_hold: Real,
    /// A slip the simulated plant makes once (rad; 0: none): the object turns by this much
    /// under the fingertips, which stay where they are (a knock; a disturbance for the
    /// planner node to recover from). Circular sections only (`run` refuses others).
    pub slip: Real,
    /// When the slip happens, from the plant's start (s).
    pub slip_at: Real,
    /// A push of the object the MuJoCo plant makes once (`None`: none).
    pub push: Option<Push>,
    /// Seed of the simulated noise.
    pub seed: u64,
    /// The nodes this host runs ([`NODES`] by default); the
    /// others run on other hosts, joined over Zenoh.
    pub nodes: Vec<String>,
    /// SCHED_FIFO priority of the nodes on the measurement-to-command path (1 to 99), or 0:
    /// normal scheduling.
    pub realtime_priority: u8,
    /// Largest smoothed pose innovation of the estimate the hand command node tracks on
    /// (rad); beyond, it holds (the estimate is off the pose measurements).
    pub max_pose_innovation: Real,
    /// Largest root-mean-square distance of the fingertips in contact from the object at
    /// the estimated pose the hand command node tracks on (m).
    pub max_contact_residual: Real,
    /// A node that has sent no heartbeat (health report) for this long is killed and
    /// restarted by `run` (s); one silent for a second is reported at once.
    pub hung_restart: Real,
}

/// A push of the object in MuJoCo (`pipeline.push_n`, `push_nm`, `push_at_s`, `push_ms`): a
/// force through its centre of mass and a torque about it, in the world frame (the hand's),
/// held for a while: a knock the loop has to recover from.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Push {
    /// The force (N).
    pub force: [Real; 3],
    /// The torque (N m).
    pub torque: [Real; 3],
    /// When it starts: MuJoCo's time, which runs from the hand's first tracking command (s).
    pub at: Real,
    /// How long it lasts (s).
    pub duration: Real,
}

/// `pipeline.max_pose_innovation_deg` by default.
pub const DEFAULT_MAX_POSE_INNOVATION_DEG: Real = 3.0;
/// `pipeline.max_contact_residual_mm` by default.
pub const DEFAULT_MAX_CONTACT_RESIDUAL_MM: Real = 1.5;
/// `pipeline.hung_restart_s` by default.
pub const DEFAULT_HUNG_RESTART_S: Real = 10.0;

impl PipelineSpec {
    /// Whether some of the loop's nodes run on another host.
    pub fn split(&self) -> bool {
        self.nodes.len() < NODES.len()
    }
}

/// When a push begins unless `pipeline.push_at_s` says (s of MuJoCo's time).
pub const DEFAULT_PUSH_AT_S: Real = 5.0;
/// How long a push lasts unless `pipeline.push_ms` says (ms).
pub const DEFAULT_PUSH_MS: Real = 50.0;

/// `pipeline.push_*`: a push when a force or a torque is given.
fn push_spec(raw: &RawPipeline) -> Result<Option<Push>> {
    let (at, ms) = (raw.push_at_s, raw.push_ms);
    if raw.push_n.is_none() && raw.push_nm.is_none() {
        if at.is_some() || ms.is_some() {
            bail!(
                "pipeline.push_at_s / push_ms: there is no push to time; give its force (push_n) or torque (push_nm)"
            );
        }
        return Ok(None);
    }
    let vector = |key: &str, v: &Option<Vec<f64>>, range: &bounds::Range| -> Result<[Real; 3]> {
        let v = match v {
            Some(v) => components(key, v, "[x, y, z] (hand frame)")?,
            None => [0.0; 3],
        };
        if v.iter().any(|x| !x.is_finite()) {
            bail!("{key}: every component must be a finite number, got {v:?}");
        }
        range.check(
            &format!("{key} (its magnitude)"),
            v.iter().map(|x| x * x).sum::<f64>().sqrt(),
        )?;
        Ok(v)
    };
    let force = vector("pipeline.push_n", &raw.push_n, &bounds::PUSH_FORCE)?;
    let torque = vector("pipeline.push_nm", &raw.push_nm, &bounds::PUSH_TORQUE)?;
    if force.iter().chain(&torque).all(|&x| x == 0.0) {
        bail!("pipeline.push_n / push_nm: both are zero, a push of nothing (leave them out)");
    }
    Ok(Some(Push {
        force,
        torque,
        at: bounds::PUSH_AT.or("pipeline.push_at_s", at, DEFAULT_PUSH_AT_S)?,
        duration: bounds::PUSH_DURATION.or("pipeline.push_ms", ms, DEFAULT_PUSH_MS)? * 1e-3,
    }))
}

pub(crate) fn pipeline_spec(raw: RawPipeline) -> Result<PipelineSpec> {
    let push = push_spec(&raw)?;
    let rig = raw.rig.unwrap_or_else(|| "sim".into());
    if rig.is_empty()
        || rig.len() > 48
        || !rig
            .bytes()
            .all(|b| b.is_ascii_alphanumeric() || b == b'_' || b == b'-')
    {
        bail!("pipeline.rig: use 1 to 48 letters, digits, '_' or '-', got {rig:?}");
    }
    let rate_hz = bounds::RATE.or("pipeline.rate_hz", raw.rate_hz, 1000.0)?;
    let pose_rate_hz = bounds::POSE_RATE
        .up_to(
            rate_hz.min(bounds::POSE_RATE.hi),
            "at least one correction a second; at most one per tick of pipeline.rate_hz",
        )
        .or("pipeline.pose_rate_hz", raw.pose_rate_hz, 30.0)?;
    let pose_latency_ms =
        bounds::POSE_LATENCY.or("pipeline.pose_latency_ms", raw.pose_latency_ms, 30.0)?;
    let spec = PipelineSpec {
        rig,
        rate_hz,
        joint_speed: bounds::JOINT_SPEED
            .or("pipeline.joint_speed_deg_s", raw.joint_speed_deg_s, 360.0)?
            .to_radians(),
        joint_noise: bounds::JOINT_NOISE
            .or("pipeline.joint_noise_deg", raw.joint_noise_deg, 0.02)?
            .to_radians(),
        pose_rate_hz,
        pose_noise: bounds::POSE_NOISE
            .or("pipeline.pose_noise_deg", raw.pose_noise_deg, 0.2)?
            .to_radians(),
        pose_latency: pose_latency_ms * 1e-3,
        max_input_age: bounds::INPUT_AGE.or(
            "pipeline.max_input_age_ms",
            raw.max_input_age_ms,
            200.0,
        )? * 1e-3,
        min_normal_force: bounds::NORMAL_FORCE.or(
            "pipeline.min_normal_force",
            raw.min_normal_force,
            1.0,
        )?,
        max_hold: bounds::MAX_HOLD.or("pipeline.max_hold_s", raw.max_hold_s, 30.0)?,
        slip: bounds::SLIP
            .or("pipeline.slip_deg", raw.slip_deg, 0.0)?
            .to_radians(),
        slip_at: bounds::SLIP_AT.or("pipeline.slip_at_s", raw.slip_at_s, 5.0)?,
        push,
        seed: raw.seed.unwrap_or(1),
        nodes: nodes_spec(raw.nodes)?,
        max_pose_innovation: bounds::POSE_INNOVATION
            .or(
                "pipeline.max_pose_innovation_deg",
                raw.max_pose_innovation_deg,
                DEFAULT_MAX_POSE_INNOVATION_DEG,
            )?
            .to_radians(),
        max_contact_residual: bounds::CONTACT_RESIDUAL.or(
            "pipeline.max_contact_residual_mm",
            raw.max_contact_residual_mm,
            DEFAULT_MAX_CONTACT_RESIDUAL_MM,
        )? * 1e-3,
        hung_restart: bounds::HUNG_RESTART.or(
            "pipeline.hung_restart_s",
            raw.hung_restart_s,
            DEFAULT_HUNG_RESTART_S,
        )?,
        realtime_priority: match raw.realtime_priority.unwrap_or(DEFAULT_REALTIME_PRIORITY) {
            p @ 0..=99 => p as u8,
            p => bail!(
                "pipeline.realtime_priority: 0 (normal scheduling) or a SCHED_FIFO priority from 1 to 99, got {p}"
            ),
        },
    };
    if raw.slip_at_s.is_some() && spec.slip == 0.0 {
        bail!(
            "pipeline.slip_at_s: there is no slip to time (the kinematic plant's scripted slip, pipeline.slip_deg, is not given or 0), so it has no effect: give slip_deg, or leave slip_at_s out"
        );
    }
    // The estimate's own noise must leave the innovation's bound for real errors: the
    // smoothed innovation's noise is a third of the pose noise, the estimate's 0.42 of it.
    if spec.pose_noise > 0.5 * spec.max_pose_innovation {
        bail!(
            "pipeline.pose_noise_deg: at most half of pipeline.max_pose_innovation_deg ({} deg), or the measurements' own noise would hold the hand; got {}",
            num(spec.max_pose_innovation.to_degrees()),
            num(spec.pose_noise.to_degrees())
        );
    }
    Ok(spec)
}

fn nodes_spec(raw: Option<Vec<String>>) -> Result<Vec<String>> {
    let Some(nodes) = raw else {
        return Ok(NODES.iter().map(|n| n.to_string()).collect());
    };
    if nodes.is_empty() {
        bail!("pipeline.nodes: names no node; the nodes are {NODES:?}");
    }
    for (i, n) in nodes.iter().enumerate() {
        if !NODES.contains(&n.as_str()) {
            bail!("pipeline.nodes: unknown node {n:?}; the nodes are {NODES:?}");
        }
        if nodes[..i].contains(n) {
            bail!("pipeline.nodes: {n:?} is named twice");
        }
    }
    // Start order, whatever the order written.
    Ok(NODES
        .iter()
        .filter(|n| nodes.iter().any(|m| m == *n))
        .map(|n| n.to_string())
        .collect())
}
