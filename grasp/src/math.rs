//! Scalar and geometric types used throughout the crate.
//!
//! Geometry (points, normals, rigid motions) uses nalgebra; wrenches are
//! plain `f64` rows of length [`crate::wrench::Space::dim`] stored
//! contiguously (row-major), so that the dense work is a matrix product.

/// The scalar type.
pub type Real = f64;
/// A 3-vector (point or direction) in the object's body frame unless stated.
pub type Vec3 = nalgebra::Vector3<f64>;
/// A rigid motion.
pub type Isometry3 = nalgebra::Isometry3<f64>;
/// A rotation.
pub type UnitQuaternion = nalgebra::UnitQuaternion<f64>;
