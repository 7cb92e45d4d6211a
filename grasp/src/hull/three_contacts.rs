//! The 6D hull of three contacts' primitive wrenches by enumerating its facets.
//!
//! # The structure it uses
//! The `s` primitive wrenches of one contact (edge-major, `phi_j = 2 pi j / s`, see
//! [`crate::wrench::WrenchFrame::primitive_wrenches`]) are
//! `w_j = c + cos(phi_j) U + sin(phi_j) V`: the image of the regular `s`-gon under an affine
//! map (`c` the wrench of the normal force, `U`, `V` those of `mu t1`, `mu t2`). So they are
//! the vertices, in cyclic order, of a strictly convex planar polygon `P_i` in R^6. A facet
//! `a . x = b` of the hull of `P_1 U P_2 U P_3` (all points `<= b`) meets each polygon in the
//! face `F_i` of `P_i` that maximises `a`: a vertex (dim 0), an edge (dim 1), the whole
//! polygon (dim 2) or nothing. The facet's points span a 5-flat, and `k` touched faces of dims
//! `d_i` span at most `sum d_i + k - 1` dimensions, so a facet touches
//! - three polygons with `d_1 + d_2 + d_3 >= 3`, or
//! - two polygons, both whole (`2 + 2 + 1 = 5`).
//!
//! In general position the sums are exactly 3: types (1,1,1) (an edge of each polygon) and
//! the six permutations of (2,1,0) (one whole polygon, an edge of another, a vertex of the
//! third), plus (2,2) (two whole polygons). Each such choice of faces has 6 points spanning a
//! 5-flat, i.e. exactly one hyperplane through them, and that hyperplane is a facet if and
//! only if every touched polygon lies below it, which (a linear function on a convex polygon
//! whose vertices are in cyclic order is unimodal along the cycle: a local maximum is global)
//! needs only the vertices next to each face: the two outer neighbours of an edge, the two
//! neighbours of a vertex; for an untouched polygon, all of its vertices. So the hull is
//! `s^3` (1,1,1) candidates, `6 s^2` (2,1,0) candidates and 3 (2,2) candidates, each a few
//! dozen flops:
//! - (1,1,1): for each edge of `P_1`, the 5-dimensional null space `F` of its two
//!   homogeneous constraints `[x; 1] . (a; -b) = 0` (Gaussian elimination with full
//!   pivoting), and the images `A_2`, `A_3` of the other two polygons' planes in it. Since
//!   those are affine regular polygons, the candidate of edges `e_2`, `e_3` is, up to a
//!   bounded error, bilinear in two constants of the edges (the normals `n = q_a x q_b` of
//!   `q_j = (1, cos phi_j, sin phi_j)`), with coefficients that are 5 x 5 cofactors computed
//!   once per edge of `P_1`: its values at the six neighbours are two 3-term dot products and
//!   two per-edge constants, which decide it (no facet, a facet, or unsure: then its exact
//!   values), and only facets compute their hyperplane `F g`
//!   (`Setup::edges_of_three` and `Setup::cofactor_bound` derive the error bound).
//! - (2,1,0): the whole polygon is the three constraints `[c; 1]`, `[U; 0]`, `[V; 0]` (its
//!   plane, from a least-squares fit, below): a 4-dimensional null space per polygon, in
//!   which a candidate (an edge of a second polygon, a vertex of the third) is, up to a
//!   bounded error, linear in the edge's normal `n`, with 4 x 4 determinants computed once
//!   per vertex as coefficients (`Setup::whole_edge_vertex`, `Setup::vertex_bound`); the
//!   candidates the screen cannot decide get the exact construction: the edge's two points
//!   give a 2-dimensional null space, and the vertex `lambda` by a 2D perpendicular.
//! - (2,2): six constraints, a one-dimensional null space; all points of the third polygon
//!   are tested.
//!
//! A degenerate configuration (a facet touching faces whose dims sum to more than the generic
//! count, e.g. an edge parallel to another polygon's plane, contacts on the equator of a
//! sphere) always shows up: either some generic candidate inside that facet has a rank-
//! deficient system, or its hyperplane is the facet and a neighbour of one of its faces lies
//! on it. Both make this construction decline.
//!
//! # Output
//! The same [`Hull`] as [`Hull::new`] (beneath-beyond): unit outward normals, offsets, per
//! facet the ascending indices of the input points within the tolerance of its hyperplane
//! (here exactly the points of its faces, since any other point that close makes the
//! construction decline), and the hull vertices: every point on a facet. That is exact here
//! (where [`Hull::new`] needs a rank test per point): a (1,1,1) or (2,1,0) facet holds 6
//! affinely independent points, a simplex, and a (2,2) facet two strictly convex polygons
//! whose planes span the 5-flat together, so every vertex of either polygon is extreme in
//! the facet, hence in the hull. Facets are in the canonical order of [`Hull`] (by their
//! point sets), so the result does not depend on which construction ran. A facet decided by
//! a screen (below) has the hyperplane of the fitted polygons where that passes within
//! `tol / 4` of its points (checked on them: the fit's residual, at most `1e-3 tol`, is
//! magnified by a poorly conditioned candidate), otherwise the one computed from its points,
//! as the others have.
//!
//! # Tolerances and when it declines
//! With `scale` the largest coordinate magnitude and `tol = 1e-10 * scale` (the tolerance of
//! [`super::beneath_beyond`], so that both agree on which points lie on a facet):
//! - input: exactly 3 contacts of `s` wrenches in R^6 with `3 <= s <=` [`MAX_EDGES`], finite,
//!   the largest coordinate magnitude within `[1e-50, 1e50]` (the screens multiply five
//!   coordinates);
//! - each contact's wrenches must fit `c + cos(phi_j) U + sin(phi_j) V` (least squares) within
//!   `1e-3 tol` in every coordinate (planar, in cyclic order, an affine regular polygon), and
//!   be clearly convex: the smallest singular value of `[U V]` times `1 - cos(2 pi / s)` (how
//!   far each vertex sticks out of its neighbours' chord) at least `100 tol`;
//! - a candidate's neighbour values are compared with the band `+-T`,
//!   `T = 1.5 tol + 64 eps scale / cond`, where `cond` (in `[0, 1]`) is the smallest pivot of
//!   the row-normalised elimination and of the final `lambda` step (0 for a rank-deficient
//!   system, which makes `T` infinite): the candidate is rejected when one neighbour is
//!   above `T` and another below `-T` (the polygons lie on both sides: no facet, whatever the
//!   rounding), accepted when all are beyond `T` on one side, and otherwise, a point within
//!   the band of a candidate or a system too ill-conditioned to tell, the construction
//!   declines ([`Decline::Ambiguous`]); the screens that decide most candidates from the
//!   fitted polygons (`Setup::edges_of_three`, `Setup::whole_edge_vertex`) use a wider band
//!   (this one bounded from above, plus their error bound) and leave what they cannot
//!   decide to this test;
//! - a repeated facet or fewer than 7 facets also decline (neither happens in exact
//!   arithmetic).
//!
//! A decline is not an error: the caller ([`Hull::of_contacts`]) then runs [`Hull::new`]. The
//! tests compare this construction with [`Hull::new`] facet for facet on thousands of random
//! grasps and count the declines.

// Loops over coordinates index several fixed-size arrays at once.
#![allow(clippy::needless_range_loop)]

use std::f64::consts::TAU;

use super::Hull;
use crate::math::Real;

/// Most cone edges handled (the candidates grow as `s^3`; point sets are `u64` bit sets).
pub const MAX_EDGES: usize = 16;

/// Dimension of the wrench space.
const D: usize = 6;
/// Homogeneous coordinates `[x - m; 1]`.
const W: usize = D + 1;
/// Most input points.
const MAX_POINTS: usize = 3 * MAX_EDGES;

/// Tolerance relative to the largest coordinate magnitude (that of beneath-beyond).
const RELATIVE_TOLERANCE: Real = super::beneath_beyond::RELATIVE_TOLERANCE;
/// Half-width of the band that makes a candidate ambiguous, in units of `tol`.
const BAND: Real = 1.5;
/// Rounding error of a candidate's values, in units of `eps * scale / cond`.
const ROUNDING: Real = 64.0;
/// Largest residual of a contact's polygon fit, in units of `tol`.
const FIT: Real = 1e-3;
/// Smallest distance of a polygon vertex from its neighbours' chord, in units of `tol`.
const CONVEX: Real = 100.0;
/// Rounding error of the (1,1,1) screen's values, in units of `eps R^4 O` (see
/// `Setup::cofactor_bound`).
const COFACTOR_ROUNDING: Real = 32768.0;

/// Why the enumeration declined (the caller then builds the hull by [`Hull::new`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum Decline {
    /// Not 3 contacts of `s` wrenches in R^6 with `3 <= s <=` [`MAX_EDGES`].
    Shape,
    /// A coordinate is NaN or infinite.
    NonFinite,
    /// A contact's wrenches are not (within the fit tolerance) a clearly convex affine
    /// regular polygon in cyclic order.
    NotPolygon {
        /// The contact.
        contact: usize,
    },
    /// A point lies within the band of a candidate hyperplane, or a candidate's system is too
    /// ill-conditioned to decide (a degenerate configuration).
    Ambiguous,
    /// The largest coordinate magnitude is outside `[1e-50, 1e50]`, where the screens'
    /// degree-5 products could overflow or their bounds underflow.
    Scale,
    /// The facets found are not a plausible hull (repeated, or fewer than 7).
    Inconsistent,
}

/// The hull of the primitive wrenches of 3 contacts with `edges`-edge friction cones in R^6
/// (`points`: `3 x edges` rows of 6, contact-major, edge-major within a contact), by facet
/// enumeration, or why it declined. See the module documentation.
///
/// Its work (`hull_in`) is compiled twice, the second time for AVX2 and FMA (with the steps it calls inlined),
/// and the CPU's version is chosen at run time: ~5 % faster on this project's benchmark
/// machine. The arithmetic is the same (no fused multiply-adds are formed without an explicit
/// `mul_add`), so both give identical results.
pub fn hull(points: &[Real], edges: usize) -> Result<Hull, Decline> {
    let mut out = Hull::empty();
    hull_in(points, edges, &mut Scratch::default(), &mut out)?;
    Ok(out)
}

/// The buffers of [`hull_in`], kept between hulls.
#[derive(Default)]
pub(crate) struct Scratch(Option<Facets>);

/// [`hull`] into `out` (replaced, and left as it was when the enumeration declines), with
/// the facets gathered in `scratch`: once both have met a hull of the size, nothing is
/// allocated.
#[multiversion::multiversion(targets("x86_64+avx2+fma"))]
pub(crate) fn hull_in(
    points: &[Real],
    edges: usize,
    scratch: &mut Scratch,
    out: &mut Hull,
) -> Result<(), Decline> {
    let s = edges;
    if !(3..=MAX_EDGES).contains(&s) || points.len() != 3 * s * D {
        return Err(Decline::Shape);
    }
    if points.iter().any(|x| !x.is_finite()) {
        return Err(Decline::NonFinite);
    }
    let setup = Setup::new(points, s)?;
    let found = scratch.0.get_or_insert_with(Facets::new);
    found.keys.clear();
    found.planes.clear();
    setup.edges_of_three(found)?;
    setup.whole_edge_vertex(found)?;
    setup.two_whole(found)?;
    found.write(out)
}

/// The facets found: point sets, unit normals, offsets.
struct Facets {
    /// Per facet found: its point set bit-reversed (so that descending keys are the
    /// canonical order of `Hull`) with its index in the low 16 bits, unused by the set.
    keys: Vec<u64>,
    planes: Vec<([Real; D], Real)>,
}

impl Facets {
    fn new() -> Self {
        Self {
            keys: Vec::with_capacity(256),
            planes: Vec::with_capacity(256),
        }
    }

    fn push(&mut self, set: u64, a: [Real; D], b: Real) {
        // Sets hold at most 48 points, so the reversed set leaves the low 16 bits free.
        self.keys
            .push(set.reverse_bits() | (self.planes.len() as u64 & 0xFFFF));
        self.planes.push((a, b));
    }

    /// Records the facet with points `set` on the hyperplane `h . [x - mean; 1] = 0` as
    /// `a . x = b`, `a = scale (h_0 .. h_5)` (`scale` = +-1 over their norm, the sign making
    /// the points below), `b = a . mean - scale h_6`.
    #[inline(always)]
    fn push_plane(&mut self, set: u64, h: &[Real; W], scale: Real, mean: &[Real; D]) {
        let mut a = [0.0; D];
        let mut am = 0.0;
        for k in 0..D {
            a[k] = h[k] * scale;
            am += h[k] * mean[k];
        }
        self.push(set, a, (am - h[D]) * scale);
    }

    /// Writes the hull of the facets found into `out`, unless they are inconsistent (then
    /// `out` is left as it was).
    #[inline(always)]
    fn write(&mut self, out: &mut Hull) -> Result<(), Decline> {
        let n = self.keys.len();
        if !(D + 1..=0xFFFF).contains(&n) {
            return Err(Decline::Inconsistent);
        }
        self.keys.sort_unstable_by(|x, y| y.cmp(x));
        if self.keys.windows(2).any(|w| w[0] >> 16 == w[1] >> 16) {
            return Err(Decline::Inconsistent);
        }
        let total: u32 = self.keys.iter().map(|k| (k >> 16).count_ones()).sum();
        let mut vertex_set = 0;
        out.dim = D;
        out.normals.clear();
        out.offsets.clear();
        out.facet_offsets.clear();
        out.facet_indices.clear();
        out.normals.reserve(n * D);
        out.offsets.reserve(n);
        out.facet_offsets.reserve(n + 1);
        out.facet_indices.reserve(total as usize);
        out.facet_offsets.push(0);
        for &key in &self.keys {
            let (a, b) = &self.planes[(key & 0xFFFF) as usize];
            out.normals.extend_from_slice(a);
            out.offsets.push(*b);
            let set = (key >> 16).reverse_bits() >> 16;
            vertex_set |= set;
            out.facet_indices.extend(members(set));
            out.facet_offsets.push(out.facet_indices.len() as u32);
        }
        // Every point on a facet is a vertex (see the module documentation).
        out.vertices.clear();
        out.vertices.extend(members(vertex_set));
        Ok(())
    }
}

/// The points of a point set (bit `i` for point `i`), ascending.
fn members(set: u64) -> Members {
    Members(set)
}

/// Iterator of [`members`] (its exact length is known, so collecting allocates once).
struct Members(u64);

impl Iterator for Members {
    type Item = u32;

    #[inline(always)]
    fn next(&mut self) -> Option<u32> {
        (self.0 != 0).then(|| {
            let i = self.0.trailing_zeros();
            self.0 &= self.0 - 1;
            i
        })
    }

    fn size_hint(&self) -> (usize, Option<usize>) {
        let n = self.0.count_ones() as usize;
        (n, Some(n))
    }
}

impl ExactSizeIterator for Members {}

/// What a candidate's neighbour values say.
enum Verdict {
    /// Points clearly on both sides: not a facet.
    Reject,
    /// All clearly on one side: a facet, with the orientation (`+1`: the values are negative).
    Accept(Real),
    /// Some value within the band.
    Ambiguous,
}

/// Classifies values against the band `+-threshold`.
#[inline(always)]
fn classify(values: &[Real], threshold: Real) -> Verdict {
    let (hi, lo) = extremes(values);
    if hi > threshold && lo < -threshold {
        Verdict::Reject
    } else if hi < -threshold {
        Verdict::Accept(1.0)
    } else if lo > threshold {
        Verdict::Accept(-1.0)
    } else {
        Verdict::Ambiguous
    }
}

/// Largest and smallest value.
#[inline(always)]
fn extremes(values: &[Real]) -> (Real, Real) {
    let (mut hi, mut lo) = (Real::NEG_INFINITY, Real::INFINITY);
    for &v in values {
        hi = hi.max(v);
        lo = lo.min(v);
    }
    (hi, lo)
}

/// `[f(0), f(1), ..]`, as `std::array::from_fn`, which the compiler leaves as calls in the
/// loops here (its closure wrapper is not inlined).
#[inline(always)]
fn array<T: Copy + Default, const N: usize>(mut f: impl FnMut(usize) -> T) -> [T; N] {
    let mut out = [T::default(); N];
    for (i, x) in out.iter_mut().enumerate() {
        *x = f(i);
    }
    out
}

/// `j mod s` for `j < 2 s`, without a division (the loops index polygon neighbours with
/// it, hundreds of times per hull).
#[inline(always)]
fn wrap(j: usize, s: usize) -> usize {
    if j >= s { j - s } else { j }
}

#[inline(always)]
fn dot<const N: usize>(a: &[Real; N], b: &[Real; N]) -> Real {
    let mut s = 0.0;
    for k in 0..N {
        s += a[k] * b[k];
    }
    s
}

/// The norm of a hyperplane's normal part (its first `D` coordinates).
#[inline(always)]
fn norm(h: &[Real; W]) -> Real {
    h[..D].iter().map(|x| x * x).sum::<Real>().sqrt()
}

#[inline(always)]
fn cross(p: &[Real; 3], q: &[Real; 3]) -> [Real; 3] {
    [
        p[1] * q[2] - p[2] * q[1],
        p[2] * q[0] - p[0] * q[2],
        p[0] * q[1] - p[1] * q[0],
    ]
}

/// `x ^ y` in R^5: the components `x_i y_j - x_j y_i` for `i < j`, in the order
/// (0,1), (0,2), (0,3), (0,4), (1,2), (1,3), (1,4), (2,3), (2,4), (3,4).
#[inline(always)]
fn wedge(x: &[Real; 5], y: &[Real; 5]) -> [Real; 10] {
    let m = |i: usize, j: usize| x[i] * y[j] - x[j] * y[i];
    [
        m(0, 1),
        m(0, 2),
        m(0, 3),
        m(0, 4),
        m(1, 2),
        m(1, 3),
        m(1, 4),
        m(2, 3),
        m(2, 4),
        m(3, 4),
    ]
}

/// The cofactor vector `c` of `x1, x2, x3, x4` in R^5 from `p = x1 ^ x2` and `q = x3 ^ x4`
/// ([`wedge`]): `c . x = det [x1, x2, x3, x4, x]`. Component `m` is `(-1)^m` times the
/// 4 x 4 minor without row `m`, by Laplace's expansion over the pairs of rows of `x1, x2`;
/// the rows `(i, j, sign)` pair `p_i q_j + p_j q_i`.
#[inline(always)]
fn cofactor(p: &[Real; 10], q: &[Real; 10]) -> [Real; 5] {
    const TERMS: [[(usize, usize, Real); 3]; 5] = [
        [(4, 9, 1.0), (5, 8, -1.0), (6, 7, 1.0)],
        [(1, 9, -1.0), (2, 8, 1.0), (3, 7, -1.0)],
        [(0, 9, 1.0), (2, 6, -1.0), (3, 5, 1.0)],
        [(0, 8, -1.0), (1, 6, 1.0), (3, 4, -1.0)],
        [(0, 7, 1.0), (1, 5, -1.0), (2, 4, 1.0)],
    ];
    array(|m| {
        TERMS[m]
            .iter()
            .map(|&(i, j, sign)| sign * (p[i] * q[j] + p[j] * q[i]))
            .sum()
    })
}

/// `x ^ y` in R^4: the components `x_i y_j - x_j y_i` for `i < j`, in the order
/// (0,1), (0,2), (0,3), (1,2), (1,3), (2,3).
#[inline(always)]
fn wedge4(x: &[Real; 4], y: &[Real; 4]) -> [Real; 6] {
    let m = |i: usize, j: usize| x[i] * y[j] - x[j] * y[i];
    [m(0, 1), m(0, 2), m(0, 3), m(1, 2), m(1, 3), m(2, 3)]
}

/// `det [x1, x2, x3, x4]` in R^4 from `p = x1 ^ x2` and `q = x3 ^ x4` ([`wedge4`]).
#[inline(always)]
fn det4(p: &[Real; 6], q: &[Real; 6]) -> Real {
    p[0] * q[5] - p[1] * q[4] + p[2] * q[3] + p[3] * q[2] - p[4] * q[1] + p[5] * q[0]
}

/// The cofactor vector `c` of `x1, x2, x3` in R^4 from `p = x1 ^ x2` ([`wedge4`]) and `x3`:
/// `c . x = det [x1, x2, x3, x]`.
#[inline(always)]
fn cofactor4(p: &[Real; 6], x: &[Real; 4]) -> [Real; 4] {
    [
        -x[1] * p[5] + x[2] * p[4] - x[3] * p[3],
        x[0] * p[5] - x[2] * p[2] + x[3] * p[1],
        -x[0] * p[4] + x[1] * p[2] - x[3] * p[0],
        x[0] * p[3] - x[1] * p[1] + x[2] * p[0],
    ]
}

/// A basis of the null space of `R` homogeneous constraints in R^N (`R + K = N`).
struct NullSpace<const N: usize, const K: usize> {
    basis: [[Real; N]; K],
    /// Smallest pivot of the elimination of the constraints scaled by their reference
    /// norms, at most 1 (0 for a rank-deficient system).
    pivot: Real,
    /// Frobenius norm of the basis (`>= 1`).
    norm: Real,
}

impl<const N: usize, const K: usize> NullSpace<N, K> {
    /// `N^T y`: the basis vectors' values at `y` (the coordinates of the constraint `y` in
    /// the null space).
    #[inline(always)]
    fn at(&self, y: &[Real; N]) -> [Real; K] {
        array(|t| dot(&self.basis[t], y))
    }

    /// The vector `N lambda`.
    #[inline(always)]
    fn combine(&self, lambda: &[Real; K]) -> [Real; N] {
        let mut h = [0.0; N];
        for t in 0..K {
            for c in 0..N {
                h[c] += lambda[t] * self.basis[t][c];
            }
        }
        h
    }
}

/// Null space by Gaussian elimination with full pivoting on the constraints divided by
/// their reference norms `scales` (so a pivot is, up to the basis' conditioning, the
/// distance of a constraint from the span of the earlier ones relative to its own size); the
/// basis vector of each free column has that coordinate 1 and the other free ones 0. A
/// rank-deficient system gives `pivot = 0` and a zero basis.
#[inline(always)]
fn null_space<const N: usize, const R: usize, const K: usize>(
    rows: [[Real; N]; R],
    scales: [Real; R],
) -> NullSpace<N, K> {
    debug_assert_eq!(R + K, N);
    let mut m = rows;
    for i in 0..R {
        let inv = 1.0 / scales[i];
        for x in m[i].iter_mut() {
            *x *= inv;
        }
    }
    let mut perm: [usize; N] = array(|j| j);
    let mut pivot: Real = 1.0;
    for k in 0..R {
        let (mut bi, mut bj, mut best) = (k, k, 0.0);
        for i in k..R {
            for j in k..N {
                let v = m[i][j].abs();
                if v > best {
                    (bi, bj, best) = (i, j, v);
                }
            }
        }
        // `!(best > 0)` also catches NaN (from a zero scale).
        if best.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
            return NullSpace {
                basis: [[0.0; N]; K],
                pivot: 0.0,
                norm: 0.0,
            };
        }
        pivot = pivot.min(best);
        m.swap(k, bi);
        if bj != k {
            for row in m.iter_mut() {
                row.swap(k, bj);
            }
            perm.swap(k, bj);
        }
        let inv = 1.0 / m[k][k];
        for i in k + 1..R {
            let f = m[i][k] * inv;
            for j in k + 1..N {
                m[i][j] -= f * m[k][j];
            }
        }
    }
    let mut basis = [[0.0; N]; K];
    let mut norm2 = 0.0;
    for t in 0..K {
        let mut x = [0.0; N];
        x[R + t] = 1.0;
        for k in (0..R).rev() {
            let mut acc = m[k][R + t];
            for j in k + 1..R {
                acc += m[k][j] * x[j];
            }
            x[k] = -acc / m[k][k];
        }
        for j in 0..N {
            basis[t][perm[j]] = x[j];
        }
        norm2 += dot(&x, &x);
    }
    NullSpace {
        basis,
        pivot,
        norm: norm2.sqrt(),
    }
}

/// The input in homogeneous coordinates, each contact's polygon plane, the tolerances.
struct Setup {
    s: usize,
    /// `[x - m; 1]` per point (`m` the mean of the points).
    y: [[Real; W]; MAX_POINTS],
    /// `|y|` per point.
    y_norm: [Real; MAX_POINTS],
    /// `m`.
    mean: [Real; D],
    /// Per contact, the constraints of its plane: `[c - m; 1]`, `[U; 0]`, `[V; 0]`.
    planes: [[[Real; W]; 3]; 3],
    /// `1.5 tol` (the band for a well-conditioned candidate).
    band: Real,
    /// `64 eps scale`: the band grows by this over `cond`.
    rounding: Real,
    /// `256 eps max(scale, 1)`: the rounding of a point's or a plane's coordinates in a null
    /// space (7-term dot products whose homogeneous coordinate is 1, whatever the scale).
    model_rounding: Real,
    /// `FIT tol`: the largest residual of a polygon fit.
    fit: Real,
    /// Per edge `(j, j + 1)` of the regular polygon `q_j = (1, cos phi_j, sin phi_j)`, its
    /// normal `q_j x q_(j+1)`.
    edge_normals: [[Real; 3]; MAX_EDGES],
    /// `q_(j-1) . (q_j x q_(j+1))` (the same for every `j`, positive).
    kappa: Real,
}

/// What a candidate needs besides its values: the bound `nf >= |N|` of its composed null
/// space basis, the smallest pivot on the way to it, and the denominator `d` of the final
/// step's conditioning `|lambda| / d`.
#[derive(Clone, Copy)]
struct Conditioning {
    nf: Real,
    pivot: Real,
    d: Real,
}

impl Setup {
    #[inline(always)]
    fn new(points: &[Real], s: usize) -> Result<Self, Decline> {
        let n = 3 * s;
        let scale = points
            .iter()
            .fold(0.0, |m: Real, x| m.max(x.abs()))
            .max(Real::MIN_POSITIVE);
        if !(1e-50..=1e50).contains(&scale) {
            return Err(Decline::Scale);
        }
        let tol = RELATIVE_TOLERANCE * scale;
        let mut mean = [0.0; D];
        for p in points.chunks_exact(D) {
            for k in 0..D {
                mean[k] += p[k];
            }
        }
        for v in mean.iter_mut() {
            *v /= n as Real;
        }
        let mut y = [[0.0; W]; MAX_POINTS];
        let mut y_norm = [0.0; MAX_POINTS];
        for (i, p) in points.chunks_exact(D).enumerate() {
            for k in 0..D {
                y[i][k] = p[k] - mean[k];
            }
            y[i][D] = 1.0;
            y_norm[i] = dot(&y[i], &y[i]).sqrt();
        }
        let mut trig = [(0.0, 0.0); MAX_EDGES];
        for (j, t) in trig.iter_mut().take(s).enumerate() {
            let (sin, cos) = (TAU * j as Real / s as Real).sin_cos();
            *t = (cos, sin);
        }
        let chord = 1.0 - (TAU / s as Real).cos();
        let q = |j: usize| [1.0, trig[j].0, trig[j].1];
        let mut edge_normals = [[0.0; 3]; MAX_EDGES];
        for (j, n) in edge_normals.iter_mut().take(s).enumerate() {
            *n = cross(&q(j), &q(wrap(j + 1, s)));
        }
        let mut planes = [[[0.0; W]; 3]; 3];
        for (i, plane) in planes.iter_mut().enumerate() {
            let poly = &points[i * s * D..(i + 1) * s * D];
            let mut c = [0.0; D];
            for p in poly.chunks_exact(D) {
                for k in 0..D {
                    c[k] += p[k] / s as Real;
                }
            }
            let (mut u, mut v) = ([0.0; D], [0.0; D]);
            for (p, &(cos, sin)) in poly.chunks_exact(D).zip(&trig) {
                for k in 0..D {
                    let x = p[k] - c[k];
                    u[k] += 2.0 * cos * x / s as Real;
                    v[k] += 2.0 * sin * x / s as Real;
                }
            }
            let mut residual: Real = 0.0;
            for (p, &(cos, sin)) in poly.chunks_exact(D).zip(&trig) {
                for k in 0..D {
                    residual = residual.max((p[k] - c[k] - cos * u[k] - sin * v[k]).abs());
                }
            }
            // Smallest singular value of [U V] from its Gram matrix.
            let (g11, g22, g12) = (dot(&u, &u), dot(&v, &v), dot(&u, &v));
            let half = 0.5 * (g11 + g22);
            let root = (0.25 * (g11 - g22) * (g11 - g22) + g12 * g12).sqrt();
            let sigma = (half - root).max(0.0).sqrt();
            if !(residual <= FIT * tol && sigma * chord >= CONVEX * tol) {
                return Err(Decline::NotPolygon { contact: i });
            }
            for k in 0..D {
                plane[0][k] = c[k] - mean[k];
                plane[1][k] = u[k];
                plane[2][k] = v[k];
            }
            plane[0][D] = 1.0;
        }
        Ok(Self {
            s,
            y,
            y_norm,
            mean,
            planes,
            band: BAND * tol,
            rounding: ROUNDING * Real::EPSILON * scale,
            model_rounding: 4.0 * ROUNDING * Real::EPSILON * scale.max(1.0),
            fit: FIT * tol,
            edge_normals,
            kappa: dot(&q(s - 1), &edge_normals[0]),
        })
    }

    /// Index of vertex `j` (taken mod `s`, `j < 2 s`) of contact `i`.
    #[inline(always)]
    fn at(&self, i: usize, j: usize) -> usize {
        i * self.s + wrap(j, self.s)
    }

    /// Whether a candidate with these values (`h . y` at the neighbours, `h = N lambda` not
    /// normalised) is surely not a facet: values beyond the band on both sides, with the band
    /// bounded from above without square roots (`|a| <= nf |lambda| <= nf |lambda|_1`).
    #[inline(always)]
    fn surely_not(&self, values: &[Real], lambda: &[Real], c: Conditioning) -> bool {
        let l1: Real = lambda.iter().map(|x| x.abs()).sum();
        let error = if c.pivot > 0.0 {
            (l1 / c.pivot).max(c.d)
        } else {
            Real::INFINITY
        };
        let band = c.nf * (l1 * self.band + self.rounding * error);
        let (hi, lo) = extremes(values);
        hi > band && lo < -band
    }

    /// Decides a candidate that no coarser test decided ([`Self::surely_not`], the screens of
    /// the (1,1,1) and (2,1,0) loops against [`Self::cofactor_bound`] and
    /// [`Self::vertex_bound`]): `h` is its hyperplane
    /// `N lambda` in homogeneous coordinates. The band is `|a| 1.5 tol + nf |lambda| 64 eps
    /// scale / cond` with `cond = min(pivot, |lambda| / d)`. An accepted facet is recorded
    /// with its points `set`.
    #[cold]
    fn settle(
        &self,
        values: &[Real],
        lambda: &[Real],
        h: [Real; W],
        c: Conditioning,
        set: u64,
        out: &mut Facets,
    ) -> Result<(), Decline> {
        let l2 = lambda.iter().map(|x| x * x).sum::<Real>().sqrt();
        let error = if c.pivot > 0.0 {
            (l2 / c.pivot).max(c.d)
        } else {
            Real::INFINITY
        };
        let a_norm = norm(&h);
        match classify(values, a_norm * self.band + c.nf * self.rounding * error) {
            Verdict::Reject => Ok(()),
            Verdict::Ambiguous => Err(Decline::Ambiguous),
            Verdict::Accept(sign) => {
                out.push_plane(set, &h, sign / a_norm, &self.mean);
                Ok(())
            }
        }
    }

    /// Type (1,1,1): an edge of each polygon. The null space `F` of the first edge's two
    /// constraints is computed once per edge, and the candidates of all pairs of edges of the
    /// other two polygons are screened in its 5 coordinates through the polygons' planes.
    ///
    /// With `A_i = F^T [c_i - m; 1 | U_i; 0 | V_i; 0]` (5 x 3), point `j` of polygon `i` is
    /// `z_j = A_i q_j + e_j`, `q_j = (1, cos phi_j, sin phi_j)` and `e_j` the polygon fit's
    /// residual. The candidate of edges `(a, b)` and `(u, v)` is the cofactor vector `g` of
    /// its four constraints (`g . x = det [z_a, z_b, z_u, z_v, x]`, the hyperplane `F g`).
    /// Without the residuals, `A q_a ^ A q_b = sum_k (q_a x q_b)_k a_(k+1) ^ a_(k+2)`, so `g` is
    /// bilinear in the edges' constant normals `n = q_a x q_b`:
    /// `g = sum_kl n2_k n3_l g_kl` with `g_kl` the cofactor of
    /// `a2_(k+1), a2_(k+2), a3_(l+1), a3_(l+2)`. Its values are then
    /// - at the first polygon's outer neighbours `o`: `n2^T [g_kl . z_o] n3`;
    /// - at the second polygon's (`det[q_a, q_b, q_o] = kappa` for both):
    ///   `kappa det[a2_0, a2_1, a2_2, A3 q_u, A3 q_v] = kappa (w3 . n3)`;
    /// - at the third's: `kappa (w2 . n2)`.
    ///
    /// So a candidate costs two 3-term dot products, and no per-pair null space is needed.
    /// The exact values (of the cofactor of the exact points) differ from these by at most
    /// the residuals through Hadamard's inequality plus rounding, bounded per first edge
    /// (`bound` below, with the band `1.5 tol |a|` for `|a| <= |F| |g| <= nf R^4`). A
    /// candidate whose values lie beyond it on both sides is no facet; one whose values all
    /// lie beyond it on one side is a facet, recorded with the hyperplane `F g`; any other
    /// (a value within it: a point near the candidate, or a degenerate, rank-deficient
    /// candidate, whose exact values are all 0) is decided on its exact values by
    /// [`Self::exact_candidate`] and [`Self::settle`].
    #[inline(always)]
    fn edges_of_three(&self, out: &mut Facets) -> Result<(), Decline> {
        let s = self.s;
        let (y, yn) = (&self.y, &self.y_norm);
        let n = &self.edge_normals;
        for e1 in 0..s {
            let (a1, b1) = (self.at(0, e1), self.at(0, e1 + 1));
            let first: NullSpace<W, 5> = null_space([y[a1], y[b1]], [yn[a1], yn[b1]]);
            if first.pivot <= 0.0 {
                // A rank-deficient edge: every candidate through it is undecidable.
                return Err(Decline::Ambiguous);
            }
            let outer = [
                first.at(&y[self.at(0, e1 + s - 1)]),
                first.at(&y[self.at(0, e1 + 2)]),
            ];
            let a2 = array(|i| first.at(&self.planes[1][i]));
            let a3 = array(|i| first.at(&self.planes[2][i]));
            let p2: [[Real; 10]; 3] = array(|k| wedge(&a2[(k + 1) % 3], &a2[(k + 2) % 3]));
            let p3: [[Real; 10]; 3] = array(|l| wedge(&a3[(l + 1) % 3], &a3[(l + 2) % 3]));
            let g: [[[Real; 5]; 3]; 3] = array(|k| array(|l| cofactor(&p2[k], &p3[l])));
            // `gamma[o][k][l] = g_kl . z_o`; `w3_l = g_0l . a2_0`; `w2_k = g_k0 . a3_0`.
            let gamma: [[[Real; 3]; 3]; 2] =
                array(|o| array(|k| array(|l| dot(&g[k][l], &outer[o]))));
            let w3: [Real; 3] = array(|l| dot(&g[0][l], &a2[0]));
            let w2: [Real; 3] = array(|k| dot(&g[k][0], &a3[0]));
            let bound = self.cofactor_bound(&first, &a2, &a3, &outer);
            let mut own2 = [0.0; MAX_EDGES];
            for (v, n3) in own2.iter_mut().zip(n).take(s) {
                *v = self.kappa * dot(&w3, n3);
            }
            for e2 in 0..s {
                let n2 = &n[e2];
                let own3 = self.kappa * dot(&w2, n2);
                let u: [[Real; 3]; 2] = array(|o| {
                    array(|l| {
                        n2[0] * gamma[o][0][l] + n2[1] * gamma[o][1][l] + n2[2] * gamma[o][2][l]
                    })
                });
                // `sum_k n2_k g_kl`: an accepted candidate's `g` is `sum_l n3_l` of these.
                let g2: [[Real; 5]; 3] = array(|l| {
                    array(|c| n2[0] * g[0][l][c] + n2[1] * g[1][l][c] + n2[2] * g[2][l][c])
                });
                let (a2, b2) = (self.at(1, e2), self.at(1, e2 + 1));
                let base = (1u64 << a1) | (1u64 << b1) | (1u64 << a2) | (1u64 << b2);
                for e3 in 0..s {
                    let n3 = &n[e3];
                    let values = [dot(&u[0], n3), dot(&u[1], n3), own2[e3], own3];
                    match classify(&values, bound) {
                        Verdict::Reject => {}
                        Verdict::Accept(sign) => {
                            let (pu, pv) = (self.at(2, e3), self.at(2, e3 + 1));
                            let gm: [Real; 5] =
                                array(|c| n3[0] * g2[0][c] + n3[1] * g2[1][c] + n3[2] * g2[2][c]);
                            let h = first.combine(&gm);
                            let a_norm = norm(&h);
                            if !self.model_plane_fits(&h, a_norm, &[a2, b2, pu, pv]) {
                                self.exact_candidate(&first, e1, e2, e3, out)?;
                                continue;
                            }
                            let set = base | (1u64 << pu) | (1u64 << pv);
                            out.push_plane(set, &h, sign / a_norm, &self.mean);
                        }
                        Verdict::Ambiguous => self.exact_candidate(&first, e1, e2, e3, out)?,
                    }
                }
            }
        }
        Ok(())
    }

    /// The bound of [`Self::edges_of_three`] on the distance of a candidate's screened
    /// values from the band of its exact values, for the first edge's null space `first`,
    /// the planes' images `a2`, `a3` and the outer neighbours `outer`. In 2-norms:
    /// - `e_z >= |z_j - A_i q_j|`: the fit residual (at most `FIT tol` per coordinate) through
    ///   `|F| <= nf`, plus the rounding of the coordinates (`model_rounding`);
    /// - `R >= |A_i q_j|, |z_j|` (`|a_i0| + |(a_i1, a_i2)|`, plus `e_z`), `O >= |z_o|, R`;
    /// - every 5 x 5 determinant of four polygon points and a neighbour is at most `R^4 O`
    ///   (Hadamard), and replacing the model points by the exact ones (five slots at most)
    ///   changes it by at most `5 e_z R^3 O`;
    /// - the band `1.5 tol |a|` with `|a| <= nf |g| <= nf R^4`, and the rounding of `F`
    ///   (that of [`Self::settle`], `nf |g| 64 eps scale / pivot`);
    /// - the rounding of the screened values, `2^15 eps R^4 O` (each is a sum of at most 9 x
    ///   5 x 6 products of magnitude at most `4 R^4 O`, each with a relative error of a few
    ///   `eps`).
    #[inline(always)]
    fn cofactor_bound(
        &self,
        first: &NullSpace<W, 5>,
        a2: &[[Real; 5]; 3],
        a3: &[[Real; 5]; 3],
        outer: &[[Real; 5]; 2],
    ) -> Real {
        let nf = first.norm;
        let e_z = nf * (6.0_f64.sqrt() * self.fit + self.model_rounding);
        let reach = |a: &[[Real; 5]; 3]| {
            dot(&a[0], &a[0]).sqrt() + (dot(&a[1], &a[1]) + dot(&a[2], &a[2])).sqrt()
        };
        let r = reach(a2).max(reach(a3)) + e_z;
        let o = dot(&outer[0], &outer[0])
            .max(dot(&outer[1], &outer[1]))
            .sqrt()
            .max(r);
        let r4 = r * r * r * r;
        nf * r4 * (self.band + self.rounding / first.pivot)
            + 5.0 * e_z * r * r * r * o
            + COFACTOR_ROUNDING * Real::EPSILON * r4 * o
    }

    /// Whether an accepted candidate's hyperplane `h` from the fitted polygons (normal part of
    /// norm `a_norm`) may be recorded: at the facet's `points` taken from the fitted planes,
    /// where the exact hyperplane is 0, it must be within a quarter of `tol` (checked on the
    /// exact points). Otherwise (a poorly conditioned candidate, whose small `|a|` magnifies
    /// the fit's residual) its exact hyperplane is computed instead.
    #[inline(always)]
    fn model_plane_fits(&self, h: &[Real; W], a_norm: Real, points: &[usize]) -> bool {
        let off = points
            .iter()
            .fold(0.0, |m: Real, &p| m.max(dot(h, &self.y[p]).abs()));
        off * 6.0 <= self.band * a_norm
    }

    /// Decides the (1,1,1) candidate of edges `e1`, `e2`, `e3` on its exact values, as every
    /// candidate was decided before the screen of [`Self::edges_of_three`]: the null space
    /// of the second edge's constraints in `first`'s coordinates, `lambda` the cross product
    /// of the third edge's points there, then [`Self::settle`].
    #[cold]
    fn exact_candidate(
        &self,
        first: &NullSpace<W, 5>,
        e1: usize,
        e2: usize,
        e3: usize,
        out: &mut Facets,
    ) -> Result<(), Decline> {
        let s = self.s;
        let (y, yn) = (&self.y, &self.y_norm);
        let z = |p: usize| first.at(&y[p]);
        let (a2, b2) = (self.at(1, e2), self.at(1, e2 + 1));
        let second: NullSpace<5, 3> = null_space([z(a2), z(b2)], [yn[a2], yn[b2]]);
        let r = |p: usize| second.at(&z(p));
        let (pu, pv) = (self.at(2, e3), self.at(2, e3 + 1));
        let lambda = cross(&r(pu), &r(pv));
        let neighbours = [
            self.at(0, e1 + s - 1),
            self.at(0, e1 + 2),
            self.at(1, e2 + s - 1),
            self.at(1, e2 + 2),
            self.at(2, e3 + s - 1),
            self.at(2, e3 + 2),
        ];
        let values: [Real; 6] = array(|i| dot(&r(neighbours[i]), &lambda));
        let nf = first.norm * second.norm;
        let c = Conditioning {
            nf,
            pivot: first.pivot.min(second.pivot),
            d: nf * nf * yn[pu] * yn[pv],
        };
        let h = first.combine(&second.combine(&lambda));
        let (a1, b1) = (self.at(0, e1), self.at(0, e1 + 1));
        let set = [a1, b1, a2, b2, pu, pv]
            .iter()
            .fold(0u64, |set, &p| set | (1u64 << p));
        self.settle(&values, &lambda, h, c, set, out)
    }

    /// Type (2,1,0) and its permutations: one whole polygon, an edge, a vertex. The null
    /// space `F` of the whole polygon's plane is computed once per polygon, and the image `A`
    /// of the edge polygon's plane in its 4 coordinates; the candidates are then screened as
    /// in [`Self::edges_of_three`]: the candidate of edge `(a, b)` and vertex `t` is the
    /// cofactor `g` of `z_a, z_b, z_t` (`g . x = det [z_a, z_b, z_t, x]`), without the
    /// residuals `sum_k n_k cof(a_(k+1), a_(k+2), z_t)` with the edge's normal `n`. Its values
    /// are
    /// - at the edge's outer neighbours (`det[q_a, q_b, q_o] = kappa`):
    ///   `-kappa det[a_0, a_1, a_2, z_t]`, a constant of the vertex;
    /// - at the vertex's neighbours: `n . m_t` and `-n . m_(t-1)`, with
    ///   `m_t = (det[a_(k+1), a_(k+2), z_t, z_(t+1)])_k`.
    ///
    /// Against [`Self::vertex_bound`]: no facet, a facet (hyperplane `F g`), or unsure, then
    /// decided on its exact values by [`Self::exact_whole_edge_vertex`].
    #[inline(always)]
    fn whole_edge_vertex(&self, out: &mut Facets) -> Result<(), Decline> {
        let s = self.s;
        let y = &self.y;
        let n = &self.edge_normals;
        let all = (1u64 << s) - 1;
        for whole in 0..3 {
            let [c, u, v] = self.planes[whole];
            let norms = [dot(&c, &c).sqrt(), dot(&u, &u).sqrt(), dot(&v, &v).sqrt()];
            let first: NullSpace<W, 4> = null_space([c, u, v], norms);
            if first.pivot <= 0.0 {
                return Err(Decline::Ambiguous);
            }
            let mut z = [[0.0; 4]; MAX_POINTS];
            for (p, z) in z.iter_mut().enumerate().take(3 * s) {
                if p / s != whole {
                    *z = first.at(&y[p]);
                }
            }
            let polygon = all << (whole * s);
            for edge in (0..3).filter(|&j| j != whole) {
                let vertex = 3 - whole - edge;
                let a = array(|i| first.at(&self.planes[edge][i]));
                let p: [[Real; 6]; 3] = array(|k| wedge4(&a[(k + 1) % 3], &a[(k + 2) % 3]));
                let plane = cofactor4(&wedge4(&a[0], &a[1]), &a[2]);
                let zt = |t: usize| &z[self.at(vertex, t)];
                let (mut m, mut own) = ([[0.0; 3]; MAX_EDGES], [0.0; MAX_EDGES]);
                let mut o2: Real = 0.0;
                for t in 0..s {
                    let q = wedge4(zt(t), zt(t + 1));
                    m[t] = array(|k| det4(&p[k], &q));
                    own[t] = -self.kappa * dot(&plane, zt(t));
                    o2 = o2.max(dot(zt(t), zt(t)));
                }
                let bound = self.vertex_bound(&first, &a, o2.sqrt());
                for e in 0..s {
                    let ne = &n[e];
                    let (pa, pb) = (self.at(edge, e), self.at(edge, e + 1));
                    let base = polygon | (1u64 << pa) | (1u64 << pb);
                    for t in 0..s {
                        let values = [own[t], dot(ne, &m[t]), -dot(ne, &m[wrap(t + s - 1, s)])];
                        let pt = self.at(vertex, t);
                        match classify(&values, bound) {
                            Verdict::Reject => {}
                            Verdict::Accept(sign) => {
                                let cof: [[Real; 4]; 3] = array(|k| cofactor4(&p[k], zt(t)));
                                let g: [Real; 4] = array(|i| {
                                    ne[0] * cof[0][i] + ne[1] * cof[1][i] + ne[2] * cof[2][i]
                                });
                                let h = first.combine(&g);
                                let a_norm = norm(&h);
                                if self.model_plane_fits(&h, a_norm, &[pa, pb]) {
                                    out.push_plane(
                                        base | (1u64 << pt),
                                        &h,
                                        sign / a_norm,
                                        &self.mean,
                                    );
                                } else {
                                    self.exact_whole_edge_vertex(
                                        &first,
                                        &z,
                                        [pa, pb, pt],
                                        polygon,
                                        out,
                                    )?;
                                }
                            }
                            Verdict::Ambiguous => self.exact_whole_edge_vertex(
                                &first,
                                &z,
                                [pa, pb, pt],
                                polygon,
                                out,
                            )?,
                        }
                    }
                }
            }
        }
        Ok(())
    }

    /// The bound of [`Self::whole_edge_vertex`], as [`Self::cofactor_bound`]: with `e_z`,
    /// `R` (of the edge polygon, from `a`) and `O >= |z_t|, R` (`o` the vertex polygon's
    /// largest `|z_t|`), `|g| <= R^2 O`, the determinants are at most `R^2 O^2`, and
    /// replacing the model points by the exact ones (three slots at most) changes them by at
    /// most `3 e_z R O^2`.
    #[inline(always)]
    fn vertex_bound(&self, first: &NullSpace<W, 4>, a: &[[Real; 4]; 3], o: Real) -> Real {
        let nf = first.norm;
        let e_z = nf * (6.0_f64.sqrt() * self.fit + self.model_rounding);
        let r = dot(&a[0], &a[0]).sqrt() + (dot(&a[1], &a[1]) + dot(&a[2], &a[2])).sqrt() + e_z;
        let o = o.max(r);
        nf * r * r * o * (self.band + self.rounding / first.pivot)
            + 3.0 * e_z * r * o * o
            + COFACTOR_ROUNDING * Real::EPSILON * r * r * o * o
    }

    /// Decides the (2,1,0) candidate of the edge `(a, b)` and the vertex `t` (`points`)
    /// whose whole polygon (`polygon`, its points) has the null space `first` and gives the
    /// points the coordinates `z`, on its exact values, as before the screen of
    /// [`Self::whole_edge_vertex`]: the null space of the edge's constraints, `lambda` the
    /// vertex's coordinates turned, then [`Self::settle`].
    #[cold]
    fn exact_whole_edge_vertex(
        &self,
        first: &NullSpace<W, 4>,
        z: &[[Real; 4]; MAX_POINTS],
        [a, b, t]: [usize; 3],
        polygon: u64,
        out: &mut Facets,
    ) -> Result<(), Decline> {
        let (s, yn) = (self.s, &self.y_norm);
        let second: NullSpace<4, 2> = null_space([z[a], z[b]], [yn[a], yn[b]]);
        let r = |p: usize| second.at(&z[p]);
        let rt = r(t);
        let lambda = [rt[1], -rt[0]];
        let (edge, e, vertex, j) = (a / s, a % s, t / s, t % s);
        let neighbours = [
            self.at(edge, e + s - 1),
            self.at(edge, e + 2),
            self.at(vertex, j + s - 1),
            self.at(vertex, j + 1),
        ];
        let values: [Real; 4] = array(|i| dot(&r(neighbours[i]), &lambda));
        let nf = first.norm * second.norm;
        let c = Conditioning {
            nf,
            pivot: first.pivot.min(second.pivot),
            d: nf * yn[t],
        };
        let h = first.combine(&second.combine(&lambda));
        let set = polygon | (1u64 << a) | (1u64 << b) | (1u64 << t);
        self.settle(&values, &lambda, h, c, set, out)
    }

    /// Type (2,2): two whole polygons; the third must lie below.
    #[inline(always)]
    fn two_whole(&self, out: &mut Facets) -> Result<(), Decline> {
        let s = self.s;
        let all = (1u64 << s) - 1;
        for (i, j) in [(0, 1), (0, 2), (1, 2)] {
            let k = 3 - i - j;
            let [ci, ui, vi] = self.planes[i];
            let [cj, uj, vj] = self.planes[j];
            let rows = [ci, ui, vi, cj, uj, vj];
            let norms = rows.map(|r| dot(&r, &r).sqrt());
            let ns: NullSpace<W, 1> = null_space(rows, norms);
            let mut values = [0.0; MAX_EDGES];
            for (t, v) in values.iter_mut().take(s).enumerate() {
                *v = ns.at(&self.y[self.at(k, t)])[0];
            }
            let c = Conditioning {
                nf: ns.norm,
                pivot: ns.pivot,
                d: 0.0,
            };
            let set = (all << (i * s)) | (all << (j * s));
            if !self.surely_not(&values[..s], &[1.0], c) {
                self.settle(&values[..s], &[1.0], ns.basis[0], c, set, out)?;
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Vec3;
    use crate::wrench::{ContactModel, Space, WrenchFrame};

    /// SplitMix64.
    struct Rng(u64);

    impl Rng {
        fn next(&mut self) -> u64 {
            self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
            let mut z = self.0;
            z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
            z ^ (z >> 31)
        }

        fn uniform(&mut self, lo: Real, hi: Real) -> Real {
            lo + (hi - lo) * (self.next() >> 11) as Real / (1u64 << 53) as Real
        }

        fn below(&mut self, n: usize) -> usize {
            (self.next() % n as u64) as usize
        }
    }

    /// The determinant of a 5 x 5 matrix of columns, by Leibniz's formula.
    fn det5(cols: &[[Real; 5]; 5]) -> Real {
        fn permutations(
            k: usize,
            p: &mut [usize; 5],
            sign: Real,
            f: &mut impl FnMut(&[usize; 5], Real),
        ) {
            if k == 5 {
                return f(p, sign);
            }
            for i in k..5 {
                p.swap(k, i);
                permutations(k + 1, p, if i == k { sign } else { -sign }, f);
                p.swap(k, i);
            }
        }
        let mut det = 0.0;
        permutations(0, &mut [0, 1, 2, 3, 4], 1.0, &mut |p, sign| {
            det += sign * (0..5).map(|c| cols[c][p[c]]).product::<Real>();
        });
        det
    }

    #[test]
    fn determinants_of_wedges_in_4d() {
        let mut rng = Rng(11);
        for _ in 0..100 {
            let x: [[Real; 4]; 4] =
                std::array::from_fn(|_| std::array::from_fn(|_| rng.uniform(-2.0, 2.0)));
            // det4 by Leibniz's formula, through det5 with a unit fifth row and column.
            let lift = |v: &[Real; 4]| [v[0], v[1], v[2], v[3], 0.0];
            let unit = [0.0, 0.0, 0.0, 0.0, 1.0];
            let want = det5(&[lift(&x[0]), lift(&x[1]), lift(&x[2]), lift(&x[3]), unit]);
            let p = wedge4(&x[0], &x[1]);
            let tol = 1e-12 * (1.0 + want.abs());
            assert!((det4(&p, &wedge4(&x[2], &x[3])) - want).abs() <= tol);
            assert!((dot(&cofactor4(&p, &x[2]), &x[3]) - want).abs() <= tol);
        }
    }

    #[test]
    fn cofactor_of_wedges_is_the_determinant() {
        let mut rng = Rng(7);
        for _ in 0..100 {
            let cols: [[Real; 5]; 5] =
                std::array::from_fn(|_| std::array::from_fn(|_| rng.uniform(-2.0, 2.0)));
            let c = cofactor(&wedge(&cols[0], &cols[1]), &wedge(&cols[2], &cols[3]));
            let want = det5(&cols);
            assert!((dot(&c, &cols[4]) - want).abs() <= 1e-12 * (1.0 + want.abs()));
        }
    }

    #[derive(Debug, Clone, Copy)]
    enum Shape {
        Sphere,
        Ellipsoid,
        Cuboid,
    }

    const SEMI_AXES: [Real; 3] = [0.06, 0.045, 0.035];

    /// A contact on `shape`: anywhere, or on the equator (z = 0) when `equator`.
    fn contact(shape: Shape, equator: bool, rng: &mut Rng) -> (Vec3, Vec3) {
        let theta = rng.uniform(0.0, TAU);
        let z: Real = if equator { 0.0 } else { rng.uniform(-1.0, 1.0) };
        let r = (1.0 - z * z).sqrt();
        let dir = Vec3::new(r * theta.cos(), r * theta.sin(), z);
        match shape {
            Shape::Sphere => (dir * 0.0475, dir),
            Shape::Ellipsoid => {
                let [a, b, c] = SEMI_AXES;
                let p = Vec3::new(a * dir.x, b * dir.y, c * dir.z);
                let n = Vec3::new(dir.x / a, dir.y / b, dir.z / c).normalize();
                (p, n)
            }
            Shape::Cuboid => {
                // A face by the largest component of the direction, a point on it.
                let [a, b, c] = SEMI_AXES;
                let half = Vec3::new(a, b, c);
                let k = (0..3)
                    .max_by(|&i, &j| dir[i].abs().total_cmp(&dir[j].abs()))
                    .unwrap_or(0);
                let mut n = Vec3::zeros();
                n[k] = dir[k].signum();
                let mut p = Vec3::zeros();
                for i in 0..3 {
                    p[i] = if i == k {
                        half[i] * n[k]
                    } else if equator && i == 2 {
                        0.0
                    } else {
                        rng.uniform(-half[i], half[i])
                    };
                }
                (p, n)
            }
        }
    }

    /// The primitive wrenches of three random contacts.
    fn grasp(rng: &mut Rng, shape: Shape, equator: bool, mu: Real, s: usize) -> Vec<Real> {
        let rho = 0.06;
        let frame = WrenchFrame::new(Vec3::zeros(), rho, Space::Spatial).unwrap();
        let model = ContactModel::new(mu, s).unwrap();
        let mut w = vec![0.0; 3 * s * D];
        for out in w.chunks_exact_mut(s * D) {
            let (p, n) = contact(shape, equator, rng);
            frame.primitive_wrenches(&p, &n, &model, out);
        }
        w
    }

    /// Same facets (in the same canonical order), offsets and normals within `tol`, same
    /// facet lists and vertices.
    fn same(a: &Hull, b: &Hull, tol: Real) -> Result<(), String> {
        if a.facet_count() != b.facet_count() {
            return Err(format!("{} vs {} facets", a.facet_count(), b.facet_count()));
        }
        for f in 0..a.facet_count() {
            if a.facet_vertices(f) != b.facet_vertices(f) {
                return Err(format!(
                    "facet {f}: points {:?} vs {:?}",
                    a.facet_vertices(f),
                    b.facet_vertices(f)
                ));
            }
            let da = (a.offsets()[f] - b.offsets()[f]).abs();
            let dn = a
                .normal(f)
                .iter()
                .zip(b.normal(f))
                .fold(0.0, |m: Real, (x, y)| m.max((x - y).abs()));
            if da > tol || dn > tol {
                return Err(format!("facet {f}: offset off by {da:e}, normal by {dn:e}"));
            }
        }
        if a.vertices() != b.vertices() {
            return Err(format!("vertices {:?} vs {:?}", a.vertices(), b.vertices()));
        }
        Ok(())
    }

    #[test]
    fn equals_beneath_beyond_on_random_grasps_or_declines() {
        let mut rng = Rng(2024);
        let shapes = [Shape::Sphere, Shape::Ellipsoid, Shape::Cuboid];
        let mut tried = 0;
        let mut declined = std::collections::BTreeMap::<String, usize>::new();
        let mut by_case = std::collections::BTreeMap::<String, (usize, usize)>::new();
        for round in 0..4000 {
            let shape = shapes[round % 3];
            let equator = round % 8 == 7;
            let s = [4, 6, 8][rng.below(3)];
            let mu = rng.uniform(0.05, 1.0);
            let w = grasp(&mut rng, shape, equator, mu, s);
            let case = format!("{shape:?}{}", if equator { " equator" } else { "" });
            let entry = by_case.entry(case).or_default();
            entry.0 += 1;
            tried += 1;
            let reference = Hull::new(&w, D);
            match hull(&w, s) {
                Ok(fast) => {
                    let reference = reference.unwrap_or_else(|e| {
                        panic!("enumerated a hull where Hull::new fails ({e}): {w:?}")
                    });
                    if let Err(e) = same(&fast, &reference, 1e-9) {
                        panic!("round {round} ({shape:?}, equator {equator}, mu {mu}, s {s}): {e}");
                    }
                }
                Err(why) => {
                    entry.1 += 1;
                    *declined.entry(format!("{why:?}")).or_default() += 1;
                }
            }
        }
        let total: usize = declined.values().sum();
        println!(
            "declined {total} of {tried}: {declined:?}; per case (tried, declined): {by_case:?}"
        );
        // Contacts anywhere on a smooth object are in general position: the enumeration must
        // handle nearly all of them.
        for (case, (n, d)) in &by_case {
            if case == "Sphere" || case == "Ellipsoid" {
                assert!(*d * 100 <= *n, "{case}: declined {d} of {n}");
            }
        }
    }

    #[test]
    fn equals_beneath_beyond_on_mesh_contacts() {
        // Facet centres of meshes as contacts (the evaluation's candidates), as in the
        // benchmarks: a UV sphere (symmetric: many contacts share a latitude) and a box.
        let objects = [
            crate::object::Object::sphere(0.0475, 72, 72).unwrap(),
            crate::object::Object::cuboid(Vec3::new(0.04, 0.03, 0.025), 4).unwrap(),
        ];
        let mut rng = Rng(99);
        for object in &objects {
            let frame =
                WrenchFrame::new(object.centre_of_mass, object.max_radius(), Space::Spatial)
                    .unwrap();
            let n = object.facets.points.len();
            let (mut tried, mut declined) = (0, 0);
            for _ in 0..500 {
                let s = [4, 6, 8][rng.below(3)];
                let model = ContactModel::new(rng.uniform(0.05, 1.0), s).unwrap();
                let mut w = vec![0.0; 3 * s * D];
                for out in w.chunks_exact_mut(s * D) {
                    let k = rng.below(n);
                    let (p, q) = (&object.facets.points[k], &object.facets.normals[k]);
                    frame.primitive_wrenches(p, q, &model, out);
                }
                tried += 1;
                match hull(&w, s) {
                    Ok(fast) => {
                        let reference = Hull::new(&w, D).unwrap();
                        if let Err(e) = same(&fast, &reference, 1e-9) {
                            panic!("{} facets, s {s}: {e}", n);
                        }
                    }
                    Err(_) => declined += 1,
                }
            }
            println!("mesh of {n} facets: declined {declined} of {tried}");
        }
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig {
            cases: 512,
            ..proptest::prelude::ProptestConfig::default()
        })]

        /// Every input point is inside every facet, each facet's points are on it, normals
        /// are unit vectors.
        #[test]
        fn every_point_is_inside_every_facet(
            seed in proptest::prelude::any::<u64>(),
            shape in 0..3usize,
            equator in proptest::prelude::any::<bool>(),
            mu in 0.05..1.0f64,
            s in proptest::prop_oneof![
                proptest::prelude::Just(4usize),
                proptest::prelude::Just(6),
                proptest::prelude::Just(8)
            ],
        ) {
            let shape = [Shape::Sphere, Shape::Ellipsoid, Shape::Cuboid][shape];
            let w = grasp(&mut Rng(seed), shape, equator, mu, s);
            let scale = w.iter().fold(0.0, |m: Real, x| m.max(x.abs()));
            let tol = RELATIVE_TOLERANCE * scale;
            if let Ok(h) = hull(&w, s) {
                for p in w.chunks_exact(D) {
                    proptest::prop_assert!(h.violation(p) <= tol, "violation {}", h.violation(p));
                }
                for f in 0..h.facet_count() {
                    let a = h.normal(f);
                    proptest::prop_assert!((dot6(a, a).sqrt() - 1.0).abs() < 1e-12);
                    for &i in h.facet_vertices(f) {
                        let p = &w[i as usize * D..(i as usize + 1) * D];
                        proptest::prop_assert!((dot6(a, p) - h.offsets()[f]).abs() <= tol);
                    }
                }
            }
        }
    }

    fn dot6(a: &[Real], b: &[Real]) -> Real {
        a.iter().zip(b).map(|(x, y)| x * y).sum()
    }

    #[test]
    fn declines_what_is_not_three_polygons() {
        let mut rng = Rng(7);
        let w = grasp(&mut rng, Shape::Sphere, false, 0.5, 8);
        assert_eq!(hull(&w, 6).err(), Some(Decline::Shape));
        assert_eq!(hull(&w[..w.len() - 6], 8).err(), Some(Decline::Shape));
        let mut bad = w.clone();
        bad[7] = Real::NAN;
        assert_eq!(hull(&bad, 8).err(), Some(Decline::NonFinite));
        // Scaled beyond what the screens' products allow.
        for factor in [1e55, 1e-55] {
            let scaled: Vec<Real> = w.iter().map(|x| x * factor).collect();
            assert_eq!(hull(&scaled, 8).err(), Some(Decline::Scale));
        }
        // Two wrenches of the second contact swapped: not in cyclic order.
        let mut swapped = w.clone();
        for k in 0..D {
            swapped.swap(8 * D + k, 9 * D + k);
        }
        assert_eq!(
            hull(&swapped, 8).err(),
            Some(Decline::NotPolygon { contact: 1 })
        );
        // No friction: each contact is one point.
        let flat = grasp(&mut rng, Shape::Sphere, false, 0.0, 8);
        assert_eq!(
            hull(&flat, 8).err(),
            Some(Decline::NotPolygon { contact: 0 })
        );
        // The same contact twice: a degenerate configuration.
        let mut twice = w.clone();
        twice.copy_within(0..8 * D, 8 * D);
        assert!(hull(&twice, 8).is_err());
    }
}
