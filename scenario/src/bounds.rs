//! The physical bounds of every numeric config value, and how numbers are printed in the
//! messages that name them.
//!
//! Each bound is a [`Range`] (or an [`Count`] for integers) with the reason for it; the same
//! reasons are in the configuration reference, `docs/configuration.md`, which lists every
//! bounded key ([`KEYS`]). A value outside is refused naming the key, the value (in
//! [`num`]'s notation) and the allowed range.

use std::fmt;

use anyhow::{Result, bail};
use icrflow_grasp::math::Real;

/// A number as messages print it: as written where that is short (`0.0475`, `360`, `-30.5`),
/// in scientific notation when very large or small (`1e300`, `1.5e-7`; Rust's `Display` would
/// print 1e300 as a 301-digit integer), and `NaN`, `inf`, `-inf`.
pub fn num(x: Real) -> String {
    if x.is_nan() {
        return "NaN".into();
    }
    if x.is_infinite() {
        return if x > 0.0 { "inf" } else { "-inf" }.into();
    }
    let a = x.abs();
    if a != 0.0 && !(1e-4..1e6).contains(&a) {
        format!("{x:e}")
    } else {
        format!("{x}")
    }
}

/// An interval of allowed values, its unit and why.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Range {
    /// Lower end.
    pub lo: Real,
    /// Whether the lower end itself is excluded.
    pub lo_open: bool,
    /// Upper end.
    pub hi: Real,
    /// Whether the upper end itself is excluded.
    pub hi_open: bool,
    /// Unit, as printed after the interval (may be empty).
    pub unit: &'static str,
    /// Why these bounds (printed in the error).
    pub why: &'static str,
}

impl Range {
    /// `[lo, hi]`.
    pub const fn closed(lo: Real, hi: Real, unit: &'static str, why: &'static str) -> Self {
        Self {
            lo,
            lo_open: false,
            hi,
            hi_open: false,
            unit,
            why,
        }
    }

    /// `(lo, hi]`.
    pub const fn above(lo: Real, hi: Real, unit: &'static str, why: &'static str) -> Self {
        Self {
            lo,
            lo_open: true,
            hi,
            hi_open: false,
            unit,
            why,
        }
    }

    /// `[lo, hi)`.
    pub const fn below(lo: Real, hi: Real, unit: &'static str, why: &'static str) -> Self {
        Self {
            lo,
            lo_open: false,
            hi,
            hi_open: true,
            unit,
            why,
        }
    }

    /// `(lo, hi)`.
    pub const fn open(lo: Real, hi: Real, unit: &'static str, why: &'static str) -> Self {
        Self {
            lo,
            lo_open: true,
            hi,
            hi_open: true,
            unit,
            why,
        }
    }

    /// The same interval with another upper end (a bound tied to another value).
    pub const fn up_to(self, hi: Real, why: &'static str) -> Self {
        Self { hi, why, ..self }
    }

    /// Whether `x` is inside (NaN never is).
    pub fn contains(&self, x: Real) -> bool {
        let lo = if self.lo_open {
            x > self.lo
        } else {
            x >= self.lo
        };
        let hi = if self.hi_open {
            x < self.hi
        } else {
            x <= self.hi
        };
        lo && hi
    }

    /// `x` if inside, else an error naming `key`, the value and the range.
    pub fn check(&self, key: &str, x: Real) -> Result<Real> {
        if !self.contains(x) {
            bail!("{key}: {} is not in the allowed range {self}", num(x));
        }
        Ok(x)
    }

    /// [`Range::check`] of an optional value, `default` when absent.
    pub fn or(&self, key: &str, x: Option<Real>, default: Real) -> Result<Real> {
        self.check(key, x.unwrap_or(default))
    }
}

impl fmt::Display for Range {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{}{}, {}{}",
            if self.lo_open { '(' } else { '[' },
            num(self.lo),
            num(self.hi),
            if self.hi_open { ')' } else { ']' }
        )?;
        if !self.unit.is_empty() {
            write!(f, " {}", self.unit)?;
        }
        if !self.why.is_empty() {
            write!(f, ": {}", self.why)?;
        }
        Ok(())
    }
}

/// A range of allowed counts (integers), inclusive, and why.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Count {
    /// Smallest.
    pub lo: u64,
    /// Largest.
    pub hi: u64,
    /// Why these bounds.
    pub why: &'static str,
}

impl Count {
    /// `lo..=hi`.
    pub const fn new(lo: u64, hi: u64, why: &'static str) -> Self {
        Self { lo, hi, why }
    }

    /// `n` if inside, else an error naming `key`, the value and the range.
    pub fn check(&self, key: &str, n: usize) -> Result<usize> {
        let x = n as u64;
        if x < self.lo || x > self.hi {
            bail!("{key}: {n} is not in the allowed range {self}");
        }
        Ok(n)
    }
}

impl fmt::Display for Count {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{} to {}", self.lo, self.hi)?;
        if !self.why.is_empty() {
            write!(f, ": {}", self.why)?;
        }
        Ok(())
    }
}

// ---------------------------------------------------------------------------------------------
// The bounds, section by section (docs/configuration.md gives the same reasons).

/// Every size of a primitive object (radius, semi-axis, half-extent, height).
pub const SIZE: Range = Range::closed(
    1e-3,
    1.0,
    "m",
    "objects a hand holds, a 1 mm bead to a 1 m ball",
);
/// Sphere and ellipsoid segments around (longitude).
pub const LONGITUDE: Count = Count::new(
    3,
    360,
    "at least a triangle; at most one per degree, so the mesh stays one the planner handles",
);
/// Sphere and ellipsoid segments from pole to pole (latitude).
pub const LATITUDE: Count = Count::new(
    2,
    180,
    "at least two bands; at most one per degree (360 x 180 = 64,800 facets: `validate` takes 0.4 s)",
);
/// Cuboid quads along each face edge.
pub const CUBOID_SEGMENTS: Count = Count::new(1, 64, "at most 6 x 64 x 64 = 24,576 quads");
/// Cylinder segments around the axis.
pub const CYLINDER_AROUND: Count =
    Count::new(3, 360, "at least a triangle; at most one per degree");
/// Cylinder segments along the axis.
pub const CYLINDER_ALONG: Count = Count::new(1, 100, "at most 100 bands (36,000 side quads)");

/// Coulomb friction coefficient.
pub const FRICTION: Range = Range::closed(
    0.0,
    2.0,
    "",
    "0 (frictionless) up to rubber on rubber (~1 to 2); no real fingertip has more",
);
/// Torque normalisation length.
pub const RHO: Range = Range::closed(1e-3, 1.0, "m", "the size of an object a hand holds");
/// Quality margin alpha.
pub const ALPHA: Range = Range::closed(
    0.0,
    2.24,
    "",
    "alpha* scales the object's wrenches into the grasp's, whose forces have unit normal components: at most sqrt(1 + mu^2) = 2.24 at mu = 2 (8 contacts around the paper's sphere reach 2.12)",
);
/// A contact's angle on the section.
pub const CONTACT_ANGLE: Range = Range::closed(-360.0, 360.0, "deg", "one turn either way");
/// A contact point's coordinates.
pub const CONTACT_POINT: Range = Range::closed(
    -10.0,
    10.0,
    "m",
    "the point must lie on the object's surface (checked when the object is built)",
);
/// A contact's angle on the fingertip cap.
pub const CAP_ANGLE: Range = Range::open(
    -180.0,
    180.0,
    "deg",
    "a point of the fingertip sphere's section",
);

/// Fingertip radius.
pub const FINGERTIP_RADIUS: Range = Range::closed(
    1e-3,
    0.1,
    "m",
    "fingertips of hands, human (~8 mm) to robot (~30 mm), with room either way",
);
/// Fingertip cap half-angle.
pub const CAP_HALF_ANGLE: Range =
    Range::open(0.0, 180.0, "deg", "some cap, at most the whole sphere");
/// Positions in the hand frame: a finger's base, the URDF root's placement.
pub const HAND_POSITION: Range = Range::closed(
    -1.0,
    1.0,
    "m",
    "a hand's parts lie within a metre of the object it holds",
);
/// Angles of the hand's description: yaw, roll-pitch-yaw, joint limits, home pose.
pub const HAND_ANGLE: Range = Range::closed(-360.0, 360.0, "deg", "one turn either way");
/// Fingers a pipeline message carries (`icrflow_interfaces::MAX_FINGERS`, which its tests
/// assert equal: this crate does not depend on the messages, and so not on iceoryx2).
pub const MESSAGE_FINGERS: usize = 8;
/// Joints per finger a pipeline message carries (`icrflow_interfaces::MAX_JOINTS`, likewise).
pub const MESSAGE_JOINTS: usize = 8;
/// Fingers of a hand.
pub const FINGERS: Count = Count::new(
    1,
    MESSAGE_FINGERS as u64,
    "the pipeline's messages carry at most icrflow_interfaces::MAX_FINGERS fingers",
);
/// Joints of a finger.
pub const JOINTS: Count = Count::new(
    1,
    MESSAGE_JOINTS as u64,
    "the pipeline's messages carry at most icrflow_interfaces::MAX_JOINTS joints per finger",
);
/// A link's length.
pub const LINK: Range = Range::closed(
    1e-3,
    0.5,
    "m",
    "finger links, human (~2 to 5 cm) to robot (~10 cm), with room either way",
);

/// Total object rotation of a plan.
pub const ROTATION: Range = Range::above(0.0, 36000.0, "deg", "at most 100 turns");
/// Object rotation per rolling step.
pub const STEP: Range = Range::above(
    0.0,
    30.0,
    "deg",
    "one rolling step is one straight joint-space move, and the planner refuses a joint that moves more than 28.6 deg in one; the paper's 5 deg is one candidate spacing of its sphere",
);
/// Margin from the edge of the fingertip cap.
pub const CAP_MARGIN: Range = Range::below(
    0.0,
    90.0,
    "deg",
    "it must leave some of the cap (and is checked against each finger's cap)",
);
/// Smallest admissible manipulability.
pub const MANIPULABILITY: Range = Range::closed(
    0.0,
    1.0,
    "m^2",
    "more than a three-link finger of 0.5 m links ever has (l1 l2 + l1 l3 + l2 l3 = 0.75 m^2)",
);
/// `plan.min_mobility_mm` (per rad).
pub const MOBILITY: Range = Range::closed(
    0.0,
    100.0,
    "mm/rad",
    "a fingertip 100 mm from every joint it moves by; the Allegro hand's fingers reach 20 to 60 in the middle of their ranges",
);
/// `plan.squeeze_reserve_mm`.
pub const SQUEEZE_RESERVE: Range = Range::closed(
    0.0,
    5.0,
    "mm",
    "the plan's summary measures the reserve up to 5 mm (icrflow_plan::planner::SQUEEZE_PROBE)",
);
/// `plan.region_erosion`.
pub const REGION_EROSION: Count = Count::new(
    0,
    3,
    "a ring is a candidate off each end of every region (5 deg on the paper's 72-candidate section): at 2 the paper's plan still turns a whole turn, at 3 it stops after 40 deg",
);
/// `plan.neighbour_rings`.
pub const NEIGHBOUR_RINGS: Count = Count::new(
    1,
    6,
    "every grasp of the plan is evaluated once per candidate within the rings of each contact (3 r (r + 1) / 2 of a triangle mesh's facets at r rings: 3, 9, 18, ...)",
);
/// Upper bound on plan steps.
pub const MAX_STEPS: Count = Count::new(
    1,
    1_000_000,
    "a trajectory is kept in memory and written out step by step",
);
/// `plan.max_plan_s`.
pub const MAX_PLAN: Range = Range::above(
    0.0,
    3600.0,
    "s",
    "a plan stops when its time has run out, short of its goal; the 5,040-triangle ellipsoid's 270 deg take about 24 s on two cores (42 s of CPU)",
);
/// Cap-angle grid of an attaching finger.
pub const ATTACH_RESOLUTION: Range = Range::closed(
    0.5,
    90.0,
    "deg",
    "each grid angle of each candidate of each switch is tried with a rolling-room simulation: at 0.5 deg the paper's plan takes twice as long as at 2 deg",
);

/// The plant's and the loop's rate.
pub const RATE: Range = Range::closed(
    10.0,
    2000.0,
    "Hz",
    "the measurement-to-command path takes ~150 us at p50 and up to ~400 us at p99 (BENCHMARKS.md): a faster tick starves the loop",
);
/// Joint speed limit.
pub const JOINT_SPEED: Range = Range::closed(
    1.0,
    720.0,
    "deg/s",
    "two turns a second, faster than the joints of dexterous hands (the Allegro hand's ~550 deg/s)",
);
/// Joint encoder noise.
pub const JOINT_NOISE: Range = Range::closed(
    0.0,
    0.1,
    "deg",
    "five standard deviations stay within the planner node's 1 deg way-point tolerance, and the fingertip's jitter (~0.26 mm at 0.1 deg on a 13 cm finger) within the estimator's 0.6 mm contact band",
);
/// Rate of the object-pose measurements (the upper end is `pipeline.rate_hz`).
pub const POSE_RATE: Range = Range::closed(
    1.0,
    2000.0,
    "Hz",
    "at least one correction a second; at most one per tick (pipeline.rate_hz)",
);
/// Object-pose noise.
pub const POSE_NOISE: Range = Range::closed(
    0.0,
    1.0,
    "deg",
    "the estimator's correction (gain 0.3) leaves ~0.4 of it in the estimate, which must stay well within the planner node's 2 deg settling tolerance",
);
/// Object-pose latency.
pub const POSE_LATENCY: Range = Range::closed(
    0.0,
    1000.0,
    "ms",
    "the plant and the estimator keep 4000 ticks of history (2 s at 2000 Hz) to delay and compensate a measurement",
);
/// The estimate's smoothed pose innovation over which the hand holds.
pub const POSE_INNOVATION: Range = Range::closed(
    0.5,
    45.0,
    "deg",
    "from just above what the pose noise leaves in the smoothed innovation to an error no grasp survives",
);
/// The fingertips' contact residual over which the hand holds.
pub const CONTACT_RESIDUAL: Range = Range::closed(
    0.1,
    10.0,
    "mm",
    "from the encoders' noise at the fingertip to a fingertip clearly off the object",
);
/// Silence after which `run` kills and restarts a node.
pub const HUNG_RESTART: Range = Range::closed(
    1.0,
    600.0,
    "s",
    "a node silent for half a second is reported at once; killing it sooner would take a slow start-up or a long plan for a hang",
);
/// Oldest input the hand command node acts on.
pub const INPUT_AGE: Range = Range::above(
    0.0,
    1000.0,
    "ms",
    "a command from a measurement more than a second old is not a closed loop",
);
/// Smallest commanded fingertip normal force.
pub const NORMAL_FORCE: Range = Range::closed(
    0.0,
    20.0,
    "N",
    "what a dexterous hand's fingertip presses continuously (~10 to 20 N)",
);
/// Longest hold a run waits through.
pub const MAX_HOLD: Range = Range::above(0.0, 3600.0, "s", "at most an hour");
/// A simulated slip.
pub const SLIP: Range = Range::closed(
    -90.0,
    90.0,
    "deg",
    "a knock, not a regrasp: the planner node plans again from where the object is",
);
/// When the slip happens.
pub const SLIP_AT: Range = Range::closed(0.0, 3600.0, "s", "within an hour of the start");
/// A push's force, its magnitude.
pub const PUSH_FORCE: Range = Range::closed(
    0.0,
    100.0,
    "N",
    "a knock, not a blow: 100 N is fifty times the ellipsoid's weight",
);
/// A push's torque, its magnitude.
pub const PUSH_TORQUE: Range = Range::closed(
    0.0,
    10.0,
    "N m",
    "a knock, not a blow: 10 N m turns the paper's sphere (2e-4 kg m^2) by hundreds of degrees in 50 ms if nothing held it",
);
/// When the push happens.
pub const PUSH_AT: Range = Range::closed(0.0, 3600.0, "s", "within an hour of the start");
/// How long the push lasts.
pub const PUSH_DURATION: Range = Range::closed(
    1.0,
    1000.0,
    "ms",
    "a knock, not a steady load: at most a second",
);

/// Frames per second of the recording.
pub const VISUALIZER_RATE: Range = Range::closed(
    1.0,
    200.0,
    "Hz",
    "a viewer draws at most its display's rate; faster frames only fill the queue and are dropped",
);
/// Frames waiting for the recording.
pub const VISUALIZER_QUEUE: Count = Count::new(
    1,
    4096,
    "frames are kept in memory; 4096 is over two minutes at 30 Hz",
);

/// `plant.timestep_ms`.
pub const TIMESTEP: Range = Range::closed(
    0.05,
    2.5,
    "ms",
    "MuJoCo's contacts need at most half their 5 ms time constant; below 0.05 ms the plant cannot keep real time",
);
/// `plant.gravity` (each component).
pub const GRAVITY: Range = Range::closed(-30.0, 30.0, "m/s^2", "up to three times the Earth's");
/// `plant.density`.
pub const DENSITY: Range =
    Range::closed(10.0, 25000.0, "kg/m^3", "from foam to the densest metals");
/// `plant.link_radius_mm`.
pub const LINK_RADIUS: Range = Range::closed(
    0.5,
    20.0,
    "mm",
    "a finger's phalanx; the planner keeps links 5 mm off the object",
);
/// `plant.kp`.
pub const KP: Range = Range::above(
    0.0,
    1000.0,
    "N m/rad",
    "a dexterous hand's joint servo (the Allegro's are ~1 to 10)",
);
/// `plant.kv`.
pub const KV: Range = Range::closed(0.0, 100.0, "N m s/rad", "the servos' damping");
/// `plant.noslip_iterations`.
pub const NOSLIP: Count = Count::new(
    0,
    100,
    "MuJoCo's no-slip solver after each step; a few do, each costs a solver pass",
);
/// `plant.squeeze_mm`.
pub const SQUEEZE: Range = Range::closed(
    0.0,
    5.0,
    "mm",
    "how far past the surface a pressing fingertip's servos aim; more crushes the grasp",
);
/// `plant.friction_margin`.
pub const FRICTION_MARGIN: Range = Range::below(
    0.0,
    1.0,
    "",
    "the fraction of mu the force targets leave unused at every contact",
);

/// A bound of the table [`KEYS`]: an interval or a count.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Bound {
    /// An interval of numbers.
    Range(Range),
    /// A range of counts.
    Count(Count),
}

impl Bound {
    /// The allowed values as the configuration reference writes them, without the reason:
    /// `[10, 2000] Hz`, `3 to 360`.
    pub fn allowed(&self) -> String {
        match self {
            Self::Range(r) => Range { why: "", ..*r }.to_string(),
            Self::Count(c) => Count { why: "", ..*c }.to_string(),
        }
    }
}

/// Every bounded key with its bound, in the order of the sections: what the configuration
/// reference (`docs/configuration.md`) lists, each on its row (a test of this crate checks
/// it does). A key of an array of tables is written with `[i]`
/// (`grasp.contacts[i].angle_deg`); a vector key's bound is each component's unless it says
/// otherwise (`pipeline.push_n`: its magnitude).
pub const KEYS: &[(&str, Bound)] = &[
    ("object.radius", Bound::Range(SIZE)),
    ("object.semi_axes", Bound::Range(SIZE)),
    ("object.half_extents", Bound::Range(SIZE)),
    ("object.height", Bound::Range(SIZE)),
    ("object.segments", Bound::Count(LONGITUDE)),
    ("object.segments", Bound::Count(LATITUDE)),
    ("object.segments", Bound::Count(CUBOID_SEGMENTS)),
    ("object.segments", Bound::Count(CYLINDER_AROUND)),
    ("object.segments", Bound::Count(CYLINDER_ALONG)),
    ("grasp.friction", Bound::Range(FRICTION)),
    ("grasp.alpha", Bound::Range(ALPHA)),
    ("grasp.rho", Bound::Range(RHO)),
    ("grasp.contacts[i].angle_deg", Bound::Range(CONTACT_ANGLE)),
    ("grasp.contacts[i].point", Bound::Range(CONTACT_POINT)),
    ("grasp.contacts[i].cap_angle_deg", Bound::Range(CAP_ANGLE)),
    ("hand.fingertip_radius", Bound::Range(FINGERTIP_RADIUS)),
    ("hand.cap_half_angle_deg", Bound::Range(CAP_HALF_ANGLE)),
    ("hand.urdf_origin", Bound::Range(HAND_POSITION)),
    ("hand.urdf_rpy_deg", Bound::Range(HAND_ANGLE)),
    ("hand.fingers", Bound::Count(FINGERS)),
    ("hand.fingers[i].base", Bound::Range(HAND_POSITION)),
    ("hand.fingers[i].base_yaw_deg", Bound::Range(HAND_ANGLE)),
    ("hand.fingers[i].links", Bound::Count(JOINTS)),
    ("hand.fingers[i].links", Bound::Range(LINK)),
    ("hand.fingers[i].limits_deg", Bound::Range(HAND_ANGLE)),
    ("hand.fingers[i].home_deg", Bound::Count(JOINTS)),
    ("hand.fingers[i].home_deg", Bound::Range(HAND_ANGLE)),
    (
        "hand.fingers[i].fingertip_radius",
        Bound::Range(FINGERTIP_RADIUS),
    ),
    ("plan.rotation_deg", Bound::Range(ROTATION)),
    ("plan.step_deg", Bound::Range(STEP)),
    ("plan.cap_margin_deg", Bound::Range(CAP_MARGIN)),
    ("plan.min_manipulability", Bound::Range(MANIPULABILITY)),
    ("plan.min_mobility_mm", Bound::Range(MOBILITY)),
    ("plan.max_steps", Bound::Count(MAX_STEPS)),
    ("plan.max_plan_s", Bound::Range(MAX_PLAN)),
    (
        "plan.attach_resolution_deg",
        Bound::Range(ATTACH_RESOLUTION),
    ),
    ("plan.squeeze_reserve_mm", Bound::Range(SQUEEZE_RESERVE)),
    ("plan.alpha", Bound::Range(ALPHA)),
    ("plan.neighbour_alpha", Bound::Range(ALPHA)),
    ("plan.neighbour_rings", Bound::Count(NEIGHBOUR_RINGS)),
    ("plan.region_erosion", Bound::Count(REGION_EROSION)),
    ("pipeline.rate_hz", Bound::Range(RATE)),
    ("pipeline.joint_speed_deg_s", Bound::Range(JOINT_SPEED)),
    ("pipeline.joint_noise_deg", Bound::Range(JOINT_NOISE)),
    ("pipeline.pose_rate_hz", Bound::Range(POSE_RATE)),
    ("pipeline.pose_noise_deg", Bound::Range(POSE_NOISE)),
    ("pipeline.pose_latency_ms", Bound::Range(POSE_LATENCY)),
    (
        "pipeline.max_pose_innovation_deg",
        Bound::Range(POSE_INNOVATION),
    ),
    (
        "pipeline.max_contact_residual_mm",
        Bound::Range(CONTACT_RESIDUAL),
    ),
    ("pipeline.hung_restart_s", Bound::Range(HUNG_RESTART)),
    ("pipeline.max_input_age_ms", Bound::Range(INPUT_AGE)),
    ("pipeline.min_normal_force", Bound::Range(NORMAL_FORCE)),
    ("pipeline.max_hold_s", Bound::Range(MAX_HOLD)),
    ("pipeline.slip_deg", Bound::Range(SLIP)),
    ("pipeline.slip_at_s", Bound::Range(SLIP_AT)),
    ("pipeline.push_n", Bound::Range(PUSH_FORCE)),
    ("pipeline.push_nm", Bound::Range(PUSH_TORQUE)),
    ("pipeline.push_at_s", Bound::Range(PUSH_AT)),
    ("pipeline.push_ms", Bound::Range(PUSH_DURATION)),
    ("plant.timestep_ms", Bound::Range(TIMESTEP)),
    ("plant.gravity", Bound::Range(GRAVITY)),
    ("plant.density", Bound::Range(DENSITY)),
    ("plant.link_radius_mm", Bound::Range(LINK_RADIUS)),
    ("plant.kp", Bound::Range(KP)),
    ("plant.kv", Bound::Range(KV)),
    ("plant.noslip_iterations", Bound::Count(NOSLIP)),
    ("plant.squeeze_mm", Bound::Range(SQUEEZE)),
    ("plant.friction_margin", Bound::Range(FRICTION_MARGIN)),
    ("visualizer.rate_hz", Bound::Range(VISUALIZER_RATE)),
    ("visualizer.queue", Bound::Count(VISUALIZER_QUEUE)),
];

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_print_short() {
        assert_eq!(num(1e300), "1e300");
        assert_eq!(num(-1e300), "-1e300");
        assert_eq!(num(1e11), "1e11");
        assert_eq!(num(1.5e-7), "1.5e-7");
        assert_eq!(num(0.0475), "0.0475");
        assert_eq!(num(360.0), "360");
        assert_eq!(num(-30.5), "-30.5");
        assert_eq!(num(0.0), "0");
        assert_eq!(num(Real::NAN), "NaN");
        assert_eq!(num(Real::INFINITY), "inf");
        assert_eq!(num(Real::NEG_INFINITY), "-inf");
    }

    #[test]
    fn the_step_bound_is_the_planner_s() {
        assert!((STEP.hi.to_radians() - icrflow_plan::planner::MAX_STEP).abs() < 1e-15);
    }

    #[test]
    fn ranges_say_key_value_and_range() {
        let e = RATE
            .check("pipeline.rate_hz", 1e11)
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with("pipeline.rate_hz: 1e11 is not in the allowed range [10, 2000] Hz: "),
            "{e}"
        );
        assert!(RATE.check("x", 2000.0).is_ok() && RATE.check("x", 10.0).is_ok());
        assert!(INPUT_AGE.check("x", 0.0).is_err() && INPUT_AGE.check("x", 1e-3).is_ok());
        assert!(RATE.check("x", Real::NAN).is_err());
        assert!(CAP_MARGIN.check("x", 90.0).is_err());
        let e = LONGITUDE
            .check("object.segments[0]", 2)
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with("object.segments[0]: 2 is not in the allowed range 3 to 360"),
            "{e}"
        );
    }

    /// Every bound of this file is some key's in [`KEYS`] (the table the configuration
    /// reference is checked against).
    #[test]
    fn every_bound_is_a_key_s() {
        let source = include_str!("bounds.rs");
        let table = &source[source.find("pub const KEYS").unwrap()..];
        let names: Vec<&str> = source
            .lines()
            .filter_map(|l| l.strip_prefix("pub const "))
            .filter(|l| l.contains(": Range") || l.contains(": Count"))
            .filter_map(|l| l.split(':').next())
            .collect();
        assert!(names.len() > 50, "{names:?}");
        for name in names {
            assert!(
                table.contains(&format!("Bound::Range({name})"))
                    || table.contains(&format!("Bound::Count({name})")),
                "{name} is no key's bound in KEYS"
            );
        }
    }
}
