//! `robimu record`: a session from an IMU board and a robot.

use std::path::PathBuf;

use anyhow::{bail, Context};
use robimu_protocol::{SensorConfig, SensorTiming};
use robimu_record::controller::RobotSpec;
use robimu_record::motion::Plan;
use robimu_record::RecordOptions;
/// Moved to [`robimu_report::recording::imu_lines`].
use robimu_report::recording::RecordSummaryText;

use robimu_workflows::plan::files::read_plan_table;

use crate::input::{record_with_progress, resolve_robot};

/// Record a session: stream the IMU board, poll the robot's joints, and
/// execute a plan on the robot.
///
/// Writes the session directory (docs/model.md §7) as it goes, flushed every
/// second; `robimu repair SESSION` finishes one cut short by a crash.
#[derive(Debug, Clone, clap::Args)]
pub struct RecordCmd {
    /// The IMU board's serial port (e.g. /dev/ttyUSB0); repeat for more
    /// boards (`--imu A --imu B`): every sensor of every board is an IMU of
    /// the session, board by board (imu.csv, imu1.csv, …; docs/model.md §9).
    #[arg(long, required = true)]
    pub imu: Vec<String>,
    /// Serial baud rate.
    #[arg(long, default_value_t = 921_600)]
    pub baud: u32,
    /// The robot controller: aubo:HOST[:PORT].
    #[arg(long)]
    pub robot: String,
    /// The robot's description: a built-in name (`robimu robots` lists
    /// them) or a TOML file.
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
    /// IMU sample rate, Hz [default: the rate the firmware's rule chooses
    /// for the bandwidths, so that reads do not alias the chip's internal
    /// updates: 150 Hz for the defaults; docs/model.md §4.8]. A rate
    /// whose alias margin is short is used, with a warning.
    #[arg(long)]
    pub rate: Option<u16>,
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
        for (i, port) in self.imu.iter().enumerate() {
            if self.imu[..i].contains(port) {
                bail!("--imu {port} is given twice: each board is read once");
            }
        }
        let defaults = SensorConfig::default();
        let rate = match self.rate {
            Some(rate) if !(1..=1000).contains(&rate) => {
                bail!("--rate must be in [1, 1000] Hz (got {rate})")
            }
            Some(rate) => rate,
            None => SensorTiming::of(&defaults).alias_free_rate().rate_hz,
        };
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
            imu_port: self.imu[0].clone(),
            extra_imu_ports: self.imu[1..].to_vec(),
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
                sample_rate_hz: rate,
                ..defaults
            },
            interrupt: None,
        })
    }

    /// Record, showing progress.
    pub fn run(self) -> anyhow::Result<()> {
        let opts = self.options()?;
        if let Some(warning) = robimu_record::alias_warning(&opts.sensor) {
            eprintln!("warning: {warning}");
        }
        let summary = record_with_progress(&opts)?;
        print!("{}", RecordSummaryText(&summary));
        print!("{}", robimu_report::recording::imu_lines(&summary));
        Ok(())
    }
}
