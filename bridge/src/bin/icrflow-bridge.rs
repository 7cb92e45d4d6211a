//! `icrflow-bridge`: the pipeline's Zenoh bridge, started by `icrflow run` when `[zenoh]` is
//! enabled (see `icrflow_bridge`).

fn main() -> std::process::ExitCode {
    icrflow_nodes::runtime::main("bridge", icrflow_bridge::run)
}
