//! Levenberg–Marquardt on an arrowhead-structured least-squares problem.
//!
//! Minimises J(θ) = ½‖r(θ)‖². Each iteration solves
//! (A + λ·D) δ = −g with A = JᵀJ, g = Jᵀr and D = diag(A) (Marquardt's scaling,
//! so the damping does not depend on the units of θ), accepts the step when
//! the cost decreases, and updates λ by Nielsen's rule from the gain ratio
//! ρ = (actual decrease) / (decrease predicted by the quadratic model).
//!
//! [`solve`] is an outline of named steps (as Ceres'
//! `TrustRegionMinimizer::Minimize`); each stopping rule is a predicate with
//! its reasoning in its doc: `gradient_tolerance_reached`,
//! `function_tolerance_reached`, `parameter_tolerance_reached`,
//! `model_predicts_no_decrease`, `at_rounding_floor`,
//! `damping_exhausted`, `stationary` and `newton_tolerance_reached`
//! (*The last step*: the Newton step is taken without linearising after
//! it); `max_iterations` bounds the loop.
//!
//! A trial step is evaluated by its cost, or — when the problem says its
//! set-up would not change there ([`LeastSquares::keeps_setup`]) and it is
//! the iteration's first try — by linearising at it: an accepted step's
//! linearisation is then the next iteration's (and the final one's), so no
//! separate cost evaluation is needed. Later tries of an iteration (after a
//! rejection, when another is likely: a cost far from quadratic, a refit
//! whose damping climbs over several tries) are evaluated by their cost
//! alone, so a rejected step costs a cost evaluation, not a linearisation.
//! The initial cost is the first linearisation's.

use super::arrow::{ArrowFactor, ArrowMatrix, FactorError};

/// A problem the solver can drive.
pub trait LeastSquares {
    /// The error of an evaluation (outside the domain, …).
    type Error: std::error::Error + Send + Sync + 'static;
    /// Called at the start of every iteration, with the current θ (e.g. to
    /// choose which samples enter the cost).
    fn begin_iteration(&mut self, theta: &[f64]) -> Result<(), Self::Error>;
    /// Cost ½‖r‖² at θ. An error means θ is not acceptable (the step is rejected).
    fn cost(&self, theta: &[f64]) -> Result<f64, Self::Error>;
    /// The cost at θ where the solver may end (its last step, *The last
    /// step* in the doc of `newton_tolerance_reached`): a problem can keep
    /// what it computed there.
    /// Default: [`Self::cost`].
    fn end_cost(&mut self, theta: &[f64]) -> Result<f64, Self::Error> {
        self.cost(theta)
    }
    /// Cost, Gauss–Newton matrix and gradient at θ.
    fn linearize(
        &self,
        theta: &[f64],
        a: &mut ArrowMatrix,
        g: &mut [f64],
    ) -> Result<f64, Self::Error>;
    /// Storage for [`Self::linearize`].
    fn new_matrix(&self) -> ArrowMatrix;
    /// Whether [`Self::begin_iteration`] at θ would leave the cost function
    /// as it is now (e.g. the same samples selected, nothing re-weighted):
    /// then the solver evaluates a trial step at θ by linearising (module
    /// doc). Default: false (trial steps by [`Self::cost`]).
    fn keeps_setup(&self, _theta: &[f64]) -> bool {
        false
    }
}

/// Solver settings.
#[derive(Debug, Clone)]
pub struct LmOptions {
    /// Most iterations (linearisations).
    pub max_iterations: usize,
    /// Stop when an accepted step lowers the cost by less than this fraction.
    pub function_tolerance: f64,
    /// Stop when ‖δ_k / (|θ_k| + s_k)‖∞ is below this.
    pub parameter_tolerance: f64,
    /// Stop when max |g_k| / √A_kk (the gradient in whitened units) is below this.
    pub gradient_tolerance: f64,
    /// Initial damping λ.
    pub initial_lambda: f64,
    /// Take the last Gauss–Newton step without linearising after it when
    /// the point it reaches is the minimum to this, in conditional σ (*The
    /// last step* in the doc of `newton_tolerance_reached`); 0 disables it. The default, 10⁻⁴ σ, is a cost
    /// excess of 5·10⁻⁹, far below what `function_tolerance` resolves.
    pub newton_tolerance: f64,
    /// Stop when an accepted, nearly undamped (λ ≤ 10⁻³) step moved every
    /// unknown by less than this fraction of its conditional σ (1/√A_kk,
    /// at most its marginal σ): what is left to gain is far below the
    /// estimate's uncertainty ([`Termination::SigmaTolerance`]); 0 (the
    /// default) disables it.
    pub sigma_tolerance: f64,
}

impl Default for LmOptions {
    fn default() -> Self {
        Self {
            max_iterations: 100,
            function_tolerance: 1e-10,
            parameter_tolerance: 1e-12,
            gradient_tolerance: 1e-10,
            initial_lambda: 1e-4,
            newton_tolerance: 1e-4,
            sigma_tolerance: 0.0,
        }
    }
}

impl LmOptions {
    /// Check that every setting is usable.
    pub fn validate(&self) -> Result<(), String> {
        let pos = |v: f64| v.is_finite() && v >= 0.0;
        if self.max_iterations == 0 {
            return Err("max_iterations must be at least 1".into());
        }
        if !(pos(self.function_tolerance)
            && pos(self.parameter_tolerance)
            && pos(self.gradient_tolerance)
            && pos(self.newton_tolerance)
            && pos(self.sigma_tolerance))
        {
            return Err("tolerances must be finite and non-negative".into());
        }
        if !(self.initial_lambda.is_finite() && self.initial_lambda > 0.0) {
            return Err("initial_lambda must be positive".into());
        }
        Ok(())
    }
}

/// One line of the iteration log.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IterationRecord {
    /// Iteration number, from 1.
    pub iteration: usize,
    /// Cost after the iteration.
    pub cost: f64,
    /// Scaled step length ‖√D δ‖ of the last step tried.
    pub step_norm: f64,
    /// Damping used for the last step tried.
    pub lambda: f64,
    /// Gradient in whitened units, max |g_k|/√A_kk, at the start of the iteration.
    pub gradient_norm: f64,
    /// Steps tried in this iteration (1 + rejections).
    pub tries: usize,
}

impl IterationRecord {
    /// The column header of the iteration log (the columns of [`Display`](std::fmt::Display)).
    pub const HEADER: &'static str = "iter           cost       step    lambda   gradient";
}

impl std::fmt::Display for IterationRecord {
    /// One line of the iteration log: iteration, cost, step, λ, gradient.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{:>4} {:>14.6e} {:>10.3e} {:>9.1e} {:>10.3e}",
            self.iteration, self.cost, self.step_norm, self.lambda, self.gradient_norm
        )
    }
}

/// Why the solver stopped.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Termination {
    /// Relative cost decrease below the function tolerance.
    FunctionTolerance,
    /// Step below the parameter tolerance.
    ParameterTolerance,
    /// Gradient below the gradient tolerance.
    GradientTolerance,
    /// The last Gauss–Newton step reached the minimum to the Newton tolerance.
    NewtonTolerance,
    /// Step below the σ tolerance ([`LmOptions::sigma_tolerance`]).
    SigmaTolerance,
    /// Iteration limit reached before convergence.
    MaxIterations,
    /// No step lowered the cost even with very strong damping.
    NoProgress,
}

impl Termination {
    /// Whether this counts as convergence.
    pub fn converged(self) -> bool {
        !matches!(self, Termination::MaxIterations | Termination::NoProgress)
    }
}

impl std::fmt::Display for Termination {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Termination::FunctionTolerance => "converged (cost change below tolerance)",
            Termination::ParameterTolerance => "converged (step below tolerance)",
            Termination::GradientTolerance => "converged (gradient below tolerance)",
            Termination::NewtonTolerance => "converged (Newton step at the minimum)",
            Termination::SigmaTolerance => "converged (step below the σ tolerance)",
            Termination::MaxIterations => "stopped at the iteration limit without converging",
            Termination::NoProgress => "stopped: no step lowers the cost",
        })
    }
}

/// What the solver did.
#[derive(Debug, Clone)]
pub struct LmSummary {
    /// Cost at the start.
    pub initial_cost: f64,
    /// Cost at the end.
    pub final_cost: f64,
    /// The iteration log.
    pub iterations: Vec<IterationRecord>,
    /// Why it stopped.
    pub termination: Termination,
}

impl std::fmt::Display for LmSummary {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        writeln!(f, "{}", IterationRecord::HEADER)?;
        for r in &self.iterations {
            writeln!(f, "{r}")?;
        }
        write!(
            f,
            "cost {:.6e} -> {:.6e}: {}",
            self.initial_cost, self.final_cost, self.termination
        )
    }
}

/// Why the solver could not run at all.
#[derive(Debug, thiserror::Error)]
pub enum LmError<E: std::error::Error + 'static> {
    /// The problem could not be evaluated at the starting point.
    #[error("the problem cannot be evaluated at the starting point: {0}")]
    Start(#[source] E),
    /// The options are invalid.
    #[error("invalid solver options: {0}")]
    Options(String),
    /// The undamped normal matrix at the solution is singular.
    #[error(transparent)]
    Factor(#[from] FactorError),
    /// The solver converged, but the information about x at the solution
    /// (the Schur complement S, eq. (24)) is singular: the data and priors
    /// do not determine some direction of x. S is returned for naming it.
    #[error("the information about the model parameters is singular at the solution")]
    Unidentified {
        /// The estimate.
        theta: Vec<f64>,
        /// S at θ (nx × nx), not positive definite.
        schur: faer::Mat<f64>,
    },
}

/// The solution: θ, the summary, and the factored normal matrix at θ.
pub struct LmSolution {
    /// The estimate.
    pub theta: Vec<f64>,
    /// The run.
    pub summary: LmSummary,
    /// The undamped Gauss–Newton matrix at θ, factored (for covariances).
    pub factor: ArrowFactor,
}

/// Relative rounding level of the cost: changes of J smaller than
/// `COST_ROUNDING · J` are not resolved by its evaluation.
///
/// J = ½ Σ r_i², r_i = (z_i − h_i(θ))/σ_i. Each h_i is computed to a few ulps
/// of |h_i|, which can be 10³ σ_i (gravity against the accelerometer's
/// noise), so r_i carries an error up to ~10³ ε ≈ 2·10⁻¹³ in units of σ.
/// When these errors do not average out (the model's rounding is
/// deterministic, not random) δJ = Σ r_i δr_i reaches ~2·10³ ε · J/|r|_rms
/// ≈ 4·10⁻¹³ J at |r|_rms ≈ 1, plus the summation's own O(ε log N) J.
/// Costs closer than 10⁻¹² J are therefore equal to rounding.
pub(crate) const COST_ROUNDING: f64 = 1e-12;

/// Largest whitened gradient max_k |g_k|/√A_kk at which a step lost in the
/// cost's rounding counts as convergence ([`at_rounding_floor`]).
///
/// In whitened units (J = ½χ², as the calibration's cost is) ½·0.1² bounds
/// from below the decrease the undamped model still claims, and 0.1 the
/// coordinate step to its optimum in σ: below anything a test statistic or
/// a covariance resolves. A larger gradient with no acceptable step is a
/// wrong Jacobian or a real non-minimum, reported as `NoProgress`.
pub(crate) const ROUNDING_GRADIENT: f64 = 0.1;

/// Stop when the gradient is below `gradient_tolerance`: max_k |g_k|/√D_k
/// (the gradient in whitened units, `gnorm`) at the start of an iteration,
/// before any step is tried.
fn gradient_tolerance_reached(opts: &LmOptions, gnorm: f64) -> bool {
    gnorm < opts.gradient_tolerance
}

/// Stop when an accepted step lowered the cost from `cost` to `new_cost` by
/// less than the fraction `function_tolerance` of it (Ceres' relative
/// cost decrease).
fn function_tolerance_reached(opts: &LmOptions, cost: f64, new_cost: f64) -> bool {
    let rel = (cost - new_cost) / cost.max(f64::MIN_POSITIVE);
    rel < opts.function_tolerance
}

/// Stop when an accepted step `delta` from `theta` is short: every
/// |δ_k| ≤ `parameter_tolerance` · (|θ_k| + s_k), with s_k = 1/√D_k the
/// coordinate's conditional σ (so a parameter at 0 is measured in σ).
fn parameter_tolerance_reached(opts: &LmOptions, delta: &[f64], theta: &[f64], d: &[f64]) -> bool {
    delta
        .iter()
        .zip(theta)
        .zip(d)
        .all(|((dt, t), dk)| dt.abs() <= opts.parameter_tolerance * (t.abs() + 1.0 / dk.sqrt()))
}

/// Stop when an accepted step `delta` taken at damping `lambda` ≤ 10⁻³
/// is below `sigma_tolerance` in every unknown, measured in its
/// conditional σ 1/√D_k: max_k |δ_k|·√D_k < `sigma_tolerance`.
fn sigma_tolerance_reached(opts: &LmOptions, delta: &[f64], d: &[f64], lambda: f64) -> bool {
    opts.sigma_tolerance > 0.0
        && lambda <= 1e-3
        && delta
            .iter()
            .zip(d)
            .all(|(dt, dk)| dt.abs() * dk.sqrt() < opts.sigma_tolerance)
}

/// Decrease of the cost (J = ½χ², whitened) below which a rejected first
/// try at a gradient below [`ROUNDING_GRADIENT`] ends the run
/// ([`model_predicts_no_decrease`]): 10⁻³ is a likelihood-ratio statistic
/// of 0.002, and bounds the distance to the model's minimum by
/// √(2·10⁻³) ≈ 0.045 conditional σ — below what any test or covariance
/// resolves.
pub(crate) const NEGLIGIBLE_DECREASE: f64 = 1e-3;

/// Stop at the first rejected step of an iteration (`tries` = 1) when the
/// decrease the quadratic model predicts for it is non-negative and either
/// below `function_tolerance` · J, or below [`NEGLIGIBLE_DECREASE`] at a
/// whitened gradient `gnorm` below [`ROUNDING_GRADIENT`]: even the (least
/// damped) model predicts no meaningful decrease, so the cost is at its
/// minimum to rounding or to what any statistic resolves. A rejected try
/// leaves θ where it is, so stopping here ends at the same θ as damping on
/// until the rounding floor would; with a Jacobian that neglects a small
/// cross-derivative (e.g. the resonance response's dependence on the
/// spline, docs/model.md §7) every further try raises the cost, and
/// damping on costs up to eight cost evaluations for nothing.
fn model_predicts_no_decrease(
    opts: &LmOptions,
    tries: usize,
    predicted: f64,
    cost: f64,
    gnorm: f64,
) -> bool {
    tries == 1
        && predicted >= 0.0
        && (predicted < opts.function_tolerance * cost
            || (gnorm <= ROUNDING_GRADIENT && predicted < NEGLIGIBLE_DECREASE))
}

/// Whether a rejected step only failed because the cost is flat to
/// rounding: the decrease the damped model predicts and the actual change
/// are both below [`COST_ROUNDING`] · J, and the gradient is below
/// [`ROUNDING_GRADIENT`]. Whatever the number of tries: with a gradient a
/// little inconsistent with the cost (weights frozen over an iteration,
/// neglected second-order terms) every step may raise J until the damping
/// has shrunk it below rounding.
fn at_rounding_floor(cost: f64, new_cost: f64, predicted: f64, gnorm: f64) -> bool {
    let level = COST_ROUNDING * cost.abs();
    new_cost.is_finite()
        && (cost - new_cost).abs() <= level
        && predicted.abs() <= level
        && gnorm <= ROUNDING_GRADIENT
}

/// Stop when no step lowers the cost at any damping: the next λ (λ·ν)
/// would exceed 10¹⁶. Whether that is convergence is [`stationary`]'s.
fn damping_exhausted(lambda: f64, nu: f64) -> bool {
    lambda * nu > 1e16
}

/// When no step lowers the cost at any damping ([`damping_exhausted`]),
/// whether the point counts as the minimum: at a whitened gradient `gnorm`
/// below [`ROUNDING_GRADIENT`] it is stationary to 0.1σ, to what any
/// statistic resolves (the cost's own discontinuities, e.g. the sample
/// set, exceed the decrease left); above it the run ends `NoProgress`.
fn stationary(gnorm: f64) -> bool {
    gnorm <= ROUNDING_GRADIENT
}

/// Whether a step of scaled length `step` is the last one: the previous
/// accepted step `last` = (length, gain ratio) was modelled well (ρ within
/// 0.75–1.25), the damping λ is negligible (≤ 10⁻³), and the error left
/// after the step, estimated as step²/last (the step times the rate of the
/// last two), is below the Newton tolerance.
///
/// **The last step.** Near the minimum the steps shrink by a rate
/// r ≈ ‖δ_k‖/‖δ_{k−1}‖ per iteration, norms scaled by √D so that a
/// coordinate's length is in units of its conditional σ (which bounds it in
/// marginal σ): Gauss–Newton converges linearly when the residuals do not
/// vanish (r of the order of the residuals' curvature over √N: about 10⁻³
/// on a 300 s session) and faster when they do, where the linear model is
/// an upper bound. So the point θ_k + δ_k is off the minimum by about
/// e = r‖δ_k‖ = ‖δ_k‖²/‖δ_{k−1}‖. When e < `newton_tolerance`, the previous
/// step's gain ratio was near 1 (the quadratic model holds), the damping is
/// negligible and the problem's set-up stays, the step is taken and the
/// solver stops: only the cost is evaluated there (it must not rise), and
/// the covariance uses the linearisation at θ_k, whose matrix differs from
/// the one at θ_k + δ_k by O(r) relative. This saves the linearisation a
/// final accepted step would cost only to show that nothing is left to gain.
fn newton_tolerance_reached(
    opts: &LmOptions,
    last: Option<(f64, f64)>,
    step: f64,
    lambda: f64,
) -> bool {
    let Some((prev, rho)) = last else {
        return false;
    };
    opts.newton_tolerance > 0.0
        && lambda <= 1e-3
        && (0.75..=1.25).contains(&rho)
        && prev > 0.0
        && step.is_finite()
        && step * step / prev < opts.newton_tolerance
}

/// Run Levenberg–Marquardt from `theta`. `report` sees every iteration.
pub fn solve<P: LeastSquares>(
    problem: &mut P,
    theta: Vec<f64>,
    opts: &LmOptions,
    report: impl FnMut(&IterationRecord),
) -> Result<LmSolution, LmError<P::Error>> {
    solve_from(problem, theta, None, opts, report)
}

/// The problem's linearisation at a point: what
/// [`LeastSquares::linearize`] writes and returns there.
#[derive(Debug, Clone)]
pub struct Linearization {
    /// The Gauss–Newton matrix.
    pub a: ArrowMatrix,
    /// The gradient.
    pub g: Vec<f64>,
    /// The cost.
    pub cost: f64,
}

/// [`solve`] given the linearisation at `theta` (`at`, e.g. a restriction
/// of a larger problem's made there already: the diagnosis's score tests,
/// docs/model.md §4.9), which the first iteration takes instead of
/// linearising. It must be the problem's own at `theta` (after
/// `begin_iteration` there); one of other dimensions is refused.
pub fn solve_from<P: LeastSquares>(
    problem: &mut P,
    theta: Vec<f64>,
    at: Option<&Linearization>,
    opts: &LmOptions,
    report: impl FnMut(&IterationRecord),
) -> Result<LmSolution, LmError<P::Error>> {
    opts.validate().map_err(LmError::Options)?;
    let mut run = Run::new(problem, theta, opts, report);
    if let Some(at) = at {
        if at.a.dims() != run.a.dims() || at.g.len() != run.theta.len() {
            return Err(LmError::Options(format!(
                "the given linearisation has dimensions {:?} and {} unknowns, the problem {:?} and {}",
                at.a.dims(),
                at.g.len(),
                run.a.dims(),
                run.theta.len()
            )));
        }
        run.a_next.clone_from(&at.a);
        run.g_next.clone_from(&at.g);
        run.ahead = Some(at.cost);
    }
    problem
        .begin_iteration(&run.theta)
        .map_err(LmError::Start)?;
    let mut termination = Termination::MaxIterations;
    for iteration in 1..=opts.max_iterations {
        if iteration > 1 {
            // the selected sample set may change with θ; the cost is re-evaluated below
            problem
                .begin_iteration(&run.theta)
                .map_err(LmError::Start)?;
        }
        if let Some(reason) = run.iteration(problem, iteration)? {
            termination = reason;
            break;
        }
    }
    let final_cost = run.final_linearization(problem)?;
    run.finish(final_cost, termination)
}

/// The solver's state across iterations.
struct Run<'o, R> {
    opts: &'o LmOptions,
    /// The estimate.
    theta: Vec<f64>,
    /// The Gauss–Newton matrix and gradient at θ.
    a: ArrowMatrix,
    g: Vec<f64>,
    /// The linearisation at an accepted trial step (module doc), and its
    /// cost (`ahead`) while it is the one at θ.
    a_next: ArrowMatrix,
    g_next: Vec<f64>,
    ahead: Option<f64>,
    /// The damping λ, and ν, its factor after a rejected step (Nielsen).
    lambda: f64,
    nu: f64,
    /// The cost of the first linearisation.
    initial_cost: Option<f64>,
    /// The iteration log, and who else sees it.
    log: Vec<IterationRecord>,
    report: R,
    /// The step being tried.
    delta: Vec<f64>,
    /// The cost of `a` when it is the linearisation at the final θ (or,
    /// after a Newton stop, the one the covariance uses).
    current: Option<f64>,
    /// The scaled length of the last accepted step, and its gain ratio.
    last_step: Option<(f64, f64)>,
}

/// An iteration's starting point: its number, the cost at θ, the scaling D
/// and the whitened gradient max_k |g_k|/√D_k.
struct IterationStart {
    iteration: usize,
    cost: f64,
    d: Vec<f64>,
    gnorm: f64,
}

/// A step tried from θ (θ + δ, δ in [`Run::delta`]).
struct Trial {
    /// Which try of the iteration, from 1.
    tries: usize,
    /// Whether the damped system gave a finite step.
    step_ok: bool,
    /// θ + δ.
    candidate: Vec<f64>,
    /// The decrease the damped quadratic model predicts.
    predicted: f64,
    /// ‖√D δ‖.
    step_norm: f64,
    /// The cost at the candidate (∞ when not evaluated or not acceptable).
    new_cost: f64,
    /// Whether the candidate was evaluated by linearising (into `a_next`).
    linearized: bool,
}

impl<'o, R: FnMut(&IterationRecord)> Run<'o, R> {
    fn new<P: LeastSquares>(problem: &P, theta: Vec<f64>, opts: &'o LmOptions, report: R) -> Self {
        let n = theta.len();
        Self {
            opts,
            theta,
            a: problem.new_matrix(),
            g: vec![0.0; n],
            a_next: problem.new_matrix(),
            g_next: vec![0.0; n],
            ahead: None,
            lambda: opts.initial_lambda,
            nu: 2.0,
            initial_cost: None,
            log: Vec::new(),
            report,
            delta: vec![0.0; n],
            current: None,
            last_step: None,
        }
    }

    /// One iteration (after `begin_iteration`): linearise at θ, then try
    /// steps until one is accepted or a stopping rule holds.
    fn iteration<P: LeastSquares>(
        &mut self,
        problem: &mut P,
        iteration: usize,
    ) -> Result<Option<Termination>, LmError<P::Error>> {
        let at = self.start(problem, iteration)?;
        if gradient_tolerance_reached(self.opts, at.gnorm) {
            self.current = Some(at.cost);
            self.record(&at, at.cost, 0.0, 0);
            return Ok(Some(Termination::GradientTolerance));
        }
        let mut tries = 0;
        loop {
            tries += 1;
            let mut trial = self.compute_step(&at, tries);
            if trial.step_ok {
                let keeps = problem.keeps_setup(&trial.candidate);
                if tries == 1
                    && keeps
                    && newton_tolerance_reached(
                        self.opts,
                        self.last_step,
                        trial.step_norm,
                        self.lambda,
                    )
                    && self.take_last_step(problem, &at, &mut trial)
                {
                    return Ok(Some(Termination::NewtonTolerance));
                }
                // after a rejected try the next is likely rejected too: its
                // cost alone (module doc)
                self.evaluate_step(problem, keeps && tries == 1, &mut trial);
            }
            let rho = if trial.predicted > 0.0 {
                (at.cost - trial.new_cost) / trial.predicted
            } else {
                -1.0
            };
            if trial.new_cost.is_finite() && trial.new_cost <= at.cost && rho > 0.0 {
                return Ok(self.handle_successful_step(&at, trial, rho));
            }
            if let Some(reason) = self.handle_unsuccessful_step(&at, &trial) {
                return Ok(Some(reason));
            }
        }
    }

    /// The linearisation at θ (the accepted step's, or a new one), the
    /// scaling D = diag(A) (floored) and the whitened gradient.
    fn start<P: LeastSquares>(
        &mut self,
        problem: &mut P,
        iteration: usize,
    ) -> Result<IterationStart, LmError<P::Error>> {
        let cost = self.linearization_at_theta(problem)?;
        self.initial_cost.get_or_insert(cost);
        let diag = self.a.diagonal();
        let dmax = diag.iter().cloned().fold(0.0f64, f64::max);
        let d: Vec<f64> = diag
            .iter()
            .map(|&v| v.max(1e-12 * dmax).max(1e-300))
            .collect();
        let gnorm = self
            .g
            .iter()
            .zip(&d)
            .map(|(gk, dk)| gk.abs() / dk.sqrt())
            .fold(0.0f64, f64::max);
        Ok(IterationStart {
            iteration,
            cost,
            d,
            gnorm,
        })
    }

    /// The linearisation at θ into `a`, `g`: the one made at the accepted
    /// step (`ahead`), or a new one. Its cost.
    fn linearization_at_theta<P: LeastSquares>(
        &mut self,
        problem: &mut P,
    ) -> Result<f64, LmError<P::Error>> {
        match self.ahead.take() {
            Some(cost) => {
                std::mem::swap(&mut self.a, &mut self.a_next);
                std::mem::swap(&mut self.g, &mut self.g_next);
                Ok(cost)
            }
            None => problem
                .linearize(&self.theta, &mut self.a, &mut self.g)
                .map_err(LmError::Start),
        }
    }

    /// Solve (A + λD) δ = −g into `delta`; the candidate θ + δ, the
    /// decrease the damped model predicts and the scaled step length.
    fn compute_step(&mut self, at: &IterationStart, tries: usize) -> Trial {
        let mut damped = self.a.clone();
        let damping: Vec<f64> = at.d.iter().map(|v| self.lambda * v).collect();
        damped.add_diagonal(&damping);
        let step_ok = match damped.factor() {
            Ok(f) => {
                for (dk, gk) in self.delta.iter_mut().zip(&self.g) {
                    *dk = -gk;
                }
                f.solve_in_place(&mut self.delta);
                self.delta.iter().all(|v| v.is_finite())
            }
            Err(_) => false,
        };
        let mut predicted = 0.0;
        let mut step_norm = f64::INFINITY;
        let candidate: Vec<f64> = self
            .theta
            .iter()
            .zip(&self.delta)
            .map(|(t, dt)| t + dt)
            .collect();
        if step_ok {
            let delta = &self.delta;
            // predicted decrease of the quadratic model: −gᵀδ − ½δᵀAδ = ½δᵀ(λD)δ − ½gᵀδ
            let gd: f64 = self.g.iter().zip(delta).map(|(a, b)| a * b).sum();
            let dd: f64 = delta.iter().zip(&damping).map(|(x, l)| l * x * x).sum();
            predicted = 0.5 * (dd - gd);
            step_norm = delta
                .iter()
                .zip(&at.d)
                .map(|(x, dk)| dk * x * x)
                .sum::<f64>()
                .sqrt();
        }
        Trial {
            tries,
            step_ok,
            candidate,
            predicted,
            step_norm,
            new_cost: f64::INFINITY,
            linearized: false,
        }
    }

    /// The last step (`newton_tolerance_reached`): its cost only, and the
    /// matrix at θ for the covariance. Taken (true) unless the cost rises
    /// beyond rounding or cannot be evaluated.
    fn take_last_step<P: LeastSquares>(
        &mut self,
        problem: &mut P,
        at: &IterationStart,
        trial: &mut Trial,
    ) -> bool {
        if let Ok(c) = problem.end_cost(&trial.candidate) {
            if c.is_finite() && c <= at.cost + COST_ROUNDING * at.cost.abs() {
                self.theta = std::mem::take(&mut trial.candidate);
                self.current = Some(c);
                self.record(at, c, trial.step_norm, trial.tries);
                return true;
            }
        }
        false
    }

    /// The cost at the candidate: by linearising there (into `a_next`) when
    /// the problem's set-up stays (`keeps`), else by the cost alone.
    fn evaluate_step<P: LeastSquares>(&mut self, problem: &P, keeps: bool, trial: &mut Trial) {
        let cost = if keeps {
            trial.linearized = true;
            problem.linearize(&trial.candidate, &mut self.a_next, &mut self.g_next)
        } else {
            problem.cost(&trial.candidate)
        };
        if let Ok(c) = cost {
            trial.new_cost = c;
        }
    }

    /// Take the accepted step, lower λ by Nielsen's rule from the gain
    /// ratio ρ, log the iteration; whether the function or parameter
    /// tolerance stops the run.
    fn handle_successful_step(
        &mut self,
        at: &IterationStart,
        trial: Trial,
        rho: f64,
    ) -> Option<Termination> {
        let cost_reached = function_tolerance_reached(self.opts, at.cost, trial.new_cost);
        let step_reached = parameter_tolerance_reached(self.opts, &self.delta, &self.theta, &at.d);
        let sigma_reached = sigma_tolerance_reached(self.opts, &self.delta, &at.d, self.lambda);
        self.theta = trial.candidate;
        if trial.linearized {
            self.ahead = Some(trial.new_cost);
        }
        self.last_step = Some((trial.step_norm, rho));
        self.lambda =
            (self.lambda * f64::max(1.0 / 3.0, 1.0 - (2.0 * rho - 1.0).powi(3))).max(1e-15);
        self.nu = 2.0;
        self.record(at, trial.new_cost, trial.step_norm, trial.tries);
        if cost_reached {
            Some(Termination::FunctionTolerance)
        } else if step_reached {
            Some(Termination::ParameterTolerance)
        } else if sigma_reached {
            Some(Termination::SigmaTolerance)
        } else {
            None
        }
    }

    /// A rejected step: stop (logging the iteration) when the cost is at
    /// its minimum to rounding or no damping helps; else raise λ for the
    /// next try.
    fn handle_unsuccessful_step(
        &mut self,
        at: &IterationStart,
        trial: &Trial,
    ) -> Option<Termination> {
        let stop = if trial.step_ok
            && (model_predicts_no_decrease(
                self.opts,
                trial.tries,
                trial.predicted,
                at.cost,
                at.gnorm,
            ) || at_rounding_floor(at.cost, trial.new_cost, trial.predicted, at.gnorm))
        {
            Some(Termination::FunctionTolerance)
        } else if damping_exhausted(self.lambda, self.nu) {
            Some(if trial.step_ok && stationary(at.gnorm) {
                Termination::FunctionTolerance
            } else {
                Termination::NoProgress
            })
        } else {
            None
        };
        if stop.is_some() {
            self.record(at, at.cost, trial.step_norm, trial.tries);
        } else {
            self.lambda *= self.nu;
            self.nu *= 2.0;
        }
        stop
    }

    /// Log an iteration (with the current λ) and show it to `report`.
    fn record(&mut self, at: &IterationStart, cost: f64, step_norm: f64, tries: usize) {
        let r = IterationRecord {
            iteration: at.iteration,
            cost,
            step_norm,
            lambda: self.lambda,
            gradient_norm: at.gnorm,
            tries,
        };
        (self.report)(&r);
        self.log.push(r);
    }

    /// The cost of the undamped matrix at the final θ, for the covariance
    /// (already in `a` when the gradient test stopped right after
    /// linearising there or after a Newton stop, in `a_next` when the last
    /// accepted step was linearised, else linearised now).
    fn final_linearization<P: LeastSquares>(
        &mut self,
        problem: &mut P,
    ) -> Result<f64, LmError<P::Error>> {
        if let Some(cost) = self.current {
            return Ok(cost);
        }
        problem
            .begin_iteration(&self.theta)
            .map_err(LmError::Start)?;
        self.linearization_at_theta(problem)
    }

    /// Factor the matrix at θ (an undetermined direction is
    /// [`LmError::Unidentified`]) and return the solution.
    fn finish<E: std::error::Error + 'static>(
        self,
        final_cost: f64,
        termination: Termination,
    ) -> Result<LmSolution, LmError<E>> {
        let factor = match self.a.factor() {
            Ok(factor) => factor,
            Err(FactorError::SchurNotPositiveDefinite) => {
                let schur = self.a.schur_complement()?;
                return Err(LmError::Unidentified {
                    theta: self.theta,
                    schur,
                });
            }
            Err(e) => return Err(e.into()),
        };
        Ok(LmSolution {
            theta: self.theta,
            summary: LmSummary {
                initial_cost: self.initial_cost.expect("at least one iteration"),
                final_cost,
                iterations: self.log,
                termination,
            },
            factor,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Rosenbrock-like problem with a band part: r = [10(c_{i+1} − c_i²), 1 − c_i] and
    /// one border unknown x coupling all: r = x − 2.
    struct Toy {
        nc: usize,
        /// What `keeps_setup` answers.
        keeps: bool,
        /// Calls of (cost, linearize).
        calls: std::cell::Cell<(usize, usize)>,
    }

    impl Toy {
        fn new(nc: usize) -> Self {
            Self {
                nc,
                keeps: false,
                calls: Default::default(),
            }
        }
    }

    #[derive(Debug, thiserror::Error)]
    #[error("never")]
    struct Never;

    impl Toy {
        fn residuals(&self, th: &[f64]) -> (Vec<f64>, Vec<Vec<(usize, f64)>>) {
            let nc = self.nc;
            let mut r = Vec::new();
            let mut j = Vec::new();
            for i in 0..nc - 1 {
                r.push(10.0 * (th[i + 1] - th[i] * th[i]));
                j.push(vec![(i, -20.0 * th[i]), (i + 1, 10.0)]);
            }
            for i in 0..nc {
                r.push(1.0 - th[i] + 0.1 * (th[nc] - 2.0));
                j.push(vec![(i, -1.0), (nc, 0.1)]);
            }
            r.push(th[nc] - 2.0);
            j.push(vec![(nc, 1.0)]);
            (r, j)
        }
    }

    impl LeastSquares for Toy {
        type Error = Never;
        fn begin_iteration(&mut self, _: &[f64]) -> Result<(), Never> {
            Ok(())
        }
        fn cost(&self, th: &[f64]) -> Result<f64, Never> {
            let (c, l) = self.calls.get();
            self.calls.set((c + 1, l));
            Ok(0.5 * self.residuals(th).0.iter().map(|v| v * v).sum::<f64>())
        }
        fn keeps_setup(&self, _: &[f64]) -> bool {
            self.keeps
        }
        fn linearize(&self, th: &[f64], a: &mut ArrowMatrix, g: &mut [f64]) -> Result<f64, Never> {
            let (c, l) = self.calls.get();
            self.calls.set((c, l + 1));
            a.clear();
            g.fill(0.0);
            let nc = self.nc;
            let (r, j) = self.residuals(th);
            for (ri, row) in r.iter().zip(&j) {
                for &(p, vp) in row {
                    g[p] += vp * ri;
                    for &(q, vq) in row {
                        match (p < nc, q < nc) {
                            (true, true) if q <= p => a.add_cc(p, q, vp * vq),
                            (false, false) => a.add_xx(0, 0, vp * vq),
                            (true, false) => {
                                let m = faer::Mat::from_fn(2, 2, |i, k| {
                                    if i == 1 && k == 0 {
                                        vp * vq
                                    } else {
                                        0.0
                                    }
                                });
                                a.add_local(p, 1, &[0], m.as_ref());
                            }
                            _ => {}
                        }
                    }
                }
            }
            let cost = 0.5 * r.iter().map(|v| v * v).sum::<f64>();
            Ok(cost)
        }
        fn new_matrix(&self) -> ArrowMatrix {
            ArrowMatrix::zeros(self.nc, 1, 1)
        }
    }

    #[test]
    fn converges_on_a_banded_rosenbrock_chain() {
        let mut toy = Toy::new(12);
        let mut start = vec![-1.2; 12];
        start.push(0.0);
        let mut seen = 0;
        let sol = solve(&mut toy, start, &LmOptions::default(), |_| seen += 1).unwrap();
        assert!(sol.summary.termination.converged(), "{}", sol.summary);
        assert_eq!(seen, sol.summary.iterations.len());
        // the minimum is c_i = 1, x = 2 with zero cost
        for v in &sol.theta[..12] {
            assert!((v - 1.0).abs() < 1e-7, "{v}");
        }
        assert!((sol.theta[12] - 2.0).abs() < 1e-7);
        assert!(sol.summary.final_cost < 1e-14);
        // costs never increase
        let costs: Vec<f64> = sol.summary.iterations.iter().map(|r| r.cost).collect();
        assert!(costs.windows(2).all(|w| w[1] <= w[0]));
    }

    /// A straight-line fit z_i = a + b t_i (σ = 1, residuals that do not
    /// vanish), its gradient shifted by `bias` in the slope's whitened units
    /// (a gradient a little inconsistent with the cost, as frozen weights or
    /// neglected second-order terms make it).
    struct Line {
        t: Vec<f64>,
        z: Vec<f64>,
        bias: f64,
        /// A jump of the cost away from the exact minimum (a discontinuity
        /// such as a change of the sample set), 0 for none.
        jump: f64,
    }

    impl Line {
        fn new(bias: f64) -> Self {
            let t: Vec<f64> = (0..400).map(|i| i as f64 * 0.25).collect();
            // offsets far above the noise, as gravity is to an accelerometer's σ
            let z = t
                .iter()
                .enumerate()
                .map(|(i, t)| 1e3 + 0.5 * t + ((i * 7919) % 13) as f64 / 6.0 - 1.0)
                .collect();
            Self {
                t,
                z,
                bias,
                jump: 0.0,
            }
        }
        /// The exact minimum (normal equations in closed form).
        fn minimum(&self) -> [f64; 2] {
            let n = self.t.len() as f64;
            let (st, sz) = (self.t.iter().sum::<f64>(), self.z.iter().sum::<f64>());
            let stt: f64 = self.t.iter().map(|t| t * t).sum();
            let stz: f64 = self.t.iter().zip(&self.z).map(|(t, z)| t * z).sum();
            let b = (n * stz - st * sz) / (n * stt - st * st);
            [(sz - b * st) / n, b]
        }
    }

    impl LeastSquares for Line {
        type Error = Never;
        fn begin_iteration(&mut self, _: &[f64]) -> Result<(), Never> {
            Ok(())
        }
        fn cost(&self, th: &[f64]) -> Result<f64, Never> {
            let jump = if th == self.minimum() { 0.0 } else { self.jump };
            Ok(jump
                + 0.5
                    * self
                        .t
                        .iter()
                        .zip(&self.z)
                        .map(|(t, z)| (z - th[0] - th[1] * t).powi(2))
                        .sum::<f64>())
        }
        fn linearize(&self, th: &[f64], a: &mut ArrowMatrix, g: &mut [f64]) -> Result<f64, Never> {
            a.clear();
            g.fill(0.0);
            for (t, z) in self.t.iter().zip(&self.z) {
                let r = z - th[0] - th[1] * t;
                let j = [-1.0, -t];
                for p in 0..2 {
                    g[p] += j[p] * r;
                    for q in 0..=p {
                        a.add_xx(p, q, j[p] * j[q]);
                    }
                }
            }
            let stt: f64 = self.t.iter().map(|t| t * t).sum();
            g[1] += self.bias * stt.sqrt();
            self.cost(th)
        }
        fn new_matrix(&self) -> ArrowMatrix {
            ArrowMatrix::zeros(0, 0, 2)
        }
    }

    /// Started at the exact minimum of a problem whose gradient is 0.06
    /// (whitened) off: every step raises the cost, until the damping makes
    /// the predicted and actual changes smaller than the cost's rounding.
    /// The old rule (only a first try counted) ran λ up to 10¹⁶ and
    /// stopped `NoProgress`; now this is convergence, at the minimum.
    #[test]
    fn a_step_lost_in_the_costs_rounding_is_convergence_at_any_try() {
        let mut line = Line::new(0.06);
        let start = line.minimum().to_vec();
        let sol = solve(&mut line, start.clone(), &LmOptions::default(), |_| {}).unwrap();
        let last = sol.summary.iterations.last().unwrap();
        println!("{}", sol.summary);
        assert_eq!(sol.summary.termination, Termination::FunctionTolerance);
        assert!(last.tries > 1, "stopped at the first try: {}", sol.summary);
        // the first try predicted more than the function tolerance allows
        // (so the old rule could not stop there), and the fit stayed put
        let c0 = line.cost(&start).unwrap();
        assert!(last.lambda > 1e3, "{}", sol.summary);
        assert!((sol.summary.final_cost - c0).abs() <= COST_ROUNDING * c0);
        for (v, m) in sol.theta.iter().zip(&start) {
            assert!((v - m).abs() < 1e-9 * m.abs().max(1.0), "{v} vs {m}");
        }
        // the exact problem from the same start stops at once
        let mut exact = Line::new(0.0);
        let sol = solve(&mut exact, start, &LmOptions::default(), |_| {}).unwrap();
        assert!(sol.summary.termination.converged(), "{}", sol.summary);
    }

    /// At the exact minimum with a gradient 0.02 (whitened) off, the first
    /// try predicts a decrease below [`NEGLIGIBLE_DECREASE`] and raises the
    /// cost: the run ends there, at the minimum, after one cost evaluation,
    /// where damping on (the rule for later tries) ends at the same θ
    /// after many.
    #[test]
    fn a_negligible_predicted_decrease_ends_at_the_first_try() {
        let mut line = Line::new(0.02);
        let start = line.minimum().to_vec();
        let sol = solve(&mut line, start.clone(), &LmOptions::default(), |_| {}).unwrap();
        let last = sol.summary.iterations.last().unwrap();
        assert_eq!(sol.summary.termination, Termination::FunctionTolerance);
        assert_eq!(last.tries, 1, "{}", sol.summary);
        assert_eq!(sol.theta, start, "no step was taken");
        let c0 = line.cost(&start).unwrap();
        assert!((sol.summary.final_cost - c0).abs() <= COST_ROUNDING * c0);
        // a gradient above 0.1 keeps damping on, as before
        let mut off = Line::new(0.2);
        let sol = solve(&mut off, start, &LmOptions::default(), |_| {}).unwrap();
        assert!(
            sol.summary.iterations.last().unwrap().tries > 1,
            "{}",
            sol.summary
        );
    }

    /// Given the linearisation at the start, the run is the same — θ, log,
    /// covariance — with one linearisation fewer; one of other dimensions
    /// is refused.
    #[test]
    fn a_given_start_linearisation_saves_one() {
        let start = vec![-1.2; 12];
        let mut plain = Toy::new(11);
        plain.keeps = true;
        let a = solve(&mut plain, start.clone(), &LmOptions::default(), |_| {}).unwrap();
        let mut given = Toy::new(11);
        given.keeps = true;
        let mut lin = Linearization {
            a: given.new_matrix(),
            g: vec![0.0; 12],
            cost: 0.0,
        };
        lin.cost = given.linearize(&start, &mut lin.a, &mut lin.g).unwrap();
        given.calls.set((0, 0));
        let b = solve_from(
            &mut given,
            start.clone(),
            Some(&lin),
            &LmOptions::default(),
            |_| {},
        )
        .unwrap();
        assert_eq!(a.theta, b.theta);
        assert_eq!(a.summary.iterations, b.summary.iterations);
        assert_eq!(
            a.factor.covariance_x().as_ref(),
            b.factor.covariance_x().as_ref()
        );
        let (pa, pb) = (plain.calls.get(), given.calls.get());
        assert_eq!(pb.1 + 1, pa.1, "linearisations: {pa:?} vs {pb:?}");
        assert_eq!(pa.0, pb.0, "cost evaluations: {pa:?} vs {pb:?}");
        // a linearisation of another problem's size is refused
        let mut other = Toy::new(11);
        let small = Linearization {
            a: Toy::new(5).new_matrix(),
            g: vec![0.0; 6],
            cost: 0.0,
        };
        let err = solve_from(
            &mut other,
            start,
            Some(&small),
            &LmOptions::default(),
            |_| {},
        );
        assert!(matches!(err, Err(LmError::Options(m)) if m.contains("dimensions")));
    }

    /// A gradient far off (10 in whitened units) at the minimum is not
    /// rounding: no step lowers the cost, and the solver says so.
    #[test]
    fn a_wrong_gradient_still_ends_without_progress() {
        let mut line = Line::new(10.0);
        let start = line.minimum().to_vec();
        let sol = solve(&mut line, start, &LmOptions::default(), |_| {}).unwrap();
        assert_eq!(
            sol.summary.termination,
            Termination::NoProgress,
            "{}",
            sol.summary
        );
    }

    /// At the minimum with a small gradient error (0.05 whitened) and a
    /// cost that jumps by far more than its rounding (10⁻⁶ J) anywhere
    /// else: no step lowers the cost at any damping, but the point is
    /// stationary to 0.05σ — convergence, not `NoProgress`; with a
    /// gradient 10 off the same jump still ends `NoProgress`.
    #[test]
    fn no_lower_cost_at_a_negligible_gradient_is_convergence() {
        for (bias, want) in [
            (0.05, Termination::FunctionTolerance),
            (10.0, Termination::NoProgress),
        ] {
            let mut line = Line::new(bias);
            let start = line.minimum().to_vec();
            line.jump = 1e-6 * line.cost(&start).unwrap();
            let sol = solve(&mut line, start.clone(), &LmOptions::default(), |_| {}).unwrap();
            assert_eq!(sol.summary.termination, want, "{}", sol.summary);
            assert_eq!(sol.theta, start, "no step was taken");
        }
    }

    /// First tries evaluated by linearising (keeps_setup) give the same run
    /// — θ, log, covariance — with a cost evaluation only for the later
    /// tries of an iteration and fewer linearisations than a cost per step
    /// tried plus a linearisation per iteration and one at the end.
    #[test]
    fn linearised_trial_steps_give_the_same_solution() {
        let start = || {
            let mut s = vec![-1.2; 12];
            s.push(0.0);
            s
        };
        // the Newton stop needs a set-up that stays: off, so both paths match
        let opts = LmOptions {
            newton_tolerance: 0.0,
            ..LmOptions::default()
        };
        let mut plain = Toy::new(12);
        let a = solve(&mut plain, start(), &opts, |_| {}).unwrap();
        let mut ahead = Toy {
            keeps: true,
            ..Toy::new(12)
        };
        let b = solve(&mut ahead, start(), &opts, |_| {}).unwrap();
        assert!(a.summary.termination.converged(), "{}", a.summary);
        assert_eq!(a.theta, b.theta);
        assert_eq!(a.summary.iterations, b.summary.iterations);
        assert_eq!(a.summary.termination, b.summary.termination);
        assert_eq!(
            (a.summary.initial_cost, a.summary.final_cost),
            (b.summary.initial_cost, b.summary.final_cost)
        );
        assert_eq!(a.factor.covariance_x(), b.factor.covariance_x());
        let tried: usize = a.summary.iterations.iter().map(|r| r.tries).sum();
        let iters = a.summary.iterations.len();
        assert!(
            tried > iters,
            "the run should reject some steps ({tried} tries)"
        );
        // a final linearisation unless the gradient test stopped right after one
        let last = usize::from(a.summary.termination != Termination::GradientTolerance);
        assert_eq!(plain.calls.get(), (tried, iters + last));
        // ahead: the first try of each iteration linearises, later ones
        // cost only; a step accepted after a rejection is linearised anew
        let later: usize = a
            .summary
            .iterations
            .iter()
            .map(|r| r.tries.saturating_sub(1))
            .sum();
        let (costs, linearisations) = ahead.calls.get();
        assert_eq!(costs, later);
        assert!(later > 0 && linearisations < 1 + tried, "{linearisations}");
    }

    /// The Newton stop takes the last step without linearising after it:
    /// one linearisation fewer than the run without it, the same minimum
    /// (to the tolerance, in conditional σ) and a covariance from the
    /// matrix one short step away.
    #[test]
    fn the_newton_stop_saves_the_last_linearisation() {
        let start = || {
            let mut s = vec![-1.2; 12];
            s.push(0.0);
            s
        };
        let toy = || Toy {
            keeps: true,
            ..Toy::new(12)
        };
        let (mut with, mut without) = (toy(), toy());
        let a = solve(&mut with, start(), &LmOptions::default(), |_| {}).unwrap();
        let off = LmOptions {
            newton_tolerance: 0.0,
            ..LmOptions::default()
        };
        let b = solve(&mut without, start(), &off, |_| {}).unwrap();
        assert_eq!(a.summary.termination, Termination::NewtonTolerance);
        assert!(b.summary.termination.converged(), "{}", b.summary);
        let (_, lin_a) = with.calls.get();
        let (_, lin_b) = without.calls.get();
        assert!(lin_a < lin_b, "{lin_a} linearisations against {lin_b}");
        // the minimum, in units of the conditional σ (√A_kk at the optimum)
        let mut m = with.new_matrix();
        let mut g = vec![0.0; a.theta.len()];
        with.linearize(&b.theta, &mut m, &mut g).unwrap();
        let d = m.diagonal();
        let tol = LmOptions::default().newton_tolerance;
        for (k, (x, y)) in a.theta.iter().zip(&b.theta).enumerate() {
            let e = (x - y).abs() * d[k].sqrt();
            assert!(e < tol, "θ[{k}] off by {e:e} σ");
        }
        let (ca, cb) = (a.factor.covariance_x(), b.factor.covariance_x());
        let rel = (ca[(0, 0)] - cb[(0, 0)]).abs() / cb[(0, 0)];
        assert!(rel < 1e-3, "covariance off by {rel:e}");
        // the last record is the step taken, at the cost evaluated there
        let last = a.summary.iterations.last().unwrap();
        assert_eq!(last.cost, a.summary.final_cost);
        // off the minimum by e < tol conditional σ: a cost excess below ½tol²
        let excess = a.summary.final_cost - b.summary.final_cost;
        assert!(excess <= 0.5 * tol * tol, "cost excess {excess:e}");
    }

    /// The σ stop ends the run after the first nearly undamped step below
    /// the tolerance in conditional σ: fewer linearisations than without
    /// it, at a point within a few tolerances (in conditional σ) of the
    /// minimum the run without it reaches.
    #[test]
    fn the_sigma_stop_ends_at_a_step_below_the_tolerance() {
        let start = || {
            let mut s = vec![-1.2; 12];
            s.push(0.0);
            s
        };
        let toy = || Toy {
            keeps: true,
            ..Toy::new(12)
        };
        let (mut with, mut without) = (toy(), toy());
        let tol = 0.05;
        let on = LmOptions {
            sigma_tolerance: tol,
            newton_tolerance: 0.0,
            ..LmOptions::default()
        };
        let off = LmOptions {
            newton_tolerance: 0.0,
            ..LmOptions::default()
        };
        let a = solve(&mut with, start(), &on, |_| {}).unwrap();
        let b = solve(&mut without, start(), &off, |_| {}).unwrap();
        assert_eq!(a.summary.termination, Termination::SigmaTolerance);
        assert_ne!(b.summary.termination, Termination::SigmaTolerance);
        let (_, lin_a) = with.calls.get();
        let (_, lin_b) = without.calls.get();
        assert!(lin_a < lin_b, "{lin_a} linearisations against {lin_b}");
        let mut m = with.new_matrix();
        let mut g = vec![0.0; a.theta.len()];
        with.linearize(&b.theta, &mut m, &mut g).unwrap();
        let d = m.diagonal();
        for (k, (x, y)) in a.theta.iter().zip(&b.theta).enumerate() {
            let e = (x - y).abs() * d[k].sqrt();
            assert!(e < tol, "θ[{k}] off by {e:e} σ");
        }
    }

    /// z_i = x₀ + x₁ + noise: only the sum is determined, so the
    /// information about x is exactly singular at any solution.
    struct Sum {
        z: Vec<f64>,
    }

    impl LeastSquares for Sum {
        type Error = Never;
        fn begin_iteration(&mut self, _: &[f64]) -> Result<(), Never> {
            Ok(())
        }
        fn cost(&self, th: &[f64]) -> Result<f64, Never> {
            Ok(0.5
                * self
                    .z
                    .iter()
                    .map(|z| (z - th[0] - th[1]).powi(2))
                    .sum::<f64>())
        }
        fn linearize(&self, th: &[f64], a: &mut ArrowMatrix, g: &mut [f64]) -> Result<f64, Never> {
            a.clear();
            g.fill(0.0);
            for z in &self.z {
                let r = z - th[0] - th[1];
                for p in 0..2 {
                    g[p] -= r;
                    for q in 0..=p {
                        a.add_xx(p, q, 1.0);
                    }
                }
            }
            self.cost(th)
        }
        fn new_matrix(&self) -> ArrowMatrix {
            ArrowMatrix::zeros(0, 0, 2)
        }
    }

    /// A direction the data do not determine ends in `Unidentified`, with
    /// the solution (the determined sum at its least-squares value) and
    /// the singular S (n·[[1, 1], [1, 1]]) to name the direction by.
    #[test]
    fn an_undetermined_direction_is_reported_with_its_information() {
        let z: Vec<f64> = (0..50)
            .map(|i| 3.0 + ((i * 37) % 11) as f64 * 0.1)
            .collect();
        let mean = z.iter().sum::<f64>() / z.len() as f64;
        let mut sum = Sum { z };
        match solve(&mut sum, vec![0.0, 0.0], &LmOptions::default(), |_| {}) {
            Err(LmError::Unidentified { theta, schur }) => {
                assert!((theta[0] + theta[1] - mean).abs() < 1e-6, "{theta:?}");
                for (i, j) in [(0, 0), (0, 1), (1, 0), (1, 1)] {
                    assert_eq!(schur[(i, j)], 50.0, "S[{i}, {j}]");
                }
            }
            Err(e) => panic!("unexpected error {e}"),
            Ok(sol) => panic!("a singular problem was solved: {}", sol.summary),
        }
    }

    #[test]
    fn iteration_log_lines_match_the_header() {
        let old = format!(
            "{:>4} {:>14} {:>10} {:>9} {:>10}",
            "iter", "cost", "step", "lambda", "gradient"
        );
        assert_eq!(IterationRecord::HEADER, old);
        let r = IterationRecord {
            iteration: 3,
            cost: 1234.5,
            step_norm: 0.25,
            lambda: 1e-4,
            gradient_norm: 2e-3,
            tries: 1,
        };
        assert_eq!(
            r.to_string(),
            "   3     1.234500e3   2.500e-1    1.0e-4   2.000e-3"
        );
        assert_eq!(r.to_string().len(), IterationRecord::HEADER.len());
    }

    #[test]
    fn invalid_options_are_rejected() {
        let opts = LmOptions {
            max_iterations: 0,
            ..LmOptions::default()
        };
        let mut toy = Toy::new(3);
        let err = solve(&mut toy, vec![0.0; 4], &opts, |_| {}).err().unwrap();
        assert!(err.to_string().contains("max_iterations"));
    }
}
