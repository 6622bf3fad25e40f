//! `robimu plan`: an excitation trajectory planned for identifiability (paper §7).

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{bail, Context};
use robimu_workflows::plan::information::{covariance, Information};
use robimu_workflows::plan::{plan, sample, PlanOptions, SplineFile};

use super::input::{resolve_robot, Progress};

/// Plan an excitation trajectory that makes x as identifiable as possible.
///
/// Sequential planning (paper §7.3): blocks of B-spline coefficient columns,
/// each chosen to minimise the largest eigenvalue of the posterior covariance
/// of x (SI units) given everything before it, within the joint position,
/// velocity and acceleration limits (enforced exactly through the spline's
/// control points and checked at 1 kHz). Writes to PLAN_DIR: plan.csv (header
/// `t,q1,…,qn`; s, rad) at the controller rate, spline.toml (knots and
/// coefficients), identifiability.csv (the measure against time) and
/// sigma.csv (every parameter's prior and posterior σ).
#[derive(Debug, Clone, clap::Args)]
pub struct PlanCmd {
    /// Robot: a built-in name (aubo_i5) or the path of a TOML robot description.
    #[arg(long, default_value = "aubo_i5")]
    pub robot: String,
    /// Length of the trajectory, s.
    #[arg(long, default_value_t = 300.0)]
    pub duration: f64,
    /// Knot spacing of the spline, s (at least 2·qd_max/qdd_max of every joint).
    #[arg(long, default_value_t = 0.5)]
    pub knot_spacing: f64,
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
    /// Plan directory to write (created if needed).
    #[arg(long, value_name = "PLAN_DIR")]
    pub out: PathBuf,
}

impl PlanCmd {
    /// Plan, write and print the summary.
    pub fn run(self) -> anyhow::Result<()> {
        if !(self.rate.is_finite() && self.rate > 0.0 && self.rate <= 100_000.0) {
            bail!("--rate must be in (0, 100000] Hz (got {})", self.rate);
        }
        if !(self.duration.is_finite() && self.duration > 0.0 && self.duration <= 86_400.0) {
            bail!("--duration must be in (0, 86400] s (got {})", self.duration);
        }
        let (robot, _) = resolve_robot(&self.robot, None)?;
        std::fs::create_dir_all(&self.out)
            .with_context(|| format!("cannot create the plan directory {}", self.out.display()))?;
        let opts = PlanOptions {
            duration: self.duration,
            knot_spacing: self.knot_spacing,
            block: self.block,
            sample_rate: self.imu_rate,
            evaluations: self.evaluations,
            seed: self.seed,
            ..PlanOptions::default()
        };
        let progress = Progress::start("planning");
        let start = Instant::now();
        let p = plan(&robot, &opts, |b, nb, l| {
            progress.set_message(format!("planning: block {b}/{nb}, λ_max ≈ {l:.3e}"))
        })
        .context("cannot plan the trajectory")?;
        let elapsed = start.elapsed().as_secs_f64();
        progress.finish();
        let dir = &self.out;
        let (t, q) = sample(&p.spline, self.rate);
        let n = robot.dof();
        write_csv(&dir.join("plan.csv"), n, &t, &q)?;
        let spline_text = toml::to_string(&SplineFile::of(&p.spline))?;
        std::fs::write(dir.join("spline.toml"), spline_text)
            .with_context(|| format!("cannot write {}", dir.join("spline.toml").display()))?;
        let path = dir.join("identifiability.csv");
        let mut f = create(&path)?;
        writeln!(f, "t,lambda_max,lambda_max_without_robot_lengths")?;
        for k in 0..p.times.len() {
            writeln!(
                f,
                "{},{:e},{:e}",
                p.times[k], p.lambda_max[k], p.lambda_max_without_lengths[k]
            )?;
        }
        f.flush()?;
        let info = Information::new(&robot, robot.sigma_z(), self.imu_rate)?;
        let layout = info.layout();
        let all: Vec<usize> = (0..layout.len()).collect();
        let cov = covariance(&p.information, &all)
            .context("the planned information matrix is not positive definite")?;
        let path = dir.join("sigma.csv");
        let mut f = create(&path)?;
        writeln!(f, "name,unit,prior_sigma,posterior_sigma")?;
        let mut out = std::io::stdout().lock();
        writeln!(
            out,
            "planned {} s in {elapsed:.1} s ({} blocks, {} objective evaluations); wrote {}",
            self.duration,
            p.times.len() - 1,
            p.evaluations,
            dir.display()
        )?;
        writeln!(
            out,
            "lambda_max(Sigma_x), SI: {:.4e} (robot lengths known: {:.4e})",
            p.lambda_max.last().copied().unwrap_or(f64::NAN),
            p.lambda_max_without_lengths
                .last()
                .copied()
                .unwrap_or(f64::NAN)
        )?;
        writeln!(
            out,
            "{:<12} {:>6} {:>12} {:>12}",
            "parameter", "unit", "prior sigma", "posterior"
        )?;
        for (k, s) in layout.specs().iter().enumerate() {
            let post = cov[(k, k)].max(0.0).sqrt();
            writeln!(f, "{},{},{:e},{:e}", s.name, s.unit, s.sigma, post)?;
            writeln!(
                out,
                "{:<12} {:>6} {:>12.4e} {:>12.4e}",
                s.name, s.unit, s.sigma, post
            )?;
        }
        f.flush()?;
        Ok(())
    }
}

fn create(path: &Path) -> anyhow::Result<BufWriter<File>> {
    Ok(BufWriter::new(File::create(path).with_context(|| {
        format!("cannot write {}", path.display())
    })?))
}

/// `t,q1,…,qn` rows (s, rad).
fn write_csv(path: &Path, n: usize, t: &[f64], q: &[f64]) -> anyhow::Result<()> {
    let mut f = create(path)?;
    let header: Vec<String> = (1..=n).map(|j| format!("q{j}")).collect();
    writeln!(f, "t,{}", header.join(","))?;
    for (ti, row) in t.iter().zip(q.chunks_exact(n)) {
        let cols: Vec<String> = row.iter().map(|v| format!("{v:.9}")).collect();
        writeln!(f, "{ti:.6},{}", cols.join(","))?;
    }
    f.flush()
        .with_context(|| format!("cannot write {}", path.display()))
}
