//! The fixed parts of a frame's layout, `COBS( version ‖ postcard(message) ‖
//! CRC-32C ) 0x00`: what the encoder ([`crate::frame`]), the decoder
//! ([`crate::decoder`]) and the errors ([`crate::error`]) all refer to.

/// The frame delimiter. Never occurs inside a COBS-encoded frame.
pub const DELIMITER: u8 = 0x00;

/// Length of the CRC-32C trailer, bytes.
pub const CRC_LEN: usize = 4;

/// The shortest valid decoded frame: version byte, a one-byte message
/// (e.g. [`HostMessage::Start`](crate::HostMessage::Start)), CRC.
pub const MIN_DECODED_LEN: usize = 1 + 1 + CRC_LEN;
