//! # icrflow-nodes: the pipeline's loop nodes
//!
//! The processes of the loop, each a module with its `run` (what its `icrflow-<name>` binary
//! runs) on the plumbing of `icrflow-runtime`: the simulated [`plant`] (our kinematic model, or MuJoCo: [`physical`]), the state
//! [`estimator`], the [`wrench`]-space node, the ICR [`planner`] node that follows the plan, and
//! the hand [`command`] node with its [`safety`] gate. The rolling kinematics they share are
//! the planner crate's (`icrflow_plan::rolling`).

#![warn(missing_docs)]

pub mod command;
pub mod estimator;
pub mod lockstep;
pub mod noise;
pub mod physical;
pub mod planner;
pub mod plant;
pub mod safety;
pub mod wrench;

/// A loop node's context: its config loaded with what it builds, and its bus.
pub type Context = icrflow_runtime::node::Context<icrflow_scenario::Loaded>;

/// Runs loop node `name` ([`icrflow_runtime::node::main`], loading the config with its setup).
pub fn main(
    name: &'static str,
    body: fn(&Context) -> anyhow::Result<()>,
) -> std::process::ExitCode {
    icrflow_runtime::node::main(name, icrflow_scenario::Loaded::load, body)
}

/// The context of a loop node whose threads outlive the loop's borrows (the planner node's
/// worker): its config and setup loaded once and kept for the life of the process.
pub type StaticContext = icrflow_runtime::node::Context<&'static icrflow_scenario::Loaded>;

/// Runs loop node `name` as [`main`] does, its config and setup kept for the life of the
/// process ([`StaticContext`]).
pub fn main_static(
    name: &'static str,
    body: fn(&StaticContext) -> anyhow::Result<()>,
) -> std::process::ExitCode {
    icrflow_runtime::node::main(
        name,
        |path| {
            let loaded = icrflow_scenario::Loaded::load(path)?;
            Ok(&*Box::leak(Box::new(loaded)))
        },
        body,
    )
}

/// What the steps' unit tests share.
#[cfg(test)]
mod testing {
    use icrflow_scenario::{Config, Setup};

    /// The paper scenario's config (`config/paper_sphere.toml`) and what it builds.
    pub fn paper() -> (Config, Setup) {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../config");
        let config = Config::load(&dir.join("paper_sphere.toml")).unwrap();
        let setup = Setup::new(&config).unwrap();
        (config, setup)
    }

    /// A tracking command made at `at` of `joints` for the fingers `fingers` (slots), pressing
    /// on the object where `pressing`.
    pub fn command(
        setup: &Setup,
        fingers: &[usize],
        joints: &[Vec<f64>],
        pressing: bool,
        at: u64,
    ) -> icrflow_interfaces::HandCommand {
        let mut c = icrflow_interfaces::HandCommand {
            header: icrflow_interfaces::Header::new(icrflow_interfaces::Kind::HandCommand, 1, 0, 0),
            mode: icrflow_interfaces::CommandMode::Track as u32,
            finger_count: fingers.len() as u32,
            ..Default::default()
        };
        c.header.source_time_ns = at;
        for (k, &slot) in fingers.iter().enumerate() {
            c.finger_ids[k] = setup.hand.fingers[slot].id;
            c.joint_targets[k][..joints[slot].len()].copy_from_slice(&joints[slot]);
            if pressing {
                c.forces[k] = [0.0, 1.0, 0.0];
            }
        }
        c
    }

    /// The hand's joints (every finger, in the hand's order) at the start of `setup`'s
    /// spatial plan and after each of its first `steps` rolling steps of 1 degree, and the
    /// slots of the fingers in contact.
    pub fn spatial_rolling(
        config: &Config,
        setup: &Setup,
        steps: usize,
    ) -> (Vec<Vec<Vec<f64>>>, Vec<usize>) {
        let scenario = setup.spatial_scenario(config).unwrap();
        let (mut hand, _) = setup.initial_grip(config).unwrap();
        let (mut touches, _) = scenario.start().unwrap();
        let slots: Vec<usize> = touches
            .iter()
            .map(|t| {
                setup
                    .hand
                    .fingers
                    .iter()
                    .position(|f| f.id == t.finger)
                    .unwrap()
            })
            .collect();
        let mut out = vec![hand.clone()];
        for k in 0..steps {
            let step = 1f64.to_radians();
            let icrflow_plan::spatial::Roll::Moved(next, _) =
                scenario.roll(&touches, k as f64 * step, step).unwrap()
            else {
                panic!("the plan's first steps roll");
            };
            touches = next;
            for (t, &slot) in touches.iter().zip(&slots) {
                hand[slot] = t.q.clone();
            }
            out.push(hand.clone());
        }
        (out, slots)
    }

    /// The Allegro hand's sphere (`config/allegro_sphere.toml`): a spatial hand.
    pub fn allegro_sphere() -> (Config, Setup) {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../config");
        let config = Config::load(&dir.join("allegro_sphere.toml")).unwrap();
        let setup = Setup::new(&config).unwrap();
        (config, setup)
    }
}
