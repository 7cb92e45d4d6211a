//! `icrflow-visualizer`: the pipeline's Rerun visualizer, started by `icrflow run` when
//! `[visualizer]` is enabled, with a node's arguments (`icrflow_runtime::launch::LaunchArgs`;
//! see `icrflow_visualizer`); with `--plan CONFIG TRAJECTORY --recording TARGET
//! --recording-id ID`, started by `icrflow plan --rrd ...`, it records a written plan instead
//! (`icrflow_visualizer::plan`); with `--render RRD --at END|STEP --out PNG --size WxH
//! --viewer RERUN`, started by `icrflow render`, it renders a recording headless into a
//! picture (`icrflow_visualizer::render`). One clap command line for the three modes.

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Parser, Subcommand};
use icrflow_runtime::launch::{Launch, LaunchArgs, RecordingArgs, RecordingLaunch};

#[global_allocator]
static ALLOCATOR: &icrflow_runtime::health::CountingAllocator =
    &icrflow_runtime::health::COUNTING_ALLOCATOR;

/// The visualizer's command line: a node's arguments, or one of its two modes.
#[derive(Debug, Parser)]
#[command(
    name = "icrflow-visualizer",
    args_conflicts_with_subcommands = true,
    subcommand_negates_reqs = true
)]
struct Cli {
    #[command(subcommand)]
    mode: Option<Mode>,
    #[command(flatten)]
    node: LaunchArgs,
}

/// The modes that are not the pipeline's node.
#[derive(Debug, Subcommand)]
enum Mode {
    /// Record a written plan (`icrflow plan --rrd`).
    #[command(long_flag = "plan")]
    Plan {
        /// The plan's config file.
        config: PathBuf,
        /// Its trajectory.json.
        trajectory: PathBuf,
        #[command(flatten)]
        recording: RecordingArgs,
    },
    /// Render a recording into a PNG (`icrflow render`).
    #[command(long_flag = "render")]
    Render(icrflow_visualizer::render::Request),
}

/// Exit status 0, or 1 with the error said on stderr.
fn exit(result: anyhow::Result<()>) -> ExitCode {
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("icrflow-visualizer: error: {e:#}");
            ExitCode::FAILURE
        }
    }
}

fn main() -> ExitCode {
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        // A malformed command line as every node says it: exit status 1, named.
        Err(e) if e.use_stderr() => {
            let said = e.render().to_string();
            eprintln!(
                "icrflow-visualizer: error: {}",
                said.trim_start_matches("error: ").trim_end()
            );
            return ExitCode::FAILURE;
        }
        Err(e) => e.exit(),
    };
    match (cli.mode, cli.node) {
        (Some(Mode::Render(request)), _) => exit(icrflow_visualizer::render::run(&request)),
        (
            Some(Mode::Plan {
                config,
                trajectory,
                recording,
            }),
            _,
        ) => exit(
            Option::<RecordingLaunch>::from(recording)
                .ok_or_else(|| anyhow::anyhow!("--plan needs --recording TARGET --recording-id ID"))
                .and_then(|r| icrflow_visualizer::plan::run(&config, &trajectory, &r).map(|_| ())),
        ),
        (None, node) => icrflow_runtime::node::main_launched(
            "visualizer",
            Launch::try_from(node),
            icrflow_scenario::Loaded::load,
            icrflow_visualizer::run,
        ),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::CommandFactory as _;
    use icrflow_runtime::bus::BusConfig;

    #[test]
    fn the_three_modes_are_read_from_what_their_starters_write() {
        Cli::command().debug_assert();
        let parse = |args: &[String]| {
            Cli::try_parse_from(
                std::iter::once("icrflow-visualizer".to_string()).chain(args.iter().cloned()),
            )
        };
        // The node, as `icrflow run` starts it.
        let bus = BusConfig::new("rig", "icr1_", PathBuf::from("/tmp/icrflow/run-1")).unwrap();
        let mut launch = Launch::supervised(PathBuf::from("/c.toml"), bus);
        launch.recording = Some(RecordingLaunch {
            target: "rrd:/o/r.rrd".into(),
            id: "id-1".into(),
            footer: true,
        });
        let cli = parse(&launch.to_args()).unwrap();
        assert!(cli.mode.is_none());
        assert_eq!(Launch::try_from(cli.node).unwrap(), launch);
        // The plan mode, as `icrflow plan --rrd` starts it.
        let mut plan: Vec<String> = ["--plan", "c.toml", "t.json"].map(String::from).into();
        plan.extend(launch.recording.clone().unwrap().to_args());
        match parse(&plan).unwrap().mode {
            Some(Mode::Plan {
                config,
                trajectory,
                recording,
            }) => {
                assert_eq!((config, trajectory), ("c.toml".into(), "t.json".into()));
                assert_eq!(Option::<RecordingLaunch>::from(recording), launch.recording);
            }
            other => panic!("{other:?}"),
        }
        // The render mode, as `icrflow render` starts it.
        let render = [
            "--render", "r.rrd", "--at", "END", "--out", "p.png", "--size", "800x600", "--viewer",
            "rerun",
        ]
        .map(String::from);
        match parse(&render).unwrap().mode {
            Some(Mode::Render(r)) => assert_eq!((r.size, r.out), ((800, 600), "p.png".into())),
            other => panic!("{other:?}"),
        }
        // A mode with a node's argument is refused, and so is a node without its own.
        let mut mixed = render.to_vec();
        mixed.extend(["--rig".into(), "r".into()]);
        assert!(parse(&mixed).is_err());
        let e = parse(&launch.to_args()[2..]).unwrap_err().to_string();
        assert!(e.contains("--config <PATH>"), "{e}");
        assert!(parse(&plan[..3]).is_ok_and(|c| matches!(c.mode, Some(Mode::Plan { .. }))));
    }
}
