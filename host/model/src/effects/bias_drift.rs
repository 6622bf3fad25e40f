//! Time-varying sensor biases: each channel's bias drifts as a low-order
//! polynomial (a spline with no interior knot) in the session time,
//!
//! ```text
//! z_c ← z_c + β_c1 P1(u) + β_c2 P2(u)      u = 2 (t − t_m)/(t_1 − t_0) ∈ [−1, 1]
//! ```
//!
//! P1, P2 the Legendre polynomials (orthogonal to the constant bias b, which
//! the baseline estimates). Twelve parameters β (m/s² for the accelerometer,
//! rad/s for the gyroscope; the drift's value at the end of the session).
//! `simulate --effect bias_drift=M` (M in °/s) injects a gyroscope drift
//! β_g·1 = M·(1, −0.7, 0.5) °/s and β_g·2 = M·(0.3, 0.2, −0.4) °/s.

use super::{Effect, EffectParam, SampleContext, SessionSpan};

/// See the module doc.
pub struct BiasDrift {
    span: SessionSpan,
}

impl BiasDrift {
    /// Drift over `span`.
    pub fn new(span: SessionSpan) -> Self {
        Self { span }
    }
}

const CHANNELS: [&str; 6] = ["ax", "ay", "az", "gx", "gy", "gz"];
const DEG: f64 = std::f64::consts::PI / 180.0;

impl Effect for BiasDrift {
    fn name(&self) -> &'static str {
        "bias_drift"
    }
    fn description(&self) -> &'static str {
        "time-varying biases: Legendre P1, P2 in session time per channel"
    }
    fn params(&self) -> Vec<EffectParam> {
        let mut out = Vec::new();
        for (c, ch) in CHANNELS.iter().enumerate() {
            for k in 1..=2 {
                let (unit, display, prior_sigma) = if c < 3 {
                    ("m/s^2", ("m/s^2", 1.0), 1.0)
                } else {
                    ("rad/s", ("deg/s", 1.0 / DEG), 0.1)
                };
                out.push(EffectParam {
                    name: format!("bias_drift.{ch}_p{k}"),
                    unit,
                    display,
                    prior_sigma,
                });
            }
        }
        out
    }
    fn columns(&self, ctx: &SampleContext<'_>, cols: &mut [[f64; 6]]) {
        let u = self.span.unit(ctx.t);
        let p = [u, 0.5 * (3.0 * u * u - 1.0)];
        for c in 0..6 {
            for k in 0..2 {
                cols[2 * c + k][c] = p[k];
            }
        }
    }
    fn magnitude_unit(&self) -> &'static str {
        "deg/s"
    }
    fn injection(&self, magnitude: f64) -> Vec<f64> {
        let mut th = vec![0.0; 12];
        let p1 = [1.0, -0.7, 0.5];
        let p2 = [0.3, 0.2, -0.4];
        for a in 0..3 {
            th[2 * (3 + a)] = magnitude * DEG * p1[a];
            th[2 * (3 + a) + 1] = magnitude * DEG * p2[a];
        }
        th
    }
}
