//! `icrflow analyze CONFIG [--json]`.

use std::io::Write;
use std::path::Path;

use anyhow::{Context, Result, bail};
use icrflow_grasp::icr::IcrError;
use icrflow_grasp::math::Real;
use icrflow_grasp::progress::Progress;
use icrflow_grasp::quality::{Closure, GraspProblem};
use icrflow_grasp::wrench::{Space, WrenchFrame};
use serde::Serialize;

use icrflow_scenario::{Config, Snap, section_problem, snap_contact};

/// The JSON report (and the data behind the text one).
#[derive(Debug, Serialize)]
pub struct Report {
    pub config: String,
    pub object: String,
    pub facets: usize,
    pub candidates: usize,
    pub space: &'static str,
    pub friction: Real,
    pub cone_edges: usize,
    pub rho: Real,
    pub alpha: Real,
    /// The plan's margin (`plan.alpha`) where it keeps more than the grasp's (`grasp.alpha`,
    /// the hand's gate, which this analysis and its regions are at): `validate`, `plan` and
    /// `run` hold the initial grasp to it.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub plan_alpha: Option<Real>,
    pub force_closure: bool,
    /// "force_closure", "origin_on_boundary", "origin_outside" or "degenerate".
    pub closure: &'static str,
    pub quality: Real,
    pub epsilon: Real,
    pub hull_facets: usize,
    /// Which candidates the contacts were snapped to: "section" (the object's section in the
    /// hand's plane: planar analysis, and what validate, plan and run evaluate) or "facets"
    /// (the mesh's facets: spatial analysis).
    pub contacts_on: &'static str,
    /// Spatial analysis: alpha* of the same contacts on the object's section in the hand's
    /// plane, the grasp validate, plan and run evaluate (`None`: planar analysis, whose grasp
    /// is that one, or the contacts do not lie in the hand's plane).
    pub section_quality: Option<Real>,
    /// Whether the config's hand is spatial: `plan` then takes the contacts on the facets, the
    /// cones' tangents about `plan.axis`, as this analysis does.
    #[serde(skip)]
    pub spatial_hand: bool,
    /// Why the regions were not computed, if they were not.
    pub icr_status: Option<String>,
    pub contacts: Vec<ContactReport>,
    pub warnings: Vec<String>,
}

/// One finger's contact and region.
#[derive(Debug, Serialize)]
pub struct ContactReport {
    pub finger: u32,
    pub candidate: usize,
    pub point: [Real; 3],
    pub normal: [Real; 3],
    /// Planar problems: the contact's angle on the section (degrees, [0, 360)).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub angle_deg: Option<Real>,
    /// Distance from the configured contact to the candidate it was snapped to (m, or
    /// degrees for angles on the section of a planar problem).
    pub snap: Real,
    /// Whether `snap` is in degrees.
    #[serde(skip)]
    pub snap_in_degrees: bool,
    pub icr: Option<IcrReport>,
}

/// One region.
#[derive(Debug, Serialize)]
pub struct IcrReport {
    pub indices: Vec<u32>,
    pub points: Vec<[Real; 3]>,
    /// Planar problems: the region as angle intervals `[start, end]` in degrees, start in
    /// [0, 360), end >= start (an interval across 0 degrees ends above 360).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub angle_intervals_deg: Option<Vec<[Real; 2]>>,
    /// Spatial problems: where the region lies, seen from the centre of mass.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub extent: Option<Extent>,
}

/// Where a region of facets lies on the object, seen from its centre of mass (body frame,
/// z up: azimuth in the hand's plane from +x, elevation above it).
#[derive(Debug, Serialize)]
pub struct Extent {
    /// Azimuth of the region's facet centres, `[from, to]` in degrees, from in [0, 360), to
    /// >= from (a region across 0 degrees ends above 360), as the planar intervals.
    pub azimuth_deg: [Real; 2],
    /// Elevation of the facet centres above the hand's plane, `[lowest, highest]` in degrees.
    pub elevation_deg: [Real; 2],
    /// The largest distance of a facet centre from the contact (m).
    pub radius: Real,
    /// The region's surface area (m^2).
    pub area: Real,
}

/// The extent of the region `members` (candidate facets) around `contact`, seen from `com`.
fn extent(
    members: &[u32],
    contact: usize,
    cands: &icrflow_grasp::object::SurfaceSamples,
    com: &icrflow_grasp::math::Vec3,
) -> Extent {
    let direction = |p: &icrflow_grasp::math::Vec3| {
        let d = p - com;
        (
            d.y.atan2(d.x).to_degrees(),
            d.z.atan2(d.x.hypot(d.y)).to_degrees(),
        )
    };
    let (around, _) = direction(&cands.points[contact]);
    let (mut az, mut el) = (
        [Real::INFINITY, Real::NEG_INFINITY],
        [Real::INFINITY, Real::NEG_INFINITY],
    );
    let (mut radius, mut area) = (0.0 as Real, 0.0 as Real);
    for &m in members {
        let m = m as usize;
        let (a, e) = direction(&cands.points[m]);
        // Relative to the contact's azimuth, in (-180, 180]: a region across 180 stays whole.
        let rel = (a - around + 540.0).rem_euclid(360.0) - 180.0;
        az = [az[0].min(rel), az[1].max(rel)];
        el = [el[0].min(e), el[1].max(e)];
        radius = radius.max((cands.points[m] - cands.points[contact]).norm());
        area += cands.areas[m];
    }
    let from = (around + az[0]).rem_euclid(360.0);
    Extent {
        azimuth_deg: [from, from + (az[1] - az[0])],
        elevation_deg: el,
        radius,
        area,
    }
}

/// Runs the verb; returns the exit status: [`crate::exit::INCOMPLETE`] when the grasp is not
/// force closure or its quality is below the margin (no regions).
pub fn run(path: &Path, json: bool, progress_after: std::time::Duration) -> Result<u8> {
    let config = Config::load(path)?;
    let mut shown = crate::progress::Shown::new(progress_after);
    let report = analyze(&config, &mut shown)?;
    drop(shown);
    let mut out = std::io::stdout().lock();
    if json {
        serde_json::to_writer_pretty(&mut out, &report).context("writing JSON")?;
        writeln!(out)?;
    } else {
        print_text(&mut out, &report)?;
    }
    Ok(if report.force_closure && report.quality >= report.alpha {
        crate::exit::DONE
    } else {
        crate::exit::INCOMPLETE
    })
}

/// Analyses the configured grasp.
pub fn analyze(config: &Config, progress: &mut dyn Progress) -> Result<Report> {
    let object = config.object.build_with(progress)?;
    let g = &config.grasp;
    let rho = g.rho.unwrap_or_else(|| object.max_radius());
    let frame = WrenchFrame::new(object.centre_of_mass, rho, g.space).context("grasp.rho")?;
    // A spatial hand's plan evaluates its grasps on the facets with the cones' tangents about
    // its axis: so does the analysis (a hand that does not build is left to validate).
    let spatial_hand = g.space == Space::Spatial
        && config
            .hand
            .build()
            .is_ok_and(|h| !h.fingers.iter().all(|f| f.in_hand_plane()));
    let frame = if spatial_hand {
        frame
            .with_tangent_axis(config.turn.axis)
            .context("plan.axis")?
    } else {
        frame
    };
    let (candidates, angles) = match g.space {
        Space::Planar => {
            if object.section.samples.is_empty() {
                bail!("the hand's plane does not cut the object: no planar candidates");
            }
            (
                object.section.samples.clone(),
                Some(object.section.angles.clone()),
            )
        }
        Space::Spatial => (object.facets.clone(), None),
    };
    let problem = GraspProblem::new_with(&object.facets, candidates, frame, g.model, progress)?;
    let mut indices = Vec::with_capacity(g.contacts.len());
    let mut snaps = Vec::with_capacity(g.contacts.len());
    for (i, c) in g.contacts.iter().enumerate() {
        let (index, snap) = snap_contact(&object, &problem, g.space == Space::Planar, i, c)?;
        indices.push(index);
        snaps.push(snap);
    }
    let eval = problem.evaluate(&indices)?;
    // A spatial analysis snaps the contacts to the mesh's facets; validate, plan and run take
    // them on the section in the hand's plane: that grasp's quality too, so both are said.
    let section_quality = match g.space {
        Space::Planar => None,
        Space::Spatial if spatial_hand => None,
        Space::Spatial if object.section.samples.is_empty() => None,
        Space::Spatial => {
            let section = section_problem(&object, frame, g.model, progress)?;
            let on: Result<Vec<usize>> = g
                .contacts
                .iter()
                .enumerate()
                .map(|(i, c)| snap_contact(&object, &section, true, i, c).map(|(k, _)| k))
                .collect();
            match on {
                Ok(on) => section.evaluate(&on).ok().map(|e| e.quality),
                // Off the hand's plane: no grasp there to compare with.
                Err(_) => None,
            }
        }
    };
    let regions = match problem.icrs(&indices, &eval, g.alpha) {
        Ok(r) => Ok(r),
        Err(e @ (IcrError::NotForceClosure | IcrError::MarginAboveQuality { .. })) => Err(e),
        Err(e) => return Err(e.into()),
    };
    let cands = problem.candidates();
    let to3 = |v: &icrflow_grasp::math::Vec3| [v.x, v.y, v.z];
    let contacts = g
        .contacts
        .iter()
        .enumerate()
        .map(|(i, c)| {
            let q = indices[i];
            ContactReport {
                finger: c.finger,
                candidate: q,
                point: to3(&cands.points[q]),
                normal: to3(&cands.normals[q]),
                angle_deg: angles.as_ref().map(|a| a[q].to_degrees()),
                snap: match snaps[i] {
                    Snap::Angle(a) => a.to_degrees(),
                    Snap::Distance(d) => d,
                },
                snap_in_degrees: matches!(snaps[i], Snap::Angle(_)),
                icr: regions.as_ref().ok().map(|r| {
                    let members = &r[i].members;
                    IcrReport {
                        indices: members.clone(),
                        points: members
                            .iter()
                            .map(|&m| to3(&cands.points[m as usize]))
                            .collect(),
                        angle_intervals_deg: angles.as_ref().map(|a| angle_intervals(members, a)),
                        extent: angles
                            .is_none()
                            .then(|| extent(members, q, cands, &object.centre_of_mass)),
                    }
                }),
            }
        })
        .collect();
    Ok(Report {
        config: config.path.display().to_string(),
        object: config.object.describe(),
        facets: object.facets.len(),
        candidates: cands.len(),
        space: g.space.name(),
        friction: g.model.mu(),
        cone_edges: g.model.edges(),
        rho,
        alpha: g.alpha,
        plan_alpha: (config.plan.alpha > g.alpha).then_some(config.plan.alpha),
        force_closure: eval.force_closure(),
        closure: match eval.closure {
            Closure::ForceClosure => "force_closure",
            Closure::OriginOnBoundary => "origin_on_boundary",
            Closure::OriginOutside => "origin_outside",
            Closure::Degenerate { .. } => "degenerate",
        },
        quality: eval.quality,
        epsilon: eval.epsilon,
        hull_facets: eval.hull.as_ref().map_or(0, |h| h.facet_count()),
        contacts_on: match g.space {
            Space::Planar => "section",
            Space::Spatial => "facets",
        },
        section_quality,
        spatial_hand,
        icr_status: regions.as_ref().err().map(|e| e.to_string()),
        contacts,
        warnings: object.warnings.iter().map(|w| w.to_string()).collect(),
    })
}

/// Groups region members (section samples) into angle intervals, in degrees. Samples are
/// split where the angular gap exceeds 1.5 times the section's largest sample spacing.
pub fn angle_intervals(members: &[u32], angles: &[Real]) -> Vec<[Real; 2]> {
    if members.is_empty() {
        return Vec::new();
    }
    let mut all: Vec<Real> = angles.iter().map(|a| a.to_degrees()).collect();
    all.sort_by(Real::total_cmp);
    let spacing = all
        .windows(2)
        .map(|w| w[1] - w[0])
        .chain(std::iter::once(all[0] + 360.0 - all[all.len() - 1]))
        .fold(0.0, Real::max);
    let mut a: Vec<Real> = members
        .iter()
        .map(|&m| angles[m as usize].to_degrees())
        .collect();
    a.sort_by(Real::total_cmp);
    let limit = 1.5 * spacing;
    let mut runs: Vec<[Real; 2]> = vec![[a[0], a[0]]];
    for &x in &a[1..] {
        let last = runs.len() - 1;
        if x - runs[last][1] <= limit {
            runs[last][1] = x;
        } else {
            runs.push([x, x]);
        }
    }
    // Join the last run with the first across 0 degrees.
    if runs.len() > 1 && runs[0][0] + 360.0 - runs[runs.len() - 1][1] <= limit {
        let first = runs.remove(0);
        let last = runs.len() - 1;
        runs[last][1] = first[1] + 360.0;
    } else if runs.len() == 1 && runs[0][0] + 360.0 - runs[0][1] <= limit {
        // The whole section.
        runs[0] = [0.0, 360.0];
    }
    runs
}

fn print_text(out: &mut impl Write, r: &Report) -> Result<()> {
    writeln!(out, "config    {}", r.config)?;
    writeln!(out, "object    {} ({} facets)", r.object, r.facets)?;
    writeln!(
        out,
        "grasp     {} space, {} candidates, mu = {}, s = {} cone edges, rho = {:.4} m, margin alpha = {}",
        r.space, r.candidates, r.friction, r.cone_edges, r.rho, r.alpha
    )?;
    for w in &r.warnings {
        writeln!(out, "warning   {w}")?;
    }
    for c in &r.contacts {
        let at = match c.angle_deg {
            Some(a) => format!("{a:7.2} deg"),
            None => format!(
                "[{:.4}, {:.4}, {:.4}] m",
                c.point[0], c.point[1], c.point[2]
            ),
        };
        let snap = if c.snap_in_degrees {
            format!("{:.2} deg", c.snap)
        } else {
            format!("{:.2} mm", 1e3 * c.snap)
        };
        writeln!(
            out,
            "contact   finger {} at {at} (candidate {}, snapped by {snap})",
            c.finger, c.candidate
        )?;
    }
    if r.force_closure {
        writeln!(out, "closure   force closure (epsilon = {:.6})", r.epsilon)?;
        let verdict = if r.quality >= r.alpha { ">=" } else { "<" };
        writeln!(
            out,
            "quality   alpha* = {:.6} {verdict} alpha = {} ({} hull facets)",
            r.quality, r.alpha, r.hull_facets
        )?;
        if let Some(plan) = r.plan_alpha {
            // The grasp validate, plan and run evaluate: on the section for a planar hand.
            let quality = r.section_quality.unwrap_or(r.quality);
            let (verdict, then) = if quality >= plan {
                (">=", "validate, plan and run take it")
            } else {
                ("<", "validate, plan and run refuse it")
            };
            writeln!(
                out,
                "          {verdict} plan.alpha = {plan}, the plan's margin over the hand's: {then}"
            )?;
        }
        if r.contacts_on == "facets" {
            writeln!(
                out,
                "          with the contacts on the nearest mesh facets (spatial analysis, its ICRs too);"
            )?;
            match r.section_quality {
                _ if r.spatial_hand => writeln!(
                    out,
                    "          as plan takes them for this spatial hand (the cones' tangents about plan.axis)"
                )?,
                Some(q) => writeln!(
                    out,
                    "          on the section in the hand's plane (validate, plan, run): alpha* = {q:.6}"
                )?,
                None => writeln!(
                    out,
                    "          (off the hand's plane, where validate, plan and run take the contacts)"
                )?,
            }
        }
    } else {
        writeln!(
            out,
            "closure   NOT force closure ({}, epsilon = {:.6}): the contacts cannot resist every wrench, alpha* = 0",
            r.closure.replace('_', " "),
            r.epsilon
        )?;
    }
    match &r.icr_status {
        Some(why) => writeln!(out, "ICRs      not computed: {why}")?,
        None => {
            if r.contacts
                .iter()
                .any(|c| c.icr.as_ref().is_some_and(|i| i.extent.is_some()))
            {
                writeln!(
                    out,
                    "ICRs      where they lie, from the centre of mass: azimuth in the hand's plane from +x,"
                )?;
                writeln!(
                    out,
                    "          elevation above it; within: the farthest facet from the contact"
                )?;
            }
            for c in &r.contacts {
                let Some(icr) = &c.icr else { continue };
                match (&icr.angle_intervals_deg, &icr.extent) {
                    (Some(iv), _) => writeln!(
                        out,
                        "ICR       finger {}: {} points, {}",
                        c.finger,
                        icr.indices.len(),
                        iv.iter()
                            .map(|[a, b]| format!("{a:.1} .. {:.1} deg", b % 360.0))
                            .collect::<Vec<_>>()
                            .join(", ")
                    )?,
                    (None, Some(e)) => writeln!(
                        out,
                        "ICR       finger {}: {} facets, {:.1} mm^2, azimuth {:.1} .. {:.1}, elevation {:.1} .. {:.1} deg, within {:.1} mm",
                        c.finger,
                        icr.indices.len(),
                        e.area * 1e6,
                        e.azimuth_deg[0],
                        e.azimuth_deg[1] % 360.0,
                        e.elevation_deg[0],
                        e.elevation_deg[1],
                        e.radius * 1e3
                    )?,
                    (None, None) => writeln!(
                        out,
                        "ICR       finger {}: {} points",
                        c.finger,
                        icr.indices.len()
                    )?,
                }
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn intervals_split_and_wrap() {
        let angles: Vec<Real> = (0..72).map(|k| (5.0 * k as Real).to_radians()).collect();
        let iv = angle_intervals(&[1, 2, 3, 10, 11], &angles);
        let close = |a: &[[Real; 2]], b: &[[Real; 2]]| {
            a.len() == b.len()
                && a.iter()
                    .zip(b)
                    .all(|(x, y)| (x[0] - y[0]).abs() < 1e-9 && (x[1] - y[1]).abs() < 1e-9)
        };
        assert!(close(&iv, &[[5.0, 15.0], [50.0, 55.0]]), "{iv:?}");
        let iv = angle_intervals(&[70, 71, 0, 1], &angles);
        assert_eq!(iv.len(), 1);
        assert!((iv[0][0] - 350.0).abs() < 1e-9 && (iv[0][1] - 365.0).abs() < 1e-9);
        let all: Vec<u32> = (0..72).collect();
        assert_eq!(angle_intervals(&all, &angles), vec![[0.0, 360.0]]);
    }
}
