//! The whole loop in one process on simulated time: the MuJoCo plant ([`Physical`]), the
//! [`Estimator`], the [`WrenchSpace`] step, the planner node's [`Follower`] and the hand
//! [`Commander`], each the very step its node runs, called in the order the messages flow,
//! one plant tick at a time, with the time each message would carry. Nothing waits: a run of
//! 20 s of simulated time takes a few seconds, and the same config gives the same run.
//!
//! It is what the loop computes, without what the processes add (scheduling, transport
//! latency, restarts): for tuning the physics, and for tests that need many runs of it (pushes
//! at many times). The pipeline tests run the real processes.
//!
//! Per tick `t` (every `1 / pipeline.rate_hz`): the plant advances under the last command and
//! measures; the estimator takes the joint state (and a pose when one is due); the planner
//! follows the estimate (its step republished every [`crate::planner::REPUBLISH`] s as the node
//! does; of the steps it publishes in one tick the command node takes the last, as it takes
//! the newest off the bus); the wrench space of the grasp state; the command that answers it,
//! which the plant follows at the next tick (one period later, as the nodes' hops are on a
//! real machine).

use anyhow::{Context as _, Result};
use icrflow_interfaces::{
    CommandMode, GraspState, HandCommand, Header, JointState, Kind, PlanPhase, PlanStepHeader,
    PlantTruth,
};
use icrflow_plan::follow::{Estimate, Event, Follower, Tolerances};
use icrflow_scenario::{Config, PlantKind, Setup};

use crate::command::Commander;
use crate::estimator::Estimator;
use crate::physical::Physical;
use crate::planner::{CLEARANCE, REPUBLISH, estimate, message};
use crate::wrench::WrenchSpace;

/// What a tick of a lockstep run shows an observer.
pub struct Tick<'s> {
    /// The simulated time since the start (s).
    pub time: f64,
    /// The plant (MuJoCo's state through [`Physical::sim`]).
    pub plant: &'s Physical<'s>,
    /// The newest plan step the planner published (none before the first; the command node
    /// was offered it, and its gate may have refused it).
    pub plan: Option<&'s PlanStepHeader>,
    /// The estimate of this tick, if the estimator made one.
    pub grasp: Option<&'s GraspState>,
    /// The command made this tick, and why it holds if it does.
    pub command: Option<(&'s HandCommand, Option<&'s str>)>,
    /// The truth published this tick (every tenth).
    pub truth: Option<&'s PlantTruth>,
}

/// How a lockstep run ended.
#[derive(Debug, Clone, PartialEq)]
pub struct Ended {
    /// The planner published `Done` (it followed the plan to its end).
    pub done: bool,
    /// Simulated time (s).
    pub time: f64,
    /// The estimated rotation at the end (rad).
    pub estimated: f64,
    /// MuJoCo's true rotation at the end (rad).
    pub rotation: f64,
    /// Hold commands.
    pub holds: u64,
    /// Plans made again from the estimate.
    pub replans: u32,
    /// The reason of the last hold, if the run ended holding.
    pub holding: Option<String>,
    /// What the planner said of each re-plan (as the planner node logs it), with the
    /// simulated time.
    pub replanned: Vec<(f64, String)>,
}

/// Runs `config`'s scenario (`plant.kind` must be `"mujoco"`) in lockstep for at most
/// `seconds` of simulated time, or until the planner is done and `settle` s more have passed;
/// `observe` sees every tick. A plan made again from the estimate takes `replan_s` s of
/// simulated time, as the planner node's takes time on the machine (1.2 to 1.6 s for the
/// ellipsoid mesh on a 2-core VM): meanwhile the planner publishes nothing, its last step goes
/// stale and the command node holds; then the new plan's first target is published. With 0 a
/// re-plan takes no time.
pub fn run(
    config: &Config,
    setup: &Setup,
    seconds: f64,
    settle: f64,
    replan_s: f64,
    observe: &mut dyn FnMut(&Tick<'_>),
) -> Result<Ended> {
    anyhow::ensure!(
        config.plant.kind == PlantKind::Mujoco,
        "a lockstep run needs plant.kind = \"mujoco\""
    );
    let p = &config.pipeline;
    let dt = (1e9 / p.rate_hz).round() as u64;
    // Any start time: the steps only compare times.
    let t0: u64 = 1_000_000_000_000;
    let (joints, _) = setup.initial_grip(config)?;
    let mut plant = Physical::new(config, setup, &joints, t0)?;
    let mut estimator = Estimator::new(&setup.hand, setup.roller(config)?, &setup.problem, 0.0);
    let mut wrench = WrenchSpace::new(&setup.problem, config.grasp.alpha);
    let mut follower = Follower::new_with(
        setup.planning(config)?,
        CLEARANCE,
        Tolerances::new(p.joint_noise),
        &mut |_| {},
        &mut |_| {},
    )
    .context("planning")?;
    let mut commander = Commander::new(config, setup, t0);
    let republish = (REPUBLISH * 1e9).round() as u64;
    let (mut joint_seq, mut grasp_seq, mut wrench_seq, mut plan_seq, mut command_seq) =
        (0u64, 0u64, 0u64, 0u64, 0u64);
    let mut first_position: Option<[f64; 3]> = None;
    let mut e = Estimate::default();
    let mut command: Option<HandCommand> = None;
    let mut plan: Option<PlanStepHeader> = None;
    let mut last_grasp: Option<Header> = None;
    let mut next_republish = t0;
    let mut done_at: Option<u64> = None;
    let mut holds = 0;
    let mut holding: Option<String> = None;
    let mut replanned = Vec::new();
    let replan_ns = (replan_s.max(0.0) * 1e9) as u64;
    // While the planner plans again (until then), it follows and publishes nothing.
    let mut busy_until: Option<u64> = None;
    let end = t0 + (seconds * 1e9) as u64;
    let mut t = t0;
    while t < end {
        t += dt;
        let out = plant.tick(t, command.as_ref());
        joint_seq += 1;
        let mut joints: JointState = out.joints;
        joints.header = stamped(Header::new(Kind::JointState, joint_seq, 0, 0), t);
        if let Some(pose) = &out.pose {
            let start = *first_position.get_or_insert(pose.position);
            let moved = [0, 1, 2].map(|k| pose.position[k] - start[k]);
            let _ = estimator
                .on_pose(
                    estimator.rotation_of(pose.orientation),
                    pose.captured_time_ns,
                )
                .and_then(|_| estimator.on_position(moved));
        }
        grasp_seq += 1;
        let header = stamped(
            Header::after(Kind::GraspState, grasp_seq, &joints.header, t),
            t,
        );
        let grasp = estimator.on_joints(&joints, header).ok();
        // The planner: the estimate followed, the current target republished on its timer.
        let mut published: Option<PlanStepHeader> = None;
        let mut publish = |follower: &Follower<'_>, k: usize, input: Option<Header>| {
            let targets = follower.targets();
            let at = k.min(targets.len() - 1);
            plan_seq += 1;
            let header = match input {
                Some(h) => Header::after(Kind::PlanStep, plan_seq, &h, t),
                None => Header::new(Kind::PlanStep, plan_seq, 0, 0),
            };
            let m = message(
                &targets[at],
                k >= targets.len(),
                &Default::default(),
                stamped(header, t),
            );
            published = Some(m);
        };
        // The new plan's first target, published when the planning is over.
        let busy = busy_until.is_some_and(|b| t < b);
        if !busy && busy_until.take().is_some() {
            if let Some(k) = follower.current() {
                publish(&follower, k, last_grasp);
            }
            next_republish = t + republish;
        }
        if let Some(g) = &grasp
            && g.rotation.is_finite()
            && !busy
        {
            last_grasp = Some(g.header);
            estimate(g, &setup.hand, &mut e);
            let followed = follower.on_estimate(&e, t, &mut || {});
            match &followed.event {
                Some(Event::Replanned(r)) => {
                    let mut said = r.to_string();
                    for n in &r.notes {
                        said += &format!("; {n}");
                    }
                    if !r.plan.summary.completed {
                        said += &format!(
                            "; the new plan stops short of the goal: {}",
                            r.plan.summary.stop_reason.as_deref().unwrap_or("?")
                        );
                    }
                    replanned.push(((t - t0) as f64 * 1e-9, said));
                    if replan_ns > 0 {
                        busy_until = Some(t + replan_ns);
                    }
                }
                Some(e @ Event::ReplanFailed { .. }) => {
                    replanned.push(((t - t0) as f64 * 1e-9, e.to_string()));
                }
                _ => {}
            }
            if busy_until.is_none() {
                for k in followed.commands() {
                    publish(&follower, k, last_grasp);
                }
            }
        }
        if t >= next_republish && busy_until.is_none() {
            next_republish = t + republish;
            if let Some(k) = follower.current() {
                publish(&follower, k, last_grasp);
            }
        }
        if let Some(m) = published {
            if m.phase == PlanPhase::Done as u32 {
                done_at.get_or_insert(t);
            }
            let _ = commander.on_plan(&m, t);
            plan = Some(m);
        }
        // The wrench space of the grasp state, and the command that answers it.
        let mut made: Option<(HandCommand, Option<String>)> = None;
        if let Some(g) = &grasp {
            commander.on_grasp(g);
            wrench_seq += 1;
            let h = stamped(
                Header::after(Kind::WrenchSpace, wrench_seq, &g.header, t),
                t,
            );
            if let Ok(w) = wrench.on_grasp(g, h) {
                let c = commander.on_wrench(&w.header, t);
                made = Some((c.command, c.hold.map(str::to_string)));
            }
        }
        if made.is_none()
            && let Some(c) = commander.on_tick(t)
        {
            made = Some((c.command, c.hold.map(str::to_string)));
        }
        if let Some((mut c, why)) = made.take() {
            command_seq += 1;
            c.header.sequence = command_seq;
            c.header.source_time_ns = t;
            if c.mode == CommandMode::Hold as u32 {
                holds += 1;
            }
            holding = why.clone();
            command = Some(c);
            made = Some((c, why));
        }
        observe(&Tick {
            time: (t - t0) as f64 * 1e-9,
            plant: &plant,
            plan: plan.as_ref(),
            grasp: grasp.as_ref(),
            command: made.as_ref().map(|(c, why)| (c, why.as_deref())),
            truth: out.truth.as_ref(),
        });
        if done_at.is_some_and(|d| t >= d + (settle * 1e9) as u64) {
            break;
        }
    }
    Ok(Ended {
        done: done_at.is_some(),
        time: (t - t0) as f64 * 1e-9,
        estimated: estimator.rotation(),
        rotation: plant.rotation(),
        holds,
        replans: follower.replans(),
        holding,
        replanned,
    })
}

/// `h` as published at `t` (the bus stamps the source time).
fn stamped(mut h: Header, t: u64) -> Header {
    h.source_time_ns = t;
    h
}
