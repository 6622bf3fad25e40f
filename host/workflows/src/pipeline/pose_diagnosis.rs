//! `robimu diagnose` of a session with tool poses (docs/model.md §7.9):
//! the session read and checked as `robimu calibrate` does, the
//! diagnosis of [`crate::pose_calibrate::diagnose`], its summary and
//! diagnosis.json (format `robimu-diagnosis/1`, the joint path's records,
//! with `"source": "poses"`).

use std::fmt;
use std::path::{Path, PathBuf};

use anyhow::{bail, Context};

use super::poses::{load_pose_session, pose_options};
use super::{DiagnoseSettings, PipelineError};
use crate::pose_calibrate::diagnose::{diagnose_poses, PoseDiagnoseOptions, PoseDiagnosis};

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
    if session.n_imus() > 1 {
        warn(format!(
            "diagnosing IMU 0 of {} (a pose session's further IMUs are not diagnosed)",
            session.n_imus()
        ));
    }
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
fn pose_diagnosis_json(d: &PoseDiagnosis) -> serde_json::Value {
    let c = &d.calibration;
    let f = d.final_calibration.as_ref().unwrap_or(c);
    let model = |c: &crate::pose_calibrate::PoseCalibration| {
        serde_json::json!({
            "names": c.names,
            "units": c.units,
            "x": c.x,
            "sigma": c.sigma,
        })
    };
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
        "residual_rms_before": (0..6).map(|k| c.imu_rms[k] / d.sigma_z[k]).collect::<Vec<_>>(),
        "residual_rms_after": (0..6).map(|k| f.imu_rms[k] / d.sigma_z[k]).collect::<Vec<_>>(),
        "baseline_model": model(c),
        "final_model": model(f),
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
                "found {}: score χ²_{} = {:.1}, p = {:.2e}; refit LR = {:.1}, p = {:.2e}{}",
                e.name,
                e.dof,
                e.statistic,
                e.p_value,
                e.lr_statistic,
                e.lr_p_value,
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
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pipeline::pose_simulate::{simulate_pose_dir, PoseSessionSpec};
    use crate::pose_calibrate::ImuTiming;

    /// `simulate --source poses --effect sensor_delay=5` written and read
    /// back, diagnosed as `robimu diagnose` does: diagnosis.json names the
    /// delay, confirmed by its refit, with its estimate within 4σ of 5 ms;
    /// the joint flags are refused.
    #[test]
    fn a_written_session_with_a_delay_is_diagnosed_into_diagnosis_json() {
        let tmp = tempfile::tempdir().unwrap();
        let dir = tmp.path().join("s");
        simulate_pose_dir(&PoseSessionSpec {
            out: dir.clone(),
            duration: 40.0,
            seed: 11,
            pose_rate: 15.0,
            pose_jitter: 0.003,
            imu_rate: 100.0,
            robot: None,
            imu_timing: ImuTiming::default(),
            imus: 1,
            effects: vec!["sensor_delay=5".into()],
        })
        .unwrap();
        let mut settings = DiagnoseSettings::new(tmp.path().join("out"));
        let d = diagnose_pose_session(&dir, &settings, |_| {}, |_| {}).unwrap();
        let path = write_pose_diagnosis(&d, &settings.out).unwrap();
        let json: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap();
        assert_eq!(json["format"], "robimu-diagnosis/1");
        assert_eq!(json["source"], "poses");
        assert!(json["effects_found"][0]["lr_p_value"].as_f64().unwrap() < d.threshold);
        let found = &json["effects_found"][0];
        assert_eq!(found["name"], "sensor_delay", "{json:#}");
        assert!(found["p_value"].as_f64().unwrap() < d.threshold);
        let p = &found["parameters"][0];
        let (v, s) = (p[2].as_f64().unwrap(), p[3].as_f64().unwrap());
        assert!((v - 0.005).abs() < 4.0 * s, "δ = {v} ± {s} s");
        settings.mass_model = Some("m.toml".into());
        let e = diagnose_pose_session(&dir, &settings, |_| {}, |_| {}).unwrap_err();
        assert!(e.to_string().contains("--mass-model"), "{e}");
    }
}
