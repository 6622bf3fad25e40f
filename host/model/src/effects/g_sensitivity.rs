//! Gyroscope g-sensitivity: a rate error proportional to the specific force,
//!
//! ```text
//! ω̃ ← ω̃ + G s          G ∈ R^{3×3}, SI unit rad/s per m/s² (= s)
//! ```
//!
//! with s the specific force in the IMU frame (eq. (5)) and the rows of G in
//! gyroscope sensor axes. Displayed in (°/s)/g. `simulate --effect
//! g_sensitivity=M` injects G = M·P with M in (°/s)/g and the fixed pattern
//! P = [[1, 0.5, −0.3], [−0.4, 1, 0.2], [0.3, −0.6, 1]].

use super::{Effect, EffectParam, ImuContext, SampleContext};

/// See the module doc.
pub struct GSensitivity;

const PATTERN: [[f64; 3]; 3] = [[1.0, 0.5, -0.3], [-0.4, 1.0, 0.2], [0.3, -0.6, 1.0]];
/// (°/s)/g per SI unit (rad/s per m/s²), with g = 9.81 m/s².
const DISPLAY: f64 = 180.0 / std::f64::consts::PI * 9.81;

impl Effect for GSensitivity {
    fn name(&self) -> &'static str {
        "g_sensitivity"
    }
    fn description(&self) -> &'static str {
        "gyroscope g-sensitivity: ω̃ += G s (3×3, (°/s)/g)"
    }
    fn params(&self) -> Vec<EffectParam> {
        let axes = ['x', 'y', 'z'];
        let mut out = Vec::new();
        for r in axes {
            for c in axes {
                out.push(EffectParam {
                    name: format!("g_sensitivity.g{r}_s{c}"),
                    unit: "s",
                    display: ("(deg/s)/g", DISPLAY),
                    prior_sigma: 1e-2,
                });
            }
        }
        out
    }
    fn columns(&self, ctx: &SampleContext<'_>, cols: &mut [[f64; 6]]) {
        self.imu_columns(ctx, cols);
    }
    fn imu_columns(&self, ctx: &dyn ImuContext, cols: &mut [[f64; 6]]) -> bool {
        let (_, s) = ctx.omega_and_force();
        for r in 0..3 {
            for c in 0..3 {
                cols[3 * r + c][3 + r] = s[c];
            }
        }
        true
    }
    fn magnitude_unit(&self) -> &'static str {
        "(deg/s)/g"
    }
    fn injection(&self, magnitude: f64) -> Vec<f64> {
        PATTERN
            .iter()
            .flatten()
            .map(|p| p * magnitude / DISPLAY)
            .collect()
    }
}
