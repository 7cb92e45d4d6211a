//! The hand command node (`icrflow-command`): turns the planner's current step into a hand
//! command, joint targets and fingertip forces that balance the grasp, only when the
//! [`Gate`] allows it; otherwise it holds the last safe command and says why.
//!
//! The critical path is three hops long: joint measurement (plant) -> grasp state (estimator)
//! -> wrench space (wrench-space node) -> hand command. Every wrench space is answered by one
//! command, computed from that wrench space together with the very grasp state it was computed
//! from (matched by sequence number; the grasp states are read off the bus only then, so they
//! cost no wake-up), and the newest plan step, which the planner publishes beside the path at
//! its own rate. The command stream therefore runs at the plant's measurement rate
//! (`pipeline.rate_hz`). When no wrench space has come for [`WATCHDOG_PERIODS`] periods, the
//! node's own timer sends holds at that rate.
//!
//! It also holds when the estimate doubts itself: the grasp state's smoothed pose innovation
//! over `pipeline.max_pose_innovation_deg`, or its contact residual over
//! `pipeline.max_contact_residual_mm` ([`EstimateBounds`]).
//!
//! A tracking command's joint targets are the plan step's, clamped into the joint limits, and
//! approached along a straight line in each finger's joint space at most
//! `pipeline.joint_speed_deg_s` per elapsed time (so the stream interpolates between plan
//! steps, and the fingertips follow the planned rolling), and its forces balance zero external
//! wrench inside
//! the exact friction cones with the configured minimum normal force
//! ([`icrflow_plan::forces::ForceSolver`], kept across commands so a new contact set costs no
//! allocation; infeasible holds).

use std::collections::VecDeque;
use std::time::Duration;

use anyhow::Result;
use icrflow_grasp::math::Vec3;
use icrflow_interfaces::{
    CommandMode, GraspState, HandCommand, Header, Kind, MAX_FINGERS, MAX_JOINTS, PlanStepHeader,
    topics, write_text,
};
use icrflow_plan::forces::{ForceContact, ForceSolver, Load};

use crate::Context;
use crate::safety::{EstimateBounds, Gate, Hold};
use icrflow_runtime::event::serve;
use icrflow_runtime::health::{Health, Sequence, now};

/// Periods without a wrench space after which the node holds on its own timer.
pub const WATCHDOG_PERIODS: f64 = 3.0;
/// Grasp states kept to find the one behind a wrench space.
const RECENT: usize = 16;

/// Runs the hand command node.
pub fn run(ctx: &Context) -> Result<()> {
    let p = &ctx.scenario.config.pipeline;
    let plans = ctx.bus.slice_subscriber(topics::PLAN_STEP)?;
    let grasps = ctx.bus.subscriber(topics::GRASP_STATE)?;
    let wrenches = ctx.bus.slice_subscriber(topics::WRENCH_SPACE)?;
    let out = ctx.bus.publisher(topics::HAND_COMMAND)?;
    let mut health = Health::new(ctx)?;
    let mut seq = Sequence::default();
    let bounds = EstimateBounds {
        pose_innovation: p.max_pose_innovation,
        contact_residual: p.max_contact_residual,
    };
    let mut gate = Gate::new(
        (p.max_input_age * 1e9) as u64,
        ctx.scenario.config.grasp.alpha,
        bounds,
    );
    let mut regions = Vec::with_capacity(4096);
    let mut facets = Vec::with_capacity(4096);
    let mut recent: VecDeque<GraspState> = VecDeque::with_capacity(RECENT);
    let mut tracker = Tracker {
        ctx,
        contacts: Vec::with_capacity(MAX_FINGERS),
        solver: ForceSolver::new(),
        solved_for: None,
        forces: Vec::with_capacity(MAX_FINGERS),
        last: None,
    };
    let period = 1.0 / p.rate_hz;
    let watchdog_ns = (WATCHDOG_PERIODS * period * 1e9) as u64;
    let mut last_sent = now();

    let tick = Some(Duration::from_secs_f64(period));
    serve(
        ctx,
        &[plans.listener(), wrenches.listener()],
        tick,
        |ticked| {
            health.tick()?;
            let plan = plans.latest(&mut regions)?;
            let wrench = wrenches.latest(&mut facets)?;
            if wrench.is_some() {
                grasps.drain(|g| {
                    if recent.len() == RECENT {
                        recent.pop_front();
                    }
                    recent.push_back(*g);
                })?;
            }
            // The clock is read after the inputs, so that every input's age is measured at the
            // decision: one published between a clock reading and the reads would count as 0 old.
            let t = now();
            if let Some(m) = plan {
                health.processed += 1;
                if let Err(e) = gate.offer_plan(&m, t) {
                    health.refuse(e);
                }
            }
            // The answer to a wrench space: the header of the command it causes (None: hold).
            let mut answer: Option<Option<Header>> = None;
            if let Some(w) = wrench {
                health.processed += 1;
                let behind = recent
                    .iter()
                    .rev()
                    .find(|g| g.header.sequence == w.header.input_sequence);
                let accepted = match behind {
                    None => Err(format!(
                        "wrench space {}: its grasp state {} was not received",
                        w.header.sequence, w.header.input_sequence
                    )),
                    Some(g) => gate
                        .offer_grasp(g, t)
                        .and_then(|()| gate.offer_wrench(&w, t))
                        .map_err(|e| e.to_string()),
                };
                answer = Some(match accepted {
                    Ok(()) => Some(Header::after(Kind::HandCommand, 0, &w.header, t)),
                    Err(why) => {
                        health.refuse(why);
                        None
                    }
                });
            }
            let command = match answer {
                Some(Some(header)) => match gate.decide(t) {
                    Ok(plan) => match tracker.track(plan, &gate, header, t) {
                        Ok(c) => Some(c),
                        Err(why) => {
                            health.refuse(why);
                            None
                        }
                    },
                    Err(hold) => {
                        health.refuse(&hold);
                        None
                    }
                },
                Some(None) => None,
                None if ticked && t.saturating_sub(last_sent) > watchdog_ns => {
                    let quiet = Hold::Quiet {
                        ms: t.saturating_sub(last_sent) as f64 * 1e-6,
                    };
                    health.refuse(gate.decide(t).err().unwrap_or(quiet));
                    None
                }
                None => return Ok(()),
            };
            let mut c = command.unwrap_or_else(|| tracker.hold(&health.last_problem));
            c.header.sequence = seq.advance();
            out.publish(c)?;
            last_sent = t;
            Ok(())
        },
    )
}

/// Tracking commands: the plan step's joint targets within limits and speed, and balancing
/// fingertip forces.
struct Tracker<'a> {
    ctx: &'a Context,
    contacts: Vec<ForceContact>,
    solver: ForceSolver,
    /// The contact set `forces` balance (candidates in slot order, padded with MAX).
    solved_for: Option<[u32; MAX_FINGERS]>,
    /// The body-frame forces of that contact set, one per contact.
    forces: Vec<Vec3>,
    /// The last tracking command and when it was made.
    last: Option<(HandCommand, u64)>,
}

impl Tracker<'_> {
    /// The command that follows `plan` in the grasp the gate accepted, with `header`, at time
    /// `t`; or why there is none.
    fn track(
        &mut self,
        plan: &PlanStepHeader,
        gate: &Gate,
        header: Header,
        t: u64,
    ) -> Result<HandCommand, String> {
        let ctx = self.ctx;
        let p = &ctx.scenario.config.pipeline;
        let hand = &ctx.scenario.setup.hand;
        let cands = ctx.scenario.setup.problem.candidates();
        let theta = gate.grasp().map_or(0.0, |g| g.rotation);
        let rot = nalgebra::Rotation3::from_axis_angle(&Vec3::z_axis(), theta);
        let n = (plan.finger_count as usize).min(MAX_FINGERS);
        let mut slots = [0usize; MAX_FINGERS];
        let mut set = [u32::MAX; MAX_FINGERS];
        let mut count = 0;
        for (k, target) in plan.targets.iter().enumerate().take(n) {
            if target.in_contact == 1 && (target.candidate as usize) < cands.points.len() {
                slots[count] = k;
                set[count] = target.candidate;
                count += 1;
            }
        }
        // The forces in the object's frame, solved once per contact set: with no external
        // load the problem is invariant under rotation (cones, equilibrium, and the least
        // squared force alike), so the hand-frame forces are these rotated.
        if self.solved_for != Some(set) {
            self.solved_for = None;
            self.contacts.clear();
            for &c in set.iter().take(count) {
                self.contacts.push(ForceContact {
                    point: cands.points[c as usize] - ctx.scenario.setup.object.centre_of_mass,
                    normal: cands.normals[c as usize],
                });
            }
            self.solver
                .solve(
                    &self.contacts,
                    &Load::none(),
                    ctx.scenario.config.grasp.model.mu(),
                    p.min_normal_force,
                    &mut self.forces,
                )
                .map_err(|e| format!("forces: {e}"))?;
            self.solved_for = Some(set);
        }
        let forces = &self.forces;
        let mut c = HandCommand {
            header,
            mode: CommandMode::Track as u32,
            finger_count: plan.finger_count,
            quality: gate.quality(),
            ..Default::default()
        };
        let dt = 1.0 / p.rate_hz;
        // The motion is that of the time since the last tracking command (a late input moves
        // the command on as far as the hand has gone meanwhile). Resumed, after no tracking
        // command for longer than the watchdog's periods (a hold, a restart): the hand sets off
        // from where it stands, one period's motion, and does not jump to where the plan has
        // gone meanwhile.
        let since = self
            .last
            .map(|(_, when)| t.saturating_sub(when) as f64 * 1e-9);
        let resumed = since.is_none_or(|s| s > WATCHDOG_PERIODS * dt);
        let elapsed = match since {
            Some(s) if !resumed => s.max(dt),
            _ => dt,
        };
        let max_step = p.joint_speed * elapsed;
        for (k, target) in plan.targets.iter().enumerate().take(n) {
            c.finger_ids[k] = target.finger;
            let Some(f) = hand.finger(target.finger) else {
                continue;
            };
            let joints = (target.joint_count as usize).min(MAX_JOINTS).min(f.dof());
            let mut goal = [0.0; MAX_JOINTS];
            for (j, g) in goal.iter_mut().enumerate().take(joints) {
                *g = target.joints[j].clamp(f.joints[j].lower, f.joints[j].upper);
            }
            // Toward the goal along a straight line in joint space, the largest joint motion at
            // most `max_step`: every joint of the finger scaled alike, so the fingertip follows
            // the planned rolling between the planner's closely spaced targets (clamping each
            // joint on its own would bend the path off the object's surface). From the last
            // tracking command; when resumed, from the joints the grasp state was estimated
            // from: where the hand stopped, which may be short of the last command.
            let from = match self.last {
                Some((prev, _)) if !resumed => Some(prev.joint_targets[k]),
                _ => gate.grasp().and_then(|g| {
                    let n = (g.finger_count as usize).min(MAX_FINGERS);
                    (0..n)
                        .find(|&s| g.fingers[s].finger == target.finger)
                        .map(|s| g.joints[s])
                }),
            };
            let scale = from.map_or(1.0, |from| {
                let largest = (0..joints).fold(0.0_f64, |m, j| m.max((goal[j] - from[j]).abs()));
                if largest > max_step {
                    max_step / largest
                } else {
                    1.0
                }
            });
            for j in 0..joints {
                c.joint_targets[k][j] = match from {
                    Some(from) => from[j] + scale * (goal[j] - from[j]),
                    None => goal[j],
                };
            }
        }
        for (slot, f) in slots.iter().zip(forces) {
            let f = rot * f;
            c.forces[*slot] = [f.x, f.y, f.z];
        }
        self.last = Some((c, t));
        Ok(c)
    }

    /// A hold of the last tracking command (before any, no motion at all), saying `why`.
    fn hold(&self, why: &str) -> HandCommand {
        let mut c = self.last.map_or_else(HandCommand::default, |(c, _)| c);
        c.header = Header::new(Kind::HandCommand, 0, 0, 0);
        c.mode = CommandMode::Hold as u32;
        c.quality = 0.0;
        write_text(&mut c.reason, why);
        c
    }
}
