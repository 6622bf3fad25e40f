//! The identifiability studies of `robimu identifiability` (paper §8.2,
//! §8.4) as tables, figures and text: sigma_vs_time, speed and baselines
//! (.csv, .png, .svg) and the lines printed about them.

use std::fmt;
use std::path::Path;

use robimu_workflows::identifiability::{
    ApproximationCheck, BaselineStudy, PrecisionGain, SigmaStudy, SpeedStudy,
};

use crate::csvfile::{exp_row, write_csv, CsvFile};
use crate::html::ReportError;
use crate::plot::{loglog_panels, LogLogPanel};

/// The figure panel of a parameter: robot errors, then g, τ and the IMU
/// rotations, then the other IMU intrinsics.
fn panel_of(name: &str) -> usize {
    if name.starts_with("eps") {
        0
    } else if ["g_", "tau", "r_"].iter().any(|p| name.starts_with(p)) {
        1
    } else {
        2
    }
}

/// `dir/sigma_vs_time.csv` and its figure (paper Fig. 6).
pub fn write_sigma_vs_time(dir: &Path, s: &SigmaStudy) -> Result<(), ReportError> {
    write_csv(
        &dir.join("sigma_vs_time.csv"),
        &format!("t,{}", s.names.join(",")),
        (s.times.iter().zip(&s.sigma)).map(|(t, row)| format!("{t},{}", exp_row(row))),
    )?;
    let titles = [
        "robot errors eps (m, rad)",
        "g_xy, tau, r_a, r_w (SI)",
        "IMU intrinsics (SI)",
    ];
    let panels: Vec<LogLogPanel> = (0..3)
        .map(|g| LogLogPanel {
            title: titles[g].into(),
            x_label: "trajectory length [s]".into(),
            y_label: "posterior sigma".into(),
            series: (0..s.names.len())
                .filter(|&k| panel_of(&s.names[k]) == g)
                .map(|k| {
                    let points = s.times.iter().zip(&s.sigma).map(|(t, r)| (*t, r[k]));
                    (s.names[k].clone(), points.collect())
                })
                .collect(),
        })
        .collect();
    loglog_panels(
        &dir.join("sigma_vs_time"),
        "Posterior sigma against trajectory length",
        &panels,
    )?;
    Ok(())
}

/// `dir/speed.csv` and its figure (paper Fig. 8).
pub fn write_speed(dir: &Path, s: &SpeedStudy) -> Result<(), ReportError> {
    write_csv(
        &dir.join("speed.csv"),
        &format!("speed,{}", s.names.join(",")),
        (s.speeds.iter().zip(&s.rows)).map(|(v, row)| format!("{v},{}", exp_row(row))),
    )?;
    let panel = LogLogPanel {
        title: "robot length parameters".into(),
        x_label: "speed-up factor".into(),
        y_label: "posterior sigma [m]".into(),
        series: s
            .names
            .iter()
            .enumerate()
            .map(|(k, n)| {
                let points = s.speeds.iter().zip(&s.rows).map(|(v, r)| (*v, r[k]));
                (n.clone(), points.collect())
            })
            .collect(),
    };
    loglog_panels(
        &dir.join("speed"),
        "Length identifiability against speed",
        &[panel],
    )?;
    Ok(())
}

/// `dir/baselines.csv` and its figure (paper Fig. 5).
pub fn write_baselines(dir: &Path, b: &BaselineStudy) -> Result<(), ReportError> {
    let mut f = CsvFile::create(
        &dir.join("baselines.csv"),
        "t,plan,plan_without_robot_lengths,uniform_median,uniform_median_without_robot_lengths,walk_median,walk_median_without_robot_lengths",
    )?;
    let mut series = vec![
        ("plan".to_string(), Vec::new()),
        ("uniform random (median)".to_string(), Vec::new()),
        ("random walk (median)".to_string(), Vec::new()),
    ];
    for (k, p) in b.plan.iter().enumerate() {
        let m = b.medians(k);
        let (u, un, w, wn) = (
            m.uniform,
            m.uniform_without_lengths,
            m.walk,
            m.walk_without_lengths,
        );
        f.line(&format!(
            "{},{:e},{:e},{u:e},{un:e},{w:e},{wn:e}",
            p.0, p.1, p.2
        ))?;
        series[0].1.push((p.0, p.1));
        series[1].1.push((p.0, u));
        series[2].1.push((p.0, w));
    }
    f.finish()?;
    loglog_panels(
        &dir.join("baselines"),
        "Largest eigenvalue of Sigma_x (SI) against time",
        &[LogLogPanel {
            title: "plan against random trajectories".into(),
            x_label: "time [s]".into(),
            y_label: "lambda_max(Sigma_x)".into(),
            series,
        }],
    )?;
    Ok(())
}

/// The robot length parameters' σ against speed, mm.
pub struct SpeedTable<'a>(pub &'a SpeedStudy);

impl fmt::Display for SpeedTable<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let s = self.0;
        writeln!(
            f,
            "robot length parameters: posterior sigma [mm] against speed"
        )?;
        let names: String = s.names.iter().map(|n| format!("{n:>9}")).collect();
        writeln!(f, "{:>6} {names}", "speed")?;
        for (speed, row) in s.speeds.iter().zip(&s.rows) {
            let cols: String = row.iter().map(|v| format!("{:>9.4}", v * 1e3)).collect();
            writeln!(f, "{speed:>6} {cols}")?;
        }
        Ok(())
    }
}

/// λ_max(Σ_x) at the end of the plan against the random trajectories'
/// medians (nothing for an empty plan).
pub struct BaselineSummary<'a>(pub &'a BaselineStudy);

impl fmt::Display for BaselineSummary<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let b = self.0;
        let Some(end) = b.plan.last() else {
            return Ok(());
        };
        let m = b.medians(b.plan.len() - 1);
        let (u, un, w, wn) = (
            m.uniform,
            m.uniform_without_lengths,
            m.walk,
            m.walk_without_lengths,
        );
        writeln!(f, "lambda_max(Sigma_x) after {:.0} s, SI:", end.0)?;
        writeln!(
            f,
            "  plan {:.4e}; median of {} uniform random {u:.4e} (ratio {:.1}); median of {} random walks {w:.4e} (ratio {:.2})",
            end.1, b.random, u / end.1, b.random, w / end.1
        )?;
        writeln!(
            f,
            "  robot lengths known: plan {:.4e}; uniform {un:.4e} (ratio {:.1}); random walks {wn:.4e} (ratio {:.2})",
            end.2, un / end.2, wn / end.2
        )
    }
}

/// The approximation (26) against the estimator's covariance (24), one line.
pub struct ApproximationLine<'a>(pub &'a ApproximationCheck);

impl fmt::Display for ApproximationLine<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let c = self.0;
        writeln!(
            f,
            "approximation (26) against the estimator's covariance (24): Frobenius norm of the difference {:.3e} (of {:.3e}); largest sigma ratio error {:.2} %",
            c.frobenius,
            c.norm,
            100.0 * c.max_sigma_ratio_error
        )
    }
}

/// The Monte Carlo errors against the predicted ones, two lines.
pub struct PrecisionGainSummary<'a>(pub &'a PrecisionGain);

impl fmt::Display for PrecisionGainSummary<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let (g, p, w) = (self.0, &self.0.plan, &self.0.walk);
        writeln!(
            f,
            "Monte Carlo, {} runs each: mean squared error along the random walk's worst direction: plan {:.3e} (predicted {:.3e}), random walk {:.3e} (predicted {:.3e}); gain {:.2} (predicted {:.2})",
            g.runs, p.along, p.predicted_along, w.along, w.predicted_along, w.along / p.along, w.predicted_along / p.predicted_along
        )?;
        writeln!(
            f,
            "  total squared error (SI): plan {:.3e} (predicted trace {:.3e}), random walk {:.3e} (predicted {:.3e}); gain {:.2} (predicted {:.2})",
            p.total, p.predicted_total, w.total, w.predicted_total, w.total / p.total, w.predicted_total / p.predicted_total
        )
    }
}
