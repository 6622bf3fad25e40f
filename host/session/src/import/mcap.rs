//! The MCAP storage of ROS 2 recordings ([`super::ros2`], decoded by [`super::collect`]).
//!
//! A rosbag2 MCAP file (the `ros2` profile) has one channel per topic with
//! message encoding `cdr` and a schema named by the message type
//! (`sensor_msgs/msg/Imu`) with encoding `ros2msg` (or `ros2idl`). Messages
//! are read in file order and handed to the [`Collector`] with their log
//! time.
//!
//! Chunks compressed with zstd or lz4 need the `mcap-compression` feature;
//! without it such a file is refused with that advice.

use std::path::Path;

use ::mcap::{McapError, MessageStream};

use super::collect::{Collector, TopicDecl, COMPRESSION_FEATURE};
use super::ImportError;

/// Feeds every message of the MCAP file `bytes` (read from `path`) to `c`.
pub(crate) fn feed(path: &Path, bytes: &[u8], c: &mut Collector<'_>) -> Result<(), ImportError> {
    let mcap_error = |source: McapError| {
        let hint = match &source {
            McapError::UnsupportedCompression(c) => format!(
                " (chunks compressed with {c}: build robimu with `--features {COMPRESSION_FEATURE}`, \
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
    let stream = MessageStream::new(bytes).map_err(mcap_error)?;
    for message in stream {
        let message = message.map_err(mcap_error)?;
        let channel = &message.channel;
        let schema = channel.schema.as_ref();
        let decl = TopicDecl {
            name: &channel.topic,
            type_name: schema.map(|s| s.name.as_str()),
            serialization: &channel.message_encoding,
            schema_encoding: schema.map(|s| s.encoding.as_str()),
        };
        c.message(&decl, message.log_time, &message.data)?;
    }
    Ok(())
}
