//! The ICR claim, checked by sampling: any choice of one point in each contact's independent
//! contact region keeps the grasp quality >= alpha. For each case, 1000 random picks (one
//! point per region), each evaluated from scratch (new hull, new support function); the test
//! prints the fraction that keep the margin and fails on any pick below alpha beyond the
//! numerical tolerance.

#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    reason = "a test, bench or example: a panic is its failure, with the message it gives"
)]

mod common;

use common::Rng;
use icrflow_grasp::math::{Real, Vec3};
use icrflow_grasp::object::Object;
use icrflow_grasp::quality::GraspProblem;
use icrflow_grasp::wrench::Space;

const PICKS: usize = 1000;
/// Relative slack for round-off between two independent hull computations.
const SLACK: Real = 1e-9;

/// Samples picks from the regions of `contacts` at margin `alpha`; returns (kept, worst).
fn sample(name: &str, problem: &GraspProblem, contacts: &[usize], alpha: Real, rng: &mut Rng) {
    let e = problem.evaluate(contacts).unwrap();
    assert!(e.force_closure(), "{name}: initial grasp not force closure");
    let regions = problem.icrs(contacts, &e, alpha).unwrap();
    for (r, &c) in regions.iter().zip(contacts) {
        assert!(
            r.members.contains(&(c as u32)),
            "{name}: contact {c} outside its own region"
        );
    }
    let sizes: Vec<usize> = regions.iter().map(|r| r.members.len()).collect();
    let mut kept = 0;
    let mut worst = Real::INFINITY;
    let mut pick = vec![0usize; contacts.len()];
    for _ in 0..PICKS {
        for (p, r) in pick.iter_mut().zip(&regions) {
            *p = r.members[rng.below(r.members.len())] as usize;
        }
        let q = problem.evaluate(&pick).unwrap().quality;
        worst = worst.min(q);
        if q >= alpha {
            kept += 1;
        }
        assert!(
            q >= alpha * (1.0 - SLACK),
            "{name}: pick {pick:?} from regions of sizes {sizes:?} has quality {q} < alpha {alpha}"
        );
    }
    println!(
        "{name}: alpha* = {:.5}, alpha = {alpha:.5}, region sizes {sizes:?}, {kept}/{PICKS} picks keep quality >= alpha (worst {worst:.5})",
        e.quality
    );
    assert!(
        sizes.iter().any(|&s| s > 1),
        "{name}: every region is a single point"
    );
}

#[test]
fn paper_sphere_planar() {
    let object = Object::sphere(0.0475, 72, 72).unwrap();
    let p = common::problem(&object, Space::Planar, 0.3, 8);
    // 30, -30 and 140 degrees on the 72-point equator ring.
    sample("paper sphere, planar", &p, &[6, 66, 28], 0.1, &mut Rng(1));
}

fn random_cases(name: &str, object: &Object, space: Space, contacts: usize, seed: u64) {
    let mut rng = Rng(seed);
    let p = common::problem(object, space, 0.5, 8);
    for (i, c) in common::force_closure_grasps(&p, &mut rng, contacts, 3)
        .iter()
        .enumerate()
    {
        let q = p.evaluate(c).unwrap().quality;
        sample(&format!("{name} #{i}"), &p, c, 0.5 * q, &mut rng);
    }
}

#[test]
fn sphere_6d_three_contacts() {
    random_cases(
        "sphere 36x36, 6D, 3 contacts",
        &Object::sphere(0.0475, 36, 36).unwrap(),
        Space::Spatial,
        3,
        2,
    );
}

#[test]
fn ellipsoid_mesh_6d_three_and_four_contacts() {
    let object = common::ellipsoid_mesh(40);
    random_cases(
        "ellipsoid STL, 6D, 3 contacts",
        &object,
        Space::Spatial,
        3,
        3,
    );
    random_cases(
        "ellipsoid STL, 6D, 4 contacts",
        &object,
        Space::Spatial,
        4,
        4,
    );
}

#[test]
fn cuboid_6d_and_planar() {
    let object = Object::cuboid(Vec3::new(0.04, 0.03, 0.025), 16).unwrap();
    random_cases("box, 6D, 3 contacts", &object, Space::Spatial, 3, 5);
    random_cases("box, planar, 3 contacts", &object, Space::Planar, 3, 6);
}
