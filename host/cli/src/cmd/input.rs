//! What the commands share: naming a robot, turning a loaded session into the
//! calibrator's inputs, recording with a progress bar, and printing progress.

use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::time::Duration;

use anyhow::{bail, Context};
use indicatif::{ProgressBar, ProgressStyle};
use robimu_model::error_selection::{identifiable_errors, IdentifiableOptions};
use robimu_model::urdf::{robot_from_urdf_file, UrdfOptions};
use robimu_model::Robot;
use robimu_record::{record, RecordOptions, RecordProgress, RecordSummary};
use robimu_session::Session;

/// Robots built into the program (`--robot NAME`, `robot = "NAME"`).
pub const BUILTIN_ROBOTS: &[&str] = &["aubo_i5"];

/// Where a robot description comes from.
pub enum RobotSource {
    /// A built-in robot.
    Builtin,
    /// A TOML robot description at this path.
    File(PathBuf),
}

impl RobotSource {
    /// `robot = …` in the session.toml of a session made for the robot
    /// `spec` names: the built-in name, or the file's absolute path (the
    /// session must find it from its own directory).
    pub fn session_field(self, spec: &str) -> String {
        match self {
            RobotSource::Builtin => spec.to_string(),
            RobotSource::File(path) => std::path::absolute(&path)
                .unwrap_or(path)
                .display()
                .to_string(),
        }
    }
}

/// The robot `spec` names: a built-in name, or a path to a TOML robot
/// description or a URDF (relative paths are taken relative to `base` when given).
pub fn resolve_robot(spec: &str, base: Option<&Path>) -> anyhow::Result<(Robot, RobotSource)> {
    resolve_robot_with(spec, base, &UrdfLinks::default())
}

/// Base and tip link of a URDF robot (`--base`, `--tip`); `None`: the URDF's
/// root link, and its only leaf link.
#[derive(Debug, Clone, Default, clap::Args)]
pub struct UrdfLinks {
    /// URDF robots: the base link of the chain [default: the root link].
    #[arg(long = "base", value_name = "LINK")]
    pub base: Option<String>,
    /// URDF robots: the tip (flange) link of the chain [default: the only leaf link].
    #[arg(long = "tip", value_name = "LINK")]
    pub tip: Option<String>,
}

/// The `resonance` effect's mode (`--resonance-hz`, `--resonance-zeta`).
#[derive(Debug, Clone, clap::Args)]
pub struct ResonanceMode {
    /// Natural frequency of the `resonance` effect's mode, Hz (0.5–50).
    #[arg(long, value_name = "HZ", default_value_t = 10.0)]
    pub resonance_hz: f64,
    /// Damping ratio of the `resonance` effect's mode (0–1, exclusive).
    #[arg(long, value_name = "ZETA", default_value_t = 0.05)]
    pub resonance_zeta: f64,
}

impl Default for ResonanceMode {
    fn default() -> Self {
        let m = robimu_model::effects::resonance::Mode::default();
        Self {
            resonance_hz: m.f_hz,
            resonance_zeta: m.zeta,
        }
    }
}

impl ResonanceMode {
    /// The checked mode.
    pub fn mode(&self) -> anyhow::Result<robimu_model::effects::resonance::Mode> {
        let (f, z) = (self.resonance_hz, self.resonance_zeta);
        if !(0.5..=50.0).contains(&f) {
            anyhow::bail!("--resonance-hz must be between 0.5 and 50 Hz (got {f})");
        }
        if !(z > 0.0 && z < 1.0) {
            anyhow::bail!("--resonance-zeta must be between 0 and 1, exclusive (got {z})");
        }
        Ok(robimu_model::effects::resonance::Mode { f_hz: f, zeta: z })
    }
}

/// Whether `path` names a URDF file (by its extension).
pub fn is_urdf(path: &Path) -> bool {
    path.extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("urdf"))
}

/// [`resolve_robot`] with the chain of a URDF robot chosen by `links`.
pub fn resolve_robot_with(
    spec: &str,
    base: Option<&Path>,
    links: &UrdfLinks,
) -> anyhow::Result<(Robot, RobotSource)> {
    if let Some(robot) = Robot::builtin(spec) {
        return Ok((robot, RobotSource::Builtin));
    }
    let path = match base {
        Some(base) if Path::new(spec).is_relative() => base.join(spec),
        _ => PathBuf::from(spec),
    };
    if !path.is_file() {
        bail!(
            "unknown robot `{spec}`: not a built-in robot ({}) and no robot description file {}",
            BUILTIN_ROBOTS.join(", "),
            path.display()
        );
    }
    let robot = if is_urdf(&path) {
        let opts = UrdfOptions {
            base: links.base.clone(),
            tip: links.tip.clone(),
            ..UrdfOptions::default()
        };
        robot_from_urdf_file(&path, &opts)
            .with_context(|| format!("cannot use the URDF {}", path.display()))?
            .0
    } else {
        Robot::from_toml_file(&path)
            .with_context(|| format!("cannot use the robot description {}", path.display()))?
    };
    // docs/model.md §1: without an explicit `[errors]` table the estimated
    // generalized errors are found numerically, never hand-listed.
    let robot = if robot.description().errors.is_none() {
        let set = identifiable_errors(&robot, &IdentifiableOptions::default()).with_context(|| {
            format!(
                "{}: cannot determine which generalized errors are identifiable (list them in an [errors] table)",
                path.display()
            )
        })?;
        robot.with_estimated_errors(set.errors)?
    } else {
        robot
    };
    Ok((robot, RobotSource::File(path)))
}

/// The session's robot, with the session's gravity magnitude when it sets one
/// and each IMU's mount prior from its `[imu.mount]` / `[imu<j>.mount]`
/// table (docs/model.md §9: IMU 0's missing keys keep the robot's
/// `[imu_mount]`, IMU j ≥ 1's keep IMU 0's).
pub fn session_robot(session: &Session) -> anyhow::Result<Robot> {
    let toml = session.dir.join("session.toml");
    let (mut robot, _) = resolve_robot(&session.meta.robot, Some(&session.dir))
        .with_context(|| format!("{}: `robot`", toml.display()))?;
    if let Some(g0) = session.meta.gravity {
        robot = robot
            .with_gravity(g0)
            .context("session.toml: `gravity` is not usable")?;
    }
    for (&j, m) in &session.meta.mounts {
        // in order: IMU 0 first, so that IMU j ≥ 1 builds on IMU 0's prior
        let base = *robot.mount();
        let name = if j == 0 {
            "imu".into()
        } else {
            format!("imu{j}")
        };
        robot = robot
            .with_mount(j, m.over(&base))
            .with_context(|| format!("{}: [{name}.mount] is not usable", toml.display()))?;
    }
    Ok(robot)
}

/// Loads the session at `dir` with its robot, checking that they have the
/// same joint count.
pub fn load_session(dir: &Path) -> anyhow::Result<(Session, Robot)> {
    let session =
        Session::load(dir).with_context(|| format!("cannot load the session {}", dir.display()))?;
    let robot = session_robot(&session)?;
    if session.joint_count() != robot.dof() {
        bail!(
            "{}: {} joint columns (q1..q{}), but robot `{}` has {} joints",
            dir.join("joints.csv").display(),
            session.joint_count(),
            session.joint_count(),
            robot.name(),
            robot.dof()
        );
    }
    Ok((session, robot))
}

/// Where a command writes its output file: `--out` if given, else `default`;
/// refused up front (before any long computation) when its directory does
/// not exist.
pub fn output_path(out: Option<&Path>, default: PathBuf) -> anyhow::Result<PathBuf> {
    let path = out.map(Path::to_path_buf).unwrap_or(default);
    if let Some(parent) = path.parent() {
        if !parent.as_os_str().is_empty() && !parent.is_dir() {
            bail!(
                "--out {}: the directory {} does not exist",
                path.display(),
                parent.display()
            );
        }
    }
    Ok(path)
}

/// Records with a progress bar on stderr (when it is a terminal). The first
/// Ctrl-C (SIGINT) or SIGTERM stops the recording cleanly (the plan halted,
/// the session finished); a second Ctrl-C ends the program at once (exit
/// 130; `robimu repair` then finishes the session).
pub fn record_with_progress(opts: &RecordOptions) -> anyhow::Result<RecordSummary> {
    use signal_hook::consts::{SIGINT, SIGTERM};
    let flag = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let mut ids = Vec::new();
    for (signal, exit) in [(SIGINT, 130), (SIGTERM, 143)] {
        // registered first: runs only when the flag is already set
        ids.push(
            signal_hook::flag::register_conditional_shutdown(signal, exit, flag.clone())
                .context("cannot install the Ctrl-C handler")?,
        );
        ids.push(
            signal_hook::flag::register(signal, flag.clone())
                .context("cannot install the Ctrl-C handler")?,
        );
    }
    let mut opts = opts.clone();
    opts.interrupt = Some(flag);
    let result = record_showing_progress(&opts);
    for id in ids {
        signal_hook::low_level::unregister(id);
    }
    result
}

fn record_showing_progress(opts: &RecordOptions) -> anyhow::Result<RecordSummary> {
    let multi = indicatif::MultiProgress::new();
    let bar = std::io::stderr().is_terminal().then(|| {
        let bar = multi.add(ProgressBar::new(1000));
        let style = ProgressStyle::with_template(
            "{spinner} recording [{elapsed_precise}] {bar:30} {percent:>3}% (~{eta} left) {msg}",
        )
        .unwrap_or_else(|_| ProgressStyle::default_bar());
        bar.set_style(style);
        bar.enable_steady_tick(Duration::from_millis(200));
        bar
    });
    // With several IMUs (docs/model.md §9): one more line per IMU.
    let mut lines: Vec<ProgressBar> = Vec::new();
    let mut show = |p: &RecordProgress| {
        if let Some(bar) = &bar {
            let done = if p.total > 0.0 {
                (p.elapsed / p.total).min(1.0)
            } else {
                0.0
            };
            bar.set_position((done * 1000.0) as u64);
            bar.set_message(format!(
                "{:.0} frames/s, {} IMU / {} joint samples, {} gaps, {} CRC errors, {} bad frames{}",
                p.imu_rate,
                p.imu_samples,
                p.joint_samples,
                p.seq_gaps,
                p.crc_errors,
                p.bad_frames,
                if p.restarts > 0 {
                    format!(", {} board restarts", p.restarts)
                } else {
                    String::new()
                }
            ));
            if p.imus.len() > 1 {
                while lines.len() < p.imus.len() {
                    let line = multi.add(ProgressBar::new_spinner());
                    line.set_style(
                        ProgressStyle::with_template("  {msg}")
                            .unwrap_or_else(|_| ProgressStyle::default_spinner()),
                    );
                    lines.push(line);
                }
                for (j, (line, imu)) in lines.iter().zip(&p.imus).enumerate() {
                    line.set_message(imu_progress_line(j, imu));
                }
            }
        }
    };
    let result = record(opts, &mut show);
    for line in &lines {
        line.finish_and_clear();
    }
    if let Some(bar) = &bar {
        bar.finish_and_clear();
    }
    Ok(result?)
}

/// IMU `j`'s progress line: its board and sensor, samples, rate, gaps and
/// the board's drops.
pub fn imu_progress_line(j: usize, p: &robimu_record::ImuProgress) -> String {
    let file = robimu_session::files::imu_csv(j);
    format!(
        "IMU {j} ({file}, {} sensor {}): {} samples, {:.0}/s, {} gaps, {} dropped by the board",
        p.port, p.sensor, p.samples, p.rate, p.seq_gaps, p.device_dropped
    )
}

/// A spinner on stderr with a message, and log lines above it; when stderr
/// is not a terminal the spinner is hidden and the log lines are plain.
pub struct Progress {
    bar: Option<ProgressBar>,
}

impl Progress {
    /// Start showing `message`.
    pub fn start(message: impl Into<String>) -> Self {
        if !std::io::stderr().is_terminal() {
            return Self { bar: None };
        }
        let bar = ProgressBar::new_spinner();
        let style = ProgressStyle::with_template("{spinner} [{elapsed}] {msg}")
            .unwrap_or_else(|_| ProgressStyle::default_spinner());
        bar.set_style(style);
        bar.set_message(message.into());
        bar.enable_steady_tick(Duration::from_millis(120));
        Self { bar: Some(bar) }
    }

    /// Replace the message.
    pub fn set_message(&self, message: impl Into<String>) {
        if let Some(bar) = &self.bar {
            bar.set_message(message.into());
        }
    }

    /// A log line on stderr (above the spinner when it is shown).
    pub fn println(&self, line: impl AsRef<str>) {
        match &self.bar {
            Some(bar) => bar.println(line.as_ref()),
            None => eprintln!("{}", line.as_ref()),
        }
    }

    /// Remove the spinner.
    pub fn finish(self) {
        if let Some(bar) = self.bar {
            bar.finish_and_clear();
        }
    }
}

/// `--imu-position J=X,Y,Z`: IMU J's position on the flange (m, flange frame).
pub fn parse_imu_position(text: &str) -> Result<(usize, [f64; 3]), String> {
    let (j, xyz) = text
        .split_once('=')
        .ok_or_else(|| format!("`{text}`: expected J=X,Y,Z (IMU index, position in m)"))?;
    let j: usize = j
        .trim()
        .parse()
        .map_err(|_| format!("`{text}`: IMU index `{}` is not a number ≥ 0", j.trim()))?;
    let v: Vec<f64> = xyz
        .split(',')
        .map(|c| c.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|_| format!("`{text}`: X,Y,Z must be three numbers (m)"))?;
    match v[..] {
        [x, y, z] if v.iter().all(|c| c.is_finite()) => Ok((j, [x, y, z])),
        _ => Err(format!("`{text}`: X,Y,Z must be three finite numbers (m)")),
    }
}

/// `robot` with the IMUs of `--imu-position J=X,Y,Z` placed (a plate of IMUs,
/// docs/model.md §9): IMU J's mount prior centred at (X, Y, Z), m, its σ
/// and rotations as before ([`Robot::with_mount`]); J < `imus`.
pub fn place_imus(
    mut robot: Robot,
    imus: usize,
    positions: &[(usize, [f64; 3])],
) -> anyhow::Result<Robot> {
    for &(j, position) in positions {
        if j >= imus {
            bail!(
                "--imu-position {j}=…: there are {imus} IMUs (0 to {}; --imus K)",
                imus - 1
            );
        }
        let mount = robimu_model::robot::ImuMount {
            position,
            ..*robot.mount_of(j)
        };
        robot = robot
            .with_mount(j, mount)
            .with_context(|| format!("--imu-position {j}=…"))?;
    }
    Ok(robot)
}
