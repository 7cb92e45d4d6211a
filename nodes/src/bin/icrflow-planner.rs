//! `icrflow-planner`: one of the pipeline's node processes, started by `icrflow run`
//! (see `icrflow_nodes::planner`).

fn main() -> std::process::ExitCode {
    icrflow_nodes::runtime::main("planner", icrflow_nodes::planner::run)
}
