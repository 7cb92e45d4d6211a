//! # icrflow-plan: the in-hand rolling planner
//!
//! The algorithm of the paper's section III (`shared/paper/icr-inhand-rolling.md`, DESIGN.md
//! section 3) on top of the grasp-analysis core `icrflow-grasp`: a multi-finger hand turns an
//! object by rolling its fingertips inside their independent contact regions and, when a
//! finger reaches a limit, hands over to a free finger at a rendezvous point, while the grasp
//! never drops below the quality margin alpha.
//!
//! | module | what |
//! |---|---|
//! | [`degrees`] | radians inside, degrees in the plan's files: the serde adapters |
//! | [`follow`] | following a plan closed loop: its targets (sub-targets, stand-offs, way points around the object), the [`follow::Follower`] step, re-planning from an estimate |
//! | [`forces`] | fingertip forces balancing the grasp inside the exact friction cones (SOCP, clarabel) |
//! | [`hand`] | fingers as revolute chains: forward kinematics, closed-form planar and damped-least-squares inverse kinematics, limits, manipulability |
//! | [`urdf`] | hands from URDF files |
//! | [`paper`] | the paper's four-finger planar hand |
//! | [`planner`] | rolling, finger switching, the trajectory and its summary |
//! | [`rendezvous`] | rendezvous regions for a switch: exact (brute force), ICR zone rule, eq. (8) LP |
//! | [`rolling`] | fingertips rolling on the object's section: the surface, contacts, the rotation from a fingertip's motion |
//! | [`spatial`] | the planner in space: fingers of any serial chain ending in a fingertip sphere turning the object about any axis, the spatial rolling kinematics, smooth convex surfaces |

#![warn(missing_docs)]

pub mod degrees;
pub mod follow;
pub mod forces;
pub mod grid_route;
pub mod hand;
pub mod paper;
pub mod planner;
pub mod rendezvous;
pub mod rolling;
pub mod route;
pub mod spatial;
pub mod urdf;
