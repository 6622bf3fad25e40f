//! ROS 2 recordings: a rosbag2 bag (the directory `ros2 bag record` writes:
//! `metadata.yaml` and one or more storage files), or one storage file,
//! MCAP (`.mcap`) or sqlite3 (`.db3`, feature `sqlite3`), with
//! `sensor_msgs/msg/JointState` and `sensor_msgs/msg/Imu` on two topics
//! (docs/model.md §7), or, for a pose session ([`Ros2Options::poses`],
//! docs/model.md §7.9), tool poses (`geometry_msgs/msg/PoseStamped`,
//! `geometry_msgs/msg/TransformStamped` or `/tf`'s `tf2_msgs/msg/TFMessage`,
//! one child frame taken) in place of the joint states.
//!
//! Every storage feeds its messages — (topic, type, log time, CDR bytes) —
//! to one collector (`collect.rs`), which decodes the two topics ([`super::cdr`]) into
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

use std::io::Read;
use std::path::{Path, PathBuf};

use serde::Deserialize;

#[cfg(not(feature = "mcap-compression"))]
use super::collect::compression_refused;
use super::collect::{
    check_topic, unzstd, Collector, TopicDecl, MCAP_MAGIC, SQLITE_MAGIC, ZSTD_MAGIC,
};
pub use super::collect::{PoseTopic, Ros2Options, TimeSource, IMU};
#[allow(unused_imports)]
pub(crate) use super::collect::{COMPRESSION_FEATURE, JOINT_STATE};
use super::ImportError;
use super::Streams;

/// Reads the joint (or pose) and IMU streams of the recording at `path`: a rosbag2
/// directory, or one MCAP or sqlite3 file (zstd-compressed or not).
pub fn read_ros2(path: &Path, opts: &Ros2Options) -> Result<Streams, ImportError> {
    if let Some(names) = &opts.joint_names {
        if let Some((i, n)) = names
            .iter()
            .enumerate()
            .find(|(i, n)| names[..*i].contains(n))
        {
            return Err(ImportError::Joints {
                path: path.to_path_buf(),
                detail: format!(
                    "joint `{n}` is named twice in the joints to import (names {} and {}): each joint once",
                    names.iter().position(|x| x == n).unwrap_or(0) + 1,
                    i + 1
                ),
            });
        }
    }
    let mut c = Collector::new(path, opts);
    if path.is_dir() {
        read_bag_dir(path, &mut c)?;
    } else {
        read_storage_file(path, &mut c)?;
    }
    c.finish(path)
}

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
    let text =
        robimu_model::text::read_to_string(&meta_path).map_err(|source| ImportError::Io {
            path: meta_path.clone(),
            source,
        })?;
    if let Err(e) = check_yaml_nesting(&text) {
        return Err(bag_error(e));
    }
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
                check_topic(&meta_path, &decl, wanted.types())?;
            }
        }
    }
    if info.relative_file_paths.is_empty() {
        return Err(bag_error("relative_file_paths lists no file".into()));
    }
    let mut seen: Vec<PathBuf> = Vec::new();
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
        let canonical = file.canonicalize().unwrap_or_else(|_| file.clone());
        if seen.contains(&canonical) {
            return Err(bag_error(format!(
                "relative_file_paths lists {rel} twice: each storage file once"
            )));
        }
        seen.push(canonical);
        read_storage_file(&file, c)?;
    }
    Ok(())
}

/// The deepest nesting of YAML flow collections (`[`, `{`) or indentation
/// levels metadata.yaml may have (rosbag2 writes 6).
const MAX_YAML_DEPTH: usize = 64;

/// Refuses YAML nested deeper than [`MAX_YAML_DEPTH`] before the parser
/// sees it (its time grows with the square of the depth).
fn check_yaml_nesting(text: &str) -> Result<(), String> {
    let (mut depth, mut deepest) = (0usize, 0usize);
    let mut quote: Option<char> = None;
    for (line_no, line) in text.lines().enumerate() {
        let indent = line.len() - line.trim_start_matches([' ', '-']).len();
        let mut line_deepest = indent / 2;
        for ch in line.chars() {
            match (quote, ch) {
                (Some(q), c) if c == q => quote = None,
                (Some(_), _) => {}
                (None, '"' | '\'') => quote = Some(ch),
                (None, '#') => break,
                (None, '[' | '{') => {
                    depth += 1;
                    line_deepest = line_deepest.max(indent / 2 + depth);
                }
                (None, ']' | '}') => depth = depth.saturating_sub(1),
                _ => {}
            }
        }
        deepest = deepest.max(line_deepest);
        if deepest > MAX_YAML_DEPTH {
            return Err(format!(
                "line {}: nested more than {MAX_YAML_DEPTH} levels deep (rosbag2 metadata \
                 nests 6): not rosbag2 metadata",
                line_no + 1
            ));
        }
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

/// rosbag2 sqlite3 files written here (rusqlite), read through [`read_ros2`].
#[cfg(all(test, feature = "sqlite3"))]
mod db3_tests {
    use super::super::cdr::{encode, ImuMsg, JointStateMsg, Stamp};
    use super::{read_ros2, Ros2Options, TimeSource};

    const T0: i64 = 1_700_000_000_000_000_000;

    /// A rosbag2 sqlite3 file with 5 joint and 5 IMU messages every 10 ms,
    /// `tweak` applied to the messages (topic id, timestamp, data) first.
    fn db3(path: &std::path::Path, tweak: impl Fn(&mut Vec<(i64, i64, Vec<u8>)>)) {
        let c = rusqlite::Connection::open(path).unwrap();
        c.execute_batch(
            "CREATE TABLE topics(id INTEGER PRIMARY KEY, name TEXT, type TEXT, serialization_format TEXT);
             CREATE TABLE messages(id INTEGER PRIMARY KEY, topic_id INTEGER, timestamp INTEGER, data BLOB);
             INSERT INTO topics VALUES (1, '/joint_states', 'sensor_msgs/msg/JointState', 'cdr');
             INSERT INTO topics VALUES (2, '/imu/data_raw', 'sensor_msgs/msg/Imu', 'cdr');",
        )
        .unwrap();
        let mut rows = Vec::new();
        for k in 0..5 {
            let t = T0 + k * 10_000_000;
            let js = encode::joint_state(&JointStateMsg {
                stamp: Stamp(t),
                frame_id: String::new(),
                name: vec![],
                position: vec![0.1 * k as f64; 6],
            });
            let imu = encode::imu(&ImuMsg {
                stamp: Stamp(t),
                frame_id: String::new(),
                angular_velocity: [0.0; 3],
                linear_acceleration: [0.0, 0.0, 9.81],
            });
            rows.push((1, t, js));
            rows.push((2, t, imu));
        }
        tweak(&mut rows);
        for (topic, t, data) in rows {
            c.execute(
                "INSERT INTO messages(topic_id, timestamp, data) VALUES (?1, ?2, ?3)",
                rusqlite::params![topic, t, data],
            )
            .unwrap();
        }
    }

    fn read(path: &std::path::Path, time: TimeSource) -> Result<(), String> {
        let opts = Ros2Options {
            joints_topic: "/joint_states".into(),
            imu_topic: "/imu/data_raw".into(),
            time,
            joint_names: None,
            names_required: false,
            poses: None,
        };
        read_ros2(path, &opts)
            .map(|_| ())
            .map_err(|e| e.to_string())
    }

    /// A pose session's topics in a sqlite3 bag: TF transforms of two
    /// frames, the one asked for taken (stamps and values as written), the
    /// other frame's ignored; without --frame the two are named.
    #[test]
    fn tf_poses_of_a_db3_bag_are_read_by_child_frame() {
        use super::super::cdr::PoseMsg;
        use super::PoseTopic;
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("poses.db3");
        let c = rusqlite::Connection::open(&path).unwrap();
        c.execute_batch(
            "CREATE TABLE topics(id INTEGER PRIMARY KEY, name TEXT, type TEXT, serialization_format TEXT);
             CREATE TABLE messages(id INTEGER PRIMARY KEY, topic_id INTEGER, timestamp INTEGER, data BLOB);
             INSERT INTO topics VALUES (1, '/tf', 'tf2_msgs/msg/TFMessage', 'cdr');
             INSERT INTO topics VALUES (2, '/imu/data_raw', 'sensor_msgs/msg/Imu', 'cdr');",
        )
        .unwrap();
        let pose = |t: i64, child: &str, x: f64| PoseMsg {
            stamp: Stamp(t),
            frame_id: "base".into(),
            child_frame_id: child.into(),
            position: [x, 0.5, -0.25],
            orientation: [0.0, 0.6, 0.0, 0.8],
        };
        for k in 0..5 {
            let t = T0 + k * 10_000_000;
            let tf = encode::tf(&[pose(t, "camera", -1.0), pose(t, "tool0", 0.1 * k as f64)]);
            let imu = encode::imu(&ImuMsg {
                stamp: Stamp(t),
                frame_id: String::new(),
                angular_velocity: [0.0; 3],
                linear_acceleration: [0.0, 0.0, 9.81],
            });
            for (topic, data) in [(1, tf), (2, imu)] {
                c.execute(
                    "INSERT INTO messages(topic_id, timestamp, data) VALUES (?1, ?2, ?3)",
                    rusqlite::params![topic, t, data],
                )
                .unwrap();
            }
        }
        let opts = |frame: Option<&str>| Ros2Options {
            joints_topic: "/joint_states".into(),
            imu_topic: "/imu/data_raw".into(),
            time: TimeSource::Header,
            joint_names: None,
            names_required: false,
            poses: Some(PoseTopic {
                topic: "/tf".into(),
                frame: frame.map(String::from),
            }),
        };
        let s = read_ros2(&path, &opts(Some("tool0"))).unwrap();
        assert_eq!(
            s.poses.t_ns,
            (0..5).map(|k| T0 + k * 10_000_000).collect::<Vec<_>>()
        );
        assert_eq!(s.poses.p[3], [0.1 * 3.0, 0.5, -0.25]);
        assert_eq!(s.poses.q[0], [0.0, 0.6, 0.0, 0.8]);
        assert_eq!(s.pose_frames, Some(("base".into(), "tool0".into())));
        assert_eq!(s.imu.len(), 5);
        let e = read_ros2(&path, &opts(None)).unwrap_err().to_string();
        assert!(
            e.contains("transforms of 2 frames: camera (in base, 5 transforms), tool0 (in base, 5 transforms)"),
            "{e}"
        );
    }

    /// Issue 41: a zeroed message and a negative log time are refused.
    #[test]
    fn zeroed_messages_and_negative_log_times_are_refused() {
        let dir = tempfile::tempdir().unwrap();
        let good = dir.path().join("good.db3");
        db3(&good, |_| {});
        read(&good, TimeSource::Header).unwrap();
        // The IMU message 2's bytes zeroed (its length kept).
        let zeroed = dir.path().join("zeroed.db3");
        db3(&zeroed, |rows| rows[5].2.fill(0));
        let e = read(&zeroed, TimeSource::Header).unwrap_err();
        assert!(
            e.contains("topic /imu/data_raw, message 2")
                && e.contains("time 0 ns: a zeroed or unset stamp"),
            "{e}"
        );
        // A negative log time, read by either time source.
        let negative = dir.path().join("negative.db3");
        db3(&negative, |rows| rows[4].1 = -5);
        for time in [TimeSource::Header, TimeSource::Log] {
            let e = read(&negative, time).unwrap_err();
            assert!(
                e.contains("has timestamp -5 ns: a log time cannot be negative"),
                "{e}"
            );
        }
    }
}
