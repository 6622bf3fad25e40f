//! `robimu`: record, simulate and calibrate robot + IMU sessions.
//!
//! The program as a library: [`run`] is `robimu`'s `main` on the given
//! arguments (the Python package's `robimu` command runs it in-process),
//! and the flags and steps that the Python package shares with the
//! program (the calibration's flags, naming a robot, placing the IMUs,
//! the simulate and plan commands) so that both give the same files.
//! Each subcommand is a module of `cmd` that parses its arguments and
//! calls the library crates. Errors end the program with a short cause
//! chain on stderr ([`error_report`]) and a non-zero exit code.

#![deny(missing_docs)]

mod args;
mod cmd;
mod flows;
mod input;

use std::ffi::OsString;

use clap::Parser;

pub use args::{CalibrateFlags, ResonanceMode, UrdfLinks};
pub use cmd::calibrate::CalibrateCmd;
pub use cmd::check::check_dir;
pub use cmd::diagnose::DiagnoseCmd;
pub use cmd::error_report;
pub use cmd::export::ExportCmd;
pub use cmd::plan::PlanCmd;
pub use cmd::simulate::SimulateCmd;
pub use flows::calibrate::fit_summary;
pub use input::output_path;

/// Unified robot and IMU self-calibration (Ferguson et al., Robotica 2023).
#[derive(Debug, Parser)]
#[command(name = "robimu", version, propagate_version = true)]
struct Cli {
    #[command(subcommand)]
    command: cmd::Command,
}

/// glibc's allocator hands large blocks (from 128 KiB, growing with use)
/// back to the kernel when they are freed, and the next one is faulted in
/// page by page again: a calibration frees and allocates its per-pass
/// buffers (matrices, residuals, tables of 1–2 MB) many times, and on a
/// virtual machine a page fault costs ≈ 2 µs (7 000 of them in a 300 s
/// calibrate). Serving blocks up to 32 MiB from the heap and keeping up to
/// 256 MiB of freed memory for reuse leaves 5 100 of them (issue 18,
/// docs/performance.md); memory is returned at exit.
pub fn keep_freed_memory() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: mallopt only sets the allocator's parameters; it takes the
    // allocator's own lock, so other threads may exist.
    unsafe {
        libc::mallopt(libc::M_MMAP_THRESHOLD, 32 << 20);
        libc::mallopt(libc::M_TRIM_THRESHOLD, 256 << 20);
    }
}

/// `robimu` on `args` (the first is the program's name): parses them (help,
/// version and usage errors print as the program prints them), runs the
/// command, prints an error's cause chain on stderr; returns the exit code
/// (0, 1 on an error, 2 on a usage error).
pub fn run<I, T>(args: I) -> u8
where
    I: IntoIterator<Item = T>,
    T: Into<OsString> + Clone,
{
    keep_freed_memory();
    let cli = match Cli::try_parse_from(args) {
        Ok(cli) => cli,
        Err(e) => {
            // --help and --version are "errors" that print to stdout, exit 0
            let _ = e.print();
            return e.exit_code().clamp(0, 255) as u8;
        }
    };
    match cli.command.run() {
        Ok(()) => 0,
        Err(e) => {
            eprint!("{}", error_report(&e));
            1
        }
    }
}
