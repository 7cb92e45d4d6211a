//! Invariants of the grasp analysis on random grasps of spheres and meshes (proptest):
//! - every input wrench is inside its hull;
//! - alpha* by hull facets and support function equals alpha* by ray-shooting LPs;
//! - alpha* is unchanged by a rigid motion of the object with its contacts;
//! - epsilon > 0 exactly when the grasp is force closure.

#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    reason = "a test, bench or example: a panic is its failure, with the message it gives"
)]

mod common;

use std::sync::OnceLock;

use icrflow_grasp::hull::Hull;
use icrflow_grasp::lp::quality_by_lp;
use icrflow_grasp::math::{Isometry3, Real, UnitQuaternion, Vec3};
use icrflow_grasp::object::Object;
use icrflow_grasp::wrench::Space;
use proptest::prelude::*;

/// Small objects, so that one LP per OWS generator stays affordable.
fn objects() -> &'static [Object] {
    static OBJECTS: OnceLock<Vec<Object>> = OnceLock::new();
    OBJECTS.get_or_init(|| {
        vec![
            Object::sphere(0.0475, 24, 12).unwrap(),
            common::ellipsoid_mesh(20),
            Object::cuboid(Vec3::new(0.04, 0.03, 0.025), 3).unwrap(),
        ]
    })
}

#[derive(Debug, Clone)]
struct Grasp {
    object: usize,
    space: Space,
    mu: Real,
    edges: usize,
    picks: Vec<prop::sample::Index>,
}

fn grasp() -> impl Strategy<Value = Grasp> {
    (
        0..3usize,
        prop_oneof![Just(Space::Planar), Just(Space::Spatial)],
        0.1..1.0f64,
        prop_oneof![Just(4usize), Just(6), Just(8)],
        prop::collection::vec(any::<prop::sample::Index>(), 2..=4),
    )
        .prop_map(|(object, space, mu, edges, picks)| Grasp {
            object,
            space,
            mu,
            edges,
            picks,
        })
}

fn contacts(g: &Grasp) -> (&'static Object, Vec<usize>) {
    let object = &objects()[g.object];
    let n = common::candidates(object, g.space).len();
    (object, g.picks.iter().map(|i| i.index(n)).collect())
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 48, ..ProptestConfig::default() })]

    #[test]
    fn every_wrench_is_inside_its_hull(g in grasp()) {
        let (object, c) = contacts(&g);
        let p = common::problem(object, g.space, g.mu, g.edges);
        let e = p.evaluate(&c).unwrap();
        if let Some(hull) = &e.hull {
            for w in e.wrenches.chunks_exact(p.dim()) {
                prop_assert!(hull.violation(w) <= e.tolerance, "violation {}", hull.violation(w));
            }
            for f in 0..hull.facet_count() {
                let a = hull.normal(f);
                prop_assert!((a.iter().map(|x| x * x).sum::<Real>().sqrt() - 1.0).abs() < 1e-9);
            }
        }
    }

    #[test]
    fn alpha_star_by_hull_equals_alpha_star_by_lp(g in grasp()) {
        let (object, c) = contacts(&g);
        let p = common::problem(object, g.space, g.mu, g.edges);
        let e = p.evaluate(&c).unwrap();
        prop_assume!(e.force_closure());
        let ows: Vec<Real> = (0..p.ows_count()).flat_map(|k| p.ows_wrench(k).to_vec()).collect();
        let lp = quality_by_lp(&e.wrenches, &ows, p.dim()).unwrap();
        prop_assert!(
            (lp - e.quality).abs() <= 1e-6 * e.quality,
            "hull {} lp {} ({:?})", e.quality, lp, g
        );
    }

    #[test]
    fn alpha_star_is_invariant_under_rigid_motion(
        g in grasp(),
        axis in (-1.0..1.0f64, -1.0..1.0f64, -1.0..1.0f64),
        angle in -3.1..3.1f64,
        shift in (-1.0..1.0f64, -1.0..1.0f64, -1.0..1.0f64),
    ) {
        let (object, c) = contacts(&g);
        // Planar problems live in the horizontal plane: move them about z only.
        let axis = match g.space {
            Space::Planar => Vec3::z(),
            Space::Spatial => Vec3::new(axis.0, axis.1, axis.2),
        };
        prop_assume!(axis.norm() > 0.1);
        let rotation = UnitQuaternion::from_axis_angle(&nalgebra::Unit::new_normalize(axis), angle);
        let motion = Isometry3::from_parts(Vec3::new(shift.0, shift.1, shift.2).into(), rotation);
        let moved = object.transformed(&motion);
        let before = common::problem(object, g.space, g.mu, g.edges).evaluate(&c).unwrap();
        let after = common::posed_problem(&moved, rotation, g.space, g.mu, g.edges)
            .evaluate(&c)
            .unwrap();
        prop_assert_eq!(before.force_closure(), after.force_closure());
        prop_assert!(
            (before.quality - after.quality).abs() <= 1e-8 * before.quality.max(1e-12),
            "before {} after {}", before.quality, after.quality
        );
    }

    #[test]
    fn epsilon_is_positive_exactly_when_force_closure(g in grasp()) {
        let (object, c) = contacts(&g);
        let p = common::problem(object, g.space, g.mu, g.edges);
        let e = p.evaluate(&c).unwrap();
        prop_assert_eq!(e.epsilon > 0.0, e.force_closure(), "{:?} epsilon {}", e.closure, e.epsilon);
        prop_assert_eq!(e.quality > 0.0, e.force_closure());
    }
}

/// How far the polytope `{z : A z <= b}` of hull `x`'s facets reaches beyond the hyperplane
/// `a . z = b`: `max { a . z : A z <= b } - b`, by LP (clarabel); infinite when unbounded or
/// not solved.
fn reach_beyond(x: &Hull, a: &[Real], b: Real) -> Real {
    use clarabel::algebra::CscMatrix;
    use clarabel::solver::{
        DefaultSettingsBuilder, DefaultSolver, IPSolver, SolverStatus, SupportedConeT,
    };
    let (d, m) = (x.dim(), x.facet_count());
    // Column-major constraint matrix: column j holds component j of every facet normal.
    let mut colptr = vec![0];
    let mut rowval = Vec::new();
    let mut nzval = Vec::new();
    for j in 0..d {
        for f in 0..m {
            rowval.push(f);
            nzval.push(x.normal(f)[j]);
        }
        colptr.push(rowval.len());
    }
    let constraints = CscMatrix::new(m, d, colptr, rowval, nzval);
    let p = CscMatrix::new(d, d, vec![0; d + 1], Vec::new(), Vec::new());
    let q: Vec<Real> = a.iter().map(|v| -v).collect();
    let settings = DefaultSettingsBuilder::default()
        .verbose(false)
        .tol_gap_abs(1e-12)
        .tol_gap_rel(1e-12)
        .tol_feas(1e-12)
        .build()
        .unwrap();
    let cones = [SupportedConeT::NonnegativeConeT(m)];
    let Ok(mut solver) = DefaultSolver::new(&p, &q, &constraints, x.offsets(), &cones, settings)
    else {
        return Real::INFINITY;
    };
    solver.solve();
    match solver.solution.status {
        SolverStatus::Solved | SolverStatus::AlmostSolved => -solver.solution.obj_val - b,
        _ => Real::INFINITY,
    }
}

/// Two hulls of the same points are the same polytope: the same extreme vertices, and every
/// facet of each either matches a facet of the other (normal and offset within `tol`) or is
/// kept by the other's facets anyway (their polytope reaches at most `tol` beyond it, by LP).
/// The second case is near-degenerate input (two contacts a hair apart): both hulls are right
/// within their tolerances and may keep or drop a sliver facet, or split nearly coplanar
/// facets differently, whose hyperplanes then agree only to the points' distance over the
/// facet's width. A facet really missing from one hull fails the LP check.
fn same_hull(a: &Hull, b: &Hull, tol: Real) -> Result<(), String> {
    if a.vertices() != b.vertices() {
        return Err(format!(
            "vertices differ: {:?} vs {:?}",
            a.vertices(),
            b.vertices()
        ));
    }
    for (name, x, y) in [("first", a, b), ("second", b, a)] {
        for f in 0..x.facet_count() {
            let matched = (0..y.facet_count()).any(|g| {
                (x.offsets()[f] - y.offsets()[g]).abs() <= tol
                    && x.normal(f)
                        .iter()
                        .zip(y.normal(g))
                        .all(|(p, q)| (p - q).abs() <= tol)
            });
            if matched {
                continue;
            }
            let beyond = reach_beyond(y, x.normal(f), x.offsets()[f]);
            if beyond > tol {
                return Err(format!(
                    "facet {f} of the {name} hull has no match, and the other reaches {beyond:.3e} beyond it ({} vs {} facets)",
                    a.facet_count(),
                    b.facet_count()
                ));
            }
        }
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 96, ..ProptestConfig::default() })]

    /// The hull used for evaluation and Qhull give the same facets and vertices.
    #[test]
    fn hull_equals_qhull(g in grasp()) {
        let (object, c) = contacts(&g);
        let p = common::problem(object, g.space, g.mu, g.edges);
        let w: Vec<Real> = c.iter().flat_map(|&i| p.candidate_wrenches(i).to_vec()).collect();
        let fast = Hull::new(&w, p.dim());
        let reference = Hull::new_qhull(&w, p.dim());
        match (fast, reference) {
            (Ok(a), Ok(b)) => {
                let scale = w.iter().fold(0.0, |m: Real, x| m.max(x.abs()));
                if let Err(e) = same_hull(&a, &b, 1e-8 * scale.max(1.0)) {
                    return Err(TestCaseError::fail(format!("{e} ({g:?}, contacts {c:?})")));
                }
            }
            (Err(a), Err(b)) => prop_assert_eq!(a, b),
            (a, b) => return Err(TestCaseError::fail(format!("one failed: {a:?} / {b:?}"))),
        }
    }
}

#[test]
fn reach_beyond_measures_how_far_a_polytope_leaves_a_halfspace() {
    // The cube [-1, 1]^3 reaches 0.5 beyond x = 0.5, and not beyond x = 1 or x + y = 2.
    let cube: Vec<Real> = (0..8)
        .flat_map(|i| (0..3).map(move |k| if i >> k & 1 == 1 { 1.0 } else { -1.0 }))
        .collect();
    let hull = Hull::new(&cube, 3).unwrap();
    assert!((reach_beyond(&hull, &[1.0, 0.0, 0.0], 0.5) - 0.5).abs() < 1e-9);
    assert!(reach_beyond(&hull, &[1.0, 0.0, 0.0], 1.0).abs() < 1e-9);
    let s = 0.5f64.sqrt();
    assert!(reach_beyond(&hull, &[s, s, 0.0], 2.0 * s).abs() < 1e-9);
}
