//! What the estimator should find on a session of the twin: the hidden
//! truth x* (τ = 0) turned into the values of the parameters that the
//! twin's physics makes effective (docs/model.md §4.8).
//!
//! * τ: the datasheet chip's gyroscope reading is its filter's group delay
//!   plus on average half an update period old, d_g = gd_g + 1/(2·ODR_g),
//!   the ODR the chip's clock makes it (ODR·(1 + ε), ε its clock error),
//!   so the sample stamped t saw the arm at t − d_g: τ = −d_g (the ideal
//!   chip: 0).
//! * `sensor_delay.delta` = d_a − d_g, the same for the accelerometer.
//! * With a warm-up, the biases are x*'s (settled) plus the offset curve
//!   `o·f(t)` over the session's samples: when `bias_drift` (M segments)
//!   is in the model, its least-squares projection on the M + 1 hats of
//!   `bias_drift`'s spline gives `b` (the projection's time mean) and
//!   β_k (its change from t_0 to knot k); without it `b` takes the
//!   curve's mean.
//! * `joint_elasticity.c_j`: the arm's compliance (its mass model is the
//!   catalogue's), 0 on loaded joints that do not deflect.
//! * Any other effect parameter: 0 (the twin has no such effect), except
//!   those listed in [`TwinTruth::not_comparable`] (`resonance`: the
//!   twin's mode moves the IMU mount, the catalogue's deflects the joints;
//!   `temperature_bias`: its values depend on where the fit puts the
//!   reference temperature).

use robimu_bno055_sim::Timing;
use robimu_session::{ImuTiming, Truth};

use crate::rig::{ChipModel, SimRigConfig};

/// Effect names whose parameters have no truth in the twin.
pub const NOT_COMPARABLE: [(&str, &str); 2] = [
    (
        "resonance",
        "the twin's structural mode moves the IMU mount; the catalogue's deflects the joints",
    ),
    (
        "temperature_bias",
        "the warm-up's bias is linear in the die temperature, but the effect's coefficients depend on the fit's reference temperature",
    ),
];

/// The truth of one session of the twin.
#[derive(Clone, Debug, Default)]
pub struct TwinTruth {
    /// Baseline parameters (layout order) and effect parameters with a truth.
    pub values: Vec<(String, f64)>,
    /// Effects without a truth, and why.
    pub not_comparable: Vec<(String, String)>,
    /// The gyroscope's and accelerometer's signal delays d_g, d_a, s.
    pub delays: [f64; 2],
}

impl TwinTruth {
    /// The truth of `name`, if the twin has one.
    pub fn get(&self, name: &str) -> Option<f64> {
        self.values.iter().find(|(n, _)| n == name).map(|v| v.1)
    }
}

/// A sensor's signal delay: its filter's group delay plus half its update
/// period (the mean age of a held register).
pub fn signal_delay(bandwidth_hz: f64, odr_hz: f64) -> f64 {
    Timing {
        bandwidth_hz,
        odr_hz,
    }
    .group_delay_s()
        + 0.5 / odr_hz
}

/// The effective truth of a session of the twin `config` whose hidden
/// truth is `truth` (τ = 0, as the rig reports it): `timing` from its
/// session.toml, `since_power_on` the IMU samples' times since the board's
/// power-up (s, for the warm-up), `effect_params` the parameter names of
/// the effects in the model compared (e.g. diagnose's final fit).
pub fn twin_truth(
    config: &SimRigConfig,
    truth: &Truth,
    timing: Option<&ImuTiming>,
    since_power_on: &[f64],
    effect_params: &[String],
) -> TwinTruth {
    let clock = 1.0 + config.chip_clock_error_ppm * 1e-6;
    let delays = match (config.chip, timing) {
        (ChipModel::Datasheet, Some(t)) => [
            signal_delay(t.gyro_bandwidth_hz, t.gyro_odr_hz * clock),
            signal_delay(t.accel_bandwidth_hz, t.accel_odr_hz * clock),
        ],
        _ => [0.0, 0.0],
    };
    // bias_drift's resolution M: the largest knot index of its parameters
    let segments = effect_params
        .iter()
        .filter_map(|p| {
            p.strip_prefix("bias_drift.")?
                .split("_k")
                .nth(1)?
                .parse()
                .ok()
        })
        .max();
    let bias = warm_up_projection(config, since_power_on, segments);
    let mut values: Vec<(String, f64)> = truth.values.clone();
    for (name, v) in values.iter_mut() {
        if name == "tau" {
            *v = -delays[0];
        }
        if let Some(c) = BIAS_NAMES.iter().position(|b| b == name) {
            *v += bias.b[c];
        }
    }
    let mut not_comparable = Vec::new();
    for p in effect_params {
        let effect = p.split('.').next().unwrap_or_default();
        if let Some((e, why)) = NOT_COMPARABLE.iter().find(|(e, _)| *e == effect) {
            if !not_comparable
                .iter()
                .any(|(n, _): &(String, String)| n == e)
            {
                not_comparable.push((e.to_string(), why.to_string()));
            }
            continue;
        }
        let value = effect_truth(config, p, delays, &bias);
        values.push((p.clone(), value));
    }
    TwinTruth {
        values,
        not_comparable,
        delays,
    }
}

const BIAS_NAMES: [&str; 6] = ["b_a_x", "b_a_y", "b_a_z", "b_w_x", "b_w_y", "b_w_z"];
const CHANNELS: [&str; 6] = ["ax", "ay", "az", "gx", "gy", "gz"];

/// The truth of effect parameter `name` (0 unless the twin has the effect).
fn effect_truth(config: &SimRigConfig, name: &str, delays: [f64; 2], bias: &BiasProjection) -> f64 {
    if name == "sensor_delay.delta" {
        return delays[1] - delays[0];
    }
    if let Some(rest) = name.strip_prefix("bias_drift.") {
        // `{ch}_k{k}`
        let mut parts = rest.split("_k");
        let (ch, k) = (
            parts.next(),
            parts.next().and_then(|k| k.parse::<usize>().ok()),
        );
        if let (Some(c), Some(k)) = (ch.and_then(|ch| CHANNELS.iter().position(|x| *x == ch)), k) {
            return bias.beta[c].get(k.wrapping_sub(1)).copied().unwrap_or(0.0);
        }
    }
    if let Some(j) = name
        .strip_prefix("joint_elasticity.c_")
        .and_then(|j| j.parse::<usize>().ok())
    {
        let compliance = config
            .arm_physics
            .as_ref()
            .and_then(|a| a.elasticity.as_ref())
            .and_then(|e| e.compliance.get(j.wrapping_sub(1)).copied());
        return compliance.unwrap_or(0.0);
    }
    0.0
}

/// The warm-up's bias offset curve projected on the model's bias terms.
#[derive(Clone, Debug, Default)]
struct BiasProjection {
    /// Per channel: the constant bias b the model fits.
    b: [f64; 6],
    /// Per channel: `bias_drift`'s β_k, the projected curve's change from
    /// t_0 to knot k (k = 1..=M; empty without bias_drift).
    beta: [Vec<f64>; 6],
}

/// The hats B_0..B_M of M equal segments over [t0, t1] at `t` (the
/// piecewise-linear basis of `bias_drift`, docs/model.md §4.7).
fn hats(t: f64, t0: f64, t1: f64, m: usize, out: &mut [f64]) {
    out.iter_mut().for_each(|v| *v = 0.0);
    let s = if t1 > t0 {
        ((t - t0) / (t1 - t0) * m as f64).clamp(0.0, m as f64)
    } else {
        0.0
    };
    let j = (s.floor() as usize).min(m - 1);
    let w = s - j as f64;
    out[j] += 1.0 - w;
    out[j + 1] += w;
}

/// Per channel: the warm-up's bias offset curve over the samples `t`
/// projected (least squares) on the model's bias terms: with `bias_drift`
/// at M segments (`segments` = Some(M)) on the M + 1 hats, whose values v_k
/// give β_k = v_k − v_0 and b = the hats' time mean
/// v_0 + Σ m_k β_k (m_k = 1/M, 1/(2M) for the last); without it b is the
/// curve's mean. Zeros without a warm-up or samples.
fn warm_up_projection(config: &SimRigConfig, t: &[f64], segments: Option<usize>) -> BiasProjection {
    let mut out = BiasProjection::default();
    let (Some(w), Some(&t0), Some(&t1)) = (config.warm_up, t.first(), t.last()) else {
        return out;
    };
    let mean = t.iter().map(|&ti| w.remaining(ti)).sum::<f64>() / t.len() as f64;
    let shape = segments.and_then(|m| {
        let n = m + 1;
        let mut a = nalgebra::DMatrix::<f64>::zeros(n, n);
        let mut rhs = nalgebra::DVector::<f64>::zeros(n);
        let mut h = vec![0.0; n];
        for &ti in t {
            hats(ti, t0, t1, m, &mut h);
            let f = w.remaining(ti);
            for r in 0..n {
                rhs[r] += h[r] * f;
                for c in 0..n {
                    a[(r, c)] += h[r] * h[c];
                }
            }
        }
        let v = a.cholesky()?.solve(&rhs);
        let beta: Vec<f64> = (1..n).map(|k| v[k] - v[0]).collect();
        let b = v[0]
            + beta
                .iter()
                .enumerate()
                .map(|(i, bk)| bk * if i + 1 == m { 0.5 } else { 1.0 } / m as f64)
                .sum::<f64>();
        Some((b, beta))
    });
    for c in 0..6 {
        let o = w.bias_start_offset[c];
        match &shape {
            Some((b, beta)) => {
                out.b[c] = o * b;
                out.beta[c] = beta.iter().map(|v| o * v).collect();
            }
            None => out.b[c] = o * mean,
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use robimu_model::Robot;

    fn warm_config() -> (SimRigConfig, crate::physics::WarmUp) {
        let mut config = SimRigConfig::drawn(Robot::aubo_i5(), 1);
        let w = crate::physics::WarmUp {
            time_constant_s: 100.0,
            temp_start_c: 20.0,
            temp_end_c: 30.0,
            bias_start_offset: [1.0, 0.0, 0.0, 0.0, 0.0, 2.0],
        };
        config.warm_up = Some(w);
        (config, w)
    }

    fn grid(t0: f64, t1: f64, n: usize) -> Vec<f64> {
        (0..n)
            .map(|k| t0 + (t1 - t0) * k as f64 / (n - 1) as f64)
            .collect()
    }

    /// Simpson's rule of g over [t0, t1] (an independent quadrature).
    fn simpson(g: impl Fn(f64) -> f64, t0: f64, t1: f64) -> f64 {
        let m = 4000;
        let h = (t1 - t0) / m as f64;
        let mut s = 0.0;
        for i in 0..=m {
            let weight = if i == 0 || i == m {
                1.0
            } else if i % 2 == 1 {
                4.0
            } else {
                2.0
            };
            s += weight * g(t0 + h * i as f64);
        }
        s * h / 3.0
    }

    /// M = 1 (a line): the discrete projection against the continuous
    /// Legendre projection c_k = (2k+1)/2 ∫ f P_k du: b = c_0, β_1 = 2 c_1.
    #[test]
    fn the_linear_warm_up_projection_matches_the_legendre_integrals() {
        let (config, w) = warm_config();
        let (t0, t1) = (10.0, 70.0);
        let p = warm_up_projection(&config, &grid(t0, t1, 20_001), Some(1));
        let u = |t: f64| (t - 40.0) / 30.0;
        let c0 = 0.5 * simpson(|t| w.remaining(t), t0, t1) / 30.0;
        let c1 = 1.5 * simpson(|t| w.remaining(t) * u(t), t0, t1) / 30.0;
        assert!((p.b[0] - c0).abs() < 1e-4, "{} vs {c0}", p.b[0]);
        assert!((p.beta[0][0] - 2.0 * c1).abs() < 1e-4);
        assert!((p.beta[5][0] - 4.0 * c1).abs() < 2e-4);
        assert!(p.beta[1].iter().all(|v| *v == 0.0) && p.b[1] == 0.0);
    }

    /// M = 4: the residual curve − projection is orthogonal to every hat
    /// (the continuous normal equations, by Simpson's rule), and the
    /// projected values reproduce b and β from the hat values.
    #[test]
    fn the_spline_warm_up_projection_is_orthogonal_to_every_hat() {
        let (config, w) = warm_config();
        let (t0, t1, m) = (10.0, 70.0, 4);
        let p = warm_up_projection(&config, &grid(t0, t1, 40_001), Some(m));
        assert_eq!(p.beta[0].len(), m);
        // rebuild the projected curve from b and β: v_0 = b − Σ m_k β_k
        let mk = |k: usize| if k == m { 0.5 } else { 1.0 } / m as f64;
        let v0 = p.b[0] - (1..=m).map(|k| mk(k) * p.beta[0][k - 1]).sum::<f64>();
        let v: Vec<f64> = std::iter::once(v0)
            .chain((1..=m).map(|k| v0 + p.beta[0][k - 1]))
            .collect();
        let proj = |t: f64| {
            let mut h = vec![0.0; m + 1];
            hats(t, t0, t1, m, &mut h);
            h.iter().zip(&v).map(|(a, b)| a * b).sum::<f64>()
        };
        for k in 0..=m {
            let hk = |t: f64| {
                let mut h = vec![0.0; m + 1];
                hats(t, t0, t1, m, &mut h);
                h[k]
            };
            let ip = simpson(|t| (w.remaining(t) - proj(t)) * hk(t), t0, t1);
            assert!(ip.abs() < 1e-5, "hat {k}: {ip}");
        }
        // a decaying curve: the drift is not linear (the knots disagree
        // with a line through the end points)
        let line = p.beta[0][m - 1] * 2.0 / m as f64;
        assert!((p.beta[0][1] - line).abs() > 1e-3, "{:?}", p.beta[0]);
        // without bias_drift: the mean
        let q = warm_up_projection(&config, &grid(t0, t1, 40_001), None);
        let mean = simpson(|t| w.remaining(t), t0, t1) / (t1 - t0);
        assert!((q.b[0] - mean).abs() < 1e-6 && q.beta[0].is_empty());
    }
}
