//! The IMU measurement of a pose session (MODEL.md §10): the 30 parameters
//! (names, units, priors) and the predicted z = [s̃; ω̃](t_i + τ) of an IMU
//! sample from a [`PoseSpline`], with exact Jacobians with respect to all
//! 30 parameters (τ included) and to the 4 + 4 control points at t_i + τ.
//!
//! The IMU frame has B's orientation and sits at p_I on B; ω and s are
//! those of the point p(t) + R(t)·p_I (§2 with W for the robot base), and
//! the sensor model is §3's (paper eq. (5), (6)).

use crate::geom::{mul_mtv, sub, M3, V3};
use crate::imu::{gravity, ImuError, ImuIntrinsics};
use crate::jet::{Jet, Scalar};
use crate::params::ParamSpec;
use crate::pose_trajectory::PoseSpline;
use crate::spline::SplineError;

/// Number of parameters of a one-IMU pose session (MODEL.md §10).
pub const POSE_PARAMS: usize = 30;
/// Index of `p_imu_x` (then y, z).
pub(crate) const P_IMU: usize = 0;
/// Index of `g_x` (then `g_y`).
pub const G_XY: usize = 3;
/// Index of `tau`.
pub const TAU: usize = 5;
/// Index of `gamma_a_yz` (the accelerometer block: γ_a, r_a, k_a, b_a).
pub const ACCEL: usize = 6;
/// Index of `gamma_w_yz` (the gyroscope block: γ_ω, r_ω, k_ω, b_ω).
pub const GYRO: usize = 18;
/// Offset of r (z, y, x) inside a sensor block.
pub const ROT: usize = 3;
/// Local control-point parameters at one time: 4 control points × (Δc, δ),
/// column 6j + c position, 6j + 3 + c rotation.
pub const CTRL: usize = 24;

/// Standard gravity g0 (m/s²), §2.
pub const G0: f64 = 9.81;

/// The 30 parameter names in §10's order.
pub fn pose_param_names() -> [String; POSE_PARAMS] {
    let mut v: Vec<String> = ["p_imu_x", "p_imu_y", "p_imu_z", "g_x", "g_y", "tau"]
        .iter()
        .map(|s| s.to_string())
        .collect();
    for s in ["a", "w"] {
        for (blk, sub) in [
            ("gamma", ["yz", "zy", "zx"]),
            ("r", ["z", "y", "x"]),
            ("k", ["x", "y", "z"]),
            ("b", ["x", "y", "z"]),
        ] {
            v.extend(sub.iter().map(|c| format!("{blk}_{s}_{c}")));
        }
    }
    v.try_into().expect("30 names")
}

/// Parameters of its own of IMU j ≥ 1 (all but the shared `g_x`, `g_y`;
/// MODEL.md §9, §10).
pub(crate) const IMU_OWN: usize = POSE_PARAMS - 2;

/// Number of parameters of a pose session with `n_imus` IMUs: IMU 0's 30,
/// then 28 per further IMU (2 + 28·K; MODEL.md §10).
pub fn n_pose_params(n_imus: usize) -> usize {
    POSE_PARAMS + IMU_OWN * n_imus.saturating_sub(1)
}

/// The indices in the K-IMU x of IMU `j`'s 30-vector (its p_I, the shared
/// g_x, g_y, its τ and sensor parameters, §10's order): 0..30 for IMU 0;
/// for j ≥ 1 its 28 at 30 + 28·(j − 1), with g at 3, 4.
pub fn imu_indices(j: usize) -> [usize; POSE_PARAMS] {
    let own = POSE_PARAMS + IMU_OWN * j.saturating_sub(1);
    std::array::from_fn(|k| match (j, k) {
        (0, _) => k,
        (_, k) if k < G_XY => own + k,
        (_, k) if k < TAU => k,
        (_, k) => own + k - 2,
    })
}

/// IMU `j`'s 30-vector of the K-IMU `x` ([`imu_indices`]).
pub fn imu_view(x: &[f64], j: usize) -> [f64; POSE_PARAMS] {
    imu_indices(j).map(|i| x[i])
}

/// The parameter specs (name, unit, prior mean, σ) of a pose session
/// (MODEL.md §10, §6): p_imu 0 ± 0.2 m, g_xy 0 ± 0.5 m/s², τ 0 ± 1 s, the §6
/// sensor priors, except the sensor rotations: prior means `r_a`, `r_w`
/// (found from the data) with a non-informative σ = π.
pub fn pose_param_specs(r_a: [f64; 3], r_w: [f64; 3]) -> Vec<ParamSpec> {
    let deg = std::f64::consts::PI / 180.0;
    let pi = std::f64::consts::PI;
    let mut spec = Vec::with_capacity(POSE_PARAMS);
    let mut push = |unit: &'static str, nominal: f64, sigma: f64| spec.push((unit, nominal, sigma));
    for _ in 0..3 {
        push("m", 0.0, 0.2);
    }
    push("m/s^2", 0.0, 0.5);
    push("m/s^2", 0.0, 0.5);
    push("s", 0.0, 1.0);
    for (r, g_sig, b_unit, b_sig) in [
        (r_a, 1.5 * deg, "m/s^2", 2.0),
        (r_w, 2.0 * deg, "rad/s", 5.0 * deg),
    ] {
        for _ in 0..3 {
            push("rad", 0.0, g_sig);
        }
        for v in r {
            push("rad", v, pi);
        }
        for _ in 0..3 {
            push("1", 1.0, 0.1);
        }
        for _ in 0..3 {
            push(b_unit, 0.0, b_sig);
        }
    }
    pose_param_names()
        .into_iter()
        .zip(spec)
        .map(|(name, (unit, nominal, sigma))| ParamSpec {
            name,
            unit,
            nominal,
            sigma,
        })
        .collect()
}

/// Why a pose-session prediction failed.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum PoseMeasurementError {
    /// t_i + τ outside the pose spline, or a bad spline.
    #[error(transparent)]
    Spline(#[from] SplineError),
    /// Gravity out of range.
    #[error(transparent)]
    Imu(#[from] ImuError),
    /// x does not have 30 entries.
    #[error("the pose-session parameter vector has {found} entries; expected 30")]
    Length {
        /// Given length.
        found: usize,
    },
}

/// The two sensors' intrinsics of x (§3), over any scalar.
pub fn intrinsics<S: Scalar>(x: &[S]) -> (ImuIntrinsics<S>, ImuIntrinsics<S>) {
    let blk = |o: usize| ImuIntrinsics {
        gamma: [x[o], x[o + 1], x[o + 2]],
        r: [x[o + 3], x[o + 4], x[o + 5]],
        k: [x[o + 6], x[o + 7], x[o + 8]],
        b: [x[o + 9], x[o + 10], x[o + 11]],
    };
    (blk(ACCEL), blk(GYRO))
}

fn check_len(x: &[f64]) -> Result<(), PoseMeasurementError> {
    if x.len() == POSE_PARAMS {
        Ok(())
    } else {
        Err(PoseMeasurementError::Length { found: x.len() })
    }
}

/// The predicted IMU sample z = [s̃; ω̃](t + τ) = [ax, ay, az, gx, gy, gz]
/// (§3, §4, §10) of the sample stamped `t`.
pub fn predict(spline: &PoseSpline, t: f64, x: &[f64]) -> Result<[f64; 6], PoseMeasurementError> {
    check_len(x)?;
    let imu = spline.imu_point(t + x[TAU], [x[P_IMU], x[P_IMU + 1], x[P_IMU + 2]])?;
    let g = gravity([x[G_XY], x[G_XY + 1]], G0)?;
    let s = mul_mtv(&imu.r, sub(imu.a_n, g));
    let (acc, gyr) = intrinsics(x);
    let (a, w) = (acc.apply(s), gyr.apply(imu.omega));
    Ok([a[0], a[1], a[2], w[0], w[1], w[2]])
}

/// A prediction and its Jacobians (`predict_jacobians`).
#[cfg(test)]
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct PosePrediction {
    /// Index of the first of the 4 control points at t + τ.
    pub first: usize,
    /// z.
    pub z: [f64; 6],
    /// ∂z/∂x (6 × 30).
    pub dx: [[f64; POSE_PARAMS]; 6],
    /// ∂z/∂(control points at t + τ) (6 × 24, [`CTRL`]'s columns; the
    /// rotation columns in the local perturbation R_k ← R_k·Exp(δ_k)).
    pub dc: [[f64; CTRL]; 6],
}

/// Jet variables of the kinematic part: p_I (0..3), g_xy (3..5), τ (5),
/// then the 24 control-point parameters (6..30).
#[cfg(test)]
type K30 = Jet<30>;
#[cfg(test)]
const KIN_CTRL: usize = 6;

/// Sensor output K Γ R v + b with its Jacobians: ∂/∂v (= KΓR) and ∂/∂(γ, r, k, b).
#[cfg(test)]
fn sensor_jac(sensor: &ImuIntrinsics<f64>, v: V3) -> (V3, M3, [[f64; 12]; 3]) {
    let p: [f64; 12] = [sensor.gamma, sensor.r, sensor.k, sensor.b]
        .concat()
        .try_into()
        .expect("12");
    let j: [Jet<12>; 12] = std::array::from_fn(|k| Jet::variable(p[k], k));
    let sj = ImuIntrinsics {
        gamma: [j[0], j[1], j[2]],
        r: [j[3], j[4], j[5]],
        k: [j[6], j[7], j[8]],
        b: [j[9], j[10], j[11]],
    };
    let out = sj.apply(v.map(Jet::cst));
    (out.map(|o| o.v), sensor.matrix(), out.map(|o| o.d))
}

/// [`predict`] and its exact Jacobians with respect to x (all 30, τ by
/// the basis's time derivatives, [`PoseSpline::kinematics_jet`]) and to
/// the control points at t + τ: the tests' 30-variable reference for
/// [`rows`].
#[cfg(test)]
pub(crate) fn predict_jacobians(
    spline: &PoseSpline,
    t: f64,
    x: &[f64],
) -> Result<PosePrediction, PoseMeasurementError> {
    check_len(x)?;
    let p_imu: V3<K30> = std::array::from_fn(|c| K30::variable(x[P_IMU + c], P_IMU + c));
    let g = gravity(
        [
            K30::variable(x[G_XY], G_XY),
            K30::variable(x[G_XY + 1], G_XY + 1),
        ],
        G0,
    )?;
    let imu = spline.imu_point_jet::<30>(t + x[TAU], p_imu, Some(TAU), Some(KIN_CTRL))?;
    let s = mul_mtv(&imu.r, sub(imu.a_n, g));
    let (acc, gyr) = intrinsics(x);
    let mut out = PosePrediction {
        first: imu.first,
        z: [0.0; 6],
        dx: [[0.0; POSE_PARAMS]; 6],
        dc: [[0.0; CTRL]; 6],
    };
    for (row0, sensor, v, blk) in [(0, &acc, s, ACCEL), (3, &gyr, imu.omega, GYRO)] {
        let (z, m, dp) = sensor_jac(sensor, v.map(|e| e.v));
        for r in 0..3 {
            out.z[row0 + r] = z[r];
            // chain through v: ∂z/∂kin = M ∂v/∂kin
            for k in 0..30 {
                let d = m[r][0] * v[0].d[k] + m[r][1] * v[1].d[k] + m[r][2] * v[2].d[k];
                if k < KIN_CTRL {
                    out.dx[row0 + r][k] = d;
                } else {
                    out.dc[row0 + r][k - KIN_CTRL] = d;
                }
            }
            out.dx[row0 + r][blk..blk + 12].copy_from_slice(&dp[r]);
        }
    }
    Ok(out)
}

pub mod inertial;
pub mod rows;
#[cfg(test)]
mod tests;
