//! `robimu simulate`: a simulated session directory (docs/model.md §7).

use std::io::Write;
use std::path::PathBuf;

use anyhow::{bail, Context};
use rand::SeedableRng;
use robimu_model::noise::NoiseModel;
use robimu_model::params::draw_truth;
use robimu_model::trajectory::random_walk;
use robimu_model::{ParamLayout, Robot};
use robimu_session::poses::{write_pose_file, write_tracker_file};
use robimu_session::{
    NoiseOverride, NoiseShape, SessionMeta, SessionWriter, Truth, IMU_TEMP_COLUMN,
};
use robimu_workflows::simulate::{simulate, tracker_recording, SimulateOptions, WarmUpTemperature};

use robimu_workflows::plan::files::read_plan;

use super::input::{resolve_robot_with, UrdfLinks};

/// Simulate a recording session (joints, IMU and the hidden truth).
///
/// A random excitation trajectory within the joint limits, a ground truth
/// drawn from the priors (or given), and the joint and IMU samples they
/// produce, written as a session directory: session.toml, joints.csv,
/// imu.csv, and truth.toml with the true parameters.
#[derive(Debug, Clone, clap::Args)]
pub struct SimulateCmd {
    /// Robot: a built-in name (aubo_i5) or the path of a TOML robot description or a URDF.
    #[arg(long, default_value = "aubo_i5")]
    pub robot: String,
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
    #[command(flatten)]
    pub resonance: super::input::ResonanceMode,
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
    #[arg(long, value_name = "J=X,Y,Z", value_parser = super::input::parse_imu_position)]
    pub imu_position: Vec<(usize, [f64; 3])>,
}

/// What [`SimulateCmd::write`] produced.
#[derive(Debug, Clone)]
pub struct Simulated {
    /// The session directory.
    pub dir: PathBuf,
    /// Joint samples written.
    pub joint_samples: usize,
    /// IMU samples written (of IMU 0).
    pub imu_samples: usize,
    /// Number of IMUs.
    pub imus: usize,
    /// The true time offset τ, s.
    pub tau: f64,
    /// Length of the trajectory, s.
    pub duration: f64,
}

/// `v` must be in (0, max].
fn in_range(what: &str, v: f64, max: f64) -> anyhow::Result<()> {
    if !(v.is_finite() && v > 0.0) {
        bail!("{what} must be a positive number (got {v})");
    }
    if v > max {
        bail!("{what} = {v} is more than this program simulates (at most {max})");
    }
    Ok(())
}

impl SimulateCmd {
    /// Simulate and write the session.
    pub fn run(self) -> anyhow::Result<()> {
        let s = self.write()?;
        let mut out = std::io::stdout().lock();
        writeln!(
            out,
            "wrote {}: {} joint samples, {} IMU samples{} over {:.1} s (true tau = {:.4} s; truth in truth.toml)",
            s.dir.display(),
            s.joint_samples,
            s.imu_samples,
            if s.imus > 1 {
                format!(" per IMU from {} IMUs", s.imus)
            } else {
                String::new()
            },
            s.duration,
            s.tau
        )?;
        Ok(())
    }

    /// Simulate and write the session; the numbers of what was written.
    pub fn write(&self) -> anyhow::Result<Simulated> {
        in_range("--duration", self.duration, 86_400.0)?;
        in_range("--rate", self.rate, 10_000.0)?;
        let joint_rate = self.joint_rate.unwrap_or(self.rate);
        in_range("--joint-rate", joint_rate, 10_000.0)?;
        let (mut robot, source) = resolve_robot_with(&self.robot, None, &self.links)?;
        let robot_field = source.session_field(&self.robot);
        if !(1..=64).contains(&self.imus) {
            bail!("--imus must be between 1 and 64 (got {})", self.imus);
        }
        robot = super::input::place_imus(robot, self.imus, &self.imu_position)?;
        if self.imus > 1 {
            for (given, flag) in [
                (!self.effect.is_empty(), "--effect"),
                (self.temperature.is_some(), "--temperature"),
                (self.bias_walk.is_some(), "--bias-walk"),
            ] {
                if given {
                    bail!(
                        "{flag} is simulated for one IMU only (drop --imus {})",
                        self.imus
                    );
                }
            }
        }
        let layout = ParamLayout::with_imus(&robot, self.imus);
        let mut rng = rand::rngs::StdRng::seed_from_u64(self.seed);
        let mut drawn = draw_truth(&layout, &mut rng);
        let nominal = layout.nominal();
        let held = layout
            .select(&self.nominal)
            .map_err(|e| anyhow::anyhow!("--nominal: {e}"))?;
        for k in held {
            drawn[k] = nominal[k];
        }
        let x_true = match &self.truth {
            Some(path) => Truth::read(path)?
                .vector(&layout)
                .map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?,
            None => drawn,
        };
        let trajectory = match &self.trajectory {
            None => random_walk(&robot, self.duration, 1.0, &mut rng)
                .context("cannot plan the excitation trajectory")?,
            Some(dir) => read_plan(&robot, dir)?,
        };
        let mut opts = SimulateOptions::paper(&robot);
        opts.imu_rate = self.rate;
        opts.joint_rate = joint_rate;
        opts.noise = !self.noise_free;
        let noise_model = self
            .noise_model
            .as_deref()
            .map(|spec| super::noise_spec::parse_noise_model(spec, robot.sigma_z(), self.rate))
            .transpose()?;
        if let Some(model) = &noise_model {
            opts.sigma_z = model.sigma_z();
            opts.noise_model = (!model.is_white()).then(|| model.clone());
        }
        let mut data = simulate(&robot, &layout, &x_true, &trajectory, &opts, self.seed)
            .context("cannot simulate the measurements at these true parameters")?;
        if let Some(w) = self.warm_up()? {
            data.imu_temp = Some(w.readings(&data.imu_t));
        }
        if !self.effect.is_empty() {
            self.inject_effects(&robot, &x_true, &trajectory, &mut data)?;
        }
        if let Some(scale) = self.bias_walk {
            if !(scale.is_finite() && scale >= 0.0) {
                bail!("--bias-walk must be a non-negative number (got {scale})");
            }
            robimu_workflows::simulate::add_bias_walk(&mut data, scale, self.seed);
        }
        let noise = noise_model
            .as_ref()
            .filter(|m| m.sigma_z() != robot.sigma_z() || !m.is_white());
        let written = self.write_session(&robot, robot_field, &layout, &x_true, &data, noise)?;
        if self.tracker {
            self.write_tracker(&robot, &layout, &x_true, &trajectory, &data, &opts)?;
        }
        Ok(written)
    }

    /// The `--effect` items injected into `data`.
    fn inject_effects(
        &self,
        robot: &Robot,
        x_true: &[f64],
        trajectory: &robimu_model::Spline,
        data: &mut robimu_model::observations::Measurements,
    ) -> anyhow::Result<()> {
        let mut setup =
            robimu_workflows::diagnose::setup_with(robot, data, None, self.resonance.mode()?);
        // the biases follow the true temperature, not the whole-degree readings
        if let Some(w) = self.warm_up()? {
            setup.set_temperature(&data.imu_t, &w.values(&data.imu_t));
        }
        let mut injected = Vec::new();
        for item in &self.effect {
            let Some((name, m)) = item.split_once('=') else {
                bail!("--effect {item}: expected NAME=MAGNITUDE (e.g. clock_drift=50)");
            };
            let e = robimu_model::effects::by_name(&setup, name.trim())
                .with_context(|| format!("--effect {item}"))?;
            let m: f64 = m
                .trim()
                .parse()
                .ok()
                .filter(|v: &f64| v.is_finite())
                .with_context(|| {
                    format!(
                        "--effect {item}: the magnitude must be a number in {}",
                        e.magnitude_unit()
                    )
                })?;
            let theta = e.injection(m);
            injected.push((e, theta));
        }
        robimu_workflows::diagnose::inject_effects(robot, x_true, trajectory, data, &injected)
            .context("cannot inject the effects")?;
        Ok(())
    }

    /// The `--temperature` warm-up.
    fn warm_up(&self) -> anyhow::Result<Option<WarmUpTemperature>> {
        let Some(spec) = &self.temperature else {
            return Ok(None);
        };
        let v: Vec<f64> = spec
            .split(',')
            .map(|x| x.trim().parse::<f64>())
            .collect::<Result<_, _>>()
            .ok()
            .filter(|v: &Vec<f64>| v.len() == 3)
            .with_context(|| {
                format!("--temperature {spec}: expected START,END,TAU (°C, °C, s), e.g. 22,32,120")
            })?;
        WarmUpTemperature::new(v[0], v[1], v[2])
            .map(Some)
            .map_err(|e| anyhow::anyhow!("--temperature {spec}: {e}"))
    }

    /// tracker.csv (the motion) and poses.csv (static poses with q1..qn).
    fn write_tracker(
        &self,
        robot: &Robot,
        layout: &ParamLayout,
        x_true: &[f64],
        trajectory: &robimu_model::Spline,
        data: &robimu_model::observations::Measurements,
        opts: &SimulateOptions,
    ) -> anyhow::Result<()> {
        if self.poses < 4 {
            bail!("--poses must be at least 4 (got {})", self.poses);
        }
        let (n, poses, seed) = (robot.dof(), self.poses, self.seed);
        let rec = tracker_recording(robot, layout, x_true, trajectory, data, opts, poses, seed)?;
        write_tracker_file(&self.out.join(robimu_session::files::TRACKER), &rec.motion)?;
        let comment = "static poses for robimu validate";
        write_pose_file(&self.out.join("poses.csv"), comment, n, &rec.poses)?;
        Ok(())
    }

    fn write_session(
        &self,
        robot: &Robot,
        robot_field: String,
        layout: &ParamLayout,
        x_true: &[f64],
        data: &robimu_model::observations::Measurements,
        noise: Option<&NoiseModel>,
    ) -> anyhow::Result<Simulated> {
        let mut meta = SessionMeta::new(robot_field);
        // the noise the samples were made with, when not the robot's white Σ_z
        if let Some(model) = noise {
            meta.noise = Some(NoiseOverride {
                sigma_z: Some(model.sigma_z()),
                sigma_q: None,
            });
            meta.noise_shape = NoiseShape::from_model(model);
        }
        meta.notes = Some(format!(
            "simulated by robimu simulate: seed {}, {} s, IMU {} Hz, joints {} Hz{}",
            self.seed,
            self.duration,
            self.rate,
            self.joint_rate.unwrap_or(self.rate),
            if self.noise_free { ", noise-free" } else { "" }
        ));
        if let Some(spec) = self.noise_model.as_ref().filter(|_| noise.is_some()) {
            let notes = meta.notes.get_or_insert_with(String::new);
            notes.push_str(&format!("; noise model {spec}"));
        }
        if !self.effect.is_empty() {
            let notes = meta.notes.get_or_insert_with(String::new);
            notes.push_str(&format!("; effects injected: {}", self.effect.join(", ")));
        }
        if let Some(scale) = self.bias_walk {
            let notes = meta.notes.get_or_insert_with(String::new);
            notes.push_str(&format!("; bias random walk {scale}x the paper's drift"));
        }
        if let Some(spec) = &self.temperature {
            let notes = meta.notes.get_or_insert_with(String::new);
            notes.push_str(&format!("; warm-up {spec} (°C, °C, s)"));
        }
        // each placed IMU's mount prior, for calibrate (docs/model.md §9)
        for &(j, p) in &self.imu_position {
            let mut mount = toml::Table::new();
            mount.insert("position".into(), toml::Value::try_from(p)?);
            let table = match j {
                0 => meta.imu.get_or_insert_with(Default::default),
                j => meta.imu_tables.entry(j).or_default(),
            };
            table.insert("mount".into(), toml::Value::Table(mount));
        }
        let n = robot.dof();
        let extra: &[&str] = match data.imu_temp {
            Some(_) => &[IMU_TEMP_COLUMN],
            None => &[],
        };
        let mut w = SessionWriter::create_with_imu_extra(&self.out, &meta, n, extra)
            .with_context(|| format!("cannot write the session {}", self.out.display()))?;
        match &data.imu_temp {
            Some(temp) => {
                for (t, q) in data.joint_t.iter().zip(data.joint_q.chunks_exact(n)) {
                    w.joint(*t, q)?;
                }
                for ((t, z), c) in data.imu_t.iter().zip(&data.imu_z).zip(temp) {
                    w.imu_extra(*t, z, &[*c])?;
                }
            }
            None => w.measurements(data)?,
        }
        w.truth(&Truth::of(layout, x_true))?;
        let dir = w.finish()?;
        Ok(Simulated {
            dir,
            joint_samples: data.joint_t.len(),
            imu_samples: data.imu_t.len(),
            imus: data.n_imus(),
            tau: x_true[layout.offsets().tau],
            duration: data.joint_t.last().copied().unwrap_or(0.0)
                - data.joint_t.first().copied().unwrap_or(0.0),
        })
    }
}
