//! The wrench-space node (`icrflow-wrench`): for every grasp state, the grasp wrench space of
//! the fingers in contact, its hull, force closure, alpha* and epsilon, published with the
//! hull's facets as an iceoryx2 dynamic slice.
//!
//! Where a contact is evaluated ([`At`]) is where the plan's margin holds: a spatial hand's
//! plan keeps alpha at its contacts' exact points and normals, so the grasp state's contacts
//! are evaluated where the estimate has them ([`At::Contacts`]); a planar hand's plan keeps it
//! at its contacts' candidates, so there each contact is its candidate ([`At::Candidates`]).
//! A contact set is evaluated once and the following grasp states with the same set (the
//! same candidates, or the same points and normals: a hand holding still) are answered from
//! that evaluation, so that the critical path (measurement to hand command) pays the hull
//! only when the grasp changes. The evaluations are made in buffers kept for the next
//! (`GraspProblem::evaluate_in`, `evaluate_at_in`), so a new contact set allocates nothing
//! either.
//!
//! [`WrenchSpace`] is the pure step (a grasp state in, the wrench space out); [`run`] is the
//! node around it (the bus, health).

use anyhow::Result;
use icrflow_grasp::math::Vec3;
use icrflow_grasp::quality::{Evaluation, EvaluationScratch, GraspError, GraspProblem};
use icrflow_interfaces::{
    Facet, GraspState, Header, Kind, MAX_FACETS, MAX_FINGERS, WrenchSpaceHeader, topics,
};

use crate::Context;
use icrflow_runtime::event::serve;
use icrflow_runtime::health::{Health, Sequence};

/// Where a grasp state's contacts are evaluated.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum At {
    /// At each contact's candidate (a planar hand's plan keeps its margin there).
    Candidates,
    /// At each contact's point and normal, as the grasp state has them (a spatial hand's plan
    /// keeps its margin where the fingertips touch).
    Contacts,
}

/// The wrench-space step's state: the last contact set's evaluation and its buffers; no I/O,
/// no clock.
pub struct WrenchSpace<'a> {
    problem: &'a GraspProblem,
    alpha: f64,
    at: At,
    /// The candidates in contact of the last grasp state.
    contacts: Vec<usize>,
    /// Their points and normals (body frame).
    touching: Vec<(Vec3, Vec3)>,
    /// The points and normals of the evaluation `evaluated` holds (with [`At::Contacts`]).
    touched: Vec<(Vec3, Vec3)>,
    /// The hull's facets of the contact set `evaluated` holds.
    facets: Vec<Facet>,
    /// The contact set of `facets` and the header fields evaluated for it.
    evaluated: Option<(Vec<usize>, WrenchSpaceHeader)>,
    e: Evaluation,
    scratch: EvaluationScratch,
}

/// The wrench space of a grasp state ([`WrenchSpace::on_grasp`]).
#[derive(Debug, Clone, Copy)]
pub struct Output<'s> {
    /// The summary: force closure, alpha*, epsilon, with the header given.
    pub header: WrenchSpaceHeader,
    /// The hull's facets (at most [`MAX_FACETS`]).
    pub facets: &'s [Facet],
    /// The candidates in contact (slot order): the contact set evaluated.
    pub contacts: &'s [usize],
    /// Whether the contact set was new (evaluated now rather than answered from the last
    /// evaluation).
    pub evaluated: bool,
}

impl<'a> WrenchSpace<'a> {
    /// The wrench-space step of `problem`, with margin `alpha` (carried in every summary),
    /// evaluating its contacts `at` their candidates or where they touch.
    pub fn new(problem: &'a GraspProblem, alpha: f64, at: At) -> Self {
        Self {
            problem,
            alpha,
            at,
            contacts: Vec::with_capacity(MAX_FINGERS),
            touching: Vec::with_capacity(MAX_FINGERS),
            touched: Vec::with_capacity(MAX_FINGERS),
            facets: Vec::with_capacity(MAX_FACETS),
            evaluated: None,
            e: Evaluation::default(),
            scratch: EvaluationScratch::default(),
        }
    }

    /// The wrench space of the fingers in contact in `g` (those whose candidate is one of the
    /// problem's), with `header`: evaluated when the contact set differs from the last one,
    /// in the kept buffers (no allocation once they have grown), otherwise the last
    /// evaluation's.
    pub fn on_grasp(&mut self, g: &GraspState, header: Header) -> Result<Output<'_>, GraspError> {
        let n = self.problem.candidates().points.len();
        self.contacts.clear();
        self.touching.clear();
        for f in g
            .fingers
            .iter()
            .take((g.finger_count as usize).min(MAX_FINGERS))
        {
            if f.in_contact == 1 && (f.candidate as usize) < n {
                self.contacts.push(f.candidate as usize);
                self.touching
                    .push((Vec3::from(f.point), Vec3::from(f.normal)));
            }
        }
        let same = match self.at {
            At::Candidates => true,
            At::Contacts => self.touched == self.touching,
        };
        let cached = self
            .evaluated
            .as_ref()
            .filter(|(set, _)| same && *set == self.contacts);
        let (mut summary, evaluated) = match cached {
            Some((_, h)) => (*h, false),
            None => (self.evaluate()?, true),
        };
        summary.header = header;
        Ok(Output {
            header: summary,
            facets: &self.facets,
            contacts: &self.contacts,
            evaluated,
        })
    }

    /// Evaluates the contact set `contacts` into `facets` and `evaluated`.
    fn evaluate(&mut self) -> Result<WrenchSpaceHeader, GraspError> {
        let dim = self.problem.dim();
        let mut h = WrenchSpaceHeader {
            dim: dim as u32,
            alpha: self.alpha,
            ..Default::default()
        };
        self.facets.clear();
        if !self.contacts.is_empty() {
            let e = &mut self.e;
            match self.at {
                At::Candidates => {
                    self.problem
                        .evaluate_in(&self.contacts, e, &mut self.scratch)?;
                }
                At::Contacts => {
                    self.problem
                        .evaluate_at_in(&self.touching, e, &mut self.scratch)?;
                }
            }
            h.force_closure = u32::from(e.force_closure());
            h.quality = if e.force_closure() { e.quality } else { 0.0 };
            h.epsilon = e.epsilon;
            if let Some(hull) = &e.hull {
                for (f, b) in hull.offsets().iter().enumerate().take(MAX_FACETS) {
                    let mut normal = [0.0; 6];
                    normal[..dim].copy_from_slice(hull.normal(f));
                    self.facets.push(Facet { normal, offset: *b });
                }
            }
        }
        self.touched.clone_from(&self.touching);
        match &mut self.evaluated {
            Some((set, old)) => {
                set.clone_from(&self.contacts);
                *old = h;
            }
            None => self.evaluated = Some((self.contacts.clone(), h)),
        }
        Ok(h)
    }
}

/// Runs the wrench-space node.
pub fn run(ctx: &Context) -> Result<()> {
    let grasps = ctx.bus.subscriber(topics::GRASP_STATE)?;
    let out = ctx.bus.slice_publisher(topics::WRENCH_SPACE)?;
    let mut health = Health::new(ctx)?;
    let mut seq = Sequence::default();
    let mut last = 0;
    let setup = &ctx.scenario.setup;
    let mut step = WrenchSpace::new(&setup.problem, ctx.scenario.config.grasp.alpha, at(setup));
    let log_contacts = ctx.launch.log.contacts;

    serve(ctx, &[grasps.listener()], None, |_| {
        health.tick()?;
        let Some(g) = grasps.latest()? else {
            return Ok(());
        };
        let received = icrflow_runtime::health::now();
        if !health.accept("grasp state", &g.header, Kind::GraspState, &mut last) {
            return Ok(());
        }
        let header = Header::after(Kind::WrenchSpace, seq.advance(), &g.header, received);
        let w = step.on_grasp(&g, header)?;
        if log_contacts && w.evaluated {
            eprintln!(
                "icrflow-wrench: candidates {:?}: force closure {}, alpha* {:.4}",
                w.contacts, w.header.force_closure, w.header.quality
            );
        }
        out.publish(w.header, w.facets)?;
        health.processed += 1;
        Ok(())
    })
}

/// Where `setup`'s grasp states are evaluated: where the fingertips touch for a spatial hand,
/// at the candidates for a planar one (see the module's docs).
pub fn at(setup: &icrflow_scenario::Setup) -> At {
    if setup.spatial.is_some() {
        At::Contacts
    } else {
        At::Candidates
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::paper;
    use icrflow_interfaces::FingerContact;

    /// A grasp state whose fingers touch `candidates` (finger 1 to n); `free` more fingers out
    /// of contact.
    fn grasp(candidates: &[usize], free: usize) -> GraspState {
        let mut g = GraspState {
            finger_count: (candidates.len() + free) as u32,
            ..Default::default()
        };
        for (slot, c) in candidates.iter().enumerate() {
            g.fingers[slot] = FingerContact {
                finger: slot as u32 + 1,
                in_contact: 1,
                candidate: *c as u32,
                ..Default::default()
            };
        }
        for slot in candidates.len()..candidates.len() + free {
            g.fingers[slot].finger = slot as u32 + 1;
            g.fingers[slot].candidate = 0;
        }
        g
    }

    /// Evaluated where the fingertips touch: at the grasp state's points and normals (not at
    /// their candidates), a state with the same points answered from the last evaluation, one
    /// with a contact moved within its candidate evaluated anew.
    #[test]
    fn where_the_fingertips_touch_the_wrench_space_is_that_of_the_contacts() {
        let (config, setup) = paper();
        let problem = &setup.problem;
        let (start, _) = setup.scenario(&config).start().unwrap();
        let initial: Vec<usize> = start.iter().map(|c| c.candidate).collect();
        let cands = problem.candidates();
        let mut g = grasp(&initial, 1);
        let turned = nalgebra::Rotation3::from_axis_angle(&Vec3::z_axis(), 0.02);
        let mut at: Vec<(Vec3, Vec3)> = initial
            .iter()
            .map(|&c| (cands.points[c], cands.normals[c]))
            .collect();
        for c in &mut at {
            *c = (turned * c.0, turned * c.1);
        }
        for (slot, (p, n)) in at.iter().enumerate() {
            g.fingers[slot].point = [p.x, p.y, p.z];
            g.fingers[slot].normal = [n.x, n.y, n.z];
        }
        let mut step = WrenchSpace::new(problem, config.grasp.alpha, At::Contacts);
        let header = Header::new(Kind::WrenchSpace, 1, 1, 0);
        let exact = problem.evaluate_at(&at).unwrap().quality;
        let grid = problem.evaluate(&initial).unwrap().quality;
        assert_ne!(exact, grid);
        let w = step.on_grasp(&g, header).unwrap();
        assert!(w.evaluated);
        assert_eq!(w.header.quality, exact);
        assert!(!step.on_grasp(&g, header).unwrap().evaluated);
        // The contacts moved back onto their candidates: the same candidates, evaluated anew.
        for (slot, &c) in initial.iter().enumerate() {
            let (p, n) = (cands.points[c], cands.normals[c]);
            g.fingers[slot].point = [p.x, p.y, p.z];
            g.fingers[slot].normal = [n.x, n.y, n.z];
        }
        let w = step.on_grasp(&g, header).unwrap();
        assert!(w.evaluated);
        assert_eq!(w.header.quality, grid);
    }

    #[test]
    fn the_wrench_space_is_that_of_grasp_problem_evaluate() {
        let (config, setup) = paper();
        let problem = &setup.problem;
        let alpha = config.grasp.alpha;
        let (start, _) = setup.scenario(&config).start().unwrap();
        let initial: Vec<usize> = start.iter().map(|c| c.candidate).collect();
        let n = problem.candidates().points.len();
        let mut step = WrenchSpace::new(problem, alpha, At::Candidates);
        // The paper's initial grasp (force closure), a set of two contacts (not force
        // closure), the initial grasp again after another set, and three contacts elsewhere.
        let two = vec![initial[0], initial[1]];
        let other: Vec<usize> = initial.iter().map(|c| (c + n / 7) % n).collect();
        let mut closures = 0;
        for (k, set) in [&initial, &two, &initial, &other].into_iter().enumerate() {
            let header = Header::new(Kind::WrenchSpace, 10 + k as u64, 3 + k as u64, 0);
            let w = step.on_grasp(&grasp(set, 1), header).unwrap();
            let e = problem.evaluate(set).unwrap();
            assert!(w.evaluated, "set {set:?}: a new set is evaluated");
            assert_eq!(w.contacts, &set[..]);
            assert_eq!(w.header.header, header);
            assert_eq!(w.header.dim as usize, problem.dim());
            assert_eq!(w.header.alpha, alpha);
            assert_eq!(w.header.force_closure, u32::from(e.force_closure()));
            let quality = if e.force_closure() { e.quality } else { 0.0 };
            assert_eq!(w.header.quality, quality, "set {set:?}");
            assert_eq!(w.header.epsilon, e.epsilon, "set {set:?}");
            let hull = e.hull.as_ref();
            assert_eq!(w.facets.len(), hull.map_or(0, |h| h.facet_count()));
            for (f, facet) in w.facets.iter().enumerate() {
                let hull = hull.unwrap();
                assert_eq!(facet.offset, hull.offsets()[f]);
                assert_eq!(&facet.normal[..problem.dim()], hull.normal(f));
            }
            closures += usize::from(e.force_closure());
        }
        assert_eq!(
            closures, 3,
            "the initial grasp twice and the other set are closed"
        );
    }

    #[test]
    fn the_same_contact_set_is_answered_from_the_last_evaluation() {
        let (config, setup) = paper();
        let (start, _) = setup.scenario(&config).start().unwrap();
        let initial: Vec<usize> = start.iter().map(|c| c.candidate).collect();
        let mut step = WrenchSpace::new(&setup.problem, config.grasp.alpha, At::Candidates);
        let first = step
            .on_grasp(&grasp(&initial, 0), Header::new(Kind::WrenchSpace, 1, 1, 0))
            .unwrap();
        let (summary, facets) = (first.header, first.facets.to_vec());
        assert!(first.evaluated && summary.force_closure == 1);
        // A free finger more and a contact on no candidate change nothing.
        let mut g = grasp(&initial, 1);
        g.fingers[3].in_contact = 1;
        g.fingers[3].candidate = u32::MAX;
        let header = Header::new(Kind::WrenchSpace, 2, 2, 0);
        let again = step.on_grasp(&g, header).unwrap();
        assert!(!again.evaluated);
        assert_eq!(again.header.header, header);
        assert_eq!(
            (again.header.quality, again.header.epsilon),
            (summary.quality, summary.epsilon)
        );
        assert_eq!(again.facets, &facets[..]);
        // No finger in contact: no wrench space at all.
        let none = step
            .on_grasp(&grasp(&[], 3), Header::new(Kind::WrenchSpace, 3, 3, 0))
            .unwrap();
        assert!(none.evaluated && none.facets.is_empty());
        assert_eq!((none.header.force_closure, none.header.quality), (0, 0.0));
    }
}
