//! Simulated one-IMU pose sessions for tests (MODEL.md §10): the one
//! set-up the pose calibration, diagnosis, τ test and pose check tests
//! share, by default poses at 15 Hz with 3 ms jitter and the IMU at 100 Hz.

use robimu_model::{PoseMeasurements, PoseSpline};

use super::{random_pose_motion, simulate_pose_session, ImuTiming, PoseNoise};

/// Timing and noise of a simulated test session; the default is the
/// simulator's usual hand-held session with exact IMU stamps.
#[derive(Clone, Debug)]
pub(crate) struct SessionSpec {
    /// Pose rate (Hz).
    pub pose_rate: f64,
    /// Pose stamp jitter σ (s).
    pub pose_jitter: f64,
    /// IMU rate (Hz).
    pub imu_rate: f64,
    /// Noise of the poses and IMU samples.
    pub noise: PoseNoise,
    /// IMU stamps' arrival timing, applied with the noise seed.
    pub timing: ImuTiming,
}

impl Default for SessionSpec {
    fn default() -> Self {
        Self {
            pose_rate: 15.0,
            pose_jitter: 0.003,
            imu_rate: 100.0,
            noise: PoseNoise::default(),
            timing: ImuTiming::default(),
        }
    }
}

/// A simulated session with the motion it followed.
pub(crate) struct Simulated {
    /// The random motion of the posed body.
    pub motion: PoseSpline,
    /// Pose and IMU samples.
    pub data: PoseMeasurements,
}

/// A `duration` s session of an IMU with parameters `truth` on the
/// random motion of `motion_seed`, the samples' noise (and IMU timing)
/// drawn from `noise_seed`.
pub(crate) fn simulated(
    truth: &[f64],
    duration: f64,
    motion_seed: u64,
    noise_seed: u64,
    spec: &SessionSpec,
) -> Simulated {
    let motion = random_pose_motion(duration, motion_seed).unwrap();
    let mut data = simulate_pose_session(
        truth,
        &motion,
        spec.pose_rate,
        spec.pose_jitter,
        spec.imu_rate,
        &spec.noise,
        noise_seed,
    )
    .unwrap();
    spec.timing.apply(&mut data, noise_seed).unwrap();
    Simulated { motion, data }
}
