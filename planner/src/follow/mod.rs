//! Following a plan closed loop: the targets a hand is led through, and the [`Follower`] that
//! leads it from the estimated grasp.
//!
//! A plan's steps become [`targets`]: a rolling step is cut into sub-targets whose fingertip
//! poses are interpolated along the rolling motion and solved by inverse kinematics
//! ([`SUBSTEP`]); an attach step is preceded by way points of the attaching finger (its free
//! pose, its route around the object, its stand-off pose [`STANDOFF`] off the contact), a
//! detach step by those of the released finger, so that a finger never crosses the object.
//!
//! A spatial hand's plan is cut into its targets by [`crate::spatial::follow::targets`]; the
//! same [`Follower`] leads it ([`Planning::Spatial`]) and plans it again from the estimate
//! ([`crate::spatial::follow::replan`]).
//!
//! The [`Follower`] is a pure step: an [`Estimate`] of the grasp and the time in, the target to
//! command out. A target is commanded until the estimate has reached it (the same fingers in
//! contact and, for a rolling step, the object's rotation within [`ROTATION_TOLERANCE`] of
//! the target, or within [`SETTLED_TOLERANCE`] of it with the object settled or the hand at
//! the target's joints, [`HAND_AT_TARGET`]), then the next; a sub-target inside a rolling step
//! (not its last) is passed as soon as the object is within [`LEAD`] of it, so that the hand
//! rolls on while a physical object follows it a degree behind. The first estimate picks the
//! target nearest to it, so that a follower started again resumes rather than sends the hand
//! back.
//!
//! When the object stops short of a rolling step's target for good (it slipped in the hand,
//! or the rolling went astray: the estimate has two fingers or more in contact, the step's or
//! others, and the free fingers at their free pose, but the object has stood still for
//! [`REPLAN_NS`] farther than [`SETTLED_TOLERANCE`] from the target), the follower plans again
//! from the estimate ([`replan`]): from the estimated rotation, contacts, cap angles and
//! joints toward the goal, at most [`REPLAN_HORIZON`] on: a plan made again on a large mesh
//! takes seconds per tens of degrees, the hand held all the while, so it is planned in legs.
//! At the end of a plan that does not reach the goal (a leg, or a plan that stopped short),
//! with the object settled there, the follower plans on from the estimate, as long as that
//! plan turned the object on ([`MIN_PROGRESS`]). The new plan's steps are numbered on from the
//! last one; its first step is a `Start`.

mod estimate;
mod follower;
mod replan;
mod targets;

pub use estimate::{Estimate, EstimatedFinger, fingers_in_contact};
pub use follower::{
    Event, Followed, Follower, GOAL_TOLERANCE, HAND_AT_TARGET, LEAD, MIN_PROGRESS, Planning,
    REPLAN_HORIZON, REPLAN_NS, ROTATION_TOLERANCE, ReplanDue, Replanned, SETTLED_NS,
    SETTLED_TOLERANCE, STOPPED, Tolerances, WAY_POINT_TOLERANCE, Wait,
};
pub use replan::{Replan, ReplanError, replan};
pub(crate) use replan::{at_the_gate, leg};
pub use targets::{STANDOFF, STANDOFFS, SUBSTEP, Target, targets};
