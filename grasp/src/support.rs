//! The OWS support function with bounds: a ball tree over the object wrenches, built once per
//! object, so that `max_k a . o_k` skips whole clusters of OWS points.
//!
//! For a node with centre `c` and radius `r` (every point within `r` of `c`) and bounding box
//! `[lo, hi]`, no point of the node can exceed `min(a . c + |a| r, sum_i max(a_i lo_i, a_i
//! hi_i))`: the ball is tight for round clusters, the box for flat ones (a sphere's object
//! wrenches have no torque, so in 6D they fill only the force coordinates). Two queries use
//! it:
//! - [`SupportTree::support`]: the exact support `h(a)` of one direction, branch and bound
//!   (children visited best bound first, a node skipped when its bound cannot beat the best
//!   point found so far);
//! - [`SupportTree::max_over`]: the largest `g_f . o_k` over many directions `g_f` at once,
//!   directions ordered by their root bound and stopped as soon as no remaining direction can
//!   win. With `g_f = a_f / b_f` (facet normal over offset) its inverse is alpha*: a facet is
//!   skipped, without touching one OWS point, whenever a lower bound on its ratio `b_f / h_f`
//!   already exceeds the best ratio found.
//!
//! Both are exact (up to the rounding of the dot products); the dense product through faer
//! ([`crate::quality::GraspProblem::support_function_dense`]) is the reference they are
//! tested against.

use crate::hull::dot;
use crate::math::Real;

/// Points per leaf.
const LEAF: usize = 32;
/// Largest supported dimension.
pub const MAX_DIM: usize = 6;

#[derive(Debug, Clone)]
struct Node {
    centre: [Real; MAX_DIM],
    radius: Real,
    lo: [Real; MAX_DIM],
    hi: [Real; MAX_DIM],
    /// Children (`u32::MAX` for a leaf) or the leaf's point range.
    left: u32,
    right: u32,
    start: u32,
    end: u32,
}

/// Recent maximising points remembered for warm starts.
const WARM: usize = 16;

/// Scratch space for support queries: the search stack and the warm-start points.
#[derive(Debug, Clone, Default)]
pub struct SupportScratch {
    stack: Vec<u32>,
    warm: Vec<u32>,
}

/// A ball tree over a fixed point set (row-major, `dim` coordinates per point).
#[derive(Debug, Clone)]
pub struct SupportTree {
    dim: usize,
    nodes: Vec<Node>,
    /// Points in tree order, row-major.
    points: Vec<Real>,
}

impl SupportTree {
    /// Builds the tree (`dim` <= [`MAX_DIM`]; the points must be finite and non-empty).
    pub fn new(points: &[Real], dim: usize) -> Self {
        assert!(dim <= MAX_DIM && dim > 0, "support tree dimension {dim}");
        let count = points.len() / dim;
        let mut order: Vec<u32> = (0..count as u32).collect();
        let mut nodes = Vec::with_capacity(2 * count / LEAF + 1);
        build(points, dim, &mut order, 0, count, &mut nodes);
        let mut sorted = Vec::with_capacity(points.len());
        for &i in &order {
            sorted.extend_from_slice(&points[i as usize * dim..(i as usize + 1) * dim]);
        }
        Self {
            dim,
            nodes,
            points: sorted,
        }
    }

    fn bound(&self, node: &Node, g: &[Real], g_norm: Real) -> Real {
        let mut ball = 0.0;
        let mut bbox = 0.0;
        for (k, x) in g.iter().enumerate() {
            ball += x * node.centre[k];
            bbox += (x * node.lo[k]).max(x * node.hi[k]);
        }
        (ball + g_norm * node.radius).min(bbox)
    }

    /// Largest `g . o` over the points, or `best` if none exceeds it, with the position (in
    /// tree order) of the point attaining it; `stack` is scratch space.
    fn search(&self, g: &[Real], mut best: Real, stack: &mut Vec<u32>) -> (Real, Option<u32>) {
        let mut arg = None;
        let d = self.dim;
        let g_norm = g.iter().map(|x| x * x).sum::<Real>().sqrt();
        stack.clear();
        stack.push(0);
        while let Some(i) = stack.pop() {
            let node = &self.nodes[i as usize];
            if self.bound(node, g, g_norm) <= best {
                continue;
            }
            if node.left == u32::MAX {
                let pts = &self.points[node.start as usize * d..node.end as usize * d];
                for (k, p) in pts.chunks_exact(d).enumerate() {
                    let v = dot(p, g);
                    if v > best {
                        best = v;
                        arg = Some(node.start + k as u32);
                    }
                }
                continue;
            }
            let (l, r) = (
                &self.nodes[node.left as usize],
                &self.nodes[node.right as usize],
            );
            let (bl, br) = (self.bound(l, g, g_norm), self.bound(r, g, g_norm));
            // Push the better child last so it is searched first.
            if bl > br {
                stack.extend([node.right, node.left]);
            } else {
                stack.extend([node.left, node.right]);
            }
        }
        (best, arg)
    }

    /// The exact support `max_k a . o_k` of direction `a`.
    pub fn support(&self, a: &[Real], stack: &mut Vec<u32>) -> Real {
        self.search(a, Real::NEG_INFINITY, stack).0
    }

    /// The exact support of every row-major direction in `dirs`, into `out`, with warm starts
    /// (see [`Self::support_warm`]).
    pub fn support_many(&self, dirs: &[Real], out: &mut [Real], scratch: &mut SupportScratch) {
        for (o, g) in out.iter_mut().zip(dirs.chunks_exact(self.dim)) {
            *o = self.support_warm(g, scratch);
        }
    }

    /// The exact support of `g`. Neighbouring directions (facets of one hull) mostly share
    /// their maximising points, so the points that won the last few queries made with the
    /// same `scratch` are tried first: their best value starts the search and prunes most of
    /// the tree.
    pub fn support_warm(&self, g: &[Real], scratch: &mut SupportScratch) -> Real {
        let d = self.dim;
        let mut start = Real::NEG_INFINITY;
        for &k in &scratch.warm {
            start = start.max(dot(&self.points[k as usize * d..(k as usize + 1) * d], g));
        }
        let (best, arg) = self.search(g, start, &mut scratch.stack);
        if let Some(k) = arg {
            if scratch.warm.len() == WARM {
                scratch.warm.remove(0);
            }
            scratch.warm.push(k);
        }
        best
    }

    /// The largest `g_f . o_k` over the row-major directions `dirs` and all points, with the
    /// direction attaining it; `None` if no value exceeds `floor`. `order` and `stack` are
    /// scratch space.
    pub fn max_over(
        &self,
        dirs: &[Real],
        floor: Real,
        order: &mut Vec<(Real, u32)>,
        stack: &mut Vec<u32>,
    ) -> Option<(usize, Real)> {
        let d = self.dim;
        let root = &self.nodes[0];
        order.clear();
        for (f, g) in dirs.chunks_exact(d).enumerate() {
            let g_norm = g.iter().map(|x| x * x).sum::<Real>().sqrt();
            order.push((self.bound(root, g, g_norm), f as u32));
        }
        order.sort_unstable_by(|a, b| b.0.total_cmp(&a.0));
        let mut best = floor;
        let mut arg = None;
        for &(bound, f) in order.iter() {
            if bound <= best {
                break;
            }
            let g = &dirs[f as usize * d..(f as usize + 1) * d];
            let (v, _) = self.search(g, best, stack);
            if v > best {
                best = v;
                arg = Some(f as usize);
            }
        }
        arg.map(|f| (f, best))
    }
}

/// Builds the subtree over `order[start..end]`, returns its index.
fn build(
    points: &[Real],
    dim: usize,
    order: &mut [u32],
    start: usize,
    end: usize,
    nodes: &mut Vec<Node>,
) -> u32 {
    let p = |i: u32| &points[i as usize * dim..(i as usize + 1) * dim];
    let mut centre = [0.0; MAX_DIM];
    let n = (end - start) as Real;
    for &i in &order[start..end] {
        for (c, x) in centre.iter_mut().zip(p(i)) {
            *c += x / n;
        }
    }
    let radius = order[start..end]
        .iter()
        .map(|&i| {
            p(i).iter()
                .zip(&centre)
                .map(|(x, c)| (x - c) * (x - c))
                .sum::<Real>()
                .sqrt()
        })
        .fold(0.0, Real::max);
    // Inflate slightly so rounding in the bound never prunes a point that could win.
    let radius = radius * (1.0 + 1e-12) + 1e-300;
    let mut lo = [0.0; MAX_DIM];
    let mut hi = [0.0; MAX_DIM];
    for k in 0..dim {
        let (l, h) = order[start..end]
            .iter()
            .fold((Real::INFINITY, Real::NEG_INFINITY), |(l, h), &i| {
                (l.min(p(i)[k]), h.max(p(i)[k]))
            });
        let pad = 1e-12 * l.abs().max(h.abs()) + 1e-300;
        lo[k] = l - pad;
        hi[k] = h + pad;
    }
    let index = nodes.len() as u32;
    nodes.push(Node {
        centre,
        radius,
        lo,
        hi,
        left: u32::MAX,
        right: u32::MAX,
        start: start as u32,
        end: end as u32,
    });
    if end - start > LEAF {
        // Split at the median of the coordinate of largest spread.
        let axis = (0..dim)
            .max_by(|&a, &b| {
                let spread = |k: usize| {
                    let (lo, hi) = order[start..end]
                        .iter()
                        .fold((Real::INFINITY, Real::NEG_INFINITY), |(lo, hi), &i| {
                            (lo.min(p(i)[k]), hi.max(p(i)[k]))
                        });
                    hi - lo
                };
                spread(a).total_cmp(&spread(b))
            })
            .unwrap_or(0);
        let mid = start + (end - start) / 2;
        order[start..end]
            .select_nth_unstable_by(mid - start, |&a, &b| p(a)[axis].total_cmp(&p(b)[axis]));
        let left = build(points, dim, order, start, mid, nodes);
        let right = build(points, dim, order, mid, end, nodes);
        nodes[index as usize].left = left;
        nodes[index as usize].right = right;
    }
    index
}

#[cfg(test)]
mod tests {
    use super::*;

    fn points(count: usize, dim: usize, seed: u64) -> Vec<Real> {
        let mut s = seed;
        (0..count * dim)
            .map(|_| {
                s = s
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                (s >> 11) as Real / (1u64 << 53) as Real - 0.5
            })
            .collect()
    }

    fn brute(pts: &[Real], dim: usize, a: &[Real]) -> Real {
        pts.chunks_exact(dim)
            .map(|p| dot(p, a))
            .fold(Real::NEG_INFINITY, Real::max)
    }

    #[test]
    fn support_equals_brute_force() {
        for dim in [3, 6] {
            let pts = points(3000, dim, 7);
            let tree = SupportTree::new(&pts, dim);
            let mut stack = Vec::new();
            for a in points(50, dim, 11).chunks_exact(dim) {
                assert_eq!(tree.support(a, &mut stack), brute(&pts, dim, a));
            }
        }
    }

    #[test]
    fn support_many_equals_brute_force() {
        let dim = 6;
        let pts = points(3000, dim, 13);
        let tree = SupportTree::new(&pts, dim);
        let dirs = points(300, dim, 17);
        let mut out = vec![0.0; 300];
        tree.support_many(&dirs, &mut out, &mut SupportScratch::default());
        for (o, a) in out.iter().zip(dirs.chunks_exact(dim)) {
            assert_eq!(*o, brute(&pts, dim, a));
        }
    }

    #[test]
    fn max_over_equals_brute_force() {
        let dim = 6;
        let pts = points(2000, dim, 3);
        let tree = SupportTree::new(&pts, dim);
        let dirs = points(200, dim, 5);
        let (mut order, mut stack) = (Vec::new(), Vec::new());
        let (f, v) = tree
            .max_over(&dirs, Real::NEG_INFINITY, &mut order, &mut stack)
            .unwrap();
        let want = dirs
            .chunks_exact(dim)
            .map(|a| brute(&pts, dim, a))
            .fold(Real::NEG_INFINITY, Real::max);
        assert_eq!(v, want);
        assert_eq!(brute(&pts, dim, &dirs[f * dim..(f + 1) * dim]), want);
        assert!(tree.max_over(&dirs, want, &mut order, &mut stack).is_none());
    }

    #[test]
    fn tiny_sets_work() {
        let tree = SupportTree::new(&[1.0, 2.0, 3.0], 3);
        assert_eq!(tree.support(&[1.0, 0.0, 0.0], &mut Vec::new()), 1.0);
    }
}
