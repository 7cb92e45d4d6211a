//! Planning again from an estimate: the contacts put on candidates, the plan made at the
//! plan's margin or the gate's, its steps turned back to the object's rotation.

use icrflow_grasp::math::Real;

use super::{Estimate, EstimatedFinger, REPLAN_HORIZON, Target, targets};
use crate::hand::{Finger, wrap};
use crate::planner::{Plan, PlanError, QUALITY_SLACK, Scenario, Settings, Start};
use crate::rolling::{Surface, tip};

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
    /// Whether it ends at the scenario's goal (not: at [`REPLAN_HORIZON`] short of it, or
    /// stopped short).
    pub at_goal: bool,
}

/// The goal of a plan made again from `from` toward `goal` (rad): at most
/// [`REPLAN_HORIZON`] on; and whether that is `goal` itself.
pub(crate) fn leg(from: Real, goal: Real) -> (Real, bool) {
    let direction = if goal >= from { 1.0 } else { -1.0 };
    if (goal - from).abs() <= REPLAN_HORIZON {
        (goal, true)
    } else {
        (from + direction * REPLAN_HORIZON, false)
    }
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
/// fingertip poses the hand's. The goal is the scenario's, at most [`REPLAN_HORIZON`] on
/// ([`Replan::at_goal`] says whether it is the scenario's): the last step turns the object
/// to it.
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
    let (goal, whole) = leg(theta, again.settings.goal + delta);
    again.settings.goal = goal;
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
        at_goal: whole && plan.summary.completed,
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
