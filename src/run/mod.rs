//! `icrflow run CONFIG [--live] [--summary-json PATH]`: the pipeline, one process per node,
//! supervised, on an iceoryx2 bus of its own, until the scenario's goal (or Ctrl-C).
//!
//! | module | what |
//! |---|---|
//! | [`launch`] | what each process is started with, the run's bus, the visualizer started first |
//! | [`watch`] | the run's event loop: what it takes off the bus, and why it stops ([`stop::StopReason`]) |
//! | [`measure`] | latencies, rates, steady-state allocations, `/proc` samples |
//! | [`histogram`] | latency percentiles in constant memory |
//! | [`hold_cause`] | the cause of a hold, from its reason, with its numbers |
//! | [`status`] | what the run says on stderr as it goes: its messages and one status line |
//! | [`physics`] | the run against MuJoCo's truth: the summary's `physics` |
//! | [`collisions`] | fingers touching each other and links touching the object in MuJoCo |
//! | [`track`] | the state machines the watch feeds: heartbeats, the estimate against the truth, re-plans, SIGHUP |
//! | [`summary`] | what the run prints at the end and writes with `--summary-json` |

pub(crate) mod collisions;
pub(crate) mod histogram;
pub(crate) mod hold_cause;
pub(crate) mod launch;
pub(crate) mod measure;
pub(crate) mod physics;
pub(crate) mod planner_waits;
pub(crate) mod status;
pub(crate) mod stop;
pub(crate) mod summary;
pub(crate) mod track;
pub(crate) mod true_margin;
pub(crate) mod watch;

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result};
use icrflow_plan::rolling::Surface;
use icrflow_plan::spatial::surface::Convex;
use icrflow_runtime::bus::Bus;
use icrflow_runtime::supervise::Supervisor;
use icrflow_scenario::{Config, Recording, Setup};

use launch::{Launching, RUNS_DIR, run_bus, sweep_killed_runs};
use summary::{Facts, RunSummary};
use track::Hangup;

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

/// A spatial hand's run: the simulated slip (`pipeline.slip_deg`) turns the object about the
/// plan's axis under fingertips that stay where they are, which keeps them on it only for a
/// sphere; another object is refused by the key.
pub fn spatial_slip(config: &Config, surface: &Convex) -> Result<()> {
    if config.pipeline.slip != 0.0 && !matches!(surface, Convex::Sphere { .. }) {
        anyhow::bail!(
            "pipeline.slip_deg: the simulated slip turns the object about the plan's axis under \
             fingertips that stay where they are, which keeps them on it only for a sphere; this \
             object is not one"
        );
    }
    Ok(())
}

/// Runs the verb; returns the exit code.
pub fn run(
    path: &Path,
    live: bool,
    summary_json: Option<PathBuf>,
    verbose: bool,
    viewer: Viewer,
) -> Result<u8> {
    // From the start: a hang-up while the config loads stops the run as one later would.
    let hangup = Hangup::install()?;
    crate::output::check(&crate::output::run(&summary_json, &viewer.rrd))?;
    let config = Config::load(path)?;
    let recording = viewer.recording(&config)?;
    let setup = Setup::new(&config)?;
    let start = match setup.spatial_scenario(&config) {
        Some(spatial) => {
            spatial_slip(&config, spatial.surface)?;
            spatial.start().map(|_| ())
        }
        None => {
            slip(&config, setup.surface()?)?;
            setup.scenario(&config).start().map(|_| ())
        }
    };
    match start {
        Ok(_) => {}
        // An answer about the grasp, as validate and plan give it (exit status 2).
        Err(e) if crate::exit::is_grasp_answer(&e) => {
            eprintln!("run: cannot start: {e} (nothing started)");
            return Ok(crate::exit::INCOMPLETE);
        }
        Err(e) => return Err(anyhow::Error::new(e).context("cannot start")),
    }
    let config_path = std::fs::canonicalize(path)
        .with_context(|| format!("cannot resolve {}", path.display()))?;
    let recording_id = format!(
        "icrflow-{}-{}-{}",
        config.pipeline.rig,
        std::process::id(),
        icrflow_interfaces::now_ns() / 1_000_000
    );
    let bus_config = run_bus(&config.pipeline.rig, std::process::id())?;
    let specs = Launching {
        config: &config,
        config_path: &config_path,
        recording: recording.as_ref(),
        recording_id: &recording_id,
        live,
        bus: &bus_config,
    }
    .specs()?;
    let names: Vec<String> = specs.iter().map(|s| s.name.clone()).collect();
    icrflow_runtime::bus::set_up_logging();
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
    // The bus and its ports live in this block, so that they are gone before the run's
    // iceoryx2 directory is removed.
    let seen = {
        let bus = Bus::new("run", &bus_config)?;
        let on = recording.is_some();
        watch::watch(&bus, &mut supervisor, &config, live, on, names, hangup)?
    };
    bus_config.remove_files();
    let by_signal = seen.stop.by_signal();
    let summary = RunSummary::new(
        seen,
        Facts {
            goal: config.plan.goal,
            alpha: config.grasp.alpha,
            restarts: supervisor.restarts(),
            seconds: started.elapsed().as_secs_f64(),
            bus: bus_config,
            recording: recording
                .as_ref()
                .map(|r| (target_name(r), recording_id.clone())),
        },
    );
    summary.print(&config_path, &config, recording.as_ref(), verbose)?;
    if let Some(p) = summary_json {
        let text = serde_json::to_string_pretty(&summary)?;
        std::fs::write(&p, text + "\n").with_context(|| format!("writing {}", p.display()))?;
    }
    // A live run ends by Ctrl-C: that is success if nothing failed.
    let interrupted = live && by_signal;
    Ok(if summary.completed || interrupted {
        crate::exit::DONE
    } else {
        crate::exit::INCOMPLETE
    })
}
