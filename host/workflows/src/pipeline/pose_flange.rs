//! A robot's flange as a pose source (`robimu simulate --source poses
//! --robot NAME`, docs/model.md §7.9): the motion, truth and IMU samples of
//! `robimu simulate --robot NAME` with the same seed, duration and rate
//! ([`super::simulate::simulate_motion`]: its imu.csv byte for byte), and
//! the flange's pose in the base frame W along the joint trajectory through
//! the true kinematics (with the truth's kinematic errors) instead of the
//! joint samples.
//!
//! The 30 pose parameters (MODEL.md §10) from the robot truth (§1, §5): B is
//! the flange, whose orientation the IMU frame has (E_n's rotation is the
//! identity), so p_imu = (ε_n1, ε_n2, ε_n3), and g_x, g_y, τ and the 24
//! sensor parameters are the robot truth's own (same W, same τ: the IMU
//! sample stamped t_i reads the motion at t_i + τ).
//!
//! Several IMUs (docs/model.md §9): the robot's K IMUs on the flange as
//! `robimu simulate --imus K` simulates them (each its own position ε_n1..3
//! at its mount, τ and sensor parameters, one motion); IMU j's pose
//! parameters are its own 28 (p_imu its ε_n1..3) after IMU 0's 30.

use std::path::PathBuf;

use rand::SeedableRng;
use rand_distr::{Distribution, StandardNormal};
use robimu_model::geom::{exp_so3, mul_mm, mul_mv, quat_from_matrix, V3};
use robimu_model::{JointState, MeasurementModel, PoseMeasurements, Robot};

use super::simulate::{simulate_motion, SessionSpec};
use crate::pose_calibrate::{ImuSamples, PoseNoise};

/// A simulated flange pose session.
pub(crate) struct FlangeSession {
    /// The 2 + 28·K pose parameters (module doc).
    pub truth: Vec<f64>,
    /// Poses of the flange and IMU 0's samples.
    pub data: PoseMeasurements,
    /// IMU j ≥ 1's samples at `more[j − 1]`.
    pub more: Vec<ImuSamples>,
    /// The IMU noise σ the samples have (the robot's).
    pub sigma_z: [f64; 6],
}

/// The flange of `robot` carrying `imus` IMUs on the motion of `robimu
/// simulate --robot` with `seed`, `duration` and IMU rate `imu_rate`; poses
/// at `pose_rate` Hz with times jittered by N(0, `pose_jitter`²) (stamped
/// exactly), noise σ_p, σ_r of `noise`.
#[allow(clippy::too_many_arguments)]
pub(crate) fn flange_session(
    robot: Robot,
    imus: usize,
    duration: f64,
    imu_rate: f64,
    seed: u64,
    pose_rate: f64,
    pose_jitter: f64,
    noise: &PoseNoise,
) -> anyhow::Result<FlangeSession> {
    // the motion alone: no session is written, no tracker poses drawn
    let spec = SessionSpec {
        poses: 0,
        imus,
        ..SessionSpec::plain(robot, duration, imu_rate, seed, PathBuf::new())
    };
    let m = simulate_motion(&spec)?;
    let robot = &spec.robot;
    let one = m.layout.imu_layout();
    // IMU j's one-IMU truth and its position on the flange
    let imu_truth = |j: usize| -> anyhow::Result<(Vec<f64>, V3)> {
        let xj = m.layout.imu_x(j, &m.x_true);
        let eps = one.unpack(&xj)?.eps[robot.dof() - 1];
        Ok((xj, [eps[0], eps[1], eps[2]]))
    };
    let (x0, p_imu) = imu_truth(0)?;
    let model = MeasurementModel::new(robot, one, &x0)?;
    let mut rng = rand::rngs::StdRng::seed_from_u64(seed ^ 0x0F1A_4E9E_5E55);
    let mut normal = |s: f64| -> f64 {
        let z: f64 = StandardNormal.sample(&mut rng);
        s * z
    };
    let (t0, t1) = (m.trajectory.knots().start(), m.trajectory.knots().end());
    let mut out = PoseMeasurements::default();
    let mut js = JointState::default();
    let n_pose = ((t1 - t0) * pose_rate) as usize;
    for k in 0..=n_pose {
        let t = (t0 + k as f64 / pose_rate + normal(pose_jitter)).clamp(t0, t1);
        if out.pose_t.last().is_some_and(|&l| t <= l) {
            continue;
        }
        m.trajectory.evaluate(t, &mut js)?;
        let (imu, _, _) = model.inertial(&js);
        let lever = mul_mv(&imu.r, p_imu);
        let n_r: V3 = std::array::from_fn(|_| normal(noise.sigma_r));
        out.pose_t.push(t);
        out.pose_p.push(std::array::from_fn(|c| {
            imu.p[c] - lever[c] + normal(noise.sigma_p)
        }));
        out.pose_q
            .push(quat_from_matrix(&mul_mm(&imu.r, &exp_so3(n_r))));
    }
    out.imu_t = m.data.imu_t;
    out.imu_z = m.data.imu_z;
    let g_xy = one.offsets().g_xy;
    let mut truth = p_imu.to_vec();
    truth.extend_from_slice(&x0[g_xy..]);
    for j in 1..imus {
        // its own 28: p_imu, then τ and the sensor parameters (g is shared)
        let (xj, pj) = imu_truth(j)?;
        truth.extend(pj);
        truth.extend_from_slice(&xj[g_xy + 2..]);
    }
    let more = (m.data.extra_imus.into_iter())
        .map(|s| ImuSamples { t: s.t, z: s.z })
        .collect();
    Ok(FlangeSession {
        truth,
        data: out,
        more,
        sigma_z: m.opts.sigma_z,
    })
}

#[cfg(test)]
#[path = "pose_flange_tests.rs"]
mod tests;
