//! What `run` measures over the run besides the plan: the latencies of the tracking commands
//! ([`Timing`]), the streams' rates ([`Rate`]), the nodes' steady-state allocations
//! ([`AllocationTrack`]), and each process's scheduling and memory from `/proc`.

use std::time::Instant;

use icrflow_interfaces::TRACE_STAMPS;

use super::histogram::Histogram;
use super::summary::{Allocations, Hops, Latencies, Stages};
use super::watch::WARM_UP;

/// Per node: the running process's first health report, its baseline (the first report after
/// [`WARM_UP`]: allocations, processed, when) and its last; plus the finished incarnations'
/// steady-state figures.
#[derive(Default)]
pub(super) struct AllocationTrack {
    pid: u32,
    first: Option<Instant>,
    base: Option<(u64, u64, Instant)>,
    last: Option<(u64, u64, Instant)>,
    done: Allocations,
}

impl AllocationTrack {
    pub(super) fn report(&mut self, pid: u32, allocations: u64, processed: u64, now: Instant) {
        if pid != self.pid {
            self.done = self.total();
            *self = Self {
                pid,
                first: Some(now),
                done: self.done,
                ..Self::default()
            };
        }
        if self.base.is_none() && self.first.is_some_and(|f| now.duration_since(f) >= WARM_UP) {
            self.base = Some((allocations, processed, now));
        }
        self.last = Some((allocations, processed, now));
    }

    pub(super) fn total(&self) -> Allocations {
        let mut a = self.done;
        if let (Some((allocations, processed, when)), Some(last)) = (self.base, self.last) {
            a.steady += last.0.saturating_sub(allocations);
            a.processed += last.1.saturating_sub(processed);
            a.seconds += last.2.duration_since(when).as_secs_f64();
        }
        a
    }
}

/// Latency samples of the critical path, from the traces of the tracking commands.
pub(super) struct Timing {
    end_to_end: Histogram,
    hops: [Histogram; 3],
    stages: [Histogram; 3],
}

impl Timing {
    pub(super) fn new() -> Self {
        Self {
            end_to_end: Histogram::new(),
            hops: std::array::from_fn(|_| Histogram::new()),
            stages: std::array::from_fn(|_| Histogram::new()),
        }
    }

    /// Adds a tracking command's trace `[measured, estimator in, out, wrench in, out,
    /// command in, out]`; other traces (a chain cut by a restart) are skipped.
    pub(super) fn add(&mut self, trace: &[u64]) {
        let &[t0, ..] = trace else { return };
        if trace.len() != TRACE_STAMPS {
            return;
        }
        let us = |a: u64, b: u64| b.saturating_sub(a) as f64 * 1e-3;
        self.end_to_end.add(us(t0, trace[6]));
        for k in 0..3 {
            self.hops[k].add(us(trace[2 * k], trace[2 * k + 1]));
            self.stages[k].add(us(trace[2 * k + 1], trace[2 * k + 2]));
        }
    }

    pub(super) fn summary(&self) -> Latencies {
        let [h0, h1, h2] = &self.hops;
        let [s0, s1, s2] = &self.stages;
        Latencies {
            end_to_end: self.end_to_end.percentiles(),
            transport: Hops {
                joint_state: h0.percentiles(),
                grasp_state: h1.percentiles(),
                wrench_space: h2.percentiles(),
            },
            compute: Stages {
                estimator: s0.percentiles(),
                wrench: s1.percentiles(),
                command: s2.percentiles(),
            },
        }
    }
}

/// A stream's rate while it flows: what its count grew by between the first and the last time
/// it was seen to grow, over that time.
#[derive(Default)]
pub(super) struct Rate {
    first: Option<(Instant, u64)>,
    last: Option<(Instant, u64)>,
}

impl Rate {
    /// The count is now `total`.
    pub(super) fn saw(&mut self, total: u64) {
        if total == 0 || self.last.is_some_and(|(_, n)| n == total) {
            return;
        }
        let now = Instant::now();
        self.first.get_or_insert((now, total));
        self.last = Some((now, total));
    }

    /// Per second between the first and the last sighting (0 before two).
    pub(super) fn hz(&self) -> f64 {
        match (self.first, self.last) {
            (Some((t0, n0)), Some((t1, n1))) if t1 > t0 => {
                (n1 - n0) as f64 / t1.duration_since(t0).as_secs_f64()
            }
            _ => 0.0,
        }
    }
}

/// The scheduling policy of process `pid`'s main thread (a node's loop) from `/proc`
/// (`"fifo 50"`, `"normal"`, ...).
pub(super) fn scheduling(pid: u32) -> Option<String> {
    let stat = std::fs::read_to_string(format!("/proc/{pid}/stat")).ok()?;
    // After the command name (in parentheses, which may hold spaces): state is field 3,
    // rt_priority field 40, policy field 41.
    let fields: Vec<&str> = stat.rsplit_once(')')?.1.split_whitespace().collect();
    let (priority, policy) = (fields.get(37)?, fields.get(38)?.parse::<u32>().ok()?);
    Some(match policy {
        0 => "normal".to_string(),
        1 => format!("fifo {priority}"),
        2 => format!("rr {priority}"),
        3 => "batch".to_string(),
        5 => "idle".to_string(),
        6 => "deadline".to_string(),
        p => format!("policy {p}"),
    })
}

/// The resident set size of process `pid` (KiB), from `/proc`.
pub(super) fn resident_kib(pid: u32) -> Option<u64> {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).ok()?;
    status
        .lines()
        .find_map(|l| l.strip_prefix("VmRSS:"))?
        .split_whitespace()
        .next()?
        .parse()
        .ok()
}
