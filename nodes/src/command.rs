//! The hand command node (`icrflow-command`): turns the planner's current step into a hand
//! command, joint targets and fingertip forces that balance the grasp, only when the
//! [`Gate`] allows it; otherwise it holds the last safe command and says why.
//!
//! Every input event and every tick of the loop rate: offer the newest plan step, grasp state
//! and wrench space to the gate (refused ones are counted and reported in the node's health);
//! if the gate allows, the joint targets are the plan step's, clamped into the joint limits
//! and to at most `pipeline.joint_speed_deg_s` from the last command per elapsed time, and
//! the forces balance zero external wrench inside the exact friction cones with the
//! configured minimum normal force ([`icrflow_plan::forces::balance`]; infeasible holds).

use std::time::Duration;

use anyhow::Result;
use iceoryx2::prelude::*;
use icrflow_grasp::math::Vec3;
use icrflow_interfaces::{
    CommandMode, GraspState, HandCommand, Header, Kind, MAX_FINGERS, MAX_JOINTS, NodeState,
    PlanStepHeader, WrenchSpaceHeader, topics, write_text,
};
use icrflow_plan::forces::{ForceContact, balance};

use crate::runtime::{Context, Health, Sequence, now, serve};
use crate::safety::Gate;

/// Runs the hand command node.
pub fn run(ctx: &Context) -> Result<()> {
    let p = &ctx.config.pipeline;
    let hand = &ctx.setup.hand;
    let problem = &ctx.setup.problem;
    let mu = ctx.config.grasp.model.mu();
    let plans = ctx
        .bus
        .slice_subscriber::<PlanStepHeader, u32>(topics::PLAN_STEP)?;
    let grasps = ctx.bus.subscriber::<GraspState>(topics::GRASP_STATE)?;
    let wrenches = ctx
        .bus
        .slice_subscriber::<WrenchSpaceHeader, icrflow_interfaces::Facet>(topics::WRENCH_SPACE)?;
    let out = ctx.bus.publisher::<HandCommand>(topics::HAND_COMMAND)?;
    let mut health = Health::new(ctx)?;
    let mut seq = Sequence::default();
    let mut gate = Gate::new((p.max_input_age * 1e9) as u64, ctx.config.grasp.alpha);
    let mut regions = Vec::with_capacity(4096);
    let mut facets = Vec::with_capacity(4096);
    let mut last: Option<(HandCommand, u64)> = None;
    let mut last_grasp: Option<GraspState> = None;
    let mut wrench_origin = 0u64;
    let dt = 1.0 / p.rate_hz;
    let mut contacts = Vec::with_capacity(MAX_FINGERS);

    let ws = WaitSetBuilder::new().create::<ipc::Service>()?;
    let w_plan = ws.attach_notification(plans.listener())?;
    let w_grasp = ws.attach_notification(grasps.listener())?;
    let w_wrench = ws.attach_notification(wrenches.listener())?;
    let tick = ws.attach_interval(Duration::from_secs_f64(dt))?;
    let mut ticks = 0u64;
    serve(&ws, |id| {
        let t = now();
        if id.has_event_from(&w_plan)
            && let Some(m) = plans.latest(&mut regions)?
        {
            health.processed += 1;
            if let Err(e) = gate.offer_plan(&m, t) {
                health.refuse(e);
            }
        }
        if id.has_event_from(&w_grasp)
            && let Some(m) = grasps.latest()?
        {
            health.processed += 1;
            match gate.offer_grasp(&m, t) {
                Ok(()) => last_grasp = Some(m),
                Err(e) => health.refuse(e),
            }
        }
        if id.has_event_from(&w_wrench)
            && let Some(m) = wrenches.latest(&mut facets)?
        {
            health.processed += 1;
            match gate.offer_wrench(&m, t) {
                Ok(()) => wrench_origin = m.header.origin_time_ns,
                Err(e) => health.refuse(e),
            }
        }
        let event =
            id.has_event_from(&w_plan) || id.has_event_from(&w_wrench) || id.has_event_from(&tick);
        if !event {
            return Ok(());
        }
        ticks += 1;
        let decision = gate.decide(t).copied();
        let command = match decision {
            Ok(plan) => {
                let theta = last_grasp.map_or(0.0, |g| g.rotation);
                let rot = nalgebra::Rotation3::from_axis_angle(&Vec3::z_axis(), theta);
                contacts.clear();
                let mut slots = Vec::with_capacity(MAX_FINGERS);
                for (k, target) in plan
                    .targets
                    .iter()
                    .enumerate()
                    .take(plan.finger_count as usize)
                {
                    if target.in_contact == 1 {
                        let c = target.candidate as usize;
                        let cands = problem.candidates();
                        if c < cands.points.len() {
                            contacts.push(ForceContact {
                                point: rot * (cands.points[c] - ctx.setup.object.centre_of_mass),
                                normal: rot * cands.normals[c],
                            });
                            slots.push(k);
                        }
                    }
                }
                match balance(
                    &contacts,
                    &Vec3::zeros(),
                    mu,
                    p.min_normal_force,
                    &Vec3::zeros(),
                    &Vec3::zeros(),
                ) {
                    Ok(forces) => {
                        let mut c = HandCommand {
                            header: Header::new(
                                Kind::HandCommand,
                                seq.advance(),
                                last_grasp.map_or(0, |g| g.header.sequence),
                                // Caused by the newest measurement among the inputs.
                                plan.header
                                    .origin_time_ns
                                    .max(last_grasp.map_or(0, |g| g.header.origin_time_ns))
                                    .max(wrench_origin),
                            ),
                            mode: CommandMode::Track as u32,
                            finger_count: plan.finger_count,
                            quality: gate.quality(),
                            ..Default::default()
                        };
                        let elapsed =
                            last.map_or(dt, |(_, when)| (t.saturating_sub(when)) as f64 * 1e-9);
                        let max_step = p.joint_speed * elapsed.max(dt);
                        for (k, target) in plan
                            .targets
                            .iter()
                            .enumerate()
                            .take(plan.finger_count as usize)
                        {
                            c.finger_ids[k] = target.finger;
                            let Some(f) = hand.finger(target.finger) else {
                                continue;
                            };
                            for j in 0..(target.joint_count as usize).min(MAX_JOINTS).min(f.dof()) {
                                let mut goal =
                                    target.joints[j].clamp(f.joints[j].lower, f.joints[j].upper);
                                if let Some((prev, _)) = &last {
                                    let from = prev.joint_targets[k][j];
                                    goal = from + (goal - from).clamp(-max_step, max_step);
                                }
                                c.joint_targets[k][j] = goal;
                            }
                        }
                        for (slot, f) in slots.iter().zip(&forces) {
                            c.forces[*slot] = [f.x, f.y, f.z];
                        }
                        Some(c)
                    }
                    Err(e) => {
                        health.refuse(format!("forces: {e}"));
                        None
                    }
                }
            }
            Err(hold) => {
                health.refuse(&hold);
                None
            }
        };
        let command = match command {
            Some(c) => {
                last = Some((c, t));
                c
            }
            None => {
                // Hold the last safe command (or, before any, no motion at all).
                let mut c = last.map_or_else(HandCommand::default, |(c, _)| c);
                c.header = Header::new(Kind::HandCommand, seq.advance(), 0, 0);
                c.mode = CommandMode::Hold as u32;
                c.quality = 0.0;
                write_text(&mut c.reason, &health.last_problem);
                c
            }
        };
        out.send(command)?;
        if ticks.is_multiple_of(50) {
            let state = if command.mode == CommandMode::Hold as u32 {
                NodeState::Degraded
            } else {
                NodeState::Running
            };
            health.report(state)?;
        }
        Ok(())
    })
}
