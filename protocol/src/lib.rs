//! Wire protocol between the robimu IMU board and the host.
//!
//! * [`messages`]: the message table ([`DeviceMessage`], [`HostMessage`]).
//! * [`frame`]: framing — `COBS(version ++ postcard(message) ++ CRC-32C) ++ 0x00`
//!   — and [`encode`] into a caller's buffer, with the worst-case frame sizes.
//! * [`alias`]: the read rate against the chip's internal updates
//!   ([`SensorTiming::alias_free_rate`], the default [`DEFAULT_SAMPLE_RATE_HZ`]).
//! * [`decoder`]: the streaming [`Decoder`] (fixed buffer, resynchronising,
//!   with [`DecoderStats`]).
//! * [`error`]: [`WireError`], every way a frame can fail.
//!
//! `no_std` without allocation; the `use-std` feature adds
//! [`encode_to_vec`] and `std` error support in dependencies.
#![cfg_attr(not(feature = "use-std"), no_std)]
#![deny(unsafe_code, missing_docs)]
// Input bytes must never be able to panic the firmware.
#![cfg_attr(
    not(test),
    deny(
        clippy::indexing_slicing,
        clippy::unwrap_used,
        clippy::expect_used,
        clippy::panic
    )
)]

pub mod alias;
pub mod decoder;
pub mod error;
pub mod frame;
pub mod layout;
pub mod messages;

pub use alias::{
    AliasLine, AliasSensor, RateChoice, ALIAS_CLOCK_TOLERANCE, ALIAS_MARGIN_HZ,
    ALIAS_MIN_AMPLITUDE_S, RATE_CHOICES_HZ,
};
pub use decoder::{Decoder, DecoderStats, DeviceDecoder, Frames, HostDecoder};
pub use error::WireError;
#[cfg(feature = "use-std")]
pub use frame::encode_to_vec;
pub use frame::{
    crc32c, encode, encode_device, encode_host, max_frame_len, DEVICE_MAX_FRAME_LEN,
    DEVICE_MAX_PAYLOAD_LEN, HOST_MAX_FRAME_LEN, HOST_MAX_PAYLOAD_LEN, MAX_FRAME_LEN,
};
pub use layout::{CRC_LEN, DELIMITER, MIN_DECODED_LEN};
pub use messages::*;

/// Protocol version carried in every frame. Bump on any incompatible change
/// to the message table or the framing; a receiver refuses frames of any
/// other version ([`WireError::WrongVersion`], the version kept in
/// [`DecoderStats::foreign_version`]).
///
/// History: 1, the first; 2, [`DeviceInfo::timing`] (the sensors'
/// bandwidths and internal output data rates) — every other message's
/// payload is as in version 1; 3, several sensors per board:
/// [`ImuSample::sensor`] (first field), [`Status::sensor`] and
/// [`DeviceInfo::sensor`] / [`DeviceInfo::sensors`] (last fields) — one
/// `Info` and one `Status` per sensor; `Pong`, `CommandResult` and every
/// host message are as in version 2. Not backward compatible: a version-2
/// host refuses version-3 frames by their version byte, and this host
/// refuses version-2 boards the same way.
pub const PROTOCOL_VERSION: u8 = 3;
