//! `icrflow-visualizer`: the pipeline's Rerun visualizer, started by `icrflow run` when
//! `[visualizer]` is enabled (see `icrflow_visualizer`); with `--plan CONFIG TRAJECTORY`,
//! `--recording TARGET --recording-id ID`, started by `icrflow plan --rrd ...`, it records a
//! written plan instead (`icrflow_visualizer::plan`); with `--render RRD --at END|STEP --out
//! PNG --size WxH --viewer RERUN`, started by `icrflow render`, it renders a recording
//! headless into a picture (`icrflow_visualizer::render`).

use std::path::Path;
use std::process::ExitCode;

use icrflow_runtime::launch::RecordingLaunch;

#[global_allocator]
static ALLOCATOR: &icrflow_runtime::health::CountingAllocator =
    &icrflow_runtime::health::COUNTING_ALLOCATOR;

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if let [flag, rest @ ..] = args.as_slice()
        && flag == "--render"
    {
        let rendered = icrflow_visualizer::render::Request::parse(rest)
            .and_then(|r| icrflow_visualizer::render::run(&r));
        return match rendered {
            Ok(()) => ExitCode::SUCCESS,
            Err(e) => {
                eprintln!("icrflow-visualizer: error: {e:#}");
                ExitCode::FAILURE
            }
        };
    }
    if let [flag, config, trajectory, recording @ ..] = args.as_slice()
        && flag == "--plan"
    {
        let recorded = RecordingLaunch::parse(recording)
            .map_err(anyhow::Error::from)
            .and_then(|r| {
                icrflow_visualizer::plan::run(Path::new(config), Path::new(trajectory), &r)
            });
        return match recorded {
            Ok(_) => ExitCode::SUCCESS,
            Err(e) => {
                eprintln!("icrflow-visualizer: error: {e:#}");
                ExitCode::FAILURE
            }
        };
    }
    icrflow_runtime::node::main(
        "visualizer",
        icrflow_scenario::Loaded::load,
        icrflow_visualizer::run,
    )
}
