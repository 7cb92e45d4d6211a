//! How close the fingers come to the object and to each other: links and fingertips as
//! capsules, segment distances, and a plan's smallest link clearance and squeeze reserve.

use icrflow_grasp::math::{Real, Vec3};
use rayon::prelude::*;

use super::surface::Convex;
use super::{SpatialScenario, Touch};
use crate::hand::Finger;
use crate::planner::{Phase, SQUEEZE_PROBE, Step};

use crate::hand::Capsule;
pub use crate::hand::segment_segment_distance;
use crate::route::FINGER_GAP;

impl SpatialScenario<'_> {
    /// How close finger `f`'s links (as lines) come to the object's surface at `q` with the
    /// object at `theta` (m; negative inside), and which link.
    pub fn link_clearance(&self, f: &Finger, q: &[Real], theta: Real) -> (Real, usize) {
        let mut closest = (Real::INFINITY, 0);
        f.link_segments(q, |link, a, b| {
            let (a, b) = (self.to_body(theta, &a), self.to_body(theta, &b));
            let d = segment_surface_distance(self.surface, &a, &b);
            if d < closest.0 {
                closest = (d, link);
            }
        });
        closest
    }

    /// Which two fingers of `touches` (the others at their home poses) come closer than their
    /// fingertips' radii or their link capsules allow with [`FINGER_GAP`] between them, if
    /// any, with the object at `theta`; and any free finger at home in the object.
    pub(super) fn clash(&self, touches: &[Touch], theta: Real) -> Option<(String, [u32; 2])> {
        self.clash_with(touches, theta, FINGER_GAP)
    }

    /// [`Self::clash`] with `gap` (m) between two fingers beyond their radii.
    pub(super) fn clash_with(
        &self,
        touches: &[Touch],
        theta: Real,
        gap: Real,
    ) -> Option<(String, [u32; 2])> {
        let parts: Vec<(u32, Vec<Capsule>)> = self
            .hand
            .fingers
            .iter()
            .map(|f| {
                let q = touches
                    .iter()
                    .find(|t| t.finger == f.id)
                    .map_or(&f.home, |t| &t.q);
                (f.id, f.capsules(q, self.spatial.link_radius))
            })
            .collect();
        let parts: Vec<(u32, &[Capsule])> = parts.iter().map(|(id, c)| (*id, &c[..])).collect();
        touching(&parts, gap).or_else(|| self.home_in_object(touches, theta))
    }

    /// The hand's fingers as capsules with finger `moving` left out, the others at their poses
    /// in `touches` or at home (finger `ignore`, if any, nowhere: none of its capsules): what
    /// [`Self::clash_moving`] checks a finger moving among them against.
    pub(super) fn bodies_without(
        &self,
        moving: u32,
        touches: &[Touch],
        ignore: Option<u32>,
    ) -> Bodies {
        let fingers: Vec<(u32, Option<Vec<Capsule>>)> = self
            .hand
            .fingers
            .iter()
            .map(|f| {
                let caps = (f.id != moving).then(|| {
                    if ignore == Some(f.id) {
                        return Vec::new();
                    }
                    let q = touches
                        .iter()
                        .find(|t| t.finger == f.id)
                        .map_or(&f.home, |t| &t.q);
                    f.capsules(q, self.spatial.link_radius)
                });
                (f.id, caps)
            })
            .collect();
        let moving = fingers
            .iter()
            .position(|(_, c)| c.is_none())
            .unwrap_or(fingers.len());
        let still: Vec<(u32, &[Capsule])> = fingers
            .iter()
            .filter_map(|(id, c)| c.as_deref().map(|c| (*id, c)))
            .collect();
        let still_touch = touching(&still, FINGER_GAP).is_some();
        let spheres = fingers
            .iter()
            .map(|(_, c)| c.as_deref().filter(|c| !c.is_empty()).map(bounding_sphere))
            .collect();
        Bodies {
            fingers,
            moving,
            still_touch,
            spheres,
        }
    }

    /// [`Self::clash`] of `touches` and finger `moving` (its id and capsules), the others'
    /// capsules `bodies` ([`Self::bodies_without`] of `touches`, made once for a move); the
    /// check of the free fingers at home, the same at every pose of the move, is kept in
    /// `home` once made. The same answer as [`Self::clash`]'s: where the others hold apart,
    /// only the pairs with the moving finger are measured, in the same order, and a pair
    /// whose bounding spheres keep the gap is passed without measuring it.
    pub(super) fn clash_moving(
        &self,
        bodies: &Bodies,
        moving: (u32, &[Capsule]),
        touches: &[Touch],
        theta: Real,
        home: &mut Option<Option<(String, [u32; 2])>>,
    ) -> Option<(String, [u32; 2])> {
        // Finger `i` of the hand as it stands in this pose.
        let part = |i: usize| -> (u32, &[Capsule]) {
            let (id, caps) = &bodies.fingers[i];
            (*id, caps.as_deref().unwrap_or(moving.1))
        };
        let n = bodies.fingers.len();
        let pairs = if bodies.still_touch {
            let parts: Vec<(u32, &[Capsule])> = (0..n).map(part).collect();
            touching(&parts, FINGER_GAP)
        } else {
            let sphere = bounding_sphere(moving.1);
            let apart = |other: Option<(Vec3, Real)>| {
                other.is_some_and(|(c, r)| {
                    (c - sphere.0).norm() - r - sphere.1 > FINGER_GAP * (1.0 + 1e-9) + 1e-12
                })
            };
            let m = bodies.moving;
            (0..n)
                .filter(|&i| i != m && !apart(bodies.spheres[i]))
                .find_map(|i| {
                    let pair = if i < m {
                        [part(i), part(m)]
                    } else {
                        [part(m), part(i)]
                    };
                    touching(&pair, FINGER_GAP)
                })
        };
        pairs.or_else(|| {
            home.get_or_insert_with(|| self.home_in_object(touches, theta))
                .clone()
        })
    }

    /// A free finger (not in `touches`) whose fingertip or links at its home pose are in the
    /// object at `theta`, said.
    fn home_in_object(&self, touches: &[Touch], theta: Real) -> Option<(String, [u32; 2])> {
        for f in &self.hand.fingers {
            if touches.iter().any(|t| t.finger == f.id) {
                continue;
            }
            let tip = self.to_body(theta, &f.tip_centre(&f.home));
            let (clear, _) = self.link_clearance(f, &f.home, theta);
            let tip_clear = self.surface.closest(&tip).distance - f.tip_radius;
            if clear < self.spatial.link_radius || tip_clear < 0.0 {
                return Some((
                    format!(
                        "free finger {} at its home pose would be in the object",
                        f.id
                    ),
                    [f.id, f.id],
                ));
            }
        }
        None
    }

    /// The smallest squeeze reserve (m, up to [`SQUEEZE_PROBE`]) of any finger in contact at
    /// any of `steps`.
    pub(super) fn min_squeeze_reserve(&self, steps: &[Step]) -> Real {
        let mut least = SQUEEZE_PROBE;
        for step in steps {
            for fs in &step.fingers {
                let Some(n) = fs.normal else { continue };
                let f = self.finger(fs.finger);
                let n_w = self.rotation(step.rotation) * Vec3::from(n);
                least = least.min(f.reach_along(&fs.joints, &-n_w, SQUEEZE_PROBE));
            }
        }
        least
    }

    /// How close any finger's links (as lines) come to the object, at every step and along the
    /// moves between them ([`crate::route::SAMPLES`] poses per straight joint-space move, the
    /// object's rotation interpolated alike): a finger in contact in both steps, or free in both,
    /// straight; an attaching finger along its approach and a released finger along its retreat
    /// ([`Switch::approach`](crate::planner::Switch::approach),
    /// [`Switch::retreat`](crate::planner::Switch::retreat)): (distance m, finger, link, step).
    pub fn plan_link_clearance(&self, steps: &[Step]) -> (Real, u32, usize, usize) {
        // Each step's move on every core (rayon), the closest taken in the steps' order: the
        // same as one step after the other, at any thread count.
        let per_step: Vec<(Real, u32, usize, usize)> = (0..steps.len())
            .into_par_iter()
            .map(|k| self.move_link_clearance(steps, k))
            .collect();
        per_step
            .into_iter()
            .fold((Real::INFINITY, 0, 0, 0), |closest, here| {
                if here.0 < closest.0 { here } else { closest }
            })
    }

    /// [`Self::plan_link_clearance`] of the move into `steps[k]` alone.
    fn move_link_clearance(&self, steps: &[Step], k: usize) -> (Real, u32, usize, usize) {
        let mut closest = (Real::INFINITY, 0, 0, 0);
        let step = &steps[k];
        let previous = if k > 0 { &steps[k - 1] } else { step };
        let samples = if k > 0 { crate::route::SAMPLES } else { 1 };
        // The switch this move belongs to: attaching at `step`, or detaching after it.
        let switch = match step.phase {
            Phase::Attach => step.switch.as_ref(),
            Phase::Detach => previous.switch.as_ref(),
            _ => None,
        };
        for (a, b) in previous.fingers.iter().zip(&step.fingers) {
            let f = self.finger(b.finger);
            let vias: &[Vec<Real>] = match (switch, step.phase) {
                (Some(w), Phase::Attach) if w.attached == b.finger => {
                    w.approach.as_deref().unwrap_or_default()
                }
                (Some(w), Phase::Detach) if w.released == b.finger => {
                    w.retreat.as_deref().unwrap_or_default()
                }
                _ => &[],
            };
            // The way from a's joints to b's: an approach runs home -> vias -> contact, a
            // retreat the same way back (its vias listed from home).
            let mut way: Vec<&[Real]> = vec![&a.joints];
            if step.phase == Phase::Detach {
                way.extend(vias.iter().rev().map(Vec::as_slice));
            } else {
                way.extend(vias.iter().map(Vec::as_slice));
            }
            way.push(&b.joints);
            for pair in way.windows(2) {
                for i in 0..samples {
                    let s = if samples > 1 {
                        i as Real / (samples - 1) as Real
                    } else {
                        1.0
                    };
                    let q: Vec<Real> = pair[0]
                        .iter()
                        .zip(pair[1])
                        .map(|(x, y)| x + s * (y - x))
                        .collect();
                    let theta = previous.rotation + s * (step.rotation - previous.rotation);
                    let (d, link) = self.link_clearance(f, &q, theta);
                    if d < closest.0 {
                        closest = (d, b.finger, link, step.step);
                    }
                }
            }
        }
        closest
    }
}

/// The fingers a finger moves among ([`SpatialScenario::bodies_without`]).
pub(super) struct Bodies {
    /// Every finger of the hand by id, as capsules (`None`: the finger that moves).
    fingers: Vec<(u32, Option<Vec<Capsule>>)>,
    /// The moving finger's place in `fingers`.
    moving: usize,
    /// Whether two of the others touch (then every pair is measured, as [`touching`] does).
    still_touch: bool,
    /// Each other finger's bounding sphere (centre, radius), in the order of `fingers`.
    spheres: Vec<Option<(Vec3, Real)>>,
}

/// A sphere holding every capsule of `caps` (their ends' centroid, radius to the farthest end
/// plus that capsule's radius).
fn bounding_sphere(caps: &[Capsule]) -> (Vec3, Real) {
    let n = (2 * caps.len()).max(1) as Real;
    let centre = caps.iter().map(|c| c.from + c.to).sum::<Vec3>() / n;
    let radius = caps
        .iter()
        .map(|c| (c.from - centre).norm().max((c.to - centre).norm()) + c.radius)
        .fold(0.0, Real::max);
    (centre, radius)
}

/// The first two fingers of `parts` (each finger's capsules, in the hand's order) nearer than
/// their radii and `gap`, said.
fn touching(parts: &[(u32, &[Capsule])], gap: Real) -> Option<(String, [u32; 2])> {
    for (i, (a, sa)) in parts.iter().enumerate() {
        for (b, sb) in &parts[i + 1..] {
            for x in *sa {
                for y in *sb {
                    let d = segment_segment_distance(&x.from, &x.to, &y.from, &y.to);
                    if d < x.radius + y.radius + gap {
                        return Some((
                            format!(
                                "fingers {a} and {b} would touch ({:.2} mm apart where {:.2} mm is needed, their {:.2} mm and a gap of {:.2} mm)",
                                d * 1e3,
                                (x.radius + y.radius + gap) * 1e3,
                                (x.radius + y.radius) * 1e3,
                                gap * 1e3
                            ),
                            [*a, *b],
                        ));
                    }
                }
            }
        }
    }
    None
}

/// The distance of the segment `ab` (body frame) from the surface (m; negative: a point of it
/// inside, by how deep). Exact for a sphere; for the other surfaces the smallest signed
/// distance of the points along it found by a golden-section search, to within
/// [`TRACE_TOLERANCE`]: the signed distance from a convex body is a convex function of the
/// point (the largest of the affine `n . x - h(n)` over its supporting planes), so along the
/// segment it has one minimum, and it changes by at most the length moved. About 15 closest
/// points for a 50 mm link, where tracing it at 0.5 mm steps took up to a hundred.
pub fn segment_surface_distance(surface: &Convex, a: &Vec3, b: &Vec3) -> Real {
    match surface {
        Convex::Sphere { centre, radius } => point_segment_distance(centre, a, b) - radius,
        _ => {
            let at = |s: Real| surface.closest(&(a + (b - a) * s)).distance;
            let length = (b - a).norm();
            let (da, db) = (at(0.0), at(1.0));
            if length <= TRACE_TOLERANCE {
                return da.min(db);
            }
            // Golden section on [lo, hi] (fractions of the segment), the bracket of the
            // minimum, until it is shorter than the tolerance.
            const G: Real = 0.618_033_988_749_894_9;
            let (mut lo, mut hi) = (0.0, 1.0);
            let (mut x1, mut x2) = (hi - G * (hi - lo), lo + G * (hi - lo));
            let (mut f1, mut f2) = (at(x1), at(x2));
            let mut least = da.min(db).min(f1).min(f2);
            while (hi - lo) * length > TRACE_TOLERANCE {
                if f1 <= f2 {
                    hi = x2;
                    (x2, f2) = (x1, f1);
                    x1 = hi - G * (hi - lo);
                    f1 = at(x1);
                    least = least.min(f1);
                } else {
                    lo = x1;
                    (x1, f1) = (x2, f2);
                    x2 = lo + G * (hi - lo);
                    f2 = at(x2);
                    least = least.min(f2);
                }
            }
            least
        }
    }
}

/// How close (m) to the smallest distance of a link from an ellipsoid or a polyhedron
/// [`segment_surface_distance`] comes.
pub const TRACE_TOLERANCE: Real = 0.05e-3;

/// Distance from point `p` to segment `ab`.
fn point_segment_distance(p: &Vec3, a: &Vec3, b: &Vec3) -> Real {
    let ab = b - a;
    let len2 = ab.norm_squared();
    let t = if len2 > 0.0 {
        ((p - a).dot(&ab) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (a + ab * t - p).norm()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::spatial::surface;

    #[test]
    fn segment_distances() {
        let z = Vec3::zeros();
        let d = segment_segment_distance(
            &z,
            &Vec3::x(),
            &Vec3::new(0.5, 1.0, -1.0),
            &Vec3::new(0.5, 1.0, 1.0),
        );
        assert!((d - 1.0).abs() < 1e-15);
        let d = segment_segment_distance(
            &z,
            &Vec3::x(),
            &Vec3::new(2.0, 0.0, 0.0),
            &Vec3::new(3.0, 0.0, 0.0),
        );
        assert!((d - 1.0).abs() < 1e-15);
        let d =
            segment_segment_distance(&z, &z, &Vec3::new(0.0, 2.0, 0.0), &Vec3::new(0.0, 2.0, 0.0));
        assert!((d - 2.0).abs() < 1e-15);
        let s = Convex::Sphere {
            centre: z,
            radius: 1.0,
        };
        let d = segment_surface_distance(&s, &Vec3::new(-2.0, 1.5, 0.0), &Vec3::new(2.0, 1.5, 0.0));
        assert!((d - 0.5).abs() < 1e-15);
    }

    /// On an ellipsoid and a cube as a polyhedron, a segment's distance from the surface is
    /// the smallest of its points' to within TRACE_TOLERANCE (sampled every 0.01 mm): segments
    /// outside, grazing, and through the object.
    #[test]
    fn a_segment_s_distance_from_a_convex_surface_is_its_nearest_point_s() {
        let surfaces = [
            Convex::Ellipsoid {
                centre: Vec3::new(0.002, -0.001, 0.003),
                semi_axes: Vec3::new(0.055, 0.045, 0.04),
            },
            Convex::polyhedron(
                &icrflow_grasp::object::Object::cuboid(Vec3::new(0.03, 0.03, 0.03), 4).unwrap(),
            )
            .unwrap(),
        ];
        let mut next = surface::uniform(3);
        for s in &surfaces {
            for _ in 0..200 {
                let a = Vec3::new(next(), next(), next()) * 0.09;
                let b = a + Vec3::new(next(), next(), next()) * 0.06;
                let d = segment_surface_distance(s, &a, &b);
                let n = ((b - a).norm() / 1e-5).ceil() as usize;
                let sampled = (0..=n)
                    .map(|i| s.closest(&(a + (b - a) * (i as Real / n as Real))).distance)
                    .fold(Real::INFINITY, Real::min);
                assert!(
                    (d - sampled).abs() <= TRACE_TOLERANCE,
                    "{a} {b}: {d} vs {sampled}"
                );
            }
        }
    }
}
