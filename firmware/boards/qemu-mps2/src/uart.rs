//! CMSDK APB UART (ARM DDI0479C §4.3), as QEMU models it on the MPS2 boards.
//!
//! Always 8N1; `BAUDDIV` must be at least 16 or QEMU ignores the port. QEMU
//! hands each byte to the character backend as soon as `DATA` is written, so
//! `TXFULL` clears at once when the backend (a file, a pty) keeps up.

use core::convert::Infallible;
use core::ptr::{read_volatile, write_volatile};

/// UART0 on the MPS2 AN385/AN386 images (QEMU's `-serial` number 0).
pub const UART0_BASE: usize = 0x4000_4000;

const DATA: usize = 0x00;
const STATE: usize = 0x04;
const CTRL: usize = 0x08;
const BAUDDIV: usize = 0x10;

const STATE_TXFULL: u32 = 1 << 0;
const STATE_RXFULL: u32 = 1 << 1;
const CTRL_TX_EN: u32 = 1 << 0;
const CTRL_RX_EN: u32 = 1 << 1;

/// An enabled CMSDK APB UART, polled.
pub struct CmsdkUart {
    base: usize,
}

impl CmsdkUart {
    /// Programs the divider for `baud` from the `pclk_hz` APB clock and
    /// enables transmit and receive.
    ///
    /// # Safety
    /// `base` must be the address of a CMSDK APB UART that nothing else uses.
    pub unsafe fn new(base: usize, pclk_hz: u32, baud: u32) -> Self {
        let uart = Self { base };
        let div = (pclk_hz / baud.max(1)).max(16);
        uart.write_reg(BAUDDIV, div);
        uart.write_reg(CTRL, CTRL_TX_EN | CTRL_RX_EN);
        uart
    }

    fn read_reg(&self, offset: usize) -> u32 {
        // SAFETY: `new`'s contract: `base` is a CMSDK UART's register block.
        unsafe { read_volatile((self.base + offset) as *const u32) }
    }

    fn write_reg(&self, offset: usize, value: u32) {
        // SAFETY: as in `read_reg`.
        unsafe { write_volatile((self.base + offset) as *mut u32, value) }
    }

    fn tx_full(&self) -> bool {
        self.read_reg(STATE) & STATE_TXFULL != 0
    }

    fn rx_full(&self) -> bool {
        self.read_reg(STATE) & STATE_RXFULL != 0
    }
}

impl embedded_io::ErrorType for CmsdkUart {
    type Error = Infallible;
}

impl embedded_io::Write for CmsdkUart {
    /// Blocks until the first byte is taken; never returns `Ok(0)` for a
    /// non-empty buffer.
    fn write(&mut self, buf: &[u8]) -> Result<usize, Infallible> {
        let mut n = 0;
        for &byte in buf {
            if n > 0 && self.tx_full() {
                break;
            }
            while self.tx_full() {}
            self.write_reg(DATA, u32::from(byte));
            n += 1;
        }
        Ok(n)
    }

    fn flush(&mut self) -> Result<(), Infallible> {
        while self.tx_full() {}
        Ok(())
    }
}

impl embedded_io::WriteReady for CmsdkUart {
    fn write_ready(&mut self) -> Result<bool, Infallible> {
        Ok(!self.tx_full())
    }
}

impl embedded_io::Read for CmsdkUart {
    /// Blocks for the first byte, then takes what else is there.
    fn read(&mut self, buf: &mut [u8]) -> Result<usize, Infallible> {
        let mut n = 0;
        for slot in buf.iter_mut() {
            if n > 0 && !self.rx_full() {
                break;
            }
            while !self.rx_full() {}
            *slot = self.read_reg(DATA) as u8;
            n += 1;
        }
        Ok(n)
    }
}

impl embedded_io::ReadReady for CmsdkUart {
    fn read_ready(&mut self) -> Result<bool, Infallible> {
        Ok(self.rx_full())
    }
}
