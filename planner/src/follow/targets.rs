//! The targets a follower commands: a plan's steps, rolling steps cut into sub-targets, and
//! the way points of a free finger around the object before it attaches and after it
//! detaches.

use icrflow_grasp::math::Real;

use super::{Estimate, LEAD, REPLAN_NS, ROTATION_TOLERANCE, SETTLED_TOLERANCE};
use crate::hand::{Capsule, Finger, Hand, gap, wrap};
use crate::planner::{Phase, Step};
use crate::rolling::{Surface, tip};
use crate::route::{self, Keepout};

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

/// One target a follower commands: a step of the plan or a sub-target of one.
#[derive(Debug, Clone, PartialEq)]
pub struct Target {
    /// The grasp to command.
    pub step: Step,
    /// A way point of a free finger (a stand-off pose, a pose on its route around the object,
    /// or its free pose before it sets off), or a detach step (the released finger at its free
    /// pose): reached only when the estimated joints of every free finger are at it, so that
    /// the finger goes from way point to way point along moves checked to stay outside the
    /// object and off the other fingers, and never cuts across; and the hand rolls on only
    /// once the released finger is home, out of the others' way.
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

    /// `step` as a target of its own, not passed on the way; a way point if it is a detach
    /// step (reached when the released finger is at its free pose).
    pub fn released(step: Step) -> Self {
        Self {
            way_point: step.phase == Phase::Detach,
            ..Self::at(step)
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

    /// Whether the hand is stuck short of the target, a rolling step: the estimate has two fingers
    /// or more in contact (the step's, or others: a finger that lost its contact after a slip) and
    /// the free fingers at their free pose, and the object, stopped (within
    /// [`STOPPED`](super::STOPPED)) for `stopped_ns` (>= [`REPLAN_NS`]), stands farther than
    /// `tolerance` from its rotation ([`SETTLED_TOLERANCE`]; the goal's
    /// [`GOAL_TOLERANCE`](super::GOAL_TOLERANCE)). A hand at its target does not turn the object
    /// on, so a follower would wait for ever.
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
/// (`surface`, turned as in `step`) and keep off the other fingers (`apart_by`: the gap to
/// them, at least [`route::FINGER_GAP`], or no less than at the leg's start where that is
/// less: two fingers of a switch touch the object side by side). `None` if there is none.
#[expect(
    clippy::too_many_arguments,
    reason = "the stand-off's search: the step, the finger, where it starts and what it keeps off"
)]
fn standoff(
    step: &Step,
    slot: usize,
    q: &[Real],
    distances: &[Real],
    legs: &[&[Real]],
    hand: &Hand,
    surface: &Surface,
    apart_by: &dyn Fn(&[Real]) -> Real,
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
                    legs.iter().all(|from| {
                        let floor = apart_by(from).min(route::FINGER_GAP);
                        outside(f, from, pose, r, surface, step.rotation)
                            && route::along(from, pose, |q| apart_by(q) >= floor)
                    })
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
/// or another finger on its way (the others as they stand in the step it moves before); the
/// detach step is reached with the released finger at its free pose. Between a stand-off and
/// the free pose a fingertip stays `clearance` (m) beyond the contact distance: farther than
/// the estimator's release distance, so that no passing finger is taken for a contact. Where a finger has no stand-off pose or no route, `note`
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
            out.push(Target::released(step.clone()));
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
        let Some(f) = hand.finger(a.finger) else {
            continue;
        };
        // Off the other fingers, as they stand while it moves (the base step's poses).
        let others: Vec<Capsule> = base
            .fingers
            .iter()
            .enumerate()
            .filter(|&(k, _)| k != slot)
            .filter_map(|(_, o)| {
                Some(
                    hand.finger(o.finger)?
                        .capsules(&o.joints, route::LINK_MARGIN),
                )
            })
            .flatten()
            .collect();
        let apart_by = |q: &[Real]| gap(&f.capsules(q, route::LINK_MARGIN), &others);
        let apart = |q: &[Real]| apart_by(q) >= route::FINGER_GAP;
        // Near the contact: the stand-off, reached straight from the contact pose.
        let Some(near) = standoff(
            base,
            slot,
            contact,
            &STANDOFFS,
            &[contact.as_slice()],
            hand,
            surface,
            &apart_by,
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
        let (start, end) = match step.phase {
            Phase::Attach => (free.clone(), near_q),
            _ => (near_q, free.clone()),
        };
        let way = match surface {
            // A circle: the fingertip beyond the contact's distance plus the clearance.
            Surface::Circle { .. } => {
                let touch = f.fk(contact).tip_centre.xy().norm();
                let reach = Keepout::new(touch + clearance, touch - f.tip_radius);
                route::route_with(f, &start, &end, reach.tip, |q| {
                    reach.holds(f, q) && apart(q)
                })
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
                            && apart(q)
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
