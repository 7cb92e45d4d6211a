//! `icrflow monitor`: a live view of a running pipeline over Zenoh, from this or another
//! machine. It subscribes to the rig's monitoring key expressions (`icrflow/<rig>/**`, JSON,
//! see `icrflow_bridge::json`), and shows phase, rotation, quality against alpha, contacts,
//! node health and restarts, and latency: redrawn in place on a terminal, one plain line per
//! second otherwise. Objects that are not monitoring JSON of our schema are ignored, with an
//! error on stderr (once per key expression and reason).
//!
//! It waits for a run to appear at the endpoint (saying so), and warns when nothing arrives for
//! its rig while other rigs publish there (a wrong `--rig`), or nothing at all does.

use std::collections::{BTreeMap, BTreeSet};
use std::io::{IsTerminal, Write};
use std::time::{Duration, Instant};

use anyhow::{Context as _, Result, anyhow};
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
/// How long the monitor waits for its rig's first message before it warns.
const RIG_WARN: Duration = Duration::from_secs(3);
/// How often it tries again to reach an endpoint where no run answers yet.
const RETRY: Duration = Duration::from_secs(1);

/// A node's last health report, when it came, and its restarts (new processes) seen.
struct NodeSeen {
    health: NodeHealthJson,
    when: Instant,
    restarts: u32,
    /// When the last restart was seen.
    restarted: Option<Instant>,
}

/// What the monitor knows of the pipeline.
#[derive(Default)]
struct View {
    plan: Option<PlanStepJson>,
    grasp: Option<GraspStateJson>,
    wrench: Option<WrenchSpaceJson>,
    command: Option<HandCommandJson>,
    health: BTreeMap<String, NodeSeen>,
    /// Messages for other rigs than the one watched, by rig.
    others: BTreeMap<String, u64>,
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
                let now = Instant::now();
                match self.health.get_mut(&h.node) {
                    Some(seen) => {
                        // A new process of the node: the supervisor restarted it.
                        if seen.health.pid != h.pid {
                            seen.restarts += 1;
                            seen.restarted = Some(now);
                        }
                        seen.health = h;
                        seen.when = now;
                    }
                    None => {
                        self.health.insert(
                            h.node.clone(),
                            NodeSeen {
                                health: h,
                                when: now,
                                restarts: 0,
                                restarted: None,
                            },
                        );
                    }
                }
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
            None if self.others.is_empty() => {
                out.push(format!("waiting for data of rig {rig} (icrflow/{rig}/*)"))
            }
            None => out.push(format!(
                "waiting for data of rig {rig}; other rigs publish here: {} (--rig?)",
                self.others.keys().cloned().collect::<Vec<_>>().join(", ")
            )),
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
        // Planar (a 3D wrench space) or before the first wrench space: where the contact
        // lies on the object as an angle about its origin in the hand's plane; spatial: the
        // point, in mm (body frame both).
        let planar = self.wrench.as_ref().is_none_or(|w| w.dim <= 3);
        out.push(match &self.grasp {
            Some(g) => {
                let c: Vec<String> = g
                    .contacts
                    .iter()
                    .map(|c| {
                        let [x, y, z] = c.point;
                        if !c.in_contact {
                            format!("finger {} free", c.finger)
                        } else if planar {
                            format!(
                                "finger {} at {:.1} deg",
                                c.finger,
                                y.atan2(x).to_degrees().rem_euclid(360.0)
                            )
                        } else {
                            format!(
                                "finger {} at ({:.1}, {:.1}, {:.1}) mm",
                                c.finger,
                                1e3 * x,
                                1e3 * y,
                                1e3 * z
                            )
                        }
                    })
                    .collect();
                format!(
                    "contacts  {} ({}, object frame)",
                    c.join(", "),
                    if planar {
                        "angle about the object's origin"
                    } else {
                        "contact point"
                    }
                )
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
            .map(|(name, seen)| {
                let h = &seen.health;
                let state = if seen.when.elapsed() > SILENT {
                    format!("{name} SILENT {:.0} s", seen.when.elapsed().as_secs_f64())
                } else if h.state == "degraded" || (h.state == "starting" && !h.message.is_empty())
                {
                    format!("{name} {} ({})", h.state, h.message)
                } else {
                    format!("{name} {}", h.state)
                };
                match (seen.restarts, seen.restarted) {
                    (0, _) | (_, None) => state,
                    (n, Some(t)) => format!(
                        "{state} (restarted {n}x, last {:.0} s ago)",
                        t.elapsed().as_secs_f64()
                    ),
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

/// Runs the monitor until Ctrl-C, or for `seconds` if given; returns the exit status
/// ([`crate::exit::INCOMPLETE`] if nothing came for the rig).
pub fn run(endpoint: &str, rig: &str, user: Option<&str>, seconds: Option<f64>) -> Result<u8> {
    icrflow_scenario::check_endpoint("--connect", endpoint)?;
    let password = match user {
        None => None,
        Some(u) => Some(std::env::var(PASSWORD_ENV).map_err(|_| {
            anyhow!("--user {u}: set the password in the environment variable {PASSWORD_ENV}")
        })?),
    };
    let login = user.zip(password.as_deref());
    let started = Instant::now();
    let end = seconds.map(|s| started + Duration::from_secs_f64(s.max(0.0)));
    let config = || {
        icrflow_bridge::client_config(endpoint, login)
            .with_context(|| format!("--connect {endpoint}"))
    };
    // Until a run's bridge answers at the endpoint: waited for, said once.
    let mut waiting = false;
    let session = loop {
        match icrflow_bridge::open(config()?, &format!("connect {endpoint}")) {
            Ok(s) => break s,
            Err(e) => {
                if !waiting {
                    waiting = true;
                    eprintln!(
                        "monitor: no run answers at {endpoint} yet ({e:#}){}; waiting for one (Ctrl-C to stop)",
                        if user.is_some() {
                            ", or it refused the login"
                        } else {
                            ""
                        }
                    );
                }
                let now = Instant::now();
                if end.is_some_and(|e| now >= e) {
                    eprintln!(
                        "monitor: no run appeared at {endpoint} in {:.1} s",
                        now.duration_since(started).as_secs_f64()
                    );
                    return Ok(crate::exit::INCOMPLETE);
                }
                let rest = end.map_or(RETRY, |e| e.saturating_duration_since(now));
                std::thread::sleep(RETRY.min(rest));
            }
        }
    };
    let connected = Instant::now();
    if waiting {
        eprintln!(
            "monitor: connected to {endpoint} after {:.1} s",
            connected.duration_since(started).as_secs_f64()
        );
    }
    // Every rig's monitoring topics (one chunk each; a split pipeline's `link/` topics are not
    // JSON), so that a wrong --rig is said: only `rig`'s are shown.
    let keys = icrflow_interfaces::topics::service("*", "*");
    let subscriber = session
        .declare_subscriber(&keys)
        .wait()
        .map_err(|e| anyhow!("subscribing to {keys}: {}", icrflow_bridge::words(&e)))?;
    let terminal = std::io::stdout().is_terminal();
    let every = if terminal { REFRESH } else { LINE };
    let mut view = View::default();
    let mut reported = BTreeSet::new();
    let mut warned = false;
    let mut next = Instant::now() + every;
    let mut out = std::io::stdout().lock();
    loop {
        let now = Instant::now();
        if end.is_some_and(|e| now >= e) {
            break;
        }
        if !warned && view.received == 0 && now.duration_since(connected) >= RIG_WARN {
            warned = true;
            if view.others.is_empty() {
                eprintln!(
                    "monitor: connected to {endpoint}, but nothing has arrived in {} s, for rig {rig:?} or any other: is a run up there with zenoh.enabled, and is its run past its start-up?",
                    RIG_WARN.as_secs()
                );
            } else {
                let others: Vec<&str> = view.others.keys().map(String::as_str).collect();
                eprintln!(
                    "monitor: nothing has arrived for rig {rig:?} in {} s, but rig(s) {} publish at {endpoint}: --rig {}? (pipeline.rig of the run's config)",
                    RIG_WARN.as_secs(),
                    others.join(", "),
                    others[0]
                );
            }
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
            .map_err(|e| anyhow!("zenoh subscriber: {}", icrflow_bridge::words(&e)))?
        else {
            continue;
        };
        let key = sample.key_expr().as_str().to_string();
        // icrflow/<rig>/<topic>
        let mut parts = key.split('/').skip(1);
        let (of, topic) = (parts.next().unwrap_or(""), parts.next().unwrap_or(""));
        if of != rig {
            *view.others.entry(of.to_string()).or_default() += 1;
            continue;
        }
        let bytes = sample.payload().to_bytes();
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
    if view.received == 0 {
        eprintln!("monitor: nothing arrived for rig {rig:?} at {endpoint}");
        return Ok(crate::exit::INCOMPLETE);
    }
    Ok(crate::exit::DONE)
}
