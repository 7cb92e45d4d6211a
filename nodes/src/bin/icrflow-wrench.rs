//! `icrflow-wrench`: one of the pipeline's node processes, started by `icrflow run`
//! (see `icrflow_nodes::wrench`).

#[global_allocator]
static ALLOCATOR: &icrflow_runtime::health::CountingAllocator =
    &icrflow_runtime::health::COUNTING_ALLOCATOR;

fn main() -> std::process::ExitCode {
    icrflow_nodes::main("wrench", icrflow_nodes::wrench::run)
}
