//! The whitened-free Jacobian rows of an IMU sample of a pose session
//! (MODEL.md §10, §3 eq. (5), (6)) in compact columns: only the columns
//! that can be non-zero, for accumulating the normal equations without
//! touching zeros. Equal to `predict_jacobians` (a test compares
//! them), computed with 13-variable rotation jets
//! (the crate's 13-variable `rotation_jet` of [`PoseSpline`]) and the rest in closed form:
//!
//! * s = Rᵀ(p̈ − g) + α × p_I + ω × (ω × p_I) (body frame, Rᵀ(p̈ − g) from
//!   the same jets; §10's
//!   Rᵀ(a_n − g) with a_n = p̈ + α_n × R p_I + ω_n × (ω_n × R p_I));
//!   ∂s/∂c_j = N̈_j Rᵀ, ∂s/∂p_I = [α]× + [ω]×², ∂s/∂g = −Rᵀ ∂g/∂g_xy;
//! * z_a = M_a s + b_a, z_ω = M_ω ω + b_ω with M = K Γ R_s (eq. (6)), whose
//!   derivatives ∂M/∂(γ, r, k) are made once per x ([`RowContext`]).
//!
//! Accelerometer rows: [`ACCEL_COLS`] columns, the local columns
//! 0..42 of [`CTRL`] + x (the 24 control-point columns, then x's p_I, g_xy,
//! τ and the accelerometer block). Gyroscope rows: [`GYRO_COLS`] columns,
//! [`GYRO_LOCAL`]: the 12 rotation columns, τ and the gyroscope block.

use super::*;
use crate::geom::{add, cross, mul_mm, mul_mv};
use crate::pose_trajectory::so3::hat;
use crate::pose_trajectory::{rot_var, RotationSeeds, ORDER, ROT_TIME, ROT_VARS};

/// Columns of an accelerometer row.
pub const ACCEL_COLS: usize = CTRL + GYRO;
/// Columns of a gyroscope row.
pub const GYRO_COLS: usize = 12 + 1 + 12;

/// The local column (0..24 control points, 24 + k for x_k) of each
/// gyroscope-row column.
pub const GYRO_LOCAL: [usize; GYRO_COLS] = {
    let mut m = [0; GYRO_COLS];
    let mut j = 0;
    while j < 4 {
        let mut c = 0;
        while c < 3 {
            m[3 * j + c] = 6 * j + 3 + c;
            c += 1;
        }
        j += 1;
    }
    m[12] = CTRL + TAU;
    let mut k = 0;
    while k < 12 {
        m[13 + k] = CTRL + GYRO + k;
        k += 1;
    }
    m
};

/// One sensor's M = K Γ R_s and ∂M/∂(γ, r, k) (9 matrices).
#[derive(Clone, Copy, Debug)]
struct SensorLinear {
    m: M3,
    dm: [M3; 9],
    b: V3,
}

impl SensorLinear {
    fn new(s: &ImuIntrinsics<f64>) -> Self {
        let p: [f64; 9] = [s.gamma, s.r, s.k].concat().try_into().expect("9");
        let j: [Jet<9>; 9] = std::array::from_fn(|k| Jet::variable(p[k], k));
        let sj = ImuIntrinsics {
            gamma: [j[0], j[1], j[2]],
            r: [j[3], j[4], j[5]],
            k: [j[6], j[7], j[8]],
            b: [Jet::cst(0.0); 3],
        };
        let mj = sj.matrix();
        Self {
            m: mj.map(|row| row.map(|e| e.v)),
            dm: std::array::from_fn(|k| mj.map(|row| row.map(|e| e.d[k]))),
            b: s.b,
        }
    }

    /// Rows r of ∂(M v + b)/∂(γ, r, k, b) (12 columns).
    fn param_rows(&self, v: V3) -> [[f64; 12]; 3] {
        let mut out = [[0.0; 12]; 3];
        for k in 0..9 {
            let d = mul_mv(&self.dm[k], v);
            for r in 0..3 {
                out[r][k] = d[r];
            }
        }
        for r in 0..3 {
            out[r][9 + r] = 1.0;
        }
        out
    }
}

/// What the rows need from x, made once per x.
#[derive(Clone, Copy, Debug)]
pub struct RowContext {
    accel: SensorLinear,
    gyro: SensorLinear,
    p_imu: V3,
    tau: f64,
    g: V3,
    dg: [V3; 2],
}

impl RowContext {
    /// The context of x (30 entries; gravity in range).
    pub fn new(x: &[f64]) -> Result<Self, PoseMeasurementError> {
        check_len(x)?;
        let gj = gravity(
            [
                Jet::<2>::variable(x[G_XY], 0),
                Jet::<2>::variable(x[G_XY + 1], 1),
            ],
            G0,
        )?;
        let (acc, gyr) = intrinsics(x);
        Ok(Self {
            accel: SensorLinear::new(&acc),
            gyro: SensorLinear::new(&gyr),
            p_imu: [x[P_IMU], x[P_IMU + 1], x[P_IMU + 2]],
            tau: x[TAU],
            g: gj.map(|e| e.v),
            dg: std::array::from_fn(|k| gj.map(|e| e.d[k])),
        })
    }
}

/// What consecutive samples of one segment share (the rotation seeds,
/// made once per segment); start with `Default`.
#[derive(Clone, Debug, Default)]
pub struct SegmentCache {
    seeds: Option<RotationSeeds>,
}

/// A sample's prediction and its Jacobian rows in compact columns (module doc).
#[derive(Clone, Copy, Debug)]
pub struct PoseRows {
    /// Index of the first of the 4 control points at t + τ.
    pub first: usize,
    /// z = [ax, ay, az, gx, gy, gz].
    pub z: [f64; 6],
    /// ∂z_a/∂(local columns 0..42).
    pub accel: [[f64; ACCEL_COLS]; 3],
    /// ∂z_ω/∂([`GYRO_LOCAL`]).
    pub gyro: [[f64; GYRO_COLS]; 3],
}

/// `M · v` for jet vectors and a constant M.
fn mul_cj(m: &M3, v: &V3<Jet<ROT_VARS>>) -> V3<Jet<ROT_VARS>> {
    std::array::from_fn(|r| v[0] * m[r][0] + v[1] * m[r][1] + v[2] * m[r][2])
}

/// The prediction of the sample stamped `t` and its rows (module doc);
/// `cache` is reused across the samples of a segment.
pub fn prediction_rows(
    spline: &PoseSpline,
    t: f64,
    ctx: &RowContext,
    cache: &mut SegmentCache,
) -> Result<PoseRows, PoseMeasurementError> {
    let k = spline.rotation_jet(t + ctx.tau, ctx.g, &mut cache.seeds)?;
    let pi = ctx.p_imu.map(Jet::cst);
    let s = add(
        add(k.f, cross(k.alpha, pi)),
        cross(k.omega, cross(k.omega, pi)),
    );
    let rv = k.r;
    let (w, al) = (k.omega.map(|e| e.v), k.alpha.map(|e| e.v));
    let wx = hat(w);
    let mut ds_dp = mul_mm(&wx, &wx);
    let ax = hat(al);
    for r in 0..3 {
        for c in 0..3 {
            ds_dp[r][c] += ax[r][c];
        }
    }
    let (ma, mg) = (&ctx.accel.m, &ctx.gyro.m);
    let ma_rt = mul_mm(ma, &crate::geom::transpose(&rv));
    let ma_dp = mul_mm(ma, &ds_dp);
    let ma_dg = ctx.dg.map(|d| mul_mv(&ma_rt, d));
    let za = mul_cj(ma, &s);
    let zg = mul_cj(mg, &k.omega);
    let sv = s.map(|e| e.v);
    let (pa, pg) = (ctx.accel.param_rows(sv), ctx.gyro.param_rows(w));
    let mut out = PoseRows {
        first: k.first,
        z: [0.0; 6],
        accel: [[0.0; ACCEL_COLS]; 3],
        gyro: [[0.0; GYRO_COLS]; 3],
    };
    for r in 0..3 {
        out.z[r] = za[r].v + ctx.accel.b[r];
        out.z[3 + r] = zg[r].v + ctx.gyro.b[r];
        let (a, g) = (&mut out.accel[r], &mut out.gyro[r]);
        for j in 0..ORDER {
            for c in 0..3 {
                a[6 * j + c] = ma_rt[r][c] * k.ddn[j];
                a[6 * j + 3 + c] = za[r].d[rot_var(j, c)];
                g[3 * j + c] = zg[r].d[rot_var(j, c)];
            }
        }
        for c in 0..3 {
            a[CTRL + P_IMU + c] = ma_dp[r][c];
        }
        a[CTRL + G_XY] = -ma_dg[0][r];
        a[CTRL + G_XY + 1] = -ma_dg[1][r];
        a[CTRL + TAU] = za[r].d[ROT_TIME];
        a[CTRL + ACCEL..].copy_from_slice(&pa[r]);
        g[12] = zg[r].d[ROT_TIME];
        g[13..].copy_from_slice(&pg[r]);
    }
    Ok(out)
}
