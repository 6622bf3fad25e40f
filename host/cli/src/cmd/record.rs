//! `robimu record`: a session from an IMU board and a robot.

use std::io::IsTerminal;
use std::path::PathBuf;
use std::time::Duration;

use anyhow::{bail, Context};
use indicatif::{ProgressBar, ProgressStyle};
use robimu_protocol::SensorConfig;
use robimu_record::controller::RobotSpec;
use robimu_record::motion::Plan;
use robimu_record::{record, RecordOptions, RecordProgress, RecordSummary};

use super::input::resolve_robot;
use super::simulate::read_plan_table;

/// Record a session: stream the IMU board, poll the robot's joints, and
/// execute a plan on the robot.
///
/// Writes the session directory (docs/model.md §7) as it goes, flushed every
/// second; `robimu repair SESSION` finishes one cut short by a crash.
#[derive(Debug, Clone, clap::Args)]
pub struct RecordCmd {
    /// The IMU board's serial port (e.g. /dev/ttyUSB0).
    #[arg(long)]
    pub imu: String,
    /// Serial baud rate.
    #[arg(long, default_value_t = 921_600)]
    pub baud: u32,
    /// The robot controller: aubo:HOST[:PORT].
    #[arg(long)]
    pub robot: String,
    /// The robot's description: a built-in name or a TOML file.
    #[arg(long, default_value = "aubo_i5")]
    pub model: String,
    /// Plan directory with plan.csv (from `robimu plan`).
    #[arg(long, required_unless_present = "no_move")]
    pub plan: Option<PathBuf>,
    /// Only record; do not move the robot.
    #[arg(long, conflicts_with = "plan")]
    pub no_move: bool,
    /// With --no-move: how long to record, s.
    #[arg(long, default_value_t = 60.0)]
    pub duration: f64,
    /// The session directory to write.
    #[arg(long)]
    pub out: PathBuf,
    /// Joint polling rate, Hz.
    #[arg(long, default_value_t = 125.0)]
    pub joint_rate: f64,
    /// IMU sample rate, Hz.
    #[arg(long, default_value_t = 120)]
    pub rate: u16,
    /// Rest recorded before and after the motion, s.
    #[arg(long, default_value_t = 1.0)]
    pub rest: f64,
}

impl RecordCmd {
    /// The options this command line asks for.
    pub fn options(&self) -> anyhow::Result<RecordOptions> {
        let robot_spec = RobotSpec::parse(&self.robot)?;
        let (robot, _) = resolve_robot(&self.model, None)?;
        let plan = match &self.plan {
            Some(dir) => {
                let table = read_plan_table(&robot, dir)?;
                Some(
                    Plan::from_samples(&table.t, &table.values, table.width())
                        .with_context(|| format!("{}", dir.join("plan.csv").display()))?,
                )
            }
            None => None,
        };
        if !(self.duration.is_finite() && self.duration > 0.0) {
            bail!(
                "--duration must be a positive number of seconds (got {})",
                self.duration
            );
        }
        if !(self.joint_rate.is_finite() && self.joint_rate >= 1.0 && self.joint_rate <= 1000.0) {
            bail!(
                "--joint-rate must be in [1, 1000] Hz (got {})",
                self.joint_rate
            );
        }
        if !(1..=1000).contains(&self.rate) {
            bail!("--rate must be in [1, 1000] Hz (got {})", self.rate);
        }
        if !(self.rest.is_finite() && self.rest >= 0.0) {
            bail!(
                "--rest must be a non-negative number of seconds (got {})",
                self.rest
            );
        }
        if self.out.join("session.toml").exists() {
            bail!(
                "{} already holds a session: choose another --out (a recording never overwrites one)",
                self.out.display()
            );
        }
        Ok(RecordOptions {
            imu_port: self.imu.clone(),
            baud: self.baud,
            robot_spec,
            robot,
            robot_name: self.model.clone(),
            plan,
            duration: self.duration,
            out: self.out.clone(),
            joint_rate: self.joint_rate,
            rest: self.rest,
            sensor: SensorConfig {
                sample_rate_hz: self.rate,
                ..SensorConfig::default()
            },
            interrupt: None,
        })
    }

    /// Record, showing progress.
    pub fn run(self) -> anyhow::Result<()> {
        let opts = self.options()?;
        let summary = record_with_progress(&opts)?;
        print_summary(&summary);
        Ok(())
    }
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
    let bar = std::io::stderr().is_terminal().then(|| {
        let bar = ProgressBar::new(1000);
        let style = ProgressStyle::with_template(
            "{spinner} recording [{elapsed_precise}] {bar:30} {percent:>3}% (~{eta} left) {msg}",
        )
        .unwrap_or_else(|_| ProgressStyle::default_bar());
        bar.set_style(style);
        bar.enable_steady_tick(Duration::from_millis(200));
        bar
    });
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
        }
    };
    let result = record(opts, &mut show);
    if let Some(bar) = &bar {
        bar.finish_and_clear();
    }
    Ok(result?)
}

/// What a user checks after a recording.
pub fn print_summary(s: &RecordSummary) {
    let p = &s.progress;
    let (v, d) = (s.device.firmware_version, &s.device);
    println!(
        "board: robimu firmware {}.{}.{}, protocol {}, BNO055 chip id {:#04x}, {} Hz",
        v[0], v[1], v[2], d.protocol_version, d.chip_id, d.config.sample_rate_hz
    );
    println!(
        "recorded {:.1} s into {}: {} IMU samples ({:.1} Hz), {} joint samples ({:.1} Hz)",
        s.duration,
        s.dir.display(),
        p.imu_samples,
        p.imu_samples as f64 / s.duration.max(1e-9),
        p.joint_samples,
        p.joint_samples as f64 / s.duration.max(1e-9)
    );
    println!(
        "link: {} sequence gaps, {} CRC errors, {} other bad frames, {} board restarts; the board dropped {}",
        p.seq_gaps, p.crc_errors, p.bad_frames, p.restarts, p.device_dropped
    );
    for (segment, f) in &s.clock {
        println!(
            "clock segment {segment}: device = session + {:.6} s, drift {:+.2} ppm, fit residual {:.1} µs ({} of {} echoes)",
            f.offset,
            f.drift_ppm(),
            f.residual_rms * 1e6,
            f.used,
            f.total
        );
    }
    if let Some(c) = &s.joint_clock {
        print_joint_clock(c);
    }
}

/// The joint times' controller clock mapping (UR), one line a segment.
pub fn print_joint_clock(clock: &robimu_record::repair::JointClock) {
    use robimu_record::repair::JointClock;
    match clock {
        JointClock::Mapped(fits) => {
            for (segment, f) in fits {
                println!(
                    "joint times from the controller clock, segment {segment}: controller = session + {:.6} s, drift {:+.2} ppm, arrival jitter {:.1} µs RMS ({} samples, {} of {} windows)",
                    f.offset,
                    f.drift_ppm(),
                    f.jitter_rms * 1e6,
                    f.samples,
                    f.windows_used,
                    f.windows
                );
            }
        }
        JointClock::Kept(why) => println!("joint times are host arrival times: {why}"),
    }
}
