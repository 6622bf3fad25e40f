//! `robimu`: record, simulate and calibrate robot + IMU sessions.
//!
//! A thin program: each subcommand is a module of [`cmd`] that parses its
//! arguments and calls the `robimu` library. Errors end the program with a
//! short cause chain on stderr and a non-zero exit code.

#![deny(missing_docs)]

mod args;
mod cmd;
mod flows;
mod input;

use std::process::ExitCode;

use clap::Parser;

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
fn keep_freed_memory() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: mallopt only sets the allocator's parameters; called before
    // any other thread exists.
    unsafe {
        libc::mallopt(libc::M_MMAP_THRESHOLD, 32 << 20);
        libc::mallopt(libc::M_TRIM_THRESHOLD, 256 << 20);
    }
}

fn main() -> ExitCode {
    keep_freed_memory();
    let cli = Cli::parse();
    match cli.command.run() {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprint!("{}", cmd::error_report(&e));
            ExitCode::FAILURE
        }
    }
}
