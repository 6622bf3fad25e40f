//! The core's microsecond clock: TIM5, a 32-bit timer, counting freely at 1 MHz.
//!
//! The prescaler divides the 100 MHz APB1 timer clock by 100 and the counter
//! runs over the full `u32` range (ARR = 0xFFFF_FFFF), so the counter value *is*
//! the wrapping microsecond time the protocol carries (wraps every 71.6 min).

use stm32f4xx_hal::{pac::TIM5, rcc::Rcc, timer::FTimerUs};

/// TIM5 as a free-running 1 MHz counter.
pub struct Tim5Clock {
    tim: TIM5,
}

impl Tim5Clock {
    /// Enables, resets and starts TIM5 at 1 MHz from 0.
    pub fn start(tim: TIM5, rcc: &mut Rcc) -> Self {
        // The HAL enables and resets the timer and computes the 1 MHz prescaler
        // from the frozen clocks (it panics if the timer clock is not a whole
        // number of MHz); the counter itself is set up here, since the HAL's
        // counters stop one tick short of 2^32.
        let tim = FTimerUs::new(tim, rcc).release();
        // SAFETY: every value is valid for the 32-bit auto-reload register.
        tim.arr().write(|w| unsafe { w.bits(u32::MAX) });
        tim.cnt().reset();
        // Load the prescaler now (it is buffered until an update event).
        tim.egr().write(|w| w.ug().set_bit());
        tim.sr().reset();
        tim.cr1().modify(|_, w| w.cen().set_bit());
        Self { tim }
    }

    /// Microseconds since [`start`](Self::start), wrapping.
    pub fn now_us(&self) -> u32 {
        self.tim.cnt().read().bits()
    }
}

impl robimu_firmware::Clock for Tim5Clock {
    fn now_us(&mut self) -> u32 {
        Tim5Clock::now_us(self)
    }
}
