//! The state estimator (`icrflow-estimator`): fuses the joint encoders, through forward
//! kinematics and the rolling kinematics ([`icrflow_plan::rolling`]), with the delayed object-pose
//! measurements into the object's rotation and the fingers' contact state.
//!
//! [`Estimator`] is the pure step (measurements and their times in, the grasp state out);
//! [`run`] is the node around it (the bus, health, the checkpoint).
//!
//! **Rotation.** Between measurements the rotation follows the rolling of the fingertips that
//! press on the object: in contact, and given a force by the newest moving hand command (the
//! contact schedule, as a legged robot's estimator trusts the kinematics of the legs in stance
//! only; the plant's rule too). A finger without a force does not roll the object, though its
//! fingertip may stay within [`RELEASE`] of the surface for a few samples on its way off, and
//! that way runs partly along the surface: counted, the four switches in a row of the Allegro
//! ellipsoid's plan at 85 degrees put the estimate 1.2-3.4 degrees ahead of the kinematic
//! plant's object, standing still (a finger let go of; one that touched while the hand held
//! below the margin and left without ever being pressed). Before the first command every
//! finger in contact counts. A pose
//! measurement of the scene captured at time `t` (it arrives `pipeline.pose_latency_ms`
//! later) is compared with the estimate *as it was at `t`, corrected by everything the filter
//! has learnt since*: the innovation `nu = measured - (theta(t) + C - C(t))`, `C` the sum of
//! the corrections applied so far. A fraction [`GAIN`] of it corrects the estimate now (and
//! `C`); the kinematics since `t` are kept, so the delay is compensated (a complementary filter
//! with replay: the rolling increments do not depend on the rotation on a circular section,
//! so replaying them from the corrected state at `t` moves the estimate by the same
//! correction). Each measurement's innovation is thus measured against the corrections of the
//! measurements before it, however many of them were still in flight when it was captured:
//! the error decays by `1 - GAIN` per measurement at any latency. (Comparing with the
//! uncorrected `theta(t)` instead counted each error once per measurement in flight, an
//! effective gain of `GAIN (1 + latency x rate)`: unstable above ~100 ms at 30 Hz.)
//!
//! **Doubt.** The grasp state carries the estimate's residuals, for the hand command node's
//! gate: the pose innovation smoothed over the last measurements (weight
//! [`INNOVATION_WEIGHT`]: the measurements' noise averages out, a bias stays) and the contact
//! consistency (the root-mean-square distance of the fingertips in contact from the object's
//! surface at the estimated pose).
//!
//! **Contacts.** A finger touches when its fingertip centre (from the encoders) is within
//! [`TOUCH`] of the object's surface offset by the fingertip radius, for [`SETTLE`] samples;
//! it leaves beyond [`RELEASE`]. Its contact point is the surface's point nearest to the
//! fingertip centre (along the normal): a planar hand's snapped to the nearest section
//! sample, a spatial hand's where it is, with its candidate (the facet it lies on, or the
//! nearest).
//!
//! **Planar and spatial hands.** What the fingertips roll on is the plant's
//! ([`icrflow_plan::rolling::Roller`]): a planar hand's section of the object, turning about
//! the hand's z axis, or a spatial hand's object turning about its plan's axis (the rotation
//! of the rolling by least squares of the fingers' rolling without slipping, the pose
//! measurement's rotation its twist about the axis). The object's centre moving, which the
//! pose measurements' positions say, is taken into account in the hand's plane for a planar
//! hand; a spatial hand's object is taken as held at its centre (the kinematic plant's is). The grasp state also
//! carries the joint angles it was estimated from (the hand's state, for the planner's way
//! points and a restarted command node).

use std::collections::VecDeque;
use std::fmt::Write as _;

use anyhow::Result;
use icrflow_grasp::math::Vec3;
use icrflow_grasp::quality::GraspProblem;
use icrflow_interfaces::{
    CommandMode, FingerContact, GraspState, HandCommand, Header, JointState, Kind, MAX_FINGERS,
    MAX_JOINTS, topics,
};
use icrflow_plan::hand::{Finger, Hand, wrap};

use crate::Context;
use icrflow_plan::rolling::{Roller, Tip, tip};
use icrflow_runtime::checkpoint::Checkpoint;
use icrflow_runtime::event::serve;
use icrflow_runtime::health::{Health, Sequence};

/// Weight of a pose measurement's correction.
pub const GAIN: f64 = 0.3;
/// Weight of the newest innovation in the smoothed one the grasp state carries
/// ([`GraspState::pose_innovation`]): its noise is `sqrt(w / (2 - w))` = 0.33 of the
/// measurements' for 0.2.
pub const INNOVATION_WEIGHT: f64 = 0.2;
/// A fingertip comes into contact when its centre is within this of the contact distance
/// (m, encoder noise included) ...
pub const TOUCH: f64 = 0.6e-3;
/// ... for this many consecutive samples (a fingertip passing by on its way is not a contact) ...
pub const SETTLE: u32 = 10;
/// ... and leaves contact beyond [`RELEASE`] (m): hysteresis against noise.
pub use icrflow_plan::rolling::RELEASE;
/// A fingertip in contact counts for the rolling only if its distance from the object's surface
/// changed less than this between two samples (m): one arriving or leaving does not roll it.
pub const RADIAL: f64 = 0.2e-3;
/// Estimates kept to compare delayed measurements with (one per joint measurement): 4 s at
/// 1 kHz, 2 s at the highest `pipeline.rate_hz`, more than the longest pose latency allowed.
pub const HISTORY: usize = 4000;

/// Why a measurement was not used.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum Refusal {
    /// A pose measurement whose rotation is not finite.
    #[error("object pose not finite")]
    PoseNotFinite,
    /// A joint angle that is not finite.
    #[error("finger {finger}: joint angle not finite")]
    JointNotFinite {
        /// The finger.
        finger: u32,
    },
}

/// A finger's contact changed: `(finger, in contact now, fingertip gap to the surface (m))`.
pub type Transition = (u32, bool, f64);

/// A fingertip as a sample has it: a planar hand's in its plane about the object's moved
/// centre, a spatial hand's by its joints.
#[derive(Debug, Clone, Copy)]
enum Fingertip {
    Planar(Tip),
    Space([f64; MAX_JOINTS]),
}

/// The estimator's state and step: no I/O, no clock.
pub struct Estimator<'a> {
    hand: &'a Hand,
    roller: Roller<'a>,
    problem: &'a GraspProblem,
    /// The estimated rotation (rad).
    theta: f64,
    /// The corrections applied so far (rad): [`Estimator::history`] holds `theta - correction`.
    correction: f64,
    /// The smoothed pose innovation (rad).
    innovation: f64,
    /// Capture time of the newest pose measurement fused (0: none).
    pose_captured: u64,
    /// Per joint measurement: its time and the estimate then, less the corrections by then.
    history: VecDeque<(u64, f64)>,
    contact: Vec<bool>,
    streak: Vec<u32>,
    previous: Vec<Option<(Fingertip, f64)>>,
    tips: Vec<Option<(Fingertip, bool)>>,
    transitions: Vec<Transition>,
    q: Vec<f64>,
    /// How far the object's centre has moved (m; a planar hand's in the hand's plane), from
    /// the pose measurements' positions: the fingertips are taken about the moved centre.
    moved: [f64; 3],
    /// Per finger slot, whether the newest moving hand command presses it (`None` before the
    /// first).
    pressing: Option<[bool; MAX_FINGERS]>,
}

impl<'a> Estimator<'a> {
    /// An estimator of `hand` holding the object `roller` rolls on, whose contacts are snapped
    /// to `problem`'s candidates, starting at rotation `theta` (rad), every finger out of
    /// contact.
    pub fn new(hand: &'a Hand, roller: Roller<'a>, problem: &'a GraspProblem, theta: f64) -> Self {
        let n = hand.fingers.len();
        Self {
            hand,
            roller,
            problem,
            theta,
            correction: 0.0,
            innovation: 0.0,
            pose_captured: 0,
            history: VecDeque::with_capacity(HISTORY),
            contact: vec![false; n],
            streak: vec![0; n],
            previous: vec![None; n],
            tips: Vec::with_capacity(n),
            transitions: Vec::with_capacity(n),
            q: Vec::with_capacity(8),
            moved: [0.0; 3],
            pressing: None,
        }
    }

    /// The estimated rotation (rad).
    pub fn rotation(&self) -> f64 {
        self.theta
    }

    /// The smoothed pose innovation (rad).
    pub fn innovation(&self) -> f64 {
        self.innovation
    }

    /// The object's rotation that orientation `q` (`[w, x, y, z]`, a pose measurement's) has
    /// about the axis the object turns about (rad).
    pub fn rotation_of(&self, q: [f64; 4]) -> f64 {
        self.roller.rotation_of(q)
    }

    /// Finger `f`'s fingertip at joints `q`.
    fn fingertip(&self, f: &Finger, q: &[f64]) -> Fingertip {
        match self.roller {
            Roller::Section(_) => {
                Fingertip::Planar(tip(f, q).from_moved([self.moved[0], self.moved[1]]))
            }
            Roller::Space(_) => {
                let mut joints = [0.0; MAX_JOINTS];
                let n = q.len().min(MAX_JOINTS);
                joints[..n].copy_from_slice(&q[..n]);
                Fingertip::Space(joints)
            }
        }
    }

    /// Where fingertip `t` of finger `f` touches the object at the estimated rotation: its
    /// candidate, the contact's point and normal (body frame), and the fingertip's gap (m). A
    /// planar hand's contact is its section sample (the planar plan's margin holds there); a
    /// spatial hand's is where the fingertip touches the surface, its candidate the facet it
    /// lies on (a mesh) or the nearest (the spatial plan keeps its margin at the exact
    /// contacts).
    fn touch(&self, f: &Finger, t: &Fingertip) -> (usize, Vec3, Vec3, f64) {
        let candidates = self.problem.candidates();
        match (self.roller, t) {
            (Roller::Section(s), Fingertip::Planar(t)) => {
                let c = s.contact_of(t, f, self.theta);
                let i = c.sample;
                (i, candidates.points[i], candidates.normals[i], c.gap)
            }
            (Roller::Space(s), Fingertip::Space(q)) => {
                let c = s.contact_of(f, &q[..f.dof()], self.theta);
                let candidate =
                    icrflow_plan::spatial::candidate_at(s.surface, self.problem, &c.point);
                (candidate, c.point, c.normal, c.gap)
            }
            _ => unreachable!("a fingertip is of its roller's kind"),
        }
    }

    /// Fingertip `t`'s gap to the object at the estimated rotation (m).
    fn gap(&self, f: &Finger, t: &Fingertip) -> f64 {
        match (self.roller, t) {
            (Roller::Section(s), Fingertip::Planar(t)) => s.contact_of(t, f, self.theta).gap,
            (roller, Fingertip::Space(q)) => roller.gap(f, &q[..f.dof()], self.theta),
            _ => unreachable!("a fingertip is of its roller's kind"),
        }
    }

    /// What finger `f` rolling from `a` to `b` turns the object by, as `(numerator, weight)`
    /// ([`Roller::turn`]).
    fn turn(&self, f: &Finger, a: &Fingertip, b: &Fingertip) -> (f64, f64) {
        match (self.roller, a, b) {
            (Roller::Section(s), Fingertip::Planar(a), Fingertip::Planar(b)) => {
                (s.rotation(a, b, f, self.theta), 1.0)
            }
            (roller, Fingertip::Space(a), Fingertip::Space(b)) => {
                roller.turn(f, &a[..f.dof()], &b[..f.dof()], self.theta)
            }
            _ => unreachable!("a fingertip is of its roller's kind"),
        }
    }

    /// The contacts that changed in the last [`Estimator::on_joints`].
    pub fn transitions(&self) -> &[Transition] {
        &self.transitions
    }

    /// A hand command: the fingers it presses on the object, the only ones that roll it from
    /// now on. A hold moves nothing and changes nothing.
    pub fn on_command(&mut self, c: &HandCommand) {
        if !CommandMode::moves(c.mode) {
            return;
        }
        let mut pressing = [false; MAX_FINGERS];
        for (p, f) in pressing.iter_mut().zip(&self.hand.fingers) {
            *p = c.presses(f.id);
        }
        self.pressing = Some(pressing);
    }

    /// Whether the finger of `slot` rolls the object: pressed by the newest moving command
    /// (every finger before the first).
    fn presses(&self, slot: usize) -> bool {
        self.pressing
            .is_none_or(|p| p.get(slot).copied().unwrap_or(false))
    }

    /// Fuses an object-pose measurement of rotation `measured` (rad) of the scene captured at
    /// `captured_ns`; returns its innovation (rad).
    pub fn on_pose(&mut self, measured: f64, captured_ns: u64) -> Result<f64, Refusal> {
        if !measured.is_finite() {
            return Err(Refusal::PoseNotFinite);
        }
        // The estimate at the capture time (the newest one not after it; before the oldest
        // kept, the oldest), corrected by what was learnt since.
        let at = self.history.partition_point(|(t, _)| *t <= captured_ns);
        let then = match at
            .checked_sub(1)
            .or((!self.history.is_empty()).then_some(0))
        {
            Some(i) => self.history[i].1 + self.correction,
            None => self.theta,
        };
        let nu = wrap(measured - then);
        self.theta += GAIN * nu;
        self.correction += GAIN * nu;
        self.innovation += INNOVATION_WEIGHT * (nu - self.innovation);
        self.pose_captured = self.pose_captured.max(captured_ns);
        Ok(nu)
    }

    /// Fuses a pose measurement's position: the object's centre moved by `moved` (m, hand
    /// frame) from where it was first measured (a kinematic plant's object never moves; a
    /// MuJoCo plant's is pushed about by the fingers by a millimetre or so). A planar hand
    /// takes its part in the hand's plane; a spatial hand all of it (its object is taken to
    /// turn about the moved centre). Smoothed with [`GAIN`] like the rotation, without the
    /// delay's compensation (the centre moves slowly).
    pub fn on_position(&mut self, moved: [f64; 3]) -> Result<(), Refusal> {
        if !moved.iter().all(|x| x.is_finite()) {
            return Err(Refusal::PoseNotFinite);
        }
        let spatial = matches!(self.roller, Roller::Space(_));
        for (k, (m, x)) in self.moved.iter_mut().zip(moved).enumerate() {
            if k < 2 || spatial {
                *m += GAIN * (x - *m);
            }
        }
        if let Roller::Space(t) = &mut self.roller {
            t.held = Vec3::from(self.moved);
        }
        Ok(())
    }

    /// The grasp state of joint measurement `m`, with `header`: the fingers' contacts, the
    /// rotation rolled on by the fingers in contact, and the residuals.
    pub fn on_joints(&mut self, m: &JointState, header: Header) -> Result<GraspState, Refusal> {
        let hand = self.hand;
        let mut g = GraspState {
            header,
            finger_count: hand.fingers.len().min(MAX_FINGERS) as u32,
            ..Default::default()
        };
        self.transitions.clear();
        self.tips.clear();
        let (mut turn, mut weight) = (0.0, 0.0);
        // Checked first: a refused measurement changes nothing.
        for f in hand.fingers.iter().take(MAX_FINGERS) {
            if let Some(k) = m.slot_of(f.id)
                && m.positions[k][..f.dof()].iter().any(|x| !x.is_finite())
            {
                return Err(Refusal::JointNotFinite { finger: f.id });
            }
        }
        for (slot, f) in hand.fingers.iter().enumerate().take(MAX_FINGERS) {
            let Some(k) = m.slot_of(f.id) else {
                self.tips.push(None);
                continue;
            };
            self.q.clear();
            self.q.extend_from_slice(&m.positions[k][..f.dof()]);
            g.joints[slot][..self.q.len()].copy_from_slice(&self.q);
            let t = self.fingertip(f, &self.q);
            let was = self.contact[slot];
            let gap = self.gap(f, &t);
            self.streak[slot] = if gap.abs() <= TOUCH {
                self.streak[slot].saturating_add(1)
            } else {
                0
            };
            let on = if was {
                gap.abs() <= RELEASE
            } else {
                self.streak[slot] >= SETTLE
            };
            if on != was {
                self.transitions.push((f.id, on, gap));
            }
            self.contact[slot] = on;
            if let Some((before, before_gap)) = self.previous[slot]
                && was
                && on
                && self.presses(slot)
                && (gap - before_gap).abs() < RADIAL
            {
                let (by, w) = self.turn(f, &before, &t);
                turn += by;
                weight += w;
            }
            self.tips.push(Some((t, on)));
            self.previous[slot] = Some((t, gap));
        }
        if weight > 0.0 {
            self.theta += turn / weight;
        }
        let (mut residual, mut touching) = (0.0, 0);
        for (slot, f) in hand.fingers.iter().enumerate().take(MAX_FINGERS) {
            let c = &mut g.fingers[slot];
            c.finger = f.id;
            let Some((t, true)) = self.tips[slot] else {
                continue;
            };
            let (index, p, n, gap) = self.touch(f, &t);
            *c = FingerContact {
                finger: f.id,
                in_contact: 1,
                candidate: index as u32,
                reserved: 0,
                point: [p.x, p.y, p.z],
                normal: [n.x, n.y, n.z],
                residual: gap,
            };
            residual += gap * gap;
            touching += 1;
        }
        g.rotation = self.theta;
        // The object's centre of mass, at the hand frame's origin at the start, moved as the
        // pose measurements say.
        g.position = self.moved;
        g.orientation = self.roller.orientation(self.theta);
        g.residual = if touching > 0 {
            (residual / touching as f64).sqrt()
        } else {
            0.0
        };
        g.pose_innovation = self.innovation;
        g.pose_captured_ns = self.pose_captured;
        if self.history.len() == HISTORY {
            self.history.pop_front();
        }
        self.history
            .push_back((m.header.source_time_ns, self.theta - self.correction));
        Ok(g)
    }
}

/// Runs the estimator node.
pub fn run(ctx: &Context) -> Result<()> {
    let setup = &ctx.scenario.setup;
    let roller = setup.roller(&ctx.scenario.config)?;
    let joints = ctx.bus.subscriber(topics::JOINT_STATE)?;
    let poses = ctx.bus.subscriber(topics::OBJECT_POSE)?;
    // Which fingers press (the contact schedule): read when a joint measurement comes.
    let commands = ctx.bus.subscriber(topics::HAND_COMMAND)?;
    let out = ctx.bus.publisher(topics::GRASP_STATE)?;
    let mut health = Health::new(ctx)?;
    let mut seq = Sequence::default();
    let checkpoint = ctx.bus.config().root.join("estimator.state");
    // The checkpoint: the rotation, then where the object's centre was first measured (the
    // reference of its motion, which a restart must keep: the command node holds the object
    // against that motion).
    let saved_text = std::fs::read_to_string(&checkpoint).unwrap_or_default();
    let mut words = saved_text
        .split_whitespace()
        .map(|w| w.parse::<f64>().ok().filter(|x| x.is_finite()));
    let theta: f64 = words.next().flatten().unwrap_or(0.0);
    let mut estimator = Estimator::new(&setup.hand, roller, &setup.problem, theta);
    let (mut last_joint_seq, mut last_pose_seq) = (0, 0);
    // Where the object's centre was measured first: its motion is taken from there.
    let mut first_position: Option<[f64; 3]> = match (
        words.next().flatten(),
        words.next().flatten(),
        words.next().flatten(),
    ) {
        (Some(x), Some(y), z) => Some([x, y, z.unwrap_or(0.0)]),
        _ => None,
    };
    let log_contacts = ctx.launch.log.contacts;
    let saved = Checkpoint::new(checkpoint)?;

    serve(ctx, &[joints.listener(), poses.listener()], None, |_| {
        health.tick()?;
        if let Some(m) = poses.latest()?
            && health.accept(
                "object pose",
                &m.header,
                Kind::ObjectPose,
                &mut last_pose_seq,
            )
        {
            let start = *first_position.get_or_insert(m.position);
            let moved = [0, 1, 2].map(|k| m.position[k] - start[k]);
            match estimator
                .on_pose(estimator.rotation_of(m.orientation), m.captured_time_ns)
                .and_then(|_| estimator.on_position(moved))
            {
                Ok(()) => health.processed += 1,
                Err(why) => health.refuse(why),
            }
        }
        // Every command since the last wake-up, in order (a tracking one followed by a hold
        // still says which fingers press); any command's: a restarted command node numbers
        // its commands from 1 again.
        commands.drain(|c| match c.header.check(Kind::HandCommand) {
            Ok(()) => estimator.on_command(c),
            Err(e) => health.refuse(format_args!("hand command: {e}")),
        })?;
        let Some(m) = joints.latest()? else {
            return Ok(());
        };
        let received = icrflow_runtime::health::now();
        if !health.accept(
            "joint state",
            &m.header,
            Kind::JointState,
            &mut last_joint_seq,
        ) {
            return Ok(());
        }
        health.processed += 1;
        let header = Header::after(Kind::GraspState, seq.advance(), &m.header, received);
        let g = match estimator.on_joints(&m, header) {
            Ok(g) => g,
            Err(why) => {
                health.refuse(why);
                return Ok(());
            }
        };
        if log_contacts {
            // Transitions only: a line per touch or release.
            for (finger, on, gap) in estimator.transitions() {
                eprintln!(
                    "icrflow-estimator: finger {finger} {} (fingertip {:+.2} mm from the surface)",
                    if *on { "touches" } else { "released" },
                    gap * 1e3
                );
            }
        }
        out.publish(g)?;
        if last_joint_seq.is_multiple_of(10) {
            let theta = estimator.rotation();
            saved.store(|text| {
                let _ = write!(text, "{theta:e}");
                if let Some([x, y, z]) = first_position {
                    let _ = write!(text, " {x:e} {y:e} {z:e}");
                }
            });
        }
        Ok(())
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::noise::Noise;
    use crate::testing::paper;
    use icrflow_scenario::{Config, Setup};

    /// The hand of the paper's initial grasp, as its encoders read it (with noise).
    fn measurement(setup: &Setup, q: &[Vec<f64>], t: u64, noise: &mut Noise) -> JointState {
        let mut m = JointState {
            header: Header::new(Kind::JointState, t / 1000 + 1, 0, 0),
            finger_count: setup.hand.fingers.len() as u32,
            ..Default::default()
        };
        m.header.source_time_ns = t;
        for (slot, f) in setup.hand.fingers.iter().enumerate() {
            m.finger_ids[slot] = f.id;
            m.joint_counts[slot] = f.dof() as u32;
            for (j, a) in q[slot].iter().enumerate() {
                m.positions[slot][j] = a + noise.gauss(0.02_f64.to_radians());
            }
        }
        m
    }

    /// What [`track`] saw.
    struct Tracked {
        /// The largest estimate error over the last second (rad).
        worst: f64,
        /// The largest smoothed innovation (rad).
        peak: f64,
        /// The last grasp state.
        last: GraspState,
    }

    /// Feeds the estimator, from `from_ms` to `to_ms`, 1 kHz joint measurements of a still
    /// hand and 30 Hz pose measurements of rotation `truth(t)` captured `latency_ms` before
    /// they arrive, with noise `sigma`.
    #[allow(clippy::too_many_arguments)]
    fn track(
        estimator: &mut Estimator<'_>,
        setup: &Setup,
        q: &[Vec<f64>],
        latency_ms: u64,
        sigma: f64,
        (from_ms, to_ms): (u64, u64),
        truth: impl Fn(u64) -> f64,
    ) -> Tracked {
        let mut noise = Noise::new(7 + from_ms);
        let (mut worst, mut peak) = (0.0_f64, 0.0_f64);
        let mut last = GraspState::default();
        for ms in from_ms + 1..=to_ms {
            let t = ms * 1_000_000;
            if ms % 33 == 0 && ms > latency_ms {
                let captured = t - latency_ms * 1_000_000;
                estimator
                    .on_pose(truth(captured) + noise.gauss(sigma), captured)
                    .unwrap();
                peak = peak.max(estimator.innovation().abs());
            }
            let m = measurement(setup, q, t, &mut noise);
            last = estimator
                .on_joints(&m, Header::new(Kind::GraspState, ms, 0, 0))
                .unwrap();
            if ms + 1000 > to_ms {
                worst = worst.max((last.rotation - truth(t)).abs());
            }
        }
        Tracked { worst, peak, last }
    }

    fn initial_joints(config: &Config, setup: &Setup) -> Vec<Vec<f64>> {
        let (contacts, _) = setup.scenario(config).start().unwrap();
        crate::plant::initial_joints(&setup.hand, &contacts)
    }

    #[test]
    fn the_estimate_converges_from_a_wrong_start_at_any_pose_latency() {
        let (config, setup) = paper();
        let surface = setup.surface().unwrap();
        let q = initial_joints(&config, &setup);
        let sigma = 0.2_f64.to_radians();
        for latency in [0, 30, 100, 200, 300, 500] {
            // 10 degrees off at the start; the object still at 0.
            let mut e = Estimator::new(
                &setup.hand,
                Roller::Section(surface),
                &setup.problem,
                10f64.to_radians(),
            );
            let Tracked { worst, last: g, .. } =
                track(&mut e, &setup, &q, latency, sigma, (0, 4000), |_| 0.0);
            assert!(
                worst < 3.0 * sigma,
                "latency {latency} ms: the estimate stays {:.3} deg off",
                worst.to_degrees()
            );
            // Converged: the smoothed innovation is of the order of the noise, and the
            // fingers of the initial grasp are in contact.
            assert!(
                g.pose_innovation.abs() < 3.0 * sigma,
                "latency {latency} ms: innovation {:.3} deg",
                g.pose_innovation.to_degrees()
            );
            let touching = g.fingers.iter().filter(|f| f.in_contact == 1).count();
            assert_eq!(touching, 3, "latency {latency} ms");
            assert!(g.residual < 0.2e-3, "residual {} m", g.residual);
            assert!(g.pose_captured_ns > 0);
        }
    }

    #[test]
    fn a_jump_of_the_object_raises_the_innovation_until_the_estimate_has_followed() {
        let (config, setup) = paper();
        let surface = setup.surface().unwrap();
        let q = initial_joints(&config, &setup);
        let mut e = Estimator::new(&setup.hand, Roller::Section(surface), &setup.problem, 0.0);
        let slip = 12f64.to_radians();
        // The object turns by 12 degrees at 2 s (a slip), seen 200 ms later.
        let truth = |t: u64| if t >= 2_000_000_000 { slip } else { 0.0 };
        let before = track(&mut e, &setup, &q, 200, 0.0, (0, 2000), truth);
        // (Only the encoders' noise rolls the estimate a little.)
        assert!(
            before.peak < 0.1f64.to_radians(),
            "{}",
            before.peak.to_degrees()
        );
        // The measurements after the slip: the innovation goes past 3 degrees, the estimate
        // follows the object (to what the encoders' noise leaves), and the innovation falls
        // back.
        let after = track(&mut e, &setup, &q, 200, 0.0, (2000, 6000), truth);
        assert!(
            after.peak > 3f64.to_radians(),
            "{}",
            after.peak.to_degrees()
        );
        assert!(
            after.worst < 0.3f64.to_radians(),
            "{}",
            after.worst.to_degrees()
        );
        assert!(after.last.pose_innovation.abs() < 0.3f64.to_radians());
    }

    #[test]
    fn a_non_finite_measurement_is_refused_and_changes_nothing() {
        let (config, setup) = paper();
        let surface = setup.surface().unwrap();
        let q = initial_joints(&config, &setup);
        let mut e = Estimator::new(&setup.hand, Roller::Section(surface), &setup.problem, 0.5);
        assert_eq!(e.on_pose(f64::NAN, 1), Err(Refusal::PoseNotFinite));
        let mut m = measurement(&setup, &q, 1_000_000, &mut Noise::new(1));
        m.positions[1][2] = f64::INFINITY;
        let finger = setup.hand.fingers[1].id;
        assert_eq!(
            e.on_joints(&m, Header::default()),
            Err(Refusal::JointNotFinite { finger })
        );
        assert_eq!(e.rotation(), 0.5);
        assert_eq!(e.innovation(), 0.0);
    }

    /// A spatial hand: the Allegro rolls the sphere through its plan's first 10 degrees on
    /// the kinematic plant (encoder noise and pose measurements as configured); the estimate
    /// follows the plant's rotation about the plan's axis, by the rolling alone as well as
    /// with the poses, and its contacts are the fingers the plant has touching, each at the
    /// candidate nearest its true contact.
    #[test]
    fn a_spatial_hand_s_rolling_is_estimated_about_the_plan_s_axis() {
        let (config, setup) = crate::testing::allegro_sphere();
        let roller = setup.roller(&config).unwrap();
        let (steps, slots) = crate::testing::spatial_rolling(&config, &setup, 10);
        for with_poses in [false, true] {
            let t0 = 1_000_000_000_000;
            let mut plant = plant_at_grip(&config, &setup, t0);
            let mut e = Estimator::new(&setup.hand, roller, &setup.problem, 0.0);
            let dt = (1e9 / config.pipeline.rate_hz) as u64;
            let mut now = t0;
            let mut last = GraspState::default();
            // The first steps' joints again and again (the hand settles on the object), then
            // each step's, 300 ticks each.
            let schedule = std::iter::repeat_n(&steps[0], 2).chain(steps.iter().skip(1));
            let mut error = 0.0;
            for (k, joints) in schedule.enumerate() {
                let mut c = crate::testing::command(&setup, &slots, joints, true, now);
                for tick in 0..300 {
                    now += dt;
                    c.header.source_time_ns = now;
                    let out = plant.tick(now, Some(&c));
                    if with_poses && let Some(p) = out.pose {
                        e.on_pose(e.rotation_of(p.orientation), p.captured_time_ns)
                            .unwrap();
                    }
                    let mut m = out.joints;
                    m.header = Header::new(Kind::JointState, now / 1000, 0, 0);
                    m.header.source_time_ns = now;
                    last = e
                        .on_joints(&m, Header::new(Kind::GraspState, now / 1000, 0, 0))
                        .unwrap();
                    if k == steps.len() && tick >= 100 {
                        // The last step, the hand still: the estimate's error, averaged
                        // over the encoders' noise.
                        error += (last.rotation - plant.rotation()) / 200.0;
                    }
                }
            }
            let truth = plant.rotation();
            assert!(truth > 9.9f64.to_radians(), "{}", truth.to_degrees());
            assert!(
                error.abs() < 0.1f64.to_radians(),
                "poses {with_poses}: estimated {} deg off the true {} deg",
                error.to_degrees(),
                truth.to_degrees()
            );
            let cands = setup.problem.candidates();
            for (slot, f) in setup.hand.fingers.iter().enumerate() {
                let c = &last.fingers[slot];
                assert_eq!(c.finger, f.id);
                assert_eq!(c.in_contact == 1, slots.contains(&slot), "finger {}", f.id);
                if c.in_contact == 1 {
                    let Roller::Space(turning) = roller else {
                        unreachable!("a spatial hand")
                    };
                    let p = turning.contact_of(f, &plant.joints()[slot], truth).point;
                    let d = (cands.points[c.candidate as usize] - p).norm();
                    assert!(
                        d < 3e-3,
                        "finger {}: candidate {d} m from the contact",
                        f.id
                    );
                }
            }
        }
    }

    /// A finger the hand commands no longer press, sliding along the object's surface on its
    /// way off (within [`RELEASE`] of it: in contact by the geometry all along), does not turn
    /// the estimate, as the plant does not turn the object with it; without the commands
    /// (every finger in contact counting), the same samples turn it.
    #[test]
    fn a_finger_no_longer_pressed_does_not_turn_the_estimate_on_its_way_off() {
        let (mut config, setup) = crate::testing::allegro_sphere();
        config.pipeline.joint_noise = 0.0;
        let (steps, slots) = crate::testing::spatial_rolling(&config, &setup, 10);
        let mut blind_most = 0.0_f64;
        for k in 0..slots.len() {
            let (told, blind) = leaving(&config, &setup, &steps, &slots, k);
            assert!(
                told.abs() < 1e-9,
                "finger {k} of the grasp: {} deg",
                told.to_degrees()
            );
            blind_most = blind_most.max(blind.abs());
        }
        // The thumb's way off, counted, turns the estimate by nearly the ten degrees its
        // contact went over (9.6): the index and the ring finger touch near the axis and weigh
        // little in the least squares.
        assert!(
            blind_most > 5f64.to_radians(),
            "{} deg",
            blind_most.to_degrees()
        );
    }

    /// The kinematic plant holding `setup`'s initial grip at `t0`.
    fn plant_at_grip<'a>(config: &'a Config, setup: &'a Setup, t0: u64) -> crate::plant::Plant<'a> {
        let (joints, touching) = setup.initial_grip(config).unwrap();
        crate::plant::Plant::new(
            &setup.hand,
            setup.roller(config).unwrap(),
            (joints, &touching),
            &config.pipeline,
            t0,
        )
    }

    /// The grasp of `slots` pressed and settled at `steps[0]`; then its finger `k`, no longer
    /// pressed, goes where `steps[10]` has it (ten degrees of rolling over the still sphere);
    /// the estimates told the commands and not told (rad).
    fn leaving(
        config: &Config,
        setup: &Setup,
        steps: &[Vec<Vec<f64>>],
        slots: &[usize],
        k: usize,
    ) -> (f64, f64) {
        let roller = setup.roller(config).unwrap();
        let t0 = 1_000_000_000_000;
        let mut plant = plant_at_grip(config, setup, t0);
        let mut told = Estimator::new(&setup.hand, roller, &setup.problem, 0.0);
        let mut blind = Estimator::new(&setup.hand, roller, &setup.problem, 0.0);
        let dt = (1e9 / config.pipeline.rate_hz) as u64;
        let mut now = t0;
        let leaving = slots[k];
        let mut away = steps[0].clone();
        away[leaving] = steps[10][leaving].clone();
        let mut off = crate::testing::command(setup, slots, &away, true, now);
        off.forces[k] = [0.0; 3];
        let (mut touching, mut samples) = (0, 0);
        for (phase, joints) in [&steps[0], &away].into_iter().enumerate() {
            if phase == 1 {
                // A hold (no force targets) moves nothing and changes nothing.
                let hold = HandCommand {
                    mode: CommandMode::Hold as u32,
                    ..off
                };
                told.on_command(&hold);
                assert!(slots.iter().all(|&s| told.presses(s)), "a hold let go");
            }
            let mut c = if phase == 0 {
                crate::testing::command(setup, slots, joints, true, now)
            } else {
                off
            };
            for _ in 0..600 {
                now += dt;
                c.header.source_time_ns = now;
                let out = plant.tick(now, Some(&c));
                let mut m = out.joints;
                m.header = Header::new(Kind::JointState, now / 1000, 0, 0);
                m.header.source_time_ns = now;
                told.on_command(&c);
                let g = told
                    .on_joints(&m, Header::new(Kind::GraspState, now / 1000, 0, 0))
                    .unwrap();
                blind
                    .on_joints(&m, Header::new(Kind::GraspState, now / 1000, 0, 0))
                    .unwrap();
                if phase == 1 {
                    samples += 1;
                    touching += g.fingers[leaving].in_contact;
                }
            }
        }
        let arrived = (plant.joints()[leaving].iter())
            .zip(&steps[10][leaving])
            .all(|(a, b)| (a - b).abs() < 1e-9);
        assert!(arrived, "finger {k} of the grasp got where it was sent");
        assert!(
            plant.rotation().abs() < 1e-12,
            "the plant turned the object"
        );
        // In contact by the geometry (within RELEASE) all the way: the case in question.
        assert_eq!(touching, samples, "finger {k} of the grasp");
        (told.rotation(), blind.rotation())
    }

    /// A spatial hand's object moved (as a MuJoCo plant's is pushed about by the fingers): the
    /// fingertips that follow it still touch it, at their contacts of the grip, once the pose
    /// measurements say where it went; the grasp state carries the move in space.
    #[test]
    fn a_spatial_hand_s_object_is_taken_about_its_moved_centre() {
        let (config, setup) = crate::testing::allegro_sphere();
        let roller = setup.roller(&config).unwrap();
        let (joints, touching) = setup.initial_grip(&config).unwrap();
        let d = Vec3::new(1.5e-3, -1.0e-3, 2.0e-3);
        let mut m = JointState {
            finger_count: setup.hand.fingers.len() as u32,
            ..Default::default()
        };
        for (slot, f) in setup.hand.fingers.iter().enumerate() {
            m.finger_ids[slot] = f.id;
            m.joint_counts[slot] = f.dof() as u32;
            let mut q = joints[slot].clone();
            if touching.contains(&f.id) {
                let centre = f.tip_centre(&joints[slot]);
                assert!(
                    f.shift_point(&joints[slot], &centre, &d, &mut q),
                    "finger {}",
                    f.id
                );
            }
            m.positions[slot][..f.dof()].copy_from_slice(&q);
        }
        let mut e = Estimator::new(&setup.hand, roller, &setup.problem, 0.0);
        let mut at_grip = GraspState::default();
        for (k, moved) in [[0.0; 3], [d.x, d.y, d.z]].into_iter().enumerate() {
            let mut g = GraspState::default();
            for tick in 0..100 {
                e.on_position(moved).unwrap();
                let h = Header::new(Kind::GraspState, (100 * k + tick) as u64, 0, 0);
                g = e.on_joints(&m, h).unwrap();
            }
            if k == 0 {
                // Not moved: the fingertips a few millimetres off where the object is.
                let made = g.fingers.iter().filter(|c| c.in_contact == 1).count();
                assert!(
                    made < touching.len() || g.residual > 1e-3,
                    "{made} {}",
                    g.residual
                );
            } else {
                at_grip = g;
            }
        }
        let g = at_grip;
        assert!(
            (Vec3::from(g.position) - d).norm() < 1e-9,
            "{:?}",
            g.position
        );
        assert!(g.residual < 1e-6, "residual {} m", g.residual);
        assert!(g.rotation.abs() < 1e-9, "{}", g.rotation);
        let start = setup.spatial_scenario(&config).unwrap().start().unwrap().0;
        for t in &start {
            let slot = setup
                .hand
                .fingers
                .iter()
                .position(|f| f.id == t.finger)
                .unwrap();
            let c = &g.fingers[slot];
            assert_eq!(c.in_contact, 1, "finger {}", t.finger);
            let p = Vec3::from(c.point);
            assert!(
                (p - t.point).norm() < 3e-3,
                "finger {}: {p} off {}",
                t.finger,
                t.point
            );
        }
    }
}
