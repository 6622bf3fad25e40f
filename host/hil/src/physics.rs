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
//! With [`ModelSource::with_noise_model`] the noise is instead correlated in
//! time and follows the motion (docs/model.md §4.6), drawn sample by sample
//! as the chip latches readings ([`NoiseSampler`]).
//!
//! The reading is computed at the instant the firmware stamps it, so the
//! true time offset τ is zero; what the host's clock mapping adds to it is
//! the recording's own error.

use rand::rngs::StdRng;
use rand::SeedableRng;
use rand_distr::{Distribution, StandardNormal};
use robimu_bno055_sim::{RawReading, SampleSource};
use robimu_hil_sim::aubo::{TrueMotion, TrueState};

use robimu_model::noise::{NoiseModel, NoiseSampler};
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
    sampler: Option<NoiseSampler>,
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
            sampler: None,
        }
    }

    /// Noise of `model` instead of white Σ_z (its σ replace `sigma_z`): the
    /// readings form one segment from the first latched one.
    pub fn with_noise_model(mut self, model: NoiseModel) -> Self {
        self.sigma_z = model.sigma_z();
        self.sampler = Some(NoiseSampler::new(model));
        self
    }

    /// How many readings were latched so far.
    pub fn latched(&self) -> u64 {
        self.latched
    }

    /// The noise-free sensor output now (m/s², rad/s), before quantisation.
    pub fn ideal_now(&self) -> [f64; 6] {
        self.ideal_at(&self.probe.now())
    }

    fn ideal_at(&self, state: &TrueState) -> [f64; 6] {
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
        let state = self.probe.now();
        let ideal = self.ideal_at(&state);
        let mut z = [0.0; 6];
        if let Some(sampler) = &mut self.sampler {
            let e: [f64; 6] = std::array::from_fn(|_| StandardNormal.sample(&mut self.rng));
            let n = self.model.dof();
            let qdd2: f64 = state.qdd[..n].iter().map(|a| a * a).sum();
            let w = sampler.next(e, qdd2);
            for c in 0..6 {
                z[c] = ideal[c] + w[c];
            }
        } else {
            for c in 0..6 {
                let n: f64 = StandardNormal.sample(&mut self.rng);
                z[c] = ideal[c] + self.sigma_z[c] * n;
            }
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

    struct Swinging(std::sync::Arc<std::sync::atomic::AtomicU64>);

    impl TrueMotion for Swinging {
        fn now(&self) -> TrueState {
            let k = self.0.fetch_add(1, std::sync::atomic::Ordering::Relaxed) as f64;
            let t = k / 100.0;
            TrueState {
                t,
                q: [0.3 * t.sin(), 0.5, -0.4, 0.2, 0.1, 0.0],
                qd: [0.3 * t.cos(), 0.0, 0.0, 0.0, 0.0, 0.0],
                qdd: [-0.3 * t.sin(), 0.0, 0.0, 0.0, 0.0, 0.0],
            }
        }
    }

    fn source(model: Option<NoiseModel>) -> ModelSource {
        let robot = robimu_model::Robot::aubo_i5();
        let layout = robimu_model::ParamLayout::new(&robot);
        let m = MeasurementModel::new(&robot, &layout, &layout.nominal()).unwrap();
        let probe = Box::new(Swinging(Default::default()));
        let s = ModelSource::new(probe, m, robot.sigma_z(), 9);
        match model {
            Some(model) => s.with_noise_model(model),
            None => s,
        }
    }

    #[test]
    fn a_white_noise_model_reads_as_white_sigma_z() {
        let sz = robimu_model::Robot::aubo_i5().sigma_z();
        let mut a = source(None);
        let mut b = source(Some(NoiseModel::white(sz).unwrap()));
        for _ in 0..200 {
            assert_eq!(a.sample(), b.sample());
        }
        // a strongly correlated gyro channel: successive readings differ
        // far less than white ones of the same σ would
        let mut m = NoiseModel::white(sz).unwrap();
        m.imu[3].ar = robimu_model::noise::ArNoise::new(vec![0.99], 0.05).unwrap();
        let mut c = source(Some(m));
        let mut w = source(None);
        let steps = |s: &mut ModelSource| -> f64 {
            let g: Vec<f64> = (0..2000).map(|_| f64::from(s.sample().gyro[0])).collect();
            g.windows(2).map(|p| (p[1] - p[0]).powi(2)).sum::<f64>() / g.len() as f64
        };
        let (dc, dw) = (steps(&mut c), steps(&mut w));
        // E(Δ²) = 2σ²(1 − φ) = 1e-4·(counts 900²)/… : far below 2σ² = 5e-3 rad²/s²
        assert!(
            dc < 0.1 * 2.0 * 0.05f64.powi(2) * 900.0 * 900.0,
            "{dc} vs white {dw}"
        );
        assert!(c.latched() == 2000);
    }

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
