//! Following a spatial plan: the targets a spatial hand is led through ([`targets`]), the
//! spatial counterpart of [`crate::follow::targets`], which the same [`crate::follow::Follower`]
//! commands.
//!
//! - **Rolling steps** are cut into sub-targets of at most [`SUBSTEP`] of the object's
//!   rotation. Each finger rolling in both steps has its joints interpolated along the straight
//!   line in joint space between the steps' (the line the hand's servos follow between two set
//!   points), then its fingertip put back on the surface at the sub-target's rotation by
//!   Newton steps of its centre along the normal (least joint motion, the joint limits kept):
//!   the straight line between a plan's 5 degree steps leaves the fingertip up to 0.6 mm off
//!   the surface, the sub-targets a few micrometres. Between two sub-targets the line's
//!   departure is about 1/100 of that.
//! - **Attach and detach steps** are preceded by way points: an attaching finger's free pose
//!   (it sets off only once there), then its approach ([`crate::planner::Switch::approach`]:
//!   the lifted poses the planner checked clear of the object and of the other fingers); a
//!   released finger's retreat through the same poses in reverse
//!   ([`crate::planner::Switch::retreat`]) before its free pose (unlike a planar hand's, the
//!   detach step is reached once the finger is off the object: it goes home from its last
//!   retreat pose as the others roll on). The planner's lifts are at
//!   least 3 mm, beyond the estimator's release distance, so no way point is taken for a
//!   contact.

use icrflow_grasp::math::{Real, Vec3};
use nalgebra::{DMatrix, DVector};

use super::SpatialScenario;
use super::rolling::Turning;
use crate::follow::{Estimate, Replan, ReplanError, SUBSTEP, Target};
use crate::hand::Finger;
use crate::planner::{Phase, Step};

/// Newton steps that put an interpolated fingertip back on the surface.
const PROJECTIONS: usize = 4;

/// How near the surface a projected fingertip is left (m).
const ON_SURFACE: Real = 1e-7;

/// Where a plan's targets go as its steps are settled, with the margin it is planned at
/// ([`replan_streamed`]).
pub type HandOn<'f> = &'f mut dyn FnMut(&[Target], Real);

/// The plan's `steps` of `scenario` cut into the targets a follower commands (the module's
/// rules).
pub fn targets(steps: &[Step], scenario: &SpatialScenario<'_>) -> Vec<Target> {
    targets_with(steps, scenario, &mut || {})
}

/// [`targets`], calling `beat` at every step (the sub-targets' Newton steps of a whole plan
/// take a fraction of a second, which a node planning again reports through).
pub fn targets_with(
    steps: &[Step],
    scenario: &SpatialScenario<'_>,
    beat: &mut dyn FnMut(),
) -> Vec<Target> {
    let mut out = Vec::with_capacity(steps.len() * 12);
    targets_after(None, steps, scenario, &mut out, beat);
    out
}

/// The targets of `steps`, a plan's steps after `prev` (the step before them, whose targets
/// were made; `None`: the plan's first steps), onto `out`: [`targets`] of a plan handed on a
/// part at a time (the parts' targets, one after the other, are the whole plan's).
pub fn targets_after(
    prev: Option<&Step>,
    steps: &[Step],
    scenario: &SpatialScenario<'_>,
    out: &mut Vec<Target>,
    beat: &mut dyn FnMut(),
) {
    let turning = scenario.turning();
    for (k, step) in steps.iter().enumerate() {
        beat();
        let before = if k == 0 { prev } else { Some(&steps[k - 1]) };
        let Some(before) = before else {
            out.push(Target::at(step.clone()));
            continue;
        };
        if matches!(step.phase, Phase::Attach | Phase::Detach) {
            way_points(before, step, out);
        }
        if step.phase != Phase::Rolling {
            out.push(Target::at(step.clone()));
            continue;
        }
        rolling(before, step, scenario, &turning, out);
    }
}

/// A spatial plan made again from the estimate `e` for `scenario` (its goal, settings and
/// hand; its initial contacts and start replaced), its steps numbered from `first`, with its
/// [`targets`]; `beat` is called as planning goes on. Each finger the estimate has in contact
/// starts where its fingertip touches the object at the estimated rotation (the surface point
/// nearest its centre), placed by inverse kinematics from its joints (the nearest pose touching
/// there: the hand does not jump): those `commanded` (the target the follower held, when it has
/// the finger in contact too), else the estimated ones. A finger pressing on the object stands
/// a little short of its commanded joints, held there by the contact's forces; set off from
/// where it stands, the hand would let go of what it presses with, and the object, turned back
/// by as much, would come no nearer (tried: the Allegro's sphere in MuJoCo, 1.4 degrees short
/// of the goal, got 0.3 degrees nearer per plan made again). The plan starts at the
/// estimated rotation, and the free fingers at their free pose, where the follower plans
/// again only; it goes at most [`crate::follow::REPLAN_HORIZON`] on. The contacts are not snapped to candidates (the spatial planner rolls on the
/// surface, its contacts' candidates the nearest ones), so the offset is 0.
pub fn replan(
    scenario: &SpatialScenario<'_>,
    e: &Estimate,
    commanded: Option<&Step>,
    first: usize,
    beat: &mut dyn FnMut(),
) -> Result<Replan, ReplanError> {
    replan_streamed(scenario, e, commanded, first, &mut |_| beat(), None)
}

/// [`replan`], with `progress` called with the rotation planned so far, and, if given,
/// `settled` handed the new plan's targets a part at a time as its steps are settled
/// ([`SpatialScenario::plan_streamed`]), with the margin it is planned at (the plan's, or the
/// gate's: [`crate::follow::Replan::notes`]); the [`Replan`]'s targets are then those parts'.
pub fn replan_streamed(
    scenario: &SpatialScenario<'_>,
    e: &Estimate,
    commanded: Option<&Step>,
    first: usize,
    progress: &mut dyn FnMut(Real),
    mut settled: Option<HandOn<'_>>,
) -> Result<Replan, ReplanError> {
    let turning = scenario.turning();
    let mut again = scenario.clone();
    again.initial = Vec::with_capacity(e.fingers.len());
    again.start_joints = Vec::with_capacity(e.fingers.len());
    let mut described = Vec::with_capacity(e.fingers.len());
    for c in e.fingers.iter().filter(|c| c.in_contact) {
        let f = scenario
            .hand
            .finger(c.finger)
            .ok_or(ReplanError::UnknownFinger { finger: c.finger })?;
        let held = commanded.and_then(|s| {
            s.fingers
                .iter()
                .find(|h| h.finger == c.finger && h.contact.is_some())
        });
        let q: Vec<Real> = match held {
            Some(h) => h.joints.iter().take(f.dof()).copied().collect(),
            None => c.joints.iter().take(f.dof()).copied().collect(),
        };
        let touch = turning.contact_of(f, &q, e.rotation);
        described.push(format!(
            "finger {} at [{:.1}, {:.1}, {:.1}] mm ({:+.2} mm off the surface)",
            f.id,
            touch.point.x * 1e3,
            touch.point.y * 1e3,
            touch.point.z * 1e3,
            touch.gap * 1e3
        ));
        again.initial.push((f.id, touch.point));
        again.start_joints.push((f.id, q));
    }
    if again.initial.is_empty() {
        return Err(ReplanError::NoContact);
    }
    again.start_rotation = e.rotation;
    let (goal, whole) = crate::follow::leg(e.rotation, again.settings.goal);
    again.settings.goal = goal;
    let mut notes = Vec::new();
    let settings = again.settings.clone();
    // The targets handed on, when they are.
    let mut streamed: Vec<Target> = Vec::new();
    let mut plan = crate::follow::at_the_gate(&settings, &mut notes, |alpha| {
        again.settings.alpha = alpha;
        again.settings.neighbour_alpha = settings.neighbour_alpha.map(|n| n.min(alpha));
        let Some(out) = settled.as_deref_mut() else {
            return again.plan(progress);
        };
        // (A plan refused at the plan's margin is refused at its start, before any step.)
        streamed.clear();
        let mut prev: Option<Step> = None;
        again.plan_streamed(progress, &mut |part| {
            let steps: Vec<Step> = part
                .iter()
                .map(|s| Step {
                    step: s.step + first,
                    ..s.clone()
                })
                .collect();
            let from = streamed.len();
            targets_after(prev.as_ref(), &steps, &again, &mut streamed, &mut || {});
            prev = steps.last().cloned();
            out(&streamed[from..], alpha);
        })
    })
    .map_err(|error| ReplanError::Planning {
        from: e.rotation,
        estimate: e.rotation,
        contacts: described.join(", "),
        error,
    })?;
    for step in &mut plan.steps {
        step.step += first;
    }
    let targets = if settled.is_some() {
        streamed
    } else {
        targets_with(&plan.steps, &again, &mut || {})
    };
    Ok(Replan {
        at_goal: whole && plan.summary.completed,
        targets,
        plan,
        delta: 0.0,
        notes,
    })
}

/// The way points before `step`, an attach or a detach step after `prev`, onto `out`.
fn way_points(prev: &Step, step: &Step, out: &mut Vec<Target>) {
    // The switch: on the attach step; a detach step follows its attach step.
    let Some(switch) = (match step.phase {
        Phase::Attach => step.switch.as_ref(),
        _ => prev.switch.as_ref(),
    }) else {
        return;
    };
    for (slot, (a, b)) in prev.fingers.iter().zip(&step.fingers).enumerate() {
        let (base, vias): (&Step, Vec<&Vec<Real>>) = match (a.contact, b.contact, step.phase) {
            (None, Some(_), Phase::Attach) if b.finger == switch.attached => {
                // Its free pose first: it sets off from there only once there.
                let mut free = prev.clone();
                free.switch = step.switch.clone();
                out.push(way_point(free, step));
                let vias = switch.approach.iter().flatten().collect();
                (prev, vias)
            }
            (Some(_), None, Phase::Detach) if a.finger == switch.released => {
                (step, switch.retreat.iter().flatten().rev().collect())
            }
            _ => continue,
        };
        for q in vias {
            let mut via = base.clone();
            via.fingers[slot].contact = None;
            via.fingers[slot].point = None;
            via.fingers[slot].normal = None;
            via.fingers[slot].cap_angle = None;
            via.fingers[slot].joints = q.clone();
            out.push(way_point(via, step));
        }
    }
}

/// `via` as a way point of `step`: numbered and phased as it, with its switch.
fn way_point(mut via: Step, step: &Step) -> Target {
    via.step = step.step;
    via.phase = step.phase;
    via.switch = step.switch.clone();
    Target {
        step: via,
        way_point: true,
        passing: false,
    }
}

/// The sub-targets of `step`, a rolling step after `prev`, onto `out`.
fn rolling(
    prev: &Step,
    step: &Step,
    scenario: &SpatialScenario<'_>,
    turning: &Turning<'_>,
    out: &mut Vec<Target>,
) {
    let turn = step.rotation - prev.rotation;
    // A whole number of sub-steps is that many, not one more for the rounding of the turn.
    let n = (turn.abs() / SUBSTEP - 1e-9).ceil().max(1.0) as usize;
    for i in 1..=n {
        let s = i as Real / n as Real;
        let mut t = step.clone();
        t.rotation = prev.rotation + s * turn;
        if i < n {
            for (slot, (a, b)) in prev.fingers.iter().zip(&step.fingers).enumerate() {
                let (Some(_), Some(_), Some(f)) =
                    (a.contact, b.contact, scenario.hand.finger(a.finger))
                else {
                    continue;
                };
                let q: Vec<Real> = a
                    .joints
                    .iter()
                    .zip(&b.joints)
                    .map(|(x, y)| x + s * (y - x))
                    .collect();
                t.fingers[slot].joints = onto_surface(f, q, turning, t.rotation);
            }
        }
        out.push(Target {
            step: t,
            way_point: false,
            passing: i < n,
        });
    }
}

/// Joints `q` of finger `f` moved, least, so that its fingertip touches the surface of the
/// object at `theta`: Newton steps of the fingertip centre along the normal (the joint
/// limits kept). Where the fingertip cannot be moved (a singular pose), `q` as it is.
pub fn onto_surface(f: &Finger, mut q: Vec<Real>, turning: &Turning<'_>, theta: Real) -> Vec<Real> {
    for _ in 0..PROJECTIONS {
        let c = turning.contact_of(f, &q, theta);
        if c.gap.abs() <= ON_SURFACE {
            break;
        }
        let normal: Vec3 = turning.rotation(theta) * c.normal;
        let jac = f.jacobian6(&q).rows(0, 3).into_owned();
        let Ok(pinv) = jac.clone().pseudo_inverse(1e-9) else {
            break;
        };
        let want = DVector::from_column_slice((normal * -c.gap).as_slice());
        let dq: DMatrix<Real> = pinv * DMatrix::from_column_slice(3, 1, want.as_slice());
        for (j, a) in q.iter_mut().enumerate() {
            *a = (*a + dq[(j, 0)]).clamp(f.joints[j].lower, f.joints[j].upper);
        }
    }
    q
}
