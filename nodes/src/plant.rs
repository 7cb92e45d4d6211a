//! The simulated hand and object (`icrflow-plant`): applies hand commands quasi-statically and
//! publishes noisy joint encoders at the loop rate and noisy, delayed object-pose
//! measurements at a lower rate.
//!
//! Each tick (`pipeline.rate_hz`): each finger's joints move toward the last tracked command
//! along a straight line in joint space, the largest at `pipeline.joint_speed_deg_s` for the
//! time since the last tick; a held command keeps them still. The fingers commanded with
//! a force that touch the object before and after the move roll it ([`icrflow_plan::rolling`]): the
//! object's rotation is the mean of what each implies. Encoders get Gaussian noise
//! (`pipeline.joint_noise_deg`); every `1 / pipeline.pose_rate_hz` s a pose measurement of the
//! rotation `pipeline.pose_latency_ms` ago, with noise `pipeline.pose_noise_deg`, is published.
//! A command older than `pipeline.max_input_age_ms` is not followed: the hand holds still.
//! Fingertips and links pass through the object (collisions are not simulated); a fingertip
//! that goes inside it, not in contact, or a link that does, is reported on stderr.
//!
//! With `pipeline.slip_deg`, the object slips once, `pipeline.slip_at_s` after the plant
//! started: it turns by that much under the fingertips, which stay where they are (a knock on
//! the object; `run` allows it on circular sections only, where the fingertips stay on the
//! surface). The estimator sees it in the pose measurements; the planner node plans again.
//!
//! It also publishes what it knows to be true (the object's rotation, which fingers touch it)
//! on [`topics::PLANT_TRUTH`], every tenth tick, for the run's summary and the tests; no node
//! of the loop reads it.
//!
//! The plant stands for the physical hand and object, whose state outlives any process: it
//! keeps its state in `plant.state` in the run's bus directory, and a restarted plant resumes
//! from it instead of from the initial grasp.

use std::collections::VecDeque;
use std::fmt::Write as _;
use std::time::{Duration, Instant};

use anyhow::{Context as _, Result};
use icrflow_interfaces::{
    CommandMode, HandCommand, Header, JointState, Kind, MAX_FINGERS, MAX_JOINTS, ObjectPose,
    PlantTruth, topics,
};

use crate::Context;
use crate::noise::Noise;
use icrflow_plan::rolling::tip;
use icrflow_runtime::checkpoint::Checkpoint;
use icrflow_runtime::health::{Health, Sequence, now};

/// Distance within which a pressing fingertip comes into contact (m).
const TOUCH: f64 = 5e-4;
/// The truth ([`PlantTruth`]) is published every this many ticks.
const TRUTH_EVERY: u64 = 10;

/// Every finger's joints in the initial grasp `contacts` (a free finger at its home pose).
pub fn initial_joints(
    hand: &icrflow_plan::hand::Hand,
    contacts: &[icrflow_plan::planner::Contact],
) -> Vec<Vec<f64>> {
    hand.fingers
        .iter()
        .map(|f| {
            contacts
                .iter()
                .find(|c| c.finger == f.id)
                .map_or_else(|| f.home.clone(), |c| c.q.clone())
        })
        .collect()
}

/// Runs the plant.
pub fn run(ctx: &Context) -> Result<()> {
    let p = &ctx.scenario.config.pipeline;
    let hand = &ctx.scenario.setup.hand;
    let surface = ctx.scenario.setup.surface()?;
    // The true state starts in the initial grasp, as the planner computes it.
    let (contacts, _) = ctx
        .scenario
        .setup
        .scenario(&ctx.scenario.config)
        .start()
        .context("the initial grasp")?;
    let mut q = initial_joints(hand, &contacts);
    // In contact: pressed on the object (a force is commanded) since it touched it. A finger
    // in contact rolls the object; it leaves contact when no force is commanded.
    let mut contact: Vec<bool> = hand
        .fingers
        .iter()
        .map(|f| contacts.iter().any(|c| c.finger == f.id))
        .collect();
    // Fingers whose fingertip is inside the object without being in contact.
    let mut intruding = vec![false; hand.fingers.len()];
    let mut link_intruding = vec![false; hand.fingers.len()];
    let mut theta = 0.0;
    // Whether the configured slip has happened (never, without one).
    let mut slipped = p.slip == 0.0;
    let state_file = ctx.bus.config().root.join("plant.state");
    if let Ok(text) = std::fs::read_to_string(&state_file) {
        let values: Vec<f64> = text
            .split_whitespace()
            .filter_map(|v| v.parse().ok())
            .collect();
        let needed = 2 + hand.fingers.len() * 2 + q.iter().map(Vec::len).sum::<usize>();
        if values.len() == needed {
            theta = values[0];
            slipped |= values[needed - 1] != 0.0;
            let mut at = 1;
            for (slot, joints) in q.iter_mut().enumerate() {
                contact[slot] = values[at] != 0.0;
                at += 2;
                for a in joints.iter_mut() {
                    *a = values[at];
                    at += 1;
                }
            }
        }
    }
    let max_age_ns = (p.max_input_age * 1e9) as u64;
    let mut history: VecDeque<(u64, f64)> = VecDeque::with_capacity(4096);
    let mut noise = Noise::new(p.seed);
    let mut target: Option<HandCommand> = None;
    let joints = ctx.bus.publisher(topics::JOINT_STATE)?;
    let poses = ctx.bus.publisher(topics::OBJECT_POSE)?;
    let truths = ctx.bus.publisher(topics::PLANT_TRUTH)?;
    let mut truth_seq = Sequence::default();
    let commands = ctx.bus.subscriber(topics::HAND_COMMAND)?;
    let mut health = Health::new(ctx)?;
    let (mut joint_seq, mut pose_seq) = (Sequence::default(), Sequence::default());
    let dt = 1.0 / p.rate_hz;
    let pose_every = (p.rate_hz / p.pose_rate_hz).round().max(1.0) as u64;
    let latency_ns = (p.pose_latency * 1e9) as u64;

    let mut ticks: u64 = 0;
    let log_contacts = ctx.launch.log.contacts;
    let saved = Checkpoint::new(state_file)?;
    // Its thread (started above) stays at normal priority.
    icrflow_runtime::node::promote(ctx.name, ctx.launch.realtime);
    // The plant keeps its own clock, like a hand's controller: a tick every period on an
    // absolute schedule (a WaitSet interval would drift by its millisecond timeouts), taking
    // the newest command at each tick; SIGTERM or SIGINT during the sleep stops it (another
    // signal only cuts the sleep short, and it sleeps on).
    let period = Duration::from_secs_f64(dt);
    let slip_at = Instant::now() + Duration::from_secs_f64(p.slip_at);
    let mut next = Instant::now();
    let mut last_tick = next;
    loop {
        health.tick()?;
        next += period;
        let early = next.saturating_duration_since(Instant::now());
        if early > Duration::ZERO {
            if icrflow_runtime::event::sleep_until(ctx.bus.node(), next) {
                return Ok(());
            }
        } else if Instant::now().duration_since(next) > period {
            // A whole period late (the process was not scheduled in time): the missed ticks
            // are skipped, not sent in a burst.
            next = Instant::now();
        }
        if let Some(c) = commands.latest()? {
            health.processed += 1;
            if c.header.check(Kind::HandCommand).is_err() {
                health.refuse("hand command of another schema or kind");
            } else if c.mode == CommandMode::Track as u32 {
                target = Some(c);
            } else {
                // Hold: stay where we are.
                target = None;
            }
        }
        ticks += 1;
        let t = now();
        // The joints move for the time since the last tick (more than a period when this
        // process was late), as a physical hand's would.
        let at = Instant::now();
        let max_step = p.joint_speed
            * at.duration_since(last_tick)
                .as_secs_f64()
                .clamp(dt, 10.0 * dt);
        last_tick = at;
        if target
            .as_ref()
            .is_some_and(|c| t.saturating_sub(c.header.source_time_ns) > max_age_ns)
        {
            // A stale command is not followed: hold still.
            target = None;
        }
        // Move the joints; roll the object with the fingers that press on it.
        let mut turn = 0.0;
        let mut rolling = 0;
        for (slot, f) in hand.fingers.iter().enumerate() {
            let before = tip(f, &q[slot]);
            if let Some(c) = &target {
                let Some(k) = (0..c.finger_count as usize).find(|&k| c.finger_ids[k] == f.id)
                else {
                    continue;
                };
                // Along the straight line to the command in joint space, every joint scaled
                // alike (a servo following a stream of set points along the same line).
                let mut goal = [0.0; MAX_JOINTS];
                let mut largest = 0.0_f64;
                for (j, a) in q[slot].iter().enumerate().take(MAX_JOINTS) {
                    goal[j] = c.joint_targets[k][j].clamp(f.joints[j].lower, f.joints[j].upper);
                    largest = largest.max((goal[j] - a).abs());
                }
                let arrived = largest <= max_step;
                let scale = if arrived { 1.0 } else { max_step / largest };
                for (j, a) in q[slot].iter_mut().enumerate().take(MAX_JOINTS) {
                    *a += scale * (goal[j] - *a);
                }
                let pressing = c.forces[k].iter().any(|x| *x != 0.0);
                let after = tip(f, &q[slot]);
                // The simulation lets a fingertip pass through the object; a real one would
                // hit it. Said on entering, always: it is a planning or tracking fault.
                // The fingertip's gap to the object (the object turns after every finger moved).
                let gap = surface.contact_of(&after, f, theta).gap;
                let depth = -gap;
                let inside = !contact[slot] && depth > TOUCH;
                if inside && !intruding[slot] {
                    eprintln!(
                        "icrflow-plant: finger {} is inside the object ({:.2} mm deep): a real \
                         hand would hit it here",
                        f.id,
                        depth * 1e3
                    );
                }
                intruding[slot] = inside;
                // The same for the links (the planner keeps them off the object).
                let (link_gap, link) = surface.link_gap(f, &q[slot], theta);
                let through = link_gap < -TOUCH;
                if through && !link_intruding[slot] {
                    eprintln!(
                        "icrflow-plant: finger {}'s link {link} passes through the object \
                         ({:.2} mm deep): a real hand would hit it here",
                        f.id,
                        -link_gap * 1e3
                    );
                }
                link_intruding[slot] = through;
                if contact[slot] && pressing {
                    turn += surface.rotation(&before, &after, f, theta);
                    rolling += 1;
                }
                // A pressing finger comes into contact where its motion ends on the surface.
                let was = contact[slot];
                contact[slot] = pressing && (contact[slot] || (arrived && gap.abs() <= TOUCH));
                if contact[slot] != was && log_contacts {
                    eprintln!(
                        "icrflow-plant: finger {} {} the object",
                        f.id,
                        if contact[slot] {
                            "presses on"
                        } else {
                            "leaves"
                        }
                    );
                }
            }
        }
        if rolling > 0 {
            theta += turn / rolling as f64;
        }
        if !slipped && at >= slip_at {
            slipped = true;
            theta += p.slip;
            eprintln!(
                "icrflow-plant: the object slips by {:+.1} deg under the fingertips \
                 (pipeline.slip_deg), to {:.1} deg",
                p.slip.to_degrees(),
                theta.to_degrees()
            );
        }
        if ticks.is_multiple_of(10) {
            saved.store(|text| {
                let _ = write!(text, "{theta:e}");
                for (slot, joints) in q.iter().enumerate() {
                    text.push_str(if contact[slot] { " 1 0" } else { " 0 0" });
                    for a in joints {
                        let _ = write!(text, " {a:e}");
                    }
                }
                text.push_str(if slipped { " 1" } else { " 0" });
            });
        }
        history.push_back((t, theta));
        while history.len() > 4000 {
            history.pop_front();
        }
        // Encoders.
        let seq = joint_seq.advance();
        let mut m = JointState {
            header: Header::new(Kind::JointState, seq, 0, 0),
            finger_count: hand.fingers.len().min(MAX_FINGERS) as u32,
            ..Default::default()
        };
        for (slot, f) in hand.fingers.iter().enumerate().take(MAX_FINGERS) {
            m.finger_ids[slot] = f.id;
            m.joint_counts[slot] = f.dof().min(MAX_JOINTS) as u32;
            for (j, a) in q[slot].iter().enumerate().take(MAX_JOINTS) {
                m.positions[slot][j] = a + noise.gauss(p.joint_noise);
            }
        }
        joints.publish(m)?;
        // The truth, every TRUTH_EVERY ticks (the run samples it at 100 Hz).
        if ticks.is_multiple_of(TRUTH_EVERY) {
            let half = 0.5 * theta;
            let mut truth = PlantTruth {
                header: Header::new(Kind::PlantTruth, truth_seq.advance(), 0, 0),
                orientation: [half.cos(), 0.0, 0.0, half.sin()],
                rotation: theta,
                finger_count: hand.fingers.len().min(MAX_FINGERS) as u32,
                ..Default::default()
            };
            for (slot, f) in hand.fingers.iter().enumerate().take(MAX_FINGERS) {
                truth.finger_ids[slot] = f.id;
                truth.in_contact[slot] = u32::from(contact[slot]);
            }
            truths.publish(truth)?;
        }
        // Pose measurement of the scene `latency` ago.
        if ticks.is_multiple_of(pose_every) {
            let captured = t.saturating_sub(latency_ns);
            let past = history
                .iter()
                .rev()
                .find(|(when, _)| *when <= captured)
                .or(history.front())
                .map_or(theta, |(_, th)| *th);
            let measured = past + noise.gauss(p.pose_noise);
            let half = 0.5 * measured;
            poses.publish(ObjectPose {
                header: Header::new(Kind::ObjectPose, pose_seq.advance(), 0, captured),
                captured_time_ns: captured,
                position: [0.0; 3],
                orientation: [half.cos(), 0.0, 0.0, half.sin()],
            })?;
        }
    }
}
