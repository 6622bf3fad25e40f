//! `robimu calibrate`: the MAP calibration of one session, its table and its
//! result file (docs/model.md §8).

use std::path::PathBuf;

use crate::args::CalibrateFlags;
use robimu_session::SessionSource;

use crate::flows::calibrate::CalibrateRun;
use crate::flows::poses::calibrate_pose_dir;

/// Calibrate the robot and the IMU together from a session.
///
/// Estimates every parameter with its posterior uncertainty, prints the
/// parameter table (against the truth when the session has a truth.toml)
/// and writes the result file (JSON, docs/model.md §8) and, next to it, the
/// solver's iteration history (NAME.convergence.csv for NAME.json).
///
/// A session with tool poses (`source = "poses"`, poses.csv; docs/model.md
/// §7.9) calibrates the IMU alone: its position on the posed body, gravity,
/// tau and the 24 sensor parameters, with the σ of its session.toml
/// (`[poses]`, `[noise]`) or the defaults; it takes --out and
/// --knot-spacing, and writes the result file (with `"source": "poses"`).
#[derive(Debug, Clone, clap::Args)]
pub struct CalibrateCmd {
    /// Session directory (session.toml, joints.csv or poses.csv, imu.csv).
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
        if let Ok(SessionSource::Poses) = SessionSource::of_dir(&self.session) {
            return calibrate_pose_dir(
                &self.session,
                self.out.as_deref(),
                &self.fit,
                self.windows.is_some(),
                self.report.as_deref(),
            )
            .map(drop);
        }
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
