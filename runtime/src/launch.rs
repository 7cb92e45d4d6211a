//! What a node process is started with ([`Launch`]): one typed description, handed to the
//! node as its command-line arguments ([`Launch::to_args`]) and parsed back by clap
//! ([`LaunchArgs`], through [`Launch::parse`] in [`crate::node::main`]) into the node's
//! context (`ctx.launch`). Every internal process takes its arguments this one way: the five
//! loop nodes and the bridge through [`crate::node::main`], the visualizer with its modes
//! flattening [`LaunchArgs`] and [`RecordingArgs`] into its own clap command line.
//!
//! The arguments, in any order:
//!
//! | argument | field | |
//! |---|---|---|
//! | `--config PATH` | [`Launch::config`] | required |
//! | `--rig RIG` | [`Launch::bus`] `.rig` | required |
//! | `--bus-prefix PREFIX` | [`Launch::bus`] `.prefix` | required |
//! | `--bus-root DIR` | [`Launch::bus`] `.root` | required |
//! | `--supervisor PID` | [`Launch::supervisor`] | |
//! | `--realtime PRIORITY` | [`Launch::realtime`] | 1 to 99 |
//! | `--log-contacts` | [`Log::contacts`] | |
//! | `--recording TARGET` | [`RecordingLaunch::target`] | the visualizer's |
//! | `--recording-id ID` | [`RecordingLaunch::id`] | with `--recording` |
//! | `--no-footer` | [`RecordingLaunch::footer`] `= false` | with `--recording` |
//!
//! Secrets stay out of them (arguments are visible to every user of the machine): the Zenoh
//! password comes from the environment (`ICRFLOW_ZENOH_PASSWORD`, read by the bridge).

use std::path::PathBuf;

use crate::bus::{BusConfig, BusError};

/// What a node is started with (see the [module](self) for its arguments).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Launch {
    /// The config file the node loads.
    pub config: PathBuf,
    /// The run's bus.
    pub bus: BusConfig,
    /// The supervisor's process id: the node stops, as on a shutdown, when that process dies
    /// however it died (SIGKILL, a crash), rather than run on unsupervised (`None`: started by
    /// hand, it does not follow a supervisor).
    pub supervisor: Option<u32>,
    /// The SCHED_FIFO priority (1 to 99) of the node's loop, if `run` asks for one (the loop's
    /// nodes on the measurement-to-command path, where the machine allows it).
    pub realtime: Option<u8>,
    /// What the node logs on stderr besides its errors.
    pub log: Log,
    /// Where the visualizer records (the visualizer's only).
    pub recording: Option<RecordingLaunch>,
}

/// What a node logs on stderr besides its errors.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Log {
    /// Every contact change (the plant, the estimator, the wrench-space node) and every plan
    /// step the planner node publishes.
    pub contacts: bool,
}

/// Where the visualizer records.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RecordingLaunch {
    /// The target, as `icrflow_scenario::Recording` writes it: `rrd:PATH`, `spawn:PORT` or
    /// `connect:URL`.
    pub target: String,
    /// The run's recording id (every process of a run records under it).
    pub id: String,
    /// Whether the `.rrd` gets Rerun's index footer (every chunk's place, held in memory
    /// until the file closes): not for a `--live` run, whose length has no bound.
    pub footer: bool,
}

/// A malformed launch description: clap's message names the argument and what it expects.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum LaunchError {
    /// An argument unknown, missing, repeated, without its value or of the wrong form.
    #[error("{}", .0.render())]
    Arguments(#[from] clap::Error),
    /// A required argument missing (where clap was told not to require it).
    #[error("{flag} is missing")]
    Missing {
        /// The argument.
        flag: &'static str,
    },
    /// The bus settings are unusable.
    #[error(transparent)]
    Bus(#[from] BusError),
}

/// The arguments of a node (see the [module](self)): parsed by clap, turned into a [`Launch`]
/// by [`Launch::try_from`]. A binary with modes of its own (the visualizer) flattens them
/// into its command line, its modes subcommands that lift their requirement
/// (`subcommand_negates_reqs`): hence the `Option`s of the required ones, which clap requires
/// (and [`Launch::try_from`] refuses missing, naming them).
#[derive(Debug, Clone, clap::Args)]
pub struct LaunchArgs {
    /// The config file the node loads.
    #[arg(long, value_name = "PATH", required = true)]
    pub config: Option<PathBuf>,
    /// The run's rig name.
    #[arg(long, required = true)]
    pub rig: Option<String>,
    /// The run's bus prefix.
    #[arg(long, value_name = "PREFIX", required = true)]
    pub bus_prefix: Option<String>,
    /// The run's bus root (an absolute path).
    #[arg(long, value_name = "DIR", required = true)]
    pub bus_root: Option<PathBuf>,
    /// The supervisor's process id.
    #[arg(long, value_name = "PID", value_parser = clap::value_parser!(u32).range(1..))]
    pub supervisor: Option<u32>,
    /// The SCHED_FIFO priority of the node's loop, 1 to 99.
    #[arg(long, value_name = "PRIORITY", value_parser = clap::value_parser!(u8).range(1..=99))]
    pub realtime: Option<u8>,
    /// Log every contact change and every plan step published.
    #[arg(long)]
    pub log_contacts: bool,
    /// Where the visualizer records.
    #[command(flatten)]
    pub recording: RecordingArgs,
}

/// The recording arguments (`--recording TARGET --recording-id ID [--no-footer]`).
#[derive(Debug, Clone, clap::Args)]
pub struct RecordingArgs {
    /// The target: `rrd:PATH`, `spawn:PORT` or `connect:URL`.
    #[arg(long, value_name = "TARGET", requires = "recording_id")]
    pub recording: Option<String>,
    /// The run's recording id.
    #[arg(long, value_name = "ID", requires = "recording")]
    pub recording_id: Option<String>,
    /// No Rerun index footer (a live run).
    #[arg(long, requires = "recording")]
    pub no_footer: bool,
}

impl From<RecordingArgs> for Option<RecordingLaunch> {
    fn from(a: RecordingArgs) -> Self {
        // clap has made `--recording` and `--recording-id` come together.
        Some(RecordingLaunch {
            target: a.recording?,
            id: a.recording_id?,
            footer: !a.no_footer,
        })
    }
}

impl TryFrom<LaunchArgs> for Launch {
    type Error = LaunchError;

    fn try_from(a: LaunchArgs) -> Result<Self, LaunchError> {
        let missing = |flag| LaunchError::Missing { flag };
        let (rig, prefix) = (
            a.rig.ok_or(missing("--rig"))?,
            a.bus_prefix.ok_or(missing("--bus-prefix"))?,
        );
        Ok(Self {
            bus: BusConfig::new(&rig, &prefix, a.bus_root.ok_or(missing("--bus-root"))?)?,
            config: a.config.ok_or(missing("--config"))?,
            supervisor: a.supervisor,
            realtime: a.realtime,
            log: Log {
                contacts: a.log_contacts,
            },
            recording: a.recording.into(),
        })
    }
}

/// A node's whole command line: its [`LaunchArgs`].
#[derive(Debug, clap::Parser)]
#[command(
    name = "icrflow-<node>",
    no_binary_name = true,
    disable_help_flag = true
)]
struct NodeCommandLine {
    #[command(flatten)]
    launch: LaunchArgs,
}

impl Launch {
    /// A node on `bus` loading `config`, following no supervisor, logging nothing extra.
    pub fn new(config: PathBuf, bus: BusConfig) -> Self {
        Self {
            config,
            bus,
            supervisor: None,
            realtime: None,
            log: Log::default(),
            recording: None,
        }
    }

    /// A node on `bus` loading `config`, supervised by this process.
    pub fn supervised(config: PathBuf, bus: BusConfig) -> Self {
        Self {
            supervisor: Some(std::process::id()),
            ..Self::new(config, bus)
        }
    }

    /// Reads the arguments a node was started with (those after its program).
    pub fn parse(args: &[String]) -> Result<Self, LaunchError> {
        use clap::Parser as _;
        NodeCommandLine::try_parse_from(args)?.launch.try_into()
    }

    /// The arguments that hand this description to a node ([`Launch::parse`] reads them).
    /// Each value joined to its flag (`--rig=VALUE`), so that a value starting with `-` (a rig
    /// named `-lab`) is not read as a flag.
    pub fn to_args(&self) -> Vec<String> {
        let mut args: Vec<String> = vec![
            format!("--config={}", self.config.display()),
            format!("--rig={}", self.bus.rig),
            format!("--bus-prefix={}", self.bus.prefix),
            format!("--bus-root={}", self.bus.root.display()),
        ];
        if let Some(pid) = self.supervisor {
            args.extend(["--supervisor".into(), pid.to_string()]);
        }
        if let Some(p) = self.realtime {
            args.extend(["--realtime".into(), p.to_string()]);
        }
        if self.log.contacts {
            args.push("--log-contacts".into());
        }
        if let Some(r) = &self.recording {
            args.extend(r.to_args());
        }
        args
    }
}

impl RecordingLaunch {
    /// Its arguments ([`RecordingArgs`] reads them).
    pub fn to_args(&self) -> Vec<String> {
        let mut args = vec![
            format!("--recording={}", self.target),
            format!("--recording-id={}", self.id),
        ];
        if !self.footer {
            args.push("--no-footer".into());
        }
        args
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn bus() -> BusConfig {
        BusConfig::new("rig_1", "icr42_", PathBuf::from("/tmp/icrflow/run-42")).unwrap()
    }

    fn args(s: &[&str]) -> Vec<String> {
        s.iter().map(|a| a.to_string()).collect()
    }

    #[test]
    fn a_launch_reads_back_what_it_writes() {
        let plain = Launch::supervised(PathBuf::from("/c/paper sphere.toml"), bus());
        let hyphens = Launch::new(
            PathBuf::from("/-c.toml"),
            BusConfig::new("-lab", "p_", PathBuf::from("/tmp/-b")).unwrap(),
        );
        let full = Launch {
            supervisor: Some(7),
            realtime: Some(50),
            log: Log { contacts: true },
            recording: Some(RecordingLaunch {
                target: "rrd:/out/a b.rrd".into(),
                id: "icrflow-rig-42-1".into(),
                footer: false,
            }),
            ..plain.clone()
        };
        let by_hand = Launch::new(PathBuf::from("c.toml"), bus());
        for l in [plain, full, by_hand, hyphens] {
            assert_eq!(Launch::parse(&l.to_args()).unwrap(), l);
        }
    }

    #[test]
    fn a_malformed_launch_is_refused_naming_the_argument() {
        let base = args(&[
            "--config",
            "/c.toml",
            "--rig",
            "r",
            "--bus-prefix",
            "p_",
            "--bus-root",
            "/tmp/b",
        ]);
        let with = |extra: &[&str]| {
            let mut a = base.clone();
            a.extend(args(extra));
            Launch::parse(&a).unwrap_err().to_string()
        };
        for (extra, names) in [
            (&["--verbose"][..], &["--verbose"][..]),
            (&["--realtime"], &["--realtime", "a value is required"]),
            (&["--realtime", "0"], &["--realtime", "1..=99"]),
            (&["--realtime", "100"], &["--realtime", "1..=99"]),
            (&["--supervisor", "me"], &["--supervisor", "me"]),
            (&["--supervisor", "0"], &["--supervisor", "0"]),
            (&["--rig", "s"], &["--rig", "cannot be used multiple times"]),
            (&["--recording-id", "x"], &["--recording <TARGET>"]),
            (&["--no-footer"], &["--recording <TARGET>"]),
            (&["--recording", "rrd:/a.rrd"], &["--recording-id <ID>"]),
        ] {
            let e = with(extra);
            for name in names {
                assert!(e.contains(name), "{extra:?}: {e}");
            }
        }
        let e = Launch::parse(&base[2..]).unwrap_err().to_string();
        assert!(e.contains("--config <PATH>"), "{e}");
        let mut relative = base.clone();
        relative[7] = "tmp/b".into();
        assert!(
            Launch::parse(&relative)
                .unwrap_err()
                .to_string()
                .contains("tmp/b must be an absolute path")
        );
    }
}
