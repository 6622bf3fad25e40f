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
//! With [`ModelSource::with_warm_up`] the biases settle after power-up along
//! an exponential warm-up curve and the die temperature (the `TEMP`
//! register, the recording's `temp_c` column) follows the same curve.
//!
//! With [`ModelSource::with_arm_physics`] the noise-free signal comes from
//! an independent implementation of the chain with hidden effects
//! ([`crate::arm_physics`]) instead of the measurement model.
//!
//! For the ideal chip ([`robimu_bno055_sim::ChipModel::Ideal`]) the reading
//! is computed at the instant the firmware stamps it, so the true time
//! offset τ is zero; what the host's clock mapping adds to it is the
//! recording's own error. For a chip in datasheet mode the source gives the
//! noise-free signal as a [`Stimulus`] (the chip filters, holds, saturates
//! and quantises it) and the noise per register update
//! ([`SampleSource::output_noise`]): the noise model's correlation is then
//! per internal update of each sensor, not per firmware read.

use rand::rngs::StdRng;
use rand::SeedableRng;
use rand_distr::{Distribution, StandardNormal};
use robimu_bno055_sim::{RawReading, SampleSource, Sensor, Stimulus};
use robimu_hil_sim::aubo::{TrueMotion, TrueState};

use super::arm_physics::ArmPhysics;

use robimu_model::noise::{NoiseModel, NoiseModelError, NoiseSampler};
use robimu_model::{JointState, MeasurementModel};

/// m/s² per accelerometer count (`UNIT_SEL` m/s²: 100 LSB per m/s²).
pub(crate) const ACCEL_LSB: f64 = 0.01;
/// rad/s per gyroscope count (`UNIT_SEL` rad/s: 900 LSB per rad/s).
pub(crate) const GYRO_LSB: f64 = 1.0 / 900.0;

/// A warm-up after power-up: with f(t) = exp(−t/τ) (t from power-up), the
/// die temperature is `temp_end_c + (temp_start_c − temp_end_c)·f(t)` and
/// the biases are the hidden truth's plus `bias_start_offset·f(t)`: the
/// truth's biases are the settled ones.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WarmUp {
    /// τ, s.
    pub time_constant_s: f64,
    /// Die temperature at power-up, °C.
    pub temp_start_c: f64,
    /// Die temperature once warm, °C.
    pub temp_end_c: f64,
    /// Bias at power-up minus the settled bias (m/s² ×3, rad/s ×3).
    pub bias_start_offset: [f64; 6],
}

impl WarmUp {
    /// f(t) = exp(−t/τ), t seconds after power-up (1 before it).
    pub fn remaining(&self, t: f64) -> f64 {
        (-t.max(0.0) / self.time_constant_s).exp()
    }

    /// The die temperature t seconds after power-up, °C.
    pub fn temperature_c(&self, t: f64) -> f64 {
        self.temp_end_c + (self.temp_start_c - self.temp_end_c) * self.remaining(t)
    }

    /// The bias offset t seconds after power-up.
    pub fn bias_offset(&self, t: f64) -> [f64; 6] {
        let f = self.remaining(t);
        self.bias_start_offset.map(|b| b * f)
    }
}

/// Accelerometer noise dominated by vibration (issue 14's model,
/// docs/model.md §4.6): channels `ax, ay, az` AR(1) with coefficient `phi`
/// and marginal σ at rest from `sigma_z`, variance σ² + `motion`·‖q̈‖²; the
/// gyroscope white with `sigma_z`.
pub(crate) fn vibration_noise(
    sigma_z: [f64; 6],
    phi: f64,
    motion: f64,
) -> Result<NoiseModel, NoiseModelError> {
    NoiseModel::ar1(sigma_z, [Some(phi), None], [motion, 0.0])
}

/// Die temperature without a warm-up, °C.
const TEMPERATURE_C: f64 = 25.0;

/// IMU readings computed from the simulated arm's true motion.
pub(crate) struct ModelSource {
    probe: Box<dyn TrueMotion>,
    model: MeasurementModel,
    /// The independent chain with hidden effects instead of `model`.
    arm: Option<ArmPhysics>,
    sigma_z: [f64; 6],
    accel_full_scale: f64,
    gyro_full_scale: f64,
    rng: StdRng,
    latched: u64,
    sampler: Option<NoiseSampler>,
    /// Datasheet mode: the gyroscope's noise sampler (the accelerometer's
    /// is `sampler`), as the two sensors update at their own rates.
    gyro_sampler: Option<NoiseSampler>,
    warm_up: Option<WarmUp>,
    /// Arm time at power-up (the source's creation), s.
    t_power_on: f64,
    /// ‖q̈‖² at the last stimulus (datasheet mode's noise level).
    last_qdd2: f64,
}

impl ModelSource {
    /// Readings of `model` (the hidden truth) along the arm `probe` reads,
    /// with noise of standard deviations `sigma_z` (m/s² ×3, rad/s ×3), the
    /// chip's default ranges (±4 g, ±2000 °/s) and 25 °C. Power-up (the
    /// warm-up's time zero) is now.
    pub fn new(
        probe: Box<dyn TrueMotion>,
        model: MeasurementModel,
        sigma_z: [f64; 6],
        seed: u64,
    ) -> Self {
        let t_power_on = probe.now().t;
        Self {
            probe,
            model,
            arm: None,
            sigma_z,
            accel_full_scale: 4.0 * 9.80665,
            gyro_full_scale: 2000f64.to_radians(),
            rng: StdRng::seed_from_u64(seed),
            latched: 0,
            sampler: None,
            gyro_sampler: None,
            warm_up: None,
            t_power_on,
            last_qdd2: 0.0,
        }
    }

    /// Noise of `model` instead of white Σ_z (its σ replace `sigma_z`): the
    /// readings form one segment from the first latched one.
    pub fn with_noise_model(mut self, model: NoiseModel) -> Self {
        self.sigma_z = model.sigma_z();
        self.gyro_sampler = Some(NoiseSampler::new(model.clone()));
        self.sampler = Some(NoiseSampler::new(model));
        self
    }

    /// The signal from `arm` (an independent chain with hidden effects,
    /// [`crate::arm_physics`]) instead of the measurement model.
    pub fn with_arm_physics(mut self, arm: ArmPhysics) -> Self {
        self.arm = Some(arm);
        self
    }

    /// Biases and temperature following `warm_up` from power-up.
    pub fn with_warm_up(mut self, warm_up: WarmUp) -> Self {
        self.warm_up = Some(warm_up);
        self
    }

    /// The die temperature at arm time `t`, °C.
    pub fn temperature_c(&self, t: f64) -> f64 {
        self.warm_up
            .map_or(TEMPERATURE_C, |w| w.temperature_c(t - self.t_power_on))
    }

    /// The noise-free sensor output with the warm-up's bias offset, and ‖q̈‖².
    fn signal_at(&mut self, state: &TrueState) -> ([f64; 6], f64) {
        let mut z = self.ideal_at(state);
        if let Some(w) = &self.warm_up {
            let offset = w.bias_offset(state.t - self.t_power_on);
            for c in 0..6 {
                z[c] += offset[c];
            }
        }
        let n = self.model.dof();
        (z, state.qdd[..n].iter().map(|a| a * a).sum())
    }

    fn normals(&mut self) -> [f64; 6] {
        std::array::from_fn(|_| StandardNormal.sample(&mut self.rng))
    }

    /// How many readings (ideal chip) or stimuli (datasheet mode) were taken so far.
    #[cfg(test)]
    pub fn latched(&self) -> u64 {
        self.latched
    }

    fn ideal_at(&mut self, state: &TrueState) -> [f64; 6] {
        let n = self.model.dof();
        if let Some(arm) = &mut self.arm {
            return arm.signal(state.t, &state.q[..n], &state.qd[..n], &state.qdd[..n]);
        }
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
pub(crate) fn to_counts(value: f64, lsb: f64, full_scale: f64) -> i16 {
    let limit = (full_scale / lsb).floor().min(f64::from(i16::MAX));
    (value / lsb).round().clamp(-limit, limit) as i16
}

impl SampleSource for ModelSource {
    fn sample(&mut self) -> RawReading {
        let state = self.probe.now();
        let (ideal, qdd2) = self.signal_at(&state);
        let mut z = [0.0; 6];
        let e = self.normals();
        if let Some(sampler) = &mut self.sampler {
            let w = sampler.next(e, qdd2);
            for c in 0..6 {
                z[c] = ideal[c] + w[c];
            }
        } else {
            for c in 0..6 {
                z[c] = ideal[c] + self.sigma_z[c] * e[c];
            }
        }
        self.latched += 1;
        RawReading {
            accel: std::array::from_fn(|i| to_counts(z[i], ACCEL_LSB, self.accel_full_scale)),
            gyro: std::array::from_fn(|i| to_counts(z[3 + i], GYRO_LSB, self.gyro_full_scale)),
            mag: [0; 3],
            temp: self.temperature_c(state.t).round().clamp(-128.0, 127.0) as i8,
        }
    }

    fn stimulus(&mut self) -> Option<Stimulus> {
        let state = self.probe.now();
        let (z, qdd2) = self.signal_at(&state);
        self.last_qdd2 = qdd2;
        self.latched += 1;
        Some(Stimulus {
            t_s: state.t,
            accel_mps2: [z[0], z[1], z[2]],
            gyro_rads: [z[3], z[4], z[5]],
            temp_c: self.temperature_c(state.t),
        })
    }

    fn output_noise(&mut self, sensor: Sensor) -> [f64; 3] {
        let e = self.normals();
        let first = match sensor {
            Sensor::Accel => 0,
            Sensor::Gyro => 3,
        };
        let sampler = match sensor {
            Sensor::Accel => self.sampler.as_mut(),
            Sensor::Gyro => self.gyro_sampler.as_mut(),
        };
        let w = match sampler {
            Some(s) => s.next(e, self.last_qdd2),
            None => std::array::from_fn(|c| self.sigma_z[c] * e[c]),
        };
        [w[first], w[first + 1], w[first + 2]]
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

    /// The rig's vibration noise (issue 14's model) drawn by the source:
    /// the accelerometer residual divided by √(σ² + c‖q̈‖²) has unit
    /// variance whether the arm accelerates little or much (while the raw
    /// residual's variance grows with ‖q̈‖²), and lag-1 correlation φ.
    #[test]
    fn vibration_noise_is_correlated_and_stronger_with_motion() {
        let robot = robimu_model::Robot::aubo_i5();
        let (phi, c) = (0.8, 5.0);
        let noise = vibration_noise(robot.sigma_z(), phi, c).unwrap();
        let layout = robimu_model::ParamLayout::new(&robot);
        let model = || MeasurementModel::new(&robot, &layout, &layout.nominal()).unwrap();
        let reference = model();
        let probe = Box::new(Swinging(Default::default()));
        let mut s = ModelSource::new(probe, model(), robot.sigma_z(), 5).with_noise_model(noise);
        let sigma = robot.sigma_z()[0];
        let (mut u, mut raw) = (Vec::new(), Vec::new());
        for i in 0..20_000 {
            let r = s.sample();
            // reading i is probe step i + 1 (`new` took step 0)
            let t = (i + 1) as f64 / 100.0;
            let js = JointState::from_slices(
                &[0.3 * t.sin(), 0.5, -0.4, 0.2, 0.1, 0.0],
                &[0.3 * t.cos(), 0.0, 0.0, 0.0, 0.0, 0.0],
                &[-0.3 * t.sin(), 0.0, 0.0, 0.0, 0.0, 0.0],
                &[0.0; 6],
            );
            let e = f64::from(r.accel[0]) * ACCEL_LSB - reference.predict(&js)[0];
            let qdd2 = (0.3 * t.sin()).powi(2);
            u.push(e / (sigma * sigma + c * qdd2).sqrt());
            raw.push((e, qdd2));
        }
        let var = |f: &dyn Fn(f64) -> bool, x: &dyn Fn(usize) -> f64| {
            let idx: Vec<usize> = (0..u.len()).filter(|&i| f(raw[i].1)).collect();
            idx.iter().map(|&i| x(i).powi(2)).sum::<f64>() / idx.len() as f64
        };
        let (calm, busy) = (|q: f64| q < 0.02, |q: f64| q > 0.06);
        for band in [&calm as &dyn Fn(f64) -> bool, &busy] {
            let v = var(band, &|i| u[i]);
            assert!((v - 1.0).abs() < 0.15, "normalised variance {v}");
        }
        let ratio = var(&busy, &|i| raw[i].0) / var(&calm, &|i| raw[i].0);
        assert!(ratio > 2.5, "raw variance ratio busy/calm {ratio}");
        let r1 =
            u.windows(2).map(|w| w[0] * w[1]).sum::<f64>() / u.iter().map(|x| x * x).sum::<f64>();
        assert!((r1 - phi).abs() < 0.03, "lag-1 correlation {r1}");
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
