//! A node's health report, its publishers' sequence numbers, and its heap allocations.

use anyhow::{Context as _, Result};
use icrflow_interfaces::{Header, Kind, NodeHealth, NodeState, now_ns, topics, write_text};

use crate::bus::Pub;
use crate::node::Context;

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
    pub fn new<S>(ctx: &Context<S>) -> Result<Self> {
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

    /// Publishes a `Starting` report whose message says what the node does meanwhile
    /// (`planning: 45 % (162 of 360 deg)`), if the last report is [`HEALTH_PERIOD_NS`] old or
    /// `now`. A node that starts up reports so: `icrflow run` shows it, and does not take the
    /// pause between two such reports for a hang.
    pub fn starting(&mut self, doing: std::fmt::Arguments<'_>, now: bool) -> Result<()> {
        let t = now_ns();
        if !now && t.saturating_sub(self.reported.0) < HEALTH_PERIOD_NS {
            return Ok(());
        }
        self.reported.0 = t;
        let mut h = self.health(NodeState::Starting);
        write_text(&mut h.message, &std::fmt::format(doing));
        self.send(h)
    }

    /// Publishes a report.
    pub fn report(&mut self, state: NodeState) -> Result<()> {
        let mut h = self.health(state);
        write_text(&mut h.message, &self.last_problem);
        self.send(h)
    }

    /// A report of `state`, without its message.
    fn health(&mut self, state: NodeState) -> NodeHealth {
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
        h
    }

    /// Publishes `h`.
    fn send(&mut self, h: NodeHealth) -> Result<()> {
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
