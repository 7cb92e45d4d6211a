//! The hand and the object in MuJoCo: the physics of `[plant] kind = "mujoco"`.
//!
//! - [`scene`]: the MJCF model of a hand ([`icrflow_plan::hand::Hand`]) holding an object
//!   ([`icrflow_grasp::object::Object`]), written from our own kinematic chains and solid.
//! - [`sim`] (feature `mujoco`, on by default): the model compiled and stepped in MuJoCo
//!   through `mujoco-rs`, joint servos and feed-forward fingertip forces in, joint angles,
//!   the object's pose and the true contacts out.
//!
//! - [`configured`]: the model and controls of a config (`[plant]`, `[object]`, `[hand]`).
//!
//! Nothing here knows of processes or messages: the plant node (`icrflow-nodes`) drives it.

#[cfg(feature = "mujoco")]
pub mod configured;
pub mod scene;
#[cfg(feature = "mujoco")]
pub mod sim;
