//! robimu acquisition firmware for the STM32F411CE "Black Pill".
//!
//! BNO055 on I2C1 (PB6 SCL, PB7 SDA, 400 kHz); protocol frames on USART1
//! (PA9 TX, PA10 RX, 921600 8N1); 100 MHz from the 25 MHz crystal. The
//! acquisition core does everything else: see `robimu_firmware`.
#![no_std]
#![no_main]

mod clock;
mod port;

use cortex_m_rt::entry;
use panic_halt as _;
use robimu_board_io::NbSerial;
use robimu_firmware::{Acquisition, Config};
use stm32f4xx_hal::{
    i2c::{DutyCycle, I2c, Mode},
    pac,
    prelude::*,
    rcc, serial,
};

use clock::Tim5Clock;
use port::Usart1;

/// BNO055 I²C address: 0x28 with the ADR/COM3 pin low (the Adafruit board's
/// default), 0x29 with it tied to 3.3 V.
const BNO055_ADDRESS: u8 = 0x28;
/// A second BNO055 on the same bus (its ADR pin tied to 3.3 V: 0x29), read
/// on the same tick: `Some(0x29)` for a two-sensor board.
const SECOND_BNO055_ADDRESS: Option<u8> = None;

/// USART1 baud rate. At PCLK2 = 100 MHz the divider gives 917 431 Bd (-0.45 %).
const BAUD: u32 = 921_600;

#[entry]
fn main() -> ! {
    // `take` only fails on a second call; this is the first.
    let dp = pac::Peripherals::take().unwrap();
    let mut rcc = dp.RCC.freeze(rcc::Config::hse(25.MHz()).sysclk(100.MHz()));

    let gpioa = dp.GPIOA.split(&mut rcc);
    let gpiob = dp.GPIOB.split(&mut rcc);

    let i2c = I2c::new(
        dp.I2C1,
        (gpiob.pb6, gpiob.pb7),
        Mode::fast(400.kHz(), DutyCycle::Ratio2to1),
        &mut rcc,
    );
    // Only an unreachable baud rate makes this fail.
    let usart = dp
        .USART1
        .serial(
            (gpioa.pa9, gpioa.pa10),
            serial::Config::default().baudrate(BAUD.bps()),
            &mut rcc,
        )
        .unwrap();
    let delay = dp.TIM2.delay_us(&mut rcc);
    let clock = Tim5Clock::start(dp.TIM5, &mut rcc);

    let config = Config {
        i2c_address: BNO055_ADDRESS,
        second_address: SECOND_BNO055_ADDRESS,
        ..Config::default()
    };
    let mut acquisition = Acquisition::new(i2c, delay, NbSerial::new(Usart1(usart)), clock, config);
    // A sensor that does not come up is not fatal: the core reports it in
    // `DeviceInfo`/`Status`, answers the host and retries on its own.
    let _ = acquisition.start();
    loop {
        acquisition.poll();
    }
}
