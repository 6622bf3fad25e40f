//! What a calibration hands to people and to later tools.
//!
//! * [`result`] — the result file `result.json` (docs/model.md §8): writing it
//!   from a [`Calibration`](robimu_workflows::calibrate::Calibration) and
//!   reading it back, validated;
//! * [`demo`] — the text of `robimu demo` between its stages;
//! * [`html`] — self-contained HTML reports (calibration, validation);
//! * [`allan`] — the Allan deviation table, allan.csv and its figure;
//! * [`convergence`] — the solver's iteration history next to a result file;
//! * [`csvfile`] — CSV tables written beside the figures;
//! * [`identifiability`] — the identifiability studies' tables, figures and text;
//! * [`noise`] — the table of `robimu noise`;
//! * [`plan`] — the plan directory and the summary of `robimu plan`;
//! * [`recording`] — the summaries of a recording and of a repair;
//! * [`validation`] — the accuracy tables `robimu validate` prints and validation.json;
//! * [`units`] — display units (mm, degrees, °/s) for the SI values in files;
//! * [`table`] — the paper's Table II as text: prior, estimate and posterior σ
//!   of every parameter, and, against a known truth, the errors and the
//!   normalised estimation error squared (NEES).

#![deny(missing_docs)]

pub mod allan;
pub mod convergence;
pub mod csvfile;
pub mod demo;
pub mod html;
pub mod identifiability;
pub mod noise;
pub mod plan;
pub mod plot;
pub mod recording;
pub mod table;
pub mod validation;

pub use robimu_model::units::DisplayUnit;
pub use table::{ParameterTable, TableRow, TruthSummary};
