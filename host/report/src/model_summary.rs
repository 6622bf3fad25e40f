//! What `calibrate` prints after its verdict (docs/model.md §8.6–8.7): the
//! model it wrote and why (each effect added with its score test, the
//! likelihood ratio of its refit and the residual RMS before and after),
//! and the flange pose accuracy before and after calibration.

use std::fmt;

use robimu_session::result::{
    ActualPoseErrors, CalibrationResult, PoseAccuracyRecord, PoseErrorStats,
};
use robimu_workflows::calibrate::fit::Fit;

use crate::fit_summary::EffectValue;

/// The model written and the evidence for its effects; `fit` (the written
/// model's fit) gives the effect parameters in display units.
pub struct ModelSummary<'a> {
    /// The result record.
    pub result: &'a CalibrationResult,
    /// The fit of the model written.
    pub fit: &'a Fit,
}

impl fmt::Display for ModelSummary<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let Some(tests) = &self.result.model_tests else {
            return Ok(());
        };
        let effects = self.result.effects.as_deref().unwrap_or_default();
        let how = match tests.selection.as_str() {
            "paper" => "asked for with --model paper",
            "given" => "the effects given with --effects",
            _ if effects.is_empty() => "no catalogue effect is significant against it",
            _ => "the effects the score tests found, added by diagnose's search",
        };
        let names: Vec<&str> = effects.iter().map(|e| e.name.as_str()).collect();
        let model = match names.is_empty() {
            true => "the paper's".to_string(),
            false => format!("the paper's + {}", names.join(", ")),
        };
        writeln!(
            f,
            "model: {model} ({how}; score tests of {} candidates at α = {})",
            tests.candidates, tests.alpha
        )?;
        for e in effects {
            if let Some(ev) = &e.evidence {
                writeln!(
                    f,
                    "  {}: score {:.1} ({} dof, p = {:.2e}), refit LR {:.1} (p = {:.2e}); whitened residual rms {}",
                    e.name,
                    ev.statistic,
                    ev.dof,
                    ev.p_value,
                    ev.lr_statistic,
                    ev.lr_p_value,
                    rms_change(&ev.rms_before, &ev.rms_after)
                )?;
            }
            for (k, p) in self.fit.effect_params.iter().enumerate() {
                if p.name.starts_with(&format!("{}.", e.name)) {
                    writeln!(f, "    {}", EffectValue::of(self.fit, k))?;
                }
            }
        }
        Ok(())
    }
}

/// `ax 1.000→0.998 …` for the channels that changed by 0.0005 or more.
fn rms_change(before: &[f64; 6], after: &[f64; 6]) -> String {
    let parts: Vec<String> = robimu_session::IMU_COLUMNS
        .iter()
        .zip(before.iter().zip(after))
        .filter(|(_, (b, a))| (*b - *a).abs() >= 5e-4)
        .map(|(n, (b, a))| format!("{n} {b:.3}→{a:.3}"))
        .collect();
    match parts.is_empty() {
        true => "unchanged".into(),
        false => parts.join(" "),
    }
}

/// The pose accuracy as a small table (docs/model.md §8.7).
pub struct PoseAccuracyText<'a>(pub &'a PoseAccuracyRecord);

impl fmt::Display for PoseAccuracyText<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let a = self.0;
        writeln!(
            f,
            "pose accuracy of the flange over {} random configurations within the joint limits (predicted from the prior and from the posterior):",
            a.configurations
        )?;
        writeln!(
            f,
            "  {:<30} {:>10} {:>10} {:>10} {:>10}",
            "", "mean mm", "p95 mm", "mean deg", "p95 deg"
        )?;
        let row = |f: &mut fmt::Formatter<'_>, label: &str, s: &PoseErrorStats, extra: &str| {
            writeln!(
                f,
                "  {label:<30} {:>10.3} {:>10.3} {:>10.4} {:>10.4}{extra}",
                s.position_mean_mm, s.position_p95_mm, s.rotation_mean_deg, s.rotation_p95_deg
            )
        };
        row(f, "before calibration (prior)", &a.before, "")?;
        row(f, "after calibration", &a.after, "")?;
        row(
            f,
            "  of which undetermined",
            &a.after_undetermined,
            "  (parameters the data left at their prior)",
        )?;
        let band = |e: &ActualPoseErrors| {
            format!(
                "  (inside the predicted 95 % band: {:.0} % / {:.0} %)",
                100.0 * e.position_inside_band,
                100.0 * e.rotation_inside_band
            )
        };
        if let Some(e) = &a.actual_before {
            row(f, "actual before (the truth)", &e.stats, &band(e))?;
        }
        if let Some(e) = &a.actual_after {
            row(f, "actual after (the truth)", &e.stats, &band(e))?;
        }
        Ok(())
    }
}
