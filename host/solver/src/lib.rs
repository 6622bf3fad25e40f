//! The calibration problem and its solvers (paper §6): the residuals,
//! priors and exact Jacobians assembled into the arrowhead normal matrix
//! ([`problem`]), its structured factorisation and covariance ([`arrow`]),
//! the Levenberg–Marquardt iteration ([`lm`]) and small dense problems on
//! that same iteration ([`dense`]).

#![deny(missing_docs)]
#![allow(clippy::needless_range_loop)]

pub mod arrow;
pub mod dense;
pub mod lm;
pub mod problem;

pub use arrow::{ArrowFactor, ArrowMatrix, FactorError};
pub use lm::{
    solve, IterationRecord, LeastSquares, LmError, LmOptions, LmSolution, LmSummary, Termination,
};
