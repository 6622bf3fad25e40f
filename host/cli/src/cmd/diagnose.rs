//! `robimu diagnose`: find where the calibrated model and the measurement
//! disagree, name the missing effect from the catalogue, add it, and show
//! the gap shrink.

use std::io::Write;
use std::path::PathBuf;

use anyhow::{bail, Context};
use robimu_model::effects::{self, MassModel};
use robimu_model::ParamLayout;
use robimu_report::plot::{line_panels, loglog_panels, LinePanel, LogLogPanel};
use robimu_session::result::CalibrationResult;
use robimu_workflows::calibrate::{check_measurements, CalibrateOptions};
use robimu_workflows::diagnose::{
    diagnose, setup_with, welch, windowed_rms, DiagnoseOptions, Diagnosis, ResidualStats, CHANNELS,
};

use super::input::{load_session, Progress};

/// Diagnose model discrepancies of a session.
///
/// Fits the baseline calibration, analyses the whitened residuals (RMS and
/// χ² per channel, Ljung–Box whiteness, spectral peaks, where in time they
/// concentrate, the regressor they follow), scores every catalogued effect
/// (g_sensitivity, size_effect, clock_drift, bias_drift, joint_elasticity,
/// encoder_scale, resonance) with a Rao score test, adds the most significant one
/// (Bonferroni at --alpha across the catalogue, confirmed by a refit's
/// likelihood ratio), and repeats until none is significant. Prints the
/// summary and writes DIR/diagnosis.json, the residuals over time
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
    #[arg(long, value_delimiter = ',')]
    pub candidates: Vec<String>,
    #[command(flatten)]
    pub resonance: super::input::ResonanceMode,
}

impl DiagnoseCmd {
    /// Diagnose, print and write.
    pub fn run(self) -> anyhow::Result<()> {
        let dir = &self.session;
        let (session, robot) = load_session(dir)?;
        if !(self.alpha > 0.0 && self.alpha < 1.0) {
            bail!("--alpha must be in (0, 1) (got {})", self.alpha);
        }
        let out_dir = self.out.clone().unwrap_or_else(|| dir.join("diagnosis"));
        std::fs::create_dir_all(&out_dir)
            .with_context(|| format!("cannot create the output directory {}", out_dir.display()))?;
        let layout = ParamLayout::new(&robot);
        let mut opts = CalibrateOptions::new(&robot);
        (opts.sigma_z, opts.sigma_q) = session.noise(&robot)?;
        let data = session.measurements();
        check_measurements(&robot, &data)
            .with_context(|| format!("cannot diagnose the session {}", dir.display()))?;
        let mass = match &self.mass_model {
            Some(p) => Some(MassModel::from_toml_file(&robot, p).context("--mass-model")?),
            None => None,
        };
        let setup = setup_with(&robot, &data, mass, self.resonance.mode()?);
        let mut dopts = DiagnoseOptions {
            alpha: self.alpha,
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
        let mut out = std::io::stdout().lock();
        write_summary(&mut out, &layout, &d)?;
        let json = diagnosis_json(&layout, &d);
        let path = out_dir.join("diagnosis.json");
        std::fs::write(&path, serde_json::to_string_pretty(&json)?)
            .with_context(|| format!("cannot write {}", path.display()))?;
        writeln!(out, "wrote {}", path.display())?;
        for p in residuals_plot(&out_dir, &data, &d)? {
            writeln!(out, "wrote {}", p.display())?;
        }
        for p in spectra_plot(&out_dir, &data, &d)? {
            writeln!(out, "wrote {}", p.display())?;
        }
        Ok(())
    }
}

/// Channel display: whitened RMS × σ in physical units (m/s², °/s).
fn physical_rms(rms: &[f64; 6], sigma: &[f64; 6]) -> [f64; 6] {
    std::array::from_fn(|c| {
        let s = if c < 3 {
            1.0
        } else {
            180.0 / std::f64::consts::PI
        };
        rms[c] * sigma[c] * s
    })
}

fn write_summary(out: &mut impl Write, layout: &ParamLayout, d: &Diagnosis) -> anyhow::Result<()> {
    let before = &d.stats_before;
    writeln!(
        out,
        "baseline: {} IMU samples, chi2 {:.0} for {} dof ({:.3} per dof)",
        before.samples,
        before.chi2_total.0,
        before.chi2_total.1,
        before.chi2_total.0 / before.chi2_total.1.max(1) as f64
    )?;
    write_stats(out, before)?;
    if d.found.is_empty() {
        writeln!(
            out,
            "no catalogued effect is significant (Bonferroni threshold p < {:.2e})",
            d.threshold
        )?;
    }
    for (k, f) in d.found.iter().enumerate() {
        writeln!(
            out,
            "\n{}. missing effect: {}  (score {:.1}, {} dof, p = {:.2e}; refit LR {:.1}, p = {:.2e}, dBIC {:.1})",
            k + 1,
            f.name,
            f.statistic,
            f.dof,
            f.p_value,
            f.lr_statistic,
            f.lr_p_value,
            f.delta_bic
        )?;
        let params = &d.final_fit.effect_params;
        for (name, _unit, v, s) in &f.parameters {
            let (du, scale) = params
                .iter()
                .find(|p| &p.name == name)
                .map_or(("", 1.0), |p| p.display);
            writeln!(
                out,
                "   {name:<34} {:+.4} ± {:.4} {du}",
                v * scale,
                s * scale
            )?;
        }
        let rb = f.rms_before;
        let ra = f.rms_after;
        let line: Vec<String> = CHANNELS
            .iter()
            .enumerate()
            .map(|(c, n)| format!("{n} {:.3}→{:.3}", rb[c], ra[c]))
            .collect();
        writeln!(out, "   whitened residual rms: {}", line.join("  "))?;
        if !f.baseline_moves.is_empty() {
            let moves: Vec<String> = f
                .baseline_moves
                .iter()
                .map(|(n, a, b, s)| format!("{n} {a:.4e}→{b:.4e} (σ {s:.1e})"))
                .collect();
            writeln!(
                out,
                "   baseline parameters moved > 1σ: {}",
                moves.join(", ")
            )?;
        }
    }
    let sz = d.sigma_z;
    let pb = physical_rms(&d.baseline.residual_rms(), &sz);
    let pa = physical_rms(&d.final_fit.residual_rms(), &sz);
    writeln!(
        out,
        "\nresidual rms before → after: accel {:.3}/{:.3}/{:.3} → {:.3}/{:.3}/{:.3} m/s^2, gyro {:.3}/{:.3}/{:.3} → {:.3}/{:.3}/{:.3} deg/s",
        pb[0], pb[1], pb[2], pa[0], pa[1], pa[2], pb[3], pb[4], pb[5], pa[3], pa[4], pa[5]
    )?;
    writeln!(
        out,
        "final model: baseline + [{}]",
        d.final_fit.effects.join(", ")
    )?;
    write_stats(out, &d.stats_after)?;
    // structure left that no candidate explains
    let lb_threshold = 0.01 / 6.0;
    let left: Vec<String> = d
        .stats_after
        .ljung_box
        .iter()
        .filter(|(_, (_, p))| *p < lb_threshold)
        .map(|(c, _)| {
            let (f, pk) = d.stats_after.spectral_peak.get(c).copied().unwrap_or_default();
            let (r, corr, z) = d
                .stats_after
                .top_regressor
                .get(c)
                .cloned()
                .unwrap_or_default();
            format!("{c} (peak {f:.2} Hz at {pk:.0}× median power; follows {r}, r = {corr:+.3}, z = {z:.1})")
        })
        .collect();
    if left.is_empty() {
        writeln!(
            out,
            "residuals are white in every channel (Ljung–Box, p ≥ {lb_threshold:.1e})"
        )?;
    } else {
        writeln!(
            out,
            "structure remains that no candidate explains: {}",
            left.join("; ")
        )?;
    }
    let _ = layout;
    Ok(())
}

fn write_stats(out: &mut impl Write, s: &ResidualStats) -> std::io::Result<()> {
    writeln!(
        out,
        "  {:<4} {:>7} {:>10} {:>10} {:>9} {:>10} {:>12}",
        "ch", "rms", "LjungBox", "p", "peak Hz", "peak/med", "top regressor"
    )?;
    for c in CHANNELS {
        let (q, p) = s.ljung_box[c];
        let (f, pk) = s.spectral_peak.get(c).copied().unwrap_or_default();
        let (r, corr, _) = s.top_regressor.get(c).cloned().unwrap_or_default();
        writeln!(
            out,
            "  {:<4} {:>7.3} {:>10.1} {:>10.2e} {:>9.2} {:>10.1} {:>6} {:+.3}",
            c, s.rms[c], q, p, f, pk, r, corr
        )?;
    }
    Ok(())
}

fn rms_map(rms: [f64; 6]) -> serde_json::Value {
    let mut m = serde_json::Map::new();
    for (c, v) in CHANNELS.iter().zip(rms) {
        m.insert(c.to_string(), v.into());
    }
    m.into()
}

/// The `diagnosis.json` document.
fn diagnosis_json(layout: &ParamLayout, d: &Diagnosis) -> serde_json::Value {
    serde_json::json!({
        "format": "robimu-diagnosis/1",
        "threshold": d.threshold,
        "effects_found": d.found,
        "last_scores": d.last_scores,
        "residual_rms_before": rms_map(d.baseline.residual_rms()),
        "residual_rms_after": rms_map(d.final_fit.residual_rms()),
        "residual_stats_before": d.stats_before,
        "residual_stats_after": d.stats_after,
        "final_model": robimu_workflows::diagnose::fit_json(layout, &d.final_fit),
    })
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
            let mut series: Vec<(String, Vec<(f64, f64)>)> =
                [("before", &d.baseline), ("after", &d.final_fit)]
                    .into_iter()
                    .map(|(label, fit)| {
                        let t: Vec<f64> =
                            fit.residuals.iter().map(|(i, _)| data.imu_t[*i]).collect();
                        let r: Vec<f64> = fit.residuals.iter().map(|(_, v)| v[c]).collect();
                        (label.to_string(), windowed_rms(&t, &r, window))
                    })
                    .collect();
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
    let mut panels = Vec::new();
    for (sensor, title) in [(0, "accelerometer"), (1, "gyroscope")] {
        let mut series = Vec::new();
        for (label, fit) in [("before", &d.baseline), ("after", &d.final_fit)] {
            for c in 3 * sensor..3 * sensor + 3 {
                let r: Vec<f64> = fit.residuals.iter().map(|(_, v)| v[c]).collect();
                series.push((format!("{} {label}", CHANNELS[c]), welch(&r, rate)));
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
