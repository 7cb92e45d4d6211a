//! Planner benchmarks: one rolling step of the paper scenario and the whole 360-degree plan,
//! on the paper's 72 x 72 sphere and on refinements of it.
//!
//! `cargo bench -p icrflow-plan --bench plan`

#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    reason = "a test, bench or example: a panic is its failure, with the message it gives"
)]

use std::f64::consts::PI;
use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use icrflow_grasp::object::Object;
use icrflow_grasp::quality::GraspProblem;
use icrflow_grasp::wrench::{ContactModel, Space, WrenchFrame};
use icrflow_plan::hand::Hand;
use icrflow_plan::paper;
use icrflow_plan::planner::{Roll, Scenario, Settings, Start};

struct Setup {
    object: Object,
    problem: GraspProblem,
    hand: Hand,
}

fn setup(segments: usize) -> Setup {
    let object = Object::sphere(paper::OBJECT_RADIUS, segments, segments).unwrap();
    let frame =
        WrenchFrame::new(object.centre_of_mass, object.max_radius(), Space::Planar).unwrap();
    let problem = GraspProblem::new(
        &object.facets,
        object.section.samples.clone(),
        frame,
        ContactModel::new(0.3, 8).unwrap(),
    )
    .unwrap();
    Setup {
        object,
        problem,
        hand: paper::hand(),
    }
}

fn scenario(s: &Setup) -> Scenario<'_> {
    let at = |deg: f64| s.object.section.nearest_angle(deg.to_radians()).unwrap().0;
    Scenario {
        problem: &s.problem,
        hand: &s.hand,
        centre: s.object.centre_of_mass,
        angles: Some(&s.object.section.angles),
        initial: vec![
            (1, at(30.0), None),
            (2, at(-30.0), None),
            (4, at(140.0), None),
        ],
        start: Start::default(),
        settings: Settings {
            alpha: 0.1,
            gate_alpha: 0.1,
            goal: 2.0 * PI,
            step: 5f64.to_radians(),
            cap_margin: 5f64.to_radians(),
            min_manipulability: 1e-4,
            squeeze_reserve: 2e-3,
            region_erosion: 0,
            neighbour_alpha: None,
            neighbour_rings: 1,
            max_steps: 10_000,
            max_plan: None,
            attach_resolution: 2f64.to_radians(),
        },
    }
}

fn bench(c: &mut Criterion) {
    for segments in [72, 144, 288] {
        let s = setup(segments);
        let sc = scenario(&s);
        let name = format!("sphere{segments}x{segments}");
        let plan = sc.plan(&mut |_| {}).unwrap();
        eprintln!(
            "{name}: {} steps ({} rolling), {} switches, completed {}",
            plan.summary.steps,
            plan.summary.rolling_steps,
            plan.summary.switches,
            plan.summary.completed
        );
        let (contacts, _) = sc.start().unwrap();
        assert!(matches!(
            sc.roll(&contacts, 0.0, sc.settings.step).unwrap(),
            Roll::Moved(..)
        ));
        c.bench_function(&format!("rolling_step/{name}"), |b| {
            b.iter(|| {
                black_box(
                    sc.roll(black_box(&contacts), 0.0, sc.settings.step)
                        .unwrap(),
                )
            })
        });
        let mut g = c.benchmark_group("plan360");
        g.sample_size(10);
        g.bench_function(&name, |b| {
            b.iter(|| black_box(sc.plan(&mut |_| {}).unwrap()))
        });
        g.finish();
    }
}

criterion_group!(benches, bench);
criterion_main!(benches);
