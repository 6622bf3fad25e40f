//! Importing recordings made by other tools as session directories
//! (docs/model.md §7).
//!
//! * `ros2` (feature `ros2`): ROS 2 recordings (`sensor_msgs/msg/JointState`
//!   and `sensor_msgs/msg/Imu` in CDR, decoded by [`cdr`]): a rosbag2
//!   directory or one storage file, MCAP (`mcap`) or sqlite3 (`sqlite3`,
//!   feature `sqlite3`).
//! * `pose_csv` ([`crate::read_pose_csv`], [`read_pose_csv_pair`]): a pose
//!   stream (a controller's TCP poses, motion capture) from a CSV with the
//!   user's columns and units, with an IMU CSV, for pose sessions
//!   (MODEL.md §10); `ros2` reads the poses of a pose session from
//!   `geometry_msgs` PoseStamped or TransformStamped, or `/tf`.
//! * [`csv`]: an EuRoC/Kalibr IMU CSV (`#timestamp [ns],w_RS_S_x [rad s^-1],…,
//!   a_RS_S_x [m s^-2],…`) with a joints CSV on the same clock.
//!
//! All read integer nanosecond timestamps into [`Streams`];
//! [`Streams::write_session`] sorts them, takes the earliest sample of
//! either stream as t = 0 (subtracting in integer nanoseconds, so that epoch
//! times keep their resolution) and writes `joints.csv` and `imu.csv` with
//! the IMU columns in the session's order `ax, ay, az, gx, gy, gz`;
//! [`Streams::write_pose_session`] does the same with `poses.csv`.

pub mod cdr;
#[cfg(feature = "ros2")]
mod collect;
pub mod csv;
#[cfg(feature = "ros2")]
mod mcap;
pub(crate) mod pose_csv;
#[cfg(feature = "ros2")]
pub mod ros2;
#[cfg(feature = "sqlite3")]
mod sqlite3;

use std::path::{Path, PathBuf};

pub use pose_csv::read_pose_csv_pair;

use crate::{
    PoseRows, PoseSessionMeta, PoseSessionWriter, SessionError, SessionMeta, SessionWriter,
    MAX_POSITION,
};

/// Why a recording could not be imported.
#[derive(Debug, thiserror::Error)]
pub enum ImportError {
    /// The file could not be read.
    #[error("cannot read {}: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The operating system's error.
        #[source]
        source: std::io::Error,
    },
    /// The MCAP container is unreadable (truncated, bad magic, compressed
    /// with a codec this build lacks, …).
    #[cfg(feature = "ros2")]
    #[error("{}: not a readable MCAP file: {source}{hint}", path.display())]
    Mcap {
        /// The file.
        path: PathBuf,
        /// The mcap crate's error.
        #[source]
        source: ::mcap::McapError,
        /// What to do about it, when known.
        hint: String,
    },
    /// A rosbag2 bag or storage file that cannot be read (metadata.yaml,
    /// a sqlite3 database, a storage this build does not read, …).
    #[error("{}: {detail}", path.display())]
    Bag {
        /// The file or directory.
        path: PathBuf,
        /// What is wrong, and what to do.
        detail: String,
    },
    /// Compressed data this build cannot (or could not) decompress.
    #[error("{}: {detail}", path.display())]
    Compressed {
        /// The file or bag.
        path: PathBuf,
        /// What is wrong, and what to do.
        detail: String,
    },
    /// A requested topic is not in the recording.
    #[error("{}: no topic {topic} (topics in the bag: {available})", path.display())]
    MissingTopic {
        /// The file.
        path: PathBuf,
        /// The topic asked for.
        topic: String,
        /// The topics there are, with their types.
        available: String,
    },
    /// A topic carries another message type or encoding.
    #[error("{}: topic {topic}: {detail}", path.display())]
    WrongType {
        /// The file.
        path: PathBuf,
        /// The topic.
        topic: String,
        /// Expected and found.
        detail: String,
    },
    /// A message could not be decoded.
    #[error("{}: topic {topic}, message {index} (log time {log_time} ns): {source}", path.display())]
    Message {
        /// The file.
        path: PathBuf,
        /// The topic.
        topic: String,
        /// 0-based index of the message on its topic.
        index: usize,
        /// Its log time.
        log_time: u64,
        /// The decoder's error.
        #[source]
        source: cdr::CdrError,
    },
    /// A decoded sample that cannot be a measurement (a value not finite, a
    /// stamp zero or negative, stepping back, or spanning more than 24 h).
    #[error("{}: topic {topic}, message {index} (log time {log_time} ns): {detail}", path.display())]
    Sample {
        /// The file.
        path: PathBuf,
        /// The topic.
        topic: String,
        /// 0-based index of the message on its topic.
        index: usize,
        /// Its log time.
        log_time: u64,
        /// What is wrong.
        detail: String,
    },
    /// A joint message does not fit the joints chosen.
    #[error("{}: {detail}", path.display())]
    Joints {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        detail: String,
    },
    /// Poses that cannot be a pose session's (docs/model.md §7.9).
    #[error("{}: {detail}", path.display())]
    Poses {
        /// The file or session.
        path: PathBuf,
        /// What is wrong.
        detail: String,
    },
    /// A CSV line is malformed.
    #[error("{}:{line}: {detail}", path.display())]
    Line {
        /// The file.
        path: PathBuf,
        /// 1-based line number.
        line: u64,
        /// What is wrong.
        detail: String,
    },
    /// A file or topic gave no samples.
    #[error("{what}: no samples")]
    Empty {
        /// The file or topic.
        what: String,
    },
    /// The session could not be written.
    #[error(transparent)]
    Session(#[from] SessionError),
}

/// The longest recording imported: 24 h, in ns (a longer span means a
/// stamp is corrupted).
pub(crate) const MAX_SPAN_NS: i64 = 24 * 3600 * 1_000_000_000;

/// How far (ns) a topic's stamps may step back: 1 s (more is a corrupted
/// or zeroed stamp, not publishers' jitter).
#[cfg(feature = "ros2")]
pub(crate) const MAX_BACKSTEP_NS: i64 = 1_000_000_000;

/// Joint samples: time (ns), positions (rad).
pub(crate) type JointRows = Vec<(i64, Vec<f64>)>;

/// The two sample streams of a recording, on one clock in integer ns.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Streams {
    /// Joint samples: time (ns), positions (rad), in the order of
    /// [`Streams::joint_names`].
    pub joints: JointRows,
    /// IMU samples: time (ns), `[ax, ay, az, gx, gy, gz]` (m/s², rad/s).
    pub imu: Vec<(i64, [f64; 6])>,
    /// Joint names, when the source has them.
    pub joint_names: Vec<String>,
    /// Tool poses, in place of joints (a pose session, docs/model.md §7.9).
    pub poses: PoseRows,
    /// The frames of the poses, when the source names them: (the fixed
    /// frame, the posed body's frame).
    pub pose_frames: Option<(String, String)>,
}

/// What [`Streams::write_session`] wrote.
#[derive(Debug, Clone, PartialEq)]
pub struct Imported {
    /// The session directory.
    pub dir: PathBuf,
    /// Joint samples written.
    pub joint_samples: usize,
    /// Pose samples written (a pose session).
    pub pose_samples: usize,
    /// IMU samples written.
    pub imu_samples: usize,
    /// Joints per sample.
    pub joint_count: usize,
    /// The source time (ns) that became t = 0.
    pub t0_ns: i64,
    /// Joint names, when the source has them.
    pub joint_names: Vec<String>,
}

impl Streams {
    /// Sorts both streams by time and writes them as the session `dir` with
    /// `meta` (existing session files in `dir` are replaced).
    pub fn write_session(
        mut self,
        dir: &Path,
        meta: &SessionMeta,
    ) -> Result<Imported, ImportError> {
        if self.joints.is_empty() {
            return Err(ImportError::Empty {
                what: "joint stream".into(),
            });
        }
        if self.imu.is_empty() {
            return Err(ImportError::Empty {
                what: "IMU stream".into(),
            });
        }
        self.joints.sort_by_key(|s| s.0);
        self.imu.sort_by_key(|s| s.0);
        let t0 = self.joints[0].0.min(self.imu[0].0);
        // (the readers bound the span; i128 keeps any pair of i64 exact)
        let seconds = |ns: i64| (i128::from(ns) - i128::from(t0)) as f64 * 1e-9;
        let joint_count = self.joints[0].1.len();
        let mut w = SessionWriter::create(dir, meta, joint_count)?;
        for (t, q) in &self.joints {
            w.joint(seconds(*t), q)?;
        }
        for (t, z) in &self.imu {
            w.imu(seconds(*t), z)?;
        }
        let dir = w.finish()?;
        Ok(Imported {
            dir,
            joint_samples: self.joints.len(),
            pose_samples: 0,
            imu_samples: self.imu.len(),
            joint_count,
            t0_ns: t0,
            joint_names: self.joint_names,
        })
    }
}

impl Streams {
    /// Sorts the poses and IMU samples by time and writes them as the pose
    /// session `dir` with `meta` (docs/model.md §7.9; existing session files
    /// in `dir` are replaced). A position beyond [`MAX_POSITION`] m is
    /// refused (not metres).
    pub fn write_pose_session(
        mut self,
        dir: &Path,
        meta: &PoseSessionMeta,
    ) -> Result<Imported, ImportError> {
        let n = self.poses.t_ns.len();
        if n == 0 {
            return Err(ImportError::Empty {
                what: "pose stream".into(),
            });
        }
        if self.imu.is_empty() {
            return Err(ImportError::Empty {
                what: "IMU stream".into(),
            });
        }
        let mut order: Vec<usize> = (0..n).collect();
        order.sort_by_key(|&k| self.poses.t_ns[k]);
        self.imu.sort_by_key(|s| s.0);
        let poses = &self.poses;
        if let Some(&k) = order
            .iter()
            .find(|&&k| poses.p[k].iter().any(|v| v.abs() > MAX_POSITION))
        {
            return Err(ImportError::Poses {
                path: dir.to_path_buf(),
                detail: format!(
                    "pose {k} has position {:?} m, beyond {MAX_POSITION} m: not metres (a file in \
                     mm needs --units mm)",
                    poses.p[k]
                ),
            });
        }
        let t0 = poses.t_ns[order[0]].min(self.imu[0].0);
        let seconds = |ns: i64| (i128::from(ns) - i128::from(t0)) as f64 * 1e-9;
        let mut w = PoseSessionWriter::create(dir, meta)?;
        for &k in &order {
            w.pose(seconds(poses.t_ns[k]), &poses.p[k], &poses.q[k])?;
        }
        for (t, z) in &self.imu {
            w.imu(seconds(*t), z)?;
        }
        let dir = w.finish()?;
        Ok(Imported {
            dir,
            joint_samples: 0,
            pose_samples: n,
            imu_samples: self.imu.len(),
            joint_count: 0,
            t0_ns: t0,
            joint_names: Vec::new(),
        })
    }
}

/// An IMU sample in the session's order from the sensor's gyro and
/// accelerometer vectors.
pub(crate) fn imu_row(gyro: [f64; 3], acc: [f64; 3]) -> [f64; 6] {
    [acc[0], acc[1], acc[2], gyro[0], gyro[1], gyro[2]]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Session;

    #[test]
    fn epoch_nanoseconds_keep_their_resolution_and_order() {
        let dir = tempfile::tempdir().unwrap();
        let base = 1_700_000_000_123_456_789_i64;
        let streams = Streams {
            // out of order on purpose
            joints: vec![(base + 2_000_001, vec![0.2]), (base + 1, vec![0.1])],
            imu: vec![(base, imu_row([4.0, 5.0, 6.0], [1.0, 2.0, 3.0]))],
            joint_names: vec!["a".into()],
            ..Streams::default()
        };
        let out = streams
            .write_session(dir.path(), &SessionMeta::new("aubo_i5"))
            .unwrap();
        assert_eq!(
            (out.t0_ns, out.joint_samples, out.imu_samples),
            (base, 2, 1)
        );
        let s = Session::load(dir.path()).unwrap();
        // 1 ns after an epoch time of 1.7e18 ns survives the subtraction.
        assert_eq!(s.joints.t, vec![1e-9, 2_000_001.0 * 1e-9]);
        assert_eq!(s.joints.row(1), [0.2]);
        assert_eq!(s.imu.row(0), [1.0, 2.0, 3.0, 4.0, 5.0, 6.0]);
        let e = Streams::default()
            .write_session(dir.path(), &SessionMeta::new("aubo_i5"))
            .unwrap_err();
        assert!(e.to_string().contains("joint stream: no samples"), "{e}");
    }

    /// Poses sorted with their rows kept together, epoch times kept to the
    /// ns, and positions beyond 10⁴ m refused naming --units mm.
    #[test]
    fn pose_streams_write_a_pose_session() {
        use crate::{PoseSession, PoseSessionMeta};
        let dir = tempfile::tempdir().unwrap();
        let base = 1_700_000_000_123_456_789_i64;
        let h = std::f64::consts::FRAC_1_SQRT_2;
        let mut streams = Streams {
            imu: vec![(base + 3, imu_row([0.0; 3], [0.0, 0.0, 9.81]))],
            poses: PoseRows {
                t_ns: vec![base + 2_000_000, base + 1],
                p: vec![[0.2, 0.0, 0.0], [0.1, 0.0, 0.0]],
                q: vec![[h, h, 0.0, 0.0], [1.0, 0.0, 0.0, 0.0]],
            },
            ..Streams::default()
        };
        let out = streams
            .clone()
            .write_pose_session(dir.path(), &PoseSessionMeta::default())
            .unwrap();
        assert_eq!(
            (out.pose_samples, out.imu_samples, out.t0_ns),
            (2, 1, base + 1)
        );
        let s = PoseSession::read(dir.path()).unwrap();
        assert_eq!(s.poses.t, vec![0.0, 1_999_999.0 * 1e-9]);
        assert_eq!(s.positions(), vec![[0.1, 0.0, 0.0], [0.2, 0.0, 0.0]]);
        assert_eq!(s.quaternions()[1], [h, h, 0.0, 0.0]);
        assert_eq!(s.imus[0].samples.t, vec![2e-9]);
        streams.poses.p[1][2] = 2e4;
        let e = streams
            .write_pose_session(dir.path(), &PoseSessionMeta::default())
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("pose 1 has position") && e.contains("--units mm"),
            "{e}"
        );
        let e = Streams::default()
            .write_pose_session(dir.path(), &PoseSessionMeta::default())
            .unwrap_err();
        assert!(e.to_string().contains("pose stream: no samples"), "{e}");
    }
}
