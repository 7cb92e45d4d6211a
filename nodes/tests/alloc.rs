//! Heap allocations of the bus in its steady state, counted by the allocator the node
//! binaries install (`icrflow_runtime::health::COUNTING_ALLOCATOR`): receiving allocates nothing; sending
//! allocates once, inside iceoryx2 0.10 (`Publisher::loan_uninit` creates a reference-counted
//! `ChunkMutSharedState` per sample), which no use of its API avoids.

#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    reason = "a test, bench or example: a panic is its failure, with the message it gives"
)]

use icrflow_interfaces::{Header, JointState, Kind, topics};
use icrflow_runtime::bus::{Bus, BusConfig};
use icrflow_runtime::health::allocations;

#[global_allocator]
static ALLOCATOR: &icrflow_runtime::health::CountingAllocator =
    &icrflow_runtime::health::COUNTING_ALLOCATOR;

/// The tests count the whole process's allocations, so they run one after another on the main
/// thread, without libtest (`harness = false`): its runner thread reports a finished test while
/// the next one counts, which once added 4 allocations to a count of 199 (CI, 6adadb5).
fn main() -> std::process::ExitCode {
    let tests: [(&str, fn()); 6] = [
        (
            "receiving_allocates_nothing_and_sending_once",
            receiving_allocates_nothing_and_sending_once,
        ),
        (
            "a_slice_topic_allocates_only_in_iceoryx2s_send",
            a_slice_topic_allocates_only_in_iceoryx2s_send,
        ),
        (
            "waiting_on_a_listener_allocates_nothing",
            waiting_on_a_listener_allocates_nothing,
        ),
        (
            "a_kept_force_solver_allocates_once_per_new_contact_set",
            a_kept_force_solver_allocates_once_per_new_contact_set,
        ),
        (
            "evaluating_new_contact_sets_in_kept_buffers_allocates_nothing",
            evaluating_new_contact_sets_in_kept_buffers_allocates_nothing,
        ),
        (
            "a_mujoco_plant_tick_allocates_nothing",
            a_mujoco_plant_tick_allocates_nothing,
        ),
    ];
    // `cargo test -- NAME` runs the tests whose names contain NAME; flags are ignored.
    let filters: Vec<String> = std::env::args()
        .skip(1)
        .filter(|a| !a.starts_with('-'))
        .collect();
    let chosen: Vec<_> = tests
        .iter()
        .filter(|(name, _)| filters.is_empty() || filters.iter().any(|f| name.contains(f.as_str())))
        .collect();
    println!("\nrunning {} tests", chosen.len());
    let mut failed = Vec::new();
    let count = chosen.len();
    for (name, test) in chosen {
        let passed = std::panic::catch_unwind(test).is_ok();
        println!("test {name} ... {}", if passed { "ok" } else { "FAILED" });
        if !passed {
            failed.push(*name);
        }
    }
    let passed = count - failed.len();
    if failed.is_empty() {
        println!("\ntest result: ok. {passed} passed; 0 failed\n");
        std::process::ExitCode::SUCCESS
    } else {
        println!("\nfailures:");
        for name in &failed {
            println!("    {name}");
        }
        println!(
            "\ntest result: FAILED. {passed} passed; {} failed\n",
            failed.len()
        );
        std::process::ExitCode::FAILURE
    }
}

fn receiving_allocates_nothing_and_sending_once() {
    let c = BusConfig::isolated("alloc").unwrap();
    {
        let a = Bus::new("sender", &c).unwrap();
        let b = Bus::new("receiver", &c).unwrap();
        let sub = b.subscriber(topics::JOINT_STATE).unwrap();
        let publisher = a.publisher(topics::JOINT_STATE).unwrap();
        let m = JointState {
            header: Header::new(Kind::JointState, 1, 0, 0),
            ..Default::default()
        };
        // Warm up: connections, buffers.
        for _ in 0..100 {
            publisher.send(m).unwrap();
            sub.drain(|_| {}).unwrap();
        }
        let n = 1000;
        let mut counts = [0u64; 3];
        for _ in 0..n {
            let t0 = allocations();
            publisher.send(m).unwrap();
            let t1 = allocations();
            sub.drain(|_| {}).unwrap();
            let t2 = allocations();
            counts[0] += t1 - t0;
            counts[1] += t2 - t1;
        }
        let t0 = allocations();
        for _ in 0..n {
            sub.latest().unwrap();
        }
        counts[2] = allocations() - t0;
        println!(
            "per operation: send {:.2}, drain {:.2}, empty latest {:.2}",
            counts[0] as f64 / n as f64,
            counts[1] as f64 / n as f64,
            counts[2] as f64 / n as f64
        );
        assert!(counts[0] <= n, "send allocates more than once: {counts:?}");
        assert_eq!(counts[1], 0, "draining a message allocates");
        assert_eq!(counts[2], 0, "polling an empty subscriber allocates");
    }
    c.remove_files();
}

/// The same for a topic with a dynamic slice (the wrench space's facets): receiving into a
/// reused vector allocates nothing; sending allocates once, in iceoryx2 0.10 (as above).
fn a_slice_topic_allocates_only_in_iceoryx2s_send() {
    use icrflow_interfaces::{Facet, WrenchSpaceHeader};
    let c = BusConfig::isolated("alloc-slice").unwrap();
    {
        let a = Bus::new("sender", &c).unwrap();
        let b = Bus::new("receiver", &c).unwrap();
        let sub = b.slice_subscriber(topics::WRENCH_SPACE).unwrap();
        let publisher = a.slice_publisher(topics::WRENCH_SPACE).unwrap();
        let header = WrenchSpaceHeader {
            header: Header::new(Kind::WrenchSpace, 1, 0, 0),
            ..Default::default()
        };
        let facets = vec![Facet::default(); 40];
        let mut received: Vec<Facet> = Vec::with_capacity(64);
        for _ in 0..100 {
            publisher.send(header, &facets).unwrap();
            sub.latest(&mut received).unwrap();
        }
        let n = 1000;
        let (mut sent, mut taken) = (0, 0);
        for _ in 0..n {
            let t0 = allocations();
            publisher.send(header, &facets).unwrap();
            let t1 = allocations();
            assert!(sub.latest(&mut received).unwrap().is_some());
            let t2 = allocations();
            sent += t1 - t0;
            taken += t2 - t1;
        }
        println!(
            "per operation: slice send {:.2}, latest {:.2}",
            sent as f64 / n as f64,
            taken as f64 / n as f64
        );
        assert_eq!(received.len(), 40);
        assert_eq!(taken, 0, "receiving a slice allocates");
        assert!(sent <= n, "a slice send allocates more than once: {sent}");
    }
    c.remove_files();
}

/// How the nodes sleep (`icrflow_runtime::event::Waiter`, ppoll on the listener): a send wakes the waiter,
/// waiting allocates nothing, and with nothing sent it sleeps out its timeout.
fn waiting_on_a_listener_allocates_nothing() {
    let c = BusConfig::isolated("alloc-wait").unwrap();
    {
        let a = Bus::new("sender", &c).unwrap();
        let b = Bus::new("receiver", &c).unwrap();
        let sub = b.subscriber(topics::JOINT_STATE).unwrap();
        let publisher = a.publisher(topics::JOINT_STATE).unwrap();
        let mut waiter = icrflow_runtime::event::Waiter::new(&[sub.listener()]);
        let m = JointState {
            header: Header::new(Kind::JointState, 1, 0, 0),
            ..Default::default()
        };
        let mut waits = 0;
        for _ in 0..200 {
            publisher.send(m).unwrap();
            let t0 = allocations();
            assert!(waiter.wait(std::time::Duration::from_secs(5)).unwrap());
            waits += allocations() - t0;
            assert_eq!(sub.drain(|_| {}).unwrap(), 1);
        }
        assert_eq!(waits, 0, "waiting allocates");
        // Nothing pending: it sleeps for its timeout.
        let timeout = std::time::Duration::from_millis(20);
        let start = std::time::Instant::now();
        assert!(waiter.wait(timeout).unwrap());
        assert!(
            start.elapsed() >= timeout,
            "woke after {:?}",
            start.elapsed()
        );
        assert!(sub.latest().unwrap().is_none());
    }
    c.remove_files();
}

/// The hand command node's force solve (`forces::ForceSolver`, kept across commands): once it
/// has met a number of contacts, a new contact set of that size allocates once, inside
/// clarabel 0.11 (`DefaultSolver::solve` resets its timers, which drops and rebuilds the map
/// of the "IP iteration" timer's sub-timers; the timers cannot be turned off). A fresh solver
/// per set, as before, allocated about 130 times.
fn a_kept_force_solver_allocates_once_per_new_contact_set() {
    use icrflow_grasp::math::Vec3;
    use icrflow_plan::forces::{ForceContact, ForceSolver, Load};
    let ring = |angles: &[f64], turn: f64| -> Vec<ForceContact> {
        angles
            .iter()
            .map(|a| {
                let a = (a + turn).to_radians();
                let n = Vec3::new(a.cos(), a.sin(), 0.1 * a.sin()).normalize();
                ForceContact {
                    point: 0.0475 * n,
                    normal: n,
                }
            })
            .collect()
    };
    let mut solver = ForceSolver::new();
    let mut forces = Vec::with_capacity(8);
    let (three, four): (&[f64], &[f64]) = (&[30.0, -30.0, 140.0], &[30.0, -30.0, 140.0, 200.0]);
    // The first of each size builds its solver.
    for set in [three, four] {
        solver
            .solve(&ring(set, 0.0), &Load::none(), 0.3, 1.0, &mut forces)
            .unwrap();
    }
    let sets: Vec<Vec<ForceContact>> = (1..200)
        .map(|k| ring(if k % 3 == 0 { four } else { three }, 0.7 * k as f64))
        .collect();
    let mut previous = forces.clone();
    let t0 = allocations();
    for contacts in &sets {
        solver
            .solve(contacts, &Load::none(), 0.3, 1.0, &mut forces)
            .unwrap();
        assert_eq!(forces.len(), contacts.len());
        assert_ne!(
            forces[0], previous[0],
            "the same forces for a new contact set"
        );
        previous.clear();
        previous.extend_from_slice(&forces);
    }
    let solving = allocations() - t0;
    println!(
        "per solve: {:.2} allocations",
        solving as f64 / sets.len() as f64
    );
    assert!(
        solving <= sets.len() as u64,
        "{} solves allocated {solving} times",
        sets.len()
    );
}

/// The wrench-space node's evaluation of a new contact set (`GraspProblem::evaluate_in`, in
/// buffers it keeps): after the first sets, evaluating allocates nothing, in the paper's
/// planar wrench space (beneath-beyond hulls in 3D) and in the spatial one of
/// `ellipsoid_spatial.toml` (three contacts: the facet enumeration in 6D; four:
/// beneath-beyond in 6D). A fresh evaluation allocates dozens of times.
fn evaluating_new_contact_sets_in_kept_buffers_allocates_nothing() {
    use icrflow_grasp::quality::{Evaluation, EvaluationScratch};
    for name in ["paper_sphere.toml", "ellipsoid_spatial.toml"] {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../config")
            .join(name);
        let config = icrflow_scenario::Config::load(&path).unwrap();
        let setup = icrflow_scenario::Setup::new(&config).unwrap();
        let problem = &setup.problem;
        let n = problem.candidates().points.len();
        // Contact sets spread around the candidates, three and four contacts.
        let sets: Vec<Vec<usize>> = (0..400)
            .map(|k| {
                let count = 3 + k % 2;
                (0..count)
                    .map(|i| (k * 7 + i * n / count + (k * i) % 5) % n)
                    .collect()
            })
            .collect();
        let mut e = Evaluation::default();
        let mut scratch = EvaluationScratch::default();
        // Warm up: the buffers grow to the largest hulls met.
        for set in &sets {
            problem.evaluate_in(set, &mut e, &mut scratch).unwrap();
        }
        let (mut closed, mut facets) = (0, 0);
        let t0 = allocations();
        for set in sets.iter().rev() {
            problem.evaluate_in(set, &mut e, &mut scratch).unwrap();
            closed += usize::from(e.force_closure());
            facets += e.hull.as_ref().map_or(0, |h| h.facet_count());
        }
        let kept = allocations() - t0;
        let t0 = allocations();
        for set in &sets[..20] {
            problem.evaluate(set).unwrap();
        }
        let fresh = allocations() - t0;
        println!(
            "{name}: {} evaluations in kept buffers allocated {kept} times ({closed} force \
             closure, {facets} facets); a fresh evaluation {:.1} times",
            sets.len(),
            fresh as f64 / 20.0
        );
        assert!(closed > 0 && facets > 0, "{name}: nothing evaluated");
        assert_eq!(kept, 0, "{name}: evaluating in kept buffers allocates");
        assert!(fresh >= 20, "{name}: the comparison allocates nothing");
    }
}

/// The MuJoCo plant's tick (`physical::Physical::tick`: MuJoCo's steps, the contacts read
/// back, the measurements and the truth), once warmed up, holding the paper's sphere in its
/// initial grasp and with a finger lifted off and put back again and again: nothing allocated
/// (the plant node allocates about 0.4 times per message more with MuJoCo than with the
/// kinematic plant, BENCHMARKS.md: not here).
fn a_mujoco_plant_tick_allocates_nothing() {
    use icrflow_nodes::physical::{Physical, holding_command};
    use icrflow_scenario::{Config, Setup};
    let dir = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../config");
    let config = Config::load(&dir.join("paper_sphere_mujoco.toml")).unwrap();
    let setup = Setup::new(&config).unwrap();
    let (contacts, _) = setup.scenario(&config).start().unwrap();
    let t0: u64 = 1_000_000_000_000;
    let joints = setup.initial_grip(&config).unwrap().0;
    let mut plant = Physical::new(&config, &setup, &joints, t0).unwrap();
    let dt = 1_000_000;
    let mut t = t0;
    let mut command = holding_command(&config, &setup, &contacts, t).unwrap();
    for _ in 0..200 {
        t += dt;
        command.header.source_time_ns = t;
        plant.tick(t, Some(&command));
    }
    let ticks = 1000;
    let before = allocations();
    for _ in 0..ticks {
        t += dt;
        command.header.source_time_ns = t;
        let out = plant.tick(t, Some(&command));
        std::hint::black_box(out);
    }
    let n = allocations() - before;
    println!("per tick: {:.3} allocations", n as f64 / ticks as f64);
    assert_eq!(n, 0, "{ticks} ticks allocated {n} times");
    // A finger lifted off the object and put back, again and again: contacts made and lost,
    // their events said.
    let held = command;
    let mut lifted = held;
    lifted.forces[0] = [0.0; 3];
    lifted.joint_targets[0][1] -= 0.2;
    let before = allocations();
    let mut events = 0;
    for k in 0..ticks {
        t += dt;
        let mut c = if (k / 100) % 2 == 0 { lifted } else { held };
        c.header.source_time_ns = t;
        let out = plant.tick(t, Some(&c));
        events += plant.events().len();
        std::hint::black_box(out);
    }
    let n = allocations() - before;
    println!(
        "lifting and putting back: {events} events, {:.3} allocations per tick",
        n as f64 / ticks as f64
    );
    assert!(events >= 5, "{events} contact events");
    assert_eq!(n, 0, "{ticks} ticks allocated {n} times");
}
