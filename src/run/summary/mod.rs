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
    /// Hand commands that held after the start-up (the start-up's are `startup_holds`).
    pub holds: u64,
    /// `holds` by cause: the reason's text before its details, numbers as `N`
    /// (`"grasp state is stale"`, `"the estimate is off"`).
    pub hold_causes: std::collections::BTreeMap<String, u64>,
    /// Hand commands that held in the start-up: before the hand first tracked, for an input
    /// not there yet (the plan, while the planner node plans). They are not holds of the run,
    /// and do not count towards `pipeline.max_hold_s`.
    pub startup_holds: u64,
    /// Seconds from the start of the loop's processes to the first plan step (`None`: none
    /// came).
    pub planned_after_s: Option<f64>,
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
    /// What MuJoCo's truth says of the run (a MuJoCo plant only; see `src/run/physics.rs`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub physics: Option<super::physics::PhysicsSummary>,
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
            completed: seen.done
                && seen.rotation >= facts.goal - icrflow_plan::follow::GOAL_TOLERANCE,
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
            hold_causes: seen.hold_causes,
            startup_holds: seen.startup_holds,
            planned_after_s: seen.planned_after,
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
            physics: seen.physics,
            recording: facts.recording.map(|(target, id)| RecordingSummary {
                target,
                id,
                frames: seen.frames.0,
                dropped: seen.frames.1,
            }),
        }
    }

    /// Prints the summary of the run of `config_path` on stdout (`recording`: where the
    /// recording went): what a researcher looks for first (the goal, the rotation, the
    /// switches, the quality, the holds and their causes, restarts, latency), in lines of at
    /// most ~100 columns; `verbose` adds the rates, the latency's parts, the plan stream and
    /// each process's memory, scheduling and allocations.
    pub(super) fn print(
        &self,
        config_path: &Path,
        config: &Config,
        recording: Option<&Recording>,
        verbose: bool,
    ) -> Result<()> {
        let s = self;
        let mut o = std::io::stdout().lock();
        writeln!(o, "run        {}", config_path.display())?;
        writeln!(
            o,
            "outcome    {} after {:.1} s",
            if s.completed {
                "goal reached"
            } else {
                "goal NOT reached"
            },
            s.seconds
        )?;
        if !s.completed || s.reason != "goal reached" {
            for line in wrap(&s.reason, 89) {
                writeln!(o, "           {line}")?;
            }
        }
        writeln!(
            o,
            "rotation   {:.1} of {:.1} deg, {} finger switches, {} plan steps{}",
            s.rotation_deg,
            s.goal_deg,
            s.switches,
            s.steps,
            match s.replans {
                0 => String::new(),
                n => format!(", planned again {n}x"),
            }
        )?;
        let here = config
            .pipeline
            .nodes
            .iter()
            .any(|n| n == NodeRole::Command.name());
        if here {
            s.print_loop(&mut o, config, verbose)?;
        } else {
            writeln!(
                o,
                "commands   none here: the hand command node runs on another host (its run reports them)"
            )?;
            writeln!(o, "restarts   {}", s.restarts)?;
        }
        if verbose {
            s.print_processes(&mut o)?;
        }
        s.print_recording(&mut o, recording)
    }

    /// The lines on the loop's commands (when the hand command node runs here).
    fn print_loop(&self, o: &mut impl Write, config: &Config, verbose: bool) -> Result<()> {
        let s = self;
        writeln!(
            o,
            "quality    minimum alpha* while tracking {:.6} {} alpha = {}",
            s.min_quality,
            if s.min_quality >= s.alpha { ">=" } else { "<" },
            s.alpha
        )?;
        let causes: Vec<String> = s
            .hold_causes
            .iter()
            .map(|(cause, n)| format!("{n} {cause}"))
            .collect();
        if causes.is_empty() {
            writeln!(o, "holds      none")?;
        } else {
            let text = format!("{}: {}", s.holds, causes.join(", "));
            for (i, line) in wrap_at(&text, ", ", 89).iter().enumerate() {
                writeln!(
                    o,
                    "{}{line}",
                    if i == 0 { "holds      " } else { "           " }
                )?;
            }
        }
        match s.planned_after_s {
            Some(t) => writeln!(
                o,
                "start-up   the plan came after {t:.1} s; the hand held its grasp meanwhile ({} commands)",
                s.startup_holds
            )?,
            None => writeln!(
                o,
                "start-up   no plan step came; the hand held its grasp ({} commands)",
                s.startup_holds
            )?,
        }
        writeln!(o, "restarts   {}", s.restarts)?;
        let l = &s.latency_us;
        writeln!(
            o,
            "latency    measurement to command p50 {:.0} us, p99 {:.0} us, max {:.0} us ({} commands)",
            l.end_to_end.p50, l.end_to_end.p99, l.end_to_end.max, l.end_to_end.samples
        )?;
        if let Some(e) = &s.estimate {
            writeln!(
                o,
                "estimate   off the truth p50 {:.2} / p99 {:.2} / max {:.2} deg; {} tracked beyond {:.1} deg",
                e.rotation_deg.p50,
                e.rotation_deg.p99,
                e.rotation_deg.max,
                e.tracked_off_truth,
                config.pipeline.max_pose_innovation.to_degrees(),
            )?;
        }
        if let Some(p) = &s.physics {
            writeln!(
                o,
                "physics    {}: the object turned {:.1} deg, its centre moved at most {:.2} mm{}",
                p.engine,
                p.rotation_deg,
                p.drift_m * 1e3,
                if p.dropped { "; DROPPED" } else { "" }
            )?;
            writeln!(
                o,
                "           contacts planned to roll: slip up to {:.1} mm/s, friction use up to {:.2} of mu, {} lost while planned",
                p.max_slip_m_s * 1e3,
                p.max_friction_use,
                p.unplanned_losses
            )?;
            for l in &p.losses {
                writeln!(
                    o,
                    "           lost: finger {} at {:.2} s (step {}, {}; the object at {:.1} deg)",
                    l.finger, l.at_s, l.step, l.phase, l.rotation_deg
                )?;
            }
            match p.min_true_quality {
                Some(q) => writeln!(
                    o,
                    "           true grasp quality >= {q:.3} (alpha {}) over {} plan steps, {} not in force closure",
                    config.grasp.alpha, p.steps_evaluated, p.steps_not_closed
                )?,
                None => writeln!(o, "           no plan step's true grasp was evaluated")?,
            }
            for n in &p.not_closed {
                writeln!(
                    o,
                    "           not in force closure: step {} ({}) at {:.2} s, fingers {:?} touching, the object at {:.1} deg",
                    n.step, n.phase, n.at_s, n.fingers, n.rotation_deg
                )?;
            }
            if let (1.., Some(q)) = (p.steps_not_closed, p.min_true_quality_closed) {
                writeln!(
                    o,
                    "           the steps in force closure: true grasp quality >= {q:.3}"
                )?;
            }
        }
        if verbose {
            writeln!(
                o,
                "commands   {} sent ({:.0} Hz; joint measurements {:.0} Hz), {} stale-tracked",
                s.commands, s.command_rate_hz, s.measurement_rate_hz, s.stale_tracked
            )?;
            writeln!(
                o,
                "           hops p50 {:.0} / {:.0} / {:.0} us, compute p50 {:.0} / {:.0} / {:.0} us",
                l.transport.joint_state.p50,
                l.transport.grasp_state.p50,
                l.transport.wrench_space.p50,
                l.compute.estimator.p50,
                l.compute.wrench.p50,
                l.compute.command.p50
            )?;
            writeln!(
                o,
                "           (hops: plant, estimator, wrench space; compute: estimator, wrench, command)"
            )?;
        }
        Ok(())
    }

    /// The plan stream and each process's memory, scheduling and allocations (`--verbose`).
    fn print_processes(&self, o: &mut impl Write) -> Result<()> {
        let s = self;
        writeln!(
            o,
            "plan       {} plan steps published, {:.0} Hz",
            s.plan_steps.published, s.plan_steps.rate_hz
        )?;
        let grew: Vec<String> = s
            .memory_kib
            .iter()
            .map(|(n, m)| format!("{n} {}->{} KiB", m.first, m.last))
            .collect();
        for (i, line) in wrap_at(&grew.join(", "), ", ", 89).iter().enumerate() {
            writeln!(
                o,
                "{}{line}",
                if i == 0 { "memory     " } else { "           " }
            )?;
        }
        let realtime: Vec<&str> = s
            .scheduling
            .iter()
            .filter(|(_, p)| p.starts_with("fifo") || p.starts_with("rr"))
            .map(|(n, _)| n.as_str())
            .collect();
        if let Some(policy) = realtime.first().and_then(|n| s.scheduling.get(*n)) {
            writeln!(
                o,
                "priority   {} at SCHED_{}",
                realtime.join(", "),
                policy.to_uppercase()
            )?;
        }
        let allocs: Vec<String> = s
            .allocations
            .iter()
            .map(|(n, a)| format!("{n} {} in {:.0} s", a.steady, a.seconds))
            .collect();
        let text = format!(
            "steady state (from {} s after each start): {}",
            WARM_UP.as_secs(),
            allocs.join(", ")
        );
        for (i, line) in wrap_at(&text, ", ", 89).iter().enumerate() {
            writeln!(
                o,
                "{}{line}",
                if i == 0 { "allocs     " } else { "           " }
            )?;
        }
        Ok(())
    }

    /// Where the recording went.
    fn print_recording(&self, o: &mut impl Write, recording: Option<&Recording>) -> Result<()> {
        let Some(r) = &self.recording else {
            return Ok(());
        };
        match &recording {
            Some(Recording::Rrd(p)) => {
                let names: Vec<String> = icrflow_scenario::rrd_parts(p)
                    .iter()
                    .map(|f| f.display().to_string())
                    .collect();
                if names.is_empty() {
                    writeln!(
                        o,
                        "recording  none: the visualizer wrote no {} (see its messages above)",
                        p.display()
                    )?;
                } else {
                    writeln!(o, "recording  saved to {}", names.join(", "))?;
                    writeln!(o, "           open it: rerun {}", names.join(" "))?;
                }
            }
            _ => writeln!(o, "recording  streamed to the {}", r.target)?,
        }
        writeln!(o, "           {} frames, {} dropped", r.frames, r.dropped)?;
        Ok(())
    }
}

/// `text` cut into lines of at most `width` characters at spaces (a longer word stays whole).
pub(super) fn wrap(text: &str, width: usize) -> Vec<String> {
    wrap_at(text, " ", width)
}

/// `text` cut into lines of at most `width` characters where `sep` separates its parts (a
/// longer part stays whole); `sep` stays at the end of a line, trimmed.
pub(super) fn wrap_at(text: &str, sep: &str, width: usize) -> Vec<String> {
    let mut lines = Vec::new();
    let mut line = String::new();
    for part in text.split(sep) {
        if !line.is_empty()
            && line.chars().count() + sep.chars().count() + part.chars().count() > width
        {
            line.push_str(sep.trim_end());
            lines.push(std::mem::take(&mut line));
        } else if !line.is_empty() {
            line.push_str(sep);
        }
        line.push_str(part);
    }
    if !line.is_empty() || lines.is_empty() {
        lines.push(line);
    }
    lines
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn text_is_wrapped_at_spaces_within_the_width() {
        let text = "bridge 330110 in 11 s, command 11205 in 11 s, estimator 11135 in 11 s, planner 1815 in 11 s";
        let lines = wrap(text, 40);
        assert!(lines.len() > 1);
        assert!(lines.iter().all(|l| l.chars().count() <= 40), "{lines:?}");
        assert_eq!(lines.join(" "), text);
        assert_eq!(wrap("", 10), vec![String::new()]);
        assert_eq!(
            wrap("averyveryverylongword", 5),
            vec!["averyveryverylongword"]
        );
    }

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
