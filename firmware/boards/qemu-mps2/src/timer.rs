//! Time from CMSDK APB timer 0: a 32-bit down counter at the 25 MHz APB clock.
//!
//! [`Mps2Clock`] extends it to the wrapping microsecond clock (it must be
//! read at least once per 2^32 ticks, 172 s); [`Mps2Delay`] busy-waits on it.
//! QEMU drives the counter from its virtual clock, so with `-icount` the time
//! seen here is a pure function of the instructions executed.

use core::ptr::{read_volatile, write_volatile};

use robimu_board_io::{CountDirection, TickExtender};

/// Timer 0 on the MPS2 AN385/AN386 images.
pub const TIMER0_BASE: usize = 0x4000_0000;
/// The APB clock of the MPS2 FPGA images (QEMU's `SYSCLK_FRQ`).
pub const PCLK_HZ: u32 = 25_000_000;
const TICKS_PER_US: u32 = PCLK_HZ / 1_000_000;

const CTRL: usize = 0x00;
const VALUE: usize = 0x04;
const RELOAD: usize = 0x08;
const CTRL_ENABLE: u32 = 1 << 0;

/// A running CMSDK APB timer's counter register.
#[derive(Clone, Copy)]
pub struct Timer {
    base: usize,
}

impl Timer {
    /// Starts the timer counting down from 0xFFFF_FFFF, reloading the same.
    ///
    /// # Safety
    /// `base` must be the address of a CMSDK APB timer that nothing else
    /// reprograms.
    pub unsafe fn start(base: usize) -> Self {
        let timer = Self { base };
        // SAFETY: `base` is a CMSDK timer's register block (contract above).
        unsafe {
            write_volatile((base + CTRL) as *mut u32, 0);
            write_volatile((base + RELOAD) as *mut u32, u32::MAX);
            write_volatile((base + VALUE) as *mut u32, u32::MAX);
            write_volatile((base + CTRL) as *mut u32, CTRL_ENABLE);
        }
        timer
    }

    /// The counter value (counts down).
    pub fn ticks(&self) -> u32 {
        // SAFETY: reading VALUE has no side effect; `base` checked in `start`.
        unsafe { read_volatile((self.base + VALUE) as *const u32) }
    }
}

/// Microseconds since the clock was made, wrapping modulo 2³².
pub struct Mps2Clock {
    timer: Timer,
    ext: TickExtender,
}

impl Mps2Clock {
    /// A clock reading 0 now.
    pub fn new(timer: Timer) -> Self {
        Self {
            timer,
            ext: TickExtender::new(32, CountDirection::Down, TICKS_PER_US, timer.ticks()),
        }
    }

    /// The current time, µs (wrapping).
    pub fn now_us(&mut self) -> u32 {
        self.ext.update(self.timer.ticks())
    }
}

/// Blocking delays measured on the timer.
pub struct Mps2Delay {
    timer: Timer,
}

impl Mps2Delay {
    /// Delays on `timer`.
    pub fn new(timer: Timer) -> Self {
        Self { timer }
    }

    /// Waits at least `ticks` ticks (at most 2^32 - 1 = 172 s).
    fn wait_ticks(&mut self, ticks: u32) {
        let start = self.timer.ticks();
        while start.wrapping_sub(self.timer.ticks()) < ticks {}
    }
}

impl embedded_hal::delay::DelayNs for Mps2Delay {
    fn delay_ns(&mut self, ns: u32) {
        // 25 ticks per µs = 1 tick per 40 ns; round up so the wait is never short.
        self.wait_ticks(ns.div_ceil(1_000_000_000 / PCLK_HZ));
    }

    fn delay_us(&mut self, us: u32) {
        for _ in 0..us / 1_000_000 {
            self.wait_ticks(1_000_000 * TICKS_PER_US);
        }
        self.wait_ticks(us % 1_000_000 * TICKS_PER_US);
    }

    fn delay_ms(&mut self, ms: u32) {
        for _ in 0..ms / 1_000 {
            self.wait_ticks(1_000_000 * TICKS_PER_US);
        }
        self.wait_ticks(ms % 1_000 * 1_000 * TICKS_PER_US);
    }
}
