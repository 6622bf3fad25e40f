//! [`Error`]: why the sensor could not be brought up or configured.

use core::fmt;
use embedded_hal::i2c::ErrorKind;

/// Why booting, configuring or reading the BNO055 failed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Error {
    /// An I²C transaction failed (no acknowledge while the chip boots, bus fault, …).
    Bus(ErrorKind),
    /// `CHIP_ID` is not 0xA0: not a BNO055, or the chip is still booting.
    WrongChipId(u8),
    /// A configuration register did not keep the value written to it
    /// (e.g. the chip was not in CONFIG mode).
    NotApplied {
        /// Register page (0 or 1).
        page: u8,
        /// Register address.
        register: u8,
        /// Value written.
        wrote: u8,
        /// Value read back.
        read: u8,
    },
    /// `OPR_MODE` did not read back as AMG after the mode switch.
    ModeNotEntered {
        /// The `OPR_MODE` operation-mode bits read back.
        found: u8,
    },
    /// The configured address is neither 0x28 nor 0x29.
    InvalidAddress(u8),
    /// The configured sample rate is outside 1..=1000 Hz.
    InvalidSampleRate(u16),
    /// The `bno055` driver reported an error that its use here cannot produce
    /// (invalid mode or accelerometer configuration).
    Driver,
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Bus(kind) => write!(f, "BNO055 I2C transaction failed: {kind}"),
            Self::WrongChipId(id) => {
                write!(f, "BNO055 CHIP_ID reads {id:#04x}, expected 0xa0")
            }
            Self::NotApplied {
                page,
                register,
                wrote,
                read,
            } => write!(
                f,
                "BNO055 page {page} register {register:#04x} reads {read:#04x} after writing {wrote:#04x}"
            ),
            Self::ModeNotEntered { found } => {
                write!(f, "BNO055 OPR_MODE reads {found:#04x}, expected AMG (0x07)")
            }
            Self::InvalidAddress(a) => {
                write!(f, "I2C address {a:#04x} is not a BNO055 address (0x28 or 0x29)")
            }
            Self::InvalidSampleRate(r) => {
                write!(f, "sample rate {r} Hz is outside 1..=1000 Hz")
            }
            Self::Driver => f.write_str("bno055 driver reported an unexpected error"),
        }
    }
}

impl core::error::Error for Error {}

impl<E: embedded_hal::i2c::Error> From<bno055::Error<E>> for Error {
    fn from(e: bno055::Error<E>) -> Self {
        match e {
            bno055::Error::I2c(e) => Self::Bus(e.kind()),
            bno055::Error::InvalidChipId(id) => Self::WrongChipId(id),
            bno055::Error::InvalidMode | bno055::Error::AccConfig(_) => Self::Driver,
        }
    }
}

impl Error {
    /// Whether the error is a failed bus transaction (counted in `Status::i2c_errors`).
    pub fn is_bus(&self) -> bool {
        matches!(self, Self::Bus(_))
    }
}
