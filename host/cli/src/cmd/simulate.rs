//! `robimu simulate`: a simulated session directory (docs/model.md §7).

use std::io::Write;
use std::path::PathBuf;

use anyhow::bail;
use robimu_workflows::pipeline::pose_simulate::{
    simulate_pose_dir, PoseSessionSpec, PoseSimulated,
};
use robimu_workflows::pipeline::simulate::{check_rates, simulate_session, SessionSpec, Simulated};
use robimu_workflows::pose_calibrate::ImuTiming;

use crate::args::UrdfLinks;
use crate::input::{place_imus, resolve_robot_with};

/// Simulate a recording session (joints, IMU and the hidden truth).
///
/// A random excitation trajectory within the joint limits, a ground truth
/// drawn from the priors (or given), and the joint and IMU samples they
/// produce, written as a session directory: session.toml, joints.csv,
/// imu.csv, and truth.toml with the true parameters.
///
/// `--source poses` simulates a session with tool poses instead
/// (docs/model.md §7.9): a random hand-held-like motion of a body carrying
/// the IMU (the 30 true parameters drawn from the priors with a uniformly
/// random mount rotation) or, with --robot, the robot's flange on the motion
/// `robimu simulate --robot` makes with the same seed, --duration and
/// --rate (its imu.csv byte for byte); its poses at --pose-rate Hz (sample
/// times jittered by --pose-jitter s), the IMU at --rate Hz, its stamps
/// optionally late by --imu-jitter and a lag drifting by --imu-drift:
/// session.toml (source = "poses"), poses.csv, imu.csv and truth.toml. The
/// other flags of joint sessions do not apply to it.
#[derive(Debug, Clone, clap::Args)]
pub struct SimulateCmd {
    /// What the session records of the motion: `joints` (joint angles of a
    /// robot, joints.csv) or `poses` (tool poses, poses.csv).
    #[arg(long, value_enum, default_value_t = SimSource::Joints)]
    pub source: SimSource,
    /// Robot: a built-in name (`robimu robots` lists them) or the path of a
    /// TOML robot description or a URDF [default: aubo_i5].
    #[arg(long)]
    pub robot: Option<String>,
    /// The chain of a URDF robot.
    #[command(flatten)]
    pub links: UrdfLinks,
    /// Length of the trajectory, s (with --trajectory: the plan's length)
    /// [default: 300; 60 with --source poses].
    #[arg(long, conflicts_with = "trajectory")]
    pub duration: Option<f64>,
    /// Execute this plan instead of a random trajectory: a directory with a
    /// `plan.csv` (header `t,q1,…,qn`; s, rad), as `robimu plan` writes.
    #[arg(long, value_name = "PLAN_DIR")]
    pub trajectory: Option<PathBuf>,
    /// IMU sample rate, Hz [default: 120; 100 with --source poses].
    #[arg(long)]
    pub rate: Option<f64>,
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
    /// `robimu_model::effects`). Recorded in session.toml's notes. With
    /// `--source poses` the IMU-side ones (g_sensitivity, size_effect,
    /// clock_drift, sensor_delay, bias_drift) on the hand-held motion.
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
    /// (`imu1/tau`, …). With --source poses each IMU j has its own p_imu,
    /// tau, sensor rotations and intrinsics, g shared: hand-held, its mount
    /// rotation drawn uniformly; with --robot, the robot's IMU j on the
    /// flange as here (--imu-position places it).
    #[arg(long, default_value_t = 1, value_name = "K")]
    pub imus: usize,
    /// `J=X,Y,Z`: IMU J mounted at (X, Y, Z) m on the flange (a plate of
    /// IMUs): its position truth is drawn around it, and session.toml gets
    /// its `[imu<J>.mount]` position prior (docs/model.md §9); repeat per IMU.
    #[arg(long, value_name = "J=X,Y,Z", value_parser = crate::input::parse_imu_position)]
    pub imu_position: Vec<(usize, [f64; 3])>,
    /// `--source poses`: pose sample rate, Hz [default: 15].
    #[arg(long, value_name = "HZ")]
    pub pose_rate: Option<f64>,
    /// `--source poses`: standard deviation of the pose sample times about
    /// their nominal grid, s (each pose is stamped with its true time)
    /// [default: 0.003].
    #[arg(long, value_name = "S")]
    pub pose_jitter: Option<f64>,
    /// `--source poses`: standard deviation of the IMU stamps' arrival
    /// jitter, s (a sample taken at t is stamped t + lag + jitter) [default: 0].
    #[arg(long, value_name = "S")]
    pub imu_jitter: Option<f64>,
    /// `--source poses`: change of the IMU stamps' lag over the recording, s
    /// (linear, zero mid-recording: the true tau is the mean lag's) [default: 0].
    #[arg(long, value_name = "S")]
    pub imu_drift: Option<f64>,
}

/// What a simulated session records of the motion.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum SimSource {
    /// Joint angles of a robot (joints.csv, docs/model.md §7).
    Joints,
    /// Tool poses of a body carrying the IMU (poses.csv, docs/model.md §7.9).
    Poses,
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
    pub fn simulate(&self) -> anyhow::Result<Box<dyn std::fmt::Display + Send>> {
        Ok(match self.source {
            SimSource::Joints => Box::new(self.simulate_joints()?),
            SimSource::Poses => Box::new(self.simulate_poses()?),
        })
    }

    /// `--source poses`: the pose session (the joint flags refused).
    fn simulate_poses(&self) -> anyhow::Result<PoseSimulated> {
        let joint_only = self.joint_only_flags();
        if !joint_only.is_empty() {
            bail!(
                "{}: not for --source poses (a pose session has no joints; it takes --out, \
                 --duration, --seed, --rate, --robot, --imus, --imu-position with --robot, \
                 --pose-rate, --pose-jitter, \
                 --imu-jitter, --imu-drift and --effect of an IMU-side effect)",
                joint_only.join(", ")
            );
        }
        let robot = match &self.robot {
            Some(name) => {
                let robot = resolve_robot_with(name, None, &self.links)?.0;
                Some(place_imus(robot, self.imus.max(1), &self.imu_position)?)
            }
            None => None,
        };
        Ok(simulate_pose_dir(&PoseSessionSpec {
            out: self.out.clone(),
            duration: self.duration.unwrap_or(60.0),
            seed: self.seed,
            pose_rate: self.pose_rate.unwrap_or(15.0),
            pose_jitter: self.pose_jitter.unwrap_or(0.003),
            imu_rate: self.rate.unwrap_or(100.0),
            robot,
            imu_timing: ImuTiming {
                jitter: self.imu_jitter.unwrap_or(0.0),
                drift: self.imu_drift.unwrap_or(0.0),
            },
            imus: self.imus,
            effects: self.effect.clone(),
        })?)
    }

    /// The flags of joint sessions given (other than their defaults).
    fn joint_only_flags(&self) -> Vec<&'static str> {
        let r = crate::args::ResonanceMode::default();
        [
            (
                self.robot.is_none() && (self.links.base.is_some() || self.links.tip.is_some()),
                "--base/--tip without --robot",
            ),
            (self.trajectory.is_some(), "--trajectory"),
            (self.joint_rate.is_some(), "--joint-rate"),
            (self.noise_free, "--noise-free"),
            (self.truth.is_some(), "--truth"),
            (self.tracker, "--tracker"),
            (!self.nominal.is_empty(), "--nominal"),
            (self.bias_walk.is_some(), "--bias-walk"),
            (self.temperature.is_some(), "--temperature"),
            (
                self.resonance.resonance_hz != r.resonance_hz
                    || self.resonance.resonance_zeta != r.resonance_zeta,
                "--resonance-hz/--resonance-zeta",
            ),
            (self.noise_model.is_some(), "--noise-model"),
            (
                !self.imu_position.is_empty() && self.robot.is_none(),
                "--imu-position without --robot",
            ),
        ]
        .into_iter()
        .filter_map(|(given, name)| given.then_some(name))
        .collect()
    }

    /// `--source joints`: the joint session.
    fn simulate_joints(&self) -> anyhow::Result<Simulated> {
        if self.pose_rate.is_some()
            || self.pose_jitter.is_some()
            || self.imu_jitter.is_some()
            || self.imu_drift.is_some()
        {
            bail!(
                "--pose-rate, --pose-jitter, --imu-jitter and --imu-drift are for --source poses \
                 (a session with tool poses)"
            );
        }
        let (duration, rate) = (self.duration.unwrap_or(300.0), self.rate.unwrap_or(120.0));
        check_rates(duration, rate, self.joint_rate)?;
        let robot_name = self.robot.as_deref().unwrap_or("aubo_i5");
        let (robot, source) = resolve_robot_with(robot_name, None, &self.links)?;
        if !(1..=64).contains(&self.imus) {
            bail!("--imus must be between 1 and 64 (got {})", self.imus);
        }
        let s = simulate_session(&SessionSpec {
            robot: place_imus(robot, self.imus, &self.imu_position)?,
            robot_field: source.session_field(robot_name),
            duration,
            trajectory: self.trajectory.clone(),
            rate,
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
