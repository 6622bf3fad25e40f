//! The Rao score test of extra columns against a fitted pose problem
//! (docs/model.md §7.9): the sums u, D, B of
//! [`robimu_solver::PoseProblem::extra_sums`] at the MAP estimate θ, where
//! the full gradient is zero, give the efficient information
//! V = D + P − Bᵀ A⁻¹ B (every unknown of θ projected out with the fit's
//! Gauss–Newton matrix A; P the extra parameters' prior information) and
//! S = uᵀ V⁻¹ u ~ χ²_k when the extra parameters are zero. One mechanism
//! serves the constant-τ test ([`super::tau_drift`]) and the catalogue's
//! IMU-side effects ([`super::diagnose`]).

use faer::linalg::solvers::DenseSolveCore;
use robimu_solver::{ArrowFactor, ExtraSums};

use crate::stats::chi2_sf;

/// A score test's outcome.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct ScoreTest {
    /// S (χ²_k when the extra parameters are zero).
    pub statistic: f64,
    /// Degrees of freedom k.
    pub dof: usize,
    /// P(χ²_k > S).
    pub p_value: f64,
    /// The one-step estimate of the extra parameters, −V⁻¹ u.
    pub step: Vec<f64>,
    /// Their standard deviations, √diag(V⁻¹).
    pub step_sigma: Vec<f64>,
}

/// The efficient information of the extra parameters and their score.
#[derive(Debug, Clone)]
pub(crate) struct Information {
    /// u (k).
    pub u: Vec<f64>,
    /// V = D + P − Bᵀ A⁻¹ B (k × k).
    pub v: faer::Mat<f64>,
}

impl Information {
    /// V of the sums `s` with the extra parameters' prior information
    /// `prior_info` (1/σ², 0 for none), `factor` the undamped Gauss–Newton
    /// matrix at θ.
    pub(crate) fn new(s: &ExtraSums, prior_info: &[f64], factor: &ArrowFactor) -> Self {
        let k = s.u.len();
        let solved: Vec<Vec<f64>> =
            s.b.iter()
                .map(|c| {
                    let mut v = c.clone();
                    factor.solve_in_place(&mut v);
                    v
                })
                .collect();
        let v = faer::Mat::from_fn(k, k, |a, b| {
            let cross: f64 = s.b[a].iter().zip(&solved[b]).map(|(x, y)| x * y).sum();
            s.d[a][b] - cross + if a == b { prior_info[a] } else { 0.0 }
        });
        Self { u: s.u.clone(), v }
    }

    /// The test of the parameters `idx` alone (the others held at zero).
    /// `None` when their V is not positive definite.
    pub(crate) fn test(&self, idx: &[usize]) -> Option<ScoreTest> {
        let k = idx.len();
        let v = faer::Mat::from_fn(k, k, |a, b| self.v[(idx[a], idx[b])]);
        let v_inv = v.llt(faer::Side::Lower).ok()?.inverse();
        let u: Vec<f64> = idx.iter().map(|&i| self.u[i]).collect();
        let vu: Vec<f64> = (0..k)
            .map(|a| (0..k).map(|b| v_inv[(a, b)] * u[b]).sum())
            .collect();
        let statistic: f64 = u.iter().zip(&vu).map(|(a, b)| a * b).sum();
        Some(ScoreTest {
            statistic,
            dof: k,
            p_value: chi2_sf(statistic, k as f64),
            step: vu.iter().map(|v| -v).collect(),
            step_sigma: (0..k).map(|a| v_inv[(a, a)].max(0.0).sqrt()).collect(),
        })
    }
}

/// The test of all the sums' parameters ([`Information::test`]).
pub(crate) fn score_test(
    s: &ExtraSums,
    prior_info: &[f64],
    factor: &ArrowFactor,
) -> Option<ScoreTest> {
    let all: Vec<usize> = (0..s.u.len()).collect();
    Information::new(s, prior_info, factor).test(&all)
}
