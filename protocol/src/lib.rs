//! Wire protocol between the robimu IMU board and the host.
//!
//! The message table lives in [`messages`]. Framing, CRC and the streaming
//! decoder are documented in their own modules.
#![cfg_attr(not(feature = "use-std"), no_std)]
#![deny(unsafe_code, missing_docs)]

pub mod messages;
pub use messages::*;

/// Protocol version carried in every frame. Bump on any incompatible change
/// to the message table or the framing.
pub const PROTOCOL_VERSION: u8 = 1;
