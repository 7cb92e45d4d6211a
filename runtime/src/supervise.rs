//! Process supervision for `icrflow run` (issue #4): every node is its own OS process,
//! started with its [`Launch`] (the run's bus settings among it) as its arguments, restarted by its policy when it
//! exits (exponential backoff, at most `max_restarts` within `window`), with the run's dead
//! iceoryx2 nodes cleaned up before a restart; shutdown sends SIGTERM, then SIGKILL to what
//! is still running after the grace period.

use std::os::unix::process::CommandExt as _;
use std::path::PathBuf;
use std::process::{Child, Command, ExitStatus, Stdio};
use std::time::{Duration, Instant};

use iceoryx2::prelude::*;
use nix::sys::signal::{Signal, kill};
use nix::unistd::Pid;

use crate::bus::BusConfig;
use crate::launch::Launch;

/// When and how often a node is restarted.
#[derive(Debug, Clone, PartialEq)]
pub struct RestartPolicy {
    /// Restarts allowed within `window`; 0: never restart.
    pub max_restarts: u32,
    /// The sliding window the restarts are counted in.
    pub window: Duration,
    /// Delay before the first restart; doubled for each further restart in the window.
    pub backoff: Duration,
    /// Longest delay.
    pub max_backoff: Duration,
}

impl Default for RestartPolicy {
    fn default() -> Self {
        Self {
            max_restarts: 5,
            window: Duration::from_secs(30),
            backoff: Duration::from_millis(100),
            max_backoff: Duration::from_secs(2),
        }
    }
}

/// One node process.
#[derive(Debug, Clone, PartialEq)]
pub struct NodeSpec {
    /// Name (for messages).
    pub name: String,
    /// The executable.
    pub program: PathBuf,
    /// Its arguments (before the launch's).
    pub args: Vec<String>,
    /// What the node is started with, as arguments after `args` (`None`: a program that is
    /// not a node).
    pub launch: Option<Launch>,
    /// The restart policy.
    pub policy: RestartPolicy,
    /// Whether the run depends on it: a node that is not (the Zenoh bridge: monitoring) may
    /// fail for good without failing the run ([`Supervisor::failed`]).
    pub essential: bool,
}

/// Something the supervisor did or saw.
#[derive(Debug, Clone, PartialEq)]
pub enum Event {
    /// A node was started (`attempt` 0 the first time).
    Started {
        /// Node name.
        name: String,
        /// Process id.
        pid: u32,
        /// Restart number.
        attempt: u32,
    },
    /// A node exited.
    Exited {
        /// Node name.
        name: String,
        /// How.
        status: String,
        /// Dead iceoryx2 nodes whose resources were removed.
        cleaned: usize,
    },
    /// A node will not be restarted.
    GaveUp {
        /// Node name.
        name: String,
        /// Why.
        reason: String,
    },
}

/// Why supervision failed.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum SuperviseError {
    /// A node could not be started at all.
    #[error("cannot start node {name} ({program}): {reason}")]
    Spawn {
        /// Node name.
        name: String,
        /// The executable.
        program: String,
        /// Why.
        reason: String,
    },
}

struct Managed {
    spec: NodeSpec,
    child: Option<Child>,
    restarts: Vec<Instant>,
    total_restarts: u32,
    restart_at: Option<Instant>,
    given_up: bool,
    /// Started once (restarts are [`Supervisor::poll`]'s).
    launched: bool,
}

/// The supervisor of one run's node processes.
pub struct Supervisor {
    bus: BusConfig,
    nodes: Vec<Managed>,
    quiet: bool,
}

fn describe(status: ExitStatus) -> String {
    use std::os::unix::process::ExitStatusExt;
    match (status.code(), status.signal()) {
        (Some(c), _) => format!("exit code {c}"),
        (None, Some(s)) => match Signal::try_from(s) {
            Ok(sig) => format!("killed by {sig}"),
            Err(_) => format!("killed by signal {s}"),
        },
        _ => "unknown status".into(),
    }
}

/// Removes the resources of every dead iceoryx2 node of the run; returns how many.
pub fn cleanup_dead_nodes(bus: &BusConfig) -> usize {
    let Ok(cfg) = bus.iceoryx() else { return 0 };
    let mut cleaned = 0;
    let _ = Node::<ipc::Service>::list(&cfg, |state| {
        if let NodeState::Dead(view) = state
            && view.try_remove_stale_resources().is_ok()
        {
            cleaned += 1;
        }
        CallbackProgression::Continue
    });
    cleaned
}

/// How many of the run's iceoryx2 nodes are alive (in any process); `None` when they could
/// not be listed.
pub fn live_nodes(bus: &BusConfig) -> Option<usize> {
    let cfg = bus.iceoryx().ok()?;
    let mut alive = 0;
    Node::<ipc::Service>::list(&cfg, |state| {
        if let NodeState::Alive(_) = state {
            alive += 1;
        }
        CallbackProgression::Continue
    })
    .ok()?;
    Some(alive)
}

impl Supervisor {
    /// A supervisor for `nodes` on the run's bus. `quiet`: node output is discarded
    /// (otherwise it goes to this process's stderr).
    pub fn new(bus: BusConfig, nodes: Vec<NodeSpec>, quiet: bool) -> Self {
        Self {
            bus,
            nodes: nodes
                .into_iter()
                .map(|spec| Managed {
                    spec,
                    child: None,
                    restarts: Vec::new(),
                    total_restarts: 0,
                    restart_at: None,
                    given_up: false,
                    launched: false,
                })
                .collect(),
            quiet,
        }
    }

    fn spawn(&self, spec: &NodeSpec) -> Result<Child, SuperviseError> {
        let mut cmd = Command::new(&spec.program);
        cmd.args(&spec.args)
            .args(spec.launch.iter().flat_map(Launch::to_args))
            .stdin(Stdio::null())
            // A process group of its own: the terminal's signals (Ctrl-C, a hang-up) reach the
            // supervisor only, which stops its nodes in order (SIGTERM, then SIGKILL).
            .process_group(0);
        if self.quiet {
            cmd.stdout(Stdio::null()).stderr(Stdio::null());
        } else {
            cmd.stdout(Stdio::inherit()).stderr(Stdio::inherit());
        }
        cmd.spawn().map_err(|e| SuperviseError::Spawn {
            name: spec.name.clone(),
            program: spec.program.display().to_string(),
            reason: e.to_string(),
        })
    }

    /// Starts every node not started yet.
    pub fn start(&mut self) -> Result<Vec<Event>, SuperviseError> {
        self.start_where(|_| true)
    }

    /// Starts the node called `name` (if there is one, and it was not started yet): a node
    /// that must be listening before the others begin.
    pub fn start_first(&mut self, name: &str) -> Result<Vec<Event>, SuperviseError> {
        self.start_where(|spec| spec.name == name)
    }

    fn start_where(
        &mut self,
        pick: impl Fn(&NodeSpec) -> bool,
    ) -> Result<Vec<Event>, SuperviseError> {
        let mut events = Vec::new();
        for i in 0..self.nodes.len() {
            if self.nodes[i].launched || !pick(&self.nodes[i].spec) {
                continue;
            }
            let child = self.spawn(&self.nodes[i].spec)?;
            events.push(Event::Started {
                name: self.nodes[i].spec.name.clone(),
                pid: child.id(),
                attempt: 0,
            });
            self.nodes[i].child = Some(child);
            self.nodes[i].launched = true;
        }
        Ok(events)
    }

    /// Reaps exited nodes, cleans up after them, and restarts those whose backoff has passed.
    pub fn poll(&mut self, now: Instant) -> Result<Vec<Event>, SuperviseError> {
        let mut events = Vec::new();
        for i in 0..self.nodes.len() {
            let exited = match self.nodes[i].child.as_mut().map(|c| c.try_wait()) {
                Some(Ok(Some(status))) => Some(describe(status)),
                Some(Err(e)) => Some(format!("lost: {e}")),
                _ => None,
            };
            if let Some(status) = exited {
                let cleaned = cleanup_dead_nodes(&self.bus);
                let m = &mut self.nodes[i];
                m.child = None;
                events.push(Event::Exited {
                    name: m.spec.name.clone(),
                    status,
                    cleaned,
                });
                let p = &m.spec.policy;
                m.restarts.retain(|t| now.duration_since(*t) < p.window);
                if m.restarts.len() as u32 >= p.max_restarts {
                    m.given_up = true;
                    events.push(Event::GaveUp {
                        name: m.spec.name.clone(),
                        reason: format!(
                            "{} restarts within {:?} (the policy allows {})",
                            m.restarts.len(),
                            p.window,
                            p.max_restarts
                        ),
                    });
                } else {
                    let factor = 1u32 << m.restarts.len().min(16);
                    let delay = (p.backoff * factor).min(p.max_backoff);
                    m.restart_at = Some(now + delay);
                }
            }
            let due = self.nodes[i].restart_at.is_some_and(|t| now >= t);
            if due && !self.nodes[i].given_up {
                let child = self.spawn(&self.nodes[i].spec)?;
                let m = &mut self.nodes[i];
                m.restart_at = None;
                m.restarts.push(now);
                m.total_restarts += 1;
                events.push(Event::Started {
                    name: m.spec.name.clone(),
                    pid: child.id(),
                    attempt: m.total_restarts,
                });
                m.child = Some(child);
            }
        }
        Ok(events)
    }

    /// Kills node `name` (SIGKILL), e.g. one that hangs: [`Supervisor::poll`] then sees it
    /// exit and restarts it by its policy. Returns its pid if it was running.
    pub fn kill(&mut self, name: &str) -> Option<u32> {
        let m = self.nodes.iter_mut().find(|m| m.spec.name == name)?;
        let c = m.child.as_mut()?;
        let _ = c.kill();
        Some(c.id())
    }

    /// Total restarts of every node.
    pub fn restarts(&self) -> u32 {
        self.nodes.iter().map(|m| m.total_restarts).sum()
    }

    /// The process id of node `name`, if running.
    pub fn pid(&self, name: &str) -> Option<u32> {
        self.nodes
            .iter()
            .find(|m| m.spec.name == name)
            .and_then(|m| m.child.as_ref().map(Child::id))
    }

    /// Whether any node has been given up on.
    pub fn failed(&self) -> Option<&str> {
        self.nodes
            .iter()
            .find(|m| m.given_up && m.spec.essential)
            .map(|m| m.spec.name.as_str())
    }

    /// Stops every node: SIGTERM, up to `grace` for them to exit, then SIGKILL; reaps them and
    /// removes the run's dead iceoryx2 nodes. Returns the nodes that had to be killed.
    pub fn shutdown(&mut self, grace: Duration) -> Vec<String> {
        for m in &mut self.nodes {
            m.restart_at = None;
            if let Some(c) = &m.child {
                let _ = kill(Pid::from_raw(c.id() as i32), Signal::SIGTERM);
            }
        }
        let deadline = Instant::now() + grace;
        loop {
            let running = self.nodes.iter_mut().any(|m| match m.child.as_mut() {
                Some(c) => !matches!(c.try_wait(), Ok(Some(_))),
                None => false,
            });
            if !running || Instant::now() >= deadline {
                break;
            }
            std::thread::sleep(Duration::from_millis(10));
        }
        let mut killed = Vec::new();
        for m in &mut self.nodes {
            if let Some(mut c) = m.child.take() {
                if !matches!(c.try_wait(), Ok(Some(_))) {
                    let _ = c.kill();
                    killed.push(m.spec.name.clone());
                }
                let _ = c.wait();
            }
        }
        cleanup_dead_nodes(&self.bus);
        killed
    }
}

impl Drop for Supervisor {
    fn drop(&mut self) {
        // Never leave node processes behind, whatever happened.
        if self.nodes.iter().any(|m| m.child.is_some()) {
            self.shutdown(Duration::from_millis(500));
        }
    }
}
