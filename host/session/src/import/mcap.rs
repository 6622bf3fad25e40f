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

use ::mcap::read::ChannelAccumulator;
use ::mcap::records::{op, Record};
use ::mcap::sans_io::{LinearReadEvent, LinearReader, LinearReaderOptions};
use ::mcap::{parse_record, McapError};

use super::collect::{Collector, TopicDecl, COMPRESSION_FEATURE};
use super::ImportError;

/// Feeds every message of the MCAP file `bytes` (read from `path`) to `c`.
///
/// No record may be longer than the file (the limit is handed to the mcap
/// crate, whose arithmetic would otherwise overflow on a corrupted length),
/// and a record of an unknown opcode — a corrupted chunk or message header,
/// which the crate would skip with every message in it — is refused.
///
/// As a last resort the mcap crate is isolated: a panic inside it (a bug
/// on bytes not foreseen here) becomes an error naming the file.
pub(crate) fn feed(path: &Path, bytes: &[u8], c: &mut Collector<'_>) -> Result<(), ImportError> {
    isolated(path, || feed_records(path, bytes, c))
}

/// `read()`, a panic in it turned into an error naming `path`.
fn isolated(
    path: &Path,
    read: impl FnOnce() -> Result<(), ImportError>,
) -> Result<(), ImportError> {
    std::panic::catch_unwind(std::panic::AssertUnwindSafe(read)).unwrap_or_else(|panic| {
        let why = panic
            .downcast_ref::<&str>()
            .map(|s| s.to_string())
            .or_else(|| panic.downcast_ref::<String>().cloned())
            .unwrap_or_default();
        Err(ImportError::Bag {
            path: path.to_path_buf(),
            detail: format!(
                "not a readable MCAP file: the MCAP reader failed on it ({why}): the file is \
                 corrupted"
            ),
        })
    })
}

fn feed_records(path: &Path, bytes: &[u8], c: &mut Collector<'_>) -> Result<(), ImportError> {
    let mcap_error = |source: McapError| {
        let hint = match &source {
            McapError::UnsupportedCompression(c) => format!(
                " (chunks compressed with {c}: build robimu with `--features {COMPRESSION_FEATURE}`, \
                 or rewrite the file uncompressed)"
            ),
            McapError::BadMagic
            | McapError::UnexpectedEof
            | McapError::UnexpectedEoc
            | McapError::BadChunkLength { .. }
            | McapError::RecordTooLarge { .. } => {
                " (the file is truncated, corrupted or not MCAP; a recording that was killed can be \
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
    let corrupted = |detail: String| ImportError::Bag {
        path: path.to_path_buf(),
        detail: format!("not a readable MCAP file: {detail} (the file is corrupted)"),
    };
    let mut reader = LinearReader::new_with_options(
        LinearReaderOptions::default()
            .with_record_length_limit(bytes.len())
            .with_emit_chunks(false),
    );
    let mut channels = ChannelAccumulator::default();
    let (mut fed, mut past_data_end) = (0usize, false);
    while let Some(event) = reader.next_event() {
        let (opcode, data) = match event.map_err(mcap_error)? {
            LinearReadEvent::ReadRequest(need) => {
                let n = need.min(bytes.len() - fed);
                reader.insert(n).copy_from_slice(&bytes[fed..fed + n]);
                reader.notify_read(n);
                fed += n;
                continue;
            }
            LinearReadEvent::Record { opcode, data } => (opcode, data),
        };
        if opcode == op::DATA_END {
            past_data_end = true;
            continue;
        }
        match parse_record(opcode, data).map_err(mcap_error)? {
            // rosbag2 writes no private records (opcodes 0x80 and up): an
            // unknown opcode is a corrupted record, its messages lost.
            Record::Unknown { opcode, .. } => {
                return Err(corrupted(format!(
                    "a record of unknown opcode 0x{opcode:02x} near byte {fed}"
                )));
            }
            Record::Message { .. } if past_data_end => {
                return Err(corrupted(format!(
                    "a message after the data section's end near byte {fed}"
                )));
            }
            // The summary repeats schemas and channels: not re-read.
            _ if past_data_end => {}
            Record::Schema { header, data } => channels
                .add_schema(header, std::borrow::Cow::Owned(data.into_owned()))
                .map_err(mcap_error)?,
            Record::Channel(channel) => channels.add_channel(channel).map_err(mcap_error)?,
            Record::Message { header, data } => {
                let channel = channels.get(header.channel_id).ok_or_else(|| {
                    mcap_error(McapError::UnknownChannel(
                        header.sequence,
                        header.channel_id,
                    ))
                })?;
                let schema = channel.schema.as_ref();
                let decl = TopicDecl {
                    name: &channel.topic,
                    type_name: schema.map(|s| s.name.as_str()),
                    serialization: &channel.message_encoding,
                    schema_encoding: schema.map(|s| s.encoding.as_str()),
                };
                c.message(&decl, header.log_time, &data)?;
            }
            _ => {}
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_panic_in_the_reader_becomes_an_error_naming_the_file() {
        let e = isolated(Path::new("bag/x.mcap"), || {
            panic!("attempt to add with overflow")
        })
        .unwrap_err()
        .to_string();
        assert!(
            e.starts_with("bag/x.mcap: not a readable MCAP file: the MCAP reader failed on it (attempt to add with overflow)"),
            "{e}"
        );
        assert!(isolated(Path::new("x.mcap"), || Ok(())).is_ok());
    }
}
