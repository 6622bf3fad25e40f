//! Time-varying sensor biases: each channel's bias follows a piecewise-linear
//! spline over the session span with `M` equal segments (knots
//! t_k = t_0 + k (t_1 − t_0)/M), whose constant part stays with the
//! baseline biases b (docs/model.md §4.7):
//!
//! ```text
//! z_c ← z_c + Σ_{k=1..M} β_ck (B_k(t) − m_k)
//! ```
//!
//! B_k the hat function of knot k (B_M the half hat at t_1), m_k = ∫B_k/T
//! its mean over the span (1/M, and 1/(2M) for the last), so every column
//! has zero mean in time and the span of the columns and the constant is
//! that of all M + 1 hats. β_ck is the change of channel c's bias from t_0
//! to t_k (m/s² for the accelerometer, rad/s for the gyroscope); 6M
//! parameters. The resolution M is a setting of the catalogue
//! ([`CatalogueSetup::bias_drift_segments`](super::CatalogueSetup),
//! `bias_drift:M` on the command line; [`DEFAULT_SEGMENTS`] when not
//! given); diagnose chooses it from the data.
//!
//! `simulate --effect bias_drift=A` (A in °/s) injects a linear gyroscope
//! drift whose change over the session is A·(1, −0.7, 0.5) °/s on
//! (gx, gy, gz), exact at every M.

use super::{Effect, EffectConstant, EffectParam, ImuContext, SampleContext, SessionSpan};
use crate::IMU_CHANNELS;

/// Segments when none is given (a linear drift).
pub(crate) const DEFAULT_SEGMENTS: usize = 1;

/// Most segments accepted (6 parameters each).
pub(crate) const MAX_SEGMENTS: usize = 64;

/// Broad prior σ of β, accelerometer, m/s²: 60× the drift the paper
/// observed over 25 min (0.017 m/s²).
pub(crate) const PRIOR_ACCEL: f64 = 1.0;

/// Broad prior σ of β, gyroscope, rad/s: 100× the drift the paper observed
/// over 25 min (0.025 °/s).
pub(crate) const PRIOR_GYRO: f64 = 2.5 * DEG;

/// See the module doc.
pub(crate) struct BiasDrift {
    span: SessionSpan,
    segments: usize,
}

impl BiasDrift {
    /// Drift over `span` with `segments` segments (clamped to
    /// 1..=[`MAX_SEGMENTS`]; the catalogue set-up validates it).
    pub fn new(span: SessionSpan, segments: usize) -> Self {
        Self {
            span,
            segments: segments.clamp(1, MAX_SEGMENTS),
        }
    }

    /// The column values B_k(t) − m_k, k = 1..=M, at `t`.
    fn basis(&self, t: f64, out: &mut [f64]) {
        let m = self.segments;
        let width = self.span.t1 - self.span.t0;
        let s = if width > 0.0 {
            ((t - self.span.t0) / width * m as f64).clamp(0.0, m as f64)
        } else {
            0.0
        };
        // the segment [t_j, t_{j+1}] holding t, and the position in it
        let j = (s.floor() as usize).min(m - 1);
        let w = s - j as f64;
        for (k, o) in out.iter_mut().enumerate().take(m) {
            let knot = k + 1;
            let hat = if knot == j {
                1.0 - w
            } else if knot == j + 1 {
                w
            } else {
                0.0
            };
            let mean = if knot == m { 0.5 } else { 1.0 } / m as f64;
            *o = hat - mean;
        }
    }
}

const DEG: f64 = std::f64::consts::PI / 180.0;

impl Effect for BiasDrift {
    fn name(&self) -> &'static str {
        "bias_drift"
    }
    fn description(&self) -> &'static str {
        "time-varying biases: a piecewise-linear bias spline per channel, M segments over the session"
    }
    fn params(&self) -> Vec<EffectParam> {
        let mut out = Vec::new();
        for (c, ch) in IMU_CHANNELS.iter().enumerate() {
            for k in 1..=self.segments {
                let (unit, display, prior_sigma) = if c < 3 {
                    ("m/s^2", ("m/s^2", 1.0), PRIOR_ACCEL)
                } else {
                    ("rad/s", ("deg/s", 1.0 / DEG), PRIOR_GYRO)
                };
                out.push(EffectParam {
                    name: format!("bias_drift.{ch}_k{k}"),
                    unit,
                    display,
                    prior_sigma,
                });
            }
        }
        out
    }
    fn columns(&self, ctx: &SampleContext<'_>, cols: &mut [[f64; 6]]) {
        self.imu_columns(ctx, cols);
    }
    fn imu_columns(&self, ctx: &dyn ImuContext, cols: &mut [[f64; 6]]) -> bool {
        let m = self.segments;
        let mut b = [0.0; MAX_SEGMENTS];
        self.basis(ctx.t(), &mut b);
        for c in 0..6 {
            for k in 0..m {
                cols[m * c + k][c] = b[k];
            }
        }
        true
    }
    fn constants(&self) -> Vec<EffectConstant> {
        let c = |name: &str, value| EffectConstant {
            name: format!("bias_drift.{name}"),
            unit: "s",
            value,
        };
        vec![c("t_start", self.span.t0), c("t_end", self.span.t1)]
    }
    fn magnitude_unit(&self) -> &'static str {
        "deg/s"
    }
    fn injection(&self, magnitude: f64) -> Vec<f64> {
        let m = self.segments;
        let mut th = vec![0.0; 6 * m];
        let dir = [1.0, -0.7, 0.5];
        for (a, d) in dir.iter().enumerate() {
            for k in 1..=m {
                // the linear drift's change from t_0 to t_k
                th[m * (3 + a) + k - 1] = magnitude * DEG * d * k as f64 / m as f64;
            }
        }
        th
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Against an independent construction: the drift at any t is the
    /// linear interpolation of the knot values (0, β_1, …, β_M) minus its
    /// time mean (trapezoid rule over the knots), and each column's sample
    /// mean over a dense uniform grid is 0.
    #[test]
    fn the_basis_is_the_zero_mean_interpolant_of_the_knot_values() {
        let span = SessionSpan { t0: 3.0, t1: 63.0 };
        for m in [1, 2, 5, 8] {
            let e = BiasDrift::new(span.clone(), m);
            let beta: Vec<f64> = (1..=m).map(|k| (k as f64 * 1.3).sin() + 0.2).collect();
            let knots: Vec<f64> = std::iter::once(0.0).chain(beta.iter().copied()).collect();
            let mean = (0..m).map(|j| 0.5 * (knots[j] + knots[j + 1])).sum::<f64>() / m as f64;
            let h = 60.0 / m as f64;
            let mut b = [0.0; MAX_SEGMENTS];
            let n = 60_000;
            let mut sums = vec![0.0; m];
            for i in 0..=n {
                let t = 3.0 + 60.0 * i as f64 / n as f64;
                e.basis(t, &mut b);
                let got: f64 = (0..m).map(|k| beta[k] * b[k]).sum();
                let j = (((t - 3.0) / h) as usize).min(m - 1);
                let w = (t - 3.0 - j as f64 * h) / h;
                let want = knots[j] * (1.0 - w) + knots[j + 1] * w - mean;
                assert!((got - want).abs() < 1e-12, "M {m} t {t}: {got} vs {want}");
                for k in 0..m {
                    sums[k] += b[k];
                }
            }
            for s in sums {
                assert!(
                    (s / n as f64).abs() < 1e-4,
                    "M {m}: column mean {}",
                    s / n as f64
                );
            }
        }
    }

    /// The injected pattern is one linear drift at every resolution: its
    /// change over the session is the documented A·(1, −0.7, 0.5) °/s.
    #[test]
    fn the_injected_drift_is_the_same_line_at_every_resolution() {
        let span = SessionSpan { t0: 0.0, t1: 90.0 };
        let mut b = [0.0; MAX_SEGMENTS];
        for t in [0.0, 17.0, 45.0, 89.0, 90.0] {
            let mut values = Vec::new();
            for m in [1, 3, 16] {
                let e = BiasDrift::new(span.clone(), m);
                let th = e.injection(0.2);
                e.basis(t, &mut b);
                let gx: f64 = (0..m).map(|k| th[3 * m + k] * b[k]).sum();
                values.push(gx);
            }
            // the line through the span's middle with slope 0.2 °/s per session
            let want = 0.2 * DEG * (t - 45.0) / 90.0;
            for v in values {
                assert!((v - want).abs() < 1e-15, "t {t}: {v} vs {want}");
            }
        }
    }
}
