//! no_std acquisition core of the robimu IMU board.
//!
//! [`Acquisition`] drives a Bosch BNO055 in AMG (raw, non-fusion) mode over
//! any embedded-hal 1.0 [`I2c`](embedded_hal::i2c::I2c) bus, samples it at a
//! fixed rate on a deadline schedule ([`schedule`]), timestamps each reading
//! with the device [`Clock`], and streams [`robimu_protocol`] frames over an
//! embedded-io serial port, answering host commands. It counts and survives
//! I²C errors and a backed-up link; it never blocks for long and never panics.
//!
//! * [`config`]: [`Config`] (bus address, sensor settings, timing, retry policy).
//! * [`sensor`]: booting and configuring the chip with the `bno055` crate,
//!   plus the one-transaction burst read of a sample.
//! * [`regs`]: register addresses and the settings' register encodings.
//! * [`schedule`]: drift-free sample deadlines.
//! * [`tx_queue`]: the fixed transmit queue that drops samples, never blocks.
//! * [`acquisition`]: the core tying these together.
#![no_std]
#![deny(unsafe_code, missing_docs)]
// Bus and serial input must never be able to panic the firmware.
#![cfg_attr(
    not(test),
    deny(
        clippy::indexing_slicing,
        clippy::unwrap_used,
        clippy::expect_used,
        clippy::panic
    )
)]

pub mod acquisition;
pub mod clock;
pub mod config;
pub mod error;
pub mod regs;
pub mod schedule;
pub mod sensor;
pub mod tx_queue;

pub use acquisition::Acquisition;
pub use clock::Clock;
pub use config::Config;
pub use error::Error;
pub use sensor::Identity;

pub use crate::sensor::AmgReading;

/// Firmware version `[major, minor, patch]`, from the crate version.
pub const FIRMWARE_VERSION: [u8; 3] = [
    parse_u8(env!("CARGO_PKG_VERSION_MAJOR")),
    parse_u8(env!("CARGO_PKG_VERSION_MINOR")),
    parse_u8(env!("CARGO_PKG_VERSION_PATCH")),
];

/// Decimal digits to `u8`, saturating; other characters count as 0
/// (compile-time only).
const fn parse_u8(s: &str) -> u8 {
    let mut rest = s.as_bytes();
    let mut value: u32 = 0;
    while let [b, tail @ ..] = rest {
        let digit = if b.is_ascii_digit() {
            (*b - b'0') as u32
        } else {
            0
        };
        value = value * 10 + digit;
        if value > 255 {
            return 255;
        }
        rest = tail;
    }
    value as u8
}
