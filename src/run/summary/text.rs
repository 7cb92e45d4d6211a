//! The run's summary as text: what `run` prints at the end, in lines of at most ~100 columns.

use std::io::Write;
use std::path::Path;

use anyhow::Result;
use icrflow_interfaces::topics::NodeRole;
use icrflow_scenario::{Config, Recording};

use super::RunSummary;
use crate::run::watch::WARM_UP;
use crate::wrap::{wrap, wrap_at};

impl RunSummary {
    /// Prints the summary of the run of `config_path` on stdout (`recording`: where the
    /// recording went): what a researcher looks for first (the goal, the rotation, the
    /// switches, the quality, the holds and their causes, restarts, latency), in lines of at
    /// most ~100 columns; `verbose` adds the rates, the latency's parts, the plan stream and
    /// each process's memory, scheduling and allocations.
    pub(in crate::run) fn print(
        &self,
        config_path: &Path,
        config: &Config,
        recording: Option<&Recording>,
        verbose: bool,
    ) -> Result<()> {
        let s = self;
        let mut o = std::io::stdout().lock();
        writeln!(o, "run        {}", config_path.display())?;
        writeln!(
            o,
            "outcome    {} after {:.1} s",
            if s.completed {
                "goal reached"
            } else {
                "goal NOT reached"
            },
            s.seconds
        )?;
        if !s.completed || s.reason != "goal reached" {
            for line in wrap(&s.reason, 89) {
                writeln!(o, "           {line}")?;
            }
        }
        writeln!(
            o,
            "rotation   {:.1} of {:.1} deg, {} finger switches, {} plan steps{}",
            s.rotation_deg,
            s.goal_deg,
            s.switches,
            s.steps,
            match s.replans {
                0 => String::new(),
                n => format!(", planned again {n}x"),
            }
        )?;
        let here = config
            .pipeline
            .nodes
            .iter()
            .any(|n| n == NodeRole::Command.name());
        if here {
            s.print_loop(&mut o, config, verbose)?;
        } else {
            writeln!(
                o,
                "commands   none here: the hand command node runs on another host (its run reports them)"
            )?;
            writeln!(o, "restarts   {}", s.restarts)?;
        }
        if verbose {
            s.print_processes(&mut o)?;
        }
        s.print_recording(&mut o, recording)
    }

    /// The lines on the loop's commands (when the hand command node runs here).
    fn print_loop(&self, o: &mut impl Write, config: &Config, verbose: bool) -> Result<()> {
        let s = self;
        writeln!(
            o,
            "quality    minimum alpha* while tracking {:.6} {} alpha = {}",
            s.min_quality,
            if s.min_quality >= s.alpha { ">=" } else { "<" },
            s.alpha
        )?;
        if let Some(a) = s.attaching_below_margin {
            writeln!(
                o,
                "attaching  {} commands moved a finger onto the object below the margin, the others held (alpha* down to {:.4})",
                a.commands, a.min_quality
            )?;
        }
        let causes: Vec<String> = s
            .hold_causes
            .iter()
            .map(|(cause, n)| format!("{n} {}", s.hold_figures.get(cause).unwrap_or(cause)))
            .collect();
        if causes.is_empty() {
            writeln!(o, "holds      none")?;
        } else {
            let text = format!("{}: {}", s.holds, causes.join(", "));
            for (i, line) in wrap_at(&text, ", ", 89).iter().enumerate() {
                writeln!(
                    o,
                    "{}{line}",
                    if i == 0 { "holds      " } else { "           " }
                )?;
            }
        }
        match s.planned_after_s {
            Some(t) => writeln!(
                o,
                "start-up   the plan came after {t:.1} s; the hand held its grasp meanwhile ({} commands)",
                s.startup_holds
            )?,
            None => writeln!(
                o,
                "start-up   no plan step came; the hand held its grasp ({} commands)",
                s.startup_holds
            )?,
        }
        let w = &s.planner_waits;
        if w.ahead.count > 0 {
            writeln!(
                o,
                "planner    the hand waited {} times for the rest of the plan: {:.1} s, at most {:.1} s",
                w.ahead.count, w.ahead.total_s, w.ahead.max_s
            )?;
        }
        if let Some(most) = w.again_s.iter().copied().reduce(f64::max) {
            writeln!(
                o,
                "re-plans   the hand waited {:.2} s in all for {} plans made again, at most {most:.2} s",
                w.again_s.iter().sum::<f64>(),
                w.again_s.len()
            )?;
        }
        writeln!(o, "restarts   {}", s.restarts)?;
        let l = &s.latency_us;
        writeln!(
            o,
            "latency    measurement to command p50 {:.0} us, p99 {:.0} us, max {:.0} us ({} commands)",
            l.end_to_end.p50, l.end_to_end.p99, l.end_to_end.max, l.end_to_end.samples
        )?;
        if let Some(e) = &s.estimate {
            writeln!(
                o,
                "estimate   off the truth p50 {:.2} / p99 {:.2} / max {:.2} deg; {} tracked beyond {:.1} deg",
                e.rotation_deg.p50,
                e.rotation_deg.p99,
                e.rotation_deg.max,
                e.tracked_off_truth,
                config.pipeline.max_pose_innovation.to_degrees(),
            )?;
        }
        if let Some(p) = &s.physics {
            writeln!(
                o,
                "physics    {}: the object turned {:.1} deg, its centre moved at most {:.2} mm{}",
                p.engine,
                p.rotation_deg,
                p.drift_m * 1e3,
                if p.dropped { "; DROPPED" } else { "" }
            )?;
            writeln!(
                o,
                "           contacts planned to roll: slip up to {:.1} mm/s, friction use up to {:.2} of mu, {} lost while planned",
                p.max_slip_m_s * 1e3,
                p.max_friction_use,
                p.unplanned_losses
            )?;
            for l in &p.losses {
                writeln!(
                    o,
                    "           lost: finger {} at {:.2} s (step {}, {}; the object at {:.1} deg)",
                    l.finger, l.at_s, l.step, l.phase, l.rotation_deg
                )?;
            }
            match p.first_grasp {
                Some(g) => writeln!(
                    o,
                    "           the hand made its grasp at {:.2} s (step {}, the object at {:.1} deg); {} plan steps ended before it",
                    g.at_s, g.step, g.rotation_deg, p.steps_before_first_grasp
                )?,
                None => writeln!(
                    o,
                    "           the hand never made its grasp ({} plan steps came)",
                    p.steps_before_first_grasp
                )?,
            }
            match p.min_true_quality {
                Some(q) => writeln!(
                    o,
                    "           true grasp quality >= {q:.3} (alpha {}) over {} plan steps, {} not in force closure",
                    config.grasp.alpha, p.steps_evaluated, p.steps_not_closed
                )?,
                None => writeln!(o, "           no plan step's true grasp was evaluated")?,
            }
            for n in &p.not_closed {
                writeln!(
                    o,
                    "           not in force closure: step {} ({}) at {:.2} s, fingers {:?} touching, the object at {:.1} deg",
                    n.step, n.phase, n.at_s, n.fingers, n.rotation_deg
                )?;
            }
            if let (1.., Some(q)) = (p.steps_not_closed, p.min_true_quality_closed) {
                writeln!(
                    o,
                    "           the steps in force closure: true grasp quality >= {q:.3}"
                )?;
            }
            match (p.true_quality_min, p.true_quality_p01) {
                (Some(q), Some(p01)) => writeln!(
                    o,
                    "           at every truth (where the fingertips touch, a lifted finger out): alpha* >= {q:.3}, p01 {p01:.3} over {} truths, {} not in force closure; {:.2} s below alpha",
                    p.true_quality_samples, p.samples_not_closed, p.time_below_alpha_s
                )?,
                _ => writeln!(
                    o,
                    "           the hand never made its grasp: no truth sampled"
                )?,
            }
            for b in &p.below_alpha {
                writeln!(
                    o,
                    "           below alpha: {:.2}-{:.2} s (step {}, {}; the object at {:.1} deg), alpha* down to {:.3} with fingers {:?} touching",
                    b.from_s, b.to_s, b.step, b.phase, b.rotation_deg, b.min_quality, b.fingers
                )?;
            }
            writeln!(
                o,
                "           the object tilted up to {:.1} deg off the plan's axis{}; gravity [{}, {}, {}] m/s^2",
                p.max_tilt_deg,
                p.max_tilt_at
                    .map(|a| format!(" (at {:.2} s, turned {:.1} deg)", a.at_s, a.rotation_deg))
                    .unwrap_or_default(),
                p.gravity[0],
                p.gravity[1],
                p.gravity[2]
            )?;
            let c = &p.collisions;
            // " (fingers 1, 2)", or nothing for none.
            let which = |f: &[u32]| {
                if f.is_empty() {
                    String::new()
                } else {
                    let ids: Vec<String> = f.iter().map(u32::to_string).collect();
                    format!(" (fingers {})", ids.join(", "))
                }
            };
            let first = |at: Option<crate::run::collisions::First>| {
                at.map(|f| format!(", first at {:.2} s ({:.1} deg)", f.at_s, f.rotation_deg))
                    .unwrap_or_default()
            };
            writeln!(
                o,
                "           of {} integration steps: {} with fingers touching each other{}{}, {} with a link on the object{}{}",
                c.physics_steps,
                c.finger_collisions,
                which(&c.fingers_touching),
                first(c.first_finger_collision),
                c.link_object_contacts,
                which(&c.links_on_object),
                first(c.first_link_object_contact),
            )?;
        }
        if verbose {
            writeln!(
                o,
                "commands   {} sent ({:.0} Hz; joint measurements {:.0} Hz), {} stale-tracked",
                s.commands, s.command_rate_hz, s.measurement_rate_hz, s.stale_tracked
            )?;
            writeln!(
                o,
                "           hops p50 {:.0} / {:.0} / {:.0} us, compute p50 {:.0} / {:.0} / {:.0} us",
                l.transport.joint_state.p50,
                l.transport.grasp_state.p50,
                l.transport.wrench_space.p50,
                l.compute.estimator.p50,
                l.compute.wrench.p50,
                l.compute.command.p50
            )?;
            writeln!(
                o,
                "           (hops: plant, estimator, wrench space; compute: estimator, wrench, command)"
            )?;
        }
        Ok(())
    }

    /// The plan stream and each process's memory, scheduling and allocations (`--verbose`).
    fn print_processes(&self, o: &mut impl Write) -> Result<()> {
        let s = self;
        writeln!(
            o,
            "plan       {} plan steps published, {:.0} Hz",
            s.plan_steps.published, s.plan_steps.rate_hz
        )?;
        let grew: Vec<String> = s
            .memory_kib
            .iter()
            .map(|(n, m)| format!("{n} {}->{} KiB", m.first, m.last))
            .collect();
        for (i, line) in wrap_at(&grew.join(", "), ", ", 89).iter().enumerate() {
            writeln!(
                o,
                "{}{line}",
                if i == 0 { "memory     " } else { "           " }
            )?;
        }
        let realtime: Vec<&str> = s
            .scheduling
            .iter()
            .filter(|(_, p)| p.starts_with("fifo") || p.starts_with("rr"))
            .map(|(n, _)| n.as_str())
            .collect();
        if let Some(policy) = realtime.first().and_then(|n| s.scheduling.get(*n)) {
            writeln!(
                o,
                "priority   {} at SCHED_{}",
                realtime.join(", "),
                policy.to_uppercase()
            )?;
        }
        let allocs: Vec<String> = s
            .allocations
            .iter()
            .map(|(n, a)| format!("{n} {} in {:.0} s", a.steady, a.seconds))
            .collect();
        let text = format!(
            "steady state (from {} s after each start): {}",
            WARM_UP.as_secs(),
            allocs.join(", ")
        );
        for (i, line) in wrap_at(&text, ", ", 89).iter().enumerate() {
            writeln!(
                o,
                "{}{line}",
                if i == 0 { "allocs     " } else { "           " }
            )?;
        }
        Ok(())
    }

    /// Where the recording went.
    fn print_recording(&self, o: &mut impl Write, recording: Option<&Recording>) -> Result<()> {
        let Some(r) = &self.recording else {
            return Ok(());
        };
        match &recording {
            Some(Recording::Rrd(p)) => {
                let names: Vec<String> = icrflow_scenario::rrd_parts(p)
                    .iter()
                    .map(|f| f.display().to_string())
                    .collect();
                if names.is_empty() {
                    writeln!(
                        o,
                        "recording  none: the visualizer wrote no {} (see its messages above)",
                        p.display()
                    )?;
                } else {
                    writeln!(o, "recording  saved to {}", names.join(", "))?;
                    writeln!(o, "           open it: rerun {}", names.join(" "))?;
                }
            }
            _ => writeln!(o, "recording  streamed to the {}", r.target)?,
        }
        writeln!(o, "           {} frames, {} dropped", r.frames, r.dropped)?;
        Ok(())
    }
}
