//! What a calibration hands to people and to later tools.
//!
//! * [`result`] — the result file `result.json` (docs/model.md §8): writing it
//!   from a [`Calibration`](robimu_workflows::calibrate::Calibration) and
//!   reading it back, validated;
//! * [`html`] — self-contained HTML reports (calibration, validation);
//! * [`convergence`] — the solver's iteration history next to a result file;
//! * [`units`] — display units (mm, degrees, °/s) for the SI values in files;
//! * [`table`] — the paper's Table II as text: prior, estimate and posterior σ
//!   of every parameter, and, against a known truth, the errors and the
//!   normalised estimation error squared (NEES).

#![deny(missing_docs)]

pub mod convergence;
pub mod html;
pub mod plot;
pub mod table;

pub use robimu_model::units::DisplayUnit;
pub use table::{ParameterTable, TableRow, TruthSummary};
