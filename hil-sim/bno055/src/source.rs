//! Where the simulated sensor's readings come from.

use crate::timing::Sensor;

/// One raw AMG reading as the BNO055 data registers hold it (sensor axes x, y, z).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct RawReading {
    /// Accelerometer counts (`ACC_DATA`, 100 LSB per m/s² with the m/s² unit).
    pub accel: [i16; 3],
    /// Gyroscope counts (`GYR_DATA`, 900 LSB per rad/s or 16 LSB per °/s).
    pub gyro: [i16; 3],
    /// Magnetometer counts (`MAG_DATA`, 16 LSB per µT).
    pub mag: [i16; 3],
    /// Temperature (`TEMP`, 1 LSB per °C).
    pub temp: i8,
}

/// What the sensing elements see at one instant, in SI units (sensor axes):
/// the input of a chip in datasheet mode ([`crate::ChipModel::Datasheet`]).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Stimulus {
    /// Time, s: the chip's internal clocks tick at multiples of 1/ODR of it.
    /// Stimuli not later than the previous one are ignored.
    pub t_s: f64,
    /// Specific force, m/s².
    pub accel_mps2: [f64; 3],
    /// Angular velocity, rad/s.
    pub gyro_rads: [f64; 3],
    /// Die temperature, °C.
    pub temp_c: f64,
}

/// Produces what the simulated chip serves.
///
/// An ideal chip ([`crate::ChipModel::Ideal`]) latches [`sample`](Self::sample)
/// into the data registers whenever a burst read starts at a data register.
/// A chip in datasheet mode takes [`stimulus`](Self::stimulus) whenever it
/// runs its clocks ([`crate::Bno055Sim::advance`], and before each data
/// read), filters it and writes the registers at its internal rates, adding
/// [`output_noise`](Self::output_noise) to each register update.
pub trait SampleSource {
    /// The next reading (ideal chip).
    fn sample(&mut self) -> RawReading;

    /// The physical input now (datasheet mode); `None`, the default: the
    /// source only has readings, and the chip serves them as an ideal chip.
    fn stimulus(&mut self) -> Option<Stimulus> {
        None
    }

    /// Noise added to one register update of `sensor` (datasheet mode), in
    /// its SI unit (m/s², rad/s); zero by default.
    fn output_noise(&mut self, sensor: Sensor) -> [f64; 3] {
        let _ = sensor;
        [0.0; 3]
    }
}

impl<T: SampleSource + ?Sized> SampleSource for &mut T {
    fn sample(&mut self) -> RawReading {
        (**self).sample()
    }
    fn stimulus(&mut self) -> Option<Stimulus> {
        (**self).stimulus()
    }
    fn output_noise(&mut self, sensor: Sensor) -> [f64; 3] {
        (**self).output_noise(sensor)
    }
}

#[cfg(feature = "alloc")]
impl<T: SampleSource + ?Sized> SampleSource for alloc::boxed::Box<T> {
    fn sample(&mut self) -> RawReading {
        (**self).sample()
    }
    fn stimulus(&mut self) -> Option<Stimulus> {
        (**self).stimulus()
    }
    fn output_noise(&mut self, sensor: Sensor) -> [f64; 3] {
        (**self).output_noise(sensor)
    }
}

/// Always the same reading.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct ConstantSource(pub RawReading);

impl SampleSource for ConstantSource {
    fn sample(&mut self) -> RawReading {
        self.0
    }
}

/// Deterministic sinusoids, one step per reading: a sensor lying flat
/// (gravity on +z) that rocks gently about all three axes.
///
/// Reading `n` is [`SineSource::reading`]`(n)`; axis `i` of each vector is
/// `offset + amplitude · sin(2π n / period + i · 2π/3)`, rounded to counts.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SineSource {
    /// Index of the next reading.
    pub n: u64,
    /// Samples per sine period.
    pub period: u32,
}

impl Default for SineSource {
    /// 200 readings per period.
    fn default() -> Self {
        Self { n: 0, period: 200 }
    }
}

/// Accelerometer offsets, counts: 9.81 m/s² on z at 100 LSB per m/s².
const ACCEL_OFFSET: [f32; 3] = [0.0, 0.0, 981.0];
/// Accelerometer amplitude, counts (0.5 m/s²).
const ACCEL_AMPLITUDE: f32 = 50.0;
/// Gyroscope amplitude, counts (0.5 rad/s at 900 LSB per rad/s).
const GYRO_AMPLITUDE: f32 = 450.0;
/// Magnetometer offsets, counts (about 20, 0, -40 µT at 16 LSB per µT).
const MAG_OFFSET: [f32; 3] = [320.0, 0.0, -640.0];
/// Magnetometer amplitude, counts.
const MAG_AMPLITUDE: f32 = 80.0;
/// Die temperature, °C.
const TEMPERATURE: i8 = 25;

impl SineSource {
    /// A source whose period is `period` readings (at least 1).
    pub fn new(period: u32) -> Self {
        Self {
            n: 0,
            period: period.max(1),
        }
    }

    /// Reading number `n` (pure function of `n` and the period).
    pub fn reading(&self, n: u64) -> RawReading {
        let period = u64::from(self.period.max(1));
        // Reduce first so that the phase stays exact for any n.
        let phase = (n % period) as f32 / period as f32 * TAU;
        let axis = |offset: f32, amplitude: f32, i: usize| -> i16 {
            let value = offset + amplitude * sin(phase + i as f32 * TAU / 3.0);
            round_to_i16(value)
        };
        RawReading {
            accel: [0, 1, 2].map(|i| axis(ACCEL_OFFSET[i], ACCEL_AMPLITUDE, i)),
            gyro: [0, 1, 2].map(|i| axis(0.0, GYRO_AMPLITUDE, i)),
            mag: [0, 1, 2].map(|i| axis(MAG_OFFSET[i], MAG_AMPLITUDE, i)),
            temp: TEMPERATURE,
        }
    }
}

impl SampleSource for SineSource {
    fn sample(&mut self) -> RawReading {
        let reading = self.reading(self.n);
        self.n = self.n.wrapping_add(1);
        reading
    }
}

const TAU: f32 = core::f32::consts::TAU;
const PI: f32 = core::f32::consts::PI;

/// Rounds half away from zero and saturates (no `libm` in `no_std`).
fn round_to_i16(x: f32) -> i16 {
    let r = if x >= 0.0 { x + 0.5 } else { x - 0.5 };
    // `as` saturates and truncates toward zero.
    r as i16
}

/// sin(x) for x in [0, 2π + 2π·2/3]: reduction to [-π/2, π/2] and a
/// degree-11 Taylor polynomial (error below 1e-6 there).
fn sin(x: f32) -> f32 {
    // To [-π, π].
    let mut x = x % TAU;
    if x > PI {
        x -= TAU;
    } else if x < -PI {
        x += TAU;
    }
    // sin(π - x) = sin(x): to [-π/2, π/2].
    if x > PI / 2.0 {
        x = PI - x;
    } else if x < -PI / 2.0 {
        x = -PI - x;
    }
    let x2 = x * x;
    // Horner form of x - x³/3! + x⁵/5! - x⁷/7! + x⁹/9! - x¹¹/11!.
    x * (1.0
        - x2 / 6.0 * (1.0 - x2 / 20.0 * (1.0 - x2 / 42.0 * (1.0 - x2 / 72.0 * (1.0 - x2 / 110.0)))))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sine_matches_std_sin() {
        for k in 0..2000 {
            let x = k as f32 * 0.0067; // up to 13.4 rad
            let reference = (x as f64).sin() as f32;
            assert!((sin(x) - reference).abs() < 2e-6, "x={x}");
        }
    }

    #[test]
    fn sine_source_follows_its_formula() {
        let mut source = SineSource::new(100);
        for n in 0..250u64 {
            let reading = source.sample();
            let phase = (n % 100) as f64 / 100.0 * core::f64::consts::TAU;
            for i in 0..3 {
                let shift = i as f64 * core::f64::consts::TAU / 3.0;
                let gyro = 450.0 * (phase + shift).sin();
                assert!(
                    (f64::from(reading.gyro[i]) - gyro).abs() <= 0.51,
                    "n={n} i={i}"
                );
                let accel = [0.0, 0.0, 981.0][i] + 50.0 * (phase + shift).sin();
                assert!((f64::from(reading.accel[i]) - accel).abs() <= 0.51);
            }
            assert_eq!(reading.temp, 25);
        }
        // Periodic and deterministic.
        assert_eq!(source.reading(7), source.reading(107));
        assert_eq!(source.n, 250);
    }

    #[test]
    fn rounding_is_half_away_from_zero_and_saturates() {
        assert_eq!(round_to_i16(1.5), 2);
        assert_eq!(round_to_i16(-1.5), -2);
        assert_eq!(round_to_i16(1.49), 1);
        assert_eq!(round_to_i16(1e9), i16::MAX);
        assert_eq!(round_to_i16(-1e9), i16::MIN);
    }
}
