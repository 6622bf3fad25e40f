//! The calibration problem and its solvers (paper §6): the residuals,
//! priors and exact Jacobians assembled into the arrowhead normal matrix
//! ([`problem`]), its structured factorisation and covariance ([`arrow`]),
//! the Levenberg–Marquardt iteration ([`lm`]) and small dense problems on
//! that same iteration ([`dense`]).
//!
//! Main types: [`ArrowMatrix`] and its factor [`ArrowFactor`] (solves and the
//! marginal covariance of x), [`problem::Problem`] (one session's MAP problem)
//! and [`solve`] (Levenberg–Marquardt on any [`LeastSquares`] problem).
//!
//! # Example
//!
//! An arrowhead matrix — a band of half-bandwidth 2 over 6 trajectory
//! unknowns, bordered by 2 model parameters — assembled from local blocks,
//! factored and solved, against a dense solve of the same matrix:
//!
//! ```
//! use faer::linalg::solvers::{DenseSolveCore, Solve};
//! use faer::{Mat, Side};
//! use robimu_solver::ArrowMatrix;
//!
//! let (nc, w, nx) = (6, 2, 2);
//! let mut a = ArrowMatrix::zeros(nc, w, nx);
//! for c0 in 0..=nc - (w + 1) {
//!     // JᵀJ of a residual block that touches w + 1 consecutive band unknowns
//!     // and both parameters
//!     let j = Mat::from_fn(4, w + 1 + nx, |r, c| ((1 + r + 3 * c + c0) as f64).sin());
//!     let local = j.transpose() * &j;
//!     a.add_local(c0, w + 1, &[0, 1], local.as_ref());
//! }
//! a.add_diagonal(&[1.0; 8]); // a prior on every unknown
//!
//! let n = nc + nx;
//! let b: Vec<f64> = (0..n).map(|i| i as f64 - 3.0).collect();
//! let factor = a.factor()?;
//! let mut x = b.clone();
//! factor.solve_in_place(&mut x);
//!
//! let dense = Mat::from_fn(n, n, |i, j| a.get(i, j));
//! let llt = dense.llt(Side::Lower).expect("positive definite");
//! let want = llt.solve(Mat::from_fn(n, 1, |i, _| b[i]));
//! for i in 0..n {
//!     assert!((x[i] - want[(i, 0)]).abs() < 1e-10, "x[{i}]");
//! }
//! // the marginal covariance of the parameters: their block of A⁻¹
//! let (cov, inv) = (factor.covariance_x(), llt.inverse());
//! for k in 0..nx {
//!     for l in 0..nx {
//!         assert!((cov[(k, l)] - inv[(nc + k, nc + l)]).abs() < 1e-10);
//!     }
//! }
//! # Ok::<(), robimu_solver::FactorError>(())
//! ```

#![deny(missing_docs)]
#![allow(clippy::needless_range_loop)]

pub mod arrow;
pub mod dense;
pub mod gram;
pub mod lm;
pub mod pose_problem;
pub mod problem;

pub use arrow::{ArrowFactor, ArrowMatrix, FactorError, SelectedInverse};
pub use lm::{
    solve, solve_from, IterationRecord, LeastSquares, Linearization, LmError, LmOptions,
    LmSolution, LmSummary, Termination,
};

pub use crate::dense::DenseError;
pub use crate::pose_problem::{
    ChannelFit, ExtraSums, PoseData, PoseImuData, PoseProblem, PoseProblemError, PoseSigma,
};
pub use crate::problem::ImuResiduals;
