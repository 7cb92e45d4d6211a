//! The paper's hand (section IV): four fingers of three revolute joints each, moving in the
//! horizontal plane, hemispherical fingertips of radius 2.5 cm, around a sphere of radius
//! 4.75 cm.
//!
//! The paper gives neither the finger dimensions nor the base poses; these are ours, chosen
//! so that its initial grasp (fingers 1, 2 and 4 at 30, -30 and 140 degrees on the sphere,
//! finger 3 free) is reachable with room to roll, and so that each finger's limits end its
//! rolling after a few tens of degrees of object rotation (which is what makes switching
//! necessary, as in the paper's Fig. 8 to 11):
//! - bases on a circle of radius [`BASE_RADIUS`] about the object's centre, at the angles
//!   [`BASE_ANGLES_DEG`] (finger 1 to 4), each first link pointing at the centre at `q = 0`;
//! - links [`LINKS`] (the last one from the third joint to the fingertip sphere's centre),
//!   about the size of a human index finger;
//! - joint limits [`LIMITS_DEG`], the same for every finger.

use std::f64::consts::FRAC_PI_2;

use icrflow_grasp::math::Real;

use crate::hand::{Finger, Hand, HandError, planar_finger};

/// Fingertip radius (m).
pub const TIP_RADIUS: Real = 0.025;
/// Object radius (m).
pub const OBJECT_RADIUS: Real = 0.0475;
/// Distance of the finger bases from the object's centre (m).
pub const BASE_RADIUS: Real = 0.15;
/// World angle of each finger's base (deg), fingers 1 to 4.
pub const BASE_ANGLES_DEG: [Real; 4] = [45.0, -45.0, -135.0, 135.0];
/// Link lengths (m): joint 1 to 2, joint 2 to 3, joint 3 to the fingertip centre.
pub const LINKS: [Real; 3] = [0.06, 0.045, 0.025];
/// Joint limits (deg).
pub const LIMITS_DEG: [[Real; 2]; 3] = [[-90.0, 90.0], [-120.0, 120.0], [-120.0, 120.0]];
/// Pose of a free finger (deg): curled back, away from the object.
pub const HOME_DEG: [Real; 3] = [0.0, 90.0, 90.0];

/// One finger of the paper's hand.
pub fn finger(id: u32, base_angle_deg: Real) -> Result<Finger, HandError> {
    let a = base_angle_deg.to_radians();
    planar_finger(
        id,
        [
            BASE_RADIUS * a.cos(),
            BASE_RADIUS * a.sin(),
            a + std::f64::consts::PI,
        ],
        &LINKS,
        &LIMITS_DEG.map(|l| l.map(Real::to_radians)),
        TIP_RADIUS,
        FRAC_PI_2,
        Some(HOME_DEG.iter().map(|d| d.to_radians()).collect()),
    )
}

/// The paper's hand.
#[expect(
    clippy::expect_used,
    reason = "constants: the paper's hand is checked by its tests"
)]
pub fn hand() -> Hand {
    let fingers = (1..=4)
        .zip(BASE_ANGLES_DEG)
        .map(|(id, a)| finger(id, a).expect("the paper hand is valid"))
        .collect();
    Hand::new(fingers).expect("the paper hand is valid")
}
