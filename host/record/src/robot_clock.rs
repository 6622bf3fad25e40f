//! Controller time → session time for joint samples (Universal Robots).
//!
//! A UR data package carries the controller's own `timestamp` (s since it
//! started), taken at the control cycle that sampled `actual_q`; the host
//! sees the package some latency later. The arrival time is
//!
//! ```text
//! t_arrival = a + b · t_robot + latency,    latency ≥ 0 (network, OS),
//! ```
//!
//! so the lower envelope of the arrival times is the clock mapping, and the
//! jitter of the latency (ms on real networks) is noise that does not belong
//! to the joint angles (it acts like q̇·δt). The fit takes, in windows of
//! [`WINDOW_S`] of controller time, the sample with the least
//! `t_arrival − t_robot`, and puts a line through these minima by least
//! squares with residuals beyond 5 × the median absolute deviation removed
//! until none is (a window in which every package was held up); windows
//! with under half the median number of samples (the last, cut one) are
//! left out, their least latency lies high. Joint
//! times are then `a + b · t_robot`: on the session clock, with the
//! controller's sampling instants and the smallest latency seen.
//!
//! A controller restart sets `t_robot` back: the samples are cut into
//! segments wherever it goes backwards, and each segment gets its own fit.

use super::clock_fit::robust_line;

/// Width of the windows whose minima make the lower envelope, s of
/// controller time.
pub(crate) const WINDOW_S: f64 = 1.0;

/// The mapping of one clock segment, in [`super::clock_fit::ClockFit`]'s
/// convention:
///
/// ```text
/// t_robot = offset + (1 + drift) · t_session
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RobotClockFit {
    /// Controller time at session time 0, s.
    pub offset: f64,
    /// Rate error of the controller's clock against the host's (positive:
    /// it runs fast), unitless.
    pub drift: f64,
    /// RMS of `t_arrival − t_session(t_robot)` over the segment's samples,
    /// s: the arrival jitter the mapping removes (its mean included).
    pub jitter_rms: f64,
    /// Windows whose minimum lies on the fitted line (of those with at
    /// least half the median number of samples) / windows.
    pub windows_used: usize,
    /// Windows.
    pub windows: usize,
    /// Samples of the segment.
    pub samples: usize,
}

impl RobotClockFit {
    /// Session time of controller time `t_robot` (s).
    pub fn to_session(&self, t_robot: f64) -> f64 {
        (t_robot - self.offset) / (1.0 + self.drift)
    }

    /// Drift in parts per million.
    pub fn drift_ppm(&self) -> f64 {
        self.drift * 1e6
    }

    /// Fits the lower envelope of `(t_robot, t_arrival)` pairs of one clock
    /// segment (`t_robot` increasing); `None` when there is no sample. With
    /// fewer than three (full enough) windows the drift is not fitted (0)
    /// and the offset is that of the least latency.
    pub fn fit(samples: &[(f64, f64)]) -> Option<RobotClockFit> {
        let first = samples.first()?.0;
        // (t_robot, t_arrival − t_robot) of each window's least latency,
        // and the window's sample count.
        let mut minima: Vec<(f64, f64, usize)> = Vec::new();
        let mut window = None;
        for &(x, arrival) in samples {
            let w = ((x - first) / WINDOW_S).floor() as i64;
            let y = arrival - x;
            match minima.last_mut() {
                Some(m) if window == Some(w) => {
                    m.2 += 1;
                    if y < m.1 {
                        (m.0, m.1) = (x, y);
                    }
                }
                _ => {
                    minima.push((x, y, 1));
                    window = Some(w);
                }
            }
        }
        let windows = minima.len();
        // The least of a few samples lies high (the last, cut window; a
        // stall): windows with under half the median count are left out.
        let mut counts: Vec<usize> = minima.iter().map(|m| m.2).collect();
        counts.sort_unstable();
        let enough = counts[counts.len() / 2].div_ceil(2);
        let minima: Vec<(f64, f64)> = minima
            .iter()
            .filter(|m| m.2 >= enough)
            .map(|m| (m.0, m.1))
            .collect();
        // y = α + β·x, i.e. t_arrival = α + (1 + β)·t_robot.
        let low = minima.iter().map(|m| m.1).fold(f64::INFINITY, f64::min);
        let kept = minima.len();
        let (alpha, beta, used) = Some(minima)
            .filter(|m| m.len() >= 3)
            .and_then(|m| robust_line(m, 3))
            .map(|(a, b, used)| (a, b, used.len()))
            .unwrap_or((low, 0.0, kept));
        let b = 1.0 + beta;
        let fit = RobotClockFit {
            offset: -alpha / b,
            drift: 1.0 / b - 1.0,
            jitter_rms: 0.0,
            windows_used: used,
            windows,
            samples: samples.len(),
        };
        let ss: f64 = samples
            .iter()
            .map(|&(x, arrival)| (arrival - fit.to_session(x)).powi(2))
            .sum();
        Some(RobotClockFit {
            jitter_rms: (ss / samples.len() as f64).sqrt(),
            ..fit
        })
    }
}

/// What [`remap`] gives.
#[derive(Clone, Debug, PartialEq)]
pub struct Remapped {
    /// The fit of each clock segment, numbered from 0.
    pub fits: Vec<(u32, RobotClockFit)>,
    /// The session time of each sample.
    pub times: Vec<f64>,
}

/// The joint times of a whole recording from its `(t_robot, t_arrival)`
/// pairs: each clock segment (cut where `t_robot` goes backwards) mapped by
/// its own fit. `Err` says why the arrival times must be kept instead: a
/// controller time that is not a number, or mapped times that would not
/// be in time order.
pub fn remap(samples: &[(f64, f64)]) -> Result<Remapped, String> {
    if let Some(k) = samples
        .iter()
        .position(|(x, a)| !(x.is_finite() && a.is_finite()))
    {
        return Err(format!(
            "joint sample {} has no controller timestamp",
            k + 1
        ));
    }
    let mut fits = Vec::new();
    let mut times = Vec::with_capacity(samples.len());
    let mut start = 0;
    while start < samples.len() {
        let len = samples[start..]
            .windows(2)
            .position(|w| w[1].0 < w[0].0)
            .map_or(samples.len() - start, |k| k + 1);
        let seg = &samples[start..start + len];
        let fit = RobotClockFit::fit(seg).expect("a segment has samples");
        times.extend(seg.iter().map(|&(x, _)| fit.to_session(x)));
        fits.push((fits.len() as u32, fit));
        start += len;
    }
    if let Some(k) = times.windows(2).position(|w| w[1] < w[0]) {
        return Err(format!(
            "the controller clock mapping would put joint sample {} ({:.6} s) before the one it follows ({:.6} s)",
            k + 2,
            times[k + 1],
            times[k]
        ));
    }
    Ok(Remapped { fits, times })
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    /// Samples at 125 Hz of a controller clock 1234.5 s ahead at session
    /// time 0 running 80 ppm fast, arriving after 100 µs plus a uniform
    /// jitter of up to 4 ms, with one window held up by 30 ms throughout.
    fn samples(seed: u64, from: f64, n: usize, offset: f64) -> (Vec<(f64, f64)>, Vec<f64>) {
        let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
        let drift = 80e-6;
        let mut out = Vec::new();
        let mut truth = Vec::new();
        for k in 0..n {
            let t = from + k as f64 / 125.0;
            let stall = if (5.0..6.0).contains(&(t - from)) {
                0.03
            } else {
                0.0
            };
            let latency = 1e-4 + 4e-3 * rng.random::<f64>() + stall;
            out.push((offset + (1.0 + drift) * t, t + latency));
            truth.push(t + 1e-4);
        }
        (out, truth)
    }

    #[test]
    fn envelope_fit_recovers_offset_drift_and_the_sampling_instants() {
        // 20 full windows and a last one of 3 samples (left out)
        let (s, truth) = samples(7, 0.0, 2503, 1234.5);
        let fit = RobotClockFit::fit(&s).unwrap();
        assert_eq!(fit.windows, 21);
        assert!(fit.windows_used < 20, "the held-up window is dropped");
        assert!(
            (fit.drift_ppm() - 80.0).abs() < 5.0,
            "drift {}",
            fit.drift_ppm()
        );
        // The offset includes the least latency (100 µs + the minima's few
        // µs): the line is the envelope, not the mean.
        let want = 1234.5 - 1e-4 * (1.0 + 80e-6);
        assert!((fit.offset - want).abs() < 1e-4, "offset {}", fit.offset);
        let err = s
            .iter()
            .zip(&truth)
            .map(|((x, _), t)| (fit.to_session(*x) - t).powi(2))
            .sum::<f64>()
            / s.len() as f64;
        assert!(err.sqrt() < 1e-4, "rms time error {}", err.sqrt());
        let raw = s
            .iter()
            .zip(&truth)
            .map(|((_, a), t)| (a - t).powi(2))
            .sum::<f64>()
            / s.len() as f64;
        // uniform 0..4 ms (plus the stall): RMS about 2.3 ms
        assert!(raw.sqrt() > 2e-3, "raw rms {}", raw.sqrt());
        assert!((fit.jitter_rms - raw.sqrt()).abs() < 1e-4);
    }

    /// Eight full windows and a last one of 2 samples, as a short
    /// recording ends: the cut window is left out of the envelope.
    #[test]
    fn a_cut_last_window_does_not_tilt_the_envelope() {
        for seed in 0..20 {
            let (s, truth) = samples(seed, 0.0, 1002, 1234.5);
            let fit = RobotClockFit::fit(&s).unwrap();
            assert_eq!(fit.windows, 9);
            let worst = s
                .iter()
                .zip(&truth)
                .map(|((x, _), t)| (fit.to_session(*x) - t).abs())
                .fold(0.0, f64::max);
            assert!(worst < 1.5e-4, "seed {seed}: {worst} {fit:?}");
        }
    }

    #[test]
    fn a_controller_restart_starts_a_new_segment() {
        let (mut s, mut truth) = samples(8, 0.0, 1000, 1234.5);
        // restarted: its clock reads 3 s when the session clock reads 10 s
        let (s2, t2) = samples(9, 10.0, 1000, -7.0);
        s.extend(s2);
        truth.extend(t2);
        let Remapped { fits, times } = remap(&s).unwrap();
        assert_eq!(fits.len(), 2);
        assert!((fits[1].1.offset - (-7.0)).abs() < 1e-3, "{fits:?}");
        assert_eq!(fits[1].1.samples, 1000);
        for (t, want) in times.iter().zip(&truth) {
            assert!((t - want).abs() < 1e-4, "{t} vs {want}");
        }
        assert!(times.windows(2).all(|w| w[1] >= w[0]));
    }

    #[test]
    fn short_segments_and_bad_timestamps() {
        // two windows: offset only, from the least latency
        let s = [(100.0, 1.003), (100.5, 1.5001), (101.2, 2.2004)];
        let fit = RobotClockFit::fit(&s).unwrap();
        assert_eq!(fit.drift, 0.0);
        assert!((fit.to_session(100.5) - 1.5001).abs() < 1e-12);
        assert!(RobotClockFit::fit(&[]).is_none());
        let e = remap(&[(1.0, 1.0), (f64::NAN, 1.1)]).unwrap_err();
        assert!(
            e.contains("joint sample 2 has no controller timestamp"),
            "{e}"
        );
        // a restart within milliseconds of the old clock would put mapped
        // times out of order: refused
        let s = [
            (10.0, 1.0),
            (10.5, 1.5),
            (11.0, 2.0),
            (11.5, 2.5),
            (12.0, 3.0),
            (0.0, 3.001),
            (0.4, 3.0012),
        ];
        let e = remap(&s).unwrap_err();
        assert!(e.contains("before the one it follows"), "{e}");
    }
}
