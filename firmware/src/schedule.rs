//! Drift-free sample deadlines.
//!
//! Deadline `k` after a start at `t0` is
//!
//! ```text
//! d_k = t0 + floor(k · 10⁶ / rate)   µs
//! ```
//!
//! computed from `k` directly, so rounding never accumulates: over any whole
//! second exactly `rate` deadlines fall. The base is advanced by exactly one
//! second every `rate` deadlines, keeping `k < rate` and the wrapping `u32`
//! arithmetic exact. When the caller is late past later deadlines, those are
//! skipped and reported as missed.
//!
//! Wrapping comparisons assume the caller polls at least every 2³¹ µs
//! (35 minutes).

/// µs per second.
const US_PER_S: u64 = 1_000_000;

/// The deadline sequence of one streaming run.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Schedule {
    rate_hz: u32,
    /// Device time of deadline 0 of the current second, µs (wrapping).
    base_us: u32,
    /// Index of the next deadline within the current second, `< rate_hz`.
    k: u32,
}

impl Schedule {
    /// Deadlines at `rate_hz` (at least 1) from `t0_us` on; the first is `t0_us`.
    pub fn new(rate_hz: u16, t0_us: u32) -> Self {
        Self {
            rate_hz: u32::from(rate_hz.max(1)),
            base_us: t0_us,
            k: 0,
        }
    }

    /// The next deadline, µs (wrapping).
    pub fn next_deadline_us(&self) -> u32 {
        self.base_us.wrapping_add(offset_us(self.k, self.rate_hz))
    }

    /// If the next deadline has passed at `now_us`, consumes every deadline up
    /// to `now_us` and returns how many of them were missed (all but the
    /// latest, which the caller samples now); otherwise `None`.
    pub fn poll(&mut self, now_us: u32) -> Option<u32> {
        let late = now_us.wrapping_sub(self.next_deadline_us());
        if late > i32::MAX as u32 {
            return None; // deadline still ahead (negative lateness)
        }
        let rate = u64::from(self.rate_hz);
        let elapsed = u64::from(now_us.wrapping_sub(self.base_us));
        // Latest index m with floor(m·10⁶/rate) <= elapsed.
        let latest = ((elapsed + 1) * rate - 1) / US_PER_S;
        let current = u64::from(self.k);
        let missed = latest.saturating_sub(current);
        let next = latest + 1;
        let seconds = next / rate;
        // Wrapping: only the time modulo 2³² matters.
        self.base_us = self
            .base_us
            .wrapping_add((seconds.wrapping_mul(US_PER_S) & u64::from(u32::MAX)) as u32);
        self.k = (next % rate) as u32;
        Some(u32::try_from(missed).unwrap_or(u32::MAX))
    }
}

/// floor(k · 10⁶ / rate) for k < rate: below 10⁶.
fn offset_us(k: u32, rate_hz: u32) -> u32 {
    (u64::from(k) * US_PER_S / u64::from(rate_hz.max(1))) as u32
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Reference deadline from the closed form with exact integer arithmetic.
    fn reference(t0: u64, k: u64, rate: u64) -> u64 {
        t0 + k * US_PER_S / rate
    }

    #[test]
    fn polling_every_microsecond_hits_each_deadline_exactly() {
        for rate in [1u16, 7, 120, 333, 1000] {
            let t0 = 4_000_000_000u32; // wraps during the run
            let mut schedule = Schedule::new(rate, t0);
            let mut hits = 0u64;
            for dt in 0..3_000_000u64 {
                let now = t0.wrapping_add(dt as u32);
                if let Some(missed) = schedule.poll(now) {
                    assert_eq!(missed, 0);
                    assert_eq!(dt, reference(0, hits, u64::from(rate)), "rate {rate}");
                    hits += 1;
                }
            }
            // Deadlines in [0, 3 s): 3·rate of them.
            assert_eq!(hits, 3 * u64::from(rate), "rate {rate}");
        }
    }

    #[test]
    fn ten_minutes_at_333_hz_do_not_drift() {
        let rate = 333u16;
        let mut schedule = Schedule::new(rate, 17);
        let mut k = 0u64;
        // Poll every 250 µs: each deadline is seen within 250 µs.
        let mut t = 17u64;
        while t < 17 + 600 * US_PER_S {
            if let Some(missed) = schedule.poll(t as u32) {
                assert_eq!(missed, 0);
                let d = reference(17, k, 333);
                assert!(t >= d && t < d + 250, "k={k} t={t} d={d}");
                k += 1;
            }
            t += 250;
        }
        assert_eq!(k, 600 * 333);
    }

    #[test]
    fn a_late_poll_skips_and_counts_missed_deadlines() {
        let mut schedule = Schedule::new(100, 0); // every 10 ms
        assert_eq!(schedule.poll(0), Some(0));
        assert_eq!(schedule.poll(9_999), None);
        // 35 ms late: deadlines 10, 20, 30 ms passed; 30 ms is sampled now.
        assert_eq!(schedule.poll(35_000), Some(2));
        assert_eq!(schedule.next_deadline_us(), 40_000);
        // Over a second boundary, many seconds late.
        assert_eq!(schedule.poll(5_000_001), Some(496)); // 40 ms ..= 4.99 s
        assert_eq!(schedule.next_deadline_us(), 5_010_000);
        assert_eq!(schedule.poll(5_010_000), Some(0));
    }

    #[test]
    fn rate_zero_is_treated_as_one_hertz() {
        let mut schedule = Schedule::new(0, 0);
        assert_eq!(schedule.poll(0), Some(0));
        assert_eq!(schedule.next_deadline_us(), 1_000_000);
    }
}
