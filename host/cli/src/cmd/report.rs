//! `robimu report`: a self-contained HTML report of a calibration result.

use std::path::PathBuf;

/// Moved to [`robimu_report::result_report::session_series`].
use robimu_report::result_report::write_result_report;

/// Write an HTML report of a calibration result.
///
/// One self-contained page (inline CSS, figures as inline SVG, no scripts,
/// no external links): the parameter table, posterior σ against the prior
/// σ, convergence (from NAME.convergence.csv next to NAME.json, written by
/// `robimu calibrate`; the page says so when it is missing) and, when the
/// session is found, the joint trajectory and the IMU residuals over time.
/// The figures are also written as PNG and SVG. A result of several IMUs
/// (docs/model.md §9) has its table and σ bars grouped by IMU and one
/// residual figure per IMU.
#[derive(Debug, Clone, clap::Args)]
pub struct ReportCmd {
    /// Result file (result.json, docs/model.md §8).
    pub result: PathBuf,
    /// Directory to write report.html and the figures to [default: `report`
    /// next to the result file].
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Session directory for the trajectory and residual plots [default: the
    /// session named in the result, when it exists].
    #[arg(long)]
    pub session: Option<PathBuf>,
}

impl ReportCmd {
    /// Write the report.
    pub fn run(self) -> anyhow::Result<()> {
        let path = write_result_report(&self.result, self.out.as_deref(), self.session.as_deref())?;
        println!("wrote {}", path.display());
        Ok(())
    }
}
