//! The ICR planner node (`icrflow-planner`): plans the scenario (the same deterministic
//! algorithm as `icrflow plan`: rolling within ICRs, finger switching) and leads the hand
//! through it step by step, closed loop, with [`icrflow_plan::follow::Follower`]: a step is
//! published as the target until the estimated grasp has reached it, then the next; after the
//! last step it publishes `Done`. Restarted after a crash, it plans again and resumes at the
//! step nearest to the estimated state.
//!
//! The plan is made in a [`worker`] thread, at normal priority, and handed on a part at a time
//! as its steps are settled (a receding horizon: the rolling steps up to where a later switch
//! could no longer reach back, then each switch as it is found; a planar plan, made in a
//! fraction of a second, at once): the hand follows the first steps while the rest is made,
//! and waits at the last target made when it gets there first. When the object stops short of
//! a rolling step for good (it slipped), the follower asks the worker for a plan made again
//! from the estimate, which comes the same way (the command node holds the hand meanwhile:
//! the targets it had were solved for the object where the plan had it); its steps are
//! numbered on from the last one, its first step a `Start`. Meanwhile the node's loop keeps serving: it republishes the
//! target it holds, says in each plan-step message whether the hand waits for the planner and
//! for how long (`planning`, `planning_ms`), and reports its health; nothing of the planning's
//! progress is passed into the math to keep the node alive. The loop runs under SCHED_FIFO
//! with the loop's other nodes (`icrflow run`).
//!
//! [`run`] is the adapter: the grasp state into an [`Estimate`], the follower's step, the
//! plan-step messages (each with its grasp's ICRs, computed with the plan in the worker:
//! `Regions`), health. The geometry and the step are the planner crate's
//! ([`icrflow_plan::follow`]).

use std::sync::mpsc::TryRecvError;
use std::time::Duration;

use anyhow::{Context as _, Result, anyhow, bail};
use icrflow_interfaces::{
    FingerTarget, GraspState, Header, Kind, MAX_FINGERS, MAX_JOINTS, MAX_REGION_POINTS, PlanPhase,
    PlanStepHeader, PlanWait, topics,
};
use icrflow_plan::follow::{
    Estimate, Event, Followed, Follower, ReplanDue, Replanned, Target, Tolerances, Wait,
    fingers_in_contact,
};
use icrflow_plan::hand::Hand;
use icrflow_plan::planner::{Phase, Step};
use icrflow_runtime::event::serve;
use icrflow_runtime::health::{Health, Sequence, now};

use crate::StaticContext;

mod worker;

use worker::Made;

/// Period of the plan-step stream (s): the current target is published at least this often
/// (100 Hz), and at once when the estimate reaches it.
pub const REPUBLISH: f64 = 0.01;

/// How far beyond the contact distance a free finger's fingertip stays on its way between a
/// stand-off and its free pose (m): farther than the estimator's release distance, so that
/// no passing finger is taken for a contact.
pub const CLEARANCE: f64 = icrflow_plan::rolling::RELEASE + 0.5e-3;

/// The grasp state `g` as the follower's estimate, into `e` (its buffers kept, so that this
/// allocates nothing once they have grown): the fingers in use, each with as many joints as
/// the hand's finger has. The plan is made about the object's starting centre; where the
/// estimate has the centre moved, each planar finger out of contact has its joints taken as
/// if its fingertip had moved back with it (`Finger::shift_planar`), the inverse of what the
/// hand command node does to such a finger's targets.
pub(crate) fn estimate(g: &GraspState, hand: &Hand, e: &mut Estimate) {
    let n = (g.finger_count as usize).min(MAX_FINGERS);
    e.rotation = g.rotation;
    e.fingers.resize_with(n, Default::default);
    for (slot, f) in e.fingers.iter_mut().enumerate() {
        let c = &g.fingers[slot];
        let dof = hand.finger(c.finger).map_or(MAX_JOINTS, |f| f.dof());
        f.finger = c.finger;
        f.in_contact = c.in_contact == 1;
        f.joints.clear();
        f.joints
            .extend_from_slice(&g.joints[slot][..dof.min(MAX_JOINTS)]);
        let back = [-g.position[0], -g.position[1]];
        if back != [0.0, 0.0]
            && !f.in_contact
            && let Some(finger) = hand.finger(c.finger)
        {
            let mut q = [0.0; MAX_JOINTS];
            if finger.shift_planar(&f.joints, back, &mut q) {
                let n = f.joints.len();
                f.joints.copy_from_slice(&q[..n]);
            }
        }
    }
}

/// A target's regions as its plan-step messages carry them: the members (each finger's ICR,
/// then the rendezvous region), each finger's region length, and the rendezvous region's
/// length.
#[derive(Debug, Clone, PartialEq, Default)]
pub(crate) struct Regions {
    members: Vec<u32>,
    lengths: [u32; MAX_FINGERS],
    rendezvous: u32,
}

impl Regions {
    /// The regions of `step`: the ICRs of its grasp (none where it has no force closure) and,
    /// for an attach step, where the attaching finger may touch (the exact region its contact
    /// was chosen from), as much of it as fits in [`MAX_REGION_POINTS`].
    fn of(step: &Step, problem: &icrflow_grasp::quality::GraspProblem, alpha: f64) -> Self {
        let mut r = Regions::default();
        let contacts: Vec<usize> = step.fingers.iter().filter_map(|f| f.contact).collect();
        let icrs = problem
            .evaluate(&contacts)
            .ok()
            .and_then(|e| problem.icrs(&contacts, &e, alpha).ok());
        let mut region = 0;
        for (slot, f) in step.fingers.iter().enumerate().take(MAX_FINGERS) {
            if f.contact.is_some() {
                if let Some(icr) = icrs.as_ref().and_then(|r| r.get(region)) {
                    let room = MAX_REGION_POINTS.saturating_sub(r.members.len());
                    let members = &icr.members[..icr.members.len().min(room)];
                    r.lengths[slot] = members.len() as u32;
                    r.members.extend_from_slice(members);
                }
                region += 1;
            }
        }
        if let Some(sw) = &step.switch {
            let room = MAX_REGION_POINTS.saturating_sub(r.members.len());
            let before = r.members.len();
            r.members
                .extend(sw.brute_force.iter().take(room).map(|&c| c as u32));
            r.rendezvous = (r.members.len() - before) as u32;
        }
        r
    }
}

/// Every target's regions (`.1[k]` indexes `.0` for target `k`), computed with the plan, so
/// that following it computes and allocates nothing per step. Consecutive targets of one grasp
/// and switch (a step's sub-targets, a finger's way points) share one computation.
fn regions(
    steps: &[Target],
    problem: &icrflow_grasp::quality::GraspProblem,
    alpha: f64,
) -> (Vec<Regions>, Vec<usize>) {
    let same = |a: &Step, b: &Step| {
        a.switch == b.switch
            && a.fingers.len() == b.fingers.len()
            && a.fingers
                .iter()
                .zip(&b.fingers)
                .all(|(f, g)| f.contact == g.contact)
    };
    let (mut distinct, mut of_target) = (Vec::<Regions>::new(), Vec::with_capacity(steps.len()));
    for (k, t) in steps.iter().enumerate() {
        if k == 0 || !same(&steps[k - 1].step, &t.step) {
            // A spatial plan's contacts change candidates at most sub-targets: hundreds of
            // 6D regions, a second's work (in the worker thread, with the plan).
            distinct.push(Regions::of(&t.step, problem, alpha));
        }
        of_target.push(distinct.len() - 1);
    }
    (distinct, of_target)
}

/// The plan-step message of `target` (`done`: the plan is done, after it) with its `regions`.
pub(crate) fn message(
    target: &Target,
    done: bool,
    regions: &Regions,
    header: Header,
) -> PlanStepHeader {
    let step = &target.step;
    let mut h = PlanStepHeader {
        header,
        phase: if done {
            PlanPhase::Done as u32
        } else {
            step.phase as u32
        },
        finger_count: step.fingers.len().min(MAX_FINGERS) as u32,
        step: step.step as u64,
        rotation: step.rotation,
        quality: step.quality,
        region_lengths: regions.lengths,
        ..Default::default()
    };
    // The attaching finger from the step itself (the command node's gate needs it whether or
    // not the regions were computed: the lockstep computes none); the region's length from
    // the regions.
    h.rendezvous_finger = step.switch.as_ref().map_or(0, |sw| sw.attached);
    h.rendezvous_length = regions.rendezvous;
    for (slot, f) in step.fingers.iter().enumerate().take(MAX_FINGERS) {
        let t = &mut h.targets[slot];
        *t = FingerTarget {
            finger: f.finger,
            in_contact: u32::from(f.contact.is_some()),
            candidate: f.contact.unwrap_or(0) as u32,
            joint_count: f.joints.len().min(MAX_JOINTS) as u32,
            point: f.point.unwrap_or([0.0; 3]),
            cap_angle: f.cap_angle.unwrap_or(0.0),
            joints: [0.0; MAX_JOINTS],
        };
        for (j, q) in f.joints.iter().enumerate().take(MAX_JOINTS) {
            t.joints[j] = *q;
        }
    }
    h
}

/// What the follower did, on stderr: re-plans always; with `ICRFLOW_LOG_CONTACTS` (`log`),
/// where it starts and the switching targets it moves on to (rolling ones are many and
/// alike).
fn log(followed: &icrflow_plan::follow::Followed, targets: &[Target], log: bool) {
    if log && let Some(k) = followed.resumed {
        eprintln!("icrflow-planner: starting at target {k}/{}", targets.len());
    }
    match &followed.event {
        Some(Event::Replanned(r)) => {
            for note in &r.notes {
                eprintln!("icrflow-planner: {note}");
            }
            eprintln!("icrflow-planner: {r}");
            if !r.plan.summary.completed {
                eprintln!(
                    "icrflow-planner: the new plan stops short of the goal: {}",
                    r.plan.summary.stop_reason.as_deref().unwrap_or("?")
                );
            }
        }
        Some(e @ (Event::ReplanFailed { .. } | Event::ReplanDue(_))) => {
            eprintln!("icrflow-planner: {e}")
        }
        Some(Event::Advanced(k))
            if log
                && let Some(next) = targets.get(*k)
                && (next.way_point || next.step.phase != Phase::Rolling) =>
        {
            eprintln!(
                "icrflow-planner: target {k}/{}: step {} {:?}{}, fingers {:?} in contact, \
                 {:.1} deg",
                targets.len(),
                next.step.step,
                next.step.phase,
                if next.way_point { " (way point)" } else { "" },
                fingers_in_contact(&next.step).collect::<Vec<_>>(),
                next.step.rotation.to_degrees()
            );
        }
        _ => {}
    }
}

/// The threads the planner node plans on (the planner's switch search and rendezvous regions
/// split over a `rayon` pool; `RAYON_NUM_THREADS`, when set, is taken instead). One, where
/// `icrflow plan` uses every core: with the node planning on both cores of the project's
/// 2-core VM, `config/allegro_ellipsoid_mujoco.toml` reached the goal in 2 of 8 runs (the CI's
/// and 7 here on 2026-12-06; the others stalled below the margin or lost the grasp at 112-250
/// deg, tilted up to 14.6 deg), on one in every run measured (BENCHMARKS.md; 8 of 8, tilted
/// 1.44-2.35 deg), the plans themselves byte-identical. Not explained by the planning itself:
/// the node is idle while the hand follows (its pool asleep, 0 % CPU), and three of the
/// failures came before any plan was made again. The CI run of 5e3a135, on one thread, failed
/// the same way with a build running beside it: 27,450 of the command node's holds for plan
/// steps gone stale, the node's loop (then planning itself, at normal priority) kept off the
/// CPU. Its loop now runs under SCHED_FIFO and plans nothing ([`worker`]). Issue 38's notes.
pub const THREADS: usize = 1;

/// Runs the planner node: the adapter around [`Follower`], the plan made in a [`worker`]
/// thread and followed a part at a time as it comes.
pub fn run(ctx: &StaticContext) -> Result<()> {
    if std::env::var_os("RAYON_NUM_THREADS").is_none()
        && let Err(e) = rayon::ThreadPoolBuilder::new()
            .num_threads(THREADS)
            .build_global()
    {
        eprintln!("icrflow-planner: the planning threads could not be set to {THREADS}: {e}");
    }
    eprintln!(
        "icrflow-planner: planning on {} thread(s)",
        rayon::current_num_threads()
    );
    let loaded: &'static icrflow_scenario::Loaded = ctx.scenario;
    let (setup, config) = (&loaded.setup, &loaded.config);
    let log_steps = ctx.launch.log.contacts;
    let tolerances = Tolerances::new(config.pipeline.joint_noise);
    let hung_restart_s = config.pipeline.hung_restart;
    // Health first: its `Starting` reports say how far the first plan has got (`icrflow run`
    // shows them), every HEALTH_PERIOD until its first part comes.
    let mut health = Health::new(ctx)?;
    let goal = config.plan.goal.to_degrees();
    let planning = |health: &mut Health, theta: f64, now: bool| {
        let done = theta.to_degrees().clamp(0.0, goal.max(0.0));
        health.starting(
            format_args!(
                "planning: {:.0} % ({done:.0} of {goal:.0} deg)",
                100.0 * done / goal.max(1e-9)
            ),
            now,
        )
    };
    planning(&mut health, 0.0, true)?;
    let scenario = setup.planning(config)?;
    let started = now();
    let worker = worker::spawn(scenario.clone(), &setup.problem)?;
    let mut follower = Follower::waiting(scenario, CLEARANCE, tolerances);
    // The regions each target's messages carry, made with the targets.
    let mut step_regions: (Vec<Regions>, Vec<usize>) = Default::default();
    // The plan made again that was asked for, and when (ns).
    let mut asked: Option<(Box<ReplanDue>, u64)> = None;
    // What the follower waits for the planner for, and since when (ns).
    let mut waited: Option<(Wait, u64)> = None;
    let grasps = ctx.bus.subscriber(topics::GRASP_STATE)?;
    let out = ctx.bus.slice_publisher(topics::PLAN_STEP)?;
    let mut seq = Sequence::default();
    let mut last_grasp = 0;
    // The header of the newest grasp state and when it was taken off the bus.
    let mut last_input: Option<(Header, u64)> = None;
    let mut e = Estimate::default();
    let mut publish = |targets: &[Target],
                       regions: &(Vec<Regions>, Vec<usize>),
                       k: usize,
                       input: Option<(Header, u64)>,
                       waited: Option<(Wait, u64)>| {
        let at = k.min(targets.len() - 1);
        let header = match input {
            Some((h, received)) => Header::after(Kind::PlanStep, seq.advance(), &h, received),
            None => Header::new(Kind::PlanStep, seq.advance(), 0, 0),
        };
        let r = &regions.0[regions.1[at]];
        let mut m = message(&targets[at], k >= targets.len(), r, header);
        if let Some((wait, since)) = waited {
            m.planning = plan_wait(wait) as u32;
            m.planning_ms =
                (now().saturating_sub(since) / 1_000_000).min(u64::from(u32::MAX)) as u32;
        }
        out.publish(m, &r.members)
    };
    let tick = Some(Duration::from_secs_f64(REPUBLISH));
    serve(ctx, &[grasps.listener()], tick, |ticked| {
        if follower.targets().is_empty() {
            planning(&mut health, worker.planned(), false)?;
        } else {
            health.tick()?;
        }
        // A planning thread that shows no progress for as long as a hung node may take is
        // taken for hung: the node stops, and the supervisor starts it again.
        let silent = worker.silent_ns(now()) as f64 * 1e-9;
        if silent > hung_restart_s {
            bail!(
                "the planning thread has shown no progress for {silent:.1} s (pipeline.hung_restart_s = {hung_restart_s}): stopped, to be started again"
            );
        }
        // What the worker made since.
        loop {
            let made = match worker.made.try_recv() {
                Ok(made) => made,
                Err(TryRecvError::Empty) => break,
                Err(TryRecvError::Disconnected) => {
                    bail!("the planning thread stopped (see its panic above)")
                }
            };
            match made {
                Made::Targets {
                    first,
                    targets,
                    regions,
                } => {
                    if first {
                        let waited = follower.waiting_for();
                        let again = waited == Some(Wait::Again);
                        follower.begin(targets, now());
                        step_regions = regions;
                        match asked.as_ref().filter(|_| again) {
                            Some((due, at)) => eprintln!(
                                "icrflow-planner: re-plan {}: its first targets after {:.0} ms",
                                due.count,
                                now().saturating_sub(*at) as f64 * 1e-6
                            ),
                            None if waited == Some(Wait::FirstPlan) => eprintln!(
                                "icrflow-planner: the plan's first targets after {:.0} ms",
                                now().saturating_sub(started) as f64 * 1e-6
                            ),
                            None => {}
                        }
                        // A plan made again: its first target at once.
                        if let Some(k) = follower.current() {
                            publish(follower.targets(), &step_regions, k, last_input, None)?;
                        }
                    } else {
                        let base = step_regions.0.len();
                        step_regions.0.extend(regions.0);
                        step_regions.1.extend(regions.1.iter().map(|r| r + base));
                        follower.extend(&targets);
                    }
                }
                Made::Planned(Ok(plan)) => {
                    follower.finish(plan.summary.completed);
                    if let Some(why) = plan.summary.stop_reason.as_deref() {
                        eprintln!("icrflow-planner: the plan stops short of the goal: {why}");
                    }
                }
                Made::Planned(Err(error)) => {
                    if follower.targets().is_empty() {
                        return Err(error).context("planning");
                    }
                    eprintln!(
                        "icrflow-planner: the plan stops after its first {} targets: {error}",
                        follower.targets().len()
                    );
                    follower.finish(false);
                }
                Made::Replanned(again) => {
                    let Some((due, at)) = asked.take() else {
                        continue;
                    };
                    let took = now().saturating_sub(at) as f64 * 1e-9;
                    let begun = follower.waiting_for() != Some(Wait::Again);
                    let event = match *again {
                        Ok(r) if begun => {
                            follower.finish(r.at_goal);
                            Event::Replanned(Box::new(Replanned {
                                rotation: due.estimate.rotation,
                                target: due.target,
                                count: due.count,
                                first: due.first,
                                plan: r.plan,
                                delta: r.delta,
                                notes: r.notes,
                                at_goal: r.at_goal,
                            }))
                        }
                        Ok(_) => {
                            follower.replan_failed();
                            eprintln!("icrflow-planner: a plan made again came without targets");
                            continue;
                        }
                        Err(error) if begun => {
                            follower.finish(false);
                            eprintln!(
                                "icrflow-planner: the plan made again stops after its first {} targets: {error}",
                                follower.targets().len()
                            );
                            continue;
                        }
                        Err(error) => {
                            follower.replan_failed();
                            Event::ReplanFailed {
                                rotation: due.estimate.rotation,
                                target: due.target,
                                error,
                            }
                        }
                    };
                    let followed = Followed {
                        resumed: None,
                        event: Some(event),
                    };
                    log(&followed, follower.targets(), log_steps);
                    eprintln!(
                        "icrflow-planner: re-plan {}: made in {took:.2} s",
                        due.count
                    );
                }
            }
        }
        if let Some(g) = grasps.latest()? {
            if !health.accept("grasp state", &g.header, Kind::GraspState, &mut last_grasp) {
                // Refused and counted.
            } else if !g.rotation.is_finite() {
                health.refuse("grasp state not finite");
            } else {
                last_input = Some((g.header, now()));
                health.processed += 1;
                estimate(&g, &setup.hand, &mut e);
                let followed = follower.on_estimate(&e, now(), &mut || {});
                log(&followed, follower.targets(), log_steps);
                if let Some(Event::ReplanDue(due)) = &followed.event {
                    asked = Some((due.clone(), now()));
                    worker
                        .jobs
                        .send(worker::Job(due.clone()))
                        .map_err(|_| anyhow!("the planning thread stopped"))?;
                }
                let w = wait_since(&mut waited, follower.waiting_for(), now());
                for k in followed.commands() {
                    publish(follower.targets(), &step_regions, k, last_input, w)?;
                }
            }
        }
        let w = wait_since(&mut waited, follower.waiting_for(), now());
        if ticked && let Some(k) = follower.current() {
            // Taken up again now: the trace's last stage is this publication alone.
            let input = last_input.map(|(h, _)| (h, now()));
            publish(follower.targets(), &step_regions, k, input, w)?;
        }
        Ok(())
    })
}

/// What the hand waits for the planner for, as the plan-step message says it.
fn plan_wait(w: Wait) -> PlanWait {
    match w {
        Wait::Ahead => PlanWait::Ahead,
        Wait::Again => PlanWait::Again,
        // (No target is published before the first plan's.)
        Wait::FirstPlan => PlanWait::None,
    }
}

/// The follower's wait `now` (`w`), and since when (ns): kept in `waited` from the wake-up it
/// began.
fn wait_since(waited: &mut Option<(Wait, u64)>, w: Option<Wait>, now: u64) -> Option<(Wait, u64)> {
    *waited = match (*waited, w) {
        (Some((was, since)), Some(w)) if was == w => Some((w, since)),
        (_, w) => w.map(|w| (w, now)),
    };
    *waited
}

#[cfg(test)]
mod tests {
    use super::*;

    use icrflow_plan::follow::targets;
    use icrflow_scenario::{Config, Setup};

    /// The config `config/NAME`.
    fn config(name: &str) -> Config {
        let dir = std::env::var_os("CARGO_MANIFEST_DIR")
            .unwrap_or_else(|| env!("CARGO_MANIFEST_DIR").into());
        Config::load(&std::path::PathBuf::from(dir).join("../config").join(name)).unwrap()
    }

    /// The scenario of `config/NAME`, its plan and its targets.
    fn planned(name: &str) -> (Setup, icrflow_plan::planner::Plan, Vec<Target>) {
        let config = config(name);
        let setup = Setup::new(&config).unwrap();
        let plan = setup.scenario(&config).plan(&mut |_| {}).unwrap();
        let surface = setup.surface().unwrap();
        let list = targets(&plan.steps, &setup.hand, surface, CLEARANCE, &mut |_| {});
        (setup, plan, list)
    }

    /// The regions computed with the plan are, target for target, those of the target's own
    /// grasp and switch: sharing one computation among consecutive targets loses nothing.
    #[test]
    fn regions_computed_with_the_plan_are_each_targets_own() {
        let (setup, plan, list) = planned("paper_sphere.toml");
        let alpha = config("paper_sphere.toml").plan.alpha;
        let (distinct, of_target) = regions(&list, &setup.problem, alpha);
        assert_eq!(of_target.len(), list.len());
        // Shared: one per grasp and switch, not one per sub-target.
        assert!(
            distinct.len() <= plan.steps.len() + 4 * plan.summary.switches,
            "{} regions for {} targets of {} steps",
            distinct.len(),
            list.len(),
            plan.steps.len()
        );
        for (k, t) in list.iter().enumerate() {
            let own = Regions::of(&t.step, &setup.problem, alpha);
            assert_eq!(distinct[of_target[k]], own, "target {k}");
            let in_contact = t
                .step
                .fingers
                .iter()
                .filter(|f| f.contact.is_some())
                .count();
            if t.step.quality >= alpha && in_contact >= 2 {
                assert!(
                    own.lengths.iter().filter(|&&n| n > 0).count() == in_contact,
                    "target {k}: a force-closure grasp without a region per contact: {own:?}"
                );
            }
            let listed: u32 = own.lengths.iter().sum::<u32>() + own.rendezvous;
            assert_eq!(listed as usize, own.members.len(), "target {k}");
            assert_eq!(own.rendezvous > 0, t.step.switch.is_some(), "target {k}");
        }
    }

    /// The follower's estimate is the grasp state's: the fingers in use, in its order, their
    /// contacts, and as many joints as each finger of the hand has; a shorter state after a
    /// longer one leaves no finger of the longer one behind.
    #[test]
    fn the_estimate_is_the_grasp_states_fingers_in_use() {
        let config = config("paper_sphere.toml");
        let setup = Setup::new(&config).unwrap();
        let mut g = GraspState {
            rotation: 0.25,
            finger_count: 3,
            ..Default::default()
        };
        for slot in 0..MAX_FINGERS {
            g.fingers[slot].finger = [2, 1, 4, 3][slot % 4];
            g.fingers[slot].in_contact = u32::from(slot != 1);
            g.joints[slot] = std::array::from_fn(|j| (10 * slot + j) as f64);
        }
        let mut e = Estimate::default();
        estimate(&g, &setup.hand, &mut e);
        assert_eq!(e.rotation, 0.25);
        assert_eq!(e.fingers.len(), 3);
        for (slot, f) in e.fingers.iter().enumerate() {
            let dof = setup.hand.finger(f.finger).unwrap().dof();
            assert_eq!(f.finger, g.fingers[slot].finger);
            assert_eq!(f.in_contact, slot != 1);
            assert_eq!(f.joints, g.joints[slot][..dof].to_vec());
        }
        assert_eq!(e.touching().collect::<Vec<_>>(), vec![2, 4]);
        g.finger_count = 2;
        estimate(&g, &setup.hand, &mut e);
        assert_eq!(e.fingers.len(), 2);
    }
}
