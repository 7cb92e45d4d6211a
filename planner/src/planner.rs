//! The in-hand rolling planner (paper section III, DESIGN.md section 3): rolling within ICRs,
//! then finger switching at a rendezvous point, repeated until the object has turned by the
//! goal.
//!
//! # Model
//! - The hand moves in its horizontal plane `z = 0`; the object's centre of mass is held at
//!   the origin and the object turns about the vertical axis by `theta` (counter-clockwise
//!   seen from the top is positive). Body point `b` is at `Rz(theta) (b - c)` in the hand
//!   frame, `c` the centre of mass.
//! - Contacts are candidates of the grasp problem: the object's section by the hand's plane
//!   (planar or spatial analysis). Everything about grasp quality is computed in the body
//!   frame (alpha* is invariant under the object's rigid motion).
//! - A finger in contact at body point `p` (outward normal `n`) has its fingertip centre at
//!   `p_w + r_f n_w`. Its *cap angle* `gamma` is where the contact lies on the fingertip: the
//!   angle from the cap axis (world angle `phi`) to the direction `-n_w` of the contact from
//!   the fingertip's centre, `gamma = angle(-n_w) - phi`.
//!
//! # Rolling step
//! The object turns by `step`. Each finger's next contact is the member of its ICR nearest to
//! the body point that would stay still in the world (`c + Rz(-step) (p - c)`: just behind
//! the current contact along the rolling direction). Rolling without slipping makes the arc
//! travelled on the fingertip equal to the arc `s` travelled on the object, with opposite
//! sense: `r_f dgamma = -s` (`s` counter-clockwise positive; for a sphere `s = r_o dtheta_b`,
//! hence the paper's `dtheta_o = (r_f / r_o) dtheta_f` when the fingertips stay in place).
//! The fingertip pose `(p_w + r_f n_w, phi = angle(-n_w) - gamma)` gives the joint angles by
//! inverse kinematics. The step is refused when a finger would leave its joint limits, its
//! fingertip cap (`|gamma| > cap half-angle - margin`), or fall below the mobility threshold;
//! and (a bug guard) when the recomputed quality is below alpha.
//!
//! One rolling step is one candidate step: two poses, between which the pipeline moves the
//! joints along a straight line. They stand for the rolling between them only while each
//! contact's travel is short and stays where the margin holds. So a contact's next contact
//! must be reached along the section through members of its ICR only, and where its
//! stay-still point is out of the ICR (it rolls to the region's member nearest that point,
//! and its fingertip moves around the object by the difference), that difference is at most
//! [`MAX_DRAG`]; otherwise the finger is blocked (a switch may help). A step of more than
//! [`MAX_STEP`] is refused outright: the stay-still point of a half turn is on the far side of
//! the section, and that of a whole turn is the contact itself, so a 360-degree step once
//! "completed" with the hand not moving at all.
//!
//! # Finger switching
//! When a finger `k` cannot roll on, a free finger takes over. Its rendezvous region is the
//! set of candidates `q` whose grasp with the remaining contacts keeps the margin: computed
//! exactly by brute force, beside the ICR zone rule and the paper's eq. (8) hyperplanes
//! (LP, clarabel), all recorded ([`crate::rendezvous`]). The rendezvous point is the exact
//! region's candidate that the free finger reaches (inverse kinematics within limits, the cap, the
//! mobility threshold, fingertips not overlapping), ahead of the released contact along the
//! rolling direction (within half a turn counter-clockwise of it) when any such is reachable,
//! with the most rolling room, i.e. the most steps it could roll before its own limits; ties
//! go to the candidate farther ahead. Then: attach (the grasp with one more contact is verified),
//! detach finger `k` (the remaining grasp is verified), and `k` becomes a free finger.

use std::f64::consts::PI;

use icrflow_grasp::icr::IcrError;
use icrflow_grasp::math::{Real, Vec3};
use icrflow_grasp::quality::{GraspError, GraspProblem};
use serde::{Deserialize, Serialize};

use crate::hand::{Finger, Hand, IkError, wrap};

/// What a rolling step found (of the planar planner's [`Contact`]s, or the spatial
/// planner's [`crate::spatial::Touch`]es).
#[derive(Debug, Clone, PartialEq)]
pub enum Roll<C = Contact> {
    /// Every finger moved; the new contacts and their quality.
    Moved(Vec<C>, Real),
    /// Contact `.0` cannot move, for reason `.1`: a switch may help.
    Blocked(usize, String),
    /// The grasp as a whole cannot go on.
    Stuck(String),
}

/// Relative slack on `quality >= alpha` checks (the ICR rule holds to 1e-9 relative).
pub const QUALITY_SLACK: Real = 1e-9;

/// Planner settings.
#[derive(Debug, Clone, PartialEq)]
pub struct Settings {
    /// The quality margin alpha.
    pub alpha: Real,
    /// The margin the command node's gate holds the estimated grasp to (`grasp.alpha`, at
    /// most [`Settings::alpha`], which may keep headroom over it): a plan made again from an
    /// estimated grasp that keeps less than `alpha`, but at least this, is made at this
    /// margin ([`crate::follow::replan`], [`crate::spatial::follow::replan`]).
    pub gate_alpha: Real,
    /// Total rotation to reach (rad, > 0: counter-clockwise seen from the top).
    pub goal: Real,
    /// Object rotation per rolling step (rad, > 0).
    pub step: Real,
    /// Margin kept from the edge of the fingertip cap (rad).
    pub cap_margin: Real,
    /// Smallest admissible manipulability of a finger in contact.
    pub min_manipulability: Real,
    /// How far (m) every finger in contact must be able to press further into the object
    /// along the contact's inward normal, inside its joint limits ([`Finger::reach_along`]):
    /// room for a hand's controller to squeeze (0: not checked).
    pub squeeze_reserve: Real,
    /// Rings of neighbouring candidates (the candidates' adjacency) by which every ICR and
    /// every rendezvous region is shrunk before the planner picks a contact from it: a
    /// contact that a real hand makes up to that many candidates off the plan's stays inside
    /// the unshrunk region. For the ICRs of a rolling grasp this keeps the margin whatever
    /// the contacts' errors within it (the ICRs hold for every contact anywhere in its
    /// region); at a switch, for the attaching finger's error. 0: the regions as they are.
    pub region_erosion: usize,
    /// The quality every grasp of a spatial plan (each rolling step's end, each switch's
    /// attach and detach grasps) keeps with any one of its contacts moved to a candidate
    /// within [`Settings::neighbour_rings`] rings of its own (the candidates' adjacency):
    /// headroom for a hand whose estimate places a contact a few candidates off the plan's,
    /// which the command node's gate holds to `grasp.alpha`. `None`: not checked.
    pub neighbour_alpha: Option<Real>,
    /// How many rings of neighbouring candidates [`Settings::neighbour_alpha`] is checked
    /// over (at least 1).
    pub neighbour_rings: usize,
    /// Upper bound on planner steps (rolling, attach and detach together).
    pub max_steps: usize,
    /// Resolution of the search over the cap angle when a finger attaches (rad).
    pub attach_resolution: Real,
}

/// The problem the planner solves.
#[derive(Clone)]
pub struct Scenario<'a> {
    /// Grasp problem whose candidates are the object's section in the hand's plane.
    pub problem: &'a GraspProblem,
    /// The hand.
    pub hand: &'a Hand,
    /// The object's centre of mass (body frame).
    pub centre: Vec3,
    /// Section angle of each candidate (rad), for reporting.
    pub angles: Option<&'a [Real]>,
    /// Initial contacts: (finger, candidate, cap angle). Without a cap angle the planner
    /// picks the one with the most rolling room.
    pub initial: Vec<(u32, usize, Option<Real>)>,
    /// Where the plan starts: the object's rotation and the hand's pose.
    pub start: Start,
    /// Settings.
    pub settings: Settings,
}

/// Where a plan starts. A scenario starts at rotation 0 with the hand at its home pose
/// (`Start::default()`); a plan made again from an estimated state (the pipeline's planner
/// node, after the object slipped) starts where the object and the hand are.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Start {
    /// The object's rotation (rad). The plan turns it from here to [`Settings::goal`].
    pub rotation: Real,
    /// Joint angles (rad) per finger that the initial contacts' inverse kinematics starts
    /// from (the solution nearest to them is taken); a finger not listed starts from its
    /// home pose.
    pub joints: Vec<(u32, Vec<Real>)>,
}

/// Why a scenario is refused before planning.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum PlanError {
    /// A finger of the grasp is not in the hand.
    #[error("finger {finger} is not in the hand (fingers: {known:?})")]
    UnknownFinger {
        /// The finger.
        finger: u32,
        /// The hand's fingers.
        known: Vec<u32>,
    },
    /// A finger is not a planar three-joint chain.
    #[error(
        "finger {finger} is not a planar three-joint chain in the hand's plane z = 0; the planner needs one"
    )]
    NotPlanar {
        /// The finger.
        finger: u32,
    },
    /// The initial grasp is not force closure.
    #[error("the initial grasp is not force closure (epsilon = {epsilon:.6}): nothing to plan")]
    NotForceClosure {
        /// Ferrari-Canny epsilon of the grasp.
        epsilon: Real,
    },
    /// The initial grasp's quality is below alpha.
    #[error(
        "the initial grasp's quality alpha* = {quality:.6} is below the margin alpha = {alpha} (the plan's: plan.alpha, or grasp.alpha where it is not set)"
    )]
    BelowMargin {
        /// Its quality.
        quality: Real,
        /// The margin.
        alpha: Real,
    },
    /// An initial contact cannot be reached.
    #[error("finger {finger} cannot reach its initial contact at {where_}: {reason}")]
    Unreachable {
        /// The finger.
        finger: u32,
        /// Where the contact is.
        where_: String,
        /// Why.
        reason: String,
    },
    /// Two fingertips would overlap.
    #[error(
        "fingers {a} and {b} overlap: their fingertip centres are {distance_mm:.2} mm apart, less than the sum of the radii"
    )]
    Overlap {
        /// One finger.
        a: u32,
        /// The other.
        b: u32,
        /// Distance between the fingertip centres (mm).
        distance_mm: Real,
    },
    /// A finger's link would pass through the object.
    #[error(
        "finger {finger}'s link {link} would pass {depth_mm:.2} mm into the object at step {step}: the hand cannot make this plan"
    )]
    LinkInObject {
        /// The finger.
        finger: u32,
        /// The link, counted from the palm (1 = first joint to second).
        link: usize,
        /// The step (at, or on the way to).
        step: usize,
        /// How deep (mm).
        depth_mm: Real,
    },
    /// A setting is impossible.
    #[error("{0}")]
    Settings(String),
    /// The grasp evaluation failed (not a grasp outcome: a numerical failure).
    #[error(transparent)]
    Grasp(#[from] GraspError),
}

/// The phase a trajectory step belongs to. Its codes (`phase as u32`) are the plan-step
/// message's `PlanPhase` codes (asserted in `icrflow-interfaces`' tests).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Phase {
    /// The initial grasp.
    Start = 0,
    /// A rolling step.
    Rolling = 1,
    /// A free finger has attached.
    Attach = 2,
    /// The finger at its limit has detached.
    Detach = 3,
}

impl Phase {
    /// Lower-case name.
    pub fn name(self) -> &'static str {
        match self {
            Phase::Start => "start",
            Phase::Rolling => "rolling",
            Phase::Attach => "attach",
            Phase::Detach => "detach",
        }
    }
}

/// One finger in one step.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FingerState {
    /// Finger number.
    pub finger: u32,
    /// Candidate index of the contact, if in contact.
    pub contact: Option<usize>,
    /// Body-frame contact point (m).
    pub point: Option<[Real; 3]>,
    /// Body-frame outward unit normal at the contact: the spatial planner's (its contacts are
    /// exact surface points); the planar planner's contacts are candidates, whose normals the
    /// grasp problem has.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub normal: Option<[Real; 3]>,
    /// The contact's angle on the section (rad, [0, 2 pi); `angle_deg` in files).
    #[serde(rename = "angle_deg", with = "crate::degrees::option")]
    pub angle: Option<Real>,
    /// Cap angle gamma of the contact on the fingertip (rad; `cap_angle_deg` in files).
    #[serde(rename = "cap_angle_deg", with = "crate::degrees::option")]
    pub cap_angle: Option<Real>,
    /// World angle of the fingertip's cap axis phi (rad; `tip_rotation_deg` in files): the
    /// fingertip's rotation.
    #[serde(rename = "tip_rotation_deg", with = "crate::degrees")]
    pub tip_rotation: Real,
    /// Fingertip centre in the hand frame (m).
    pub tip_centre: [Real; 3],
    /// Joint angles (rad; `joints_deg` in files).
    #[serde(rename = "joints_deg", with = "crate::degrees::list")]
    pub joints: Vec<Real>,
}

/// A finger switch.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Switch {
    /// The finger that could not roll on.
    pub released: u32,
    /// The free finger that took over.
    pub attached: u32,
    /// Why the released finger stopped.
    pub reason: String,
    /// The rendezvous region by the ICR zone rule (candidate indices, ascending).
    pub icr_region: Vec<usize>,
    /// The rendezvous region by the eq. (8) hyperplanes (candidate indices, ascending).
    pub lp_region: Vec<usize>,
    /// The exact region by brute force (candidate indices, ascending); the rendezvous point
    /// is chosen from it shrunk by [`Settings::region_erosion`] rings.
    pub brute_force: Vec<usize>,
    /// How many candidates the rendezvous point was chosen from: the exact region shrunk by
    /// [`Settings::region_erosion`] rings (all of it without erosion; 0 in plans written
    /// before it was recorded).
    #[serde(default)]
    pub chosen_from: usize,
    /// The chosen rendezvous candidate.
    pub rendezvous: usize,
    /// Its angle on the section (rad; `rendezvous_angle_deg` in files).
    #[serde(rename = "rendezvous_angle_deg", with = "crate::degrees::option")]
    pub rendezvous_angle: Option<Real>,
    /// Rolling steps the attached finger could make from there alone.
    pub room_steps: usize,
    /// How far the rendezvous point is ahead of the released contact along the rolling
    /// direction (rad, counter-clockwise about the object's centre, in [0, 2 pi); `ahead_deg`
    /// in files).
    #[serde(rename = "ahead_deg", with = "crate::degrees")]
    pub ahead: Real,
    /// A spatial plan's approach of the attaching finger: the joints (rad; `approach_deg` in
    /// files) of the poses it passes through from its home pose to the rendezvous point (none:
    /// straight; else a pose turned at its base but not yet curled, or curled but not yet
    /// turned, and poses with its fingertip lifted off the point along the normal, the nearest
    /// last; [`crate::spatial::LIFTS`]); each straight joint-space move, home -> these -> the
    /// contact, is checked clear of the object (its fingertip not pressing in) and of the
    /// other fingers.
    #[serde(
        rename = "approach_deg",
        default,
        skip_serializing_if = "Option::is_none",
        with = "crate::degrees::option_poses"
    )]
    pub approach: Option<Vec<Vec<Real>>>,
    /// A spatial plan's retreat of the released finger: the same poses off its last contact,
    /// passed through in reverse on its way home (rad; `retreat_deg` in files).
    #[serde(
        rename = "retreat_deg",
        default,
        skip_serializing_if = "Option::is_none",
        with = "crate::degrees::option_poses"
    )]
    pub retreat: Option<Vec<Vec<Real>>>,
}

/// One step of the trajectory.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Step {
    /// Step number from 0.
    pub step: usize,
    /// Phase.
    pub phase: Phase,
    /// Object rotation about the vertical axis (rad, counter-clockwise positive;
    /// `rotation_deg` in files).
    #[serde(rename = "rotation_deg", with = "crate::degrees")]
    pub rotation: Real,
    /// Quality alpha* of the grasp in force (recomputed).
    pub quality: Real,
    /// Every finger of the hand.
    pub fingers: Vec<FingerState>,
    /// For an attach step: the switch.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub switch: Option<Switch>,
}

impl Step {
    /// Step `step` of phase `phase` at rotation `rotation` (rad) of quality `quality`, its
    /// fingers `fingers`, not a switch.
    pub fn new(
        step: usize,
        phase: Phase,
        rotation: Real,
        quality: Real,
        fingers: Vec<FingerState>,
    ) -> Self {
        Self {
            step,
            phase,
            rotation,
            quality,
            fingers,
            switch: None,
        }
    }
}

/// What the planning loop ([`drive`]) asks of a scenario: the planar [`Scenario`] and the
/// spatial [`crate::spatial::SpatialScenario`] plan alike, a rolling step at a time and a
/// finger switch where a contact is blocked.
pub(crate) trait Stepper {
    /// A contact of the grasp.
    type Contact;
    /// The finger of contact `c`.
    fn finger_of(c: &Self::Contact) -> u32;
    /// The hand's fingers.
    fn fingers(&self) -> usize;
    /// The grasp `contacts` rolled on by `step` from `theta` (rad).
    fn roll(
        &self,
        contacts: &[Self::Contact],
        theta: Real,
        step: Real,
    ) -> Result<Roll<Self::Contact>, PlanError>;
    /// A free finger taking over from contact `k`, blocked for `why`: the grasp with it
    /// attached, the grasp after the release, the switch and the two grasps' qualities; or
    /// why there is none.
    fn switch(
        &self,
        contacts: &[Self::Contact],
        k: usize,
        theta: Real,
        why: &str,
        progress: &mut dyn FnMut(Real),
    ) -> Result<Result<Switched<Self::Contact>, NoSwitch>, PlanError>;
    /// Step `step` of phase `phase` at `theta` with `contacts` of quality `quality`.
    fn record(
        &self,
        step: usize,
        phase: Phase,
        theta: Real,
        quality: Real,
        contacts: &[Self::Contact],
    ) -> Step;
}

/// A switch found ([`Stepper::switch`]): the grasp with the attached finger, the grasp after
/// the release, the switch, and the two grasps' qualities.
pub(crate) type Switched<C> = (Vec<C>, Vec<C>, Switch, Real, Real);

/// Why no free finger takes over ([`Stepper::switch`]).
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct NoSwitch {
    /// Why, in words.
    pub reason: String,
    /// Whether it is a defect of the planner (a region that is exact failed verification):
    /// the plan stops there, no earlier switch tried in its place.
    pub defect: bool,
}

impl NoSwitch {
    /// No free finger can take over, for `reason`.
    pub(crate) fn none(reason: String) -> Self {
        Self {
            reason,
            defect: false,
        }
    }

    /// A defect of the planner, `reason`.
    pub(crate) fn defect(reason: String) -> Self {
        Self {
            reason,
            defect: true,
        }
    }
}

impl Stepper for Scenario<'_> {
    type Contact = Contact;

    fn finger_of(c: &Contact) -> u32 {
        c.finger
    }

    fn fingers(&self) -> usize {
        self.hand.fingers.len()
    }

    fn roll(&self, contacts: &[Contact], theta: Real, step: Real) -> Result<Roll, PlanError> {
        Scenario::roll(self, contacts, theta, step)
    }

    fn switch(
        &self,
        contacts: &[Contact],
        k: usize,
        theta: Real,
        why: &str,
        _progress: &mut dyn FnMut(Real),
    ) -> Result<Result<Switched<Contact>, NoSwitch>, PlanError> {
        let released = contacts[k].finger;
        let free: Vec<&Finger> = self
            .hand
            .fingers
            .iter()
            .filter(|f| contacts.iter().all(|c| c.finger != f.id))
            .filter(|f| f.dof() == 3 && f.planar.is_some())
            .collect();
        if free.is_empty() {
            return Ok(Err(NoSwitch::none(format!(
                "finger {released} cannot roll on ({why}) and no free finger can take over"
            ))));
        }
        let idx: Vec<usize> = contacts.iter().map(|c| c.candidate).collect();
        let regions = crate::rendezvous::regions(self.problem, &idx, k, self.settings.alpha)?;
        // The exact region shrunk by the erosion: an attaching finger that lands that many
        // candidates off the rendezvous point still keeps the margin.
        let shrunk: Vec<usize>;
        let brute: &[usize] = if self.settings.region_erosion == 0 {
            &regions.exact
        } else {
            let exact: Vec<u32> = regions.exact.iter().map(|&c| c as u32).collect();
            shrunk = self.erode(&exact).into_iter().map(|c| c as usize).collect();
            &shrunk
        };
        let angle = |c: usize| {
            let p = self.problem.candidates().points[c] - self.centre;
            p.y.atan2(p.x)
        };
        let here = angle(contacts[k].candidate);
        // Every reachable option: (room, ahead, finger, candidate, gamma, q).
        let mut options: Vec<(usize, Real, u32, usize, Real, Vec<Real>)> = Vec::new();
        for f in &free {
            for &c in brute {
                let Some((gamma, q, room)) = self.best_attach(f, c, theta) else {
                    continue;
                };
                let mut trial = contacts.to_vec();
                trial.push(Contact {
                    finger: f.id,
                    candidate: c,
                    gamma,
                    q: q.clone(),
                });
                if self.overlap(&trial).is_some() {
                    continue;
                }
                let ahead = wrap(angle(c) - here).rem_euclid(2.0 * PI);
                options.push((room, ahead, f.id, c, gamma, q));
            }
        }
        // Ahead of the released contact along the rolling direction first, then the most
        // rolling room, then the farthest ahead (then the lowest finger and candidate, so the
        // order is total and the plan reproducible).
        options.sort_by(|x, y| {
            let ahead = |a: Real| a > 0.0 && a < PI;
            ahead(y.1)
                .cmp(&ahead(x.1))
                .then(y.0.cmp(&x.0))
                .then(y.1.total_cmp(&x.1))
                .then(x.2.cmp(&y.2))
                .then(x.3.cmp(&y.3))
        });
        let floor = self.settings.alpha * (1.0 - QUALITY_SLACK);
        let mut rejected = Vec::new();
        let mut chosen = None;
        for (room, ahead, id, c, gamma, q) in options {
            let mut attach = contacts.to_vec();
            attach.push(Contact {
                finger: id,
                candidate: c,
                gamma,
                q,
            });
            let (q_attach, _) = self.quality(&attach)?;
            let mut detach = attach.clone();
            detach.remove(k);
            let (q_detach, _) = self.quality(&detach)?;
            if q_attach < floor || q_detach < floor {
                return Ok(Err(NoSwitch::defect(format!(
                    "switch of finger {released} to finger {id} at {} fails verification: quality {q_attach:.6} attached, {q_detach:.6} detached, alpha = {} (a defect: the region is exact)",
                    self.describe(c),
                    self.settings.alpha
                ))));
            }
            // One step of lookahead: the attached finger must be able to roll on with the
            // grasp it joins (its rolling room was estimated alone).
            let step = self.settings.step.min(self.settings.goal - theta);
            if step > 1e-12 {
                let new = detach.len() - 1;
                match self.roll(&detach, theta, step)? {
                    Roll::Blocked(j, why) if j == new => {
                        rejected.push(format!("{} by finger {id}: {why}", self.describe(c)));
                        continue;
                    }
                    Roll::Stuck(why) => {
                        rejected.push(format!("{} by finger {id}: {why}", self.describe(c)));
                        continue;
                    }
                    _ => {}
                }
            }
            chosen = Some((room, ahead, id, c, attach, detach, q_attach, q_detach));
            break;
        }
        let Some((room, ahead, id, c, attach, detach, q_attach, q_detach)) = chosen else {
            return Ok(Err(NoSwitch::none(format!(
                "finger {released} cannot roll on ({why}); of the {} candidates that keep the margin with the remaining contacts{}, none is reachable by a free finger ({:?}) with a rolling step after it{}",
                brute.len(),
                match self.settings.region_erosion {
                    0 => String::new(),
                    n => format!(" ({n} ring(s) inside the exact region)"),
                },
                free.iter().map(|f| f.id).collect::<Vec<_>>(),
                if rejected.is_empty() {
                    String::new()
                } else {
                    format!(" (tried {})", rejected.join("; "))
                }
            ))));
        };
        let info = Switch {
            released,
            attached: id,
            reason: why.to_string(),
            icr_region: regions.icr.clone(),
            lp_region: regions.lp.clone(),
            brute_force: regions.exact.clone(),
            chosen_from: brute.len(),
            rendezvous: c,
            rendezvous_angle: self.angles.map(|a| a[c]),
            room_steps: room,
            ahead,
            approach: None,
            retreat: None,
        };
        Ok(Ok((attach, detach, info, q_attach, q_detach)))
    }

    fn record(
        &self,
        step: usize,
        phase: Phase,
        theta: Real,
        quality: Real,
        contacts: &[Contact],
    ) -> Step {
        let cands = self.problem.candidates();
        let fingers = self
            .hand
            .fingers
            .iter()
            .map(|f| {
                let contact = contacts.iter().find(|c| c.finger == f.id);
                let q = contact.map_or(&f.home, |c| &c.q);
                let pose = f.fk(q);
                let p = contact.map(|c| cands.points[c.candidate]);
                FingerState {
                    finger: f.id,
                    contact: contact.map(|c| c.candidate),
                    point: p.map(|p| [p.x, p.y, p.z]),
                    normal: None,
                    angle: contact.and_then(|c| self.angles.map(|a| a[c.candidate])),
                    cap_angle: contact.map(|c| c.gamma),
                    tip_rotation: pose.cap_axis.y.atan2(pose.cap_axis.x),
                    tip_centre: [pose.tip_centre.x, pose.tip_centre.y, pose.tip_centre.z],
                    joints: q.to_vec(),
                }
            })
            .collect();
        Step::new(step, phase, theta, quality, fingers)
    }
}

/// The steps the planning loop made and where it stopped.
pub(crate) struct Driven {
    /// The steps, the start's first.
    pub steps: Vec<Step>,
    /// The rotation reached (rad).
    pub rotation: Real,
    /// The smallest quality of any grasp in force.
    pub min_quality: Real,
    /// Finger switches.
    pub switches: usize,
    /// Why it stopped short of the goal, if it did.
    pub stop_reason: Option<String>,
}

/// How many rolling steps back the planning loop tries a finger switch again where the
/// switch of a blocked finger fails: the finger released that much earlier, where the
/// object's and the other fingers' positions leave a free finger other candidates.
pub const EARLY_SWITCH_STEPS: usize = 6;

/// The planning loop of `s` under `settings`, from the grasp `started` (its contacts and
/// quality) at rotation `theta` (rad): rolling steps toward the goal; where a contact is
/// blocked, a finger switch, unless the blocked finger has just attached or every finger has
/// switched since the last rolling step (the hand has no way forward). Where no free finger
/// can take over from the blocked one, the switch is tried up to [`EARLY_SWITCH_STEPS`]
/// rolling steps earlier (the latest that serves is kept, the steps after it dropped).
/// `progress` is called with the rotation after every step (and during a switch, as `s`
/// does), `moved` with the contacts of every rolling step kept.
pub(crate) fn drive<S: Stepper>(
    s: &S,
    settings: &Settings,
    mut theta: Real,
    started: (Vec<S::Contact>, Real),
    progress: &mut dyn FnMut(Real),
    moved: &mut dyn FnMut(&[S::Contact]),
) -> Result<Driven, PlanError>
where
    S::Contact: Clone,
{
    let (mut contacts, quality) = started;
    let mut steps = vec![s.record(0, Phase::Start, theta, quality, &contacts)];
    let mut switches = 0;
    let mut stop_reason = None;
    // Switches since the last rolling step, and the finger the last switch attached.
    let mut switches_in_a_row = 0;
    let mut just_attached: Option<u32> = None;
    // The rolling steps kept (their step's index, rotation and contacts), and where in them
    // the run since the last switch begins (an earlier switch may be tried within it).
    let mut rolled: Vec<(usize, Real, Vec<S::Contact>)> = Vec::new();
    let mut run_start = 0;
    while theta < settings.goal - 1e-9 {
        if steps.len() >= settings.max_steps {
            stop_reason = Some(format!(
                "stopped after plan.max_steps = {} steps",
                settings.max_steps
            ));
            break;
        }
        let step = settings.step.min(settings.goal - theta);
        match s.roll(&contacts, theta, step)? {
            Roll::Stuck(reason) => {
                stop_reason = Some(reason);
                break;
            }
            Roll::Moved(next, quality) => {
                switches_in_a_row = 0;
                just_attached = None;
                contacts = next;
                theta += step;
                rolled.push((steps.len(), theta, contacts.clone()));
                steps.push(s.record(steps.len(), Phase::Rolling, theta, quality, &contacts));
                progress(theta);
            }
            Roll::Blocked(k, why) => {
                let finger = S::finger_of(&contacts[k]);
                if just_attached == Some(finger) || switches_in_a_row >= s.fingers() {
                    stop_reason = Some(format!(
                        "finger {finger} cannot roll on ({why}) right after it attached: the hand has no way forward"
                    ));
                    break;
                }
                let mut found = s.switch(&contacts, k, theta, &why, progress)?;
                if let Some(NoSwitch { reason, defect }) = found.as_ref().err().cloned() {
                    // Released earlier, the latest first (not in place of a defect).
                    let mut tried = 0;
                    for back in (1..=EARLY_SWITCH_STEPS).filter(|_| !defect) {
                        // The current grasp is the last rolled (if any since the switch).
                        let Some(r) = rolled
                            .len()
                            .checked_sub(1 + back)
                            .filter(|&r| r >= run_start)
                        else {
                            break;
                        };
                        let (at, earlier) = (rolled[r].1, &rolled[r].2);
                        let Some(j) = earlier.iter().position(|c| S::finger_of(c) == finger) else {
                            break;
                        };
                        tried = back;
                        let early = format!(
                            "released {back} steps early: {} deg on, no free finger could take over ({why})",
                            (theta - at).to_degrees().round()
                        );
                        if let Ok(sw) = s.switch(earlier, j, at, &early, progress)? {
                            steps.truncate(rolled[r].0 + 1);
                            contacts = earlier.clone();
                            rolled.truncate(r + 1);
                            theta = at;
                            found = Ok(sw);
                            break;
                        }
                    }
                    if found.is_err() {
                        stop_reason = Some(match tried {
                            0 => reason,
                            n => format!(
                                "{reason} (nor released up to {n} rolling steps earlier, since the last switch or the start)"
                            ),
                        });
                        break;
                    }
                }
                if let Ok((attach, detach, info, q_attach, q_detach)) = found {
                    just_attached = Some(info.attached);
                    let mut a = s.record(steps.len(), Phase::Attach, theta, q_attach, &attach);
                    a.switch = Some(info);
                    steps.push(a);
                    steps.push(s.record(steps.len(), Phase::Detach, theta, q_detach, &detach));
                    contacts = detach;
                    switches += 1;
                    switches_in_a_row += 1;
                    run_start = rolled.len();
                    progress(theta);
                }
            }
        }
    }
    for (_, _, c) in &rolled {
        moved(c);
    }
    let min_quality = steps
        .iter()
        .map(|s| s.quality)
        .fold(Real::INFINITY, Real::min);
    Ok(Driven {
        steps,
        rotation: theta,
        min_quality,
        switches,
        stop_reason,
    })
}

impl Driven {
    /// The plan of these steps under `settings`, about `axis`, with the planner's own
    /// figures: its largest rolling residual (m), its links' smallest clearance (m) and its
    /// smallest squeeze reserve (m).
    pub(crate) fn into_plan(
        self,
        settings: &Settings,
        axis: [Real; 3],
        max_rolling_residual: Real,
        link_clearance: Real,
        squeeze_reserve: Real,
    ) -> Plan {
        let steps = self.steps;
        let switch_list = || steps.iter().filter_map(|s| s.switch.as_ref());
        let lp_region_unsafe = switch_list()
            .map(|s| {
                s.lp_region
                    .iter()
                    .filter(|q| s.brute_force.binary_search(q).is_err())
                    .count()
            })
            .sum();
        let summary = Summary {
            completed: self.stop_reason.is_none(),
            stop_reason: self.stop_reason,
            rotation: self.rotation,
            goal: settings.goal,
            axis,
            switches: self.switches,
            steps: steps.len(),
            rolling_steps: steps.iter().filter(|s| s.phase == Phase::Rolling).count(),
            min_quality: self.min_quality,
            alpha: settings.alpha,
            max_rolling_residual,
            icr_region_candidates: switch_list().map(|s| s.icr_region.len()).sum(),
            lp_region_candidates: switch_list().map(|s| s.lp_region.len()).sum(),
            lp_region_unsafe,
            brute_force_candidates: switch_list().map(|s| s.brute_force.len()).sum(),
            chosen_from_candidates: switch_list().map(|s| s.chosen_from).sum(),
            region_erosion: settings.region_erosion,
            min_link_clearance_mm: Some(link_clearance * 1e3),
            min_squeeze_reserve_mm: Some(squeeze_reserve * 1e3),
        };
        Plan { summary, steps }
    }
}

/// Summary of a plan.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Summary {
    /// Whether the goal rotation was reached.
    pub completed: bool,
    /// Why planning stopped early, if it did.
    pub stop_reason: Option<String>,
    /// Total object rotation (rad; `rotation_deg` in files).
    #[serde(rename = "rotation_deg", with = "crate::degrees")]
    pub rotation: Real,
    /// Goal (rad; `goal_deg` in files).
    #[serde(rename = "goal_deg", with = "crate::degrees")]
    pub goal: Real,
    /// The unit axis (hand frame) the object turns about, positive by the right-hand rule:
    /// `[0, 0, 1]` for the planar planner (counter-clockwise seen from the top).
    #[serde(default = "vertical")]
    pub axis: [Real; 3],
    /// Finger switches.
    pub switches: usize,
    /// Trajectory steps (all phases; the start included).
    pub steps: usize,
    /// Rolling steps.
    pub rolling_steps: usize,
    /// Smallest quality of any grasp in force.
    pub min_quality: Real,
    /// The margin.
    pub alpha: Real,
    /// Largest rolling-relation residual (m): the planar planner's `|r_f dgamma + s|`, from
    /// forward kinematics of the planned joint angles; the spatial planner's slip of a step,
    /// the contact's travel over the object less its travel over the fingertip
    /// ([`crate::spatial::Touch::slip`]).
    pub max_rolling_residual: Real,
    /// Rendezvous candidates found by the ICR zone rule, summed over the switches.
    pub icr_region_candidates: usize,
    /// Rendezvous candidates found by the eq. (8) LP hyperplanes, summed over the switches.
    pub lp_region_candidates: usize,
    /// Rendezvous candidates of the LP region that brute force rejects (should be 0).
    pub lp_region_unsafe: usize,
    /// Rendezvous candidates found by brute force, summed over the switches.
    pub brute_force_candidates: usize,
    /// Rendezvous candidates the points were chosen from (the exact regions shrunk by
    /// [`Settings::region_erosion`]), summed over the switches; 0 in plans written before it
    /// was reported.
    #[serde(default)]
    pub chosen_from_candidates: usize,
    /// The [`Settings::region_erosion`] planned with (rings of candidates); 0 in plans
    /// written before it was reported.
    #[serde(default)]
    pub region_erosion: usize,
    /// How close any finger's link comes to the object's section (mm), at the steps and along
    /// the straight joint-space moves between them ([`link_clearance`]); `None` in plans
    /// written before it was reported.
    #[serde(default)]
    pub min_link_clearance_mm: Option<Real>,
    /// The smallest squeeze reserve of any finger in contact at any step (mm, measured up to
    /// [`SQUEEZE_PROBE`]): how much further the tightest finger could press into the object
    /// along its contact normal inside its joint limits ([`Scenario::squeeze_reserve`]);
    /// `None` in plans written before it was reported.
    #[serde(default)]
    pub min_squeeze_reserve_mm: Option<Real>,
}

fn vertical() -> [Real; 3] {
    [0.0, 0.0, 1.0]
}

/// How far the plan's summary measures the squeeze reserve (m): a reserve this large or
/// larger is reported as this.
pub const SQUEEZE_PROBE: Real = 5e-3;

/// A plan.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Plan {
    /// Summary.
    pub summary: Summary,
    /// The trajectory.
    pub steps: Vec<Step>,
}

/// A finger in contact.
#[derive(Debug, Clone, PartialEq)]
pub struct Contact {
    /// Finger number.
    pub finger: u32,
    /// Candidate index of the contact point.
    pub candidate: usize,
    /// Cap angle gamma (rad).
    pub gamma: Real,
    /// Joint angles (rad).
    pub q: Vec<Real>,
}

/// Why a finger cannot take a step.
#[derive(Debug, Clone, PartialEq)]
enum Blocked {
    Cap {
        gamma: Real,
    },
    Ik(IkError),
    Mobility {
        value: Real,
    },
    Squeeze {
        reach: Real,
        needed: Real,
    },
    Jump {
        joint: usize,
        degrees: Real,
    },
    OutOfRegion {
        from: String,
        past: String,
    },
    Drag {
        step: Real,
        still: String,
        to: String,
        drag: Real,
    },
}

/// ICR members tried, nearest the target first, for a finger's next contact. One: trying
/// farther members lets the contacts drift from where the fingers' rolling room was planned,
/// which ends in overlapping fingertips and stranded fingers on the shipped scenarios.
const NEXT_CONTACT_TRIES: usize = 1;

/// Largest joint motion accepted in one rolling step (rad): more means the inverse
/// kinematics jumped to the other elbow branch, which the finger cannot do in contact.
const MAX_JOINT_STEP: Real = 0.5;

/// Largest turn of a contact point in the world, about the object's centre, in one rolling
/// step (rad, 10 deg): a contact that rolls short of its stay-still point (that point is out
/// of its ICR) moves its fingertip around the object by the difference, along the straight
/// joint-space move of the step instead of an arc; at 10 deg the fingertip's path stays within
/// about 0.3 mm of the arc on the paper's sphere. Steps of 5 deg (the paper's) never come near.
pub const MAX_DRAG: Real = 10.0 * PI / 180.0;

/// Largest object rotation of one rolling step (rad, 30 deg): one step is one straight
/// joint-space move, and a joint may move at most [`MAX_JOINT_STEP`] (28.6 deg) in one; far
/// below the half turn at which a contact's stay-still point no longer says which way it
/// rolled. `plan.step_deg` is bounded by the same.
pub const MAX_STEP: Real = 30.0 * PI / 180.0;

/// An angle in degrees for messages, rounded to a millionth (30, not 29.999999999999996).
fn degrees(x: Real) -> String {
    format!("{}", (x.to_degrees() * 1e6).round() / 1e6)
}

impl std::fmt::Display for Blocked {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Blocked::Cap { gamma } => write!(
                f,
                "the contact would leave the fingertip cap (cap angle {:.1} deg)",
                gamma.to_degrees()
            ),
            Blocked::Ik(e) => write!(f, "{e}"),
            Blocked::Mobility { value } => {
                write!(f, "mobility lost (manipulability {value:.3e})")
            }
            Blocked::Squeeze { reach, needed } => write!(
                f,
                "the finger could press only {:.2} mm further into the object (needs {:.2} mm)",
                reach * 1e3,
                needed * 1e3
            ),
            Blocked::Jump { joint, degrees } => write!(
                f,
                "joint {} would have to jump by {degrees:.1} deg (the other elbow branch)",
                joint + 1
            ),
            Blocked::OutOfRegion { from, past } => write!(
                f,
                "its contact would roll out of its ICR on the way from {from} (past {past})"
            ),
            Blocked::Drag {
                step,
                still,
                to,
                drag,
            } => write!(
                f,
                "its contact would roll out of its ICR: turning the object by {:.1} deg takes it to {still}, outside the region, and rolling to {to} instead would drag the fingertip {:.1} deg around the object in one step (at most {} deg)",
                step.to_degrees(),
                drag.abs().to_degrees(),
                degrees(MAX_DRAG)
            ),
        }
    }
}

impl Scenario<'_> {
    fn finger(&self, id: u32) -> &Finger {
        self.hand.finger(id).expect("fingers are checked up front")
    }

    /// World position and normal of candidate `c` with the object at `theta`.
    fn world(&self, c: usize, theta: Real) -> (Vec3, Vec3) {
        let cands = self.problem.candidates();
        let r = nalgebra::Rotation3::from_axis_angle(&Vec3::z_axis(), theta);
        (r * (cands.points[c] - self.centre), r * cands.normals[c])
    }

    /// The fingertip pose for a contact at `c` with cap angle `gamma`: centre and phi.
    fn tip_pose(&self, finger: &Finger, c: usize, theta: Real, gamma: Real) -> (Vec3, Real) {
        let (p, n) = self.world(c, theta);
        let centre = p + finger.tip_radius * n;
        let inward = (-n.y).atan2(-n.x);
        (centre, wrap(inward - gamma))
    }

    /// Joint angles for finger `finger` touching `c` at cap angle `gamma`, or why not. With
    /// `continuous`, the joints must stay within [`MAX_JOINT_STEP`] of `near`.
    fn place(
        &self,
        finger: &Finger,
        c: usize,
        theta: Real,
        gamma: Real,
        near: &[Real],
        continuous: bool,
    ) -> Result<Vec<Real>, Blocked> {
        let s = &self.settings;
        if gamma.abs() > finger.cap_half_angle - s.cap_margin {
            return Err(Blocked::Cap { gamma });
        }
        let (centre, phi) = self.tip_pose(finger, c, theta, gamma);
        let q = finger
            .ik_planar(centre.x, centre.y, phi, near)
            .map_err(Blocked::Ik)?;
        let jump = q
            .iter()
            .zip(near)
            .map(|(a, b)| (a - b).abs())
            .enumerate()
            .find(|(_, d)| *d > MAX_JOINT_STEP);
        if let (true, Some((joint, d))) = (continuous, jump) {
            return Err(Blocked::Jump {
                joint,
                degrees: d.to_degrees(),
            });
        }
        let m = finger.manipulability(&q);
        if m < s.min_manipulability {
            return Err(Blocked::Mobility { value: m });
        }
        if s.squeeze_reserve > 0.0 {
            // Checked in two steps (half way, all the way); where they fall short, measured
            // finely, which decides (and says how far it gets).
            let short = |reach: Real| reach < s.squeeze_reserve * (1.0 - 1e-6);
            if short(self.squeeze_reserve(finger, c, theta, &q, s.squeeze_reserve, 2)) {
                let reach = self.squeeze_reserve(
                    finger,
                    c,
                    theta,
                    &q,
                    s.squeeze_reserve,
                    crate::hand::REACH_STEPS,
                );
                if short(reach) {
                    return Err(Blocked::Squeeze {
                        reach,
                        needed: s.squeeze_reserve,
                    });
                }
            }
        }
        Ok(q)
    }

    /// How far (m, at most `probe`) `finger` at joints `q`, touching candidate `c` with the
    /// object at `theta`, can press further into the object along the inward normal: for a
    /// planar finger in the hand's plane with its fingertip's cap axis kept
    /// ([`Finger::reach_along_planar`]: pressing on with the same point of the cap), for
    /// others by the fingertip centre alone ([`Finger::reach_along`]); the path followed in
    /// `steps` steps (see [`Finger::reach_along_planar`]).
    #[allow(clippy::too_many_arguments)]
    pub fn squeeze_reserve(
        &self,
        finger: &Finger,
        c: usize,
        theta: Real,
        q: &[Real],
        probe: Real,
        steps: usize,
    ) -> Real {
        let (_, n) = self.world(c, theta);
        let mut inward = -n;
        if finger.planar.is_some() {
            inward.z = 0.0;
        }
        match inward.try_normalize(1e-12) {
            Some(d) if finger.planar.is_some() && finger.dof() == 3 => {
                finger.reach_along_planar(q, &d, probe, steps)
            }
            Some(d) => finger.reach_along(q, &d, probe),
            None => 0.0,
        }
    }

    /// Signed arc length (counter-clockwise positive) along the section from `a` to `b`,
    /// from the chord and the turn of the normal (exact on circles).
    fn arc(&self, a: usize, b: usize) -> Real {
        if a == b {
            return 0.0;
        }
        let cands = self.problem.candidates();
        let (na, nb) = (cands.normals[a], cands.normals[b]);
        let turn = wrap(nb.y.atan2(nb.x) - na.y.atan2(na.x));
        let chord = (cands.points[b] - cands.points[a]).xy().norm();
        let half = 0.5 * turn.abs();
        let length = if half < 1e-12 {
            chord
        } else {
            chord * half / half.sin()
        };
        if turn == 0.0 {
            // A flat stretch: the sense of travel from the positions.
            let (pa, pb) = (cands.points[a] - self.centre, cands.points[b] - self.centre);
            length * pa.xy().perp(&pb.xy()).signum()
        } else {
            length * turn.signum()
        }
    }

    /// The members of a region (sorted candidate indices) whose neighbours, to
    /// [`Settings::region_erosion`] rings of the candidates' adjacency, are all members too.
    fn erode(&self, members: &[u32]) -> Vec<u32> {
        self.problem
            .candidates()
            .adjacency
            .erode(members, self.settings.region_erosion)
    }

    /// The body point that stays still in the world when the object turns by `step`.
    fn behind(&self, c: usize, step: Real) -> Vec3 {
        let r = nalgebra::Rotation3::from_axis_angle(&Vec3::z_axis(), -step);
        self.centre + r * (self.problem.candidates().points[c] - self.centre)
    }

    /// The candidate nearest to `target`, found by walking the neighbourhood graph from
    /// `from` to ever nearer neighbours (a local search: it touches only the points on the
    /// way).
    fn walk(&self, from: usize, target: &Vec3) -> usize {
        match self.walk_within(from, target, None) {
            Ok(at) | Err(at) => at,
        }
    }

    /// [`Self::walk`], every point on the way (but `from`) checked to be in `region` (sorted
    /// candidate indices, if given): the end, or `Err` with the first point outside.
    fn walk_within(
        &self,
        from: usize,
        target: &Vec3,
        region: Option<&[u32]>,
    ) -> Result<usize, usize> {
        walk_candidates(self.problem.candidates(), from, target, region)
    }

    /// Steps finger `finger` could roll alone from `(c, gamma, q)`, up to `limit`, keeping
    /// its contact still in the world (any candidate allowed).
    fn room(
        &self,
        finger: &Finger,
        mut c: usize,
        mut gamma: Real,
        mut q: Vec<Real>,
        mut theta: Real,
        limit: usize,
    ) -> usize {
        for k in 0..limit {
            let target = self.behind(c, self.settings.step);
            let next = self.walk(c, &target);
            let g = gamma - self.arc(c, next) / finger.tip_radius;
            theta += self.settings.step;
            match self.place(finger, next, theta, g, &q, true) {
                Ok(qn) => {
                    (c, gamma, q) = (next, g, qn);
                }
                Err(_) => return k,
            }
        }
        limit
    }

    /// Every way `finger` can touch `c` with the object at `theta`, starting from its home
    /// pose: the cap angles on the attach grid that are reachable, with the joint angles and
    /// the rolling room (steps) of each.
    fn attach_options(
        &self,
        finger: &Finger,
        c: usize,
        theta: Real,
    ) -> Vec<(Real, Vec<Real>, usize)> {
        let s = &self.settings;
        let span = finger.cap_half_angle - s.cap_margin;
        let count = (2.0 * span / s.attach_resolution).floor() as usize;
        let limit = ((s.goal / s.step).ceil() as usize).clamp(1, 2000);
        (0..=count)
            .filter_map(|i| {
                let gamma = -span + i as Real * s.attach_resolution;
                let q = self
                    .place(finger, c, theta, gamma, &finger.home, false)
                    .ok()?;
                let room = self.room(finger, c, gamma, q.clone(), theta, limit);
                Some((gamma, q, room))
            })
            .collect()
    }

    /// The best way for `finger` to touch `c` with the object at `theta`: the cap angle
    /// with the most rolling room (the first such on the grid); `(gamma, q, room)`.
    fn best_attach(
        &self,
        finger: &Finger,
        c: usize,
        theta: Real,
    ) -> Option<(Real, Vec<Real>, usize)> {
        self.attach_options(finger, c, theta)
            .into_iter()
            .reduce(|best, o| if o.2 > best.2 { o } else { best })
    }

    /// Every way finger `id` can touch candidate `c` with the object at `theta`: the
    /// reachable cap angles on the attach grid, each with its rolling room (steps).
    pub fn reach(&self, id: u32, c: usize, theta: Real) -> Vec<(Real, usize)> {
        self.hand.finger(id).map_or_else(Vec::new, |f| {
            self.attach_options(f, c, theta)
                .into_iter()
                .map(|(g, _, room)| (g, room))
                .collect()
        })
    }

    fn check(&self) -> Result<(), PlanError> {
        let s = &self.settings;
        let positive = |name: &str, x: Real| {
            if x.is_finite() && x > 0.0 {
                Ok(())
            } else {
                Err(PlanError::Settings(format!(
                    "plan.{name}: must be a finite number > 0, got {x}"
                )))
            }
        };
        positive("rotation_deg", s.goal)?;
        if !self.start.rotation.is_finite() {
            return Err(PlanError::Settings(format!(
                "the start rotation must be finite, got {}",
                self.start.rotation
            )));
        }
        positive("step_deg", s.step)?;
        if s.step > MAX_STEP {
            return Err(PlanError::Settings(format!(
                "plan.step_deg: a rolling step of {} deg is more than one step can represent (at most {} deg: one straight joint-space move)",
                degrees(s.step),
                degrees(MAX_STEP)
            )));
        }
        positive("attach_resolution_deg", s.attach_resolution)?;
        if !(s.cap_margin.is_finite() && s.cap_margin >= 0.0) {
            return Err(PlanError::Settings(format!(
                "plan.cap_margin_deg: must be >= 0, got {}",
                s.cap_margin.to_degrees()
            )));
        }
        if !(s.squeeze_reserve.is_finite() && s.squeeze_reserve >= 0.0) {
            return Err(PlanError::Settings(format!(
                "plan.squeeze_reserve_mm: must be >= 0, got {}",
                s.squeeze_reserve * 1e3
            )));
        }
        if !(s.min_manipulability.is_finite() && s.min_manipulability >= 0.0) {
            return Err(PlanError::Settings(format!(
                "plan.min_manipulability: must be >= 0, got {}",
                s.min_manipulability
            )));
        }
        let known: Vec<u32> = self.hand.fingers.iter().map(|f| f.id).collect();
        for &(id, _, _) in &self.initial {
            let Some(f) = self.hand.finger(id) else {
                return Err(PlanError::UnknownFinger { finger: id, known });
            };
            if !f.in_hand_plane() {
                return Err(PlanError::NotPlanar { finger: id });
            }
        }
        for f in &self.hand.fingers {
            cap_left(f, s.cap_margin)?;
        }
        Ok(())
    }

    fn describe(&self, c: usize) -> String {
        match self.angles {
            Some(a) => format!("{:.1} deg", a[c].to_degrees()),
            None => {
                let p = self.problem.candidates().points[c];
                format!("[{:.4}, {:.4}, {:.4}] m", p.x, p.y, p.z)
            }
        }
    }

    fn overlap(&self, contacts: &[Contact]) -> Option<PlanError> {
        let tips: Vec<(u32, Vec3, Real)> = contacts
            .iter()
            .map(|c| {
                let f = self.finger(c.finger);
                (c.finger, f.fk(&c.q).tip_centre, f.tip_radius)
            })
            .collect();
        for (i, a) in tips.iter().enumerate() {
            for b in &tips[i + 1..] {
                let d = (a.1 - b.1).norm();
                if d < a.2 + b.2 {
                    return Some(PlanError::Overlap {
                        a: a.0,
                        b: b.0,
                        distance_mm: 1e3 * d,
                    });
                }
            }
        }
        None
    }

    fn quality(&self, contacts: &[Contact]) -> Result<(Real, Real), GraspError> {
        let idx: Vec<usize> = contacts.iter().map(|c| c.candidate).collect();
        let e = self.problem.evaluate(&idx)?;
        Ok((if e.force_closure() { e.quality } else { 0.0 }, e.epsilon))
    }

    /// The initial grasp, checked (force closure, quality >= alpha, every finger placed,
    /// no fingertips overlapping): its contacts and quality.
    pub fn start(&self) -> Result<(Vec<Contact>, Real), PlanError> {
        self.check()?;
        let alpha = self.settings.alpha;
        let floor = alpha * (1.0 - QUALITY_SLACK);
        let theta = self.start.rotation;
        // The initial grasp.
        let idx: Vec<usize> = self.initial.iter().map(|c| c.1).collect();
        let e = self.problem.evaluate(&idx)?;
        if !e.force_closure() {
            return Err(PlanError::NotForceClosure { epsilon: e.epsilon });
        }
        if e.quality < floor {
            return Err(PlanError::BelowMargin {
                quality: e.quality,
                alpha,
            });
        }
        let mut contacts = Vec::with_capacity(self.initial.len());
        for &(id, c, cap) in &self.initial {
            let f = self.finger(id);
            let near = self
                .start
                .joints
                .iter()
                .find(|(finger, q)| *finger == id && q.len() == f.dof())
                .map_or(&f.home, |(_, q)| q);
            let unreachable = |reason: String| PlanError::Unreachable {
                finger: id,
                where_: self.describe(c),
                reason,
            };
            let (gamma, q) = match cap {
                Some(gamma) => {
                    let q = self.place(f, c, theta, gamma, near, false).map_err(|b| {
                        unreachable(format!("with cap angle {:.1} deg: {b}", gamma.to_degrees()))
                    })?;
                    (gamma, q)
                }
                None => self
                    .best_attach(f, c, theta)
                    .map(|(g, q, _)| (g, q))
                    .ok_or_else(|| {
                        unreachable(match self.place(f, c, theta, 0.0, near, false) {
                            Err(b) => format!("at any cap angle (at the cap's centre: {b})"),
                            Ok(_) => "at any cap angle".into(),
                        })
                    })?,
            };
            contacts.push(Contact {
                finger: id,
                candidate: c,
                gamma,
                q,
            });
        }
        if let Some(e) = self.overlap(&contacts) {
            return Err(e);
        }
        Ok((contacts, e.quality))
    }

    /// Plans the scenario. `progress` is called after every step with the rotation done
    /// (rad).
    pub fn plan(&self, progress: &mut dyn FnMut(Real)) -> Result<Plan, PlanError> {
        let started = self.start()?;
        let driven = drive(
            self,
            &self.settings,
            self.start.rotation,
            started,
            progress,
            &mut |_| {},
        )?;
        let closest = link_clearance(self, &driven.steps);
        if closest.clearance < 0.0 {
            return Err(PlanError::LinkInObject {
                finger: closest.finger,
                link: closest.link,
                step: closest.step,
                depth_mm: -closest.clearance * 1e3,
            });
        }
        let residual = rolling_residuals(self, &driven.steps)
            .into_iter()
            .fold(0.0, Real::max);
        let reserve = self.min_squeeze_reserve(&driven.steps);
        Ok(driven.into_plan(
            &self.settings,
            vertical(),
            residual,
            closest.clearance,
            reserve,
        ))
    }

    /// The smallest squeeze reserve (m, up to [`SQUEEZE_PROBE`]) of any finger in contact at
    /// any of `steps`.
    fn min_squeeze_reserve(&self, steps: &[Step]) -> Real {
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

    /// Why contact `c` cannot travel to `n` in one rolling step of `step` from `theta`, if it
    /// cannot: every candidate on the way along the section must be in its `region`, and
    /// where `n` falls short of the stay-still point `target` (the point itself is outside the
    /// region), the fingertip is dragged around the object by the difference within the step,
    /// at most [`MAX_DRAG`].
    fn travel(
        &self,
        c: usize,
        n: usize,
        target: &Vec3,
        theta: Real,
        step: Real,
        region: &icrflow_grasp::icr::Region,
    ) -> Option<Blocked> {
        let pts = &self.problem.candidates().points;
        if let Err(out) = self.walk_within(c, &pts[n], Some(&region.members)) {
            return Some(Blocked::OutOfRegion {
                from: self.describe(c),
                past: self.describe(out),
            });
        }
        // How far the contact point turns in the world about the object's centre.
        let world = |k: usize, at: Real| {
            let (p, _) = self.world(k, at);
            p.y.atan2(p.x)
        };
        let drag = wrap(world(n, theta + step) - world(c, theta));
        if drag.abs() > MAX_DRAG {
            let still = self.walk(c, target);
            return Some(Blocked::Drag {
                step,
                still: self.describe(still),
                to: self.describe(n),
                drag,
            });
        }
        None
    }

    /// One rolling step of every contact, the object turning from `theta` by `step`: the new
    /// contacts and their quality, or the first finger that cannot move and why.
    pub fn roll(&self, contacts: &[Contact], theta: Real, step: Real) -> Result<Roll, PlanError> {
        if !(step > 0.0 && step <= MAX_STEP) {
            return Err(PlanError::Settings(format!(
                "a rolling step of {} deg: one step turns the object by more than 0 and at most {} deg (one straight joint-space move)",
                degrees(step),
                degrees(MAX_STEP)
            )));
        }
        let idx: Vec<usize> = contacts.iter().map(|c| c.candidate).collect();
        let eval = self.problem.evaluate(&idx)?;
        let regions = match self.problem.icrs(&idx, &eval, self.settings.alpha) {
            Ok(r) => r,
            Err(e @ (IcrError::NotForceClosure | IcrError::MarginAboveQuality { .. })) => {
                return Ok(Roll::Stuck(format!("the grasp lost its margin: {e}")));
            }
            Err(e) => return Ok(Roll::Stuck(e.to_string())),
        };
        let regions: Vec<icrflow_grasp::icr::Region> = if self.settings.region_erosion == 0 {
            regions
        } else {
            regions
                .into_iter()
                .map(|r| icrflow_grasp::icr::Region {
                    members: self.erode(&r.members),
                    ..r
                })
                .collect()
        };
        let mut next = Vec::with_capacity(contacts.len());
        for (i, (c, region)) in contacts.iter().zip(&regions).enumerate() {
            let f = self.finger(c.finger);
            let target = self.behind(c.candidate, step);
            // The ICR members nearest the target, tried in order: the first the finger can
            // reach by rolling is the next contact.
            let pts = &self.problem.candidates().points;
            let mut order: Vec<usize> = region.members.iter().map(|&m| m as usize).collect();
            order.sort_by(|&a, &b| {
                (pts[a] - target)
                    .norm_squared()
                    .total_cmp(&(pts[b] - target).norm_squared())
                    .then(a.cmp(&b))
            });
            let mut first_block = None;
            let mut placed = None;
            for &n in order.iter().take(NEXT_CONTACT_TRIES) {
                if let Some(why) = self.travel(c.candidate, n, &target, theta, step, region) {
                    first_block.get_or_insert(why);
                    continue;
                }
                let gamma = c.gamma - self.arc(c.candidate, n) / f.tip_radius;
                match self.place(f, n, theta + step, gamma, &c.q, true) {
                    Ok(q) => {
                        placed = Some(Contact {
                            finger: c.finger,
                            candidate: n,
                            gamma,
                            q,
                        });
                        break;
                    }
                    Err(b) => {
                        first_block.get_or_insert(b);
                    }
                }
            }
            match (placed, first_block) {
                (Some(contact), _) => next.push(contact),
                (None, Some(b)) => return Ok(Roll::Blocked(i, b.to_string())),
                (None, None) => {
                    let why = match self.settings.region_erosion {
                        0 => "its ICR is empty".to_string(),
                        n => format!("its ICR shrunk by {n} ring(s) of candidates is empty"),
                    };
                    return Ok(Roll::Blocked(i, why));
                }
            }
        }
        if let Some(e) = self.overlap(&next) {
            return Ok(Roll::Stuck(format!("rolling on: {e}")));
        }
        let (quality, _) = self.quality(&next)?;
        if quality < self.settings.alpha * (1.0 - QUALITY_SLACK) {
            return Ok(Roll::Stuck(format!(
                "the next grasp would have quality {quality:.6} < alpha = {} (a defect: the ICRs guarantee the margin)",
                self.settings.alpha
            )));
        }
        Ok(Roll::Moved(next, quality))
    }
}

/// Whether finger `f`'s fingertip cap leaves room for contacts `cap_margin` (rad) inside its
/// edge (both planners' settings check): an error naming `plan.cap_margin_deg` if not.
pub(crate) fn cap_left(f: &Finger, cap_margin: Real) -> Result<(), PlanError> {
    if f.cap_half_angle <= cap_margin {
        return Err(PlanError::Settings(format!(
            "plan.cap_margin_deg: {} deg leaves no usable cap on finger {} (half-angle {} deg)",
            cap_margin.to_degrees(),
            f.id,
            f.cap_half_angle.to_degrees()
        )));
    }
    Ok(())
}

/// The candidate of `cands` nearest to `target`, found by walking their adjacency from `from`
/// to ever nearer neighbours (a local search: it touches only the points on the way), every
/// point on the way (but `from`) checked to be in `region` (sorted candidate indices, if
/// given): the end, or `Err` with the first point outside.
pub(crate) fn walk_candidates(
    cands: &icrflow_grasp::object::SurfaceSamples,
    from: usize,
    target: &Vec3,
    region: Option<&[u32]>,
) -> Result<usize, usize> {
    let dist = |i: usize| (cands.points[i] - target).norm_squared();
    let mut at = from;
    loop {
        let next = cands
            .adjacency
            .neighbours(at)
            .iter()
            .map(|&m| m as usize)
            .min_by(|&a, &b| dist(a).total_cmp(&dist(b)));
        match next {
            Some(n) if dist(n) < dist(at) => {
                if region.is_some_and(|r| r.binary_search(&(n as u32)).is_err()) {
                    return Err(n);
                }
                at = n;
            }
            _ => return Ok(at),
        }
    }
}

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

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// A hand of fingers 1-4 whose contacts are their numbers: finger 1 is blocked once the
    /// object has turned `limit` steps, and a free finger takes over only while it has turned
    /// at most `reach` steps (or never).
    struct Toy {
        limit: usize,
        reach: Option<usize>,
        /// Where a switch fails verification (a defect), if anywhere.
        defect: Option<usize>,
        step: Real,
    }

    impl Stepper for Toy {
        type Contact = u32;

        fn finger_of(c: &u32) -> u32 {
            *c
        }

        fn fingers(&self) -> usize {
            4
        }

        fn roll(&self, contacts: &[u32], theta: Real, step: Real) -> Result<Roll<u32>, PlanError> {
            let done = ((theta + step) / self.step).round() as usize;
            Ok(match contacts.iter().position(|&c| c == 1) {
                Some(k) if done > self.limit => Roll::Blocked(k, "at its limit".into()),
                // The quality falls while finger 1 holds: the steps dropped take theirs along.
                Some(_) => Roll::Moved(contacts.to_vec(), 1.0 - done as Real * 0.1),
                None => Roll::Moved(contacts.to_vec(), 0.95),
            })
        }

        fn switch(
            &self,
            contacts: &[u32],
            k: usize,
            theta: Real,
            why: &str,
            _: &mut dyn FnMut(Real),
        ) -> Result<Result<Switched<u32>, NoSwitch>, PlanError> {
            let done = (theta / self.step).round() as usize;
            if self.defect == Some(done) {
                return Ok(Err(NoSwitch::defect(format!("a defect at {done} steps"))));
            }
            if self.reach.is_none_or(|r| done > r) {
                return Ok(Err(NoSwitch::none(format!(
                    "no free finger reaches at {done} steps"
                ))));
            }
            let mut attach = contacts.to_vec();
            attach.push(4);
            let mut detach = attach.clone();
            let released = detach.remove(k);
            let switch = Switch {
                released,
                attached: 4,
                reason: why.to_string(),
                icr_region: Vec::new(),
                lp_region: Vec::new(),
                brute_force: Vec::new(),
                chosen_from: 0,
                rendezvous: 0,
                rendezvous_angle: None,
                room_steps: 0,
                ahead: 0.0,
                approach: None,
                retreat: None,
            };
            Ok(Ok((attach, detach, switch, 0.9, 0.9)))
        }

        fn record(&self, step: usize, phase: Phase, theta: Real, quality: Real, _: &[u32]) -> Step {
            Step::new(step, phase, theta, quality, Vec::new())
        }
    }

    /// Settings for a test of the loop: margins `alpha` and `gate_alpha`, `steps` steps of
    /// `step` (rad) to the goal; nothing else checked.
    pub(crate) fn settings(alpha: Real, gate_alpha: Real, step: Real, steps: usize) -> Settings {
        Settings {
            alpha,
            gate_alpha,
            goal: step * steps as Real,
            step,
            cap_margin: 0.0,
            min_manipulability: 0.0,
            squeeze_reserve: 0.0,
            region_erosion: 0,
            neighbour_alpha: None,
            neighbour_rings: 1,
            max_steps: 1000,
            attach_resolution: 0.01,
        }
    }

    fn plan(limit: usize, reach: Option<usize>) -> (Driven, usize) {
        plan_with(limit, reach, None)
    }

    fn plan_with(limit: usize, reach: Option<usize>, defect: Option<usize>) -> (Driven, usize) {
        let step = 5f64.to_radians();
        let toy = Toy {
            limit,
            reach,
            defect,
            step,
        };
        let mut moved = 0;
        let driven = drive(
            &toy,
            &settings(0.1, 0.1, step, 10),
            0.0,
            (vec![1, 2, 3], 1.0),
            &mut |_| {},
            &mut |_| moved += 1,
        )
        .unwrap();
        (driven, moved)
    }

    #[test]
    fn a_switch_that_fails_at_the_limit_is_made_earlier_the_steps_after_it_dropped() {
        // Blocked after 6 steps; a free finger reaches up to 4: released 2 steps early.
        let (d, moved) = plan(6, Some(4));
        assert_eq!(d.stop_reason, None);
        assert_eq!(d.switches, 1);
        let phases: Vec<Phase> = d.steps.iter().map(|s| s.phase).collect();
        let mut expected = vec![Phase::Start];
        expected.extend([Phase::Rolling; 4]);
        expected.extend([Phase::Attach, Phase::Detach]);
        expected.extend([Phase::Rolling; 6]);
        assert_eq!(phases, expected);
        // Numbered in order, the switch at the rotation of the step it follows.
        assert!(d.steps.iter().enumerate().all(|(i, s)| s.step == i));
        assert!((d.steps[5].rotation - d.steps[4].rotation).abs() < 1e-12);
        let w = d.steps[5].switch.as_ref().unwrap();
        assert_eq!((w.released, w.attached), (1, 4));
        assert!(
            w.reason.starts_with("released 2 steps early"),
            "{}",
            w.reason
        );
        // The dropped steps' contacts and qualities are gone: 10 rolling steps kept, the
        // lowest quality the 4th's (the dropped 6th's was 0.4).
        assert_eq!(moved, 10);
        assert!((d.min_quality - 0.6).abs() < 1e-12, "{}", d.min_quality);
    }

    #[test]
    fn a_switch_no_earlier_step_serves_stops_the_plan_with_the_first_reason() {
        // Too far back: EARLY_SWITCH_STEPS short of the limit is not enough.
        let (d, moved) = plan(8, Some(8 - EARLY_SWITCH_STEPS - 1));
        assert!(
            d.stop_reason.as_deref().unwrap().contains("at 8 steps"),
            "{:?}",
            d.stop_reason
        );
        assert_eq!(d.switches, 0);
        assert_eq!(moved, 8);
        assert_eq!(d.steps.len(), 9);
        let reason = d.stop_reason.unwrap();
        assert!(
            reason.contains("nor released up to 6 rolling steps earlier"),
            "{reason}"
        );
        // Blocked before any rolling step: nothing earlier to try.
        let (d, moved) = plan(0, None);
        assert_eq!((d.steps.len(), moved), (1, 0));
        assert_eq!(
            d.stop_reason.as_deref(),
            Some("no free finger reaches at 0 steps")
        );
        // Not past the start: blocked after 3 steps, tried 2 and 1 steps earlier.
        let (d, _) = plan(3, None);
        let reason = d.stop_reason.unwrap();
        assert!(
            reason.contains("at 3 steps") && reason.contains("up to 2 rolling steps earlier"),
            "{reason}"
        );
    }

    #[test]
    fn a_defect_stops_the_plan_where_it_is_found_no_earlier_switch_in_its_place() {
        // An earlier switch would serve (reach 4), but the one at the limit is a defect.
        let (d, moved) = plan_with(6, Some(4), Some(6));
        assert_eq!(d.switches, 0);
        assert_eq!(moved, 6);
        assert_eq!(d.stop_reason.as_deref(), Some("a defect at 6 steps"));
    }
}
