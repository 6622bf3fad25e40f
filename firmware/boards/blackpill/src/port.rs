//! USART1 as the `embedded-io` byte stream the acquisition core writes frames to.
//!
//! stm32f4xx-hal 0.23's own `embedded_io::Write` returns `Ok(0)` when the
//! transmit register is full, which makes `write_all` panic; this goes through
//! its `embedded_hal_nb::serial` implementation and the board-io adapter
//! instead, with TXE/RXNE as the readiness flags.

use robimu_board_io::SerialReadiness;
use stm32f4xx_hal::{
    pac::USART1,
    prelude::*,
    serial::{self, Serial},
};

/// USART1 (PA9 TX, PA10 RX), 8N1.
pub struct Usart1(pub Serial<USART1, u8>);

impl embedded_hal_nb::serial::ErrorType for Usart1 {
    type Error = serial::Error;
}

impl embedded_hal_nb::serial::Read<u8> for Usart1 {
    fn read(&mut self) -> nb::Result<u8, serial::Error> {
        self.0.read()
    }
}

impl embedded_hal_nb::serial::Write<u8> for Usart1 {
    fn write(&mut self, word: u8) -> nb::Result<(), serial::Error> {
        self.0.write(word)
    }

    fn flush(&mut self) -> nb::Result<(), serial::Error> {
        self.0.flush()
    }
}

impl SerialReadiness for Usart1 {
    fn rx_ready(&self) -> bool {
        self.0.is_rx_not_empty()
    }

    fn tx_ready(&self) -> bool {
        self.0.is_tx_empty()
    }
}
