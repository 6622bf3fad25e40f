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

use std::path::PathBuf;

use rand::SeedableRng;
use rand_distr::{Distribution, StandardNormal};
use robimu_model::geom::{exp_so3, mul_mm, mul_mv, quat_from_matrix, V3};
use robimu_model::{JointState, MeasurementModel, PoseMeasurements, Robot};

use super::simulate::{simulate_motion, SessionSpec};
use crate::pose_calibrate::PoseNoise;

/// A simulated flange pose session.
pub(crate) struct FlangeSession {
    /// The 30 pose parameters (module doc).
    pub truth: Vec<f64>,
    /// Poses of the flange and the IMU samples.
    pub data: PoseMeasurements,
    /// The IMU noise σ the samples have (the robot's).
    pub sigma_z: [f64; 6],
}

/// The flange of `robot` on the motion of `robimu simulate --robot` with
/// `seed`, `duration` and IMU rate `imu_rate`; poses at `pose_rate` Hz with
/// times jittered by N(0, `pose_jitter`²) (stamped exactly), noise σ_p, σ_r
/// of `noise`.
pub(crate) fn flange_session(
    robot: Robot,
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
        ..SessionSpec::plain(robot, duration, imu_rate, seed, PathBuf::new())
    };
    let m = simulate_motion(&spec)?;
    let robot = &spec.robot;
    let params = m.layout.unpack(&m.x_true)?;
    let p_imu: V3 = std::array::from_fn(|c| params.eps[robot.dof() - 1][c]);
    let model = MeasurementModel::new(robot, &m.layout, &m.x_true)?;
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
    let mut truth = p_imu.to_vec();
    truth.extend_from_slice(&m.x_true[m.layout.offsets().g_xy..]);
    Ok(FlangeSession {
        truth,
        data: out,
        sigma_z: m.opts.sigma_z,
    })
}

#[cfg(test)]
#[path = "pose_flange_tests.rs"]
mod tests;
