//! The text of `robimu demo` between its stages: what was planned, the
//! simulated hardware, the equivalent `robimu record` command, the truth
//! check of diagnose's final model (docs/model.md §4.8), the files.

use std::fmt;
use std::path::Path;

/// The plan stage: the excitation planned and written.
pub struct DemoPlanned<'a> {
    /// Length of the excitation, s.
    pub duration: f64,
    /// How long planning took, s.
    pub seconds: f64,
    /// The final min λ_max(Σ_x), SI.
    pub lambda_max: f64,
    /// plan.csv.
    pub path: &'a Path,
    /// Its waypoints (at 250 Hz).
    pub waypoints: usize,
}

impl fmt::Display for DemoPlanned<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "{} s excitation planned in {:.1} s (sequential, min λ_max(Σ_x) = {:.3e} in SI; exact joint limits; at rest at both ends): {} ({} waypoints at 250 Hz)",
            self.duration,
            self.seconds,
            self.lambda_max,
            self.path.display(),
            self.waypoints
        )
    }
}

/// The simulated hardware stage.
pub struct DemoHardware<'a> {
    /// The IMU board's pseudo-terminal (`None`: recorded in virtual time).
    pub imu_port: Option<&'a str>,
    /// The board's clock drift, ppm.
    pub drift_ppm: f64,
    /// The AUBO controller's address (`None`: virtual time).
    pub robot_addr: Option<String>,
    /// The seed of the hidden truth.
    pub seed: u64,
    /// What the twin simulates (one line).
    pub twin: &'a str,
}

impl fmt::Display for DemoHardware<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let port = self
            .imu_port
            .map_or("a virtual link".to_string(), |p| p.to_string());
        writeln!(
            f,
            "IMU board on {port} (the real firmware core over a register-level BNO055; clock {:+.1} ppm)",
            self.drift_ppm
        )?;
        let addr = self.robot_addr.clone().map_or(
            "a virtual clock (robimu_hil::twin, no real time)".into(),
            |a| format!("{a} (JSON-RPC)"),
        );
        writeln!(
            f,
            "AUBO i5 controller on {addr}, 20 ms tracking lag, encoder noise as the paper's"
        )?;
        writeln!(f, "twin: {}", self.twin)?;
        writeln!(
            f,
            "hidden truth: robot errors and IMU parameters drawn from the priors (seed {})",
            self.seed
        )
    }
}

/// The `robimu record` command the record stage runs.
pub struct DemoRecordCommand<'a> {
    /// --imu.
    pub imu_port: &'a str,
    /// --robot.
    pub robot_spec: &'a str,
    /// --plan.
    pub plan_dir: &'a Path,
    /// --out.
    pub session: &'a Path,
}

impl fmt::Display for DemoRecordCommand<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "robimu record --imu {} --robot {} --plan {} --out {}",
            self.imu_port,
            self.robot_spec,
            self.plan_dir.display(),
            self.session.display()
        )
    }
}

/// Where the demo left its files, and what to try next.
pub struct DemoFiles<'a> {
    /// The plan directory.
    pub plan_dir: &'a Path,
    /// The session directory.
    pub session: &'a Path,
    /// The report directory.
    pub report: &'a Path,
    /// How long the demo took, s.
    pub seconds: f64,
    /// The result calibrate wrote.
    pub result: &'a robimu_session::CalibrationResult,
    /// What to do next.
    pub next: &'a str,
}

impl fmt::Display for DemoFiles<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "\nfiles: {} (plan.csv), {} (session.toml, joints.csv, imu.csv, pings.csv, truth.toml = the twin's truth for the baseline model, docs/model.md §4.8, result.json, diagnosis/)",
            self.plan_dir.display(),
            self.session.display()
        )?;
        writeln!(
            f,
            "report: {} (open it in a browser; the figures are beside it as PNG and SVG; truth_check.json: calibrate's result against the truth)",
            self.report.join("report.html").display()
        )?;
        if let Some(v) = &self.result.verdict {
            writeln!(f, "calibrate's result: {}", crate::verdict::trust_line(v))?;
        }
        if let Some(p) = &self.result.pose_accuracy {
            writeln!(
                f,
                "flange pose error over the workspace: {:.2} mm, {:.3}° before calibration → {:.2} mm, {:.3}° after (mean, predicted{})",
                p.before.position_mean_mm,
                p.before.rotation_mean_deg,
                p.after.position_mean_mm,
                p.after.rotation_mean_deg,
                p.actual_after.map_or(String::new(), |a| format!(
                    "; actual against the truth {:.2} mm, {:.3}°",
                    a.stats.position_mean_mm, a.stats.rotation_mean_deg
                ))
            )?;
        }
        writeln!(f, "demo took {:.1} s; next: {}", self.seconds, self.next)
    }
}

pub use robimu_session::TruthRow;

/// The demo's last stage: diagnose's final model (or, with several IMUs,
/// the joint calibration) against the twin's truth.
#[derive(Clone, Debug)]
pub struct DemoTruthCheck {
    /// What is compared (`diagnose's final model`, `the joint calibration
    /// of 2 IMUs`).
    pub model: String,
    /// Which twin (`realistic` or `ideal`).
    pub twin: String,
    /// The effects in the final model.
    pub effects: Vec<String>,
    /// Every estimated parameter with a truth.
    pub rows: Vec<TruthRow>,
    /// Effects of the final model without a truth, and why.
    pub not_comparable: Vec<(String, String)>,
    /// The bound, σ.
    pub limit: f64,
}

impl DemoTruthCheck {
    /// Rows beyond the bound.
    pub fn failures(&self) -> Vec<&TruthRow> {
        self.rows
            .iter()
            .filter(|r| r.z().abs() > self.limit || r.z().is_nan())
            .collect()
    }

    /// The row farthest from its truth.
    pub fn worst(&self) -> Option<&TruthRow> {
        self.rows
            .iter()
            .max_by(|a, b| a.z().abs().total_cmp(&b.z().abs()))
    }

    /// `truth_check.json`: `{"model", "twin", "effects", "limit_sigma", "all_within",
    /// "worst", "parameters": [{"name", "estimate", "sigma", "truth", "z", "mode_share"}],
    /// "not_comparable": [{"effect", "why"}]}`.
    pub fn to_json(&self) -> serde_json::Value {
        serde_json::json!({
            "model": self.model,
            "twin": self.twin,
            "effects": self.effects,
            "limit_sigma": self.limit,
            "all_within": self.failures().is_empty(),
            "worst": self.worst().map(|r| serde_json::json!({"name": r.name, "z": r.z()})),
            "parameters": self.rows.iter().map(|r| serde_json::json!({
                "name": r.name, "estimate": r.estimate, "sigma": r.sigma,
                "truth": r.truth, "z": r.z(), "mode_share": r.mode_share,
            })).collect::<Vec<_>>(),
            "not_comparable": self.not_comparable.iter().map(|(e, why)| serde_json::json!({
                "effect": e, "why": why,
            })).collect::<Vec<_>>(),
        })
    }
}

impl fmt::Display for DemoTruthCheck {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let effects = if self.effects.is_empty() {
            "none".to_string()
        } else {
            self.effects.join(", ")
        };
        writeln!(
            f,
            "{} (effects: {effects}) against the {} twin's truth (docs/model.md §4.8):",
            self.model, self.twin
        )?;
        let mut rows: Vec<&TruthRow> = self.rows.iter().collect();
        rows.sort_by(|a, b| b.z().abs().total_cmp(&a.z().abs()));
        let shown = rows.len().min(6).max(self.failures().len());
        writeln!(
            f,
            "  {:<28} {:>14} {:>12} {:>14} {:>8}",
            "parameter", "estimate", "σ", "truth", "z"
        )?;
        for r in rows.iter().take(shown) {
            writeln!(
                f,
                "  {:<28} {:>14.6e} {:>12.3e} {:>14.6e} {:>+8.2}",
                r.name,
                r.estimate,
                r.sigma,
                r.truth,
                r.z()
            )?;
        }
        if rows.len() > shown {
            writeln!(f, "  … {} more, all closer", rows.len() - shown)?;
        }
        for (e, why) in &self.not_comparable {
            writeln!(f, "  {e}: not compared ({why})")?;
        }
        let mut shares: Vec<&TruthRow> = self.rows.iter().filter(|r| r.mode_share != 0.0).collect();
        shares.sort_by(|a, b| {
            (b.mode_share / b.sigma)
                .abs()
                .total_cmp(&(a.mode_share / a.sigma).abs())
        });
        if !shares.is_empty() {
            writeln!(
                f,
                "  the truth includes the model's share of the twin's structural mode (docs/model.md §4.8), largest: {}",
                shares
                    .iter()
                    .take(3)
                    .map(|r| format!("{} {:+.1}σ", r.name, r.mode_share / r.sigma))
                    .collect::<Vec<_>>()
                    .join(", ")
            )?;
        }
        let failures = self.failures();
        match (failures.is_empty(), self.worst()) {
            (true, Some(w)) => writeln!(
                f,
                "truth check: every one of {} parameters within {}σ of the truth (worst {:.2}σ: {})",
                self.rows.len(),
                self.limit,
                w.z().abs(),
                w.name
            ),
            (true, None) => writeln!(f, "truth check: no parameter to compare"),
            (false, _) => writeln!(
                f,
                "truth check FAILED: {} of {} parameters beyond {}σ of the truth: {}",
                failures.len(),
                self.rows.len(),
                self.limit,
                failures
                    .iter()
                    .map(|r| format!("{} ({:+.1}σ)", r.name, r.z()))
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
        }
    }
}
