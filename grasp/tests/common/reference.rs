//! Export of grasp cases in the input format of the Python/Qhull reference
//! (`bench/reference_qhull.py`, documented in `bench/README.md`), so that the two
//! implementations can be cross-checked (`tests/cross_reference_qhull.rs`) and timed
//! (`benches/quality.rs`) on identical data. Shared by the test and the bench (which includes
//! this file by its path).

use icrflow_grasp::math::{Real, Vec3};
use icrflow_grasp::object::{Object, SurfaceSamples};
use icrflow_grasp::wrench::{ContactModel, Space};
use serde_json::{Value, json};

/// One grasp case for the reference.
pub struct Case<'a> {
    /// Identifier echoed back in the results.
    pub id: String,
    /// The object (its facets are the OWS generators).
    pub object: &'a Object,
    /// Candidate contact points (the object's facets in 6D, its section when planar).
    pub candidates: &'a SurfaceSamples,
    /// Wrench space.
    pub space: Space,
    /// Contact model.
    pub model: ContactModel,
    /// Torque normalisation length.
    pub rho: Real,
    /// Quality margin.
    pub alpha: Real,
    /// Contacts (candidate indices).
    pub contacts: Vec<usize>,
}

/// Points or normals as `[[x, y, z], ...]`.
fn vec3s(v: &[Vec3]) -> Value {
    v.iter().map(|p| json!([p.x, p.y, p.z])).collect()
}

/// `{"cases": [...]}` for the given cases (serde_json writes each number in the shortest form
/// that reads back exactly).
pub fn cases_json(cases: &[Case<'_>]) -> String {
    let cases: Vec<Value> = cases
        .iter()
        .map(|c| {
            let com = c.object.centre_of_mass;
            let neighbours: Vec<&[u32]> = (0..c.candidates.len())
                .map(|q| c.candidates.adjacency.neighbours(q))
                .collect();
            json!({
                "id": c.id,
                "space": c.space.name(),
                "mu": c.model.mu(),
                "cone_edges": c.model.edges(),
                "rho": c.rho,
                "alpha": c.alpha,
                "centre": [com.x, com.y, com.z],
                "ows_points": vec3s(&c.object.facets.points),
                "ows_normals": vec3s(&c.object.facets.normals),
                "candidate_points": vec3s(&c.candidates.points),
                "candidate_normals": vec3s(&c.candidates.normals),
                "candidate_neighbours": neighbours,
                "contacts": c.contacts,
            })
        })
        .collect();
    json!({ "cases": cases }).to_string()
}
