//! Angles in degrees at the plan's edges.
//!
//! Every angle inside the planner is in radians. A plan written out (`plan --json`, the CSV,
//! the Python dictionaries) gives its angles in degrees under names ending in `_deg`, as the
//! config does. These serde adapters convert at that edge, so a field reads
//!
//! ```
//! # use icrflow_grasp::math::Real;
//! # use serde::{Deserialize, Serialize};
//! #[derive(Serialize, Deserialize)]
//! struct Example {
//!     /// Object rotation (rad; `rotation_deg` in files).
//!     #[serde(rename = "rotation_deg", with = "icrflow_plan::degrees")]
//!     rotation: Real,
//! }
//! let e = Example { rotation: std::f64::consts::FRAC_PI_2 };
//! assert_eq!(serde_json::to_string(&e).unwrap(), r#"{"rotation_deg":90.0}"#);
//! ```
//!
//! Writing converts with [`f64::to_degrees`], the same call that made the degrees the planner
//! stored before its fields were radians, so the files are byte for byte what they were.

use icrflow_grasp::math::Real;
use serde::{Deserialize, Deserializer, Serialize, Serializer};

/// Writes radians as degrees.
pub fn serialize<S: Serializer>(radians: &Real, s: S) -> Result<S::Ok, S::Error> {
    radians.to_degrees().serialize(s)
}

/// Reads degrees as radians.
pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Real, D::Error> {
    Real::deserialize(d).map(Real::to_radians)
}

/// The same for an optional angle (`null` when absent).
pub mod option {
    use super::*;

    /// Writes radians as degrees.
    pub fn serialize<S: Serializer>(radians: &Option<Real>, s: S) -> Result<S::Ok, S::Error> {
        radians.map(Real::to_degrees).serialize(s)
    }

    /// Reads degrees as radians.
    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Option<Real>, D::Error> {
        Option::<Real>::deserialize(d).map(|a| a.map(Real::to_radians))
    }
}

/// The same for a list of angles (a finger's joints).
pub mod list {
    use super::*;

    /// Writes radians as degrees.
    pub fn serialize<S: Serializer>(radians: &[Real], s: S) -> Result<S::Ok, S::Error> {
        s.collect_seq(radians.iter().map(|a| a.to_degrees()))
    }

    /// Reads degrees as radians.
    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<Real>, D::Error> {
        Vec::<Real>::deserialize(d).map(|v| v.into_iter().map(Real::to_radians).collect())
    }
}

/// The same for an optional list of poses, each a list of angles (`null` when absent).
pub mod option_poses {
    use super::*;

    /// Writes radians as degrees.
    pub fn serialize<S: Serializer>(
        radians: &Option<Vec<Vec<Real>>>,
        s: S,
    ) -> Result<S::Ok, S::Error> {
        radians
            .as_ref()
            .map(|poses| {
                poses
                    .iter()
                    .map(|v| v.iter().map(|a| a.to_degrees()).collect::<Vec<_>>())
                    .collect::<Vec<_>>()
            })
            .serialize(s)
    }

    /// Reads degrees as radians.
    pub fn deserialize<'de, D: Deserializer<'de>>(
        d: D,
    ) -> Result<Option<Vec<Vec<Real>>>, D::Error> {
        Option::<Vec<Vec<Real>>>::deserialize(d).map(|p| {
            p.map(|poses| {
                poses
                    .into_iter()
                    .map(|v| v.into_iter().map(Real::to_radians).collect())
                    .collect()
            })
        })
    }
}
