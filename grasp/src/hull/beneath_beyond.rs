//! Beneath-beyond convex hull for small point sets (tens of points) in 2 to 8 dimensions,
//! with merged (non-simplicial) facets. Standard library only.
//!
//! # Algorithm
//! Incremental construction (beneath-beyond, the scheme Qhull also uses) that keeps the
//! *true* facets of the current polytope rather than a triangulation, so nothing needs
//! merging afterwards:
//!
//! - A facet is a hyperplane `a . x = b` (`a` a unit outward normal), the set of inserted
//!   points lying on it (a bit set: `u64`, or `u128` above 64 points) and a neighbour list
//!   with one entry per ridge. A facet may hold any number of points.
//! - The points are first scaled by a power of two into [-1, 1] (exact; no overflow for any
//!   finite input). The initial simplex is chosen greedily for volume: the point farthest from
//!   the centroid, then repeatedly the point farthest from the affine hull of those chosen
//!   (Gram-Schmidt). Its centroid lies inside every later hull and orients the normals.
//! - Every other point is kept in the conflict list of one facet it lies above (as in Qhull);
//!   a point above no facet is inside (or on) the hull and is not looked at again until the
//!   final check. The next point inserted is the one farthest above its facet.
//! - Inserting `p`: a breadth-first search from `p`'s facet over the neighbour graph classifies
//!   facets as *visible* (`a . p - b > tol`), *coplanar* (`|a . p - b| <= tol`) or *below*.
//!   The horizon ridges are the ridges between a visible facet `F` and a non-visible one `G`,
//!   with points `R = V_F & V_G`:
//!   - `G` below: a new facet through `R` and `p`. Its normal is the combination of `a_F` and
//!     `a_G` that vanishes at `p` (both hyperplanes contain the ridge): a few flops, exact up
//!     to the rounding carried by `F` and `G`. Every facet carries a bound on that rounding;
//!     past `tol / 1000` the residuals at the points are measured, and if they are too large
//!     the hyperplane is recomputed from the points (Gaussian elimination with full pivoting
//!     on the edge vectors from `p`, so a ridge with many points is handled by picking
//!     `dim - 1` independent ones).
//!   - `G` coplanar: `G` keeps its hyperplane and gains `p` (the cone over `R` from `p` is
//!     merged into `G`, as Qhull merges a coplanar new facet into its horizon neighbour). This
//!     is how non-simplicial facets arise and grow.
//!
//!   Visible facets are deleted.
//! - Adjacency through `p`: every cone (new facet, or piece merged into a coplanar facet) has
//!   one ridge through `p` per facet ("sub-ridge") of its horizon ridge `R`, and the horizon
//!   is a closed (dim - 2)-sphere, so every sub-ridge lies on exactly two cones. Sub-ridges
//!   are matched by their point sets in a hash table, which fills the new facets' neighbour
//!   lists. For a simplex ridge they are `R` minus one point; otherwise they are the
//!   inclusion-maximal sets among `R & V_E` over the other neighbours `E` of `F` (each facet
//!   of `R` is `F`'s ridge with one of them). Pure bit-set work: no rank decisions. A
//!   sub-ridge seen once or three times means the input defeated the tolerance: `Err`.
//! - The conflict points of deleted facets move to the new and grown facets (a point outside
//!   the new hull that was above a deleted facet is above one of those), with a scan of all
//!   facets as a fallback.
//! - A final pass evaluates every facet at every input point (vectorized, four facets at a
//!   time): any point more than `tol` above a facet makes the result an error, and each
//!   facet's list is *all* input points within `tol` of its hyperplane.
//!
//! # Tolerance
//! `tol = 1e-10 * max_i |x_i|` (the largest coordinate magnitude of the input), used as an
//! absolute distance (normals are unit vectors) for visibility (`> tol`), coplanarity and
//! facet membership (`|a . x - b| <= tol`), and degeneracy of a recomputed hyperplane (a
//! pivot `<= tol`). A rotated hyperplane is accepted only within `1e-13 * max_i |x_i|` of its
//! points (the rounding bound above), 1000 times below the tolerance.
//! Degeneracies of grasp inputs are exact up to rounding (~1e-16 relative) and their
//! features are far above `tol`, so the tolerance normally only decides cases that are
//! degenerate in exact arithmetic. Features between Qhull's merge tolerance (~1e-13 here)
//! and `tol` (e.g. two contacts a few 1e-5 apart) are merged: such a hull has fewer facets
//! than Qhull's, each within `tol` of the points; rarely the construction instead detects an
//! inconsistency and returns `Err`.
//!
//! # Output
//! Facets in no particular order; each with its unit outward normal, offset `b` (with
//! `a . x <= b + tol` for every input point, checked) and the ascending indices of **all
//! input points within `tol` of the hyperplane**. That includes points that lie on the
//! facet without being vertices of the hull (duplicates, points inside a facet or on one of
//! its edges): Qhull reports only vertices and keeps such points as "coplanar points", so
//! Qhull's lists are ours restricted to Qhull's vertices.
//!
//! # Failure
//! Never panics and never returns a hull that fails the final check. Inputs it cannot handle
//! give `Err` with a reason: a dimension outside 2..=8, more than 128 points, non-finite or
//! lower-dimensional input, and inconsistencies detected during construction (which need
//! near-degeneracies at the scale of `tol`); the caller then falls back to Qhull.

// Loops over the `D` coordinates index several fixed-size arrays at once; iterator chains
// would hide that and do not vectorize better.
#![allow(clippy::needless_range_loop)]

use std::ops::{BitAnd, BitOr, BitXor};

/// Tolerance relative to the largest coordinate magnitude of the input.
pub const RELATIVE_TOLERANCE: f64 = 1e-10;

/// Most input points accepted (point sets are `u128` bit sets).
pub const MAX_POINTS: usize = 128;

/// Why the construction gave up (the caller then falls back to Qhull): an input it does not
/// take, or an inconsistency that a near-degenerate input caused at the scale of the tolerance.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum BeneathBeyondError {
    /// The dimension is not one the construction is compiled for.
    #[error("dimension {dim} is not in 2..=8")]
    Dimension {
        /// The dimension asked for.
        dim: usize,
    },
    /// The coordinate buffer is not a whole number of points.
    #[error("{len} coordinates are not a whole number of {dim}-dimensional points")]
    Ragged {
        /// Number of coordinates.
        len: usize,
        /// Dimension.
        dim: usize,
    },
    /// Fewer points than a simplex of the space has vertices.
    #[error("{count} points cannot span R^{dim}")]
    TooFewPoints {
        /// Number of points.
        count: usize,
        /// Dimension.
        dim: usize,
    },
    /// More points than the point sets hold ([`MAX_POINTS`]).
    #[error("{count} points: more than {max}", max = MAX_POINTS)]
    TooManyPoints {
        /// Number of points.
        count: usize,
    },
    /// A coordinate is NaN or infinite.
    #[error("point {index} has a non-finite coordinate")]
    NonFinite {
        /// Index of the point.
        index: usize,
    },
    /// More facets were created than the guard allows.
    #[error("too many facets")]
    TooManyFacets,
    /// A facet to be made has fewer points than a hyperplane needs.
    #[error("a facet has too few points")]
    FacetTooFewPoints,
    /// A facet's points do not span a hyperplane.
    #[error("degenerate facet (its points do not span a hyperplane)")]
    DegenerateFacet,
    /// A facet's normal has no length.
    #[error("degenerate facet normal")]
    DegenerateNormal,
    /// A facet's hyperplane passes through the interior reference point.
    #[error("a facet passes through the interior reference point")]
    ThroughInterior,
    /// No initial simplex: the points do not span the space.
    #[error("the points do not span the space")]
    NotSpanning,
    /// A point's conflict facet is no longer visible from it.
    #[error("conflict list out of date")]
    StaleConflictList,
    /// A horizon ridge's facets are not neighbours.
    #[error("inconsistent adjacency")]
    InconsistentAdjacency,
    /// A ridge has fewer points than it needs.
    #[error("a ridge with too few points")]
    RidgeTooFewPoints,
    /// A ridge has fewer facets than it needs.
    #[error("a ridge with too few facets")]
    RidgeTooFewFacets,
    /// A ridge is shared by more than two facets.
    #[error("a ridge on more than two facets")]
    RidgeOnMoreThanTwoFacets,
    /// A sub-ridge of the new facets was seen once or three times.
    #[error("the horizon is not closed (near-degenerate input)")]
    HorizonNotClosed,
    /// The final check found an input point above a facet.
    #[error("an input point is above a facet (tolerance {tol:e})")]
    PointAboveFacet {
        /// The tolerance it is beyond.
        tol: f64,
    },
    /// The final check found a facet without all of its points.
    #[error("a facet lost its points in the final check")]
    FacetLostPoints,
    /// A facet's normal is not of unit length or its offset not finite.
    #[error("a facet hyperplane is not finite")]
    FacetNotFinite,
    /// Fewer facets than a simplex has.
    #[error("too few facets")]
    TooFewFacets,
}

/// Most facets created over a whole construction before giving up (a guard, not a limit
/// reached by the hulls this is meant for).
const MAX_FACETS_CREATED: usize = 1 << 20;

/// Facets of the hull of `points` (row-major, `dim` coordinates each): for each facet, its
/// unit outward normal a, offset b (a . x <= b for all input points) and the indices of all
/// input points lying on it (within the tolerance), i.e. *merged* facets: coplanar simplicial
/// pieces are one facet. Precondition (checked by the caller): the points are finite and
/// affinely span R^dim.
///
/// The tolerance is `RELATIVE_TOLERANCE * max |coordinate|`: every input point satisfies
/// `a . x <= b + tol` for every facet, and a facet's list holds every input point with
/// `|a . x - b| <= tol`, ascending. See the module documentation for the algorithm and for
/// when `Err` is returned (the caller then falls back to Qhull).
#[allow(clippy::type_complexity)]
pub fn hull(
    points: &[f64],
    dim: usize,
) -> Result<
    (
        Vec<f64>,      /*normals, F x dim*/
        Vec<f64>,      /*offsets*/
        Vec<Vec<u32>>, /*facet vertex lists*/
    ),
    BeneathBeyondError,
> {
    let c = hull_compressed(points, dim)?;
    let lists = c
        .facet_offsets
        .windows(2)
        .map(|w| c.facet_indices[w[0] as usize..w[1] as usize].to_vec())
        .collect();
    Ok((c.normals, c.offsets, lists))
}

/// Normals (`F x dim`), offsets, and the facet lists in compressed form: the list of facet
/// `f` is `facet_indices[facet_offsets[f]..facet_offsets[f + 1]]`, ascending.
#[derive(Debug, Clone, Default)]
pub(crate) struct Compressed {
    pub normals: Vec<f64>,
    pub offsets: Vec<f64>,
    pub facet_offsets: Vec<u32>,
    pub facet_indices: Vec<u32>,
}

/// [`hull`] with the facet lists in compressed form.
pub(crate) fn hull_compressed(
    points: &[f64],
    dim: usize,
) -> Result<Compressed, BeneathBeyondError> {
    let mut out = Compressed::default();
    hull_compressed_in(points, dim, &mut Scratch::default(), &mut out)?;
    Ok(out)
}

/// The builders [`hull_compressed_in`] keeps between hulls, one per dimension (for up to 64
/// points), with their buffers grown to the largest input so far.
#[derive(Default)]
pub(crate) struct Scratch {
    d2: Option<Builder<2, u64>>,
    d3: Option<Builder<3, u64>>,
    d4: Option<Builder<4, u64>>,
    d5: Option<Builder<5, u64>>,
    d6: Option<Builder<6, u64>>,
    d7: Option<Builder<7, u64>>,
    d8: Option<Builder<8, u64>>,
    sets: Vec<u64>,
}

/// [`hull_compressed`] into `out` (overwritten), building with `scratch`'s builders: once
/// they have met an input of this dimension and size, a hull of up to 64 points allocates
/// nothing (more points take a builder of their own).
pub(crate) fn hull_compressed_in(
    points: &[f64],
    dim: usize,
    scratch: &mut Scratch,
    out: &mut Compressed,
) -> Result<(), BeneathBeyondError> {
    if !(2..=8).contains(&dim) {
        return Err(BeneathBeyondError::Dimension { dim });
    }
    if !points.len().is_multiple_of(dim) {
        return Err(BeneathBeyondError::Ragged {
            len: points.len(),
            dim,
        });
    }
    let n = points.len() / dim;
    if n < dim + 1 {
        return Err(BeneathBeyondError::TooFewPoints { count: n, dim });
    }
    if n > MAX_POINTS {
        return Err(BeneathBeyondError::TooManyPoints { count: n });
    }
    if let Some(i) = points.iter().position(|x| !x.is_finite()) {
        return Err(BeneathBeyondError::NonFinite { index: i / dim });
    }
    if n > 64 {
        let mut sets = Vec::new();
        return match dim {
            2 => Builder::<2, u128>::empty().run(points, out, &mut sets),
            3 => Builder::<3, u128>::empty().run(points, out, &mut sets),
            4 => Builder::<4, u128>::empty().run(points, out, &mut sets),
            5 => Builder::<5, u128>::empty().run(points, out, &mut sets),
            6 => Builder::<6, u128>::empty().run(points, out, &mut sets),
            7 => Builder::<7, u128>::empty().run(points, out, &mut sets),
            _ => Builder::<8, u128>::empty().run(points, out, &mut sets),
        };
    }
    fn kept<const D: usize>(b: &mut Option<Builder<D, u64>>) -> &mut Builder<D, u64> {
        b.get_or_insert_with(Builder::empty)
    }
    let sets = &mut scratch.sets;
    match dim {
        2 => kept(&mut scratch.d2).run(points, out, sets),
        3 => kept(&mut scratch.d3).run(points, out, sets),
        4 => kept(&mut scratch.d4).run(points, out, sets),
        5 => kept(&mut scratch.d5).run(points, out, sets),
        6 => kept(&mut scratch.d6).run(points, out, sets),
        7 => kept(&mut scratch.d7).run(points, out, sets),
        _ => kept(&mut scratch.d8).run(points, out, sets),
    }
}

/// A set of point indices as a bit set.
trait Set: Copy + Eq + BitAnd<Output = Self> + BitOr<Output = Self> + BitXor<Output = Self> {
    const EMPTY: Self;
    fn bit(i: usize) -> Self;
    /// The set with bits `lo` (points 0..64) and `hi` (points 64..128).
    fn from_words(lo: u64, hi: u64) -> Self;
    fn count(self) -> u32;
    fn lowest(self) -> usize;
    fn without_lowest(self) -> Self;
    fn hash(self) -> u64;
    fn has(self, i: usize) -> bool {
        self & Self::bit(i) != Self::EMPTY
    }
    /// Whether the set has at least `k` members (cheaper than `count` without `popcnt`).
    fn at_least(self, k: usize) -> bool {
        let mut s = self;
        for _ in 1..k {
            s = s.without_lowest();
        }
        k == 0 || s != Self::EMPTY
    }
}

impl Set for u64 {
    const EMPTY: Self = 0;
    fn bit(i: usize) -> Self {
        1 << i
    }
    fn from_words(lo: u64, _hi: u64) -> Self {
        lo
    }
    fn count(self) -> u32 {
        self.count_ones()
    }
    fn lowest(self) -> usize {
        self.trailing_zeros() as usize
    }
    fn without_lowest(self) -> Self {
        self & self.wrapping_sub(1)
    }
    fn hash(self) -> u64 {
        (self ^ (self >> 32)).wrapping_mul(0x9E37_79B9_7F4A_7C15)
    }
}

impl Set for u128 {
    const EMPTY: Self = 0;
    fn bit(i: usize) -> Self {
        1 << i
    }
    fn from_words(lo: u64, hi: u64) -> Self {
        (lo as u128) | ((hi as u128) << 64)
    }
    fn count(self) -> u32 {
        self.count_ones()
    }
    fn lowest(self) -> usize {
        self.trailing_zeros() as usize
    }
    fn without_lowest(self) -> Self {
        self & self.wrapping_sub(1)
    }
    fn hash(self) -> u64 {
        ((self as u64) ^ ((self >> 64) as u64).rotate_left(29)).hash()
    }
}

/// Indices of the points in a set, ascending.
struct Members<S>(S);

impl<S: Set> Iterator for Members<S> {
    type Item = usize;
    fn next(&mut self) -> Option<usize> {
        if self.0 == S::EMPTY {
            None
        } else {
            let i = self.0.lowest();
            self.0 = self.0.without_lowest();
            Some(i)
        }
    }
}

const NONE: u32 = u32::MAX;

/// Facet classes relative to the point being inserted.
const BELOW: u8 = 0;
const COPLANAR: u8 = 1;
const VISIBLE: u8 = 2;
const NEW: u8 = 3;
/// Coplanar and extended by the cone over one of its ridges with a visible facet.
const GROWN: u8 = 4;

/// The `state` of a facet of class `class` at insertion `step`.
fn tag(step: u32, class: u8) -> u32 {
    step << 3 | class as u32
}

/// A facet (a slot: dead slots are recycled). Fields in the order the insertion touches
/// them (`repr(C)` keeps it). Its class for the current insertion is in `Builder::state`.
#[derive(Clone, Copy)]
#[repr(C)]
struct Facet<const D: usize, S> {
    alive: bool,
    nb_len: u32,
    nb_start: u32,
    nb_cap: u32,
    offset: f64,
    normal: [f64; D],
    /// `a . p - b` for the point being inserted (valid where `state` is of this insertion).
    dist: f64,
    verts: S,
    /// Bound on `|a . x - b|` over the points that define the hyperplane.
    err: f64,
}

/// A sub-ridge of a cone through the new point: its points, the facet that owns the cone
/// and the arena index, in that facet's neighbour list, reserved for the facet across it
/// (`NONE` for a grown coplanar facet, whose list is appended to).
#[derive(Clone, Copy)]
struct Key<S> {
    key: S,
    facet: u32,
    slot: u32,
}

/// Hash slot for matching sub-ridges: the key, and the step it was written in with the
/// owner and neighbour slot of the first key seen (`MATCHED` once paired).
#[derive(Clone, Copy)]
struct Slot<S> {
    key: S,
    stamp: u32,
    owner: u32,
    slot: u32,
}

const MATCHED: u32 = u32::MAX - 1;

fn dot<const D: usize>(a: &[f64; D], b: &[f64; D]) -> f64 {
    let mut s = 0.0;
    for k in 0..D {
        s += a[k] * b[k];
    }
    s
}

fn sub<const D: usize>(a: &[f64; D], b: &[f64; D]) -> [f64; D] {
    let mut r = [0.0; D];
    for k in 0..D {
        r[k] = a[k] - b[k];
    }
    r
}

struct Builder<const D: usize, S> {
    /// The input points, scaled by a power of two (`1 / unscale`) into [-1, 1] (unless the
    /// input's magnitude is beyond 2^±1000).
    pts: Vec<[f64; D]>,
    unscale: f64,
    /// Largest coordinate magnitude of `pts`.
    scale: f64,
    tol: f64,
    interior: [f64; D],
    facets: Vec<Facet<D, S>>,
    /// Per facet, `step << 3 | class` where it was classified for insertion `step` (kept
    /// apart from the facets so that class tests touch little memory).
    state: Vec<u32>,
    arena: Vec<u32>,
    free: Vec<u32>,
    created: usize,
    step: u32,
    // Conflict lists: the facet each pending point is above (or NONE), and by how much.
    owner: Vec<u32>,
    height: Vec<f64>,
    // Per-insertion scratch.
    queue: Vec<u32>,
    visible: Vec<u32>,
    grown: Vec<u32>,
    /// New facets and where each replaces a visible facet in its below neighbour's list.
    fresh: Vec<(u32, u32)>,
    keys: Vec<Key<S>>,
    pending: Vec<(u32, u32)>,
    subs: Vec<S>,
    table: Vec<Slot<S>>,
    table_step: u32,
    mat: Vec<[f64; D]>,
}

impl<const D: usize, S: Set> Builder<D, S> {
    /// A builder with nothing allocated yet.
    fn empty() -> Self {
        Self {
            pts: Vec::new(),
            unscale: 1.0,
            scale: 0.0,
            tol: 0.0,
            interior: [0.0; D],
            facets: Vec::new(),
            state: Vec::new(),
            arena: Vec::new(),
            free: Vec::new(),
            created: 0,
            step: 0,
            owner: Vec::new(),
            height: Vec::new(),
            queue: Vec::new(),
            visible: Vec::new(),
            grown: Vec::new(),
            fresh: Vec::new(),
            keys: Vec::new(),
            pending: Vec::new(),
            subs: Vec::new(),
            table: Vec::new(),
            table_step: 0,
            mat: Vec::new(),
        }
    }

    /// Builds the hull of `points` and writes it to `out` (`sets`: scratch for the facets'
    /// point sets). The builder's buffers are kept for the next hull.
    fn run(
        &mut self,
        points: &[f64],
        out: &mut Compressed,
        sets: &mut Vec<S>,
    ) -> Result<(), BeneathBeyondError> {
        self.reset(points);
        self.initial_simplex()?;
        while let Some(p) = self.next_point() {
            self.insert(p)?;
        }
        self.output(&mut out.normals, &mut out.offsets, sets)?;
        let total: u32 = sets.iter().map(|s| s.count()).sum();
        out.facet_offsets.clear();
        out.facet_indices.clear();
        out.facet_offsets.reserve(sets.len() + 1);
        out.facet_indices.reserve(total as usize);
        out.facet_offsets.push(0);
        for &set in sets.iter() {
            out.facet_indices.extend(Members(set).map(|i| i as u32));
            out.facet_offsets.push(out.facet_indices.len() as u32);
        }
        Ok(())
    }

    /// Starts over on `points`, keeping the buffers (grown to at least a fresh builder's).
    fn reset(&mut self, points: &[f64]) {
        let n = points.len() / D;
        // Work on the points scaled by a power of two into [-1, 1]: exact, and products
        // cannot overflow whatever the input's magnitude. `output` scales the offsets back.
        let max = points.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        let exponent = if max > 0.0 {
            (max.log2().ceil() as i32).clamp(-1000, 1000)
        } else {
            0
        };
        self.unscale = 2f64.powi(exponent);
        let rescale = 2f64.powi(-exponent);
        self.pts.clear();
        self.pts.reserve(n);
        let mut scale: f64 = 0.0;
        for c in points.chunks_exact(D) {
            let mut x = [0.0; D];
            for k in 0..D {
                x[k] = c[k] * rescale;
                scale = scale.max(x[k].abs());
            }
            self.pts.push(x);
        }
        self.scale = scale.max(f64::MIN_POSITIVE);
        self.tol = RELATIVE_TOLERANCE * self.scale;
        self.interior = [0.0; D];
        let cap = 16 * n + 64;
        fn fresh<T>(v: &mut Vec<T>, cap: usize) {
            v.clear();
            v.reserve(cap);
        }
        fresh(&mut self.facets, cap);
        fresh(&mut self.state, cap);
        fresh(&mut self.arena, cap * (D + 2));
        fresh(&mut self.free, cap);
        self.created = 0;
        self.step = 0;
        self.owner.clear();
        self.owner.resize(n, NONE);
        self.height.clear();
        self.height.resize(n, 0.0);
        fresh(&mut self.queue, 64);
        fresh(&mut self.visible, 64);
        fresh(&mut self.grown, 64);
        fresh(&mut self.fresh, 128);
        fresh(&mut self.keys, 128 * D);
        fresh(&mut self.pending, 64);
        fresh(&mut self.subs, 64);
        // The table is stamped per use (`table_step`): what is left in it is never read. Long
        // before the stamps wrap around it starts afresh.
        if self.table_step > u32::MAX / 2 {
            self.table = Vec::new();
            self.table_step = 0;
        }
        self.mat.clear();
        self.mat.resize(n, [0.0; D]);
    }

    // ---- facets and neighbour lists --------------------------------------------------------

    #[inline]
    fn nb_push(&mut self, f: usize, g: usize) {
        let fc = &self.facets[f];
        if fc.nb_len == fc.nb_cap {
            self.nb_grow(f);
        }
        let fc = &mut self.facets[f];
        let at = (fc.nb_start + fc.nb_len) as usize;
        fc.nb_len += 1;
        self.arena[at] = g as u32;
    }

    /// Makes room for `cap` neighbours of an empty list.
    fn nb_reserve(&mut self, f: usize, cap: usize) {
        if (self.facets[f].nb_cap as usize) < cap {
            let cap = cap.max(2 * D);
            let start = self.arena.len();
            self.arena.resize(start + cap, 0);
            let fc = &mut self.facets[f];
            fc.nb_start = start as u32;
            fc.nb_cap = cap as u32;
        }
    }

    #[cold]
    fn nb_grow(&mut self, f: usize) {
        let fc = &self.facets[f];
        let (old, len) = (fc.nb_start as usize, fc.nb_len as usize);
        let cap = (2 * len).max(2 * D);
        let start = self.arena.len();
        self.arena.extend_from_within(old..old + len);
        self.arena.resize(start + cap, 0);
        let fc = &mut self.facets[f];
        fc.nb_start = start as u32;
        fc.nb_cap = cap as u32;
    }

    fn add_facet(
        &mut self,
        normal: [f64; D],
        offset: f64,
        err: f64,
        verts: S,
    ) -> Result<usize, BeneathBeyondError> {
        self.created += 1;
        if self.created > MAX_FACETS_CREATED {
            return Err(BeneathBeyondError::TooManyFacets);
        }
        let (nb_start, nb_cap, slot) = match self.free.pop() {
            Some(f) => {
                let old = &self.facets[f as usize];
                (old.nb_start, old.nb_cap, Some(f as usize))
            }
            None => {
                let start = self.arena.len();
                self.arena.resize(start + D + 2, 0);
                (start as u32, (D + 2) as u32, None)
            }
        };
        let facet = Facet {
            normal,
            offset,
            err,
            dist: 0.0,
            verts,
            nb_start,
            nb_len: 0,
            nb_cap,
            alive: true,
        };
        Ok(match slot {
            Some(f) => {
                self.facets[f] = facet;
                self.state[f] = 0;
                f
            }
            None => {
                self.facets.push(facet);
                self.state.push(0);
                self.facets.len() - 1
            }
        })
    }

    fn distance(&self, f: usize, q: usize) -> f64 {
        let fc = &self.facets[f];
        dot(&fc.normal, &self.pts[q]) - fc.offset
    }

    /// Rounding of one evaluation of `a . x - b`.
    fn unit(&self) -> f64 {
        4.0 * D as f64 * f64::EPSILON * self.scale
    }

    // ---- linear algebra --------------------------------------------------------------------

    /// Unit outward normal, offset and residual bound of the hyperplane through point `o` and
    /// the points of `set` (which must span a `(D - 1)`-flat with `o`), oriented away from
    /// the interior point.
    fn plane(&mut self, o: usize, set: S) -> Result<([f64; D], f64, f64), BeneathBeyondError> {
        let x0 = self.pts[o];
        let mut m = 0;
        for i in Members(set) {
            if i != o {
                self.mat[m] = sub(&self.pts[i], &x0);
                m += 1;
            }
        }
        if m + 1 < D {
            return Err(BeneathBeyondError::FacetTooFewPoints);
        }
        let mat = &mut self.mat[..m];
        let mut perm = [0usize; D];
        for (k, p) in perm.iter_mut().enumerate() {
            *p = k;
        }
        // Gaussian elimination with full pivoting down to D - 1 pivots.
        for k in 0..D - 1 {
            let (mut bi, mut bj, mut best) = (k, k, 0.0);
            for (i, row) in mat.iter().enumerate().skip(k) {
                for (j, v) in row.iter().enumerate().skip(k) {
                    if v.abs() > best {
                        (bi, bj, best) = (i, j, v.abs());
                    }
                }
            }
            if best <= self.tol {
                return Err(BeneathBeyondError::DegenerateFacet);
            }
            mat.swap(k, bi);
            if bj != k {
                for row in mat.iter_mut() {
                    row.swap(k, bj);
                }
                perm.swap(k, bj);
            }
            let pivot = mat[k];
            for row in mat[k + 1..].iter_mut() {
                let f = row[k] / pivot[k];
                if f != 0.0 {
                    for j in k + 1..D {
                        row[j] -= f * pivot[j];
                    }
                }
            }
        }
        let mut y = [0.0; D];
        y[D - 1] = 1.0;
        for k in (0..D - 1).rev() {
            let mut s = 0.0;
            for j in k + 1..D {
                s += mat[k][j] * y[j];
            }
            y[k] = -s / mat[k][k];
        }
        let mut a = [0.0; D];
        for k in 0..D {
            a[perm[k]] = y[k];
        }
        let norm = dot(&a, &a).sqrt();
        if !(norm.is_finite() && norm > 0.0) {
            return Err(BeneathBeyondError::DegenerateNormal);
        }
        for v in a.iter_mut() {
            *v /= norm;
        }
        let mut b = dot(&a, &x0);
        let depth = b - dot(&a, &self.interior);
        if depth < 0.0 {
            for v in a.iter_mut() {
                *v = -*v;
            }
            b = -b;
        }
        if depth.abs() <= self.tol {
            return Err(BeneathBeyondError::ThroughInterior);
        }
        let mut err: f64 = 0.0;
        for i in Members(set) {
            err = err.max((dot(&a, &self.pts[i]) - b).abs());
        }
        Ok((a, b, err + self.unit()))
    }

    // ---- construction ----------------------------------------------------------------------

    fn initial_simplex(&mut self) -> Result<(), BeneathBeyondError> {
        let n = self.pts.len();
        let mut centroid = [0.0; D];
        for x in &self.pts {
            for k in 0..D {
                centroid[k] += x[k] / n as f64;
            }
        }
        let mut first = 0;
        let mut best = -1.0;
        for (i, x) in self.pts.iter().enumerate() {
            let d = sub(x, &centroid);
            let s = dot(&d, &d);
            if s > best {
                (first, best) = (i, s);
            }
        }
        let mut chosen = [0usize; 9];
        chosen[0] = first;
        let x0 = self.pts[first];
        for (r, x) in self.mat.iter_mut().zip(&self.pts) {
            *r = sub(x, &x0);
        }
        let mut used = S::bit(first);
        for c in chosen.iter_mut().take(D + 1).skip(1) {
            let (mut bi, mut best) = (usize::MAX, 0.0);
            for (i, r) in self.mat.iter().enumerate() {
                let s = dot(r, r);
                if !used.has(i) && s > best {
                    (bi, best) = (i, s);
                }
            }
            if bi == usize::MAX || best.sqrt() <= self.tol {
                return Err(BeneathBeyondError::NotSpanning);
            }
            *c = bi;
            used = used | S::bit(bi);
            let mut e = self.mat[bi];
            let inv = 1.0 / best.sqrt();
            for v in e.iter_mut() {
                *v *= inv;
            }
            for r in self.mat.iter_mut() {
                let c = dot(r, &e);
                for j in 0..D {
                    r[j] -= c * e[j];
                }
            }
        }
        let mut interior = [0.0; D];
        for &i in &chosen[..=D] {
            for k in 0..D {
                interior[k] += self.pts[i][k] / (D + 1) as f64;
            }
        }
        self.interior = interior;
        for k in 0..=D {
            let set = used ^ S::bit(chosen[k]);
            let (a, b, err) = self.plane(set.lowest(), set)?;
            self.add_facet(a, b, err, set)?;
        }
        for f in 0..=D {
            for g in 0..=D {
                if f != g {
                    self.nb_push(f, g);
                }
            }
        }
        for q in 0..n {
            if used.has(q) {
                continue;
            }
            let (mut bf, mut bh) = (NONE, self.tol);
            for f in 0..=D {
                let h = self.distance(f, q);
                if h > bh {
                    (bf, bh) = (f as u32, h);
                }
            }
            self.owner[q] = bf;
            self.height[q] = bh;
        }
        Ok(())
    }

    fn next_point(&self) -> Option<usize> {
        let mut best = None;
        let mut h = 0.0;
        for (q, (&o, &d)) in self.owner.iter().zip(&self.height).enumerate() {
            if o != NONE && d > h {
                (best, h) = (Some(q), d);
            }
        }
        best
    }

    fn insert(&mut self, p: usize) -> Result<(), BeneathBeyondError> {
        let x = self.pts[p];
        let start = self.owner[p];
        self.owner[p] = NONE;
        self.step += 1;
        let step = self.step;
        let tol = self.tol;

        // Classify the facets around p (breadth-first from its conflict facet, through the
        // visible and coplanar ones): visible, coplanar, below.
        self.queue.clear();
        self.visible.clear();
        {
            let Self {
                facets,
                state,
                arena,
                queue,
                visible,
                ..
            } = self;
            let fc = &mut facets[start as usize];
            let s = dot(&fc.normal, &x) - fc.offset;
            if s <= tol {
                return Err(BeneathBeyondError::StaleConflictList);
            }
            fc.dist = s;
            state[start as usize] = tag(step, VISIBLE);
            queue.push(start);
            visible.push(start);
            while let Some(f) = queue.pop() {
                let fc = &facets[f as usize];
                let (lo, hi) = (fc.nb_start as usize, (fc.nb_start + fc.nb_len) as usize);
                for &g in &arena[lo..hi] {
                    if state[g as usize] >> 3 == step {
                        continue;
                    }
                    let gc = &mut facets[g as usize];
                    let s = dot(&gc.normal, &x) - gc.offset;
                    gc.dist = s;
                    let class = if s > tol {
                        visible.push(g);
                        queue.push(g);
                        VISIBLE
                    } else if s >= -tol {
                        queue.push(g);
                        COPLANAR
                    } else {
                        BELOW
                    };
                    state[g as usize] = tag(step, class);
                }
            }
        }

        // Horizon ridges: a new facet through each ridge to a below facet; a coplanar facet
        // absorbs the cone over its ridges. Each cone's ridges through p are keyed by the
        // sub-ridge they contain.
        let pbit = S::bit(p);
        self.fresh.clear();
        self.grown.clear();
        self.keys.clear();
        for vi in 0..self.visible.len() {
            let f = self.visible[vi] as usize;
            let (lo, len) = (
                self.facets[f].nb_start as usize,
                self.facets[f].nb_len as usize,
            );
            for k in lo..lo + len {
                let g = self.arena[k] as usize;
                match (self.state[g] & 7) as u8 {
                    VISIBLE => {}
                    BELOW => {
                        let ridge = self.facets[f].verts & self.facets[g].verts;
                        // Where f sits in g's list: the new facet takes its place there.
                        let gc = &self.facets[g];
                        let (lo, hi) = (gc.nb_start as usize, (gc.nb_start + gc.nb_len) as usize);
                        let Some(at_g) = self.arena[lo..hi].iter().position(|&e| e == f as u32)
                        else {
                            return Err(BeneathBeyondError::InconsistentAdjacency);
                        };
                        let (a, b, err) = self.rotate(f, g, ridge, p)?;
                        let h = self.add_facet(a, b, err, ridge | pbit)?;
                        self.state[h] = tag(step, NEW);
                        self.fresh.push((h as u32, (lo + at_g) as u32));
                        // Neighbour list: g, then one slot per sub-ridge, filled by matching.
                        let first = self.keys.len();
                        self.sub_ridges(f, g, h as u32, true)?;
                        let m = self.keys.len() - first;
                        self.nb_reserve(h, 1 + m);
                        let fc = &mut self.facets[h];
                        let at = fc.nb_start as usize;
                        fc.nb_len = (1 + m) as u32;
                        self.arena[at] = g as u32;
                        self.arena[at + 1..at + 1 + m].fill(NONE);
                        for (j, key) in self.keys[first..].iter_mut().enumerate() {
                            key.slot = (at + 1 + j) as u32;
                        }
                    }
                    COPLANAR => {
                        self.state[g] = tag(step, GROWN);
                        self.grown.push(g as u32);
                        self.sub_ridges(f, g, g as u32, false)?;
                    }
                    _ => self.sub_ridges(f, g, g as u32, false)?,
                }
            }
        }
        let unit = self.unit();
        for &g in &self.grown {
            // p joins the facet where it is, within tol of the hyperplane: widen the bound.
            let fc = &mut self.facets[g as usize];
            fc.verts = fc.verts | pbit;
            fc.err = fc.err.max(fc.dist.abs() + unit);
        }
        self.match_keys()?;
        self.link(step)?;
        self.reassign(step);
        for &f in &self.visible {
            self.facets[f as usize].alive = false;
        }
        self.free.extend_from_slice(&self.visible);
        Ok(())
    }

    /// Updates the neighbour lists after an insertion (the new facets' lists were filled
    /// while matching sub-ridges).
    fn link(&mut self, step: u32) -> Result<(), BeneathBeyondError> {
        for &(h, at) in &self.fresh {
            self.arena[at as usize] = h;
        }
        {
            let Self {
                facets,
                state,
                arena,
                grown,
                ..
            } = self;
            let visible = tag(step, VISIBLE);
            for &g in grown.iter() {
                let gc = &facets[g as usize];
                let (lo, len) = (gc.nb_start as usize, gc.nb_len as usize);
                let mut w = 0;
                for r in lo..lo + len {
                    let e = arena[r];
                    if state[e as usize] != visible {
                        arena[lo + w] = e;
                        w += 1;
                    }
                }
                facets[g as usize].nb_len = w as u32;
            }
        }
        let grown = tag(step, GROWN);
        for li in 0..self.pending.len() {
            let (x, y) = self.pending[li];
            let (x, y) = (x as usize, y as usize);
            if self.state[y] == grown {
                // Two grown facets may already be neighbours, or meet at several sub-ridges.
                let xc = &self.facets[x];
                let lo = xc.nb_start as usize;
                if self.arena[lo..lo + xc.nb_len as usize].contains(&(y as u32)) {
                    continue;
                }
            }
            self.nb_push(x, y);
        }
        Ok(())
    }

    /// Moves the conflict points of the deleted (visible) facets to the new and grown ones.
    fn reassign(&mut self, step: u32) {
        let tol = self.tol;
        for q in 0..self.pts.len() {
            let o = self.owner[q];
            if o == NONE {
                continue;
            }
            if self.state[o as usize] != tag(step, VISIBLE) {
                continue;
            }
            let x = &self.pts[q];
            let (mut bf, mut bh) = (NONE, tol);
            for h in self
                .fresh
                .iter()
                .map(|t| t.0)
                .chain(self.grown.iter().copied())
            {
                let fc = &self.facets[h as usize];
                let d = dot(&fc.normal, x) - fc.offset;
                if d > bh {
                    (bf, bh) = (h, d);
                }
            }
            if bf == NONE {
                for (f, fc) in self.facets.iter().enumerate() {
                    if fc.alive && self.state[f] != tag(step, VISIBLE) {
                        let d = dot(&fc.normal, x) - fc.offset;
                        if d > bh {
                            (bf, bh) = (f as u32, d);
                        }
                    }
                }
            }
            self.owner[q] = bf;
            self.height[q] = bh;
        }
    }

    /// Hyperplane through the ridge `ridge` of visible `f` and below `g`, and the new point
    /// `p`: the combination of the two hyperplanes that vanishes at `p` (both contain the
    /// ridge). Its rounding is bounded from theirs; past `tol / 1000` the hyperplane is
    /// recomputed from the points.
    fn rotate(
        &mut self,
        f: usize,
        g: usize,
        ridge: S,
        p: usize,
    ) -> Result<([f64; D], f64, f64), BeneathBeyondError> {
        let (ff, gg) = (&self.facets[f], &self.facets[g]);
        let (wf, wg) = (-gg.dist, ff.dist);
        let mut a = [0.0; D];
        for k in 0..D {
            a[k] = wf * ff.normal[k] + wg * gg.normal[k];
        }
        let norm = dot(&a, &a).sqrt();
        let inv = 1.0 / norm;
        for v in a.iter_mut() {
            *v *= inv;
        }
        let b = (wf * ff.offset + wg * gg.offset) * inv;
        let err = (wf * ff.err + wg * gg.err + (wf + wg) * self.unit()) * inv;
        let lim = 1e-3 * self.tol;
        if err <= lim {
            return Ok((a, b, err));
        }
        // The a-priori bound is pessimistic: measure the residuals before recomputing.
        let mut res = (dot(&a, &self.pts[p]) - b).abs();
        for i in Members(ridge) {
            res = res.max((dot(&a, &self.pts[i]) - b).abs());
        }
        let res = res + self.unit();
        if res <= 0.1 * lim {
            Ok((a, b, res))
        } else {
            self.plane(p, ridge)
        }
    }

    /// Appends the keys (sub-ridges) of the cone over the ridge between visible `f` and `g`,
    /// owned by `owner` (with reserved neighbour slots from 1 on if `slots`). A sub-ridge is
    /// a facet of the ridge: for a simplex ridge, the ridge minus one point; otherwise the
    /// inclusion-maximal intersections of the ridge with the other neighbours of `f` (or of
    /// `g`): each facet of the ridge is `f`'s ridge with one of them.
    fn sub_ridges(
        &mut self,
        f: usize,
        g: usize,
        owner: u32,
        slots: bool,
    ) -> Result<(), BeneathBeyondError> {
        let ridge = self.facets[f].verts & self.facets[g].verts;
        if !ridge.at_least(D - 1) {
            return Err(BeneathBeyondError::RidgeTooFewPoints);
        }
        let first = self.keys.len();
        let slot = |i: usize| if slots { (i - first + 1) as u32 } else { NONE };
        if !ridge.at_least(D) {
            let mut keys = [Key {
                key: ridge,
                facet: owner,
                slot: NONE,
            }; D];
            for (j, (k, i)) in keys.iter_mut().zip(Members(ridge)).enumerate() {
                k.key = ridge ^ S::bit(i);
                if slots {
                    k.slot = j as u32 + 1;
                }
            }
            self.keys.extend_from_slice(&keys[..D - 1]);
            return Ok(());
        }
        // Scan the shorter neighbour list of the two facets at the ridge.
        let (e0, skip) = if self.facets[g].nb_len < self.facets[f].nb_len {
            (g, f)
        } else {
            (f, g)
        };
        let subs = &mut self.subs;
        subs.clear();
        let (start, len) = (
            self.facets[e0].nb_start as usize,
            self.facets[e0].nb_len as usize,
        );
        for &e in &self.arena[start..start + len] {
            if e as usize == skip {
                continue;
            }
            let s = ridge & self.facets[e as usize].verts;
            if !s.at_least(D - 2) || subs.iter().any(|&t| s & t == s) {
                continue;
            }
            // Keep the candidates an antichain: drop those inside the new one.
            let mut i = 0;
            while i < subs.len() {
                if subs[i] & s == subs[i] {
                    subs.swap_remove(i);
                } else {
                    i += 1;
                }
            }
            subs.push(s);
        }
        if subs.len() + 1 < D {
            return Err(BeneathBeyondError::RidgeTooFewFacets);
        }
        for i in 0..self.subs.len() {
            let k = Key {
                key: self.subs[i],
                facet: owner,
                slot: slot(self.keys.len()),
            };
            self.keys.push(k);
        }
        Ok(())
    }

    /// Pairs equal keys: each pair is a ridge through p shared by its two owners. Writes the
    /// new facets' reserved neighbour slots; grown facets' new neighbours go to `pending`.
    fn match_keys(&mut self) -> Result<(), BeneathBeyondError> {
        self.pending.clear();
        let want = (2 * self.keys.len()).next_power_of_two().max(16);
        if self.table.len() < want {
            self.table = vec![
                Slot {
                    key: S::EMPTY,
                    stamp: 0,
                    owner: NONE,
                    slot: NONE,
                };
                want
            ];
            self.table_step = 0;
        }
        self.table_step += 1;
        let ts = self.table_step;
        let mask = want - 1;
        let shift = 64 - want.trailing_zeros();
        let Self {
            table,
            keys,
            arena,
            pending,
            ..
        } = self;
        let table = &mut table[..want];
        let mut matched = 0;
        for k in keys.iter() {
            let mut at = (k.key.hash() >> shift) as usize;
            let e = loop {
                let e = &mut table[at & mask];
                if e.stamp != ts || e.key == k.key {
                    break e;
                }
                at += 1;
            };
            if e.stamp != ts {
                *e = Slot {
                    key: k.key,
                    stamp: ts,
                    owner: k.facet,
                    slot: k.slot,
                };
                continue;
            }
            let (x, sx) = (e.owner, e.slot);
            if sx == MATCHED {
                return Err(BeneathBeyondError::RidgeOnMoreThanTwoFacets);
            }
            e.slot = MATCHED;
            matched += 1;
            let y = k.facet;
            if x == y {
                continue; // two pieces of one grown facet
            }
            for (x, sx, y) in [(x, sx, y), (y, k.slot, x)] {
                if sx == NONE {
                    pending.push((x, y));
                } else {
                    arena[sx as usize] = y;
                }
            }
        }
        if 2 * matched != keys.len() {
            return Err(BeneathBeyondError::HorizonNotClosed);
        }
        Ok(())
    }

    /// The final check: every facet against every input point. Writes the facets (normals,
    /// offsets) with the set of input points on each.
    fn output(
        &self,
        normals: &mut Vec<f64>,
        offsets: &mut Vec<f64>,
        sets: &mut Vec<S>,
    ) -> Result<(), BeneathBeyondError> {
        let live = self.facets.iter().filter(|f| f.alive).count();
        normals.clear();
        offsets.clear();
        sets.clear();
        normals.reserve(live * D);
        offsets.reserve(live);
        sets.reserve(live);
        let n = self.pts.len();
        let tol = self.tol;
        let mut facets = self.facets.iter().filter(|f| f.alive);
        loop {
            // BLOCK facets at a time, so that the arithmetic vectorizes.
            let mut block = [None; BLOCK];
            for slot in block.iter_mut() {
                *slot = facets.next();
            }
            if block[0].is_none() {
                break;
            }
            let mut a = [[0.0; BLOCK]; D];
            let mut b = [f64::MAX; BLOCK];
            for (j, fc) in block.iter().enumerate() {
                if let Some(fc) = fc {
                    for k in 0..D {
                        a[k][j] = fc.normal[k];
                    }
                    b[j] = fc.offset;
                }
            }
            let mut above = [0u64; BLOCK];
            let hi = scan_block(&self.pts[n.min(64)..], &a, &b, tol, &mut above);
            let lo = scan_block(&self.pts[..n.min(64)], &a, &b, tol, &mut above);
            for (j, fc) in block.iter().enumerate() {
                let Some(fc) = fc else { break };
                if above[j] != 0 {
                    return Err(BeneathBeyondError::PointAboveFacet { tol });
                }
                let set = S::from_words(lo[j], hi[j]);
                if set & fc.verts != fc.verts || !set.at_least(D) {
                    return Err(BeneathBeyondError::FacetLostPoints);
                }
                let norm = dot(&fc.normal, &fc.normal).sqrt();
                let offset = fc.offset * self.unscale;
                if !((norm - 1.0).abs() <= 1e-9 && offset.is_finite()) {
                    return Err(BeneathBeyondError::FacetNotFinite);
                }
                normals.extend_from_slice(&fc.normal);
                offsets.push(offset);
                sets.push(set);
            }
        }
        if sets.len() < D + 1 {
            return Err(BeneathBeyondError::TooFewFacets);
        }
        Ok(())
    }
}

/// Evaluates `BLOCK` facets (`a` by coordinate, `b`) at the points: returns, per facet, the
/// points within `tol` of it as bits (point `i` at bit `i`), and sets `above` for a point
/// more than `tol` above it.
fn scan_block<const D: usize>(
    pts: &[[f64; D]],
    a: &[[f64; BLOCK]; D],
    b: &[f64; BLOCK],
    tol: f64,
    above: &mut [u64; BLOCK],
) -> [u64; BLOCK] {
    let mut on = [0u64; BLOCK];
    let mut up = [0u64; BLOCK];
    for x in pts.iter().rev() {
        let mut s = [0.0; BLOCK];
        for j in 0..BLOCK {
            s[j] = -b[j];
        }
        for k in 0..D {
            let xk = x[k];
            for j in 0..BLOCK {
                s[j] += a[k][j] * xk;
            }
        }
        for j in 0..BLOCK {
            on[j] = (on[j] << 1) | (s[j] >= -tol) as u64;
            up[j] |= (s[j] > tol) as u64;
        }
    }
    for j in 0..BLOCK {
        above[j] |= up[j];
    }
    on
}

/// Facets evaluated together in the final check.
const BLOCK: usize = 4;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::hull::tests::cube;

    #[test]
    fn cubes_have_merged_facets() {
        for dim in 2..=6 {
            let (normals, offsets, lists) = hull(&cube(dim), dim).unwrap();
            assert_eq!(offsets.len(), 2 * dim, "dim {dim}");
            for (f, list) in lists.iter().enumerate() {
                assert!((offsets[f] - 1.0).abs() < 1e-12);
                assert_eq!(list.len(), 1 << (dim - 1));
                let a = &normals[f * dim..(f + 1) * dim];
                assert!(a.iter().filter(|v| v.abs() > 1e-12).count() == 1);
            }
        }
    }

    #[test]
    fn duplicates_and_points_on_facets_are_listed() {
        let mut pts = cube(3);
        // Centre (interior), a face centre, a duplicate vertex, an edge midpoint.
        pts.extend_from_slice(&[0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 0.0]);
        let (_, offsets, lists) = hull(&pts, 3).unwrap();
        assert_eq!(offsets.len(), 6);
        let on = |i: u32| lists.iter().filter(|l| l.contains(&i)).count();
        assert_eq!(on(8), 0);
        assert_eq!(on(9), 1);
        assert_eq!(on(10), 3);
        assert_eq!(on(11), 2);
    }

    #[test]
    fn more_than_64_points_use_wide_sets() {
        // 125 points of a 5 x 5 x 5 grid: the cube's 6 facets, 25 points on each.
        let mut pts = Vec::new();
        for i in 0..125 {
            pts.extend([(i % 5) as f64, (i / 5 % 5) as f64, (i / 25) as f64]);
        }
        let (_, offsets, lists) = hull(&pts, 3).unwrap();
        assert_eq!(offsets.len(), 6);
        assert!(lists.iter().all(|l| l.len() == 25));
        pts.extend([0.0; 12]);
        let refused = hull(&pts, 3).unwrap_err();
        assert_eq!(refused, BeneathBeyondError::TooManyPoints { count: 129 });
        assert_eq!(refused.to_string(), "129 points: more than 128");
    }

    #[test]
    fn bad_input_is_an_error() {
        assert_eq!(
            hull(&[0.0; 5], 3).unwrap_err(),
            BeneathBeyondError::Ragged { len: 5, dim: 3 }
        );
        let nan = [
            0.0,
            0.0,
            f64::NAN,
            1.0,
            0.0,
            0.0,
            0.0,
            1.0,
            0.0,
            0.0,
            0.0,
            1.0,
        ];
        assert_eq!(
            hull(&nan, 3).unwrap_err(),
            BeneathBeyondError::NonFinite { index: 0 }
        );
        // Flat: four points in a plane of R^3.
        assert_eq!(
            hull(&[0., 0., 0., 1., 0., 0., 0., 1., 0., 1., 1., 0.], 3).unwrap_err(),
            BeneathBeyondError::NotSpanning
        );
        assert_eq!(
            hull(&[], 3).unwrap_err(),
            BeneathBeyondError::TooFewPoints { count: 0, dim: 3 }
        );
        assert_eq!(
            hull(&cube(3), 1).unwrap_err(),
            BeneathBeyondError::Dimension { dim: 1 }
        );
        let nine = hull(&cube(3), 9).unwrap_err();
        assert_eq!(nine, BeneathBeyondError::Dimension { dim: 9 });
        assert_eq!(nine.to_string(), "dimension 9 is not in 2..=8");
    }
}
