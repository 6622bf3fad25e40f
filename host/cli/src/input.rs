//! What the commands share (not a command): naming a robot, output paths,
//! IMU positions, recording with a progress bar, and printing progress.

use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::time::Duration;

use anyhow::{bail, Context};
use indicatif::{ProgressBar, ProgressStyle};
use robimu_model::Robot;
use robimu_record::{record, RecordOptions, RecordProgress, RecordSummary};
pub use robimu_workflows::pipeline::{session_robot, RobotSource};

use crate::args::UrdfLinks;

/// The robot `spec` names: a built-in name, or a path to a TOML robot
/// description or a URDF (relative paths are taken relative to `base` when given).
pub fn resolve_robot(spec: &str, base: Option<&Path>) -> anyhow::Result<(Robot, RobotSource)> {
    resolve_robot_with(spec, base, &UrdfLinks::default())
}

/// [`resolve_robot`] with the chain of a URDF robot chosen by `links`.
pub fn resolve_robot_with(
    spec: &str,
    base: Option<&Path>,
    links: &UrdfLinks,
) -> anyhow::Result<(Robot, RobotSource)> {
    let links = robimu_workflows::pipeline::ChainLinks {
        base: links.base.clone(),
        tip: links.tip.clone(),
    };
    robimu_workflows::resolve_robot(spec, base, &links)
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
                    line.set_message(robimu_report::recording::imu_progress_line(j, imu));
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
