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
        check(points, dim)?;
        match beneath_beyond::hull_compressed(points, dim) {
            Ok((normals, offsets, facet_offsets, facet_indices)) => Ok(Self::from_compressed(
                dim,
                normals,
                offsets,
                facet_offsets,
                facet_indices,
            )),
            Err(_) => qhull::hull(points, dim),
        }
    }

    /// The hull of the primitive wrenches of contacts with `edges`-edge friction cones
    /// (contact-major, edge-major within a contact, `dim` coordinates each): by the facet
    /// enumeration of [`three_contacts`] for three contacts in 6D, falling back to
    /// [`Hull::new`] elsewhere and whenever the enumeration declines. The same hull as
    /// [`Hull::new`] either way.
    pub fn of_contacts(points: &[Real], dim: usize, edges: usize) -> Result<Self, HullError> {
        if dim == 6
            && points.len() == 3 * edges * dim
            && let Ok(hull) = three_contacts::hull(points, edges)
        {
            return Ok(hull);
        }
        Self::new(points, dim)
    }

    /// The same hull computed by Qhull alone: the reference for the fast path.
    pub fn new_qhull(points: &[Real], dim: usize) -> Result<Self, HullError> {
        check(points, dim)?;
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
        let mut facet_offsets = Vec::with_capacity(facets.len() + 1);
        let mut facet_indices = Vec::new();
        facet_offsets.push(0);
        for mut f in facets {
            f.sort_unstable();
            facet_indices.extend_from_slice(&f);
            facet_offsets.push(facet_indices.len() as u32);
        }
        Self::from_compressed(dim, normals, offsets, facet_offsets, facet_indices)
    }

    /// The hull from its facets, with ascending facet lists in compressed form (the list of
    /// facet `f` is `facet_indices[facet_offsets[f]..facet_offsets[f + 1]]`), in any order.
    fn from_compressed(
        dim: usize,
        normals: Vec<Real>,
        offsets: Vec<Real>,
        facet_offsets: Vec<u32>,
        facet_indices: Vec<u32>,
    ) -> Self {
        let list =
            |f: usize| &facet_indices[facet_offsets[f] as usize..facet_offsets[f + 1] as usize];
        let count = offsets.len();
        if (1..count).all(|f| canonical_cmp(list(f - 1), list(f)).is_lt()) {
            return Self::from_sorted(dim, normals, offsets, facet_offsets, facet_indices);
        }
        let mut order: Vec<u32> = (0..count as u32).collect();
        if facet_indices.iter().all(|&i| i < 128) {
            let keys: Vec<u128> = (0..count).map(|f| canonical_key(list(f))).collect();
            order.sort_unstable_by_key(|&f| std::cmp::Reverse(keys[f as usize]));
        } else {
            order.sort_unstable_by(|&f, &g| canonical_cmp(list(f as usize), list(g as usize)));
        }
        let mut sorted_normals = Vec::with_capacity(normals.len());
        let mut sorted_offsets = Vec::with_capacity(count);
        let mut sorted_facet_offsets = Vec::with_capacity(count + 1);
        let mut sorted_indices = Vec::with_capacity(facet_indices.len());
        sorted_facet_offsets.push(0);
        for &f in &order {
            let f = f as usize;
            sorted_normals.extend_from_slice(&normals[f * dim..(f + 1) * dim]);
            sorted_offsets.push(offsets[f]);
            sorted_indices.extend_from_slice(list(f));
            sorted_facet_offsets.push(sorted_indices.len() as u32);
        }
        Self::from_sorted(
            dim,
            sorted_normals,
            sorted_offsets,
            sorted_facet_offsets,
            sorted_indices,
        )
    }

    /// The hull from facets already in the canonical order and its vertices (ascending), for
    /// a construction that knows them: [`three_contacts`], where every point on a facet is
    /// extreme (see there), so the per-point rank test of [`Self::from_sorted`] is not needed.
    fn from_sorted_with_vertices(
        dim: usize,
        normals: Vec<Real>,
        offsets: Vec<Real>,
        facet_offsets: Vec<u32>,
        facet_indices: Vec<u32>,
        vertices: Vec<u32>,
    ) -> Self {
        Self {
            dim,
            normals,
            offsets,
            facet_offsets,
            facet_indices,
            vertices,
        }
    }

    /// [`Self::from_compressed`] for facets already in the canonical order.
    fn from_sorted(
        dim: usize,
        normals: Vec<Real>,
        offsets: Vec<Real>,
        facet_offsets: Vec<u32>,
        facet_indices: Vec<u32>,
    ) -> Self {
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
        let mut bases = vec![Basis::default(); count];
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
        let vertices = bases
            .iter()
            .enumerate()
            .filter(|(_, b)| b.rank == dim)
            .map(|(i, _)| i as u32)
            .collect();
        Self::from_sorted_with_vertices(
            dim,
            normals,
            offsets,
            facet_offsets,
            facet_indices,
            vertices,
        )
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

/// Checks the input: dimension, whole points, finite, full-dimensional.
fn check(points: &[Real], dim: usize) -> Result<(), HullError> {
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
    let rank = affine_rank(points, dim);
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
    let mut e = vec![0.0; dim];
    // Greedy: repeatedly add the point whose residual after projection is largest.
    let mut residuals: Vec<Real> = points
        .chunks_exact(dim)
        .flat_map(|p| p.iter().zip(origin).map(|(x, o)| x - o))
        .collect();
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
            let c = dot(r, &e);
            for (ri, ei) in r.iter_mut().zip(&e) {
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
