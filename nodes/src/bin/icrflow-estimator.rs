//! `icrflow-estimator`: one of the pipeline's node processes, started by `icrflow run`
//! (see `icrflow_nodes::estimator`).

#[global_allocator]
static ALLOCATOR: &icrflow_nodes::runtime::CountingAllocator =
    &icrflow_nodes::runtime::COUNTING_ALLOCATOR;

fn main() -> std::process::ExitCode {
    icrflow_nodes::runtime::main("estimator", icrflow_nodes::estimator::run)
}
