//! Following a plan closed loop: the targets a hand is led through, and the [`Follower`] that
//! leads it from the estimated grasp.
//!
//! A plan's steps become [`targets`]: a rolling step is cut into sub-targets whose fingertip
//! poses are interpolated along the rolling motion and solved by inverse kinematics
//! ([`SUBSTEP`]); an attach step is preceded by way points of the attaching finger (its free
//! pose, its route around the object, its stand-off pose [`STANDOFF`] off the contact), a
//! detach step by those of the released finger, so that a finger never crosses the object.
//!
//! A spatial hand's plan is cut into its targets by [`crate::spatial::follow::targets`]; the
//! same [`Follower`] leads it ([`Planning::Spatial`]) and plans it again from the estimate
//! ([`crate::spatial::follow::replan`]).
//!
//! The [`Follower`] is a pure step: an [`Estimate`] of the grasp and the time in, the target to
//! command out. A target is commanded until the estimate has reached it (the same fingers in
//! contact and, for a rolling step, the object's rotation within [`ROTATION_TOLERANCE`] of
//! the target, or within [`SETTLED_TOLERANCE`] of it with the object settled or the hand at
//! the target's joints, [`HAND_AT_TARGET`]), then the next; a sub-target inside a rolling step
//! (not its last) is passed as soon as the object is within [`LEAD`] of it, so that the hand
//! rolls on while a physical object follows it a degree behind. The first estimate picks the
//! target nearest to it, so that a follower started again resumes rather than sends the hand
//! back.
//!
//! When the object stops short of a rolling step's target for good (it slipped in the hand,
//! or the rolling went astray: the estimate has two fingers or more in contact, the step's or
//! others, and the free fingers at their free pose, but the object has stood still for
//! [`REPLAN_NS`] farther than [`SETTLED_TOLERANCE`] from the target), the follower plans again
//! from the estimate ([`replan`]): from the estimated rotation, contacts, cap angles and
//! joints to the goal. The new plan's steps are numbered on from the last one; its first step
//! is a `Start`.

use std::fmt;

use icrflow_grasp::math::Real;

use crate::hand::{Finger, Hand, wrap};
use crate::planner::{Phase, Plan, PlanError, QUALITY_SLACK, Scenario, Settings, Start, Step};
use crate::rolling::{Surface, tip};
use crate::route::{self, Keepout};

/// How close the estimated rotation must come to a step's target (rad).
pub const ROTATION_TOLERANCE: Real = 0.3 * std::f64::consts::PI / 180.0;
/// Largest object rotation between two targets of a rolling step (rad): the step is cut into
/// sub-targets whose fingertip poses are interpolated along the rolling motion (centre and cap
/// angle) and solved by inverse kinematics, so that the hand follows the planned rolling
/// rather than a straight line in joint space that would lift the fingertips.
pub const SUBSTEP: Real = 0.5 * std::f64::consts::PI / 180.0;

/// How far from the object a finger comes to before it touches and goes to after it lets go
/// (m): it approaches and leaves along the surface normal, never through the object. Where
/// that pose is out of reach, the nearer ones of [`STANDOFFS`] are tried.
pub const STANDOFF: Real = 8e-3;
/// Stand-off distances tried, farthest first (m); all beyond the estimator's release distance.
pub const STANDOFFS: [Real; 4] = [STANDOFF, 6e-3, 4.5e-3, 3e-3];
/// Directions tried for a stand-off (rad from straight out of the object's centre through the
/// contact), straight out first: a finger at a joint limit may only be able to leave the
/// object sideways.
const SWINGS: [Real; 5] = [
    0.0,
    30.0_f64.to_radians(),
    -30.0_f64.to_radians(),
    60.0_f64.to_radians(),
    -60.0_f64.to_radians(),
];
/// Cap-angle changes tried at a stand-off pose (rad), the unchanged one first.
const CAP_TURNS: [Real; 7] = [
    0.0,
    10.0_f64.to_radians(),
    -10.0_f64.to_radians(),
    20.0_f64.to_radians(),
    -20.0_f64.to_radians(),
    35.0_f64.to_radians(),
    -35.0_f64.to_radians(),
];

/// How close a free finger's joints must come to a way point (rad), beyond the encoder noise
/// (five standard deviations of `pipeline.joint_noise_deg` are added: [`Tolerances::new`]).
pub const WAY_POINT_TOLERANCE: Real = 1.0 * std::f64::consts::PI / 180.0;
/// How far from a sub-target inside a rolling step the object may be for the target to count
/// as passed (rad): the hand goes on to the next while the object follows. With a
/// physical plant the object lags the hand's sub-target by about a degree at rest (the
/// contacts give under the squeeze and the tangential loads), and waiting for it to settle
/// at each sub-target ([`SETTLED_NS`]) crawled at 1 deg/s. The command then leads the object
/// by at most `LEAD` plus a [`SUBSTEP`]; an object that stops (a slip) stops the hand there,
/// and one that slipped ahead of it by more is held there too, to be planned again from.
pub const LEAD: Real = 1.5 * std::f64::consts::PI / 180.0;
/// How far short of a rolling step the object may settle and the step still count as reached
/// (rad); a hand held still farther away waits.
pub const SETTLED_TOLERANCE: Real = 2.0 * std::f64::consts::PI / 180.0;
/// How close the joints of the fingers in contact must come to a rolling target's for the
/// hand to count as there (rad), beyond the encoder noise (five standard deviations of
/// `pipeline.joint_noise_deg` are added: [`Tolerances::new`]): the rolling hand moves them on
/// by more between the sub-targets of a step.
pub const HAND_AT_TARGET: Real = 0.1 * std::f64::consts::PI / 180.0;
/// How close to the goal a run must turn the object (rad): the last target, stopped farther
/// short of it, is planned again from the estimate; `icrflow run` counts a run completed within
/// it.
pub const GOAL_TOLERANCE: Real = 0.5 * std::f64::consts::PI / 180.0;
/// How long the estimated rotation must stay within [`STOPPED`] for the object to count as
/// settled (ns).
pub const SETTLED_NS: u64 = 500_000_000;
/// How long the object must stand still short of a rolling step's target before the follower
/// plans again from the estimate (ns): longer than [`SETTLED_NS`], so that a step that settles
/// within [`SETTLED_TOLERANCE`] counts as reached first.
pub const REPLAN_NS: u64 = 1_000_000_000;
/// Band the estimated rotation must stay in for the object to count as stopped, for a settled
/// step and for a re-plan (rad): wider than the estimate's noise (the pose measurements' 0.2
/// deg, corrected with the estimator's gain), far narrower than a rolling hand turns it in
/// [`SETTLED_NS`] (~14 deg in the paper's run). A band of 0.05 deg, used for settling until
/// session 11, was never met through that noise: an object that stopped 0.3 to 2 deg short of
/// a step was neither reached nor re-planned, and the run waited for its timeout.
pub const STOPPED: Real = 0.5 * std::f64::consts::PI / 180.0;

/// The estimated grasp a plan is followed and made again from.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Estimate {
    /// The object's rotation about the vertical axis since the start (rad, unwrapped).
    pub rotation: Real,
    /// The hand's fingers, in the estimate's order.
    pub fingers: Vec<EstimatedFinger>,
}

/// One finger of an [`Estimate`].
#[derive(Debug, Clone, Default, PartialEq)]
pub struct EstimatedFinger {
    /// Finger number.
    pub finger: u32,
    /// Whether it touches the object.
    pub in_contact: bool,
    /// Its joint angles (rad).
    pub joints: Vec<Real>,
}

impl Estimate {
    /// The fingers in contact.
    pub fn touching(&self) -> impl Iterator<Item = u32> + '_ {
        self.fingers
            .iter()
            .filter(|f| f.in_contact)
            .map(|f| f.finger)
    }

    /// Whether the estimate has `step`'s fingers in contact (in the same order).
    pub fn same_contacts(&self, step: &Step) -> bool {
        self.touching().eq(fingers_in_contact(step))
    }

    /// The largest difference between the estimated joint angles of `step`'s fingers in
    /// contact (`in_contact`) or free, and their targets (rad; 0 if there is none).
    pub fn joint_error(&self, step: &Step, in_contact: bool) -> Real {
        step.fingers
            .iter()
            .filter(|f| f.contact.is_some() == in_contact)
            .filter_map(|f| {
                let e = self.fingers.iter().find(|e| e.finger == f.finger)?;
                Some(
                    f.joints
                        .iter()
                        .zip(&e.joints)
                        .fold(0.0_f64, |m, (t, q)| m.max((t - q).abs())),
                )
            })
            .fold(0.0, f64::max)
    }
}

/// The fingers in contact in a plan step.
pub fn fingers_in_contact(step: &Step) -> impl Iterator<Item = u32> + '_ {
    step.fingers
        .iter()
        .filter(|f| f.contact.is_some())
        .map(|f| f.finger)
}

/// One target a follower commands: a step of the plan or a sub-target of one.
#[derive(Debug, Clone, PartialEq)]
pub struct Target {
    /// The grasp to command.
    pub step: Step,
    /// A way point of a free finger (a stand-off pose, a pose on its route around the object,
    /// or its free pose before it sets off): reached only when the estimated joints of every
    /// free finger are at it, so that the finger goes from way point to way point along moves
    /// checked to stay outside the object, and never cuts across.
    pub way_point: bool,
    /// A sub-target inside a rolling step (not its last): passed as soon as the object is
    /// within [`LEAD`] of it ([`Target::reached`]), so that the hand rolls on without waiting
    /// for the object to settle at each.
    pub passing: bool,
}

impl Target {
    /// `step` as a target of its own (not a way point, not passed on the way).
    pub fn at(step: Step) -> Self {
        Self {
            step,
            way_point: false,
            passing: false,
        }
    }

    /// Whether the estimate has reached the target: its fingers in contact; for a rolling
    /// step its rotation within [`ROTATION_TOLERANCE`] (attaching and releasing a finger do
    /// not turn the object), or, `settled` (the object has stopped turning, or the hand is at
    /// the target's joints: [`Target::hand_at`]), within [`SETTLED_TOLERANCE`] of it (the
    /// rolling of a real hand never matches the plan exactly; waiting for the rest would wait
    /// for ever); for a way point, every free finger within `joint_tolerance` (rad) of it.
    pub fn reached(&self, e: &Estimate, settled: bool, joint_tolerance: Real) -> bool {
        let step = &self.step;
        let off = (e.rotation - step.rotation).abs();
        e.same_contacts(step)
            && (step.phase != Phase::Rolling
                || off <= ROTATION_TOLERANCE
                || (settled && off <= SETTLED_TOLERANCE)
                || (self.passing && off <= LEAD))
            && (!self.way_point || e.joint_error(step, false) <= joint_tolerance)
    }

    /// Whether the estimate has the fingers in contact in the target within `hand_tolerance`
    /// (rad) of its joints.
    pub fn hand_at(&self, e: &Estimate, hand_tolerance: Real) -> bool {
        e.joint_error(&self.step, true) <= hand_tolerance
    }

    /// Whether the hand is stuck short of the target, a rolling step: the estimate has two
    /// fingers or more in contact (the step's, or others: a finger that lost its contact after
    /// a slip) and the free fingers at their free pose, and the object, stopped (within
    /// [`STOPPED`]) for `stopped_ns` (>= [`REPLAN_NS`]), stands farther than `tolerance` from
    /// its rotation ([`SETTLED_TOLERANCE`]; the goal's [`GOAL_TOLERANCE`]). A hand at its
    /// target does not turn the object on, so a follower would wait for ever.
    pub fn stalled(
        &self,
        e: &Estimate,
        stopped_ns: u64,
        joint_tolerance: Real,
        tolerance: Real,
    ) -> bool {
        let step = &self.step;
        step.phase == Phase::Rolling
            && !self.way_point
            && stopped_ns >= REPLAN_NS
            && e.touching().count() >= 2
            && e.joint_error(step, false) <= joint_tolerance
            && (e.rotation - step.rotation).abs() > tolerance
    }
}

/// `step` with finger `slot` (not in contact in it) at a pose off the contact pose `q`:
/// the fingertip moved out along the line from the object's centre (the hand frame's origin),
/// or swung from it by one of [`SWINGS`], by the first of `distances` and [`CAP_TURNS`] whose
/// straight joint-space moves from every pose of `legs` stay outside the object
/// (`surface`, turned as in `step`). `None` if there is none.
fn standoff(
    step: &Step,
    slot: usize,
    q: &[Real],
    distances: &[Real],
    legs: &[&[Real]],
    hand: &Hand,
    surface: &Surface,
) -> Option<Step> {
    let f = hand.finger(step.fingers[slot].finger)?;
    let (x, y, phi) = f.planar_pose(q)?;
    let r = x.hypot(y);
    let q = SWINGS.iter().find_map(|swing| {
        // The direction out of the contact: away from the centre, swung by `swing`.
        let (sin, cos) = swing.sin_cos();
        let (ux, uy) = ((cos * x - sin * y) / r, (sin * x + cos * y) / r);
        distances.iter().find_map(|d| {
            CAP_TURNS.iter().find_map(|turn| {
                let ik = f.ik_planar(x + d * ux, y + d * uy, phi + turn, q);
                ik.ok().filter(|pose| {
                    legs.iter()
                        .all(|from| outside(f, from, pose, r, surface, step.rotation))
                })
            })
        })
    })?;
    let mut t = step.clone();
    t.fingers[slot].contact = None;
    t.fingers[slot].joints = q;
    Some(t)
}

/// Whether the fingertip of `f` stays off the object all along the straight joint-space line
/// from `a`, a contact pose, to `b`, as the hand moves between targets: never more than 0.2 mm
/// deeper than it is at `a` (a contact pose may press a fraction of a millimetre into the
/// surface: on a mesh, or planned again from an estimate), and its links
/// [`route::LINK_MARGIN`] off it. On a circular section (the sphere): the fingertip at least
/// `r` (less 0.2 mm) from the centre, `r` the contact pose's fingertip distance, and the links
/// beyond the circle of radius `r` less the fingertip's. On another section: the fingertip's
/// and the links' gaps to `surface` turned by `theta`.
fn outside(f: &Finger, a: &[Real], b: &[Real], r: Real, surface: &Surface, theta: Real) -> bool {
    match surface {
        Surface::Circle { .. } => route::clear(f, a, b, Keepout::new(r - 2e-4, r - f.tip_radius)),
        Surface::Curve(_) => {
            let floor = surface.contact_of(&tip(f, a), f, theta).gap.min(0.0) - 2e-4;
            route::along(a, b, |q| {
                surface.contact_of(&tip(f, q), f, theta).gap >= floor
                    && surface.link_gap(f, q, theta).0 >= route::LINK_MARGIN
            })
        }
    }
}

/// The plan's `steps` cut into the targets a follower commands (see [`SUBSTEP`]). An attach
/// step is preceded by way points of the attaching finger (its free pose, its route around
/// the object where needed ([`route`]), its stand-off pose), a detach step by those of the
/// released finger (its stand-off pose, its route), so that a finger never crosses the object
/// on its way. Between a stand-off and the free pose a fingertip stays `clearance` (m) beyond
/// the contact distance: farther than the estimator's release distance, so that no passing
/// finger is taken for a contact. Where a finger has no stand-off pose or no route, `note`
/// is told, and it moves straight.
pub fn targets(
    steps: &[Step],
    hand: &Hand,
    surface: &Surface,
    clearance: Real,
    note: &mut dyn FnMut(String),
) -> Vec<Target> {
    let mut out = Vec::with_capacity(steps.len() * 12);
    for (k, step) in steps.iter().enumerate() {
        if k > 0 && matches!(step.phase, Phase::Attach | Phase::Detach) {
            way_points(
                &steps[k - 1],
                step,
                hand,
                surface,
                clearance,
                note,
                &mut out,
            );
        }
        if k == 0 || step.phase != Phase::Rolling {
            out.push(Target::at(step.clone()));
            continue;
        }
        rolling(&steps[k - 1], step, hand, &mut out);
    }
    out
}

/// The way points before `step`, an attach or detach step after `prev`, onto `out`.
fn way_points(
    prev: &Step,
    step: &Step,
    hand: &Hand,
    surface: &Surface,
    clearance: Real,
    note: &mut dyn FnMut(String),
    out: &mut Vec<Target>,
) {
    for (slot, (a, b)) in prev.fingers.iter().zip(&step.fingers).enumerate() {
        // The free pose, the contact pose, and which way the finger goes between them.
        let (free, contact, base) = match (a.contact, b.contact, step.phase) {
            (None, Some(_), Phase::Attach) => (&a.joints, &b.joints, prev),
            (Some(_), None, Phase::Detach) => (&b.joints, &a.joints, step),
            _ => continue,
        };
        // Near the contact: the stand-off, reached straight from the contact pose.
        let Some(near) = standoff(
            base,
            slot,
            contact,
            &STANDOFFS,
            &[contact.as_slice()],
            hand,
            surface,
        ) else {
            note(format!(
                "step {}: no stand-off pose found for finger {}; it moves straight between the \
                 contact and its free pose",
                step.step, a.finger
            ));
            continue;
        };
        let near_q = near.fingers[slot].joints.clone();
        // Between it and the free pose, around the object where the straight move would come
        // close to it or cut through.
        let Some(f) = hand.finger(a.finger) else {
            continue;
        };
        let (start, end) = match step.phase {
            Phase::Attach => (free.clone(), near_q),
            _ => (near_q, free.clone()),
        };
        let way = match surface {
            // A circle: the fingertip beyond the contact's distance plus the clearance.
            Surface::Circle { .. } => {
                let touch = f.fk(contact).tip_centre.xy().norm();
                let reach = Keepout::new(touch + clearance, touch - f.tip_radius);
                route::route(f, &start, &end, reach)
            }
            // Another section: the fingertip's gap to it (turned as in the step) at least the
            // clearance, the links' at least the link margin, the roadmap beyond its farthest
            // point.
            Surface::Curve(_) => {
                let theta = base.rotation;
                route::route_with(
                    f,
                    &start,
                    &end,
                    surface.circumscribed() + f.tip_radius + clearance,
                    |q| {
                        surface.contact_of(&tip(f, q), f, theta).gap >= clearance
                            && surface.link_gap(f, q, theta).0 >= route::LINK_MARGIN
                    },
                )
            }
        };
        let way = way.unwrap_or_else(|| {
            note(format!(
                "step {}: no route found for finger {} around the object; it moves straight",
                step.step, f.id
            ));
            Vec::new()
        });
        let mut legs = Vec::with_capacity(way.len() + 2);
        if step.phase == Phase::Attach {
            // Free pose -> way points -> stand-off -> contact: the finger sets off from its
            // free pose only once it is there (it may still be on its way back from the last
            // switch).
            legs.push(prev.clone());
        }
        for q in way {
            let mut t = base.clone();
            t.fingers[slot].contact = None;
            t.fingers[slot].joints = q;
            legs.push(t);
        }
        if step.phase == Phase::Attach {
            legs.push(near);
        } else {
            legs.insert(0, near);
        }
        for mut via in legs {
            via.step = step.step;
            via.phase = step.phase;
            // On the way to the rendezvous too, the step says where it is.
            via.switch = step.switch.clone();
            out.push(Target {
                step: via,
                way_point: true,
                passing: false,
            });
        }
    }
}

/// The sub-targets of `step`, a rolling step after `prev`, onto `out`: the fingertip poses of
/// the fingers in contact interpolated along the rolling (centre and cap angle), solved by
/// inverse kinematics from the previous sub-target's joints.
fn rolling(prev: &Step, step: &Step, hand: &Hand, out: &mut Vec<Target>) {
    let turn = step.rotation - prev.rotation;
    // A whole number of sub-steps is that many, not one more for the rounding of the turn.
    let n = (turn.abs() / SUBSTEP - 1e-9).ceil().max(1.0) as usize;
    let mut near: Vec<Vec<Real>> = prev.fingers.iter().map(|f| f.joints.clone()).collect();
    for i in 1..=n {
        let s = i as Real / n as Real;
        let mut t = step.clone();
        t.rotation = prev.rotation + s * (step.rotation - prev.rotation);
        if i < n {
            for (slot, (a, b)) in prev.fingers.iter().zip(&step.fingers).enumerate() {
                let (Some(_), Some(_), Some(f)) = (a.contact, b.contact, hand.finger(a.finger))
                else {
                    continue;
                };
                let (qa, qb) = (&a.joints, &b.joints);
                let (Some((xa, ya, pa)), Some((xb, yb, pb))) =
                    (f.planar_pose(qa), f.planar_pose(qb))
                else {
                    continue;
                };
                let phi = pa + s * wrap(pb - pa);
                if let Ok(q) = f.ik_planar(xa + s * (xb - xa), ya + s * (yb - ya), phi, &near[slot])
                {
                    t.fingers[slot].joints = q.clone();
                    near[slot] = q;
                }
            }
        }
        out.push(Target {
            step: t,
            way_point: false,
            passing: i < n,
        });
    }
}

/// Why a plan could not be made again from an estimate.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum ReplanError {
    /// A finger in contact in the estimate is not in the hand.
    #[error("the estimate names finger {finger}, not in the hand")]
    UnknownFinger {
        /// The finger.
        finger: u32,
    },
    /// No finger of the estimate touches the object.
    #[error("the estimate has no finger in contact")]
    NoContact,
    /// A finger in contact does not move in the hand's plane.
    #[error("finger {finger} does not move in the hand's plane")]
    NotPlanar {
        /// The finger.
        finger: u32,
    },
    /// The planner refused the scenario made from the estimate.
    #[error(
        "from {:.2} deg (estimate {:.2} deg), contacts: {contacts}: {error}",
        .from.to_degrees(),
        .estimate.to_degrees()
    )]
    Planning {
        /// The rotation planned from: the estimate's, turned by the candidates' offset (rad).
        from: Real,
        /// The estimated rotation (rad).
        estimate: Real,
        /// The contacts planned from, described.
        contacts: String,
        /// Why the planner refused.
        error: PlanError,
    },
}

/// A plan made again from an estimate ([`replan`]).
#[derive(Debug, Clone)]
pub struct Replan {
    /// Its targets.
    pub targets: Vec<Target>,
    /// The plan, its steps turned back to the object's rotations.
    pub plan: Plan,
    /// The rotation offset it was planned with (rad).
    pub delta: Real,
    /// What [`targets`] noted (fingers without a stand-off or a route), and a plan made at
    /// the gate's margin ([`at_the_gate`]).
    pub notes: Vec<String>,
}

/// `plan(alpha)` at the plan's margin (`settings.alpha`); where the estimated grasp it starts
/// from keeps less than that but at least the gate's margin (`settings.gate_alpha`), at the
/// gate's, noted in `notes`: the plan's headroom is spent, the margin the hand is held to is
/// kept. (`plan` holds `Settings::neighbour_alpha` to at most the `alpha` it is given.)
pub(crate) fn at_the_gate(
    settings: &Settings,
    notes: &mut Vec<String>,
    mut plan: impl FnMut(Real) -> Result<Plan, PlanError>,
) -> Result<Plan, PlanError> {
    let gate = settings.gate_alpha;
    match plan(settings.alpha) {
        Err(PlanError::BelowMargin { quality, alpha })
            if gate < alpha && quality >= gate * (1.0 - QUALITY_SLACK) =>
        {
            notes.push(format!(
                "the estimated grasp keeps alpha* = {quality:.4}, below the plan's margin {alpha} but not the gate's {gate}: planned at the gate's"
            ));
            plan(gate)
        }
        other => other,
    }
}

/// A plan made again from the estimate `e` for `scenario` (its goal, settings and hand; its
/// initial contacts and start are replaced), its steps numbered from `first`, with its
/// [`targets`] on `surface` (`clearance` as there); `beat` is called as planning goes on.
///
/// The plan starts from the contacts of the estimated hand (forward kinematics of its joints,
/// the object at the estimated rotation `theta`), with their cap angles and the estimated
/// joints. The contacts lie between candidates (after a slip, anywhere), so the planner works
/// at the rotation `theta + delta` that puts them on candidates together: `delta`, within a
/// candidate spacing, makes the farthest of them from its nearest candidate the nearest (on a
/// circle, all of them on candidates), and those candidates are the contacts. The steps it
/// returns are turned back by `delta`, so that their rotations are the object's and their
/// fingertip poses the hand's. The goal is the scenario's: the last step turns the object to
/// it.
pub fn replan(
    scenario: &Scenario<'_>,
    e: &Estimate,
    surface: &Surface,
    first: usize,
    clearance: Real,
    beat: &mut dyn FnMut(),
) -> Result<Replan, ReplanError> {
    let hand = scenario.hand;
    let normals = &scenario.problem.candidates().normals;
    let joints = |ef: &EstimatedFinger, f: &Finger| -> Vec<Real> {
        ef.joints.iter().take(f.dof()).copied().collect()
    };
    // Each contact: its finger, its joints, and its normal's body angle (from the estimated
    // joints and rotation, not snapped to a candidate).
    let mut touching = Vec::with_capacity(e.fingers.len());
    for c in e.fingers.iter().filter(|c| c.in_contact) {
        let f = hand
            .finger(c.finger)
            .ok_or(ReplanError::UnknownFinger { finger: c.finger })?;
        let q = joints(c, f);
        let normal = surface.contact_of(&tip(f, &q), f, e.rotation).normal;
        touching.push((f, q, normal));
    }
    if touching.is_empty() {
        return Err(ReplanError::NoContact);
    }
    let angles: Vec<Real> = normals.iter().map(|n| n.y.atan2(n.x)).collect();
    let contact_angles: Vec<Real> = touching.iter().map(|(_, _, normal)| *normal).collect();
    let delta = offset(&contact_angles, &angles);
    let contacts: Vec<_> = touching
        .into_iter()
        .map(|(f, q, normal)| {
            let (candidate, _) = nearest(&angles, normal - delta);
            (f, candidate, q, wrap(normal - delta - angles[candidate]))
        })
        .collect();
    let theta = e.rotation + delta;
    let mut again = scenario.clone();
    again.initial = Vec::with_capacity(contacts.len());
    for (f, candidate, q, _) in &contacts {
        // The cap angle: from the fingertip's axis to the contact's inward normal.
        let (_, _, phi) = f
            .planar_pose(q)
            .ok_or(ReplanError::NotPlanar { finger: f.id })?;
        let n = normals[*candidate];
        let inward = n.y.atan2(n.x) + theta + std::f64::consts::PI;
        again
            .initial
            .push((f.id, *candidate, Some(wrap(inward - phi))));
    }
    again.start = Start {
        rotation: theta,
        joints: hand
            .fingers
            .iter()
            .filter_map(|f| {
                let ef = e.fingers.iter().find(|ef| ef.finger == f.id)?;
                Some((f.id, joints(ef, f)))
            })
            .collect(),
    };
    again.settings.goal += delta;
    let mut notes = Vec::new();
    let settings = again.settings.clone();
    let mut plan = at_the_gate(&settings, &mut notes, |alpha| {
        again.settings.alpha = alpha;
        again.settings.neighbour_alpha = settings.neighbour_alpha.map(|n| n.min(alpha));
        again.plan(&mut |_| beat())
    })
    .map_err(|error| ReplanError::Planning {
        from: theta,
        estimate: e.rotation,
        contacts: describe(&contacts, &again.initial, &angles),
        error,
    })?;
    for step in &mut plan.steps {
        step.step += first;
        step.rotation -= delta;
    }
    let targets = targets(&plan.steps, hand, surface, clearance, &mut |n| {
        notes.push(n)
    });
    Ok(Replan {
        targets,
        plan,
        delta,
        notes,
    })
}

/// The candidate nearest to the body angle `a` (rad) among the candidates' normal angles
/// `angles`, and how far it is (rad).
fn nearest(angles: &[Real], a: Real) -> (usize, Real) {
    angles
        .iter()
        .enumerate()
        .map(|(i, c)| (i, wrap(a - c).abs()))
        .min_by(|x, y| x.1.total_cmp(&y.1))
        .unwrap_or((0, f64::INFINITY))
}

/// The offset `delta` (rad) that puts the contacts, at the normal angles `normals`, nearest to
/// candidates (at `angles`, in order round the section) together: the worst one's distance
/// the least, tried from each contact's two nearest candidates (the estimator snaps each
/// contact on its own, and contacts halfway between two candidates would be snapped to
/// either side); equally near (to rounding), the smaller turn.
fn offset(normals: &[Real], angles: &[Real]) -> Real {
    let mut trials = Vec::with_capacity(2 * normals.len());
    for normal in normals {
        // The nearest candidate and the nearer of its neighbours.
        let (i, _) = nearest(angles, *normal);
        let off = |j: usize| wrap(normal - angles[j]);
        let (after, before) = (
            (i + 1) % angles.len(),
            (i + angles.len() - 1) % angles.len(),
        );
        let next = if off(after).abs() < off(before).abs() {
            after
        } else {
            before
        };
        trials.push(off(i));
        trials.push(off(next));
    }
    let worst = |delta: Real| {
        normals
            .iter()
            .map(|normal| nearest(angles, normal - delta).1)
            .fold(0.0, f64::max)
    };
    trials
        .into_iter()
        .min_by(|&a, &b| {
            let (wa, wb) = (worst(a), worst(b));
            if (wa - wb).abs() > 1e-9 {
                wa.total_cmp(&wb)
            } else {
                a.abs().total_cmp(&b.abs())
            }
        })
        .unwrap_or(0.0)
}

/// The contacts a plan was made again from, for a message: each finger, its candidate's angle,
/// how far off it the estimated contact is, and its cap angle.
fn describe(
    contacts: &[(&Finger, usize, Vec<Real>, Real)],
    initial: &[(u32, usize, Option<Real>)],
    angles: &[Real],
) -> String {
    let list: Vec<String> = contacts
        .iter()
        .zip(initial)
        .map(|((f, c, _, off), (_, _, gamma))| {
            format!(
                "finger {} at {:.1} deg ({:+.2} deg off it), cap angle {:.1} deg",
                f.id,
                angles[*c].to_degrees(),
                off.to_degrees(),
                gamma.unwrap_or(0.0).to_degrees()
            )
        })
        .collect();
    list.join("; ")
}

/// How close the estimate must come to a target's joints (rad): the constants plus five
/// standard deviations of the joint encoders' noise.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Tolerances {
    /// A free finger to a way point ([`WAY_POINT_TOLERANCE`] plus the noise).
    pub joint: Real,
    /// The fingers in contact to a rolling target ([`HAND_AT_TARGET`] plus the noise).
    pub hand: Real,
}

impl Tolerances {
    /// The tolerances under joint-encoder noise of standard deviation `joint_noise` (rad).
    pub fn new(joint_noise: Real) -> Self {
        Self {
            joint: WAY_POINT_TOLERANCE + 5.0 * joint_noise,
            hand: HAND_AT_TARGET + 5.0 * joint_noise,
        }
    }
}

/// Since when, at which rotation and on which target the object has been stopped (within
/// [`STOPPED`]).
#[derive(Debug, Clone, Copy)]
struct Stopped {
    /// Since when (ns); `None`: from the next estimate on (after a failed re-plan, whose
    /// planning took a while).
    since: Option<u64>,
    rotation: Real,
    target: usize,
}

/// What one estimate made a [`Follower`] do.
#[derive(Debug, Clone, Default)]
pub struct Followed {
    /// The first estimate: the follower starts (or resumes) at this target.
    pub resumed: Option<usize>,
    /// What followed from the estimate, if anything.
    pub event: Option<Event>,
}

impl Followed {
    /// The targets to command now, in order (an index equal to the number of targets: the
    /// plan is done).
    pub fn commands(&self) -> impl Iterator<Item = usize> + '_ {
        let then = match &self.event {
            Some(Event::Advanced(k)) => Some(*k),
            Some(Event::Replanned(_)) => Some(0),
            _ => None,
        };
        self.resumed.into_iter().chain(then)
    }
}

/// What an estimate changed.
#[derive(Debug, Clone)]
pub enum Event {
    /// The estimate reached its target; this one is next (the number of targets: done).
    Advanced(usize),
    /// The object stood still off the plan: it was planned again from the estimate, and its
    /// first target is commanded.
    Replanned(Box<Replanned>),
    /// The object stood still off the plan and planning again failed: the target is held, and
    /// planning is tried again after another [`REPLAN_NS`].
    ReplanFailed {
        /// The estimated rotation (rad).
        rotation: Real,
        /// The target's rotation (rad).
        target: Real,
        /// Why planning failed.
        error: ReplanError,
    },
}

/// A re-plan ([`Event::Replanned`]), for the record.
#[derive(Debug, Clone)]
pub struct Replanned {
    /// The estimated rotation it was planned from (rad).
    pub rotation: Real,
    /// The rotation of the target the object stopped short of (rad).
    pub target: Real,
    /// Re-plans so far, this one included.
    pub count: u32,
    /// The number of the new plan's first step.
    pub first: usize,
    /// The new plan's summary and steps.
    pub plan: Plan,
    /// The rotation offset it was planned with (rad).
    pub delta: Real,
    /// What [`targets`] noted.
    pub notes: Vec<String>,
}

impl fmt::Display for Replanned {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let p = &self.plan;
        let (rotation, target) = (self.rotation.to_degrees(), self.target.to_degrees());
        write!(
            f,
            "the object stopped at {rotation:.1} deg, {:+.1} deg off the target {target:.1} deg: \
             planned again from the estimate (re-plan {}: {} steps from step {}, {} switches, \
             {:.1} deg to go; the plan's candidates {:+.2} deg from the contacts)",
            rotation - target,
            self.count,
            p.steps.len(),
            self.first,
            p.summary.switches,
            (p.summary.goal - p.steps.first().map_or(0.0, |s| s.rotation) - self.delta)
                .to_degrees(),
            self.delta.to_degrees(),
        )
    }
}

impl fmt::Display for Event {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Event::Advanced(k) => write!(f, "on to target {k}"),
            Event::Replanned(r) => r.fmt(f),
            Event::ReplanFailed {
                rotation,
                target,
                error,
            } => write!(
                f,
                "the object stopped at {:.1} deg, off the target {:.1} deg, and planning again \
                 from the estimate failed: {error}",
                rotation.to_degrees(),
                target.to_degrees()
            ),
        }
    }
}

/// What a [`Follower`] plans with: a planar hand's scenario and the section its fingertips
/// roll on, or a spatial hand's scenario.
#[derive(Clone)]
pub enum Planning<'a> {
    /// The planar planner ([`Scenario`]) on the object's section.
    Planar(Scenario<'a>, &'a Surface),
    /// The spatial planner ([`crate::spatial`]).
    Spatial(crate::spatial::SpatialScenario<'a>),
}

impl Planning<'_> {
    /// The plan and its targets ([`targets`], [`crate::spatial::follow::targets`]).
    fn plan(
        &self,
        clearance: Real,
        note: &mut dyn FnMut(String),
        progress: &mut dyn FnMut(Real),
    ) -> Result<(Plan, Vec<Target>), PlanError> {
        Ok(match self {
            Self::Planar(scenario, surface) => {
                let plan = scenario.plan(progress)?;
                let targets = targets(&plan.steps, scenario.hand, surface, clearance, note);
                (plan, targets)
            }
            Self::Spatial(scenario) => {
                let plan = scenario.plan(progress)?;
                let targets = crate::spatial::follow::targets(&plan.steps, scenario);
                (plan, targets)
            }
        })
    }
}

/// Leads a hand through a plan from the estimated grasp: a pure step ([`Follower::on_estimate`]:
/// an estimate and the time in, the target to command out), with no I/O or clock inside.
pub struct Follower<'a> {
    /// The scenario planned, which re-plans start from.
    planning: Planning<'a>,
    clearance: Real,
    tolerances: Tolerances,
    targets: Vec<Target>,
    /// Whether the plan's last step is the goal (a plan made again may end short of it).
    ends_at_goal: bool,
    /// Plans made again from the estimate; 0 while the first plan is followed.
    replans: u32,
    /// The target being commanded; chosen from the first estimate (a restart resumes).
    current: Option<usize>,
    stopped: Stopped,
}

impl<'a> Follower<'a> {
    /// Whether the estimated object has turned past the last target's rotation, in the
    /// direction the plan turns it.
    fn past_goal(&self, e: &Estimate) -> bool {
        let (Some(first), Some(last)) = (self.targets.first(), self.targets.last()) else {
            return false;
        };
        let goal = last.step.rotation;
        let direction = (goal - first.step.rotation).signum();
        direction != 0.0 && (e.rotation - goal) * direction > 0.0
    }

    /// Plans `planning`'s scenario and follows the plan's targets ([`targets`], `clearance`
    /// and `note` as there; a spatial plan's, [`crate::spatial::follow::targets`]).
    pub fn new(
        planning: Planning<'a>,
        clearance: Real,
        tolerances: Tolerances,
        note: &mut dyn FnMut(String),
    ) -> Result<Self, PlanError> {
        Self::new_with(planning, clearance, tolerances, note, &mut |_| {})
    }

    /// [`Follower::new`], reporting the planning's progress to `progress` (the rotation
    /// planned so far, rad, as [`Scenario::plan`] does).
    pub fn new_with(
        planning: Planning<'a>,
        clearance: Real,
        tolerances: Tolerances,
        note: &mut dyn FnMut(String),
        progress: &mut dyn FnMut(Real),
    ) -> Result<Self, PlanError> {
        let (plan, targets) = planning.plan(clearance, note, progress)?;
        Ok(Self {
            planning,
            clearance,
            tolerances,
            targets,
            ends_at_goal: plan.summary.completed,
            replans: 0,
            current: None,
            stopped: Stopped {
                since: Some(0),
                rotation: f64::NAN,
                target: usize::MAX,
            },
        })
    }

    /// The targets being followed.
    pub fn targets(&self) -> &[Target] {
        &self.targets
    }

    /// The target being commanded (the number of targets: done); `None` before the first
    /// estimate.
    pub fn current(&self) -> Option<usize> {
        self.current
    }

    /// Plans made again from the estimate so far.
    pub fn replans(&self) -> u32 {
        self.replans
    }

    /// The target nearest to `e`: the same fingers in contact, the closest rotation, then the
    /// free fingers' nearest way point (a fresh run is at the start), so that a restarted
    /// follower never sends the hand back, and a free finger between two way points goes on
    /// to one of them, along the move checked between them.
    fn nearest(&self, e: &Estimate) -> usize {
        let steps = &self.targets;
        (0..steps.len())
            .filter(|&k| e.same_contacts(&steps[k].step))
            .min_by(|&a, &b| {
                let d = |k: usize| (e.rotation - steps[k].step.rotation).abs();
                let j = |k: usize| e.joint_error(&steps[k].step, false);
                d(a).total_cmp(&d(b))
                    .then(j(a).total_cmp(&j(b)))
                    .then(b.cmp(&a))
            })
            .unwrap_or(0)
    }

    /// Takes the estimate `e` at `now_ns` (ns, any monotonic clock): starts at the target
    /// nearest to the first one, moves on as it reaches a target, and plans again when the
    /// object has stopped off the plan for good (`beat` is called as that planning goes on).
    pub fn on_estimate(&mut self, e: &Estimate, now_ns: u64, beat: &mut dyn FnMut()) -> Followed {
        let mut out = Followed::default();
        let k = match self.current {
            Some(k) => k,
            None => {
                let k = self.nearest(e);
                self.current = Some(k);
                out.resumed = Some(k);
                k
            }
        };
        // Settled: the rotation has stayed within STOPPED for SETTLED_NS on this target. (The
        // first estimate restarts this, so it never re-plans: `resumed` and a re-plan never
        // come together.)
        if (e.rotation - self.stopped.rotation).abs() > STOPPED || self.stopped.target != k {
            self.stopped = Stopped {
                since: Some(now_ns),
                rotation: e.rotation,
                target: k,
            };
        }
        let since = *self.stopped.since.get_or_insert(now_ns);
        let stopped_ns = now_ns.saturating_sub(since);
        let n = self.targets.len();
        let tol = self.tolerances;
        // Or the hand is at the target's joints: the object, rolled by them, is where the
        // hand put it and goes no farther. After a re-plan it can stay about a degree off the
        // plan's rotation (the contacts are not where the plan has them); waiting SETTLED_NS
        // for each sub-target then crawled at 1 deg/s.
        let hand_there = k < n && self.targets[k].hand_at(e, tol.hand);
        // The last target, when it is the goal, is reached within ROTATION_TOLERANCE, or,
        // settled, anywhere past it (the hand cannot turn the object back; after a re-plan the
        // object can end a degree beyond the plan's rotation); stopped farther than
        // GOAL_TOLERANCE short of it, the object is turned on by a plan made again (a physical
        // hand's rolling turns the object a little less than the plan's, and the hand at the
        // goal turns it no farther). A plan that ends short of the goal ends as it settles.
        let settling = stopped_ns >= SETTLED_NS || hand_there;
        let goal = k + 1 == n && self.ends_at_goal;
        let settled = settling && !goal;
        let at_target = k < n
            && (self.targets[k].reached(e, settled, tol.joint)
                || (goal
                    && settling
                    && self.past_goal(e)
                    && e.same_contacts(&self.targets[k].step)));
        let short = if goal {
            GOAL_TOLERANCE
        } else {
            SETTLED_TOLERANCE
        };
        if k < n && !at_target && self.targets[k].stalled(e, stopped_ns, tol.joint, short) {
            // Stuck short of the target: plan again from the estimate.
            let target = self.targets[k].step.rotation;
            let first = self.targets[k].step.step + 1;
            let again = match &self.planning {
                Planning::Planar(scenario, surface) => {
                    replan(scenario, e, surface, first, self.clearance, beat)
                }
                Planning::Spatial(scenario) => {
                    let held = &self.targets[k].step;
                    crate::spatial::follow::replan(scenario, e, Some(held), first, beat)
                }
            };
            match again {
                Ok(again) => {
                    self.replans += 1;
                    self.targets = again.targets;
                    self.ends_at_goal = again.plan.summary.completed;
                    self.current = Some(0);
                    self.stopped = Stopped {
                        since: Some(now_ns),
                        rotation: e.rotation,
                        target: usize::MAX,
                    };
                    out.event = Some(Event::Replanned(Box::new(Replanned {
                        rotation: e.rotation,
                        target,
                        count: self.replans,
                        first,
                        plan: again.plan,
                        delta: again.delta,
                        notes: again.notes,
                    })));
                    return out;
                }
                Err(error) => {
                    // Tried again after another REPLAN_NS from the next estimate on (the
                    // planning took a while); the target is held.
                    self.stopped.since = None;
                    out.event = Some(Event::ReplanFailed {
                        rotation: e.rotation,
                        target,
                        error,
                    });
                }
            }
        }
        if at_target {
            self.current = Some(k + 1);
            out.event = Some(Event::Advanced(k + 1));
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::planner::Summary;

    fn settings(alpha: Real, gate_alpha: Real) -> Settings {
        crate::planner::tests::settings(alpha, gate_alpha, 0.1, 10)
    }

    /// A planner whose start keeps `quality`: refused below its margin, else an empty plan
    /// at the margin asked; the margins asked, in order.
    fn planned(quality: Real, s: &Settings) -> (Result<Plan, PlanError>, Vec<Real>, Vec<String>) {
        let mut asked = Vec::new();
        let mut notes = Vec::new();
        let r = at_the_gate(s, &mut notes, |alpha| {
            asked.push(alpha);
            if quality < alpha {
                return Err(PlanError::BelowMargin { quality, alpha });
            }
            let mut plan = Plan {
                summary: serde_json::from_value::<Summary>(serde_json::json!({
                    "completed": true, "stop_reason": null, "rotation_deg": 0.0,
                    "goal_deg": 0.0, "switches": 0, "steps": 0, "rolling_steps": 0,
                    "min_quality": quality, "alpha": alpha, "max_rolling_residual": 0.0,
                    "icr_region_candidates": 0, "lp_region_candidates": 0,
                    "lp_region_unsafe": 0, "brute_force_candidates": 0
                }))
                .unwrap(),
                steps: Vec::new(),
            };
            plan.summary.alpha = alpha;
            Ok(plan)
        });
        (r, asked, notes)
    }

    #[test]
    fn a_re_plan_between_the_two_margins_is_made_at_the_gate_s_below_it_refused() {
        let s = settings(0.12, 0.1);
        // Between the two: planned again at the gate's margin, and said so.
        let (r, asked, notes) = planned(0.11, &s);
        assert_eq!(r.unwrap().summary.alpha, 0.1);
        assert_eq!(asked, vec![0.12, 0.1]);
        assert_eq!(notes.len(), 1);
        assert!(
            notes[0].contains("0.1100") && notes[0].contains("gate"),
            "{notes:?}"
        );
        // Above the plan's: once, at the plan's.
        let (r, asked, notes) = planned(0.2, &s);
        assert_eq!(r.unwrap().summary.alpha, 0.12);
        assert_eq!((asked, notes.len()), (vec![0.12], 0));
        // Below the gate's: refused at the plan's margin, not tried again.
        let (r, asked, _) = planned(0.09, &s);
        assert!(matches!(r, Err(PlanError::BelowMargin { alpha, .. }) if alpha == 0.12));
        assert_eq!(asked, vec![0.12]);
        // No headroom (the margins equal): refused as it was.
        let (r, asked, _) = planned(0.09, &settings(0.1, 0.1));
        assert!(r.is_err());
        assert_eq!(asked, vec![0.1]);
    }
}
