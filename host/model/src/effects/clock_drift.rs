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

use super::{Effect, EffectConstant, EffectParam, ExactContext, SampleContext, SessionSpan};
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
        let dt = ctx.t - self.span.mid();
        cols[0] = ctx.dz_dt().map(|v| v * dt);
    }
    fn exact(&self, ctx: &ExactContext<'_>, theta: &[f64], _: &ParamLayout) -> [f64; 6] {
        let t = ctx.t + ctx.tau + theta[0] * (ctx.t - self.span.mid());
        ctx.model.predict(&(ctx.trajectory)(t))
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
