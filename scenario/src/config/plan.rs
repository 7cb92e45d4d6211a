//! `[plan]`: the planner's settings (`icrflow_plan::planner::Settings`) and what the object
//! turns about ([`Turn`]).

use anyhow::{Result, bail};
use icrflow_grasp::math::{Real, Vec3};
use icrflow_plan::planner::Settings;

use super::components;
use crate::bounds::{self, num};
use crate::raw::RawPlan;

/// Planner defaults.
pub const DEFAULT_ROTATION_DEG: Real = 360.0;
/// Default squeeze reserve every contact pose of a plan keeps (mm).
pub const DEFAULT_SQUEEZE_RESERVE_MM: Real = 2.0;
/// Default object rotation per rolling step (deg).
pub const DEFAULT_STEP_DEG: Real = 5.0;
/// `plan.max_plan_s` when not given (s): seven times the longest shipped plan's CPU time (the
/// mesh ellipsoid's ~42 s), so that a machine under load still plans them whole.
pub const DEFAULT_MAX_PLAN_S: Real = 300.0;

/// What the object turns about, and the spatial planner's own limits (`[plan]`).
#[derive(Debug, Clone, PartialEq)]
pub struct Turn {
    /// The unit axis (hand frame) the object turns about, positive by the right-hand rule
    /// (`plan.axis`, normalised; `[0, 0, 1]` by default, the only axis of a planar hand).
    pub axis: Vec3,
    /// Smallest singular value of a spatial finger's fingertip-centre Jacobian in contact
    /// (m per rad; `plan.min_mobility_mm`).
    pub min_mobility: Real,
}

/// Keys given that only one kind of hand's planning reads: the `[plan]` keys of one planner,
/// and `plant.link_radius_mm` on the kinematic plant (there only the spatial planner reads
/// it). Which kind the hand is, the hand it builds says: [`Setup::new`](crate::Setup::new)
/// refuses the other kind's keys, naming the key and the hand.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct HandKeys {
    /// Keys only a planar hand's planning reads, as given: (key, what it is).
    pub planar: Vec<(&'static str, &'static str)>,
    /// Keys only a spatial hand's planning reads, as given: (key, what it is).
    pub spatial: Vec<(&'static str, &'static str)>,
}

/// The [`HandKeys`] of a `[plan]` section; `link_radius`: whether `plant.link_radius_mm` is
/// given with the kinematic plant.
pub(crate) fn hand_keys(raw: Option<&RawPlan>, link_radius: bool) -> HandKeys {
    let mut keys = HandKeys::default();
    if let Some(r) = raw {
        for (key, given, what) in [
            (
                "plan.min_manipulability",
                r.min_manipulability.is_some(),
                "the planar planner's least manipulability of a finger in contact (a spatial hand's limit is plan.min_mobility_mm)",
            ),
            (
                "plan.attach_resolution_deg",
                r.attach_resolution_deg.is_some(),
                "the planar planner's grid of fingertip cap angles for an attaching finger (a spatial hand's fingertip touches where its inverse kinematics puts it)",
            ),
        ] {
            if given {
                keys.planar.push((key, what));
            }
        }
        for (key, given, what) in [
            (
                "plan.min_mobility_mm",
                r.min_mobility_mm.is_some(),
                "the spatial planner's least fingertip mobility in contact (a planar hand's limit is plan.min_manipulability)",
            ),
            (
                "plan.neighbour_alpha",
                r.neighbour_alpha.is_some(),
                "the spatial planner's check of the grasps with a contact moved to a neighbouring candidate (a planar hand keeps its contacts off the regions' edges by plan.region_erosion)",
            ),
            (
                "plan.neighbour_rings",
                r.neighbour_rings.is_some(),
                "the rings the spatial planner checks plan.neighbour_alpha over",
            ),
        ] {
            if given {
                keys.spatial.push((key, what));
            }
        }
    }
    if link_radius {
        keys.spatial.push((
            "plant.link_radius_mm",
            "the links' capsules, which only the MuJoCo plant and the spatial planner have (plant.kind = \"kinematic\" here)",
        ));
    }
    keys
}

/// Default `plan.min_mobility_mm`.
pub const DEFAULT_MIN_MOBILITY_MM: Real = 5.0;

pub(crate) fn turn_spec(raw: Option<&RawPlan>) -> Result<Turn> {
    let axis = match raw.and_then(|r| r.axis.as_deref()) {
        None => Vec3::z(),
        Some(a) => {
            let a: [Real; 3] = components("plan.axis", a, "[x, y, z]")?;
            let v = Vec3::from(a);
            if !v.iter().all(|x| x.is_finite()) || v.norm() < 1e-9 {
                bail!(
                    "plan.axis: [{}, {}, {}] is not a direction (finite, not zero)",
                    num(a[0]),
                    num(a[1]),
                    num(a[2])
                );
            }
            v.normalize()
        }
    };
    let min_mobility = bounds::MOBILITY.or(
        "plan.min_mobility_mm",
        raw.and_then(|r| r.min_mobility_mm),
        DEFAULT_MIN_MOBILITY_MM,
    )? * 1e-3;
    Ok(Turn { axis, min_mobility })
}

pub(crate) fn plan_spec(raw: Option<RawPlan>, alpha: Real) -> Result<Settings> {
    let raw = raw.unwrap_or(RawPlan {
        rotation_deg: None,
        step_deg: None,
        cap_margin_deg: None,
        min_manipulability: None,
        max_steps: None,
        max_plan_s: None,
        attach_resolution_deg: None,
        squeeze_reserve_mm: None,
        region_erosion: None,
        neighbour_alpha: None,
        neighbour_rings: None,
        alpha: None,
        axis: None,
        min_mobility_mm: None,
    });
    let rotation =
        bounds::ROTATION.or("plan.rotation_deg", raw.rotation_deg, DEFAULT_ROTATION_DEG)?;
    let step = bounds::STEP.or("plan.step_deg", raw.step_deg, DEFAULT_STEP_DEG)?;
    let cap_margin = bounds::CAP_MARGIN.or("plan.cap_margin_deg", raw.cap_margin_deg, 5.0)?;
    let m = bounds::MANIPULABILITY.or("plan.min_manipulability", raw.min_manipulability, 1e-4)?;
    let max_steps = bounds::MAX_STEPS.check("plan.max_steps", raw.max_steps.unwrap_or(100_000))?;
    // The rolling steps alone: a plan that cannot reach its goal within max_steps is refused
    // before it starts (switches add two steps each on top).
    let rolling = (rotation / step).ceil();
    if rolling >= max_steps as Real {
        bail!(
            "plan.max_steps: {max_steps} steps cannot turn plan.rotation_deg = {} deg in steps of plan.step_deg = {} deg, which takes {} rolling steps (and the start, and two per finger switch)",
            num(rotation),
            num(step),
            num(rolling)
        );
    }
    // The plan's margin: the hand's (`grasp.alpha`, which the command node's gate holds the
    // estimated grasp to), or more, as headroom for contacts the estimate snaps a candidate
    // off the plan's.
    let plan_alpha = bounds::ALPHA.or("plan.alpha", raw.alpha, alpha)?;
    if raw.neighbour_rings.is_some() && raw.neighbour_alpha.is_none() {
        bail!(
            "plan.neighbour_rings: the rings plan.neighbour_alpha is checked over, given without it (nothing is checked)"
        );
    }
    if plan_alpha < alpha {
        bail!(
            "plan.alpha: {} is below grasp.alpha = {}: the plan keeps at least the margin the hand's gate holds to (leave plan.alpha out to plan at grasp.alpha)",
            num(plan_alpha),
            num(alpha)
        );
    }
    Ok(Settings {
        alpha: plan_alpha,
        gate_alpha: alpha,
        goal: rotation.to_radians(),
        step: step.to_radians(),
        cap_margin: cap_margin.to_radians(),
        min_manipulability: m,
        max_steps,
        max_plan: Some(std::time::Duration::from_secs_f64(bounds::MAX_PLAN.or(
            "plan.max_plan_s",
            raw.max_plan_s,
            DEFAULT_MAX_PLAN_S,
        )?)),
        attach_resolution: bounds::ATTACH_RESOLUTION
            .or("plan.attach_resolution_deg", raw.attach_resolution_deg, 2.0)?
            .to_radians(),
        squeeze_reserve: bounds::SQUEEZE_RESERVE.or(
            "plan.squeeze_reserve_mm",
            raw.squeeze_reserve_mm,
            DEFAULT_SQUEEZE_RESERVE_MM,
        )? * 1e-3,
        region_erosion: bounds::REGION_EROSION
            .check("plan.region_erosion", raw.region_erosion.unwrap_or(0))?,
        neighbour_alpha: raw
            .neighbour_alpha
            .map(|a| bounds::ALPHA.check("plan.neighbour_alpha", a))
            .transpose()?,
        neighbour_rings: bounds::NEIGHBOUR_RINGS
            .check("plan.neighbour_rings", raw.neighbour_rings.unwrap_or(1))?,
    })
}
