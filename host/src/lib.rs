//! robimu host library.

// Numerical kernels index several arrays in step (rows, columns, channels);
// index loops say that more plainly than zipped iterators.
#![allow(clippy::needless_range_loop)]

pub mod effects;
pub mod export;
pub mod hil;
pub mod import;
pub mod link;
pub mod model;
pub mod plot;
pub mod problem;
pub mod record;
pub mod report;
pub mod robot;
pub mod session;
pub mod solver;
pub mod workflows;
