//! What `icrflow run` watches besides the topics' flow, each a pure state machine fed with
//! the time (unit-tested here, driven by [`super::watch`]): the nodes' heartbeats ([`Heartbeats`]), the
//! estimate against the simulated plant's truth ([`TruthTrack`]), whether plans made again
//! from the estimate get anywhere ([`ReplanProgress`]), and the hang-up signal ([`Hangup`]).

use std::collections::{BTreeMap, VecDeque};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use anyhow::{Context as _, Result};
use icrflow_interfaces::{GraspState, PlantTruth};

use super::histogram::{Histogram, Percentiles};

/// A node silent (no health report, which every node sends every 100 ms) this long is
/// reported: within a second of its last report.
pub const SILENT: Duration = Duration::from_millis(500);

/// What [`Heartbeats::check`] found.
#[derive(Debug, Clone, PartialEq)]
pub enum Silence {
    /// The node has been silent for [`SILENT`] (said once per silence).
    Silent {
        /// The node.
        name: String,
        /// Its process.
        pid: u32,
        /// Since its last report.
        since: Duration,
    },
    /// The node has been silent for the restart time: to be killed, and restarted.
    Hung {
        /// The node.
        name: String,
        /// Its process.
        pid: u32,
        /// Since its last report.
        since: Duration,
    },
    /// A node reported silent has reported again.
    Back {
        /// The node.
        name: String,
        /// How long it was silent.
        after: Duration,
    },
}

#[derive(Debug, Clone)]
struct Beat {
    pid: u32,
    last: Instant,
    /// Reported silent (and when killed as hung).
    silent: bool,
    killed: bool,
}

/// The nodes' last health reports, by node and process: a node is watched from its first
/// report on (its start-up, a plan at the planner's start say, is not a hang), and a
/// restarted node's new process from its own first report.
#[derive(Debug, Default)]
pub struct Heartbeats {
    beats: BTreeMap<String, Beat>,
    /// Silences found back, said at the next check.
    back: Vec<Silence>,
}

impl Heartbeats {
    /// Node `name` (process `pid`) reported at `now`.
    pub fn beat(&mut self, name: &str, pid: u32, now: Instant) {
        match self.beats.get_mut(name) {
            Some(b) if b.pid == pid => {
                if b.silent && !b.killed {
                    self.back.push(Silence::Back {
                        name: name.to_string(),
                        after: now.saturating_duration_since(b.last),
                    });
                }
                b.last = now;
                b.silent = false;
            }
            _ => {
                self.beats.insert(
                    name.to_string(),
                    Beat {
                        pid,
                        last: now,
                        silent: false,
                        killed: false,
                    },
                );
            }
        }
    }

    /// The silences at `now` of the nodes whose process is still the one `pid_of` gives (a
    /// node that exited is the supervisor's business), a node silent for `restart` hung.
    pub fn check(
        &mut self,
        now: Instant,
        restart: Duration,
        pid_of: impl Fn(&str) -> Option<u32>,
    ) -> Vec<Silence> {
        let mut found = std::mem::take(&mut self.back);
        for (name, b) in &mut self.beats {
            if pid_of(name) != Some(b.pid) || b.killed {
                continue;
            }
            let since = now.saturating_duration_since(b.last);
            if since >= restart {
                b.killed = true;
                found.push(Silence::Hung {
                    name: name.clone(),
                    pid: b.pid,
                    since,
                });
            } else if since >= SILENT && !b.silent {
                b.silent = true;
                found.push(Silence::Silent {
                    name: name.clone(),
                    pid: b.pid,
                    since,
                });
            }
        }
        found
    }
}

/// The estimate against the plant's truth: the rotation error of every grasp state sampled,
/// against the truth at the time of the joint measurement it was estimated from (interpolated
/// between the truths around it: an estimate waits for the truth after it, at most 10 ms).
#[derive(Debug)]
pub struct TruthTrack {
    /// Recent truths: (time, rotation).
    truths: VecDeque<(u64, f64)>,
    /// Estimates waiting for a truth after them: (time, rotation).
    pending: VecDeque<(u64, f64)>,
    /// The error of the newest estimate compared (rad), if any.
    error: Option<f64>,
    /// Errors in millidegrees (the histogram's resolution is 1 % above 1).
    errors: Histogram,
    /// Tracking commands sent while the estimate was off the truth by more than the bound.
    pub tracked_off: u64,
}

/// Truths kept (at the plant's 100 Hz: 2 s).
const TRUTHS: usize = 200;

/// The estimate's error against the truth, as the summary gives it.
#[derive(Debug, Clone, serde::Serialize)]
pub struct EstimateError {
    /// |estimated - true| rotation (degrees): p50, p99, max of the grasp states sampled.
    pub rotation_deg: Percentiles,
    /// Tracking commands sent while the estimate was off the truth by more than
    /// `pipeline.max_pose_innovation_deg` (the estimate's bound): 0 in a sound run.
    pub tracked_off_truth: u64,
}

impl Default for TruthTrack {
    fn default() -> Self {
        Self {
            truths: VecDeque::with_capacity(TRUTHS),
            pending: VecDeque::with_capacity(TRUTHS),
            error: None,
            errors: Histogram::new(),
            tracked_off: 0,
        }
    }
}

impl TruthTrack {
    /// A truth from the plant.
    pub fn truth(&mut self, t: &PlantTruth) {
        if self
            .truths
            .back()
            .is_some_and(|(when, _)| *when >= t.header.source_time_ns)
        {
            return;
        }
        if self.truths.len() == TRUTHS {
            self.truths.pop_front();
        }
        self.truths.push_back((t.header.source_time_ns, t.rotation));
    }

    /// The true rotation at `time`, interpolated between the truths around it (`None` outside
    /// them).
    pub fn at(&self, time: u64) -> Option<f64> {
        let i = self.truths.partition_point(|(t, _)| *t <= time);
        if i == 0 || i == self.truths.len() {
            // At the newest truth exactly, or beyond the kept ones.
            return self
                .truths
                .back()
                .filter(|(t, _)| *t == time)
                .map(|(_, r)| *r);
        }
        let (t0, r0) = self.truths[i - 1];
        let (t1, r1) = self.truths[i];
        let f = (time - t0) as f64 / (t1 - t0) as f64;
        Some(r0 + f * (r1 - r0))
    }

    /// Compares grasp state `g` with the truth at its joint measurement's time, once a truth
    /// after it has come; returns the newest error (rad) found.
    pub fn estimate(&mut self, g: &GraspState) -> Option<f64> {
        let time = if g.header.origin_time_ns > 0 {
            g.header.origin_time_ns
        } else {
            g.header.source_time_ns
        };
        if self.pending.len() == TRUTHS {
            self.pending.pop_front();
        }
        self.pending.push_back((time, g.rotation));
        let newest = self.truths.back().map_or(0, |(t, _)| *t);
        while let Some(&(time, rotation)) = self.pending.front() {
            if time > newest {
                break;
            }
            self.pending.pop_front();
            // Before the oldest truth kept: not compared.
            if let Some(truth) = self.at(time) {
                let error = (rotation - truth).abs();
                self.error = Some(error);
                self.errors.add(error.to_degrees() * 1e3);
            }
        }
        self.error
    }

    /// `n` tracking commands were sent; counted as off the truth if the newest error is over
    /// `bound` (rad).
    pub fn tracked(&mut self, n: u64, bound: f64) {
        if self.error.is_some_and(|e| e > bound) {
            self.tracked_off += n;
        }
    }

    /// The summary (`None` without any truth: a plant on another host, or a real hand).
    pub fn summary(&self) -> Option<EstimateError> {
        let p = self.errors.percentiles();
        (p.samples > 0).then_some(EstimateError {
            rotation_deg: Percentiles {
                p50: p.p50 * 1e-3,
                p99: p.p99 * 1e-3,
                max: p.max * 1e-3,
                samples: p.samples,
            },
            tracked_off_truth: self.tracked_off,
        })
    }
}

/// Plans made again from the estimate, in a row, without the object getting on by
/// [`REPLAN_PROGRESS`] (or, nearer the goal than that, by a quarter of what was left to it),
/// after which a run gives up.
pub const REPLANS_WITHOUT_PROGRESS: u32 = 3;
/// What counts as getting on between two plans made again (rad): 2 degrees.
pub const REPLAN_PROGRESS: f64 = 2.0 * std::f64::consts::PI / 180.0;

/// Whether the plans made again from the estimate get the object anywhere.
#[derive(Debug, Default)]
pub struct ReplanProgress {
    /// The rotation at the first re-plan of the run without progress since, and how many
    /// came after it.
    base: Option<(f64, u32)>,
}

impl ReplanProgress {
    /// A plan was made again with the object at `rotation` (rad), on the way to `goal` (rad);
    /// why the run gives up, if it should. Near the goal, where the plans made again turn the
    /// object by what is left (a physical hand's rolling turns it a little less than the
    /// plan's), getting a quarter of the way on from the first counts as progress.
    pub fn replanned(&mut self, rotation: f64, goal: f64) -> Option<String> {
        match &mut self.base {
            Some((base, count))
                if (rotation - *base).abs() < REPLAN_PROGRESS.min(0.25 * (goal - *base).abs()) =>
            {
                *count += 1;
                (*count >= REPLANS_WITHOUT_PROGRESS).then(|| {
                    format!(
                        "gave up: the plan was made again from the estimate {} times in a row with the object stuck at {:.1} deg (within {:.0} deg): re-planning makes no progress (see the planner's messages)",
                        *count + 1,
                        rotation.to_degrees(),
                        REPLAN_PROGRESS.to_degrees()
                    )
                })
            }
            _ => {
                self.base = Some((rotation, 0));
                None
            }
        }
    }
}

/// SIGHUP (the terminal closed): `run` stops on it as on SIGTERM (iceoryx2's handler takes
/// SIGTERM and SIGINT only; SIGHUP's default would kill `run` outright, leaving its bus).
#[derive(Debug, Clone)]
pub struct Hangup(Arc<AtomicBool>);

impl Hangup {
    /// Installs the handler (it only sets a flag).
    pub fn install() -> Result<Self> {
        let flag = Arc::new(AtomicBool::new(false));
        signal_hook::flag::register(signal_hook::consts::SIGHUP, flag.clone())
            .context("installing the SIGHUP handler")?;
        Ok(Self(flag))
    }

    /// Whether SIGHUP came.
    pub fn came(&self) -> bool {
        self.0.load(Ordering::Relaxed)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use icrflow_interfaces::{Header, Kind};

    #[test]
    fn a_silent_node_is_reported_once_then_hung_and_a_restarted_one_watched_anew() {
        let t0 = Instant::now();
        let ms = |n: u64| t0 + Duration::from_millis(n);
        let restart = Duration::from_secs(3);
        let mut h = Heartbeats::default();
        let pids = std::cell::RefCell::new(BTreeMap::from([("command", 10u32), ("plant", 11)]));
        let pid_of = |n: &str| pids.borrow().get(n).copied();
        h.beat("command", 10, ms(0));
        h.beat("plant", 11, ms(0));
        for t in (100..=400).step_by(100) {
            h.beat("plant", 11, ms(t));
            assert_eq!(h.check(ms(t), restart, pid_of), []);
        }
        // The command node stopped reporting at 0: said at 500 ms, once.
        h.beat("plant", 11, ms(500));
        let found = h.check(ms(500), restart, pid_of);
        assert!(
            matches!(&found[..], [Silence::Silent { name, pid: 10, .. }] if name == "command"),
            "{found:?}"
        );
        h.beat("plant", 11, ms(900));
        assert_eq!(h.check(ms(900), restart, pid_of), []);
        // At the restart time: hung, once.
        h.beat("plant", 11, ms(3000));
        let found = h.check(ms(3000), restart, pid_of);
        assert!(
            matches!(&found[..], [Silence::Hung { pid: 10, .. }]),
            "{found:?}"
        );
        h.beat("plant", 11, ms(3500));
        assert_eq!(h.check(ms(3500), restart, pid_of), []);
        // Restarted: the new process is watched from its first report only.
        pids.borrow_mut().insert("command", 12);
        h.beat("plant", 11, ms(3900));
        h.beat("plant", 11, ms(4800));
        assert_eq!(h.check(ms(5000), restart, pid_of), []);
        h.beat("command", 12, ms(5000));
        h.beat("plant", 11, ms(5400));
        let found = h.check(ms(5600), restart, pid_of);
        assert!(
            matches!(&found[..], [Silence::Silent { pid: 12, .. }]),
            "{found:?}"
        );
        // It comes back (SIGCONT after a SIGSTOP, say): said.
        h.beat("command", 12, ms(5900));
        h.beat("plant", 11, ms(5900));
        let found = h.check(ms(5900), restart, pid_of);
        assert!(matches!(&found[..], [Silence::Back { .. }]), "{found:?}");
        // A node that exited is not watched (the supervisor restarts it).
        pids.borrow_mut().remove("plant");
        assert!(
            h.check(ms(20_000), restart, pid_of)
                .iter()
                .all(|s| !matches!(
                    s,
                    Silence::Silent { pid: 11, .. } | Silence::Hung { pid: 11, .. }
                ))
        );
    }

    fn truth(ns: u64, rotation: f64) -> PlantTruth {
        let mut t = PlantTruth {
            header: Header::new(Kind::PlantTruth, ns, 0, 0),
            rotation,
            ..Default::default()
        };
        t.header.source_time_ns = ns;
        t
    }

    #[test]
    fn the_estimate_is_compared_with_the_truth_at_its_measurement_time() {
        let mut track = TruthTrack::default();
        assert!(track.summary().is_none());
        track.truth(&truth(1_000, 0.0));
        track.truth(&truth(2_000, 0.1));
        track.truth(&truth(1_500, 9.0)); // out of order: ignored
        assert_eq!(track.at(500), None);
        assert!((track.at(1_500).unwrap() - 0.05).abs() < 1e-12);
        assert_eq!(track.at(2_000), Some(0.1));
        assert_eq!(track.at(2_001), None);
        let mut g = GraspState {
            header: Header::new(Kind::GraspState, 1, 0, 1_500),
            rotation: 0.05 + 0.1,
            ..Default::default()
        };
        let e = track.estimate(&g).unwrap();
        assert!((e - 0.1).abs() < 1e-12);
        // Commands while that far off count against a bound below it, not one above.
        track.tracked(5, 0.2);
        assert_eq!(track.tracked_off, 0);
        track.tracked(5, 0.05);
        assert_eq!(track.tracked_off, 5);
        // An estimate after the newest truth waits for the next one.
        g.header.origin_time_ns = 2_500;
        g.rotation = 0.15;
        assert!(
            (track.estimate(&g).unwrap() - 0.1).abs() < 1e-12,
            "the older error"
        );
        track.truth(&truth(3_000, 0.2));
        g.header.origin_time_ns = 3_500;
        let e = track.estimate(&g).unwrap();
        assert!(e.abs() < 1e-12, "0.15 against the truth 0.15 at 2500: {e}");
        let s = track.summary().unwrap();
        assert_eq!(s.rotation_deg.samples, 2);
        assert!((s.rotation_deg.max - 0.1f64.to_degrees()).abs() < 1e-9);
        assert_eq!(s.tracked_off_truth, 5);
    }

    #[test]
    fn re_plans_that_get_nowhere_give_up_and_progress_starts_anew() {
        let deg = |d: f64| d.to_radians();
        let goal = deg(360.0);
        let mut p = ReplanProgress::default();
        assert_eq!(p.replanned(deg(10.0), goal), None);
        assert_eq!(p.replanned(deg(11.0), goal), None);
        // Got on: counted from here.
        assert_eq!(p.replanned(deg(40.0), goal), None);
        assert_eq!(p.replanned(deg(40.5), goal), None);
        assert_eq!(p.replanned(deg(39.8), goal), None);
        let why = p.replanned(deg(40.1), goal).unwrap();
        assert!(why.contains("4 times in a row"), "{why}");
        assert!(why.contains("40.1 deg"), "{why}");
        // Near the goal, a quarter of the way on is progress: 1.4 deg short, then 1.1, 0.9
        // (0.5 on from 358.6, more than 0.35), 0.7, 0.55; stuck at 359.45 it gives up.
        let mut p = ReplanProgress::default();
        for at in [358.6, 358.9, 359.1, 359.3, 359.45] {
            assert_eq!(p.replanned(deg(at), goal), None, "{at}");
        }
        assert_eq!(p.replanned(deg(359.45), goal), None);
        assert_eq!(p.replanned(deg(359.46), goal), None);
        assert!(p.replanned(deg(359.45), goal).is_some());
    }
}
