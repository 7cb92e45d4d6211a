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
use icrflow_plan::planner::Phase;
use icrflow_scenario::{Config, PlantKind, Setup};

use crate::command::Commander;
use crate::estimator::Estimator;
use crate::physical::Physical;
use crate::planner::{CLEARANCE, REPUBLISH, estimate, message};
use crate::wrench::WrenchSpace;

pub mod truth;

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
    /// Commands that attached a finger below the margin, the others held
    /// (`CommandMode::Attach`).
    pub attaches_below_margin: u64,
    /// Plans made again from the estimate.
    pub replans: u32,
    /// The reason of the last hold, if the run ended holding.
    pub holding: Option<String>,
    /// What the planner said of each re-plan (as the planner node logs it), with the
    /// simulated time.
    pub replanned: Vec<(f64, String)>,
}

/// A loop stalled now and then, as on a machine busy with other work: for the first `length`
/// ticks of every `period`, the joint states do not reach the estimator (those of the stalled
/// ticks are lost; the first one after is taken), so no grasp state, wrench space or follower
/// step comes of them and the command node has nothing to answer: its own timer holds the hand
/// after [`crate::command::WATCHDOG_PERIODS`] periods, as it does on the bus. The plant goes on
/// in time under the last command; what is not stalled: the object-pose measurements (taken by
/// the estimator when due), the planner's republishing of its step on its timer, and the
/// command node's timer.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Stall {
    /// Ticks stalled at the start of every period (0: never).
    pub length: u64,
    /// The period (ticks).
    pub period: u64,
}

impl Stall {
    /// Never stalled.
    pub const NONE: Stall = Stall {
        length: 0,
        period: 1,
    };

    /// `length_ms` stalled of every `period_ms` at `rate_hz` ticks a second (whole ticks; an
    /// error for a period under a tick or a stall longer than its period).
    pub fn of_ms(length_ms: f64, period_ms: f64, rate_hz: f64) -> Result<Stall> {
        let ticks = |ms: f64| (ms * 1e-3 * rate_hz).round();
        let (length, period) = (ticks(length_ms), ticks(period_ms));
        anyhow::ensure!(
            length_ms >= 0.0 && period >= 1.0 && length < period,
            "a stall of {length_ms} ms every {period_ms} ms: expected at least 0 ms, less than \
             its period, and a period of at least one tick ({} ms)",
            1e3 / rate_hz
        );
        Ok(Stall {
            length: length as u64,
            period: period as u64,
        })
    }

    /// Whether tick `k` (from 0) is stalled.
    pub fn covers(&self, k: u64) -> bool {
        k % self.period.max(1) < self.length
    }
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
    run_stalled(
        config,
        setup,
        seconds,
        settle,
        replan_s,
        Stall::NONE,
        observe,
    )
}

/// [`run`] with the loop upstream of the command node stalled as `stall` says.
pub fn run_stalled(
    config: &Config,
    setup: &Setup,
    seconds: f64,
    settle: f64,
    replan_s: f64,
    stall: Stall,
    observe: &mut dyn FnMut(&Tick<'_>),
) -> Result<Ended> {
    anyhow::ensure!(
        config.plant.kind == PlantKind::Mujoco,
        "a lockstep run needs plant.kind = \"mujoco\""
    );
    // Any start time: the steps only compare times.
    let t0: u64 = 1_000_000_000_000;
    let dt = (1e9 / config.pipeline.rate_hz).round() as u64;
    let mut lp = Loop::new(config, setup, t0, replan_s)?;
    let end = t0 + (seconds * 1e9) as u64;
    let mut t = t0;
    let mut k = 0;
    while t < end {
        t += dt;
        let (out, joints) = lp.measure(t);
        let grasp = if stall.covers(k) {
            None
        } else {
            lp.estimate(&joints, t)
        };
        k += 1;
        lp.follow(grasp.as_ref(), t);
        let made = lp.command(grasp.as_ref(), t);
        observe(&Tick {
            time: (t - t0) as f64 * 1e-9,
            plant: &lp.plant,
            plan: lp.plan.as_ref(),
            grasp: grasp.as_ref(),
            command: made.as_ref().map(|(c, why)| (c, why.as_deref())),
            truth: out.truth.as_ref(),
        });
        // Done at the goal: after `settle`. Done short of it (a leg of a plan made again, or a
        // plan that stopped short): the follower plans on once the object has stood still
        // for REPLAN_NS (and planned), else it is over.
        let wait = if lp.follower.ends_at_goal() {
            (settle * 1e9) as u64
        } else {
            (settle * 1e9) as u64 + 2 * icrflow_plan::follow::REPLAN_NS + lp.replan_ns
        };
        if lp.done_at.is_some_and(|d| t >= d + wait) {
            break;
        }
    }
    Ok(Ended {
        done: lp.done_at.is_some(),
        time: (t - t0) as f64 * 1e-9,
        estimated: lp.estimator.rotation(),
        rotation: lp.plant.rotation(),
        holds: lp.holds,
        attaches_below_margin: lp.attaches_below_margin,
        replans: lp.follower.replans(),
        holding: lp.holding,
        replanned: lp.replanned,
    })
}

/// The sequence numbers of each topic's messages.
#[derive(Default)]
struct Sequences {
    joint: u64,
    grasp: u64,
    wrench: u64,
    plan: u64,
    command: u64,
}

/// The loop's steps and what they carry from one tick to the next.
struct Loop<'s> {
    setup: &'s Setup,
    t0: u64,
    republish: u64,
    replan_ns: u64,
    plant: Physical<'s>,
    estimator: Estimator<'s>,
    wrench: WrenchSpace<'s>,
    follower: Follower<'s>,
    commander: Commander<'s>,
    seq: Sequences,
    /// The object's first measured position (the estimator takes the position moved since).
    first_position: Option<[f64; 3]>,
    e: Estimate,
    /// The last command (the plant follows it at the next tick).
    command: Option<HandCommand>,
    /// The newest plan step published.
    plan: Option<PlanStepHeader>,
    last_grasp: Option<Header>,
    next_republish: u64,
    done_at: Option<u64>,
    holds: u64,
    attaches_below_margin: u64,
    holding: Option<String>,
    replanned: Vec<(f64, String)>,
    /// While the planner plans again (until then), it follows and publishes nothing.
    busy_until: Option<u64>,
}

impl<'s> Loop<'s> {
    fn new(config: &'s Config, setup: &'s Setup, t0: u64, replan_s: f64) -> Result<Self> {
        let (joints, _) = setup.initial_grip(config)?;
        Ok(Self {
            setup,
            t0,
            republish: (REPUBLISH * 1e9).round() as u64,
            replan_ns: (replan_s.max(0.0) * 1e9) as u64,
            plant: Physical::new(config, setup, &joints, t0)?,
            estimator: Estimator::new(&setup.hand, setup.roller(config)?, &setup.problem, 0.0),
            wrench: WrenchSpace::new(&setup.problem, config.grasp.alpha, crate::wrench::at(setup)),
            follower: Follower::new_with(
                setup.planning(config)?,
                CLEARANCE,
                Tolerances::new(config.pipeline.joint_noise),
                &mut |_| {},
                &mut |_| {},
            )
            .context("planning")?,
            commander: Commander::new(config, setup, t0),
            seq: Sequences::default(),
            first_position: None,
            e: Estimate::default(),
            command: None,
            plan: None,
            last_grasp: None,
            next_republish: t0,
            done_at: None,
            holds: 0,
            attaches_below_margin: 0,
            holding: None,
            replanned: Vec::new(),
            busy_until: None,
        })
    }

    /// The plant advances under the last command and measures: the joint state, stamped; a
    /// pose when one is due goes to the estimator.
    fn measure(&mut self, t: u64) -> (crate::plant::Output, JointState) {
        let out = self.plant.tick(t, self.command.as_ref());
        self.seq.joint += 1;
        let mut joints: JointState = out.joints;
        joints.header = stamped(Header::new(Kind::JointState, self.seq.joint, 0, 0), t);
        if let Some(pose) = &out.pose {
            let start = *self.first_position.get_or_insert(pose.position);
            let moved = [0, 1, 2].map(|k| pose.position[k] - start[k]);
            let _ = self
                .estimator
                .on_pose(
                    self.estimator.rotation_of(pose.orientation),
                    pose.captured_time_ns,
                )
                .and_then(|_| self.estimator.on_position(moved));
        }
        (out, joints)
    }

    /// The estimator's grasp state of the joint state.
    fn estimate(&mut self, joints: &JointState, t: u64) -> Option<GraspState> {
        self.seq.grasp += 1;
        let header = stamped(
            Header::after(Kind::GraspState, self.seq.grasp, &joints.header, t),
            t,
        );
        self.estimator.on_joints(joints, header).ok()
    }

    /// The plan step message of the follower's target `k`, answering `input`.
    fn message(&mut self, k: usize, input: Option<Header>, t: u64) -> PlanStepHeader {
        let targets = self.follower.targets();
        let at = k.min(targets.len() - 1);
        self.seq.plan += 1;
        let header = match input {
            Some(h) => Header::after(Kind::PlanStep, self.seq.plan, &h, t),
            None => Header::new(Kind::PlanStep, self.seq.plan, 0, 0),
        };
        message(
            &targets[at],
            k >= targets.len(),
            &Default::default(),
            stamped(header, t),
        )
    }

    /// The planner: the estimate followed, the current target republished on its timer; the
    /// last step published this tick goes to the command node.
    fn follow(&mut self, grasp: Option<&GraspState>, t: u64) {
        let mut published: Option<PlanStepHeader> = None;
        // The new plan's first target, published when the planning is over.
        let busy = self.busy_until.is_some_and(|b| t < b);
        if !busy && self.busy_until.take().is_some() {
            if let Some(k) = self.follower.current() {
                published = Some(self.message(k, self.last_grasp, t));
            }
            self.next_republish = t + self.republish;
        }
        if let Some(g) = grasp
            && g.rotation.is_finite()
            && !busy
        {
            self.last_grasp = Some(g.header);
            estimate(g, &self.setup.hand, &mut self.e);
            let followed = self.follower.on_estimate(&self.e, t, &mut || {});
            self.note_replan(followed.event.as_ref(), t);
            if self.busy_until.is_none() {
                for k in followed.commands() {
                    published = Some(self.message(k, self.last_grasp, t));
                }
            }
        }
        if t >= self.next_republish && self.busy_until.is_none() {
            self.next_republish = t + self.republish;
            if let Some(k) = self.follower.current() {
                published = Some(self.message(k, self.last_grasp, t));
            }
        }
        if let Some(m) = published {
            if m.phase == PlanPhase::Done as u32 {
                self.done_at.get_or_insert(t);
            } else {
                // A plan made on from the end of one short of the goal.
                self.done_at = None;
            }
            let _ = self.commander.on_plan(&m, t);
            self.plan = Some(m);
        }
    }

    /// A re-plan said as the planner node logs it; the planner is busy for `replan_s` after.
    fn note_replan(&mut self, event: Option<&Event>, t: u64) {
        let time = (t - self.t0) as f64 * 1e-9;
        match event {
            Some(Event::Replanned(r)) => {
                let mut said = r.to_string();
                for n in &r.notes {
                    said += &format!("; {n}");
                }
                // Its switches: which finger leaves for which, and why.
                for s in &r.plan.steps {
                    if let Some(w) = s.switch.as_ref().filter(|_| s.phase == Phase::Attach) {
                        said += &format!(
                            "; at {:.1} deg finger {} leaves ({}), finger {} takes over",
                            s.rotation.to_degrees(),
                            w.released,
                            w.reason,
                            w.attached
                        );
                    }
                }
                if !r.plan.summary.completed {
                    said += &format!(
                        "; the new plan stops short of the goal: {}",
                        r.plan.summary.stop_reason.as_deref().unwrap_or("?")
                    );
                }
                self.replanned.push((time, said));
                // Not done: the plan made again goes on (with `replan_s`, its first step is
                // published only when the planning is over).
                self.done_at = None;
                if self.replan_ns > 0 {
                    self.busy_until = Some(t + self.replan_ns);
                }
            }
            Some(e @ Event::ReplanFailed { .. }) => {
                self.replanned.push((time, e.to_string()));
            }
            _ => {}
        }
    }

    /// The wrench space of the grasp state, and the command that answers it (or the command
    /// node's tick), numbered; the plant follows it at the next tick.
    fn command(
        &mut self,
        grasp: Option<&GraspState>,
        t: u64,
    ) -> Option<(HandCommand, Option<String>)> {
        let mut made: Option<(HandCommand, Option<String>)> = None;
        if let Some(g) = grasp {
            self.commander.on_grasp(g);
            self.seq.wrench += 1;
            let h = stamped(
                Header::after(Kind::WrenchSpace, self.seq.wrench, &g.header, t),
                t,
            );
            if let Ok(w) = self.wrench.on_grasp(g, h) {
                let c = self.commander.on_wrench(&w.header, t);
                made = Some((c.command, c.hold.map(str::to_string)));
            }
        }
        if made.is_none()
            && let Some(c) = self.commander.on_tick(t)
        {
            made = Some((c.command, c.hold.map(str::to_string)));
        }
        let (mut c, why) = made?;
        self.seq.command += 1;
        c.header.sequence = self.seq.command;
        c.header.source_time_ns = t;
        if c.mode == CommandMode::Hold as u32 {
            self.holds += 1;
        } else if c.mode == CommandMode::Attach as u32 {
            self.attaches_below_margin += 1;
        }
        self.holding = why.clone();
        self.estimator.on_command(&c);
        self.command = Some(c);
        Some((c, why))
    }
}

/// `h` as published at `t` (the bus stamps the source time).
fn stamped(mut h: Header, t: u64) -> Header {
    h.source_time_ns = t;
    h
}
