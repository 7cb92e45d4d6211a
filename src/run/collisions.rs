//! The hand's collisions in MuJoCo over a run (the summary's `physics` counts): the plant's
//! integration steps in which two fingers touched each other, or a link (not a fingertip)
//! touched the object, which fingers, and when it first happened. A plan keeps the links'
//! capsules clear of the object and of each other ([`icrflow_plan::spatial`]'s clearance);
//! MuJoCo models the same capsules ([`icrflow_physics::scene`]), so any count is the physics
//! leaving the plan.

use icrflow_grasp::math::Real;
use icrflow_interfaces::{MAX_FINGERS, PlantTruth};
use serde::Serialize;

/// The first step of a kind of collision: when, and where the turn was.
#[derive(Debug, Clone, Copy, Serialize, PartialEq)]
pub struct First {
    /// Seconds since the first truth.
    pub at_s: Real,
    /// The object's true rotation then (deg).
    pub rotation_deg: Real,
}

/// The summary's collision counts (flattened into `physics`).
#[derive(Debug, Clone, Default, Serialize, PartialEq)]
pub struct CollisionSummary {
    /// The plant's integration steps the counts are over.
    pub physics_steps: u64,
    /// Steps in which two fingers touched each other.
    pub finger_collisions: u64,
    /// The fingers that did.
    pub fingers_touching: Vec<u32>,
    /// The first such step.
    pub first_finger_collision: Option<First>,
    /// Steps in which a link touched the object.
    pub link_object_contacts: u64,
    /// The fingers whose links did.
    pub links_on_object: Vec<u32>,
    /// The first such step.
    pub first_link_object_contact: Option<First>,
}

/// The counts so far.
#[derive(Debug, Default)]
pub struct CollisionTrack {
    out: CollisionSummary,
    /// Finger numbers (bit of their slot) that touched each other, and whose links touched.
    fingers_touching: u32,
    links_on_object: u32,
    ids: [u32; MAX_FINGERS],
}

impl CollisionTrack {
    /// A truth, `at_s` seconds after the first.
    pub fn truth(&mut self, t: &PlantTruth, at_s: Real) {
        let first = First {
            at_s,
            rotation_deg: t.rotation.to_degrees(),
        };
        self.out.physics_steps += u64::from(t.physics_steps);
        self.out.finger_collisions += u64::from(t.finger_touch_steps);
        self.out.link_object_contacts += u64::from(t.link_object_steps);
        if t.finger_touch_steps > 0 {
            self.out.first_finger_collision.get_or_insert(first);
        }
        if t.link_object_steps > 0 {
            self.out.first_link_object_contact.get_or_insert(first);
        }
        self.fingers_touching |= t.fingers_touching;
        self.links_on_object |= t.links_on_object;
        let n = (t.finger_count as usize).min(MAX_FINGERS);
        for (id, &finger) in self.ids.iter_mut().zip(&t.finger_ids[..n]) {
            *id = finger;
        }
    }

    /// What it found.
    pub fn summary(&self) -> CollisionSummary {
        let fingers = |mask: u32| {
            (0..MAX_FINGERS)
                .filter(|&k| mask & (1 << k) != 0)
                .map(|k| self.ids[k])
                .collect()
        };
        CollisionSummary {
            fingers_touching: fingers(self.fingers_touching),
            links_on_object: fingers(self.links_on_object),
            ..self.out.clone()
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn steps_add_up_and_slots_name_their_fingers() {
        let mut track = CollisionTrack::default();
        let mut t = PlantTruth {
            finger_count: 4,
            finger_ids: [1, 2, 3, 4, 0, 0, 0, 0],
            physics_steps: 20,
            rotation: 0.5,
            ..Default::default()
        };
        track.truth(&t, 0.0);
        t.finger_touch_steps = 3;
        t.fingers_touching = 0b0110;
        track.truth(&t, 0.01);
        t.finger_touch_steps = 0;
        t.fingers_touching = 0;
        t.link_object_steps = 20;
        t.links_on_object = 0b1000;
        track.truth(&t, 0.02);
        t.finger_touch_steps = 1;
        t.fingers_touching = 0b0011;
        track.truth(&t, 0.03);
        let s = track.summary();
        assert_eq!(s.physics_steps, 80);
        assert_eq!(s.finger_collisions, 4);
        assert_eq!(s.fingers_touching, vec![1, 2, 3]);
        assert_eq!(s.first_finger_collision.unwrap().at_s, 0.01);
        assert_eq!(s.link_object_contacts, 40);
        assert_eq!(s.links_on_object, vec![4]);
        assert_eq!(s.first_link_object_contact.unwrap().at_s, 0.02);
        assert!((s.first_link_object_contact.unwrap().rotation_deg - 28.6478).abs() < 1e-3);
    }

    #[test]
    fn no_collision_is_zero_and_none() {
        let mut track = CollisionTrack::default();
        let t = PlantTruth {
            finger_count: 2,
            finger_ids: [1, 2, 0, 0, 0, 0, 0, 0],
            physics_steps: 10,
            ..Default::default()
        };
        track.truth(&t, 0.0);
        let s = track.summary();
        assert_eq!(s.physics_steps, 10);
        assert_eq!((s.finger_collisions, s.link_object_contacts), (0, 0));
        assert!(s.fingers_touching.is_empty() && s.links_on_object.is_empty());
        assert!(s.first_finger_collision.is_none() && s.first_link_object_contact.is_none());
    }
}
