//! The pose calibration's noise levels from its own residuals (docs/model.md
//! §7.9, *noise*): after the solve, each channel's
//! σ̂_c = σ_c √(RSS_c / (N_c − h_c)) ([`ChannelFit`]: the rows' leverage h_c
//! puts back the part of the noise the spline and x absorbed, which leaves
//! the raw RMS 5–13 % low); while some σ̂ differs from the σ used by more
//! than [`SETTLE`], the problem is refitted from its solution with σ̂, at
//! most [`MAX_REFITS`] times. The channels are the six IMU channels and the
//! poses' position and rotation; the noise stays white (the paper's model):
//! a level is identified, not a correlation.

use robimu_solver::{
    solve_from, ArrowFactor, ChannelFit, IterationRecord, LeastSquares, LmOptions, LmSolution,
    PoseProblem, PoseSigma,
};

use super::PoseCalibrationError;

/// The identification has settled when every σ̂ is within this share of
/// the σ used (a 2 % error in σ is a 2 % error in every σ of x), or
/// within [`SETTLE_SE`] of its standard error, whichever is wider.
pub(crate) const SETTLE: f64 = 0.02;

/// σ̂_c/σ_c within this many standard errors 1/√(2 (N_c − h_c)) of 1 is
/// what the data cannot tell from 1: no refit.
pub(crate) const SETTLE_SE: f64 = 3.0;

/// The settling tolerance of channel `c` (relative).
fn tolerance(fit: &ChannelFit, c: usize) -> f64 {
    let dof = (fit.rows[c] as f64 - fit.leverage[c]).max(1.0);
    SETTLE.max(SETTLE_SE / (2.0 * dof).sqrt())
}

/// The IMU rows' leverage from every this many samples
/// ([`PoseProblem::channel_fit`]).
const STRIDE: usize = 16;

/// Most refits with identified σ.
pub const MAX_REFITS: usize = 4;

/// The noise levels of a pose calibration.
#[derive(Debug, Clone, PartialEq)]
pub struct NoiseLevels {
    /// The σ the calibration started from (session.toml's or the defaults).
    pub given: PoseSigma,
    /// The σ of the final fit (its rows, covariance and whitened RMS).
    pub used: PoseSigma,
    /// Whether σ were identified (false: `used` is `given`).
    pub identified: bool,
    /// Refits with identified σ.
    pub refits: usize,
    /// Whether the last σ̂ are within [`SETTLE`] of `used`.
    pub settled: bool,
    /// RSS, rows and leverage of the final fit, per channel.
    pub fit: ChannelFit,
}

impl NoiseLevels {
    /// The final fit's residual RMS of IMU `j` per channel (not whitened).
    pub fn imu_rms(&self, j: usize) -> [f64; 6] {
        std::array::from_fn(|c| self.rms(6 * j + c))
    }

    /// The final fit's residual RMS of the poses' position (m) and
    /// rotation (rad) per component.
    pub fn pose_rms(&self) -> [f64; 2] {
        let k = self.used.sigma_z.len();
        [self.rms(6 * k), self.rms(6 * k + 1)]
    }

    fn rms(&self, c: usize) -> f64 {
        let s = self.used.channels()[c];
        s * (self.fit.rss[c] / self.fit.rows[c].max(1) as f64).sqrt()
    }

    /// The σ the final fit's residuals give: `used` times σ̂/σ.
    pub fn suggested(&self) -> PoseSigma {
        let ratio: Vec<f64> = (self.fit.sigma_ratio().iter())
            .map(|r| r.unwrap_or(1.0))
            .collect();
        self.used.scaled(&ratio)
    }
}

fn solver_error<E: std::fmt::Display>(e: E) -> PoseCalibrationError {
    PoseCalibrationError::Solver(e.to_string())
}

/// Solve `problem` from `theta` and, with `identify`, identify its σ and
/// refit until they settle (module doc); `stage` hears of each refit.
/// `beside(problem, θ, factor)` runs on a second thread while each
/// solution's levels are identified; the final solution's value is
/// returned (the τ score tests: independent of the identification when it
/// settles without a refit, as it mostly does).
pub(crate) fn solve_identified<T: Send>(
    problem: &mut PoseProblem,
    theta: Vec<f64>,
    (lm, identify): (&LmOptions, bool),
    mut stage: impl FnMut(&str),
    mut iteration: impl FnMut(&IterationRecord),
    beside: impl Fn(&PoseProblem, &[f64], &ArrowFactor) -> T + Sync,
) -> Result<(LmSolution, NoiseLevels, T), PoseCalibrationError> {
    let given = problem.sigma();
    let mut sol = solve_from(problem, theta, None, lm, &mut iteration).map_err(solver_error)?;
    let mut refits = 0;
    loop {
        problem.begin_iteration(&sol.theta)?;
        let (p, s) = (&*problem, &sol);
        let (fit, side) = std::thread::scope(|scope| {
            let fit =
                scope.spawn(move || p.channel_fit(&s.theta, &s.factor.selected_inverse(), STRIDE));
            let side = beside(p, &s.theta, &s.factor);
            let fit = fit.join().unwrap_or_else(|e| std::panic::resume_unwind(e));
            (fit, side)
        });
        let fit = fit?;
        let factor: Vec<f64> = (fit.sigma_ratio().iter())
            .map(|r| r.unwrap_or(1.0))
            .collect();
        let settled = (0..factor.len()).all(|c| (factor[c] - 1.0).abs() <= tolerance(&fit, c));
        if !identify || settled || refits == MAX_REFITS {
            let levels = NoiseLevels {
                given,
                used: problem.sigma(),
                identified: identify,
                refits,
                settled,
                fit,
            };
            return Ok((sol, levels, side));
        }
        let next = problem.sigma().scaled(&factor);
        problem.set_sigma(&next)?;
        refits += 1;
        stage(&format!(
            "refit {refits} with the noise levels of the residuals (σ changed by up to {:.0} %)",
            100.0 * factor.iter().map(|f| (f - 1.0).abs()).fold(0.0, f64::max)
        ));
        sol = solve_from(problem, sol.theta, None, lm, &mut iteration).map_err(solver_error)?;
    }
}
