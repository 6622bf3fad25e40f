//! The figures of a diagnosis, before and after its effects: the
//! whitened residuals' windowed RMS over time and their spectra, one panel
//! per channel or sensor (`robimu diagnose`'s files, and the calibration
//! report's evidence for each effect the model gained).

use std::path::{Path, PathBuf};

use robimu_workflows::diagnose::{welch, windowed_rms, Diagnosis, CHANNELS};

use crate::plot::{line_panels, loglog_panels, LinePanel, LogLogPanel, PlotError};

/// Whether the final fit is the baseline itself (no effect added): its
/// residual curves are then the baseline's, computed once.
fn same_fits(d: &Diagnosis) -> bool {
    d.found.is_empty() && d.final_fit.effects.is_empty()
}

/// Window of the residual plot, s.
const RMS_WINDOW: f64 = 1.0;

/// Whitened residuals over time before and after the effects (files
/// `stem`.png and .svg), one panel per
/// channel, as their RMS over consecutive windows of about 1 s (a tenth of
/// the session when shorter than 10 s): a sample-by-sample plot of 10⁵–10⁶
/// points would be an unreadable band and a multi-megabyte SVG, while the
/// windowed RMS keeps one point per second and shows where and when the
/// residuals rise above the noise model's level of 1 (drawn as a line).
pub fn residuals_plot(
    stem: &Path,
    data: &robimu_model::observations::Measurements,
    d: &Diagnosis,
) -> Result<Vec<PathBuf>, PlotError> {
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
    line_panels(
        stem,
        "whitened residuals (windowed RMS), before and after the effects",
        &panels,
        3,
    )
}

/// Residual spectra before and after (files `stem`.png and .svg), one
/// panel per sensor.
pub fn spectra_plot(
    stem: &Path,
    data: &robimu_model::observations::Measurements,
    d: &Diagnosis,
) -> Result<Vec<PathBuf>, PlotError> {
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
    loglog_panels(
        stem,
        "whitened residual spectra, before and after the effects",
        &panels,
    )
}
