//! Export of grasp cases in the input format of the Python/Qhull reference
//! (`bench/reference_qhull.py`, documented in `bench/README.md`), so that the two
//! implementations can be cross-checked and timed on identical data.

use std::fmt::Write;

use crate::math::{Real, Vec3};
use crate::object::{Object, SurfaceSamples};
use crate::wrench::{ContactModel, Space};

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

fn vec3s(out: &mut String, key: &str, v: &[Vec3]) {
    let _ = write!(out, "\"{key}\":[");
    for (i, p) in v.iter().enumerate() {
        let sep = if i == 0 { "" } else { "," };
        // `{:?}` prints the shortest representation that round-trips exactly.
        let _ = write!(out, "{sep}[{:?},{:?},{:?}]", p.x, p.y, p.z);
    }
    out.push_str("],");
}

/// Writes `{"cases": [...]}` for the given cases.
pub fn cases_json(cases: &[Case<'_>]) -> String {
    let mut out = String::from("{\"cases\":[");
    for (i, c) in cases.iter().enumerate() {
        if i > 0 {
            out.push(',');
        }
        let com = c.object.centre_of_mass;
        let _ = write!(
            out,
            "{{\"id\":\"{}\",\"space\":\"{}\",\"mu\":{:?},\"cone_edges\":{},\"rho\":{:?},\"alpha\":{:?},\"centre\":[{:?},{:?},{:?}],",
            c.id,
            c.space.name(),
            c.model.mu(),
            c.model.edges(),
            c.rho,
            c.alpha,
            com.x,
            com.y,
            com.z
        );
        vec3s(&mut out, "ows_points", &c.object.facets.points);
        vec3s(&mut out, "ows_normals", &c.object.facets.normals);
        vec3s(&mut out, "candidate_points", &c.candidates.points);
        vec3s(&mut out, "candidate_normals", &c.candidates.normals);
        out.push_str("\"candidate_neighbours\":[");
        for q in 0..c.candidates.len() {
            let sep = if q == 0 { "" } else { "," };
            let nb: Vec<String> = c
                .candidates
                .adjacency
                .neighbours(q)
                .iter()
                .map(|x| x.to_string())
                .collect();
            let _ = write!(out, "{sep}[{}]", nb.join(","));
        }
        let contacts: Vec<String> = c.contacts.iter().map(|x| x.to_string()).collect();
        let _ = write!(out, "],\"contacts\":[{}]}}", contacts.join(","));
    }
    out.push_str("]}");
    out
}
