//! The hand command node's safety gate (issue #4, "Safety"): a command is computed only from
//! inputs that are present, of our schema and kind, in order, fresh, finite and, for the
//! grasp's wrench space, force closure with quality >= alpha. Otherwise the node holds the
//! last safe grasp and reports the [`Hold`] reason.

use icrflow_interfaces::{
    GraspState, Header, HeaderError, Kind, MAX_FINGERS, MAX_JOINTS, PlanPhase, PlanStepHeader,
    PlanWait, WrenchSpaceHeader,
};

/// Why the hand holds.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum Hold {
    /// No message of this input has been offered yet (one that was offered and refused is
    /// reported by its refusal instead).
    #[error("no {0} yet")]
    Missing(&'static str),
    /// A message was refused by its header.
    #[error("{topic}: {error}")]
    Header {
        /// The input.
        topic: &'static str,
        /// Why.
        error: HeaderError,
    },
    /// The last accepted message is too old now.
    #[error("{topic} is stale: {age_ms:.1} ms old, limit {limit_ms:.1} ms")]
    Stale {
        /// The input.
        topic: &'static str,
        /// Its age (ms).
        age_ms: f64,
        /// The limit (ms).
        limit_ms: f64,
    },
    /// The planner node makes the plan again from the estimate (the object stopped off its
    /// target, [`PlanWait::Again`]): the hand holds rather than track a target of the plan
    /// the object has left (its joints were solved for the object where the plan had it).
    #[error("the planner plans again from the estimate: {ms} ms so far")]
    Replanning {
        /// How long the planner has planned so far (ms, as the plan step says).
        ms: u32,
    },
    /// A value is not finite or out of range.
    #[error("{topic}: invalid {what}")]
    Invalid {
        /// The input.
        topic: &'static str,
        /// What is wrong.
        what: String,
    },
    /// The wrench space was computed from another grasp state than the one accepted.
    #[error("the wrench space (of grasp state {wrench_of}) is not that of grasp state {grasp}")]
    Mismatch {
        /// The grasp state the wrench space was computed from.
        wrench_of: u64,
        /// The grasp state accepted.
        grasp: u64,
    },
    /// No input has caused a command for a while.
    #[error("no wrench space for {ms:.1} ms")]
    Quiet {
        /// Since the last command (ms).
        ms: f64,
    },
    /// The estimate doubts itself: a residual of the grasp state the command would be
    /// computed from is over its bound (DESIGN.md section 5: the quality gate on the
    /// estimated grasp is necessary, not sufficient).
    #[error(
        "the estimate is off: {what} {value:.2} {unit} over the bound {bound:.2} {unit} (pipeline.{key})"
    )]
    Estimate {
        /// The residual.
        what: &'static str,
        /// Its value (in `unit`).
        value: f64,
        /// The bound (in `unit`).
        bound: f64,
        /// The unit of both.
        unit: &'static str,
        /// The config key of the bound.
        key: &'static str,
    },
    /// The grasp is not force closure.
    #[error("the grasp is not force closure")]
    NotForceClosure,
    /// The grasp's quality is below the margin.
    #[error("quality alpha* = {quality:.4} below the margin alpha = {alpha}")]
    BelowMargin {
        /// The quality.
        quality: f64,
        /// The margin.
        alpha: f64,
    },
}

/// The bounds of the estimate's residuals ([`GraspState::pose_innovation`],
/// [`GraspState::residual`]) over which the hand holds.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EstimateBounds {
    /// Largest smoothed pose innovation (rad).
    pub pose_innovation: f64,
    /// Largest root-mean-square distance of the fingertips in contact from the object (m).
    pub contact_residual: f64,
}

impl EstimateBounds {
    /// No bound (every estimate is believed).
    pub const NONE: Self = Self {
        pose_innovation: f64::INFINITY,
        contact_residual: f64::INFINITY,
    };

    /// Why grasp state `g` is not to be believed, if it is not.
    pub fn check(&self, g: &GraspState) -> Result<(), Hold> {
        if g.pose_innovation.abs() > self.pose_innovation {
            return Err(Hold::Estimate {
                what: "pose innovation",
                value: g.pose_innovation.abs().to_degrees(),
                bound: self.pose_innovation.to_degrees(),
                unit: "deg",
                key: "max_pose_innovation_deg",
            });
        }
        if g.residual > self.contact_residual {
            return Err(Hold::Estimate {
                what: "contact residual",
                value: g.residual * 1e3,
                bound: self.contact_residual * 1e3,
                unit: "mm",
                key: "max_contact_residual_mm",
            });
        }
        Ok(())
    }
}

/// Accepted inputs and their order.
#[derive(Debug, Clone)]
pub struct Gate {
    max_age_ns: u64,
    alpha: f64,
    estimate: EstimateBounds,
    plan: Option<PlanStepHeader>,
    grasp: Option<GraspState>,
    wrench: Option<WrenchSpaceHeader>,
    last: [u64; 3],
    /// Per input, why its last refused message was refused: while none of it has been
    /// accepted, that is the reason to hold (rather than "no plan step yet").
    refused: [Option<Hold>; 3],
}

fn finite(values: &[f64]) -> bool {
    values.iter().all(|x| x.is_finite())
}

impl Gate {
    /// A gate accepting inputs up to `max_age_ns` old, with margin `alpha`, and estimates
    /// within `estimate`.
    pub fn new(max_age_ns: u64, alpha: f64, estimate: EstimateBounds) -> Self {
        Self {
            max_age_ns,
            alpha,
            estimate,
            plan: None,
            grasp: None,
            wrench: None,
            last: [0; 3],
            refused: [None, None, None],
        }
    }

    fn header(
        &self,
        topic: &'static str,
        h: &Header,
        kind: Kind,
        slot: usize,
        now: u64,
    ) -> Result<(), Hold> {
        h.check_fresh(kind, self.last[slot], now, self.max_age_ns)
            .map_err(|error| Hold::Header { topic, error })
    }

    /// Offers a plan step; accepted if valid.
    pub fn offer_plan(&mut self, m: &PlanStepHeader, now: u64) -> Result<(), Hold> {
        self.check_plan(m, now)
            .inspect_err(|e| self.refused[0] = Some(e.clone()))?;
        self.last[0] = m.header.sequence;
        self.plan = Some(*m);
        Ok(())
    }

    fn check_plan(&self, m: &PlanStepHeader, now: u64) -> Result<(), Hold> {
        const T: &str = "plan step";
        self.header(T, &m.header, Kind::PlanStep, 0, now)?;
        let invalid = |what: String| Hold::Invalid { topic: T, what };
        if m.finger_count as usize > MAX_FINGERS {
            return Err(invalid(format!("finger count {}", m.finger_count)));
        }
        if m.phase > PlanPhase::Done as u32 {
            return Err(invalid(format!("phase {}", m.phase)));
        }
        if !finite(&[m.rotation, m.quality]) {
            return Err(invalid("rotation or quality (not finite)".into()));
        }
        for t in &m.targets[..m.finger_count as usize] {
            if t.joint_count as usize > MAX_JOINTS {
                return Err(invalid(format!(
                    "joint count {} of finger {}",
                    t.joint_count, t.finger
                )));
            }
            if !finite(&t.joints[..t.joint_count as usize]) || !finite(&t.point) {
                return Err(invalid(format!(
                    "target of finger {} (not finite)",
                    t.finger
                )));
            }
        }
        Ok(())
    }

    /// Offers a grasp state; accepted if valid.
    pub fn offer_grasp(&mut self, m: &GraspState, now: u64) -> Result<(), Hold> {
        self.check_grasp(m, now)
            .inspect_err(|e| self.refused[1] = Some(e.clone()))?;
        self.last[1] = m.header.sequence;
        self.grasp = Some(*m);
        Ok(())
    }

    fn check_grasp(&self, m: &GraspState, now: u64) -> Result<(), Hold> {
        const T: &str = "grasp state";
        self.header(T, &m.header, Kind::GraspState, 1, now)?;
        let invalid = |what: String| Hold::Invalid { topic: T, what };
        if m.finger_count as usize > MAX_FINGERS {
            return Err(invalid(format!("finger count {}", m.finger_count)));
        }
        if !finite(&m.position)
            || !finite(&m.orientation)
            || !finite(&[m.rotation, m.residual, m.pose_innovation])
        {
            return Err(invalid("object pose (not finite)".into()));
        }
        for f in &m.fingers[..m.finger_count as usize] {
            if !finite(&f.point) || !finite(&f.normal) || !f.residual.is_finite() {
                return Err(invalid(format!(
                    "contact of finger {} (not finite)",
                    f.finger
                )));
            }
        }
        Ok(())
    }

    /// Offers a wrench-space summary; accepted if valid (force closure and quality are judged
    /// by [`Gate::decide`], so that a bad grasp holds the hand rather than being ignored).
    pub fn offer_wrench(&mut self, m: &WrenchSpaceHeader, now: u64) -> Result<(), Hold> {
        self.check_wrench(m, now)
            .inspect_err(|e| self.refused[2] = Some(e.clone()))?;
        self.last[2] = m.header.sequence;
        self.wrench = Some(*m);
        Ok(())
    }

    fn check_wrench(&self, m: &WrenchSpaceHeader, now: u64) -> Result<(), Hold> {
        const T: &str = "wrench space";
        self.header(T, &m.header, Kind::WrenchSpace, 2, now)?;
        if !finite(&[m.quality, m.epsilon, m.alpha]) {
            return Err(Hold::Invalid {
                topic: T,
                what: "quality (not finite)".into(),
            });
        }
        Ok(())
    }

    /// The last accepted plan step.
    pub fn plan(&self) -> Option<&PlanStepHeader> {
        self.plan.as_ref()
    }

    /// The last accepted grasp state.
    pub fn grasp(&self) -> Option<&GraspState> {
        self.grasp.as_ref()
    }

    /// Whether the last accepted grasp state has finger `id` touching the object.
    pub fn touching(&self, id: u32) -> bool {
        self.grasp.as_ref().is_some_and(|g| {
            let n = (g.finger_count as usize).min(MAX_FINGERS);
            g.fingers[..n]
                .iter()
                .any(|c| c.finger == id && c.in_contact == 1)
        })
    }

    /// The quality alpha* of the last accepted wrench space (0 before any).
    pub fn quality(&self) -> f64 {
        self.wrench.as_ref().map_or(0.0, |w| w.quality)
    }

    /// Whether a command may be computed now: every input accepted, still fresh, the wrench
    /// space that of the accepted grasp state, and that grasp force closure with quality >=
    /// alpha. Returns the plan step to follow.
    pub fn decide(&self, now: u64) -> Result<&PlanStepHeader, Hold> {
        let missing =
            |slot: usize, topic| self.refused[slot].clone().unwrap_or(Hold::Missing(topic));
        let plan = self.plan.as_ref().ok_or_else(|| missing(0, "plan step"))?;
        let grasp = self
            .grasp
            .as_ref()
            .ok_or_else(|| missing(1, "grasp state"))?;
        let wrench = self
            .wrench
            .as_ref()
            .ok_or_else(|| missing(2, "wrench space"))?;
        for (topic, h) in [
            ("plan step", &plan.header),
            ("grasp state", &grasp.header),
            ("wrench space", &wrench.header),
        ] {
            let age = now.saturating_sub(h.source_time_ns);
            if age > self.max_age_ns {
                return Err(Hold::Stale {
                    topic,
                    age_ms: age as f64 * 1e-6,
                    limit_ms: self.max_age_ns as f64 * 1e-6,
                });
            }
        }
        if plan.planning == PlanWait::Again as u32 {
            return Err(Hold::Replanning {
                ms: plan.planning_ms,
            });
        }
        // End to end: the joint measurement the grasp state was estimated from must be fresh
        // too, not only the estimate.
        let origin = grasp.header.origin_time_ns;
        if origin > 0 && now.saturating_sub(origin) > self.max_age_ns {
            return Err(Hold::Stale {
                topic: "joint measurement behind the grasp state",
                age_ms: now.saturating_sub(origin) as f64 * 1e-6,
                limit_ms: self.max_age_ns as f64 * 1e-6,
            });
        }
        // The quality judged below is that of the grasp the command is computed from.
        if wrench.header.input_sequence != grasp.header.sequence {
            return Err(Hold::Mismatch {
                wrench_of: wrench.header.input_sequence,
                grasp: grasp.header.sequence,
            });
        }
        // The grasp judged below is the estimate's: it must be believable.
        self.estimate.check(grasp)?;
        if wrench.force_closure != 1 {
            return Err(Hold::NotForceClosure);
        }
        if wrench.quality < self.alpha * (1.0 - 1e-9) {
            return Err(Hold::BelowMargin {
                quality: wrench.quality,
                alpha: self.alpha,
            });
        }
        Ok(plan)
    }
}

/// A plan step's attach let through below the margin ([`Gate::attach_below_margin`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Attach {
    /// The finger that attaches.
    pub finger: u32,
    /// The quality alpha* of the estimated grasp, the fingers touching without it.
    pub quality: f64,
    /// The margin it is below.
    pub alpha: f64,
}

impl Gate {
    /// Below the margin, the one command that cannot lower it: where the gate holds for
    /// `hold` = [`Hold::BelowMargin`] (so every other check passed: fresh, matched, believed,
    /// force closure) and the plan step attaches a finger (`rendezvous_finger`; the step
    /// itself, or a way point of the finger's approach, where it is still free) to exactly the
    /// fingers the estimate has touching, the attach may go on with those fingers held where
    /// the last command that moved the hand put them (the caller's part): the grasp is the one
    /// the gate judged, a free finger moves along its planned approach, and a contact is added to the
    /// grasp; the wrench space of more contacts contains that of fewer, so alpha* can only
    /// grow once it touches. Holding instead leaves the grasp below the margin for as long as
    /// the plan waits for that attach. The attaching finger and the quality; `None` where the
    /// hold stands.
    pub fn attach_below_margin(&self, hold: &Hold) -> Option<Attach> {
        let Hold::BelowMargin { quality, alpha } = *hold else {
            return None;
        };
        let (plan, grasp) = (self.plan.as_ref()?, self.grasp.as_ref()?);
        let touching = |id: u32| self.touching(id);
        let finger = plan.rendezvous_finger;
        if plan.phase != PlanPhase::Attach as u32 || finger == 0 || quality <= 0.0 {
            return None;
        }
        let n = (plan.finger_count as usize).min(MAX_FINGERS);
        let planned = &plan.targets[..n];
        if !planned.iter().any(|t| t.finger == finger) {
            return None;
        }
        let m = (grasp.finger_count as usize).min(MAX_FINGERS);
        // The estimate's contacts are the plan step's without the attaching finger's: no
        // finger touching that the step has free, none of its others lost.
        let same = planned
            .iter()
            .all(|t| touching(t.finger) == (t.in_contact == 1 && t.finger != finger))
            && grasp.fingers[..m]
                .iter()
                .filter(|c| c.in_contact == 1)
                .all(|c| planned.iter().any(|t| t.finger == c.finger));
        same.then_some(Attach {
            finger,
            quality,
            alpha,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use icrflow_interfaces::{SCHEMA_VERSION, now_ns};

    fn inputs(seq: u64) -> (PlanStepHeader, GraspState, WrenchSpaceHeader) {
        let plan = PlanStepHeader {
            header: Header::new(Kind::PlanStep, seq, 0, 0),
            phase: PlanPhase::Rolling as u32,
            finger_count: 1,
            ..Default::default()
        };
        let grasp = GraspState {
            header: Header::new(Kind::GraspState, seq, 0, 0),
            orientation: [1.0, 0.0, 0.0, 0.0],
            finger_count: 1,
            ..Default::default()
        };
        let wrench = WrenchSpaceHeader {
            header: Header::new(Kind::WrenchSpace, seq, seq, 0),
            force_closure: 1,
            dim: 3,
            quality: 0.2,
            epsilon: 0.1,
            alpha: 0.1,
        };
        (plan, grasp, wrench)
    }

    const AGE: u64 = 200_000_000;

    #[test]
    fn good_inputs_are_followed() {
        let mut g = Gate::new(AGE, 0.1, EstimateBounds::NONE);
        let (p, s, w) = inputs(1);
        assert_eq!(g.decide(now_ns()), Err(Hold::Missing("plan step")));
        g.offer_plan(&p, now_ns()).unwrap();
        g.offer_grasp(&s, now_ns()).unwrap();
        g.offer_wrench(&w, now_ns()).unwrap();
        assert!(g.decide(now_ns()).is_ok());
    }

    /// While the planner makes the plan again from the estimate the hand holds, saying for how
    /// long; a target that is the last planned so far (the rest of the plan to come) is
    /// followed.
    #[test]
    fn the_hand_holds_while_the_plan_is_made_again() {
        let now = now_ns();
        let mut g = Gate::new(AGE, 0.1, EstimateBounds::NONE);
        let (mut p, s, w) = inputs(1);
        p.planning = PlanWait::Again as u32;
        p.planning_ms = 40;
        g.offer_plan(&p, now).unwrap();
        g.offer_grasp(&s, now).unwrap();
        g.offer_wrench(&w, now).unwrap();
        let hold = g.decide(now).unwrap_err();
        assert_eq!(hold, Hold::Replanning { ms: 40 });
        assert_eq!(
            hold.to_string(),
            "the planner plans again from the estimate: 40 ms so far"
        );
        let (mut ahead, _, _) = inputs(2);
        ahead.planning = PlanWait::Ahead as u32;
        g.offer_plan(&ahead, now).unwrap();
        assert!(g.decide(now).is_ok());
    }

    #[test]
    fn an_input_refused_before_any_was_accepted_holds_with_its_refusal() {
        let now = now_ns();
        let mut g = Gate::new(AGE, 0.1, EstimateBounds::NONE);
        let (mut p, s, w) = inputs(1);
        p.header.source_time_ns = now - 2 * AGE;
        let refusal = g.offer_plan(&p, now).unwrap_err();
        assert!(
            refusal.to_string().starts_with("plan step: stale"),
            "{refusal}"
        );
        g.offer_grasp(&s, now).unwrap();
        g.offer_wrench(&w, now).unwrap();
        // Not "no plan step yet": the plan steps come, and are too old.
        assert_eq!(g.decide(now), Err(refusal));
        let (p, _, _) = inputs(2);
        g.offer_plan(&p, now).unwrap();
        assert!(g.decide(now).is_ok());
    }

    #[test]
    fn every_kind_of_bad_input_holds_with_its_reason() {
        let now = now_ns();
        let mut g = Gate::new(AGE, 0.1, EstimateBounds::NONE);
        let (p, s, w) = inputs(5);
        g.offer_plan(&p, now).unwrap();
        g.offer_grasp(&s, now).unwrap();
        g.offer_wrench(&w, now).unwrap();
        // Out of order and repeated.
        let (old, _, _) = inputs(4);
        assert!(matches!(
            g.offer_plan(&old, now),
            Err(Hold::Header {
                error: HeaderError::OutOfOrder { .. },
                ..
            })
        ));
        // Another schema version.
        let (mut v2, _, _) = inputs(6);
        v2.header.schema = SCHEMA_VERSION + 1;
        assert!(matches!(
            g.offer_plan(&v2, now),
            Err(Hold::Header {
                error: HeaderError::Schema { .. },
                ..
            })
        ));
        // NaN in a target.
        let (mut nan, _, _) = inputs(7);
        nan.targets[0].joint_count = 3;
        nan.targets[0].joints[1] = f64::NAN;
        assert!(matches!(g.offer_plan(&nan, now), Err(Hold::Invalid { .. })));
        // NaN in the object pose.
        let (_, mut bad, _) = inputs(8);
        bad.position[0] = f64::INFINITY;
        assert!(matches!(
            g.offer_grasp(&bad, now),
            Err(Hold::Invalid { .. })
        ));
        // Stale on arrival.
        let (_, _, mut late) = inputs(9);
        late.header.source_time_ns = now - 2 * AGE;
        assert!(matches!(
            g.offer_wrench(&late, now),
            Err(Hold::Header {
                error: HeaderError::Stale { .. },
                ..
            })
        ));
        // The refused messages changed nothing: still following the good inputs.
        assert!(g.decide(now).is_ok());
        // The wrench space of another grasp state than the accepted one.
        let (_, _, mut other) = inputs(10);
        other.header.input_sequence = 4;
        g.offer_wrench(&other, now).unwrap();
        assert_eq!(
            g.decide(now),
            Err(Hold::Mismatch {
                wrench_of: 4,
                grasp: 5
            })
        );
        // Quality below alpha, then not force closure (of the accepted grasp state, 5).
        let (_, _, mut low) = inputs(13);
        low.header.input_sequence = 5;
        low.quality = 0.05;
        g.offer_wrench(&low, now).unwrap();
        assert!(matches!(g.decide(now), Err(Hold::BelowMargin { .. })));
        let (_, _, mut open) = inputs(14);
        open.header.input_sequence = 5;
        open.force_closure = 0;
        g.offer_wrench(&open, now).unwrap();
        assert_eq!(g.decide(now), Err(Hold::NotForceClosure));
        // Inputs that stop coming go stale: a crashed planner holds the hand.
        let (_, _, mut w) = inputs(15);
        w.header.input_sequence = 5;
        g.offer_wrench(&w, now).unwrap();
        assert!(g.decide(now).is_ok());
        assert!(matches!(g.decide(now + 2 * AGE), Err(Hold::Stale { .. })));
    }

    #[test]
    fn an_estimate_whose_residuals_are_over_their_bounds_holds_naming_which() {
        let now = now_ns();
        let bounds = EstimateBounds {
            pose_innovation: 3f64.to_radians(),
            contact_residual: 1.5e-3,
        };
        let mut g = Gate::new(AGE, 0.1, bounds);
        let (p, mut s, mut w) = inputs(1);
        g.offer_plan(&p, now).unwrap();
        // Within the bounds (either sign of the innovation): followed.
        s.pose_innovation = -2.9f64.to_radians();
        s.residual = 1.4e-3;
        g.offer_grasp(&s, now).unwrap();
        g.offer_wrench(&w, now).unwrap();
        assert!(g.decide(now).is_ok());
        // The innovation over its bound: held, and said so with the key.
        let (_, mut off, _) = inputs(2);
        off.pose_innovation = -3.1f64.to_radians();
        g.offer_grasp(&off, now).unwrap();
        w.header.input_sequence = 2;
        w.header.sequence = 2;
        g.offer_wrench(&w, now).unwrap();
        let hold = g.decide(now).unwrap_err();
        assert!(matches!(
            hold,
            Hold::Estimate {
                what: "pose innovation",
                ..
            }
        ));
        let text = hold.to_string();
        assert!(
            text.contains("pose innovation 3.10 deg over the bound 3.00 deg (pipeline.max_pose_innovation_deg)"),
            "{text}"
        );
        // The contact residual over its bound.
        s = off;
        s.header.sequence = 3;
        s.pose_innovation = 0.0;
        s.residual = 1.6e-3;
        g.offer_grasp(&s, now).unwrap();
        w.header.input_sequence = 3;
        w.header.sequence = 3;
        g.offer_wrench(&w, now).unwrap();
        assert!(
            g.decide(now)
                .unwrap_err()
                .to_string()
                .contains("contact residual 1.60 mm")
        );
        // A non-finite innovation is refused on arrival.
        let (_, mut nan, _) = inputs(4);
        nan.pose_innovation = f64::NAN;
        assert!(matches!(
            g.offer_grasp(&nan, now),
            Err(Hold::Invalid { .. })
        ));
    }
}
