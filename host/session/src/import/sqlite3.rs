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
