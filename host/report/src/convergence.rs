//! The solver's iteration history file (NAME.convergence.csv): defined in
//! [`robimu_workflows::convergence`], which writes it with every result file.

pub use robimu_workflows::convergence::*;
