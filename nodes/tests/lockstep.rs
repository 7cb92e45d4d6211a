//! The loop in lockstep on MuJoCo ([`icrflow_nodes::lockstep`]): the nodes' own steps on
//! simulated time, no processes. The paper's sphere turned toward 45 degrees.

use icrflow_nodes::lockstep;
use icrflow_scenario::{Config, Setup};

/// `config/paper_sphere_mujoco.toml` with the goal at `goal_deg`.
fn paper(goal_deg: f64) -> (Config, Setup) {
    let dir = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../config");
    let mut config = Config::load(&dir.join("paper_sphere_mujoco.toml")).unwrap();
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
    let ended = lockstep::run(config, setup, seconds, 0.5, &mut |tick| {
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
    let e = lockstep::run(&config, &setup, 1.0, 0.0, &mut |_| {})
        .unwrap_err()
        .to_string();
    assert!(e.contains("plant.kind = \"mujoco\""), "{e}");
}
