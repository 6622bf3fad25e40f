//! `robimu diagnose`: find where the calibrated model and the measurement
//! disagree, name the missing effect from the catalogue, add it, and show
//! the gap shrink.

use std::io::Write;
use std::path::PathBuf;

use anyhow::{bail, Context};
use robimu_model::effects::{self, MassModel};
use robimu_model::ParamLayout;
use robimu_report::diagnosis::DiagnosisSummary;
use robimu_report::plot::{line_panels, loglog_panels, LinePanel, LogLogPanel};
use robimu_session::result::CalibrationResult;
use robimu_workflows::calibrate::{check_measurements, CalibrateOptions};
use robimu_workflows::diagnose::{
    diagnose, setup_with, welch, windowed_rms, DiagnoseOptions, Diagnosis, CHANNELS,
};

use super::input::{load_session, Progress};
use super::noise_spec::{noise_choice, NoiseFileArg};

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
    #[command(flatten)]
    pub resonance: super::input::ResonanceMode,
    /// The IMU noise model of the fits and tests: `auto` (white unless the
    /// white baseline's residuals fail the whiteness test; then identified
    /// from them, again after each effect is added, and every score, refit
    /// and residual statistic is on the prewhitened residuals; a session
    /// whose `[noise]` table gives `ar_z`/`motion_z` uses that model),
    /// `white` (the paper's model), or a TOML FILE with a `[noise]` table
    /// (docs/model.md §4.6).
    #[arg(long, value_name = "white|auto|FILE", default_value = "auto")]
    pub noise_model: String,
}

impl DiagnoseCmd {
    /// Diagnose, print and write.
    pub fn run(self) -> anyhow::Result<()> {
        self.run_diagnosis().map(|_| ())
    }

    /// [`Self::run`], returning the diagnosis (for `robimu demo`).
    pub fn run_diagnosis(self) -> anyhow::Result<Diagnosis> {
        let dir = &self.session;
        let (session, robot) = load_session(dir)?;
        if !(self.alpha > 0.0 && self.alpha < 1.0) {
            bail!("--alpha must be in (0, 1) (got {})", self.alpha);
        }
        let out_dir = self.out.clone().unwrap_or_else(|| dir.join("diagnosis"));
        std::fs::create_dir_all(&out_dir)
            .with_context(|| format!("cannot create the output directory {}", out_dir.display()))?;
        let mut opts = CalibrateOptions::new(&robot);
        (opts.sigma_z, opts.sigma_q) = session.noise(&robot)?;
        let data = session.measurements();
        // every IMU of the session (docs/model.md §9)
        let layout = ParamLayout::with_imus(&robot, data.n_imus());
        check_measurements(&robot, &data)
            .with_context(|| format!("cannot diagnose the session {}", dir.display()))?;
        let mass = match &self.mass_model {
            Some(p) => Some(MassModel::from_toml_file(&robot, p).context("--mass-model")?),
            None => None,
        };
        let setup = setup_with(&robot, &data, mass, self.resonance.mode()?);
        let file = NoiseFileArg::from_flags(None, &self.noise_model)?;
        if let Some(z) = file.as_ref().and_then(|f| f.file.noise.sigma_z) {
            opts.sigma_z = z;
        }
        let noise = noise_choice(
            &self.noise_model,
            &session,
            opts.sigma_z,
            data.imu_t.len(),
            file.as_ref(),
        )?;
        let mut dopts = DiagnoseOptions {
            alpha: self.alpha,
            noise,
            ..DiagnoseOptions::default()
        };
        if !self.candidates.is_empty() {
            for c in &self.candidates {
                effects::by_name(&setup, c).context("--candidates")?;
            }
            dopts.candidates = self.candidates.clone();
            dopts.max_effects = self.candidates.len();
        }
        if let Some(path) = &self.calibration {
            let result = CalibrationResult::read(path)
                .with_context(|| format!("--calibration {}", path.display()))?;
            let mut x = layout.nominal();
            for (k, spec) in layout.specs().iter().enumerate() {
                match result.parameter(&spec.name) {
                    Some(p) => x[k] = p.value,
                    None => bail!(
                        "--calibration {}: parameter `{}` is missing (is it for robot `{}`?)",
                        path.display(),
                        spec.name,
                        robot.name()
                    ),
                }
            }
            dopts.x_start = Some(x);
        }
        let progress = Progress::start("fitting the baseline model");
        let d = diagnose(&robot, &data, &opts, &setup, &dopts, |m| {
            progress.set_message(m.to_string())
        });
        progress.finish();
        let d = d.with_context(|| format!("cannot diagnose the session {}", dir.display()))?;
        // the two figures on their own threads while the summary and the
        // JSON are written (each is independent of the others)
        let (written, residuals, spectra) = std::thread::scope(|s| {
            let residuals = s.spawn(|| residuals_plot(&out_dir, &data, &d));
            let spectra = s.spawn(|| spectra_plot(&out_dir, &data, &d));
            let written = write_summary(&out_dir, &layout, &d);
            (
                written,
                residuals.join().expect("residual plot panicked"),
                spectra.join().expect("spectra plot panicked"),
            )
        });
        written?;
        let mut out = std::io::stdout().lock();
        for p in residuals?.into_iter().chain(spectra?) {
            writeln!(out, "wrote {}", p.display())?;
        }
        Ok(d)
    }
}

/// Print the summary and write DIR/diagnosis.json.
fn write_summary(
    out_dir: &std::path::Path,
    layout: &ParamLayout,
    d: &Diagnosis,
) -> anyhow::Result<()> {
    let mut out = std::io::stdout().lock();
    write!(out, "{}", DiagnosisSummary(d))?;
    let json = d.to_json(layout);
    let path = out_dir.join("diagnosis.json");
    std::fs::write(&path, serde_json::to_string_pretty(&json)?)
        .with_context(|| format!("cannot write {}", path.display()))?;
    writeln!(out, "wrote {}", path.display())?;
    Ok(())
}

/// Whether the final fit is the baseline itself (no effect added): its
/// residual curves are then the baseline's, computed once.
fn same_fits(d: &Diagnosis) -> bool {
    d.found.is_empty() && d.final_fit.effects.is_empty()
}

/// Window of the residual plot, s.
const RMS_WINDOW: f64 = 1.0;

/// Whitened residuals over time before and after the effects, one panel per
/// channel, as their RMS over consecutive windows of about 1 s (a tenth of
/// the session when shorter than 10 s): a sample-by-sample plot of 10⁵–10⁶
/// points would be an unreadable band and a multi-megabyte SVG, while the
/// windowed RMS keeps one point per second and shows where and when the
/// residuals rise above the noise model's level of 1 (drawn as a line).
fn residuals_plot(
    dir: &std::path::Path,
    data: &robimu_model::observations::Measurements,
    d: &Diagnosis,
) -> anyhow::Result<Vec<PathBuf>> {
    let span = match (data.imu_t.first(), data.imu_t.last()) {
        (Some(a), Some(b)) => (*a, *b),
        _ => (0.0, 1.0),
    };
    let window = RMS_WINDOW.min((span.1 - span.0) / 10.0);
    let panels: Vec<LinePanel> = CHANNELS
        .iter()
        .enumerate()
        .map(|(c, name)| {
            let rms = |fit: &robimu_workflows::calibrate::fit::Fit| {
                let t: Vec<f64> = fit.residuals.iter().map(|(i, _)| data.imu_t[*i]).collect();
                let r: Vec<f64> = fit.residuals.iter().map(|(_, v)| v[c]).collect();
                windowed_rms(&t, &r, window)
            };
            let before = rms(&d.baseline);
            let after = same_fits(d).then(|| before.clone());
            let after = after.unwrap_or_else(|| rms(&d.final_fit));
            let mut series = vec![("before".to_string(), before), ("after".to_string(), after)];
            series.push(("noise model".into(), vec![(span.0, 1.0), (span.1, 1.0)]));
            LinePanel {
                title: format!("{name} residual"),
                x_label: "session time [s]".into(),
                y_label: format!("RMS per ~{window:.2} s [σ]"),
                series,
            }
        })
        .collect();
    Ok(line_panels(
        &dir.join("residuals"),
        "whitened residuals (windowed RMS), before and after the effects",
        &panels,
        3,
    )?)
}

/// Residual spectra before and after, one panel per sensor.
fn spectra_plot(
    dir: &std::path::Path,
    data: &robimu_model::observations::Measurements,
    d: &Diagnosis,
) -> anyhow::Result<Vec<PathBuf>> {
    let rate = {
        let t = &data.imu_t;
        if t.len() > 1 {
            (t.len() - 1) as f64 / (t[t.len() - 1] - t[0]).max(1e-9)
        } else {
            1.0
        }
    };
    let spectrum = |fit: &robimu_workflows::calibrate::fit::Fit, c: usize| {
        let r: Vec<f64> = fit.residuals.iter().map(|(_, v)| v[c]).collect();
        welch(&r, rate)
    };
    let mut panels = Vec::new();
    for (sensor, title) in [(0, "accelerometer"), (1, "gyroscope")] {
        let before: Vec<_> = (3 * sensor..3 * sensor + 3)
            .map(|c| spectrum(&d.baseline, c))
            .collect();
        let after: Vec<_> = match same_fits(d) {
            true => before.clone(),
            false => (3 * sensor..3 * sensor + 3)
                .map(|c| spectrum(&d.final_fit, c))
                .collect(),
        };
        let mut series = Vec::new();
        for (label, spectra) in [("before", before), ("after", after)] {
            for (c, p) in (3 * sensor..).zip(spectra) {
                series.push((format!("{} {label}", CHANNELS[c]), p));
            }
        }
        panels.push(LogLogPanel {
            title: format!("{title} residual spectra"),
            x_label: "frequency [Hz]".into(),
            y_label: "PSD [whitened²/Hz]".into(),
            series,
        });
    }
    Ok(loglog_panels(
        &dir.join("residual_spectra"),
        "whitened residual spectra, before and after the effects",
        &panels,
    )?)
}
