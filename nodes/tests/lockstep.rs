//! The loop in lockstep on MuJoCo ([`icrflow_nodes::lockstep`]): the nodes' own steps on
//! simulated time, no processes. The paper's sphere turned toward 45 degrees; both MuJoCo
//! scenarios pushed at ten times of their whole turn; the ellipsoid with re-plans that take time;
//! the Allegro sphere through re-plans, its pinch kept; the Allegro sphere and the ellipsoid on
//! ten noise seeds each never used to tune them.

#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    reason = "a test, bench or example: a panic is its failure, with the message it gives"
)]

use icrflow_interfaces::{CommandMode, PlanPhase};
use icrflow_nodes::lockstep;
use icrflow_nodes::lockstep::truth::TruthWatch;
use icrflow_nodes::plant::Event;
use icrflow_scenario::{Config, Push, Setup};

/// `config/NAME`.
fn load(name: &str) -> Config {
    let dir = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../config");
    Config::load(&dir.join(name)).unwrap()
}

/// `config/paper_sphere_mujoco.toml` with the goal at `goal_deg`.
fn paper(goal_deg: f64) -> (Config, Setup) {
    let mut config = load("paper_sphere_mujoco.toml");
    config.plan.goal = goal_deg.to_radians();
    let setup = Setup::new(&config).unwrap();
    (config, setup)
}

/// What a run showed: the largest gap between the estimated and the true rotation (rad), the
/// largest distance of the object's centre from its start and that distance at the end (m),
/// the fewest fingertips touching the object once the hand had closed, and how it ended.
fn run(config: &Config, setup: &Setup, seconds: f64) -> (f64, [f64; 2], usize, lockstep::Ended) {
    let (mut gap, mut drift, mut fewest) = (0.0_f64, [0.0_f64; 2], usize::MAX);
    let mut start = None;
    let ended = lockstep::run(config, setup, seconds, 0.5, 0.0, &mut |tick| {
        let Some(truth) = tick.truth else { return };
        if let Some(g) = tick.grasp {
            gap = gap.max((g.rotation - truth.rotation).abs());
        }
        let c = tick.plant.sim().object_centre();
        let s = *start.get_or_insert(c);
        drift = [drift[0].max((c - s).norm()), (c - s).norm()];
        if tick.time > 0.1 {
            let n = truth.finger_count as usize;
            fewest = fewest.min(truth.in_contact[..n].iter().filter(|&&x| x == 1).count());
        }
    })
    .unwrap();
    (gap, drift, fewest, ended)
}

/// The fingertips roll the sphere in MuJoCo through a finger switch: the object turns most of
/// the way (the follower waits for the last degrees, which the physics' lag leaves), the
/// estimate stays on MuJoCo's truth, the hand keeps the object's centre where the plan has it
/// (the command node's centring), at least two fingertips always hold it; and the same config
/// runs the same again.
#[test]
fn the_paper_sphere_turns_in_lockstep_as_the_estimate_says() {
    let (config, setup) = paper(45.0);
    let (gap, drift, fewest, ended) = run(&config, &setup, 15.0);
    assert!(ended.rotation.to_degrees() > 40.0, "{ended:?}");
    assert!(ended.rotation.to_degrees() < 47.0, "{ended:?}");
    assert!(
        gap.to_degrees() < 1.5,
        "estimate off by {} deg",
        gap.to_degrees()
    );
    // Pushed about by a millimetre or two while fingers attach and release, the centre is
    // brought back (without the centring it ends 1.5 mm off).
    assert!(drift[0] < 3e-3, "the centre moved {} m", drift[0]);
    assert!(drift[1] < 0.3e-3, "the centre ended {} m off", drift[1]);
    assert!(fewest >= 2, "{fewest} fingertips touching");
    let (_, _, _, again) = run(&config, &setup, 15.0);
    assert_eq!(ended, again);
}

/// A config whose plant is not MuJoCo is refused by name.
#[test]
fn a_lockstep_run_needs_the_mujoco_plant() {
    let (mut config, setup) = paper(45.0);
    config.plant.kind = icrflow_scenario::PlantKind::Kinematic;
    let e = lockstep::run(&config, &setup, 1.0, 0.0, 0.0, &mut |_| {})
        .unwrap_err()
        .to_string();
    assert!(e.contains("plant.kind = \"mujoco\""), "{e}");
}

/// How a pushed run went: the plan phase when the push began (`None` if it never did, `Some(None)`
/// before any plan step), the largest distance of the object's centre from its start (m), and
/// how the run ended.
fn pushed(config: &Config, setup: &Setup) -> (Option<Option<u32>>, f64, lockstep::Ended) {
    let (mut phase, mut drift, mut start) = (None, 0.0_f64, None);
    let ended = lockstep::run(config, setup, 60.0, 0.5, 0.0, &mut |tick| {
        if tick
            .plant
            .events()
            .iter()
            .any(|e| matches!(e, Event::Pushed { .. }))
        {
            phase = Some(tick.plan.map(|p| p.phase));
        }
        let c = tick.plant.sim().object_centre();
        drift = drift.max((c - *start.get_or_insert(c)).norm());
    })
    .unwrap();
    (phase, drift, ended)
}

/// Ten runs of `name`, each with a twist of the object (0.05 N m about the vertical for 50
/// ms: an angular impulse that would spin the free sphere at 12 rad/s; held, it turns about a
/// degree under the fingertips) at another time of the whole turn, while it rolls and while a
/// finger attaches or lets go: each run ends at the goal (MuJoCo's rotation within 2 % of 360
/// degrees), the object in the hand. What it took (re-plans) is printed. (Twice as hard a
/// twist the sphere's grasp survived in 6 of 10 runs: issue 21's note.)
fn every_push_is_recovered(name: &str) {
    let config = load(name);
    let setup = Setup::new(&config).unwrap();
    let mut phases = Vec::new();
    for at in [1.0, 2.5, 4.0, 5.5, 7.0, 8.5, 10.0, 11.5, 13.0, 14.5] {
        let mut config = config.clone();
        config.pipeline.push = Some(Push {
            force: [0.0; 3],
            torque: [0.0, 0.0, 0.05],
            at,
            duration: 0.05,
        });
        let (phase, drift, ended) = pushed(&config, &setup);
        println!(
            "{name}: pushed at {at} s (phase {phase:?}): {:.1} deg after {:.1} s, {} re-plans, centre at most {:.1} mm off",
            ended.rotation.to_degrees(),
            ended.time,
            ended.replans,
            drift * 1e3
        );
        let phase = phase
            .unwrap_or_else(|| panic!("no push at {at} s: {ended:?}"))
            .unwrap_or_else(|| panic!("pushed at {at} s before any plan step"));
        phases.push(phase);
        assert!(ended.done, "pushed at {at} s: {ended:?}");
        assert!(
            (ended.rotation.to_degrees() - 360.0).abs() <= 7.2,
            "pushed at {at} s: {ended:?}"
        );
        assert!(
            drift < 0.5 * setup.object.max_radius(),
            "dropped: {drift} m"
        );
    }
    let rolling = PlanPhase::Rolling as u32;
    assert!(phases.contains(&rolling), "{phases:?}");
    assert!(phases.iter().any(|&p| p != rolling), "{phases:?}");
}

#[test]
fn every_push_of_the_sphere_is_recovered() {
    every_push_is_recovered("paper_sphere_mujoco.toml");
}

#[test]
fn every_push_of_the_ellipsoid_under_gravity_is_recovered() {
    every_push_is_recovered("ellipsoid_mujoco.toml");
}

/// The ellipsoid's whole turn under gravity with re-plans that take 1.3 s of simulated time
/// (the planner node's 1.2 to 1.6 s on the mesh on this project's 2-core machines: its last
/// step goes stale and the hand holds meanwhile), under three seeds of the measurement noise
/// looked at while fixing it and ten never used to tune anything (31-40, 2026-12-05): each run
/// reaches the goal, the object in the hand, no contact lost while planned (as `run` counts a
/// loss), no fingers touching, no link on the object, tilted less than 3 deg (the pipeline
/// test's bound). With seed 2 a plan made again from the
/// estimate once had an attach whose contact pose pressed 0.27 mm into the mesh; the follower
/// found no stand-off for it, moved the finger straight onto the object, and the strike knocked
/// the ellipsoid 20 deg on and 14 mm off its place, short of the goal for good (as the real
/// pipeline did in about half its runs of 2026-12-03).
#[test]
fn the_ellipsoid_turns_a_whole_turn_with_re_plans_that_take_time() {
    let config = load("ellipsoid_mujoco.toml");
    let setup = Setup::new(&config).unwrap();
    for seed in [1, 2, 3].into_iter().chain(31..=40) {
        let mut config = config.clone();
        config.pipeline.seed = seed;
        let mut drift = 0.0_f64;
        let mut start = None;
        let mut watch = TruthWatch::new(&config);
        let ended = lockstep::run(&config, &setup, 40.0, 0.5, 1.3, &mut |tick| {
            let c = tick.plant.sim().object_centre();
            drift = drift.max((c - *start.get_or_insert(c)).norm());
            watch.observe(tick);
        })
        .unwrap();
        println!(
            "seed {seed}: {:.1} deg after {:.1} s, {} re-plans, {} holds, centre at most {:.1} mm off, {} contacts lost, tilt at most {:.2} deg: {:?}",
            ended.rotation.to_degrees(),
            ended.time,
            ended.replans,
            ended.holds,
            drift * 1e3,
            watch.losses.len(),
            watch.max_tilt.0,
            ended.replanned
        );
        assert!(watch.losses.is_empty(), "seed {seed}: {:?}", watch.losses);
        assert!(
            watch.integrated > 10_000,
            "seed {seed}: {}",
            watch.integrated
        );
        assert_eq!(
            (watch.fingers_touching, watch.links_on_object),
            (0, 0),
            "seed {seed}"
        );
        assert!(watch.max_tilt.0 < 3.0, "seed {seed}: {:?}", watch.max_tilt);
        assert!(ended.done, "seed {seed}: {ended:?}");
        assert!(ended.replans >= 1, "seed {seed}: {ended:?}");
        assert!(
            (ended.rotation.to_degrees() - 360.0).abs() <= 0.02 * 360.0,
            "seed {seed}: {ended:?}"
        );
        assert!(drift < 5e-3, "seed {seed}: the centre {drift} m off");
        assert!(
            ended
                .replanned
                .iter()
                .all(|(_, r)| !r.contains("no stand-off")),
            "seed {seed}: {:?}",
            ended.replanned
        );
        // Each re-plan names each of its switches: which finger takes over from which, and why.
        for (_, r) in &ended.replanned {
            let Some(switches) = r
                .split(" switches")
                .next()
                .and_then(|s| s.rsplit(' ').next())
                .and_then(|n| n.parse::<usize>().ok())
            else {
                continue;
            };
            assert_eq!(
                r.matches(" deg finger ").count(),
                switches,
                "seed {seed}: {r}"
            );
        }
    }
}

/// The Allegro sphere in lockstep under noise seed `seed`, plans made again taking 1.2 s of
/// simulated time (as the planner node's on a 2-core machine), watched against the truth;
/// asserted to have turned the sphere a whole turn (within 2 %) through MuJoCo's integration.
fn allegro_sphere(seed: u64) -> (lockstep::Ended, TruthWatch) {
    let mut config = load("allegro_sphere_mujoco.toml");
    config.pipeline.seed = seed;
    let setup = Setup::new(&config).unwrap();
    let mut watch = TruthWatch::new(&config);
    let ended = lockstep::run(&config, &setup, 60.0, 0.5, 1.2, &mut |tick| {
        watch.observe(tick)
    })
    .unwrap();
    assert!(ended.done, "seed {seed}: {ended:?}");
    assert!(
        (ended.rotation.to_degrees() - 360.0).abs() <= 0.02 * 360.0,
        "seed {seed}: {ended:?}"
    );
    assert!(
        watch.integrated > 10_000,
        "seed {seed}: {}",
        watch.integrated
    );
    (ended, watch)
}

/// The Allegro's index and ring pinch the sphere at the poles of its axis all the way round:
/// plans made again from the estimate (each taking 1.2 s of simulated time, as the planner
/// node's do on a 2-core machine) release only the thumb and the middle finger, also where the
/// thumb rolls up to the index (the finger that rolls into the other leaves), the fingers never
/// touch each other in MuJoCo, and the sphere turns a whole turn. Seed 12 of the measurement
/// noise has the thumb roll up to the index after a re-plan; releasing the index there instead
/// (the first of the two in the grasp's order, as the planner did until 2026-12-05) left
/// middle, ring and thumb to hold the sphere along its axis by friction alone, and the
/// pipeline dropped it in 3 of 8 runs under load. In seed 25 the thumb rolled to within 24.0x mm
/// of the index (24.00 needed) before the switch released it, and MuJoCo had the two touching
/// for 359 integration steps while the middle finger attached, before the planner kept
/// [`icrflow_plan::route::FINGER_GAP`] between fingers. Since the estimator rolls the object
/// with the fingers pressed only (2026-12-06), seed 25's thumb no longer rolls up to the index (no clash
/// to decide) and seed 14's does: of seeds 12-22 and 25, 12, 14, 15, 20 and 22 decide a clash,
/// none has fingers touching. Each seed here is run, none may have fingers touching, and two
/// of the three must decide a clash.
#[test]
fn the_allegro_keeps_its_pinch_through_plans_made_again() {
    let mut decided = Vec::new();
    for seed in [12, 14, 25] {
        let (ended, watch) = allegro_sphere(seed);
        let (integrated, touching) = (watch.integrated, watch.fingers_touching);
        let switches: Vec<&str> = ended
            .replanned
            .iter()
            .flat_map(|(_, r)| r.split("; at ").skip(1))
            .collect();
        println!(
            "seed {seed}: {:.1} deg after {:.1} s, {} re-plans, {touching} of {integrated} integration steps with fingers touching; their switches: {switches:#?}",
            ended.rotation.to_degrees(),
            ended.time,
            ended.replans
        );
        assert_eq!(touching, 0, "seed {seed}: fingers touching: {switches:#?}");
        if switches.iter().any(|s| s.contains("would touch")) {
            decided.push(seed);
        }
        for s in &switches {
            assert!(
                !s.contains("finger 1 leaves") && !s.contains("finger 3 leaves"),
                "seed {seed}: {s}"
            );
        }
    }
    assert!(
        decided.len() >= 2,
        "a clash decided in seeds {decided:?} only"
    );
}

/// Noise seeds never used to tune the Allegro sphere's config, the planner or the nodes (61-70;
/// 2026-12-05): plans made again taking 1.2 s of simulated time, each seed turns the sphere a
/// whole turn (within 2 %), loses no contact while planned (as `run` counts a loss), has no
/// fingers touching each other and no link on the object at any integration step, and tilts
/// the sphere less than 1.5 deg off the plan's axis (the pipeline test's bound). Each seed's
/// figures are printed.
#[test]
fn the_allegro_turns_the_sphere_on_held_out_seeds() {
    for seed in 61..=70 {
        let (ended, watch) = allegro_sphere(seed);
        let w = watch.worst_estimate;
        println!(
            "seed {seed}: {:.1} deg after {:.1} s, {} re-plans, {} contacts lost, {} of {} integration steps with fingers touching, {} with a link on the object, tilt at most {:.2} deg; the estimate at most {:.2} deg off the truth ({} at {:.2} s)",
            ended.rotation.to_degrees(),
            ended.time,
            ended.replans,
            watch.losses.len(),
            watch.fingers_touching,
            watch.integrated,
            watch.links_on_object,
            watch.max_tilt.0,
            w.deg,
            w.phase,
            w.time
        );
        assert!(watch.losses.is_empty(), "seed {seed}: {:?}", watch.losses);
        assert_eq!(watch.fingers_touching, 0, "seed {seed}");
        assert_eq!(watch.links_on_object, 0, "seed {seed}");
        assert!(watch.max_tilt.0 < 1.5, "seed {seed}: {:?}", watch.max_tilt);
    }
}

/// Below the margin at an attach, the one command that cannot lower it goes on. The Allegro's
/// ellipsoid mesh planned at `plan.alpha` 0.12 (its config's 0.13 less 0.01 of headroom): at the
/// detach of step 44 (128 deg) the index slips 2 mm off its contact, and the grasp of index,
/// middle and thumb keeps alpha* 0.08 < 0.1 where MuJoCo's fingertips touch; the gate held the
/// hand at step 46, the ring finger's attach, for as long as the run lasted (90 s of simulated
/// time, 2026-12-06, before the gate let such an attach through: the CI's "held 40 s at an
/// attach" of the pipeline test, reproduced). Now the ring finger attaches with the others
/// held, and the margin comes back with it: in every noise seed of 1-6 where such an attach
/// happens (at least two), the ellipsoid turns to the goal, no finger touching another, no link
/// on the object, no contact lost after. The situation is a knife edge: in the other seeds the index's slip
/// lets the ellipsoid spin out between two fingers (tilted 103 deg) before any attach, with the
/// estimator that rolled the object with every finger in contact (attaches in seeds 1 and 5)
/// and with the one that rolls it with the fingers pressed only (4 and 6; 2026-12-06): issue
/// 37's.
#[test]
fn below_the_margin_a_finger_attaching_to_the_grasp_held_restores_it() {
    let dir = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../config");
    let path = dir.join("allegro_ellipsoid_mujoco.toml");
    let mut table: toml::Table = std::fs::read_to_string(&path).unwrap().parse().unwrap();
    table["plan"]
        .as_table_mut()
        .unwrap()
        .insert("alpha".into(), toml::Value::Float(0.12));
    let mut config = Config::from_table(table, &path).unwrap();
    let setup = Setup::new(&config).unwrap();
    let mut met = Vec::new();
    for seed in 1..=6 {
        config.pipeline.seed = seed;
        let mut watch = TruthWatch::new(&config);
        let mut first_attach = None;
        let ended = lockstep::run(&config, &setup, 90.0, 0.5, 0.0, &mut |tick| {
            watch.observe(tick);
            if tick
                .command
                .is_some_and(|(c, _)| c.mode == CommandMode::Attach as u32)
            {
                first_attach.get_or_insert(tick.time);
            }
        })
        .unwrap();
        println!(
            "seed {seed}: {:.1} deg after {:.1} s, {} attach commands below the margin from {first_attach:?} s, {} holds, tilt at most {:.1} deg, losses {:?}",
            ended.rotation.to_degrees(),
            ended.time,
            ended.attaches_below_margin,
            ended.holds,
            watch.max_tilt.0,
            watch.losses
        );
        let Some(from) = first_attach else {
            continue;
        };
        met.push(seed);
        assert!(ended.attaches_below_margin > 0, "seed {seed}");
        assert!(ended.done, "seed {seed}: {ended:?}");
        assert!(
            (ended.rotation.to_degrees() - 270.0).abs() <= 0.01 * 270.0,
            "seed {seed}: {ended:?}"
        );
        assert_eq!(ended.holding, None, "seed {seed}: {ended:?}");
        assert!(
            watch.losses.iter().all(|l| l.time < from),
            "seed {seed}: {:?}",
            watch.losses
        );
        assert_eq!(watch.fingers_touching, 0, "seed {seed}");
        assert_eq!(watch.links_on_object, 0, "seed {seed}");
    }
    // Two of the six when this was written (4 and 6).
    assert!(
        met.len() >= 2,
        "an attach below the margin in seeds {met:?} of 1-6 only: the situation was not met"
    );
}

/// The paper's sphere, and the ellipsoid under gravity, turned a whole turn with the loop
/// upstream of the command node stalled a few milliseconds at a time (`lockstep::Stall`), as
/// on a machine busy with other work: 3 of every 5 ms, 4 of every 8, 8 of every 12 (the
/// command node's timer holding the hand in the longer gaps). Each run reaches the goal
/// (MuJoCo's rotation within 2 % of 360 degrees), no contact lost while planned, the centre
/// within 5 mm, the estimate never tracked more than the gate's bound off the truth.
///
/// Before (2026-12-06), a command more than three periods late resumed: every finger set off
/// from where the grasp state had it, short of its command by the contact's give, so the
/// fingers pressing on the object let go of it a little at every command, and the hand went
/// one period's motion per command. The sphere lost its grasp in each (585, 58 and -235 deg
/// after 120 s, 13, 9 and 6 contacts lost; the CI run of 7b4020a failed so in the pipeline,
/// its loop 2 to 14 ms late), and the ellipsoid fell out of the hand in each. With only the
/// pressing fingers set off from their last command, the sphere reached the goal in 57 to 88
/// s, and the ellipsoid, as slow, crept down out of the fingers under gravity (MuJoCo's soft
/// friction: 0.18 mm/s) at 236 deg. Now a command late by up to `command::LATE_PERIODS`
/// moves the hand on by the time gone: 18 to 32 s, as unstalled (18.4 and 18.9 s).
#[test]
fn a_stalled_loop_keeps_the_grasp_and_turns_the_object_to_the_goal() {
    for name in ["paper_sphere_mujoco.toml", "ellipsoid_mujoco.toml"] {
        let config = load(name);
        let setup = Setup::new(&config).unwrap();
        for (length_ms, period_ms) in [(3.0, 5.0), (4.0, 8.0), (8.0, 12.0)] {
            let stall =
                lockstep::Stall::of_ms(length_ms, period_ms, config.pipeline.rate_hz).unwrap();
            let mut watch = TruthWatch::new(&config);
            let (mut drift, mut start) = (0.0_f64, None);
            let ended =
                lockstep::run_stalled(&config, &setup, 120.0, 0.5, 0.0, stall, &mut |tick| {
                    watch.observe(tick);
                    let c = tick.plant.sim().object_centre();
                    drift = drift.max((c - *start.get_or_insert(c)).norm());
                })
                .unwrap();
            let said = format!(
                "{name} stalled {length_ms} of every {period_ms} ms: {ended:?}, losses {:?}, drift {drift} m",
                watch.losses
            );
            println!("{said}");
            assert!(ended.done, "{said}");
            assert!(
                (ended.rotation.to_degrees() - 360.0).abs() <= 0.02 * 360.0,
                "{said}"
            );
            assert!(watch.losses.is_empty(), "{said}");
            assert!(drift < 5e-3, "{said}");
            assert_eq!(watch.tracked_off, 0, "{said}");
        }
    }
}

/// A stall is whole ticks of its period, refused where it is no stall at all.
#[test]
fn a_stall_is_counted_in_ticks_and_refused_past_its_period() {
    let s = lockstep::Stall::of_ms(4.0, 8.0, 1000.0).unwrap();
    assert_eq!((s.length, s.period), (4, 8));
    let covered: Vec<bool> = (0..9).map(|k| s.covers(k)).collect();
    assert_eq!(
        covered,
        [true, true, true, true, false, false, false, false, true]
    );
    assert!((0..100).all(|k| !lockstep::Stall::NONE.covers(k)));
    for (length, period) in [(8.0, 8.0), (1.0, 0.2), (-1.0, 8.0)] {
        let e = lockstep::Stall::of_ms(length, period, 1000.0)
            .unwrap_err()
            .to_string();
        assert!(e.contains("less than its period"), "{e}");
    }
}
