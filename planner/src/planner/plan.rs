//! A plan: its trajectory's steps (each finger's state, the switches) and its summary.

use icrflow_grasp::math::Real;
use serde::{Deserialize, Serialize};

/// The phase a trajectory step belongs to. Its codes (`phase as u32`) are the plan-step
/// message's `PlanPhase` codes (asserted in `icrflow-interfaces`' tests).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Phase {
    /// The initial grasp.
    Start = 0,
    /// A rolling step.
    Rolling = 1,
    /// A free finger has attached.
    Attach = 2,
    /// The finger at its limit has detached.
    Detach = 3,
}

impl Phase {
    /// Lower-case name.
    pub fn name(self) -> &'static str {
        match self {
            Phase::Start => "start",
            Phase::Rolling => "rolling",
            Phase::Attach => "attach",
            Phase::Detach => "detach",
        }
    }
}

/// One finger in one step.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FingerState {
    /// Finger number.
    pub finger: u32,
    /// Candidate index of the contact, if in contact.
    pub contact: Option<usize>,
    /// Body-frame contact point (m).
    pub point: Option<[Real; 3]>,
    /// Body-frame outward unit normal at the contact: the spatial planner's (its contacts are
    /// exact surface points); the planar planner's contacts are candidates, whose normals the
    /// grasp problem has.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub normal: Option<[Real; 3]>,
    /// The contact's angle on the section (rad, [0, 2 pi); `angle_deg` in files).
    #[serde(rename = "angle_deg", with = "crate::degrees::option")]
    pub angle: Option<Real>,
    /// Cap angle gamma of the contact on the fingertip (rad; `cap_angle_deg` in files).
    #[serde(rename = "cap_angle_deg", with = "crate::degrees::option")]
    pub cap_angle: Option<Real>,
    /// World angle of the fingertip's cap axis phi (rad; `tip_rotation_deg` in files): the
    /// fingertip's rotation.
    #[serde(rename = "tip_rotation_deg", with = "crate::degrees")]
    pub tip_rotation: Real,
    /// Fingertip centre in the hand frame (m).
    pub tip_centre: [Real; 3],
    /// Joint angles (rad; `joints_deg` in files).
    #[serde(rename = "joints_deg", with = "crate::degrees::list")]
    pub joints: Vec<Real>,
}

/// A finger switch.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Switch {
    /// The finger that could not roll on.
    pub released: u32,
    /// The free finger that took over.
    pub attached: u32,
    /// Why the released finger stopped.
    pub reason: String,
    /// The rendezvous region by the ICR zone rule (candidate indices, ascending).
    pub icr_region: Vec<usize>,
    /// The rendezvous region by the eq. (8) hyperplanes (candidate indices, ascending).
    pub lp_region: Vec<usize>,
    /// The exact region by brute force (candidate indices, ascending); the rendezvous point is
    /// chosen from it shrunk by [`Settings::region_erosion`](super::Settings::region_erosion)
    /// rings.
    pub brute_force: Vec<usize>,
    /// How many candidates the rendezvous point was chosen from: the exact region shrunk by
    /// [`Settings::region_erosion`](super::Settings::region_erosion) rings (all of it without
    /// erosion; 0 in plans written before it was recorded).
    #[serde(default)]
    pub chosen_from: usize,
    /// The chosen rendezvous candidate.
    pub rendezvous: usize,
    /// Its angle on the section (rad; `rendezvous_angle_deg` in files).
    #[serde(rename = "rendezvous_angle_deg", with = "crate::degrees::option")]
    pub rendezvous_angle: Option<Real>,
    /// Rolling steps the attached finger could make from there alone.
    pub room_steps: usize,
    /// How far the rendezvous point is ahead of the released contact along the rolling
    /// direction (rad, counter-clockwise about the object's centre, in [0, 2 pi); `ahead_deg`
    /// in files).
    #[serde(rename = "ahead_deg", with = "crate::degrees")]
    pub ahead: Real,
    /// A spatial plan's approach of the attaching finger: the joints (rad; `approach_deg` in
    /// files) of the poses it passes through from its home pose to the rendezvous point (none:
    /// straight; else a pose turned at its base but not yet curled, or curled but not yet
    /// turned, and poses with its fingertip lifted off the point along the normal, the nearest
    /// last; [`crate::spatial::LIFTS`]); each straight joint-space move, home -> these -> the
    /// contact, is checked clear of the object (its fingertip not pressing in) and of the
    /// other fingers.
    #[serde(
        rename = "approach_deg",
        default,
        skip_serializing_if = "Option::is_none",
        with = "crate::degrees::option_poses"
    )]
    pub approach: Option<Vec<Vec<Real>>>,
    /// A spatial plan's retreat of the released finger: the same poses off its last contact,
    /// passed through in reverse on its way home (rad; `retreat_deg` in files).
    #[serde(
        rename = "retreat_deg",
        default,
        skip_serializing_if = "Option::is_none",
        with = "crate::degrees::option_poses"
    )]
    pub retreat: Option<Vec<Vec<Real>>>,
}

/// One step of the trajectory.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Step {
    /// Step number from 0.
    pub step: usize,
    /// Phase.
    pub phase: Phase,
    /// Object rotation about the vertical axis (rad, counter-clockwise positive;
    /// `rotation_deg` in files).
    #[serde(rename = "rotation_deg", with = "crate::degrees")]
    pub rotation: Real,
    /// Quality alpha* of the grasp in force (recomputed).
    pub quality: Real,
    /// Every finger of the hand.
    pub fingers: Vec<FingerState>,
    /// For an attach step: the switch.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub switch: Option<Switch>,
}

impl Step {
    /// Step `step` of phase `phase` at rotation `rotation` (rad) of quality `quality`, its
    /// fingers `fingers`, not a switch.
    pub fn new(
        step: usize,
        phase: Phase,
        rotation: Real,
        quality: Real,
        fingers: Vec<FingerState>,
    ) -> Self {
        Self {
            step,
            phase,
            rotation,
            quality,
            fingers,
            switch: None,
        }
    }
}

/// Summary of a plan.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Summary {
    /// Whether the goal rotation was reached.
    pub completed: bool,
    /// Why planning stopped early, if it did.
    pub stop_reason: Option<String>,
    /// Total object rotation (rad; `rotation_deg` in files).
    #[serde(rename = "rotation_deg", with = "crate::degrees")]
    pub rotation: Real,
    /// Goal (rad; `goal_deg` in files).
    #[serde(rename = "goal_deg", with = "crate::degrees")]
    pub goal: Real,
    /// The unit axis (hand frame) the object turns about, positive by the right-hand rule:
    /// `[0, 0, 1]` for the planar planner (counter-clockwise seen from the top).
    #[serde(default = "vertical")]
    pub axis: [Real; 3],
    /// Finger switches.
    pub switches: usize,
    /// Trajectory steps (all phases; the start included).
    pub steps: usize,
    /// Rolling steps.
    pub rolling_steps: usize,
    /// Smallest quality of any grasp in force.
    pub min_quality: Real,
    /// The margin.
    pub alpha: Real,
    /// Largest rolling-relation residual (m): the planar planner's `|r_f dgamma + s|`, from
    /// forward kinematics of the planned joint angles; the spatial planner's slip of a step,
    /// the contact's travel over the object less its travel over the fingertip
    /// ([`crate::spatial::Touch::slip`]).
    pub max_rolling_residual: Real,
    /// Rendezvous candidates found by the ICR zone rule, summed over the switches.
    pub icr_region_candidates: usize,
    /// Rendezvous candidates found by the eq. (8) LP hyperplanes, summed over the switches.
    pub lp_region_candidates: usize,
    /// Rendezvous candidates of the LP region that brute force rejects (should be 0).
    pub lp_region_unsafe: usize,
    /// Rendezvous candidates found by brute force, summed over the switches.
    pub brute_force_candidates: usize,
    /// Rendezvous candidates the points were chosen from (the exact regions shrunk by
    /// [`Settings::region_erosion`](super::Settings::region_erosion)), summed over the switches; 0
    /// in plans written before it was reported.
    #[serde(default)]
    pub chosen_from_candidates: usize,
    /// The [`Settings::region_erosion`](super::Settings::region_erosion) planned with (rings of
    /// candidates); 0 in plans written before it was reported.
    #[serde(default)]
    pub region_erosion: usize,
    /// How close any finger's link comes to the object's section (mm), at the steps and along the
    /// straight joint-space moves between them ([`link_clearance`](super::link_clearance)); `None`
    /// in plans written before it was reported.
    #[serde(default)]
    pub min_link_clearance_mm: Option<Real>,
    /// The smallest squeeze reserve of any finger in contact at any step (mm, measured up to
    /// [`SQUEEZE_PROBE`]): how much further the tightest finger could press into the object along
    /// its contact normal inside its joint limits
    /// ([`Scenario::squeeze_reserve`](super::Scenario::squeeze_reserve)); `None` in plans written
    /// before it was reported.
    #[serde(default)]
    pub min_squeeze_reserve_mm: Option<Real>,
}

pub(super) fn vertical() -> [Real; 3] {
    [0.0, 0.0, 1.0]
}

/// How far the plan's summary measures the squeeze reserve (m): a reserve this large or
/// larger is reported as this.
pub const SQUEEZE_PROBE: Real = 5e-3;

/// A plan.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Plan {
    /// Summary.
    pub summary: Summary,
    /// The trajectory.
    pub steps: Vec<Step>,
}
