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

use super::{Effect, EffectParam, ExactContext, SampleContext};
use crate::ParamLayout;

/// See the module doc.
pub(crate) struct SensorDelay;

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
        let dz = ctx.dz_dt();
        cols[0] = [-dz[0], -dz[1], -dz[2], 0.0, 0.0, 0.0];
    }
    fn exact(&self, ctx: &ExactContext<'_>, theta: &[f64], _: &ParamLayout) -> [f64; 6] {
        let gyro = ctx.baseline();
        let accel = ctx
            .model
            .predict(&(ctx.trajectory)(ctx.t + ctx.tau - theta[0]));
        [accel[0], accel[1], accel[2], gyro[3], gyro[4], gyro[5]]
    }
    fn magnitude_unit(&self) -> &'static str {
        "ms"
    }
    fn injection(&self, magnitude: f64) -> Vec<f64> {
        vec![magnitude * 1e-3]
    }
}
