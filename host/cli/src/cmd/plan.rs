//! `robimu plan`: an excitation trajectory planned for identifiability (paper §7).

use std::io::Write;
use std::path::PathBuf;
use std::time::Instant;

use anyhow::{bail, Context};
use robimu_report::plan::{write_plan_files, write_sigma_csv, PlanSummary};
use robimu_workflows::plan::information::posterior_sigma;
use robimu_workflows::plan::{knot_spacing_for, plan, PlanOptions};

use crate::input::{resolve_robot, Progress};
use robimu_workflows::pipeline::noise_spec::parse_noise_model;

/// Plan an excitation trajectory that makes x as identifiable as possible.
///
/// Sequential planning (paper §7.3): blocks of B-spline coefficient columns,
/// each chosen to minimise the largest eigenvalue of the posterior covariance
/// of x (SI units) given everything before it, within the joint position,
/// velocity and acceleration limits (enforced exactly through the spline's
/// control points and checked at 1 kHz). Writes to PLAN_DIR: plan.csv (header
/// `t,q1,…,qn`; s, rad) at the controller rate, spline.toml (knots and
/// coefficients), identifiability.csv (the measure against time) and
/// sigma.csv (every parameter's prior and posterior σ). With `--noise-model`
/// the information is that of the generalised least squares under that IMU
/// noise (docs/model.md §4.6), so the plan is optimised for, and its σ
/// predicted under, the noise it will meet. With `--imus K` the plan is for
/// K IMUs on the flange fitted jointly (docs/model.md §9): the information
/// is summed over the IMUs, the criterion spans the shared and every IMU's
/// parameters, and sigma.csv names them as §9 does (`imu1/k_a_x`, …); every
/// IMU sits at the robot's nominal mount unless `--imu-position` places it.
#[derive(Debug, Clone, clap::Args)]
pub struct PlanCmd {
    /// Robot: a built-in name (`robimu robots` lists them) or the path of a
    /// TOML robot description.
    #[arg(long, default_value = "aubo_i5")]
    pub robot: String,
    /// Length of the trajectory, s.
    #[arg(long, default_value_t = 300.0)]
    pub duration: f64,
    /// Knot spacing of the spline, s (at least 2·qd_max/qdd_max of every
    /// joint) [default: 0.5, or that least spacing when larger, as for the
    /// UR arms at their published speed limits].
    #[arg(long)]
    pub knot_spacing: Option<f64>,
    /// Coefficient columns per block.
    #[arg(long, default_value_t = 8)]
    pub block: usize,
    /// IMU sample rate assumed for the information, Hz.
    #[arg(long, default_value_t = 120.0)]
    pub imu_rate: f64,
    /// Rate of plan.csv, Hz (the robot controller's).
    #[arg(long, default_value_t = 250.0)]
    pub rate: f64,
    /// Objective evaluations per block (more: slower, slightly better).
    #[arg(long, default_value_t = 240)]
    pub evaluations: usize,
    /// Seed of the optimiser.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// The IMU noise the plan assumes: `white` (the robot's σ_z),
    /// `ar1:accel=TAU_MS[,gyro=TAU_MS][,motion=C]`, or a TOML FILE with a
    /// `[noise]` table (`sigma_z`, `ar_z`, `motion_z`; e.g. from `robimu
    /// noise`); AR coefficients per sample at --imu-rate.
    #[arg(long, value_name = "SPEC", default_value = "white")]
    pub noise_model: String,
    /// Number of IMUs on the flange, fitted jointly (docs/model.md §9).
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..=64))]
    pub imus: u32,
    /// `J=X,Y,Z`: IMU J's position on the flange, m, in the flange frame
    /// (ε_n1..3; default the robot's nominal mount); repeat for each IMU placed.
    #[arg(long, value_name = "J=X,Y,Z", value_parser = crate::input::parse_imu_position)]
    pub imu_position: Vec<(usize, [f64; 3])>,
    /// Plan directory to write (created if needed).
    #[arg(long, value_name = "PLAN_DIR")]
    pub out: PathBuf,
}

impl PlanCmd {
    /// Plan, write and print the summary.
    pub fn run(self) -> anyhow::Result<()> {
        let summary = self.plan()?;
        write!(std::io::stdout().lock(), "{summary}")?;
        Ok(())
    }

    /// Plan and write the plan's files; returns the summary `run` prints.
    pub fn plan(&self) -> anyhow::Result<String> {
        if !(self.rate.is_finite() && self.rate > 0.0 && self.rate <= 100_000.0) {
            bail!("--rate must be in (0, 100000] Hz (got {})", self.rate);
        }
        if !(self.duration.is_finite() && self.duration > 0.0 && self.duration <= 86_400.0) {
            bail!("--duration must be in (0, 86400] s (got {})", self.duration);
        }
        let (robot, _) = resolve_robot(&self.robot, None)?;
        let robot = crate::input::place_imus(robot, self.imus as usize, &self.imu_position)?;
        let noise = parse_noise_model(&self.noise_model, robot.sigma_z(), self.imu_rate)?;
        std::fs::create_dir_all(&self.out)
            .with_context(|| format!("cannot create the plan directory {}", self.out.display()))?;
        let opts = PlanOptions {
            duration: self.duration,
            knot_spacing: self.knot_spacing.unwrap_or_else(|| {
                knot_spacing_for(&robot, self.duration, 0.5, PlanOptions::default().margin)
            }),
            block: self.block,
            sample_rate: self.imu_rate,
            evaluations: self.evaluations,
            seed: self.seed,
            noise: Some(noise.clone()),
            imus: self.imus as usize,
            ..PlanOptions::default()
        };
        let progress = Progress::start("planning");
        let start = Instant::now();
        let p = plan(&robot, &opts, |b, nb, l| {
            progress.set_message(format!("planning: block {b}/{nb}, λ_max ≈ {l:.3e}"))
        })
        .context("cannot plan the trajectory")?;
        let seconds = start.elapsed().as_secs_f64();
        progress.finish();
        let dir = &self.out;
        write_plan_files(dir, &p, self.rate)?;
        let layout = &p.layout;
        let posterior = posterior_sigma(&p.information)
            .context("the planned information matrix is not positive definite")?;
        write_sigma_csv(dir, layout, &posterior)?;
        let summary = PlanSummary {
            duration: self.duration,
            seconds,
            plan: &p,
            dir,
            layout,
            posterior: &posterior,
            noise: (&noise, &self.noise_model),
        };
        Ok(summary.to_string())
    }
}
