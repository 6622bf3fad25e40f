//! What the estimator should find on a session of the twin: the hidden
//! truth x* (τ = 0) turned into the values of the parameters that the
//! twin's physics makes effective (docs/model.md §4.8).
//!
//! * τ: the datasheet chip's gyroscope reading is its filter's group delay
//!   plus on average half an update period old, d_g = gd_g + 1/(2·ODR_g),
//!   the ODR the chip's clock makes it (ODR·(1 + ε), ε its clock error),
//!   so the sample stamped t saw the arm at t − d_g: τ = −d_g (the ideal
//!   chip: 0); plus the error e of the session's clock mapping (a sample
//!   the session puts at t was taken at t + e; the twin knows its board's
//!   clock): τ = e − d_g.
//! * `sensor_delay.delta` = d_a − d_g, the same for the accelerometer.
//! * With a warm-up, the biases are x*'s (settled) plus the offset curve
//!   `o·f(t)` over the session's samples: when `bias_drift` (M segments)
//!   is in the model, its least-squares projection on the M + 1 hats of
//!   `bias_drift`'s spline gives `b` (the projection's time mean) and
//!   β_k (its change from t_0 to knot k); without it `b` takes the
//!   curve's mean.
//! * `joint_elasticity.c_j`: the arm's compliance (its mass model is the
//!   catalogue's), 0 on loaded joints that do not deflect.
//! * With the structural mode (the realistic twin), every value plus the
//!   compared model's share of it: its estimate minus its estimate from
//!   the session without the mode's signal ([`mode_signal`]; computed by
//!   the caller, which has the fits, and passed to [`twin_truth`]).
//! * Any other effect parameter: 0 (the twin has no such effect), except
//!   those listed in [`TwinTruth::not_comparable`] (`resonance`: the
//!   twin's mode moves the IMU mount, the catalogue's deflects the joints;
//!   `temperature_bias`: its values depend on where the fit puts the
//!   reference temperature).

use robimu_bno055_sim::Timing;
use robimu_model::{ParamLayout, IMU_CHANNELS};
use robimu_record::clock_fit::ClockFit;
use robimu_session::{ImuTiming, Truth};

use crate::arm_physics::{ArmEffects, ArmPhysics, UrdfArm};
use crate::rig::{ChipModel, SimRigConfig};

/// Effect names whose parameters have no truth in the twin.
pub(crate) const NOT_COMPARABLE: [(&str, &str); 2] = [
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
    /// The structural mode's share included in `values`, by name.
    pub mode: Vec<(String, f64)>,
}

impl TwinTruth {
    /// The truth of `name`, if the twin has one.
    pub fn get(&self, name: &str) -> Option<f64> {
        self.values.iter().find(|(n, _)| n == name).map(|v| v.1)
    }

    /// The structural mode's share of the truth of `name` (0 without one).
    pub fn mode_share(&self, name: &str) -> f64 {
        share_of(&self.mode, name)
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
/// the effects in the model compared (e.g. diagnose's final fit), `mode`
/// the structural mode's share of the estimate per parameter name
/// ([`mode_signal`]), `imu_time_error_s` the IMU samples' true session
/// times minus the session's (its clock mapping's error, when known:
/// [`crate::twin::TwinSummary::imu_time_error_s`]; τ absorbs it).
pub(crate) fn twin_truth(
    config: &SimRigConfig,
    truth: &Truth,
    timing: Option<&ImuTiming>,
    since_power_on: &[f64],
    effect_params: &[String],
    mode: Option<&[(String, f64)]>,
    imu_time_error_s: f64,
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
    let mode = mode.unwrap_or_default();
    let mut values: Vec<(String, f64)> = truth.values.clone();
    for (name, v) in values.iter_mut() {
        if name == "tau" {
            *v = imu_time_error_s - delays[0];
        }
        if let Some(c) = BIAS_NAMES.iter().position(|b| b == name) {
            *v += bias.b[c];
        }
        *v += share_of(mode, name);
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
        values.push((
            p.clone(),
            effect_truth(config, p, delays, &bias) + share_of(mode, p),
        ));
    }
    TwinTruth {
        values,
        not_comparable,
        delays,
        mode: mode.to_vec(),
    }
}

/// The share of `name` in a list of (name, share); 0 when it is not listed.
fn share_of(shares: &[(String, f64)], name: &str) -> f64 {
    shares.iter().find(|(n, _)| n == name).map_or(0.0, |v| v.1)
}

/// The session clock mapping's own error at session time `middle`: the
/// true session time of the board's clock reading `device_s` there (s,
/// unwrapped) minus the time the session's clock fit of segment 0 gives it
/// (0 without one). τ absorbs it (docs/model.md §4.8).
pub fn clock_mapping_error(fits: &[(u32, ClockFit)], middle: f64, device_s: f64) -> f64 {
    fits.iter()
        .find(|(segment, _)| *segment == 0)
        .map_or(0.0, |(_, fit)| middle - fit.to_session(device_s))
}

const BIAS_NAMES: [&str; 6] = ["b_a_x", "b_a_y", "b_a_z", "b_w_x", "b_w_y", "b_w_z"];

/// The IMU's joint state at one sample: arm time t (s) and q, q̇, q̈.
#[derive(Clone, Debug)]
pub(crate) struct MotionSample {
    /// Arm time, s (the mode integrates along it).
    pub t: f64,
    /// q, rad.
    pub q: Vec<f64>,
    /// q̇, rad/s.
    pub qd: Vec<f64>,
    /// q̈, rad/s².
    pub qdd: Vec<f64>,
}

/// The structural mode's part of the noise-free output at each sample of
/// `motion` (docs/model.md §4.8): the twin's signal with its mount mode
/// minus the same without it (`[ax, ay, az, gx, gy, gz]`). None when the
/// twin has no mode.
///
/// Below its frequency the mount's mode adds to ω the flange's rate
/// filtered by ≈ (f/f₀)² and to s a tilt and a lag of the flange's
/// acceleration: a signal that follows the motion, so a calibration absorbs
/// part of it into the sensors' gains, axes and the trajectory. What it
/// absorbs is the truth's share of the mode: the difference between the
/// fits of the session with and without this signal (the demo's
/// `ModeShare`).
pub(crate) fn mode_signal(
    config: &SimRigConfig,
    motion: &[MotionSample],
) -> Result<Option<Vec<[f64; 6]>>, TruthError> {
    let Some(effects) = config.arm_physics.as_ref().filter(|e| e.mode.is_some()) else {
        return Ok(None);
    };
    let robot = &config.robot;
    let layout = ParamLayout::new(robot);
    let mut x = config.truth.clone();
    if let Some(tau) = x.get_mut(layout.offsets().tau) {
        *tau = 0.0;
    }
    let arm = UrdfArm::from_model(robot, &layout, &x)?;
    let still = ArmEffects {
        mode: None,
        ..effects.clone()
    };
    let mut with = ArmPhysics::new(arm.clone(), effects.clone(), robot.gravity())?;
    let mut without = ArmPhysics::new(arm, still, robot.gravity())?;
    Ok(Some(
        motion
            .iter()
            .map(|m| {
                let z = with.signal(m.t, &m.q, &m.qd, &m.qdd);
                let z0 = without.signal(m.t, &m.q, &m.qd, &m.qdd);
                std::array::from_fn(|c| z[c] - z0[c])
            })
            .collect(),
    ))
}

/// Why [`mode_signal`] could not be computed.
#[derive(Debug, thiserror::Error)]
pub(crate) enum TruthError {
    /// The truth does not fit the robot.
    #[error(transparent)]
    Model(#[from] robimu_model::ModelError),
    /// The twin's arm could not be built.
    #[error(transparent)]
    Arm(#[from] crate::arm_physics::ArmPhysicsError),
}

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
        if let (Some(c), Some(k)) = (
            ch.and_then(|ch| IMU_CHANNELS.iter().position(|x| *x == ch)),
            k,
        ) {
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

    /// Joint 1 swinging as A sin(Ωt), the others still: the mount's
    /// rotation obeys φ̈ + 2ζω₀φ̇ + ω₀²φ = −α (base frame), so once the
    /// start's transient has died φ̇ = r²/(1 − r²) ω to O(ζr) (r = Ω/ω₀,
    /// ω the flange's rate, about joint 1's axis; the forced response of a
    /// base-excited oscillator, an independent formula): the gyroscope's
    /// part of the mode's signal, taken back through the sensor's K Γ R and
    /// the IMU's orientation, is that.
    #[test]
    fn the_mode_signal_is_the_base_excited_oscillators_response() {
        let robot = Robot::aubo_i5();
        let config = SimRigConfig::realistic(robot.clone(), 3).unwrap();
        let mode = config.arm_physics.as_ref().unwrap().mode.unwrap();
        let (f, amp) = (0.7, 0.4);
        let omega = 2.0 * std::f64::consts::PI * f;
        let r = f / mode.frequency_hz;
        let pose = [0.0, 0.3, 1.2, -0.4, 0.8, 0.2];
        let motion: Vec<MotionSample> = (0..3000)
            .map(|i| {
                let t = i as f64 / 200.0;
                let mut q = pose.to_vec();
                let mut qd = vec![0.0; 6];
                let mut qdd = vec![0.0; 6];
                q[0] = amp * (omega * t).sin();
                qd[0] = amp * omega * (omega * t).cos();
                qdd[0] = -amp * omega * omega * (omega * t).sin();
                MotionSample { t, q, qd, qdd }
            })
            .collect();
        let dz = mode_signal(&config, &motion).unwrap().unwrap();
        let layout = ParamLayout::new(&robot);
        let p = layout.unpack(&config.truth).unwrap();
        let arm = UrdfArm::from_model(&robot, &layout, &config.truth).unwrap();
        // the joints stand deflected by the elasticity: the IMU's orientation there
        let effects = config.arm_physics.clone().unwrap();
        let physics = ArmPhysics::new(arm.clone(), effects, robot.gravity()).unwrap();
        let expected = r * r / (1.0 - r * r);
        // after 5 s: the start's transient has decayed by e^{−ζω₀t} ≈ 6·10⁻⁴
        let pairs: Vec<_> = motion
            .iter()
            .zip(&dz)
            .skip(1000)
            .map(|(m, d)| {
                let raw = [d[3] + p.gyro.b[0], d[4] + p.gyro.b[1], d[5] + p.gyro.b[2]];
                let [q, qd, qdd] = physics.actual_joints(&m.q, &m.qd, &m.qdd);
                let k = arm.kinematics(&q, &qd, &qdd);
                let u = k.r * nalgebra::Vector3::from(p.gyro.invert(raw).unwrap());
                (u, k.r * k.omega)
            })
            .collect();
        let slope = pairs.iter().map(|(u, w)| u.dot(w)).sum::<f64>()
            / pairs.iter().map(|(_, w)| w.norm_squared()).sum::<f64>();
        assert!(
            (slope / expected - 1.0).abs() < 1e-3,
            "φ̇ / ω = {slope:.5e}, the oscillator's {expected:.5e}"
        );
        let peak = expected * amp * omega;
        let off = pairs
            .iter()
            .map(|(u, w)| (u - w * expected).norm())
            .fold(0.0, f64::max);
        // the damping's phase lag: 2ζr/(1 − r²) ≈ 2·10⁻³ of the peak
        assert!(
            off < 0.005 * peak,
            "φ̇ off the oscillator's by {off:.2e} (peak {peak:.2e})"
        );
    }

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
