//! Why a scenario is refused before planning.

use icrflow_grasp::math::Real;
use icrflow_grasp::quality::GraspError;

/// Why a scenario is refused before planning.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum PlanError {
    /// A finger of the grasp is not in the hand.
    #[error("finger {finger} is not in the hand (fingers: {known:?})")]
    UnknownFinger {
        /// The finger.
        finger: u32,
        /// The hand's fingers.
        known: Vec<u32>,
    },
    /// A finger is not a planar three-joint chain.
    #[error(
        "finger {finger} is not a planar three-joint chain in the hand's plane z = 0; the planner needs one"
    )]
    NotPlanar {
        /// The finger.
        finger: u32,
    },
    /// The initial grasp is not force closure.
    #[error("the initial grasp is not force closure (epsilon = {epsilon:.6}): nothing to plan")]
    NotForceClosure {
        /// Ferrari-Canny epsilon of the grasp.
        epsilon: Real,
    },
    /// The initial grasp's quality is below alpha.
    #[error(
        "the initial grasp's quality alpha* = {quality:.6} is below the margin alpha = {alpha} (the plan's: plan.alpha, or grasp.alpha where it is not set)"
    )]
    BelowMargin {
        /// Its quality.
        quality: Real,
        /// The margin.
        alpha: Real,
    },
    /// An initial contact cannot be reached.
    #[error("finger {finger} cannot reach its initial contact at {where_}: {reason}")]
    Unreachable {
        /// The finger.
        finger: u32,
        /// Where the contact is.
        where_: String,
        /// Why.
        reason: String,
    },
    /// Two fingertips would overlap.
    #[error(
        "fingers {a} and {b} overlap: their fingertip centres are {distance_mm:.2} mm apart, less than the sum of the radii"
    )]
    Overlap {
        /// One finger.
        a: u32,
        /// The other.
        b: u32,
        /// Distance between the fingertip centres (mm).
        distance_mm: Real,
    },
    /// A finger's link would pass through the object.
    #[error(
        "finger {finger}'s link {link} would pass {depth_mm:.2} mm into the object at step {step}: the hand cannot make this plan"
    )]
    LinkInObject {
        /// The finger.
        finger: u32,
        /// The link, counted from the palm (1 = first joint to second).
        link: usize,
        /// The step (at, or on the way to).
        step: usize,
        /// How deep (mm).
        depth_mm: Real,
    },
    /// A setting is impossible.
    #[error("{0}")]
    Settings(String),
    /// The grasp evaluation failed (not a grasp outcome: a numerical failure).
    #[error(transparent)]
    Grasp(#[from] GraspError),
}
