//! `robimu identifiability`: how well a planned trajectory identifies x
//! (paper §8.2, §8.4).

use std::io::Write;
use std::path::PathBuf;

use anyhow::{bail, Context};
use rand::SeedableRng;
use robimu_report::identifiability::{
    write_baselines, write_sigma_vs_time, write_speed, ApproximationLine, BaselineSummary,
    PrecisionGainSummary, SpeedTable,
};
use robimu_workflows::identifiability::{
    baseline_study, check_plan_approximation, precision_gain, sigma_study, speed_study,
};
use robimu_workflows::plan::information::Information;

use robimu_workflows::plan::files::read_plan_spline;

use crate::input::{resolve_robot, Progress};
use robimu_report::noise::NoiseChannels;
use robimu_workflows::pipeline::noise_spec::parse_noise_model;

/// Identifiability of a plan: σ against length and speed, against random trajectories.
///
/// Reads PLAN_DIR (spline.toml, else plan.csv, as `robimu plan` writes) and
/// writes to --out (default PLAN_DIR): sigma_vs_time.csv/.png/.svg (posterior
/// σ of every parameter against trajectory length, paper Fig. 6),
/// speed.csv/.png/.svg (σ of the robot length parameters for time-scaled
/// copies at equal sample count, Fig. 8), baselines.csv/.png/.svg (the
/// largest eigenvalue of Σ_x, SI, against time for the plan and random
/// trajectories of equal length under the same limits, Fig. 5). Prints the
/// ratios of λ_max(Σ_x) and the check of the approximation (26) against the
/// estimator's covariance (24) on the same plan. With `--noise-model` every
/// study is under that IMU noise (the generalised least squares' information,
/// docs/model.md §4.6; the Monte Carlo sessions get that noise and are fitted
/// with it).
#[derive(Debug, Clone, clap::Args)]
pub struct IdentifiabilityCmd {
    /// The plan directory.
    #[arg(long, value_name = "PLAN_DIR")]
    pub plan: PathBuf,
    /// Robot: a built-in name (`robimu robots` lists them) or the path of a
    /// TOML robot description.
    #[arg(long, default_value = "aubo_i5")]
    pub robot: String,
    /// Speed-up factors of the length study.
    #[arg(long, value_delimiter = ',', default_value = "1,2,4,8,16,32")]
    pub speeds: Vec<f64>,
    /// Random trajectories of each kind.
    #[arg(long, default_value_t = 10)]
    pub random: usize,
    /// IMU (and joint) sample rate, Hz.
    #[arg(long, default_value_t = 120.0)]
    pub rate: f64,
    /// Monte Carlo calibrations on the plan and on one random walk (0: none).
    #[arg(long, default_value_t = 0)]
    pub montecarlo: usize,
    /// Skip the check of (26) against the estimator's (24).
    #[arg(long)]
    pub no_check: bool,
    /// Seed of the random trajectories and the Monte Carlo runs.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// The IMU noise assumed: `white` (the robot's σ_z),
    /// `ar1:accel=TAU_MS[,gyro=TAU_MS][,motion=C]`, or a TOML FILE with a
    /// `[noise]` table (`sigma_z`, `ar_z`, `motion_z`); AR coefficients per
    /// sample at --rate.
    #[arg(long, value_name = "SPEC", default_value = "white")]
    pub noise_model: String,
    /// Directory for the tables and figures [default: PLAN_DIR].
    #[arg(long)]
    pub out: Option<PathBuf>,
}

impl IdentifiabilityCmd {
    /// Run the studies, write and print.
    pub fn run(self) -> anyhow::Result<()> {
        if !(self.rate.is_finite() && self.rate > 0.0 && self.rate <= 10_000.0) {
            bail!("--rate must be in (0, 10000] Hz (got {})", self.rate);
        }
        if let Some(s) = self.speeds.iter().find(|s| !(s.is_finite() && **s > 0.0)) {
            bail!("--speeds: {s} is not a positive speed-up factor");
        }
        let (robot, _) = resolve_robot(&self.robot, None)?;
        let spline = read_plan_spline(&robot, &self.plan)?;
        let dir = self.out.clone().unwrap_or_else(|| self.plan.clone());
        if !dir.is_dir() {
            bail!("--out {}: not a directory", dir.display());
        }
        let noise = parse_noise_model(&self.noise_model, robot.sigma_z(), self.rate)?;
        let info = Information::with_noise(&robot, noise.clone(), self.rate)?;
        let mut out = std::io::stdout().lock();
        if noise.is_white() {
            writeln!(
                out,
                "noise model assumed: white (--noise-model {})",
                self.noise_model
            )?;
        } else {
            writeln!(
                out,
                "noise model assumed (--noise-model {}):",
                self.noise_model
            )?;
            write!(out, "{}", NoiseChannels(&noise))?;
        }
        let progress = Progress::start("identifiability");

        progress.set_message("posterior sigma against trajectory length");
        write_sigma_vs_time(&dir, &sigma_study(&info, &spline, 5.0))?;

        progress.set_message("robot length parameters against speed");
        let speed = speed_study(&info, &spline, &self.speeds);
        write_speed(&dir, &speed)?;
        write!(out, "{}", SpeedTable(&speed))?;

        let mut rng = rand::rngs::StdRng::seed_from_u64(self.seed);
        let random = self.random;
        let baselines = baseline_study(&robot, &info, &spline, 5.0, random, &mut rng, |kind, k| {
            progress.set_message(format!("random trajectory {kind:?} {k}/{random}"))
        })
        .context("cannot make a random trajectory")?;
        write_baselines(&dir, &baselines)?;
        write!(out, "{}", BaselineSummary(&baselines))?;

        if !self.no_check {
            progress.set_message("estimator covariance (24) on the plan");
            let c = check_plan_approximation(&robot, &spline, self.rate, &noise)
                .context("cannot compute the estimator's covariance on the plan")?;
            write!(out, "{}", ApproximationLine(&c))?;
        }

        if self.montecarlo > 0 {
            let runs = self.montecarlo;
            let gain =
                precision_gain(&robot, &info, &spline, runs, self.seed, &mut rng, |t, r| {
                    progress.set_message(format!("Monte Carlo on the {t}: run {r}/{runs}"))
                })?;
            write!(out, "{}", PrecisionGainSummary(&gain))?;
        }
        progress.finish();
        writeln!(
            out,
            "wrote sigma_vs_time, speed and baselines (.csv, .png, .svg) to {}",
            dir.display()
        )?;
        Ok(())
    }
}
