//! The calibration: MAP estimate of x and the trajectory from one session
//! (paper §6), with the marginal posterior covariance of x (eq. (24)).
//!
//! 1. The [`fit`] of the baseline model: trajectory spline fitted to the
//!    joint samples, τ found from the data ([`super::time_offset`]),
//!    Levenberg–Marquardt from the nominal x (with that τ) over θ = [c, x],
//!    Σ_x = S⁻¹ with S the Schur complement of the normal matrix at the optimum.
//! 2. The information the data alone carries about x is checked for
//!    directions it does not determine (reported by parameter name).

pub mod fit;
#[cfg(test)]
mod gls_montecarlo;
#[cfg(test)]
mod newton_stop_tests;
pub mod noise_choice;
#[cfg(test)]
mod sandwich;
pub mod sandwich_fit;
#[cfg(test)]
pub(crate) mod sandwich_montecarlo;
#[cfg(test)]
mod tau_search_tests;

use faer::Side;
use robimu_session::result::{
    CalibrationResult, ChannelNoiseRecord, CovarianceMatrix, DirectionShare, ImuNoiseModelRecord,
    NoiseModelRecord, ParameterResult, WeakDirectionRecord, RESULT_FORMAT,
};

use super::time_offset::{TauError, TauEstimate, TauSearch};
use fit::FitSpec;
use robimu_model::noise::NoiseModel;
use robimu_model::observations::Measurements;
use robimu_model::spline::MAX_DEGREE;
use robimu_model::MAX_JOINTS;
use robimu_model::{Knots, ModelError, ParamLayout, Robot, SpanPolynomials, Spline, SplineError};
use robimu_solver::problem::{ProblemError, ProblemOptions};
use robimu_solver::{IterationRecord, LmError, LmOptions, LmSummary};

/// Calibration settings.
#[derive(Debug, Clone)]
pub struct CalibrateOptions {
    /// Interior knot spacing of the trajectory spline, s; `None` chooses it
    /// from the data ([`choose_knots`]).
    pub knot_spacing: Option<f64>,
    /// Spline degree.
    pub degree: usize,
    /// Use the priors (off: data only, for identifiability checks).
    pub use_prior: bool,
    /// Parameters held at their nominal value (indices into x).
    pub frozen: Vec<usize>,
    /// σ of `[ax, ay, az, gx, gy, gz]`.
    pub sigma_z: [f64; 6],
    /// The IMU noise model of the fit (None: white of `sigma_z`, the
    /// paper's model; given, it replaces `sigma_z` and the fit is the
    /// generalised least squares of [`robimu_solver::problem`]).
    pub noise: Option<NoiseModel>,
    /// Each IMU's own noise model (docs/model.md §9): IMU j's residuals are
    /// whitened by `imu_noise[j]` (its Σ_z of the paper's eq. (22)), one
    /// entry per IMU of the session; empty: `noise` (or white of `sigma_z`)
    /// serves every IMU. `--noise-model auto` fills it with the model
    /// identified from each IMU's own residuals ([`noise_choice`]).
    pub imu_noise: Vec<NoiseModel>,
    /// σ of each joint, rad.
    pub sigma_q: Vec<f64>,
    /// The τ search (None: start from the nominal τ).
    pub tau_search: Option<TauSearch>,
    /// Solver settings.
    pub lm: LmOptions,
}

impl CalibrateOptions {
    /// Defaults for `robot`: cubic spline, one knot per second, priors on, its noise.
    pub fn new(robot: &Robot) -> Self {
        Self {
            knot_spacing: None,
            degree: 3,
            use_prior: true,
            frozen: Vec::new(),
            sigma_z: robot.sigma_z(),
            noise: None,
            imu_noise: Vec::new(),
            sigma_q: robot.sigma_q().to_vec(),
            tau_search: Some(TauSearch::default()),
            lm: LmOptions::default(),
        }
    }

    /// How the calibration problem is set up with these settings.
    pub fn problem_options(&self) -> ProblemOptions {
        ProblemOptions {
            sigma_q: self.sigma_q.clone(),
            sigma_z: self.sigma_z,
            noise: if self.imu_noise.is_empty() {
                self.noise.clone().into_iter().collect()
            } else {
                self.imu_noise.clone()
            },
            use_prior: self.use_prior,
            frozen: self.frozen.clone(),
        }
    }
}

/// A parameter group the data barely determines.
#[derive(Debug, Clone, PartialEq)]
pub struct WeakDirection {
    /// Data information along the direction relative to the prior's (0 = none).
    pub relative_information: f64,
    /// The parameters that make up the direction, largest share first, with their share.
    pub parameters: Vec<(String, f64)>,
}

impl WeakDirection {
    /// Whether every parameter of the direction is a robot length error
    /// ε_i{1,2,3} of a link i < n (not the IMU position): the errors a slow
    /// motion cannot observe.
    pub fn only_robot_lengths(&self, layout: &ParamLayout) -> bool {
        let n = layout.n_links();
        self.parameters.iter().all(|(name, _)| {
            layout.index_of(name).is_some_and(|k| {
                layout
                    .estimated_errors()
                    .get(k)
                    .is_some_and(|e| e.is_length(n))
            })
        })
    }
}

/// The outcome of a calibration.
#[derive(Debug, Clone)]
pub struct Calibration {
    /// Every parameter of x, SI.
    pub x: Vec<f64>,
    /// Posterior σ of each parameter of x (0 when frozen).
    pub sigma: Vec<f64>,
    /// Estimated (not frozen) parameters, indices into x.
    pub active: Vec<usize>,
    /// Marginal covariance over `active` (row-major, active × active).
    pub covariance: Vec<f64>,
    /// The fitted trajectory.
    pub trajectory: Spline,
    /// The τ found before the fit.
    pub tau_initial: Option<TauEstimate>,
    /// Knot spacing used, s.
    pub knot_spacing: f64,
    /// Root-mean-square of the whitened joint residuals of the initial spline fit, per joint.
    pub joint_fit_rms: Vec<f64>,
    /// Solver run.
    pub summary: LmSummary,
    /// IMU samples used in the final fit.
    pub imu_samples_used: usize,
    /// Directions of x the data determines poorly (when the priors are on) or
    /// not at all (numerically singular information).
    pub weak_directions: Vec<WeakDirection>,
    /// Root-mean-square of the whitened residuals per IMU channel at the optimum.
    pub residual_rms: [f64; 6],
    /// The noise model the fit used for IMU 0 (for every IMU of a one-IMU
    /// session).
    pub noise_model: NoiseModel,
    /// The noise model the fit used for each IMU j ≥ 1
    /// (`extra_noise_models[j - 1]`; empty for one IMU; docs/model.md §9).
    pub extra_noise_models: Vec<NoiseModel>,
}

/// Why a calibration failed.
#[derive(Debug, thiserror::Error)]
pub enum CalibrateError {
    /// The session does not fit the robot.
    #[error("{0}")]
    Input(String),
    /// The joint trajectory could not be represented.
    #[error("the joint samples cannot be fitted by the trajectory spline: {0}")]
    Spline(#[from] SplineError),
    /// The model is invalid at the nominal parameters.
    #[error(transparent)]
    Model(#[from] ModelError),
    /// The time offset could not be found.
    #[error("cannot find the time offset between the IMU and the robot: {0}")]
    Tau(#[from] TauError),
    /// The problem could not be set up.
    #[error(transparent)]
    Problem(#[from] ProblemError),
    /// The solver failed.
    #[error("the fit failed: {0}")]
    Solver(#[from] LmError<ProblemError>),
    /// The fit did not converge.
    #[error(
        "the fit did not converge ({} iterations, cost {:.6e} -> {:.6e}: {})",
        summary.iterations.len(),
        summary.initial_cost,
        summary.final_cost,
        summary.termination
    )]
    NotConverged {
        /// The solver run.
        summary: Box<LmSummary>,
    },
    /// The data carries no information about some parameters and no priors were used.
    #[error("the data does not determine these parameters (use the priors, or freeze them): {}", names.join(", "))]
    Unidentifiable {
        /// Parameter names.
        names: Vec<String>,
    },
}

/// Check that a session fits the robot before any numerics.
pub(crate) fn check_measurements(robot: &Robot, data: &Measurements) -> Result<(), CalibrateError> {
    let n = robot.dof();
    let bad = |m: String| Err(CalibrateError::Input(m));
    if data.joint_t.is_empty() || data.imu_t.is_empty() {
        return bad("the session has no joint samples or no IMU samples".into());
    }
    if data.joint_q.len() != data.joint_t.len() * n {
        return bad(format!(
            "joints.csv has {} joint columns but robot `{}` has {n} joints",
            data.joint_q.len() / data.joint_t.len(),
            robot.name()
        ));
    }
    let (a, b) = (data.joint_t[0], *data.joint_t.last().expect("non-empty"));
    if b <= a {
        return bad("the joint samples span no time (all at one instant)".into());
    }
    for j in 0..data.n_imus() {
        let file = robimu_session::files::imu_csv(j);
        let t = data.imu(j).t;
        let (Some(&c), Some(&d)) = (t.first(), t.last()) else {
            return bad(format!("{file} has no samples"));
        };
        if d < a - 10.0 || c > b + 10.0 {
            return bad(format!(
                "the IMU samples of {file} ({c:.3}..{d:.3} s) do not overlap the joint samples ({a:.3}..{b:.3} s): are both files on the same session clock?"
            ));
        }
    }
    if let Some(v) = joint_outside_limits(robot, &data.joint_q) {
        return bad(v.to_string());
    }
    Ok(())
}

/// A joint sample far outside the robot's limits (docs/model.md §7.8): the
/// sign of joints recorded in degrees.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct JointLimitViolation {
    /// Joint index (0-based).
    pub joint: usize,
    /// Sample index (0-based).
    pub sample: usize,
    /// The sample's value, rad.
    pub q: f64,
    /// The joint's limits, rad.
    pub limits: (f64, f64),
}

impl std::fmt::Display for JointLimitViolation {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "joint {} sample {} is {:.3} rad, far outside the robot's limits [{:.3}, {:.3}]: are the joints in radians?",
            self.joint + 1,
            self.sample + 1,
            self.q,
            self.limits.0,
            self.limits.1
        )
    }
}

/// The first joint sample of `joint_q` (rows of the robot's joints) beyond
/// the robot's limits by more than 0.2 rad (recorded positions may overshoot
/// a planning limit a little), the joints in order: found by a search when
/// a first pass over the rows finds some sample beyond them.
pub(crate) fn joint_outside_limits(robot: &Robot, joint_q: &[f64]) -> Option<JointLimitViolation> {
    const SLACK: f64 = 0.2;
    // a robot has 1..=MAX_JOINTS joints
    let n = robot.dof();
    let (mut below, mut above) = ([f64::NEG_INFINITY; MAX_JOINTS], [f64::INFINITY; MAX_JOINTS]);
    for (j, lim) in robot.limits().iter().enumerate() {
        (below[j], above[j]) = (lim.q_min - SLACK, lim.q_max + SLACK);
    }
    let mut beyond = false;
    for row in joint_q.chunks_exact(n) {
        for ((q, b), a) in row.iter().zip(&below[..n]).zip(&above[..n]) {
            beyond |= (*q < *b) | (*q > *a);
        }
    }
    if !beyond && joint_q.len() % n == 0 {
        return None;
    }
    robot.limits().iter().enumerate().find_map(|(j, lim)| {
        joint_q
            .chunks(n)
            .map(|row| row[j])
            .enumerate()
            .find(|(_, q)| *q < lim.q_min - SLACK || *q > lim.q_max + SLACK)
            .map(|(sample, q)| JointLimitViolation {
                joint: j,
                sample,
                q,
                limits: (lim.q_min, lim.q_max),
            })
    })
}

/// Calibrate `robot` from `data`: the [`fit`](fn@fit::fit) of the baseline
/// model from the nominal x, then the check of the data's information for
/// weak directions. `report` sees every solver iteration.
pub fn calibrate(
    robot: &Robot,
    data: &Measurements,
    opts: &CalibrateOptions,
    report: impl FnMut(&IterationRecord),
) -> Result<Calibration, CalibrateError> {
    let f = fit::fit(&FitSpec::baseline(robot, data), opts, report)?;
    calibration_of(robot, opts, &f)
}

/// The calibration of a finished baseline fit `f` made with `opts`: the
/// check of the data's information for weak directions (module doc, step 2).
pub(crate) fn calibration_of(
    robot: &Robot,
    opts: &CalibrateOptions,
    f: &fit::Fit,
) -> Result<Calibration, CalibrateError> {
    let layout = ParamLayout::with_imus(robot, f.n_imus);
    let active = &f.active;
    let na = active.len();
    let info = data_information(&f.information, active, &layout, opts.use_prior);
    let weak_directions = weak_directions(&info, active, &layout, opts.use_prior);
    if !opts.use_prior && !weak_directions.is_empty() {
        return Err(CalibrateError::Unidentifiable {
            names: direction_names(&weak_directions),
        });
    }
    let cov = &f.covariance;
    let covariance = (0..na * na).map(|k| cov[(k / na, k % na)]).collect();
    Ok(Calibration {
        residual_rms: f.residual_rms(),
        noise_model: f.noise.clone(),
        extra_noise_models: f.extra_noise.clone(),
        imu_samples_used: f.imu_samples_used(),
        x: f.x.clone(),
        sigma: f.sigma_x.clone(),
        active: f.active.clone(),
        covariance,
        trajectory: f.trajectory.clone(),
        tau_initial: f.tau_initial,
        knot_spacing: f.knot_spacing,
        joint_fit_rms: f.joint_fit_rms.clone(),
        summary: f.summary.clone(),
        weak_directions,
    })
}

/// The trajectory spline chosen for a session.
#[derive(Debug, Clone)]
pub struct TrajectoryFit {
    /// Its knots.
    pub knots: Knots,
    /// Least-squares fit to the joint samples.
    pub spline: Spline,
    /// Knot spacing, s.
    pub spacing: f64,
    /// Whitened residual RMS per joint.
    pub rms: Vec<f64>,
}

/// Coarsest spacing tried when choosing automatically, s.
pub(crate) const AUTO_SPACING_START: f64 = 1.0;
/// Finest spacing tried when choosing automatically, s.
pub(crate) const AUTO_SPACING_MIN: f64 = 0.05;

/// Fit the trajectory spline to the joint samples ([`Spline::fit_on`] the
/// knots' span polynomials, which also give the residuals' basis).
///
/// With `spacing = Some(s)` the knots are every s seconds. With `None` the
/// spacing starts at [`AUTO_SPACING_START`] and is halved while the spline
/// cannot follow the joint samples to within their noise: while, for some
/// joint, the whitened residual sum of squares exceeds its degrees of freedom
/// by more than 5 standard deviations of χ² (a motion with more bandwidth
/// than the knots can carry, which would otherwise bias the IMU fit). It
/// stops at [`AUTO_SPACING_MIN`] or when a span would hold fewer than 4 joint
/// samples.
pub fn choose_knots(
    data: &Measurements,
    n: usize,
    sigma_q: &[f64],
    degree: usize,
    spacing: Option<f64>,
) -> Result<TrajectoryFit, SplineError> {
    let (a, b) = (
        data.joint_t[0],
        *data.joint_t.last().expect("checked non-empty"),
    );
    let samples = data.joint_t.len();
    let min_spacing = AUTO_SPACING_MIN.max(4.0 * (b - a) / samples as f64);
    let mut h = spacing.unwrap_or(AUTO_SPACING_START);
    loop {
        let knots = Knots::uniform(a, b, h, degree)?;
        let spans = SpanPolynomials::new(&knots);
        let spline = Spline::fit_on(&spans, n, &data.joint_t, &data.joint_q)?;
        let ss = whitened_squares(&spans, &spline, data, sigma_q);
        let dof = (samples as f64 - knots.num_coeffs() as f64).max(1.0);
        let rms: Vec<f64> = ss.iter().map(|v| (v / dof).sqrt()).collect();
        let too_coarse = ss.iter().any(|&v| v > dof + 5.0 * (2.0 * dof).sqrt());
        if spacing.is_some() || !too_coarse || h / 2.0 < min_spacing {
            return Ok(TrajectoryFit {
                knots,
                spline,
                spacing: h,
                rms,
            });
        }
        h /= 2.0;
    }
}

/// Per joint, the sum over the joint samples of the squared residual of
/// `spline` (on the knots of `spans`) in units of `sigma_q`. The samples in
/// two halves on two threads; the second half's terms are added after the
/// first's (the sums of one pass in sample order).
fn whitened_squares(
    spans: &SpanPolynomials,
    spline: &Spline,
    data: &Measurements,
    sigma_q: &[f64],
) -> Vec<f64> {
    let n = spline.dim();
    let (coeffs, count) = (spline.coeffs(), spline.knots().degree() + 1);
    // each sample's terms, as the basis forms q (Spline::evaluate_basis)
    let terms = |s: usize, span: &mut usize, out: &mut [f64]| {
        let mut v = [0.0; MAX_DEGREE + 1];
        let first = spans
            .values_near(data.joint_t[s], span, &mut v)
            .expect("a fitted sample is inside the knots");
        let mut q = [0.0; MAX_JOINTS];
        for a in 0..count {
            let c = &coeffs[(first + a) * n..(first + a + 1) * n];
            for j in 0..n {
                q[j] += v[a] * c[j];
            }
        }
        for j in 0..n {
            out[j] = (data.joint_q[s * n + j] - q[j]) / sigma_q[j];
            out[j] *= out[j];
        }
    };
    let samples = data.joint_t.len();
    let mid = samples / 2;
    let (mut ss, second) = robimu_model::pair::join(
        || {
            let (mut ss, mut out, mut span) = (vec![0.0; n], [0.0; MAX_JOINTS], 0);
            for s in 0..mid {
                terms(s, &mut span, &mut out[..n]);
                for j in 0..n {
                    ss[j] += out[j];
                }
            }
            ss
        },
        || {
            let (mut t, mut span) = (vec![0.0; (samples - mid) * n], 0);
            for (s, out) in (mid..samples).zip(t.chunks_exact_mut(n)) {
                terms(s, &mut span, out);
            }
            t
        },
    );
    for row in second.chunks_exact(n) {
        for j in 0..n {
            ss[j] += row[j];
        }
    }
    ss
}

/// Relative eigenvalue of the data information below which a direction is
/// numerically undetermined (rounding level for 48 parameters; weakly but
/// truly determined directions, such as the robot lengths at low speed, sit
/// near 1e-11).
pub(crate) const SINGULAR: f64 = 1e-13;

/// Directions in which the data's information (prior-σ units) is negligible:
/// below [`SINGULAR`] of the largest (numerically singular), or — with priors — below
/// 0.01 of the prior's (the data adds almost nothing to the prior there).
/// The information about the active x from the data alone, in units of
/// the prior σ: the Schur complement S (eq. (24); data and priors) less the
/// priors when they are used, scaled by σ_i σ_j and symmetrised.
fn data_information(
    schur: &faer::Mat<f64>,
    active: &[usize],
    layout: &ParamLayout,
    use_prior: bool,
) -> faer::Mat<f64> {
    let na = active.len();
    let specs = layout.specs();
    let mut info = faer::Mat::from_fn(na, na, |i, j| {
        let (si, sj) = (specs[active[i]].sigma, specs[active[j]].sigma);
        let prior = if use_prior && i == j {
            1.0 / (si * si)
        } else {
            0.0
        };
        (schur[(i, j)] - prior) * si * sj
    });
    for i in 0..na {
        for j in 0..i {
            let v = 0.5 * (info[(i, j)] + info[(j, i)]);
            info[(i, j)] = v;
            info[(j, i)] = v;
        }
    }
    info
}

/// The parameters the directions involve, each once, in order.
fn direction_names(directions: &[WeakDirection]) -> Vec<String> {
    let mut names: Vec<String> = Vec::new();
    for (name, _) in directions.iter().flat_map(|w| &w.parameters) {
        if !names.contains(name) {
            names.push(name.clone());
        }
    }
    names
}

/// The parameters of the directions a singular information S at the
/// solution leaves undetermined ([`LmError::Unidentified`]): those of its
/// (near-)null directions, or all active ones if none stands out.
fn unidentified_names(
    schur: &faer::Mat<f64>,
    active: &[usize],
    layout: &ParamLayout,
    use_prior: bool,
) -> Vec<String> {
    let info = data_information(schur, active, layout, use_prior);
    let names = direction_names(&weak_directions(&info, active, layout, false));
    if names.is_empty() {
        active
            .iter()
            .map(|&k| layout.specs()[k].name.clone())
            .collect()
    } else {
        names
    }
}

fn weak_directions(
    info: &faer::Mat<f64>,
    active: &[usize],
    layout: &ParamLayout,
    use_prior: bool,
) -> Vec<WeakDirection> {
    let Ok(evd) = info.self_adjoint_eigen(Side::Lower) else {
        return Vec::new();
    };
    let s = evd.S();
    let u = evd.U();
    let na = active.len();
    let max = (0..na).map(|i| s[i]).fold(0.0f64, f64::max);
    let mut out = Vec::new();
    for k in 0..na {
        let lam = s[k];
        let singular = lam <= SINGULAR * max;
        let weak = use_prior && lam < 1e-2;
        if !(singular || weak) {
            continue;
        }
        let mut parts: Vec<(String, f64)> = (0..na)
            .map(|i| {
                (
                    layout.specs()[active[i]].name.clone(),
                    u[(i, k)] * u[(i, k)],
                )
            })
            .filter(|(_, w)| *w > 0.05)
            .collect();
        parts.sort_by(|a, b| b.1.total_cmp(&a.1));
        out.push(WeakDirection {
            relative_information: lam.max(0.0),
            parameters: parts,
        });
    }
    out
}

impl Calibration {
    /// The parameter layout of this calibration's x for `robot`: one IMU
    /// or, for a multi-IMU session, [`ParamLayout::with_imus`] (docs/model.md §9).
    ///
    /// # Panics
    /// If x fits no layout of `robot`.
    pub fn layout(&self, robot: &Robot) -> ParamLayout {
        let k = ParamLayout::imus_for_len(robot, self.x.len())
            .expect("a calibration's x has the length of a layout of its robot");
        ParamLayout::with_imus(robot, k)
    }

    /// The result file (docs/model.md §8) of this calibration, for the
    /// parameter layout it was computed with.
    ///
    /// # Panics
    /// If `calibration` does not belong to `layout` (different lengths).
    #[track_caller]
    pub fn to_result(&self, layout: &ParamLayout) -> CalibrationResult {
        let calibration = self;
        let specs = layout.specs();
        assert_eq!(calibration.x.len(), specs.len(), "x length");
        let active = &calibration.active;
        let na = active.len();
        let parameters = specs
            .iter()
            .enumerate()
            .map(|(k, s)| ParameterResult {
                name: s.name.clone(),
                unit: s.unit.to_string(),
                value: calibration.x[k],
                prior: s.nominal,
                prior_sigma: s.sigma,
                sigma: calibration.sigma[k],
                frozen: !active.contains(&k),
            })
            .collect();
        let covariance = CovarianceMatrix {
            names: active.iter().map(|&k| specs[k].name.clone()).collect(),
            matrix: (0..na)
                .map(|i| calibration.covariance[i * na..(i + 1) * na].to_vec())
                .collect(),
        };
        let summary = &calibration.summary;
        CalibrationResult {
            format: RESULT_FORMAT.into(),
            parameters,
            covariance,
            robot: None,
            source: None,
            session: None,
            priors_used: None,
            tau_initial: calibration.tau_initial.as_ref().map(|t| t.tau),
            knot_spacing: Some(calibration.knot_spacing),
            iterations: Some(summary.iterations.len()),
            initial_cost: Some(summary.initial_cost),
            final_cost: Some(summary.final_cost),
            termination: Some(summary.termination.to_string()),
            residual_rms: Some(calibration.residual_rms),
            imu_samples_used: Some(calibration.imu_samples_used),
            noise_model: Some(noise_model_record(&calibration.noise_model)),
            imu_noise_models: imu_noise_records(&calibration.extra_noise_models),
            noise_warning: None,
            verdict: None,
            effects: None,
            model_tests: None,
            pose_accuracy: None,
            covariance_kind: None,
            weak_directions: calibration
                .weak_directions
                .iter()
                .map(|w| WeakDirectionRecord {
                    relative_information: w.relative_information,
                    parameters: w
                        .parameters
                        .iter()
                        .map(|(name, share)| DirectionShare {
                            name: name.clone(),
                            share: *share,
                        })
                        .collect(),
                })
                .collect(),
        }
    }
}

/// The result.json records of the noise models of IMUs j ≥ 1
/// (`extra[j - 1]`), each named by its IMU's parameter prefix `imu<j>`
/// (docs/model.md §8.2, §9); empty for one IMU.
fn imu_noise_records(extra: &[NoiseModel]) -> Vec<ImuNoiseModelRecord> {
    extra
        .iter()
        .enumerate()
        .map(|(k, m)| ImuNoiseModelRecord {
            imu: format!("imu{}", k + 1),
            noise_model: noise_model_record(m),
        })
        .collect()
}

/// The result.json record of a noise model (`{"kind": "white"}` when white).
pub fn noise_model_record(m: &NoiseModel) -> NoiseModelRecord {
    if m.is_white() {
        return NoiseModelRecord::White;
    }
    NoiseModelRecord::Ar {
        channels: m
            .imu
            .iter()
            .map(|c| ChannelNoiseRecord {
                phi: c.ar.phi().to_vec(),
                sigma: c.ar.sigma(),
                motion: c.motion,
            })
            .collect(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    /// The former search: joint by joint, the first sample beyond the limits.
    fn search(robot: &Robot, joint_q: &[f64]) -> Option<JointLimitViolation> {
        let n = robot.dof();
        robot.limits().iter().enumerate().find_map(|(j, lim)| {
            joint_q
                .chunks(n)
                .map(|row| row[j])
                .enumerate()
                .find(|(_, q)| *q < lim.q_min - 0.2 || *q > lim.q_max + 0.2)
                .map(|(sample, q)| JointLimitViolation {
                    joint: j,
                    sample,
                    q,
                    limits: (lim.q_min, lim.q_max),
                })
        })
    }

    /// With the first pass over the extremes, the violation found is the
    /// search's: none inside the limits (and at the slack's edge), the first
    /// in joint order when several joints and samples are beyond them.
    #[test]
    fn joint_outside_limits_is_the_searchs() {
        let robot = Robot::aubo_i5();
        let (n, lims) = (robot.dof(), robot.limits());
        let mut rng = rand::rngs::StdRng::seed_from_u64(4);
        let mut q: Vec<f64> = (0..500 * n)
            .map(|k| {
                let l = &lims[k % n];
                rng.random_range(l.q_min..l.q_max)
            })
            .collect();
        assert_eq!(joint_outside_limits(&robot, &q), None);
        q[7 * n + 2] = lims[2].q_max + 0.2;
        q[9 * n + 4] = lims[4].q_min - 0.2;
        assert_eq!(joint_outside_limits(&robot, &q), None);
        for (sample, joint, v) in [(300, 4, -9.0), (100, 4, 9.0), (400, 1, 1e3), (2, 5, -1e3)] {
            q[sample * n + joint] = v;
            assert_eq!(joint_outside_limits(&robot, &q), search(&robot, &q));
            assert!(joint_outside_limits(&robot, &q).is_some());
        }
        assert_eq!(joint_outside_limits(&robot, &q).unwrap().joint, 1);
    }
}
