//! Benchmarks of the grasp analysis (BENCHMARKS.md has the figures and the commands).
//!
//! With `ICRFLOW_BENCH_CASES=PATH` set, the cases are also written to PATH in the input
//! format of `bench/reference_qhull.py`, so `bench/compare.sh` can time the Python/Qhull
//! reference on identical data in the same run.

#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    reason = "a test, bench or example: a panic is its failure, with the message it gives"
)]

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use icrflow_grasp::math::{Real, Vec3};
use icrflow_grasp::object::{Object, SurfaceSamples};
use icrflow_grasp::quality::{Evaluation, EvaluationScratch, GraspProblem};
use icrflow_grasp::wrench::{ContactModel, Space, WrenchFrame};
use reference::{Case, cases_json};

#[path = "../tests/common/reference.rs"]
mod reference;

const MU: Real = 0.5;
const EDGES: usize = 8;

fn candidates(object: &Object, space: Space) -> &SurfaceSamples {
    match space {
        Space::Planar => &object.section.samples,
        Space::Spatial => &object.facets,
    }
}

fn problem(object: &Object, space: Space) -> GraspProblem {
    let frame = WrenchFrame::new(object.centre_of_mass, object.max_radius(), space).unwrap();
    let model = ContactModel::new(MU, EDGES).unwrap();
    let c = candidates(object, space).clone();
    GraspProblem::new(&object.facets, c, frame, model).unwrap()
}

/// Three contacts near the directions at 0, 120 and 240 degrees about z, tilted by `tilt`
/// out of the plane (a well-spread, force-closure grasp), snapped to candidates.
fn spread_contacts(object: &Object, space: Space, tilt: Real) -> Vec<usize> {
    let c = candidates(object, space);
    (0..3)
        .map(|k| {
            let t = std::f64::consts::TAU * k as Real / 3.0 + 0.1;
            let z = if k == 1 { -tilt } else { tilt };
            let dir = Vec3::new(t.cos(), t.sin(), z) * object.max_radius() * 2.0;
            c.nearest(&(object.centre_of_mass + dir)).unwrap().0
        })
        .collect()
}

struct Bench {
    id: &'static str,
    object: Object,
    space: Space,
    contacts: Vec<usize>,
}

fn ellipsoid(lon: usize, lat: usize) -> Object {
    Object::ellipsoid(Vec3::new(0.06, 0.045, 0.035), lon, lat).unwrap()
}

fn ellipsoid_mesh_5k() -> Object {
    // A triangulated 50 x 50 UV ellipsoid read back from binary STL: 4,900 facets.
    let path = std::env::temp_dir().join(format!("icrflow-bench-{}.stl", std::process::id()));
    ellipsoid(50, 50).write_stl(&path).unwrap();
    let object = Object::from_file(&path).unwrap();
    let _ = std::fs::remove_file(&path);
    object
}

fn benches() -> Vec<Bench> {
    let sphere = Object::sphere(0.0475, 72, 72).unwrap();
    let mesh = ellipsoid_mesh_5k();
    let mut out = vec![
        Bench {
            id: "alpha6d-sphere72x72",
            contacts: spread_contacts(&sphere, Space::Spatial, 0.3),
            object: sphere.clone(),
            space: Space::Spatial,
        },
        Bench {
            id: "alpha6d-ellipsoid5k",
            contacts: spread_contacts(&mesh, Space::Spatial, 0.3),
            object: mesh,
            space: Space::Spatial,
        },
        Bench {
            id: "alphaplanar-sphere72x72",
            // The paper's contacts: 30, -30 and 140 degrees on the equator ring.
            contacts: vec![6, 66, 28],
            object: sphere,
            space: Space::Planar,
        },
    ];
    for (id, lon, lat) in [
        ("ows1k", 32, 32),
        ("ows10k", 100, 100),
        ("ows100k", 317, 316),
    ] {
        let object = ellipsoid(lon, lat);
        out.push(Bench {
            id,
            contacts: spread_contacts(&object, Space::Spatial, 0.3),
            object,
            space: Space::Spatial,
        });
    }
    out
}

fn quality(c: &mut Criterion) {
    let benches = benches();
    if let Ok(path) = std::env::var("ICRFLOW_BENCH_CASES") {
        let cases: Vec<Case<'_>> = benches
            .iter()
            .map(|b| {
                let p = problem(&b.object, b.space);
                let e = p.evaluate(&b.contacts).unwrap();
                Case {
                    id: b.id.to_string(),
                    object: &b.object,
                    candidates: candidates(&b.object, b.space),
                    space: b.space,
                    model: ContactModel::new(MU, EDGES).unwrap(),
                    rho: b.object.max_radius(),
                    alpha: 0.5 * e.quality,
                    contacts: b.contacts.clone(),
                }
            })
            .collect();
        std::fs::write(&path, cases_json(&cases)).unwrap();
    }
    let mut group = c.benchmark_group("grasp");
    for b in &benches {
        let p = problem(&b.object, b.space);
        let e = p.evaluate(&b.contacts).unwrap();
        assert!(
            e.force_closure(),
            "{}: bench grasp is not force closure",
            b.id
        );
        let hull = e.hull.clone().unwrap();
        eprintln!(
            "{}: {} OWS points, {} candidates, {} hull facets, alpha* = {:.5}",
            b.id,
            p.ows_count(),
            p.candidates().len(),
            hull.facet_count(),
            e.quality
        );
        group.bench_function(format!("{}/alpha_star", b.id), |bench| {
            bench.iter(|| black_box(p.evaluate(black_box(&b.contacts)).unwrap().quality))
        });
        // The same in buffers kept between evaluations, as the wrench-space node evaluates.
        let (mut kept, mut scratch) = (Evaluation::default(), EvaluationScratch::default());
        group.bench_function(format!("{}/alpha_star_kept", b.id), |bench| {
            bench.iter(|| {
                p.evaluate_in(black_box(&b.contacts), &mut kept, &mut scratch)
                    .unwrap();
                black_box(kept.quality)
            })
        });
        if !b.id.starts_with("ows") {
            let alpha = 0.5 * e.quality;
            group.bench_function(format!("{}/icrs_query", b.id), |bench| {
                bench.iter(|| {
                    let e = p.evaluate(black_box(&b.contacts)).unwrap();
                    black_box(p.icrs(&b.contacts, &e, alpha).unwrap())
                })
            });
            group.bench_function(format!("{}/icrs_only", b.id), |bench| {
                bench.iter(|| black_box(p.icrs(black_box(&b.contacts), &e, alpha).unwrap()))
            });
            group.bench_function(format!("{}/hull_qhull", b.id), |bench| {
                bench.iter(|| {
                    black_box(
                        icrflow_grasp::hull::Hull::new_qhull(black_box(&e.wrenches), p.dim())
                            .unwrap(),
                    )
                })
            });
            if p.dim() == 6 {
                assert!(
                    icrflow_grasp::hull::three_contacts::hull(&e.wrenches, EDGES).is_ok(),
                    "{}: the facet enumeration declined the bench grasp",
                    b.id
                );
            }
            group.bench_function(format!("{}/hull_contacts", b.id), |bench| {
                bench.iter(|| {
                    black_box(
                        icrflow_grasp::hull::Hull::of_contacts(
                            black_box(&e.wrenches),
                            p.dim(),
                            EDGES,
                        )
                        .unwrap(),
                    )
                })
            });
            group.bench_function(format!("{}/hull_only", b.id), |bench| {
                bench.iter(|| {
                    black_box(
                        icrflow_grasp::hull::Hull::new(black_box(&e.wrenches), p.dim()).unwrap(),
                    )
                })
            });
        }
        let mut out = vec![0.0; hull.facet_count()];
        group.bench_function(format!("{}/support_only", b.id), |bench| {
            bench.iter(|| p.support_function(black_box(hull.normals()), black_box(&mut out)))
        });
        group.bench_function(format!("{}/support_dense", b.id), |bench| {
            bench.iter(|| p.support_function_dense(black_box(hull.normals()), black_box(&mut out)))
        });
    }
    group.finish();
}

criterion_group!(benches_group, quality);
criterion_main!(benches_group);
