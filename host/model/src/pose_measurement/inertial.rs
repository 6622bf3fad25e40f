//! The IMU's own quantities at a sample of a pose session (MODEL.md §10,
//! docs/model.md §7.9): t_i, ω, ω̇ and s in the IMU frame at t_i + τ, dz/dt
//! and M_a, for the catalogue's IMU-side effects ([`ImuContext`]).
//!
//! ω, ω̇ = α are the body's (the IMU frame has B's orientation); s =
//! Rᵀ(p̈ − g) + α × p_I + ω × (ω × p_I), the specific force at p_I (the
//! module doc of [`super::rows`]). dz/dt is ∂z/∂τ, given by the caller from
//! the sample's Jacobian rows ([`super::rows::PoseRows`]) or by
//! [`PoseImuSample::at`] from them.

use std::cell::OnceCell;

use super::rows::{prediction_rows, RowContext, SegmentCache, GYRO_LOCAL};
use super::{intrinsics, PoseMeasurementError, CTRL, G0, G_XY, P_IMU, TAU};
use crate::effects::{ImuContext, Inertial};
use crate::geom::{add, cross, mul_mtv, sub, M3, V3};
use crate::imu::gravity;
use crate::pose_trajectory::PoseSpline;

/// The IMU-side context of one pose-session sample (module doc); ω, ω̇
/// and s are evaluated on first use.
pub struct PoseImuSample<'a> {
    spline: &'a PoseSpline,
    t: f64,
    x: &'a [f64],
    dz_dt: [f64; 6],
    accel: M3,
    inertial: OnceCell<Inertial>,
}

impl<'a> PoseImuSample<'a> {
    /// The sample stamped `t` at x (30 entries) on `spline`, with its
    /// dz/dt (`dz_dt`, e.g. the τ column of its rows).
    pub fn new(spline: &'a PoseSpline, t: f64, x: &'a [f64], dz_dt: [f64; 6]) -> Self {
        Self {
            spline,
            t,
            x,
            dz_dt,
            accel: intrinsics(x).0.matrix(),
            inertial: OnceCell::new(),
        }
    }

    /// [`Self::new`] with dz/dt from the sample's Jacobian rows.
    pub fn at(spline: &'a PoseSpline, t: f64, x: &'a [f64]) -> Result<Self, PoseMeasurementError> {
        let ctx = RowContext::new(x)?;
        let rows = prediction_rows(spline, t, &ctx, &mut SegmentCache::default())?;
        Ok(Self::new(spline, t, x, dz_dt_of(&rows)))
    }

    fn evaluate(&self) -> Inertial {
        let x = self.x;
        let p_imu: V3 = [x[P_IMU], x[P_IMU + 1], x[P_IMU + 2]];
        // x passed RowContext (or the caller's fit): gravity is in range
        let g = gravity([x[G_XY], x[G_XY + 1]], G0).unwrap_or([0.0, 0.0, -G0]);
        match self.spline.evaluate(self.t + x[TAU]) {
            Ok(st) => {
                let lever = add(
                    cross(st.alpha, p_imu),
                    cross(st.omega, cross(st.omega, p_imu)),
                );
                Inertial {
                    omega: st.omega,
                    omega_dot: st.alpha,
                    s: add(mul_mtv(&st.r, sub(st.a, g)), lever),
                }
            }
            // outside the span (never for a selected sample): no motion
            Err(_) => Inertial {
                omega: [0.0; 3],
                omega_dot: [0.0; 3],
                s: [0.0; 3],
            },
        }
    }
}

/// dz/dt = ∂z/∂τ of a sample's rows.
pub fn dz_dt_of(rows: &super::rows::PoseRows) -> [f64; 6] {
    let g = GYRO_LOCAL
        .iter()
        .position(|&l| l == CTRL + TAU)
        .expect("τ is a gyroscope column");
    std::array::from_fn(|c| {
        if c < 3 {
            rows.accel[c][CTRL + TAU]
        } else {
            rows.gyro[c - 3][g]
        }
    })
}

impl ImuContext for PoseImuSample<'_> {
    fn t(&self) -> f64 {
        self.t
    }
    fn omega_and_force(&self) -> (V3, V3) {
        let i = self.inertial();
        (i.omega, i.s)
    }
    fn inertial(&self) -> Inertial {
        *self.inertial.get_or_init(|| self.evaluate())
    }
    fn dz_dt(&self) -> [f64; 6] {
        self.dz_dt
    }
    fn accel_matrix(&self) -> M3 {
        self.accel
    }
}

#[cfg(test)]
#[path = "inertial_tests.rs"]
mod tests;
