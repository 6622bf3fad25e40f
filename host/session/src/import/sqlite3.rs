//! The sqlite3 storage of ROS 2 recordings (`.db3`, ROS 2 Humble's default;
//! feature `sqlite3`), read with SQLite's own C code (rusqlite, bundled).
//!
//! rosbag2's schema: `topics(id, name, type, serialization_format, …)` and
//! `messages(id, topic_id, timestamp, data)`, `timestamp` the recorder's
//! receive time in ns (the log time) and `data` the CDR bytes. Messages are
//! read in timestamp order and handed to the [`Collector`].

use std::collections::HashMap;
use std::path::Path;

use rusqlite::{Connection, OpenFlags};

use super::collect::{Collector, TopicDecl};
use super::ImportError;

/// Feeds every message of the database file `db` (shown as `shown` in
/// errors) to `c`.
pub(crate) fn feed(db: &Path, shown: &Path, c: &mut Collector<'_>) -> Result<(), ImportError> {
    let fail = |what: &str, e: rusqlite::Error| ImportError::Bag {
        path: shown.to_path_buf(),
        detail: format!("not a readable rosbag2 sqlite3 file ({what}: {e})"),
    };
    let conn = Connection::open_with_flags(
        db,
        OpenFlags::SQLITE_OPEN_READ_ONLY | OpenFlags::SQLITE_OPEN_NO_MUTEX,
    )
    .map_err(|e| fail("open", e))?;
    // id → (name, type, serialization)
    let mut topics: HashMap<i64, (String, String, String)> = HashMap::new();
    {
        let mut st = conn
            .prepare("SELECT id, name, type, serialization_format FROM topics")
            .map_err(|e| fail("table topics", e))?;
        let rows = st
            .query_map([], |r| {
                Ok((
                    r.get::<_, i64>(0)?,
                    (
                        r.get::<_, String>(1)?,
                        r.get::<_, String>(2)?,
                        r.get::<_, String>(3)?,
                    ),
                ))
            })
            .map_err(|e| fail("table topics", e))?;
        for row in rows {
            let (id, t) = row.map_err(|e| fail("table topics", e))?;
            c.declare(&t.0, &t.1, None);
            topics.insert(id, t);
        }
    }
    let mut st = conn
        .prepare("SELECT topic_id, timestamp, data FROM messages ORDER BY timestamp, id")
        .map_err(|e| fail("table messages", e))?;
    let mut rows = st.query([]).map_err(|e| fail("table messages", e))?;
    while let Some(row) = rows.next().map_err(|e| fail("table messages", e))? {
        let topic_id: i64 = row.get(0).map_err(|e| fail("messages.topic_id", e))?;
        let timestamp: i64 = row.get(1).map_err(|e| fail("messages.timestamp", e))?;
        let data = row
            .get_ref(2)
            .and_then(|v| v.as_blob().map_err(rusqlite::Error::from))
            .map_err(|e| fail("messages.data", e))?;
        let Some((name, type_name, serialization)) = topics.get(&topic_id) else {
            return Err(ImportError::Bag {
                path: shown.to_path_buf(),
                detail: format!("a message has topic_id {topic_id}, which table topics lacks"),
            });
        };
        let decl = TopicDecl {
            name,
            type_name: Some(type_name),
            serialization,
            schema_encoding: None,
        };
        let Ok(log_time) = u64::try_from(timestamp) else {
            return Err(ImportError::Bag {
                path: shown.to_path_buf(),
                detail: format!(
                    "a message on {name} has timestamp {timestamp} ns: a log time cannot be \
                     negative (a corrupted database)"
                ),
            });
        };
        c.message(&decl, log_time, data)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::super::cdr::{encode, ImuMsg, JointStateMsg, Stamp};
    use super::super::ros2::{read_ros2, Ros2Options, TimeSource};

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
        };
        read_ros2(path, &opts)
            .map(|_| ())
            .map_err(|e| e.to_string())
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
