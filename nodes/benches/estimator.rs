//! The estimator's step on a joint measurement (`Estimator::on_joints`, once per plant period
//! in the pipeline): the planar paper hand on its sphere against the spatial Allegro on its
//! sphere and on the ellipsoid mesh, each hand at its initial grip with every planned contact
//! made and pressed by a tracking command (the contact schedule the estimator rolls the
//! object with), the encoders read with the pipeline's noise (so the contacts roll a little
//! each step, as a still hand's do).
//!
//! `cargo bench -p icrflow-nodes --bench estimator`

#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    reason = "a test, bench or example: a panic is its failure, with the message it gives"
)]

use std::hint::black_box;
use std::path::Path;

use criterion::{Criterion, criterion_group, criterion_main};
use icrflow_interfaces::{CommandMode, HandCommand, Header, JointState, Kind};
use icrflow_nodes::estimator::Estimator;
use icrflow_nodes::noise::Noise;
use icrflow_scenario::{Config, Setup};

fn steps(c: &mut Criterion) {
    let mut group = c.benchmark_group("estimator_step");
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../config");
    for name in [
        "paper_sphere.toml",
        "allegro_sphere.toml",
        "allegro_ellipsoid.toml",
    ] {
        let config = Config::load(&dir.join(name)).unwrap();
        let setup = Setup::new(&config).unwrap();
        let (joints, touching) = setup.initial_grip(&config).unwrap();
        let roller = setup.roller(&config).unwrap();
        let mut estimator = Estimator::new(&setup.hand, roller, &setup.problem, 0.0);
        // A tracking command pressing the planned contacts (as in a run, after the first).
        let mut command = HandCommand {
            header: Header::new(Kind::HandCommand, 0, 0, 0),
            mode: CommandMode::Track as u32,
            finger_count: setup.hand.fingers.len() as u32,
            ..Default::default()
        };
        for (slot, f) in setup.hand.fingers.iter().enumerate() {
            command.finger_ids[slot] = f.id;
            if touching.contains(&f.id) {
                command.forces[slot] = [0.0, 0.0, 1.0];
            }
        }
        estimator.on_command(&command);
        let mut noise = Noise::new(1);
        let sigma = config.pipeline.joint_noise;
        let mut t = 1_000_000_000_u64;
        let hand = &setup.hand;
        let mut measure = move || {
            t += 1_000_000;
            let mut m = JointState {
                header: Header::new(Kind::JointState, t / 1_000_000, 0, 0),
                finger_count: hand.fingers.len() as u32,
                ..Default::default()
            };
            m.header.source_time_ns = t;
            for (slot, f) in hand.fingers.iter().enumerate() {
                m.finger_ids[slot] = f.id;
                m.joint_counts[slot] = f.dof() as u32;
                for (j, a) in joints[slot].iter().enumerate() {
                    m.positions[slot][j] = a + noise.gauss(sigma);
                }
            }
            m
        };
        // The contacts settle first: the timed steps are those of a hand holding the object.
        let mut made = 0;
        for _ in 0..100 {
            let m = measure();
            let g = estimator.on_joints(&m, m.header).unwrap();
            made = g.fingers.iter().filter(|c| c.in_contact == 1).count();
        }
        assert_eq!(made, touching.len(), "{name}: the planned contacts made");
        group.bench_function(name.trim_end_matches(".toml"), |b| {
            b.iter(|| {
                let m = measure();
                black_box(estimator.on_joints(&m, m.header).unwrap());
            })
        });
    }
    group.finish();
}

criterion_group!(benches, steps);
criterion_main!(benches);
