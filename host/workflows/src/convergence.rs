//! The solver's iteration history next to a result file, so that
//! `robimu report RESULT` can draw the convergence figure later.
//!
//! `robimu calibrate --out DIR/NAME.json` also writes `DIR/NAME.convergence.csv`
//! ([`convergence_path`]):
//!
//! ```text
//! iteration,cost,step_norm,lambda,gradient_norm,tries
//! 0,<initial cost>,,,,
//! 1,<cost after iteration 1>,<‖√D δ‖>,<λ>,<max |g_k|/√A_kk>,<steps tried>
//! …
//! ```
//!
//! Row 0 is the cost at the start; each further row is one Levenberg–Marquardt
//! iteration ([`IterationRecord`]). The cost is J = ½‖r‖² of the MAP problem.

use std::path::{Path, PathBuf};

use robimu_solver::lm::{IterationRecord, LmSummary};

/// The convergence file could not be written or read.
#[derive(Debug, thiserror::Error)]
pub enum ConvergenceError {
    /// Reading or writing failed.
    #[error("cannot {action} {}: {message}", path.display())]
    Io {
        /// `read` or `write`.
        action: &'static str,
        /// The file.
        path: PathBuf,
        /// What went wrong.
        message: String,
    },
    /// The file is not an iteration history.
    #[error("{}: line {line}: {message}", path.display())]
    Format {
        /// The file.
        path: PathBuf,
        /// 1-based line number (1 = header).
        line: usize,
        /// What is wrong.
        message: String,
    },
}

/// Column names of the convergence file.
pub(crate) const CONVERGENCE_COLUMNS: [&str; 6] = [
    "iteration",
    "cost",
    "step_norm",
    "lambda",
    "gradient_norm",
    "tries",
];

/// `DIR/NAME.convergence.csv` for the result file `DIR/NAME.json`.
pub fn convergence_path(result: &Path) -> PathBuf {
    let stem = result
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "result".into());
    result.with_file_name(format!("{stem}.convergence.csv"))
}

/// The iteration history of one solver run.
#[derive(Debug, Clone, PartialEq)]
pub struct ConvergenceLog {
    /// Cost before the first iteration.
    pub initial_cost: f64,
    /// One record per iteration.
    pub iterations: Vec<IterationRecord>,
}

impl ConvergenceLog {
    /// The history of a solver run.
    pub fn from_summary(summary: &LmSummary) -> Self {
        Self {
            initial_cost: summary.initial_cost,
            iterations: summary.iterations.clone(),
        }
    }

    /// The cost at the start and after each iteration.
    pub fn costs(&self) -> Vec<f64> {
        std::iter::once(self.initial_cost)
            .chain(self.iterations.iter().map(|r| r.cost))
            .collect()
    }

    /// Write the CSV file (full precision).
    pub fn write(&self, path: &Path) -> Result<(), ConvergenceError> {
        let err = |e: csv::Error| ConvergenceError::Io {
            action: "write",
            path: path.to_path_buf(),
            message: e.to_string(),
        };
        let mut w = csv::Writer::from_path(path).map_err(err)?;
        w.write_record(CONVERGENCE_COLUMNS).map_err(err)?;
        w.write_record(["0", &self.initial_cost.to_string(), "", "", "", ""])
            .map_err(err)?;
        for r in &self.iterations {
            w.write_record([
                r.iteration.to_string(),
                r.cost.to_string(),
                r.step_norm.to_string(),
                r.lambda.to_string(),
                r.gradient_norm.to_string(),
                r.tries.to_string(),
            ])
            .map_err(err)?;
        }
        w.flush().map_err(|e| ConvergenceError::Io {
            action: "write",
            path: path.to_path_buf(),
            message: e.to_string(),
        })
    }

    /// Read and check a file written by [`Self::write`].
    pub fn read(path: &Path) -> Result<Self, ConvergenceError> {
        let mut rdr = csv::ReaderBuilder::new()
            .trim(csv::Trim::All)
            .from_path(path)
            .map_err(|e| ConvergenceError::Io {
                action: "read",
                path: path.to_path_buf(),
                message: e.to_string(),
            })?;
        let bad = |line: usize, message: String| ConvergenceError::Format {
            path: path.to_path_buf(),
            line,
            message,
        };
        let header = rdr.headers().map_err(|e| bad(1, e.to_string()))?.clone();
        if header.iter().ne(CONVERGENCE_COLUMNS) {
            return Err(bad(
                1,
                format!(
                    "header must be `{}`, not `{}`",
                    CONVERGENCE_COLUMNS.join(","),
                    header.iter().collect::<Vec<_>>().join(",")
                ),
            ));
        }
        let mut initial_cost = None;
        let mut iterations = Vec::new();
        for (k, rec) in rdr.records().enumerate() {
            let line = k + 2;
            let rec = rec.map_err(|e| bad(line, e.to_string()))?;
            let num = |c: usize| -> Result<f64, ConvergenceError> {
                let field = rec.get(c).unwrap_or("");
                field
                    .parse::<f64>()
                    .ok()
                    .filter(|v| v.is_finite())
                    .ok_or_else(|| {
                        bad(
                            line,
                            format!("{} = `{field}` is not a number", CONVERGENCE_COLUMNS[c]),
                        )
                    })
            };
            let iteration = num(0)?;
            if iteration != k as f64 {
                return Err(bad(
                    line,
                    format!("iteration {iteration} where {k} was expected"),
                ));
            }
            let cost = num(1)?;
            if k == 0 {
                initial_cost = Some(cost);
                continue;
            }
            iterations.push(IterationRecord {
                iteration: k,
                cost,
                step_norm: num(2)?,
                lambda: num(3)?,
                gradient_norm: num(4)?,
                tries: num(5)? as usize,
            });
        }
        let initial_cost = initial_cost.ok_or_else(|| bad(2, "no rows".into()))?;
        Ok(Self {
            initial_cost,
            iterations,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trips_and_rejects_other_files() {
        let log = ConvergenceLog {
            initial_cost: 1.234_567_890_123e6,
            iterations: (1..=3)
                .map(|k| IterationRecord {
                    iteration: k,
                    cost: 1e6 / (k * k) as f64 + 0.1,
                    step_norm: 0.5 / k as f64,
                    lambda: 1e-4 / 3f64.powi(k as i32),
                    gradient_norm: 10f64.powi(-(k as i32)),
                    tries: k,
                })
                .collect(),
        };
        let dir = tempfile::tempdir().unwrap();
        let path = convergence_path(&dir.path().join("run.json"));
        assert_eq!(path.file_name().unwrap(), "run.convergence.csv");
        log.write(&path).unwrap();
        assert_eq!(ConvergenceLog::read(&path).unwrap(), log);
        assert_eq!(log.costs().len(), 4);

        std::fs::write(&path, "t,q1\n0,1\n").unwrap();
        let e = ConvergenceLog::read(&path).unwrap_err().to_string();
        assert!(e.contains("header must be"), "{e}");
        std::fs::write(
            &path,
            "iteration,cost,step_norm,lambda,gradient_norm,tries\n0,5,,,,\n2,4,1,1,1,1\n",
        )
        .unwrap();
        let e = ConvergenceLog::read(&path).unwrap_err().to_string();
        assert!(e.contains("line 3") && e.contains("expected"), "{e}");
        std::fs::write(
            &path,
            "iteration,cost,step_norm,lambda,gradient_norm,tries\n0,x,,,,\n",
        )
        .unwrap();
        let e = ConvergenceLog::read(&path).unwrap_err().to_string();
        assert!(e.contains("cost = `x`"), "{e}");
        let e = ConvergenceLog::read(&dir.path().join("none.csv"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("cannot read"), "{e}");
    }
}
