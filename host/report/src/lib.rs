//! What a calibration hands to people and to later tools.
//!
//! * [`result`] — the result file `result.json` (docs/model.md §8): writing it
//!   from a [`Calibration`](robimu_workflows::calibrate::Calibration) and
//!   reading it back, validated;
//! * [`html`] — self-contained HTML reports (calibration, validation);
//! * [`montecarlo`] — the files, table and histograms of a Monte Carlo study;
//! * [`convergence`] — the solver's iteration history next to a result file;
//! * [`diagnosis`] — the text summary of a model-discrepancy diagnosis;
//! * [`fit_summary`] — brief and full text reports of a fit, the
//!   weak-direction warning, fitted effects, the repeatability table;
//! * [`units`] — display units (mm, degrees, °/s) for the SI values in files;
//! * [`table`] — the paper's Table II as text: prior, estimate and posterior σ
//!   of every parameter, and, against a known truth, the errors and the
//!   normalised estimation error squared (NEES).

#![deny(missing_docs)]

pub mod convergence;
pub mod diagnosis;
pub mod fit_summary;
pub mod html;
pub mod montecarlo;
pub mod plot;
pub mod table;

pub use robimu_model::units::DisplayUnit;
pub use table::{ParameterTable, TableRow, TruthSummary};
