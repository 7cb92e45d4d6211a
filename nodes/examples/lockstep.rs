//! A MuJoCo run of a config in lockstep (`icrflow_nodes::lockstep`): what the physics did,
//! per plan phase, for tuning the plant's controls.
//!
//!     cargo run --release -p icrflow-nodes --example lockstep -- CONFIG [--seconds S]
//!         [--every-s S] [--replan-s S] [--stall-ms MS --stall-every-ms MS]
//!         [SECTION.KEY=VALUE ...]
//!
//! `--seconds`: simulated seconds to run (40); `--every-s`: the interval of the lines (0.5 s);
//! `--replan-s`: simulated seconds a re-plan takes (`lockstep::run`'s `replan_s`, 0);
//! `--stall-ms`, `--stall-every-ms`: the loop upstream of the command node stalled that many
//! milliseconds of every period (`lockstep::Stall`; none by default).
//! `SECTION.KEY=VALUE`: a config key set over the file's, the value in TOML (e.g. `plant.kp=5
//! pipeline.seed=2 pipeline.push_nm=[0,0,0.05]`), validated with the file as `run` validates
//! it (a value out of its bounds is refused by its key). Prints a line every `--every-s` of
//! simulated time (true, estimated and planned rotation; per fingertip its normal force, the
//! commanded force's magnitude in brackets, friction use and slip speed in mm/s; each finger's
//! contact candidate, estimated / planned; how far each fingertip is from its command across
//! and along the surface; link contacts; the object's centre) and, at the end, the re-plans
//! and per phase the largest slip speed and friction use at contacts planned to roll, and
//! contacts lost while planned; the collisions, the largest tilt, and the estimate's largest
//! error against the truth (`lockstep::truth::TruthWatch`).

#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    reason = "a test, bench or example: a panic is its failure, with the message it gives"
)]

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use anyhow::{Context as _, Result, bail};
use clap::Parser;
use icrflow_interfaces::{CommandMode, MAX_FINGERS, PlanPhase, PlantTruth, read_text};
use icrflow_nodes::lockstep;
use icrflow_nodes::lockstep::truth::{LOST_AFTER, TruthWatch};
use icrflow_plan::rolling::tilt as tilt_of;
use icrflow_scenario::{Config, Setup};

#[derive(Default, Debug)]
struct PhaseStats {
    ticks: u64,
    slip: f64,
    friction_use: f64,
    lost: u64,
    /// Rotation off the plan's axis accrued truth to truth (deg).
    off_axis: f64,
}

/// Finger `slot`'s true normal force (N) and friction use `|f_t| / (mu f_n)`.
fn pressing(truth: &PlantTruth, slot: usize, mu: f64) -> (f64, f64) {
    let f = truth.contact_forces[slot];
    let n = truth.contact_normals[slot];
    let normal = -(f[0] * n[0] + f[1] * n[1] + f[2] * n[2]);
    let tangential = (0..3)
        .map(|k| (f[k] + n[k] * normal).powi(2))
        .sum::<f64>()
        .sqrt();
    (normal, tangential / (mu * normal.max(1e-9)))
}

/// The example's command line (see the module's docs).
#[derive(Debug, Parser)]
#[command(name = "lockstep")]
struct Cli {
    /// The config (a MuJoCo plant's).
    config: PathBuf,
    /// Simulated seconds to run.
    #[arg(long, default_value_t = 40.0)]
    seconds: f64,
    /// Simulated seconds between the lines.
    #[arg(long, default_value_t = 0.5)]
    every_s: f64,
    /// Simulated seconds a re-plan takes.
    #[arg(long, default_value_t = 0.0)]
    replan_s: f64,
    /// Milliseconds of every `--stall-every-ms` the loop upstream of the command node is
    /// stalled (`lockstep::Stall`).
    #[arg(long, default_value_t = 0.0)]
    stall_ms: f64,
    /// The period of the stalls (ms).
    #[arg(long, default_value_t = 1.0)]
    stall_every_ms: f64,
    /// A config key set over the file's, its value in TOML: `plant.kp=5`.
    #[arg(value_name = "SECTION.KEY=VALUE", value_parser = setting)]
    set: Vec<Setting>,
}

/// A config key set from the command line.
#[derive(Debug, Clone)]
struct Setting {
    section: String,
    key: String,
    value: toml::Value,
}

/// Reads `SECTION.KEY=VALUE` (the value in TOML).
fn setting(text: &str) -> Result<Setting> {
    let (name, value) = text
        .split_once('=')
        .with_context(|| format!("{text:?}: expected SECTION.KEY=VALUE, e.g. plant.kp=5"))?;
    let (section, key) = name
        .split_once('.')
        .with_context(|| format!("{name:?}: expected SECTION.KEY, e.g. plant.kp"))?;
    let value: toml::Table = format!("v = {value}")
        .parse()
        .with_context(|| format!("{name}: {value:?} is not a TOML value"))?;
    let value = value.get("v").cloned().context("a TOML value")?;
    Ok(Setting {
        section: section.trim().into(),
        key: key.trim().into(),
        value,
    })
}

/// The config file with the settings over it, validated as `run` validates a file.
fn configured(path: &Path, settings: &[Setting]) -> Result<Config> {
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("cannot read config {}", path.display()))?;
    let mut table: toml::Table = text
        .parse()
        .with_context(|| format!("invalid config {}", path.display()))?;
    for s in settings {
        let section = table
            .entry(s.section.clone())
            .or_insert_with(|| toml::Value::Table(toml::Table::new()));
        let toml::Value::Table(section) = section else {
            bail!("{}: not a section of the config", s.section);
        };
        section.insert(s.key.clone(), s.value.clone());
    }
    Config::from_table(table, path)
        .with_context(|| format!("invalid config {} with the settings given", path.display()))
}

fn main() -> Result<()> {
    let cli = Cli::parse();
    let config = configured(&cli.config, &cli.set)?;
    let (seconds, every, replan_s) = (cli.seconds, cli.every_s, cli.replan_s);
    let setup = Setup::new(&config)?;
    let stall = lockstep::Stall::of_ms(cli.stall_ms, cli.stall_every_ms, config.pipeline.rate_hz)?;
    let mu = config.grasp.model.mu();
    let mut stats: BTreeMap<&'static str, PhaseStats> = BTreeMap::new();
    let mut next_line = 0.0;
    let mut worst: Option<(f64, String)> = None;
    // Losses, collisions, tilt and the estimate's error, as `run` counts them.
    let mut watch = TruthWatch::new(&config);
    // The object's orientation at the last truth (its rotation off the axis accrues per phase).
    let axis = nalgebra::Unit::new_normalize(config.turn.axis);
    let mut last_pose: Option<nalgebra::UnitQuaternion<f64>> = None;
    // Per finger slot: ticks in a row its fingertip has been off the object while the plan has
    // it in contact (rolling steps), and how many such gaps ended after each length (1 ms
    // ticks; the last bucket: longer).
    let mut off_ticks = [0usize; MAX_FINGERS];
    let mut gaps = [0u64; 12];
    let started = std::time::Instant::now();
    let ended = lockstep::run_stalled(
        &config,
        &setup,
        seconds,
        0.5,
        replan_s,
        stall,
        &mut |tick| {
            if let Some(plan) = tick.plan.filter(|p| p.phase == PlanPhase::Rolling as u32) {
                let n = (plan.finger_count as usize).min(MAX_FINGERS);
                for (slot, f) in setup.hand.fingers.iter().enumerate().take(MAX_FINGERS) {
                    let planned = plan.targets[..n]
                        .iter()
                        .any(|t| t.finger == f.id && t.in_contact == 1);
                    let on = tick.plant.sim().contact(slot).is_some();
                    if planned && !on {
                        off_ticks[slot] += 1;
                    } else {
                        if planned && off_ticks[slot] > 0 {
                            gaps[off_ticks[slot].min(gaps.len() - 1)] += 1;
                        }
                        off_ticks[slot] = 0;
                    }
                }
            }
            watch.observe(tick);
            let Some(truth) = tick.truth else {
                return;
            };
            let q = TruthWatch::orientation(truth);
            let off_axis = last_pose.replace(q).map_or(0.0, |last| {
                tilt_of(&(q * last.inverse()), &axis).to_degrees()
            });
            let plan = tick.plan;
            let phase = plan.map_or("none", |p| PlanPhase::name_of(p.phase));
            let s = stats.entry(phase).or_default();
            s.ticks += 1;
            s.off_axis += off_axis;
            if let Some(plan) = plan {
                let n = (plan.finger_count as usize).min(MAX_FINGERS);
                for k in 0..n {
                    let target = &plan.targets[k];
                    if target.in_contact != 1 {
                        continue;
                    }
                    let Some(slot) = (0..truth.finger_count as usize)
                        .find(|&s| truth.finger_ids[s] == target.finger)
                    else {
                        continue;
                    };
                    if truth.in_contact[slot] == 0 {
                        s.lost += 1;
                        continue;
                    }
                    let (fn_, u) = pressing(truth, slot, mu);
                    s.slip = s.slip.max(truth.slip_speeds[slot]);
                    s.friction_use = s.friction_use.max(u);
                    if truth.slip_speeds[slot] > 0.01
                        && worst
                            .as_ref()
                            .is_none_or(|(w, _)| truth.slip_speeds[slot] > *w)
                    {
                        worst = Some((
                            truth.slip_speeds[slot],
                            format!(
                                "t {:.2} s, step {} {phase}, finger {}: slip {:.1} mm/s, f_n {:.2} N, use {:.2}",
                                tick.time,
                                plan.step,
                                target.finger,
                                truth.slip_speeds[slot] * 1e3,
                                fn_,
                                u
                            ),
                        ));
                    }
                }
            }
            if tick.time >= next_line {
                next_line += every;
                let c = tick.plant.sim().object_centre();
                let mut forces = String::new();
                for slot in 0..truth.finger_count as usize {
                    if truth.in_contact[slot] == 1 {
                        let (fn_, u) = pressing(truth, slot, mu);
                        // The commanded force's magnitude beside the true normal force.
                        let commanded = tick.command.and_then(|(c, _)| {
                            (0..c.finger_count as usize)
                                .find(|&k| c.finger_ids[k] == truth.finger_ids[slot])
                                .map(|k| c.forces[k].iter().map(|x| x * x).sum::<f64>().sqrt())
                        });
                        forces += &format!(
                            " {:.1}({:.1})/{:.2}/{:.0}",
                            fn_,
                            commanded.unwrap_or(f64::NAN),
                            u,
                            truth.slip_speeds[slot] * 1e3
                        );
                    } else {
                        forces += " -";
                    }
                }
                let mut errors = String::new();
                if let (Some((c, _)), Some(g)) = (tick.command, tick.grasp) {
                    for slot in 0..c.finger_count as usize {
                        let Some(f) = setup.hand.finger(c.finger_ids[slot]) else {
                            continue;
                        };
                        let n = f.dof();
                        let target = f.tip_centre(&c.joint_targets[slot][..n]);
                        let d = f.tip_centre(&g.joints[slot][..n]) - target;
                        let radial = (target - setup.object.centre_of_mass).normalize();
                        let along = d.dot(&radial);
                        errors += &format!(
                            " {:.2}/{:+.2}",
                            (d - radial * along).norm() * 1e3,
                            along * 1e3
                        );
                    }
                }
                // Each finger's contact candidate, estimated / planned ("-": none).
                let mut cands = String::new();
                if let (Some(g), Some(plan)) = (tick.grasp, plan) {
                    for slot in 0..g.finger_count as usize {
                        let e = &g.fingers[slot];
                        let planned = plan.targets[..(plan.finger_count as usize).min(MAX_FINGERS)]
                            .iter()
                            .find(|t| t.finger == e.finger && t.in_contact == 1);
                        let est = if e.in_contact == 1 {
                            e.candidate.to_string()
                        } else {
                            "-".into()
                        };
                        let pl = planned.map_or("-".into(), |t| t.candidate.to_string());
                        cands += &format!(" {est}/{pl}");
                    }
                }
                // Each finger's largest joint error from the plan step's target (deg).
                let mut joint_errors = String::new();
                if let (Some(g), Some(plan)) = (tick.grasp, plan) {
                    for slot in 0..g.finger_count as usize {
                        let finger = g.fingers[slot].finger;
                        let Some(t) = plan.targets[..(plan.finger_count as usize).min(MAX_FINGERS)]
                            .iter()
                            .find(|t| t.finger == finger)
                        else {
                            continue;
                        };
                        let n = t.joint_count as usize;
                        let e = (0..n).fold(0.0_f64, |m, j| {
                            m.max((t.joints[j] - g.joints[slot][j]).abs())
                        });
                        joint_errors += &format!(" {:.1}", e.to_degrees());
                    }
                }
                forces += &format!(
                    " | cand est/plan{cands} | tip across/along{errors} mm | joints off plan{joint_errors} deg | links on object {:#b} fingers touching {:#b} | tilt {:.2} deg",
                    tick.plant.sim().collisions().links_on_object,
                    tick.plant.sim().collisions().fingers_touching,
                    watch.tilt_deg
                );
                eprintln!(
                    "t {:5.2} s  true {:7.2} est {:7.2} plan {:7.2} deg  step {:4} {:8} fn/use/slip{forces}  centre [{:+.1} {:+.1} {:+.1}] mm{}",
                    tick.time,
                    truth.rotation.to_degrees(),
                    tick.grasp.map_or(f64::NAN, |g| g.rotation.to_degrees()),
                    plan.map_or(f64::NAN, |p| p.rotation.to_degrees()),
                    plan.map_or(0, |p| p.step),
                    phase,
                    c.x * 1e3,
                    c.y * 1e3,
                    c.z * 1e3,
                    tick.command
                        .and_then(|(c, why)| match why {
                            Some(w) => Some(format!("  HOLD {w}")),
                            None if c.mode == CommandMode::Attach as u32 => {
                                Some(format!("  ATTACH {}", read_text(&c.reason)))
                            }
                            None => None,
                        })
                        .unwrap_or_default()
                );
            }
        },
    )?;
    eprintln!(
        "ended after {:.2} s simulated ({:.1} s computed): done {}, true {:.2} deg, estimated {:.2} deg, {} holds, {} attach commands below the margin, {} replans{}",
        ended.time,
        started.elapsed().as_secs_f64(),
        ended.done,
        ended.rotation.to_degrees(),
        ended.estimated.to_degrees(),
        ended.holds,
        ended.attaches_below_margin,
        ended.replans,
        ended
            .holding
            .as_ref()
            .map(|w| format!(", holding: {w}"))
            .unwrap_or_default()
    );
    for (t, said) in &ended.replanned {
        eprintln!("  at {t:.2} s: {said}");
    }
    eprintln!(
        "  {} contacts lost while planned ({LOST_AFTER} truths off in a row)",
        watch.losses.len()
    );
    for l in &watch.losses {
        eprintln!("    lost: {l}");
    }
    eprintln!(
        "  contacts planned to roll, off for N ticks (1 ms) then back: {}",
        (1..gaps.len())
            .filter(|&k| gaps[k] > 0)
            .map(|k| format!(
                "{k}{}: {}",
                if k + 1 == gaps.len() { "+" } else { "" },
                gaps[k]
            ))
            .collect::<Vec<_>>()
            .join(", ")
    );
    let first = |t: Option<f64>| {
        t.map(|t| format!(" (first at {t:.2} s)"))
            .unwrap_or_default()
    };
    eprintln!(
        "  of {} integration steps: {} with fingers touching each other{}, {} with a link on the object{}",
        watch.integrated,
        watch.fingers_touching,
        first(watch.first_touching),
        watch.links_on_object,
        first(watch.first_link)
    );
    eprintln!(
        "  the object tilted off the plan's axis: at most {:.2} deg (at {:.2} s), {:.2} deg at the end",
        watch.max_tilt.0, watch.max_tilt.1, watch.tilt_deg
    );
    let w = watch.worst_estimate;
    eprintln!(
        "  the estimate off the truth: at most {:.2} deg (at {:.2} s, {}, true {:.1} deg); {} truths with a command tracked on an estimate more than {:.1} deg off",
        w.deg,
        w.time,
        w.phase,
        w.true_deg,
        watch.tracked_off,
        watch.bound_deg()
    );
    for (phase, s) in &stats {
        eprintln!(
            "  {phase:8} {:6} truths  max slip {:7.1} mm/s  max friction use {:.2}  lost {}  off the axis {:.2} deg",
            s.ticks,
            s.slip * 1e3,
            s.friction_use,
            s.lost,
            s.off_axis
        );
    }
    if let Some((_, w)) = worst {
        eprintln!("  worst slip: {w}");
    }
    Ok(())
}
