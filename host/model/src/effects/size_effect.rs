//! Accelerometer size effect: each accelerometer sensor axis sits at its own
//! lever arm, so it senses the specific force of its own point,
//!
//! ```text
//! s̃_i ← s̃_i + (M_a)_i · ( ω̇ × r_i + ω × (ω × r_i) )      i = y, z
//! ```
//!
//! with M_a = K_a Γ_a R_a (eq. (6)), ω, ω̇ in the IMU frame and r_i the
//! position of sensor axis i relative to the x axis's, in the IMU frame (the
//! x axis is the reference: a common offset of all three is the IMU
//! position ε_n1..3). Six parameters, metres (displayed in mm).
//! `simulate --effect size_effect=M` (M in mm) injects
//! r_y = M·(0.8, −0.5, 0.3) mm and r_z = M·(−0.4, 0.7, 0.6) mm.

use super::{lever_acceleration, Effect, EffectParam, ImuContext, SampleContext};
use crate::geom::dot;

/// See the module doc.
pub(crate) struct SizeEffect;

const PATTERN: [f64; 6] = [0.8, -0.5, 0.3, -0.4, 0.7, 0.6];

impl Effect for SizeEffect {
    fn name(&self) -> &'static str {
        "size_effect"
    }
    fn description(&self) -> &'static str {
        "accelerometer size effect: y and z axes at their own lever arms r_y, r_z (mm) from the x axis"
    }
    fn params(&self) -> Vec<EffectParam> {
        let mut out = Vec::new();
        for axis in ['y', 'z'] {
            for c in ['x', 'y', 'z'] {
                out.push(EffectParam {
                    name: format!("size_effect.r{axis}_{c}"),
                    unit: "m",
                    display: ("mm", 1e3),
                    prior_sigma: 0.1,
                });
            }
        }
        out
    }
    fn columns(&self, ctx: &SampleContext<'_>, cols: &mut [[f64; 6]]) {
        self.imu_columns(ctx, cols);
    }
    fn imu_columns(&self, ctx: &dyn ImuContext, cols: &mut [[f64; 6]]) -> bool {
        let inertial = &ctx.inertial();
        let m = ctx.accel_matrix();
        for (a, row) in [1usize, 2].into_iter().enumerate() {
            for c in 0..3 {
                let mut e = [0.0; 3];
                e[c] = 1.0;
                let acc = lever_acceleration(inertial, e);
                cols[3 * a + c][row] = dot(m[row], acc);
            }
        }
        true
    }
    fn magnitude_unit(&self) -> &'static str {
        "mm"
    }
    fn injection(&self, magnitude: f64) -> Vec<f64> {
        PATTERN.iter().map(|p| p * magnitude * 1e-3).collect()
    }
}
