//! The run's summary: what `run` prints at the end, and writes as JSON with
//! `--summary-json` ([`RunSummary`]).

use std::io::Write;
use std::path::Path;

use anyhow::Result;
use icrflow_interfaces::topics::NodeRole;
use icrflow_scenario::{Config, Recording};
use serde::Serialize;

use super::track::EstimateError;
use super::watch::{Seen, WARM_UP};

/// The run's Rerun recording.
#[derive(Debug, Serialize, Default)]
pub struct RecordingSummary {
    /// The `.rrd` file (or `spawned viewer`, or the viewer's URL).
    pub target: String,
    /// The recording id.
    pub id: String,
    /// Frames the visualizer recorded (plan steps, scene and time-series frames).
    pub frames: u64,
    /// Frames it dropped because the recording lagged.
    pub dropped: u64,
}

/// Latency percentiles (microseconds).
#[derive(Debug, Serialize, Default, Clone, Copy)]
pub struct Percentiles {
    /// Median.
    pub p50: f64,
    /// 99th percentile.
    pub p99: f64,
    /// Largest.
    pub max: f64,
    /// Samples.
    pub samples: usize,
}

/// Latency samples (us) in a fixed histogram of buckets 1 % wide from 1 us to about 100 s, so
/// that a long `--live` run keeps constant memory. Percentiles are bucket upper bounds (within
/// 1 % above the true value, never above the largest sample); the largest sample is exact.
#[derive(Debug, Clone)]
pub(crate) struct Histogram {
    counts: Vec<u64>,
    samples: u64,
    max: f64,
}

impl Histogram {
    const GROWTH: f64 = 1.01;
    const BUCKETS: usize = 1852; // 1.01^1851 > 1e8

    pub(crate) fn new() -> Self {
        Self {
            counts: vec![0; Self::BUCKETS],
            samples: 0,
            max: 0.0,
        }
    }

    pub(crate) fn add(&mut self, us: f64) {
        let bucket = if us <= 1.0 {
            0
        } else {
            ((us.ln() / Self::GROWTH.ln()).ceil() as usize).min(Self::BUCKETS - 1)
        };
        self.counts[bucket] += 1;
        self.samples += 1;
        self.max = self.max.max(us);
    }

    fn at(&self, q: f64) -> f64 {
        let rank = ((q * self.samples as f64).ceil() as u64).clamp(1, self.samples);
        let mut seen = 0;
        for (bucket, count) in self.counts.iter().enumerate() {
            seen += count;
            if seen >= rank {
                return Self::GROWTH.powi(bucket as i32).min(self.max);
            }
        }
        self.max
    }

    pub(crate) fn percentiles(&self) -> Percentiles {
        if self.samples == 0 {
            return Percentiles::default();
        }
        Percentiles {
            p50: self.at(0.5),
            p99: self.at(0.99),
            max: self.max,
            samples: self.samples as usize,
        }
    }
}

/// The run's summary (`--summary-json`).
#[derive(Debug, Serialize)]
pub struct RunSummary {
    /// Whether the goal was reached.
    pub completed: bool,
    /// Why the run ended.
    pub reason: String,
    /// Object rotation reached, from the state estimate (deg).
    pub rotation_deg: f64,
    /// Goal (deg).
    pub goal_deg: f64,
    /// Finger switches executed (attach steps reached).
    pub switches: usize,
    /// The last plan step commanded (the plan's step number; the start is 0), i.e. the number
    /// of plan steps executed after the start.
    pub steps: usize,
    /// Times the planner node planned again from the estimate (the object stopped off its
    /// target, e.g. after `pipeline.slip_deg`): `start` plan steps after step 0.
    pub replans: usize,
    /// Smallest quality alpha* of the grasp a tracking command was computed with.
    pub min_quality: f64,
    /// The margin.
    pub alpha: f64,
    /// Node restarts by the supervisor.
    pub restarts: u32,
    /// Hand commands that held.
    pub holds: u64,
    /// Hand commands sent (one per joint measurement that reached the command node; holds
    /// when none came for three periods).
    pub commands: u64,
    /// Joint measurements the plant published (`pipeline.rate_hz` nominal; a tick the plant
    /// was not scheduled for in time is skipped).
    pub measurements: u64,
    /// Measurements per second while they flow (from the first to the last the run saw: the
    /// start-up before the plant's first tick is not counted).
    pub measurement_rate_hz: f64,
    /// Hand commands per second while they flow (from the first to the last).
    pub command_rate_hz: f64,
    /// Tracking commands made (their source time) from a joint measurement older than
    /// `pipeline.max_input_age_ms` plus 10 ms (the command's computation after the node's
    /// check): should be 0, the hand command node holds instead.
    pub stale_tracked: u64,
    /// Wall time (s).
    pub seconds: f64,
    /// The run's iceoryx2 prefix (its shared-memory objects are `/dev/shm/<prefix>*`).
    pub bus_prefix: String,
    /// The run's iceoryx2 root directory (removed at the end).
    pub bus_root: String,
    /// Latency of the critical path, end to end and per stage (us).
    pub latency_us: Latencies,
    /// The planner's plan-step stream.
    pub plan_steps: PlanStream,
    /// Resident memory of each node process, sampled every second (KiB).
    pub memory_kib: std::collections::BTreeMap<String, Memory>,
    /// The scheduling policy of each node process's main thread (its loop), as last sampled
    /// (`"fifo 50"`, `"normal"`): `pipeline.realtime_priority` at work.
    pub scheduling: std::collections::BTreeMap<String, String>,
    /// Per node: heap allocations in the steady state (from its health reports).
    pub allocations: std::collections::BTreeMap<String, Allocations>,
    /// The Rerun recording (absent without the visualizer).
    pub recording: Option<RecordingSummary>,
    /// The estimate against the simulated plant's truth (`None` where no truth comes: the
    /// plant on another host).
    pub estimate: Option<EstimateError>,
    /// Hold commands because the estimate was off (its residuals over their bounds).
    pub estimate_holds: u64,
}

/// Latency percentiles of the tracking commands: from the plant's joint measurement to the
/// hand command it caused, and its parts, from the commands' traces
/// ([`icrflow_interfaces::Trace`]).
#[derive(Debug, Serialize, Default)]
pub struct Latencies {
    /// Joint measurement published to hand command published.
    pub end_to_end: Percentiles,
    /// Each hop's transport: publication to the next process taking the message off the bus
    /// (iceoryx2 delivery, the event that wakes the receiver, and its scheduling).
    pub transport: Hops,
    /// Each process's computation: input taken off the bus to output published.
    pub compute: Stages,
}

/// Per-hop transport latencies of the critical path.
#[derive(Debug, Serialize, Default)]
pub struct Hops {
    /// Plant to estimator.
    pub joint_state: Percentiles,
    /// Estimator to wrench-space node.
    pub grasp_state: Percentiles,
    /// Wrench-space node to hand command node.
    pub wrench_space: Percentiles,
}

/// Per-process computation latencies of the critical path.
#[derive(Debug, Serialize, Default)]
pub struct Stages {
    /// Joint state to grasp state.
    pub estimator: Percentiles,
    /// Grasp state to wrench space.
    pub wrench: Percentiles,
    /// Wrench space (with its grasp state and the plan step) to hand command.
    pub command: Percentiles,
}

/// The plan-step stream.
#[derive(Debug, Serialize, Default)]
pub struct PlanStream {
    /// Plan steps published (the current target at the stream's rate, and each new one).
    pub published: u64,
    /// Mean rate while the stream flows, from the first step the run saw to the last (Hz).
    pub rate_hz: f64,
    /// The planner's time from taking up a step to publishing it (us).
    pub compute_us: Percentiles,
}

/// Resident memory of one process over the run (KiB).
#[derive(Debug, Serialize, Default, Clone, Copy)]
pub struct Memory {
    /// At the first sample.
    pub first: u64,
    /// At the last sample.
    pub last: u64,
    /// The largest sample.
    pub max: u64,
    /// Samples.
    pub samples: usize,
}

/// A node's heap allocations in its steady state, from its health reports: counted from its
/// first report [`WARM_UP`] after its process started (each incarnation of a restarted node
/// on its own), to its last.
#[derive(Debug, Serialize, Default, Clone, Copy)]
pub struct Allocations {
    /// Allocations (and reallocations) in the steady state.
    pub steady: u64,
    /// Messages the node processed meanwhile.
    pub processed: u64,
    /// Seconds of steady state observed.
    pub seconds: f64,
}

/// What the summary says besides what the watch saw.
pub(super) struct Facts {
    /// The goal (rad).
    pub goal: f64,
    /// The margin.
    pub alpha: f64,
    /// Node restarts by the supervisor.
    pub restarts: u32,
    /// Wall time (s).
    pub seconds: f64,
    /// The run's bus.
    pub bus: icrflow_runtime::bus::BusConfig,
    /// The recording's target and id, if any.
    pub recording: Option<(String, String)>,
}

impl RunSummary {
    /// The summary of what the watch saw.
    pub(super) fn new(seen: Seen, facts: Facts) -> Self {
        Self {
            completed: seen.done && seen.rotation >= facts.goal - 0.5f64.to_radians(),
            reason: seen.stop.to_string(),
            rotation_deg: seen.rotation.to_degrees(),
            goal_deg: facts.goal.to_degrees(),
            switches: seen.attaches,
            replans: seen.replans,
            steps: seen.steps,
            min_quality: if seen.min_quality.is_finite() {
                seen.min_quality
            } else {
                0.0
            },
            alpha: facts.alpha,
            restarts: facts.restarts,
            holds: seen.holds,
            commands: seen.sent,
            measurements: seen.measurements,
            measurement_rate_hz: seen.measurement_rate_hz,
            command_rate_hz: seen.command_rate_hz,
            stale_tracked: seen.stale_tracked,
            seconds: facts.seconds,
            bus_prefix: facts.bus.prefix.clone(),
            bus_root: facts.bus.root.display().to_string(),
            latency_us: seen.latencies,
            plan_steps: seen.plan_steps,
            memory_kib: seen.memory,
            scheduling: seen.scheduling,
            allocations: seen.allocations,
            estimate: seen.estimate,
            estimate_holds: seen.estimate_holds,
            recording: facts.recording.map(|(target, id)| RecordingSummary {
                target,
                id,
                frames: seen.frames.0,
                dropped: seen.frames.1,
            }),
        }
    }

    /// Prints the summary of the run of `config_path` on stdout (`recording`: where the
    /// recording went).
    pub(super) fn print(
        &self,
        config_path: &Path,
        config: &Config,
        recording: Option<&Recording>,
    ) -> Result<()> {
        let summary = self;
        let mut o = std::io::stdout().lock();
        writeln!(
            o,
            "run        {} ({})",
            config_path.display(),
            summary.reason
        )?;
        writeln!(
            o,
            "rotation   {:.1} deg of {:.1} deg, {} plan steps, {} finger switches{}",
            summary.rotation_deg,
            summary.goal_deg,
            summary.steps,
            summary.switches,
            match summary.replans {
                0 => String::new(),
                n => format!(", planned again from the estimate {n} time(s)"),
            }
        )?;
        if config
            .pipeline
            .nodes
            .iter()
            .any(|n| n == NodeRole::Command.name())
        {
            summary.print_loop(&mut o, config)?;
        } else {
            writeln!(
                o,
                "commands   none here: the hand command node runs on another host (its run reports them)"
            )?;
        }
        summary.print_rest(&mut o, recording)
    }

    /// The lines on the loop's commands (when the hand command node runs here).
    fn print_loop(&self, o: &mut impl Write, config: &Config) -> Result<()> {
        let summary = self;
        writeln!(
            o,
            "quality    minimum alpha* while tracking = {:.6} (alpha = {})",
            summary.min_quality, summary.alpha
        )?;
        if let Some(e) = &summary.estimate {
            writeln!(
                o,
                "estimate   off the plant's truth p50 {:.2} / p99 {:.2} / max {:.2} deg; {} tracking commands beyond the bound ({:.1} deg), {} holds for the estimate",
                e.rotation_deg.p50,
                e.rotation_deg.p99,
                e.rotation_deg.max,
                e.tracked_off_truth,
                config.pipeline.max_pose_innovation.to_degrees(),
                summary.estimate_holds
            )?;
        }
        writeln!(
            o,
            "commands   {} sent ({:.0} Hz; {:.0} Hz of joint measurements), {} holds; {} node restarts; {:.1} s",
            summary.commands,
            summary.command_rate_hz,
            summary.measurement_rate_hz,
            summary.holds,
            summary.restarts,
            summary.seconds
        )?;
        let l = &summary.latency_us;
        writeln!(
            o,
            "latency    joint measurement to hand command p50 {:.0} us, p99 {:.0} us, max {:.0} us ({} commands)",
            l.end_to_end.p50, l.end_to_end.p99, l.end_to_end.max, l.end_to_end.samples
        )?;
        writeln!(
            o,
            "           hops p50 {:.0} / {:.0} / {:.0} us, compute p50 {:.0} / {:.0} / {:.0} us (estimator, wrench space, command)",
            l.transport.joint_state.p50,
            l.transport.grasp_state.p50,
            l.transport.wrench_space.p50,
            l.compute.estimator.p50,
            l.compute.wrench.p50,
            l.compute.command.p50
        )?;
        Ok(())
    }

    /// The plan stream, the processes and the recording.
    fn print_rest(&self, o: &mut impl Write, recording: Option<&Recording>) -> Result<()> {
        let summary = self;
        writeln!(
            o,
            "plan       {} plan steps published, {:.0} Hz",
            summary.plan_steps.published, summary.plan_steps.rate_hz
        )?;
        let grew: Vec<String> = summary
            .memory_kib
            .iter()
            .map(|(n, m)| format!("{n} {}->{} KiB", m.first, m.last))
            .collect();
        writeln!(o, "memory     {}", grew.join(", "))?;
        let realtime: Vec<&str> = summary
            .scheduling
            .iter()
            .filter(|(_, p)| p.starts_with("fifo") || p.starts_with("rr"))
            .map(|(n, _)| n.as_str())
            .collect();
        if let Some(policy) = realtime.first().and_then(|n| summary.scheduling.get(*n)) {
            writeln!(
                o,
                "priority   {} at SCHED_{}",
                realtime.join(", "),
                policy.to_uppercase()
            )?;
        }
        let allocs: Vec<String> = summary
            .allocations
            .iter()
            .map(|(n, a)| format!("{n} {} in {:.0} s", a.steady, a.seconds))
            .collect();
        writeln!(
            o,
            "allocs     steady state (from {} s after each start): {}",
            WARM_UP.as_secs(),
            allocs.join(", ")
        )?;
        if let Some(r) = &summary.recording {
            let open = match &recording {
                Some(Recording::Rrd(p)) => {
                    let names: Vec<String> = icrflow_scenario::rrd_parts(p)
                        .iter()
                        .map(|f| f.display().to_string())
                        .collect();
                    if names.is_empty() {
                        format!(
                            "none: the visualizer wrote no {} (see its messages above)",
                            p.display()
                        )
                    } else {
                        format!(
                            "saved to {} (open it: rerun {})",
                            names.join(", "),
                            names.join(" ")
                        )
                    }
                }
                _ => format!("streamed to the {}", r.target),
            };
            writeln!(
                o,
                "recording  {open}; {} frames, {} dropped",
                r.frames, r.dropped
            )?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn histogram_percentiles_are_within_one_percent_above_the_exact_ones() {
        // Latency-like samples from 0.3 us to ~60 ms (a deterministic spread).
        let mut exact: Vec<f64> = (0..20_000u64)
            .map(|i| 0.3 * (1.0 + (i * 7919 % 20_000) as f64).powf(1.3))
            .collect();
        let mut h = Histogram::new();
        for &x in &exact {
            h.add(x);
        }
        exact.sort_by(f64::total_cmp);
        let p = h.percentiles();
        assert_eq!(p.samples, exact.len());
        assert_eq!(p.max, exact[exact.len() - 1]);
        for (q, got) in [(0.5, p.p50), (0.99, p.p99)] {
            let want = exact[(q * exact.len() as f64).ceil() as usize - 1];
            assert!(
                got >= want && got <= want.max(1.0) * 1.01,
                "q {q}: {got} vs exact {want}"
            );
        }
        assert_eq!(Histogram::new().percentiles().samples, 0);
    }
}
