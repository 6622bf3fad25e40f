//! `robimu report`: a self-contained HTML report of a calibration result.

use std::path::{Path, PathBuf};

use anyhow::Context;
use robimu_model::observations::Measurements;
use robimu_model::{ParamLayout, Robot};
use robimu_report::convergence::{convergence_path, ConvergenceLog};
use robimu_report::figures::NoiseBand;
use robimu_report::html::{calibration_report_imus, Convergence, ReportError, SessionSeries};
use robimu_session::result::CalibrationResult;
use robimu_session::Session;
use robimu_workflows::calibrate::choose_knots;

use super::input::session_robot;

/// Write an HTML report of a calibration result.
///
/// One self-contained page (inline CSS, figures as inline SVG, no scripts,
/// no external links): the parameter table, posterior σ against the prior
/// σ, convergence (from NAME.convergence.csv next to NAME.json, written by
/// `robimu calibrate`; the page says so when it is missing) and, when the
/// session is found, the joint trajectory and the IMU residuals over time.
/// The figures are also written as PNG and SVG. A result of several IMUs
/// (docs/model.md §9) has its table and σ bars grouped by IMU and one
/// residual figure per IMU.
#[derive(Debug, Clone, clap::Args)]
pub struct ReportCmd {
    /// Result file (result.json, docs/model.md §8).
    pub result: PathBuf,
    /// Directory to write report.html and the figures to [default: `report`
    /// next to the result file].
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Session directory for the trajectory and residual plots [default: the
    /// session named in the result, when it exists].
    #[arg(long)]
    pub session: Option<PathBuf>,
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
pub fn series_for(
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
                &NoiseBand::of_fit(result.noise_model.as_ref(), &sigma_z),
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
fn convergence_history(result: &Path) -> anyhow::Result<Result<Vec<f64>, String>> {
    let path = convergence_path(result);
    if path.is_file() {
        return Ok(Ok(ConvergenceLog::read(&path)?.costs()));
    }
    Ok(Err(format!(
        "the solver's iteration history {} is missing (`robimu calibrate` writes it next to the result file; results written before it did, or copied without it, have none)",
        path.display()
    )))
}

impl ReportCmd {
    /// Write the report.
    pub fn run(self) -> anyhow::Result<()> {
        let result = CalibrationResult::read(&self.result)?;
        let dir = self.out.clone().unwrap_or_else(|| {
            self.result
                .parent()
                .unwrap_or(Path::new("."))
                .join("report")
        });
        let session_dir = self.session.clone().or_else(|| {
            result
                .session
                .as_ref()
                .map(PathBuf::from)
                .filter(|d| d.is_dir())
        });
        let session = match &session_dir {
            Some(d) => Some(
                Session::load(d)
                    .with_context(|| format!("cannot load the session {}", d.display()))?,
            ),
            None => None,
        };
        let series = match &session {
            Some(s) => series_for(s, &result)?,
            None => Vec::new(),
        };
        let truth = session.as_ref().and_then(|s| s.truth.as_ref());
        let history = convergence_history(&self.result)?;
        let convergence = match &history {
            Ok(costs) => Convergence::Costs(costs),
            Err(why) => Convergence::Unavailable(why),
        };
        let path = calibration_report_imus(&dir, &result, truth, convergence, &series)?;
        println!("wrote {}", path.display());
        Ok(())
    }
}
