//! Spatial rolling without slipping (`icrflow_plan::spatial::rolling`): a fingertip sphere
//! rolled along random paths on ellipsoids, its centre and orientation integrated from the
//! no-slip relation `b' = r_f omega x n` alone (the contact found anew each time as the
//! surface's closest point to the centre), travels equal arc lengths on the object and on the
//! fingertip; the contact's velocity from Montana's equations matches its finite differences.

#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    reason = "a test, bench or example: a panic is its failure, with the message it gives"
)]

use icrflow_grasp::math::{Real, UnitQuaternion, Vec3};
use icrflow_plan::spatial::rolling::{centre_velocity, contact_velocity};
use icrflow_plan::spatial::surface::Convex;
use proptest::prelude::*;

/// Integration steps over the path.
const STEPS: usize = 4000;

/// The relative angular velocity at time `t` in [0, 1]: a smooth random path (its part along
/// the normal spins the fingertip in place, which the test keeps).
fn omega(c: &[[Real; 3]; 3], t: Real) -> Vec3 {
    let (s, k) = (
        (2.0 * std::f64::consts::PI * t).sin(),
        (2.0 * std::f64::consts::PI * t).cos(),
    );
    Vec3::from(c[0]) + Vec3::from(c[1]) * s + Vec3::from(c[2]) * k
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    #[test]
    fn rolling_on_an_ellipsoid_keeps_the_arc_lengths_equal(
        axes in prop::array::uniform3(0.03..0.06f64),
        tip_radius in 0.008..0.02f64,
        start in prop::array::uniform3(-1.0..1.0f64),
        coefficients in prop::array::uniform3(prop::array::uniform3(-1.5..1.5f64)),
    ) {
        let start = Vec3::from(start);
        prop_assume!(start.norm() > 0.1);
        let surface = Convex::Ellipsoid { centre: Vec3::new(0.01, 0.0, -0.02), semi_axes: Vec3::from(axes) };
        let p0 = surface.closest(&(surface.centre() + start.normalize() * 0.2)).point;
        // State: the fingertip's centre (object frame) and orientation.
        let mut b = p0 + surface.normal(&p0) * tip_radius;
        let mut r = UnitQuaternion::identity();
        let h = 1.0 / STEPS as Real;
        let rate = |b: &Vec3, t: Real| {
            let n = surface.closest(b).normal;
            centre_velocity(&n, tip_radius, &omega(&coefficients, t))
        };
        let contact = |b: &Vec3, r: &UnitQuaternion| {
            let p = surface.closest(b).point;
            (p, r.inverse() * (p - b))
        };
        let (mut p, mut u) = contact(&b, &r);
        let (mut on_object, mut on_tip) = (0.0, 0.0);
        for i in 0..STEPS {
            let t = i as Real * h;
            // Classical Runge-Kutta for the centre; the orientation by the midpoint rotation.
            let k1 = rate(&b, t);
            let k2 = rate(&(b + k1 * (0.5 * h)), t + 0.5 * h);
            let k3 = rate(&(b + k2 * (0.5 * h)), t + 0.5 * h);
            let k4 = rate(&(b + k3 * h), t + h);
            let w1 = omega(&coefficients, t);
            let w2 = omega(&coefficients, t + 0.5 * h);
            let w4 = omega(&coefficients, t + h);
            let turn = (w1 + w2 * 4.0 + w4) * (h / 6.0);
            // Montana's contact velocity against the contact's finite difference.
            if i % 500 == 250 {
                let (ahead, _) = contact(&(b + (k1 + k2 * 2.0 + k3 * 2.0 + k4) * (h / 6.0)), &r);
                let fd = (ahead - p) / h;
                let mid = surface.closest(&(b + (k1 + k2 * 2.0 + k3 * 2.0 + k4) * (h / 12.0))).point;
                let v = contact_velocity(&surface, &mid, tip_radius, &w2);
                prop_assert!((fd - v).norm() <= 1e-4 * v.norm().max(1e-3), "{fd} vs {v}");
            }
            b += (k1 + k2 * 2.0 + k3 * 2.0 + k4) * (h / 6.0);
            r = UnitQuaternion::from_scaled_axis(turn) * r;
            let (pn, un) = contact(&b, &r);
            on_object += (pn - p).norm();
            on_tip += (un - u).norm();
            (p, u) = (pn, un);
        }
        // The centre stays on the offset surface (the relation is tangent to it).
        prop_assert!((surface.closest(&b).distance - tip_radius).abs() < 1e-9);
        prop_assert!(on_object > 1e-3, "the path is {on_object} m long");
        prop_assert!(
            (on_object - on_tip).abs() <= 1e-6 * on_object,
            "arc lengths {on_object} on the object, {on_tip} on the fingertip"
        );
    }
}

/// A control: with the fingertip's centre moved at twice the no-slip rate (the fingertip
/// slipping), the arc lengths differ: the test above can fail.
#[test]
fn a_slipping_fingertip_travels_unequal_arcs() {
    let surface = Convex::Ellipsoid {
        centre: Vec3::zeros(),
        semi_axes: Vec3::new(0.05, 0.04, 0.035),
    };
    let tip_radius = 0.012;
    let p0 = surface.closest(&Vec3::new(0.1, 0.05, 0.02)).point;
    let mut b = p0 + surface.normal(&p0) * tip_radius;
    let mut r = UnitQuaternion::identity();
    let w = Vec3::new(0.3, -1.0, 0.5);
    let h = 1.0 / STEPS as Real;
    let contact = |b: &Vec3, r: &UnitQuaternion| {
        let p = surface.closest(b).point;
        (p, r.inverse() * (p - b))
    };
    let (mut p, mut u) = contact(&b, &r);
    let (mut on_object, mut on_tip) = (0.0, 0.0);
    for _ in 0..STEPS {
        let n = surface.closest(&b).normal;
        b += centre_velocity(&n, tip_radius, &w) * (2.0 * h);
        b = surface.closest(&b).point + surface.closest(&b).normal * tip_radius;
        r = UnitQuaternion::from_scaled_axis(w * h) * r;
        let (pn, un) = contact(&b, &r);
        on_object += (pn - p).norm();
        on_tip += (un - u).norm();
        (p, u) = (pn, un);
    }
    assert!((on_object - on_tip).abs() > 0.1 * on_object);
}
