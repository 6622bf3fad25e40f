//! The device clock that timestamps samples.

/// A free-running microsecond clock.
///
/// `now_us` wraps modulo 2³² (every 71.6 minutes), like
/// [`ImuSample::t_us`](robimu_protocol::ImuSample::t_us). It must be monotonic
/// between wraps; its rate defines the device's time base, so its drift is
/// what the host estimates when it maps device time to host time.
pub trait Clock {
    /// The current time, µs, wrapping.
    fn now_us(&mut self) -> u32;
}

impl<C: Clock + ?Sized> Clock for &mut C {
    fn now_us(&mut self) -> u32 {
        (**self).now_us()
    }
}
