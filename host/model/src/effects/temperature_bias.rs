//! Biases that follow the sensor temperature (docs/model.md §4.5): per
//! channel a linear temperature coefficient,
//!
//! ```text
//! z_c ← z_c + k_c (T̃(t) − T_ref)        T_ref = mean of T̃ over the IMU samples
//! ```
//!
//! so the constant part stays with the baseline biases b. T̃ is the
//! session's IMU temperature column smoothed in time ([`TemperatureTrack`]:
//! the BNO055 reports whole °C). Six parameters k (m/s²/K for the
//! accelerometer, shown in mg/K; rad/s/K for the gyroscope, shown in
//! °/s/K); priors σ 5 mg/K and 0.075 °/s/K, five times the datasheet's
//! typical zero-offset TCO (±1 mg/K, ±0.015 °/s/K). Linear only: the
//! datasheet gives no curvature, and over a session's few-kelvin warm-up a
//! quadratic term is nearly collinear with the linear one and with a
//! drift in time (see docs/model.md §4.5).
//!
//! Available only when the session has a temperature column that varies
//! ([`TemperatureTrack::from_samples`]). `simulate --effect
//! temperature_bias=M` (M in mg/K) injects k_a = M·(1, −0.6, 0.8) mg/K and
//! k_g = M·0.015·(1, −0.7, 0.5) °/s/K (the datasheet's gyroscope-to-
//! accelerometer ratio).

use std::sync::Arc;

use super::{Effect, EffectConstant, EffectParam, ImuContext, SampleContext};
use crate::{JointState, Knots, Spline, IMU_CHANNELS};

/// What a session needs for the effect (the message of an unavailable one).
pub(crate) const REQUIRES: &str =
    "an IMU temperature column that varies by at least half a degree \
     (temp_c in imu.csv; `simulate --temperature` writes one)";

/// Smallest knot spacing of the smoothing spline, s.
pub(crate) const MIN_KNOT_SPACING: f64 = 20.0;

/// Smallest range of the smoothed temperature over the session for the
/// effect to be offered, K (half the BNO055's 1 °C LSB).
pub(crate) const MIN_RANGE: f64 = 0.5;

/// The recorded temperature smoothed in time: a least-squares cubic
/// B-spline with uniform knots spaced `max(`[`MIN_KNOT_SPACING`]`, 2·span /
/// changes)` (changes: how often the reading changes), so that each knot
/// interval holds at least about two of the register's 1 °C steps and the
/// staircase of a slow drift is averaged rather than followed; at most one
/// interval (a cubic polynomial) for the whole span.
#[derive(Debug, Clone)]
pub struct TemperatureTrack {
    spline: Spline,
    reference: f64,
    range: f64,
}

impl TemperatureTrack {
    /// The track of readings `temp` (°C) at the IMU times `t` (s; non-finite
    /// readings skipped). `None` when there are too few readings, they do
    /// not change, or the smoothed range is below [`MIN_RANGE`].
    pub fn from_samples(t: &[f64], temp: &[f64]) -> Option<Self> {
        if t.len() != temp.len() {
            return None;
        }
        let (ts, vs): (Vec<f64>, Vec<f64>) = t
            .iter()
            .zip(temp)
            .filter(|(a, b)| a.is_finite() && b.is_finite())
            .map(|(a, b)| (*a, *b))
            .unzip();
        let (t0, t1) = (*ts.first()?, *ts.last()?);
        if ts.len() < 8 || t1 <= t0 || ts.windows(2).any(|w| w[1] < w[0]) {
            return None;
        }
        let changes = vs.windows(2).filter(|w| w[1] != w[0]).count();
        if changes == 0 {
            return None;
        }
        let span = t1 - t0;
        // whole intervals of at least the wanted spacing
        let wanted = (2.0 * span / changes as f64).max(MIN_KNOT_SPACING);
        let mut intervals = (span / wanted).floor().max(1.0);
        // a gap in the stream can leave an interval empty: widen until it fits
        let spline = loop {
            let knots = Knots::uniform(t0, t1, span / intervals, 3).ok()?;
            match Spline::fit(knots, 1, &ts, &vs) {
                Ok(s) => break s,
                Err(_) if intervals > 1.0 => intervals = (intervals / 2.0).floor(),
                Err(_) => return None,
            }
        };
        let mut track = Self {
            spline,
            reference: 0.0,
            range: 0.0,
        };
        let smooth: Vec<f64> = ts.iter().map(|&s| track.at(s)).collect();
        track.reference = smooth.iter().sum::<f64>() / smooth.len() as f64;
        let (lo, hi) = smooth
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
                (a.min(v), b.max(v))
            });
        track.range = hi - lo;
        (track.range >= MIN_RANGE).then_some(track)
    }

    /// T̃(t), °C (the end values outside the recorded span).
    pub fn at(&self, t: f64) -> f64 {
        let mut js = JointState::default();
        self.spline.evaluate_clamped(t, &mut js);
        js.q[0]
    }

    /// T_ref: the mean of T̃ over the samples, °C.
    pub fn reference(&self) -> f64 {
        self.reference
    }

    /// Range of T̃ over the samples, K.
    pub fn range(&self) -> f64 {
        self.range
    }

    /// The smoothing spline's knot spacing, s.
    pub fn knot_spacing(&self) -> f64 {
        let k = self.spline.knots();
        (k.end() - k.start()) / (k.num_coeffs() - k.degree()) as f64
    }
}

/// See the module doc.
pub(crate) struct TemperatureBias {
    track: Arc<TemperatureTrack>,
}

impl TemperatureBias {
    /// Biases following `track`.
    pub fn new(track: Arc<TemperatureTrack>) -> Self {
        Self { track }
    }
}

const DEG: f64 = std::f64::consts::PI / 180.0;
/// One milli-g, m/s².
const MG: f64 = 9.80665e-3;
/// The datasheet's typical gyroscope TCO per accelerometer TCO, (°/s/K) per (mg/K).
const GYRO_PER_ACCEL: f64 = 0.015;

impl Effect for TemperatureBias {
    fn name(&self) -> &'static str {
        "temperature_bias"
    }
    fn description(&self) -> &'static str {
        "biases linear in the smoothed sensor temperature, per channel"
    }
    fn params(&self) -> Vec<EffectParam> {
        IMU_CHANNELS
            .iter()
            .enumerate()
            .map(|(c, ch)| {
                let (unit, display, prior_sigma) = if c < 3 {
                    ("m/s^2/K", ("mg/K", 1.0 / MG), 5.0 * MG)
                } else {
                    (
                        "rad/s/K",
                        ("deg/s/K", 1.0 / DEG),
                        5.0 * GYRO_PER_ACCEL * DEG,
                    )
                };
                EffectParam {
                    name: format!("temperature_bias.{ch}"),
                    unit,
                    display,
                    prior_sigma,
                }
            })
            .collect()
    }
    fn columns(&self, ctx: &SampleContext<'_>, cols: &mut [[f64; 6]]) {
        self.imu_columns(ctx, cols);
    }
    fn imu_columns(&self, ctx: &dyn ImuContext, cols: &mut [[f64; 6]]) -> bool {
        let dt = self.track.at(ctx.t()) - self.track.reference();
        for (c, col) in cols.iter_mut().enumerate().take(6) {
            col[c] = dt;
        }
        true
    }
    fn constants(&self) -> Vec<EffectConstant> {
        vec![
            EffectConstant {
                name: "temperature_bias.t_ref".into(),
                unit: "degC",
                value: self.track.reference(),
            },
            EffectConstant {
                name: "temperature_bias.smoothing_knot_spacing".into(),
                unit: "s",
                value: self.track.knot_spacing(),
            },
        ]
    }
    fn magnitude_unit(&self) -> &'static str {
        "mg/K"
    }
    fn injection(&self, magnitude: f64) -> Vec<f64> {
        let a = [1.0, -0.6, 0.8].map(|v| magnitude * MG * v);
        let g = [1.0, -0.7, 0.5].map(|v| magnitude * GYRO_PER_ACCEL * DEG * v);
        [a, g].concat()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// RMS over the samples of `f(t) − g(t)`.
    fn rms(t: &[f64], f: impl Fn(usize, f64) -> f64) -> f64 {
        (t.iter()
            .enumerate()
            .map(|(i, &s)| f(i, s).powi(2))
            .sum::<f64>()
            / t.len() as f64)
            .sqrt()
    }

    /// A warm-up T(t) = 35 − 10 e^{−t/60} over 300 s at 100 Hz, read with
    /// the BNO055's 1 °C LSB: the track is closer to the true curve than
    /// the readings (RMS under half theirs; where the reading no longer
    /// changes nothing better than ±0.5 K is known), its reference is the
    /// true curve's mean to 0.1 K, and the knots are spaced to hold at
    /// least two of the register's steps.
    #[test]
    fn the_track_recovers_a_warm_up_from_whole_degree_readings() {
        let truth = |t: f64| 35.0 - 10.0 * (-t / 60.0).exp();
        let t: Vec<f64> = (0..30_000).map(|i| i as f64 * 0.01).collect();
        let read: Vec<f64> = t.iter().map(|&s| truth(s).round()).collect();
        let track = TemperatureTrack::from_samples(&t, &read).unwrap();
        let err = rms(&t, |_, s| track.at(s) - truth(s));
        let raw = rms(&t, |i, s| read[i] - truth(s));
        // while the warm-up is fast (first 120 s, 8 steps)
        let early = rms(&t[..12_000], |_, s| track.at(s) - truth(s));
        println!(
            "RMS error {err:.3} K, first 120 s {early:.3} K (readings {raw:.3} K), spacing {:.1} s",
            track.knot_spacing()
        );
        assert!(err < 0.5 * raw, "{err} vs {raw}");
        assert!(early < 0.1, "{early}");
        let mean = t.iter().map(|&s| truth(s)).sum::<f64>() / t.len() as f64;
        let smooth_mean = t.iter().map(|&s| track.at(s)).sum::<f64>() / t.len() as f64;
        assert!((track.reference() - smooth_mean).abs() < 1e-9);
        println!(
            "reference {:.3} °C, true mean {mean:.3} °C, range {:.3} K",
            track.reference(),
            track.range()
        );
        assert!((track.reference() - mean).abs() < 0.1);
        assert!((track.range() - (truth(300.0) - truth(0.0))).abs() < 0.5);
        // 10 steps in 299.99 s: spacing ≥ 2·span/10
        assert!(
            track.knot_spacing() >= 2.0 * 299.99 / 10.0,
            "{}",
            track.knot_spacing()
        );
    }

    /// No track for a constant or too short column, a column of another
    /// length, or one that only wobbles by less than [`MIN_RANGE`]; a slow
    /// drift of one step per two minutes is averaged (spacing ≥ 4 min).
    #[test]
    fn the_track_is_absent_without_a_varying_temperature() {
        let t: Vec<f64> = (0..6000).map(|i| i as f64 * 0.05).collect();
        assert!(TemperatureTrack::from_samples(&t, &vec![24.0; t.len()]).is_none());
        assert!(TemperatureTrack::from_samples(&t[..5], &[24.0, 25.0, 24.0, 25.0, 24.0]).is_none());
        assert!(TemperatureTrack::from_samples(&t, &vec![24.0; t.len() - 1]).is_none());
        // one sample at 25 °C among 24 °C: smoothed range far below 0.5 K
        let mut blip = vec![24.0; t.len()];
        blip[3000] = 25.0;
        assert!(TemperatureTrack::from_samples(&t, &blip).is_none());
        // 22.2 → 24.7 °C linearly over 300 s: steps at 22.5, 23.5, 24.5
        let truth = |s: f64| 22.2 + 2.5 * s / 300.0;
        let read: Vec<f64> = t.iter().map(|&s| truth(s).round()).collect();
        let track = TemperatureTrack::from_samples(&t, &read).unwrap();
        assert!(track.knot_spacing() >= 200.0, "{}", track.knot_spacing());
        let err = rms(&t, |_, s| track.at(s) - truth(s));
        let raw = rms(&t, |i, s| read[i] - truth(s));
        println!("slow drift: RMS error {err:.3} K (readings {raw:.3} K)");
        assert!(err < 0.5 * raw, "{err} vs {raw}");
    }
}
