//! A free finger's way between two poses searched over a grid of its joint space: where the
//! fingertip roadmap of [`crate::route`] finds none (its poses keep the fingertip on circles
//! around the object, and a planar finger that must change its elbow branch on its way home
//! past a neighbouring finger finds no such pose clear of it), the joints' box is cut into a
//! grid of [`STEP`], each grid pose kept or not by the caller's `holds`, neighbouring poses
//! joined (every joint moving by at most one grid step), and the shortest way in joint motion
//! found by A*, every move checked at [`EDGE_SAMPLE`] intervals; way points a clear straight
//! move can skip are then dropped, every remaining leg checked by [`crate::route::along`] as
//! any route's.
//!
//! The grid's poses are checked only as the search reaches them; fingers of more than
//! [`MAX_JOINTS`] joints are not searched (their grids are too large). The A* is our own, a
//! few lines over the grid's indices; `pathfinding::astar` (integer costs) would serve as
//! well and is not yet compared.

use std::cmp::Reverse;
use std::collections::BinaryHeap;

use icrflow_grasp::math::Real;

use crate::hand::Finger;
use crate::route::skipping;

/// The grid's spacing in every joint (rad): 10 deg.
pub const STEP: Real = 10.0 * std::f64::consts::PI / 180.0;
/// How far apart a move between grid poses is checked (rad, in the joint that moves most):
/// 1 deg.
pub const EDGE_SAMPLE: Real = std::f64::consts::PI / 180.0;
/// The most joints a searched finger has.
pub const MAX_JOINTS: usize = 4;

/// The way points (rad) from `from` to `to` of `finger` over its joint grid, every move kept
/// by `holds`, neither end included; `None` where the grid has none (or the finger has more
/// than [`MAX_JOINTS`] joints).
pub fn grid_route(
    finger: &Finger,
    from: &[Real],
    to: &[Real],
    holds: impl Fn(&[Real]) -> bool,
) -> Option<Vec<Vec<Real>>> {
    let d = finger.dof();
    if d == 0 || d > MAX_JOINTS || from.len() != d || to.len() != d {
        return None;
    }
    let lows: Vec<Real> = finger.joints.iter().map(|j| j.lower).collect();
    let counts: Vec<usize> = finger
        .joints
        .iter()
        .map(|j| ((j.upper - j.lower) / STEP).ceil().max(1.0) as usize + 1)
        .collect();
    let spans: Vec<Real> = finger
        .joints
        .iter()
        .zip(&counts)
        .map(|(j, &n)| (j.upper - j.lower) / (n - 1) as Real)
        .collect();
    let cells: usize = counts.iter().product();
    let pose = |mut id: usize| -> Vec<Real> {
        let mut q = Vec::with_capacity(d);
        for k in 0..d {
            q.push(lows[k] + (id % counts[k]) as Real * spans[k]);
            id /= counts[k];
        }
        q
    };
    let id_of = |idx: &[usize]| -> usize {
        let mut id = 0;
        for k in (0..d).rev() {
            id = id * counts[k] + idx[k];
        }
        id
    };
    // 0: not checked, 1: kept, 2: not.
    let mut state = vec![0u8; cells];
    let kept = |id: usize, state: &mut Vec<u8>| -> bool {
        if state[id] == 0 {
            state[id] = if holds(&pose(id)) { 1 } else { 2 };
        }
        state[id] == 1
    };
    let motion = |a: &[Real], b: &[Real]| {
        a.iter()
            .zip(b)
            .fold(0.0, |m: Real, (x, y)| m.max((x - y).abs()))
    };
    let clear = |a: &[Real], b: &[Real]| {
        let n = (motion(a, b) / EDGE_SAMPLE).ceil().max(1.0) as usize;
        let mut q = vec![0.0; d];
        (0..=n).all(|i| {
            let s = i as Real / n as Real;
            for ((x, y), out) in a.iter().zip(b).zip(q.iter_mut()) {
                *out = x + s * (y - x);
            }
            holds(&q)
        })
    };
    // The grid poses around a pose: the corners of its grid box.
    let corners = |q: &[Real]| -> Vec<usize> {
        let base: Vec<usize> = (0..d)
            .map(|k| (((q[k] - lows[k]) / spans[k]).floor().max(0.0) as usize).min(counts[k] - 1))
            .collect();
        (0..1usize << d)
            .map(|bits| {
                let idx: Vec<usize> = (0..d)
                    .map(|k| (base[k] + (bits >> k & 1)).min(counts[k] - 1))
                    .collect();
                id_of(&idx)
            })
            .collect()
    };
    let ends: Vec<usize> = corners(to)
        .into_iter()
        .filter(|&id| kept(id, &mut state) && clear(&pose(id), to))
        .collect();
    if ends.is_empty() {
        return None;
    }
    // A* over the grid from the corners reachable from `from`; costs in joint motion.
    let mut cost = vec![Real::INFINITY; cells];
    let mut previous = vec![usize::MAX; cells];
    let mut heap = BinaryHeap::new();
    let key = |c: Real| Reverse(c.to_bits());
    for id in corners(from) {
        if kept(id, &mut state) && clear(from, &pose(id)) {
            let c = motion(from, &pose(id));
            if c < cost[id] {
                cost[id] = c;
                heap.push((key(c + motion(&pose(id), to)), id));
            }
        }
    }
    let mut idx = vec![0usize; d];
    let mut n = vec![0usize; d];
    let mut reached = None;
    while let Some((_, u)) = heap.pop() {
        if ends.contains(&u) {
            reached = Some(u);
            break;
        }
        let q = pose(u);
        let mut rest = u;
        for (k, slot) in idx.iter_mut().enumerate() {
            *slot = rest % counts[k];
            rest /= counts[k];
        }
        // Every neighbour: each joint -1, 0 or +1 grid step.
        for m in 0..3usize.pow(d as u32) {
            let mut code = m;
            let mut inside = true;
            let mut moved = false;
            for k in 0..d {
                let step = (code % 3) as i64 - 1;
                code /= 3;
                moved |= step != 0;
                let v = idx[k] as i64 + step;
                if v < 0 || v >= counts[k] as i64 {
                    inside = false;
                    break;
                }
                n[k] = v as usize;
            }
            if !inside || !moved {
                continue;
            }
            let v = id_of(&n);
            let qv = pose(v);
            let c = cost[u] + motion(&q, &qv);
            if c < cost[v] && kept(v, &mut state) && clear(&q, &qv) {
                cost[v] = c;
                previous[v] = u;
                heap.push((key(c + motion(&qv, to)), v));
            }
        }
    }
    let last = reached?;
    let mut path = vec![pose(last)];
    let mut at = last;
    while previous[at] != usize::MAX {
        at = previous[at];
        path.push(pose(at));
    }
    path.push(from.to_vec());
    path.reverse();
    path.push(to.to_vec());
    Some(skipping(&path, &holds))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::paper;
    use crate::route::along;

    /// A wall across the way: the grid goes around it, every leg of the route clear.
    #[test]
    fn the_grid_finds_a_way_around_what_blocks_the_straight_move() {
        let hand = paper::hand();
        let f = &hand.fingers[0];
        let from = vec![-0.6, 1.2, -1.5];
        let to = f.home.clone();
        // Blocked: every pose whose first joint is between -0.35 and -0.15 rad unless its
        // elbow is bent back (q3 > 1.0).
        let holds = |q: &[Real]| !(q[0] > -0.35 && q[0] < -0.15 && q[2] <= 1.0);
        assert!(!along(&from, &to, holds));
        let way = grid_route(f, &from, &to, holds).expect("a way around");
        assert!(!way.is_empty());
        let mut legs = vec![from.clone()];
        legs.extend(way);
        legs.push(to.clone());
        for w in legs.windows(2) {
            assert!(along(&w[0], &w[1], holds), "{:?} -> {:?}", w[0], w[1]);
        }
        // Nothing kept: no way.
        assert!(grid_route(f, &from, &to, |_| false).is_none());
    }
}
