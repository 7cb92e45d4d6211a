//! `icrflow plan CONFIG [--out DIR] [--json] [--verbose]`: the whole scenario offline.

use std::fmt::Write as _;
use std::io::{IsTerminal, Write};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::Instant;

use anyhow::{Context, Result, bail};
use icrflow_grasp::math::Real;
use icrflow_plan::hand::Hand;
use icrflow_plan::planner::Plan;
use icrflow_plan::spatial::times::{PhaseTime, PhaseTimes};
use serde::Serialize;

use icrflow_scenario::{Config, Recording, Setup};

use crate::run::Viewer;

/// What `trajectory.json` holds.
#[derive(Serialize)]
struct Trajectory<'a> {
    config: String,
    object: String,
    space: &'static str,
    friction: Real,
    cone_edges: usize,
    fingertip_radius: Vec<(u32, Real)>,
    #[serde(flatten)]
    plan: &'a Plan,
}

/// Which grasp `validate`, `plan` and `run` evaluate, in lines under the quality: the contacts
/// on the object's section in the hand's plane (where the fingertips roll), and, for a
/// spatial analysis, how `analyze` differs.
pub fn section_note(config: &Config) -> &'static [&'static str] {
    match config.grasp.space {
        icrflow_grasp::wrench::Space::Planar => {
            &["the contacts on the object's section in the hand's plane (as analyze, plan, run)"]
        }
        icrflow_grasp::wrench::Space::Spatial => &[
            "the contacts on the object's section in the hand's plane, where the fingertips roll",
            "(as plan and run); analyze also snaps them to the nearest mesh facets: another alpha*",
        ],
    }
}

/// Runs the verb; returns the process exit code.
pub fn run(
    path: &Path,
    out: Option<PathBuf>,
    (json, verbose): (bool, bool),
    viewer: &Viewer,
    progress_after: std::time::Duration,
) -> Result<u8> {
    let flag = if out.is_some() {
        "--out"
    } else {
        "the output directory (no --out)"
    };
    let dir = out.unwrap_or_else(|| {
        let stem = path
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_else(|| "plan".into());
        PathBuf::from("out").join(stem)
    });
    {
        use crate::output::Kind;
        crate::output::check(&[
            (flag, Some(&dir), Kind::Dir),
            (
                flag,
                Some(&dir.join("trajectory.json")),
                Kind::FileInNewDirs,
            ),
            (flag, Some(&dir.join("trajectory.csv")), Kind::FileInNewDirs),
            ("--rrd", viewer.rrd.as_deref(), Kind::FileInNewDirs),
        ])?;
    }
    let config = Config::load(path)?;
    // The recording's target and program are checked before planning.
    let recording = viewer
        .flagged(&config)?
        .map(crate::run::absolute)
        .transpose()?;
    let program = recording
        .as_ref()
        .map(|_| crate::run::launch::node_program(icrflow_interfaces::topics::NodeRole::Visualizer))
        .transpose()?;
    let mut shown = crate::progress::Shown::new(progress_after);
    let setup = Setup::new_with(&config, &mut shown)?;
    drop(shown);
    let spatial = setup.spatial_scenario(&config);
    let mut shown = Planning::new(config.plan.goal, progress_after);
    let started = Instant::now();
    let planned = match &spatial {
        Some(s) => s
            .plan_timed(&mut |theta| shown.at(theta))
            .map(|(p, t)| (p, Some(t))),
        None => setup
            .scenario(&config)
            .plan(&mut |theta| shown.at(theta))
            .map(|p| (p, None)),
    };
    let elapsed = started.elapsed();
    shown.finish();
    let (plan, times) = match planned {
        Ok(p) => p,
        Err(e) if crate::exit::is_grasp_answer(&e) => {
            // The words of the Python binding's error (`cannot plan: ...`); nothing written.
            eprintln!("plan: cannot plan: {e}");
            return Ok(crate::exit::INCOMPLETE);
        }
        Err(e) => return Err(anyhow::Error::new(e).context("cannot plan")),
    };
    let trajectory = Trajectory {
        config: path.display().to_string(),
        object: config.object.describe(),
        space: config.grasp.space.name(),
        friction: config.grasp.model.mu(),
        cone_edges: config.grasp.model.edges(),
        fingertip_radius: setup
            .hand
            .fingers
            .iter()
            .map(|f| (f.id, f.tip_radius))
            .collect(),
        plan: &plan,
    };
    write_outputs(&dir, &trajectory, &plan, &setup.hand)?;
    let recorded = match (&recording, &program) {
        (Some(r), Some(program)) => Some(record(program, path, &dir, r)?),
        _ => None,
    };
    let s = &plan.summary;
    if json {
        let mut o = std::io::stdout().lock();
        if verbose {
            let mut v = serde_json::to_value(s).context("writing JSON")?;
            if let Some(m) = v.as_object_mut() {
                m.insert("phases".into(), serde_json::to_value(times)?);
            }
            serde_json::to_writer_pretty(&mut o, &v).context("writing JSON")?;
        } else {
            serde_json::to_writer_pretty(&mut o, s).context("writing JSON")?;
        }
        writeln!(o)?;
    } else {
        print_text(
            path,
            &config,
            s,
            plan.steps.first().map_or(0.0, |st| st.quality),
            &dir,
            elapsed,
            recording
                .as_ref()
                .map(|r| (r, recorded.as_deref().unwrap_or_default())),
            spatial.is_some(),
        )?;
        if verbose {
            let mut text = String::new();
            print_phases(&mut text, times.as_ref(), elapsed);
            std::io::stdout().lock().write_all(text.as_bytes())?;
        }
    }
    Ok(if s.completed {
        crate::exit::DONE
    } else {
        crate::exit::INCOMPLETE
    })
}

/// `plan --verbose`'s lines: where a spatial plan's time went, per phase (`times`; `None`: a
/// planar plan, not timed per phase), the planning having taken `elapsed`.
fn print_phases(o: &mut String, times: Option<&PhaseTimes>, elapsed: std::time::Duration) {
    let Some(t) = times else {
        let _ = writeln!(
            o,
            "phases     not timed: the planar planner's phases are not counted (the spatial planner's are)"
        );
        return;
    };
    let _ = writeln!(
        o,
        "phases     where the time went (count, time summed over the threads; {:.2} s of wall time):",
        elapsed.as_secs_f64()
    );
    let rows: [(&str, &PhaseTime, &str); 6] = [
        ("rolling steps", &t.rolling, ""),
        (
            "switch searches",
            &t.switches,
            " (each on the planning thread)",
        ),
        ("  exact regions", &t.regions, ""),
        (
            "  placements",
            &t.placements,
            " (a centred inverse kinematics each)",
        ),
        ("  rolling rooms", &t.rooms, ""),
        ("  checks", &t.checks, ""),
    ];
    for (name, p, note) in rows {
        let _ = writeln!(
            o,
            "           {name:<17} {:>7} x {:>8.3} s{note}",
            p.count, p.seconds
        );
    }
    let _ = writeln!(
        o,
        "             of which routes {:>5} x {:>8.3} s (approach and retreat)",
        t.routes.count, t.routes.seconds
    );
}

/// The progress of planning on stderr, once it has taken `--progress-after`: a bar on a
/// terminal, else a line every [`PLANNING_LINE`] (`planning   45 % (162 of 360 deg), 2.0 s`).
struct Planning {
    goal: Real,
    start: Instant,
    after: std::time::Duration,
    bar: Option<indicatif::ProgressBar>,
    terminal: bool,
    last_line: Option<Instant>,
}

/// How often a plain line of the planning's progress is printed (not on a terminal).
const PLANNING_LINE: std::time::Duration = std::time::Duration::from_secs(2);

impl Planning {
    fn new(goal: Real, after: std::time::Duration) -> Self {
        Self {
            goal,
            start: Instant::now(),
            after,
            bar: None,
            terminal: std::io::stderr().is_terminal(),
            last_line: None,
        }
    }

    /// The plan has turned the object by `theta` (rad).
    fn at(&mut self, theta: Real) {
        let now = Instant::now();
        if now.duration_since(self.start) < self.after {
            return;
        }
        let goal = self.goal.to_degrees();
        let done = theta.to_degrees().clamp(0.0, goal.max(0.0));
        if self.terminal {
            let bar = self.bar.get_or_insert_with(|| {
                let bar = indicatif::ProgressBar::new(goal.ceil() as u64);
                if let Ok(style) = indicatif::ProgressStyle::with_template(
                    "planning {bar:40} {pos:>4}/{len} deg rotated, {elapsed_precise}",
                ) {
                    bar.set_style(style);
                }
                bar
            });
            bar.set_position(done.round() as u64);
        } else if self
            .last_line
            .is_none_or(|t| now.duration_since(t) >= PLANNING_LINE)
        {
            self.last_line = Some(now);
            eprintln!(
                "planning   {:.0} % ({done:.0} of {goal:.0} deg), {:.1} s",
                100.0 * done / goal.max(1e-9),
                now.duration_since(self.start).as_secs_f64()
            );
        }
    }

    /// Clears the bar.
    fn finish(&mut self) {
        if let Some(b) = self.bar.take() {
            b.finish_and_clear();
        }
    }
}

/// The plan's summary `s` as text on stdout: the plan of config `path`, its initial grasp of
/// quality `start_quality`, written in `dir`, planned in `elapsed`, recorded to `recording`
/// (with its id); `spatial`: planned by the spatial planner.
#[allow(clippy::too_many_arguments)]
fn print_text(
    path: &Path,
    config: &Config,
    s: &icrflow_plan::planner::Summary,
    start_quality: Real,
    dir: &Path,
    elapsed: std::time::Duration,
    recording: Option<(&Recording, &str)>,
    spatial: bool,
) -> Result<()> {
    let mut o = std::io::stdout().lock();
    writeln!(o, "config     {}", path.display())?;
    writeln!(
        o,
        "object     {} ({} space, mu = {}, s = {})",
        config.object.describe(),
        config.grasp.space.name(),
        config.grasp.model.mu(),
        config.grasp.model.edges()
    )?;
    writeln!(
        o,
        "rotation   {:.1} deg of {:.1} deg{}{}",
        s.rotation.to_degrees(),
        s.goal.to_degrees(),
        if spatial {
            format!(
                " about [{:.3}, {:.3}, {:.3}] (spatial)",
                s.axis[0], s.axis[1], s.axis[2]
            )
        } else {
            String::new()
        },
        if s.completed { "" } else { " (stopped early)" }
    )?;
    writeln!(
        o,
        "steps      {} ({} rolling), {} finger switches",
        s.steps, s.rolling_steps, s.switches
    )?;
    writeln!(
        o,
        "quality    alpha* = {start_quality:.6} at the start, minimum {:.6} {} alpha = {}{}",
        s.min_quality,
        if s.min_quality >= s.alpha { ">=" } else { "<" },
        s.alpha,
        if s.alpha > config.grasp.alpha {
            format!(
                " (plan.alpha: headroom over the hand's gate, grasp.alpha = {})",
                config.grasp.alpha
            )
        } else {
            String::new()
        }
    )?;
    if spatial {
        writeln!(
            o,
            "           where the fingertips touch (each step's exact contact points and normals; their candidates' grasp keeps alpha too), 6D analysis, the cones' tangents about the axis (as analyze)"
        )?;
        writeln!(
            o,
            "rolling    largest slip of a step (the contact's travel over the object less over the fingertip) = {:.3e} m",
            s.max_rolling_residual
        )?;
        if !matches!(
            config.object,
            icrflow_scenario::ObjectSpec::Sphere { .. }
                | icrflow_scenario::ObjectSpec::Ellipsoid { .. }
        ) {
            writeln!(
                o,
                "           (on a polyhedron that includes pivoting about its edges, where the contact stays on the object and moves over the fingertip: rolling, not slip)"
            )?;
        }
    } else {
        for line in section_note(config) {
            writeln!(o, "           {line}")?;
        }
        writeln!(
            o,
            "rolling    largest residual |r_f dgamma + s| = {:.3e} m",
            s.max_rolling_residual
        )?;
    }
    if let Some(mm) = s.min_link_clearance_mm {
        if spatial {
            let r = config.plant.link_radius * 1e3;
            writeln!(
                o,
                "links      closest {mm:.1} mm to the object: their capsules (radius {r:.1} mm, plant.link_radius_mm) clear of it by {:.1} mm, and of each other",
                mm - r
            )?;
        } else {
            writeln!(
                o,
                "links      closest {mm:.1} mm to the object (links as lines: their thickness is the hand's margin)"
            )?;
        }
    }
    if let Some(mm) = s.min_squeeze_reserve_mm {
        writeln!(
            o,
            "squeeze    every finger in contact can press at least {mm:.2} mm further along its contact normal{}",
            if mm >= icrflow_plan::planner::SQUEEZE_PROBE * 1e3 - 1e-9 {
                " (measured up to 5 mm)"
            } else {
                ""
            }
        )?;
    }
    if s.switches > 0 {
        let pct = |x: usize| 100.0 * x as Real / s.brute_force_candidates.max(1) as Real;
        writeln!(
            o,
            "switching  rendezvous candidates over all switches: {} exact (brute force, {}),\n           {} by eq. 8 LP ({:.0} %, {} unsafe), {} by the ICR zone rule ({:.0} %)",
            s.brute_force_candidates,
            match s.region_erosion {
                0 => "used".to_string(),
                n => format!(
                    "the points chosen from the {} of them {n} ring{} inside",
                    s.chosen_from_candidates,
                    if n == 1 { "" } else { "s" }
                ),
            },
            s.lp_region_candidates,
            pct(s.lp_region_candidates),
            s.lp_region_unsafe,
            s.icr_region_candidates,
            pct(s.icr_region_candidates)
        )?;
    }
    if let Some(why) = &s.stop_reason {
        writeln!(o, "stopped    {why}")?;
    }
    writeln!(
        o,
        "wrote      {} and {} ({:.0} ms planning)",
        dir.join("trajectory.csv").display(),
        dir.join("trajectory.json").display(),
        elapsed.as_secs_f64() * 1e3
    )?;
    if let Some((r, recorded)) = recording {
        let how = match r {
            Recording::Rrd(p) => {
                format!("saved to {} (open it: rerun {})", p.display(), p.display())
            }
            other => format!("streamed to the {}", crate::run::target_name(other)),
        };
        writeln!(o, "recording  {how}; id {}", recorded)?;
    }
    Ok(())
}

/// Records the plan written in `dir` with the visualizer in its plan mode (Rerun lives in that
/// binary only), to `target`; returns the recording id.
fn record(program: &Path, config: &Path, dir: &Path, target: &Recording) -> Result<String> {
    let id = format!(
        "icrflow-plan-{}-{}",
        std::process::id(),
        icrflow_interfaces::now_ns() / 1_000_000
    );
    eprintln!("recording the plan for Rerun ...");
    let status = Command::new(program)
        .arg("--plan")
        .arg(config)
        .arg(dir.join("trajectory.json"))
        .args(
            icrflow_runtime::launch::RecordingLaunch {
                target: target.to_text(),
                id: id.clone(),
                footer: true,
            }
            .to_args(),
        )
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .status()
        .with_context(|| format!("starting {}", program.display()))?;
    if !status.success() {
        bail!(
            "the plan was written, but recording it failed ({} {status})",
            program.display()
        );
    }
    Ok(id)
}

/// Writes `trajectory.json` and `trajectory.csv` into `dir`, each through a temporary file
/// renamed into place, so that a failure never leaves a partial file under the final name.
fn write_outputs(dir: &Path, trajectory: &Trajectory<'_>, plan: &Plan, hand: &Hand) -> Result<()> {
    std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let mut json = serde_json::to_string_pretty(trajectory).context("serialising the plan")?;
    json.push('\n');
    let csv = csv(plan, hand);
    for (name, text) in [("trajectory.json", json), ("trajectory.csv", csv)] {
        let tmp = dir.join(format!(".{name}.tmp"));
        std::fs::write(&tmp, text).with_context(|| format!("cannot write {}", tmp.display()))?;
        std::fs::rename(&tmp, dir.join(name))
            .with_context(|| format!("cannot write {}", dir.join(name).display()))?;
    }
    Ok(())
}

/// The trajectory as CSV: one row per step, a group of columns per finger (empty cells for
/// a free finger's contact).
fn csv(plan: &Plan, hand: &Hand) -> String {
    let mut out = String::from("step,phase,rotation_deg,quality");
    for f in &hand.fingers {
        let id = f.id;
        let _ = write!(
            out,
            ",f{id}_contact,f{id}_x,f{id}_y,f{id}_z,f{id}_angle_deg,f{id}_cap_angle_deg,f{id}_tip_rotation_deg"
        );
        for j in 1..=f.dof() {
            let _ = write!(out, ",f{id}_q{j}_deg");
        }
    }
    out.push('\n');
    let opt = |x: Option<Real>| x.map_or(String::new(), |v| format!("{v}"));
    // Angles in degrees, as in the JSON (the same conversion).
    let deg = |x: Option<Real>| opt(x.map(Real::to_degrees));
    for s in &plan.steps {
        let _ = write!(
            out,
            "{},{},{},{}",
            s.step,
            s.phase.name(),
            s.rotation.to_degrees(),
            s.quality
        );
        for f in &s.fingers {
            let p = f.point.map(|p| p.map(Some)).unwrap_or([None; 3]);
            let _ = write!(
                out,
                ",{},{},{},{},{},{},{}",
                u8::from(f.contact.is_some()),
                opt(p[0]),
                opt(p[1]),
                opt(p[2]),
                deg(f.angle),
                deg(f.cap_angle),
                f.tip_rotation.to_degrees()
            );
            for q in &f.joints {
                let _ = write!(out, ",{}", q.to_degrees());
            }
        }
        out.push('\n');
    }
    out
}
