//! `[plan]`: the planner's settings (`icrflow_plan::planner::Settings`) and what the object
//! turns about ([`Turn`]).

use anyhow::{Result, bail};
use icrflow_grasp::math::{Real, Vec3};
use icrflow_plan::planner::Settings;

use crate::bounds::{self, num};
use crate::raw::RawPlan;

/// Planner defaults.
pub const DEFAULT_ROTATION_DEG: Real = 360.0;
/// Default squeeze reserve every contact pose of a plan keeps (mm).
pub const DEFAULT_SQUEEZE_RESERVE_MM: Real = 2.0;
/// Default object rotation per rolling step (deg).
pub const DEFAULT_STEP_DEG: Real = 5.0;

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

/// Default `plan.min_mobility_mm`.
pub const DEFAULT_MIN_MOBILITY_MM: Real = 5.0;

pub(crate) fn turn_spec(raw: Option<&RawPlan>) -> Result<Turn> {
    let axis = match raw.and_then(|r| r.axis) {
        None => Vec3::z(),
        Some(a) => {
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
