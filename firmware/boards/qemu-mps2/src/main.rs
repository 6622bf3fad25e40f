//! The robimu acquisition core on QEMU's `mps2-an386` (Cortex-M4F), with a
//! simulated BNO055 as its I²C device: the cross-compiled smoke test.
//!
//! The real [`Acquisition`] runs with `autostart`, streams protocol frames on
//! CMSDK UART0 (QEMU's `-serial`), and after [`SAMPLES_TO_SEND`] samples
//! leaves QEMU through semihosting: exit status 0 when nothing was dropped
//! and no I²C transaction failed, 1 otherwise (or on panic). Run it with
//! `run.sh` beside this crate or the `qemu_smoke` test of `robimu-tests`.
#![no_std]
#![no_main]

mod stack;
mod timer;
mod uart;
mod vectors;

use cortex_m_rt::entry;
use cortex_m_semihosting::{debug, hprintln};
use robimu_bno055_sim::{Bno055Sim, SineSource};
use robimu_firmware::{Acquisition, Clock, Config};

use timer::{Mps2Clock, Mps2Delay, Timer, PCLK_HZ, TIMER0_BASE};
use uart::{CmsdkUart, UART0_BASE};

/// Samples streamed before the image exits.
pub const SAMPLES_TO_SEND: u32 = 300;
/// Simulated chip: address (the `Config` default, Adafruit-style), and how
/// many transactions it ignores while "booting" (exercises the boot retry).
const SIM_ADDRESS: u8 = 0x28;
const SIM_BOOT_TRANSACTIONS: u32 = 3;
/// UART0 baud rate: only the divider register cares in QEMU.
const BAUD: u32 = 921_600;

impl Clock for Mps2Clock {
    fn now_us(&mut self) -> u32 {
        Mps2Clock::now_us(self)
    }
}

#[entry]
fn main() -> ! {
    stack::paint();
    // SAFETY: UART0 and timer 0 are the AN386's, and used nowhere else.
    let serial = unsafe { CmsdkUart::new(UART0_BASE, PCLK_HZ, BAUD) };
    // SAFETY: as above.
    let timer = unsafe { Timer::start(TIMER0_BASE) };
    let sensor =
        Bno055Sim::new(SIM_ADDRESS, SineSource::default()).booting_for(SIM_BOOT_TRANSACTIONS);
    let config = Config {
        i2c_address: SIM_ADDRESS,
        autostart: true,
        ..Config::default()
    };
    let mut acquisition = Acquisition::new(
        sensor,
        Mps2Delay::new(timer),
        serial,
        Mps2Clock::new(timer),
        config,
    );
    if let Err(e) = acquisition.start() {
        hprintln!("robimu-qemu-mps2: sensor start failed: {}", e);
        exit(false);
    }
    loop {
        acquisition.poll();
        let status = acquisition.status();
        if status.samples_sent >= SAMPLES_TO_SEND && acquisition.tx_queued() == 0 {
            hprintln!("robimu-qemu-mps2: {:?}", status);
            match stack::high_water_bytes() {
                Some(bytes) => hprintln!("robimu-qemu-mps2: stack high-water mark {} bytes", bytes),
                None => hprintln!(
                    "robimu-qemu-mps2: stack deeper than {} bytes",
                    stack::PAINT_SPAN
                ),
            }
            exit(status.samples_dropped == 0 && status.i2c_errors == 0);
        }
    }
}

/// Ends the QEMU run with exit status 0 (`ok`) or 1.
fn exit(ok: bool) -> ! {
    debug::exit(if ok {
        debug::EXIT_SUCCESS
    } else {
        debug::EXIT_FAILURE
    });
    // Only reached without a semihosting host (e.g. on real hardware).
    loop {
        cortex_m::asm::wfi();
    }
}

#[panic_handler]
fn panic(info: &core::panic::PanicInfo) -> ! {
    hprintln!("robimu-qemu-mps2: {}", info);
    exit(false)
}
