//! The event loop every node runs ([`serve`]), and waiting that a termination signal cuts
//! short but another signal does not.

use std::ops::ControlFlow;
use std::time::Duration;

use anyhow::{Context as _, Result, anyhow};
use iceoryx2::port::listener::Listener;
use iceoryx2::prelude::{FileDescriptorBased, ipc};

use crate::node::{Context, promote};

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
/// when [`RESYNC`] has passed since its last wake-up, which bounds such a stall to that
/// period; a loop that ticks more often (the plant) wakes for its ticks only. A termination
/// signal that came while `handle` ran is seen within [`RESYNC`].
pub fn serve<S>(
    ctx: &Context<S>,
    listeners: &[&Listener<ipc::Service>],
    tick: Option<Duration>,
    mut handle: impl FnMut(bool) -> Result<()>,
) -> Result<()> {
    let on = Loop {
        node: ctx.bus.node(),
        name: ctx.name,
        realtime: ctx.launch.realtime,
    };
    on.serve_until(listeners, tick, |ticked| {
        handle(ticked).map(|()| ControlFlow::<()>::Continue(()))
    })
    .map(|_| ())
}

/// Who runs an event loop: the process's iceoryx2 node (whose signal handler records the
/// termination request), its name for messages, and the SCHED_FIFO priority the loop switches
/// to, if any ([`promote`]). [`serve`] runs a node's (at its [`Launch::realtime`]); `icrflow
/// run` waits on its own at normal priority.
///
/// [`Launch::realtime`]: crate::launch::Launch::realtime
#[derive(Clone, Copy)]
pub struct Loop<'a> {
    /// The process's iceoryx2 node.
    pub node: &'a iceoryx2::node::Node<ipc::Service>,
    /// Its name (in error messages).
    pub name: &'a str,
    /// The SCHED_FIFO priority the loop runs at, if any.
    pub realtime: Option<u8>,
}

impl Loop<'_> {
    /// [`serve`]'s loop, which `handle` may also end: it returns
    /// `ControlFlow::Break(b)`, and the loop returns `Some(b)`; `None` after a termination
    /// signal.
    pub fn serve_until<B>(
        self,
        listeners: &[&Listener<ipc::Service>],
        tick: Option<Duration>,
        mut handle: impl FnMut(bool) -> Result<ControlFlow<B>>,
    ) -> Result<Option<B>> {
        use std::time::Instant;

        // Checks for a termination request; the first call installs iceoryx2's signal handler.
        let terminated = || termination_requested(self.node);
        if terminated() {
            return Ok(None);
        }
        let mut waiter = Waiter::new(listeners);
        promote(self.name, self.realtime);
        let start = Instant::now();
        let mut next_tick = tick.map(|t| start + t);
        let mut next_resync = start + RESYNC;
        let mut next_check = next_resync;
        loop {
            let deadline = next_tick.map_or(next_resync, |t| t.min(next_resync));
            let woken = waiter
                .wait(deadline.saturating_duration_since(Instant::now()))
                .with_context(|| format!("{}: waiting for input", self.name))?;
            // A signal: a termination request, or another one (then on as usual).
            if !woken && terminated() {
                return Ok(None);
            }
            let now = Instant::now();
            if now >= next_check {
                next_check = now + RESYNC;
                // A termination request that came while `handle` ran is seen here at the
                // latest.
                if terminated() {
                    return Ok(None);
                }
            }
            let ticked = match (next_tick, tick) {
                (Some(due), Some(period)) if now >= due => {
                    // The next one a period on; missed ones are skipped, not made up in a
                    // burst.
                    let next = due + period;
                    next_tick = Some(if next > now { next } else { now + period });
                    true
                }
                _ => false,
            };
            // Every wake-up reads every input, so the resync is due RESYNC after the last
            // one: a loop that ticks more often than that (the plant at 1 kHz) never wakes
            // for it.
            next_resync = now + RESYNC;
            if let ControlFlow::Break(b) = handle(ticked)? {
                return Ok(Some(b));
            }
        }
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
