//! The simulated hand and object (`icrflow-plant`): applies hand commands quasi-statically and
//! publishes noisy joint encoders at the loop rate and noisy, delayed object-pose
//! measurements at a lower rate.
//!
//! Each tick (`pipeline.rate_hz`): each finger's joints move toward the last tracked command
//! along a straight line in joint space, the largest at `pipeline.joint_speed_deg_s` for the
//! time since the last tick; a held command keeps them still. The fingers commanded with
//! a force that touch the object before and after the move roll it
//! ([`icrflow_plan::rolling::Roller`]): a planar hand's section turns about the hand's z axis
//! by the mean of what each finger implies; a spatial hand's object turns about its plan's
//! axis by the least squares of the fingers' rolling without slipping
//! ([`icrflow_plan::spatial::rolling`]). The object's centre stays where it is. Encoders get Gaussian noise
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
//!
//! [`Plant`] is the pure step (the time and the newest command in, the measurements out);
//! [`run`] is the node around it (the timer, the bus, health, the checkpoint).

use std::collections::VecDeque;
use std::fmt::Write as _;
use std::time::Duration;

use anyhow::Result;
use icrflow_interfaces::{
    CommandMode, HandCommand, Header, JointState, Kind, MAX_FINGERS, MAX_JOINTS, ObjectPose,
    PlantTruth, topics,
};
use icrflow_plan::hand::Hand;
use icrflow_plan::rolling::Roller;
use icrflow_scenario::{PipelineSpec, PlantKind};

use crate::Context;
use crate::noise::Noise;
use icrflow_runtime::checkpoint::Checkpoint;
use icrflow_runtime::event::serve;
use icrflow_runtime::health::{Health, Sequence, now};

/// Distance within which a pressing fingertip comes into contact (m).
const TOUCH: f64 = 5e-4;
/// The truth ([`PlantTruth`]) is published every this many ticks.
const TRUTH_EVERY: u64 = 10;
/// The plant's state is checkpointed every this many ticks.
const SAVE_EVERY: u64 = 10;
/// Rotations kept to measure the pose of the past from (one per tick).
const HISTORY: usize = 4000;

pub use icrflow_physics::scene::initial_joints;

/// Something the plant has to say (the node writes it on stderr).
#[derive(Debug, Clone, Copy, PartialEq)]
#[non_exhaustive]
pub enum Event {
    /// A fingertip went inside the object without being in contact (said on entering).
    Inside {
        /// The finger.
        finger: u32,
        /// How deep (m).
        depth: f64,
    },
    /// A finger's link went through the object (said on entering).
    LinkThrough {
        /// The finger.
        finger: u32,
        /// The link.
        link: usize,
        /// How deep (m).
        depth: f64,
    },
    /// A finger came into contact (pressing on the object) or left it.
    Contact {
        /// The finger.
        finger: u32,
        /// In contact now.
        on: bool,
    },
    /// The configured push of the object began (`pipeline.push_n`, `push_nm`; MuJoCo).
    Pushed {
        /// The force (N, hand frame).
        force: [f64; 3],
        /// The torque (N m).
        torque: [f64; 3],
        /// For how long (s).
        duration: f64,
        /// The object's rotation when it began (rad).
        at: f64,
    },
    /// The configured slip happened.
    Slipped {
        /// By how much (rad).
        by: f64,
        /// The rotation after it (rad).
        to: f64,
    },
}

impl std::fmt::Display for Event {
    fn fmt(&self, out: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match *self {
            Self::Inside { finger, depth } => write!(
                out,
                "finger {finger} is inside the object ({:.2} mm deep): a real hand would hit it \
                 here",
                depth * 1e3
            ),
            Self::LinkThrough {
                finger,
                link,
                depth,
            } => write!(
                out,
                "finger {finger}'s link {link} passes through the object ({:.2} mm deep): a real \
                 hand would hit it here",
                depth * 1e3
            ),
            Self::Contact { finger, on } => write!(
                out,
                "finger {finger} {} the object",
                if on { "presses on" } else { "leaves" }
            ),
            Self::Pushed {
                force,
                torque,
                duration,
                at,
            } => write!(
                out,
                "the object is pushed at {:.1} deg (pipeline.push_*): {:?} N and {:?} N m for \
                 {:.0} ms",
                at.to_degrees(),
                force,
                torque,
                duration * 1e3
            ),
            Self::Slipped { by, to } => write!(
                out,
                "the object slips by {:+.1} deg under the fingertips (pipeline.slip_deg), to \
                 {:.1} deg",
                by.to_degrees(),
                to.to_degrees()
            ),
        }
    }
}

/// What a tick measured (their headers to be made by the node).
#[derive(Debug, Clone, Copy)]
pub struct Output {
    /// The encoders, every tick.
    pub joints: JointState,
    /// The truth, every [`TRUTH_EVERY`] ticks.
    pub truth: Option<PlantTruth>,
    /// The pose measurement of the scene `pipeline.pose_latency_ms` ago, every
    /// `1 / pipeline.pose_rate_hz` s (its `captured_time_ns` set).
    pub pose: Option<ObjectPose>,
}

/// The simulated hand and object: their state and the step; no I/O, no clock.
#[derive(Debug)]
pub struct Plant<'a> {
    hand: &'a Hand,
    roller: Roller<'a>,
    /// Joint speed (rad/s), joint and pose noise (rad), slip (rad).
    joint_speed: f64,
    joint_noise: f64,
    pose_noise: f64,
    slip: f64,
    /// The period (s).
    dt: f64,
    max_age_ns: u64,
    latency_ns: u64,
    pose_every: u64,
    /// When the slip is due (ns).
    slip_at_ns: u64,
    /// The joints (rad).
    q: Vec<Vec<f64>>,
    /// In contact: pressed on the object (a force is commanded) since it touched it. A finger
    /// in contact rolls the object; it leaves contact when no force is commanded.
    contact: Vec<bool>,
    /// Fingers whose fingertip is inside the object without being in contact.
    intruding: Vec<bool>,
    link_intruding: Vec<bool>,
    /// The object's rotation (rad).
    theta: f64,
    /// Whether the configured slip has happened (never, without one).
    slipped: bool,
    /// Per tick: its time and the rotation then.
    history: VecDeque<(u64, f64)>,
    noise: Noise,
    /// The command followed (None: holding still).
    target: Option<HandCommand>,
    ticks: u64,
    /// When the last tick was (ns).
    last_tick: u64,
    events: Vec<Event>,
}

impl<'a> Plant<'a> {
    /// The plant of `hand` holding the object `roller` rolls on in the initial grasp: every
    /// finger's `joints`, the fingers `touching` it ([`icrflow_scenario::Setup::initial_grip`]),
    /// under `pipeline`'s rates, noise and slip, started at `now_ns`.
    pub fn new(
        hand: &'a Hand,
        roller: Roller<'a>,
        (joints, touching): (Vec<Vec<f64>>, &[u32]),
        p: &PipelineSpec,
        now_ns: u64,
    ) -> Self {
        let n = hand.fingers.len();
        Self {
            hand,
            roller,
            joint_speed: p.joint_speed,
            joint_noise: p.joint_noise,
            pose_noise: p.pose_noise,
            slip: p.slip,
            dt: 1.0 / p.rate_hz,
            max_age_ns: (p.max_input_age * 1e9) as u64,
            latency_ns: (p.pose_latency * 1e9) as u64,
            pose_every: (p.rate_hz / p.pose_rate_hz).round().max(1.0) as u64,
            slip_at_ns: now_ns.saturating_add(Duration::from_secs_f64(p.slip_at).as_nanos() as u64),
            q: joints,
            contact: hand
                .fingers
                .iter()
                .map(|f| touching.contains(&f.id))
                .collect(),
            intruding: vec![false; n],
            link_intruding: vec![false; n],
            theta: 0.0,
            slipped: p.slip == 0.0,
            history: VecDeque::with_capacity(HISTORY + 1),
            noise: Noise::new(p.seed),
            target: None,
            ticks: 0,
            last_tick: now_ns,
            // At most three a finger (inside, link through, contact) and the slip.
            events: Vec::with_capacity(3 * n + 1),
        }
    }

    /// The object's rotation (rad).
    pub fn rotation(&self) -> f64 {
        self.theta
    }

    /// Every finger's joints (rad).
    pub fn joints(&self) -> &[Vec<f64>] {
        &self.q
    }

    /// Which fingers are in contact.
    pub fn contacts(&self) -> &[bool] {
        &self.contact
    }

    /// The ticks so far.
    pub fn ticks(&self) -> u64 {
        self.ticks
    }

    /// What the last tick has to say.
    pub fn events(&self) -> &[Event] {
        &self.events
    }

    /// The state as the checkpoint keeps it: the rotation, per finger its contact (and a
    /// spare 0) and its joints, whether the slip happened.
    pub fn save(&self, text: &mut String) {
        let _ = write!(text, "{:e}", self.theta);
        for (slot, joints) in self.q.iter().enumerate() {
            text.push_str(if self.contact[slot] { " 1 0" } else { " 0 0" });
            for a in joints {
                let _ = write!(text, " {a:e}");
            }
        }
        text.push_str(if self.slipped { " 1" } else { " 0" });
    }

    /// Resumes from a state [`Plant::save`] wrote; `false` (nothing changed) if `text` is not
    /// one of this hand's.
    pub fn restore(&mut self, text: &str) -> bool {
        let values: Vec<f64> = text
            .split_whitespace()
            .filter_map(|v| v.parse().ok())
            .collect();
        let needed = 2 + self.q.len() * 2 + self.q.iter().map(Vec::len).sum::<usize>();
        if values.len() != needed {
            return false;
        }
        self.theta = values[0];
        self.slipped |= values[needed - 1] != 0.0;
        let mut at = 1;
        for (slot, joints) in self.q.iter_mut().enumerate() {
            self.contact[slot] = values[at] != 0.0;
            at += 2;
            for a in joints.iter_mut() {
                *a = values[at];
                at += 1;
            }
        }
        true
    }

    /// One tick at `now_ns`, with the newest `command` if one came since the last tick (a
    /// hold stops the hand; a tracking command is followed until it is older than
    /// `pipeline.max_input_age_ms`): the joints move toward the command for the time since
    /// the last tick (one to ten periods), the fingers pressing on the object roll it, the
    /// slip happens when due; then the measurements.
    pub fn tick(&mut self, now_ns: u64, command: Option<&HandCommand>) -> Output {
        self.events.clear();
        if let Some(c) = command {
            self.target = CommandMode::moves(c.mode).then_some(*c);
        }
        self.ticks += 1;
        let t = now_ns;
        // The joints move for the time since the last tick (more than a period when the
        // process was late), as a physical hand's would.
        let elapsed = t.saturating_sub(self.last_tick) as f64 * 1e-9;
        let max_step = self.joint_speed * elapsed.clamp(self.dt, 10.0 * self.dt);
        self.last_tick = t;
        if self
            .target
            .as_ref()
            .is_some_and(|c| t.saturating_sub(c.header.source_time_ns) > self.max_age_ns)
        {
            // A stale command is not followed: hold still.
            self.target = None;
        }
        self.roll(max_step);
        if !self.slipped && t >= self.slip_at_ns {
            self.slipped = true;
            self.theta += self.slip;
            self.events.push(Event::Slipped {
                by: self.slip,
                to: self.theta,
            });
        }
        if self.history.len() == HISTORY {
            self.history.pop_front();
        }
        self.history.push_back((t, self.theta));
        self.measure(t)
    }

    /// Moves the joints by at most `max_step` toward the target; rolls the object with the
    /// fingers that press on it.
    fn roll(&mut self, max_step: f64) {
        let (hand, roller, theta) = (self.hand, self.roller, self.theta);
        let Some(c) = &self.target else {
            return;
        };
        let (mut turn, mut weight) = (0.0, 0.0);
        for (slot, f) in hand.fingers.iter().enumerate() {
            let q = &mut self.q[slot];
            let mut before = [0.0; MAX_JOINTS];
            let n = q.len().min(MAX_JOINTS);
            before[..n].copy_from_slice(&q[..n]);
            let Some(k) = c.slot_of(f.id) else {
                continue;
            };
            // Along the straight line to the command in joint space, every joint scaled
            // alike (a servo following a stream of set points along the same line).
            let mut goal = [0.0; MAX_JOINTS];
            let mut largest = 0.0_f64;
            for (j, a) in q.iter().enumerate().take(MAX_JOINTS) {
                goal[j] = c.joint_targets[k][j].clamp(f.joints[j].lower, f.joints[j].upper);
                largest = largest.max((goal[j] - a).abs());
            }
            let arrived = largest <= max_step;
            let scale = if arrived { 1.0 } else { max_step / largest };
            for (j, a) in q.iter_mut().enumerate().take(MAX_JOINTS) {
                *a += scale * (goal[j] - *a);
            }
            let pressing = c.presses_slot(k);
            // The simulation lets a fingertip pass through the object; a real one would
            // hit it. Said on entering, always: it is a planning or tracking fault.
            // The fingertip's gap to the object (the object turns after every finger moved).
            let gap = roller.gap(f, q, theta);
            let depth = -gap;
            let inside = !self.contact[slot] && depth > TOUCH;
            if inside && !self.intruding[slot] {
                self.events.push(Event::Inside {
                    finger: f.id,
                    depth,
                });
            }
            self.intruding[slot] = inside;
            // The same for the links (the planner keeps them off the object).
            let (link_gap, link) = roller.link_gap(f, q, theta);
            let through = link_gap < -TOUCH;
            if through && !self.link_intruding[slot] {
                self.events.push(Event::LinkThrough {
                    finger: f.id,
                    link,
                    depth: -link_gap,
                });
            }
            self.link_intruding[slot] = through;
            if self.contact[slot] && pressing {
                let (t, w) = roller.turn(f, &before[..n], q, theta);
                turn += t;
                weight += w;
            }
            // A pressing finger comes into contact where its motion ends on the surface.
            let was = self.contact[slot];
            self.contact[slot] = pressing && (was || (arrived && gap.abs() <= TOUCH));
            if self.contact[slot] != was {
                self.events.push(Event::Contact {
                    finger: f.id,
                    on: self.contact[slot],
                });
            }
        }
        if weight > 0.0 {
            self.theta += turn / weight;
        }
    }

    /// The measurements of tick `t`: the encoders with noise, the truth when due, the pose
    /// of `latency` ago with noise when due.
    fn measure(&mut self, t: u64) -> Output {
        let hand = self.hand;
        let mut joints = JointState {
            finger_count: hand.fingers.len().min(MAX_FINGERS) as u32,
            ..Default::default()
        };
        for (slot, f) in hand.fingers.iter().enumerate().take(MAX_FINGERS) {
            joints.finger_ids[slot] = f.id;
            joints.joint_counts[slot] = f.dof().min(MAX_JOINTS) as u32;
            for (j, a) in self.q[slot].iter().enumerate().take(MAX_JOINTS) {
                joints.positions[slot][j] = a + self.noise.gauss(self.joint_noise);
            }
        }
        let truth = self.ticks.is_multiple_of(TRUTH_EVERY).then(|| {
            let mut truth = PlantTruth {
                orientation: self.roller.orientation(self.theta),
                rotation: self.theta,
                finger_count: hand.fingers.len().min(MAX_FINGERS) as u32,
                ..Default::default()
            };
            for (slot, f) in hand.fingers.iter().enumerate().take(MAX_FINGERS) {
                truth.finger_ids[slot] = f.id;
                truth.in_contact[slot] = u32::from(self.contact[slot]);
            }
            truth
        });
        let pose = self.ticks.is_multiple_of(self.pose_every).then(|| {
            let captured = t.saturating_sub(self.latency_ns);
            let past = self
                .history
                .iter()
                .rev()
                .find(|(when, _)| *when <= captured)
                .or(self.history.front())
                .map_or(self.theta, |(_, th)| *th);
            let measured = past + self.noise.gauss(self.pose_noise);
            ObjectPose {
                captured_time_ns: captured,
                position: [0.0; 3],
                orientation: self.roller.orientation(measured),
                ..Default::default()
            }
        });
        Output {
            joints,
            truth,
            pose,
        }
    }
}

/// The plant of the config (`plant.kind`).
enum Any<'a> {
    Kinematic(Box<Plant<'a>>),
    Mujoco(Box<crate::physical::Physical<'a>>),
}

impl Any<'_> {
    fn tick(&mut self, now_ns: u64, command: Option<&HandCommand>) -> Output {
        match self {
            Self::Kinematic(p) => p.tick(now_ns, command),
            Self::Mujoco(p) => p.tick(now_ns, command),
        }
    }

    fn events(&self) -> &[Event] {
        match self {
            Self::Kinematic(p) => p.events(),
            Self::Mujoco(p) => p.events(),
        }
    }

    fn ticks(&self) -> u64 {
        match self {
            Self::Kinematic(p) => p.ticks(),
            Self::Mujoco(p) => p.ticks(),
        }
    }

    fn save(&self, text: &mut String) {
        match self {
            Self::Kinematic(p) => p.save(text),
            Self::Mujoco(p) => p.save(text),
        }
    }

    fn restore(&mut self, text: &str) -> bool {
        match self {
            Self::Kinematic(p) => p.restore(text),
            Self::Mujoco(p) => p.restore(text),
        }
    }
}

/// Runs the plant.
pub fn run(ctx: &Context) -> Result<()> {
    let config = &ctx.scenario.config;
    let setup = &ctx.scenario.setup;
    let p = &config.pipeline;
    let mut plant = match config.plant.kind {
        PlantKind::Kinematic => {
            // The true state starts in the initial grasp, as the planner computes it.
            let (joints, touching) = setup.initial_grip(config)?;
            let plant = Plant::new(
                &setup.hand,
                setup.roller(config)?,
                (joints, &touching),
                p,
                now(),
            );
            Any::Kinematic(Box::new(plant))
        }
        PlantKind::Mujoco => {
            let (joints, _) = setup.initial_grip(config)?;
            let physical = crate::physical::Physical::new(config, setup, &joints, now())?;
            eprintln!(
                "icrflow-plant: MuJoCo {}, the object {:.3} kg",
                physical.version(),
                physical.sim().object_mass()
            );
            Any::Mujoco(Box::new(physical))
        }
    };
    let joints = ctx.bus.publisher(topics::JOINT_STATE)?;
    let poses = ctx.bus.publisher(topics::OBJECT_POSE)?;
    let truths = ctx.bus.publisher(topics::PLANT_TRUTH)?;
    let commands = ctx.bus.subscriber(topics::HAND_COMMAND)?;
    let mut health = Health::new(ctx)?;
    let (mut joint_seq, mut pose_seq) = (Sequence::default(), Sequence::default());
    let mut truth_seq = Sequence::default();
    let log_contacts = ctx.launch.log.contacts;
    let state_file = ctx.bus.config().root.join("plant.state");
    if let Ok(text) = std::fs::read_to_string(&state_file) {
        plant.restore(&text);
    }
    // Its thread stays at normal priority (`serve` promotes this one).
    let saved = Checkpoint::new(state_file)?;

    // The plant keeps its own clock, like a hand's controller: a tick every period on an
    // absolute schedule, taking the newest command at each tick.
    let period = Some(Duration::from_secs_f64(1.0 / p.rate_hz));
    serve(ctx, &[], period, |ticked| {
        health.tick()?;
        if !ticked {
            return Ok(());
        }
        let command = commands.latest()?;
        if let Some(c) = &command {
            health.processed += 1;
            if c.header.check(Kind::HandCommand).is_err() {
                health.refuse("hand command of another schema or kind");
            }
        }
        let command = command.filter(|c| c.header.check(Kind::HandCommand).is_ok());
        let out = plant.tick(now(), command.as_ref());
        for e in plant.events() {
            if log_contacts || !matches!(e, Event::Contact { .. }) {
                eprintln!("icrflow-plant: {e}");
            }
        }
        if plant.ticks().is_multiple_of(SAVE_EVERY) {
            saved.store(|text| plant.save(text));
        }
        let mut m = out.joints;
        m.header = Header::new(Kind::JointState, joint_seq.advance(), 0, 0);
        joints.publish(m)?;
        if let Some(mut truth) = out.truth {
            truth.header = Header::new(Kind::PlantTruth, truth_seq.advance(), 0, 0);
            truths.publish(truth)?;
        }
        if let Some(mut pose) = out.pose {
            let captured = pose.captured_time_ns;
            pose.header = Header::new(Kind::ObjectPose, pose_seq.advance(), 0, captured);
            poses.publish(pose)?;
        }
        Ok(())
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::command;
    use crate::testing::paper;
    use icrflow_plan::rolling::tip;
    use icrflow_scenario::{Config, Setup};

    /// The initial grasp: every finger's joints and the fingers touching.
    type Grip = (Vec<Vec<f64>>, Vec<u32>);

    /// A start time (ns).
    const T0: u64 = 1_000_000_000_000;

    /// The paper's plant without noise, its initial grasp, and the slots of the fingers in
    /// contact and of those free.
    /// The paper's plant in the initial grasp `grip`, under `p`, started at [`T0`].
    fn paper_plant<'a>(setup: &'a Setup, grip: &Grip, p: &PipelineSpec) -> Plant<'a> {
        let surface = setup.surface().unwrap();
        Plant::new(
            &setup.hand,
            Roller::Section(surface),
            (grip.0.clone(), &grip.1),
            p,
            T0,
        )
    }

    fn still(config: &mut Config, setup: &Setup) -> (Grip, Vec<usize>, Vec<usize>) {
        config.pipeline.joint_noise = 0.0;
        config.pipeline.pose_noise = 0.0;
        let grip = setup.initial_grip(config).unwrap();
        let (touching, free): (Vec<usize>, Vec<usize>) = (0..setup.hand.fingers.len())
            .partition(|&s| grip.1.contains(&setup.hand.fingers[s].id));
        (grip, touching, free)
    }

    #[test]
    fn a_commanded_finger_in_contact_rolls_the_object_as_the_rolling_kinematics_say() {
        let (mut config, setup) = paper();
        let (grip, touching, _) = still(&mut config, &setup);
        let surface = setup.surface().unwrap();
        let mut plant = paper_plant(&setup, &grip, &config.pipeline);
        let dt = (1e9 / config.pipeline.rate_hz) as u64;
        let slot = touching[0];
        let f = &setup.hand.fingers[slot];
        // A small motion of one finger in contact (within a tick's reach), pressing.
        let from = plant.joints().to_vec();
        let mut to = from.clone();
        for a in to[slot].iter_mut() {
            *a += 0.05_f64.to_radians();
        }
        let c = command(&setup, &[slot], &to, true, T0);
        let out = plant.tick(T0 + dt, Some(&c));
        assert_eq!(plant.joints()[slot], to[slot]);
        let turn = surface.rotation(&tip(f, &from[slot]), &tip(f, &to[slot]), f, 0.0);
        assert!(turn.abs() > 1e-5, "the motion rolls: {turn}");
        assert!(
            (plant.rotation() - turn).abs() < 1e-15,
            "{} vs {turn}",
            plant.rotation()
        );
        // The encoders say where the hand is; the fingers in contact stay so.
        for (s, q) in plant.joints().iter().enumerate() {
            assert_eq!(&out.joints.positions[s][..q.len()], &q[..]);
            assert_eq!(out.joints.finger_ids[s], setup.hand.fingers[s].id);
        }
        // The truth (every tenth tick) reports the rotation and the contacts.
        let mut truth = out.truth;
        for k in 2..=TRUTH_EVERY {
            truth = plant.tick(T0 + k * dt, None).truth;
            assert_eq!(truth.is_some(), k == TRUTH_EVERY);
        }
        let truth = truth.unwrap();
        assert_eq!(
            truth.rotation,
            plant.rotation(),
            "a kept command reached moves no more"
        );
        for (s, f) in setup.hand.fingers.iter().enumerate() {
            assert_eq!(truth.finger_ids[s], f.id);
            assert_eq!(truth.in_contact[s], u32::from(touching.contains(&s)));
        }
        assert!(plant.events().is_empty(), "{:?}", plant.events());
    }

    #[test]
    fn a_finger_off_the_object_does_not_turn_it() {
        let (mut config, setup) = paper();
        let (grip, touching, free) = still(&mut config, &setup);
        assert!(!free.is_empty(), "the paper's hand has a free finger");
        let mut plant = paper_plant(&setup, &grip, &config.pipeline);
        let dt = (1e9 / config.pipeline.rate_hz) as u64;
        let mut to = plant.joints().to_vec();
        for slot in [free[0], touching[0]] {
            for a in to[slot].iter_mut() {
                *a += 0.05_f64.to_radians();
            }
        }
        // The free finger pressing in the air, and a finger in contact commanded without a
        // force: it leaves the object, which neither turns.
        let mut c = command(&setup, &[free[0], touching[0]], &to, true, T0);
        c.forces[1] = [0.0; 3];
        plant.tick(T0 + dt, Some(&c));
        assert_eq!(plant.joints()[free[0]], to[free[0]]);
        assert_eq!(plant.joints()[touching[0]], to[touching[0]]);
        assert_eq!(plant.rotation(), 0.0);
        assert_eq!(
            plant.events(),
            &[Event::Contact {
                finger: setup.hand.fingers[touching[0]].id,
                on: false
            }]
        );
        assert!(!plant.contacts()[free[0]] && !plant.contacts()[touching[0]]);
        // A command older than the input age limit is not followed.
        let before = plant.joints().to_vec();
        let mut moved = before.clone();
        moved[touching[1]][0] += 0.05_f64.to_radians();
        let stale = command(&setup, &[touching[1]], &moved, true, T0);
        let later = T0 + (config.pipeline.max_input_age * 1e9) as u64 + 2 * dt;
        plant.tick(later, Some(&stale));
        assert_eq!(plant.joints(), &before[..]);
        assert_eq!(plant.rotation(), 0.0);
    }

    #[test]
    fn the_pose_measurement_comes_after_the_delay_with_the_noise() {
        let (mut config, setup) = paper();
        let (grip, _, _) = still(&mut config, &setup);
        let p = &mut config.pipeline;
        p.pose_latency = 0.1;
        p.slip = 10f64.to_radians();
        p.slip_at = 0.5;
        let dt = (1e9 / p.rate_hz) as u64;
        let every = (p.rate_hz / p.pose_rate_hz).round() as u64;
        let latency = (p.pose_latency * 1e9) as u64;
        let slip_at = T0 + (p.slip_at * 1e9) as u64;
        // Without noise: the rotation of `latency` ago, every `every` ticks.
        let mut plant = paper_plant(&setup, &grip, p);
        let mut poses = 0;
        for k in 1..=1000 {
            let t = T0 + k * dt;
            let out = plant.tick(t, None);
            assert_eq!(out.pose.is_some(), k % every == 0, "tick {k}");
            if t >= slip_at && t < slip_at + dt {
                assert_eq!(
                    plant.events(),
                    &[Event::Slipped {
                        by: p.slip,
                        to: p.slip
                    }]
                );
            }
            let Some(pose) = out.pose else { continue };
            poses += 1;
            assert_eq!(pose.captured_time_ns, t - latency);
            let [w, _, _, z] = pose.orientation;
            let measured = 2.0 * z.atan2(w);
            let then = if t - latency >= slip_at { p.slip } else { 0.0 };
            assert!(
                (measured - then).abs() < 1e-12,
                "tick {k}: {measured} vs {then}"
            );
        }
        assert_eq!(poses, 1000 / every);
        // With noise: measurements of the still object spread by the configured deviation.
        let sigma = 0.5_f64.to_radians();
        p.pose_noise = sigma;
        p.slip = 0.0;
        let mut plant = paper_plant(&setup, &grip, p);
        let errors: Vec<f64> = (1..=30_000)
            .filter_map(|k| plant.tick(T0 + k * dt, None).pose)
            .map(|pose| 2.0 * pose.orientation[3].atan2(pose.orientation[0]))
            .collect();
        let n = errors.len() as f64;
        let mean = errors.iter().sum::<f64>() / n;
        let sd = (errors.iter().map(|e| (e - mean).powi(2)).sum::<f64>() / n).sqrt();
        assert!(errors.len() >= 900, "{}", errors.len());
        assert!(mean.abs() < 4.0 * sigma / n.sqrt(), "mean {mean}");
        assert!((sd / sigma - 1.0).abs() < 0.1, "deviation {sd} for {sigma}");
    }

    #[test]
    fn a_saved_state_is_resumed() {
        let (mut config, setup) = paper();
        let (grip, touching, _) = still(&mut config, &setup);
        let surface = setup.surface().unwrap();
        let mut plant = paper_plant(&setup, &grip, &config.pipeline);
        let mut to = plant.joints().to_vec();
        to[touching[0]][0] += 0.05_f64.to_radians();
        let c = command(&setup, &[touching[0]], &to, true, T0);
        plant.tick(T0 + 1_000_000, Some(&c));
        let mut text = String::new();
        plant.save(&mut text);
        let mut resumed = Plant::new(
            &setup.hand,
            Roller::Section(surface),
            (grip.0.clone(), &[]),
            &config.pipeline,
            T0,
        );
        assert!(resumed.restore(&text));
        assert_eq!(resumed.rotation(), plant.rotation());
        assert_eq!(resumed.joints(), plant.joints());
        assert_eq!(resumed.contacts(), plant.contacts());
        // Another hand's state changes nothing.
        assert!(!resumed.restore("0.5 1 0 0.1"));
        assert_eq!(resumed.rotation(), plant.rotation());
    }

    /// A spatial hand's fingers rolling the object as its plan has them turn it: the plant
    /// commanded the Allegro's joints of each of the sphere's first rolling steps (1 deg
    /// each, about the hand's y axis) turns it by the plan's rotation, the fingertips staying
    /// on the surface; the pose it measures is that rotation about the axis.
    #[test]
    fn a_spatial_hand_rolling_as_planned_turns_the_object_as_planned() {
        let (mut config, setup) = crate::testing::allegro_sphere();
        let (grip, _, _) = still(&mut config, &setup);
        let roller = setup.roller(&config).unwrap();
        let mut plant = Plant::new(
            &setup.hand,
            roller,
            (grip.0.clone(), &grip.1),
            &config.pipeline,
            T0,
        );
        let (steps, slots) = crate::testing::spatial_rolling(&config, &setup, 10);
        let dt = (1e9 / config.pipeline.rate_hz) as u64;
        let mut now = T0;
        let mut worst = 0.0_f64;
        for (k, joints) in steps.iter().enumerate().skip(1) {
            let c = command(&setup, &slots, joints, true, now);
            for _ in 0..200 {
                now += dt;
                plant.tick(now, Some(&c));
                if slots.iter().all(|&s| plant.joints()[s] == joints[s]) {
                    break;
                }
            }
            assert!(slots.iter().all(|&s| plant.joints()[s] == joints[s]));
            worst = worst.max((plant.rotation() - (k as f64).to_radians()).abs());
            for &s in &slots {
                let f = &setup.hand.fingers[s];
                let gap = roller.gap(f, &plant.joints()[s], plant.rotation());
                assert!(gap.abs() < 0.05e-3, "finger {}: {gap} m off", f.id);
            }
        }
        assert!(
            worst < 0.02f64.to_radians(),
            "the plant turned it {} deg off the plan",
            worst.to_degrees()
        );
        assert!(plant.events().is_empty(), "{:?}", plant.events());
        // The pose measured (no noise; the object still for longer than the latency) is the
        // rotation about the plan's axis.
        let still_until = now + (config.pipeline.pose_latency * 1e9) as u64;
        let mut pose = None;
        while pose.is_none() || now <= still_until {
            now += dt;
            pose = plant.tick(now, None).pose;
        }
        let measured = roller.rotation_of(pose.unwrap().orientation);
        assert!((measured - plant.rotation()).abs() < 1e-12);
        let [_, x, y, z] = pose.unwrap().orientation;
        assert!(x.abs() < 1e-15 && z.abs() < 1e-15 && y > 0.0, "about +y");
    }
}
