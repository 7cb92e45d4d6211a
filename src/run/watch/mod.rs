//! Watching the run: what `run` takes off the bus while the nodes run ([`Watch`], fed on every
//! wake-up of its event loop, `icrflow_runtime::event`'s as every node's) until it stops
//! ([`StopReason`]); what it saw goes to the summary ([`Seen`]).

use std::collections::{BTreeMap, BTreeSet};
use std::ops::ControlFlow;
use std::time::{Duration, Instant};

use anyhow::Result;
use icrflow_interfaces::{
    CommandMode, GraspState, HandCommand, JointState, NodeHealth, NodeState, PlanPhase,
    PlanStepHeader, PlantTruth, TEXT_BYTES, read_text, topics,
};
use icrflow_runtime::bus::{Bus, SliceSub, Sub};
use icrflow_runtime::event::{Loop, RESYNC};
use icrflow_runtime::supervise::Supervisor;
use icrflow_scenario::{Config, PlantKind};

use super::launch::{VisualizerStart, report, start_visualizer};
use super::measure::{AllocationTrack, Rate, Timing, resident_kib, scheduling};
use super::physics::{PhysicsSummary, PhysicsTrack};
use super::status::{Status, say};
use super::stop::StopReason;
use super::summary::{Allocations, Histogram, Latencies, Memory, PlanStream};
use super::track::{EstimateError, Hangup, Heartbeats, ReplanProgress, Silence, TruthTrack};

/// A hold this long is reported on stderr, and again every time as long.
const HOLD_REPORT: Duration = Duration::from_secs(1);

/// The text a hold because of the estimate starts with (the command node's
/// `Hold::Estimate`).
const ESTIMATE_OFF: &str = "the estimate is off";

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
    pub holds: u64,
    pub startup_holds: u64,
    pub hold_causes: BTreeMap<String, u64>,
    pub planned_after: Option<f64>,
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
    rotation: f64,
    /// Holds after the start-up (see [`Watch::command`]), and by cause.
    holds: u64,
    hold_causes: BTreeMap<String, u64>,
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
    /// The planner node's last word while it plans (its `Starting` health report).
    planning: Option<String>,
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
            rotation: 0.0,
            holds: 0,
            hold_causes: BTreeMap::new(),
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
            planning: None,
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

    /// The status line: what the planner node does until the first plan step, then how far
    /// the run has got (`now`: drawn now, whatever the period).
    fn show(&mut self, now: bool) {
        if !self.status.due(now) {
            return;
        }
        let l = &self.limits;
        let elapsed = l.started.elapsed().as_secs_f64();
        let text = match (&self.first_plan, &self.planning) {
            (None, Some(doing)) => format!("run: the planner node is {doing}, {elapsed:.1} s"),
            // The processes' start: said once it takes a while.
            (None, None) if !now && elapsed < super::status::LINE_EVERY.as_secs_f64() => return,
            (None, None) => format!("run: waiting for the first plan step, {elapsed:.1} s"),
            (Some(_), _) => format!(
                "run: {:.1} of {:.1} deg | {} switches | min alpha* {} (alpha {}) | {} holds | {} restarts | {elapsed:.1} s",
                self.rotation.to_degrees(),
                l.goal.to_degrees(),
                self.attaches.len(),
                if self.min_quality.is_finite() {
                    format!("{:.4}", self.min_quality)
                } else {
                    "-".into()
                },
                l.alpha,
                self.holds,
                self.restarts
            ),
        };
        self.status.update(now, || text);
    }

    /// A plan step.
    fn plan_step(&mut self, p: &PlanStepHeader) {
        self.plan_published += 1;
        if let Some(physics) = &mut self.physics {
            physics.plan_step(p);
        }
        if let [.., taken, published] = p.header.trace.as_slice() {
            self.plan_compute
                .add(published.saturating_sub(*taken) as f64 * 1e-3);
        }
        if self.first_plan.is_none() {
            let now = Instant::now();
            self.first_plan = Some(now);
            self.status.clear();
            say!(
                "run: the plan is ready after {:.1} s (the hand held the initial grasp meanwhile); the hand follows it",
                now.duration_since(self.limits.started).as_secs_f64()
            );
            self.show(true);
        }
        if p.phase == PlanPhase::Done as u32 {
            self.done = true;
            return;
        }
        self.last_step = self.last_step.max(p.step);
        if self.progress.is_none_or(|(step, _)| step != p.step) {
            self.progress = Some((p.step, Instant::now()));
        }
        if p.phase == PlanPhase::Attach as u32 {
            self.attaches.insert(p.step);
        }
        if p.phase == PlanPhase::Start as u32
            && p.step > 0
            && self.replans.insert(p.step)
            && let Some(why) = self.replan_progress.replanned(p.rotation, self.limits.goal)
        {
            self.gave_up.get_or_insert(why);
        }
    }

    /// A hand command.
    fn command(&mut self, c: &HandCommand) {
        self.sent += 1;
        if c.mode == CommandMode::Track as u32 {
            self.tracked = true;
            if let Some((since, _)) = self.holding.take()
                && since.elapsed() >= HOLD_REPORT
            {
                say!(
                    "run: the hand tracks again after holding {:.1} s",
                    since.elapsed().as_secs_f64()
                );
            }
            self.min_quality = self.min_quality.min(c.quality);
            self.truth.tracked(1, self.limits.estimate_bound);
            self.doubting = false;
            self.timing.add(c.header.trace.as_slice());
            if c.header.origin_time_ns > 0 {
                let made = c.header.source_time_ns;
                if made.saturating_sub(c.header.origin_time_ns) > self.limits.max_age_ns {
                    self.stale_tracked += 1;
                }
            }
            return;
        }
        let reason = read_text(&c.reason);
        // The start-up: the hand holds its initial grasp until every input has come (the
        // plan, while the planner node plans): not a hold of the run, and no reason to give
        // up (the planner node's failure is the supervisor's).
        if !self.tracked && reason.starts_with("no ") && reason.ends_with(" yet") {
            self.startup_holds += 1;
            return;
        }
        self.holds += 1;
        *self.hold_causes.entry(cause(&reason)).or_default() += 1;
        self.hold_reason = c.reason;
        if c.reason.starts_with(ESTIMATE_OFF.as_bytes()) {
            self.estimate_holds += 1;
            // Said at once, once a spell: the loop noticed its estimate is wrong.
            if !self.doubting {
                say!("run: the hand holds: {reason}");
            }
            self.doubting = true;
        } else {
            self.doubting = false;
        }
        // A hold longer than HOLD_REPORT is reported (with its reason), then every
        // HOLD_REPORT again; short ones only count.
        let now = Instant::now();
        let (since, reported) = self.holding.get_or_insert((now, now));
        if now.duration_since(*reported) >= HOLD_REPORT {
            *reported = now;
            say!(
                "run: the hand has held for {:.1} s: {reason}",
                now.duration_since(*since).as_secs_f64()
            );
        }
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
        }
        if let Some(g) = ports.grasps.latest()? {
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

    /// Whether a run to the goal cannot go on: a plan that does not go on while the hand
    /// tracks (a target it never reaches, and the planner node does not plan again), or
    /// ended short of the goal (a plan made again from the estimate may); a hand that holds
    /// too long.
    fn stalled(&self) -> Option<StopReason> {
        let l = &self.limits;
        if l.live {
            return None;
        }
        let short = self.rotation < l.goal - icrflow_plan::follow::GOAL_TOLERANCE;
        // Before the first plan step the planner node plans: however long that takes, it is
        // no stall (a planner node that fails is the supervisor's, and said).
        let (step, since) = self.progress.map(|(step, t)| (step, t.elapsed()))?;
        if (!self.done || short) && self.holding.is_none() && since >= l.max_hold {
            return Some(if self.done {
                StopReason::PlanEndedShort {
                    step,
                    rotation: self.rotation,
                }
            } else {
                StopReason::PlanStalled {
                    step,
                    since,
                    rotation: self.rotation,
                }
            });
        }
        // A run to the goal does not wait for ever on a hand that cannot go on.
        match self.holding {
            Some((since, _)) if since.elapsed() >= l.max_hold => Some(StopReason::HandHeld {
                since: since.elapsed(),
                reason: read_text(&self.hold_reason),
            }),
            _ => None,
        }
    }

    /// Samples each process's scheduling policy and resident memory.
    fn sample(&mut self, supervisor: &Supervisor) {
        for n in &self.names {
            if let Some(policy) = supervisor.pid(n).and_then(scheduling) {
                self.policies.insert(n.clone(), policy);
            }
            if let Some(kib) = supervisor.pid(n).and_then(resident_kib) {
                let m = self.memory.entry(n.clone()).or_insert(Memory {
                    first: kib,
                    ..Memory::default()
                });
                m.last = kib;
                m.max = m.max.max(kib);
                m.samples += 1;
            }
        }
    }

    /// Takes a node's health report, taken off the bus at `now`: its heartbeat, its
    /// allocations into its track, and the visualizer's frames recorded and dropped (per
    /// process).
    fn take_health(&mut self, h: &NodeHealth, now: Instant) {
        let node = read_text(&h.node);
        if h.state == NodeState::Starting as u32 {
            // A node that says it starts up (the planner node planning) is not watched for
            // hangs until it runs; what it does is shown.
            if node == icrflow_interfaces::topics::NodeRole::Planner.name() {
                let doing = read_text(&h.message);
                if self.planning.is_none() {
                    say!("run: the planner node is {doing}");
                }
                self.planning = Some(doing);
            }
            return;
        }
        self.beats.beat(&node, h.pid, now);
        if node == icrflow_interfaces::topics::NodeRole::Visualizer.name() {
            self.frames.insert(h.pid, (h.processed, h.refused));
        }
        self.tracks
            .entry(node)
            .or_default()
            .report(h.pid, h.allocations, h.processed, now);
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
            holds: self.holds,
            startup_holds: self.startup_holds,
            hold_causes: self.hold_causes,
            planned_after: self
                .first_plan
                .map(|t| t.duration_since(self.limits.started).as_secs_f64()),
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

/// The cause of a hold, from its reason: the text before its details, the parts up to the
/// first with a number (`grasp state: stale` of `grasp state: stale: 12.1 ms old, limit
/// 10.0 ms`), numbers in the first part as `N`.
pub(super) fn cause(reason: &str) -> String {
    let mut parts = reason.split(':');
    let mut head = parts.next().unwrap_or(reason).trim().to_string();
    if !head.chars().any(|c| c.is_ascii_digit()) {
        for part in parts.take_while(|p| !p.chars().any(|c| c.is_ascii_digit())) {
            head.push(':');
            head.push_str(part);
        }
    }
    let head = head.trim();
    let mut out = String::with_capacity(head.len());
    let mut in_number = false;
    for ch in head.chars() {
        if ch.is_ascii_digit() || (in_number && ch == '.') {
            if !in_number {
                out.push('N');
            }
            in_number = true;
        } else {
            in_number = false;
            out.push(ch);
        }
    }
    out
}

/// Says what a node's silence is, and kills a hung node (the supervisor restarts it).
fn silence(s: &Silence, supervisor: &mut Supervisor, restart_s: f64) {
    match s {
        Silence::Silent { name, pid, since } => say!(
            "run: node {name} (pid {pid}) has sent no heartbeat for {:.1} s: hung or stopped? (restarted after {restart_s} s: pipeline.hung_restart_s)",
            since.as_secs_f64()
        ),
        Silence::Hung { name, pid, since } => {
            supervisor.kill(name);
            say!(
                "run: node {name} (pid {pid}) has sent no heartbeat for {:.1} s: killed, to be restarted",
                since.as_secs_f64()
            );
        }
        Silence::Back { name, after } => say!(
            "run: node {name} sends heartbeats again after {:.1} s",
            after.as_secs_f64()
        ),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_holds_cause_is_its_reason_without_the_details() {
        assert_eq!(
            cause("grasp state is stale: 12.1 ms old, limit 10.0 ms"),
            "grasp state is stale"
        );
        assert_eq!(
            cause("grasp state: stale: 3.2 ms old, limit 0.0 ms"),
            "grasp state: stale"
        );
        assert_eq!(
            cause("the estimate is off: pose innovation 3.20 deg over the bound 2.00 deg"),
            "the estimate is off"
        );
        assert_eq!(
            cause("no wrench space for 31.5 ms"),
            "no wrench space for N ms"
        );
        assert_eq!(
            cause("quality alpha* = 0.0812 below the margin alpha = 0.1"),
            "quality alpha* = N below the margin alpha = N"
        );
    }
}
