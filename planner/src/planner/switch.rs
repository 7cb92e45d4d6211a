//! The planar scenario's finger switch: the rendezvous region, the free finger's reachable
//! placements in it, the choice among them and its verification.

use std::f64::consts::PI;

use icrflow_grasp::math::Real;

use super::{Contact, NoSwitch, PlanError, QUALITY_SLACK, Roll, Scenario, Switch, Switched};
use crate::hand::{Finger, wrap};

impl Scenario<'_> {
    /// A free finger taking over from contact `k`, blocked for `why`, with the object at
    /// `theta` (the planning loop's [`Stepper::switch`](super::Stepper::switch)): the grasp
    /// with it attached, the grasp after the release, the switch and the two grasps'
    /// qualities; or why there is none.
    pub(super) fn switch(
        &self,
        contacts: &[Contact],
        k: usize,
        theta: Real,
        why: &str,
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
    pub(super) fn best_attach(
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
}
