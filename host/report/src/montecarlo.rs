//! What a Monte Carlo study ([`robimu_workflows::montecarlo`], paper §8.3)
//! hands over: runs.csv, summary.csv, the per-parameter table of error/σ
//! with the NEES verdict, and the histograms of the errors with the
//! predicted posterior density (paper Fig. 7).

use std::fmt;
use std::io::Write;
use std::path::{Path, PathBuf};

use robimu_model::units::DisplayUnit;
use robimu_model::ParamLayout;
use robimu_workflows::montecarlo::MonteCarloResult;

use crate::plot::{histogram_grid, HistogramPanel, PlotError};

/// runs.csv: per run and parameter (x order) truth, estimate, σ and
/// error/σ, SI units.
pub(crate) fn write_runs_csv(
    path: &Path,
    layout: &ParamLayout,
    result: &MonteCarloResult,
) -> std::io::Result<()> {
    let mut w = std::io::BufWriter::new(std::fs::File::create(path)?);
    writeln!(
        w,
        "run,seed,parameter,unit,truth,estimate,sigma,error_over_sigma"
    )?;
    for (k, run) in result.runs.iter().enumerate() {
        for (i, spec) in layout.specs().iter().enumerate() {
            let e = run.estimate[i] - run.truth[i];
            writeln!(
                w,
                "{k},{},{},{},{:?},{:?},{:?},{:?}",
                run.seed,
                spec.name,
                spec.unit,
                run.truth[i],
                run.estimate[i],
                run.sigma[i],
                e / run.sigma[i]
            )?;
        }
    }
    w.flush()
}

/// summary.csv: per estimated parameter the mean and standard deviation of error/σ.
pub(crate) fn write_summary_csv(path: &Path, result: &MonteCarloResult) -> std::io::Result<()> {
    let mut s = String::from("parameter,mean_error_over_sigma,std_error_over_sigma\n");
    for st in &result.stats {
        s.push_str(&format!("{},{:?},{:?}\n", st.name, st.mean, st.std));
    }
    std::fs::write(path, s)
}

/// The study's verdict: per parameter mean and std of error/σ (ideal 0
/// and 1), the extremes over the parameters, and the average NEES against
/// its 95 % interval.
pub struct MonteCarloSummary<'a> {
    /// The study.
    pub result: &'a MonteCarloResult,
    /// Session length of each run, s.
    pub duration: f64,
    /// Wall-clock time of the study, s.
    pub elapsed: f64,
}

impl fmt::Display for MonteCarloSummary<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let result = self.result;
        writeln!(
            f,
            "{:>12} {:>10} {:>10}",
            "parameter", "mean(e/σ)", "std(e/σ)"
        )?;
        for st in &result.stats {
            writeln!(f, "{:>12} {:>+10.3} {:>10.3}", st.name, st.mean, st.std)?;
        }
        let worst_mean = result
            .stats
            .iter()
            .map(|s| s.mean.abs())
            .fold(0.0, f64::max);
        let (std_lo, std_hi) = result
            .stats
            .iter()
            .fold((f64::INFINITY, 0.0f64), |(a, b), s| {
                (a.min(s.std), b.max(s.std))
            });
        let (lo, hi) = result.nees_interval;
        let inside = result.nees_mean > lo && result.nees_mean < hi;
        writeln!(
            f,
            "\n{} runs of {:.0} s in {:.0} s: max |mean(e/σ)| = {:.3}, std(e/σ) in [{:.3}, {:.3}]",
            result.runs.len(),
            self.duration,
            self.elapsed,
            worst_mean,
            std_lo,
            std_hi
        )?;
        writeln!(
            f,
            "average NEES {:.2} for {} parameters; 95 % interval [{:.2}, {:.2}]: {}",
            result.nees_mean,
            result.dof,
            lo,
            hi,
            if inside { "consistent" } else { "OUTSIDE" }
        )
    }
}

/// Histograms of the error per parameter in display units, with the
/// predicted density N(0, σ̄²) (σ̄² the mean posterior variance), written
/// to `stem.png` and `stem.svg`.
pub fn error_histograms(
    stem: &Path,
    layout: &ParamLayout,
    result: &MonteCarloResult,
) -> Result<Vec<PathBuf>, PlotError> {
    let panels: Vec<HistogramPanel> = layout
        .specs()
        .iter()
        .enumerate()
        .map(|(i, spec)| {
            let unit = DisplayUnit::for_si(spec.unit);
            let errors: Vec<f64> = result
                .runs
                .iter()
                .map(|r| unit.show(r.estimate[i] - r.truth[i]))
                .collect();
            let mean_var = result
                .runs
                .iter()
                .map(|r| r.sigma[i] * r.sigma[i])
                .sum::<f64>()
                / result.runs.len() as f64;
            HistogramPanel {
                title: format!("{} [{}]", spec.name, unit.symbol()),
                values: errors,
                normal: Some((0.0, unit.show(mean_var.sqrt()))),
            }
        })
        .collect();
    histogram_grid(
        stem,
        &format!(
            "Estimation error over {} runs (bars) and predicted posterior density (line)",
            result.runs.len()
        ),
        &panels,
        8,
    )
}

/// runs.csv and summary.csv of the study `result` in the directory `out`;
/// their paths.
pub fn write_study_csv(
    out: &Path,
    layout: &ParamLayout,
    result: &MonteCarloResult,
) -> Result<(PathBuf, PathBuf), crate::html::ReportError> {
    let io = |path: &Path| {
        let path = path.to_path_buf();
        move |source| crate::html::ReportError::Io { path, source }
    };
    let runs_path = out.join("runs.csv");
    write_runs_csv(&runs_path, layout, result).map_err(io(&runs_path))?;
    let summary_path = out.join("summary.csv");
    write_summary_csv(&summary_path, result).map_err(io(&summary_path))?;
    Ok((runs_path, summary_path))
}

/// The lines after [`MonteCarloSummary`]: how many runs of the `auto` fit
/// noise (`auto_noise`) were refitted by GLS or kept white with a warning,
/// and with several IMUs the mean σ gain of each shared parameter
/// ([`MonteCarloResult::shared_sigma_gain`]).
pub struct MonteCarloNotes<'a> {
    /// The study.
    pub result: &'a MonteCarloResult,
    /// Its parameters.
    pub layout: &'a ParamLayout,
    /// Whether the fits' noise model was `auto`.
    pub auto_noise: bool,
    /// IMUs per session.
    pub imus: usize,
}

impl fmt::Display for MonteCarloNotes<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let result = self.result;
        if self.auto_noise {
            let refitted = result.runs.iter().filter(|r| r.refits > 0).count();
            let warned = result.runs.iter().filter(|r| r.warning.is_some()).count();
            writeln!(
                f,
                "fit noise auto: identified and refitted by GLS in {refitted} of {} runs; white kept with a warning in {warned}",
                result.runs.len()
            )?;
        }
        let gain = result.shared_sigma_gain(self.layout);
        if !gain.is_empty() {
            writeln!(
                f,
                "shared parameters, mean sigma(IMU 0 alone) / sigma({} IMUs jointly) (sqrt(K) = {:.3}):",
                self.imus,
                (self.imus as f64).sqrt()
            )?;
            for (name, g) in &gain {
                writeln!(f, "  {name:<10} {g:.3}")?;
            }
        }
        Ok(())
    }
}
