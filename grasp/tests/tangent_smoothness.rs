//! The friction cones' tangent rule along a rolling path (issue #22 item 2): a contact rolling
//! on a sphere about a horizontal axis crosses `|n_z| = 0.9`, where the rule of sessions 1-17
//! (`ez x n` below, `ex x n` above) turned its cone abruptly. With the rule `t1 = axis x n`
//! (`wrench::tangent_basis_about`), for the rolling axis and for the default `+z` alike, the
//! grasp's alpha* changes smoothly along the path; with the old rule it jumps at the seam.

#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    reason = "a test, bench or example: a panic is its failure, with the message it gives"
)]

use icrflow_grasp::math::{Real, Vec3};
use icrflow_grasp::object::Object;
use icrflow_grasp::quality::GraspProblem;
use icrflow_grasp::wrench::{ContactModel, Space, WrenchFrame, tangent_basis_about};

const RADIUS: Real = 0.035;
const EDGES: usize = 8;
const MU: Real = 0.6;

/// The tangent rule of sessions 1-17, for the comparison.
fn old_rule(n: &Vec3) -> (Vec3, Vec3) {
    let r = if n.z.abs() < 0.9 {
        Vec3::z()
    } else {
        Vec3::x()
    };
    let t1 = r.cross(n).normalize();
    (t1, n.cross(&t1))
}

/// The primitive wrenches of contacts at the sphere's `normals` under the tangent rule
/// `basis`, in `frame`.
fn wrenches(
    frame: &WrenchFrame,
    normals: &[Vec3],
    basis: &dyn Fn(&Vec3) -> (Vec3, Vec3),
) -> Vec<Real> {
    let d = frame.dim();
    let mut out = vec![0.0; normals.len() * EDGES * d];
    for (n, block) in normals.iter().zip(out.chunks_exact_mut(EDGES * d)) {
        let (t1, t2) = basis(n);
        for (j, row) in block.chunks_exact_mut(d).enumerate() {
            let phi = std::f64::consts::TAU * j as Real / EDGES as Real;
            let f = -n + MU * (phi.cos() * t1 + phi.sin() * t2);
            frame.wrench(&(RADIUS * n), &f, row);
        }
    }
    out
}

/// alpha* every 0.1 deg along the rolling path under the rule `basis`.
fn along_the_path(basis: &dyn Fn(&Vec3) -> (Vec3, Vec3)) -> Vec<Real> {
    along_with(basis, &FIXED)
}

/// The two contacts that stay (their normals, normalised): a grasp in force closure all along
/// the path whose alpha* depends on the rolling contact's cone (of sixty random pairs, the
/// old rule's seam jumped 10 to 490 times the median step in half).
const FIXED: [[Real; 3]; 2] = [[0.44, 0.96, -0.16], [-0.41, -0.54, -0.54]];

fn along_with(basis: &dyn Fn(&Vec3) -> (Vec3, Vec3), fixed: &[[Real; 3]; 2]) -> Vec<Real> {
    let o = Object::sphere(RADIUS, 72, 36).unwrap();
    let frame = WrenchFrame::new(o.centre_of_mass, RADIUS, Space::Spatial).unwrap();
    let p = GraspProblem::new(
        &o.facets,
        o.facets.clone(),
        frame,
        ContactModel::new(MU, EDGES).unwrap(),
    )
    .unwrap();
    // The contact rolls about the horizontal axis at azimuth 120 deg, from azimuth 30 deg on the
    // equator down towards the south pole: n(t) = cos t n0 - sin t ez, |n_z| = 0.9 at t = 64.2 deg.
    let n0 = Vec3::new(30f64.to_radians().cos(), 30f64.to_radians().sin(), 0.0);
    let fixed = [
        Vec3::from(fixed[0]).normalize(),
        Vec3::from(fixed[1]).normalize(),
    ];
    (0..=300)
        .map(|k| {
            let t = (50.0 + 0.1 * k as Real).to_radians();
            let n = t.cos() * n0 - t.sin() * Vec3::z();
            let e = p
                .evaluate_wrenches(wrenches(&frame, &[n, fixed[0], fixed[1]], basis))
                .unwrap();
            e.quality
        })
        .collect()
}

/// The largest step of `alpha` between neighbouring samples against the median step.
fn roughness(alpha: &[Real]) -> (Real, Real) {
    let mut steps: Vec<Real> = alpha.windows(2).map(|w| (w[1] - w[0]).abs()).collect();
    let largest = steps.iter().copied().fold(0.0, Real::max);
    steps.sort_by(Real::total_cmp);
    (largest, steps[steps.len() / 2])
}

#[test]
fn alpha_changes_smoothly_along_a_rolling_path_across_the_old_seam() {
    let axis = Vec3::new(-(30f64.to_radians().sin()), 30f64.to_radians().cos(), 0.0);
    for (name, alpha) in [
        (
            "about the rolling axis",
            along_the_path(&|n: &Vec3| tangent_basis_about(&axis, n)),
        ),
        (
            "about +z",
            along_the_path(&|n: &Vec3| tangent_basis_about(&Vec3::z(), n)),
        ),
    ] {
        assert!(
            alpha.iter().all(|&a| a > 0.0),
            "{name}: not force closure along the path"
        );
        let (largest, median) = roughness(&alpha);
        println!(
            "{name}: alpha* {:.4} to {:.4}, largest step {largest:.2e}, median {median:.2e}",
            alpha.iter().copied().fold(Real::INFINITY, Real::min),
            alpha.iter().copied().fold(0.0, Real::max)
        );
        assert!(
            largest <= 3.0 * median,
            "{name}: a step of {largest} against a median of {median}"
        );
    }
    let old = along_the_path(&old_rule);
    let (largest, median) = roughness(&old);
    let at = old
        .windows(2)
        .position(|w| (w[1] - w[0]).abs() == largest)
        .unwrap();
    println!(
        "the old rule: largest step {largest:.2e} at {:.1} deg, median {median:.2e}",
        50.0 + 0.1 * at as Real
    );
    assert!(
        largest > 10.0 * median,
        "the old rule's seam: {largest} against {median}"
    );
}
