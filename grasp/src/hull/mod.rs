//! Convex hulls in 3 and 6 dimensions, as an H-representation with facet-vertex incidence.
//!
//! # Two implementations: a fast one, and Qhull as the reference
//! The hulls here are small (the `n x s` primitive wrenches of a grasp, in R^3 or R^6) but
//! their input is degenerate by construction: the `s` edges of one linearised friction cone
//! lie on a 2-flat, so many facets of a 6D grasp hull are not simplices, and duplicate or
//! coplanar points are the rule.
//!
//! - Qhull (Barber, Dobkin & Huhdanpaa 1996) is the field's standard for exactly this: it
//!   merges coplanar facets with a bounded error and reports degenerate input as an error
//!   value instead of returning a wrong hull. We call it through the `qhull` crate (bundled
//!   Qhull sources, safe Rust API) with its default options, which in 5D and up include exact
//!   pre-merges (`Qx`). But a 6D hull of 24 points costs it about 2 to 3 ms here, most of a
//!   quality evaluation.
//! - [`beneath_beyond`] is an incremental construction written for these inputs (tens of
//!   points, 2 to 8 dimensions) that keeps merged, non-simplicial facets as bit sets of
//!   points and checks its result against every input point. It is what [`Hull::new`] uses;
//!   for inputs it declines (more than 128 points, or near-degeneracies at the scale of its
//!   tolerance) [`Hull::new`] falls back to Qhull. [`Hull::new_qhull`] is Qhull alone, the
//!   reference the fast path is tested against (same facet hyperplanes and vertices, in
//!   `grasp/tests/properties.rs`).
//!
//! - [`three_contacts`] enumerates the facets of the 6D hull of three contacts directly
//!   (each contact's wrenches are a convex polygon, so the facets are a few hundred
//!   candidates of known types) and declines degenerate configurations; [`Hull::of_contacts`]
//!   uses it where it applies, [`Hull::new`] otherwise and whenever it declines. Tested
//!   against [`Hull::new`] facet for facet.
//!
//! # Conventions
//! Facet `f` is the half-space `a_f . x <= b_f` with `a_f` a unit outward normal. Vertex and
//! facet-vertex indices refer to the input points.
//!
//! Facets are in a canonical order, whichever construction ran: by their point sets, the
//! facet holding the smallest point on which two facets' lists differ first (for ascending
//! lists: lexicographic, except that a list comes before its own prefixes). So everything
//! downstream that depends on facet order (ties in alpha*'s limiting facet, the published
//! facet list) is the same for every path.

pub mod beneath_beyond;
mod qhull;
pub mod three_contacts;

use crate::math::Real;

/// Why no hull could be built. A lower-dimensional input is an expected outcome that callers
/// branch on (a grasp whose wrenches span a subspace is not force closure).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum HullError {
    /// The dimension is not supported.
    #[error("convex hulls are computed in 2 to 8 dimensions, not {dim}")]
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
    /// A coordinate is NaN or infinite.
    #[error("point {index} has a non-finite coordinate")]
    NonFinite {
        /// Index of the point.
        index: usize,
    },
    /// The points span an affine subspace of lower dimension (this includes too few points).
    #[error("the {count} points span an affine subspace of dimension {rank} < {dim}")]
    Degenerate {
        /// Number of points.
        count: usize,
        /// Dimension of their affine hull.
        rank: usize,
        /// Dimension of the space.
        dim: usize,
    },
    /// Qhull failed for another reason (its message is kept).
    #[error("qhull failed: {message}")]
    Backend {
        /// Qhull's error text.
        message: String,
    },
}

/// A full-dimensional convex polytope: facets `a_f . x <= b_f` and their vertices.
#[derive(Debug, Clone, PartialEq)]
pub struct Hull {
    dim: usize,
    normals: Vec<Real>,
    offsets: Vec<Real>,
    facet_offsets: Vec<u32>,
    facet_indices: Vec<u32>,
    vertices: Vec<u32>,
}

impl Hull {
    /// Builds the convex hull of `points` (row-major, `dim` coordinates per point): by the
    /// beneath-beyond construction for small sets ([`beneath_beyond`]), falling back to
    /// Qhull for the inputs it declines.
    pub fn new(points: &[Real], dim: usize) -> Result<Self, HullError> {
        let mut hull = Self::empty();
        hull.build(points, dim, &mut HullScratch::default())?;
        Ok(hull)
    }

    /// The hull of the primitive wrenches of contacts with `edges`-edge friction cones
    /// (contact-major, edge-major within a contact, `dim` coordinates each): by the facet
    /// enumeration of [`three_contacts`] for three contacts in 6D, falling back to
    /// [`Hull::new`] elsewhere and whenever the enumeration declines. The same hull as
    /// [`Hull::new`] (facet for facet, in the same order).
    pub fn of_contacts(points: &[Real], dim: usize, edges: usize) -> Result<Self, HullError> {
        let mut hull = Self::empty();
        hull.of_contacts_in(points, dim, edges, &mut HullScratch::default())?;
        Ok(hull)
    }

    /// [`Hull::of_contacts`] into `self` (replaced; on an error its contents are unspecified),
    /// built in `scratch`'s buffers: for a caller that builds hull after hull (the wrench-space
    /// node, once per contact set). Once `scratch` and `self` have met an input of the size,
    /// a hull of up to 64 points allocates nothing, unless the construction falls back to
    /// Qhull.
    pub fn of_contacts_in(
        &mut self,
        points: &[Real],
        dim: usize,
        edges: usize,
        scratch: &mut HullScratch,
    ) -> Result<(), HullError> {
        if dim == 6
            && points.len() == 3 * edges * dim
            && three_contacts::hull_in(points, edges, &mut scratch.three, self).is_ok()
        {
            return Ok(());
        }
        self.build(points, dim, scratch)
    }

    /// [`Hull::new`] into `self`, in `scratch`'s buffers.
    fn build(
        &mut self,
        points: &[Real],
        dim: usize,
        scratch: &mut HullScratch,
    ) -> Result<(), HullError> {
        check(points, dim, &mut scratch.residuals)?;
        match beneath_beyond::hull_compressed_in(
            points,
            dim,
            &mut scratch.builders,
            &mut scratch.compressed,
        ) {
            Ok(()) => {
                self.assign_compressed(
                    dim,
                    &mut scratch.compressed,
                    &mut scratch.order,
                    &mut scratch.keys,
                    &mut scratch.bases,
                );
                Ok(())
            }
            Err(_) => {
                *self = qhull::hull(points, dim)?;
                Ok(())
            }
        }
    }

    /// A hull with no facets: only ever a buffer to build into.
    pub(crate) fn empty() -> Self {
        Self {
            dim: 0,
            normals: Vec::new(),
            offsets: Vec::new(),
            facet_offsets: Vec::new(),
            facet_indices: Vec::new(),
            vertices: Vec::new(),
        }
    }

    /// The same hull computed by Qhull alone: the reference for the fast path.
    pub fn new_qhull(points: &[Real], dim: usize) -> Result<Self, HullError> {
        check(points, dim, &mut Vec::new())?;
        qhull::hull(points, dim)
    }

    /// Dimension of the space.
    pub fn dim(&self) -> usize {
        self.dim
    }

    /// Number of facets.
    pub fn facet_count(&self) -> usize {
        self.offsets.len()
    }

    /// Outward unit normals, row-major (`facet_count x dim`).
    pub fn normals(&self) -> &[Real] {
        &self.normals
    }

    /// Outward unit normal of facet `f`.
    pub fn normal(&self, f: usize) -> &[Real] {
        &self.normals[f * self.dim..(f + 1) * self.dim]
    }

    /// Offsets `b_f` (signed distance of each facet hyperplane from the origin).
    pub fn offsets(&self) -> &[Real] {
        &self.offsets
    }

    /// Input indices of the points on facet `f` (within the tolerance of its hyperplane).
    pub fn facet_vertices(&self, f: usize) -> &[u32] {
        &self.facet_indices[self.facet_offsets[f] as usize..self.facet_offsets[f + 1] as usize]
    }

    /// Input indices of the hull's vertices (extreme points; every copy of a duplicated
    /// extreme point), ascending.
    pub fn vertices(&self) -> &[u32] {
        &self.vertices
    }

    /// Largest violation `max_f (a_f . x - b_f)`: negative inside, positive outside.
    pub fn violation(&self, x: &[Real]) -> Real {
        self.normals
            .chunks_exact(self.dim)
            .zip(&self.offsets)
            .map(|(a, b)| dot(a, x) - b)
            .fold(Real::NEG_INFINITY, Real::max)
    }

    /// For each input point, the facets it lies on if it is a vertex (an extreme point), else
    /// an empty list.
    pub fn vertex_facets(&self, input_count: usize) -> Vec<Vec<u32>> {
        let mut out = incident_facets(&self.facet_offsets, &self.facet_indices, input_count);
        for (i, facets) in out.iter_mut().enumerate() {
            if self.vertices.binary_search(&(i as u32)).is_err() {
                facets.clear();
            }
        }
        out
    }

    fn from_parts(
        dim: usize,
        normals: Vec<Real>,
        offsets: Vec<Real>,
        facets: Vec<Vec<u32>>,
    ) -> Self {
        let mut c = beneath_beyond::Compressed {
            normals,
            offsets,
            facet_offsets: Vec::with_capacity(facets.len() + 1),
            facet_indices: Vec::new(),
        };
        c.facet_offsets.push(0);
        for mut f in facets {
            f.sort_unstable();
            c.facet_indices.extend_from_slice(&f);
            c.facet_offsets.push(c.facet_indices.len() as u32);
        }
        let mut hull = Self::empty();
        hull.assign_compressed(
            dim,
            &mut c,
            &mut Vec::new(),
            &mut Vec::new(),
            &mut Vec::new(),
        );
        hull
    }

    /// Makes `self` the hull with the facets of `c` (ascending facet lists in compressed
    /// form, in any order): the facets in the canonical order, and the vertices. Facets
    /// already in that order are not copied: `self`'s buffers and `c`'s are swapped (both
    /// keep their capacity for the next hull). `order`, `keys` and `bases` are scratch.
    fn assign_compressed(
        &mut self,
        dim: usize,
        c: &mut beneath_beyond::Compressed,
        order: &mut Vec<u32>,
        keys: &mut Vec<u128>,
        bases: &mut Vec<Basis>,
    ) {
        self.dim = dim;
        let count = c.offsets.len();
        let list = |c: &beneath_beyond::Compressed, f: usize| -> std::ops::Range<usize> {
            c.facet_offsets[f] as usize..c.facet_offsets[f + 1] as usize
        };
        let sorted = (1..count).all(|f| {
            canonical_cmp(
                &c.facet_indices[list(c, f - 1)],
                &c.facet_indices[list(c, f)],
            )
            .is_lt()
        });
        if sorted {
            std::mem::swap(&mut self.normals, &mut c.normals);
            std::mem::swap(&mut self.offsets, &mut c.offsets);
            std::mem::swap(&mut self.facet_offsets, &mut c.facet_offsets);
            std::mem::swap(&mut self.facet_indices, &mut c.facet_indices);
            self.find_vertices(bases);
            return;
        }
        let indices = &c.facet_indices;
        order.clear();
        order.extend(0..count as u32);
        if indices.iter().all(|&i| i < 128) {
            keys.clear();
            keys.extend((0..count).map(|f| canonical_key(&indices[list(c, f)])));
            order.sort_unstable_by_key(|&f| std::cmp::Reverse(keys[f as usize]));
        } else {
            order.sort_unstable_by(|&f, &g| {
                canonical_cmp(&indices[list(c, f as usize)], &indices[list(c, g as usize)])
            });
        }
        self.normals.clear();
        self.offsets.clear();
        self.facet_offsets.clear();
        self.facet_indices.clear();
        self.normals.reserve(c.normals.len());
        self.offsets.reserve(count);
        self.facet_offsets.reserve(count + 1);
        self.facet_indices.reserve(indices.len());
        self.facet_offsets.push(0);
        for &f in order.iter() {
            let f = f as usize;
            self.normals
                .extend_from_slice(&c.normals[f * dim..(f + 1) * dim]);
            self.offsets.push(c.offsets[f]);
            self.facet_indices.extend_from_slice(&indices[list(c, f)]);
            self.facet_offsets.push(self.facet_indices.len() as u32);
        }
        self.find_vertices(bases);
    }

    /// The vertices of a hull whose facets are in place (in the canonical order), into
    /// `self.vertices`; `bases` is scratch.
    fn find_vertices(&mut self, bases: &mut Vec<Basis>) {
        let dim = self.dim;
        let (normals, offsets, facet_offsets, facet_indices) = (
            &self.normals,
            &self.offsets,
            &self.facet_offsets,
            &self.facet_indices,
        );
        debug_assert!((1..offsets.len()).all(|f| {
            let list =
                |f: usize| &facet_indices[facet_offsets[f] as usize..facet_offsets[f + 1] as usize];
            canonical_cmp(list(f - 1), list(f)).is_lt()
        }));
        // A point on facets is a vertex (an extreme point) when the normals of its facets span
        // the space: its normal cone is full-dimensional. This leaves out points that lie on
        // the boundary without being extreme (inside a facet, on an edge between two vertices).
        // Greedy Gram-Schmidt per point over its facets, stopping at a basis; a normal counts
        // when its residual exceeds 1e-10. Facets with `dim` points (simplices) go first, then
        // the others, each group in a golden-ratio stride order of the facet indices: a
        // point's simplicial facets point in varied directions, while its large facets (a
        // whole friction polygon, say) often share a subspace, and neighbours in the canonical
        // order often share a ridge; so a basis is reached in few steps.
        let count = facet_indices
            .iter()
            .map(|&i| i as usize + 1)
            .max()
            .unwrap_or(0);
        bases.clear();
        bases.resize(count, Basis::default());
        let facets = offsets.len();
        let stride = golden_stride(facets);
        for simplices in [true, false] {
            let mut f = 0;
            for _ in 0..facets {
                f += stride;
                if f >= facets {
                    f -= facets;
                }
                let range = facet_offsets[f] as usize..facet_offsets[f + 1] as usize;
                if (range.len() == dim) == simplices {
                    let a = &normals[f * dim..(f + 1) * dim];
                    for &i in &facet_indices[range] {
                        bases[i as usize].add(a, dim);
                    }
                }
            }
        }
        self.vertices.clear();
        self.vertices.extend(
            bases
                .iter()
                .enumerate()
                .filter(|(_, b)| b.rank == dim)
                .map(|(i, _)| i as u32),
        );
    }
}

/// The buffers of [`Hull::of_contacts_in`], kept between hulls.
#[derive(Default)]
pub struct HullScratch {
    three: three_contacts::Scratch,
    builders: beneath_beyond::Scratch,
    compressed: beneath_beyond::Compressed,
    residuals: Vec<Real>,
    order: Vec<u32>,
    keys: Vec<u128>,
    bases: Vec<Basis>,
}

impl std::fmt::Debug for HullScratch {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("HullScratch").finish_non_exhaustive()
    }
}

/// An orthonormal basis (up to 8 dimensions) grown by greedy Gram-Schmidt.
#[derive(Clone, Copy, Default)]
struct Basis {
    vectors: [[Real; 8]; 8],
    rank: usize,
}

impl Basis {
    /// Adds the unit vector `v` (`dim` <= 8 coordinates) when its residual after projection
    /// exceeds 1e-10; nothing once the basis spans R^dim.
    #[inline]
    fn add(&mut self, v: &[Real], dim: usize) {
        if self.rank == dim {
            return;
        }
        match dim {
            6 => self.add_fixed::<6>(v),
            3 => self.add_fixed::<3>(v),
            _ => self.add_any(v, dim),
        }
    }

    /// [`Self::add`] for a fixed dimension (unrolled; the same arithmetic as `add_any`).
    #[inline(always)]
    fn add_fixed<const D: usize>(&mut self, v: &[Real]) {
        let mut r = [0.0; D];
        r.copy_from_slice(&v[..D]);
        for e in &self.vectors[..self.rank] {
            let c = dot(&r, &e[..D]);
            for k in 0..D {
                r[k] -= c * e[k];
            }
        }
        let norm = dot(&r, &r).sqrt();
        if norm > 1e-10 {
            for (b, x) in self.vectors[self.rank][..D].iter_mut().zip(&r) {
                *b = x / norm;
            }
            self.rank += 1;
        }
    }

    fn add_any(&mut self, v: &[Real], dim: usize) {
        let mut r = [0.0; 8];
        r[..dim].copy_from_slice(&v[..dim]);
        for e in &self.vectors[..self.rank] {
            let c = dot(&r[..dim], &e[..dim]);
            for k in 0..dim {
                r[k] -= c * e[k];
            }
        }
        let norm = dot(&r[..dim], &r[..dim]).sqrt();
        if norm > 1e-10 {
            for (b, x) in self.vectors[self.rank][..dim].iter_mut().zip(&r) {
                *b = x / norm;
            }
            self.rank += 1;
        }
    }
}

/// A stride coprime with `n` near `0.618 n` (1 for `n <= 2`): stepping by it modulo `n`
/// visits every index once, consecutive visits far apart.
fn golden_stride(n: usize) -> usize {
    fn gcd(a: usize, b: usize) -> usize {
        if b == 0 { a } else { gcd(b, a % b) }
    }
    if n <= 2 {
        return 1;
    }
    let mut stride = ((n as f64 * 0.618_034) as usize).clamp(1, n - 1);
    while gcd(n, stride) != 1 {
        stride -= 1;
    }
    stride
}

/// The canonical order of two facets by their ascending point lists: the one holding the
/// smallest point in which they differ comes first (lexicographic, except that a list comes
/// before its own prefixes).
fn canonical_cmp(a: &[u32], b: &[u32]) -> std::cmp::Ordering {
    for (x, y) in a.iter().zip(b) {
        if x != y {
            return x.cmp(y);
        }
    }
    b.len().cmp(&a.len())
}

/// A key for [`canonical_cmp`] when every point index is below 128: the point set with point
/// `i` at bit `127 - i`; descending keys are the canonical order.
fn canonical_key(list: &[u32]) -> u128 {
    list.iter().fold(0, |k, &i| k | (1u128 << (127 - i)))
}

/// For each input point, the facets whose lists hold it.
fn incident_facets(offsets: &[u32], indices: &[u32], count: usize) -> Vec<Vec<u32>> {
    let mut out = vec![Vec::new(); count];
    for f in 0..offsets.len().saturating_sub(1) {
        for &v in &indices[offsets[f] as usize..offsets[f + 1] as usize] {
            if let Some(list) = out.get_mut(v as usize) {
                list.push(f as u32);
            }
        }
    }
    out
}

/// Checks the input: dimension, whole points, finite, full-dimensional (`residuals`:
/// scratch for [`affine_rank_in`]).
fn check(points: &[Real], dim: usize, residuals: &mut Vec<Real>) -> Result<(), HullError> {
    if !(2..=8).contains(&dim) {
        return Err(HullError::Dimension { dim });
    }
    if !points.len().is_multiple_of(dim) {
        return Err(HullError::Ragged {
            len: points.len(),
            dim,
        });
    }
    if let Some(i) = points.iter().position(|x| !x.is_finite()) {
        return Err(HullError::NonFinite { index: i / dim });
    }
    let count = points.len() / dim;
    let rank = affine_rank_in(points, dim, residuals);
    if rank < dim {
        return Err(HullError::Degenerate { count, rank, dim });
    }
    Ok(())
}

/// Dot product of two equal-length slices, unrolled for the wrench dimensions 3 and 6.
#[inline(always)]
pub(crate) fn dot(a: &[Real], b: &[Real]) -> Real {
    if let (Ok(a), Ok(b)) = (<&[Real; 6]>::try_from(a), <&[Real; 6]>::try_from(b)) {
        return (a[0] * b[0] + a[1] * b[1])
            + (a[2] * b[2] + a[3] * b[3])
            + (a[4] * b[4] + a[5] * b[5]);
    }
    if let (Ok(a), Ok(b)) = (<&[Real; 3]>::try_from(a), <&[Real; 3]>::try_from(b)) {
        return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    }
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// Dimension of the affine hull of the points, by Gram-Schmidt with a relative tolerance.
pub fn affine_rank(points: &[Real], dim: usize) -> usize {
    affine_rank_in(points, dim, &mut Vec::new())
}

/// [`affine_rank`] with its residuals in `residuals` (scratch; `dim` <= 8).
fn affine_rank_in(points: &[Real], dim: usize, residuals: &mut Vec<Real>) -> usize {
    let count = points.len() / dim;
    if count == 0 {
        return 0;
    }
    let origin = &points[..dim];
    let scale = points
        .chunks_exact(dim)
        .map(|p| {
            p.iter()
                .zip(origin)
                .map(|(x, o)| (x - o).abs())
                .fold(0.0, Real::max)
        })
        .fold(0.0, Real::max);
    if scale == 0.0 {
        return 0;
    }
    let tol = 1e-10 * scale;
    let mut rank = 0;
    let mut e = [0.0; 8];
    let e = &mut e[..dim];
    // Greedy: repeatedly add the point whose residual after projection is largest.
    residuals.clear();
    residuals.extend(
        points
            .chunks_exact(dim)
            .flat_map(|p| p.iter().zip(origin).map(|(x, o)| x - o)),
    );
    while rank < dim {
        let (best, norm) = residuals
            .chunks_exact(dim)
            .enumerate()
            .map(|(i, r)| (i, dot(r, r).sqrt()))
            .fold((0, 0.0), |acc, x| if x.1 > acc.1 { x } else { acc });
        if norm <= tol {
            break;
        }
        for (ek, x) in e.iter_mut().zip(&residuals[best * dim..(best + 1) * dim]) {
            *ek = x / norm;
        }
        for r in residuals.chunks_exact_mut(dim) {
            let c = dot(r, e);
            for (ri, ei) in r.iter_mut().zip(e.iter()) {
                *ri -= c * ei;
            }
        }
        rank += 1;
    }
    rank
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// The vertices of the cube [-1, 1]^dim, row-major.
    pub(crate) fn cube(dim: usize) -> Vec<Real> {
        let mut pts = Vec::new();
        for mask in 0..(1u32 << dim) {
            for k in 0..dim {
                pts.push(if mask >> k & 1 == 1 { 1.0 } else { -1.0 });
            }
        }
        pts
    }

    #[test]
    fn cube_hulls_have_2d_facets_at_distance_one() {
        for dim in [3, 6] {
            let pts = cube(dim);
            let hull = Hull::new(&pts, dim).unwrap();
            assert_eq!(hull.facet_count(), 2 * dim, "dim {dim}");
            for f in 0..hull.facet_count() {
                assert!((hull.offsets()[f] - 1.0).abs() < 1e-12);
                // A merged cube facet has 2^(dim-1) vertices.
                assert_eq!(hull.facet_vertices(f).len(), 1 << (dim - 1));
            }
            assert_eq!(hull.vertices().len(), 1 << dim);
            for p in pts.chunks_exact(dim) {
                assert!(hull.violation(p) <= 1e-12);
            }
        }
    }

    #[test]
    fn interior_and_duplicate_points_are_not_vertices() {
        let mut pts = cube(3);
        pts.extend_from_slice(&[0.0, 0.0, 0.0, 0.5, 0.5, 0.5, 1.0, 1.0, 1.0]);
        let hull = Hull::new(&pts, 3).unwrap();
        assert!(!hull.vertices().contains(&8));
        assert!(!hull.vertices().contains(&9));
        // A duplicate of a vertex is a vertex too (both backends).
        assert!(hull.vertices().contains(&10) && hull.vertices().contains(&7));
        let reference = Hull::new_qhull(&pts, 3).unwrap();
        assert_eq!(reference.vertices(), hull.vertices());
        assert_eq!(hull.facet_count(), 6);
    }

    #[test]
    fn flat_input_is_a_status_not_a_panic() {
        // Six points in a 3-flat of R^6.
        let mut pts = cube(3);
        pts = pts
            .chunks_exact(3)
            .flat_map(|p| [p[0], p[1], p[2], 0.0, 0.0, 0.0])
            .collect();
        match Hull::new(&pts, 6) {
            Err(HullError::Degenerate { rank, dim, .. }) => assert_eq!((rank, dim), (3, 6)),
            other => panic!("expected a degenerate status, got {other:?}"),
        }
        assert!(matches!(
            Hull::new(&[0.0, 0.0, f64::NAN, 1.0, 0.0, 0.0], 3),
            Err(HullError::NonFinite { index: 0 })
        ));
        assert!(matches!(
            Hull::new(&[0.0; 5], 3),
            Err(HullError::Ragged { .. })
        ));
        assert!(matches!(
            Hull::new(&[], 3),
            Err(HullError::Degenerate { rank: 0, .. })
        ));
    }

    #[test]
    fn affine_rank_counts_dimensions() {
        assert_eq!(affine_rank(&[1.0, 1.0, 1.0, 1.0, 1.0, 1.0], 3), 0);
        assert_eq!(
            affine_rank(&[0.0, 0.0, 0.0, 1.0, 2.0, 3.0, 2.0, 4.0, 6.0], 3),
            1
        );
        assert_eq!(affine_rank(&cube(3), 3), 3);
    }
}
