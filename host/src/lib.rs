//! robimu host library.

pub mod link;
pub mod model;
pub mod problem;
pub mod session;
pub mod solver;
pub mod workflows;
