//! The read rate against the chip's internal updates (docs/model.md §4.8,
//! "Reading rate").
//!
//! The board reads asynchronously at f; a sensor updates its registers at
//! its ODR F on its own clock, so a reading's age is the sawtooth
//! a(t) = frac(F t)/F sampled at t = n/f:
//!
//! a(t) = 1/(2F) − Σ_k sin(2π k F t)/(π k F),
//!
//! a delay modulation whose k-th harmonic, of amplitude 1/(πkF) s, appears in
//! the read sequence at the aliased frequency f·‖kF/f‖ (‖·‖ the distance to
//! the nearest integer). A chip clock off by ε moves it to f·‖kF(1+ε)/f‖,
//! by at most kF|ε|. A line near 0 Hz is a slowly varying delay, inside the
//! motion's band, that no model effect has.
//!
//! **The rule.** The *alias margin* of f is the minimum, over both sensors
//! and the harmonics that count, of f·‖kF/f‖ − kF·δ: the lowest frequency
//! the line can have for any chip clock within ±δ. A harmonic counts while
//! its amplitude 1/(πkF) ≥ [`ALIAS_MIN_AMPLITUDE_S`] (the default 125 Hz
//! accelerometer: k = 1…4; the 1000 Hz gyroscope: none). A rate is
//! alias-free when its margin is at least [`ALIAS_MARGIN_HZ`]. The choices:
//!
//! * δ = [`ALIAS_CLOCK_TOLERANCE`] = 2 %: **assumed** — the datasheet gives
//!   no tolerance for the internal oscillator in AMG mode that we know of.
//! * A_min = 0.6 ms: at 120 Hz the default accelerometer's fundamental
//!   (2.5 ms) beats at 5 Hz and made diagnose raise false alarms in 2 of 20
//!   60 s null sessions of the twin, just above its detection level; a
//!   line's test statistic grows as amplitude² × duration, so a 0.6 ms line
//!   needs ≈ 17 times as long (17 min) to be as visible.
//! * margin 20 Hz: a line at f_a modulates the motion's signal (band B of a
//!   few Hz) into f_a ± B; 20 Hz keeps that above the motion and above the
//!   catalogue's `resonance` (10 Hz by default).
//!
//! [`SensorTiming::alias_free_rate`] picks the default read rate: the lowest
//! alias-free rate of [`RATE_CHOICES_HZ`] (100 … 1000 Hz in 10 Hz steps);
//! for the default bandwidths 150 Hz ([`DEFAULT_SAMPLE_RATE_HZ`]: the
//! accelerometer's fundamental at 25 Hz, 22.5 Hz at a 2 % clock error).

use crate::messages::{SensorTiming, DEFAULT_SAMPLE_RATE_HZ};

/// Assumed relative tolerance δ of the chip's internal clock.
pub const ALIAS_CLOCK_TOLERANCE: f64 = 0.02;
/// Smallest delay amplitude of a harmonic that counts, s.
pub const ALIAS_MIN_AMPLITUDE_S: f64 = 0.6e-3;
/// Margin a rate needs to be alias-free, Hz.
pub const ALIAS_MARGIN_HZ: f64 = 20.0;
/// The rates [`SensorTiming::alias_free_rate`] chooses from, Hz: (lowest,
/// highest, step). The highest is the firmware's highest.
pub const RATE_CHOICES_HZ: (u16, u16, u16) = (100, 1000, 10);
/// Harmonics examined per sensor at most (an ODR below about 8 Hz would
/// count more).
const MAX_HARMONICS: u32 = 64;

/// Which sensor a line comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum AliasSensor {
    /// The accelerometer.
    Accel,
    /// The gyroscope.
    Gyro,
}

/// One harmonic of a sensor's age sawtooth as the reads see it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AliasLine {
    /// The sensor.
    pub sensor: AliasSensor,
    /// Its ODR, Hz.
    pub odr_hz: f64,
    /// The harmonic k.
    pub harmonic: u32,
    /// Its delay amplitude 1/(πkF), s.
    pub amplitude_s: f64,
    /// Its aliased frequency f·‖kF(1+ε)/f‖, Hz.
    pub frequency_hz: f64,
    /// Its lowest frequency over clock errors within ±δ, f·‖kF/f‖ − kFδ
    /// (negative when the line can reach 0 Hz), Hz.
    pub margin_hz: f64,
}

/// A read rate and its alias margin.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RateChoice {
    /// The rate, Hz.
    pub rate_hz: u16,
    /// Its alias margin ([`f64::INFINITY`] if no harmonic counts), Hz.
    pub margin_hz: f64,
    /// Whether the margin meets [`ALIAS_MARGIN_HZ`].
    pub alias_free: bool,
}

/// Distance from `x` (finite) to the nearest integer.
fn distance_to_integer(x: f64) -> f64 {
    let x = if x < 0.0 { -x } else { x };
    let r = x - (x as u64) as f64;
    r.min(1.0 - r)
}

impl SensorTiming {
    /// The harmonics that count ([`ALIAS_MIN_AMPLITUDE_S`]) of both
    /// sensors, read at `rate_hz` from a chip whose clock runs
    /// (1 + `clock_error`) fast. A sensor whose ODR is not a positive
    /// number contributes none.
    pub fn alias_lines(
        &self,
        rate_hz: f64,
        clock_error: f64,
    ) -> impl Iterator<Item = AliasLine> + '_ {
        let sensors = [
            (AliasSensor::Accel, f64::from(self.accel_odr_hz)),
            (AliasSensor::Gyro, f64::from(self.gyro_odr_hz)),
        ];
        sensors.into_iter().flat_map(move |(sensor, odr_hz)| {
            let usable = odr_hz.is_finite() && odr_hz > 0.0 && rate_hz.is_finite() && rate_hz > 0.0;
            let count = if usable {
                let k = 1.0 / (core::f64::consts::PI * odr_hz * ALIAS_MIN_AMPLITUDE_S);
                (k as u32).min(MAX_HARMONICS)
            } else {
                0
            };
            (1..=count).map(move |k| {
                let kf = f64::from(k) * odr_hz;
                AliasLine {
                    sensor,
                    odr_hz,
                    harmonic: k,
                    amplitude_s: 1.0 / (core::f64::consts::PI * kf),
                    frequency_hz: rate_hz * distance_to_integer(kf * (1.0 + clock_error) / rate_hz),
                    margin_hz: rate_hz * distance_to_integer(kf / rate_hz)
                        - kf * ALIAS_CLOCK_TOLERANCE,
                }
            })
        })
    }

    /// The line that sets the alias margin of `rate_hz` (the smallest
    /// [`AliasLine::margin_hz`]); `None` when no harmonic counts.
    pub fn worst_alias(&self, rate_hz: f64) -> Option<AliasLine> {
        self.alias_lines(rate_hz, 0.0)
            .reduce(|a, b| if b.margin_hz < a.margin_hz { b } else { a })
    }

    /// The alias margin of `rate_hz`, Hz ([`f64::INFINITY`] when no
    /// harmonic counts).
    pub fn alias_margin_hz(&self, rate_hz: f64) -> f64 {
        self.worst_alias(rate_hz)
            .map_or(f64::INFINITY, |l| l.margin_hz)
    }

    /// `rate_hz` and its margin.
    pub fn rate_choice(&self, rate_hz: u16) -> RateChoice {
        let margin_hz = self.alias_margin_hz(f64::from(rate_hz));
        RateChoice {
            rate_hz,
            margin_hz,
            alias_free: margin_hz >= ALIAS_MARGIN_HZ,
        }
    }

    /// The default read rate for this timing: the lowest alias-free rate of
    /// [`RATE_CHOICES_HZ`], or, if none is, the one with the largest margin
    /// (`alias_free` false).
    pub fn alias_free_rate(&self) -> RateChoice {
        let mut best: Option<RateChoice> = None;
        for choice in rate_choices().map(|r| self.rate_choice(r)) {
            if choice.alias_free {
                return choice;
            }
            if best.is_none_or(|b| choice.margin_hz > b.margin_hz) {
                best = Some(choice);
            }
        }
        // RATE_CHOICES_HZ is not empty
        best.unwrap_or(RateChoice {
            rate_hz: DEFAULT_SAMPLE_RATE_HZ,
            margin_hz: f64::NEG_INFINITY,
            alias_free: false,
        })
    }

    /// The alias-free rate of [`RATE_CHOICES_HZ`] nearest to `rate_hz` (the
    /// lower of two equally near), if any.
    pub fn nearest_alias_free_rate(&self, rate_hz: u16) -> Option<u16> {
        rate_choices()
            .filter(|&r| self.rate_choice(r).alias_free)
            .min_by_key(|&r| (r.abs_diff(rate_hz), r))
    }
}

/// The rates of [`RATE_CHOICES_HZ`], ascending.
fn rate_choices() -> impl Iterator<Item = u16> {
    let (lo, hi, step) = RATE_CHOICES_HZ;
    (lo..=hi).step_by(usize::from(step))
}
