//! A finger's reach map: poses on a grid over its joint ranges, which seed a switch's
//! placements and rule out targets far from them.

use icrflow_grasp::math::{Real, Vec3};

use crate::hand::Finger;

/// Joint values per joint of a [`ReachMap`]'s grid.
const REACH_MAP_GRID: usize = 7;

/// How far (m) a fingertip target may be from every pose of a finger's [`ReachMap`] and still
/// be tried: a little more than the grid's spacing at the fingertip (a seventh of a joint's
/// range at a 50 mm lever).
pub(super) const REACH_MAP_GAP: Real = 0.012;

/// A finger's reach map: its fingertip centre at poses on a grid over its joint ranges, to
/// rule out targets far from all of them and to seed the inverse kinematics of the others.
pub struct ReachMap {
    /// The finger.
    pub finger: u32,
    /// (fingertip centre, joints) at each pose of the grid.
    pub poses: Vec<(Vec3, Vec<Real>)>,
}

impl ReachMap {
    /// The map of finger `f`: [`REACH_MAP_GRID`] values per joint, its ends inside the limits
    /// (of a finger of more than six joints, the seventh and eighth held at their lowest
    /// grid value).
    pub fn new(f: &Finger) -> Self {
        let n = f.dof();
        let count = REACH_MAP_GRID.pow(n.min(6) as u32);
        let poses = (0..count)
            .map(|mut k| {
                let q: Vec<Real> = f
                    .joints
                    .iter()
                    .map(|j| {
                        let i = k % REACH_MAP_GRID;
                        k /= REACH_MAP_GRID;
                        let u = (i as Real + 0.5) / REACH_MAP_GRID as Real;
                        j.lower + u * (j.upper - j.lower)
                    })
                    .collect();
                (f.tip_centre(&q), q)
            })
            .collect();
        Self {
            finger: f.id,
            poses,
        }
    }

    /// The pose whose fingertip centre is nearest `target`: its distance and joints.
    pub fn nearest(&self, target: &Vec3) -> Option<(Real, &[Real])> {
        self.poses
            .iter()
            .map(|(p, q)| ((p - target).norm_squared(), q))
            .min_by(|a, b| a.0.total_cmp(&b.0))
            .map(|(d, q)| (d.sqrt(), q.as_slice()))
    }
}
