//! The planner node's worker thread: it makes the plan, and every plan made again, off the
//! node's loop, and hands each on a part at a time as its steps are settled
//! ([`Planning::plan_streamed`]), with the regions the parts' plan-step messages carry. The
//! loop keeps serving meanwhile: it follows the targets it has, republishes the one it holds,
//! and reports the node's health, with nothing of the planning's progress passed into the
//! math to keep it alive.
//!
//! The thread is not joined: it may be in the middle of a plan of tens of seconds when the node
//! is told to stop, and the process ends with the loop (the thread's plan with it).

use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::mpsc::{Receiver, Sender, channel};

use anyhow::{Context as _, Result};
use icrflow_grasp::math::Real;
use icrflow_grasp::quality::GraspProblem;
use icrflow_plan::follow::{Planning, Replan, ReplanDue, ReplanError, Target};
use icrflow_plan::planner::{Plan, PlanError};
use icrflow_runtime::health::now;

use super::{CLEARANCE, Regions, regions};

/// A plan made again that the loop asks the worker for.
pub(crate) struct Job(pub Box<ReplanDue>);

/// What the worker hands the loop.
pub(crate) enum Made {
    /// A part of the plan being made: its targets, after those handed on before (`first`:
    /// the plan's first part), and their regions (`.0` the distinct ones, `.1[k]` indexing
    /// `.0` for target `k`).
    Targets {
        first: bool,
        targets: Vec<Target>,
        regions: (Vec<Regions>, Vec<usize>),
    },
    /// The first plan, made (or why not).
    Planned(Result<Plan, PlanError>),
    /// A plan made again, made (or why not).
    Replanned(Box<Result<Replan, ReplanError>>),
}

/// The worker's ends on the loop's side: where to ask for a plan made again, what comes back,
/// the rotation planned so far (rad, as `f64` bits), which the node's health reports say
/// while the first plan is made, and when the worker last showed progress on a plan (ns; 0
/// while it has none to make).
pub(crate) struct Worker {
    pub jobs: Sender<Job>,
    pub made: Receiver<Made>,
    planned: Arc<AtomicU64>,
    beat: Arc<AtomicU64>,
}

impl Worker {
    /// The rotation planned so far (rad).
    pub fn planned(&self) -> Real {
        f64::from_bits(self.planned.load(Ordering::Relaxed))
    }

    /// How long the worker has shown no progress on the plan it makes, at `now` (ns); 0 while
    /// it makes none. (The planner reports its progress after every step and between the
    /// batches of a switch search: tens of milliseconds apart.)
    pub fn silent_ns(&self, now: u64) -> u64 {
        match self.beat.load(Ordering::Relaxed) {
            0 => 0,
            at => now.saturating_sub(at),
        }
    }
}

/// Starts the worker: it makes `planning`'s plan at once, then a plan made again for every
/// [`Job`], until the loop's side is gone; regions of the grasp problem `problem`.
pub(crate) fn spawn(planning: Planning<'static>, problem: &'static GraspProblem) -> Result<Worker> {
    let (jobs, asked) = channel::<Job>();
    let (hand, made) = channel::<Made>();
    let planned = Arc::new(AtomicU64::new(0f64.to_bits()));
    let beat = Arc::new(AtomicU64::new(now()));
    let (progress, beating) = (Arc::clone(&planned), Arc::clone(&beat));
    std::thread::Builder::new()
        .name("planning".into())
        .spawn(move || {
            let mut part = Part::default();
            let mut said = |theta: Real| {
                progress.store(theta.to_bits(), Ordering::Relaxed);
                beating.store(now(), Ordering::Relaxed);
            };
            let plan = planning.plan_streamed(
                CLEARANCE,
                &mut |note| eprintln!("icrflow-planner: {note}"),
                &mut said,
                &mut |targets, alpha| part.hand_on(targets, alpha, problem, &hand),
            );
            part.flush(problem, &hand);
            beating.store(0, Ordering::Relaxed);
            if hand.send(Made::Planned(plan)).is_err() {
                return;
            }
            for Job(due) in asked {
                beating.store(now(), Ordering::Relaxed);
                part = Part::default();
                let again = planning.replan_streamed(&due, CLEARANCE, &mut said, &mut |t, a| {
                    part.hand_on(t, a, problem, &hand)
                });
                part.flush(problem, &hand);
                beating.store(0, Ordering::Relaxed);
                if hand.send(Made::Replanned(Box::new(again))).is_err() {
                    return;
                }
            }
        })
        .context("starting the planning thread")?;
    Ok(Worker {
        jobs,
        made,
        planned,
        beat,
    })
}

/// The parts of one plan as the worker hands them on: the first once it has two targets or
/// more (a follower starts at a plan's first target and needs the next to go anywhere: a
/// spatial plan's first settled part is its start alone), each with its regions.
#[derive(Default)]
struct Part {
    /// Whether the first part has been handed on.
    sent: bool,
    /// The targets kept back for the first part, and the margin they were planned at.
    kept: Vec<Target>,
    alpha: Real,
}

impl Part {
    /// `targets`, planned at `alpha`, handed on to `to` (or kept for the first part).
    fn hand_on(
        &mut self,
        targets: &[Target],
        alpha: Real,
        problem: &GraspProblem,
        to: &Sender<Made>,
    ) {
        self.kept.extend_from_slice(targets);
        self.alpha = alpha;
        if self.sent || self.kept.len() >= 2 {
            self.flush(problem, to);
        }
    }

    /// Hands on what is kept (at the end of a plan, however little).
    fn flush(&mut self, problem: &GraspProblem, to: &Sender<Made>) {
        if self.kept.is_empty() {
            return;
        }
        let targets = std::mem::take(&mut self.kept);
        let regions = regions(&targets, problem, self.alpha);
        let first = !std::mem::replace(&mut self.sent, true);
        // (A loop that is gone wants nothing more; the worker stops when it sees so.)
        let _ = to.send(Made::Targets {
            first,
            targets,
            regions,
        });
    }
}
