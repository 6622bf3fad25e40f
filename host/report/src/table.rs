//! The parameter table of the paper's Table II: for every parameter its
//! nominal value and prior σ, the estimate and its posterior σ, in display
//! units ([`DisplayUnit`]); against a known truth (a simulated session's
//! `truth.toml`) also the error and the error in posterior σ, and the
//! normalised estimation error squared
//!
//! ```text
//! NEES = eᵀ Σ⁻¹ e,   e = x̂ − x_true over the estimated parameters,
//! ```
//!
//! which for a consistent estimator is χ²-distributed with as many degrees of
//! freedom as parameters.

use std::f64::consts::PI;
use std::fmt;

use faer::linalg::solvers::Solve;
use faer::{Mat, Side};

use robimu_model::units::DisplayUnit;
use robimu_session::result::CalibrationResult;
use robimu_session::Truth;

/// One line of the table, in display units.
#[derive(Debug, Clone, PartialEq)]
pub struct TableRow {
    /// Parameter name.
    pub name: String,
    /// Display unit.
    pub unit: DisplayUnit,
    /// Prior mean.
    pub nominal: f64,
    /// Prior σ.
    pub prior_sigma: f64,
    /// Estimate.
    pub estimate: f64,
    /// Posterior σ; `None` when frozen.
    pub sigma: Option<f64>,
    /// Estimate − truth (angles wrapped to ±180°), when the truth is known.
    pub error: Option<f64>,
    /// Error / posterior σ, when the truth is known and the parameter estimated.
    pub normalized_error: Option<f64>,
}

/// How the estimate compares with a known truth.
#[derive(Debug, Clone, PartialEq)]
pub struct TruthSummary {
    /// Largest |error/σ| over the estimated parameters.
    pub max_abs_normalized_error: f64,
    /// The parameter where it occurs.
    pub worst: String,
    /// eᵀ Σ⁻¹ e over the estimated parameters with a true value; `None` when
    /// the covariance is not positive definite.
    pub nees: Option<f64>,
    /// Degrees of freedom of the NEES (estimated parameters with a true value).
    pub dof: usize,
    /// Parameters that `truth.toml` does not list.
    pub missing: Vec<String>,
}

impl TruthSummary {
    /// The central 95 % range of χ² with [`dof`](Self::dof) degrees of freedom
    /// (Wilson–Hilferty approximation): where the NEES of a consistent
    /// estimator falls 19 times in 20.
    pub fn nees_range_95(&self) -> (f64, f64) {
        chi2_central_range(self.dof, 1.959_963_984_540_054)
    }
}

/// Quantiles of χ²_k at the standard-normal quantiles ∓z (Wilson–Hilferty).
fn chi2_central_range(k: usize, z: f64) -> (f64, f64) {
    let k = k.max(1) as f64;
    let c = 2.0 / (9.0 * k);
    let q = |z: f64| k * (1.0 - c + z * c.sqrt()).max(0.0).powi(3);
    (q(-z), q(z))
}

/// The table of one result.
#[derive(Debug, Clone, PartialEq)]
pub struct ParameterTable {
    /// One row per parameter, in x order.
    pub rows: Vec<TableRow>,
    /// The comparison with the truth, when one was given.
    pub truth: Option<TruthSummary>,
    /// A result of several IMUs (docs/model.md §9): the shared parameters,
    /// then each IMU's, under a heading; empty for one IMU (a plain table).
    pub sections: Vec<TableSection>,
}

/// A heading of a [`ParameterTable`] and the rows under it.
#[derive(Debug, Clone, PartialEq)]
pub struct TableSection {
    /// `shared: robot errors and gravity` (a pose session's result, which
    /// has no robot: `shared: gravity`), `IMU 1 (imu1.csv)`, …
    pub title: String,
    /// Indices into [`ParameterTable::rows`], in file order.
    pub rows: Vec<usize>,
}

impl TableSection {
    /// The sections of `result`: empty for one IMU, else the shared
    /// parameters, then IMU 0, 1, … ([`CalibrationResult::imu_sets`]).
    pub fn of(result: &CalibrationResult) -> Vec<Self> {
        let Ok(sets) = result.imu_sets() else {
            return Vec::new();
        };
        if sets.len() < 2 {
            return Vec::new();
        }
        let shared = if result.source.as_deref() == Some(robimu_session::SOURCE_POSES) {
            "shared: gravity"
        } else {
            "shared: robot errors and gravity"
        };
        let mut out = vec![Self {
            title: shared.into(),
            rows: sets.shared.clone(),
        }];
        for (j, rows) in sets.imus.iter().enumerate() {
            let file = if j == 0 {
                "imu.csv".to_string()
            } else {
                format!("imu{j}.csv")
            };
            out.push(Self {
                title: format!("IMU {j} ({file})"),
                rows: rows.clone(),
            });
        }
        out
    }
}

/// `a − b`, wrapped into (−π, π] for angles.
fn difference(a: f64, b: f64, angle: bool) -> f64 {
    let d = a - b;
    if angle {
        let w = d.rem_euclid(2.0 * PI);
        if w > PI {
            w - 2.0 * PI
        } else {
            w
        }
    } else {
        d
    }
}

impl ParameterTable {
    /// The table of `result`, compared with `truth` when given.
    pub fn new(result: &CalibrationResult, truth: Option<&Truth>) -> Self {
        let mut rows = Vec::with_capacity(result.parameters.len());
        // SI errors of the estimated parameters with a true value, by covariance index
        let mut errors: Vec<(usize, f64)> = Vec::new();
        let mut missing = Vec::new();
        let mut worst = (0.0f64, String::new());
        for p in &result.parameters {
            let unit = DisplayUnit::for_si(&p.unit);
            let true_value = truth.and_then(|t| t.get(&p.name));
            if truth.is_some() && true_value.is_none() {
                missing.push(p.name.clone());
            }
            let error_si = true_value.map(|t| difference(p.value, t, unit.is_angle()));
            let normalized = match (error_si, p.frozen) {
                (Some(e), false) => Some(e / p.sigma),
                _ => None,
            };
            if let (Some(z), Some(e)) = (normalized, error_si) {
                if z.abs() > worst.0 || worst.1.is_empty() {
                    worst = (z.abs(), p.name.clone());
                }
                if let Some(i) = result.covariance.names.iter().position(|n| n == &p.name) {
                    errors.push((i, e));
                }
            }
            rows.push(TableRow {
                name: p.name.clone(),
                nominal: unit.show(p.prior),
                prior_sigma: unit.show(p.prior_sigma),
                estimate: unit.show(p.value),
                sigma: (!p.frozen).then(|| unit.show(p.sigma)),
                error: error_si.map(|e| unit.show(e)),
                normalized_error: normalized,
                unit,
            });
        }
        let truth = truth.map(|_| TruthSummary {
            max_abs_normalized_error: worst.0,
            worst: worst.1,
            nees: nees(&result.covariance.matrix, &errors),
            dof: errors.len(),
            missing,
        });
        Self {
            rows,
            truth,
            sections: TableSection::of(result),
        }
    }

    /// Per section with a known truth: its title, the largest |error/σ| and
    /// where it occurs (empty for one IMU).
    pub fn worst_per_section(&self) -> Vec<(String, f64, String)> {
        self.sections
            .iter()
            .filter_map(|s| {
                s.rows
                    .iter()
                    .filter_map(|&i| {
                        let r = &self.rows[i];
                        r.normalized_error.map(|z| (z.abs(), r.name.clone()))
                    })
                    .max_by(|a, b| a.0.total_cmp(&b.0))
                    .map(|(z, name)| (s.title.clone(), z, name))
            })
            .collect()
    }
}

/// eᵀ Σ_s⁻¹ e with Σ_s the rows and columns of `cov` that `errors` index.
fn nees(cov: &[Vec<f64>], errors: &[(usize, f64)]) -> Option<f64> {
    let k = errors.len();
    if k == 0 {
        return None;
    }
    let sub = Mat::from_fn(k, k, |a, b| cov[errors[a].0][errors[b].0]);
    let llt = sub.llt(Side::Lower).ok()?;
    let e = Mat::from_fn(k, 1, |a, _| errors[a].1);
    let w = llt.solve(&e);
    Some((0..k).map(|a| e[(a, 0)] * w[(a, 0)]).sum())
}

/// Decimals that show `sigma` with two to three significant digits.
fn decimals(sigma: f64) -> usize {
    if !(sigma.is_finite() && sigma > 0.0) {
        return 4;
    }
    (2 - sigma.log10().floor() as i64).clamp(0, 9) as usize
}

impl fmt::Display for ParameterTable {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let with_truth = self.truth.is_some();
        let mut header = vec!["parameter", "unit", "nominal", "prior σ", "estimate", "σ"];
        if with_truth {
            header.extend(["error", "error/σ"]);
        }
        let mut cells: Vec<Vec<String>> = vec![header.iter().map(|s| s.to_string()).collect()];
        // one IMU: the rows in order; several: each section's under its title
        let order: Vec<(Option<&str>, usize)> = if self.sections.is_empty() {
            (0..self.rows.len()).map(|i| (None, i)).collect()
        } else {
            self.sections
                .iter()
                .flat_map(|s| {
                    s.rows
                        .iter()
                        .enumerate()
                        .map(move |(k, &i)| ((k == 0).then_some(s.title.as_str()), i))
                })
                .collect()
        };
        let mut titles: Vec<(usize, &str)> = Vec::new();
        for (title, i) in order {
            let r = &self.rows[i];
            if let Some(t) = title {
                titles.push((cells.len(), t));
            }
            let dp = decimals(r.prior_sigma);
            let d = decimals(r.sigma.unwrap_or(r.prior_sigma));
            let mut line = vec![
                r.name.clone(),
                r.unit.symbol().to_string(),
                format!("{:.dp$}", r.nominal),
                format!("{:.dp$}", r.prior_sigma),
                format!("{:.d$}", r.estimate),
                r.sigma
                    .map_or_else(|| "frozen".to_string(), |s| format!("{s:.d$}")),
            ];
            if with_truth {
                line.push(r.error.map_or_else(|| "-".into(), |e| format!("{e:.d$}")));
                line.push(
                    r.normalized_error
                        .map_or_else(|| "-".into(), |z| format!("{z:.2}")),
                );
            }
            cells.push(line);
        }
        let columns = cells[0].len();
        let width: Vec<usize> = (0..columns)
            .map(|c| {
                cells
                    .iter()
                    .map(|l| l[c].chars().count())
                    .max()
                    .unwrap_or(0)
            })
            .collect();
        writeln!(
            f,
            "values in display units: m as mm, rad as deg, rad/s as deg/s (result files hold SI)"
        )?;
        let total = width.iter().sum::<usize>() + 2 * (columns - 1);
        for (i, line) in cells.iter().enumerate() {
            if let Some((_, t)) = titles.iter().find(|(at, _)| *at == i) {
                let rule = total.saturating_sub(t.chars().count() + 4).max(2);
                writeln!(f, "-- {t} {}", "-".repeat(rule))?;
            }
            let mut text = String::new();
            for (c, cell) in line.iter().enumerate() {
                let pad = width[c] - cell.chars().count();
                if c < 2 {
                    // names and units left-aligned
                    text.push_str(cell);
                    text.push_str(&" ".repeat(pad));
                } else {
                    text.push_str(&" ".repeat(pad));
                    text.push_str(cell);
                }
                if c + 1 < columns {
                    text.push_str("  ");
                }
            }
            writeln!(f, "{}", text.trim_end())?;
            if i == 0 {
                writeln!(f, "{}", "-".repeat(total))?;
            }
        }
        if let Some(t) = &self.truth {
            write!(
                f,
                "against the truth: max |error/σ| = {:.2} ({})",
                t.max_abs_normalized_error, t.worst
            )?;
            match t.nees {
                Some(nees) => {
                    let (lo, hi) = t.nees_range_95();
                    write!(
                        f,
                        "; NEES = {nees:.1} over {} estimated parameters (a consistent estimator: {lo:.1} .. {hi:.1}, 95 %)",
                        t.dof
                    )?;
                }
                None => write!(f, "; NEES unavailable (covariance not positive definite)")?,
            }
            writeln!(f)?;
            let per = self.worst_per_section();
            if !per.is_empty() {
                let parts: Vec<String> = per
                    .iter()
                    .map(|(title, z, name)| format!("{title} {z:.2} ({name})"))
                    .collect();
                writeln!(f, "max |error/σ| by section: {}", parts.join("; "))?;
            }
            if !t.missing.is_empty() {
                writeln!(f, "the truth does not list: {}", t.missing.join(", "))?;
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use robimu_session::result::{CovarianceMatrix, ParameterResult, RESULT_FORMAT};

    fn param(name: &str, unit: &str, value: f64, sigma: f64, frozen: bool) -> ParameterResult {
        ParameterResult {
            name: name.into(),
            unit: unit.into(),
            value,
            prior: 0.0,
            prior_sigma: 1.0,
            sigma,
            frozen,
        }
    }

    fn result(parameters: Vec<ParameterResult>, cov: Vec<Vec<f64>>) -> CalibrationResult {
        let names = parameters
            .iter()
            .filter(|p| !p.frozen)
            .map(|p| p.name.clone())
            .collect();
        let r = CalibrationResult {
            format: RESULT_FORMAT.into(),
            parameters,
            covariance: CovarianceMatrix { names, matrix: cov },
            robot: None,
            source: None,
            session: None,
            priors_used: None,
            tau_initial: None,
            knot_spacing: None,
            iterations: None,
            initial_cost: None,
            final_cost: None,
            termination: None,
            residual_rms: None,
            imu_samples_used: None,
            weak_directions: Vec::new(),
            noise_model: None,
            imu_noise_models: Vec::new(),
            noise_warning: None,
            verdict: None,
            effects: None,
            model_tests: None,
            pose_accuracy: None,
            covariance_kind: None,
        };
        r.validate().unwrap();
        r
    }

    fn truth(values: &[(&str, f64)]) -> Truth {
        Truth {
            values: values.iter().map(|(n, v)| (n.to_string(), *v)).collect(),
        }
    }

    #[test]
    fn nees_matches_the_explicit_inverse() {
        // Σ = [[a, c], [c, b]]: Σ⁻¹ = [[b, −c], [−c, a]] / (ab − c²)
        let (a, b, c): (f64, f64, f64) = (4e-6, 9e-2, 3e-4);
        let r = result(
            vec![
                param("eps_1_1", "m", 0.003, a.sqrt(), false),
                param("k_a_x", "1", 1.0, 0.0, true),
                param("tau", "s", 0.5, b.sqrt(), false),
            ],
            vec![vec![a, c], vec![c, b]],
        );
        let t = truth(&[("eps_1_1", 0.001), ("k_a_x", 1.01), ("tau", 0.2)]);
        let table = ParameterTable::new(&r, Some(&t));
        let (e1, e2) = (0.002, 0.3);
        let want = (b * e1 * e1 - 2.0 * c * e1 * e2 + a * e2 * e2) / (a * b - c * c);
        let s = table.truth.as_ref().unwrap();
        assert!(
            (s.nees.unwrap() - want).abs() < 1e-9 * want,
            "{s:?} vs {want}"
        );
        assert_eq!(s.dof, 2);
        // error/σ: 0.002 / 0.002 = 1 and 0.3 / 0.3 = 1; display in mm
        let row = &table.rows[0];
        assert!((row.error.unwrap() - 2.0).abs() < 1e-12);
        assert!((row.normalized_error.unwrap() - 1.0).abs() < 1e-12);
        assert!((s.max_abs_normalized_error - 1.0).abs() < 1e-12);
        // frozen: error shown, no error/σ
        assert!((table.rows[1].error.unwrap() + 0.01).abs() < 1e-12);
        assert_eq!(table.rows[1].normalized_error, None);
        let text = table.to_string();
        assert!(text.contains("frozen") && text.contains("NEES"), "{text}");
    }

    #[test]
    fn angle_errors_wrap_and_missing_truth_is_reported() {
        let r = result(
            vec![
                param("r_a_z", "rad", PI - 0.01, 0.02, false),
                param("g_x", "m/s^2", 0.1, 0.05, false),
            ],
            vec![vec![4e-4, 0.0], vec![0.0, 2.5e-3]],
        );
        let t = truth(&[("r_a_z", -PI + 0.01)]);
        let table = ParameterTable::new(&r, Some(&t));
        let row = &table.rows[0];
        assert!(
            (row.normalized_error.unwrap() + 1.0).abs() < 1e-9,
            "{row:?}"
        );
        assert!((row.error.unwrap() + 0.02 * 180.0 / PI).abs() < 1e-9);
        let s = table.truth.unwrap();
        assert_eq!(s.missing, ["g_x"]);
        assert!((s.nees.unwrap() - 1.0).abs() < 1e-9);
    }

    #[test]
    fn chi2_range_is_close_to_tabulated_quantiles() {
        // χ²: k = 10 → 3.247, 20.483; k = 48 → 30.755, 69.023
        let (lo, hi) = chi2_central_range(10, 1.959_963_984_540_054);
        assert!(
            (lo - 3.247).abs() < 0.05 && (hi - 20.483).abs() < 0.05,
            "{lo} {hi}"
        );
        let (lo, hi) = chi2_central_range(48, 1.959_963_984_540_054);
        assert!(
            (lo - 30.755).abs() < 0.05 && (hi - 69.023).abs() < 0.05,
            "{lo} {hi}"
        );
    }

    #[test]
    fn table_without_truth_has_no_error_columns() {
        let r = result(
            vec![param("b_w_x", "rad/s", 0.01, 1e-4, false)],
            vec![vec![1e-8]],
        );
        let text = ParameterTable::new(&r, None).to_string();
        assert!(!text.contains("error"), "{text}");
        assert!(text.contains("deg/s"));
        // 0.01 rad/s = 0.57296 deg/s, σ 0.0057296 → shown with 5 decimals
        assert!(
            text.contains("0.57296") && text.contains("0.00573"),
            "{text}"
        );
    }

    const FIXTURES: &str = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../cli/tests/fixtures/multi_imu"
    );

    fn fixture(k: usize) -> (CalibrationResult, Truth) {
        let dir = std::path::Path::new(FIXTURES);
        (
            CalibrationResult::read(&dir.join(format!("result{k}.json"))).unwrap(),
            Truth::read(&dir.join(format!("truth{k}.toml"))).unwrap(),
        )
    }

    fn golden(name: &str) -> String {
        std::fs::read_to_string(
            std::path::Path::new(FIXTURES)
                .join("one_imu_golden")
                .join(name),
        )
        .unwrap()
    }

    /// The one-IMU table is the one of d3fc17f (before several IMUs),
    /// byte for byte, with and without a truth.
    #[test]
    fn one_imu_table_is_unchanged() {
        let (r, t) = fixture(1);
        let table = ParameterTable::new(&r, None);
        assert!(table.sections.is_empty());
        assert_eq!(table.to_string(), golden("table.txt"));
        assert_eq!(
            ParameterTable::new(&r, Some(&t)).to_string(),
            golden("table_truth.txt")
        );
    }

    /// Two and three IMUs: the shared parameters first, then each IMU's 28
    /// under its heading; each IMU's rows are those of its one-IMU view
    /// (`CalibrationResult::imu`), and the NEES spans every estimated
    /// parameter.
    #[test]
    fn multi_imu_tables_are_grouped_by_imu() {
        for k in [2, 3] {
            let (r, t) = fixture(k);
            let table = ParameterTable::new(&r, Some(&t));
            let titles: Vec<&str> = table.sections.iter().map(|s| s.title.as_str()).collect();
            let mut want = vec!["shared: robot errors and gravity".to_string()];
            want.extend((0..k).map(|j| {
                if j == 0 {
                    "IMU 0 (imu.csv)".to_string()
                } else {
                    format!("IMU {j} (imu{j}.csv)")
                }
            }));
            assert_eq!(titles, want);
            assert_eq!(table.sections[0].rows.len(), 20);
            for j in 0..k {
                let section = &table.sections[1 + j];
                assert_eq!(section.rows.len(), 28);
                let view = ParameterTable::new(&r.imu(j).unwrap(), Some(&t.of_imu(j)));
                for &i in &section.rows {
                    let row = &table.rows[i];
                    let base = row
                        .name
                        .strip_prefix(&format!("imu{j}/"))
                        .unwrap_or(&row.name);
                    let v = view.rows.iter().find(|v| v.name == base).unwrap();
                    assert_eq!(
                        TableRow {
                            name: base.to_string(),
                            ..row.clone()
                        },
                        *v
                    );
                }
            }
            let s = table.truth.as_ref().unwrap();
            assert_eq!(s.dof, r.covariance.names.len());
            assert!(s.missing.is_empty());
            let text = table.to_string();
            let lines: Vec<&str> = text.lines().collect();
            // every parameter once, each heading before its first row
            assert_eq!(lines.len(), 3 + (k + 1) + r.parameters.len() + 2);
            let at = |needle: &str| lines.iter().position(|l| l.starts_with(needle)).unwrap();
            assert!(at("-- shared") < at("eps_1_1 ") && at("eps_5_6 ") < at("-- IMU 0"));
            assert!(at("-- IMU 0") < at("eps_6_1 ") && at("b_w_z ") < at("-- IMU 1"));
            assert!(at("-- IMU 1") < at("imu1/eps_6_1 "));
            assert!(lines[at("max |error/σ| by section")].contains(&format!(
                "IMU {} (imu{}.csv)",
                k - 1,
                k - 1
            )));
        }
    }

    /// A pose session's result of two IMUs (docs/model.md §7.9): no
    /// robot, so its shared section is gravity's alone.
    #[test]
    fn a_pose_results_shared_section_is_gravity() {
        let names = robimu_session::pose_parameter_names(2);
        let params = names
            .iter()
            .map(|n| param(n, "1", 0.5, 0.1, false))
            .collect();
        let cov = (0..58)
            .map(|a| (0..58).map(|b| if a == b { 0.01 } else { 0.0 }).collect())
            .collect();
        let mut r = result(params, cov);
        r.source = Some(robimu_session::SOURCE_POSES.into());
        let table = ParameterTable::new(&r, None);
        let titles: Vec<&str> = table.sections.iter().map(|s| s.title.as_str()).collect();
        assert_eq!(
            titles,
            ["shared: gravity", "IMU 0 (imu.csv)", "IMU 1 (imu1.csv)"]
        );
        let shared: Vec<&str> = table.sections[0]
            .rows
            .iter()
            .map(|&i| table.rows[i].name.as_str())
            .collect();
        assert_eq!(shared, ["g_x", "g_y"]);
        let text = table.to_string();
        assert!(text.contains("-- shared: gravity"), "{text}");
        assert!(!text.contains("robot"), "{text}");
        // a joint result of two IMUs keeps its robot errors' title
        let (joint, _) = fixture(2);
        let title = &ParameterTable::new(&joint, None).sections[0].title;
        assert_eq!(title, "shared: robot errors and gravity");
    }
}
