//! The plan directory `robimu plan` writes (plan.csv, spline.toml,
//! identifiability.csv, sigma.csv) and the summary it prints.

use std::fmt;
use std::path::Path;

use robimu_model::ParamLayout;
use robimu_workflows::plan::{sample, Plan, SplineFile};

use crate::csvfile::write_csv;
use crate::html::ReportError;

/// plan.csv (`t,q1,…,qn`, s and rad, at `rate` Hz), spline.toml and
/// identifiability.csv (λ_max against time) in `dir`.
pub fn write_plan_files(dir: &Path, plan: &Plan, rate: f64) -> Result<(), ReportError> {
    let n = plan.spline.dim();
    let (t, q) = sample(&plan.spline, rate);
    let header: Vec<String> = (1..=n).map(|j| format!("q{j}")).collect();
    let rows = t.iter().zip(q.chunks_exact(n)).map(|(ti, row)| {
        let cols: Vec<String> = row.iter().map(|v| format!("{v:.9}")).collect();
        format!("{ti:.6},{}", cols.join(","))
    });
    write_csv(
        &dir.join("plan.csv"),
        &format!("t,{}", header.join(",")),
        rows,
    )?;
    let path = dir.join("spline.toml");
    toml::to_string(&SplineFile::of(&plan.spline))
        .map_err(std::io::Error::other)
        .and_then(|text| std::fs::write(&path, text))
        .map_err(|source| ReportError::Io { path, source })?;
    let rows = (0..plan.times.len()).map(|k| {
        format!(
            "{},{:e},{:e}",
            plan.times[k], plan.lambda_max[k], plan.lambda_max_without_lengths[k]
        )
    });
    write_csv(
        &dir.join("identifiability.csv"),
        "t,lambda_max,lambda_max_without_robot_lengths",
        rows,
    )
}

/// sigma.csv in `dir`: every parameter's prior and posterior σ.
pub fn write_sigma_csv(
    dir: &Path,
    layout: &ParamLayout,
    posterior: &[f64],
) -> Result<(), ReportError> {
    let rows = (layout.specs().iter().zip(posterior))
        .map(|(s, post)| format!("{},{},{:e},{:e}", s.name, s.unit, s.sigma, post));
    write_csv(
        &dir.join("sigma.csv"),
        "name,unit,prior_sigma,posterior_sigma",
        rows,
    )
}

/// What was planned: length, time taken, blocks, λ_max(Σ_x), and the
/// prior and posterior σ of every parameter.
pub struct PlanSummary<'a> {
    /// The planned length, s.
    pub duration: f64,
    /// How long planning took, s.
    pub seconds: f64,
    /// The plan.
    pub plan: &'a Plan,
    /// Where it was written.
    pub dir: &'a Path,
    /// The parameters.
    pub layout: &'a ParamLayout,
    /// Their posterior σ.
    pub posterior: &'a [f64],
    /// The IMU noise model the plan assumed, and the `--noise-model` spec it
    /// came from.
    pub noise: (&'a robimu_model::noise::NoiseModel, &'a str),
}

impl fmt::Display for PlanSummary<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let p = self.plan;
        writeln!(
            f,
            "planned {} s in {:.1} s ({} blocks, {} objective evaluations); wrote {}",
            self.duration,
            self.seconds,
            p.times.len() - 1,
            p.evaluations,
            self.dir.display()
        )?;
        let (model, spec) = self.noise;
        if model.is_white() {
            let s: Vec<String> = model.sigma_z().iter().map(|v| format!("{v:.3e}")).collect();
            writeln!(
                f,
                "noise model assumed: white (--noise-model {spec}), sigma_z [{}]",
                s.join(", ")
            )?;
        } else {
            writeln!(f, "noise model assumed (--noise-model {spec}):")?;
            write!(f, "{}", crate::noise::NoiseChannels(model))?;
        }
        let last = |v: &[f64]| v.last().copied().unwrap_or(f64::NAN);
        writeln!(
            f,
            "lambda_max(Sigma_x), SI: {:.4e} (robot lengths known: {:.4e})",
            last(&p.lambda_max),
            last(&p.lambda_max_without_lengths)
        )?;
        let specs = self.layout.specs();
        let w = specs.iter().map(|s| s.name.len()).fold(12, usize::max);
        if self.layout.n_imus() > 1 {
            writeln!(
                f,
                "{} IMUs fitted jointly (docs/model.md §9): {} parameters",
                self.layout.n_imus(),
                specs.len()
            )?;
        }
        writeln!(
            f,
            "{:<w$} {:>6} {:>12} {:>12}",
            "parameter", "unit", "prior sigma", "posterior"
        )?;
        for (s, post) in specs.iter().zip(self.posterior) {
            writeln!(
                f,
                "{:<w$} {:>6} {:>12.4e} {:>12.4e}",
                s.name, s.unit, s.sigma, post
            )?;
        }
        Ok(())
    }
}
