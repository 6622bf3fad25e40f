//! `embedded-io` 0.6 over a non-blocking `embedded_hal_nb::serial` port.
//!
//! The `embedded-io` contract: `read`/`write` on a non-empty buffer block until
//! at least one byte moved and never return `Ok(0)`; `read_ready`/`write_ready`
//! tell whether they would block. A non-blocking port answers
//! `nb::Error::WouldBlock` instead, and its readiness flags are HAL specific,
//! hence [`SerialReadiness`].

use core::fmt;

use embedded_hal_nb::serial::{self as nbs, ErrorKind};

/// Readiness flags of a UART, read without side effects.
pub trait SerialReadiness {
    /// A received byte waits in the data register (RXNE).
    fn rx_ready(&self) -> bool;
    /// The transmit data register can take a byte (TXE).
    fn tx_ready(&self) -> bool;
}

/// A serial port failure, by kind (overrun, framing, parity, noise, other).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SerialError {
    /// What went wrong, as the port reported it.
    pub kind: ErrorKind,
}

impl SerialError {
    fn from_port<E: nbs::Error>(e: E) -> Self {
        Self { kind: e.kind() }
    }
}

impl fmt::Display for SerialError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "serial port error: {}", self.kind)
    }
}

impl core::error::Error for SerialError {}

impl embedded_io::Error for SerialError {
    fn kind(&self) -> embedded_io::ErrorKind {
        match self.kind {
            ErrorKind::Overrun | ErrorKind::FrameFormat | ErrorKind::Parity | ErrorKind::Noise => {
                embedded_io::ErrorKind::InvalidData
            }
            _ => embedded_io::ErrorKind::Other,
        }
    }
}

/// An `embedded-io` view of a non-blocking serial port.
///
/// A port error met after some bytes already moved is kept and returned by
/// the next call, so a `read`/`write` never both moves bytes and fails.
pub struct NbSerial<S> {
    port: S,
    rx_error: Option<SerialError>,
    tx_error: Option<SerialError>,
}

impl<S> NbSerial<S> {
    /// Wraps a configured port.
    pub const fn new(port: S) -> Self {
        Self {
            port,
            rx_error: None,
            tx_error: None,
        }
    }

    /// The wrapped port.
    pub fn port_mut(&mut self) -> &mut S {
        &mut self.port
    }

    /// Gives the port back.
    pub fn into_inner(self) -> S {
        self.port
    }
}

impl<S> embedded_io::ErrorType for NbSerial<S> {
    type Error = SerialError;
}

impl<S: nbs::Read<u8>> embedded_io::Read for NbSerial<S> {
    /// Blocks for the first byte, then takes whatever else is already there.
    fn read(&mut self, buf: &mut [u8]) -> Result<usize, SerialError> {
        let Some((first, rest)) = buf.split_first_mut() else {
            return Ok(0);
        };
        if let Some(e) = self.rx_error.take() {
            return Err(e);
        }
        *first = nb::block!(self.port.read()).map_err(SerialError::from_port)?;
        let mut n = 1;
        for slot in rest {
            match self.port.read() {
                Ok(byte) => {
                    *slot = byte;
                    n += 1;
                }
                Err(nb::Error::WouldBlock) => break,
                Err(nb::Error::Other(e)) => {
                    self.rx_error = Some(SerialError::from_port(e));
                    break;
                }
            }
        }
        Ok(n)
    }
}

impl<S: nbs::Read<u8> + SerialReadiness> embedded_io::ReadReady for NbSerial<S> {
    fn read_ready(&mut self) -> Result<bool, SerialError> {
        Ok(self.rx_error.is_some() || self.port.rx_ready())
    }
}

impl<S: nbs::Write<u8>> embedded_io::Write for NbSerial<S> {
    /// Blocks until the first byte is taken, then queues bytes while the port
    /// takes them; returns at least 1 for a non-empty buffer.
    fn write(&mut self, buf: &[u8]) -> Result<usize, SerialError> {
        let Some((&first, rest)) = buf.split_first() else {
            return Ok(0);
        };
        if let Some(e) = self.tx_error.take() {
            return Err(e);
        }
        nb::block!(self.port.write(first)).map_err(SerialError::from_port)?;
        let mut n = 1;
        for &byte in rest {
            match self.port.write(byte) {
                Ok(()) => n += 1,
                Err(nb::Error::WouldBlock) => break,
                Err(nb::Error::Other(e)) => {
                    self.tx_error = Some(SerialError::from_port(e));
                    break;
                }
            }
        }
        Ok(n)
    }

    fn flush(&mut self) -> Result<(), SerialError> {
        if let Some(e) = self.tx_error.take() {
            return Err(e);
        }
        nb::block!(self.port.flush()).map_err(SerialError::from_port)
    }
}

impl<S: nbs::Write<u8> + SerialReadiness> embedded_io::WriteReady for NbSerial<S> {
    fn write_ready(&mut self) -> Result<bool, SerialError> {
        Ok(self.tx_error.is_some() || self.port.tx_ready())
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use std::collections::VecDeque;
    use std::vec::Vec;

    use embedded_io::{Read, ReadReady, Write, WriteReady};

    use super::*;

    #[derive(Debug, Clone, Copy)]
    struct FakeError(ErrorKind);
    impl nbs::Error for FakeError {
        fn kind(&self) -> ErrorKind {
            self.0
        }
    }

    /// A UART with a one-byte transmit register that the line drains one
    /// poll in `drain_every`, and a receive queue with injectable errors.
    struct FakeUart {
        tx_full: bool,
        polls: u32,
        drain_every: u32,
        line: Vec<u8>,
        rx: VecDeque<Result<u8, ErrorKind>>,
        /// Bytes become readable only after this many polls.
        rx_delay: u32,
    }

    impl FakeUart {
        fn new(drain_every: u32) -> Self {
            Self {
                tx_full: false,
                polls: 0,
                drain_every,
                line: Vec::new(),
                rx: VecDeque::new(),
                rx_delay: 0,
            }
        }
        fn tick(&mut self) {
            self.polls += 1;
            if self.tx_full && self.polls % self.drain_every == 0 {
                self.tx_full = false;
            }
        }
    }

    impl nbs::ErrorType for FakeUart {
        type Error = FakeError;
    }

    impl nbs::Write<u8> for FakeUart {
        fn write(&mut self, word: u8) -> nb::Result<(), FakeError> {
            self.tick();
            if self.tx_full {
                return Err(nb::Error::WouldBlock);
            }
            self.line.push(word);
            self.tx_full = true;
            Ok(())
        }
        fn flush(&mut self) -> nb::Result<(), FakeError> {
            self.tick();
            if self.tx_full {
                Err(nb::Error::WouldBlock)
            } else {
                Ok(())
            }
        }
    }

    impl nbs::Read<u8> for FakeUart {
        fn read(&mut self) -> nb::Result<u8, FakeError> {
            if self.rx_delay > 0 {
                self.rx_delay -= 1;
                return Err(nb::Error::WouldBlock);
            }
            match self.rx.pop_front() {
                None => Err(nb::Error::WouldBlock),
                Some(Ok(b)) => Ok(b),
                Some(Err(kind)) => Err(nb::Error::Other(FakeError(kind))),
            }
        }
    }

    impl SerialReadiness for FakeUart {
        fn rx_ready(&self) -> bool {
            self.rx_delay == 0 && !self.rx.is_empty()
        }
        fn tx_ready(&self) -> bool {
            !self.tx_full
        }
    }

    #[test]
    fn write_never_returns_zero_and_write_all_delivers_in_order() {
        for drain_every in [1, 2, 3, 7] {
            let mut s = NbSerial::new(FakeUart::new(drain_every));
            let data: Vec<u8> = (0..=255u8).cycle().take(1000).collect();
            let mut rest = &data[..];
            while !rest.is_empty() {
                let n = s.write(rest).unwrap();
                assert!(n >= 1 && n <= rest.len(), "write returned {n}");
                rest = &rest[n..];
            }
            s.write_all(&data).unwrap();
            s.flush().unwrap();
            assert!(s.write_ready().unwrap(), "flushed port must be ready");
            let mut expected = data.clone();
            expected.extend_from_slice(&data);
            assert_eq!(s.into_inner().line, expected);
        }
    }

    #[test]
    fn write_ready_follows_the_transmit_register() {
        let mut s = NbSerial::new(FakeUart::new(1000));
        assert!(s.write_ready().unwrap());
        assert_eq!(s.write(&[1, 2, 3]).unwrap(), 1, "register holds one byte");
        assert!(!s.write_ready().unwrap());
        assert_eq!(s.write(&[]).unwrap(), 0);
    }

    #[test]
    fn read_blocks_for_one_byte_then_drains_what_is_there() {
        let mut uart = FakeUart::new(1);
        uart.rx.extend([Ok(10), Ok(11), Ok(12)]);
        uart.rx_delay = 5;
        let mut s = NbSerial::new(uart);
        assert!(!s.read_ready().unwrap());
        let mut buf = [0u8; 8];
        let n = s.read(&mut buf).unwrap();
        assert_eq!(&buf[..n], &[10, 11, 12]);
        assert!(!s.read_ready().unwrap());
        assert_eq!(s.read(&mut []).unwrap(), 0);
    }

    #[test]
    fn an_error_after_data_is_reported_by_the_next_read() {
        let mut uart = FakeUart::new(1);
        uart.rx
            .extend([Ok(1), Err(ErrorKind::Overrun), Ok(2), Err(ErrorKind::Noise)]);
        let mut s = NbSerial::new(uart);
        let mut buf = [0u8; 8];
        assert_eq!(s.read(&mut buf).unwrap(), 1);
        assert_eq!(buf[0], 1);
        assert!(s.read_ready().unwrap(), "a pending error must not block");
        let e = s.read(&mut buf).unwrap_err();
        assert_eq!(e.kind, ErrorKind::Overrun);
        assert_eq!(
            embedded_io::Error::kind(&e),
            embedded_io::ErrorKind::InvalidData
        );
        assert_eq!(s.read(&mut buf).unwrap(), 1);
        assert_eq!(buf[0], 2);
        assert_eq!(s.read(&mut buf).unwrap_err().kind, ErrorKind::Noise);
        assert!(std::format!("{e}").contains("overrun"));
    }
}
