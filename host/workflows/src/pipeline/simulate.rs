//! A simulated session directory (`robimu simulate`, docs/model.md §7):
//! the truth drawn (or given), the trajectory planned (or read from a
//! plan), the samples simulated with the requested noise and injected
//! effects, and session.toml, joints.csv, imu.csv, truth.toml and, with a
//! tracker, tracker.csv and poses.csv written.

use std::fmt;
use std::path::PathBuf;

use anyhow::{bail, Context};
use rand::SeedableRng;
use robimu_model::effects::resonance::Mode;
use robimu_model::noise::NoiseModel;
use robimu_model::observations::Measurements;
use robimu_model::params::draw_truth;
use robimu_model::trajectory::random_walk;
use robimu_model::{ParamLayout, Robot, Spline};
use robimu_session::poses::{write_pose_file, write_tracker_file};
use robimu_session::{
    NoiseOverride, NoiseShape, SessionMeta, SessionWriter, Truth, IMU_TEMP_COLUMN,
};

use super::checked_mode;
use super::noise_spec::parse_noise_model;
use crate::plan::files::read_plan;
use crate::simulate::{
    add_bias_walk, simulate, tracker_recording, SimulateOptions, WarmUpTemperature,
};

/// What to simulate and where to write it (`robimu simulate`'s flags).
#[derive(Debug, Clone)]
pub struct SessionSpec {
    /// The robot, its IMUs placed.
    pub robot: Robot,
    /// session.toml's `robot` field.
    pub robot_field: String,
    /// Length of the random trajectory, s.
    pub duration: f64,
    /// A plan directory (`plan.csv`) executed instead of a random trajectory.
    pub trajectory: Option<PathBuf>,
    /// IMU sample rate, Hz.
    pub rate: f64,
    /// Joint sample rate, Hz [default: `rate`].
    pub joint_rate: Option<f64>,
    /// Seed of the truth, the trajectory and the noise.
    pub seed: u64,
    /// The session directory.
    pub out: PathBuf,
    /// Exact measurements.
    pub noise_free: bool,
    /// A truth.toml of every parameter, instead of a drawn truth.
    pub truth: Option<PathBuf>,
    /// Also write tracker.csv and poses.csv.
    pub tracker: bool,
    /// Parameters whose truth stays at nominal (`lengths` and/or names).
    pub nominal: Vec<String>,
    /// Number of static poses in poses.csv (with `tracker`).
    pub poses: usize,
    /// Catalogue effects injected, `NAME=MAGNITUDE`.
    pub effects: Vec<String>,
    /// A random-walk bias, this many times the paper's drift.
    pub bias_walk: Option<f64>,
    /// A sensor warm-up `START,END,TAU` (°C, °C, s).
    pub temperature: Option<String>,
    /// The `resonance` effect's mode (checked when effects are injected).
    pub resonance: Mode,
    /// The IMU noise model's spec (`white`, `ar1:…` or a TOML file).
    pub noise_model: Option<String>,
    /// Number of IMUs.
    pub imus: usize,
    /// IMU J's mount position on the flange, m (`[imu<J>.mount]` priors).
    pub imu_position: Vec<(usize, [f64; 3])>,
}

/// What [`simulate_session`] wrote.
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

impl fmt::Display for Simulated {
    /// `wrote DIR: … samples … (true tau = …)`, the line `robimu simulate` prints.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "wrote {}: {} joint samples, {} IMU samples{} over {:.1} s (true tau = {:.4} s; truth in truth.toml)",
            self.dir.display(),
            self.joint_samples,
            self.imu_samples,
            if self.imus > 1 {
                format!(" per IMU from {} IMUs", self.imus)
            } else {
                String::new()
            },
            self.duration,
            self.tau
        )
    }
}

/// The length and rates are in range: `duration` at most a day, the rates
/// (`joint_rate` defaults to `rate`) at most 10 kHz.
pub fn check_rates(duration: f64, rate: f64, joint_rate: Option<f64>) -> anyhow::Result<()> {
    in_range("--duration", duration, 86_400.0)?;
    in_range("--rate", rate, 10_000.0)?;
    in_range("--joint-rate", joint_rate.unwrap_or(rate), 10_000.0)
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

/// The truth, the trajectory and the samples of `spec` before any effect,
/// warm-up or bias walk (what [`simulate_session`] and a robot's flange pose
/// session, [`super::pose_flange`], share).
pub(crate) struct SimulatedMotion {
    /// The layout of x.
    pub layout: ParamLayout,
    /// The true x.
    pub x_true: Vec<f64>,
    /// The joint trajectory.
    pub trajectory: Spline,
    /// The samples.
    pub data: Measurements,
    /// How they were sampled.
    pub opts: SimulateOptions,
    /// The IMU noise model given.
    pub noise_model: Option<NoiseModel>,
}

/// The motion and samples of `spec` ([`SimulatedMotion`]).
pub(crate) fn simulate_motion(spec: &SessionSpec) -> anyhow::Result<SimulatedMotion> {
    let robot = &spec.robot;
    if spec.imus > 1 {
        for (given, flag) in [
            (!spec.effects.is_empty(), "--effect"),
            (spec.temperature.is_some(), "--temperature"),
            (spec.bias_walk.is_some(), "--bias-walk"),
        ] {
            if given {
                bail!(
                    "{flag} is simulated for one IMU only (drop --imus {})",
                    spec.imus
                );
            }
        }
    }
    let layout = ParamLayout::with_imus(robot, spec.imus);
    let mut rng = rand::rngs::StdRng::seed_from_u64(spec.seed);
    let mut drawn = draw_truth(&layout, &mut rng);
    let nominal = layout.nominal();
    let held = layout
        .select(&spec.nominal)
        .map_err(|e| anyhow::anyhow!("--nominal: {e}"))?;
    for k in held {
        drawn[k] = nominal[k];
    }
    let x_true = match &spec.truth {
        Some(path) => Truth::read(path)?
            .vector(&layout)
            .map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?,
        None => drawn,
    };
    let trajectory = match &spec.trajectory {
        None => random_walk(robot, spec.duration, 1.0, &mut rng)
            .context("cannot plan the excitation trajectory")?,
        Some(dir) => read_plan(robot, dir)?,
    };
    let mut opts = SimulateOptions::paper(robot);
    opts.imu_rate = spec.rate;
    opts.joint_rate = spec.joint_rate.unwrap_or(spec.rate);
    opts.noise = !spec.noise_free;
    let noise_model = spec
        .noise_model
        .as_deref()
        .map(|s| parse_noise_model(s, robot.sigma_z(), spec.rate))
        .transpose()?;
    if let Some(model) = &noise_model {
        opts.sigma_z = model.sigma_z();
        opts.noise_model = (!model.is_white()).then(|| model.clone());
    }
    let data = simulate(robot, &layout, &x_true, &trajectory, &opts, spec.seed)
        .context("cannot simulate the measurements at these true parameters")?;
    Ok(SimulatedMotion {
        layout,
        x_true,
        trajectory,
        data,
        opts,
        noise_model,
    })
}

impl SessionSpec {
    /// `robimu simulate --robot NAME --duration --rate --seed --out`'s spec
    /// (every other flag at its default).
    pub(crate) fn plain(robot: Robot, duration: f64, rate: f64, seed: u64, out: PathBuf) -> Self {
        Self {
            robot_field: robot.name().to_string(),
            robot,
            duration,
            trajectory: None,
            rate,
            joint_rate: None,
            seed,
            out,
            noise_free: false,
            truth: None,
            tracker: false,
            nominal: Vec::new(),
            poses: 250,
            effects: Vec::new(),
            bias_walk: None,
            temperature: None,
            resonance: Mode::default(),
            noise_model: None,
            imus: 1,
            imu_position: Vec::new(),
        }
    }
}

/// Simulate the session `spec` describes and write it.
pub fn simulate_session(spec: &SessionSpec) -> anyhow::Result<Simulated> {
    let robot = &spec.robot;
    let SimulatedMotion {
        layout,
        x_true,
        trajectory,
        mut data,
        opts,
        noise_model,
    } = simulate_motion(spec)?;
    if let Some(w) = warm_up(spec)? {
        data.imu_temp = Some(w.readings(&data.imu_t));
    }
    if !spec.effects.is_empty() {
        inject_effects(spec, &x_true, &trajectory, &mut data)?;
    }
    if let Some(scale) = spec.bias_walk {
        if !(scale.is_finite() && scale >= 0.0) {
            bail!("--bias-walk must be a non-negative number (got {scale})");
        }
        add_bias_walk(&mut data, scale, spec.seed);
    }
    let noise = noise_model
        .as_ref()
        .filter(|m| m.sigma_z() != robot.sigma_z() || !m.is_white());
    let written = write_session(spec, &layout, &x_true, &data, noise)?;
    if spec.tracker {
        write_tracker(spec, &layout, &x_true, &trajectory, &data, &opts)?;
    }
    Ok(written)
}

/// The `effects` injected into `data`.
fn inject_effects(
    spec: &SessionSpec,
    x_true: &[f64],
    trajectory: &Spline,
    data: &mut Measurements,
) -> anyhow::Result<()> {
    let robot = &spec.robot;
    let mode = checked_mode(spec.resonance)?;
    let mut setup = crate::diagnose::setup_with(robot, data, None, mode);
    // the biases follow the true temperature, not the whole-degree readings
    if let Some(w) = warm_up(spec)? {
        setup.set_temperature(&data.imu_t, &w.values(&data.imu_t));
    }
    let mut injected = Vec::new();
    for item in &spec.effects {
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
    crate::diagnose::inject_effects(robot, x_true, trajectory, data, &injected)
        .context("cannot inject the effects")?;
    Ok(())
}

/// The `temperature` warm-up.
fn warm_up(spec: &SessionSpec) -> anyhow::Result<Option<WarmUpTemperature>> {
    let Some(text) = &spec.temperature else {
        return Ok(None);
    };
    let v: Vec<f64> = text
        .split(',')
        .map(|x| x.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .ok()
        .filter(|v: &Vec<f64>| v.len() == 3)
        .with_context(|| {
            format!("--temperature {text}: expected START,END,TAU (°C, °C, s), e.g. 22,32,120")
        })?;
    WarmUpTemperature::new(v[0], v[1], v[2])
        .map(Some)
        .map_err(|e| anyhow::anyhow!("--temperature {text}: {e}"))
}

/// tracker.csv (the motion) and poses.csv (static poses with q1..qn).
fn write_tracker(
    spec: &SessionSpec,
    layout: &ParamLayout,
    x_true: &[f64],
    trajectory: &Spline,
    data: &Measurements,
    opts: &SimulateOptions,
) -> anyhow::Result<()> {
    if spec.poses < 4 {
        bail!("--poses must be at least 4 (got {})", spec.poses);
    }
    let robot = &spec.robot;
    let (n, poses, seed) = (robot.dof(), spec.poses, spec.seed);
    let rec = tracker_recording(robot, layout, x_true, trajectory, data, opts, poses, seed)?;
    write_tracker_file(&spec.out.join(robimu_session::files::TRACKER), &rec.motion)?;
    let comment = "static poses for robimu validate";
    write_pose_file(&spec.out.join("poses.csv"), comment, n, &rec.poses)?;
    Ok(())
}

/// session.toml's metadata: the noise the samples were made with (when not
/// the robot's white Σ_z), the notes, the placed IMUs' mount priors.
fn session_meta(spec: &SessionSpec, noise: Option<&NoiseModel>) -> anyhow::Result<SessionMeta> {
    let mut meta = SessionMeta::new(spec.robot_field.clone());
    if let Some(model) = noise {
        meta.noise = Some(NoiseOverride {
            sigma_z: Some(model.sigma_z()),
            sigma_q: None,
        });
        meta.noise_shape = NoiseShape::from_model(model);
    }
    let mut notes = format!(
        "simulated by robimu simulate: seed {}, {} s, IMU {} Hz, joints {} Hz{}",
        spec.seed,
        spec.duration,
        spec.rate,
        spec.joint_rate.unwrap_or(spec.rate),
        if spec.noise_free { ", noise-free" } else { "" }
    );
    if let Some(text) = spec.noise_model.as_ref().filter(|_| noise.is_some()) {
        notes.push_str(&format!("; noise model {text}"));
    }
    if !spec.effects.is_empty() {
        notes.push_str(&format!("; effects injected: {}", spec.effects.join(", ")));
    }
    if let Some(scale) = spec.bias_walk {
        notes.push_str(&format!("; bias random walk {scale}x the paper's drift"));
    }
    if let Some(text) = &spec.temperature {
        notes.push_str(&format!("; warm-up {text} (°C, °C, s)"));
    }
    meta.notes = Some(notes);
    // each placed IMU's mount prior, for calibrate (docs/model.md §9)
    for &(j, p) in &spec.imu_position {
        let mut mount = toml::Table::new();
        mount.insert("position".into(), toml::Value::try_from(p)?);
        let table = match j {
            0 => meta.imu.get_or_insert_with(Default::default),
            j => meta.imu_tables.entry(j).or_default(),
        };
        table.insert("mount".into(), toml::Value::Table(mount));
    }
    Ok(meta)
}

/// Write the session directory: session.toml, joints.csv, imu.csv (with a
/// temperature column when simulated), truth.toml.
fn write_session(
    spec: &SessionSpec,
    layout: &ParamLayout,
    x_true: &[f64],
    data: &Measurements,
    noise: Option<&NoiseModel>,
) -> anyhow::Result<Simulated> {
    let meta = session_meta(spec, noise)?;
    let n = spec.robot.dof();
    let extra: &[&str] = match data.imu_temp {
        Some(_) => &[IMU_TEMP_COLUMN],
        None => &[],
    };
    let mut w = SessionWriter::create_with_imu_extra(&spec.out, &meta, n, extra)
        .with_context(|| format!("cannot write the session {}", spec.out.display()))?;
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
