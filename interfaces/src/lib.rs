//! # icrflow-interfaces: the pipeline's messages
//!
//! The messages the pipeline's processes exchange over iceoryx2 (DESIGN.md section 2):
//! `#[repr(C)]`, self-contained (no pointers, fixed capacities), [`ZeroCopySend`] with explicit
//! type names that carry the schema version, each starting with the common [`Header`]. Large
//! payloads (hull facets, ICR regions) travel as iceoryx2 dynamic slices behind a fixed user
//! header ([`WrenchSpaceHeader`] + `[Facet]`, [`PlanStepHeader`] + `[u32]`). Topic names are
//! in [`topics`].
//!
//! Conventions: SI units, radians; times are nanoseconds since the Unix epoch
//! ([`now_ns`]), comparable across the processes of one machine (and, with synchronised
//! clocks, across machines); arrays are indexed by finger slot (`0..finger_count`), each slot
//! naming its finger number.

#![warn(missing_docs)]
// The ZeroCopySend derive expands to `unsafe impl`: the one place this crate has unsafe code
// (the derive checks `#[repr(C)]` and that every field is ZeroCopySend).
#![allow(unsafe_code)]

use iceoryx2::prelude::ZeroCopySend;
// Byte views of the messages, checked at compile time (no padding, every bit pattern valid),
// for the Zenoh link between hosts ([`wire`]).
use zerocopy::{FromBytes, Immutable, IntoBytes, KnownLayout};

pub mod wire;

/// Version of the message schema. A node refuses messages with another version, and the type
/// names carry it, so that iceoryx2 refuses to connect mismatched ports at all.
pub const SCHEMA_VERSION: u32 = 8;

/// Largest number of fingers a message carries.
pub const MAX_FINGERS: usize = 8;
/// Largest number of joints per finger a message carries.
pub const MAX_JOINTS: usize = 8;
/// Bytes of a node name in [`NodeHealth`].
pub const NAME_BYTES: usize = 32;
/// Bytes of a free-text message in [`NodeHealth`] and [`HandCommand`].
pub const TEXT_BYTES: usize = 128;

/// The wall-clock time in nanoseconds since the Unix epoch (0 if the clock is before it).
pub fn now_ns() -> u64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos() as u64)
}

/// The type name iceoryx2 compares when ports connect (e.g. `icrflow.JointState.v8`).
pub fn type_name<T: ZeroCopySend>() -> &'static str {
    // SAFETY: `ZeroCopySend::type_name` is unsafe to *implement* (the name must identify the
    // layout); calling it only reads a static string.
    unsafe { <T as ZeroCopySend>::type_name() }
}

/// What kind of message a header belongs to (a second check beside the type name).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u32)]
pub enum Kind {
    /// [`JointState`].
    JointState = 1,
    /// [`ObjectPose`].
    ObjectPose = 2,
    /// [`GraspState`].
    GraspState = 3,
    /// [`WrenchSpaceHeader`].
    WrenchSpace = 4,
    /// [`PlanStepHeader`].
    PlanStep = 5,
    /// [`HandCommand`].
    HandCommand = 6,
    /// [`NodeHealth`].
    NodeHealth = 7,
    /// [`PlantTruth`].
    PlantTruth = 8,
}

/// The header every message starts with.
#[derive(
    Debug,
    Clone,
    Copy,
    PartialEq,
    Eq,
    Default,
    ZeroCopySend,
    FromBytes,
    IntoBytes,
    Immutable,
    KnownLayout,
)]
#[type_name("icrflow.Header.v8")]
#[repr(C)]
pub struct Header {
    /// [`SCHEMA_VERSION`] of the sender.
    pub schema: u32,
    /// [`Kind`] as `u32`.
    pub kind: u32,
    /// Sequence number of this message from its publisher: strictly increasing, never 0 (the
    /// pipeline's nodes start at the time in microseconds, so a restart continues above).
    pub sequence: u64,
    /// When the sender produced it ([`now_ns`]).
    pub source_time_ns: u64,
    /// Sequence number of the input message it was computed from (0: none).
    pub input_sequence: u64,
    /// Source time of the plant measurement at the start of the chain that led to this
    /// message (end-to-end latency = now - origin).
    pub origin_time_ns: u64,
    /// When each process along that chain took its input off the bus and published its
    /// output, for the per-stage latency ([`Trace`]).
    pub trace: Trace,
}

/// Most timestamps a [`Trace`] holds: the measurement and three processing stages after it.
pub const TRACE_STAMPS: usize = 7;

/// The timestamps ([`now_ns`]) of a message chain, oldest first: the origin's publication,
/// then for every process after it the time it took its input off the bus and the time it
/// published. A hand command caused by a joint measurement carries `[measured, estimator in,
/// estimator out, wrench in, wrench out, command in, command out]`: the differences are the
/// transport hops (out to in) and the computations (in to out). Stamps beyond
/// [`TRACE_STAMPS`] are dropped (`len` stays at the limit).
#[derive(
    Debug,
    Clone,
    Copy,
    PartialEq,
    Eq,
    Default,
    ZeroCopySend,
    FromBytes,
    IntoBytes,
    Immutable,
    KnownLayout,
)]
#[type_name("icrflow.Trace.v8")]
#[repr(C)]
pub struct Trace {
    /// The stamps (the first `len`).
    pub stamps: [u64; TRACE_STAMPS],
    /// How many are set.
    pub len: u32,
    /// Padding (zero).
    pub reserved: u32,
}

impl Trace {
    /// Appends a stamp (dropped when full).
    pub fn push(&mut self, t: u64) {
        if let Some(slot) = self.stamps.get_mut(self.len as usize) {
            *slot = t;
            self.len += 1;
        }
    }

    /// The stamps set.
    pub fn as_slice(&self) -> &[u64] {
        &self.stamps[..(self.len as usize).min(TRACE_STAMPS)]
    }
}

/// Why a header is refused.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum HeaderError {
    /// Another schema version.
    #[error("schema version {got}, expected {expected}")]
    Schema {
        /// The message's version.
        got: u32,
        /// Ours.
        expected: u32,
    },
    /// Another kind of message than the topic carries.
    #[error("message kind {got}, expected {expected}")]
    Kind {
        /// The message's kind.
        got: u32,
        /// The topic's.
        expected: u32,
    },
    /// Sequence 0, or not above the last one accepted.
    #[error("sequence {got} is not after {last}")]
    OutOfOrder {
        /// The message's sequence.
        got: u64,
        /// The last accepted.
        last: u64,
    },
    /// Older than the receiver accepts.
    #[error("stale: {age_ms:.1} ms old, limit {limit_ms:.1} ms")]
    Stale {
        /// Age (ms).
        age_ms: f64,
        /// Limit (ms).
        limit_ms: f64,
    },
}

impl Header {
    /// A header for a new message.
    pub fn new(kind: Kind, sequence: u64, input_sequence: u64, origin_time_ns: u64) -> Self {
        Self {
            schema: SCHEMA_VERSION,
            kind: kind as u32,
            sequence,
            source_time_ns: now_ns(),
            input_sequence,
            origin_time_ns,
            trace: Trace::default(),
        }
    }

    /// A header for a message computed from `input`, which this process took off the bus at
    /// `received_ns`: the input's sequence, origin and trace (with `received_ns` appended).
    pub fn after(kind: Kind, sequence: u64, input: &Header, received_ns: u64) -> Self {
        let mut trace = input.trace;
        trace.push(received_ns);
        Self {
            input_sequence: input.sequence,
            origin_time_ns: if input.origin_time_ns > 0 {
                input.origin_time_ns
            } else {
                input.source_time_ns
            },
            trace,
            ..Self::new(kind, sequence, 0, 0)
        }
    }

    /// Marks the message as published now: its source time, appended to its trace. Called by
    /// the bus when sending ([`Message`]), so that the source time is the publication time.
    pub fn stamp(&mut self) {
        self.source_time_ns = now_ns();
        self.trace.push(self.source_time_ns);
    }

    /// Checks the schema version and kind.
    pub fn check(&self, kind: Kind) -> Result<(), HeaderError> {
        if self.schema != SCHEMA_VERSION {
            return Err(HeaderError::Schema {
                got: self.schema,
                expected: SCHEMA_VERSION,
            });
        }
        if self.kind != kind as u32 {
            return Err(HeaderError::Kind {
                got: self.kind,
                expected: kind as u32,
            });
        }
        Ok(())
    }

    /// Checks schema, kind, order after `last` (the last accepted sequence) and age against
    /// `max_age_ns` at `now_ns`.
    pub fn check_fresh(
        &self,
        kind: Kind,
        last: u64,
        now_ns: u64,
        max_age_ns: u64,
    ) -> Result<(), HeaderError> {
        self.check(kind)?;
        if self.sequence == 0 || self.sequence <= last {
            return Err(HeaderError::OutOfOrder {
                got: self.sequence,
                last,
            });
        }
        let age = now_ns.saturating_sub(self.source_time_ns);
        if age > max_age_ns {
            return Err(HeaderError::Stale {
                age_ms: age as f64 * 1e-6,
                limit_ms: max_age_ns as f64 * 1e-6,
            });
        }
        Ok(())
    }
}

/// A message type: a [`Header`] first, then its fields (for the fixed user header of a slice
/// topic, the header of the whole sample).
pub trait Message {
    /// The kind its header carries.
    const KIND: Kind;
    /// The header.
    fn header(&self) -> &Header;
    /// The header, for the bus to [`Header::stamp`] at publication.
    fn header_mut(&mut self) -> &mut Header;
}

macro_rules! messages {
    ($($t:ident => $kind:ident),*) => {$(
        impl Message for $t {
            const KIND: Kind = Kind::$kind;
            fn header(&self) -> &Header {
                &self.header
            }
            fn header_mut(&mut self) -> &mut Header {
                &mut self.header
            }
        }
    )*};
}

messages!(
    JointState => JointState,
    ObjectPose => ObjectPose,
    GraspState => GraspState,
    WrenchSpaceHeader => WrenchSpace,
    PlanStepHeader => PlanStep,
    HandCommand => HandCommand,
    NodeHealth => NodeHealth,
    PlantTruth => PlantTruth
);

/// Joint encoder readings of the hand.
#[derive(
    Debug,
    Clone,
    Copy,
    PartialEq,
    Default,
    ZeroCopySend,
    FromBytes,
    IntoBytes,
    Immutable,
    KnownLayout,
)]
#[type_name("icrflow.JointState.v8")]
#[repr(C)]
pub struct JointState {
    /// Header ([`Kind::JointState`]).
    pub header: Header,
    /// Fingers in use.
    pub finger_count: u32,
    /// Padding (zero).
    pub reserved: u32,
    /// Finger number of each slot.
    pub finger_ids: [u32; MAX_FINGERS],
    /// Joints of each finger.
    pub joint_counts: [u32; MAX_FINGERS],
    /// Joint angles (rad).
    pub positions: [[f64; MAX_JOINTS]; MAX_FINGERS],
}

impl JointState {
    /// The slot of finger `finger` among the message's first `finger_count` (at most
    /// [`MAX_FINGERS`]: a count beyond it, malformed, is read as that many).
    pub fn slot_of(&self, finger: u32) -> Option<usize> {
        slot_of(&self.finger_ids, self.finger_count, finger)
    }
}

/// The slot of `finger` in `ids`, of which the first `count` are in use (at most all).
fn slot_of(ids: &[u32; MAX_FINGERS], count: u32, finger: u32) -> Option<usize> {
    ids.iter().take(count as usize).position(|&id| id == finger)
}

/// An object-pose measurement (e.g. from vision): noisy, delayed, lower rate.
#[derive(
    Debug,
    Clone,
    Copy,
    PartialEq,
    Default,
    ZeroCopySend,
    FromBytes,
    IntoBytes,
    Immutable,
    KnownLayout,
)]
#[type_name("icrflow.ObjectPose.v8")]
#[repr(C)]
pub struct ObjectPose {
    /// Header ([`Kind::ObjectPose`]); `source_time_ns` is when it was published.
    pub header: Header,
    /// When the measured scene was captured ([`now_ns`]); earlier than the header's time by
    /// the measurement's latency.
    pub captured_time_ns: u64,
    /// Object centre of mass in the hand frame (m).
    pub position: [f64; 3],
    /// Object orientation, unit quaternion `[w, x, y, z]`.
    pub orientation: [f64; 4],
}

/// What a simulated plant knows to be true, for the run's summary, the tests and the
/// visualizer: never read by the estimator, which sees only the measurements.
#[derive(
    Debug,
    Clone,
    Copy,
    PartialEq,
    Default,
    ZeroCopySend,
    FromBytes,
    IntoBytes,
    Immutable,
    KnownLayout,
)]
#[type_name("icrflow.PlantTruth.v8")]
#[repr(C)]
pub struct PlantTruth {
    /// Header ([`Kind::PlantTruth`]); `source_time_ns` is the time of the state it gives.
    pub header: Header,
    /// Object centre of mass in the hand frame (m).
    pub position: [f64; 3],
    /// Object orientation, unit quaternion `[w, x, y, z]`.
    pub orientation: [f64; 4],
    /// Object rotation about the vertical axis since the start (rad, unwrapped).
    pub rotation: f64,
    /// Fingers in use.
    pub finger_count: u32,
    /// The plant ([`PlantEngine`] as `u32`).
    pub engine: u32,
    /// Finger number of each slot.
    pub finger_ids: [u32; MAX_FINGERS],
    /// 1 where the finger of the slot is in contact with the object, 0 not.
    pub in_contact: [u32; MAX_FINGERS],
    /// Where each finger in contact touches the object (hand frame, m; zero when not in
    /// contact).
    pub contact_points: [[f64; 3]; MAX_FINGERS],
    /// The object's outward unit normal there (hand frame).
    pub contact_normals: [[f64; 3]; MAX_FINGERS],
    /// The force each fingertip applies to the object (hand frame, N; zero from a plant
    /// that simulates no forces).
    pub contact_forces: [[f64; 3]; MAX_FINGERS],
    /// Tangential slip speed at each contact (m/s; 0 rolling).
    pub slip_speeds: [f64; MAX_FINGERS],
    /// The plant's integration steps since the previous truth (0 from a plant that counts
    /// none: the kinematic plant).
    pub physics_steps: u32,
    /// Of them, the steps in which a link (not a fingertip) touched the object.
    pub link_object_steps: u32,
    /// Of them, the steps in which two fingers touched each other.
    pub finger_touch_steps: u32,
    /// Slots (bit `k`: the finger of slot `k`) a link of which touched the object in any of
    /// them.
    pub links_on_object: u32,
    /// Slots of the fingers that touched another finger in any of them.
    pub fingers_touching: u32,
    /// Padding (zero).
    pub reserved: u32,
}

/// Which plant a [`PlantTruth`] comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u32)]
pub enum PlantEngine {
    /// The kinematic plant: contacts from the rolling kinematics, no forces.
    Kinematic = 0,
    /// MuJoCo.
    Mujoco = 1,
}

/// One finger's contact in a [`GraspState`].
#[derive(
    Debug,
    Clone,
    Copy,
    PartialEq,
    Default,
    ZeroCopySend,
    FromBytes,
    IntoBytes,
    Immutable,
    KnownLayout,
)]
#[type_name("icrflow.FingerContact.v8")]
#[repr(C)]
pub struct FingerContact {
    /// Finger number.
    pub finger: u32,
    /// 1 in contact, 0 not.
    pub in_contact: u32,
    /// Candidate index of the contact point (when in contact).
    pub candidate: u32,
    /// Padding (zero).
    pub reserved: u32,
    /// Body-frame contact point (m).
    pub point: [f64; 3],
    /// Body-frame outward normal.
    pub normal: [f64; 3],
    /// Distance between the fingertip (forward kinematics) and the object surface (m).
    pub residual: f64,
}

/// The estimated object pose, contact state and hand joints.
#[derive(
    Debug,
    Clone,
    Copy,
    PartialEq,
    Default,
    ZeroCopySend,
    FromBytes,
    IntoBytes,
    Immutable,
    KnownLayout,
)]
#[type_name("icrflow.GraspState.v8")]
#[repr(C)]
pub struct GraspState {
    /// Header ([`Kind::GraspState`]).
    pub header: Header,
    /// Object centre of mass in the hand frame (m).
    pub position: [f64; 3],
    /// Object orientation `[w, x, y, z]`.
    pub orientation: [f64; 4],
    /// Object rotation about the vertical axis since the start (rad, unwrapped).
    pub rotation: f64,
    /// Root-mean-square fit residual of the fingertips on the object (m): the contact
    /// consistency between the fingertips' forward kinematics and the object model at the
    /// estimated pose.
    pub residual: f64,
    /// The pose innovation (rad): how far the estimate was off the object-pose measurements,
    /// each compared with the estimate as it was when the measured scene was captured,
    /// smoothed over the last few measurements (an exponential average, so that the
    /// measurements' noise averages out and a bias stays). 0 before the first measurement.
    pub pose_innovation: f64,
    /// When the newest object-pose measurement the estimate has fused was captured
    /// ([`now_ns`]; 0: none yet).
    pub pose_captured_ns: u64,
    /// Fingers in use.
    pub finger_count: u32,
    /// Padding (zero).
    pub reserved: u32,
    /// Each finger's contact.
    pub fingers: [FingerContact; MAX_FINGERS],
    /// Each finger's joint angles (rad), in the slots of `fingers`: the hand's state the
    /// contacts were estimated from.
    pub joints: [[f64; MAX_JOINTS]; MAX_FINGERS],
}

/// User header of the wrench-space topic; the payload is a slice of [`Facet`].
#[derive(
    Debug,
    Clone,
    Copy,
    PartialEq,
    Default,
    ZeroCopySend,
    FromBytes,
    IntoBytes,
    Immutable,
    KnownLayout,
)]
#[type_name("icrflow.WrenchSpaceHeader.v8")]
#[repr(C)]
pub struct WrenchSpaceHeader {
    /// Header ([`Kind::WrenchSpace`]).
    pub header: Header,
    /// 1 if force closure.
    pub force_closure: u32,
    /// Wrench-space dimension (3 planar, 6 spatial).
    pub dim: u32,
    /// The quality alpha* (0 unless force closure).
    pub quality: f64,
    /// Ferrari-Canny epsilon.
    pub epsilon: f64,
    /// The margin alpha the pipeline keeps.
    pub alpha: f64,
}

/// One facet `normal . w <= offset` of the grasp wrench space's hull.
#[derive(
    Debug,
    Clone,
    Copy,
    PartialEq,
    Default,
    ZeroCopySend,
    FromBytes,
    IntoBytes,
    Immutable,
    KnownLayout,
)]
#[type_name("icrflow.Facet.v8")]
#[repr(C)]
pub struct Facet {
    /// Unit outward normal (the first `dim` components).
    pub normal: [f64; 6],
    /// Offset.
    pub offset: f64,
}

/// Planner phases in [`PlanStepHeader::phase`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u32)]
pub enum PlanPhase {
    /// The initial grasp.
    Start = 0,
    /// Rolling.
    Rolling = 1,
    /// A free finger attaches.
    Attach = 2,
    /// The finger at its limit detaches.
    Detach = 3,
    /// The goal is reached; hold.
    Done = 4,
}

impl PlanPhase {
    /// The name of phase `phase` as [`PlanStepHeader::phase`] carries it (`"start"`,
    /// `"rolling"`, `"attach"`, `"detach"`, `"done"`; `"unknown"` for any other number).
    pub const fn name_of(phase: u32) -> &'static str {
        match phase {
            0 => "start",
            1 => "rolling",
            2 => "attach",
            3 => "detach",
            4 => "done",
            _ => "unknown",
        }
    }
}

/// One finger's target in a [`PlanStepHeader`].
#[derive(
    Debug,
    Clone,
    Copy,
    PartialEq,
    Default,
    ZeroCopySend,
    FromBytes,
    IntoBytes,
    Immutable,
    KnownLayout,
)]
#[type_name("icrflow.FingerTarget.v8")]
#[repr(C)]
pub struct FingerTarget {
    /// Finger number.
    pub finger: u32,
    /// 1 in contact, 0 free.
    pub in_contact: u32,
    /// Candidate index of the target contact.
    pub candidate: u32,
    /// Joints used in `joints`.
    pub joint_count: u32,
    /// Body-frame target contact point (m).
    pub point: [f64; 3],
    /// Cap angle of the contact on the fingertip (rad).
    pub cap_angle: f64,
    /// Joint targets (rad).
    pub joints: [f64; MAX_JOINTS],
}

/// User header of the plan-step topic; the payload is the ICR regions, candidate indices of
/// every finger in slot order (`region_lengths` long each), then, in an attach step, the
/// rendezvous region (`rendezvous_length` long).
#[derive(
    Debug,
    Clone,
    Copy,
    PartialEq,
    Default,
    ZeroCopySend,
    FromBytes,
    IntoBytes,
    Immutable,
    KnownLayout,
)]
#[type_name("icrflow.PlanStepHeader.v8")]
#[repr(C)]
pub struct PlanStepHeader {
    /// Header ([`Kind::PlanStep`]).
    pub header: Header,
    /// [`PlanPhase`] as `u32`.
    pub phase: u32,
    /// Fingers in use.
    pub finger_count: u32,
    /// Planned step number.
    pub step: u64,
    /// Target object rotation (rad).
    pub rotation: f64,
    /// Quality alpha* of the planned grasp.
    pub quality: f64,
    /// Each finger's target.
    pub targets: [FingerTarget; MAX_FINGERS],
    /// Length of each finger's region in the payload.
    pub region_lengths: [u32; MAX_FINGERS],
    /// In an attach step, the finger that attaches (0 otherwise).
    pub rendezvous_finger: u32,
    /// In an attach step, the length of the rendezvous region (the candidates where the
    /// attaching finger keeps the grasp's quality at or above alpha, among which its contact
    /// was chosen), after the fingers' regions in the payload; 0 otherwise.
    pub rendezvous_length: u32,
    /// [`PlanWait`] as `u32`: whether the hand waits for the planner at this target.
    pub planning: u32,
    /// How long the hand has waited for the planner at this target so far (ms; 0 when
    /// `planning` is [`PlanWait::None`]).
    pub planning_ms: u32,
}

/// What the hand waits for the planner for, in [`PlanStepHeader::planning`]: the planner node
/// plans in a worker thread and hands the plan on a part at a time, so the target it
/// publishes may be the last one planned so far.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u32)]
pub enum PlanWait {
    /// Nothing: the target is the plan's, with more after it (or the last of a plan made).
    None = 0,
    /// The target is the last one planned so far: the hand tracks it (and stays there) while
    /// the rest of the plan is made.
    Ahead = 1,
    /// The object stopped off the plan: the hand holds (the command node's gate) while a plan
    /// is made again from the estimate.
    Again = 2,
}

impl PlanWait {
    /// The name of wait `w` as [`PlanStepHeader::planning`] carries it (`""`, `"ahead"`,
    /// `"again"`; `"unknown"` for any other number).
    pub const fn name_of(w: u32) -> &'static str {
        match w {
            0 => "",
            1 => "ahead",
            2 => "again",
            _ => "unknown",
        }
    }
}

/// Hand command modes in [`HandCommand::mode`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u32)]
pub enum CommandMode {
    /// Track the joint and force targets.
    Track = 0,
    /// Hold the last safe grasp (see `reason`).
    Hold = 1,
    /// Below the margin, hold the grasp's fingers where the last command that moved the hand
    /// put them and move the finger the plan step attaches onto the object (see `reason`): adding a
    /// contact can only raise the grasp's quality (the command node's
    /// `Gate::attach_below_margin`). A plant follows it as it follows `Track`.
    Attach = 2,
}

impl CommandMode {
    /// Whether a command of mode `mode` (as in [`HandCommand::mode`]) moves the hand to its
    /// targets: tracking, or attaching below the margin; a hold (or an unknown mode) keeps
    /// the hand where the last such command put it.
    pub fn moves(mode: u32) -> bool {
        mode == Self::Track as u32 || mode == Self::Attach as u32
    }
}

/// A command to the hand.
#[derive(
    Debug, Clone, Copy, PartialEq, ZeroCopySend, FromBytes, IntoBytes, Immutable, KnownLayout,
)]
#[type_name("icrflow.HandCommand.v8")]
#[repr(C)]
pub struct HandCommand {
    /// Header ([`Kind::HandCommand`]).
    pub header: Header,
    /// [`CommandMode`] as `u32`.
    pub mode: u32,
    /// Fingers in use.
    pub finger_count: u32,
    /// Finger number of each slot.
    pub finger_ids: [u32; MAX_FINGERS],
    /// Joint targets (rad).
    pub joint_targets: [[f64; MAX_JOINTS]; MAX_FINGERS],
    /// Fingertip force targets in the hand frame (N); zero for a free finger.
    pub forces: [[f64; 3]; MAX_FINGERS],
    /// Quality alpha* of the grasp (from the wrench space) the command was computed with; 0
    /// when holding.
    pub quality: f64,
    /// Why the hand holds, or attaches below the margin (UTF-8, zero-padded; empty when
    /// tracking).
    pub reason: [u8; TEXT_BYTES],
}

impl HandCommand {
    /// Whether the command presses finger `finger` on the object: it is among the command's
    /// fingers with a force target (a free, approaching or leaving finger has none). Only a
    /// pressing finger rolls the object (the plant's rule, and the estimator's).
    pub fn presses(&self, finger: u32) -> bool {
        self.slot_of(finger).is_some_and(|k| self.presses_slot(k))
    }

    /// Whether the command gives the finger of its slot `k` a force target (`false` beyond
    /// [`MAX_FINGERS`]).
    pub fn presses_slot(&self, k: usize) -> bool {
        self.forces
            .get(k)
            .is_some_and(|f| f.iter().any(|x| *x != 0.0))
    }

    /// The slot of finger `finger` among the command's first `finger_count` (at most
    /// [`MAX_FINGERS`]).
    pub fn slot_of(&self, finger: u32) -> Option<usize> {
        slot_of(&self.finger_ids, self.finger_count, finger)
    }
}

impl Default for HandCommand {
    fn default() -> Self {
        Self {
            header: Header::default(),
            mode: CommandMode::Hold as u32,
            finger_count: 0,
            finger_ids: [0; MAX_FINGERS],
            joint_targets: [[0.0; MAX_JOINTS]; MAX_FINGERS],
            forces: [[0.0; 3]; MAX_FINGERS],
            quality: 0.0,
            reason: [0; TEXT_BYTES],
        }
    }
}

/// Node states in [`NodeHealth::state`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u32)]
pub enum NodeState {
    /// Starting up.
    Starting = 0,
    /// Working normally.
    Running = 1,
    /// Working, but refusing some input (see `message`).
    Degraded = 2,
    /// Shutting down.
    Stopping = 3,
}

/// A node's periodic health report.
#[derive(
    Debug, Clone, Copy, PartialEq, ZeroCopySend, FromBytes, IntoBytes, Immutable, KnownLayout,
)]
#[type_name("icrflow.NodeHealth.v8")]
#[repr(C)]
pub struct NodeHealth {
    /// Header ([`Kind::NodeHealth`]).
    pub header: Header,
    /// Node name (UTF-8, zero-padded).
    pub node: [u8; NAME_BYTES],
    /// [`NodeState`] as `u32`.
    pub state: u32,
    /// Process id.
    pub pid: u32,
    /// Messages processed since start.
    pub processed: u64,
    /// Messages refused since start.
    pub refused: u64,
    /// Heap allocations (and reallocations) of the process since it started.
    pub allocations: u64,
    /// Last problem (UTF-8, zero-padded).
    pub message: [u8; TEXT_BYTES],
}

impl Default for NodeHealth {
    fn default() -> Self {
        Self {
            header: Header::default(),
            node: [0; NAME_BYTES],
            state: NodeState::Starting as u32,
            pid: 0,
            processed: 0,
            refused: 0,
            allocations: 0,
            message: [0; TEXT_BYTES],
        }
    }
}

/// Copies `text` into a zero-padded fixed buffer, cut at a character boundary.
pub fn write_text<const N: usize>(out: &mut [u8; N], text: &str) {
    *out = [0; N];
    let mut end = text.len().min(N);
    while !text.is_char_boundary(end) {
        end -= 1;
    }
    out[..end].copy_from_slice(&text.as_bytes()[..end]);
}

/// The text of a zero-padded buffer (lossy on invalid UTF-8).
pub fn read_text(buf: &[u8]) -> String {
    let end = buf.iter().position(|b| *b == 0).unwrap_or(buf.len());
    String::from_utf8_lossy(&buf[..end]).into_owned()
}

/// The most facets a wrench-space message carries (the slice's capacity).
pub const MAX_FACETS: usize = 4096;

/// The most region points a plan-step message carries (the slice's capacity).
pub const MAX_REGION_POINTS: usize = 4096;

/// The pipeline's topology, one place for all: which topics there are and what each carries
/// ([`Topic`], [`SliceTopic`]: a topic opened with another message type does not compile),
/// the nodes ([`NodeRole`]), and who publishes and reads what. Each topic's service is prefixed
/// by the rig name: `icrflow/<rig>/<topic>`, the same key expression the Zenoh bridge uses.
pub mod topics {
    use std::marker::PhantomData;

    use crate::{
        GraspState, HandCommand, JointState, MAX_FACETS, MAX_REGION_POINTS, NodeHealth, ObjectPose,
        PlanStepHeader, PlantTruth, WrenchSpaceHeader,
    };

    /// A topic: its name, and what it carries. Shown (`{}` and `{:?}`) by its name.
    #[derive(Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
    #[non_exhaustive]
    pub enum TopicId {
        /// Joint encoder readings ([`JointState`]).
        JointState,
        /// Object-pose measurements ([`ObjectPose`]).
        ObjectPose,
        /// Estimated grasp state ([`GraspState`]).
        GraspState,
        /// Wrench space ([`WrenchSpaceHeader`] + facets).
        WrenchSpace,
        /// Plan steps ([`PlanStepHeader`] + regions).
        PlanStep,
        /// Hand commands ([`HandCommand`]).
        HandCommand,
        /// Node health ([`NodeHealth`]).
        NodeHealth,
        /// The simulated plant's true state ([`PlantTruth`]): for the run's summary, the
        /// tests and the visualizer; no node of the loop reads it, and it does not cross hosts.
        PlantTruth,
    }

    impl TopicId {
        /// Its name in service names and key expressions.
        pub const fn name(self) -> &'static str {
            match self {
                Self::JointState => "joint_state",
                Self::ObjectPose => "object_pose",
                Self::GraspState => "grasp_state",
                Self::WrenchSpace => "wrench_space",
                Self::PlanStep => "plan_step",
                Self::HandCommand => "hand_command",
                Self::NodeHealth => "node_health",
                Self::PlantTruth => "plant_truth",
            }
        }

        /// The topic named `name`, if any.
        pub fn from_name(name: &str) -> Option<Self> {
            ALL.into_iter()
                .chain([Self::PlantTruth])
                .find(|t| t.name() == name)
        }
    }

    impl std::fmt::Display for TopicId {
        fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
            f.write_str(self.name())
        }
    }

    impl std::fmt::Debug for TopicId {
        fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
            write!(f, "{:?}", self.name())
        }
    }

    /// A topic carrying messages `T`.
    #[derive(Debug)]
    pub struct Topic<T> {
        /// Which topic.
        pub id: TopicId,
        message: PhantomData<fn() -> T>,
    }

    impl<T> Clone for Topic<T> {
        fn clone(&self) -> Self {
            *self
        }
    }
    impl<T> Copy for Topic<T> {}

    impl<T> Topic<T> {
        const fn new(id: TopicId) -> Self {
            Self {
                id,
                message: PhantomData,
            }
        }

        /// Its name.
        pub const fn name(self) -> &'static str {
            self.id.name()
        }
    }

    /// A topic carrying a header `H` and up to `max_len` items `T` per message.
    #[derive(Debug)]
    pub struct SliceTopic<H, T> {
        /// Which topic.
        pub id: TopicId,
        /// The most items a message carries.
        pub max_len: usize,
        message: PhantomData<fn() -> (H, T)>,
    }

    impl<H, T> Clone for SliceTopic<H, T> {
        fn clone(&self) -> Self {
            *self
        }
    }
    impl<H, T> Copy for SliceTopic<H, T> {}

    impl<H, T> SliceTopic<H, T> {
        const fn new(id: TopicId, max_len: usize) -> Self {
            Self {
                id,
                max_len,
                message: PhantomData,
            }
        }

        /// Its name.
        pub const fn name(self) -> &'static str {
            self.id.name()
        }
    }

    /// Joint encoder readings.
    pub const JOINT_STATE: Topic<JointState> = Topic::new(TopicId::JointState);
    /// Object-pose measurements.
    pub const OBJECT_POSE: Topic<ObjectPose> = Topic::new(TopicId::ObjectPose);
    /// Estimated grasp state.
    pub const GRASP_STATE: Topic<GraspState> = Topic::new(TopicId::GraspState);
    /// Wrench space: the header and the hull's facets.
    pub const WRENCH_SPACE: SliceTopic<WrenchSpaceHeader, crate::Facet> =
        SliceTopic::new(TopicId::WrenchSpace, MAX_FACETS);
    /// Plan steps: the header and the regions' candidate indices.
    pub const PLAN_STEP: SliceTopic<PlanStepHeader, u32> =
        SliceTopic::new(TopicId::PlanStep, MAX_REGION_POINTS);
    /// Hand commands.
    pub const HAND_COMMAND: Topic<HandCommand> = Topic::new(TopicId::HandCommand);
    /// Node health.
    pub const NODE_HEALTH: Topic<NodeHealth> = Topic::new(TopicId::NodeHealth);
    /// The simulated plant's true state (see [`TopicId::PlantTruth`]).
    pub const PLANT_TRUTH: Topic<PlantTruth> = Topic::new(TopicId::PlantTruth);

    /// Every topic the bridge may carry (all but the plant's truth).
    pub const ALL: [TopicId; 7] = [
        TopicId::JointState,
        TopicId::ObjectPose,
        TopicId::GraspState,
        TopicId::WrenchSpace,
        TopicId::PlanStep,
        TopicId::HandCommand,
        TopicId::NodeHealth,
    ];

    /// A process of the pipeline.
    #[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
    #[non_exhaustive]
    pub enum NodeRole {
        /// The simulated hand and object.
        Plant,
        /// The state estimator.
        Estimator,
        /// The wrench-space node.
        Wrench,
        /// The ICR planner.
        Planner,
        /// The hand command node.
        Command,
        /// The Zenoh bridge.
        Bridge,
        /// The Rerun visualizer.
        Visualizer,
    }

    impl NodeRole {
        /// The loop's nodes, in the order they start (`icrflow_scenario::NODES`, the config's
        /// names, is the same list).
        pub const LOOP: [NodeRole; 5] = [
            Self::Plant,
            Self::Estimator,
            Self::Wrench,
            Self::Planner,
            Self::Command,
        ];

        /// Its name: in the config, in health reports, and as `icrflow-<name>`, its binary.
        pub const fn name(self) -> &'static str {
            match self {
                Self::Plant => "plant",
                Self::Estimator => "estimator",
                Self::Wrench => "wrench",
                Self::Planner => "planner",
                Self::Command => "command",
                Self::Bridge => "bridge",
                Self::Visualizer => "visualizer",
            }
        }

        /// The role named `name`, if any.
        pub fn from_name(name: &str) -> Option<Self> {
            Self::LOOP
                .into_iter()
                .chain([Self::Bridge, Self::Visualizer])
                .find(|r| r.name() == name)
        }

        /// The loop topics it publishes (every node also publishes [`NODE_HEALTH`]).
        pub const fn publishes(self) -> &'static [TopicId] {
            match self {
                Self::Plant => &[TopicId::JointState, TopicId::ObjectPose],
                Self::Estimator => &[TopicId::GraspState],
                Self::Wrench => &[TopicId::WrenchSpace],
                Self::Planner => &[TopicId::PlanStep],
                Self::Command => &[TopicId::HandCommand],
                Self::Bridge | Self::Visualizer => &[],
            }
        }

        /// The loop topics it reads.
        pub const fn reads(self) -> &'static [TopicId] {
            match self {
                Self::Plant => &[TopicId::HandCommand],
                Self::Estimator => &[
                    TopicId::JointState,
                    TopicId::ObjectPose,
                    TopicId::HandCommand,
                ],
                Self::Wrench | Self::Planner => &[TopicId::GraspState],
                Self::Command => &[TopicId::PlanStep, TopicId::GraspState, TopicId::WrenchSpace],
                Self::Bridge | Self::Visualizer => &[],
            }
        }
    }

    impl std::fmt::Display for NodeRole {
        fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
            f.write_str(self.name())
        }
    }

    /// The full service name of `topic` on rig `rig`.
    pub fn service(rig: &str, topic: &str) -> String {
        format!("icrflow/{rig}/{topic}")
    }

    /// The Zenoh key expression that carries `topic` of rig `rig` between hosts, as bytes
    /// ([`crate::wire`]), beside the JSON one of monitoring ([`service`]).
    pub fn link(rig: &str, topic: TopicId) -> String {
        format!("{}{topic}", link_prefix(rig))
    }

    /// What every [`link`] key expression of rig `rig` starts with.
    pub fn link_prefix(rig: &str) -> String {
        format!("icrflow/{rig}/link/")
    }

    /// The loop topics that cross between a host running the nodes `local` and the host(s)
    /// running the others.
    #[derive(Debug, Clone, PartialEq, Eq, Default)]
    pub struct Links {
        /// Published here, read by a node elsewhere.
        pub export: Vec<TopicId>,
        /// Read here, published by a node elsewhere.
        pub import: Vec<TopicId>,
    }

    /// The links of a host running `local` (node names as in `icrflow_scenario::NODES`, the
    /// config's list; other names are ignored).
    pub fn links(local: &[impl AsRef<str>]) -> Links {
        let here = |node: NodeRole| local.iter().any(|n| n.as_ref() == node.name());
        let mut links = Links::default();
        for topic in ALL {
            let (mut published, mut read) = ([false; 2], [false; 2]);
            for node in NodeRole::LOOP {
                let side = usize::from(!here(node));
                published[side] |= node.publishes().contains(&topic);
                read[side] |= node.reads().contains(&topic);
            }
            if published[0] && read[1] {
                links.export.push(topic);
            }
            if read[0] && published[1] {
                links.import.push(topic);
            }
        }
        links
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A finger's slot is found among the fingers in use only; a malformed count over
    /// MAX_FINGERS reads as MAX_FINGERS (no index out of bounds); a command presses a finger
    /// with a force target only.
    #[test]
    fn a_finger_s_slot_and_whether_it_presses() {
        let mut m = JointState {
            finger_count: 2,
            ..Default::default()
        };
        m.finger_ids[..3].copy_from_slice(&[4, 1, 2]);
        assert_eq!(m.slot_of(1), Some(1));
        assert_eq!(m.slot_of(2), None, "slot 2 is not in use");
        m.finger_count = u32::MAX;
        assert_eq!(m.slot_of(2), Some(2));
        assert_eq!(m.slot_of(9), None);
        let mut c = HandCommand {
            finger_count: 2,
            ..Default::default()
        };
        c.finger_ids[..2].copy_from_slice(&[4, 1]);
        c.forces[1] = [0.0, 0.0, -1.5];
        assert!(c.presses(1));
        assert!(!c.presses(4), "no force target");
        assert!(!c.presses(2), "not in the command");
        c.finger_count = 1000;
        assert!(!c.presses(7));
        assert!(c.presses_slot(1) && !c.presses_slot(0));
        assert!(!c.presses_slot(MAX_FINGERS), "beyond the slots");
    }

    #[test]
    fn header_checks_schema_kind_order_and_age() {
        let h = Header::new(Kind::JointState, 5, 0, 0);
        assert!(h.check(Kind::JointState).is_ok());
        assert!(matches!(
            h.check(Kind::GraspState),
            Err(HeaderError::Kind { .. })
        ));
        let mut old = h;
        old.schema = SCHEMA_VERSION + 1;
        assert!(matches!(
            old.check(Kind::JointState),
            Err(HeaderError::Schema { .. })
        ));
        let now = h.source_time_ns;
        assert!(h.check_fresh(Kind::JointState, 4, now, 1_000_000).is_ok());
        assert!(matches!(
            h.check_fresh(Kind::JointState, 5, now, 1_000_000),
            Err(HeaderError::OutOfOrder { .. })
        ));
        assert!(matches!(
            h.check_fresh(Kind::JointState, 4, now + 2_000_000, 1_000_000),
            Err(HeaderError::Stale { .. })
        ));
    }

    #[test]
    fn a_chain_of_messages_carries_its_origin_and_every_stage_in_its_trace() {
        let mut joint = Header::new(Kind::JointState, 7, 0, 0);
        joint.stamp();
        let measured = joint.source_time_ns;
        let mut grasp = Header::after(Kind::GraspState, 3, &joint, measured + 10);
        grasp.stamp();
        assert_eq!(grasp.input_sequence, 7);
        assert_eq!(grasp.origin_time_ns, measured);
        let mut wrench = Header::after(Kind::WrenchSpace, 9, &grasp, grasp.source_time_ns + 10);
        wrench.stamp();
        let mut command = Header::after(Kind::HandCommand, 2, &wrench, wrench.source_time_ns + 1);
        command.stamp();
        let t = command.trace.as_slice();
        assert_eq!(t.len(), TRACE_STAMPS);
        assert_eq!(t[0], measured);
        assert_eq!(t[1], measured + 10);
        assert_eq!(t[6], command.source_time_ns);
        assert!(t.windows(2).all(|w| w[0] <= w[1]), "{t:?}");
        assert_eq!(command.origin_time_ns, measured);
        // A longer chain keeps the first stamps.
        let mut more = Header::after(Kind::HandCommand, 3, &command, command.source_time_ns);
        more.stamp();
        assert_eq!(more.trace, command.trace);
    }

    #[test]
    fn text_round_trips_and_cuts_at_a_character_boundary() {
        let mut buf = [0u8; 8];
        write_text(&mut buf, "held: né");
        assert_eq!(read_text(&buf), "held: n");
        write_text(&mut buf, "ok");
        assert_eq!(read_text(&buf), "ok");
    }

    #[test]
    fn type_names_carry_the_schema_version() {
        assert_eq!(type_name::<JointState>(), "icrflow.JointState.v8");
        assert_eq!(type_name::<HandCommand>(), "icrflow.HandCommand.v8");
        assert_eq!(type_name::<PlanStepHeader>(), "icrflow.PlanStepHeader.v8");
        assert_eq!(type_name::<Trace>(), "icrflow.Trace.v8");
        assert_eq!(type_name::<PlantTruth>(), "icrflow.PlantTruth.v8");
        assert_eq!(SCHEMA_VERSION, 8);
    }

    #[test]
    fn a_split_pipeline_links_exactly_the_topics_that_cross_hosts() {
        use topics::TopicId::*;
        use topics::*;
        let robot = links(&["plant", "estimator", "command"]);
        assert_eq!(robot.export, [GraspState]);
        assert_eq!(robot.import, [WrenchSpace, PlanStep]);
        let workstation = links(&["wrench", "planner"]);
        assert_eq!(workstation.export, [WrenchSpace, PlanStep]);
        assert_eq!(workstation.import, [GraspState]);
        // One host: nothing crosses.
        assert_eq!(links(&icrflow_scenario::NODES), Links::default());
        // The plant alone: commands in, measurements out.
        let plant = links(&["plant"]);
        assert_eq!(plant.export, [JointState, ObjectPose]);
        assert_eq!(plant.import, [HandCommand]);
        // The estimator alone: the measurements and which fingers the commands press in.
        let estimator = links(&["estimator"]);
        assert_eq!(estimator.export, [GraspState]);
        assert_eq!(estimator.import, [JointState, ObjectPose, HandCommand]);
    }

    #[test]
    fn topics_and_roles_round_trip_their_names_and_the_config_names_the_loop() {
        use topics::{NodeRole, TopicId};
        for t in topics::ALL.into_iter().chain([TopicId::PlantTruth]) {
            assert_eq!(TopicId::from_name(t.name()), Some(t));
        }
        assert_eq!(TopicId::from_name("joint"), None);
        let names: Vec<&str> = NodeRole::LOOP.iter().map(|r| r.name()).collect();
        assert_eq!(names, icrflow_scenario::NODES);
        for r in NodeRole::LOOP
            .into_iter()
            .chain([NodeRole::Bridge, NodeRole::Visualizer])
        {
            assert_eq!(NodeRole::from_name(r.name()), Some(r));
        }
        // Every loop topic has a publisher and a reader among the loop's nodes.
        for t in topics::ALL
            .into_iter()
            .filter(|t| *t != TopicId::NodeHealth)
        {
            assert!(
                NodeRole::LOOP.iter().any(|r| r.publishes().contains(&t)),
                "{t}"
            );
            assert!(NodeRole::LOOP.iter().any(|r| r.reads().contains(&t)), "{t}");
        }
    }

    #[test]
    fn plan_phase_codes_are_the_planners() {
        use icrflow_plan::planner::Phase;
        for (phase, wire) in [
            (Phase::Start, PlanPhase::Start),
            (Phase::Rolling, PlanPhase::Rolling),
            (Phase::Attach, PlanPhase::Attach),
            (Phase::Detach, PlanPhase::Detach),
        ] {
            assert_eq!(phase as u32, wire as u32);
        }
    }

    #[test]
    fn the_configs_bounds_are_the_messages_capacities() {
        assert_eq!(icrflow_scenario::bounds::MESSAGE_FINGERS, MAX_FINGERS);
        assert_eq!(icrflow_scenario::bounds::MESSAGE_JOINTS, MAX_JOINTS);
    }

    #[test]
    fn layouts_are_padding_free_where_it_matters() {
        // Fixed sizes: a change here is a schema change (bump SCHEMA_VERSION and the names).
        assert_eq!(std::mem::size_of::<Trace>(), 64);
        assert_eq!(std::mem::size_of::<Header>(), 104);
        assert_eq!(std::mem::size_of::<Facet>(), 56);
        assert_eq!(std::mem::size_of::<FingerContact>(), 72);
        assert_eq!(std::mem::size_of::<GraspState>(), 104 + 96 + 8 * 72 + 512);
        assert_eq!(
            std::mem::size_of::<PlantTruth>(),
            104 + 64 + 8 + 64 + 3 * 192 + 64 + 24
        );
        assert_eq!(std::mem::size_of::<FingerTarget>(), 112);
        assert_eq!(
            std::mem::size_of::<PlanStepHeader>(),
            104 + 32 + 8 * 112 + 8 * 4 + 16
        );
    }
}
