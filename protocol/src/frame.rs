//! Framing: how one message becomes bytes on the serial link.
//!
//! ```text
//! frame = COBS( version:u8 ++ postcard(message) ++ crc32c:u32le ) ++ 0x00
//! ```
//!
//! * `version` is [`PROTOCOL_VERSION`]; a receiver rejects other versions
//!   with [`WireError::WrongVersion`].
//! * `postcard(message)` is the [postcard](https://docs.rs/postcard) encoding
//!   of a [`DeviceMessage`](crate::DeviceMessage) or
//!   [`HostMessage`](crate::HostMessage) (varint integers, enum variant index
//!   first).
//! * `crc32c` is CRC-32C (Castagnoli, `CRC_32_ISCSI`: reflected polynomial
//!   0x82F63B78, init and xor-out 0xFFFFFFFF) over `version ++ payload`,
//!   little-endian. Check value: `crc32c(b"123456789") == 0xE306_9283`.
//! * COBS removes every `0x00` from the frame so that `0x00` ([`DELIMITER`])
//!   marks frame ends. For bodies under 254 bytes (every message here) COBS
//!   adds exactly one byte, so a frame is always `payload + 7` bytes.
//!
//! **Resynchronisation.** Two delimiters in a row form an empty frame, which
//! receivers skip silently. A sender should therefore write one lone
//! [`DELIMITER`] at boot and after a reconnect: it terminates whatever partial
//! frame the receiver still holds (which then fails its CRC and is counted),
//! so the first real frame is decoded intact.
//!
//! # Worst-case sizes
//!
//! Postcard integers are varints (u32 ≤ 5 bytes, u16/i16 ≤ 3 bytes, zigzag for
//! signed), `f32` is 4 bytes, `bool`, `u8`, `i8` and every enum tag here 1 byte.
//!
//! | message                         | max payload | max frame |
//! |---------------------------------|------------:|----------:|
//! | `DeviceMessage::Info`           | 50          | **57**    |
//! | `DeviceMessage::Sample`         | 31          | 38        |
//! | `DeviceMessage::Status`         | 38          | 45        |
//! | `DeviceMessage::Pong`           | 11          | 18        |
//! | `DeviceMessage::CommandResult`  | 4           | 11        |
//! | `HostMessage::Configure`        | 8           | **15**    |
//! | `HostMessage::Ping`             | 6           | 13        |
//! | `HostMessage::{Start, Stop, GetInfo, GetStatus}` | 1 | 8   |
//!
//! A typical BNO055 sample frame is 25 bytes at rest and up to 30 bytes
//! while moving (seq < 2²¹, `t_us` ≥ 2²⁸ after 4.5 minutes, two-byte readings);
//! at 921600 baud (92 160 bytes/s with 8N1) the link carries over 3 000
//! samples per second, so even two sensors at 1 kHz use at most 65 % of it.

use postcard::ser_flavors::{Cobs, Flavor, Slice};
use serde::Serialize;

use crate::layout::CRC_LEN;
use crate::{DeviceMessage, HostMessage, WireError, PROTOCOL_VERSION};

/// Largest postcard payload of a [`DeviceMessage`] (`Info` with a
/// three-byte software revision and sample rate), bytes.
pub const DEVICE_MAX_PAYLOAD_LEN: usize = 50;

/// Largest postcard payload of a [`HostMessage`] (`Configure` with a
/// three-byte sample rate), bytes.
pub const HOST_MAX_PAYLOAD_LEN: usize = 8;

/// Longest encoded [`DeviceMessage`] frame, delimiter included.
pub const DEVICE_MAX_FRAME_LEN: usize = max_frame_len(DEVICE_MAX_PAYLOAD_LEN);

/// Longest encoded [`HostMessage`] frame, delimiter included.
pub const HOST_MAX_FRAME_LEN: usize = max_frame_len(HOST_MAX_PAYLOAD_LEN);

/// Longest encoded frame in either direction, delimiter included: a buffer of
/// this size always suffices for [`encode`], and a
/// [`Decoder`](crate::Decoder) with `N = MAX_FRAME_LEN` accepts every message.
pub const MAX_FRAME_LEN: usize = if DEVICE_MAX_FRAME_LEN > HOST_MAX_FRAME_LEN {
    DEVICE_MAX_FRAME_LEN
} else {
    HOST_MAX_FRAME_LEN
};

/// Upper bound on the encoded length, delimiter included, of a frame whose
/// postcard payload is `payload_len` bytes.
///
/// The COBS body is `1 + payload_len + 4` bytes; COBS adds one header byte
/// per started 254-byte block (`n / 254 + 1` bytes, which also covers the
/// extra empty block postcard's encoder emits after exactly 254 bytes).
pub const fn max_frame_len(payload_len: usize) -> usize {
    let body = 1 + payload_len + CRC_LEN;
    body + body / 254 + 1 + 1
}

/// The CRC-32C engine (`CRC_32_ISCSI`, 256-entry table).
static CRC32C: crc::Crc<u32> = crc::Crc::<u32>::new(&crc::CRC_32_ISCSI);

/// CRC-32C (Castagnoli) of `data`, as carried in every frame.
pub fn crc32c(data: &[u8]) -> u32 {
    CRC32C.checksum(data)
}

/// Postcard flavor that feeds every byte through the CRC and the COBS
/// encoder, and appends the CRC (through COBS) and the delimiter at the end.
struct FrameFlavor<'b> {
    cobs: Cobs<Slice<'b>>,
    digest: crc::Digest<'static, u32>,
}

impl<'b> Flavor for FrameFlavor<'b> {
    type Output = &'b mut [u8];

    fn try_push(&mut self, data: u8) -> postcard::Result<()> {
        self.digest.update(&[data]);
        self.cobs.try_push(data)
    }

    fn try_extend(&mut self, data: &[u8]) -> postcard::Result<()> {
        self.digest.update(data);
        data.iter().try_for_each(|&b| self.cobs.try_push(b))
    }

    fn finalize(mut self) -> postcard::Result<Self::Output> {
        let crc = self.digest.finalize();
        crc.to_le_bytes()
            .iter()
            .try_for_each(|&b| self.cobs.try_push(b))?;
        // Writes the last COBS header and the 0x00 delimiter.
        self.cobs.finalize()
    }
}

/// Encodes `msg` as one complete frame (delimiter included) at the start of
/// `buf` and returns the frame.
///
/// Works for any `Serialize` type; the protocol's messages always fit in
/// [`MAX_FRAME_LEN`] bytes.
///
/// # Errors
///
/// [`WireError::BufferTooSmall`] if the frame does not fit `buf`;
/// [`WireError::Serialize`] if postcard cannot serialise `msg` (never for
/// the protocol's messages).
pub fn encode<'b, M: Serialize + ?Sized>(
    msg: &M,
    buf: &'b mut [u8],
) -> Result<&'b [u8], WireError> {
    let capacity = buf.len();
    let too_small = |_| WireError::BufferTooSmall { capacity };
    let mut flavor = FrameFlavor {
        cobs: Cobs::try_new(Slice::new(buf)).map_err(too_small)?,
        digest: CRC32C.digest(),
    };
    flavor.try_push(PROTOCOL_VERSION).map_err(too_small)?;
    match postcard::serialize_with_flavor(msg, flavor) {
        Ok(frame) => Ok(frame),
        Err(postcard::Error::SerializeBufferFull) => Err(WireError::BufferTooSmall { capacity }),
        Err(e) => Err(WireError::Serialize(e)),
    }
}

/// Encodes a device-to-host message; see [`encode`].
///
/// # Errors
///
/// [`WireError::BufferTooSmall`] if `buf` is shorter than the frame
/// ([`DEVICE_MAX_FRAME_LEN`] always suffices).
pub fn encode_device<'b>(msg: &DeviceMessage, buf: &'b mut [u8]) -> Result<&'b [u8], WireError> {
    encode(msg, buf)
}

/// Encodes a host-to-device message; see [`encode`].
///
/// # Errors
///
/// [`WireError::BufferTooSmall`] if `buf` is shorter than the frame
/// ([`HOST_MAX_FRAME_LEN`] always suffices).
pub fn encode_host<'b>(msg: &HostMessage, buf: &'b mut [u8]) -> Result<&'b [u8], WireError> {
    encode(msg, buf)
}

/// Encodes `msg` as one frame into a new `Vec` (host and simulator side).
///
/// # Errors
///
/// [`WireError::Serialize`] if postcard cannot serialise `msg` (never for
/// the protocol's messages).
#[cfg(feature = "use-std")]
pub fn encode_to_vec<M: Serialize + ?Sized>(msg: &M) -> Result<std::vec::Vec<u8>, WireError> {
    let payload_len = postcard::serialize_with_flavor(msg, postcard::ser_flavors::Size::default())
        .map_err(WireError::Serialize)?;
    let mut buf = std::vec![0u8; max_frame_len(payload_len)];
    let len = encode(msg, &mut buf)?.len();
    buf.truncate(len);
    Ok(buf)
}
