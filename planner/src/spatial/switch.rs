//! The spatial finger switch: the rendezvous region, the free fingers' placements in it (seeded
//! by their reach maps), their rolling room, the approach and retreat routes, and the checks
//! of the chosen one.

use std::f64::consts::PI;
use std::sync::OnceLock;

use icrflow_grasp::math::{Real, Vec3};
use rayon::prelude::*;

use super::reach::REACH_MAP_GAP;
use super::times::{Counter, Timing};
use super::{LIFTS, ReachMap, Roll, STEERS, SpatialScenario, Touch, segment_surface_distance};
use crate::hand::Finger;
use crate::planner::{Deadline, NoSwitch, PlanError, QUALITY_SLACK, Switch, Switched};

/// Per way of [`LIFTS`], a finger's lifted poses off its contact, or why it cannot lift so;
/// found once, when first needed (by any thread).
type Lifted = [OnceLock<Result<Vec<Vec<Real>>, String>>; LIFTS.len()];

/// The released finger's retreat, the same for every placement of a switch search: its lifted
/// poses, and per free finger whether the retreat is clear of the object and of every finger
/// but that one (found once, when first needed). Where it is not, no placement of that finger
/// can make it clear: the finger only adds to what the retreat must keep clear of.
struct Retreat {
    lifted: Lifted,
    without: Vec<(u32, OnceLock<Result<(), String>>)>,
}

/// A switch that passed its checks ([`SpatialScenario::try_switch`]).
struct Chosen {
    t: Touch,
    attach: Vec<Touch>,
    detach: Vec<Touch>,
    q_attach: Real,
    q_detach: Real,
    approach: Vec<Vec<Real>>,
    retreat: Vec<Vec<Real>>,
}

/// What trying one rendezvous placement found.
enum Attempt {
    /// It passed.
    Chosen(Box<Chosen>),
    /// It did not (said in the rejections).
    Rejected,
    /// Its grasps fell below the margin: a defect, which stops the plan.
    Defect(String),
}

/// The largest spacing (m) of the fingertip's travel between two poses at which an approach or
/// a retreat is checked.
const ROUTE_SPACING: Real = 0.1e-3;

/// How many of a switch's reachable options (best limit margin first) get their rolling room
/// simulated.
const ROOM_OPTIONS: usize = 12;

/// The most placements a switch search checks at once (on every core).
const MAX_BATCH: usize = 32;

/// Placements tried on every core between two calls of a switch search's progress.
const PLACE_CHUNK: usize = 64;

/// Most rolling steps simulated for a rendezvous option's rolling room.
const ROOM_LIMIT: usize = 36;

impl SpatialScenario<'_> {
    /// The way of finger `t.finger` between its home pose and its contact `t` (`what`: its
    /// approach or its retreat), the fingers of `others` holding still, the object at `theta`:
    /// straight joint-space moves from home (through a pose turned at the finger's base but
    /// not yet curled, if the straight way is not clear) through poses with the fingertip
    /// lifted off the contact along its normal ([`LIFTS`], the farthest first) to the
    /// contact, each checked
    /// at [`crate::route::SAMPLES`] poses: the fingertip off the object (touching only at the
    /// contact), the link capsules off it, no two fingers touching. The first of [`LIFTS`]
    /// whose way is clear: its poses; or why the way straight from home was not.
    ///
    /// `lifted` keeps the lifted poses of each of [`LIFTS`] once found (or why there are
    /// none): a released finger's retreat is routed from the same contact for every placement
    /// of the finger that takes over.
    fn route(
        &self,
        t: &Touch,
        others: &[Touch],
        theta: Real,
        what: &str,
        lifted: &Lifted,
        ignore: Option<u32>,
    ) -> Result<Vec<Vec<Real>>, String> {
        let f = self.finger(t.finger);
        let mut why: Option<String> = None;
        'ways: for (w, heights) in LIFTS.iter().enumerate() {
            let vias = match lifted[w]
                .get_or_init(|| self.lifted(f, t, theta, heights, what))
                .clone()
            {
                Ok(vias) => vias,
                Err(e) => {
                    why.get_or_insert(e);
                    continue 'ways;
                }
            };
            // From home straight to the first lifted pose, or first to that pose with its
            // distal joints (from the second, or the third, on) still at home (the finger
            // turns at its base before it curls: a thumb swinging home past a fingertip), or
            // with its base joints still at home (it curls first).
            let first = vias.first().unwrap_or(&t.q);
            let split = |from: usize, base_first: bool| -> Vec<Real> {
                first
                    .iter()
                    .zip(&f.home)
                    .enumerate()
                    .map(|(j, (q, h))| if (j < from) == base_first { *q } else { *h })
                    .collect()
            };
            let uncurled: Vec<Vec<Real>> = (1..f.dof().saturating_sub(1))
                .flat_map(|from| [split(from, true), split(from, false)])
                .collect();
            'turns: for turn in std::iter::once(None).chain(uncurled.iter().map(Some)) {
                let mut way: Vec<&[Real]> = vec![&f.home];
                way.extend(turn.map(Vec::as_slice));
                way.extend(vias.iter().map(Vec::as_slice));
                way.push(&t.q);
                let legs = way.len() - 1;
                for (leg, pair) in way.windows(2).enumerate() {
                    // The last leg ends touching: it may not press in.
                    let floor = if leg + 1 == legs {
                        f.tip_radius - 1e-9
                    } else {
                        f.tip_radius
                    };
                    if let Err(e) =
                        self.clear_move(f, pair[0], pair[1], floor, t, others, theta, ignore)
                    {
                        why.get_or_insert(format!("on its {what} {e}"));
                        continue 'turns;
                    }
                }
                let mut poses: Vec<Vec<Real>> = turn.into_iter().cloned().collect();
                poses.extend(vias);
                return Ok(poses);
            }
        }
        Err(why.unwrap_or_default())
    }

    /// Finger `f`'s poses with its fingertip lifted `heights` off its contact `t` along the
    /// normal (the object at `theta`), or why it cannot lift so (`what`: its approach or its
    /// retreat).
    fn lifted(
        &self,
        f: &Finger,
        t: &Touch,
        theta: Real,
        heights: &[Real],
        what: &str,
    ) -> Result<Vec<Vec<Real>>, String> {
        let n_w = self.rotation(theta) * t.normal;
        let contact = self.to_world(theta, &t.point);
        heights
            .iter()
            .map(|h| {
                f.ik_position_centred(&(contact + n_w * (f.tip_radius + h)), &t.q)
                    .map_err(|e| {
                        format!(
                            "on its {what} its fingertip cannot lift {:.0} mm off the contact: {e}",
                            h * 1e3
                        )
                    })
            })
            .collect()
    }

    /// Whether finger `f` moving straight in joint space from `from` to `to` (checked at
    /// [`crate::route::SAMPLES`] poses, its fingertip also every [`ROUTE_SPACING`]) keeps its fingertip centre at least `floor` from the
    /// object, its link capsules off it, and off the fingers of `others` (`t`: the finger's
    /// contact, for its identity).
    #[allow(clippy::too_many_arguments)]
    fn clear_move(
        &self,
        f: &Finger,
        from: &[Real],
        to: &[Real],
        floor: Real,
        t: &Touch,
        others: &[Touch],
        theta: Real,
        ignore: Option<u32>,
    ) -> Result<(), String> {
        let at =
            |s: Real| -> Vec<Real> { from.iter().zip(to).map(|(a, b)| a + s * (b - a)).collect() };
        // The fingertip at least every ROUTE_SPACING of its straight-line travel: a fingertip
        // grazing the object between two checked poses dips in by about the square of their
        // spacing times the path's curvature. The distance from the object changes by at most
        // the distance moved, so a pose whose fingertip is nearer the last one measured than
        // that one's distance less the floor is clear without measuring it.
        // A pose whose fingertip cannot have moved that far from the last measured (by
        // [`Finger::tip_travel_bound`], kept a little over) is passed without its kinematics:
        // the same poses are measured as if each were computed.
        let travel = (f.tip_centre(to) - f.tip_centre(from)).norm();
        let fine = crate::route::SAMPLES.max((travel / ROUTE_SPACING).ceil() as usize + 1);
        let per_sample = f.tip_travel_bound(from, to) * (1.0 + 1e-9) / (fine - 1) as Real + 1e-15;
        let mut measured: Option<(usize, Vec3, Real)> = None;
        for i in 0..fine {
            if measured.is_some_and(|(k, _, d)| (i - k) as Real * per_sample < d - floor) {
                continue;
            }
            let tip = self.to_body(theta, &f.tip_centre(&at(i as Real / (fine - 1) as Real)));
            if measured.is_some_and(|(_, p, d)| (tip - p).norm() < d - floor) {
                continue;
            }
            let d = self.surface.closest(&tip).distance;
            if d < floor {
                return Err("its fingertip would hit the object".into());
            }
            measured = Some((i, tip, d));
        }
        // The links and the other fingers at the route's samples; a link whose ends both
        // moved less than its last measured clearance beyond the capsule's radius is clear
        // (every point of it moved less).
        // The other fingers hold still: their capsules are made once, and the check of the
        // free fingers at home once it is needed.
        let samples = crate::route::SAMPLES;
        let bodies = self.bodies_without(t.finger, others, ignore);
        let mut home = None;
        let mut trial = others.to_vec();
        trial.push(t.clone());
        // A finger left out is not at home either.
        trial.extend(ignore.map(|finger| Touch {
            finger,
            ..t.clone()
        }));
        let mut links: Vec<Option<(Vec3, Vec3, Real)>> = Vec::new();
        for i in 0..samples {
            let q = at(i as Real / (samples - 1) as Real);
            // Its links (each capsule but the last, the fingertip), counted from 1.
            let caps = f.capsules(&q, self.spatial.link_radius);
            let mut hit: Option<(Real, usize)> = None;
            for (k, c) in caps[..caps.len() - 1].iter().enumerate() {
                let link = k + 1;
                let (a, b) = (self.to_body(theta, &c.from), self.to_body(theta, &c.to));
                if links.len() <= link {
                    links.resize(link + 1, None);
                }
                if let Some((a0, b0, d0)) = links[link] {
                    let moved = (a - a0).norm().max((b - b0).norm());
                    if moved < d0 - self.spatial.link_radius {
                        continue;
                    }
                }
                let d = segment_surface_distance(self.surface, &a, &b);
                links[link] = Some((a, b, d));
                if d < self.spatial.link_radius {
                    hit = Some((d, link));
                    break;
                }
            }
            if let Some((clear, link)) = hit {
                return Err(format!(
                    "its link {link} would come {:.2} mm from the object",
                    clear * 1e3
                ));
            }
            if let Some((why, _)) =
                self.clash_moving(&bodies, (t.finger, &caps), &trial, theta, &mut home)
            {
                return Err(why);
            }
        }
        Ok(())
    }

    /// Steps finger `t.finger` could roll alone from `t` (no ICR), up to `limit`.
    fn room(&self, t: &Touch, mut theta: Real, limit: usize) -> usize {
        let mut t = t.clone();
        for k in 0..limit {
            match STEERS.iter().find_map(|&w| {
                self.roll_finger(&t, theta, self.settings.step, None, false, w)
                    .ok()
            }) {
                Some(next) => t = next,
                None => return k,
            }
            theta += self.settings.step;
        }
        limit
    }

    /// The signed angle (rad, in [0, 2 pi)) about the axis from body point `a` to `b`, or
    /// `None` where either is within a millimetre of the axis.
    fn ahead(&self, a: &Vec3, b: &Vec3) -> Option<Real> {
        let axis = self.spatial.axis;
        let flat = |p: &Vec3| {
            let v = p - self.centre;
            v - axis * axis.dot(&v)
        };
        let (u, v) = (flat(a), flat(b));
        if u.norm() < 1e-3 || v.norm() < 1e-3 {
            return None;
        }
        let angle = axis.dot(&u.cross(&v)).atan2(u.dot(&v));
        Some(angle.rem_euclid(2.0 * PI))
    }

    /// Switches finger `touches[k]` for the best free finger; `progress(theta)` is called as
    /// the search goes on (per [`PLACE_CHUNK`] candidates placed, per batch of placements
    /// checked: a search that takes a second still reports); `timing` counts its phases. A
    /// search still going when `deadline` passes stops between two batches (no switch).
    #[allow(clippy::too_many_arguments)]
    pub(super) fn switch(
        &self,
        touches: &[Touch],
        k: usize,
        theta: Real,
        why: &str,
        maps: &[ReachMap],
        progress: &mut dyn FnMut(Real),
        deadline: &Deadline,
        timing: &Timing,
    ) -> Result<Result<Switched<Touch>, NoSwitch>, PlanError> {
        let released = touches[k].finger;
        let free: Vec<&Finger> = self
            .hand
            .fingers
            .iter()
            .filter(|f| touches.iter().all(|t| t.finger != f.id))
            .collect();
        if free.is_empty() {
            return Ok(Err(NoSwitch::none(format!(
                "finger {released} cannot roll on ({why}) and no free finger can take over"
            ))));
        }
        let idx: Vec<usize> = touches.iter().map(|t| t.candidate).collect();
        let regions = timing
            .regions
            .time(|| crate::rendezvous::regions(self.problem, &idx, k, self.settings.alpha))?;
        let chosen_from: Vec<usize> = if self.settings.region_erosion == 0 {
            regions.exact.clone()
        } else {
            let exact: Vec<u32> = regions.exact.iter().map(|&c| c as u32).collect();
            self.problem
                .candidates()
                .adjacency
                .erode(&exact, self.settings.region_erosion)
                .into_iter()
                .map(|c| c as usize)
                .collect()
        };
        let cands = self.problem.candidates();
        let here = touches[k].point;
        let is_ahead = |a: Option<Real>| a.is_some_and(|a| a > 0.0 && a < PI);
        // The candidates ahead first; those behind only when none ahead serves.
        let (ahead, behind): (Vec<usize>, Vec<usize>) = chosen_from
            .iter()
            .partition(|&&c| is_ahead(self.ahead(&here, &cands.points[c])));
        // Finger `f` placed at candidate `c`, if it reaches it clear of the others: its limit
        // margin and touch.
        let place_at = |f: &Finger, c: usize| -> Option<(Real, Touch)> {
            // Far from every sampled pose of the finger: out of its reach (or nearly), not
            // worth an inverse kinematics; else the nearest sample seeds it.
            let map = maps.iter().find(|m| m.finger == f.id);
            let p = self.surface.closest(&cands.points[c]);
            let tip = self.to_world(theta, &(p.point + p.normal * f.tip_radius));
            let seed = match map.map(|m| m.nearest(&tip)) {
                Some(Some((d, _))) if d > REACH_MAP_GAP => return None,
                Some(Some((_, q))) => q,
                _ => &f.home,
            };
            let t = timing
                .placements
                .time(|| self.place(f, &cands.points[c], theta, seed, false, false))
                .ok()
                .filter(|t| t.candidate == c)?;
            let mut trial = touches.to_vec();
            trial.push(t.clone());
            if self.clash(&trial, theta).is_some() {
                return None;
            }
            Some((f.limit_margin(&t.q), t))
        };
        let out_of_time = || {
            Ok(Err(NoSwitch::out_of_time(format!(
                "the search for a finger to take over from finger {released} ({why}) was stopped: its time had run out"
            ))))
        };
        // Every reachable placement of a tier, ranked (none: the time ran out).
        let placements = |tier: &[usize], progress: &mut dyn FnMut(Real)| {
            // Every free finger at every candidate of the tier, on every core (rayon), a
            // chunk at a time with the progress said between, kept in order.
            let pairs: Vec<(&Finger, usize)> = free
                .iter()
                .flat_map(|f| tier.iter().map(move |&c| (*f, c)))
                .collect();
            let mut options: Vec<(Real, Touch)> = Vec::new();
            for chunk in pairs.chunks(PLACE_CHUNK) {
                progress(theta);
                if deadline.passed() {
                    return None;
                }
                let placed: Vec<Option<(Real, Touch)>> =
                    chunk.par_iter().map(|&(f, c)| place_at(f, c)).collect();
                options.extend(placed.into_iter().flatten());
            }
            // The best centred joints first; of the first ROOM_OPTIONS, the most rolling
            // room first; then the rest (their room measured if one is chosen).
            options.sort_by(|x, y| {
                y.0.total_cmp(&x.0)
                    .then(x.1.finger.cmp(&y.1.finger))
                    .then(x.1.candidate.cmp(&y.1.candidate))
            });
            let limit = ((self.settings.goal - theta) / self.settings.step)
                .ceil()
                .clamp(1.0, ROOM_LIMIT as Real) as usize;
            let rest = options.split_off(options.len().min(ROOM_OPTIONS));
            progress(theta);
            let mut ranked: Vec<(Option<usize>, Touch)> = options
                .into_par_iter()
                .map(|(_, t)| (Some(timing.rooms.time(|| self.room(&t, theta, limit))), t))
                .collect();
            ranked.sort_by(|x, y| {
                y.0.cmp(&x.0)
                    .then(x.1.finger.cmp(&y.1.finger))
                    .then(x.1.candidate.cmp(&y.1.candidate))
            });
            ranked.extend(rest.into_iter().map(|(_, t)| (None, t)));
            Some((ranked, limit))
        };
        let floor = self.settings.alpha * (1.0 - QUALITY_SLACK);
        let mut rejected = Vec::new();
        let mut chosen = None;
        let mut tried = 0;
        // The released finger retreats from the same contact whichever finger takes over.
        let retreat = Retreat {
            lifted: Lifted::default(),
            without: free.iter().map(|f| (f.id, OnceLock::new())).collect(),
        };
        'tiers: for tier in [&ahead, &behind] {
            let Some((ranked, limit)) = placements(tier, progress) else {
                return out_of_time();
            };
            tried += ranked.len();
            // The placements in their order, a batch at a time on every core (rayon), the
            // batch growing while none passes: the first that passes is chosen, and the
            // rejections before it kept, as one at a time would.
            let mut batch = rayon::current_num_threads().max(1);
            let mut rest = ranked.as_slice();
            while !rest.is_empty() {
                let (now, later) = rest.split_at(batch.min(rest.len()));
                rest = later;
                progress(theta);
                if deadline.passed() {
                    return out_of_time();
                }
                let results: Vec<(Vec<String>, Result<Attempt, PlanError>)> = now
                    .par_iter()
                    .map(|(_, t)| {
                        let mut why = Vec::new();
                        let r = timing.checks.time(|| {
                            self.try_switch(
                                touches,
                                k,
                                theta,
                                t.clone(),
                                floor,
                                &mut why,
                                &retreat,
                                &timing.routes,
                            )
                        });
                        (why, r)
                    })
                    .collect();
                for ((room, t), (why, r)) in now.iter().zip(results) {
                    rejected.extend(why);
                    match r? {
                        Attempt::Chosen(c) => {
                            let room = room.unwrap_or_else(|| {
                                timing.rooms.time(|| self.room(t, theta, limit))
                            });
                            let ahead = self.ahead(&here, &t.point);
                            chosen = Some((room, ahead, *c));
                            break 'tiers;
                        }
                        Attempt::Rejected => {}
                        Attempt::Defect(why) => return Ok(Err(NoSwitch::defect(why))),
                    }
                }
                batch = (batch * 2).min(MAX_BATCH);
            }
        }
        let Some((
            room,
            ahead,
            Chosen {
                t,
                attach,
                detach,
                q_attach,
                q_detach,
                approach,
                retreat,
            },
        )) = chosen
        else {
            return Ok(Err(NoSwitch::none(format!(
                "finger {released} cannot roll on ({why}); of the {} candidates that keep the margin with the remaining contacts, none is reachable by a free finger ({:?}) with a rolling step after it ({tried} placements tried){}",
                chosen_from.len(),
                free.iter().map(|f| f.id).collect::<Vec<_>>(),
                rejections(&rejected)
            ))));
        };
        let info = Switch {
            released,
            attached: t.finger,
            reason: why.to_string(),
            icr_region: regions.icr.clone(),
            lp_region: regions.lp.clone(),
            brute_force: regions.exact.clone(),
            chosen_from: chosen_from.len(),
            rendezvous: t.candidate,
            rendezvous_angle: None,
            room_steps: room,
            ahead: ahead.unwrap_or(0.0),
            approach: Some(approach),
            retreat: Some(retreat),
        };
        Ok(Ok((attach, detach, info, q_attach, q_detach)))
    }

    /// Finger `t.finger` attaching at `t` in place of `touches[k]` with the object at
    /// `theta`, checked: its squeeze reserve, its approach and the released finger's retreat,
    /// the attach and detach grasps' quality (against `floor`: below is a defect, the region
    /// being exact), and one rolling step after it. Why not goes to `rejected`.
    #[allow(clippy::too_many_arguments)]
    fn try_switch(
        &self,
        touches: &[Touch],
        k: usize,
        theta: Real,
        t: Touch,
        floor: Real,
        rejected: &mut Vec<String>,
        retreat: &Retreat,
        routes_timing: &Counter,
    ) -> Result<Attempt, PlanError> {
        let mut reject = |why: String| {
            rejected.push(format!(
                "{} by finger {}: {why}",
                self.describe(&t.point),
                t.finger
            ));
            Ok(Attempt::Rejected)
        };
        let f = self.finger(t.finger);
        let touch = self.touch_of(f, &t.q, theta);
        if let Some(why) = self.pose_check(f, &t.q, theta, &touch, true) {
            return reject(why);
        }
        // The released finger's retreat clear of all but this finger, else none of its
        // placements can serve (found once per finger of a search).
        if let Some((_, clear)) = retreat.without.iter().find(|(id, _)| *id == t.finger) {
            let without = clear.get_or_init(|| {
                let mut others = touches.to_vec();
                let gone = others.remove(k);
                self.route(
                    &gone,
                    &others,
                    theta,
                    "retreat",
                    &retreat.lifted,
                    Some(t.finger),
                )
                .map(|_| ())
            });
            if let Err(why) = without {
                return reject(why.clone());
            }
        }
        // The approach from home and the released finger's retreat to it.
        let mut detach_set = touches.to_vec();
        detach_set.push(t.clone());
        let gone = detach_set.remove(k);
        let routes = routes_timing.time(|| {
            self.route(&t, touches, theta, "approach", &Lifted::default(), None)
                .and_then(|approach| {
                    self.route(&gone, &detach_set, theta, "retreat", &retreat.lifted, None)
                        .map(|retreat| (approach, retreat))
                })
        });
        let (approach, retreat) = match routes {
            Ok(r) => r,
            Err(why) => return reject(why),
        };
        // Then the grasps and the rolling step after it. (Checked first, they cost the
        // Allegro sphere's plan more than they save: 1,737 of its 1,738 placements checked
        // went on to their routes.)
        let mut attach = touches.to_vec();
        attach.push(t.clone());
        let mut detach = attach.clone();
        detach.remove(k);
        let (g_attach, g_detach) = (self.grid_quality(&attach)?, self.grid_quality(&detach)?);
        if g_attach < floor || g_detach < floor {
            return Ok(Attempt::Defect(format!(
                "switch of finger {} to finger {} at {} fails verification: quality {g_attach:.6} attached, {g_detach:.6} detached at the candidates, alpha = {} (a defect: the region is exact)",
                touches[k].finger,
                t.finger,
                self.describe(&t.point),
                self.settings.alpha
            )));
        }
        let (q_attach, q_detach) = (self.quality(&attach)?, self.quality(&detach)?);
        if q_attach < floor || q_detach < floor {
            return reject(format!(
                "where the fingertips touch the grasp would keep alpha* {q_attach:.4} attached, {q_detach:.4} detached < alpha = {} (at the candidates {g_attach:.4}, {g_detach:.4})",
                self.settings.alpha
            ));
        }
        for (grasp, name) in [(&attach, "attached"), (&detach, "detached")] {
            if let Some((_, why)) = self.one_off(grasp)? {
                return reject(format!("{name}: {why}"));
            }
        }
        let step = self.settings.step.min(self.settings.goal - theta);
        if step > 1e-12 {
            let new = detach.len() - 1;
            match self.roll(&detach, theta, step)? {
                Roll::Blocked(j, why) if j == new => return reject(why),
                Roll::Stuck(why) => return reject(why),
                _ => {}
            }
        }
        Ok(Attempt::Chosen(Box::new(Chosen {
            t,
            attach,
            detach,
            q_attach,
            q_detach,
            approach,
            retreat,
        })))
    }
}

/// What the placements of a switch that failed ran into, for its message: each reason (the
/// text after the placement's `point by finger N: `) with how many placements it stopped,
/// the most frequent first, and the first three placements as examples; empty for none.
fn rejections(rejected: &[String]) -> String {
    if rejected.is_empty() {
        return String::new();
    }
    // Counted by reason, its figures left out (each placement's own are in the examples).
    let mut counts: Vec<(String, usize)> = Vec::new();
    for r in rejected {
        let why = without_figures(r.split_once(": ").map_or(r.as_str(), |(_, why)| why));
        match counts.iter_mut().find(|(w, _)| *w == why) {
            Some((_, n)) => *n += 1,
            None => counts.push((why, 1)),
        }
    }
    counts.sort_by_key(|c| std::cmp::Reverse(c.1));
    let reasons: Vec<String> = counts.iter().map(|(w, n)| format!("{n} x {w}")).collect();
    let examples = rejected
        .iter()
        .take(3)
        .cloned()
        .collect::<Vec<_>>()
        .join("; ");
    format!(" (stopped by: {}; e.g. {examples})", reasons.join(", "))
}

/// `text` with each number in it (digits, with a sign or decimal point) written `N`.
fn without_figures(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    let mut chars = text.chars().peekable();
    while let Some(c) = chars.next() {
        let starts = c.is_ascii_digit()
            || ((c == '-' || c == '.') && chars.peek().is_some_and(char::is_ascii_digit));
        if starts {
            while chars
                .peek()
                .is_some_and(|d| d.is_ascii_digit() || *d == '.' || *d == 'e')
            {
                chars.next();
            }
            out.push('N');
        } else {
            out.push(c);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_reason_is_counted_without_its_figures() {
        assert_eq!(
            without_figures("alpha* 0.4361 attached, -0.1033 detached < alpha = 0.12 (at 12)"),
            "alpha* N attached, N detached < alpha = N (at N)"
        );
        let rejected = [
            "[1.0, 0.0, 0.0] mm by finger 2: alpha* 0.1033 detached",
            "[2.0, 0.0, 0.0] mm by finger 2: alpha* 0.1024 detached",
        ]
        .map(String::from);
        assert!(
            rejections(&rejected).starts_with(" (stopped by: 2 x alpha* N detached; e.g. [1.0"),
            "{}",
            rejections(&rejected)
        );
    }

    /// A failed switch's message counts the placements per reason, the most frequent first,
    /// with three examples, however many were tried (it once listed all 804).
    #[test]
    fn a_failed_switch_says_what_stopped_its_placements_in_a_line() {
        assert_eq!(rejections(&[]), "");
        let rejected: Vec<String> = (0..800)
            .map(|i| {
                let why = if i % 100 == 7 {
                    "on its approach its fingertip would hit the object"
                } else {
                    "on its retreat its fingertip would hit the object"
                };
                format!("[{i}.0, 0.0, 0.0] mm by finger 2: {why}")
            })
            .collect();
        let said = rejections(&rejected);
        assert_eq!(
            said,
            " (stopped by: 792 x on its retreat its fingertip would hit the object, 8 x on its \
             approach its fingertip would hit the object; e.g. [0.0, 0.0, 0.0] mm by finger 2: on \
             its retreat its fingertip would hit the object; [1.0, 0.0, 0.0] mm by finger 2: on \
             its retreat its fingertip would hit the object; [2.0, 0.0, 0.0] mm by finger 2: on \
             its retreat its fingertip would hit the object)"
        );
    }
}
