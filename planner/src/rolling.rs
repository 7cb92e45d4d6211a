//! Rolling kinematics of fingertips on the object, as the simulated plant applies them and the
//! state estimator inverts them. The object turns about the vertical axis through its centre
//! of mass, held at the hand frame's origin; what touches the fingertips is its section by the
//! hand's plane ([`Surface`]).
//!
//! A fingertip of radius `r_f` in contact has its centre `C` (world, from the centre) on the
//! section offset by `r_f`, and its cap axis at world angle `phi`. With the contact's outward
//! normal `N` (world), its tangent `T = z x N` and the section's support `h = p . n` there
//! (the distance of the tangent line from the centre), rolling without slipping
//! (`r_f dgamma = -ds`, `ds` the arc length on the object, `gamma` the contact's angle on the
//! cap from its axis) gives the object's rotation from the fingertip's motion:
//! `dtheta = (dC . T - r_f dphi) / h`. (Differentiate `C = R(theta) (p(s) + r_f n(s))`:
//! `dC . T = dtheta (h + r_f) + (1 + r_f kappa) ds`, and `(1 + r_f kappa) ds =
//! r_f (dphi - dtheta)` from `gamma = theta + angle(n) + pi - phi`.) On a circle of radius
//! `r_o` (the paper's sphere) this is `dtheta = (1 + r_f / r_o) dpsi - (r_f / r_o) dphi`, `psi`
//! the fingertip centre's world angle, which is what [`Surface::Circle`] computes.

use icrflow_grasp::math::{UnitQuaternion, Vec3};
use icrflow_grasp::object::Section;
use nalgebra::Unit;

use crate::hand::{Finger, wrap};

/// Why an object's section cannot be rolled on, naming what is wrong.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum SurfaceError {
    /// Fewer than three samples.
    #[error(
        "the object's section in the hand's plane has {0} samples; rolling needs a closed curve"
    )]
    TooFewSamples(usize),
    /// A sample is NaN or infinite.
    #[error("the object's section has a sample that is not finite")]
    NotFinite,
    /// The section passes through the centre.
    #[error("the object's section passes through its centre: rolling needs a section around it")]
    ThroughCentre,
    /// A normal points towards the centre.
    #[error(
        "the object's section is not star-shaped about its centre (sample {0}: its normal points inwards)"
    )]
    NotStarShaped(usize),
    /// Two samples at one polar angle.
    #[error("the object's section has two samples at the same polar angle (sample {0})")]
    SamePolarAngle(usize),
    /// The normal turns back.
    #[error("the object's section is not convex: its normal turns back at sample {0}")]
    NotConvex(usize),
    /// The normal does not turn once around.
    #[error(
        "the object's section is not one convex loop about its centre (its normal turns {0:.1} degrees)"
    )]
    NotOneLoop(f64),
}

/// How far from the object's surface a fingertip in contact is taken to have left it (m): the
/// estimator's hysteresis against encoder noise, and what a free finger passing by keeps
/// clear of (the planner node's clearance is beyond it).
pub const RELEASE: f64 = 2e-3;

/// Where a fingertip is, seen from the object's centre.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Tip {
    /// The fingertip centre in the hand's plane, from the object's centre (m).
    pub centre: [f64; 2],
    /// World angle of the fingertip centre about the object's centre (rad).
    pub psi: f64,
    /// World angle of the cap axis (rad).
    pub phi: f64,
    /// Distance of the fingertip centre from the object's centre (m).
    pub distance: f64,
}

impl Tip {
    /// The same fingertip seen from an object whose centre has moved by `by` in the hand's
    /// plane (m): its centre, angle and distance taken from the moved centre.
    pub fn from_moved(self, by: [f64; 2]) -> Tip {
        let centre = [self.centre[0] - by[0], self.centre[1] - by[1]];
        Tip {
            centre,
            psi: centre[1].atan2(centre[0]),
            phi: self.phi,
            distance: centre[0].hypot(centre[1]),
        }
    }
}

/// The fingertip of `finger` at joint angles `q`.
pub fn tip(finger: &Finger, q: &[f64]) -> Tip {
    let (centre, cap) = finger.fk_tip(q);
    Tip {
        centre: [centre.x, centre.y],
        psi: centre.y.atan2(centre.x),
        phi: cap.y.atan2(cap.x),
        distance: centre.xy().norm(),
    }
}

/// Where a fingertip centre is against the section.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Contact {
    /// Signed distance of the fingertip centre beyond the section offset by the fingertip
    /// radius (m): 0 in contact, negative inside.
    pub gap: f64,
    /// Body angle of the outward normal at the nearest point of the section (rad).
    pub normal: f64,
    /// The section's support there, `p . n` (m, positive for a section around its centre).
    pub support: f64,
    /// The section sample nearest to that point.
    pub sample: usize,
}

/// The object's section by the hand's plane, around the object's centre.
#[derive(Debug, Clone)]
pub enum Surface {
    /// A circle of this radius (every sample at the same distance, normals radial): exact.
    Circle {
        /// Its radius (m).
        radius: f64,
        /// The section's sample angles (for the nearest sample).
        section: Section,
    },
    /// A closed convex curve through the samples, star-shaped about the centre: between two
    /// neighbouring samples the point's polar angle and radius and the normal's angle are
    /// interpolated linearly (exact on circles), as the planner's arc lengths assume a
    /// constant turn of the normal between samples.
    Curve(Curve),
}

/// What the pipeline's kinematic plant and its estimator roll fingertips on: a planar hand's
/// section of the object in its plane ([`Surface`], turned about the hand's z axis), or a
/// spatial hand's object turning about its plan's axis
/// ([`crate::spatial::rolling::Turning`]).
#[derive(Debug, Clone, Copy)]
pub enum Roller<'a> {
    /// The section in the hand's plane.
    Section(&'a Surface),
    /// The object in space.
    Space(crate::spatial::rolling::Turning<'a>),
}

impl Roller<'_> {
    /// The unit axis (hand frame) the object turns about.
    pub fn axis(&self) -> [f64; 3] {
        match self {
            Self::Section(_) => [0.0, 0.0, 1.0],
            Self::Space(t) => [t.axis.x, t.axis.y, t.axis.z],
        }
    }

    /// Signed distance of finger `finger`'s fingertip at `q` from the object at `theta`
    /// (m; 0 touching, negative inside).
    pub fn gap(&self, finger: &Finger, q: &[f64], theta: f64) -> f64 {
        match self {
            Self::Section(s) => s.contact_of(&tip(finger, q), finger, theta).gap,
            Self::Space(t) => t.contact_of(finger, q, theta).gap,
        }
    }

    /// How close the links of `finger` at `q` come to the object at `theta` (m, negative
    /// inside), and which link.
    pub fn link_gap(&self, finger: &Finger, q: &[f64], theta: f64) -> (f64, usize) {
        match self {
            Self::Section(s) => s.link_gap(finger, q, theta),
            Self::Space(t) => t.link_gap(finger, q, theta),
        }
    }

    /// The object's rotation implied by `finger` rolling from joints `qa` to `qb`, the object
    /// at `theta` before, as `(numerator, weight)`: over several fingers the object turns by
    /// the sums' quotient (on a section every finger weighs 1: the mean of what each
    /// implies; in space, the least squares of [`crate::spatial::rolling`]).
    pub fn turn(&self, finger: &Finger, qa: &[f64], qb: &[f64], theta: f64) -> (f64, f64) {
        match self {
            Self::Section(s) => (
                s.rotation(&tip(finger, qa), &tip(finger, qb), finger, theta),
                1.0,
            ),
            Self::Space(t) => t.turn(finger, qa, qb, theta),
        }
    }

    /// The object's orientation at `theta` as a unit quaternion `[w, x, y, z]`.
    pub fn orientation(&self, theta: f64) -> [f64; 4] {
        let [x, y, z] = self.axis();
        let (s, c) = (0.5 * theta).sin_cos();
        [c, s * x, s * y, s * z]
    }

    /// The object's rotation about the axis that orientation `q` (`[w, x, y, z]`) has: the
    /// angle of its twist about the axis (rad, in `(-pi, pi]`); `q`'s swing off the axis,
    /// which the object's model does not have, is left out.
    pub fn rotation_of(&self, q: [f64; 4]) -> f64 {
        twist(q, self.axis())
    }
}

/// The angle (rad, in `(-pi, pi]`) of orientation `q` (`[w, x, y, z]`) twisted about the unit
/// `axis`: its swing off the axis left out.
pub fn twist(q: [f64; 4], axis: [f64; 3]) -> f64 {
    let along = q[1] * axis[0] + q[2] * axis[1] + q[3] * axis[2];
    wrap(2.0 * along.atan2(q[0]))
}

/// The angle (rad) of rotation `q` off the unit `axis`: the angle of its swing, `q` with its
/// twist about the axis ([`twist`]) taken away. How far an object turned off the plan's axis.
pub fn tilt(q: &UnitQuaternion, axis: &Unit<Vec3>) -> f64 {
    let about = twist([q.w, q.i, q.j, q.k], [axis.x, axis.y, axis.z]);
    (q * UnitQuaternion::from_axis_angle(axis, about).inverse()).angle()
}

/// The samples of a [`Surface::Curve`], in order of increasing polar angle.
#[derive(Debug, Clone)]
pub struct Curve {
    /// Polar angle, unwrapped (increasing, spanning less than `2 pi` from the first).
    angle: Vec<f64>,
    /// Distance from the centre.
    radius: Vec<f64>,
    /// Angle of the outward normal, unwrapped along the ring.
    normal: Vec<f64>,
    /// The section sample of each entry.
    sample: Vec<usize>,
    /// Each entry's point and unit normal, Cartesian.
    point: Vec<[f64; 2]>,
    unit: Vec<[f64; 2]>,
    /// Smallest distance of the curve from the centre.
    inscribed: f64,
}

/// Relative tolerance within which a section is taken for a circle.
const ROUND: f64 = 1e-9;
/// Samples on each side of the one nearest in polar angle searched for the nearest point.
const WINDOW: usize = 8;
/// Points (beyond the first) at which a link is measured against a non-circular section.
pub const LINK_POINTS: usize = 12;
/// Most steps of the search for the foot of a point on a segment (it converges in a few).
const REFINE: usize = 12;

impl Surface {
    /// The surface of `section` (its samples relative to `centre`, the object's centre of
    /// mass); an error naming what is wrong if it is not one closed curve around the centre,
    /// convex, with outward normals.
    pub fn new(section: &Section, centre: [f64; 2]) -> Result<Self, SurfaceError> {
        let s = &section.samples;
        let n = s.points.len();
        if n < 3 {
            return Err(SurfaceError::TooFewSamples(n));
        }
        let mut entries: Vec<(f64, f64, f64, usize)> = (0..n)
            .map(|i| {
                let (x, y) = (s.points[i].x - centre[0], s.points[i].y - centre[1]);
                let nrm = s.normals[i];
                (y.atan2(x), x.hypot(y), nrm.y.atan2(nrm.x), i)
            })
            .collect();
        if entries
            .iter()
            .any(|e| !(e.0.is_finite() && e.1.is_finite() && e.2.is_finite()))
        {
            return Err(SurfaceError::NotFinite);
        }
        let (r_min, r_max) = entries
            .iter()
            .fold((f64::INFINITY, 0.0_f64), |(lo, hi), e| {
                (lo.min(e.1), hi.max(e.1))
            });
        if r_min <= 0.0 {
            return Err(SurfaceError::ThroughCentre);
        }
        // Every normal must point away from the centre: the section encloses it.
        for e in &entries {
            if wrap(e.2 - e.0).abs() >= 0.5 * std::f64::consts::PI {
                return Err(SurfaceError::NotStarShaped(e.3));
            }
        }
        if r_max - r_min <= ROUND * r_max && entries.iter().all(|e| wrap(e.2 - e.0).abs() <= ROUND)
        {
            return Ok(Self::Circle {
                radius: r_max,
                section: section.clone(),
            });
        }
        entries.sort_by(|a, b| a.0.total_cmp(&b.0));
        let mut angle = Vec::with_capacity(n);
        let mut radius = Vec::with_capacity(n);
        let mut normal = Vec::with_capacity(n);
        let mut sample = Vec::with_capacity(n);
        for (k, e) in entries.iter().enumerate() {
            let a = e.0;
            let nu = match normal.last() {
                None => e.2,
                Some(&prev) => prev + wrap(e.2 - prev),
            };
            if k > 0 && a <= angle[k - 1] {
                return Err(SurfaceError::SamePolarAngle(e.3));
            }
            if k > 0 && nu < normal[k - 1] {
                return Err(SurfaceError::NotConvex(e.3));
            }
            angle.push(a);
            radius.push(e.1);
            normal.push(nu);
            sample.push(e.3);
        }
        let turn = normal[n - 1] - normal[0] + wrap(normal[0] - normal[n - 1]);
        if (turn - std::f64::consts::TAU).abs() > 1e-6 {
            return Err(SurfaceError::NotOneLoop(turn.to_degrees()));
        }
        let point = angle
            .iter()
            .zip(&radius)
            .map(|(a, r)| [r * a.cos(), r * a.sin()])
            .collect();
        let unit = normal.iter().map(|nu| [nu.cos(), nu.sin()]).collect();
        Ok(Self::Curve(Curve {
            angle,
            radius,
            normal,
            sample,
            point,
            unit,
            inscribed: r_min,
        }))
    }

    /// What it is, for the user: "a circle of radius 47.5 mm" or "a convex section of 72
    /// samples, 45.0 to 55.0 mm from the centre".
    pub fn describe(&self) -> String {
        match self {
            Self::Circle { radius, .. } => format!("a circle of radius {:.1} mm", radius * 1e3),
            Self::Curve(c) => format!(
                "a convex section of {} samples, {:.1} to {:.1} mm from the centre",
                c.angle.len(),
                c.inscribed * 1e3,
                self.circumscribed() * 1e3
            ),
        }
    }

    /// Largest distance of the section from the centre (m).
    pub fn circumscribed(&self) -> f64 {
        match self {
            Self::Circle { radius, .. } => *radius,
            Self::Curve(c) => c.radius.iter().fold(0.0, |m: f64, &r| m.max(r)),
        }
    }

    /// Smallest distance of the section from the centre (m).
    pub fn inscribed(&self) -> f64 {
        match self {
            Self::Circle { radius, .. } => *radius,
            Self::Curve(c) => c.inscribed,
        }
    }

    /// Where the fingertip centre at body point `c` (from the centre) is against the section,
    /// for a fingertip of radius `r_f`.
    pub fn contact(&self, c: [f64; 2], r_f: f64) -> Contact {
        match self {
            Self::Circle { radius, section } => {
                let a = c[1].atan2(c[0]);
                Contact {
                    gap: c[0].hypot(c[1]) - radius - r_f,
                    normal: a,
                    support: *radius,
                    sample: section.nearest_angle(a).map_or(0, |(i, _)| i),
                }
            }
            Self::Curve(curve) => curve.contact(c, r_f),
        }
    }

    /// The contact of tip `t` with the object turned by `theta`.
    pub fn contact_of(&self, t: &Tip, finger: &Finger, theta: f64) -> Contact {
        let (sin, cos) = (-theta).sin_cos();
        let body = [
            cos * t.centre[0] - sin * t.centre[1],
            sin * t.centre[0] + cos * t.centre[1],
        ];
        self.contact(body, finger.tip_radius)
    }

    /// How close the links of `finger` at `q` come to the object turned by `theta` (m,
    /// negative inside), and which link. On a circle: their distance from the centre less the
    /// radius; otherwise, links nearer the centre than the section's farthest point are
    /// measured against the section at [`LINK_POINTS`] points each.
    pub fn link_gap(&self, finger: &Finger, q: &[f64], theta: f64) -> (f64, usize) {
        let (d, link) = finger.link_distance(q);
        let far = self.circumscribed();
        match self {
            Self::Circle { radius, .. } => (d - radius, link),
            Self::Curve(_) if d >= far => (d - far, link),
            Self::Curve(_) => {
                let (sin, cos) = (-theta).sin_cos();
                let mut closest = (f64::INFINITY, link);
                finger.link_segments(q, |link, a, b| {
                    for i in 0..=LINK_POINTS {
                        let t = i as f64 / LINK_POINTS as f64;
                        let (x, y) = (a.x + t * (b.x - a.x), a.y + t * (b.y - a.y));
                        let body = [cos * x - sin * y, sin * x + cos * y];
                        let gap = self.contact(body, 0.0).gap;
                        if gap < closest.0 {
                            closest = (gap, link);
                        }
                    }
                });
                closest
            }
        }
    }

    /// The object's rotation implied by a fingertip rolling from `a` to `b`, the object at
    /// `theta` when the fingertip was at `a`.
    pub fn rotation(&self, a: &Tip, b: &Tip, finger: &Finger, theta: f64) -> f64 {
        match self {
            Self::Circle { radius, .. } => {
                let k = finger.tip_radius / radius;
                (1.0 + k) * wrap(b.psi - a.psi) - k * wrap(b.phi - a.phi)
            }
            Self::Curve(_) => {
                let c = self.contact_of(a, finger, theta);
                let (sin, cos) = (theta + c.normal).sin_cos();
                let along = (b.centre[0] - a.centre[0]) * -sin + (b.centre[1] - a.centre[1]) * cos;
                (along - finger.tip_radius * wrap(b.phi - a.phi)) / c.support
            }
        }
    }
}

impl Curve {
    /// The entry `k` taken around the ring (any integer), with its angles unwrapped by whole
    /// turns so that consecutive entries increase.
    fn entry(&self, k: isize) -> (f64, f64, f64, usize) {
        let n = self.angle.len() as isize;
        let turns = k.div_euclid(n) as f64 * std::f64::consts::TAU;
        let i = k.rem_euclid(n) as usize;
        (
            self.angle[i] + turns,
            self.radius[i],
            self.normal[i] + turns,
            self.sample[i],
        )
    }

    /// The point and normal angle at `t` in `[0, 1]` between entries `k` and `k + 1`.
    fn at(&self, k: isize, t: f64) -> ([f64; 2], f64) {
        let (a0, r0, n0, _) = self.entry(k);
        let (a1, r1, n1, _) = self.entry(k + 1);
        let (a, r) = (a0 + t * (a1 - a0), r0 + t * (r1 - r0));
        ([r * a.cos(), r * a.sin()], n0 + t * (n1 - n0))
    }

    /// `(c - B(t)) . T(t)` for the offset point `B = p + r_f n` at `t` of segment `k` and the
    /// tangent `T = z x n`: positive while the foot of `c` lies further along the curve.
    fn along(&self, k: isize, t: f64, c: [f64; 2], r_f: f64) -> f64 {
        let (p, nu) = self.at(k, t);
        let (sin, cos) = nu.sin_cos();
        -(c[0] - p[0] - r_f * cos) * sin + (c[1] - p[1] - r_f * sin) * cos
    }

    fn contact(&self, c: [f64; 2], r_f: f64) -> Contact {
        let n = self.angle.len() as isize;
        // The sample nearest in polar angle, then the nearest offset sample around it.
        let a = c[1].atan2(c[0]);
        let start = self.angle.partition_point(|&x| x < a) as isize;
        let mut best = (f64::INFINITY, start);
        for k in start - WINDOW as isize..=start + WINDOW as isize {
            let i = k.rem_euclid(n) as usize;
            let (dx, dy) = (
                c[0] - self.point[i][0] - r_f * self.unit[i][0],
                c[1] - self.point[i][1] - r_f * self.unit[i][1],
            );
            let d = dx * dx + dy * dy;
            if d < best.0 {
                best = (d, k);
            }
        }
        // The foot of `c` on the segment after it or the one before, where `along` changes
        // sign (regula falsi, Illinois variant; `along` is monotone on a convex curve).
        let k = if self.along(best.1, 0.0, c, r_f) >= 0.0 {
            best.1
        } else {
            best.1 - 1
        };
        let (mut t0, mut g0) = (0.0, self.along(k, 0.0, c, r_f));
        let (mut t1, mut g1) = (1.0, self.along(k, 1.0, c, r_f));
        let t = if g0 <= 0.0 {
            0.0
        } else if g1 >= 0.0 {
            1.0
        } else {
            let mut t = t0;
            for _ in 0..REFINE {
                t = t0 - g0 * (t1 - t0) / (g1 - g0);
                let g = self.along(k, t, c, r_f);
                if g.abs() <= 1e-15 {
                    break;
                }
                if (g > 0.0) == (g0 > 0.0) {
                    (t0, g0) = (t, g);
                    g1 *= 0.5;
                } else {
                    (t1, g1) = (t, g);
                    g0 *= 0.5;
                }
            }
            t
        };
        let (p, nu) = self.at(k, t);
        let (sin, cos) = nu.sin_cos();
        let gap = (c[0] - p[0]) * cos + (c[1] - p[1]) * sin - r_f;
        let sample = self.entry(if t < 0.5 { k } else { k + 1 }).3;
        Contact {
            gap,
            normal: nu,
            support: p[0] * cos + p[1] * sin,
            sample,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use icrflow_grasp::math::Vec3;
    use icrflow_grasp::object::Object;

    #[test]
    fn the_tilt_is_what_is_not_about_the_axis() {
        let axis = nalgebra::Unit::new_normalize(Vec3::new(0.2, 1.0, 0.2));
        // About the axis only: no tilt, however far.
        for a in [0.3, 2.0, -3.0] {
            let q = UnitQuaternion::from_axis_angle(&axis, a);
            assert!(tilt(&q, &axis) < 1e-12, "{a}");
        }
        // 5 deg about an axis at right angles to it, before and after a turn about it.
        let across = nalgebra::Unit::new_normalize(axis.cross(&Vec3::x()));
        let off = UnitQuaternion::from_axis_angle(&across, 5f64.to_radians());
        for a in [0.0, 1.0, 2.5] {
            let q = off * UnitQuaternion::from_axis_angle(&axis, a);
            assert!((tilt(&q, &axis).to_degrees() - 5.0).abs() < 1e-9, "{a}");
        }
    }

    fn ellipse() -> (Object, Surface) {
        let o = Object::ellipsoid(Vec3::new(0.055, 0.045, 0.04), 72, 36).unwrap();
        let s = Surface::new(&o.section, [o.centre_of_mass.x, o.centre_of_mass.y]).unwrap();
        (o, s)
    }

    #[test]
    fn a_sphere_is_a_circle_and_an_ellipsoid_a_curve() {
        let o = Object::sphere(0.0475, 72, 72).unwrap();
        let s = Surface::new(&o.section, [0.0, 0.0]).unwrap();
        assert!(matches!(s, Surface::Circle { radius, .. } if (radius - 0.0475).abs() < 1e-12));
        let (_, e) = ellipse();
        assert!(matches!(e, Surface::Curve(_)));
        assert!((e.inscribed() - 0.045).abs() < 1e-4, "{}", e.inscribed());
    }

    /// The section of the polar curve `r(a)` at `n` samples, with its outward normals.
    fn polar(n: usize, r: impl Fn(f64) -> (f64, f64)) -> Section {
        use icrflow_grasp::object::{Adjacency, SurfaceSamples};
        let (mut points, mut normals, mut angles) = (Vec::new(), Vec::new(), Vec::new());
        for k in 0..n {
            let a = std::f64::consts::TAU * k as f64 / n as f64;
            let (r, dr) = r(a);
            let (s, c) = a.sin_cos();
            let t = Vec3::new(dr * c - r * s, dr * s + r * c, 0.0);
            points.push(Vec3::new(r * c, r * s, 0.0));
            normals.push(Vec3::new(t.y, -t.x, 0.0).normalize());
            angles.push(a);
        }
        let lists: Vec<Vec<u32>> = (0..n as u32)
            .map(|k| vec![(k + n as u32 - 1) % n as u32, (k + 1) % n as u32])
            .collect();
        Section {
            samples: SurfaceSamples {
                points,
                normals,
                areas: vec![1e-3; n],
                adjacency: Adjacency::from_lists(&lists),
            },
            angles,
            height: 0.0,
        }
    }

    #[test]
    fn sections_the_plant_cannot_roll_on_are_refused_by_what_is_wrong() {
        // A flower: star-shaped about its centre, not convex.
        let flower = polar(72, |a| {
            (0.05 + 0.01 * (5.0 * a).cos(), -0.05 * (5.0 * a).sin())
        });
        let e = Surface::new(&flower, [0.0, 0.0]).unwrap_err().to_string();
        assert!(e.contains("not convex"), "{e}");
        // The same ellipse about a centre outside it.
        let (o, _) = ellipse();
        let e = Surface::new(&o.section, [0.2, 0.0])
            .unwrap_err()
            .to_string();
        assert!(e.contains("not star-shaped"), "{e}");
        // Too few samples.
        let e = Surface::new(&polar(2, |_| (0.05, 0.0)), [0.0, 0.0])
            .unwrap_err()
            .to_string();
        assert!(e.contains("2 samples"), "{e}");
        // A circle given as a polar curve is a circle.
        let round = Surface::new(&polar(36, |_| (0.05, 0.0)), [0.0, 0.0]).unwrap();
        assert!(matches!(round, Surface::Circle { .. }));
    }

    #[test]
    fn the_contact_of_an_offset_point_is_where_it_was_offset_from() {
        let (_, s) = ellipse();
        let r_f = 0.025;
        // Points of the analytic ellipse, offset along its normal by r_f + gap.
        for k in 0..50 {
            let t = k as f64 * 0.1257 + 0.05;
            let (a, b) = (0.055, 0.045);
            let p = [a * t.cos(), b * t.sin()];
            let nu = (a * t.sin()).atan2(b * t.cos());
            for gap in [0.0, 1e-3, -1e-3] {
                let c = [p[0] + (r_f + gap) * nu.cos(), p[1] + (r_f + gap) * nu.sin()];
                let got = s.contact(c, r_f);
                // The samples are 5 degrees apart: the interpolated curve is within ~0.1 mm of
                // the ellipse, its normal within a fraction of a degree.
                assert!((got.gap - gap).abs() < 1e-4, "t {t} gap {gap}: {got:?}");
                assert!(
                    wrap(got.normal - nu).abs() < 0.5f64.to_radians(),
                    "t {t}: {got:?}"
                );
                let support = p[0] * nu.cos() + p[1] * nu.sin();
                assert!((got.support - support).abs() < 1e-4, "t {t}: {got:?}");
            }
        }
    }

    #[test]
    fn a_tip_rolled_on_the_ellipse_turns_it_by_what_the_kinematics_say() {
        // A fingertip rolling without slipping on a fixed body turned by theta: integrate the
        // exact motion, and check that the rotation recovered from the tip's motion alone
        // matches the object's.
        let (o, s) = ellipse();
        let r_f = 0.025;
        let finger = crate::paper::hand().fingers[0].clone();
        let finger = Finger {
            tip_radius: r_f,
            ..finger
        };
        let _ = o;
        // The contact at body parameter u, the object at theta, the cap angle gamma: the tip
        // centre and cap axis in the world.
        let (a, b) = (0.055_f64, 0.045_f64);
        let pose = |u: f64, theta: f64, gamma: f64| {
            let p = [a * u.cos(), b * u.sin()];
            let nu = (a * u.sin()).atan2(b * u.cos()) + theta;
            let (st, ct) = theta.sin_cos();
            let pw = [ct * p[0] - st * p[1], st * p[0] + ct * p[1]];
            let centre = [pw[0] + r_f * nu.cos(), pw[1] + r_f * nu.sin()];
            let phi = nu + std::f64::consts::PI - gamma;
            Tip {
                centre,
                psi: centre[1].atan2(centre[0]),
                phi: wrap(phi),
                distance: centre[0].hypot(centre[1]),
            }
        };
        let arc = |u: f64| (a * a * u.sin().powi(2) + b * b * u.cos().powi(2)).sqrt();
        // The object turns by 0.5 mrad per step while the contact moves by du: rolling gives
        // r_f dgamma = -ds.
        let (mut u, mut theta, mut gamma, mut est) = (0.3_f64, 0.0_f64, 0.0_f64, 0.0_f64);
        for _ in 0..400 {
            let before = pose(u, theta, gamma);
            let du = 2e-3;
            gamma -= arc(u + 0.5 * du) * du / r_f;
            u += du;
            let dtheta = 5e-4;
            let at = theta;
            theta += dtheta;
            let after = pose(u, theta, gamma);
            est += s.rotation(&before, &after, &finger, at);
        }
        assert!((est - theta).abs() < 0.01 * theta.abs(), "{est} vs {theta}");
    }
}
