//! The classical calibrations the paper compares with (§9): a standard robot
//! calibration from tracker poses and a standard IMU calibration from a
//! tracked trajectory. They need an external tracker, which the unified
//! method does not; they are here so that users can compare methods on
//! their own data.
//!
//! * [`robot_calibration`] — least squares on the same generalized errors
//!   ε (docs/model.md §1) and the two constant transforms T_tracker←base and
//!   T_flange←marker, from the pose residuals
//!
//! ```text
//! r_k = [ (p_meas − p_pred) / σ_p ;  log(R_measᵀ R_pred) / σ_R ],
//! [R_pred p_pred] = T_tb · F(q_k; ε) · T_fm
//! ```
//!
//! * [`imu_calibration`] — per sensor a general linear model `z = M v + b`
//!   (equivalent to K Γ R of eq. (6): any 3×3 matrix factors so), fitted by
//!   linear least squares to the tracker's ground-truth ω and s.

use crate::tracker::{
    flange_pose, pose_residual, register, Registration, TrackedPose, ValidateError,
};
use faer::linalg::solvers::Solve;
use faer::{Mat, Side};
use robimu_model::geom::inverse3;
use robimu_model::geom::{mul_mv, sub, M3, V3};
use robimu_model::{ParamLayout, Robot};
use robimu_solver::{dense, LmOptions};

pub(crate) use crate::tracker::TRACKER_SIGMA;

/// The outcome of the standard robot calibration.
#[derive(Debug, Clone)]
pub struct RobotBaseline {
    /// Generalized errors ε of links 1..n (the last row, redundant with the
    /// marker transform, is zero).
    pub eps: Vec<[f64; 6]>,
    /// The constant transforms.
    pub registration: Registration,
    /// Estimated errors: (index into x, name, value).
    pub estimated: Vec<(usize, String, f64)>,
    /// RMS of the weighted pose residuals at the optimum (1 ≈ tracker noise).
    pub residual_rms: f64,
}

/// Standard robot calibration (paper §9, ref. \[38\]) from tracked static
/// poses: the generalized errors of `layout`'s estimated set on links
/// 1..n−1 (those of link n are redundant with T_flange←marker), except the
/// indices in `frozen`, plus both constant transforms.
pub(crate) fn robot_calibration(
    robot: &Robot,
    layout: &ParamLayout,
    poses: &[TrackedPose],
    frozen: &[usize],
) -> Result<RobotBaseline, ValidateError> {
    let n = robot.dof();
    let nominal = layout.nominal();
    let mut eps0 = layout
        .unpack(&nominal)
        .map_err(|e| ValidateError::Input(e.to_string()))?
        .eps;
    eps0[n - 1] = [0.0; 6];
    let active: Vec<(usize, usize, usize)> = layout
        .estimated_errors()
        .iter()
        .filter(|e| e.link < n)
        .filter_map(|e| {
            let ix = layout.eps_index(e.link, e.k)?;
            (!frozen.contains(&ix)).then_some((ix, e.link - 1, e.k - 1))
        })
        .collect();
    let flanges0: Vec<_> = poses
        .iter()
        .map(|p| flange_pose(robot, &eps0, &p.q))
        .collect();
    let markers: Vec<_> = poses.iter().map(|p| p.marker).collect();
    let reg0 = register(&flanges0, &markers)?;
    let (sp, sr) = TRACKER_SIGMA;
    let residuals = |theta: &[f64]| -> Vec<f64> {
        let reg = reg0.perturbed(&theta[..12]);
        let mut eps = eps0.clone();
        for (k, &(_, l, c)) in active.iter().enumerate() {
            eps[l][c] = theta[12 + k];
        }
        let mut out = Vec::with_capacity(6 * poses.len());
        for p in poses {
            let pred = reg.predict(&flange_pose(robot, &eps, &p.q));
            out.extend(pose_residual(&p.marker, &pred, sp, sr));
        }
        out
    };
    let sol = dense::solve(
        residuals,
        vec![0.0; 12 + active.len()],
        &LmOptions::default(),
    )
    .map_err(|e| {
        ValidateError::Input(format!(
            "the tracked poses do not determine the robot calibration: {e}"
        ))
    })?;
    let (theta, cost) = (sol.theta, 2.0 * sol.summary.final_cost);
    let mut eps = eps0;
    let mut estimated = Vec::with_capacity(active.len());
    for (k, &(ix, l, c)) in active.iter().enumerate() {
        eps[l][c] = theta[12 + k];
        estimated.push((ix, layout.specs()[ix].name.clone(), theta[12 + k]));
    }
    Ok(RobotBaseline {
        eps,
        registration: reg0.perturbed(&theta[..12]),
        estimated,
        residual_rms: (cost / (6 * poses.len()).max(1) as f64).sqrt(),
    })
}

/// One sensor's general linear model `z = M v + b`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LinearSensor {
    /// M (sensor axes × IMU frame).
    pub m: M3,
    /// b.
    pub b: V3,
}

impl LinearSensor {
    /// The physical vector from a raw output: M⁻¹ (z − b); `None` when M is singular.
    pub fn correct(&self, z: V3) -> Option<V3> {
        let inv = inverse3(&self.m)?;
        Some(mul_mv(&inv, sub(z, self.b)))
    }
}

/// The standard IMU calibration: both sensors' linear models.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ImuBaseline {
    /// Accelerometer.
    pub accel: LinearSensor,
    /// Gyroscope.
    pub gyro: LinearSensor,
}

/// Standard IMU calibration (paper §9, ref. \[7\]) from ground-truth
/// `(ω, s)` (IMU frame) and the raw outputs `[ax, ay, az, gx, gy, gz]` at the
/// same instants: each sensor's `M`, `b` by linear least squares.
pub(crate) fn imu_calibration(
    truth: &[(V3, V3)],
    raw: &[[f64; 6]],
) -> Result<ImuBaseline, ValidateError> {
    if truth.len() != raw.len() || truth.len() < 8 {
        return Err(ValidateError::Input(format!(
            "the IMU calibration needs at least 8 samples with ground truth (got {})",
            truth.len().min(raw.len())
        )));
    }
    let fit = |pick: &dyn Fn(usize) -> (V3, V3)| -> Result<LinearSensor, ValidateError> {
        // Per output axis: z_a = m_a · v + b_a, regressors [v, 1]; the
        // normal equations of the three axes share AᵀA (one Cholesky).
        let mut ata = Mat::<f64>::zeros(4, 4);
        let mut atz = Mat::<f64>::zeros(4, 3);
        for i in 0..truth.len() {
            let (v, z) = pick(i);
            let reg = [v[0], v[1], v[2], 1.0];
            for a in 0..4 {
                for b in 0..4 {
                    ata[(a, b)] += reg[a] * reg[b];
                }
                for ax in 0..3 {
                    atz[(a, ax)] += reg[a] * z[ax];
                }
            }
        }
        let sol = ata
            .llt(Side::Lower)
            .map_err(|_| {
                ValidateError::Input(
                    "the tracked motion does not excite every axis: the IMU calibration is singular"
                        .into(),
                )
            })?
            .solve(atz);
        Ok(LinearSensor {
            m: std::array::from_fn(|ax| [sol[(0, ax)], sol[(1, ax)], sol[(2, ax)]]),
            b: std::array::from_fn(|ax| sol[(3, ax)]),
        })
    };
    let accel = fit(&|i| (truth[i].1, [raw[i][0], raw[i][1], raw[i][2]]))?;
    let gyro = fit(&|i| (truth[i].0, [raw[i][3], raw[i][4], raw[i][5]]))?;
    Ok(ImuBaseline { accel, gyro })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn inverse3_inverts() {
        let m = [[2.0, 0.3, -0.1], [0.2, 1.5, 0.4], [-0.3, 0.1, 0.9]];
        let inv = inverse3(&m).unwrap();
        for i in 0..3 {
            for j in 0..3 {
                let v: f64 = (0..3).map(|k| m[i][k] * inv[k][j]).sum();
                assert!((v - if i == j { 1.0 } else { 0.0 }).abs() < 1e-12);
            }
        }
        assert!(inverse3(&[[1.0, 2.0, 3.0], [2.0, 4.0, 6.0], [0.0, 0.0, 1.0]]).is_none());
    }

    #[test]
    fn imu_calibration_recovers_a_linear_sensor() {
        let m_a = [[1.02, 0.01, -0.02], [0.0, 0.97, 0.03], [0.01, -0.01, 1.05]];
        let b_a = [0.1, -0.2, 0.3];
        let m_w = [[0.0, -1.01, 0.0], [1.0, 0.0, 0.02], [0.0, 0.01, 0.99]];
        let b_w = [0.01, 0.02, -0.03];
        let mut truth = Vec::new();
        let mut raw = Vec::new();
        for k in 0..50 {
            let t = k as f64 * 0.37;
            let w = [t.sin(), (1.3 * t).cos(), (0.7 * t).sin() + 0.2];
            let s = [2.0 * t.cos(), 9.0 * (0.3 * t).sin(), 9.8 * (0.5 * t).cos()];
            let za = robimu_model::geom::add(mul_mv(&m_a, s), b_a);
            let zw = robimu_model::geom::add(mul_mv(&m_w, w), b_w);
            truth.push((w, s));
            raw.push([za[0], za[1], za[2], zw[0], zw[1], zw[2]]);
        }
        let cal = imu_calibration(&truth, &raw).unwrap();
        for i in 0..3 {
            assert!((cal.accel.b[i] - b_a[i]).abs() < 1e-9);
            assert!((cal.gyro.b[i] - b_w[i]).abs() < 1e-9);
            for j in 0..3 {
                assert!((cal.accel.m[i][j] - m_a[i][j]).abs() < 1e-9);
                assert!((cal.gyro.m[i][j] - m_w[i][j]).abs() < 1e-9);
            }
        }
        let back = cal
            .accel
            .correct([raw[3][0], raw[3][1], raw[3][2]])
            .unwrap();
        for i in 0..3 {
            assert!((back[i] - truth[3].1[i]).abs() < 1e-9);
        }
    }
}
