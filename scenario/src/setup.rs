//! Everything the planner (offline or in the pipeline) needs, built from a config.

use anyhow::{Context, Result, bail};
use icrflow_grasp::math::Real;
use icrflow_grasp::object::Object;
use icrflow_grasp::quality::GraspProblem;
use icrflow_grasp::wrench::WrenchFrame;
use icrflow_plan::hand::Hand;
use icrflow_plan::planner::{Scenario, Start};

use crate::config::{Config, ContactSpec};

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
        if object.section.samples.is_empty() {
            bail!(
                "object: the hand's plane (z = {:.4} m, through the centre of mass) does not cut it: no contact candidates",
                object.section.height
            );
        }
        let problem = GraspProblem::new_with(
            &object.facets,
            object.section.samples.clone(),
            frame,
            g.model,
            progress,
        )?;
        let hand = config.hand.build()?;
        let mut initial = Vec::with_capacity(g.contacts.len());
        for (i, c) in g.contacts.iter().enumerate() {
            if hand.finger(c.finger).is_none() {
                bail!(
                    "grasp.contacts[{i}].finger: finger {} is not in the hand (fingers {:?})",
                    c.finger,
                    hand.fingers.iter().map(|f| f.id).collect::<Vec<_>>()
                );
            }
            let index = match c.at {
                ContactSpec::Angle(a) => object.section.nearest_angle(a).map(|x| x.0),
                ContactSpec::Point(p) => problem.candidates().nearest(&p).map(|x| x.0),
            }
            .context("the object's section has no samples")?;
            initial.push((c.finger, index, c.cap_angle));
        }
        if hand
            .fingers
            .iter()
            .all(|f| g.contacts.iter().any(|c| c.finger == f.id))
        {
            bail!(
                "grasp.contacts: every finger of the hand ({:?}) is in contact, so none is free to take over when one reaches its limit; leave one out",
                hand.fingers.iter().map(|f| f.id).collect::<Vec<_>>()
            );
        }
        Ok(Self {
            object,
            problem,
            hand,
            initial,
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
