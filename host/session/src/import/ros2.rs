//! ROS 2 recordings: a rosbag2 bag (the directory `ros2 bag record` writes:
//! `metadata.yaml` and one or more storage files), or one storage file,
//! MCAP (`.mcap`) or sqlite3 (`.db3`, feature `sqlite3`), with
//! `sensor_msgs/msg/JointState` and `sensor_msgs/msg/Imu` on two topics
//! (docs/model.md §7).
//!
//! Every storage feeds its messages — (topic, type, log time, CDR bytes) —
//! to one [`Collector`], which decodes the two topics ([`super::cdr`]) into
//! [`Streams`]. Sample times are the messages' `header.stamp`
//! ([`TimeSource::Header`], the time the driver gave the measurement) or
//! the recorder's log time ([`TimeSource::Log`], for drivers that leave the
//! stamp zero).
//!
//! `metadata.yaml` (`rosbag2_bagfile_information`) gives the storage
//! (`storage_identifier`: `mcap` or `sqlite3`), the files in order
//! (`relative_file_paths`: a split bag's files are read one after the other),
//! the topics with their types and message counts, and the compression:
//! `compression_mode` `file` (each file zstd-compressed, `….mcap.zstd`) or
//! `message` (each message's bytes). Compressed bags need the
//! `mcap-compression` feature; without it they are refused naming it. A
//! storage file is recognised by its first bytes (MCAP, SQLite or zstd
//! magic), not by its name.

use std::borrow::Cow;
use std::collections::BTreeMap;
use std::io::Read;
use std::path::{Path, PathBuf};

use serde::Deserialize;

use super::cdr::{ImuMsg, JointStateMsg};
use super::{imu_row, ImportError, Streams};

/// Type name of joint states.
pub const JOINT_STATE: &str = "sensor_msgs/msg/JointState";
/// Type name of IMU samples.
pub const IMU: &str = "sensor_msgs/msg/Imu";
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
    /// The joints to import, in this order (default: the names of the first
    /// joint message, in its order).
    pub joint_names: Option<Vec<String>>,
}

/// Reads the joint and IMU streams of the recording at `path`: a rosbag2
/// directory, or one MCAP or sqlite3 file (zstd-compressed or not).
pub fn read_ros2(path: &Path, opts: &Ros2Options) -> Result<Streams, ImportError> {
    let mut c = Collector::new(path, opts);
    if path.is_dir() {
        read_bag_dir(path, &mut c)?;
    } else {
        read_storage_file(path, &mut c)?;
    }
    c.finish(path)
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
    message_zstd: bool,
    topics: BTreeMap<String, TopicInfo>,
    joints: JointPicker,
    out: Streams,
    /// Per stream (joints, IMU): the first time and whether any differs.
    stamps: [(Option<i64>, bool); 2],
}

impl<'o> Collector<'o> {
    pub(crate) fn new(file: &Path, opts: &'o Ros2Options) -> Self {
        Self {
            opts,
            file: file.to_path_buf(),
            message_zstd: false,
            topics: BTreeMap::new(),
            joints: JointPicker::new(opts.joint_names.clone()),
            out: Streams::default(),
            stamps: [(None, false); 2],
        }
    }

    /// The file whose messages follow.
    pub(crate) fn set_file(&mut self, file: &Path) {
        self.file = file.to_path_buf();
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
    fn wanted(&self, topic: &str) -> Option<&'static str> {
        if topic == self.opts.joints_topic {
            Some(JOINT_STATE)
        } else if topic == self.opts.imu_topic {
            Some(IMU)
        } else {
            None
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
            check_topic(&self.file, topic, wanted)?;
            info.checked = true;
        }
        let file = &self.file;
        let data: Cow<[u8]> = if self.message_zstd {
            Cow::Owned(unzstd(data, file, "message")?)
        } else {
            Cow::Borrowed(data)
        };
        let decode_error = |source| ImportError::Message {
            path: file.clone(),
            topic: topic.name.to_string(),
            index,
            log_time,
            source,
        };
        let log_time = i64::try_from(log_time).unwrap_or(i64::MAX);
        let pick_time = |stamp: i64| match self.opts.time {
            TimeSource::Header => stamp,
            TimeSource::Log => log_time,
        };
        if wanted == JOINT_STATE {
            let m = JointStateMsg::decode(&data).map_err(decode_error)?;
            let t = pick_time(m.stamp.0);
            advance(&mut self.stamps[0], t);
            let q = self
                .joints
                .pick(&m, index)
                .map_err(|detail| ImportError::Joints {
                    path: file.clone(),
                    detail,
                })?;
            if let Some(q) = q {
                self.out.joints.push((t, q));
            }
        } else {
            let m = ImuMsg::decode(&data).map_err(decode_error)?;
            let t = pick_time(m.stamp.0);
            advance(&mut self.stamps[1], t);
            self.out
                .imu
                .push((t, imu_row(m.angular_velocity, m.linear_acceleration)));
        }
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
    fn missing_topic(&self, source: &Path) -> Option<ImportError> {
        let opts = self.opts;
        for (topic, wanted) in [(&opts.joints_topic, JOINT_STATE), (&opts.imu_topic, IMU)] {
            if !self.topics.contains_key(topic) {
                return Some(ImportError::MissingTopic {
                    path: source.to_path_buf(),
                    topic: format!("{topic} ({wanted})"),
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
        let counts = [self.out.joints.len(), self.out.imu.len()];
        for (k, topic) in [&opts.joints_topic, &opts.imu_topic]
            .into_iter()
            .enumerate()
        {
            let (first, moved) = self.stamps[k];
            if opts.time == TimeSource::Header && counts[k] > 1 && !moved {
                return Err(ImportError::WrongType {
                    path: source.to_path_buf(),
                    topic: topic.clone(),
                    detail: format!(
                        "every header.stamp is {} ns: the driver does not stamp its messages (use --time log)",
                        first.unwrap_or(0)
                    ),
                });
            }
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
                        "no message on {} has all of the joints {:?} ({} skipped)",
                        opts.joints_topic,
                        self.joints.names.clone().unwrap_or_default(),
                        self.joints.skipped
                    ),
                }
            });
        }
        out.joint_names = self.joints.names.unwrap_or_default();
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

fn check_topic(file: &Path, topic: &TopicDecl<'_>, wanted: &str) -> Result<(), ImportError> {
    let wrong = |detail: String| ImportError::WrongType {
        path: file.to_path_buf(),
        topic: topic.name.to_string(),
        detail,
    };
    let Some(type_name) = topic.type_name else {
        return Err(wrong(format!("has no schema, expected {wanted}")));
    };
    if type_name != wanted {
        return Err(wrong(format!("carries {type_name}, expected {wanted}")));
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
    /// Width of positional (unnamed) messages.
    width: Option<usize>,
    skipped: usize,
}

impl JointPicker {
    fn new(names: Option<Vec<String>>) -> Self {
        Self {
            names,
            width: None,
            skipped: 0,
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
            if let Some(names) = &self.names {
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

// ---------------------------------------------------------------------------
// Compression

const ZSTD_MAGIC: [u8; 4] = [0x28, 0xb5, 0x2f, 0xfd];
const MCAP_MAGIC: &[u8] = b"\x89MCAP";
const SQLITE_MAGIC: &[u8] = b"SQLite format 3\0";

/// The zstd-compressed `data` of `what` (a file or a message) in `path`,
/// decompressed; refused naming the feature when this build lacks it.
fn unzstd(data: &[u8], path: &Path, what: &str) -> Result<Vec<u8>, ImportError> {
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
fn compression_refused(path: &Path, what: &str) -> ImportError {
    ImportError::Compressed {
        path: path.to_path_buf(),
        detail: format!(
            "zstd-compressed (per {what}), and this robimu was built without the \
             `{COMPRESSION_FEATURE}` feature: build it with `cargo build --release --features \
             {COMPRESSION_FEATURE}`, or decompress the bag (`ros2 bag convert`)"
        ),
    }
}

// ---------------------------------------------------------------------------
// Storage files and bag directories

/// One storage file: MCAP or sqlite3, possibly zstd-compressed as a whole.
fn read_storage_file(path: &Path, c: &mut Collector<'_>) -> Result<(), ImportError> {
    c.set_file(path);
    let io = |source| ImportError::Io {
        path: path.to_path_buf(),
        source,
    };
    let mut head = [0u8; 16];
    let n = {
        let mut f = std::fs::File::open(path).map_err(io)?;
        let mut n = 0;
        while n < head.len() {
            match f.read(&mut head[n..]).map_err(io)? {
                0 => break,
                k => n += k,
            }
        }
        n
    };
    let head = &head[..n];
    if head.starts_with(&ZSTD_MAGIC) {
        let bytes = std::fs::read(path).map_err(io)?;
        let bytes = unzstd(&bytes, path, "file")?;
        return read_storage_bytes(path, &bytes, c);
    }
    if head.starts_with(SQLITE_MAGIC) {
        return read_db3(path, path, c);
    }
    let bytes = std::fs::read(path).map_err(io)?;
    read_storage_bytes(path, &bytes, c)
}

/// A storage file's (decompressed) bytes.
fn read_storage_bytes(path: &Path, bytes: &[u8], c: &mut Collector<'_>) -> Result<(), ImportError> {
    if bytes.starts_with(SQLITE_MAGIC) {
        // rusqlite reads files: the decompressed database goes to a
        // temporary file, removed afterwards.
        let tmp = TempFile::write(bytes).map_err(|source| ImportError::Io {
            path: std::env::temp_dir(),
            source,
        })?;
        return read_db3(&tmp.0, path, c);
    }
    let looks_mcap = bytes.starts_with(MCAP_MAGIC)
        || path
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("mcap"));
    if looks_mcap {
        return super::mcap::feed(path, bytes, c);
    }
    Err(ImportError::Bag {
        path: path.to_path_buf(),
        detail: "neither MCAP nor sqlite3 (rosbag2's storage formats) nor zstd".into(),
    })
}

#[cfg(feature = "sqlite3")]
fn read_db3(db: &Path, shown: &Path, c: &mut Collector<'_>) -> Result<(), ImportError> {
    super::sqlite3::feed(db, shown, c)
}

#[cfg(not(feature = "sqlite3"))]
fn read_db3(_db: &Path, shown: &Path, _c: &mut Collector<'_>) -> Result<(), ImportError> {
    Err(ImportError::Bag {
        path: shown.to_path_buf(),
        detail: "a sqlite3 bag, and this robimu was built without the `sqlite3` feature \
                 (build it with `--features sqlite3`, or convert the bag to MCAP: \
                 `ros2 bag convert`)"
            .into(),
    })
}

/// A temporary file removed when dropped.
struct TempFile(PathBuf);

impl TempFile {
    fn write(bytes: &[u8]) -> std::io::Result<Self> {
        use std::sync::atomic::{AtomicUsize, Ordering};
        static N: AtomicUsize = AtomicUsize::new(0);
        let name = format!(
            "robimu-import-{}-{}.db3",
            std::process::id(),
            N.fetch_add(1, Ordering::Relaxed)
        );
        let path = std::env::temp_dir().join(name);
        std::fs::write(&path, bytes)?;
        Ok(Self(path))
    }
}

impl Drop for TempFile {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.0);
    }
}

/// `metadata.yaml` of a rosbag2 bag (the fields robimu reads).
#[derive(Debug, Deserialize)]
struct MetadataFile {
    rosbag2_bagfile_information: BagInfo,
}

#[derive(Debug, Deserialize)]
struct BagInfo {
    storage_identifier: String,
    #[serde(default)]
    relative_file_paths: Vec<String>,
    #[serde(default)]
    topics_with_message_count: Vec<TopicCount>,
    #[serde(default)]
    compression_format: Option<String>,
    #[serde(default)]
    compression_mode: Option<String>,
}

#[derive(Debug, Deserialize)]
struct TopicCount {
    topic_metadata: TopicMeta,
    #[serde(default)]
    message_count: u64,
}

#[derive(Debug, Deserialize)]
struct TopicMeta {
    name: String,
    #[serde(rename = "type")]
    type_name: String,
    #[serde(default)]
    serialization_format: String,
}

/// A bag directory: its metadata, then each file in order.
fn read_bag_dir(dir: &Path, c: &mut Collector<'_>) -> Result<(), ImportError> {
    let meta_path = dir.join("metadata.yaml");
    if !meta_path.exists() {
        return read_dir_without_metadata(dir, c);
    }
    let bag_error = |detail: String| ImportError::Bag {
        path: meta_path.clone(),
        detail,
    };
    let text = std::fs::read_to_string(&meta_path).map_err(|source| ImportError::Io {
        path: meta_path.clone(),
        source,
    })?;
    let meta: MetadataFile =
        serde_yaml::from_str(&text).map_err(|e| bag_error(format!("not rosbag2 metadata: {e}")))?;
    let info = meta.rosbag2_bagfile_information;
    let storage = info.storage_identifier.to_ascii_lowercase();
    if !matches!(storage.as_str(), "mcap" | "sqlite3") {
        return Err(bag_error(format!(
            "storage_identifier {:?}: robimu reads the storages mcap and sqlite3",
            info.storage_identifier
        )));
    }
    let mode = info
        .compression_mode
        .unwrap_or_default()
        .to_ascii_lowercase();
    let format = info
        .compression_format
        .unwrap_or_default()
        .to_ascii_lowercase();
    let (file_zstd, message_zstd) = match mode.as_str() {
        "" | "none" => (false, false),
        "file" => (true, false),
        "message" => (false, true),
        other => {
            return Err(bag_error(format!(
                "compression_mode {other:?}: robimu reads none, file and message"
            )))
        }
    };
    if (file_zstd || message_zstd) && format != "zstd" {
        return Err(bag_error(format!(
            "compression_format {format:?}: robimu reads zstd"
        )));
    }
    #[cfg(not(feature = "mcap-compression"))]
    if file_zstd || message_zstd {
        return Err(compression_refused(
            dir,
            if file_zstd { "file" } else { "message" },
        ));
    }
    c.message_zstd = message_zstd;
    for t in &info.topics_with_message_count {
        let m = &t.topic_metadata;
        c.declare(&m.name, &m.type_name, Some(t.message_count));
    }
    // A topic asked for that the metadata lacks: say so before reading.
    if !info.topics_with_message_count.is_empty() {
        if let Some(e) = c.missing_topic(dir) {
            return Err(e);
        }
        for t in &info.topics_with_message_count {
            let m = &t.topic_metadata;
            if let Some(wanted) = c.wanted(&m.name) {
                let decl = TopicDecl {
                    name: &m.name,
                    type_name: Some(&m.type_name),
                    serialization: if m.serialization_format.is_empty() {
                        "cdr"
                    } else {
                        &m.serialization_format
                    },
                    schema_encoding: None,
                };
                check_topic(&meta_path, &decl, wanted)?;
            }
        }
    }
    if info.relative_file_paths.is_empty() {
        return Err(bag_error("relative_file_paths lists no file".into()));
    }
    for rel in &info.relative_file_paths {
        let mut file = dir.join(rel);
        // Older rosbag2 versions wrote paths relative to the bag's parent.
        if !file.exists() {
            if let Some(name) = Path::new(rel).file_name() {
                file = dir.join(name);
            }
        }
        if !file.exists() {
            return Err(bag_error(format!(
                "lists {rel}, which is not in {}",
                dir.display()
            )));
        }
        read_storage_file(&file, c)?;
    }
    Ok(())
}

/// A directory without metadata.yaml (a recording that was killed): its
/// storage files in the order of their `_N` index.
fn read_dir_without_metadata(dir: &Path, c: &mut Collector<'_>) -> Result<(), ImportError> {
    let entries = std::fs::read_dir(dir).map_err(|source| ImportError::Io {
        path: dir.to_path_buf(),
        source,
    })?;
    let mut files: Vec<(u64, PathBuf)> = Vec::new();
    for e in entries.flatten() {
        let p = e.path();
        let name = p.file_name().and_then(|n| n.to_str()).unwrap_or("");
        let stem = name.strip_suffix(".zstd").unwrap_or(name);
        let Some(base) = stem
            .strip_suffix(".mcap")
            .or_else(|| stem.strip_suffix(".db3"))
        else {
            continue;
        };
        let index = base
            .rsplit('_')
            .next()
            .and_then(|s| s.parse::<u64>().ok())
            .unwrap_or(0);
        files.push((index, p));
    }
    if files.is_empty() {
        return Err(ImportError::Bag {
            path: dir.to_path_buf(),
            detail: "no metadata.yaml and no .mcap or .db3 file: not a rosbag2 bag".into(),
        });
    }
    files.sort();
    for (_, f) in &files {
        read_storage_file(f, c)?;
    }
    Ok(())
}
