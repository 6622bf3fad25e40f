//! The regularity of a stream's time stamps beyond rates and gaps
//! ([`super::streams`]): the timing jitter (the RMS of the stamp intervals
//! about their median) and a start-up burst (samples at the start of a
//! stream stamped far closer together than the median interval, then normal
//! spacing: samples buffered before the recorder read them, stamped on
//! arrival, so stamped late).

use super::streams::GAP_FACTOR;
use super::{median_of, Finding, Severity};

/// Jitter above this part of the median interval is named (information).
pub(crate) const JITTER_INFO: f64 = 0.02;
/// Jitter above this part of the median interval is a warning.
pub(crate) const JITTER_WARN: f64 = 0.1;
/// An interval below this part of the median is one of a burst's.
pub(crate) const BURST_FRACTION: f64 = 0.25;
/// A burst has at least this many such intervals in a row.
pub(crate) const BURST_MIN: usize = 5;
/// A start-up burst begins within this many intervals of the first row.
pub(crate) const BURST_START: usize = 3;

/// The median of the positive intervals of `t` (NaN without one).
pub(crate) fn median_period(t: &[f64]) -> f64 {
    let mut dt: Vec<f64> = t
        .windows(2)
        .map(|w| w[1] - w[0])
        .filter(|d| *d > 0.0)
        .collect();
    median_of(&mut dt)
}

/// The RMS of the intervals of `t` about their median, gaps (over
/// 3 median periods, as in [`super::streams`]) and repeated stamps left out: named above
/// `JITTER_INFO` of the median interval, a warning above `JITTER_WARN`.
pub fn jitter(name: &str, t: &[f64]) -> Option<Finding> {
    let period = median_period(t);
    if period.is_nan() || period <= 0.0 {
        return None;
    }
    let (sum, n) = t
        .windows(2)
        .map(|w| w[1] - w[0])
        .filter(|d| *d > 0.0 && *d <= GAP_FACTOR * period)
        .fold((0.0, 0usize), |(s, n), d| (s + (d - period).powi(2), n + 1));
    let rms = (sum / n.max(1) as f64).sqrt();
    let share = rms / period;
    if share <= JITTER_INFO {
        return None;
    }
    let severity = if share > JITTER_WARN {
        Severity::Warning
    } else {
        Severity::Info
    };
    Some(Finding::new(
        "jitter",
        severity,
        name,
        rms,
        format!(
            "{name}: timing jitter {:.3} ms rms about the median interval {:.3} ms ({:.1} %)",
            rms * 1e3,
            period * 1e3,
            100.0 * share
        ),
        if share > JITTER_WARN {
            "the stamps are arrival times on a busy link or host: stamp the samples at the source (the controller's or tracker's own clock), or record on a host that is not busy"
        } else {
            ""
        },
    ))
}

/// A start-up burst of late-stamped samples: at least `BURST_MIN`
/// intervals in a row below `BURST_FRACTION` of the median, beginning
/// within `BURST_START` intervals of the first row and followed by normal
/// spacing. Names the samples' count, the span they were stamped in and
/// the time they end (a warning).
pub fn startup_burst(name: &str, t: &[f64]) -> Option<Finding> {
    let period = median_period(t);
    if period.is_nan() || period <= 0.0 {
        return None;
    }
    let short = |i: usize| t[i + 1] - t[i] < BURST_FRACTION * period;
    let intervals = t.len() - 1;
    let start = (0..intervals.min(BURST_START + 1)).find(|&i| short(i))?;
    let end = (start..intervals).find(|&i| !short(i)).unwrap_or(intervals);
    let run = end - start;
    // the run must be a burst, and normal spacing must follow it
    if run < BURST_MIN || end == intervals || run * 2 > intervals {
        return None;
    }
    let samples = run + 1;
    let span = t[end] - t[start];
    Some(Finding::new(
        "startup_burst",
        Severity::Warning,
        name,
        samples as f64,
        format!(
            "{name}: a start-up burst of {samples} samples stamped within {:.1} ms from t = {:.3} s \
             ({:.2} ms apart on average, the median interval is {:.3} ms), then normal spacing: \
             samples buffered before the first read and stamped late on arrival",
            span * 1e3,
            t[start],
            span / run as f64 * 1e3,
            period * 1e3
        ),
        format!(
            "drop the first {} rows (up to t = {} s: their stamps are not their sample instants), or stamp the samples on the device's clock",
            end + 1,
            t[end]
        ),
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `n` stamps at 100 Hz, rounded as a recorder writes them.
    fn regular(n: usize) -> Vec<f64> {
        (0..n)
            .map(|i| (i as f64 * 0.01 * 1e9).round() / 1e9)
            .collect()
    }

    /// A deterministic spread in [-1, 1].
    fn wiggle(i: usize) -> f64 {
        (i * 7919 % 101) as f64 / 50.0 - 1.0
    }

    #[test]
    fn jitter_is_named_with_its_rms_and_silent_on_a_clean_stream() {
        let t = regular(1000);
        assert!(jitter("poses.csv", &t).is_none());
        // a 2 s gap is a gap, not jitter
        let gap: Vec<f64> = t
            .iter()
            .map(|&v| if v > 5.0 { v + 2.0 } else { v })
            .collect();
        assert!(jitter("poses.csv", &gap).is_none());
        // stamps off their instants by up to ±1 ms: intervals off by up to ±2 ms
        let noisy: Vec<f64> = t
            .iter()
            .enumerate()
            .map(|(i, &v)| v + 0.001 * wiggle(i))
            .collect();
        let f = jitter("poses.csv", &noisy).expect("jitter found");
        assert_eq!(f.kind, "jitter");
        assert_eq!(f.severity, Severity::Warning);
        assert!(f.value > 5e-4 && f.value < 2e-3, "{}", f.value);
        assert!(
            f.message.contains("ms rms about the median interval"),
            "{}",
            f.message
        );
        // a little jitter is information
        let small: Vec<f64> = t
            .iter()
            .enumerate()
            .map(|(i, &v)| v + 0.0002 * wiggle(i))
            .collect();
        assert_eq!(jitter("x", &small).unwrap().severity, Severity::Info);
        assert!(jitter("x", &[1.0]).is_none() && jitter("x", &[]).is_none());
    }

    #[test]
    fn a_startup_burst_is_counted_with_its_span() {
        let clean = regular(1000);
        assert!(startup_burst("imu.csv", &clean).is_none());
        // the first 40 samples stamped 0.5 ms apart, then 10 ms spacing
        let mut t: Vec<f64> = (0..40).map(|i| i as f64 * 0.0005).collect();
        let t0 = t[39];
        t.extend((1..1000).map(|i| t0 + i as f64 * 0.01));
        let f = startup_burst("imu.csv", &t).expect("burst found");
        assert_eq!(f.kind, "startup_burst");
        assert_eq!(f.value, 40.0);
        assert!(f.message.contains("within 19.5 ms"), "{}", f.message);
        assert!(f.action.contains("drop the first 40 rows"), "{}", f.action);
        // a few short intervals are not a burst; nor is one in the middle
        let mut few = regular(1000);
        for v in few.iter_mut().skip(1).take(3) {
            *v -= 0.008;
        }
        assert!(startup_burst("imu.csv", &few).is_none());
        let mut middle: Vec<f64> = regular(500);
        let m0 = middle[499];
        middle.extend((1..40).map(|i| m0 + i as f64 * 0.0005));
        let m1 = *middle.last().unwrap();
        middle.extend((1..500).map(|i| m1 + i as f64 * 0.01));
        assert!(startup_burst("imu.csv", &middle).is_none());
        // repeated stamps at the start are not a burst of late samples
        // unless there are many: then they are
        assert!(startup_burst("imu.csv", &[0.0, 0.0, 0.01]).is_none());
    }
}
