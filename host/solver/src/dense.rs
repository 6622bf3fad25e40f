//! Small dense nonlinear least-squares problems (the classical tracker
//! baselines, the tracker registration) on the calibration's own
//! Levenberg–Marquardt ([`crate::lm`]).
//!
//! Minimises J(θ) = ½‖f(θ)‖² for a residual closure f with a
//! central-difference Jacobian
//!
//! ```text
//! ∂f/∂θ_k ≈ (f(θ + h_k e_k) − f(θ − h_k e_k)) / (2 h_k),   h_k = 1e-6 (1 + |θ_k|)
//! ```
//!
//! The normal matrix has no spline block: an [`ArrowMatrix`] with nc = 0,
//! whose whole content is the dense corner JᵀJ (its factorisation is then
//! the Cholesky factorisation of JᵀJ).

use crate::arrow::ArrowMatrix;
use crate::lm::{self, LeastSquares, LmError, LmOptions, LmSolution};

/// Why a dense residual cannot be evaluated.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum DenseError {
    /// Some residual is NaN or infinite at θ (the step is rejected).
    #[error("the residuals are not finite")]
    NotFinite,
}

/// A dense problem given by its residual closure `f(θ)` (θ of length `n`).
pub(crate) struct DenseProblem<F> {
    f: F,
    n: usize,
}

impl<F: Fn(&[f64]) -> Vec<f64>> DenseProblem<F> {
    /// The problem ½‖f(θ)‖² over θ ∈ ℝⁿ.
    pub fn new(n: usize, f: F) -> Self {
        Self { f, n }
    }

    fn residuals(&self, theta: &[f64]) -> Result<Vec<f64>, DenseError> {
        let r = (self.f)(theta);
        if r.iter().all(|v| v.is_finite()) {
            Ok(r)
        } else {
            Err(DenseError::NotFinite)
        }
    }
}

impl<F: Fn(&[f64]) -> Vec<f64>> LeastSquares for DenseProblem<F> {
    type Error = DenseError;

    fn begin_iteration(&mut self, _theta: &[f64]) -> Result<(), DenseError> {
        Ok(())
    }

    fn cost(&self, theta: &[f64]) -> Result<f64, DenseError> {
        Ok(0.5 * self.residuals(theta)?.iter().map(|v| v * v).sum::<f64>())
    }

    fn linearize(
        &self,
        theta: &[f64],
        a: &mut ArrowMatrix,
        g: &mut [f64],
    ) -> Result<f64, DenseError> {
        let r = self.residuals(theta)?;
        let (m, n) = (r.len(), self.n);
        // column-major central-difference Jacobian
        let mut jac = vec![0.0; m * n];
        let mut tp = theta.to_vec();
        for k in 0..n {
            let h = 1e-6 * (1.0 + theta[k].abs());
            tp[k] = theta[k] + h;
            let rp = self.residuals(&tp)?;
            tp[k] = theta[k] - h;
            let rm = self.residuals(&tp)?;
            tp[k] = theta[k];
            for i in 0..m {
                jac[k * m + i] = (rp[i] - rm[i]) / (2.0 * h);
            }
        }
        a.clear();
        for k in 0..n {
            let ck = &jac[k * m..(k + 1) * m];
            g[k] = ck.iter().zip(&r).map(|(j, r)| j * r).sum();
            for l in 0..=k {
                let cl = &jac[l * m..(l + 1) * m];
                a.add_xx(k, l, ck.iter().zip(cl).map(|(x, y)| x * y).sum());
            }
        }
        Ok(0.5 * r.iter().map(|v| v * v).sum::<f64>())
    }

    fn new_matrix(&self) -> ArrowMatrix {
        ArrowMatrix::zeros(0, 0, self.n)
    }
}

/// Minimise ½‖f(θ)‖² from `theta` by [`lm::solve`] on a [`DenseProblem`].
pub fn solve<F: Fn(&[f64]) -> Vec<f64>>(
    f: F,
    theta: Vec<f64>,
    opts: &LmOptions,
) -> Result<LmSolution, LmError<DenseError>> {
    let mut problem = DenseProblem::new(theta.len(), f);
    lm::solve(&mut problem, theta, opts, |_| {})
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fits_a_nonlinear_curve() {
        // y = a·exp(b·t) from exact samples.
        let t: Vec<f64> = (0..20).map(|k| k as f64 * 0.1).collect();
        let y: Vec<f64> = t.iter().map(|t| 2.5 * (-1.3 * t).exp()).collect();
        let f = |x: &[f64]| -> Vec<f64> {
            t.iter()
                .zip(&y)
                .map(|(t, y)| x[0] * (x[1] * t).exp() - y)
                .collect()
        };
        let sol = solve(f, vec![1.0, 0.0], &LmOptions::default()).unwrap();
        let x = &sol.theta;
        assert!(
            (x[0] - 2.5).abs() < 1e-6 && (x[1] + 1.3).abs() < 1e-6,
            "{x:?}"
        );
        assert!(2.0 * sol.summary.final_cost < 1e-12); // ‖f‖²
    }

    /// The covariance of a linear problem is (JᵀJ)⁻¹, through the nc = 0 arrow.
    #[test]
    fn linear_problem_has_the_normal_equations_covariance() {
        // r = [θ0 − 1, 2 θ1 − 4, θ0 + θ1 − 3]
        let f = |x: &[f64]| vec![x[0] - 1.0, 2.0 * x[1] - 4.0, x[0] + x[1] - 3.0];
        let sol = solve(f, vec![0.0, 0.0], &LmOptions::default()).unwrap();
        assert!((sol.theta[0] - 1.0).abs() < 1e-9 && (sol.theta[1] - 2.0).abs() < 1e-9);
        // JᵀJ = [[2, 1], [1, 5]], inverse [[5, −1], [−1, 2]] / 9
        let c = sol.factor.covariance_x();
        for (i, j, v) in [(0, 0, 5.0), (0, 1, -1.0), (1, 0, -1.0), (1, 1, 2.0)] {
            assert!((c[(i, j)] - v / 9.0).abs() < 1e-8, "{i},{j}: {}", c[(i, j)]);
        }
    }

    #[test]
    fn non_finite_residuals_reject_the_step() {
        let f = |x: &[f64]| vec![x[0].sqrt() - 2.0];
        let sol = solve(f, vec![1.0], &LmOptions::default()).unwrap();
        assert!((sol.theta[0] - 4.0).abs() < 1e-6, "{:?}", sol.theta);
        let mut p = DenseProblem::new(1, f);
        assert_eq!(p.cost(&[-1.0]), Err(DenseError::NotFinite));
        assert!(p.begin_iteration(&[0.0]).is_ok());
    }
}
