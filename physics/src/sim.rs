//! The hand and object stepped in MuJoCo ([`Sim`]): joint servos toward the commanded targets,
//! feed-forward torques `J^T f` from the fingertip force targets, and what MuJoCo knows to be
//! true (the object's pose, each fingertip's contact point, normal, force and slip).
//!
//! **Feed-forward.** For a finger commanded with a force `f` (on the object, hand frame) the
//! joints get `tau_k = (a_k x (p - o_k)) . f`, `a_k` and `o_k` the joint's axis and anchor in
//! the world and `p` where the fingertip touches (MuJoCo's contact point; the point of the
//! fingertip sphere along `f` when it touches nothing): the torques that press `f` on the
//! object through a rigid finger, written into `qfrc_applied` before every step. Nothing is
//! allocated per step.
//!
//! **Squeeze.** A finger commanded with a force has its servo targets moved so that its
//! fingertip centre's target lies further along `f`, by [`Controls::squeeze`] times `|f|` over
//! the largest force commanded to any finger (a damped least-squares step of the fingertip
//! Jacobian): the position servos then press too, as a hand's controller squeezes an object
//! it holds, and press the fingers in proportion to the balancing forces, so that what they
//! add is itself nearly balanced. (The same squeeze for every finger, used until session 18,
//! added an unbalanced push wherever the forces differ: the object lagged the hand by a
//! degree and more, and the ellipsoid slipped out under gravity.)

use icrflow_grasp::math::{Real, Vec3};
use icrflow_plan::hand::Hand;
use mujoco_rs::prelude::*;
use nalgebra::{Matrix3, UnitQuaternion};

use crate::scene::{OBJECT, actuator_name, joint_name, tip_name};

/// The MuJoCo version this build is for (the library of PyPI's `mujoco` wheel).
pub const MUJOCO_VERSION: &str = "3.17.0";
/// Joints a finger may have (as the pipeline's messages carry).
const MAX_JOINTS: usize = 8;
/// Damping of the squeeze's least-squares step (m^2).
const SQUEEZE_DAMPING: Real = 1e-6;

/// Why a model cannot be simulated.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum SimError {
    /// The library loaded is another version than the one this build is for.
    #[error(
        "MuJoCo {found} was loaded, but icrflow is built for MuJoCo {MUJOCO_VERSION} (the library of PyPI's mujoco=={MUJOCO_VERSION}; run scripts/setup.sh)"
    )]
    Version {
        /// The version loaded.
        found: String,
    },
    /// MuJoCo refused the model (its words).
    #[error("MuJoCo cannot build the model: {0}")]
    Model(String),
    /// A name the model must have is not in it.
    #[error("the model has no {0}")]
    Missing(String),
}

/// How the hand is driven (the `[plant]` section's controls).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Controls {
    /// Feed the fingertip force targets forward as joint torques.
    pub feedforward: bool,
    /// How far past the commanded fingertip position the servos of the finger pressing
    /// hardest aim (m); the others' in proportion to their forces.
    pub squeeze: Real,
}

/// One fingertip's contact as MuJoCo has it (hand frame).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct TrueContact {
    /// Where (the mean of the contact points between the fingertip and the object).
    pub point: Vec3,
    /// The object's outward unit normal there.
    pub normal: Vec3,
    /// The force the fingertip applies to the object (N).
    pub force: Vec3,
    /// Its normal part (N, pushing in: positive).
    pub normal_force: Real,
    /// Its tangential part's magnitude (N).
    pub tangential_force: Real,
    /// Speed of the fingertip's surface relative to the object's at the contact, in the
    /// tangent plane (m/s): zero when it rolls.
    pub slip_speed: Real,
}

/// Which parts of the hand touch what they should not this step (bit `k`: the finger in slot
/// `k`): a planned grasp touches the object with its fingertips only, and no finger touches
/// another.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Collisions {
    /// Fingers a link of which (not the fingertip) touches the object.
    pub links_on_object: u32,
    /// Fingers touching another finger (fingertip or link, either side).
    pub fingers_touching: u32,
}

/// Where a finger is in the model.
#[derive(Debug, Clone)]
struct FingerIds {
    /// `qpos` address and `dof` address of each joint, and its joint id.
    qpos: Vec<usize>,
    dof: Vec<usize>,
    joint: Vec<usize>,
    /// Actuator of each joint.
    actuator: Vec<usize>,
    /// The fingertip geom and its body.
    tip_geom: usize,
    tip_body: usize,
    /// The commanded joint targets (rad) and force (N, on the object; zero: none).
    target: [Real; MAX_JOINTS],
    force: Vec3,
}

/// The hand and the object in MuJoCo.
pub struct Sim {
    data: MjData<Box<MjModel>>,
    fingers: Vec<FingerIds>,
    object_body: usize,
    object_geom: usize,
    /// The object's free joint's qpos address.
    object_qpos: usize,
    controls: Controls,
    hand: Hand,
    /// Per finger, where its fingertip touches the object this step (None: nowhere), and of
    /// how many of MuJoCo's contacts that is the mean.
    touching: Vec<Option<TrueContact>>,
    counts: Vec<usize>,
    /// The finger slot of each geom of the hand (`None`: the object's, or another).
    geom_slot: Vec<Option<u8>>,
    /// This step's collisions.
    collisions: Collisions,
    /// An external force and torque on the object (hand frame, about its centre of mass)
    /// until a simulation time (s).
    push: Option<([Real; 6], Real)>,
}

/// The MuJoCo version loaded, checked against the one this build is for.
pub fn check_version() -> Result<&'static str, SimError> {
    let found = mujoco_rs::mujoco_version();
    if found != MUJOCO_VERSION {
        return Err(SimError::Version {
            found: found.to_string(),
        });
    }
    Ok(found)
}

/// Compiles `xml` in MuJoCo: whether it can build the model, in its words.
pub fn compile(xml: &str) -> Result<(), SimError> {
    check_version()?;
    MjModel::from_xml_string(xml)
        .map(drop)
        .map_err(|e| SimError::Model(model_error(e)))
}

fn model_error(e: MjModelError) -> String {
    match e {
        MjModelError::LoadFailed(why) => why.trim().to_string(),
        other => format!("{other:?}"),
    }
}

impl Sim {
    /// The model `xml` (written by [`crate::scene::mjcf`] for `hand`), the hand at `joints`
    /// (per finger, rad) with its servos holding them, the object at rest at the origin.
    pub fn new(
        xml: &str,
        hand: &Hand,
        joints: &[Vec<Real>],
        controls: Controls,
    ) -> Result<Self, SimError> {
        check_version()?;
        let model = MjModel::from_xml_string(xml).map_err(|e| SimError::Model(model_error(e)))?;
        let id = |kind: MjtObjBase, name: &str| {
            model
                .name_to_id(kind, name)
                .ok_or_else(|| SimError::Missing(format!("{name:?}")))
        };
        let object_body = id(MjtObjBase::mjOBJ_BODY, OBJECT)?;
        let object_geom = id(MjtObjBase::mjOBJ_GEOM, OBJECT)?;
        let object_joint = id(MjtObjBase::mjOBJ_JOINT, OBJECT)?;
        let object_qpos = model.jnt_qposadr()[object_joint] as usize;
        let mut fingers = Vec::with_capacity(hand.fingers.len());
        for f in &hand.fingers {
            if f.dof() > MAX_JOINTS {
                return Err(SimError::Model(format!(
                    "finger {} has {} joints, more than {MAX_JOINTS}",
                    f.id,
                    f.dof()
                )));
            }
            let mut ids = FingerIds {
                qpos: Vec::with_capacity(f.dof()),
                dof: Vec::with_capacity(f.dof()),
                joint: Vec::with_capacity(f.dof()),
                actuator: Vec::with_capacity(f.dof()),
                tip_geom: id(MjtObjBase::mjOBJ_GEOM, &tip_name(f.id))?,
                tip_body: 0,
                target: [0.0; MAX_JOINTS],
                force: Vec3::zeros(),
            };
            ids.tip_body = model.geom_bodyid()[ids.tip_geom] as usize;
            for k in 0..f.dof() {
                let j = id(MjtObjBase::mjOBJ_JOINT, &joint_name(f.id, k))?;
                ids.joint.push(j);
                ids.qpos.push(model.jnt_qposadr()[j] as usize);
                ids.dof.push(model.jnt_dofadr()[j] as usize);
                ids.actuator
                    .push(id(MjtObjBase::mjOBJ_ACTUATOR, &actuator_name(f.id, k))?);
            }
            fingers.push(ids);
        }
        // A geom belongs to the finger whose joints move its body.
        let geom_slot = model
            .geom_bodyid()
            .iter()
            .map(|&body| {
                fingers
                    .iter()
                    .position(|f| f.joint.iter().any(|&j| model.jnt_bodyid()[j] == body))
                    .map(|slot| slot as u8)
            })
            .collect();
        let mut sim = Self {
            data: MjData::new(Box::new(model)),
            geom_slot,
            collisions: Collisions::default(),
            touching: vec![None; fingers.len()],
            counts: vec![0; fingers.len()],
            fingers,
            object_body,
            object_geom,
            object_qpos,
            controls,
            hand: hand.clone(),
            push: None,
        };
        for (slot, q) in joints.iter().enumerate().take(sim.fingers.len()) {
            let f = &mut sim.fingers[slot];
            for (k, &a) in q.iter().enumerate().take(f.qpos.len()) {
                sim.data.qpos_mut()[f.qpos[k]] = a;
                f.target[k] = a;
            }
        }
        sim.apply_targets();
        sim.data.forward();
        sim.observe();
        Ok(sim)
    }

    /// MuJoCo's version.
    pub fn version(&self) -> &'static str {
        mujoco_rs::mujoco_version()
    }

    /// The simulation time (s).
    pub fn time(&self) -> Real {
        self.data.time()
    }

    /// The timestep (s).
    pub fn timestep(&self) -> Real {
        self.data.model().opt().timestep
    }

    /// Commands finger `slot`: its joint targets (rad; clamped into the limits by the
    /// servos' control range) and the force its fingertip is to apply to the object (hand
    /// frame; zero for none).
    pub fn command(&mut self, slot: usize, targets: &[Real], force: Vec3) {
        let Some(f) = self.fingers.get_mut(slot) else {
            return;
        };
        for (k, &t) in targets.iter().enumerate().take(f.qpos.len()) {
            f.target[k] = t;
        }
        f.force = force;
    }

    /// Pushes the object with `force` (N) and `torque` (N m, about its centre of mass), both
    /// in the hand frame, for `duration` s from now.
    pub fn push(&mut self, force: Vec3, torque: Vec3, duration: Real) {
        self.push = Some((
            [force.x, force.y, force.z, torque.x, torque.y, torque.z],
            self.time() + duration,
        ));
    }

    /// One timestep: the servo targets (squeezed) and the feed-forward torques from the
    /// commands, the push if one is on, then MuJoCo's step; then the contacts are read.
    pub fn step(&mut self) {
        self.apply_targets();
        let mut wrench = [0.0; 6];
        if let Some((w, until)) = self.push {
            if self.time() < until {
                wrench = w;
            } else {
                self.push = None;
            }
        }
        self.data.xfrc_applied_mut()[self.object_body] = wrench;
        self.data.step();
        self.observe();
    }

    /// Servo targets and feed-forward torques from the commands, at the current state.
    fn apply_targets(&mut self) {
        let n = self.fingers.len();
        // The largest force commanded: the finger that presses hardest squeezes the whole
        // `squeeze`, the others in proportion to their forces.
        let largest = self
            .fingers
            .iter()
            .map(|f| f.force.norm())
            .fold(0.0, Real::max);
        for slot in 0..n {
            let (force, has_force) = {
                let f = &self.fingers[slot];
                (f.force, f.force.norm_squared() > 0.0)
            };
            let at = self.touching[slot].map(|c| c.point);
            // The fingertip's point along the force where it touches nothing.
            let tip_centre = self.tip_centre(slot);
            let radius = self.hand.fingers[slot].tip_radius;
            let p = at.unwrap_or_else(|| {
                if has_force {
                    tip_centre + force.normalize() * radius
                } else {
                    tip_centre
                }
            });
            let mut jac = [Vec3::zeros(); MAX_JOINTS];
            let mut jac_centre = [Vec3::zeros(); MAX_JOINTS];
            let dof = self.fingers[slot].joint.len();
            for k in 0..dof {
                let j = self.fingers[slot].joint[k];
                let axis = Vec3::from(self.data.xaxis()[j]);
                let anchor = Vec3::from(self.data.xanchor()[j]);
                jac[k] = axis.cross(&(p - anchor));
                jac_centre[k] = axis.cross(&(tip_centre - anchor));
            }
            // The squeeze: the fingertip centre's target further along the force, by
            // `squeeze` times its share of the largest force.
            let mut dq = [0.0; MAX_JOINTS];
            if has_force && self.controls.squeeze > 0.0 {
                let d = force * (self.controls.squeeze / largest);
                let mut jjt = Matrix3::identity() * SQUEEZE_DAMPING;
                for c in jac_centre.iter().take(dof) {
                    jjt += c * c.transpose();
                }
                if let Some(inv) = jjt.try_inverse() {
                    let y = inv * d;
                    for k in 0..dof {
                        dq[k] = jac_centre[k].dot(&y);
                    }
                }
            }
            let f = &self.fingers[slot];
            for k in 0..dof {
                self.data.ctrl_mut()[f.actuator[k]] = f.target[k] + dq[k];
                self.data.qfrc_applied_mut()[f.dof[k]] = if has_force && self.controls.feedforward {
                    jac[k].dot(&force)
                } else {
                    0.0
                };
            }
        }
    }

    /// The fingertip sphere's centre of finger `slot` (hand frame).
    fn tip_centre(&self, slot: usize) -> Vec3 {
        Vec3::from(self.data.geom_xpos()[self.fingers[slot].tip_geom])
    }

    /// Reads each fingertip's contact with the object from MuJoCo's contacts.
    fn observe(&mut self) {
        for t in self.touching.iter_mut() {
            *t = None;
        }
        self.counts.fill(0);
        self.collisions = Collisions::default();
        let object = self.object_geom as i32;
        let slot_of = |g: i32| usize::try_from(g).ok().and_then(|g| self.geom_slot[g]);
        for i in 0..self.data.contact().len() {
            let c = &self.data.contact()[i];
            let (g1, g2) = (c.geom[0], c.geom[1]);
            let other = if g1 == object {
                g2
            } else if g2 == object {
                g1
            } else {
                // Two parts of the hand: the model lets only different fingers touch.
                if let (Some(a), Some(b)) = (slot_of(g1), slot_of(g2)) {
                    self.collisions.fingers_touching |= (1 << a) | (1 << b);
                }
                continue;
            };
            let Some(slot) = self.fingers.iter().position(|f| f.tip_geom as i32 == other) else {
                if let Some(k) = slot_of(other) {
                    self.collisions.links_on_object |= 1 << k;
                }
                continue;
            };
            let frame = c.frame;
            let point = Vec3::new(c.pos[0], c.pos[1], c.pos[2]);
            let cf = self.data.contact_force(i);
            // The frame's rows: the normal (from geom 1 to geom 2) and two tangents; the force
            // in it acts on geom 2.
            let n = Vec3::new(frame[0], frame[1], frame[2]);
            let t1 = Vec3::new(frame[3], frame[4], frame[5]);
            let t2 = Vec3::new(frame[6], frame[7], frame[8]);
            let on_2 = n * cf[0] + t1 * cf[1] + t2 * cf[2];
            let (force, outward) = if g2 == object { (on_2, -n) } else { (-on_2, n) };
            let e = self.touching[slot].get_or_insert_with(TrueContact::default);
            e.point += point;
            e.normal += outward;
            e.force += force;
            self.counts[slot] += 1;
        }
        for slot in 0..self.touching.len() {
            let Some(mut c) = self.touching[slot] else {
                continue;
            };
            let k = self.counts[slot].max(1) as Real;
            c.point /= k;
            c.normal = c.normal.try_normalize(1e-12).unwrap_or(c.normal);
            c.normal_force = -c.force.dot(&c.normal);
            c.tangential_force = (c.force + c.normal * c.normal_force).norm();
            // The relative velocity of the two bodies' points at the contact.
            let tip = self.point_velocity(self.fingers[slot].tip_body, &c.point);
            let obj = self.point_velocity(self.object_body, &c.point);
            let rel = tip - obj;
            c.slip_speed = (rel - c.normal * rel.dot(&c.normal)).norm();
            self.touching[slot] = Some(c);
        }
    }

    /// Which parts of the hand touched what they should not this step.
    pub fn collisions(&self) -> Collisions {
        self.collisions
    }

    /// The velocity of the point `p` (hand frame) moving with body `body`.
    fn point_velocity(&self, body: usize, p: &Vec3) -> Vec3 {
        let v = self
            .data
            .object_velocity(MjtObjBase::mjOBJ_XBODY, body, false);
        let (w, lin) = (Vec3::new(v[0], v[1], v[2]), Vec3::new(v[3], v[4], v[5]));
        let origin = Vec3::from(self.data.xpos()[body]);
        lin + w.cross(&(p - origin))
    }

    /// The state as numbers: the time, `qpos`, `qvel`, and every finger's commanded targets
    /// and force (what a restarted plant resumes from, [`Sim::set_state`]); nothing allocated.
    pub fn state(&self) -> impl Iterator<Item = Real> + '_ {
        std::iter::once(self.time())
            .chain(self.data.qpos().iter().copied())
            .chain(self.data.qvel().iter().copied())
            .chain(self.fingers.iter().flat_map(|f| {
                f.target[..f.qpos.len()]
                    .iter()
                    .copied()
                    .chain(f.force.iter().copied())
            }))
    }

    /// Resumes from a [`Sim::state`] of this model; `false` (nothing changed) if `v` is not one.
    pub fn set_state(&mut self, v: &[Real]) -> bool {
        let (nq, nv) = (self.data.qpos().len(), self.data.qvel().len());
        let commands: usize = self.fingers.iter().map(|f| f.qpos.len() + 3).sum();
        if v.len() != 1 + nq + nv + commands || !v.iter().all(|x| x.is_finite()) {
            return false;
        }
        self.data.set_time(v[0]);
        self.data.qpos_mut().copy_from_slice(&v[1..1 + nq]);
        self.data
            .qvel_mut()
            .copy_from_slice(&v[1 + nq..1 + nq + nv]);
        let mut at = 1 + nq + nv;
        for f in &mut self.fingers {
            let dof = f.qpos.len();
            f.target[..dof].copy_from_slice(&v[at..at + dof]);
            f.force = Vec3::new(v[at + dof], v[at + dof + 1], v[at + dof + 2]);
            at += dof + 3;
        }
        self.data.forward();
        self.observe();
        true
    }

    /// Finger `slot`'s joints (rad).
    pub fn joints(&self, slot: usize, out: &mut [Real]) {
        if let Some(f) = self.fingers.get(slot) {
            for (k, o) in out.iter_mut().enumerate().take(f.qpos.len()) {
                *o = self.data.qpos()[f.qpos[k]];
            }
        }
    }

    /// The object's body frame in the hand frame: its origin and orientation.
    pub fn object_pose(&self) -> (Vec3, UnitQuaternion<Real>) {
        let q = &self.data.qpos()[self.object_qpos..self.object_qpos + 7];
        let quat = nalgebra::Quaternion::new(q[3], q[4], q[5], q[6]);
        (
            Vec3::new(q[0], q[1], q[2]),
            UnitQuaternion::from_quaternion(quat),
        )
    }

    /// The object's centre of mass in the hand frame.
    pub fn object_centre(&self) -> Vec3 {
        Vec3::from(self.data.xipos()[self.object_body])
    }

    /// The object's mass (kg).
    pub fn object_mass(&self) -> Real {
        self.data.model().body_mass()[self.object_body]
    }

    /// Finger `slot`'s contact with the object, if its fingertip touches it.
    pub fn contact(&self, slot: usize) -> Option<&TrueContact> {
        self.touching.get(slot).and_then(Option::as_ref)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::{Params, Shape, mjcf};
    use icrflow_grasp::object::Object;

    #[test]
    fn the_loaded_library_is_the_version_built_for() {
        assert_eq!(check_version().unwrap(), MUJOCO_VERSION);
    }

    #[test]
    fn a_model_mujoco_refuses_is_named_in_its_words() {
        let e = compile("<mujoco><worldbody><geom type=\"sphere\"/></worldbody></mujoco>")
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("MuJoCo cannot build the model: "), "{e}");
        assert!(e.contains("size"), "{e}");
    }

    /// The paper's hand and sphere in MuJoCo, the fingers of the initial grasp at `joints`.
    fn paper(gravity: Vec3) -> (Hand, String) {
        let hand = icrflow_plan::paper::hand();
        let object = Object::sphere(0.0475, 16, 16).unwrap();
        let p = Params {
            timestep: 5e-4,
            gravity,
            density: 500.0,
            friction: 0.6,
            link_radius: 0.004,
            kp: 5.0,
            kv: 0.05,
            noslip_iterations: 0,
        };
        let xml = mjcf(&hand, &object, Shape::Sphere { radius: 0.0475 }, &p).unwrap();
        (hand, xml)
    }

    #[test]
    fn fk_in_mujoco_is_ours() {
        let (hand, xml) = paper(Vec3::zeros());
        let joints: Vec<Vec<Real>> = hand
            .fingers
            .iter()
            .enumerate()
            .map(|(s, f)| {
                f.joints
                    .iter()
                    .enumerate()
                    .map(|(k, j)| (0.2 + 0.1 * (s + k) as Real).clamp(j.lower, j.upper))
                    .collect()
            })
            .collect();
        let controls = Controls {
            feedforward: true,
            squeeze: 0.0,
        };
        let sim = Sim::new(&xml, &hand, &joints, controls).unwrap();
        for (slot, f) in hand.fingers.iter().enumerate() {
            let ours = f.fk(&joints[slot]).tip_centre;
            let theirs = sim.tip_centre(slot);
            assert!(
                (ours - theirs).norm() < 1e-9,
                "finger {}: {ours} vs {theirs}",
                f.id
            );
        }
    }
}
