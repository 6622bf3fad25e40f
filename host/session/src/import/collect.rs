//! The one decoding path of ROS 2 recordings ([`super::ros2`]): every
//! storage (MCAP, sqlite3) hands each message — (topic, type, log time, CDR
//! bytes) — to a [`Collector`], which decodes the two topics asked for
//! ([`super::cdr`]) into [`Streams`] (docs/model.md §7): joint states or
//! tool poses (`PoseStamped`, `TransformStamped` or `/tf`'s `TFMessage`, for
//! a pose session, docs/model.md §7.9), and IMU samples.

use std::borrow::Cow;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use super::cdr::{CdrError, ImuMsg, JointStateMsg, PoseMsg};
use super::{imu_row, ImportError, Streams, MAX_BACKSTEP_NS, MAX_SPAN_NS};
use crate::MIN_QUATERNION_NORM;

/// Type name of joint states.
pub const JOINT_STATE: &str = "sensor_msgs/msg/JointState";
/// Type name of IMU samples.
pub const IMU: &str = "sensor_msgs/msg/Imu";
/// Type name of stamped poses.
pub const POSE_STAMPED: &str = "geometry_msgs/msg/PoseStamped";
/// Type name of one stamped transform.
pub const TRANSFORM_STAMPED: &str = "geometry_msgs/msg/TransformStamped";
/// Type name of `/tf`'s lists of transforms.
pub const TF_MESSAGE: &str = "tf2_msgs/msg/TFMessage";
/// The cargo feature that reads compressed recordings.
pub const COMPRESSION_FEATURE: &str = "mcap-compression";

/// Which timestamp a sample gets.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum TimeSource {
    /// The message's `header.stamp`.
    #[default]
    Header,
    /// The log time (when the recorder received it).
    Log,
}

/// What to read from a ROS 2 recording.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Ros2Options {
    /// Topic of `sensor_msgs/msg/JointState`.
    pub joints_topic: String,
    /// Topic of `sensor_msgs/msg/Imu`.
    pub imu_topic: String,
    /// Which timestamp to use.
    pub time: TimeSource,
    /// The joints to import, in this order, picked from each message by
    /// name (other joints, such as a gripper's, are ignored); default: the
    /// names of the first joint message, in its order.
    pub joint_names: Option<Vec<String>>,
    /// Whether a message without joint names is refused when `joint_names`
    /// is set (the user chose the joints) or taken as it is (`joint_names`
    /// are the robot's chain, and an unnamed message is taken to be in
    /// chain order).
    pub names_required: bool,
    /// A pose session (docs/model.md §7.9): the motion is read from this
    /// topic of tool poses instead of `joints_topic`.
    pub poses: Option<PoseTopic>,
}

/// The topic of tool poses of a pose session.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PoseTopic {
    /// Topic of `geometry_msgs/msg/PoseStamped`, `…/TransformStamped` or
    /// `tf2_msgs/msg/TFMessage`.
    pub topic: String,
    /// The transform to take (its `child_frame_id`) [default: the one frame
    /// the topic's transforms have].
    pub frame: Option<String>,
}

/// Which stream a topic feeds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Stream {
    Joints,
    Poses,
    Imu,
}

impl Stream {
    /// The message types the stream's topic may carry.
    pub(crate) fn types(self) -> &'static [&'static str] {
        match self {
            Stream::Joints => &[JOINT_STATE],
            Stream::Poses => &[POSE_STAMPED, TRANSFORM_STAMPED, TF_MESSAGE],
            Stream::Imu => &[IMU],
        }
    }
}

/// The transforms seen on the pose topic and the one taken.
#[derive(Debug, Default)]
struct PoseTrack {
    /// The child frame taken: `--frame`, else the first seen.
    frame: Option<String>,
    /// Every child frame seen: its parent and count of transforms.
    seen: BTreeMap<String, (String, usize)>,
}

impl PoseTrack {
    /// The frames seen, as "child (in parent, N)".
    fn listing(&self) -> String {
        self.seen
            .iter()
            .map(|(c, (p, n))| {
                let c = if c.is_empty() { "(none)" } else { c };
                format!("{c} (in {p}, {n} transforms)")
            })
            .collect::<Vec<_>>()
            .join(", ")
    }
}

/// Where a message is, for its errors.
struct At<'a> {
    file: &'a Path,
    topic: &'a str,
    index: usize,
    log_time: u64,
}

impl At<'_> {
    fn decode(&self, source: CdrError) -> ImportError {
        ImportError::Message {
            path: self.file.to_path_buf(),
            topic: self.topic.to_string(),
            index: self.index,
            log_time: self.log_time,
            source,
        }
    }

    fn sample(&self, detail: String) -> ImportError {
        ImportError::Sample {
            path: self.file.to_path_buf(),
            topic: self.topic.to_string(),
            index: self.index,
            log_time: self.log_time,
            detail,
        }
    }
}

/// A topic as a storage declares it.
#[derive(Debug, Clone, Copy)]
pub(crate) struct TopicDecl<'a> {
    /// Topic name.
    pub name: &'a str,
    /// Message type (`None`: the storage has no schema for it).
    pub type_name: Option<&'a str>,
    /// Message serialisation (`cdr`).
    pub serialization: &'a str,
    /// MCAP's schema encoding (`ros2msg`, `ros2idl`); `None` elsewhere.
    pub schema_encoding: Option<&'a str>,
}

/// A topic seen in the recording.
#[derive(Debug, Default)]
struct TopicInfo {
    type_name: String,
    /// Messages read.
    messages: usize,
    /// The count metadata.yaml gives, when there is one.
    declared: Option<u64>,
    /// Whether its declaration was checked against the wanted type.
    checked: bool,
}

/// Turns (topic, log time, CDR bytes) into [`Streams`]: the one decoding
/// path of every ROS 2 storage.
pub(crate) struct Collector<'o> {
    opts: &'o Ros2Options,
    /// The file being read (for messages' errors).
    file: PathBuf,
    /// Whether each message's bytes are zstd-compressed.
    pub(crate) message_zstd: bool,
    topics: BTreeMap<String, TopicInfo>,
    joints: JointPicker,
    poses: PoseTrack,
    out: Streams,
    /// Per stream (joints, IMU): the first time and whether any differs.
    stamps: [(Option<i64>, bool); 2],
    /// Per stream: the latest time so far; over both: the earliest.
    latest: [Option<i64>; 2],
    earliest: Option<i64>,
}

impl<'o> Collector<'o> {
    pub(crate) fn new(file: &Path, opts: &'o Ros2Options) -> Self {
        Self {
            opts,
            file: file.to_path_buf(),
            message_zstd: false,
            topics: BTreeMap::new(),
            joints: JointPicker::new(opts.joint_names.clone(), opts.names_required),
            poses: PoseTrack {
                frame: opts.poses.as_ref().and_then(|p| p.frame.clone()),
                seen: BTreeMap::new(),
            },
            out: Streams::default(),
            stamps: [(None, false); 2],
            latest: [None; 2],
            earliest: None,
        }
    }

    /// The file whose messages follow (each file's topics are checked
    /// anew: a split bag's files need not agree).
    pub(crate) fn set_file(&mut self, file: &Path) {
        self.file = file.to_path_buf();
        for info in self.topics.values_mut() {
            info.checked = false;
        }
    }

    /// Why sample `t` (ns) with `values` of stream `k` (0 motion, 1 IMU)
    /// cannot be a measurement, if it cannot: a value not finite, a time
    /// zero or negative, stepping back more than [`MAX_BACKSTEP_NS`] on its
    /// topic, or the recording spanning more than [`MAX_SPAN_NS`].
    fn check_sample(&mut self, k: usize, t: i64, values: &[f64]) -> Result<(), String> {
        if let Some(i) = values.iter().position(|v| !v.is_finite()) {
            return Err(format!("value {i} is {} (not a measurement)", values[i]));
        }
        if t <= 0 {
            return Err(format!(
                "time {t} ns: a zeroed or unset stamp (use --time log if the driver does not stamp)"
            ));
        }
        if let Some(latest) = self.latest[k] {
            if t < latest - MAX_BACKSTEP_NS {
                return Err(format!(
                    "time {t} ns is {:.3} s before the topic's previous message (stamps out of order)",
                    (latest - t) as f64 * 1e-9
                ));
            }
        }
        let latest = self.latest[k].map_or(t, |l| l.max(t));
        let earliest = self.earliest.map_or(t, |e| e.min(t));
        let last = latest.max(self.latest[1 - k].unwrap_or(latest));
        if last.saturating_sub(earliest) > MAX_SPAN_NS {
            return Err(format!(
                "time {t} ns makes the recording span {:.0} s, more than the {} h a recording may \
                 (a corrupted stamp)",
                last.saturating_sub(earliest) as f64 * 1e-9,
                MAX_SPAN_NS / 3_600_000_000_000
            ));
        }
        self.latest[k] = Some(latest);
        self.earliest = Some(earliest);
        Ok(())
    }

    /// Registers a topic (with its count, when a metadata file gives it), so
    /// that it is listed even without messages.
    pub(crate) fn declare(&mut self, name: &str, type_name: &str, count: Option<u64>) {
        let info = self.topics.entry(name.to_string()).or_default();
        if info.type_name.is_empty() {
            info.type_name = type_name.to_string();
        }
        if count.is_some() {
            info.declared = count;
        }
    }

    /// Which stream a topic feeds, if any.
    pub(crate) fn wanted(&self, topic: &str) -> Option<Stream> {
        if self.opts.poses.as_ref().is_some_and(|p| p.topic == topic) {
            Some(Stream::Poses)
        } else if topic == self.opts.imu_topic {
            Some(Stream::Imu)
        } else if self.opts.poses.is_none() && topic == self.opts.joints_topic {
            Some(Stream::Joints)
        } else {
            None
        }
    }

    /// The motion's topic and stream: the joints' or the poses'.
    fn motion(&self) -> (&str, Stream) {
        match &self.opts.poses {
            Some(p) => (&p.topic, Stream::Poses),
            None => (&self.opts.joints_topic, Stream::Joints),
        }
    }

    /// One message: decoded when its topic is one of the two asked for.
    pub(crate) fn message(
        &mut self,
        topic: &TopicDecl<'_>,
        log_time: u64,
        data: &[u8],
    ) -> Result<(), ImportError> {
        let wanted = self.wanted(topic.name);
        let info = self.topics.entry(topic.name.to_string()).or_default();
        if info.type_name.is_empty() {
            info.type_name = topic.type_name.unwrap_or("(no schema)").to_string();
        }
        info.messages += 1;
        let index = info.messages - 1;
        let Some(wanted) = wanted else {
            return Ok(());
        };
        if !info.checked {
            check_topic(&self.file, topic, wanted.types())?;
            info.checked = true;
        }
        let file = self.file.clone();
        let data: Cow<[u8]> = if self.message_zstd {
            Cow::Owned(unzstd(data, &file, "message")?)
        } else {
            Cow::Borrowed(data)
        };
        let at = At {
            file: &file,
            topic: topic.name,
            index,
            log_time,
        };
        let log_time = i64::try_from(log_time).unwrap_or(i64::MAX);
        let time_source = self.opts.time;
        let pick_time = |stamp: i64| match time_source {
            TimeSource::Header => stamp,
            TimeSource::Log => log_time,
        };
        match wanted {
            Stream::Joints => {
                let m = JointStateMsg::decode(&data).map_err(|e| at.decode(e))?;
                let t = pick_time(m.stamp.0);
                let q = self
                    .joints
                    .pick(&m, index)
                    .map_err(|detail| ImportError::Joints {
                        path: file.clone(),
                        detail,
                    })?;
                self.check_sample(0, t, q.as_deref().unwrap_or_default())
                    .map_err(|d| at.sample(d))?;
                advance(&mut self.stamps[0], t);
                if let Some(q) = q {
                    self.out.joints.push((t, q));
                }
            }
            Stream::Poses => {
                let poses = match topic.type_name {
                    Some(TF_MESSAGE) => PoseMsg::decode_tf(&data),
                    Some(TRANSFORM_STAMPED) => {
                        PoseMsg::decode_transform_stamped(&data).map(|m| vec![m])
                    }
                    _ => PoseMsg::decode_pose_stamped(&data).map(|m| vec![m]),
                }
                .map_err(|e| at.decode(e))?;
                for m in poses {
                    let t = pick_time(m.stamp.0);
                    self.pose(&m, t).map_err(|d| at.sample(d))?;
                }
            }
            Stream::Imu => {
                let m = ImuMsg::decode(&data).map_err(|e| at.decode(e))?;
                let t = pick_time(m.stamp.0);
                let z = imu_row(m.angular_velocity, m.linear_acceleration);
                self.check_sample(1, t, &z).map_err(|d| at.sample(d))?;
                advance(&mut self.stamps[1], t);
                self.out.imu.push((t, z));
            }
        }
        Ok(())
    }

    /// One pose (a PoseStamped's, or a transform's) at time `t` (ns): kept
    /// when its child frame is the one taken, and checked (finite, a
    /// rotation, in the frame of the poses before it).
    fn pose(&mut self, m: &PoseMsg, t: i64) -> Result<(), String> {
        let seen = self
            .poses
            .seen
            .entry(m.child_frame_id.clone())
            .or_insert_with(|| (m.frame_id.clone(), 0));
        seen.1 += 1;
        let parent = seen.0.clone();
        let frame = self
            .poses
            .frame
            .get_or_insert_with(|| m.child_frame_id.clone());
        if *frame != m.child_frame_id {
            return Ok(());
        }
        if m.frame_id != parent {
            return Err(format!(
                "the pose of {:?} is in frame {:?}, the ones before it in {parent:?}: poses must be \
                 in one fixed frame",
                m.child_frame_id, m.frame_id
            ));
        }
        let values: Vec<f64> = m.position.iter().chain(&m.orientation).copied().collect();
        self.check_sample(0, t, &values)?;
        let [w, x, y, z] = m.orientation;
        let norm = (w * w + x * x + y * y + z * z).sqrt();
        if norm < MIN_QUATERNION_NORM {
            return Err(format!(
                "the orientation (x, y, z, w) = ({x}, {y}, {z}, {w}) of norm {norm} is not a rotation"
            ));
        }
        advance(&mut self.stamps[0], t);
        self.out.poses.t_ns.push(t);
        self.out.poses.p.push(m.position);
        self.out.poses.q.push(m.orientation);
        Ok(())
    }

    /// The topics as "name [type, N messages]".
    fn listing(&self) -> String {
        if self.topics.is_empty() {
            return "none".into();
        }
        self.topics
            .iter()
            .map(|(t, i)| {
                let n = match (i.messages, i.declared) {
                    (0, Some(d)) => d as usize,
                    (n, _) => n,
                };
                format!("{t} [{}, {n} messages]", i.type_name)
            })
            .collect::<Vec<_>>()
            .join(", ")
    }

    /// The error for a topic asked for that the recording lacks, if any.
    pub(crate) fn missing_topic(&self, source: &Path) -> Option<ImportError> {
        let (motion, stream) = self.motion();
        for (topic, stream) in [
            (motion, stream),
            (self.opts.imu_topic.as_str(), Stream::Imu),
        ] {
            if !self.topics.contains_key(topic) {
                return Some(ImportError::MissingTopic {
                    path: source.to_path_buf(),
                    topic: format!("{topic} ({})", stream.types().join(" or ")),
                    available: self.listing(),
                });
            }
        }
        None
    }

    /// The streams, after every file: errors for topics absent, stamps
    /// that never change, or no joint message with the chosen joints.
    pub(crate) fn finish(self, source: &Path) -> Result<Streams, ImportError> {
        if let Some(e) = self.missing_topic(source) {
            return Err(e);
        }
        let opts = self.opts;
        let (motion, _) = self.motion();
        let counts = [
            self.out.joints.len() + self.out.poses.t_ns.len(),
            self.out.imu.len(),
        ];
        for (k, topic) in [motion, opts.imu_topic.as_str()].into_iter().enumerate() {
            let (first, moved) = self.stamps[k];
            if opts.time == TimeSource::Header && counts[k] > 1 && !moved {
                return Err(ImportError::WrongType {
                    path: source.to_path_buf(),
                    topic: topic.to_string(),
                    detail: format!(
                        "every header.stamp is {} ns: the driver does not stamp its messages (use --time log)",
                        first.unwrap_or(0)
                    ),
                });
            }
        }
        if let Some(pt) = &opts.poses {
            return self.finish_poses(source, pt);
        }
        let mut out = self.out;
        if out.joints.is_empty() {
            let seen = self
                .topics
                .get(&opts.joints_topic)
                .map_or(0, |i| i.messages);
            return Err(if seen == 0 {
                ImportError::Empty {
                    what: format!("{}: topic {}", source.display(), opts.joints_topic),
                }
            } else {
                ImportError::Joints {
                    path: source.to_path_buf(),
                    detail: format!(
                        "no message on {} has all of the joints {:?} ({} skipped){}",
                        opts.joints_topic,
                        self.joints.names.clone().unwrap_or_default(),
                        self.joints.skipped,
                        self.joints.closest_miss()
                    ),
                }
            });
        }
        out.joint_names = self.joints.names.unwrap_or_default();
        Ok(out)
    }
}

impl Collector<'_> {
    /// The streams of a pose session: errors for no pose, or for a topic
    /// of transforms of several frames without `--frame`, or without the
    /// frame asked for.
    fn finish_poses(self, source: &Path, pt: &PoseTopic) -> Result<Streams, ImportError> {
        let frames = &self.poses;
        let type_name = self
            .topics
            .get(&pt.topic)
            .map_or("", |i| i.type_name.as_str());
        let wrong = |detail: String| ImportError::WrongType {
            path: source.to_path_buf(),
            topic: pt.topic.clone(),
            detail,
        };
        if frames.seen.is_empty() {
            return Err(ImportError::Empty {
                what: format!("{}: topic {}", source.display(), pt.topic),
            });
        }
        if let (Some(f), POSE_STAMPED) = (&pt.frame, type_name) {
            return Err(wrong(format!(
                "--frame {f} picks a transform by its child_frame_id, and {POSE_STAMPED} names \
                 no child frame: leave --frame out for a PoseStamped topic"
            )));
        }
        if self.out.poses.t_ns.is_empty() {
            return Err(wrong(format!(
                "no transform of frame {:?} (child_frame_id); the frames present: {}",
                frames.frame.as_deref().unwrap_or_default(),
                frames.listing()
            )));
        }
        if pt.frame.is_none() && frames.seen.len() > 1 {
            return Err(wrong(format!(
                "transforms of {} frames: {}; choose the posed body's with --frame CHILD_FRAME_ID",
                frames.seen.len(),
                frames.listing()
            )));
        }
        let mut out = self.out;
        out.pose_frames = frames
            .frame
            .as_ref()
            .and_then(|f| frames.seen.get(f).map(|(p, _)| (p.clone(), f.clone())));
        Ok(out)
    }
}

/// Tracks whether a stream's times ever change.
fn advance(state: &mut (Option<i64>, bool), t: i64) {
    match state.0 {
        None => state.0 = Some(t),
        Some(f) if f != t => state.1 = true,
        _ => {}
    }
}

pub(crate) fn check_topic(
    file: &Path,
    topic: &TopicDecl<'_>,
    wanted: &[&str],
) -> Result<(), ImportError> {
    let wrong = |detail: String| ImportError::WrongType {
        path: file.to_path_buf(),
        topic: topic.name.to_string(),
        detail,
    };
    let wanted_names = wanted.join(" or ");
    let Some(type_name) = topic.type_name else {
        return Err(wrong(format!("has no schema, expected {wanted_names}")));
    };
    if !wanted.contains(&type_name) {
        return Err(wrong(format!(
            "carries {type_name}, expected {wanted_names}"
        )));
    }
    if let Some(enc) = topic.schema_encoding {
        if !matches!(enc, "ros2msg" | "ros2idl") {
            return Err(wrong(format!(
                "schema encoding is {enc:?}, expected \"ros2msg\" (a ROS 2 recording)"
            )));
        }
    }
    if topic.serialization != "cdr" {
        return Err(wrong(format!(
            "message encoding is {:?}, expected \"cdr\"",
            topic.serialization
        )));
    }
    Ok(())
}

/// Chooses the joints from each `JointState`.
struct JointPicker {
    /// The joints to import (`None` until the first message when not given).
    names: Option<Vec<String>>,
    /// Whether unnamed messages are refused when `names` was given.
    names_required: bool,
    /// Width of positional (unnamed) messages.
    width: Option<usize>,
    skipped: usize,
    /// Of the skipped messages, the one lacking the fewest of the joints:
    /// (the joints it lacks, the names it has).
    closest: Option<(Vec<String>, Vec<String>)>,
}

impl JointPicker {
    fn new(names: Option<Vec<String>>, names_required: bool) -> Self {
        Self {
            names,
            names_required,
            width: None,
            skipped: 0,
            closest: None,
        }
    }

    /// The joints the closest skipped message lacks, for the error.
    fn closest_miss(&self) -> String {
        match &self.closest {
            None => String::new(),
            Some((missing, has)) => format!(
                ": the closest message lacks {} (its joints: {})",
                missing
                    .iter()
                    .map(|n| format!("`{n}`"))
                    .collect::<Vec<_>>()
                    .join(", "),
                has.join(", ")
            ),
        }
    }

    /// The positions of the chosen joints, `None` when the message lacks
    /// one of them (a message of another joint group on the same topic).
    fn pick(&mut self, m: &JointStateMsg, index: usize) -> Result<Option<Vec<f64>>, String> {
        if !m.name.is_empty() && m.name.len() != m.position.len() {
            return Err(format!(
                "joint message {index} has {} names but {} positions",
                m.name.len(),
                m.position.len()
            ));
        }
        if m.name.is_empty() {
            // Positional: every message must have the same width.
            if let Some(names) = self.names.as_ref().filter(|_| self.names_required) {
                return Err(format!(
                    "joint message {index} has no joint names, so joints {names:?} cannot be picked"
                ));
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
        let mut missing = Vec::new();
        for n in names.iter() {
            match m.name.iter().position(|x| x == n) {
                Some(i) => q.push(m.position[i]),
                None => missing.push(n.clone()),
            }
        }
        if missing.is_empty() {
            return Ok(Some(q));
        }
        self.skipped += 1;
        if self
            .closest
            .as_ref()
            .is_none_or(|(fewest, _)| missing.len() < fewest.len())
        {
            self.closest = Some((missing, m.name.clone()));
        }
        Ok(None)
    }
}

// ---------------------------------------------------------------------------
// Compression

pub(crate) const ZSTD_MAGIC: [u8; 4] = [0x28, 0xb5, 0x2f, 0xfd];
pub(crate) const MCAP_MAGIC: &[u8] = b"\x89MCAP";
pub(crate) const SQLITE_MAGIC: &[u8] = b"SQLite format 3\0";

/// The zstd-compressed `data` of `what` (a file or a message) in `path`,
/// decompressed; refused naming the feature when this build lacks it.
pub(crate) fn unzstd(data: &[u8], path: &Path, what: &str) -> Result<Vec<u8>, ImportError> {
    #[cfg(feature = "mcap-compression")]
    {
        zstd::decode_all(data).map_err(|e| ImportError::Compressed {
            path: path.to_path_buf(),
            detail: format!("the {what} is not valid zstd data: {e}"),
        })
    }
    #[cfg(not(feature = "mcap-compression"))]
    {
        let _ = data;
        Err(compression_refused(path, what))
    }
}

#[cfg(not(feature = "mcap-compression"))]
pub(crate) fn compression_refused(path: &Path, what: &str) -> ImportError {
    ImportError::Compressed {
        path: path.to_path_buf(),
        detail: format!(
            "zstd-compressed (per {what}), and this robimu was built without the \
             `{COMPRESSION_FEATURE}` feature: build it with `cargo build --release --features \
             {COMPRESSION_FEATURE}`, or decompress the bag (`ros2 bag convert`)"
        ),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::import::cdr::Stamp;

    fn msg(names: &[&str], q: &[f64]) -> JointStateMsg {
        JointStateMsg {
            stamp: Stamp(0),
            frame_id: String::new(),
            name: names.iter().map(|n| n.to_string()).collect(),
            position: q.to_vec(),
        }
    }

    fn chain() -> Option<Vec<String>> {
        Some(["a", "b", "c"].iter().map(|n| n.to_string()).collect())
    }

    #[test]
    fn joints_are_picked_by_name_in_chain_order_extra_ones_ignored() {
        let mut p = JointPicker::new(chain(), false);
        let m = msg(&["b", "grip", "c", "a"], &[2.0, 9.0, 3.0, 1.0]);
        assert_eq!(p.pick(&m, 0).unwrap(), Some(vec![1.0, 2.0, 3.0]));
        // A gripper-only message on the same topic is skipped.
        assert_eq!(p.pick(&msg(&["grip"], &[9.0]), 1).unwrap(), None);
        // The closest skipped message is the one reported.
        assert_eq!(p.pick(&msg(&["b", "a", "x"], &[0.0; 3]), 2).unwrap(), None);
        assert_eq!(
            p.closest_miss(),
            ": the closest message lacks `c` (its joints: b, a, x)"
        );
        assert_eq!(p.skipped, 2);
    }

    #[test]
    fn unnamed_messages_follow_the_chain_unless_names_were_given() {
        let m = msg(&[], &[1.0, 2.0, 3.0]);
        let mut robot = JointPicker::new(chain(), false);
        assert_eq!(robot.pick(&m, 0).unwrap(), Some(vec![1.0, 2.0, 3.0]));
        let mut given = JointPicker::new(chain(), true);
        let e = given.pick(&m, 0).unwrap_err();
        assert!(e.contains("has no joint names"), "{e}");
    }
}
