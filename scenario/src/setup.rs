//! Everything the planner (offline or in the pipeline) needs, built from a config.

use anyhow::{Context, Result, bail};
use icrflow_grasp::math::{Real, Vec3};
use icrflow_grasp::object::Object;
use icrflow_grasp::progress::Progress;
use icrflow_grasp::quality::{GraspError, GraspProblem};
use icrflow_grasp::wrench::{ContactModel, Space, WrenchFrame};
use icrflow_plan::follow::Planning;
use icrflow_plan::hand::Hand;
use icrflow_plan::planner::{Scenario, Start};
use icrflow_plan::rolling::{Roller, Surface, SurfaceError};
use icrflow_plan::spatial::rolling::Turning;
use icrflow_plan::spatial::surface::Convex;
use icrflow_plan::spatial::{Spatial, SpatialScenario};

use crate::bounds::num;
use crate::config::{Config, ContactSpec, FingerContact, ObjectSpec};

/// Everything the planner needs, built from a config.
pub struct Setup {
    /// The object.
    pub object: Object,
    /// The grasp problem (candidates: the object's section).
    pub problem: GraspProblem,
    /// The hand.
    pub hand: Hand,
    /// Initial contacts: (finger, candidate, cap angle).
    pub initial: Vec<(u32, usize, Option<Real>)>,
    /// The object's section as fingertips roll on it in the pipeline (the plant, the
    /// estimator, the planner node), or why they cannot: see [`Setup::surface`].
    surface: Result<Surface, SurfaceError>,
    /// For a spatial hand (a finger that is not a planar three-joint chain in the hand's
    /// plane): what the spatial planner rolls on. Then [`Setup::problem`]'s candidates are
    /// the object's facets and [`Setup::initial`]'s candidates the facets nearest the
    /// configured points.
    pub spatial: Option<SpatialSetup>,
}

/// What a spatial hand's plan rolls on ([`icrflow_plan::spatial`]).
pub struct SpatialSetup {
    /// The smooth convex surface the fingertips roll on (body frame).
    pub surface: Convex,
    /// The initial contacts: (finger, the configured point moved onto the surface).
    pub initial: Vec<(u32, Vec3)>,
}

/// A config file loaded, with what it builds: what a node of the pipeline starts from.
pub struct Loaded {
    /// The config.
    pub config: Config,
    /// What it builds.
    pub setup: Setup,
}

impl Loaded {
    /// Loads the config file at `path` and builds its setup.
    pub fn load(path: &std::path::Path) -> Result<Self> {
        let config = Config::load(path)?;
        let setup = Setup::new(&config)?;
        Ok(Self { config, setup })
    }
}

impl Setup {
    /// Builds and checks the scenario's parts; errors name the key or finger.
    pub fn new(config: &Config) -> Result<Self> {
        Self::new_with(config, &mut icrflow_grasp::progress::Silent)
    }

    /// [`Setup::new`], reporting the object's loading and the grasp problem's building to
    /// `progress`.
    pub fn new_with(
        config: &Config,
        progress: &mut dyn icrflow_grasp::progress::Progress,
    ) -> Result<Self> {
        let object = config.object.build_with(progress)?;
        let g = &config.grasp;
        let rho = g.rho.unwrap_or_else(|| object.max_radius());
        let frame = WrenchFrame::new(object.centre_of_mass, rho, g.space).context("grasp.rho")?;
        let hand = config.hand.build()?;
        if !hand.fingers.iter().all(|f| f.in_hand_plane()) {
            return Self::spatial(config, object, frame, hand, progress);
        }
        if let Some((key, what)) = config.hand_keys.spatial.first() {
            bail!(
                "{key}: {what}; this hand is planar (every finger a three-joint chain in the hand's plane z = 0), planned by the planar planner, so it has no effect: leave it out"
            );
        }
        let axis = config.turn.axis;
        if (axis - Vec3::z()).norm() > 1e-9 {
            bail!(
                "plan.axis: [{}, {}, {}]: the planar hand (three-joint fingers in the plane z = 0) turns objects about the hand's z axis only; give [0, 0, 1] or leave it out",
                num(axis.x),
                num(axis.y),
                num(axis.z)
            );
        }
        if object.section.samples.is_empty() {
            bail!(
                "object: the hand's plane (z = {:.4} m, through the centre of mass) does not cut it: no contact candidates",
                object.section.height
            );
        }
        let problem = section_problem(&object, frame, g.model, progress)?;
        let mut initial = Vec::with_capacity(g.contacts.len());
        for (i, c) in g.contacts.iter().enumerate() {
            if hand.finger(c.finger).is_none() {
                bail!(
                    "grasp.contacts[{i}].finger: finger {} is not in the hand (fingers {:?})",
                    c.finger,
                    hand.fingers.iter().map(|f| f.id).collect::<Vec<_>>()
                );
            }
            let (index, _) = snap_contact(&object, &problem, true, i, c)?;
            initial.push((c.finger, index, c.cap_angle));
        }
        one_free(config, &hand)?;
        let surface = Surface::new(
            &object.section,
            [object.centre_of_mass.x, object.centre_of_mass.y],
        );
        Ok(Self {
            object,
            problem,
            hand,
            initial,
            surface,
            spatial: None,
        })
    }

    /// The setup of a spatial hand: the grasp problem on the object's facets (its cones'
    /// tangents about the plan's axis), the exact surface the fingertips roll on, the
    /// configured contact points on it.
    fn spatial(
        config: &Config,
        object: Object,
        frame: WrenchFrame,
        hand: Hand,
        progress: &mut dyn Progress,
    ) -> Result<Self> {
        if let Some((key, what)) = config.hand_keys.planar.first() {
            bail!(
                "{key}: {what}; this hand is spatial (a finger that is not a three-joint chain in the hand's plane z = 0), planned by the spatial planner, so it has no effect: leave it out"
            );
        }
        let g = &config.grasp;
        let planar: Vec<u32> = hand
            .fingers
            .iter()
            .filter(|f| !f.in_hand_plane())
            .map(|f| f.id)
            .collect();
        if g.space != Space::Spatial {
            bail!(
                "grasp.space: fingers {planar:?} are not planar three-joint chains in the hand's plane, so the hand is planned in space, and its grasps need spatial analysis: set space = \"spatial\""
            );
        }
        let c = object.centre_of_mass;
        let surface = match &config.object {
            ObjectSpec::Sphere { radius, .. } => Convex::Sphere {
                centre: c,
                radius: *radius,
            },
            ObjectSpec::Ellipsoid { semi_axes, .. } => Convex::Ellipsoid {
                centre: c,
                semi_axes: Vec3::from(*semi_axes),
            },
            // Anything else as the convex polyhedron its mesh is.
            other => Convex::polyhedron(&object).map_err(|e| {
                anyhow::anyhow!(
                    "object: {}: a spatial hand's fingertips cannot roll on it: {e}",
                    other.describe()
                )
            })?,
        };
        let frame = frame
            .with_tangent_axis(config.turn.axis)
            .context("plan.axis")?;
        let problem = GraspProblem::new_with(
            &object.facets,
            object.facets.clone(),
            frame,
            g.model,
            progress,
        )?;
        let mut initial = Vec::with_capacity(g.contacts.len());
        let mut points = Vec::with_capacity(g.contacts.len());
        for (i, contact) in g.contacts.iter().enumerate() {
            if hand.finger(contact.finger).is_none() {
                bail!(
                    "grasp.contacts[{i}].finger: finger {} is not in the hand (fingers {:?})",
                    contact.finger,
                    hand.fingers.iter().map(|f| f.id).collect::<Vec<_>>()
                );
            }
            if let ContactSpec::Angle(_) = contact.at {
                bail!(
                    "grasp.contacts[{i}] (finger {}): angle_deg is a place on the object's section in the hand's plane; a spatial hand's contacts are points: give point = [x, y, z] (body frame, m)",
                    contact.finger
                );
            }
            if contact.cap_angle.is_some() {
                bail!(
                    "grasp.contacts[{i}].cap_angle_deg (finger {}): a planar hand's; a spatial hand's fingertip touches where its joints put it, found by inverse kinematics",
                    contact.finger
                );
            }
            let (index, _) = snap_contact(&object, &problem, false, i, contact)?;
            let ContactSpec::Point(p) = contact.at else {
                unreachable!("angles are refused above")
            };
            initial.push((contact.finger, index, None));
            points.push((contact.finger, surface.closest(&p).point));
        }
        one_free(config, &hand)?;
        let section = Surface::new(
            &object.section,
            [object.centre_of_mass.x, object.centre_of_mass.y],
        );
        Ok(Self {
            object,
            problem,
            hand,
            initial,
            surface: section,
            spatial: Some(SpatialSetup {
                surface,
                initial: points,
            }),
        })
    }

    /// The spatial planner's scenario, for a spatial hand ([`Setup::spatial`]).
    pub fn spatial_scenario<'a>(&'a self, config: &Config) -> Option<SpatialScenario<'a>> {
        let s = self.spatial.as_ref()?;
        Some(SpatialScenario {
            problem: &self.problem,
            hand: &self.hand,
            surface: &s.surface,
            centre: self.object.centre_of_mass,
            initial: s.initial.clone(),
            start_rotation: 0.0,
            start_joints: Vec::new(),
            settings: config.plan.clone(),
            spatial: Spatial {
                axis: config.turn.axis,
                link_radius: config.plant.link_radius,
                min_mobility: config.turn.min_mobility,
                part: icrflow_plan::spatial::PART,
            },
        })
    }

    /// What the pipeline's plant and estimator roll fingertips on: a planar hand's section
    /// ([`Setup::surface`], or why there is none), a spatial hand's object turning about
    /// `plan.axis`.
    pub fn roller(&self, config: &Config) -> Result<Roller<'_>> {
        Ok(match &self.spatial {
            Some(s) => Roller::Space(Turning {
                surface: &s.surface,
                centre: self.object.centre_of_mass,
                axis: nalgebra::Unit::new_normalize(config.turn.axis),
                held: Vec3::zeros(),
            }),
            None => Roller::Section(self.surface()?),
        })
    }

    /// What the planner node's follower plans with: the spatial planner's scenario for a
    /// spatial hand, else the planar planner's and the section its fingertips roll on
    /// ([`Setup::surface`], or why there is none).
    pub fn planning(&self, config: &Config) -> Result<Planning<'_>> {
        Ok(match self.spatial_scenario(config) {
            Some(s) => Planning::Spatial(s),
            None => Planning::Planar(self.scenario(config), self.surface()?),
        })
    }

    /// The initial grasp as the hand takes it: every finger's joints (in the hand's order;
    /// the free fingers at home) and the fingers in contact, by the planar or the spatial
    /// planner's start.
    pub fn initial_grip(&self, config: &Config) -> Result<(Vec<Vec<Real>>, Vec<u32>)> {
        let placed: Vec<(u32, Vec<Real>)> = match self.spatial_scenario(config) {
            Some(s) => {
                let (touches, _) = s.start().context("the initial grasp")?;
                touches.into_iter().map(|t| (t.finger, t.q)).collect()
            }
            None => {
                let (contacts, _) = self.scenario(config).start().context("the initial grasp")?;
                contacts.into_iter().map(|c| (c.finger, c.q)).collect()
            }
        };
        let joints = self
            .hand
            .fingers
            .iter()
            .map(|f| {
                placed
                    .iter()
                    .find(|(id, _)| *id == f.id)
                    .map_or_else(|| f.home.clone(), |(_, q)| q.clone())
            })
            .collect();
        Ok((joints, placed.into_iter().map(|(id, _)| id).collect()))
    }

    /// The object's section as the pipeline's plant and estimator roll fingertips on it, or
    /// why they cannot (named by its key). Offline planning does not need it.
    pub fn surface(&self) -> Result<&Surface> {
        self.surface.as_ref().map_err(|e| {
            anyhow::anyhow!(
                "object: the pipeline's plant and estimator cannot roll fingertips on it: {e}"
            )
        })
    }

    /// The scenario for the planner.
    pub fn scenario<'a>(&'a self, config: &Config) -> Scenario<'a> {
        Scenario {
            problem: &self.problem,
            hand: &self.hand,
            centre: self.object.centre_of_mass,
            angles: Some(&self.object.section.angles),
            initial: self.initial.clone(),
            start: Start::default(),
            settings: config.plan.clone(),
        }
    }
}

/// A plan needs a free finger to take over when one reaches its limit.
fn one_free(config: &Config, hand: &Hand) -> Result<()> {
    if hand
        .fingers
        .iter()
        .all(|f| config.grasp.contacts.iter().any(|c| c.finger == f.id))
    {
        bail!(
            "grasp.contacts: every finger of the hand ({:?}) is in contact, so none is free to take over when one reaches its limit; leave one out",
            hand.fingers.iter().map(|f| f.id).collect::<Vec<_>>()
        );
    }
    Ok(())
}

/// How far a configured contact point may lie from the object's surface (m): 1 mm, or 1 % of
/// the object's largest radius if that is more (a point written with a few digits, on a mesh
/// that only approximates the surface).
pub fn surface_tolerance(object: &Object) -> Real {
    (0.01 * object.max_radius()).max(1e-3)
}

/// How far a configured contact moved to its candidate.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Snap {
    /// From the configured angle on the section to the candidate's (rad).
    Angle(Real),
    /// From the configured point (or, for an angle, its point of the section) to the
    /// candidate (m).
    Distance(Real),
}

/// The grasp problem whose candidates are `object`'s section in the hand's plane, where the
/// fingertips roll: the one the planner, `validate`, `plan` and `run` evaluate (a spatial
/// `analyze` evaluates the facets and this one beside them).
pub fn section_problem(
    object: &Object,
    frame: WrenchFrame,
    model: ContactModel,
    progress: &mut dyn Progress,
) -> Result<GraspProblem, GraspError> {
    GraspProblem::new_with(
        &object.facets,
        object.section.samples.clone(),
        frame,
        model,
        progress,
    )
}

/// Snaps contact `i` of the config to a candidate of `problem`, whose candidates are the
/// object's section in the hand's plane when `section` (planar analysis, and the planner
/// always), else its facets; returns the candidate and how far the contact moved. The one
/// place every verb resolves a contact: a point must lie on the object's surface within
/// [`surface_tolerance`], and for section candidates in the hand's plane too, else it is
/// refused with the distance.
pub fn snap_contact(
    object: &Object,
    problem: &GraspProblem,
    section: bool,
    i: usize,
    c: &FingerContact,
) -> Result<(usize, Snap)> {
    let key = |k: &str| format!("grasp.contacts[{i}]{k} (finger {})", c.finger);
    let cands = problem.candidates();
    match c.at {
        ContactSpec::Angle(a) => {
            let (s, d) = object
                .section
                .nearest_angle(a)
                .with_context(|| format!("{}: the object's section has no samples", key("")))?;
            if section {
                return Ok((s, Snap::Angle(d)));
            }
            // Facet candidates: the facet nearest to that point of the section.
            let (f, d) = cands
                .nearest(&object.section.samples.points[s])
                .with_context(|| format!("{}: the object has no facets", key("")))?;
            Ok((f, Snap::Distance(d)))
        }
        ContactSpec::Point(p) => {
            let tolerance = surface_tolerance(object);
            let off = object.surface_distance(&p);
            if off > tolerance {
                bail!(
                    "{}: [{}, {}, {}] is {} from the object's surface; a contact must lie on it (within {})",
                    key(".point"),
                    crate::bounds::num(p.x),
                    crate::bounds::num(p.y),
                    crate::bounds::num(p.z),
                    length(off),
                    length(tolerance)
                );
            }
            if section {
                let off = (p.z - object.section.height).abs();
                if off > tolerance {
                    bail!(
                        "{}: [{}, {}, {}] is {} off the hand's plane z = {:.4} m, where the contact candidates are (the object's section); the planner and planar analysis take contacts in that plane (within {})",
                        key(".point"),
                        crate::bounds::num(p.x),
                        crate::bounds::num(p.y),
                        crate::bounds::num(p.z),
                        length(off),
                        object.section.height,
                        length(tolerance)
                    );
                }
            }
            let (n, d) = cands
                .nearest(&p)
                .with_context(|| format!("{}: the object has no candidates", key("")))?;
            Ok((n, Snap::Distance(d)))
        }
    }
}

/// A length for messages: millimetres below a metre, metres above.
fn length(x: Real) -> String {
    if x < 1.0 {
        format!("{:.2} mm", 1e3 * x)
    } else {
        format!("{:.3} m", x)
    }
}
