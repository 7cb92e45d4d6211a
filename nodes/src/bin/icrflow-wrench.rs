//! `icrflow-wrench`: one of the pipeline's node processes, started by `icrflow run`
//! (see `icrflow_nodes::wrench`).

#[global_allocator]
static ALLOCATOR: &icrflow_nodes::runtime::CountingAllocator =
    &icrflow_nodes::runtime::COUNTING_ALLOCATOR;

fn main() -> std::process::ExitCode {
    icrflow_nodes::runtime::main("wrench", icrflow_nodes::wrench::run)
}
