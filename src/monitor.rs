//! `icrflow monitor`: a live view of a running pipeline over Zenoh, from this or another
//! machine. It subscribes to the rig's monitoring key expressions (`icrflow/<rig>/**`, JSON,
//! see `icrflow_bridge::json`), and shows phase, rotation, quality against alpha, contacts,
//! node health and latency: redrawn in place on a terminal, one plain line per second
//! otherwise. Objects that are not monitoring JSON of our schema are ignored, with an error
//! on stderr (once per key expression and reason).

use std::collections::{BTreeMap, BTreeSet};
use std::io::{IsTerminal, Write};
use std::time::{Duration, Instant};

use anyhow::{Result, anyhow};
use icrflow_bridge::json::{
    GraspStateJson, HandCommandJson, NodeHealthJson, PlanStepJson, WrenchSpaceJson, envelope,
};
use icrflow_bridge::zenoh::Wait;

/// The environment variable `--user`'s password is read from (never from the command line,
/// where other users of the machine could read it).
pub use icrflow_scenario::PASSWORD_ENV;
/// How often the view is redrawn on a terminal.
const REFRESH: Duration = Duration::from_millis(200);
/// How often a plain line is printed when not on a terminal.
const LINE: Duration = Duration::from_secs(1);
/// A node whose last health report is older than this is shown as silent.
const SILENT: Duration = Duration::from_secs(1);
/// Latencies kept for the percentiles.
const WINDOW: usize = 1000;

/// What the monitor knows of the pipeline.
#[derive(Default)]
struct View {
    plan: Option<PlanStepJson>,
    grasp: Option<GraspStateJson>,
    wrench: Option<WrenchSpaceJson>,
    command: Option<HandCommandJson>,
    health: BTreeMap<String, (NodeHealthJson, Instant)>,
    latencies: std::collections::VecDeque<f64>,
    received: u64,
    ignored: u64,
    /// When the last message came.
    last: Option<Instant>,
}

impl View {
    fn take(&mut self, topic: &str, bytes: &[u8]) -> Result<(), String> {
        let parse = |e: serde_json::Error| format!("{topic}: {e}");
        match topic {
            "plan_step" => self.plan = Some(serde_json::from_slice(bytes).map_err(parse)?),
            "grasp_state" => self.grasp = Some(serde_json::from_slice(bytes).map_err(parse)?),
            "wrench_space" => self.wrench = Some(serde_json::from_slice(bytes).map_err(parse)?),
            "hand_command" => {
                let c: HandCommandJson = serde_json::from_slice(bytes).map_err(parse)?;
                if c.latency_us > 0.0 {
                    if self.latencies.len() == WINDOW {
                        self.latencies.pop_front();
                    }
                    self.latencies.push_back(c.latency_us);
                }
                self.command = Some(c);
            }
            "node_health" => {
                let h: NodeHealthJson = serde_json::from_slice(bytes).map_err(parse)?;
                self.health.insert(h.node.clone(), (h, Instant::now()));
            }
            _ => {}
        }
        self.received += 1;
        self.last = Some(Instant::now());
        Ok(())
    }

    /// The latencies' p50 and p99, from one sort.
    fn percentiles(&self) -> Option<(f64, f64)> {
        let mut v: Vec<f64> = self.latencies.iter().copied().collect();
        if v.is_empty() {
            return None;
        }
        v.sort_by(f64::total_cmp);
        let at = |q: f64| v[((v.len() - 1) as f64 * q).round() as usize];
        Some((at(0.5), at(0.99)))
    }

    /// The view as lines.
    fn lines(&self, rig: &str, endpoint: &str) -> Vec<String> {
        let mut out = vec![format!(
            "icrflow monitor  rig {rig}  via {endpoint}  ({} messages, {} ignored)",
            self.received, self.ignored
        )];
        // Silence: the link, the bridge or the run is gone; what follows is the last state.
        match self.last.map(|t| t.elapsed()) {
            Some(d) if d > SILENT => out.push(format!(
                "NO DATA for {:.1} s: the last state received follows",
                d.as_secs_f64()
            )),
            None => out.push("waiting for data".into()),
            Some(_) => {}
        }
        out.push(match &self.plan {
            Some(p) => format!(
                "phase     {} (step {}), target {:.1} deg",
                p.phase, p.step, p.rotation_deg
            ),
            None => "phase     (no plan step yet)".into(),
        });
        out.push(match &self.grasp {
            Some(g) => format!("rotation  {:.1} deg", g.rotation_deg),
            None => "rotation  (no grasp state yet)".into(),
        });
        out.push(match &self.wrench {
            Some(w) => format!(
                "quality   alpha* {:.4} vs alpha {} ({}){}",
                w.quality,
                w.alpha,
                if w.quality >= w.alpha { "ok" } else { "BELOW" },
                if w.force_closure {
                    ""
                } else {
                    ", not force closure"
                }
            ),
            None => "quality   (no wrench space yet)".into(),
        });
        out.push(match &self.grasp {
            Some(g) => {
                let c: Vec<String> = g
                    .contacts
                    .iter()
                    .map(|c| {
                        if c.in_contact {
                            format!("{}@{}", c.finger, c.candidate)
                        } else {
                            format!("{} free", c.finger)
                        }
                    })
                    .collect();
                format!("contacts  {}", c.join("  "))
            }
            None => "contacts  -".into(),
        });
        out.push(match &self.command {
            Some(c) if c.mode == "hold" => format!("command   HOLD: {}", c.reason),
            Some(_) => "command   tracking".into(),
            None => "command   (none yet)".into(),
        });
        out.push(match self.percentiles() {
            Some((p50, p99)) => format!(
                "latency   measurement to command p50 {p50:.0} us, p99 {p99:.0} us (last {})",
                self.latencies.len()
            ),
            None => "latency   -".into(),
        });
        let nodes: Vec<String> = self
            .health
            .iter()
            .map(|(name, (h, when))| {
                if when.elapsed() > SILENT {
                    format!("{name} SILENT")
                } else if h.state == "degraded" {
                    format!("{name} degraded ({})", h.message)
                } else {
                    format!("{name} {}", h.state)
                }
            })
            .collect();
        out.push(format!(
            "nodes     {}",
            if nodes.is_empty() {
                "-".into()
            } else {
                nodes.join(", ")
            }
        ));
        out
    }
}

/// Runs the monitor until Ctrl-C, or for `seconds` if given.
pub fn run(endpoint: &str, rig: &str, user: Option<&str>, seconds: Option<f64>) -> Result<u8> {
    let password = match user {
        None => None,
        Some(u) => Some(std::env::var(PASSWORD_ENV).map_err(|_| {
            anyhow!("--user {u}: set the password in the environment variable {PASSWORD_ENV}")
        })?),
    };
    let login = user.zip(password.as_deref());
    let session = icrflow_bridge::open(
        icrflow_bridge::client_config(endpoint, login)?,
        &format!("connect {endpoint}"),
    )?;
    // The monitoring topics (one chunk each; a split pipeline's `link/` topics are not JSON).
    let keys = icrflow_interfaces::topics::service(rig, "*");
    let subscriber = session
        .declare_subscriber(&keys)
        .wait()
        .map_err(|e| anyhow!("subscribing to {keys}: {e}"))?;
    let terminal = std::io::stdout().is_terminal();
    let every = if terminal { REFRESH } else { LINE };
    let started = Instant::now();
    let end = seconds.map(|s| started + Duration::from_secs_f64(s.max(0.0)));
    let mut view = View::default();
    let mut reported = BTreeSet::new();
    let mut next = Instant::now() + every;
    let mut out = std::io::stdout().lock();
    loop {
        let now = Instant::now();
        if end.is_some_and(|e| now >= e) {
            break;
        }
        if now >= next {
            next += every;
            let lines = view.lines(rig, endpoint);
            if terminal {
                // Home, then each line cleared to its end, then the rest of the screen.
                write!(out, "\x1b[H")?;
                for l in &lines {
                    write!(out, "{l}\x1b[K\r\n")?;
                }
                write!(out, "\x1b[J")?;
            } else {
                writeln!(
                    out,
                    "{:.1}s {}",
                    started.elapsed().as_secs_f64(),
                    lines[1..].join(" | ")
                )?;
            }
            out.flush()?;
        }
        let wait = next.saturating_duration_since(Instant::now());
        let Some(sample) = subscriber
            .recv_timeout(wait)
            .map_err(|e| anyhow!("zenoh subscriber: {e}"))?
        else {
            continue;
        };
        let key = sample.key_expr().as_str().to_string();
        let bytes = sample.payload().to_bytes();
        let topic = key.rsplit('/').next().unwrap_or("");
        let checked = envelope(&bytes)
            .map_err(|e| e.to_string())
            .and_then(|_| view.take(topic, &bytes));
        if let Err(why) = checked {
            view.ignored += 1;
            // Said once per key and reason (at most a hundred of them).
            if reported.len() < 100 && reported.insert((key.clone(), why.clone())) {
                eprintln!("monitor: ignored a message on {key}: {why}");
            }
        }
    }
    Ok(0)
}
