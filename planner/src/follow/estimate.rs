//! The estimated grasp a plan is followed and made again from.

use icrflow_grasp::math::Real;

use crate::planner::Step;

/// The estimated grasp a plan is followed and made again from.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Estimate {
    /// The object's rotation about the vertical axis since the start (rad, unwrapped).
    pub rotation: Real,
    /// The hand's fingers, in the estimate's order.
    pub fingers: Vec<EstimatedFinger>,
}

/// One finger of an [`Estimate`].
#[derive(Debug, Clone, Default, PartialEq)]
pub struct EstimatedFinger {
    /// Finger number.
    pub finger: u32,
    /// Whether it touches the object.
    pub in_contact: bool,
    /// Its joint angles (rad).
    pub joints: Vec<Real>,
}

impl Estimate {
    /// The fingers in contact.
    pub fn touching(&self) -> impl Iterator<Item = u32> + '_ {
        self.fingers
            .iter()
            .filter(|f| f.in_contact)
            .map(|f| f.finger)
    }

    /// Whether the estimate has `step`'s fingers in contact (in the same order).
    pub fn same_contacts(&self, step: &Step) -> bool {
        self.touching().eq(fingers_in_contact(step))
    }

    /// The largest difference between the estimated joint angles of `step`'s fingers in
    /// contact (`in_contact`) or free, and their targets (rad; 0 if there is none).
    pub fn joint_error(&self, step: &Step, in_contact: bool) -> Real {
        step.fingers
            .iter()
            .filter(|f| f.contact.is_some() == in_contact)
            .filter_map(|f| {
                let e = self.fingers.iter().find(|e| e.finger == f.finger)?;
                Some(
                    f.joints
                        .iter()
                        .zip(&e.joints)
                        .fold(0.0_f64, |m, (t, q)| m.max((t - q).abs())),
                )
            })
            .fold(0.0, f64::max)
    }
}

/// The fingers in contact in a plan step.
pub fn fingers_in_contact(step: &Step) -> impl Iterator<Item = u32> + '_ {
    step.fingers
        .iter()
        .filter(|f| f.contact.is_some())
        .map(|f| f.finger)
}
