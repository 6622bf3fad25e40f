//! `robimu import`: recordings of other tools as session directories.

use std::io::Write;
use std::path::PathBuf;

use anyhow::Context;
use robimu_session::import::csv::read_csv_pair;
use robimu_session::import::ros2::{read_ros2, Ros2Options, TimeSource};
use robimu_session::import::Imported;
use robimu_workflows::import::{write_imported, ImportRobot};

/// Import a recording made with other tools as a session directory.
///
/// `ros2` (alias `mcap`): a ROS 2 bag — the rosbag2 directory `ros2 bag
/// record` writes (metadata.yaml, MCAP or sqlite3 storage, split files), or
/// one .mcap or .db3 file — with sensor_msgs/msg/JointState and
/// sensor_msgs/msg/Imu topics. `csv`: an EuRoC/Kalibr IMU CSV
/// (timestamp [ns], gyroscope [rad/s], accelerometer [m/s²]) and a joints
/// CSV (timestamp [ns], one column per joint [rad]) on the same clock.
/// The earliest sample of either stream becomes t = 0.
#[derive(Debug, Clone, clap::Args)]
pub struct ImportCmd {
    #[command(subcommand)]
    pub format: ImportFormat,
}

/// The source format.
#[derive(Debug, Clone, clap::Subcommand)]
pub enum ImportFormat {
    #[command(alias = "mcap")]
    Ros2(Ros2Cmd),
    Csv(CsvCmd),
}

/// What every import writes.
#[derive(Debug, Clone, clap::Args)]
pub struct SessionArgs {
    /// Session directory to write (created if needed; session files in it are replaced).
    #[arg(long)]
    pub out: PathBuf,
    /// Robot: a built-in name (`robimu robots` lists them) or the path of a
    /// TOML robot description or a URDF; its joint count must match the
    /// joints imported.
    #[arg(long, default_value = "aubo_i5")]
    pub robot: String,
}

/// Import a ROS 2 recording: a rosbag2 directory, or one .mcap or .db3 file
/// (CDR messages; zstd-compressed files and messages need the
/// `mcap-compression` feature).
#[derive(Debug, Clone, clap::Args)]
pub struct Ros2Cmd {
    /// The bag: a rosbag2 directory (with metadata.yaml), a .mcap or a .db3 file.
    pub file: PathBuf,
    /// Topic of sensor_msgs/msg/JointState.
    #[arg(long, default_value = "/joint_states")]
    pub joints: String,
    /// Topic of sensor_msgs/msg/Imu.
    #[arg(long, default_value = "/imu/data_raw")]
    pub imu: String,
    /// Joints to import, in chain order (comma-separated names) [default:
    /// the robot's joint names, picked by name from each message whatever
    /// the driver's order, other joints such as a gripper's ignored; for a
    /// robot without joint names, those of the first joint message].
    #[arg(long, value_delimiter = ',')]
    pub joint_names: Option<Vec<String>>,
    /// Sample times: `header` (the messages' header.stamp) or `log` (when
    /// the recorder received them).
    #[arg(long, default_value = "header", value_parser = ["header", "log"])]
    pub time: String,
    #[command(flatten)]
    pub session: SessionArgs,
}

/// Import an EuRoC/Kalibr IMU CSV and a joints CSV.
#[derive(Debug, Clone, clap::Args)]
pub struct CsvCmd {
    /// The IMU file (EuRoC imu0/data.csv or Kalibr imu.csv).
    pub imu: PathBuf,
    /// The joints file: timestamp [ns] then one column per joint [rad].
    #[arg(long)]
    pub joints: PathBuf,
    #[command(flatten)]
    pub session: SessionArgs,
}

impl ImportCmd {
    /// Import and print what was written.
    pub fn run(self) -> anyhow::Result<()> {
        let out = self.write()?;
        let names = if out.joint_names.is_empty() {
            String::new()
        } else {
            format!(" (joints {})", out.joint_names.join(", "))
        };
        writeln!(
            std::io::stdout().lock(),
            "wrote {}: {} joint samples{names}, {} IMU samples; t = 0 is source time {} ns",
            out.dir.display(),
            out.joint_samples,
            out.imu_samples,
            out.t0_ns
        )?;
        Ok(())
    }

    /// Import; what was written.
    pub fn write(&self) -> anyhow::Result<Imported> {
        let session = match &self.format {
            ImportFormat::Ros2(c) => &c.session,
            ImportFormat::Csv(c) => &c.session,
        };
        let robot = ImportRobot::resolve(&session.robot)?;
        let (streams, source) = match &self.format {
            ImportFormat::Ros2(c) => {
                let joints = robot.joints_by_name(c.joint_names.clone());
                let opts = Ros2Options {
                    joints_topic: c.joints.clone(),
                    imu_topic: c.imu.clone(),
                    time: if c.time == "log" {
                        TimeSource::Log
                    } else {
                        TimeSource::Header
                    },
                    joint_names: joints.names.clone(),
                    names_required: joints.given,
                };
                let s = read_ros2(&c.file, &opts).with_context(|| match &joints.names {
                    Some(_) if !joints.given => format!(
                        "cannot import {}: robot `{}`'s joints are picked by name from each JointState (choose others with --joint-names)",
                        c.file.display(),
                        robot.robot.name(),
                    ),
                    _ => format!("cannot import {}", c.file.display()),
                })?;
                (s, c.file.display().to_string())
            }
            ImportFormat::Csv(c) => {
                let s = read_csv_pair(&c.imu, &c.joints).with_context(|| {
                    format!(
                        "cannot import {} and {}",
                        c.imu.display(),
                        c.joints.display()
                    )
                })?;
                (s, format!("{} + {}", c.imu.display(), c.joints.display()))
            }
        };
        write_imported(streams, &session.out, robot, &source)
    }
}
