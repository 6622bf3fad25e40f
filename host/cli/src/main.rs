//! `robimu`: record, simulate and calibrate robot + IMU sessions.
//!
//! A thin program: each subcommand is a module of [`cmd`] that parses its
//! arguments and calls the `robimu` library. Errors end the program with a
//! short cause chain on stderr and a non-zero exit code.

#![deny(missing_docs)]

mod cmd;

use std::process::ExitCode;

use clap::Parser;

/// Unified robot and IMU self-calibration (Ferguson et al., Robotica 2023).
#[derive(Debug, Parser)]
#[command(name = "robimu", version, propagate_version = true)]
struct Cli {
    #[command(subcommand)]
    command: cmd::Command,
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    match cli.command.run() {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprint!("{}", cmd::error_report(&e));
            ExitCode::FAILURE
        }
    }
}
