//! `icrflow-planner`: one of the pipeline's node processes, started by `icrflow run`
//! (see `icrflow_nodes::planner`).

#[global_allocator]
static ALLOCATOR: &icrflow_runtime::health::CountingAllocator =
    &icrflow_runtime::health::COUNTING_ALLOCATOR;

fn main() -> std::process::ExitCode {
    icrflow_nodes::main_static("planner", icrflow_nodes::planner::run)
}
