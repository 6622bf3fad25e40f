//! A wrapping 32-bit microsecond clock from a narrower or faster tick counter.
//!
//! Hardware counters rarely count microseconds over the full `u32` range:
//! SysTick is 24 bits wide, the CMSDK timer counts 25 MHz ticks down. The
//! extender accumulates the counter's wrapping difference between calls (so
//! it must be called at least once per counter period, `2^bits` ticks) and
//! carries the sub-microsecond remainder, so no time is lost or invented
//! between calls.

/// Which way the hardware counter runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CountDirection {
    /// Counts up and wraps from `2^bits - 1` to 0.
    Up,
    /// Counts down and reloads `2^bits - 1` after 0.
    Down,
}

/// Turns raw counter reads into wrapping microseconds.
#[derive(Debug, Clone)]
pub struct TickExtender {
    mask: u32,
    direction: CountDirection,
    ticks_per_us: u32,
    last_raw: u32,
    rem_ticks: u32,
    now_us: u32,
}

impl TickExtender {
    /// A clock reading 0 µs at counter value `raw_now`.
    ///
    /// `bits` (1..=32) is the counter width; the counter must run over its
    /// full range (reload value `2^bits - 1`). `ticks_per_us` (>= 1) is the
    /// counter frequency in MHz. Out-of-range arguments are clamped.
    pub const fn new(
        bits: u32,
        direction: CountDirection,
        ticks_per_us: u32,
        raw_now: u32,
    ) -> Self {
        let bits = if bits == 0 {
            1
        } else if bits > 32 {
            32
        } else {
            bits
        };
        let mask = if bits == 32 {
            u32::MAX
        } else {
            (1 << bits) - 1
        };
        Self {
            mask,
            direction,
            ticks_per_us: if ticks_per_us == 0 { 1 } else { ticks_per_us },
            last_raw: raw_now & mask,
            rem_ticks: 0,
            now_us: 0,
        }
    }

    /// Advances by the ticks elapsed since the previous call and returns the
    /// time in µs (wrapping modulo 2³²).
    pub fn update(&mut self, raw: u32) -> u32 {
        let raw = raw & self.mask;
        let elapsed = match self.direction {
            CountDirection::Up => raw.wrapping_sub(self.last_raw),
            CountDirection::Down => self.last_raw.wrapping_sub(raw),
        } & self.mask;
        self.last_raw = raw;
        let mut us = elapsed / self.ticks_per_us;
        // rem_ticks < ticks_per_us, so this sum cannot overflow.
        self.rem_ticks += elapsed % self.ticks_per_us;
        if self.rem_ticks >= self.ticks_per_us {
            self.rem_ticks -= self.ticks_per_us;
            us += 1;
        }
        self.now_us = self.now_us.wrapping_add(us);
        self.now_us
    }

    /// The time returned by the last [`update`](Self::update).
    pub fn now_us(&self) -> u32 {
        self.now_us
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// xorshift32: deterministic steps without a dependency.
    fn next(state: &mut u32) -> u32 {
        *state ^= *state << 13;
        *state ^= *state >> 17;
        *state ^= *state << 5;
        *state
    }

    /// Drives a modelled counter with random steps shorter than its period and
    /// compares with floor(total ticks / ticks per µs) mod 2³² computed from
    /// an exact 128-bit tick total.
    fn check(bits: u32, direction: CountDirection, tpu: u32, start: u32, steps: usize) {
        let period: u128 = 1u128 << bits;
        let mut seed = 0x9E37_79B9 ^ bits ^ tpu;
        let mut total: u128 = 0;
        let raw_at = |t: u128| -> u32 {
            let pos = (u128::from(start) + t) % period;
            match direction {
                CountDirection::Up => pos as u32,
                CountDirection::Down => ((period - 1 - pos) % period) as u32,
            }
        };
        let mut ext = TickExtender::new(bits, direction, tpu, raw_at(0));
        for i in 0..steps {
            let step = if i % 97 == 0 {
                (period - 1) as u64 // the longest allowed gap
            } else {
                u64::from(next(&mut seed)) % (period as u64)
            };
            total += u128::from(step);
            // Garbage above the counter width must be ignored.
            let noise = if bits < 32 {
                next(&mut seed) << bits
            } else {
                0
            };
            let got = ext.update(raw_at(total) | noise);
            let want = ((total / u128::from(tpu)) % (1u128 << 32)) as u32;
            assert_eq!(got, want, "bits {bits} {direction:?} tpu {tpu} step {i}");
            assert_eq!(ext.now_us(), want);
        }
    }

    #[test]
    fn matches_exact_tick_count_for_systick_cmsdk_and_tim5_shapes() {
        check(24, CountDirection::Down, 25, 0x12_3456, 20_000); // SysTick at 25 MHz
        check(32, CountDirection::Down, 25, 7, 20_000); // CMSDK APB timer at 25 MHz
        check(32, CountDirection::Up, 1, u32::MAX - 5, 20_000); // TIM5 at 1 MHz
        check(16, CountDirection::Up, 3, 0, 20_000);
    }

    #[test]
    fn microseconds_wrap_modulo_2_pow_32() {
        // 32-bit down counter at 1 tick/µs: the µs clock must wrap exactly.
        let mut ext = TickExtender::new(32, CountDirection::Down, 1, 0);
        let mut raw = 0u32;
        let mut last = 0u32;
        let mut wraps = 0;
        for _ in 0..5 {
            raw = raw.wrapping_sub(0x7000_0000);
            let now = ext.update(raw);
            assert_eq!(now.wrapping_sub(last), 0x7000_0000);
            if now < last {
                wraps += 1;
            }
            last = now;
        }
        assert_eq!(wraps, 2);
    }

    #[test]
    fn no_progress_reads_the_same_time() {
        let mut ext = TickExtender::new(24, CountDirection::Down, 25, 100);
        assert_eq!(ext.update(100), 0);
        assert_eq!(ext.update(100 - 24), 0);
        assert_eq!(ext.update(100 - 25), 1);
        assert_eq!(ext.update(100 - 49), 1);
        assert_eq!(ext.update(100 - 50), 2);
    }
}
