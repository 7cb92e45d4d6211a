//! The run's summary: what `run` writes as JSON with `--summary-json` ([`RunSummary`]), made
//! from what the watch saw; [`text`] prints it at the end.

mod text;

use serde::Serialize;

pub use super::histogram::Percentiles;
use super::track::EstimateError;
use super::watch::Seen;

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

/// The commands that moved a finger onto the object while the grasp was below the margin,
/// its other fingers held (the command node's attach below the margin: adding a contact
/// cannot lower alpha*); neither tracking (`min_quality` is not theirs) nor holds.
#[derive(Debug, Clone, Copy, Serialize, PartialEq)]
pub struct BelowMarginAttaches {
    /// Commands sent.
    pub commands: u64,
    /// The smallest alpha* of the grasp they were sent with (below the margin).
    pub min_quality: f64,
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
    /// The attaches below the margin, if any.
    pub attaching_below_margin: Option<BelowMarginAttaches>,
    /// The margin.
    pub alpha: f64,
    /// Node restarts by the supervisor.
    pub restarts: u32,
    /// Hand commands that held after the start-up (the start-up's are `startup_holds`).
    pub holds: u64,
    /// `holds` by cause: the reason's text before its details, numbers as `N`
    /// (`"grasp state is stale"`, `"the estimate is off"`).
    pub hold_causes: std::collections::BTreeMap<String, u64>,
    /// The causes of `hold_causes` with the numbers their reasons had (from the smallest to
    /// the largest), as the text says them: not in the JSON.
    #[serde(skip)]
    pub hold_figures: std::collections::BTreeMap<String, String>,
    /// Hand commands that held in the start-up: before the hand first tracked, for an input
    /// not there yet (the plan, while the planner node plans). They are not holds of the run,
    /// and do not count towards `pipeline.max_hold_s`.
    pub startup_holds: u64,
    /// Seconds from the start of the loop's processes to the first plan step (`None`: none
    /// came): the start-up's wait for the planner.
    pub planned_after_s: Option<f64>,
    /// The hand's waits for the planner after that: at the last target planned so far while
    /// the rest was made, and for each plan made again from the estimate.
    pub planner_waits: crate::run::planner_waits::PlannerWaits,
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
/// first report [`WARM_UP`](super::watch::WARM_UP) after its process started (each incarnation of a restarted node
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
            attaching_below_margin: seen.attaching_below_margin,
            alpha: facts.alpha,
            restarts: facts.restarts,
            holds: seen.holds,
            hold_causes: seen.hold_causes,
            hold_figures: seen.hold_figures,
            startup_holds: seen.startup_holds,
            planned_after_s: seen.planned_after,
            planner_waits: seen.planner_waits,
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
}
