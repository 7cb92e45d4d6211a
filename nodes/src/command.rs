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
//! A tracking command's joint targets are the plan step's, moved with the object where the
//! estimate has its centre moved from where the plan has it (a finger out of contact moved with
//! the object, so that it meets the surface where it is; the fingers in contact together against
//! the drift, by its integral: [`CENTRING_RATE`]; a planar hand's in its plane, a spatial
//! hand's in space), clamped into the joint limits, and
//! approached along a straight line in each finger's joint space at most
//! `pipeline.joint_speed_deg_s` per elapsed time (so the stream interpolates between plan
//! steps, and the fingertips follow the planned rolling; a command late by up to
//! [`LATE_PERIODS`] periods, nothing having refused to track meanwhile, moves on by the time
//! gone; after a longer gap or a hold the gate decided, one period's motion), and its forces, on the contacts of
//! the plan step that the estimate has made (an attaching finger presses only once it
//! touches: pressing on its way, it would hit the object, and the others, their forces
//! already those of the grasp with it, would let the object slip meanwhile), balance the
//! object's weight (`plant.gravity`, none by default) inside the exact friction cones narrowed by
//! `plant.friction_margin`, with the configured minimum normal force
//! ([`icrflow_plan::forces::ForceSolver`], kept across commands so a new contact set costs no
//! allocation; infeasible holds).
//!
//! [`Commander`] is the pure step (the inputs and the time in, the command to publish out);
//! [`run`] is the node around it (the bus, the timer, health).

use std::collections::VecDeque;
use std::fmt::Write as _;
use std::time::Duration;

use anyhow::Result;
use icrflow_grasp::math::Vec3;
use icrflow_interfaces::{
    CommandMode, GraspState, HandCommand, Header, Kind, MAX_FINGERS, MAX_JOINTS, PlanStepHeader,
    WrenchSpaceHeader, topics, write_text,
};
use icrflow_plan::forces::{Balance, ForceContact, ForceError, ForceSolver, Load};
use icrflow_scenario::{Config, Setup};

use crate::Context;
use crate::safety::{Attach, EstimateBounds, Gate, Hold};
use icrflow_runtime::event::serve;
use icrflow_runtime::health::{Health, Sequence, now};

/// Periods without a wrench space after which the node holds on its own timer.
pub const WATCHDOG_PERIODS: f64 = 3.0;
/// How fast the fingers in contact move against the object's estimated drift (1/s: the
/// integral gain of the centring, a time constant of half a second).
pub const CENTRING_RATE: f64 = 2.0;
/// The farthest the centring moves the fingers in contact (m).
pub const CENTRING_LIMIT: f64 = 3e-3;
/// How far the object may turn about a spatial plan's axis that is not vertical before the
/// balancing forces, whose load (the weight) turns with it in the object's frame, are solved
/// again (rad).
pub const RESOLVE_TURN: f64 = 0.5 * std::f64::consts::PI / 180.0;
/// Periods after the last tracking command within which a command that comes, nothing having
/// refused to track meanwhile, is late rather than resumed: it moves the hand's targets on by
/// the motion of the time gone, in one command (at most 3.6 degrees per joint at the default
/// 360 deg/s and 1 kHz; the hand held at the last command meanwhile, so it is that far behind
/// the plan's pace). After a hold the gate or the forces decided, a command more than
/// [`WATCHDOG_PERIODS`] late resumes, as every one did before 2026-12-06.
pub const LATE_PERIODS: f64 = 10.0;
/// Grasp states kept to find the one behind a wrench space.
const RECENT: usize = 16;

/// A command to publish ([`Commander::on_wrench`], [`Commander::on_tick`]), its sequence
/// number still 0.
#[derive(Debug, Clone, Copy)]
pub struct Command<'s> {
    /// The command: tracking, attaching below the margin, or holding the last command that
    /// moved the hand.
    pub command: HandCommand,
    /// Why it holds (also in the command's `reason`); `None` when it tracks.
    pub hold: Option<&'s str>,
}

/// The hand command step: the safety gate, the grasp states a wrench space may refer to, and
/// the tracking; no I/O, no clock.
pub struct Commander<'a> {
    gate: Gate,
    recent: VecDeque<GraspState>,
    tracker: Tracker<'a>,
    watchdog_ns: u64,
    /// When the last command was made.
    last_sent: u64,
    /// Why the last hold holds (kept: no allocation once grown).
    reason: String,
}

impl<'a> Commander<'a> {
    /// The hand command step of `setup` under `config`'s pipeline settings, at time `now`
    /// (ns; the watchdog counts from it until the first command).
    pub fn new(config: &'a Config, setup: &'a Setup, now: u64) -> Self {
        let p = &config.pipeline;
        let bounds = EstimateBounds {
            pose_innovation: p.max_pose_innovation,
            contact_residual: p.max_contact_residual,
        };
        Self {
            gate: Gate::new((p.max_input_age * 1e9) as u64, config.grasp.alpha, bounds),
            recent: VecDeque::with_capacity(RECENT),
            tracker: Tracker {
                config,
                setup,
                contacts: Vec::with_capacity(MAX_FINGERS),
                solver: ForceSolver::new(),
                solved_for: None,
                pressing: [u32::MAX; MAX_FINGERS],
                forces: Vec::with_capacity(MAX_FINGERS),
                last: None,
                held: None,
                centring: [0.0; 3],
                gated: false,
            },
            watchdog_ns: (WATCHDOG_PERIODS * (1.0 / p.rate_hz) * 1e9) as u64,
            last_sent: now,
            reason: String::with_capacity(256),
        }
    }

    /// The safety gate.
    pub fn gate(&self) -> &Gate {
        &self.gate
    }

    /// Offers plan step `m` to the gate at `now`; why it was refused, if it was.
    pub fn on_plan(&mut self, m: &PlanStepHeader, now: u64) -> Result<(), Hold> {
        self.gate.offer_plan(m, now)
    }

    /// Keeps grasp state `g` for the wrench spaces to come (the last [`RECENT`]).
    pub fn on_grasp(&mut self, g: &GraspState) {
        if self.recent.len() == RECENT {
            self.recent.pop_front();
        }
        self.recent.push_back(*g);
    }

    /// The answer to wrench space `w` at `now`: it and the grasp state it was computed from
    /// are offered to the gate; if the gate then allows it, the command that tracks the plan
    /// step; otherwise a hold, with the reason.
    pub fn on_wrench(&mut self, w: &WrenchSpaceHeader, now: u64) -> Command<'_> {
        self.reason.clear();
        let behind = self
            .recent
            .iter()
            .rev()
            .find(|g| g.header.sequence == w.header.input_sequence);
        let accepted = match behind {
            None => {
                let _ = write!(
                    self.reason,
                    "wrench space {}: its grasp state {} was not received",
                    w.header.sequence, w.header.input_sequence
                );
                false
            }
            Some(g) => match self
                .gate
                .offer_grasp(g, now)
                .and_then(|()| self.gate.offer_wrench(w, now))
            {
                Ok(()) => true,
                Err(why) => {
                    let _ = write!(self.reason, "{why}");
                    false
                }
            },
        };
        if accepted {
            let mut header = Header::after(Kind::HandCommand, 0, &w.header, now);
            header.source_time_ns = now;
            let decided = self.gate.decide(now).copied();
            // Below the margin, an attach that adds a finger to the grasp the gate judged goes
            // on, the grasp's fingers held (the gate's `attach_below_margin`); only where each
            // has a command to be held at (`Tracker::can_hold`).
            let attach = decided
                .as_ref()
                .err()
                .and_then(|h| self.attach_below_margin(h));
            match (decided, attach) {
                (Ok(plan), _) => return self.track(&plan, header, now, None),
                (Err(_), Some((plan, a))) => return self.track(&plan, header, now, Some(a)),
                (Err(hold), None) => {
                    let _ = write!(self.reason, "{hold}");
                }
            }
        }
        self.hold(now, true)
    }

    /// The command that tracks `plan` at `now` with `header` (attaching `attach` below the
    /// margin, the other fingers held); a hold if no forces balance its contacts.
    fn track(
        &mut self,
        plan: &PlanStepHeader,
        header: Header,
        now: u64,
        attach: Option<Attach>,
    ) -> Command<'_> {
        match self
            .tracker
            .track(plan, &self.gate, header, now, attach.map(|a| a.finger))
        {
            Ok(mut c) => {
                self.last_sent = now;
                let Some(a) = attach else {
                    return Command {
                        command: c,
                        hold: None,
                    };
                };
                c.mode = CommandMode::Attach as u32;
                let _ = write!(
                    self.reason,
                    "finger {} attaches, the others held: quality alpha* = {:.4} below the margin alpha = {}",
                    a.finger, a.quality, a.alpha
                );
                write_text(&mut c.reason, &self.reason);
                Command {
                    command: c,
                    hold: None,
                }
            }
            Err(e) => {
                let _ = write!(self.reason, "forces: {e}");
                self.hold(now, true)
            }
        }
    }

    /// The watchdog, on the node's timer at `now`: a hold when no command has been made for
    /// [`WATCHDOG_PERIODS`] periods (why the gate holds, or that no wrench space came).
    pub fn on_tick(&mut self, now: u64) -> Option<Command<'_>> {
        let quiet_ns = now.saturating_sub(self.last_sent);
        if quiet_ns <= self.watchdog_ns {
            return None;
        }
        let quiet = Hold::Quiet {
            ms: quiet_ns as f64 * 1e-6,
        };
        let refused = self.gate.decide(now).err();
        // Gated where the gate refuses to track; not where the wrench space that did not come
        // would have been answered by an attach below the margin (as `on_wrench` does).
        let gated = refused
            .as_ref()
            .is_some_and(|h| self.attach_below_margin(h).is_none());
        self.reason.clear();
        let _ = write!(self.reason, "{}", refused.unwrap_or(quiet));
        Some(self.hold(now, gated))
    }

    /// The attach below the margin that goes on despite the gate's `hold` (the gate's
    /// `attach_below_margin`), with the plan step it attaches in: only where each other finger
    /// has a command to be held at (`Tracker::can_hold`).
    fn attach_below_margin(&self, hold: &Hold) -> Option<(PlanStepHeader, Attach)> {
        let plan = self.gate.plan()?;
        self.gate
            .attach_below_margin(hold)
            .filter(|a| self.tracker.can_hold(plan, a.finger))
            .map(|a| (*plan, a))
    }

    /// A hold at `now` for the reason in `reason`: `gated` when something refused to track
    /// (the gate, the forces), not when the inputs were only late (the watchdog's own).
    fn hold(&mut self, now: u64, gated: bool) -> Command<'_> {
        self.last_sent = now;
        let mut c = self.tracker.hold(&self.reason, gated);
        c.header.source_time_ns = now;
        Command {
            command: c,
            hold: Some(&self.reason),
        }
    }
}

/// Runs the hand command node.
pub fn run(ctx: &Context) -> Result<()> {
    let plans = ctx.bus.slice_subscriber(topics::PLAN_STEP)?;
    let grasps = ctx.bus.subscriber(topics::GRASP_STATE)?;
    let wrenches = ctx.bus.slice_subscriber(topics::WRENCH_SPACE)?;
    let out = ctx.bus.publisher(topics::HAND_COMMAND)?;
    let mut health = Health::new(ctx)?;
    let mut seq = Sequence::default();
    let (mut regions, mut facets) = (Vec::with_capacity(4096), Vec::with_capacity(4096));
    let mut step = Commander::new(&ctx.scenario.config, &ctx.scenario.setup, now());
    let tick = Some(Duration::from_secs_f64(
        1.0 / ctx.scenario.config.pipeline.rate_hz,
    ));

    serve(
        ctx,
        &[plans.listener(), wrenches.listener()],
        tick,
        |ticked| {
            health.tick()?;
            let plan = plans.latest(&mut regions)?;
            let wrench = wrenches.latest(&mut facets)?;
            if wrench.is_some() {
                grasps.drain(|g| step.on_grasp(g))?;
            }
            // The clock is read after the inputs, so that every input's age is measured at the
            // decision: one published between a clock reading and the reads would count as 0 old.
            let t = now();
            if let Some(m) = plan {
                health.processed += 1;
                if let Err(e) = step.on_plan(&m, t) {
                    health.refuse(e);
                }
            }
            let command = match wrench {
                Some(w) => {
                    health.processed += 1;
                    Some(step.on_wrench(&w, t))
                }
                None if ticked => step.on_tick(t),
                None => None,
            };
            let Some(Command { mut command, hold }) = command else {
                return Ok(());
            };
            if let Some(why) = hold {
                health.refuse(why);
            }
            command.header.sequence = seq.advance();
            out.publish(command)?;
            Ok(())
        },
    )
}

/// Tracking commands: the plan step's joint targets within limits and speed, and balancing
/// fingertip forces.
struct Tracker<'a> {
    config: &'a Config,
    setup: &'a Setup,
    contacts: Vec<ForceContact>,
    solver: ForceSolver,
    /// The contact set `forces` balance (candidates in slot order, padded with MAX), and
    /// the object's rotation they were solved at (rad).
    solved_for: Option<([u32; MAX_FINGERS], f64)>,
    /// The fingers that pressed in the last tracking command (padded with MAX).
    pressing: [u32; MAX_FINGERS],
    /// The body-frame forces of that contact set, one per contact.
    forces: Vec<Vec3>,
    /// The last command that moved the hand (tracking or attaching) and when it was made.
    last: Option<(HandCommand, u64)>,
    /// While a finger attaches below the margin: the command before, whose joint targets hold
    /// the other fingers, the centring then, and the plan step and the finger attached.
    held: Option<(HandCommand, [f64; 3], (u64, u32))>,
    /// How far the fingers in contact are moved together to hold the object's centre where
    /// the plan has it (m; a planar hand's in the hand's plane).
    centring: [f64; 3],
    /// Whether a hold refused to track since the last tracking command (the gate's or the
    /// forces'; not the watchdog's where only the inputs came late, or where the gate would
    /// have let an attach below the margin go on).
    gated: bool,
}

/// Finger `id`'s joint targets in command `c`, if it has the finger.
fn joints_of(c: &HandCommand, id: u32) -> Option<[f64; MAX_JOINTS]> {
    let m = (c.finger_count as usize).min(MAX_FINGERS);
    (0..m)
        .find(|&s| c.finger_ids[s] == id)
        .map(|s| c.joint_targets[s])
}

/// Joint targets toward `goal` (its first `joints`) along a straight line in joint space,
/// from `from` (none: the goal itself), the largest joint motion at most `max_step`: every
/// joint of the finger scaled alike, so the fingertip follows the planned rolling between the
/// planner's closely spaced targets (clamping each joint on its own would bend the path off
/// the object's surface).
fn step_toward(
    from: Option<[f64; MAX_JOINTS]>,
    goal: &[f64; MAX_JOINTS],
    joints: usize,
    max_step: f64,
    out: &mut [f64; MAX_JOINTS],
) {
    let scale = from.map_or(1.0, |from| {
        let largest = (0..joints).fold(0.0_f64, |m, j| m.max((goal[j] - from[j]).abs()));
        if largest > max_step {
            max_step / largest
        } else {
            1.0
        }
    });
    for j in 0..joints {
        out[j] = match from {
            Some(from) => from[j] + scale * (goal[j] - from[j]),
            None => goal[j],
        };
    }
}

/// Why a plan step was not tracked: no forces balance its contacts (an outcome: the
/// commander holds), or the force problem could not be posed.
#[derive(Debug, thiserror::Error)]
enum Untracked {
    /// No balancing forces exist.
    #[error("{0}")]
    Infeasible(Balance<()>),
    /// Bad input to the force solve.
    #[error(transparent)]
    Input(#[from] ForceError),
}

impl Tracker<'_> {
    /// The command that follows `plan` in the grasp the gate accepted, with `header`, at time
    /// `t`; or why there is none. With `attaching` (below the margin: the gate's
    /// `attach_below_margin`), only that finger moves toward the plan step; every other
    /// finger keeps the joint targets of the last command that moved the hand before the
    /// attach (those in contact moved together by the centring since), its forces those of the
    /// grasp without the attaching finger until it touches, as in any attach.
    fn track(
        &mut self,
        plan: &PlanStepHeader,
        gate: &Gate,
        header: Header,
        t: u64,
        attaching: Option<u32>,
    ) -> Result<HandCommand, Untracked> {
        let (config, setup) = (self.config, self.setup);
        let p = &config.pipeline;
        let theta = gate.grasp().map_or(0.0, |g| g.rotation);
        let axis = nalgebra::Unit::new_normalize(config.turn.axis);
        let rot = nalgebra::Rotation3::from_axis_angle(&axis, theta);
        let n = (plan.finger_count as usize).min(MAX_FINGERS);
        let (slots, set, count) = self.pressing_contacts(plan, gate, n);
        self.balance(&set, count, theta, &axis, &rot)?;
        let mut c = HandCommand {
            header,
            mode: CommandMode::Track as u32,
            finger_count: plan.finger_count,
            quality: gate.quality(),
            ..Default::default()
        };
        let (elapsed, resumed) = self.elapsed(t, 1.0 / p.rate_hz);
        let max_step = p.joint_speed * elapsed;
        let moved = gate.grasp().map_or([0.0; 3], |g| g.position);
        // The object held where the plan has it: the fingers in contact move together against
        // the estimated drift of its centre, by an integral of it (a slow loop: it corrects
        // the offsets of the hand's squeeze and the contacts' give, not the rolling).
        for (c, m) in self.centring.iter_mut().zip(moved) {
            *c = (*c - CENTRING_RATE * elapsed * m).clamp(-CENTRING_LIMIT, CENTRING_LIMIT);
        }
        // Below the margin, the grasp is held from the first attach command on where the last
        // command that moved the hand put it (the gate allows one only after a tracking
        // command); taken again for another attach (another plan step or finger).
        match attaching {
            Some(a) if self.held.is_none_or(|(_, _, at)| at != (plan.step, a)) => {
                self.held = self
                    .last
                    .map(|(prev, _)| (prev, self.centring, (plan.step, a)));
            }
            Some(_) => {}
            None => self.held = None,
        }
        let held = self.held.map(|(prev, at, _)| (prev, at));
        for (k, target) in plan.targets.iter().enumerate().take(n) {
            c.finger_ids[k] = target.finger;
            let Some(f) = setup.hand.finger(target.finger) else {
                continue;
            };
            let joints = (target.joint_count as usize).min(MAX_JOINTS).min(f.dof());
            let touches = gate.touching(target.finger);
            let shift = if touches { self.centring } else { moved };
            // A held finger keeps its joints then, moved only by the centring since (the
            // grasp carried as a whole, so that the object's centre comes back to where the
            // plan has it and the attaching finger, aimed where the estimate has the object,
            // meets its way points).
            let kept = attaching
                .filter(|&a| a != target.finger)
                .and(held)
                .and_then(|(prev, at)| {
                    let mut kept = *target;
                    kept.joints = joints_of(&prev, target.finger)?;
                    let since = if touches {
                        [0, 1, 2].map(|i| self.centring[i] - at[i])
                    } else {
                        [0.0; 3]
                    };
                    Some(self.goal(f, &kept, joints, touches, since, &rot))
                });
            let goal = match kept {
                Some(q) => q,
                None => self.goal(f, target, joints, touches, shift, &rot),
            };
            // From the last tracking command; when resumed, from the joints the grasp state
            // was estimated from: where the hand stopped, which may be short of the last
            // command. A held finger from its last command, however long the hand held (the
            // holds commanded it there; set off from where it stands, a finger pressing on
            // the object would let go of what it presses); so too a finger that presses after
            // a gap in which nothing refused to track, only the inputs came late (when every
            // command more than three periods late resumed, under a loop stalled a few
            // milliseconds at a time, the pressing fingers, set off from where they stood,
            // short of their commands by the contact's give, let the object drift off until
            // the grasp was lost). After a hold the gate or the forces decided, from where it
            // stands (tried: from its last command then, the Allegro's ellipsoid at
            // plan.alpha 0.12 spun out in lockstep where it had reached the goal).
            let presses = self.pressing.contains(&target.finger) && !self.gated;
            let stands = || {
                gate.grasp().and_then(|g| {
                    let n = (g.finger_count as usize).min(MAX_FINGERS);
                    (0..n)
                        .find(|&s| g.fingers[s].finger == target.finger)
                        .map(|s| g.joints[s])
                })
            };
            let from = match self.last {
                Some((prev, _)) if kept.is_some() => joints_of(&prev, target.finger),
                Some((prev, _)) if presses => joints_of(&prev, target.finger).or_else(stands),
                Some((prev, _)) if !resumed => Some(prev.joint_targets[k]),
                _ => stands(),
            };
            step_toward(from, &goal, joints, max_step, &mut c.joint_targets[k]);
        }
        for (slot, f) in slots.iter().zip(&self.forces) {
            let f = rot * f;
            c.forces[*slot] = [f.x, f.y, f.z];
        }
        self.last = Some((c, t));
        self.gated = false;
        Ok(c)
    }

    /// The contacts that carry forces: those of the plan step (its first `n` targets) that
    /// the estimate has made: their slots in the plan step, their candidates (padded with
    /// MAX) and how many. An attaching finger presses only once it touches: given its share
    /// while it still approaches, it would hit the object with it, and the others, their
    /// forces already those of the grasp with it, would let the object slip meanwhile. A
    /// finger that pressed in the last command goes on pressing while the plan has it in
    /// contact, whatever the estimate says meanwhile: a contact that flickers off in the
    /// estimate for a tick does not change the forces (nor solve them again).
    fn pressing_contacts(
        &mut self,
        plan: &PlanStepHeader,
        gate: &Gate,
        n: usize,
    ) -> ([usize; MAX_FINGERS], [u32; MAX_FINGERS], usize) {
        let cands = self.setup.problem.candidates();
        let mut slots = [0usize; MAX_FINGERS];
        let mut set = [u32::MAX; MAX_FINGERS];
        let mut count = 0;
        let mut pressing = [u32::MAX; MAX_FINGERS];
        for (k, target) in plan.targets.iter().enumerate().take(n) {
            if target.in_contact == 1
                && (target.candidate as usize) < cands.points.len()
                && (self.pressing.contains(&target.finger) || gate.touching(target.finger))
            {
                slots[count] = k;
                set[count] = target.candidate;
                pressing[count] = target.finger;
                count += 1;
            }
        }
        self.pressing = pressing;
        (slots, set, count)
    }

    /// The forces of the contact set (its first `count` candidates) in the object's frame,
    /// at the object's rotation `theta` about `axis` (`rot`), into `self.forces`; solved once
    /// per contact set: the load is the object's weight (`plant.gravity`), in the object's
    /// frame; turning about the hand's z axis (a planar hand's, or a spatial plan's vertical
    /// axis) leaves it unchanged, and the problem is invariant under that rotation (cones,
    /// equilibrium, and the least squared force alike), so the hand-frame forces are these
    /// rotated. About another axis, a weight turns in the object's frame as the object turns:
    /// solved again every RESOLVE_TURN of it. The cones are narrowed by
    /// `plant.friction_margin`.
    fn balance(
        &mut self,
        set: &[u32; MAX_FINGERS],
        count: usize,
        theta: f64,
        axis: &nalgebra::Unit<Vec3>,
        rot: &nalgebra::Rotation3<f64>,
    ) -> Result<(), Untracked> {
        let (config, setup) = (self.config, self.setup);
        let cands = setup.problem.candidates();
        let weight = Vec3::from(config.plant.weight(setup.object.volume));
        let turns_load = weight != Vec3::zeros() && axis.cross(&Vec3::z()).norm() > 1e-9;
        let current = self.solved_for.is_some_and(|(s, at)| {
            s == *set && (!turns_load || (at - theta).abs() <= RESOLVE_TURN)
        });
        if current {
            return Ok(());
        }
        self.solved_for = None;
        self.contacts.clear();
        for &c in set.iter().take(count) {
            self.contacts.push(ForceContact {
                point: cands.points[c as usize] - setup.object.centre_of_mass,
                normal: cands.normals[c as usize],
            });
        }
        let load = Load {
            force: rot.inverse() * weight,
            ..Load::none()
        };
        let found = self.solver.solve(
            &self.contacts,
            &load,
            config.grasp.model.mu() * (1.0 - config.plant.friction_margin),
            config.pipeline.min_normal_force,
            &mut self.forces,
        )?;
        if let Balance::Infeasible { .. } = found {
            return Err(Untracked::Infeasible(found));
        }
        self.solved_for = Some((*set, theta));
        Ok(())
    }

    /// The time this command's motion covers (s) and whether tracking resumes. The motion is
    /// that of the time since the last tracking command (a late input, as from a loop stalled
    /// by other work while the watchdog held, moves the command on as far as the hand would
    /// have gone meanwhile). Resumed, after no tracking command for more than [`LATE_PERIODS`]
    /// periods (a restart, a long stall), or for more than [`WATCHDOG_PERIODS`] with a hold the
    /// gate or the forces decided since: the
    /// hand goes one period's (`dt`) motion on, and does not jump to where the plan has gone
    /// meanwhile; a free finger sets off from where it stands, a finger pressing on the object
    /// from its last command unless a hold refused to track meanwhile ([`Tracker::track`]).
    /// (Resumed after three periods, as before 2026-12-06, a stalled loop went one period per
    /// command: the ellipsoid under gravity, turned a third as fast, crept out of the hand.)
    fn elapsed(&self, t: u64, dt: f64) -> (f64, bool) {
        let since = self
            .last
            .map(|(_, when)| t.saturating_sub(when) as f64 * 1e-9);
        let resumed = since
            .is_none_or(|s| s > LATE_PERIODS * dt || (self.gated && s > WATCHDOG_PERIODS * dt));
        let elapsed = match since {
            Some(s) if !resumed => s.max(dt),
            _ => dt,
        };
        (elapsed, resumed)
    }

    /// Finger `f`'s goal for `target` (its first `joints` joints), shifted by `shift` and
    /// within its limits. The plan is about the object's starting centre. A finger that does
    /// not touch the object (free, or on its way to attach) aims where the estimate has the
    /// object moved, so that it meets the surface where it is; the fingers in contact are
    /// moved together by the centring (following the object with them would push it on for
    /// ever): the caller's `shift`. A planar finger's fingertip is moved with its cap axis kept
    /// (`Finger::shift_planar`); a spatial finger's material point at its contact (touching:
    /// so that it carries the object rather than rolls on it) or its fingertip centre
    /// (`Finger::shift_point`), where it moves without its joints swinging.
    fn goal(
        &self,
        f: &icrflow_plan::hand::Finger,
        target: &icrflow_interfaces::FingerTarget,
        joints: usize,
        touches: bool,
        shift: [f64; 3],
        rot: &nalgebra::Rotation3<f64>,
    ) -> [f64; MAX_JOINTS] {
        let cands = self.setup.problem.candidates();
        let mut goal = [0.0; MAX_JOINTS];
        goal[..joints].copy_from_slice(&target.joints[..joints]);
        if shift != [0.0; 3] {
            let plan = goal;
            if f.planar.is_some() {
                f.shift_planar(&plan[..joints], [shift[0], shift[1]], &mut goal[..joints]);
            } else {
                let centre = f.tip_centre(&plan[..joints]);
                let point = match cands.normals.get(target.candidate as usize) {
                    Some(n) if touches && target.in_contact == 1 => centre - rot * n * f.tip_radius,
                    _ => centre,
                };
                if !f.shift_point(
                    &plan[..joints],
                    &point,
                    &Vec3::from(shift),
                    &mut goal[..joints],
                ) {
                    goal = plan;
                }
            }
        }
        for (j, g) in goal.iter_mut().enumerate().take(joints) {
            *g = g.clamp(f.joints[j].lower, f.joints[j].upper);
        }
        goal
    }

    /// Whether finger `attaching` can attach to plan step `plan` below the margin with every
    /// other finger of the step held: each is in the command it would be held at (the one
    /// already held for this attach, else the last that moved the hand). Otherwise the hand
    /// holds: a finger without a command to keep would move.
    fn can_hold(&self, plan: &PlanStepHeader, attaching: u32) -> bool {
        let at = (plan.step, attaching);
        let from = match self.held {
            Some((prev, _, held)) if held == at => Some(prev),
            _ => self.last.map(|(prev, _)| prev),
        };
        let n = (plan.finger_count as usize).min(MAX_FINGERS);
        from.is_some_and(|prev| {
            plan.targets[..n]
                .iter()
                .filter(|t| t.finger != attaching)
                .all(|t| joints_of(&prev, t.finger).is_some())
        })
    }

    /// A hold of the last command that moved the hand (before any, no motion at all), saying
    /// `why`.
    fn hold(&mut self, why: &str, gated: bool) -> HandCommand {
        self.gated |= gated;
        let mut c = self.last.map_or_else(HandCommand::default, |(c, _)| c);
        c.header = Header::new(Kind::HandCommand, 0, 0, 0);
        c.mode = CommandMode::Hold as u32;
        c.quality = 0.0;
        write_text(&mut c.reason, why);
        c
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::paper;
    use icrflow_interfaces::{FingerContact, FingerTarget, PlanPhase, read_text};

    /// A start time (ns).
    const T0: u64 = 1_000_000_000_000;

    fn header(kind: Kind, sequence: u64, input: u64, at: u64) -> Header {
        let mut h = Header::new(kind, sequence, input, at);
        h.source_time_ns = at;
        h
    }

    /// The inputs of the paper's initial grasp at time `at`: the plan step (its targets the
    /// grasp's joints, plus `ahead` rad on every joint), grasp state `seq` and its wrench space
    /// (force closure, quality twice the margin).
    struct Inputs {
        plan: PlanStepHeader,
        grasp: GraspState,
        wrench: WrenchSpaceHeader,
    }

    fn inputs(config: &Config, setup: &Setup, seq: u64, at: u64, ahead: f64) -> Inputs {
        let (start, _) = setup.scenario(config).start().unwrap();
        let cands = setup.problem.candidates();
        let n = setup.hand.fingers.len();
        let mut plan = PlanStepHeader {
            header: header(Kind::PlanStep, seq, 0, at),
            phase: PlanPhase::Rolling as u32,
            finger_count: n as u32,
            ..Default::default()
        };
        let mut grasp = GraspState {
            header: header(Kind::GraspState, seq, seq, at),
            orientation: [1.0, 0.0, 0.0, 0.0],
            finger_count: n as u32,
            ..Default::default()
        };
        for (slot, f) in setup.hand.fingers.iter().enumerate() {
            let contact = start.iter().find(|c| c.finger == f.id);
            let q = contact.map_or(&f.home, |c| &c.q);
            let mut target = FingerTarget {
                finger: f.id,
                joint_count: f.dof() as u32,
                ..Default::default()
            };
            let mut finger = FingerContact {
                finger: f.id,
                ..Default::default()
            };
            if let Some(c) = contact {
                let p = cands.points[c.candidate];
                target.in_contact = 1;
                target.candidate = c.candidate as u32;
                target.point = [p.x, p.y, p.z];
                finger.in_contact = 1;
                finger.candidate = c.candidate as u32;
                finger.point = target.point;
            }
            for (j, a) in q.iter().enumerate() {
                target.joints[j] = a + ahead;
                grasp.joints[slot][j] = *a;
            }
            plan.targets[slot] = target;
            grasp.fingers[slot] = finger;
        }
        let wrench = WrenchSpaceHeader {
            header: header(Kind::WrenchSpace, seq, seq, at),
            force_closure: 1,
            dim: 3,
            quality: 2.0 * config.grasp.alpha,
            epsilon: 0.1,
            alpha: config.grasp.alpha,
        };
        Inputs {
            plan,
            grasp,
            wrench,
        }
    }

    /// `i`'s plan step made an attach step: the free finger attaches at the candidate opposite
    /// the first contact's. Its slot and candidate.
    fn attach_free_finger(setup: &Setup, i: &mut Inputs) -> (usize, u32) {
        let free = (0..setup.hand.fingers.len())
            .find(|&s| i.plan.targets[s].in_contact == 0)
            .unwrap();
        let cands = setup.problem.candidates();
        let n = cands.points.len() as u32;
        let at = (i.plan.targets[0].candidate + n / 2) % n;
        let p = cands.points[at as usize];
        i.plan.phase = PlanPhase::Attach as u32;
        i.plan.rendezvous_finger = i.plan.targets[free].finger;
        i.plan.targets[free].in_contact = 1;
        i.plan.targets[free].candidate = at;
        i.plan.targets[free].point = [p.x, p.y, p.z];
        (free, at)
    }

    /// Offers `i` (plan step, grasp state, wrench space) at `at`: the command.
    fn offer(c: &mut Commander<'_>, i: &Inputs, at: u64) -> (HandCommand, Option<String>) {
        c.on_plan(&i.plan, at).unwrap();
        c.on_grasp(&i.grasp);
        let out = c.on_wrench(&i.wrench, at);
        (out.command, out.hold.map(str::to_string))
    }

    /// A command that comes late, nothing having refused to track meanwhile (a loop stalled by
    /// other work: the watchdog's holds only), moves every finger on from its last command by
    /// the motion of the time gone, up to [`LATE_PERIODS`]. After a longer gap the fingers
    /// pressing on the object set off from their last command, a free finger from where the
    /// grasp state has it, both one period's motion on; after a hold the gate decided, every
    /// finger from where it stands. The hand stands short of its last command (the contact's
    /// give): set off from there without cause, the pressing fingers let go of the object (a
    /// stalled loop lost the paper sphere's grasp so).
    #[test]
    fn after_a_gap_the_pressing_fingers_set_off_from_their_last_command() {
        let (config, setup) = paper();
        let mut c = Commander::new(&config, &setup, T0);
        let dt = (1e9 / config.pipeline.rate_hz) as u64;
        let step = config.pipeline.joint_speed / config.pipeline.rate_hz;
        let first = inputs(&config, &setup, 1, T0, 0.2);
        let stood = |slot: usize, j: usize| first.grasp.joints[slot][j];
        let (mut last, hold) = offer(&mut c, &first, T0);
        assert_eq!(hold, None);
        let mut at = T0;
        // Late by 5 periods, and by more than LATE_PERIODS (the watchdog holding meanwhile).
        for (seq, gap) in [(2, 5), (3, LATE_PERIODS as u64 + 5)] {
            let mut t = at;
            while t + 4 * dt < at + gap * dt {
                t += 4 * dt;
                let held = c.on_tick(t).unwrap();
                assert!(held.hold.is_some_and(|h| h.contains("no wrench space")));
            }
            at += gap * dt;
            let (now, hold) = offer(&mut c, &inputs(&config, &setup, seq, at, 0.2), at);
            assert_eq!(hold, None);
            let late = gap as f64 <= LATE_PERIODS;
            let mut free = 0;
            for (slot, f) in setup.hand.fingers.iter().enumerate() {
                let presses = first.plan.targets[slot].in_contact == 1;
                free += usize::from(!presses);
                for j in 0..f.dof() {
                    let want = match (late, presses) {
                        (true, _) => last.joint_targets[slot][j] + gap as f64 * step,
                        (false, true) => last.joint_targets[slot][j] + step,
                        (false, false) => stood(slot, j) + step,
                    };
                    let got = now.joint_targets[slot][j];
                    assert!((got - want).abs() < 1e-12, "gap {gap}, finger {}", f.id);
                }
            }
            assert!(free > 0, "the paper's start has a free finger");
            last = now;
        }
        // After a hold the gate decided (the grasp below the margin): a command within
        // WATCHDOG_PERIODS of the last tracking one is late as ever (every finger from its last
        // command, by the time gone); more than that, and every finger sets off from where it
        // stands, as after a restart: the gate refused the grasp it pressed.
        let mut seq = 4;
        for gap in [2, WATCHDOG_PERIODS as u64 + 2] {
            let held_at = at + dt;
            let mut below = inputs(&config, &setup, seq, held_at, 0.2);
            below.wrench.quality = 0.5 * config.grasp.alpha;
            let (_, hold) = offer(&mut c, &below, held_at);
            assert!(hold.is_some_and(|h| h.contains("below the margin")));
            at += gap * dt;
            let (now, hold) = offer(&mut c, &inputs(&config, &setup, seq + 1, at, 0.2), at);
            assert_eq!(hold, None);
            let late = gap as f64 <= WATCHDOG_PERIODS;
            for (slot, f) in setup.hand.fingers.iter().enumerate() {
                for j in 0..f.dof() {
                    let want = if late {
                        last.joint_targets[slot][j] + gap as f64 * step
                    } else {
                        stood(slot, j) + step
                    };
                    let got = now.joint_targets[slot][j];
                    assert!((got - want).abs() < 1e-12, "gap {gap} after a gated hold");
                }
            }
            last = now;
            seq += 2;
        }
    }

    /// A finger the plan step has attach presses only once the estimate has it touching:
    /// while it approaches it gets no force and the others keep the forces of the grasp
    /// without it; once it touches, all four press, balanced, and go on pressing when the
    /// estimate loses the contact for a tick.
    #[test]
    fn an_attaching_finger_presses_only_once_it_touches() {
        let (config, setup) = paper();
        let mut c = Commander::new(&config, &setup, T0);
        let mut i = inputs(&config, &setup, 1, T0, 0.0);
        let (before, hold) = offer(&mut c, &i, T0);
        assert_eq!(hold, None);
        let (free, at) = attach_free_finger(&setup, &mut i);
        let dt = (1e9 / config.pipeline.rate_hz) as u64;
        let step = |c: &mut Commander<'_>, i: &mut Inputs, seq: u64| {
            let t = T0 + seq * dt;
            i.plan.header = header(Kind::PlanStep, seq, 0, t);
            i.grasp.header = header(Kind::GraspState, seq, seq, t);
            i.wrench.header = header(Kind::WrenchSpace, seq, seq, t);
            offer(c, i, t)
        };
        let (approaching, hold) = step(&mut c, &mut i, 2);
        assert_eq!(hold, None);
        assert_eq!(approaching.forces[free], [0.0; 3]);
        assert_eq!(approaching.forces, before.forces);
        // It touches.
        i.grasp.fingers[free].in_contact = 1;
        i.grasp.fingers[free].candidate = at;
        let (touching, hold) = step(&mut c, &mut i, 3);
        assert_eq!(hold, None);
        let mut net = Vec3::zeros();
        for slot in 0..setup.hand.fingers.len() {
            let v = Vec3::from(touching.forces[slot]);
            assert!(v.norm() > 0.0, "slot {slot}");
            net += v;
        }
        assert!(net.norm() < 1e-5, "net force {net}");
        // The estimate loses it for a tick: it goes on pressing as the plan has it.
        i.grasp.fingers[free].in_contact = 0;
        let (flicker, hold) = step(&mut c, &mut i, 4);
        assert_eq!(hold, None);
        assert_eq!(flicker.forces, touching.forces);
    }

    /// Below the margin the gate holds, except for the one command that cannot lower the
    /// margin: an attach step adding its finger to exactly the grasp the estimate has; then
    /// only that finger moves (the others keep the last tracking command's targets and
    /// forces), and the command says so. Any other attach below the margin holds: the
    /// attaching finger already touching, a planned contact lost, no force closure, no
    /// tracking command before.
    #[test]
    fn below_the_margin_only_an_attach_to_the_grasp_held_moves_and_only_its_finger() {
        let (config, setup) = paper();
        let alpha = config.grasp.alpha;
        let dt = (1e9 / config.pipeline.rate_hz) as u64;
        let max_step = config.pipeline.joint_speed / config.pipeline.rate_hz;
        // The attach step: the free finger attaches opposite the first contact, every joint
        // target 20 periods' motion ahead of the hand.
        let attach = |seq: u64| {
            let mut i = inputs(&config, &setup, seq, T0 + (seq + 10) * dt, 20.0 * max_step);
            // The hand stands short of where it was commanded (pressing on the object).
            for q in i.grasp.joints.iter_mut() {
                for a in q.iter_mut() {
                    *a -= 5.0 * max_step;
                }
            }
            let (free, _) = attach_free_finger(&setup, &mut i);
            i.wrench.quality = 0.6 * alpha;
            (i, free)
        };
        // No tracking command yet: held.
        let mut c = Commander::new(&config, &setup, T0);
        let (i, _) = attach(1);
        let (_, hold) = offer(&mut c, &i, T0 + 11 * dt);
        assert!(hold.unwrap().contains("below the margin"));
        // After one: the attach goes on.
        let mut c = Commander::new(&config, &setup, T0);
        let (tracked, hold) = offer(&mut c, &inputs(&config, &setup, 1, T0, 0.0), T0);
        assert_eq!(hold, None);
        // A while after it (the hand held below the margin meanwhile: the tracking resumes
        // from where the hand stands, but the held fingers do not set off from there).
        let (i, free) = attach(2);
        let (cmd, hold) = offer(&mut c, &i, T0 + 12 * dt);
        assert_eq!(hold, None);
        assert_eq!(cmd.mode, CommandMode::Attach as u32);
        assert_eq!(cmd.quality, 0.6 * alpha);
        let f = setup.hand.fingers[free].id;
        assert!(
            read_text(&cmd.reason).starts_with(&format!(
                "finger {f} attaches, the others held: quality alpha* = {:.4} below the margin",
                0.6 * alpha
            )),
            "{}",
            read_text(&cmd.reason)
        );
        for slot in 0..setup.hand.fingers.len() {
            if slot == free {
                assert_ne!(cmd.joint_targets[slot], tracked.joint_targets[slot]);
                assert_eq!(cmd.forces[slot], [0.0; 3]);
            } else {
                assert_eq!(
                    cmd.joint_targets[slot], tracked.joint_targets[slot],
                    "{slot}"
                );
            }
        }
        assert_eq!(cmd.forces, tracked.forces);
        // A way point of its approach (the finger still free in the step) goes on alike.
        let (mut way, _) = attach(3);
        way.plan.targets[free].in_contact = 0;
        let (via, hold) = offer(&mut c, &way, T0 + 13 * dt);
        assert_eq!(hold, None);
        assert_eq!(via.mode, CommandMode::Attach as u32);
        for slot in (0..setup.hand.fingers.len()).filter(|&s| s != free) {
            assert_eq!(
                via.joint_targets[slot], tracked.joint_targets[slot],
                "{slot}"
            );
        }
        let cmd = via;
        // The same step held: the attaching finger touches (the attach is made: the grasp
        // with it is judged), a planned contact is lost, no force closure, or rolling.
        type Spoil = fn(&mut Inputs, usize);
        let cases: [(&str, Spoil); 4] = [
            ("below the margin", |i, free| {
                i.grasp.fingers[free].in_contact = 1;
                i.grasp.fingers[free].candidate = i.plan.targets[free].candidate;
            }),
            ("below the margin", |i, free| {
                let other = (free + 1) % i.plan.finger_count as usize;
                i.grasp.fingers[other].in_contact = 0;
            }),
            ("not force closure", |i, _| i.wrench.force_closure = 0),
            ("below the margin", |i, _| {
                i.plan.phase = PlanPhase::Rolling as u32;
            }),
        ];
        for (k, (reason, spoil)) in cases.into_iter().enumerate() {
            let seq = 4 + k as u64;
            let (mut i, free) = attach(seq);
            spoil(&mut i, free);
            let (held, hold) = offer(&mut c, &i, T0 + (seq + 10) * dt);
            let hold = hold.unwrap_or_else(|| panic!("case {k}: not held"));
            assert!(hold.contains(reason), "case {k}: {hold}");
            assert_eq!(held.mode, CommandMode::Hold as u32);
            // What a hold holds is the last command that moved the hand.
            assert_eq!(held.joint_targets, cmd.joint_targets, "case {k}");
        }
    }

    #[test]
    fn good_inputs_are_tracked_at_the_joint_speed_with_balancing_forces() {
        let (config, setup) = paper();
        let p = &config.pipeline;
        let dt_ns = (1e9 / p.rate_hz) as u64;
        let max_step = p.joint_speed / p.rate_hz;
        let mut c = Commander::new(&config, &setup, T0);
        // The plan 20 steps ahead of the hand on every joint.
        let ahead = 20.0 * max_step;
        let first = inputs(&config, &setup, 1, T0, ahead);
        let (cmd, hold) = offer(&mut c, &first, T0);
        assert_eq!(hold, None);
        assert_eq!(cmd.mode, CommandMode::Track as u32);
        assert_eq!(cmd.quality, first.wrench.quality);
        assert_eq!(cmd.header.input_sequence, first.wrench.header.sequence);
        assert_eq!(read_text(&cmd.reason), "");
        let mut force = Vec3::zeros();
        let mut pressing = 0;
        for (slot, f) in setup.hand.fingers.iter().enumerate() {
            assert_eq!(cmd.finger_ids[slot], f.id);
            let target = &first.plan.targets[slot];
            // One period's motion from where the hand is, every joint alike (none at a limit
            // in the initial grasp).
            for j in 0..f.dof() {
                let moved = cmd.joint_targets[slot][j] - first.grasp.joints[slot][j];
                let goal = target.joints[j].clamp(f.joints[j].lower, f.joints[j].upper);
                if goal == target.joints[j] {
                    assert!((moved - max_step).abs() < 1e-12, "finger {}: {moved}", f.id);
                }
            }
            let [x, y, z] = cmd.forces[slot];
            let v = Vec3::new(x, y, z);
            if target.in_contact == 1 {
                assert!(v.norm() >= p.min_normal_force * (1.0 - 1e-6), "{v}");
                pressing += 1;
            } else {
                assert_eq!(v.norm(), 0.0);
            }
            force += v;
        }
        assert_eq!(pressing, 3);
        assert!(
            force.norm() < 1e-5 * p.min_normal_force,
            "net force {force}"
        );
        // The next period: one more step, from the last command.
        let at = T0 + dt_ns;
        let next = inputs(&config, &setup, 2, at, ahead);
        let (again, hold) = offer(&mut c, &next, at);
        assert_eq!(hold, None);
        let mut largest = 0.0_f64;
        for (slot, f) in setup.hand.fingers.iter().enumerate() {
            for j in 0..f.dof() {
                let moved = again.joint_targets[slot][j] - cmd.joint_targets[slot][j];
                assert!(moved >= 0.0 && moved <= max_step + 1e-12, "{moved}");
                largest = largest.max(moved);
            }
        }
        assert!((largest - max_step).abs() < 1e-12, "{largest}");
        // The watchdog is quiet while commands come.
        assert!(c.on_tick(at + dt_ns).is_none());
    }

    #[test]
    fn every_bad_input_holds_with_its_reason_and_good_ones_track_again() {
        let (config, setup) = paper();
        let p = &config.pipeline;
        let max_age = (p.max_input_age * 1e9) as u64;
        let dt_ns = (1e9 / p.rate_hz) as u64;
        // No plan step: held, with nothing to hold but stillness.
        let mut c = Commander::new(&config, &setup, T0);
        let i = inputs(&config, &setup, 1, T0, 0.0);
        c.on_grasp(&i.grasp);
        let out = c.on_wrench(&i.wrench, T0);
        assert_eq!(out.hold, Some("no plan step yet"));
        assert_eq!(out.command.mode, CommandMode::Hold as u32);
        assert_eq!(read_text(&out.command.reason), "no plan step yet");
        assert_eq!(out.command.joint_targets, [[0.0; MAX_JOINTS]; MAX_FINGERS]);
        // Then tracking; each bad input after it holds the last tracking command.
        let (tracked, hold) = offer(&mut c, &inputs(&config, &setup, 2, T0, 0.0), T0);
        assert_eq!(hold, None);
        type Spoil = fn(&mut Inputs, &Config, u64);
        let cases: [(&str, Spoil); 9] = [
            ("was not received", |i, _, _| {
                i.wrench.header.input_sequence += 100
            }),
            ("wrench space: stale", |i, config, at| {
                i.wrench.header.source_time_ns =
                    at - 2 * (config.pipeline.max_input_age * 1e9) as u64
            }),
            ("grasp state: stale", |i, config, at| {
                i.grasp.header.source_time_ns =
                    at - 2 * (config.pipeline.max_input_age * 1e9) as u64
            }),
            (
                "joint measurement behind the grasp state is stale",
                |i, config, at| {
                    i.grasp.header.origin_time_ns =
                        at - 2 * (config.pipeline.max_input_age * 1e9) as u64
                },
            ),
            ("the estimate is off: pose innovation", |i, config, _| {
                i.grasp.pose_innovation = 2.0 * config.pipeline.max_pose_innovation
            }),
            ("the estimate is off: contact residual", |i, config, _| {
                i.grasp.residual = 2.0 * config.pipeline.max_contact_residual
            }),
            ("below the margin", |i, config, _| {
                i.wrench.quality = 0.5 * config.grasp.alpha
            }),
            ("not force closure", |i, _, _| i.wrench.force_closure = 0),
            (
                "grasp state: invalid object pose (not finite)",
                |i, _, _| i.grasp.rotation = f64::NAN,
            ),
        ];
        let mut seq = 3;
        let mut at = T0;
        for (reason, spoil) in cases {
            at += dt_ns;
            let mut bad = inputs(&config, &setup, seq, at, 0.0);
            spoil(&mut bad, &config, at);
            let (held, hold) = offer(&mut c, &bad, at);
            let hold = hold.unwrap_or_else(|| panic!("{reason}: tracked"));
            assert!(hold.contains(reason), "{reason}: {hold}");
            assert_eq!(read_text(&held.reason), hold);
            assert_eq!(held.mode, CommandMode::Hold as u32, "{reason}");
            assert_eq!(held.joint_targets, tracked.joint_targets, "{reason}");
            assert_eq!(held.forces, tracked.forces, "{reason}");
            assert_eq!(held.quality, 0.0);
            // Good inputs after it are tracked again.
            at += dt_ns;
            let good = inputs(&config, &setup, seq + 1, at, 0.0);
            let (_, hold) = offer(&mut c, &good, at);
            assert_eq!(hold, None, "after {reason}");
            seq += 2;
        }
        // A plan step refused (not finite) is said, and the last good one is still followed.
        let mut nan = inputs(&config, &setup, seq, at, 0.0);
        nan.plan.rotation = f64::NAN;
        assert!(matches!(
            c.on_plan(&nan.plan, at),
            Err(Hold::Invalid { .. })
        ));
        c.on_grasp(&nan.grasp);
        assert_eq!(c.on_wrench(&nan.wrench, at).hold, None);
        // No wrench space for longer than the watchdog's periods: held on the timer, and the
        // plan step gone stale says so.
        let quiet = at + (WATCHDOG_PERIODS as u64 + 1) * dt_ns;
        let out = c.on_tick(quiet).unwrap();
        assert!(
            out.hold.unwrap().starts_with("no wrench space for"),
            "{:?}",
            out.hold
        );
        assert!(
            c.on_tick(quiet + dt_ns).is_none(),
            "a hold a period, not more"
        );
        let late = c.on_tick(at + 2 * max_age).unwrap();
        assert!(
            late.hold.unwrap().starts_with("plan step is stale"),
            "{:?}",
            late.hold
        );
    }
}
