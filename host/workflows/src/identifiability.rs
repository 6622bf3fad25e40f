//! Identifiability studies of a trajectory (paper §8.2, §8.4): posterior σ
//! against trajectory length (Fig. 6), the robot length parameters against
//! speed (Fig. 8), a plan against random trajectories (Fig. 5), the
//! approximation (26) against the estimator's covariance (24), and a Monte
//! Carlo check that the predicted gain in precision is real.

use faer::Mat;
use rand::{Rng, SeedableRng};

use super::calibrate::{calibrate, CalibrateError, CalibrateOptions};
use super::plan::information::{
    covariance, lambda_max, robot_lengths, without_robot_lengths, Information, InformationError,
    Sampling,
};
use super::plan::random_uniform;
use super::simulate::{simulate, SimulateOptions};
use robimu_model::noise::NoiseModel;
use robimu_model::params::draw_truth;
use robimu_model::trajectory::random_walk;
use robimu_model::{ModelError, ParamLayout, Robot, Spline, SplineError};

/// Posterior σ of every parameter at `times` (s from the start), all samples.
pub fn sigma_vs_time(info: &Information, spline: &Spline, step: f64) -> (Vec<f64>, Vec<Vec<f64>>) {
    let (t0, t1) = (spline.knots().start(), spline.knots().end());
    let all: Vec<usize> = (0..info.dim()).collect();
    let mut lam = info.prior();
    let mut times = Vec::new();
    let mut sigmas = Vec::new();
    let mut a = t0;
    while a < t1 {
        let b = (a + step).min(t1);
        let last = b >= t1;
        info.accumulate(spline, a, b, last, 1.0, Sampling::Exact, &mut lam);
        if let Some(cov) = covariance(&lam, &all) {
            times.push(b - t0);
            sigmas.push(
                (0..all.len())
                    .map(|k| cov[(k, k)].max(0.0).sqrt())
                    .collect(),
            );
        }
        a = b;
    }
    (times, sigmas)
}

/// λ_max(Σ_x) (all parameters, and robot lengths known) at every `step` s.
pub(crate) fn lambda_vs_time(
    info: &Information,
    spline: &Spline,
    step: f64,
) -> Vec<(f64, f64, f64)> {
    let (t0, t1) = (spline.knots().start(), spline.knots().end());
    let all: Vec<usize> = (0..info.dim()).collect();
    let nl = without_robot_lengths(info.layout());
    let mut lam = info.prior();
    let mut out = Vec::new();
    let mut a = t0;
    while a < t1 {
        let b = (a + step).min(t1);
        info.accumulate(spline, a, b, b >= t1, 1.0, Sampling::Exact, &mut lam);
        out.push((b - t0, lambda_max(&lam, &all), lambda_max(&lam, &nl)));
        a = b;
    }
    out
}

/// Posterior σ of the robot length parameters (names, then one row per
/// speed) for copies of the trajectory played `speed` times faster, sampled
/// `speed` times faster (equal sample count; paper Fig. 8).
pub(crate) fn length_sigma_vs_speed(
    info: &Information,
    spline: &Spline,
    speeds: &[f64],
) -> (Vec<String>, Vec<Vec<f64>>) {
    let lengths = robot_lengths(info.layout());
    let all: Vec<usize> = (0..info.dim()).collect();
    let names = lengths
        .iter()
        .map(|&k| info.layout().specs()[k].name.clone())
        .collect();
    let rows = speeds
        .iter()
        .map(|&s| {
            let lam = info.total(spline, s, Sampling::Exact);
            let cov = covariance(&lam, &all);
            lengths
                .iter()
                .map(|&k| cov.as_ref().map_or(f64::NAN, |c| c[(k, k)].max(0.0).sqrt()))
                .collect()
        })
        .collect();
    (names, rows)
}

/// The two random baselines of one length and limits.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Baseline {
    /// Coefficients uniform within the position limits, then shrunk (paper §8.2).
    Uniform,
    /// A random walk of the coefficients near the velocity limit ([`random_walk`]).
    RandomWalk,
}

/// A random trajectory of the kind `kind` (knots every 1 s, as the paper's).
pub fn baseline<R: Rng>(
    robot: &Robot,
    kind: Baseline,
    duration: f64,
    rng: &mut R,
) -> Result<Spline, SplineError> {
    match kind {
        Baseline::Uniform => random_uniform(robot, duration, 1.0, rng),
        Baseline::RandomWalk => random_walk(robot, duration, 1.0, rng),
    }
}

/// Median of a non-empty list (mean of the middle two for even length).
pub fn median(v: &[f64]) -> f64 {
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    let k = s.len();
    if k == 0 {
        return f64::NAN;
    }
    if k % 2 == 1 {
        s[k / 2]
    } else {
        0.5 * (s[k / 2 - 1] + s[k / 2])
    }
}

/// The approximation (26) against the estimator's Σ_x (24) on the same
/// trajectory.
#[derive(Clone, Debug)]
pub struct ApproximationCheck {
    /// ‖Σ_(24) − Σ_(26)‖_F, SI.
    pub frobenius: f64,
    /// ‖Σ_(24)‖_F, SI.
    pub norm: f64,
    /// Largest |σ_(24)/σ_(26) − 1| over the parameters.
    pub max_sigma_ratio_error: f64,
}

/// Why the approximation could not be checked.
#[derive(Debug, thiserror::Error)]
pub enum CheckError {
    /// Simulation failed.
    #[error(transparent)]
    Model(#[from] ModelError),
    /// The information model could not be built.
    #[error(transparent)]
    Information(#[from] InformationError),
    /// The estimator failed.
    #[error(transparent)]
    Calibrate(#[from] CalibrateError),
    /// (26) is singular.
    #[error("the approximate information matrix (26) is not positive definite")]
    Singular,
}

/// Noise-free data at the nominal x on `spline` (joints and IMU at `rate`),
/// calibrated with the trajectory knots every `knot_spacing` s under the IMU
/// noise model `noise` (generalised least squares unless white); its Σ_x
/// against (26) with that noise at the same rate.
pub(crate) fn check_approximation(
    robot: &Robot,
    spline: &Spline,
    rate: f64,
    knot_spacing: f64,
    noise: &NoiseModel,
) -> Result<ApproximationCheck, CheckError> {
    let layout = ParamLayout::new(robot);
    let mut sim = SimulateOptions::paper(robot);
    sim.imu_rate = rate;
    sim.joint_rate = rate;
    sim.noise = false;
    let data = simulate(robot, &layout, &layout.nominal(), spline, &sim, 1)?;
    let mut copts = fit_options(robot, noise);
    copts.knot_spacing = Some(knot_spacing);
    copts.tau_search = None;
    let cal = calibrate(robot, &data, &copts, |_| {})?;
    let info = Information::with_noise(robot, noise.clone(), rate)?;
    let all: Vec<usize> = (0..info.dim()).collect();
    // the same samples the estimator used: t_k = k / rate over the span
    let lam = info.total(spline, 1.0, Sampling::Exact);
    let approx = covariance(&lam, &all).ok_or(CheckError::Singular)?;
    let na = cal.active.len();
    let mut diff = 0.0;
    let mut norm = 0.0;
    let mut worst = 0.0f64;
    for i in 0..na {
        for j in 0..na {
            let (a, b) = (cal.active[i], cal.active[j]);
            let full = cal.covariance[i * na + j];
            diff += (full - approx[(a, b)]).powi(2);
            norm += full * full;
        }
        let a = cal.active[i];
        let r = cal.covariance[i * na + i].sqrt() / approx[(a, a)].sqrt();
        worst = worst.max((r - 1.0).abs());
    }
    Ok(ApproximationCheck {
        frobenius: diff.sqrt(),
        norm: norm.sqrt(),
        max_sigma_ratio_error: worst,
    })
}

/// The calibration settings of a fit under `noise`: the robot's defaults,
/// σ_z from `noise`, generalised least squares unless it is white.
fn fit_options(robot: &Robot, noise: &NoiseModel) -> CalibrateOptions {
    let mut copts = CalibrateOptions::new(robot);
    copts.sigma_z = noise.sigma_z();
    copts.noise = (!noise.is_white()).then(|| noise.clone());
    copts
}

/// Monte Carlo errors on one trajectory: per run a truth drawn from the
/// priors, a simulated session on `spline` (120 Hz, IMU noise `noise`), a
/// calibration under that noise ([`fit_options`]); returns the errors
/// x̂ − x per run (SI).
pub(crate) fn monte_carlo_errors(
    robot: &Robot,
    spline: &Spline,
    noise: &NoiseModel,
    runs: usize,
    seed: u64,
    mut progress: impl FnMut(usize),
) -> Result<Vec<Vec<f64>>, CheckError> {
    let layout = ParamLayout::new(robot);
    let mut sim = SimulateOptions::paper(robot);
    sim.sigma_z = noise.sigma_z();
    sim.noise_model = (!noise.is_white()).then(|| noise.clone());
    let copts = fit_options(robot, noise);
    let mut out = Vec::with_capacity(runs);
    for r in 0..runs {
        let s = seed.wrapping_add(r as u64);
        let mut rng = rand::rngs::StdRng::seed_from_u64(s);
        let truth = draw_truth(&layout, &mut rng);
        let data = simulate(robot, &layout, &truth, spline, &sim, s)?;
        let cal = calibrate(robot, &data, &copts, |_| {})?;
        out.push(cal.x.iter().zip(&truth).map(|(a, b)| a - b).collect());
        progress(r + 1);
    }
    Ok(out)
}

/// Mean squared error along the unit vector `v` and in total, over runs.
pub(crate) fn error_moments(errors: &[Vec<f64>], v: &[f64]) -> (f64, f64) {
    let n = errors.len().max(1) as f64;
    let along = errors
        .iter()
        .map(|e| e.iter().zip(v).map(|(a, b)| a * b).sum::<f64>().powi(2))
        .sum::<f64>()
        / n;
    let total = errors
        .iter()
        .map(|e| e.iter().map(|a| a * a).sum::<f64>())
        .sum::<f64>()
        / n;
    (along, total)
}

/// The eigenvector of Σ = Λ⁻¹ with the largest eigenvalue (that of Λ's smallest).
pub(crate) fn worst_direction(info: &Mat<f64>) -> Vec<f64> {
    match info.self_adjoint_eigen(faer::Side::Lower) {
        Ok(evd) => {
            let s = evd.S();
            let k = (0..info.nrows())
                .min_by(|&a, &b| s[a].total_cmp(&s[b]))
                .unwrap_or(0);
            (0..info.nrows()).map(|i| evd.U()[(i, k)]).collect()
        }
        Err(_) => vec![0.0; info.nrows()],
    }
}

/// Posterior σ of every parameter against trajectory length (paper Fig. 6).
#[derive(Clone, Debug)]
pub struct SigmaStudy {
    /// The parameter names, in x order.
    pub names: Vec<String>,
    /// Trajectory lengths, s.
    pub times: Vec<f64>,
    /// Per time, every parameter's posterior σ (SI).
    pub sigma: Vec<Vec<f64>>,
}

/// [`sigma_vs_time`] every `step` s, with the parameter names.
pub fn sigma_study(info: &Information, spline: &Spline, step: f64) -> SigmaStudy {
    let (times, sigma) = sigma_vs_time(info, spline, step);
    SigmaStudy {
        names: info
            .layout()
            .specs()
            .iter()
            .map(|s| s.name.clone())
            .collect(),
        times,
        sigma,
    }
}

/// Posterior σ of the robot length parameters for time-scaled copies of a
/// trajectory (paper Fig. 8).
#[derive(Clone, Debug)]
pub struct SpeedStudy {
    /// The speed-up factors.
    pub speeds: Vec<f64>,
    /// The length parameters' names.
    pub names: Vec<String>,
    /// Per speed, each length parameter's σ, m.
    pub rows: Vec<Vec<f64>>,
}

/// [`length_sigma_vs_speed`] at `speeds`.
pub fn speed_study(info: &Information, spline: &Spline, speeds: &[f64]) -> SpeedStudy {
    let (names, rows) = length_sigma_vs_speed(info, spline, speeds);
    SpeedStudy {
        speeds: speeds.to_vec(),
        names,
        rows,
    }
}

/// λ_max(Σ_x) against time, `(t, λ_max, λ_max without the robot lengths)`.
pub(crate) type LambdaCurve = Vec<(f64, f64, f64)>;

/// A plan against random trajectories of equal length under the same limits
/// (paper Fig. 5).
#[derive(Clone, Debug)]
pub struct BaselineStudy {
    /// The plan's curve.
    pub plan: LambdaCurve,
    /// Random trajectories of each kind.
    pub random: usize,
    /// The curves of the uniform random trajectories.
    pub uniform: Vec<LambdaCurve>,
    /// The curves of the random walks.
    pub walk: Vec<LambdaCurve>,
}

/// The medians over random trajectories at one time of a [`BaselineStudy`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BaselineMedians {
    /// Uniform random: λ_max.
    pub uniform: f64,
    /// Uniform random: λ_max with the robot lengths known.
    pub uniform_without_lengths: f64,
    /// Random walks: λ_max.
    pub walk: f64,
    /// Random walks: λ_max with the robot lengths known.
    pub walk_without_lengths: f64,
}

impl BaselineStudy {
    /// The medians of the random curves at the plan's `k`-th time.
    pub fn medians(&self, k: usize) -> BaselineMedians {
        let med = |c: &[LambdaCurve], without: bool| -> f64 {
            let v: Vec<f64> = c
                .iter()
                .filter_map(|x| x.get(k).map(|p| if without { p.2 } else { p.1 }))
                .collect();
            median(&v)
        };
        BaselineMedians {
            uniform: med(&self.uniform, false),
            uniform_without_lengths: med(&self.uniform, true),
            walk: med(&self.walk, false),
            walk_without_lengths: med(&self.walk, true),
        }
    }
}

/// Length of `spline`, s.
fn span(spline: &Spline) -> f64 {
    spline.knots().end() - spline.knots().start()
}

/// λ_max(Σ_x) every `step` s of the plan and of `random` trajectories of
/// each [`Baseline`] kind drawn from `rng` (uniform first);
/// `progress(kind, k)` before the k-th (1-based) of each kind.
pub fn baseline_study<R: Rng>(
    robot: &Robot,
    info: &Information,
    spline: &Spline,
    step: f64,
    random: usize,
    rng: &mut R,
    mut progress: impl FnMut(Baseline, usize),
) -> Result<BaselineStudy, SplineError> {
    let plan = lambda_vs_time(info, spline, step);
    let mut curves = Vec::new();
    for kind in [Baseline::Uniform, Baseline::RandomWalk] {
        let mut v = Vec::new();
        for k in 0..random {
            progress(kind, k + 1);
            let s = baseline(robot, kind, span(spline), rng)?;
            v.push(lambda_vs_time(info, &s, step));
        }
        curves.push(v);
    }
    let walk = curves.pop().unwrap_or_default();
    let uniform = curves.pop().unwrap_or_default();
    Ok(BaselineStudy {
        plan,
        random,
        uniform,
        walk,
    })
}

/// [`check_approximation`] with the trajectory knots as the spline's own
/// (its first knot span).
pub fn check_plan_approximation(
    robot: &Robot,
    spline: &Spline,
    rate: f64,
    noise: &NoiseModel,
) -> Result<ApproximationCheck, CheckError> {
    let h = spline.knots().knots()[spline.knots().degree() + 1] - spline.knots().start();
    check_approximation(robot, spline, rate, h, noise)
}

/// Mean squared errors of a Monte Carlo run, measured and predicted.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ErrorMoments {
    /// Along the random walk's worst direction, measured.
    pub along: f64,
    /// In total (the trace), measured.
    pub total: f64,
    /// Along the worst direction, predicted by (26).
    pub predicted_along: f64,
    /// The predicted trace.
    pub predicted_total: f64,
}

/// The Monte Carlo check of the predicted gain in precision of a plan over
/// a random walk of the same length.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PrecisionGain {
    /// Calibrations on each trajectory.
    pub runs: usize,
    /// On the plan.
    pub plan: ErrorMoments,
    /// On the random walk.
    pub walk: ErrorMoments,
}

/// Why the gain in precision could not be checked.
#[derive(Debug, thiserror::Error)]
pub enum GainError {
    /// The random walk could not be made.
    #[error(transparent)]
    Trajectory(#[from] SplineError),
    /// An information matrix is singular.
    #[error("singular information")]
    Singular,
    /// The Monte Carlo calibrations failed.
    #[error("Monte Carlo on the {trajectory}")]
    MonteCarlo {
        /// `plan` or `random walk`.
        trajectory: &'static str,
        /// Why.
        #[source]
        source: CheckError,
    },
}

/// `runs` Monte Carlo calibrations ([`monte_carlo_errors`], seeded with
/// `seed`, with `info`'s noise model) on the plan and on a random walk drawn
/// from `rng`, against the precision (26) predicts; `progress(trajectory,
/// run)` after each run.
pub fn precision_gain<R: Rng>(
    robot: &Robot,
    info: &Information,
    spline: &Spline,
    runs: usize,
    seed: u64,
    rng: &mut R,
    mut progress: impl FnMut(&str, usize),
) -> Result<PrecisionGain, GainError> {
    let walk = baseline(robot, Baseline::RandomWalk, span(spline), rng)?;
    let all: Vec<usize> = (0..info.dim()).collect();
    let lam_plan = info.total(spline, 1.0, Sampling::Exact);
    let lam_walk = info.total(&walk, 1.0, Sampling::Exact);
    let v = worst_direction(&lam_walk);
    let predict = |lam: &Mat<f64>| -> Result<(f64, f64), GainError> {
        let c = covariance(lam, &all).ok_or(GainError::Singular)?;
        let mut along = 0.0;
        for i in 0..all.len() {
            for j in 0..all.len() {
                along += v[i] * c[(i, j)] * v[j];
            }
        }
        Ok((along, (0..all.len()).map(|i| c[(i, i)]).sum()))
    };
    let (pp, pw) = (predict(&lam_plan)?, predict(&lam_walk)?);
    let mut measured = Vec::new();
    for (trajectory, s) in [("plan", spline), ("random walk", &walk)] {
        let e = monte_carlo_errors(robot, s, info.noise(), runs, seed, |r| {
            progress(trajectory, r)
        })
        .map_err(|source| GainError::MonteCarlo { trajectory, source })?;
        measured.push(error_moments(&e, &v));
    }
    let moments = |(along, total): (f64, f64), (pa, pt): (f64, f64)| ErrorMoments {
        along,
        total,
        predicted_along: pa,
        predicted_total: pt,
    };
    Ok(PrecisionGain {
        runs,
        plan: moments(measured[0], pp),
        walk: moments(measured[1], pw),
    })
}
