//! The in-hand rolling planner (paper section III, DESIGN.md section 3): rolling within ICRs,
//! then finger switching at a rendezvous point, repeated until the object has turned by the
//! goal.
//!
//! # Model
//! - The hand moves in its horizontal plane `z = 0`; the object's centre of mass is held at
//!   the origin and the object turns about the vertical axis by `theta` (counter-clockwise
//!   seen from the top is positive). Body point `b` is at `Rz(theta) (b - c)` in the hand
//!   frame, `c` the centre of mass.
//! - Contacts are candidates of the grasp problem: the object's section by the hand's plane
//!   (planar or spatial analysis). Everything about grasp quality is computed in the body
//!   frame (alpha* is invariant under the object's rigid motion).
//! - A finger in contact at body point `p` (outward normal `n`) has its fingertip centre at
//!   `p_w + r_f n_w`. Its *cap angle* `gamma` is where the contact lies on the fingertip: the
//!   angle from the cap axis (world angle `phi`) to the direction `-n_w` of the contact from
//!   the fingertip's centre, `gamma = angle(-n_w) - phi`.
//!
//! # Rolling step
//! The object turns by `step`. Each finger's next contact is the member of its ICR nearest to
//! the body point that would stay still in the world (`c + Rz(-step) (p - c)`: just behind
//! the current contact along the rolling direction). Rolling without slipping makes the arc
//! travelled on the fingertip equal to the arc `s` travelled on the object, with opposite
//! sense: `r_f dgamma = -s` (`s` counter-clockwise positive; for a sphere `s = r_o dtheta_b`,
//! hence the paper's `dtheta_o = (r_f / r_o) dtheta_f` when the fingertips stay in place).
//! The fingertip pose `(p_w + r_f n_w, phi = angle(-n_w) - gamma)` gives the joint angles by
//! inverse kinematics. The step is refused when a finger would leave its joint limits, its
//! fingertip cap (`|gamma| > cap half-angle - margin`), or fall below the mobility threshold;
//! and (a bug guard) when the recomputed quality is below alpha.
//!
//! One rolling step is one candidate step: two poses, between which the pipeline moves the
//! joints along a straight line. They stand for the rolling between them only while each
//! contact's travel is short and stays where the margin holds. So a contact's next contact
//! must be reached along the section through members of its ICR only, and where its
//! stay-still point is out of the ICR (it rolls to the region's member nearest that point,
//! and its fingertip moves around the object by the difference), that difference is at most
//! [`MAX_DRAG`]; otherwise the finger is blocked (a switch may help). A step of more than
//! [`MAX_STEP`] is refused outright: the stay-still point of a half turn is on the far side of
//! the section, and that of a whole turn is the contact itself, so a 360-degree step once
//! "completed" with the hand not moving at all.
//!
//! # Finger switching
//! When a finger `k` cannot roll on, a free finger takes over. Its rendezvous region is the
//! set of candidates `q` whose grasp with the remaining contacts keeps the margin: computed
//! exactly by brute force, beside the ICR zone rule and the paper's eq. (8) hyperplanes
//! (LP, clarabel), all recorded ([`crate::rendezvous`]). The rendezvous point is the exact
//! region's candidate that the free finger reaches (inverse kinematics within limits, the cap, the
//! mobility threshold, fingertips not overlapping), ahead of the released contact along the
//! rolling direction (within half a turn counter-clockwise of it) when any such is reachable,
//! with the most rolling room, i.e. the most steps it could roll before its own limits; ties
//! go to the candidate farther ahead. Then: attach (the grasp with one more contact is verified),
//! detach finger `k` (the remaining grasp is verified), and `k` becomes a free finger.

mod checks;
mod deadline;
mod drive;
mod error;
mod plan;
mod roll;
mod scenario;
mod settings;
mod switch;

pub use checks::{LINK_SPACING, LinkClearance, link_clearance, rolling_residuals};
pub(crate) use deadline::Deadline;
pub use drive::{EARLY_SWITCH_STEPS, Roll};
pub(crate) use drive::{NoSwitch, Stepper, Switched, drive};
pub use error::PlanError;
pub use plan::{FingerState, Phase, Plan, SQUEEZE_PROBE, Step, Summary, Switch};
pub use roll::{MAX_DRAG, MAX_STEP};
pub(crate) use scenario::cap_left;
pub use scenario::{Contact, Scenario};
pub use settings::{QUALITY_SLACK, Settings, Start};

/// The planning loop's tests' helpers, for other modules' tests.
#[cfg(test)]
pub(crate) use drive::tests;
