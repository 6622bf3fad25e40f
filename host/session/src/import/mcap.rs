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
    check_chunks(bytes).map_err(|detail| ImportError::Bag {
        path: path.to_path_buf(),
        detail: format!("not a readable MCAP file: {detail} (the file is corrupted)"),
    })?;
    isolated(path, || feed_records(path, bytes, c))
}

/// The records inside every uncompressed chunk fit in it. The mcap crate
/// (0.26) bounds a chunk's record lengths by the file only: a record
/// claiming more than its chunk holds underflows `compressed_remaining`
/// (`sans_io/linear_reader.rs:745`, a panic; the fuzz harness found it).
/// Compressed chunks are checked by the crate after decompression; records
/// whose lengths exceed the file are left to the crate's limit.
fn check_chunks(bytes: &[u8]) -> Result<(), String> {
    let u64_at = |b: &[u8], at: usize| -> Option<usize> {
        let v = u64::from_le_bytes(b.get(at..at + 8)?.try_into().ok()?);
        usize::try_from(v).ok()
    };
    // past the magic: top-level records, opcode and length, up to the footer
    let mut at = 8;
    while let (Some(&opcode), Some(len)) = (bytes.get(at), u64_at(bytes, at + 1)) {
        let Some(content) = (at + 9)
            .checked_add(len)
            .and_then(|end| bytes.get(at + 9..end))
        else {
            return Ok(());
        };
        if opcode == op::FOOTER {
            return Ok(());
        }
        if opcode == op::CHUNK {
            check_chunk(content, at, u64_at)?;
        }
        at += 9 + len;
    }
    Ok(())
}

/// [`check_chunks`] for the chunk record `content` at byte `at`: start and
/// end time, uncompressed size, CRC (28 bytes), compression (a string),
/// then the records' length and bytes.
fn check_chunk(
    content: &[u8],
    at: usize,
    u64_at: impl Fn(&[u8], usize) -> Option<usize>,
) -> Result<(), String> {
    let Some(name_len) = content
        .get(28..32)
        .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as usize)
    else {
        return Ok(());
    };
    let Some(records_at) = 32usize
        .checked_add(name_len)
        .filter(|&r| r <= content.len())
    else {
        return Ok(());
    };
    if name_len > 0 {
        return Ok(());
    }
    let Some(records) = u64_at(content, records_at)
        .and_then(|n| content.get(records_at + 8..(records_at + 8).checked_add(n)?))
    else {
        return Ok(());
    };
    let mut pos = 0;
    while pos < records.len() {
        let left = records.len() - pos;
        let claimed = u64_at(records, pos + 1);
        if left < 9 || claimed.is_none_or(|n| n > left - 9) {
            return Err(format!(
                "a record in the chunk at byte {at} claims {} bytes where the chunk has {} left",
                claimed.map_or("more".to_string(), |n| n.to_string()),
                left.saturating_sub(9)
            ));
        }
        pos += 9 + claimed.unwrap_or(0);
    }
    Ok(())
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

    /// Issue 41, found by the fuzz harness's process-level mode: a record
    /// inside an uncompressed chunk whose length (within the file) exceeds
    /// what the chunk holds made the mcap crate panic ("attempt to subtract
    /// with overflow", linear_reader.rs:745), printed as a panic before
    /// the isolation turned it into an error. Refused before the crate
    /// reads it. Reproducer for the crate: the fixture with its chunk's
    /// first record length (bytes 43 + 9 + 40 + 1 ..) set to 80 000.
    #[test]
    fn a_record_longer_than_its_chunk_is_refused_before_the_crate_reads_it() {
        let good: &[u8] = include_bytes!("../../../cli/tests/fixtures/ros2/run_mcap/run_mcap.mcap");
        assert_eq!(check_chunks(good), Ok(()));
        // the chunk at 43: its records start after 9 + 28 + 4 + 0 + 8 bytes
        let first = 43 + 9 + 40;
        let mut bad = good.to_vec();
        bad[first + 1..first + 9].copy_from_slice(&80_000u64.to_le_bytes());
        assert_eq!(
            check_chunks(&bad),
            Err("a record in the chunk at byte 43 claims 80000 bytes where the chunk has 79053 left".into())
        );
        // 2^64 - 1, the length that wrapped `9 + len` at top level
        let mut max = good.to_vec();
        max[first + 1..first + 9].copy_from_slice(&u64::MAX.to_le_bytes());
        let e = check_chunks(&max).unwrap_err();
        assert!(
            e.contains("claims 18446744073709551615 bytes where the chunk has 79053 left"),
            "{e}"
        );
    }
}
