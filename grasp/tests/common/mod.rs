//! Shared fixtures for the grasp integration tests.
#![allow(dead_code)]

pub mod reference;

use std::path::PathBuf;

use icrflow_grasp::math::{Real, UnitQuaternion};
use icrflow_grasp::object::{Object, SurfaceSamples};
use icrflow_grasp::quality::GraspProblem;
use icrflow_grasp::wrench::{ContactModel, Space, WrenchFrame};

/// Candidates of `object` for `space`: facets in 6D, the section when planar.
pub fn candidates(object: &Object, space: Space) -> &SurfaceSamples {
    match space {
        Space::Planar => &object.section.samples,
        Space::Spatial => &object.facets,
    }
}

/// The problem for `object` in `space`, rho = the object's largest radius.
pub fn problem(object: &Object, space: Space, mu: Real, edges: usize) -> GraspProblem {
    posed_problem(object, UnitQuaternion::identity(), space, mu, edges)
}

/// The problem for `object` (already moved to `orientation`) in `space`.
pub fn posed_problem(
    object: &Object,
    orientation: UnitQuaternion,
    space: Space,
    mu: Real,
    edges: usize,
) -> GraspProblem {
    let frame = WrenchFrame::new(object.centre_of_mass, object.max_radius(), space)
        .unwrap()
        .with_orientation(orientation);
    GraspProblem::new(
        &object.facets,
        candidates(object, space).clone(),
        frame,
        ContactModel::new(mu, edges).unwrap(),
    )
    .unwrap()
}

/// A scratch directory for one test, removed and recreated.
pub fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("icrflow-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// An ellipsoid read back from a binary STL file (triangulated), so that the mesh path is
/// the one exercised: `segments` x `segments / 2` gives about `segments^2` triangles.
pub fn ellipsoid_mesh(segments: usize) -> Object {
    let dir = scratch(&format!("ellipsoid-{segments}"));
    let path = dir.join("ellipsoid.stl");
    Object::ellipsoid(
        icrflow_grasp::math::Vec3::new(0.06, 0.045, 0.035),
        segments,
        segments / 2,
    )
    .unwrap()
    .write_stl(&path)
    .unwrap();
    let object = Object::from_file(&path).unwrap();
    let _ = std::fs::remove_dir_all(&dir);
    object
}

/// Deterministic pseudo-random numbers (SplitMix64), so failures reproduce.
pub struct Rng(pub u64);

impl Rng {
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    pub fn below(&mut self, n: usize) -> usize {
        (self.next_u64() % n as u64) as usize
    }

    pub fn uniform(&mut self, lo: Real, hi: Real) -> Real {
        lo + (hi - lo) * (self.next_u64() >> 11) as Real / (1u64 << 53) as Real
    }
}

/// Random force-closure grasps: among 40 x `wanted` random tries of `contacts` candidates,
/// the `wanted` force-closure grasps of highest quality (strong grasps have regions large
/// enough to sample).
pub fn force_closure_grasps(
    problem: &GraspProblem,
    rng: &mut Rng,
    contacts: usize,
    wanted: usize,
) -> Vec<Vec<usize>> {
    let n = problem.candidates().len();
    let mut found: Vec<(Real, Vec<usize>)> = Vec::new();
    for _ in 0..wanted * 40 {
        let c: Vec<usize> = (0..contacts).map(|_| rng.below(n)).collect();
        let e = problem.evaluate(&c).unwrap();
        if e.force_closure() && e.quality > 0.0 && e.quality.is_finite() {
            found.push((e.quality, c));
        }
    }
    assert!(
        found.len() >= wanted,
        "found only {} force-closure grasps",
        found.len()
    );
    found.sort_by(|a, b| b.0.total_cmp(&a.0));
    found.into_iter().take(wanted).map(|(_, c)| c).collect()
}
