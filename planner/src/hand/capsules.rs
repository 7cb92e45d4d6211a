//! A finger's body as capsules (its links and its fingertip), and how far two fingers' bodies
//! keep apart: what keeps fingers off each other in plans and on their way between poses.

use icrflow_grasp::math::{Real, Vec3};

use super::Finger;

/// A segment swept by a sphere: a link (`radius` its half-thickness), or a fingertip (a
/// segment of zero length, the fingertip's radius).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Capsule {
    /// One end (hand frame, m).
    pub from: Vec3,
    /// The other end.
    pub to: Vec3,
    /// Radius (m).
    pub radius: Real,
}

impl Finger {
    /// The finger at `q` as capsules: its links ([`Finger::link_segments`]) of radius
    /// `link_radius`, then its fingertip sphere.
    pub fn capsules(&self, q: &[Real], link_radius: Real) -> Vec<Capsule> {
        let mut out = Vec::with_capacity(q.len() + 2);
        self.link_segments(q, |_, from, to| {
            out.push(Capsule {
                from,
                to,
                radius: link_radius,
            });
        });
        let tip = self.tip_centre(q);
        out.push(Capsule {
            from: tip,
            to: tip,
            radius: self.tip_radius,
        });
        out
    }
}

/// The smallest gap between any capsule of `a` and any of `b` (m; negative: they overlap by
/// that much; infinite if either is empty).
pub fn gap(a: &[Capsule], b: &[Capsule]) -> Real {
    let mut least = Real::INFINITY;
    for x in a {
        for y in b {
            let d = segment_segment_distance(&x.from, &x.to, &y.from, &y.to);
            least = least.min(d - x.radius - y.radius);
        }
    }
    least
}

/// Distance between segments `p0 p1` and `q0 q1` (Ericson, Real-Time Collision Detection,
/// 5.1.9); either may be a point.
pub fn segment_segment_distance(p0: &Vec3, p1: &Vec3, q0: &Vec3, q1: &Vec3) -> Real {
    let (d1, d2, r) = (p1 - p0, q1 - q0, p0 - q0);
    let (a, e, f) = (d1.norm_squared(), d2.norm_squared(), d2.dot(&r));
    let eps = 1e-18;
    let (s, t);
    if a <= eps && e <= eps {
        return r.norm();
    }
    if a <= eps {
        s = 0.0;
        t = (f / e).clamp(0.0, 1.0);
    } else {
        let c = d1.dot(&r);
        if e <= eps {
            t = 0.0;
            s = (-c / a).clamp(0.0, 1.0);
        } else {
            let b = d1.dot(&d2);
            let denom = a * e - b * b;
            let mut s0 = if denom > eps {
                ((b * f - c * e) / denom).clamp(0.0, 1.0)
            } else {
                0.0
            };
            let mut t0 = (b * s0 + f) / e;
            if t0 < 0.0 {
                t0 = 0.0;
                s0 = (-c / a).clamp(0.0, 1.0);
            } else if t0 > 1.0 {
                t0 = 1.0;
                s0 = ((b - c) / a).clamp(0.0, 1.0);
            }
            s = s0;
            t = t0;
        }
    }
    ((p0 + d1 * s) - (q0 + d2 * t)).norm()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::paper;

    #[test]
    fn two_fingers_gap_is_their_nearest_capsules_distance_less_their_radii() {
        let hand = paper::hand();
        let (f1, f2) = (&hand.fingers[0], &hand.fingers[1]);
        let home = |f: &Finger| f.home.clone();
        let a = f1.capsules(&home(f1), 0.004);
        // Two links and the fingertip: the distal link (25 mm) lies inside the 25 mm fingertip.
        assert_eq!(a.len(), 3);
        assert_eq!(a[2].radius, f1.tip_radius);
        assert_eq!(a[0].radius, 0.004);
        let b = f2.capsules(&home(f2), 0.004);
        let g = gap(&a, &b);
        // Brute force over the segments sampled.
        let mut least = Real::INFINITY;
        for x in &a {
            for y in &b {
                for i in 0..=200 {
                    for j in 0..=200 {
                        let p = x.from + (x.to - x.from) * (i as Real / 200.0);
                        let q = y.from + (y.to - y.from) * (j as Real / 200.0);
                        least = least.min((p - q).norm() - x.radius - y.radius);
                    }
                }
            }
        }
        assert!(g <= least + 1e-12 && g > least - 1e-4, "{g} vs {least}");
        // A finger overlaps itself by its radii.
        assert!(gap(&a, &a) <= -0.008 + 1e-12);
        assert_eq!(gap(&a, &[]), Real::INFINITY);
    }
}
