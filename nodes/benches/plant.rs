//! The plant's tick (one period of `pipeline.rate_hz`, 1 ms): MuJoCo's (`[plant] kind =
//! "mujoco"`, two 0.5 ms timesteps a tick, the servos, the feed-forward torques and the
//! contacts read back) against the kinematic plant's on the same scenario, the paper sphere
//! and the ellipsoid mesh, each holding its initial grasp with balancing forces (one command,
//! solved before the timed loop, its time stamp renewed every tick). A tick's time against the
//! period is the real-time factor: the period over it.
//!
//! `cargo bench -p icrflow-nodes --bench plant`

#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    reason = "a test, bench or example: a panic is its failure, with the message it gives"
)]

use std::hint::black_box;
use std::path::Path;

use criterion::{Criterion, criterion_group, criterion_main};
use icrflow_nodes::physical::{Physical, holding_command};
use icrflow_nodes::plant::Plant;
use icrflow_scenario::{Config, Setup};

const T0: u64 = 1_000_000_000_000;

fn load(name: &str) -> (Config, Setup) {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../config");
    let config = Config::load(&dir.join(name)).unwrap();
    let setup = Setup::new(&config).unwrap();
    (config, setup)
}

fn ticks(c: &mut Criterion) {
    let mut group = c.benchmark_group("plant_tick");
    for name in ["paper_sphere_mujoco.toml", "ellipsoid_mujoco.toml"] {
        let (config, setup) = load(name);
        let contacts = setup.scenario(&config).start().unwrap().0;
        let period = (1e9 / config.pipeline.rate_hz) as u64;
        let joints = setup.initial_grip(&config).unwrap().0;
        let mut plant = Physical::new(&config, &setup, &joints, T0).unwrap();
        let mut t = T0;
        // Settle the grasp first: the timed ticks are those of a hand holding the object.
        for _ in 0..200 {
            t += period;
            let cmd = holding_command(&config, &setup, &contacts, t).unwrap();
            plant.tick(t, Some(&cmd));
        }
        let mut cmd = holding_command(&config, &setup, &contacts, t).unwrap();
        let stem = name.trim_end_matches(".toml");
        group.bench_function(stem, |b| {
            b.iter(|| {
                t += period;
                cmd.header.source_time_ns = t;
                black_box(plant.tick(t, Some(&cmd)));
            })
        });
        // The same scenario on the kinematic plant.
        let (joints, touching) = setup.initial_grip(&config).unwrap();
        let roller = setup.roller(&config).unwrap();
        let mut plant = Plant::new(
            &setup.hand,
            roller,
            (joints, &touching),
            &config.pipeline,
            T0,
        );
        let mut t = T0;
        let stem = format!("{}_kinematic", stem.trim_end_matches("_mujoco"));
        group.bench_function(&stem, |b| {
            b.iter(|| {
                t += period;
                cmd.header.source_time_ns = t;
                black_box(plant.tick(t, Some(&cmd)));
            })
        });
    }
    group.finish();
}

criterion_group!(benches, ticks);
criterion_main!(benches);
