//! `robimu montecarlo`: the estimator's consistency over many simulated runs
//! (paper §8.3, Fig. 7).

use std::path::PathBuf;

use anyhow::Context;
use robimu_model::ParamLayout;
use robimu_report::montecarlo::{
    error_histograms, write_study_csv, MonteCarloNotes, MonteCarloSummary,
};
use robimu_workflows::calibrate::noise_choice::NoiseChoice;
use robimu_workflows::montecarlo::{monte_carlo, MonteCarloOptions};

use crate::args::UrdfLinks;
use crate::input::resolve_robot_with;

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
    /// Robot: a built-in name (`robimu robots` lists them) or the path of a
    /// TOML robot description or a URDF.
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
    /// IMU noise of the simulated sessions, as `robimu simulate
    /// --noise-model`: `white` (default), `ar1:accel=TAU_MS[,gyro=TAU_MS][,motion=C]`
    /// or a TOML file with a [noise] table.
    #[arg(long, value_name = "SPEC")]
    pub noise_model: Option<String>,
    /// The noise model of the fits: `auto` (`robimu calibrate`'s default:
    /// white unless the residuals fail the whiteness test, then identified
    /// from them and refitted by GLS), `white` (the paper's model), or
    /// `true` (the simulated sessions' model, given).
    #[arg(long, value_name = "auto|white|true", default_value = "auto")]
    pub fit_noise: String,
    /// IMUs per session K (docs/model.md §9): one motion, each IMU its own
    /// 28 truths, fitted jointly. With K > 1 each run also fits IMU 0 alone
    /// and the mean σ(IMU 0 alone)/σ(joint) of every shared parameter is
    /// printed (√K ideal).
    #[arg(long, default_value_t = 1, value_name = "K")]
    pub imus: usize,
}

impl MonteCarloCmd {
    /// Run the study.
    pub fn run(self) -> anyhow::Result<()> {
        anyhow::ensure!(self.runs >= 2, "--runs must be at least 2");
        anyhow::ensure!(
            self.duration.is_finite() && self.duration >= 10.0,
            "--duration must be at least 10 s"
        );
        anyhow::ensure!(
            (1..=64).contains(&self.imus),
            "--imus must be between 1 and 64"
        );
        let (robot, _) = resolve_robot_with(&self.robot, None, &self.links)?;
        let layout = ParamLayout::with_imus(&robot, self.imus);
        std::fs::create_dir_all(&self.out)
            .with_context(|| format!("cannot create {}", self.out.display()))?;
        let (runs, duration, seed, imus) = (self.runs, self.duration, self.seed, self.imus);
        let noise_model = self.noise_model.as_deref();
        let opts = MonteCarloOptions::study(
            &robot,
            runs,
            duration,
            seed,
            imus,
            noise_model,
            &self.fit_noise,
        )?;
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
        let (runs_path, summary_path) = write_study_csv(&self.out, &layout, &result)?;
        print!(
            "{}",
            MonteCarloSummary {
                result: &result,
                duration,
                elapsed
            }
        );
        let auto_noise = matches!(opts.noise, NoiseChoice::Auto);
        let (result, layout) = (&result, &layout);
        print!(
            "{}",
            MonteCarloNotes {
                result,
                layout,
                auto_noise,
                imus
            }
        );
        let files = error_histograms(&self.out.join("histograms"), layout, result)?;
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
