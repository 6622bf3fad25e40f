//! `robimu diagnose` of a session with tool poses (docs/model.md §7.9):
//! the session read and checked as `robimu calibrate` does, the
//! diagnosis of [`crate::pose_calibrate::diagnose`], its summary and
//! diagnosis.json (format `robimu-diagnosis/1`, the joint path's records,
//! with `"source": "poses"` and `"refit"` saying the refit is not done).

use std::fmt;
use std::path::{Path, PathBuf};

use anyhow::{bail, Context};

use super::poses::{load_pose_session, pose_options};
use super::{DiagnoseSettings, PipelineError};
use crate::pose_calibrate::diagnose::{diagnose_poses, PoseDiagnoseOptions, PoseDiagnosis};

/// What diagnosis.json and the summary say of the refit.
pub const REFIT_NOT_DONE: &str = "not done: the effects' values are one Gauss–Newton step from \
     the baseline fit (with their σ), not a refit with them; no likelihood ratio, ΔBIC or \
     residuals after";

/// Diagnose the pose session in `dir` with `settings` (those a pose
/// session cannot use refused); warnings to `warn`, stages to `progress`.
pub fn diagnose_pose_session(
    dir: &Path,
    settings: &DiagnoseSettings,
    mut warn: impl FnMut(String),
    progress: impl FnMut(&str),
) -> Result<PoseDiagnosis, PipelineError> {
    refuse_joint_flags(settings).map_err(PipelineError::input)?;
    let session = load_pose_session(dir, &mut warn)?;
    let opts = pose_options(&session.meta, &mut warn);
    std::fs::create_dir_all(&settings.out)
        .with_context(|| {
            format!(
                "cannot create the output directory {}",
                settings.out.display()
            )
        })
        .map_err(PipelineError::input)?;
    let dopts = PoseDiagnoseOptions {
        alpha: settings.alpha,
        candidates: settings.candidates.clone(),
    };
    diagnose_poses(&session.measurements(), &opts, &dopts, progress)
        .with_context(|| format!("cannot diagnose the pose session {}", dir.display()))
        .map_err(PipelineError::fit)
}

/// The flags of joint sessions a pose diagnosis cannot use.
fn refuse_joint_flags(s: &DiagnoseSettings) -> anyhow::Result<()> {
    let given: Vec<&str> = [
        (s.calibration.is_some(), "--calibration"),
        (s.mass_model.is_some(), "--mass-model"),
        (
            s.resonance != robimu_model::effects::resonance::Mode::default(),
            "--resonance-hz/--resonance-zeta",
        ),
        (
            !matches!(s.noise_model.as_str(), "auto" | "white"),
            "--noise-model FILE",
        ),
    ]
    .into_iter()
    .filter_map(|(g, n)| g.then_some(n))
    .collect();
    if !given.is_empty() {
        bail!(
            "{}: not for a pose session (its diagnosis takes --out, --alpha and --candidates; \
             the IMU noise is white with session.toml's σ)",
            given.join(", ")
        );
    }
    if !(s.alpha > 0.0 && s.alpha < 1.0) {
        bail!("--alpha must be in (0, 1) (got {})", s.alpha);
    }
    Ok(())
}

/// The diagnosis.json document of a pose diagnosis.
pub fn pose_diagnosis_json(d: &PoseDiagnosis) -> serde_json::Value {
    let c = &d.calibration;
    serde_json::json!({
        "format": "robimu-diagnosis/1",
        "source": "poses",
        "threshold": d.threshold,
        "candidates": d.candidates,
        "noise_choice": "white",
        "effects_found": d.found,
        "final_effect_specs": d.found.iter().map(|f| f.name.clone()).collect::<Vec<_>>(),
        "last_scores": d.last_scores,
        "rejected": d.rejected,
        "not_applicable": d.not_applicable,
        "refit": REFIT_NOT_DONE,
        "residual_rms_before": (0..6).map(|k| c.imu_rms[k] / d.sigma_z[k]).collect::<Vec<_>>(),
        "baseline_model": {
            "names": c.names,
            "units": c.units,
            "x": c.x,
            "sigma": c.sigma,
        },
    })
}

/// Write OUT/diagnosis.json; its path.
pub fn write_pose_diagnosis(d: &PoseDiagnosis, out: &Path) -> Result<PathBuf, PipelineError> {
    let path = out.join("diagnosis.json");
    (|| -> anyhow::Result<()> {
        let text = serde_json::to_string_pretty(&pose_diagnosis_json(d))?;
        std::fs::write(&path, text).with_context(|| format!("cannot write {}", path.display()))
    })()
    .map_err(PipelineError::write)?;
    Ok(path)
}

/// The summary `robimu diagnose` prints.
pub struct PoseDiagnosisSummary<'a>(pub &'a PoseDiagnosis);

impl fmt::Display for PoseDiagnosisSummary<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let d = self.0;
        writeln!(
            f,
            "pose session: {} IMU-side effects scored (Bonferroni threshold {:.1e}); not \
             applicable: {}",
            d.candidates,
            d.threshold,
            d.not_applicable
                .iter()
                .map(|n| n.name.as_str())
                .collect::<Vec<_>>()
                .join(", ")
        )?;
        for e in &d.found {
            writeln!(
                f,
                "found {}: score χ²_{} = {:.1}, p = {:.2e}{}",
                e.name,
                e.dof,
                e.statistic,
                e.p_value,
                if e.ambiguous_with.is_empty() {
                    String::new()
                } else {
                    format!(" (ambiguous with {})", e.ambiguous_with.join(", "))
                }
            )?;
            for p in &e.parameters {
                writeln!(
                    f,
                    "  {} = {:.4e} ± {:.1e} {}",
                    p.name, p.value, p.sigma, p.unit
                )?;
            }
        }
        for r in &d.rejected {
            writeln!(f, "rejected {}: {}", r.name, r.reason)?;
        }
        if d.found.is_empty() {
            writeln!(f, "no effect significant")?;
        }
        for s in &d.last_scores {
            writeln!(
                f,
                "  score {}: χ²_{} = {:.2}, p = {:.3}",
                s.name, s.dof, s.statistic, s.p_value
            )?;
        }
        writeln!(f, "refit: {REFIT_NOT_DONE}")
    }
}
