//! `icrflow run CONFIG [--live] [--summary-json PATH]`: the pipeline, one process per node,
//! supervised, on an iceoryx2 bus of its own, until the scenario's goal (or Ctrl-C).

use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use anyhow::{Context, Result, bail};
use iceoryx2::prelude::*;
use iceoryx2::waitset::WaitSetRunResult;
use icrflow_interfaces::{CommandMode, NodeHealth, PlanPhase, read_text, topics};
use icrflow_plan::rolling::Surface;
use icrflow_runtime::bus::{Bus, BusConfig, Sub};
use icrflow_runtime::supervise::{Event, NodeSpec, RestartPolicy, Supervisor};
use icrflow_scenario::{Config, Recording, Setup};
use serde::Serialize;

use crate::watch::{EstimateError, Hangup, Heartbeats, ReplanProgress, Silence, TruthTrack};

/// A hold this long is reported on stderr, and again every time as long.
const HOLD_REPORT: Duration = Duration::from_secs(1);

/// The visualizer's node name (when the visualizer is on, started first and alone: the loop
/// starts once it listens).
pub const VISUALIZER: &str = "visualizer";
/// coreutils' `nice`, which starts the visualizer at a lower CPU priority.
const NICE: &str = "/usr/bin/nice";
/// The nodes on the measurement-to-command path, whose loops run under SCHED_FIFO at
/// `pipeline.realtime_priority`: the plant (it stands for the hand's driver), the estimator,
/// the wrench-space node and the hand command node. The planner works beside the path, and
/// may take milliseconds.
const REALTIME_NODES: [&str; 4] = ["plant", "estimator", "wrench", "command"];

/// The scheduling policy of process `pid`'s main thread (a node's loop) from `/proc`
/// (`"fifo 50"`, `"normal"`, ...).
fn scheduling(pid: u32) -> Option<String> {
    let stat = std::fs::read_to_string(format!("/proc/{pid}/stat")).ok()?;
    // After the command name (in parentheses, which may hold spaces): state is field 3,
    // rt_priority field 40, policy field 41.
    let fields: Vec<&str> = stat.rsplit_once(')')?.1.split_whitespace().collect();
    let (priority, policy) = (fields.get(37)?, fields.get(38)?.parse::<u32>().ok()?);
    Some(match policy {
        0 => "normal".to_string(),
        1 => format!("fifo {priority}"),
        2 => format!("rr {priority}"),
        3 => "batch".to_string(),
        5 => "idle".to_string(),
        6 => "deadline".to_string(),
        p => format!("policy {p}"),
    })
}

/// Where `run`'s flags send the Rerun recording (over `[visualizer]` of the config).
#[derive(Debug, Default)]
pub struct Viewer {
    /// `--rrd PATH`.
    pub rrd: Option<PathBuf>,
    /// `--spawn-viewer`.
    pub spawn: bool,
    /// `--connect-viewer URL`.
    pub connect: Option<String>,
    /// `--no-visualizer`.
    pub off: bool,
}

impl Viewer {
    /// The recording target, or `None` without the visualizer.
    fn recording(self, config: &Config) -> Result<Option<Recording>> {
        if self.off || !config.visualizer.enabled {
            return Ok(None);
        }
        let r = self
            .flagged(config)?
            .unwrap_or_else(|| config.visualizer.recording.clone());
        Ok(Some(absolute(r)?))
    }

    /// The target the flags ask for, if any (a spawned viewer listens at the port of
    /// `visualizer.url`).
    pub fn flagged(&self, config: &Config) -> Result<Option<Recording>> {
        Ok(if let Some(p) = &self.rrd {
            Some(Recording::Rrd(p.clone()))
        } else if self.spawn {
            let (_, port) = icrflow_scenario::viewer_url(&config.visualizer.url)?;
            Some(Recording::Spawn(port))
        } else if let Some(url) = &self.connect {
            icrflow_scenario::viewer_url(url).context("--connect-viewer")?;
            Some(Recording::Connect(url.clone()))
        } else {
            None
        })
    }
}

/// The recording target with a relative `.rrd` path made absolute (the processes that write it
/// may run elsewhere).
pub fn absolute(r: Recording) -> Result<Recording> {
    Ok(match r {
        Recording::Rrd(p) if p.is_relative() => Recording::Rrd(
            std::env::current_dir()
                .context("the current directory")?
                .join(p),
        ),
        other => other,
    })
}

/// Where a recording went, as the summaries say it.
pub fn target_name(r: &Recording) -> String {
    match r {
        Recording::Rrd(p) => p.display().to_string(),
        Recording::Spawn(port) => format!("spawned viewer (rerun+http://127.0.0.1:{port}/proxy)"),
        Recording::Connect(url) => url.clone(),
    }
}

/// The run's Rerun recording.
#[derive(Debug, Serialize, Default)]
pub struct RecordingSummary {
    /// The `.rrd` file (or `spawned viewer`, or the viewer's URL).
    pub target: String,
    /// The recording id.
    pub id: String,
    /// Frames the visualizer recorded (plan steps, scene and time-series frames).
    pub frames: u64,
    /// Frames it dropped because the recording lagged.
    pub dropped: u64,
}

/// The Zenoh bridge's node name (started after the loop's nodes when `zenoh.enabled`).
pub const BRIDGE: &str = "bridge";

/// Latency percentiles (microseconds).
#[derive(Debug, Serialize, Default, Clone, Copy)]
pub struct Percentiles {
    /// Median.
    pub p50: f64,
    /// 99th percentile.
    pub p99: f64,
    /// Largest.
    pub max: f64,
    /// Samples.
    pub samples: usize,
}

/// Latency samples (us) in a fixed histogram of buckets 1 % wide from 1 us to about 100 s, so
/// that a long `--live` run keeps constant memory. Percentiles are bucket upper bounds (within
/// 1 % above the true value, never above the largest sample); the largest sample is exact.
#[derive(Debug, Clone)]
pub(crate) struct Histogram {
    counts: Vec<u64>,
    samples: u64,
    max: f64,
}

impl Histogram {
    const GROWTH: f64 = 1.01;
    const BUCKETS: usize = 1852; // 1.01^1851 > 1e8

    pub(crate) fn new() -> Self {
        Self {
            counts: vec![0; Self::BUCKETS],
            samples: 0,
            max: 0.0,
        }
    }

    pub(crate) fn add(&mut self, us: f64) {
        let bucket = if us <= 1.0 {
            0
        } else {
            ((us.ln() / Self::GROWTH.ln()).ceil() as usize).min(Self::BUCKETS - 1)
        };
        self.counts[bucket] += 1;
        self.samples += 1;
        self.max = self.max.max(us);
    }

    fn at(&self, q: f64) -> f64 {
        let rank = ((q * self.samples as f64).ceil() as u64).clamp(1, self.samples);
        let mut seen = 0;
        for (bucket, count) in self.counts.iter().enumerate() {
            seen += count;
            if seen >= rank {
                return Self::GROWTH.powi(bucket as i32).min(self.max);
            }
        }
        self.max
    }

    pub(crate) fn percentiles(&self) -> Percentiles {
        if self.samples == 0 {
            return Percentiles::default();
        }
        Percentiles {
            p50: self.at(0.5),
            p99: self.at(0.99),
            max: self.max,
            samples: self.samples as usize,
        }
    }
}

/// The run's summary (`--summary-json`).
#[derive(Debug, Serialize)]
pub struct RunSummary {
    /// Whether the goal was reached.
    pub completed: bool,
    /// Why the run ended.
    pub reason: String,
    /// Object rotation reached, from the state estimate (deg).
    pub rotation_deg: f64,
    /// Goal (deg).
    pub goal_deg: f64,
    /// Finger switches executed (attach steps reached).
    pub switches: usize,
    /// The last plan step commanded (the plan's step number; the start is 0), i.e. the number
    /// of plan steps executed after the start.
    pub steps: usize,
    /// Times the planner node planned again from the estimate (the object stopped off its
    /// target, e.g. after `pipeline.slip_deg`): `start` plan steps after step 0.
    pub replans: usize,
    /// Smallest quality alpha* of the grasp a tracking command was computed with.
    pub min_quality: f64,
    /// The margin.
    pub alpha: f64,
    /// Node restarts by the supervisor.
    pub restarts: u32,
    /// Hand commands that held.
    pub holds: u64,
    /// Hand commands sent (one per joint measurement that reached the command node; holds
    /// when none came for three periods).
    pub commands: u64,
    /// Joint measurements the plant published (`pipeline.rate_hz` nominal; a tick the plant
    /// was not scheduled for in time is skipped).
    pub measurements: u64,
    /// Measurements per second while they flow (from the first to the last the run saw: the
    /// start-up before the plant's first tick is not counted).
    pub measurement_rate_hz: f64,
    /// Hand commands per second while they flow (from the first to the last).
    pub command_rate_hz: f64,
    /// Tracking commands made (their source time) from a joint measurement older than
    /// `pipeline.max_input_age_ms` plus 10 ms (the command's computation after the node's
    /// check): should be 0, the hand command node holds instead.
    pub stale_tracked: u64,
    /// Wall time (s).
    pub seconds: f64,
    /// The run's iceoryx2 prefix (its shared-memory objects are `/dev/shm/<prefix>*`).
    pub bus_prefix: String,
    /// The run's iceoryx2 root directory (removed at the end).
    pub bus_root: String,
    /// Latency of the critical path, end to end and per stage (us).
    pub latency_us: Latencies,
    /// The planner's plan-step stream.
    pub plan_steps: PlanStream,
    /// Resident memory of each node process, sampled every second (KiB).
    pub memory_kib: std::collections::BTreeMap<String, Memory>,
    /// The scheduling policy of each node process's main thread (its loop), as last sampled
    /// (`"fifo 50"`, `"normal"`): `pipeline.realtime_priority` at work.
    pub scheduling: std::collections::BTreeMap<String, String>,
    /// Per node: heap allocations in the steady state (from its health reports).
    pub allocations: std::collections::BTreeMap<String, Allocations>,
    /// The Rerun recording (absent without the visualizer).
    pub recording: Option<RecordingSummary>,
    /// The estimate against the simulated plant's truth (`None` where no truth comes: the
    /// plant on another host).
    pub estimate: Option<EstimateError>,
    /// Hold commands because the estimate was off (its residuals over their bounds).
    pub estimate_holds: u64,
}

/// Latency percentiles of the tracking commands: from the plant's joint measurement to the
/// hand command it caused, and its parts, from the commands' traces
/// ([`icrflow_interfaces::Trace`]).
#[derive(Debug, Serialize, Default)]
pub struct Latencies {
    /// Joint measurement published to hand command published.
    pub end_to_end: Percentiles,
    /// Each hop's transport: publication to the next process taking the message off the bus
    /// (iceoryx2 delivery, the event that wakes the receiver, and its scheduling).
    pub transport: Hops,
    /// Each process's computation: input taken off the bus to output published.
    pub compute: Stages,
}

/// Per-hop transport latencies of the critical path.
#[derive(Debug, Serialize, Default)]
pub struct Hops {
    /// Plant to estimator.
    pub joint_state: Percentiles,
    /// Estimator to wrench-space node.
    pub grasp_state: Percentiles,
    /// Wrench-space node to hand command node.
    pub wrench_space: Percentiles,
}

/// Per-process computation latencies of the critical path.
#[derive(Debug, Serialize, Default)]
pub struct Stages {
    /// Joint state to grasp state.
    pub estimator: Percentiles,
    /// Grasp state to wrench space.
    pub wrench: Percentiles,
    /// Wrench space (with its grasp state and the plan step) to hand command.
    pub command: Percentiles,
}

/// The plan-step stream.
#[derive(Debug, Serialize, Default)]
pub struct PlanStream {
    /// Plan steps published (the current target at the stream's rate, and each new one).
    pub published: u64,
    /// Mean rate while the stream flows, from the first step the run saw to the last (Hz).
    pub rate_hz: f64,
    /// The planner's time from taking up a step to publishing it (us).
    pub compute_us: Percentiles,
}

/// Resident memory of one process over the run (KiB).
#[derive(Debug, Serialize, Default, Clone, Copy)]
pub struct Memory {
    /// At the first sample.
    pub first: u64,
    /// At the last sample.
    pub last: u64,
    /// The largest sample.
    pub max: u64,
    /// Samples.
    pub samples: usize,
}

/// A node's heap allocations in its steady state, from its health reports: counted from its
/// first report [`WARM_UP`] after its process started (each incarnation of a restarted node
/// on its own), to its last.
#[derive(Debug, Serialize, Default, Clone, Copy)]
pub struct Allocations {
    /// Allocations (and reallocations) in the steady state.
    pub steady: u64,
    /// Messages the node processed meanwhile.
    pub processed: u64,
    /// Seconds of steady state observed.
    pub seconds: f64,
}

/// How long after a node process starts its allocations are not counted as steady state
/// (setup: planning, buffers, the first contact sets).
pub const WARM_UP: Duration = Duration::from_secs(2);

/// Per node: the running process's first health report, its baseline (the first report after
/// [`WARM_UP`]: allocations, processed, when) and its last; plus the finished incarnations'
/// steady-state figures.
#[derive(Default)]
struct AllocationTrack {
    pid: u32,
    first: Option<Instant>,
    base: Option<(u64, u64, Instant)>,
    last: Option<(u64, u64, Instant)>,
    done: Allocations,
}

impl AllocationTrack {
    fn report(&mut self, pid: u32, allocations: u64, processed: u64, now: Instant) {
        if pid != self.pid {
            self.done = self.total();
            *self = Self {
                pid,
                first: Some(now),
                done: self.done,
                ..Self::default()
            };
        }
        if self.base.is_none() && self.first.is_some_and(|f| now.duration_since(f) >= WARM_UP) {
            self.base = Some((allocations, processed, now));
        }
        self.last = Some((allocations, processed, now));
    }

    fn total(&self) -> Allocations {
        let mut a = self.done;
        if let (Some((allocations, processed, when)), Some(last)) = (self.base, self.last) {
            a.steady += last.0.saturating_sub(allocations);
            a.processed += last.1.saturating_sub(processed);
            a.seconds += last.2.duration_since(when).as_secs_f64();
        }
        a
    }
}

/// The resident set size of process `pid` (KiB), from `/proc`.
fn resident_kib(pid: u32) -> Option<u64> {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).ok()?;
    status
        .lines()
        .find_map(|l| l.strip_prefix("VmRSS:"))?
        .split_whitespace()
        .next()?
        .parse()
        .ok()
}

/// Latency samples of the critical path, from the traces of the tracking commands.
struct Timing {
    end_to_end: Histogram,
    hops: [Histogram; 3],
    stages: [Histogram; 3],
}

impl Timing {
    fn new() -> Self {
        Self {
            end_to_end: Histogram::new(),
            hops: std::array::from_fn(|_| Histogram::new()),
            stages: std::array::from_fn(|_| Histogram::new()),
        }
    }

    /// Adds a tracking command's trace `[measured, estimator in, out, wrench in, out,
    /// command in, out]`; other traces (a chain cut by a restart) are skipped.
    fn add(&mut self, trace: &[u64]) {
        let &[t0, ..] = trace else { return };
        if trace.len() != icrflow_interfaces::TRACE_STAMPS {
            return;
        }
        let us = |a: u64, b: u64| b.saturating_sub(a) as f64 * 1e-3;
        self.end_to_end.add(us(t0, trace[6]));
        for k in 0..3 {
            self.hops[k].add(us(trace[2 * k], trace[2 * k + 1]));
            self.stages[k].add(us(trace[2 * k + 1], trace[2 * k + 2]));
        }
    }

    fn summary(&self) -> Latencies {
        let [h0, h1, h2] = &self.hops;
        let [s0, s1, s2] = &self.stages;
        Latencies {
            end_to_end: self.end_to_end.percentiles(),
            transport: Hops {
                joint_state: h0.percentiles(),
                grasp_state: h1.percentiles(),
                wrench_space: h2.percentiles(),
            },
            compute: Stages {
                estimator: s0.percentiles(),
                wrench: s1.percentiles(),
                command: s2.percentiles(),
            },
        }
    }
}

pub(crate) fn node_program(name: &str) -> Result<PathBuf> {
    let exe = std::env::current_exe().context("locating the icrflow executable")?;
    let dir = exe
        .parent()
        .context("the icrflow executable has no directory")?;
    let path = dir.join(format!("icrflow-{name}"));
    if !path.is_file() {
        bail!(
            "node binary {} not found beside icrflow: build them with `cargo build --release --workspace`",
            path.display()
        );
    }
    Ok(path)
}

/// Refuses `pipeline.slip_deg` on a section other than a circle: the simulated slip turns the
/// object under fingertips that stay where they are, which keeps them on it only when the
/// section is a circle about the centre.
pub fn slip(config: &Config, surface: &Surface) -> Result<()> {
    if config.pipeline.slip != 0.0 && !matches!(surface, Surface::Circle { .. }) {
        anyhow::bail!(
            "pipeline.slip_deg: the simulated slip turns the object under fingertips that stay \
             where they are, which keeps them on it only for a circular section; this object's \
             is {}",
            surface.describe()
        );
    }
    Ok(())
}

/// Runs the verb; returns the exit code.
pub fn run(path: &Path, live: bool, summary_json: Option<PathBuf>, viewer: Viewer) -> Result<u8> {
    // From the start: a hang-up while the config loads stops the run as one later would.
    let hangup = Hangup::install()?;
    crate::output::check(&crate::output::run(&summary_json, &viewer.rrd))?;
    let config = Config::load(path)?;
    let recording = viewer.recording(&config)?;
    let setup = Setup::new(&config)?;
    slip(&config, setup.surface()?)?;
    setup.scenario(&config).start().context("cannot start")?;
    let config_path = std::fs::canonicalize(path)
        .with_context(|| format!("cannot resolve {}", path.display()))?;
    // The loop's nodes run their loops under SCHED_FIFO where the machine allows it (each
    // switches once its start-up is done); otherwise that is said once, and they run at
    // normal priority.
    let realtime = match config.pipeline.realtime_priority {
        0 => None,
        p if config
            .pipeline
            .nodes
            .iter()
            .any(|n| REALTIME_NODES.contains(&n.as_str())) =>
        {
            match icrflow_runtime::node::realtime_allowed(p) {
                Ok(()) => Some(p),
                Err(why) => {
                    eprintln!(
                        "run: pipeline.realtime_priority = {p} is not available here ({why:#}); the loop's nodes run at normal priority"
                    );
                    None
                }
            }
        }
        _ => None,
    };
    let mut specs = Vec::new();
    for n in &config.pipeline.nodes {
        specs.push(NodeSpec {
            name: n.into(),
            program: node_program(n)?,
            args: vec!["--config".into(), config_path.display().to_string()],
            policy: RestartPolicy::default(),
            essential: true,
            env: match realtime {
                Some(p) if REALTIME_NODES.contains(&n.as_str()) => {
                    vec![(icrflow_runtime::node::ENV_REALTIME.into(), p.to_string())]
                }
                _ => Vec::new(),
            },
        });
    }
    if config.zenoh.enabled {
        // Remote monitoring, and the loop topics of the nodes on other hosts when
        // `pipeline.nodes` runs only some here. Monitoring alone, the run goes on without the
        // bridge if it fails for good; a split loop cannot.
        specs.push(NodeSpec {
            name: BRIDGE.into(),
            program: node_program(BRIDGE)?,
            args: vec!["--config".into(), config_path.display().to_string()],
            policy: RestartPolicy::default(),
            essential: config.pipeline.split(),
            env: Vec::new(),
        });
    }
    if config.pipeline.split() {
        let links = topics::links(&config.pipeline.nodes);
        eprintln!(
            "run: this host runs {}; the others are joined over Zenoh (sending {:?}, taking {:?})",
            config.pipeline.nodes.join(", "),
            links.export,
            links.import
        );
    }
    let recording_id = format!(
        "icrflow-{}-{}-{}",
        config.pipeline.rig,
        std::process::id(),
        icrflow_interfaces::now_ns() / 1_000_000
    );
    if let Some(r) = &recording {
        if let Recording::Rrd(p) = r {
            // This run's output: an older recording of that name is replaced, with the parts
            // a restarted visualizer of that run wrote beside it.
            for part in icrflow_scenario::rrd_parts(p) {
                std::fs::remove_file(&part)
                    .with_context(|| format!("replacing {}", part.display()))?;
            }
        }
        // It never holds the run: it may fail for good without failing it.
        // At a lower CPU priority (nice 10, through coreutils' `nice`, which execs it under
        // the same pid): on a busy machine the loop's nodes go first, the recording waits.
        let program = node_program(VISUALIZER)?;
        let nice = Path::new(NICE);
        let (program, mut args) = if nice.is_file() {
            (
                nice.to_path_buf(),
                vec!["-n".into(), "10".into(), program.display().to_string()],
            )
        } else {
            (program, Vec::new())
        };
        args.extend(["--config".into(), config_path.display().to_string()]);
        specs.push(NodeSpec {
            name: VISUALIZER.into(),
            program,
            args,
            policy: RestartPolicy::default(),
            essential: false,
            env: [
                (icrflow_scenario::ENV_RECORDING.into(), r.to_env()),
                (
                    icrflow_scenario::ENV_RECORDING_ID.into(),
                    recording_id.clone(),
                ),
            ]
            .into_iter()
            // A live run's recording has no end in sight: Rerun's index footer (every chunk's
            // place, held in memory until the file closes: ~1.3 GB an hour here) is left out.
            .chain(live.then(|| (icrflow_scenario::ENV_RECORDING_FOOTER.into(), "0".into())))
            .collect(),
        });
    }
    let names: Vec<String> = specs.iter().map(|s| s.name.clone()).collect();
    let bus_config = run_bus(&config.pipeline.rig, std::process::id())?;
    set_log_level(LogLevel::Warn);
    // A run that was killed outright (SIGKILL, power loss) leaves its bus and the plant's and
    // estimator's checkpoints behind under its pid; a later run given the same pid must not
    // resume from them. No live process has our pid, so what is there is stale.
    bus_config.remove_files();
    let swept = sweep_killed_runs(&config.pipeline.rig);
    if !swept.is_empty() {
        eprintln!("run: removed what killed runs left in {RUNS_DIR} (pids {swept:?})");
    }
    let mut supervisor = Supervisor::new(bus_config.clone(), specs, false);
    let started = Instant::now();
    let goal = config.plan.goal;
    let alpha = config.grasp.alpha;
    // The bus, its ports and the WaitSet live in this block, so that they are gone before the
    // run's iceoryx2 directory is removed.
    let stats = {
        let bus = Bus::new("run", &bus_config)?;
        let plans = bus.slice_subscriber(topics::PLAN_STEP)?;
        // Read on the run's own tick (only the newest matters), so they cost no wake-up.
        let grasps = bus.subscriber(topics::GRASP_STATE)?;
        let joints = bus.subscriber(topics::JOINT_STATE)?;
        // Joint measurements, counted by their sequence numbers (one per measurement; a
        // restarted plant starts higher up).
        let (mut measurements, mut last_joint) = (0u64, 0u64);
        let (mut measurement_rate, mut command_rate, mut plan_rate) =
            (Rate::default(), Rate::default(), Rate::default());
        let commands = bus.subscriber(topics::HAND_COMMAND)?;
        // Read on the run's tick: the nodes' allocation counts.
        let healths = bus.subscriber(topics::NODE_HEALTH)?;
        let mut tracks = std::collections::BTreeMap::<String, AllocationTrack>::new();
        // The visualizer's frames recorded and dropped, per process (a restart counts anew).
        let mut frames = std::collections::BTreeMap::<u32, (u64, u64)>::new();
        // Every node's heartbeat (its health reports): a silent one is said, a hung one
        // restarted after pipeline.hung_restart_s.
        let mut beats = Heartbeats::default();
        let hung_restart = Duration::from_secs_f64(config.pipeline.hung_restart);
        // The simulated plant's truth, against which the estimate is measured.
        let truths = bus.subscriber(topics::PLANT_TRUTH)?;
        let mut truth = TruthTrack::default();
        let estimate_bound = config.pipeline.max_pose_innovation;
        let mut estimate_holds = 0u64;
        // Whether the last command was a hold for the estimate.
        let mut doubting = false;
        let mut replan_progress = ReplanProgress::default();
        let mut gave_up: Option<String> = None;
        // The visualizer listens before the loop begins, or its recording would miss the
        // first plan steps (it starts at a lower priority, and sets up as long as a node).
        let mut waited = VisualizerStart::Listening;
        if recording.is_some() {
            for e in supervisor.start_first(VISUALIZER)? {
                report(&e);
            }
            waited = visualizer_listening(&bus, &mut supervisor, &healths, &hangup, |h| {
                take_health(h, Instant::now(), &mut frames, &mut tracks, &mut beats)
            })?;
            match waited {
                VisualizerStart::Late => eprintln!(
                    "run: the visualizer is not listening after {} s; the loop starts without it (its recording may miss the first plan steps)",
                    VISUALIZER_READY.as_secs()
                ),
                VisualizerStart::Exited => eprintln!(
                    "run: the visualizer exited before it listened; the loop starts without it (the supervisor restarts it)"
                ),
                VisualizerStart::Listening | VisualizerStart::Interrupted => {}
            }
        }
        // Interrupted meanwhile: the loop below ends at once, as on a Ctrl-C.
        if waited != VisualizerStart::Interrupted {
            for e in supervisor.start()? {
                report(&e);
            }
        }
        let timeout = Duration::from_secs(600);
        let mut last_step = 0u64;
        let mut attaches = std::collections::BTreeSet::new();
        let mut replans = std::collections::BTreeSet::new();
        let mut min_quality = f64::INFINITY;
        let mut rotation = 0.0;
        let (mut holds, mut sent, mut stale_tracked) = (0u64, 0u64, 0u64);
        // What the hand command node guarantees at publication, plus an allowance for the
        // delivery to this process.
        let max_age_ns = (config.pipeline.max_input_age * 1e9) as u64 + 10_000_000;
        let mut done = false;
        let mut reason = String::new();
        let mut timing = Timing::new();
        // Since when the hand holds, when that was last reported, and the last hold's reason.
        let mut holding: Option<(Instant, Instant)> = None;
        let mut hold_reason = [0u8; icrflow_interfaces::TEXT_BYTES];
        let max_hold = Duration::from_secs_f64(config.pipeline.max_hold);
        // The newest plan step and since when (the plan goes on while its steps advance).
        let mut progress = (0u64, Instant::now());
        let (mut plan_published, mut plan_compute) = (0u64, Histogram::new());
        let mut memory = std::collections::BTreeMap::<String, Memory>::new();
        let mut policies = std::collections::BTreeMap::<String, String>::new();
        let mut next_sample = Instant::now() + Duration::from_secs(1);

        let ws = WaitSetBuilder::new().create::<ipc::Service>()?;
        let _plans = ws.attach_notification(plans.listener())?;
        let _commands = ws.attach_notification(commands.listener())?;
        let tick = ws.attach_interval(icrflow_runtime::event::RESYNC)?;
        let mut failure = None;
        let mut on_event = |id: WaitSetAttachmentId<ipc::Service>| {
            let mut step = || -> Result<bool> {
                // Every wake-up reads every input (see icrflow_runtime::event::serve).
                plans.drain(|p, _| {
                    plan_published += 1;
                    if let [.., taken, published] = p.header.trace.as_slice() {
                        plan_compute.add(published.saturating_sub(*taken) as f64 * 1e-3);
                    }
                    if p.phase == PlanPhase::Done as u32 {
                        done = true;
                    } else {
                        last_step = last_step.max(p.step);
                        if p.step != progress.0 {
                            progress = (p.step, Instant::now());
                        }
                        if p.phase == PlanPhase::Attach as u32 {
                            attaches.insert(p.step);
                        }
                        if p.phase == PlanPhase::Start as u32
                            && p.step > 0
                            && replans.insert(p.step)
                            && let Some(why) = replan_progress.replanned(p.rotation)
                        {
                            gave_up.get_or_insert(why);
                        }
                    }
                })?;
                {
                    commands.drain(|c| {
                        sent += 1;
                        if c.mode == CommandMode::Track as u32 {
                            if let Some((since, _)) = holding.take()
                                && since.elapsed() >= HOLD_REPORT
                            {
                                eprintln!(
                                    "run: the hand tracks again after holding {:.1} s",
                                    since.elapsed().as_secs_f64()
                                );
                            }
                            min_quality = min_quality.min(c.quality);
                            truth.tracked(1, estimate_bound);
                            doubting = false;
                            timing.add(c.header.trace.as_slice());
                            if c.header.origin_time_ns > 0 {
                                let made = c.header.source_time_ns;
                                if made.saturating_sub(c.header.origin_time_ns) > max_age_ns {
                                    stale_tracked += 1;
                                }
                            }
                        } else {
                            holds += 1;
                            hold_reason = c.reason;
                            if c.reason.starts_with(ESTIMATE_OFF.as_bytes()) {
                                estimate_holds += 1;
                                // Said at once, once a spell: the loop noticed its estimate
                                // is wrong.
                                if !doubting {
                                    eprintln!("run: the hand holds: {}", read_text(&c.reason));
                                }
                                doubting = true;
                            } else {
                                doubting = false;
                            }
                            // A hold longer than HOLD_REPORT is reported (with its reason),
                            // then every HOLD_REPORT again; short ones only count.
                            let now = Instant::now();
                            let (since, reported) = holding.get_or_insert((now, now));
                            if now.duration_since(*reported) >= HOLD_REPORT {
                                *reported = now;
                                eprintln!(
                                    "run: the hand has held for {:.1} s: {}",
                                    now.duration_since(*since).as_secs_f64(),
                                    read_text(&c.reason)
                                );
                            }
                        }
                    })?;
                    command_rate.saw(sent);
                    plan_rate.saw(plan_published);
                }
                if id.has_event_from(&tick) {
                    if let Some(j) = joints.latest()? {
                        let gap = j.header.sequence.wrapping_sub(last_joint);
                        measurements += if last_joint > 0 && gap < 1_000_000 {
                            gap
                        } else {
                            1
                        };
                        last_joint = j.header.sequence;
                        measurement_rate.saw(measurements);
                    }
                    if let Some(g) = grasps.latest()? {
                        rotation = g.rotation;
                        truth.estimate(&g);
                    }
                    let now = Instant::now();
                    healths.drain(|h| take_health(h, now, &mut frames, &mut tracks, &mut beats))?;
                    truths.drain(|t| truth.truth(t))?;
                    for e in supervisor.poll(Instant::now())? {
                        report(&e);
                    }
                    for s in beats.check(Instant::now(), hung_restart, |n| supervisor.pid(n)) {
                        silence(&s, &mut supervisor, config.pipeline.hung_restart);
                    }
                    if hangup.came() {
                        reason = "stopped by SIGHUP (the terminal closed)".into();
                        return Ok(false);
                    }
                    if let Some(why) = gave_up.take() {
                        reason = why;
                        return Ok(false);
                    }
                    if Instant::now() >= next_sample {
                        next_sample += Duration::from_secs(1);
                        for n in &names {
                            if let Some(policy) = supervisor.pid(n).and_then(scheduling) {
                                policies.insert(n.clone(), policy);
                            }
                            if let Some(kib) = supervisor.pid(n).and_then(resident_kib) {
                                let m = memory.entry(n.clone()).or_insert(Memory {
                                    first: kib,
                                    ..Memory::default()
                                });
                                m.last = kib;
                                m.max = m.max.max(kib);
                                m.samples += 1;
                            }
                        }
                    }
                    if let Some(n) = supervisor.failed() {
                        reason = format!("node {n} failed too often");
                        return Ok(false);
                    }
                    if started.elapsed() > timeout {
                        reason = format!("timed out after {timeout:?}");
                        return Ok(false);
                    }
                    // Nor on a plan that does not go on while the hand tracks (a target it
                    // never reaches, and the planner node does not plan again).
                    // A plan that ended short of the goal (a plan made again from the estimate
                    // may) does not go on either.
                    let short = rotation < goal - 0.5f64.to_radians();
                    if !live
                        && (!done || short)
                        && holding.is_none()
                        && progress.1.elapsed() >= max_hold
                    {
                        reason = if done {
                            format!(
                                "gave up: the plan ended at step {} with the object at {:.1} deg, short of the goal (see the planner's messages)",
                                progress.0,
                                rotation.to_degrees()
                            )
                        } else {
                            format!(
                                "gave up: no plan step after step {} for {:.1} s (pipeline.max_hold_s); the object at {:.1} deg",
                                progress.0,
                                progress.1.elapsed().as_secs_f64(),
                                rotation.to_degrees()
                            )
                        };
                        return Ok(false);
                    }
                    // A run to the goal does not wait for ever on a hand that cannot go on.
                    if let Some((since, _)) = holding
                        && !live
                        && since.elapsed() >= max_hold
                    {
                        reason = format!(
                            "gave up: the hand held for {:.1} s (pipeline.max_hold_s): {}",
                            since.elapsed().as_secs_f64(),
                            read_text(&hold_reason)
                        );
                        return Ok(false);
                    }
                }
                if done && !live && rotation >= goal - 0.5f64.to_radians() {
                    reason = "goal reached".into();
                    return Ok(false);
                }
                Ok(true)
            };
            match step() {
                Ok(true) => CallbackProgression::Continue,
                Ok(false) => CallbackProgression::Stop,
                Err(e) => {
                    failure = Some(e);
                    CallbackProgression::Stop
                }
            }
        };
        // A signal other than SIGTERM, SIGINT or SIGHUP (SIGCONT, SIGWINCH, ...) only
        // interrupts the wait: on.
        let outcome = loop {
            match ws.wait_and_process(&mut on_event) {
                Ok(WaitSetRunResult::Interrupt) if !hangup.came() => continue,
                other => break other,
            }
        };
        if reason.is_empty() {
            reason = match outcome {
                Ok(WaitSetRunResult::Interrupt) => "stopped by SIGHUP (the terminal closed)".into(),
                Ok(WaitSetRunResult::TerminationRequest) => {
                    "stopped by a signal (Ctrl-C or SIGTERM)".into()
                }
                other => format!("{other:?}"),
            };
        }
        // The grace period lets the visualizer write the end of its recording.
        let killed = supervisor.shutdown(Duration::from_secs(5));
        if !killed.is_empty() {
            eprintln!("run: killed after the grace period: {killed:?}");
        }
        // The visualizer's last report, as it stopped.
        healths.drain(|h| {
            if read_text(&h.node) == VISUALIZER {
                frames.insert(h.pid, (h.processed, h.refused));
            }
        })?;
        if let Some(e) = failure {
            return Err(e);
        }
        Stats {
            done,
            reason,
            rotation,
            attaches: attaches.len(),
            replans: replans.len(),
            steps: last_step as usize,
            min_quality,
            holds,
            sent,
            measurements,
            stale_tracked,
            latencies: timing.summary(),
            measurement_rate_hz: measurement_rate.hz(),
            command_rate_hz: command_rate.hz(),
            plan_steps: PlanStream {
                published: plan_published,
                rate_hz: plan_rate.hz(),
                compute_us: plan_compute.percentiles(),
            },
            memory,
            scheduling: policies,
            allocations: tracks.iter().map(|(n, t)| (n.clone(), t.total())).collect(),
            estimate: truth.summary(),
            estimate_holds,
            frames: frames
                .values()
                .fold((0, 0), |(a, b), (p, r)| (a + p, b + r)),
        }
    };
    bus_config.remove_files();
    let summary = RunSummary {
        completed: stats.done && stats.rotation >= goal - 0.5f64.to_radians(),
        reason: stats.reason,
        rotation_deg: stats.rotation.to_degrees(),
        goal_deg: goal.to_degrees(),
        switches: stats.attaches,
        replans: stats.replans,
        steps: stats.steps,
        min_quality: if stats.min_quality.is_finite() {
            stats.min_quality
        } else {
            0.0
        },
        alpha,
        restarts: supervisor.restarts(),
        holds: stats.holds,
        commands: stats.sent,
        measurements: stats.measurements,
        measurement_rate_hz: stats.measurement_rate_hz,
        command_rate_hz: stats.command_rate_hz,
        stale_tracked: stats.stale_tracked,
        seconds: started.elapsed().as_secs_f64(),
        bus_prefix: bus_config.prefix.clone(),
        bus_root: bus_config.root.display().to_string(),
        latency_us: stats.latencies,
        plan_steps: stats.plan_steps,
        memory_kib: stats.memory,
        scheduling: stats.scheduling,
        allocations: stats.allocations,
        estimate: stats.estimate,
        estimate_holds: stats.estimate_holds,
        recording: recording.as_ref().map(|r| RecordingSummary {
            target: target_name(r),
            id: recording_id.clone(),
            frames: stats.frames.0,
            dropped: stats.frames.1,
        }),
    };
    let mut o = std::io::stdout().lock();
    writeln!(
        o,
        "run        {} ({})",
        config_path.display(),
        summary.reason
    )?;
    writeln!(
        o,
        "rotation   {:.1} deg of {:.1} deg, {} plan steps, {} finger switches{}",
        summary.rotation_deg,
        summary.goal_deg,
        summary.steps,
        summary.switches,
        match summary.replans {
            0 => String::new(),
            n => format!(", planned again from the estimate {n} time(s)"),
        }
    )?;
    if config.pipeline.nodes.iter().any(|n| n == "command") {
        writeln!(
            o,
            "quality    minimum alpha* while tracking = {:.6} (alpha = {alpha})",
            summary.min_quality
        )?;
        if let Some(e) = &summary.estimate {
            writeln!(
                o,
                "estimate   off the plant's truth p50 {:.2} / p99 {:.2} / max {:.2} deg; {} tracking commands beyond the bound ({} deg), {} holds for the estimate",
                e.rotation_deg.p50,
                e.rotation_deg.p99,
                e.rotation_deg.max,
                e.tracked_off_truth,
                config.pipeline.max_pose_innovation.to_degrees(),
                summary.estimate_holds
            )?;
        }
        writeln!(
            o,
            "commands   {} sent ({:.0} Hz; {:.0} Hz of joint measurements), {} holds; {} node restarts; {:.1} s",
            summary.commands,
            summary.command_rate_hz,
            summary.measurement_rate_hz,
            summary.holds,
            summary.restarts,
            summary.seconds
        )?;
        let l = &summary.latency_us;
        writeln!(
            o,
            "latency    joint measurement to hand command p50 {:.0} us, p99 {:.0} us, max {:.0} us ({} commands)",
            l.end_to_end.p50, l.end_to_end.p99, l.end_to_end.max, l.end_to_end.samples
        )?;
        writeln!(
            o,
            "           hops p50 {:.0} / {:.0} / {:.0} us, compute p50 {:.0} / {:.0} / {:.0} us (estimator, wrench space, command)",
            l.transport.joint_state.p50,
            l.transport.grasp_state.p50,
            l.transport.wrench_space.p50,
            l.compute.estimator.p50,
            l.compute.wrench.p50,
            l.compute.command.p50
        )?;
    } else {
        writeln!(
            o,
            "commands   none here: the hand command node runs on another host (its run reports them)"
        )?;
    }
    writeln!(
        o,
        "plan       {} plan steps published, {:.0} Hz",
        summary.plan_steps.published, summary.plan_steps.rate_hz
    )?;
    let grew: Vec<String> = summary
        .memory_kib
        .iter()
        .map(|(n, m)| format!("{n} {}->{} KiB", m.first, m.last))
        .collect();
    writeln!(o, "memory     {}", grew.join(", "))?;
    let realtime: Vec<&str> = summary
        .scheduling
        .iter()
        .filter(|(_, p)| p.starts_with("fifo") || p.starts_with("rr"))
        .map(|(n, _)| n.as_str())
        .collect();
    if let Some(policy) = realtime.first().and_then(|n| summary.scheduling.get(*n)) {
        writeln!(
            o,
            "priority   {} at SCHED_{}",
            realtime.join(", "),
            policy.to_uppercase()
        )?;
    }
    let allocs: Vec<String> = summary
        .allocations
        .iter()
        .map(|(n, a)| format!("{n} {} in {:.0} s", a.steady, a.seconds))
        .collect();
    writeln!(
        o,
        "allocs     steady state (from {} s after each start): {}",
        WARM_UP.as_secs(),
        allocs.join(", ")
    )?;
    if let Some(r) = &summary.recording {
        let open = match &recording {
            Some(Recording::Rrd(p)) => {
                let names: Vec<String> = icrflow_scenario::rrd_parts(p)
                    .iter()
                    .map(|f| f.display().to_string())
                    .collect();
                if names.is_empty() {
                    format!(
                        "none: the visualizer wrote no {} (see its messages above)",
                        p.display()
                    )
                } else {
                    format!(
                        "saved to {} (open it: rerun {})",
                        names.join(", "),
                        names.join(" ")
                    )
                }
            }
            _ => format!("streamed to the {}", r.target),
        };
        writeln!(
            o,
            "recording  {open}; {} frames, {} dropped",
            r.frames, r.dropped
        )?;
    }
    if let Some(p) = summary_json {
        let text = serde_json::to_string_pretty(&summary)?;
        std::fs::write(&p, text + "\n").with_context(|| format!("writing {}", p.display()))?;
    }
    // A live run ends by Ctrl-C: that is success if nothing failed.
    let interrupted = live && summary.reason.starts_with("stopped by");
    Ok(if summary.completed || interrupted {
        0
    } else {
        2
    })
}

/// A stream's rate while it flows: what its count grew by between the first and the last time
/// it was seen to grow, over that time.
#[derive(Default)]
struct Rate {
    first: Option<(Instant, u64)>,
    last: Option<(Instant, u64)>,
}

impl Rate {
    /// The count is now `total`.
    fn saw(&mut self, total: u64) {
        if total == 0 || self.last.is_some_and(|(_, n)| n == total) {
            return;
        }
        let now = Instant::now();
        self.first.get_or_insert((now, total));
        self.last = Some((now, total));
    }

    /// Per second between the first and the last sighting (0 before two).
    fn hz(&self) -> f64 {
        match (self.first, self.last) {
            (Some((t0, n0)), Some((t1, n1))) if t1 > t0 => {
                (n1 - n0) as f64 / t1.duration_since(t0).as_secs_f64()
            }
            _ => 0.0,
        }
    }
}

/// What the run saw.
struct Stats {
    /// The visualizer's frames recorded and dropped.
    frames: (u64, u64),
    done: bool,
    reason: String,
    rotation: f64,
    attaches: usize,
    replans: usize,
    steps: usize,
    min_quality: f64,
    holds: u64,
    sent: u64,
    measurements: u64,
    measurement_rate_hz: f64,
    command_rate_hz: f64,
    stale_tracked: u64,
    latencies: Latencies,
    plan_steps: PlanStream,
    memory: std::collections::BTreeMap<String, Memory>,
    scheduling: std::collections::BTreeMap<String, String>,
    allocations: std::collections::BTreeMap<String, Allocations>,
    estimate: Option<EstimateError>,
    estimate_holds: u64,
}

/// Where runs keep their iceoryx2 files: `run-PID` each.
const RUNS_DIR: &str = "/tmp/icrflow";

/// The bus of the run whose process is `pid`.
fn run_bus(rig: &str, pid: u32) -> Result<BusConfig> {
    Ok(BusConfig::new(
        rig,
        &format!("icr{pid}_"),
        PathBuf::from(format!("{RUNS_DIR}/run-{pid}")),
    )?)
}

/// Removes what runs killed outright left (their bus files, shared memory and checkpoints):
/// those whose process is gone and none of whose iceoryx2 nodes is alive (their nodes stop
/// when the run dies, see `runtime::ENV_SUPERVISOR`). Returns their pids.
fn sweep_killed_runs(rig: &str) -> Vec<u32> {
    let Ok(dir) = std::fs::read_dir(RUNS_DIR) else {
        return Vec::new();
    };
    let mut swept = Vec::new();
    for e in dir.flatten() {
        let name = e.file_name();
        let Some(pid) = name
            .to_str()
            .and_then(|n| n.strip_prefix("run-"))
            .and_then(|p| p.parse::<u32>().ok())
        else {
            continue;
        };
        if pid == std::process::id() || Path::new(&format!("/proc/{pid}")).exists() {
            continue;
        }
        let Ok(bus) = run_bus(rig, pid) else { continue };
        if icrflow_runtime::supervise::live_nodes(&bus) != Some(0) {
            continue;
        }
        // All its files go, dead iceoryx2 nodes' resources with them.
        bus.remove_files();
        swept.push(pid);
    }
    swept.sort_unstable();
    swept
}

/// Takes a node's health report, taken off the bus at `now`: its allocations into its track,
/// and the visualizer's frames recorded and dropped (per process).
fn take_health(
    h: &NodeHealth,
    now: Instant,
    frames: &mut std::collections::BTreeMap<u32, (u64, u64)>,
    tracks: &mut std::collections::BTreeMap<String, AllocationTrack>,
    beats: &mut Heartbeats,
) {
    let node = read_text(&h.node);
    beats.beat(&node, h.pid, now);
    if node == VISUALIZER {
        frames.insert(h.pid, (h.processed, h.refused));
    }
    tracks
        .entry(node)
        .or_default()
        .report(h.pid, h.allocations, h.processed, now);
}

/// How long `run` waits for the visualizer to listen before it starts the loop anyway.
pub const VISUALIZER_READY: Duration = Duration::from_secs(15);

/// How waiting for the visualizer ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum VisualizerStart {
    /// It reported its health: it has subscribed to its inputs.
    Listening,
    /// It did not report within [`VISUALIZER_READY`] (the run goes on without it: the
    /// visualizer never holds the run).
    Late,
    /// It exited before it reported (the run goes on; the supervisor restarts it).
    Exited,
    /// Ctrl-C or SIGTERM came meanwhile.
    Interrupted,
}

/// Waits until the visualizer, started alone, reports its health (it subscribes to its
/// inputs before its first report), at most [`VISUALIZER_READY`]; `seen` takes its reports.
fn visualizer_listening(
    bus: &Bus,
    supervisor: &mut Supervisor,
    healths: &Sub<NodeHealth>,
    hangup: &Hangup,
    mut seen: impl FnMut(&NodeHealth),
) -> Result<VisualizerStart> {
    let deadline = Instant::now() + VISUALIZER_READY;
    let mut listening = false;
    while Instant::now() < deadline {
        healths.drain(|h| {
            if read_text(&h.node) == VISUALIZER {
                listening = true;
                seen(h);
            }
        })?;
        if listening {
            return Ok(VisualizerStart::Listening);
        }
        let events = supervisor.poll(Instant::now())?;
        for e in &events {
            report(e);
        }
        if events.iter().any(|e| matches!(e, Event::Exited { .. })) {
            return Ok(VisualizerStart::Exited);
        }
        // Sleeps (a signal cuts it short); SIGTERM, SIGINT or SIGHUP stop the run.
        let _ = bus.node().wait(Duration::from_millis(5));
        if icrflow_runtime::event::termination_requested(bus.node()) || hangup.came() {
            return Ok(VisualizerStart::Interrupted);
        }
    }
    Ok(VisualizerStart::Late)
}

/// The text a hold because of the estimate starts with (the command node's
/// `Hold::Estimate`).
const ESTIMATE_OFF: &str = "the estimate is off";

/// Says what a node's silence is, and kills a hung node (the supervisor restarts it).
fn silence(s: &Silence, supervisor: &mut Supervisor, restart_s: f64) {
    match s {
        Silence::Silent { name, pid, since } => eprintln!(
            "run: node {name} (pid {pid}) has sent no heartbeat for {:.1} s: hung or stopped? (restarted after {restart_s} s: pipeline.hung_restart_s)",
            since.as_secs_f64()
        ),
        Silence::Hung { name, pid, since } => {
            supervisor.kill(name);
            eprintln!(
                "run: node {name} (pid {pid}) has sent no heartbeat for {:.1} s: killed, to be restarted",
                since.as_secs_f64()
            );
        }
        Silence::Back { name, after } => eprintln!(
            "run: node {name} sends heartbeats again after {:.1} s",
            after.as_secs_f64()
        ),
    }
}

fn report(e: &Event) {
    match e {
        Event::Started { name, pid, attempt } if *attempt > 0 => {
            eprintln!("run: restarted {name} (pid {pid}, restart {attempt})")
        }
        Event::Started { .. } => {}
        Event::Exited {
            name,
            status,
            cleaned,
        } => eprintln!("run: node {name} exited ({status}); cleaned {cleaned} dead iceoryx2 nodes"),
        Event::GaveUp { name, reason } if name == BRIDGE => eprintln!(
            "run: giving up on {name}: {reason}; the run goes on without Zenoh monitoring"
        ),
        Event::GaveUp { name, reason } => eprintln!("run: giving up on {name}: {reason}"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn histogram_percentiles_are_within_one_percent_above_the_exact_ones() {
        // Latency-like samples from 0.3 us to ~60 ms (a deterministic spread).
        let mut exact: Vec<f64> = (0..20_000u64)
            .map(|i| 0.3 * (1.0 + (i * 7919 % 20_000) as f64).powf(1.3))
            .collect();
        let mut h = Histogram::new();
        for &x in &exact {
            h.add(x);
        }
        exact.sort_by(f64::total_cmp);
        let p = h.percentiles();
        assert_eq!(p.samples, exact.len());
        assert_eq!(p.max, exact[exact.len() - 1]);
        for (q, got) in [(0.5, p.p50), (0.99, p.p99)] {
            let want = exact[(q * exact.len() as f64).ceil() as usize - 1];
            assert!(
                got >= want && got <= want.max(1.0) * 1.01,
                "q {q}: {got} vs exact {want}"
            );
        }
        assert_eq!(Histogram::new().percentiles().samples, 0);
    }
}
