//! `icrflow-bridge`: the pipeline's Zenoh bridge, started by `icrflow run` when `[zenoh]` is
//! enabled (see `icrflow_bridge`).

#[global_allocator]
static ALLOCATOR: &icrflow_nodes::runtime::CountingAllocator =
    &icrflow_nodes::runtime::COUNTING_ALLOCATOR;

fn main() -> std::process::ExitCode {
    icrflow_nodes::runtime::main("bridge", icrflow_bridge::run)
}
