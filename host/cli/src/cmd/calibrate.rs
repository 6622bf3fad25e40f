//! `robimu calibrate`: the MAP calibration of one session, its table and its
//! result file (docs/model.md §8).

use std::path::PathBuf;

use crate::args::CalibrateFlags;
use crate::flows::calibrate::CalibrateRun;

/// Calibrate the robot and the IMU together from a session.
///
/// Estimates every parameter with its posterior uncertainty, prints the
/// parameter table (against the truth when the session has a truth.toml)
/// and writes the result file (JSON, docs/model.md §8) and, next to it, the
/// solver's iteration history (NAME.convergence.csv for NAME.json).
#[derive(Debug, Clone, clap::Args)]
pub struct CalibrateCmd {
    /// Session directory (session.toml, joints.csv, imu.csv).
    pub session: PathBuf,
    /// Result file to write [default: result.json in the session directory].
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Repeatability: also calibrate each of N equal time windows (N >= 2;
    /// the paper used five 1-minute windows), print each parameter group's
    /// largest difference from the full calibration and write
    /// repeatability.csv next to the result file.
    #[arg(long, value_name = "N")]
    pub windows: Option<usize>,
    /// Also write a self-contained HTML report (report.html and its figures)
    /// into this directory.
    #[arg(long, value_name = "DIR")]
    pub report: Option<PathBuf>,
    /// The calibration's settings (shared with `robimu calibrate-batch`).
    #[command(flatten)]
    pub fit: CalibrateFlags,
}

impl CalibrateCmd {
    /// Calibrate, print the table and write the result file.
    pub fn run(self) -> anyhow::Result<()> {
        CalibrateRun {
            session: &self.session,
            out: self.out.as_deref(),
            windows: self.windows,
            report: self.report.as_deref(),
            flags: &self.fit,
        }
        .run()
        .map(drop)
    }
}
