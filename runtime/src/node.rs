//! A node process: its arguments, what it loads, its bus, and its supervisor.

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::{Context as _, Result, anyhow, bail};
use iceoryx2::prelude::{LogLevel, set_log_level};

use crate::bus::{Bus, BusConfig};

/// A node's context: its name, what it loaded from its config file (`S`: the config, or the
/// config with what it builds), and its bus connection.
pub struct Context<S> {
    /// Node name.
    pub name: &'static str,
    /// What the node loaded from `--config PATH`.
    pub scenario: S,
    /// The bus.
    pub bus: Bus,
}

/// Runs node `name`: reads `--config PATH` from the arguments and the bus settings from the
/// environment, loads the config with `load`, builds the context and calls `body`; errors are
/// printed with the node's name and give exit status 1.
pub fn main<S>(
    name: &'static str,
    load: fn(&Path) -> Result<S>,
    body: fn(&Context<S>) -> Result<()>,
) -> ExitCode {
    set_log_level(LogLevel::Warn);
    let result = (|| -> Result<()> {
        let supervisor = follow_supervisor()?;
        let args: Vec<String> = std::env::args().skip(1).collect();
        let config = match args.as_slice() {
            [flag, path] if flag == "--config" => PathBuf::from(path),
            _ => bail!("usage: icrflow-{name} --config CONFIG (started by `icrflow run`)"),
        };
        let scenario = load(&config)?;
        let bus = Bus::new(name, &BusConfig::from_env()?)?;
        body(&Context {
            name,
            scenario,
            bus,
        })?;
        // Stopped by the supervisor's death (its SIGTERM, above). iceoryx2 removes the dead
        // supervisor's node as the last nodes leave; its directory is the next run's to remove.
        if let Some(pid) = supervisor
            && std::os::unix::process::parent_id() != pid
        {
            eprintln!("icrflow-{name}: stopped: its supervisor (pid {pid}) died");
        }
        Ok(())
    })();
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("icrflow-{name}: error: {e:#}");
            ExitCode::FAILURE
        }
    }
}

/// The environment variable through which a [`Supervisor`](crate::supervise::Supervisor) gives
/// the nodes it starts its process id: a node started with it stops, as on a shutdown, when
/// that process dies however it died (SIGKILL, a crash), rather than run on unsupervised.
pub const ENV_SUPERVISOR: &str = "ICRFLOW_SUPERVISOR_PID";

/// With [`ENV_SUPERVISOR`] set: asks the kernel for SIGTERM when the parent dies
/// (`PR_SET_PDEATHSIG`) and checks that the parent is that supervisor still (it may have died
/// before). Returns the supervisor's pid, `None` without the variable.
fn follow_supervisor() -> Result<Option<u32>> {
    let Ok(text) = std::env::var(ENV_SUPERVISOR) else {
        return Ok(None);
    };
    let pid: u32 = text
        .parse()
        .map_err(|_| anyhow!("{ENV_SUPERVISOR}={text:?} is not a process id"))?;
    nix::sys::prctl::set_pdeathsig(nix::sys::signal::Signal::SIGTERM)
        .context("asking for SIGTERM when the supervisor dies (prctl PR_SET_PDEATHSIG)")?;
    if std::os::unix::process::parent_id() != pid {
        bail!("its supervisor (pid {pid}) is gone; not starting");
    }
    Ok(Some(pid))
}

/// The environment variable through which `run` asks a node to run its loop under SCHED_FIFO,
/// at this priority (1 to 99): see [`promote`].
pub const ENV_REALTIME: &str = "ICRFLOW_REALTIME_PRIORITY";

/// Puts the calling thread under SCHED_FIFO at `priority` (1 to 99).
pub fn set_fifo(priority: u8) -> Result<()> {
    use thread_priority::{
        Error, RealtimeThreadSchedulePolicy, ThreadPriority, ThreadPriorityValue,
        ThreadSchedulePolicy, set_thread_priority_and_policy, thread_native_id,
    };
    let value = ThreadPriorityValue::try_from(priority)
        .ok()
        .filter(|_| priority >= 1)
        .ok_or_else(|| anyhow!("SCHED_FIFO priority {priority}: expected 1 to 99"))?;
    set_thread_priority_and_policy(
        thread_native_id(),
        ThreadPriority::Crossplatform(value),
        ThreadSchedulePolicy::Realtime(RealtimeThreadSchedulePolicy::Fifo),
    )
    .map_err(|e| match e {
        Error::OS(code) => anyhow!(
            "SCHED_FIFO priority {priority}: {} (it needs root, CAP_SYS_NICE or an RLIMIT_RTPRIO of at least {priority})",
            std::io::Error::from_raw_os_error(code)
        ),
        e => anyhow!("SCHED_FIFO priority {priority}: {e}"),
    })
}

/// Whether threads may run under SCHED_FIFO at `priority` here, tried on a thread of its own
/// that then ends (the caller's scheduling is left alone).
pub fn realtime_allowed(priority: u8) -> Result<()> {
    std::thread::spawn(move || set_fifo(priority))
        .join()
        .map_err(|_| anyhow!("the SCHED_FIFO probe thread panicked"))?
}

/// Runs the calling thread (a node's loop) under SCHED_FIFO when `run` asked for it through
/// [`ENV_REALTIME`]. Called as the loop starts, so that the node's start-up (its config,
/// grasp problem and bus) ran at normal priority and cannot hold up other processes starting
/// beside it. A failure is said on stderr, and the loop runs at normal priority.
pub fn promote(name: &str) {
    let Some(value) = std::env::var_os(ENV_REALTIME) else {
        return;
    };
    let result = value
        .to_str()
        .and_then(|v| v.parse::<u8>().ok())
        .ok_or_else(|| anyhow!("{ENV_REALTIME}={value:?}: expected a priority from 1 to 99"))
        .and_then(set_fifo);
    if let Err(e) = result {
        eprintln!("icrflow-{name}: the loop runs at normal priority: {e:#}");
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sched_fifo_priorities_outside_1_to_99_are_refused_by_name() {
        for p in [0, 100, 255] {
            let e = set_fifo(p).unwrap_err().to_string();
            assert!(
                e.contains(&format!("priority {p}: expected 1 to 99")),
                "{e}"
            );
        }
    }

    #[test]
    fn the_sched_fifo_probe_leaves_the_calling_thread_alone() {
        let before = thread_priority::thread_schedule_policy().unwrap();
        // Allowed or not (root or not), the caller's policy is unchanged, and a refusal says
        // what it needs.
        if let Err(e) = realtime_allowed(10) {
            assert!(e.to_string().contains("CAP_SYS_NICE"), "{e}");
        }
        assert_eq!(thread_priority::thread_schedule_policy().unwrap(), before);
    }
}
