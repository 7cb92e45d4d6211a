//! The planner's settings and where a plan starts.

use icrflow_grasp::math::Real;

/// Relative slack on `quality >= alpha` checks (the ICR rule holds to 1e-9 relative).
pub const QUALITY_SLACK: Real = 1e-9;

/// Planner settings.
#[derive(Debug, Clone, PartialEq)]
pub struct Settings {
    /// The quality margin alpha.
    pub alpha: Real,
    /// The margin the command node's gate holds the estimated grasp to (`grasp.alpha`, at
    /// most [`Settings::alpha`], which may keep headroom over it): a plan made again from an
    /// estimated grasp that keeps less than `alpha`, but at least this, is made at this
    /// margin ([`crate::follow::replan`], [`crate::spatial::follow::replan`]).
    pub gate_alpha: Real,
    /// Total rotation to reach (rad, > 0: counter-clockwise seen from the top).
    pub goal: Real,
    /// Object rotation per rolling step (rad, > 0).
    pub step: Real,
    /// Margin kept from the edge of the fingertip cap (rad).
    pub cap_margin: Real,
    /// Smallest admissible manipulability of a finger in contact.
    pub min_manipulability: Real,
    /// How far (m) every finger in contact must be able to press further into the object along the
    /// contact's inward normal, inside its joint limits
    /// ([`Finger::reach_along`](crate::hand::Finger::reach_along)): room for a hand's controller to
    /// squeeze (0: not checked).
    pub squeeze_reserve: Real,
    /// Rings of neighbouring candidates (the candidates' adjacency) by which every ICR and
    /// every rendezvous region is shrunk before the planner picks a contact from it: a
    /// contact that a real hand makes up to that many candidates off the plan's stays inside
    /// the unshrunk region. For the ICRs of a rolling grasp this keeps the margin whatever
    /// the contacts' errors within it (the ICRs hold for every contact anywhere in its
    /// region); at a switch, for the attaching finger's error. 0: the regions as they are.
    pub region_erosion: usize,
    /// The quality every grasp of a spatial plan (each rolling step's end, each switch's
    /// attach and detach grasps) keeps with any one of its contacts moved to a candidate
    /// within [`Settings::neighbour_rings`] rings of its own (the candidates' adjacency):
    /// headroom for a hand whose estimate places a contact a few candidates off the plan's,
    /// which the command node's gate holds to `grasp.alpha`. `None`: not checked.
    pub neighbour_alpha: Option<Real>,
    /// How many rings of neighbouring candidates [`Settings::neighbour_alpha`] is checked
    /// over (at least 1).
    pub neighbour_rings: usize,
    /// Upper bound on planner steps (rolling, attach and detach together).
    pub max_steps: usize,
    /// The wall-clock time a plan may take (`plan.max_plan_s`): a plan still being made when
    /// it has run out stops there, short of its goal, and says where it was (checked before
    /// every step and between the batches of a switch search). `None`: no bound.
    pub max_plan: Option<std::time::Duration>,
    /// Resolution of the search over the cap angle when a finger attaches (rad).
    pub attach_resolution: Real,
}

/// Where a plan starts. A scenario starts at rotation 0 with the hand at its home pose
/// (`Start::default()`); a plan made again from an estimated state (the pipeline's planner
/// node, after the object slipped) starts where the object and the hand are.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Start {
    /// The object's rotation (rad). The plan turns it from here to [`Settings::goal`].
    pub rotation: Real,
    /// Joint angles (rad) per finger that the initial contacts' inverse kinematics starts
    /// from (the solution nearest to them is taken); a finger not listed starts from its
    /// home pose.
    pub joints: Vec<(u32, Vec<Real>)>,
}
