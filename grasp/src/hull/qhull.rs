//! The Qhull backend.

use super::{Hull, HullError, dot};
use crate::math::Real;

/// Runs Qhull with its default options on full-rank input.
///
/// Qhull's output capture is off: the `qhull` crate would open two temporary files per hull
/// for it (most of the cost of a small hull, and a panic if no temporary file can be made).
/// With no output options Qhull prints nothing on success; on failure it prints its message
/// to stderr and the error code comes back here.
///
/// Facet lists are taken as the beneath-beyond path defines them, every input point within
/// the tolerance of the facet's hyperplane, rather than Qhull's vertex lists (which keep only
/// one of duplicate points and none of the points inside a facet), so that both paths give
/// the same vertices.
pub(super) fn hull(points: &[Real], dim: usize) -> Result<Hull, HullError> {
    let mut coords = points.to_vec();
    let qh = qhull::Qh::builder()
        .capture_stdout(false)
        .capture_stderr(false)
        .build(dim, &mut coords)
        .map_err(|e| HullError::Backend {
            message: e.to_string(),
        })?;
    let mut normals = Vec::with_capacity(qh.num_facets() * dim);
    let mut offsets = Vec::with_capacity(qh.num_facets());
    for facet in qh.facets() {
        let Some(normal) = facet.normal() else {
            return Err(HullError::Backend {
                message: format!("facet {} has no normal", facet.id()),
            });
        };
        normals.extend_from_slice(normal);
        offsets.push(-facet.offset());
    }
    let tol = super::beneath_beyond::RELATIVE_TOLERANCE
        * points.iter().fold(0.0, |m: Real, x| m.max(x.abs()));
    let facets = normals
        .chunks_exact(dim)
        .zip(&offsets)
        .map(|(a, b)| {
            points
                .chunks_exact(dim)
                .enumerate()
                .filter(|(_, p)| (dot(a, p) - b).abs() <= tol)
                .map(|(i, _)| i as u32)
                .collect()
        })
        .collect();
    Ok(Hull::from_parts(dim, normals, offsets, facets))
}
