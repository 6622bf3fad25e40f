//! Is τ constant over the recording? A Rao score test at the MAP estimate
//! (docs/model.md §7.9, *time offset*).
//!
//! The alternative: the IMU samples of segment k (the used samples cut
//! into [`SEGMENTS`] runs of equal count) read at t_i + τ + δ_k, δ_0 = 0.
//! Their residuals' Jacobian is ∂r_i/∂δ_k = ∂r_i/∂τ = dz/dt on segment k:
//! K − 1 extra columns, tested by [`super::score`] (one pass over the IMU
//! samples, [`robimu_solver::PoseProblem::extra_sums`]). The efficient
//! information V = D − Bᵀ A⁻¹ B projects out every parameter of the fit
//! (spline, p_I, g, τ and the 24 sensor parameters) with the fit's own
//! Gauss–Newton matrix A; at the MAP estimate the full gradient is zero, so
//! S = gᵀ V⁻¹ g ~ χ²_{K−1} when τ is constant. A lag that wanders (a drifting
//! clock, arrival stamps) makes it large even where the other parameters
//! absorb most of the drift, which refitting τ alone per half misses.

use robimu_model::effects::ImuContext;
use robimu_solver::{ArrowFactor, PoseProblem, PoseProblemError};

use super::score::score_test;

/// Number of segments K.
pub(crate) const SEGMENTS: usize = 4;

/// The test's outcome.
#[derive(Debug, Clone, PartialEq)]
pub struct TauDrift {
    /// S (χ²_{K−1} under a constant τ).
    pub statistic: f64,
    /// Degrees of freedom, K − 1.
    pub dof: usize,
    /// P(χ²_{K−1} > S).
    pub p_value: f64,
    /// One-step estimates of δ_1 … δ_{K−1} (s): τ in segment k less τ in
    /// the first, V⁻¹ g.
    pub delta: Vec<f64>,
    /// Their standard deviations (s), √diag(V⁻¹).
    pub delta_sigma: Vec<f64>,
}

/// The segment k ≥ 1 of the m-th of `n` selected samples (`None`: the first).
fn segment_of(m: usize, n: usize) -> Option<usize> {
    (1..SEGMENTS).rev().find(|&k| m >= n * k / SEGMENTS)
}

/// The score test of IMU `imu`'s τ at the solution θ of `problem` (its
/// selection that of θ), with `factor` the undamped Gauss–Newton matrix at
/// θ: the extra columns of δ_k are dz/dt on segment k ([`super::score`]).
/// `None` when there are too few IMU samples to cut or V is singular.
pub(crate) fn tau_drift(
    problem: &PoseProblem,
    imu: usize,
    theta: &[f64],
    factor: &ArrowFactor,
) -> Result<Option<TauDrift>, PoseProblemError> {
    let (m, n) = (SEGMENTS - 1, problem.selected_of(imu).len());
    if n < 10 * SEGMENTS {
        return Ok(None);
    }
    let sums = problem.extra_sums(theta, imu, m, |i, sample, cols| {
        if let Some(k) = segment_of(i, n) {
            cols[k - 1] = sample.dz_dt();
        }
    })?;
    Ok(score_test(&sums, &vec![0.0; m], factor).map(|t| TauDrift {
        statistic: t.statistic,
        dof: t.dof,
        p_value: t.p_value,
        delta: t.step,
        delta_sigma: t.step_sigma,
    }))
}

/// Below this p-value the verdict doubts a constant τ.
pub(crate) const P_DOUBT: f64 = 0.01;

/// The verdict's *time offset* check: τ constant over the recording
/// (p ≥ [`P_DOUBT`]); when doubted, τ per segment relative to the first.
pub(crate) fn verdict_check(drift: Option<&TauDrift>) -> robimu_session::result::VerdictCheck {
    let (ok, text) = match drift {
        None => (
            true,
            "not tested (too few IMU samples to cut the recording)".to_string(),
        ),
        Some(d) => {
            let per = d
                .delta
                .iter()
                .zip(&d.delta_sigma)
                .map(|(v, s)| format!("{:+.1} ± {:.1} ms", v * 1e3, s * 1e3))
                .collect::<Vec<_>>()
                .join(", ");
            let ok = d.p_value >= P_DOUBT;
            let head = if ok {
                "τ constant over the recording"
            } else {
                "τ changes over the recording (a lag that wanders or a drifting clock: the \
                 estimates and σ do not hold)"
            };
            (
                ok,
                format!(
                    "{head}: score test over {} segments χ²_{} = {:.1}, p = {:.2e}; τ of \
                     segments 2–{} less the first's: {per}",
                    d.dof + 1,
                    d.dof,
                    d.statistic,
                    d.p_value,
                    d.dof + 1
                ),
            )
        }
    };
    robimu_session::result::VerdictCheck {
        topic: "time offset".into(),
        ok,
        text,
    }
}

#[cfg(test)]
#[path = "tau_drift_tests.rs"]
mod tests;
