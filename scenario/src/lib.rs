//! # icrflow-scenario: configs and what they build
//!
//! The config file, read in two steps (raw serde structs rejecting unknown keys; then
//! the validated [`Config`], whose [`Config::load`] is the only way in; every error names the
//! offending key; the keys are documented in `docs/configuration.md`), and [`Setup`]: the object,
//! grasp problem, hand and initial contacts a config describes. Shared by the CLI and the
//! pipeline's nodes.

#![warn(missing_docs)]

pub mod bounds;
mod config;
mod raw;
mod setup;

pub use config::*;
pub use setup::{
    Loaded, Setup, Snap, SpatialSetup, section_problem, snap_contact, surface_tolerance,
};
