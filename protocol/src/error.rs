//! [`WireError`]: every way a frame can fail to encode or decode.

use core::fmt;

/// A protocol fault: a frame that could not be encoded, or bytes on the link
/// that did not form a valid frame.
///
/// Decoding errors are recoverable: the [`Decoder`](crate::Decoder) has
/// already dropped the offending bytes and resynchronised at the next
/// delimiter, so the caller may log or count the error and keep reading.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum WireError {
    /// The bytes between two delimiters are not valid COBS (a block header
    /// points past the end of the frame).
    Cobs,
    /// The CRC-32C at the end of the frame does not match the frame's content.
    Crc {
        /// The CRC carried by the frame.
        received: u32,
        /// The CRC computed over the frame's version byte and payload.
        computed: u32,
    },
    /// The frame is intact but was sent with another
    /// [`PROTOCOL_VERSION`](crate::PROTOCOL_VERSION).
    WrongVersion {
        /// The version byte the frame carries.
        found: u8,
    },
    /// More than `limit` encoded bytes arrived without a delimiter. The
    /// decoder discards everything up to the next `0x00`.
    FrameTooLong {
        /// The decoder's buffer size: the longest frame it accepts, in
        /// encoded bytes without the delimiter.
        limit: usize,
    },
    /// The decoded frame is shorter than the shortest valid frame
    /// ([`MIN_DECODED_LEN`](crate::layout::MIN_DECODED_LEN): version, one payload
    /// byte, CRC).
    FrameTooShort {
        /// Decoded length of the frame, bytes.
        len: usize,
    },
    /// The payload passed the CRC but is not a message of the expected type
    /// (unknown variant, bad varint, bad bool, truncated).
    Deserialize(postcard::Error),
    /// The payload holds a valid message followed by `count` extra bytes.
    TrailingBytes {
        /// Number of bytes left over after the message.
        count: usize,
    },
    /// The message could not be serialised (only possible for a `Serialize`
    /// implementation postcard does not support; never for the protocol's
    /// own messages).
    Serialize(postcard::Error),
    /// The output buffer given to [`encode`](crate::encode) is too small for
    /// the frame; [`MAX_FRAME_LEN`](crate::MAX_FRAME_LEN) bytes always suffice.
    BufferTooSmall {
        /// Length of the buffer that was given.
        capacity: usize,
    },
}

impl fmt::Display for WireError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Cobs => f.write_str("frame is not valid COBS"),
            Self::Crc { received, computed } => write!(
                f,
                "frame CRC mismatch: frame carries {received:#010x}, content gives {computed:#010x}"
            ),
            Self::WrongVersion { found } => write!(
                f,
                "frame has protocol version {found}, expected {}",
                crate::PROTOCOL_VERSION
            ),
            Self::FrameTooLong { limit } => write!(
                f,
                "no frame delimiter within {limit} bytes; discarding up to the next delimiter"
            ),
            Self::FrameTooShort { len } => write!(
                f,
                "frame of {len} decoded bytes is shorter than the minimum of {}",
                crate::layout::MIN_DECODED_LEN
            ),
            Self::Deserialize(e) => write!(f, "frame payload is not a valid message: {e}"),
            Self::TrailingBytes { count } => {
                write!(f, "frame payload has {count} bytes after the message")
            }
            Self::Serialize(e) => write!(f, "message could not be serialised: {e}"),
            Self::BufferTooSmall { capacity } => {
                write!(f, "frame does not fit the {capacity}-byte output buffer")
            }
        }
    }
}

impl core::error::Error for WireError {
    fn source(&self) -> Option<&(dyn core::error::Error + 'static)> {
        match self {
            Self::Deserialize(e) | Self::Serialize(e) => Some(e),
            _ => None,
        }
    }
}
