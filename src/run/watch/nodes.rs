//! The node processes as the run sees them: their health reports (heartbeats, steady-state
//! allocations, the visualizer's frames, what the planner node does while it plans), their
//! memory and scheduling sampled from `/proc`, and what their silence means ([`silence`]).

use std::time::Instant;

use icrflow_interfaces::{NodeHealth, NodeState, read_text};
use icrflow_runtime::supervise::Supervisor;

use super::Watch;
use crate::run::measure::{resident_kib, scheduling};
use crate::run::status::say;
use crate::run::summary::Memory;
use crate::run::track::Silence;

impl Watch {
    /// Samples each process's scheduling policy and resident memory.
    pub(super) fn sample(&mut self, supervisor: &Supervisor) {
        for n in &self.names {
            if let Some(policy) = supervisor.pid(n).and_then(scheduling) {
                self.policies.insert(n.clone(), policy);
            }
            if let Some(kib) = supervisor.pid(n).and_then(resident_kib) {
                let m = self.memory.entry(n.clone()).or_insert(Memory {
                    first: kib,
                    ..Memory::default()
                });
                m.last = kib;
                m.max = m.max.max(kib);
                m.samples += 1;
            }
        }
    }

    /// Takes a node's health report, taken off the bus at `now`: its heartbeat, its
    /// allocations into its track, and the visualizer's frames recorded and dropped (per
    /// process).
    pub(super) fn take_health(&mut self, h: &NodeHealth, now: Instant) {
        let node = read_text(&h.node);
        if h.state == NodeState::Starting as u32 {
            // A node that says it starts up (the planner node planning) is not watched for
            // hangs until it runs; what it does is shown.
            if node == icrflow_interfaces::topics::NodeRole::Planner.name() {
                let doing = read_text(&h.message);
                if self.planning.is_none() {
                    say!("run: the planner node is {doing}");
                }
                self.planning = Some(doing);
            }
            return;
        }
        if node == icrflow_interfaces::topics::NodeRole::Planner.name() {
            self.planned = true;
        }
        self.beats.beat(&node, h.pid, now);
        if node == icrflow_interfaces::topics::NodeRole::Visualizer.name() {
            self.frames.insert(h.pid, (h.processed, h.refused));
        }
        self.tracks
            .entry(node)
            .or_default()
            .report(h.pid, h.allocations, h.processed, now);
    }
}

/// Says what a node's silence is, and kills a hung node (the supervisor restarts it).
pub(super) fn silence(s: &Silence, supervisor: &mut Supervisor, restart_s: f64) {
    match s {
        Silence::Silent { name, pid, since } => say!(
            "run: node {name} (pid {pid}) has sent no heartbeat for {:.1} s: hung or stopped? (restarted after {restart_s} s: pipeline.hung_restart_s)",
            since.as_secs_f64()
        ),
        Silence::Hung { name, pid, since } => {
            supervisor.kill(name);
            say!(
                "run: node {name} (pid {pid}) has sent no heartbeat for {:.1} s: killed, to be restarted",
                since.as_secs_f64()
            );
        }
        Silence::Back { name, after } => say!(
            "run: node {name} sends heartbeats again after {:.1} s",
            after.as_secs_f64()
        ),
    }
}
