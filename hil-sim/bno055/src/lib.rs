//! Register-level simulated Bosch BNO055, as an `embedded_hal::i2c::I2c` device.
//!
//! [`Bno055Sim`] answers on one 7-bit address (a [`Bno055Bus`] holds two,
//! at 0x28 and 0x29, on one bus) with the BNO055 register map
//! (datasheet BST-BNO055-DS000, section 4): two pages selected by `PAGE_ID`
//! (0x07), identity registers, `OPR_MODE` rules (configuration registers only
//! writable in CONFIG mode), `SYS_TRIGGER` reset, auto-incrementing bursts, and
//! the AMG data registers, filled from a [`SampleSource`] whenever a burst read
//! starts at a data register. For tests it can also refuse transactions while
//! "booting" and fail transactions on demand ([`Bno055Sim::fail_next`]).
//!
//! Two chip models ([`ChipModel`]): the ideal chip (the default) latches a
//! fresh reading from the source at every data read; in datasheet mode the
//! accelerometer and gyroscope sample on their own internal clocks at the
//! output data rates their configured bandwidths imply, low-pass filtered
//! at those bandwidths, and the registers hold the last update between two
//! ([`timing`]: the datasheet facts and what is assumed).
//!
//! The simulator has no clock of its own: busy periods are counted in bus
//! transactions, and in datasheet mode time is the source's
//! ([`Stimulus::t_s`]).
#![no_std]
#![deny(unsafe_code, missing_docs)]

#[cfg(feature = "alloc")]
extern crate alloc;
#[cfg(test)]
extern crate std;

mod bus;
mod error;
pub mod regs;
mod sim;
mod source;
pub mod timing;

pub use bus::Bno055Bus;
pub use error::SimError;
pub use sim::{Bno055Sim, ChipModel};
pub use source::{ConstantSource, RawReading, SampleSource, SineSource, Stimulus};
pub use timing::{Sensor, Timing};
