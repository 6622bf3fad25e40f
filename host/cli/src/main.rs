//! `robimu`: record, simulate and calibrate robot + IMU sessions.
//!
//! A thin program: [`robimu_cli::run`] on the command line's arguments.

use std::process::ExitCode;

fn main() -> ExitCode {
    ExitCode::from(robimu_cli::run(std::env::args_os()))
}
