//! The Qhull backend.

use super::{Hull, HullError};
use crate::math::Real;

/// Runs Qhull with its default options on full-rank input.
///
/// Qhull's output capture is off: the `qhull` crate would open two temporary files per hull
/// for it (most of the cost of a small hull, and a panic if no temporary file can be made).
/// With no output options Qhull prints nothing on success; on failure it prints its message
/// to stderr and the error code comes back here.
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
    let mut facets = Vec::with_capacity(qh.num_facets());
    for facet in qh.facets() {
        let (Some(normal), Some(vertices)) = (facet.normal(), facet.vertices()) else {
            return Err(HullError::Backend {
                message: format!("facet {} has no normal or no vertices", facet.id()),
            });
        };
        let mut ids = Vec::with_capacity(vertices.size(&qh));
        for v in vertices.iter() {
            let id = v.point_id(&qh).map_err(|e| HullError::Backend {
                message: e.to_string(),
            })?;
            let id = u32::try_from(id).map_err(|_| HullError::Backend {
                message: format!("vertex {} has no input point", v.id()),
            })?;
            ids.push(id);
        }
        normals.extend_from_slice(normal);
        offsets.push(-facet.offset());
        facets.push(ids);
    }
    Ok(Hull::from_parts(dim, normals, offsets, facets))
}
