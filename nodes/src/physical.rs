//! The plant in MuJoCo (`[plant] kind = "mujoco"`): the hand and object of the config as rigid
//! bodies with soft contacts and friction ([`icrflow_physics`]), stepped in real time, driven
//! by the hand commands, measured like the kinematic plant ([`crate::plant`]).
//!
//! Each tick (`pipeline.rate_hz`) MuJoCo advances by the time since the last tick (whole
//! timesteps of `plant.timestep_ms`, at most ten periods' worth when the process was late).
//! A tracking command sets every finger's joint servo targets and its fingertip force target
//! (fed forward as `J^T f` with `plant.feedforward`, the servos of the finger with the
//! largest force aiming `plant.squeeze_mm` past the surface, the others' in proportion to
//! their forces: `icrflow_physics::sim`); a hold, or a command older than `pipeline.max_input_age_ms`, keeps the
//! last targets and forces: the hand keeps its grip. The configured push of the object
//! (`pipeline.push_n`, `push_nm`) begins at the first timestep at or after `push_at_s` of
//! MuJoCo's time (an [`Event::Pushed`]). The world waits for the hand: MuJoCo
//! does not advance until the first tracking command (until then nothing holds the object
//! with a force, and under gravity it would fall out of a hand that has not yet closed).
//!
//! Measurements go out as the kinematic plant's do (encoders with `pipeline.joint_noise_deg`;
//! the object's pose `pipeline.pose_latency_ms` late, its rotation about z noisy by
//! `pipeline.pose_noise_deg`), and the truth (MuJoCo's object pose, each fingertip's contact
//! point, normal, force and slip speed) on [`topics::PLANT_TRUTH`] every tenth tick.

use std::collections::VecDeque;

use anyhow::{Result, anyhow};
use icrflow_grasp::math::{Real, UnitQuaternion, Vec3};
use icrflow_interfaces::{
    CommandMode, HandCommand, Header, JointState, Kind, MAX_FINGERS, MAX_JOINTS, ObjectPose,
    PlantEngine, PlantTruth,
};
use icrflow_physics::configured::{controls, model};
use icrflow_physics::scene::initial_joints;
use icrflow_physics::sim::Sim;
use icrflow_plan::forces::{Balance, ForceContact, ForceSolver, Load};
use icrflow_plan::hand::{Hand, wrap};
use icrflow_plan::planner::Contact;
use icrflow_scenario::{Config, PipelineSpec, Push, Setup};

use crate::noise::Noise;
use crate::plant::{Event, Output};

/// The truth is published every this many ticks (as the kinematic plant's).
const TRUTH_EVERY: u64 = 10;
/// Poses kept to measure the past from (one per tick).
const HISTORY: usize = 4000;

/// The twist of `q` about the unit `axis` (rad, in (-pi, pi]): [`icrflow_plan::rolling::twist`].
fn twist(q: &UnitQuaternion, axis: &Vec3) -> Real {
    let q = q.quaternion();
    icrflow_plan::rolling::twist([q.w, q.i, q.j, q.k], [axis.x, axis.y, axis.z])
}

/// The plant in MuJoCo: the simulation and the measurements; no I/O, no clock.
pub struct Physical<'a> {
    hand: &'a Hand,
    /// The axis the plan turns the object about (hand frame, unit): the rotation measured is
    /// the object's twist about it.
    axis: nalgebra::Unit<Vec3>,
    sim: Sim,
    joint_noise: Real,
    pose_noise: Real,
    dt: Real,
    max_age_ns: u64,
    latency_ns: u64,
    pose_every: u64,
    /// The commands are followed (MuJoCo advances) since the first tracking command.
    started: bool,
    ticks: u64,
    last_tick: u64,
    /// The object's rotation about the axis since the start (rad, unwrapped) and its last
    /// twist.
    rotation: Real,
    last_twist: Real,
    /// Per tick: its time, the object's centre and orientation then.
    history: VecDeque<(u64, Vec3, UnitQuaternion)>,
    /// Which fingers touch the object (for the contact events).
    touching: Vec<bool>,
    noise: Noise,
    /// When the last tracking command was made (ns; commands older than the input age limit
    /// are not followed).
    command_time: u64,
    events: Vec<Event>,
    /// The configured push, until it is made.
    push: Option<Push>,
    /// Since the last truth: integration steps, those with a link on the object or fingers
    /// touching, and which fingers ([`PlantTruth`]'s fields of the same names).
    window: Window,
}

/// What the plant's integration steps since the last truth saw of the hand's collisions.
#[derive(Debug, Clone, Copy, Default)]
struct Window {
    steps: u32,
    link_object_steps: u32,
    finger_touch_steps: u32,
    links_on_object: u32,
    fingers_touching: u32,
}

impl Window {
    fn add(&mut self, c: icrflow_physics::sim::Collisions) {
        self.steps += 1;
        self.link_object_steps += u32::from(c.links_on_object != 0);
        self.finger_touch_steps += u32::from(c.fingers_touching != 0);
        self.links_on_object |= c.links_on_object;
        self.fingers_touching |= c.fingers_touching;
    }
}

impl<'a> Physical<'a> {
    /// The plant of `setup`'s hand and object under `config`, the hand at `joints` (every
    /// finger's, in the hand's order: the initial grasp, [`Setup::initial_grip`]), started at
    /// `now_ns`.
    pub fn new(
        config: &Config,
        setup: &'a Setup,
        joints: &[Vec<Real>],
        now_ns: u64,
    ) -> Result<Self> {
        let p: &PipelineSpec = &config.pipeline;
        let hand = &setup.hand;
        let xml = model(config, setup)?;
        let sim = Sim::new(&xml, hand, joints, controls(config))
            .map_err(|e| anyhow!("plant.kind = \"mujoco\": {e}"))?;
        let (_, q) = sim.object_pose();
        let n = hand.fingers.len();
        let axis = nalgebra::Unit::new_normalize(config.turn.axis);
        Ok(Self {
            hand,
            axis,
            joint_noise: p.joint_noise,
            pose_noise: p.pose_noise,
            dt: 1.0 / p.rate_hz,
            max_age_ns: (p.max_input_age * 1e9) as u64,
            latency_ns: (p.pose_latency * 1e9) as u64,
            pose_every: (p.rate_hz / p.pose_rate_hz).round().max(1.0) as u64,
            started: false,
            ticks: 0,
            last_tick: now_ns,
            rotation: 0.0,
            last_twist: twist(&q, &axis),
            history: VecDeque::with_capacity(HISTORY + 1),
            touching: (0..n).map(|s| sim.contact(s).is_some()).collect(),
            sim,
            noise: Noise::new(p.seed),
            command_time: 0,
            events: Vec::with_capacity(n + 1),
            push: p.push,
            window: Window::default(),
        })
    }

    /// MuJoCo's version.
    pub fn version(&self) -> &'static str {
        self.sim.version()
    }

    /// The object's rotation about z (rad, unwrapped).
    pub fn rotation(&self) -> Real {
        self.rotation
    }

    /// The simulation.
    pub fn sim(&self) -> &Sim {
        &self.sim
    }

    /// The ticks so far.
    pub fn ticks(&self) -> u64 {
        self.ticks
    }

    /// What the last tick has to say.
    pub fn events(&self) -> &[Event] {
        &self.events
    }

    /// The state as the checkpoint keeps it: `mujoco`, the rotation and the last twist,
    /// whether the commands are followed, then MuJoCo's state ([`Sim::state`]).
    pub fn save(&self, text: &mut String) {
        use std::fmt::Write as _;
        let _ = write!(
            text,
            "mujoco {:e} {:e} {}",
            self.rotation,
            self.last_twist,
            u8::from(self.started)
        );
        for x in self.sim.state() {
            let _ = write!(text, " {x:e}");
        }
    }

    /// Resumes from a state [`Physical::save`] wrote; `false` (nothing changed) if `text` is
    /// not one of this model's.
    pub fn restore(&mut self, text: &str) -> bool {
        let mut words = text.split_whitespace();
        if words.next() != Some("mujoco") {
            return false;
        }
        let Ok(v) = words.map(str::parse).collect::<Result<Vec<Real>, _>>() else {
            return false;
        };
        if v.len() < 4 || !self.sim.set_state(&v[3..]) {
            return false;
        }
        self.rotation = v[0];
        self.last_twist = v[1];
        self.started = v[2] != 0.0;
        // A push due before the state was saved was made then (or cut short by the crash):
        // it is not made again.
        if self.push.is_some_and(|p| p.at < self.sim.time()) {
            self.push = None;
        }
        for slot in 0..self.touching.len() {
            self.touching[slot] = self.sim.contact(slot).is_some();
        }
        true
    }

    /// One tick at `now_ns` with the newest `command` if one came: the commands set, MuJoCo
    /// advanced by the time since the last tick, then the measurements.
    pub fn tick(&mut self, now_ns: u64, command: Option<&HandCommand>) -> Output {
        self.events.clear();
        self.ticks += 1;
        if let Some(c) = command.filter(|c| CommandMode::moves(c.mode)) {
            self.started = true;
            self.command_time = c.header.source_time_ns;
            if now_ns.saturating_sub(self.command_time) <= self.max_age_ns {
                self.follow(c);
            }
        }
        let elapsed = now_ns.saturating_sub(self.last_tick) as Real * 1e-9;
        self.last_tick = now_ns;
        if self.started {
            let h = self.sim.timestep();
            let span = elapsed.clamp(self.dt, 10.0 * self.dt);
            let steps = (span / h).round().max(1.0) as usize;
            for _ in 0..steps {
                if let Some(p) = self.push.filter(|p| self.sim.time() >= p.at) {
                    self.push = None;
                    self.sim
                        .push(Vec3::from(p.force), Vec3::from(p.torque), p.duration);
                    self.events.push(Event::Pushed {
                        force: p.force,
                        torque: p.torque,
                        duration: p.duration,
                        at: self.rotation,
                    });
                }
                self.sim.step();
                self.window.add(self.sim.collisions());
            }
        }
        let (_, q) = self.sim.object_pose();
        let y = twist(&q, &self.axis);
        self.rotation += wrap(y - self.last_twist);
        self.last_twist = y;
        for slot in 0..self.touching.len() {
            let on = self.sim.contact(slot).is_some();
            if on != self.touching[slot] {
                self.touching[slot] = on;
                self.events.push(Event::Contact {
                    finger: self.hand.fingers[slot].id,
                    on,
                });
            }
        }
        if self.history.len() == HISTORY {
            self.history.pop_front();
        }
        self.history
            .push_back((now_ns, self.sim.object_centre(), q));
        self.measure(now_ns)
    }

    /// Sets every commanded finger's targets and force.
    fn follow(&mut self, c: &HandCommand) {
        for (slot, f) in self.hand.fingers.iter().enumerate() {
            let Some(k) =
                (0..(c.finger_count as usize).min(MAX_FINGERS)).find(|&k| c.finger_ids[k] == f.id)
            else {
                continue;
            };
            let mut q = [0.0; MAX_JOINTS];
            for (j, joint) in f.joints.iter().enumerate().take(MAX_JOINTS) {
                q[j] = c.joint_targets[k][j].clamp(joint.lower, joint.upper);
            }
            self.sim
                .command(slot, &q[..f.dof().min(MAX_JOINTS)], Vec3::from(c.forces[k]));
        }
    }

    fn measure(&mut self, t: u64) -> Output {
        let hand = self.hand;
        let mut joints = JointState {
            finger_count: hand.fingers.len().min(MAX_FINGERS) as u32,
            ..Default::default()
        };
        let mut q = [0.0; MAX_JOINTS];
        for (slot, f) in hand.fingers.iter().enumerate().take(MAX_FINGERS) {
            joints.finger_ids[slot] = f.id;
            let dof = f.dof().min(MAX_JOINTS);
            joints.joint_counts[slot] = dof as u32;
            self.sim.joints(slot, &mut q[..dof]);
            for (out, a) in joints.positions[slot].iter_mut().zip(&q[..dof]) {
                *out = a + self.noise.gauss(self.joint_noise);
            }
        }
        let truth = self.ticks.is_multiple_of(TRUTH_EVERY).then(|| {
            let (_, orientation) = self.sim.object_pose();
            let o = orientation.quaternion();
            let w = std::mem::take(&mut self.window);
            let mut truth = PlantTruth {
                position: self.sim.object_centre().into(),
                orientation: [o.w, o.i, o.j, o.k],
                rotation: self.rotation,
                finger_count: hand.fingers.len().min(MAX_FINGERS) as u32,
                engine: PlantEngine::Mujoco as u32,
                physics_steps: w.steps,
                link_object_steps: w.link_object_steps,
                finger_touch_steps: w.finger_touch_steps,
                links_on_object: w.links_on_object,
                fingers_touching: w.fingers_touching,
                ..Default::default()
            };
            for (slot, f) in hand.fingers.iter().enumerate().take(MAX_FINGERS) {
                truth.finger_ids[slot] = f.id;
                if let Some(c) = self.sim.contact(slot) {
                    truth.in_contact[slot] = 1;
                    truth.contact_points[slot] = c.point.into();
                    truth.contact_normals[slot] = c.normal.into();
                    truth.contact_forces[slot] = c.force.into();
                    truth.slip_speeds[slot] = c.slip_speed;
                }
            }
            truth
        });
        let pose = self.ticks.is_multiple_of(self.pose_every).then(|| {
            let captured = t.saturating_sub(self.latency_ns);
            let (centre, q) = self
                .history
                .iter()
                .rev()
                .find(|(when, ..)| *when <= captured)
                .or(self.history.front())
                .map(|(_, c, q)| (*c, *q))
                .unwrap_or_else(|| (self.sim.object_centre(), self.sim.object_pose().1));
            let noise =
                UnitQuaternion::from_axis_angle(&self.axis, self.noise.gauss(self.pose_noise));
            let m = (noise * q).into_inner();
            ObjectPose {
                captured_time_ns: captured,
                position: centre.into(),
                orientation: [m.w, m.i, m.j, m.k],
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

/// A tracking command made at `at_ns` that holds the hand still in the grasp `contacts`: every
/// finger's joints at that grasp (where [`Physical::new`] starts them) and forces that balance
/// the object's weight inside the friction cones narrowed by `plant.friction_margin`, each
/// pressing at least `pipeline.min_normal_force` (for tests and benchmarks of the plant).
pub fn holding_command(
    config: &Config,
    setup: &Setup,
    contacts: &[Contact],
    at_ns: u64,
) -> Result<HandCommand> {
    let cands = setup.problem.candidates();
    let points: Vec<ForceContact> = contacts
        .iter()
        .map(|c| ForceContact {
            point: cands.points[c.candidate] - setup.object.centre_of_mass,
            normal: cands.normals[c.candidate],
        })
        .collect();
    let load = Load {
        force: Vec3::from(config.plant.weight(setup.object.volume)),
        ..Load::none()
    };
    let mut forces = Vec::new();
    let found = ForceSolver::new().solve(
        &points,
        &load,
        config.grasp.model.mu() * (1.0 - config.plant.friction_margin),
        config.pipeline.min_normal_force,
        &mut forces,
    )?;
    if !matches!(found, Balance::Balanced(())) {
        return Err(anyhow!("the grasp cannot hold the object: {found}"));
    }
    let mut cmd = HandCommand {
        header: Header::new(Kind::HandCommand, 1, 0, 0),
        mode: CommandMode::Track as u32,
        finger_count: setup.hand.fingers.len() as u32,
        ..Default::default()
    };
    cmd.header.source_time_ns = at_ns;
    let joints = initial_joints(&setup.hand, contacts);
    for (slot, f) in setup.hand.fingers.iter().enumerate().take(MAX_FINGERS) {
        cmd.finger_ids[slot] = f.id;
        let dof = f.dof().min(MAX_JOINTS);
        cmd.joint_targets[slot][..dof].copy_from_slice(&joints[slot][..dof]);
        if let Some(i) = contacts.iter().position(|c| c.finger == f.id) {
            cmd.forces[slot] = forces[i].into();
        }
    }
    Ok(cmd)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::paper;

    const T0: u64 = 1_000_000_000_000;

    /// Holds the paper sphere in its initial grasp for `seconds`: the object's drift (m) and
    /// the largest friction use seen.
    fn hold(config: &Config, setup: &Setup, seconds: Real) -> (Real, Real, usize) {
        let contacts = setup.scenario(config).start().unwrap().0;
        let joints = setup.initial_grip(config).unwrap().0;
        let mut plant = Physical::new(config, setup, &joints, T0).unwrap();
        let start = plant.sim().object_centre();
        let dt = (1e9 / config.pipeline.rate_hz) as u64;
        let mut use_max: Real = 0.0;
        let mut touching = 0;
        let ticks = (seconds * config.pipeline.rate_hz) as u64;
        for k in 1..=ticks {
            let t = T0 + k * dt;
            let cmd = holding_command(config, setup, &contacts, t).unwrap();
            plant.tick(t, Some(&cmd));
            touching = 0;
            for slot in 0..setup.hand.fingers.len() {
                if let Some(c) = plant.sim().contact(slot) {
                    touching += 1;
                    if k > ticks / 2 {
                        use_max = use_max
                            .max(c.tangential_force / (config.grasp.model.mu() * c.normal_force));
                    }
                }
            }
        }
        (
            (plant.sim().object_centre() - start).norm(),
            use_max,
            touching,
        )
    }

    #[test]
    fn the_paper_grasp_holds_the_sphere_still_with_its_balancing_forces() {
        let (mut config, setup) = paper();
        config.plant.kind = icrflow_scenario::PlantKind::Mujoco;
        config.plant.friction_margin = 0.2;
        let (drift, friction_use, touching) = hold(&config, &setup, 1.0);
        assert_eq!(touching, 3);
        assert!(drift < 1e-3, "drift {drift}");
        assert!(friction_use < 1.0, "friction use {friction_use}");
    }

    #[test]
    fn under_gravity_the_forces_carry_the_weight() {
        let (mut config, setup) = paper();
        config.plant.kind = icrflow_scenario::PlantKind::Mujoco;
        config.plant.friction_margin = 0.2;
        config.plant.gravity = [0.0, 0.0, -9.81];
        let (drift, friction_use, touching) = hold(&config, &setup, 1.0);
        assert_eq!(touching, 3);
        assert!(drift < 2e-3, "drift {drift}");
        assert!(friction_use < 1.0, "friction use {friction_use}");
        // Without force targets or squeeze the servos hold the fingertips on the surface, which
        // presses nothing: the object falls.
        config.plant.feedforward = false;
        config.plant.squeeze = 0.0;
        let (drift, _, _) = hold(&config, &setup, 1.0);
        assert!(drift > 0.02, "drift {drift}");
    }
}
