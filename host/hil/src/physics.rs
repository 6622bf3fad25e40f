//! What an IMU on the simulated arm's flange measures.
//!
//! [`ModelSource`] is a [`SampleSource`] for the register-level BNO055: each
//! time the firmware latches a reading it takes the simulated arm's true
//! joint state at that instant ([`TrueMotion::now`], from the simulated
//! AUBO or UR controller), predicts the sensor
//! output with the measurement model at the hidden truth x* (docs/model.md §2–3,
//! paper (5)–(6)), adds Gaussian noise Σ_z, and turns it into register
//! counts as the chip does: rounded to the LSB (0.01 m/s², 1/900 rad/s with
//! the firmware's `UNIT_SEL`) and saturated at the configured full scale.
//!
//! The reading is computed at the instant the firmware stamps it, so the
//! true time offset τ is zero; what the host's clock mapping adds to it is
//! the recording's own error.

use rand::rngs::StdRng;
use rand::SeedableRng;
use rand_distr::{Distribution, StandardNormal};
use robimu_bno055_sim::{RawReading, SampleSource};
use robimu_hil_sim::aubo::TrueMotion;

use robimu_model::{JointState, MeasurementModel};

/// m/s² per accelerometer count (`UNIT_SEL` m/s²: 100 LSB per m/s²).
pub const ACCEL_LSB: f64 = 0.01;
/// rad/s per gyroscope count (`UNIT_SEL` rad/s: 900 LSB per rad/s).
pub const GYRO_LSB: f64 = 1.0 / 900.0;

/// IMU readings computed from the simulated arm's true motion.
pub struct ModelSource {
    probe: Box<dyn TrueMotion>,
    model: MeasurementModel,
    sigma_z: [f64; 6],
    accel_full_scale: f64,
    gyro_full_scale: f64,
    temperature_c: i8,
    rng: StdRng,
    latched: u64,
}

impl ModelSource {
    /// Readings of `model` (the hidden truth) along the arm `probe` reads,
    /// with noise of standard deviations `sigma_z` (m/s² ×3, rad/s ×3), the
    /// chip's default ranges (±4 g, ±2000 °/s) and 25 °C.
    pub fn new(
        probe: Box<dyn TrueMotion>,
        model: MeasurementModel,
        sigma_z: [f64; 6],
        seed: u64,
    ) -> Self {
        Self {
            probe,
            model,
            sigma_z,
            accel_full_scale: 4.0 * 9.80665,
            gyro_full_scale: 2000f64.to_radians(),
            temperature_c: 25,
            rng: StdRng::seed_from_u64(seed),
            latched: 0,
        }
    }

    /// How many readings were latched so far.
    pub fn latched(&self) -> u64 {
        self.latched
    }

    /// The noise-free sensor output now (m/s², rad/s), before quantisation.
    pub fn ideal_now(&self) -> [f64; 6] {
        let state = self.probe.now();
        let n = self.model.dof();
        let js = JointState::from_slices(
            &state.q[..n],
            &state.qd[..n],
            &state.qdd[..n],
            &[0.0; 6][..n],
        );
        self.model.predict(&js)
    }
}

/// Rounds `value` to counts of `lsb`, saturated at ±`full_scale`.
pub fn to_counts(value: f64, lsb: f64, full_scale: f64) -> i16 {
    let limit = (full_scale / lsb).floor().min(f64::from(i16::MAX));
    (value / lsb).round().clamp(-limit, limit) as i16
}

impl SampleSource for ModelSource {
    fn sample(&mut self) -> RawReading {
        let ideal = self.ideal_now();
        let mut z = [0.0; 6];
        for c in 0..6 {
            let n: f64 = StandardNormal.sample(&mut self.rng);
            z[c] = ideal[c] + self.sigma_z[c] * n;
        }
        self.latched += 1;
        RawReading {
            accel: std::array::from_fn(|i| to_counts(z[i], ACCEL_LSB, self.accel_full_scale)),
            gyro: std::array::from_fn(|i| to_counts(z[3 + i], GYRO_LSB, self.gyro_full_scale)),
            mag: [0; 3],
            temp: self.temperature_c,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counts_round_to_the_lsb_and_saturate() {
        assert_eq!(to_counts(9.81, ACCEL_LSB, 39.2266), 981);
        assert_eq!(to_counts(-0.004_9, ACCEL_LSB, 39.2266), 0);
        assert_eq!(to_counts(-0.005_1, ACCEL_LSB, 39.2266), -1);
        assert_eq!(to_counts(100.0, ACCEL_LSB, 39.2266), 3922);
        assert_eq!(to_counts(-100.0, ACCEL_LSB, 39.2266), -3922);
        assert_eq!(to_counts(1.0, GYRO_LSB, 2000f64.to_radians()), 900);
        assert_eq!(to_counts(1e9, GYRO_LSB, 1e9), i16::MAX);
    }
}
