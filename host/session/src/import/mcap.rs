//! ROS 2 recordings in MCAP: `sensor_msgs/msg/JointState` and
//! `sensor_msgs/msg/Imu` on two topics.
//!
//! A rosbag2 MCAP file (the `ros2` profile) has one channel per topic with
//! message encoding `cdr` and a schema named by the message type
//! (`sensor_msgs/msg/Imu`) with encoding `ros2msg` (or `ros2idl`). Messages
//! are read in file order; each is decoded by [`super::cdr`]. Sample times
//! are the messages' `header.stamp` ([`TimeSource::Header`], the time the
//! driver gave the measurement) or the recorder's log time
//! ([`TimeSource::Log`], for drivers that leave the stamp zero).
//!
//! Chunks compressed with zstd or lz4 need the `mcap-compression` feature;
//! without it such a file is refused with that advice.

use std::collections::BTreeMap;
use std::path::Path;

use ::mcap::{McapError, MessageStream};

use super::cdr::{ImuMsg, JointStateMsg};
use super::{imu_row, ImportError, Streams};

/// Schema name of joint states.
pub const JOINT_STATE: &str = "sensor_msgs/msg/JointState";
/// Schema name of IMU samples.
pub const IMU: &str = "sensor_msgs/msg/Imu";

/// Which timestamp a sample gets.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum TimeSource {
    /// The message's `header.stamp`.
    #[default]
    Header,
    /// The MCAP log time (when the recorder received it).
    Log,
}

/// What to read from an MCAP file.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct McapOptions {
    /// Topic of `sensor_msgs/msg/JointState`.
    pub joints_topic: String,
    /// Topic of `sensor_msgs/msg/Imu`.
    pub imu_topic: String,
    /// Which timestamp to use.
    pub time: TimeSource,
    /// The joints to import, in this order (default: the names of the first
    /// joint message, in its order).
    pub joint_names: Option<Vec<String>>,
}

/// A topic seen in the file.
#[derive(Debug, Default)]
struct TopicInfo {
    schema: String,
    messages: usize,
}

/// Reads the joint and IMU streams of the MCAP file at `path`.
pub fn read_mcap(path: &Path, opts: &McapOptions) -> Result<Streams, ImportError> {
    let bytes = std::fs::read(path).map_err(|source| ImportError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    let mcap_error = |source: McapError| {
        let hint = match &source {
            McapError::UnsupportedCompression(c) => format!(
                " (chunks compressed with {c}: build robimu with `--features mcap-compression`, \
                 or rewrite the file uncompressed)"
            ),
            McapError::BadMagic
            | McapError::UnexpectedEof
            | McapError::UnexpectedEoc
            | McapError::BadChunkLength { .. } => {
                " (the file is truncated or not MCAP; a recording that was killed can be \
                 repaired with `mcap recover`)"
                    .to_string()
            }
            _ => String::new(),
        };
        ImportError::Mcap {
            path: path.to_path_buf(),
            source,
            hint,
        }
    };
    let stream = MessageStream::new(&bytes).map_err(mcap_error)?;
    let mut topics: BTreeMap<String, TopicInfo> = BTreeMap::new();
    let mut joints = JointPicker::new(path, opts.joint_names.clone());
    let mut out = Streams::default();
    let mut stamps_advance = (None::<i64>, false, None::<i64>, false);
    for message in stream {
        let message = message.map_err(mcap_error)?;
        let channel = &message.channel;
        let info = topics.entry(channel.topic.clone()).or_default();
        info.messages += 1;
        let index = info.messages - 1;
        let schema = channel.schema.as_ref();
        if info.schema.is_empty() {
            info.schema = schema.map_or("(no schema)".into(), |s| s.name.clone());
        }
        let wanted = if channel.topic == opts.joints_topic {
            JOINT_STATE
        } else if channel.topic == opts.imu_topic {
            IMU
        } else {
            continue;
        };
        if index == 0 {
            check_channel(path, channel, wanted)?;
        }
        let decode_error = |source| ImportError::Message {
            path: path.to_path_buf(),
            topic: channel.topic.clone(),
            index,
            log_time: message.log_time,
            source,
        };
        let log_time = i64::try_from(message.log_time).unwrap_or(i64::MAX);
        if wanted == JOINT_STATE {
            let m = JointStateMsg::decode(&message.data).map_err(decode_error)?;
            let t = match opts.time {
                TimeSource::Header => m.stamp.0,
                TimeSource::Log => log_time,
            };
            advance(&mut stamps_advance.0, &mut stamps_advance.1, t);
            if let Some(q) = joints.pick(&m, index)? {
                out.joints.push((t, q));
            }
        } else {
            let m = ImuMsg::decode(&message.data).map_err(decode_error)?;
            let t = match opts.time {
                TimeSource::Header => m.stamp.0,
                TimeSource::Log => log_time,
            };
            advance(&mut stamps_advance.2, &mut stamps_advance.3, t);
            out.imu
                .push((t, imu_row(m.angular_velocity, m.linear_acceleration)));
        }
    }
    for (topic, wanted) in [(&opts.joints_topic, JOINT_STATE), (&opts.imu_topic, IMU)] {
        if !topics.contains_key(topic) {
            let available = if topics.is_empty() {
                "none".to_string()
            } else {
                topics
                    .iter()
                    .map(|(t, i)| format!("{t} [{}, {} messages]", i.schema, i.messages))
                    .collect::<Vec<_>>()
                    .join(", ")
            };
            return Err(ImportError::MissingTopic {
                path: path.to_path_buf(),
                topic: format!("{topic} ({wanted})"),
                available,
            });
        }
    }
    let frozen = [
        (
            &opts.joints_topic,
            stamps_advance.0,
            stamps_advance.1,
            out.joints.len(),
        ),
        (
            &opts.imu_topic,
            stamps_advance.2,
            stamps_advance.3,
            out.imu.len(),
        ),
    ];
    for (topic, first, moved, n) in frozen {
        if opts.time == TimeSource::Header && n > 1 && !moved {
            return Err(ImportError::WrongType {
                path: path.to_path_buf(),
                topic: topic.clone(),
                detail: format!(
                    "every header.stamp is {} ns: the driver does not stamp its messages (use --time log)",
                    first.unwrap_or(0)
                ),
            });
        }
    }
    if out.joints.is_empty() {
        return Err(ImportError::Joints {
            path: path.to_path_buf(),
            detail: format!(
                "no message on {} has all of the joints {:?} ({} skipped)",
                opts.joints_topic,
                joints.names.clone().unwrap_or_default(),
                joints.skipped
            ),
        });
    }
    out.joint_names = joints.names.unwrap_or_default();
    Ok(out)
}

/// Tracks whether a stream's times ever change.
fn advance(first: &mut Option<i64>, moved: &mut bool, t: i64) {
    match first {
        None => *first = Some(t),
        Some(f) if *f != t => *moved = true,
        _ => {}
    }
}

fn check_channel(
    path: &Path,
    channel: &::mcap::Channel<'_>,
    wanted: &str,
) -> Result<(), ImportError> {
    let wrong = |detail: String| ImportError::WrongType {
        path: path.to_path_buf(),
        topic: channel.topic.clone(),
        detail,
    };
    let Some(schema) = channel.schema.as_ref() else {
        return Err(wrong(format!("has no schema, expected {wanted}")));
    };
    if schema.name != wanted {
        return Err(wrong(format!("carries {}, expected {wanted}", schema.name)));
    }
    if !matches!(schema.encoding.as_str(), "ros2msg" | "ros2idl") {
        return Err(wrong(format!(
            "schema encoding is {:?}, expected \"ros2msg\" (a ROS 2 recording)",
            schema.encoding
        )));
    }
    if channel.message_encoding != "cdr" {
        return Err(wrong(format!(
            "message encoding is {:?}, expected \"cdr\"",
            channel.message_encoding
        )));
    }
    Ok(())
}

/// Chooses the joints from each `JointState`.
struct JointPicker<'a> {
    path: &'a Path,
    /// The joints to import (`None` until the first message when not given).
    names: Option<Vec<String>>,
    /// Width of positional (unnamed) messages.
    width: Option<usize>,
    skipped: usize,
}

impl<'a> JointPicker<'a> {
    fn new(path: &'a Path, names: Option<Vec<String>>) -> Self {
        Self {
            path,
            names,
            width: None,
            skipped: 0,
        }
    }

    /// The positions of the chosen joints, `None` when the message lacks
    /// one of them (a message of another joint group on the same topic).
    fn pick(&mut self, m: &JointStateMsg, index: usize) -> Result<Option<Vec<f64>>, ImportError> {
        if !m.name.is_empty() && m.name.len() != m.position.len() {
            return Err(ImportError::Joints {
                path: self.path.to_path_buf(),
                detail: format!(
                    "joint message {index} has {} names but {} positions",
                    m.name.len(),
                    m.position.len()
                ),
            });
        }
        if m.name.is_empty() {
            // Positional: every message must have the same width.
            if let Some(names) = &self.names {
                return Err(ImportError::Joints {
                    path: self.path.to_path_buf(),
                    detail: format!(
                        "joint message {index} has no joint names, so joints {names:?} cannot be picked"
                    ),
                });
            }
            let width = *self.width.get_or_insert(m.position.len());
            if m.position.len() != width || width == 0 {
                self.skipped += 1;
                return Ok(None);
            }
            return Ok(Some(m.position.clone()));
        }
        let names = self.names.get_or_insert_with(|| m.name.clone());
        let mut q = Vec::with_capacity(names.len());
        for n in names.iter() {
            match m.name.iter().position(|x| x == n) {
                Some(i) => q.push(m.position[i]),
                None => {
                    self.skipped += 1;
                    return Ok(None);
                }
            }
        }
        Ok(Some(q))
    }
}
