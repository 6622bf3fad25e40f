//! Accelerometer delay relative to the gyroscope (different internal filter
//! group delays, docs/model.md §4.5): the gyroscope channels see the joint
//! state at t_i + τ (τ is the gyroscope's offset), the accelerometer
//! channels at t_i + τ − δ
//!
//! ```text
//! z_a,i = h_a(q(t_i + τ − δ))        z_g,i = h_g(q(t_i + τ))
//! ∂z_a/∂δ = −dz_a/dt,  ∂z_g/∂δ = 0   (dz/dt = ∂z/∂τ, analytic through q⃛)
//! ```
//!
//! δ > 0: the accelerometer lags the gyroscope. One parameter δ, seconds
//! (displayed in ms); prior σ 10 ms. The simulator evaluates the
//! accelerometer at the exact shifted time. `simulate --effect
//! sensor_delay=MS` injects δ = MS ms.

use super::{Effect, EffectParam, ExactContext, ImuContext, ImuExactContext, SampleContext};
use crate::ParamLayout;

/// See the module doc.
pub(crate) struct SensorDelay;

/// The exact z: the gyroscope's baseline at t + τ, the accelerometer's at
/// t + τ − δ, from the baseline `z_at` a trajectory time.
fn delayed(t: f64, tau: f64, delta: f64, z_at: &dyn Fn(f64) -> [f64; 6]) -> [f64; 6] {
    let (gyro, accel) = (z_at(t + tau), z_at(t + tau - delta));
    [accel[0], accel[1], accel[2], gyro[3], gyro[4], gyro[5]]
}

impl Effect for SensorDelay {
    fn name(&self) -> &'static str {
        "sensor_delay"
    }
    fn description(&self) -> &'static str {
        "accelerometer delay δ relative to the gyroscope: accel at t + τ − δ (ms)"
    }
    fn params(&self) -> Vec<EffectParam> {
        vec![EffectParam {
            name: "sensor_delay.delta".into(),
            unit: "s",
            display: ("ms", 1e3),
            prior_sigma: 1e-2,
        }]
    }
    fn columns(&self, ctx: &SampleContext<'_>, cols: &mut [[f64; 6]]) {
        self.imu_columns(ctx, cols);
    }
    fn imu_columns(&self, ctx: &dyn ImuContext, cols: &mut [[f64; 6]]) -> bool {
        let dz = ctx.dz_dt();
        cols[0] = [-dz[0], -dz[1], -dz[2], 0.0, 0.0, 0.0];
        true
    }
    fn exact(&self, ctx: &ExactContext<'_>, theta: &[f64], _: &ParamLayout) -> [f64; 6] {
        let z_at = |t| ctx.model.predict(&(ctx.trajectory)(t));
        delayed(ctx.t, ctx.tau, theta[0], &z_at)
    }
    fn imu_exact(&self, ctx: &ImuExactContext<'_>, theta: &[f64]) -> Option<[f64; 6]> {
        Some(delayed(ctx.t, ctx.tau, theta[0], ctx.z_at))
    }
    fn magnitude_unit(&self) -> &'static str {
        "ms"
    }
    fn injection(&self, magnitude: f64) -> Vec<f64> {
        vec![magnitude * 1e-3]
    }
}
