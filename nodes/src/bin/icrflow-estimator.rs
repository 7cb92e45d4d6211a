//! `icrflow-estimator`: one of the pipeline's node processes, started by `icrflow run`
//! (see `icrflow_nodes::estimator`).

fn main() -> std::process::ExitCode {
    icrflow_nodes::runtime::main("estimator", icrflow_nodes::estimator::run)
}
