//! `icrflow-visualizer`: the pipeline's Rerun visualizer, started by `icrflow run` when
//! `[visualizer]` is enabled (see `icrflow_visualizer`).

#[global_allocator]
static ALLOCATOR: &icrflow_nodes::runtime::CountingAllocator =
    &icrflow_nodes::runtime::COUNTING_ALLOCATOR;

fn main() -> std::process::ExitCode {
    icrflow_nodes::runtime::main("visualizer", icrflow_visualizer::run)
}
