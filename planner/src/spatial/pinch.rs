//! How near a set of contacts comes to squeezing the object with normal forces alone: the
//! smallest net wrench of unit-sum normal forces at them. Zero for a pinch (two contacts
//! facing each other through the object, or more whose normals balance): such a grasp holds
//! its squeeze without friction. Contacts whose normals cannot balance (the Allegro's ring
//! at one pole of the sphere, its thumb below it) squeeze the object only through friction,
//! which the fingers' compliant joints give way to.

use icrflow_grasp::math::{Real, Vec3};
use icrflow_grasp::wrench::WrenchFrame;
use nalgebra::{DMatrix, DVector};

/// The norm of the smallest net wrench (in `frame`: force, torque over rho) of normal forces
/// pressing on the object at `contacts` (body-frame points and outward normals), their
/// magnitudes summing to one: 0 where the normal forces alone can balance; up to 1. Infinite
/// without contacts.
pub fn unbalanced(frame: &WrenchFrame, contacts: &[(Vec3, Vec3)]) -> Real {
    let dim = frame.dim();
    let wrenches: Vec<DVector<Real>> = contacts
        .iter()
        .map(|(p, n)| {
            let mut w = vec![0.0; dim];
            frame.wrench(p, &(-n), &mut w);
            DVector::from_vec(w)
        })
        .collect();
    let k = wrenches.len();
    // The nearest point to the origin of the wrenches' convex hull: over every subset, the
    // nearest point of its affine hull, where its weights are all non-negative (k is at most
    // the fingers of a hand: 2^k - 1 small systems, exact). A QP solver (clarabel, which the
    // grasp crate's LP check uses) would do the same with a solver set up per call; this runs
    // only where two fingers clash in planning.
    let mut best = Real::INFINITY;
    for mask in 1_u32..(1 << k) {
        let members: Vec<usize> = (0..k).filter(|&i| mask & (1 << i) != 0).collect();
        let m = members.len();
        let mut kkt = DMatrix::<Real>::zeros(m + 1, m + 1);
        for (r, &i) in members.iter().enumerate() {
            for (c, &j) in members.iter().enumerate() {
                kkt[(r, c)] = wrenches[i].dot(&wrenches[j]);
            }
            kkt[(r, m)] = 1.0;
            kkt[(m, r)] = 1.0;
        }
        let mut rhs = DVector::<Real>::zeros(m + 1);
        rhs[m] = 1.0;
        let Some(solution) = kkt.lu().solve(&rhs) else {
            continue;
        };
        if (0..m).any(|r| solution[r] < -1e-12) {
            continue;
        }
        let net = members
            .iter()
            .enumerate()
            .fold(DVector::<Real>::zeros(dim), |acc, (r, &i)| {
                acc + &wrenches[i] * solution[r]
            });
        best = best.min(net.norm());
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;
    use icrflow_grasp::wrench::Space;

    fn frame() -> WrenchFrame {
        WrenchFrame::new(Vec3::zeros(), 0.035, Space::Spatial).unwrap()
    }

    /// A contact on the sphere of radius 35 mm at `dir`.
    fn at(dir: [Real; 3]) -> (Vec3, Vec3) {
        let n = Vec3::from(dir).normalize();
        (n * 0.035, n)
    }

    #[test]
    fn a_pinch_balances_and_a_ring_with_a_thumb_does_not() {
        let f = frame();
        // Index and ring at the poles of the y axis.
        let pinch = [at([0.0, 1.0, 0.0]), at([0.0, -1.0, 0.0])];
        assert!(unbalanced(&f, &pinch) < 1e-12);
        // The pinch with the thumb below it still balances (the thumb's share zero).
        let three = [pinch[0], pinch[1], at([0.0, 0.0, -1.0])];
        assert!(unbalanced(&f, &three) < 1e-12);
        // Ring and thumb: their normals at right angles, the nearest net force half of each:
        // sqrt(2) / 2.
        let ring_thumb = [pinch[1], at([0.0, 0.0, -1.0])];
        assert!((unbalanced(&f, &ring_thumb) - 0.5_f64.sqrt()).abs() < 1e-9);
        // Three normals 120 deg apart in a plane balance.
        let s = 3.0_f64.sqrt() / 2.0;
        let tri = [at([1.0, 0.0, 0.0]), at([-0.5, s, 0.0]), at([-0.5, -s, 0.0])];
        assert!(unbalanced(&f, &tri) < 1e-9);
        // One contact: its own unit force.
        assert!((unbalanced(&f, &pinch[..1]) - 1.0).abs() < 1e-9);
        assert_eq!(unbalanced(&f, &[]), Real::INFINITY);
    }
}
