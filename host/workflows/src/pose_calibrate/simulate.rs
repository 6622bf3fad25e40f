//! Simulated pose sessions with known truth (MODEL.md §10): a smooth random
//! hand-held-like motion as a [`PoseSpline`], a truth x drawn from the
//! priors with the mount rotation uniform over SO(3), and pose and IMU
//! samples with noise.

use rand::{Rng, SeedableRng};
use rand_distr::{Distribution, Normal};
use robimu_model::geom::{exp_so3, matrix_from_quat, mul_mm, quat_from_matrix, M3, V3};
use robimu_model::pose_measurement::{self as pm, ACCEL, GYRO, POSE_PARAMS, ROT};
use robimu_model::{ImuIntrinsics, Knots, PoseMeasurements, PoseSpline};

use super::startup::euler_zyx;
use super::PoseCalibrationError;

#[cfg(test)]
#[path = "test_support.rs"]
pub(crate) mod test_support;

/// Time the random motion extends beyond the session at each end (s), so
/// that t_i + τ stays on it for |τ| < this.
pub(crate) const MOTION_PAD: f64 = 6.0;
/// Knot spacing of the random motion (s).
pub(crate) const MOTION_KNOTS: f64 = 0.5;

/// Noise of a simulated pose session.
#[derive(Clone, Debug, PartialEq)]
pub struct PoseNoise {
    /// Pose position σ_p (m).
    pub sigma_p: f64,
    /// Pose rotation σ_r (rad).
    pub sigma_r: f64,
    /// IMU σ per channel (m/s², rad/s).
    pub sigma_z: [f64; 6],
}

impl Default for PoseNoise {
    /// As [`super::PoseCalibrationOptions::default`].
    fn default() -> Self {
        let o = super::PoseCalibrationOptions::default();
        Self {
            sigma_p: o.sigma_p,
            sigma_r: o.sigma_r,
            sigma_z: o.sigma_z,
        }
    }
}

fn normal(rng: &mut impl Rng, sigma: f64) -> f64 {
    Normal::new(0.0, sigma)
        .map(|d| d.sample(rng))
        .unwrap_or(0.0)
}

/// A rotation uniform on SO(3) (a normalised 4-D Gaussian quaternion).
pub(crate) fn uniform_rotation(rng: &mut impl Rng) -> M3 {
    loop {
        let q: [f64; 4] = std::array::from_fn(|_| normal(rng, 1.0));
        let n = q.iter().map(|v| v * v).sum::<f64>().sqrt();
        if n > 1e-6 {
            return matrix_from_quat(q.map(|v| v / n));
        }
    }
}

/// A hand-held-like random motion over [−pad, duration + pad] (pad =
/// [`MOTION_PAD`]): control points every [`MOTION_KNOTS`] s, positions
/// N(0, 0.15 m) per axis, rotation steps N(0, 0.8 rad) per axis (capped at
/// 2 rad): rates of hundreds of °/s.
pub fn random_pose_motion(duration: f64, seed: u64) -> Result<PoseSpline, PoseCalibrationError> {
    let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
    let knots = Knots::uniform(-MOTION_PAD, duration + MOTION_PAD, MOTION_KNOTS, 3)
        .map_err(|e| PoseCalibrationError::Input(e.to_string()))?;
    let m = knots.num_coeffs();
    let pos: Vec<V3> = (0..m)
        .map(|_| std::array::from_fn(|_| normal(&mut rng, 0.15)))
        .collect();
    let mut r = uniform_rotation(&mut rng);
    let rot: Vec<M3> = (0..m)
        .map(|_| {
            let mut d: V3 = std::array::from_fn(|_| normal(&mut rng, 0.8));
            let n = d.iter().map(|v| v * v).sum::<f64>().sqrt();
            if n > 2.0 {
                d = d.map(|v| v * 2.0 / n);
            }
            r = mul_mm(&r, &exp_so3(d));
            r
        })
        .collect();
    Ok(PoseSpline::new(knots, &pos, &rot)?)
}

/// A truth x drawn from the §10 priors: p_imu N(0, 0.2 m), g_xy N(0, 0.5),
/// τ N(0, 1 s), the §6 sensor intrinsics; the rotations R_a = Q·Rzyx(n_a),
/// R_ω = Q·Rzyx(n_ω) with Q uniform on SO(3) and n ~ N(0, 5°) per angle.
pub fn draw_pose_truth(seed: u64) -> Vec<f64> {
    let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
    let d = std::f64::consts::PI / 180.0;
    let q = uniform_rotation(&mut rng);
    let specs = pm::pose_param_specs([0.0; 3], [0.0; 3]);
    let mut x: Vec<f64> = specs
        .iter()
        .map(|s| s.nominal + normal(&mut rng, s.sigma))
        .collect();
    for blk in [ACCEL, GYRO] {
        let n: V3 = std::array::from_fn(|_| normal(&mut rng, 5.0 * d));
        let r = mul_mm(&q, &ImuIntrinsics::ideal(n).rotation());
        x[blk + ROT..blk + ROT + 3].copy_from_slice(&euler_zyx(&r));
    }
    x
}

/// A pose session of the motion `motion` (from [`random_pose_motion`]) on
/// its span less [`MOTION_PAD`] at each end, with IMU parameters `truth`:
/// poses at `pose_rate` Hz with sample times jittered by N(0, `pose_jitter`)
/// (stamped exactly), the IMU at `imu_rate` Hz reading at t_i + τ, noise
/// `noise` (§4, §10).
pub fn simulate_pose_session(
    truth: &[f64],
    motion: &PoseSpline,
    pose_rate: f64,
    pose_jitter: f64,
    imu_rate: f64,
    noise: &PoseNoise,
    seed: u64,
) -> Result<PoseMeasurements, PoseCalibrationError> {
    if truth.len() != POSE_PARAMS || !(pose_rate > 0.0 && imu_rate > 0.0 && pose_jitter >= 0.0) {
        return Err(PoseCalibrationError::Input(
            "simulate: 30 parameters and positive rates needed".into(),
        ));
    }
    let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
    let (t0, t1) = (
        motion.knots().start() + MOTION_PAD,
        motion.knots().end() - MOTION_PAD,
    );
    let mut out = PoseMeasurements::default();
    let n_pose = ((t1 - t0) * pose_rate) as usize;
    for k in 0..=n_pose {
        let t = (t0 + k as f64 / pose_rate + normal(&mut rng, pose_jitter)).clamp(t0, t1);
        if out.pose_t.last().is_some_and(|&l| t <= l) {
            continue;
        }
        let s = motion
            .evaluate(t)
            .map_err(|e| PoseCalibrationError::Input(e.to_string()))?;
        let n_r: V3 = std::array::from_fn(|_| normal(&mut rng, noise.sigma_r));
        out.pose_t.push(t);
        out.pose_p.push(std::array::from_fn(|c| {
            s.p[c] + normal(&mut rng, noise.sigma_p)
        }));
        out.pose_q
            .push(quat_from_matrix(&mul_mm(&s.r, &exp_so3(n_r))));
    }
    let n_imu = ((t1 - t0) * imu_rate) as usize;
    for i in 0..=n_imu {
        let t = t0 + i as f64 / imu_rate;
        let z = pm::predict(motion, t, truth)
            .map_err(|e| PoseCalibrationError::Input(format!("simulate: {e}")))?;
        out.imu_t.push(t);
        out.imu_z.push(std::array::from_fn(|c| {
            z[c] + normal(&mut rng, noise.sigma_z[c])
        }));
    }
    Ok(out)
}

/// Arrival timing of simulated IMU stamps (docs/model.md §7.9): a sample
/// taken at true time t is stamped t + lag(t) + n, n ~ N(0, `jitter`²),
/// lag(t) = `drift` · ((t − t_0)/(t_1 − t_0) − ½) over the samples' span
/// [t_0, t_1] (zero mid-recording, so the truth's τ is the mean lag's).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ImuTiming {
    /// Arrival jitter σ (s).
    pub jitter: f64,
    /// Change of the lag over the recording (s).
    pub drift: f64,
}

impl ImuTiming {
    /// Whether the stamps are the true times.
    pub fn is_exact(&self) -> bool {
        self.jitter == 0.0 && self.drift == 0.0
    }

    /// Restamp the IMU samples of `data` (module doc of [`ImuTiming`]),
    /// keeping them in stamp order.
    pub fn apply(
        &self,
        data: &mut PoseMeasurements,
        seed: u64,
    ) -> Result<(), PoseCalibrationError> {
        if !(self.jitter.is_finite() && self.jitter >= 0.0 && self.drift.is_finite()) {
            return Err(PoseCalibrationError::Input(format!(
                "IMU timing: jitter {} s must be ≥ 0 and drift {} s finite",
                self.jitter, self.drift
            )));
        }
        if self.is_exact() || data.imu_t.len() < 2 {
            return Ok(());
        }
        let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
        let (t0, t1) = (data.imu_t[0], data.imu_t[data.imu_t.len() - 1]);
        let mut samples: Vec<(f64, [f64; 6])> = data
            .imu_t
            .iter()
            .zip(&data.imu_z)
            .map(|(&t, &z)| {
                let lag = self.drift * ((t - t0) / (t1 - t0) - 0.5);
                (t + lag + normal(&mut rng, self.jitter), z)
            })
            .collect();
        samples.sort_by(|a, b| a.0.total_cmp(&b.0));
        (data.imu_t, data.imu_z) = samples.into_iter().unzip();
        Ok(())
    }
}
