//! `robimu diagnose`: find where the calibrated model and the measurement
//! disagree, name the missing effect from the catalogue, add it, and show
//! the gap shrink.

use std::path::PathBuf;

use std::path::Path;

use robimu_session::SessionSource;
use robimu_workflows::pipeline::pose_diagnosis::{
    diagnose_pose_session, write_pose_diagnosis, PoseDiagnosisSummary,
};
use robimu_workflows::DiagnoseSettings;

/// Diagnose model discrepancies of a session.
///
/// Fits the baseline calibration under the noise model of --noise-model,
/// analyses the whitened residuals (prewhitened with a correlated noise
/// model; RMS and χ² per channel, Ljung–Box whiteness, spectral peaks, where
/// in time they concentrate, the regressor they follow), scores every catalogued effect
/// (g_sensitivity, size_effect, clock_drift, sensor_delay, bias_drift, joint_elasticity,
/// encoder_scale, resonance, and temperature_bias where imu.csv has a varying
/// temp_c) with a Rao score test, adds the most significant one
/// (Bonferroni at --alpha across the catalogue, confirmed by a refit's
/// likelihood ratio), and repeats until none is significant; a narrow
/// spectral peak left in a channel is reported as unexplained structure.
/// Prints the summary (with the noise model used) and writes DIR/diagnosis.json, the residuals over time
/// (residuals.png/svg) and their spectra (residual_spectra.png/svg), before
/// and after the effects.
#[derive(Debug, Clone, clap::Args)]
pub struct DiagnoseCmd {
    /// Session directory (session.toml, joints.csv, imu.csv).
    pub session: PathBuf,
    /// A calibration result (robimu-result/1 JSON) to start the baseline fit from.
    #[arg(long, value_name = "FILE")]
    pub calibration: Option<PathBuf>,
    /// Output directory [default: diagnosis/ in the session directory].
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
    /// Family-wise significance level (divided by the number of candidates).
    #[arg(long, default_value_t = 0.01)]
    pub alpha: f64,
    /// Mass model (TOML, `[[link]] mass = kg, com = [m, m, m]` per link) for
    /// joint elasticity [default: built-in estimate for the AUBO i5].
    #[arg(long, value_name = "FILE")]
    pub mass_model: Option<PathBuf>,
    /// Candidates to consider, comma-separated [default: the whole catalogue].
    /// With several IMUs a per-sensor effect's plain name selects it on
    /// every IMU, `imu<j>/NAME` on IMU j alone (docs/model.md §9).
    #[arg(long, value_delimiter = ',')]
    pub candidates: Vec<String>,
    /// The `resonance` candidate's mode.
    #[command(flatten)]
    pub resonance: crate::args::ResonanceMode,
    /// The IMU noise model of the fits and tests: `auto` (white unless the
    /// white baseline's residuals fail the whiteness test; then identified
    /// from them, again after each effect is added, and every score, refit
    /// and residual statistic is on the prewhitened residuals; a session
    /// whose `[noise]` table gives `ar_z`/`motion_z` uses that model),
    /// `white` (the paper's model), or a TOML FILE with a `[noise]` table
    /// (docs/model.md §4.6).
    #[arg(long, value_name = "white|auto|FILE", default_value = "auto")]
    pub noise_model: String,
    /// Also write the HTML report of the final model into DIR (report.html:
    /// calibrate's page — verdict, pose accuracy, the model and the
    /// evidence for its effects, the parameters — with every candidate's
    /// score in every round).
    #[arg(long, value_name = "DIR")]
    pub report: Option<PathBuf>,
}

impl DiagnoseCmd {
    /// Diagnose, print and write.
    pub fn run(self) -> anyhow::Result<()> {
        let settings = self.settings();
        if let Ok(SessionSource::Poses) = SessionSource::of_dir(&self.session) {
            if self.report.is_some() {
                anyhow::bail!(
                    "--report: not available for a pose session yet (diagnosis.json has its \
                     scores)"
                );
            }
            return diagnose_poses(&self.session, &settings);
        }
        let d = crate::flows::diagnose::run(&self.session, &settings)?;
        if let Some(dir) = &self.report {
            let page = crate::flows::calibrate::diagnosis_report(&self.session, dir, d)?;
            println!("wrote {}", page.display());
        }
        Ok(())
    }

    /// The library's settings of these flags (`--out` defaults to the
    /// session's `diagnosis` directory).
    pub fn settings(&self) -> DiagnoseSettings {
        DiagnoseSettings {
            calibration: self.calibration.clone(),
            out: self
                .out
                .clone()
                .unwrap_or_else(|| self.session.join("diagnosis")),
            alpha: self.alpha,
            mass_model: self.mass_model.clone(),
            candidates: self.candidates.clone(),
            resonance: self.resonance.unchecked(),
            noise_model: self.noise_model.clone(),
        }
    }
}

/// `robimu diagnose` of a pose session (docs/model.md §7.9): the summary
/// and DIR/diagnosis.json.
fn diagnose_poses(dir: &Path, settings: &DiagnoseSettings) -> anyhow::Result<()> {
    let progress = crate::input::Progress::start("calibrating the pose session");
    let d = diagnose_pose_session(
        dir,
        settings,
        |w| eprintln!("warning: {w}"),
        |m| progress.set_message(m.to_string()),
    );
    progress.finish();
    let d = d?;
    print!("{}", PoseDiagnosisSummary(&d));
    let path = write_pose_diagnosis(&d, &settings.out)?;
    println!("wrote {}", path.display());
    Ok(())
}
