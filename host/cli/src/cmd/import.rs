//! `robimu import`: recordings of other tools as session directories.

use std::io::Write;
use std::path::PathBuf;

use anyhow::{bail, Context};
use robimu_session::import::csv::read_csv_pair;
use robimu_session::import::ros2::{read_ros2, PoseTopic, Ros2Options, TimeSource};
use robimu_session::import::{read_pose_csv_pair, Imported, Streams};
use robimu_session::{Orientation, PoseCsvOptions, PoseNoise, PoseSessionMeta, QuaternionOrder};
use robimu_workflows::import::{write_imported, ImportRobot};

/// The robot of a joint import without `--robot`.
const DEFAULT_ROBOT: &str = "aubo_i5";

/// Import a recording made with other tools as a session directory.
///
/// `ros2` (alias `mcap`): a ROS 2 bag — the rosbag2 directory `ros2 bag
/// record` writes (metadata.yaml, MCAP or sqlite3 storage, split files), or
/// one .mcap or .db3 file — with sensor_msgs/msg/JointState and
/// sensor_msgs/msg/Imu topics, or with `--poses TOPIC` tool poses
/// (PoseStamped, TransformStamped or tf) for a pose session. `csv`: an
/// EuRoC/Kalibr IMU CSV (timestamp [ns], gyroscope [rad/s], accelerometer
/// [m/s²]) and a joints CSV (timestamp [ns], one column per joint [rad]) on
/// the same clock. `poses`: a pose CSV with the user's columns and units and
/// an EuRoC/Kalibr IMU CSV, as a pose session (docs/model.md §7.9). The
/// earliest sample of either stream becomes t = 0.
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
    Poses(PosesCmd),
}

/// What every import writes.
#[derive(Debug, Clone, clap::Args)]
pub struct SessionArgs {
    /// Session directory to write (created if needed; session files in it are replaced).
    #[arg(long)]
    pub out: PathBuf,
    /// Robot: a built-in name (`robimu robots` lists them) or the path of a
    /// TOML robot description or a URDF; its joint count must match the
    /// joints imported [default: aubo_i5; none with --poses].
    #[arg(long)]
    pub robot: Option<String>,
}

/// Import a ROS 2 recording: a rosbag2 directory, or one .mcap or .db3 file
/// (CDR messages; zstd-compressed files and messages need the
/// `mcap-compression` feature).
#[derive(Debug, Clone, clap::Args)]
pub struct Ros2Cmd {
    /// The bag: a rosbag2 directory (with metadata.yaml), a .mcap or a .db3 file.
    pub file: PathBuf,
    /// Topic of sensor_msgs/msg/JointState [default: /joint_states].
    #[arg(long)]
    pub joints: Option<String>,
    /// A pose session (docs/model.md §7.9): topic of the posed body's poses,
    /// geometry_msgs/msg/PoseStamped, geometry_msgs/msg/TransformStamped or
    /// tf2_msgs/msg/TFMessage (/tf), in place of joint states.
    #[arg(long, alias = "pose-topic", value_name = "TOPIC")]
    pub poses: Option<String>,
    /// With --poses on transforms: the posed body's frame (the transforms'
    /// child_frame_id) [default: the one frame the topic has].
    #[arg(long, requires = "poses", value_name = "CHILD_FRAME_ID")]
    pub frame: Option<String>,
    /// Topic of sensor_msgs/msg/Imu.
    #[arg(long, default_value = "/imu/data_raw")]
    pub imu: String,
    /// Joints to import, in chain order (comma-separated names) [default:
    /// the robot's joint names, picked by name from each message whatever
    /// the driver's order, other joints such as a gripper's ignored; for a
    /// robot without joint names, those of the first joint message].
    #[arg(long, value_delimiter = ',', conflicts_with = "poses")]
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
        let motion = if out.pose_samples > 0 {
            format!("{} pose samples", out.pose_samples)
        } else if out.joint_names.is_empty() {
            format!("{} joint samples", out.joint_samples)
        } else {
            format!(
                "{} joint samples (joints {})",
                out.joint_samples,
                out.joint_names.join(", ")
            )
        };
        writeln!(
            std::io::stdout().lock(),
            "wrote {}: {motion}, {} IMU samples; t = 0 is source time {} ns",
            out.dir.display(),
            out.imu_samples,
            out.t0_ns
        )?;
        Ok(())
    }

    /// Import; what was written.
    pub fn write(&self) -> anyhow::Result<Imported> {
        match &self.format {
            ImportFormat::Ros2(c) if c.poses.is_some() => c.write_poses(),
            ImportFormat::Ros2(c) => c.write_joints(),
            ImportFormat::Csv(c) => c.write(),
            ImportFormat::Poses(c) => c.write(),
        }
    }
}

impl Ros2Cmd {
    /// The reader's options but the joints'.
    fn options(&self) -> Ros2Options {
        Ros2Options {
            joints_topic: self
                .joints
                .clone()
                .unwrap_or_else(|| "/joint_states".into()),
            imu_topic: self.imu.clone(),
            time: if self.time == "log" {
                TimeSource::Log
            } else {
                TimeSource::Header
            },
            joint_names: None,
            names_required: false,
            poses: self.poses.clone().map(|topic| PoseTopic {
                topic,
                frame: self.frame.clone(),
            }),
        }
    }

    /// A joint session.
    fn write_joints(&self) -> anyhow::Result<Imported> {
        let spec = self.session.robot.as_deref().unwrap_or(DEFAULT_ROBOT);
        let robot = ImportRobot::resolve(spec)?;
        let joints = robot.joints_by_name(self.joint_names.clone());
        let opts = Ros2Options {
            joint_names: joints.names.clone(),
            names_required: joints.given,
            ..self.options()
        };
        let s = read_ros2(&self.file, &opts).with_context(|| match &joints.names {
            Some(_) if !joints.given => format!(
                "cannot import {}: robot `{}`'s joints are picked by name from each JointState (choose others with --joint-names)",
                self.file.display(),
                robot.robot.name(),
            ),
            _ => format!("cannot import {}", self.file.display()),
        })?;
        write_imported(
            s,
            &self.session.out,
            robot,
            &self.file.display().to_string(),
        )
    }

    /// A pose session (--poses).
    fn write_poses(&self) -> anyhow::Result<Imported> {
        if let Some(flag) = [
            self.session.robot.as_ref().map(|_| "--robot"),
            self.joints.as_ref().map(|_| "--joints"),
        ]
        .into_iter()
        .flatten()
        .next()
        {
            bail!(
                "{flag}: not with --poses (a pose session has no robot and no joints; \
                 docs/model.md §7.9)"
            );
        }
        let streams = read_ros2(&self.file, &self.options())
            .with_context(|| format!("cannot import {}", self.file.display()))?;
        let source = match &streams.pose_frames {
            Some((parent, child)) if !child.is_empty() => {
                format!("{} (poses of {child} in {parent})", self.file.display())
            }
            Some((parent, _)) => format!("{} (poses in {parent})", self.file.display()),
            None => self.file.display().to_string(),
        };
        write_poses(
            streams,
            &self.session.out,
            &source,
            PoseSessionMeta::default(),
        )
    }
}

impl CsvCmd {
    fn write(&self) -> anyhow::Result<Imported> {
        let robot = ImportRobot::resolve(self.session.robot.as_deref().unwrap_or(DEFAULT_ROBOT))?;
        let s = read_csv_pair(&self.imu, &self.joints).with_context(|| {
            format!(
                "cannot import {} and {}",
                self.imu.display(),
                self.joints.display()
            )
        })?;
        let source = format!("{} + {}", self.imu.display(), self.joints.display());
        write_imported(s, &self.session.out, robot, &source)
    }
}

/// Import a pose CSV and an IMU CSV as a pose session (docs/model.md §7.9).
///
/// The pose file has a header naming its columns (or none: columns are
/// then given by 0-based index), one pose per row: a time, a position and
/// an orientation (a quaternion, Euler angles or a rotation vector) of the
/// posed body in a fixed frame. The IMU file is an EuRoC/Kalibr IMU CSV on
/// the same clock, as `import csv` reads it.
#[derive(Debug, Clone, clap::Args)]
pub struct PosesCmd {
    /// The pose CSV.
    pub poses: PathBuf,
    /// The IMU file (EuRoC imu0/data.csv or Kalibr imu.csv).
    #[arg(long)]
    pub imu: PathBuf,
    /// The time column (a header name, or a 0-based index).
    #[arg(long, default_value = "t", value_name = "COLUMN")]
    pub time_col: String,
    /// The unit of the time column.
    #[arg(long, default_value = "s", value_parser = ["s", "ms", "us", "ns"])]
    pub time_unit: String,
    /// The position's x, y, z columns.
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "px,py,pz",
        value_name = "X,Y,Z"
    )]
    pub position_cols: Vec<String>,
    /// The unit of the position.
    #[arg(long, default_value = "m", value_parser = ["m", "mm"])]
    pub units: String,
    /// The quaternion's four columns, in the file's order [default:
    /// qw,qx,qy,qz, or qx,qy,qz,qw with --quat-order xyzw].
    #[arg(long, value_delimiter = ',', value_name = "A,B,C,D")]
    pub quat_cols: Option<Vec<String>>,
    /// Which component each quaternion column holds: wxyz (MODEL.md, ABB)
    /// or xyzw (ROS, Eigen).
    #[arg(long, default_value = "wxyz", value_parser = ["wxyz", "xyzw"])]
    pub quat_order: String,
    /// Orientation as roll, pitch, yaw columns instead (R = Rz(yaw)·Ry(pitch)·Rx(roll);
    /// KUKA's A, B, C are yaw, pitch, roll); radians unless --euler-deg.
    #[arg(long, value_delimiter = ',', value_name = "ROLL,PITCH,YAW", conflicts_with_all = ["quat_cols", "rotvec_cols"])]
    pub euler_cols: Option<Vec<String>>,
    /// The Euler angles are in degrees.
    #[arg(long, requires = "euler_cols")]
    pub euler_deg: bool,
    /// Orientation as a rotation vector's columns instead (axis × angle, rad;
    /// Universal Robots' rx, ry, rz).
    #[arg(
        long,
        value_delimiter = ',',
        value_name = "RX,RY,RZ",
        conflicts_with = "quat_cols"
    )]
    pub rotvec_cols: Option<Vec<String>>,
    /// The file gives the fixed frame in the body (a camera's view of a
    /// target): each pose is inverted.
    #[arg(long, conflicts_with = "conjugate")]
    pub inverse: bool,
    /// The orientation is the inverse rotation (R_BW with the position of
    /// the body in the fixed frame, or JPL quaternions): each rotation is
    /// inverted, the position kept (what `robimu check` names as the
    /// inverse rotation convention).
    #[arg(long)]
    pub conjugate: bool,
    /// Pose noise: σ of each position component, m [default: the
    /// calibration's].
    #[arg(long)]
    pub sigma_p: Option<f64>,
    /// Pose noise: σ of the rotation error, rad [default: the calibration's].
    #[arg(long)]
    pub sigma_r: Option<f64>,
    /// Session directory to write (created if needed; session files in it are replaced).
    #[arg(long)]
    pub out: PathBuf,
}

impl PosesCmd {
    /// What the flags say of the pose file.
    pub fn options(&self) -> anyhow::Result<PoseCsvOptions> {
        let three = |flag: &str, v: &[String]| -> anyhow::Result<[String; 3]> {
            <[String; 3]>::try_from(v.to_vec())
                .map_err(|v| anyhow::anyhow!("{flag}: {} columns given, 3 needed", v.len()))
        };
        if self.euler_deg && self.euler_cols.is_none() {
            bail!("--euler-deg: give the Euler angles' columns with --euler-cols ROLL,PITCH,YAW");
        }
        let orientation = if let Some(c) = &self.euler_cols {
            Orientation::Euler {
                columns: three("--euler-cols", c)?,
                degrees: self.euler_deg,
            }
        } else if let Some(c) = &self.rotvec_cols {
            Orientation::RotationVector {
                columns: three("--rotvec-cols", c)?,
            }
        } else {
            let order = if self.quat_order == "xyzw" {
                QuaternionOrder::Xyzw
            } else {
                QuaternionOrder::Wxyz
            };
            let default = match order {
                QuaternionOrder::Wxyz => ["qw", "qx", "qy", "qz"],
                QuaternionOrder::Xyzw => ["qx", "qy", "qz", "qw"],
            };
            let cols = self
                .quat_cols
                .clone()
                .unwrap_or_else(|| default.map(String::from).to_vec());
            check_quaternion_names(&cols, &self.quat_order)?;
            let n = cols.len();
            Orientation::Quaternion {
                columns: <[String; 4]>::try_from(cols)
                    .map_err(|_| anyhow::anyhow!("--quat-cols: {n} columns given, 4 needed"))?,
                order,
            }
        };
        Ok(PoseCsvOptions {
            time: self.time_col.clone(),
            time_ns_per_unit: match self.time_unit.as_str() {
                "ms" => 1e6,
                "us" => 1e3,
                "ns" => 1.0,
                _ => 1e9,
            },
            position: three("--position-cols", &self.position_cols)?,
            metres_per_unit: if self.units == "mm" { 1e-3 } else { 1.0 },
            orientation,
            inverse: self.inverse,
            conjugate: self.conjugate,
        })
    }

    fn write(&self) -> anyhow::Result<Imported> {
        let noise = [self.sigma_p, self.sigma_r];
        if let Some(v) = noise
            .into_iter()
            .flatten()
            .find(|v| !(v.is_finite() && *v > 0.0))
        {
            bail!("--sigma-p/--sigma-r: {v} is not a positive standard deviation");
        }
        let meta = PoseSessionMeta {
            poses: (self.sigma_p.is_some() || self.sigma_r.is_some()).then_some(PoseNoise {
                sigma_p: self.sigma_p,
                sigma_r: self.sigma_r,
            }),
            ..PoseSessionMeta::default()
        };
        let streams =
            read_pose_csv_pair(&self.poses, &self.options()?, &self.imu).with_context(|| {
                format!(
                    "cannot import {} and {}",
                    self.poses.display(),
                    self.imu.display()
                )
            })?;
        let source = format!("{} + {}", self.poses.display(), self.imu.display());
        write_poses(streams, &self.out, &source, meta)
    }
}

/// Refuses quaternion columns whose names say another order than
/// `--quat-order` (`q_x,q_y,q_z,q_w` read as w, x, y, z would be a wrong
/// rotation, silently): each name's last letter w, x, y or z, all four
/// different, in another order.
fn check_quaternion_names(cols: &[String], order: &str) -> anyhow::Result<()> {
    let letters: String = cols
        .iter()
        .filter_map(|c| c.chars().last().map(|l| l.to_ascii_lowercase()))
        .filter(|l| "wxyz".contains(*l))
        .collect();
    let distinct = letters.len() == 4 && "wxyz".chars().all(|l| letters.contains(l));
    if distinct && letters != order {
        bail!(
            "--quat-cols {}: the names say the order {letters}, and --quat-order is {order}: \
             pass --quat-order {letters} (or give the columns by index if the names are wrong)",
            cols.join(",")
        );
    }
    Ok(())
}

/// Write `streams`, read from `source` (named in the notes), as the pose
/// session `out` with `meta`.
fn write_poses(
    streams: Streams,
    out: &std::path::Path,
    source: &str,
    mut meta: PoseSessionMeta,
) -> anyhow::Result<Imported> {
    meta.notes = Some(format!("imported from {source}"));
    streams
        .write_pose_session(out, &meta)
        .with_context(|| format!("cannot write the session {}", out.display()))
}
