//! What the estimator should find on a session of the twin: the hidden
//! truth x* (τ = 0) turned into the values of the parameters that the
//! twin's physics makes effective (docs/model.md §4.7).
//!
//! * τ: the datasheet chip's gyroscope reading is its filter's group delay
//!   plus on average half an update period old, d_g = gd_g + 1/(2·ODR_g),
//!   so the sample stamped t saw the arm at t − d_g: τ = −d_g (the ideal
//!   chip: 0).
//! * `sensor_delay.delta` = d_a − d_g, the same for the accelerometer.
//! * With a warm-up, the biases are x*'s (settled) plus the offset curve
//!   `o·f(t)` over the session's samples: its least-squares projection on
//!   1, P1(u), P2(u) (u the session time on [−1, 1], as `bias_drift`)
//!   gives `b` and, when `bias_drift` is in the model, its P1, P2
//!   coefficients; without it `b` takes the curve's mean.
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
    let delays = match (config.chip, timing) {
        (ChipModel::Datasheet, Some(t)) => [
            signal_delay(t.gyro_bandwidth_hz, t.gyro_odr_hz),
            signal_delay(t.accel_bandwidth_hz, t.accel_odr_hz),
        ],
        _ => [0.0, 0.0],
    };
    let drift_in_model = effect_params.iter().any(|p| p.starts_with("bias_drift."));
    let bias = warm_up_projection(config, since_power_on);
    let mut values: Vec<(String, f64)> = truth.values.clone();
    for (name, v) in values.iter_mut() {
        if name == "tau" {
            *v = -delays[0];
        }
        if let Some(c) = BIAS_NAMES.iter().position(|b| b == name) {
            *v += if drift_in_model {
                bias[c][0]
            } else {
                bias[c][3]
            };
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
fn effect_truth(config: &SimRigConfig, name: &str, delays: [f64; 2], bias: &[[f64; 4]; 6]) -> f64 {
    if name == "sensor_delay.delta" {
        return delays[1] - delays[0];
    }
    if let Some(rest) = name.strip_prefix("bias_drift.") {
        // `{ch}_p{k}`
        let mut parts = rest.split("_p");
        let (ch, k) = (
            parts.next(),
            parts.next().and_then(|k| k.parse::<usize>().ok()),
        );
        if let (Some(c), Some(k @ 1..=2)) =
            (ch.and_then(|ch| CHANNELS.iter().position(|x| *x == ch)), k)
        {
            return bias[c][k];
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

/// Per channel: the warm-up's bias offset curve over the samples projected
/// on 1, P1(u), P2(u) (coefficients 0–2), and its mean (3); zeros without
/// a warm-up or samples.
fn warm_up_projection(config: &SimRigConfig, t: &[f64]) -> [[f64; 4]; 6] {
    let mut out = [[0.0; 4]; 6];
    let (Some(w), Some(&t0), Some(&t1)) = (config.warm_up, t.first(), t.last()) else {
        return out;
    };
    let (mid, half) = (0.5 * (t0 + t1), 0.5 * (t1 - t0));
    // normal equations of the 3-term fit of f(t)
    let mut a = [[0.0; 3]; 3];
    let mut rhs = [0.0; 3];
    let mut mean = 0.0;
    for &ti in t {
        let u = if half > 0.0 { (ti - mid) / half } else { 0.0 };
        let basis = [1.0, u, 0.5 * (3.0 * u * u - 1.0)];
        let f = w.remaining(ti);
        mean += f / t.len() as f64;
        for r in 0..3 {
            rhs[r] += basis[r] * f;
            for c in 0..3 {
                a[r][c] += basis[r] * basis[c];
            }
        }
    }
    let coef = solve3(a, rhs).unwrap_or([mean, 0.0, 0.0]);
    for (c, row) in out.iter_mut().enumerate() {
        let o = w.bias_start_offset[c];
        *row = [o * coef[0], o * coef[1], o * coef[2], o * mean];
    }
    out
}

/// Solves a 3×3 system by Cramer's rule; `None` when singular.
fn solve3(a: [[f64; 3]; 3], b: [f64; 3]) -> Option<[f64; 3]> {
    let det = |m: [[f64; 3]; 3]| {
        m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
            - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
            + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
    };
    let d = det(a);
    if d.abs() < 1e-300 {
        return None;
    }
    Some(std::array::from_fn(|k| {
        let mut m = a;
        for r in 0..3 {
            m[r][k] = b[r];
        }
        det(m) / d
    }))
}

#[cfg(test)]
mod tests {
    use super::*;
    use robimu_model::Robot;

    /// The discrete least-squares projection against the continuous
    /// Legendre projection c_k = (2k+1)/2 ∫ f P_k du (Simpson's rule, an
    /// independent formula): on a dense uniform grid they agree to O(1/N).
    #[test]
    // k indexes the projection and the Legendre basis together
    #[allow(clippy::needless_range_loop)]
    fn the_warm_up_projection_matches_the_legendre_integrals() {
        let mut config = SimRigConfig::drawn(Robot::aubo_i5(), 1);
        let w = crate::physics::WarmUp {
            time_constant_s: 100.0,
            temp_start_c: 20.0,
            temp_end_c: 30.0,
            bias_start_offset: [1.0, 0.0, 0.0, 0.0, 0.0, 2.0],
        };
        config.warm_up = Some(w);
        let n = 20_001;
        let (t0, t1) = (10.0, 70.0);
        let t: Vec<f64> = (0..n)
            .map(|k| t0 + (t1 - t0) * k as f64 / (n - 1) as f64)
            .collect();
        let p = warm_up_projection(&config, &t);
        let legendre = |k: usize, u: f64| [1.0, u, 0.5 * (3.0 * u * u - 1.0)][k];
        for k in 0..3 {
            let m = 2000;
            let mut integral = 0.0;
            for i in 0..=m {
                let u = -1.0 + 2.0 * i as f64 / m as f64;
                let weight = if i == 0 || i == m {
                    1.0
                } else if i % 2 == 1 {
                    4.0
                } else {
                    2.0
                };
                let ti = 40.0 + 30.0 * u;
                integral += weight * w.remaining(ti) * legendre(k, u);
            }
            integral *= (2.0 / m as f64) / 3.0;
            let want = (2 * k + 1) as f64 / 2.0 * integral;
            assert!((p[0][k] - want).abs() < 1e-4, "{k}: {} vs {want}", p[0][k]);
            assert!((p[5][k] - 2.0 * want).abs() < 2e-4);
        }
        // the P2 term is there (a curve, not a line) and the mean is c_0's
        assert!(p[0][2].abs() > 1e-3, "{:?}", p[0]);
        assert!((p[0][3] - p[0][0]).abs() < 1e-4);
        assert!(p[1].iter().all(|v| *v == 0.0));
    }
}
