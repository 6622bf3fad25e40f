//! The HTML report of a result file (`robimu report`): the result, its
//! session's trajectory and residual series when the session is found, and
//! the solver's iteration history written next to it.

use std::path::{Path, PathBuf};

use anyhow::Context;
use robimu_model::observations::Measurements;
use robimu_model::{ParamLayout, Robot};
use robimu_session::result::CalibrationResult;
use robimu_session::{PoseSession, Session};
use robimu_workflows::calibrate::choose_knots;
use robimu_workflows::export::is_pose_result;
use robimu_workflows::pipeline::poses::PoseFitted;
use robimu_workflows::pipeline::{load_session, session_robot};

use crate::convergence::{convergence_path, ConvergenceLog};
use crate::figures::NoiseBand;
use crate::html::{
    calibration_report_imus, pose_calibration_report, Convergence, ReportError, SessionSeries,
};

/// Write the report of the result file `result` into `out` [default:
/// `report` next to the result file], with the series of the session in
/// `session` [default: the session the result names, when it exists]; the
/// page's path.
pub fn write_result_report(
    result: &Path,
    out: Option<&Path>,
    session: Option<&Path>,
) -> anyhow::Result<PathBuf> {
    let result_path = result;
    let result = CalibrationResult::read(result_path)?;
    let dir = out.map(Path::to_path_buf).unwrap_or_else(|| {
        result_path
            .parent()
            .unwrap_or(Path::new("."))
            .join("report")
    });
    let session_dir = session.map(Path::to_path_buf).or_else(|| {
        result
            .session
            .as_ref()
            .map(PathBuf::from)
            .filter(|d| d.is_dir())
    });
    if is_pose_result(&result) {
        return pose_result_report(result_path, &result, &dir, session_dir.as_deref());
    }
    // loaded as every command that fits a spline loads it: times checked
    let session = match &session_dir {
        Some(d) => Some(load_session(d)?.0),
        None => None,
    };
    let series = match &session {
        Some(s) => series_for(s, &result)?,
        None => Vec::new(),
    };
    let truth = session.as_ref().and_then(|s| s.truth.as_ref());
    let history = convergence_history(result_path)?;
    let convergence = match &history {
        Ok(costs) => Convergence::Costs(costs),
        Err(why) => Convergence::Unavailable(why),
    };
    Ok(calibration_report_imus(
        &dir,
        &result,
        truth,
        convergence,
        &series,
    )?)
}

/// [`write_result_report`] of a pose session's result (docs/model.md
/// §7.9, [`pose_calibration_report`]): the session read for its truth.
fn pose_result_report(
    result_path: &Path,
    result: &CalibrationResult,
    dir: &Path,
    session_dir: Option<&Path>,
) -> anyhow::Result<PathBuf> {
    let session = match session_dir {
        Some(d) => Some(PoseSession::read(d)?),
        None => None,
    };
    let history = convergence_history(result_path)?;
    let convergence = match &history {
        Ok(costs) => Convergence::Costs(costs),
        Err(why) => Convergence::Unavailable(why),
    };
    let truth = session.as_ref().and_then(|s| s.truth.as_ref());
    Ok(pose_calibration_report(
        dir,
        result,
        truth,
        convergence,
        &[],
    )?)
}

/// Write the report of a pose calibration just made (`robimu calibrate
/// --report DIR` on a pose session, docs/model.md §7.9) into `dir`: the
/// result with the final solve's convergence and each IMU's residuals
/// along the fit's pose spline ([`SessionSeries::of_pose_fit`]), the σ
/// band the fit's white σ_z; the page's path.
pub fn write_pose_fit_report(dir: &Path, fitted: &PoseFitted) -> anyhow::Result<PathBuf> {
    let cal = &fitted.cal;
    let source = if cal.noise.identified {
        "the white noise levels identified from the residuals"
    } else {
        "the white noise σ_z given"
    };
    let series = (0..cal.noise.used.sigma_z.len())
        .map(|j| {
            let tau_name = match j {
                0 => "tau".to_string(),
                _ => format!("imu{j}/tau"),
            };
            let tau = (cal.names.iter().position(|n| *n == tau_name)).map_or(0.0, |k| cal.x[k]);
            let residuals = fitted.imu_residuals(j)?;
            let sigma = &cal.noise.used.sigma_z[j];
            Ok(SessionSeries::of_pose_fit(&residuals, sigma, source, tau))
        })
        .collect::<anyhow::Result<Vec<_>>>()?;
    let costs = ConvergenceLog::from_summary(&cal.summary).costs();
    let truth = fitted.session.truth.as_ref();
    Ok(pose_calibration_report(
        dir,
        &fitted.result,
        truth,
        Convergence::Costs(&costs),
        &series,
    )?)
}

/// The series of `data` under parameters `x` for the report: the IMU
/// residuals along the joint trajectory refitted to the samples with the
/// calibration's knot spacing (`knot_spacing`; chosen from the data when
/// the result does not give it), with the σ of the fit's noise model.
pub fn session_series(
    robot: &Robot,
    data: &Measurements,
    x: &[f64],
    sigma_q: &[f64],
    knot_spacing: Option<f64>,
    noise: &NoiseBand,
) -> anyhow::Result<SessionSeries> {
    SessionSeries::check(robot, data, x)?;
    let fit = choose_knots(data, robot.dof(), sigma_q, 3, knot_spacing)
        .map_err(|e| ReportError::Session(format!("cannot fit the joint trajectory: {e}")))?;
    Ok(SessionSeries::new(robot, data, x, &fit.spline, noise)?)
}

/// The session's trajectory and residual series under `result`: one per
/// IMU of the result (docs/model.md §9), IMU j's residuals of `imu<j>.csv`
/// under its own parameters ([`CalibrationResult::imu`]).
pub(crate) fn series_for(
    session: &Session,
    result: &CalibrationResult,
) -> anyhow::Result<Vec<SessionSeries>> {
    let robot = session_robot(session)?;
    let layout = ParamLayout::new(&robot);
    let (sigma_z, sigma_q) = session.noise(&robot)?;
    let k = result.imu_count();
    if k > session.n_imus() {
        anyhow::bail!(
            "the result has {k} IMUs but the session {} has {} (imu.csv{})",
            session.dir.display(),
            session.n_imus(),
            (1..session.n_imus())
                .map(|j| format!(", imu{j}.csv"))
                .collect::<String>()
        );
    }
    let data = session.measurements();
    (0..k)
        .map(|j| {
            let view = result.imu(j).map_err(anyhow::Error::msg)?;
            let x = view.values(&layout)?;
            session_series(
                &robot,
                &data.only_imu(j),
                &x,
                &sigma_q,
                result.knot_spacing,
                &NoiseBand::of_fit(result.noise_model_of(j), &sigma_z),
            )
            .with_context(|| {
                format!(
                    "cannot plot the session {} under this result{}",
                    session.dir.display(),
                    if k == 1 {
                        String::new()
                    } else {
                        format!(" (IMU {j})")
                    }
                )
            })
        })
        .collect()
}

/// The costs of the solver's iteration history written next to `result`
/// (NAME.convergence.csv), or why the report has none (`Ok(Err(why))`).
pub(crate) fn convergence_history(result: &Path) -> anyhow::Result<Result<Vec<f64>, String>> {
    let path = convergence_path(result);
    if path.is_file() {
        return Ok(Ok(ConvergenceLog::read(&path)?.costs()));
    }
    Ok(Err(format!(
        "the solver's iteration history {} is missing (`robimu calibrate` writes it next to the result file; results written before it did, or copied without it, have none)",
        path.display()
    )))
}
