//! Joint encoder scale (gear-ratio error): the true joint angle is the
//! encoder reading scaled by (1 + κ_j),
//!
//! ```text
//! q_j = (1 + κ_j) q_enc,j     ⇒  δq = κ q,  δq̇ = κ q̇,  δq̈ = κ q̈
//! z ≈ h + Σ_j κ_j (∂z/∂q_j q_j + ∂z/∂q̇_j q̇_j + ∂z/∂q̈_j q̈_j)   (analytic ∂z/∂q…)
//! ```
//!
//! One dimensionless κ per joint (displayed in ppm). The simulator scales the
//! joint state exactly. `simulate --effect encoder_scale=M` (M in ppm)
//! injects κ = M·(1, −0.8, 0.6, −0.5, 0.9, −0.7, …) ppm.

use super::{Effect, EffectParam, ExactContext, SampleContext};
use crate::ParamLayout;

/// See the module doc.
pub struct EncoderScale {
    n: usize,
}

impl EncoderScale {
    /// For a robot of `n` joints.
    pub fn new(n: usize) -> Self {
        Self { n }
    }
}

const PATTERN: [f64; 8] = [1.0, -0.8, 0.6, -0.5, 0.9, -0.7, 0.4, -0.3];

impl Effect for EncoderScale {
    fn name(&self) -> &'static str {
        "encoder_scale"
    }
    fn description(&self) -> &'static str {
        "joint encoder scale (gear-ratio error): q = (1 + κ_j) q_encoder (ppm)"
    }
    fn params(&self) -> Vec<EffectParam> {
        (1..=self.n)
            .map(|j| EffectParam {
                name: format!("encoder_scale.kappa_{j}"),
                unit: "1",
                display: ("ppm", 1e6),
                prior_sigma: 1e-1,
            })
            .collect()
    }
    fn columns(&self, ctx: &SampleContext<'_>, cols: &mut [[f64; 6]]) {
        let js = ctx.js;
        for j in 0..self.n {
            cols[j] = ctx.through_joints(j, js.q[j], js.qd[j], js.qdd[j]);
        }
    }
    fn exact(&self, ctx: &ExactContext<'_>, theta: &[f64], _: &ParamLayout) -> [f64; 6] {
        let mut js = (ctx.trajectory)(ctx.t + ctx.tau);
        for j in 0..self.n {
            let f = 1.0 + theta[j];
            js.q[j] *= f;
            js.qd[j] *= f;
            js.qdd[j] *= f;
            js.qddd[j] *= f;
        }
        ctx.model.predict(&js)
    }
    fn magnitude_unit(&self) -> &'static str {
        "ppm"
    }
    fn injection(&self, magnitude: f64) -> Vec<f64> {
        (0..self.n)
            .map(|j| PATTERN[j % 8] * magnitude * 1e-6)
            .collect()
    }
}
