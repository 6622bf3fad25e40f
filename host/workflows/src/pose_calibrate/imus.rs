//! Several IMUs on one posed body (MODEL.md §9, §10): IMU 0's 30
//! parameters, then each further IMU's 28 (`imu<j>/<name>`, g_x and g_y
//! shared); each IMU's start-up, x and prior in that layout
//! ([`robimu_model::pose_measurement::imu_indices`]), and its fit.

use std::collections::BTreeMap;

use robimu_model::params::ParamSpec;
use robimu_model::pose_measurement::{self as pm, imu_view, pose_param_specs, G_XY, POSE_PARAMS};

use robimu_session::MountPrior;

use super::{PoseCalibrationError, Startup, TauDrift};

/// The samples of IMU j ≥ 1 of a pose session (IMU 0's are in
/// [`robimu_model::PoseMeasurements`]).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ImuSamples {
    /// Sample times (s, session clock).
    pub t: Vec<f64>,
    /// Samples [ax, ay, az, gx, gy, gz].
    pub z: Vec<[f64; 6]>,
}

/// What the calibration found for IMU j ≥ 1 (IMU 0's is in
/// [`super::PoseCalibration`]'s own fields).
#[derive(Debug, Clone)]
pub struct PoseImuFit {
    /// Its start-up (τ and sensor rotations from the data).
    pub startup: Startup,
    /// Residual RMS of its used samples per channel [ax … gz].
    pub imu_rms: [f64; 6],
    /// Its samples in the fit.
    pub imu_used: usize,
    /// The score test of its constant τ; `None` when it could not be formed.
    pub tau_drift: Option<TauDrift>,
}

/// The 30-vector of the start-up `st` (§10's order, g = 0).
pub(crate) fn start_x(st: &Startup) -> Vec<f64> {
    let mut x0 = Vec::with_capacity(POSE_PARAMS);
    x0.extend(st.p_imu);
    x0.extend([0.0, 0.0, st.tau]);
    for s in [&st.accel, &st.gyro] {
        x0.extend(s.gamma.iter().chain(&s.r).chain(&s.k).chain(&s.b));
    }
    x0
}

/// Whether entry `k` of a 30-vector is an IMU's own (not the shared g).
fn own(k: usize) -> bool {
    !(G_XY..G_XY + 2).contains(&k)
}

/// The specs and start of x for IMUs with start-ups `st` (IMU 0 first) and
/// the session's `mounts` ([`super::mount`]): IMU 0's 30, then each further
/// IMU's own 28 named `imu<j>/<name>`.
pub(crate) fn specs_and_start(
    st: &[Startup],
    mounts: &BTreeMap<usize, MountPrior>,
) -> (Vec<ParamSpec>, Vec<f64>) {
    let (mut specs, mut x0) = (Vec::new(), Vec::new());
    for (j, s) in st.iter().enumerate() {
        let (mut sj, mut xj) = (pose_param_specs(s.accel.r, s.gyro.r), start_x(s));
        super::mount::apply(&MountPrior::of_imu(mounts, j), &mut sj, &mut xj);
        for (k, (mut spec, v)) in sj.into_iter().zip(xj).enumerate() {
            if j == 0 || own(k) {
                if j > 0 {
                    spec.name = format!("imu{j}/{}", spec.name);
                }
                specs.push(spec);
                x0.push(v);
            }
        }
    }
    (specs, x0)
}

/// The checks of one IMU's samples ([`super::checked`]'s).
pub(crate) fn check_imu(
    t: &[f64],
    z: &[[f64; 6]],
    which: &str,
) -> Result<(), PoseCalibrationError> {
    let bad = |m: String| Err(PoseCalibrationError::Input(m));
    if z.len() != t.len() {
        return bad(format!("{which}: times and samples differ in length"));
    }
    if t.len() < 20 {
        return bad(format!("{which}: too few samples (need ≥ 20)"));
    }
    if t.windows(2)
        .any(|w| !(super::greater(w[1], w[0]) || w[1] == w[0]))
    {
        return bad(format!(
            "{which}: sample times must be finite and increasing"
        ));
    }
    if z.iter().flatten().any(|v| !v.is_finite()) {
        return bad(format!("{which}: a sample is not finite"));
    }
    Ok(())
}

/// Seed of IMU j ≥ 1's draws, from the session's `seed`.
fn imu_seed(seed: u64, j: usize) -> u64 {
    seed.wrapping_add((j as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15))
}

/// A truth of `n_imus` IMUs (2 + 28·K, MODEL.md §9): IMU 0's
/// [`super::draw_pose_truth`] of `seed`, each further IMU's own 28 from its
/// own draw (own mount rotation, intrinsics, p_I and τ), g IMU 0's.
pub fn draw_pose_imus_truth(seed: u64, n_imus: usize) -> Vec<f64> {
    let mut x = super::draw_pose_truth(seed);
    for j in 1..n_imus {
        let xj = super::draw_pose_truth(imu_seed(seed, j));
        x.extend((0..POSE_PARAMS).filter(|&k| own(k)).map(|k| xj[k]));
    }
    x
}

/// A session of `n_imus` IMUs with the K-IMU `truth` on `motion`: IMU 0
/// and the poses as [`super::simulate_pose_session`] of `seed`, IMU j ≥ 1
/// read at its own t_i + τ_j with its own noise draw.
#[allow(clippy::too_many_arguments)]
pub fn simulate_pose_imus(
    truth: &[f64],
    n_imus: usize,
    motion: &robimu_model::PoseSpline,
    (pose_rate, pose_jitter): (f64, f64),
    imu_rate: f64,
    noise: &super::PoseNoise,
    seed: u64,
) -> Result<(robimu_model::PoseMeasurements, Vec<ImuSamples>), PoseCalibrationError> {
    if n_imus == 0 || truth.len() != pm::n_pose_params(n_imus) {
        return Err(PoseCalibrationError::Input(format!(
            "simulate: {} IMU(s) need {} parameters (got {})",
            n_imus,
            pm::n_pose_params(n_imus),
            truth.len()
        )));
    }
    let sim = |j: usize, s: u64| {
        let xj = imu_view(truth, j);
        super::simulate_pose_session(&xj, motion, pose_rate, pose_jitter, imu_rate, noise, s)
    };
    let data = sim(0, seed)?;
    let mut more = Vec::with_capacity(n_imus - 1);
    for j in 1..n_imus {
        let d = sim(j, imu_seed(seed, j))?;
        more.push(ImuSamples {
            t: d.imu_t,
            z: d.imu_z,
        });
    }
    Ok((data, more))
}

#[cfg(test)]
#[path = "imus_tests.rs"]
mod tests;
