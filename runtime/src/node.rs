//! A node process: what it is started with ([`Launch`]), what it loads, its bus, and its
//! supervisor.

use std::path::Path;
use std::process::ExitCode;

use anyhow::{Context as _, Result, anyhow, bail};

use crate::bus::Bus;
pub use crate::launch::{Launch, LaunchError};

/// A node's context: its name, what it was started with, what it loaded from its config file
/// (`S`: the config, or the config with what it builds), and its bus connection.
pub struct Context<S> {
    /// Node name.
    pub name: &'static str,
    /// What it was started with.
    pub launch: Launch,
    /// What the node loaded from [`Launch::config`].
    pub scenario: S,
    /// The bus.
    pub bus: Bus,
}

/// Runs node `name`: reads what it was started with from its arguments ([`Launch::parse`]),
/// then as [`main_launched`].
pub fn main<S>(
    name: &'static str,
    load: fn(&Path) -> Result<S>,
    body: fn(&Context<S>) -> Result<()>,
) -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    main_launched(name, Launch::parse(&args), load, body)
}

/// Runs node `name` started with `launch` (parsed by the caller: a binary with modes of its
/// own flattens [`crate::launch::LaunchArgs`] into its command line): follows its supervisor,
/// loads the config with `load`, builds the context and calls `body`; errors (a malformed
/// launch among them) are printed with the node's name and give exit status 1.
pub fn main_launched<S>(
    name: &'static str,
    launch: Result<Launch, LaunchError>,
    load: fn(&Path) -> Result<S>,
    body: fn(&Context<S>) -> Result<()>,
) -> ExitCode {
    crate::bus::set_up_logging();
    let result = (|| -> Result<()> {
        let launch = launch.with_context(|| {
            format!(
                "icrflow-{name} is started by `icrflow run` (see icrflow_runtime::launch for its arguments)"
            )
        })?;
        let supervisor = follow_supervisor(launch.supervisor)?;
        let scenario = load(&launch.config)?;
        let bus = Bus::new(name, &launch.bus)?;
        body(&Context {
            name,
            launch,
            scenario,
            bus,
        })?;
        // Stopped by the supervisor's death (its SIGTERM, above). iceoryx2 removes the dead
        // supervisor's node as the last nodes leave; its directory is the next run's to remove.
        if let Some(pid) = supervisor
            && std::os::unix::process::parent_id() != pid
        {
            // One write: the nodes stop at once, and their lines must not interleave on the
            // stderr they share (eprintln! writes a line in pieces).
            let line = format!("icrflow-{name}: stopped: its supervisor (pid {pid}) died\n");
            let _ = std::io::Write::write_all(&mut std::io::stderr(), line.as_bytes());
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

/// With a supervisor ([`Launch::supervisor`]): asks the kernel for SIGTERM when the parent
/// dies (`PR_SET_PDEATHSIG`) and checks that the parent is that supervisor still (it may have
/// died before). Returns the supervisor's pid.
fn follow_supervisor(supervisor: Option<u32>) -> Result<Option<u32>> {
    let Some(pid) = supervisor else {
        return Ok(None);
    };
    nix::sys::prctl::set_pdeathsig(nix::sys::signal::Signal::SIGTERM)
        .context("asking for SIGTERM when the supervisor dies (prctl PR_SET_PDEATHSIG)")?;
    if std::os::unix::process::parent_id() != pid {
        bail!("its supervisor (pid {pid}) is gone; not starting");
    }
    Ok(Some(pid))
}

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

/// Runs the calling thread (node `name`'s loop) under SCHED_FIFO at `priority` when `run`
/// asked for it ([`Launch::realtime`]). Called as the loop starts, so that the node's
/// start-up (its config, grasp problem and bus) ran at normal priority and cannot hold up
/// other processes starting beside it. A failure is said on stderr, and the loop runs at
/// normal priority.
pub fn promote(name: &str, priority: Option<u8>) {
    let Some(priority) = priority else {
        return;
    };
    if let Err(e) = set_fifo(priority) {
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
