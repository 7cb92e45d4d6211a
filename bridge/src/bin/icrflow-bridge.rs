//! `icrflow-bridge`: the pipeline's Zenoh bridge, started by `icrflow run` when `[zenoh]` is
//! enabled (see `icrflow_bridge`).

#[global_allocator]
static ALLOCATOR: &icrflow_runtime::health::CountingAllocator =
    &icrflow_runtime::health::COUNTING_ALLOCATOR;

fn main() -> std::process::ExitCode {
    icrflow_runtime::node::main(
        "bridge",
        icrflow_scenario::Config::load,
        icrflow_bridge::run,
    )
}
