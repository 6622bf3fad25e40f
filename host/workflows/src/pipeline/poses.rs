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
//!   within 0.67–[`POSE_RMS_MAX`]: outside, the σ do not fit the data
//!   (*doubtful*), and the σ the residuals suggest are given for
//!   `session.toml`. The upper bound is tighter than the joint path's 1.5:
//!   the pose calibration does not identify its noise, so a σ taken 1.5×
//!   too small would leave every σ of x 1.5× too small;
//! * **undetermined** — parameters with an informative prior whose
//!   posterior σ is above 0.9 of it: listed, not a reason for doubt;
//! * **plausible** — estimates more than 4 prior σ from the prior mean,
//!   where the prior is informative (not the sensor rotations, whose
//!   prior σ is π): *doubtful*;
//! * **time offset** — a score test of a constant τ over the recording
//!   ([`TauDrift`](crate::TauDrift), docs/model.md §7.9): p below 0.01 is
//!   *doubtful*.

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

/// The largest whitened residual RMS of a good pose calibration. With
/// the right σ it is about 0.95 for the IMU channels (the spline takes
/// some of the noise; 60 s, 15 Hz poses, 100 Hz IMU) and 0.87–1.01 for
/// the poses; σ taken too small by more than 1.15/0.95 ≈ 20 % make the
/// σ of x too small by as much (the Monte Carlo's bound is 15 %).
pub(crate) const POSE_RMS_MAX: f64 = 1.15;

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
        verdict: Some(pose_verdict(opts, cal, dir)),
        effects: None,
        model_tests: None,
        pose_accuracy: None,
        covariance_kind: None,
    }
}

/// The IMU residual RMS per channel over σ_z.
fn whitened_imu_rms(opts: &PoseCalibrationOptions, cal: &PoseCalibration) -> [f64; 6] {
    std::array::from_fn(|c| cal.imu_rms[c] / opts.sigma_z[c])
}

/// The verdict on a pose calibration (module doc).
fn pose_verdict(opts: &PoseCalibrationOptions, cal: &PoseCalibration, dir: &Path) -> VerdictRecord {
    let checks = vec![
        VerdictCheck {
            topic: "converged".into(),
            ok: cal.converged,
            text: format!("{} after {} iterations", cal.termination, cal.iterations),
        },
        residuals(opts, cal),
        undetermined(cal),
        plausible(cal),
        crate::pose_calibrate::tau_drift::verdict_check(cal.tau_drift.as_ref()),
    ];
    let mut verdict = crate::verdict::record(checks, !cal.converged);
    verdict.next_steps = pose_next_steps(&verdict, dir);
    verdict
}

/// What to do about each failed check, as commands or edits to paste
/// (`dir` is the session). A τ that wanders also inflates the residuals:
/// then the timing comes first, and no σ is suggested.
fn pose_next_steps(verdict: &VerdictRecord, dir: &Path) -> Vec<String> {
    let dir = dir.display();
    let failed = |topic: &str| verdict.checks.iter().any(|c| c.topic == topic && !c.ok);
    let mut steps = Vec::new();
    if failed("converged") {
        steps.push(format!(
            "find what keeps the fit from converging: robimu check {dir}"
        ));
    }
    if failed("time offset") {
        steps.push(
            "stamp the IMU's samples where they are taken (the board's own clock, as \
             `robimu record` does) instead of on arrival at the PC, or record with the IMU \
             and the pose source on one clock; then record again"
                .into(),
        );
    } else if failed("residuals") {
        steps.push(format!(
            "put the σ the residuals suggest (the residuals check) in {dir}/session.toml's \
             [noise] and [poses] tables and calibrate again"
        ));
    }
    if failed("plausible") {
        steps.push(format!(
            "check the units and the pose convention: robimu check {dir} (positions in mm \
             need --units mm at the import; the inverse rotation --conjugate or --inverse)"
        ));
    }
    steps
}

/// The whitened RMS of the IMU channels and the poses, within
/// [`RMS_RANGE`]`.0`–[`POSE_RMS_MAX`]; outside, the σ the residuals
/// suggest.
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
        .filter(|(_, v)| !(RMS_RANGE.0..=POSE_RMS_MAX).contains(*v))
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
            "whitened RMS outside {}–{POSE_RMS_MAX}: {} (the σ of session.toml's [poses] and \
             [noise] do not fit the data; the residuals suggest {}); all: {all}",
            RMS_RANGE.0,
            outside.join(", "),
            suggested_sigma(cal)
        )
    };
    VerdictCheck {
        topic: "residuals".into(),
        ok: outside.is_empty(),
        text,
    }
}

/// session.toml's σ as the residuals' RMS give them (a little small: the
/// spline takes some of the noise).
fn suggested_sigma(cal: &PoseCalibration) -> String {
    let z: Vec<String> = cal.imu_rms.iter().map(|v| format!("{v:.3e}")).collect();
    format!(
        "[noise] sigma_z = [{}], [poses] sigma_p = {:.3e}, sigma_r = {:.3e}",
        z.join(", "),
        cal.pose_rms[0],
        cal.pose_rms[1]
    )
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

    /// A 40 s simulated session calibrated with the IMU's σ taken as
    /// given and 1.3× too small: good with the right σ; doubtful with the
    /// wrong ones, naming the channels and suggesting σ within 10 % of the
    /// simulation's.
    #[test]
    fn sigma_too_small_by_a_third_is_doubtful_and_the_right_sigma_suggested() {
        use crate::pose_calibrate::{
            calibrate_poses, draw_pose_truth, random_pose_motion, simulate_pose_session,
            PoseNoise as SimNoise,
        };
        let truth = draw_pose_truth(7);
        let motion = random_pose_motion(40.0, 8).unwrap();
        let noise = SimNoise::default();
        let data = simulate_pose_session(&truth, &motion, 15.0, 0.003, 100.0, &noise, 9).unwrap();
        let right = PoseCalibrationOptions::default();
        let cal = calibrate_poses(&data, &right).unwrap();
        let check = residuals(&right, &cal);
        assert!(check.ok, "{}", check.text);
        let wrong = PoseCalibrationOptions {
            sigma_z: noise.sigma_z.map(|s| s / 1.3),
            ..right
        };
        let cal = calibrate_poses(&data, &wrong).unwrap();
        let check = residuals(&wrong, &cal);
        assert!(!check.ok, "{}", check.text);
        assert!(check.text.contains("ax 1.2"), "{}", check.text);
        for (c, s) in noise.sigma_z.iter().enumerate() {
            let suggested = cal.imu_rms[c];
            assert!(
                (suggested / s - 1.0).abs() < 0.1,
                "channel {c}: {suggested} against {s}"
            );
            assert!(
                check.text.contains(&format!("{suggested:.3e}")),
                "{}",
                check.text
            );
        }
        let verdict = pose_verdict(&wrong, &cal, Path::new("s"));
        assert_eq!(verdict.trust, robimu_session::result::Trust::Doubtful);
        assert_eq!(verdict.next_steps.len(), 1, "{:?}", verdict.next_steps);
        assert!(verdict.next_steps[0].contains("s/session.toml's [noise]"));
    }
}
