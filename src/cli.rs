//! Command-line interface: one subcommand per verb.

use std::path::PathBuf;

use clap::{Args, Parser, Subcommand};

/// In-hand rolling manipulation with independent contact regions and a quality margin.
#[derive(Debug, Parser)]
#[command(name = "icrflow", version, about, after_help = crate::exit::HELP)]
pub struct Cli {
    /// What to do.
    #[command(subcommand)]
    pub command: Command,
    /// `--progress-after` before the verb (`icrflow --progress-after 0 plan ...`), as it was
    /// taken when the flag was global; offered in the help of the verbs it acts on only
    /// ([`Progress`]), and refused before any other verb.
    #[arg(
        long = "progress-after",
        hide = true,
        value_name = "SECONDS",
        value_parser = crate::progress::parse_after
    )]
    pub progress_after: Option<std::time::Duration>,
}

/// The flag of the verbs that load the object and build the grasp problem (validate, analyze,
/// plan).
#[derive(Debug, Args)]
pub struct Progress {
    /// Show the progress of loading the object and building the grasp problem (and, for
    /// plan, of planning) once it has taken this long, in seconds (0 to 3600; 0: always)
    /// [default: 1].
    #[arg(
        long = "progress-after",
        value_name = "SECONDS",
        value_parser = crate::progress::parse_after
    )]
    pub progress_after: Option<std::time::Duration>,
}

/// `--progress-after`'s default.
pub const PROGRESS_AFTER: std::time::Duration = std::time::Duration::from_secs(1);

impl Cli {
    /// The `--progress-after` of the verb that takes it (`verb`'s, else the one before the
    /// verb, else [`PROGRESS_AFTER`]); the flag before a verb it does not act on is refused as
    /// a usage error (exit status 2).
    pub fn progress_delay(&self, verb: Option<&Progress>) -> std::time::Duration {
        match (verb, self.progress_after) {
            (Some(p), before) => p.progress_after.or(before).unwrap_or(PROGRESS_AFTER),
            (None, None) => PROGRESS_AFTER,
            (None, Some(_)) => {
                use clap::CommandFactory as _;
                Self::command()
                    .error(
                        clap::error::ErrorKind::ArgumentConflict,
                        "--progress-after acts on validate, analyze and plan only",
                    )
                    .exit()
            }
        }
    }
}

/// The verbs.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Analyse the grasp in CONFIG: force closure, quality alpha*, epsilon, and each contact's
    /// independent contact region for the margin alpha. Exit status 2: not force closure, or
    /// alpha* below alpha (no regions).
    Analyze {
        /// Config file (TOML; see docs/configuration.md).
        config: PathBuf,
        /// Print one JSON object instead of text.
        #[arg(long)]
        json: bool,
        #[command(flatten)]
        progress: Progress,
    },
    /// Run the pipeline on CONFIG: every node its own process on a private iceoryx2 bus,
    /// supervised, closed loop on the simulated hand, until the goal rotation (or Ctrl-C with
    /// --live), saying what it does on stderr; prints a summary. Exit status 2: the initial
    /// grasp is not force closure or below alpha, or the goal was not reached (a --live run
    /// stopped by Ctrl-C exits 0).
    Run {
        /// Config file (TOML; see docs/configuration.md).
        config: PathBuf,
        /// Keep running after the goal, until Ctrl-C.
        #[arg(long)]
        live: bool,
        /// Also write the summary as JSON to this file.
        #[arg(long)]
        summary_json: Option<PathBuf>,
        /// Also print each process's memory, scheduling and steady-state allocations, and
        /// the latency's parts.
        #[arg(long, short)]
        verbose: bool,
        /// Save the Rerun recording to this file (default: `visualizer.rrd` of the config,
        /// else out/<config name>.rrd).
        #[arg(long, conflicts_with_all = ["spawn_viewer", "connect_viewer", "no_visualizer"])]
        rrd: Option<PathBuf>,
        /// Stream the recording to a Rerun viewer started for it (`rerun` 0.36 on the PATH).
        #[arg(long, conflicts_with_all = ["connect_viewer", "no_visualizer"])]
        spawn_viewer: bool,
        /// Stream the recording to the Rerun viewer at this URL
        /// (e.g. rerun+http://127.0.0.1:9876/proxy).
        #[arg(long, value_name = "URL", conflicts_with = "no_visualizer")]
        connect_viewer: Option<String>,
        /// Run without the visualizer node.
        #[arg(long)]
        no_visualizer: bool,
    },
    /// Watch a running pipeline over Zenoh (from this or another machine): phase, rotation,
    /// quality against alpha, contacts, node health and restarts, latency, redrawn in place on
    /// a terminal, otherwise every second as short lines with the time (one or more per part).
    /// Read-only. Waits for a run to appear, says when it has ended (every node silent), and
    /// waits for the next; stops on Ctrl-C.
    Monitor {
        /// The Zenoh endpoint of the pipeline's bridge (`zenoh.listen` of its config).
        #[arg(long, default_value = "tcp/127.0.0.1:7447")]
        connect: String,
        /// The rig to watch (`pipeline.rig` of its config).
        #[arg(long, default_value = "sim")]
        rig: String,
        /// Authenticate as this user (`zenoh.users_file` of the pipeline's config); the
        /// password comes from the environment variable ICRFLOW_ZENOH_PASSWORD.
        #[arg(long)]
        user: Option<String>,
        /// Stop after this many seconds.
        #[arg(long)]
        seconds: Option<f64>,
    },
    /// Check CONFIG and every file it names (mesh, URDF), build the object and the hand, and
    /// check the initial grasp (force closure, quality >= alpha, every finger reaching its
    /// contact). Exit status 1 with the first problem named, 2 when the grasp is not force
    /// closure or below alpha; nothing is started or written.
    Validate {
        /// Config file (TOML; see docs/configuration.md).
        config: PathBuf,
        #[command(flatten)]
        progress: Progress,
    },
    /// Plan the in-hand rolling scenario in CONFIG offline: roll within the ICRs, switch
    /// fingers at their limits, until the object has turned by plan.rotation_deg. Writes
    /// trajectory.csv and trajectory.json and prints a summary; with --rrd, --spawn-viewer or
    /// --connect-viewer, also records the plan for Rerun, step by step. Exit status 2: the
    /// initial grasp is not force closure or below alpha (nothing written), or the planner
    /// stopped before the goal (the files say why).
    Plan {
        /// Config file (TOML; see docs/configuration.md).
        config: PathBuf,
        /// Output directory [default: out/<config file stem>].
        #[arg(long)]
        out: Option<PathBuf>,
        /// Print the summary as one JSON object instead of text.
        #[arg(long)]
        json: bool,
        /// Also print where the planning's time went, per phase of the spatial planner
        /// (rolling steps, switch searches and their parts: how many, and their time summed
        /// over the threads that ran them; `phases` in the JSON).
        #[arg(long, short)]
        verbose: bool,
        /// Record the plan to this Rerun file.
        #[arg(long, conflicts_with_all = ["spawn_viewer", "connect_viewer"])]
        rrd: Option<PathBuf>,
        /// Record the plan to a Rerun viewer started for it (`rerun` 0.36 on the PATH).
        #[arg(long, conflicts_with = "connect_viewer")]
        spawn_viewer: bool,
        /// Record the plan to the Rerun viewer at this URL.
        #[arg(long, value_name = "URL")]
        connect_viewer: Option<String>,
        #[command(flatten)]
        progress: Progress,
    },
    /// Render a recording of `run` or `plan` into a PNG as the Rerun viewer shows it at a plan
    /// step or at the end, headless (`rerun` 0.36 beside $ICRFLOW_PYTHON, in the project's venv
    /// ${ICRFLOW_CACHE:-$HOME/.cache/icrflow}/venv/bin that scripts/setup.sh makes, or on the PATH).
    Render {
        /// The recording (.rrd).
        rrd: PathBuf,
        /// END, or the plan step to show.
        #[arg(long, default_value = "END")]
        at: String,
        /// The picture to write.
        #[arg(long)]
        out: PathBuf,
        /// The window size in logical points, WIDTHxHEIGHT.
        #[arg(long, default_value = "1280x720")]
        size: String,
    },
}
