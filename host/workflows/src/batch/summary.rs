//! The summary of a batch: one row per session and IMU (docs/guide/calibrating.md "Production
//! batches" lists the columns), written as CSV.

use std::path::{Path, PathBuf};

use robimu_model::ParamLayout;

use super::limits::{sensor_rms, Limits};
use super::Outcome;

/// The names of the IMU's own parameters in x (docs/model.md §5, MODEL.md
/// §9): its position (the estimated translations of the last link's ε),
/// τ and its 24 intrinsics.
pub(crate) fn imu_parameter_names(layout: &ParamLayout) -> Vec<String> {
    let specs = layout.specs();
    let n = layout.n_links();
    let position = layout
        .estimated_errors()
        .iter()
        .enumerate()
        .filter(|(_, e)| e.link == n && e.is_translation())
        .map(|(k, _)| specs[k].name.clone());
    let rest = specs[layout.offsets().tau..].iter().map(|s| s.name.clone());
    position.chain(rest).collect()
}

/// One session of a batch with its outcome.
#[derive(Debug, Clone)]
pub struct SessionOutcome {
    /// The session directory.
    pub dir: PathBuf,
    /// How it ended.
    pub outcome: Outcome,
    /// [`imu_parameter_names`] of its robot (empty when unreadable).
    pub imu_parameters: Vec<String>,
}

/// One summary row: a session's IMU.
#[derive(Debug, Clone)]
pub struct Row {
    /// The session directory.
    pub session: String,
    /// The IMU (0: imu.csv).
    pub imu: usize,
    /// `ok`, `failed` or `unreadable`.
    pub status: &'static str,
    /// The error of a failed or unreadable session.
    pub error: String,
    /// The limits it fails (empty when it passes or was not calibrated).
    pub failed_limits: Vec<String>,
    /// Why the solver stopped.
    pub termination: String,
    /// Solver iterations.
    pub iterations: Option<usize>,
    /// Whitened residual RMS of the accelerometer and the gyroscope.
    pub residual_rms: Option<[f64; 2]>,
    /// The IMU's parameters: name, value, σ (SI, result.json's).
    pub values: Vec<(String, f64, f64)>,
}

impl Row {
    /// Whether the unit passes: calibrated and within every limit.
    pub fn passes(&self) -> bool {
        self.status == "ok" && self.failed_limits.is_empty()
    }
}

/// The summary of a batch.
#[derive(Debug, Clone)]
pub struct Summary {
    /// One row per session and IMU, in the sessions' order.
    pub rows: Vec<Row>,
}

impl Summary {
    /// The rows of `sessions` checked against `limits`: one per IMU of a
    /// calibrated session (docs/model.md §9: IMU j's parameters under their
    /// §5 names, [`CalibrationResult::imu`](robimu_session::result::CalibrationResult::imu)), one for a session that failed
    /// or is unreadable. The residual RMS of a multi-IMU result is over all
    /// its IMUs (the result file has no per-IMU one, §8), so a residual
    /// limit applies to the joint fit.
    pub fn new(sessions: &[SessionOutcome], limits: &Limits) -> Self {
        let mut rows = Vec::new();
        for s in sessions {
            let row = |imu: usize| Row {
                session: s.dir.display().to_string(),
                imu,
                status: "ok",
                error: String::new(),
                failed_limits: Vec::new(),
                termination: String::new(),
                iterations: None,
                residual_rms: None,
                values: Vec::new(),
            };
            let r = match &s.outcome {
                Outcome::Unreadable(e) => {
                    rows.push(Row {
                        status: "unreadable",
                        error: e.clone(),
                        ..row(0)
                    });
                    continue;
                }
                Outcome::Failed(e) => {
                    rows.push(Row {
                        status: "failed",
                        error: e.clone(),
                        ..row(0)
                    });
                    continue;
                }
                Outcome::Calibrated(r) => r,
            };
            let k = r.imu_sets().map_or(1, |sets| sets.len());
            for j in 0..k {
                let view = match r.imu(j) {
                    Ok(mut v) => {
                        v.residual_rms = r.residual_rms;
                        v
                    }
                    Err(e) => {
                        rows.push(Row {
                            status: "failed",
                            error: format!("the result's IMU {j}: {e}"),
                            ..row(j)
                        });
                        continue;
                    }
                };
                rows.push(Row {
                    failed_limits: limits.failures(&view),
                    termination: view.termination.clone().unwrap_or_default(),
                    iterations: view.iterations,
                    residual_rms: view.residual_rms.as_ref().map(sensor_rms),
                    values: s
                        .imu_parameters
                        .iter()
                        .filter_map(|name| {
                            view.parameters
                                .iter()
                                .find(|p| &p.name == name)
                                .map(|p| (p.name.clone(), p.value, p.sigma))
                        })
                        .collect(),
                    ..row(j)
                });
            }
        }
        Self { rows }
    }

    /// Rows that are calibrated but fail a limit, that failed, and that are
    /// unreadable.
    pub fn counts(&self) -> (usize, usize, usize) {
        let n = |f: &dyn Fn(&Row) -> bool| self.rows.iter().filter(|r| f(r)).count();
        (
            n(&|r| r.status == "ok" && !r.failed_limits.is_empty()),
            n(&|r| r.status == "failed"),
            n(&|r| r.status == "unreadable"),
        )
    }

    /// The CSV: the fixed columns, then `NAME` and `NAME_sigma` of every
    /// parameter any row has (first appearance order); numbers in Rust's
    /// shortest round-trip form, empty where a row has no value.
    pub fn write_csv(&self, path: &Path) -> Result<(), csv::Error> {
        let mut names: Vec<&str> = Vec::new();
        for r in &self.rows {
            for (n, _, _) in &r.values {
                if !names.contains(&n.as_str()) {
                    names.push(n);
                }
            }
        }
        let mut w = csv::Writer::from_path(path)?;
        let mut header: Vec<String> = [
            "session",
            "imu",
            "status",
            "error",
            "limits",
            "failed_limits",
            "termination",
            "iterations",
            "residual_rms_accel",
            "residual_rms_gyro",
        ]
        .map(String::from)
        .to_vec();
        for n in &names {
            header.push(n.to_string());
            header.push(format!("{n}_sigma"));
        }
        w.write_record(&header)?;
        let opt = |v: Option<f64>| v.map(|v| v.to_string()).unwrap_or_default();
        for r in &self.rows {
            let verdict = match (r.status, r.passes()) {
                ("ok", true) => "pass",
                _ => "fail",
            };
            let mut rec = vec![
                r.session.clone(),
                r.imu.to_string(),
                r.status.to_string(),
                r.error.clone(),
                verdict.to_string(),
                r.failed_limits.join("; "),
                r.termination.clone(),
                r.iterations.map(|i| i.to_string()).unwrap_or_default(),
                opt(r.residual_rms.map(|x| x[0])),
                opt(r.residual_rms.map(|x| x[1])),
            ];
            for n in &names {
                let v = r.values.iter().find(|(m, _, _)| m == n);
                rec.push(opt(v.map(|v| v.1)));
                rec.push(opt(v.map(|v| v.2)));
            }
            w.write_record(&rec)?;
        }
        w.flush()?;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use robimu_model::Robot;

    #[test]
    fn imu_parameters_are_position_tau_and_the_24_intrinsics() {
        let layout = ParamLayout::new(&Robot::aubo_i5());
        let names = imu_parameter_names(&layout);
        assert_eq!(names.len(), 28);
        assert_eq!(names[..4], ["eps_6_1", "eps_6_2", "eps_6_3", "tau"]);
        assert_eq!(names[4], "gamma_a_yz");
        assert_eq!(names[27], "b_w_z");
        assert!(names.iter().all(|n| !n.starts_with("g_")));
    }
}
