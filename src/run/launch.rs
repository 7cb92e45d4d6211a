//! Launching the run's processes: what each node is started with ([`Launching::specs`], each
//! with its typed [`Launch`]), the run's bus and what killed runs left ([`run_bus`],
//! [`sweep_killed_runs`]), and the visualizer started first, alone, until it listens
//! ([`start_visualizer`]).

use std::ops::ControlFlow;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use anyhow::{Context, Result, bail};
use icrflow_interfaces::topics::{self, NodeRole};
use icrflow_interfaces::{NodeHealth, read_text};
use icrflow_runtime::bus::{Bus, BusConfig, Sub};
use icrflow_runtime::event::Loop;
use icrflow_runtime::launch::{Launch, Log, RecordingLaunch};
use icrflow_runtime::supervise::{Event, NodeSpec, RestartPolicy, Supervisor};
use icrflow_scenario::{Config, Recording};

use super::status::say;
use super::track::Hangup;

/// coreutils' `nice`, which starts the visualizer at a lower CPU priority.
const NICE: &str = "/usr/bin/nice";

/// The nodes whose loops run under SCHED_FIFO at `pipeline.realtime_priority`: those on the
/// measurement-to-command path (the plant, which stands for the hand's driver, the estimator,
/// the wrench-space node and the hand command node), and the planner node's loop, which leads
/// the hand from target to target (the command node holds the hand on a plan step older than
/// `pipeline.max_input_age_ms`). The planner's planning runs in a worker thread of its own at
/// normal priority (`icrflow_nodes::planner`), so its loop takes microseconds per message as
/// the others' do. With the planner's loop at normal priority, two processes busy beside the
/// run (a build) kept its plan steps from the command node long enough for 27,450 holds in a
/// CI run of the Allegro ellipsoid in MuJoCo, which lost its grasp (issue 38's notes).
const REALTIME_NODES: [NodeRole; 5] = [
    NodeRole::Plant,
    NodeRole::Estimator,
    NodeRole::Wrench,
    NodeRole::Planner,
    NodeRole::Command,
];

/// The environment variable that asks the nodes to log every contact change and plan step
/// (`ICRFLOW_LOG_CONTACTS=1 icrflow run ...`, a debugging aid): the user's switch, which `run`
/// hands to its nodes in their [`Launch`] (`--log-contacts`).
pub const ENV_LOG_CONTACTS: &str = "ICRFLOW_LOG_CONTACTS";

/// The loop's nodes this host runs (`pipeline.nodes`).
pub(super) fn local_nodes(config: &Config) -> Result<Vec<NodeRole>> {
    config
        .pipeline
        .nodes
        .iter()
        .map(|n| NodeRole::from_name(n).with_context(|| format!("pipeline.nodes: no node {n:?}")))
        .collect()
}

/// The executable of node `role`: `icrflow-<name>` beside this one.
pub(crate) fn node_program(role: NodeRole) -> Result<PathBuf> {
    let exe = std::env::current_exe().context("locating the icrflow executable")?;
    let dir = exe
        .parent()
        .context("the icrflow executable has no directory")?;
    let path = dir.join(format!("icrflow-{role}"));
    if !path.is_file() {
        bail!(
            "node binary {} not found beside icrflow: build them with `cargo build --release --workspace`",
            path.display()
        );
    }
    Ok(path)
}

/// The SCHED_FIFO priority the loop's nodes run their loops at, if any: where the machine
/// allows it (each switches once its start-up is done); otherwise that is said once, and they
/// run at normal priority.
fn realtime(config: &Config, nodes: &[NodeRole]) -> Option<u8> {
    let p = config.pipeline.realtime_priority;
    if p == 0 || !nodes.iter().any(|n| REALTIME_NODES.contains(n)) {
        return None;
    }
    match icrflow_runtime::node::realtime_allowed(p) {
        Ok(()) => Some(p),
        Err(why) => {
            say!(
                "run: pipeline.realtime_priority = {p} is not available here ({why:#}); the loop's nodes run at normal priority"
            );
            None
        }
    }
}

/// What the run starts its processes with.
pub(super) struct Launching<'a> {
    /// The config.
    pub config: &'a Config,
    /// Its absolute path.
    pub config_path: &'a Path,
    /// The recording, if the visualizer is on.
    pub recording: Option<&'a Recording>,
    /// The recording id.
    pub recording_id: &'a str,
    /// `--live`.
    pub live: bool,
    /// The run's bus.
    pub bus: &'a BusConfig,
}

impl Launching<'_> {
    /// The processes of the run, in the order they start: the loop's nodes here, the Zenoh
    /// bridge (with `zenoh.enabled`), the visualizer (with a recording).
    pub(super) fn specs(&self) -> Result<Vec<NodeSpec>> {
        let config = self.config;
        let nodes = local_nodes(config)?;
        let realtime = realtime(config, &nodes);
        let mut specs = Vec::new();
        for n in nodes {
            specs.push(NodeSpec {
                name: n.name().into(),
                program: node_program(n)?,
                args: Vec::new(),
                launch: Some(Launch {
                    realtime: realtime.filter(|_| REALTIME_NODES.contains(&n)),
                    ..self.launch()
                }),
                policy: RestartPolicy::default(),
                essential: true,
            });
        }
        if config.zenoh.enabled {
            // Remote monitoring, and the loop topics of the nodes on other hosts when
            // `pipeline.nodes` runs only some here. Monitoring alone, the run goes on without
            // the bridge if it fails for good; a split loop cannot.
            specs.push(NodeSpec {
                name: NodeRole::Bridge.name().into(),
                program: node_program(NodeRole::Bridge)?,
                args: Vec::new(),
                launch: Some(self.launch()),
                policy: RestartPolicy::default(),
                essential: config.pipeline.split(),
            });
        }
        if config.pipeline.split() {
            let links = topics::links(&config.pipeline.nodes);
            say!(
                "run: this host runs {}; the others are joined over Zenoh (sending {:?}, taking {:?})",
                config.pipeline.nodes.join(", "),
                links.export,
                links.import
            );
        }
        if let Some(r) = self.recording {
            specs.push(self.visualizer(r)?);
        }
        Ok(specs)
    }

    /// What a process of the run is started with: the config, the bus, this process as its
    /// supervisor, and the user's log switch ([`ENV_LOG_CONTACTS`]).
    fn launch(&self) -> Launch {
        Launch {
            log: Log {
                contacts: std::env::var_os(ENV_LOG_CONTACTS).is_some(),
            },
            ..Launch::supervised(self.config_path.to_path_buf(), self.bus.clone())
        }
    }

    /// The visualizer's process, recording to `r`.
    fn visualizer(&self, r: &Recording) -> Result<NodeSpec> {
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
        let program = node_program(NodeRole::Visualizer)?;
        let nice = Path::new(NICE);
        let (program, args) = if nice.is_file() {
            (
                nice.to_path_buf(),
                vec!["-n".into(), "10".into(), program.display().to_string()],
            )
        } else {
            (program, Vec::new())
        };
        Ok(NodeSpec {
            name: NodeRole::Visualizer.name().into(),
            program,
            args,
            launch: Some(Launch {
                recording: Some(RecordingLaunch {
                    target: r.to_text(),
                    id: self.recording_id.to_string(),
                    // A live run's recording has no end in sight: Rerun's index footer (every
                    // chunk's place, held in memory until the file closes: ~1.3 GB an hour
                    // here) is left out.
                    footer: !self.live,
                }),
                ..self.launch()
            }),
            policy: RestartPolicy::default(),
            essential: false,
        })
    }
}

/// Where runs keep their iceoryx2 files: `run-PID` each.
pub(super) const RUNS_DIR: &str = "/tmp/icrflow";

/// The bus of the run whose process is `pid`.
pub(super) fn run_bus(rig: &str, pid: u32) -> Result<BusConfig> {
    Ok(BusConfig::new(
        rig,
        &format!("icr{pid}_"),
        PathBuf::from(format!("{RUNS_DIR}/run-{pid}")),
    )?)
}

/// Removes what runs killed outright left (their bus files, shared memory and checkpoints):
/// those whose process is gone and none of whose iceoryx2 nodes is alive (their nodes stop
/// when the run dies, see `icrflow_runtime::launch::Launch::supervisor`). Returns their pids.
pub(super) fn sweep_killed_runs(rig: &str) -> Vec<u32> {
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

/// How long `run` waits for the visualizer to listen before it starts the loop anyway.
pub const VISUALIZER_READY: Duration = Duration::from_secs(15);

/// How often [`start_visualizer`] looks at the supervisor meanwhile.
const VISUALIZER_POLL: Duration = Duration::from_millis(5);

/// How waiting for the visualizer ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum VisualizerStart {
    /// It reported its health: it has subscribed to its inputs.
    Listening,
    /// It did not report within [`VISUALIZER_READY`] (the run goes on without it: the
    /// visualizer never holds the run).
    Late,
    /// It exited before it reported (the run goes on; the supervisor restarts it).
    Exited,
    /// Ctrl-C, SIGTERM or SIGHUP came meanwhile.
    Interrupted,
}

/// Starts the visualizer alone and waits until it reports its health (it subscribes to its
/// inputs before its first report), at most [`VISUALIZER_READY`]; `seen` takes its reports.
/// A late or exited visualizer is said on stderr.
pub(super) fn start_visualizer(
    bus: &Bus,
    supervisor: &mut Supervisor,
    healths: &Sub<NodeHealth>,
    hangup: &Hangup,
    mut seen: impl FnMut(&NodeHealth),
) -> Result<VisualizerStart> {
    for e in supervisor.start_first(NodeRole::Visualizer.name())? {
        report(&e);
    }
    let deadline = Instant::now() + VISUALIZER_READY;
    let on = Loop {
        node: bus.node(),
        name: "run",
        realtime: None,
    };
    // Woken by the health reports, and every VISUALIZER_POLL for the supervisor; SIGTERM,
    // SIGINT or SIGHUP stop the run.
    let waited = on.serve_until(&[healths.listener()], Some(VISUALIZER_POLL), |_| {
        let mut listening = false;
        healths.drain(|h| {
            if read_text(&h.node) == NodeRole::Visualizer.name() {
                listening = true;
                seen(h);
            }
        })?;
        if listening {
            return Ok(ControlFlow::Break(VisualizerStart::Listening));
        }
        let events = supervisor.poll(Instant::now())?;
        for e in &events {
            report(e);
        }
        Ok(
            if events.iter().any(|e| matches!(e, Event::Exited { .. })) {
                ControlFlow::Break(VisualizerStart::Exited)
            } else if hangup.came() {
                ControlFlow::Break(VisualizerStart::Interrupted)
            } else if Instant::now() >= deadline {
                ControlFlow::Break(VisualizerStart::Late)
            } else {
                ControlFlow::Continue(())
            },
        )
    })?;
    let waited = waited.unwrap_or(VisualizerStart::Interrupted);
    match waited {
        VisualizerStart::Late => say!(
            "run: the visualizer is not listening after {} s; the loop starts without it (its recording may miss the first plan steps)",
            VISUALIZER_READY.as_secs()
        ),
        VisualizerStart::Exited => say!(
            "run: the visualizer exited before it listened; the loop starts without it (the supervisor restarts it)"
        ),
        VisualizerStart::Listening | VisualizerStart::Interrupted => {}
    }
    Ok(waited)
}

/// Says on stderr what the supervisor did (a first start is not said).
pub(super) fn report(e: &Event) {
    match e {
        Event::Started { name, pid, attempt } if *attempt > 0 => {
            say!("run: restarted {name} (pid {pid}, restart {attempt})")
        }
        Event::Started { .. } => {}
        Event::Exited {
            name,
            status,
            cleaned,
        } => say!("run: node {name} exited ({status}); cleaned {cleaned} dead iceoryx2 nodes"),
        Event::GaveUp { name, reason } if name == NodeRole::Bridge.name() => {
            say!("run: giving up on {name}: {reason}; the run goes on without Zenoh monitoring")
        }
        Event::GaveUp { name, reason } => say!("run: giving up on {name}: {reason}"),
    }
}
