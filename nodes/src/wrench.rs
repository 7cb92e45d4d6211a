//! The wrench-space node (`icrflow-wrench`): for every grasp state, the grasp wrench space of
//! the fingers in contact, its hull, force closure, alpha* and epsilon, published with the
//! hull's facets as an iceoryx2 dynamic slice.
//!
//! These depend only on which candidate points are in contact (body frame), which stays the
//! same over many grasp states while a contact rolls across one facet: the node evaluates a
//! contact set once and answers the following grasp states with the same set from that
//! evaluation, so that the critical path (measurement to hand command) pays the hull only
//! when a contact moves to another candidate. The evaluations are made in buffers kept for the
//! next (`GraspProblem::evaluate_in`), so a new contact set allocates nothing either.

use anyhow::Result;
use icrflow_grasp::quality::{Evaluation, EvaluationScratch};
use icrflow_interfaces::{Facet, Header, Kind, MAX_FACETS, MAX_FINGERS, WrenchSpaceHeader, topics};

use crate::Context;
use icrflow_runtime::event::serve;
use icrflow_runtime::health::{Health, Sequence};

/// Runs the wrench-space node.
pub fn run(ctx: &Context) -> Result<()> {
    let problem = &ctx.scenario.setup.problem;
    let alpha = ctx.scenario.config.grasp.alpha;
    let dim = problem.dim();
    let grasps = ctx.bus.subscriber(topics::GRASP_STATE)?;
    let out = ctx.bus.slice_publisher(topics::WRENCH_SPACE)?;
    let mut health = Health::new(ctx)?;
    let mut seq = Sequence::default();
    let mut last = 0;
    let mut contacts = Vec::with_capacity(MAX_FINGERS);
    let mut facets: Vec<Facet> = Vec::with_capacity(MAX_FACETS);
    // The contact set of `facets` and the header fields evaluated for it.
    let mut evaluated: Option<(Vec<usize>, WrenchSpaceHeader)> = None;
    let mut e = Evaluation::default();
    let mut scratch = EvaluationScratch::default();
    let log_contacts = ctx.launch.log.contacts;
    let n = problem.candidates().points.len();

    serve(ctx, &[grasps.listener()], None, |_| {
        health.tick()?;
        let Some(g) = grasps.latest()? else {
            return Ok(());
        };
        let received = icrflow_runtime::health::now();
        if !health.accept("grasp state", &g.header, Kind::GraspState, &mut last) {
            return Ok(());
        }
        contacts.clear();
        for f in g
            .fingers
            .iter()
            .take((g.finger_count as usize).min(MAX_FINGERS))
        {
            if f.in_contact == 1 && (f.candidate as usize) < n {
                contacts.push(f.candidate as usize);
            }
        }
        let cached = evaluated.as_ref().filter(|(set, _)| *set == contacts);
        let mut header = match cached {
            Some((_, h)) => *h,
            None => {
                let mut h = WrenchSpaceHeader {
                    dim: dim as u32,
                    alpha,
                    ..Default::default()
                };
                facets.clear();
                if !contacts.is_empty() {
                    problem.evaluate_in(&contacts, &mut e, &mut scratch)?;
                    h.force_closure = u32::from(e.force_closure());
                    h.quality = if e.force_closure() { e.quality } else { 0.0 };
                    h.epsilon = e.epsilon;
                    if let Some(hull) = &e.hull {
                        for (f, b) in hull.offsets().iter().enumerate().take(MAX_FACETS) {
                            let mut normal = [0.0; 6];
                            normal[..dim].copy_from_slice(hull.normal(f));
                            facets.push(Facet { normal, offset: *b });
                        }
                    }
                }
                if log_contacts {
                    eprintln!(
                        "icrflow-wrench: candidates {contacts:?}: force closure {}, alpha* {:.4}",
                        h.force_closure, h.quality
                    );
                }
                match &mut evaluated {
                    Some((set, old)) => {
                        set.clone_from(&contacts);
                        *old = h;
                    }
                    None => evaluated = Some((contacts.clone(), h)),
                }
                h
            }
        };
        header.header = Header::after(Kind::WrenchSpace, seq.advance(), &g.header, received);
        out.publish(header, &facets)?;
        health.processed += 1;
        Ok(())
    })
}
