//! `icrflow run CONFIG [--live] [--summary-json PATH]`: the pipeline, one process per node,
//! supervised, on an iceoryx2 bus of its own, until the scenario's goal (or Ctrl-C).

use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use anyhow::{Context, Result, bail};
use iceoryx2::prelude::*;
use iceoryx2::waitset::WaitSetRunResult;
use icrflow_interfaces::{
    CommandMode, Facet, GraspState, HandCommand, PlanPhase, PlanStepHeader, WrenchSpaceHeader,
    now_ns, read_text, topics,
};
use icrflow_nodes::bus::{Bus, BusConfig};
use icrflow_nodes::supervise::{Event, NodeSpec, RestartPolicy, Supervisor};
use icrflow_scenario::{Config, Setup};
use serde::Serialize;

/// The node processes, in start order.
pub const NODES: [&str; 5] = ["plant", "estimator", "wrench", "planner", "command"];

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

fn percentiles(v: &mut [f64]) -> Percentiles {
    if v.is_empty() {
        return Percentiles::default();
    }
    v.sort_by(f64::total_cmp);
    let at = |q: f64| v[((q * (v.len() - 1) as f64).round() as usize).min(v.len() - 1)];
    Percentiles {
        p50: at(0.5),
        p99: at(0.99),
        max: v[v.len() - 1],
        samples: v.len(),
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
    /// Smallest quality alpha* of the grasp a tracking command was computed with.
    pub min_quality: f64,
    /// The margin.
    pub alpha: f64,
    /// Node restarts by the supervisor.
    pub restarts: u32,
    /// Hand commands that held.
    pub holds: u64,
    /// Hand commands sent.
    pub commands: u64,
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
    /// Latency per stage: from the plant's joint measurement to the grasp state, the wrench
    /// space, the plan step and the hand command caused by it (us).
    pub latency_us: Latencies,
}

/// Latency percentiles per stage.
#[derive(Debug, Serialize, Default)]
pub struct Latencies {
    /// Joint measurement to grasp state (estimator).
    pub grasp_state: Percentiles,
    /// Joint measurement to wrench space (estimator + wrench-space node).
    pub wrench_space: Percentiles,
    /// Joint measurement to hand command: end to end.
    pub hand_command: Percentiles,
}

fn node_program(name: &str) -> Result<PathBuf> {
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

/// Runs the verb; returns the exit code.
pub fn run(path: &Path, live: bool, summary_json: Option<PathBuf>) -> Result<u8> {
    let config = Config::load(path)?;
    if !matches!(config.object, icrflow_scenario::ObjectSpec::Sphere { .. }) {
        bail!(
            "object.shape: the pipeline's plant and estimator model a sphere for now; `plan` handles {}",
            config.object.describe()
        );
    }
    let setup = Setup::new(&config)?;
    setup
        .scenario(&config)
        .start()
        .context("cannot start: the initial grasp")?;
    let config_path = std::fs::canonicalize(path)
        .with_context(|| format!("cannot resolve {}", path.display()))?;
    let mut specs = Vec::new();
    for n in NODES {
        specs.push(NodeSpec {
            name: n.into(),
            program: node_program(n)?,
            args: vec!["--config".into(), config_path.display().to_string()],
            policy: RestartPolicy::default(),
        });
    }
    let pid = std::process::id();
    let bus_config = BusConfig::new(
        &config.pipeline.rig,
        &format!("icr{pid}_"),
        PathBuf::from(format!("/tmp/icrflow/run-{pid}")),
    )?;
    set_log_level(LogLevel::Warn);
    let mut supervisor = Supervisor::new(bus_config.clone(), specs, false);
    let started = Instant::now();
    let goal = config.plan.goal;
    let alpha = config.grasp.alpha;
    // The bus, its ports and the WaitSet live in this block, so that they are gone before the
    // run's iceoryx2 directory is removed.
    let stats = {
        let bus = Bus::new("run", &bus_config)?;
        let plans = bus.slice_subscriber::<PlanStepHeader, u32>(topics::PLAN_STEP)?;
        let grasps = bus.subscriber::<GraspState>(topics::GRASP_STATE)?;
        let wrenches = bus.slice_subscriber::<WrenchSpaceHeader, Facet>(topics::WRENCH_SPACE)?;
        let commands = bus.subscriber::<HandCommand>(topics::HAND_COMMAND)?;
        for e in supervisor.start()? {
            report(&e);
        }
        let timeout = Duration::from_secs(600);
        let (mut regions, mut facets) = (Vec::new(), Vec::new());
        let mut last_step = 0u64;
        let mut attaches = std::collections::BTreeSet::new();
        let mut min_quality = f64::INFINITY;
        let mut rotation = 0.0;
        let (mut holds, mut sent, mut stale_tracked) = (0u64, 0u64, 0u64);
        // What the hand command node guarantees at publication, plus an allowance for the
        // delivery to this process.
        let max_age_ns = (config.pipeline.max_input_age * 1e9) as u64 + 10_000_000;
        let mut done = false;
        let mut reason = String::new();
        let (mut lat_g, mut lat_w, mut lat_c) = (Vec::new(), Vec::new(), Vec::new());
        let mut tracking = false;

        let ws = WaitSetBuilder::new().create::<ipc::Service>()?;
        let w_plan = ws.attach_notification(plans.listener())?;
        let w_grasp = ws.attach_notification(grasps.listener())?;
        let w_wrench = ws.attach_notification(wrenches.listener())?;
        let w_cmd = ws.attach_notification(commands.listener())?;
        let tick = ws.attach_interval(Duration::from_millis(10))?;
        let mut failure = None;
        let mut on_event = |id: WaitSetAttachmentId<ipc::Service>| {
            let mut step = || -> Result<bool> {
                let t = now_ns();
                let us = |origin: u64| (t.saturating_sub(origin)) as f64 * 1e-3;
                if id.has_event_from(&w_grasp) {
                    grasps.drain(|g| {
                        rotation = g.rotation;
                        if g.header.origin_time_ns > 0 {
                            lat_g.push(us(g.header.origin_time_ns));
                        }
                    })?;
                }
                if id.has_event_from(&w_wrench)
                    && let Some(w) = wrenches.latest(&mut facets)?
                    && w.header.origin_time_ns > 0
                {
                    lat_w.push(us(w.header.origin_time_ns));
                }
                if id.has_event_from(&w_plan)
                    && let Some(p) = plans.latest(&mut regions)?
                {
                    if p.phase == PlanPhase::Done as u32 {
                        done = true;
                    } else {
                        last_step = last_step.max(p.step);
                        if p.phase == PlanPhase::Attach as u32 {
                            attaches.insert(p.step);
                        }
                    }
                }
                if id.has_event_from(&w_cmd) {
                    commands.drain(|c| {
                        sent += 1;
                        tracking = c.mode == CommandMode::Track as u32;
                        if tracking {
                            min_quality = min_quality.min(c.quality);
                            if c.header.origin_time_ns > 0 {
                                lat_c.push(us(c.header.origin_time_ns));
                                let made = c.header.source_time_ns;
                                if made.saturating_sub(c.header.origin_time_ns) > max_age_ns {
                                    stale_tracked += 1;
                                }
                            }
                        } else {
                            holds += 1;
                            if holds % 500 == 1 {
                                eprintln!("run: hand holds: {}", read_text(&c.reason));
                            }
                        }
                    })?;
                }
                if id.has_event_from(&tick) {
                    for e in supervisor.poll(Instant::now())? {
                        report(&e);
                    }
                    if let Some(n) = supervisor.failed() {
                        reason = format!("node {n} failed too often");
                        return Ok(false);
                    }
                    if started.elapsed() > timeout {
                        reason = format!("timed out after {timeout:?}");
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
        let outcome = ws.wait_and_process(&mut on_event);
        if reason.is_empty() {
            reason = match outcome {
                Ok(WaitSetRunResult::TerminationRequest | WaitSetRunResult::Interrupt) => {
                    "stopped by a signal (Ctrl-C)".into()
                }
                other => format!("{other:?}"),
            };
        }
        let killed = supervisor.shutdown(Duration::from_secs(2));
        if !killed.is_empty() {
            eprintln!("run: killed after the grace period: {killed:?}");
        }
        if let Some(e) = failure {
            return Err(e);
        }
        Stats {
            done,
            reason,
            rotation,
            attaches: attaches.len(),
            steps: last_step as usize,
            min_quality,
            holds,
            sent,
            stale_tracked,
            latencies: Latencies {
                grasp_state: percentiles(&mut lat_g),
                wrench_space: percentiles(&mut lat_w),
                hand_command: percentiles(&mut lat_c),
            },
        }
    };
    remove_run_files(&bus_config);
    let summary = RunSummary {
        completed: stats.done && stats.rotation >= goal - 0.5f64.to_radians(),
        reason: stats.reason,
        rotation_deg: stats.rotation.to_degrees(),
        goal_deg: goal.to_degrees(),
        switches: stats.attaches,
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
        stale_tracked: stats.stale_tracked,
        seconds: started.elapsed().as_secs_f64(),
        bus_prefix: bus_config.prefix.clone(),
        bus_root: bus_config.root.display().to_string(),
        latency_us: stats.latencies,
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
        "rotation   {:.1} deg of {:.1} deg, {} plan steps, {} finger switches",
        summary.rotation_deg, summary.goal_deg, summary.steps, summary.switches
    )?;
    writeln!(
        o,
        "quality    minimum alpha* while tracking = {:.6} (alpha = {alpha})",
        summary.min_quality
    )?;
    writeln!(
        o,
        "commands   {} sent, {} holds; {} node restarts; {:.1} s",
        summary.commands, summary.holds, summary.restarts, summary.seconds
    )?;
    let l = &summary.latency_us;
    writeln!(
        o,
        "latency    joint measurement to hand command p50 {:.0} us, p99 {:.0} us, max {:.0} us",
        l.hand_command.p50, l.hand_command.p99, l.hand_command.max
    )?;
    if let Some(p) = summary_json {
        let text = serde_json::to_string_pretty(&summary)?;
        std::fs::write(&p, text + "\n").with_context(|| format!("writing {}", p.display()))?;
    }
    Ok(if summary.completed { 0 } else { 2 })
}

/// What the run saw.
struct Stats {
    done: bool,
    reason: String,
    rotation: f64,
    attaches: usize,
    steps: usize,
    min_quality: f64,
    holds: u64,
    sent: u64,
    stale_tracked: u64,
    latencies: Latencies,
}

/// Removes what iceoryx2 leaves of a finished run: its root directory (empty directories by
/// then) and the one shared-memory counter it keeps by design.
fn remove_run_files(bus: &BusConfig) {
    let _ = std::fs::remove_dir_all(&bus.root);
    if let Ok(dir) = std::fs::read_dir("/dev/shm") {
        for e in dir.flatten() {
            if e.file_name().to_string_lossy().starts_with(&bus.prefix) {
                let _ = std::fs::remove_file(e.path());
            }
        }
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
        Event::GaveUp { name, reason } => eprintln!("run: giving up on {name}: {reason}"),
    }
}
