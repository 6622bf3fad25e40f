//! Calibrate an IMU from a pose stream (MODEL.md §10): its §3 intrinsics,
//! its position p_I on the posed body B, τ and gravity, from pose samples
//! of B in W and IMU samples.
//!
//! [`calibrate_poses`]: fit the pose spline to the poses, find τ and the
//! sensor rotations from the data (the start-up, [`Startup`]), then solve the MAP problem
//! ([`robimu_solver::PoseProblem`]) by Levenberg–Marquardt; the covariance
//! of x is the Schur complement's inverse (paper (24)); then a score test
//! of a constant τ over the recording (`tau_drift.rs`, [`TauDrift`]).
//! [`simulate`] makes sessions with known truth. Several IMUs on the body
//! (MODEL.md §9): [`calibrate_pose_imus_with`], one spline and g for all,
//! each IMU's start-up and τ test its own (`imus.rs`).

pub mod diagnose;
pub(crate) mod imus;
pub(crate) mod inject;
pub(crate) mod memo;
pub(crate) mod mount;
pub mod noise;
pub(crate) mod refit;
pub(crate) mod score;
pub mod simulate;
pub(crate) mod startup;
pub(crate) mod tau_drift;
#[cfg(test)]
mod tests;

use robimu_model::geom::matrix_from_quat;
use robimu_model::{PoseMeasurements, PoseSplineError};
use robimu_solver::{
    IterationRecord, LmOptions, PoseData, PoseImuData, PoseProblem, PoseProblemError,
};

pub use imus::{draw_pose_imus_truth, simulate_pose_imus, ImuSamples, PoseImuFit};
pub use noise::NoiseLevels;
pub use simulate::{
    draw_pose_truth, random_pose_motion, simulate_pose_session, ImuTiming, PoseNoise,
};
use startup::greater;
pub use startup::Startup;
pub use tau_drift::TauDrift;

/// Why a pose calibration failed.
#[derive(Debug, thiserror::Error)]
pub enum PoseCalibrationError {
    /// The measurements or options are unusable.
    #[error("pose calibration input: {0}")]
    Input(String),
    /// The pose spline could not be fitted.
    #[error("fitting the pose spline: {0}")]
    Fit(#[from] PoseSplineError),
    /// τ or the sensor rotations could not be found.
    #[error("pose calibration start-up: {0}")]
    Startup(String),
    /// The problem could not be evaluated.
    #[error(transparent)]
    Problem(#[from] PoseProblemError),
    /// The solver failed.
    #[error("pose calibration solver: {0}")]
    Solver(String),
}

/// The σ stop of the pose calibration ([`LmOptions::sigma_tolerance`]):
/// the solve ends after a step of under 0.1 conditional σ in every unknown
/// (Gauss–Newton's steps then shrink about tenfold per iteration here, so
/// the point is about 0.01 σ from the minimum; the joint-angle calibration
/// leaves the σ stop off).
const SIGMA_TOLERANCE: f64 = 0.1;

/// Options of [`calibrate_poses`].
#[derive(Debug, Clone)]
pub struct PoseCalibrationOptions {
    /// Pose position noise σ_p (m).
    pub sigma_p: f64,
    /// Pose rotation noise σ_r (rad).
    pub sigma_r: f64,
    /// IMU noise σ per channel [ax, ay, az (m/s²), gx, gy, gz (rad/s)].
    pub sigma_z: [f64; 6],
    /// Knot spacing of the pose spline (s); default max(1.5 / pose rate,
    /// 0.05 s) for one IMU, max(1.125 / pose rate, 0.05 s) for several
    /// (`default_knot_spacing_for`): fine enough that the spline's
    /// approximation of a hand-held motion stays below the IMU noise (at
    /// 2 / pose rate, 15 Hz poses and rates of hundreds of °/s, it biased τ
    /// by a few σ in simulation).
    pub knot_spacing: Option<f64>,
    /// τ is searched within ±this (s).
    pub tau_search: f64,
    /// Identify the noise levels from the residuals and refit with them
    /// ([`noise`]); false: σ as given.
    pub identify_noise: bool,
    /// Levenberg–Marquardt settings.
    pub lm: LmOptions,
    /// The session's mount priors by IMU (`[imu.mount]`, `[imu<j>.mount]`)
    /// over MODEL.md §10's ([`mount`]).
    pub mounts: std::collections::BTreeMap<usize, robimu_session::MountPrior>,
}

impl Default for PoseCalibrationOptions {
    /// σ_p = 1 mm, σ_r = 0.005 rad, the §6 IMU noise, τ within ±5 s.
    fn default() -> Self {
        let d = std::f64::consts::PI / 180.0;
        Self {
            sigma_p: 1e-3,
            sigma_r: 5e-3,
            sigma_z: [0.38, 0.21, 0.19, 0.32 * d, 0.47 * d, 0.57 * d],
            knot_spacing: None,
            tau_search: 5.0,
            identify_noise: true,
            lm: LmOptions {
                max_iterations: 50,
                sigma_tolerance: SIGMA_TOLERANCE,
                ..LmOptions::default()
            },
            mounts: Default::default(),
        }
    }
}

/// The result of [`calibrate_poses`].
#[derive(Debug, Clone)]
pub struct PoseCalibration {
    /// Names of x (§10 order).
    pub names: Vec<String>,
    /// Units of x.
    pub units: Vec<&'static str>,
    /// The estimate x.
    pub x: Vec<f64>,
    /// Standard deviations √diag(Σ_x).
    pub sigma: Vec<f64>,
    /// The marginal covariance of x (30 × 30 for one IMU), row-major.
    pub covariance: Vec<Vec<f64>>,
    /// The prior means used (the sensor rotations' from the start-up).
    pub prior_mean: Vec<f64>,
    /// The prior standard deviations used (π for the sensor rotations: no
    /// informative prior).
    pub prior_sigma: Vec<f64>,
    /// Residual RMS of IMU 0's used samples per channel [ax … gz].
    pub imu_rms: [f64; 6],
    /// Residual RMS of the pose samples: position (m), rotation (rad).
    pub pose_rms: [f64; 2],
    /// IMU 0's samples in the fit.
    pub imu_used: usize,
    /// Levenberg–Marquardt iterations.
    pub iterations: usize,
    /// Why Levenberg–Marquardt stopped.
    pub termination: String,
    /// Whether that is convergence.
    pub converged: bool,
    /// Final cost ½‖r‖².
    pub cost: f64,
    /// The final solve's run (after a refit with identified σ, the
    /// refit's: the one `iterations`, `termination` and `cost` describe).
    pub summary: robimu_solver::LmSummary,
    /// Knot spacing used (s).
    pub knot_spacing: f64,
    /// What the start-up found (IMU 0).
    pub startup: Startup,
    /// The score test of IMU 0's constant τ (docs/model.md §7.9, *time
    /// offset*); `None` when it could not be formed.
    pub tau_drift: Option<TauDrift>,
    /// The noise levels given, identified and used ([`noise`]).
    pub noise: NoiseLevels,
    /// IMU j ≥ 1's start-up, residuals and τ test at `more[j − 1]`.
    pub more: Vec<PoseImuFit>,
}

/// Checks of the measurements; the rotations as matrices.
fn checked(data: &PoseMeasurements) -> Result<Vec<robimu_model::geom::M3>, PoseCalibrationError> {
    let bad = |m: &str| Err(PoseCalibrationError::Input(m.to_string()));
    let n = data.pose_t.len();
    if data.pose_p.len() != n || data.pose_q.len() != n {
        return bad("pose_t, pose_p and pose_q differ in length");
    }
    if n < 8 {
        return bad("too few pose samples (need ≥ 8)");
    }
    if data.pose_t.windows(2).any(|w| !greater(w[1], w[0])) {
        return bad("pose times must be finite and increasing");
    }
    imus::check_imu(&data.imu_t, &data.imu_z, "IMU 0")?;
    Ok(data.pose_q.iter().map(|q| matrix_from_quat(*q)).collect())
}

/// The pose spline's default knot spacing (s) for one IMU and poses
/// stamped `pose_t` (at least two): max(1.5 / pose rate, 0.05 s)
/// ([`PoseCalibrationOptions::knot_spacing`]).
pub(crate) fn default_knot_spacing(pose_t: &[f64]) -> f64 {
    default_knot_spacing_for(pose_t, 1)
}

/// Pose intervals per knot interval of the default spacing: one IMU,
/// several IMUs (docs/model.md §7.9, *Several IMUs*).
const POSES_PER_KNOT: [f64; 2] = [1.5, 1.125];

/// The default knot spacing for `n_imus` IMUs: max(1.5 / pose rate,
/// 0.05 s) for one, max(1.125 / pose rate, 0.05 s) for several. The
/// spline's approximation error is a timing error common to every
/// gyroscope: with two IMUs on 1.5 / rate it biased τ by 0.72 σ_τ RMS on
/// noise-free sessions (one IMU: 0.40), on 1.125 / rate by 0.18.
pub(crate) fn default_knot_spacing_for(pose_t: &[f64], n_imus: usize) -> f64 {
    let n = pose_t.len();
    let rate = (n - 1) as f64 / (pose_t[n - 1] - pose_t[0]);
    (POSES_PER_KNOT[usize::from(n_imus > 1)] / rate).max(0.05)
}

/// The pose spline at `opts`' knot spacing, else the default for
/// `n_imus`; a default for several IMUs that the poses cannot carry (a
/// knot interval without enough poses) falls back to one IMU's (`check`'s
/// convention test fits the same, [`memo`]).
pub(crate) fn fit_spline(
    data: &PoseMeasurements,
    opts: &PoseCalibrationOptions,
    n_imus: usize,
    stage: &mut impl FnMut(&str),
) -> Result<(robimu_model::PoseSpline, f64), PoseCalibrationError> {
    let (t, n) = (&data.pose_t, data.pose_t.len());
    let fit = |h: f64| memo::fit(t, &data.pose_p, &data.pose_q, h);
    let spacing = match opts.knot_spacing {
        Some(h) => h,
        None => default_knot_spacing_for(t, n_imus),
    };
    if !(spacing.is_finite() && spacing > 0.0) {
        return Err(PoseCalibrationError::Input(format!(
            "knot spacing {spacing} s"
        )));
    }
    stage(&format!(
        "fitting the pose spline ({n} poses, knots every {spacing:.3} s)"
    ));
    match fit(spacing) {
        Err(_) if opts.knot_spacing.is_none() && n_imus > 1 => {
            let h = default_knot_spacing(t);
            stage(&format!("the poses do not carry it: knots every {h:.3} s"));
            Ok((fit(h)?, h))
        }
        r => Ok((r?, spacing)),
    }
}

/// Calibrate an IMU from a pose session (module doc).
pub fn calibrate_poses(
    data: &PoseMeasurements,
    opts: &PoseCalibrationOptions,
) -> Result<PoseCalibration, PoseCalibrationError> {
    calibrate_poses_with(data, opts, |_| {}, |_| {})
}

/// [`calibrate_poses`], saying what it does: `stage` at the start of each
/// stage (the spline fit, the start-up, the solve), `iteration` after each
/// Levenberg–Marquardt iteration.
pub fn calibrate_poses_with(
    data: &PoseMeasurements,
    opts: &PoseCalibrationOptions,
    stage: impl FnMut(&str),
    iteration: impl FnMut(&IterationRecord),
) -> Result<PoseCalibration, PoseCalibrationError> {
    calibrate_pose_imus_with(data, &[], opts, stage, iteration)
}

/// [`calibrate_poses_with`] with IMU 0 in `data` and IMU j ≥ 1's samples
/// in `more[j − 1]` (MODEL.md §9, §10): x is IMU 0's 30 then each further
/// IMU's 28, named `imu<j>/<name>`.
pub fn calibrate_pose_imus_with(
    data: &PoseMeasurements,
    more: &[ImuSamples],
    opts: &PoseCalibrationOptions,
    stage: impl FnMut(&str),
    iteration: impl FnMut(&IterationRecord),
) -> Result<PoseCalibration, PoseCalibrationError> {
    Ok(fit_poses(data, more, opts, stage, iteration)?.0)
}

/// The solved problem behind a [`PoseCalibration`] (for the score tests
/// of [`diagnose`]).
pub(crate) struct PoseFit {
    /// The problem, its selection that of `theta`.
    pub problem: PoseProblem,
    /// The MAP estimate θ.
    pub theta: Vec<f64>,
    /// The undamped Gauss–Newton matrix at θ, factored.
    pub factor: robimu_solver::ArrowFactor,
}

/// [`calibrate_poses_with`] and the solved problem.
pub(crate) fn fit_poses(
    data: &PoseMeasurements,
    more: &[ImuSamples],
    opts: &PoseCalibrationOptions,
    mut stage: impl FnMut(&str),
    iteration: impl FnMut(&IterationRecord),
) -> Result<(PoseCalibration, PoseFit), PoseCalibrationError> {
    let pose_r = checked(data)?;
    for (j, m) in more.iter().enumerate() {
        imus::check_imu(&m.t, &m.z, &format!("IMU {}", j + 1))?;
    }
    let (spline, spacing) = fit_spline(data, opts, 1 + more.len(), &mut stage)?;
    stage("start-up: tau and the sensor rotations from the data");
    let mut starts = vec![startup::startup(
        &spline,
        &data.imu_t,
        &data.imu_z,
        opts.tau_search,
    )?];
    for m in more {
        starts.push(startup::startup(&spline, &m.t, &m.z, opts.tau_search)?);
    }
    let (specs, x0) = imus::specs_and_start(&starts, &opts.mounts);
    let nx = specs.len();
    let more_data: Vec<PoseImuData> = more
        .iter()
        .map(|m| PoseImuData {
            imu_t: m.t.clone(),
            imu_z: m.z.clone(),
            sigma_z: opts.sigma_z,
        })
        .collect();
    let pdata = PoseData {
        pose_t: data.pose_t.clone(),
        pose_p: data.pose_p.clone(),
        pose_r,
        imu_t: data.imu_t.clone(),
        imu_z: data.imu_z.clone(),
        sigma_p: opts.sigma_p,
        sigma_r: opts.sigma_r,
        sigma_z: opts.sigma_z,
        prior_mean: specs.iter().map(|s| s.nominal).collect(),
        prior_sigma: specs.iter().map(|s| s.sigma).collect(),
    };
    let mut problem = PoseProblem::with_imus(spline, pdata, more_data)?;
    let mut theta = vec![0.0; problem.n_band()];
    theta.extend(x0);
    stage(&format!(
        "solving: tau = {:.4} s from the start-up (correlation {:.3})",
        starts[0].tau, starts[0].correlation
    ));
    // every IMU's τ score test, beside the noise identification
    let tau_tests = |p: &PoseProblem, theta: &[f64], f: &robimu_solver::ArrowFactor| {
        (0..p.n_imus())
            .map(|j| tau_drift::tau_drift(p, j, theta, f))
            .collect::<Result<Vec<_>, _>>()
    };
    let (sol, noise, drifts) = noise::solve_identified(
        &mut problem,
        theta,
        (&opts.lm, opts.identify_noise),
        &mut stage,
        iteration,
        tau_tests,
    )?;
    let mut drifts = drifts?.into_iter();
    let cov = sol.factor.covariance_x();
    let x = problem.x(&sol.theta).to_vec();
    let (imu_rms, pose_rms) = (noise.imu_rms(0), noise.pose_rms());
    let tau_drift0 = drifts.next().flatten();
    let mut fits = Vec::with_capacity(more.len());
    for ((j, st), drift) in (1..).zip(starts.drain(1..)).zip(drifts) {
        fits.push(PoseImuFit {
            startup: st,
            imu_rms: noise.imu_rms(j),
            imu_used: problem.selected_of(j).len(),
            tau_drift: drift,
        });
    }
    let st = starts.remove(0);
    let cal = PoseCalibration {
        names: specs.iter().map(|s| s.name.clone()).collect(),
        units: specs.iter().map(|s| s.unit).collect(),
        sigma: (0..nx).map(|k| cov[(k, k)].max(0.0).sqrt()).collect(),
        covariance: (0..nx)
            .map(|k| (0..nx).map(|l| cov[(k, l)]).collect())
            .collect(),
        prior_mean: specs.iter().map(|s| s.nominal).collect(),
        prior_sigma: specs.iter().map(|s| s.sigma).collect(),
        x,
        imu_rms,
        pose_rms,
        imu_used: problem.selected().len(),
        iterations: sol.summary.iterations.len(),
        termination: sol.summary.termination.to_string(),
        converged: sol.summary.termination.converged(),
        cost: sol.summary.final_cost,
        summary: sol.summary.clone(),
        knot_spacing: spacing,
        startup: st,
        tau_drift: tau_drift0,
        noise,
        more: fits,
    };
    let fit = PoseFit {
        problem,
        theta: sol.theta,
        factor: sol.factor,
    };
    Ok((cal, fit))
}
