//! `robimu calibrate` of a session with tool poses (docs/model.md §7.9,
//! MODEL.md §10): the session read and checked, its σ from `session.toml`
//! or the defaults, [`calibrate_poses`], and the result file of
//! docs/model.md §8 with `"source": "poses"` and a verdict.
//!
//! The verdict's checks, as the joint calibration's ([`crate::verdict`]):
//!
//! * **converged** — Levenberg–Marquardt's termination; not converged is *bad*;
//! * **residuals** — the RMS of the whitened residuals of each IMU channel
//!   (residual / σ_z) and of the poses (position / σ_p, rotation / σ_r)
//!   within 0.67–1.5: outside, the σ do not fit the data (*doubtful*);
//! * **undetermined** — parameters with an informative prior whose
//!   posterior σ is above 0.9 of it: listed, not a reason for doubt;
//! * **plausible** — estimates more than 4 prior σ from the prior mean,
//!   where the prior is informative (not the sensor rotations, whose
//!   prior σ is π): *doubtful*.

use std::path::Path;

use robimu_session::result::{
    CalibrationResult, CovarianceMatrix, NoiseModelRecord, ParameterResult, VerdictCheck,
    VerdictRecord, RESULT_FORMAT,
};
use robimu_session::{PoseSession, PoseSessionMeta, SOURCE_POSES};

use super::{fatal_findings, FitEvent, PipelineError};
use crate::check::{check_pose_session, Severity};
use crate::pose_calibrate::{calibrate_poses_with, PoseCalibration, PoseCalibrationOptions};
use crate::verdict::{IMPLAUSIBLE, RMS_RANGE, UNDETERMINED};

/// A prior σ at or above this (rad) is no information: the sensor
/// rotations' (π).
const UNINFORMATIVE: f64 = 3.0;

/// A calibrated pose session ([`calibrate_pose_session`]).
#[derive(Debug, Clone)]
pub struct PoseFitted {
    /// The session.
    pub session: PoseSession,
    /// The options the calibration used.
    pub options: PoseCalibrationOptions,
    /// The calibration.
    pub cal: PoseCalibration,
    /// The result file's contents.
    pub result: CalibrationResult,
}

impl PoseFitted {
    /// Write the result file (docs/model.md §8) to `path`.
    pub fn write(&self, path: &Path) -> Result<(), PipelineError> {
        self.result
            .write(path)
            .map_err(|e| PipelineError::write(e.into()))
    }
}

/// Read the pose session in `dir` and check it as `robimu check` does
/// (warnings to `warn`; a fatal finding stops here with its message).
pub fn load_pose_session(
    dir: &Path,
    mut warn: impl FnMut(String),
) -> Result<PoseSession, PipelineError> {
    let session = PoseSession::read(dir).map_err(|e| PipelineError::input(e.into()))?;
    let report = check_pose_session(&session);
    for f in report.of(Severity::Warning) {
        warn(format!("{} ({})", f.message, f.action));
    }
    fatal_findings(&report, dir).map_err(|e| {
        PipelineError::input(anyhow::anyhow!(
            "{e}; `robimu check {}` lists every finding",
            dir.display()
        ))
    })?;
    Ok(session)
}

/// The calibration's options from `session.toml`: `[poses]` σ_p, σ_r and
/// `[noise]` σ_z where given, else [`PoseCalibrationOptions::default`]; what
/// the pose calibration does not use is said through `warn`.
pub fn pose_options(
    meta: &PoseSessionMeta,
    mut warn: impl FnMut(String),
) -> PoseCalibrationOptions {
    let mut opts = PoseCalibrationOptions::default();
    if let Some(p) = &meta.poses {
        opts.sigma_p = p.sigma_p.unwrap_or(opts.sigma_p);
        opts.sigma_r = p.sigma_r.unwrap_or(opts.sigma_r);
    }
    if let Some(z) = meta.noise.as_ref().and_then(|n| n.sigma_z) {
        opts.sigma_z = z;
    }
    if meta.noise_shape.as_ref().is_some_and(|s| s.ar_z.is_some()) {
        warn("[noise] ar_z is not used: the pose calibration assumes white IMU noise".into());
    }
    let g0 = robimu_model::pose_measurement::G0;
    if let Some(g) = meta.gravity.filter(|g| (g - g0).abs() > 1e-9) {
        warn(format!(
            "gravity = {g} is not used: the pose calibration takes g0 = {g0} m/s²"
        ));
    }
    opts
}

/// Calibrate IMU 0 of `session` (other IMUs are left out, said through
/// `report`'s first stage), reporting the stages and the solver's
/// iterations.
pub fn calibrate_pose_session(
    session: PoseSession,
    options: PoseCalibrationOptions,
    mut report: impl FnMut(FitEvent),
) -> Result<PoseFitted, PipelineError> {
    if session.n_imus() > 1 {
        report(FitEvent::Stage(&format!(
            "calibrating IMU 0 of {} (a pose session's IMUs are calibrated one at a time)",
            session.n_imus()
        )));
    }
    let data = session.measurements();
    let report = std::cell::RefCell::new(report);
    let cal = calibrate_poses_with(
        &data,
        &options,
        |s| (report.borrow_mut())(FitEvent::Stage(s)),
        |r| (report.borrow_mut())(FitEvent::Iteration(r)),
    )
    .map_err(|e| PipelineError::fit(e.into()))?;
    let result = pose_result(&session.dir, &options, &cal);
    Ok(PoseFitted {
        session,
        options,
        cal,
        result,
    })
}

/// The result file of a pose calibration (docs/model.md §8): the 30
/// parameters, their covariance, `"source": "poses"`, the solver's run,
/// the whitened residual RMS and the verdict.
fn pose_result(
    dir: &Path,
    opts: &PoseCalibrationOptions,
    cal: &PoseCalibration,
) -> CalibrationResult {
    let parameters = (0..cal.x.len())
        .map(|k| ParameterResult {
            name: cal.names[k].clone(),
            unit: cal.units[k].to_string(),
            value: cal.x[k],
            prior: cal.prior_mean[k],
            prior_sigma: cal.prior_sigma[k],
            sigma: cal.sigma[k],
            frozen: false,
        })
        .collect();
    CalibrationResult {
        format: RESULT_FORMAT.into(),
        parameters,
        covariance: CovarianceMatrix {
            names: cal.names.clone(),
            matrix: cal.covariance.clone(),
        },
        robot: None,
        source: Some(SOURCE_POSES.into()),
        session: Some(dir.display().to_string()),
        priors_used: Some(true),
        tau_initial: Some(cal.startup.tau),
        knot_spacing: Some(cal.knot_spacing),
        iterations: Some(cal.iterations),
        initial_cost: None,
        final_cost: Some(cal.cost),
        termination: Some(cal.termination.clone()),
        residual_rms: Some(whitened_imu_rms(opts, cal)),
        imu_samples_used: Some(cal.imu_used),
        weak_directions: Vec::new(),
        noise_model: Some(NoiseModelRecord::White),
        imu_noise_models: Vec::new(),
        noise_warning: None,
        verdict: Some(pose_verdict(opts, cal)),
        effects: None,
        model_tests: None,
        pose_accuracy: None,
    }
}

/// The IMU residual RMS per channel over σ_z.
fn whitened_imu_rms(opts: &PoseCalibrationOptions, cal: &PoseCalibration) -> [f64; 6] {
    std::array::from_fn(|c| cal.imu_rms[c] / opts.sigma_z[c])
}

/// The verdict on a pose calibration (module doc).
fn pose_verdict(opts: &PoseCalibrationOptions, cal: &PoseCalibration) -> VerdictRecord {
    let checks = vec![
        VerdictCheck {
            topic: "converged".into(),
            ok: cal.converged,
            text: format!("{} after {} iterations", cal.termination, cal.iterations),
        },
        residuals(opts, cal),
        undetermined(cal),
        plausible(cal),
    ];
    crate::verdict::record(checks, !cal.converged)
}

/// The whitened RMS of the IMU channels and the poses, within [`RMS_RANGE`].
fn residuals(opts: &PoseCalibrationOptions, cal: &PoseCalibration) -> VerdictCheck {
    let imu = whitened_imu_rms(opts, cal);
    let pose = [
        cal.pose_rms[0] / opts.sigma_p,
        cal.pose_rms[1] / opts.sigma_r,
    ];
    let names = robimu_session::IMU_COLUMNS
        .iter()
        .copied()
        .chain(["position", "rotation"]);
    let values = imu.iter().chain(&pose);
    let outside: Vec<String> = names
        .clone()
        .zip(values.clone())
        .filter(|(_, v)| !(RMS_RANGE.0..=RMS_RANGE.1).contains(*v))
        .map(|(n, v)| format!("{n} {v:.2}"))
        .collect();
    let all = names
        .zip(values)
        .map(|(n, v)| format!("{n} {v:.2}"))
        .collect::<Vec<_>>()
        .join(", ");
    let text = if outside.is_empty() {
        format!("white noise model; whitened RMS {all}")
    } else {
        format!(
            "whitened RMS outside {}–{}: {} (the σ of session.toml's [poses] and [noise] do \
             not fit the data); all: {all}",
            RMS_RANGE.0,
            RMS_RANGE.1,
            outside.join(", ")
        )
    };
    VerdictCheck {
        topic: "residuals".into(),
        ok: outside.is_empty(),
        text,
    }
}

/// Informative priors the data barely narrows (listed, not a failure).
fn undetermined(cal: &PoseCalibration) -> VerdictCheck {
    let names: Vec<&str> = (0..cal.x.len())
        .filter(|&k| {
            cal.prior_sigma[k] < UNINFORMATIVE && cal.sigma[k] > UNDETERMINED * cal.prior_sigma[k]
        })
        .map(|k| cal.names[k].as_str())
        .collect();
    VerdictCheck {
        topic: "undetermined".into(),
        ok: true,
        text: if names.is_empty() {
            "every parameter is determined by the data".into()
        } else {
            format!(
                "{} (their estimate and σ are the prior's: the motion does not determine them)",
                names.join(", ")
            )
        },
    }
}

/// Estimates more than [`IMPLAUSIBLE`] prior σ from an informative prior.
fn plausible(cal: &PoseCalibration) -> VerdictCheck {
    let far: Vec<String> = (0..cal.x.len())
        .filter(|&k| cal.prior_sigma[k] < UNINFORMATIVE)
        .map(|k| (k, (cal.x[k] - cal.prior_mean[k]) / cal.prior_sigma[k]))
        .filter(|(_, z)| z.abs() > IMPLAUSIBLE)
        .map(|(k, z)| format!("{} {z:+.1} prior σ", cal.names[k]))
        .collect();
    VerdictCheck {
        topic: "plausible".into(),
        ok: far.is_empty(),
        text: if far.is_empty() {
            format!("every estimate within {IMPLAUSIBLE} prior σ of its prior mean (rotations: no prior)")
        } else {
            format!("beyond {IMPLAUSIBLE} prior σ: {}", far.join(", "))
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use robimu_session::{NoiseOverride, PoseNoise};

    #[test]
    fn options_take_the_sessions_sigma_and_say_what_they_ignore() {
        let mut warnings = Vec::new();
        let d = PoseCalibrationOptions::default();
        let opts = pose_options(&PoseSessionMeta::default(), |w| warnings.push(w));
        assert_eq!(
            (opts.sigma_p, opts.sigma_r, opts.sigma_z),
            (d.sigma_p, d.sigma_r, d.sigma_z)
        );
        assert!(warnings.is_empty());
        let meta = PoseSessionMeta {
            gravity: Some(9.7),
            poses: Some(PoseNoise {
                sigma_p: Some(2e-4),
                sigma_r: None,
            }),
            noise: Some(NoiseOverride {
                sigma_z: Some([0.1, 0.2, 0.3, 0.01, 0.02, 0.03]),
                sigma_q: None,
            }),
            ..Default::default()
        };
        let opts = pose_options(&meta, |w| warnings.push(w));
        assert_eq!((opts.sigma_p, opts.sigma_r), (2e-4, d.sigma_r));
        assert_eq!(opts.sigma_z[5], 0.03);
        assert_eq!(warnings.len(), 1);
        assert!(warnings[0].contains("gravity = 9.7"), "{warnings:?}");
    }
}
