//! Structural resonance: one damped mode of natural frequency f_n and
//! damping ratio ζ, excited by the joint accelerations. Each joint's link
//! deflects by c_j times the mode's response y_j to that joint's own
//! acceleration (unit static gain):
//!
//! ```text
//! ÿ_j + 2ζω ẏ_j + ω² y_j = ω² q̈_j(t)          ω = 2π f_n, at rest before the motion
//! q_j = q_enc,j + c_j y_j     ⇒  δq = c y,  δq̇ = c ẏ,  δq̈ = c ÿ
//! z ≈ h + Σ_j c_j (∂z/∂q_j y_j + ∂z/∂q̇_j ẏ_j + ∂z/∂q̈_j ÿ_j)   (analytic ∂z/∂q…)
//! ```
//!
//! For motion slower than the mode, y ≈ q̈: the link lags by a deflection
//! proportional to its inertial load (c_j ≈ 1/ω_j² for a bare torsional
//! mode), and every change of jerk rings the mode at f_n for ≈ 1/(ζω) s.
//! c_j in s² (rad per rad/s²), displayed in mrad/(rad/s²). Unlike the other
//! effects this one needs the trajectory's history: y is integrated once per
//! session (RK4, four steps per grid step of ≤ 2 ms, Hermite-interpolated
//! between grid points) from the joint spline fitted to the recorded joints
//! (for the estimator) or from the true trajectory (for the simulator); the
//! response's dependence on the spline's coefficients is neglected like the
//! other effects' cross-derivatives. f_n and ζ are settings of the effect
//! ([`Mode`], default 10 Hz and 0.05): for motion below the mode the fit is
//! insensitive to them.
//! `simulate --effect resonance=M` (M in mrad/(rad/s²)) injects
//! c = M·(1, 0.8, 0.6, 0.5, 0.9, 0.7, …)·10⁻³ s².

use std::sync::{Arc, OnceLock};

use super::{Effect, EffectParam, ExactContext, SampleContext};
use crate::{JointState, ParamLayout, SpanPolynomials, Spline, MAX_JOINTS};

/// The mode's natural frequency and damping.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Mode {
    /// Natural frequency f_n, Hz.
    pub f_hz: f64,
    /// Damping ratio ζ.
    pub zeta: f64,
}

impl Default for Mode {
    /// 10 Hz, ζ = 0.05 (a lightly damped first mode of a collaborative arm).
    fn default() -> Self {
        Self {
            f_hz: 10.0,
            zeta: 0.05,
        }
    }
}

impl Mode {
    fn omega(&self) -> f64 {
        2.0 * std::f64::consts::PI * self.f_hz
    }
    /// ÿ from the mode equation.
    fn accel(&self, qdd: f64, y: f64, yd: f64) -> f64 {
        let w = self.omega();
        w * w * (qdd - y) - 2.0 * self.zeta * w * yd
    }
}

/// y, ẏ, ÿ of every joint on a uniform time grid (see the module doc).
#[derive(Debug, Clone)]
pub struct ModeResponse {
    mode: Mode,
    n: usize,
    t0: f64,
    dt: f64,
    /// [y, ẏ, ÿ] per grid point and joint: `nodes[k * n + j]`.
    nodes: Vec<[f64; 3]>,
}

/// Time before the first and after the last sample the grid covers, s.
const MARGIN: f64 = 2.0;

impl ModeResponse {
    /// Integrate the mode over [t0, t1] (t0 rounded down to the grid) for
    /// the `n` joint accelerations `qdd(t)`, starting at rest.
    pub fn integrate(
        mode: Mode,
        n: usize,
        t0: f64,
        t1: f64,
        qdd: impl Fn(f64) -> JointState,
    ) -> Self {
        let w = mode.omega();
        let dt = 0.002f64.min(0.1 / w);
        // grid on multiples of dt: responses of one trajectory over different
        // spans agree at common nodes
        let t0 = (t0 / dt).floor() * dt;
        let steps = ((t1 - t0) / dt).ceil().max(1.0) as usize;
        let sub = 4;
        let h = dt / sub as f64;
        let mut nodes = Vec::with_capacity((steps + 1) * n);
        let mut y = [0.0; MAX_JOINTS];
        let mut yd = [0.0; MAX_JOINTS];
        let push = |nodes: &mut Vec<[f64; 3]>, t: f64, y: &[f64], yd: &[f64]| {
            let a = qdd(t).qdd;
            for j in 0..n {
                nodes.push([y[j], yd[j], mode.accel(a[j], y[j], yd[j])]);
            }
        };
        push(&mut nodes, t0, &y, &yd);
        // sub-step s of step k starts at t0 + k·dt + s·h (the step's end is
        // the next step's start), so each sub-step's end value is the next
        // one's start value
        let at = |k: usize, s: usize| {
            let (k, s) = if s == sub { (k + 1, 0) } else { (k, s) };
            t0 + k as f64 * dt + s as f64 * h
        };
        let mut a0 = qdd(t0).qdd;
        for k in 0..steps {
            for s in 0..sub {
                let t = at(k, s);
                let (am, a1) = (qdd(t + 0.5 * h).qdd, qdd(at(k, s + 1)).qdd);
                for j in 0..n {
                    // RK4 on (y, ẏ)
                    let f = |a: f64, y: f64, v: f64| (v, mode.accel(a, y, v));
                    let (k1y, k1v) = f(a0[j], y[j], yd[j]);
                    let (k2y, k2v) = f(am[j], y[j] + 0.5 * h * k1y, yd[j] + 0.5 * h * k1v);
                    let (k3y, k3v) = f(am[j], y[j] + 0.5 * h * k2y, yd[j] + 0.5 * h * k2v);
                    let (k4y, k4v) = f(a1[j], y[j] + h * k3y, yd[j] + h * k3v);
                    y[j] += h / 6.0 * (k1y + 2.0 * k2y + 2.0 * k3y + k4y);
                    yd[j] += h / 6.0 * (k1v + 2.0 * k2v + 2.0 * k3v + k4v);
                }
                a0 = a1;
            }
            push(&mut nodes, t0 + (k + 1) as f64 * dt, &y, &yd);
        }
        Self {
            mode,
            n,
            t0,
            dt,
            nodes,
        }
    }

    /// The response to a joint spline (at rest outside its span), over the
    /// spline's span widened by 2 s.
    pub fn of_spline(mode: Mode, spline: &Spline) -> Self {
        let spans = SpanPolynomials::new(spline.knots());
        let traj = |t| {
            let mut js = JointState::default();
            spline.state_at_spans(&spans, t, &mut js);
            js
        };
        let k = spline.knots();
        Self::integrate(
            mode,
            spline.dim(),
            k.start() - MARGIN,
            k.end() + MARGIN,
            traj,
        )
    }

    /// (y, ẏ) of joint j at t by cubic Hermite interpolation (constant
    /// outside the grid), and ÿ from the mode equation with q̈_j(t) = `qdd`.
    pub fn at(&self, t: f64, j: usize, qdd: f64) -> [f64; 3] {
        let last = self.nodes.len() / self.n - 1;
        let u = ((t - self.t0) / self.dt).clamp(0.0, last as f64);
        let k = (u.floor() as usize).min(last.saturating_sub(1));
        let s = (u - k as f64).clamp(0.0, 1.0);
        let (a, b) = (
            self.nodes[k * self.n + j],
            self.nodes[(k + 1).min(last) * self.n + j],
        );
        let h = self.dt;
        let (h00, h10, h01, h11) = (
            (1.0 + 2.0 * s) * (1.0 - s) * (1.0 - s),
            s * (1.0 - s) * (1.0 - s),
            s * s * (3.0 - 2.0 * s),
            s * s * (s - 1.0),
        );
        let y = h00 * a[0] + h10 * h * a[1] + h01 * b[0] + h11 * h * b[1];
        let yd = h00 * a[1] + h10 * h * a[2] + h01 * b[1] + h11 * h * b[2];
        [y, yd, self.mode.accel(qdd, y, yd)]
    }
}

/// See the module doc. One instance simulates one trajectory: the exact
/// form's response is integrated on its first use and kept.
pub struct Resonance {
    mode: Mode,
    n: usize,
    /// Response to the recorded joints (the estimator's columns).
    fitted: Arc<ModeResponse>,
    /// Response to the true trajectory (the simulator), built on first use.
    exact: OnceLock<ModeResponse>,
    /// IMU time span (for the simulator's grid).
    span: (f64, f64),
}

const PATTERN: [f64; 8] = [1.0, 0.8, 0.6, 0.5, 0.9, 0.7, 0.4, 0.3];

/// mrad/(rad/s²) per s².
const DISPLAY: f64 = 1e3;

impl Resonance {
    /// For `n` joints with mode `mode`, the response to the recorded joints,
    /// and the IMU span.
    pub fn new(mode: Mode, n: usize, fitted: Arc<ModeResponse>, span: (f64, f64)) -> Self {
        Self {
            mode,
            n,
            fitted,
            exact: OnceLock::new(),
            span,
        }
    }
}

impl Effect for Resonance {
    fn name(&self) -> &'static str {
        "resonance"
    }
    fn description(&self) -> &'static str {
        "structural resonance: a damped mode driven by each joint's acceleration deflects the link, q = q_encoder + c_j y_j (mrad/(rad/s²))"
    }
    fn params(&self) -> Vec<EffectParam> {
        (1..=self.n)
            .map(|j| EffectParam {
                name: format!("resonance.c_{j}"),
                unit: "s^2",
                display: ("mrad/(rad/s^2)", DISPLAY),
                prior_sigma: 1e-2,
            })
            .collect()
    }
    fn columns(&self, ctx: &SampleContext<'_>, cols: &mut [[f64; 6]]) {
        let resp = &self.fitted;
        let t = ctx.t + ctx.model.params().tau;
        for j in 0..self.n {
            let [y, yd, ydd] = resp.at(t, j, ctx.js.qdd[j]);
            cols[j] = ctx.through_joints(j, y, yd, ydd);
        }
    }
    fn exact(&self, ctx: &ExactContext<'_>, theta: &[f64], _: &ParamLayout) -> [f64; 6] {
        let resp = self.exact.get_or_init(|| {
            let (t0, t1) = self.span;
            ModeResponse::integrate(
                self.mode,
                self.n,
                t0 + ctx.tau - MARGIN,
                t1 + ctx.tau + MARGIN,
                ctx.trajectory,
            )
        });
        let t = ctx.t + ctx.tau;
        let mut js = (ctx.trajectory)(t);
        let w = self.mode.omega();
        for j in 0..self.n {
            let [y, yd, ydd] = resp.at(t, j, js.qdd[j]);
            let yddd = w * w * (js.qddd[j] - yd) - 2.0 * self.mode.zeta * w * ydd;
            let c = theta[j];
            js.q[j] += c * y;
            js.qd[j] += c * yd;
            js.qdd[j] += c * ydd;
            js.qddd[j] += c * yddd;
        }
        ctx.model.predict(&js)
    }
    fn magnitude_unit(&self) -> &'static str {
        "mrad/(rad/s^2)"
    }
    fn injection(&self, magnitude: f64) -> Vec<f64> {
        (0..self.n)
            .map(|j| PATTERN[j % 8] * magnitude / DISPLAY)
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A step of q̈ at rest: y(t) = a (1 − e^{−ζωt}(cos ω_d t + ζ/√(1−ζ²) sin ω_d t))
    /// (the textbook step response of the second-order system).
    #[test]
    fn step_response_matches_the_closed_form() {
        let mode = Mode {
            f_hz: 7.0,
            zeta: 0.08,
        };
        let a = 1.3;
        let state = |t: f64| {
            let mut js = JointState::default();
            js.qdd[0] = if t >= 0.0 { a } else { 0.0 };
            js
        };
        let r = ModeResponse::integrate(mode, 1, 0.0, 2.0, state);
        let (w, z) = (mode.omega(), mode.zeta);
        let wd = w * (1.0 - z * z).sqrt();
        for t in [0.0123, 0.05, 0.1337, 0.5, 1.2345, 1.9] {
            let e = (-z * w * t).exp();
            let y = a * (1.0 - e * ((wd * t).cos() + z / (1.0 - z * z).sqrt() * (wd * t).sin()));
            let yd = a * e * w * w / wd * (wd * t).sin();
            let [ry, ryd, rydd] = r.at(t, 0, a);
            assert!((ry - y).abs() < 1e-6 * a, "t {t}: y {ry} vs {y}");
            assert!((ryd - yd).abs() < 1e-5 * a * w, "t {t}: ẏ {ryd} vs {yd}");
            let ydd = mode.accel(a, y, yd);
            assert!(
                (rydd - ydd).abs() < 1e-4 * a * w * w,
                "t {t}: ÿ {rydd} vs {ydd}"
            );
        }
    }
}
