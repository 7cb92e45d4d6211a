//! What a node process is started with ([`Launch`]): one typed description, handed to the
//! node as its command-line arguments ([`Launch::to_args`]) and parsed back by
//! [`crate::node::main`] ([`Launch::parse`]) into the node's context (`ctx.launch`).
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

use std::collections::BTreeMap;
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

/// A malformed launch description, with the argument named.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum LaunchError {
    /// An argument no node takes.
    #[error("unknown argument {arg:?}")]
    Unknown {
        /// The argument.
        arg: String,
    },
    /// A flag without its value.
    #[error("{flag} needs a value")]
    NoValue {
        /// The flag.
        flag: &'static str,
    },
    /// A flag given twice.
    #[error("{flag} is given twice")]
    Repeated {
        /// The flag.
        flag: &'static str,
    },
    /// A required flag missing.
    #[error("{flag} is missing")]
    Missing {
        /// The flag.
        flag: &'static str,
    },
    /// A value of the wrong form.
    #[error("{flag} {value:?}: expected {expected}")]
    Invalid {
        /// The flag.
        flag: &'static str,
        /// Its value.
        value: String,
        /// What it should be.
        expected: &'static str,
    },
    /// The bus settings are unusable.
    #[error(transparent)]
    Bus(#[from] BusError),
}

/// The flags: whether each takes a value.
const FLAGS: [(&str, bool); 10] = [
    ("--config", true),
    ("--rig", true),
    ("--bus-prefix", true),
    ("--bus-root", true),
    ("--supervisor", true),
    ("--realtime", true),
    ("--log-contacts", false),
    ("--recording", true),
    ("--recording-id", true),
    ("--no-footer", false),
];

/// The flags given, each with its value (`""` for a switch).
struct Flags(BTreeMap<&'static str, String>);

impl Flags {
    fn parse(args: &[String]) -> Result<Self, LaunchError> {
        let mut flags = BTreeMap::new();
        let mut args = args.iter();
        while let Some(arg) = args.next() {
            let Some(&(flag, valued)) = FLAGS.iter().find(|(f, _)| *f == arg.as_str()) else {
                return Err(LaunchError::Unknown { arg: arg.clone() });
            };
            let value = if valued {
                args.next()
                    .filter(|v| !v.starts_with("--"))
                    .ok_or(LaunchError::NoValue { flag })?
                    .clone()
            } else {
                String::new()
            };
            if flags.insert(flag, value).is_some() {
                return Err(LaunchError::Repeated { flag });
            }
        }
        Ok(Self(flags))
    }

    fn take(&mut self, flag: &'static str) -> Option<String> {
        self.0.remove(flag)
    }

    fn required(&mut self, flag: &'static str) -> Result<String, LaunchError> {
        self.take(flag).ok_or(LaunchError::Missing { flag })
    }

    fn number<T: std::str::FromStr>(
        &mut self,
        flag: &'static str,
        expected: &'static str,
        valid: impl Fn(&T) -> bool,
    ) -> Result<Option<T>, LaunchError> {
        self.take(flag)
            .map(|value| match value.parse::<T>() {
                Ok(n) if valid(&n) => Ok(n),
                _ => Err(LaunchError::Invalid {
                    flag,
                    value,
                    expected,
                }),
            })
            .transpose()
    }

    /// The recording flags (`--recording-id` and `--no-footer` only with `--recording`).
    fn recording(&mut self) -> Result<Option<RecordingLaunch>, LaunchError> {
        let Some(target) = self.take("--recording") else {
            for flag in ["--recording-id", "--no-footer"] {
                if self.0.contains_key(flag) {
                    return Err(LaunchError::Missing {
                        flag: "--recording",
                    });
                }
            }
            return Ok(None);
        };
        Ok(Some(RecordingLaunch {
            target,
            id: self.required("--recording-id")?,
            footer: self.take("--no-footer").is_none(),
        }))
    }

    /// Refuses what is left.
    fn done(self) -> Result<(), LaunchError> {
        match self.0.into_keys().next() {
            Some(flag) => Err(LaunchError::Unknown { arg: flag.into() }),
            None => Ok(()),
        }
    }
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
        let mut flags = Flags::parse(args)?;
        let config = PathBuf::from(flags.required("--config")?);
        let (rig, prefix, root) = (
            flags.required("--rig")?,
            flags.required("--bus-prefix")?,
            flags.required("--bus-root")?,
        );
        let bus = BusConfig::new(&rig, &prefix, PathBuf::from(root))?;
        let supervisor = flags.number("--supervisor", "a process id", |&p: &u32| p > 0)?;
        let realtime = flags.number("--realtime", "a priority from 1 to 99", |&p: &u8| {
            (1..=99).contains(&p)
        })?;
        let log = Log {
            contacts: flags.take("--log-contacts").is_some(),
        };
        let recording = flags.recording()?;
        flags.done()?;
        Ok(Self {
            config,
            bus,
            supervisor,
            realtime,
            log,
            recording,
        })
    }

    /// The arguments that hand this description to a node ([`Launch::parse`] reads them).
    pub fn to_args(&self) -> Vec<String> {
        let mut args: Vec<String> = [
            "--config".into(),
            self.config.display().to_string(),
            "--rig".into(),
            self.bus.rig.clone(),
            "--bus-prefix".into(),
            self.bus.prefix.clone(),
            "--bus-root".into(),
            self.bus.root.display().to_string(),
        ]
        .into();
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
    /// Reads the recording arguments alone (`--recording TARGET --recording-id ID
    /// [--no-footer]`): the visualizer's plan mode, which runs on no bus.
    pub fn parse(args: &[String]) -> Result<Self, LaunchError> {
        let mut flags = Flags::parse(args)?;
        let recording = flags.recording()?.ok_or(LaunchError::Missing {
            flag: "--recording",
        })?;
        flags.done()?;
        Ok(recording)
    }

    /// Its arguments ([`RecordingLaunch::parse`] reads them).
    pub fn to_args(&self) -> Vec<String> {
        let mut args = vec![
            "--recording".into(),
            self.target.clone(),
            "--recording-id".into(),
            self.id.clone(),
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
        for l in [plain, full, by_hand] {
            assert_eq!(Launch::parse(&l.to_args()).unwrap(), l);
        }
        let r = RecordingLaunch {
            target: "spawn:9876".into(),
            id: "x".into(),
            footer: true,
        };
        assert_eq!(RecordingLaunch::parse(&r.to_args()).unwrap(), r);
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
        assert_eq!(with(&["--verbose"]), "unknown argument \"--verbose\"");
        assert_eq!(with(&["--realtime"]), "--realtime needs a value");
        assert_eq!(
            with(&["--realtime", "0"]),
            "--realtime \"0\": expected a priority from 1 to 99"
        );
        assert_eq!(
            with(&["--realtime", "100"]),
            "--realtime \"100\": expected a priority from 1 to 99"
        );
        assert_eq!(
            with(&["--supervisor", "me"]),
            "--supervisor \"me\": expected a process id"
        );
        assert_eq!(with(&["--rig", "s"]), "--rig is given twice");
        assert_eq!(with(&["--recording-id", "x"]), "--recording is missing");
        assert_eq!(
            with(&["--recording", "rrd:/a.rrd"]),
            "--recording-id is missing"
        );
        assert_eq!(
            Launch::parse(&base[2..]).unwrap_err().to_string(),
            "--config is missing"
        );
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
