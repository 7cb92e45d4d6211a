//! `[zenoh]`: the bridge between the run's local bus and Zenoh ([`ZenohSpec`]).

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};

use super::existing_file;
use crate::raw::RawZenoh;

/// The validated `[zenoh]` section: the bridge between the run's local bus and Zenoh.
#[derive(Debug, Clone, PartialEq)]
pub struct ZenohSpec {
    /// Whether `icrflow run` starts the bridge.
    pub enabled: bool,
    /// Zenoh mode: `peer`, `client` or `router`.
    pub mode: String,
    /// Endpoints the bridge listens on (`tcp/HOST:PORT`).
    pub listen: Vec<String>,
    /// Endpoints it connects to.
    pub connect: Vec<String>,
    /// Multicast scouting (finding peers on the network without `connect`).
    pub scouting: bool,
    /// Remote peers may only subscribe to the rig's key expressions (Zenoh access control):
    /// no put, delete, query or queryable of theirs gets through.
    pub read_only: bool,
    /// A file of `user:password` lines: when given, only peers that authenticate with one of
    /// them may connect (Zenoh's user/password authentication).
    pub users_file: Option<PathBuf>,
    /// Users (from `users_file`) whose hosts run the pipeline's other nodes: the only remote
    /// peers allowed to put the loop topics this host takes from Zenoh (read-only sessions).
    /// Empty without a users file: then any peer that connects may.
    pub link_users: Vec<String>,
    /// The user the bridge logs in as where it connects (`connect`), with the password in
    /// [`PASSWORD_ENV`]: a split pipeline's host that connects to one with a users file.
    pub user: Option<String>,
    /// The local topics published for monitoring.
    pub monitor: Vec<String>,
}

/// The local topics the bridge publishes for monitoring unless `zenoh.monitor` says otherwise.
pub const DEFAULT_MONITOR: [&str; 6] = [
    "joint_state",
    "grasp_state",
    "wrench_space",
    "plan_step",
    "hand_command",
    "node_health",
];
/// The environment variable holding the password of `zenoh.user` (and of `icrflow monitor
/// --user`), so that it is in no file and no command line.
pub const PASSWORD_ENV: &str = "ICRFLOW_ZENOH_PASSWORD";
/// Where the bridge listens unless `zenoh.listen` says otherwise: this machine only.
pub const DEFAULT_LISTEN: &str = "tcp/127.0.0.1:7447";

pub(crate) fn zenoh_spec(raw: RawZenoh, base: &Path) -> Result<ZenohSpec> {
    let mut names = Vec::new();
    let users_file = match raw.users_file {
        None => None,
        Some(file) => {
            let full = existing_file("zenoh.users_file", "a users file", base.join(&file))?;
            let text = std::fs::read_to_string(&full)
                .with_context(|| format!("zenoh.users_file: cannot read {}", full.display()))?;
            let mut users = 0;
            for (i, line) in text.lines().enumerate() {
                // Zenoh's format: one `user:password` per line, blank lines skipped, no
                // comments.
                let line = line.trim();
                if line.is_empty() {
                    continue;
                }
                match line.split_once(':') {
                    Some((u, p)) if !u.trim().is_empty() && !p.trim().is_empty() => {
                        users += 1;
                        names.push(u.trim().to_string());
                    }
                    _ => bail!(
                        "zenoh.users_file: {} line {}: expected user:password",
                        full.display(),
                        i + 1
                    ),
                }
            }
            if users == 0 {
                bail!("zenoh.users_file: {} names no user", full.display());
            }
            Some(full)
        }
    };
    let mode = raw.mode.unwrap_or_else(|| "peer".into());
    if !matches!(mode.as_str(), "peer" | "client" | "router") {
        bail!("zenoh.mode: one of \"peer\", \"client\", \"router\", got {mode:?}");
    }
    let endpoints = |key: &str, list: Vec<String>| -> Result<Vec<String>> {
        for e in &list {
            check_endpoint(key, e)?;
        }
        Ok(list)
    };
    let monitor = raw
        .monitor
        .unwrap_or_else(|| DEFAULT_MONITOR.iter().map(|t| t.to_string()).collect());
    for t in &monitor {
        if !DEFAULT_MONITOR.contains(&t.as_str()) {
            bail!("zenoh.monitor: unknown topic {t:?}; the topics are {DEFAULT_MONITOR:?}");
        }
    }
    let link_users = raw.link_users.unwrap_or_default();
    for u in &link_users {
        if users_file.is_none() {
            bail!("zenoh.link_users: needs zenoh.users_file (the users peers log in as)");
        }
        if !names.contains(u) {
            bail!("zenoh.link_users: {u:?} is not a user of zenoh.users_file");
        }
    }
    if let Some(u) = &raw.user
        && (u.is_empty() || u.contains(':'))
    {
        bail!("zenoh.user: a user name without ':', got {u:?}");
    }
    Ok(ZenohSpec {
        link_users,
        user: raw.user,
        enabled: raw.enabled.unwrap_or(true),
        mode,
        listen: endpoints(
            "zenoh.listen",
            raw.listen.unwrap_or_else(|| vec![DEFAULT_LISTEN.into()]),
        )?,
        connect: endpoints("zenoh.connect", raw.connect.unwrap_or_default())?,
        scouting: raw.scouting.unwrap_or(false),
        read_only: raw.read_only.unwrap_or(true),
        users_file,
        monitor,
    })
}

/// Checks a Zenoh endpoint given under `key` (a config key, or a flag such as `--connect`):
/// `tcp/HOST:PORT` (TCP is the only transport built in), so that a typo is named in our words
/// rather than in Zenoh's.
pub fn check_endpoint(key: &str, e: &str) -> Result<()> {
    let Some((proto, address)) = e.split_once('/') else {
        bail!("{key}: {e:?} is not an endpoint like \"tcp/127.0.0.1:7447\"");
    };
    if proto != "tcp" {
        bail!("{key}: {e:?}: only tcp endpoints are built in, got {proto:?}");
    }
    let address = address.split('#').next().unwrap_or(address);
    let ok = address
        .rsplit_once(':')
        .is_some_and(|(host, port)| !host.is_empty() && port.parse::<u16>().is_ok());
    if !ok {
        bail!("{key}: {e:?}: expected tcp/HOST:PORT");
    }
    Ok(())
}
