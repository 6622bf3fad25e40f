//! A loop run at a fixed rate: the AUBO joint poller's requests, the
//! simulated controllers' integration steps.

use std::thread;
use std::time::{Duration, Instant};

/// Sleeps out each period of a fixed-rate loop, counted from its start. A
/// loop that falls behind restarts its schedule from now instead of
/// running the missed periods back to back.
#[derive(Debug, Clone)]
pub struct Pacer {
    period: Duration,
    next: Instant,
}

impl Pacer {
    /// A schedule of `period` starting now.
    pub fn new(period: Duration) -> Self {
        Pacer {
            period,
            next: Instant::now(),
        }
    }

    /// Waits until the next period is due.
    pub fn wait(&mut self) {
        self.next += self.period;
        let now = Instant::now();
        if self.next > now {
            thread::sleep(self.next - now);
        } else {
            self.next = now;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keeps_the_rate_and_does_not_catch_up() {
        let start = Instant::now();
        let mut p = Pacer::new(Duration::from_millis(5));
        for _ in 0..4 {
            p.wait();
        }
        assert!(start.elapsed() >= Duration::from_millis(20));
        // Behind by much more than a period: the next wait is a full one.
        thread::sleep(Duration::from_millis(30));
        p.wait();
        let t = Instant::now();
        p.wait();
        assert!(t.elapsed() >= Duration::from_millis(4));
    }
}
