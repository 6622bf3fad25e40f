//! Solvers: the structured factorisation of the normal equations
//! ([`arrow`]) and the Levenberg–Marquardt iteration ([`lm`]).

pub mod arrow;
pub mod lm;

pub use arrow::{ArrowFactor, ArrowMatrix, FactorError};
pub use lm::{
    solve, IterationRecord, LeastSquares, LmError, LmOptions, LmSolution, LmSummary, Termination,
};
