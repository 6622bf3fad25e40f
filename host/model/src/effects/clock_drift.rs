//! IMU clock drift: the IMU clock runs at rate (1 + κ) of the robot's, so the
//! sample stamped t_i was taken at robot time
//!
//! ```text
//! t_i + τ + κ (t_i − t_m)          (t_m the middle of the session: the offset
//!                                   at t_m is τ itself)
//! z_i ≈ h(t_i + τ) + κ (t_i − t_m) dz/dt     dz/dt = ∂z/∂τ (analytic)
//! ```
//!
//! One parameter κ, dimensionless (displayed in ppm). The simulator uses the
//! exact warped time. `simulate --effect clock_drift=M` injects κ = M ppm.

use super::{
    Effect, EffectConstant, EffectParam, ExactContext, ImuContext, ImuExactContext, SampleContext,
    SessionSpan,
};
use crate::ParamLayout;

/// See the module doc.
pub(crate) struct ClockDrift {
    span: SessionSpan,
}

impl ClockDrift {
    /// Clock drift about the middle of `span`.
    pub fn new(span: SessionSpan) -> Self {
        Self { span }
    }

    /// The exact z: the baseline `z_at` the warped time.
    fn warped(&self, t: f64, tau: f64, kappa: f64, z_at: &dyn Fn(f64) -> [f64; 6]) -> [f64; 6] {
        z_at(t + tau + kappa * (t - self.span.mid()))
    }
}

impl Effect for ClockDrift {
    fn name(&self) -> &'static str {
        "clock_drift"
    }
    fn description(&self) -> &'static str {
        "IMU clock drift: IMU time runs at (1 + κ) robot time (ppm)"
    }
    fn params(&self) -> Vec<EffectParam> {
        vec![EffectParam {
            name: "clock_drift.kappa".into(),
            unit: "1",
            display: ("ppm", 1e6),
            prior_sigma: 1e-2,
        }]
    }
    fn columns(&self, ctx: &SampleContext<'_>, cols: &mut [[f64; 6]]) {
        self.imu_columns(ctx, cols);
    }
    fn imu_columns(&self, ctx: &dyn ImuContext, cols: &mut [[f64; 6]]) -> bool {
        let dt = ctx.t() - self.span.mid();
        cols[0] = ctx.dz_dt().map(|v| v * dt);
        true
    }
    fn exact(&self, ctx: &ExactContext<'_>, theta: &[f64], _: &ParamLayout) -> [f64; 6] {
        let z_at = |t| ctx.model.predict(&(ctx.trajectory)(t));
        self.warped(ctx.t, ctx.tau, theta[0], &z_at)
    }
    fn imu_exact(&self, ctx: &ImuExactContext<'_>, theta: &[f64]) -> Option<[f64; 6]> {
        Some(self.warped(ctx.t, ctx.tau, theta[0], ctx.z_at))
    }
    fn constants(&self) -> Vec<EffectConstant> {
        vec![EffectConstant {
            name: "clock_drift.t_ref".into(),
            unit: "s",
            value: self.span.mid(),
        }]
    }
    fn magnitude_unit(&self) -> &'static str {
        "ppm"
    }
    fn injection(&self, magnitude: f64) -> Vec<f64> {
        vec![magnitude * 1e-6]
    }
}
