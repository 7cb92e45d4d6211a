//! `icrflow monitor`: a live view of a running pipeline over Zenoh, from this or another
//! machine. It subscribes to the rig's monitoring key expressions (`icrflow/<rig>/**`, JSON,
//! see `icrflow_bridge::json`), and shows phase, rotation, quality against alpha, contacts,
//! node health and restarts, and latency: redrawn in place on a terminal, otherwise every
//! second as plain lines of at most [`PLAIN_WIDTH`] characters, each with the time (one per
//! part of the view). Objects that are not monitoring JSON of our schema are ignored, with an
//! error on stderr (once per key expression and reason).
//!
//! It waits for a run to appear at the endpoint (saying so), and warns when nothing arrives for
//! its rig while other rigs publish there (a wrong `--rig`), or nothing at all does. When every
//! node it has seen has gone silent, it says that the run ended (on stderr, once per run, and
//! in the view), and waits for the next.

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
/// The width of a plain line (not on a terminal), its time included; a longer part of the
/// view goes on over several lines.
const PLAIN_WIDTH: usize = 100;
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

    /// The latencies' p50 and p99 (the nearest rank, [`crate::percentile`]), from one sort.
    fn percentiles(&self) -> Option<(f64, f64)> {
        let mut v: Vec<f64> = self.latencies.iter().copied().collect();
        v.sort_by(f64::total_cmp);
        let at = |q: f64| crate::percentile::of_sorted(&v, q);
        at(0.5).zip(at(0.99))
    }

    /// How long since the last node reported, when every node seen has gone silent: the run
    /// ended (or the link to it is down); `None` while one reports, or before any did.
    fn ended(&self) -> Option<Duration> {
        self.health
            .values()
            .map(|seen| seen.when.elapsed())
            .min()
            .filter(|d| *d > SILENT)
    }

    /// The view as lines.
    fn lines(&self, rig: &str, endpoint: &str) -> Vec<String> {
        let mut out = vec![format!(
            "icrflow monitor  rig {rig}  via {endpoint}  ({} messages, {} ignored)",
            self.received, self.ignored
        )];
        let ended = self.ended();
        // Silence: the link, the bridge or the run is gone; what follows is the last state.
        match (self.last.map(|t| t.elapsed()), ended) {
            (Some(_), Some(d)) => out.push(format!(
                "RUN ENDED: no node has reported for {:.1} s{} (or the link to it is down); its last state follows",
                d.as_secs_f64(),
                if self.plan.as_ref().is_some_and(|p| p.phase == "done") {
                    ", its plan done"
                } else {
                    ""
                }
            )),
            (Some(d), None) if d > SILENT => out.push(format!(
                "NO DATA for {:.1} s: the last state received follows",
                d.as_secs_f64()
            )),
            (None, _) if self.others.is_empty() => {
                out.push(format!("waiting for data of rig {rig} (icrflow/{rig}/*)"))
            }
            (None, _) => out.push(format!(
                "waiting for data of rig {rig}; other rigs publish here: {} (--rig?)",
                self.others.keys().cloned().collect::<Vec<_>>().join(", ")
            )),
            (Some(_), None) => {}
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
            Some(c) if c.mode == "attach" => format!("command   ATTACH: {}", c.reason),
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
                let state = if ended.is_some() {
                    name.clone()
                } else if seen.when.elapsed() > SILENT {
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
            "nodes     {}{}",
            if ended.is_some() { "ended: " } else { "" },
            if nodes.is_empty() {
                "-".into()
            } else {
                nodes.join(", ")
            }
        ));
        out
    }

    /// The view as plain lines (not on a terminal), each beginning with `time` and at most
    /// [`PLAIN_WIDTH`] characters long (a longer part of the view is cut into several at its
    /// commas; a single word longer than that stays whole): one or more per part, the header
    /// left out.
    fn plain(&self, rig: &str, endpoint: &str, time: &str) -> Vec<String> {
        let width = PLAIN_WIDTH.saturating_sub(time.chars().count() + 1);
        let mut out = Vec::new();
        for line in self.lines(rig, endpoint).iter().skip(1) {
            // The parts' names are 10 characters wide: their continuations go under their text.
            let (name, text) = match line.split_at_checked(10) {
                Some((name, text)) if name.ends_with("  ") => (name, text),
                _ => ("", line.as_str()),
            };
            let room = width.saturating_sub(name.len());
            let parts = crate::wrap::wrap_at(text, ", ", room)
                .into_iter()
                .flat_map(|part| crate::wrap::wrap(&part, room));
            for (i, part) in parts.enumerate() {
                let lead = if i == 0 { name } else { "          " };
                out.push(format!("{time} {}{part}", &lead[..name.len()]));
            }
        }
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
    // Whether the run's end was said (again once nodes report anew: the next run).
    let mut said_ended = false;
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
        match view.ended() {
            Some(d) if !said_ended => {
                said_ended = true;
                eprintln!(
                    "monitor: the run has ended: no node of rig {rig:?} has reported for {:.1} s; waiting for the next (Ctrl-C to stop)",
                    d.as_secs_f64()
                );
            }
            None if said_ended && view.health.values().any(|s| s.when.elapsed() <= SILENT) => {
                said_ended = false;
            }
            _ => {}
        }
        if now >= next {
            next += every;
            if terminal {
                let lines = view.lines(rig, endpoint);
                // Home, then each line cleared to its end, then the rest of the screen.
                write!(out, "\x1b[H")?;
                for l in &lines {
                    write!(out, "{l}\x1b[K\r\n")?;
                }
                write!(out, "\x1b[J")?;
            } else {
                let time = format!("{:.1}s", started.elapsed().as_secs_f64());
                for l in view.plain(rig, endpoint, &time) {
                    writeln!(out, "{l}")?;
                }
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

#[cfg(test)]
mod tests {
    use super::*;

    /// A health report of `node` (process `pid`) as the bridge publishes it.
    fn health(node: &str, pid: u32) -> Vec<u8> {
        serde_json::json!({
            "schema": 1, "topic": "node_health", "rig": "sim", "sequence": 1, "time_ns": 1,
            "origin_ns": 0, "node": node, "state": "running", "pid": pid, "processed": 5,
            "refused": 0, "message": ""
        })
        .to_string()
        .into_bytes()
    }

    #[test]
    fn plain_lines_are_short_and_the_end_of_the_run_is_said() {
        let mut view = View::default();
        let nodes = [
            "bridge",
            "command",
            "estimator",
            "planner",
            "plant",
            "visualizer",
            "wrench",
        ];
        for (pid, node) in (100..).zip(nodes) {
            view.take("node_health", &health(node, pid)).unwrap();
        }
        let plain = view.plain("sim", "tcp/127.0.0.1:7447", "12.0s");
        assert!(
            plain
                .iter()
                .all(|l| l.starts_with("12.0s ") && l.chars().count() <= PLAIN_WIDTH),
            "{plain:#?}"
        );
        // Every node on the nodes' lines, which go on under their text.
        let text = plain.join("\n");
        for node in nodes {
            assert!(text.contains(&format!("{node} running")), "{text}");
        }
        assert!(text.contains("12.0s nodes     bridge running"), "{text}");
        assert!(text.contains("12.0s           "), "{text}");
        assert_eq!(view.ended(), None);
        assert!(!text.contains("ENDED"), "{text}");
        // Every node silent after it was seen: the run ended, said once, not node by node.
        for seen in view.health.values_mut() {
            seen.when -= SILENT + Duration::from_millis(500);
        }
        view.last = view.last.map(|t| t - SILENT - Duration::from_millis(500));
        assert!(view.ended().is_some_and(|d| d > SILENT));
        let lines = view.lines("sim", "tcp/127.0.0.1:7447");
        assert!(
            lines[1].starts_with("RUN ENDED: no node has reported for 1.5 s (or"),
            "{lines:#?}"
        );
        // With the plan's last step `done`: said.
        let done = serde_json::json!({
            "schema": 1, "topic": "plan_step", "rig": "sim", "sequence": 9, "time_ns": 1,
            "origin_ns": 0, "phase": "done", "step": 72, "rotation": 1.0, "rotation_deg": 57.3,
            "quality": 0.2, "targets": []
        });
        view.take("plan_step", done.to_string().as_bytes()).unwrap();
        let lines = view.lines("sim", "tcp/127.0.0.1:7447");
        assert!(
            lines[1].contains("reported for 1.5 s, its plan done (or the link"),
            "{lines:#?}"
        );
        assert!(lines.iter().all(|l| !l.contains("SILENT")), "{lines:#?}");
        assert!(
            lines
                .last()
                .unwrap()
                .starts_with("nodes     ended: bridge, command"),
            "{lines:#?}"
        );
        let plain = view.plain("sim", "tcp/127.0.0.1:7447", "12.0s");
        assert!(
            plain.iter().all(|l| l.chars().count() <= PLAIN_WIDTH),
            "{plain:#?}"
        );
        // One node silent while the others report: that node is SILENT, the run goes on.
        view.take("node_health", &health("plant", 104)).unwrap();
        assert_eq!(view.ended(), None);
        let lines = view.lines("sim", "tcp/127.0.0.1:7447").join("\n");
        assert!(
            lines.contains("bridge SILENT") && lines.contains("plant running"),
            "{lines}"
        );
    }
}
