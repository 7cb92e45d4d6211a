//! The OWS support function with bounds: a tree of bounding ellipsoids over the object wrenches, built once per
//! object, so that `max_k a . o_k` skips whole clusters of OWS points.
//!
//! Each node keeps its centre `c` (the mean), a bounding ellipsoid `{c + L y : |y| <= 1}` with
//! `L L^T = s^2 (C + eps I)` (`C` the covariance of its points, `s` the largest Mahalanobis
//! distance, `eps` a tiny regularisation) and its bounding box `[lo, hi]`. No point of the
//! node can exceed `min(a . c + |L^T a|, sum_i max(a_i lo_i, a_i hi_i))` (the ellipsoid's
//! `L^T` is stored packed, so its bound is 21 multiply-adds in 6D). The ellipsoid is what
//! makes the bound tight deep in the tree: the points that nearly maximise `a . o` lie on a
//! curved patch roughly normal to `a`, thin along `a`, where a ball bound is as loose as the
//! patch is wide; flat sets (a sphere's object wrenches have no torque) cost nothing in their
//! missing directions.
//!
//! Near the root the ellipsoid is loose: the force block of every object wrench is a unit
//! normal, so a large node's points fill a sphere in force space, while their small torques
//! (zero up to rounding and facet shape on a sphere) have heavy tails, and scaling the
//! covariance ellipsoid to contain the outliers there inflates it in every direction. So each
//! node also keeps the radii `r_1`, `r_2` of its points about `c` in the force and torque
//! blocks, and the block-ball bound `a . c + |a_1| r_1 + |a_2| r_2` (two multiply-adds once
//! the block norms of `a` are known) is tried first; the others are evaluated only when it
//! does not already prune the node. On the benchmark sphere this takes alpha* from 63 full
//! searches (of 216 facets) to 2. Two queries use the tree:
//! - [`SupportTree::support`]: the exact support `h(a)` of one direction, branch and bound
//!   (children visited best bound first, a node skipped when its bound cannot beat the best
//!   point found so far);
//! - [`SupportTree::max_over`]: the largest `g_f . o_k` over many directions `g_f` at once:
//!   the direction with the largest root bound is searched first, then the others whose root
//!   bound exceeds its value, in order of that bound, stopping as soon as none can win. With `g_f = a_f / b_f` (facet normal over offset) its inverse is alpha*: a facet is
//!   skipped, without touching one OWS point, whenever a lower bound on its ratio `b_f / h_f`
//!   already exceeds the best ratio found.
//!
//! Both are exact (up to the rounding of the dot products); the dense product through faer
//! ([`crate::quality::GraspProblem::support_function_dense`]) is the reference they are
//! tested against.

use crate::hull::dot;
use crate::math::Real;
use crate::progress::{EVERY, Progress, Silent, Stage};

/// Points per leaf.
const LEAF: usize = 32;
/// Largest supported dimension.
pub const MAX_DIM: usize = 6;
/// Entries of a packed upper-triangular `MAX_DIM x MAX_DIM` matrix.
const PACKED: usize = MAX_DIM * (MAX_DIM + 1) / 2;

/// Start of row `j` of a packed upper-triangular `dim x dim` matrix (rows `j..dim` wide).
#[inline(always)]
const fn packed_row(j: usize, dim: usize) -> usize {
    j * dim - j * (j.saturating_sub(1)) / 2
}

#[derive(Debug, Clone)]
struct Node {
    centre: [Real; MAX_DIM],
    /// The ellipsoid's factor `U = L^T` (upper triangular, `L L^T` the ellipsoid matrix),
    /// packed by rows: row `j` holds `U[j][j..dim]` from [`packed_row`]`(j, dim)`.
    factor: [Real; PACKED],
    lo: [Real; MAX_DIM],
    hi: [Real; MAX_DIM],
    /// Radii of the node's points about the centre in the two coordinate blocks
    /// (`..split(dim)` and `split(dim)..`: force and torque), padded for rounding.
    radii: [Real; 2],
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
    pub(crate) stack: Vec<(Real, u32)>,
    warm: Vec<u32>,
}

/// A tree of bounding ellipsoids over a fixed point set (row-major, `dim` coordinates per point).
#[derive(Debug, Clone)]
pub struct SupportTree {
    dim: usize,
    nodes: Vec<Node>,
    /// Points in tree order, row-major.
    points: Vec<Real>,
    /// Neighbours of each point (tree order), CSR: for hill climbing to a warm start.
    neighbour_offsets: Vec<u32>,
    neighbours: Vec<u32>,
}

impl SupportTree {
    /// Builds the tree (`dim` <= [`MAX_DIM`]; the points must be finite and non-empty).
    /// `neighbours(i)` lists the points adjacent to point `i` (e.g. the facets sharing an
    /// edge with facet `i`), used only to climb to a good starting value; any graph, even an
    /// empty one, gives exact results.
    ///
    /// # Panics
    /// If `dim` is 0 or above [`MAX_DIM`] (wrench spaces have 3 or 6 dimensions).
    pub fn new<'a>(points: &[Real], dim: usize, neighbours: impl Fn(usize) -> &'a [u32]) -> Self {
        Self::new_with(points, dim, neighbours, &mut Silent)
    }

    /// [`SupportTree::new`], reporting [`Stage::SupportTree`] to `progress` (the points
    /// placed in leaves so far).
    ///
    /// # Panics
    /// As [`SupportTree::new`].
    pub fn new_with<'a>(
        points: &[Real],
        dim: usize,
        neighbours: impl Fn(usize) -> &'a [u32],
        progress: &mut dyn Progress,
    ) -> Self {
        assert!(dim <= MAX_DIM && dim > 0, "support tree dimension {dim}");
        let count = points.len() / dim;
        let mut order: Vec<u32> = (0..count as u32).collect();
        let mut nodes = Vec::with_capacity(2 * count / LEAF + 1);
        progress.report(Stage::SupportTree, 0, count);
        let mut placed = Placed {
            progress,
            done: 0,
            reported: 0,
            total: count,
        };
        build(points, dim, &mut order, 0, count, &mut nodes, &mut placed);
        let mut sorted = Vec::with_capacity(points.len());
        let mut position = vec![0u32; count];
        for (pos, &i) in order.iter().enumerate() {
            sorted.extend_from_slice(&points[i as usize * dim..(i as usize + 1) * dim]);
            position[i as usize] = pos as u32;
        }
        let mut neighbour_offsets = Vec::with_capacity(count + 1);
        let mut adjacent = Vec::new();
        neighbour_offsets.push(0);
        for &i in &order {
            adjacent.extend(
                neighbours(i as usize)
                    .iter()
                    .filter(|&&j| (j as usize) < count)
                    .map(|&j| position[j as usize]),
            );
            neighbour_offsets.push(adjacent.len() as u32);
        }
        placed.progress.report(Stage::SupportTree, count, count);
        Self {
            dim,
            nodes,
            points: sorted,
            neighbour_offsets,
            neighbours: adjacent,
        }
    }

    fn point(&self, k: u32) -> &[Real] {
        &self.points[k as usize * self.dim..(k as usize + 1) * self.dim]
    }

    /// An upper bound on `g . o` over the node's points (`norms`: [`Self::block_norms`] of
    /// `g`): the smallest of the block-ball, ellipsoid and box bounds, or only the cheap
    /// block-ball bound when that is already at most `best` (the node is pruned either way).
    #[inline(always)]
    fn bound(&self, node: &Node, g: &[Real], norms: [Real; 2], best: Real) -> Real {
        match self.dim {
            6 => bound_fixed::<6>(node, g, norms, best),
            3 => bound_fixed::<3>(node, g, norms, best),
            _ => bound_any(node, g, norms, best),
        }
    }

    /// The norms of `g`'s two coordinate blocks.
    #[inline(always)]
    fn block_norms(&self, g: &[Real]) -> [Real; 2] {
        let (a, b) = g.split_at(split(self.dim));
        [dot(a, a).sqrt(), dot(b, b).sqrt()]
    }

    /// Largest `g . o` over the points, or `best` if none exceeds it, with the position (in
    /// tree order) of the point attaining it; `stack` is scratch space.
    fn search(
        &self,
        g: &[Real],
        mut best: Real,
        stack: &mut Vec<(Real, u32)>,
    ) -> (Real, Option<u32>) {
        let mut arg = None;
        let d = self.dim;
        let norms = self.block_norms(g);
        stack.clear();
        stack.push((Real::INFINITY, 0));
        while let Some((bound, i)) = stack.pop() {
            if bound <= best {
                continue;
            }
            let node = &self.nodes[i as usize];
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
            let (bl, br) = (self.bound(l, g, norms, best), self.bound(r, g, norms, best));
            // Push the better child last so it is searched first.
            if bl > br {
                stack.extend([(br, node.right), (bl, node.left)]);
            } else {
                stack.extend([(bl, node.left), (br, node.right)]);
            }
        }
        (best, arg)
    }

    /// The exact support `max_k a . o_k` of direction `a`.
    pub fn support(&self, a: &[Real], stack: &mut Vec<(Real, u32)>) -> Real {
        self.search(a, Real::NEG_INFINITY, stack).0
    }

    /// The exact support of direction `a` if it exceeds `threshold`, `None` if no point's
    /// `a . o_k` does (a decision that prunes every node whose bound is at most `threshold`,
    /// so it is cheap when the support is well below it).
    pub fn support_above(
        &self,
        a: &[Real],
        threshold: Real,
        stack: &mut Vec<(Real, u32)>,
    ) -> Option<Real> {
        match self.search(a, threshold, stack) {
            (h, Some(_)) => Some(h),
            (_, None) => None,
        }
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
        // Best remembered point, then climb the neighbourhood graph while it improves.
        let mut at = None;
        let mut start = Real::NEG_INFINITY;
        for &k in &scratch.warm {
            let v = dot(self.point(k), g);
            if v > start {
                start = v;
                at = Some(k);
            }
        }
        if let Some(mut k) = at {
            loop {
                let range = self.neighbour_offsets[k as usize] as usize
                    ..self.neighbour_offsets[k as usize + 1] as usize;
                let mut next = k;
                for &j in &self.neighbours[range] {
                    let v = dot(self.point(j), g);
                    if v > start {
                        start = v;
                        next = j;
                    }
                }
                if next == k {
                    break;
                }
                k = next;
            }
            at = Some(k);
        }
        let (best, arg) = self.search(g, start, &mut scratch.stack);
        if let Some(k) = arg.or(at) {
            if let Some(pos) = scratch.warm.iter().position(|&w| w == k) {
                scratch.warm.remove(pos);
            } else if scratch.warm.len() == WARM {
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
        stack: &mut Vec<(Real, u32)>,
    ) -> Option<(usize, Real)> {
        let d = self.dim;
        let root = &self.nodes[0];
        let dir = |f: u32| &dirs[f as usize * d..(f as usize + 1) * d];
        // Root bounds by the cheap block-ball bound alone (`bound` with `best = inf`); the
        // full bound is evaluated only for a direction about to be searched.
        order.clear();
        for (f, g) in dirs.chunks_exact(d).enumerate() {
            let norms = self.block_norms(g);
            order.push((self.bound(root, g, norms, Real::INFINITY), f as u32));
        }
        let mut best = floor;
        let mut arg = None;
        let mut consider = |f: u32, best: &mut Real, stack: &mut Vec<(Real, u32)>| {
            let g = dir(f);
            if self.bound(root, g, self.block_norms(g), *best) <= *best {
                return;
            }
            let (v, _) = self.search(g, *best, stack);
            if v > *best {
                *best = v;
                arg = Some(f as usize);
            }
        };
        // The most promising direction first: its value usually prunes all the others, so
        // the rest is filtered before it is sorted.
        if let Some(top) = (0..order.len()).max_by(|&i, &j| order[i].0.total_cmp(&order[j].0)) {
            let (bound, f) = order.swap_remove(top);
            if bound > best {
                consider(f, &mut best, stack);
            }
        }
        order.retain(|&(bound, _)| bound > best);
        order.sort_unstable_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
        for &(bound, f) in order.iter() {
            if bound <= best {
                break;
            }
            consider(f, &mut best, stack);
        }
        arg.map(|f| (f, best))
    }
}

/// Points placed in leaves while the tree is built, reported every [`EVERY`] points.
struct Placed<'p> {
    progress: &'p mut dyn Progress,
    done: usize,
    reported: usize,
    total: usize,
}

impl Placed<'_> {
    fn leaf(&mut self, points: usize) {
        self.done += points;
        if self.done - self.reported >= EVERY && self.done < self.total {
            self.reported = self.done;
            self.progress
                .report(Stage::SupportTree, self.done, self.total);
        }
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
    placed: &mut Placed<'_>,
) -> u32 {
    let p = |i: u32| &points[i as usize * dim..(i as usize + 1) * dim];
    let mut centre = [0.0; MAX_DIM];
    let n = (end - start) as Real;
    for &i in &order[start..end] {
        for (c, x) in centre.iter_mut().zip(p(i)) {
            *c += x / n;
        }
    }
    let (shape, factor) = bounding_ellipsoid(order[start..end].iter().map(|&i| p(i)), &centre, dim);
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
    // Block radii, padded by 1e-10 relative plus 1e-14 (|c| + max |o|), which exceeds the
    // rounding of both `g . o` and the bound (the errors are ~6 eps |g| (|o| + |c|)).
    let split = split(dim);
    let mut radii = [0.0; 2];
    let mut reach: Real = 0.0;
    for &i in &order[start..end] {
        let x = p(i);
        let (mut r0, mut r1) = (0.0, 0.0);
        for k in 0..dim {
            let dk = (x[k] - centre[k]).powi(2);
            if k < split {
                r0 += dk;
            } else {
                r1 += dk;
            }
        }
        radii[0] = Real::max(radii[0], r0);
        radii[1] = Real::max(radii[1], r1);
        reach = reach.max(dot(x, x));
    }
    let pad = 1e-14 * (dot(&centre[..dim], &centre[..dim]).sqrt() + reach.sqrt());
    let radii = radii.map(|r2| r2.sqrt() * (1.0 + 1e-10) + pad);
    let index = nodes.len() as u32;
    nodes.push(Node {
        centre,
        factor,
        lo,
        hi,
        radii,
        left: u32::MAX,
        right: u32::MAX,
        start: start as u32,
        end: end as u32,
    });
    if end - start > LEAF {
        // Split at the median along the principal axis of the node's ellipsoid (power
        // iteration), so that leaves are compact, nearly flat patches.
        let mut axis = [1.0; MAX_DIM];
        for _ in 0..30 {
            let mut next = [0.0; MAX_DIM];
            for i in 0..dim {
                next[i] = (0..dim).map(|j| shape[i][j] * axis[j]).sum();
            }
            let norm = next[..dim].iter().map(|x| x * x).sum::<Real>().sqrt();
            if norm == 0.0 {
                break;
            }
            for k in 0..dim {
                axis[k] = next[k] / norm;
            }
        }
        let key = |i: u32| dot(p(i), &axis[..dim]);
        let mid = start + (end - start) / 2;
        order[start..end].select_nth_unstable_by(mid - start, |&a, &b| key(a).total_cmp(&key(b)));
        let left = build(points, dim, order, start, mid, nodes, placed);
        let right = build(points, dim, order, mid, end, nodes, placed);
        nodes[index as usize].left = left;
        nodes[index as usize].right = right;
    } else {
        placed.leaf(end - start);
    }
    index
}

/// An ellipsoid about `centre` containing the points: its matrix `M = L L^T = s^2 (C + eps
/// I)`, `C` their covariance, `eps = 1e-12 trace(C)` (so flat sets work), `s` the largest
/// Mahalanobis distance, inflated so rounding never excludes a point; and `L^T` packed (see
/// [`Node::factor`]), so that `sqrt(g^T M g) = |L^T g|`.
// The loops index the covariance and the factor by row and column at once.
#[allow(clippy::needless_range_loop)]
fn bounding_ellipsoid<'a>(
    points: impl Iterator<Item = &'a [Real]> + Clone,
    centre: &[Real; MAX_DIM],
    dim: usize,
) -> ([[Real; MAX_DIM]; MAX_DIM], [Real; PACKED]) {
    let n = points.clone().count().max(1) as Real;
    // Accumulated on the stack (the heap matrix's stores were the build's hot spot), with
    // the same operations in the same order, so the covariance is the same to the bit.
    let mut lower = [[0.0; MAX_DIM]; MAX_DIM];
    for p in points.clone() {
        for i in 0..dim {
            for j in 0..=i {
                lower[i][j] += (p[i] - centre[i]) * (p[j] - centre[j]) / n;
            }
        }
    }
    let mut cov = nalgebra::DMatrix::<Real>::zeros(dim, dim);
    for i in 0..dim {
        for j in 0..=i {
            cov[(i, j)] = lower[i][j];
        }
    }
    let trace: Real = (0..dim).map(|i| cov[(i, i)]).sum();
    let eps = (1e-12 * trace).max(Real::MIN_POSITIVE);
    for i in 0..dim {
        cov[(i, i)] += eps;
        for j in 0..i {
            cov[(j, i)] = cov[(i, j)];
        }
    }
    let mut shape = [[0.0; MAX_DIM]; MAX_DIM];
    let mut factor = [0.0; PACKED];
    let Some(chol) = cov.clone().cholesky() else {
        // Cannot happen for a regularised covariance; fall back to the bounding ball.
        let r2 = points
            .map(|p| (0..dim).map(|k| (p[k] - centre[k]).powi(2)).sum::<Real>())
            .fold(0.0, Real::max)
            * (1.0 + 1e-8);
        for (i, row) in shape.iter_mut().enumerate().take(dim) {
            row[i] = r2;
            factor[packed_row(i, dim)] = r2.sqrt();
        }
        return (shape, factor);
    };
    let l = chol.l();
    let mut lower = [[0.0; MAX_DIM]; MAX_DIM];
    for (i, row) in lower.iter_mut().enumerate().take(dim) {
        for (j, x) in row.iter_mut().enumerate().take(i + 1) {
            *x = l[(i, j)];
        }
    }
    let mut s2: Real = 0.0;
    for p in points {
        s2 = s2.max(mahalanobis_squared(&lower, p, centre, dim));
    }
    // Inflate so that rounding (here and in the bound) never excludes a point.
    let s2 = s2 * (1.0 + 1e-8) + Real::MIN_POSITIVE;
    for (i, row) in shape.iter_mut().enumerate().take(dim) {
        for (j, m) in row.iter_mut().enumerate().take(dim) {
            *m = s2 * cov[(i, j)];
        }
    }
    let s = s2.sqrt();
    for j in 0..dim {
        for i in j..dim {
            factor[packed_row(j, dim) + i - j] = s * l[(i, j)];
        }
    }
    (shape, factor)
}

/// `|y|^2` for `L y = p - centre` (`lower`: `L`, lower triangular), in place on the stack:
/// the same operations, in the same order, as nalgebra's `solve_lower_triangular` and
/// `norm_squared` on a dynamic vector (forward substitution by columns, `y_j <- (-y_i) L_ji +
/// y_j`; the squares summed from the first), so the result is the same to the bit, without
/// the vector's allocation per point and node (2 million points and 16 levels in a
/// 2-million-triangle mesh). A zero on the diagonal (never, for a regularised covariance)
/// gives `|p - centre|^2`, as nalgebra's refusal did.
#[allow(clippy::needless_range_loop)]
fn mahalanobis_squared(
    lower: &[[Real; MAX_DIM]; MAX_DIM],
    p: &[Real],
    centre: &[Real; MAX_DIM],
    dim: usize,
) -> Real {
    let mut y = [0.0; MAX_DIM];
    for k in 0..dim {
        y[k] = p[k] - centre[k];
    }
    let dev = y;
    let mut solved = true;
    for i in 0..dim {
        let diag = lower[i][i];
        if diag == 0.0 {
            solved = false;
            break;
        }
        let coeff = y[i] / diag;
        y[i] = coeff;
        for j in i + 1..dim {
            y[j] += -coeff * lower[j][i]; // = (-coeff L_ji) + y_j: addition commutes, bit for bit
        }
    }
    let y = if solved { &y } else { &dev };
    let mut sum = 0.0;
    for x in &y[..dim] {
        sum += x * x;
    }
    sum
}

/// The two coordinate blocks of the bounds split at this index: force `..3` and torque `3..`
/// in 6D, `(f_x, f_y)` and `tau_z` in the plane. The force block of every object wrench is a
/// unit normal, so the block-ball bound is tight where the ellipsoid of a round set is not.
const fn split(dim: usize) -> usize {
    dim - dim / 2
}

/// The node bound for a fixed dimension (unrolled): the block-ball bound
/// `g . c + |g_1| r_1 + |g_2| r_2`, returned alone when it is at most `best`, else its minimum
/// with the ellipsoid bound `g . c + |L^T g|` and the box bound.
// The loops index `g` and several node arrays at once.
#[allow(clippy::needless_range_loop)]
#[inline(always)]
fn bound_fixed<const D: usize>(node: &Node, g: &[Real], norms: [Real; 2], best: Real) -> Real {
    let Ok(g) = <&[Real; D]>::try_from(g) else {
        return bound_any(node, g, norms, best);
    };
    let mut centre = 0.0;
    for i in 0..D {
        centre += g[i] * node.centre[i];
    }
    let ball = centre + norms[0] * node.radii[0] + norms[1] * node.radii[1];
    if ball <= best {
        return ball;
    }
    let mut bbox = 0.0;
    for i in 0..D {
        bbox += (g[i] * node.lo[i]).max(g[i] * node.hi[i]);
    }
    let mut quad = 0.0;
    for j in 0..D {
        let row = &node.factor[packed_row(j, D)..packed_row(j, D) + D - j];
        let mut s = 0.0;
        for i in j..D {
            s += row[i - j] * g[i];
        }
        quad += s * s;
    }
    (centre + quad.sqrt()).min(bbox).min(ball)
}

/// [`bound_fixed`] for any dimension.
fn bound_any(node: &Node, g: &[Real], norms: [Real; 2], best: Real) -> Real {
    let dim = g.len();
    let centre = dot(g, &node.centre[..dim]);
    let ball = centre + norms[0] * node.radii[0] + norms[1] * node.radii[1];
    if ball <= best {
        return ball;
    }
    let mut bbox = 0.0;
    for (i, gi) in g.iter().enumerate() {
        bbox += (gi * node.lo[i]).max(gi * node.hi[i]);
    }
    let mut quad = 0.0;
    for j in 0..dim {
        let row = &node.factor[packed_row(j, dim)..packed_row(j, dim) + dim - j];
        let s: Real = row.iter().zip(&g[j..]).map(|(u, x)| u * x).sum();
        quad += s * s;
    }
    (centre + quad.sqrt()).min(bbox).min(ball)
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

    /// The stack solve gives what nalgebra's dynamic solve and norm gave before it, to the
    /// bit, so the trees (and every bound, hence every search) are unchanged.
    #[test]
    fn mahalanobis_on_the_stack_equals_nalgebra_to_the_bit() {
        for (dim, seed) in [(3, 1), (6, 2), (6, 3)] {
            let pts = points(200, dim, seed);
            let mut centre = [0.0; MAX_DIM];
            for p in pts.chunks_exact(dim) {
                for k in 0..dim {
                    centre[k] += p[k] / 200.0;
                }
            }
            let mut cov = nalgebra::DMatrix::<Real>::zeros(dim, dim);
            for p in pts.chunks_exact(dim) {
                let d = nalgebra::DVector::from_iterator(dim, (0..dim).map(|k| p[k] - centre[k]));
                cov += &d * d.transpose() / 200.0;
            }
            let l = cov.cholesky().unwrap().l();
            let mut lower = [[0.0; MAX_DIM]; MAX_DIM];
            for i in 0..dim {
                for j in 0..=i {
                    lower[i][j] = l[(i, j)];
                }
            }
            for p in pts.chunks_exact(dim) {
                let dev = nalgebra::DVector::from_iterator(dim, (0..dim).map(|k| p[k] - centre[k]));
                let expected = l.solve_lower_triangular(&dev).unwrap().norm_squared();
                let got = mahalanobis_squared(&lower, p, &centre, dim);
                assert_eq!(
                    got.to_bits(),
                    expected.to_bits(),
                    "dim {dim}: {got} vs {expected}"
                );
            }
            // A zero on the diagonal: the plain squared distance, as before.
            let mut singular = lower;
            singular[1][1] = 0.0;
            let p = &pts[..dim];
            let plain: Real = (0..dim).map(|k| (p[k] - centre[k]).powi(2)).sum();
            let got = mahalanobis_squared(&singular, p, &centre, dim);
            assert!((got - plain).abs() <= 1e-15 * plain, "{got} vs {plain}");
        }
    }

    #[test]
    fn support_equals_brute_force() {
        for dim in [3, 6] {
            let pts = points(3000, dim, 7);
            let tree = SupportTree::new(&pts, dim, |_| &[]);
            let mut stack = Vec::new();
            for a in points(50, dim, 11).chunks_exact(dim) {
                assert_eq!(tree.support(a, &mut stack), brute(&pts, dim, a));
            }
        }
    }

    #[test]
    fn support_above_decides_and_is_exact_above() {
        let dim = 6;
        let pts = points(3000, dim, 19);
        let tree = SupportTree::new(&pts, dim, |_| &[]);
        let mut stack = Vec::new();
        for a in points(50, dim, 23).chunks_exact(dim) {
            let h = brute(&pts, dim, a);
            assert_eq!(tree.support_above(a, h, &mut stack), None);
            assert_eq!(tree.support_above(a, h + 0.1, &mut stack), None);
            assert_eq!(tree.support_above(a, h.next_down(), &mut stack), Some(h));
            assert_eq!(tree.support_above(a, h - 0.1, &mut stack), Some(h));
        }
    }

    #[test]
    fn support_many_equals_brute_force() {
        let dim = 6;
        let pts = points(3000, dim, 13);
        let tree = SupportTree::new(&pts, dim, |_| &[]);
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
        let tree = SupportTree::new(&pts, dim, |_| &[]);
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

    /// Object wrenches of real objects (unit force blocks, small or zero torques: near ties
    /// in every direction) against the brute force, for random directions, pure-force
    /// directions (where a sphere's points tie closest) and `max_over`.
    #[test]
    fn ows_support_equals_brute_force() {
        use crate::math::Vec3;
        use crate::wrench::{Space, WrenchFrame};
        let objects = [
            crate::object::Object::sphere(0.0475, 36, 36).unwrap(),
            crate::object::Object::ellipsoid(Vec3::new(0.06, 0.045, 0.035), 40, 30).unwrap(),
            crate::object::Object::cuboid(Vec3::new(0.04, 0.03, 0.025), 5).unwrap(),
        ];
        for object in &objects {
            for space in [Space::Spatial, Space::Planar] {
                let frame =
                    WrenchFrame::new(object.centre_of_mass, object.max_radius(), space).unwrap();
                let dim = frame.dim();
                let mut ows = vec![0.0; dim * object.facets.points.len()];
                for ((l, n), o) in object
                    .facets
                    .points
                    .iter()
                    .zip(&object.facets.normals)
                    .zip(ows.chunks_exact_mut(dim))
                {
                    frame.object_wrench(l, n, o);
                }
                let tree = SupportTree::new(&ows, dim, |i| object.facets.adjacency.neighbours(i));
                let mut dirs = points(300, dim, 29);
                // Pure force directions, and nearly pure ones.
                for (f, a) in dirs.chunks_exact_mut(dim).enumerate() {
                    let split = split(dim);
                    for x in &mut a[split..] {
                        *x *= if f % 3 == 0 { 0.0 } else { 1e-3 };
                    }
                }
                let mut stack = Vec::new();
                let mut scratch = SupportScratch::default();
                for a in dirs.chunks_exact(dim) {
                    let want = brute(&ows, dim, a);
                    assert_eq!(tree.support(a, &mut stack), want);
                    assert_eq!(tree.support_warm(a, &mut scratch), want);
                    assert_eq!(tree.support_above(a, want, &mut stack), None);
                    assert_eq!(
                        tree.support_above(a, want.next_down(), &mut stack),
                        Some(want)
                    );
                }
                let want = dirs
                    .chunks_exact(dim)
                    .map(|a| brute(&ows, dim, a))
                    .fold(Real::NEG_INFINITY, Real::max);
                let (mut order, mut stack) = (Vec::new(), Vec::new());
                let (_, v) = tree
                    .max_over(&dirs, Real::NEG_INFINITY, &mut order, &mut stack)
                    .unwrap();
                assert_eq!(v, want);
            }
        }
    }

    #[test]
    fn tiny_sets_work() {
        let tree = SupportTree::new(&[1.0, 2.0, 3.0], 3, |_| &[]);
        assert_eq!(tree.support(&[1.0, 0.0, 0.0], &mut Vec::new()), 1.0);
    }
}
