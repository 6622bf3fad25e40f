//! What a calibration hands to people: tables, figures and HTML pages made
//! from finished results (a [`CalibrationResult`](robimu_session::CalibrationResult),
//! the solver's iteration history, the validation's accuracies). Nothing here
//! fits or calibrates; the callers pass in what those computed.
//!
//! * [`table`] — the paper's Table II as text ([`ParameterTable`]): prior,
//!   estimate and posterior σ of every parameter, and, against a known truth,
//!   the errors and the normalised estimation error squared (NEES);
//! * [`check`] — the table of the pre-flight check of a recording;
//! * [`html`] — self-contained HTML reports (calibration, validation);
//! * [`montecarlo`] — the files, table and histograms of a Monte Carlo study;
//! * [`convergence`] — the solver's iteration history next to a result file;
//! * [`diagnosis`] — the text summary of a model-discrepancy diagnosis;
//! * [`diagnosis_figures`] — its residual and spectrum figures, before and after;
//! * [`fit_summary`] — brief and full text reports of a fit, the
//!   weak-direction warning, fitted effects, the repeatability table;
//! * [`plot`] — line, bar and histogram figures as PNG and SVG (embedded font);
//! * [`figures`] — the calibration report's σ-reduction and residual figures;
//! * [`allan`] — the Allan deviation table, allan.csv and its figure;
//! * [`csvfile`] — CSV tables written beside the figures;
//! * [`demo`] — the text of `robimu demo` between its stages;
//! * [`identifiability`] — the identifiability studies' tables, figures and text;
//! * [`model_summary`] — the model a calibration wrote and why, and its pose accuracy;
//! * [`noise`] — the table of `robimu noise`;
//! * [`plan`] — the plan directory and the summary of `robimu plan`;
//! * [`recording`] — the summaries of a recording and of a repair;
//! * [`result_report`] — `robimu report`'s page of a result file, with its
//!   session's series and iteration history;
//! * [`verdict`] — the verdict on a calibration, as text (the HTML block is [`html`]'s);
//! * [`validation`] — the accuracy tables `robimu validate` prints and validation.json.
//!
//! # Example
//!
//! The table and the HTML report of a result file (from `robimu calibrate`):
//!
//! ```no_run
//! use std::path::Path;
//!
//! use robimu_report::html::calibration_report;
//! use robimu_report::ParameterTable;
//! use robimu_session::CalibrationResult;
//!
//! let result = CalibrationResult::read(Path::new("session/result.json"))?;
//! println!("{}", ParameterTable::new(&result, None));
//! // no truth, no iteration history, no session series
//! let page = calibration_report(Path::new("report"), &result, None, None, None)?;
//! println!("wrote {}", page.display());
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

#![deny(missing_docs)]

pub mod allan;
pub mod check;
pub mod convergence;
pub mod csvfile;
pub mod demo;
pub mod diagnosis;
pub mod diagnosis_figures;
pub mod figures;
pub mod fit_summary;
pub mod html;
pub mod identifiability;
pub mod model_summary;
pub mod montecarlo;
pub mod noise;
pub mod plan;
pub mod plot;
pub mod recording;
pub mod result_report;
pub mod table;
pub mod validation;
pub mod verdict;

pub use robimu_model::units::DisplayUnit;
pub use table::{ParameterTable, TableRow, TableSection, TruthSummary};

pub use crate::html::SessionSeries;
pub use crate::html::{
    calibration_report, calibration_report_imus, calibration_report_with, ModelEvidence,
    ReportError,
};
pub use crate::plot::PlotError;
