//! `icrflow-planner`: one of the pipeline's node processes, started by `icrflow run`
//! (see `icrflow_nodes::planner`).

#[global_allocator]
static ALLOCATOR: &icrflow_nodes::runtime::CountingAllocator =
    &icrflow_nodes::runtime::COUNTING_ALLOCATOR;

fn main() -> std::process::ExitCode {
    icrflow_nodes::runtime::main("planner", icrflow_nodes::planner::run)
}
