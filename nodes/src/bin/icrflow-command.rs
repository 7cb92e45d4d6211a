//! `icrflow-command`: one of the pipeline's node processes, started by `icrflow run`
//! (see `icrflow_nodes::command`).

fn main() -> std::process::ExitCode {
    icrflow_nodes::runtime::main("command", icrflow_nodes::command::run)
}
