//! The state estimator (`icrflow-estimator`): fuses the joint encoders, through forward
//! kinematics and the rolling kinematics ([`crate::rolling`]), with the delayed object-pose
//! measurements into the object's rotation and the fingers' contact state.
//!
//! Between measurements the rotation follows the fingertips' rolling; a measurement captured
//! at time `t` is compared with the estimate the filter had at `t` (kept in a short history),
//! and a fraction [`GAIN`] of the difference corrects the current estimate: the kinematics
//! since `t` are kept, so the delay is compensated (a complementary filter with replay).
//! A finger touches when its fingertip centre (from the encoders) is within [`TOUCH`] of the
//! object's surface offset by the fingertip radius; its contact point is the section's point
//! nearest to the fingertip centre (along the normal), snapped to the nearest candidate.
//! The grasp state also carries the joint angles it was estimated from (the hand's state, for
//! the planner's way points and a restarted command node).

use std::collections::VecDeque;
use std::fmt::Write as _;

use anyhow::Result;
use icrflow_interfaces::{
    FingerContact, GraspState, Header, JointState, Kind, MAX_FINGERS, ObjectPose, topics,
};
use icrflow_plan::hand::wrap;

use crate::rolling::{Surface, Tip, tip};
use crate::runtime::{Checkpoint, Context, Health, Sequence, serve};

/// Weight of a pose measurement's correction.
pub const GAIN: f64 = 0.3;
/// A fingertip comes into contact when its centre is within this of the contact distance
/// (m, encoder noise included) ...
pub const TOUCH: f64 = 0.6e-3;
/// ... for this many consecutive samples (a fingertip passing by on its way is not a contact) ...
pub const SETTLE: u32 = 10;
/// ... and leaves contact beyond this (m): hysteresis against noise.
pub const RELEASE: f64 = 2e-3;
/// A fingertip in contact counts for the rolling only if its distance from the object's surface
/// changed less than this between two samples (m): one arriving or leaving does not roll it.
pub const RADIAL: f64 = 0.2e-3;

/// Runs the estimator.
pub fn run(ctx: &Context) -> Result<()> {
    let hand = &ctx.setup.hand;
    let object = &ctx.setup.object;
    let surface = Surface::new(
        &object.section,
        [object.centre_of_mass.x, object.centre_of_mass.y],
    )?;
    let section = &object.section;
    let joints = ctx.bus.subscriber::<JointState>(topics::JOINT_STATE)?;
    let poses = ctx.bus.subscriber::<ObjectPose>(topics::OBJECT_POSE)?;
    let out = ctx.bus.publisher::<GraspState>(topics::GRASP_STATE)?;
    let mut health = Health::new(ctx)?;
    let mut seq = Sequence::default();
    let checkpoint = ctx.bus.config().root.join("estimator.state");
    let mut theta: f64 = std::fs::read_to_string(&checkpoint)
        .ok()
        .and_then(|t| t.trim().parse().ok())
        .filter(|x: &f64| x.is_finite())
        .unwrap_or(0.0);
    let mut last_joint_seq = 0;
    let mut last_pose_seq = 0;
    let mut previous: Vec<Option<(Tip, f64)>> = vec![None; hand.fingers.len()];
    let mut contact = vec![false; hand.fingers.len()];
    let mut streak = vec![0u32; hand.fingers.len()];
    let mut history: VecDeque<(u64, f64)> = VecDeque::with_capacity(4096);
    let mut q = vec![0.0; 8];
    let log_contacts = std::env::var_os("ICRFLOW_LOG_CONTACTS").is_some();
    let mut tips: Vec<Option<(Tip, bool)>> = Vec::with_capacity(hand.fingers.len());
    let saved = Checkpoint::new(checkpoint)?;

    serve(ctx, &[joints.listener(), poses.listener()], None, |_| {
        health.tick()?;
        if let Some(m) = poses.latest()? {
            let [w, _, _, z] = m.orientation;
            let measured = 2.0 * z.atan2(w);
            if !health.accept(
                "object pose",
                &m.header,
                Kind::ObjectPose,
                &mut last_pose_seq,
            ) {
                // Refused and counted.
            } else if !measured.is_finite() {
                health.refuse("object pose not finite");
            } else {
                let then = history
                    .iter()
                    .rev()
                    .find(|(t, _)| *t <= m.captured_time_ns)
                    .or(history.front())
                    .map_or(theta, |(_, th)| *th);
                theta += GAIN * wrap(measured - then);
                health.processed += 1;
            }
        }
        let Some(m) = joints.latest()? else {
            return Ok(());
        };
        let received = crate::runtime::now();
        if !health.accept(
            "joint state",
            &m.header,
            Kind::JointState,
            &mut last_joint_seq,
        ) {
            return Ok(());
        }
        health.processed += 1;
        let mut g = GraspState {
            header: Header::after(Kind::GraspState, seq.advance(), &m.header, received),
            finger_count: hand.fingers.len().min(MAX_FINGERS) as u32,
            ..Default::default()
        };
        let mut turn = 0.0;
        let mut rolling = 0;
        let mut residual = 0.0;
        let mut touching = 0;
        tips.clear();
        for (slot, f) in hand.fingers.iter().enumerate().take(MAX_FINGERS) {
            let Some(k) = (0..m.finger_count as usize).find(|&k| m.finger_ids[k] == f.id) else {
                tips.push(None);
                continue;
            };
            q.clear();
            q.extend_from_slice(&m.positions[k][..f.dof()]);
            if q.iter().any(|x| !x.is_finite()) {
                health.refuse(format_args!("finger {}: joint angle not finite", f.id));
                return Ok(());
            }
            g.joints[slot][..q.len()].copy_from_slice(&q);
            let t = tip(f, &q);
            let was = contact[slot];
            let gap = surface.contact_of(&t, f, theta).gap;
            streak[slot] = if gap.abs() <= TOUCH {
                streak[slot].saturating_add(1)
            } else {
                0
            };
            let on = if was {
                gap.abs() <= RELEASE
            } else {
                streak[slot] >= SETTLE
            };
            if on != was && log_contacts {
                // Transitions only: a line per touch or release.
                eprintln!(
                    "icrflow-estimator: finger {} {} (fingertip {:+.2} mm from the surface)",
                    f.id,
                    if on { "touches" } else { "released" },
                    gap * 1e3
                );
            }
            contact[slot] = on;
            if let Some((before, before_gap)) = previous[slot]
                && was
                && on
                && (gap - before_gap).abs() < RADIAL
            {
                turn += surface.rotation(&before, &t, f, theta);
                rolling += 1;
            }
            tips.push(Some((t, on)));
            previous[slot] = Some((t, gap));
        }
        if rolling > 0 {
            theta += turn / rolling as f64;
        }
        for (slot, f) in hand.fingers.iter().enumerate().take(MAX_FINGERS) {
            let c = &mut g.fingers[slot];
            c.finger = f.id;
            let Some((t, on)) = tips[slot] else { continue };
            if !on {
                continue;
            }
            let touch = surface.contact_of(&t, f, theta);
            let index = touch.sample;
            let p = section.samples.points[index];
            let n = section.samples.normals[index];
            *c = FingerContact {
                finger: f.id,
                in_contact: 1,
                candidate: index as u32,
                reserved: 0,
                point: [p.x, p.y, p.z],
                normal: [n.x, n.y, n.z],
                residual: touch.gap,
            };
            residual += c.residual * c.residual;
            touching += 1;
        }
        g.rotation = theta;
        let half = 0.5 * theta;
        g.orientation = [half.cos(), 0.0, 0.0, half.sin()];
        g.residual = if touching > 0 {
            (residual / touching as f64).sqrt()
        } else {
            0.0
        };
        history.push_back((m.header.source_time_ns, theta));
        while history.len() > 4000 {
            history.pop_front();
        }
        out.publish(g)?;
        if last_joint_seq.is_multiple_of(10) {
            saved.store(|text| {
                let _ = write!(text, "{theta:e}");
            });
        }
        Ok(())
    })
}
