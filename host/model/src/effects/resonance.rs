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
use crate::lanes::has_avx2;
use crate::{F64x4, JointState, Knots, ParamLayout, SpanPolynomials, Spline, MAX_JOINTS};

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
/// The response to a joint spline ([`Self::of_spline`]) is integrated on
/// its first use ([`Self::prepare`] does it ahead, e.g. on another thread
/// while the baseline is fitted).
#[derive(Debug, Clone)]
pub struct ModeResponse {
    mode: Mode,
    n: usize,
    /// The joint spline integrated on first use (`None`: integrated when
    /// made).
    spline: Option<Spline>,
    grid: OnceLock<Grid>,
}

/// The integrated response.
#[derive(Debug, Clone)]
struct Grid {
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
        let grid = Grid::integrate(mode, n, t0, t1, |t| qdd(t).qdd);
        Self {
            mode,
            n,
            spline: None,
            grid: OnceLock::from(grid),
        }
    }

    /// The response to a joint spline (at rest outside its span), over the
    /// spline's span widened by 2 s, integrated on first use.
    pub fn of_spline(mode: Mode, spline: &Spline) -> Self {
        Self {
            mode,
            n: spline.dim(),
            spline: Some(spline.clone()),
            grid: OnceLock::new(),
        }
    }

    /// Integrate the response now if it is not yet (a later use, on any
    /// thread, waits for one under way).
    pub fn prepare(&self) {
        self.grid();
    }

    fn grid(&self) -> &Grid {
        self.grid.get_or_init(|| {
            let spline = self
                .spline
                .as_ref()
                .expect("a lazy response has its spline");
            Grid::of_spline(self.mode, spline)
        })
    }

    /// (y, ẏ) of joint j at t by cubic Hermite interpolation (constant
    /// outside the grid), and ÿ from the mode equation with q̈_j(t) = `qdd`.
    pub fn at(&self, t: f64, j: usize, qdd: f64) -> [f64; 3] {
        let g = self.grid();
        let n = self.n;
        let last = g.nodes.len() / n - 1;
        let u = ((t - g.t0) / g.dt).clamp(0.0, last as f64);
        let k = (u.floor() as usize).min(last.saturating_sub(1));
        let s = (u - k as f64).clamp(0.0, 1.0);
        let (a, b) = (g.nodes[k * n + j], g.nodes[(k + 1).min(last) * n + j]);
        let h = g.dt;
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

impl Grid {
    /// [`ModeResponse::integrate`] from q̈(t) alone, asked for at
    /// non-decreasing times (eight per grid step: the RK4 sub-steps'
    /// middles and ends). The joints are integrated together in lanes
    /// ([`F64x4`], all [`MAX_JOINTS`]; the AVX2 copy where the CPU has it),
    /// each lane the scalar RK4's operations in its order (bit-identical,
    /// tested against the scalar loop).
    fn integrate(
        mode: Mode,
        n: usize,
        t0: f64,
        t1: f64,
        qdd: impl FnMut(f64) -> [f64; MAX_JOINTS],
    ) -> Self {
        #[cfg(target_arch = "x86_64")]
        {
            #[target_feature(enable = "avx,avx2")]
            fn avx2(
                mode: Mode,
                n: usize,
                t0: f64,
                t1: f64,
                qdd: impl FnMut(f64) -> [f64; MAX_JOINTS],
            ) -> Grid {
                Grid::integrate_lanes(mode, n, t0, t1, qdd)
            }
            if has_avx2() {
                // SAFETY: the CPU has AVX and AVX2 (checked just above).
                return unsafe { avx2(mode, n, t0, t1, qdd) };
            }
        }
        Self::integrate_lanes(mode, n, t0, t1, qdd)
    }

    #[inline(always)]
    fn integrate_lanes(
        mode: Mode,
        n: usize,
        t0: f64,
        t1: f64,
        mut qdd: impl FnMut(f64) -> [f64; MAX_JOINTS],
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
        let mut y = [F64x4::splat(0.0); 2];
        let mut yd = [F64x4::splat(0.0); 2];
        // a: q̈ at the node (the last sub-step's end, at the same time)
        let push = |nodes: &mut Vec<[f64; 3]>, a: &[f64], y: &[F64x4; 2], yd: &[F64x4; 2]| {
            for j in 0..n {
                let (y, yd) = (y[j / 4].lane(j % 4), yd[j / 4].lane(j % 4));
                nodes.push([y, yd, mode.accel(a[j], y, yd)]);
            }
        };
        // sub-step s of step k starts at t0 + k·dt + s·h (the step's end is
        // the next step's start), so each sub-step's end value is the next
        // one's start value
        let at = |k: usize, s: usize| {
            let (k, s) = if s == sub { (k + 1, 0) } else { (k, s) };
            t0 + k as f64 * dt + s as f64 * h
        };
        // the mode equation's factors as the scalar accel forms them:
        // w·w·(q̈ − y) − 2ζ·w·ẏ
        let (ww, c) = (F64x4::splat(w * w), F64x4::splat(2.0 * mode.zeta * w));
        let accel = |a: F64x4, y: F64x4, v: F64x4| ww * (a - y) - c * v;
        let (half, sixth) = (F64x4::splat(0.5 * h), F64x4::splat(h / 6.0));
        let (hv, two) = (F64x4::splat(h), F64x4::splat(2.0));
        let lanes = |a: &[f64; MAX_JOINTS]| {
            [
                F64x4([a[0], a[1], a[2], a[3]]),
                F64x4([a[4], a[5], a[6], a[7]]),
            ]
        };
        let mut a0 = qdd(t0);
        push(&mut nodes, &a0, &y, &yd);
        for k in 0..steps {
            for s in 0..sub {
                let t = at(k, s);
                let am = qdd(t + 0.5 * h);
                let a1 = qdd(at(k, s + 1));
                let (l0, lm, l1) = (lanes(&a0), lanes(&am), lanes(&a1));
                for g in 0..2 {
                    // RK4 on (y, ẏ)
                    let (y0, v0) = (y[g], yd[g]);
                    let (k1y, k1v) = (v0, accel(l0[g], y0, v0));
                    let (y2, v2) = (y0 + half * k1y, v0 + half * k1v);
                    let (k2y, k2v) = (v2, accel(lm[g], y2, v2));
                    let (y3, v3) = (y0 + half * k2y, v0 + half * k2v);
                    let (k3y, k3v) = (v3, accel(lm[g], y3, v3));
                    let (y4, v4) = (y0 + hv * k3y, v0 + hv * k3v);
                    let (k4y, k4v) = (v4, accel(l1[g], y4, v4));
                    y[g] = y0 + sixth * (k1y + two * k2y + two * k3y + k4y);
                    yd[g] = v0 + sixth * (k1v + two * k2v + two * k3v + k4v);
                }
                a0 = a1;
            }
            // the node t0 + (k+1)·dt is the last sub-step's end: its q̈ is a0
            push(&mut nodes, &a0, &y, &yd);
        }
        Self { t0, dt, nodes }
    }

    /// The response to a joint spline (at rest outside its span), over the
    /// spline's span widened by 2 s. A spline of degree ≤ 3 has a q̈ linear
    /// on each knot span, evaluated from its value and q⃛ at the span's
    /// start ([`SpanAccelerations`]: a few operations per time instead of
    /// the span search and the whole joint state; equal to rounding); a
    /// higher degree is evaluated through its span polynomials.
    fn of_spline(mode: Mode, spline: &Spline) -> Self {
        let k = spline.knots();
        let (t0, t1) = (k.start() - MARGIN, k.end() + MARGIN);
        if let Some(mut acc) = SpanAccelerations::new(spline) {
            return Self::integrate(mode, spline.dim(), t0, t1, |t| acc.at(t));
        }
        let spans = SpanPolynomials::new(spline.knots());
        let qdd = |t| {
            let mut js = JointState::default();
            spline.state_at_spans(&spans, t, &mut js);
            js.qdd
        };
        Self::integrate(mode, spline.dim(), t0, t1, qdd)
    }
}

/// q̈(t) of a spline of degree p ≤ 3 for many t in increasing order: on
/// knot span μ it is q̈(y_μ) + (t − y_μ) q⃛(y_μ) exactly (q̈ has degree
/// p − 2 ≤ 1 there; q⃛ the right-hand derivative), the span found by a
/// cursor that moves forward (a binary search when t goes back), and zero
/// outside the spline's span (at rest, [`Spline::state_at`]).
struct SpanAccelerations<'s> {
    knots: &'s Knots,
    /// Per span μ − p: q̈(y_μ), q⃛(y_μ) (zero on an empty span).
    coef: Vec<[[f64; MAX_JOINTS]; 2]>,
    /// The span of the last time asked for.
    cursor: usize,
}

impl<'s> SpanAccelerations<'s> {
    /// `None` for a degree above 3.
    fn new(spline: &'s Spline) -> Option<Self> {
        let knots = spline.knots();
        let (p, m, y) = (knots.degree(), knots.num_coeffs(), knots.knots());
        if p > 3 {
            return None;
        }
        let mut js = JointState::default();
        let coef = (p..m)
            .map(|mu| {
                if y[mu] < y[mu + 1] && spline.evaluate(y[mu], &mut js).is_ok() {
                    [js.qdd, js.qddd]
                } else {
                    [[0.0; MAX_JOINTS]; 2]
                }
            })
            .collect();
        Some(Self {
            knots,
            coef,
            cursor: p,
        })
    }

    /// q̈(t) ([`Spline::state_at`]'s, to rounding).
    fn at(&mut self, t: f64) -> [f64; MAX_JOINTS] {
        let k = self.knots;
        if !k.contains(t) {
            return [0.0; MAX_JOINTS];
        }
        let (p, m, y) = (k.degree(), k.num_coeffs(), k.knots());
        // the span of Knots::span: the last μ ≤ m − 1 with y_μ ≤ t
        if t < y[self.cursor] {
            self.cursor = k.span(t).unwrap_or(p);
        }
        while self.cursor + 1 < m && y[self.cursor + 1] <= t {
            self.cursor += 1;
        }
        let [a, b] = &self.coef[self.cursor - p];
        let s = t - y[self.cursor];
        std::array::from_fn(|j| a[j] + s * b[j])
    }
}

/// See the module doc. One instance simulates one trajectory: the exact
/// form's response is integrated on its first use and kept.
pub(crate) struct Resonance {
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

    /// A test spline: `dim` joints on `knots`, smooth pseudo-random coefficients.
    fn spline_on(knots: Knots, dim: usize) -> Spline {
        let m = knots.num_coeffs();
        let coeffs = (0..m * dim)
            .map(|i| 0.7 * ((i as f64 * 0.37).sin() + 0.5 * (i as f64 * 1.91).cos()))
            .collect();
        Spline::new(knots, dim, coeffs).unwrap()
    }

    /// The span accelerations of a cubic (uniform knots, and irregular ones
    /// with a repeated interior knot) equal q̈ of [`Spline::state_at`] to
    /// rounding at times forward, backward and outside the span; a quintic
    /// has none.
    #[test]
    fn span_accelerations_are_the_splines_qdd() {
        let irregular = Knots::new(
            3,
            vec![0.0, 0.0, 0.0, 0.0, 0.3, 1.1, 1.1, 1.2, 2.0, 2.0, 2.0, 2.0],
        )
        .unwrap();
        for knots in [Knots::uniform(0.0, 7.0, 0.25, 3).unwrap(), irregular] {
            let s = spline_on(knots, 6);
            let mut acc = SpanAccelerations::new(&s).unwrap();
            let (a, b) = (s.knots().start(), s.knots().end());
            let mut ts: Vec<f64> = (0..=400)
                .map(|i| a - 0.5 + (b - a + 1.0) * i as f64 / 400.0)
                .collect();
            ts.extend([b, a, 1.1, 1.1 - 1e-12, 0.3, b - 1e-9, a + 1e-9]);
            ts.extend((0..50).map(|i| b - (b - a) * i as f64 / 50.0));
            for t in ts {
                let mut js = JointState::default();
                s.state_at(t, &mut js);
                let got = acc.at(t);
                for j in 0..MAX_JOINTS {
                    let scale = 1.0 + js.qdd[j].abs();
                    assert!(
                        (got[j] - js.qdd[j]).abs() < 1e-11 * scale,
                        "t {t} joint {j}: {} vs {}",
                        got[j],
                        js.qdd[j]
                    );
                }
            }
        }
        let quintic = spline_on(Knots::uniform(0.0, 3.0, 0.5, 5).unwrap(), 2);
        assert!(SpanAccelerations::new(&quintic).is_none());
    }

    /// [`ModeResponse::of_spline`] (span accelerations, integrated on first
    /// use) against the integration of the spline's state through its span
    /// polynomials (the former evaluation), node by node; and a quintic
    /// takes that path.
    #[test]
    fn of_spline_matches_the_state_evaluation() {
        let mode = Mode::default();
        for (degree, spacing) in [(3, 0.2), (5, 0.5)] {
            let s = spline_on(Knots::uniform(1.0, 9.0, spacing, degree).unwrap(), 6);
            let spans = SpanPolynomials::new(s.knots());
            let k = s.knots();
            let old = ModeResponse::integrate(mode, 6, k.start() - MARGIN, k.end() + MARGIN, |t| {
                let mut js = JointState::default();
                s.state_at_spans(&spans, t, &mut js);
                js
            });
            let new = ModeResponse::of_spline(mode, &s);
            assert!(new.grid.get().is_none(), "integrated on first use");
            new.prepare();
            let (old, new) = (old.grid(), new.grid());
            assert_eq!(
                (old.t0, old.dt, old.nodes.len()),
                (new.t0, new.dt, new.nodes.len())
            );
            let scale: [f64; 3] =
                std::array::from_fn(|c| old.nodes.iter().map(|v| v[c].abs()).fold(0.0, f64::max));
            assert!(scale.iter().all(|&v| v > 0.0), "{scale:?}");
            for (a, b) in old.nodes.iter().zip(&new.nodes) {
                for c in 0..3 {
                    assert!(
                        (a[c] - b[c]).abs() <= 1e-12 * scale[c],
                        "degree {degree}: {a:?} vs {b:?}"
                    );
                }
            }
        }
    }

    /// The former scalar RK4 loop, joint by joint (the reference of the
    /// lanes of [`Grid::integrate`]).
    fn integrate_scalar(
        mode: Mode,
        n: usize,
        t0: f64,
        t1: f64,
        qdd: impl Fn(f64) -> [f64; MAX_JOINTS],
    ) -> Grid {
        let w = mode.omega();
        let dt = 0.002f64.min(0.1 / w);
        let t0 = (t0 / dt).floor() * dt;
        let steps = ((t1 - t0) / dt).ceil().max(1.0) as usize;
        let sub = 4;
        let h = dt / sub as f64;
        let mut nodes = Vec::new();
        let (mut y, mut yd) = ([0.0; MAX_JOINTS], [0.0; MAX_JOINTS]);
        let push = |nodes: &mut Vec<[f64; 3]>, t: f64, y: &[f64], yd: &[f64]| {
            let a = qdd(t);
            for j in 0..n {
                nodes.push([y[j], yd[j], mode.accel(a[j], y[j], yd[j])]);
            }
        };
        push(&mut nodes, t0, &y, &yd);
        let at = |k: usize, s: usize| {
            let (k, s) = if s == sub { (k + 1, 0) } else { (k, s) };
            t0 + k as f64 * dt + s as f64 * h
        };
        let mut a0 = qdd(t0);
        for k in 0..steps {
            for s in 0..sub {
                let t = at(k, s);
                let (am, a1) = (qdd(t + 0.5 * h), qdd(at(k, s + 1)));
                for j in 0..n {
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
        Grid { t0, dt, nodes }
    }

    /// The lanes integrate bit-identically to the scalar loop, for 6 and
    /// 8 joints and a step input (both copies: AVX2 where the CPU has it,
    /// and the plain one).
    #[test]
    fn lane_integration_is_the_scalar_one() {
        let mode = Mode {
            f_hz: 7.0,
            zeta: 0.08,
        };
        for n in [1, 6, 8] {
            let qdd = |t: f64| -> [f64; MAX_JOINTS] {
                std::array::from_fn(|j| {
                    if j < n {
                        (t * (1.0 + j as f64)).sin() + if t > 0.3 { 1.3 } else { 0.0 }
                    } else {
                        0.0
                    }
                })
            };
            let want = integrate_scalar(mode, n, -0.1, 2.0, qdd);
            for got in [
                Grid::integrate(mode, n, -0.1, 2.0, qdd),
                Grid::integrate_lanes(mode, n, -0.1, 2.0, qdd),
            ] {
                assert_eq!((got.t0, got.dt), (want.t0, want.dt));
                assert_eq!(got.nodes.len(), want.nodes.len());
                for (a, b) in got.nodes.iter().zip(&want.nodes) {
                    assert_eq!(a.map(f64::to_bits), b.map(f64::to_bits), "{n} joints");
                }
            }
        }
    }
}
