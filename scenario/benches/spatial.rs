//! The spatial planner against the planar one, in the same run: one rolling step and the ICRs
//! of the starting grasp, and the whole plan, on the paper's scenario (planar hand, 72
//! section candidates) and the Allegro configs (spatial hand, 2,048 facet candidates). Before
//! the measurements it prints each plan's steps, switches, and the ICRs' mean size.
//!
//! `cargo bench -p icrflow-scenario --bench spatial`

#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    reason = "a test, bench or example: a panic is its failure, with the message it gives"
)]

use std::hint::black_box;
use std::path::Path;

use criterion::{Criterion, criterion_group, criterion_main};
use icrflow_scenario::{Config, Setup};

fn load(name: &str) -> (Config, Setup) {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../config")
        .join(name);
    let config = Config::load(&path).unwrap();
    let setup = Setup::new(&config).unwrap();
    (config, setup)
}

fn bench(c: &mut Criterion) {
    for name in [
        "paper_sphere.toml",
        "allegro_sphere.toml",
        "allegro_ellipsoid_exact.toml",
    ] {
        let (config, setup) = load(name);
        let alpha = config.grasp.alpha;
        let stem = name.trim_end_matches(".toml");
        // The plan and the ICRs of every grasp in it.
        let plan = match setup.spatial_scenario(&config) {
            Some(s) => s.plan(&mut |_| {}).unwrap(),
            None => setup.scenario(&config).plan(&mut |_| {}).unwrap(),
        };
        let mut members = 0usize;
        let mut regions = 0usize;
        for step in &plan.steps {
            let idx: Vec<usize> = step.fingers.iter().filter_map(|f| f.contact).collect();
            let e = setup.problem.evaluate(&idx).unwrap();
            if let Ok(r) = setup.problem.icrs(&idx, &e, alpha) {
                regions += r.len();
                members += r.iter().map(|r| r.members.len()).sum::<usize>();
            }
        }
        eprintln!(
            "{stem}: {} candidates, {} steps ({} rolling), {} switches, completed {}, ICRs {:.1} candidates each on average",
            setup.problem.candidates().points.len(),
            plan.summary.steps,
            plan.summary.rolling_steps,
            plan.summary.switches,
            plan.summary.completed,
            members as f64 / regions.max(1) as f64
        );
        let start: Vec<usize> = plan.steps[0]
            .fingers
            .iter()
            .filter_map(|f| f.contact)
            .collect();
        let e = setup.problem.evaluate(&start).unwrap();
        c.bench_function(&format!("icrs_at_start/{stem}"), |b| {
            b.iter(|| black_box(setup.problem.icrs(black_box(&start), &e, alpha).unwrap()))
        });
        match setup.spatial_scenario(&config) {
            Some(s) => {
                let (touches, _) = s.start().unwrap();
                c.bench_function(&format!("rolling_step/{stem}"), |b| {
                    b.iter(|| black_box(s.roll(black_box(&touches), 0.0, s.settings.step).unwrap()))
                });
                let mut g = c.benchmark_group("plan");
                g.sample_size(10);
                g.bench_function(stem, |b| b.iter(|| black_box(s.plan(&mut |_| {}).unwrap())));
                g.finish();
            }
            None => {
                let s = setup.scenario(&config);
                let (contacts, _) = s.start().unwrap();
                c.bench_function(&format!("rolling_step/{stem}"), |b| {
                    b.iter(|| {
                        black_box(s.roll(black_box(&contacts), 0.0, s.settings.step).unwrap())
                    })
                });
                let mut g = c.benchmark_group("plan");
                g.sample_size(10);
                g.bench_function(stem, |b| b.iter(|| black_box(s.plan(&mut |_| {}).unwrap())));
                g.finish();
            }
        }
    }
}

criterion_group!(benches, bench);
criterion_main!(benches);
