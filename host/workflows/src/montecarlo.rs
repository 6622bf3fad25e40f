//! Monte Carlo consistency of the estimator (paper §8.3): per run, draw a
//! truth from the priors, simulate a session, calibrate with the chosen
//! noise model ([`NoiseChoice`]), and compare the error with the reported
//! posterior covariance.
//!
//! A consistent estimator gives, for every parameter, error/σ with mean 0 and
//! standard deviation 1, and a normalised estimation error squared
//! NEES = eᵀ Σ⁻¹ e whose average over N runs of d parameters lies in the 95 %
//! interval of χ²(N·d)/N.
//!
//! With K IMUs (docs/model.md §9) every session has K IMUs on one motion,
//! each with its own 28 truths, fitted jointly; optionally IMU 0 alone is
//! fitted too, for the gain in the shared parameters' σ
//! ([`MonteCarloResult::shared_sigma_gain`]).

use super::calibrate::noise_choice::{calibrate_with_noise, NoiseChoice};
use super::calibrate::{CalibrateError, CalibrateOptions};
use super::simulate::{random_session_imus, RandomSession, SimulateError, SimulateOptions};
use crate::pipeline::noise_spec::parse_noise_model;
use faer::linalg::solvers::DenseSolveCore;
use faer::Side;
use robimu_model::noise::NoiseModel;
use robimu_model::{ParamLayout, Robot};
use robimu_session::result::{ActualPoseErrors, PoseAccuracyRecord, PoseErrorStats};

use crate::pose_accuracy::{pose_accuracy, Posterior};

/// Settings of a Monte Carlo study.
#[derive(Debug, Clone)]
pub struct MonteCarloOptions {
    /// Number of runs.
    pub runs: usize,
    /// Session length, s.
    pub duration: f64,
    /// Base seed; run k uses seed + k.
    pub seed: u64,
    /// How sessions are sampled.
    pub simulate: SimulateOptions,
    /// How they are calibrated.
    pub calibrate: CalibrateOptions,
    /// The noise model of the fits (`Auto` is `robimu calibrate`'s default).
    pub noise: NoiseChoice,
    /// IMUs per session K (1: the one-IMU study).
    pub n_imus: usize,
    /// Also fit IMU 0 alone in every run (K > 1): [`RunOutcome::sigma_imu0`].
    pub compare_imu0: bool,
}

impl MonteCarloOptions {
    /// `robimu montecarlo`'s study of `robot`: `runs` sessions of `duration`
    /// s with `imus` IMUs, simulated as the paper's with the IMU noise
    /// `noise_model` (a `robimu simulate --noise-model` spec; default white)
    /// and fitted with the noise model `fit_noise`: `auto`, `white`, or
    /// `true` (the simulated model, given).
    pub fn study(
        robot: &Robot,
        runs: usize,
        duration: f64,
        seed: u64,
        imus: usize,
        noise_model: Option<&str>,
        fit_noise: &str,
    ) -> anyhow::Result<Self> {
        let mut simulate = SimulateOptions::paper(robot);
        let mut truth = NoiseModel::white(robot.sigma_z())?;
        if let Some(spec) = noise_model {
            truth = parse_noise_model(spec, robot.sigma_z(), simulate.imu_rate)?;
            simulate.sigma_z = truth.sigma_z();
            simulate.noise_model = (!truth.is_white()).then_some(truth.clone());
        }
        let noise = match fit_noise.trim() {
            "auto" => NoiseChoice::Auto,
            "white" => NoiseChoice::White,
            "true" => NoiseChoice::Given(Box::new(truth)),
            other => anyhow::bail!("--fit-noise `{other}`: expected `auto`, `white` or `true`"),
        };
        let mut calibrate = CalibrateOptions::new(robot);
        calibrate.sigma_z = simulate.sigma_z;
        Ok(Self {
            runs,
            duration,
            seed,
            simulate,
            calibrate,
            noise,
            n_imus: imus,
            compare_imu0: imus > 1,
        })
    }
}

/// One run.
#[derive(Debug, Clone)]
pub struct RunOutcome {
    /// The run's seed.
    pub seed: u64,
    /// True x.
    pub truth: Vec<f64>,
    /// Estimated x.
    pub estimate: Vec<f64>,
    /// Posterior σ.
    pub sigma: Vec<f64>,
    /// NEES over the estimated parameters.
    pub nees: f64,
    /// LM iterations (of the final fit).
    pub iterations: usize,
    /// GLS refits of `Auto` (0: the white fit was kept).
    pub refits: usize,
    /// Why `Auto` kept the white fit although the residuals are correlated.
    pub warning: Option<String>,
    /// Posterior σ of the one-IMU x from IMU 0 alone
    /// ([`MonteCarloOptions::compare_imu0`]).
    pub sigma_imu0: Option<Vec<f64>>,
    /// The predicted pose accuracy and the actual errors against the truth
    /// (docs/model.md §8.7).
    pub pose: PoseAccuracyRecord,
}

/// The predicted pose accuracy against the actual errors over the runs
/// (docs/model.md §8.7): each run's share of configurations inside their
/// predicted 95 % band, averaged, and the predicted and actual mean errors,
/// averaged; before calibration (the prior) and after.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PoseCoverage {
    /// Before: [position, rotation] share inside the band.
    pub inside_before: [f64; 2],
    /// After.
    pub inside_after: [f64; 2],
    /// Before: predicted [position mm, rotation deg] mean error.
    pub predicted_before: [f64; 2],
    /// Before: actual mean error.
    pub actual_before: [f64; 2],
    /// After: predicted.
    pub predicted_after: [f64; 2],
    /// After: actual.
    pub actual_after: [f64; 2],
}

impl PoseCoverage {
    /// The coverage of `runs`.
    pub fn of(runs: &[RunOutcome]) -> Self {
        let n = runs.len().max(1) as f64;
        let avg = |f: &dyn Fn(&PoseAccuracyRecord) -> [f64; 2]| {
            let mut s = [0.0; 2];
            for r in runs {
                let v = f(&r.pose);
                s[0] += v[0] / n;
                s[1] += v[1] / n;
            }
            s
        };
        let inside = |e: &Option<ActualPoseErrors>| {
            e.map_or([f64::NAN; 2], |e| {
                [e.position_inside_band, e.rotation_inside_band]
            })
        };
        let mean = |s: &PoseErrorStats| [s.position_mean_mm, s.rotation_mean_deg];
        let actual = |e: &Option<ActualPoseErrors>| e.map_or([f64::NAN; 2], |e| mean(&e.stats));
        Self {
            inside_before: avg(&|p| inside(&p.actual_before)),
            inside_after: avg(&|p| inside(&p.actual_after)),
            predicted_before: avg(&|p| mean(&p.before)),
            actual_before: avg(&|p| actual(&p.actual_before)),
            predicted_after: avg(&|p| mean(&p.after)),
            actual_after: avg(&|p| actual(&p.actual_after)),
        }
    }
}

/// Per-parameter statistics of error/σ over the runs.
#[derive(Debug, Clone)]
pub struct ParamStats {
    /// Parameter name.
    pub name: String,
    /// Mean of error/σ.
    pub mean: f64,
    /// Standard deviation of error/σ.
    pub std: f64,
}

/// The study's result.
#[derive(Debug, Clone)]
pub struct MonteCarloResult {
    /// Every run, in order.
    pub runs: Vec<RunOutcome>,
    /// Per estimated parameter.
    pub stats: Vec<ParamStats>,
    /// Average NEES.
    pub nees_mean: f64,
    /// 95 % interval of the average NEES of a consistent estimator.
    pub nees_interval: (f64, f64),
    /// Degrees of freedom of one NEES (estimated parameters).
    pub dof: usize,
    /// The predicted pose accuracy against the actual errors.
    pub pose: PoseCoverage,
}

/// Why the study stopped.
#[derive(Debug, thiserror::Error)]
pub enum MonteCarloError {
    /// A run's calibration failed.
    #[error("run {run} (seed {seed}): {source}")]
    Run {
        /// Run index.
        run: usize,
        /// Its seed.
        seed: u64,
        /// What failed.
        #[source]
        source: CalibrateError,
    },
    /// A session could not be simulated.
    #[error(transparent)]
    Simulate(#[from] SimulateError),
}

/// The p-quantile of χ²(k) by the Wilson–Hilferty approximation (relative
/// error below 1e-4 for k ≥ 100, which is where it is used here).
pub(crate) fn chi2_quantile(k: f64, p: f64) -> f64 {
    let z = normal_quantile(p);
    let a = 2.0 / (9.0 * k);
    k * (1.0 - a + z * a.sqrt()).powi(3)
}

/// The p-quantile of the standard normal (Acklam's rational approximation,
/// relative error below 1.2e-9).
#[allow(clippy::excessive_precision)] // the published coefficients, verbatim
pub(crate) fn normal_quantile(p: f64) -> f64 {
    const A: [f64; 6] = [
        -3.969683028665376e1,
        2.209460984245205e2,
        -2.759285104469687e2,
        1.383577518672690e2,
        -3.066479806614716e1,
        2.506628277459239,
    ];
    const B: [f64; 5] = [
        -5.447609879822406e1,
        1.615858368580409e2,
        -1.556989798598866e2,
        6.680131188771972e1,
        -1.328068155288572e1,
    ];
    const C: [f64; 6] = [
        -7.784894002430293e-3,
        -3.223964580411365e-1,
        -2.400758277161838,
        -2.549732539343734,
        4.374664141464968,
        2.938163982698783,
    ];
    const D: [f64; 4] = [
        7.784695709041462e-3,
        3.224671290700398e-1,
        2.445134137142996,
        3.754408661907416,
    ];
    let tail = |q: f64| {
        (((((C[0] * q + C[1]) * q + C[2]) * q + C[3]) * q + C[4]) * q + C[5])
            / ((((D[0] * q + D[1]) * q + D[2]) * q + D[3]) * q + 1.0)
    };
    if p < 0.02425 {
        tail((-2.0 * p.ln()).sqrt())
    } else if p > 1.0 - 0.02425 {
        -tail((-2.0 * (1.0 - p).ln()).sqrt())
    } else {
        let q = p - 0.5;
        let r = q * q;
        (((((A[0] * r + A[1]) * r + A[2]) * r + A[3]) * r + A[4]) * r + A[5]) * q
            / (((((B[0] * r + B[1]) * r + B[2]) * r + B[3]) * r + B[4]) * r + 1.0)
    }
}

/// Run the study. `progress(k)` is called after run k.
pub fn monte_carlo(
    robot: &Robot,
    opts: &MonteCarloOptions,
    mut progress: impl FnMut(usize, &RunOutcome),
) -> Result<MonteCarloResult, MonteCarloError> {
    let layout = ParamLayout::with_imus(robot, opts.n_imus);
    let mut runs = Vec::with_capacity(opts.runs);
    let mut dof = 0;
    for run in 0..opts.runs {
        let seed = opts.seed.wrapping_add(run as u64);
        let RandomSession { truth, data, .. } =
            random_session_imus(robot, opts.n_imus, opts.duration, 1.0, &opts.simulate, seed)?;
        let (cal, noise) = calibrate_with_noise(robot, &data, &opts.calibrate, &opts.noise, |_| {})
            .map_err(|source| MonteCarloError::Run { run, seed, source })?;
        let sigma_imu0 = if opts.compare_imu0 {
            let mut one = opts.calibrate.clone();
            // the frozen entries of IMU 0 and the shared ones are the same indices
            one.frozen.retain(|&k| k < layout.imu_layout().len());
            let alone = data.only_imu(0);
            let (c0, _) = calibrate_with_noise(robot, &alone, &one, &opts.noise, |_| {})
                .map_err(|source| MonteCarloError::Run { run, seed, source })?;
            Some(c0.sigma)
        } else {
            None
        };
        let na = cal.active.len();
        dof = na;
        let cov = faer::Mat::from_fn(na, na, |i, j| cal.covariance[i * na + j]);
        let info = cov
            .llt(Side::Lower)
            .map(|l| l.inverse())
            .unwrap_or_else(|_| faer::Mat::zeros(na, na));
        let e: Vec<f64> = cal.active.iter().map(|&k| cal.x[k] - truth[k]).collect();
        let mut nees = 0.0;
        for i in 0..na {
            for j in 0..na {
                nees += e[i] * info[(i, j)] * e[j];
            }
        }
        let posterior = Posterior {
            x: &cal.x,
            sigma: &cal.sigma,
            active: &cal.active,
            covariance: &cal.covariance,
        };
        let pose = pose_accuracy(robot, &layout, &posterior, Some(&truth));
        let outcome = RunOutcome {
            pose,
            seed,
            truth,
            estimate: cal.x,
            sigma: cal.sigma,
            nees,
            iterations: cal.summary.iterations.len(),
            refits: noise.refits,
            warning: noise.warning,
            sigma_imu0,
        };
        progress(run, &outcome);
        runs.push(outcome);
    }
    let active: Vec<usize> = (0..layout.len())
        .filter(|k| !opts.calibrate.frozen.contains(k))
        .collect();
    let n = runs.len() as f64;
    let stats = active
        .iter()
        .map(|&k| {
            let z: Vec<f64> = runs
                .iter()
                .map(|r| (r.estimate[k] - r.truth[k]) / r.sigma[k])
                .collect();
            let mean = z.iter().sum::<f64>() / n;
            let var = z.iter().map(|v| (v - mean) * (v - mean)).sum::<f64>() / (n - 1.0).max(1.0);
            ParamStats {
                name: layout.specs()[k].name.clone(),
                mean,
                std: var.sqrt(),
            }
        })
        .collect();
    let nees_mean = runs.iter().map(|r| r.nees).sum::<f64>() / n;
    let k = n * dof as f64;
    let nees_interval = (chi2_quantile(k, 0.025) / n, chi2_quantile(k, 0.975) / n);
    Ok(MonteCarloResult {
        pose: PoseCoverage::of(&runs),
        runs,
        stats,
        nees_mean,
        nees_interval,
        dof,
    })
}

impl MonteCarloResult {
    /// Per shared parameter (docs/model.md §9: robot errors other than the
    /// IMU position, g_x, g_y) estimated in both fits, the mean over the runs
    /// of σ(IMU 0 alone) / σ(all IMUs): the gain of the joint fit (√K when
    /// every IMU carries the same information). Empty without
    /// [`MonteCarloOptions::compare_imu0`].
    pub fn shared_sigma_gain(&self, layout: &ParamLayout) -> Vec<(String, f64)> {
        let one = layout.imu_layout();
        (0..one.len())
            .filter(|&k| !one.is_per_imu(k))
            .filter_map(|k| {
                let ratios: Vec<f64> = self
                    .runs
                    .iter()
                    .filter_map(|r| {
                        let s0 = r.sigma_imu0.as_ref()?[k];
                        (s0 > 0.0 && r.sigma[k] > 0.0).then(|| s0 / r.sigma[k])
                    })
                    .collect();
                (!ratios.is_empty()).then(|| {
                    let m = ratios.iter().sum::<f64>() / ratios.len() as f64;
                    (one.specs()[k].name.clone(), m)
                })
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The honesty check (docs/model.md §8.7): 50 sessions of 60 s
    /// simulated with truths from the priors and calibrated; at 200
    /// configurations each, the actual flange errors fall inside their
    /// predicted 95 % band for 92–98 % of all configurations, before and
    /// after, and the predicted mean error is the measured one within 20 %.
    #[test]
    fn predicted_pose_accuracy_is_honest_over_fifty_sessions() {
        pose_accuracy_is_honest(&Robot::aubo_i5(), 60.0);
    }

    /// The same on a catalogue arm described by its maker's joint origins
    /// (the flange pose once took the DH part alone, zero for these):
    /// `cargo test -p robimu-workflows --release --lib -- --ignored
    /// pose_accuracy_of_a_ur5e --nocapture`.
    #[test]
    #[ignore = "a study: 50 UR5e sessions of 60 s"]
    fn pose_accuracy_of_a_ur5e_is_honest_over_fifty_sessions() {
        pose_accuracy_is_honest(&Robot::builtin("ur5e").unwrap(), 60.0);
    }

    fn pose_accuracy_is_honest(robot: &Robot, duration: f64) {
        let opts = MonteCarloOptions::study(robot, 50, duration, 11, 1, None, "white").unwrap();
        let mc = monte_carlo(robot, &opts, |_, _| {}).unwrap();
        let c = mc.pose;
        println!("{}: {c:#?}", robot.name());
        for (what, inside) in [("before", c.inside_before), ("after", c.inside_after)] {
            for (k, v) in inside.iter().enumerate() {
                assert!((0.92..=0.98).contains(v), "{what} [{k}]: {v}");
            }
        }
        for (what, predicted, actual) in [
            ("before", c.predicted_before, c.actual_before),
            ("after", c.predicted_after, c.actual_after),
        ] {
            for k in 0..2 {
                let ratio = actual[k] / predicted[k];
                assert!((ratio - 1.0).abs() < 0.2, "{what} [{k}]: {ratio}");
            }
        }
    }

    #[test]
    fn quantiles_match_tabulated_values() {
        // standard normal: Φ⁻¹(0.975) = 1.959963985, Φ⁻¹(0.001) = −3.090232306
        assert!((normal_quantile(0.975) - 1.959963985).abs() < 1e-8);
        assert!((normal_quantile(0.001) + 3.090232306).abs() < 1e-8);
        // χ²(100): 2.5 % = 74.2219, 97.5 % = 129.5612 (tables)
        assert!((chi2_quantile(100.0, 0.025) - 74.2219).abs() < 0.02);
        assert!((chi2_quantile(100.0, 0.975) - 129.5612).abs() < 0.02);
    }
}
