//! Rendezvous regions on random grasps: the ICR rule's and the eq. (8) LP's regions never hold
//! a candidate the brute force rejects; how much of the exact region each recovers is
//! printed.

#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    reason = "a test, bench or example: a panic is its failure, with the message it gives"
)]

use icrflow_grasp::math::{Real, Vec3};
use icrflow_grasp::object::Object;
use icrflow_grasp::quality::GraspProblem;
use icrflow_grasp::wrench::{ContactModel, Space, WrenchFrame};
use icrflow_plan::rendezvous::regions;

/// A small deterministic generator (SplitMix64), so failures reproduce.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n as u64) as usize
    }
}

fn problem(object: &Object, space: Space, mu: Real) -> GraspProblem {
    let frame = WrenchFrame::new(object.centre_of_mass, object.max_radius(), space).unwrap();
    GraspProblem::new(
        &object.facets,
        object.section.samples.clone(),
        frame,
        ContactModel::new(mu, 8).unwrap(),
    )
    .unwrap()
}

/// Checks `cases` random force-closure grasps of three section points; returns the region
/// sizes summed (exact, LP, ICR).
fn check(p: &GraspProblem, cases: usize, seed: u64) -> (usize, usize, usize) {
    let n = p.candidates().points.len();
    let mut rng = Rng(seed);
    let (mut exact, mut lp, mut icr) = (0, 0, 0);
    let mut done = 0;
    let mut tries = 0;
    while done < cases {
        tries += 1;
        assert!(tries < 100 * cases, "too few force-closure grasps");
        let contacts = [rng.below(n), rng.below(n), rng.below(n)];
        if contacts[0] == contacts[1] || contacts[1] == contacts[2] || contacts[0] == contacts[2] {
            continue;
        }
        let e = p.evaluate(&contacts).unwrap();
        if !e.force_closure() {
            continue;
        }
        let alpha = e.quality * [0.3, 0.5, 0.8][done % 3];
        let k = rng.below(3);
        let r = regions(p, &contacts, k, alpha).unwrap();
        // The contact being replaced is always in the exact region (the grasp itself).
        assert!(r.exact.contains(&contacts[k]));
        for q in &r.icr {
            assert!(
                r.exact.contains(q),
                "ICR region point {q} unsafe: grasp {contacts:?}, k = {k}, alpha = {alpha}"
            );
        }
        for q in &r.lp {
            assert!(
                r.exact.contains(q),
                "LP region point {q} unsafe: grasp {contacts:?}, k = {k}, alpha = {alpha}"
            );
        }
        exact += r.exact.len();
        lp += r.lp.len();
        icr += r.icr.len();
        done += 1;
    }
    (exact, lp, icr)
}

fn report(name: &str, (exact, lp, icr): (usize, usize, usize)) {
    println!(
        "{name}: exact {exact}, eq. 8 LP {lp} ({:.0} %), ICR rule {icr} ({:.0} %)",
        100.0 * lp as Real / exact as Real,
        100.0 * icr as Real / exact as Real
    );
}

#[test]
fn planar_sphere_regions_are_inside_the_exact_region() {
    let o = Object::sphere(0.0475, 72, 72).unwrap();
    let p = problem(&o, Space::Planar, 0.3);
    report("planar sphere", check(&p, 60, 1));
}

#[test]
fn spatial_ellipsoid_regions_are_inside_the_exact_region() {
    let o = Object::ellipsoid(Vec3::new(0.055, 0.045, 0.04), 48, 24).unwrap();
    let p = problem(&o, Space::Spatial, 0.6);
    report("spatial ellipsoid", check(&p, 12, 2));
}
