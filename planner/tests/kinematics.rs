//! Forward and inverse kinematics: FK(IK(x)) = x, and the same hand from URDF and from link
//! lengths.

#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    reason = "a test, bench or example: a panic is its failure, with the message it gives"
)]

use std::path::PathBuf;

use icrflow_grasp::math::{Isometry3, Real, Vec3};
use icrflow_plan::hand::Finger;
use icrflow_plan::paper;
use icrflow_plan::urdf::{UrdfFinger, fingers_from_file};
use proptest::prelude::*;

/// The package's directory, as cargo gives it when running the test (a test binary cached from
/// another checkout of the same commit would carry that checkout's compile-time path).
fn manifest_dir() -> std::ffi::OsString {
    std::env::var_os("CARGO_MANIFEST_DIR").unwrap_or_else(|| env!("CARGO_MANIFEST_DIR").into())
}
fn hands_dir() -> PathBuf {
    PathBuf::from(manifest_dir()).join("../config/hands")
}

/// Joint angles inside the limits from unit fractions.
fn within(f: &Finger, u: &[Real]) -> Vec<Real> {
    f.joints
        .iter()
        .zip(u)
        .map(|(j, t)| j.lower + t * (j.upper - j.lower))
        .collect()
}

fn allegro() -> Vec<Finger> {
    let tips = ["link_3_tip", "link_7_tip", "link_11_tip", "link_15_tip"];
    let specs: Vec<UrdfFinger> = tips
        .iter()
        .enumerate()
        .map(|(i, t)| UrdfFinger {
            id: i as u32 + 1,
            tip_link: (*t).into(),
            tip_radius: None,
            cap_half_angle: 1.5,
            home: None,
        })
        .collect();
    fingers_from_file(
        &hands_dir().join("allegro_right.urdf"),
        Isometry3::identity(),
        &specs,
    )
    .unwrap()
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(500))]

    /// Closed-form planar IK: any reachable fingertip pose (x, y, phi) is reached exactly,
    /// from any starting pose.
    #[test]
    fn planar_ik_reaches_every_reachable_pose(
        finger in 1u32..=4,
        u in prop::array::uniform3(0.0..1.0f64),
        v in prop::array::uniform3(0.0..1.0f64),
    ) {
        let hand = paper::hand();
        let f = hand.finger(finger).unwrap();
        let q = within(f, &u);
        let (x, y, phi) = f.planar_pose(&q).unwrap();
        let sol = f.ik_planar(x, y, phi, &within(f, &v)).unwrap();
        let (x2, y2, phi2) = f.planar_pose(&sol).unwrap();
        prop_assert!((x - x2).abs() < 1e-12 && (y - y2).abs() < 1e-12);
        prop_assert!(icrflow_plan::hand::wrap(phi - phi2).abs() < 1e-12);
        prop_assert!(f.limit_violation(&sol, 0.0).is_none());
    }

    /// Damped least squares on the Allegro hand's fingers (4 joints, spatial): a reachable
    /// fingertip centre is reached from a seed within 0.3 rad of a solution. A finger has a
    /// joint more than the centre needs: `ik_position_centred` reaches it too (within 1e-9 m,
    /// inside the limits) at a joint-limit cost no higher than the plain solution's.
    #[test]
    fn dls_ik_reaches_reachable_targets_on_the_allegro_hand(
        finger in 0usize..4,
        u in prop::array::uniform4(0.0..1.0f64),
        noise in prop::array::uniform4(-0.3..0.3f64),
    ) {
        let fingers = allegro();
        let f = &fingers[finger];
        let q = within(f, &u);
        let target = f.fk(&q).tip_centre;
        let seed: Vec<Real> = q.iter().zip(&noise).map(|(a, n)| a + n).collect();
        let sol = f.ik_position(&target, &seed).unwrap();
        prop_assert!((f.fk(&sol).tip_centre - target).norm() < 1e-9);
        prop_assert!(f.limit_violation(&sol, 0.0).is_none());
        let centred = f.ik_position_centred(&target, &seed).unwrap();
        prop_assert!((f.fk(&centred).tip_centre - target).norm() < 1e-9);
        prop_assert!(f.limit_violation(&centred, 0.0).is_none());
        prop_assert!(f.limit_cost(&centred) <= f.limit_cost(&sol));
    }

    /// The bound of a fingertip's travel on a straight joint-space move (what lets a route's
    /// check pass poses without their kinematics) holds on the Allegro's fingers: the length
    /// of the fingertip centre's path over any first part of the move, sampled finely, is at
    /// most the bound scaled by the part's fraction.
    #[test]
    fn a_fingertip_travels_no_farther_than_its_bound_on_the_allegro(
        finger in 0usize..4,
        a in prop::array::uniform4(0.0..1.0f64),
        b in prop::array::uniform4(0.0..1.0f64),
    ) {
        let fingers = allegro();
        let f = &fingers[finger];
        let (from, to) = (within(f, &a), within(f, &b));
        let bound = f.tip_travel_bound(&from, &to);
        let (mut at, mut path) = (f.tip_centre(&from), 0.0);
        for i in 1..=400 {
            let s = i as Real / 400.0;
            let q: Vec<Real> = from.iter().zip(&to).map(|(x, y)| x + s * (y - x)).collect();
            let next = f.tip_centre(&q);
            path += (next - at).norm();
            at = next;
            prop_assert!(path <= s * bound * (1.0 + 1e-12) + 1e-15, "{path} > {s} x {bound}");
        }
    }

    /// The command loop's shift of a fingertip after the object's centre (`shift_point`): on
    /// the Allegro's fingers, the fingertip's material point at its centre or at a contact on
    /// its sphere (outward normal `n` of the object there: the point `centre - r_f n`), in a
    /// pose whose Jacobian of that point has its smallest singular value at least twice
    /// `SHIFT_LEVER` (the joints turn by less than the move over it), moved by up to 3 mm in
    /// any direction lands within a micrometre of there; a move out of the finger's reach is
    /// refused, and so is a move of the stretched finger (all joints at 0) along itself, for
    /// which its joints would swing.
    #[test]
    fn shift_point_moves_the_allegros_fingertips_by_millimetres(
        finger in 0usize..4,
        u in prop::array::uniform4(0.0..1.0f64),
        d in prop::array::uniform3(-3e-3..3e-3f64),
        normal in prop::array::uniform3(-1.0..1.0f64),
        at_contact in any::<bool>(),
    ) {
        let fingers = allegro();
        let f = &fingers[finger];
        let q = within(f, &u);
        let d = Vec3::from(d);
        let n = Vec3::from(normal);
        prop_assume!(n.norm() > 0.1);
        let n = n.normalize();
        let (point, jac) = if at_contact {
            (f.tip_centre(&q) - n * f.tip_radius, f.contact_jacobian(&q, &n))
        } else {
            (f.tip_centre(&q), f.jacobian6(&q).rows(0, 3).into_owned())
        };
        prop_assume!(jac.singular_values().min() >= 2.0 * icrflow_plan::hand::SHIFT_LEVER);
        let local = f.tip_frame(&q).inverse() * nalgebra::Point3::from(point);
        let mut out = [0.0; 4];
        prop_assert!(f.shift_point(&q, &point, &d, &mut out));
        prop_assert!(((f.tip_frame(&out) * local).coords - point - d).norm() < 1e-6);
        let motion = q.iter().zip(&out).fold(0.0_f64, |m, (a, b)| m.max((a - b).abs()));
        prop_assert!(motion * icrflow_plan::hand::SHIFT_LEVER <= d.norm(), "{motion}");
        prop_assert!(!f.shift_point(&q, &point, &Vec3::new(1.0, 0.0, 0.0), &mut out));
        let straight = [0.0; 4];
        if f.limit_violation(&straight, 0.0).is_none() {
            // Along the finger, toward the palm: the joints bend by ~sqrt(2 |d| / length).
            let pose = f.fk(&straight);
            let inward = (pose.joints[1] - pose.tip_centre).normalize() * 1e-4;
            prop_assert!(!f.shift_point(&straight, &pose.tip_centre, &inward, &mut out));
        }
    }
}

#[test]
fn urdf_and_link_lengths_describe_the_same_hand() {
    let built_in = paper::hand();
    let specs: Vec<UrdfFinger> = (1..=4)
        .map(|id| UrdfFinger {
            id,
            tip_link: format!("f{id}_tip"),
            tip_radius: None,
            cap_half_angle: std::f64::consts::FRAC_PI_2,
            home: None,
        })
        .collect();
    let urdf = fingers_from_file(
        &hands_dir().join("paper_hand.urdf"),
        Isometry3::identity(),
        &specs,
    )
    .unwrap();
    for (a, b) in built_in.fingers.iter().zip(&urdf) {
        assert_eq!(a.id, b.id);
        assert_eq!(b.tip_radius, paper::TIP_RADIUS);
        assert!(b.planar.is_some(), "the URDF finger {} is planar", b.id);
        for (ja, jb) in a.joints.iter().zip(&b.joints) {
            assert!((ja.lower - jb.lower).abs() < 1e-12 && (ja.upper - jb.upper).abs() < 1e-12);
        }
        for k in 0..200 {
            let u = [
                (k as Real * 0.618).fract(),
                (k as Real * 0.414).fract(),
                (k as Real * 0.732).fract(),
            ];
            let q = within(a, &u);
            let (pa, pb) = (a.fk(&q), b.fk(&q));
            assert!((pa.tip_centre - pb.tip_centre).norm() < 1e-12);
            assert!((pa.cap_axis - pb.cap_axis).norm() < 1e-12);
            for (x, y) in pa.joints.iter().zip(&pb.joints) {
                assert!((x - y).norm() < 1e-12);
            }
            // The closed form works on the URDF finger too.
            let (x, y, phi) = b.planar_pose(&q).unwrap();
            let sol = b.ik_planar(x, y, phi, &q).unwrap();
            assert!((b.fk(&sol).tip_centre - pb.tip_centre).norm() < 1e-12);
        }
    }
}

#[test]
fn urdf_errors_name_the_problem() {
    let spec = |tip: &str| UrdfFinger {
        id: 2,
        tip_link: tip.into(),
        tip_radius: None,
        cap_half_angle: 1.0,
        home: None,
    };
    let path = hands_dir().join("paper_hand.urdf");
    let e = fingers_from_file(&path, Isometry3::identity(), &[spec("nope")]).unwrap_err();
    assert!(
        e.to_string().contains("finger 2") && e.to_string().contains("nope"),
        "{e}"
    );
    // The palm has no sphere to take the fingertip radius from.
    let e = fingers_from_file(&path, Isometry3::identity(), &[spec("f1_l3")]).unwrap_err();
    assert!(e.to_string().contains("sphere"), "{e}");
    let e = icrflow_plan::urdf::fingers_from_str("<robot", Isometry3::identity(), &[spec("x")])
        .unwrap_err();
    assert!(e.to_string().starts_with("URDF"), "{e}");
    let missing = hands_dir().join("missing.urdf");
    let e = fingers_from_file(&missing, Isometry3::identity(), &[spec("x")]).unwrap_err();
    assert!(e.to_string().contains("missing.urdf"), "{e}");
}

#[test]
fn jacobian_matches_finite_differences() {
    for f in allegro().iter().chain(paper::hand().fingers.iter()) {
        let q = within(f, &[0.3, 0.6, 0.2, 0.7]);
        let jac = f.jacobian(&q);
        for c in 0..f.dof() {
            let h = 1e-7;
            let mut qp = q.clone();
            qp[c] += h;
            let d = (f.fk(&qp).tip_centre - f.fk(&q).tip_centre) / h;
            for r in 0..3 {
                assert!(
                    (jac[(r, c)] - d[r]).abs() < 1e-6,
                    "finger {} joint {c} row {r}: {} vs {}",
                    f.id,
                    jac[(r, c)],
                    d[r]
                );
            }
        }
    }
}

/// The whole fingertip Jacobian against finite differences on the Allegro's and the paper's
/// fingers: its linear rows the fingertip centre's motion, its angular rows the fingertip's
/// rotation (`log(R(q + h e_c) R(q)^T) / h`); and the contact Jacobian the motion of the
/// fingertip's material point at a contact `r_f` from the centre along `-n`.
#[test]
fn the_whole_and_the_contact_jacobian_match_finite_differences() {
    for f in allegro().iter().chain(paper::hand().fingers.iter()) {
        let q = within(f, &[0.3, 0.6, 0.2, 0.7]);
        let jac = f.jacobian6(&q);
        let pose = f.fk(&q);
        let n = Vec3::new(0.3, -0.5, 0.81).normalize();
        let contact = f.contact_jacobian(&q, &n);
        // The material point at the contact, in the fingertip's frame.
        let body = pose.tip_rotation.inverse() * (-f.tip_radius * n);
        let h = 1e-7;
        for c in 0..f.dof() {
            let mut qp = q.clone();
            qp[c] += h;
            let moved = f.fk(&qp);
            let v = (moved.tip_centre - pose.tip_centre) / h;
            let w = (moved.tip_rotation * pose.tip_rotation.inverse()).scaled_axis() / h;
            let m = (moved.tip_centre + moved.tip_rotation * body
                - (pose.tip_centre + pose.tip_rotation * body))
                / h;
            for r in 0..3 {
                for (got, want, what) in [
                    (jac[(r, c)], v[r], "linear"),
                    (jac[(r + 3, c)], w[r], "angular"),
                    (contact[(r, c)], m[r], "contact"),
                ] {
                    assert!(
                        (got - want).abs() < 1e-6,
                        "finger {} joint {c} {what} row {r}: {got} vs {want}",
                        f.id
                    );
                }
            }
        }
    }
}

/// Over targets the Allegro's index finger reaches from poses with a joint near a limit, the
/// centred solutions keep its joints farther from the limits than the plain ones: the median
/// limit margin grows (0.020 to 0.125 of a joint's range), the smallest does not shrink (the
/// abduction joint is not redundant: where it is at 0.02 it stays).
#[test]
fn centred_ik_moves_the_allegros_joints_off_their_limits() {
    let fingers = allegro();
    let f = &fingers[0];
    let (mut plain, mut centred) = (Vec::new(), Vec::new());
    for k in 0..200 {
        // Poses with a joint near a limit (fractions 0.02 or 0.98 on one joint).
        let u: Vec<Real> = (0..4)
            .map(|i| {
                if i == k % 4 {
                    if k % 8 < 4 { 0.02 } else { 0.98 }
                } else {
                    0.2 + 0.6 * (((k * 7 + i * 13) % 17) as Real / 16.0)
                }
            })
            .collect();
        let q = within(f, &u);
        let target = f.fk(&q).tip_centre;
        plain.push(f.limit_margin(&f.ik_position(&target, &q).unwrap()));
        let c = f.ik_position_centred(&target, &q).unwrap();
        assert!((f.fk(&c).tip_centre - target).norm() < 1e-9);
        centred.push(f.limit_margin(&c));
    }
    let median = |v: &mut Vec<Real>| {
        v.sort_by(Real::total_cmp);
        v[v.len() / 2]
    };
    let (pm, cm) = (median(&mut plain), median(&mut centred));
    println!(
        "limit margin: plain min {:.3} median {pm:.3}; centred min {:.3} median {cm:.3}",
        plain[0], centred[0]
    );
    assert!(cm > pm + 0.05, "median {cm} against {pm}");
    assert!(
        centred[0] >= plain[0] - 1e-9,
        "min {} against {}",
        centred[0],
        plain[0]
    );
}
