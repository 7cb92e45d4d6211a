//! `icrflow`: the command-line entry point.

mod analyze;
mod cli;
mod exit;
mod monitor;
mod output;
mod percentile;
mod plan;
mod progress;
mod render;
mod run;
mod validate;
mod wrap;

use std::process::ExitCode;

use clap::Parser;

fn main() -> ExitCode {
    let cli = cli::Cli::parse();
    let verb = match &cli.command {
        cli::Command::Analyze { progress, .. }
        | cli::Command::Plan { progress, .. }
        | cli::Command::Validate { progress, .. } => Some(progress),
        cli::Command::Run { .. } | cli::Command::Monitor { .. } | cli::Command::Render { .. } => {
            None
        }
    };
    let after = cli.progress_delay(verb);
    let result = match cli.command {
        cli::Command::Analyze { config, json, .. } => analyze::run(&config, json, after),
        cli::Command::Plan {
            config,
            out,
            json,
            verbose,
            rrd,
            spawn_viewer,
            connect_viewer,
            ..
        } => plan::run(
            &config,
            out,
            (json, verbose),
            &run::Viewer {
                rrd,
                spawn: spawn_viewer,
                connect: connect_viewer,
                off: false,
            },
            after,
        ),
        cli::Command::Render { rrd, at, out, size } => render::run(&rrd, &at, &out, &size),
        cli::Command::Validate { config, .. } => validate::run(&config, after),
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
