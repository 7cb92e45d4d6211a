//! `icrflow-command`: one of the pipeline's node processes, started by `icrflow run`
//! (see `icrflow_nodes::command`).

#[global_allocator]
static ALLOCATOR: &icrflow_nodes::runtime::CountingAllocator =
    &icrflow_nodes::runtime::COUNTING_ALLOCATOR;

fn main() -> std::process::ExitCode {
    icrflow_nodes::runtime::main("command", icrflow_nodes::command::run)
}
