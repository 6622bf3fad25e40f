//! Glue between board HALs and the robimu acquisition core.
//!
//! - [`NbSerial`] turns a non-blocking `embedded_hal_nb::serial` port into the
//!   `embedded-io` 0.6 `Read + ReadReady + Write + WriteReady` the core wants,
//!   and never answers a non-empty `write` with `Ok(0)` (stm32f4xx-hal 0.23's
//!   own `embedded_io::Write` does, which makes `write_all` panic).
//! - [`TickExtender`] turns a free-running hardware tick counter of any width
//!   (up or down) into the core's wrapping 32-bit microsecond clock.
//!
//! Hardware-free, so the logic is unit-tested on the host:
//! `cargo test -p robimu-board-io --target x86_64-unknown-linux-gnu`.
#![no_std]
#![deny(missing_docs)]

mod serial;
mod ticks;

pub use serial::{NbSerial, SerialError, SerialReadiness};
pub use ticks::{CountDirection, TickExtender};
