//! The monitoring payloads: every local message the bridge publishes on Zenoh, as one JSON
//! object, so that any Zenoh client can read it without our message layouts.
//!
//! Every object has the fields of [`Envelope`]: `schema` ([`SCHEMA`]), `topic`, `rig`,
//! `sequence` (the publisher's sequence number), `time_ns` (when the message was published,
//! nanoseconds since the Unix epoch) and `origin_ns` (the plant measurement at the start of
//! its chain, 0 if none), then the fields of its topic, named like the message's
//! (`icrflow_interfaces`); angles in radians unless the name ends in `_deg`, lengths in metres,
//! forces in newtons. The README of this crate lists them per topic.

use icrflow_interfaces::{
    CommandMode, FingerContact, GraspState, HandCommand, Header, JointState, MAX_FINGERS,
    NodeHealth, NodeState, PlanPhase, PlanStepHeader, PlanWait, WrenchSpaceHeader, read_text,
};
use serde::{Deserialize, Serialize};

/// Version of the monitoring JSON; a client should ignore objects of another.
pub const SCHEMA: u32 = 1;

/// The fields every monitoring object starts with.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Envelope {
    /// [`SCHEMA`].
    pub schema: u32,
    /// The local topic (`grasp_state`, ...).
    pub topic: String,
    /// The rig (`pipeline.rig`).
    pub rig: String,
    /// The publisher's sequence number.
    pub sequence: u64,
    /// When the message was published (ns since the Unix epoch).
    pub time_ns: u64,
    /// The plant measurement its chain started from (ns since the Unix epoch; 0: none).
    pub origin_ns: u64,
}

impl Envelope {
    fn of(topic: &str, rig: &str, h: &Header) -> Self {
        Self {
            schema: SCHEMA,
            topic: topic.into(),
            rig: rig.into(),
            sequence: h.sequence,
            time_ns: h.source_time_ns,
            origin_ns: h.origin_time_ns,
        }
    }
}

/// `joint_state`: the encoders.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct JointStateJson {
    /// The common fields.
    #[serde(flatten)]
    pub envelope: Envelope,
    /// Each finger's joint angles.
    pub fingers: Vec<FingerJoints>,
}

/// One finger's joint angles.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FingerJoints {
    /// Finger id.
    pub finger: u32,
    /// Joint angles (rad), base first.
    pub joints: Vec<f64>,
}

/// `grasp_state`: the estimate.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GraspStateJson {
    /// The common fields.
    #[serde(flatten)]
    pub envelope: Envelope,
    /// Object rotation about the vertical axis since the start (unwrapped).
    pub rotation: f64,
    /// The same in degrees.
    pub rotation_deg: f64,
    /// Object orientation `[w, x, y, z]`.
    pub orientation: [f64; 4],
    /// Object centre of mass in the hand frame.
    pub position: [f64; 3],
    /// Root-mean-square fit residual of the fingertips on the object.
    pub residual: f64,
    /// The estimate's smoothed pose innovation (rad): how far it was off the object-pose
    /// measurements.
    pub pose_innovation: f64,
    /// Each finger's contact state.
    pub contacts: Vec<ContactJson>,
}

/// One finger's estimated contact.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ContactJson {
    /// Finger id.
    pub finger: u32,
    /// Whether the fingertip touches the object.
    pub in_contact: bool,
    /// Candidate index of the contact point (meaningful when in contact).
    pub candidate: u32,
    /// Body-frame contact point and outward normal.
    pub point: [f64; 3],
    /// Body-frame outward normal at the contact point.
    pub normal: [f64; 3],
}

/// `wrench_space`: the grasp's wrench space (its hull facets are not sent).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct WrenchSpaceJson {
    /// The common fields.
    #[serde(flatten)]
    pub envelope: Envelope,
    /// The grasp state it was computed from.
    pub grasp_sequence: u64,
    /// Whether the grasp is force closure.
    pub force_closure: bool,
    /// Quality alpha* (0 unless force closure).
    pub quality: f64,
    /// The margin alpha the pipeline keeps.
    pub alpha: f64,
    /// Ferrari-Canny epsilon.
    pub epsilon: f64,
    /// Wrench-space dimension (3 planar, 6 spatial).
    pub dim: u32,
    /// Facets of the hull.
    pub facets: usize,
}

/// `plan_step`: the planner's current target.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PlanStepJson {
    /// The common fields.
    #[serde(flatten)]
    pub envelope: Envelope,
    /// `start`, `rolling`, `attach`, `detach` or `done`.
    pub phase: String,
    /// Planned step number.
    pub step: u64,
    /// Target object rotation.
    pub rotation: f64,
    /// The same in degrees.
    pub rotation_deg: f64,
    /// Quality alpha* of the planned grasp.
    pub quality: f64,
    /// Each finger's target, with the size of its ICR.
    pub targets: Vec<TargetJson>,
    /// In an attach step: the finger that attaches and the size of its rendezvous region.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rendezvous: Option<RendezvousJson>,
    /// Whether the hand holds this target waiting for the planner: `ahead` (the rest of the
    /// plan being made) or `again` (a plan made again from the estimate), and for how long so
    /// far (ms); absent when it does not wait.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub planning: Option<PlanningJson>,
}

/// The hand waiting for the planner at a plan step.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PlanningJson {
    /// `ahead` or `again` (`PlanWait`).
    pub wait: String,
    /// How long so far (ms).
    pub ms: u32,
}

/// The rendezvous region of an attach step.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RendezvousJson {
    /// The finger that attaches.
    pub finger: u32,
    /// Candidates in its rendezvous region.
    pub size: u32,
}

/// One finger's target in a plan step.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TargetJson {
    /// Finger id.
    pub finger: u32,
    /// Whether the finger is in contact in this step.
    pub in_contact: bool,
    /// Candidate index of its contact point (meaningful when in contact).
    pub candidate: u32,
    /// Body-frame contact point.
    pub point: [f64; 3],
    /// Joint targets (rad), base first.
    pub joints: Vec<f64>,
    /// Candidates in this finger's ICR.
    pub icr_size: u32,
}

/// `hand_command`: what the hand is told.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct HandCommandJson {
    /// The common fields.
    #[serde(flatten)]
    pub envelope: Envelope,
    /// `track`, `hold`, or `attach` (below the margin, a finger attaching to the grasp held).
    pub mode: String,
    /// Why the hand holds or attaches below the margin (empty when tracking).
    pub reason: String,
    /// Quality alpha* the command was computed with (0 when holding).
    pub quality: f64,
    /// Measurement-to-command latency (us; 0 when unknown, e.g. a hold).
    pub latency_us: f64,
    /// Each finger's joint targets and fingertip force.
    pub fingers: Vec<FingerCommandJson>,
}

/// One finger's command.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FingerCommandJson {
    /// Finger id.
    pub finger: u32,
    /// Joint targets (rad), base first.
    pub joints: Vec<f64>,
    /// Fingertip force target (N, hand frame).
    pub force: [f64; 3],
}

/// `node_health`: a node's periodic report.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct NodeHealthJson {
    /// The common fields.
    #[serde(flatten)]
    pub envelope: Envelope,
    /// The node's name.
    pub node: String,
    /// `starting`, `running`, `degraded` or `stopping`.
    pub state: String,
    /// Its process id.
    pub pid: u32,
    /// Messages it has processed.
    pub processed: u64,
    /// Messages it has refused.
    pub refused: u64,
    /// The last problem (empty if none).
    pub message: String,
}

fn fingers(count: u32) -> usize {
    (count as usize).min(MAX_FINGERS)
}

/// `joint_state` as JSON.
pub fn joint_state(rig: &str, m: &JointState) -> JointStateJson {
    JointStateJson {
        envelope: Envelope::of("joint_state", rig, &m.header),
        fingers: (0..fingers(m.finger_count))
            .map(|k| FingerJoints {
                finger: m.finger_ids[k],
                joints: m.positions[k][..(m.joint_counts[k] as usize).min(m.positions[k].len())]
                    .to_vec(),
            })
            .collect(),
    }
}

fn contact(c: &FingerContact) -> ContactJson {
    ContactJson {
        finger: c.finger,
        in_contact: c.in_contact == 1,
        candidate: c.candidate,
        point: c.point,
        normal: c.normal,
    }
}

/// `grasp_state` as JSON.
pub fn grasp_state(rig: &str, g: &GraspState) -> GraspStateJson {
    GraspStateJson {
        envelope: Envelope::of("grasp_state", rig, &g.header),
        rotation: g.rotation,
        rotation_deg: g.rotation.to_degrees(),
        orientation: g.orientation,
        position: g.position,
        residual: g.residual,
        pose_innovation: g.pose_innovation,
        contacts: g.fingers[..fingers(g.finger_count)]
            .iter()
            .map(contact)
            .collect(),
    }
}

/// `wrench_space` as JSON, with the number of facets that came with it.
pub fn wrench_space(rig: &str, w: &WrenchSpaceHeader, facets: usize) -> WrenchSpaceJson {
    WrenchSpaceJson {
        envelope: Envelope::of("wrench_space", rig, &w.header),
        grasp_sequence: w.header.input_sequence,
        force_closure: w.force_closure == 1,
        quality: w.quality,
        alpha: w.alpha,
        epsilon: w.epsilon,
        dim: w.dim,
        facets,
    }
}

/// `plan_step` as JSON.
pub fn plan_step(rig: &str, p: &PlanStepHeader) -> PlanStepJson {
    PlanStepJson {
        envelope: Envelope::of("plan_step", rig, &p.header),
        phase: PlanPhase::name_of(p.phase).into(),
        step: p.step,
        rotation: p.rotation,
        rotation_deg: p.rotation.to_degrees(),
        quality: p.quality,
        targets: (0..fingers(p.finger_count))
            .map(|k| {
                let t = &p.targets[k];
                TargetJson {
                    finger: t.finger,
                    in_contact: t.in_contact == 1,
                    candidate: t.candidate,
                    point: t.point,
                    joints: t.joints[..(t.joint_count as usize).min(t.joints.len())].to_vec(),
                    icr_size: p.region_lengths[k],
                }
            })
            .collect(),
        rendezvous: (p.rendezvous_length > 0).then_some(RendezvousJson {
            finger: p.rendezvous_finger,
            size: p.rendezvous_length,
        }),
        planning: (p.planning != PlanWait::None as u32).then(|| PlanningJson {
            wait: PlanWait::name_of(p.planning).into(),
            ms: p.planning_ms,
        }),
    }
}

/// `hand_command` as JSON.
pub fn hand_command(rig: &str, c: &HandCommand) -> HandCommandJson {
    let tracking = c.mode == CommandMode::Track as u32;
    let latency_us = if tracking && c.header.origin_time_ns > 0 {
        c.header
            .source_time_ns
            .saturating_sub(c.header.origin_time_ns) as f64
            * 1e-3
    } else {
        0.0
    };
    HandCommandJson {
        envelope: Envelope::of("hand_command", rig, &c.header),
        mode: match c.mode {
            m if m == CommandMode::Track as u32 => "track",
            m if m == CommandMode::Attach as u32 => "attach",
            _ => "hold",
        }
        .into(),
        reason: read_text(&c.reason),
        quality: c.quality,
        latency_us,
        fingers: (0..fingers(c.finger_count))
            .map(|k| FingerCommandJson {
                finger: c.finger_ids[k],
                joints: c.joint_targets[k].to_vec(),
                force: c.forces[k],
            })
            .collect(),
    }
}

/// The name of a node state.
pub fn state_name(state: u32) -> &'static str {
    match state {
        s if s == NodeState::Starting as u32 => "starting",
        s if s == NodeState::Running as u32 => "running",
        s if s == NodeState::Degraded as u32 => "degraded",
        s if s == NodeState::Stopping as u32 => "stopping",
        _ => "unknown",
    }
}

/// `node_health` as JSON.
pub fn node_health(rig: &str, h: &NodeHealth) -> NodeHealthJson {
    NodeHealthJson {
        envelope: Envelope::of("node_health", rig, &h.header),
        node: read_text(&h.node),
        state: state_name(h.state).into(),
        pid: h.pid,
        processed: h.processed,
        refused: h.refused,
        message: read_text(&h.message),
    }
}

/// Why a monitoring object was refused.
#[derive(Debug, thiserror::Error)]
pub enum Refused {
    /// Not JSON, or not an object with the envelope's fields.
    #[error("malformed monitoring JSON: {0}")]
    Malformed(String),
    /// Another [`SCHEMA`].
    #[error("monitoring schema {got}, expected {SCHEMA}")]
    Schema {
        /// The schema the object carries.
        got: u32,
    },
}

/// The envelope of a monitoring object, checked: JSON with the envelope's fields and this
/// [`SCHEMA`].
pub fn envelope(bytes: &[u8]) -> Result<Envelope, Refused> {
    let e: Envelope =
        serde_json::from_slice(bytes).map_err(|e| Refused::Malformed(e.to_string()))?;
    if e.schema != SCHEMA {
        return Err(Refused::Schema { got: e.schema });
    }
    Ok(e)
}

#[cfg(test)]
mod tests {
    use super::*;
    use icrflow_interfaces::{Kind, write_text};

    #[test]
    fn a_hold_reads_back_with_its_reason_and_envelope() {
        let mut c = HandCommand {
            header: Header::new(Kind::HandCommand, 7, 0, 0),
            finger_count: 2,
            ..Default::default()
        };
        c.finger_ids[..2].copy_from_slice(&[1, 4]);
        c.forces[1] = [0.5, -1.0, 0.0];
        write_text(&mut c.reason, "the grasp is not force closure");
        let text = serde_json::to_vec(&hand_command("lab", &c)).unwrap();
        let back: HandCommandJson = serde_json::from_slice(&text).unwrap();
        assert_eq!(back.envelope.schema, SCHEMA);
        assert_eq!(back.envelope.topic, "hand_command");
        assert_eq!(back.envelope.rig, "lab");
        assert_eq!(back.envelope.sequence, 7);
        assert_eq!(back.mode, "hold");
        assert_eq!(back.reason, "the grasp is not force closure");
        assert_eq!(back.fingers.len(), 2);
        assert_eq!(back.fingers[1].finger, 4);
        assert_eq!(back.fingers[1].force, [0.5, -1.0, 0.0]);
        assert_eq!(envelope(&text).unwrap(), back.envelope);
        // Each mode by its name; an unknown one is a hold, as the plants take it.
        for (mode, name) in [(0, "track"), (1, "hold"), (2, "attach"), (7, "hold")] {
            c.mode = mode;
            assert_eq!(hand_command("lab", &c).mode, name, "{mode}");
        }
    }

    #[test]
    fn a_plan_step_says_whether_the_hand_waits_for_the_planner() {
        let mut p = PlanStepHeader {
            header: Header::new(Kind::PlanStep, 3, 0, 0),
            phase: PlanPhase::Rolling as u32,
            ..Default::default()
        };
        let text = serde_json::to_string(&plan_step("lab", &p)).unwrap();
        assert!(!text.contains("planning"), "{text}");
        for (wait, name) in [(PlanWait::Ahead, "ahead"), (PlanWait::Again, "again")] {
            p.planning = wait as u32;
            p.planning_ms = 1234;
            let text = serde_json::to_vec(&plan_step("lab", &p)).unwrap();
            let back: PlanStepJson = serde_json::from_slice(&text).unwrap();
            let planning = back.planning.unwrap();
            assert_eq!((planning.wait.as_str(), planning.ms), (name, 1234));
        }
    }

    #[test]
    fn malformed_or_foreign_objects_are_refused_with_the_reason() {
        assert!(matches!(envelope(b"{not json"), Err(Refused::Malformed(_))));
        assert!(matches!(envelope(b"[1, 2]"), Err(Refused::Malformed(_))));
        let other = br#"{"schema": 9, "topic": "x", "rig": "r", "sequence": 1, "time_ns": 1, "origin_ns": 0}"#;
        let e = envelope(other).unwrap_err();
        assert!(matches!(e, Refused::Schema { got: 9 }));
        assert_eq!(
            e.to_string(),
            format!("monitoring schema 9, expected {SCHEMA}")
        );
    }
}
