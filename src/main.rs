//! `icrflow`: the command-line entry point.

mod analyze;
mod cli;
mod exit;
mod monitor;
mod output;
mod plan;
mod progress;
mod render;
mod run;

use std::process::ExitCode;

use clap::Parser;

fn main() -> ExitCode {
    let cli = cli::Cli::parse();
    let after = cli.progress_after;
    let result = match cli.command {
        cli::Command::Analyze { config, json } => analyze::run(&config, json, after),
        cli::Command::Plan {
            config,
            out,
            json,
            rrd,
            spawn_viewer,
            connect_viewer,
        } => plan::run(
            &config,
            out,
            json,
            &run::Viewer {
                rrd,
                spawn: spawn_viewer,
                connect: connect_viewer,
                off: false,
            },
            after,
        ),
        cli::Command::Render { rrd, at, out, size } => render::run(&rrd, &at, &out, &size),
        cli::Command::Validate { config } => plan::validate(&config, after),
        cli::Command::Monitor {
            connect,
            rig,
            user,
            seconds,
        } => monitor::run(&connect, &rig, user.as_deref(), seconds),
        cli::Command::Run {
            config,
            live,
            summary_json,
            verbose,
            rrd,
            spawn_viewer,
            connect_viewer,
            no_visualizer,
        } => run::run(
            &config,
            live,
            summary_json,
            verbose,
            run::Viewer {
                rrd,
                spawn: spawn_viewer,
                connect: connect_viewer,
                off: no_visualizer,
            },
        ),
    };
    match result {
        Ok(code) => ExitCode::from(code),
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}
