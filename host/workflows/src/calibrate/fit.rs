//! The one fit pipeline behind every estimate of x (paper §4–6): the plain
//! calibration ([`super::calibrate`]), the diagnosis' baseline and its refits
//! with catalogue effects ([`crate::diagnose`]), the repeatability windows
//! ([`crate::repeatability`]), the Monte Carlo runs ([`crate::montecarlo`])
//! and the calibration a validation starts from all call [`fit`].
//!
//! 1. Check the session against the robot ([`super::check_measurements`]).
//! 2. Represent the trajectory q(t) by a B-spline (eq. (20)) fitted to the
//!    joint samples ([`super::choose_knots`]), or take a previous fit's.
//! 3. Find τ from the data ([`crate::time_offset`]) unless the fit starts
//!    from a given x or τ is frozen.
//! 4. Levenberg–Marquardt over θ = [c, x_a, θ_E] on the MAP cost
//!    (from a start that is not a previous fit, the first step from a
//!    thinned set of IMU samples: [`Problem::thin_first_iteration`])
//!    J = ½‖e‖² of eq. (22) (residuals eq. (10), priors eq. (16)), the
//!    effects of the spec as extra parameter blocks θ_E with their priors
//!    ([`robimu_solver::problem::Problem`]; none in a plain calibration).
//! 5. Convergence check, then the posterior covariance of [x_a, θ_E] as the
//!    inverse of the Schur complement S of the normal matrix at the optimum
//!    (eq. (24) restricted to x), and the whitened IMU residuals.
//!
//! **Several IMUs** (docs/model.md §9): a session with K IMUs is fitted
//! jointly, x of [`ParamLayout::with_imus`] (shared robot errors and
//! gravity, each IMU's position, τ and intrinsics); each IMU's τ is found
//! from its own gyroscope before the fit. One noise model serves all IMUs.
//!
//! The IMU noise is white of σ_z (the paper's model) unless
//! [`CalibrateOptions::noise`] gives a [`NoiseModel`]: then every step's
//! cost is the generalised least squares ½ rᵀΣ⁻¹r of that model (AR
//! correlation in time, motion-dependent level; see
//! [`robimu_solver::problem`]), so the covariance, the residuals and the
//! effects' score tests all account for it.

use faer::Mat;

use super::{
    check_measurements, choose_knots, unidentified_names, CalibrateError, CalibrateOptions,
};
use crate::body_rate::BodyRate;
use crate::time_offset::{find_tau, TauEstimate};
use robimu_model::effects::{EffectConstant, EffectParam, EffectSet};
use robimu_model::noise::NoiseModel;
use robimu_model::observations::Measurements;
use robimu_model::{MeasurementModel, ParamLayout, Robot, Spline};
use robimu_solver as solver;
use robimu_solver::problem::Problem;
use robimu_solver::{IterationRecord, Linearization, LmError, LmSummary};

/// Where a fit starts.
#[derive(Debug, Clone, Copy)]
pub enum Start<'a> {
    /// Nominal x; τ found from the data (when the options ask for a τ
    /// search and τ is estimated). The trajectory spline is fitted to the
    /// joint samples.
    Nominal,
    /// This x (e.g. a loaded calibration), no τ search; the trajectory
    /// spline is fitted to the joint samples.
    At(&'a [f64]),
    /// A previous fit whose effects are a prefix of the spec's: its knots,
    /// trajectory, x and θ (the new effect parameters at 0).
    Refit(&'a Fit),
    /// [`Start::Refit`] with the problem's linearisation there, made
    /// already (a restriction of the score tests', docs/model.md §4.9): the
    /// solver's first iteration takes it instead of linearising.
    RefitAt(&'a Fit, &'a Linearization),
}

/// What is fitted: a session, the model's effects, the starting point.
#[derive(Clone, Copy)]
pub struct FitSpec<'a> {
    /// The robot.
    pub robot: &'a Robot,
    /// The session's samples.
    pub data: &'a Measurements,
    /// Effects added to the baseline model ([`EffectSet::none`] for a plain
    /// calibration: then no effect work is done at any sample).
    pub effects: &'a EffectSet,
    /// The starting point.
    pub start: Start<'a>,
}

impl<'a> FitSpec<'a> {
    /// The baseline model of `data`, from the nominal x.
    pub fn baseline(robot: &'a Robot, data: &'a Measurements) -> Self {
        Self {
            robot,
            data,
            effects: EffectSet::none(),
            start: Start::Nominal,
        }
    }
}

/// The outcome of a fit.
#[derive(Debug, Clone)]
pub struct Fit {
    /// Effects in the model, in θ_E order.
    pub effects: Vec<String>,
    /// The full x.
    pub x: Vec<f64>,
    /// Posterior σ of x (0 when frozen).
    pub sigma_x: Vec<f64>,
    /// Estimated (not frozen) parameters, indices into x.
    pub active: Vec<usize>,
    /// Posterior covariance Σ of [x_a, θ_E] (eq. (24)), (n_active + n_E)².
    pub covariance: Mat<f64>,
    /// Its inverse: the Schur complement S of the normal matrix at the
    /// optimum, the information about [x_a, θ_E] from data and priors.
    pub information: Mat<f64>,
    /// θ = [c, x_a, θ_E] at the optimum.
    pub theta: Vec<f64>,
    /// θ_E.
    pub theta_e: Vec<f64>,
    /// Posterior σ of θ_E.
    pub sigma_e: Vec<f64>,
    /// Names of θ_E.
    pub effect_params: Vec<EffectParam>,
    /// The fixed values θ_E is relative to ([`EffectSet::constants`]).
    pub effect_constants: Vec<EffectConstant>,
    /// Final cost ½‖r‖² (negative log-posterior up to a constant).
    pub cost: f64,
    /// The fitted trajectory.
    pub trajectory: Spline,
    /// Whitened IMU residuals at the optimum (sample index, r), IMU 0.
    pub residuals: Vec<(usize, [f64; 6])>,
    /// The same for IMU j ≥ 1 (`extra_residuals[j - 1]`; empty for one IMU).
    pub extra_residuals: Vec<Vec<(usize, [f64; 6])>>,
    /// Number of IMUs K (x has the layout [`ParamLayout::with_imus`]`(robot, K)`).
    pub n_imus: usize,
    /// The solver run.
    pub summary: LmSummary,
    /// The τ found before the fit (none when started from a given x or a
    /// fit), IMU 0.
    pub tau_initial: Option<TauEstimate>,
    /// The τ of IMU j ≥ 1 found before the fit (`extra_tau_initial[j - 1]`).
    pub extra_tau_initial: Vec<Option<TauEstimate>>,
    /// Knot spacing of the trajectory spline, s.
    pub knot_spacing: f64,
    /// Whitened residual RMS per joint of the initial spline fit.
    pub joint_fit_rms: Vec<f64>,
    /// IMU 0's noise model in the fit (white of σ_z unless
    /// [`CalibrateOptions::noise`] or [`CalibrateOptions::imu_noise`] gave
    /// one); its residuals are whitened by it.
    pub noise: NoiseModel,
    /// The same for IMU j ≥ 1 (`extra_noise[j - 1]`; empty for one IMU):
    /// each IMU's residuals are whitened by its own (docs/model.md §9).
    pub extra_noise: Vec<NoiseModel>,
}

impl Fit {
    /// RMS per IMU channel of the whitened residuals of every IMU
    /// (GLS-whitened with a noise model that is not white: about 1 when the
    /// model fits).
    pub fn residual_rms(&self) -> [f64; 6] {
        let all = || {
            self.residuals
                .iter()
                .chain(self.extra_residuals.iter().flatten())
        };
        let n = all().count().max(1) as f64;
        std::array::from_fn(|c| (all().map(|(_, r)| r[c] * r[c]).sum::<f64>() / n).sqrt())
    }

    /// IMU samples used over all IMUs.
    pub fn imu_samples_used(&self) -> usize {
        self.residuals.len() + self.extra_residuals.iter().map(Vec::len).sum::<usize>()
    }
}

/// Fit `spec` with `opts`; `report` sees every solver iteration (see the
/// module doc for the steps).
///
/// # Panics
/// With [`Start::Refit`] from a fit whose effects are not a prefix of the
/// spec's.
#[track_caller]
pub fn fit(
    spec: &FitSpec<'_>,
    opts: &CalibrateOptions,
    report: impl FnMut(&IterationRecord),
) -> Result<Fit, CalibrateError> {
    let FitSpec {
        robot,
        data,
        effects,
        start,
    } = *spec;
    check_measurements(robot, data)?;
    let n_imus = data.n_imus();
    let layout = ParamLayout::with_imus(robot, n_imus);
    let initial = match start {
        Start::Refit(f) | Start::RefitAt(f, _) => Initial::of_refit(f, effects, n_imus),
        Start::Nominal | Start::At(_) => Initial::of_joints(robot, data, opts, &layout, start)?,
    };
    let mut problem = Problem::new(
        robot,
        &layout,
        data,
        initial.spline.knots().clone(),
        initial.x.clone(),
        &opts.problem_options(),
        effects,
    )?;
    if initial.theta.is_none() {
        // a start far from the optimum: its first step from a thinned set
        problem.thin_first_iteration();
    }
    let mut theta0 = problem.theta(&initial.spline, &initial.x);
    if let Some(prev) = initial.theta {
        theta0[..prev.len()].copy_from_slice(prev);
    }
    let given = match start {
        Start::RefitAt(_, at) => Some(at),
        _ => None,
    };
    let sol = match solver::solve_from(&mut problem, theta0, given, &opts.lm, report) {
        Err(LmError::Unidentified { schur, .. }) => {
            let names = unidentified_names(&schur, problem.active(), &layout, opts.use_prior);
            return Err(CalibrateError::Unidentifiable { names });
        }
        sol => sol?,
    };
    if !sol.summary.termination.converged() {
        return Err(CalibrateError::NotConverged {
            summary: Box::new(sol.summary),
        });
    }
    fit_at_solution(&mut problem, sol, effects, (&layout, n_imus), initial)
}

/// The fit at the solver's solution `sol` of `problem`: x, its posterior
/// σ and covariance, θ_E, the residuals, the trajectory.
fn fit_at_solution(
    problem: &mut Problem,
    sol: solver::LmSolution,
    effects: &EffectSet,
    (layout, n_imus): (&ParamLayout, usize),
    initial: Initial<'_>,
) -> Result<Fit, CalibrateError> {
    // the solver ends with the problem set up at its final θ (samples
    // selected, levels) and its cost there
    let cost = sol.summary.final_cost;
    let active = problem.active().to_vec();
    let na = active.len();
    let covariance = sol.factor.covariance_x();
    let mut sigma_x = vec![0.0; layout.len()];
    for (a, &k) in active.iter().enumerate() {
        sigma_x[k] = covariance[(a, a)].max(0.0).sqrt();
    }
    let sigma_e = (0..effects.len())
        .map(|e| covariance[(na + e, na + e)].max(0.0).sqrt())
        .collect();
    let mut residuals = problem.take_residuals(&sol.theta)?;
    let extra_residuals = residuals.split_off(1);
    Ok(Fit {
        effects: effects.names().iter().map(|s| s.to_string()).collect(),
        x: problem.x_of(&sol.theta),
        sigma_x,
        information: sol.factor.schur().to_owned(),
        covariance,
        theta_e: problem.effect_params_of(&sol.theta).to_vec(),
        sigma_e,
        effect_params: effects.params().to_vec(),
        effect_constants: effects.constants(),
        cost,
        trajectory: problem.spline_of(&sol.theta),
        residuals: residuals.remove(0),
        extra_residuals,
        n_imus,
        active,
        theta: sol.theta,
        summary: sol.summary,
        tau_initial: initial.tau_initial[0],
        extra_tau_initial: initial.tau_initial[1..].to_vec(),
        knot_spacing: initial.knot_spacing,
        joint_fit_rms: initial.joint_fit_rms,
        noise: problem.noise().clone(),
        extra_noise: (1..n_imus).map(|j| problem.noise_of(j).clone()).collect(),
    })
}

/// The starting point of the solver and what led to it.
struct Initial<'f> {
    spline: Spline,
    x: Vec<f64>,
    /// θ of a previous fit (a prefix of the new θ).
    theta: Option<&'f [f64]>,
    /// Per IMU.
    tau_initial: Vec<Option<TauEstimate>>,
    knot_spacing: f64,
    joint_fit_rms: Vec<f64>,
}
impl<'f> Initial<'f> {
    /// The start of a refit: the previous fit's trajectory, x and θ.
    #[track_caller]
    fn of_refit(f: &'f Fit, effects: &EffectSet, n_imus: usize) -> Self {
        let names = effects.names();
        assert!(
            f.effects.len() <= names.len() && f.effects.iter().zip(&names).all(|(a, b)| a == b),
            "a refit extends the effects {:?} of its start, not {names:?}",
            f.effects
        );
        Initial {
            spline: f.trajectory.clone(),
            x: f.x.clone(),
            theta: Some(&f.theta),
            tau_initial: vec![None; n_imus],
            knot_spacing: f.knot_spacing,
            joint_fit_rms: f.joint_fit_rms.clone(),
        }
    }

    /// The start from the nominal or a given x (`start`): the trajectory
    /// spline fitted to the joint samples, and (from the nominal x) each
    /// IMU's τ found from the data when searched for and estimated.
    fn of_joints(
        robot: &Robot,
        data: &Measurements,
        opts: &CalibrateOptions,
        layout: &ParamLayout,
        start: Start<'_>,
    ) -> Result<Self, CalibrateError> {
        let tf = choose_knots(
            data,
            robot.dof(),
            &opts.sigma_q,
            opts.degree,
            opts.knot_spacing,
        )?;
        let mut x = match start {
            Start::At(x) => x.to_vec(),
            _ => layout.nominal(),
        };
        let tau_own = layout.imu_layout().offsets().tau;
        let mut tau_initial = vec![None; data.n_imus()];
        for (j, found) in tau_initial.iter_mut().enumerate() {
            let tau_at = layout.imu_map(j)[tau_own];
            *found = match (&opts.tau_search, start) {
                (Some(search), Start::Nominal) if !opts.frozen.contains(&tau_at) => {
                    let own = layout.imu_x(j, &x);
                    let model = MeasurementModel::new(robot, layout.imu_layout(), &own)?;
                    let imu = data.imu(j);
                    let gyro: Vec<[f64; 3]> = imu.z.iter().map(|z| [z[3], z[4], z[5]]).collect();
                    let rate = BodyRate::new(robot, &model);
                    let est = find_tau(&rate, &tf.spline, imu.t, &gyro, search)?;
                    x[tau_at] = est.tau;
                    Some(est)
                }
                _ => None,
            };
        }
        Ok(Initial {
            spline: tf.spline,
            x,
            theta: None,
            tau_initial,
            knot_spacing: tf.spacing,
            joint_fit_rms: tf.rms,
        })
    }
}
