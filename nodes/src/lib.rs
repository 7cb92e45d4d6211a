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

    /// The Allegro hand's sphere (`config/allegro_sphere.toml`): a spatial hand.
    pub fn allegro_sphere() -> (Config, Setup) {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../config");
        let config = Config::load(&dir.join("allegro_sphere.toml")).unwrap();
        let setup = Setup::new(&config).unwrap();
        (config, setup)
    }
}
