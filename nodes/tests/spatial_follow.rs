//! Following a spatial plan on the kinematic plant: the Allegro led through every target of
//! its plan of the sphere ([`icrflow_plan::spatial::follow::targets`]: rolling sub-targets put
//! back on the surface, the switches' approach and retreat way points), each commanded until
//! the plant's joints reach it, the fingers in contact pressing.

#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    reason = "a test, bench or example: a panic is its failure, with the message it gives"
)]

use icrflow_interfaces::{CommandMode, HandCommand, Header, Kind, MAX_JOINTS};
use icrflow_nodes::plant::{Event, Plant};
use icrflow_plan::planner::Phase;
use icrflow_scenario::{Config, Setup};

fn allegro_sphere() -> (Config, Setup) {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../config");
    let mut config = Config::load(&dir.join("allegro_sphere.toml")).unwrap();
    config.pipeline.joint_noise = 0.0;
    let setup = Setup::new(&config).unwrap();
    (config, setup)
}

/// The whole turn: the object turns as the plan has it at every step (the rolling's integral
/// along the commanded joint lines, within 0.2 degrees of the plan's rotation; at a rolling
/// step's sub-targets, whose rotations are interpolated, within the follower's lead), the
/// fingertips in contact stay within 0.1 mm of the surface all along (the straight joint
/// lines between the plan's 5 degree steps leave them up to 0.6 mm off), no fingertip or link
/// enters the object, and the fingers the plant has in contact are the plan's at every
/// target reached.
#[test]
fn the_allegro_follows_its_spatial_targets_a_whole_turn_on_the_kinematic_plant() {
    let (config, setup) = allegro_sphere();
    let scenario = setup.spatial_scenario(&config).unwrap();
    let plan = scenario.plan(&mut |_| {}).unwrap();
    assert!(plan.summary.completed && plan.summary.switches >= 3);
    let targets = icrflow_plan::spatial::follow::targets(&plan.steps, &scenario);
    assert!(targets.len() > 5 * plan.steps.len(), "{}", targets.len());
    assert!(targets.iter().any(|t| t.way_point));
    let roller = setup.roller(&config).unwrap();
    let (joints, touching) = setup.initial_grip(&config).unwrap();
    let t0 = 1_000_000_000_000;
    let mut plant = Plant::new(
        &setup.hand,
        roller,
        (joints, &touching),
        &config.pipeline,
        t0,
    );
    let dt = (1e9 / config.pipeline.rate_hz) as u64;
    let mut now = t0;
    let (mut worst_gap, mut worst_turn, mut worst_passing) = (0.0_f64, 0.0_f64, 0.0_f64);
    for (k, target) in targets.iter().enumerate() {
        let step = &target.step;
        let mut c = HandCommand {
            header: Header::new(Kind::HandCommand, k as u64 + 1, 0, 0),
            mode: CommandMode::Track as u32,
            finger_count: step.fingers.len() as u32,
            ..Default::default()
        };
        for (slot, f) in step.fingers.iter().enumerate() {
            c.finger_ids[slot] = f.finger;
            c.joint_targets[slot][..f.joints.len().min(MAX_JOINTS)].copy_from_slice(&f.joints);
            if f.contact.is_some() {
                c.forces[slot] = [0.0, 0.0, 1.0];
            }
        }
        let arrived = |plant: &Plant<'_>| {
            step.fingers
                .iter()
                .zip(plant.joints())
                .all(|(f, q)| f.joints == *q)
        };
        for _ in 0..5000 {
            now += dt;
            c.header.source_time_ns = now;
            plant.tick(now, Some(&c));
            for e in plant.events() {
                assert!(
                    matches!(e, Event::Contact { .. }),
                    "target {k} (step {} {:?}): {e}",
                    step.step,
                    step.phase
                );
            }
            for (slot, f) in setup.hand.fingers.iter().enumerate() {
                if plant.contacts()[slot] {
                    let gap = roller.gap(f, &plant.joints()[slot], plant.rotation());
                    worst_gap = worst_gap.max(gap.abs());
                }
            }
            if arrived(&plant) {
                break;
            }
        }
        assert!(arrived(&plant), "target {k} not reached");
        // Two more ticks: an arriving finger comes into contact as its motion ends.
        for _ in 0..2 {
            now += dt;
            c.header.source_time_ns = now;
            plant.tick(now, Some(&c));
        }
        for (slot, f) in step.fingers.iter().enumerate() {
            assert_eq!(
                plant.contacts()[slot],
                f.contact.is_some(),
                "target {k} (step {} {:?}): finger {}",
                step.step,
                step.phase,
                f.finger
            );
        }
        if step.phase == Phase::Rolling {
            let off = (plant.rotation() - step.rotation).abs();
            if target.passing {
                // A sub-target's rotation is interpolated; it is passed within LEAD.
                worst_passing = worst_passing.max(off);
            } else {
                worst_turn = worst_turn.max(off);
            }
        }
    }
    assert!(
        worst_gap < 0.1e-3,
        "a fingertip in contact {} mm off the surface",
        worst_gap * 1e3
    );
    assert!(
        worst_turn < 0.2f64.to_radians(),
        "the object {} deg off the plan",
        worst_turn.to_degrees()
    );
    assert!(
        worst_passing < icrflow_plan::follow::LEAD,
        "a sub-target {} deg off the object",
        worst_passing.to_degrees()
    );
    let goal = plan.steps.last().unwrap().rotation;
    assert!((plant.rotation() - goal).abs() < 0.2f64.to_radians());
}
