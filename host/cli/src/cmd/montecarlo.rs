//! `robimu montecarlo`: the estimator's consistency over many simulated runs
//! (paper §8.3, Fig. 7).

use std::io::Write;
use std::path::PathBuf;

use anyhow::Context;
use robimu_model::units::DisplayUnit;
use robimu_model::ParamLayout;
use robimu_report::plot::{histogram_grid, HistogramPanel};
use robimu_workflows::calibrate::CalibrateOptions;
use robimu_workflows::montecarlo::{monte_carlo, MonteCarloOptions};
use robimu_workflows::simulate::SimulateOptions;

use super::input::{resolve_robot_with, UrdfLinks};

/// Check that the reported uncertainties are honest: per run, draw a truth
/// from the priors, simulate a session, calibrate it, and compare the error
/// with the posterior σ.
///
/// Writes runs.csv (per run and parameter: truth, estimate, σ, error/σ),
/// summary.csv, and histograms of the errors with the predicted posterior
/// density overlaid (histograms.png / .svg); prints per parameter the mean
/// and standard deviation of error/σ (ideal: 0 and 1) and the average NEES
/// against its 95 % χ² interval.
#[derive(Debug, Clone, clap::Args)]
pub struct MonteCarloCmd {
    /// Robot: a built-in name (aubo_i5) or the path of a TOML robot description or a URDF.
    #[arg(long, default_value = "aubo_i5")]
    pub robot: String,
    #[command(flatten)]
    pub links: UrdfLinks,
    /// Number of runs.
    #[arg(long, default_value_t = 100)]
    pub runs: usize,
    /// Length of each simulated session, s.
    #[arg(long, default_value_t = 300.0)]
    pub duration: f64,
    /// Seed of run 0; run k uses seed + k.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Output directory.
    #[arg(long)]
    pub out: PathBuf,
}

impl MonteCarloCmd {
    /// Run the study.
    pub fn run(self) -> anyhow::Result<()> {
        anyhow::ensure!(self.runs >= 2, "--runs must be at least 2");
        anyhow::ensure!(
            self.duration.is_finite() && self.duration >= 10.0,
            "--duration must be at least 10 s"
        );
        let (robot, _) = resolve_robot_with(&self.robot, None, &self.links)?;
        let layout = ParamLayout::new(&robot);
        std::fs::create_dir_all(&self.out)
            .with_context(|| format!("cannot create {}", self.out.display()))?;
        let opts = MonteCarloOptions {
            runs: self.runs,
            duration: self.duration,
            seed: self.seed,
            simulate: SimulateOptions::paper(&robot),
            calibrate: CalibrateOptions::new(&robot),
        };
        let bar = indicatif::ProgressBar::new(self.runs as u64);
        bar.set_style(
            indicatif::ProgressStyle::with_template(
                "{bar:40} {pos}/{len} runs  {elapsed} elapsed, {eta} left  {msg}",
            )
            .expect("valid template"),
        );
        let started = std::time::Instant::now();
        let result = monte_carlo(&robot, &opts, |_, run| {
            bar.inc(1);
            bar.set_message(format!("last NEES {:.1}", run.nees));
        })?;
        bar.finish_and_clear();
        let elapsed = started.elapsed().as_secs_f64();

        // per-run CSV
        let runs_path = self.out.join("runs.csv");
        let mut w = std::io::BufWriter::new(
            std::fs::File::create(&runs_path)
                .with_context(|| format!("cannot write {}", runs_path.display()))?,
        );
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
        w.flush()?;

        // summary
        let summary_path = self.out.join("summary.csv");
        let mut s = String::from("parameter,mean_error_over_sigma,std_error_over_sigma\n");
        println!("{:>12} {:>10} {:>10}", "parameter", "mean(e/σ)", "std(e/σ)");
        for st in &result.stats {
            println!("{:>12} {:>+10.3} {:>10.3}", st.name, st.mean, st.std);
            s.push_str(&format!("{},{:?},{:?}\n", st.name, st.mean, st.std));
        }
        std::fs::write(&summary_path, s)
            .with_context(|| format!("cannot write {}", summary_path.display()))?;
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
        println!(
            "\n{} runs of {:.0} s in {:.0} s: max |mean(e/σ)| = {:.3}, std(e/σ) in [{:.3}, {:.3}]",
            self.runs, self.duration, elapsed, worst_mean, std_lo, std_hi
        );
        println!(
            "average NEES {:.2} for {} parameters; 95 % interval [{:.2}, {:.2}]: {}",
            result.nees_mean,
            result.dof,
            lo,
            hi,
            if inside { "consistent" } else { "OUTSIDE" }
        );

        // histograms of the error in display units, predicted density N(0, σ̄²)
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
        let files = histogram_grid(
            &self.out.join("histograms"),
            &format!(
                "Estimation error over {} runs (bars) and predicted posterior density (line)",
                self.runs
            ),
            &panels,
            8,
        )?;
        println!(
            "wrote {}, {} and {}",
            runs_path.display(),
            summary_path.display(),
            files
                .iter()
                .map(|p| p.display().to_string())
                .collect::<Vec<_>>()
                .join(", ")
        );
        Ok(())
    }
}
