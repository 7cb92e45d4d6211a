//! `icrflow-wrench`: one of the pipeline's node processes, started by `icrflow run`
//! (see `icrflow_nodes::wrench`).

fn main() -> std::process::ExitCode {
    icrflow_nodes::runtime::main("wrench", icrflow_nodes::wrench::run)
}
