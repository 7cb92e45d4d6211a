//! Rolling kinematics of fingertips on the object, as the simulated plant applies them and the
//! state estimator inverts them. The object turns about the vertical axis through its centre
//! (the hand frame's origin); the model is exact for a sphere of radius `r_o` (the paper's
//! object) and the pipeline refuses other objects for now.
//!
//! A fingertip of radius `r_f` in contact has its centre at distance `r_o + r_f` from the
//! object's centre, at world angle `psi`; its cap axis is at world angle `phi`. Rolling
//! without slipping (`r_f dgamma = -r_o d(body angle)`, `gamma = psi + pi - phi`, body angle
//! `= psi - theta`) gives the object's rotation from the fingertip's motion:
//! `dtheta = (1 + r_f / r_o) dpsi - (r_f / r_o) dphi`.

use icrflow_plan::hand::{Finger, wrap};

/// Where a fingertip is, seen from the object's centre.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Tip {
    /// World angle of the fingertip centre about the object's centre (rad).
    pub psi: f64,
    /// World angle of the cap axis (rad).
    pub phi: f64,
    /// Distance of the fingertip centre from the object's centre (m).
    pub distance: f64,
}

/// The fingertip of `finger` at joint angles `q`.
pub fn tip(finger: &Finger, q: &[f64]) -> Tip {
    let (centre, cap) = finger.fk_tip(q);
    Tip {
        psi: centre.y.atan2(centre.x),
        phi: cap.y.atan2(cap.x),
        distance: centre.xy().norm(),
    }
}

/// Whether the fingertip touches an object of radius `r_o` (within `tolerance`, m).
pub fn touches(t: &Tip, finger: &Finger, r_o: f64, tolerance: f64) -> bool {
    (t.distance - (r_o + finger.tip_radius)).abs() <= tolerance
}

/// The object's rotation implied by a fingertip rolling from `a` to `b`.
pub fn rotation(a: &Tip, b: &Tip, finger: &Finger, r_o: f64) -> f64 {
    let k = finger.tip_radius / r_o;
    (1.0 + k) * wrap(b.psi - a.psi) - k * wrap(b.phi - a.phi)
}
