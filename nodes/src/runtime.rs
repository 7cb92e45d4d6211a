//! What every node process shares: argument parsing, the run's config and bus, health
//! reports, sequence numbers, simulated noise.

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Duration;

use anyhow::{Context as _, Result, anyhow, bail};
use iceoryx2::port::listener::Listener;
use iceoryx2::prelude::{FileDescriptorBased, LogLevel, ipc, set_log_level};
use icrflow_interfaces::{Header, Kind, NodeHealth, NodeState, now_ns, topics, write_text};
use icrflow_scenario::{Config, Setup};

use crate::bus::{Bus, BusConfig, Pub};

/// A node's context: its config, what the config builds, and its bus connection.
pub struct Context {
    /// Node name.
    pub name: &'static str,
    /// The run's config.
    pub config: Config,
    /// Object, grasp problem, hand, initial contacts.
    pub setup: Setup,
    /// The bus.
    pub bus: Bus,
}

/// Runs node `name`: reads `--config PATH` from the arguments and the bus settings from the
/// environment, builds the context and calls `body`; errors are printed with the node's
/// name and give exit status 1.
pub fn main(name: &'static str, body: fn(&Context) -> Result<()>) -> ExitCode {
    set_log_level(LogLevel::Warn);
    let result = (|| -> Result<()> {
        let supervisor = follow_supervisor()?;
        let args: Vec<String> = std::env::args().skip(1).collect();
        let config = match args.as_slice() {
            [flag, path] if flag == "--config" => PathBuf::from(path),
            _ => bail!("usage: icrflow-{name} --config CONFIG (started by `icrflow run`)"),
        };
        let config = Config::load(&config)?;
        let setup = Setup::new(&config)?;
        let bus = Bus::new(name, &BusConfig::from_env()?)?;
        body(&Context {
            name,
            config,
            setup,
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

/// Period of the wake-up every node's event loop has besides its inputs' events (see
/// [`serve`]).
pub const RESYNC: Duration = Duration::from_millis(10);

/// Node `ctx.name`'s event loop: sleeps until a sender notifies one of `listeners` (the
/// iceoryx2 event of each topic the node waits on), or `tick` (if any) or [`RESYNC`] is due,
/// and calls `handle(ticked)` on every wake-up, `ticked` whether it is `tick`'s; until a
/// termination signal (SIGTERM or SIGINT, as iceoryx2's handler records them) stops it
/// (`Ok`), or `handle` fails (its error). The loop runs under SCHED_FIFO when `run` asked for
/// it ([`promote`]).
///
/// It sleeps in `ppoll(2)` on the listeners' file descriptors, with a timeout to the next
/// deadline, and allocates nothing per wake-up: iceoryx2 0.10's WaitSet, which it replaces,
/// collected the triggered file descriptors in fresh vectors at every wake-up (one or two heap
/// allocations, a node's largest share of them; see `nodes/README.md`).
///
/// `handle` must read every one of its subscribers on every wake-up, whichever woke it
/// (reading is non-blocking and consumes the subscriber's pending events, so the descriptors
/// are quiet again): iceoryx2 0.10's listener can lose a wake-up for good when a notifier
/// sends while the listener is draining (the datagram is consumed, the shared state stays
/// "notified", and later notifiers skip sending; see [`crate::bus`]). So the loop also wakes
/// every [`RESYNC`], which bounds such a stall to that period.
pub fn serve(
    ctx: &Context,
    listeners: &[&Listener<ipc::Service>],
    tick: Option<Duration>,
    mut handle: impl FnMut(bool) -> Result<()>,
) -> Result<()> {
    use std::time::Instant;

    let node = ctx.bus.node();
    // Checks for a termination request; the first call installs iceoryx2's signal handler.
    let terminated = || termination_requested(node);
    if terminated() {
        return Ok(());
    }
    let mut waiter = Waiter::new(listeners);
    promote(ctx.name);
    let start = Instant::now();
    let mut next_tick = tick.map(|t| start + t);
    let mut next_resync = start + RESYNC;
    loop {
        let deadline = next_tick.map_or(next_resync, |t| t.min(next_resync));
        let woken = waiter
            .wait(deadline.saturating_duration_since(Instant::now()))
            .with_context(|| format!("{}: waiting for input", ctx.name))?;
        // A signal: a termination request, or another one (then on as usual).
        if !woken && terminated() {
            return Ok(());
        }
        let now = Instant::now();
        if now >= next_resync {
            next_resync = now + RESYNC;
            // A termination request that came while `handle` ran is seen here at the latest.
            if terminated() {
                return Ok(());
            }
        }
        let ticked = match (next_tick, tick) {
            (Some(due), Some(period)) if now >= due => {
                // The next one a period on; missed ones are skipped, not made up in a burst.
                let next = due + period;
                next_tick = Some(if next > now { next } else { now + period });
                true
            }
            _ => false,
        };
        handle(ticked)?;
    }
}

/// Whether a termination signal (SIGTERM or SIGINT, as iceoryx2's handler records them) has
/// come. Another signal (SIGCONT, SIGWINCH, ...) is not one: it only interrupts a wait.
pub fn termination_requested(node: &iceoryx2::node::Node<ipc::Service>) -> bool {
    matches!(
        node.wait(Duration::ZERO),
        Err(iceoryx2::node::NodeWaitFailure::TerminationRequest)
    )
}

/// Sleeps until `deadline`, or until a termination signal comes: then `true`. Another signal
/// cuts a sleep short; it sleeps on to the deadline.
pub fn sleep_until(
    node: &iceoryx2::node::Node<ipc::Service>,
    deadline: std::time::Instant,
) -> bool {
    loop {
        let left = deadline.saturating_duration_since(std::time::Instant::now());
        if left.is_zero() {
            return termination_requested(node);
        }
        match node.wait(left) {
            Ok(()) => return false,
            Err(iceoryx2::node::NodeWaitFailure::TerminationRequest) => return true,
            Err(iceoryx2::node::NodeWaitFailure::Interrupt) => {}
        }
    }
}

/// Sleeps on listeners' file descriptors (the iceoryx2 events their senders notify) with
/// `ppoll(2)`: allocates nothing per wait. How [`serve`] and the hop benchmark wait.
pub struct Waiter<'a> {
    fds: Vec<nix::poll::PollFd<'a>>,
}

impl<'a> Waiter<'a> {
    /// A waiter on `listeners`.
    pub fn new(listeners: &[&'a Listener<ipc::Service>]) -> Self {
        let fds = listeners
            .iter()
            .map(|l| nix::poll::PollFd::new(descriptor(l), nix::poll::PollFlags::POLLIN))
            .collect();
        Self { fds }
    }

    /// Sleeps until a listener has a notification pending (reading its subscriber consumes
    /// it) or `timeout` has passed: `true`; or a signal came: `false`.
    pub fn wait(&mut self, timeout: Duration) -> Result<bool> {
        let timeout = nix::sys::time::TimeSpec::from_duration(timeout);
        match nix::poll::ppoll(&mut self.fds, Some(timeout), None) {
            Ok(_) => Ok(true),
            Err(nix::errno::Errno::EINTR) => Ok(false),
            Err(e) => Err(anyhow!("ppoll on the listeners failed: {e}")),
        }
    }
}

/// The file descriptor `listener` is woken on, borrowed for as long as the listener.
#[allow(unsafe_code)]
fn descriptor(listener: &Listener<ipc::Service>) -> std::os::fd::BorrowedFd<'_> {
    // SAFETY: `native_handle` is unsafe because the raw descriptor must not outlive its
    // owner, nor be closed by anyone else: the borrow ties it to `listener`, and nothing here
    // closes it (ppoll only reads it).
    unsafe { std::os::fd::BorrowedFd::borrow_raw(listener.file_descriptor().native_handle()) }
}

/// Sequence numbers of one publisher. They start at the current time in microseconds since
/// the Unix epoch and count up by one, so that a restarted publisher continues above its
/// previous incarnation (receivers refuse sequences that do not increase), as long as it
/// publishes below 1 MHz.
#[derive(Debug)]
pub struct Sequence(u64);

impl Default for Sequence {
    fn default() -> Self {
        Self(now_ns() / 1000)
    }
}

impl Sequence {
    /// The next number.
    pub fn advance(&mut self) -> u64 {
        self.0 += 1;
        self.0
    }
}

/// A node's health reports.
pub struct Health {
    publisher: Pub<NodeHealth>,
    sequence: Sequence,
    name: &'static str,
    /// Messages processed.
    pub processed: u64,
    /// Messages refused.
    pub refused: u64,
    /// The last problem.
    pub last_problem: String,
    /// When the last report was published, and the refusals counted by then.
    reported: (u64, u64),
}

/// Period of the health reports ([`Health::tick`]).
pub const HEALTH_PERIOD_NS: u64 = 100_000_000;

impl Health {
    /// Health reports of the context's node.
    pub fn new(ctx: &Context) -> Result<Self> {
        Ok(Self {
            publisher: ctx.bus.publisher(topics::NODE_HEALTH)?,
            sequence: Sequence::default(),
            name: ctx.name,
            processed: 0,
            refused: 0,
            last_problem: String::with_capacity(256),
            reported: (0, 0),
        })
    }

    /// Counts a refused input and remembers why (written into the kept text: no allocation
    /// once it has grown to the longest reason; pass `format_args!`, not `format!`).
    pub fn refuse(&mut self, why: impl std::fmt::Display) {
        use std::fmt::Write as _;
        self.refused += 1;
        self.last_problem.clear();
        let _ = write!(self.last_problem, "{why}");
    }

    /// Accepts a message's header if it is of our schema, of `kind`, and after `last` (then
    /// moved to it); otherwise counts the refusal with `topic` named.
    pub fn accept(&mut self, topic: &str, h: &Header, kind: Kind, last: &mut u64) -> bool {
        if let Err(e) = h.check(kind) {
            self.refuse(format_args!("{topic}: {e}"));
            false
        } else if h.sequence <= *last {
            self.refuse(format_args!("{topic} out of order"));
            false
        } else {
            *last = h.sequence;
            true
        }
    }

    /// Publishes a report if the last is [`HEALTH_PERIOD_NS`] old: `Degraded` if inputs were
    /// refused since the last report, `Running` otherwise. Called on every wake-up.
    pub fn tick(&mut self) -> Result<()> {
        let t = now_ns();
        if t.saturating_sub(self.reported.0) < HEALTH_PERIOD_NS {
            return Ok(());
        }
        let state = if self.refused > self.reported.1 {
            NodeState::Degraded
        } else {
            NodeState::Running
        };
        self.reported = (t, self.refused);
        self.report(state)
    }

    /// Publishes a report.
    pub fn report(&mut self, state: NodeState) -> Result<()> {
        let mut h = NodeHealth {
            header: Header::new(Kind::NodeHealth, self.sequence.advance(), 0, 0),
            state: state as u32,
            pid: std::process::id(),
            processed: self.processed,
            refused: self.refused,
            allocations: allocations(),
            ..Default::default()
        };
        write_text(&mut h.node, self.name);
        write_text(&mut h.message, &self.last_problem);
        self.publisher
            .publish(h)
            .context("publishing health")
            .map(|_| ())
    }
}

/// The allocator every node binary installs (`#[global_allocator]`), so that its health
/// reports count its heap allocations: the steady-state loops are meant to make none.
pub use stats_alloc::INSTRUMENTED_SYSTEM as COUNTING_ALLOCATOR;
/// The type of [`COUNTING_ALLOCATOR`].
pub type CountingAllocator = stats_alloc::StatsAlloc<std::alloc::System>;

/// Heap allocations and reallocations of this process so far (0 if its binary does not
/// install [`COUNTING_ALLOCATOR`]).
pub fn allocations() -> u64 {
    let s = COUNTING_ALLOCATOR.stats();
    (s.allocations + s.reallocations) as u64
}

/// Nanoseconds as seconds.
pub fn seconds(ns: u64) -> f64 {
    ns as f64 * 1e-9
}

/// The time now ([`now_ns`]).
pub fn now() -> u64 {
    now_ns()
}

/// A small deterministic random generator (SplitMix64) with Gaussian samples, for the
/// simulated sensor noise.
#[derive(Debug, Clone)]
pub struct Noise(u64);

impl Noise {
    /// A generator from `seed`.
    pub fn new(seed: u64) -> Self {
        Self(seed ^ 0x5DEE_CE66_D1CE_4E5B)
    }

    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in (0, 1].
    fn unit(&mut self) -> f64 {
        ((self.next() >> 11) as f64 + 1.0) / (1u64 << 53) as f64
    }

    /// A normal sample of standard deviation `sigma` (Box-Muller).
    pub fn gauss(&mut self, sigma: f64) -> f64 {
        if sigma == 0.0 {
            return 0.0;
        }
        let (u, v) = (self.unit(), self.unit());
        sigma * (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
    }
}

/// Period of a [`Checkpoint`]'s writes.
pub const CHECKPOINT_PERIOD: Duration = Duration::from_millis(10);

/// A file in which a node keeps the state a restarted incarnation resumes from, written off
/// the event loop: the loop only stores the newest text in memory ([`Checkpoint::store`]: no
/// system call, no allocation once the text has grown to its longest), and a thread of the
/// node writes it, to a temporary file renamed over the file, every [`CHECKPOINT_PERIOD`] when
/// it changed, and once more when the checkpoint is dropped.
///
/// On the loop itself the write cost the plant and the estimator a tick: a write and a rename
/// take ~1.3 ms p50 (2.6 ms p99) on the test VM's ext4 `/tmp`, so every tenth 1 kHz tick was
/// late and its measurement went out back to back with the next one.
pub struct Checkpoint {
    shared: std::sync::Arc<CheckpointState>,
    writer: Option<std::thread::JoinHandle<()>>,
}

struct CheckpointState {
    /// The newest text, and whether the writer has not taken it yet.
    newest: std::sync::Mutex<(String, bool)>,
    stop: std::sync::atomic::AtomicBool,
}

impl Checkpoint {
    /// Keeps `path` up to date from its own thread (named after the file).
    pub fn new(path: PathBuf) -> Result<Self> {
        let shared = std::sync::Arc::new(CheckpointState {
            newest: std::sync::Mutex::new((String::with_capacity(1024), false)),
            stop: std::sync::atomic::AtomicBool::new(false),
        });
        let state = shared.clone();
        let writer = std::thread::Builder::new()
            .name("checkpoint".into())
            .spawn(move || {
                let tmp = path.with_extension("tmp");
                let mut text = String::with_capacity(1024);
                loop {
                    let stopping = state.stop.load(std::sync::atomic::Ordering::Acquire);
                    let fresh = {
                        let mut newest = state.newest.lock().unwrap_or_else(|e| e.into_inner());
                        let fresh = std::mem::take(&mut newest.1);
                        if fresh {
                            text.clear();
                            text.push_str(&newest.0);
                        }
                        fresh
                    };
                    if fresh && std::fs::write(&tmp, &text).is_ok() {
                        let _ = std::fs::rename(&tmp, &path);
                    }
                    if stopping {
                        return;
                    }
                    std::thread::park_timeout(CHECKPOINT_PERIOD);
                }
            })
            .context("starting the checkpoint thread")?;
        Ok(Self {
            shared,
            writer: Some(writer),
        })
    }

    /// Replaces the text to write by what `fill` writes into the (cleared) kept buffer.
    pub fn store(&self, fill: impl FnOnce(&mut String)) {
        let mut newest = self.shared.newest.lock().unwrap_or_else(|e| e.into_inner());
        newest.0.clear();
        fill(&mut newest.0);
        newest.1 = true;
    }
}

impl Drop for Checkpoint {
    /// Writes the newest text, if the writer has not yet, and stops the thread.
    fn drop(&mut self) {
        self.shared
            .stop
            .store(true, std::sync::atomic::Ordering::Release);
        if let Some(writer) = self.writer.take() {
            writer.thread().unpark();
            let _ = writer.join();
        }
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

    fn scratch(name: &str) -> PathBuf {
        let dir =
            std::env::temp_dir().join(format!("icrflow-checkpoint-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }

    #[test]
    fn checkpoint_writes_the_newest_text_from_its_thread_and_on_drop() {
        let dir = scratch("newest");
        let path = dir.join("node.state");
        let saved = Checkpoint::new(path.clone()).unwrap();
        saved.store(|t| t.push_str("one"));
        saved.store(|t| t.push_str("2 2"));
        // The writer gets there by itself, without a drop.
        let deadline = std::time::Instant::now() + Duration::from_secs(10);
        while std::fs::read_to_string(&path).ok().as_deref() != Some("2 2") {
            assert!(
                std::time::Instant::now() < deadline,
                "the checkpoint thread never wrote the newest text"
            );
            std::thread::sleep(Duration::from_millis(5));
        }
        // The last text stored is written when the checkpoint goes, however soon.
        saved.store(|t| t.push_str("3 3 3"));
        drop(saved);
        assert_eq!(std::fs::read_to_string(&path).unwrap(), "3 3 3");
        assert!(!path.with_extension("tmp").exists(), "temporary file left");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn checkpoint_into_a_missing_directory_fails_quietly() {
        let dir = scratch("missing");
        let path = dir.join("gone").join("node.state");
        let saved = Checkpoint::new(path.clone()).unwrap();
        saved.store(|t| t.push_str("one"));
        drop(saved);
        assert!(!path.exists());
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
