//! `icrflow-plant`: one of the pipeline's node processes, started by `icrflow run`
//! (see `icrflow_nodes::plant`).

#[global_allocator]
static ALLOCATOR: &icrflow_nodes::runtime::CountingAllocator =
    &icrflow_nodes::runtime::COUNTING_ALLOCATOR;

fn main() -> std::process::ExitCode {
    icrflow_nodes::runtime::main("plant", icrflow_nodes::plant::run)
}
