//! The Rerun visualizer node (`icrflow-visualizer`): one Rerun recording per run, showing what
//! the paper's figures show, live: the hand and the object with each finger's ICR painted on
//! it (Fig. 10), the wrench space in `(f_x, f_y, tau_z / rho)` (Fig. 9), and the angles,
//! quality and phase over time (Fig. 11), plus the pipeline's latency. With MuJoCo as the plant
//! it also shows the truth beside the estimate (from [`topics::PLANT_TRUTH`], which no node of
//! the loop reads): where the fingertips truly touch, the true contact forces as arrows, and
//! the object's true rotation beside the estimated one.
//!
//! It is off the control loop: it reads its subscribers on its own 10 ms timer (no node on the
//! loop wakes it), builds a frame from the newest state at `visualizer.rate_hz`, and hands it to the
//! recording thread ([`record`]) through a bounded queue (`visualizer.queue`): when the
//! recording lags (a slow viewer; Rerun's SDK blocks when its queues are full), frames are
//! dropped and counted (its health's `refused`, and `/timeseries/dropped_frames`), never
//! queued without bound. Rerun lives in this crate only.
//!
//! Where the recording goes comes from `icrflow run` in the node's launch
//! ([`icrflow_runtime::launch::RecordingLaunch`], `--recording TARGET --recording-id ID`): an
//! `.rrd` file (the default), a viewer it spawns, or a viewer at a URL.

#![warn(missing_docs)]

pub mod blueprint;
pub mod geometry;
pub mod plan;
pub mod record;
pub mod render;

/// The Rerun SDK, as this crate uses it.
pub use rerun;

use std::sync::mpsc::{TrySendError, sync_channel};
use std::time::{Duration, Instant};

use anyhow::{Context as _, Result, anyhow, bail};
use icrflow_grasp::math::Vec3;
use icrflow_interfaces::{
    CommandMode, GraspState, JointState, MAX_FINGERS, PlanStepHeader, PlantTruth, TRACE_STAMPS,
    topics,
};
use icrflow_runtime::event::serve;
use icrflow_runtime::health::Health;
use icrflow_runtime::launch::RecordingLaunch;
use icrflow_runtime::node::Context;
use icrflow_scenario::Loaded;
use icrflow_scenario::{Recording, rrd_parts};

use geometry::{P3, p3};
use record::{FingerView, Frame, Statics, TruthView};

/// A restarted visualizer must not overwrite what its predecessor wrote: it records into the
/// first free `STEM.N.rrd` beside the file (same recording id, so the viewer shows them as one:
/// `rerun STEM.rrd STEM.2.rrd`).
fn fresh(recording: Recording) -> Recording {
    match recording {
        Recording::Rrd(path) => Recording::Rrd(icrflow_scenario::rrd_part(
            &path,
            1 + rrd_parts(&path).len() as u32,
        )),
        other => other,
    }
}

/// The latest of everything the frames are built from.
#[derive(Default)]
struct State {
    grasp: Option<GraspState>,
    joints: Option<JointState>,
    quality: Option<f64>,
    latency: Option<[f64; 7]>,
    step: Option<u64>,
    /// The newest truth of a simulated plant.
    truth: Option<PlantTruth>,
}

impl State {
    /// A scene and time-series frame from the newest state, taking the quality and latency
    /// gathered since the last one; none before the first grasp state.
    fn frame(&mut self, t: f64, ctx: &Context<Loaded>, com: &Vec3, dropped: u64) -> Option<Frame> {
        let g = self.grasp.as_ref()?;
        Some(tick_frame(
            t,
            g,
            self.joints.as_ref(),
            self.truth.as_ref(),
            ctx,
            com,
            &mut self.quality,
            &mut self.latency,
            dropped,
        ))
    }
}

/// What a recording of `setup` with the margin `alpha` shows from the start, the object turning
/// about the unit `axis` (hand frame); `run`: of a pipeline run (else of a plan).
pub(crate) fn statics(
    setup: &icrflow_scenario::Setup,
    id: &str,
    alpha: f64,
    axis: &Vec3,
    run: bool,
) -> Statics {
    let radius = setup.object.max_radius();
    let arrow = axis * (1.5 * radius);
    Statics {
        recording_id: id.to_string(),
        object: geometry::object_mesh(&setup.object),
        object_colours: geometry::object_colours(&setup.object),
        marker: (
            p3(&setup.object.centre_of_mass),
            [1.35 * radius as f32, 0.0, 0.0],
        ),
        ows: geometry::hull_mesh(&geometry::scaled_ows(&setup.problem, alpha)),
        alpha,
        axis: (p3(&setup.object.centre_of_mass), p3(&arrow)),
        fingers: setup.hand.fingers.iter().map(|f| f.id).collect(),
        layout: blueprint::Layout {
            hand_radius: geometry::hand_radius(&setup.hand, radius) as f32,
            run,
            spatial: setup.spatial.is_some(),
        },
    }
}

/// Runs the visualizer node.
pub fn run(ctx: &Context<Loaded>) -> Result<()> {
    let Some(RecordingLaunch { target, id, footer }) = &ctx.launch.recording else {
        bail!("no --recording TARGET: the visualizer is started by `icrflow run`");
    };
    let (recording, footer) = (fresh(Recording::parse(target)?), *footer);
    let spec = &ctx.scenario.config.visualizer;
    let setup = &ctx.scenario.setup;
    let problem = &setup.problem;
    let alpha = ctx.scenario.config.grasp.alpha;
    let com = setup.object.centre_of_mass;
    // Subscribed first, and the loop runs while the recording opens (a spawned viewer may take
    // seconds to listen): frames queue meanwhile, so the first plan steps are not missed.
    let grasps = ctx.bus.subscriber(topics::GRASP_STATE)?;
    let joints = ctx.bus.subscriber(topics::JOINT_STATE)?;
    let commands = ctx.bus.subscriber(topics::HAND_COMMAND)?;
    let plans = ctx.bus.slice_subscriber(topics::PLAN_STEP)?;
    let truths = ctx.bus.subscriber(topics::PLANT_TRUTH)?;
    let statics = statics(setup, id, alpha, &Vec3::z(), true);
    // The recording thread: it owns the stream, so only it can block on a lagging viewer.
    let (tx, rx) = sync_channel::<Frame>(spec.queue);
    let (opened_tx, opened_rx) = sync_channel::<Result<()>>(1);
    let target = recording.clone();
    let recorder = std::thread::Builder::new()
        .name("recording".into())
        .spawn(move || -> Result<u64> {
            let rec = match record::open(&target, &statics.recording_id, footer, &statics.layout)
                .and_then(|rec| record::statics(&rec, &statics).map(|()| rec))
            {
                Ok(rec) => {
                    let _ = opened_tx.send(Ok(()));
                    rec
                }
                Err(e) => {
                    let _ = opened_tx.send(Err(anyhow!("{e:#}")));
                    return Ok(0);
                }
            };
            let logged = record::log_frames(&rec, statics.alpha, rx)?;
            rec.flush_with_timeout(Duration::from_secs(4))
                .map_err(|e| anyhow!("flushing the recording: {e}"))?;
            Ok(logged)
        })
        .context("starting the recording thread")?;
    // Whether the recording is open yet (checked on each wake-up; a failure to open ends
    // the node).
    let mut opened = false;
    let mut check_opened = || -> Result<()> {
        if opened {
            return Ok(());
        }
        match opened_rx.try_recv() {
            Ok(result) => {
                result?;
                opened = true;
                match &recording {
                    Recording::Rrd(p) if footer => {
                        eprintln!("icrflow-visualizer: recording to {}", p.display())
                    }
                    Recording::Rrd(p) => eprintln!(
                        "icrflow-visualizer: recording to {} without Rerun's index footer (a live run; `rerun rrd optimize` adds it)",
                        p.display()
                    ),
                    Recording::Spawn(port) => eprintln!(
                        "icrflow-visualizer: recording to a Rerun viewer spawned on port {port}"
                    ),
                    Recording::Connect(url) => {
                        eprintln!("icrflow-visualizer: recording to the viewer at {url}")
                    }
                }
                Ok(())
            }
            Err(std::sync::mpsc::TryRecvError::Empty) => Ok(()),
            Err(std::sync::mpsc::TryRecvError::Disconnected) => {
                bail!("the recording thread ended while opening")
            }
        }
    };
    let mut health = Health::new(ctx)?;
    let mut state = State::default();
    let mut dropped = 0u64;
    let started = Instant::now();
    let period = Duration::from_secs_f64(1.0 / spec.rate_hz);
    let mut next_frame = started;
    // The subscribers are read every RESYNC (10 ms), more often than frames are made, so that
    // no hand command is lost to a full subscriber queue (32 at 1 kHz) between two frames:
    // the quality series' minimum is the run's.
    // Hands a frame to the recording thread, or drops and counts it; false when that thread
    // has ended.
    let send = |frame: Frame, health: &mut Health, dropped: &mut u64| match tx.try_send(frame) {
        Ok(()) => {
            health.processed += 1;
            true
        }
        Err(TrySendError::Full(_)) => {
            *dropped += 1;
            health.refuse("the recording lags: frame dropped");
            true
        }
        Err(TrySendError::Disconnected(_)) => false,
    };
    // Until SIGTERM or SIGINT (another signal, SIGCONT or SIGWINCH, only interrupts the wait),
    // or a failure: every tick reads every input (see `icrflow_runtime::event::serve`).
    let tick = period.min(icrflow_runtime::event::RESYNC);
    let served = serve(ctx, &[], Some(tick), |_| {
        check_opened()?;
        let t = started.elapsed().as_secs_f64();
        if let Some(g) = grasps.latest()? {
            state.grasp = Some(g);
        }
        if let Some(j) = joints.latest()? {
            state.joints = Some(j);
        }
        if let Some(truth) = truths.latest()? {
            state.truth = Some(truth);
        }
        commands.drain(|c| {
            if c.mode != CommandMode::Track as u32 {
                return;
            }
            state.quality = Some(state.quality.map_or(c.quality, |q| q.min(c.quality)));
            let s = c.header.trace.as_slice();
            if s.len() == TRACE_STAMPS {
                let us = |a: u64, b: u64| b.saturating_sub(a) as f64 * 1e-3;
                let l = [
                    us(s[0], s[6]),
                    us(s[0], s[1]),
                    us(s[2], s[3]),
                    us(s[4], s[5]),
                    us(s[1], s[2]),
                    us(s[3], s[4]),
                    us(s[5], s[6]),
                ];
                let m = state.latency.get_or_insert(l);
                for (a, b) in m.iter_mut().zip(l) {
                    *a = a.max(b);
                }
            }
        })?;
        let mut steps = Vec::new();
        plans.drain(|h, regions| {
            if state.step.is_none_or(|s| h.step > s) {
                state.step = Some(h.step);
                steps.push(live_step_frame(t, h, regions, problem));
            }
        })?;
        for f in steps {
            if !send(f, &mut health, &mut dropped) {
                bail!("the recording thread ended");
            }
        }
        let now = Instant::now();
        if now >= next_frame
            && let Some(frame) = state.frame(t, ctx, &com, dropped)
        {
            next_frame = (next_frame + period).max(now);
            if !send(frame, &mut health, &mut dropped) {
                bail!("the recording thread ended");
            }
        }
        health.tick()?;
        Ok(())
    });
    // Stopped: what came since the last frame goes in a last one; the rest of the queue is
    // written, and the file closed.
    if state.quality.is_some()
        && let Some(frame) = state.frame(started.elapsed().as_secs_f64(), ctx, &com, dropped)
    {
        send(frame, &mut health, &mut dropped);
    }
    drop(tx);
    let logged = recorder
        .join()
        .map_err(|_| anyhow!("the recording thread panicked"))??;
    health.report(icrflow_interfaces::NodeState::Stopping)?;
    eprintln!("icrflow-visualizer: {logged} frames recorded, {dropped} dropped");
    served
}

/// A plan step's frame from the plan-step message: its payload holds each finger's region,
/// then the rendezvous region of an attach step.
fn live_step_frame(
    t: f64,
    h: &PlanStepHeader,
    regions: &[u32],
    problem: &icrflow_grasp::quality::GraspProblem,
) -> Frame {
    let mut fingers = Vec::new();
    let mut at = 0usize;
    for (slot, target) in h.targets.iter().enumerate().take(h.finger_count as usize) {
        let len = h.region_lengths[slot] as usize;
        let region = regions.get(at..at + len).unwrap_or(&[]);
        at += len;
        let contact = (target.in_contact != 0).then_some(target.candidate as usize);
        fingers.push((target.finger, contact, region));
    }
    let rendezvous = (h.rendezvous_length > 0).then(|| {
        let len = h.rendezvous_length as usize;
        (
            h.rendezvous_finger,
            regions.get(at..at + len).unwrap_or(&[]),
        )
    });
    step_frame(Some(t), h.step, h.phase, &fingers, rendezvous, problem)
}

/// A plan step's frame: each finger's ICR (its candidates `region`, shown while the finger is
/// in contact at candidate `contact`), the rendezvous region of an attach step, and the wrench
/// space of the contacts. Candidate indices out of range are skipped.
pub(crate) fn step_frame(
    t: Option<f64>,
    step: u64,
    phase: u32,
    fingers: &[(u32, Option<usize>, &[u32])],
    rendezvous: Option<(u32, &[u32])>,
    problem: &icrflow_grasp::quality::GraspProblem,
) -> Frame {
    let candidates = problem.candidates();
    let count = candidates.points.len();
    // Drawn a little outside the surface, so that they show over the object's silhouette
    // seen from the top (a planar grasp's candidates lie on its equator).
    let out = geometry::ICR_OFFSET * problem.frame().rho();
    let points = |region: &[u32]| -> Vec<P3> {
        region
            .iter()
            .filter(|&&i| (i as usize) < count)
            .map(|&i| {
                let i = i as usize;
                p3(&(candidates.points[i] + out * candidates.normals[i]))
            })
            .collect()
    };
    let mut icrs = Vec::new();
    let mut contacts = Vec::new();
    let mut candidate_wrenches = Vec::new();
    for &(finger, contact, region) in fingers {
        let in_contact = contact.is_some_and(|c| c < count);
        if let Some(c) = contact.filter(|_| in_contact) {
            contacts.push(c);
            for &i in region.iter().filter(|&&i| (i as usize) < count) {
                candidate_wrenches.extend(geometry::candidate_wrenches(problem, i as usize));
            }
        }
        icrs.push((finger, in_contact, points(region)));
    }
    let primitive: Vec<P3> = contacts
        .iter()
        .flat_map(|&c| geometry::candidate_wrenches(problem, c))
        .collect();
    Frame::Step {
        t,
        step,
        phase,
        icrs,
        rendezvous: rendezvous.map(|(finger, region)| (finger, points(region))),
        gws: geometry::hull_mesh(&primitive),
        primitive,
        candidates: candidate_wrenches,
    }
}

/// Contacts at hand-frame points with outward normals: their points and their friction cones'
/// edges (a contact with a non-finite point or a zero normal is left out).
pub(crate) fn contacts_view(
    contacts: impl Iterator<Item = (Vec3, Vec3)>,
    grasp: &icrflow_scenario::GraspSpec,
) -> (Vec<P3>, Vec<Vec<P3>>) {
    let mut points = Vec::new();
    let mut cones = Vec::new();
    for (p, n) in contacts {
        if !(p.iter().all(|x| x.is_finite()) && n.norm() > 0.0) {
            continue;
        }
        points.push(p3(&p));
        cones.extend(geometry::cone_edges(
            &p,
            &n,
            grasp.model.mu(),
            grasp.model.edges(),
            grasp.space,
            geometry::CONE_LENGTH,
        ));
    }
    (points, cones)
}

/// A finger at joint angles `q` (rad): its links, fingertip, and the fingertip's angle around
/// the object's `centre` (hand frame); none for angles that are not the finger's.
pub(crate) fn finger_view(
    finger: &icrflow_plan::hand::Finger,
    q: &[f64],
    centre: &Vec3,
) -> Option<FingerView> {
    if q.len() != finger.dof() || q.iter().any(|x| !x.is_finite()) {
        return None;
    }
    let pose = finger.fk(q);
    let mut links: Vec<P3> = pose.joints.iter().map(p3).collect();
    links.push(p3(&pose.tip_centre));
    Some(FingerView {
        finger: finger.id,
        links,
        tip: (p3(&pose.tip_centre), finger.tip_radius as f32),
        angle_deg: geometry::angle_deg(&pose.tip_centre, centre),
    })
}

/// What a simulated plant's truth shows: the fingertips touching the object, where, and with
/// what force; the object's pose (its frame at the hand frame's origin at the start, centre of
/// mass `com`), and how far it turned off the plan's `axis`.
fn truth_view(t: &PlantTruth, com: &Vec3, axis: &Vec3) -> TruthView {
    let n = (t.finger_count as usize).min(MAX_FINGERS);
    let touching = (0..n).filter(|&s| t.in_contact[s] != 0);
    let f32s = |v: &[f64; 3]| [v[0] as f32, v[1] as f32, v[2] as f32];
    let (translation, rotation) = geometry::pose(t.position, t.orientation, com);
    let q = rotation.quaternion();
    TruthView {
        contacts: touching
            .clone()
            .map(|s| f32s(&t.contact_points[s]))
            .collect(),
        forces: touching.map(|s| f32s(&t.contact_forces[s])).collect(),
        rotation_deg: t.rotation.to_degrees(),
        pose: (
            p3(&translation),
            [q.i as f32, q.j as f32, q.k as f32, q.w as f32],
        ),
        tilt_deg: icrflow_plan::rolling::tilt(&rotation, &nalgebra::Unit::new_normalize(*axis))
            .to_degrees(),
    }
}

/// A scene and time-series frame from the newest grasp state and joint readings; takes the
/// quality and latency gathered since the last one.
#[allow(clippy::too_many_arguments)]
fn tick_frame(
    t: f64,
    g: &GraspState,
    joints: Option<&JointState>,
    truth: Option<&PlantTruth>,
    ctx: &Context<Loaded>,
    com: &Vec3,
    quality: &mut Option<f64>,
    latency: &mut Option<[f64; 7]>,
    dropped: u64,
) -> Frame {
    let (translation, rotation) = geometry::pose(g.position, g.orientation, com);
    let centre = Vec3::from(g.position);
    let (contacts, cones) = contacts_view(
        g.fingers
            .iter()
            .take(g.finger_count as usize)
            .filter(|c| c.in_contact != 0)
            .map(|c| {
                (
                    translation + rotation * Vec3::from(c.point),
                    rotation * Vec3::from(c.normal),
                )
            }),
        &ctx.scenario.config.grasp,
    );
    let mut fingers = Vec::new();
    if let Some(j) = joints {
        for slot in 0..(j.finger_count as usize).min(j.finger_ids.len()) {
            let Some(finger) = ctx.scenario.setup.hand.finger(j.finger_ids[slot]) else {
                continue;
            };
            let q = &j.positions[slot][..finger.dof().min(j.positions[slot].len())];
            fingers.extend(finger_view(finger, q, &centre));
        }
    }
    let truth = truth.map(|t| truth_view(t, com, &ctx.scenario.config.turn.axis));
    let q = rotation.quaternion();
    Frame::Tick {
        t: Some(t),
        pose: (
            p3(&translation),
            [q.i as f32, q.j as f32, q.k as f32, q.w as f32],
        ),
        object_deg: g.rotation.to_degrees(),
        contacts,
        cones,
        fingers,
        truth,
        quality: quality.take(),
        latency: latency.take(),
        dropped,
    }
}
