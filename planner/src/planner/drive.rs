//! The planning loop shared by the planar and the spatial planner ([`drive`]): rolling steps
//! toward the goal, a finger switch where a contact is blocked, tried earlier where it fails.

use icrflow_grasp::math::Real;

use super::{Contact, Deadline, Phase, Plan, PlanError, Settings, Step, Summary, Switch};

/// What a rolling step found (of the planar planner's [`Contact`]s, or the spatial
/// planner's [`crate::spatial::Touch`]es).
#[derive(Debug, Clone, PartialEq)]
pub enum Roll<C = Contact> {
    /// Every finger moved; the new contacts and their quality.
    Moved(Vec<C>, Real),
    /// Contact `.0` cannot move, for reason `.1`: a switch may help.
    Blocked(usize, String),
    /// The grasp as a whole cannot go on.
    Stuck(String),
}

/// What the planning loop ([`drive`]) asks of a scenario: the planar [`Scenario`] and the
/// spatial [`crate::spatial::SpatialScenario`] plan alike, a rolling step at a time and a
/// finger switch where a contact is blocked.
pub(crate) trait Stepper {
    /// A contact of the grasp.
    type Contact;
    /// The finger of contact `c`.
    fn finger_of(c: &Self::Contact) -> u32;
    /// The hand's fingers.
    fn fingers(&self) -> usize;
    /// The grasp `contacts` rolled on by `step` from `theta` (rad).
    fn roll(
        &self,
        contacts: &[Self::Contact],
        theta: Real,
        step: Real,
    ) -> Result<Roll<Self::Contact>, PlanError>;
    /// A free finger taking over from contact `k`, blocked for `why`: the grasp with it
    /// attached, the grasp after the release, the switch and the two grasps' qualities; or
    /// why there is none (also where the search stopped because `deadline` passed).
    fn switch(
        &self,
        contacts: &[Self::Contact],
        k: usize,
        theta: Real,
        why: &str,
        progress: &mut dyn FnMut(Real),
        deadline: &Deadline,
    ) -> Result<Result<Switched<Self::Contact>, NoSwitch>, PlanError>;
    /// Step `step` of phase `phase` at `theta` with `contacts` of quality `quality`.
    fn record(
        &self,
        step: usize,
        phase: Phase,
        theta: Real,
        quality: Real,
        contacts: &[Self::Contact],
    ) -> Step;
}

/// A switch found ([`Stepper::switch`]): the grasp with the attached finger, the grasp after
/// the release, the switch, and the two grasps' qualities.
pub(crate) type Switched<C> = (Vec<C>, Vec<C>, Switch, Real, Real);

/// Why no free finger takes over ([`Stepper::switch`]).
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct NoSwitch {
    /// Why, in words.
    pub reason: String,
    /// Whether it is a defect of the planner (a region that is exact failed verification):
    /// the plan stops there, no earlier switch tried in its place.
    pub defect: bool,
    /// Whether the search was stopped because the plan's time ran out
    /// ([`Settings::max_plan`]) before it found one: the plan stops there.
    pub out_of_time: bool,
}

impl NoSwitch {
    /// No free finger can take over, for `reason`.
    pub(crate) fn none(reason: String) -> Self {
        Self {
            reason,
            defect: false,
            out_of_time: false,
        }
    }

    /// A defect of the planner, `reason`.
    pub(crate) fn defect(reason: String) -> Self {
        Self {
            reason,
            defect: true,
            out_of_time: false,
        }
    }

    /// The search stopped when the plan's time ran out, `reason`.
    pub(crate) fn out_of_time(reason: String) -> Self {
        Self {
            reason,
            defect: false,
            out_of_time: true,
        }
    }
}

/// How many of the planning loop's first steps no later step can drop, of `steps` made:
/// those up to the earliest rolling step an earlier switch may go back to (at most
/// [`EARLY_SWITCH_STEPS`] before the last one `rolled`, none before the run that began at
/// `run_start`, the last switch); all of them where the run has no rolling step to go back
/// to.
fn settled_len<C>(steps: usize, rolled: &[(usize, Real, C)], run_start: usize) -> usize {
    let earliest = run_start.max(rolled.len().saturating_sub(1 + EARLY_SWITCH_STEPS));
    rolled.get(earliest).map_or(steps, |r| r.0 + 1)
}

/// The steps the planning loop made and where it stopped.
pub(crate) struct Driven {
    /// The steps, the start's first.
    pub steps: Vec<Step>,
    /// The rotation reached (rad).
    pub rotation: Real,
    /// The smallest quality of any grasp in force.
    pub min_quality: Real,
    /// Finger switches.
    pub switches: usize,
    /// Why it stopped short of the goal, if it did.
    pub stop_reason: Option<String>,
}

/// How many rolling steps back the planning loop tries a finger switch again where the
/// switch of a blocked finger fails: the finger released that much earlier, where the
/// object's and the other fingers' positions leave a free finger other candidates.
pub const EARLY_SWITCH_STEPS: usize = 6;

/// Why a plan stopped when its time ran out ([`Settings::max_plan`]): at `theta` (rad) with
/// `steps` steps made, searching for a finger to take over from `switching` if it was.
fn out_of_time(deadline: &Deadline, theta: Real, steps: usize, switching: Option<u32>) -> String {
    let during = switching.map_or(String::new(), |f| {
        format!(", searching for a finger to take over from finger {f}")
    });
    let plural = if steps == 1 { "" } else { "s" };
    format!(
        "stopped after plan.max_plan_s = {} s, at {:.1} deg with {steps} step{plural} made{during} (raise plan.max_plan_s to plan on)",
        deadline.budget.map_or(0.0, |b| b.as_secs_f64()),
        theta.to_degrees()
    )
}

/// The planning loop of `s` under `settings`, from the grasp `started` (its contacts and
/// quality) at rotation `theta` (rad): rolling steps toward the goal; where a contact is
/// blocked, a finger switch, unless the blocked finger has just attached or every finger has
/// switched since the last rolling step (the hand has no way forward). Where no free finger
/// can take over from the blocked one, the switch is tried up to [`EARLY_SWITCH_STEPS`]
/// rolling steps earlier (the latest that serves is kept, the steps after it dropped).
/// `progress` is called with the rotation after every step (and during a switch, as `s`
/// does), `moved` with the contacts of every rolling step kept, and `settled` with the steps,
/// in order and each once, as soon as no later step can drop them ([`settled_len`]): a hand
/// may follow those while the rest is planned (the receding horizon of
/// [`crate::follow::Follower`]'s node).
#[allow(clippy::too_many_arguments)]
pub(crate) fn drive<S: Stepper>(
    s: &S,
    settings: &Settings,
    mut theta: Real,
    started: (Vec<S::Contact>, Real),
    deadline: &Deadline,
    progress: &mut dyn FnMut(Real),
    moved: &mut dyn FnMut(&[S::Contact]),
    settled: &mut dyn FnMut(&[Step]),
) -> Result<Driven, PlanError>
where
    S::Contact: Clone,
{
    let (mut contacts, quality) = started;
    let mut steps = vec![s.record(0, Phase::Start, theta, quality, &contacts)];
    let mut switches = 0;
    let mut stop_reason = None;
    // Switches since the last rolling step, and the finger the last switch attached.
    let mut switches_in_a_row = 0;
    let mut just_attached: Option<u32> = None;
    // The rolling steps kept (their step's index, rotation and contacts), and where in them
    // the run since the last switch begins (an earlier switch may be tried within it).
    let mut rolled: Vec<(usize, Real, Vec<S::Contact>)> = Vec::new();
    let mut run_start = 0;
    // The steps handed to `settled` so far.
    let mut sent = 0;
    while theta < settings.goal - 1e-9 {
        let now = settled_len(steps.len(), &rolled, run_start);
        if now > sent {
            settled(&steps[sent..now]);
            sent = now;
        }
        if steps.len() >= settings.max_steps {
            stop_reason = Some(format!(
                "stopped after plan.max_steps = {} steps",
                settings.max_steps
            ));
            break;
        }
        if deadline.passed() {
            stop_reason = Some(out_of_time(deadline, theta, steps.len(), None));
            break;
        }
        let step = settings.step.min(settings.goal - theta);
        match s.roll(&contacts, theta, step)? {
            Roll::Stuck(reason) => {
                stop_reason = Some(reason);
                break;
            }
            Roll::Moved(next, quality) => {
                switches_in_a_row = 0;
                just_attached = None;
                contacts = next;
                theta += step;
                rolled.push((steps.len(), theta, contacts.clone()));
                steps.push(s.record(steps.len(), Phase::Rolling, theta, quality, &contacts));
                progress(theta);
            }
            Roll::Blocked(k, why) => {
                let finger = S::finger_of(&contacts[k]);
                if just_attached == Some(finger) || switches_in_a_row >= s.fingers() {
                    stop_reason = Some(format!(
                        "finger {finger} cannot roll on ({why}) right after it attached: the hand has no way forward"
                    ));
                    break;
                }
                let mut found = s.switch(&contacts, k, theta, &why, progress, deadline)?;
                // (What the search says, not the clock: a search that ended with its answer,
                // no switch or a defect, as the time ran out keeps that answer.)
                if found.as_ref().is_err_and(|e| e.out_of_time) {
                    stop_reason = Some(out_of_time(deadline, theta, steps.len(), Some(finger)));
                    break;
                }
                if let Some(NoSwitch { reason, defect, .. }) = found.as_ref().err().cloned() {
                    // Released earlier, the latest first (not in place of a defect), while
                    // the plan has time.
                    let mut tried = 0;
                    let mut timed_out = false;
                    for back in (1..=EARLY_SWITCH_STEPS).filter(|_| !defect) {
                        // The current grasp is the last rolled (if any since the switch).
                        let Some(r) = rolled
                            .len()
                            .checked_sub(1 + back)
                            .filter(|&r| r >= run_start)
                        else {
                            break;
                        };
                        let (at, earlier) = (rolled[r].1, &rolled[r].2);
                        let Some(j) = earlier.iter().position(|c| S::finger_of(c) == finger) else {
                            break;
                        };
                        tried = back;
                        let early = format!(
                            "released {back} steps early: {} deg on, no free finger could take over ({why})",
                            (theta - at).to_degrees().round()
                        );
                        if deadline.passed() {
                            timed_out = true;
                            break;
                        }
                        match s.switch(earlier, j, at, &early, progress, deadline)? {
                            Ok(sw) => {
                                steps.truncate(rolled[r].0 + 1);
                                contacts = earlier.clone();
                                rolled.truncate(r + 1);
                                theta = at;
                                found = Ok(sw);
                                break;
                            }
                            Err(e) if e.out_of_time => {
                                timed_out = true;
                                break;
                            }
                            Err(_) => {}
                        }
                    }
                    if found.is_err() && timed_out {
                        stop_reason = Some(out_of_time(deadline, theta, steps.len(), Some(finger)));
                        break;
                    }
                    if found.is_err() {
                        stop_reason = Some(match tried {
                            0 => reason,
                            n => format!(
                                "{reason} (nor released up to {n} rolling steps earlier, since the last switch or the start)"
                            ),
                        });
                        break;
                    }
                }
                if let Ok((attach, detach, info, q_attach, q_detach)) = found {
                    just_attached = Some(info.attached);
                    let mut a = s.record(steps.len(), Phase::Attach, theta, q_attach, &attach);
                    a.switch = Some(info);
                    steps.push(a);
                    steps.push(s.record(steps.len(), Phase::Detach, theta, q_detach, &detach));
                    contacts = detach;
                    switches += 1;
                    switches_in_a_row += 1;
                    run_start = rolled.len();
                    progress(theta);
                }
            }
        }
    }
    if steps.len() > sent {
        settled(&steps[sent..]);
    }
    for (_, _, c) in &rolled {
        moved(c);
    }
    let min_quality = steps
        .iter()
        .map(|s| s.quality)
        .fold(Real::INFINITY, Real::min);
    Ok(Driven {
        steps,
        rotation: theta,
        min_quality,
        switches,
        stop_reason,
    })
}

impl Driven {
    /// The plan of these steps under `settings`, about `axis`, with the planner's own
    /// figures: its largest rolling residual (m), its links' smallest clearance (m) and its
    /// smallest squeeze reserve (m).
    pub(crate) fn into_plan(
        self,
        settings: &Settings,
        axis: [Real; 3],
        max_rolling_residual: Real,
        link_clearance: Real,
        squeeze_reserve: Real,
    ) -> Plan {
        let steps = self.steps;
        let switch_list = || steps.iter().filter_map(|s| s.switch.as_ref());
        let lp_region_unsafe = switch_list()
            .map(|s| {
                s.lp_region
                    .iter()
                    .filter(|q| s.brute_force.binary_search(q).is_err())
                    .count()
            })
            .sum();
        let summary = Summary {
            completed: self.stop_reason.is_none(),
            stop_reason: self.stop_reason,
            rotation: self.rotation,
            goal: settings.goal,
            axis,
            switches: self.switches,
            steps: steps.len(),
            rolling_steps: steps.iter().filter(|s| s.phase == Phase::Rolling).count(),
            min_quality: self.min_quality,
            alpha: settings.alpha,
            max_rolling_residual,
            icr_region_candidates: switch_list().map(|s| s.icr_region.len()).sum(),
            lp_region_candidates: switch_list().map(|s| s.lp_region.len()).sum(),
            lp_region_unsafe,
            brute_force_candidates: switch_list().map(|s| s.brute_force.len()).sum(),
            chosen_from_candidates: switch_list().map(|s| s.chosen_from).sum(),
            region_erosion: settings.region_erosion,
            min_link_clearance_mm: Some(link_clearance * 1e3),
            min_squeeze_reserve_mm: Some(squeeze_reserve * 1e3),
        };
        Plan { summary, steps }
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// A hand of fingers 1-4 whose contacts are their numbers: finger 1 is blocked once the
    /// object has turned `limit` steps, and a free finger takes over only while it has turned
    /// at most `reach` steps (or never).
    struct Toy {
        limit: usize,
        reach: Option<usize>,
        /// Where a switch fails verification (a defect), if anywhere.
        defect: Option<usize>,
        step: Real,
    }

    impl Stepper for Toy {
        type Contact = u32;

        fn finger_of(c: &u32) -> u32 {
            *c
        }

        fn fingers(&self) -> usize {
            4
        }

        fn roll(&self, contacts: &[u32], theta: Real, step: Real) -> Result<Roll<u32>, PlanError> {
            let done = ((theta + step) / self.step).round() as usize;
            Ok(match contacts.iter().position(|&c| c == 1) {
                Some(k) if done > self.limit => Roll::Blocked(k, "at its limit".into()),
                // The quality falls while finger 1 holds: the steps dropped take theirs along.
                Some(_) => Roll::Moved(contacts.to_vec(), 1.0 - done as Real * 0.1),
                None => Roll::Moved(contacts.to_vec(), 0.95),
            })
        }

        fn switch(
            &self,
            contacts: &[u32],
            k: usize,
            theta: Real,
            why: &str,
            _: &mut dyn FnMut(Real),
            deadline: &Deadline,
        ) -> Result<Result<Switched<u32>, NoSwitch>, PlanError> {
            let done = (theta / self.step).round() as usize;
            if self.defect == Some(done) {
                return Ok(Err(NoSwitch::defect(format!("a defect at {done} steps"))));
            }
            // (As the spatial search: it stops when the time has run out.)
            if deadline.passed() {
                return Ok(Err(NoSwitch::out_of_time("stopped".into())));
            }
            if self.reach.is_none_or(|r| done > r) {
                return Ok(Err(NoSwitch::none(format!(
                    "no free finger reaches at {done} steps"
                ))));
            }
            let mut attach = contacts.to_vec();
            attach.push(4);
            let mut detach = attach.clone();
            let released = detach.remove(k);
            let switch = Switch {
                released,
                attached: 4,
                reason: why.to_string(),
                icr_region: Vec::new(),
                lp_region: Vec::new(),
                brute_force: Vec::new(),
                chosen_from: 0,
                rendezvous: 0,
                rendezvous_angle: None,
                room_steps: 0,
                ahead: 0.0,
                approach: None,
                retreat: None,
            };
            Ok(Ok((attach, detach, switch, 0.9, 0.9)))
        }

        fn record(&self, step: usize, phase: Phase, theta: Real, quality: Real, _: &[u32]) -> Step {
            Step::new(step, phase, theta, quality, Vec::new())
        }
    }

    /// Settings for a test of the loop: margins `alpha` and `gate_alpha`, `steps` steps of
    /// `step` (rad) to the goal; nothing else checked.
    pub(crate) fn settings(alpha: Real, gate_alpha: Real, step: Real, steps: usize) -> Settings {
        Settings {
            alpha,
            gate_alpha,
            goal: step * steps as Real,
            step,
            cap_margin: 0.0,
            min_manipulability: 0.0,
            squeeze_reserve: 0.0,
            region_erosion: 0,
            neighbour_alpha: None,
            neighbour_rings: 1,
            max_steps: 1000,
            max_plan: None,
            attach_resolution: 0.01,
        }
    }

    fn plan(limit: usize, reach: Option<usize>) -> (Driven, usize) {
        plan_with(limit, reach, None)
    }

    fn plan_with(limit: usize, reach: Option<usize>, defect: Option<usize>) -> (Driven, usize) {
        plan_until(limit, reach, defect, &Deadline::after(None))
    }

    fn plan_until(
        limit: usize,
        reach: Option<usize>,
        defect: Option<usize>,
        deadline: &Deadline,
    ) -> (Driven, usize) {
        let step = 5f64.to_radians();
        let toy = Toy {
            limit,
            reach,
            defect,
            step,
        };
        let mut moved = 0;
        let mut settled: Vec<Step> = Vec::new();
        let driven = drive(
            &toy,
            &settings(0.1, 0.1, step, 10),
            0.0,
            (vec![1, 2, 3], 1.0),
            deadline,
            &mut |_| {},
            &mut |_| moved += 1,
            &mut |s| settled.extend_from_slice(s),
        )
        .unwrap();
        // The settled steps, handed on as they were made, are the plan's, each once: none
        // of them was dropped for an earlier switch.
        assert_eq!(settled, driven.steps);
        (driven, moved)
    }

    /// The steps are settled while the plan is made: after a switch at once, while rolling
    /// up to [`EARLY_SWITCH_STEPS`] rolling steps behind the last.
    #[test]
    fn steps_are_settled_as_soon_as_no_earlier_switch_can_drop_them() {
        // Six rolling steps made, the run from the start: a switch may go back to the first
        // (released five steps early), which is kept with the start.
        let rolled: Vec<(usize, Real, ())> = (1..=6).map(|k| (k, 0.0, ())).collect();
        assert_eq!(settled_len(7, &rolled, 0), 2);
        // Eight: to the second at the earliest (EARLY_SWITCH_STEPS before the last).
        let rolled: Vec<(usize, Real, ())> = (1..=8).map(|k| (k, 0.0, ())).collect();
        assert_eq!(settled_len(9, &rolled, 0), 3);
        // Right after a switch (its two steps after rolling step 8): all of them.
        assert_eq!(settled_len(11, &rolled, 8), 11);
        // One rolling step since that switch (step 11): still all (none earlier to go back to).
        let mut after = rolled.clone();
        after.push((11, 0.0, ()));
        assert_eq!(settled_len(12, &after, 8), 12);
    }

    #[test]
    fn a_switch_that_fails_at_the_limit_is_made_earlier_the_steps_after_it_dropped() {
        // Blocked after 6 steps; a free finger reaches up to 4: released 2 steps early.
        let (d, moved) = plan(6, Some(4));
        assert_eq!(d.stop_reason, None);
        assert_eq!(d.switches, 1);
        let phases: Vec<Phase> = d.steps.iter().map(|s| s.phase).collect();
        let mut expected = vec![Phase::Start];
        expected.extend([Phase::Rolling; 4]);
        expected.extend([Phase::Attach, Phase::Detach]);
        expected.extend([Phase::Rolling; 6]);
        assert_eq!(phases, expected);
        // Numbered in order, the switch at the rotation of the step it follows.
        assert!(d.steps.iter().enumerate().all(|(i, s)| s.step == i));
        assert!((d.steps[5].rotation - d.steps[4].rotation).abs() < 1e-12);
        let w = d.steps[5].switch.as_ref().unwrap();
        assert_eq!((w.released, w.attached), (1, 4));
        assert!(
            w.reason.starts_with("released 2 steps early"),
            "{}",
            w.reason
        );
        // The dropped steps' contacts and qualities are gone: 10 rolling steps kept, the
        // lowest quality the 4th's (the dropped 6th's was 0.4).
        assert_eq!(moved, 10);
        assert!((d.min_quality - 0.6).abs() < 1e-12, "{}", d.min_quality);
    }

    #[test]
    fn a_switch_no_earlier_step_serves_stops_the_plan_with_the_first_reason() {
        // Too far back: EARLY_SWITCH_STEPS short of the limit is not enough.
        let (d, moved) = plan(8, Some(8 - EARLY_SWITCH_STEPS - 1));
        assert!(
            d.stop_reason.as_deref().unwrap().contains("at 8 steps"),
            "{:?}",
            d.stop_reason
        );
        assert_eq!(d.switches, 0);
        assert_eq!(moved, 8);
        assert_eq!(d.steps.len(), 9);
        let reason = d.stop_reason.unwrap();
        assert!(
            reason.contains("nor released up to 6 rolling steps earlier"),
            "{reason}"
        );
        // Blocked before any rolling step: nothing earlier to try.
        let (d, moved) = plan(0, None);
        assert_eq!((d.steps.len(), moved), (1, 0));
        assert_eq!(
            d.stop_reason.as_deref(),
            Some("no free finger reaches at 0 steps")
        );
        // Not past the start: blocked after 3 steps, tried 2 and 1 steps earlier.
        let (d, _) = plan(3, None);
        let reason = d.stop_reason.unwrap();
        assert!(
            reason.contains("at 3 steps") && reason.contains("up to 2 rolling steps earlier"),
            "{reason}"
        );
    }

    #[test]
    fn a_defect_stops_the_plan_where_it_is_found_no_earlier_switch_in_its_place() {
        // An earlier switch would serve (reach 4), but the one at the limit is a defect.
        let (d, moved) = plan_with(6, Some(4), Some(6));
        assert_eq!(d.switches, 0);
        assert_eq!(moved, 6);
        assert_eq!(d.stop_reason.as_deref(), Some("a defect at 6 steps"));
    }

    /// A plan whose time runs out stops where it is, short of its goal, and says where:
    /// before a step, or in a switch search (no earlier switch tried then).
    #[test]
    fn a_plan_whose_time_runs_out_stops_where_it_is_and_says_so() {
        // Asked before each of the 6 rolling steps and before the 7th, which is blocked: the
        // switch search asks once more and finds the time run out.
        let (d, moved) = plan_until(6, Some(4), None, &Deadline::after_asking(7));
        assert_eq!((d.switches, moved, d.steps.len()), (0, 6, 7));
        assert_eq!(
            d.stop_reason.as_deref(),
            Some(
                "stopped after plan.max_plan_s = 0 s, at 30.0 deg with 7 steps made, searching for a finger to take over from finger 1 (raise plan.max_plan_s to plan on)"
            )
        );
        // Before the third step.
        let (d, moved) = plan_until(6, Some(4), None, &Deadline::after_asking(2));
        assert_eq!((d.switches, moved, d.steps.len()), (0, 2, 3));
        assert_eq!(
            d.stop_reason.as_deref(),
            Some(
                "stopped after plan.max_plan_s = 0 s, at 10.0 deg with 3 steps made (raise plan.max_plan_s to plan on)"
            )
        );
        // A search that ends with its own answer (a defect) as the time runs out keeps it: the
        // answer is the search's, not the clock's (the next ask would find the time gone).
        let (d, _) = plan_until(6, Some(4), Some(6), &Deadline::after_asking(7));
        assert_eq!(d.stop_reason.as_deref(), Some("a defect at 6 steps"));
        // Time enough: the whole plan, as without a bound.
        let hour = Deadline::after(Some(std::time::Duration::from_secs(3600)));
        let (d, _) = plan_until(6, Some(4), None, &hour);
        let unbounded = plan(6, Some(4)).0;
        assert_eq!((d.steps, d.stop_reason), (unbounded.steps, None));
    }
}
