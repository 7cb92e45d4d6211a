//! The checks of a planar plan after it is made: its links' clearance from the object, its
//! rolling residuals and its smallest squeeze reserve.

use icrflow_grasp::math::Real;

use super::{Phase, SQUEEZE_PROBE, Scenario, Step};
use crate::hand::wrap;

/// Where a plan's links come closest to the object ([`link_clearance`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LinkClearance {
    /// Radial distance of the closest point of a link beyond the object's section (m;
    /// negative: inside).
    pub clearance: Real,
    /// Its finger.
    pub finger: u32,
    /// The link ([`crate::hand::Finger::link_distance`]).
    pub link: usize,
    /// The step at which, or on the way to which, it is closest.
    pub step: usize,
}

/// Spacing of the points at which a link is compared with the object's section (m).
pub const LINK_SPACING: Real = 0.5e-3;

/// How close the fingers' links ([`crate::hand::Finger::link_segments`], taken as lines) come
/// to the object's section in the hand's plane, at every step and along the straight
/// joint-space move of every finger from each step to the next ([`crate::route::SAMPLES`]
/// poses): the smallest radial distance, from the object's centre, of a point of a link
/// ([`LINK_SPACING`] apart) beyond the section (its candidates in polar form about the centre,
/// turned by the step's rotation, the radius interpolated between neighbouring candidates; the
/// section's chords lie inside that outline, so the check errs on the side of the object).
/// Negative: inside. The way points the pipeline's planner node adds around the object for
/// free fingers are checked where they are made ([`crate::route::Keepout`]).
pub fn link_clearance(scenario: &Scenario<'_>, steps: &[Step]) -> LinkClearance {
    let cands = scenario.problem.candidates();
    let mut outline: Vec<(Real, Real)> = cands
        .points
        .iter()
        .map(|p| {
            let v = p - scenario.centre;
            (v.y.atan2(v.x), v.xy().norm())
        })
        .collect();
    outline.sort_by(|a, b| a.0.total_cmp(&b.0));
    let largest = outline.iter().map(|o| o.1).fold(0.0, Real::max);
    // The section's radius at body angle `a`, between the neighbouring candidates.
    let radius = |a: Real| -> Real {
        let a = wrap(a);
        let n = outline.len();
        let k = outline.partition_point(|o| o.0 < a);
        let (lo, hi) = (outline[(k + n - 1) % n], outline[k % n]);
        let span = wrap(hi.0 - lo.0).rem_euclid(std::f64::consts::TAU);
        if span <= 0.0 {
            return lo.1.max(hi.1);
        }
        let s = (wrap(a - lo.0).rem_euclid(std::f64::consts::TAU) / span).clamp(0.0, 1.0);
        lo.1 + s * (hi.1 - lo.1)
    };
    let mut closest = LinkClearance {
        clearance: Real::INFINITY,
        finger: 0,
        link: 0,
        step: 0,
    };
    if outline.is_empty() {
        return closest;
    }
    let mut q = Vec::new();
    for (k, step) in steps.iter().enumerate() {
        let previous = if k > 0 { &steps[k - 1] } else { step };
        let theta = step.rotation;
        for (a, b) in previous.fingers.iter().zip(&step.fingers) {
            let f = scenario.finger(b.finger);
            let samples = if k > 0 { crate::route::SAMPLES } else { 1 };
            for i in 0..samples {
                let s = if samples > 1 {
                    i as Real / (samples - 1) as Real
                } else {
                    1.0
                };
                q.clear();
                q.extend(a.joints.iter().zip(&b.joints).map(|(x, y)| x + s * (y - x)));
                f.link_segments(&q, |link, from, to| {
                    // No point of a link far from the centre can beat the closest so far.
                    if crate::hand::segment_distance(&from, &to) - largest >= closest.clearance {
                        return;
                    }
                    let n = ((to - from).norm() / LINK_SPACING).ceil().max(1.0) as usize;
                    for j in 0..=n {
                        let p = from + (to - from) * (j as Real / n as Real);
                        let c = p.xy().norm() - radius(p.y.atan2(p.x) - theta);
                        if c < closest.clearance {
                            closest = LinkClearance {
                                clearance: c,
                                finger: b.finger,
                                link,
                                step: step.step,
                            };
                        }
                    }
                });
            }
        }
    }
    closest
}

/// The rolling-relation residuals `|r_f dgamma + s|` (m) of every finger that stays in
/// contact over a rolling step, with `gamma` recomputed from forward kinematics of the
/// planned joint angles and `s` the signed arc between its two contacts.
pub fn rolling_residuals(scenario: &Scenario<'_>, steps: &[Step]) -> Vec<Real> {
    let mut out = Vec::new();
    for w in steps.windows(2) {
        if w[1].phase != Phase::Rolling {
            continue;
        }
        for (a, b) in w[0].fingers.iter().zip(&w[1].fingers) {
            let (Some(ca), Some(cb)) = (a.contact, b.contact) else {
                continue;
            };
            let f = scenario.finger(a.finger);
            let gamma = |c: usize, rot: Real, q: &[Real]| {
                let (_, n) = scenario.world(c, rot);
                let phi = {
                    let axis = f.fk(q).cap_axis;
                    axis.y.atan2(axis.x)
                };
                wrap((-n.y).atan2(-n.x) - phi)
            };
            let ga = gamma(ca, w[0].rotation, &a.joints);
            let gb = gamma(cb, w[1].rotation, &b.joints);
            out.push((f.tip_radius * wrap(gb - ga) + scenario.arc(ca, cb)).abs());
        }
    }
    out
}

impl Scenario<'_> {
    /// The smallest squeeze reserve (m, up to [`SQUEEZE_PROBE`]) of any finger in contact at
    /// any of `steps`.
    pub(super) fn min_squeeze_reserve(&self, steps: &[Step]) -> Real {
        let mut least = SQUEEZE_PROBE;
        for step in steps {
            for f in &step.fingers {
                let Some(c) = f.contact else { continue };
                let finger = self.finger(f.finger);
                let r = self.squeeze_reserve(
                    finger,
                    c,
                    step.rotation,
                    &f.joints,
                    SQUEEZE_PROBE,
                    crate::hand::REACH_STEPS,
                );
                least = least.min(r);
            }
        }
        least
    }
}
