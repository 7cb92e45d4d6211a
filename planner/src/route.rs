//! Moves of a free finger around the object: from where it let go to its free pose, and back
//! to where it will touch, without its fingertip cutting through the object.
//!
//! The hand moves between targets along straight lines in joint space (every joint scaled
//! alike), so a route is a list of way points, each leg a straight joint-space move along
//! which the fingertip centre stays at least a given distance from the object's centre (the
//! hand frame's origin; the object's section in the hand's plane is taken as a circle, exact
//! for the sphere, conservative for any object inside that radius; [`route_with`] takes any
//! keep-out, e.g. the fingertip's gap to a non-circular section), and every link
//! ([`Finger::link_distance`]: the segments between the joints, and the distal link up to the
//! fingertip sphere) at least [`LINK_MARGIN`] from its surface ([`Keepout`]).
//!
//! Where the straight move is clear, the route is empty. Otherwise a small roadmap is searched:
//! fingertip poses on circles of [`RADII`] beyond the given distance, every [`SPACING`]
//! around the object, with cap angles every [`CAP_SPACING`], both elbow branches, each
//! solved by inverse kinematics within the joint limits. Each pose is joined to its
//! [`NEIGHBOURS`] nearest (in joint space), the start and goal to all; the shortest route (in
//! joint motion, the time it takes at the joints' speed, plus [`LEG_COST`] per leg) is found
//! by Dijkstra's algorithm, checking a leg only when it would shorten a route; finally way
//! points that can be skipped along a clear leg are dropped. Where the roadmap has no route,
//! the finger's joint space is searched on a grid ([`crate::grid_route`]).

use std::f64::consts::TAU;

use icrflow_grasp::math::Real;

use crate::hand::Finger;

/// Distances of the roadmap's fingertip circles beyond the required distance (m).
pub const RADII: [Real; 4] = [10e-3, 20e-3, 35e-3, 55e-3];
/// Spacing of the roadmap's poses around the object (rad): 15 deg.
pub const SPACING: Real = 15.0_f64.to_radians();
/// Spacing of the cap angles tried at each roadmap position (rad): 30 deg.
pub const CAP_SPACING: Real = 30.0_f64.to_radians();
/// Roadmap poses each one is joined to.
pub const NEIGHBOURS: usize = 12;
/// Cost of a leg beyond its joint motion (rad): fewer way points among routes of about the
/// same length.
pub const LEG_COST: Real = 0.05;
/// Points checked along a leg (its ends included).
pub const SAMPLES: usize = 48;

/// How far every link keeps from the object's surface on a move (m): room for the links'
/// thickness, which the hand model does not give (they are line segments in it).
pub const LINK_MARGIN: Real = 5e-3;

/// How far a moving finger keeps from the other fingers' bodies (m; links as capsules of
/// [`LINK_MARGIN`], fingertips as their spheres): the hand's links are not lines, and a finger
/// crossing another's, as a planar hand's fingers in one plane would, collides. The spatial
/// planner keeps it too between any two fingers beyond their radii (its clash check, links as
/// capsules of `plant.link_radius_mm`): with none, it rolled the Allegro's thumb to within
/// 24.0x mm of the index (24.00 needed) at the sphere's pole before a switch released it, and
/// the object, rolled a few tenths of a degree past the step while the middle finger attached,
/// had MuJoCo's thumb and index touching (2 of 40 lockstep seeds and a CI run, 2026-12-05).
pub const FINGER_GAP: Real = 1e-3;

/// What a move keeps clear of the object (whose centre is the hand frame's origin).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Keepout {
    /// Smallest distance of the fingertip centre from the object's centre, in the hand's plane
    /// (m).
    pub tip: Real,
    /// Smallest distance of every link from the object's centre (m).
    pub links: Real,
}

impl Keepout {
    /// The fingertip centre at least `tip` from the centre of an object of radius
    /// `object_radius` (its largest distance from its centre), the links at least
    /// [`LINK_MARGIN`] beyond that radius.
    pub fn new(tip: Real, object_radius: Real) -> Self {
        Self {
            tip,
            links: object_radius + LINK_MARGIN,
        }
    }

    /// Whether `finger` at `q` keeps clear.
    pub fn holds(&self, finger: &Finger, q: &[Real]) -> bool {
        let (p, _) = finger.fk_tip(q);
        p.x.hypot(p.y) >= self.tip && finger.link_distance(q).0 >= self.links
    }
}

/// Whether `finger` keeps clear of the object ([`Keepout`]) all along the straight joint-space
/// move from `a` to `b` (checked at [`SAMPLES`] points).
pub fn clear(finger: &Finger, a: &[Real], b: &[Real], keep: Keepout) -> bool {
    along(a, b, |q| keep.holds(finger, q))
}

/// Whether `holds` is true all along the straight joint-space move from `a` to `b` (at
/// [`SAMPLES`] points, both ends included).
pub fn along(a: &[Real], b: &[Real], mut holds: impl FnMut(&[Real]) -> bool) -> bool {
    let mut q = vec![0.0; a.len()];
    (0..SAMPLES).all(|i| {
        let s = i as Real / (SAMPLES - 1) as Real;
        for ((x, y), out) in a.iter().zip(b).zip(q.iter_mut()) {
            *out = x + s * (y - x);
        }
        holds(&q)
    })
}

/// The largest joint motion between two poses (rad): how long the move takes at the joints'
/// speed.
fn motion(a: &[Real], b: &[Real]) -> Real {
    a.iter()
        .zip(b)
        .fold(0.0, |m, (x, y)| Real::max(m, (x - y).abs()))
}

/// The way points (joint angles, rad) that take `finger` from `from` to `to` keeping clear of
/// the object ([`Keepout`]) along every leg, neither end included; empty where the straight
/// move is clear, `None` where no route is found (a planar finger is needed for the roadmap).
pub fn route(finger: &Finger, from: &[Real], to: &[Real], keep: Keepout) -> Option<Vec<Vec<Real>>> {
    route_with(finger, from, to, keep.tip, |q| keep.holds(finger, q))
}

/// [`route`] for any keep-out: `holds` says whether a pose keeps clear (every leg is checked
/// with it, [`along`]), and the roadmap's circles lie [`RADII`] beyond `distance` (from the
/// object's centre), which must be at least the fingertip distance `holds` requires in every
/// direction (for a non-circular object: its largest).
pub fn route_with(
    finger: &Finger,
    from: &[Real],
    to: &[Real],
    distance: Real,
    holds: impl Fn(&[Real]) -> bool,
) -> Option<Vec<Vec<Real>>> {
    if along(from, to, &holds) {
        return Some(Vec::new());
    }
    roadmap(finger, from, to, distance, &holds)
        .or_else(|| crate::grid_route::grid_route(finger, from, to, &holds))
}

/// The fingertip roadmap's route of [`route_with`] (`None`: none).
fn roadmap(
    finger: &Finger,
    from: &[Real],
    to: &[Real],
    distance: Real,
    holds: impl Fn(&[Real]) -> bool,
) -> Option<Vec<Vec<Real>>> {
    // The roadmap: index 0 is the start, 1 the goal, then the poses.
    let mut poses: Vec<Vec<Real>> = vec![from.to_vec(), to.to_vec()];
    let around = (TAU / SPACING).round() as usize;
    let caps = (TAU / CAP_SPACING).round() as usize;
    for radius in RADII.map(|r| distance + r) {
        for i in 0..around {
            let psi = i as Real * SPACING;
            let (x, y) = (radius * psi.cos(), radius * psi.sin());
            for c in 0..caps {
                let phi = psi + c as Real * CAP_SPACING;
                for near in [from, to] {
                    if let Ok(q) = finger.ik_planar(x, y, phi, near)
                        && !poses.iter().any(|p| motion(p, &q) < 1e-6)
                    {
                        poses.push(q);
                    }
                }
            }
        }
    }
    let n = poses.len();
    if n == 2 {
        return None;
    }
    // Joined: each pose to its nearest, both ways; the start and the goal to every pose.
    let mut joined = vec![Vec::<usize>::new(); n];
    for a in 2..n {
        let mut order: Vec<usize> = (2..n).filter(|&b| b != a).collect();
        order.sort_by(|&x, &y| {
            motion(&poses[a], &poses[x]).total_cmp(&motion(&poses[a], &poses[y]))
        });
        for &b in order.iter().take(NEIGHBOURS) {
            joined[a].push(b);
            joined[b].push(a);
        }
        joined[0].push(a);
        joined[a].push(1);
    }
    for list in &mut joined {
        list.sort_unstable();
        list.dedup();
    }
    // Dijkstra from the start, legs checked lazily.
    let mut cost = vec![Real::INFINITY; n];
    let mut previous = vec![usize::MAX; n];
    let mut done = vec![false; n];
    cost[0] = 0.0;
    loop {
        let u = (0..n)
            .filter(|&i| !done[i] && cost[i].is_finite())
            .min_by(|&a, &b| cost[a].total_cmp(&cost[b]))?;
        if u == 1 {
            break;
        }
        done[u] = true;
        for &v in &joined[u] {
            let c = cost[u] + motion(&poses[u], &poses[v]) + LEG_COST;
            if !done[v] && c < cost[v] && along(&poses[u], &poses[v], &holds) {
                cost[v] = c;
                previous[v] = u;
            }
        }
    }
    let mut path = vec![1];
    while let Some(&last) = path.last()
        && last != 0
    {
        path.push(previous[last]);
    }
    path.reverse();
    let poses: Vec<Vec<Real>> = path.iter().map(|&i| poses[i].clone()).collect();
    Some(skipping(&poses, &holds))
}

/// The way points of the route through `path` (its first pose the start, its last the goal)
/// that a clear straight move (`holds` all along it, [`along`]) cannot skip, neither end
/// included: from each kept pose, the farthest pose of `path` reached in one clear move.
pub(crate) fn skipping(path: &[Vec<Real>], holds: impl Fn(&[Real]) -> bool) -> Vec<Vec<Real>> {
    let mut out = Vec::new();
    let mut at = 0;
    while at + 1 < path.len() {
        let next = (at + 1..path.len())
            .rev()
            .find(|&j| along(&path[at], &path[j], &holds))
            .unwrap_or(at + 1);
        if next + 1 < path.len() {
            out.push(path[next].clone());
        }
        at = next;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::paper;

    /// On the paper's hand: from a pose beside the object on the far side of its base to its
    /// home pose, the straight move cuts through the object; the route goes around it.
    #[test]
    fn a_route_goes_around_the_object_where_the_straight_move_cuts_through() {
        let hand = paper::hand();
        let r = paper::OBJECT_RADIUS + paper::TIP_RADIUS;
        let mut routed = 0;
        for f in &hand.fingers {
            let home = f.home.clone();
            let base = f.base.translation.vector;
            let psi_base = base.y.atan2(base.x);
            // Fingertip poses 4 mm off the surface all around the object.
            for k in 0..36 {
                let psi = psi_base + (k as Real * 10.0).to_radians();
                let d = r + 4e-3;
                let Some(start) = (0..12).find_map(|c| {
                    let phi = psi + (c as Real * 30.0).to_radians();
                    f.ik_planar(d * psi.cos(), d * psi.sin(), phi, &home).ok()
                }) else {
                    continue;
                };
                let limit = Keepout::new(r + 2.5e-3, paper::OBJECT_RADIUS);
                let way = route(f, &start, &home, limit)
                    .unwrap_or_else(|| panic!("finger {} at {k}0 deg: no route", f.id));
                let mut legs = vec![start.clone()];
                legs.extend(way.iter().cloned());
                legs.push(home.clone());
                for w in legs.windows(2) {
                    assert!(
                        clear(f, &w[0], &w[1], limit),
                        "finger {}: a leg cuts in",
                        f.id
                    );
                }
                if !clear(f, &start, &home, limit) {
                    assert!(!way.is_empty());
                    routed += 1;
                }
            }
        }
        assert!(
            routed > 0,
            "no case needed a route: the test checks nothing"
        );
    }

    /// A move is clear only if the links keep their distance too, not the fingertip alone.
    #[test]
    fn the_links_are_kept_clear_as_well_as_the_fingertip() {
        let hand = paper::hand();
        let f = &hand.fingers[0];
        let q = f.home.clone();
        let (tip, _) = f.fk_tip(&q);
        let tip = tip.x.hypot(tip.y);
        let (links, _) = f.link_distance(&q);
        let keep = |links: Real| Keepout {
            tip: tip - 1e-3,
            links,
        };
        assert!(keep(links - 1e-3).holds(f, &q));
        assert!(
            !keep(links + 1e-3).holds(f, &q),
            "the links were not checked"
        );
        assert!(!clear(f, &q, &q, keep(links + 1e-3)));
        // The paper's hand keeps its links ~3 cm off the sphere where its fingertip is.
        assert!(links > paper::OBJECT_RADIUS + LINK_MARGIN, "{links}");
    }

    #[test]
    fn a_clear_move_needs_no_way_points() {
        let hand = paper::hand();
        let f = &hand.fingers[0];
        assert_eq!(
            route(f, &f.home, &f.home, Keepout::new(0.01, 0.005)),
            Some(Vec::new())
        );
    }
}
