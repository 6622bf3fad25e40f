//! `robimu simulate`: a simulated session directory (docs/model.md §7).

use std::io::Write;
use std::path::PathBuf;

use anyhow::bail;
use robimu_workflows::pipeline::simulate::{check_rates, simulate_session, SessionSpec, Simulated};

use crate::args::UrdfLinks;
use crate::input::{place_imus, resolve_robot_with};

/// Simulate a recording session (joints, IMU and the hidden truth).
///
/// A random excitation trajectory within the joint limits, a ground truth
/// drawn from the priors (or given), and the joint and IMU samples they
/// produce, written as a session directory: session.toml, joints.csv,
/// imu.csv, and truth.toml with the true parameters.
#[derive(Debug, Clone, clap::Args)]
pub struct SimulateCmd {
    /// Robot: a built-in name (`robimu robots` lists them) or the path of a
    /// TOML robot description or a URDF.
    #[arg(long, default_value = "aubo_i5")]
    pub robot: String,
    /// The chain of a URDF robot.
    #[command(flatten)]
    pub links: UrdfLinks,
    /// Length of the trajectory, s (with --trajectory: the plan's length).
    #[arg(long, default_value_t = 300.0, conflicts_with = "trajectory")]
    pub duration: f64,
    /// Execute this plan instead of a random trajectory: a directory with a
    /// `plan.csv` (header `t,q1,…,qn`; s, rad), as `robimu plan` writes.
    #[arg(long, value_name = "PLAN_DIR")]
    pub trajectory: Option<PathBuf>,
    /// IMU sample rate, Hz.
    #[arg(long, default_value_t = 120.0)]
    pub rate: f64,
    /// Joint sample rate, Hz [default: the IMU rate].
    #[arg(long)]
    pub joint_rate: Option<f64>,
    /// Seed of the truth, the trajectory and the noise.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Session directory to write (created if needed; session files in it are replaced).
    #[arg(long)]
    pub out: PathBuf,
    /// Exact measurements: no sensor or joint noise.
    #[arg(long)]
    pub noise_free: bool,
    /// True parameters to use instead of drawing them: a truth.toml listing
    /// every parameter (`name = value`, SI units).
    #[arg(long)]
    pub truth: Option<PathBuf>,
    /// Also simulate an external tracker (noise 0.1 mm, 0.05° per axis) for
    /// `robimu validate`: tracker.csv, the marker pose at every joint sample
    /// of the motion, and poses.csv, static poses at random configurations
    /// with their joint angles (columns q1..qn).
    #[arg(long)]
    pub tracker: bool,
    /// Parameters whose truth stays at nominal instead of being drawn from
    /// the prior, comma-separated: `lengths` and/or parameter names — the
    /// truth that `calibrate --freeze` with the same list assumes.
    #[arg(
        long,
        value_delimiter = ',',
        value_name = "PARAMS",
        conflicts_with = "truth"
    )]
    pub nominal: Vec<String>,
    /// Number of static poses in poses.csv (with --tracker).
    #[arg(long, default_value_t = 250, requires = "tracker")]
    pub poses: usize,
    /// Inject a catalogue effect into the IMU samples, NAME=MAGNITUDE
    /// (repeatable), magnitudes in physical units: g_sensitivity (deg/s)/g,
    /// size_effect mm, clock_drift ppm, sensor_delay ms, bias_drift deg/s, joint_elasticity
    /// deg/(kN*m), encoder_scale ppm, resonance mrad/(rad/s^2),
    /// temperature_bias mg/K (needs --temperature; the gyroscope's 0.015 deg/s/K
    /// per mg/K) (each a fixed pattern scaled by the magnitude; see
    /// `robimu_model::effects`). Recorded in session.toml's notes.
    #[arg(long, value_name = "NAME=MAGNITUDE")]
    pub effect: Vec<String>,
    /// Add a seeded random-walk (Brownian) bias to every IMU channel,
    /// SCALE times the drift the paper observed: its standard deviation
    /// after 25 min is SCALE × 0.017 m/s² (accelerometer) and SCALE ×
    /// 0.025 °/s (gyroscope), centred on the session (truth.toml's biases
    /// are the session means; docs/model.md §4.7). Recorded in the notes.
    #[arg(long, value_name = "SCALE")]
    pub bias_walk: Option<f64>,
    /// A sensor warm-up START,END,TAU (°C, °C, s): imu.csv gets a temp_c
    /// column, T = END + (START − END)·exp(−t/TAU) from the first IMU
    /// sample, read in whole °C as the BNO055 reports it; with
    /// `--effect temperature_bias=M` the biases follow the unrounded curve.
    #[arg(long, value_name = "START,END,TAU")]
    pub temperature: Option<String>,
    /// The `resonance` effect's mode.
    #[command(flatten)]
    pub resonance: crate::args::ResonanceMode,
    /// IMU noise: `white` (default), `ar1:accel=TAU_MS[,gyro=TAU_MS][,motion=C]`
    /// (AR(1) of correlation time TAU ms, same σ; motion=C adds C·|q̈|² to
    /// each channel's variance), or a TOML file with a [noise] table
    /// (`ar_z`, `motion_z`, `sigma_z` as in session.toml). Recorded in
    /// session.toml's [noise] table.
    #[arg(long, value_name = "SPEC", conflicts_with = "noise_free")]
    pub noise_model: Option<String>,
    /// Number of IMUs K on the flange (docs/model.md §9): one robot motion,
    /// each IMU j its own 28 truths (position, tau, intrinsics) drawn from
    /// the priors, written to imu.csv, imu1.csv, … and truth.toml
    /// (`imu1/tau`, …).
    #[arg(long, default_value_t = 1, value_name = "K")]
    pub imus: usize,
    /// `J=X,Y,Z`: IMU J mounted at (X, Y, Z) m on the flange (a plate of
    /// IMUs): its position truth is drawn around it, and session.toml gets
    /// its `[imu<J>.mount]` position prior (docs/model.md §9); repeat per IMU.
    #[arg(long, value_name = "J=X,Y,Z", value_parser = crate::input::parse_imu_position)]
    pub imu_position: Vec<(usize, [f64; 3])>,
}

impl SimulateCmd {
    /// Simulate and write the session, and say what was written.
    pub fn run(self) -> anyhow::Result<()> {
        let s = self.simulate()?;
        writeln!(std::io::stdout().lock(), "{s}")?;
        Ok(())
    }

    /// Simulate and write the session; returns what was written (its text
    /// is what `run` prints).
    pub fn simulate(&self) -> anyhow::Result<Simulated> {
        check_rates(self.duration, self.rate, self.joint_rate)?;
        let (robot, source) = resolve_robot_with(&self.robot, None, &self.links)?;
        if !(1..=64).contains(&self.imus) {
            bail!("--imus must be between 1 and 64 (got {})", self.imus);
        }
        let s = simulate_session(&SessionSpec {
            robot: place_imus(robot, self.imus, &self.imu_position)?,
            robot_field: source.session_field(&self.robot),
            duration: self.duration,
            trajectory: self.trajectory.clone(),
            rate: self.rate,
            joint_rate: self.joint_rate,
            seed: self.seed,
            out: self.out.clone(),
            noise_free: self.noise_free,
            truth: self.truth.clone(),
            tracker: self.tracker,
            nominal: self.nominal.clone(),
            poses: self.poses,
            effects: self.effect.clone(),
            bias_walk: self.bias_walk,
            temperature: self.temperature.clone(),
            resonance: self.resonance.unchecked(),
            noise_model: self.noise_model.clone(),
            imus: self.imus,
            imu_position: self.imu_position.clone(),
        })?;
        Ok(s)
    }
}
