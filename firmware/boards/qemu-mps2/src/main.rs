//! The robimu acquisition core on QEMU's `mps2-an386` (Cortex-M4F), with two
//! simulated BNO055 on its I²C bus (0x28 and 0x29, [`Bno055Bus`]): the
//! cross-compiled smoke test.
//!
//! The real [`Acquisition`] runs with `autostart`, streams protocol frames on
//! CMSDK UART0 (QEMU's `-serial`), and after [`SAMPLES_TO_SEND`] samples of
//! each sensor leaves QEMU through semihosting: exit status 0 when nothing
//! was dropped and no I²C transaction failed, 1 otherwise (or on panic). Run it with
//! `run.sh` beside this crate or the `qemu_smoke` test of `robimu-tests`.
#![no_std]
#![no_main]

mod stack;
mod timer;
mod uart;
mod vectors;

use cortex_m_rt::entry;
use cortex_m_semihosting::{debug, hprintln};
use robimu_bno055_sim::{Bno055Bus, Bno055Sim, SineSource};
use robimu_firmware::{Acquisition, Clock, Config};

use timer::{Mps2Clock, Mps2Delay, Timer, PCLK_HZ, TIMER0_BASE};
use uart::{CmsdkUart, UART0_BASE};

/// Samples streamed per sensor before the image exits.
pub const SAMPLES_TO_SEND: u32 = 300;
/// Simulated chips: addresses (the `Config` default, Adafruit-style, and
/// the other one), and how many transactions they ignore while "booting"
/// (exercises the boot retry).
const SIM_ADDRESS: u8 = 0x28;
const SIM_SECOND_ADDRESS: u8 = 0x29;
const SIM_BOOT_TRANSACTIONS: u32 = 3;
/// Readings per sine period of the second chip (the first has the default
/// 200), so that the host tells their streams apart.
pub const SECOND_SINE_PERIOD: u32 = 150;
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
    let bus = Bno055Bus::two(
        Bno055Sim::new(SIM_ADDRESS, SineSource::default()).booting_for(SIM_BOOT_TRANSACTIONS),
        Bno055Sim::new(SIM_SECOND_ADDRESS, SineSource::new(SECOND_SINE_PERIOD))
            .booting_for(SIM_BOOT_TRANSACTIONS),
    );
    let config = Config {
        i2c_address: SIM_ADDRESS,
        second_address: Some(SIM_SECOND_ADDRESS),
        autostart: true,
        ..Config::default()
    };
    let mut acquisition = Acquisition::new(
        bus,
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
        let (status, second) = (acquisition.status_of(0), acquisition.status_of(1));
        if status.samples_sent.min(second.samples_sent) >= SAMPLES_TO_SEND
            && acquisition.tx_queued() == 0
        {
            hprintln!("robimu-qemu-mps2: {:?}", status);
            hprintln!("robimu-qemu-mps2: {:?}", second);
            match stack::high_water_bytes() {
                Some(bytes) => hprintln!("robimu-qemu-mps2: stack high-water mark {} bytes", bytes),
                None => hprintln!(
                    "robimu-qemu-mps2: stack deeper than {} bytes",
                    stack::PAINT_SPAN
                ),
            }
            exit(
                [status, second]
                    .iter()
                    .all(|s| s.samples_dropped == 0 && s.i2c_errors == 0),
            );
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
