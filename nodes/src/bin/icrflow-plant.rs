//! `icrflow-plant`: one of the pipeline's node processes, started by `icrflow run`
//! (see `icrflow_nodes::plant`).

fn main() -> std::process::ExitCode {
    icrflow_nodes::runtime::main("plant", icrflow_nodes::plant::run)
}
