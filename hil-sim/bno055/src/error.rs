//! The simulator's bus error.

use core::fmt;
use embedded_hal::i2c::{Error, ErrorKind, NoAcknowledgeSource};

/// Why a simulated transaction failed. The failed transaction had no effect.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum SimError {
    /// The address was not the simulator's, or the chip is busy (booting,
    /// resetting) and does not acknowledge its address.
    NoAcknowledge,
    /// A fault injected with [`crate::Bno055Sim::fail_next`].
    Injected,
}

impl Error for SimError {
    fn kind(&self) -> ErrorKind {
        match self {
            Self::NoAcknowledge => ErrorKind::NoAcknowledge(NoAcknowledgeSource::Address),
            Self::Injected => ErrorKind::Bus,
        }
    }
}

impl fmt::Display for SimError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::NoAcknowledge => f.write_str("simulated BNO055 did not acknowledge its address"),
            Self::Injected => f.write_str("injected I2C bus fault"),
        }
    }
}

impl core::error::Error for SimError {}
