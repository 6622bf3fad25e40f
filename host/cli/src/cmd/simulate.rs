//! `robimu simulate`: a simulated session directory (docs/model.md §7).

use std::io::Write;
use std::path::{Path, PathBuf};

use anyhow::{bail, Context};
use rand::SeedableRng;
use robimu_model::params::draw_truth;
use robimu_model::trajectory::random_walk;
use robimu_model::{ParamLayout, Robot};
use robimu_session::{read_table, Columns, SessionMeta, SessionWriter, Truth};
use robimu_workflows::simulate::{simulate, SimulateOptions};

use super::input::{resolve_robot_with, RobotSource, UrdfLinks};

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
    /// size_effect mm, clock_drift ppm, bias_drift deg/s, joint_elasticity
    /// deg/(kN*m), encoder_scale ppm, resonance mrad/(rad/s^2) (each a
    /// fixed pattern scaled by the magnitude; see `robimu_model::effects`).
    /// Recorded in session.toml's notes.
    #[arg(long, value_name = "NAME=MAGNITUDE")]
    pub effect: Vec<String>,
    #[command(flatten)]
    pub resonance: super::input::ResonanceMode,
}

/// What [`SimulateCmd::write`] produced.
#[derive(Debug, Clone)]
pub struct Simulated {
    /// The session directory.
    pub dir: PathBuf,
    /// Joint samples written.
    pub joint_samples: usize,
    /// IMU samples written.
    pub imu_samples: usize,
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

/// Every parameter of `layout` from `truth`, in x order.
fn truth_vector(layout: &ParamLayout, truth: &Truth, path: &Path) -> anyhow::Result<Vec<f64>> {
    if let Some((name, _)) = truth
        .values
        .iter()
        .find(|(n, _)| layout.index_of(n).is_none())
    {
        bail!(
            "{}: `{name}` is not a parameter of this robot (see docs/model.md §5 for the names)",
            path.display()
        );
    }
    layout
        .specs()
        .iter()
        .map(|s| {
            truth
                .get(&s.name)
                .with_context(|| format!("{}: `{}` is missing", path.display(), s.name))
        })
        .collect()
}

/// The trajectory of `PLAN_DIR/plan.csv`, checked against the robot.
fn read_plan(robot: &Robot, dir: &Path) -> anyhow::Result<robimu_model::Spline> {
    let path = dir.join("plan.csv");
    let table = read_plan_table(robot, dir)?;
    let n = robot.dof();
    robimu_model::trajectory::from_samples(n, &table.t, &table.values).with_context(|| {
        format!(
            "{}: cannot represent the plan as a trajectory",
            path.display()
        )
    })
}

/// The samples of `PLAN_DIR/plan.csv`, checked against the robot's joint
/// count and position limits.
pub fn read_plan_table(robot: &Robot, dir: &Path) -> anyhow::Result<robimu_session::Table> {
    let path = dir.join("plan.csv");
    let table = read_table(&path, Columns::Joints)?;
    let n = robot.dof();
    if table.width() != n {
        bail!(
            "{}: {} joint columns, but robot `{}` has {n} joints",
            path.display(),
            table.width(),
            robot.name()
        );
    }
    for (s, row) in table.values.chunks_exact(n).enumerate() {
        for (j, (q, lim)) in row.iter().zip(robot.limits()).enumerate() {
            if *q < lim.q_min - 1e-9 || *q > lim.q_max + 1e-9 {
                bail!(
                    "{}: row {} (t = {} s): q{} = {q} rad is outside the joint limits [{}, {}]",
                    path.display(),
                    s + 1,
                    table.t[s],
                    j + 1,
                    lim.q_min,
                    lim.q_max
                );
            }
        }
    }
    if table.len() < 8 {
        bail!(
            "{}: a plan needs at least 8 samples, found {}",
            path.display(),
            table.len()
        );
    }
    Ok(table)
}

impl SimulateCmd {
    /// Simulate and write the session.
    pub fn run(self) -> anyhow::Result<()> {
        let s = self.write()?;
        let mut out = std::io::stdout().lock();
        writeln!(
            out,
            "wrote {}: {} joint samples, {} IMU samples over {:.1} s (true tau = {:.4} s; truth in truth.toml)",
            s.dir.display(),
            s.joint_samples,
            s.imu_samples,
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
        let (robot, source) = resolve_robot_with(&self.robot, None, &self.links)?;
        let robot_field = match source {
            RobotSource::Builtin => self.robot.clone(),
            // absolute: the session must find it from its own directory
            RobotSource::File(path) => std::path::absolute(&path)
                .unwrap_or(path)
                .display()
                .to_string(),
        };
        let layout = ParamLayout::new(&robot);
        let mut rng = rand::rngs::StdRng::seed_from_u64(self.seed);
        let mut drawn = draw_truth(&layout, &mut rng);
        let nominal = layout.nominal();
        for k in super::calibrate::parameter_indices(&robot, &layout, &self.nominal, "--nominal")? {
            drawn[k] = nominal[k];
        }
        let x_true = match &self.truth {
            Some(path) => {
                let t = Truth::read(path)?;
                truth_vector(&layout, &t, path)?
            }
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
        let mut data = simulate(&robot, &layout, &x_true, &trajectory, &opts, self.seed)
            .context("cannot simulate the measurements at these true parameters")?;
        if !self.effect.is_empty() {
            let setup =
                robimu_workflows::diagnose::setup_with(&robot, &data, None, self.resonance.mode()?);
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
            robimu_workflows::diagnose::inject_effects(
                &robot,
                &x_true,
                &trajectory,
                &mut data,
                &injected,
            )
            .context("cannot inject the effects")?;
        }
        let written = self.write_session(&robot, robot_field, &layout, &x_true, &data)?;
        if self.tracker {
            self.write_tracker(&robot, &layout, &x_true, &trajectory, &data, &opts)?;
        }
        Ok(written)
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
        use robimu_workflows::simulate::{static_poses, tracked_motion};
        use robimu_workflows::tracker::row_from_pose;
        if self.poses < 4 {
            bail!("--poses must be at least 4 (got {})", self.poses);
        }
        let markers = tracked_motion(
            robot,
            layout,
            x_true,
            trajectory,
            &data.joint_t,
            opts.noise,
            self.seed,
        )?;
        let header = format!("t,{}", robimu_session::TRACKER_COLUMNS.join(","));
        let path = self.out.join(robimu_session::files::TRACKER);
        let mut text = format!("{header}\n");
        for (t, m) in data.joint_t.iter().zip(&markers) {
            let row: Vec<String> = row_from_pose(m).iter().map(|v| format!("{v:?}")).collect();
            text.push_str(&format!("{t:?},{}\n", row.join(",")));
        }
        std::fs::write(&path, text).with_context(|| format!("cannot write {}", path.display()))?;
        let poses = static_poses(robot, layout, x_true, self.poses, opts, self.seed)?;
        let path = self.out.join("poses.csv");
        let qs: Vec<String> = (1..=robot.dof()).map(|j| format!("q{j}")).collect();
        let mut text = format!(
            "# static poses for robimu validate\n{header},{}\n",
            qs.join(",")
        );
        for p in &poses {
            let row: Vec<String> = row_from_pose(&p.marker)
                .iter()
                .chain(&p.q)
                .map(|v| format!("{v:?}"))
                .collect();
            text.push_str(&format!("{:?},{}\n", p.t, row.join(",")));
        }
        std::fs::write(&path, text).with_context(|| format!("cannot write {}", path.display()))?;
        Ok(())
    }

    fn write_session(
        &self,
        robot: &Robot,
        robot_field: String,
        layout: &ParamLayout,
        x_true: &[f64],
        data: &robimu_model::observations::Measurements,
    ) -> anyhow::Result<Simulated> {
        let mut meta = SessionMeta::new(robot_field);
        meta.notes = Some(format!(
            "simulated by robimu simulate: seed {}, {} s, IMU {} Hz, joints {} Hz{}",
            self.seed,
            self.duration,
            self.rate,
            self.joint_rate.unwrap_or(self.rate),
            if self.noise_free { ", noise-free" } else { "" }
        ));
        if !self.effect.is_empty() {
            let notes = meta.notes.get_or_insert_with(String::new);
            notes.push_str(&format!("; effects injected: {}", self.effect.join(", ")));
        }
        let n = robot.dof();
        let mut w = SessionWriter::create(&self.out, &meta, n)
            .with_context(|| format!("cannot write the session {}", self.out.display()))?;
        for (t, q) in data.joint_t.iter().zip(data.joint_q.chunks_exact(n)) {
            w.joint(*t, q)?;
        }
        for (t, z) in data.imu_t.iter().zip(&data.imu_z) {
            w.imu(*t, z)?;
        }
        w.truth(&Truth {
            values: layout
                .specs()
                .iter()
                .zip(x_true)
                .map(|(s, v)| (s.name.clone(), *v))
                .collect(),
        })?;
        let dir = w.finish()?;
        Ok(Simulated {
            dir,
            joint_samples: data.joint_t.len(),
            imu_samples: data.imu_t.len(),
            tau: x_true[layout.offsets().tau],
            duration: data.joint_t.last().copied().unwrap_or(0.0)
                - data.joint_t.first().copied().unwrap_or(0.0),
        })
    }
}
