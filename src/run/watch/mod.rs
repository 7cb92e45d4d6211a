//! Watching the run: what `run` takes off the bus while the nodes run ([`Watch`], fed on every
//! wake-up of its event loop, `icrflow_runtime::event`'s as every node's) until it stops
//! ([`StopReason`]); what it saw goes to the summary ([`Seen`]).
//!
//! | module | what the watch takes |
//! |---|---|
//! | this one | the loop: the topics read, each wake-up and tick, what was seen at the end |
//! | [`plan`] | the plan steps, and whether the plan still goes on |
//! | [`commands`] | the hand commands: tracking, and holds by cause |
//! | [`nodes`] | the nodes' health reports, `/proc` samples, silences |
//! | [`line`] | the status line on stderr |

mod commands;
mod line;
mod nodes;
mod plan;

use std::collections::{BTreeMap, BTreeSet};
use std::ops::ControlFlow;
use std::time::{Duration, Instant};

use anyhow::Result;
use icrflow_interfaces::{
    GraspState, HandCommand, JointState, NodeHealth, PlanStepHeader, PlantTruth, TEXT_BYTES,
    read_text, topics,
};
use icrflow_runtime::bus::{Bus, SliceSub, Sub};
use icrflow_runtime::event::{Loop, RESYNC};
use icrflow_runtime::supervise::Supervisor;
use icrflow_scenario::{Config, PlantKind};

use super::histogram::Histogram;
use super::hold_cause::HoldCause;
use super::launch::{VisualizerStart, report, start_visualizer};
use super::measure::{AllocationTrack, Rate, Timing};
use super::physics::{PhysicsSummary, PhysicsTrack};
use super::planner_waits::{PlannerWaits, WaitTrack};
use super::status::{Status, say};
use super::stop::StopReason;
use super::summary::{Allocations, BelowMarginAttaches, Latencies, Memory, PlanStream};
use super::track::{EstimateError, Hangup, Heartbeats, ReplanProgress, TruthTrack};
use nodes::silence;

/// How long a run to the goal may take, from its first plan step (and how long it waits for
/// that one).
const TIMEOUT: Duration = Duration::from_secs(600);

/// How long after a node process starts its allocations are not counted as steady state
/// (setup: planning, buffers, the first contact sets).
pub const WARM_UP: Duration = Duration::from_secs(2);

/// What the run watched stopped with, for the summary.
pub(super) struct Seen {
    /// Why it stopped.
    pub stop: StopReason,
    /// The visualizer's frames recorded and dropped.
    pub frames: (u64, u64),
    pub done: bool,
    pub rotation: f64,
    pub attaches: usize,
    pub replans: usize,
    pub steps: usize,
    pub min_quality: f64,
    pub attaching_below_margin: Option<BelowMarginAttaches>,
    pub holds: u64,
    pub startup_holds: u64,
    pub hold_causes: BTreeMap<String, u64>,
    /// The holds' causes with their numbers as the reasons had them, by cause.
    pub hold_figures: BTreeMap<String, String>,
    pub planned_after: Option<f64>,
    pub planner_waits: PlannerWaits,
    pub sent: u64,
    pub measurements: u64,
    pub measurement_rate_hz: f64,
    pub command_rate_hz: f64,
    pub stale_tracked: u64,
    pub latencies: Latencies,
    pub plan_steps: PlanStream,
    pub memory: BTreeMap<String, Memory>,
    pub scheduling: BTreeMap<String, String>,
    pub allocations: BTreeMap<String, Allocations>,
    pub estimate: Option<EstimateError>,
    pub estimate_holds: u64,
    pub physics: Option<PhysicsSummary>,
}

/// The topics the run reads.
struct Ports {
    /// Woken on.
    plans: SliceSub<PlanStepHeader, u32>,
    /// Woken on.
    commands: Sub<HandCommand>,
    // Read on the run's own tick (only the newest matters), so they cost no wake-up.
    grasps: Sub<GraspState>,
    joints: Sub<JointState>,
    /// The nodes' allocation counts and heartbeats, read on the tick.
    healths: Sub<NodeHealth>,
    /// The simulated plant's truth, against which the estimate is measured.
    truths: Sub<PlantTruth>,
}

impl Ports {
    fn new(bus: &Bus) -> Result<Self> {
        Ok(Self {
            plans: bus.slice_subscriber(topics::PLAN_STEP)?,
            commands: bus.subscriber(topics::HAND_COMMAND)?,
            grasps: bus.subscriber(topics::GRASP_STATE)?,
            joints: bus.subscriber(topics::JOINT_STATE)?,
            healths: bus.subscriber(topics::NODE_HEALTH)?,
            truths: bus.subscriber(topics::PLANT_TRUTH)?,
        })
    }
}

/// What the run needs to know from the config and the command line to watch.
struct Limits {
    live: bool,
    /// The goal (rad).
    goal: f64,
    started: Instant,
    /// `pipeline.hung_restart_s`.
    hung_restart: Duration,
    hung_restart_s: f64,
    /// The estimate's bound (`pipeline.max_pose_innovation_deg`, rad).
    estimate_bound: f64,
    /// What the hand command node guarantees at publication, plus an allowance for the
    /// delivery to this process.
    max_age_ns: u64,
    /// `pipeline.max_hold_s`.
    max_hold: Duration,
    /// The margin.
    alpha: f64,
    /// How long a run that reached its goal goes on before it stops: [`LINGER`] on the host
    /// of a split run that plans (its planner republishes `Done`, which the other host's run
    /// needs to hear to stop), none otherwise.
    linger: Duration,
    /// The topics a split run takes from the other host and watches for ([`WATCHED`]), and
    /// its Zenoh link, in words (`connecting to tcp/..., listening on tcp/...`).
    imports: Vec<&'static str>,
    link: String,
}

/// The topics the run reads (and so sees arrive) that can come from the other host of a split
/// run.
const WATCHED: [topics::TopicId; 4] = [
    topics::TopicId::JointState,
    topics::TopicId::GraspState,
    topics::TopicId::PlanStep,
    topics::TopicId::HandCommand,
];

/// A split run's link to the other host, in words: where its bridge connects and listens.
fn link(zenoh: &icrflow_scenario::ZenohSpec) -> String {
    let mut parts = Vec::new();
    if !zenoh.connect.is_empty() {
        parts.push(format!("connecting to {}", zenoh.connect.join(", ")));
    }
    if !zenoh.listen.is_empty() {
        parts.push(format!("listening on {}", zenoh.listen.join(", ")));
    }
    format!("Zenoh, {}", parts.join(", "))
}

/// How long the planning host of a split run goes on after its goal, so that the planner's
/// `Done` (republished every 10 ms) crosses to the other host before this host's bridge
/// stops: without it, in one of 8 cut-link runs here, the other host's run never heard it
/// (this host stopped its bridge as its planner published it) and held for `max_hold_s`.
pub const LINGER: Duration = Duration::from_secs(1);

/// The run's watch: the state it keeps across wake-ups.
pub(super) struct Watch {
    limits: Limits,
    hangup: Hangup,
    /// The processes whose memory and scheduling are sampled.
    names: Vec<String>,
    /// Joint measurements, counted by their sequence numbers (one per measurement; a
    /// restarted plant starts higher up), and the last sequence number.
    measurements: u64,
    last_joint: u64,
    measurement_rate: Rate,
    command_rate: Rate,
    plan_rate: Rate,
    tracks: BTreeMap<String, AllocationTrack>,
    /// The visualizer's frames recorded and dropped, per process (a restart counts anew).
    frames: BTreeMap<u32, (u64, u64)>,
    /// Every node's heartbeat (its health reports): a silent one is said, a hung one
    /// restarted after pipeline.hung_restart_s.
    beats: Heartbeats,
    truth: TruthTrack,
    /// The run against MuJoCo's truth (a MuJoCo plant only).
    physics: Option<PhysicsTrack>,
    estimate_holds: u64,
    /// Whether the last command was a hold for the estimate.
    doubting: bool,
    replan_progress: ReplanProgress,
    gave_up: Option<String>,
    last_step: u64,
    attaches: BTreeSet<u64>,
    replans: BTreeSet<u64>,
    min_quality: f64,
    attaching_below_margin: Option<BelowMarginAttaches>,
    /// Whether the last command attached below the margin.
    attaching: bool,
    rotation: f64,
    /// Holds after the start-up (see [`Watch::command`]), and by cause.
    holds: u64,
    hold_causes: BTreeMap<String, u64>,
    /// The holds' causes with their numbers, by cause.
    hold_figures: BTreeMap<String, HoldCause>,
    /// Holds of the start-up: before the hand first tracked, for an input not there yet
    /// (the plan, while the planner node plans).
    startup_holds: u64,
    /// Whether a tracking command has come.
    tracked: bool,
    sent: u64,
    stale_tracked: u64,
    done: bool,
    timing: Timing,
    /// Since when the hand holds, when that was last reported, and the last hold's reason.
    holding: Option<(Instant, Instant)>,
    hold_reason: [u8; TEXT_BYTES],
    /// The newest plan step and since when (the plan goes on while its steps advance); `None`
    /// before the first.
    progress: Option<(u64, Instant)>,
    /// When the first plan step came.
    first_plan: Option<Instant>,
    /// The hand waiting for the planner after that.
    waits: WaitTrack,
    /// The planner node's last word while it plans (its `Starting` health report).
    planning: Option<String>,
    /// Whether the planner node has planned (it reports that it runs).
    planned: bool,
    /// The topics seen on the bus so far (their names), of those a split run can wait for.
    arrived: BTreeSet<&'static str>,
    /// What `run` says on stderr as it goes.
    status: Status,
    /// Whether the goal's reaching was said.
    goal_said: bool,
    /// When the goal was reached (for [`Limits::linger`]).
    goal_at: Option<Instant>,
    /// Node restarts so far.
    restarts: u32,
    plan_published: u64,
    plan_compute: Histogram,
    memory: BTreeMap<String, Memory>,
    policies: BTreeMap<String, String>,
    next_sample: Instant,
}

/// Starts the run's processes (the visualizer first, alone, with `recording`) and watches
/// them on `bus` until the run stops; then shuts them down. `names`: the processes.
pub(super) fn watch(
    bus: &Bus,
    supervisor: &mut Supervisor,
    config: &Config,
    live: bool,
    recording: bool,
    names: Vec<String>,
    hangup: Hangup,
) -> Result<Seen> {
    let ports = Ports::new(bus)?;
    let now = Instant::now();
    say!(
        "run: starting {} processes: {}",
        names.len(),
        names.join(", ")
    );
    let physics = match config.plant.kind {
        PlantKind::Mujoco => Some(PhysicsTrack::new(
            config,
            icrflow_physics::sim::MUJOCO_VERSION,
        )?),
        PlantKind::Kinematic => None,
    };
    let mut w = Watch::new(config, live, names, hangup, now);
    w.physics = physics;
    // The visualizer listens before the loop begins, or its recording would miss the first
    // plan steps (it starts at a lower priority, and sets up as long as a node).
    let mut waited = VisualizerStart::Listening;
    if recording {
        waited = start_visualizer(bus, supervisor, &ports.healths, &w.hangup.clone(), |h| {
            w.take_health(h, Instant::now())
        })?;
    }
    // Interrupted meanwhile: the loop below ends at once, as on a Ctrl-C.
    if waited != VisualizerStart::Interrupted {
        for e in supervisor.start()? {
            report(&e);
        }
    }
    let on = Loop {
        node: bus.node(),
        name: "run",
        realtime: None,
    };
    // Every wake-up reads every input (see icrflow_runtime::event::serve); the tick is the
    // resync's period.
    let woken = [ports.plans.listener(), ports.commands.listener()];
    let outcome = on.serve_until(&woken, Some(RESYNC), |ticked| {
        Ok(match w.wake(&ports, supervisor, ticked) {
            Ok(None) => ControlFlow::Continue(()),
            Ok(Some(stop)) => ControlFlow::Break(Ok(stop)),
            Err(e) => ControlFlow::Break(Err(e)),
        })
    });
    let stop = match outcome {
        Ok(Some(stop)) => stop,
        Ok(None) => Ok(StopReason::Signal),
        Err(e) => Ok(StopReason::WaitFailed(format!("{e:#}"))),
    };
    w.status.clear();
    if let Ok(stop) = &stop {
        say!("run: stopping the processes: {stop}");
    }
    // The grace period lets the visualizer write the end of its recording.
    let killed = supervisor.shutdown(Duration::from_secs(5));
    if !killed.is_empty() {
        say!("run: killed after the grace period: {killed:?}");
    }
    // The visualizer's last report, as it stopped.
    ports.healths.drain(|h| {
        if read_text(&h.node) == icrflow_interfaces::topics::NodeRole::Visualizer.name() {
            w.frames.insert(h.pid, (h.processed, h.refused));
        }
    })?;
    Ok(w.seen(stop?))
}

impl Watch {
    fn new(config: &Config, live: bool, names: Vec<String>, hangup: Hangup, now: Instant) -> Self {
        let p = &config.pipeline;
        Self {
            limits: Limits {
                live,
                goal: config.plan.goal,
                started: now,
                hung_restart: Duration::from_secs_f64(p.hung_restart),
                hung_restart_s: p.hung_restart,
                estimate_bound: p.max_pose_innovation,
                max_age_ns: (p.max_input_age * 1e9) as u64 + 10_000_000,
                max_hold: Duration::from_secs_f64(p.max_hold),
                alpha: config.grasp.alpha,
                linger: if p.split() && p.nodes.iter().any(|n| n == "planner") {
                    LINGER
                } else {
                    Duration::ZERO
                },
                imports: if p.split() {
                    topics::links(&p.nodes)
                        .import
                        .into_iter()
                        .filter(|t| WATCHED.contains(t))
                        .map(|t| t.name())
                        .collect()
                } else {
                    Vec::new()
                },
                link: link(&config.zenoh),
            },
            hangup,
            names,
            measurements: 0,
            last_joint: 0,
            measurement_rate: Rate::default(),
            command_rate: Rate::default(),
            plan_rate: Rate::default(),
            tracks: BTreeMap::new(),
            frames: BTreeMap::new(),
            beats: Heartbeats::default(),
            truth: TruthTrack::default(),
            physics: None,
            estimate_holds: 0,
            doubting: false,
            replan_progress: ReplanProgress::default(),
            gave_up: None,
            last_step: 0,
            attaches: BTreeSet::new(),
            replans: BTreeSet::new(),
            min_quality: f64::INFINITY,
            attaching_below_margin: None,
            attaching: false,
            rotation: 0.0,
            holds: 0,
            hold_causes: BTreeMap::new(),
            hold_figures: BTreeMap::new(),
            startup_holds: 0,
            tracked: false,
            sent: 0,
            stale_tracked: 0,
            done: false,
            timing: Timing::new(),
            holding: None,
            hold_reason: [0; TEXT_BYTES],
            progress: None,
            first_plan: None,
            waits: WaitTrack::default(),
            planning: None,
            planned: false,
            arrived: BTreeSet::new(),
            status: Status::default(),
            goal_said: false,
            goal_at: None,
            restarts: 0,
            plan_published: 0,
            plan_compute: Histogram::new(),
            memory: BTreeMap::new(),
            policies: BTreeMap::new(),
            next_sample: now + Duration::from_secs(1),
        }
    }

    /// One wake-up of the run's loop (`ticked`: the periodic one): why the run stops, if it
    /// does.
    fn wake(
        &mut self,
        ports: &Ports,
        supervisor: &mut Supervisor,
        ticked: bool,
    ) -> Result<Option<StopReason>> {
        if self.hangup.came() {
            return Ok(Some(StopReason::Hangup));
        }
        ports.plans.drain(|p, _| self.plan_step(p))?;
        ports.commands.drain(|c| self.command(c))?;
        self.command_rate.saw(self.sent);
        self.plan_rate.saw(self.plan_published);
        if ticked && let Some(stop) = self.tick(ports, supervisor)? {
            return Ok(Some(stop));
        }
        let l = &self.limits;
        let at_goal = self.done && self.rotation >= l.goal - icrflow_plan::follow::GOAL_TOLERANCE;
        if at_goal && !self.goal_said {
            self.goal_said = true;
            self.status.clear();
            say!(
                "run: goal reached: {:.1} of {:.1} deg, {} finger switches, after {:.1} s{}",
                self.rotation.to_degrees(),
                l.goal.to_degrees(),
                self.attaches.len(),
                l.started.elapsed().as_secs_f64(),
                if l.live {
                    "; --live: the hand holds the object there until Ctrl-C"
                } else {
                    ""
                }
            );
        }
        if at_goal && !l.live {
            let since = *self.goal_at.get_or_insert_with(Instant::now);
            if since.elapsed() >= l.linger {
                return Ok(Some(StopReason::GoalReached));
            }
        }
        Ok(None)
    }

    /// The periodic wake-up: the topics read on it, the supervisor, the heartbeats, the
    /// samples; why the run stops, if it does.
    fn tick(&mut self, ports: &Ports, supervisor: &mut Supervisor) -> Result<Option<StopReason>> {
        if let Some(j) = ports.joints.latest()? {
            let gap = j.header.sequence.wrapping_sub(self.last_joint);
            self.measurements += if self.last_joint > 0 && gap < 1_000_000 {
                gap
            } else {
                1
            };
            self.last_joint = j.header.sequence;
            self.measurement_rate.saw(self.measurements);
            self.arrived.insert(topics::TopicId::JointState.name());
        }
        if let Some(g) = ports.grasps.latest()? {
            self.arrived.insert(topics::TopicId::GraspState.name());
            self.rotation = g.rotation;
            self.truth.estimate(&g);
        }
        let now = Instant::now();
        ports.healths.drain(|h| self.take_health(h, now))?;
        ports.truths.drain(|t| {
            self.truth.truth(t);
            if let Some(p) = &mut self.physics {
                p.truth(t);
            }
        })?;
        for e in supervisor.poll(Instant::now())? {
            report(&e);
        }
        self.restarts = supervisor.restarts();
        self.show(false);
        let (restart, restart_s) = (self.limits.hung_restart, self.limits.hung_restart_s);
        for s in self
            .beats
            .check(Instant::now(), restart, |n| supervisor.pid(n))
        {
            silence(&s, supervisor, restart_s);
        }
        if let Some(why) = self.gave_up.take() {
            return Ok(Some(StopReason::ReplanStuck(why)));
        }
        if Instant::now() >= self.next_sample {
            self.next_sample += Duration::from_secs(1);
            self.sample(supervisor);
        }
        if let Some(n) = supervisor.failed() {
            return Ok(Some(StopReason::NodeFailed(n.to_string())));
        }
        if self.first_plan.unwrap_or(self.limits.started).elapsed() > TIMEOUT {
            return Ok(Some(StopReason::TimedOut(TIMEOUT)));
        }
        Ok(self.stalled())
    }

    /// What the run saw, as it stopped for `stop`.
    fn seen(self, stop: StopReason) -> Seen {
        Seen {
            stop,
            done: self.done,
            rotation: self.rotation,
            attaches: self.attaches.len(),
            replans: self.replans.len(),
            steps: self.last_step as usize,
            min_quality: self.min_quality,
            attaching_below_margin: self.attaching_below_margin,
            holds: self.holds,
            startup_holds: self.startup_holds,
            hold_causes: self.hold_causes,
            hold_figures: self
                .hold_figures
                .iter()
                .map(|(k, c)| (k.clone(), c.shown()))
                .collect(),
            planned_after: self
                .first_plan
                .map(|t| t.duration_since(self.limits.started).as_secs_f64()),
            planner_waits: self.waits.summary(Instant::now()),
            sent: self.sent,
            measurements: self.measurements,
            stale_tracked: self.stale_tracked,
            latencies: self.timing.summary(),
            measurement_rate_hz: self.measurement_rate.hz(),
            command_rate_hz: self.command_rate.hz(),
            plan_steps: PlanStream {
                published: self.plan_published,
                rate_hz: self.plan_rate.hz(),
                compute_us: self.plan_compute.percentiles(),
            },
            memory: self.memory,
            scheduling: self.policies,
            allocations: self
                .tracks
                .iter()
                .map(|(n, t)| (n.clone(), t.total()))
                .collect(),
            estimate: self.truth.summary(),
            estimate_holds: self.estimate_holds,
            physics: self.physics.as_ref().map(PhysicsTrack::summary),
            frames: self
                .frames
                .values()
                .fold((0, 0), |(a, b), (p, r)| (a + p, b + r)),
        }
    }
}
