//! Robot and IMU accuracy against an external tracker (paper §9, Fig. 10–11).
//!
//! **Robot accuracy.** The tracker measures the pose M_k of a marker body on
//! the flange at static joint configurations q_k. With the flange pose
//! F(q; ε) (eq. (3) without the IMU mount) the model predicts
//!
//! ```text
//! M_k ≈ T_tb · F(q_k; ε) · T_fm
//! ```
//!
//! T_tb (robot base in the tracker frame) and T_fm (marker body in the flange
//! frame) are solved on the training poses for each parameter set
//! ([`register`]); the held-out poses give the position error ‖p_meas − p_pred‖
//! and the rotation error, the angle of R_measᵀ R_pred.
//!
//! **IMU accuracy.** Splines of degree 5 (one interior knot per 30 samples)
//! fitted to the IMU pose computed from a tracked motion give the ground-truth
//! angular rate and specific force (eq. (5), with the calibration's τ and g);
//! the IMU output corrected by the inverse of eq. (6) with nominal, calibrated
//! and standard-calibration intrinsics is compared against them.

use crate::baseline::{self, ImuBaseline, RobotBaseline};
use crate::tracker::{
    flange_eps, flange_pose, pose_from_row, register, Registration, TrackedPose, ValidateError,
};
use robimu_model::geom::{log_so3, matrix_from_quat, quat_from_matrix, quat_mul};

fn input(m: impl Into<String>) -> ValidateError {
    ValidateError::Input(m.into())
}
use robimu_model::geom::{self, dot, mul_mm, scale, sub, Iso, V3};
use robimu_model::imu::{self, ImuIntrinsics};
use robimu_model::{JointState, Knots, ParamLayout, Robot, Spline};
use robimu_session::Table;

/// Position and rotation errors of predicted against measured poses.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct PoseErrors {
    /// ‖p_meas − p_pred‖ per pose, m.
    pub position: Vec<f64>,
    /// Angle of R_measᵀ R_pred per pose, rad.
    pub rotation: Vec<f64>,
}

fn mean(v: &[f64]) -> f64 {
    v.iter().sum::<f64>() / v.len().max(1) as f64
}

fn rms(v: &[f64]) -> f64 {
    (v.iter().map(|x| x * x).sum::<f64>() / v.len().max(1) as f64).sqrt()
}

fn max(v: &[f64]) -> f64 {
    v.iter().copied().fold(0.0, f64::max)
}

impl PoseErrors {
    /// Errors of `reg`'s predictions from `flanges` against `markers`.
    pub fn new(reg: &Registration, flanges: &[Iso], markers: &[Iso]) -> Self {
        let mut e = Self::default();
        for (f, m) in flanges.iter().zip(markers) {
            let pred = reg.predict(f);
            let dp = sub(m.p, pred.p);
            e.position.push(dot(dp, dp).sqrt());
            let dr = log_so3(&mul_mm(&geom::transpose(&m.r), &pred.r));
            e.rotation.push(dot(dr, dr).sqrt());
        }
        e
    }
    /// Mean position error, m.
    pub fn mean_position(&self) -> f64 {
        mean(&self.position)
    }
    /// Mean rotation error, rad.
    pub fn mean_rotation(&self) -> f64 {
        mean(&self.rotation)
    }
    /// Largest position error, m.
    pub fn max_position(&self) -> f64 {
        max(&self.position)
    }
    /// Largest rotation error, rad.
    pub fn max_rotation(&self) -> f64 {
        max(&self.rotation)
    }
}

/// Robot accuracy on held-out poses (paper Fig. 10).
#[derive(Debug, Clone)]
pub struct RobotAccuracy {
    /// Poses used to solve the transforms (and the standard calibration).
    pub train: usize,
    /// Held-out poses the errors are computed on.
    pub test: usize,
    /// With the nominal parameters.
    pub nominal: PoseErrors,
    /// With the calibrated parameters.
    pub calibrated: PoseErrors,
    /// With the standard (tracker) calibration.
    pub classical: PoseErrors,
    /// The standard calibration itself.
    pub baseline: RobotBaseline,
    /// T_tb, T_fm solved with the calibrated parameters.
    pub registration: Registration,
}

/// Robot accuracy: the first `train` poses fit the transforms (for each
/// parameter set) and the standard calibration (with the generalized errors
/// in `frozen` held at nominal), the others are held out.
pub fn robot_accuracy(
    robot: &Robot,
    layout: &ParamLayout,
    x_calibrated: &[f64],
    poses: &[TrackedPose],
    train: usize,
    frozen: &[usize],
) -> Result<RobotAccuracy, ValidateError> {
    let n = robot.dof();
    if let Some((k, p)) = poses.iter().enumerate().find(|(_, p)| p.q.len() != n) {
        return Err(input(format!(
            "pose {} has {} joint angles but robot `{}` has {n} joints",
            k + 1,
            p.q.len(),
            robot.name()
        )));
    }
    if train < 3 || train >= poses.len() {
        return Err(input(format!(
            "{} poses: need at least 3 to fit and 1 to hold out (training with {train})",
            poses.len()
        )));
    }
    let (fit, held) = poses.split_at(train);
    let markers_fit: Vec<Iso> = fit.iter().map(|p| p.marker).collect();
    let markers_held: Vec<Iso> = held.iter().map(|p| p.marker).collect();
    let errors_with = |eps: &[[f64; 6]]| -> Result<(PoseErrors, Registration), ValidateError> {
        let f_fit: Vec<Iso> = fit.iter().map(|p| flange_pose(robot, eps, &p.q)).collect();
        let reg = register(&f_fit, &markers_fit)?;
        let f_held: Vec<Iso> = held.iter().map(|p| flange_pose(robot, eps, &p.q)).collect();
        Ok((PoseErrors::new(&reg, &f_held, &markers_held), reg))
    };
    let (nominal, _) = errors_with(&flange_eps(layout, &layout.nominal())?)?;
    let (calibrated, registration) = errors_with(&flange_eps(layout, x_calibrated)?)?;
    let baseline = baseline::robot_calibration(robot, layout, fit, frozen)?;
    let f_held: Vec<Iso> = held
        .iter()
        .map(|p| flange_pose(robot, &baseline.eps, &p.q))
        .collect();
    let classical = PoseErrors::new(&baseline.registration, &f_held, &markers_held);
    Ok(RobotAccuracy {
        train,
        test: held.len(),
        nominal,
        calibrated,
        classical,
        baseline,
        registration,
    })
}

// ---------------------------------------------------------------- IMU

/// Ground truth from a tracked motion: the IMU pose in the base frame fitted
/// by degree-5 splines, evaluated at IMU sample times.
pub struct ImuGroundTruth {
    position: Spline,
    attitude: Spline,
    g: V3,
}

impl ImuGroundTruth {
    /// Fit the IMU pose (from the marker poses of `tracker` through `reg` and
    /// the IMU position `p_imu` in the flange frame), one interior knot per
    /// `samples_per_knot` tracker samples; `g` is gravity in the base frame.
    pub fn fit(
        tracker: &Table,
        reg: &Registration,
        p_imu: V3,
        g: V3,
        samples_per_knot: usize,
    ) -> Result<Self, ValidateError> {
        let m = tracker.len();
        if tracker.width() != 7 {
            return Err(input(format!(
                "a tracker table has 7 value columns (px, py, pz, qw, qx, qy, qz), not {}",
                tracker.width()
            )));
        }
        let (t0, t1) = tracker.span().unwrap_or_default();
        if m < 6 * samples_per_knot.max(1) || t1 <= t0 {
            return Err(input(format!(
                "the tracked motion has {m} samples: too few for the ground-truth splines"
            )));
        }
        let mut pos = Vec::with_capacity(3 * m);
        let mut att = Vec::with_capacity(4 * m);
        let mut prev = [1.0, 0.0, 0.0, 0.0];
        for i in 0..m {
            let marker = pose_from_row(tracker.row(i)).map_err(|e| {
                input(format!(
                    "tracker sample {} (t = {} s): {e}",
                    i + 1,
                    tracker.t[i]
                ))
            })?;
            let imu = reg.imu_in_base(&marker, p_imu);
            pos.extend(imu.p);
            let mut q = quat_from_matrix(&imu.r);
            if q.iter().zip(&prev).map(|(a, b)| a * b).sum::<f64>() < 0.0 {
                q = q.map(|v| -v);
            }
            prev = q;
            att.extend(q);
        }
        let spacing = samples_per_knot as f64 * (t1 - t0) / (m - 1) as f64;
        let knots = Knots::uniform(t0, t1, spacing, 5).map_err(|e| input(e.to_string()))?;
        let fit = |dim: usize, v: &[f64]| {
            Spline::fit(knots.clone(), dim, &tracker.t, v)
                .map_err(|e| input(format!("cannot fit the tracked motion: {e}")))
        };
        Ok(Self {
            position: fit(3, &pos)?,
            attitude: fit(4, &att)?,
            g,
        })
    }

    /// The span where the fit is trusted (one knot span in from each end).
    pub fn span(&self) -> (f64, f64) {
        let k = self.position.knots();
        let margin = (k.end() - k.start()) / (k.num_coeffs() - k.degree()).max(1) as f64;
        (k.start() + margin, k.end() - margin)
    }

    /// `(ω, s)` in the IMU frame at robot time t (eq. (5)), or `None` outside [`Self::span`].
    pub fn at(&self, t: f64) -> Option<(V3, V3)> {
        let (a, b) = self.span();
        if !(t >= a && t <= b) {
            return None;
        }
        let (mut p, mut q) = (JointState::default(), JointState::default());
        self.position.evaluate(t, &mut p).ok()?;
        self.attitude.evaluate(t, &mut q).ok()?;
        let qv = [q.q[0], q.q[1], q.q[2], q.q[3]];
        let qd = [q.qd[0], q.qd[1], q.qd[2], q.qd[3]];
        let n2: f64 = qv.iter().map(|v| v * v).sum();
        // ω_n = 2 vec(q̇ ⊗ q*) / |q|² (exact for a non-unit q too)
        let d = quat_mul(qd, [qv[0], -qv[1], -qv[2], -qv[3]]);
        let omega_n = scale([d[1], d[2], d[3]], 2.0 / n2);
        let r = matrix_from_quat(qv);
        let a_n = [p.qdd[0], p.qdd[1], p.qdd[2]];
        Some(imu::inertial(&r, omega_n, a_n, self.g))
    }
}

/// Norms of the corrected-output errors against the ground truth.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ImuErrors {
    /// ‖ω_corrected − ω_true‖ per sample, rad/s.
    pub gyro: Vec<f64>,
    /// ‖s_corrected − s_true‖ per sample, m/s².
    pub accel: Vec<f64>,
}

impl ImuErrors {
    /// RMS angular-rate error, rad/s.
    pub fn rms_gyro(&self) -> f64 {
        rms(&self.gyro)
    }
    /// RMS specific-force error, m/s².
    pub fn rms_accel(&self) -> f64 {
        rms(&self.accel)
    }
}

/// IMU accuracy on the held-out half of a tracked motion (paper Fig. 11).
#[derive(Debug, Clone)]
pub struct ImuAccuracy {
    /// IMU samples that fit the standard calibration.
    pub train: usize,
    /// IMU samples the errors are computed on.
    pub test: usize,
    /// Corrected with the nominal intrinsics.
    pub nominal: ImuErrors,
    /// Corrected with the calibrated intrinsics.
    pub calibrated: ImuErrors,
    /// Corrected with the standard IMU calibration.
    pub classical: ImuErrors,
    /// The standard IMU calibration.
    pub baseline: ImuBaseline,
}

/// Corrects a raw IMU output `[ax, ay, az, gx, gy, gz]` into `(ω, s)`.
type Corrector<'a> = &'a dyn Fn(&[f64; 6]) -> Option<(V3, V3)>;

/// IMU accuracy from a tracked motion with IMU samples (`imu_t`, `imu_z`):
/// ground truth from `truth` at t_i + τ (the calibration's τ); the first half
/// of the samples fits the standard calibration, the second half is held out.
pub fn imu_accuracy(
    layout: &ParamLayout,
    x_nominal: &[f64],
    x_calibrated: &[f64],
    truth: &ImuGroundTruth,
    imu_t: &[f64],
    imu_z: &[[f64; 6]],
) -> Result<ImuAccuracy, ValidateError> {
    let tau = x_calibrated[layout.offsets().tau];
    let mut gt = Vec::new();
    let mut raw = Vec::new();
    for (t, z) in imu_t.iter().zip(imu_z) {
        if let Some(v) = truth.at(t + tau) {
            gt.push(v);
            raw.push(*z);
        }
    }
    if gt.len() < 20 {
        return Err(input(format!(
            "only {} IMU samples fall inside the tracked motion (after the time offset tau = {tau} s)",
            gt.len()
        )));
    }
    let half = gt.len() / 2;
    let baseline = baseline::imu_calibration(&gt[..half], &raw[..half])?;
    let intrinsics = |x: &[f64]| -> Result<(ImuIntrinsics, ImuIntrinsics), ValidateError> {
        let p = layout.unpack(x).map_err(|e| input(e.to_string()))?;
        Ok((p.accel, p.gyro))
    };
    let errors = |correct: Corrector<'_>| -> Result<ImuErrors, ValidateError> {
        let mut e = ImuErrors::default();
        for (z, (w, s)) in raw[half..].iter().zip(&gt[half..]) {
            let (wc, sc) = correct(z).ok_or_else(|| input("a sensor model is not invertible"))?;
            let (dw, ds) = (sub(wc, *w), sub(sc, *s));
            e.gyro.push(dot(dw, dw).sqrt());
            e.accel.push(dot(ds, ds).sqrt());
        }
        Ok(e)
    };
    let (an, gn) = intrinsics(x_nominal)?;
    let (ac, gc) = intrinsics(x_calibrated)?;
    let nominal = errors(&|z| imu::correct(&an, &gn, *z).ok())?;
    let calibrated = errors(&|z| imu::correct(&ac, &gc, *z).ok())?;
    let classical = errors(&|z| {
        Some((
            baseline.gyro.correct([z[3], z[4], z[5]])?,
            baseline.accel.correct([z[0], z[1], z[2]])?,
        ))
    })?;
    Ok(ImuAccuracy {
        train: half,
        test: gt.len() - half,
        nominal,
        calibrated,
        classical,
        baseline,
    })
}

/// The IMU position (ε_n1..3) and gravity of a parameter vector.
pub fn imu_position_and_gravity(
    robot: &Robot,
    layout: &ParamLayout,
    x: &[f64],
) -> Result<(V3, V3), ValidateError> {
    let p = layout.unpack(x).map_err(|e| input(e.to_string()))?;
    let last = p.eps.last().copied().unwrap_or([0.0; 6]);
    let g = imu::gravity(p.g_xy, robot.gravity()).map_err(|e| input(e.to_string()))?;
    Ok(([last[0], last[1], last[2]], g))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tracker::tracked_poses;
    use robimu_model::geom::exp_so3;

    fn pose(w: V3, p: V3) -> Iso {
        Iso { r: exp_so3(w), p }
    }

    #[test]
    fn poses_take_joint_angles_from_columns_or_interpolated_samples() {
        let row = |p: [f64; 7]| p.to_vec();
        let tracker = Table {
            columns: robimu_session::TRACKER_COLUMNS.map(String::from).to_vec(),
            t: vec![0.5, 3.0],
            values: [row([0.1, 0.2, 0.3, 1.0, 0.0, 0.0, 0.0]), row([0.0; 7])].concat(),
        };
        let joints = Table {
            columns: vec!["q1".into(), "q2".into()],
            t: vec![0.0, 1.0],
            values: vec![0.0, 1.0, 2.0, 3.0],
        };
        let one = Table {
            t: vec![0.5],
            values: tracker.values[..7].to_vec(),
            ..tracker.clone()
        };
        let p = tracked_poses(&one, None, Some(&joints), 2).unwrap();
        assert_eq!(p[0].q, vec![1.0, 2.0]);
        assert_eq!(p[0].marker.p, [0.1, 0.2, 0.3]);
        let p = tracked_poses(&one, Some(&[7.0, 8.0]), Some(&joints), 2).unwrap();
        assert_eq!(p[0].q, vec![7.0, 8.0]);
        // the second pose: a zero quaternion, and outside the joints' span
        let e = tracked_poses(&tracker, Some(&[0.0; 4]), None, 2).unwrap_err();
        assert!(
            e.to_string().contains("pose 2") && e.to_string().contains("unit quaternion"),
            "{e}"
        );
        let mut late = one.clone();
        late.t = vec![3.0];
        let e = tracked_poses(&late, None, Some(&joints), 2).unwrap_err();
        assert!(e.to_string().contains("outside the joint samples"), "{e}");
    }

    #[test]
    fn register_recovers_both_transforms_from_exact_poses() {
        let x = pose([0.3, -1.2, 2.0], [1.5, -0.4, 0.8]);
        let y = pose([-0.2, 0.4, 0.1], [0.03, -0.05, 0.07]);
        let flanges: Vec<Iso> = (0..12)
            .map(|k| {
                let k = k as f64;
                pose(
                    [(0.7 * k).sin(), (1.1 * k).cos(), 0.5 * (0.3 * k).sin()],
                    [0.3 * k.cos(), 0.4 * k.sin(), 0.5 + 0.1 * k.sin()],
                )
            })
            .collect();
        let markers: Vec<Iso> = flanges.iter().map(|f| x.compose(f).compose(&y)).collect();
        let reg = register(&flanges, &markers).unwrap();
        for (a, b) in [(reg.tracker_base, x), (reg.flange_marker, y)] {
            for i in 0..3 {
                assert!((a.p[i] - b.p[i]).abs() < 1e-9, "{a:?} vs {b:?}");
                for j in 0..3 {
                    assert!((a.r[i][j] - b.r[i][j]).abs() < 1e-9);
                }
            }
        }
        let e = PoseErrors::new(&reg, &flanges, &markers);
        assert!(e.max_position() < 1e-9 && e.max_rotation() < 1e-9);
    }
}
